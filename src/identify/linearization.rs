//! [`Linearization`]: the noise-weighted residual and Jacobian of a data set at a model, pose by
//! pose, and [`linearize`], which computes it.
use super::joints;
use crate::error::{CalibError, KinError};
use crate::measure::{self, Measurement, Noise};
use crate::model::Mechanism;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::ops::Range;

/// Weighted residual vector and weighted Jacobian of a data set at a model.
#[derive(Debug, Clone)]
pub struct Linearization {
    /// Weighted Jacobian of the predictions (rows × parameters).
    pub jacobian: DMatrix<f64>,
    /// Weighted residual "measured − predicted".
    pub residual: DVector<f64>,
    /// First row of each pose's block.
    pub offsets: Vec<usize>,
    /// For each row: true if it is an orientation (rad) row.
    pub angular_rows: Vec<bool>,
}

impl Linearization {
    /// The rows of pose `i`.
    pub fn pose_rows(&self, i: usize) -> Range<usize> {
        pose_rows(&self.offsets, self.residual.len(), i)
    }

    /// How many rows each pose has, in pose order.
    pub fn layout(&self) -> Vec<usize> {
        (0..self.offsets.len()).map(|i| self.pose_rows(i).len()).collect()
    }
}

/// The rows of pose `i` among `rows` rows whose poses start at `offsets`.
pub(crate) fn pose_rows(offsets: &[usize], rows: usize, i: usize) -> Range<usize> {
    offsets[i]..offsets.get(i + 1).copied().unwrap_or(rows)
}

/// Linearise `model` at every measurement (in parallel), weighting rows by `noise`.
pub fn linearize<M: Mechanism + ?Sized>(model: &M, data: &[Measurement], noise: &Noise) -> Result<Linearization, CalibError> {
    let units = model.observed_joints();
    let blocks: Vec<_> = data
        .par_iter()
        .enumerate()
        .map(|(i, m)| {
            let (pose, jac, jr, ja) = joints::linearize(model, i, m, &units, noise, None)?;
            let a = measure::residual_jacobian(&m.obs, &pose, &jac);
            let r = measure::residual(&m.obs, &pose);
            if r.iter().any(|v| !v.is_finite()) {
                let source = KinError::NonFinite("the residual (check the measurement and the model's geometry)".into());
                return Err(CalibError::Kinematics { pose: i, source });
            }
            let w = measure::row_weights(&m.obs, noise);
            Ok((a, r, w, (jr, ja)))
        })
        .collect::<Vec<Result<_, CalibError>>>()
        // The first failing pose in data order (not whichever thread failed first): the same
        // inputs give the same message.
        .into_iter()
        .collect::<Result<Vec<_>, CalibError>>()?;
    let rows: usize = blocks.iter().map(|b| b.1.len() + b.3 .0.len()).sum();
    let p = model.n_params();
    let mut jacobian = DMatrix::zeros(rows, p);
    let mut residual = DVector::zeros(rows);
    let mut offsets = Vec::with_capacity(blocks.len());
    let mut angular_rows = Vec::with_capacity(rows);
    let mut row = 0;
    for (a, r, w, (jr, ja)) in &blocks {
        offsets.push(row);
        for k in 0..r.len() {
            for c in 0..p {
                jacobian[(row + k, c)] = a[(k, c)] * w[k];
            }
            residual[row + k] = r[k] * w[k];
            angular_rows.push(r.len() == 6 && k >= 3);
        }
        row += r.len();
        if let Some(ja) = ja {
            jacobian.view_mut((row, 0), (jr.len(), p)).copy_from(ja);
            for (k, v) in jr.iter().enumerate() {
                residual[row + k] = *v;
                angular_rows.push(false);
            }
            row += jr.len();
        }
    }
    Ok(Linearization {
        jacobian,
        residual,
        offsets,
        angular_rows,
    })
}
