//! Seats, a ballbar and a tracker beside each other with noise (docs/instruments.md):
//! IRB 120 virtual prototypes (errors ±0.5 mm / ±0.1° on the model's free parameters, a ball
//! 120 mm out and off the flange axis), each calibrated through `calibrate()` from 120 rows of
//!
//! - four seats × 30 orientations (tilt ≤ 35°), 10 µm per axis, the seats' distances known;
//! - a 100 mm ballbar at three pivots × 40, 1 µm along the bar: fixed (every row 100 mm), and
//!   telescoping (each row's length uniform in 100 ± 0.8 mm);
//! - a tracker 2 m away measuring the ball's position at 120 random configurations, 20 µm per axis;
//!
//! then judged (median of N prototypes) on held-out tool points against the truth's, after the rigid motion none of
//! them is asked to find (the seats and the ballbar do not place the base; the tracker's frame
//! is its own): at 30 random configurations over the whole workspace, and at 40 configurations
//! drawn as the instruments' are (near the seats, new orientations). Prototypes seeded 1..=N.
//!
//! ```text
//! cargo run --release --example instrument_noise -- 7
//! ```
mod common;

use common::{data_set, near_reference, print_progress, print_table, prototype, run, tracker_run, Outcome, Prototype};
use kinecal::calibrate::CalibrationOptions;
use kinecal::instrument::simulate::{distance_rows, seat_distances, seat_rows};
use kinecal::io::builtin;
use kinecal::io::data_file::MeasurementFormat;
use kinecal::io::model_file::ModelFile;
use nalgebra::Vector3;

/// Rows per calibration, every kind.
const ROWS: usize = 120;
/// The telescoping ballbar's range (mm, ±): each row's length uniform in 100 ± RANGE.
const RANGE: f64 = 0.8;

fn main() {
    let draws: u64 = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(5);
    let file: ModelFile = builtin::model_file("irb120").unwrap();
    let _nominal = file.build();
    let inputs = file.inputs();
    let ball = common::ball();
    let names = [
        "seats 4 × 30, 10 µm",
        "ballbar 3 × 40, fixed 100 mm, 1 µm",
        "ballbar 3 × 40, 100 ± 0.8 mm, 1 µm",
        "tracker 120 positions, 20 µm",
    ];
    let mut table: Vec<Vec<Outcome>> = vec![Vec::new(); names.len()];
    for seed in 1..=draws {
        // Seats where the true ball stands near the reference; pivots 100 mm below three of them.
        let Prototype {
            proto,
            truth,
            seats,
            whole,
            near,
            mut rng,
        } = prototype(&file, seed, None);
        let how = |per_point: usize, noise_mm: f64, seed: u64| near_reference(per_point, noise_mm, seed, &inputs);
        let pivots: Vec<Vector3<f64>> = seats[..3].iter().map(|c| c - Vector3::new(0.0, 0.0, 100.0)).collect();
        let seat_data = data_set(
            seat_rows(&truth, &seats, &how(ROWS / 4, 0.01, seed)).unwrap(),
            MeasurementFormat::Seat,
        );
        let seat_opts = CalibrationOptions {
            seat_distances: seat_distances(&seats),
            ..CalibrationOptions::default()
        };
        table[0].push(run(&file, seat_data, 0.01, seat_opts, &truth, &whole, &near));
        // The same bar fixed at 100 mm (every row one length), then telescoping over ±0.8 mm.
        for (k, range) in [(1, 0.0), (2, RANGE)] {
            let bar = data_set(
                distance_rows(&truth, &pivots, 100.0, range, &how(ROWS / 3, 0.001, seed)).unwrap(),
                MeasurementFormat::Distance,
            );
            table[k].push(run(&file, bar, 0.001, CalibrationOptions::default(), &truth, &whole, &near));
        }
        table[3].push(tracker_run(&file, proto, ball, &inputs, ROWS, &mut rng, &whole, &near));
        print_progress(seed, "", &table);
    }
    print_table(
        &format!(
            "IRB 120, {draws} prototypes, {ROWS} rows each: held-out 3-D position error RMS (mm) after a rigid motion, median [min–max]"
        ),
        &names,
        &table,
    );
}
