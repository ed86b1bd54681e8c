//! The least-squares solves of [`super::identify`]: minimum-norm, rank-truncated or damped steps
//! on a column subset, from a (triangular) design matrix or from the normal equations, and the
//! covariance of those solutions.
use crate::error::CalibError;
use crate::identifiability;
use nalgebra::{DMatrix, DVector};

/// Solve `min |A_S·x − b|` on the columns `cols` with column scaling; returns the full-length
/// step. With `rank = Some(r)` the solve is the minimum-norm solution truncated to the `r` largest
/// singular values (gauge-free over redundant parameters); with `damping > 0` it is the
/// Levenberg–Marquardt step `(AᵀA + λI)⁻¹Aᵀb` in scaled coordinates.
pub(super) fn solve_subset(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    cols: &[usize],
    damping: f64,
    rank: Option<usize>,
) -> Result<DVector<f64>, CalibError> {
    let (scaled, norms) = identifiability::scale_columns(a, cols);
    // Tall problems: a thin QR first, then the SVD of the small k×k factor R (A = Q·R, so the
    // singular values and right vectors of A are those of R, and Uᵀb = U_Rᵀ·Qᵀb).
    let (small, rhs) = if scaled.nrows() > scaled.ncols() {
        let k = scaled.ncols();
        let qr = scaled.qr();
        let mut qtb = b.clone();
        qr.q_tr_mul(&mut qtb);
        (qr.r(), qtb.rows(0, k).into_owned())
    } else {
        (scaled, b.clone())
    };
    let b = &rhs;
    // nalgebra's SVD does not return on non-finite input.
    if small.iter().chain(b.iter()).any(|v| !v.is_finite()) {
        return Err(CalibError::Numerical("non-finite values in the least-squares system".into()));
    }
    let svd = small.svd(true, true);
    let (u, vt) = match (&svd.u, &svd.v_t) {
        (Some(u), Some(vt)) => (u, vt),
        _ => return Err(CalibError::Numerical("SVD failed".into())),
    };
    let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
    order.sort_by(|&i, &j| svd.singular_values[j].total_cmp(&svd.singular_values[i]));
    let keep = rank.unwrap_or(order.len()).min(order.len());
    let mut y = DVector::zeros(cols.len());
    for &i in order.iter().take(keep) {
        let s = svd.singular_values[i];
        if s <= 0.0 {
            continue;
        }
        let coef = u.column(i).dot(b) * s / (s * s + damping);
        y.axpy(coef, &vt.row(i).transpose(), 1.0);
    }
    unscale(&y, cols, &norms, a.ncols())
}

/// Standard deviations on the columns `cols` from `σ₀²·(AᵀA)⁻¹`.
/// Unit-weight covariance `(AᵀA)⁺` of the solution on the columns `cols` (model units, full
/// size, zero outside `cols`): with `rank = Some(r)` the pseudo-inverse truncated to the `r`
/// largest singular values of the column-scaled matrix — the covariance of the minimum-norm
/// solution the Gauss–Newton steps take — otherwise the plain inverse (subset solution).
pub(super) fn covariance(a: &DMatrix<f64>, cols: &[usize], rank: Option<usize>) -> DMatrix<f64> {
    covariance_gram(&(a.transpose() * a), cols, rank)
}

/// [`covariance`] from the Gram matrix `AᵀA` (p × p) instead of `A`.
pub(super) fn covariance_gram(gram: &DMatrix<f64>, cols: &[usize], rank: Option<usize>) -> DMatrix<f64> {
    let p = gram.ncols();
    let mut out = DMatrix::zeros(p, p);
    let (n, norms) = scale_gram(gram, cols);
    if n.iter().any(|v| !v.is_finite()) {
        return out;
    }
    let inv = match rank {
        None => match n.try_inverse() {
            Some(inv) => inv,
            None => return out,
        },
        Some(r) => {
            let eig = n.symmetric_eigen();
            let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
            order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
            let k = cols.len();
            let mut inv = DMatrix::zeros(k, k);
            for &i in order.iter().take(r.min(k)) {
                let l = eig.eigenvalues[i];
                if l > 0.0 {
                    let v = eig.eigenvectors.column(i);
                    inv += (v * v.transpose()) / l;
                }
            }
            inv
        }
    };
    for (i, &ci) in cols.iter().enumerate() {
        for (j, &cj) in cols.iter().enumerate() {
            out[(ci, cj)] = inv[(i, j)] / (norms[i] * norms[j]);
        }
    }
    out
}

/// The Gram matrix of the columns `cols` scaled to unit norm, and the column norms (a zero
/// column keeps scale 1 so that it stays zero).
fn scale_gram(gram: &DMatrix<f64>, cols: &[usize]) -> (DMatrix<f64>, Vec<f64>) {
    let norms: Vec<f64> = cols.iter().map(|&c| gram[(c, c)].max(0.0).sqrt()).collect();
    let s = |k: usize| if norms[k] > 0.0 { norms[k] } else { 1.0 };
    let n = DMatrix::from_fn(cols.len(), cols.len(), |i, j| gram[(cols[i], cols[j])] / (s(i) * s(j)));
    (n, norms)
}

/// [`solve_subset`] from the normal equations `AᵀA·x = Aᵀb` (`gram`, `rhs`): the same minimum-norm,
/// rank-truncated or damped step, from the eigen-decomposition of the column-scaled `AᵀA`
/// (eigenvalues are the squared singular values of the scaled `A`).
pub(super) fn solve_gram(
    gram: &DMatrix<f64>,
    rhs: &DVector<f64>,
    cols: &[usize],
    damping: f64,
    rank: Option<usize>,
) -> Result<DVector<f64>, CalibError> {
    let (n, norms) = scale_gram(gram, cols);
    let g = DVector::from_fn(cols.len(), |k, _| if norms[k] > 0.0 { rhs[cols[k]] / norms[k] } else { 0.0 });
    if n.iter().chain(g.iter()).any(|v| !v.is_finite()) {
        return Err(CalibError::Numerical("non-finite values in the least-squares system".into()));
    }
    let eig = n.symmetric_eigen();
    let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let keep = rank.unwrap_or(order.len()).min(order.len());
    let mut y = DVector::zeros(cols.len());
    for &i in order.iter().take(keep) {
        let l = eig.eigenvalues[i];
        if l <= 0.0 {
            continue;
        }
        let v = eig.eigenvectors.column(i);
        y.axpy(v.dot(&g) / (l + damping), &v, 1.0);
    }
    unscale(&y, cols, &norms, gram.ncols())
}

/// The full-length step (`p` parameters) of a solution `y` in column-scaled coordinates on
/// `cols`; a non-finite solution is an error.
fn unscale(y: &DVector<f64>, cols: &[usize], norms: &[f64], p: usize) -> Result<DVector<f64>, CalibError> {
    if y.iter().any(|v| !v.is_finite()) {
        return Err(CalibError::Numerical("non-finite step".into()));
    }
    let mut delta = DVector::zeros(p);
    for (k, &c) in cols.iter().enumerate() {
        if norms[k] > 0.0 {
            delta[c] = y[k] / norms[k];
        }
    }
    Ok(delta)
}
