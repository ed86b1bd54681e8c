//! Model files: a mechanism's nominal (or calibrated) geometry in TOML.
//!
//! ```toml
//! name = "irb120"
//! description = "ABB IRB 120, nominal"
//!
//! [units]
//! length = "mm"      # "mm" or "m": every length in this file
//! angle = "deg"      # "deg" or "rad": every angle in this file (rpy, rotvec, limits, noise)
//!
//! [mechanism]
//! kind = "serial"    # the mechanism kind; decides what else [mechanism] holds
//!
//! [[mechanism.joints]]
//! name = "q1"
//! type = "revolute"  # or "prismatic"
//! axis = [0.0, 0.0, 1.0]
//! limits = [-165.0, 165.0]
//! position = [0.0, 0.0, 0.0]
//! rpy = [0.0, 0.0, 0.0]
//!
//! [mechanism.tool]
//! position = [0.0, 0.0, 0.0]
//! rpy = [0.0, 0.0, 0.0]
//!
//! [calibration]
//! free = ["*"]       # parameter names or globs ('*', '?'), in priority order
//! fixed = ["0-1.*"]  # removed from the free set
//!
//! [noise]            # optional: measurement standard deviations (identification weights)
//! position = 0.02    # length unit
//! orientation = 0.02 # angle unit
//! ```
//!
//! # Conventions
//! * A pose is `position` plus *one* rotation: `rpy = [roll, pitch, yaw]` meaning
//!   `R = Rz(yaw)·Ry(pitch)·Rx(roll)` (fixed axes x, then y, then z), or `rotvec = [x, y, z]`
//!   (axis × angle). Neither means no rotation.
//! * `kind = "serial"`: a local-POE chain ([`SerialChain`]). Joint `j`'s `position`/`rpy` is its
//!   initial pose `T_{j-1,j}(0)`: the joint frame relative to the previous joint frame at zero
//!   joint values (for the first joint: relative to the world/base frame). `axis` is the joint axis
//!   in that frame, through its origin. `tool` is `T_{n,T}(0)`. Parameter names are
//!   `"<dyad>.<vx|vy|vz|wx|wy|wz>"` with dyads `0-1`, `1-2`, …, `n-T`.
//! * `kind = "serial"` may instead hold a Denavit–Hartenberg table: `[[mechanism.dh]]` rows
//!   (standard DH) or `[[mechanism.mdh]]` rows (modified DH, Craig), each with `name`, `type`,
//!   `a`, `alpha`, `d`, `theta` (the offsets at zero joint value; lengths in the length unit,
//!   angles in the angle unit), optional `limits` and, in standard DH only, Hayati's `beta`;
//!   optional `[mechanism.base]` (frame 0 in the world frame) and `[mechanism.tool]` (the tool
//!   in the last DH frame). The table is built into the same local-POE chain
//!   ([`crate::model::dh`]), so parameters, identifiability and every command are those of the
//!   chain; a calibrated model is written in the joint form (`kinecal model export --format dh`
//!   writes a table again where the geometry allows).
//!
//!   ```toml
//!   [[mechanism.dh]]
//!   name = "q1"
//!   type = "revolute"
//!   a = 0.0
//!   alpha = 90.0
//!   d = 162.5
//!   theta = 0.0
//!   limits = [-360.0, 360.0]
//!   ```
//! * Limits of revolute joints are in the angle unit, of prismatic joints in the length unit.
//! * `kind = "pm5"` (the 5-DOF PUU-2PR(RPRR)S machine) and `kind = "stewart"` (6-UPS): every value
//!   of the constraint model, see "Closed-loop kinds" below and
//!   `kinecal model export pm5`. Their parameter names are the presets' (the paper's `dg1, dc1x, …,
//!   dφ1, …, dγ0` for pm5; `S1x … U1x … L01` for stewart); in `free`/`fixed` the Greek letters may
//!   be spelt `phi`, `alpha`, `beta`, `gamma` ([`param_match`]).
//!
//! # Closed-loop kinds
//! Poses are `position` + `euler_xyz = [α, β, γ]`, `R = Rot(x,α)·Rot(y,β)·Rot(z,γ)` (the
//! platform coordinates of [`crate::model::closed`]). pm5: `[mechanism.limb1]` (`c`, `b`, `phi`,
//! `l`, `g_offset`, `stroke`), `[mechanism.limb2]`/`[mechanism.limb3]` (`c`, `b`, `phi`,
//! `g_offset`, `stroke`, `sub_loop = [l2, l3, l4, l5]`, `sub_offset`, `sub_stroke`),
//! `[mechanism.tool]` (`position`), `[mechanism.base]`, `[mechanism.home]`,
//! `[mechanism.workspace]` (`x, y, z, alpha, beta` as `[min, max]`; γ is parasitic) and
//! `parasitic = "physical" | "paper"` (with `[mechanism.parasitic_reference]` `c, b, phi` for the
//! paper's mode; default limb 1's values). stewart: `[mechanism.home]`, `[mechanism.workspace]`
//! (with `gamma`) and six `[[mechanism.legs]]` (`base`, `platform`, `length`, `stroke`). The
//! calibrated model is written with the current (identified) values, exactly.
//!
//! Every problem (a misspelt key, a wrong unit, a bad value) is one [`IoError`] line naming the
//! file and the line. After loading, all values are in millimetres and radians.
//!
//! # Adding a mechanism kind
//! Add a variant to [`MechanismSpec`], a `Raw…` struct with `#[serde(deny_unknown_fields)]` and a
//! `kind` field, an arm in `load_str`'s dispatch, and the arms of the `MechanismSpec` methods.
//! Nothing else (data files, CLI, report) depends on the kind.
mod parallel;

use super::IoError;
use crate::measure::Noise;
use crate::model::chain::{ChainJoint, JointKind, SerialChain};
use crate::model::dh::{DhConvention, DhError, DhJoint, DhOptions, DhTable};
use crate::model::framed::Framed;
use crate::model::Mechanism;
use crate::params::{Param, Unit};
use crate::se3::Pose;
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// Length unit of a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LengthUnit {
    /// Millimetres.
    Mm,
    /// Metres.
    M,
}

/// Angle unit of a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AngleUnit {
    /// Degrees.
    Deg,
    /// Radians.
    Rad,
}

impl LengthUnit {
    /// Millimetres per file unit.
    pub fn to_mm(self) -> f64 {
        match self {
            LengthUnit::Mm => 1.0,
            LengthUnit::M => 1000.0,
        }
    }
    /// The unit's symbol.
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Mm => "mm",
            LengthUnit::M => "m",
        }
    }
    /// Parse `"mm"` or `"m"`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "mm" => Some(LengthUnit::Mm),
            "m" => Some(LengthUnit::M),
            _ => None,
        }
    }
}

impl AngleUnit {
    /// Radians per file unit.
    pub fn to_rad(self) -> f64 {
        match self {
            AngleUnit::Deg => std::f64::consts::PI / 180.0,
            AngleUnit::Rad => 1.0,
        }
    }
    /// The unit's symbol.
    pub fn symbol(self) -> &'static str {
        match self {
            AngleUnit::Deg => "deg",
            AngleUnit::Rad => "rad",
        }
    }
    /// Parse `"deg"` or `"rad"`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "deg" => Some(AngleUnit::Deg),
            "rad" => Some(AngleUnit::Rad),
            _ => None,
        }
    }
}

/// The units a file is written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Units {
    /// Length unit.
    pub length: LengthUnit,
    /// Angle unit.
    pub angle: AngleUnit,
}

impl Default for Units {
    /// Millimetres and degrees.
    fn default() -> Self {
        Units {
            length: LengthUnit::Mm,
            angle: AngleUnit::Deg,
        }
    }
}

impl Units {
    /// Internal value (mm or rad) per file unit for a quantity of kind `unit`.
    pub fn factor(&self, unit: Unit) -> f64 {
        match unit {
            Unit::Length => self.length.to_mm(),
            Unit::Angle => self.angle.to_rad(),
            Unit::Dimensionless => 1.0,
        }
    }
}

pub use crate::model::kind::{InputSpec, MechanismSpec, KINDS};

/// Write the `[mechanism]` part of a model file for `spec` in `units`.
fn write_mechanism(spec: &MechanismSpec, units: &Units, out: &mut String) -> Result<(), String> {
    let (l, a) = (units.length.to_mm(), units.angle.to_rad());
    match spec {
        MechanismSpec::Serial(c) => {
            out.push_str("[mechanism]\nkind = \"serial\"\n");
            out.push_str("# Joint j: position/rpy = T_{j-1,j}(0), the joint frame in the previous joint frame at zero\n");
            out.push_str("# joint values; axis = joint axis in that frame through its origin.\n");
            for (j, joint) in c.joints().iter().enumerate() {
                let t = joint.twist;
                let (kind, axis, rest) = match joint.kind {
                    JointKind::Revolute => ("revolute", [t[3], t[4], t[5]], [t[0], t[1], t[2]]),
                    JointKind::Prismatic => ("prismatic", [t[0], t[1], t[2]], [t[3], t[4], t[5]]),
                };
                if rest.iter().any(|v| v.abs() > 1e-12) {
                    return Err(format!(
                        "joint '{}': a joint twist with an offset cannot be written; put the offset in the joint's position",
                        joint.name
                    ));
                }
                let _ = write!(
                    out,
                    "\n[[mechanism.joints]]\nname = \"{}\"\ntype = \"{kind}\"\naxis = {}\n",
                    joint.name,
                    fmt3(axis)
                );
                if let Some((lo, hi)) = joint.limits {
                    let f = if joint.kind == JointKind::Revolute { a } else { l };
                    let _ = writeln!(out, "limits = [{}, {}]", num(lo / f), num(hi / f));
                }
                write_pose(&c.initial_poses()[j], units, out);
            }
            out.push_str("\n[mechanism.tool]\n");
            write_pose(c.tool(), units, out);
        }
        MechanismSpec::Pm5(m) => parallel::write_pm5(m, units, out),
        MechanismSpec::Stewart(m) => parallel::write_stewart(m, units, out),
    }
    Ok(())
}

/// A parsed model file (all values in mm and rad).
#[derive(Debug, Clone, PartialEq)]
pub struct ModelFile {
    /// Model name.
    pub name: String,
    /// Free text.
    pub description: Option<String>,
    /// Units used when the file was read, and used again when it is written.
    pub units: Units,
    /// The mechanism's geometry.
    pub mechanism: MechanismSpec,
    /// Free parameter patterns, in priority order (default `["*"]`).
    pub free: Vec<String>,
    /// Fixed parameter patterns.
    pub fixed: Vec<String>,
    /// Largest plausible corrections of the geometric parameters (`[calibration] tolerance_mm`,
    /// `tolerance_deg`).
    pub tolerances: Tolerances,
    /// Measurement noise, if given.
    pub noise: Option<Noise>,
    /// Where a calibrated model came from (written by `kinecal identify`; kept on reading).
    pub provenance: Option<Provenance>,
    /// The measurement frame and the tool frame (`[frames]`), found by frame registration: the
    /// built mechanism is then [`Framed`] (`T = X · M(q) · Y`) and its data live in the
    /// measurement (tracker) frame.
    pub frames: Option<Frames>,
}

/// `[frames]` of a model file: `measurement` is the mechanism's base in the measurement (tracker)
/// frame, `tool` the measured tool frame in the flange/platform frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frames {
    /// `X`.
    pub measurement: Pose,
    /// `Y`.
    pub tool: Pose,
}

/// The largest plausible correction of a geometric parameter. A calibration that moves a
/// parameter further fails its checks: the model describes another machine, or the data are
/// wrong. Defaults: 5 mm and 2°, far above machining and assembly errors, far below a wrong link.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Tolerances {
    /// Lengths (mm).
    pub length_mm: f64,
    /// Angles (degrees).
    pub angle_deg: f64,
}

impl Default for Tolerances {
    fn default() -> Self {
        Tolerances {
            length_mm: 5.0,
            angle_deg: 2.0,
        }
    }
}

/// The record a calibrated model file keeps of how it was made: `[provenance]`.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Provenance {
    /// `"calibrated"`, `"usable with warnings"` or `"failed"` (written only with `--force`).
    pub status: String,
    /// Why, when the status is not `"calibrated"`.
    #[serde(default)]
    pub reasons: Vec<String>,
    /// The command line that wrote the file.
    pub command: String,
    /// kinecal's version.
    pub version: String,
    /// UTC date and time, ISO 8601.
    pub date: String,
    /// The identification data file(s).
    pub data: Vec<String>,
}

/// True when `name` matches the glob `pattern` (`*`: any run of characters, `?`: one character).
pub fn glob_match(pattern: &str, name: &str) -> bool {
    let (p, n): (Vec<char>, Vec<char>) = (pattern.chars().collect(), name.chars().collect());
    let (mut pi, mut ni, mut star, mut mark) = (0, 0, None, 0);
    while ni < n.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == n[ni]) {
            pi += 1;
            ni += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some(pi);
            mark = ni;
            pi += 1;
        } else if let Some(s) = star {
            pi = s + 1;
            mark += 1;
            ni = mark;
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

/// A pattern with ASCII spellings of the Greek letters in parameter names replaced
/// (`phi` → `φ`, `alpha` → `α`, `beta` → `β`, `gamma` → `γ`: `dphi1` means `dφ1`).
pub fn greek_pattern(pattern: &str) -> String {
    pattern
        .replace("alpha", "α")
        .replace("beta", "β")
        .replace("gamma", "γ")
        .replace("phi", "φ")
}

/// True when `name` matches `pattern` as a glob ([`glob_match`]), or with the pattern's ASCII
/// Greek letters spelt out ([`greek_pattern`]).
pub fn param_match(pattern: &str, name: &str) -> bool {
    glob_match(pattern, name) || glob_match(&greek_pattern(pattern), name)
}

/// Indices of the parameters selected by `free` patterns minus those matching `fixed`, in the
/// order of the patterns (priority order), each parameter once; patterns match as [`param_match`]. Returns the first pattern that
/// matches no parameter as an error.
pub fn select_params(params: &[Param], free: &[String], fixed: &[String]) -> Result<Vec<usize>, String> {
    for pat in free.iter().chain(fixed) {
        if !params.iter().any(|p| param_match(pat, &p.name)) {
            return Err(pat.clone());
        }
    }
    let mut out = Vec::new();
    for pat in free {
        for (i, p) in params.iter().enumerate() {
            if param_match(pat, &p.name) && !fixed.iter().any(|f| param_match(f, &p.name)) && !out.contains(&i) {
                out.push(i);
            }
        }
    }
    Ok(out)
}

impl ModelFile {
    /// A model file for `mechanism` with every parameter free, in mm and degrees.
    pub fn new(name: impl Into<String>, mechanism: MechanismSpec) -> Self {
        ModelFile {
            name: name.into(),
            description: None,
            units: Units::default(),
            mechanism,
            free: vec!["*".into()],
            fixed: Vec::new(),
            tolerances: Tolerances::default(),
            noise: None,
            provenance: None,
            frames: None,
        }
    }

    /// The mechanism, ready to compute with: seen through its [`Frames`] when the file has them.
    pub fn build(&self) -> Box<dyn Mechanism> {
        match &self.frames {
            Some(f) => Box::new(Framed::new(self.mechanism.build(), f.measurement, f.tool)),
            None => self.mechanism.build(),
        }
    }

    /// Inputs with units and limits.
    pub fn inputs(&self) -> Vec<InputSpec> {
        self.mechanism.inputs()
    }

    /// Indices of the free parameters in priority order.
    pub fn free_indices(&self) -> Result<Vec<usize>, IoError> {
        select_params(&self.build().params(), &self.free, &self.fixed).map_err(|pat| IoError::Invalid {
            path: PathBuf::from(format!("model '{}'", self.name)),
            message: format!("calibration pattern '{pat}' matches no parameter"),
        })
    }

    /// A copy with the geometry of `model` (a calibrated mechanism of the same kind, or such a
    /// mechanism seen through frames, [`Framed`], whose frames are then kept too).
    pub fn with_geometry_of(&self, model: &dyn Mechanism) -> Result<ModelFile, String> {
        if let Some((measurement, tool)) = model.frames() {
            return Ok(ModelFile {
                mechanism: self.mechanism.with_geometry_of(model)?,
                frames: Some(Frames { measurement, tool }),
                ..self.clone()
            });
        }
        Ok(ModelFile {
            mechanism: self.mechanism.with_geometry_of(model)?,
            ..self.clone()
        })
    }

    /// The file's text, in [`ModelFile::units`].
    pub fn to_toml(&self) -> Result<String, String> {
        self.render(|out| write_mechanism(&self.mechanism, &self.units, out))
    }

    /// The file's text with its serial chain written as a DH table in `convention`
    /// (`[[mechanism.dh]]` or `[[mechanism.mdh]]`, see [`crate::model::dh`]); everything else
    /// (calibration, noise, frames, provenance) as in [`ModelFile::to_toml`]. Loaded back, it
    /// gives the same kinematics. Fails for other kinds and for geometry DH cannot hold
    /// ([`DhError::NearlyParallel`]: the joints are named).
    pub fn to_toml_dh(&self, convention: DhConvention, opts: DhOptions) -> Result<String, DhError> {
        let MechanismSpec::Serial(chain) = &self.mechanism else {
            return Err(DhError::NotSerial(self.mechanism.kind().to_string()));
        };
        let table = DhTable::from_chain(chain, convention, opts)?;
        self.render(|out| {
            write_dh(&table, &self.units, out);
            Ok(())
        })
        .map_err(DhError::Write)
    }

    fn render(&self, write_mechanism: impl FnOnce(&mut String) -> Result<(), String>) -> Result<String, String> {
        let mut out = String::new();
        match self.mechanism {
            MechanismSpec::Serial(_) => {
                out.push_str("# kinecal model file. Poses: position + rpy = [roll, pitch, yaw] with R = Rz(yaw)·Ry(pitch)·Rx(roll)\n");
                out.push_str("# (or rotvec = axis·angle instead of rpy).\n");
            }
            MechanismSpec::Pm5(_) | MechanismSpec::Stewart(_) => {
                out.push_str("# kinecal model file. Poses: position + euler_xyz = [α, β, γ] with R = Rot(x,α)·Rot(y,β)·Rot(z,γ).\n");
                out.push_str("# Calibration parameters: the additive errors of these values (names: `kinecal identifiability`).\n");
            }
        }
        let _ = writeln!(out, "name = {}", quote(&self.name));
        if let Some(d) = &self.description {
            let _ = writeln!(out, "description = {}", quote(d));
        }
        let _ = write!(
            out,
            "\n[units]\nlength = \"{}\"  # \"mm\" or \"m\"\nangle = \"{}\"  # \"deg\" or \"rad\"\n\n",
            self.units.length.symbol(),
            self.units.angle.symbol()
        );
        write_mechanism(&mut out)?;
        out.push_str("\n[calibration]\n# Parameter names or globs ('*', '?'); free in priority order, fixed removed from them.\n");
        let list = |v: &[String]| v.iter().map(|s| quote(s)).collect::<Vec<_>>().join(", ");
        let _ = writeln!(out, "free = [{}]\nfixed = [{}]", list(&self.free), list(&self.fixed));
        let _ = writeln!(
            out,
            "# Largest plausible correction of a geometric parameter: a larger one fails the calibration\n# (a model of another machine, or wrong data). Frame parameters are not limited.\ntolerance_mm = {}\ntolerance_deg = {}",
            num(self.tolerances.length_mm),
            num(self.tolerances.angle_deg)
        );
        if let Some(n) = &self.noise {
            let _ = write!(
                out,
                "\n[noise]  # measurement standard deviations, per axis\nposition = {}  # {}\norientation = {}  # {}\n",
                num(n.position / self.units.length.to_mm()),
                self.units.length.symbol(),
                num(n.orientation / self.units.angle.to_rad()),
                self.units.angle.symbol()
            );
        }
        if let Some(f) = &self.frames {
            out.push_str("\n[frames]  # found by frame registration (kinecal identify): T = measurement · mechanism(q) · tool\n");
            out.push_str("# measurement: the mechanism's base in the measurement (tracker) frame; tool: the measured tool\n");
            out.push_str("# frame in the flange/platform frame. rpy = [roll, pitch, yaw], R = Rz(yaw)·Ry(pitch)·Rx(roll).\n");
            out.push_str("[frames.measurement]\n");
            write_pose(&f.measurement, &self.units, &mut out);
            out.push_str("[frames.tool]\n");
            write_pose(&f.tool, &self.units, &mut out);
        }
        if let Some(p) = &self.provenance {
            let list = |v: &[String]| v.iter().map(|s| quote(s)).collect::<Vec<_>>().join(", ");
            let _ = write!(
                out,
                "\n[provenance]  # how this file was made\nstatus = {}\nreasons = [{}]\ncommand = {}\nversion = {}\ndate = {}\ndata = [{}]\n",
                quote(&p.status),
                list(&p.reasons),
                quote(&p.command),
                quote(&p.version),
                quote(&p.date),
                list(&p.data)
            );
        }
        Ok(out)
    }

    /// Write the file.
    pub fn save(&self, path: &Path) -> Result<(), IoError> {
        let text = self.to_toml().map_err(|message| IoError::Invalid {
            path: path.to_path_buf(),
            message,
        })?;
        super::write_atomic(path, text.as_bytes())
    }

    /// Read and check a model file.
    pub fn load(path: &Path) -> Result<ModelFile, IoError> {
        let text = super::read_text(path)?;
        Self::load_str(path, &text)
    }

    /// [`ModelFile::load`] on text in memory (`path` is only used in messages).
    pub fn load_str(path: &Path, text: &str) -> Result<ModelFile, IoError> {
        let ctx = Ctx { path, text };
        let probe: Probe = toml::from_str(text).map_err(|e| ctx.toml_error(&e))?;
        ctx.check_array_lengths()?;
        let kind = probe.mechanism.and_then(|m| m.kind).ok_or_else(|| IoError::Invalid {
            path: path.to_path_buf(),
            message: format!("missing key 'mechanism.kind' (one of: {})", kinds_list()),
        })?;
        let file = match kind.get_ref().as_str() {
            "serial" => {
                let raw: RawFile<RawSerial> = toml::from_str(text).map_err(|e| ctx.toml_error(&e))?;
                let units = ctx.units(&raw.units)?;
                let mech = ctx.serial(&raw.name, &raw.mechanism, &units)?;
                ctx.finish(raw, units, mech)?
            }
            "pm5" => {
                let raw: RawFile<parallel::RawPm5> = toml::from_str(text).map_err(|e| ctx.toml_error(&e))?;
                let units = ctx.units(&raw.units)?;
                let mech = ctx.pm5(&raw.mechanism, &units)?;
                ctx.finish(raw, units, mech)?
            }
            "stewart" => {
                let raw: RawFile<parallel::RawStewart> = toml::from_str(text).map_err(|e| ctx.toml_error(&e))?;
                let units = ctx.units(&raw.units)?;
                let mech = ctx.stewart(&raw.mechanism, &units)?;
                ctx.finish(raw, units, mech)?
            }
            other => {
                return Err(ctx.at(
                    &kind.span(),
                    format!("mechanism.kind: unknown mechanism kind '{other}' (one of: {})", kinds_list()),
                ))
            }
        };
        Ok(file)
    }
}

fn kinds_list() -> String {
    KINDS.iter().map(|k| format!("\"{k}\"")).collect::<Vec<_>>().join(", ")
}

fn quote(s: &str) -> String {
    format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))
}

/// `v` as written in a file: a decimal of at most 12 significant digits when one lies within
/// 2e-15 (relative) of `v` — unit conversions do not leave `119.99999999999999` where the user
/// wrote `120` — else the shortest decimal that reads back as exactly `v` (calibrated values lose
/// nothing). Writing a value read from such a text gives the same text again. `-0.0` is `0.0`.
fn num(v: f64) -> String {
    if v == 0.0 {
        return "0.0".into();
    }
    for prec in 0..12 {
        let s = format!("{v:.prec$e}");
        if let Ok(p) = s.parse::<f64>() {
            if (p - v).abs() <= 2e-15 * v.abs() {
                return format!("{p:?}");
            }
        }
    }
    format!("{v:?}")
}

fn fmt3(v: [f64; 3]) -> String {
    format!("[{}, {}, {}]", num(v[0]), num(v[1]), num(v[2]))
}

/// Writes `position` and `rpy` ([`crate::se3::rpy`]), or `rotvec` where roll/pitch/yaw would
/// not give the rotation back to 1e-14 rad.
fn write_pose(p: &Pose, units: &Units, out: &mut String) {
    let t = p.translation.vector / units.length.to_mm();
    let f = units.angle.to_rad();
    let _ = writeln!(out, "position = {}", fmt3([t.x, t.y, t.z]));
    let [roll, pitch, yaw] = crate::se3::rpy(&p.rotation);
    let back = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
    if crate::se3::so3_log(&(back.inverse() * p.rotation)).norm() <= 1e-14 {
        let _ = writeln!(out, "rpy = {}", fmt3([roll / f, pitch / f, yaw / f]));
    } else {
        let v = crate::se3::so3_log(&p.rotation) / f;
        let _ = writeln!(out, "rotvec = {}", fmt3([v.x, v.y, v.z]));
    }
}

fn write_dh(table: &DhTable, units: &Units, out: &mut String) {
    let (l, a) = (units.length.to_mm(), units.angle.to_rad());
    let key = table.convention.key();
    out.push_str("[mechanism]\nkind = \"serial\"\n");
    match table.convention {
        DhConvention::Standard => {
            out.push_str("# Standard DH: A_i(q) = Rz(theta + q)·Tz(d)·Tx(a)·Rx(alpha)·Ry(beta) (q adds to d for prismatic\n");
            out.push_str("# joints; beta is Hayati's, 0 when absent); g(q) = base · A_1(q_1) ··· A_n(q_n) · tool.\n");
        }
        DhConvention::Modified => {
            out.push_str("# Modified DH (Craig): A_i(q) = Rx(alpha)·Tx(a)·Rz(theta + q)·Tz(d), row i holding alpha_{i-1}\n");
            out.push_str("# and a_{i-1} (q adds to d for prismatic joints); g(q) = base · A_1(q_1) ··· A_n(q_n) · tool.\n");
        }
    }
    out.push_str("\n[mechanism.base]  # frame 0 in the world frame\n");
    write_pose(&table.base, units, out);
    for j in &table.joints {
        let kind = match j.kind {
            JointKind::Revolute => "revolute",
            JointKind::Prismatic => "prismatic",
        };
        let _ = write!(
            out,
            "\n[[mechanism.{key}]]\nname = {}\ntype = \"{kind}\"\na = {}\nalpha = {}\nd = {}\ntheta = {}\n",
            quote(&j.name),
            num(j.a / l),
            num(j.alpha / a),
            num(j.d / l),
            num(j.theta / a)
        );
        if j.beta != 0.0 {
            let _ = writeln!(
                out,
                "beta = {}  # Hayati: this joint's next axis is nearly parallel to it",
                num(j.beta / a)
            );
        }
        if let Some((lo, hi)) = j.limits {
            let f = if j.kind == JointKind::Revolute { a } else { l };
            let _ = writeln!(out, "limits = [{}, {}]", num(lo / f), num(hi / f));
        }
    }
    out.push_str("\n[mechanism.tool]  # the tool in the last DH frame\n");
    write_pose(&table.tool, units, out);
}

#[derive(Deserialize)]
struct Probe {
    mechanism: Option<ProbeMechanism>,
}

#[derive(Deserialize)]
struct ProbeMechanism {
    kind: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile<M> {
    name: String,
    description: Option<String>,
    units: RawUnits,
    mechanism: M,
    calibration: Option<RawCalibration>,
    noise: Option<Spanned<RawNoise>>,
    provenance: Option<Provenance>,
    frames: Option<RawFrames>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFrames {
    measurement: Spanned<RawPose>,
    tool: Spanned<RawPose>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawUnits {
    length: Spanned<String>,
    angle: Spanned<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCalibration {
    free: Option<Vec<Spanned<String>>>,
    fixed: Option<Vec<Spanned<String>>>,
    tolerance_mm: Option<Spanned<f64>>,
    tolerance_deg: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNoise {
    position: f64,
    orientation: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPose {
    position: Option<[f64; 3]>,
    rpy: Option<[f64; 3]>,
    rotvec: Option<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawJoint {
    name: String,
    #[serde(rename = "type")]
    kind: JointKind,
    axis: [f64; 3],
    limits: Option<[f64; 2]>,
    position: Option<[f64; 3]>,
    rpy: Option<[f64; 3]>,
    rotvec: Option<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDhRow {
    name: String,
    #[serde(rename = "type")]
    kind: JointKind,
    a: f64,
    alpha: f64,
    d: f64,
    theta: f64,
    beta: Option<f64>,
    limits: Option<[f64; 2]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSerial {
    #[allow(dead_code)]
    kind: String,
    joints: Option<Vec<Spanned<RawJoint>>>,
    dh: Option<Vec<Spanned<RawDhRow>>>,
    mdh: Option<Vec<Spanned<RawDhRow>>>,
    base: Option<Spanned<RawPose>>,
    tool: Option<Spanned<RawPose>>,
}

struct Ctx<'a> {
    path: &'a Path,
    text: &'a str,
}

/// Fixed lengths of the numeric arrays of model files, by key: serde reads the first `n` values
/// of a longer TOML array and drops the rest, so a typo such as `c = [0, 100, 0, 5]` would pass
/// silently without this check.
const ARRAY_LENGTHS: [(&str, usize); 19] = [
    ("position", 3),
    ("rpy", 3),
    ("rotvec", 3),
    ("axis", 3),
    ("b", 3),
    ("c", 3),
    ("base", 3),
    ("platform", 3),
    ("euler_xyz", 3),
    ("alpha", 2),
    ("beta", 2),
    ("gamma", 2),
    ("limits", 2),
    ("stroke", 2),
    ("sub_stroke", 2),
    ("x", 2),
    ("y", 2),
    ("z", 2),
    ("sub_loop", 4),
];

impl Ctx<'_> {
    /// Every array under a key of [`ARRAY_LENGTHS`] has exactly that many values.
    fn check_array_lengths(&self) -> Result<(), IoError> {
        use toml::de::{DeTable, DeValue};
        fn walk(ctx: &Ctx<'_>, table: &DeTable<'_>, prefix: &str) -> Result<(), IoError> {
            for (k, v) in table.iter() {
                let key = k.get_ref().as_ref();
                let full = if prefix.is_empty() {
                    key.to_string()
                } else {
                    format!("{prefix}.{key}")
                };
                match v.get_ref() {
                    DeValue::Table(t) => walk(ctx, t, &full)?,
                    DeValue::Array(items) => {
                        if let Some(&(_, n)) = ARRAY_LENGTHS.iter().find(|(name, _)| *name == key) {
                            if items.len() != n {
                                return Err(ctx.at(&v.span(), format!("{full}: expected {n} values, found {}", items.len())));
                            }
                        }
                        for item in items {
                            if let DeValue::Table(t) = item.get_ref() {
                                walk(ctx, t, &full)?;
                            }
                        }
                    }
                    _ => {}
                }
            }
            Ok(())
        }
        let table = DeTable::parse(self.text).map_err(|e| self.toml_error(&e))?;
        walk(self, table.get_ref(), "")
    }

    fn line_of(&self, offset: usize) -> usize {
        self.text[..offset.min(self.text.len())].matches('\n').count() + 1
    }

    fn at(&self, span: &Range<usize>, message: String) -> IoError {
        IoError::AtLine {
            path: self.path.to_path_buf(),
            line: self.line_of(span.start),
            message,
        }
    }

    fn toml_error(&self, e: &toml::de::Error) -> IoError {
        let message = e.message().trim().replace('\n', "; ");
        match e.span() {
            Some(s) => self.at(&s, message),
            None => IoError::Invalid {
                path: self.path.to_path_buf(),
                message,
            },
        }
    }

    fn units(&self, raw: &RawUnits) -> Result<Units, IoError> {
        let length = LengthUnit::parse(raw.length.get_ref()).ok_or_else(|| {
            self.at(
                &raw.length.span(),
                format!("units.length: unknown length unit '{}' (use \"mm\" or \"m\")", raw.length.get_ref()),
            )
        })?;
        let angle = AngleUnit::parse(raw.angle.get_ref()).ok_or_else(|| {
            self.at(
                &raw.angle.span(),
                format!("units.angle: unknown angle unit '{}' (use \"deg\" or \"rad\")", raw.angle.get_ref()),
            )
        })?;
        Ok(Units { length, angle })
    }

    fn pose(
        &self,
        span: &Range<usize>,
        what: &str,
        position: Option<[f64; 3]>,
        rpy: Option<[f64; 3]>,
        rotvec: Option<[f64; 3]>,
        units: &Units,
    ) -> Result<Pose, IoError> {
        let all = position.iter().chain(rpy.iter()).chain(rotvec.iter()).flatten();
        if all.clone().any(|v| !v.is_finite()) {
            return Err(self.at(span, format!("{what}: non-finite value in position/rpy/rotvec")));
        }
        let p = Vector3::from(position.unwrap_or([0.0; 3])) * units.length.to_mm();
        let f = units.angle.to_rad();
        let rot = match (rpy, rotvec) {
            (Some(_), Some(_)) => return Err(self.at(span, format!("{what}: give either 'rpy' or 'rotvec', not both"))),
            (Some(r), None) => UnitQuaternion::from_euler_angles(r[0] * f, r[1] * f, r[2] * f),
            (None, Some(v)) => crate::se3::so3_exp(&(Vector3::from(v) * f)),
            (None, None) => UnitQuaternion::identity(),
        };
        Ok(Pose::from_parts(Translation3::from(p), rot))
    }

    fn limits(
        &self,
        span: &Range<usize>,
        what: &str,
        limits: Option<[f64; 2]>,
        kind: JointKind,
        units: &Units,
    ) -> Result<Option<(f64, f64)>, IoError> {
        let Some([lo, hi]) = limits else { return Ok(None) };
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(self.at(
                span,
                format!("{what}.limits: need two finite values with min < max, got [{lo}, {hi}]"),
            ));
        }
        let f = match kind {
            JointKind::Revolute => units.angle.to_rad(),
            JointKind::Prismatic => units.length.to_mm(),
        };
        Ok(Some((lo * f, hi * f)))
    }

    fn serial(&self, name: &str, raw: &RawSerial, units: &Units) -> Result<MechanismSpec, IoError> {
        let forms = [raw.joints.is_some(), raw.dh.is_some(), raw.mdh.is_some()];
        if forms.iter().filter(|f| **f).count() != 1 {
            return Err(IoError::Invalid {
                path: self.path.to_path_buf(),
                message: "mechanism: a serial chain needs exactly one of [[mechanism.joints]] (local POE), [[mechanism.dh]] (standard DH) or [[mechanism.mdh]] (modified DH)".into(),
            });
        }
        if let Some(rows) = raw.dh.as_ref().or(raw.mdh.as_ref()) {
            let convention = if raw.dh.is_some() {
                DhConvention::Standard
            } else {
                DhConvention::Modified
            };
            return self.dh_table(name, convention, rows, raw, units);
        }
        if let Some(b) = &raw.base {
            return Err(self.at(
                &b.span(),
                "mechanism.base: only with a DH table ([[mechanism.dh]] or [[mechanism.mdh]]); with [[mechanism.joints]] the first joint's position/rpy is the base".into(),
            ));
        }
        let raw_joints = raw.joints.as_deref().unwrap_or_default();
        if raw_joints.is_empty() {
            return Err(IoError::Invalid {
                path: self.path.to_path_buf(),
                message: "mechanism.joints: a serial chain needs at least one joint".into(),
            });
        }
        let mut joints = Vec::new();
        let mut initial = Vec::new();
        for (j, sj) in raw_joints.iter().enumerate() {
            let span = sj.span();
            let rj = sj.get_ref();
            let what = format!("mechanism.joints[{j}] ('{}')", rj.name);
            if rj.name.is_empty() || joints.iter().any(|x: &ChainJoint| x.name == rj.name) {
                return Err(self.at(&span, format!("{what}: joint names must be non-empty and unique")));
            }
            let axis = Vector3::from(rj.axis);
            if !axis.iter().all(|v| v.is_finite()) || axis.norm() < 1e-9 {
                return Err(self.at(&span, format!("{what}.axis: must be a finite non-zero vector")));
            }
            let mut joint = match rj.kind {
                JointKind::Revolute => ChainJoint::revolute(rj.name.clone(), axis),
                JointKind::Prismatic => ChainJoint::prismatic(rj.name.clone(), axis),
            };
            joint.limits = self.limits(&span, &what, rj.limits, rj.kind, units)?;
            joints.push(joint);
            initial.push(self.pose(&span, &what, rj.position, rj.rpy, rj.rotvec, units)?);
        }
        let tool = match &raw.tool {
            Some(t) => {
                let r = t.get_ref();
                self.pose(&t.span(), "mechanism.tool", r.position, r.rpy, r.rotvec, units)?
            }
            None => Pose::identity(),
        };
        Ok(MechanismSpec::Serial(SerialChain::new(name, joints, initial, tool)))
    }

    fn dh_table(
        &self,
        name: &str,
        convention: DhConvention,
        rows: &[Spanned<RawDhRow>],
        raw: &RawSerial,
        units: &Units,
    ) -> Result<MechanismSpec, IoError> {
        let key = convention.key();
        if rows.is_empty() {
            return Err(IoError::Invalid {
                path: self.path.to_path_buf(),
                message: format!("mechanism.{key}: a DH table needs at least one row"),
            });
        }
        let (l, a) = (units.length.to_mm(), units.angle.to_rad());
        let mut joints: Vec<DhJoint> = Vec::new();
        for (j, sr) in rows.iter().enumerate() {
            let span = sr.span();
            let r = sr.get_ref();
            let what = format!("mechanism.{key}[{j}] ('{}')", r.name);
            if r.name.is_empty() || joints.iter().any(|x| x.name == r.name) {
                return Err(self.at(&span, format!("{what}: joint names must be non-empty and unique")));
            }
            let values = [r.a, r.alpha, r.d, r.theta, r.beta.unwrap_or(0.0)];
            if values.iter().any(|v| !v.is_finite()) {
                return Err(self.at(&span, format!("{what}: non-finite value in a, alpha, d, theta or beta")));
            }
            if r.beta.is_some() && convention == DhConvention::Modified {
                return Err(self.at(
                    &span,
                    format!("{what}.beta: Hayati's beta belongs to standard DH ([[mechanism.dh]]), not to modified DH"),
                ));
            }
            joints.push(DhJoint {
                name: r.name.clone(),
                kind: r.kind,
                a: r.a * l,
                alpha: r.alpha * a,
                d: r.d * l,
                theta: r.theta * a,
                beta: r.beta.unwrap_or(0.0) * a,
                limits: self.limits(&span, &what, r.limits, r.kind, units)?,
            });
        }
        let pose = |p: &Option<Spanned<RawPose>>, what: &str| match p {
            Some(t) => {
                let r = t.get_ref();
                self.pose(&t.span(), what, r.position, r.rpy, r.rotvec, units)
            }
            None => Ok(Pose::identity()),
        };
        let table = DhTable {
            convention,
            base: pose(&raw.base, "mechanism.base")?,
            joints,
            tool: pose(&raw.tool, "mechanism.tool")?,
        };
        Ok(MechanismSpec::Serial(table.to_chain(name)))
    }

    fn finish<M>(&self, raw: RawFile<M>, units: Units, mechanism: MechanismSpec) -> Result<ModelFile, IoError> {
        let params = mechanism.build().params();
        let (free, fixed) = match &raw.calibration {
            Some(c) => (
                c.free.clone().unwrap_or_else(|| vec![Spanned::new(0..0, "*".to_string())]),
                c.fixed.clone().unwrap_or_default(),
            ),
            None => (vec![Spanned::new(0..0, "*".to_string())], Vec::new()),
        };
        for (key, list) in [("free", &free), ("fixed", &fixed)] {
            for pat in list {
                if !params.iter().any(|p| param_match(pat.get_ref(), &p.name)) {
                    let examples: Vec<&str> = params.iter().take(3).map(|p| p.name.as_str()).collect();
                    return Err(self.at(
                        &pat.span(),
                        format!(
                            "calibration.{key}: '{}' matches no parameter (names look like {}, …)",
                            pat.get_ref(),
                            examples.join(", ")
                        ),
                    ));
                }
            }
        }
        let mut tolerances = Tolerances::default();
        if let Some(c) = &raw.calibration {
            for (key, given, slot) in [
                ("tolerance_mm", &c.tolerance_mm, &mut tolerances.length_mm),
                ("tolerance_deg", &c.tolerance_deg, &mut tolerances.angle_deg),
            ] {
                if let Some(v) = given {
                    if !(v.get_ref().is_finite() && *v.get_ref() > 0.0) {
                        return Err(self.at(&v.span(), format!("calibration.{key}: must be finite and > 0")));
                    }
                    *slot = *v.get_ref();
                }
            }
        }
        let frames = match &raw.frames {
            Some(f) => {
                let pose = |p: &Spanned<RawPose>, what: &str| {
                    let r = p.get_ref();
                    self.pose(&p.span(), what, r.position, r.rpy, r.rotvec, &units)
                };
                Some(Frames {
                    measurement: pose(&f.measurement, "frames.measurement")?,
                    tool: pose(&f.tool, "frames.tool")?,
                })
            }
            None => None,
        };
        let noise = match &raw.noise {
            Some(n) => {
                let r = n.get_ref();
                if !(r.position > 0.0 && r.orientation > 0.0 && r.position.is_finite() && r.orientation.is_finite()) {
                    return Err(self.at(&n.span(), "noise: position and orientation must be finite and > 0".into()));
                }
                Some(Noise {
                    position: r.position * units.length.to_mm(),
                    orientation: r.orientation * units.angle.to_rad(),
                })
            }
            None => None,
        };
        Ok(ModelFile {
            name: raw.name,
            description: raw.description,
            units,
            mechanism,
            free: free.into_iter().map(|s| s.into_inner()).collect(),
            fixed: fixed.into_iter().map(|s| s.into_inner()).collect(),
            tolerances,
            noise,
            provenance: raw.provenance,
            frames,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glob() {
        assert!(glob_match("0-1.*", "0-1.vx"));
        assert!(!glob_match("0-1.*", "1-2.vx"));
        assert!(glob_match("*.w?", "3-4.wz"));
        assert!(glob_match("*", "anything"));
        assert!(!glob_match("*.wx", "3-4.wz"));
        assert!(param_match("dphi1", "dφ1") && param_match("dgamma0", "dγ0") && param_match("dalpha?", "dα0"));
        assert!(!param_match("dphi2", "dφ1"));
    }
}
