//! `kinecal plan`: choose measurement configurations (issue #5) and write them as CSV.
//!
//! For now the mechanism is a seeded random revolute serial chain (candidates drawn in joint
//! space); the library API (`kinecal::design`) is generic over any mechanism, so presets and model
//! files plug in here without changing the planning code.
use anyhow::Context;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use kinecal::design::{self, CandidateFilter, CandidateJacobians, Criterion, Sampling, SelectOptions, SelectionMethod};
use kinecal::measure::Noise;
use kinecal::model::Mechanism;
use kinecal::simulate::{random_serial_chain, ObservationKind};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `kinecal plan`.
#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Revolute joints of the built-in random serial chain.
    #[arg(long, default_value_t = 6)]
    pub joints: usize,
    /// Seed of the random chain.
    #[arg(long, default_value_t = 1)]
    pub chain_seed: u64,
    /// Number of candidate configurations (Halton points in joint space).
    #[arg(long, default_value_t = 300_000)]
    pub candidates: usize,
    /// Joint range ± (degrees) of the candidates.
    #[arg(long, default_value_t = 170.0)]
    pub joint_range_deg: f64,
    /// Largest condition number of the input Jacobian (orientation rows × 100 mm) a candidate may
    /// have; none by default.
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

/// Run the command.
pub fn run(args: PlanArgs) -> anyhow::Result<()> {
    let kind = match args.observe.as_str() {
        "pose" => ObservationKind::Pose,
        "position" => ObservationKind::Position,
        o => anyhow::bail!("--observe must be pose or position, got '{o}'"),
    };
    if args.joints == 0 || args.joints > 16 {
        anyhow::bail!("--joints must be between 1 and 16, got {}", args.joints);
    }
    let noise = Noise {
        position: args.noise_position_mm,
        orientation: args.noise_orientation_deg.to_radians(),
    };
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
    let (cands, rep) = design::candidates_in_input_box(
        &chain,
        &vec![-lim; args.joints],
        &vec![lim; args.joints],
        &Sampling::Halton {
            n: args.candidates,
            seed: args.seed,
        },
        &filter,
        Some(&inc),
    )?;
    pb.finish_and_clear();
    println!(
        "mechanism {}: {} candidates kept of {} sampled ({} near-singular, {} unreachable) in {:.2} s",
        chain.name(),
        rep.kept,
        rep.sampled,
        rep.near_singular,
        rep.unreachable,
        t.elapsed().as_secs_f64()
    );

    let t = Instant::now();
    let cols = design::identifiable_columns(
        &chain,
        &cands,
        kind,
        &noise,
        None,
        200,
        kinecal::identifiability::DEFAULT_RANK_TOLERANCE,
    )?;
    let pb = bar(cands.len() as u64, "jacobians");
    let inc = |k: u64| pb.inc(k);
    let blocks = CandidateJacobians::build(&chain, &cands, kind, &noise, &cols, Some(&inc))?;
    pb.finish_and_clear();
    println!(
        "identification Jacobian blocks: {} × {}×{} ({} identifiable of {} parameters) in {:.2} s",
        blocks.len(),
        blocks.rows_per_candidate(),
        blocks.n_columns(),
        cols.len(),
        chain.n_params(),
        t.elapsed().as_secs_f64()
    );

    let opts = SelectOptions {
        n: args.n,
        criterion: args.criterion,
        pool: args.pool,
        shortlist: args.shortlist,
        ..Default::default()
    };
    let t = Instant::now();
    let spinner = ProgressBar::new_spinner();
    let sel = design::select(&blocks, args.method, &opts, &mut |s| {
        spinner.set_message(format!(
            "{:?} {:?} #{}: size {}, score {:.5e}",
            args.method, s.action, s.candidate, s.size, s.score
        ));
        spinner.tick();
    })?;
    spinner.finish_and_clear();
    let ix = &sel.indices;
    println!(
        "{:?} on {}: {} configurations in {:.2} s ({} moves, {} chosen D-optimally before full rank)",
        sel.method,
        sel.criterion,
        sel.selected.len(),
        t.elapsed().as_secs_f64(),
        sel.history.len(),
        sel.warm_up
    );
    println!(
        "indices (scaled, dimensionless): O1 {:.4e}  O2 {:.4e} (O_T {:.3})  O3 {:.4e}  O4 {:.4e}  O5 {:.4e}  log det {:.3}",
        ix.o1, ix.o2, ix.o_t, ix.o3, ix.o4, ix.o5, ix.log_det
    );
    let file = std::fs::File::create(&args.output).with_context(|| format!("cannot create {}", args.output.display()))?;
    let angle_inputs = vec![true; args.joints];
    design::write_plan_csv(std::io::BufWriter::new(file), &chain.input_names(), &angle_inputs, &cands, &sel)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    println!(
        "wrote {} (joint values in degrees, target poses in mm and degrees)",
        args.output.display()
    );
    Ok(())
}
