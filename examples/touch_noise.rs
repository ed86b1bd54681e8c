//! A touch probe with noise (docs/instruments.md): IRB 120 virtual prototypes (errors
//! ±0.5 mm / ±0.1° on the model's free parameters, the probe ball 120 mm out and off the flange
//! axis, radius 1.5 mm), each calibrated through `calibrate()` from 120 rows of
//!
//! - three reference spheres (25.4 mm) × 40 touches, and one sphere × 120;
//! - a datum cube (100 mm edge, turned) × 20 touches per face, and three unknown planes (three of
//!   the cube's faces, their offsets and normals unknown) × 40;
//! - a tracker 2 m away measuring the ball's position at 120 random configurations;
//! - a mixed set: 10 of those tracker positions + the three spheres × 40 (and the 10 alone);
//!
//! probe 5 µm, tracker 20 µm per axis, each kind weighted by its own σ. Judged (median of N
//! prototypes) on held-out tool points against the truth's after the rigid motion (touches do not
//! place the base), at 30 random configurations over the whole workspace and 40 near the
//! artifacts. Prototypes seeded 1..=N.
//!
//! ```text
//! cargo run --release --example touch_noise -- 5
//! ```
mod common;

use common::{data_set, print_progress, print_table, prototype, run_with, tracker, tracker_rows, tracker_run, Outcome, Prototype};
use kinecal::instrument::simulate::{random_touches, Touched};
use kinecal::io::builtin;
use kinecal::io::data_file::MeasurementFormat;
use kinecal::io::model_file::ModelFile;
use kinecal::model::framed::Framed;
use kinecal::se3::{self};
use nalgebra::Vector3;

/// Touch rows per calibration.
const ROWS: usize = 120;
/// The probe's and the tracker's noise (mm).
const PROBE: f64 = 0.005;
const TRACKER: f64 = 0.02;
/// The probe ball's radius (mm).
const RADIUS: f64 = 1.5;

fn main() {
    let draws: u64 = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(5);
    let file: ModelFile = builtin::model_file("irb120").unwrap();
    let nominal = file.build();
    let inputs = file.inputs();
    let ball = common::ball();
    let opts = || common::probe_options(PROBE, TRACKER);
    let names = [
        "3 spheres × 40, 5 µm",
        "1 sphere × 120, 5 µm",
        "datum cube 6 faces × 20, 5 µm",
        "3 unknown planes × 40, 5 µm",
        "tracker 120 positions, 20 µm",
        "mixed: 10 tracker + 3 spheres × 40",
        "tracker 10 positions alone",
    ];
    let mut table: Vec<Vec<Outcome>> = vec![Vec::new(); names.len()];
    for seed in 1..=draws {
        let Prototype {
            proto,
            truth,
            whole,
            near,
            mut rng,
            ..
        } = prototype(&file, seed, None);
        // Three spheres in front of the robot, within its reach from many directions.
        let centres = [
            Vector3::new(300.0, 0.0, 300.0),
            Vector3::new(350.0, -150.0, 250.0),
            Vector3::new(350.0, 150.0, 250.0),
        ];
        let spheres: Vec<Touched> = (0..3).map(|k| Touched::sphere(k, centres[k], 25.4, RADIUS)).collect();
        let cube_pose = se3::pose_from_parts(Vector3::new(350.0, 0.0, 250.0), Vector3::new(5.0, 10.0, 15.0).map(f64::to_radians));
        let cube = Touched::cube(cube_pose, 100.0, RADIUS);
        // Three of the cube's faces as unknown planes: +x, +y, +z, through their centres.
        let planes: Vec<Touched> = (0..3)
            .map(|k| {
                let n = cube_pose.rotation * Vector3::ith(k, 1.0);
                Touched::plane(k, cube_pose.translation.vector + 50.0 * n, n, RADIUS)
            })
            .collect();
        let sets: [(usize, Vec<Touched>, usize); 4] = [
            (0, spheres.clone(), ROWS / 3),
            (1, spheres[..1].to_vec(), ROWS),
            (2, cube, ROWS / 6),
            (3, planes, ROWS / 3),
        ];
        for (k, artifacts, per) in sets {
            let rows = random_touches(&truth, &inputs, &artifacts, per, PROBE, &mut rng).unwrap();
            table[k].push(run_with(
                &file,
                data_set(rows, MeasurementFormat::Touch),
                opts(),
                &truth,
                &whole,
                &near,
            ));
        }
        table[4].push(tracker_run(&file, proto.clone(), ball, &inputs, ROWS, &mut rng, &whole, &near));
        // The mixed set, in the tracker's frame: its spheres where the tracker sees them.
        let tracked = Framed::new(proto.clone(), tracker(), ball);
        let seen: Vec<Touched> = (0..3)
            .map(|k| Touched::sphere(k, tracker().transform_point(&centres[k].into()).coords, 25.4, RADIUS))
            .collect();
        let ten = tracker_rows(&tracked, &*nominal, &inputs, 10, TRACKER, &mut rng);
        let mut rows = ten.clone();
        rows.extend(random_touches(&tracked, &inputs, &seen, ROWS / 3, PROBE, &mut rng).unwrap());
        table[5].push(run_with(
            &file,
            data_set(rows, MeasurementFormat::Mixed),
            opts(),
            &tracked,
            &whole,
            &near,
        ));
        table[6].push(run_with(
            &file,
            data_set(ten, MeasurementFormat::Position),
            opts(),
            &tracked,
            &whole,
            &near,
        ));
        print_progress(seed, "", &table);
    }
    print_table(
        &format!("IRB 120, {draws} prototypes: held-out 3-D position error RMS (mm) after a rigid motion, median [min–max]"),
        &names,
        &table,
    );
}
