//! `kinecal study t3r1`: the §6 simulation study of the 3T1R paper, paper vs kinecal.
use clap::Args;
use kinecal::t3r1::{run_study, PairErrorStats, StudyCase, StudyConfig};

/// Arguments of `kinecal study t3r1`.
#[derive(Args, Debug)]
pub struct StudyT3r1Args {
    /// Seed of every random draw.
    #[arg(long, default_value_t = 2020)]
    pub seed: u64,
    /// Identification poses.
    #[arg(long, default_value_t = 20)]
    pub identification_poses: usize,
    /// Validation poses.
    #[arg(long, default_value_t = 20)]
    pub validation_poses: usize,
    /// Pose position noise of the noisy run, per axis (mm); also its weight.
    #[arg(long, default_value_t = 0.02)]
    pub noise_mm: f64,
    /// Pose orientation noise of the noisy run, per axis (degrees).
    #[arg(long, default_value_t = 0.02)]
    pub noise_deg: f64,
    /// Encoder noise of the noisy run on the upper and platform angles (degrees).
    #[arg(long, default_value_t = 0.01)]
    pub encoder_noise_deg: f64,
    /// Workspace half widths x,y,z (mm) and yaw (degrees) around its centre, e.g. 80,200,80,15.
    #[arg(long, value_delimiter = ',', default_values_t = [80.0, 200.0, 80.0, 15.0])]
    pub workspace_half: Vec<f64>,
    /// The whole machine's model file the same data are also identified with, from the sliders
    /// alone (a path, or the built-in `t3r1`); its inputs must be the sliders s1..s4.
    #[arg(long, default_value = "t3r1")]
    pub model: String,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

fn line(label: &str, e: &PairErrorStats) -> String {
    format!(
        "  {label:<28} position mean {:>10.3e} max {:>10.3e} mm   orientation mean {:>10.3e} max {:>10.3e} deg",
        e.mean_position_mm, e.max_position_mm, e.mean_orientation_deg, e.max_orientation_deg
    )
}

fn print_case(name: &str, c: &StudyCase) {
    println!("\n== {name} ==");
    if let Some(n) = &c.noise {
        println!(
            "noise: pose {:.3} mm / {:.3} deg per axis, encoders {:.3} deg (validation uses noise-free readings and true poses)",
            n.position,
            n.orientation.to_degrees(),
            n.encoder.to_degrees()
        );
    }
    println!(
        "identified {} of 60 coordinates (identifiable subset, ordered QR), RLS per iteration",
        c.identified
    );
    for (k, set) in ["identification", "validation"].iter().enumerate() {
        println!("{set} poses (worse of the two chains per pose):");
        println!("{}", line("nominal model", &c.nominal[k]));
        println!("{}", line("after 1 iteration", &c.one_iteration[k]));
        let label = match c.failure() {
            None => format!("after {} iterations", c.x_norms.len()),
            Some(_) => format!("after {} its. (FAILED)", c.x_norms.len()),
        };
        println!("{}", line(&label, &c.converged[k]));
    }
    let v = &c.nominal[1];
    let f = &c.one_iteration[1];
    let l = &c.converged[1];
    println!(
        "reduction (validation, max): 1 iteration position {:.3e}x orientation {:.3e}x; converged position {:.3e}x orientation {:.3e}x",
        v.max_position_mm / f.max_position_mm,
        v.max_orientation_deg / f.max_orientation_deg,
        v.max_position_mm / l.max_position_mm,
        v.max_orientation_deg / l.max_orientation_deg
    );
    let xs: Vec<String> = c.x_norms.iter().map(|x| format!("{x:.2e}")).collect();
    println!("||X|| per iteration: {} (tolerance reached: {})", xs.join(" "), c.reached_tolerance);
    println!("idle pair B2/B4 cross-validation:");
    println!("{}", line("idle pair, validation", &c.cross_validation.idle_validation));
    println!(
        "  pairs agree to {:.3e} mm and {:.3e} deg on the validation poses",
        c.cross_validation.agreement_position_mm, c.cross_validation.agreement_orientation_deg
    );
    if !c.ablations.is_empty() {
        println!("where q_i3 comes from (same data; validation max after the iterations):");
        for a in &c.ablations {
            println!(
                "  {:<60} {:>2} iterations  {:>10.3e} mm {:>10.3e} deg  last ||X|| {:.2e}",
                a.variant, a.iterations, a.validation.max_position_mm, a.validation.max_orientation_deg, a.last_x_norm
            );
        }
        println!(
            "  {:<60} {:>2} iterations  {:>10.3e} mm {:>10.3e} deg",
            "q_i3 from the current closure with its derivative (kinecal)",
            c.x_norms.len(),
            c.converged[1].max_position_mm,
            c.converged[1].max_orientation_deg
        );
    }
    print_whole_machine(c);
    let k = &c.compensation;
    println!("compensation (§7, validation targets, calibrated IK -> sliders; T_cp = nominal FK of those sliders):");
    println!(
        "  before: position {:.3e} mm, yaw {:.3e} deg;  after: position {:.3e} mm, yaw {:.3e} deg;  tilt (not compensable) {:.4} deg;  |T_cp - T_co| up to {:.3} mm",
        k.before_position_mm, k.before_yaw_deg, k.after_position_mm, k.after_yaw_deg, k.tilt_deg, k.program_change_mm
    );
}

fn print_whole_machine(c: &StudyCase) {
    let Some(w) = &c.whole_machine else {
        println!(
            "the whole machine's model file: identification failed: {}",
            c.whole_machine_error.as_deref().unwrap_or("?")
        );
        return;
    };
    let read = if w.observed.is_empty() {
        String::new()
    } else {
        format!(", encoders {} read as observations", w.observed.join(", "))
    };
    println!(
        "the whole machine's model file, same poses, tracker and encoder noise, predicted from the sliders alone{read} (general identify, {} of {} free parameters identifiable):",
        w.rank, w.free
    );
    println!(
        "  {} after {} iterations, sigma0 {:.3}",
        if w.converged { "converged" } else { "NOT converged (FAILED)" },
        w.iterations,
        w.sigma0
    );
    for (label, e) in [
        ("nominal model", &w.nominal_validation),
        ("after 1 iteration", &w.one_iteration),
        ("calibrated, validation", &w.validation),
    ] {
        println!(
            "  {label:<28} position mean {:>10.3e} max {:>10.3e} mm   orientation mean {:>10.3e} max {:>10.3e} deg",
            e.position_mean_mm,
            e.position_max_mm,
            e.orientation_mean_deg.unwrap_or(f64::NAN),
            e.orientation_max_deg.unwrap_or(f64::NAN)
        );
    }
    let k = &w.compensation;
    println!(
        "  compensation (general compensate): before position {:.3e} mm, yaw {:.3e} deg;  after position {:.3e} mm, yaw {:.3e} deg;  tilt {:.4} deg",
        k.before_position_mm, k.before_yaw_deg, k.after_position_mm, k.after_yaw_deg, k.tilt_deg
    );
}

/// Run the command.
pub fn run(args: StudyT3r1Args) -> anyhow::Result<()> {
    let mut config = StudyConfig {
        seed: args.seed,
        identification_poses: args.identification_poses,
        validation_poses: args.validation_poses,
        noise: kinecal::t3r1::StudyNoise {
            position: args.noise_mm,
            orientation: args.noise_deg.to_radians(),
            encoder: args.encoder_noise_deg.to_radians(),
        },
        model: args.model.clone(),
        ..Default::default()
    };
    let h = &args.workspace_half;
    anyhow::ensure!(
        h.len() == 4,
        "--workspace-half: expected four values x,y,z (mm),yaw (degrees), got {}",
        h.len()
    );
    config.workspace.half.x = h[0];
    config.workspace.half.y = h[1];
    config.workspace.half.z = h[2];
    config.workspace.half.yaw = h[3].to_radians();
    let report = run_study(&config)?;
    let mut failures: Vec<String> = [("noise-free", &report.noise_free), ("noisy", &report.noisy)]
        .iter()
        .filter_map(|(name, c)| c.failure().map(|f| format!("{name} run: {f}")))
        .collect();
    // The model file's identification: both runs share their poses, so a failure for want of
    // poses is said once.
    match (report.noise_free.whole_machine_failure(), report.noisy.whole_machine_failure()) {
        (Some(a), Some(b)) if a == b => failures.push(format!("noise-free and noisy runs: {a}")),
        (a, b) => {
            failures.extend(a.map(|f| format!("noise-free run: {f}")));
            failures.extend(b.map(|f| format!("noisy run: {f}")));
        }
    }
    // Fitted or not, a pair that the identification poses do not determine is no calibration.
    failures.extend(report.too_few_poses());
    let verdict = || Err(super::FailedChecks(format!("study t3r1: {}", failures.join("; "))).into());
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return if failures.is_empty() { Ok(()) } else { verdict() };
    }
    println!(
        "kinecal study t3r1: 3T1R manipulator (Zhang et al. 2020), §6 simulation, seed {}",
        config.seed
    );
    println!("machine: l_u = l_d = 700 mm, a = 300 mm, b = 1000 mm, slider zero y = 30 mm; alpha = 45 deg, beta = 60 deg");
    let e = &config.errors;
    println!(
        "preset errors: dt = ({}, {}, {} mm, {}, {}, {} rad) on every dyad of every chain; dq = {} mm (sliders), {} rad (revolutes); axis tilts {} rad (upper pivots toward z, perpendicular to the rail)",
        e.dt[0], e.dt[1], e.dt[2], e.dt[3], e.dt[4], e.dt[5], e.offsets[0], e.offsets[1], e.tilt
    );
    println!(
        "poses: {} identification + {} validation in x 500±80, y 600±200, z -111.25±80 mm, yaw ±15 deg; worst cond d(x,y,z,(a/2)yaw)/d(sliders) = {:.1}",
        config.identification_poses, config.validation_poses, report.worst_actuator_condition
    );
    let r = &report.ranks;
    println!(
        "\nranks over {} poses (paper §3.2: 34 = 4r + 2p + 6 'maximum identifiable'):",
        r.poses
    );
    println!("  {:<46} {:>8} {:>12} {:>15}", "", "kinecal", "fixed links", "printed chains");
    let rows = [
        (
            "one chain, all q measured (/30)",
            r.link_dyads.one_chain,
            r.fixed_links.one_chain,
            r.printed_one_chain.to_string(),
        ),
        (
            "pair, q_i3 measured (/60)",
            r.link_dyads.pair_measured,
            r.fixed_links.pair_measured,
            "-".into(),
        ),
        (
            "pair, q_i3 from the model's closure (/60)",
            r.link_dyads.pair_closure,
            r.fixed_links.pair_closure,
            "-".into(),
        ),
        (
            "paper's literal A = [J1, J2] (/60)",
            r.link_dyads.paper_literal,
            r.fixed_links.paper_literal,
            r.printed_literal.to_string(),
        ),
    ];
    for (label, a, b, c) in rows {
        println!("  {label:<46} {a:>8} {b:>12} {c:>15}");
    }
    println!("  lost to the closure (kinecal): {}", r.link_dyads.lost_to_closure.join(", "));
    println!("  lost to the closure (fixed links): {}", r.fixed_links.lost_to_closure.join(", "));
    let l = &report.lower_angles;
    println!("\nlower angle q_i3 on the actual machine (true model, true readings):");
    println!(
        "  full closure: max error {:.3e} deg;  eq. (25)-(30) pseudo-inverse: max error {:.3} deg with | |A1A2| - a | <= {:.1e} mm",
        l.closure_max_error_deg, l.eq25_max_error_deg, l.eq25_distance_residual_mm
    );
    print_case("noise-free", &report.noise_free);
    print_case("noisy", &report.noisy);
    let nf = &report.noise_free;
    let red1 = (nf.nominal[1].max_position_mm / nf.one_iteration[1].max_position_mm)
        .min(nf.nominal[1].max_orientation_deg / nf.one_iteration[1].max_orientation_deg);
    let redc = (nf.nominal[1].max_position_mm / nf.converged[1].max_position_mm)
        .min(nf.nominal[1].max_orientation_deg / nf.converged[1].max_orientation_deg);
    println!("\n== paper vs kinecal ==");
    println!("  paper §6 / Fig. 4: both errors reduced >= 10x in one iteration (Table 2 lists T(0) of the printed chains, which do not close as a mechanism: not compared)");
    println!(
        "  kinecal, noise-free: {red1:.3e}x after one iteration (claim >= 10x: {}), {redc:.3e}x after convergence (claim >= 1000x: {})",
        if red1 >= 10.0 { "met" } else { "NOT met" },
        if redc >= 1000.0 { "met" } else { "NOT met" }
    );
    println!(
        "  kinecal, noisy: validation max {:.3e} mm / {:.3e} deg {} (from {:.3} mm / {:.3} deg)",
        report.noisy.converged[1].max_position_mm,
        report.noisy.converged[1].max_orientation_deg,
        if report.noisy.failure().is_some() {
            "where the iterations ended (FAILED)"
        } else {
            "after convergence"
        },
        report.noisy.nominal[1].max_position_mm,
        report.noisy.nominal[1].max_orientation_deg
    );
    println!(
        "  idle-pair cross-validation, noise-free: pairs agree to {:.3e} mm / {:.3e} deg",
        nf.cross_validation.agreement_position_mm, nf.cross_validation.agreement_orientation_deg
    );
    if !failures.is_empty() {
        return verdict();
    }
    Ok(())
}
