//! Gauss–Newton on the reduced problem: the weighted Jacobian `A` (rows × p) is never held whole.
//!
//! Each linearisation is done in two passes over the poses, in parallel:
//! 1. [`evaluate`]: forward kinematics only — the weighted residual, the per-pose loss weights and
//!    the cost. A trial step that raises the cost is rejected after this pass alone.
//! 2. [`factor`]: the Jacobian rows, pose block by pose block, folded into the triangular factor
//!    of `[A | r] = Q·[R z; 0 e]` by Householder QR (a fixed partition of the poses into
//!    contiguous chunks, each folded block after block, then the chunks in order: the same
//!    digits whatever the number of threads).
//!
//! `R` (p × p) carries everything the solver needs: `AᵀA = RᵀR` (covariance), the column norms
//! and inner products (column scaling, the ordered QR of the identifiability analysis), the
//! singular values and right singular vectors (minimum-norm steps), and `min |A·δ − r|` is
//! `min |R·δ − z|` (plus the constant `|e|`). Memory is `O(p²)` per thread plus the residual
//! (rows), not rows × p.
use super::{loss_weights, Loss};
use crate::error::{CalibError, KinError};
use crate::measure::{self, Measurement, Noise, Observation};
use crate::model::Mechanism;
use nalgebra::{DMatrix, DVector, Vector3};
use rayon::prelude::*;

/// Poses folded into the factor at once.
const BLOCK_POSES: usize = 128;
/// At most this many chunks of poses are reduced in parallel (fixed: the partition, hence the
/// result, does not depend on the thread count).
const MAX_CHUNKS: usize = 64;

/// The residual side of a linearisation: what forward kinematics alone gives.
#[derive(Debug, Clone)]
pub(crate) struct Evaluated {
    /// Weighted residual rows (noise and loss weights applied).
    pub residual: DVector<f64>,
    /// First row of each pose.
    pub offsets: Vec<usize>,
    /// For each row: true if it is an orientation (rad) row.
    pub angular_rows: Vec<bool>,
    /// Robust cost (`½|r|²` for least squares).
    pub cost: f64,
    /// Loss weight per pose (1: full weight).
    pub pose_weights: Vec<f64>,
    /// The predicted pose of each measurement: where [`factor`]'s forward kinematics starts
    /// (a closed loop's Newton then only confirms it).
    pub poses: Vec<crate::se3::Pose>,
}

/// Weighted residuals of `model` at every measurement, the loss weights and the cost.
pub(crate) fn evaluate<M: Mechanism + ?Sized>(model: &M, data: &[Measurement], noise: &Noise, loss: Loss) -> Result<Evaluated, CalibError> {
    let blocks = data
        .par_iter()
        .enumerate()
        .map(|(i, m)| {
            let pose = model.forward(&m.q).map_err(|source| CalibError::Kinematics { pose: i, source })?;
            let r = measure::residual(&m.obs, &pose);
            if r.iter().any(|v| !v.is_finite()) {
                let source = KinError::NonFinite("the residual (check the measurement and the model's geometry)".into());
                return Err(CalibError::Kinematics { pose: i, source });
            }
            let mut r = r;
            for (k, v) in r.iter_mut().enumerate() {
                *v *= measure::row_weight(&m.obs, k, noise);
            }
            Ok((pose, r))
        })
        .collect::<Vec<Result<_, CalibError>>>()
        // The first failing pose in data order, whichever thread failed first.
        .into_iter()
        .collect::<Result<Vec<_>, CalibError>>()?;
    let (poses, blocks): (Vec<crate::se3::Pose>, Vec<Vec<f64>>) = blocks.into_iter().unzip();
    let rows: usize = blocks.iter().map(Vec::len).sum();
    let mut residual = DVector::zeros(rows);
    let mut offsets = Vec::with_capacity(blocks.len());
    let mut angular_rows = Vec::with_capacity(rows);
    let mut row = 0;
    for r in &blocks {
        offsets.push(row);
        for (k, v) in r.iter().enumerate() {
            residual[row + k] = *v;
            angular_rows.push(r.len() == 6 && k >= 3);
        }
        row += r.len();
    }
    let (cost, pose_weights) = loss_weights(&residual, &offsets, loss);
    for (i, &w) in pose_weights.iter().enumerate() {
        if w < 1.0 {
            let end = offsets.get(i + 1).copied().unwrap_or(rows);
            residual.rows_mut(offsets[i], end - offsets[i]).scale_mut(w.sqrt());
        }
    }
    Ok(Evaluated {
        residual,
        offsets,
        angular_rows,
        cost,
        pose_weights,
        poses,
    })
}

/// `[R z]` of the stacked rows `m` ((p + 1) columns): the upper triangle of its QR, padded with
/// zero rows to (p + 1) × (p + 1).
fn triangle(m: DMatrix<f64>) -> DMatrix<f64> {
    let c = m.ncols();
    if m.nrows() == 0 {
        return DMatrix::zeros(c, c);
    }
    let r = m.qr().r();
    if r.nrows() == c {
        return r;
    }
    let mut out = DMatrix::zeros(c, c);
    out.view_mut((0, 0), (r.nrows(), c)).copy_from(&r);
    out
}

/// Stack `top` over `bottom` (same column count).
fn stack(top: &DMatrix<f64>, bottom: &DMatrix<f64>) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(top.nrows() + bottom.nrows(), top.ncols());
    m.view_mut((0, 0), top.shape()).copy_from(top);
    m.view_mut((top.nrows(), 0), bottom.shape()).copy_from(bottom);
    m
}

/// The least-squares system of a linearisation, in one of two reduced forms.
#[derive(Debug, Clone)]
pub(crate) enum System {
    /// `[A | r] = Q·[R z; 0 e]`: `R` (p × p) and `z` (p). Orthogonal: what the identifiability
    /// analysis needs (singular values down to round-off).
    Triangular { r: DMatrix<f64>, z: DVector<f64> },
    /// The normal equations `AᵀA` (p × p) and `Aᵀr` (p): cheaper to accumulate, enough for steps
    /// and covariances once the rank is known (their eigenvalues are well above round-off).
    Gram { n: DMatrix<f64>, g: DVector<f64> },
}

impl System {
    /// The minimum-norm (rank-truncated, optionally damped) step on `cols`.
    pub fn solve(&self, cols: &[usize], damping: f64, rank: Option<usize>) -> Result<DVector<f64>, CalibError> {
        match self {
            System::Triangular { r, z } => super::solve::solve_subset(r, z, cols, damping, rank),
            System::Gram { n, g } => super::solve::solve_gram(n, g, cols, damping, rank),
        }
    }

    /// `|A·δ|`, the predicted change of the weighted residual.
    pub fn predicted(&self, step: &DVector<f64>) -> f64 {
        match self {
            System::Triangular { r, .. } => (r * step).norm(),
            System::Gram { n, .. } => step.dot(&(n * step)).max(0.0).sqrt(),
        }
    }

    /// `Aᵀr·δ − ½|A·δ|²`: the cost reduction the linear model predicts for a step `δ`.
    pub fn predicted_reduction(&self, step: &DVector<f64>) -> f64 {
        let g = match self {
            System::Triangular { r, z } => r.transpose() * z,
            System::Gram { g, .. } => g.clone(),
        };
        let p = self.predicted(step);
        g.dot(step) - 0.5 * p * p
    }

    /// The information matrix `AᵀA` (p × p).
    pub fn gram(&self) -> DMatrix<f64> {
        match self {
            System::Triangular { r, .. } => r.tr_mul(r),
            System::Gram { n, .. } => n.clone(),
        }
    }

    /// The unit-weight covariance on `cols` (see [`super::solve::covariance`]).
    pub fn covariance(&self, cols: &[usize], rank: Option<usize>) -> DMatrix<f64> {
        match self {
            System::Triangular { r, .. } => super::solve::covariance(r, cols, rank),
            System::Gram { n, .. } => super::solve::covariance_gram(n, cols, rank),
        }
    }
}

/// Which reduced form [`factor`] builds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Form {
    /// [`System::Triangular`].
    Triangular,
    /// [`System::Gram`].
    Gram,
}

/// The weighted Jacobian of `model` at `data` with the rows weighted as in `ev` (noise and loss
/// weights) and the residual of `ev`, reduced to `form`.
pub(crate) fn factor<M: Mechanism + ?Sized>(
    model: &M,
    data: &[Measurement],
    noise: &Noise,
    ev: &Evaluated,
    form: Form,
) -> Result<System, CalibError> {
    let n = data.len();
    let p = model.n_params();
    let rows = ev.residual.len();
    let row_of = |i: usize| if i < n { ev.offsets[i] } else { rows };
    // The rows [A_i | r_i] of poses b..be, below `top` zero rows.
    let block = |b: usize, be: usize, top: usize| -> Result<DMatrix<f64>, CalibError> {
        let mut m = DMatrix::zeros(top + row_of(be) - row_of(b), p + 1);
        for (i, d) in data.iter().enumerate().take(be).skip(b) {
            let lw = ev.pose_weights[i].sqrt();
            let r0 = top + ev.offsets[i] - ev.offsets[b];
            match &d.obs {
                // Pose and position rows straight from the spatial Jacobian: (v − p × ω, ω) per
                // column, weighted, without an intermediate matrix per pose.
                Observation::Pose(_) | Observation::Position(_) => {
                    let (pose, jac) = super::spatial_jacobian_near(model, i, d, ev.poses.get(i))?;
                    let pt = pose.translation.vector;
                    let nrows = if matches!(d.obs, Observation::Pose(_)) { 6 } else { 3 };
                    let (wp, wo) = (lw / noise.position, lw / noise.orientation);
                    for c in 0..p {
                        let col = jac.column(c);
                        let (jl, ja) = (Vector3::new(col[0], col[1], col[2]), Vector3::new(col[3], col[4], col[5]));
                        let v = jl - pt.cross(&ja);
                        for k in 0..3 {
                            m[(r0 + k, c)] = v[k] * wp;
                        }
                        if nrows == 6 {
                            for k in 0..3 {
                                m[(r0 + 3 + k, c)] = ja[k] * wo;
                            }
                        }
                    }
                    for k in 0..nrows {
                        m[(r0 + k, p)] = ev.residual[ev.offsets[i] + k];
                    }
                }
                Observation::Points(_) => {
                    let (_, a) = super::residual_jacobian_near(model, i, d, ev.poses.get(i))?;
                    let w = measure::row_weights(&d.obs, noise);
                    for (k, wk) in w.iter().enumerate() {
                        let s = wk * lw;
                        for c in 0..p {
                            m[(r0 + k, c)] = a[(k, c)] * s;
                        }
                        m[(r0 + k, p)] = ev.residual[ev.offsets[i] + k];
                    }
                }
            }
        }
        Ok(m)
    };
    let chunk = n.div_ceil(MAX_CHUNKS).max(BLOCK_POSES);
    let starts: Vec<usize> = (0..n).step_by(chunk.max(1)).collect();
    let parts = starts
        .par_iter()
        .map(|&s| {
            let e = (s + chunk).min(n);
            let mut acc = match form {
                Form::Triangular => DMatrix::zeros(0, p + 1),
                Form::Gram => DMatrix::zeros(p + 1, p + 1),
            };
            for b in (s..e).step_by(BLOCK_POSES) {
                let be = (b + BLOCK_POSES).min(e);
                match form {
                    Form::Triangular => {
                        let top = acc.nrows();
                        let mut m = block(b, be, top)?;
                        m.view_mut((0, 0), (top, p + 1)).copy_from(&acc);
                        acc = triangle(m);
                    }
                    Form::Gram => {
                        let m = block(b, be, 0)?;
                        // A blocked matrix product (matrixmultiply), not nalgebra's dot-product `gemm_tr`.
                        acc += m.transpose() * &m;
                    }
                }
            }
            Ok(acc)
        })
        .collect::<Vec<Result<DMatrix<f64>, CalibError>>>();
    let mut acc: Option<DMatrix<f64>> = None;
    for part in parts {
        let part = part?;
        acc = Some(match (acc, form) {
            (None, _) => part,
            (Some(a), Form::Triangular) => triangle(stack(&a, &part)),
            (Some(a), Form::Gram) => a + part,
        });
    }
    let full = match acc {
        Some(a) if a.nrows() > 0 => a,
        _ => DMatrix::zeros(p + 1, p + 1),
    };
    if full.iter().any(|v| !v.is_finite()) {
        return Err(CalibError::Numerical("non-finite values in the least-squares system".into()));
    }
    Ok(match form {
        Form::Triangular => System::Triangular {
            r: full.view((0, 0), (p, p)).upper_triangle(),
            z: full.view((0, p), (p, 1)).column(0).into_owned(),
        },
        Form::Gram => System::Gram {
            n: full.view((0, 0), (p, p)).into_owned(),
            g: full.view((0, p), (p, 1)).column(0).into_owned(),
        },
    })
}
