//! Parallel mechanisms from their limbs: a base, a moving platform and limbs that are serial
//! chains of joints in local-POE form ([`SerialChain`]), each joint actuated, passive with a
//! sensor, or passive. Nothing is derived by hand: the closure equations, forward and inverse
//! kinematics and the identification Jacobian all follow from the limb chains.
//!
//! # Closure
//! Limb `i` reaches `E_i(q_i)` (its chain's end: the dyads' product, closed by the chain's last
//! placement). It closes on the platform frame `X` in one of two ways ([`LimbEnd`]):
//!
//! * **frame** — the end is the platform frame: `E_i = X`, six equations
//!   `r_i = log(E_i·X⁻¹) = 0`;
//! * **point** — a spherical joint: the end's origin is the platform point `a_i` (platform
//!   frame), three equations `r_i = p(E_i) − X·a_i = 0`.
//!
//! The unknowns of forward kinematics are the platform pose (a spatial twist `ζ`, `X ← exp(ζ)·X`)
//! and the passive joints' values; the inputs are the actuated and sensed joints' values. With `F_z` the derivative of the stacked residual with respect to the unknowns (spatial joint
//! Jacobians of the chains, `−I` or `−[I | −[X·a]×]` for the platform), Gauss–Newton solves
//! `F_z·dz = −r` (least squares when the sensed joints make the system overdetermined, as in the
//! 3T1R paper). A mechanism whose `F_z` has a null space at home has uncommanded freedoms: an
//! error naming the mobility.
//!
//! # Identification Jacobian
//! The error parameters are each limb chain's dyad errors (eq. (33) of the 3T1R paper, six per
//! dyad, named `<limb>.<dyad>.<vx…wz>`) and, for a point end, the platform point (`<limb>.a.x…z`,
//! mm). By the implicit-function theorem, `dz = −F_z⁺·F_θ·dθ`; the first six rows of `dz` are the
//! platform's spatial twist, i.e. the spatial identification Jacobian of [`Mechanism`].
//!
//! # Inverse kinematics
//! The same equations plus the task equations ([`Task`]: the commanded part of the platform pose)
//! in the platform pose and every joint value, solved by Gauss–Newton along a straight path from
//! the home configuration to the target (continuation: the assembly mode of home is kept).
use super::chain::{JointKind, SerialChain};
use super::{check_inputs, ForwardAndObserved, Mechanism, SolvedInverse, Task};
use crate::error::KinError;
use crate::params::{Param, Unit};
use crate::se3::{self, Pose, Twist};
use nalgebra::{DMatrix, DVector, Matrix3, Matrix6xX, Vector3};
use serde::{Deserialize, Serialize};

mod closure;
mod elimination;
mod kinematics;
mod observed;
mod overconstraint;
mod reach;
mod skeleton;

/// What a joint's value is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointRole {
    /// Driven: an input.
    Actuated,
    /// Passive with a sensor: its reading is an input (a data column), as in the 3T1R paper.
    Sensed,
    /// Passive, not measured: solved from the closure.
    Passive,
    /// Passive, solved from the closure, with a sensor whose reading is an **observation**: a
    /// data column compared with the model's value and weighted by the encoder noise (maximum
    /// likelihood), not an input. For a machine whose actuators already determine it (the 3T1R
    /// machine's upper and platform angles), where a `Sensed` reading would overdetermine the
    /// closure.
    Observed,
}

/// How a limb closes on the platform.
#[derive(Debug, Clone, PartialEq)]
pub enum LimbEnd {
    /// The limb's end frame is the platform frame (six equations).
    Frame,
    /// A spherical joint: the limb end's origin is this point of the platform frame (mm; three
    /// equations).
    Point(Vector3<f64>),
}

/// A body of a limb: the frame after one of its joints (e.g. the rod of a leg, where a
/// sub-closed loop's actuator is hinged).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BodyRef {
    /// The limb (its index in the mechanism's limbs).
    pub limb: usize,
    /// The joint (index in that limb's chain) the body comes after.
    pub joint: usize,
}

/// One limb: a serial chain from the base (or a body of another limb) to its end, each joint's
/// role, and its closure.
#[derive(Debug, Clone, PartialEq)]
pub struct Limb {
    /// Name (a parameter prefix).
    pub name: String,
    /// The chain, base frame to end (its last placement reaches the end).
    pub chain: SerialChain,
    /// Role of each joint of the chain.
    pub roles: Vec<JointRole>,
    /// Closure.
    pub end: LimbEnd,
    /// Where the chain starts: the base (`None`) or a body of an earlier limb that starts on the
    /// base (a branch, as the actuator of a sub-closed loop).
    pub start: Option<BodyRef>,
    /// What the limb closes on: the platform (`None`) or a body of an earlier limb that starts on
    /// the base (a sub-closed loop). A point end's point is then in that body's frame.
    pub end_on: Option<BodyRef>,
    /// Joint values at home (the assembly branch: continuation starts here).
    pub home: Vec<f64>,
    /// How the chain's joints group into the joints of the drawing, in order (their counts add
    /// up to the chain's joints).
    pub groups: Vec<JointGroup>,
}

/// A joint of the drawing: one revolute or prismatic joint of the chain, or a universal (two)
/// or spherical (three revolute joints) whose axes meet at one point at right angles by
/// construction: the placements between them are exact and carry no error parameters (their
/// errors would be identifiable only at second order — a universal joint whose axes miss each
/// other by 0.2 mm changes the reachable points by micrometres).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointGroup {
    /// Name of the joint (its chain joints are `<name>_1`, `<name>_2`, … when there are several).
    pub name: String,
    /// What it is.
    pub kind: GroupKind,
    /// Number of chain joints (1, 2 or 3).
    pub count: usize,
    /// Its placement is exact by construction (no error parameters): e.g. the actuator of a
    /// UPS leg, whose axis runs through the universal joint's centre; an offset there would act
    /// only at second order.
    pub exact: bool,
}

/// Kind of a [`JointGroup`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GroupKind {
    /// One revolute joint.
    Revolute,
    /// One prismatic joint.
    Prismatic,
    /// Two revolute joints with intersecting axes.
    Universal,
    /// Three revolute joints with intersecting axes.
    Spherical,
    /// A parallelogram: two revolute joints about parallel axes, the distal one turning back
    /// by the proximal one's angle (`exp(ŝq)·T_bar·exp(−ŝq)`, the 3T1R paper's eq. (5)–(7)): the
    /// distal bar translates on a circle and keeps its orientation. One value `q`; the bar
    /// placement between the two carries error parameters (length, phase, mounting).
    Parallelogram,
}

impl JointGroup {
    /// One single joint per chain joint (a chain without universal or spherical joints).
    pub fn singles(chain: &SerialChain) -> Vec<JointGroup> {
        chain
            .joints()
            .iter()
            .map(|j| JointGroup {
                name: j.name.clone(),
                kind: if j.kind == JointKind::Revolute {
                    GroupKind::Revolute
                } else {
                    GroupKind::Prismatic
                },
                count: 1,
                exact: false,
            })
            .collect()
    }
}

impl Limb {
    /// Attach the limb's end to what it closes on (the platform or a body), standing at `home`,
    /// with the limb at its `home` joint values starting at `start` (the base: identity): a
    /// frame end gets its last placement (the chain's end then *is* that frame at home), a point
    /// end its point (the end's origin in that frame). What a model file that gives neither means.
    pub fn attach_at(&mut self, start: &Pose, home: &Pose) -> Result<(), KinError> {
        let e = start * self.chain.forward(&self.home)?;
        match &mut self.end {
            LimbEnd::Frame => {
                let last = self.chain.initial_poses().len() - 1;
                let tool = *self.chain.tool() * e.inverse() * home;
                self.chain.set_initial_pose(last, tool);
            }
            LimbEnd::Point(a) => *a = home.inverse_transform_point(&nalgebra::Point3::from(e.translation.vector)).coords,
        }
        Ok(())
    }

    /// The error parameters of the chain, in order: (dyad, component) with dyads the placement
    /// before each joint, then the end placement, and components `vx vy vz wx wy wz` of
    /// `T ← T·exp(δ)`. The placements inside a universal or spherical joint carry none; a
    /// parallelogram's bar carries its three translations only (length, phase and the offset
    /// along the pivots: a rotation of the bar would tilt the distal pivot, and a parallelogram
    /// whose pivots are not parallel does not move; the distal bar's orientation error is the next
    /// placement's).
    pub fn param_slots(&self) -> Vec<(usize, usize)> {
        let mut out = Vec::with_capacity(6 * (self.chain.n_joints() + 1));
        let mut dyad = 0;
        for g in &self.groups {
            if !g.exact {
                out.extend((0..6).map(|c| (dyad, c)));
            }
            if g.kind == GroupKind::Parallelogram {
                out.extend((0..3).map(|c| (dyad + 1, c)));
            }
            dyad += g.count;
        }
        out.extend((0..6).map(|c| (dyad, c)));
        out
    }

    /// Per chain joint: the joint it follows (its value the negative of that joint's: the distal
    /// joint of a parallelogram), if any.
    pub fn followers(&self) -> Vec<Option<usize>> {
        let mut out = Vec::with_capacity(self.chain.n_joints());
        for g in &self.groups {
            let first = out.len();
            out.push(None);
            for _ in 1..g.count {
                out.push((g.kind == GroupKind::Parallelogram).then_some(first));
            }
        }
        out
    }

    fn chain_params(&self) -> usize {
        self.param_slots().len()
    }

    fn rows(&self) -> usize {
        match self.end {
            LimbEnd::Frame => 6,
            LimbEnd::Point(_) => 3,
        }
    }
    fn n_params(&self) -> usize {
        self.chain_params() + if matches!(self.end, LimbEnd::Point(_)) { 3 } else { 0 }
    }
}

/// A box of platform poses: position (mm, base frame) and roll-pitch-yaw (rad) offsets from the
/// home orientation, `R = Rz(yaw)·Ry(pitch)·Rx(roll)·R_home` (as `kinecal plan`'s box), where
/// configurations are drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseBox {
    /// Lower position bounds (mm, base frame).
    pub position_min: Vector3<f64>,
    /// Upper position bounds.
    pub position_max: Vector3<f64>,
    /// Lower roll, pitch, yaw offsets (rad).
    pub rpy_min: [f64; 3],
    /// Upper offsets.
    pub rpy_max: [f64; 3],
}

/// A parallel (or hybrid) mechanism described by its limbs (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq)]
pub struct LimbMechanism {
    name: String,
    limbs: Vec<Limb>,
    task: Task,
    home: Pose,
    workspace: Option<PoseBox>,
    /// Per input: (limb, joint).
    inputs: Vec<(usize, usize)>,
    /// Per passive unknown: (limb, joint).
    passive: Vec<(usize, usize)>,
    /// The observed joints ([`JointRole::Observed`]): indices into `passive`.
    observed: Vec<usize>,
    /// Per limb and joint: the input or passive unknown it is.
    slots: Vec<Vec<Slot>>,
    /// The limbs grouped for the elimination of the closure's Newton systems.
    clusters: Option<Vec<elimination::Cluster>>,
    /// The forward kinematics' tangent at home (the first continuation stage's predictor).
    tangent: Option<DMatrix<f64>>,
}

/// What a joint's value is among the unknowns: the `k`-th input or the `k`-th passive joint.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Slot {
    Input(usize),
    Passive(usize),
    /// The distal joint of a parallelogram: minus the value of this joint of its limb.
    Follows(usize),
}

/// Per limb and joint, its [`Slot`].
fn slots(limbs: &[Limb], inputs: &[(usize, usize)], passive: &[(usize, usize)]) -> Vec<Vec<Slot>> {
    let mut out: Vec<Vec<Slot>> = limbs.iter().map(|l| vec![Slot::Passive(0); l.chain.n_joints()]).collect();
    for (k, &(i, j)) in inputs.iter().enumerate() {
        out[i][j] = Slot::Input(k);
    }
    for (k, &(i, j)) in passive.iter().enumerate() {
        out[i][j] = Slot::Passive(k);
    }
    for (i, l) in limbs.iter().enumerate() {
        for (j, f) in l.followers().into_iter().enumerate() {
            if let Some(m) = f {
                out[i][j] = Slot::Follows(m);
            }
        }
    }
    out
}

/// Newton iterations of one solve.
const MAX_ITERATIONS: usize = 60;
/// Convergence: max-norm of the closure residual (mm and rad).
const TOLERANCE: f64 = 1e-11;
/// Closure residual (mm / rad) an intermediate continuation stage is solved to.
const STAGE_TOLERANCE: f64 = 1e-6;
/// Largest input change (rad) of one forward-kinematics continuation stage.
pub const FK_STAGE_RAD: f64 = 0.25;
/// Largest input change (mm) of one forward-kinematics continuation stage.
pub const FK_STAGE_MM: f64 = 25.0;
/// Largest gap (mm / rad) a limb may leave at the home pose before the whole mechanism is solved
/// there: geometric errors leave a lower-mobility machine's limbs a little off a pose they are
/// not free to reach; a limb further off is described wrongly.
const HOME_GAP: f64 = 10.0;
/// Condition number of `F_z` beyond which a configuration is singular.
const MAX_CONDITION: f64 = 1e10;

/// The values of every joint of every limb.
type Joints = Vec<Vec<f64>>;

impl LimbMechanism {
    /// A mechanism from its limbs; `home` is the platform pose where the limbs' `home` joint values
    /// (the assembly branch) hold. The home configuration is solved once (from those values) and
    /// its mobility checked: errors name the limb that cannot close, or the freedoms that no
    /// input commands.
    pub fn new(name: impl Into<String>, limbs: Vec<Limb>, task: Task, home: Pose, workspace: Option<PoseBox>) -> Result<Self, String> {
        let mut inputs = Vec::new();
        let mut sensed = Vec::new();
        let mut passive = Vec::new();
        let mut observed = Vec::new();
        let mut names = std::collections::HashSet::new();
        if limbs.is_empty() {
            return Err("a parallel mechanism needs at least one limb".into());
        }
        for (i, l) in limbs.iter().enumerate() {
            if l.roles.len() != l.chain.n_joints() || l.home.len() != l.chain.n_joints() {
                return Err(format!("limb '{}': one role and one home value per joint", l.name));
            }
            if l.groups.iter().map(|g| g.count).sum::<usize>() != l.chain.n_joints() || l.groups.iter().any(|g| g.count == 0) {
                return Err(format!("limb '{}': its joint groups do not cover its chain's joints", l.name));
            }
            if !names.insert(l.name.clone()) {
                return Err(format!("limb '{}': limb names must be unique", l.name));
            }
            if l.groups.iter().any(|g| g.kind == GroupKind::Parallelogram && g.count != 2) {
                return Err(format!("limb '{}': a parallelogram is two chain joints", l.name));
            }
            let followers = l.followers();
            for (j, r) in l.roles.iter().enumerate() {
                if followers[j].is_some() {
                    continue;
                }
                match r {
                    JointRole::Actuated => inputs.push((i, j)),
                    JointRole::Sensed => sensed.push((i, j)),
                    JointRole::Passive => passive.push((i, j)),
                    JointRole::Observed => {
                        observed.push(passive.len());
                        passive.push((i, j));
                    }
                }
            }
        }
        for (i, l) in limbs.iter().enumerate() {
            for (what, b) in [("starts", &l.start), ("closes", &l.end_on)] {
                let Some(b) = b else { continue };
                let ok = b.limb < i && limbs[b.limb].start.is_none() && b.joint < limbs[b.limb].chain.n_joints();
                if !ok {
                    return Err(format!(
                        "limb '{}' {what} on a body of a limb that is not an earlier limb starting on the base (list the limb it {what} on first)",
                        l.name
                    ));
                }
            }
        }
        inputs.extend(sensed);
        let mut joint_names = std::collections::HashSet::new();
        for (i, l) in limbs.iter().enumerate() {
            for jt in l.chain.joints() {
                if !joint_names.insert(jt.name.clone()) {
                    return Err(format!(
                        "limb '{}': joint name '{}' is used twice (joint names are input names: unique over the mechanism)",
                        limbs[i].name, jt.name
                    ));
                }
            }
        }
        if inputs.is_empty() {
            return Err("no joint is actuated or sensed: the mechanism has no inputs".into());
        }
        let mut m = LimbMechanism {
            name: name.into(),
            task,
            home,
            workspace,
            clusters: elimination::clusters(&limbs, &inputs, &passive),
            slots: slots(&limbs, &inputs, &passive),
            tangent: None,
            limbs,
            inputs,
            passive,
            observed,
        };
        // Each limb as close to the home pose as it gets from its home values (least squares, per
        // limb, to name the one that cannot close) ...
        let mut gaps = Vec::with_capacity(m.limbs.len());
        for i in 0..m.limbs.len() {
            // (The bodies a limb starts or ends on belong to earlier limbs, solved already.)
            let joints: Joints = m.limbs.iter().map(|l| l.home.clone()).collect();
            let (start, target) = (m.start_pose(i, &joints), m.target_pose(i, &m.home, &joints));
            let (Ok(start), Ok(target)) = (start, target) else {
                return Err(format!(
                    "limb '{}': the body it starts or closes on cannot be evaluated at home",
                    m.limbs[i].name
                ));
            };
            let (solved, gap) = m.solve_limb_from(i, &start, &target, m.limbs[i].home.clone());
            gaps.push(gap);
            if gap.is_nan() || gap >= HOME_GAP {
                return Err(format!(
                    "limb '{}' cannot close at the home pose: its end stays {gap:.3} (mm / rad) from the platform; check its joint placements, the platform point and the home pose",
                    m.limbs[i].name
                ));
            }
            m.limbs[i].home = solved;
        }
        // ... then the whole mechanism at the commanded part of the home pose (a machine with
        // fewer than six freedoms and geometric errors has its own orientation there).
        let (x, q, passive) = m
            .solve_inverse(&m.home.clone(), (m.home, m.home_inputs(), m.home_passive()))
            .map_err(|e| {
                let worst = (0..gaps.len()).max_by(|a, b| gaps[*a].total_cmp(&gaps[*b])).unwrap_or(0);
                format!(
                    "the limbs do not close together at the home pose ({e}); limb '{}' is furthest off ({:.3e} mm / rad alone): check its geometry and the home pose",
                    m.limbs[worst].name, gaps[worst]
                )
            })?;
        let joints = m.joints_of(&q, &passive);
        for (l, j) in m.limbs.iter_mut().zip(joints) {
            l.home = j;
        }
        // The home values are only seeds of the assembly: a solve that closed the machine with a
        // joint beyond its limits (e.g. a crank wound by turns) found another configuration.
        for l in &m.limbs {
            for (jt, v) in l.chain.joints().iter().zip(&l.home) {
                if let Some((lo, hi)) = jt.limits {
                    if *v < lo - 1e-6 || *v > hi + 1e-6 {
                        let (f, unit) = if jt.kind == JointKind::Revolute {
                            (180.0 / std::f64::consts::PI, "deg")
                        } else {
                            (1.0, "mm")
                        };
                        return Err(format!(
                            "limb '{}' closes at the home pose only with joint {} = {:.3} {unit}, outside its limits [{:.3}, {:.3}] {unit}: check the home values (they choose the assembly branch) and the geometry",
                            l.name, jt.name, v * f, lo * f, hi * f
                        ));
                    }
                }
            }
        }
        m.home = x;
        m.tangent = m.home_tangent();
        let rows: usize = m.limbs.iter().map(Limb::rows).sum();
        let unknowns = 6 + m.passive.len();
        let joints: Joints = m.limbs.iter().map(|l| l.home.clone()).collect();
        let (_, fz) = m.closure(&m.home, &joints, true);
        if fz.iter().any(|v| !v.is_finite() || v.abs() > 1e100) {
            return Err("the closure's derivative at the home pose has extreme values: check the joint placements and platform points for extreme numbers".into());
        }
        if rows < unknowns {
            return Err(format!(
                "wrong mobility: {rows} closure equations for {unknowns} unknowns (the platform's 6 and {} passive joints): with the inputs fixed the platform could still move{}; actuate or sense more joints, or close limbs with a full frame",
                m.passive.len(),
                m.free_motion(&fz)
            ));
        }
        let sv = fz.singular_values();
        let (hi, lo) = (sv.max(), sv.min());
        if lo.is_nan() || lo <= hi / MAX_CONDITION {
            let free = sv.iter().filter(|s| **s <= hi / MAX_CONDITION).count();
            return Err(format!(
                "wrong mobility: with the inputs fixed at home the platform and passive joints keep {free} freedom(s) (the closure equations do not determine them){}; actuate or sense more joints, or check the limb geometry (a limb at a singularity at home)",
                m.free_motion(&fz)
            ));
        }
        Ok(m)
    }

    /// The limbs.
    pub fn limbs(&self) -> &[Limb] {
        &self.limbs
    }
    /// The home platform pose.
    pub fn home(&self) -> &Pose {
        &self.home
    }
    /// The workspace box, if given.
    pub fn workspace(&self) -> Option<&PoseBox> {
        self.workspace.as_ref()
    }
    /// Per input: (limb, joint) it drives or reads.
    pub fn input_joints(&self) -> &[(usize, usize)] {
        &self.inputs
    }
    /// The inputs at home.
    pub fn home_inputs(&self) -> Vec<f64> {
        self.inputs.iter().map(|&(i, j)| self.limbs[i].home[j]).collect()
    }

    /// This mechanism with the geometry `values` of [`Mechanism::geometry`].
    pub fn with_geometry(&self, values: &[f64]) -> Result<LimbMechanism, String> {
        let mut out = self.clone();
        let mut k = 0;
        for l in &mut out.limbs {
            let n = 12 * l.chain.initial_poses().len();
            let v = values.get(k..k + n).ok_or("geometry: too few values for this mechanism")?;
            l.chain = l.chain.with_geometry(v)?;
            k += n;
            if let LimbEnd::Point(a) = &mut l.end {
                let v = values.get(k..k + 3).ok_or("geometry: too few values for this mechanism")?;
                *a = Vector3::new(v[0], v[1], v[2]);
                k += 3;
            }
        }
        if k != values.len() {
            return Err(format!("geometry: {} values for a mechanism of {k}", values.len()));
        }
        // The home configuration is where the home inputs put the new geometry (a calibrated
        // model is written with a home it closes at).
        let q0 = out.home_inputs();
        let (x, passive) = out
            .solve_forward(&q0, out.home, out.home_passive(), TOLERANCE)
            .map_err(|e| format!("geometry: the mechanism does not assemble at its home inputs ({e})"))?;
        let joints = out.joints_of(&q0, &passive);
        for (l, j) in out.limbs.iter_mut().zip(joints) {
            l.home = j;
        }
        out.home = x;
        out.tangent = out.home_tangent();
        Ok(out)
    }
}

impl Mechanism for LimbMechanism {
    fn name(&self) -> &str {
        &self.name
    }

    fn input_names(&self) -> Vec<String> {
        self.inputs
            .iter()
            .map(|&(i, j)| self.limbs[i].chain.joints()[j].name.clone())
            .collect()
    }

    fn params(&self) -> Vec<Param> {
        let mut out = Vec::new();
        for l in &self.limbs {
            let all = l.chain.params();
            for (d, c) in l.param_slots() {
                let p = &all[6 * d + c];
                out.push(Param::new(format!("{}.{}", l.name, p.name), p.unit, format!("limb {}", l.name)));
            }
            if matches!(l.end, LimbEnd::Point(_)) {
                for c in ["x", "y", "z"] {
                    out.push(Param::new(format!("{}.a.{c}", l.name), Unit::Length, format!("limb {}", l.name)));
                }
            }
        }
        out
    }

    fn n_params(&self) -> usize {
        self.limbs.iter().map(Limb::n_params).sum()
    }
    fn assembly_breaking(&self) -> Vec<usize> {
        LimbMechanism::assembly_breaking(self)
    }

    fn skeleton(&self) -> Vec<Vec<Vector3<f64>>> {
        self.home_skeleton()
    }

    fn forward(&self, q: &[f64]) -> Result<Pose, KinError> {
        self.forward_full(q).map(|(x, _)| x)
    }

    fn forward_with_jacobian(&self, q: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        let (x, _, fz, fp) = self.linearized(q)?;
        Ok((x, self.platform_rows(&fz, &fp)?))
    }

    /// The platform pose and the passive joints' values.
    fn forward_solution(&self, q: &[f64]) -> Result<(Pose, Vec<f64>), KinError> {
        self.forward_full(q)
    }

    /// The closure's derivatives at `(pose, rest)` (the passive joints' values), no forward solve.
    fn forward_with_jacobian_at(&self, q: &[f64], pose: &Pose, rest: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        self.jacobian_at(q, pose, rest)
    }

    fn retract(&mut self, delta: &DVector<f64>) {
        let mut k = 0;
        for l in &mut self.limbs {
            let mut d = DVector::zeros(l.chain.n_params());
            for (dyad, c) in l.param_slots() {
                d[6 * dyad + c] = delta[k];
                k += 1;
            }
            l.chain.retract(&d);
            if let LimbEnd::Point(a) = &mut l.end {
                *a += Vector3::new(delta[k], delta[k + 1], delta[k + 2]);
                k += 3;
            }
        }
    }

    fn inverse(&self, target: &Pose, _seed: Option<&[f64]>) -> Result<Vec<f64>, KinError> {
        let (q, _, _) = self.inverse_full(target)?;
        self.within_limits(q)
    }

    /// The inputs, the pose reached and the passive joints' values the inverse solved.
    fn inverse_solution(&self, target: &Pose, _seed: Option<&[f64]>) -> Result<SolvedInverse, KinError> {
        let (q, passive, reached) = self.inverse_full(target)?;
        Ok((self.within_limits(q)?, Some((reached, passive))))
    }

    fn box_clone(&self) -> Box<dyn Mechanism> {
        Box::new(self.clone())
    }

    fn inverse_ignores_seed(&self) -> bool {
        true
    }

    fn geometry(&self) -> Option<Vec<f64>> {
        let mut out = Vec::new();
        for l in &self.limbs {
            out.extend(l.chain.geometry()?);
            if let LimbEnd::Point(a) = &l.end {
                out.extend(a.iter().copied());
            }
        }
        Some(out)
    }

    fn task(&self) -> Task {
        self.task
    }

    fn sample_configurations(&self, n: usize, seed: u64) -> Option<Result<Vec<Vec<f64>>, KinError>> {
        self.sample_in_workspace(n, seed)
    }

    fn observed_joints(&self) -> Vec<(String, Unit)> {
        self.observed_names()
    }

    fn observed_joint_values(&self, q: &[f64]) -> Result<Vec<f64>, KinError> {
        self.observed_values(q)
    }

    fn observed_joints_with_jacobian(&self, q: &[f64]) -> Result<(Vec<f64>, DMatrix<f64>), KinError> {
        self.observed_with_jacobian(q)
    }

    fn forward_and_observed(&self, q: &[f64]) -> Result<(Pose, Vec<f64>), KinError> {
        let (x, passive) = self.forward_full(q)?;
        Ok((x, self.observed_of(&passive)))
    }

    /// One forward solve and one closure derivative for both: the platform's rows and the
    /// observed joints' rows of `dz = −F_z⁻¹·F_θ`.
    fn forward_with_jacobian_and_observed(&self, q: &[f64], _near: Option<&Pose>) -> Result<ForwardAndObserved, KinError> {
        let (x, passive, fz, fp) = self.linearized(q)?;
        Ok((
            x,
            self.platform_rows(&fz, &fp)?,
            self.observed_of(&passive),
            self.observed_rows(&fz, &fp)?,
        ))
    }
}

/// A limbs machine from model-file text (the tests of this module's parts).
#[cfg(test)]
fn limbs_from_text(text: &str) -> LimbMechanism {
    use crate::io::model_file::{MechanismSpec, ModelFile};
    match ModelFile::load_str(std::path::Path::new("m.toml"), text).unwrap().mechanism {
        MechanismSpec::Limbs(m) => m,
        _ => panic!("a limbs model expected"),
    }
}
