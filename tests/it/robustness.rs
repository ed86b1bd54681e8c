//! Hostile but realistic input (never hang, never destroy, never pass a failed result):
//! each case answers at once with one clear message.
use kinecal::design::{CandidateJacobians, SelectOptions};
use kinecal::io::builtin;
use kinecal::io::data_file::{data_from_table, InputColumns};
use kinecal::io::model_file::ModelFile;
use kinecal::io::table::parse_table;
use kinecal::Mechanism;
use std::path::Path;

fn irb120_file() -> ModelFile {
    builtin::model_file("irb120").unwrap()
}

fn read(text: &str) -> Result<kinecal::io::data_file::DataSet, String> {
    let path = Path::new("d.csv");
    let table = parse_table(path, text).map_err(|e| e.to_string())?;
    data_from_table(&table, &irb120_file().inputs(), InputColumns::Required).map_err(|e| e.to_string())
}

const HEADER: &str = "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm";

#[test]
fn duplicate_ids_name_both_lines() {
    let e = read(&format!("{HEADER}\n1,0,0,0,0,30,0,1,2,3\n1,0,0,0,0,30,0,1,2,3\n")).unwrap_err();
    assert_eq!(e, "d.csv:3: id 1 appears twice (first on line 2); every pose needs its own id");
}

#[test]
fn an_implausible_coordinate_is_refused_with_its_line() {
    // A corrupted number (it once sent the frame estimate into an endless loop).
    let e = read(&format!("{HEADER}\n1,0,0,0,0,30,0,1,2,3\n2,0,0,0,0,30,0,1,2,4.3e156\n")).unwrap_err();
    assert!(
        e.starts_with("d.csv:3: column 'z_mm': 4.3000e156 mm is not a plausible coordinate"),
        "{e}"
    );
}

#[test]
fn joint_values_outside_the_limits_are_refused() {
    let e = read(&format!("{HEADER}\n1,500,0,0,0,30,0,1,2,3\n")).unwrap_err();
    assert!(e.starts_with("d.csv:2: q1: 500.0000 deg is outside the model's limits"), "{e}");
}

#[test]
fn a_header_only_file_is_refused() {
    let e = read(&format!("{HEADER}\n")).unwrap_err();
    assert!(e.contains("no data rows"), "{e}");
}

#[test]
fn extra_array_elements_in_a_model_file_are_refused() {
    let text = builtin::model_file("pm5").unwrap().to_toml().unwrap();
    let line = text
        .lines()
        .position(|l| l.trim_start().starts_with("c = ["))
        .expect("a 'c = [..]' line");
    let bad: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| if i == line { l.replacen(']', ", 5]", 1) } else { l.to_string() })
        .collect();
    let e = ModelFile::load_str(Path::new("m.toml"), &bad.join("\n")).unwrap_err().to_string();
    assert!(e.starts_with(&format!("m.toml:{}: ", line + 1)), "{e}");
    assert!(e.ends_with(".c: expected 3 values, found 4"), "{e}");
}

#[test]
fn extreme_geometry_fails_fast_instead_of_hanging() {
    // 1e15 mm, 1e-308 and 1e300 in closed-loop geometries: loading, forward kinematics and the
    // identification Jacobian answer (a clear error, or finite values), never spin inside an SVD
    // of NaN.
    for kind in ["stewart", "pm5"] {
        let text = builtin::model_file(kind).unwrap().to_toml().unwrap();
        let line = text
            .lines()
            .find(|l| l.trim_start().starts_with("base = [") || l.trim_start().starts_with("c = ["))
            .unwrap();
        let first = line.split('[').nth(1).unwrap().split(',').next().unwrap();
        for extreme in ["1e15", "1e-308", "1e300"] {
            let bad = text.replacen(line, &line.replacen(first, extreme, 1), 1);
            let file = match ModelFile::load_str(Path::new("m.toml"), &bad) {
                Ok(f) => f,
                Err(e) => {
                    assert!(e.to_string().starts_with("m.toml:"), "{e}");
                    continue;
                }
            };
            let m = file.build();
            let q = vec![1.0; m.input_names().len()];
            if let Ok((pose, jac)) = m.forward_with_jacobian(&q) {
                assert!(pose.translation.vector.iter().all(|v| v.is_finite()), "{kind} {extreme}");
                assert!(jac.iter().all(|v| v.is_finite()), "{kind} {extreme}");
            }
        }
    }
}

#[test]
fn plan_options_that_cannot_work_are_refused() {
    let blocks = CandidateJacobians::from_raw(
        6,
        (0..12).collect(),
        (0..6 * 12 * 4).map(|i| ((i * 37) % 11) as f64 - 5.0).collect(),
    )
    .unwrap();
    let mut opts = SelectOptions {
        n: 1,
        ..SelectOptions::default()
    };
    let e = kinecal::design::select::greedy(&blocks, &opts, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("choose at least 2"), "{e}");
    opts.n = 2;
    opts.pool = 0;
    let e = kinecal::design::select::sffs(&blocks, &opts, &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("pool must be at least 1"), "{e}");
}

/// A directory with the exported IRB 120 model and simulated data with 0.05 mm / 0.05° noise.
fn noisy_irb120() -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    crate::cli::ok(d, &["model", "export", "irb120", "--out", "m.toml"]);
    crate::cli::ok(
        d,
        &[
            "simulate",
            "m.toml",
            "--poses",
            "40",
            "--seed",
            "3",
            "--noise-mm",
            "0.05",
            "--noise-deg",
            "0.05",
            "--out",
            "d.csv",
            "--truth",
            "t.toml",
            "--validation-poses",
            "10",
            "--validation-out",
            "v.csv",
        ],
    );
    tmp
}

/// Every file of `dir` with its contents.
fn snapshot(dir: &Path) -> Vec<(std::path::PathBuf, Vec<u8>)> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let p = e.unwrap().path();
            let c = std::fs::read(&p).unwrap_or_default();
            (p, c)
        })
        .collect();
    v.sort();
    v
}

#[test]
fn outputs_never_replace_inputs_each_other_or_existing_files() {
    let tmp = noisy_irb120();
    let d = tmp.path();
    let before = snapshot(d);
    let cases: [(&[&str], &str); 5] = [
        (&["identify", "m.toml", "d.csv", "--out", "d.csv"], "would replace the input"),
        (
            &["identify", "m.toml", "d.csv", "--out", "c.toml", "--report", "c.toml"],
            "two outputs",
        ),
        (
            &["identify", "m.toml", "d.csv", "--out", "c.toml", "--report", "nodir/r.html"],
            "does not exist",
        ),
        (&["identify", "m.toml", "d.csv", "--out", "t.toml"], "--force"),
        (
            &["simulate", "m.toml", "--out", "nodir/x.csv", "--truth", "t2.toml"],
            "does not exist",
        ),
    ];
    for (args, expect) in cases {
        let e = crate::cli::fails(d, args);
        assert!(e.contains(expect), "{args:?}: {e}");
        assert_eq!(snapshot(d), before, "{args:?} changed a file");
    }
}

#[test]
fn a_stated_noise_far_too_small_alone_warns_and_does_not_fail() {
    let tmp = noisy_irb120();
    let d = tmp.path();
    // 0.05 mm noise stated as 1 µm: σ̂₀ ≈ 50, but the calibration clearly improves the held-out
    // poses with a machine within its tolerances: usable, the warning names the residual.
    let args = [
        "identify",
        "m.toml",
        "d.csv",
        "--validation",
        "v.csv",
        "--noise-mm",
        "0.001",
        "--noise-deg",
        "0.001",
        "--out",
        "c.toml",
    ];
    let text = crate::cli::ok(d, &args);
    assert!(text.contains("verdict: usable with warnings: the residual is"), "{text}");
    assert!(text.contains("the stated noise is optimistic"), "{text}");
}

#[test]
fn a_wrong_model_exits_2_and_writes_nothing_without_force() {
    let tmp = noisy_irb120();
    let d = tmp.path();
    // A model of another machine: a link 120 mm longer than the simulated one.
    let model = std::fs::read_to_string(d.join("m.toml")).unwrap().replacen("270.0", "390.0", 1);
    std::fs::write(d.join("other.toml"), model).unwrap();
    let before = snapshot(d);
    let args = ["identify", "other.toml", "d.csv", "--out", "c.toml", "--report", "r.html"];
    let out = crate::cli::kinecal(d, &args);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(
        err.starts_with("kinecal: failed: verdict: failed: corrections beyond the model's tolerances"),
        "{err}"
    );
    assert!(
        !String::from_utf8(out.stdout).unwrap().contains(" converged after"),
        "a failed fit must not say converged"
    );
    assert_eq!(snapshot(d), before);
    // --force writes both, marked failed; compensating with it needs --force too.
    let mut forced = args.to_vec();
    forced.push("--force");
    assert_eq!(crate::cli::kinecal(d, &forced).status.code(), Some(2));
    let text = std::fs::read_to_string(d.join("c.toml")).unwrap();
    assert!(text.contains("[provenance]") && text.contains("status = \"failed\""), "{text}");
    assert!(std::fs::read_to_string(d.join("r.html")).unwrap().contains("FAILED"));
    let e = crate::cli::fails(d, &["compensate", "c.toml", "v.csv", "--out", "cmd.csv"]);
    assert!(e.contains("marked failed"), "{e}");
}

#[test]
fn a_good_fit_records_its_provenance_and_verdict() {
    let tmp = noisy_irb120();
    let d = tmp.path();
    let args = [
        "identify",
        "m.toml",
        "d.csv",
        "--validation",
        "v.csv",
        "--noise-mm",
        "0.05",
        "--noise-deg",
        "0.05",
        "--out",
        "c.toml",
    ];
    let text = crate::cli::ok(d, &args);
    assert!(text.contains("verdict: "), "{text}");
    let model = ModelFile::load(&d.join("c.toml")).unwrap();
    let p = model.provenance.expect("provenance");
    assert_ne!(p.status, "failed");
    assert_eq!(p.version, env!("CARGO_PKG_VERSION"));
    assert!(
        p.command.contains("identify") && p.data[0] == "d.csv" && p.date.ends_with('Z'),
        "{p:?}"
    );
}

#[test]
fn a_utf8_bom_is_accepted_and_a_header_only_file_refused() {
    let tmp = noisy_irb120();
    let d = tmp.path();
    let mut bytes = b"\xEF\xBB\xBF".to_vec();
    bytes.extend(std::fs::read(d.join("v.csv")).unwrap());
    std::fs::write(d.join("bom.csv"), bytes).unwrap();
    crate::cli::ok(d, &["validate", "m.toml", "bom.csv"]);
    let header = std::fs::read_to_string(d.join("v.csv"))
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .to_string();
    std::fs::write(d.join("empty.csv"), header + "\n").unwrap();
    let e = crate::cli::fails(d, &["validate", "m.toml", "empty.csv"]);
    assert!(e.contains("no data rows"), "{e}");
}

/// Replace the first occurrence of `from` in `file` (in `dir`) and write the result to `to`.
fn edited(dir: &Path, file: &str, from: &str, with: &str, to: &str) {
    let text = std::fs::read_to_string(dir.join(file)).unwrap();
    assert!(text.contains(from), "{file} has no '{from}'");
    std::fs::write(dir.join(to), text.replacen(from, with, 1)).unwrap();
}

/// Every tenth pose's x moved by 5–50 mm.
fn with_blunders(dir: &Path, file: &str, to: &str) {
    let text = std::fs::read_to_string(dir.join(file)).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let ix = header.split(',').position(|c| c == "x_mm").unwrap();
    let mut out = header.to_string() + "\n";
    for (i, l) in lines.enumerate() {
        let mut v: Vec<String> = l.split(',').map(String::from).collect();
        if i % 10 == 3 {
            let shift = 5.0 + 45.0 * ((i * 7919) % 100) as f64 / 100.0;
            v[ix] = (v[ix].parse::<f64>().unwrap() + if i % 20 == 3 { shift } else { -shift }).to_string();
        }
        out += &(v.join(",") + "\n");
    }
    std::fs::write(dir.join(to), out).unwrap();
}

/// The hostile cases of the closed-loop machines: each answers within a minute (in practice well
/// under a second) with one clear line and the right exit code, and a failed command leaves no
/// output behind and every input unchanged.
#[test]
fn hostile_cases_answer_at_once_with_one_line() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let ok = |args: &[&str]| crate::cli::ok(d, args);
    ok(&["model", "export", "pm5", "--out", "pm5.toml"]);
    ok(&["model", "export", "stewart", "--out", "st.toml"]);
    for (m, data) in [("pm5.toml", "p.csv"), ("st.toml", "s.csv")] {
        ok(&[
            "simulate",
            m,
            "--poses",
            "30",
            "--seed",
            "1",
            "--noise-mm",
            "0.02",
            "--noise-deg",
            "0.02",
            "--out",
            data,
            "--truth",
            &format!("t-{data}.toml"),
        ]);
    }
    ok(&[
        "simulate",
        "pm5.toml",
        "--poses",
        "6",
        "--seed",
        "1",
        "--noise-mm",
        "0.02",
        "--noise-deg",
        "0.02",
        "--out",
        "p6.csv",
        "--truth",
        "t6.toml",
    ]);
    edited(d, "pm5.toml", "c = [0.0, 100.0, 0.0]", "c = [0.0, -100.0, 0.0]", "pm5-typo.toml");
    edited(
        d,
        "st.toml",
        "position = [0.0, 0.0, 300.0]",
        "position = [0.0, 0.0, -300.0]",
        "st-typo.toml",
    );
    with_blunders(d, "p.csv", "p-blunders.csv");
    with_blunders(d, "s.csv", "s-blunders.csv");
    std::fs::write(
        d.join("header.csv"),
        std::fs::read_to_string(d.join("p.csv"))
            .unwrap()
            .lines()
            .next()
            .unwrap()
            .to_string()
            + "\n",
    )
    .unwrap();
    std::fs::write(
        d.join("yaw.csv"),
        "x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg\n0,0,400,0,0,89.95\n10,0,380,1,0,-89.99\n",
    )
    .unwrap();
    let before = snapshot(d);
    // (arguments, exit code, text expected in the one line of stderr, output files it may write)
    let cases: Vec<(Vec<&str>, i32, &str, Vec<&str>)> = vec![
        (
            vec!["identify", "pm5-typo.toml", "p.csv", "--out", "c.toml"],
            1,
            "does not assemble at its home pose",
            vec![],
        ),
        (
            vec!["identify", "st-typo.toml", "s.csv", "--out", "c.toml"],
            2,
            "the model's tolerances",
            vec![],
        ),
        (
            vec!["identify", "pm5.toml", "p-blunders.csv", "--out", "c.toml"],
            0,
            "set aside as blunders (beyond 10 robust σ of the per-pose residuals): ids 3 13 23",
            vec!["c.toml"],
        ),
        (
            vec!["identify", "st.toml", "s-blunders.csv", "--out", "c.toml"],
            0,
            "set aside as blunders (beyond 10 robust σ of the per-pose residuals): ids 3 13 23",
            vec!["c.toml"],
        ),
        (
            // Six poses for 32 parameters: the corrections are poorly determined, and a machine
            // within its tolerances (the truth: ±0.5 mm / ±0.1 deg) explains the data, so the
            // tolerance check finds no evidence against it (it once failed on a split that
            // pushed well-determined angles to 5 deg to keep poorly determined ones small). With
            // 7 rows beyond 29 parameters (three more seen too weakly, held) nothing checks the fit: a
            // warning says so.
            vec!["identify", "pm5.toml", "p6.csv", "--frames", "model", "--out", "c.toml"],
            0,
            "only 7 residual rows beyond the 29 identified parameters",
            vec!["c.toml"],
        ),
        (vec!["validate", "pm5.toml", "header.csv"], 1, "no data rows", vec![]),
        (
            vec!["simulate", "pm5.toml", "--error-mm", "100", "--out", "x.csv", "--truth", "xt.toml"],
            1,
            "errors this large make another machine",
            vec![],
        ),
        (
            vec![
                "plan",
                "--model",
                "pm5.toml",
                "--candidates",
                "2000",
                "-n",
                "5",
                "--output",
                "plan5.csv",
            ],
            1,
            "choose at least 6",
            vec![],
        ),
        (
            vec![
                "plan",
                "--model",
                "pm5.toml",
                "--candidates",
                "2000",
                "-n",
                "8",
                "--pool",
                "0",
                "--output",
                "plan5.csv",
            ],
            1,
            "pool must be at least 1",
            vec![],
        ),
        (
            vec![
                "plan",
                "--model",
                "pm5.toml",
                "--z-mm",
                "100,450",
                "--candidates",
                "3000",
                "-n",
                "30",
                "--output",
                "plan.csv",
            ],
            0,
            "",
            vec!["plan.csv"],
        ),
        (
            vec!["compensate", "pm5.toml", "yaw.csv", "--out", "cmd.csv"],
            0,
            "",
            vec!["cmd.csv"],
        ),
    ];
    for (args, code, expect, writes) in cases {
        let out = crate::cli::kinecal_within(d, &args, 60);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
        if code != 0 {
            assert_eq!(err.lines().filter(|l| l.starts_with("kinecal: ")).count(), 1, "{args:?}: {err}");
            assert!(err.contains(expect), "{args:?}: {err}");
        } else {
            let stdout = String::from_utf8_lossy(&out.stdout);
            assert!(stdout.contains(expect), "{args:?}: {stdout}");
        }
        let mut after = snapshot(d);
        after.retain(|(p, _)| !writes.iter().any(|w| p.ends_with(w)));
        assert_eq!(after, before, "{args:?} changed or left a file");
        for w in writes {
            std::fs::remove_file(d.join(w)).unwrap();
        }
    }
}

/// Drop the `dir_<joint>` columns of a CSV file (`from` → `to`, in `dir`).
fn without_directions(dir: &Path, from: &str, to: &str) {
    let text = std::fs::read_to_string(dir.join(from)).unwrap();
    let rows: Vec<Vec<&str>> = text.lines().map(|l| l.split(',').collect()).collect();
    let keep: Vec<usize> = (0..rows[0].len()).filter(|&i| !rows[0][i].starts_with("dir_")).collect();
    let out: String = rows
        .iter()
        .map(|r| keep.iter().map(|&i| r[i]).collect::<Vec<_>>().join(",") + "\n")
        .collect();
    std::fs::write(dir.join(to), out).unwrap();
}

/// What a real arm leaves after a geometric calibration: a virtual IRB 120 with lost motion and
/// gravity compliance in its joints (the joint terms), measured from a tracker with 20 µm /
/// 0.02° noise, calibrated with the geometric model at the default noise. The residual is
/// ~12× the noise, the held-out error halves: usable with warnings, never failed.
#[test]
fn a_real_arm_s_unmodelled_residual_is_usable_with_warnings_not_failed() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    crate::cli::ok(d, &["model", "export", "irb120", "--out", "m.toml"]);
    let text = std::fs::read_to_string(d.join("m.toml")).unwrap();
    let at = text.find("\n[calibration]").expect("a [calibration] section");
    let terms = format!(
        "{}\n[mechanism.joint_terms]\nbacklash = [\"q1\", \"q2\", \"q3\", \"q4\", \"q5\", \"q6\"]\ngravity = [\"q2\", \"q3\"]\n{}\n[frames]\n[frames.measurement]\nposition = [2000.0, -700.0, 400.0]\nrpy = [100.0, -40.0, 75.0]\n[frames.tool]\nposition = [90.0, -80.0, 90.0]\nrpy = [10.0, 20.0, -30.0]\n",
        &text[..at],
        &text[at..]
    );
    std::fs::write(d.join("terms.toml"), terms).unwrap();
    crate::cli::simulate(d, "terms.toml", 150, 50, 6, 0.02, &[]);
    without_directions(d, "d.csv", "dg.csv");
    without_directions(d, "v.csv", "vg.csv");
    let out = crate::cli::ok(d, &["identify", "m.toml", "dg.csv", "--validation", "vg.csv", "--out", "c.toml"]);
    assert!(out.contains("verdict: usable with warnings: the residual is"), "{out}");
    assert!(
        out.contains("real machines leave such a residual") && out.contains("joint terms"),
        "{out}"
    );
    assert!(d.join("c.toml").exists());
}

/// A Stewart platform whose joint centres sit up to 5 mm (its tolerance) from the drawing,
/// measured in a tracker frame with a tool offset, frames estimated: the corrections are judged
/// in the split of redundant parameters and frames that keeps them smallest, so a machine within
/// its tolerances is not failed for how the minimum-norm solution split them.
#[test]
fn a_machine_at_its_tolerances_is_not_failed_for_a_split_of_the_parameters() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    crate::cli::ok(d, &["model", "export", "stewart", "--out", "s.toml"]);
    let mut text = std::fs::read_to_string(d.join("s.toml")).unwrap();
    text.push_str(
        "\n[frames]\n[frames.measurement]\nposition = [2000.0, -700.0, 400.0]\nrpy = [100.0, -40.0, 75.0]\n\
         [frames.tool]\nposition = [20.0, -30.0, 50.0]\nrpy = [10.0, 20.0, -30.0]\n",
    );
    std::fs::write(d.join("tracker.toml"), text).unwrap();
    for (seed, noise) in [(2, 0.02), (1, 0.0)] {
        crate::cli::simulate(
            d,
            "tracker.toml",
            50,
            20,
            seed,
            noise,
            &["--error-mm", "5", "--error-deg", "0.5", "--force"],
        );
        let out = crate::cli::ok(
            d,
            &["identify", "s.toml", "d.csv", "--validation", "v.csv", "--out", "c.toml", "--force"],
        );
        assert!(out.contains("verdict: calibrated"), "seed {seed}, noise {noise}: {out}");
    }
}

/// Position data planned at one tool orientation barely show the tool offset (at one orientation
/// it moves every point alike; only the robot's own geometric errors turn the tool a little from
/// pose to pose). Noise-free that little is enough and the offset is found (held-out poses to
/// round-off); with 0.01 mm of noise it is not: the fit is good on the identification poses and
/// held-out poses at other orientations keep the offset's error. The verdict says so (a warning,
/// exit 0), instead of "calibrated".
#[test]
fn held_out_poses_far_worse_than_the_fit_are_a_warning() {
    use crate::cli::ok;
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ok(d, &["model", "export", "irb120", "--out", "irb.toml"]);
    ok(
        d,
        &[
            "plan",
            "--model",
            "irb.toml",
            "-n",
            "25",
            "--candidates",
            "2000",
            "--x-mm",
            "300,500",
            "--y-mm",
            "-150,150",
            "--z-mm",
            "300,550",
            "-o",
            "plan.csv",
        ],
    );
    for (noise, calibrated) in [("0", true), ("0.01", false)] {
        ok(
            d,
            &[
                "simulate",
                "irb.toml",
                "--at",
                "plan.csv",
                "--measure",
                "position",
                "--seed",
                "2",
                "--noise-mm",
                noise,
                "--noise-deg",
                "0",
                "--validation-poses",
                "30",
                "--out",
                "s.csv",
                "--truth",
                "t.toml",
                "--validation-out",
                "v.csv",
                "--force",
            ],
        );
        let v = crate::cli::json(
            d,
            &[
                "identify",
                "irb.toml",
                "s.csv",
                "--validation",
                "v.csv",
                "--out",
                "c.toml",
                "--force",
            ],
        );
        let held_out = v["validation"]["after_stats"]["position_rms_mm"].as_f64().unwrap();
        let verdict = v["verdict"]["status"].as_str().unwrap().to_string();
        if calibrated {
            assert!(held_out < 1e-6, "noise-free: held-out RMS {held_out} mm\n{v}");
            assert_eq!(verdict, "calibrated", "{v}");
        } else {
            assert!(held_out > 0.1, "0.01 mm noise: held-out RMS {held_out} mm\n{v}");
            assert_eq!(verdict, "usable-with-warnings", "{v}");
            let reasons = v["verdict"]["reasons"].to_string();
            assert!(reasons.contains("the held-out poses keep"), "{reasons}");
        }
    }
}

/// Three poses of thirty 25 mm off in the same direction (the whole tool: all three reflectors)
/// pull a Huber fit so far that its robust scale grows with them and none stands out; the
/// trimmed fit finds them. Before: held-out 4.22 mm RMS, "failed", exit 2; now they are set
/// aside and the held-out poses are predicted to the noise.
#[test]
fn blunders_that_pull_the_fit_together_are_found_by_a_trimmed_fit() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let ok = |args: &[&str]| crate::cli::ok(d, args);
    ok(&["model", "export", "irb120", "--out", "m.toml"]);
    crate::cli::simulate(d, "m.toml", 30, 20, 5, 0.02, &["--measure", "reflectors"]);
    let text = std::fs::read_to_string(d.join("d.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().filter(|l| !l.starts_with('#')).map(String::from).collect();
    let ix = lines[0].split(',').position(|c| c == "m1x_mm").unwrap();
    for k in [4, 14, 24] {
        let mut v: Vec<String> = lines[k].split(',').map(String::from).collect();
        for j in [ix, ix + 3, ix + 6] {
            v[j] = (v[j].parse::<f64>().unwrap() + 25.0).to_string();
        }
        lines[k] = v.join(",");
    }
    std::fs::write(d.join("b.csv"), lines.join("\n") + "\n").unwrap();
    let v = crate::cli::json(d, &["identify", "m.toml", "b.csv", "--validation", "v.csv", "--out", "c.toml"]);
    let set_aside: Vec<i64> = v["blunders"].as_array().unwrap().iter().map(|x| x.as_i64().unwrap()).collect();
    assert_eq!(set_aside, vec![3, 13, 23], "{v}");
    let after = v["validation"]["after_stats"]["position_rms_mm"].as_f64().unwrap();
    assert!(after < 0.05, "held-out RMS {after} mm\n{v}");
    // Clean data keep their fit: nothing set aside.
    let c = crate::cli::json(d, &["identify", "m.toml", "d.csv", "--validation", "v.csv", "--out", "c2.toml"]);
    assert!(c["blunders"].as_array().unwrap().is_empty(), "{c}");
}

/// A residual far beyond the stated noise with a calibration that improves the held-out poses,
/// but not clearly (0.8–0.9 of the nominal RMS), is a warning naming the weak improvement, not a
/// failure; hardly any improvement (above 0.9) still fails. Noise 0.05 mm stated as 0.002 mm
/// (σ̂₀ ≈ 24) on an IRB 120 whose errors are of the noise's size.
#[test]
fn a_weak_but_real_improvement_is_a_warning_and_none_a_failure() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    crate::cli::ok(d, &["model", "export", "irb120", "--out", "m.toml"]);
    let identify = [
        "identify",
        "m.toml",
        "d.csv",
        "--validation",
        "v.csv",
        "--noise-mm",
        "0.002",
        "--noise-deg",
        "0.002",
        "--out",
        "c.toml",
    ];
    crate::cli::simulate(d, "m.toml", 40, 20, 3, 0.05, &["--error-mm", "0.05", "--error-deg", "0.002"]);
    let said = crate::cli::ok(d, &identify);
    assert!(
        said.contains("verdict: usable with warnings: the calibration improves the held-out poses by only"),
        "{said}"
    );
    crate::cli::simulate(
        d,
        "m.toml",
        40,
        20,
        3,
        0.05,
        &["--error-mm", "0.02", "--error-deg", "0.002", "--force"],
    );
    let mut again = identify.to_vec();
    *again.last_mut().unwrap() = "c2.toml";
    let out = crate::cli::kinecal(d, &again);
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("does not clearly improve on the nominal model"));
}
