//! The accuracy calibrations predict against the spread they show: one virtual prototype of a
//! built-in model, the same configurations measured in many noise draws and calibrated each
//! time; at 50 held-out configurations, the predicted position σ (median over the draws) beside
//! the RMS spread of the calibrated models' predictions (`kinecal::studies::predicted`).
//!
//! ```text
//! cargo run --release --example predicted_spread -- irb120 200
//! cargo run --release --example predicted_spread -- pm5 200
//! ```
use kinecal::studies::predicted::{predicted_against_spread, SpreadOptions};
use std::time::Instant;

fn main() {
    let model = std::env::args().nth(1).unwrap_or_else(|| "irb120".into());
    let draws: usize = std::env::args().nth(2).and_then(|a| a.parse().ok()).unwrap_or(200);
    let opts = SpreadOptions::new(&model, draws);
    let t = Instant::now();
    let check = match predicted_against_spread(&opts) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    };
    let (lo, hi) = check.ratio_range();
    let (olo, ohi) = check.orientation_ratio_range();
    let mean =
        |f: &dyn Fn(&kinecal::studies::predicted::PoseSpread) -> f64| check.poses.iter().map(f).sum::<f64>() / check.poses.len() as f64;
    println!(
        "{model}: {} of {draws} draws calibrated ({} identification poses, errors ±{} mm / ±{}°, noise {} mm / {:.3}°, {:.0} s)",
        check.draws,
        opts.poses,
        opts.error_mm,
        opts.error_deg,
        opts.noise.position,
        opts.noise.orientation.to_degrees(),
        t.elapsed().as_secs_f64()
    );
    println!(
        "{} held-out poses: predicted position σ mean {:.4} mm, observed spread mean {:.4} mm; predicted/observed {lo:.3}..{hi:.3}",
        check.poses.len(),
        mean(&|p| p.predicted_mm),
        mean(&|p| p.observed_mm)
    );
    println!(
        "orientation: predicted σ mean {:.5}°, observed spread mean {:.5}°; predicted/observed {olo:.3}..{ohi:.3}",
        mean(&|p| p.predicted_deg),
        mean(&|p| p.observed_deg)
    );
    let within = check.poses.iter().filter(|p| (p.ratio() - 1.0).abs() <= 0.2).count();
    println!("position within 20 %: {within} of {} poses", check.poses.len());
}
