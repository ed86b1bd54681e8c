//! Benchmark of measurement planning: candidate generation, Jacobian blocks and each selection
//! method, with the time per phase and the index reached.
//!
//! ```text
//! cargo run --release --example plan_bench -- --candidates 300000 --n 30 --criterion o2
//! cargo run --release --example plan_bench -- --preset pm5 --candidates 300000 --criterion o2
//! cargo run --release --example plan_bench -- --preset pm5 --grid --criterion d
//! cargo run --release --example plan_bench -- --model examples/models/hexapod-6rus.toml --methods sffs
//! ```
//!
//! With `--preset pm5` the candidates are the 5-DOF machine's platform workspace
//! (`design::candidates_in_platform_box`); measured figures are in `docs/design.md`. With
//! `--model FILE` they are those `kinecal plan --model FILE` samples in the file's workspace
//! (`design::sample_candidates`: Halton points, tool poses solved by the inverse kinematics).
//!
//! The phases after candidate generation are in [`bench`], generic over any [`Mechanism`]: to
//! benchmark another mechanism, generate its candidates (e.g. with
//! `design::candidates_in_workspace`) and call [`bench`] with it.
use clap::Parser;
use kinecal::design::{self, Candidate, CandidateFilter, CandidateJacobians, Criterion, Sampling, SelectOptions, SelectionMethod};
use kinecal::measure::Noise;
use kinecal::model::Mechanism;
use kinecal::simulate::{random_serial_chain, ObservationKind};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

#[derive(Parser, Debug)]
struct Args {
    /// Number of candidate configurations (Halton points in joint space).
    #[arg(long, default_value_t = 300_000)]
    candidates: usize,
    /// Configurations to choose.
    #[arg(long, default_value_t = 30)]
    n: usize,
    /// Criterion: d, o1, o2, o3, o4, o5.
    #[arg(long, default_value = "o2")]
    criterion: Criterion,
    /// Methods to run (comma-separated: greedy, sffs, exchange).
    #[arg(long, default_value = "greedy,sffs,exchange", value_delimiter = ',')]
    methods: Vec<SelectionMethod>,
    /// Revolute joints of the random serial chain.
    #[arg(long, default_value_t = 6)]
    joints: usize,
    /// Seed of the chain and of the Halton shift.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Draw candidates in a workspace box (±100 mm, ±10° roll/pitch/yaw around the pose at
    /// q = 0.3 rad) solved by inverse kinematics, instead of directly in joint space.
    #[arg(long)]
    workspace: bool,
    /// Benchmark a preset instead of the random chain: `pm5` (candidates in its platform
    /// workspace, filtered by IK, strokes, FK∘IK and the actuator-Jacobian condition).
    #[arg(long)]
    preset: Option<String>,
    /// Benchmark a model file (e.g. a limbs machine) instead: candidates as `kinecal plan --model`
    /// samples them in the file's workspace.
    #[arg(long)]
    model: Option<std::path::PathBuf>,
    /// Sample the pm5 workspace on the paper's grid of 304,920 points instead of Halton points.
    #[arg(long)]
    grid: bool,
    /// Largest actuator-Jacobian condition number of a pm5 candidate.
    #[arg(long, default_value_t = 100.0)]
    max_condition: f64,
    /// Shortlist size for O2–O5.
    #[arg(long, default_value_t = 32)]
    shortlist: usize,
}

/// CPU time (user + system) of this process so far, in seconds (Linux; 0 elsewhere). With the
/// machine shared, wall time depends on the load; CPU time / threads is the unloaded wall time.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the command name (which is in parentheses): utime is field 14, stime 15.
    let Some(rest) = stat.rsplit(')').next() else { return 0.0 };
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11).and_then(|v| v.parse().ok()).unwrap_or(0.0) + f.get(12).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    ticks / 100.0
}

/// Jacobian blocks and selection for any mechanism and candidate set; prints timings and indices.
fn bench<M: Mechanism + ?Sized>(mech: &M, candidates: &[Candidate], kind: ObservationKind, args: &Args) -> anyhow::Result<()> {
    let noise = Noise::default();
    let (t, c0) = (Instant::now(), cpu_seconds());
    let cols = design::identifiable_columns(mech, candidates, kind, &noise, None, 200, 1e-8)?;
    let blocks = CandidateJacobians::build(mech, candidates, kind, &noise, &cols, None)?;
    println!(
        "jacobians: {:.2} s wall, {:.2} s CPU  ({} candidates × {}×{} blocks, {} MB)",
        t.elapsed().as_secs_f64(),
        cpu_seconds() - c0,
        blocks.len(),
        blocks.rows_per_candidate(),
        blocks.n_columns(),
        blocks.data().len() * 8 / 1_000_000
    );
    for &method in &args.methods {
        let opts = SelectOptions {
            n: args.n,
            criterion: args.criterion,
            shortlist: args.shortlist,
            ..Default::default()
        };
        let (t, c0) = (Instant::now(), cpu_seconds());
        let mut moves = 0usize;
        let verbose = std::env::var("PLAN_BENCH_VERBOSE").is_ok();
        let sel = design::select(&blocks, method, &opts, &mut |s| {
            moves += 1;
            if verbose {
                eprintln!("{:?} {} size {} score {:.6e}", s.action, s.candidate, s.size, s.score);
            }
        })?;
        let ix = &sel.indices;
        println!(
            "selection {:>8?}: {:6.2} s wall, {:6.2} s CPU  {moves:3} moves  {} = {:.6e}  (O1 {:.4e}  O2 {:.4e}  O_T {:.2}  O3 {:.4e}  O4 {:.4e}  O5 {:.4e}  logdet {:.3})",
            method,
            t.elapsed().as_secs_f64(),
            cpu_seconds() - c0,
            sel.criterion,
            sel.value(),
            ix.o1,
            ix.o2,
            ix.o_t,
            ix.o3,
            ix.o4,
            ix.o5,
            ix.log_det
        );
    }
    Ok(())
}

/// The 5-DOF preset: candidates over its prescribed workspace, then [`bench`].
fn bench_pm5(args: &Args) -> anyhow::Result<()> {
    use kinecal::model::closed::ConstraintSystem;
    use kinecal::model::presets::pm5::{Parasitic, Pm5};
    let mech = Pm5::mechanism(Parasitic::Physical);
    let sampling = if args.grid {
        Sampling::Grid {
            counts: kinecal::model::presets::pm5::CANDIDATE_GRID.to_vec(),
        }
    } else {
        Sampling::Halton {
            n: args.candidates,
            seed: args.seed,
        }
    };
    let filter = CandidateFilter {
        input_limits: Some(mech.system().strokes()),
        max_condition: Some(args.max_condition),
        ..Default::default()
    };
    let (t, c0) = (Instant::now(), cpu_seconds());
    let (cands, gen) = design::candidates_in_platform_box(&mech, &mech.system().workspace(), &sampling, &filter, None)?;
    let rep = gen.report;
    println!(
        "candidates: {:.2} s wall, {:.2} s CPU  ({} sampled, {} kept, {} unreachable, {} out of strokes, {} near-singular; actuator-Jacobian condition {:.2}–{:.2}) on pm5",
        t.elapsed().as_secs_f64(),
        cpu_seconds() - c0,
        rep.sampled,
        rep.kept,
        rep.unreachable,
        rep.out_of_limits,
        rep.near_singular,
        gen.condition_min,
        gen.condition_max
    );
    bench(&mech, &cands, ObservationKind::Pose, args)
}

/// A model file: candidates in its workspace as `kinecal plan --model` makes them, then [`bench`].
fn bench_model(path: &std::path::Path, args: &Args) -> anyhow::Result<()> {
    use kinecal::design::{CandidateSampling, Points, PoseRanges, Region};
    let file = kinecal::io::model_file::ModelFile::load(path)?;
    let sampling = CandidateSampling {
        region: Region::Poses(PoseRanges {
            position: [None; 3],
            angles: [None; 3],
        }),
        points: Points::Halton {
            n: args.candidates,
            seed: args.seed,
        },
        max_condition: None,
    };
    let (t, c0) = (Instant::now(), cpu_seconds());
    let (mech, cands) = design::sample_candidates(&file, &sampling, None)?;
    let rep = cands.report;
    println!(
        "candidates: {:.2} s wall, {:.2} s CPU  ({} sampled, {} kept, {} unreachable) on {}",
        t.elapsed().as_secs_f64(),
        cpu_seconds() - c0,
        rep.sampled,
        rep.kept,
        rep.unreachable,
        mech.name()
    );
    bench(&*mech, &cands.candidates, ObservationKind::Pose, args)
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!("threads: {}, load average: {}", rayon::current_num_threads(), load.trim());
    if let Some(path) = &args.model {
        return bench_model(path, &args);
    }
    if let Some(p) = &args.preset {
        anyhow::ensure!(p == "pm5", "--preset: only pm5 is supported, got '{p}'");
        return bench_pm5(&args);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(args.seed);
    let chain = random_serial_chain(&mut rng, args.joints, 0);
    let lim = 170f64.to_radians();
    let (t, c0) = (Instant::now(), cpu_seconds());
    let sampling = Sampling::Halton {
        n: args.candidates,
        seed: args.seed,
    };
    let (cands, rep) = if args.workspace {
        let q0 = vec![0.3; args.joints];
        let home = chain.forward(&q0)?;
        let d = nalgebra::Vector3::new(100.0, 100.0, 100.0);
        let a = 10f64.to_radians();
        let ws = design::Workspace {
            position_min: home.translation.vector - d,
            position_max: home.translation.vector + d,
            reference: home.rotation,
            rpy_min: [-a; 3],
            rpy_max: [a; 3],
        };
        design::candidates_in_workspace(&chain, &ws, &sampling, Some(&q0), &CandidateFilter::default(), None)?
    } else {
        design::candidates_in_input_box(
            &chain,
            &vec![-lim; args.joints],
            &vec![lim; args.joints],
            &sampling,
            &CandidateFilter::default(),
            None,
        )?
    };
    println!(
        "candidates: {:.2} s wall, {:.2} s CPU  ({} sampled, {} kept) on {}",
        t.elapsed().as_secs_f64(),
        cpu_seconds() - c0,
        rep.sampled,
        rep.kept,
        chain.name()
    );
    bench(&chain, &cands, ObservationKind::Pose, &args)
}
