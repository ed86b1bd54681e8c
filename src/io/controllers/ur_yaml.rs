//! Universal Robots kinematics YAML: the file `ur_description` and the UR ROS drivers take as
//! `kinematics_params` (`ur_calibration` writes a robot's factory calibration in it).
//!
//! # Convention (that of `ur_description`'s URDF)
//! ```text
//! kinematics:
//!   shoulder:  {x, y, z (m), roll, pitch, yaw (rad)}
//!   upper_arm: …   forearm: …   wrist_1: …   wrist_2: …   wrist_3: …
//!   hash: <text>
//! ```
//! Each segment is the `<origin>` of one joint in the URDF: the child frame is
//! `Trans(x, y, z)·Rz(yaw)·Ry(pitch)·Rx(roll)` (URDF `rpy`, fixed axes X, Y, Z) in the parent
//! frame, then the joint turns about its z axis. The chain, from `base_link` to `tool0`:
//!
//! ```text
//! base_link ─Rz(π)─ base_link_inertia ─shoulder·Rz(q1)─ shoulder_link ─upper_arm·Rz(q2)─ …
//!   ─wrist_3·Rz(q6)─ wrist_3_link ─rpy(0, −π/2, −π/2)─ flange ─rpy(π/2, 0, π/2)─ tool0
//! ```
//! (the fixed joints are `ur_description`'s; their rotations have no translation).
//!
//! # Export ([`export`])
//! A serial model of six revolute joints. Closed form, exact up to round-off: joint `j`'s axis
//! (any line in its frame) is turned onto z by a frame `C_j` (the identity when the axis is
//! already z through the origin), and segment `j` is `C_{j-1}⁻¹·T_{j-1,j}(0)·C_j` with `C_0 =
//! Rz(π)`. The tool pose `T_{6,T}` is written up to what `wrist_3` can hold of it (a turn about
//! and a shift along the last axis); the rest, the calibrated flange in `tool0`, and the
//! measurement frame (`base_link` in the tracker's frame) have no place in the file: they are
//! reported ([`super::Projection::not_written`]) and belong in the cell's URDF and the TCP.
//! Lengths with 13 decimals (m), angles with 13 decimals (rad). `hash` is `kinecal_` and 16 hex
//! digits of the written numbers (the ROS driver compares it with the robot's own calibration
//! and logs a mismatch: expected, the geometry is kinecal's, not the controller's).
//!
//! # Import ([`import`])
//! The chain above as a serial model (mm, joints `shoulder_pan_joint` … `wrist_3_joint`, limits
//! ±2π, the elbow ±π), base `base_link`, tool `tool0`; the hash goes into the description.
use super::{fixed, number, strip_comment, ControllerError, Export, Projection};
use crate::io::model_file::{MechanismSpec, ModelFile};
use crate::model::chain::{ChainJoint, JointKind, SerialChain};
use crate::model::projection::{compare, spread_configurations};
use crate::model::Mechanism;
use crate::se3::{self, Pose};
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use std::f64::consts::PI;
use std::fmt::Write as _;

/// The segments of the file, in chain order.
pub const SEGMENTS: [&str; 6] = ["shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"];
/// The joint names of `ur_description`, in chain order.
pub const JOINTS: [&str; 6] = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
];
const KEYS: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];
const DECIMALS: usize = 13;

/// A UR kinematics file's numbers: per segment `[x, y, z (m), roll, pitch, yaw (rad)]`.
#[derive(Debug, Clone, PartialEq)]
pub struct UrKinematics {
    /// The six segments of [`SEGMENTS`].
    pub segments: [[f64; 6]; 6],
    /// The file's `hash`.
    pub hash: String,
}

fn urdf_pose(v: &[f64; 6]) -> Pose {
    Pose::from_parts(
        Translation3::new(v[0] * 1000.0, v[1] * 1000.0, v[2] * 1000.0),
        UnitQuaternion::from_euler_angles(v[3], v[4], v[5]),
    )
}

/// `base_link` → `base_link_inertia`.
pub fn base_turn() -> Pose {
    urdf_pose(&[0.0, 0.0, 0.0, 0.0, 0.0, PI])
}

/// `wrist_3_link` → `tool0` (through `flange`).
pub fn tool_turn() -> Pose {
    urdf_pose(&[0.0, 0.0, 0.0, 0.0, -PI / 2.0, -PI / 2.0]) * urdf_pose(&[0.0, 0.0, 0.0, PI / 2.0, 0.0, PI / 2.0])
}

impl UrKinematics {
    /// The serial chain `base_link` → `tool0` of these numbers (mm).
    pub fn chain(&self) -> SerialChain {
        let mut joints = Vec::new();
        let mut initial = Vec::new();
        for (k, seg) in self.segments.iter().enumerate() {
            let mut j = ChainJoint::revolute(JOINTS[k], Vector3::z());
            let lim = if k == 2 { PI } else { 2.0 * PI };
            j.limits = Some((-lim, lim));
            joints.push(j);
            let p = urdf_pose(seg);
            initial.push(if k == 0 { base_turn() * p } else { p });
        }
        SerialChain::new("ur", joints, initial, tool_turn())
    }

    /// The numbers as they are written (rounded to the file's decimals).
    pub fn as_written(&self) -> UrKinematics {
        let mut out = self.clone();
        for s in out.segments.iter_mut() {
            for v in s.iter_mut() {
                *v = fixed(*v, DECIMALS).parse().expect("a formatted number parses");
            }
        }
        out
    }

    /// The file's text.
    pub fn to_text(&self) -> String {
        let mut body = String::new();
        for (name, seg) in SEGMENTS.iter().zip(&self.segments) {
            let _ = writeln!(body, "  {name}:");
            for (key, v) in KEYS.iter().zip(seg) {
                let _ = writeln!(body, "    {key}: {}", fixed(*v, DECIMALS));
            }
        }
        let mut out = String::new();
        out.push_str("# Universal Robots kinematics (ur_description / UR ROS driver `kinematics_params`), written by\n");
        out.push_str("# kinecal (`kinecal model export MODEL --format ur-yaml`; docs/controllers.md).\n");
        out.push_str("# Each segment is one joint's URDF <origin> in its parent link: x y z in metres, then roll pitch yaw\n");
        out.push_str("# in radians (URDF rpy: R = Rz(yaw)·Ry(pitch)·Rx(roll)); the joint turns about the z axis it reaches.\n");
        out.push_str("# Frame: base_link (shoulder is placed in base_link_inertia = base_link turned by pi about z);\n");
        out.push_str("# tool0 follows wrist_3 by ur_description's fixed rotations.\n");
        out.push_str("kinematics:\n");
        out.push_str(&body);
        let _ = writeln!(out, "  hash: {}", self.hash);
        out
    }

    /// Read the file's text.
    pub fn parse(text: &str) -> Result<UrKinematics, ControllerError> {
        let err = |line: usize, message: String| ControllerError::Parse { line, message };
        let mut segments: [[Option<f64>; 6]; 6] = [[None; 6]; 6];
        let mut seen_segment = [0usize; 6];
        let mut hash = None;
        let mut in_kinematics = None;
        let mut current: Option<usize> = None;
        let mut last_line = 0;
        for (i, raw) in text.lines().enumerate() {
            let n = i + 1;
            last_line = n;
            let line = strip_comment(raw);
            if line.trim().is_empty() {
                continue;
            }
            let indent = line.len() - line.trim_start().len();
            let body = line.trim();
            let Some((key, value)) = body.split_once(':') else {
                return Err(err(n, format!("expected 'key: value', got '{body}'")));
            };
            let (key, value) = (key.trim(), value.trim());
            match indent {
                0 => {
                    if key != "kinematics" || !value.is_empty() {
                        return Err(err(n, format!("expected 'kinematics:' at the top level, got '{body}'")));
                    }
                    if in_kinematics.is_some() {
                        return Err(err(n, "'kinematics:' given twice".into()));
                    }
                    in_kinematics = Some(n);
                    current = None;
                }
                _ if in_kinematics.is_none() => {
                    return Err(err(n, "expected 'kinematics:' before the segments".into()));
                }
                1..=3 => {
                    if key == "hash" {
                        if value.is_empty() {
                            return Err(err(n, "'hash:' needs a value".into()));
                        }
                        hash = Some(value.trim_matches('"').trim_matches('\'').to_string());
                        current = None;
                        continue;
                    }
                    let Some(k) = SEGMENTS.iter().position(|s| *s == key) else {
                        return Err(err(
                            n,
                            format!("unknown segment '{key}' (expected one of {} or hash)", SEGMENTS.join(", ")),
                        ));
                    };
                    if !value.is_empty() {
                        return Err(err(n, format!("segment '{key}:' takes its values on the lines below it")));
                    }
                    if seen_segment[k] != 0 {
                        return Err(err(n, format!("segment '{key}' given twice (first on line {})", seen_segment[k])));
                    }
                    seen_segment[k] = n;
                    current = Some(k);
                }
                _ => {
                    let Some(k) = current else {
                        return Err(err(n, format!("'{key}' is not inside a segment")));
                    };
                    let Some(c) = KEYS.iter().position(|s| *s == key) else {
                        return Err(err(
                            n,
                            format!(
                                "unknown key '{key}' in segment '{}' (expected x, y, z, roll, pitch, yaw)",
                                SEGMENTS[k]
                            ),
                        ));
                    };
                    if segments[k][c].is_some() {
                        return Err(err(n, format!("'{key}' given twice in segment '{}'", SEGMENTS[k])));
                    }
                    segments[k][c] = Some(number(value, n, &format!("{}.{key}", SEGMENTS[k]))?);
                }
            }
        }
        let end = last_line.max(1);
        if in_kinematics.is_none() {
            return Err(err(end, "no 'kinematics:' section".into()));
        }
        let mut out = [[0.0; 6]; 6];
        for k in 0..6 {
            if seen_segment[k] == 0 {
                return Err(err(end, format!("segment '{}' missing", SEGMENTS[k])));
            }
            for c in 0..6 {
                out[k][c] =
                    segments[k][c].ok_or_else(|| err(seen_segment[k], format!("segment '{}' has no '{}'", SEGMENTS[k], KEYS[c])))?;
            }
        }
        Ok(UrKinematics {
            segments: out,
            hash: hash.ok_or_else(|| err(end, "no 'hash:' (ur_description requires one)".into()))?,
        })
    }
}

/// 16 hex digits (FNV-1a, 64 bits) of `text`.
fn fnv(text: &str) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// A frame turning z onto the revolute axis of `twist` (unit `(v, ω)`), its origin on the axis.
fn axis_frame(j: &ChainJoint) -> Pose {
    let v = Vector3::new(j.twist[0], j.twist[1], j.twist[2]);
    let w = Vector3::new(j.twist[3], j.twist[4], j.twist[5]);
    let p = w.cross(&v);
    let z = Vector3::z();
    let r = if w == z {
        UnitQuaternion::identity()
    } else {
        UnitQuaternion::rotation_between(&z, &w).unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), PI))
    };
    Pose::from_parts(Translation3::from(p), r)
}

/// The UR numbers of a six-revolute chain and the pose `X` left over: `tool0·X` is the chain's
/// tool (see the module docs).
pub fn from_chain(chain: &SerialChain) -> Result<(UrKinematics, Pose), ControllerError> {
    if chain.n_joints() != 6 || chain.joints().iter().any(|j| j.kind != JointKind::Revolute) {
        return Err(ControllerError::Unsupported(format!(
            "a UR kinematics file describes six revolute joints; this chain has {} joints ({} revolute)",
            chain.n_joints(),
            chain.joint_counts().0
        )));
    }
    let c: Vec<Pose> = chain.joints().iter().map(axis_frame).collect();
    let t = chain.initial_poses();
    let mut segments = [[0.0; 6]; 6];
    for k in 0..6 {
        let prev = if k == 0 { base_turn() } else { c[k - 1] };
        let mut seg = prev.inverse() * t[k] * c[k];
        if k == 5 {
            // What wrist_3 can hold of the tool: a turn about and a shift along its z axis.
            let w = c[5].inverse() * chain.tool() * tool_turn().inverse();
            let m = w.rotation.to_rotation_matrix().into_inner();
            let phi = (m[(1, 0)] - m[(0, 1)]).atan2(m[(0, 0)] + m[(1, 1)]);
            let z = Pose::from_parts(
                Translation3::new(0.0, 0.0, w.translation.vector.z),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), phi),
            );
            seg *= z;
        }
        let r = se3::rpy(&seg.rotation);
        let p = seg.translation.vector / 1000.0;
        segments[k] = [p.x, p.y, p.z, r[0], r[1], r[2]];
    }
    let mut k = UrKinematics {
        segments,
        hash: String::new(),
    }
    .as_written();
    let numbers: String = k
        .segments
        .iter()
        .flatten()
        .map(|v| fixed(*v, DECIMALS))
        .collect::<Vec<_>>()
        .join(" ");
    k.hash = format!("kinecal_{}", fnv(&numbers));
    // The leftover: the written chain's tool0 → the model's tool.
    let written = k.chain();
    let g_model = chain.forward(&[0.0; 6])?;
    let g_written = written.forward(&[0.0; 6])?;
    Ok((k, g_written.inverse() * g_model))
}

fn describe(p: &Pose) -> String {
    let t = p.translation.vector;
    let w = se3::so3_log(&p.rotation);
    format!(
        "translation ({}, {}, {}) mm, rotation vector ({}, {}, {}) rad",
        fixed(t.x, 6),
        fixed(t.y, 6),
        fixed(t.z, 6),
        fixed(w.x, 9),
        fixed(w.y, 9),
        fixed(w.z, 9)
    )
}

/// The UR kinematics file of a serial model (see the module docs) and what it leaves.
pub fn export(file: &ModelFile) -> Result<Export, ControllerError> {
    let chain = match &file.mechanism {
        MechanismSpec::Serial(c) => c,
        MechanismSpec::SerialTerms(_) => {
            return Err(ControllerError::Unsupported(
                "a serial chain with joint terms: the UR kinematics file holds joint frames only (remove [mechanism.joint_terms] to write the geometry; the terms are then lost)".into(),
            ))
        }
        m => {
            return Err(ControllerError::Unsupported(format!(
                "a {} mechanism cannot be written as a UR kinematics file (six revolute joints)",
                m.kind()
            )))
        }
    };
    let (k, leftover) = from_chain(chain)?;
    let text = k.to_text();
    // The controller's kinematics as read back from the text, with the frames it leaves.
    let read = UrKinematics::parse(&text)?.chain();
    let (measurement, tool) = match &file.frames {
        Some(f) => (f.measurement, leftover * f.tool),
        None => (Pose::identity(), leftover),
    };
    let controller = crate::model::framed::Framed::new(Box::new(read) as Box<dyn Mechanism>, measurement, tool);
    let model = file.build();
    let configurations = spread_configurations(&*model, &file.inputs(), super::PROJECTION_POSES, super::PROJECTION_SEED)?;
    let difference = compare(&*model, &controller, &configurations, true)?;
    let mut not_written = Vec::new();
    if let Some(f) = &file.frames {
        not_written.push(format!(
            "measurement frame (base_link in the instrument's frame): {} — the robot's place in the cell's URDF",
            describe(&f.measurement)
        ));
    }
    not_written.push(format!(
        "tool (the model's tool frame in tool0{}): {} — the TCP / tool0 → tool in the cell's URDF",
        if file.frames.is_some() { ", measured tool included" } else { "" },
        describe(&tool)
    ));
    Ok(Export {
        text,
        projection: Projection {
            difference,
            not_represented: Vec::new(),
            fit_residual_mm: None,
            not_written,
        },
    })
}

/// A serial model file of a UR kinematics file (see the module docs).
pub fn import(text: &str) -> Result<ModelFile, ControllerError> {
    let k = UrKinematics::parse(text)?;
    let mut file = ModelFile::new("ur", MechanismSpec::Serial(k.chain()));
    file.description = Some(format!("imported from a UR kinematics file (hash {}): base_link to tool0", k.hash));
    Ok(file)
}
