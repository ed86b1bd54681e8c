//! `kinecal study pm5 | t3r1`: the seed papers' simulation studies, paper vs kinecal.
use clap::{Args, Subcommand, ValueEnum};
use kinecal::design::{Criterion, SelectionMethod};
use kinecal::model::presets::pm5::Parasitic;
use kinecal::study::{
    pm5_design_study, pm5_plan, pm5_study, CompensatedErrorStats, Compensation, DesignStudyOptions, PlanOptions, Pm5Study, StudyOptions,
    SubLoopChoice,
};
use std::time::Instant;

/// Arguments of `kinecal study`.
#[derive(Args, Debug)]
pub struct StudyCommand {
    #[command(subcommand)]
    which: Study,
}

/// Which study.
#[derive(Subcommand, Debug)]
pub enum Study {
    /// §5.1 of the 5-DOF paper: the PUU-2PR(RPRR)S machine, random errors, 30 identification and
    /// 20 verification configurations, noise-free and noisy, exact and first-order compensation,
    /// Monte-Carlo.
    Pm5(StudyArgs),
    /// Does planning matter: Monte-Carlo on the 5-DOF machine comparing identification on planned
    /// configuration sets (greedy/SFFS/exchange on O2 and D) with fresh random sets of the same
    /// size: verification error after exact compensation, mean and 95th percentile.
    Pm5Design(DesignArgs),
    /// §6 of the 3T1R paper: ranks, identification of the B1/B3 pair with the closure-computed
    /// lower angles, idle-pair cross-validation and §7 compensation, noise-free and noisy.
    T3r1(super::study_t3r1::StudyT3r1Args),
}

/// Run `kinecal study …`.
pub fn run(cmd: StudyCommand) -> anyhow::Result<()> {
    match cmd.which {
        Study::Pm5(a) => run_pm5(a),
        Study::Pm5Design(a) => run_design(a),
        Study::T3r1(a) => super::study_t3r1::run(a),
    }
}

/// Parasitic-constraint model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ParasiticArg {
    /// Evaluated on the real geometry (physically consistent, default).
    Physical,
    /// Evaluated error-free on the nominal geometry (the paper's model).
    Paper,
}

/// Sub-loop parameters kept in dW′.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SubLoopArg {
    /// Keep dl2, dl3, dg4 (and dl6, dl7, dg5).
    L2l3,
    /// Keep dl4, dl5, dg4 (and dl8, dl9, dg5), as the paper.
    L4l5,
}

/// Arguments of `kinecal study pm5`.
#[derive(Args, Debug)]
pub struct StudyArgs {
    /// Seed of the single trial (Monte-Carlo draw k uses seed + 1 + k).
    #[arg(long, default_value_t = 2024)]
    pub seed: u64,
    /// Monte-Carlo draws.
    #[arg(long, default_value_t = 100)]
    pub draws: usize,
    /// Identification configurations.
    #[arg(long, default_value_t = 30)]
    pub identification: usize,
    /// Verification configurations.
    #[arg(long, default_value_t = 20)]
    pub verification: usize,
    /// Parasitic-constraint model of truth and identified model.
    #[arg(long, value_enum, default_value_t = ParasiticArg::Physical)]
    pub parasitic: ParasiticArg,
    /// Sub-loop parameters dW′ keeps: l2l3 (dl2 dl3 dg4, the default) or l4l5 (the paper's).
    #[arg(long, value_enum, default_value_t = SubLoopArg::L2l3)]
    pub sub_loop: SubLoopArg,
    /// Identification configurations: random (fresh per trial, default) or optimised (one set
    /// planned by SFFS on O2 over --plan-candidates Halton candidates, used in every trial).
    #[arg(long, value_enum, default_value_t = ConfigurationsArg::Random)]
    pub configurations: ConfigurationsArg,
    /// Candidates of the plan (with --configurations optimised).
    #[arg(long, default_value_t = 300_000)]
    pub plan_candidates: usize,
    /// Plan on the paper-sized grid (11·11·21·12·10 = 304,920 points, corners included) instead
    /// of --plan-candidates Halton points.
    #[arg(long)]
    pub plan_grid: bool,
    /// Method of the plan (with --configurations optimised): greedy, sffs or exchange.
    #[arg(long, default_value = "sffs")]
    pub plan_method: SelectionMethod,
    /// Criterion of the plan (with --configurations optimised): d, o1 … o5.
    #[arg(long, default_value = "o2")]
    pub plan_criterion: Criterion,
    /// Print JSON instead of tables.
    #[arg(long)]
    pub json: bool,
}

/// Where the identification configurations come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ConfigurationsArg {
    /// Random in the workspace, fresh per trial.
    Random,
    /// Planned, the same set in every trial.
    Optimised,
}

/// Arguments of `kinecal study pm5-design`.
#[derive(Args, Debug)]
pub struct DesignArgs {
    /// Seed: draw k uses seed + k.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Monte-Carlo draws.
    #[arg(long, default_value_t = 200)]
    pub draws: usize,
    /// Verification configurations per draw (fresh random).
    #[arg(long, default_value_t = 50)]
    pub verification: usize,
    /// Halton candidates of the plan.
    #[arg(long, default_value_t = 300_000)]
    pub candidates: usize,
    /// Sample the paper-sized grid (304,920 points, corners included) instead of Halton points.
    #[arg(long)]
    pub grid: bool,
    /// Configurations per set.
    #[arg(short, long, default_value_t = 30)]
    pub n: usize,
    /// Optimised sets, comma-separated METHOD:CRITERION (methods greedy, sffs, exchange;
    /// criteria d, o1 … o5).
    #[arg(long, default_value = "greedy:o2,sffs:o2,exchange:o2,greedy:d,exchange:d", value_delimiter = ',')]
    pub sets: Vec<String>,
    /// Print JSON instead of tables.
    #[arg(long)]
    pub json: bool,
}

fn parse_sets(sets: &[String]) -> anyhow::Result<Vec<(SelectionMethod, Criterion)>> {
    sets.iter()
        .map(|s| {
            let (m, c) = s
                .split_once(':')
                .ok_or_else(|| anyhow::anyhow!("--sets: expected METHOD:CRITERION, got '{s}'"))?;
            let m: SelectionMethod = m.parse().map_err(|e| anyhow::anyhow!("--sets '{s}': {e}"))?;
            let c: Criterion = c.parse().map_err(|e| anyhow::anyhow!("--sets '{s}': {e}"))?;
            Ok((m, c))
        })
        .collect()
}

fn run_design(args: DesignArgs) -> anyhow::Result<()> {
    let methods = parse_sets(&args.sets)?;
    let start = Instant::now();
    let sp = super::progress::spinner(
        &format!("planning {} sets of {} on {} candidates", methods.len(), args.n, args.candidates),
        args.json,
    );
    let plan = pm5_plan(
        &PlanOptions {
            candidates: args.candidates,
            paper_grid: args.grid,
            n: args.n,
            ..PlanOptions::default()
        },
        &methods,
    )?;
    sp.finish_and_clear();
    let plan_secs = start.elapsed().as_secs_f64();
    let sp = super::progress::spinner(
        &format!("Monte-Carlo: {} draws × {} identifications", args.draws, methods.len() + 1),
        args.json,
    );
    let opts = DesignStudyOptions {
        seed: args.seed,
        draws: args.draws,
        verification: args.verification,
        ..DesignStudyOptions::default()
    };
    let study = pm5_design_study(plan, &opts)?;
    sp.finish_and_clear();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&study)?);
        return Ok(());
    }
    let p = &study.plan;
    println!(
        "kinecal study pm5-design — does planning matter? (seed {}, {} draws, errors ±{} mm / ±{:.3}°, noise {:.0} µm / {:.3}°)",
        opts.seed,
        opts.draws,
        opts.error_length,
        opts.error_angle.to_degrees(),
        p.options.noise.position * 1000.0,
        p.options.noise.orientation.to_degrees()
    );
    println!(
        "plan: {} candidates kept of {} ({:.1} s), Jacobian blocks on {} parameters ({:.1} s), {} sets of {} ({:.1} s in all)",
        p.generation.kept,
        p.generation.sampled,
        p.candidate_seconds,
        p.columns.len(),
        p.jacobian_seconds,
        p.sets.len(),
        p.options.n,
        plan_secs
    );
    println!(
        "verification: {} fresh random configurations per draw; identification on {} configurations; exact compensation",
        opts.verification, p.options.n
    );
    println!(
        "  {:<20} {:>10} {:>11} {:>11} {:>11} {:>11} {:>10} {:>8} {:>6}",
        "set", "O2 (norm.)", "pos mean", "pos p95", "axis mean", "axis p95", "pos/random", "wins", "failed"
    );
    let random = study.rows.last().map(|r| r.position.mean).unwrap_or(f64::NAN);
    for r in &study.rows {
        println!(
            "  {:<20} {:>10.3e} {:>8.4} mm {:>8.4} mm {:>9.5}° {:>9.5}° {:>10.3} {:>7.0}% {:>6}",
            r.set,
            r.o2,
            r.position.mean,
            r.position.p95,
            r.axis.mean,
            r.axis.p95,
            r.position.mean / random,
            100.0 * r.beats_random,
            r.failures
        );
    }
    println!(
        "(per-draw mean verification error, then mean and 95th percentile over draws; wins: draws in which the set's\n position error is below the random set's on the same errors and verification poses; {:.1} s)",
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn row(label: &str, s: &CompensatedErrorStats, paper: Option<(f64, f64)>) -> String {
    let p = paper
        .map(|(a, b)| format!("{a:>8.3} {b:>8.3}"))
        .unwrap_or_else(|| format!("{:>8} {:>8}", "–", "–"));
    format!(
        "  {label:<26} {:>9.3e} {:>9.3e} {:>9.3e} {:>9.3e} {:>9.3e} {:>9.3e}   {p}",
        s.position_mean, s.position_max, s.rotation_mean, s.rotation_max, s.axis_mean, s.axis_max
    )
}

fn block(title: &str, c: &Compensation, paper_before: Option<(f64, f64)>, paper_after: Option<(f64, f64)>) {
    println!("{title}");
    println!(
        "  {:<26} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}   {:>8} {:>8}",
        "", "pos mean", "pos max", "rot mean", "rot max", "axis mean", "axis max", "paper mm", "paper °"
    );
    println!("{}", row("before calibration", &c.before, paper_before));
    println!("{}", row("after exact (calibrated IK)", &c.exact, paper_after));
    println!("{}", row("after first order Q−H′dW′", &c.first_order, None));
}

fn print(study: &Pm5Study, secs: f64) {
    let o = &study.options;
    println!(
        "kinecal study pm5 — §5.1 of the 5-DOF paper (seed {}, parasitic constraint {:?})",
        o.seed, o.parasitic
    );
    println!(
        "errors uniform ±{} mm / ±{:.3}°, noise σ = {:.0} µm / {:.3}°, {} identification + {} verification configurations",
        o.error_length,
        o.error_angle.to_degrees(),
        o.noise.position * 1000.0,
        o.noise.orientation.to_degrees(),
        o.identification,
        o.verification
    );
    for a in &study.identifiability {
        println!(
            "identifiability ({:?} parasitic constraint, {} random configurations): rank {} of 44, weakest σ/σmax {:.1e}, redundant {}",
            a.parasitic,
            a.configurations,
            a.rank,
            a.weakest,
            a.redundant.join(" ")
        );
    }
    println!("dW′ sub-loop choice: {:?}", o.sub_loop);
    println!("paper (§3.2): rank 35 of 44, redundant db1y db2y dl2 dl3 db3y dl6 dl7 dty dy0 (after reordering)");
    println!(
        "identified dW′ ({} parameters) = {}",
        study.identified.len(),
        study.identified.join(" ")
    );
    println!("units: position mm, rotation (full) and axis (tool z-axis direction) in degrees");
    let p = &study.paper;
    for (name, t, after) in [
        ("NOISE-FREE", &study.noise_free, p.after_noise_free),
        ("WITH NOISE", &study.noisy, p.after_noisy),
    ] {
        println!();
        println!(
            "{name}: {} Gauss–Newton iterations, converged {}, σ̂0 = {:.3}",
            t.iterations, t.converged, t.sigma0
        );
        block(
            "identification configurations (the paper's set)",
            &t.identification_set,
            Some(p.before),
            Some(after),
        );
        block("verification configurations (held out)", &t.verification_set, None, None);
    }
    let m = &study.monte_carlo;
    println!();
    println!(
        "MONTE-CARLO with noise: {} draws ({} failed); per-draw mean error after exact compensation: mean / 95th percentile over draws",
        m.draws,
        m.failures.len()
    );
    println!(
        "  verification   position {:.4} / {:.4} mm   tool axis {:.4} / {:.4}°   rotation {:.4} / {:.4}°",
        m.verification_position.mean,
        m.verification_position.p95,
        m.verification_axis.mean,
        m.verification_axis.p95,
        m.verification_rotation.mean,
        m.verification_rotation.p95
    );
    println!(
        "  identification position {:.4} / {:.4} mm   tool axis {:.4} / {:.4}°   rotation {:.4} / {:.4}°",
        m.identification_position.mean,
        m.identification_position.p95,
        m.identification_axis.mean,
        m.identification_axis.p95,
        m.identification_rotation.mean,
        m.identification_rotation.p95
    );
    println!(
        "  verification, first-order compensation: position {:.4} / {:.4} mm   tool axis {:.4} / {:.4}°",
        m.first_order_position.mean, m.first_order_position.p95, m.first_order_axis.mean, m.first_order_axis.p95
    );
    for f in &m.failures {
        println!("  failed: {f}");
    }
    println!(
        "  paper (one trial, its 30 optimised configurations): {:.3} mm, {:.3}°",
        p.after_noisy.0, p.after_noisy.1
    );
    println!("  independent reference (computed apart from kinecal, 30 random configurations, 100 draws): 0.021 mm, 0.011° tool axis");
    println!();
    println!("notes: the full rotation includes the rotation about the tool axis, a parasitic motion the machine");
    println!("cannot command; the tool axis is the controllable part. With noise and dW′ keeping dl2 dl3 dg4, dl2/dl3");
    println!("(dl6/dl7) are poorly determined (σ of 10-20 mm), so dW′ can be mm away from the truth along directions");
    println!("the poses hardly see: exact compensation is insensitive to that, the first-order Q − H′dW′ is not");
    println!("(try --sub-loop l4l5, the paper's dW′, for small identified values and a working first-order row).");
    println!();
    println!("time {secs:.2} s");
}

/// Run `kinecal study pm5`.
fn run_pm5(args: StudyArgs) -> anyhow::Result<()> {
    {
        {
            let opts = StudyOptions {
                seed: args.seed,
                draws: args.draws,
                identification: args.identification,
                verification: args.verification,
                parasitic: match args.parasitic {
                    ParasiticArg::Physical => Parasitic::Physical,
                    ParasiticArg::Paper => Parasitic::NominalGeometry,
                },
                sub_loop: match args.sub_loop {
                    SubLoopArg::L2l3 => SubLoopChoice::KeepL2L3,
                    SubLoopArg::L4l5 => SubLoopChoice::KeepL4L5,
                },
                ..StudyOptions::default()
            };
            let mut opts = opts;
            if args.configurations == ConfigurationsArg::Optimised {
                let sp = super::progress::spinner(
                    &format!(
                        "planning {} configurations ({:?} on {}) over {} candidates",
                        args.identification, args.plan_method, args.plan_criterion, args.plan_candidates
                    ),
                    args.json,
                );
                let plan = pm5_plan(
                    &PlanOptions {
                        candidates: args.plan_candidates,
                        paper_grid: args.plan_grid,
                        n: args.identification,
                        parasitic: opts.parasitic,
                        sub_loop: opts.sub_loop,
                        ..PlanOptions::default()
                    },
                    &[(args.plan_method, args.plan_criterion)],
                )?;
                sp.finish_and_clear();
                let set = &plan.sets[0];
                if !args.json {
                    println!(
                        "optimised identification configurations: {:?} on {} over {} candidates, O_T {:.1} (scaled), the same {} in every trial",
                        set.method, set.criterion, plan.generation.kept, set.indices.o_t, args.identification
                    );
                }
                opts.planned = Some(set.inputs.clone());
            }
            let start = Instant::now();
            let study = pm5_study(&opts)?;
            let secs = start.elapsed().as_secs_f64();
            if args.json {
                println!("{}", serde_json::to_string_pretty(&study)?);
            } else {
                print(&study, secs);
            }
            let failed: Vec<String> = [("noise-free", &study.noise_free), ("noisy", &study.noisy)]
                .iter()
                .filter(|(_, t)| !t.converged)
                .map(|(name, t)| format!("the {name} identification did not converge after {} iterations", t.iterations))
                .collect();
            if !failed.is_empty() {
                return Err(super::FailedChecks(format!("study pm5: {}", failed.join("; "))).into());
            }
            Ok(())
        }
    }
}
