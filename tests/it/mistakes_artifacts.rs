//! Mistakes in what a user states of the instrument and its artifacts, each one line naming the
//! likely cause, exit 1 (the tutorials' "What can go wrong", docs/tutorial-instruments.md): each
//! artifact size read another way (`kinecal::calibrate::sizes`: a sphere diameter in inches or
//! given as its radius, a probe's diameter given as its radius or its radius halved, a cube edge
//! in inches, a ballbar length in inches, centimetres or metres), radians in `_deg` columns of a
//! 6-axis arm (touches and tracker), seats paired across placements, a known seat distance off
//! the nominal one (a warning, then the fit's verdict); `data check` and `validate` name wrong
//! units as `identify` does.
use crate::cli::{fails, import_panda, kinecal, ok, panda_sockets};
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

/// Tutorial 3's touch probe on a UR5e, in `d`: the model imported to `ur5e.toml`, then `per_point`
/// touches on each of `artifact`'s spheres or cube faces (its `simulate` options) to `out`, the
/// 1.5 mm probe at (10, −5, 120) mm, noise 5 µm, seed 3; the touches as stated calibrate.
fn touches(d: &Path, artifact: &[&str], per_point: &str, out: &str) {
    ur5e(d);
    let mut args = vec!["simulate", "ur5e.toml"];
    args.extend_from_slice(artifact);
    args.extend([
        "--probe-radius-mm",
        "1.5",
        "--per-point",
        per_point,
        "--tool-mm",
        "10,-5,120",
        "--noise-mm",
        "0.005",
        "--seed",
        "3",
        "--out",
        out,
        "--truth",
        "truth.toml",
    ]);
    ok(d, &args);
    let said = ok(d, &identify(out));
    assert!(said.contains("verdict: calibrated"), "{said}");
    fs::remove_file(d.join("c.toml")).unwrap();
}

/// `identify` of the touches in `file` on `ur5e.toml`, the probe's noise stated, to `c.toml`.
fn identify(file: &str) -> Vec<&str> {
    vec!["identify", "ur5e.toml", file, "--kind-noise", "probe=0.005", "--out", "c.toml"]
}

/// Tutorial 3's sphere touches (a UR5e, three 25.4 mm spheres, a 1.5 mm probe): calibrated as
/// stated; a diameter in inches, a sphere's radius in the diameter column, the probe's diameter
/// in the radius column, the probe's radius halved and radians in the `_deg` columns are each one
/// line naming that mistake, exit 1, nothing written.
#[test]
fn sphere_sizes_in_the_wrong_unit_and_radians_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    touches(
        d,
        &["--spheres", "450,-150,100;450,150,100;300,0,300", "--sphere-diameter-mm", "25.4"],
        "20",
        "spheres.csv",
    );
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
    rewrite(d, "spheres.csv", "radius.csv", &|c, v| {
        if c == "sphere_diameter_mm" {
            v / 2.0
        } else {
            v
        }
    });
    rewrite(d, "spheres.csv", "halved.csv", &|c, v| {
        if c == "probe_radius_mm" {
            v / 2.0
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
        (
            "radius.csv",
            "the sphere's radius given as its diameter? (sphere_diameter_mm 12.7 read as 25.4000 mm)",
        ),
        (
            "halved.csv",
            "probe radius halved, as if it were a diameter? (probe_radius_mm 0.75 read as 1.5000 mm)",
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
    for file in ["inch.csv", "radius.csv", "probe.csv", "halved.csv"] {
        let e = fails(d, &identify(file));
        assert!(
            e.contains("as stated the calibration fails") && e.contains("read so, it calibrates"),
            "{file}: {e}"
        );
    }
}

/// Tutorial 3's datum cube (100 mm edge, turned 20°, 10 touches a face): calibrated as stated;
/// its edge in inches is one line naming the edge's unit, with what the calibration does as
/// stated and read in mm, exit 1, nothing written.
#[test]
fn a_cube_edge_in_inches_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    touches(
        d,
        &["--cube", "400,0,150", "--cube-edge-mm", "100", "--cube-rotation-deg", "0,0,20"],
        "10",
        "cube.csv",
    );
    // The edge as a user writes it from the cube's inch drawing: 3.937 for 100 mm.
    let text = fs::read_to_string(d.join("cube.csv")).unwrap();
    fs::write(d.join("inch.csv"), text.replace(",100,1.5\n", ",3.937,1.5\n")).unwrap();
    assert_ne!(text, fs::read_to_string(d.join("inch.csv")).unwrap());
    let e = fails(d, &identify("inch.csv"));
    assert!(
        e.starts_with("inch.csv: cube edge in inches? (cube_edge_mm 3.937 read as 99.9998 mm; give it in mm)")
            && e.contains("as stated the calibration fails")
            && e.contains("read so, it calibrates")
            && !e.contains("a model of another machine"),
        "{e}"
    );
    assert!(!d.join("c.toml").exists());
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

/// Tutorial 2's ballbar (pm5, three pivots, a 100 mm bar) with the lengths in inches,
/// centimetres or metres: one line naming the bar length's unit, exit 1, nothing written.
#[test]
fn a_bar_length_in_inches_centimetres_or_metres_is_named() {
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
    for (file, factor, cause) in [
        ("inch.csv", 25.4, "bar length in inches? (length_mm "),
        ("cm.csv", 10.0, "bar length in centimetres? (length_mm "),
        ("m.csv", 1000.0, "bar length in metres? (length_mm "),
    ] {
        rewrite(d, "bar.csv", file, &|c, v| if c == "length_mm" { v / factor } else { v });
        let e = fails(d, &["identify", "pm5.toml", file, "--noise-mm", "0.001", "--out", "c.toml"]);
        assert!(
            e.starts_with(&format!("{file}: {cause}"))
                && e.contains("as stated the calibration fails")
                && e.contains("read so, it calibrates"),
            "{e}"
        );
        assert!(!d.join("c.toml").exists());
    }
}

/// In `d`: the Panda's model imported to `panda.toml`; returns the `data join` of its six real
/// sockets (three placements of two) to `seats.csv`, angles in radians, not yet run.
fn panda_seats(d: &Path) -> Vec<String> {
    import_panda(d);
    let mut args: Vec<String> = ["data", "join", "panda.toml", "--angles", "rad", "--out", "seats.csv"]
        .map(String::from)
        .to_vec();
    for s in panda_sockets(&["back_left", "front_right", "high"]) {
        args.extend(["--seat".into(), s]);
    }
    args
}

/// Tutorial 1's seats (the real Panda sockets, three placements): a known distance between seats
/// of two placements (0:2 for 0:1) is one line naming the likely cause and a pair the nominal
/// model puts at that distance, exit 1, before fitting.
#[test]
fn seats_paired_across_placements_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let args = panda_seats(d);
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

/// The Panda's sockets with a known distance between seats 0 and 1 stated against the distance
/// between their centres placed by the nominal model (about 50 mm): 1.67× off (30 mm) is a
/// warning naming the pair, and the fit goes on to its verdict, which fails here (exit 2,
/// nothing written); within 0.8–1.25× (45 mm) there is no such line and the calibration is
/// written; beyond half or twice (110 mm, 0.46×) it is one line and exit 1 before fitting.
#[test]
fn a_seat_distance_off_by_half_again_is_a_warning_naming_the_pair() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let join = panda_seats(d);
    ok(d, &join.iter().map(String::as_str).collect::<Vec<_>>());
    let identify = |first: &'static str| -> Vec<&'static str> {
        vec![
            "identify",
            "panda.toml",
            "seats.csv",
            "--seat-distance",
            first,
            "--seat-distance",
            "2:3:50",
            "--seat-distance",
            "4:5:50",
            "--out",
            "c.toml",
        ]
    };
    let out = kinecal(d, &identify("0:1:30"));
    let err = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        lines.len() == 2
            && lines[0].starts_with("warning: --seat-distance 0:1:30: the nominal model puts seats 0 and 1 ")
            && lines[0].contains("1.67× the stated 30 mm")
            && lines[0].contains("seats paired across placements, or wrong seat numbers?")
            && lines[1].starts_with("kinecal: failed: verdict: failed"),
        "{err}"
    );
    assert!(!d.join("c.toml").exists());
    // Within 0.8–1.25× of the nominal distance: no warning, calibrated and written.
    let out = kinecal(d, &identify("0:1:45"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(!err.contains("--seat-distance"), "{err}");
    assert!(d.join("c.toml").exists());
    fs::remove_file(d.join("c.toml")).unwrap();
    // Less than half the stated distance: one line, exit 1, before fitting.
    let e = fails(d, &identify("0:1:110"));
    assert!(
        e.starts_with("seats.csv: --seat-distance 0:1:110: the nominal model puts seats 0 and 1 ")
            && e.contains("0.46× the stated 110 mm")
            && e.contains("seats paired across placements, or wrong seat numbers?"),
        "{e}"
    );
    assert!(!d.join("c.toml").exists());
}

/// Five placements of a two-seat artifact (50 mm) on a simulated Panda, the first pair's distance
/// stated as 30 mm: a warning naming seats 0 and 1 (1.67× the stated), and the fit goes on. The
/// other four placements carry the calibration, the first pair's 40 rows are set aside as
/// blunders, and the calibration is written, exit 0, the verdict naming the rows set aside.
#[test]
fn a_seat_distance_off_warns_and_the_rest_calibrates() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    import_panda(d);
    ok(
        d,
        &[
            "simulate",
            "panda.toml",
            "--seats",
            "500,-200,300;500,-150,300;550,0,250;550,50,250;450,200,350;450,250,350;400,-100,450;400,-50,450;600,100,150;600,150,150",
            "--per-point",
            "20",
            "--tool-mm",
            "0,0,50",
            "--noise-mm",
            "0.02",
            "--seed",
            "4",
            "--out",
            "s.csv",
            "--truth",
            "t.toml",
        ],
    );
    let mut args = vec!["identify", "panda.toml", "s.csv", "--noise-mm", "0.02", "--out", "c.toml"];
    for pair in ["0:1:30", "2:3:50", "4:5:50", "6:7:50", "8:9:50"] {
        args.extend(["--seat-distance", pair]);
    }
    let out = kinecal(d, &args);
    let (said, err) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(
        err.lines().count() == 1
            && err.starts_with("warning: --seat-distance 0:1:30: the nominal model puts seats 0 and 1 ")
            && err.contains("1.67× the stated 30 mm")
            && err.contains("seats paired across placements, or wrong seat numbers?"),
        "{err}"
    );
    assert!(
        said.contains("40 poses set aside as blunders") && said.contains("ids 0 1 2 ") && said.contains("verdict: usable with warnings"),
        "{said}"
    );
    assert!(d.join("c.toml").exists());
}
