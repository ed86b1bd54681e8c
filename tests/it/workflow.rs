//! End-to-end: the `kinecal` binary through model export → simulate → identifiability → identify
//! → validate → compensate on the built-in IRB 120, checking the numbers; and one test per bad
//! input, checking the one-line message and the non-zero exit.
use crate::cli::{fails, json, ok};
use kinecal::io::data_file::{read_data, write_data, InputColumns};
use kinecal::io::model_file::ModelFile;
use kinecal::io::table::read_table;
use kinecal::measure::{Measurement, Observation};
use kinecal::se3;
use std::path::{Path, PathBuf};
use tempfile::TempDir;

/// A directory with the exported IRB 120 model and noise-free simulated data.
fn setup(poses: usize) -> (TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path().to_path_buf();
    ok(&d, &["model", "export", "irb120", "--out", "irb120.toml"]);
    let n = poses.to_string();
    ok(
        &d,
        &[
            "simulate",
            "irb120.toml",
            "--poses",
            &n,
            "--seed",
            "11",
            "--error-mm",
            "0.5",
            "--error-deg",
            "0.1",
            "--out",
            "ident.csv",
            "--truth",
            "truth.toml",
            "--validation-poses",
            "25",
            "--validation-out",
            "valid.csv",
        ],
    );
    (tmp, d)
}

#[test]
fn simulate_identify_validate_compensate_recovers_the_truth() {
    let (_tmp, d) = setup(40);
    let model = ModelFile::load(&d.join("irb120.toml")).unwrap();
    let inputs = model.inputs();

    // Identifiability on the measured poses: 4r + 2p + 6 = 30 of 42 for full poses.
    let id = json(&d, &["identifiability", "irb120.toml", "ident.csv"]);
    assert_eq!(id["rank"], 30);
    assert_eq!(id["redundant"].as_array().unwrap().len(), 12);
    assert!(id["condition"].as_f64().unwrap() < 1e3);

    // Identify (noise-free): the calibrated model reproduces the validation set to round-off.
    let rep = json(
        &d,
        &[
            "identify",
            "--frames",
            "model",
            "irb120.toml",
            "ident.csv",
            "--validation",
            "valid.csv",
            "--out",
            "cal.toml",
            "--report",
            "r.html",
        ],
    );
    assert_eq!(rep["converged"], true);
    assert_eq!(rep["rank"], 30);
    let before = rep["validation"]["before_stats"]["position_rms_mm"].as_f64().unwrap();
    let after = rep["validation"]["after_stats"]["position_max_mm"].as_f64().unwrap();
    let after_deg = rep["validation"]["after_stats"]["orientation_max_deg"].as_f64().unwrap();
    assert!(before > 0.2, "nominal model should be off by tenths of mm, got {before}");
    assert!(after < 1e-6 && after_deg < 1e-6, "after calibration: {after} mm, {after_deg} deg");
    let html = std::fs::read_to_string(d.join("r.html")).unwrap();
    assert!(html.contains("<svg") && html.contains("Per-pose errors, validation set") && html.contains("Redundant"));
    // Self-contained: no external resources (only the SVG namespace URI).
    let outside = html.replace("http://www.w3.org/2000/svg", "");
    assert!(!outside.contains("http://") && !outside.contains("https://") && !html.contains("<link") && !html.contains("src="));
    assert_eq!(
        html.matches("<svg").count(),
        2 * 5 + 6 + 2 + 2 + 2,
        "5 plots per data set, the error against each of the 6 joints, the singular values, the correlations, the two workspace maps and the two maps of predicted accuracy"
    );
    assert!(html.contains("<canvas id=\"view3d\""), "no 3-D view");

    // The calibrated model file has the truth's kinematics (not its parameters: 12 are redundant).
    let cal = ModelFile::load(&d.join("cal.toml")).unwrap().build();
    let truth = ModelFile::load(&d.join("truth.toml")).unwrap().build();
    let nominal = model.build();
    for k in 0..10 {
        let q: Vec<f64> = (0..6).map(|j| ((k * 6 + j) as f64 * 0.71).sin()).collect();
        let e = se3::pose_error(&truth.forward(&q).unwrap(), &cal.forward(&q).unwrap());
        assert!(se3::lin(&e).norm() < 1e-6 && se3::ang(&e).norm() < 1e-9, "{e}");
    }

    // Validate: calibrated vs nominal on the validation set.
    let v = json(&d, &["validate", "cal.toml", "valid.csv"]);
    assert!(v["stats"]["position_max_mm"].as_f64().unwrap() < 1e-6);
    assert_eq!(v["stats"]["poses"], 25);
    let v0 = json(&d, &["validate", "irb120", "valid.csv"]);
    assert!((v0["stats"]["position_rms_mm"].as_f64().unwrap() - before).abs() < 1e-9);

    // Compensate: targets are where the NOMINAL model thinks the validation commands go; the
    // compensated commands must put the TRUE machine there.
    let val = read_data(&d.join("valid.csv"), &inputs, InputColumns::Required).unwrap();
    let targets: Vec<Measurement> = val
        .measurements
        .iter()
        .map(|m| Measurement {
            joints: Vec::new(),
            q: m.q.clone(),
            obs: Observation::Pose(nominal.forward(&m.q).unwrap()),
        })
        .collect();
    write_data(&d.join("targets.csv"), &inputs, &val.ids, &targets, None).unwrap();
    let c = json(&d, &["compensate", "cal.toml", "targets.csv", "--out", "cmd.csv"]);
    assert_eq!(c["count"], 25);
    let cmd = read_table(&d.join("cmd.csv")).unwrap();
    assert_eq!(cmd.columns, ["id", "q1_deg", "q2_deg", "q3_deg", "q4_deg", "q5_deg", "q6_deg"]);
    let mut moved = 0.0_f64;
    for (row, t) in cmd.rows.iter().zip(&targets) {
        let q: Vec<f64> = row[1..].iter().map(|v| v.to_radians()).collect();
        let Observation::Pose(target) = &t.obs else { unreachable!() };
        let e = se3::pose_error(target, &truth.forward(&q).unwrap());
        assert!(se3::lin(&e).norm() < 1e-6 && se3::ang(&e).norm() < 1e-9, "target missed by {e}");
        moved = moved.max(q.iter().zip(&t.q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max));
        for (qi, inp) in q.iter().zip(&inputs) {
            let (lo, hi) = inp.limits.unwrap();
            assert!(*qi >= lo - 1e-9 && *qi <= hi + 1e-9);
        }
    }
    // Compensation did something: commands differ from the nominal ones.
    assert!(moved > 1e-4, "{moved}");

    // Targets without commands: --nominal seeds the calibrated inverse with the nominal one, so
    // the commands stay on the nominal solution branch (within a fraction of a degree of it).
    let bare: Vec<Measurement> = targets
        .iter()
        .map(|t| Measurement {
            joints: Vec::new(),
            q: vec![],
            obs: t.obs.clone(),
        })
        .collect();
    write_data(&d.join("bare.csv"), &inputs, &val.ids, &bare, None).unwrap();
    assert!(std::fs::read_to_string(d.join("bare.csv"))
        .unwrap()
        .starts_with("id,x_mm,y_mm,z_mm,qw,qx,qy,qz\n"));
    ok(
        &d,
        &[
            "compensate",
            "cal.toml",
            "bare.csv",
            "--nominal",
            "irb120.toml",
            "--out",
            "cmd2.csv",
        ],
    );
    ok(&d, &["compensate", "irb120.toml", "bare.csv", "--out", "nom.csv"]);
    let (cmd2, nom) = (read_table(&d.join("cmd2.csv")).unwrap(), read_table(&d.join("nom.csv")).unwrap());
    for ((row, n), t) in cmd2.rows.iter().zip(&nom.rows).zip(&targets) {
        let q: Vec<f64> = row[1..].iter().map(|v| v.to_radians()).collect();
        let Observation::Pose(target) = &t.obs else { unreachable!() };
        let e = se3::pose_error(target, &truth.forward(&q).unwrap());
        assert!(se3::lin(&e).norm() < 1e-6 && se3::ang(&e).norm() < 1e-9, "target missed by {e}");
        let gap = row[1..].iter().zip(&n[1..]).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(gap < 5.0, "compensated command {gap} deg away from the nominal one");
    }
}

#[test]
fn noisy_reflector_data_calibrates_to_the_noise_level() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ok(
        d,
        &[
            "simulate",
            "irb120",
            "--poses",
            "60",
            "--seed",
            "5",
            "--noise-mm",
            "0.02",
            "--measure",
            "reflectors",
            "--out",
            "ident.csv",
            "--truth",
            "truth.toml",
            "--validation-poses",
            "30",
            "--validation-out",
            "valid.csv",
        ],
    );
    let header = std::fs::read_to_string(d.join("ident.csv")).unwrap();
    assert!(header.starts_with("id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,m1x_mm,m1y_mm,m1z_mm,m2x_mm"));
    let rep = json(
        d,
        &[
            "identify",
            "irb120",
            "ident.csv",
            "--validation",
            "valid.csv",
            "--out",
            "cal.toml",
            "--reweight",
        ],
    );
    let before = rep["validation"]["before_stats"]["position_rms_mm"].as_f64().unwrap();
    let after = rep["validation"]["after_stats"]["position_rms_mm"].as_f64().unwrap();
    // The covariance of the identified parameters: symmetric, its diagonal the squared standard
    // deviations of the parameter table.
    let cov = &rep["covariance"];
    let names: Vec<&str> = cov["params"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    let m: Vec<Vec<f64>> = cov["matrix"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect())
        .collect();
    assert_eq!(m.len(), rep["rank"].as_u64().unwrap() as usize);
    for (i, name) in names.iter().enumerate() {
        let row = rep["params"].as_array().unwrap().iter().find(|p| p["name"] == *name).unwrap();
        let sd = row["std_dev"].as_f64().unwrap();
        assert!((m[i][i].sqrt() - sd).abs() <= 1e-12 * (1.0 + sd), "{name}");
        assert_eq!(cov["units"][i], row["unit"]);
        for j in 0..m.len() {
            assert!((m[i][j] - m[j][i]).abs() <= 1e-12 * (m[i][i] * m[j][j]).sqrt(), "{name}");
        }
    }
    // Reflector noise 0.02 mm per axis: the frame origin (mean of three) has σ ≈ 0.012 mm per
    // axis, so an RMS position error around 0.02 mm; the calibrated model must get close to it.
    assert!(before > 0.5 && after < 0.05, "before {before} after {after}");
}

fn write(d: &Path, name: &str, text: &str) {
    std::fs::write(d.join(name), text).unwrap();
}

/// The first `n` lines of a file, with `f` applied to the header and `g` to line 3.
fn edited(d: &Path, name: &str, f: impl Fn(&str) -> String, g: impl Fn(&str) -> String) -> String {
    let text = std::fs::read_to_string(d.join(name)).unwrap();
    text.lines()
        .enumerate()
        .map(|(i, l)| match i {
            0 => f(l),
            2 => g(l),
            _ => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn unknown_column_is_one_line() {
    let (_tmp, d) = setup(10);
    let t = edited(&d, "ident.csv", |h| format!("{h},temp_C"), |l| format!("{l},21"));
    let t: String = t
        .lines()
        .enumerate()
        .map(|(i, l)| if i > 0 && i != 2 { format!("{l},21\n") } else { format!("{l}\n") })
        .collect();
    write(&d, "bad.csv", &t);
    let e = fails(&d, &["identify", "irb120.toml", "bad.csv", "--out", "c.toml"]);
    assert!(e.starts_with("bad.csv:1: unknown column 'temp_C' (expected: q1_deg|_rad"), "{e}");
}

#[test]
fn wrong_unit_is_one_line() {
    let (_tmp, d) = setup(10);
    write(
        &d,
        "bad.csv",
        &edited(&d, "ident.csv", |h| h.replace("q2_deg", "q2_mm"), |l| l.to_string()),
    );
    let e = fails(&d, &["validate", "irb120.toml", "bad.csv"]);
    assert_eq!(
        e,
        "bad.csv:1: column 'q2_mm': unit 'mm' for the angular input 'q2' (use q2_deg or q2_rad)"
    );
    // A unit the model file does not know.
    let m = std::fs::read_to_string(d.join("irb120.toml"))
        .unwrap()
        .replace("angle = \"deg\"", "angle = \"grad\"");
    write(&d, "m.toml", &m);
    let line = m.lines().position(|l| l.starts_with("angle = ")).unwrap() + 1;
    let e = fails(&d, &["validate", "m.toml", "ident.csv"]);
    assert_eq!(
        e,
        format!("m.toml:{line}: units.angle: unknown angle unit 'grad' (use \"deg\" or \"rad\")")
    );
}

#[test]
fn nan_and_text_values_are_one_line() {
    let (_tmp, d) = setup(10);
    let nan = |l: &str| {
        let mut f: Vec<String> = l.split(',').map(String::from).collect();
        f[8] = "NaN".into();
        f.join(",")
    };
    write(&d, "bad.csv", &edited(&d, "ident.csv", |h| h.to_string(), nan));
    let e = fails(&d, &["identify", "irb120.toml", "bad.csv", "--out", "c.toml"]);
    assert_eq!(e, "bad.csv:3: column 'y_mm': non-finite value 'NaN'");
    let txt = |l: &str| l.replacen(',', ",abc", 1);
    write(&d, "bad2.csv", &edited(&d, "ident.csv", |h| h.to_string(), txt));
    let e = fails(&d, &["validate", "irb120.toml", "bad2.csv"]);
    assert!(e.starts_with("bad2.csv:3: column 'q1_deg': 'abc"), "{e}");
}

#[test]
fn row_length_and_row_count_mismatches_are_one_line() {
    let (_tmp, d) = setup(10);
    let short = |l: &str| l.rsplit_once(',').unwrap().0.to_string();
    write(&d, "bad.csv", &edited(&d, "ident.csv", |h| h.to_string(), short));
    let e = fails(&d, &["identify", "irb120.toml", "bad.csv", "--out", "c.toml"]);
    assert_eq!(e, "bad.csv:3: expected 14 fields, found 13");
    // Too few rows for the parameters to identify.
    let text = std::fs::read_to_string(d.join("ident.csv")).unwrap();
    write(&d, "few.csv", &text.lines().take(4).collect::<Vec<_>>().join("\n"));
    let e = fails(&d, &["identify", "irb120.toml", "few.csv", "--out", "c.toml"]);
    assert!(e.starts_with("few.csv: too few measurements: 18 residual rows from 3 poses"), "{e}");
    // An inputs file and a measurement file with different row counts.
    let text = std::fs::read_to_string(d.join("ident.csv")).unwrap();
    let (mut joints, mut meas) = (String::new(), String::new());
    for l in text.lines() {
        let f: Vec<&str> = l.split(',').collect();
        joints.push_str(&(f[..7].join(",") + "\n"));
        meas.push_str(&(std::iter::once(f[0]).chain(f[7..].iter().copied()).collect::<Vec<_>>().join(",") + "\n"));
    }
    write(&d, "joints.csv", &joints);
    write(&d, "tracker.csv", &meas);
    let j = json(
        &d,
        &["data", "join", "irb120.toml", "joints.csv", "tracker.csv", "--out", "joined.csv"],
    );
    assert_eq!(j["poses"], 10);
    let v = json(&d, &["validate", "truth.toml", "joined.csv"]);
    assert!(
        v["stats"]["position_max_mm"].as_f64().unwrap() < 1e-9,
        "joined data must be the simulated data"
    );
    write(&d, "tracker9.csv", &meas.lines().take(10).collect::<Vec<_>>().join("\n"));
    let e = fails(&d, &["data", "join", "irb120.toml", "joints.csv", "tracker9.csv", "--out", "j.csv"]);
    assert_eq!(
        e,
        "tracker9.csv: 9 rows but joints.csv has 10; every file must have one row per pose"
    );
    // A missing column.
    write(
        &d,
        "miss.csv",
        &edited(&d, "ident.csv", |h| h.replace("qz", "qq"), |l| l.to_string()),
    );
    let e = fails(&d, &["validate", "irb120.toml", "miss.csv"]);
    assert!(e.starts_with("miss.csv:1: unknown column 'qq'"), "{e}");
}

#[test]
fn unreachable_target_names_the_line() {
    let (_tmp, d) = setup(10);
    ok(&d, &["identify", "irb120.toml", "ident.csv", "--out", "cal.toml"]);
    write(
        &d,
        "targets.csv",
        "# x, y, z in mm; roll/pitch/yaw in degrees\nid,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg\n1,300,100,500,0,30,0\n2,350,-50,400,0,90,0\n3,2000,0,630,0,0,0\n",
    );
    let e = fails(&d, &["compensate", "cal.toml", "targets.csv", "--out", "cmd.csv"]);
    assert!(e.starts_with("targets.csv:5: target 3: unreachable target: "), "{e}");
    assert!(!d.join("cmd.csv").exists(), "no partial output on error");
}

#[test]
fn model_file_typo_names_file_line_and_key() {
    let (_tmp, d) = setup(10);
    let m = std::fs::read_to_string(d.join("irb120.toml")).unwrap();
    let typo = m.replacen("limits = [", "limit = [", 1);
    let line = typo.lines().position(|l| l.starts_with("limit = ")).unwrap() + 1;
    write(&d, "typo.toml", &typo);
    let e = fails(&d, &["identify", "typo.toml", "ident.csv", "--out", "c.toml"]);
    assert!(
        e.starts_with(&format!("typo.toml:{line}: `limit = [")) && e.contains("unknown field `limit`, expected one of"),
        "{e}"
    );
    // A value the TOML parser cannot read: the line is quoted, so the reader sees the letter O.
    let bad = m.replacen("limits = [-165.0", "limits = [-1O5.0", 1);
    write(&d, "bad.toml", &bad);
    let e = fails(&d, &["identify", "bad.toml", "ident.csv", "--out", "c.toml"]);
    assert!(e.contains("`limits = [-1O5.0, 165.0]`: "), "{e}");
    // An unknown built-in name or missing file.
    let e = fails(&d, &["validate", "nosuch", "ident.csv"]);
    assert_eq!(
        e,
        "nosuch: no such file, and not a built-in model (built-in: irb120, pm5, stewart, hexapod-6rus, head-3prs, linear-delta, stewart-limbs, pm5-limbs, t3r1-chain, t3r1, planar-3rrr)"
    );
}
