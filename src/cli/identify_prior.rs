//! `kinecal identify --prior CAL NEW.csv -o OUT`: a calibration brought up to date from a few
//! new poses ([`kinecal::drift::update`]).
use super::identify::IdentifyArgs;
use kinecal::drift::{update, UpdateOptions};
use kinecal::io::data_file::{read_data, InputColumns};
use kinecal::io::model_file::Provenance;
use kinecal::io::output::Outputs;
use std::path::Path;

/// Run the update: exit 0 when the new poses and the updated calibration agree within noise,
/// 2 when they do not (nothing written unless --force).
pub fn run(a: &IdentifyArgs, prior_path: &Path, data_path: &Path) -> anyhow::Result<()> {
    anyhow::ensure!(
        a.false_alarm > 0.0 && a.false_alarm < 100.0,
        "--false-alarm: a percentage between 0 and 100 (it is {})",
        a.false_alarm
    );
    let mut outputs = Outputs::new(a.force);
    outputs.input(prior_path).input(data_path);
    outputs.output(&a.out)?;
    let prior = super::check::load_prior(prior_path)?;
    let data = read_data(data_path, &prior.model.data_columns(), InputColumns::Required)?;
    super::check::tracker_rows(&data)?;
    super::warn_limits(&data);
    let opts = UpdateOptions {
        false_alarm: a.false_alarm / 100.0,
        ..UpdateOptions::default()
    };
    let up = update(&prior, &data.measurements, &opts).map_err(|e| data.locate(e))?;
    let passed = up.passed();
    let verdict = if passed {
        format!(
            "verdict: passed: the new poses{} and the updated calibration agree within noise (χ² {:.1} over {} rows, bound {:.1})",
            if up.set_aside.is_some() {
                " (all but the one set aside)"
            } else {
                ""
            },
            up.chi2,
            up.rows,
            up.bound
        )
    } else if !up.converged {
        "verdict: failed: the update did not converge".to_string()
    } else {
        format!(
            "verdict: failed: the new poses still disagree with the updated calibration beyond noise (χ² {:.1} over {} rows, bound {:.1} at {} %): recalibrate",
            up.chi2, up.rows, up.bound, a.false_alarm
        )
    };
    let mut file = up.model_file.clone();
    file.provenance = Some(Provenance {
        status: if passed { "passed" } else { "failed" }.to_string(),
        reasons: if passed { Vec::new() } else { vec![verdict.clone()] },
        command: std::env::args().collect::<Vec<_>>().join(" "),
        version: env!("CARGO_PKG_VERSION").to_string(),
        date: super::utc_now(),
        data: vec![format!("{} (prior)", prior_path.display()), data_path.display().to_string()],
    });
    if passed || a.force {
        let text = file.to_toml().map_err(|e| anyhow::anyhow!("{}: {e}", a.out.display()))?;
        outputs.stage(&a.out, text.as_bytes())?;
        outputs.commit()?;
    }
    if a.json {
        let releases: Vec<_> = up
            .releases
            .iter()
            .map(|r| serde_json::json!({"pattern": r.name, "kind": r.kind, "values": r.values}))
            .collect();
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "prior": prior_path, "data": data_path, "released": releases, "declined": up.declined,
                "moved": up.moved, "largest_move_sigmas": up.largest_move_sigmas, "chi2": up.chi2, "rows": up.rows,
                "bound": up.bound, "converged": up.converged, "before": up.before, "after": up.after, "passed": passed,
                "set_aside": up.set_aside.as_ref().map(|s| serde_json::json!({
                    "id": data.ids[s.index], "line": data.lines[s.index], "position_mm": s.position_mm, "chi2": s.chi2, "rows": s.rows}))}))?
        );
    } else {
        println!(
            "updated {} from {} ({}): {} after the update",
            prior.model.name,
            data_path.display(),
            super::count(data.measurements.len(), "pose"),
            if up.converged { "converged" } else { "NOT converged" }
        );
        if let Some(s) = &up.set_aside {
            println!(
                "pose {} (line {}) set aside: {:.4} mm off, χ² {:.1} over its {} rows; the others agree without it (a blunder, or an error local to that pose): measure it again",
                data.ids[s.index], data.lines[s.index], s.position_mm, s.chi2, s.rows
            );
        }
        if up.releases.is_empty() {
            println!("the new poses agree with the calibration: no pattern released");
        }
        for r in &up.releases {
            println!("released (the new poses contradict the prior): {}", r.describe());
        }
        if let Some(d) = &up.declined {
            println!(
                "not released: {} (lowers χ² by {:.1}, needs more than {:.1}: noise could do it)",
                d.name, d.chi2_drop, d.bound
            );
        }
        let which = if up.set_aside.is_some() { "the other poses" } else { "new poses" };
        println!("{which} before: {}", up.before);
        println!("{which} after:  {}", up.after);
        if up.moved.is_empty() {
            println!("no parameter moved beyond its σ (largest move {:.2} σ)", up.largest_move_sigmas);
        } else {
            println!("{:<10} {:>12} {:>12} {:>12} unit", "moved", "change", "σ before", "σ after");
            for m in up.moved.iter().take(20) {
                println!(
                    "{:<10} {:>+12.5} {:>12.5} {:>12.5} {}",
                    m.name, m.change, m.prior_sigma, m.sigma, m.unit
                );
            }
            if up.moved.len() > 20 {
                println!("… and {} more (all of them with --json)", up.moved.len() - 20);
            }
        }
        if passed || a.force {
            println!("updated model → {}", a.out.display());
        } else {
            println!("nothing written (pass --force to write the failed update anyway)");
        }
        println!("{verdict}");
    }
    if !passed {
        return Err(super::FailedChecks(verdict).into());
    }
    Ok(())
}
