//! `kinecal plan`: choose measurement configurations and write them as CSV. One call,
//! [`design::plan_sampled`], makes the candidates and chooses among them; this module parses the
//! arguments (the sampling ones in [`super::sampling`]), shows progress and prints. The mechanism:
//! `--preset NAME` (built-in), `--model NAME|FILE` (as for `identify`), or neither: a seeded random
//! revolute serial chain (`--joints`, `--chain-seed`) sampled in joint space. `--iso9283`, `--seats`: other files.
use crate::cli::{progress, sampling::SamplingArgs};
use anyhow::Context;
use clap::Args;
use kinecal::design::{self, Criterion, PlanEvent, PlanOptions, SelectOptions, SelectionMethod};
use kinecal::io::{builtin, model_file::ModelFile, output::Outputs};
use kinecal::measure::Noise;
use kinecal::model::Mechanism;
use kinecal::report::plan::plan_html;
use kinecal::simulate::{random_serial_chain, ObservationKind};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `kinecal plan`.
#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Built-in model to plan for, e.g. pm5 (the 5-DOF PUU-2PR(RPRR)S machine): as --model, never a file.
    #[arg(long, conflicts_with = "model")]
    pub preset: Option<String>,
    /// Built-in model name or model file (as for `kinecal identify`).
    #[arg(long)]
    pub model: Option<String>,
    /// The model as the first argument, as for the other commands (`kinecal plan robot.toml`).
    #[arg(value_name = "MODEL", conflicts_with_all = ["preset", "model"])]
    pub model_arg: Option<String>,
    /// Where and how candidates are sampled.
    #[command(flatten)]
    pub sampling: SamplingArgs,
    /// The ISO 9283 test poses instead ([`super::iso_plan`]).
    #[command(flatten)]
    pub iso: super::iso_plan::IsoArgs,
    /// An instrument's rows instead: seats or ballbar pivots ([`super::instrument_plan`]).
    #[command(flatten)]
    pub instrument: super::instrument_plan::InstrumentArgs,
    /// Revolute joints of the built-in random serial chain.
    #[arg(long, default_value_t = 6)]
    pub joints: usize,
    /// Seed of the random chain.
    #[arg(long, default_value_t = 1)]
    pub chain_seed: u64,
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
    /// Output CSV (inputs in degrees, target poses in mm and degrees).
    #[arg(short, long, visible_alias = "out", default_value = "plan.csv")]
    pub output: PathBuf,
    /// Write an HTML report of the plan here: the candidates and the chosen configurations in 3-D,
    /// the criterion as they are added, the parameters identified and not.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Print a JSON summary (indices, chosen candidates, timings) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Replace an existing output file.
    #[arg(long)]
    pub force: bool,
}

/// The model file of the arguments, and whether it is the joint-space demonstration chain.
pub(crate) fn model(args: &PlanArgs) -> anyhow::Result<(ModelFile, bool)> {
    if let Some(p) = &args.preset {
        let names: Vec<&str> = builtin::list().into_iter().map(|(n, _)| n).collect();
        let unknown = || anyhow::anyhow!("--preset: unknown preset '{p}' (available: {})", names.join(", "));
        return Ok((builtin::model_file(p).ok_or_else(unknown)?, false));
    }
    if let Some(m) = &args.model {
        let file = ModelFile::load_or_builtin(m)?;
        super::note_held(&file, false);
        return Ok((file, false));
    }
    let joints = args.joints;
    anyhow::ensure!((1..=16).contains(&joints), "--joints must be between 1 and 16, got {joints}");
    let chain = random_serial_chain(&mut ChaCha8Rng::seed_from_u64(args.chain_seed), joints, 0);
    Ok((ModelFile::new(chain.name().to_string(), chain.into()), true))
}

/// Run the command.
pub fn run(args: PlanArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let say = |line: String| (!args.json).then(|| println!("{line}"));
    let observe: ObservationKind = args.observe.parse().map_err(|e| anyhow::anyhow!("--observe {e}"))?;
    let mut noise = Noise::default();
    (noise.position, noise.orientation) = (args.noise_position_mm, args.noise_orientation_deg.to_radians());
    let select = SelectOptions {
        n: args.n,
        criterion: args.criterion,
        pool: args.pool,
        shortlist: args.shortlist,
        ..Default::default()
    };
    let opts = PlanOptions {
        observe,
        noise,
        method: args.method,
        select,
        ..Default::default()
    };
    opts.check()
        .map_err(|e| anyhow::anyhow!("--noise-position-mm / --noise-orientation-deg: {e}"))?;
    let mut outputs = Outputs::new(args.force);
    if let Some(m) = &args.model {
        outputs.input(std::path::Path::new(m));
    }
    outputs.output(&args.output)?.output_opt(args.report.as_deref())?;
    let (file, demo) = model(&args)?;
    let sampling = args.sampling.sampling(demo.then(|| file.inputs().len()));
    let stages = progress::Stages::new(args.json);
    let on_event = |e: PlanEvent| match e {
        PlanEvent::Sampling {
            space,
            samples,
            max_condition,
        } => {
            let cond = max_condition.map_or(String::new(), |m| format!(", actuator-Jacobian condition ≤ {m}"));
            say(format!("{} workspace: {space}, {samples} samples{cond}", file.name));
            stages.start(samples, "candidates");
        }
        PlanEvent::Done(k) => stages.inc(k),
        PlanEvent::Generated(c) => {
            stages.end();
            say(format!("mechanism {}: {} in {:.2} s", file.name, c.report, c.seconds));
            if let Some((lo, hi)) = c.condition {
                say(format!("actuator-Jacobian condition of the kept candidates: {lo:.2} – {hi:.2}"));
            }
        }
        PlanEvent::Jacobians { blocks } => stages.start(blocks, "jacobians"),
        PlanEvent::Step(s) => stages.spin(format!(
            "{:?} {:?} #{}: size {}, score {:.5e}",
            args.method, s.action, s.candidate, s.size, s.score
        )),
    };
    let planned = design::plan_sampled(&file, &sampling, &opts, Some(&on_event));
    stages.finish();
    let planned = planned?;
    let (p, sel, n) = (&planned.plan, &planned.plan.selection, planned.candidates.candidates.len());
    let (cols, rows, params, secs) = (p.columns.len(), p.rows_per_candidate, planned.parameters, p.jacobian_seconds);
    say(format!(
        "identification Jacobian blocks: {n} × {rows}×{cols} ({cols} identifiable of {params} parameters) in {secs:.2} s"
    ));
    let aside = p.set_aside.len();
    (aside > 0).then(|| say(format!("{aside} chosen candidates set aside and replaced: the forward kinematics from the home pose reaches another assembly mode there")));
    let (chosen, moves, warm, secs) = (sel.selected.len(), sel.history.len(), sel.warm_up, p.selection_seconds);
    say(format!(
        "{:?} on {}: {} in {secs:.2} s ({moves} moves, {warm} chosen D-optimally before full rank)",
        sel.method,
        sel.criterion,
        super::count(chosen, "configuration")
    ));
    say(format!("indices (scaled, dimensionless): {}", sel.indices));
    if let Some(line) = sel
        .indices
        .rank_shortfall(&format!("the plan's {}", super::count(chosen, "configuration")))
    {
        anyhow::ensure!(args.force, "{line}");
        eprintln!("warning: {line}");
    }
    let mut text = Vec::new();
    planned
        .write_csv(&mut text)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    outputs.stage(&args.output, &text)?;
    if let Some(path) = &args.report {
        outputs.stage(path, plan_html(&planned).map_err(|e| anyhow::anyhow!("report: {e}"))?.as_bytes())?;
    }
    outputs.commit()?;
    say(format!(
        "wrote {} (angle inputs in degrees, length inputs in mm, target tool poses in mm and degrees)",
        args.output.display()
    ));
    if args.json {
        let mut summary = planned.summary();
        summary["total_seconds"] = started.elapsed().as_secs_f64().into();
        summary["output"] = serde_json::json!(args.output);
        println!("{}", serde_json::to_string_pretty(&summary)?);
    }
    Ok(())
}
