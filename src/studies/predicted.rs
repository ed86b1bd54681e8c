//! Does the accuracy a calibration predicts hold? One virtual prototype of a built-in model (its
//! geometric errors drawn once), seen by a tracker 2 m away through a tool 150 mm from the
//! flange, measured at the same configurations in `draws` noise draws and calibrated each time
//! ([`crate::calibrate::calibrate`], its default options with the stated noise). At held-out
//! configurations the spread of the calibrated models' predicted positions over the draws (RMS
//! 3-D distance from their mean) is set beside the σ each calibrated model file predicts there
//! ([`crate::predict::accuracy_of_file`], its median over the draws).
use crate::calibrate::{calibrate, CalibrateError, CalibrationOptions};
use crate::error::CalibError;
use crate::io::builtin;
use crate::io::data_file::DataSet;
use crate::io::IoError;
use crate::measure::Noise;
use crate::model::framed::Framed;
use crate::model::Mechanism;
use crate::se3::{self, Pose};
use crate::simulate::{measure, random_configurations, virtual_prototype, ObservationKind};
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

/// What [`predicted_against_spread`] runs.
#[derive(Debug, Clone, PartialEq)]
pub struct SpreadOptions {
    /// A built-in model (`irb120`, `pm5`, …).
    pub model: String,
    /// Noise draws (calibrations).
    pub draws: usize,
    /// Identification poses (the same configurations in every draw).
    pub poses: usize,
    /// Held-out configurations the predictions are compared at.
    pub held_out: usize,
    /// The prototype's geometric errors: uniform within ± this (mm) on lengths.
    pub error_mm: f64,
    /// … and ± this (degrees) on angles.
    pub error_deg: f64,
    /// The measurement noise (stated to the calibration as it is).
    pub noise: Noise,
    /// Seed of the prototype and the configurations; draw `k` uses `seed + 1 + k`.
    pub seed: u64,
}

impl SpreadOptions {
    /// `draws` draws on `model`: 60 identification poses, 50 held out, errors 0.5 mm / 0.1°,
    /// noise 20 µm / 0.02°, seed 7.
    pub fn new(model: &str, draws: usize) -> Self {
        SpreadOptions {
            model: model.into(),
            draws,
            poses: 60,
            held_out: 50,
            error_mm: 0.5,
            error_deg: 0.1,
            noise: Noise::default(),
            seed: 7,
        }
    }
}

/// Predicted against observed at one held-out configuration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PoseSpread {
    /// Median over the draws of the predicted position σ (mm, `sqrt(trace Σ_position)`).
    pub predicted_mm: f64,
    /// RMS 3-D distance of the calibrated models' predicted positions from their mean (mm).
    pub observed_mm: f64,
    /// Median predicted orientation σ (degrees).
    pub predicted_deg: f64,
    /// RMS rotation of the predicted orientations from their mean (degrees).
    pub observed_deg: f64,
}

impl PoseSpread {
    /// `predicted / observed` of the position.
    pub fn ratio(&self) -> f64 {
        self.predicted_mm / self.observed_mm
    }
}

/// The outcome of [`predicted_against_spread`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SpreadCheck {
    /// Per held-out configuration.
    pub poses: Vec<PoseSpread>,
    /// Draws whose calibration succeeded (the others are left out).
    pub draws: usize,
}

impl SpreadCheck {
    /// The smallest and largest [`PoseSpread::ratio`].
    pub fn ratio_range(&self) -> (f64, f64) {
        let r = self.poses.iter().map(PoseSpread::ratio);
        (r.clone().fold(f64::INFINITY, f64::min), r.fold(0.0, f64::max))
    }

    /// The same of the orientation.
    pub fn orientation_ratio_range(&self) -> (f64, f64) {
        let r = self.poses.iter().map(|p| p.predicted_deg / p.observed_deg);
        (r.clone().fold(f64::INFINITY, f64::min), r.fold(0.0, f64::max))
    }
}

/// The tracker of the study: 2 m away, turned 120° about an oblique axis.
fn tracker() -> Pose {
    se3::pose_from_parts(
        Vector3::new(2000.0, -700.0, 400.0),
        Vector3::new(1.0, 2.0, -0.5).normalize() * 120f64.to_radians(),
    )
}

/// The measured tool: 150 mm from the flange, turned.
fn tool() -> Pose {
    se3::pose_from_parts(Vector3::new(90.0, -80.0, 90.0), Vector3::new(0.3, -0.2, 0.5))
}

/// Run the study ([module docs](self)).
pub fn predicted_against_spread(opts: &SpreadOptions) -> Result<SpreadCheck, CalibrateError> {
    let invalid = |message: String| IoError::Invalid {
        path: opts.model.clone().into(),
        message,
    };
    let file = builtin::model_file(&opts.model).ok_or_else(|| invalid("no built-in model of this name".into()))?;
    let nominal = file.build();
    let free = file.free_indices()?;
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let (proto, _) = virtual_prototype(&nominal, &free, opts.error_mm, opts.error_deg.to_radians(), &mut rng);
    let truth = Framed::new(proto, tracker(), tool());
    let inputs = file.inputs();
    let kin = |e: crate::error::KinError| CalibError::InvalidOption(format!("configurations: {e}"));
    let ident = random_configurations(&*nominal, &inputs, opts.poses, &mut rng).map_err(kin)?;
    let held = random_configurations(&*nominal, &inputs, opts.held_out, &mut rng).map_err(kin)?;
    let cal_opts = CalibrationOptions {
        noise: opts.noise,
        ..CalibrationOptions::default()
    };
    type Draw = (Vec<Pose>, Vec<(f64, f64)>);
    let draws: Vec<Option<Draw>> = (0..opts.draws)
        .into_par_iter()
        .map(|k| -> Result<Option<Draw>, CalibrateError> {
            let mut rng = ChaCha8Rng::seed_from_u64(opts.seed + 1 + k as u64);
            let data = measure(&truth, &ident, ObservationKind::Pose, Some(&opts.noise), &mut rng)?;
            let Ok(cal) = calibrate(&file, &DataSet::from_measurements("draw", data), None, &cal_opts) else {
                return Ok(None);
            };
            let model = cal.model_file.build();
            let poses = held.iter().map(|q| model.forward(q)).collect::<Result<Vec<_>, _>>();
            let Ok(poses) = poses else { return Ok(None) };
            let acc = crate::predict::accuracy_of_file(&cal.model_file, "draw", &held)
                .map_err(|e| CalibError::InvalidOption(format!("prediction: {e}")))?;
            Ok(Some((
                poses,
                acc.poses.iter().map(|p| (p.position_mm, p.orientation_deg)).collect(),
            )))
        })
        .collect::<Result<_, _>>()?;
    let ok: Vec<&Draw> = draws.iter().flatten().collect();
    if ok.len() < 2 {
        return Err(invalid(format!("{} of {} draws calibrated: no spread to compare", ok.len(), opts.draws)).into());
    }
    let n = ok.len() as f64;
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let poses = (0..held.len())
        .map(|i| {
            let mean = ok.iter().map(|d| d.0[i].translation.vector).sum::<Vector3<f64>>() / n;
            let observed_mm = (ok.iter().map(|d| (d.0[i].translation.vector - mean).norm_squared()).sum::<f64>() / n).sqrt();
            let r0 = ok[0].0[i].rotation;
            let w: Vec<Vector3<f64>> = ok.iter().map(|d| se3::so3_log(&(d.0[i].rotation * r0.inverse()))).collect();
            let wm = w.iter().sum::<Vector3<f64>>() / n;
            let observed_deg = (w.iter().map(|v| (v - wm).norm_squared()).sum::<f64>() / n).sqrt().to_degrees();
            PoseSpread {
                predicted_mm: median(ok.iter().map(|d| d.1[i].0).collect()),
                observed_mm,
                predicted_deg: median(ok.iter().map(|d| d.1[i].1).collect()),
                observed_deg,
            }
        })
        .collect();
    Ok(SpreadCheck { poses, draws: ok.len() })
}
