//! `kinecal quickstart` end to end (small candidate set): every step runs, the files exist, and
//! the compensated commands beat the nominal ones on the virtual prototype.
use assert_cmd::Command;

fn number_after(text: &str, line_start: &str, key: &str) -> f64 {
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with(line_start))
        .unwrap_or_else(|| panic!("no line '{line_start}' in:\n{text}"));
    let rest = &line[line.find(key).unwrap_or_else(|| panic!("no '{key}' in '{line}'")) + key.len()..];
    rest.split_whitespace()
        .next()
        .unwrap()
        .trim_end_matches([',', ';'])
        .parse()
        .unwrap()
}

#[test]
fn quickstart_calibrates_and_compensates_the_5dof_machine() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::cargo_bin("kinecal")
        .unwrap()
        .args(["quickstart", "--candidates", "3000", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}\n{}", stdout, String::from_utf8_lossy(&out.stderr));
    for f in [
        "pm5.toml",
        "plan.csv",
        "measurements.csv",
        "truth.toml",
        "validation.csv",
        "calibrated.toml",
        "report.html",
        "commands.csv",
    ] {
        assert!(dir.path().join(f).exists(), "{f} missing");
    }
    // Each step is echoed as the command line a user would type.
    for step in [
        "$ kinecal model export",
        "$ kinecal plan",
        "$ kinecal simulate",
        "$ kinecal identify",
        "$ kinecal validate",
        "$ kinecal compensate",
    ] {
        assert!(stdout.contains(step), "{step} not run");
    }
    assert_eq!(number_after(&stdout, "pm5:", "rank "), 32.0);
    let nominal = number_after(&stdout, "nominal commands:", "max position error ");
    let compensated = number_after(&stdout, "compensated commands:", "max position error ");
    let axis = number_after(&stdout, "compensated commands:", "max tool-axis error ");
    // ±0.2 mm / ±0.02° errors put the nominal commands tenths of a millimetre off; with 20 µm /
    // 0.02° noise the calibrated commands land within a few noise standard deviations.
    assert!(nominal > 0.1, "nominal {nominal}");
    assert!(
        compensated < 0.1 && compensated < nominal / 4.0,
        "compensated {compensated} vs nominal {nominal}"
    );
    assert!(axis < 0.1, "tool axis {axis} deg");
}
