//! Data files holding rows of several kinds ([`MeasurementFormat::Mixed`]): a header with the
//! columns of more than one kind — tracker `x_mm,y_mm,z_mm` (+ `qw,qx,qy,qz` or
//! `roll_deg,pitch_deg,yaw_deg`), `seat`, `pivot` with `length_mm` or `reading_mm`, touches
//! (`sphere` with `sphere_diameter_mm`, `plane`, `face` with `cube_edge_mm`, each with
//! `probe_radius_mm`) — and each row filling the cells of exactly one kind, the others left
//! empty:
//!
//! ```text
//! id,q1_deg,…,q6_deg,x_mm,y_mm,z_mm,seat,pivot,length_mm
//! 0,10,…,5,412.3,-20.1,388.0,,,
//! 1,12,…,7,,,,0,,
//! 2,11,…,4,,,,,2,100.31
//! ```
//!
//! A row filling no kind or two is a one-line error naming the file and the line.
use super::*;
use crate::measure::PointKind;

/// Whether the columns hold more than one kind of measurement (a mixed file; touches of
/// several kinds, spheres and planes say, count as several).
pub(super) fn is_mixed(slots: &[(Slot, f64)]) -> bool {
    let has = |pred: &dyn Fn(&Slot) -> bool| slots.iter().any(|(s, _)| pred(s));
    let touched: std::collections::BTreeSet<PointKind> = slots
        .iter()
        .filter_map(|(s, _)| if let Slot::Touched(k) = s { Some(*k) } else { None })
        .collect();
    let kinds = [
        has(&|s| matches!(s, Slot::Pos(_) | Slot::Quat(_) | Slot::Rpy(_) | Slot::Reflector(..))),
        has(&|s| matches!(s, Slot::Seat)),
        has(&|s| matches!(s, Slot::Pivot | Slot::Length | Slot::Reading)),
        touched.is_empty() && has(&|s| matches!(s, Slot::Size | Slot::Probe)),
    ];
    kinds.iter().filter(|k| **k).count() + touched.len() > 1
}

/// Whether every row of `measurements` is a touch (of any artifact kind): such a set is
/// [`MeasurementFormat::Touch`] even when it mixes spheres, planes and a cube.
pub(super) fn touches_only(measurements: &[Measurement]) -> bool {
    measurements.iter().all(|m| matches!(m.obs, Observation::Touch(_)))
}

/// The columns of a mixed file checked: each kind's complete (x,y,z together, a pivot with a
/// length column), no reflector columns (a mixed file's tracker rows are positions or poses).
pub(super) fn check_columns(table: &Table, slots: &[(Slot, f64)]) -> Result<MeasurementFormat, IoError> {
    let has = |pred: &dyn Fn(&Slot) -> bool| slots.iter().filter(|(s, _)| pred(s)).count();
    let at_header = |message: String| IoError::AtLine {
        path: table.path.clone(),
        line: 1,
        message,
    };
    if has(&|s| matches!(s, Slot::Reflector(..))) > 0 {
        return Err(at_header(
            "a file mixing kinds takes tracker rows as x_mm,y_mm,z_mm (+ qw,qx,qy,qz or roll,pitch,yaw), not reflector columns".into(),
        ));
    }
    let tracker = has(&|s| matches!(s, Slot::Pos(_) | Slot::Quat(_) | Slot::Rpy(_)));
    if tracker > 0 && has(&|s| matches!(s, Slot::Pos(_))) < 3 {
        return Err(at_header("tracker columns need x_mm, y_mm and z_mm".into()));
    }
    let (pivot, lengths) = (
        has(&|s| matches!(s, Slot::Pivot)),
        has(&|s| matches!(s, Slot::Length | Slot::Reading)),
    );
    if (pivot > 0) != (lengths > 0) {
        return Err(at_header(
            "distance rows need 'pivot' and a length column (length_mm or reading_mm)".into(),
        ));
    }
    let touched = has(&|s| matches!(s, Slot::Touched(_)));
    if touched > 0 && has(&|s| matches!(s, Slot::Probe)) != 1 {
        return Err(at_header(
            "touch rows need one 'probe_radius_mm' column: the radius of the probe's tip ball in mm (0 for a pointed tip)".into(),
        ));
    }
    for (touch, size) in [("sphere", "sphere_diameter"), ("face", "cube_edge")] {
        let with = |name: &str| table.columns.iter().any(|c| columns::split_unit(c).0 == name);
        if with(touch) && !with(size) {
            return Err(at_header(format!("'{touch}' touches need a '{size}_mm' column (mm)")));
        }
    }
    // Touches of several kinds and nothing else: touch data.
    if tracker + has(&|s| matches!(s, Slot::Seat)) + pivot + lengths == 0 {
        return Ok(MeasurementFormat::Touch);
    }
    Ok(MeasurementFormat::Mixed)
}

/// The observation of one row of a mixed file (values in mm / rad, empty cells NaN).
pub(super) fn observation(
    path: &Path,
    line: usize,
    slots: &[(Slot, f64)],
    columns: &[String],
    row: &[f64],
) -> Result<Observation, IoError> {
    let at = |message: String| IoError::AtLine {
        path: path.to_path_buf(),
        line,
        message,
    };
    let (mut p, mut quat, mut rpy) = ([f64::NAN; 3], [f64::NAN; 4], [f64::NAN; 3]);
    let (mut seat, mut pivot, mut length, mut relative) = (None, None, None, false);
    // A touch: the artifact's kind and number; its size and the probe's radius by column name.
    let (mut touch, mut sizes, mut probe) = (Vec::new(), Vec::new(), None);
    for (((slot, f), v), col) in slots.iter().zip(row).zip(columns) {
        if v.is_nan() {
            continue;
        }
        match *slot {
            Slot::Pos(i) => p[i] = v * f,
            Slot::Quat(i) => quat[i] = *v,
            Slot::Rpy(i) => rpy[i] = v * f,
            Slot::Seat => seat = Some(columns::point_number(path, line, col, *v)?),
            Slot::Pivot => pivot = Some(columns::point_number(path, line, col, *v)?),
            Slot::Length => length = Some(v * f),
            Slot::Reading => (length, relative) = (Some(v * f), true),
            Slot::Touched(k) => touch.push((k, columns::point_number(path, line, col, *v)?)),
            Slot::Size => sizes.push((columns::split_unit(col).0, v * f)),
            Slot::Probe => probe = Some(v * f),
            _ => {}
        }
    }
    let filled = |v: &[f64]| v.iter().filter(|x| !x.is_nan()).count();
    let tracker = filled(&p) + filled(&quat) + filled(&rpy) > 0;
    let distance = pivot.is_some() || length.is_some();
    let kinds: Vec<&str> = [
        (tracker, "tracker (x,y,z)"),
        (seat.is_some(), "seat"),
        (distance, "distance (pivot, length)"),
        (!touch.is_empty(), "a touch (sphere, plane or face)"),
    ]
    .iter()
    .filter(|k| k.0)
    .map(|k| k.1)
    .collect();
    match kinds.len() {
        0 => {
            return Err(at(
                "the row fills no measurement: give one kind per row (tracker x,y,z, a seat, a pivot and its length, or a touch)".into(),
            ))
        }
        1 => {}
        _ => {
            return Err(at(format!(
                "the row fills {}: give one kind per row (leave the other kinds' cells empty)",
                kinds.join(" and ")
            )))
        }
    }
    if let Some(s) = seat {
        return Ok(Observation::Seat(s));
    }
    if let Some(&(kind, point)) = touch.first() {
        if touch.len() > 1 {
            return Err(at("the row fills two touch columns (sphere, plane, face): one touch per row".into()));
        }
        let probe = probe.ok_or_else(|| at("a touch without its probe radius (fill probe_radius_mm)".into()))?;
        let wanted = match kind {
            PointKind::Sphere => Some("sphere_diameter"),
            PointKind::Cube => Some("cube_edge"),
            _ => None,
        };
        let size = match wanted {
            Some(name) => sizes
                .iter()
                .find(|(n, _)| *n == name)
                .map(|s| s.1)
                .ok_or_else(|| at(format!("a touch without its size (fill {name}_mm)")))?,
            None => f64::NAN,
        };
        return Ok(columns::touch(kind, point, size, probe));
    }
    if distance {
        return match (pivot, length) {
            (Some(pivot), Some(length)) => Ok(Observation::Distance { pivot, length, relative }),
            (None, _) => Err(at("a length without its pivot (fill 'pivot')".into())),
            _ => Err(at("a pivot without its length (fill length_mm or reading_mm)".into())),
        };
    }
    if filled(&p) < 3 {
        return Err(at("x_mm,y_mm,z_mm: give all three".into()));
    }
    let t = Translation3::new(p[0], p[1], p[2]);
    match (filled(&quat), filled(&rpy)) {
        (0, 0) => Ok(Observation::Position(t.vector)),
        (4, 0) => {
            let qn = Quaternion::new(quat[0], quat[1], quat[2], quat[3]);
            if (qn.norm() - 1.0).abs() > 1e-3 {
                return Err(at(format!("qw,qx,qy,qz: not a unit quaternion (norm {:.6})", qn.norm())));
            }
            Ok(Observation::Pose(Pose::from_parts(t, UnitQuaternion::from_quaternion(qn))))
        }
        (0, 3) => Ok(Observation::Pose(Pose::from_parts(
            t,
            UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
        ))),
        _ => Err(at(
            "the orientation: give all of qw,qx,qy,qz or of roll,pitch,yaw, or none (a position)".into(),
        )),
    }
}

/// Whether `measurements` need a mixed file: more than one kind, lengths and readings, or
/// touches of several artifact kinds (their columns differ).
pub(super) fn needs_mixed(measurements: &[Measurement]) -> bool {
    use crate::measure::Touch;
    let kind = |m: &Measurement| match &m.obs {
        Observation::Pose(_) | Observation::Position(_) | Observation::Points(_) => 0,
        Observation::Seat(_) => 1,
        Observation::Distance { relative: false, .. } => 2,
        Observation::Distance { relative: true, .. } => 3,
        Observation::Touch(Touch::Sphere { .. }) => 4,
        Observation::Touch(Touch::Plane { .. }) => 5,
        Observation::Touch(Touch::Face { .. }) => 6,
    };
    measurements.windows(2).any(|w| kind(&w[0]) != kind(&w[1]))
}

/// The measurement header and cells of a mixed file's rows: tracker `x_mm,y_mm,z_mm` (+
/// `qw,qx,qy,qz` when a row is a pose), `seat`, `pivot` with `length_mm` and/or `reading_mm`,
/// each only when some row uses it; a row's other cells empty (NaN, written empty).
pub(super) fn cells(path: &Path, measurements: &[Measurement]) -> Result<(Vec<String>, Vec<Vec<f64>>), IoError> {
    let any = |f: &dyn Fn(&Observation) -> bool| measurements.iter().any(|m| f(&m.obs));
    let pose = any(&|o| matches!(o, Observation::Pose(_)));
    let tracker = pose || any(&|o| matches!(o, Observation::Position(_)));
    let seat = any(&|o| matches!(o, Observation::Seat(_)));
    let length = any(&|o| matches!(o, Observation::Distance { relative: false, .. }));
    let reading = any(&|o| matches!(o, Observation::Distance { relative: true, .. }));
    let mut header: Vec<String> = Vec::new();
    let mut push = |on: bool, names: &[&str]| {
        if on {
            header.extend(names.iter().map(|s| s.to_string()));
        }
    };
    push(tracker, &["x_mm", "y_mm", "z_mm"]);
    push(pose, &["qw", "qx", "qy", "qz"]);
    push(seat, &["seat"]);
    push(length || reading, &["pivot"]);
    push(length, &["length_mm"]);
    push(reading, &["reading_mm"]);
    let touch = |f: &dyn Fn(&crate::measure::Touch) -> bool| any(&|o| matches!(o, Observation::Touch(t) if f(t)));
    use crate::measure::Touch;
    push(touch(&|t| matches!(t, Touch::Sphere { .. })), &["sphere", "sphere_diameter_mm"]);
    push(touch(&|t| matches!(t, Touch::Plane { .. })), &["plane"]);
    push(touch(&|t| matches!(t, Touch::Face { .. })), &["face", "cube_edge_mm"]);
    push(touch(&|_| true), &["probe_radius_mm"]);
    let col = |name: &str| header.iter().position(|h| h == name).expect("a column of the header");
    let mut rows = Vec::with_capacity(measurements.len());
    for (k, m) in measurements.iter().enumerate() {
        let mut row = vec![f64::NAN; header.len()];
        match &m.obs {
            Observation::Pose(t) => {
                let (v, q) = (t.translation.vector, t.rotation.quaternion());
                for (c, x) in ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"]
                    .iter()
                    .zip([v.x, v.y, v.z, q.w, q.i, q.j, q.k])
                {
                    row[col(c)] = x;
                }
            }
            Observation::Position(v) => {
                for (c, x) in ["x_mm", "y_mm", "z_mm"].iter().zip([v.x, v.y, v.z]) {
                    row[col(c)] = x;
                }
            }
            Observation::Seat(s) => row[col("seat")] = *s as f64,
            Observation::Distance { pivot, length, relative } => {
                row[col("pivot")] = *pivot as f64;
                row[col(if *relative { "reading_mm" } else { "length_mm" })] = *length;
            }
            Observation::Points(_) => {
                return Err(IoError::Invalid {
                    path: path.to_path_buf(),
                    message: format!("pose {k}: point-set observations are not written to a file mixing kinds"),
                })
            }
            Observation::Touch(t) => {
                for (c, x) in columns::touch_columns(t).iter().zip(columns::touch_values(t)) {
                    row[col(c)] = x;
                }
            }
        }
        rows.push(row);
    }
    Ok((header, rows))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::table::parse_table_with_gaps;

    fn inputs() -> Vec<InputSpec> {
        vec![InputSpec {
            name: "q1".into(),
            unit: Unit::Angle,
            limits: None,
            approach_of: None,
            observed: false,
        }]
    }

    fn read(text: &str) -> Result<DataSet, String> {
        let t = parse_table_with_gaps(Path::new("m.csv"), text).map_err(|e| e.to_string())?;
        data_from_table(&t, &inputs(), InputColumns::Required).map_err(|e| e.to_string())
    }

    #[test]
    fn a_mixed_file_reads_each_rows_kind_and_writes_back() {
        let d = read("id,q1_deg,x_mm,y_mm,z_mm,seat,pivot,length_mm\n0,10,1,2,3,,,\n1,20,,,,4,,\n2,30,,,,,7,100.5\n").unwrap();
        assert_eq!(d.format, MeasurementFormat::Mixed);
        let obs: Vec<&Observation> = d.measurements.iter().map(|m| &m.obs).collect();
        assert_eq!(*obs[0], Observation::Position(Vector3::new(1.0, 2.0, 3.0)));
        assert_eq!(*obs[1], Observation::Seat(4));
        assert_eq!(
            *obs[2],
            Observation::Distance {
                pivot: 7,
                length: 100.5,
                relative: false
            }
        );
        // Poses and readings too, written and read back unchanged.
        let mut ms = d.measurements.clone();
        ms.push(Measurement {
            q: vec![0.5],
            obs: Observation::Pose(crate::se3::pose_from_parts(
                Vector3::new(4.0, 5.0, 6.0),
                Vector3::new(0.1, 0.2, 0.3),
            )),
            joints: Vec::new(),
        });
        ms.push(Measurement {
            q: vec![0.6],
            obs: Observation::Distance {
                pivot: 8,
                length: 12.25,
                relative: true,
            },
            joints: Vec::new(),
        });
        let text = data_text(Path::new("m.csv"), &inputs(), &[0, 1, 2, 3, 4], &ms, None).unwrap();
        assert!(
            text.starts_with("id,q1_deg,x_mm,y_mm,z_mm,qw,qx,qy,qz,seat,pivot,length_mm,reading_mm\n"),
            "{text}"
        );
        assert!(text.contains("\n1,20,,,,,,,,4,,,\n"), "{text}");
        let back = read(&text).unwrap();
        assert_eq!(back.format, MeasurementFormat::Mixed);
        for (a, b) in back.measurements.iter().zip(&ms) {
            assert!((a.q[0] - b.q[0]).abs() < 1e-12);
            match (&a.obs, &b.obs) {
                (Observation::Pose(x), Observation::Pose(y)) => assert!((x.to_homogeneous() - y.to_homogeneous()).norm() < 1e-12),
                (x, y) => assert_eq!(x, y),
            }
        }
    }

    #[test]
    fn touches_mix_with_tracker_rows_and_write_back() {
        use crate::measure::Touch;
        let d = read("id,q1_deg,x_mm,y_mm,z_mm,sphere,sphere_diameter_mm,plane,face,cube_edge_mm,probe_radius_mm\n0,10,1,2,3,,,,,,\n1,20,,,,2,25.4,,,,1.5\n2,30,,,,,,3,,,1.5\n3,40,,,,,,,5,50,1.5\n").unwrap();
        assert_eq!(d.format, MeasurementFormat::Mixed);
        let obs: Vec<&Observation> = d.measurements.iter().map(|m| &m.obs).collect();
        assert_eq!(*obs[0], Observation::Position(Vector3::new(1.0, 2.0, 3.0)));
        assert_eq!(
            *obs[1],
            Observation::Touch(Touch::Sphere {
                sphere: 2,
                diameter: 25.4,
                probe: 1.5
            })
        );
        assert_eq!(*obs[2], Observation::Touch(Touch::Plane { plane: 3, probe: 1.5 }));
        assert_eq!(
            *obs[3],
            Observation::Touch(Touch::Face {
                face: 5,
                edge: 50.0,
                probe: 1.5
            })
        );
        let text = data_text(Path::new("m.csv"), &inputs(), &[0, 1, 2, 3], &d.measurements, None).unwrap();
        let back = read(&text).unwrap();
        assert_eq!(back.measurements.iter().map(|m| &m.obs).collect::<Vec<_>>(), obs, "{text}");
        // A touch without its probe radius or its size, and two touches in one row: one line each.
        let e = read("q1_deg,x_mm,y_mm,z_mm,plane\n10,1,2,3,\n20,,,,0\n").unwrap_err();
        assert!(e.contains("probe_radius_mm") && !e.contains('\n'), "{e}");
        let e = read("q1_deg,x_mm,y_mm,z_mm,sphere,probe_radius_mm\n10,1,2,3,,\n").unwrap_err();
        assert!(e.contains("sphere_diameter_mm"), "{e}");
        let e = read("q1_deg,x_mm,y_mm,z_mm,sphere,sphere_diameter_mm,plane,probe_radius_mm\n10,,,,1,25,2,1\n").unwrap_err();
        assert!(e.contains("m.csv:2:") && e.contains("two touch columns"), "{e}");
    }

    #[test]
    fn a_row_of_no_kind_or_two_is_a_one_line_error() {
        let e = read("q1_deg,x_mm,y_mm,z_mm,seat\n10,1,2,3,\n20,1,2,3,4\n").unwrap_err();
        assert!(e.contains("m.csv:3:") && e.contains("tracker (x,y,z) and seat"), "{e}");
        assert!(!e.contains('\n'));
        let e = read("q1_deg,x_mm,y_mm,z_mm,seat\n10,,,,\n").unwrap_err();
        assert!(e.contains("m.csv:2:") && e.contains("fills no measurement"), "{e}");
        let e = read("q1_deg,x_mm,y_mm,z_mm,seat,pivot,length_mm\n10,,,,,3,\n").unwrap_err();
        assert!(e.contains("a pivot without its length"), "{e}");
        let e = read("q1_deg,x_mm,y_mm,seat\n10,1,2,\n").unwrap_err();
        assert!(e.contains("x_mm, y_mm and z_mm"), "{e}");
    }
}
