//! Writing data files: headers, input values in file units, whole files written atomically.
use super::*;

/// Header names of the input columns: angles in degrees, lengths in mm.
pub fn input_headers(inputs: &[InputSpec]) -> Vec<String> {
    inputs.iter().map(header_of).collect()
}

/// The column header of one input as kinecal writes it: `<name>_deg`, `<name>_mm`, or the bare
/// name of a dimensionless input (an approach direction).
pub fn header_of(i: &InputSpec) -> String {
    match i.unit {
        Unit::Angle => format!("{}_deg", i.name),
        Unit::Dimensionless => i.name.clone(),
        Unit::Length => format!("{}_mm", i.name),
    }
}

/// Input values converted for [`input_headers`] (rad → deg, mm stays).
pub fn input_values_for_file(inputs: &[InputSpec], q: &[f64]) -> Vec<f64> {
    inputs
        .iter()
        .zip(q)
        .map(|(i, v)| if i.unit == Unit::Angle { v.to_degrees() } else { *v })
        .collect()
}

/// Write a data file: `id`, the inputs (deg / mm) when `q` is not empty, and the observation
/// (positions in mm, orientations as a quaternion). Reflector data is written as the three
/// reflector centres `reflectors[k]` of each row when given.
pub fn write_data(
    path: &Path,
    inputs: &[InputSpec],
    ids: &[i64],
    measurements: &[Measurement],
    reflectors: Option<&[[Vector3<f64>; 3]]>,
) -> Result<(), IoError> {
    let text = data_text(path, inputs, ids, measurements, reflectors)?;
    crate::io::write_atomic(path, text.as_bytes())
}

/// The text [`write_data`] writes (`path` is only used in messages).
pub fn data_text(
    path: &Path,
    inputs: &[InputSpec],
    ids: &[i64],
    measurements: &[Measurement],
    reflectors: Option<&[[Vector3<f64>; 3]]>,
) -> Result<String, IoError> {
    let mut header = vec!["id".to_string()];
    // `inputs` may end with observed joints' columns (a model's data columns): written when
    // the measurements hold their readings.
    let (inputs, observed) = split_observed(inputs);
    let with_inputs = measurements.first().is_some_and(|m| !m.q.is_empty());
    if with_inputs {
        header.extend(input_headers(inputs));
    }
    let with_joints = !observed.is_empty() && measurements.first().is_some_and(|m| m.joints.len() == observed.len());
    if with_joints {
        header.extend(input_headers(observed));
    }
    let pose = matches!(measurements.first().map(|m| &m.obs), Some(Observation::Pose(_)));
    let first = measurements.first().map(|m| &m.obs);
    // Rows of several kinds: one file, each row filling its kind's cells.
    let mixed = if reflectors.is_none() && super::mixed::needs_mixed(measurements) {
        let (h, cells) = super::mixed::cells(path, measurements)?;
        header.extend(h);
        Some(cells)
    } else {
        None
    };
    if mixed.is_some() {
    } else if let Some(Observation::Seat(_)) = first {
        header.push("seat".into());
    } else if let Some(Observation::Distance { relative, .. }) = first {
        header.extend(["pivot", if *relative { "reading_mm" } else { "length_mm" }].map(String::from));
    } else if let Some(Observation::Touch(t)) = first {
        header.extend(columns::touch_columns(t).into_iter().map(String::from));
    } else if reflectors.is_some() {
        for r in 1..=3 {
            for a in ["x", "y", "z"] {
                header.push(format!("m{r}{a}_mm"));
            }
        }
    } else {
        header.extend(["x_mm", "y_mm", "z_mm"].map(String::from));
        if pose {
            header.extend(["qw", "qx", "qy", "qz"].map(String::from));
        }
    }
    let mut rows = Vec::with_capacity(measurements.len());
    for (k, m) in measurements.iter().enumerate() {
        let mut row = vec![ids.get(k).copied().unwrap_or(k as i64) as f64];
        if with_inputs {
            row.extend(input_values_for_file(inputs, &m.q));
        }
        if with_joints {
            if m.joints.len() != observed.len() {
                return Err(IoError::Invalid {
                    path: path.to_path_buf(),
                    message: format!(
                        "pose {k}: {} observed-joint readings, the first pose has {}",
                        m.joints.len(),
                        observed.len()
                    ),
                });
            }
            row.extend(input_values_for_file(observed, &m.joints));
        }
        if let Some(cells) = &mixed {
            row.extend(&cells[k]);
            rows.push(row);
            continue;
        }
        match (reflectors, &m.obs) {
            (Some(r), _) => row.extend(r[k].iter().flat_map(|v| [v.x, v.y, v.z])),
            (None, Observation::Pose(t)) => {
                let v = t.translation.vector;
                let q = t.rotation.quaternion();
                row.extend([v.x, v.y, v.z, q.w, q.i, q.j, q.k]);
            }
            (None, Observation::Position(v)) => row.extend([v.x, v.y, v.z]),
            (None, Observation::Seat(s)) if matches!(first, Some(Observation::Seat(_))) => row.push(*s as f64),
            (None, Observation::Distance { pivot, length, relative }) if matches!(first, Some(Observation::Distance { relative: r, .. }) if r == relative) => {
                row.extend([*pivot as f64, *length])
            }
            (None, Observation::Touch(t))
                if first.is_some_and(|f| matches!(f, Observation::Touch(u) if columns::touch_columns(u) == columns::touch_columns(t))) =>
            {
                row.extend(columns::touch_values(t))
            }
            (None, Observation::Seat(_) | Observation::Distance { .. } | Observation::Touch(_)) => {
                return Err(IoError::Invalid {
                    path: path.to_path_buf(),
                    message: format!(
                    "pose {k}: one data file holds one kind of measurement (seat rows, length rows and reading rows go to separate files)"
                ),
                })
            }
            (None, Observation::Points(_)) => {
                return Err(IoError::Invalid {
                    path: path.to_path_buf(),
                    message: "point-set observations are written as three-reflector columns: pass the reflector centres".into(),
                })
            }
        }
        rows.push(row);
    }
    Ok(csv_text(&header, &rows))
}

/// Write a numeric CSV with a header; values in full precision (integers without decimals).
/// The file is written whole or not at all ([`crate::io::write_atomic`]).
pub fn write_csv(path: &Path, header: &[String], rows: &[Vec<f64>]) -> Result<(), IoError> {
    crate::io::write_atomic(path, csv_text(header, rows).as_bytes())
}

/// The text of [`write_csv`].
pub fn csv_text(header: &[String], rows: &[Vec<f64>]) -> String {
    let mut out = header.join(",");
    out.push('\n');
    for row in rows {
        let fields: Vec<String> = row
            .iter()
            .map(|v| {
                // An empty cell: a mixed file's other kinds ([`super::mixed`]).
                if v.is_nan() {
                    String::new()
                } else if v.fract() == 0.0 && v.abs() < 1e15 {
                    format!("{}", *v as i64)
                } else {
                    format!("{v}")
                }
            })
            .collect();
        let _ = writeln!(out, "{}", fields.join(","));
    }
    out
}
