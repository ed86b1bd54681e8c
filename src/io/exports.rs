//! Raw exports joined into one data file: a controller log of joint values and one tracker export
//! per reflector, matched by pose id ([`join_exports`]).
//!
//! | file | columns | unit |
//! |---|---|---|
//! | joints (controller log) | an id column (`idx` or `id`), then one column per input, in the model's input order (any names) | [`ExportFiles::angles`] for revolute inputs, [`ExportFiles::lengths`] for prismatic ones |
//! | reflector `k` (1 or 3 files) | an id column, then `x, y, z` (any names) | [`ExportFiles::lengths`] |
//! | reference reflectors (optional) | an id column, then `x, y, z` | [`ExportFiles::lengths`] |
//!
//! Rows are matched by id, not by position: a pose missing from a reflector file, or whose
//! reading is empty or exactly (0, 0, 0) (a lost beam), is dropped and listed with the reason.
//! Reference reflectors fixed on the robot's base or the floor do not enter the calibration: their
//! spread over the measurement says how stable the tracker stood ([`ReferenceStability`]).
use super::data_file::{data_from_table, input_headers, DataSet, InputColumns};
use super::model_file::{AngleUnit, InputSpec, LengthUnit};
use super::table::{read_table_with_gaps, Table};
use super::IoError;
use crate::params::Unit;
use nalgebra::Vector3;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A reference-reflector reading farther than this from its median is counted as failed (mm).
pub const REFERENCE_OUTLIER_MM: f64 = 1.0;

/// The files to join and their units.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportFiles {
    /// Controller log: id, then one column per input.
    pub joints: PathBuf,
    /// Unit of the angle columns of the controller log.
    pub angles: AngleUnit,
    /// Tool reflector exports: one (its position is measured) or three (their frame, or the three
    /// points).
    pub reflectors: Vec<PathBuf>,
    /// Fixed reference reflectors (tracker stability only).
    pub references: Vec<PathBuf>,
    /// Unit of the length columns of every file.
    pub lengths: LengthUnit,
}

/// How steady one reference reflector stayed.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ReferenceStability {
    /// The export file.
    pub path: PathBuf,
    /// Readings used (neither lost nor beyond [`REFERENCE_OUTLIER_MM`]).
    pub valid: usize,
    /// Readings lost (empty or zero) or beyond [`REFERENCE_OUTLIER_MM`] from the median.
    pub failed: usize,
    /// Largest distance of a valid reading from the median position (mm).
    pub max_deviation_mm: f64,
    /// RMS distance of the valid readings from the median position (mm).
    pub rms_deviation_mm: f64,
}

/// What [`join_exports`] produced.
#[derive(Debug, Clone, PartialEq)]
pub struct JoinedExports {
    /// The joined data set (ids from the controller log; values in mm and rad).
    pub data: DataSet,
    /// Poses dropped, with the reason (`(id, reason)`).
    pub dropped: Vec<(i64, String)>,
    /// One entry per reference file.
    pub references: Vec<ReferenceStability>,
}

/// One export: rows by id (value columns only), the file's line of each id.
struct Export {
    table: Table,
    by_id: HashMap<i64, usize>,
}

/// An export with an id column and then `values` value columns, or `also` when given (a
/// controller log with optional extra columns).
fn read_export(path: &Path, values: usize, also: Option<usize>, what: &str) -> Result<Export, IoError> {
    let table = read_table_with_gaps(path)?;
    let id_col = table.columns.iter().position(|c| {
        let c = c.trim().to_ascii_lowercase();
        c == "idx" || c == "id"
    });
    if id_col != Some(0) {
        return Err(IoError::Invalid {
            path: path.to_path_buf(),
            message: format!(
                "the first column must be the pose id, named 'idx' or 'id' (header: {}); then {values} {what} column(s)",
                table.columns.join(",")
            ),
        });
    }
    if table.columns.len() != values + 1 && also.is_none_or(|a| table.columns.len() != a + 1) {
        return Err(IoError::Invalid {
            path: path.to_path_buf(),
            message: format!(
                "{} columns after the id, expected {values} ({what}); header: {}",
                table.columns.len() - 1,
                table.columns.join(",")
            ),
        });
    }
    let mut by_id = HashMap::new();
    for (r, row) in table.rows.iter().enumerate() {
        let v = row[0];
        if !v.is_finite() || v.fract() != 0.0 {
            return Err(IoError::AtLine {
                path: path.to_path_buf(),
                line: table.lines[r],
                message: format!("id '{v}' is not an integer"),
            });
        }
        if let Some(first) = by_id.insert(v as i64, r) {
            return Err(IoError::AtLine {
                path: path.to_path_buf(),
                line: table.lines[r],
                message: format!("id {} appears twice (first on line {})", v as i64, table.lines[first]),
            });
        }
    }
    Ok(Export { table, by_id })
}

impl Export {
    /// The point of pose `id`: `Ok(None)` when the id is absent, `Err(line)` for a lost reading.
    fn point(&self, id: i64, to_mm: f64) -> Result<Option<Vector3<f64>>, usize> {
        let Some(&r) = self.by_id.get(&id) else { return Ok(None) };
        let row = &self.table.rows[r];
        let p = Vector3::new(row[1], row[2], row[3]) * to_mm;
        if p.iter().any(|v| !v.is_finite()) || p.iter().all(|v| *v == 0.0) {
            return Err(self.table.lines[r]);
        }
        Ok(Some(p))
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    if v.is_empty() {
        0.0
    } else {
        v[v.len() / 2]
    }
}

fn stability(path: &Path, points: &[Option<Vector3<f64>>]) -> ReferenceStability {
    let valid: Vec<Vector3<f64>> = points.iter().flatten().copied().collect();
    let med = Vector3::new(
        median(valid.iter().map(|p| p.x).collect()),
        median(valid.iter().map(|p| p.y).collect()),
        median(valid.iter().map(|p| p.z).collect()),
    );
    let near: Vec<f64> = valid
        .iter()
        .map(|p| (p - med).norm())
        .filter(|d| *d <= REFERENCE_OUTLIER_MM)
        .collect();
    ReferenceStability {
        path: path.to_path_buf(),
        valid: near.len(),
        failed: points.len() - near.len(),
        max_deviation_mm: near.iter().copied().fold(0.0, f64::max),
        rms_deviation_mm: (near.iter().map(|d| d * d).sum::<f64>() / near.len().max(1) as f64).sqrt(),
    }
}

/// Join the exports of `files` for a mechanism with `inputs` into one data set (see the module
/// docs). `out` names the data set (used in its messages). The joined set passes every check of
/// a data file (joint limits, duplicate ids); an empty join is an error.
///
/// `columns` are a model's data columns (its inputs, then its observed joints,
/// [`crate::io::model_file::ModelFile::data_columns`]): the controller log holds the inputs'
/// values and, optionally, the observed joints' readings after them.
pub fn join_exports(files: &ExportFiles, columns: &[InputSpec], out: &Path) -> Result<JoinedExports, IoError> {
    let (inputs, observed) = crate::io::data_file::split_observed(columns);
    if !matches!(files.reflectors.len(), 1 | 3) {
        return Err(IoError::Invalid {
            path: files.joints.clone(),
            message: format!(
                "give one reflector export (its position is measured) or three (the tool frame), not {}",
                files.reflectors.len()
            ),
        });
    }
    // The controller log holds the joint values; approach directions (a model with lost motion)
    // come from its row order, the motion order, lost beams included.
    let measured_inputs = inputs.iter().filter(|i| i.approach_of.is_none()).count();
    // With the observed joints' readings when the log has their columns too.
    let also = (!observed.is_empty()).then_some(measured_inputs + observed.len());
    let what = if observed.is_empty() {
        "joint values, in the model's input order".to_string()
    } else {
        format!(
            "joint values, in the model's input order, optionally followed by the readings of its observed joints {}",
            observed.iter().map(|o| o.name.as_str()).collect::<Vec<_>>().join(", ")
        )
    };
    let joints = read_export(&files.joints, measured_inputs, also, &what)?;
    let with_observed = also == Some(joints.table.columns.len() - 1);
    let mut with_approach: Vec<Vec<f64>> = joints
        .table
        .rows
        .iter()
        .filter(|row| row[1..].iter().all(|v| v.is_finite()))
        .map(|row| {
            let mut q = vec![0.0; inputs.len()];
            q[..measured_inputs].copy_from_slice(&row[1..=measured_inputs]);
            q
        })
        .collect();
    crate::model::kind::approach_from_order(inputs, &vec![false; inputs.len()], &mut with_approach);
    let mut approach_rows = with_approach.into_iter();
    let tool: Vec<Export> = files
        .reflectors
        .iter()
        .map(|p| read_export(p, 3, None, "x, y, z"))
        .collect::<Result<_, _>>()?;
    let refs: Vec<Export> = files
        .references
        .iter()
        .map(|p| read_export(p, 3, None, "x, y, z"))
        .collect::<Result<_, _>>()?;
    let to_mm = files.lengths.to_mm();
    let logged_columns: Vec<&InputSpec> = inputs
        .iter()
        .filter(|i| i.approach_of.is_none())
        .chain(observed.iter().filter(|_| with_observed))
        .collect();
    let factors: Vec<f64> = logged_columns
        .iter()
        .map(|i| {
            if i.unit == Unit::Angle {
                files.angles.to_rad().to_degrees()
            } else {
                to_mm
            }
        })
        .collect();
    let mut header = vec!["id".to_string()];
    header.extend(input_headers(inputs));
    if with_observed {
        header.extend(input_headers(observed));
    }
    if tool.len() == 3 {
        for k in 1..=3 {
            header.extend(["x", "y", "z"].map(|a| format!("m{k}{a}_mm")));
        }
    } else {
        header.extend(["x_mm", "y_mm", "z_mm"].map(String::from));
    }
    let mut rows = Vec::new();
    let mut lines = Vec::new();
    let mut dropped = Vec::new();
    let mut kept_ids = Vec::new();
    'pose: for (r, row) in joints.table.rows.iter().enumerate() {
        let id = row[0] as i64;
        if let Some(c) = row[1..].iter().position(|v| !v.is_finite()) {
            dropped.push((
                id,
                format!("no value of input {} in {}", logged_columns[c].name, files.joints.display()),
            ));
            continue;
        }
        let approach = approach_rows.next().unwrap_or_default();
        let mut out_row: Vec<f64> = vec![id as f64];
        let converted: Vec<f64> = row[1..].iter().zip(&factors).map(|(v, f)| v * f).collect();
        out_row.extend(&converted[..measured_inputs]);
        out_row.extend(&approach[measured_inputs.min(approach.len())..]);
        out_row.extend(&converted[measured_inputs..]);
        for (k, e) in tool.iter().enumerate() {
            match e.point(id, to_mm) {
                Ok(Some(p)) => out_row.extend([p.x, p.y, p.z]),
                Ok(None) => {
                    dropped.push((id, format!("no reading in {}", files.reflectors[k].display())));
                    continue 'pose;
                }
                Err(line) => {
                    dropped.push((
                        id,
                        format!("lost beam (empty or 0,0,0) in {} line {line}", files.reflectors[k].display()),
                    ));
                    continue 'pose;
                }
            }
        }
        rows.push(out_row);
        lines.push(joints.table.lines[r]);
        kept_ids.push(id);
    }
    for (k, e) in tool.iter().enumerate() {
        let mut extra: Vec<i64> = e.by_id.keys().copied().filter(|id| !joints.by_id.contains_key(id)).collect();
        extra.sort_unstable();
        for id in extra {
            dropped.push((
                id,
                format!("in {} but not in {}", files.reflectors[k].display(), files.joints.display()),
            ));
        }
    }
    let references = refs
        .iter()
        .zip(&files.references)
        .map(|(e, path)| {
            let pts: Vec<Option<Vector3<f64>>> = kept_ids.iter().map(|&id| e.point(id, to_mm).ok().flatten()).collect();
            stability(path, &pts)
        })
        .collect();
    if rows.is_empty() {
        return Err(IoError::Invalid {
            path: files.joints.clone(),
            message: format!(
                "no pose left after matching ids ({} dropped; first: {})",
                dropped.len(),
                dropped.first().map_or("-".into(), |(id, why)| format!("id {id}: {why}"))
            ),
        });
    }
    let table = Table {
        path: out.to_path_buf(),
        columns: header,
        rows,
        lines,
    };
    let mut data = data_from_table(&table, columns, InputColumns::Required).map_err(|e| match e {
        // A joined row's problem is a problem of the controller log's line.
        IoError::AtLine { line, message, .. } => IoError::AtLine {
            path: files.joints.clone(),
            line,
            message,
        },
        e => e,
    })?;
    data.path = out.to_path_buf();
    Ok(JoinedExports { data, dropped, references })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::model_file::ModelFile;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn joins_by_id_drops_lost_beams_and_converts_units() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let model = ModelFile::load_or_builtin("irb120").unwrap();
        let joints = write(
            d,
            "j.csv",
            "idx,a,b,c,d,e,f\n0,0.1,0.2,0.3,0.4,0.5,0.6\n1,0,0,0,0,0,0\n2,0,0.1,0,0,0,0\n",
        );
        // Rows in another order; pose 1 lost, pose 7 unknown to the controller.
        let r1 = write(d, "r1.csv", "idx,x,y,z\n2,1,2,3\n0,4,5,6\n1,0,0,0\n7,1,1,1\n");
        let base = write(d, "b.csv", "idx,x,y,z\n0,1,1,1\n2,1.0001,1,1\n");
        let files = ExportFiles {
            joints,
            angles: AngleUnit::Rad,
            reflectors: vec![r1],
            references: vec![base],
            lengths: LengthUnit::M,
        };
        let j = join_exports(&files, &model.inputs(), &d.join("out.csv")).unwrap();
        assert_eq!(j.data.ids, vec![0, 2]);
        assert!((j.data.measurements[0].q[1] - 0.2).abs() < 1e-12);
        match &j.data.measurements[0].obs {
            crate::measure::Observation::Position(p) => assert!((p - Vector3::new(4000.0, 5000.0, 6000.0)).norm() < 1e-9),
            o => panic!("{o:?}"),
        }
        let ids: Vec<i64> = j.dropped.iter().map(|d| d.0).collect();
        assert_eq!(ids, vec![1, 7]);
        assert!(j.dropped[0].1.contains("lost beam"), "{:?}", j.dropped);
        assert_eq!(j.references[0].valid, 2);
        assert!((j.references[0].max_deviation_mm - 0.1).abs() < 1e-6, "{:?}", j.references);
    }

    #[test]
    fn wrong_column_count_names_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let model = ModelFile::load_or_builtin("irb120").unwrap();
        let joints = write(d, "j.csv", "idx,a,b,c\n0,1,2,3\n");
        let r1 = write(d, "r1.csv", "idx,x,y,z\n0,1,2,3\n");
        let files = ExportFiles {
            joints,
            angles: AngleUnit::Deg,
            reflectors: vec![r1],
            references: vec![],
            lengths: LengthUnit::Mm,
        };
        let e = join_exports(&files, &model.inputs(), &d.join("out.csv")).unwrap_err().to_string();
        assert!(e.contains("j.csv") && e.contains("expected 6"), "{e}");
    }
}
