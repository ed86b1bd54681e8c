//! Time of one `calibrate()` (the library call behind `kinecal identify` and Python's
//! `kinecal.calibrate`) on a simulated IRB 120: 500 full poses, 20 µm / 0.01° noise, frames from
//! the model, one start. `benches/python_identify.py` times the same call from Python.
//!
//! ```text
//! cargo run --release --example calibrate_bench
//! ```
use kinecal::calibrate::{calibrate, CalibrationOptions, FrameMode};
use kinecal::io::builtin;
use kinecal::io::data_file::DataSet;
use kinecal::measure::Noise;
use kinecal::simulate::{random_configurations, synthesize, virtual_prototype, Instrument};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

fn main() {
    let file = builtin::model_file("irb120").expect("built-in");
    let nominal = file.build();
    let free = file.free_indices().expect("free");
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (truth, _) = virtual_prototype(&nominal, &free, 0.5, 0.1f64.to_radians(), &mut rng);
    let qs = random_configurations(&*nominal, &file.inputs(), 500, &mut rng).expect("configurations");
    let noise = Noise {
        position: 0.02,
        orientation: 0.01f64.to_radians(),
        ..Noise::default()
    };
    let set = synthesize(&*truth, qs, Instrument::Pose, &noise, &mut rng, &|_| {}).expect("measure");
    let data = DataSet::from_measurements("<simulated>", set.measurements);
    let opts = CalibrationOptions {
        noise,
        frames: FrameMode::Model,
        starts: 1,
        ..CalibrationOptions::default()
    };
    let reps = 200;
    let mut sigma0 = 0.0;
    let t = Instant::now();
    for _ in 0..reps {
        sigma0 = calibrate(&file, &data, None, &opts).expect("calibrate").identification.sigma0;
    }
    println!(
        "calibrate(), IRB 120, 500 poses, frames from the model, 1 start: {:.3} ms per call (mean of {reps}), σ̂₀ {sigma0:.6}",
        t.elapsed().as_secs_f64() * 1e3 / reps as f64
    );
}
