//! What geometry cannot explain: non-geometric joint terms of a serial chain.
//!
//! A geometric model moves the joint axes; it cannot describe a joint whose angle depends on how it
//! was reached or on the load it carries. [`WithJointTerms`] wraps a local-POE [`SerialChain`] and
//! feeds it effective joint values
//!
//! ```text
//! q_eff,j = q_j + b_j·s_j                                  lost motion (backlash)
//!               + Σ_i κ_{j,i} · a_j·((p_i − o_j) × ĝ) / 1000  gravity compliance
//!               + c_j·cos q_j + d_j·sin q_j                 first harmonic (gear eccentricity)
//! ```
//!
//! * **Lost motion** `b_j` (rad): `s_j ∈ {−1, 0, +1}` is the direction from which joint `j`
//!   approached the pose (an extra input `dir_<joint>` per joint with backlash: the sign of the
//!   last motion of that joint before the pose; 0 when unknown). `2·b_j` is the dead band.
//! * **Gravity compliance** `κ_{j,i}` (rad per metre of lever): a lumped load at point `p_i`
//!   (the axis point of a downstream joint, or the tool origin) pulls along the gravity
//!   direction `ĝ` (the chain's base frame, default `−z`); its torque about joint `j`'s axis
//!   `(o_j, a_j)` is proportional to the lever `a_j·((p_i − o_j) × ĝ)`, and the joint yields by
//!   `κ_{j,i}` (= compliance × weight) times that lever in metres. The levers are computed at
//!   the commanded joint values on a *reference geometry*, frozen when the model is made (the
//!   model file's chain, or its `reference` rows once a calibration has moved the chain): a
//!   lumped load's place is a modelling choice, and levers that followed the identified
//!   geometry would tie the terms to the kinematically invisible directions of the chain (a
//!   frame slid along its joint axis). The calibration of a few millimetres changes a lever by
//!   well under 1 %.
//! * **First harmonic** `c_j, d_j` (rad): an error that repeats once per joint turn.
//!
//! The terms' values are error coordinates like the geometric ones (updated additively) and are
//! identified jointly with them; parameter names are `<joint>.backlash`,
//! `<joint>.gravity.<load>` (`<load>` a joint name or `tool`), `<joint>.cos`, `<joint>.sin`.
use super::chain::{JointKind, SerialChain};
use super::{check_inputs, Mechanism};
use crate::error::KinError;
use crate::params::{Param, Unit};
use crate::se3::{self, Pose};
use nalgebra::{DMatrix, DVector, Matrix6xX, Vector3};

/// Which non-geometric terms a serial chain carries, and their current values (the model file's
/// `[mechanism.joint_terms]`). Joint indices are 0-based positions in the chain; a load index
/// equal to the number of joints is the tool.
#[derive(Debug, Clone, PartialEq)]
pub struct JointTerms {
    /// Joints with lost motion, in order.
    pub backlash: Vec<usize>,
    /// Revolute joints that yield under gravity, in order.
    pub gravity: Vec<usize>,
    /// Load points: a joint index (the point of that joint's axis nearest its frame origin) or
    /// `n` (the tool origin). A load acts on every compliant joint before it in the chain.
    pub loads: Vec<usize>,
    /// Direction of gravity in the chain's base frame (a unit vector).
    pub gravity_direction: Vector3<f64>,
    /// Joints with a first-harmonic error, in order.
    pub harmonic: Vec<usize>,
    /// The terms' values in parameter order (see [`WithJointTerms`]); zeros when not given.
    pub values: Vec<f64>,
}

impl JointTerms {
    /// The (compliant joint, load) pairs that get a gravity parameter: every load after the joint.
    pub fn gravity_pairs(&self) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        for &j in &self.gravity {
            for &i in &self.loads {
                if i > j {
                    out.push((j, i));
                }
            }
        }
        out
    }

    /// Number of term parameters.
    pub fn n_params(&self) -> usize {
        self.backlash.len() + self.gravity_pairs().len() + 2 * self.harmonic.len()
    }

    /// The default load points for `chain` with compliant joints `gravity`: the axis point of
    /// every joint after the first compliant one and the tool origin, without points that
    /// coincide (within 1 µm, at zero joint values) with one already listed.
    pub fn default_loads(chain: &SerialChain, gravity: &[usize]) -> Vec<usize> {
        let n = chain.n_joints();
        let Some(&first) = gravity.iter().min() else {
            return Vec::new();
        };
        let points = load_points(chain, &vec![0.0; n]);
        let mut out: Vec<usize> = Vec::new();
        for i in first + 1..=n {
            if out.iter().all(|&k| (points[k] - points[i]).norm() > 1e-3) {
                out.push(i);
            }
        }
        out
    }
}

/// A serial chain with non-geometric joint terms (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct WithJointTerms {
    chain: SerialChain,
    /// The geometry the gravity levers are computed on.
    reference: SerialChain,
    terms: JointTerms,
    pairs: Vec<(usize, usize)>,
}

/// Frames `A_k = g_{0,k−1}(q)·T_{k−1,k}(0)` for every joint `k`, then the tool pose.
fn dyad_frames(chain: &SerialChain, q: &[f64]) -> Vec<Pose> {
    let mut g = Pose::identity();
    let mut out = Vec::with_capacity(q.len() + 1);
    for (j, joint) in chain.joints().iter().enumerate() {
        let a = g * chain.initial_poses()[j];
        out.push(a);
        g = a * se3::exp_joint(&joint.twist(), q[j]);
    }
    out.push(g * chain.tool());
    out
}

/// The point of joint `j`'s axis nearest its frame origin, in the frame reached by its initial
/// pose (`ω × v` for a unit revolute twist `(v, ω)`; the origin for a prismatic joint).
fn local_axis_point(chain: &SerialChain, j: usize) -> Vector3<f64> {
    let joint = &chain.joints()[j];
    let t = joint.twist();
    match joint.kind {
        JointKind::Revolute => se3::ang(&t).cross(&se3::lin(&t)),
        JointKind::Prismatic => Vector3::zeros(),
    }
}

/// Load points `p_k` (every joint's axis point, then the tool origin) in the base frame at `q`.
fn load_points(chain: &SerialChain, q: &[f64]) -> Vec<Vector3<f64>> {
    let frames = dyad_frames(chain, q);
    let n = chain.n_joints();
    (0..=n)
        .map(|k| {
            if k < n {
                frames[k] * nalgebra::Point3::from(local_axis_point(chain, k))
            } else {
                nalgebra::Point3::from(frames[n].translation.vector)
            }
            .coords
        })
        .collect()
}

/// The unit axis of revolute joint `j` in the base frame, from its frame `a_frame`.
fn axis_of(chain: &SerialChain, j: usize, a_frame: &Pose) -> Vector3<f64> {
    a_frame.rotation * se3::ang(&chain.joints()[j].twist())
}

impl WithJointTerms {
    /// `chain` with `terms`; an error when a term names a joint that is not there, gravity acts
    /// on a prismatic joint, the gravity direction is not a unit vector, or the number of values
    /// does not fit the terms.
    pub fn new(chain: SerialChain, terms: JointTerms) -> Result<Self, String> {
        let n = chain.n_joints();
        let joints = terms.backlash.iter().chain(&terms.gravity).chain(&terms.harmonic);
        if let Some(j) = joints.into_iter().find(|&&j| j >= n) {
            return Err(format!("joint index {j} is beyond the chain's {n} joints"));
        }
        if let Some(&i) = terms.loads.iter().find(|&&i| i > n) {
            return Err(format!("load index {i} is beyond the chain's {n} joints and tool"));
        }
        if let Some(&j) = terms.gravity.iter().find(|&&j| chain.joints()[j].kind != JointKind::Revolute) {
            return Err(format!(
                "joint '{}': gravity compliance is modelled for revolute joints only",
                chain.joints()[j].name
            ));
        }
        if (terms.gravity_direction.norm() - 1.0).abs() > 1e-9 {
            return Err("the gravity direction must be a unit vector".into());
        }
        for list in [&terms.backlash, &terms.gravity, &terms.harmonic, &terms.loads] {
            let mut s = list.clone();
            s.sort_unstable();
            s.dedup();
            if s.len() != list.len() {
                return Err("a joint or load is listed twice in the same term".into());
            }
        }
        if terms.values.len() != terms.n_params() {
            return Err(format!(
                "{} term values for {} term parameters",
                terms.values.len(),
                terms.n_params()
            ));
        }
        let pairs = terms.gravity_pairs();
        Ok(WithJointTerms {
            reference: chain.clone(),
            chain,
            terms,
            pairs,
        })
    }

    /// The same model with the gravity levers computed on `reference` (a chain of the same
    /// joints); an error when it does not fit.
    pub fn with_reference(mut self, reference: SerialChain) -> Result<Self, String> {
        if reference.joints() != self.chain.joints() {
            return Err("the reference geometry must have the chain's joints".into());
        }
        self.reference = reference;
        Ok(self)
    }

    /// The geometry the gravity levers are computed on.
    pub fn reference(&self) -> &SerialChain {
        &self.reference
    }

    /// The chain (its geometry).
    pub fn chain(&self) -> &SerialChain {
        &self.chain
    }

    /// The terms with their current values.
    pub fn terms(&self) -> &JointTerms {
        &self.terms
    }

    /// A load's name in parameter names: its joint's name, or `tool`.
    pub fn load_name(&self, i: usize) -> String {
        self.chain.joints().get(i).map_or_else(|| "tool".to_string(), |j| j.name.clone())
    }

    /// Names of the extra inputs: `dir_<joint>` per joint with lost motion.
    pub fn approach_names(&self) -> Vec<String> {
        self.terms
            .backlash
            .iter()
            .map(|&j| format!("dir_{}", self.chain.joints()[j].name))
            .collect()
    }

    /// This model with the geometry `values` of [`Mechanism::geometry`] (the chain's, then the
    /// term values).
    pub fn with_geometry(&self, values: &[f64]) -> Result<WithJointTerms, String> {
        let m = self.terms.values.len();
        if values.len() < m {
            return Err("too few geometry values".into());
        }
        let (g, t) = values.split_at(values.len() - m);
        let chain = self.chain.with_geometry(g)?;
        let mut terms = self.terms.clone();
        terms.values = t.to_vec();
        WithJointTerms::new(chain, terms)?.with_reference(self.reference.clone())
    }

    /// The joint offsets `q_eff − q` at joint values `q` and approach directions `s`, and, when
    /// `with_features`, their derivatives with respect to the term values (n × terms).
    fn offsets(&self, q: &[f64], s: &[f64], with_features: bool) -> (Vec<f64>, Option<DMatrix<f64>>) {
        let n = self.chain.n_joints();
        let m = self.terms.values.len();
        let mut off = vec![0.0; n];
        let mut features = with_features.then(|| DMatrix::zeros(n, m));
        let mut k = 0;
        for (&j, &sj) in self.terms.backlash.iter().zip(s) {
            off[j] += self.terms.values[k] * sj;
            if let Some(d) = features.as_mut() {
                d[(j, k)] = sj;
            }
            k += 1;
        }
        if !self.pairs.is_empty() {
            let r = &self.reference;
            let frames = dyad_frames(r, q);
            let g = self.terms.gravity_direction;
            let point = |i: usize| -> Vector3<f64> {
                if i < n {
                    (frames[i] * nalgebra::Point3::from(local_axis_point(r, i))).coords
                } else {
                    frames[n].translation.vector
                }
            };
            for &(j, i) in &self.pairs {
                let a = axis_of(r, j, &frames[j]);
                let lever = a.dot(&(point(i) - point(j)).cross(&g)) / 1000.0;
                off[j] += self.terms.values[k] * lever;
                if let Some(d) = features.as_mut() {
                    d[(j, k)] = lever;
                }
                k += 1;
            }
        }
        for &j in &self.terms.harmonic {
            let (sn, cs) = q[j].sin_cos();
            off[j] += self.terms.values[k] * cs + self.terms.values[k + 1] * sn;
            if let Some(d) = features.as_mut() {
                d[(j, k)] = cs;
                d[(j, k + 1)] = sn;
            }
            k += 2;
        }
        (off, features)
    }

    fn split<'a>(&self, q: &'a [f64]) -> Result<(&'a [f64], &'a [f64]), KinError> {
        let n = self.chain.n_joints();
        check_inputs(q, n + self.terms.backlash.len())?;
        Ok(q.split_at(n))
    }

    /// The effective joint values the chain sees at inputs `q` (joint values, then approach
    /// directions).
    pub fn effective_joints(&self, q: &[f64]) -> Result<Vec<f64>, KinError> {
        let (qj, s) = self.split(q)?;
        let (off, _) = self.offsets(qj, s, false);
        Ok(qj.iter().zip(off).map(|(a, b)| a + b).collect())
    }
}

impl Mechanism for WithJointTerms {
    fn name(&self) -> &str {
        self.chain.name()
    }

    fn input_names(&self) -> Vec<String> {
        let mut out = self.chain.input_names();
        out.extend(self.approach_names());
        out
    }

    fn params(&self) -> Vec<Param> {
        let mut out = self.chain.params();
        let name = |j: usize| self.chain.joints()[j].name.clone();
        let group = "joint terms";
        for &j in &self.terms.backlash {
            out.push(Param::new(format!("{}.backlash", name(j)), Unit::Angle, group));
        }
        for &(j, i) in &self.pairs {
            out.push(Param::new(format!("{}.gravity.{}", name(j), self.load_name(i)), Unit::Angle, group));
        }
        for &j in &self.terms.harmonic {
            out.push(Param::new(format!("{}.cos", name(j)), Unit::Angle, group));
            out.push(Param::new(format!("{}.sin", name(j)), Unit::Angle, group));
        }
        out
    }

    fn n_params(&self) -> usize {
        self.chain.n_params() + self.terms.values.len()
    }

    fn skeleton(&self) -> Vec<Vec<Vector3<f64>>> {
        self.chain.skeleton()
    }

    fn forward(&self, q: &[f64]) -> Result<Pose, KinError> {
        let qe = self.effective_joints(q)?;
        self.chain.forward(&qe)
    }

    fn forward_with_jacobian(&self, q: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        let (qj, s) = self.split(q)?;
        let (off, features) = self.offsets(qj, s, true);
        let features = features.expect("the features were asked for");
        let qe: Vec<f64> = qj.iter().zip(&off).map(|(a, b)| a + b).collect();
        let (pose, jg) = self.chain.forward_with_jacobian(&qe)?;
        let (_, jq) = self.chain.joint_jacobian(&qe)?;
        let pg = jg.ncols();
        let mut jac = Matrix6xX::zeros(pg + features.ncols());
        jac.columns_mut(0, pg).copy_from(&jg);
        jac.columns_mut(pg, features.ncols()).copy_from(&(&jq * features));
        Ok((pose, jac))
    }

    fn retract(&mut self, delta: &DVector<f64>) {
        let pg = self.chain.n_params();
        self.chain.retract(&delta.rows(0, pg).into_owned());
        for (v, d) in self.terms.values.iter_mut().zip(delta.rows(pg, delta.len() - pg).iter()) {
            *v += d;
        }
    }

    /// Newton on the joint values with the approach directions of `seed` (none: 0, mid-play):
    /// the chain's inverse kinematics gives the effective joint values, then `q = q_eff − Δ(q)`
    /// is iterated to a fixed point (the terms change by far less than the joint values).
    fn inverse(&self, target: &Pose, seed: Option<&[f64]>) -> Result<Vec<f64>, KinError> {
        let n = self.chain.n_joints();
        let nb = self.terms.backlash.len();
        let (mut q, s): (Vec<f64>, Vec<f64>) = match seed {
            Some(sd) if sd.len() == n + nb => (sd[..n].to_vec(), sd[n..].to_vec()),
            Some(sd) if sd.len() == n => (sd.to_vec(), vec![0.0; nb]),
            Some(sd) => {
                return Err(KinError::InputLength {
                    expected: n + nb,
                    got: sd.len(),
                })
            }
            None => (vec![0.0; n], vec![0.0; nb]),
        };
        let qe = self.chain.inverse(target, Some(&q))?;
        let mut change = f64::INFINITY;
        for _ in 0..50 {
            let (off, _) = self.offsets(&q, &s, false);
            let next: Vec<f64> = qe.iter().zip(&off).map(|(a, b)| a - b).collect();
            change = next.iter().zip(&q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            q = next;
            if change < 1e-14 {
                break;
            }
        }
        if change > 1e-10 {
            return Err(KinError::NoConvergence {
                what: "joint-term inverse kinematics".into(),
                iterations: 50,
                residual: change,
            });
        }
        q.extend(s);
        Ok(q)
    }

    fn box_clone(&self) -> Box<dyn Mechanism> {
        Box::new(self.clone())
    }

    fn geometry(&self) -> Option<Vec<f64>> {
        let mut g = self.chain.geometry()?;
        g.extend(&self.terms.values);
        Some(g)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::irb120;

    fn model() -> WithJointTerms {
        let chain = irb120::nominal();
        let gravity = vec![1, 2];
        let loads = JointTerms::default_loads(&chain, &gravity);
        let mut terms = JointTerms {
            backlash: (0..6).collect(),
            gravity,
            loads,
            gravity_direction: -Vector3::z(),
            harmonic: vec![1],
            values: Vec::new(),
        };
        terms.values = (0..terms.n_params()).map(|k| 1e-4 * (k as f64 + 1.0)).collect();
        WithJointTerms::new(chain, terms).unwrap()
    }

    #[test]
    fn default_loads_of_the_irb120_skip_the_tool_at_the_flange() {
        let m = model();
        assert_eq!(m.terms().loads, vec![2, 3, 4, 5]);
        let names: Vec<String> = m
            .params()
            .iter()
            .map(|p| p.name.clone())
            .filter(|n| n.contains("gravity"))
            .collect();
        assert_eq!(
            names,
            [
                "q2.gravity.q3",
                "q2.gravity.q4",
                "q2.gravity.q5",
                "q2.gravity.q6",
                "q3.gravity.q4",
                "q3.gravity.q5",
                "q3.gravity.q6"
            ]
        );
    }

    #[test]
    fn inverse_round_trips() {
        let m = model();
        let q = [0.3, -0.4, 0.5, 0.2, 0.7, -0.3, 1.0, -1.0, 1.0, 0.0, 1.0, -1.0];
        let t = m.forward(&q).unwrap();
        let mut seed = q.to_vec();
        for v in seed.iter_mut().take(6) {
            *v += 0.05;
        }
        let back = m.inverse(&t, Some(&seed)).unwrap();
        for (a, b) in back.iter().zip(q) {
            assert!((a - b).abs() < 1e-10, "{back:?} vs {q:?}");
        }
    }
}
