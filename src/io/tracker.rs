//! Laser-tracker data sets of a serial robot, as a folder of CSV files:
//!
//! | file | columns | unit |
//! |---|---|---|
//! | `joints_deg.csv` | `idx,q1,…,qn` — controller joint readings | degree |
//! | `smr1.csv` … `smr3.csv` | `idx,x,y,z` — tool reflector centres | mm, tracker frame |
//! | `base1.csv` … `base3.csv` (optional) | `idx,x,y,z` — base reflector centres | mm, tracker frame |
//!
//! Every file has one row per pose, with the same `idx` in the same order. A reading of exactly
//! (0, 0, 0) is the tracker's "no measurement" and counts as failed. Tool poses with a failed
//! reflector are dropped; failed base readings (zero, or farther than
//! [`BASE_OUTLIER_MM`] from that reflector's median) are only flagged, because the base
//! reflectors serve as a stability check and do not enter the calibration.
use super::table::{read_table, Table};
use super::IoError;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// A base-reflector reading farther than this from its median position is a failed reading (mm).
pub const BASE_OUTLIER_MM: f64 = 1.0;

/// A laser-tracker data set.
#[derive(Debug, Clone)]
pub struct TrackerData {
    /// The folder read.
    pub folder: PathBuf,
    /// Pose indices of the kept poses.
    pub idx: Vec<i64>,
    /// Joint values (rad) of the kept poses.
    pub joints: Vec<Vec<f64>>,
    /// Tool reflector centres (mm, tracker frame) of the kept poses, `[pose][reflector]`.
    pub tool: Vec<[Vector3<f64>; 3]>,
    /// Base reflector centres (mm, tracker frame) of the kept poses, `None` for failed readings;
    /// empty when the folder has no base files.
    pub base: Vec<Vec<Option<Vector3<f64>>>>,
    /// Poses dropped, with the reason.
    pub dropped: Vec<(i64, String)>,
    /// Failed base readings flagged: (pose index, base reflector number 1-based, reason).
    pub failed_base: Vec<(i64, usize, String)>,
}

impl TrackerData {
    /// Number of kept poses.
    pub fn len(&self) -> usize {
        self.idx.len()
    }

    /// True when no pose was kept.
    pub fn is_empty(&self) -> bool {
        self.idx.is_empty()
    }

    /// Maximum deviation (mm) of each base reflector from its median over the valid readings.
    pub fn base_stability(&self) -> Vec<f64> {
        let nb = self.base.first().map(|b| b.len()).unwrap_or(0);
        (0..nb)
            .map(|k| {
                let pts: Vec<Vector3<f64>> = self.base.iter().filter_map(|b| b[k]).collect();
                let med = median_point(&pts);
                pts.iter().map(|p| (p - med).norm()).fold(0.0, f64::max)
            })
            .collect()
    }
}

fn median_point(pts: &[Vector3<f64>]) -> Vector3<f64> {
    let med = |k: usize| {
        let mut v: Vec<f64> = pts.iter().map(|p| p[k]).collect();
        v.sort_by(|a, b| a.total_cmp(b));
        if v.is_empty() {
            0.0
        } else {
            v[v.len() / 2]
        }
    };
    Vector3::new(med(0), med(1), med(2))
}

fn read_points(path: &Path, reference: &Table) -> Result<Vec<Vector3<f64>>, IoError> {
    let t = read_table(path)?;
    for c in ["idx", "x", "y", "z"] {
        t.column(c)?;
    }
    check_same_poses(&t, reference)?;
    let (x, y, z) = (t.values("x")?, t.values("y")?, t.values("z")?);
    Ok((0..t.len()).map(|i| Vector3::new(x[i], y[i], z[i])).collect())
}

fn check_same_poses(t: &Table, reference: &Table) -> Result<(), IoError> {
    if t.len() != reference.len() {
        return Err(IoError::RowCountMismatch {
            path: t.path.clone(),
            found: t.len(),
            other: reference.path.clone(),
            expected: reference.len(),
        });
    }
    let (a, b) = (t.values("idx")?, reference.values("idx")?);
    for i in 0..a.len() {
        if a[i] != b[i] {
            return Err(IoError::IndexMismatch {
                path: t.path.clone(),
                line: t.lines[i],
                found: a[i] as i64,
                other: reference.path.clone(),
                expected: b[i] as i64,
            });
        }
    }
    Ok(())
}

/// Read a tracker data folder (see the module docs). `joints` joint columns `q1…qn` are expected.
pub fn read_folder(folder: &Path, joints: usize) -> Result<TrackerData, IoError> {
    let jpath = folder.join("joints_deg.csv");
    let jt = read_table(&jpath)?;
    jt.column("idx")?;
    let mut jcols = Vec::new();
    for k in 1..=joints {
        jcols.push(jt.column(&format!("q{k}"))?);
    }
    if jt.is_empty() {
        return Err(IoError::Invalid {
            path: jpath,
            message: "no poses".into(),
        });
    }
    let tool: Vec<Vec<Vector3<f64>>> = (1..=3)
        .map(|k| read_points(&folder.join(format!("smr{k}.csv")), &jt))
        .collect::<Result<_, _>>()?;
    let base_files: Vec<PathBuf> = (1..=3)
        .map(|k| folder.join(format!("base{k}.csv")))
        .filter(|p| p.exists())
        .collect();
    let base_raw: Vec<Vec<Vector3<f64>>> = base_files.iter().map(|p| read_points(p, &jt)).collect::<Result<_, _>>()?;
    let base_median: Vec<Vector3<f64>> = base_raw
        .iter()
        .map(|pts| {
            let valid: Vec<Vector3<f64>> = pts.iter().copied().filter(|p| p.norm() > 0.0).collect();
            median_point(&valid)
        })
        .collect();
    let idx = jt.values("idx")?;
    let mut out = TrackerData {
        folder: folder.to_path_buf(),
        idx: Vec::new(),
        joints: Vec::new(),
        tool: Vec::new(),
        base: Vec::new(),
        dropped: Vec::new(),
        failed_base: Vec::new(),
    };
    for (i, &id) in idx.iter().enumerate() {
        let id = id as i64;
        if let Some(k) = (0..3).find(|&k| tool[k][i].norm() == 0.0) {
            out.dropped.push((id, format!("tool reflector {} has no reading (0, 0, 0)", k + 1)));
            continue;
        }
        let mut base = Vec::new();
        for (k, pts) in base_raw.iter().enumerate() {
            let p = pts[i];
            if p.norm() == 0.0 {
                out.failed_base.push((id, k + 1, "no reading (0, 0, 0)".into()));
                base.push(None);
            } else if (p - base_median[k]).norm() > BASE_OUTLIER_MM {
                out.failed_base
                    .push((id, k + 1, format!("{:.1} mm from its median position", (p - base_median[k]).norm())));
                base.push(None);
            } else {
                base.push(Some(p));
            }
        }
        out.idx.push(id);
        out.joints.push(jcols.iter().map(|&c| jt.rows[i][c].to_radians()).collect());
        out.tool.push([tool[0][i], tool[1][i], tool[2][i]]);
        if !base_raw.is_empty() {
            out.base.push(base);
        }
    }
    Ok(out)
}
