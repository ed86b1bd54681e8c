//! `kinecal check CAL DATA`: re-measured poses judged against a calibration's prediction.
use clap::Args;
use kinecal::drift::{check, CheckOptions, Prior, DEFAULT_FALSE_ALARM};
use kinecal::io::data_file::{read_data, DataSet, InputColumns, MeasurementFormat};
use kinecal::io::model_file::ModelFile;
use std::path::{Path, PathBuf};

/// Arguments of `kinecal check`.
#[derive(Args, Debug)]
pub struct CheckArgs {
    /// The calibrated model file (written by `kinecal identify`: it carries the covariance of
    /// its parameters and the noise).
    pub calibration: PathBuf,
    /// The re-measured poses (CSV, the calibration's measurement kind).
    pub data: PathBuf,
    /// False-alarm rate (the probability of "drifted" for a machine as calibrated), in percent.
    #[arg(long, default_value_t = 100.0 * DEFAULT_FALSE_ALARM)]
    pub false_alarm: f64,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The prior a calibrated model file carries.
pub fn load_prior(path: &Path) -> anyhow::Result<Prior> {
    let file = ModelFile::load(path)?;
    kinecal::drift::Prior::from_model_file(&file).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// Tracker rows only: the instrument kinds' artifacts are placed by their own rows.
pub fn tracker_rows(data: &DataSet) -> anyhow::Result<()> {
    anyhow::ensure!(
        !matches!(
            data.format,
            MeasurementFormat::Seat | MeasurementFormat::Distance | MeasurementFormat::Touch | MeasurementFormat::Mixed
        ),
        "{}: check and identify --prior judge tracker rows (poses, positions, reflectors); this file gives {}",
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
    let data = read_data(&a.data, &prior.model.data_columns(), InputColumns::Required)?;
    tracker_rows(&data)?;
    super::warn_limits(&data);
    let opts = CheckOptions {
        false_alarm: a.false_alarm / 100.0,
        ..CheckOptions::default()
    };
    let r = check(&prior, &data.measurements, &opts).map_err(|e| data.locate(e))?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({"calibration": a.calibration, "data": a.data,
                "ids": data.ids, "check": r, "verdict": if r.drifted { "drifted" } else { "still calibrated" }}))?
        );
    } else {
        println!(
            "{} on {} ({}, {} rows)",
            prior.model.name,
            a.data.display(),
            super::count(data.measurements.len(), "pose"),
            r.rows
        );
        for p in &r.poses {
            let o = p.orientation_deg.map(|o| format!(", {o:.4}°")).unwrap_or_default();
            let mark = if p.beyond() {
                format!("BEYOND by {:.1}×", p.chi2 / p.bound)
            } else {
                "within".to_string()
            };
            println!(
                "  pose {} (line {}): {:.4} mm{o} off, the calibration expects {:.4} mm; χ² {:.1} over {} rows, {mark} its bound {:.1}",
                data.ids[p.index], data.lines[p.index], p.position_mm, p.expected_mm, p.chi2, p.rows, p.bound
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
