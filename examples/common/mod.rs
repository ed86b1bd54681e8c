//! What the instrument examples share (`instrument_noise.rs`, `instrument_plan.rs`): the IRB 120
//! set-up (reference configuration, ball, seats near the reference), a tracker's rows, a
//! calibration through `calibrate()` judged on held-out tool points after the rigid motion the
//! instruments do not see, and the table's median [min–max].
#![allow(dead_code)]
pub mod drift;
use kinecal::calibrate::{calibrate, CalibrationOptions};
use kinecal::io::data_file::{DataSet, MeasurementFormat};
use kinecal::io::model_file::ModelFile;
use kinecal::measure::{register_points, Measurement, Noise, Observation};
use kinecal::model::kind::InputSpec;
use kinecal::se3::{self, Pose};
use kinecal::simulate::random_configurations;
use kinecal::Mechanism;
use nalgebra::Vector3;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// The IRB 120's reference configuration (rad): the tool pointing down in front of the robot.
pub const REFERENCE: [f64; 6] = [0.0, 0.35, 0.2, 0.0, 1.0, 0.0];

/// The ball on the flange: 120 mm out and off the axis.
pub fn ball() -> Pose {
    se3::pose_from_parts(Vector3::new(15.0, -10.0, 120.0), Vector3::zeros())
}

/// Four seats where `model`'s tool point stands at the reference and three nearby configurations.
pub fn seats_near_reference(model: &dyn Mechanism) -> Vec<Vector3<f64>> {
    [[0.0, 0.0, 0.0], [0.5, 0.1, -0.1], [-0.5, -0.1, 0.2], [0.2, 0.3, 0.3]]
        .iter()
        .map(|s| {
            let q: Vec<f64> = REFERENCE
                .iter()
                .enumerate()
                .map(|(k, v)| v + s.get(k).copied().unwrap_or(0.0))
                .collect();
            model.forward(&q).unwrap().translation.vector
        })
        .collect()
}

/// A data set of instrument or tracker rows (its format follows from the rows).
pub fn data_set(measurements: Vec<Measurement>, format: MeasurementFormat) -> DataSet {
    let set = DataSet::from_measurements("data.csv", measurements);
    assert_eq!(set.format, format);
    set
}

/// RMS distance between `a` and `b` after the rigid motion that takes `a` best onto `b`.
pub fn aligned_rms(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    let t = register_points(a, b).unwrap();
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| (t.transform_point(&(*p).into()).coords - q).norm_squared())
        .sum();
    (sum / a.len() as f64).sqrt()
}

/// Held-out RMS (mm) of the calibrated model against the truth at `qs`, a rigid motion removed.
pub fn held_out(calibrated: &dyn Mechanism, truth: &dyn Mechanism, qs: &[Vec<f64>]) -> f64 {
    let at = |m: &dyn Mechanism| -> Vec<Vector3<f64>> { qs.iter().map(|q| m.forward(q).unwrap().translation.vector).collect() };
    aligned_rms(&at(calibrated), &at(truth))
}

/// One calibration: held-out RMS over the whole workspace, near the seats, and the verdict.
pub type Outcome = (f64, f64, String);

/// Calibrate `file` from `data` with the stated position noise `noise` (mm) and `opts`, reload the
/// written model, and judge it against `truth` at `whole` and `near` ([`held_out`]).
pub fn run(
    file: &ModelFile,
    data: DataSet,
    noise: f64,
    opts: CalibrationOptions,
    truth: &dyn Mechanism,
    whole: &[Vec<f64>],
    near: &[Vec<f64>],
) -> Outcome {
    let noise = Noise {
        position: noise,
        ..Noise::default()
    };
    run_with(file, data, CalibrationOptions { noise, ..opts }, truth, whole, near)
}

/// [`run`] with the noise (per kind) in `opts`.
pub fn run_with(
    file: &ModelFile,
    data: DataSet,
    opts: CalibrationOptions,
    truth: &dyn Mechanism,
    whole: &[Vec<f64>],
    near: &[Vec<f64>],
) -> Outcome {
    let cal = calibrate(file, &data, None, &opts).unwrap();
    let status = format!("{:?}", cal.report.verdict.status).to_lowercase();
    if std::env::var_os("KINECAL_REASONS").is_some() {
        eprintln!("{status}: {}", cal.report.verdict.reasons.join(" | "));
    }
    let text = cal.model_file.to_toml().unwrap();
    let back = ModelFile::load_str(std::path::Path::new("cal.toml"), &text).unwrap().build();
    (held_out(&*back, truth, whole), held_out(&*back, truth, near), status)
}

/// A tracker's rows: `tracked` (the truth seen from the tracker) at `n` random configurations of
/// `nominal`, the ball's position with `sigma` mm of noise per axis.
pub fn tracker_rows(
    tracked: &dyn Mechanism,
    nominal: &dyn Mechanism,
    inputs: &[InputSpec],
    n: usize,
    sigma: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Measurement> {
    let normal = Normal::new(0.0, sigma).unwrap();
    let qs = random_configurations(nominal, inputs, n, rng).unwrap();
    qs.into_iter()
        .map(|q| {
            let p = tracked.forward(&q).unwrap().translation.vector;
            let e = Vector3::new(normal.sample(rng), normal.sample(rng), normal.sample(rng));
            Measurement {
                q,
                obs: Observation::Position(p + e),
                joints: Vec::new(),
            }
        })
        .collect()
}

/// The tracker 2 m away (its frame in the robot's base).
pub fn tracker() -> Pose {
    se3::pose_from_parts(
        Vector3::new(2000.0, -700.0, 400.0),
        Vector3::new(1.0, 2.0, -0.5).normalize() * 120f64.to_radians(),
    )
}

/// One row of the table: `name`, the median [min–max] of both held-out columns, the verdicts.
pub fn table_row(name: &str, runs: &[Outcome]) -> String {
    let col = |f: fn(&Outcome) -> f64| {
        let mut v: Vec<f64> = runs.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        format!("{:.4} [{:.4}–{:.4}]", v[v.len() / 2], v[0], v[v.len() - 1])
    };
    let calibrated = runs.iter().filter(|r| r.2 == "calibrated").count();
    format!("| {name} | {} | {} | {calibrated} of {} |", col(|r| r.0), col(|r| r.1), runs.len())
}

/// One line on stderr with prototype `seed`'s outcome in every column of `table` (`prefix`
/// first).
pub fn print_progress(seed: u64, prefix: &str, table: &[Vec<Outcome>]) {
    let cells: Vec<String> = table
        .iter()
        .map(|column| {
            let (w, n, status) = &column[seed as usize - 1];
            format!("{w:.4} / {n:.4} mm ({status})")
        })
        .collect();
    eprintln!("prototype {seed}: {prefix}{}", cells.join(", "));
}

/// The markdown table of `table` (one row per instrument, named by `names`) under `title`.
pub fn print_table<S: AsRef<str>>(title: &str, names: &[S], table: &[Vec<Outcome>]) {
    println!("{title}");
    println!("| instrument | whole workspace (30 random configurations) | near the seats (40 new orientations) | verdict \"calibrated\" |");
    println!("|---|---|---|---|");
    for (name, column) in names.iter().zip(table) {
        println!("{}", table_row(name.as_ref(), column));
    }
}

/// The tracker beside the instruments: the prototype `proto` with its `ball`, seen from
/// [`tracker`], measured at `n` random configurations (20 µm per axis) and calibrated and judged
/// like the instrument rows ([`run`]).
#[allow(clippy::too_many_arguments)]
pub fn tracker_run(
    file: &ModelFile,
    proto: Box<dyn Mechanism>,
    ball: Pose,
    inputs: &[InputSpec],
    n: usize,
    rng: &mut ChaCha8Rng,
    whole: &[Vec<f64>],
    near: &[Vec<f64>],
) -> Outcome {
    let nominal = file.build();
    let tracked = kinecal::model::framed::Framed::new(proto, tracker(), ball);
    let rows = tracker_rows(&tracked, &*nominal, inputs, n, 0.02, rng);
    run(
        file,
        data_set(rows, MeasurementFormat::Position),
        0.02,
        CalibrationOptions::default(),
        &tracked,
        whole,
        near,
    )
}

/// How the instrument rows are drawn about [`REFERENCE`] (tool tilted up to 35°, within the
/// limits of `inputs`): `per_point` rows per seat or pivot, `noise_mm`, `seed`.
pub fn near_reference(per_point: usize, noise_mm: f64, seed: u64, inputs: &[InputSpec]) -> kinecal::instrument::simulate::Placement {
    kinecal::instrument::simulate::Placement {
        per_point,
        reference: REFERENCE.to_vec(),
        max_tilt: 35f64.to_radians(),
        noise_mm,
        seed,
        inputs: inputs.to_vec(),
    }
}

/// One IRB 120 prototype of the instrument examples and where it is judged ([`prototype`]).
pub struct Prototype {
    /// The prototype (errors ±0.5 mm / ±0.1° on the model file's free parameters).
    pub proto: Box<dyn Mechanism>,
    /// It with its [`ball`], in its own base frame.
    pub truth: kinecal::model::framed::Framed<Box<dyn Mechanism>>,
    /// The seats it is judged near.
    pub seats: Vec<Vector3<f64>>,
    /// 30 random configurations over the whole workspace.
    pub whole: Vec<Vec<f64>>,
    /// 40 configurations near the seats (10 new orientations at each).
    pub near: Vec<Vec<f64>>,
    /// The random draws, after those above.
    pub rng: ChaCha8Rng,
}

/// Prototype `seed` of `file`, judged near `seats` (the true ball's [`seats_near_reference`]
/// when `None`).
pub fn prototype(file: &ModelFile, seed: u64, seats: Option<&[Vector3<f64>]>) -> Prototype {
    use rand::SeedableRng;
    let nominal = file.build();
    let inputs = file.inputs();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (proto, _) = kinecal::simulate::virtual_prototype(&nominal, &file.free_indices().unwrap(), 0.5, 0.1f64.to_radians(), &mut rng);
    let truth = kinecal::model::framed::Framed::new(proto.clone(), Pose::identity(), ball());
    let seats = seats.map_or_else(|| seats_near_reference(&truth), <[_]>::to_vec);
    let whole = random_configurations(&*nominal, &inputs, 30, &mut rng).unwrap();
    let near = kinecal::instrument::simulate::seat_rows(&truth, &seats, &near_reference(10, 0.0, 1000 + seed, &inputs))
        .unwrap()
        .into_iter()
        .map(|m| m.q)
        .collect();
    Prototype {
        proto,
        truth,
        seats,
        whole,
        near,
        rng,
    }
}

/// Calibration options with the tracker's σ `tracker_mm` (per axis) and the touch probe's own
/// `probe_mm` ([`kinecal::measure::KindNoise::probe`]), each kind weighted by its own.
pub fn probe_options(probe_mm: f64, tracker_mm: f64) -> CalibrationOptions {
    CalibrationOptions {
        noise: kinecal::measure::Noise {
            position: tracker_mm,
            kinds: kinecal::measure::KindNoise {
                probe: Some(probe_mm),
                ..Default::default()
            },
            ..Default::default()
        },
        ..CalibrationOptions::default()
    }
}
