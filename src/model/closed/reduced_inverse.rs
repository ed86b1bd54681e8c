//! Inverse kinematics reduced to the coordinates the task leaves free.
//!
//! A task fixes the tool pose up to a few free coordinates `u`: none for [`Task::Full`], the
//! rotation `ψ` about the tool axis for [`Task::PositionAndAxis`]. Every tool pose
//! `T(u) = T_seed·Rz(ψ)` meets the task exactly, its platform coordinates `X(u)` follow from the
//! frames, and the system's per-limb closed form gives the inputs `q(X)` that satisfy the limb
//! equations. What is left are the constraints the inputs do not drive (the parasitic-motion
//! equation of the 5-DOF machine): `6 − inputs` equations in `6 − dof` unknowns, solved here by
//! Gauss–Newton with a secant derivative (one evaluation per step). That is one unknown for the
//! 5-DOF machine and none for the Stewart platform, instead of Newton on the `6 + inputs`
//! unknowns `(X, q)` with an automatic-differentiation Jacobian per step.
//!
//! [`ClosedLoop::inverse_with_pose`] tries this first and verifies its answer on the full system
//! (same residual tolerance, same conditioning check); where it does not apply or does not
//! converge the full Newton decides, so the reduction changes speed, not answers.
use super::{max_abs, ClosedLoop, ConstraintSystem, Task, MAX_BACKTRACKS};
use crate::se3::Pose;
use nalgebra::{UnitQuaternion, Vector3};

/// Step of the first (forward) difference of the free rotation, and the shortest step that
/// updates the secant slope (rad).
const STEP: f64 = 1e-6;

/// One evaluation at a value of the free coordinate: platform coordinates, inputs, residual.
type Point = ([f64; 6], Vec<f64>, [f64; 6]);

impl<C: ConstraintSystem> ClosedLoop<C> {
    /// The platform pose, inputs and constraint residual at the tool pose `seed·Rz(ψ)`; `None`
    /// where a limb cannot reach it.
    fn at_twist(&self, seed: &Pose, psi: f64) -> Option<Point> {
        let pose = if psi == 0.0 {
            *seed
        } else {
            seed * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), psi)
        };
        let x = self.platform_of_tool(&pose);
        let q = self.system.inputs_for_pose(&x, &self.geometry).ok()?;
        let f = self.system.equations(&x, &q, &self.geometry);
        f.iter().all(|v| v.is_finite()).then_some((x, q, f))
    }

    /// Inputs and platform coordinates that reach `seed` (a tool pose meeting the task, its
    /// twist about the tool axis the starting guess): `None` when the task has no reduction,
    /// a limb cannot reach, or the remaining constraints do not converge to the solver
    /// tolerance.
    pub(super) fn inverse_reduced(&self, seed: &Pose) -> Option<(Vec<f64>, [f64; 6])> {
        let free = match self.system.task() {
            Task::Full => false,
            Task::PositionAndAxis => true,
            Task::Position | Task::HeightAndAxis | Task::PositionAndYaw => return None,
        };
        let tol = self.solver.tolerance;
        let mut psi = 0.0;
        let (mut x, mut q, mut f) = self.at_twist(seed, psi)?;
        let mut norm = max_abs(&f);
        if norm <= tol {
            return Some((q, x));
        }
        if !free {
            return None;
        }
        // The slope df/dψ: a forward difference first, then secants through the iterates (one
        // evaluation per step); a step shorter than the difference step keeps the last slope.
        let (_, _, f1) = self.at_twist(seed, STEP)?;
        let mut slope: [f64; 6] = std::array::from_fn(|k| (f1[k] - f[k]) / STEP);
        for _ in 0..self.solver.max_iterations {
            let jj: f64 = slope.iter().map(|j| j * j).sum();
            let jf: f64 = slope.iter().zip(&f).map(|(j, v)| j * v).sum();
            if !(jj > 0.0 && jj.is_finite()) {
                return None;
            }
            let step = -jf / jj;
            let mut s = 1.0;
            let mut accepted = None;
            for _ in 0..MAX_BACKTRACKS {
                if let Some(p) = self.at_twist(seed, psi + s * step) {
                    if max_abs(&p.2) < norm {
                        accepted = Some(p);
                        break;
                    }
                }
                s *= 0.5;
            }
            let (xn, qn, fn_) = accepted?;
            let dpsi = s * step;
            if dpsi.abs() >= STEP {
                slope = std::array::from_fn(|k| (fn_[k] - f[k]) / dpsi);
            }
            psi += dpsi;
            (x, q, f) = (xn, qn, fn_);
            norm = max_abs(&f);
            if norm <= tol {
                return Some((q, x));
            }
        }
        (norm <= tol).then_some((q, x))
    }
}
