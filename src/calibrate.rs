//! One call from files to a calibrated model: [`calibrate`].
//!
//! model file + data set (+ validation set) + [`CalibrationOptions`] →
//! frame registration ([`crate::register`]) → iterated identification ([`crate::identify`]) →
//! the calibrated model file (with its `[frames]` and `[provenance]`), the report with its verdict
//! ([`CalibrationReport`]), from which the command line, the JSON output and the HTML are written.
use crate::error::CalibError;
use crate::identify::{identify, Identification, Loss, Method, Options};
use crate::io::data_file::DataSet;
use crate::io::model_file::{select_params, ModelFile};
use crate::io::IoError;
use crate::measure::{Measurement, Noise};
use crate::model::framed::{Framed, FRAME_PARAMS};
use crate::model::Mechanism;
use crate::params::Unit;
use crate::register::{register, Registration};
use crate::report::CalibrationReport;
use crate::se3::Pose;
use std::f64::consts::PI;
use thiserror::Error;

/// Where the data's frames come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FrameMode {
    /// Find the measurement frame and the tool frame from the data ([`crate::register`]) and
    /// identify them with the geometry (the default: data straight from a tracker, in its frame).
    #[default]
    Estimate,
    /// The data are in the model's own frames (simulated data, or data already transformed): use
    /// the model file as it is.
    Model,
}

/// Default Huber threshold of [`calibrate`], in robust standard deviations of the per-pose
/// residuals: Gaussian data are untouched, blunders of many standard deviations lose their pull.
pub const DEFAULT_HUBER_K: f64 = 5.0;

/// Rounds of setting blunders aside and fitting again.
const MAX_REJECTION_ROUNDS: usize = 5;

/// Options of [`calibrate`].
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationOptions {
    /// Identification algorithm.
    pub method: Method,
    /// Measurement noise: the weights, and the scale the residual is judged against.
    pub noise: Noise,
    /// Re-estimate the position / orientation noise from the residuals.
    pub reweight: bool,
    /// Where the frames come from.
    pub frames: FrameMode,
    /// Loss on each pose's residual (Huber against blunders).
    pub loss: Loss,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        CalibrationOptions {
            method: Method::GaussNewton,
            noise: Noise::default(),
            reweight: false,
            frames: FrameMode::Estimate,
            loss: Loss::Huber { k: DEFAULT_HUBER_K },
        }
    }
}

/// Errors of [`calibrate`]: a file problem (with its file and line) or a computation problem.
#[derive(Debug, Error)]
pub enum CalibrateError {
    /// A file problem.
    #[error(transparent)]
    Io(#[from] IoError),
    /// A computation problem not tied to one line of a file.
    #[error(transparent)]
    Calib(#[from] CalibError),
}

/// What [`calibrate`] produced.
pub struct Calibration {
    /// The calibrated model file (geometry, frames, noise, provenance status and reasons; the
    /// caller adds the command line).
    pub model_file: ModelFile,
    /// The identification itself (the calibrated mechanism is `identification.model`).
    pub identification: Identification<Box<dyn Mechanism>>,
    /// The starting model: the nominal geometry in the registered frames.
    pub start: Box<dyn Mechanism>,
    /// The frame registration, when the frames were estimated.
    pub registration: Option<Registration>,
    /// Free parameters, in priority order (indices into the calibrated mechanism's parameters).
    pub free: Vec<usize>,
    /// The report (statistics, parameter table, verdict).
    pub report: CalibrationReport,
    /// Ids of the poses set aside as blunders: beyond the Huber threshold of the robust loss at
    /// the solution, then left out of the final fit.
    pub blunders: Vec<i64>,
}

/// Calibrate `model` from `data` (and judge it on `validation`): see the module docs.
pub fn calibrate(
    model: &ModelFile,
    data: &DataSet,
    validation: Option<&DataSet>,
    opts: &CalibrationOptions,
) -> Result<Calibration, CalibrateError> {
    plausible_angles(model, data)?;
    let (start, free, registration): (Box<dyn Mechanism>, Vec<usize>, Option<Registration>) = match opts.frames {
        FrameMode::Model => (model.build(), model.free_indices()?, None),
        FrameMode::Estimate => {
            let inner = model.mechanism.build();
            let inner_free = select_params(&inner.params(), &model.free, &model.fixed).map_err(|pat| IoError::Invalid {
                path: format!("model '{}'", model.name).into(),
                message: format!("calibration pattern '{pat}' matches no parameter"),
            })?;
            let tool_guess = model.frames.map_or(Pose::identity(), |f| f.tool);
            let reg = register(&inner, &data.measurements, &tool_guess).map_err(|e| data.locate(e))?;
            let framed = Framed::new(inner, reg.measurement, reg.tool);
            let mut free: Vec<usize> = (0..FRAME_PARAMS).collect();
            free.extend(inner_free.iter().map(|i| i + FRAME_PARAMS));
            (Box::new(framed), free, Some(reg))
        }
    };
    let id_opts = Options {
        method: opts.method,
        noise: opts.noise,
        reweight: opts.reweight,
        free: Some(free.clone()),
        loss: opts.loss,
        ..Options::default()
    };
    let mut identification = identify(&start, &data.measurements, &id_opts).map_err(|e| data.locate(e))?;
    // Blunders: poses the robust loss down-weighted are set aside and the fit repeated on the rest,
    // until the set is stable (a Huber fit alone still lets many blunders pull together).
    let mut kept: Vec<usize> = (0..data.measurements.len()).collect();
    for _ in 0..MAX_REJECTION_ROUNDS {
        let rejected: Vec<usize> = kept
            .iter()
            .zip(&identification.pose_weights)
            .filter(|(_, w)| **w < 1.0)
            .map(|(i, _)| *i)
            .collect();
        if rejected.is_empty() {
            break;
        }
        kept.retain(|i| !rejected.contains(i));
        let subset: Vec<Measurement> = kept.iter().map(|&i| data.measurements[i].clone()).collect();
        let again = identify(&identification.model, &subset, &id_opts).map_err(|e| match e {
            CalibError::Kinematics { pose, source } => data.locate(CalibError::Kinematics { pose: kept[pose], source }),
            other => data.locate(other),
        })?;
        let delta = identification.delta.clone() + &again.delta;
        identification = Identification { delta, ..again };
    }
    let set_aside: Vec<usize> = (0..data.measurements.len()).filter(|i| !kept.contains(i)).collect();
    let mut calibrated = model.with_geometry_of(&*identification.model).map_err(|message| IoError::Invalid {
        path: format!("model '{}'", model.name).into(),
        message,
    })?;
    calibrated.description = Some(format!("calibrated from '{}' on {}", model.name, data.path.display()));
    calibrated.noise = Some(identification.noise);
    let validation_name = validation.map(|v| v.path.display().to_string());
    let mut report = CalibrationReport::new(
        &start,
        &identification,
        &free,
        &format!("{:?}", opts.method),
        &data.path.display().to_string(),
        &data.measurements,
        validation.map(|v| (validation_name.as_deref().unwrap_or("validation"), v.measurements.as_slice())),
    )?;
    report.assess(&opts.noise, &model.tolerances);
    let blunders = set_aside.iter().map(|&i| data.ids[i]).collect();
    Ok(Calibration {
        blunders,
        model_file: calibrated,
        identification,
        start,
        registration,
        free,
        report,
    })
}

/// Angle columns whose every value, read in degrees, stays within ±π (what radians in a degree
/// column give) while the joint's limits allow far more, are almost certainly in the wrong unit.
fn plausible_angles(model: &ModelFile, data: &DataSet) -> Result<(), IoError> {
    if data.measurements.len() < 10 {
        return Ok(());
    }
    let inputs = model.inputs();
    let suspicious: Vec<&str> = inputs
        .iter()
        .enumerate()
        .filter(|(_, i)| i.unit == Unit::Angle)
        .filter(|(_, i)| i.limits.is_none_or(|(lo, hi)| hi - lo > 4.0 * PI.to_radians()))
        .filter(|(k, _)| {
            let max = data.measurements.iter().map(|m| m.q[*k].abs()).fold(0.0, f64::max);
            max > 0.0 && max <= PI.to_radians() * 1.0001
        })
        .map(|(_, i)| i.name.as_str())
        .collect();
    if suspicious.len() >= 2 && suspicious.len() * 2 >= inputs.iter().filter(|i| i.unit == Unit::Angle).count() {
        return Err(IoError::Invalid {
            path: data.path.clone(),
            message: format!(
                "the angle columns {} never leave ±3.1416 degrees: they look like radians; name them {}_rad (or convert them to degrees)",
                suspicious.join(", "),
                suspicious[0]
            ),
        });
    }
    Ok(())
}
