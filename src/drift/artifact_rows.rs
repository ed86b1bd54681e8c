//! An instrument's rows in a check: seats, ballbar (or draw-wire) pivots and touched spheres,
//! planes or cubes placed where the new rows put them, with the machine as calibrated, then
//! taken out of the rows.
//!
//! An artifact put back on the table stands somewhere unknown: its coordinates are nuisance
//! parameters of the check. They are fitted to the new rows at the calibrated model (started
//! by [`crate::instrument::place_points`], then Gauss–Newton over the artifact's columns
//! alone), and each artifact point's rows are projected onto the complement of its columns (an
//! orthonormal basis of what its fit leaves free). What is left is a [`Linearization`] in the
//! model's parameters whose blocks are the artifact points: `3·n − 3` rows for a seat of `n`
//! poses, `n − 3` for a pivot of `n` lengths (`n − 4` with its zero unknown) or a sphere or
//! plane of `n` touches, `n − 6` for a cube. With the noise
//! white and the calibration right, each block is χ² with as many degrees of freedom as rows,
//! which is what [`super::check()`] judges.
use crate::error::CalibError;
use crate::identify::{linearize, Linearization};
use crate::instrument::{index_points, place_points, Artifact};
use crate::io::model_file::ModelFile;
use crate::measure::{self, Measurement, Noise};
use crate::model::Mechanism;
use crate::se3::Pose;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// Gauss–Newton steps of the artifact's fit at most.
const MAX_STEPS: usize = 30;

/// One artifact point's rows in a check.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArtifactRows {
    /// `seat 0`, `pivot 1`: its kind and number in the data.
    pub name: String,
    /// The data's poses (indices) measured at it.
    pub poses: Vec<usize>,
    /// The RMS over those poses of the tool point's distance from the seat as placed (or of
    /// the length's error for a pivot), mm.
    pub rms_mm: f64,
}

/// A pattern's direction is seen by an artifact's rows when what they keep of the motion it
/// causes (after the artifact is placed again) is at least this share of it. With seats alone a
/// uniform scale of a machine's lengths or a turn of its base moves every ball with its seat:
/// what the rows keep of it is the balls' spread about the seat, which such a pattern would
/// fit, residual and all.
pub const SEEN: f64 = 0.01;

/// The projected rows and the artifact points they come from, in block order.
pub(super) struct Projected {
    pub lin: Linearization,
    pub points: Vec<ArtifactRows>,
    /// The rows' Jacobian in the model's parameters before the projection.
    unprojected: DMatrix<f64>,
}

impl Projected {
    /// Whether every direction (column) of `directions` is seen ([`SEEN`]).
    pub fn sees(&self, directions: &DMatrix<f64>) -> bool {
        let before = &self.unprojected * directions;
        let after = &self.lin.jacobian * directions;
        (0..directions.ncols()).all(|c| after.column(c).norm() >= SEEN * before.column(c).norm() && before.column(c).norm() > 0.0)
    }
}

/// The rows of `data` at `model` with every artifact point fitted and projected out (module
/// docs), or `None` when `data` has no instrument rows.
///
/// Errors: tracker and instrument rows mixed, a point whose rows do not place it or leave
/// nothing once it is placed.
pub(super) fn project(file: &ModelFile, data: &[Measurement], noise: &Noise) -> Result<Option<Projected>, CalibError> {
    let Some((points, _, indexed)) = index_points(data, &[])? else {
        return Ok(None);
    };
    // The flange at each row (the mechanism without the probe), for which side of a touched
    // surface the probe came from.
    let bare = file.mechanism.build();
    let placed = file.frames.as_ref().map_or_else(Pose::identity, |f| f.measurement);
    let n_q = bare.input_names().len();
    let flanges = indexed
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let pose = bare
                .forward(&m.q[..n_q])
                .map_err(|source| CalibError::Kinematics { pose: i, source })?;
            Ok((placed * pose).translation.vector)
        })
        .collect::<Result<Vec<_>, CalibError>>()?;
    let mut artifact: Artifact<Box<dyn Mechanism>> = place_points(file.build(), points, &indexed, &flanges)?;
    let columns: Vec<usize> = artifact.artifact_columns().collect();
    let p = artifact.inner.n_params();
    let mut lin = linearize(&artifact, &indexed, noise)?;
    for _ in 0..MAX_STEPS {
        let a = lin.jacobian.select_columns(&columns);
        let step = a
            .svd(true, true)
            .solve(&lin.residual, 1e-12)
            .map_err(|e| CalibError::Numerical(format!("placing the artifact: {e}")))?;
        let mut delta = DVector::zeros(artifact.n_params());
        for (k, &c) in columns.iter().enumerate() {
            delta[c] = step[k];
        }
        artifact.retract(&delta);
        lin = linearize(&artifact, &indexed, noise)?;
        if step.norm() < 1e-10 * (1.0 + step.norm()) {
            break;
        }
    }
    let mut blocks = Vec::new();
    let mut out = Vec::new();
    let mut unprojected = Vec::new();
    for (k, point) in artifact.points.iter().enumerate() {
        let poses: Vec<usize> = (0..indexed.len()).filter(|&i| indexed[i].q.last() == Some(&(k as f64))).collect();
        let rows: Vec<usize> = poses.iter().flat_map(|&i| lin.pose_rows(i)).collect();
        let name = format!("{} {}", point.kind.name(), point.id);
        let own = lin.jacobian.select_rows(&rows).select_columns(&columns);
        let q = complement(&own);
        if q.ncols() == 0 {
            return Err(CalibError::InvalidOption(format!(
                "{name}: its {} rows only place it and tell nothing of the machine; measure more poses there",
                rows.len()
            )));
        }
        let jm = lin.jacobian.select_rows(&rows).columns(0, p).into_owned();
        let r = lin.residual.select_rows(&rows);
        unprojected.push(jm.clone());
        blocks.push((q.transpose() * jm, q.transpose() * r));
        let mut sum = 0.0;
        for &i in &poses {
            let w = measure::row_weights(&indexed[i].obs, noise);
            let at = lin.pose_rows(i);
            sum += at.clone().map(|row| (lin.residual[row] / w[row - at.start]).powi(2)).sum::<f64>();
        }
        out.push(ArtifactRows {
            name,
            rms_mm: (sum / poses.len().max(1) as f64).sqrt(),
            poses,
        });
    }
    let jacobians: Vec<DMatrix<f64>> = blocks.iter().map(|b| b.0.clone()).collect();
    let residuals: Vec<DMatrix<f64>> = blocks
        .iter()
        .map(|b| DMatrix::from_column_slice(b.1.len(), 1, b.1.as_slice()))
        .collect();
    let offsets = blocks
        .iter()
        .scan(0, |at, b| {
            let start = *at;
            *at += b.1.len();
            Some(start)
        })
        .collect();
    let residual = stack(&residuals, 1).column(0).into_owned();
    Ok(Some(Projected {
        lin: Linearization {
            jacobian: stack(&jacobians, p),
            angular_rows: vec![false; residual.len()],
            residual,
            offsets,
        },
        points: out,
        unprojected: stack(&unprojected, p),
    }))
}

/// The blocks `blocks` (each `p` columns) one over the other.
fn stack(blocks: &[DMatrix<f64>], p: usize) -> DMatrix<f64> {
    let rows: usize = blocks.iter().map(DMatrix::nrows).sum();
    let mut out = DMatrix::zeros(rows, p);
    let mut at = 0;
    for b in blocks {
        out.view_mut((at, 0), (b.nrows(), p)).copy_from(b);
        at += b.nrows();
    }
    out
}

/// An orthonormal basis (columns) of the complement of the column space of `a`.
fn complement(a: &DMatrix<f64>) -> DMatrix<f64> {
    let m = a.nrows();
    let svd = a.clone().svd(true, false);
    let u = svd.u.expect("u requested");
    let top = svd.singular_values.iter().copied().fold(0.0, f64::max);
    let range: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&k| svd.singular_values[k] > 1e-10 * top.max(1e-300))
        .collect();
    let ur = u.select_columns(&range);
    let projector = DMatrix::identity(m, m) - &ur * ur.transpose();
    let eig = projector.symmetric_eigen();
    let keep: Vec<usize> = (0..m).filter(|&k| eig.eigenvalues[k] > 0.5).collect();
    eig.eigenvectors.select_columns(&keep)
}

#[cfg(test)]
mod tests {
    use super::complement;
    use nalgebra::DMatrix;

    #[test]
    fn the_complement_is_orthonormal_and_orthogonal_to_the_columns() {
        let a = DMatrix::from_row_slice(5, 2, &[1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 2.0]);
        let q = complement(&a);
        assert_eq!(q.ncols(), 3);
        assert!((q.transpose() * &q - DMatrix::identity(3, 3)).norm() < 1e-12);
        assert!((q.transpose() * &a).norm() < 1e-12);
    }
}
