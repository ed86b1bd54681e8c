//! Mistakes in what a user states of the instrument and its artifacts, each one line naming the
//! likely cause, exit 1 (the tutorials' "What can go wrong", docs/tutorial-instruments.md): a
//! sphere diameter in inches, a probe's diameter given as its radius, radians in `_deg` columns
//! of a 6-axis arm (touches and tracker), a ballbar length in inches, seats paired across
//! placements; `data check` and `validate` name wrong units as `identify` does.
use crate::cli::{fails, kinecal, ok};
use std::fs;
use std::path::Path;

/// Rewrite the CSV `from` into `to`, each cell through `f(column, value)`.
fn rewrite(d: &Path, from: &str, to: &str, f: &dyn Fn(&str, f64) -> f64) {
    let text = fs::read_to_string(d.join(from)).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let mut out = header.join(",") + "\n";
    for l in lines {
        let row: Vec<String> = l
            .split(',')
            .zip(&header)
            .map(|(v, c)| f(c, v.parse().unwrap()).to_string())
            .collect();
        out += &(row.join(",") + "\n");
    }
    fs::write(d.join(to), out).unwrap();
}

fn ur5e(d: &Path) {
    let urdf = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/models/ur5e.urdf");
    ok(
        d,
        &[
            "model",
            "import",
            urdf.to_str().unwrap(),
            "--base",
            "base_link_inertia",
            "--tip",
            "tool0",
            "-o",
            "ur5e.toml",
        ],
    );
}

/// Tutorial 3's sphere touches (a UR5e, three 25.4 mm spheres, a 1.5 mm probe): calibrated as
/// stated; a diameter in inches, the probe's diameter in the radius column and radians in the
/// `_deg` columns are each one line naming that mistake, exit 1, nothing written.
#[test]
fn sphere_sizes_in_the_wrong_unit_and_radians_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ur5e(d);
    ok(
        d,
        &[
            "simulate",
            "ur5e.toml",
            "--spheres",
            "450,-150,100;450,150,100;300,0,300",
            "--sphere-diameter-mm",
            "25.4",
            "--probe-radius-mm",
            "1.5",
            "--per-point",
            "20",
            "--tool-mm",
            "10,-5,120",
            "--noise-mm",
            "0.005",
            "--seed",
            "3",
            "--out",
            "spheres.csv",
            "--truth",
            "truth.toml",
        ],
    );
    let identify =
        |file: &'static str| -> Vec<&'static str> { vec!["identify", "ur5e.toml", file, "--kind-noise", "probe=0.005", "--out", "c.toml"] };
    let said = ok(d, &identify("spheres.csv"));
    assert!(said.contains("verdict: calibrated"), "{said}");
    fs::remove_file(d.join("c.toml")).unwrap();
    rewrite(d, "spheres.csv", "inch.csv", &|c, v| {
        if c == "sphere_diameter_mm" {
            v / 25.4
        } else {
            v
        }
    });
    rewrite(d, "spheres.csv", "probe.csv", &|c, v| {
        if c == "probe_radius_mm" {
            2.0 * v
        } else {
            v
        }
    });
    rewrite(d, "spheres.csv", "rad.csv", &|c, v| {
        if c.ends_with("_deg") {
            v.to_radians()
        } else {
            v
        }
    });
    for (file, cause) in [
        (
            "inch.csv",
            "sphere diameter in inches? (sphere_diameter_mm 1 read as 25.4000 mm; give it in mm)",
        ),
        (
            "probe.csv",
            "probe radius given as its diameter? (probe_radius_mm 3 read as 1.5000 mm)",
        ),
        ("rad.csv", "they look like radians; name them shoulder_pan_joint_rad"),
    ] {
        let e = fails(d, &identify(file));
        assert!(e.starts_with(file) && e.contains(cause), "{file}: {e}");
        assert!(!e.contains("a model of another machine"), "{file}: {e}");
        assert!(!d.join("c.toml").exists());
    }
    // The size readings say what the data do with them: the calibration as stated fails, read
    // the other way it calibrates.
    let e = fails(d, &identify("inch.csv"));
    assert!(
        e.contains("as stated the calibration fails") && e.contains("read so, it calibrates"),
        "{e}"
    );
}

/// Radians in the `_deg` columns of a 6-axis arm measured by a tracker. With the URDF's limits
/// (±360°, the elbow ±180°) the columns never leave what radians can be: "they look like
/// radians". On a model without limits the values pass ±π on most joints, and the joint values
/// fit the nominal model far better read as radians (the distances between the measured
/// positions are the model's): one line with both figures. Each exit 1, from `identify`, `data
/// check` and `validate` alike, never a calibration with σ̂₀ 0.000; a `_rad` column gets a note
/// naming it.
#[test]
fn radians_in_degree_columns_fit_far_better_as_radians() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ur5e(d);
    let text = fs::read_to_string(d.join("ur5e.toml")).unwrap();
    let free: Vec<&str> = text.lines().filter(|l| !l.starts_with("limits")).collect();
    fs::write(d.join("free.toml"), free.join("\n") + "\n").unwrap();
    ok(
        d,
        &[
            "simulate",
            "ur5e.toml",
            "--poses",
            "40",
            "--out",
            "t.csv",
            "--truth",
            "truth.toml",
            "--noise-mm",
            "0.01",
            "--noise-deg",
            "0.01",
            "--seed",
            "2",
        ],
    );
    rewrite(d, "t.csv", "rad.csv", &|c, v| {
        if c.ends_with("_joint_deg") {
            v.to_radians()
        } else {
            v
        }
    });
    for model in ["ur5e.toml", "free.toml"] {
        for args in [
            &["identify", model, "rad.csv", "--out", "c.toml"][..],
            &["data", "check", model, "rad.csv"][..],
            &["validate", model, "rad.csv"][..],
        ] {
            let e = fails(d, args);
            let named = match model {
                "ur5e.toml" => e.contains("never leave ±6.2832 degrees") && e.contains("they look like radians"),
                _ => {
                    e.contains("fit the nominal model far better in another unit")
                        && e.contains("the angle columns hold radians where they say degrees (name them _rad)")
                }
            };
            assert!(e.starts_with("rad.csv") && named, "{args:?}: {e}");
            assert!(!d.join("c.toml").exists());
        }
    }
    // Positions in metres: data check and validate name them as identify does.
    rewrite(d, "t.csv", "m.csv", &|c, v| {
        if ["x_mm", "y_mm", "z_mm"].contains(&c) {
            v / 1000.0
        } else {
            v
        }
    });
    for args in [
        &["data", "check", "ur5e.toml", "m.csv"][..],
        &["validate", "ur5e.toml", "m.csv"][..],
    ] {
        let e = fails(d, args);
        assert!(
            e.contains("about 1/1000 of the model's reach") && e.contains("metres in the _mm columns"),
            "{args:?}: {e}"
        );
    }
    // Named as radians, they are read as radians, with a note saying so.
    let text = fs::read_to_string(d.join("rad.csv")).unwrap();
    let (head, rest) = text.split_once('\n').unwrap();
    fs::write(d.join("named.csv"), head.replace("_joint_deg", "_joint_rad") + "\n" + rest).unwrap();
    for args in [
        &["data", "check", "ur5e.toml", "named.csv"][..],
        &["validate", "ur5e.toml", "named.csv"][..],
    ] {
        let out = kinecal(d, args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {err}");
        assert!(
            err.contains("note: named.csv: shoulder_pan_joint_rad") && err.contains("read as radians"),
            "{err}"
        );
    }
}

/// Tutorial 2's ballbar (pm5, three pivots, a 100 mm bar) with the lengths in inches: one line
/// naming the bar length's unit, exit 1.
#[test]
fn a_bar_length_in_inches_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ok(d, &["model", "export", "pm5", "-o", "pm5.toml"]);
    ok(
        d,
        &[
            "simulate",
            "pm5.toml",
            "--pivots",
            "0,-30,370;40,-30,380;-30,20,375",
            "--ballbar-mm",
            "100",
            "--tool-mm",
            "10,-5,60",
            "--tilt-deg",
            "15",
            "--noise-mm",
            "0.001",
            "--seed",
            "1",
            "--per-point",
            "30",
            "--out",
            "bar.csv",
            "--truth",
            "t.toml",
        ],
    );
    rewrite(d, "bar.csv", "inch.csv", &|c, v| if c == "length_mm" { v / 25.4 } else { v });
    let e = fails(d, &["identify", "pm5.toml", "inch.csv", "--noise-mm", "0.001", "--out", "c.toml"]);
    assert!(
        e.starts_with("inch.csv") && e.contains("bar length in inches?") && e.contains("read so, it calibrates"),
        "{e}"
    );
}

/// Tutorial 1's seats (the real Panda sockets, three placements): a known distance between seats
/// of two placements (0:2 for 0:1) is one line naming the likely cause and a pair the nominal
/// model puts at that distance, exit 1, before fitting.
#[test]
fn seats_paired_across_placements_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mukca-panda");
    ok(
        d,
        &[
            "model",
            "import",
            data.join("panda.urdf").to_str().unwrap(),
            "--tip",
            "ball_link",
            "-o",
            "panda.toml",
        ],
    );
    let mut args: Vec<String> = ["data", "join", "panda.toml", "--angles", "rad", "--out", "seats.csv"]
        .map(String::from)
        .to_vec();
    for p in ["back_left", "front_right", "high"] {
        for s in [0, 1] {
            args.push("--seat".into());
            args.push(data.join(p).join(format!("socket_{s}.csv")).display().to_string());
        }
    }
    // The sockets' radians joined as degrees: the values a wrong unit explains are refused.
    let as_deg: Vec<&str> = args.iter().map(|a| if a == "rad" { "deg" } else { a.as_str() }).collect();
    let e = fails(d, &as_deg);
    assert!(
        e.contains("socket_0.csv:1: panda_joint4")
            && e.contains("every value of the column fits them read in rad: check the column's unit"),
        "{e}"
    );
    ok(d, &args.iter().map(String::as_str).collect::<Vec<_>>());
    let e = fails(
        d,
        &[
            "identify",
            "panda.toml",
            "seats.csv",
            "--seat-distance",
            "0:2:50",
            "--seat-distance",
            "4:5:50",
            "--out",
            "c.toml",
        ],
    );
    assert!(
        e.starts_with("seats.csv")
            && e.contains("--seat-distance 0:2:50: the nominal model puts seats 0 and 2")
            && e.contains("seats paired across placements, or wrong seat numbers?")
            && e.contains("apart: --seat-distance"),
        "{e}"
    );
    // Paired within each placement: no such line.
    let out = kinecal(
        d,
        &[
            "identify",
            "panda.toml",
            "seats.csv",
            "--seat-distance",
            "0:1:50",
            "--seat-distance",
            "2:3:50",
            "--seat-distance",
            "4:5:50",
            "--out",
            "c.toml",
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(!err.contains("paired across"), "{err}");
}
