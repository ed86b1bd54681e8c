//! `kinecal filter` on G-code for a linear delta (the kinematics of a delta 3-D printer)
//! calibrated from simulated tracker data: absolute and incremental (`G91`) blocks, modal axes,
//! comments; read back by an independent modal interpreter; arcs refused with a line.
use crate::cli::{fails, ok};
use kinecal::io::model_file::ModelFile;
use kinecal::se3::Pose;
use kinecal::Mechanism;
use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use std::path::Path;

const TRACKER: &str = "
[frames]
[frames.measurement]
position = [1500.0, -600.0, 200.0]
rpy = [2.0, -5.0, 100.0]
[frames.tool]
position = [10.0, -15.0, 40.0]
rpy = [0.0, 0.0, 0.0]
";

/// Absolute positions (mm) of each block that moves, read here: `G90`/`G91`, `G20`/`G21`,
/// comments `;` and `( … )`.
fn positions(text: &str) -> Vec<Vector3<f64>> {
    let (mut p, mut inc, mut inch) = (Vector3::zeros(), false, false);
    let mut out = Vec::new();
    for line in text.lines() {
        let mut code = line.split(';').next().unwrap().to_string();
        while let (Some(a), Some(b)) = (code.find('('), code.find(')')) {
            code.replace_range(a..=b, " ");
        }
        let mut moved = false;
        for w in code.split_whitespace() {
            let (l, v) = w.split_at(1);
            let v: f64 = v.parse().unwrap();
            match (l, v as i32) {
                ("G", 90) => inc = false,
                ("G", 91) => inc = true,
                ("G", 20) => inch = true,
                ("G", 21) => inch = false,
                ("X" | "Y" | "Z", _) => {
                    let k = "XYZ".find(l).unwrap();
                    let v = if inch { v * 25.4 } else { v };
                    p[k] = if inc { p[k] + v } else { v };
                    moved = true;
                }
                _ => {}
            }
        }
        if moved {
            out.push(p);
        }
    }
    out
}

/// A G-code line with every number (a word's value) replaced by `#`.
fn skeleton(line: &str) -> String {
    let mut out = String::new();
    let mut in_number = false;
    for c in line.chars() {
        let digit = c.is_ascii_digit() || c == '.' || ((c == '-' || c == '+') && !in_number);
        if digit {
            if !in_number {
                out.push('#');
            }
            in_number = true;
        } else {
            in_number = false;
            out.push(c);
        }
    }
    out
}

/// A line with the axis words it does not hold in `original` removed (the words the filter
/// adds where the correction moves an axis a block does not name).
fn without_added(line: &str, original: &str) -> String {
    let has = |c: char| original.split(';').next().unwrap().split_whitespace().any(|w| w.starts_with(c));
    line.split(' ')
        .filter(|w| !(w.len() > 1 && "XYZ".contains(&w[..1]) && !has(w.chars().next().unwrap()) && w[1..].parse::<f64>().is_ok()))
        .collect::<Vec<_>>()
        .join(" ")
}

/// A program of 40 moves: absolute, then a G91 section, back to G90, some blocks naming one or
/// two axes only.
fn program(seed: u64) -> (String, usize) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut s = String::from("; delta test part\nG21 G90 (mm, absolute)\nM104 S200\nG0 X0 Y0 Z120.000 F6000\n");
    let mut n = 1;
    let mut p = [0.0, 0.0, 120.0];
    for k in 0..39 {
        if k == 15 {
            s += "G91 ; incremental section\n";
        }
        if k == 27 {
            s += "G90\n";
        }
        let next = [
            rng.random_range(-35.0..35.0),
            rng.random_range(-35.0..35.0),
            rng.random_range(70.0..125.0),
        ];
        let inc = (15..27).contains(&k);
        let v = |a: usize| if inc { next[a] - p[a] } else { next[a] };
        match k % 5 {
            0 => s += &format!("G1 X{:.3} F1500 ; one axis\n", v(0)),
            1 => s += &format!("G1 X{:.3} Y{:.3}\n", v(0), v(1)),
            _ => s += &format!("N{} G1 X{:.3} Y{:.3} Z{:.3} E{:.4}\n", 100 + k, v(0), v(1), v(2), 0.1 * k as f64),
        }
        // The nominal position after the block.
        let named = match k % 5 {
            0 => 1,
            1 => 2,
            _ => 3,
        };
        p[..named].copy_from_slice(&next[..named]);
        n += 1;
    }
    s += "M84 (motors off)\n";
    (s, n)
}

#[test]
fn linear_delta_gcode_filtered_reaches_the_targets_as_compensate_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/models/linear-delta.toml");
    let text = std::fs::read_to_string(&model).unwrap();
    std::fs::write(d.join("delta.toml"), &text).unwrap();
    std::fs::write(d.join("m.toml"), text + TRACKER).unwrap();
    ok(
        d,
        &[
            "simulate",
            "m.toml",
            "--poses",
            "40",
            "--seed",
            "4",
            "--error-mm",
            "0.3",
            "--error-deg",
            "0.05",
            "--noise-mm",
            "0.005",
            "--noise-deg",
            "0.003",
            "--out",
            "ident.csv",
            "--truth",
            "truth.toml",
        ],
    );
    ok(d, &["identify", "m.toml", "ident.csv", "--out", "cal.toml"]);
    let (prog, n) = program(9);
    std::fs::write(d.join("part.gcode"), &prog).unwrap();
    let out = ok(
        d,
        &[
            "filter",
            "cal.toml",
            "part.gcode",
            "--nominal",
            "delta.toml",
            "--out",
            "part_cal.gcode",
        ],
    );
    eprintln!("{}", out.lines().take(2).collect::<Vec<_>>().join("\n"));
    let filtered = std::fs::read_to_string(d.join("part_cal.gcode")).unwrap();
    // Byte for byte outside the numbers, but for the axis words added.
    assert_eq!(prog.lines().count(), filtered.lines().count());
    for (a, b) in prog.lines().zip(filtered.lines()) {
        assert_eq!(skeleton(a), skeleton(&without_added(b, a)), "{a} → {b}");
    }
    let (orig, corr) = (positions(&prog), positions(&filtered));
    assert_eq!(orig.len(), n);
    assert_eq!(corr.len(), n);
    // The nominal controller (the nominal delta's inverse) at the filtered positions, and
    // compensate at the originals; the prototype read through the calibration's frames.
    let nominal = ModelFile::load(&d.join("delta.toml")).unwrap().build();
    let truth = ModelFile::load(&d.join("truth.toml")).unwrap().build();
    let cal = ModelFile::load(&d.join("cal.toml")).unwrap();
    let f = cal.frames.unwrap();
    let reached = |q: &[f64]| {
        (f.measurement.inverse() * truth.forward(q).unwrap() * f.tool.inverse())
            .translation
            .vector
    };
    let mut csv = String::from("id,x_mm,y_mm,z_mm,qw,qx,qy,qz\n");
    for (k, p) in orig.iter().enumerate() {
        csv += &format!("{k},{:.9},{:.9},{:.9},1,0,0,0\n", p.x, p.y, p.z);
    }
    std::fs::write(d.join("targets.csv"), csv).unwrap();
    ok(
        d,
        &[
            "compensate",
            "cal.toml",
            "targets.csv",
            "--nominal",
            "delta.toml",
            "--base-frame",
            "--out",
            "cmd.csv",
        ],
    );
    let commands = kinecal::io::table::read_table(&d.join("cmd.csv")).unwrap();
    let (mut comp, mut filt, mut before) = (0.0f64, 0.0f64, 0.0f64);
    for (k, (p, p2)) in orig.iter().zip(&corr).enumerate() {
        let q = nominal.inverse(&Pose::translation(p2.x, p2.y, p2.z), None).unwrap();
        let q0 = nominal.inverse(&Pose::translation(p.x, p.y, p.z), None).unwrap();
        filt = filt.max((reached(&q) - p).norm());
        before = before.max((reached(&q0) - p).norm());
        comp = comp.max((reached(&commands.rows[k][1..]) - p).norm());
    }
    eprintln!("linear delta G-code, {n} moves: max error unfiltered {before:.4} mm, compensate {comp:.5} mm, filtered {filt:.5} mm");
    assert!(filt <= 1.1 * comp, "filtered {filt} against compensate's {comp}");
    assert!(before > 5.0 * filt);
    // An arc: one line naming it, nothing written.
    let arc = prog.replacen("G1 X", "G2 I5 J0 X", 1);
    std::fs::write(d.join("arc.gcode"), &arc).unwrap();
    let e = fails(
        d,
        &[
            "filter",
            "cal.toml",
            "arc.gcode",
            "--nominal",
            "delta.toml",
            "--out",
            "arc_cal.gcode",
        ],
    );
    let line = arc.lines().position(|l| l.contains("G2 I")).unwrap() + 1;
    assert!(e.starts_with(&format!("arc.gcode:{line}: an arc (G2)")), "{e}");
    assert!(!d.join("arc_cal.gcode").exists());
}

/// Absolute X Y Z A B of each block that moves (G90 only), read here.
fn poses_5axis(text: &str) -> Vec<[f64; 5]> {
    let mut p = [0.0; 5];
    let mut out = Vec::new();
    for line in text.lines() {
        let code = line.split(';').next().unwrap();
        let mut moved = false;
        for w in code.split_whitespace() {
            let (l, v) = w.split_at(1);
            if let Some(k) = "XYZAB".find(l) {
                p[k] = v.parse().unwrap();
                moved = true;
            }
        }
        if moved {
            out.push(p);
        }
    }
    out
}

/// pm5 (the 5-DOF parallel head) with 5-axis G-code: tool tip X Y Z and tool axis A B
/// (`Rot(x, A)·Rot(y, B)`, degrees): the prototype driven by the nominal controller to the
/// filtered blocks reaches the original tips and axes within 1.1× `compensate`'s error.
#[test]
fn pm5_five_axis_gcode_filtered_reaches_the_targets_as_compensate_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = kinecal::io::builtin::model_file("pm5").unwrap().to_toml().unwrap();
    std::fs::write(d.join("pm5.toml"), &text).unwrap();
    std::fs::write(d.join("m.toml"), text + TRACKER).unwrap();
    ok(
        d,
        &[
            "simulate",
            "m.toml",
            "--poses",
            "40",
            "--seed",
            "6",
            "--error-mm",
            "0.2",
            "--error-deg",
            "0.02",
            "--noise-mm",
            "0.005",
            "--noise-deg",
            "0.003",
            "--out",
            "ident.csv",
            "--truth",
            "truth.toml",
        ],
    );
    ok(d, &["identify", "m.toml", "ident.csv", "--out", "cal.toml"]);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut prog = String::from("G21 G90 ; pm5, tool tip and axis\n");
    for k in 0..30 {
        let v = [
            rng.random_range(-25.0..25.0),
            rng.random_range(-25.0..25.0),
            rng.random_range(380.0..420.0),
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
        ];
        prog += &format!("N{k} G1 X{:.3} Y{:.3} Z{:.3} A{:.4} B{:.4} F800\n", v[0], v[1], v[2], v[3], v[4]);
    }
    std::fs::write(d.join("head.nc"), &prog).unwrap();
    let out = ok(
        d,
        &["filter", "cal.toml", "head.nc", "--nominal", "pm5.toml", "--out", "head_cal.nc"],
    );
    eprintln!("{}", out.lines().take(2).collect::<Vec<_>>().join("\n"));
    let filtered = std::fs::read_to_string(d.join("head_cal.nc")).unwrap();
    for (a, b) in prog.lines().zip(filtered.lines()) {
        assert_eq!(skeleton(a), skeleton(b), "{a} → {b}");
    }
    let pose = |v: &[f64; 5]| {
        let r = nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), v[3].to_radians())
            * nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), v[4].to_radians());
        Pose::from_parts(
            nalgebra::Translation3::new(v[0], v[1], v[2]),
            nalgebra::UnitQuaternion::from_rotation_matrix(&r),
        )
    };
    let (orig, corr) = (poses_5axis(&prog), poses_5axis(&filtered));
    assert_eq!(orig.len(), 30);
    let nominal = ModelFile::load(&d.join("pm5.toml")).unwrap().build();
    let truth = ModelFile::load(&d.join("truth.toml")).unwrap().build();
    let cal = ModelFile::load(&d.join("cal.toml")).unwrap();
    let f = cal.frames.unwrap();
    let reached = |q: &[f64]| f.measurement.inverse() * truth.forward(q).unwrap() * f.tool.inverse();
    let mut csv = String::from("id,x_mm,y_mm,z_mm,qw,qx,qy,qz\n");
    for (k, v) in orig.iter().enumerate() {
        let q = pose(v).rotation.into_inner();
        csv += &format!(
            "{k},{:.9},{:.9},{:.9},{:.12},{:.12},{:.12},{:.12}\n",
            v[0], v[1], v[2], q.w, q.i, q.j, q.k
        );
    }
    std::fs::write(d.join("targets.csv"), csv).unwrap();
    ok(
        d,
        &[
            "compensate",
            "cal.toml",
            "targets.csv",
            "--nominal",
            "pm5.toml",
            "--base-frame",
            "--out",
            "cmd.csv",
        ],
    );
    let commands = kinecal::io::table::read_table(&d.join("cmd.csv")).unwrap();
    let task = nominal.task();
    let (mut comp, mut filt, mut before) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64), (0.0f64, 0.0f64));
    let max = |a: (f64, f64), b: (f64, f64)| (a.0.max(b.0), a.1.max(b.1));
    for (k, (v, v2)) in orig.iter().zip(&corr).enumerate() {
        let t = pose(v);
        let q = nominal.inverse(&pose(v2), None).unwrap();
        let q0 = nominal.inverse(&t, None).unwrap();
        filt = max(filt, kinecal::validate::commanded_error(task, &t, &reached(&q)));
        before = max(before, kinecal::validate::commanded_error(task, &t, &reached(&q0)));
        comp = max(comp, kinecal::validate::commanded_error(task, &t, &reached(&commands.rows[k][1..])));
    }
    eprintln!(
        "pm5 5-axis G-code, 30 moves: max error (mm, rad of the tool axis) unfiltered {before:?}, compensate {comp:?}, filtered {filt:?}"
    );
    assert!(
        filt.0 <= 1.1 * comp.0 && filt.1 <= 1.1 * comp.1,
        "filtered {filt:?} against compensate's {comp:?}"
    );
    assert!(before.0 > 5.0 * filt.0);
}
