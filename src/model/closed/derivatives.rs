//! Partial derivatives of a closed loop's equations by forward-mode automatic differentiation:
//! `F_X`, `F_q`, `F_θ` of the constraints and the Jacobian of the inverse-kinematics system.
//!
//! Each is evaluated with vector dual numbers carrying [`LANES`] partial derivatives at once: the
//! equations run `⌈columns / LANES⌉` times instead of once per column. Only the variables asked
//! for are seeded (the lanes past the last column stay empty). A lane's derivative is computed by
//! the same operations whatever the lane count, so the width changes the cost, not the values.
//!
//! # `F_θ` compressed by its sparsity
//! A geometric parameter usually enters few equations (one limb's), and parameters whose
//! equations are disjoint can share a lane: the lane then carries, in each equation, the
//! derivative by the one parameter that enters it (Curtis, Powell and Reid's column grouping).
//! [`ThetaGroups`] finds the equations each parameter enters (the nonzero rows of `F_θ` at two
//! generic points, once per mechanism) and groups the parameters greedily; the 5-DOF machine's
//! 35 parameters then fit one pass of [`THETA_LANES`] instead of three of 12, with the same
//! numbers (each equation sees the same operations on the same single seed).
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

/// Lanes of the compressed `F_θ` pass (the 5-DOF machine needs 13 groups, the Stewart platform 7).
const THETA_LANES: usize = 16;

type DT = DualSVec64<THETA_LANES>;

/// The equations each geometric parameter enters and a grouping of parameters with disjoint
/// equations (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct ThetaGroups {
    /// Per parameter: bit `i` set when it enters equation `i`.
    rows: Vec<u8>,
    /// Per parameter: its group (lane `group % THETA_LANES` of pass `group / THETA_LANES`).
    group: Vec<usize>,
    /// Number of groups.
    groups: usize,
}

impl ThetaGroups {
    /// The grouping of `system`'s parameters around the geometry `theta`: the rows of `F_θ` that
    /// are nonzero (or not finite) at either of two generic points near the home pose.
    pub(super) fn detect<C: ConstraintSystem>(system: &C, theta: &[f64]) -> Self {
        let home = system.home();
        let nq = system.input_names().len();
        let mut rows = vec![0u8; theta.len()];
        for (s, point) in [(0.37, 1.0), (-0.53, -1.0)].into_iter().enumerate() {
            let x: [f64; 6] = std::array::from_fn(|i| home[i] + point.1 * (0.7 + 0.13 * i as f64) * if i < 3 { 1.0 } else { 0.01 });
            let q: Vec<f64> = match system.inputs_for_pose(&x, theta) {
                Ok(q) if q.len() == nq => q,
                _ => (0..nq).map(|i| 1.0 + point.0 * (i as f64 + 1.0)).collect(),
            };
            let t: Vec<f64> = theta
                .iter()
                .enumerate()
                .map(|(j, v)| v + point.0 * 1e-3 * ((j + s) as f64 + 1.0).sin())
                .collect();
            let ungrouped = ClosedLoop {
                system: system.clone(),
                geometry: t,
                tool: [0.0; 3],
                base: [0.0; 6],
                frame_errors: false,
                solver: super::SolverOptions::default(),
                theta_groups: ThetaGroups::default(),
            };
            let m = ungrouped.constraint_partials(&x, &q, 6 + nq, theta.len());
            for (j, r) in rows.iter_mut().enumerate() {
                for i in 0..6 {
                    if m[(i, j)] != 0.0 || !m[(i, j)].is_finite() {
                        *r |= 1 << i;
                    }
                }
            }
        }
        // Greedy grouping: each parameter joins the first group none of whose equations it enters.
        let mut used: Vec<u8> = Vec::new();
        let group = rows
            .iter()
            .map(|&r| match used.iter().position(|&u| u & r == 0) {
                Some(g) => {
                    used[g] |= r;
                    g
                }
                None => {
                    used.push(r);
                    used.len() - 1
                }
            })
            .collect();
        ThetaGroups {
            rows,
            group,
            groups: used.len(),
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

    /// `F_θ` (6 × geometric parameters), by the grouped passes of [`ThetaGroups`] (one per
    /// [`THETA_LANES`] groups); without a grouping (or one that does not fit the geometry), one
    /// pass per [`LANES`] parameters.
    pub(super) fn jacobian_theta_raw(&self, x: &[f64; 6], q: &[f64]) -> DMatrix<f64> {
        let ng = self.geometry.len();
        let g = &self.theta_groups;
        if g.rows.len() != ng || g.groups == 0 {
            return self.constraint_partials(x, q, 6 + q.len(), ng);
        }
        let mut m = DMatrix::zeros(6, ng);
        let xd: [DT; 6] = std::array::from_fn(|i| DT::from_re(x[i]));
        let qd: Vec<DT> = q.iter().map(|&v| DT::from_re(v)).collect();
        for lo in (0..g.groups).step_by(THETA_LANES) {
            let td: Vec<DT> = self
                .geometry
                .iter()
                .zip(&g.group)
                .map(|(&v, &k)| {
                    let d = DT::from_re(v);
                    if k >= lo && k < lo + THETA_LANES {
                        d.derivative(k - lo)
                    } else {
                        d
                    }
                })
                .collect();
            let f = self.system.equations(&xd, &qd, &td);
            for (j, (&k, &rows)) in g.group.iter().zip(&g.rows).enumerate() {
                if k < lo || k >= lo + THETA_LANES {
                    continue;
                }
                for (i, fi) in f.iter().enumerate() {
                    if rows & (1 << i) != 0 {
                        if let Some(d) = &fi.eps.0 {
                            m[(i, j)] = d[k - lo];
                        }
                    }
                }
            }
        }
        m
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

#[cfg(test)]
mod tests {
    use crate::model::closed::{ClosedLoop, ConstraintSystem};
    use crate::model::presets::pm5::{Parasitic, Pm5};
    use crate::model::presets::stewart::{Stewart, StewartGeometry};
    use rand::SeedableRng;

    /// The grouped `F_θ` equals the one-pass-per-12-parameters `F_θ` exactly, at random
    /// assembled configurations and away from them, and needs fewer passes.
    fn grouped_equals_ungrouped<C: ConstraintSystem>(m: &ClosedLoop<C>, groups: usize) {
        let g = &m.theta_groups;
        assert_eq!(g.rows.len(), m.geometry.len());
        // One group per parameter of the limb that has the most.
        assert_eq!(g.groups, groups);
        // Every equation that some parameter enters is seen, and no group holds two
        // parameters of one equation.
        for a in 0..g.rows.len() {
            for b in a + 1..g.rows.len() {
                if g.group[a] == g.group[b] {
                    assert_eq!(g.rows[a] & g.rows[b], 0, "parameters {a} and {b} share an equation and a group");
                }
            }
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let qs = m.random_configurations(&mut rng, 20).unwrap();
        for (n, q) in qs.iter().enumerate() {
            let mut x = m.platform_pose(q, None).unwrap();
            if n % 2 == 1 {
                // Off the assembly: the equations' derivatives, not only at solutions.
                x[0] += 0.3;
                x[4] -= 0.002;
            }
            let a = m.jacobian_theta_raw(&x, q);
            // One pass per LANES parameters, without grouping.
            let b = m.constraint_partials(&x, q, 6 + q.len(), m.geometry.len());
            // Equal as numbers (an ungrouped pass may leave −0 where a parameter does not enter).
            assert!(a.iter().zip(b.iter()).all(|(u, v)| u == v), "{a}\n{b}");
            assert!(b.iter().any(|v| *v != 0.0));
        }
    }

    #[test]
    fn grouped_theta_jacobian_is_the_ungrouped_one() {
        grouped_equals_ungrouped(&Pm5::mechanism(Parasitic::Physical), 13);
        grouped_equals_ungrouped(&Pm5::mechanism(Parasitic::NominalGeometry), 13);
        grouped_equals_ungrouped(&Stewart::mechanism(StewartGeometry::default()), 7);
    }
}
