//! `kinecal check CAL DATA`: re-measured poses judged against a calibration's prediction;
//! `kinecal check CAL --plan N`: the configurations to measure for such a check.
use clap::Args;
use kinecal::drift::{check, plan_check_poses, CheckOptions, CheckPlanOptions, Prior, DEFAULT_FALSE_ALARM};
use kinecal::io::data_file::{read_configurations, read_data, DataSet, InputColumns, MeasurementFormat};
use kinecal::io::model_file::ModelFile;
use kinecal::io::output::Outputs;
use kinecal::params::Unit;
use kinecal::simulate::Instrument;
use std::path::{Path, PathBuf};

/// Arguments of `kinecal check`.
#[derive(Args, Debug)]
pub struct CheckArgs {
    /// The calibrated model file (written by `kinecal identify`: it carries the covariance of
    /// its parameters and the noise).
    pub calibration: PathBuf,
    /// The re-measured poses (CSV, the calibration's measurement kind). Without it, `--plan`.
    pub data: Option<PathBuf>,
    /// False-alarm rate (the probability of "drifted" for a machine as calibrated), in percent.
    #[arg(long, default_value_t = 100.0 * DEFAULT_FALSE_ALARM)]
    pub false_alarm: f64,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Choose N configurations to measure for a check instead: those at which the check tells
    /// the calibration's patterns of change apart best (written to --out).
    #[arg(long, value_name = "N", conflicts_with = "data")]
    pub plan: Option<usize>,
    /// With --plan: candidates drawn over the calibrated model's workspace (a serial arm: its
    /// inputs within their limits; pm5: its platform workspace).
    #[arg(long, default_value_t = 2000, requires = "plan")]
    pub candidates: usize,
    /// With --plan: the candidates from a CSV of configurations instead (a plan, a data file, or
    /// the inputs alone).
    #[arg(long, value_name = "CSV", requires = "plan")]
    pub among: Option<PathBuf>,
    /// With --plan: the size of the drifts to name apart, as the RMS tool motion they cause (mm).
    #[arg(long, default_value_t = 0.1, requires = "plan")]
    pub drift_mm: f64,
    /// With --plan: what the check will measure: pose (three reflectors) or position (one).
    #[arg(long, default_value = "pose", requires = "plan")]
    pub observe: String,
    /// With --plan: seed of the candidates drawn.
    #[arg(long, default_value_t = 1, requires = "plan")]
    pub seed: u64,
    /// With --plan: the CSV written (inputs in degrees / mm, the calibrated model's tool poses).
    #[arg(short, long, visible_alias = "out", default_value = "check-poses.csv", requires = "plan")]
    pub output: PathBuf,
    /// With --plan: replace an existing output file.
    #[arg(long, requires = "plan")]
    pub force: bool,
}

/// The prior a calibrated model file carries.
pub fn load_prior(path: &Path) -> anyhow::Result<Prior> {
    let file = ModelFile::load(path)?;
    kinecal::drift::Prior::from_model_file(&file).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// Tracker rows only: an update's artifacts would be placed by its own few rows.
pub fn tracker_rows(data: &DataSet) -> anyhow::Result<()> {
    anyhow::ensure!(
        !matches!(
            data.format,
            MeasurementFormat::Seat | MeasurementFormat::Distance | MeasurementFormat::Touch | MeasurementFormat::Mixed
        ),
        "{}: identify --prior updates from tracker rows (poses, positions, reflectors); this file gives {} (kinecal check judges an instrument's rows; a recalibration updates from them)",
        data.path.display(),
        data.format.describe()
    );
    Ok(())
}

/// What a check takes: tracker rows, or an instrument's rows alone.
fn checked_rows(data: &DataSet) -> anyhow::Result<()> {
    anyhow::ensure!(
        !matches!(data.format, MeasurementFormat::Mixed),
        "{}: check judges tracker rows, or an instrument's rows (seats, pivots, touches) alone; this file gives {}",
        data.path.display(),
        data.format.describe()
    );
    Ok(())
}

/// Run the command: exit 0 "still calibrated", 2 "drifted".
pub fn run(a: CheckArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        a.false_alarm > 0.0 && a.false_alarm < 100.0,
        "--false-alarm: a percentage between 0 and 100 (it is {})",
        a.false_alarm
    );
    let prior = load_prior(&a.calibration)?;
    if let Some(n) = a.plan {
        return plan(&a, &prior, n);
    }
    let Some(path) = a.data.clone() else {
        anyhow::bail!(
            "no re-measured poses: kinecal check {} DATA judges them, kinecal check {} --plan 5 chooses where to measure them",
            a.calibration.display(),
            a.calibration.display()
        );
    };
    let data = read_data(&path, &prior.model.data_columns(), InputColumns::Required)?;
    checked_rows(&data)?;
    super::warn_limits(&data);
    let opts = CheckOptions {
        false_alarm: a.false_alarm / 100.0,
        ..CheckOptions::default()
    };
    let r = check(&prior, &data.measurements, &opts).map_err(|e| data.locate(e))?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({"calibration": a.calibration, "data": path,
                "ids": data.ids, "check": r, "verdict": if r.drifted { "drifted" } else { "still calibrated" }}))?
        );
    } else {
        println!(
            "{} on {} ({}, {} rows)",
            prior.model.name,
            path.display(),
            super::count(data.measurements.len(), "pose"),
            r.rows
        );
        for p in &r.poses {
            let mark = if p.beyond() {
                format!("BEYOND by {:.1}×", p.chi2 / p.bound)
            } else {
                "within".to_string()
            };
            if let Some(a) = &p.artifact {
                let (first, last) = (a.poses.first().copied().unwrap_or(0), a.poses.last().copied().unwrap_or(0));
                println!(
                    "  {} ({}, lines {}–{}): {:.4} mm RMS off it, the calibration expects {:.4} mm; χ² {:.1} over {} rows, {mark} its bound {:.1}",
                    a.name,
                    super::count(a.poses.len(), "pose"),
                    data.lines[first],
                    data.lines[last],
                    p.position_mm,
                    p.expected_mm,
                    p.chi2,
                    p.rows,
                    p.bound
                );
                continue;
            }
            let o = p.orientation_deg.map(|o| format!(", {o:.4}°")).unwrap_or_default();
            println!(
                "  pose {} (line {}): {:.4} mm{o} off, the calibration expects {:.4} mm; χ² {:.1} over {} rows, {mark} its bound {:.1}",
                data.ids[p.index], data.lines[p.index], p.position_mm, p.expected_mm, p.chi2, p.rows, p.bound
            );
        }
        if let Some((o, a)) = r.one_pose.as_ref().and_then(|o| r.poses[o.index].artifact.as_ref().map(|a| (o, a))) {
            println!(
                "without {}: χ² {:.1} over {} rows, within the bound {:.1}: the rows beyond rest on that artifact point alone (moved while measured, a ball not seated), not a drift of the machine",
                a.name, o.chi2_without, o.rows_without, o.bound_without
            );
        } else if let Some(o) = &r.one_pose {
            println!(
                "without pose {} (line {}): χ² {:.1} over {} rows, within the bound {:.1}: the rows beyond rest on that pose alone (a blunder, or an error local to it), not a drift of the machine",
                data.ids[o.index], data.lines[o.index], o.chi2_without, o.rows_without, o.bound_without
            );
        }
        if let (true, Some(p)) = (r.drifted, &r.pattern) {
            if p.significant() && p.explains() {
                println!(
                    "explained by: {} (what is left: χ² {:.1}, within {:.1})",
                    p.describe(),
                    p.chi2_after,
                    p.bound_after
                );
            } else {
                println!(
                    "no single pattern of the {} tried explains it; the closest: {} (what is left: χ² {:.1}, bound {:.1})",
                    r.patterns_tried,
                    p.describe(),
                    p.chi2_after,
                    p.bound_after
                );
            }
        }
    }
    let verdict = r.verdict();
    if r.drifted {
        if !a.json {
            println!("verdict: {verdict}");
        }
        return Err(super::FailedChecks(format!("verdict: {verdict}")).into());
    }
    if !a.json {
        println!("verdict: {verdict}");
    }
    Ok(())
}

/// `--plan N`: choose the configurations of a check and write them.
fn plan(a: &CheckArgs, prior: &Prior, n: usize) -> anyhow::Result<()> {
    let instrument = match a.observe.as_str() {
        "pose" => Instrument::Pose,
        "position" => Instrument::Position,
        other => anyhow::bail!("--observe: pose or position (it is '{other}')"),
    };
    let mut outputs = Outputs::new(a.force);
    outputs.input(&a.calibration);
    if let Some(p) = &a.among {
        outputs.input(p);
    }
    outputs.output(&a.output)?;
    let inputs = prior.model.inputs();
    let model = prior.model.build();
    let configurations = match &a.among {
        Some(p) => read_configurations(p, &inputs)?,
        None => {
            let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(a.seed);
            kinecal::simulate::random_configurations(&*model, &inputs, a.candidates, &mut rng)
                .map_err(|e| anyhow::anyhow!("drawing {} candidates: {e}", a.candidates))?
        }
    };
    let opts = CheckPlanOptions {
        n,
        instrument,
        drift_mm: a.drift_mm,
        ..CheckPlanOptions::default()
    };
    let started = std::time::Instant::now();
    let spinner = super::progress::spinner(&format!("choosing {n} of {} candidates", configurations.len()), a.json);
    let planned = plan_check_poses(prior, &configurations, &opts);
    spinner.finish_and_clear();
    let planned = planned?;
    let chosen: Vec<kinecal::design::Candidate> = planned
        .selected
        .iter()
        .map(|&i| {
            let q = configurations[i].clone();
            let target = model.forward(&q).map_err(|e| anyhow::anyhow!("candidate {i}: {e}"))?;
            Ok(kinecal::design::Candidate { q, target, solution: None })
        })
        .collect::<anyhow::Result<_>>()?;
    let numbers: Vec<String> = planned.selected.iter().map(|i| i.to_string()).collect();
    let comments = [
        format!(
            "kinecal check --plan {n}: configurations of a check of {}, chosen to name a drift of {} mm (tool motion, RMS)",
            a.calibration.display(),
            a.drift_mm
        ),
        format!(
            "expected wrong names per pattern: {:.4} (the first {n} candidates: {:.4})",
            planned.wrong_names, planned.wrong_names_unplanned
        ),
        format!("candidate numbers: {}", numbers.join(" ")),
        "tool poses: the calibrated model's, in the measurement frame".to_string(),
    ];
    let names: Vec<String> = inputs.iter().map(|i| i.name.clone()).collect();
    let angles: Vec<bool> = inputs.iter().map(|i| i.unit == Unit::Angle).collect();
    let rows: Vec<&kinecal::design::Candidate> = chosen.iter().collect();
    let mut text = Vec::new();
    kinecal::design::write_configurations_csv(&mut text, &names, &angles, &comments, &rows)?;
    outputs.stage(&a.output, &text)?;
    outputs.commit()?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({"calibration": a.calibration, "output": a.output,
                "candidates": configurations.len(), "plan": planned, "seconds": started.elapsed().as_secs_f64()}))?
        );
        return Ok(());
    }
    println!(
        "{}: {} chosen among {} candidates in {:.1} s to tell apart its {} one-coefficient patterns of change ({} ordered pairs weighed; {} that all the candidates together do not tell apart left out)",
        prior.model.name,
        super::count(n, "check configuration"),
        configurations.len(),
        started.elapsed().as_secs_f64(),
        planned.patterns,
        planned.pairs,
        planned.alike
    );
    println!(
        "expected wrong names per pattern for a drift of {} mm: {:.4} (the first {n} candidates: {:.4})",
        a.drift_mm, planned.wrong_names, planned.wrong_names_unplanned
    );
    let weakest: Vec<String> = planned
        .weakest
        .iter()
        .map(|w| format!("{} taken for {} (χ² {:.2})", w.drifted, w.taken_for, w.chi2))
        .collect();
    println!("least apart: {}", weakest.join(", "));
    println!(
        "wrote {} (angle inputs in degrees, length inputs in mm, the calibrated model's tool poses in mm and degrees): measure there, then kinecal check {} DATA",
        a.output.display(),
        a.calibration.display()
    );
    Ok(())
}
