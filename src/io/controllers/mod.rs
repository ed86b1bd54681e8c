//! The files controllers read their kinematics from: a calibrated model projected onto a
//! controller's parameter set and written in its format ([`export`]), and such a file read back
//! as a model file ([`import`]), so a calibration starts from the parameters a controller has.
//!
//! | format | controller | module |
//! |---|---|---|
//! | `ur-yaml` | Universal Robots' `ur_description` / ROS driver kinematics YAML | [`ur_yaml`] |
//! | `linuxcnc-hexapod` | LinuxCNC `genhexkins` HAL parameters | [`linuxcnc_hexapod`] |
//! | `klipper-delta` | Klipper `printer.cfg` `[printer] kinematics: delta` and `[stepper_*]` | [`klipper_delta`] |
//!
//! Each controller's model is smaller than kinecal's: [`Export::projection`] says what the
//! written parameters leave — the largest and RMS tool-pose difference between the model and
//! the controller's kinematics with the written parameters (as printed, over configurations
//! spread over the workspace) and which error parameters the controller cannot represent.
//! Numbers are written with a fixed number of decimals, so a file read back and written again
//! is the same byte for byte. Conventions, units and frames: each module and docs/controllers.md.
pub mod bed;
pub mod klipper_delta;
pub mod linuxcnc_hexapod;
pub mod ur_yaml;

use super::model_file::ModelFile;
use crate::error::KinError;
use crate::model::projection::PoseDifference;
use thiserror::Error;

/// Configurations compared when a projection is measured.
pub const PROJECTION_POSES: usize = 500;
/// The seed those configurations are drawn from.
pub const PROJECTION_SEED: u64 = 47_001;

/// A controller whose kinematics file kinecal writes and reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Controller {
    /// Universal Robots kinematics YAML (`ur_description`, ROS driver).
    UrYaml,
    /// LinuxCNC `genhexkins` HAL parameters.
    LinuxcncHexapod,
    /// Klipper linear delta `printer.cfg` sections.
    KlipperDelta,
}

impl Controller {
    /// The format's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Controller::UrYaml => "ur-yaml",
            Controller::LinuxcncHexapod => "linuxcnc-hexapod",
            Controller::KlipperDelta => "klipper-delta",
        }
    }

    /// The controller called `name` ([`Controller::name`]).
    pub fn parse(name: &str) -> Option<Controller> {
        [Controller::UrYaml, Controller::LinuxcncHexapod, Controller::KlipperDelta]
            .into_iter()
            .find(|c| c.name() == name)
    }
}

/// Why a model cannot be written for a controller, or a controller file cannot be read.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ControllerError {
    /// A malformed file: the line (1-based) and what is wrong there.
    #[error("line {line}: {message}")]
    Parse {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The model is not of the kind the controller describes.
    #[error("{0}")]
    Unsupported(String),
    /// The kinematics failed while the projection was measured.
    #[error("{0}")]
    Kinematics(#[from] KinError),
}

impl ControllerError {
    /// The error as one line about the file `path` (`path:line: message` for a malformed file).
    pub fn at(&self, path: &str) -> String {
        match self {
            ControllerError::Parse { line, message } => format!("{path}:{line}: {message}"),
            other => format!("{path}: {other}"),
        }
    }
}

/// What writing a model into a controller's parameter set leaves out.
#[derive(Debug, Clone, PartialEq)]
pub struct Projection {
    /// Tool-pose difference between the model and the controller's kinematics with the
    /// parameters as written, at [`PROJECTION_POSES`] configurations spread over the workspace
    /// (drawn from [`PROJECTION_SEED`]), with the frames of [`Projection::not_written`] applied.
    pub difference: PoseDifference,
    /// Error parameters (or geometry) of the model the controller cannot represent, each a line.
    pub not_represented: Vec<String>,
    /// The largest residual (mm) of the controller's own equations over the least-squares fit
    /// (strut lengths, carriage heights), where the projection is a fit.
    pub fit_residual_mm: Option<f64>,
    /// Frames the controller's file has no place for (measurement frame, tool offsets), each a
    /// line saying where they go.
    pub not_written: Vec<String>,
}

/// A controller file and what its projection leaves.
#[derive(Debug, Clone, PartialEq)]
pub struct Export {
    /// The file's text.
    pub text: String,
    /// What the written parameters leave.
    pub projection: Projection,
}

/// Write `file` (nominal or calibrated) for `controller`: see the module docs.
pub fn export(file: &ModelFile, controller: Controller) -> Result<Export, ControllerError> {
    match controller {
        Controller::UrYaml => ur_yaml::export(file),
        Controller::LinuxcncHexapod => linuxcnc_hexapod::export(file),
        Controller::KlipperDelta => klipper_delta::export(file),
    }
}

/// Read a controller file (`text`) as a model file.
pub fn import(text: &str, controller: Controller) -> Result<ModelFile, ControllerError> {
    match controller {
        Controller::UrYaml => ur_yaml::import(text),
        Controller::LinuxcncHexapod => linuxcnc_hexapod::import(text),
        Controller::KlipperDelta => klipper_delta::import(text),
    }
}

/// `v` with `decimals` decimals, never `-0.…`.
pub(crate) fn fixed(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// A finite number from `s`, or a parse error at `line` naming `what`.
pub(crate) fn number(s: &str, line: usize, what: &str) -> Result<f64, ControllerError> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(ControllerError::Parse {
            line,
            message: format!("{what}: expected a finite number, got '{}'", s.trim()),
        }),
    }
}

/// The text of `line` without a `#` comment, trimmed at the end.
pub(crate) fn strip_comment(line: &str) -> &str {
    line.split('#').next().unwrap_or("").trim_end()
}
