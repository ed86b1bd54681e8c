//! Raw exports through the general path: `data join` (controller log + one file per reflector,
//! any units, rows matched by id, lost beams dropped), `data split`, and `identify` on the
//! joined tracker-frame data, fitting the reflectors as a frame or as three points; several
//! starts that disagree fail the calibration.
use crate::cli::{fails, import_panda, kinecal, ok, panda_data, panda_sockets};
use std::fs;
use std::path::Path;

/// A tracker-frame IRB 120 data set of reflector triples (noise-free), split into raw exports:
/// `joints.csv` (idx, q1..q6 in rad, shuffled), `r1.csv`..`r3.csv` (idx, x, y, z in metres), a
/// lost beam (0,0,0) on id 7 in r2, and a steady reference reflector.
fn exports(d: &Path) {
    ok(d, &["model", "export", "irb120", "--out", "m.toml"]);
    let mut text = fs::read_to_string(d.join("m.toml")).unwrap();
    text.push_str(
        "\n[frames]\n[frames.measurement]\nposition = [2000.0, -700.0, 400.0]\nrpy = [100.0, -40.0, 75.0]\n\
         [frames.tool]\nposition = [90.0, -80.0, 90.0]\nrpy = [10.0, 20.0, -30.0]\n",
    );
    fs::write(d.join("tracker.toml"), text).unwrap();
    ok(
        d,
        &[
            "simulate",
            "tracker.toml",
            "--poses",
            "80",
            "--seed",
            "3",
            "--measure",
            "reflectors",
            "--out",
            "d.csv",
            "--truth",
            "t.toml",
        ],
    );
    let data = fs::read_to_string(d.join("d.csv")).unwrap();
    let rows: Vec<Vec<f64>> = data
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let mut joints = String::from("idx,a1,a2,a3,a4,a5,a6\n");
    for r in rows.iter().rev() {
        let q: Vec<String> = r[1..7].iter().map(|v| v.to_radians().to_string()).collect();
        joints += &format!("{},{}\n", r[0], q.join(","));
    }
    fs::write(d.join("joints.csv"), joints).unwrap();
    for k in 0..3 {
        let mut s = String::from("idx,x,y,z\n");
        for r in &rows {
            let c = 7 + 3 * k;
            if k == 1 && r[0] == 7.0 {
                s += "7,0,0,0\n";
            } else {
                s += &format!("{},{},{},{}\n", r[0], r[c] / 1000.0, r[c + 1] / 1000.0, r[c + 2] / 1000.0);
            }
        }
        fs::write(d.join(format!("r{}.csv", k + 1)), s).unwrap();
    }
    let mut s = String::from("id,x,y,z\n");
    for r in &rows {
        s += &format!("{},1.2,0.3,-0.4\n", r[0]);
    }
    fs::write(d.join("base.csv"), s).unwrap();
}

const JOIN: [&str; 18] = [
    "data",
    "join",
    "m.toml",
    "--joints",
    "joints.csv",
    "--reflector",
    "r1.csv",
    "--reflector",
    "r2.csv",
    "--reflector",
    "r3.csv",
    "--reference",
    "base.csv",
    "--angles",
    "rad",
    "--units",
    "m",
    "--out",
];

#[test]
fn joined_exports_calibrate_as_frame_and_as_points() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    exports(d);
    let mut args = JOIN.to_vec();
    args.push("all.csv");
    let out = kinecal(d, &args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (stdout, stderr) = (String::from_utf8(out.stdout).unwrap(), String::from_utf8(out.stderr).unwrap());
    assert!(stdout.contains("all.csv: 79 poses"), "{stdout}");
    assert!(stderr.contains("id 7: lost beam (empty or 0,0,0) in r2.csv line"), "{stderr}");
    assert!(
        stdout.contains("base.csv: 79 readings") && stdout.contains("max deviation 0.0000 mm"),
        "{stdout}"
    );
    let split = ok(
        d,
        &[
            "data", "split", "m.toml", "all.csv", "--by", "even", "--out", "a.csv", "--rest", "b.csv",
        ],
    );
    assert!(split.contains("a.csv (40 poses)") && split.contains("b.csv (39 poses)"), "{split}");
    for fit in ["frame", "points"] {
        let out = ok(
            d,
            &[
                "identify",
                "m.toml",
                "a.csv",
                "--validation",
                "b.csv",
                "--reflectors",
                fit,
                "--out",
                &format!("c-{fit}.toml"),
            ],
        );
        let line = out.lines().find(|l| l.starts_with("validation set after")).unwrap();
        let rms: f64 = line.split("RMS ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
        assert!(rms < 1e-6, "{fit}: {line}");
        assert!(out.contains("3 starts agree"), "{out}");
    }
    // The joined file is refused as an output over an input, and an existing output needs --force.
    let e = fails(d, &args);
    assert!(e.contains("--force"), "{e}");
}

#[test]
fn join_errors_name_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    exports(d);
    fs::write(d.join("short.csv"), "idx,a1,a2\n0,1,2\n").unwrap();
    let e = fails(
        d,
        &[
            "data",
            "join",
            "m.toml",
            "--joints",
            "short.csv",
            "--reflector",
            "r1.csv",
            "--out",
            "x.csv",
        ],
    );
    assert!(e.contains("short.csv") && e.contains("expected 6"), "{e}");
    let e = fails(
        d,
        &[
            "data",
            "join",
            "m.toml",
            "--joints",
            "joints.csv",
            "--reflector",
            "r1.csv",
            "--reflector",
            "r2.csv",
            "--out",
            "x.csv",
        ],
    );
    assert!(e.contains("one reflector export") && e.contains("not 2"), "{e}");
    let e = fails(
        d,
        &[
            "data", "split", "m.toml", "d.csv", "--by", "half", "--out", "a.csv", "--rest", "b.csv",
        ],
    );
    assert!(e.contains("below:ID, even or random:FRACTION"), "{e}");
    assert!(!d.join("x.csv").exists() && !d.join("a.csv").exists());
}

/// Tolerances of ±300° let the perturbed starts begin far from the nominal geometry: one of six
/// ends in a clearly worse minimum (σ̂₀ in the thousands against 0.000), far from the others'
/// predictions. It does not question the kept solution, which the other starts reproduce: it
/// is set aside and named, and the calibration stands. (Starts that fit about as well and
/// predict differently fail: `calibrate::starts` unit tests.)
#[test]
fn a_start_in_a_clearly_worse_minimum_is_set_aside() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    exports(d);
    let text = fs::read_to_string(d.join("m.toml")).unwrap();
    let wide: String = text
        .lines()
        .map(|l| {
            if l.starts_with("tolerance_deg") {
                "tolerance_deg = 300.0".to_string()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    fs::write(d.join("wide.toml"), wide).unwrap();
    let out = kinecal(d, &["identify", "wide.toml", "d.csv", "--starts", "6", "--out", "c.toml"]);
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    eprintln!("{stdout}{stderr}");
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stdout.contains("clearly worse minimum"), "{stdout}");
    assert!(d.join("c.toml").exists());
}

/// The third form of `data join`: one raw export per seat (the Panda's sockets as its controller
/// logged them, joints in rad, no header): one data file with a `seat` column, seat k the k-th
/// file, every row kept; a row with a missing joint and a seat with one row are one line each.
#[test]
fn seat_exports_join_into_one_seat_file() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    import_panda(d);
    let sockets = panda_sockets(&["back_left", "high"]);
    let mut args = vec!["data", "join", "panda.toml", "--angles", "rad", "--out", "seats.csv"];
    for s in &sockets {
        args.extend(["--seat", s.as_str()]);
    }
    ok(d, &args);
    let text = fs::read_to_string(d.join("seats.csv")).unwrap();
    let header = text.lines().next().unwrap();
    assert!(header.starts_with("id,panda_joint1_deg") && header.ends_with(",seat"), "{header}");
    // Every configuration of every file, in order, with its seat number; angles now in degrees.
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let mut expected = Vec::new();
    for (k, s) in sockets.iter().enumerate() {
        for line in fs::read_to_string(s).unwrap().lines().filter(|l| !l.trim().is_empty()) {
            let q: Vec<f64> = line.split(',').map(|v| v.trim().parse().unwrap()).collect();
            expected.push((q, k));
        }
    }
    assert_eq!(rows.len(), expected.len());
    for (row, (q, seat)) in rows.iter().zip(&expected) {
        assert_eq!(row[8], *seat as f64);
        for j in 0..7 {
            assert!((row[1 + j] - q[j].to_degrees()).abs() < 1e-9);
        }
    }
    // A mistake in a file: one line naming the file and line.
    let first = fs::read_to_string(&sockets[0]).unwrap();
    let mut lines: Vec<&str> = first.lines().collect();
    let short = lines[2].rsplit_once(',').unwrap().0.to_string();
    lines[2] = &short;
    fs::write(d.join("bad.csv"), lines.join("\n")).unwrap();
    let e = fails(
        d,
        &[
            "data",
            "join",
            "panda.toml",
            "--seat",
            "bad.csv",
            "--angles",
            "rad",
            "--out",
            "x.csv",
        ],
    );
    assert!(e.contains("bad.csv:3: 6 values, the model has 7 joint inputs"), "{e}");
    fs::write(d.join("one.csv"), lines[0]).unwrap();
    let e = fails(
        d,
        &[
            "data",
            "join",
            "panda.toml",
            "--seat",
            "one.csv",
            "--angles",
            "rad",
            "--out",
            "x.csv",
        ],
    );
    assert!(e.contains("one.csv: 1 configuration: a seat needs at least 2"), "{e}");
    assert!(!d.join("x.csv").exists());
}

/// A vendor's URDF whose limits are narrower than the robot's own log (panda_joint4 down to
/// −2.89 rad where the robot went to −3.049 rad): its limits are the vendor's software limits,
/// so the rows are kept with one warning naming the joint and the excess, from `data join`,
/// `data check` and `identify`, and the calibration runs (exit 0). Values in the wrong unit
/// still get the unit hint, and a value beyond the limits by more than half their range is
/// still refused.
#[test]
fn limits_narrower_than_the_data_are_a_warning_and_a_wrong_unit_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let urdf = fs::read_to_string(panda_data().join("panda.urdf")).unwrap();
    let narrowed = urdf.replacen("lower=\"-3.0718\"", "lower=\"-2.8900\"", 1);
    assert_ne!(narrowed, urdf);
    fs::write(d.join("panda.urdf"), narrowed).unwrap();
    ok(d, &["model", "import", "panda.urdf", "--tip", "ball_link", "-o", "panda.toml"]);
    let sockets = panda_sockets(&["back_left", "front_right", "high"]);
    let join = |angles: &str, out: &str| {
        let mut args = vec!["data", "join", "panda.toml", "--angles", angles, "--out", out];
        for s in &sockets {
            args.extend(["--seat", s.as_str()]);
        }
        kinecal(d, &args)
    };
    let joined = join("rad", "seats.csv");
    assert!(joined.status.success());
    let said = String::from_utf8(joined.stderr).unwrap();
    // The robot's own minimum of joint 4 over these files, beyond the narrowed −2.89 rad.
    let lowest = sockets
        .iter()
        .flat_map(|s| {
            fs::read_to_string(s)
                .unwrap()
                .lines()
                .filter_map(|l| l.split(',').nth(3)?.trim().parse::<f64>().ok())
                .collect::<Vec<_>>()
        })
        .fold(f64::INFINITY, f64::min);
    let excess = -2.89 - lowest;
    assert!(excess > 0.1, "{lowest}");
    let expected = format!("by up to {excess:.4} rad ({:.2}°)", excess.to_degrees());
    assert_eq!(said.lines().count(), 1, "{said}");
    assert!(
        said.starts_with("warning: 6 seat exports: panda_joint4: ")
            && said.contains("rows beyond the model's limits [-2.8900, -0.0698] rad")
            && said.contains(&expected)
            && said.contains("vendor's software limits"),
        "{said}"
    );
    // The joined file states degrees: the same rows, the same excess, in degrees.
    let checked = kinecal(d, &["data", "check", "panda.toml", "seats.csv"]);
    let said = String::from_utf8(checked.stderr).unwrap();
    assert!(
        checked.status.success() && said.contains("panda_joint4: ") && said.contains(&format!("by up to {:.4} deg", excess.to_degrees())),
        "{said}"
    );
    let mut args = vec!["identify", "panda.toml", "seats.csv", "--out", "cal.toml", "--json"];
    args.extend([
        "--seat-distance",
        "0:1:50",
        "--seat-distance",
        "2:3:50",
        "--seat-distance",
        "4:5:50",
    ]);
    let out = kinecal(d, &args);
    let said = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(0), "{said}");
    assert!(said.contains("warning: seats.csv: panda_joint4: "), "{said}");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_ne!(report["verdict"]["status"], "failed");
    assert!(
        report["flags"]
            .as_array()
            .unwrap()
            .iter()
            .any(|f| f.as_str().unwrap().contains("panda_joint4: ")),
        "the report shows it too"
    );
    // Radians joined as degrees: within ±2π, every one fits the limits read as radians.
    let wrong = join("deg", "wrong.csv");
    assert_eq!(wrong.status.code(), Some(1));
    let e = String::from_utf8(wrong.stderr).unwrap();
    assert!(
        e.contains("panda_joint4: ") && e.contains("check the column's unit") && e.contains("read in rad"),
        "{e}"
    );
    assert!(e.contains("/socket_0.csv:1: panda_joint4: "), "named with its file and line: {e}");
    // Degrees in a column said to be radians: far beyond, every one fits read as degrees.
    let text = fs::read_to_string(d.join("seats.csv")).unwrap().replace("_deg", "_rad");
    fs::write(d.join("rad.csv"), text).unwrap();
    let e = fails(d, &["data", "check", "panda.toml", "rad.csv"]);
    assert!(
        e.contains("is outside the model's limits") && e.contains("check the column's unit") && e.contains("read in deg"),
        "{e}"
    );
}
