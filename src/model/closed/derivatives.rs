//! Partial derivatives of a closed loop's equations by forward-mode automatic differentiation:
//! `F_X`, `F_q`, `F_θ` of the constraints and the Jacobian of the inverse-kinematics system.
//!
//! Each is evaluated with vector dual numbers carrying [`LANES`] partial derivatives at once: the
//! equations run `⌈columns / LANES⌉` times instead of once per column. Only the variables asked
//! for are seeded (the lanes past the last column stay empty). A lane's derivative is computed by
//! the same operations whatever the lane count, so the width changes the cost, not the values.
use super::{ClosedLoop, ConstraintSystem};
use crate::se3::Pose;
use nalgebra::DMatrix;
use num_dual::DualSVec64;

/// Partial derivatives carried by one evaluation: 12 covers the inverse-kinematics system of a
/// 6-input machine (or of pm5's 5 inputs, 11 variables) in one pass and a 35-parameter `F_θ` in
/// three (with 8 lanes: two and five).
const LANES: usize = 12;

type D = DualSVec64<LANES>;

/// Variables as duals, those of index `start..end` seeded (`end ≤ start + LANES`).
fn seeded(values: &[f64], offset: usize, start: usize, end: usize) -> Vec<D> {
    values
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let d = D::from_re(v);
            let k = i + offset;
            if k >= start && k < end {
                d.derivative(k - start)
            } else {
                d
            }
        })
        .collect()
}

/// Write the derivative parts of `f` into columns `start..` of `m`.
fn store(m: &mut DMatrix<f64>, f: &[D], start: usize) {
    let lanes = LANES.min(m.ncols() - start);
    for (i, fi) in f.iter().enumerate().take(m.nrows()) {
        if let Some(d) = &fi.eps.0 {
            for k in 0..lanes {
                m[(i, start + k)] = d[k];
            }
        }
    }
}

impl<C: ConstraintSystem> ClosedLoop<C> {
    /// `∂F/∂z` (6 × columns) for the variables `z = (X, q, θ)` of indices `from..from + columns`.
    fn constraint_partials(&self, x: &[f64; 6], q: &[f64], from: usize, columns: usize) -> DMatrix<f64> {
        let mut m = DMatrix::zeros(6, columns);
        for start in (from..from + columns).step_by(LANES) {
            let end = (start + LANES).min(from + columns);
            let xd = seeded(x, 0, start, end);
            let qd = seeded(q, 6, start, end);
            let td = seeded(&self.geometry, 6 + q.len(), start, end);
            let f = self.system.equations(&[xd[0], xd[1], xd[2], xd[3], xd[4], xd[5]], &qd, &td);
            store(&mut m, &f, start - from);
        }
        m
    }

    /// `F_X` (6 × 6).
    pub(super) fn jacobian_x_raw(&self, x: &[f64; 6], q: &[f64]) -> DMatrix<f64> {
        self.constraint_partials(x, q, 0, 6)
    }

    /// `F_q` (6 × inputs).
    pub(super) fn jacobian_q_raw(&self, x: &[f64; 6], q: &[f64]) -> DMatrix<f64> {
        self.constraint_partials(x, q, 6, q.len())
    }

    /// `F_θ` (6 × geometric parameters).
    pub(super) fn jacobian_theta_raw(&self, x: &[f64; 6], q: &[f64]) -> DMatrix<f64> {
        self.constraint_partials(x, q, 6 + q.len(), self.geometry.len())
    }

    /// Jacobian of the inverse-kinematics system (the constraints, then the task equations) with
    /// respect to `z = (X, q)`.
    pub(super) fn ik_jacobian(&self, z: &[f64], target: &Pose) -> DMatrix<f64> {
        let n = z.len();
        let mut m = DMatrix::zeros(n, n);
        let td: Vec<D> = self.geometry.iter().map(|&v| D::from_re(v)).collect();
        for start in (0..n).step_by(LANES) {
            let zd = seeded(z, 0, start, (start + LANES).min(n));
            let x = [zd[0], zd[1], zd[2], zd[3], zd[4], zd[5]];
            let mut e: Vec<D> = self.system.equations(&x, &zd[6..], &td).to_vec();
            e.extend(self.task_equations(&x, target));
            store(&mut m, &e, start);
        }
        m
    }
}
