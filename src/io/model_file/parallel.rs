//! Model-file kinds of the closed-loop presets: `kind = "pm5"` (the 5-DOF PUU-2PR(RPRR)S machine,
//! [`Pm5`]) and `kind = "stewart"` (a 6-UPS platform, [`Stewart`]).
//!
//! Every value the constraint model uses is in the file, so a calibrated model (geometry with the
//! identified additive errors applied) is written and read back without loss:
//!
//! * `pm5`: per limb the platform joint `c`, the rail origin `b`, the rail angle `phi`, the
//!   actuator offset `g_offset` and the stroke; the PUU rod length `l` (limb 1); the sub-closed
//!   loop `sub_loop = [l2, l3, l4, l5]` (`[l6, l7, l8, l9]`), its actuator offset `sub_offset` and
//!   stroke `sub_stroke` (limbs 2 and 3); the tool offset, the base frame, the home pose, the
//!   workspace box (x, y, z, α, β — γ is parasitic) and the parasitic-constraint mode
//!   (`"physical"`, default, or `"paper"` with its `[mechanism.parasitic_reference]`).
//! * `stewart`: per leg the base joint `base` (U_i), the platform joint `platform` (S_i), the
//!   leg length at zero input `length` (L0_i; default: the length at the home pose) and the
//!   stroke; the home pose and the workspace box (x, y, z, α, β, γ).
//!
//! Poses of these kinds use the platform coordinates of [`crate::model::closed`]:
//! `position` and `euler_xyz = [α, β, γ]` with `R = Rot(x,α)·Rot(y,β)·Rot(z,γ)`.
use super::{fmt3, num, num_per, Ctx, IoError, MechanismSpec, Units};
use crate::model::closed::{ClosedLoop, Workspace};
use crate::model::presets::pm5::{Parasitic, Pm5};
use crate::model::presets::stewart::Stewart;
use crate::model::Mechanism;
use serde::Deserialize;
use std::fmt::Write as _;
use std::ops::Range;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPm5 {
    #[allow(dead_code)]
    kind: String,
    parasitic: Option<Spanned<String>>,
    limb1: Spanned<RawPuu>,
    limb2: Spanned<RawDoubleDriven>,
    limb3: Spanned<RawDoubleDriven>,
    tool: Spanned<RawPosition>,
    base: Spanned<RawFrame>,
    home: Spanned<RawFrame>,
    workspace: Spanned<RawWorkspace>,
    parasitic_reference: Option<Spanned<RawReference>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPuu {
    c: [f64; 3],
    b: [f64; 3],
    phi: f64,
    l: f64,
    g_offset: Option<f64>,
    stroke: [f64; 2],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDoubleDriven {
    c: [f64; 3],
    b: [f64; 3],
    phi: f64,
    g_offset: Option<f64>,
    stroke: [f64; 2],
    sub_loop: [f64; 4],
    sub_offset: Option<f64>,
    sub_stroke: [f64; 2],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPosition {
    position: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFrame {
    position: [f64; 3],
    euler_xyz: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWorkspace {
    x: [f64; 2],
    y: [f64; 2],
    z: [f64; 2],
    alpha: [f64; 2],
    beta: [f64; 2],
    gamma: Option<[f64; 2]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawReference {
    c: [f64; 3],
    b: [f64; 3],
    phi: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawStewart {
    #[allow(dead_code)]
    kind: String,
    home: Spanned<RawFrame>,
    workspace: Spanned<RawWorkspace>,
    legs: Vec<Spanned<RawLeg>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLeg {
    base: [f64; 3],
    platform: [f64; 3],
    length: Option<f64>,
    stroke: [f64; 2],
}

/// Conversion and checks of one table's values, with the table's span for messages.
struct Values<'c, 'a> {
    ctx: &'c Ctx<'a>,
    span: Range<usize>,
    what: String,
    l: f64,
    a: f64,
}

impl Values<'_, '_> {
    fn bad(&self, key: &str, message: impl std::fmt::Display) -> IoError {
        self.ctx.at(&self.span, format!("{}.{key}: {message}", self.what))
    }
    fn finite(&self, key: &str, v: &[f64]) -> Result<(), IoError> {
        if v.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(self.bad(key, "non-finite value"))
        }
    }
    fn length3(&self, key: &str, v: [f64; 3]) -> Result<[f64; 3], IoError> {
        self.finite(key, &v)?;
        Ok(v.map(|x| x * self.l))
    }
    fn angle(&self, key: &str, v: f64) -> Result<f64, IoError> {
        self.finite(key, &[v])?;
        Ok(v * self.a)
    }
    fn positive_length(&self, key: &str, v: f64) -> Result<f64, IoError> {
        if !(v.is_finite() && v > 0.0) {
            return Err(self.bad(key, format!("must be a finite length > 0, got {v}")));
        }
        Ok(v * self.l)
    }
    fn offset(&self, key: &str, v: Option<f64>) -> Result<f64, IoError> {
        let v = v.unwrap_or(0.0);
        self.finite(key, &[v])?;
        Ok(v * self.l)
    }
    fn range(&self, key: &str, v: [f64; 2], factor: f64, allow_equal: bool) -> Result<(f64, f64), IoError> {
        let ok = v[0].is_finite() && v[1].is_finite() && (v[0] < v[1] || (allow_equal && v[0] == v[1]));
        if !ok {
            return Err(self.bad(
                key,
                format!("need two finite values [min, max] with min < max, got [{}, {}]", v[0], v[1]),
            ));
        }
        Ok((v[0] * factor, v[1] * factor))
    }
    fn frame(&self, f: &RawFrame) -> Result<[f64; 6], IoError> {
        let p = self.length3("position", f.position)?;
        self.finite("euler_xyz", &f.euler_xyz)?;
        let e = f.euler_xyz.map(|x| x * self.a);
        Ok([p[0], p[1], p[2], e[0], e[1], e[2]])
    }
    fn workspace(&self, w: &RawWorkspace, gamma: bool) -> Result<Workspace, IoError> {
        let mut out = Workspace {
            min: [0.0; 6],
            max: [0.0; 6],
        };
        let mut axes = vec![
            ("x", w.x, self.l),
            ("y", w.y, self.l),
            ("z", w.z, self.l),
            ("alpha", w.alpha, self.a),
            ("beta", w.beta, self.a),
        ];
        match (gamma, w.gamma) {
            (true, Some(g)) => axes.push(("gamma", g, self.a)),
            (true, None) => return Err(self.bad("gamma", "missing (the platform's rotation about z, [min, max])")),
            (false, Some(_)) => return Err(self.bad("gamma", "not allowed: γ is the 5-DOF machine's parasitic rotation, not commanded")),
            (false, None) => {}
        }
        for (i, (key, v, f)) in axes.into_iter().enumerate() {
            let (lo, hi) = self.range(key, v, f, true)?;
            out.min[i] = lo;
            out.max[i] = hi;
        }
        Ok(out)
    }
}

impl<'a> Ctx<'a> {
    fn values(&self, span: Range<usize>, what: &str, units: &Units) -> Values<'_, 'a> {
        Values {
            ctx: self,
            span,
            what: what.to_string(),
            l: units.length.to_mm(),
            a: units.angle.to_rad(),
        }
    }

    /// The home pose must assemble: inverse kinematics at it, then forward kinematics back.
    fn check_home<C: crate::model::closed::ConstraintSystem>(
        &self,
        span: &Range<usize>,
        m: &ClosedLoop<C>,
        home: &[f64; 6],
    ) -> Result<(), IoError> {
        let target = m.tool_pose_of(home);
        let back = m.inverse(&target, None).and_then(|q| m.forward(&q));
        match back {
            Ok(_) => Ok(()),
            Err(e) => Err(self.at(
                span,
                format!("mechanism.home: the mechanism does not assemble at its home pose: {e}"),
            )),
        }
    }

    pub(super) fn pm5(&self, raw: &RawPm5, units: &Units) -> Result<MechanismSpec, IoError> {
        let parasitic = match &raw.parasitic {
            None => Parasitic::Physical,
            Some(p) => match p.get_ref().as_str() {
                "physical" => Parasitic::Physical,
                "paper" => Parasitic::NominalGeometry,
                other => {
                    return Err(self.at(
                        &p.span(),
                        format!("mechanism.parasitic: unknown mode '{other}' (use \"physical\" or \"paper\")"),
                    ))
                }
            },
        };
        let mut theta = Vec::with_capacity(35);
        let mut strokes = [(0.0, 0.0); 5];
        let v = self.values(raw.limb1.span(), "mechanism.limb1", units);
        let r = raw.limb1.get_ref();
        theta.push(v.offset("g_offset", r.g_offset)?);
        theta.extend(v.length3("c", r.c)?);
        theta.extend(v.length3("b", r.b)?);
        theta.push(v.positive_length("l", r.l)?);
        theta.push(v.angle("phi", r.phi)?);
        strokes[0] = v.range("stroke", r.stroke, v.l, false)?;
        for (k, limb) in [&raw.limb2, &raw.limb3].into_iter().enumerate() {
            let v = self.values(limb.span(), &format!("mechanism.limb{}", k + 2), units);
            let r = limb.get_ref();
            theta.push(v.offset("g_offset", r.g_offset)?);
            theta.extend(v.length3("c", r.c)?);
            theta.extend(v.length3("b", r.b)?);
            theta.push(v.angle("phi", r.phi)?);
            for s in r.sub_loop {
                theta.push(v.positive_length("sub_loop", s)?);
            }
            theta.push(v.offset("sub_offset", r.sub_offset)?);
            strokes[1 + k] = v.range("stroke", r.stroke, v.l, false)?;
            strokes[3 + k] = v.range("sub_stroke", r.sub_stroke, v.l, false)?;
        }
        let tool = self
            .values(raw.tool.span(), "mechanism.tool", units)
            .length3("position", raw.tool.get_ref().position)?;
        let base = self.values(raw.base.span(), "mechanism.base", units).frame(raw.base.get_ref())?;
        let home = self.values(raw.home.span(), "mechanism.home", units).frame(raw.home.get_ref())?;
        let workspace = self
            .values(raw.workspace.span(), "mechanism.workspace", units)
            .workspace(raw.workspace.get_ref(), false)?;
        let mut reference = theta.clone();
        if let Some(rr) = &raw.parasitic_reference {
            if parasitic != Parasitic::NominalGeometry {
                return Err(self.at(
                    &rr.span(),
                    "mechanism.parasitic_reference: only used with parasitic = \"paper\"".into(),
                ));
            }
            let v = self.values(rr.span(), "mechanism.parasitic_reference", units);
            let r = rr.get_ref();
            reference[1..4].copy_from_slice(&v.length3("c", r.c)?);
            reference[4..7].copy_from_slice(&v.length3("b", r.b)?);
            reference[8] = v.angle("phi", r.phi)?;
            if reference[1..4].iter().all(|x| *x == 0.0) {
                return Err(v.bad("c", "must not be zero (the constraint is divided by |c1|)"));
            }
        }
        if theta[1..4].iter().all(|x| *x == 0.0) {
            return Err(self.at(
                &raw.limb1.span(),
                "mechanism.limb1.c: must not be zero (the parasitic constraint is divided by |c1|)".into(),
            ));
        }
        let invalid = |e: crate::error::CalibError| self.at(&raw.limb1.span(), e.to_string());
        let system = Pm5::from_parameters(theta, parasitic)
            .and_then(|s| s.with_reference(reference))
            .map_err(invalid)?
            .with_strokes(strokes)
            .with_workspace(workspace)
            .with_home(home);
        let m = ClosedLoop::new(system, tool, true).with_frames(tool, base);
        self.check_home(&raw.home.span(), &m, &home)?;
        Ok(MechanismSpec::Pm5(m))
    }

    pub(super) fn stewart(&self, raw: &RawStewart, units: &Units) -> Result<MechanismSpec, IoError> {
        if raw.legs.len() != 6 {
            return Err(IoError::Invalid {
                path: self.path.to_path_buf(),
                message: format!("mechanism.legs: a Stewart platform has 6 legs, the file gives {}", raw.legs.len()),
            });
        }
        let home = self.values(raw.home.span(), "mechanism.home", units).frame(raw.home.get_ref())?;
        let workspace = self
            .values(raw.workspace.span(), "mechanism.workspace", units)
            .workspace(raw.workspace.get_ref(), true)?;
        let r = crate::model::closed::rotation_xyz(home[3], home[4], home[5]);
        let mut theta = Vec::with_capacity(42);
        let mut strokes = [(0.0, 0.0); 6];
        for (i, leg) in raw.legs.iter().enumerate() {
            let v = self.values(leg.span(), &format!("mechanism.legs[{i}]"), units);
            let l = leg.get_ref();
            let s = v.length3("platform", l.platform)?;
            let u = v.length3("base", l.base)?;
            let at_home =
                (nalgebra::Vector3::new(home[0], home[1], home[2]) + r * nalgebra::Vector3::from(s) - nalgebra::Vector3::from(u)).norm();
            let length = match l.length {
                Some(x) => v.positive_length("length", x)?,
                None if at_home > 1e-9 => at_home,
                None => return Err(v.bad("base", "the leg has zero length at the home pose")),
            };
            theta.extend(s);
            theta.extend(u);
            theta.push(length);
            strokes[i] = v.range("stroke", l.stroke, v.l, false)?;
        }
        let system = Stewart::from_parameters(theta, home, strokes, workspace).map_err(|e| IoError::Invalid {
            path: self.path.to_path_buf(),
            message: e.to_string(),
        })?;
        let m = Stewart::mechanism_of(system);
        self.check_home(&raw.home.span(), &m, &home)?;
        Ok(MechanismSpec::Stewart(m))
    }
}

fn write_frame(out: &mut String, table: &str, comment: &str, x: &[f64; 6], units: &Units) {
    let (l, a) = (units.length.to_mm(), units.angle.to_rad());
    let _ = writeln!(out, "\n[mechanism.{table}]  # {comment}");
    let _ = writeln!(out, "position = {}", fmt3([x[0] / l, x[1] / l, x[2] / l]));
    let _ = writeln!(
        out,
        "euler_xyz = {}  # [α, β, γ], R = Rot(x,α)·Rot(y,β)·Rot(z,γ)",
        fmt3([x[3] / a, x[4] / a, x[5] / a])
    );
}

fn write_workspace(out: &mut String, w: &Workspace, gamma: bool, units: &Units) {
    let (l, a) = (units.length.to_mm(), units.angle.to_rad());
    out.push_str("\n[mechanism.workspace]  # platform-pose box [min, max] where simulate and identifiability draw poses\n");
    let n = if gamma { 6 } else { 5 };
    for (i, key) in ["x", "y", "z", "alpha", "beta", "gamma"].iter().take(n).enumerate() {
        let f = if i < 3 { l } else { a };
        let _ = writeln!(out, "{key} = [{}, {}]", num(w.min[i] / f), num(w.max[i] / f));
    }
}

fn stroke(s: (f64, f64), l: f64) -> String {
    format!("[{}, {}]", num(s.0 / l), num(s.1 / l))
}

/// The `[mechanism]` tables of a pm5 model (current values: nominal or calibrated).
pub(super) fn write_pm5(m: &ClosedLoop<Pm5>, units: &Units, out: &mut String) {
    let (l, a) = (units.length.to_mm(), units.angle.to_rad());
    let t = m.geometry();
    let sys = m.system();
    let strokes = crate::model::closed::ConstraintSystem::strokes(sys);
    let v3 = |i: usize| fmt3([t[i] / l, t[i + 1] / l, t[i + 2] / l]);
    out.push_str("[mechanism]\nkind = \"pm5\"\n");
    out.push_str("# 5-DOF PUU-2PR(RPRR)S machine (001_8dc75bc45f73c552.txt). Platform pose X = (x, y, z, α, β, γ),\n");
    out.push_str("# R = Rot(x,α)·Rot(y,β)·Rot(z,γ). Rail i: b + (g_i + g_offset)·(cos phi, sin phi, 0); c: platform joint\n");
    out.push_str("# in the platform frame. Inputs g1 g2 g3 (rail sliders) and g4 g5 (sub-loop actuators), prismatic.\n");
    let mode = match sys.parasitic() {
        Parasitic::Physical => "physical",
        Parasitic::NominalGeometry => "paper",
    };
    let _ = writeln!(
        out,
        "parasitic = \"{mode}\"  # \"physical\": constraint on the real geometry; \"paper\": eq. (16)-(18), on [mechanism.parasitic_reference]"
    );
    out.push_str("\n[mechanism.limb1]  # PUU: |p + R·c − b − (g1 + g_offset)·w| = l\n");
    let _ = writeln!(
        out,
        "c = {}\nb = {}\nphi = {}\nl = {}",
        v3(1),
        v3(4),
        num_per(t[8], a),
        num(t[7] / l)
    );
    let _ = writeln!(out, "g_offset = {}\nstroke = {}", num(t[0] / l), stroke(strokes[0], l));
    for (k, off) in [9usize, 22].into_iter().enumerate() {
        let _ = writeln!(
            out,
            "\n[mechanism.limb{}]  # PR(RPRR)S: rod normal to the rail, rod length from the sub-loop (cosine law, eq. (9))",
            k + 2
        );
        let _ = writeln!(out, "c = {}\nb = {}\nphi = {}", v3(off + 1), v3(off + 4), num_per(t[off + 7], a));
        let _ = writeln!(out, "g_offset = {}\nstroke = {}", num(t[off] / l), stroke(strokes[1 + k], l));
        let s = &t[off + 8..off + 12];
        let names = if k == 0 { "l2, l3, l4, l5" } else { "l6, l7, l8, l9" };
        let _ = writeln!(
            out,
            "sub_loop = [{}, {}, {}, {}]  # [{names}]",
            num(s[0] / l),
            num(s[1] / l),
            num(s[2] / l),
            num(s[3] / l)
        );
        let _ = writeln!(
            out,
            "sub_offset = {}  # offset of g{}\nsub_stroke = {}",
            num(t[off + 12] / l),
            4 + k,
            stroke(strokes[3 + k], l)
        );
    }
    let tool = m.tool();
    let _ = writeln!(
        out,
        "\n[mechanism.tool]  # tool offset in the platform frame\nposition = {}",
        fmt3(tool.map(|x| x / l))
    );
    write_frame(out, "base", "base frame in the world (measurement) frame", &m.base(), units);
    write_frame(
        out,
        "home",
        "platform pose where forward kinematics starts",
        &crate::model::closed::ConstraintSystem::home(sys),
        units,
    );
    write_workspace(out, &crate::model::closed::ConstraintSystem::workspace(sys), false, units);
    if sys.parasitic() == Parasitic::NominalGeometry {
        let r = sys.reference();
        out.push_str("\n[mechanism.parasitic_reference]  # c1, b1, phi1 of the paper's parasitic constraint\n");
        let _ = writeln!(
            out,
            "c = {}\nb = {}\nphi = {}",
            fmt3([r[1] / l, r[2] / l, r[3] / l]),
            fmt3([r[4] / l, r[5] / l, r[6] / l]),
            num_per(r[8], a)
        );
    }
}

/// The `[mechanism]` tables of a Stewart model (current values: nominal or calibrated).
pub(super) fn write_stewart(m: &ClosedLoop<Stewart>, units: &Units, out: &mut String) {
    let l = units.length.to_mm();
    let t = m.geometry();
    let sys = m.system();
    let strokes = crate::model::closed::ConstraintSystem::strokes(sys);
    out.push_str("[mechanism]\nkind = \"stewart\"\n");
    out.push_str("# 6-UPS platform: |p + R·platform_i − base_i| = length_i + q_i. Platform pose X = (x, y, z, α, β, γ),\n");
    out.push_str("# R = Rot(x,α)·Rot(y,β)·Rot(z,γ); the tool frame is the platform frame. Inputs q1…q6 (prismatic).\n");
    write_frame(
        out,
        "home",
        "platform pose where forward kinematics starts",
        &crate::model::closed::ConstraintSystem::home(sys),
        units,
    );
    write_workspace(out, &crate::model::closed::ConstraintSystem::workspace(sys), true, units);
    for i in 0..6 {
        let c = &t[7 * i..7 * i + 7];
        let _ = writeln!(
            out,
            "\n[[mechanism.legs]]  # leg {}\nbase = {}  # U_{}, base frame\nplatform = {}  # S_{}, platform frame\nlength = {}  # L0_{}: leg length at q{} = 0\nstroke = {}",
            i + 1,
            fmt3([c[3] / l, c[4] / l, c[5] / l]),
            i + 1,
            fmt3([c[0] / l, c[1] / l, c[2] / l]),
            i + 1,
            num(c[6] / l),
            i + 1,
            i + 1,
            stroke(strokes[i], l)
        );
    }
}
