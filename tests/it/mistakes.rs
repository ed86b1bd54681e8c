//! A user's mistakes get one line naming the cause (exit 1), or a line beside the result when it
//! can go on; small wording a user reads (plurals, what a command wrote).
use crate::cli::{fails, import_panda as panda, kinecal, ok, panda_sockets};
use std::fs;

/// A data file where the model goes (`identify DATA MODEL`): the order, not a TOML message.
#[test]
fn a_csv_given_as_the_model_names_the_order() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let said = ok(d, &["simulate", "pm5", "--poses", "1", "--out", "d.csv", "--truth", "t.toml"]);
    // One pose is "1 pose".
    assert!(said.contains("1 pose,") && !said.contains("1 poses"), "{said}");
    let said = ok(d, &["model", "export", "pm5", "--out", "m.toml"]);
    assert!(said.contains("→ m.toml") && said.contains("pm5"), "{said}");
    for args in [
        &["identify", "d.csv", "m.toml", "--out", "c.toml"][..],
        &["data", "check", "d.csv", "m.toml"][..],
        &["validate", "d.csv", "m.toml"][..],
    ] {
        let e = fails(d, args);
        assert!(
            e.contains("d.csv") && e.contains("this is a CSV") && e.contains("MODEL DATA"),
            "{args:?}: {e}"
        );
    }
    let said = ok(d, &["data", "check", "m.toml", "d.csv"]);
    assert!(said.contains("1 pose,"), "{said}");
}

fn sockets() -> Vec<String> {
    panda_sockets(&["back_left", "front_right", "high"])
}

/// `data join --seat`: a file given twice, or a copy of another seat's file, is refused; a seat of
/// 2 rows beside seats of 30 is a warning; `;`-separated files are refused naming the separator.
#[test]
fn data_join_refuses_a_seat_twice_and_warns_on_a_thin_seat() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    panda(d);
    let s = sockets();
    fn join<'a>(seats: &[&'a str]) -> Vec<&'a str> {
        let mut args = vec!["data", "join", "panda.toml", "--angles", "rad", "--out", "x.csv"];
        for s in seats {
            args.extend(["--seat", s]);
        }
        args
    }
    let e = fails(d, &join(&[&s[0], &s[1], &s[0]]));
    assert!(e.contains("given twice") && e.contains("socket_0.csv"), "{e}");
    fs::copy(&s[1], d.join("copy.csv")).unwrap();
    let e = fails(d, &join(&[&s[0], &s[1], "copy.csv"]));
    assert!(e.contains("copy.csv") && e.contains("the same rows as seat 1"), "{e}");
    assert!(!d.join("x.csv").exists());
    // A seat of two rows beside seats of 30.
    let two: Vec<String> = fs::read_to_string(&s[2]).unwrap().lines().take(2).map(String::from).collect();
    fs::write(d.join("two.csv"), two.join("\n")).unwrap();
    let out = kinecal(d, &join(&[&s[0], &s[1], &s[3], &s[4], "two.csv"]));
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(0), "{err}");
    let w: Vec<&str> = err.lines().filter(|l| l.starts_with("warning:")).collect();
    assert!(w.iter().any(|l| l.contains("seat 4 (2 rows)") && l.contains("median of")), "{err}");
    fs::remove_file(d.join("x.csv")).unwrap();
    // `;` between the values: one line naming the separator, for the seat form and the others.
    let semi = fs::read_to_string(&s[0]).unwrap().replace(',', ";");
    fs::write(d.join("semi.csv"), semi).unwrap();
    let e = fails(d, &join(&["semi.csv", &s[1]]));
    assert!(e.contains("semi.csv:1") && e.contains("separated by ';'"), "{e}");
    ok(d, &["simulate", "pm5", "--poses", "3", "--out", "p.csv", "--truth", "t.toml"]);
    let semi = fs::read_to_string(d.join("p.csv")).unwrap().replace(',', ";");
    fs::write(d.join("psemi.csv"), semi).unwrap();
    let e = fails(d, &["data", "check", "pm5", "psemi.csv"]);
    assert!(
        e.contains("psemi.csv") && e.contains("separated by ';'") && e.contains("comma-separated"),
        "{e}"
    );
}

/// Targets in metres (`x_m`): read as metres, as the data files' docs say, with a line saying so.
#[test]
fn targets_in_metres_are_read_as_metres_with_a_line() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ok(
        d,
        &[
            "simulate", "irb120", "--poses", "3", "--out", "p.csv", "--truth", "t.toml", "--seed", "4",
        ],
    );
    // The simulated poses as targets without inputs, in mm and then in metres.
    let text = fs::read_to_string(d.join("p.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let keep: Vec<usize> = (0..header.len())
        .filter(|&k| header[k] == "id" || ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"].contains(&header[k]))
        .collect();
    let rows: Vec<Vec<String>> = lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            keep.iter()
                .map(|&k| match header[k].ends_with("_mm") {
                    true => (f[k].parse::<f64>().unwrap() / 1000.0).to_string(),
                    false => f[k].to_string(),
                })
                .collect()
        })
        .collect();
    let head: Vec<String> = keep.iter().map(|&k| header[k].replace("_mm", "_m")).collect();
    let mut out = head.join(",") + "\n";
    for r in &rows {
        out += &(r.join(",") + "\n");
    }
    fs::write(d.join("targets.csv"), out).unwrap();
    let run = kinecal(d, &["compensate", "irb120", "targets.csv", "--out", "cmd.csv"]);
    let err = String::from_utf8(run.stderr).unwrap();
    assert_eq!(run.status.code(), Some(0), "{err}");
    assert!(err.contains("targets.csv: x_m, y_m, z_m read as metres"), "{err}");
}

/// A plan that cannot identify the model (12 ballbar rows for 32 identifiable columns) ends with
/// one line and exit 1, nothing written; `--force` writes it with a warning.
#[test]
fn a_rank_deficient_plan_is_refused_unless_forced() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ok(d, &["model", "export", "pm5", "-o", "pm5.toml"]);
    let args = [
        "plan",
        "--model",
        "pm5.toml",
        "--pivots",
        "0,-30,370;40,-30,380;-30,20,375",
        "--ballbar-mm",
        "100",
        "--tool-mm",
        "0,0,-50",
        "-n",
        "12",
        "-o",
        "p.csv",
    ];
    let e = fails(d, &args);
    assert!(
        e.contains("12 rows determine only") && e.contains("of the 32 identifiable columns") && e.contains("--force"),
        "{e}"
    );
    assert!(!d.join("p.csv").exists());
    let forced = kinecal(d, &[&args[..], &["--force"]].concat());
    assert_eq!(forced.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&forced.stderr).contains("warning: the plan's 12 rows determine only"));
    assert!(d.join("p.csv").exists());
}

/// A data row at which the model does not assemble (pm5's first actuator 40 mm off in one row:
/// its forward kinematics from home does not converge) is set aside with a line naming the file
/// and line, as a blunder is, and identify, validate and identifiability go on with the rest.
#[test]
fn a_row_where_the_model_does_not_assemble_is_set_aside() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ok(d, &["model", "export", "pm5", "-o", "pm5.toml"]);
    ok(
        d,
        &[
            "simulate",
            "pm5.toml",
            "--poses",
            "40",
            "--out",
            "d.csv",
            "--truth",
            "t.toml",
            "--noise-mm",
            "0.001",
            "--noise-deg",
            "0.001",
        ],
    );
    let text = fs::read_to_string(d.join("d.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut f: Vec<String> = lines[3].split(',').map(String::from).collect();
    f[1] = (f[1].parse::<f64>().unwrap() + 40.0).to_string();
    lines[3] = f.join(",");
    fs::write(d.join("bad.csv"), lines.join("\n") + "\n").unwrap();
    for args in [
        &["identify", "pm5.toml", "bad.csv", "--frames", "model", "--out", "c.toml"][..],
        &["validate", "pm5.toml", "bad.csv"][..],
        &["identifiability", "pm5.toml", "bad.csv"][..],
    ] {
        let out = kinecal(d, args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {err}");
        let w: Vec<&str> = err.lines().filter(|l| l.contains("set aside")).collect();
        assert_eq!(w.len(), 1, "{args:?}: {err}");
        assert!(
            w[0].contains("bad.csv: 1 row set aside: the model does not assemble there") && w[0].contains("line 4"),
            "{args:?}: {err}"
        );
    }
    assert!(ok(d, &["validate", "pm5.toml", "bad.csv"]).contains("(39 poses)"));
}

/// Before fitting: positions in metres or inches in `_mm` columns and radians in `_deg` columns
/// are one line naming the mistake (exit 1); a stated noise 1000× the real one is a warning with
/// σ̂₀ and the residual beside a calibration that goes on.
#[test]
fn wrong_units_and_an_overstated_noise_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ok(
        d,
        &[
            "simulate",
            "irb120",
            "--poses",
            "40",
            "--out",
            "i.csv",
            "--truth",
            "t.toml",
            "--noise-mm",
            "0.005",
            "--noise-deg",
            "0.005",
        ],
    );
    let text = fs::read_to_string(d.join("i.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    let write = |name: &str, f: &dyn Fn(&str, f64) -> f64| {
        let mut out = header.join(",") + "\n";
        for r in &rows {
            out += &(r
                .iter()
                .zip(&header)
                .map(|(v, c)| f(c, *v).to_string())
                .collect::<Vec<_>>()
                .join(",")
                + "\n");
        }
        fs::write(d.join(name), out).unwrap();
    };
    let xyz = |c: &str| ["x_mm", "y_mm", "z_mm"].contains(&c);
    write("m.csv", &|c, v| if xyz(c) { v / 1000.0 } else { v });
    write("in.csv", &|c, v| if xyz(c) { v / 25.4 } else { v });
    write("rad.csv", &|c, v| if c.ends_with("_deg") { v.to_radians() } else { v });
    for (file, expect) in [
        ("m.csv", "about 1/1000 of the model's reach"),
        ("in.csv", "about 1/25.4 of the model's reach"),
        ("rad.csv", "they look like radians"),
    ] {
        let e = fails(d, &["identify", "irb120", file, "--out", "c.toml"]);
        assert!(e.starts_with(file) && e.contains(expect), "{file}: {e}");
    }
    // One column in radians is no refusal before the fit (a joint can stay near its zero), but
    // the fit that fails for it names the column (exit 2, one line, nothing written).
    write("q3rad.csv", &|c, v| if c == "q3_deg" { v.to_radians() } else { v });
    let out = kinecal(d, &["identify", "irb120", "q3rad.csv", "--out", "c3.toml"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    let last: Vec<&str> = err.lines().filter(|l| l.starts_with("kinecal: ")).collect();
    assert!(
        last.len() == 1 && last[0].contains("are the joint columns in the right unit? q3 (never beyond ±") && last[0].contains("radians?"),
        "{err}"
    );
    assert!(!d.join("c3.toml").exists());
    assert!(fails(d, &["identify", "irb120", "m.csv", "--out", "c.toml"]).contains("metres in the _mm columns"));
    assert!(fails(d, &["identify", "irb120", "in.csv", "--out", "c.toml"]).contains("inches in the _mm columns"));
    // 5 mm stated for 5 µm: calibrated, with a warning naming σ̂₀ and the residual.
    let out = kinecal(
        d,
        &[
            "identify",
            "irb120",
            "i.csv",
            "--out",
            "c.toml",
            "--noise-mm",
            "5",
            "--noise-deg",
            "5",
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    let w: Vec<&str> = err.lines().filter(|l| l.starts_with("warning: σ̂₀")).collect();
    assert!(
        w.len() == 1 && w[0].contains("the stated noise is far too large") && w[0].contains("(5 mm)"),
        "{err}"
    );
    // Stated as it is: no such warning.
    let out = kinecal(
        d,
        &[
            "identify",
            "irb120",
            "i.csv",
            "--out",
            "c2.toml",
            "--noise-mm",
            "0.005",
            "--noise-deg",
            "0.005",
        ],
    );
    assert!(!String::from_utf8_lossy(&out.stderr).contains("far too large"));
}

/// A known seat distance in metres (0.05 for the Panda's sockets 50 mm apart) is one line naming
/// the unit and the distance in mm, before fitting.
#[test]
fn a_seat_distance_in_metres_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    panda(d);
    let s = sockets();
    ok(
        d,
        &[
            "data",
            "join",
            "panda.toml",
            "--angles",
            "rad",
            "--seat",
            &s[0],
            "--seat",
            &s[1],
            "--out",
            "seats.csv",
        ],
    );
    let e = fails(
        d,
        &[
            "identify",
            "panda.toml",
            "seats.csv",
            "--seat-distance",
            "0:1:0.05",
            "--out",
            "c.toml",
        ],
    );
    assert!(
        e.contains("--seat-distance 0:1:0.05") && e.contains("metres for mm") && e.contains("0:1:50.0000"),
        "{e}"
    );
}
