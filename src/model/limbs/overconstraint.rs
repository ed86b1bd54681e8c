//! Overconstrained limb mechanisms: the error parameters that would keep them from assembling.
//!
//! A planar 3-RRR, a five-bar or any machine whose limbs repeat a constraint (all joint axes
//! parallel: each limb holds the platform in the plane) has more independent closure equations
//! than its unknowns need at the drawing: its closure Jacobian `F_z` (rows: the limbs' closure
//! equations; columns: the platform twist, the passive and the sensed joints) has a left null
//! space. An error that moves the closure out of `F_z`'s range — a joint axis tilted out of the
//! plane — cannot be absorbed by any platform pose: the drawn mechanism with that error does not
//! assemble (the real one jams or deforms), so forward kinematics fails and a fit that moves such
//! a parameter never takes a step. Linearised, such parameters still look identifiable (the
//! least-squares closure spreads them over the platform), which is why they are found here and
//! held at their drawn values by identification, simulation and planning.
//!
//! A parameter whose closure column has a component outside `range(F_z)` above [`TOLERANCE`]
//! of its norm at the home configuration breaks the assembly. Combinations that stay consistent
//! (every axis tilted together: a tilted plane) are the measurement frame's business.
use super::{JointRole, LimbMechanism};
use nalgebra::DMatrix;

/// Relative part of a parameter's closure column outside `range(F_z)` above which it breaks the
/// assembly (those of a planar machine are 0 to round-off, about 1e-16, or of order 1).
const TOLERANCE: f64 = 1e-8;

/// Singular values of `F_z` below this fraction of the largest are its left null space.
const RANK_TOLERANCE: f64 = 1e-10;

impl LimbMechanism {
    /// The error parameters that an overconstrained mechanism cannot take alone, in parameter
    /// order: those whose closure column at home has a part outside the range of the closure
    /// Jacobian (with every joint that is not actuated among its unknowns). Empty for a mechanism
    /// whose closure equations are independent (every mechanism that is not overconstrained).
    pub fn assembly_breaking(&self) -> Vec<usize> {
        let q = self.home_inputs();
        let passive = self.home_passive();
        let joints = self.joints_of(&q, &passive);
        // Every joint that is not actuated is an unknown of the structure: sensed joints
        // overdetermine the closure only through their readings.
        let (_, all) = self.closure(&self.home, &joints, false);
        let actuated: Vec<bool> = self
            .inputs
            .iter()
            .map(|&(i, j)| self.limbs[i].roles[j] == JointRole::Actuated)
            .collect();
        let keep: Vec<usize> = (0..all.ncols())
            .filter(|&c| c < 6 || c - 6 >= actuated.len() || !actuated[c - 6])
            .collect();
        let fz = DMatrix::from_fn(all.nrows(), keep.len(), |r, c| all[(r, keep[c])]);
        if fz.nrows() <= fz.ncols() {
            return Vec::new();
        }
        let fp = self.closure_params(&self.home, &joints);
        if fz.iter().chain(fp.iter()).any(|v| !v.is_finite()) {
            return Vec::new();
        }
        let rows = fz.nrows();
        let svd = fz.svd(true, false);
        let Some(u) = svd.u else { return Vec::new() };
        let hi = svd.singular_values.max();
        let basis: Vec<usize> = (0..svd.singular_values.len())
            .filter(|&k| svd.singular_values[k] > hi * RANK_TOLERANCE)
            .collect();
        if basis.len() >= rows {
            return Vec::new();
        }
        let range = DMatrix::from_fn(u.nrows(), basis.len(), |r, c| u[(r, basis[c])]);
        (0..fp.ncols())
            .filter(|&j| {
                let col = fp.column(j);
                let norm = col.norm();
                let outside = (col - &range * (range.transpose() * col)).norm();
                norm > 0.0 && outside > TOLERANCE * norm
            })
            .collect()
    }
}
