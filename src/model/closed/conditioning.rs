//! The conditioning check of a closed loop's solves: whether a square Jacobian (`F_X` at a
//! forward solution, the inverse-kinematics system at an inverse one) is too close to singular.
use nalgebra::DMatrix;

/// Condition number of a square matrix; infinite when it holds a non-finite entry (nalgebra's
/// SVD does not return on NaN input, so it must never see one).
fn condition(m: &DMatrix<f64>) -> f64 {
    if m.iter().any(|v| !v.is_finite()) {
        return f64::INFINITY;
    }
    let s = m.clone().singular_values();
    let hi = s.iter().cloned().fold(0.0, f64::max);
    let lo = s.iter().cloned().fold(f64::INFINITY, f64::min);
    if lo > 0.0 {
        hi / lo
    } else {
        f64::INFINITY
    }
}

/// `‖m⁻¹‖₁` of a square matrix by Gauss–Jordan elimination with partial pivoting on one flat
/// scratch buffer `[m | I]` (row-major); `None` at a zero or non-finite pivot. For the 6 × 6 and
/// 11 × 11 Jacobians checked here this is several times cheaper than nalgebra's LU inverse
/// (generic indexing, one allocation per column); the bound below only compares it to a limit.
#[allow(clippy::needless_range_loop)] // the elimination reads best with indices
fn inverse_norm1(m: &DMatrix<f64>) -> Option<f64> {
    let n = m.nrows();
    let w = 2 * n;
    let mut a = vec![0.0; n * w];
    let mut prow = vec![0.0; w];
    for r in 0..n {
        for c in 0..n {
            a[r * w + c] = m[(r, c)];
        }
        a[r * w + n + r] = 1.0;
    }
    for col in 0..n {
        let mut p = col;
        for r in col + 1..n {
            if a[r * w + col].abs() > a[p * w + col].abs() {
                p = r;
            }
        }
        let pivot = a[p * w + col];
        if pivot == 0.0 || !pivot.is_finite() {
            return None;
        }
        if p != col {
            for c in 0..w {
                a.swap(p * w + c, col * w + c);
            }
        }
        let inv = 1.0 / pivot;
        for v in &mut a[col * w + col..(col + 1) * w] {
            *v *= inv;
        }
        prow[col..].copy_from_slice(&a[col * w + col..(col + 1) * w]);
        for (r, row) in a.chunks_exact_mut(w).enumerate() {
            let f = row[col];
            if r == col || f == 0.0 {
                continue;
            }
            for (v, p) in row[col..].iter_mut().zip(&prow[col..]) {
                *v -= f * p;
            }
        }
    }
    Some(
        (0..n)
            .map(|c| (0..n).map(|r| a[r * w + n + c].abs()).sum::<f64>())
            .fold(0.0, f64::max),
    )
}

/// `Some(condition number)` when that of the square matrix `m` exceeds `limit`, `None` when it does
/// not. The bound `cond₂ ≤ n·‖m‖₁·‖m⁻¹‖₁` settles the common, well-conditioned case without the
/// SVD (several times dearer for a 6 × 6 matrix, and this runs once per forward kinematics); near
/// the limit, or when the inverse fails, the SVD decides (so the answer does not depend on the
/// round-off of the bound).
pub(super) fn ill_conditioned(m: &DMatrix<f64>, limit: f64) -> Option<f64> {
    if m.iter().any(|v| !v.is_finite()) {
        return Some(f64::INFINITY);
    }
    if let Some(inv_norm) = inverse_norm1(m) {
        let norm1 = m.column_iter().map(|c| c.iter().map(|v| v.abs()).sum::<f64>()).fold(0.0, f64::max);
        let bound = m.nrows() as f64 * norm1 * inv_norm;
        if bound.is_finite() && bound <= limit {
            return None;
        }
    }
    let c = condition(m);
    (c > limit).then_some(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_norm_is_that_of_the_lu_inverse() {
        let m = DMatrix::from_fn(7, 7, |r, c| ((r * 7 + c) as f64 * 0.37).sin() + if r == c { 2.0 } else { 0.0 });
        let inv = m.clone().try_inverse().unwrap();
        let want = inv
            .column_iter()
            .map(|c| c.iter().map(|v| v.abs()).sum::<f64>())
            .fold(0.0, f64::max);
        let got = inverse_norm1(&m).unwrap();
        assert!((got - want).abs() <= 1e-12 * want, "{got} vs {want}");
        assert!(inverse_norm1(&DMatrix::zeros(3, 3)).is_none());
        // A singular matrix is caught by the SVD.
        let mut s = DMatrix::identity(4, 4);
        s[(3, 3)] = 0.0;
        assert_eq!(ill_conditioned(&s, 1e10), Some(f64::INFINITY));
        assert_eq!(ill_conditioned(&DMatrix::identity(4, 4), 1e10), None);
    }
}
