//! `kinecal irb120` end to end on synthetic tracker data (no ../shared needed), and its errors.
use assert_cmd::Command;
use kinecal::model::{irb120, Mechanism};
use kinecal::se3;
use kinecal::simulate;
use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::fmt::Write as _;
use std::path::Path;

/// Write a tracker data folder measured on a perturbed IRB 120 seen from a tracker 2.5 m away,
/// with three reflectors ~150 mm apart on the tool. Noise-free.
fn write_dataset(dir: &Path, poses: usize, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nominal = irb120::nominal();
    let delta = simulate::random_errors(&nominal, &mut rng, 0.5, 0.002, None);
    let mut truth = simulate::perturbed(&nominal, &delta);
    let tracker_from_base = se3::pose_from_parts(Vector3::new(2500.0, 300.0, -600.0), Vector3::new(0.01, -0.02, 2.8));
    truth.set_initial_pose(0, tracker_from_base * truth.initial_poses()[0]);
    let flange_to_tool = se3::pose_from_parts(Vector3::new(40.0, 10.0, 60.0), Vector3::new(0.3, 0.2, -0.4));
    truth.set_initial_pose(6, truth.tool() * flange_to_tool);
    let reflectors = [
        Vector3::new(0.0, 86.6, 0.0),
        Vector3::new(75.0, -43.3, 0.0),
        Vector3::new(-75.0, -43.3, 0.0),
    ];
    let mut joints = String::from("idx,q1,q2,q3,q4,q5,q6\n");
    let mut smr = [
        String::from("idx,x,y,z\n"),
        String::from("idx,x,y,z\n"),
        String::from("idx,x,y,z\n"),
    ];
    let limits = [150.0, 80.0, 60.0, 150.0, 100.0, 170.0];
    for i in 0..poses {
        let q: Vec<f64> = limits.iter().map(|l: &f64| rng.random_range(-*l..*l)).collect();
        let qr: Vec<f64> = q.iter().map(|d| d.to_radians()).collect();
        let t = truth.forward(&qr).unwrap();
        writeln!(joints, "{i},{}", q.iter().map(|v| format!("{v:.15}")).collect::<Vec<_>>().join(",")).unwrap();
        for k in 0..3 {
            let p = t.transform_point(&reflectors[k].into());
            writeln!(smr[k], "{i},{:.12},{:.12},{:.12}", p.x, p.y, p.z).unwrap();
        }
    }
    std::fs::write(dir.join("joints_deg.csv"), joints).unwrap();
    for (k, text) in smr.iter().enumerate() {
        std::fs::write(dir.join(format!("smr{}.csv", k + 1)), text).unwrap();
    }
}

fn kinecal() -> Command {
    Command::cargo_bin("kinecal").unwrap()
}

#[test]
fn noise_free_synthetic_tracker_data_is_recovered_exactly() {
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), 120, 7);
    let out = kinecal()
        .args(["irb120", "--json", "--split", "60"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let runs = v["runs"].as_array().unwrap();
    let get = |label: &str, fit: &str| {
        runs.iter()
            .find(|r| r["label"].as_str().unwrap().trim() == label && r["fit"] == fit)
            .unwrap()
    };
    // Frames only cannot absorb the geometric errors…
    let frames = &get("(i)  base + tool only", "frame")["validation"];
    assert!(frames["position_rms_mm"].as_f64().unwrap() > 0.1);
    // …full calibration recovers the truth to numerical precision, whatever the fitted residual.
    for fit in ["frame", "3 points", "frame, σ from residuals"] {
        let full = &get("(ii) full geometric", "frame");
        let full = if fit == "frame" { full } else { get("full geometric", fit) };
        let val = &full["validation"];
        assert!(val["position_max_mm"].as_f64().unwrap() < 1e-6, "{fit}: {val}");
        assert!(val["orientation_max_deg"].as_f64().unwrap() < 1e-6, "{fit}: {val}");
        assert_eq!(full["identified"], 30);
    }
    let pos = &get("reflector 1: full geometric", "position");
    assert_eq!(pos["identified"], 27);
    assert!(pos["validation"]["position_max_mm"].as_f64().unwrap() < 1e-6);
}

/// Run the command on a folder and return (success, stderr).
fn run_on(dir: &Path, extra: &[&str]) -> (bool, String) {
    let out = kinecal().arg("irb120").arg(dir).args(extra).output().unwrap();
    (out.status.success(), String::from_utf8_lossy(&out.stderr).to_string())
}

fn assert_one_line_error(dir: &Path, extra: &[&str], needles: &[&str]) {
    let (ok, err) = run_on(dir, extra);
    assert!(!ok, "expected failure");
    assert_eq!(err.trim_end().lines().count(), 1, "one line expected, got: {err}");
    assert!(!err.contains("panicked"), "{err}");
    for n in needles {
        assert!(err.contains(n), "'{n}' not in: {err}");
    }
}

fn edit(dir: &Path, file: &str, f: impl Fn(String) -> String) {
    let p = dir.join(file);
    let s = std::fs::read_to_string(&p).unwrap();
    std::fs::write(p, f(s)).unwrap();
}

#[test]
fn missing_file_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), 20, 1);
    std::fs::remove_file(dir.path().join("smr2.csv")).unwrap();
    assert_one_line_error(dir.path(), &[], &["smr2.csv", "cannot read"]);
    let nowhere = dir.path().join("does-not-exist");
    assert_one_line_error(&nowhere, &[], &["joints_deg.csv", "cannot read"]);
}

#[test]
fn short_row_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), 20, 2);
    edit(dir.path(), "joints_deg.csv", |s| s.replacen("\n5,", "\n5,1.0\n#", 1));
    assert_one_line_error(dir.path(), &[], &["joints_deg.csv:7", "expected 7 fields, found 2"]);
}

#[test]
fn non_numeric_field_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), 20, 3);
    edit(dir.path(), "smr3.csv", |s| {
        let mut lines: Vec<String> = s.lines().map(String::from).collect();
        lines[4] = "3,12.5,abc,7".into();
        lines.join("\n")
    });
    assert_one_line_error(dir.path(), &[], &["smr3.csv:5", "column 'y'", "'abc' is not a number"]);
}

#[test]
fn nan_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), 20, 4);
    edit(dir.path(), "smr1.csv", |s| {
        let mut lines: Vec<String> = s.lines().map(String::from).collect();
        lines[2] = "1,NaN,1,2".into();
        lines.join("\n")
    });
    assert_one_line_error(dir.path(), &[], &["smr1.csv:3", "column 'x'", "non-finite"]);
}

#[test]
fn mismatched_row_counts_are_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), 20, 5);
    edit(dir.path(), "smr2.csv", |s| s.lines().take(15).collect::<Vec<_>>().join("\n"));
    assert_one_line_error(dir.path(), &[], &["smr2.csv", "14 rows", "joints_deg.csv has 20"]);
}

#[test]
fn too_few_poses_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), 8, 6);
    // 4 identification poses: 24 residual rows for 30 identifiable parameters.
    assert_one_line_error(dir.path(), &["--split", "4"], &["too few measurements"]);
}

#[test]
fn bad_option_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), 20, 8);
    assert_one_line_error(dir.path(), &["--sigma-orientation", "0"], &["must be positive"]);
    assert_one_line_error(dir.path(), &["--split", "1000"], &["no pose"]);
}
