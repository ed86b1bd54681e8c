//! Unit tests of the data-file reader.
use super::*;
use crate::io::table::parse_table;

fn inputs() -> Vec<InputSpec> {
    vec![
        InputSpec {
            name: "q1".into(),
            unit: Unit::Angle,
            limits: None,
            approach_of: None,
            observed: false,
        },
        InputSpec {
            name: "d2".into(),
            unit: Unit::Length,
            limits: None,
            approach_of: None,
            observed: false,
        },
    ]
}

fn read(text: &str) -> Result<DataSet, String> {
    let t = parse_table(Path::new("d.csv"), text).map_err(|e| e.to_string())?;
    data_from_table(&t, &inputs(), InputColumns::Required).map_err(|e| e.to_string())
}

#[test]
fn reads_every_format_in_internal_units() {
    let d = read("q1_deg,d2_m,x_m,y_mm,z_mm\n90,0.5,1,2,3\n").unwrap();
    assert_eq!(d.format, MeasurementFormat::Position);
    assert!((d.measurements[0].q[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    assert_eq!(d.measurements[0].q[1], 500.0);
    assert_eq!(d.measurements[0].obs, Observation::Position(Vector3::new(1000.0, 2.0, 3.0)));
    let d = read("id,q1_rad,d2_mm,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg\n7,0,0,0,0,0,0,0,90\n").unwrap();
    assert_eq!(d.ids, vec![7]);
    let Observation::Pose(t) = &d.measurements[0].obs else { panic!() };
    assert!((t.rotation.angle() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    let d = read("q1_rad,d2_mm,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0,0,0,0,0,1,0,0,0\n").unwrap();
    assert_eq!(d.format, MeasurementFormat::PoseQuaternion);
    let d = read("q1_rad,d2_mm,m1x_mm,m1y_mm,m1z_mm,m2x_mm,m2y_mm,m2z_mm,m3x_mm,m3y_mm,m3z_mm\n0,0,0,60,0,40,-30,0,-40,-30,0\n").unwrap();
    let Observation::Pose(t) = &d.measurements[0].obs else { panic!() };
    assert!(t.rotation.angle() < 1e-12 && t.translation.vector.norm() < 1e-12);
}

#[test]
fn errors_name_file_line_and_column() {
    assert_eq!(
        read("q1_mm,d2_mm,x_mm,y_mm,z_mm\n").unwrap_err(),
        "d.csv:1: column 'q1_mm': unit 'mm' for the angular input 'q1' (use q1_deg or q1_rad)"
    );
    assert_eq!(
        read("q1,d2_mm,x_mm,y_mm,z_mm\n").unwrap_err(),
        "d.csv:1: column 'q1': no unit suffix for the angular input 'q1' (use q1_deg or q1_rad)"
    );
    assert!(read("q1_deg,d2_mm,x_mm,y_mm,z_mm,w\n")
        .unwrap_err()
        .starts_with("d.csv:1: unknown column 'w'"));
    assert!(read("q1_deg,x_mm,y_mm,z_mm\n")
        .unwrap_err()
        .starts_with("d.csv:1: missing column 'd2_mm'"));
    assert!(read("q1_deg,d2_mm,x_mm,y_mm\n")
        .unwrap_err()
        .starts_with("d.csv:1: missing column 'z_mm'"));
    assert_eq!(
        read("q1_deg,d2_mm,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0,0,0,0,0,2,0,0,0\n").unwrap_err(),
        "d.csv:2: qw,qx,qy,qz: not a unit quaternion (norm 2.000000)"
    );
}

#[test]
fn joins_an_inputs_file_and_a_measurement_file() {
    let dir = std::env::temp_dir().join(format!("kinecal-join-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (j, m) = (dir.join("j.csv"), dir.join("m.csv"));
    std::fs::write(&j, "id,q1_deg,d2_mm\n5,90,1\n6,0,2\n").unwrap();
    std::fs::write(&m, "id,x_mm,y_mm,z_mm\n5,1,2,3\n6,4,5,6\n").unwrap();
    let d = join_files(&j, &m, &inputs()).unwrap();
    assert_eq!(d.ids, vec![5, 6]);
    assert_eq!(d.measurements[1].q, vec![0.0, 2.0]);
    assert_eq!(d.measurements[1].obs, Observation::Position(Vector3::new(4.0, 5.0, 6.0)));
    let msg = |e: IoError| e.to_string().replace(&format!("{}/", dir.display()), "");
    std::fs::write(&m, "id,x_mm,y_mm,z_mm\n5,1,2,3\n").unwrap();
    assert_eq!(
        msg(join_files(&j, &m, &inputs()).unwrap_err()),
        "m.csv: 1 rows but j.csv has 2; every file must have one row per pose"
    );
    std::fs::write(&m, "id,x_mm,y_mm,z_mm\n5,1,2,3\n7,4,5,6\n").unwrap();
    assert_eq!(
        msg(join_files(&j, &m, &inputs()).unwrap_err()),
        "m.csv:3: pose index 7 where j.csv has 6"
    );
    std::fs::write(&m, "id,q1_deg,x_mm,y_mm,z_mm\n5,1,1,2,3\n6,1,4,5,6\n").unwrap();
    assert!(msg(join_files(&j, &m, &inputs()).unwrap_err()).starts_with("m.csv:1: unknown column 'q1_deg'"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn write_then_read_round_trips() {
    let dir = std::env::temp_dir().join(format!("kinecal-data-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("w.csv");
    let t = crate::se3::pose_from_parts(Vector3::new(1.5, -2.0, 3.25), Vector3::new(0.1, -0.2, 0.3));
    let m = vec![Measurement {
        joints: Vec::new(),
        q: vec![0.25, 12.5],
        obs: Observation::Pose(t),
    }];
    write_data(&path, &inputs(), &[3], &m, None).unwrap();
    let d = read_data(&path, &inputs(), InputColumns::Required).unwrap();
    assert_eq!(d.ids, vec![3]);
    assert!((d.measurements[0].q[0] - 0.25).abs() < 1e-15);
    let Observation::Pose(b) = &d.measurements[0].obs else { panic!() };
    assert!((b.to_homogeneous() - t.to_homogeneous()).abs().max() < 1e-14);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Observed joints' readings (`role = "observed"`): optional columns after the inputs, all of
/// them or none, written back as they were read.
#[test]
fn observed_joint_columns_are_optional_all_or_none_and_round_trip() {
    let mut cols = inputs();
    for (name, unit) in [("u1", Unit::Angle), ("x2", Unit::Length)] {
        cols.push(InputSpec {
            name: name.into(),
            unit,
            limits: None,
            approach_of: None,
            observed: true,
        });
    }
    let read = |text: &str| {
        let t = parse_table(Path::new("d.csv"), text).map_err(|e| e.to_string())?;
        data_from_table(&t, &cols, InputColumns::Required).map_err(|e| e.to_string())
    };
    let d = read("q1_deg,d2_mm,u1_deg,x2_m,x_mm,y_mm,z_mm\n90,5,45,0.002,1,2,3\n").unwrap();
    let m = &d.measurements[0];
    assert_eq!(m.q.len(), 2);
    assert!((m.joints[0] - std::f64::consts::FRAC_PI_4).abs() < 1e-15 && (m.joints[1] - 2.0).abs() < 1e-12);
    // Without them: no readings.
    let d = read("q1_deg,d2_mm,x_mm,y_mm,z_mm\n90,5,1,2,3\n").unwrap();
    assert!(d.measurements[0].joints.is_empty());
    // Some of them: an error naming the missing ones.
    let e = read("q1_deg,d2_mm,u1_deg,x_mm,y_mm,z_mm\n90,5,45,1,2,3\n").unwrap_err();
    assert_eq!(
        e,
        "d.csv:1: observed-joint columns missing: x2_mm (give every observed joint's reading, or none)"
    );
    // Written back with the readings, read again the same.
    let dir = std::env::temp_dir().join(format!("kinecal-observed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("o.csv");
    let d = read("q1_deg,d2_mm,u1_deg,x2_m,x_mm,y_mm,z_mm\n90,5,45,0.002,1,2,3\n").unwrap();
    write_data(&path, &cols, &d.ids, &d.measurements, None).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with("id,q1_deg,d2_mm,u1_deg,x2_mm,x_mm,y_mm,z_mm\n"), "{text}");
    let back = read_data(&path, &cols, InputColumns::Required).unwrap();
    assert!((back.measurements[0].joints[0] - d.measurements[0].joints[0]).abs() < 1e-15);
    assert!((back.measurements[0].joints[1] - 2.0).abs() < 1e-12);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Touch files (sphere, plane, cube face) written and read back give the same rows; a plane
/// touch with every value zero is a row, not a lost measurement; a touch file without the
/// probe's radius is a one-line error naming what is missing; touches of several kinds share a
/// file (each row one touch), and a row filling two is a one-line error.
#[test]
fn touch_files_round_trip_and_name_what_is_missing() {
    use crate::measure::Touch;
    for touches in [
        vec![
            Touch::Sphere {
                sphere: 0,
                diameter: 25.4,
                probe: 1.5,
            },
            Touch::Sphere {
                sphere: 2,
                diameter: 25.4,
                probe: 1.5,
            },
        ],
        vec![Touch::Plane { plane: 0, probe: 0.0 }, Touch::Plane { plane: 3, probe: 1.5 }],
        vec![
            Touch::Face {
                face: 0,
                edge: 50.0,
                probe: 1.5,
            },
            Touch::Face {
                face: 5,
                edge: 50.0,
                probe: 1.5,
            },
        ],
    ] {
        let rows: Vec<Measurement> = touches
            .iter()
            .map(|t| Measurement {
                q: vec![0.0, 0.0],
                obs: Observation::Touch(*t),
                joints: Vec::new(),
            })
            .collect();
        let text = data_text(Path::new("t.csv"), &inputs(), &[0, 1], &rows, None).unwrap();
        let back = read(&text).unwrap();
        assert_eq!((back.format, back.measurements), (MeasurementFormat::Touch, rows), "{text}");
    }
    let d = read("q1_deg,d2_mm,sphere,sphere_diameter_m,probe_radius_mm\n0,0,1,0.025,2\n").unwrap();
    assert_eq!(
        d.measurements[0].obs,
        Observation::Touch(Touch::Sphere {
            sphere: 1,
            diameter: 25.0,
            probe: 2.0
        })
    );
    let e = read("q1_deg,d2_mm,plane\n0,0,1\n").unwrap_err();
    assert!(e.starts_with("d.csv:1: plane touches need one 'probe_radius_mm' column"), "{e}");
    let e = read("q1_deg,d2_mm,face,probe_radius_mm\n0,0,1,2\n").unwrap_err();
    assert!(e.contains("face touches need one 'cube_edge_mm' column"), "{e}");
    // Touches of several kinds in one file: each row one touch, the other kinds' cells empty
    // (read as files are, empty cells allowed).
    let read = |text: &str| {
        let t = crate::io::table::parse_table_with_gaps(Path::new("d.csv"), text).map_err(|e| e.to_string())?;
        data_from_table(&t, &inputs(), InputColumns::Required).map_err(|e| e.to_string())
    };
    let d = read("q1_deg,d2_mm,plane,sphere,sphere_diameter_mm,probe_radius_mm\n0,0,1,,,2\n0,1,,3,25.4,1.5\n").unwrap();
    assert_eq!(d.format, MeasurementFormat::Touch);
    assert_eq!(d.measurements[0].obs, Observation::Touch(Touch::Plane { plane: 1, probe: 2.0 }));
    assert_eq!(
        d.measurements[1].obs,
        Observation::Touch(Touch::Sphere {
            sphere: 3,
            diameter: 25.4,
            probe: 1.5
        })
    );
    let text = data_text(Path::new("t.csv"), &inputs(), &[0, 1], &d.measurements, None).unwrap();
    let back = read(&text).unwrap();
    assert_eq!(
        (back.format, &back.measurements),
        (MeasurementFormat::Touch, &d.measurements),
        "{text}"
    );
    let e = read("q1_deg,d2_mm,plane,sphere,sphere_diameter_mm,probe_radius_mm\n0,0,1,3,25.4,2\n").unwrap_err();
    assert!(e.contains("d.csv:2:") && e.contains("two touch columns"), "{e}");
}

/// Limits: rows a little beyond them are kept and said; a column that fits them in the other
/// unit of its kind, or a value beyond them by more than half their range, is refused.
#[test]
fn rows_beyond_the_limits_are_kept_unless_a_mistake_explains_them() {
    let limited = || {
        let mut i = inputs();
        i[0].limits = Some((-100f64.to_radians(), 100f64.to_radians()));
        i[1].limits = Some((200.0, 400.0));
        i
    };
    let read = |text: &str| {
        let t = parse_table(Path::new("d.csv"), text).unwrap();
        data_from_table(&t, &limited(), InputColumns::Required).map_err(|e| e.to_string())
    };
    // 110° and 105° against ±100°: kept, one warning for q1 with its excess.
    let d = read("id,q1_deg,d2_mm,x_mm,y_mm,z_mm\n1,110,300,0,0,1\n2,50,300,0,0,1\n3,-105,300,0,0,1\n").unwrap();
    assert_eq!(d.measurements.len(), 3);
    assert_eq!(d.beyond_limits.len(), 1);
    let b = &d.beyond_limits[0];
    assert_eq!(
        (b.input.as_str(), b.rows, b.ids.clone(), b.unit.as_str()),
        ("q1", 2, vec![1, 3], "deg")
    );
    assert!((b.max_excess - 10.0).abs() < 1e-9 && (b.limits.1 - 100.0).abs() < 1e-9, "{b:?}");
    assert!(d.limit_warnings()[0].starts_with(
        "d.csv: q1: 2 rows beyond the model's limits [-100.0000, 100.0000] deg, by up to 10.0000 deg (0.1745 rad) (ids 1, 3)"
    ));
    // Metres in a millimetre column: they fit read in m.
    let e = read("q1_deg,d2_mm,x_mm,y_mm,z_mm\n0,0.3,0,0,1\n0,0.25,0,0,1\n").unwrap_err();
    assert!(
        e.starts_with("d.csv:2: d2: 0.3000 mm is outside the model's limits") && e.contains("read in m: check the column's unit"),
        "{e}"
    );
    // 300° against ±100°: beyond by more than half the range, and not radians.
    let e = read("q1_deg,d2_mm,x_mm,y_mm,z_mm\n300,300,0,0,1\n").unwrap_err();
    assert!(e.contains("more than half their range"), "{e}");
}
