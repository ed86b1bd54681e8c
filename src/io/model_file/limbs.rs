//! Model-file kind `limbs`: a parallel (or hybrid) mechanism written as its limbs
//! ([`crate::model::limbs::LimbMechanism`]).
//!
//! ```toml
//! [mechanism]
//! kind = "limbs"
//! task = "pose"            # what the inputs command: "pose", "position", "position-and-axis", "height-and-axis"
//!                          #   or "position-and-yaw" (3T1R: position and the rotation about the base z)
//!
//! [mechanism.home]         # the platform frame at home, in the base frame
//! position = [0.0, 0.0, 220.0]
//! rpy = [0.0, 0.0, 0.0]
//!
//! [mechanism.workspace]    # where simulate and plan draw platform poses (optional)
//! position_min = [-40.0, -40.0, 190.0]
//! position_max = [40.0, 40.0, 250.0]
//! rpy_min = [-8.0, -8.0, -8.0]   # offsets from the home orientation (default 0)
//! rpy_max = [8.0, 8.0, 8.0]
//!
//! [[mechanism.limbs]]
//! name = "leg1"
//! end = "point"            # "point": a spherical joint on the platform; "frame": the limb's end is the platform frame
//! platform_point = [...]   # point ends: the joint centre in the platform frame (default: where the limb ends at home)
//! start = { limb = "leg2", after = "r2" }    # optional: starts on the body after joint r2 of an earlier
//!                                            #   limb (a branch: the actuator of a sub-closed loop)
//! end_on = { limb = "leg2", after = "k2" }   # optional: closes on that body instead of the platform
//!                                            #   (platform_point and end_placement are then in its frame)
//! [mechanism.limbs.end_placement]   # the limb's end in its last joint frame (a point end: the
//! position = [...]                  # sphere centre, default its origin; a frame end: default the
//!                                   # platform frame as it stands at home)
//!
//! [[mechanism.limbs.joints]]   # as in a serial chain, plus role and home
//! name = "m1"
//! type = "revolute"        # or "prismatic"; a universal joint is two revolute joints, a spherical joint three;
//!                          #   "parallelogram": two pivots about `axis`, the distal bar keeping its orientation,
//!                          #   with bar = { position = [...] } (the distal pivot in the proximal one's frame)
//! role = "actuated"        # "actuated", "sensed" (a passive joint with a sensor whose reading is an input: a data column),
//!                           # "observed" (a passive joint solved by the closure whose sensor reading is compared with the
//!                           # model: a data column weighted by the encoder noise) or "passive"
//! axis = [0.0, 1.0, 0.0]
//! position = [...]         # the joint frame in the previous one (the first: in the base frame)
//! rpy = [...]
//! limits = [-60.0, 60.0]
//! home = 0.0               # the joint value at home (chooses the assembly mode; default 0)
//! exact_placement = true   # optional: the placement is exact by construction (no error parameters),
//!                          #   e.g. a UPS leg's actuator, whose axis runs through the universal joint
//! ```
//!
//! Inputs (data columns) are the actuated joints in limb order, then the sensed ones.
use super::{fmt3, num, quote, write_pose, Ctx, IoError, MechanismSpec, RawPose, Units};
use crate::model::chain::{ChainJoint, JointKind, SerialChain};
use crate::model::limbs::{BodyRef, GroupKind, JointGroup, JointRole, Limb, LimbEnd, LimbMechanism, PoseBox};
use crate::model::{Mechanism as _, Task};
use crate::se3::Pose;
use nalgebra::Vector3;
use serde::Deserialize;
use std::fmt::Write as _;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawLimbs {
    #[allow(dead_code)]
    kind: String,
    task: Option<Spanned<String>>,
    home: Option<Spanned<RawPose>>,
    workspace: Option<Spanned<RawBox>>,
    limbs: Option<Vec<Spanned<RawLimb>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBox {
    position_min: [f64; 3],
    position_max: [f64; 3],
    rpy_min: Option<[f64; 3]>,
    rpy_max: Option<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLimb {
    name: String,
    start: Option<Spanned<RawBody>>,
    end: Spanned<String>,
    end_on: Option<Spanned<RawBody>>,
    platform_point: Option<[f64; 3]>,
    end_placement: Option<Spanned<RawPose>>,
    joints: Option<Vec<Spanned<RawLimbJoint>>>,
}

/// A body of another limb: the one after its joint `after`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBody {
    limb: String,
    after: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLimbJoint {
    name: String,
    #[serde(rename = "type")]
    kind: Spanned<String>,
    role: Spanned<String>,
    axis: Option<[f64; 3]>,
    axes: Option<Vec<[f64; 3]>>,
    limits: Option<[f64; 2]>,
    position: Option<[f64; 3]>,
    rpy: Option<[f64; 3]>,
    rotvec: Option<[f64; 3]>,
    home: Option<HomeValue>,
    exact_placement: Option<bool>,
    bar: Option<Spanned<RawPose>>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum HomeValue {
    One(f64),
    Many(Vec<f64>),
}

fn task_of(s: &str) -> Option<Task> {
    match s {
        "pose" => Some(Task::Full),
        "position" => Some(Task::Position),
        "position-and-axis" => Some(Task::PositionAndAxis),
        "height-and-axis" => Some(Task::HeightAndAxis),
        "position-and-yaw" => Some(Task::PositionAndYaw),
        _ => None,
    }
}

fn task_name(t: Task) -> &'static str {
    match t {
        Task::Full => "pose",
        Task::Position => "position",
        Task::PositionAndAxis => "position-and-axis",
        Task::HeightAndAxis => "height-and-axis",
        Task::PositionAndYaw => "position-and-yaw",
    }
}

impl Ctx<'_> {
    /// `kind = "limbs"`.
    pub(super) fn limbs(&self, name: &str, raw: &RawLimbs, units: &Units) -> Result<MechanismSpec, IoError> {
        let whole = || IoError::Invalid {
            path: self.path.to_path_buf(),
            message: "mechanism: a limbs mechanism needs [[mechanism.limbs]] tables, each with [[mechanism.limbs.joints]]".into(),
        };
        let task = match &raw.task {
            None => Task::Full,
            Some(t) => task_of(t.get_ref()).ok_or_else(|| {
                self.at(
                    &t.span(),
                    format!(
                        "mechanism.task: unknown task '{}' (use \"pose\", \"position\", \"position-and-axis\", \"height-and-axis\" or \"position-and-yaw\")",
                        t.get_ref()
                    ),
                )
            })?,
        };
        let home = match &raw.home {
            Some(h) => {
                let r = h.get_ref();
                self.pose(&h.span(), "mechanism.home", r.position, r.rpy, r.rotvec, units)?
            }
            None => Pose::identity(),
        };
        let workspace = match &raw.workspace {
            None => None,
            Some(w) => {
                let r = w.get_ref();
                let (l, a) = (units.length.to_mm(), units.angle.to_rad());
                let all = r
                    .position_min
                    .iter()
                    .chain(&r.position_max)
                    .chain(r.rpy_min.iter().flatten())
                    .chain(r.rpy_max.iter().flatten());
                let rmin = r.rpy_min.unwrap_or([0.0; 3]);
                let rmax = r.rpy_max.unwrap_or([0.0; 3]);
                if all.clone().any(|v| !v.is_finite()) || (0..3).any(|k| r.position_min[k] > r.position_max[k] || rmin[k] > rmax[k]) {
                    return Err(self.at(&w.span(), "mechanism.workspace: need finite bounds with min ≤ max".into()));
                }
                Some(PoseBox {
                    position_min: Vector3::from(r.position_min) * l,
                    position_max: Vector3::from(r.position_max) * l,
                    rpy_min: rmin.map(|v| v * a),
                    rpy_max: rmax.map(|v| v * a),
                })
            }
        };
        let raw_limbs = raw.limbs.as_deref().filter(|l| !l.is_empty()).ok_or_else(whole)?;
        let mut limbs = Vec::new();
        let mut derive = Vec::new();
        for (i, sl) in raw_limbs.iter().enumerate() {
            let (limb, d) = self.limb(i, sl, units)?;
            limbs.push(limb);
            derive.push(d);
        }
        for (i, sl) in raw_limbs.iter().enumerate() {
            let rl = sl.get_ref();
            let start = rl
                .start
                .as_ref()
                .map(|b| self.body(b, &limbs, &format!("mechanism.limbs[{i}].start")));
            limbs[i].start = start.transpose()?;
            let end_on = rl
                .end_on
                .as_ref()
                .map(|b| self.body(b, &limbs, &format!("mechanism.limbs[{i}].end_on")));
            limbs[i].end_on = end_on.transpose()?;
        }
        // Ends not given: attached where the limb ends at its home values (platform at home).
        for (i, sl) in raw_limbs.iter().enumerate() {
            if !derive[i] {
                continue;
            }
            let what = format!("mechanism.limbs[{i}] ('{}')", limbs[i].name);
            let frame_of = |b: &Option<BodyRef>, otherwise: Pose| match b {
                None => Ok(otherwise),
                Some(b) => limbs[b.limb].chain.frames(&limbs[b.limb].home).map(|f| f[b.joint]),
            };
            let start = frame_of(&limbs[i].start, Pose::identity());
            let target = frame_of(&limbs[i].end_on, home);
            let attached = start
                .and_then(|s| target.map(|t| (s, t)))
                .and_then(|(s, t)| limbs[i].attach_at(&s, &t));
            attached.map_err(|e| self.at(&sl.span(), format!("{what}: {e}")))?;
        }
        LimbMechanism::new(name, limbs, task, home, workspace)
            .map(MechanismSpec::Limbs)
            .map_err(|message| {
                // An error about one limb points at that limb's table.
                let named = raw_limbs.iter().find(|l| message.contains(&format!("limb '{}'", l.get_ref().name)));
                match named {
                    Some(l) => self.at(&l.span(), format!("mechanism: {message}")),
                    None => IoError::Invalid {
                        path: self.path.to_path_buf(),
                        message: format!("mechanism: {message}"),
                    },
                }
            })
    }

    /// A body named in a limb table: `{ limb = "...", after = "<joint>" }`.
    fn body(&self, b: &Spanned<RawBody>, limbs: &[Limb], what: &str) -> Result<BodyRef, IoError> {
        let r = b.get_ref();
        let limb = limbs.iter().position(|l| l.name == r.limb).ok_or_else(|| {
            let names: Vec<&str> = limbs.iter().map(|l| l.name.as_str()).collect();
            self.at(
                &b.span(),
                format!("{what}: no limb named '{}' (limbs: {})", r.limb, names.join(", ")),
            )
        })?;
        let mut end = 0;
        for g in &limbs[limb].groups {
            end += g.count;
            if g.name == r.after {
                return Ok(BodyRef { limb, joint: end - 1 });
            }
        }
        let names: Vec<&str> = limbs[limb].groups.iter().map(|g| g.name.as_str()).collect();
        Err(self.at(
            &b.span(),
            format!(
                "{what}: limb '{}' has no joint '{}' (its joints: {})",
                r.limb,
                r.after,
                names.join(", ")
            ),
        ))
    }

    /// One limb, and whether its end is to be attached where it stands at home (no end placement
    /// or point given).
    fn limb(&self, i: usize, sl: &Spanned<RawLimb>, units: &Units) -> Result<(Limb, bool), IoError> {
        let rl = sl.get_ref();
        let what = format!("mechanism.limbs[{i}] ('{}')", rl.name);
        if rl.name.is_empty() || rl.name.contains(['.', ' ']) {
            return Err(self.at(
                &sl.span(),
                format!("{what}: a limb needs a name without dots or spaces (it prefixes parameter names)"),
            ));
        }
        let raw_joints = rl.joints.as_deref().filter(|j| !j.is_empty()).ok_or_else(|| {
            self.at(
                &sl.span(),
                format!("{what}: a limb needs at least one joint ([[mechanism.limbs.joints]] after its [[mechanism.limbs]])"),
            )
        })?;
        let (mut joints, mut initial, mut roles, mut homes, mut groups) = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut names = std::collections::HashSet::new();
        for (j, sj) in raw_joints.iter().enumerate() {
            let span = sj.span();
            let rj = sj.get_ref();
            let jw = format!("{what}.joints[{j}] ('{}')", rj.name);
            if rj.name.is_empty() || !names.insert(rj.name.clone()) {
                return Err(self.at(&span, format!("{jw}: joint names must be non-empty and unique")));
            }
            let (group, count, default_axes): (GroupKind, usize, &[[f64; 3]]) = match rj.kind.get_ref().as_str() {
                "revolute" => (GroupKind::Revolute, 1, &[]),
                "prismatic" => (GroupKind::Prismatic, 1, &[]),
                "universal" => (GroupKind::Universal, 2, &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
                "spherical" => (GroupKind::Spherical, 3, &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
                "parallelogram" => (GroupKind::Parallelogram, 2, &[]),
                other => {
                    return Err(self.at(
                        &rj.kind.span(),
                        format!(
                            "{jw}.type: unknown joint type '{other}' (use \"revolute\", \"prismatic\", \"universal\", \"spherical\" or \"parallelogram\")"
                        ),
                    ))
                }
            };
            let parallelogram = group == GroupKind::Parallelogram;
            if parallelogram != rj.bar.is_some() {
                return Err(self.at(
                    &span,
                    format!("{jw}: a parallelogram needs 'bar' (the distal pivot in the proximal one's frame, e.g. bar = {{ position = [0.0, 700.0, 0.0] }}), and only a parallelogram has one"),
                ));
            }
            let axes: Vec<[f64; 3]> = match (count, &rj.axis, &rj.axes) {
                (1, Some(a), None) => vec![*a],
                (2, Some(a), None) if parallelogram => vec![*a, *a],
                (2, _, _) if parallelogram => {
                    return Err(self.at(
                        &span,
                        format!("{jw}: a parallelogram needs 'axis' (its pivots' direction; no 'axes')"),
                    ))
                }
                (1, _, _) => return Err(self.at(&span, format!("{jw}: a {} joint needs 'axis' (and no 'axes')", rj.kind.get_ref()))),
                (_, None, None) => default_axes.to_vec(),
                (n, None, Some(v)) if v.len() == n => v.clone(),
                (n, _, _) => {
                    return Err(self.at(
                        &span,
                        format!(
                            "{jw}: a {} joint takes 'axes' with {n} axes (default: the local x, y{} axes), not 'axis'",
                            rj.kind.get_ref(),
                            if n == 3 { ", z" } else { "" }
                        ),
                    ))
                }
            };
            let kind = if group == GroupKind::Prismatic {
                JointKind::Prismatic
            } else {
                JointKind::Revolute
            };
            let f = match kind {
                JointKind::Revolute => units.angle.to_rad(),
                JointKind::Prismatic => units.length.to_mm(),
            };
            let home: Vec<f64> = match &rj.home {
                None => vec![0.0; count],
                Some(HomeValue::One(v)) if count == 1 => vec![*v],
                Some(HomeValue::One(v)) if parallelogram => vec![*v, -*v],
                Some(HomeValue::Many(_)) if parallelogram => {
                    return Err(self.at(&span, format!("{jw}.home: give one value (the parallelogram's angle)")))
                }
                Some(HomeValue::Many(v)) if v.len() == count => v.clone(),
                Some(_) => return Err(self.at(&span, format!("{jw}.home: give {count} value(s), one per axis"))),
            };
            if home.iter().any(|v| !v.is_finite()) {
                return Err(self.at(&span, format!("{jw}.home: must be finite")));
            }
            let role = match rj.role.get_ref().as_str() {
                "actuated" => JointRole::Actuated,
                "sensed" => JointRole::Sensed,
                "passive" => JointRole::Passive,
                "observed" => JointRole::Observed,
                other => {
                    return Err(self.at(
                        &rj.role.span(),
                        format!("{jw}.role: unknown role '{other}' (use \"actuated\", \"sensed\", \"observed\" or \"passive\")"),
                    ))
                }
            };
            let limits = self.limits(&span, &jw, rj.limits, kind, units)?;
            let placement = self.pose(&span, &jw, rj.position, rj.rpy, rj.rotvec, units)?;
            let bar = match &rj.bar {
                Some(b) => {
                    let r = b.get_ref();
                    self.pose(&b.span(), &format!("{jw}.bar"), r.position, r.rpy, r.rotvec, units)?
                }
                None => Pose::identity(),
            };
            for (k, axis) in axes.iter().enumerate() {
                let axis = Vector3::from(*axis);
                if !axis.iter().all(|v| v.is_finite()) || axis.norm() < 1e-9 {
                    return Err(self.at(&span, format!("{jw}: every axis must be a finite non-zero vector")));
                }
                // (A parallelogram's value is its proximal joint's, named as the joint.)
                let name = match (count, parallelogram, k) {
                    (1, _, _) | (_, true, 0) => rj.name.clone(),
                    (_, true, _) => format!("{}_distal", rj.name),
                    _ => format!("{}_{}", rj.name, k + 1),
                };
                let mut joint = match kind {
                    JointKind::Revolute => ChainJoint::revolute(name, axis),
                    JointKind::Prismatic => ChainJoint::prismatic(name, axis),
                };
                joint.limits = if k == 0 { limits } else { None };
                joints.push(joint);
                initial.push(match (k, parallelogram) {
                    (0, _) => placement,
                    (_, true) => bar,
                    _ => Pose::identity(),
                });
                roles.push(role);
                homes.push(home[k] * f);
            }
            groups.push(JointGroup {
                name: rj.name.clone(),
                kind: group,
                count,
                exact: rj.exact_placement.unwrap_or(false),
            });
        }
        let end_placement = match &rl.end_placement {
            Some(e) => {
                let r = e.get_ref();
                Some(self.pose(&e.span(), &format!("{what}.end_placement"), r.position, r.rpy, r.rotvec, units)?)
            }
            None => None,
        };
        let (end, derive) = match rl.end.get_ref().as_str() {
            "frame" => {
                if rl.platform_point.is_some() {
                    return Err(self.at(&sl.span(), format!("{what}.platform_point: only for end = \"point\"")));
                }
                (LimbEnd::Frame, end_placement.is_none())
            }
            "point" => match rl.platform_point {
                Some(p) if p.iter().all(|v| v.is_finite()) => (LimbEnd::Point(Vector3::from(p) * units.length.to_mm()), false),
                Some(_) => return Err(self.at(&sl.span(), format!("{what}.platform_point: must be finite"))),
                None => (LimbEnd::Point(Vector3::zeros()), true),
            },
            other => {
                return Err(self.at(
                    &rl.end.span(),
                    format!("{what}.end: unknown end '{other}' (use \"point\" for a spherical joint on the platform or \"frame\")"),
                ))
            }
        };
        let chain = SerialChain::new(rl.name.clone(), joints, initial, end_placement.unwrap_or_else(Pose::identity));
        let limb = Limb {
            name: rl.name.clone(),
            chain,
            roles,
            end,
            start: None,
            end_on: None,
            home: homes,
            groups,
        };
        Ok((limb, derive))
    }
}

/// The `[mechanism]` part of a `limbs` model file (every value explicit: reads back exactly).
pub(super) fn write_limbs(m: &LimbMechanism, units: &Units, out: &mut String) -> Result<(), String> {
    let (l, a) = (units.length.to_mm(), units.angle.to_rad());
    out.push_str("[mechanism]\nkind = \"limbs\"\n");
    out.push_str("# A parallel mechanism from its limbs (docs/parallel-machines.md): each limb a chain of joints from\n");
    out.push_str("# the base; end = \"point\" (a spherical joint at platform_point, platform frame) or \"frame\".\n");
    let _ = writeln!(out, "task = {}", quote(task_name(m.task())));
    out.push_str("\n[mechanism.home]\n");
    write_pose(m.home(), units, out);
    if let Some(w) = m.workspace() {
        out.push_str("\n[mechanism.workspace]\n");
        let p = |v: &Vector3<f64>| fmt3([v.x / l, v.y / l, v.z / l]);
        let r = |v: &[f64; 3]| fmt3([v[0] / a, v[1] / a, v[2] / a]);
        let _ = writeln!(out, "position_min = {}\nposition_max = {}", p(&w.position_min), p(&w.position_max));
        let _ = writeln!(out, "rpy_min = {}\nrpy_max = {}", r(&w.rpy_min), r(&w.rpy_max));
    }
    let body = |b: &BodyRef| -> Result<String, String> {
        let l = &m.limbs()[b.limb];
        let mut end = 0;
        for g in &l.groups {
            end += g.count;
            if end == b.joint + 1 {
                return Ok(format!("{{ limb = {}, after = {} }}", quote(&l.name), quote(&g.name)));
            }
        }
        Err(format!("limb '{}': no joint ends at chain joint {}", l.name, b.joint))
    };
    for limb in m.limbs() {
        let _ = writeln!(out, "\n[[mechanism.limbs]]\nname = {}", quote(&limb.name));
        if let Some(b) = &limb.start {
            let _ = writeln!(out, "start = {}", body(b)?);
        }
        if let Some(b) = &limb.end_on {
            let _ = writeln!(out, "end_on = {}", body(b)?);
        }
        match &limb.end {
            LimbEnd::Frame => out.push_str("end = \"frame\"\n"),
            LimbEnd::Point(p) => {
                let _ = writeln!(out, "end = \"point\"\nplatform_point = {}", fmt3([p.x / l, p.y / l, p.z / l]));
            }
        }
        out.push_str("\n[mechanism.limbs.end_placement]\n");
        write_pose(limb.chain.tool(), units, out);
        let mut j = 0;
        for g in &limb.groups {
            let joint = &limb.chain.joints()[j];
            let axis_of = |jt: &ChainJoint| {
                let t = jt.twist;
                match jt.kind {
                    JointKind::Revolute => [t[3], t[4], t[5]],
                    JointKind::Prismatic => [t[0], t[1], t[2]],
                }
            };
            let f = if joint.kind == JointKind::Revolute { a } else { l };
            let role = match limb.roles[j] {
                JointRole::Actuated => "actuated",
                JointRole::Sensed => "sensed",
                JointRole::Passive => "passive",
                JointRole::Observed => "observed",
            };
            let kind = match g.kind {
                GroupKind::Revolute => "revolute",
                GroupKind::Prismatic => "prismatic",
                GroupKind::Universal => "universal",
                GroupKind::Spherical => "spherical",
                GroupKind::Parallelogram => "parallelogram",
            };
            let _ = write!(
                out,
                "\n[[mechanism.limbs.joints]]\nname = {}\ntype = \"{kind}\"\nrole = \"{role}\"\n",
                quote(&g.name)
            );
            let members = &limb.chain.joints()[j..j + g.count];
            if g.count == 1 || g.kind == GroupKind::Parallelogram {
                let _ = writeln!(out, "axis = {}\nhome = {}", fmt3(axis_of(joint)), num(limb.home[j] / f));
            } else {
                let axes: Vec<String> = members.iter().map(|m| fmt3(axis_of(m))).collect();
                let homes: Vec<String> = (j..j + g.count).map(|k| num(limb.home[k] / f)).collect();
                let _ = writeln!(out, "axes = [{}]\nhome = [{}]", axes.join(", "), homes.join(", "));
            }
            if let Some((lo, hi)) = joint.limits {
                let _ = writeln!(out, "limits = [{}, {}]", num(lo / f), num(hi / f));
            }
            if g.exact {
                out.push_str("exact_placement = true\n");
            }
            write_pose(&limb.chain.initial_poses()[j], units, out);
            if g.kind == GroupKind::Parallelogram {
                out.push_str("\n[mechanism.limbs.joints.bar]\n");
                write_pose(&limb.chain.initial_poses()[j + 1], units, out);
            }
            j += g.count;
        }
    }
    Ok(())
}
