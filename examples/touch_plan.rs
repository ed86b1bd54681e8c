//! A planned set of touches beside a random one (docs/instruments.md "Planning where
//! to touch"): IRB 120 virtual prototypes (errors ±0.5 mm / ±0.1° on the model's free
//! parameters, the probe ball 120 mm out and off the flange axis, radius 1.5 mm) calibrated
//! through `calibrate()` from `n` touches, 5 µm, on three reference spheres (25.4 mm) and a
//! datum cube (100 mm, turned (5, 10, 15)°) in front of the robot:
//!
//! - **planned** on the nominal model ([`plan_touches`]: the chosen `n` of 40 candidates per
//!   sphere and cube face, D-optimal), measured on the prototype ([`touch_planned`]: each planned
//!   configuration moved onto the real surface);
//! - **random**: `n / 9` touches per sphere and face at the random configurations nearest it.
//!
//! Judged (median of N prototypes) on held-out tool points against the truth's after the best
//! rigid motion (30 random configurations over the whole workspace, 40 near the reference).
//!
//! ```text
//! cargo run --release --example touch_plan -- 5 54
//! ```
mod common;

use common::{data_set, print_progress, print_table, prototype, run_with, Outcome, Prototype};
use kinecal::design::{plan_touches, Criterion, InstrumentPlanOptions, SelectOptions, SelectionMethod, TouchLayout};
use kinecal::instrument::simulate::{random_touches, touch_planned, Placement, Touched};
use kinecal::io::builtin;
use kinecal::io::data_file::MeasurementFormat;
use kinecal::io::model_file::ModelFile;
use kinecal::measure::Noise;
use kinecal::se3;
use nalgebra::Vector3;

const PROBE: f64 = 0.005;
const RADIUS: f64 = 1.5;

fn main() {
    let arg = |k: usize| std::env::args().nth(k);
    let draws: u64 = arg(1).and_then(|a| a.parse().ok()).unwrap_or(5);
    let n: usize = arg(2).and_then(|a| a.parse().ok()).unwrap_or(54);
    let file: ModelFile = builtin::model_file("irb120").unwrap();
    let inputs = file.inputs();
    let ball = common::ball();
    let mut artifacts: Vec<Touched> = [[300.0, 0.0, 300.0], [350.0, -150.0, 250.0], [350.0, 150.0, 250.0]]
        .iter()
        .enumerate()
        .map(|(k, c)| Touched::sphere(k, Vector3::from(*c), 25.4, RADIUS))
        .collect();
    let cube_pose = se3::pose_from_parts(Vector3::new(350.0, 0.0, 250.0), Vector3::new(5.0, 10.0, 15.0).map(f64::to_radians));
    artifacts.extend(Touched::cube(cube_pose, 100.0, RADIUS));
    let layout = TouchLayout {
        artifacts: artifacts.clone(),
        ball: ball.translation.vector,
    };
    let t = std::time::Instant::now();
    let opts = InstrumentPlanOptions {
        draw: Placement {
            per_point: 40,
            reference: Vec::new(),
            max_tilt: 0.0,
            noise_mm: PROBE,
            seed: 1,
            inputs: inputs.clone(),
        },
        min_per_point: 0,
        method: SelectionMethod::Sffs,
        select: SelectOptions {
            n,
            criterion: Criterion::DOptimal,
            ..Default::default()
        },
    };
    let plan = plan_touches(&file, &layout, &opts).unwrap();
    eprintln!(
        "plan: {n} of {} candidates in {:.1} s, {} repair moves, {}",
        plan.candidates.len(),
        t.elapsed().as_secs_f64(),
        plan.repairs,
        plan.selection.indices
    );
    let opts = || common::probe_options(PROBE, Noise::default().position);
    let names = [
        format!("{n} planned touches (3 spheres, cube), 5 µm"),
        format!("{} random touches per sphere and face, 5 µm", n / 9),
    ];
    let mut table: Vec<Vec<Outcome>> = vec![Vec::new(); 2];
    for seed in 1..=draws {
        let Prototype {
            truth,
            whole,
            near,
            mut rng,
            ..
        } = prototype(&file, seed, None);
        let planned = touch_planned(&truth, &plan.rows, &artifacts, PROBE, seed, &inputs).unwrap();
        let random = random_touches(&truth, &inputs, &artifacts, n / 9, PROBE, &mut rng).unwrap();
        for (k, rows) in [planned, random].into_iter().enumerate() {
            table[k].push(run_with(
                &file,
                data_set(rows, MeasurementFormat::Touch),
                opts(),
                &truth,
                &whole,
                &near,
            ));
        }
        print_progress(seed, "", &table);
    }
    print_table(
        &format!(
            "IRB 120, {draws} prototypes, {n} touches each: held-out 3-D position error RMS (mm) after a rigid motion, median [min–max]"
        ),
        &names,
        &table,
    );
}
