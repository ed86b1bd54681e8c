//! Recursive least squares (the first paper's estimator), in square-root information form.
use super::Linearization;
use crate::error::CalibError;
use crate::identifiability;
use nalgebra::{DMatrix, DVector};

/// Recursive least squares in square-root information form, pose block after pose block, on the
/// columns `cols` (scaled to unit norm): `[R d; A_i b_i] = Q·[R' d'; 0 e]`, then `R·x = d`.
///
/// Equal to batch least squares to round-off: each pose only updates the triangular factor of
/// the information matrix by orthogonal transformations, never inverts it. (A covariance-form
/// recursion `P ← P − K·A·P` started from an ill-conditioned first block of poses keeps its error
/// through every update; the 3T1R machine showed 1e-4 relative.)
pub fn rls_solve(lin: &Linearization, cols: &[usize]) -> Result<DVector<f64>, CalibError> {
    let (scaled, norms) = identifiability::scale_columns(&lin.jacobian, cols);
    let k = cols.len();
    let rows = scaled.nrows();
    let mut ends: Vec<usize> = lin.offsets.iter().skip(1).copied().collect();
    ends.push(rows);
    let mut r = DMatrix::<f64>::zeros(k, k + 1);
    let mut start = 0;
    for &e in &ends {
        let m = e - start;
        let mut stack = DMatrix::zeros(k + m, k + 1);
        stack.view_mut((0, 0), (k, k + 1)).copy_from(&r);
        stack.view_mut((k, 0), (m, k)).copy_from(&scaled.rows(start, m));
        stack.view_mut((k, k), (m, 1)).copy_from(&lin.residual.rows(start, m));
        let f = stack.qr().r();
        r.fill(0.0);
        let n = f.nrows().min(k);
        r.view_mut((0, 0), (n, k + 1)).copy_from(&f.view((0, 0), (n, k + 1)));
        start = e;
    }
    let tri = r.view((0, 0), (k, k)).into_owned();
    let d = r.column(k).into_owned();
    let dmax = (0..k).map(|i| tri[(i, i)].abs()).fold(0.0, f64::max);
    if (0..k).any(|i| tri[(i, i)].abs() <= 1e-13 * dmax) {
        return Err(CalibError::Numerical(
            "recursive least squares: the data never reach full rank".into(),
        ));
    }
    let x = tri
        .solve_upper_triangular(&d)
        .ok_or_else(|| CalibError::Numerical("recursive least squares: singular information matrix".into()))?;
    let mut delta = DVector::zeros(lin.jacobian.ncols());
    for (i, &c) in cols.iter().enumerate() {
        delta[c] = x[i] / norms[i];
    }
    Ok(delta)
}
