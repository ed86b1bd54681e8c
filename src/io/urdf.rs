//! URDF in and out: serial chains from the robot descriptions ROS, MoveIt and the vendors ship,
//! and calibrated chains back as URDF.
//!
//! # Import ([`import`])
//! The file is parsed with `urdf-rs`. The chain runs from a base link (default: the root) to a
//! tip link (default: the one leaf reached through the most movable joints). Along it:
//!
//! * a `revolute`, `continuous` or `prismatic` joint becomes a chain joint named as in the URDF;
//!   its initial pose `T_{j-1,j}(0)` is the joint's `<origin>` after every `fixed` joint since the
//!   previous movable joint (fixed joints are folded into the next placement), its axis the
//!   joint's `<axis>` (unit length; default x, as in URDF), its limits the `<limit>` (none for
//!   `continuous`, nor when `lower = upper`);
//! * fixed joints after the last movable joint become the tool pose;
//! * metres become millimetres; `rpy` means `R = Rz(yaw)·Ry(pitch)·Rx(roll)` in URDF and in
//!   kinecal alike.
//!
//! The tool pose is then `g(q) = base-link → tip-link`, exactly the URDF's forward kinematics.
//! Refused, each in one line ([`UrdfError`]): xacro files (out of scope: expand them with
//! `xacro` first), mimic joints on the chain, `floating` / `planar` / `spherical` joints on it,
//! joints naming undeclared links, links with two parent joints (closed loops), several roots,
//! several chains from the base when no tip is given, no path from base to tip.
//!
//! # Export ([`export`])
//! Links `base_link`, `link_1` … `link_n`, `flange`; joint `j` keeps its name, its `<origin>` is
//! the (calibrated) initial pose `T_{j-1,j}(0)` and its `<axis>` the joint axis; a fixed joint
//! `flange_joint` carries the tool pose. A model file with `[frames]` (calibrated against a
//! tracker) adds a root link `measurement` (the tracker frame) fixed to `base_link` by the
//! measurement frame, and a link `measured_tool` fixed to `flange` by the tool frame, so the
//! URDF from `measurement` to `measured_tool` is the calibrated model exactly. Lengths in metres,
//! angles in radians, every number with the digits that read back as the same `f64`. URDF keeps
//! only geometry and position limits of kinecal's model: `effort` and `velocity` are written as
//! 0 (copy them from the vendor's URDF), and there are no visuals, collisions or inertias.
use super::model_file::{MechanismSpec, ModelFile};
use crate::model::chain::{ChainJoint, JointKind, SerialChain};
use crate::se3::{self, Pose};
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use thiserror::Error;

/// What is wrong with a URDF, or why a model cannot be written as one. Every message is one
/// line saying what to do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum UrdfError {
    /// A xacro file (a macro language over URDF).
    #[error(
        "this is a xacro file, and xacro is out of scope: expand it first (`xacro robot.urdf.xacro > robot.urdf`) and import the URDF"
    )]
    Xacro,
    /// Not readable as URDF.
    #[error("not a valid URDF: {0}")]
    Parse(String),
    /// A mimic joint on the chain.
    #[error("joint '{joint}' mimics joint '{of}': a mimic joint is not an independent input and kinecal has no coupled joints; choose a --tip before it")]
    Mimic {
        /// The mimic joint.
        joint: String,
        /// The joint it follows.
        of: String,
    },
    /// A joint that is not one degree of freedom.
    #[error("joint '{joint}' is {kind}: a serial chain takes revolute, continuous, prismatic and fixed joints only")]
    UnsupportedJoint {
        /// The joint.
        joint: String,
        /// Its type.
        kind: String,
    },
    /// A joint naming a link the file does not declare.
    #[error("joint '{joint}' names {role} link '{link}', which the file does not declare")]
    MissingLink {
        /// The joint.
        joint: String,
        /// "parent" or "child".
        role: &'static str,
        /// The missing link.
        link: String,
    },
    /// A link with two parent joints: a closed loop.
    #[error("link '{link}' is the child of two joints ('{first}' and '{second}'): a closed loop, which URDF (a tree) cannot describe; cut the loop")]
    Loop {
        /// The link.
        link: String,
        /// One parent joint.
        first: String,
        /// The other.
        second: String,
    },
    /// No root, or several.
    #[error("{0}")]
    Roots(String),
    /// A `--base` or `--tip` link that does not exist.
    #[error("no link '{link}' ({which}); links: {links}")]
    NoSuchLink {
        /// The link asked for.
        link: String,
        /// "base" or "tip".
        which: &'static str,
        /// The links there are.
        links: String,
    },
    /// The tip is not below the base.
    #[error("no path from base link '{base}' to tip link '{tip}': '{tip}' is not below '{base}'")]
    NoPath {
        /// Base link.
        base: String,
        /// Tip link.
        tip: String,
    },
    /// Several chains leave the base and no tip was given.
    #[error("several chains from base link '{base}' (tips: {tips}); choose one with --tip")]
    SeveralChains {
        /// Base link.
        base: String,
        /// The candidate tips.
        tips: String,
    },
    /// No movable joint between base and tip.
    #[error("no movable joint between '{base}' and '{tip}'")]
    NoJoints {
        /// Base link.
        base: String,
        /// Tip link.
        tip: String,
    },
    /// A joint with an unusable value.
    #[error("joint '{joint}': {message}")]
    BadJoint {
        /// The joint.
        joint: String,
        /// What is wrong.
        message: String,
    },
    /// The model is not a serial chain.
    #[error("{0} cannot be written as URDF: only plain serial chains can")]
    NotSerial(String),
    /// The chain has a joint twist URDF cannot state (an axis not through the joint origin).
    #[error("joint '{0}' has an axis that does not pass through its frame's origin: URDF cannot state it")]
    OffsetAxis(String),
}

/// A serial model file from the URDF text `text`: the chain from link `base` (default: the root)
/// to link `tip` (default: the only leaf reached through the most movable joints). Lengths in the
/// file are metres; the model file is in mm and degrees. See the module docs.
pub fn import(text: &str, base: Option<&str>, tip: Option<&str>) -> Result<ModelFile, UrdfError> {
    if text.contains("xmlns:xacro") || text.contains("<xacro:") {
        return Err(UrdfError::Xacro);
    }
    let robot = urdf_rs::read_from_string(text).map_err(|e| {
        let msg = e.to_string();
        UrdfError::Parse(msg.split_whitespace().collect::<Vec<_>>().join(" "))
    })?;
    let links: BTreeSet<&str> = robot.links.iter().map(|l| l.name.as_str()).collect();
    let mut parent_of: BTreeMap<&str, usize> = BTreeMap::new();
    for (k, j) in robot.joints.iter().enumerate() {
        for (role, link) in [("parent", &j.parent.link), ("child", &j.child.link)] {
            if !links.contains(link.as_str()) {
                return Err(UrdfError::MissingLink {
                    joint: j.name.clone(),
                    role,
                    link: link.clone(),
                });
            }
        }
        if let Some(&other) = parent_of.get(j.child.link.as_str()) {
            return Err(UrdfError::Loop {
                link: j.child.link.clone(),
                first: robot.joints[other].name.clone(),
                second: j.name.clone(),
            });
        }
        parent_of.insert(&j.child.link, k);
    }
    let list = |v: &mut dyn Iterator<Item = &str>| v.map(|s| format!("'{s}'")).collect::<Vec<_>>().join(", ");
    let roots: Vec<&str> = links.iter().copied().filter(|l| !parent_of.contains_key(l)).collect();
    let base = match base {
        Some(b) => {
            if !links.contains(b) {
                return Err(UrdfError::NoSuchLink {
                    link: b.into(),
                    which: "base",
                    links: list(&mut links.iter().copied()),
                });
            }
            b
        }
        None => match roots.as_slice() {
            [r] => r,
            [] => {
                return Err(UrdfError::Roots(
                    "no root link: the joints form a loop, which URDF (a tree) cannot describe".into(),
                ))
            }
            _ => {
                return Err(UrdfError::Roots(format!(
                    "several root links ({}): a URDF has one; choose the chain's with --base",
                    list(&mut roots.iter().copied())
                )))
            }
        },
    };
    // The chain's joints from the tip up to the base, following parent joints.
    let path_to = |tip: &str| -> Option<Vec<usize>> {
        let mut path = Vec::new();
        let mut link = tip;
        while link != base {
            let &k = parent_of.get(link)?;
            if path.len() > robot.joints.len() {
                return None;
            }
            path.push(k);
            link = &robot.joints[k].parent.link;
        }
        path.reverse();
        Some(path)
    };
    let movable = |k: &usize| robot.joints[*k].joint_type != urdf_rs::JointType::Fixed;
    let tip = match tip {
        Some(t) => {
            if !links.contains(t) {
                return Err(UrdfError::NoSuchLink {
                    link: t.into(),
                    which: "tip",
                    links: list(&mut links.iter().copied()),
                });
            }
            t
        }
        None => {
            let has_child: BTreeSet<&str> = robot.joints.iter().map(|j| j.parent.link.as_str()).collect();
            let leaves: Vec<(&str, Vec<usize>)> = links
                .iter()
                .copied()
                .filter(|l| !has_child.contains(l))
                .filter_map(|l| path_to(l).map(|p| (l, p.into_iter().filter(movable).collect::<Vec<_>>())))
                .collect();
            let most = leaves.iter().map(|(_, m)| m.len()).max().unwrap_or(0);
            let best: Vec<&(&str, Vec<usize>)> = leaves.iter().filter(|(_, m)| m.len() == most).collect();
            match best.as_slice() {
                [(t, _)] => t,
                [] => base,
                _ => {
                    return Err(UrdfError::SeveralChains {
                        base: base.into(),
                        tips: list(&mut best.iter().map(|(t, _)| *t)),
                    })
                }
            }
        }
    };
    let path = path_to(tip).ok_or_else(|| UrdfError::NoPath {
        base: base.into(),
        tip: tip.into(),
    })?;
    let mut joints: Vec<ChainJoint> = Vec::new();
    let mut initial = Vec::new();
    let mut pending = Pose::identity();
    for &k in &path {
        let j = &robot.joints[k];
        let bad = |message: String| UrdfError::BadJoint {
            joint: j.name.clone(),
            message,
        };
        let xyz = j.origin.xyz.0;
        let rpy = j.origin.rpy.0;
        if xyz.iter().chain(rpy.iter()).any(|v| !v.is_finite()) {
            return Err(bad("non-finite value in <origin>".into()));
        }
        let origin = Pose::from_parts(
            Translation3::new(xyz[0] * 1000.0, xyz[1] * 1000.0, xyz[2] * 1000.0),
            UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
        );
        let kind = match j.joint_type {
            urdf_rs::JointType::Fixed => {
                pending *= origin;
                continue;
            }
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => JointKind::Revolute,
            urdf_rs::JointType::Prismatic => JointKind::Prismatic,
            ref other => {
                return Err(UrdfError::UnsupportedJoint {
                    joint: j.name.clone(),
                    kind: format!("{other:?}").to_lowercase(),
                })
            }
        };
        if let Some(m) = &j.mimic {
            return Err(UrdfError::Mimic {
                joint: j.name.clone(),
                of: m.joint.clone(),
            });
        }
        if joints.iter().any(|c| c.name == j.name) || j.name.is_empty() {
            return Err(bad("joint names on the chain must be non-empty and unique".into()));
        }
        let axis = Vector3::from(j.axis.xyz.0);
        if !axis.iter().all(|v| v.is_finite()) || axis.norm() < 1e-12 {
            return Err(bad(format!("<axis xyz> must be a finite non-zero vector, got {:?}", j.axis.xyz.0)));
        }
        let mut joint = match kind {
            JointKind::Revolute => ChainJoint::revolute(j.name.clone(), axis),
            JointKind::Prismatic => ChainJoint::prismatic(j.name.clone(), axis),
        };
        let (lo, hi) = (j.limit.lower, j.limit.upper);
        let unit = if kind == JointKind::Prismatic { 1000.0 } else { 1.0 };
        if j.joint_type != urdf_rs::JointType::Continuous && lo.is_finite() && hi.is_finite() && lo < hi {
            joint.limits = Some((lo * unit, hi * unit));
        }
        joints.push(joint);
        initial.push(pending * origin);
        pending = Pose::identity();
    }
    if joints.is_empty() {
        return Err(UrdfError::NoJoints {
            base: base.into(),
            tip: tip.into(),
        });
    }
    let name = if robot.name.is_empty() {
        "robot".to_string()
    } else {
        robot.name.clone()
    };
    let chain = SerialChain::new(name.clone(), joints, initial, pending);
    let mut file = ModelFile::new(name.clone(), MechanismSpec::Serial(chain));
    file.description = Some(format!("imported from URDF: robot '{name}', base link '{base}', tip link '{tip}'"));
    Ok(file)
}

/// `v` as URDF text: the shortest decimal that reads back as the same `f64`.
fn num(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else {
        format!("{v:?}")
    }
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn origin(p: &Pose) -> String {
    let t = p.translation.vector / 1000.0;
    let r = se3::rpy(&p.rotation);
    format!(
        "<origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/>",
        num(t.x),
        num(t.y),
        num(t.z),
        num(r[0]),
        num(r[1]),
        num(r[2])
    )
}

fn fixed_joint(out: &mut String, name: &str, parent: &str, child: &str, pose: &Pose) {
    let _ = writeln!(
        out,
        "  <joint name=\"{}\" type=\"fixed\">\n    <parent link=\"{}\"/>\n    <child link=\"{}\"/>\n    {}\n  </joint>",
        xml_escape(name),
        xml_escape(parent),
        xml_escape(child),
        origin(pose)
    );
}

/// The URDF of a serial model file (nominal or calibrated), see the module docs.
pub fn export(file: &ModelFile) -> Result<String, UrdfError> {
    let MechanismSpec::Serial(chain) = &file.mechanism else {
        return Err(UrdfError::NotSerial(match &file.mechanism {
                crate::io::model_file::MechanismSpec::SerialTerms(_) => "a serial chain with joint terms (URDF has no place for them: remove [mechanism.joint_terms] to export the geometry alone; the terms are then lost)".to_string(),
                m => format!("a {} mechanism", m.kind()),
            }));
    };
    let mut out = String::new();
    let _ = writeln!(out, "<?xml version=\"1.0\"?>");
    let _ = writeln!(
        out,
        "<!-- Written by kinecal {} from model '{}'{}. Geometry and position limits only: effort and\n     velocity are placeholders (0), copy them from the vendor's URDF. Lengths in m, angles in rad. -->",
        env!("CARGO_PKG_VERSION"),
        xml_escape(&file.name).replace("--", "- -"),
        match &file.provenance {
            Some(p) => format!(" ({}, {})", p.status, p.date).replace("--", "- -"),
            None => String::new(),
        }
    );
    let _ = writeln!(out, "<robot name=\"{}\">", xml_escape(&file.name));
    let n = chain.n_joints();
    let link = |k: usize| if k == 0 { "base_link".to_string() } else { format!("link_{k}") };
    let mut link_names: Vec<String> = (0..=n).map(link).collect();
    link_names.push("flange".into());
    if file.frames.is_some() {
        link_names.insert(0, "measurement".into());
        link_names.push("measured_tool".into());
    }
    for l in &link_names {
        let _ = writeln!(out, "  <link name=\"{l}\"/>");
    }
    if let Some(f) = &file.frames {
        out.push_str("  <!-- The measurement (tracker) frame of the calibration: base_link in it. -->\n");
        fixed_joint(&mut out, "measurement_joint", "measurement", "base_link", &f.measurement);
    }
    for (k, j) in chain.joints().iter().enumerate() {
        let t = j.twist;
        let (axis, rest) = match j.kind {
            JointKind::Revolute => ([t[3], t[4], t[5]], [t[0], t[1], t[2]]),
            JointKind::Prismatic => ([t[0], t[1], t[2]], [t[3], t[4], t[5]]),
        };
        if rest.iter().any(|v| v.abs() > 1e-12) {
            return Err(UrdfError::OffsetAxis(j.name.clone()));
        }
        let kind = match (j.kind, j.limits) {
            (JointKind::Revolute, None) => "continuous",
            (JointKind::Revolute, Some(_)) => "revolute",
            (JointKind::Prismatic, _) => "prismatic",
        };
        let _ = writeln!(
            out,
            "  <joint name=\"{}\" type=\"{kind}\">\n    <parent link=\"{}\"/>\n    <child link=\"{}\"/>\n    {}\n    <axis xyz=\"{} {} {}\"/>",
            xml_escape(&j.name),
            link(k),
            link(k + 1),
            origin(&chain.initial_poses()[k]),
            num(axis[0]),
            num(axis[1]),
            num(axis[2])
        );
        let unit = if j.kind == JointKind::Prismatic { 1000.0 } else { 1.0 };
        match j.limits {
            Some((lo, hi)) => {
                let _ = writeln!(
                    out,
                    "    <limit lower=\"{}\" upper=\"{}\" effort=\"0\" velocity=\"0\"/>",
                    num(lo / unit),
                    num(hi / unit)
                );
            }
            None if j.kind == JointKind::Prismatic => {
                // URDF requires limits on prismatic joints; kinecal's default range.
                let _ = writeln!(out, "    <limit lower=\"-0.1\" upper=\"0.1\" effort=\"0\" velocity=\"0\"/>");
            }
            None => {}
        }
        out.push_str("  </joint>\n");
    }
    fixed_joint(&mut out, "flange_joint", &link(n), "flange", chain.tool());
    if let Some(f) = &file.frames {
        out.push_str("  <!-- The measured tool (e.g. the reflector frame) in the flange frame. -->\n");
        fixed_joint(&mut out, "measured_tool_joint", "flange", "measured_tool", &f.tool);
    }
    out.push_str("</robot>\n");
    Ok(out)
}
