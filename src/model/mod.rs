//! Mechanisms: what kinecal calibrates.
//!
//! A [`Mechanism`] maps actuator (and sensed passive-joint) values `q` to the pose of its tool frame
//! in the world frame (for a tracker measurement: the tracker frame), and exposes its geometric
//! error coordinates as named [`Param`]s. Identification only ever needs three things from it:
//!
//! * the tool pose at `q`,
//! * the *spatial* identification Jacobian `J(q)`, 6 × p, defined by
//!   `log(T(q; θ ⊕ δ)·T(q; θ)⁻¹) = J(q)·δ + O(|δ|²)` (twist order (v, ω), see [`crate::se3`]),
//! * the update `θ ← θ ⊕ δ` ([`Mechanism::retract`]): for a local-POE chain `T(0) ← T(0)·exp(δt)`
//!   (eq. (33) of the 3T1R paper), for a constraint model `θ ← θ + δ`.
//!
//! Because every model is re-linearised at its current parameters, identification iterates to
//! convergence on any mechanism that implements this trait.
use crate::error::KinError;
use crate::params::{Param, Unit};
use crate::se3::Pose;
use nalgebra::{DMatrix, DVector, Matrix6xX, Vector3};

pub mod builtin;
pub mod chain;
pub mod closed;
pub mod dh;
pub mod framed;
pub mod irb120;
pub mod joint_terms;
pub mod kind;
pub mod limbs;
pub mod presets;
pub mod projection;

/// The tool poses at `q` of `m` with parameter `c` retracted by `+h` and by `−h`: the two sides
/// of a central difference, for the unit tests that check identification Jacobians.
#[cfg(test)]
pub(crate) fn retracted_poses<M: Mechanism + Clone>(m: &M, q: &[f64], c: usize, h: f64) -> (Pose, Pose) {
    let side = |s: f64| {
        let mut d = DVector::zeros(m.n_params());
        d[c] = s * h;
        let mut moved = m.clone();
        moved.retract(&d);
        moved.forward(q).expect("forward kinematics at the test configuration")
    };
    (side(1.0), side(-1.0))
}

/// The tool pose, the spatial identification Jacobian (6 × p), the observed joints' values and
/// their parameter Jacobian (observed × p), from one evaluation
/// ([`Mechanism::forward_with_jacobian_and_observed`]).
pub type ForwardAndObserved = (Pose, Matrix6xX<f64>, Vec<f64>, DMatrix<f64>);

/// Which part of the tool pose the actuators command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Task {
    /// All six degrees of freedom (e.g. a Stewart platform).
    Full,
    /// Tool position and tool z-axis direction (5 DOF): rotation about the tool axis is a
    /// parasitic motion the mechanism cannot command (e.g. the 5-DOF PUU-2PR(RPRR)S machine).
    PositionAndAxis,
    /// Tool position only (3 DOF): the orientation follows from the constraints (e.g. a delta
    /// robot, whose platform only translates).
    Position,
    /// Tool height (z) and tool z-axis direction (3 DOF): a tilting head such as a 3-PRS, whose
    /// x, y and rotation about the axis are parasitic motions its constraints decide (commanding
    /// x and y instead would be ill-posed: they change only at second order in the tilts).
    HeightAndAxis,
    /// Tool position and the rotation about the base z-axis, the yaw `atan2(R₁₀, R₀₀)` (4 DOF,
    /// "3T1R"): the tilts are parasitic motions its constraints decide (e.g. the 3T1R machine of
    /// the 3T1R paper, a pick-and-place delta with a rotating axis, a SCARA).
    PositionAndYaw,
}

impl Task {
    /// Number of commanded degrees of freedom.
    pub fn dof(self) -> usize {
        match self {
            Task::Full => 6,
            Task::PositionAndAxis => 5,
            Task::Position => 3,
            Task::HeightAndAxis => 3,
            Task::PositionAndYaw => 4,
        }
    }
}

/// What [`Mechanism::inverse_solution`] solved: the inputs, and where the mechanism gives them,
/// the pose reached and the rest of the forward solution there.
pub type SolvedInverse = (Vec<f64>, Option<(Pose, Vec<f64>)>);

/// A calibratable mechanism.
pub trait Mechanism: Send + Sync {
    /// A short name, e.g. `"irb120"`.
    fn name(&self) -> &str;
    /// Names of the input values `q` of one pose, in order (actuators first, then sensed passive
    /// joints), with their unit: revolute joints in rad, prismatic in mm.
    fn input_names(&self) -> Vec<String>;
    /// The error parameters, in Jacobian column order.
    fn params(&self) -> Vec<Param>;
    /// Number of error parameters.
    fn n_params(&self) -> usize {
        self.params().len()
    }
    /// Tool pose in the world frame at inputs `q`.
    fn forward(&self, q: &[f64]) -> Result<Pose, KinError>;
    /// Tool pose and spatial identification Jacobian (6 × p) at inputs `q`.
    fn forward_with_jacobian(&self, q: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError>;
    /// [`Mechanism::forward_with_jacobian`] when the tool pose at `q` is already known (a planned
    /// candidate's): a mechanism that solves its forward kinematics iteratively may start from
    /// `near` instead of its home pose. The default ignores the hint.
    fn forward_with_jacobian_near(&self, q: &[f64], near: &Pose) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        let _ = near;
        self.forward_with_jacobian(q)
    }
    /// [`Mechanism::forward`] and the rest of what its forward kinematics solved for (a limbs
    /// machine's passive joint values; nothing by default): given back with the pose to
    /// [`Mechanism::forward_with_jacobian_at`], it linearises there without solving again.
    fn forward_solution(&self, q: &[f64]) -> Result<(Pose, Vec<f64>), KinError> {
        Ok((self.forward(q)?, Vec::new()))
    }
    /// [`Mechanism::forward_with_jacobian`] at a solution `(pose, rest)` of
    /// [`Mechanism::forward_solution`] at `q`: the same numbers, without the forward solve where
    /// the mechanism can (the default solves from `pose`: [`Mechanism::forward_with_jacobian_near`]).
    fn forward_with_jacobian_at(&self, q: &[f64], pose: &Pose, rest: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        let _ = rest;
        self.forward_with_jacobian_near(q, pose)
    }
    /// Apply an increment of the error coordinates (length p) to the model's geometry.
    fn retract(&mut self, delta: &DVector<f64>);
    /// Inputs that bring the tool to `target` (inverse kinematics); `seed` is a starting guess for
    /// mechanisms that solve numerically.
    fn inverse(&self, target: &Pose, seed: Option<&[f64]>) -> Result<Vec<f64>, KinError>;
    /// [`Mechanism::inverse`] with what it solved besides the inputs, where the mechanism can
    /// give it: the pose reached (the target's commanded part, the rest following from the
    /// constraints) and the rest of the forward solution there (as
    /// [`Mechanism::forward_solution`] gives it). `None` (the default): only the inputs are known,
    /// and a caller that needs the pose reached solves the forward kinematics. A solution given
    /// here is that of the inverse kinematics' own path, which may be another assembly mode than
    /// the forward kinematics from home reaches: planning checks that on the chosen candidates.
    fn inverse_solution(&self, target: &Pose, seed: Option<&[f64]>) -> Result<SolvedInverse, KinError> {
        Ok((self.inverse(target, seed)?, None))
    }
    /// A boxed copy (lets command-line code hold any mechanism).
    fn box_clone(&self) -> Box<dyn Mechanism>;
    /// Whether [`Mechanism::inverse`] ignores its `seed` (a closed-form or self-started inverse):
    /// callers then gain nothing by retrying from other starting points.
    fn inverse_ignores_seed(&self) -> bool {
        false
    }
    /// The mechanism's complete geometry as numbers, in its kind's own order (what a calibrated
    /// model is written back from: [`kind::MechanismSpec::with_geometry_of`]); `None` for
    /// mechanisms no model file describes. A mechanism seen through frames
    /// ([`framed::Framed`]) answers with its inner mechanism's.
    fn geometry(&self) -> Option<Vec<f64>> {
        None
    }
    /// The measurement and tool frames `(X, Y)` of a mechanism seen through frames
    /// ([`framed::Framed`]: `T = X·M(q)·Y`); `None` otherwise.
    fn frames(&self) -> Option<(Pose, Pose)> {
        None
    }
    /// The error parameters an **overconstrained** mechanism cannot take alone: with any one of
    /// them changed the drawn mechanism no longer assembles (a planar machine's joint axes tilted
    /// out of its plane; see [`limbs::LimbMechanism::assembly_breaking`]). Identification,
    /// simulation and planning hold them at their drawn values. Empty (default) for a mechanism
    /// whose closure equations are independent.
    fn assembly_breaking(&self) -> Vec<usize> {
        Vec::new()
    }
    /// Which part of the tool pose the inputs command: [`Task::Full`] (default) or, for a 5-DOF
    /// machine, [`Task::PositionAndAxis`] (the rotation about the tool axis is then a parasitic
    /// motion that inverse kinematics does not match).
    fn task(&self) -> Task {
        Task::Full
    }
    /// `n` input vectors at which the mechanism assembles, drawn reproducibly from `seed`, for
    /// mechanisms where independent uniform inputs may not assemble (closed loops draw poses in
    /// their workspace and solve the inverse kinematics). `None` (default): any inputs within the
    /// limits assemble, draw them uniformly ([`crate::simulate::random_configurations`] does).
    fn sample_configurations(&self, n: usize, seed: u64) -> Option<Result<Vec<Vec<f64>>, KinError>> {
        let _ = (n, seed);
        None
    }
    /// The machine drawn at its home configuration, for the report's 3-D view: polylines
    /// through its joints in the world frame (mm). A serial chain gives one, from the base
    /// through every joint frame's origin to the tool; a limb mechanism one per limb (base to
    /// its end) and the platform's outline. Empty (default) for a mechanism without a drawing.
    fn skeleton(&self) -> Vec<Vec<Vector3<f64>>> {
        Vec::new()
    }
    /// The passive joints whose sensors are read as **observations** (their readings are compared
    /// with the model, weighted by the encoder noise, like the tracker's): name and unit
    /// ([`Unit::Angle`] in rad, [`Unit::Length`] in mm), in the order of
    /// [`crate::measure::Measurement::joints`]. Empty (default) for mechanisms without them.
    fn observed_joints(&self) -> Vec<(String, Unit)> {
        Vec::new()
    }
    /// The values of the observed joints at inputs `q` (see [`Mechanism::observed_joints`]).
    fn observed_joint_values(&self, q: &[f64]) -> Result<Vec<f64>, KinError> {
        let _ = q;
        Ok(Vec::new())
    }
    /// The values of the observed joints at inputs `q` and their derivative with respect to the
    /// error parameters (one row per observed joint, p columns).
    fn observed_joints_with_jacobian(&self, q: &[f64]) -> Result<(Vec<f64>, DMatrix<f64>), KinError> {
        let _ = q;
        Ok((Vec::new(), DMatrix::zeros(0, self.n_params())))
    }
    /// The tool pose and the observed joints' values at `q` ([`Mechanism::forward`],
    /// [`Mechanism::observed_joint_values`]); a mechanism that solves them together overrides this
    /// to solve once.
    fn forward_and_observed(&self, q: &[f64]) -> Result<(Pose, Vec<f64>), KinError> {
        Ok((self.forward(q)?, self.observed_joint_values(q)?))
    }
    /// [`Mechanism::forward_with_jacobian_near`] (or without a hint) and
    /// [`Mechanism::observed_joints_with_jacobian`]; a mechanism that solves them together
    /// overrides this to solve once.
    fn forward_with_jacobian_and_observed(&self, q: &[f64], near: Option<&Pose>) -> Result<ForwardAndObserved, KinError> {
        let (pose, jac) = match near {
            Some(p) => self.forward_with_jacobian_near(q, p)?,
            None => self.forward_with_jacobian(q)?,
        };
        let (values, rows) = self.observed_joints_with_jacobian(q)?;
        Ok((pose, jac, values, rows))
    }
}

impl Clone for Box<dyn Mechanism> {
    fn clone(&self) -> Self {
        self.box_clone()
    }
}

impl Mechanism for Box<dyn Mechanism> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn input_names(&self) -> Vec<String> {
        (**self).input_names()
    }
    fn params(&self) -> Vec<Param> {
        (**self).params()
    }
    fn n_params(&self) -> usize {
        (**self).n_params()
    }
    fn forward(&self, q: &[f64]) -> Result<Pose, KinError> {
        (**self).forward(q)
    }
    fn forward_with_jacobian(&self, q: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        (**self).forward_with_jacobian(q)
    }
    fn forward_with_jacobian_near(&self, q: &[f64], near: &Pose) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        (**self).forward_with_jacobian_near(q, near)
    }
    fn forward_solution(&self, q: &[f64]) -> Result<(Pose, Vec<f64>), KinError> {
        (**self).forward_solution(q)
    }
    fn forward_with_jacobian_at(&self, q: &[f64], pose: &Pose, rest: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        (**self).forward_with_jacobian_at(q, pose, rest)
    }
    fn retract(&mut self, delta: &DVector<f64>) {
        (**self).retract(delta)
    }
    fn inverse(&self, target: &Pose, seed: Option<&[f64]>) -> Result<Vec<f64>, KinError> {
        (**self).inverse(target, seed)
    }
    fn inverse_solution(&self, target: &Pose, seed: Option<&[f64]>) -> Result<SolvedInverse, KinError> {
        (**self).inverse_solution(target, seed)
    }
    fn box_clone(&self) -> Box<dyn Mechanism> {
        (**self).box_clone()
    }
    fn inverse_ignores_seed(&self) -> bool {
        (**self).inverse_ignores_seed()
    }
    fn geometry(&self) -> Option<Vec<f64>> {
        (**self).geometry()
    }
    fn frames(&self) -> Option<(Pose, Pose)> {
        (**self).frames()
    }
    fn assembly_breaking(&self) -> Vec<usize> {
        (**self).assembly_breaking()
    }
    fn task(&self) -> Task {
        (**self).task()
    }
    fn sample_configurations(&self, n: usize, seed: u64) -> Option<Result<Vec<Vec<f64>>, KinError>> {
        (**self).sample_configurations(n, seed)
    }
    fn skeleton(&self) -> Vec<Vec<Vector3<f64>>> {
        (**self).skeleton()
    }
    fn observed_joints(&self) -> Vec<(String, Unit)> {
        (**self).observed_joints()
    }
    fn observed_joint_values(&self, q: &[f64]) -> Result<Vec<f64>, KinError> {
        (**self).observed_joint_values(q)
    }
    fn observed_joints_with_jacobian(&self, q: &[f64]) -> Result<(Vec<f64>, DMatrix<f64>), KinError> {
        (**self).observed_joints_with_jacobian(q)
    }
    fn forward_and_observed(&self, q: &[f64]) -> Result<(Pose, Vec<f64>), KinError> {
        (**self).forward_and_observed(q)
    }
    fn forward_with_jacobian_and_observed(&self, q: &[f64], near: Option<&Pose>) -> Result<ForwardAndObserved, KinError> {
        (**self).forward_with_jacobian_and_observed(q, near)
    }
}

/// Check an input vector: length and finiteness.
pub fn check_inputs(q: &[f64], expected: usize) -> Result<(), KinError> {
    if q.len() != expected {
        return Err(KinError::InputLength { expected, got: q.len() });
    }
    if q.iter().any(|v| !v.is_finite()) {
        return Err(KinError::NonFinite("joint values".into()));
    }
    Ok(())
}
