//! Helpers shared by the tests that drive the `kinecal` binary.
use assert_cmd::Command;
use serde_json::Value;
use std::path::Path;

/// Run `kinecal ARGS` in `dir`.
pub fn kinecal(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::cargo_bin("kinecal").unwrap().current_dir(dir).args(args).output().unwrap()
}

/// Run a command that must succeed; returns its standard output.
pub fn ok(dir: &Path, args: &[&str]) -> String {
    let out = kinecal(dir, args);
    assert!(
        out.status.success(),
        "kinecal {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Run a command with `--json` that must succeed; returns the parsed output.
pub fn json(dir: &Path, args: &[&str]) -> Value {
    let mut a = args.to_vec();
    a.push("--json");
    serde_json::from_str(&ok(dir, &a)).unwrap()
}

/// Run a command that must fail with exit code 1 and exactly one line on stderr; returns that
/// line without the `kinecal: error: ` prefix.
pub fn fails(dir: &Path, args: &[&str]) -> String {
    let out = kinecal(dir, args);
    assert_eq!(out.status.code(), Some(1), "kinecal {args:?} should fail with exit 1");
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.lines().count(), 1, "one line expected, got: {err}");
    err.trim_end()
        .strip_prefix("kinecal: error: ")
        .unwrap_or_else(|| panic!("prefix: {err}"))
        .to_string()
}

/// Run `kinecal ARGS` in `dir`, killed after `seconds` (a watchdog against hangs: the test fails
/// with the command line rather than running forever).
pub fn kinecal_within(dir: &Path, args: &[&str], seconds: u64) -> std::process::Output {
    let out = Command::cargo_bin("kinecal")
        .unwrap()
        .current_dir(dir)
        .args(args)
        .timeout(std::time::Duration::from_secs(seconds))
        .output()
        .unwrap();
    assert!(out.status.code().is_some(), "kinecal {args:?} did not answer within {seconds} s");
    out
}

/// `kinecal simulate MODEL` in `dir`: `poses` identification poses to `d.csv` (truth `t.toml`)
/// and `validation` held-out poses to `v.csv`, seed `seed`, noise `noise` mm and degrees, then
/// any `extra` arguments (errors, `--force`).
pub fn simulate(dir: &Path, model: &str, poses: usize, validation: usize, seed: u64, noise: f64, extra: &[&str]) -> String {
    let (poses, validation, seed, noise) = (poses.to_string(), validation.to_string(), seed.to_string(), noise.to_string());
    let mut args = vec![
        "simulate",
        model,
        "--poses",
        &poses,
        "--seed",
        &seed,
        "--noise-mm",
        &noise,
        "--noise-deg",
        &noise,
        "--out",
        "d.csv",
        "--truth",
        "t.toml",
        "--validation-poses",
        &validation,
        "--validation-out",
        "v.csv",
    ];
    args.extend_from_slice(extra);
    ok(dir, &args)
}

/// The test copy of the real Panda data: its URDF and each placement's two socket exports.
pub fn panda_data() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mukca-panda")
}

/// `kinecal model import` of the Panda's URDF cut at the ball, to `panda.toml` in `dir`.
pub fn import_panda(dir: &Path) {
    let urdf = panda_data().join("panda.urdf");
    ok(
        dir,
        &["model", "import", urdf.to_str().unwrap(), "--tip", "ball_link", "-o", "panda.toml"],
    );
}

/// The socket exports of these Panda placements, in order: `P/socket_0.csv`, `P/socket_1.csv`
/// of each (seats 2k and 2k+1 of placement k once joined).
pub fn panda_sockets(placements: &[&str]) -> Vec<String> {
    let data = panda_data();
    placements
        .iter()
        .flat_map(|p| [0, 1].map(|s| data.join(p).join(format!("socket_{s}.csv")).display().to_string()))
        .collect()
}
