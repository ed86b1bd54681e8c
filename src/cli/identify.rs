//! `kinecal identify MODEL DATA`: identify the free parameters → calibrated model file + report.
use super::progress;
use clap::{Args, ValueEnum};
use kinecal::calibrate::{calibrate, CalibrationOptions, FrameMode, ReflectorFit};
use kinecal::identify::{Loss, Method};
use kinecal::io::data_file::{read_data, InputColumns};
use kinecal::io::model_file::{ModelFile, Provenance};
use kinecal::io::output::Outputs;
use kinecal::measure::Noise;
use kinecal::report::{ParamStatus, Status};
use kinecal::simulate::default_noise;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Identification algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// Iterated Gauss–Newton with Levenberg–Marquardt fallback (converges on nonlinear models).
    GaussNewton,
    /// One linearisation, batch least squares.
    Linear,
    /// One linearisation, recursive least squares pose by pose.
    Recursive,
}

/// Where the data's frames come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FramesArg {
    /// Find them from the data (frame registration), then identify them with the geometry.
    Estimate,
    /// The data are in the model file's frames.
    Model,
}

/// How reflector triples are fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ReflectorsArg {
    /// The frame the three reflectors define.
    Frame,
    /// The three reflector points themselves.
    Points,
}

/// Arguments of `kinecal identify`.
#[derive(Args, Debug)]
pub struct IdentifyArgs {
    /// Starting (nominal) model: a model file or a built-in name. Its [calibration] free/fixed
    /// lists choose what is identified, in priority order.
    pub model: String,
    /// Measurement data file (CSV; see docs/workflow.md for the columns). With `--prior`, the
    /// only file given: `kinecal identify --prior CAL NEW.csv -o OUT`.
    #[arg(required_unless_present = "prior")]
    pub data: Option<PathBuf>,
    /// Update the calibrated model file CAL from a few new poses (the only positional file is
    /// then the data): its parameters and their covariance as prior information, the new poses
    /// as data; where they contradict the prior, the pattern that explains it (a joint offset, a
    /// length, the tool, a uniform scale) is released, each release tested at --false-alarm.
    #[arg(long, value_name = "CAL")]
    pub prior: Option<PathBuf>,
    /// With `--prior`: the false-alarm rate of each release and of the final test, in percent.
    #[arg(long, default_value_t = 100.0 * kinecal::drift::DEFAULT_FALSE_ALARM, requires = "prior")]
    pub false_alarm: f64,
    /// Where to write the calibrated model (TOML, same format and units as the input model).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Independent validation data (CSV), evaluated before and after calibration. Instrument
    /// data (seats, pivots, touches) are held-out placements: their artifacts are their own,
    /// each placed by its own rows with the model fixed, as `kinecal validate` judges them.
    #[arg(long)]
    pub validation: Option<PathBuf>,
    /// A known distance between two seats of the validation data, `A:B:MM`, numbered as in that
    /// file (its seats are its own, whatever the identification data's numbers); its error is
    /// reported before and after and judged. Repeat for more.
    #[arg(long = "validation-seat-distance", value_name = "A:B:MM", requires = "validation")]
    pub validation_seat_distances: Vec<kinecal::instrument::SeatDistance>,
    /// Write the HTML report here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Algorithm.
    #[arg(long, value_enum, default_value_t = MethodArg::GaussNewton)]
    pub method: MethodArg,
    /// Position noise σ per axis (mm) used as weight; default: the model file's [noise], else 0.02.
    #[arg(long)]
    pub noise_mm: Option<f64>,
    /// Orientation noise σ per axis (degrees) used as weight; default: the model file's [noise], else 0.02.
    #[arg(long)]
    pub noise_deg: Option<f64>,
    /// Noise σ of the observed joints' readings (degrees; passive-joint encoders, `role =
    /// "observed"`) used as weight; default 0.01.
    #[arg(long)]
    pub encoder_noise_deg: Option<f64>,
    /// Noise σ of the observed prismatic joints' readings (mm) used as weight; default 0.01.
    #[arg(long)]
    pub encoder_noise_mm: Option<f64>,
    /// One instrument kind's noise σ (mm) used as weight for its rows, `KIND=MM` with KIND
    /// `seat` or `distance` (e.g. `seat=0.005`); repeat for more. Default: the model file's
    /// [noise], else the position noise.
    #[arg(long = "kind-noise", value_name = "KIND=MM")]
    pub kind_noise: Vec<String>,
    /// Re-estimate the position / orientation noise from the residuals (real data).
    #[arg(long)]
    pub reweight: bool,
    /// Print the report as JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Where the data's frames come from: `estimate` finds the measurement (tracker) frame and the
    /// tool / reflector offset from the data and identifies them with the geometry (data in any
    /// frame); `model` takes the data to be in the model file's own frames.
    #[arg(long, value_enum, default_value_t = FramesArg::Estimate)]
    pub frames: FramesArg,
    /// Huber threshold against gross blunders, in robust standard deviations of the per-pose
    /// residuals (poses beyond it are down-weighted and listed); 0 = plain least squares.
    #[arg(long, default_value_t = kinecal::calibrate::DEFAULT_HUBER_K)]
    pub huber: f64,
    /// Starts of the identification: the registered start plus perturbed ones (geometry moved at
    /// random within a third of the model's tolerances); starts whose predictions disagree by
    /// more than the stated noise fail the calibration.
    #[arg(long, default_value_t = kinecal::calibrate::DEFAULT_STARTS, value_parser = clap::value_parser!(u64).range(1..=100))]
    pub starts: u64,
    /// Seed of the perturbed starts.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// How three reflector centres per pose (m1x_mm … m3z_mm) are fitted: `frame` (the frame
    /// they define, 6 rows per pose) or `points` (the three points, 9 rows per pose: the
    /// tracker's own measurement model). Validation is on the frame either way.
    #[arg(long, value_enum, default_value_t = ReflectorsArg::Frame)]
    pub reflectors: ReflectorsArg,
    /// Replace existing output files; and write the model and report even when the calibration
    /// failed its checks (marked failed in both; the exit code is still 2).
    #[arg(long)]
    pub force: bool,
    /// A known distance between two seats of one artifact, `A:B:MM` (seat data: the scale that
    /// seats alone do not give); repeat for more.
    #[arg(long = "seat-distance", value_name = "A:B:MM")]
    pub seat_distances: Vec<kinecal::instrument::SeatDistance>,
}

/// The noise weights, the observed joints' encoders' included (degrees, mm): command line, else
/// model file, else the default.
pub fn resolve_noise(
    file: &ModelFile,
    mm: Option<f64>,
    deg: Option<f64>,
    encoder_deg: Option<f64>,
    encoder_mm: Option<f64>,
    kind_noise: &[String],
) -> anyhow::Result<Noise> {
    let base = file.noise.unwrap_or_else(default_noise);
    let mut kinds = base.kinds;
    for k in kind_noise {
        kinds.set_from(k).map_err(|e| anyhow::anyhow!("--kind-noise {e}"))?;
    }
    let n = Noise {
        position: mm.unwrap_or(base.position),
        orientation: deg.map(f64::to_radians).unwrap_or(base.orientation),
        joint_angle: encoder_deg.map(f64::to_radians).unwrap_or(base.joint_angle),
        joint_length: encoder_mm.unwrap_or(base.joint_length),
        kinds,
    };
    anyhow::ensure!(
        n.position > 0.0 && n.orientation > 0.0 && n.position.is_finite() && n.orientation.is_finite(),
        "--noise-mm / --noise-deg: must be finite and > 0"
    );
    anyhow::ensure!(
        n.joint_angle > 0.0 && n.joint_length > 0.0 && n.joint_angle.is_finite() && n.joint_length.is_finite(),
        "--encoder-noise-deg / --encoder-noise-mm: must be finite and > 0"
    );
    Ok(n)
}

/// Run the command.
pub fn run(a: IdentifyArgs) -> anyhow::Result<()> {
    if let Some(prior) = a.prior.clone() {
        anyhow::ensure!(
            a.data.is_none(),
            "--prior takes the place of MODEL: give the new poses' file only (kinecal identify --prior {} NEW.csv -o OUT)",
            prior.display()
        );
        return super::identify_prior::run(&a, &prior, Path::new(&a.model));
    }
    let data_path = a.data.clone().expect("clap requires DATA without --prior");
    let mut outputs = Outputs::new(a.force);
    outputs.input(Path::new(&a.model)).input(&data_path);
    if let Some(v) = &a.validation {
        outputs.input(v);
    }
    outputs.output(&a.out)?.output_opt(a.report.as_deref())?;
    let file = ModelFile::load_or_builtin(&a.model)?;
    super::note_held(&file, a.json);
    let inputs = file.data_columns();
    let mut data = read_data(&data_path, &inputs, InputColumns::Required)?;
    let mut validation = match &a.validation {
        Some(p) => Some(read_data(p, &inputs, InputColumns::Required)?),
        None => None,
    };
    let observed: Vec<&str> = inputs.iter().filter(|c| c.observed).map(|c| c.name.as_str()).collect();
    if !observed.is_empty() && data.measurements.first().is_some_and(|m| m.joints.is_empty()) {
        eprintln!(
            "note: {} holds no readings of the model's observed joints ({}): fitted from the poses alone, their encoders' zeros stay unidentified",
            data_path.display(),
            observed.join(", ")
        );
    }
    let opts = CalibrationOptions {
        compare_terms: true,
        seat_distances: a.seat_distances.clone(),
        validation_seat_distances: a.validation_seat_distances.clone(),
        method: match a.method {
            MethodArg::GaussNewton => Method::GaussNewton,
            MethodArg::Linear => Method::Linear,
            MethodArg::Recursive => Method::Recursive,
        },
        noise: resolve_noise(
            &file,
            a.noise_mm,
            a.noise_deg,
            a.encoder_noise_deg,
            a.encoder_noise_mm,
            &a.kind_noise,
        )?,
        reweight: a.reweight,
        frames: match a.frames {
            FramesArg::Estimate => FrameMode::Estimate,
            FramesArg::Model => FrameMode::Model,
        },
        loss: if a.huber > 0.0 {
            anyhow::ensure!(
                a.huber.is_finite(),
                "--huber: must be a finite number of standard deviations (0 = off)"
            );
            Loss::Huber { k: a.huber }
        } else {
            Loss::Squares
        },
        starts: a.starts,
        seed: a.seed,
        reflectors: match a.reflectors {
            ReflectorsArg::Frame => ReflectorFit::Frame,
            ReflectorsArg::Points => ReflectorFit::Points,
        },
    };
    for d in std::iter::once(&data).chain(validation.as_ref()) {
        super::check_units(&file, d, false)?;
        if let Some(note) = d.derived_note() {
            eprintln!("note: {note}");
        }
        if let Some(note) = d.dropped_note() {
            eprintln!("{note}");
        }
        super::warn_limits(d);
    }
    for w in kinecal::calibrate::checks::plausible_seat_distances(&file, &data, &opts.seat_distances)? {
        eprintln!("warning: {w}");
    }
    let sp = progress::spinner(
        &format!("identifying {} on {}", file.name, super::count(data.measurements.len(), "pose")),
        a.json,
    );
    let cal = match calibrate(&file, &data, validation.as_ref(), &opts) {
        // Rows at which the model does not assemble are set aside with a line (as blunders are)
        // when the rest is enough, and the calibration runs on the rest; any other error stands.
        Err(e) => {
            let model = file.build();
            let mut aside = false;
            for d in std::iter::once(&mut data).chain(validation.as_mut()) {
                if let Some(u) = d.set_aside_unassembled(&*model)? {
                    eprintln!("warning: {}", u.note(d));
                    aside = true;
                }
            }
            anyhow::ensure!(aside, "{e}");
            calibrate(&file, &data, validation.as_ref(), &opts)?
        }
        Ok(c) => c,
    };
    sp.finish_and_clear();
    let mut cal = cal;
    if let Some(w) = kinecal::calibrate::checks::stated_noise(cal.identification.sigma0, cal.identification.noise.position) {
        eprintln!("warning: {w}");
        cal.report.flags.push(w);
    }
    let report = &cal.report;
    let mut calibrated = cal.model_file.clone();
    let failed = report.verdict.status == Status::Failed;
    let mut data_files = vec![data_path.display().to_string()];
    data_files.extend(a.validation.iter().map(|v| format!("{} (validation)", v.display())));
    calibrated.provenance = Some(Provenance {
        status: report.verdict.status.as_str().to_string(),
        reasons: report.verdict.reasons.clone(),
        command: std::env::args().collect::<Vec<_>>().join(" "),
        version: env!("CARGO_PKG_VERSION").to_string(),
        date: super::utc_now(),
        data: data_files,
    });
    let mut report = cal.report.clone();
    report.provenance = calibrated.provenance.clone();
    let report = &report;
    if !failed || a.force {
        let text = calibrated.to_toml().map_err(|e| anyhow::anyhow!("{}: {e}", a.out.display()))?;
        outputs.stage(&a.out, text.as_bytes())?;
        if let Some(path) = &a.report {
            let html = report.to_html().map_err(|e| anyhow::anyhow!("report: {e}"))?;
            outputs.stage(path, html.as_bytes())?;
        }
        outputs.commit()?;
    }
    let verdict = || {
        let mut line = format!("verdict: {}", report.verdict.status.as_str());
        if !report.verdict.reasons.is_empty() {
            let _ = write!(line, ": {}", report.verdict.reasons.join("; "));
        }
        line
    };
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        if failed {
            return Err(super::FailedChecks(verdict()).into());
        }
        return Ok(());
    }
    println!(
        "identified {} of {} free parameters of {} from {} ({:?}, {} after {} iterations, σ̂₀ = {:.3})",
        report.rank,
        report.free,
        file.name,
        super::count(data.measurements.len(), "pose"),
        opts.method,
        match (report.converged, failed) {
            (false, _) => "NOT converged",
            (true, true) => "FAILED its checks",
            (true, false) => "converged",
        },
        report.iterations,
        report.sigma0
    );
    if report.kinds.len() > 1 || report.kinds.iter().any(|k| k.instrument()) {
        for k in &report.kinds {
            println!(
                "  {} rows ({}): residual {:.4} mm RMS ({}), {:.2}× their σ {:.4} mm",
                k.kind,
                k.rows,
                k.rms_mm,
                k.what(),
                k.ratio,
                k.sigma_mm
            );
        }
    }
    if let Some(worst) = report
        .known_distances
        .iter()
        .max_by(|a, b| a.error_mm.abs().total_cmp(&b.error_mm.abs()))
    {
        println!(
            "{} known distances between seats: calibrated within {:.4} mm of the stated (seats {}–{}: {:.4} mm for {} mm)",
            report.known_distances.len(),
            worst.error_mm.abs(),
            worst.seats.0,
            worst.seats.1,
            worst.fitted_mm,
            worst.known_mm
        );
    }
    // Draw-wire readings (reading_mm): each pivot's zero, placed with the calibrated model.
    if let Ok(h) = kinecal::instrument::held_out(&*cal.model_file.build(), &data.measurements, &[]) {
        for p in &h.pivots {
            let Some(zero) = p.zero_mm else { continue };
            let name = format!("pivot{}.zero", p.pivot);
            let sd = report.params.iter().find(|r| r.name == name).map_or(0.0, |r| r.std_dev);
            println!("pivot {}: zero {zero:.4} mm (σ {sd:.4} mm; length = reading + zero)", p.pivot);
        }
    }
    println!(
        "condition number {:.3e}; redundant: {}",
        report.condition,
        report.redundant.join(" ")
    );
    if !report.weak.is_empty() {
        println!(
            "held as drawn, seen too weakly to fix (a correction of their tolerance would change the residual by less than its noise): {}",
            report.weak.join(" ")
        );
        if let Some(cause) = &report.weak_cause {
            println!("  likely cause: {cause}");
        }
    }
    if !report.placement.is_empty() {
        println!(
            "held as drawn, where the machine stands (no instrument in the data sees it; the artifacts' places absorb it): {}",
            report.placement.join(" ")
        );
    }
    println!("identification set before: {}", report.identification.before_stats);
    println!("identification set after:  {}", report.identification.after_stats);
    if let Some(v) = &report.validation {
        println!("validation set before:     {}", v.before_stats);
        println!("validation set after:      {}", v.after_stats);
    }
    if let Some(h) = &report.held_out {
        for line in h.lines() {
            println!("{line}");
        }
    }
    for (set, s) in std::iter::once(("identification", &report.identification)).chain(report.validation.as_ref().map(|v| ("validation", v)))
    {
        if !s.joints_after.is_empty() {
            let per: Vec<String> = s
                .joints_before
                .iter()
                .zip(&s.joints_after)
                .map(|(b, a)| format!("{} {:.4} → {:.4} {}", a.name, b.rms, a.rms, a.unit))
                .collect();
            println!("observed joints, {set} set, RMS reading − model before → after: {}", per.join(", "));
        }
    }
    for v in &report.variants {
        let (set, stats) = match &v.validation {
            Some(s) => ("validation", s),
            None => ("identification", &v.identification),
        };
        println!(
            "  compared, {}: {set} set after: {stats} (σ̂₀ = {:.3}, {} of {} parameters)",
            v.name, v.sigma0, v.rank, v.free
        );
    }
    if cal.starts.len() > 1 {
        let kept = cal.starts[0].sigma0;
        let compared: Vec<_> = (cal.starts.iter())
            .filter(|s| s.max_difference_mm.is_some() && !s.clearly_worse_than(kept))
            .collect();
        let spread = compared.iter().filter_map(|s| s.max_difference_mm).fold(0.0, f64::max);
        let agree = if spread <= cal.start_tolerance_mm { "agree" } else { "DISAGREE" };
        if compared.len() > 1 {
            println!(
                "{} starts {agree}: predictions within {spread:.2e} mm of the kept solution (σ̂₀ {})",
                compared.len(),
                compared.iter().map(|s| format!("{:.4}", s.sigma0)).collect::<Vec<_>>().join(" / ")
            );
        } else {
            println!("no other start could be compared with the kept solution:");
        }
        for (k, s) in cal.starts.iter().enumerate() {
            if let Some(why) = &s.unchecked {
                println!("start {} left out of the agreement check: {why}", k + 1);
            } else if s.clearly_worse_than(kept) {
                println!(
                    "start {} ended in a clearly worse minimum (σ̂₀ {:.4}, the kept {kept:.4}), set aside from the agreement check",
                    k + 1,
                    s.sigma0
                );
            }
        }
    }
    if !cal.blunders.is_empty() {
        // At most 50 ids on the line (--json lists every one).
        let ids: Vec<String> = cal.blunders.iter().take(50).map(|id| id.to_string()).collect();
        let more = cal.blunders.len().saturating_sub(ids.len());
        println!(
            "{} set aside as blunders (beyond {} robust σ of the per-pose residuals): ids {}{}",
            super::count(cal.blunders.len(), "pose"),
            a.huber / kinecal::calibrate::BLUNDER_WEIGHT,
            ids.join(" "),
            if more > 0 {
                format!(" … and {more} more (all of them with --json)")
            } else {
                String::new()
            }
        );
    }
    let flagged: usize = report.identification.outliers.len() + report.validation.as_ref().map_or(0, |v| v.outliers.len());
    if flagged > 0 {
        println!(
            "{} flagged as outliers (residual > 3σ; see the report)",
            super::count(flagged, "pose")
        );
    }
    println!("{:<10} {:>12} {:>12} unit", "parameter", "value", "std.dev");
    for p in report.params.iter().filter(|p| p.status == ParamStatus::Identified) {
        println!("{:<10} {:>12.5} {:>12.5} {}", p.name, p.value, p.std_dev, p.unit);
    }
    if failed && !a.force {
        println!("nothing written (pass --force to write the failed model and report anyway)");
        return Err(super::FailedChecks(verdict()).into());
    }
    println!("calibrated model → {}", a.out.display());
    if let Some(r) = &a.report {
        println!("report → {}", r.display());
    }
    println!("{}", verdict());
    if failed {
        return Err(super::FailedChecks(verdict()).into());
    }
    Ok(())
}
