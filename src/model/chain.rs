//! Local product-of-exponentials serial chains (3T1R paper, §2.2–§3.1).
//!
//! A chain of `n` joints is a product of dyads closed by a tool frame,
//!
//! ```text
//! g(q) = T_{0,1}(0)·exp(ŝ_1 q_1) · T_{1,2}(0)·exp(ŝ_2 q_2) ··· T_{n-1,n}(0)·exp(ŝ_n q_n) · T_{n,T}(0)
//! ```
//!
//! (eq. (4)–(7)). The joint twists `s_j` are expressed in the frame that `T_{j-1,j}(0)` reaches
//! and stay nominal; all geometric errors live in the initial poses: each `T(0)` gets six error
//! coordinates `δt = (δv, δω)` (mm, rad), updated as `T(0) ← T(0)·exp(δt)` (eq. (33)). The first
//! dyad carries the base frame (for tracker data: the tracker-to-robot registration), the last
//! the tool frame.
//!
//! The spatial identification Jacobian is the row of adjoints of eq. (17)–(19):
//! `log(g_a·g⁻¹) = [Ad_{T_{0,1}(0)}, Ad_{g_{0,1}T_{1,2}(0)}, …, Ad_{g_{0,n}T_{n,T}(0)}]·[δt_1; …; δt_T]`.
//!
//! With `r` revolute and `p` prismatic joints, `6(n+1)` coordinates give an identification
//! Jacobian of rank `4r + 2p + 6` for full-pose measurements and `4r + 2p + 3` for positions.
use super::{check_inputs, Mechanism};
use crate::error::KinError;
use crate::params::{Param, Unit};
use crate::se3::{self, Pose, Twist};
use nalgebra::{DMatrix, DVector, Matrix6xX, Vector3};
use serde::{Deserialize, Serialize};

/// Kind of a one-degree-of-freedom joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Rotation about an axis; value in rad.
    Revolute,
    /// Translation along an axis; value in mm.
    Prismatic,
}

/// One joint of a chain.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChainJoint {
    /// Joint name, e.g. `"q1"`.
    pub name: String,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Unit joint twist `(v, ω)` in the frame reached by the dyad's initial pose.
    pub twist: [f64; 6],
    /// Optional joint limits (rad or mm).
    pub limits: Option<(f64, f64)>,
}

impl ChainJoint {
    /// A revolute joint about `axis` through the local origin.
    pub fn revolute(name: impl Into<String>, axis: Vector3<f64>) -> Self {
        let a = axis.normalize();
        ChainJoint {
            name: name.into(),
            kind: JointKind::Revolute,
            twist: [0.0, 0.0, 0.0, a.x, a.y, a.z],
            limits: None,
        }
    }
    /// A prismatic joint along `axis`.
    pub fn prismatic(name: impl Into<String>, axis: Vector3<f64>) -> Self {
        let a = axis.normalize();
        ChainJoint {
            name: name.into(),
            kind: JointKind::Prismatic,
            twist: [a.x, a.y, a.z, 0.0, 0.0, 0.0],
            limits: None,
        }
    }
    /// The joint twist as a vector.
    pub fn twist(&self) -> Twist {
        Twist::from_row_slice(&self.twist)
    }
}

/// A serial chain in local-POE form.
#[derive(Debug, Clone, PartialEq)]
pub struct SerialChain {
    name: String,
    joints: Vec<ChainJoint>,
    /// `n + 1` initial poses: `T_{0,1}(0) … T_{n-1,n}(0)`, then the tool `T_{n,T}(0)`.
    initial: Vec<Pose>,
    /// The poses the errors are counted from: `initial[k] = reference[k]·exp(offset[k])`.
    reference: Vec<Pose>,
    /// The sum of the increments each dyad was retracted by (its six error coordinates).
    offset: Vec<Twist>,
    /// `J_r(offset[k])` where the offset is not zero: the error coordinates' Jacobian columns.
    right: Vec<Option<nalgebra::Matrix6<f64>>>,
    /// Names of the `n + 1` dyads, used as parameter-name prefixes.
    dyad_names: Vec<String>,
}

const COMPONENTS: [&str; 6] = ["vx", "vy", "vz", "wx", "wy", "wz"];

impl SerialChain {
    /// A chain from its joints, the `n` joint initial poses and the tool pose.
    ///
    /// Dyads are named `"0-1"`, `"1-2"`, …, `"n-T"`.
    pub fn new(name: impl Into<String>, joints: Vec<ChainJoint>, joint_initial: Vec<Pose>, tool: Pose) -> Self {
        assert_eq!(joints.len(), joint_initial.len(), "one initial pose per joint");
        let n = joints.len();
        let mut dyad_names: Vec<String> = (0..n).map(|j| format!("{}-{}", j, j + 1)).collect();
        dyad_names.push(format!("{n}-T"));
        let mut initial = joint_initial;
        initial.push(tool);
        let m = initial.len();
        SerialChain {
            name: name.into(),
            joints,
            reference: initial.clone(),
            initial,
            offset: vec![Twist::zeros(); m],
            right: vec![None; m],
            dyad_names,
        }
    }

    /// Rename the dyads (parameter prefixes); `names.len()` must be `n + 1`.
    pub fn with_dyad_names(mut self, names: Vec<String>) -> Self {
        assert_eq!(names.len(), self.initial.len());
        self.dyad_names = names;
        self
    }

    /// This chain with the geometry `values` of [`Mechanism::geometry`] (its `n + 1` initial
    /// poses: translation, then the rotation matrix column by column); an error when the length
    /// does not fit this chain.
    pub fn with_geometry(&self, values: &[f64]) -> Result<SerialChain, String> {
        if values.len() != 12 * self.initial.len() {
            return Err(format!(
                "{} geometry values for a serial chain of {} joints (expected {})",
                values.len(),
                self.joints.len(),
                12 * self.initial.len()
            ));
        }
        let mut out = self.clone();
        for (k, chunk) in values.chunks(12).enumerate() {
            let t = nalgebra::Vector3::new(chunk[0], chunk[1], chunk[2]);
            let r = nalgebra::Matrix3::from_column_slice(&chunk[3..12]);
            out.set_initial_pose(k, crate::se3::pose_from_matrix(&r, &t));
        }
        Ok(out)
    }

    /// The joints.
    pub fn joints(&self) -> &[ChainJoint] {
        &self.joints
    }

    /// Number of joints.
    pub fn n_joints(&self) -> usize {
        self.joints.len()
    }

    /// Initial poses `T_{j-1,j}(0)` followed by the tool pose.
    pub fn initial_poses(&self) -> &[Pose] {
        &self.initial
    }

    /// Replace the initial pose of dyad `k` (`k = n` is the tool).
    /// Its error coordinates count from there again.
    pub fn set_initial_pose(&mut self, k: usize, pose: Pose) {
        self.initial[k] = pose;
        self.reference[k] = pose;
        self.offset[k] = Twist::zeros();
        self.right[k] = None;
    }

    /// The base dyad's initial pose `T_{0,1}(0)`.
    pub fn base(&self) -> &Pose {
        &self.initial[0]
    }

    /// The tool pose `T_{n,T}(0)`.
    pub fn tool(&self) -> &Pose {
        self.initial.last().expect("a chain has a tool pose")
    }

    /// Dyad names.
    pub fn dyad_names(&self) -> &[String] {
        &self.dyad_names
    }

    /// Numbers of revolute and prismatic joints.
    pub fn joint_counts(&self) -> (usize, usize) {
        let r = self.joints.iter().filter(|j| j.kind == JointKind::Revolute).count();
        (r, self.joints.len() - r)
    }

    /// Indices of the parameters of the base dyad (6) and the tool dyad (6).
    pub fn frame_param_indices(&self) -> Vec<usize> {
        let n = self.joints.len();
        (0..6).chain(6 * n..6 * n + 6).collect()
    }

    /// Poses of every joint frame `g_{0,j}` (after each joint motion) and the tool pose.
    pub fn frames(&self, q: &[f64]) -> Result<Vec<Pose>, KinError> {
        check_inputs(q, self.joints.len())?;
        let mut g = Pose::identity();
        let mut out = Vec::with_capacity(self.joints.len() + 1);
        for (j, joint) in self.joints.iter().enumerate() {
            g = g * self.initial[j] * se3::exp_joint(&joint.twist(), q[j]);
            out.push(g);
        }
        out.push(g * self.tool());
        Ok(out)
    }

    /// Spatial joint Jacobian (6 × n): `log(g(q + dq)·g(q)⁻¹) ≈ J_q·dq`.
    pub fn joint_jacobian(&self, q: &[f64]) -> Result<(Pose, DMatrix<f64>), KinError> {
        check_inputs(q, self.joints.len())?;
        let mut g = Pose::identity();
        let mut jq = DMatrix::zeros(6, self.joints.len());
        for (j, joint) in self.joints.iter().enumerate() {
            let a = g * self.initial[j];
            jq.set_column(j, &se3::adjoint_apply(&a, &joint.twist()));
            g = a * se3::exp_joint(&joint.twist(), q[j]);
        }
        Ok((g * self.tool(), jq))
    }

    /// The spatial Jacobian columns of dyad `k`'s six error coordinates, `a` the frame its
    /// initial pose reaches: `Ad_a`, times `J_r` of its offset once it was retracted.
    fn error_columns(&self, k: usize, a: &Pose) -> nalgebra::Matrix6<f64> {
        match &self.right[k] {
            Some(jr) => se3::adjoint(a) * jr,
            None => se3::adjoint(a),
        }
    }
}

impl Mechanism for SerialChain {
    fn name(&self) -> &str {
        &self.name
    }

    fn input_names(&self) -> Vec<String> {
        self.joints.iter().map(|j| j.name.clone()).collect()
    }

    fn params(&self) -> Vec<Param> {
        let mut out = Vec::with_capacity(6 * self.initial.len());
        let n = self.joints.len();
        for (k, dyad) in self.dyad_names.iter().enumerate() {
            let group = if k == 0 {
                "base".to_string()
            } else if k == n {
                "tool".to_string()
            } else {
                format!("dyad {dyad}")
            };
            for (c, comp) in COMPONENTS.iter().enumerate() {
                let unit = if c < 3 { Unit::Length } else { Unit::Angle };
                out.push(Param::new(format!("{dyad}.{comp}"), unit, group.clone()));
            }
        }
        out
    }

    fn n_params(&self) -> usize {
        6 * self.initial.len()
    }

    /// The base origin, every joint frame's origin and the tool, at zero joint values.
    fn skeleton(&self) -> Vec<Vec<nalgebra::Vector3<f64>>> {
        let zero = vec![0.0; self.joints.len()];
        let frames = self.frames(&zero).unwrap_or_default();
        let mut line = vec![nalgebra::Vector3::zeros()];
        line.extend(frames.iter().map(|g| g.translation.vector));
        vec![line]
    }

    fn forward(&self, q: &[f64]) -> Result<Pose, KinError> {
        check_inputs(q, self.joints.len())?;
        let mut g = Pose::identity();
        for (j, joint) in self.joints.iter().enumerate() {
            g = g * self.initial[j] * se3::exp_joint(&joint.twist(), q[j]);
        }
        Ok(g * self.tool())
    }

    fn forward_with_jacobian(&self, q: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        check_inputs(q, self.joints.len())?;
        let n = self.joints.len();
        let mut jac = Matrix6xX::zeros(6 * (n + 1));
        let mut g = Pose::identity();
        for (j, joint) in self.joints.iter().enumerate() {
            let a = g * self.initial[j];
            jac.fixed_view_mut::<6, 6>(0, 6 * j).copy_from(&self.error_columns(j, &a));
            g = a * se3::exp_joint(&joint.twist(), q[j]);
        }
        let a = g * self.tool();
        jac.fixed_view_mut::<6, 6>(0, 6 * n).copy_from(&self.error_columns(n, &a));
        Ok((a, jac))
    }

    fn retract(&mut self, delta: &DVector<f64>) {
        assert_eq!(delta.len(), 6 * self.initial.len(), "one 6-vector per dyad");
        // The increments add up in the error coordinates, `T = T_ref·exp(Σδ)`, so that where a
        // dyad's fixed coordinates stay zero the pose reached does not depend on the path: a
        // product `T·exp(δ₁)·exp(δ₂)` of steps in some coordinates only (`vz wy wz`) moves the
        // others by their brackets (`[wy, wz] = wx`), which no later step can undo.
        for k in 0..self.initial.len() {
            let d = Twist::from_iterator(delta.rows(6 * k, 6).iter().copied());
            // A zero increment leaves the pose bit for bit.
            if d.iter().any(|v| *v != 0.0) {
                self.offset[k] += d;
                self.initial[k] = self.reference[k] * se3::exp(&self.offset[k]);
                self.right[k] = Some(se3::right_jacobian(&self.offset[k]));
            }
        }
    }

    /// Damped least-squares Newton on the joint values, from `seed` (default: all zeros).
    fn inverse(&self, target: &Pose, seed: Option<&[f64]>) -> Result<Vec<f64>, KinError> {
        let n = self.joints.len();
        let mut q: Vec<f64> = seed.map(|s| s.to_vec()).unwrap_or_else(|| vec![0.0; n]);
        check_inputs(&q, n)?;
        let mut err = f64::INFINITY;
        for _ in 0..100 {
            let (g, jq) = self.joint_jacobian(&q)?;
            let e = se3::log(&(target * g.inverse()));
            // Converged when within 1e-10 mm and 1e-12 rad.
            err = se3::lin(&e).norm() + 1e3 * se3::ang(&e).norm();
            if se3::lin(&e).norm() < 1e-10 && se3::ang(&e).norm() < 1e-12 {
                return Ok(q);
            }
            let jt = jq.transpose();
            let lambda = 1e-9;
            let h = &jt * &jq + DMatrix::identity(n, n) * lambda;
            let ev = DVector::from_column_slice(e.as_slice());
            let dq = h
                .cholesky()
                .ok_or_else(|| KinError::Singular {
                    what: "serial-chain inverse kinematics".into(),
                    condition: f64::INFINITY,
                })?
                .solve(&(&jt * ev));
            for (qi, d) in q.iter_mut().zip(dq.iter()) {
                *qi += d;
            }
        }
        Err(KinError::NoConvergence {
            what: "serial-chain inverse kinematics".into(),
            iterations: 100,
            residual: err,
        })
    }

    fn box_clone(&self) -> Box<dyn Mechanism> {
        Box::new(self.clone())
    }

    fn geometry(&self) -> Option<Vec<f64>> {
        Some(
            self.initial
                .iter()
                .flat_map(|p| {
                    let r = crate::se3::rotation_matrix(p);
                    p.translation.vector.iter().copied().chain(r.iter().copied()).collect::<Vec<_>>()
                })
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn planar_rp() -> SerialChain {
        SerialChain::new(
            "rp",
            vec![ChainJoint::revolute("q1", Vector3::z()), ChainJoint::prismatic("q2", Vector3::x())],
            vec![Pose::identity(), se3::translation(100.0, 0.0, 0.0)],
            se3::translation(10.0, 0.0, 0.0),
        )
    }

    #[test]
    fn forward_of_simple_chain() {
        let c = planar_rp();
        let t = c.forward(&[std::f64::consts::FRAC_PI_2, 5.0]).unwrap();
        assert_relative_eq!(t.translation.vector, Vector3::new(0.0, 115.0, 0.0), epsilon = 1e-12);
    }

    #[test]
    fn wrong_input_length_is_an_error() {
        assert_eq!(planar_rp().forward(&[0.0]), Err(KinError::InputLength { expected: 2, got: 1 }));
    }
}
