//! Closed-loop (parallel) mechanisms described by constraint equations.
//!
//! A parallel mechanism is a set of limb constraint equations
//!
//! ```text
//! F(X, q, θ) = 0,   F: 6 equations
//! ```
//!
//! in the platform pose `X = (x, y, z, α, β, γ)` (position of the platform frame and its X-Y-Z
//! Euler angles, `R = Rot(x,α)·Rot(y,β)·Rot(z,γ)`, eq. (2) of the 5-DOF paper), the actuator values
//! `q` and the geometric parameters `θ` — the closed-loop vector method of §2.2 of the 5-DOF
//! paper, plus any extra constraint such as its parasitic motion (eq. (15)–(16)). A
//! [`ConstraintSystem`] writes these equations once, generic over the scalar type
//! ([`Scalar`]: `f64` or a forward-mode dual number of `num-dual`); [`ClosedLoop`] derives
//! everything else from that single description:
//!
//! * **forward kinematics**: damped Newton on `F(·, q, θ) = 0` from a seed (by default the home
//!   pose), with [`KinError::NoConvergence`] or [`KinError::Singular`] when it fails;
//! * **inverse kinematics**: the system's per-limb closed form gives a first guess (and
//!   [`KinError::Unreachable`] when a limb cannot reach), then Newton on the square system
//!   `F(X, q, θ) = 0`, `G(X) = 0` in `(X, q)`, where `G` matches the commanded part of the tool
//!   pose ([`Task`]); actuator strokes are checked ([`KinError::OutOfWorkspace`]);
//! * **the identification Jacobian** by the implicit function theorem,
//!   `dX = −F_X⁻¹·F_θ·dθ` (what eq. (14)–(20) of the paper derive by hand), mapped through the
//!   base and tool frames to the *spatial* twist Jacobian of [`Mechanism`]:
//!   `ω = vee(dR·Rᵀ)`, `v = dp − ω × p`.
//!
//! All partial derivatives `F_X`, `F_q`, `F_θ` and those of the tool pose come from forward-mode
//! automatic differentiation (vector dual numbers, many variables per pass; `F_θ` in passes
//! grouped by its sparsity, see `derivatives`): exact to round-off.
//!
//! # Frames (§2.3 of the 5-DOF paper)
//! With frame errors enabled the parameter vector is `[θ_geometry, t (3), base (6)]`: the tool
//! offset `t` (platform frame) and the base pose `(x0, y0, z0, α0, β0, γ0)` (X-Y-Z Euler angles).
//! The tool pose in the world (measurement) frame is
//! `T_tool = T_base · T(X) · Trans(t)`, its rotation that of the platform. All parameters are
//! additive: [`Mechanism::retract`] is `θ ← θ + δ`.
use super::{check_inputs, Mechanism};
use crate::error::KinError;
use crate::params::{Param, Unit};
use crate::se3::{self, Pose};
use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, Matrix6xX, Rotation3, Translation3, UnitQuaternion, Vector3, LU, U6};
use num_dual::DualNum;
use rand::{Rng, RngExt};

/// Scalar types the constraint equations are written for: `f64` and forward-mode dual numbers.
pub trait Scalar: DualNum<Primitive = f64> + Copy + Send + Sync {}
impl<T: DualNum<Primitive = f64> + Copy + Send + Sync> Scalar for T {}

mod conditioning;
mod derivatives;
mod mechanism;
mod reduced_inverse;
/// Small generic 3-vector / 3×3-matrix algebra on [`Scalar`]s (row-major arrays), used to write
/// constraint equations once for `f64` and dual numbers.
pub mod v3;

use conditioning::ill_conditioned;
use v3::{M3, V3};

pub use crate::model::Task;

/// A box of platform poses `X = (x, y, z, α, β, γ)` (mm, rad): the prescribed workspace.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Workspace {
    /// Lower bounds.
    pub min: [f64; 6],
    /// Upper bounds.
    pub max: [f64; 6],
}

impl Workspace {
    /// Whether `x` lies in the box (a coordinate with `min == max` is not checked: a parasitic
    /// coordinate such as γ of the 5-DOF machine).
    pub fn contains(&self, x: &[f64; 6]) -> bool {
        (0..6).all(|i| self.min[i] == self.max[i] || (x[i] >= self.min[i] - 1e-9 && x[i] <= self.max[i] + 1e-9))
    }
    /// A uniformly random pose in the box.
    pub fn sample<R: Rng>(&self, rng: &mut R) -> [f64; 6] {
        let mut x = [0.0; 6];
        for (i, v) in x.iter_mut().enumerate() {
            *v = if self.max[i] > self.min[i] {
                rng.random_range(self.min[i]..self.max[i])
            } else {
                self.min[i]
            };
        }
        x
    }
}

/// The constraint equations of a closed-loop mechanism (see the [module docs](self)).
pub trait ConstraintSystem: Clone + Send + Sync + 'static {
    /// Short name, e.g. `"pm5"`.
    fn name(&self) -> &str;
    /// Names of the actuator inputs `q`, in order.
    fn input_names(&self) -> Vec<String>;
    /// Geometric parameters (error names, units, groups), in the order of `θ`.
    fn geometry_params(&self) -> Vec<Param>;
    /// Nominal values of the geometric parameters `θ` (absolute values, mm and rad).
    fn nominal_geometry(&self) -> Vec<f64>;
    /// The six constraint equations `F(X, q, θ)`; they vanish on every assembled configuration.
    fn equations<D: Scalar>(&self, x: &[D; 6], q: &[D], theta: &[D]) -> [D; 6];
    /// Inputs for a full platform pose `x` from each limb's closed-form inverse kinematics
    /// (equations not involving `q` may be violated by `x`). Errors: [`KinError::Unreachable`].
    fn inputs_for_pose(&self, x: &[f64; 6], theta: &[f64]) -> Result<Vec<f64>, KinError>;
    /// What the actuators command.
    fn task(&self) -> Task;
    /// Home platform pose (the forward-kinematics seed).
    fn home(&self) -> [f64; 6];
    /// Actuator strokes `(min, max)` per input.
    fn strokes(&self) -> Vec<(f64, f64)>;
    /// The prescribed workspace.
    fn workspace(&self) -> Workspace;
    /// The machine drawn at platform pose `x` and inputs `q` on geometry `θ`, for the report's
    /// 3-D view ([`Mechanism::skeleton`]): polylines in the base frame (mm), e.g. each limb
    /// from the base through its actuator to the platform, and the platform. Empty (default)
    /// without a drawing.
    fn skeleton(&self, x: &[f64; 6], q: &[f64], theta: &[f64]) -> Vec<Vec<Vector3<f64>>> {
        let _ = (x, q, theta);
        Vec::new()
    }
}

/// Partial derivatives of the constraint equations at one configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct ConstraintJacobians {
    /// `F_X` (6×6).
    pub x: DMatrix<f64>,
    /// `F_q` (6 × inputs).
    pub q: DMatrix<f64>,
    /// `F_θ` (6 × geometric parameters).
    pub theta: DMatrix<f64>,
}

/// Newton-solver settings of [`ClosedLoop`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverOptions {
    /// Maximum Newton iterations.
    pub max_iterations: usize,
    /// Convergence: max-norm of the constraint residual (mm).
    pub tolerance: f64,
    /// Condition number of the Newton matrix above which the configuration is singular.
    pub max_condition: f64,
    /// Inverse kinematics tries the reduced solve first (only the coordinates the task leaves
    /// free, the inputs from the per-limb closed form; its answer is kept only if the full system
    /// holds). Off: Newton on all of `(X, q)` from the start. Same answers, the reduced solve is
    /// about twice as fast.
    pub reduced_inverse: bool,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            max_iterations: 50,
            tolerance: 1e-11,
            max_condition: 1e10,
            reduced_inverse: true,
        }
    }
}

/// A closed-loop mechanism: a [`ConstraintSystem`] with its current geometry, tool and base
/// frames. Implements [`Mechanism`].
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedLoop<C: ConstraintSystem> {
    system: C,
    geometry: Vec<f64>,
    tool: [f64; 3],
    base: [f64; 6],
    frame_errors: bool,
    solver: SolverOptions,
    /// The equations each geometric parameter enters, for the grouped `F_θ` passes.
    theta_groups: derivatives::ThetaGroups,
}

/// Names of the tool-offset parameters.
pub const TOOL_PARAMS: [&str; 3] = ["dtx", "dty", "dtz"];
/// Names of the base-frame parameters.
pub const BASE_PARAMS: [&str; 6] = ["dx0", "dy0", "dz0", "dα0", "dβ0", "dγ0"];

pub use crate::se3::euler_xyz;

/// The pose of platform coordinates `X`.
pub fn pose_of(x: &[f64; 6]) -> Pose {
    let r = v3::rot_xyz(x[3], x[4], x[5]);
    let m = Matrix3::new(r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2]);
    se3::pose_from_rotation(&m, &Vector3::new(x[0], x[1], x[2]))
}

/// Platform coordinates `X` of a pose.
pub fn coords_of(t: &Pose) -> [f64; 6] {
    let e = euler_xyz(&se3::rotation_matrix(t));
    let p = t.translation.vector;
    [p.x, p.y, p.z, e[0], e[1], e[2]]
}

/// Tool position and rotation `T_base · T(X) · Trans(t)` for any scalar.
pub fn tool_pose_generic<D: Scalar>(x: &[D; 6], tool: &[D; 3], base: &[D; 6]) -> (V3<D>, M3<D>) {
    let r = v3::rot_xyz(x[3], x[4], x[5]);
    let r0 = v3::rot_xyz(base[3], base[4], base[5]);
    let p_plat = v3::add(&[x[0], x[1], x[2]], &v3::mul(&r, tool));
    let p = v3::add(&[base[0], base[1], base[2]], &v3::mul(&r0, &p_plat));
    (p, v3::matmul(&r0, &r))
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// Halvings of a Newton step before a solve gives up (the step is then 2⁻⁴⁰ of its length).
const MAX_BACKTRACKS: usize = 40;

/// Inputs, platform coordinates and the inverse-kinematics system's Jacobian at the solution
/// ([`ClosedLoop::inverse_with_jacobian`]).
pub type InverseSolution = (Vec<f64>, [f64; 6], DMatrix<f64>);

/// LU factors of the 6 × 6 constraint Jacobian `F_X` (fixed size: no allocation, unrolled; the
/// same elimination as the dynamic LU, so the same numbers).
type Factors = LU<f64, U6, U6>;

impl<C: ConstraintSystem> ClosedLoop<C> {
    /// The mechanism at its nominal geometry, with base and tool frame errors as parameters
    /// (`frame_errors`) or without (frames then fixed: identity base, `tool` offset).
    pub fn new(system: C, tool: [f64; 3], frame_errors: bool) -> Self {
        let geometry = system.nominal_geometry();
        let theta_groups = derivatives::ThetaGroups::detect(&system, &geometry);
        ClosedLoop {
            theta_groups,
            system,
            geometry,
            tool,
            base: [0.0; 6],
            frame_errors,
            solver: SolverOptions::default(),
        }
    }

    /// The same mechanism with the tool offset `t` (mm, platform frame) and the base pose
    /// `(x0, y0, z0, α0, β0, γ0)` (mm, rad; X-Y-Z Euler angles) replaced, e.g. from a model file.
    pub fn with_frames(mut self, tool: [f64; 3], base: [f64; 6]) -> Self {
        self.tool = tool;
        self.base = base;
        self
    }

    /// Whether the tool offset and base pose are error parameters.
    pub fn frame_errors(&self) -> bool {
        self.frame_errors
    }

    /// Replace the Newton settings.
    pub fn with_solver(mut self, solver: SolverOptions) -> Self {
        self.solver = solver;
        self
    }

    /// This machine with the geometry `values` of [`Mechanism::geometry`] (`θ`, then the tool
    /// offset and the base frame); an error when the length does not fit.
    pub fn with_geometry(&self, values: &[f64]) -> Result<Self, String> {
        let (ng, nt) = (self.geometry.len(), self.tool.len() + self.base.len());
        if values.len() != ng + nt {
            return Err(format!(
                "{} geometry values for the {} machine (expected {})",
                values.len(),
                self.system.name(),
                ng + nt
            ));
        }
        let mut out = self.clone();
        out.geometry.copy_from_slice(&values[..ng]);
        out.tool.copy_from_slice(&values[ng..ng + 3]);
        out.base.copy_from_slice(&values[ng + 3..]);
        Ok(out)
    }

    /// The constraint system.
    pub fn system(&self) -> &C {
        &self.system
    }
    /// Current geometric parameters `θ` (absolute values).
    pub fn geometry(&self) -> &[f64] {
        &self.geometry
    }
    /// Current tool offset `t` (mm, platform frame).
    pub fn tool(&self) -> [f64; 3] {
        self.tool
    }
    /// Current base pose `(x0, y0, z0, α0, β0, γ0)`.
    pub fn base(&self) -> [f64; 6] {
        self.base
    }
    /// All parameter values in Jacobian column order (geometry, then tool and base when frame
    /// errors are enabled).
    pub fn values(&self) -> Vec<f64> {
        let mut v = self.geometry.clone();
        if self.frame_errors {
            v.extend_from_slice(&self.tool);
            v.extend_from_slice(&self.base);
        }
        v
    }

    /// Constraint residual `F(X, q, θ)` at the current geometry. Errors: wrong input count.
    pub fn residual(&self, x: &[f64; 6], q: &[f64]) -> Result<[f64; 6], KinError> {
        check_inputs(q, self.system.input_names().len())?;
        Ok(self.residual_raw(x, q))
    }

    /// `F_X` (6×6), `F_q` (6 × inputs) and `F_θ` (6 × geometric parameters) at `(x, q)`, by
    /// forward-mode differentiation. Errors: wrong input count.
    pub fn constraint_jacobians(&self, x: &[f64; 6], q: &[f64]) -> Result<ConstraintJacobians, KinError> {
        check_inputs(q, self.system.input_names().len())?;
        Ok(ConstraintJacobians {
            x: self.jacobian_x_raw(x, q),
            q: self.jacobian_q_raw(x, q),
            theta: self.jacobian_theta_raw(x, q),
        })
    }

    fn residual_raw(&self, x: &[f64; 6], q: &[f64]) -> [f64; 6] {
        self.system.equations(x, q, &self.geometry)
    }

    /// Check inputs against the strokes.
    pub fn check_strokes(&self, q: &[f64]) -> Result<(), KinError> {
        let names = self.system.input_names();
        for (i, (&v, &(lo, hi))) in q.iter().zip(self.system.strokes().iter()).enumerate() {
            if v < lo - 1e-9 || v > hi + 1e-9 {
                return Err(KinError::OutOfWorkspace(format!(
                    "actuator {} = {v:.3} outside its stroke [{lo}, {hi}]",
                    names.get(i).map(String::as_str).unwrap_or("?")
                )));
            }
        }
        Ok(())
    }

    /// Check that platform coordinates lie in the prescribed workspace.
    pub fn check_workspace(&self, x: &[f64; 6]) -> Result<(), KinError> {
        let ws = self.system.workspace();
        if ws.contains(x) {
            Ok(())
        } else {
            Err(KinError::OutOfWorkspace(format!(
                "platform pose (x, y, z) = ({:.2}, {:.2}, {:.2}) mm, (α, β, γ) = ({:.3}, {:.3}, {:.3})° outside the prescribed workspace",
                x[0],
                x[1],
                x[2],
                x[3].to_degrees(),
                x[4].to_degrees(),
                x[5].to_degrees()
            )))
        }
    }

    /// Forward kinematics of the platform: Newton on `F(·, q, θ) = 0` from `seed` (default: home).
    pub fn platform_pose(&self, q: &[f64], seed: Option<&[f64; 6]>) -> Result<[f64; 6], KinError> {
        self.solve_platform(q, seed).map(|(x, _)| x)
    }

    /// [`ClosedLoop::platform_pose`] and the LU factors of the constraint Jacobian `F_X` at the
    /// solution (computed for the conditioning check, and reused by the identification Jacobian).
    fn solve_platform(&self, q: &[f64], seed: Option<&[f64; 6]>) -> Result<([f64; 6], Factors), KinError> {
        check_inputs(q, self.system.input_names().len())?;
        self.check_strokes(q)?;
        let mut x = seed.copied().unwrap_or_else(|| self.system.home());
        let mut f = self.residual_raw(&x, q);
        let mut norm = max_abs(&f);
        for _ in 0..self.solver.max_iterations {
            if !norm.is_finite() {
                break;
            }
            if norm <= self.solver.tolerance {
                return self.well_conditioned(x, q);
            }
            let jx = self.jacobian_x_raw(&x, q);
            let rhs = DVector::from_iterator(6, f.iter().map(|v| -v));
            let step = jx.lu().solve(&rhs).ok_or_else(|| KinError::Singular {
                what: "forward kinematics (constraint Jacobian F_X)".into(),
                condition: f64::INFINITY,
            })?;
            // Backtracking on the residual max-norm, bounded: a step whose trial points never
            // evaluate to finite residuals ends the solve instead of halving forever.
            let mut t = 1.0;
            let mut accepted = false;
            for _ in 0..MAX_BACKTRACKS {
                let mut trial = x;
                for i in 0..6 {
                    trial[i] += t * step[i];
                }
                let ft = self.residual_raw(&trial, q);
                let nt = max_abs(&ft);
                if nt.is_finite() && (nt < norm || t < 1e-3) {
                    x = trial;
                    f = ft;
                    norm = nt;
                    accepted = true;
                    break;
                }
                t *= 0.5;
            }
            if !accepted {
                return Err(KinError::NonFinite(format!(
                    "{} forward kinematics: the constraint residual is not finite near the current pose",
                    self.system.name()
                )));
            }
        }
        if norm <= self.solver.tolerance {
            return self.well_conditioned(x, q);
        }
        Err(KinError::NoConvergence {
            what: format!("{} forward kinematics", self.system.name()),
            iterations: self.solver.max_iterations,
            residual: norm,
        })
    }

    /// [`ClosedLoop::solve_platform`] when `x` already solves the constraints at `q` (residual
    /// within the tolerance): the same checks (inputs, strokes, conditioning), no Newton step.
    /// `Ok(None)` when `x` is not a solution.
    fn solved_at(&self, q: &[f64], x: [f64; 6]) -> Result<Option<([f64; 6], Factors)>, KinError> {
        check_inputs(q, self.system.input_names().len())?;
        self.check_strokes(q)?;
        if max_abs(&self.residual_raw(&x, q)) <= self.solver.tolerance {
            return self.well_conditioned(x, q).map(Some);
        }
        Ok(None)
    }

    /// `x` if the constraint Jacobian `F_X` there is within the solver's condition limit (the
    /// platform is not at a singularity), checked once at the solution rather than at every
    /// Newton iterate.
    fn well_conditioned(&self, x: [f64; 6], q: &[f64]) -> Result<([f64; 6], Factors), KinError> {
        let fx = self.jacobian_x_raw(&x, q);
        if let Some(cond) = ill_conditioned(&fx, self.solver.max_condition) {
            return Err(KinError::Singular {
                what: "forward kinematics (constraint Jacobian F_X)".into(),
                condition: cond,
            });
        }
        Ok((x, Matrix6::from_fn(|r, c| fx[(r, c)]).lu()))
    }

    /// Tool pose of platform coordinates `x` at the current frames.
    pub fn tool_pose_of(&self, x: &[f64; 6]) -> Pose {
        let (p, r) = tool_pose_generic(x, &self.tool, &self.base);
        let m = Matrix3::new(r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2]);
        se3::pose_from_rotation(&m, &Vector3::new(p[0], p[1], p[2]))
    }

    /// Platform coordinates of a tool pose (inverse of [`Self::tool_pose_of`]).
    pub fn platform_of_tool(&self, target: &Pose) -> [f64; 6] {
        let base = pose_of(&self.base);
        let tool = Pose::from_parts(
            Translation3::new(self.tool[0], self.tool[1], self.tool[2]),
            UnitQuaternion::identity(),
        );
        coords_of(&(base.inverse() * target * tool.inverse()))
    }

    /// Task equations `G(X)`: tool position minus target position (mm), then the rotation
    /// mismatch — `vee(skew(R·R_tᵀ))` for [`Task::Full`], the target-frame x and y components of the
    /// tool z-axis (scaled by 1000 mm) for [`Task::PositionAndAxis`].
    fn task_equations<D: Scalar>(&self, x: &[D; 6], target: &Pose) -> Vec<D> {
        let c = v3::c::<D>;
        let tool = [c(self.tool[0]), c(self.tool[1]), c(self.tool[2])];
        let base = [
            c(self.base[0]),
            c(self.base[1]),
            c(self.base[2]),
            c(self.base[3]),
            c(self.base[4]),
            c(self.base[5]),
        ];
        let (p, r) = tool_pose_generic(x, &tool, &base);
        let pt = target.translation.vector;
        let rt = se3::rotation_matrix(target);
        let mut g = vec![p[0] - pt.x, p[1] - pt.y, p[2] - pt.z];
        let scale: D = c(1000.0);
        match self.system.task() {
            Task::Full => {
                // M = R·R_tᵀ; vee of its skew part.
                let mut m: [[D; 3]; 3] = [[c(0.0); 3]; 3];
                for (i, row) in m.iter_mut().enumerate() {
                    for (j, v) in row.iter_mut().enumerate() {
                        *v = r[i][0] * rt[(j, 0)] + r[i][1] * rt[(j, 1)] + r[i][2] * rt[(j, 2)];
                    }
                }
                g.push((m[2][1] - m[1][2]) * c(0.5) * scale);
                g.push((m[0][2] - m[2][0]) * c(0.5) * scale);
                g.push((m[1][0] - m[0][1]) * c(0.5) * scale);
            }
            Task::PositionAndAxis => {
                let z = v3::column(&r, 2);
                for k in 0..2 {
                    let a = [c(rt[(0, k)]), c(rt[(1, k)]), c(rt[(2, k)])];
                    g.push(v3::dot(&z, &a) * scale);
                }
            }
            Task::Position | Task::HeightAndAxis | Task::PositionAndYaw => {}
        }
        g
    }

    /// Inverse kinematics with the platform solution: inputs `q` and platform coordinates `X`
    /// that put the tool at `target` (all six DOF for [`Task::Full`]; position and tool axis for
    /// [`Task::PositionAndAxis`], the rotation about the tool axis then follows from the
    /// constraints).
    pub fn inverse_with_pose(&self, target: &Pose) -> Result<(Vec<f64>, [f64; 6]), KinError> {
        self.inverse_with_jacobian(target).map(|(q, x, _)| (q, x))
    }

    /// [`Self::inverse_with_pose`] and the Jacobian of the inverse-kinematics system at the
    /// solution (rows: the 6 constraints, then the task equations; columns: `X`, then `q`), whose
    /// upper blocks are `F_X` and `F_q`.
    pub fn inverse_with_jacobian(&self, target: &Pose) -> Result<InverseSolution, KinError> {
        let t = target.translation.vector;
        if !(t.iter().all(|v| v.is_finite()) && target.rotation.coords.iter().all(|v| v.is_finite())) {
            return Err(KinError::NonFinite("target pose".into()));
        }
        let nq = self.system.input_names().len();
        let task = self.system.task();
        if task.dof() != nq {
            return Err(KinError::Singular {
                what: format!("{}: {} inputs for a {}-DOF task", self.system.name(), nq, task.dof()),
                condition: f64::INFINITY,
            });
        }
        // A 5-DOF task leaves the rotation about the tool axis to the constraints: the seed takes
        // the target's axis without its twist (a yaw of ±90° in the targets file then starts
        // Newton where the machine is, not in a singular corner of its platform coordinates).
        let seed = match task {
            Task::Full | Task::Position | Task::HeightAndAxis | Task::PositionAndYaw => *target,
            Task::PositionAndAxis => {
                let axis = target.rotation * nalgebra::Vector3::z();
                let swing = nalgebra::UnitQuaternion::rotation_between(&nalgebra::Vector3::z(), &axis)
                    .unwrap_or_else(|| nalgebra::UnitQuaternion::from_axis_angle(&nalgebra::Vector3::x_axis(), std::f64::consts::PI));
                Pose::from_parts(target.translation, swing)
            }
        };
        let n = 6 + nq;
        let eval = |z: &[f64]| -> Vec<f64> {
            let x = [z[0], z[1], z[2], z[3], z[4], z[5]];
            let mut e: Vec<f64> = self.system.equations(&x, &z[6..], &self.geometry).to_vec();
            e.extend(self.task_equations(&x, target));
            e
        };
        // The reduced solve first (the free twist only); kept only if the full system holds.
        let reduced = if self.solver.reduced_inverse {
            self.inverse_reduced(&seed)
        } else {
            None
        };
        if let Some((q, x)) = reduced {
            let z: Vec<f64> = x.iter().copied().chain(q.iter().copied()).collect();
            if max_abs(&eval(&z)) <= self.solver.tolerance {
                return self.finish_inverse(z, target);
            }
        }
        let x0 = self.platform_of_tool(&seed);
        let q0 = self.system.inputs_for_pose(&x0, &self.geometry)?;
        let mut z: Vec<f64> = x0.iter().copied().chain(q0.iter().copied()).collect();
        let mut f = eval(&z);
        let mut norm = max_abs(&f);
        for _ in 0..self.solver.max_iterations {
            if norm <= self.solver.tolerance || !norm.is_finite() {
                break;
            }
            let jac = self.ik_jacobian(&z, target);
            let rhs = DVector::from_iterator(n, f.iter().map(|v| -v));
            let step = jac.lu().solve(&rhs).ok_or_else(|| KinError::Singular {
                what: format!("{} inverse kinematics", self.system.name()),
                condition: f64::INFINITY,
            })?;
            let mut s = 1.0;
            let mut accepted = false;
            for _ in 0..MAX_BACKTRACKS {
                let trial: Vec<f64> = z.iter().zip(step.iter()).map(|(a, b)| a + s * b).collect();
                let ft = eval(&trial);
                let nt = max_abs(&ft);
                if nt.is_finite() && (nt < norm || s < 1e-3) {
                    z = trial;
                    f = ft;
                    norm = nt;
                    accepted = true;
                    break;
                }
                s *= 0.5;
            }
            if !accepted {
                return Err(KinError::NonFinite(format!(
                    "{} inverse kinematics: the constraint residual is not finite near the current pose",
                    self.system.name()
                )));
            }
        }
        if norm.is_nan() || norm > self.solver.tolerance {
            return Err(KinError::NoConvergence {
                what: format!("{} inverse kinematics", self.system.name()),
                iterations: self.solver.max_iterations,
                residual: norm,
            });
        }
        self.finish_inverse(z, target)
    }

    /// The end of an inverse solve at its solution `z = (X, q)`: conditioning checked once (a
    /// singular pose of the task there), then the strokes.
    fn finish_inverse(&self, z: Vec<f64>, target: &Pose) -> Result<InverseSolution, KinError> {
        let jac = self.ik_jacobian(&z, target);
        if let Some(cond) = ill_conditioned(&jac, self.solver.max_condition) {
            return Err(KinError::Singular {
                what: format!("{} inverse kinematics", self.system.name()),
                condition: cond,
            });
        }
        let q = z[6..].to_vec();
        self.check_strokes(&q)?;
        Ok((q, [z[0], z[1], z[2], z[3], z[4], z[5]], jac))
    }

    /// `F_X` (6×6) and `F_q` (6 × inputs) at `(x, q)`: the actuator Jacobian's ingredients,
    /// without the geometric `F_θ` of [`ClosedLoop::constraint_jacobians`]. Errors: wrong input
    /// count.
    pub fn actuator_jacobians(&self, x: &[f64; 6], q: &[f64]) -> Result<(DMatrix<f64>, DMatrix<f64>), KinError> {
        check_inputs(q, self.system.input_names().len())?;
        Ok((self.jacobian_x_raw(x, q), self.jacobian_q_raw(x, q)))
    }

    /// Inputs that bring the platform to the commanded coordinates `x` (for
    /// [`Task::PositionAndAxis`] the γ of `x` is ignored), checked against the workspace.
    pub fn inputs_for(&self, x: &[f64; 6]) -> Result<Vec<f64>, KinError> {
        self.check_workspace(x)?;
        let target = self.tool_pose_of(x);
        self.inverse_with_pose(&target).map(|r| r.0)
    }

    /// `n` random configurations (inputs) in the prescribed workspace, drawn uniformly in
    /// platform coordinates and mapped through this model's inverse kinematics.
    pub fn random_configurations<R: Rng>(&self, rng: &mut R, n: usize) -> Result<Vec<Vec<f64>>, KinError> {
        let ws = self.system.workspace();
        (0..n).map(|_| self.inputs_for(&ws.sample(rng))).collect()
    }

    /// Platform coordinates and their sensitivity `dX/dθ` (6 × all parameters; zero columns for
    /// the frame parameters) by the implicit function theorem `dX = −F_X⁻¹·F_θ·dθ`.
    pub fn pose_sensitivity(&self, q: &[f64], seed: Option<&[f64; 6]>) -> Result<([f64; 6], DMatrix<f64>), KinError> {
        let solved = self.solve_platform(q, seed)?;
        self.sensitivity_at(q, solved)
    }

    /// [`ClosedLoop::pose_sensitivity`] at a forward solution `(X, LU of F_X)` of `q`.
    fn sensitivity_at(&self, q: &[f64], (x, lu): ([f64; 6], Factors)) -> Result<([f64; 6], DMatrix<f64>), KinError> {
        let ft = self.jacobian_theta_raw(&x, q);
        let sol = lu.solve(&(-ft)).ok_or_else(|| KinError::Singular {
            what: "identification Jacobian (F_X)".into(),
            condition: f64::INFINITY,
        })?;
        let p = self.n_params_total();
        let mut dx = DMatrix::zeros(6, p);
        dx.columns_mut(0, self.geometry.len()).copy_from(&sol);
        Ok((x, dx))
    }

    fn n_params_total(&self) -> usize {
        self.geometry.len() + if self.frame_errors { 9 } else { 0 }
    }
}

/// A rotation matrix of X-Y-Z Euler angles (f64).
pub fn rotation_xyz(a: f64, b: f64, g: f64) -> Rotation3<f64> {
    let r = v3::rot_xyz(a, b, g);
    Rotation3::from_matrix_unchecked(Matrix3::new(
        r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
    ))
}
