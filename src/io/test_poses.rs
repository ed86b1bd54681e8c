//! ISO 9283 test files ([`crate::assess`]): the commanded test poses and the attained poses.
//!
//! Commanded: `pose,x_mm,y_mm,z_mm` and optionally `roll_deg,pitch_deg,yaw_deg` (the rotations
//! `a, b, c` about x, y, z; each column may be `_rad` instead), one row per test pose. Attained: `pose,cycle,x_mm,y_mm,z_mm` and
//! optionally the same three angles, one row per pose reached; both in the same frame (the
//! robot's base, as a registered tracker gives them). [`attained_text`] writes an attained file,
//! [`test_poses_text`] the test poses of `kinecal plan --iso9283`; [`read_circle`] reads an
//! ISO 230-4 circular test.
use super::table::{read_table, Table};
use super::IoError;
use crate::assess::{Attained, Iso9283Plan, TestPose};
use crate::model::kind::InputSpec;
use nalgebra::Vector3;
use std::path::Path;

const ANGLES: [&str; 3] = ["roll", "pitch", "yaw"];

/// Column names that say an orientation in a form these files do not hold (a quaternion, other
/// angle names), refused rather than silently left out.
const OTHER_ORIENTATION: [&str; 12] = ["qw", "qx", "qy", "qz", "rx", "ry", "rz", "a", "b", "c", "w", "p"];

/// The angle columns of a table, each `roll|pitch|yaw` with `_deg` or `_rad` (read as
/// degrees), with the factor to degrees: all three, or none. Orientation columns of any other
/// form are an error naming them.
fn angle_columns(t: &Table) -> Result<Option<[(usize, f64); 3]>, IoError> {
    let invalid = |message: String| IoError::Invalid {
        path: t.path.clone(),
        message,
    };
    let mut found: [Option<(usize, f64)>; 3] = [None; 3];
    for (k, name) in ANGLES.iter().enumerate() {
        for (suffix, factor) in [("deg", 1.0), ("rad", 180.0 / std::f64::consts::PI)] {
            if let Some(i) = t.columns.iter().position(|c| *c == format!("{name}_{suffix}")) {
                if found[k].is_some() {
                    return Err(invalid(format!("{name} is given twice ({name}_deg and {name}_rad): keep one")));
                }
                found[k] = Some((i, factor));
            }
        }
    }
    let other: Vec<&str> = t
        .columns
        .iter()
        .map(String::as_str)
        .filter(|c| {
            let lower = c.to_ascii_lowercase();
            let stem = lower.trim_end_matches("_deg").trim_end_matches("_rad");
            let read = ANGLES.iter().any(|a| [format!("{a}_deg"), format!("{a}_rad")].contains(&lower));
            !read && (OTHER_ORIENTATION.contains(&stem) || ANGLES.contains(&stem))
        })
        .collect();
    if !other.is_empty() {
        return Err(invalid(format!(
            "orientation columns {} are not read: the orientation is roll_deg, pitch_deg, yaw_deg (or _rad; R = Rz(yaw)·Ry(pitch)·Rx(roll)); convert them, or leave them out to assess positions only",
            other.join(", ")
        )));
    }
    match found.iter().filter(|f| f.is_some()).count() {
        0 => Ok(None),
        3 => Ok(Some([
            found[0].unwrap_or_default(),
            found[1].unwrap_or_default(),
            found[2].unwrap_or_default(),
        ])),
        _ => Err(invalid(format!(
            "the orientation needs all three columns roll, pitch, yaw (each _deg or _rad), or none of them; found {}",
            found
                .iter()
                .flatten()
                .map(|(i, _)| t.columns[*i].as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}

/// An integer id column's value at a row, or an error naming the line.
fn id(t: &Table, row: usize, col: usize, name: &str) -> Result<i64, IoError> {
    let v = t.rows[row][col];
    if v.fract() != 0.0 || v.abs() > 1e15 {
        return Err(IoError::AtLine {
            path: t.path.clone(),
            line: t.lines[row],
            message: format!("column '{name}': {v} is not a whole number"),
        });
    }
    Ok(v as i64)
}

/// Position and angles of a row.
fn pose_of(t: &Table, row: usize, xyz: [usize; 3], angles: Option<[(usize, f64); 3]>) -> (Vector3<f64>, Option<[f64; 3]>) {
    let r = &t.rows[row];
    (
        Vector3::new(r[xyz[0]], r[xyz[1]], r[xyz[2]]),
        angles.map(|a| a.map(|(i, f)| r[i] * f)),
    )
}

/// Read the commanded test poses. The test-pose column is `pose`, or `id`: a targets file of
/// `kinecal compensate` (`id,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg`) is a commanded file.
pub fn read_commanded(path: &Path) -> Result<Vec<TestPose>, IoError> {
    let t = read_table(path)?;
    let pose = match t.columns.iter().position(|c| c == "id") {
        Some(i) if !t.columns.iter().any(|c| c == "pose") => i,
        _ => t.column("pose")?,
    };
    let xyz = [t.column("x_mm")?, t.column("y_mm")?, t.column("z_mm")?];
    let angles = angle_columns(&t)?;
    (0..t.len())
        .map(|r| {
            let (position, angles) = pose_of(&t, r, xyz, angles);
            Ok(TestPose {
                pose: id(&t, r, pose, "pose")?,
                position,
                angles,
            })
        })
        .collect()
}

/// Read the attained poses.
pub fn read_attained(path: &Path) -> Result<Vec<Attained>, IoError> {
    let t = read_table(path)?;
    let (pose, cycle) = (t.column("pose")?, t.column("cycle")?);
    let xyz = [t.column("x_mm")?, t.column("y_mm")?, t.column("z_mm")?];
    let angles = angle_columns(&t)?;
    (0..t.len())
        .map(|r| {
            let (position, angles) = pose_of(&t, r, xyz, angles);
            Ok(Attained {
                pose: id(&t, r, pose, "pose")?,
                cycle: id(&t, r, cycle, "cycle")?,
                position,
                angles,
                line: t.lines[r],
            })
        })
        .collect()
}

/// An attained file (the columns [`read_attained`] reads, with the three angles), full
/// precision.
pub fn attained_text(rows: &[Attained]) -> String {
    let mut out = String::from("pose,cycle,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg\n");
    for a in rows {
        let [r, p, y] = a.angles.unwrap_or([0.0; 3]);
        out.push_str(&format!(
            "{},{},{},{},{},{r},{p},{y}\n",
            a.pose, a.cycle, a.position.x, a.position.y, a.position.z
        ));
    }
    out
}

/// The test poses of an ISO 9283 plan with their commands, one row per test pose:
/// `id,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg` and the input columns (degrees for angles, mm
/// for lengths). `kinecal assess --commanded` reads it as the commanded poses, `kinecal simulate
/// --at` as the commands, `kinecal compensate` as targets seeded with these commands.
pub fn test_poses_text(plan: &Iso9283Plan, inputs: &[InputSpec]) -> String {
    let mut header: Vec<String> = ["id", "x_mm", "y_mm", "z_mm", "roll_deg", "pitch_deg", "yaw_deg"]
        .map(String::from)
        .to_vec();
    header.extend(super::data_file::input_headers(inputs));
    let rows: Vec<Vec<f64>> = plan
        .poses
        .iter()
        .zip(&plan.commands)
        .map(|(p, q)| {
            let mut row = vec![p.pose as f64, p.position.x, p.position.y, p.position.z];
            row.extend(p.angles.unwrap_or([0.0; 3]));
            row.extend(super::data_file::input_values_for_file(inputs, q));
            row
        })
        .collect();
    super::data_file::csv_text(&header, &rows)
}

/// The measured points of an ISO 230-4 circular test ([`crate::assess::circle`]) in the plane's
/// coordinates about the nominal centre (mm). The file holds either ballbar readings, `angle_deg`
/// with `radius_mm` (the distance from the pivot) or `deviation_mm` (that distance less the
/// nominal `radius`), or measured points `x_mm,y_mm,z_mm` (a coordinate across the plane may be
/// left out), taken about `centre` in `plane`.
pub fn read_circle(path: &Path, plane: crate::assess::Plane, centre: &Vector3<f64>, radius: f64) -> Result<Vec<[f64; 2]>, IoError> {
    let t = read_table(path)?;
    let col = |n: &str| t.columns.iter().position(|c| c == n);
    if let Some(a) = col("angle_deg") {
        let (r, offset) = match (col("radius_mm"), col("deviation_mm")) {
            (Some(r), None) => (r, 0.0),
            (None, Some(d)) => (d, radius),
            _ => {
                return Err(IoError::Invalid {
                    path: t.path.clone(),
                    message: "ballbar readings: angle_deg with one of radius_mm or deviation_mm".into(),
                })
            }
        };
        let readings: Vec<[f64; 2]> = t.rows.iter().map(|row| [row[a], row[r] + offset]).collect();
        return Ok(crate::assess::circle::points_from_radii(&readings));
    }
    let xyz = ["x_mm", "y_mm", "z_mm"].map(col);
    let across = match plane {
        crate::assess::Plane::Xy => 2,
        crate::assess::Plane::Yz => 0,
        crate::assess::Plane::Zx => 1,
    };
    if (0..3).any(|k| k != across && xyz[k].is_none()) {
        return Err(IoError::Invalid {
            path: t.path.clone(),
            message: format!(
                "a circle file holds angle_deg with radius_mm or deviation_mm (ballbar readings), or the points' x_mm, y_mm, z_mm (columns: {})",
                t.columns.join(",")
            ),
        });
    }
    Ok(t.rows
        .iter()
        .map(|row| {
            let p = Vector3::from_fn(|k, _| xyz[k].map_or(centre[k], |c| row[c]));
            plane.coordinates(&(p - centre))
        })
        .collect())
}
