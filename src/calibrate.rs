//! One call from files to a calibrated model: [`calibrate`].
//!
//! model file + data set (+ validation set) + [`CalibrationOptions`] →
//! frame registration ([`crate::register`]) → iterated identification ([`crate::identify`]) →
//! the calibrated model file (with its `[frames]` and `[provenance]`), the report with its verdict
//! ([`CalibrationReport`]), from which the command line, the JSON output and the HTML are written.
mod variants;

use crate::error::CalibError;
use crate::identify::{identify, Agreement, Identification, Loss, Method, Options};
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

/// How three reflector centres per pose (`m1x_mm … m3z_mm`) enter the identification.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ReflectorFit {
    /// As the frame they define (6 residual rows per pose; the default).
    #[default]
    Frame,
    /// As three measured points (9 rows per pose, each reflector at its mean position in the
    /// reflector frame): the tracker's own measurement model. Validation stays on the frame.
    Points,
}

/// Default Huber threshold of [`calibrate`], in robust standard deviations of the per-pose
/// residuals: Gaussian data are untouched, blunders of many standard deviations lose their pull.
pub const DEFAULT_HUBER_K: f64 = 5.0;

/// Default number of starts of [`calibrate`] (see [`CalibrationOptions::starts`]).
pub const DEFAULT_STARTS: u64 = 3;

/// A pose is set aside as a blunder when the Huber loss weighs it below this, i.e. when its
/// residual is beyond twice the Huber threshold. Poses between one and two thresholds are only
/// down-weighted: real machines leave a heavy tail of residuals the geometric model cannot
/// explain (compliance, backlash), and those poses are data, not blunders.
pub const BLUNDER_WEIGHT: f64 = 0.5;

/// Rounds of setting blunders aside and fitting again.
const MAX_REJECTION_ROUNDS: usize = 5;

/// A start agrees with the first fit once its predictions come this close, as a fraction of
/// the stated position noise (see [`crate::identify::Options::agree_with`]).
pub const START_AGREEMENT: f64 = 0.01;

/// Poses the other starts run on at most (an evenly spread subset of larger sets).
pub const START_POSES: usize = 20_000;

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
    /// Starts of the identification: the registered (or model) start, plus `starts − 1` starts
    /// whose geometric parameters are perturbed at random within a third of the model's
    /// tolerances. The best is kept; predictions that disagree by more than the stated position
    /// noise fail the calibration (a wrong minimum, or data that do not determine the geometry).
    pub starts: u64,
    /// Seed of the perturbed starts.
    pub seed: u64,
    /// How reflector triples enter the fit (ignored for other measurement kinds).
    pub reflectors: ReflectorFit,
    /// For a model with joint terms: fit the geometric model alone and each kind of term alone
    /// too, for the report's comparison ([`crate::report::CalibrationReport::variants`]).
    pub compare_terms: bool,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        CalibrationOptions {
            method: Method::GaussNewton,
            noise: Noise::default(),
            reweight: false,
            frames: FrameMode::Estimate,
            loss: Loss::Huber { k: DEFAULT_HUBER_K },
            starts: DEFAULT_STARTS,
            seed: 1,
            reflectors: ReflectorFit::Frame,
            compare_terms: true,
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
    /// What each start reached (the first is the registered start).
    pub starts: Vec<StartOutcome>,
}

/// The outcome of one start of [`calibrate`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StartOutcome {
    /// A-posteriori standard deviation of unit weight reached.
    pub sigma0: f64,
    /// Whether that identification converged.
    pub converged: bool,
    /// Largest distance (mm) between this start's predicted tool positions and the kept
    /// solution's, over the identification poses.
    pub max_difference_mm: f64,
}

/// A random perturbation of the free, non-frame geometric parameters: uniform within a third of
/// the tolerance of each parameter's unit (lengths in mm, angles in rad).
fn perturbation(model: &dyn Mechanism, free: &[usize], tol: &crate::io::model_file::Tolerances, seed: u64) -> nalgebra::DVector<f64> {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let params = model.params();
    let mut d = nalgebra::DVector::zeros(params.len());
    for &i in free {
        if params[i].group.ends_with(" frame") {
            continue;
        }
        let s = match params[i].unit {
            Unit::Length => tol.length_mm / 3.0,
            Unit::Angle => tol.angle_deg.to_radians() / 3.0,
            _ => 0.0,
        };
        d[i] = rng.random_range(-s..=s);
    }
    d
}

/// Largest distance (mm) between the tool positions two models predict at the poses of `data`.
fn max_prediction_difference(a: &dyn Mechanism, b: &dyn Mechanism, data: &[Measurement]) -> f64 {
    data.iter()
        .map(|m| match (a.forward(&m.q), b.forward(&m.q)) {
            (Ok(x), Ok(y)) => (x.translation.vector - y.translation.vector).norm(),
            _ => f64::INFINITY,
        })
        .fold(0.0, f64::max)
}

/// Calibrate `model` from `data` (and judge it on `validation`): see the module docs.
pub fn calibrate(
    model: &ModelFile,
    data: &DataSet,
    validation: Option<&DataSet>,
    opts: &CalibrationOptions,
) -> Result<Calibration, CalibrateError> {
    plausible_angles(model, data)?;
    let measurements: Vec<Measurement> = match opts.reflectors {
        ReflectorFit::Frame => data.measurements.clone(),
        ReflectorFit::Points => data.reflector_points().ok_or_else(|| IoError::Invalid {
            path: data.path.clone(),
            message: format!(
                "fitting reflector points needs three reflector centres per pose (m1x_mm … m3z_mm); this file gives a {}",
                data.format.describe()
            ),
        })?,
    };
    let (start, free, registration): (Box<dyn Mechanism>, Vec<usize>, Option<Registration>) = match opts.frames {
        FrameMode::Model => (model.build(), model.free_indices()?, None),
        FrameMode::Estimate => {
            let inner = model.mechanism.build();
            let inner_free = select_params(&inner.params(), &model.free, &model.fixed).map_err(|pat| IoError::Invalid {
                path: format!("model '{}'", model.name).into(),
                message: format!("calibration pattern '{pat}' matches no parameter"),
            })?;
            let tool_guess = model.frames.map_or(Pose::identity(), |f| f.tool);
            let reg = register(&inner, &measurements, &tool_guess).map_err(|e| data.locate(e))?;
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
    let mut identification = identify(&start, &measurements, &id_opts).map_err(|e| data.locate(e))?;
    // Blunders: poses the robust loss down-weighted are set aside and the fit repeated on the rest,
    // until the set is stable (a Huber fit alone still lets many blunders pull together).
    let mut kept: Vec<usize> = (0..measurements.len()).collect();
    for _ in 0..MAX_REJECTION_ROUNDS {
        let rejected: Vec<usize> = kept
            .iter()
            .zip(&identification.pose_weights)
            .filter(|(_, w)| **w < BLUNDER_WEIGHT)
            .map(|(i, _)| *i)
            .collect();
        if rejected.is_empty() {
            break;
        }
        let rejected: std::collections::HashSet<usize> = rejected.into_iter().collect();
        kept.retain(|i| !rejected.contains(i));
        let subset: Vec<Measurement> = kept.iter().map(|&i| measurements[i].clone()).collect();
        let again = identify(&identification.model, &subset, &id_opts).map_err(|e| match e {
            CalibError::Kinematics { pose, source } => data.locate(CalibError::Kinematics { pose: kept[pose], source }),
            other => data.locate(other),
        })?;
        let delta = identification.delta.clone() + &again.delta;
        identification = Identification { delta, ..again };
    }
    let mut in_fit = vec![false; data.measurements.len()];
    for &i in &kept {
        in_fit[i] = true;
    }
    let set_aside: Vec<usize> = (0..data.measurements.len()).filter(|&i| !in_fit[i]).collect();
    // Other starts: perturbed geometry, the same frames; the best is kept. They test for other
    // minima, so on large sets they run on an evenly spread subset of START_POSES poses.
    let stride = kept.len().div_ceil(START_POSES).max(1);
    let subset: Vec<Measurement> = kept.iter().step_by(stride).map(|&i| measurements[i].clone()).collect();
    let mut others = Vec::new();
    // A start whose predictions come within a hundredth of the noise of the first fit's has
    // entered its basin: it agrees, and is not iterated to the end.
    let agree_opts = Options {
        agree_with: (opts.starts > 1)
            .then(|| -> Option<Agreement> {
                let positions = subset
                    .iter()
                    .map(|m| identification.model.forward(&m.q).ok().map(|t| t.translation.vector))
                    .collect::<Option<Vec<_>>>()?;
                Some(Agreement {
                    positions,
                    tolerance_mm: START_AGREEMENT * opts.noise.position,
                    identifiability: (stride == 1).then(|| identification.identifiability.clone()),
                })
            })
            .flatten(),
        ..id_opts.clone()
    };
    for k in 1..opts.starts.max(1) as usize {
        let pert = perturbation(&*start, &free, &model.tolerances, opts.seed.wrapping_add(k as u64));
        let mut perturbed = start.box_clone();
        perturbed.retract(&pert);
        // A start that fails outright (a pose out of reach) is a start that did not agree.
        let outcome = identify(&perturbed, &subset, &agree_opts).ok().map(|r| {
            let delta = pert + &r.delta;
            Identification { delta, ..r }
        });
        others.push(outcome);
    }
    // On a subset, the fit on every pose is compared with the other starts on the same poses:
    // polished there first (one or two iterations from its solution).
    let (first, full_fit) = if stride > 1 {
        let on_subset = identify(&identification.model, &subset, &id_opts).ok().map(|r| {
            let delta = identification.delta.clone() + &r.delta;
            Identification { delta, ..r }
        });
        (on_subset, Some(identification))
    } else {
        (Some(identification), None)
    };
    let mut all: Vec<Option<Identification<Box<dyn Mechanism>>>> = vec![first];
    all.extend(others);
    // The registered start is kept unless another reaches a clearly lower residual: equal fits
    // from perturbed starts differ only in how redundant directions were split.
    let sigma = |k: usize| {
        all[k]
            .as_ref()
            .filter(|r| r.converged && r.sigma0.is_finite())
            .map_or(f64::INFINITY, |r| r.sigma0)
    };
    let mut best = 0;
    for k in 1..all.len() {
        if sigma(k) < sigma(best) * (1.0 - 1e-6) || (sigma(best).is_infinite() && sigma(k).is_finite()) {
            best = k;
        }
    }
    let reference = all[best].as_ref().map(|r| r.model.box_clone());
    let starts: Vec<StartOutcome> = std::iter::once(best)
        .chain((0..all.len()).filter(|&k| k != best))
        .map(|k| match (&all[k], &reference) {
            (Some(r), Some(reference)) => StartOutcome {
                sigma0: r.sigma0,
                converged: r.converged,
                max_difference_mm: if k == best {
                    0.0
                } else {
                    max_prediction_difference(&*r.model, &**reference, &subset)
                },
            },
            (Some(r), None) => StartOutcome {
                sigma0: r.sigma0,
                converged: r.converged,
                max_difference_mm: 0.0,
            },
            (None, _) => StartOutcome {
                sigma0: f64::NAN,
                converged: false,
                max_difference_mm: if k == best { 0.0 } else { f64::INFINITY },
            },
        })
        .collect();
    let chosen = all[best].take();
    let identification = match (full_fit, best) {
        (Some(full), 0) => full,
        // Another start won on the subset: its solution, refitted on every kept pose.
        (Some(full), _) => match chosen {
            Some(c) => {
                let kept_data: Vec<Measurement> = kept.iter().map(|&i| measurements[i].clone()).collect();
                let r = identify(&c.model, &kept_data, &id_opts).map_err(|e| data.locate(e))?;
                let delta = c.delta + &r.delta;
                Identification { delta, ..r }
            }
            None => full,
        },
        (None, _) => chosen.expect("the best start has a result"),
    };
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
    // Blunders are reported as such, not again as outliers of the identification set.
    report
        .identification
        .outliers
        .retain(|o| in_fit.get(o.pose).copied().unwrap_or(true));
    report.blunders = set_aside.iter().map(|&i| data.ids[i]).collect();
    report.set_ids(&data.ids, validation.map(|v| v.ids.as_slice()));
    report.set_inputs(&model.inputs());
    report.assess(&opts.noise, &model.tolerances);
    let spread = starts.iter().map(|s| s.max_difference_mm).fold(0.0, f64::max);
    if spread > opts.noise.position {
        let sigmas: Vec<String> = starts.iter().map(|s| format!("{:.3}", s.sigma0)).collect();
        report.fail(format!(
            "the {} starts disagree: their predictions differ by up to {spread:.4} mm (more than the stated noise, {} mm; σ̂₀ {}): the fit has several minima here and the kept one (the lowest) may not be the true geometry: check the nominal model and the tolerances, add or spread the poses, or fix parameters",
            starts.len(),
            opts.noise.position,
            sigmas.join(" / ")
        ));
    }
    if opts.compare_terms {
        report.variants = variants::variants(model, data, validation, opts);
    }
    let blunders = set_aside.iter().map(|&i| data.ids[i]).collect();
    Ok(Calibration {
        blunders,
        model_file: calibrated,
        identification,
        start,
        registration,
        free,
        report,
        starts,
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
