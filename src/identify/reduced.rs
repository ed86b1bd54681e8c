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
    /// For each row: true if it is an observed joint's row.
    pub joint_rows: Vec<bool>,
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
    let units = model.observed_joints();
    let blocks = data
        .par_iter()
        .enumerate()
        .map(|(i, m)| {
            let (pose, joint_rows) = super::joints::evaluate(model, i, m, &units, noise)?;
            let r = measure::residual(&m.obs, &pose);
            if r.iter().any(|v| !v.is_finite()) {
                let source = KinError::NonFinite("the residual (check the measurement and the model's geometry)".into());
                return Err(CalibError::Kinematics { pose: i, source });
            }
            let mut r = r;
            for (k, v) in r.iter_mut().enumerate() {
                *v *= measure::row_weight(&m.obs, k, noise);
            }
            let nobs = r.len();
            r.extend(joint_rows);
            Ok((pose, (r, nobs)))
        })
        .collect::<Vec<Result<_, CalibError>>>()
        // The first failing pose in data order, whichever thread failed first.
        .into_iter()
        .collect::<Result<Vec<_>, CalibError>>()?;
    let (poses, blocks): (Vec<crate::se3::Pose>, Vec<(Vec<f64>, usize)>) = blocks.into_iter().unzip();
    let rows: usize = blocks.iter().map(|b| b.0.len()).sum();
    let mut residual = DVector::zeros(rows);
    let mut offsets = Vec::with_capacity(blocks.len());
    let mut angular_rows = Vec::with_capacity(rows);
    let mut joint_rows = Vec::with_capacity(rows);
    let mut row = 0;
    for (r, nobs) in &blocks {
        offsets.push(row);
        for (k, v) in r.iter().enumerate() {
            residual[row + k] = *v;
            angular_rows.push(*nobs == 6 && (3..6).contains(&k));
            joint_rows.push(k >= *nobs);
        }
        row += r.len();
    }
    let (cost, pose_weights) = loss_weights(&residual, &offsets, loss);
    for (i, &w) in pose_weights.iter().enumerate() {
        if w < 1.0 {
            let at = super::linearization::pose_rows(&offsets, rows, i);
            residual.rows_mut(at.start, at.len()).scale_mut(w.sqrt());
        }
    }
    Ok(Evaluated {
        residual,
        offsets,
        angular_rows,
        joint_rows,
        cost,
        pose_weights,
        poses,
    })
}

/// Fold the rows `rows` (m × c) into the upper-triangular `r` (c × c) by Householder
/// reflections that act on one row of `r` and all of `rows` at a time (LAPACK's `tpqrt`
/// structure): afterwards `[r_before; rows] = Q·[r; 0]`. `rows` is consumed as workspace.
/// Column-major slices throughout, so the inner products and updates run over contiguous memory
/// (nalgebra's QR of the stacked rows also swept the zeros under `r`, column by column).
fn fold(r: &mut DMatrix<f64>, mut rows: DMatrix<f64>) {
    let c = r.ncols();
    let m = rows.nrows();
    if m == 0 {
        return;
    }
    let data = rows.as_mut_slice();
    for j in 0..c {
        let (head, tail) = data.split_at_mut((j + 1) * m);
        let v = &mut head[j * m..];
        let sigma = dot(v, v);
        if sigma == 0.0 {
            continue;
        }
        let x0 = r[(j, j)];
        let alpha = (x0 * x0 + sigma).sqrt();
        let beta = if x0 > 0.0 { -alpha } else { alpha };
        let tau = (beta - x0) / beta;
        let inv = 1.0 / (x0 - beta);
        v.iter_mut().for_each(|x| *x *= inv);
        r[(j, j)] = beta;
        for (k, col) in tail.chunks_exact_mut(m).enumerate() {
            let k = j + 1 + k;
            let w = tau * (r[(j, k)] + dot(v, col));
            r[(j, k)] -= w;
            col.iter_mut().zip(v.iter()).for_each(|(x, &y)| *x -= w * y);
        }
    }
}

/// `a·b` with eight partial sums (vectorisable; the summation order is fixed).
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut s = [0.0; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            s[k] += x[k] * y[k];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    ((s[0] + s[4]) + (s[1] + s[5])) + ((s[2] + s[6]) + (s[3] + s[7])) + tail
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

/// `acc += mᵀ·m` by matrixmultiply's blocked product (not nalgebra's dot-product `gemm_tr`),
/// reading `mᵀ` through swapped strides instead of a transposed copy.
fn add_gram(acc: &mut DMatrix<f64>, m: &DMatrix<f64>) {
    let (r, c) = m.shape();
    assert_eq!(acc.shape(), (c, c), "Gram accumulator of the wrong size");
    let (rs, cs) = (r as isize, c as isize);
    // SAFETY: `m` is an r×c column-major matrix (element (i, j) at i + j·r), so its transpose is
    // read with row stride r and column stride 1 and `m` itself with strides 1 and r; `acc` is
    // c×c column-major (strides 1 and c), owned mutably and not aliased by `m`.
    unsafe {
        matrixmultiply::dgemm(c, r, c, 1.0, m.as_ptr(), rs, 1, m.as_ptr(), 1, rs, 1.0, acc.as_mut_ptr(), 1, cs);
    }
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
    let units = model.observed_joints();
    let row_of = |i: usize| if i < n { ev.offsets[i] } else { rows };
    // The rows [A_i | r_i] of poses b..be.
    let block = |b: usize, be: usize| -> Result<DMatrix<f64>, CalibError> {
        let mut m = DMatrix::zeros(row_of(be) - row_of(b), p + 1);
        for (i, d) in data.iter().enumerate().take(be).skip(b) {
            let lw = ev.pose_weights[i].sqrt();
            let r0 = ev.offsets[i] - ev.offsets[b];
            // One evaluation of the model for the observation's rows and the observed joints'.
            let (pose, jac, _, joints) = super::joints::linearize(model, i, d, &units, noise, ev.poses.get(i))?;
            match &d.obs {
                // Pose and position rows straight from the spatial Jacobian: (v − p × ω, ω) per
                // column, weighted, without an intermediate matrix per pose.
                Observation::Pose(_) | Observation::Position(_) | Observation::Seat(_) => {
                    let pt = pose.translation.vector;
                    let nrows = if matches!(d.obs, Observation::Pose(_)) { 6 } else { 3 };
                    // (A seat's rows by its kind's σ: [`measure::row_weight`].)
                    let (wp, wo) = (lw * measure::row_weight(&d.obs, 0, noise), lw / noise.orientation);
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
                Observation::Points(_) | Observation::Distance { .. } | Observation::Touch(_) => {
                    let a = measure::residual_jacobian(&d.obs, &pose, &jac);
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
            // The observed joints' rows, after the observation's.
            if let Some(j) = joints {
                let j0 = d.obs.rows();
                for k in 0..j.nrows() {
                    for c in 0..p {
                        m[(r0 + j0 + k, c)] = j[(k, c)] * lw;
                    }
                    m[(r0 + j0 + k, p)] = ev.residual[ev.offsets[i] + j0 + k];
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
            let mut acc = DMatrix::zeros(p + 1, p + 1);
            for b in (s..e).step_by(BLOCK_POSES) {
                let be = (b + BLOCK_POSES).min(e);
                match form {
                    Form::Triangular => fold(&mut acc, block(b, be)?),
                    Form::Gram => {
                        let m = block(b, be)?;
                        add_gram(&mut acc, &m);
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
            (Some(mut a), Form::Triangular) => {
                fold(&mut a, part);
                a
            }
            (Some(a), Form::Gram) => a + part,
        });
    }
    let full = acc.unwrap_or_else(|| DMatrix::zeros(p + 1, p + 1));
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Folding rows block by block gives a triangular factor of the whole stack: `RᵀR = AᵀA`,
    /// and the same `|R|` diagonal as nalgebra's QR of the stacked rows (a factor is unique up
    /// to the signs of its rows), also with an exactly dependent column (its pivot at round-off) and a zero one.
    #[test]
    fn fold_gives_the_triangular_factor_of_the_stacked_rows() {
        let (m, c) = (37, 6);
        let mut a = DMatrix::from_fn(m, c, |i, j| ((i * 7 + j * 13) % 11) as f64 - 5.0 + 0.1 * (i as f64).sin());
        for i in 0..m {
            a[(i, 4)] = a[(i, 0)] - 2.0 * a[(i, 1)];
            a[(i, 5)] = 0.0;
        }
        let mut r = DMatrix::zeros(c, c);
        for (s, e) in [(0, 10), (10, 11), (11, 30), (30, 37)] {
            fold(&mut r, a.rows(s, e - s).into_owned());
        }
        for i in 0..c {
            for j in 0..i {
                assert_eq!(r[(i, j)], 0.0);
            }
        }
        let gram = a.transpose() * &a;
        let err = (r.transpose() * &r - &gram).abs().max();
        assert!(err <= 1e-12 * gram.abs().max(), "RᵀR − AᵀA: {err:e}");
        let reference = a.clone().qr().r();
        let scale = gram.abs().max().sqrt();
        assert!(r[(4, 4)].abs() <= 1e-12 * scale && r[(5, 5)] == 0.0);
        for i in 0..4 {
            let (x, y) = (r[(i, i)].abs(), reference[(i, i)].abs());
            assert!((x - y).abs() <= 1e-12 * scale, "diagonal {i}: {x} against {y}");
        }
    }

    /// The strided product adds `mᵀm` to what the accumulator holds, for a tall block and a
    /// non-square, non-symmetric start, exactly as nalgebra's product of the transposed copy.
    #[test]
    fn add_gram_accumulates_the_transposed_product() {
        let m = DMatrix::from_fn(131, 9, |i, j| ((i * 5 + j * 3) % 17) as f64 * 0.25 - 2.0 + (j as f64).cos());
        let start = DMatrix::from_fn(9, 9, |i, j| (i * 9 + j) as f64);
        let mut acc = start.clone();
        add_gram(&mut acc, &m);
        let want = &start + m.transpose() * &m;
        assert!((acc - want).amax() < 1e-12 * (m.transpose() * &m).amax());
    }
}
