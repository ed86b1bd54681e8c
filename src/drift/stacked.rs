//! The least-squares problem of [`super::check`] and [`super::update`] at one linearisation: the
//! prior's rows over whitened coordinates `z` (the parameters' change `L·z`) stacked over the new
//! poses' noise-weighted rows, with the released patterns' coefficients `β` free (no prior rows),
//! solved in square-root form ([`crate::identify::rls_solve`]: the prior's rows are the first
//! block, each pose's rows the next).
use crate::error::CalibError;
use crate::identify::{rls_solve, Linearization};
use nalgebra::{DMatrix, DVector};

/// The stacked rows `K·u ≈ rhs` over `u = [z; β]`.
pub(super) struct Stacked {
    pub k: DMatrix<f64>,
    pub rhs: DVector<f64>,
    /// First row of each block: the prior's, then each pose's.
    offsets: Vec<usize>,
    /// Rows of the prior (`r`, the size of `z`).
    pub r: usize,
}

/// A least-squares solution of the stacked rows.
pub(super) struct Solution {
    /// The step in `[z; β]` (and a candidate's coefficients last).
    pub u: DVector<f64>,
    /// `|rhs − K·u|²`.
    pub cost: f64,
}

impl Stacked {
    /// The rows at a linearisation `lin` of the model moved by `L·z + D·β` from the prior's
    /// estimate: the prior's rows `I·δz = −z`, the new rows `A·L·δz + A·D·δβ = e`.
    pub fn new(lin: &Linearization, l: &DMatrix<f64>, released: &DMatrix<f64>, z: &DVector<f64>) -> Stacked {
        let (r, g, m) = (l.ncols(), released.ncols(), lin.residual.len());
        let mut k = DMatrix::zeros(r + m, r + g);
        k.view_mut((0, 0), (r, r)).fill_with_identity();
        k.view_mut((r, 0), (m, r)).copy_from(&(&lin.jacobian * l));
        if g > 0 {
            k.view_mut((r, r), (m, g)).copy_from(&(&lin.jacobian * released));
        }
        let mut rhs = DVector::zeros(r + m);
        rhs.rows_mut(0, r).copy_from(&(-z));
        rhs.rows_mut(r, m).copy_from(&lin.residual);
        let mut offsets = vec![0];
        offsets.extend(lin.offsets.iter().map(|o| o + r));
        Stacked { k, rhs, offsets, r }
    }

    /// The stacked matrix with the extra data columns `extra` (new rows only; zero in the prior's
    /// rows) appended.
    fn with_extra(&self, extra: Option<&DMatrix<f64>>) -> DMatrix<f64> {
        let Some(x) = extra else {
            return self.k.clone();
        };
        let (rows, cols) = self.k.shape();
        let mut k = DMatrix::zeros(rows, cols + x.ncols());
        k.view_mut((0, 0), (rows, cols)).copy_from(&self.k);
        k.view_mut((self.r, cols), (rows - self.r, x.ncols())).copy_from(x);
        k
    }

    /// The least-squares solution, with the extra data columns `extra` (new rows only) free too;
    /// `None` when the columns are not all determined (a pattern these poses do not see).
    pub fn solve(&self, extra: Option<&DMatrix<f64>>) -> Result<Option<Solution>, CalibError> {
        let k = self.with_extra(extra);
        let cols: Vec<usize> = (0..k.ncols()).collect();
        if k.ncols() > k.nrows() {
            return Ok(None);
        }
        let lin = Linearization {
            angular_rows: vec![false; k.nrows()],
            jacobian: k,
            residual: self.rhs.clone(),
            offsets: self.offsets.clone(),
        };
        let u = match rls_solve(&lin, &cols) {
            Ok(u) => u,
            Err(CalibError::Numerical(_)) => return Ok(None),
            Err(e) => return Err(e),
        };
        let cost = (&self.rhs - &lin.jacobian * &u).norm_squared();
        Ok(Some(Solution { u, cost }))
    }

    /// The covariance of `[z; β]` (unit weight), with the extra data columns `extra` free too.
    pub fn covariance(&self, extra: Option<&DMatrix<f64>>) -> Option<DMatrix<f64>> {
        let k = self.with_extra(extra);
        let n = k.tr_mul(&k);
        let s: Vec<f64> = (0..n.nrows()).map(|i| n[(i, i)].max(0.0).sqrt()).collect();
        if s.iter().any(|v| *v <= 0.0) {
            return None;
        }
        let scaled = DMatrix::from_fn(n.nrows(), n.ncols(), |i, j| n[(i, j)] / (s[i] * s[j]));
        let inv = scaled.try_inverse()?;
        Some(DMatrix::from_fn(inv.nrows(), inv.ncols(), |i, j| inv[(i, j)] / (s[i] * s[j])))
    }
}
