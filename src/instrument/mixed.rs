//! Rows of several kinds in one fit: tracker rows (pose, position, reflector points) beside an
//! instrument's (seats, distances).
//!
//! A tracker row refers to no artifact point: its point index is [`NO_POINT`], and
//! [`Artifact`] predicts it as the mechanism inside predicts it — in the tracker's frame, through
//! the measurement frame [`crate::model::framed::Framed`] carries. The artifact points then live
//! in that frame too (an instrument row's prediction is the same tool point, relative to its
//! point), so the tracker places the base that an instrument alone cannot see, and the artifact
//! with it.
use super::Artifact;
use crate::measure::Measurement;
use crate::model::Mechanism;
use nalgebra::{DMatrix, Matrix6xX};

/// The point index of a row that refers to no artifact point: a tracker row.
pub const NO_POINT: f64 = -1.0;

/// Whether indexed inputs `q` of a mechanism with `n_q` inputs are a tracker row's.
pub fn is_tracker_row(q: &[f64], n_q: usize) -> bool {
    q.len() == n_q + 1 && q[n_q] == NO_POINT
}

/// Whether `indexed` measurements ([`super::index_points`]) hold tracker rows.
pub fn has_tracker_rows(indexed: &[Measurement]) -> bool {
    indexed.iter().any(|m| m.q.last() == Some(&NO_POINT))
}

impl<M: Mechanism> Artifact<M> {
    /// The inner inputs of a tracker row ([`NO_POINT`]); `None` for any other row.
    pub(super) fn tracker_inputs<'q>(&self, q: &'q [f64]) -> Option<&'q [f64]> {
        let n = self.inner.input_names().len();
        is_tracker_row(q, n).then(|| &q[..n])
    }

    /// An inner (6 × p) Jacobian with the artifact's columns (points, zeros) appended, zero: a
    /// tracker row does not depend on them.
    pub(super) fn padded(&self, jac: Matrix6xX<f64>) -> Matrix6xX<f64> {
        let p = jac.ncols();
        let mut out = Matrix6xX::zeros(self.artifact_columns().end);
        out.columns_mut(0, p).copy_from(&jac);
        out
    }

    /// Observed joints' rows over the inner parameters with the artifact's columns appended.
    pub(super) fn padded_rows(&self, rows: &DMatrix<f64>) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(rows.nrows(), self.artifact_columns().end);
        out.columns_mut(0, rows.ncols()).copy_from(rows);
        out
    }
}

/// `measurements` (tracker rows alone) indexed as [`super::index_points`] indexes tracker rows.
pub fn tracker_only(measurements: &[Measurement]) -> Vec<Measurement> {
    measurements
        .iter()
        .map(|m| {
            let mut q = m.q.clone();
            q.push(NO_POINT);
            Measurement { q, ..m.clone() }
        })
        .collect()
}
