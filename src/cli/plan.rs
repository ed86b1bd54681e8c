//! `kinecal plan`: choose measurement configurations (issue #5) and write them as CSV.
//!
//! The mechanism comes from, in this order of precedence:
//! * `--preset pm5`: the 5-DOF preset ([`kinecal::model::presets::pm5`]); candidates in its
//!   platform-coordinate workspace (default: the preset's; override with `--x-mm`, `--y-mm`,
//!   `--z-mm`, `--alpha-deg`, `--beta-deg`), filtered by inverse kinematics, strokes, FK∘IK and
//!   the actuator-Jacobian condition ([`kinecal::design::closed`]);
//! * `--model NAME|FILE`: any built-in model or model file, loaded exactly as `kinecal identify`
//!   does ([`ModelFile::load_or_builtin`]); candidates in a tool-pose box (`--x-mm`, `--y-mm`,
//!   `--z-mm` required; roll/pitch/yaw about the world axes applied to the tool orientation at zero
//!   inputs, `--alpha-deg`, `--beta-deg`, `--gamma-deg`, default 0) solved by its inverse
//!   kinematics from zero inputs, input limits of the model file applied;
//! * neither: a seeded random revolute serial chain (`--joints`, `--chain-seed`), candidates in
//!   joint space (a self-contained demonstration, used by the tests).
use anyhow::Context;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use kinecal::design::{self, Candidate, CandidateFilter, Criterion, PlanOptions, Sampling, SelectOptions, SelectionMethod};
use kinecal::io::model_file::ModelFile;
use kinecal::io::output::Outputs;
use kinecal::measure::Noise;
use kinecal::model::Mechanism;
use kinecal::params::Unit;
use kinecal::simulate::{random_serial_chain, ObservationKind};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Set by `--json`: the text lines are not printed.
static QUIET: AtomicBool = AtomicBool::new(false);

/// `println!` unless `--json` asked for JSON only.
macro_rules! say {
    ($($t:tt)*) => {
        if !QUIET.load(Ordering::Relaxed) {
            println!($($t)*);
        }
    };
}

/// Arguments of `kinecal plan`.
#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Built-in preset to plan for: pm5 (the 5-DOF PUU-2PR(RPRR)S machine).
    #[arg(long, conflicts_with = "model")]
    pub preset: Option<String>,
    /// Built-in model name or model file (as for `kinecal identify`).
    #[arg(long)]
    pub model: Option<String>,
    /// Workspace range of x, "MIN,MAX" or a fixed "VALUE" (mm).
    #[arg(long, allow_hyphen_values = true)]
    pub x_mm: Option<String>,
    /// Workspace range of y (mm).
    #[arg(long, allow_hyphen_values = true)]
    pub y_mm: Option<String>,
    /// Workspace range of z (mm).
    #[arg(long, allow_hyphen_values = true)]
    pub z_mm: Option<String>,
    /// Range of α (pm5: platform X-Y-Z Euler angle α; model: roll about world x) (degrees).
    #[arg(long, allow_hyphen_values = true)]
    pub alpha_deg: Option<String>,
    /// Range of β (pm5: Euler angle β; model: pitch about world y) (degrees).
    #[arg(long, allow_hyphen_values = true)]
    pub beta_deg: Option<String>,
    /// Range of γ (model: yaw about world z; pm5: parasitic, must be a fixed value) (degrees).
    #[arg(long, allow_hyphen_values = true)]
    pub gamma_deg: Option<String>,
    /// Sample the workspace on a full grid "N1,N2,…" (one count per coordinate x, y, z, α, β, γ;
    /// pm5 default grid with --grid paper: 11,11,21,12,10,1 = 304,920 points) instead of Halton
    /// points.
    #[arg(long)]
    pub grid: Option<String>,
    /// Revolute joints of the built-in random serial chain.
    #[arg(long, default_value_t = 6)]
    pub joints: usize,
    /// Seed of the random chain.
    #[arg(long, default_value_t = 1)]
    pub chain_seed: u64,
    /// Number of candidate samples (Halton points).
    #[arg(long, default_value_t = 300_000)]
    pub candidates: usize,
    /// Joint range ± (degrees) of the candidates.
    #[arg(long, default_value_t = 170.0)]
    pub joint_range_deg: f64,
    /// Largest condition number of the input Jacobian (orientation rows × 100 mm) a candidate may
    /// have; none by default (pm5: 100).
    #[arg(long)]
    pub max_condition: Option<f64>,
    /// Configurations to choose.
    #[arg(short, long, default_value_t = 30)]
    pub n: usize,
    /// Selection method: greedy, sffs or exchange.
    #[arg(long, default_value = "sffs")]
    pub method: SelectionMethod,
    /// Index to maximise: d (log det), o1, o2 (= 1/O_T of the 5-DOF paper), o3, o4, o5.
    #[arg(long, default_value = "o2")]
    pub criterion: Criterion,
    /// What the tracker measures: pose (three reflectors) or position (one reflector).
    #[arg(long, default_value = "pose")]
    pub observe: String,
    /// Position noise (mm), the row weight of position residuals.
    #[arg(long, default_value_t = 0.020)]
    pub noise_position_mm: f64,
    /// Orientation noise (degrees), the row weight of orientation residuals.
    #[arg(long, default_value_t = 0.02)]
    pub noise_orientation_deg: f64,
    /// Candidates kept for SFFS / exchange on large sets (see `SelectOptions::pool`).
    #[arg(long, default_value_t = 10_000)]
    pub pool: usize,
    /// Candidates evaluated exactly per addition for O2–O5.
    #[arg(long, default_value_t = 32)]
    pub shortlist: usize,
    /// Seed of the Halton shift (candidate sample).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output CSV (inputs in degrees, target poses in mm and degrees).
    #[arg(short, long, default_value = "plan.csv")]
    pub output: PathBuf,
    /// Print a JSON summary (indices, chosen candidates, timings) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Replace an existing output file.
    #[arg(long)]
    pub force: bool,
}

fn bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} ({elapsed})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

/// Parse a range "MIN,MAX" or a fixed "VALUE"; `None` → `default`.
fn range(arg: &Option<String>, flag: &str, default: Option<(f64, f64)>) -> anyhow::Result<(f64, f64)> {
    let Some(text) = arg else {
        return default.ok_or_else(|| anyhow::anyhow!("--{flag} is required with --model (MIN,MAX or VALUE)"));
    };
    let v: Vec<f64> = text
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("--{flag}: expected MIN,MAX or VALUE, got '{text}'"))?;
    let r = match v.as_slice() {
        [a] => (*a, *a),
        [a, b] => (*a, *b),
        _ => anyhow::bail!("--{flag}: expected MIN,MAX or VALUE, got '{text}'"),
    };
    anyhow::ensure!(
        r.0.is_finite() && r.1.is_finite() && r.0 <= r.1,
        "--{flag}: need finite MIN ≤ MAX, got '{text}'"
    );
    Ok(r)
}

fn sampling(args: &PlanArgs, paper_grid: Option<&[usize]>) -> anyhow::Result<Sampling> {
    Ok(match &args.grid {
        None => Sampling::Halton {
            n: args.candidates,
            seed: args.seed,
        },
        Some(g) if g == "paper" => Sampling::Grid {
            counts: paper_grid
                .ok_or_else(|| anyhow::anyhow!("--grid paper is only defined for --preset pm5"))?
                .to_vec(),
        },
        Some(g) => Sampling::Grid {
            counts: g
                .split(',')
                .map(|t| t.trim().parse::<usize>())
                .collect::<Result<_, _>>()
                .map_err(|_| anyhow::anyhow!("--grid: expected six counts N1,…,N6 or 'paper', got '{g}'"))?,
        },
    })
}

/// The mechanism, its candidates and which inputs are angles (written in degrees).
struct Planned {
    mech: Box<dyn Mechanism>,
    candidates: Vec<Candidate>,
    angle_inputs: Vec<bool>,
}

fn print_generation(name: &str, rep: &design::GenerationReport, secs: f64) {
    say!(
        "mechanism {name}: {} candidates kept of {} sampled ({} unreachable, {} outside strokes/limits, {} near-singular, {} rejected) in {secs:.2} s",
        rep.kept, rep.sampled, rep.unreachable, rep.out_of_limits, rep.near_singular, rep.rejected
    );
}

/// Candidates of a 5-DOF machine (the built-in preset or a pm5 model file's geometry) in its
/// platform-coordinate workspace.
fn pm5_candidates(args: &PlanArgs, mech: kinecal::model::closed::ClosedLoop<kinecal::model::presets::pm5::Pm5>) -> anyhow::Result<Planned> {
    use kinecal::model::closed::{ConstraintSystem, Workspace};
    let ws = mech.system().workspace();
    let deg = |a: f64| a.to_degrees();
    let rd = |r: (f64, f64)| (r.0.to_radians(), r.1.to_radians());
    let x = range(&args.x_mm, "x-mm", Some((ws.min[0], ws.max[0])))?;
    let y = range(&args.y_mm, "y-mm", Some((ws.min[1], ws.max[1])))?;
    let z = range(&args.z_mm, "z-mm", Some((ws.min[2], ws.max[2])))?;
    let a = rd(range(&args.alpha_deg, "alpha-deg", Some((deg(ws.min[3]), deg(ws.max[3]))))?);
    let b = rd(range(&args.beta_deg, "beta-deg", Some((deg(ws.min[4]), deg(ws.max[4]))))?);
    let g = rd(range(&args.gamma_deg, "gamma-deg", Some((0.0, 0.0)))?);
    let ws = Workspace {
        min: [x.0, y.0, z.0, a.0, b.0, g.0],
        max: [x.1, y.1, z.1, a.1, b.1, g.1],
    };
    let sampling = sampling(args, Some(&kinecal::model::presets::pm5::CANDIDATE_GRID))?;
    // FK∘IK is checked on the chosen configurations (design::plan), not on every sample.
    let filter = CandidateFilter {
        input_limits: Some(mech.system().strokes()),
        max_condition: Some(args.max_condition.unwrap_or(100.0)),
        check_forward: false,
        ..Default::default()
    };
    let n = sampling.len(6)?;
    say!(
        "pm5 workspace: x {:?} mm, y {:?} mm, z {:?} mm, α {:?}°, β {:?}°, γ {:?}° (parasitic), {n} samples, actuator-Jacobian condition ≤ {}",
        x,
        y,
        z,
        (deg(a.0), deg(a.1)),
        (deg(b.0), deg(b.1)),
        (deg(g.0), deg(g.1)),
        filter.max_condition.unwrap_or(f64::INFINITY)
    );
    let t = Instant::now();
    let pb = bar(n as u64, "candidates");
    let inc = |k: u64| pb.inc(k);
    let (candidates, gen) = design::candidates_in_platform_box(&mech, &ws, &sampling, &filter, Some(&inc))?;
    pb.finish_and_clear();
    print_generation("pm5", &gen.report, t.elapsed().as_secs_f64());
    say!(
        "actuator-Jacobian condition of the kept candidates: {:.2} – {:.2}",
        gen.condition_min,
        gen.condition_max
    );
    Ok(Planned {
        mech: Box::new(mech),
        candidates,
        angle_inputs: vec![false; 5],
    })
}

fn model_candidates(args: &PlanArgs, model: &str) -> anyhow::Result<Planned> {
    let file = ModelFile::load_or_builtin(model)?;
    let mech = file.build();
    // A 5-DOF machine plans in its own platform workspace (the file's geometry, strokes, box).
    if let kinecal::model::kind::MechanismSpec::Pm5(pm5) = &file.mechanism {
        return pm5_candidates(args, pm5.clone());
    }
    let inputs = file.inputs();
    // A limbs mechanism starts at its home inputs and defaults to its own workspace box.
    let (zeros, own) = match &file.mechanism {
        kinecal::model::kind::MechanismSpec::Limbs(m) => (m.home_inputs(), m.workspace().cloned()),
        _ => (vec![0.0; inputs.len()], None),
    };
    let home = mech.forward(&zeros).map_err(|e| {
        anyhow::anyhow!(
            "{}: forward kinematics at its start inputs (zero, or a limbs mechanism's home): {e}",
            file.name
        )
    })?;
    let deg = |v: f64| v.to_degrees();
    let own_range = |k: usize| own.as_ref().map(|w| (w.position_min[k], w.position_max[k]));
    let own_angle = |k: usize| own.as_ref().map_or((0.0, 0.0), |w| (deg(w.rpy_min[k]), deg(w.rpy_max[k])));
    let x = range(&args.x_mm, "x-mm", own_range(0))?;
    let y = range(&args.y_mm, "y-mm", own_range(1))?;
    let z = range(&args.z_mm, "z-mm", own_range(2))?;
    let rd = |r: (f64, f64)| (r.0.to_radians(), r.1.to_radians());
    let a = rd(range(&args.alpha_deg, "alpha-deg", Some(own_angle(0)))?);
    let b = rd(range(&args.beta_deg, "beta-deg", Some(own_angle(1)))?);
    let g = rd(range(&args.gamma_deg, "gamma-deg", Some(own_angle(2)))?);
    let ws = design::Workspace {
        position_min: nalgebra::Vector3::new(x.0, y.0, z.0),
        position_max: nalgebra::Vector3::new(x.1, y.1, z.1),
        reference: home.rotation,
        rpy_min: [a.0, b.0, g.0],
        rpy_max: [a.1, b.1, g.1],
    };
    let limits: Option<Vec<(f64, f64)>> = if inputs.iter().any(|i| i.limits.is_some()) {
        Some(
            inputs
                .iter()
                .map(|i| i.limits.unwrap_or((f64::NEG_INFINITY, f64::INFINITY)))
                .collect(),
        )
    } else {
        None
    };
    let filter = CandidateFilter {
        input_limits: limits,
        max_condition: args.max_condition,
        ..Default::default()
    };
    let sampling = sampling(args, None)?;
    let t = Instant::now();
    let pb = bar(sampling.len(6)? as u64, "candidates");
    let inc = |k: u64| pb.inc(k);
    let (candidates, rep) = design::candidates_in_workspace(&*mech, &ws, &sampling, Some(&zeros), &filter, Some(&inc))?;
    pb.finish_and_clear();
    print_generation(&file.name, &rep, t.elapsed().as_secs_f64());
    Ok(Planned {
        mech,
        candidates,
        angle_inputs: inputs.iter().map(|i| i.unit == Unit::Angle).collect(),
    })
}

fn chain_candidates(args: &PlanArgs) -> anyhow::Result<Planned> {
    if args.joints == 0 || args.joints > 16 {
        anyhow::bail!("--joints must be between 1 and 16, got {}", args.joints);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(args.chain_seed);
    let chain = random_serial_chain(&mut rng, args.joints, 0);
    let lim = args.joint_range_deg.to_radians();
    let t = Instant::now();
    let pb = bar(args.candidates as u64, "candidates");
    let inc = |k: u64| pb.inc(k);
    let filter = CandidateFilter {
        max_condition: args.max_condition,
        ..Default::default()
    };
    let (candidates, rep) = design::candidates_in_input_box(
        &chain,
        &vec![-lim; args.joints],
        &vec![lim; args.joints],
        &sampling(args, None)?,
        &filter,
        Some(&inc),
    )?;
    pb.finish_and_clear();
    print_generation(chain.name(), &rep, t.elapsed().as_secs_f64());
    Ok(Planned {
        mech: Box::new(chain),
        candidates,
        angle_inputs: vec![true; args.joints],
    })
}

/// Run the command.
pub fn run(args: PlanArgs) -> anyhow::Result<()> {
    QUIET.store(args.json, Ordering::Relaxed);
    let started = Instant::now();
    let kind = match args.observe.as_str() {
        "pose" => ObservationKind::Pose,
        "position" => ObservationKind::Position,
        o => anyhow::bail!("--observe must be pose or position, got '{o}'"),
    };
    let noise = Noise {
        position: args.noise_position_mm,
        orientation: args.noise_orientation_deg.to_radians(),
        ..Noise::default()
    };
    anyhow::ensure!(
        noise.position > 0.0 && noise.orientation > 0.0 && noise.position.is_finite() && noise.orientation.is_finite(),
        "--noise-position-mm / --noise-orientation-deg must be finite and > 0"
    );
    let mut outputs = Outputs::new(args.force);
    if let Some(m) = &args.model {
        outputs.input(std::path::Path::new(m));
    }
    outputs.output(&args.output)?;
    let planned = match (&args.preset, &args.model) {
        (Some(p), _) if p == "pm5" => pm5_candidates(
            &args,
            kinecal::model::presets::pm5::Pm5::mechanism(kinecal::model::presets::pm5::Parasitic::Physical),
        )?,
        (Some(p), _) => anyhow::bail!("--preset: unknown preset '{p}' (available: pm5)"),
        (None, Some(m)) => model_candidates(&args, m)?,
        (None, None) => chain_candidates(&args)?,
    };
    let Planned {
        mech,
        candidates: cands,
        angle_inputs,
    } = planned;
    let opts = PlanOptions {
        observe: kind,
        noise,
        method: args.method,
        select: SelectOptions {
            n: args.n,
            criterion: args.criterion,
            pool: args.pool,
            shortlist: args.shortlist,
            ..Default::default()
        },
        ..Default::default()
    };
    let pb = bar(cands.len() as u64, "jacobians");
    let inc = |k: u64| pb.inc(k);
    let spinner = if args.json {
        ProgressBar::hidden()
    } else {
        ProgressBar::new_spinner()
    };
    let mut on_step = |s: &design::Step| {
        if !pb.is_finished() {
            pb.finish_and_clear();
        }
        spinner.set_message(format!(
            "{:?} {:?} #{}: size {}, score {:.5e}",
            args.method, s.action, s.candidate, s.size, s.score
        ));
        spinner.tick();
    };
    let planned = design::plan(&*mech, &cands, &opts, Some(&inc), &mut on_step)?;
    pb.finish_and_clear();
    spinner.finish_and_clear();
    let (cols, sel) = (&planned.columns, &planned.selection);
    say!(
        "identification Jacobian blocks: {} × {}×{} ({} identifiable of {} parameters) in {:.2} s",
        cands.len(),
        planned.rows_per_candidate,
        cols.len(),
        cols.len(),
        mech.n_params(),
        planned.jacobian_seconds
    );
    if !planned.set_aside.is_empty() {
        say!(
            "{} chosen candidates set aside and replaced: the forward kinematics from the home pose reaches another assembly mode there",
            planned.set_aside.len()
        );
    }
    let selection_seconds = planned.selection_seconds;
    let ix = &sel.indices;
    say!(
        "{:?} on {}: {} configurations in {:.2} s ({} moves, {} chosen D-optimally before full rank)",
        sel.method,
        sel.criterion,
        sel.selected.len(),
        selection_seconds,
        sel.history.len(),
        sel.warm_up
    );
    say!(
        "indices (scaled, dimensionless): O1 {:.4e}  O2 {:.4e} (O_T {:.3})  O3 {:.4e}  O4 {:.4e}  O5 {:.4e}  log det {:.3}",
        ix.o1,
        ix.o2,
        ix.o_t,
        ix.o3,
        ix.o4,
        ix.o5,
        ix.log_det
    );
    let mut text = Vec::new();
    design::write_plan_csv(&mut text, &mech.input_names(), &angle_inputs, &cands, sel)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    outputs.stage(&args.output, &text)?;
    outputs.commit()?;
    say!(
        "wrote {} (angle inputs in degrees, length inputs in mm, target tool poses in mm and degrees)",
        args.output.display()
    );
    if args.json {
        let summary = serde_json::json!({
            "mechanism": mech.name(),
            "candidates": cands.len(),
            "identifiable_parameters": cols.len(),
            "method": format!("{:?}", sel.method),
            "criterion": sel.criterion.to_string(),
            "configurations": sel.selected.len(),
            "chosen_candidates": sel.selected,
            "indices": {"o1": ix.o1, "o2": ix.o2, "o_t": ix.o_t, "o3": ix.o3, "o4": ix.o4, "o5": ix.o5, "log_det": ix.log_det},
            "selection_seconds": selection_seconds,
            "total_seconds": started.elapsed().as_secs_f64(),
            "output": args.output,
        });
        println!("{}", serde_json::to_string_pretty(&summary)?);
    }
    Ok(())
}
