//! The drift scenarios of `examples/drift.rs` and `tests/it/drift.rs`: a virtual prototype (the
//! model file's calibrated parameters off by up to ±0.2 mm / ±0.02°) calibrated from 60 tracker
//! poses (20 µm / 0.02° noise), then measured again unchanged or after one drift: a joint offset,
//! a length, the tool re-mounted.
#![allow(dead_code)]
use kinecal::calibrate::{calibrate, Calibration, CalibrationOptions};
use kinecal::drift::Prior;
use kinecal::io::data_file::DataSet;
use kinecal::io::model_file::ModelFile;
use kinecal::measure::{Measurement, Noise};
use kinecal::params::Unit;
use kinecal::simulate::{random_configurations, random_errors, synthesize, Instrument};
use kinecal::Mechanism;
use nalgebra::DVector;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// One drift of the machine after its calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Drift {
    /// Unchanged.
    None,
    /// Input `input` (index) offset by `amount` (rad or mm): the machine is at `q + amount` when
    /// its controller reads `q`.
    InputOffset { input: usize, amount: f64 },
    /// The parameter `name` of the machine changed by `amount` (mm or rad).
    Parameter { name: &'static str, amount: f64 },
    /// The tool re-mounted `mm` off, in a direction drawn from the draw's seed.
    Tool { mm: f64 },
}

/// A virtual prototype.
pub struct Machine {
    pub file: ModelFile,
    pub truth: Box<dyn Mechanism>,
    pub noise: Noise,
}

/// The prototype of `model` (a built-in name) drawn from `seed`.
pub fn machine(model: &str, seed: u64) -> Machine {
    let file = ModelFile::load_or_builtin(model).expect("built-in model");
    let mut truth = file.build();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let free = file.free_indices().expect("free parameters");
    let delta = random_errors(&*truth, &mut rng, 0.2, 0.02f64.to_radians(), Some(&free));
    truth.retract(&delta);
    Machine {
        file,
        truth,
        noise: Noise::default(),
    }
}

/// The machine after `drift` and the input shift it needs (rng: the tool's direction).
pub fn drifted(m: &Machine, drift: Drift, rng: &mut ChaCha8Rng) -> (Box<dyn Mechanism>, Vec<f64>) {
    let params = m.truth.params();
    let p = params.len();
    let mut shift = vec![0.0; m.file.inputs().len()];
    let mut delta = DVector::zeros(p);
    match drift {
        Drift::None => {}
        Drift::InputOffset { input, amount } => shift[input] = amount,
        Drift::Parameter { name, amount } => {
            let k = params.iter().position(|q| q.name == name).expect("parameter");
            delta[k] = amount;
        }
        Drift::Tool { mm } => {
            let tool: Vec<usize> = (0..p)
                .filter(|&k| params[k].group == "tool" && params[k].unit == Unit::Length)
                .collect();
            let v: Vec<f64> = tool.iter().map(|_| rng.random_range(-1.0..1.0)).collect();
            let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            for (k, x) in tool.iter().zip(&v) {
                delta[*k] = mm * x / n;
            }
        }
    }
    let mut truth = clone_of(m);
    truth.retract(&delta);
    (truth, shift)
}

/// A copy of the prototype (its model file with the prototype's geometry).
fn clone_of(m: &Machine) -> Box<dyn Mechanism> {
    m.file.with_geometry_of(&*m.truth).expect("geometry").build()
}

/// `n` configurations of the model drawn from `rng`.
pub fn configurations(m: &Machine, n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    random_configurations(&*m.file.build(), &m.file.inputs(), n, rng).expect("configurations")
}

/// Tracker poses of `truth` at the commanded `configurations` (the machine at `q + shift`), with
/// the noise `noise` (none: `Noise` with zeros is not allowed, pass `None`).
pub fn measure(
    truth: &dyn Mechanism,
    shift: &[f64],
    configurations: &[Vec<f64>],
    noise: Option<&Noise>,
    rng: &mut ChaCha8Rng,
) -> Vec<Measurement> {
    let at: Vec<Vec<f64>> = configurations
        .iter()
        .map(|q| q.iter().zip(shift).map(|(a, b)| a + b).collect())
        .collect();
    let zero = Noise {
        position: 0.0,
        orientation: 0.0,
        ..Noise::default()
    };
    let mut set = synthesize(truth, at, Instrument::Pose, noise.unwrap_or(&zero), rng, &|_| {})
        .expect("measurable")
        .measurements;
    for (m, q) in set.iter_mut().zip(configurations) {
        m.q = q.clone();
    }
    set
}

/// The calibration of `truth` from `n` poses drawn from `seed`, as a prior.
pub fn calibrated(m: &Machine, truth: &dyn Mechanism, shift: &[f64], n: usize, seed: u64) -> Prior {
    Prior::from_calibration(&calibration(m, truth, shift, n, seed)).expect("prior")
}

/// The calibration of `truth` from `n` poses drawn from `seed`, as the prior its calibrated
/// model file gives once written and read back (what `kinecal check` and `identify --prior` read).
pub fn calibrated_file(m: &Machine, truth: &dyn Mechanism, shift: &[f64], n: usize, seed: u64) -> Prior {
    let cal = calibration(m, truth, shift, n, seed);
    let text = cal.model_file.to_toml().expect("model file");
    let file = ModelFile::load_str(std::path::Path::new("cal.toml"), &text).expect("read back");
    Prior::from_model_file(&file).expect("prior")
}

/// The calibration of `truth` from `n` poses drawn from `seed`.
pub fn calibration(m: &Machine, truth: &dyn Mechanism, shift: &[f64], n: usize, seed: u64) -> Calibration {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let q = configurations(m, n, &mut rng);
    let data = measure(truth, shift, &q, Some(&m.noise), &mut rng);
    let set = DataSet::from_measurements("calibration.csv", data);
    let opts = CalibrationOptions {
        noise: m.noise,
        starts: 1,
        compare_terms: false,
        ..CalibrationOptions::default()
    };
    calibrate(&m.file, &set, None, &opts).expect("calibration")
}

/// RMS position error (mm) of `model` against noise-free poses of `truth`.
pub fn held_out_rms(model: &dyn Mechanism, truth: &dyn Mechanism, shift: &[f64], q: &[Vec<f64>]) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let data = measure(truth, shift, q, None, &mut rng);
    let e = kinecal::validate::pose_errors(model, &data).expect("errors");
    kinecal::validate::ErrorStats::of(&e).position_rms_mm
}
