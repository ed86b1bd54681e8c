//! A planned set of seat rows beside a random one (docs/instruments.md "Planning"):
//! IRB 120 virtual prototypes (errors ±0.5 mm / ±0.1° on the model's free parameters, the ball
//! 120 mm out and off the flange axis) calibrated through `calibrate()` from `n` rows of
//!
//! - four seats, the orientations **planned** on the nominal model ([`plan_instrument`]: the
//!   chosen `n` of 4 × 100 candidates tilted up to 35°, criterion as given), measured on the
//!   prototype ([`measure_planned`]), 10 µm per axis, the seats' distances known;
//! - the same four seats × `n/4` **random** orientations (tilt ≤ 35°, as the candidates), 10 µm;
//! - a tracker 2 m away, `n` random configurations, 20 µm per axis;
//!
//! then judged (median of N prototypes) on held-out tool points against the truth's after the
//! best rigid motion: 30 random configurations over the whole workspace, and 40 drawn as the
//! seats' are (near the seats, new orientations). Prototypes seeded 1..=N.
//!
//! ```text
//! cargo run --release --example instrument_plan -- 7 60 d
//! ```
mod common;

use common::{
    data_set, near_reference, print_progress, print_table, prototype, run, seats_near_reference, tracker_run, Outcome, Prototype,
};
use kinecal::calibrate::CalibrationOptions;
use kinecal::design::{instrument_blocks, plan_instrument, Criterion, InstrumentLayout, InstrumentPlanOptions, ObservabilityIndices};
use kinecal::design::{SelectOptions, SelectionMethod};
use kinecal::instrument::measure_planned;
use kinecal::instrument::simulate::{seat_distances, seat_rows};
use kinecal::io::builtin;
use kinecal::io::data_file::MeasurementFormat;
use kinecal::io::model_file::ModelFile;
use kinecal::model::framed::Framed;
use kinecal::se3::Pose;

fn main() {
    let arg = |k: usize| std::env::args().nth(k);
    let draws: u64 = arg(1).and_then(|a| a.parse().ok()).unwrap_or(7);
    let n: usize = arg(2).and_then(|a| a.parse().ok()).unwrap_or(60);
    let criterion: Criterion = arg(3).and_then(|a| a.parse().ok()).unwrap_or(Criterion::DOptimal);
    let file: ModelFile = builtin::model_file("irb120").unwrap();
    let nominal = file.build();
    let inputs = file.inputs();
    let ball = common::ball();
    let how = |per_point: usize, noise_mm: f64, seed: u64| near_reference(per_point, noise_mm, seed, &inputs);
    // The seats where the nominal ball stands near the reference: the artifact's drawing.
    let seats = seats_near_reference(&Framed::new(nominal.clone(), Pose::identity(), ball));
    let layout = InstrumentLayout {
        points: seats.clone(),
        bar_length: None,
        ball: ball.translation.vector,
    };
    let t = std::time::Instant::now();
    let opts = InstrumentPlanOptions {
        draw: how(100, 0.01, 1),
        min_per_point: 0,
        method: SelectionMethod::Sffs,
        select: SelectOptions {
            n,
            criterion,
            ..Default::default()
        },
    };
    let plan = plan_instrument(&file, &layout, &opts).unwrap();
    let per_seat: Vec<usize> = (0..4)
        .map(|k| plan.rows.iter().filter(|m| m.obs.artifact_point().unwrap().1 == k).count())
        .collect();
    eprintln!(
        "plan: {n} of {} candidates in {:.1} s, per seat {per_seat:?}, {} repair moves, {}",
        plan.candidates.len(),
        t.elapsed().as_secs_f64(),
        plan.repairs,
        plan.selection.indices
    );
    let names = [
        format!("seats 4 seats, {n} planned rows ({criterion}), 10 µm"),
        format!("seats 4 × {} random rows, 10 µm", n / 4),
        format!("tracker {n} positions, 20 µm"),
    ];
    let mut table: Vec<Vec<Outcome>> = vec![Vec::new(); 3];
    for seed in 1..=draws {
        let Prototype {
            proto,
            truth,
            whole,
            near,
            mut rng,
            ..
        } = prototype(&file, seed, Some(&seats));
        let seat_opts = || CalibrationOptions {
            seat_distances: seat_distances(&seats),
            ..CalibrationOptions::default()
        };
        let planned = measure_planned(&truth, &plan.rows, &seats, 0.01, seed, &inputs).unwrap();
        let random = seat_rows(&truth, &seats, &how(n / 4, 0.01, seed)).unwrap();
        // Both sets by the criterion, on one scaling (the blocks of both together, on the nominal).
        let both: Vec<_> = planned.iter().chain(&random).cloned().collect();
        let blocks = instrument_blocks(&file, &layout, &both, 0.01, Some(&plan.columns)).unwrap();
        let value = |set: Vec<usize>| ObservabilityIndices::from_information(&blocks.information(&set), 3 * set.len()).value(criterion);
        let (vp, vr) = (value((0..planned.len()).collect()), value((planned.len()..both.len()).collect()));
        table[0].push(run(
            &file,
            data_set(planned, MeasurementFormat::Seat),
            0.01,
            seat_opts(),
            &truth,
            &whole,
            &near,
        ));
        table[1].push(run(
            &file,
            data_set(random, MeasurementFormat::Seat),
            0.01,
            seat_opts(),
            &truth,
            &whole,
            &near,
        ));
        table[2].push(tracker_run(&file, proto, ball, &inputs, n, &mut rng, &whole, &near));
        print_progress(seed, &format!("{criterion} planned {vp:.4e} random {vr:.4e}; "), &table);
    }
    print_table(
        &format!("IRB 120, {draws} prototypes, {n} rows each: held-out 3-D position error RMS (mm) after a rigid motion, median [min–max]"),
        &names,
        &table,
    );
}
