//! The 3T1R 4-DOF symmetrical parallel manipulator of the seed paper (Zhang et al., 2020), as a
//! mechanism that closes.
//!
//! # The machine
//!
//! Base frame `{B}`: two rails along `y`, side I at `x = 0` and side II at `x = b`, `z` up. On each
//! rail two sliders (side I: `B1`, `B2`; side II: `B3`, `B4`) carry **upper parallelograms** whose
//! pivots run along `x`: they move in the `y–z` plane of their rail and meet, as an inverted V, at
//! a sub-platform `D_s`, which therefore only translates (in `y` and `z`). From `D_s` a **lower
//! parallelogram** with pivots along `y` (motion in the `x–z` plane) carries a body that holds a
//! revolute joint `A_s` (axis `z`) of the moving platform. `|A1A2| = a`, the tool point `P` is the
//! midpoint of `A1A2`. Four sliders give `(x, y, z, yaw)` of the platform (3T1R).
//!
//! Dimensions (§6): `l_u = l_d = 700 mm`, `a = 300 mm`, `b = 1000 mm`; the printed 0.03 m is the
//! slider zero: a slider coordinate `s` puts the slider at `y = 30 mm + s`.
//!
//! # Branched chains (eq. (5)–(7)) and the printed matrices
//!
//! A chain runs from one slider to `P` and has four joint coordinates: the slider `q_i1` (mm), the
//! upper-parallelogram angle `q_i2`, the lower-parallelogram angle `q_i3` and the platform
//! revolute `q_i4` (rad). A parallelogram of link `T = [R, p]` about the pivot twist `ŝ` is exactly
//! two coupled revolutes,
//!
//! ```text
//! Par(q) = exp(ŝq)·Trans(p)·exp(−ŝq)·Rot(R) = [R, R_ŝ(q)·p]
//! ```
//!
//! (the distal bar translates on a circle and keeps its orientation `R`), so a chain is
//!
//! ```text
//! g_i = T_{B,i1}(0)·exp(ŝ_{i1}q_{i1}) · T_{i1,i2}(0)·Par_{ŝ_{i2}}(q_{i2}; T_{i2,i3}(0)) · Par_{ŝ_{i3}}(q_{i3}; T_{i3,i4}(0)) · exp(ŝ_{i4}q_{i4})·T_{i4,P}(0)
//! ```
//!
//! with five initial poses (30 error coordinates, the paper's `x_i`). Nominally
//! `T_{B,11} = Trans(0, 30, 0)`, `T_{11,12} = I`, `T_{12,13} = Trans(0, l_u, 0)`,
//! `T_{13,14} = Trans(l_d, 0, 0)`, `T_{14,P} = Trans(a/2, 0, 0)`, `s_{11} = y` (prismatic), `s_{12} = x`,
//! `s_{13} = y`, `s_{14} = z` (revolutes); side II has `T_{B,21} = Trans(b, 30, 0)` and
//! `T_{24,P} = Trans(−a/2, 0, 0)`. The **printed** chain of §6 is this chain with the
//! counter-rotations frozen at the nominal angles: `T_{12,13}(0) = Trans(0, l_u, 0)·R_x(−α)` is
//! `Trans(p)·exp(−ŝα)`, `T_{13,14}(0) = Trans(l_d, 0, 0)·R_y(−β)` and `T_{23,24}(0) =
//! Trans(l_d, 0, 0)·R_y(−(π − β))` (the printed matrix with `−cos β`, `−sin β`). Nominal angles:
//! `q_12 = q_22 = α = 45°` (Table 2), `q_13 = β`, `q_23 = π − β` with `b − 2·l_d·cos β = a`, i.e.
//! `β = 60°`; the idle chains `B2`, `B4` have `q = π − α` at their upper parallelogram and share
//! the lower parallelogram and the platform revolute of their side.
//!
//! Inside kinecal a chain is a [`SerialChain`] of six joints (the two coupled pairs expanded),
//! `q = (q1, q2, −q2, q3, −q3, q4)`, whose seven initial poses are `T_B, T_12, Trans(p_23),
//! Rot(R_23), Trans(p_34), Rot(R_34), T_4P`; [`BranchedChain`] maps the paper's 30 coordinates onto
//! that chain's 42 (its identification Jacobian is the chain's row of adjoints times that map).
//!
//! # Workspace
//!
//! [`Workspace::default`]: `x ∈ 500 ± 80 mm`, `y ∈ 600 ± 200 mm`, `z ∈ −111.25 ± 80 mm`,
//! `yaw ∈ ±15°` around the home pose (all angles at their nominal values). Every pose of that box
//! is reachable: on a 9⁴ grid over it the upper-parallelogram angles stay within 30.7°–61.4°, the
//! lower ones within 51.6°–67.3° of their rail plane, the sliders within −271…1411 mm, and the
//! condition number of `d(x, y, z, (a/2)·yaw)/d(sliders)` (yaw as the arc of the platform
//! revolutes, all rows in mm; [`T3r1::actuator_jacobian`]) within 1.7–2.4 (tested).
//!
use crate::error::KinError;
use crate::model::chain::{ChainJoint, JointKind, SerialChain};
use crate::model::{check_inputs, Mechanism};
use crate::params::{Param, Unit};
use crate::se3::{self, Pose, Twist};
use nalgebra::{DMatrix, DVector, Matrix4, Matrix6x4, Matrix6xX, Translation3, UnitQuaternion, Vector3, Vector6};
use serde::Serialize;
use std::f64::consts::PI;

/// Dimensions of the machine (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Geometry {
    /// Upper-parallelogram link length `l_u`.
    pub l_u: f64,
    /// Lower-parallelogram link length `l_d`.
    pub l_d: f64,
    /// Distance `a = |A1A2|` of the platform revolutes.
    pub a: f64,
    /// Rail distance `b`.
    pub b: f64,
    /// `y` of the slider zero (the printed 0.03 m).
    pub slider_zero: f64,
}

impl Default for Geometry {
    /// The dimensions of §6: `l_u = l_d = 700`, `a = 300`, `b = 1000`, slider zero 30 (mm).
    fn default() -> Self {
        Geometry {
            l_u: 700.0,
            l_d: 700.0,
            a: 300.0,
            b: 1000.0,
            slider_zero: 30.0,
        }
    }
}

impl Geometry {
    /// Nominal upper-parallelogram angle `α` of the printed matrices (45°, Table 2).
    pub fn alpha(&self) -> f64 {
        PI / 4.0
    }
    /// Nominal lower-parallelogram angle `β` from `b − 2·l_d·cos β = a` (60° for §6).
    pub fn beta(&self) -> f64 {
        ((self.b - self.a) / (2.0 * self.l_d)).acos()
    }
    /// The home pose: every angle at its nominal value, slider `B1` at its zero.
    pub fn home(&self) -> PlatformPose {
        let (al, be) = (self.alpha(), self.beta());
        PlatformPose {
            x: self.b / 2.0,
            y: self.slider_zero + self.l_u * al.cos(),
            z: self.l_u * al.sin() - self.l_d * be.sin(),
            yaw: 0.0,
        }
    }
}

/// The four branched chains: `B1`, `B3` are the calibrated pair (`i = 1, 2`), `B2`, `B4` the idle
/// pair used for cross-validation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum ChainId {
    /// Slider `B1`, side I (chain `i = 1`).
    B1,
    /// Slider `B2`, side I (idle chain `ī = 1`).
    B2,
    /// Slider `B3`, side II (chain `i = 2`).
    B3,
    /// Slider `B4`, side II (idle chain `ī = 2`).
    B4,
}

impl ChainId {
    /// All four chains, slider order.
    pub const ALL: [ChainId; 4] = [ChainId::B1, ChainId::B2, ChainId::B3, ChainId::B4];
    /// Slider index 0..4 (`B1`..`B4`).
    pub fn index(self) -> usize {
        match self {
            ChainId::B1 => 0,
            ChainId::B2 => 1,
            ChainId::B3 => 2,
            ChainId::B4 => 3,
        }
    }
    /// Side: 0 for I (`x = 0`), 1 for II (`x = b`).
    pub fn side(self) -> usize {
        self.index() / 2
    }
    /// Whether this is an idle chain (`B2`, `B4`).
    pub fn idle(self) -> bool {
        self.index() % 2 == 1
    }
    /// The label used in dyad names: `1`, `1'`, `2`, `2'` (the paper's `i` and `ī`).
    pub fn label(self) -> &'static str {
        match self {
            ChainId::B1 => "1",
            ChainId::B2 => "1'",
            ChainId::B3 => "2",
            ChainId::B4 => "2'",
        }
    }
}

/// Platform pose in the 3T1R coordinates: position (mm) and yaw (rad).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlatformPose {
    /// x (mm).
    pub x: f64,
    /// y (mm).
    pub y: f64,
    /// z (mm).
    pub z: f64,
    /// Rotation about z (rad).
    pub yaw: f64,
}

impl PlatformPose {
    /// The pose `Trans(x, y, z)·R_z(yaw)`.
    pub fn to_pose(&self) -> Pose {
        Pose::from_parts(
            Translation3::new(self.x, self.y, self.z),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.yaw),
        )
    }
    /// The 3T1R coordinates of a pose: its position and `yaw = atan2(R₁₀, R₀₀)` (any tilt is
    /// dropped; see [`tilt`]).
    pub fn from_pose(t: &Pose) -> Self {
        let r = se3::rotation_matrix(t);
        PlatformPose {
            x: t.translation.x,
            y: t.translation.y,
            z: t.translation.z,
            yaw: r[(1, 0)].atan2(r[(0, 0)]),
        }
    }
}

/// Tilt of a pose (rad): the angle between its `z` axis and the base `z` axis. A 3T1R machine
/// cannot change it, so it is reported apart from `(x, y, z, yaw)`.
pub fn tilt(t: &Pose) -> f64 {
    let z = t.rotation * Vector3::z();
    z.z.clamp(-1.0, 1.0).acos()
}

/// One branched chain `B_i → P` in local POE with parallelograms (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct BranchedChain {
    name: String,
    dyad_names: [String; 5],
    /// The paper's five initial poses `T_{B,i1}, T_{i1,i2}, T_{i2,i3}, T_{i3,i4}, T_{i4,P}`.
    dyads: [Pose; 5],
    /// Joint twists `s_{i1}` (prismatic) … `s_{i4}`; parallelogram and revolute twists are pure
    /// rotations through their frame's origin.
    twists: [Twist; 4],
    serial: SerialChain,
}

fn split(t: &Pose) -> (Pose, Pose) {
    (
        Pose::from_parts(t.translation, UnitQuaternion::identity()),
        Pose::from_parts(Translation3::identity(), t.rotation),
    )
}

impl BranchedChain {
    /// A chain from its five initial poses and four joint twists; `label` names the dyads
    /// (`"1"` gives `B-11`, `11-12`, `12-13`, `13-14`, `14-P`).
    pub fn new(name: impl Into<String>, label: &str, dyads: [Pose; 5], twists: [Twist; 4]) -> Self {
        let dyad_names = [
            format!("B-{label}1"),
            format!("{label}1-{label}2"),
            format!("{label}2-{label}3"),
            format!("{label}3-{label}4"),
            format!("{label}4-P"),
        ];
        Self::from_parts(name.into(), dyad_names, dyads, twists)
    }

    fn from_parts(name: String, dyad_names: [String; 5], dyads: [Pose; 5], twists: [Twist; 4]) -> Self {
        let serial = Self::build_serial(&name, &dyads, &twists);
        BranchedChain {
            name,
            dyad_names,
            dyads,
            twists,
            serial,
        }
    }

    fn build_serial(name: &str, dyads: &[Pose; 5], twists: &[Twist; 4]) -> SerialChain {
        let joint = |n: &str, kind: JointKind, s: &Twist| ChainJoint {
            name: n.to_string(),
            kind,
            twist: [s[0], s[1], s[2], s[3], s[4], s[5]],
            limits: None,
        };
        let joints = vec![
            joint("q1", JointKind::Prismatic, &twists[0]),
            joint("q2", JointKind::Revolute, &twists[1]),
            joint("-q2", JointKind::Revolute, &twists[1]),
            joint("q3", JointKind::Revolute, &twists[2]),
            joint("-q3", JointKind::Revolute, &twists[2]),
            joint("q4", JointKind::Revolute, &twists[3]),
        ];
        let (p23, r23) = split(&dyads[2]);
        let (p34, r34) = split(&dyads[3]);
        SerialChain::new(name, joints, vec![dyads[0], dyads[1], p23, r23, p34, r34], dyads[4])
    }

    /// The nominal chain `id` of the machine `geometry`.
    pub fn nominal(geometry: &Geometry, id: ChainId) -> Self {
        let g = geometry;
        let x0 = if id.side() == 0 { 0.0 } else { g.b };
        let tool = if id.side() == 0 { g.a / 2.0 } else { -g.a / 2.0 };
        let dyads = [
            se3::translation(x0, g.slider_zero, 0.0),
            Pose::identity(),
            se3::translation(0.0, g.l_u, 0.0),
            se3::translation(g.l_d, 0.0, 0.0),
            se3::translation(tool, 0.0, 0.0),
        ];
        let twists = [
            Twist::new(0.0, 1.0, 0.0, 0.0, 0.0, 0.0),
            Twist::new(0.0, 0.0, 0.0, 1.0, 0.0, 0.0),
            Twist::new(0.0, 0.0, 0.0, 0.0, 1.0, 0.0),
            Twist::new(0.0, 0.0, 0.0, 0.0, 0.0, 1.0),
        ];
        BranchedChain::new(format!("B{}", id.index() + 1), id.label(), dyads, twists)
    }

    /// The five initial poses.
    pub fn dyads(&self) -> &[Pose; 5] {
        &self.dyads
    }

    /// The four joint twists.
    pub fn twists(&self) -> &[Twist; 4] {
        &self.twists
    }

    /// Names of the five dyads (`B-11`, `11-12`, …, `14-P`).
    pub fn dyad_names(&self) -> &[String; 5] {
        &self.dyad_names
    }

    /// The equivalent six-joint local-POE serial chain.
    pub fn serial(&self) -> &SerialChain {
        &self.serial
    }

    /// The six serial-chain joint values `(q1, q2, −q2, q3, −q3, q4)` of the four chain coordinates.
    pub fn expand(q: &[f64]) -> [f64; 6] {
        [q[0], q[1], -q[1], q[2], -q[2], q[3]]
    }

    /// Position of the sub-platform point `D` (distal pivot of the upper parallelogram) and of the
    /// platform revolute `A` (distal pivot of the lower parallelogram).
    pub fn points(&self, q: &[f64]) -> Result<(Vector3<f64>, Vector3<f64>), KinError> {
        check_inputs(q, 4)?;
        let f = self.serial.frames(&Self::expand(q))?;
        Ok((f[2].translation.vector, f[4].translation.vector))
    }

    /// Spatial joint Jacobian (6 × 4) of the four chain coordinates and the tool pose.
    pub fn joint_jacobian(&self, q: &[f64]) -> Result<(Pose, Matrix6x4<f64>), KinError> {
        check_inputs(q, 4)?;
        let (g, j6) = self.serial.joint_jacobian(&Self::expand(q))?;
        let mut j = Matrix6x4::zeros();
        j.set_column(0, &j6.column(0));
        j.set_column(1, &(j6.column(1) - j6.column(2)));
        j.set_column(2, &(j6.column(3) - j6.column(4)));
        j.set_column(3, &j6.column(5));
        Ok((g, j))
    }

    /// Replace the twists by the nominal directions (`y` prismatic, `x`, `y`, `z` revolutes) and
    /// the readings by `reading = actual − offset`, keeping every pose of the chain: the
    /// equivalent chain of the model family, in the coordinates the sensors read.
    ///
    /// Exact rewriting (module docs): a joint offset `δ` of a parallelogram moves into the
    /// preceding pose (`·exp(ŝδ)`) and the link's rotation (`exp(−ŝδ)·R`); an axis tilt `s = R_c·n`
    /// moves into the preceding pose (`·R_c`) and the following one (`R_c⁻¹·`).
    /// Twists must be pure translations (slider) or rotations through their frame's origin.
    pub fn in_reading_coordinates(&self, offsets: &[f64; 4]) -> BranchedChain {
        let mut d = self.dyads;
        let s = self.twists;
        // Offsets, with the actual twists.
        d[0] *= se3::exp(&(s[0] * offsets[0]));
        for (k, j) in [(1usize, 1usize), (2, 2)] {
            let e = se3::exp(&(s[j] * offsets[j]));
            d[k] *= e;
            let (p, r) = split(&d[k + 1]);
            d[k + 1] = p * e.inverse() * r;
        }
        d[3] *= se3::exp(&(s[3] * offsets[3]));
        // Tilts.
        let nominal = [Vector3::y(), Vector3::x(), Vector3::y(), Vector3::z()];
        for j in 0..4 {
            let dir = if j == 0 { se3::lin(&s[j]) } else { se3::ang(&s[j]) };
            // Anti-parallel directions: a half turn about a perpendicular basis axis.
            let rc = UnitQuaternion::rotation_between(&nominal[j], &dir)
                .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(nominal[(j + 1) % 4]), PI));
            let rc = Pose::from_parts(Translation3::identity(), rc);
            d[j] *= rc;
            d[j + 1] = rc.inverse() * d[j + 1];
        }
        let mut twists = [Twist::zeros(); 4];
        twists[0] = Twist::new(0.0, 1.0, 0.0, 0.0, 0.0, 0.0);
        twists[1] = Twist::new(0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
        twists[2] = Twist::new(0.0, 0.0, 0.0, 0.0, 1.0, 0.0);
        twists[3] = Twist::new(0.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        BranchedChain::from_parts(self.name.clone(), self.dyad_names.clone(), d, twists)
    }

    /// A copy with the initial poses multiplied on the right by `exp(δt)` (Table 1's preset
    /// errors), the twists replaced by `twists` (the `δs` tilts, unit directions).
    pub fn with_errors(&self, dt: &[Twist; 5], twists: [Twist; 4]) -> BranchedChain {
        let mut d = self.dyads;
        for (k, t) in d.iter_mut().enumerate() {
            *t *= se3::exp(&dt[k]);
        }
        let mut out = self.clone();
        out.dyads = d;
        out.twists = twists;
        out.serial = Self::build_serial(&out.name, &out.dyads, &out.twists);
        out
    }

    fn embed(&self) -> DMatrix<f64> {
        // d(42 serial coordinates)/d(30 paper coordinates) at the current poses.
        let mut e = DMatrix::zeros(42, 30);
        let put = |e: &mut DMatrix<f64>, r0: usize, c0: usize| {
            for i in 0..6 {
                e[(r0 + i, c0 + i)] = 1.0;
            }
        };
        put(&mut e, 0, 0);
        put(&mut e, 6, 6);
        put(&mut e, 36, 24);
        for (k, r0) in [(2usize, 12usize), (3, 24)] {
            let r = se3::rotation_matrix(&self.dyads[k]);
            let c0 = 6 * k;
            // Trans dyad: (R·δv, 0); Rot dyad: (0, δω).
            for i in 0..3 {
                for j in 0..3 {
                    e[(r0 + i, c0 + j)] = r[(i, j)];
                }
                e[(r0 + 6 + 3 + i, c0 + 3 + i)] = 1.0;
            }
        }
        e
    }
}

/// Which 30 error coordinates a chain carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum ErrorModel {
    /// kinecal: the five dyads of the module docs; the parallelogram links `T_{i2,i3}(0)`,
    /// `T_{i3,i4}(0)` carry their own errors (length, phase, mounting of the distal bar).
    LinkDyads,
    /// The links fixed at `Trans(l)` between the coupled revolutes and a full `T(0)` before every
    /// joint instead: `T_B, T_12, [Trans(l_u)], T_23, [Trans(l_d)], T_34, T_4P`. A link-length
    /// error cannot be represented (each parallelogram keeps 3 identifiable coordinates instead of
    /// 4); used only to compare ranks with that formulation's figures.
    FixedLinks,
}

impl BranchedChain {
    /// The 6 × 30 spatial identification Jacobian of `model` at `q` (for
    /// [`ErrorModel::LinkDyads`] the same as [`Mechanism::forward_with_jacobian`]).
    pub fn identification_jacobian(&self, q: &[f64], model: ErrorModel) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        match model {
            ErrorModel::LinkDyads => self.forward_with_jacobian(q),
            ErrorModel::FixedLinks => {
                check_inputs(q, 4)?;
                let (g, j42) = self.serial.forward_with_jacobian(&Self::expand(q))?;
                let mut j = Matrix6xX::zeros(30);
                for (k, d) in [0usize, 1, 3, 5, 6].iter().enumerate() {
                    j.fixed_view_mut::<6, 6>(0, 6 * k).copy_from(&j42.fixed_view::<6, 6>(0, 6 * d));
                }
                Ok((g, j))
            }
        }
    }
}

const COMPONENTS: [&str; 6] = ["vx", "vy", "vz", "wx", "wy", "wz"];

impl Mechanism for BranchedChain {
    fn name(&self) -> &str {
        &self.name
    }

    /// `q1` (slider, mm), `q2`, `q3`, `q4` (rad): all four chain coordinates as data.
    fn input_names(&self) -> Vec<String> {
        ["q1", "q2", "q3", "q4"].iter().map(|s| s.to_string()).collect()
    }

    fn params(&self) -> Vec<Param> {
        let mut out = Vec::with_capacity(30);
        for dyad in &self.dyad_names {
            for (c, comp) in COMPONENTS.iter().enumerate() {
                let unit = if c < 3 { Unit::Length } else { Unit::Angle };
                out.push(Param::new(format!("{}.{comp}", dyad), unit, format!("{} dyad {dyad}", self.name)));
            }
        }
        out
    }

    fn n_params(&self) -> usize {
        30
    }

    fn forward(&self, q: &[f64]) -> Result<Pose, KinError> {
        check_inputs(q, 4)?;
        self.serial.forward(&Self::expand(q))
    }

    /// The 6 × 30 spatial identification Jacobian: the serial chain's row of adjoints (eq. (19))
    /// times the map from the paper's five dyads to its seven.
    fn forward_with_jacobian(&self, q: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        check_inputs(q, 4)?;
        let (g, j42) = self.serial.forward_with_jacobian(&Self::expand(q))?;
        let j42 = DMatrix::from_iterator(6, 42, j42.iter().copied());
        let j = j42 * self.embed();
        Ok((g, Matrix6xX::from_iterator(30, j.iter().copied())))
    }

    /// `T(0) ← T(0)·exp(δt)` on the five dyads (eq. (33)).
    fn retract(&mut self, delta: &DVector<f64>) {
        assert_eq!(delta.len(), 30, "five 6-vectors");
        for k in 0..5 {
            let d = Twist::from_iterator(delta.rows(6 * k, 6).iter().copied());
            self.dyads[k] *= se3::exp(&d);
        }
        self.serial = Self::build_serial(&self.name, &self.dyads, &self.twists);
    }

    /// A chain has four coordinates: only poses of its 4-dimensional image are reachable. Solved
    /// by damped Gauss–Newton; an error when the pose is not reached.
    fn inverse(&self, target: &Pose, seed: Option<&[f64]>) -> Result<Vec<f64>, KinError> {
        let mut q: Vec<f64> = seed.map(|s| s.to_vec()).unwrap_or_else(|| vec![0.0, PI / 4.0, PI / 3.0, 0.0]);
        check_inputs(&q, 4)?;
        let mut res = f64::INFINITY;
        for _ in 0..100 {
            let (g, j) = self.joint_jacobian(&q)?;
            let e = se3::log(&(target * g.inverse()));
            res = e.norm();
            if se3::lin(&e).norm() < 1e-10 && se3::ang(&e).norm() < 1e-12 {
                return Ok(q);
            }
            let h = j.transpose() * j + Matrix4::identity() * 1e-12;
            let dq = h.try_inverse().ok_or_else(|| KinError::Singular {
                what: "branched-chain inverse".into(),
                condition: f64::INFINITY,
            })? * (j.transpose() * e);
            for (qi, d) in q.iter_mut().zip(dq.iter()) {
                *qi += d;
            }
        }
        Err(KinError::Unreachable(format!(
            "chain {}: pose not in the chain's 4-dimensional image (residual {res:.3e})",
            self.name
        )))
    }

    fn box_clone(&self) -> Box<dyn Mechanism> {
        Box::new(self.clone())
    }
}

/// Derivative of `(x, y, z, yaw)` of a pose with respect to a spatial twist `ξ = (v, ω)`: rows
/// position (`v + ω × p`) and yaw.
pub fn platform_rows(t: &Pose, xi: &Vector6<f64>) -> nalgebra::Vector4<f64> {
    let p = t.translation.vector;
    let w = se3::ang(xi);
    let dp = se3::lin(xi) + w.cross(&p);
    let r = se3::rotation_matrix(t);
    let c0 = r.column(0).into_owned();
    let dc0 = w.cross(&c0);
    let den = c0.x * c0.x + c0.y * c0.y;
    let dyaw = (c0.x * dc0.y - c0.y * dc0.x) / den;
    nalgebra::Vector4::new(dp.x, dp.y, dp.z, dyaw)
}

fn wrap(a: f64) -> f64 {
    (a + PI).rem_euclid(2.0 * PI) - PI
}

impl BranchedChain {
    /// Chain coordinates that bring `P` to `target` in `(x, y, z, yaw)` (any tilt of the chain is
    /// left as it is): Newton on the 4 × 4 system from `seed`.
    pub fn inverse_platform(&self, target: &PlatformPose, seed: &[f64]) -> Result<[f64; 4], KinError> {
        check_inputs(seed, 4)?;
        let mut q = [seed[0], seed[1], seed[2], seed[3]];
        let mut res = f64::INFINITY;
        for _ in 0..50 {
            let (g, j) = self.joint_jacobian(&q)?;
            let cur = PlatformPose::from_pose(&g);
            let e = nalgebra::Vector4::new(target.x - cur.x, target.y - cur.y, target.z - cur.z, wrap(target.yaw - cur.yaw));
            res = e.fixed_rows::<3>(0).norm() + 1e3 * e[3].abs();
            if e.fixed_rows::<3>(0).norm() < 1e-11 && e[3].abs() < 1e-13 {
                return Ok(q);
            }
            let mut m = Matrix4::zeros();
            for c in 0..4 {
                m.set_column(c, &platform_rows(&g, &j.column(c).into_owned()));
            }
            let dq = m.lu().solve(&e).ok_or_else(|| KinError::Singular {
                what: format!("chain {} platform inverse", self.name),
                condition: f64::INFINITY,
            })?;
            for (qi, d) in q.iter_mut().zip(dq.iter()) {
                *qi += d;
            }
        }
        Err(KinError::NoConvergence {
            what: format!("chain {} platform inverse", self.name),
            iterations: 50,
            residual: res,
        })
    }
}

/// A full configuration of the machine.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Configuration {
    /// Slider coordinates `B1..B4` (mm from the slider zero).
    pub sliders: [f64; 4],
    /// Upper-parallelogram angles of `B1..B4` (rad).
    pub upper: [f64; 4],
    /// Lower-parallelogram angles of sides I and II (`q_13`, `q_23`, rad).
    pub lower: [f64; 2],
    /// Platform revolutes of sides I and II (`q_14`, `q_24`, rad).
    pub platform: [f64; 2],
}

impl Configuration {
    /// The four coordinates of chain `id`.
    pub fn chain_inputs(&self, id: ChainId) -> [f64; 4] {
        let k = id.index();
        let s = id.side();
        [self.sliders[k], self.upper[k], self.lower[s], self.platform[s]]
    }
}

/// A box of platform poses around the home pose.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Workspace {
    /// Centre.
    pub center: PlatformPose,
    /// Half widths in x, y, z (mm) and yaw (rad).
    pub half: PlatformPose,
}

impl Default for Workspace {
    fn default() -> Self {
        let center = PlatformPose {
            x: 500.0,
            y: 600.0,
            z: Geometry::default().home().z,
            yaw: 0.0,
        };
        Workspace {
            center,
            half: PlatformPose {
                x: 80.0,
                y: 200.0,
                z: 80.0,
                yaw: 15f64.to_radians(),
            },
        }
    }
}

impl Workspace {
    /// A uniformly drawn pose of the box.
    pub fn sample<R: rand::Rng>(&self, rng: &mut R) -> PlatformPose {
        use rand::RngExt;
        let mut u = || rng.random_range(-1.0..=1.0);
        PlatformPose {
            x: self.center.x + u() * self.half.x,
            y: self.center.y + u() * self.half.y,
            z: self.center.z + u() * self.half.z,
            yaw: self.center.yaw + u() * self.half.yaw,
        }
    }
}

/// The nominal machine: analytic forward and inverse kinematics on the four sliders.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct T3r1 {
    /// Dimensions.
    pub geometry: Geometry,
}

impl T3r1 {
    /// The nominal chain `id`.
    pub fn chain(&self, id: ChainId) -> BranchedChain {
        BranchedChain::nominal(&self.geometry, id)
    }

    /// Inverse kinematics: the configuration (slider coordinates and every passive angle) that
    /// puts `P` at `target`. Closed form: `A_s` from the pose, the lower angle from `x` of `A_s`,
    /// `D_s` above it, the upper angles from the height of `D_s`.
    pub fn inverse(&self, target: &PlatformPose) -> Result<Configuration, KinError> {
        let g = &self.geometry;
        if ![target.x, target.y, target.z, target.yaw].iter().all(|v| v.is_finite()) {
            return Err(KinError::NonFinite("target pose".into()));
        }
        let (c, s) = (target.yaw.cos(), target.yaw.sin());
        let half = Vector3::new(c, s, 0.0) * (g.a / 2.0);
        let p = Vector3::new(target.x, target.y, target.z);
        let a_pts = [p - half, p + half];
        let mut out = Configuration {
            sliders: [0.0; 4],
            upper: [0.0; 4],
            lower: [0.0; 2],
            platform: [target.yaw; 2],
        };
        for (side, a) in a_pts.iter().enumerate() {
            let x0 = if side == 0 { 0.0 } else { g.b };
            let cb = (a.x - x0) / g.l_d;
            if cb.abs() >= 1.0 {
                return Err(KinError::Unreachable(format!(
                    "side {}: A_s out of reach of the lower parallelogram",
                    side + 1
                )));
            }
            let q3 = cb.acos();
            let zd = a.z + g.l_d * q3.sin();
            let su = zd / g.l_u;
            if su <= 0.0 || su >= 1.0 {
                return Err(KinError::Unreachable(format!(
                    "side {}: D_s out of reach of the upper parallelograms",
                    side + 1
                )));
            }
            let q2 = su.asin();
            let spread = g.l_u * q2.cos();
            out.lower[side] = q3;
            out.upper[2 * side] = q2;
            out.upper[2 * side + 1] = PI - q2;
            out.sliders[2 * side] = a.y - spread - g.slider_zero;
            out.sliders[2 * side + 1] = a.y + spread - g.slider_zero;
        }
        Ok(out)
    }

    /// Forward kinematics: the configuration at slider coordinates `sliders` (`B1..B4`, mm).
    /// Closed form: `D_s` from the two sliders of each side, the yaw from the `y` offset of the two
    /// sub-platforms, `A1` as the lower intersection of two circles of radius `l_d` in `x–z`.
    pub fn forward(&self, sliders: &[f64; 4]) -> Result<Configuration, KinError> {
        let g = &self.geometry;
        check_inputs(sliders, 4)?;
        let mut d = [Vector3::zeros(); 2];
        let mut upper = [0.0; 4];
        for side in 0..2 {
            let (y1, y2) = (sliders[2 * side] + g.slider_zero, sliders[2 * side + 1] + g.slider_zero);
            let h = (y2 - y1) / 2.0;
            if h <= 0.0 || h >= g.l_u {
                return Err(KinError::OutOfWorkspace(format!(
                    "side {}: slider spread {:.3} mm outside (0, {})",
                    side + 1,
                    2.0 * h,
                    2.0 * g.l_u
                )));
            }
            let zd = (g.l_u * g.l_u - h * h).sqrt();
            d[side] = Vector3::new(if side == 0 { 0.0 } else { g.b }, (y1 + y2) / 2.0, zd);
            upper[2 * side] = zd.atan2(h);
            upper[2 * side + 1] = PI - upper[2 * side];
        }
        let sy = (d[1].y - d[0].y) / g.a;
        if sy.abs() >= 1.0 {
            return Err(KinError::OutOfWorkspace("sub-platforms further apart in y than a".into()));
        }
        let yaw = sy.asin();
        // A1 on the circle (centre (0, zD1), radius l_d) and on the circle (b − a·cos φ, zD2).
        let c1 = nalgebra::Vector2::new(0.0, d[0].z);
        let c2 = nalgebra::Vector2::new(g.b - g.a * yaw.cos(), d[1].z);
        let dist = (c2 - c1).norm();
        if dist >= 2.0 * g.l_d || dist == 0.0 {
            return Err(KinError::OutOfWorkspace("lower parallelograms cannot meet the platform".into()));
        }
        let m = (c1 + c2) / 2.0;
        let hh = (g.l_d * g.l_d - dist * dist / 4.0).sqrt();
        let n = nalgebra::Vector2::new(-(c2 - c1).y, (c2 - c1).x) / dist;
        let cand = [m + n * hh, m - n * hh];
        let a1 = if cand[0].y < cand[1].y { cand[0] } else { cand[1] };
        let q13 = (-(a1.y - c1.y)).atan2(a1.x - c1.x);
        let a2 = nalgebra::Vector2::new(a1.x + g.a * yaw.cos(), a1.y);
        let q23 = (-(a2.y - d[1].z)).atan2(a2.x - g.b);
        Ok(Configuration {
            sliders: *sliders,
            upper,
            lower: [q13, q23],
            platform: [yaw, yaw],
        })
    }

    /// Platform pose of a configuration (through chain `B1`).
    pub fn pose(&self, config: &Configuration) -> Result<Pose, KinError> {
        self.chain(ChainId::B1).forward(&config.chain_inputs(ChainId::B1))
    }

    /// The 4 × 4 Jacobian `d(x, y, z, yaw)/d(sliders)` at `sliders` (central differences of the
    /// closed-form forward kinematics, step 1e-4 mm), e.g. for its condition number.
    pub fn actuator_jacobian(&self, sliders: &[f64; 4]) -> Result<Matrix4<f64>, KinError> {
        let h = 1e-4;
        let mut j = Matrix4::zeros();
        for c in 0..4 {
            let (mut a, mut b) = (*sliders, *sliders);
            a[c] += h;
            b[c] -= h;
            let pa = PlatformPose::from_pose(&self.pose(&self.forward(&a)?)?);
            let pb = PlatformPose::from_pose(&self.pose(&self.forward(&b)?)?);
            j.set_column(
                c,
                &(nalgebra::Vector4::new(pa.x - pb.x, pa.y - pb.y, pa.z - pb.z, pa.yaw - pb.yaw) / (2.0 * h)),
            );
        }
        Ok(j)
    }
}

/// The simulated machine's errors (§6, Table 1), in mm and rad.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PresetErrors {
    /// `δt` applied to every dyad of every chain, `T(0) ← T(0)·exp(δt)` (eq. (34)).
    pub dt: Twist,
    /// `δq` of every joint: slider (mm), upper, lower, platform (rad): `q_actual = reading + δq`.
    pub offsets: [f64; 4],
    /// Axis tilt (rad) of the upper-parallelogram pivots (toward `z`, kept perpendicular to the
    /// rail), of the lower pivots (`y` toward `z`, Table 1 row 12-13) and of the platform
    /// revolutes (`z` toward `y`, Table 1 row 13-14).
    pub tilt: f64,
}

impl Default for PresetErrors {
    /// Table 1 in kinecal units: `δt = (2, 2, 2 mm, 0.001, 0.001, 0.001 rad)`, `δq = 0.02`
    /// (20 mm on the sliders, 0.02 rad on the revolutes), tilts of 0.02 rad.
    fn default() -> Self {
        PresetErrors {
            dt: Twist::new(2.0, 2.0, 2.0, 0.001, 0.001, 0.001),
            offsets: [20.0, 0.02, 0.02, 0.02],
            tilt: 0.02,
        }
    }
}

/// The "actual" machine of a simulation: four perturbed chains that assemble.
///
/// Every chain gets the same `δt` on all five dyads and the same tilts and offsets (all nominal
/// frames are parallel to `{B}`, so the two chains of a side share their sub-platform and the two
/// platform revolutes stay parallel: the machine assembles for any such preset). Table 1's tilt
/// of the upper pivots (rows 11-12 and 21-22, toward the rail) cannot be assembled — the two upper
/// parallelograms of one side would move in different planes — so the upper pivots are tilted
/// toward `z` instead and kept perpendicular to the rail (which also cancels the 0.001 rad that
/// `δt` of dyad 11-12 turns them toward the rail).
#[derive(Debug, Clone, PartialEq)]
pub struct ActualMachine {
    /// Nominal machine.
    pub nominal: T3r1,
    /// Literal chains: perturbed poses, tilted twists (joint values `reading + offset`).
    literal: [BranchedChain; 4],
    offsets: [f64; 4],
    /// The same chains rewritten with nominal twists, in reading coordinates.
    reading: [BranchedChain; 4],
}

impl ActualMachine {
    /// The machine with `errors` applied to every chain of `nominal`.
    pub fn new(nominal: &T3r1, errors: &PresetErrors) -> Self {
        let t = errors.tilt;
        let literal = ChainId::ALL.map(|id| {
            let c = nominal.chain(id);
            let dt = [errors.dt; 5];
            // Upper pivot: toward z, perpendicular to the rail seen from the pivot frame.
            let r12 = se3::rotation_matrix(&(c.dyads()[1] * se3::exp(&errors.dt)));
            let rail = r12.transpose() * Vector3::y();
            let u0 = Vector3::new(t.cos(), 0.0, t.sin());
            let u = (u0 - rail * u0.dot(&rail)).normalize();
            let twists = [
                Twist::new(0.0, 1.0, 0.0, 0.0, 0.0, 0.0),
                Twist::new(0.0, 0.0, 0.0, u.x, u.y, u.z),
                Twist::new(0.0, 0.0, 0.0, 0.0, t.cos(), t.sin()),
                Twist::new(0.0, 0.0, 0.0, 0.0, t.sin(), t.cos()),
            ];
            c.with_errors(&dt, twists)
        });
        let reading = ChainId::ALL.map(|id| literal[id.index()].in_reading_coordinates(&errors.offsets));
        ActualMachine {
            nominal: nominal.clone(),
            literal,
            offsets: errors.offsets,
            reading,
        }
    }

    /// Chain `id` as built: perturbed poses and tilted twists, evaluated at `reading + offset`.
    pub fn literal_chain(&self, id: ChainId) -> &BranchedChain {
        &self.literal[id.index()]
    }

    /// Joint offsets `δq` (slider mm, upper, lower, platform rad).
    pub fn offsets(&self) -> &[f64; 4] {
        &self.offsets
    }

    /// Chain `id` in the model family (nominal twists) and in reading coordinates: the chain a
    /// perfect calibration would find.
    pub fn chain(&self, id: ChainId) -> &BranchedChain {
        &self.reading[id.index()]
    }

    fn residual(&self, sliders: &[f64; 4], u: &[f64; 8]) -> Result<(DVector<f64>, Pose), KinError> {
        let cfg = Configuration {
            sliders: *sliders,
            upper: [u[0], u[1], u[2], u[3]],
            lower: [u[4], u[5]],
            platform: [u[6], u[7]],
        };
        let mut r = DVector::zeros(12);
        let pts = ChainId::ALL.map(|id| self.chain(id).points(&cfg.chain_inputs(id)));
        for side in 0..2 {
            let (d1, _) = pts[2 * side].clone()?;
            let (d2, _) = pts[2 * side + 1].clone()?;
            r.rows_mut(3 * side, 3).copy_from(&(d1 - d2));
        }
        let p1 = self.chain(ChainId::B1).forward(&cfg.chain_inputs(ChainId::B1))?;
        let p2 = self.chain(ChainId::B3).forward(&cfg.chain_inputs(ChainId::B3))?;
        r.rows_mut(6, 6).copy_from(&se3::pose_error(&p1, &p2));
        Ok((r, p1))
    }

    /// Forward kinematics of the actual machine at slider readings `sliders`: the configuration
    /// (angles as their sensors read them) and the platform pose. Gauss–Newton on the twelve
    /// closure equations (both sub-platforms, the platform pose from both sides) in the eight
    /// passive angles, started from the nominal forward kinematics.
    pub fn forward(&self, sliders: &[f64; 4]) -> Result<(Configuration, Pose), KinError> {
        let start = self.nominal.forward(sliders)?;
        let mut u = [
            start.upper[0],
            start.upper[1],
            start.upper[2],
            start.upper[3],
            start.lower[0],
            start.lower[1],
            start.platform[0],
            start.platform[1],
        ];
        let mut res = f64::INFINITY;
        for _ in 0..60 {
            let (r, pose) = self.residual(sliders, &u)?;
            let previous = res;
            res = r.norm();
            // Converged, or stalled at round-off of the difference Jacobian below 1e-9 mm (some
            // presets without axis tilts stop near 2e-10).
            if res < 1e-11 || (res < 1e-9 && res > 0.5 * previous) {
                let cfg = Configuration {
                    sliders: *sliders,
                    upper: [u[0], u[1], u[2], u[3]],
                    lower: [u[4], u[5]],
                    platform: [u[6], u[7]],
                };
                return Ok((cfg, pose));
            }
            let mut j = DMatrix::zeros(12, 8);
            let h = 1e-7;
            for c in 0..8 {
                let (mut a, mut b) = (u, u);
                a[c] += h;
                b[c] -= h;
                let col = (self.residual(sliders, &a)?.0 - self.residual(sliders, &b)?.0) / (2.0 * h);
                j.set_column(c, &col);
            }
            let step = (j.transpose() * &j)
                .cholesky()
                .ok_or_else(|| KinError::Singular {
                    what: "actual-machine forward kinematics".into(),
                    condition: f64::INFINITY,
                })?
                .solve(&(j.transpose() * r));
            for (x, d) in u.iter_mut().zip(step.iter()) {
                *x -= d;
            }
        }
        Err(KinError::NoConvergence {
            what: "actual-machine forward kinematics".into(),
            iterations: 60,
            residual: res,
        })
    }
}
