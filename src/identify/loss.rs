//! The loss applied to each pose's weighted residual ([`Loss`]): plain least squares or Huber's
//! robust loss on the per-pose RMS residual, with the pose weights it gives.
use super::linearization::pose_rows;
use super::Linearization;
use crate::measure::Noise;
use nalgebra::DVector;
use serde::Serialize;

/// The loss applied to each pose's weighted residual.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub enum Loss {
    /// Plain (weighted) least squares: the maximum-likelihood estimate under Gaussian noise.
    #[default]
    Squares,
    /// Huber's loss on the per-pose RMS residual `s_i` (in units of the stated noise): quadratic
    /// up to `k` robust standard deviations of the set (1.4826 × the median of `s_i`, re-estimated
    /// at every linearisation, and never below the stated noise: a pose within `k` stated
    /// standard deviations is no blunder, however exactly the others fit), linear beyond. A
    /// blunder of millimetres then pulls on the fit like a residual of `k` standard deviations,
    /// not like its square.
    Huber {
        /// Threshold in robust standard deviations (5 keeps Gaussian data untouched).
        k: f64,
    },
}

/// Scale rows of `lin` by the square root of each pose's Huber weight and return the robust cost
/// `Σ ρ(s_i)·rows_i` (equal to `½|r|²` for [`Loss::Squares`]). The weights of the poses are
/// returned too (1 = full weight).
pub fn apply_loss(lin: &mut Linearization, loss: Loss) -> (f64, Vec<f64>) {
    let (cost, weights) = loss_weights(&lin.residual, &lin.offsets, loss);
    for (i, &w) in weights.iter().enumerate() {
        if w < 1.0 {
            let at = lin.pose_rows(i);
            let r = w.sqrt();
            lin.residual.rows_mut(at.start, at.len()).scale_mut(r);
            lin.jacobian.rows_mut(at.start, at.len()).scale_mut(r);
        }
    }
    (cost, weights)
}

/// The robust cost and the weight of each pose (rows `offsets[i]..offsets[i + 1]` of the
/// weighted `residual`) under `loss`, without changing anything (see [`apply_loss`]).
pub(crate) fn loss_weights(residual: &DVector<f64>, offsets: &[usize], loss: Loss) -> (f64, Vec<f64>) {
    let n = offsets.len();
    let Loss::Huber { k } = loss else {
        return (0.5 * residual.norm_squared(), vec![1.0; n]);
    };
    let s = pose_rms(residual, offsets);
    let threshold = huber_threshold(k, &s);
    let mut cost = 0.0;
    let mut weights = Vec::with_capacity(n);
    for (i, &si) in s.iter().enumerate() {
        let m = pose_rows(offsets, residual.len(), i).len() as f64;
        let w = if threshold > 0.0 && si > threshold { threshold / si } else { 1.0 };
        cost += if w < 1.0 {
            m * (threshold * si - 0.5 * threshold * threshold)
        } else {
            0.5 * m * si * si
        };
        weights.push(w);
    }
    (cost, weights)
}

/// Each pose's RMS weighted residual `s_i` (rows `offsets[i]..offsets[i + 1]` of `residual`; 1 =
/// the stated noise), as the Huber loss measures it.
pub(crate) fn pose_rms(residual: &DVector<f64>, offsets: &[usize]) -> Vec<f64> {
    let rows = residual.len();
    (0..offsets.len())
        .map(|i| {
            let at = pose_rows(offsets, rows, i);
            (residual.rows(at.start, at.len()).norm_squared() / at.len().max(1) as f64).sqrt()
        })
        .collect()
}

/// The Huber threshold of per-pose residuals `s`: `k` robust standard deviations (1.4826 × the
/// median), never below the stated noise.
pub(crate) fn huber_threshold(k: f64, s: &[f64]) -> f64 {
    let mut sorted = s.to_vec();
    sorted.sort_by(f64::total_cmp);
    let median = if sorted.is_empty() { 0.0 } else { sorted[sorted.len() / 2] };
    // The rows are noise-weighted: 1 is the stated noise. Without that floor, a noise-free fit
    // (a robust scale of round-off) would treat its least exact poses as blunders.
    k * (1.4826 * median).max(1.0)
}

/// Re-estimate the position and orientation noise from weighted residuals (one variance
/// component per row kind), keeping the ratio meaningful when one kind is absent.
pub(super) fn reestimate_noise(
    residual: &DVector<f64>,
    angular_rows: &[bool],
    joint_rows: &[bool],
    noise: &Noise,
    dof_ratio: f64,
) -> Noise {
    let (mut sp, mut np, mut sa, mut na) = (0.0, 0usize, 0.0, 0usize);
    for (k, &ang) in angular_rows.iter().enumerate() {
        let r2 = residual[k] * residual[k];
        if joint_rows.get(k).copied().unwrap_or(false) {
            // The encoders keep their stated noise.
            continue;
        } else if ang {
            sa += r2;
            na += 1;
        } else {
            sp += r2;
            np += 1;
        }
    }
    let scale = |s: f64, n: usize| if n > 0 { (s / (n as f64 * dof_ratio)).sqrt() } else { 1.0 };
    Noise {
        position: noise.position * scale(sp, np),
        orientation: noise.orientation * scale(sa, na),
        ..*noise
    }
}
