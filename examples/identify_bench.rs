//! Identification speed and memory on the IRB 120 (42 chain coordinates, rank 30) with simulated
//! noisy full-pose data, phase by phase, and the peak resident memory of the process.
//!
//! ```text
//! cargo run --release --example identify_bench -- 500        # poses (default 500)
//! cargo run --release --example identify_bench -- 100000 1   # poses, repetitions
//! cargo run --release --example identify_bench -- 500 200 identify   # only the identification
//! ```
use kinecal::identifiability;
use kinecal::identify::{identify, linearize, Options};
use kinecal::measure::Noise;
use kinecal::model::irb120;
use kinecal::model::Mechanism;
use kinecal::simulate::{self, ObservationKind};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("VmHWM:")).map(str::to_owned))
        .and_then(|l| l.split_whitespace().nth(1).and_then(|v| v.parse::<f64>().ok()))
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(500);
    let reps: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(20);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let nominal = irb120::nominal();
    let delta = simulate::random_errors(&nominal, &mut rng, 0.5, 0.002, None);
    let truth = simulate::perturbed(&nominal, &delta);
    let q: Vec<Vec<f64>> = (0..n).map(|_| (0..6).map(|_| rng.random_range(-2.0..2.0)).collect()).collect();
    let noise = Noise {
        position: 0.02,
        orientation: 2e-4,
        ..Noise::default()
    };
    let data = simulate::measure(&truth, &q, ObservationKind::Pose, Some(&noise), &mut rng).unwrap();
    println!(
        "IRB 120, {n} poses, full pose, 42 parameters; peak RSS after the data {:.1} MB",
        peak_rss_mb()
    );
    let opts = Options {
        noise,
        ..Options::default()
    };
    let time = |what: &str, f: &mut dyn FnMut()| {
        let t = Instant::now();
        for _ in 0..reps {
            f();
        }
        let ms = t.elapsed().as_secs_f64() * 1e3 / reps as f64;
        println!("{what:<34} {ms:>10.3} ms");
    };
    let phases = args.get(3).map_or("all", String::as_str) == "all";
    if phases {
        time("linearize (FK + Jacobian, weights)", &mut || {
            linearize(&nominal, &data, &noise).unwrap();
        });
        let lin = linearize(&nominal, &data, &noise).unwrap();
        let all: Vec<usize> = (0..42).collect();
        time("identifiability analysis (full Jacobian)", &mut || {
            identifiability::analyze(&lin.jacobian, &all, opts.rank_tolerance);
        });
    }
    let mut result = None;
    time("identify (Gauss-Newton, converged)", &mut || {
        result = Some(identify(&nominal, &data, &opts).unwrap());
    });
    let r = result.unwrap();
    let worst = q
        .iter()
        .map(|q| (r.model.forward(q).unwrap().translation.vector - truth.forward(q).unwrap().translation.vector).norm())
        .fold(0.0, f64::max);
    println!(
        "converged {} after {} iterations, σ̂₀ {:.4}; max position difference to the truth {worst:.3e} mm",
        r.converged,
        r.iterations.len(),
        r.sigma0
    );
    for (k, it) in r.iterations.iter().enumerate() {
        println!(
            "  iteration {}: cost {:.6e}, step {:.3e}, damping {:.1e}",
            k + 1,
            it.cost,
            it.step,
            it.damping
        );
    }
    println!("peak RSS {:.1} MB", peak_rss_mb());
}
