//! `kinecal simulate`: a virtual prototype — the model with random geometric errors, measured with
//! noise at random poses → a data file, and the true model written separately.
use super::progress;
use clap::{Args, ValueEnum};
use kinecal::error::CalibError;
use kinecal::instrument::simulate::{distance_rows, parse_points, seat_distances, seat_rows, Placement};
use kinecal::io::data_file::data_text;
use kinecal::io::model_file::ModelFile;
use kinecal::io::output::Outputs;
use kinecal::measure::Noise;
use kinecal::simulate::{random_configurations, synthesize, virtual_prototype, Instrument};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};

/// What the simulated instrument measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MeasureKind {
    /// Tool pose: x,y,z (mm) and a quaternion.
    Pose,
    /// Tool-frame origin: x,y,z (mm).
    Position,
    /// Three reflector centres m1..m3 (mm) at (0,60,0), (40,−30,0), (−40,−30,0) mm in the tool
    /// frame (their frame is the tool frame); the noise is applied to each centre.
    Reflectors,
}

/// Arguments of `kinecal simulate`.
#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// Model file, or a built-in model name (`kinecal model list`).
    pub model: String,
    /// Number of random poses: inputs uniform within the joint limits (±180° / ±100 mm without);
    /// for closed-loop mechanisms (pm5, stewart) platform poses uniform in the model's workspace,
    /// mapped to inputs by the nominal model's inverse kinematics.
    #[arg(long, default_value_t = 50)]
    pub poses: usize,
    /// Measure the identification set at the configurations of this file (the CSV of `kinecal
    /// plan`, a data file, or the commands of `kinecal compensate`: any file with the model's
    /// input columns) instead of at random ones;
    /// `--poses` is then the file's row count.
    #[arg(long, value_name = "PLAN.csv")]
    pub at: Option<PathBuf>,
    /// Seed of every random draw (errors, poses, noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Range of the geometric length errors: uniform in ±ERROR_MM (mm), on the model's free parameters.
    #[arg(long, default_value_t = 0.5)]
    pub error_mm: f64,
    /// Range of the geometric angle errors: uniform in ±ERROR_DEG (degrees).
    #[arg(long, default_value_t = 0.1)]
    pub error_deg: f64,
    /// Measurement noise, standard deviation per axis (mm); 0 = noise-free.
    #[arg(long, default_value_t = 0.0)]
    pub noise_mm: f64,
    /// Orientation noise, standard deviation per axis (degrees); 0 = noise-free.
    #[arg(long, default_value_t = 0.0)]
    pub noise_deg: f64,
    /// Noise of the observed revolute joints' readings (degrees; `role = "observed"`); 0 = exact.
    #[arg(long, default_value_t = 0.0)]
    pub encoder_noise_deg: f64,
    /// Noise of the observed prismatic joints' readings (mm); 0 = exact.
    #[arg(long, default_value_t = 0.0)]
    pub encoder_noise_mm: f64,
    /// What is measured.
    #[arg(long, value_enum, default_value_t = MeasureKind::Pose, conflicts_with_all = ["spheres", "planes", "cube"])]
    pub measure: MeasureKind,
    /// Data file to write (CSV).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Where to write the true (perturbed) model (TOML). Needed unless `--error-mm 0
    /// --error-deg 0`, which measures the model as it is (e.g. a calibrated model's truth file).
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// An ISO 9283 test run instead of a data file: the robot goes `N` times through the
    /// configurations of `--at` (the commands `kinecal compensate` writes: their `id` is the test
    /// pose), and `--out` gets the attained poses (`pose,cycle,x_mm,…,yaw_deg`) for `kinecal
    /// assess`
    #[arg(long, value_name = "N", requires = "at", conflicts_with_all = ["validation_out", "spheres", "planes", "cube"])]
    pub cycles: Option<usize>,
    /// Repeatability of the virtual robot in a test run: standard deviation per axis of where it
    /// arrives (mm), beside the measurement noise
    #[arg(long, default_value_t = 0.0)]
    pub repeatability_mm: f64,
    /// Repeatability of its orientation: standard deviation per axis (degrees)
    #[arg(long, default_value_t = 0.0)]
    pub repeatability_deg: f64,
    /// Also write an independent validation set with this many poses (needs --validation-out).
    #[arg(long, default_value_t = 0, requires = "validation_out")]
    pub validation_poses: usize,
    /// Validation data file to write (CSV).
    #[arg(long)]
    pub validation_out: Option<PathBuf>,
    /// Instrument data instead of tracker data: fixed seats at these points (mm, base frame,
    /// `X,Y,Z;X,Y,Z;…`), the tool point placed in each from `--per-point` orientations; the data
    /// file gets a `seat` column (seat k is the k-th point). `--validation-out` then gets
    /// `--validation-poses` fresh orientations per seat.
    /// With `--at` (an instrument plan of `kinecal plan --seats`), the plan's rows are measured.
    #[arg(long, value_name = "X,Y,Z;…", conflicts_with_all = ["pivots", "measure", "cycles"])]
    pub seats: Option<String>,
    /// Instrument data: a ballbar between the tool point and each of these pivots (mm, base
    /// frame, `X,Y,Z;…`), `--per-point` lengths each (directions within 60° of the pivot's
    /// direction toward the reference tool point); columns `pivot,length_mm`. Needs `--ballbar-mm`.
    #[arg(long, value_name = "X,Y,Z;…", requires = "ballbar_mm", conflicts_with_all = ["measure", "cycles"])]
    pub pivots: Option<String>,
    /// The ballbar's length (mm): its certified length, about which it measures.
    #[arg(long, value_name = "L", requires = "pivots")]
    pub ballbar_mm: Option<f64>,
    /// The ballbar's measuring range (mm, ±): each row's length is drawn uniformly in
    /// L ± R (a telescoping bar's travel). 0: a fixed bar, every row the same length, which
    /// does not rule out a machine that stands still over a pivot's rows.
    #[arg(long, value_name = "R", requires = "pivots", default_value_t = kinecal::instrument::simulate::DEFAULT_BALLBAR_RANGE_MM)]
    pub ballbar_range_mm: f64,
    /// A draw-wire's readings instead of lengths: each row's length minus its pivot's zero (mm;
    /// one value for every pivot, or `Z0,Z1,…` one per pivot), written as `reading_mm` (the
    /// zero unknown to `identify`, which estimates it as `pivotK.zero`).
    #[arg(long, value_name = "Z[,Z…]", requires = "pivots")]
    pub length_zero_mm: Option<String>,
    /// With `--planes` and `--pivots`: the ballbar's lengths per pivot written beside the
    /// touches (default `--per-point`).
    #[arg(long, value_name = "N", requires = "planes")]
    pub lengths_per_pivot: Option<usize>,
    /// Instrument data: rows per seat or pivot.
    #[arg(long, visible_aliases = ["per-seat", "per-pivot"], default_value_t = 15)]
    pub per_point: usize,
    /// Instrument data: largest tilt of the tool from its orientation at the reference
    /// configuration (degrees).
    #[arg(long, default_value_t = 30.0)]
    pub tilt_deg: f64,
    /// Instrument data: the configuration the orientations are drawn about, the model's inputs
    /// in file units (deg / mm, comma-separated); default the middle of each input's limits.
    #[arg(long, value_name = "Q1,Q2,…", allow_hyphen_values = true)]
    pub reference: Option<String>,
    /// Instrument data: the true tool point (the ball's centre) in the flange or platform frame
    /// (mm, `X,Y,Z`); written as the truth's tool frame. Default: the flange origin.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub tool_mm: Option<String>,
    /// Touch-probe data: spheres, planes or a datum cube (the same options as `kinecal plan`).
    #[command(flatten)]
    pub touch: super::touch_args::TouchArgs,
    /// Print a JSON summary instead of text.
    #[arg(long)]
    pub json: bool,
    /// Replace existing output files.
    #[arg(long)]
    pub force: bool,
}

struct Written {
    path: PathBuf,
    poses: usize,
}

/// Run the command.
pub fn run(a: SimulateArgs) -> anyhow::Result<()> {
    for (name, v) in [
        ("--error-mm", a.error_mm),
        ("--error-deg", a.error_deg),
        ("--noise-mm", a.noise_mm),
        ("--noise-deg", a.noise_deg),
        ("--encoder-noise-deg", a.encoder_noise_deg),
        ("--encoder-noise-mm", a.encoder_noise_mm),
        ("--repeatability-mm", a.repeatability_mm),
        ("--repeatability-deg", a.repeatability_deg),
    ] {
        anyhow::ensure!(v.is_finite() && v >= 0.0, "{name}: must be a finite value ≥ 0, got {v}");
    }
    anyhow::ensure!(a.poses > 0, "--poses: must be at least 1");
    let mut outputs = Outputs::new(a.force);
    outputs.input(Path::new(&a.model));
    if let Some(p) = &a.at {
        outputs.input(p);
    }
    anyhow::ensure!(
        a.truth.is_some() || as_it_is(&a),
        "--truth FILE: where to keep the virtual prototype with its ±{} mm / ±{} deg errors (--error-mm 0 --error-deg 0 measures the model as it is, without one)",
        a.error_mm,
        a.error_deg
    );
    outputs
        .output(&a.out)?
        .output_opt(a.truth.as_deref())?
        .output_opt(a.validation_out.as_deref())?;
    let file = ModelFile::load_or_builtin(&a.model)?;
    super::note_held(&file, a.json);
    let nominal = file.build();
    let inputs = file.inputs();
    let free = file.free_indices()?;
    let mut rng = ChaCha8Rng::seed_from_u64(a.seed);
    let (truth, _delta) = virtual_prototype(&nominal, &free, a.error_mm, a.error_deg.to_radians(), &mut rng);
    let touches = a.touch.active();
    let instrument = a.seats.is_some() || a.pivots.is_some() || touches;
    anyhow::ensure!(
        instrument || (a.tool_mm.is_none() && a.reference.is_none()),
        "--tool-mm and --reference describe instrument data: give --seats or --pivots with them"
    );
    let truth: Box<dyn kinecal::Mechanism> = match &a.tool_mm {
        Some(text) => {
            let [ball] = parse_points(text)
                .map_err(|e| anyhow::anyhow!("--tool-mm {e}"))?
                .try_into()
                .map_err(|_| anyhow::anyhow!("--tool-mm '{text}': one point X,Y,Z (mm)"))?;
            let tool = kinecal::se3::pose_from_parts(ball, nalgebra::Vector3::zeros());
            Box::new(kinecal::model::framed::Framed::new(truth, kinecal::se3::Pose::identity(), tool))
        }
        None => truth,
    };
    let noise = Noise {
        position: a.noise_mm,
        orientation: a.noise_deg.to_radians(),
        joint_angle: a.encoder_noise_deg.to_radians(),
        joint_length: a.encoder_noise_mm,
        kinds: Default::default(),
    };
    let mut truth_file = file.with_geometry_of(&*truth).map_err(|e| anyhow::anyhow!(e))?;
    truth_file.description = Some(format!(
        "virtual prototype of '{}': seed {}, errors ±{} mm / ±{} deg on {} free parameters",
        file.name,
        a.seed,
        a.error_mm,
        a.error_deg,
        free.len()
    ));
    if let Some(path) = &a.truth {
        let truth_text = truth_file.to_toml().map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        outputs.stage(path, truth_text.as_bytes())?;
    }

    if touches {
        return touch_run(&a, &file, &*truth, &mut rng, outputs);
    }
    if instrument {
        return instrument_run(&a, &file, &*truth, &mut rng, outputs);
    }
    if let (Some(cycles), Some(at)) = (a.cycles, &a.at) {
        return test_run(&a, &file.name, &*truth, &inputs, at, cycles, &noise, &mut rng, outputs);
    }
    let planned: Option<Vec<Vec<f64>>> = match &a.at {
        Some(p) => {
            let qs = kinecal::io::data_file::read_configurations(p, &inputs)?;
            anyhow::ensure!(!qs.is_empty(), "{}: no configuration in the file", p.display());
            Some(qs)
        }
        None => None,
    };
    let first_n = planned.as_ref().map_or(a.poses, |p| p.len());
    let mut sets = vec![(a.out.clone(), first_n, 0i64)];
    if let Some(v) = &a.validation_out {
        anyhow::ensure!(a.validation_poses > 0, "--validation-out needs --validation-poses N (N ≥ 1)");
        sets.push((v.clone(), a.validation_poses, first_n as i64));
    }
    let mut written = Vec::new();
    for (path, n, first_id) in sets {
        let qs = match (&planned, first_id) {
            (Some(p), 0) => p.clone(),
            _ => random_configurations(&*nominal, &inputs, n, &mut rng)
                .map_err(|e| anyhow::anyhow!("drawing poses on {}: {e}", file.name))?,
        };
        let pb = progress::bar(n, "measuring", a.json);
        let instrument = match a.measure {
            MeasureKind::Pose => Instrument::Pose,
            MeasureKind::Position => Instrument::Position,
            MeasureKind::Reflectors => Instrument::Reflectors,
        };
        let set = synthesize(&*truth, qs, instrument, &noise, &mut rng, &|_| pb.inc(1)).map_err(|e| match e {
            CalibError::Kinematics { pose, source } => anyhow::anyhow!(
                "pose {pose}: the virtual prototype (errors ±{} mm / ±{} deg, seed {}) does not reach this configuration: {source}{}",
                a.error_mm,
                a.error_deg,
                a.seed,
                if a.error_mm > 5.0 || a.error_deg > 2.0 {
                    "; errors this large make another machine: geometric errors are of the order of machining tolerances (e.g. --error-mm 0.5 --error-deg 0.1)"
                } else {
                    ""
                }
            ),
            e => e.into(),
        })?;
        pb.finish_and_clear();
        let ids: Vec<i64> = (0..n as i64).map(|i| first_id + i).collect();
        let data = data_text(&path, &file.data_columns(), &ids, &set.measurements, set.reflectors.as_deref())?;
        outputs.stage(&path, data.as_bytes())?;
        written.push(Written { path, poses: n });
    }
    outputs.commit()?;
    if a.json {
        let files: Vec<_> = written
            .iter()
            .map(|w| serde_json::json!({"path": w.path, "poses": w.poses}))
            .collect();
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "model": file.name, "seed": a.seed, "error_mm": a.error_mm, "error_deg": a.error_deg,
                "noise_mm": a.noise_mm, "noise_deg": a.noise_deg, "perturbed_params": free.len(),
                "truth": a.truth, "data": files,
            }))?
        );
    } else if as_it_is(&a) {
        println!("{} measured as it is (no errors added; truth → {})", file.name, truth_shown(&a));
    } else {
        println!(
            "virtual prototype of {}: ±{} mm / ±{} deg errors on {} free parameters (seed {}) → {}",
            file.name,
            a.error_mm,
            a.error_deg,
            free.len(),
            a.seed,
            truth_shown(&a)
        );
        for w in &written {
            println!(
                "{}, {} measurements, noise {} mm / {} deg → {}",
                super::count(w.poses, "pose"),
                format!("{:?}", a.measure).to_lowercase(),
                a.noise_mm,
                a.noise_deg,
                w.path.display()
            );
        }
    }
    Ok(())
}

/// `--cycles N`: an ISO 9283 test run of `truth` (the prototype of the model file `model`) at the
/// commands of `at`, written to `--out`.
#[allow(clippy::too_many_arguments)]
fn test_run(
    a: &SimulateArgs,
    model: &str,
    truth: &dyn kinecal::Mechanism,
    inputs: &[kinecal::model::kind::InputSpec],
    at: &Path,
    cycles: usize,
    noise: &Noise,
    rng: &mut ChaCha8Rng,
    mut outputs: Outputs,
) -> anyhow::Result<()> {
    anyhow::ensure!(
        cycles >= 2,
        "--cycles: ISO 9283 needs at least 2 cycles (30 in the standard), got {cycles}"
    );
    let (ids, qs) = kinecal::io::data_file::read_commands(at, inputs)?;
    anyhow::ensure!(!qs.is_empty(), "{}: no configuration in the file", at.display());
    let commands: Vec<(i64, Vec<f64>)> = ids.into_iter().zip(qs).collect();
    let repeat = kinecal::assess::Repeatability {
        position_mm: a.repeatability_mm,
        orientation_rad: a.repeatability_deg.to_radians(),
    };
    let attained = kinecal::assess::measure_cycles(truth, &commands, cycles, &repeat, noise, rng).map_err(|e| match e {
        CalibError::Kinematics { pose, source } => anyhow::anyhow!(
            "{}: command {}: the virtual prototype does not reach it: {source}",
            at.display(),
            commands[pose].0
        ),
        e => e.into(),
    })?;
    outputs.stage(&a.out, kinecal::io::test_poses::attained_text(&attained).as_bytes())?;
    outputs.commit()?;
    // Say which robot ran: the model as it is, or a prototype with random errors (the default
    // errors apply here too, and a test run of a calibrated model's truth file wants none).
    let robot = if as_it_is(a) {
        format!("{model} as it is")
    } else {
        format!(
            "a virtual prototype of {model} (±{} mm / ±{} deg errors, seed {} → {}; --error-mm 0 --error-deg 0 runs the model as it is)",
            a.error_mm,
            a.error_deg,
            a.seed,
            truth_shown(a)
        )
    };
    println!(
        "ISO 9283 test run on {robot}: {} test poses × {cycles} cycles, repeatability {} mm / {} deg, noise {} mm / {} deg → {}",
        commands.len(),
        a.repeatability_mm,
        a.repeatability_deg,
        a.noise_mm,
        a.noise_deg,
        a.out.display()
    );
    Ok(())
}

/// The instrument rows `draw(k, per)` makes (`k` 0: `--out`, `--per-point` per artifact; 1:
/// `--validation-out`, `--validation-poses` per artifact, `per_what` naming that count) staged
/// in `outputs`, the ids running on from one file to the next; what each file holds.
fn stage_sets(
    a: &SimulateArgs,
    file: &ModelFile,
    outputs: &mut Outputs,
    per_what: &str,
    mut draw: impl FnMut(usize, usize) -> anyhow::Result<Vec<kinecal::measure::Measurement>>,
) -> anyhow::Result<Vec<Written>> {
    let mut sets = vec![(a.out.clone(), a.per_point)];
    if let Some(v) = &a.validation_out {
        anyhow::ensure!(
            a.validation_poses > 0,
            "--validation-out needs --validation-poses N (N ≥ 1 {per_what})"
        );
        sets.push((v.clone(), a.validation_poses));
    }
    let mut written = Vec::new();
    let mut first_id = 0i64;
    for (k, (path, per)) in sets.into_iter().enumerate() {
        let rows = draw(k, per)?;
        let ids: Vec<i64> = (first_id..first_id + rows.len() as i64).collect();
        first_id += rows.len() as i64;
        let data = data_text(&path, &file.data_columns(), &ids, &rows, None)?;
        outputs.stage(&path, data.as_bytes())?;
        written.push(Written { path, poses: rows.len() });
    }
    Ok(written)
}

/// `--seats` or `--pivots`: instrument rows of `truth` to `--out` (and `--validation-out`).
fn instrument_run(
    a: &SimulateArgs,
    file: &ModelFile,
    truth: &dyn kinecal::Mechanism,
    rng: &mut ChaCha8Rng,
    mut outputs: Outputs,
) -> anyhow::Result<()> {
    use rand::RngExt;
    anyhow::ensure!(a.per_point > 0, "--per-point: must be at least 1");
    anyhow::ensure!(
        a.tilt_deg.is_finite() && (0.0..=90.0).contains(&a.tilt_deg),
        "--tilt-deg: must be between 0 and 90, got {}",
        a.tilt_deg
    );
    let inputs = file.inputs();
    let reference = kinecal::instrument::simulate::reference_configuration(a.reference.as_deref(), &inputs).map_err(anyhow::Error::msg)?;
    truth
        .forward(&reference)
        .map_err(|e| anyhow::anyhow!("the reference configuration: {e} (give one the machine reaches with --reference)"))?;
    let how = |per_point: usize, seed: u64| Placement {
        per_point,
        reference: reference.clone(),
        max_tilt: a.tilt_deg.to_radians(),
        noise_mm: a.noise_mm,
        seed,
        inputs: inputs.clone(),
    };
    let (option, text) = match (&a.seats, &a.pivots) {
        (Some(s), _) => ("--seats", s),
        (None, Some(p)) => ("--pivots", p),
        (None, None) => unreachable!("called with seats or pivots"),
    };
    let points = parse_points(text).map_err(|e| anyhow::anyhow!("{option} {e}"))?;
    let zeros: Option<Vec<f64>> = match &a.length_zero_mm {
        None => None,
        Some(text) => {
            let zeros: Vec<f64> = text
                .split(',')
                .map(|z| z.trim().parse::<f64>().ok().filter(|z| z.is_finite()))
                .collect::<Option<_>>()
                .ok_or_else(|| anyhow::anyhow!("--length-zero-mm '{text}': one zero in mm, or one per pivot (Z0,Z1,…)"))?;
            anyhow::ensure!(
                zeros.len() == 1 || zeros.len() == points.len(),
                "--length-zero-mm '{text}': {} values for {} pivots; give one, or one per pivot",
                zeros.len(),
                points.len()
            );
            Some(zeros)
        }
    };
    let draw = |how: &Placement| -> anyhow::Result<Vec<kinecal::measure::Measurement>> {
        let rows = match a.ballbar_mm {
            Some(length) if a.seats.is_none() => distance_rows(truth, &points, length, a.ballbar_range_mm, how).map(|rows| match &zeros {
                Some(z) => kinecal::instrument::simulate::as_readings(rows, z),
                None => rows,
            }),
            _ => seat_rows(truth, &points, how),
        };
        rows.map_err(|e| match e {
            CalibError::Kinematics { source, .. } => anyhow::anyhow!("{option}: {source}"),
            e => anyhow::anyhow!("{option}: {e}"),
        })
    };
    let written = stage_sets(a, file, &mut outputs, "rows per point", |k, per_point| match &a.at {
        Some(at) if k == 0 => planned(at, file, truth, &points, a.seats.is_some(), a.noise_mm, rng.random()),
        _ => draw(&how(per_point, rng.random())),
    })?;
    outputs.commit()?;
    let kind = if a.seats.is_some() { "seat" } else { "pivot" };
    let distances: Vec<String> = if a.seats.is_some() {
        seat_distances(&points)
            .iter()
            .map(|d| format!("{}:{}:{:.6}", d.a, d.b, d.length))
            .collect()
    } else {
        Vec::new()
    };
    if a.json {
        let files: Vec<_> = written
            .iter()
            .map(|w| serde_json::json!({"path": w.path, "rows": w.poses}))
            .collect();
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "model": file.name, "seed": a.seed, "error_mm": a.error_mm, "error_deg": a.error_deg,
                "noise_mm": a.noise_mm, "instrument": kind, "points": points.len(), "ballbar_mm": a.ballbar_mm,
                "ballbar_range_mm": a.pivots.as_ref().map(|_| a.ballbar_range_mm),
                "seat_distances": distances, "truth": a.truth, "data": files,
            }))?
        );
        return Ok(());
    }
    println!(
        "virtual prototype of {}: ±{} mm / ±{} deg errors (seed {}) → {}",
        file.name,
        a.error_mm,
        a.error_deg,
        a.seed,
        truth_shown(a)
    );
    for w in &written {
        println!(
            "{} {kind}s × {} rows ({}), noise {} mm → {}",
            points.len(),
            w.poses / points.len(),
            match &a.at {
                Some(at) if w.path == a.out => format!("planned in {}", at.display()),
                _ => format!("tilt ≤ {}°", a.tilt_deg),
            },
            a.noise_mm,
            w.path.display()
        );
    }
    if let (Some(length), None) = (a.ballbar_mm, &a.seats) {
        println!(
            "ballbar {length} mm ± {} mm (each row's length uniform in that range)",
            a.ballbar_range_mm
        );
        if let Some(z) = &a.length_zero_mm {
            println!("written as readings (reading_mm): each length minus its pivot's zero, {z} mm");
        }
    }
    if !distances.is_empty() {
        println!(
            "the seats' distances (the artifact's known dimensions, for identify): --seat-distance {}",
            distances.join(" --seat-distance ")
        );
    }
    Ok(())
}

/// The instrument plan `at` (`kinecal plan --seats` / `--pivots`) measured on `truth`
/// ([`kinecal::instrument::measure_planned`]); `seats`: whether the points are seats.
fn planned(
    at: &Path,
    file: &ModelFile,
    truth: &dyn kinecal::Mechanism,
    points: &[nalgebra::Vector3<f64>],
    seats: bool,
    noise_mm: f64,
    seed: u64,
) -> anyhow::Result<Vec<kinecal::measure::Measurement>> {
    use kinecal::io::data_file::{read_data, InputColumns};
    let mut plan = read_data(at, &file.data_columns(), InputColumns::Required)?;
    // Planned rows at which the prototype does not assemble are not measured (a line says which).
    if let Some(u) = plan.set_aside_unassembled(truth)? {
        eprintln!("warning: {} (not measured)", u.note(&plan));
    }
    let kind = if seats { "seat" } else { "pivot" };
    anyhow::ensure!(
        plan.measurements
            .iter()
            .all(|m| m.obs.artifact_point().is_some_and(|(k, _)| k.name() == kind)),
        "{}: not a plan of {kind} rows (plan with kinecal plan --{kind}s, and measure with the same --{kind}s)",
        at.display()
    );
    kinecal::instrument::measure_planned(truth, &plan.measurements, points, noise_mm, seed, &file.inputs())
        .map_err(|e| anyhow::anyhow!("{}: {e}", at.display()))
}

/// `--spheres`, `--planes` or `--cube`: a touch probe's rows of `truth` to `--out`
/// ([`kinecal::instrument::simulate::touch_rows`]; the touched configurations are the random
/// ones nearest each surface, moved onto it).
fn touch_run(
    a: &SimulateArgs,
    file: &ModelFile,
    truth: &dyn kinecal::Mechanism,
    rng: &mut ChaCha8Rng,
    mut outputs: Outputs,
) -> anyhow::Result<()> {
    use kinecal::instrument::simulate::{random_touches, touch_planned};
    use rand::RngExt;
    anyhow::ensure!(a.per_point > 0, "--per-point: must be at least 1");
    let (kind, artifacts, probe) = a.touch.artifacts()?;
    let inputs = file.inputs();
    let plain = |e: CalibError| match e {
        CalibError::Kinematics { source, .. } => anyhow::anyhow!("{source}"),
        CalibError::InvalidOption(m) => anyhow::anyhow!("{m}"),
        e => anyhow::anyhow!("{e}"),
    };
    // A touch plan (`kinecal plan --spheres …`): its rows moved onto the real surfaces.
    let plan = match &a.at {
        Some(at) => {
            use kinecal::io::data_file::{read_data, InputColumns};
            let plan = read_data(at, &file.data_columns(), InputColumns::Required)?;
            anyhow::ensure!(
                plan.measurements
                    .iter()
                    .all(|m| matches!(m.obs, kinecal::measure::Observation::Touch(_))),
                "{}: not a plan of touches (plan with kinecal plan --spheres/--planes/--cube, and measure with the same options)",
                at.display()
            );
            Some((at, plan.measurements))
        }
        None => None,
    };
    // A ballbar's lengths beside the touches: its pivots, length and how the rows are drawn.
    let bar = match (&a.pivots, a.ballbar_mm) {
        (Some(text), Some(length)) => {
            anyhow::ensure!(plan.is_none(), "--pivots with --at: a touch plan holds only touches");
            anyhow::ensure!(a.length_zero_mm.is_none(), "--length-zero-mm: not with touches");
            let points = parse_points(text).map_err(|e| anyhow::anyhow!("--pivots {e}"))?;
            let reference =
                kinecal::instrument::simulate::reference_configuration(a.reference.as_deref(), &inputs).map_err(anyhow::Error::msg)?;
            let how = Placement {
                per_point: a.per_point,
                reference,
                max_tilt: a.tilt_deg.to_radians(),
                noise_mm: a.noise_mm,
                seed: 0,
                inputs: inputs.clone(),
            };
            Some((points, length, how))
        }
        _ => None,
    };
    // `per` touches of each artifact at the random configurations nearest it, or the plan.
    stage_sets(a, file, &mut outputs, "touches per artifact", |k, per| match (&plan, k) {
        (Some((at, rows)), 0) => touch_planned(truth, rows, &artifacts, a.noise_mm, rng.random(), &inputs)
            .map_err(|e| anyhow::anyhow!("{}: {}", at.display(), plain(e))),
        _ => {
            let mut rows = random_touches(truth, &inputs, &artifacts, per, a.noise_mm, rng).map_err(plain)?;
            if let Some(how) = &bar {
                let placement = Placement {
                    per_point: a.lengths_per_pivot.unwrap_or(per),
                    seed: rng.random(),
                    ..how.2.clone()
                };
                rows.extend(
                    distance_rows(truth, &how.0, how.1, a.ballbar_range_mm, &placement)
                        .map_err(|e| anyhow::anyhow!("--pivots: {}", plain(e)))?,
                );
            }
            Ok(rows)
        }
    })?;
    outputs.commit()?;
    println!(
        "virtual prototype of {}: ±{} mm / ±{} deg errors (seed {}) → {}",
        file.name,
        a.error_mm,
        a.error_deg,
        a.seed,
        truth_shown(a)
    );
    match &plan {
        Some((at, rows)) => println!(
            "{} planned touches of {}, probe radius {probe} mm, noise {} mm → {}",
            rows.len(),
            at.display(),
            a.noise_mm,
            a.out.display()
        ),
        None => println!(
            "{} {kind}s × {} touches, probe radius {probe} mm, noise {} mm → {}",
            artifacts.len(),
            a.per_point,
            a.noise_mm,
            a.out.display()
        ),
    }
    if let Some((points, length, _)) = &bar {
        println!(
            "and a ballbar of {length} mm ± {} mm: {} pivots × {} lengths in the same file",
            a.ballbar_range_mm,
            points.len(),
            a.lengths_per_pivot.unwrap_or(a.per_point)
        );
    }
    if let Some(v) = &a.validation_out {
        println!(
            "{} {kind}s × {} touches (held out), noise {} mm → {}",
            artifacts.len(),
            a.validation_poses,
            a.noise_mm,
            v.display()
        );
    }
    Ok(())
}

/// Where the truth went, for the messages.
fn truth_shown(a: &SimulateArgs) -> String {
    a.truth
        .as_ref()
        .map_or("not written (no --truth)".into(), |p| p.display().to_string())
}

/// Whether no errors are added: the model file is measured as it is (a truth file, say).
fn as_it_is(a: &SimulateArgs) -> bool {
    a.error_mm == 0.0 && a.error_deg == 0.0
}
