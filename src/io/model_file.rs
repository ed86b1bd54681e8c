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
//! seat = 0.005      # optional, length unit: seat rows' σ (distance = …: ballbar, probe = …: touches); default position
//! ```
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
//! * `kind = "limbs"`: any parallel machine as a base, a platform and limbs of joints (revolute,
//!   prismatic, universal, spherical; actuated, sensed or passive) closing on the platform with a
//!   frame or a spherical joint; poses as in the serial kind. The format is in `limbs.rs` of this
//!   module and docs/parallel-machines.md; examples in `examples/models/`.
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
mod covariance;
mod limbs;
mod parallel;
mod parse;
mod select;
mod write;

pub use covariance::{Covariance, Held};
use parse::RawJointTerms;
pub use select::{free_params, glob_match, greek_pattern, param_match, select_params};
use write::{fmt3, num, num_per, quote, write_dh, write_mechanism, write_pose};

use super::IoError;
use crate::measure::Noise;
use crate::model::chain::{ChainJoint, JointKind, SerialChain};
use crate::model::dh::{DhConvention, DhError, DhJoint, DhOptions, DhTable};
use crate::model::framed::Framed;
use crate::model::joint_terms::{JointTerms, WithJointTerms};
use crate::model::Mechanism;
use crate::params::Unit;
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
    /// The covariance of a calibration's identified parameters (`[covariance]`, written by
    /// `kinecal identify`): error coordinates of [`ModelFile::build`] about this geometry.
    pub covariance: Option<Covariance>,
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

impl Tolerances {
    /// The tolerance of a parameter of this unit in kinecal's units (mm, rad); `None` for a pure
    /// number, which has none.
    pub fn of(&self, unit: Unit) -> Option<f64> {
        match unit {
            Unit::Length => Some(self.length_mm),
            Unit::Angle => Some(self.angle_deg.to_radians()),
            Unit::Dimensionless => None,
        }
    }
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
            covariance: None,
        }
    }

    /// The mechanism, ready to compute with: seen through its [`Frames`] when the file has them.
    pub fn build(&self) -> Box<dyn Mechanism> {
        match &self.frames {
            Some(f) => Box::new(Framed::new(self.mechanism.build(), f.measurement, f.tool)),
            None => self.mechanism.build(),
        }
    }

    /// The mechanism in its own base frame carrying `tool` (a program's tool, in the mechanism's
    /// tool frame: a robot arm's flange): what a controller's programs are written in. The
    /// file's `[frames]` (where a tracker stood, and its reflector or probe) belong to the
    /// instrument and are left out.
    pub fn build_in_base_frame(&self, tool: &Pose) -> Box<dyn Mechanism> {
        Box::new(Framed::new(self.mechanism.build(), Pose::identity(), *tool))
    }

    /// Inputs with units and limits.
    pub fn inputs(&self) -> Vec<InputSpec> {
        self.mechanism.inputs()
    }

    /// The columns of a measurement data file: inputs, then observed joints
    /// ([`MechanismSpec::data_columns`]).
    pub fn data_columns(&self) -> Vec<InputSpec> {
        self.mechanism.data_columns()
    }

    /// Indices of the free parameters in priority order, without those the mechanism cannot
    /// take alone ([`Mechanism::assembly_breaking`], [`ModelFile::held_by_assembly`]).
    pub fn free_indices(&self) -> Result<Vec<usize>, IoError> {
        free_params(&*self.build(), &self.free, &self.fixed).map_err(|message| IoError::Invalid {
            path: PathBuf::from(format!("model '{}'", self.name)),
            message,
        })
    }

    /// Names of the error parameters the model's mechanism is too constrained to take alone
    /// ([`Mechanism::assembly_breaking`]): held at their drawn values whatever `[calibration]`
    /// says. Empty for every mechanism that is not overconstrained.
    pub fn held_by_assembly(&self) -> Vec<String> {
        let mech = self.build();
        let params = mech.params();
        mech.assembly_breaking().into_iter().map(|i| params[i].name.clone()).collect()
    }

    /// A copy with the geometry of `model` (a calibrated mechanism of the same kind, or such a
    /// mechanism seen through frames, [`Framed`], whose frames are then kept too). A covariance
    /// belongs to the geometry it was identified at and is left out.
    pub fn with_geometry_of(&self, model: &dyn Mechanism) -> Result<ModelFile, String> {
        if let Some((measurement, tool)) = model.frames() {
            return Ok(ModelFile {
                mechanism: self.mechanism.with_geometry_of(model)?,
                frames: Some(Frames { measurement, tool }),
                covariance: None,
                ..self.clone()
            });
        }
        Ok(ModelFile {
            mechanism: self.mechanism.with_geometry_of(model)?,
            covariance: None,
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
            return Err(DhError::NotSerial(match &self.mechanism {
                crate::io::model_file::MechanismSpec::SerialTerms(_) => "a serial chain with joint terms (a DH table has no place for them: remove [mechanism.joint_terms] to export the geometry alone; the terms are then lost)".to_string(),
                m => format!("a {} mechanism", m.kind()),
            }));
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
            MechanismSpec::Serial(_) | MechanismSpec::SerialTerms(_) | MechanismSpec::Limbs(_) => {
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
            write::write_noise(n, &self.units, &mut out);
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
        if let Some(c) = &self.covariance {
            covariance::write_covariance(c, &mut out);
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
        let probe: Probe = toml::from_str(text).map_err(|e| match looks_like_csv(text) {
            true => IoError::Invalid {
                path: path.to_path_buf(),
                message: "this is a CSV (a data file), not a model file: the order is MODEL DATA".into(),
            },
            false => ctx.toml_error(&e),
        })?;
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
            "limbs" => {
                let raw: RawFile<limbs::RawLimbs> = toml::from_str(text).map_err(|e| ctx.toml_error(&e))?;
                let units = ctx.units(&raw.units)?;
                let mech = ctx.limbs(&raw.name, &raw.mechanism, &units)?;
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
    covariance: Option<Spanned<covariance::RawCovariance>>,
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
    encoder_angle: Option<f64>,
    encoder_length: Option<f64>,
    seat: Option<f64>,
    distance: Option<f64>,
    probe: Option<f64>,
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
    joint_terms: Option<Spanned<RawJointTerms>>,
}

struct Ctx<'a> {
    path: &'a Path,
    text: &'a str,
}

/// Whether text that TOML could not read is a CSV table: its first line (not a comment) holds
/// commas, no `=` and no `[`.
fn looks_like_csv(text: &str) -> bool {
    text.lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .is_some_and(|l| l.contains(',') && !l.contains('=') && !l.starts_with('['))
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
