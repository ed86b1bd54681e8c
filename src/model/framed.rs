//! A mechanism seen through a measurement frame and a tool frame: what a laser tracker measures.
//!
//! A tracker measures the tool (a reflector, or the frame of three reflectors) in its own frame,
//! which stands anywhere relative to the mechanism's base; the tool sits at an unknown offset from
//! the flange or platform. [`Framed`] wraps any [`Mechanism`] `M` as
//!
//! ```text
//! T(q) = X · M(q) · Y
//! ```
//!
//! with `X` the mechanism's base in the measurement frame and `Y` the tool in the flange/platform
//! frame, and adds their errors as 12 parameters in front of the mechanism's own:
//! `mx my mz mrx mry mrz` (`X ← X·exp(δ)`) and `tx ty tz trx try trz` (`Y ← Y·exp(δ)`), twists in
//! (v, ω) order. The spatial identification Jacobian in the measurement frame is
//! `[Ad_X | Ad_T | Ad_X·J_M]` (`T` the whole tool pose, `J_M` the mechanism's own spatial
//! Jacobian in its base frame).
//!
//! Where the mechanism has base or tool parameters of its own they duplicate these; the
//! identifiability analysis then names the mechanism's ones redundant (the frame parameters come
//! first in priority order), which is the intended reading: the frames are what the data fixes.
//! [`crate::register`] finds `X` and `Y` from the data before identification.
use super::{Mechanism, Task};
use crate::error::KinError;
use crate::params::{Param, Unit};
use crate::se3::{self, Pose, Twist};
use nalgebra::{DVector, Matrix6xX};

mod commanded;

/// Number of frame parameters [`Framed`] adds in front of the mechanism's own.
pub const FRAME_PARAMS: usize = 12;

/// The tool frame's translation among the frame parameters (`tx ty tz`): all a point-measuring
/// instrument sees of the tool frame.
pub const TOOL_TRANSLATION: std::ops::Range<usize> = 6..9;

/// Names of the 12 frame parameters, in order.
pub const FRAME_PARAM_NAMES: [&str; FRAME_PARAMS] = ["mx", "my", "mz", "mrx", "mry", "mrz", "tx", "ty", "tz", "trx", "try", "trz"];

/// A mechanism measured in another frame, with a tool offset: `T(q) = X · M(q) · Y`.
#[derive(Debug, Clone)]
pub struct Framed<M> {
    /// The mechanism.
    pub inner: M,
    /// `X`: the mechanism's base in the measurement frame.
    pub measurement: Pose,
    /// `Y`: the measured tool frame in the mechanism's tool (flange / platform) frame.
    pub tool: Pose,
}

impl<M: Mechanism> Framed<M> {
    /// `inner` seen through the frames `measurement` (`X`) and `tool` (`Y`).
    pub fn new(inner: M, measurement: Pose, tool: Pose) -> Self {
        Framed { inner, measurement, tool }
    }

    /// The tool pose and identification Jacobian from the inner mechanism's `(M, J_M)`:
    /// `T = X·M·Y` and `[Ad_X | Ad_T | Ad_X·J_M]`.
    fn framed_jacobian(&self, (m, jm): (Pose, Matrix6xX<f64>)) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        let t = self.measurement * m * self.tool;
        let ad_x = se3::adjoint(&self.measurement);
        let mut jac = Matrix6xX::zeros(FRAME_PARAMS + jm.ncols());
        jac.fixed_view_mut::<6, 6>(0, 0).copy_from(&ad_x);
        jac.fixed_view_mut::<6, 6>(0, 6).copy_from(&se3::adjoint(&t));
        let inner = se3::mul6(&ad_x, &jm);
        jac.view_mut((0, FRAME_PARAMS), (6, inner.ncols())).copy_from(&inner);
        Ok((t, jac))
    }
}

/// Rows over an inner mechanism's parameters, with the frames' (zero) columns in front.
fn frame_columns(j: &nalgebra::DMatrix<f64>) -> nalgebra::DMatrix<f64> {
    let mut out = nalgebra::DMatrix::zeros(j.nrows(), FRAME_PARAMS + j.ncols());
    out.view_mut((0, FRAME_PARAMS), j.shape()).copy_from(j);
    out
}

impl<M: Mechanism + Clone + 'static> Mechanism for Framed<M> {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn input_names(&self) -> Vec<String> {
        self.inner.input_names()
    }
    fn params(&self) -> Vec<Param> {
        let mut out: Vec<Param> = FRAME_PARAM_NAMES
            .iter()
            .enumerate()
            .map(|(k, n)| {
                let unit = if k % 6 < 3 { Unit::Length } else { Unit::Angle };
                let group = if k < 6 { "measurement frame" } else { "tool frame" };
                Param::new(*n, unit, group)
            })
            .collect();
        out.extend(self.inner.params());
        out
    }
    fn n_params(&self) -> usize {
        FRAME_PARAMS + self.inner.n_params()
    }
    fn assembly_breaking(&self) -> Vec<usize> {
        self.inner.assembly_breaking().into_iter().map(|i| i + FRAME_PARAMS).collect()
    }
    fn forward(&self, q: &[f64]) -> Result<Pose, KinError> {
        Ok(self.measurement * self.inner.forward(q)? * self.tool)
    }
    fn forward_with_jacobian(&self, q: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        self.framed_jacobian(self.inner.forward_with_jacobian(q)?)
    }
    /// The inner mechanism starts from `near` seen in its own frames, `X⁻¹·near·Y⁻¹`.
    fn forward_with_jacobian_near(&self, q: &[f64], near: &Pose) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        let inner_near = self.measurement.inverse() * near * self.tool.inverse();
        self.framed_jacobian(self.inner.forward_with_jacobian_near(q, &inner_near)?)
    }
    fn retract(&mut self, delta: &DVector<f64>) {
        let dx = Twist::from_iterator(delta.rows(0, 6).iter().copied());
        let dy = Twist::from_iterator(delta.rows(6, 6).iter().copied());
        self.measurement *= se3::exp(&dx);
        self.tool *= se3::exp(&dy);
        let rest = delta.rows(FRAME_PARAMS, delta.len() - FRAME_PARAMS).into_owned();
        self.inner.retract(&rest);
    }
    /// The whole pose commanded: the inner mechanism at `X⁻¹·T·Y⁻¹`. Part of it commanded:
    /// Newton on that part of `X·M(q)·Y` (`commanded::inverse`), the rest following from the
    /// constraints through the tool offset.
    fn inverse(&self, target: &Pose, seed: Option<&[f64]>) -> Result<Vec<f64>, KinError> {
        if self.inner.task() == Task::Full {
            let inner_target = self.measurement.inverse() * target * self.tool.inverse();
            return self.inner.inverse(&inner_target, seed);
        }
        commanded::inverse(&self.inner, &self.tool, &(self.measurement.inverse() * target), seed)
    }
    fn box_clone(&self) -> Box<dyn Mechanism> {
        Box::new(self.clone())
    }
    fn inverse_ignores_seed(&self) -> bool {
        self.inner.inverse_ignores_seed()
    }
    fn task(&self) -> Task {
        self.inner.task()
    }
    fn sample_configurations(&self, n: usize, seed: u64) -> Option<Result<Vec<Vec<f64>>, KinError>> {
        self.inner.sample_configurations(n, seed)
    }
    fn geometry(&self) -> Option<Vec<f64>> {
        self.inner.geometry()
    }
    fn observed_joints(&self) -> Vec<(String, crate::params::Unit)> {
        self.inner.observed_joints()
    }
    fn observed_joint_values(&self, q: &[f64]) -> Result<Vec<f64>, KinError> {
        self.inner.observed_joint_values(q)
    }
    /// The inner mechanism's rows, the frames' columns zero (joint values do not depend on them).
    fn observed_joints_with_jacobian(&self, q: &[f64]) -> Result<(Vec<f64>, nalgebra::DMatrix<f64>), KinError> {
        let (v, j) = self.inner.observed_joints_with_jacobian(q)?;
        Ok((v, frame_columns(&j)))
    }
    fn forward_and_observed(&self, q: &[f64]) -> Result<(Pose, Vec<f64>), KinError> {
        let (t, v) = self.inner.forward_and_observed(q)?;
        Ok((self.measurement * t * self.tool, v))
    }
    fn forward_with_jacobian_and_observed(&self, q: &[f64], near: Option<&Pose>) -> Result<super::ForwardAndObserved, KinError> {
        let inner_near = near.map(|n| self.measurement.inverse() * n * self.tool.inverse());
        let (t, j, v, rows) = self.inner.forward_with_jacobian_and_observed(q, inner_near.as_ref())?;
        let (pose, jac) = self.framed_jacobian((t, j))?;
        Ok((pose, jac, v, frame_columns(&rows)))
    }
    fn frames(&self) -> Option<(Pose, Pose)> {
        Some((self.measurement, self.tool))
    }
    /// The inner mechanism's drawing, in the measurement frame.
    fn skeleton(&self) -> Vec<Vec<nalgebra::Vector3<f64>>> {
        let x = self.measurement;
        let lines = self.inner.skeleton();
        lines
            .iter()
            .map(|l| l.iter().map(|p| x.transform_point(&(*p).into()).coords).collect())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::builtin::irb120;
    use nalgebra::Vector3;

    fn framed() -> Framed<crate::model::chain::SerialChain> {
        Framed::new(
            irb120(),
            se3::pose_from_parts(Vector3::new(2000.0, -500.0, 300.0), Vector3::new(0.4, -1.2, 0.9)),
            se3::pose_from_parts(Vector3::new(30.0, 150.0, -20.0), Vector3::new(-0.3, 0.2, 0.1)),
        )
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let m = framed();
        let q = [0.3, -0.4, 0.5, 0.9, -1.1, 0.7];
        let (t, jac) = m.forward_with_jacobian(&q).unwrap();
        let h = 1e-6;
        for c in 0..m.n_params() {
            let (tp, tm) = crate::model::retracted_poses(&m, &q, c, h);
            let fd = (se3::log(&(tp * t.inverse())) - se3::log(&(tm * t.inverse()))) / (2.0 * h);
            let err = (fd - jac.column(c)).norm();
            assert!(err < 1e-5 * (1.0 + jac.column(c).norm()), "column {c}: {err:e}");
        }
    }

    #[test]
    fn inverse_undoes_forward() {
        let m = framed();
        let q = [0.3, -0.4, 0.5, 0.9, -1.1, 0.7];
        let t = m.forward(&q).unwrap();
        let back = m.inverse(&t, Some(&[0.2, -0.3, 0.4, 0.8, -1.0, 0.6])).unwrap();
        let t2 = m.forward(&back).unwrap();
        assert!((t2.translation.vector - t.translation.vector).norm() < 1e-9);
    }
}
