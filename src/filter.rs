//! Filtering programs for a controller that keeps its nominal kinematics.
//!
//! A robot or machine controller takes Cartesian targets and applies its own, nominal kinematics.
//! The calibration cannot replace that kinematics, but it can replace the targets: each target
//! `T` (the program's tool pose in the robot's base frame, or in a work object) becomes
//!
//! ```text
//! T' = FK_nominal(IK_calibrated(T))
//! ```
//!
//! on the branch the program states (an arm's configuration data) or, without one, the branch
//! the nominal controller takes from the previous target. Sent `T'`, the nominal controller
//! computes the joint values `IK_nominal(T') = IK_calibrated(T)`, which bring the real machine —
//! as the calibrated model describes it — to `T`.
//!
//! Frames: targets are in the mechanism's base frame with the program's tool (given in the
//! mechanism's tool frame: a robot arm's flange). The calibrated model file's `[frames]` (where
//! the tracker stood, the reflector, ball or probe it measured) belong to the instrument and are
//! not used: both models are built with [`ModelFile::build_in_base_frame`].
//!
//! Program formats (each a module): CSV targets ([`csv`], `kinecal compensate`'s TARGETS
//! format), ABB RAPID modules ([`rapid`]), KUKA KRL ([`krl`]), URScript ([`urscript`]) and
//! G-code for machines commanding their tool position (and axis) ([`gcode`]). Every byte outside the numbers that change is
//! kept ([`rewrite`]). [`filter_program`] is the one call of `kinecal filter`.
pub mod arc;
pub mod branch;
pub mod csv;
pub mod gcode;
pub mod krl;
mod lex;
pub mod path;
pub mod rapid;
pub mod rewrite;
mod solve;
pub mod urscript;

use crate::io::model_file::{MechanismSpec, ModelFile};
use crate::io::IoError;
use crate::model::kind::InputSpec;
use crate::model::Mechanism;
use crate::se3::Pose;
use crate::validate::commanded_error;
use branch::{ArmBranches, ArmConfiguration, Configuration, StatusTurn};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Why a program could not be filtered: one line naming the file and the line.
#[derive(Debug, thiserror::Error)]
pub enum FilterError {
    /// The program cannot be read as its format (a malformed target, an unknown tooldata).
    #[error("{}:{line}: {message}", path.display())]
    Parse {
        /// The program.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A target the calibrated model cannot reach on its branch, outside the limits, or on
    /// another configuration than the program states.
    #[error("{}:{line}: {message}", path.display())]
    Target {
        /// The program.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What cannot be corrected.
        message: String,
    },
    /// Options that do not fit the program.
    #[error("{0}")]
    Options(String),
    /// The models do not fit together (different inputs).
    #[error("{0}")]
    Models(String),
    /// A file could not be read.
    #[error(transparent)]
    Io(#[from] IoError),
}

impl FilterError {
    /// The lexers' and parsers' `(line, message)` errors as [`FilterError::Parse`] of `path`.
    pub(crate) fn parse_at(path: &Path) -> impl Fn((usize, String)) -> FilterError + Copy + '_ {
        move |(line, message)| FilterError::Parse {
            path: path.to_path_buf(),
            line,
            message,
        }
    }
}

/// A program's format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// CSV targets (`x_mm,y_mm,z_mm` + quaternion or roll/pitch/yaw; optional id and inputs).
    Csv,
    /// An ABB RAPID module (`.mod`, `.modx`, `.prg`).
    Rapid,
    /// A URScript program (`.script`, `.urscript`).
    #[serde(rename = "urscript")]
    UrScript,
    /// A KUKA KRL program (`.src`, with its `.dat`).
    Krl,
    /// G-code (`.nc`, `.ngc`, `.gcode`).
    Gcode,
}

impl Format {
    /// The format a file name's extension names.
    pub fn from_path(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "csv" => Some(Format::Csv),
            "mod" | "modx" | "prg" => Some(Format::Rapid),
            "script" | "urscript" => Some(Format::UrScript),
            "src" => Some(Format::Krl),
            "nc" | "ngc" | "gcode" => Some(Format::Gcode),
            _ => None,
        }
    }
}

impl std::str::FromStr for Format {
    type Err = String;
    /// `csv`, `rapid`, `urscript`, `krl` or `gcode`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "csv" => Ok(Format::Csv),
            "rapid" => Ok(Format::Rapid),
            "urscript" => Ok(Format::UrScript),
            "krl" => Ok(Format::Krl),
            "gcode" => Ok(Format::Gcode),
            o => Err(format!("unknown program format '{o}' (csv, rapid, urscript, krl or gcode)")),
        }
    }
}

/// The calibrated and the nominal model, each in the base frame, and the arm branches of the
/// nominal one (a 6R arm's configuration data).
pub struct FilterModels {
    calibrated: ModelFile,
    nominal: ModelFile,
    /// The inputs (the same for both models).
    pub inputs: Vec<InputSpec>,
    /// The columns of a targets file (inputs as optional starting points).
    pub columns: Vec<InputSpec>,
    branches: Option<ArmBranches>,
}

impl FilterModels {
    /// The two models; refused when their inputs differ.
    pub fn new(calibrated: &ModelFile, nominal: &ModelFile) -> Result<Self, FilterError> {
        let inputs = calibrated.inputs();
        if !nominal.inputs().iter().map(|i| &i.name).eq(inputs.iter().map(|i| &i.name)) {
            return Err(FilterError::Models(format!(
                "the nominal model '{}' has other inputs than the calibrated model '{}'",
                nominal.name, calibrated.name
            )));
        }
        let branches = match &nominal.mechanism {
            MechanismSpec::Serial(chain) => ArmBranches::new(chain),
            _ => None,
        };
        Ok(FilterModels {
            calibrated: calibrated.clone(),
            nominal: nominal.clone(),
            columns: calibrated.data_columns(),
            inputs,
            branches,
        })
    }

    /// What the machine commands (the calibrated model's task).
    pub fn task(&self) -> crate::model::Task {
        self.calibrated.build().task()
    }

    /// The arm configuration of joint values `q` (a 6R arm; `None` for other mechanisms).
    pub fn configuration(&self, q: &[f64]) -> Option<ArmConfiguration> {
        self.branches.as_ref().and_then(|b| b.of(q).ok())
    }

    /// The calibrated and the nominal model in the base frame with `tool`.
    pub fn with_tool(&self, tool: &Pose) -> (Box<dyn Mechanism>, Box<dyn Mechanism>) {
        (self.calibrated.build_in_base_frame(tool), self.nominal.build_in_base_frame(tool))
    }
}

/// A target to correct.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// The tool pose in the base frame (mm).
    pub pose: Pose,
    /// The tool in the mechanism's tool frame (the flange).
    pub tool: Pose,
    /// The configuration the program states (a 6R arm), if any.
    pub configuration: Option<Configuration>,
    /// Joint values to start the nominal inverse kinematics from, if the program gives them.
    pub seed: Option<Vec<f64>>,
}

/// A corrected target.
#[derive(Debug, Clone, PartialEq)]
pub struct Corrected {
    /// `T' = FK_nominal(IK_calibrated(T))`, base frame.
    pub pose: Pose,
    /// What the nominal controller commands for the original target.
    pub nominal_q: Vec<f64>,
    /// What the calibrated model needs, and the nominal controller commands for `pose`.
    pub q: Vec<f64>,
    /// The configuration `q` is on (a 6R arm): ABB's configuration data.
    pub configuration: Option<ArmConfiguration>,
    /// The same as KUKA's Status and Turn.
    pub status_turn: Option<StatusTurn>,
    /// Predicted error at the target without the filter (mm, rad; the commanded task's).
    pub before: (f64, f64),
    /// Predicted error with it: the calibrated model at the nominal controller's solution for
    /// `pose` on `configuration` (mm, rad).
    pub after: (f64, f64),
}

/// Correct each target; one result per target (an error is one line's message, without file
/// and line).
pub fn correct(models: &FilterModels, targets: &[Target]) -> Vec<Result<Corrected, String>> {
    let starts = crate::compensate::fixed_starts(&models.inputs, crate::compensate::COMPENSATION_STARTS);
    // The models for the last tool seen (a program changes tools rarely).
    type Built = (Pose, Box<dyn Mechanism>, Box<dyn Mechanism>);
    let mut built: Option<Built> = None;
    let mut previous: Option<Vec<f64>> = None;
    let mut out = Vec::with_capacity(targets.len());
    for t in targets {
        if built.as_ref().is_none_or(|(tool, _, _)| *tool != t.tool) {
            let (c, n) = models.with_tool(&t.tool);
            built = Some((t.tool, c, n));
        }
        let (_, cal, nom) = built.as_ref().expect("built above");
        let r = correct_one(models, &**cal, &**nom, t, previous.as_deref(), &starts);
        if let Ok(c) = &r {
            previous = Some(c.nominal_q.clone());
        }
        out.push(r);
    }
    out
}

fn correct_one(
    models: &FilterModels,
    cal: &dyn Mechanism,
    nom: &dyn Mechanism,
    t: &Target,
    previous: Option<&[f64]>,
    starts: &[Vec<f64>],
) -> Result<Corrected, String> {
    let inputs = &models.inputs;
    let stated = t.configuration;
    let branches = models.branches.as_ref();
    // The nominal controller: its inverse kinematics on the stated configuration (or, without
    // one, from the program's joint values, then the previous target's solution).
    let mut seeds: Vec<Vec<f64>> = Vec::new();
    seeds.extend(t.seed.iter().cloned());
    let conf_seeds = match (stated, branches) {
        (Some(c), Some(b)) => b.seeds_for(&c, starts),
        _ => Vec::new(),
    };
    let reference: Vec<f64> = match (stated, branches) {
        (Some(c), Some(b)) => b.reference(&c),
        _ => t.seed.clone().or(previous.map(<[f64]>::to_vec)).unwrap_or_default(),
    };
    seeds.extend(previous.map(<[f64]>::to_vec));
    seeds.extend(conf_seeds);
    seeds.extend(starts.iter().cloned());
    let on_stated = |q: &[f64]| match (stated, branches) {
        (Some(c), Some(b)) => b.matches(q, &c),
        _ => true,
    };
    let nominal_q = solve::solve(nom, inputs, &t.pose, &seeds, &reference, &on_stated).map_err(|e| match e {
        solve::SolveError::OtherBranch => format!(
            "the nominal model reaches this target, but not on the configuration the program states ({})",
            stated.map(|c| c.to_string()).unwrap_or_default()
        ),
        solve::SolveError::Kin(e) => format!("the nominal model cannot reach this target: {e}"),
    })?;
    let nominal_conf = branches.and_then(|b| b.of(&nominal_q).ok());
    // The calibrated model on the same branch (its quadrants may change across a boundary).
    let same_branch = |q: &[f64]| match (nominal_conf, branches) {
        (Some(c), Some(b)) => b.of(q).is_ok_and(|k| k.cfx == c.cfx),
        _ => true,
    };
    let mut cal_seeds = vec![nominal_q.clone()];
    cal_seeds.extend(starts.iter().cloned());
    let q = solve::solve(cal, inputs, &t.pose, &cal_seeds, &nominal_q, &same_branch).map_err(|e| match e {
        solve::SolveError::OtherBranch => format!(
            "configuration flip: the calibrated model reaches this target only on another configuration than the nominal's ({})",
            nominal_conf.map(|c| c.to_string()).unwrap_or_default()
        ),
        solve::SolveError::Kin(e) => format!("the calibrated model cannot reach this target on its branch: {e}"),
    })?;
    let pose = nom.forward(&q).map_err(|e| e.to_string())?;
    let configuration = branches.and_then(|b| b.of(&q).ok());
    let status_turn = branches.and_then(|b| b.status_turn(&q).ok());
    let written = match (stated, branches) {
        (Some(c), Some(b)) => b.configuration(&q, &c).ok(),
        _ => None,
    };
    let task = cal.task();
    let before = commanded_error(task, &t.pose, &cal.forward(&nominal_q).map_err(|e| e.to_string())?);
    // The nominal controller sent the corrected target on its configuration.
    let on_corrected = |x: &[f64]| match (written, branches) {
        (Some(c), Some(b)) => b.matches(x, &c),
        _ => true,
    };
    let mut back_seeds = vec![q.clone()];
    back_seeds.extend(starts.iter().cloned());
    let back = solve::solve(nom, inputs, &pose, &back_seeds, &q, &on_corrected)
        .map_err(|_| "the nominal model does not reach the corrected target on its configuration".to_string())?;
    let after = commanded_error(task, &t.pose, &cal.forward(&back).map_err(|e| e.to_string())?);
    Ok(Corrected {
        pose,
        nominal_q,
        q,
        configuration,
        status_turn,
        before,
        after,
    })
}

/// A joint target corrected (`--joints`): the joint values `q` taught on the nominal controller
/// name the pose `T = FK_nominal(q)` of `tool`; the calibrated model's joint values for `T` on
/// the same branch (a 6R arm's configuration, else the solution nearest `q`) are returned, with
/// the predicted error of `q` at `T` before (mm, rad).
pub fn correct_joints(models: &FilterModels, q: &[f64], tool: &Pose) -> Result<(Vec<f64>, (f64, f64)), String> {
    let (cal, nom) = models.with_tool(tool);
    let target = nom
        .forward(q)
        .map_err(|e| format!("the nominal model's forward kinematics fails here: {e}"))?;
    let starts = crate::compensate::fixed_starts(&models.inputs, crate::compensate::COMPENSATION_STARTS);
    let branches = models.branches.as_ref();
    let conf = branches.and_then(|b| b.of(q).ok());
    let same_branch = |x: &[f64]| match (conf, branches) {
        (Some(c), Some(b)) => b.of(x).is_ok_and(|k| k.cfx == c.cfx),
        _ => true,
    };
    let mut seeds = vec![q.to_vec()];
    seeds.extend(starts.iter().cloned());
    let corrected = solve::solve(&*cal, &models.inputs, &target, &seeds, q, &same_branch).map_err(|e| match e {
        solve::SolveError::OtherBranch => {
            "configuration flip: the calibrated model reaches this pose only on another configuration".to_string()
        }
        solve::SolveError::Kin(e) => format!("the calibrated model cannot reach this pose on its branch: {e}"),
    })?;
    let before = commanded_error(cal.task(), &target, &cal.forward(q).map_err(|e| e.to_string())?);
    Ok((corrected, before))
}

/// Options of [`filter_program`].
#[derive(Debug, Clone, PartialEq)]
pub struct FilterOptions {
    /// Keep going past targets that cannot be corrected (they are left as they are and listed).
    pub force: bool,
    /// The program's tool where the format has none (CSV targets), or before the program sets
    /// one (KRL): in the mechanism's tool frame.
    pub tool: Pose,
    /// KRL: `TOOL_DATA[n]` the files do not assign (the flange frame).
    pub tool_data: Vec<(u32, Pose)>,
    /// KRL: `BASE_DATA[n]` the files do not assign (the robot's base frame).
    pub base_data: Vec<(u32, Pose)>,
    /// G-code and CSV targets: split each straight move so that the machine, driven by the
    /// nominal controller between corrected points, stays within this distance (mm) of the
    /// commanded line (judged on the calibrated model); G-code arcs are linearised within it.
    /// `None`: nothing is split, the largest deviation is reported, arcs are linearised within
    /// [`DEFAULT_ARC_TOLERANCE_MM`].
    pub max_deviation_mm: Option<f64>,
    /// Correct joint targets too (URScript joint lists, RAPID `jointtarget`s) with
    /// [`correct_joints`]; otherwise they are left as they are, with a note.
    pub joints: bool,
}

/// The tolerance (mm) G-code arcs are linearised within when no
/// [`FilterOptions::max_deviation_mm`] is given: half of it for the chords.
pub const DEFAULT_ARC_TOLERANCE_MM: f64 = 0.01;

/// The paths between a program's targets (G-code, CSV targets: straight moves between them).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct PathReport {
    /// Straight moves judged (between two corrected targets).
    pub moves: usize,
    /// Straight moves the nominal controller's inverse kinematics could not follow from one
    /// target to the next (not judged; with a tolerance, an error).
    pub unjudged: usize,
    /// Points added to hold [`FilterOptions::max_deviation_mm`].
    pub added_points: usize,
    /// The largest distance (mm) of the machine's path (the calibrated model driven by the
    /// nominal controller along its straight lines between the corrected points, sampled) from
    /// the commanded line, after any splitting.
    pub largest_deviation_mm: f64,
    /// The line of that move.
    pub largest_deviation_line: usize,
    /// G-code arcs linearised.
    pub arcs: usize,
    /// The chords they became.
    pub arc_chords: usize,
    /// The largest distance of a chord from its arc (mm).
    pub largest_chord_error_mm: f64,
}

impl Default for FilterOptions {
    fn default() -> Self {
        FilterOptions {
            force: false,
            tool: Pose::identity(),
            tool_data: Vec::new(),
            base_data: Vec::new(),
            max_deviation_mm: None,
            joints: false,
        }
    }
}

/// One corrected target of a program.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TargetReport {
    /// 1-based line of the target in the program.
    pub line: usize,
    /// Its name (a robtarget's, or the row's id) or `inline`.
    pub name: String,
    /// Predicted error without the filter: position (mm) and orientation (deg).
    pub before_mm: f64,
    /// See `before_mm`.
    pub before_deg: f64,
    /// Predicted error with the filter (mm, deg).
    pub after_mm: f64,
    /// See `after_mm`.
    pub after_deg: f64,
    /// How far the target moved (mm, deg).
    pub shift_mm: f64,
    /// See `shift_mm`.
    pub shift_deg: f64,
}

/// A filtered program.
#[derive(Debug, Clone)]
pub struct FilteredProgram {
    /// The program's new text.
    pub text: String,
    /// The new text of its companion file (a KRL program's `.dat`), if it has one.
    pub companion: Option<String>,
    /// Its format.
    pub format: Format,
    /// The targets corrected, in the order of the program.
    pub targets: Vec<TargetReport>,
    /// Targets that could not be corrected and were left as they were (only with
    /// [`FilterOptions::force`]): one line each, file and line first.
    pub uncorrected: Vec<String>,
    /// What was left as it was on purpose (joint targets, targets computed at run time, unused
    /// declarations): one line each.
    pub notes: Vec<String>,
    /// The paths between targets, where the format's moves are straight lines between them
    /// (G-code, CSV targets).
    pub paths: Option<PathReport>,
}

/// Filter a program's text (`path` names it in messages) in `format`; `companion` is the file
/// that goes with it (a KRL `.src`'s `.dat`: path and text), if any.
pub fn filter_program(
    path: &Path,
    text: &str,
    companion: Option<(&Path, &str)>,
    format: Format,
    models: &FilterModels,
    opts: &FilterOptions,
) -> Result<FilteredProgram, FilterError> {
    if let Some(d) = opts.max_deviation_mm {
        if !(d.is_finite() && d > 0.0) {
            return Err(FilterError::Options(format!(
                "--max-deviation-mm {d}: expected a distance above 0 mm"
            )));
        }
        if !matches!(format, Format::Gcode | Format::Csv) {
            return Err(FilterError::Options(format!(
                "--max-deviation-mm splits the straight moves of G-code and CSV targets; a {format:?} program's moves are not split (the largest deviation between its targets is not judged either)"
            )));
        }
    }
    match format {
        Format::Krl => krl::filter_krl(path, text, companion, models, opts),
        Format::Gcode => gcode::filter_gcode(path, text, models, opts),
        Format::Csv => csv::filter_csv(path, text, models, opts),
        Format::Rapid => rapid::filter_rapid(path, text, models, opts),
        Format::UrScript => urscript::filter_urscript(path, text, models, opts),
    }
}

/// [`correct_located`]'s result.
pub(crate) struct Located {
    /// Each target's correction (`None`: left as it was, with `force`).
    pub corrected: Vec<Option<Corrected>>,
    /// The reports of those corrected.
    pub reports: Vec<TargetReport>,
    /// One line for each left as it was.
    pub uncorrected: Vec<String>,
}

/// Corrections of a program's targets, each with its file, line and name: the reports of those
/// corrected, and the lines of those that were not (an error unless `force`).
pub(crate) fn correct_located(
    models: &FilterModels,
    targets: &[Target],
    located: &[(PathBuf, usize, String)],
    force: bool,
) -> Result<Located, FilterError> {
    let results = correct(models, targets);
    let (mut kept, mut reports, mut uncorrected) = (Vec::new(), Vec::new(), Vec::new());
    for ((r, t), (path, line, name)) in results.into_iter().zip(targets).zip(located) {
        match r {
            Ok(c) => {
                let e = crate::se3::pose_error(&c.pose, &t.pose);
                reports.push(TargetReport {
                    line: *line,
                    name: name.clone(),
                    before_mm: c.before.0,
                    before_deg: c.before.1.to_degrees(),
                    after_mm: c.after.0,
                    after_deg: c.after.1.to_degrees(),
                    shift_mm: crate::se3::lin(&e).norm(),
                    shift_deg: crate::se3::ang(&e).norm().to_degrees(),
                });
                kept.push(Some(c));
            }
            Err(message) => {
                let message = format!("{name}: {message}");
                if !force {
                    return Err(FilterError::Target {
                        path: path.clone(),
                        line: *line,
                        message,
                    });
                }
                uncorrected.push(format!("{}:{line}: {message}", path.display()));
                kept.push(None);
            }
        }
    }
    Ok(Located {
        corrected: kept,
        reports,
        uncorrected,
    })
}
