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

/// A line the filter adds after a block it splits (an arc's chords, a long move's pieces):
/// `G1` and every axis, an extrusion perhaps, nothing else.
fn inserted(line: &str) -> bool {
    let w: Vec<&str> = line.split_whitespace().collect();
    w.len() >= 4
        && w[0] == "G1"
        && w[1].starts_with('X')
        && w[2].starts_with('Y')
        && w[3].starts_with('Z')
        && w[4..].iter().all(|x| x.starts_with('E'))
}

/// Absolute positions (mm) of each block that moves, read here: `G90`/`G91`, `G20`/`G21`,
/// comments `;` and `( … )`; arcs by their end.
fn positions(text: &str) -> Vec<Vector3<f64>> {
    line_positions(text).into_iter().flatten().collect()
}

/// For each line of `original` that moves, the positions of its lines in `filtered`: its own,
/// then those of the lines the filter inserted after it (only after the lines `split`, 1-based).
fn moves(original: &str, filtered: &str, split: &[usize]) -> Vec<Vec<Vector3<f64>>> {
    let (o, f) = (line_positions(original), line_positions(filtered));
    let lines: Vec<&str> = filtered.lines().collect();
    let (mut j, mut out) = (0, Vec::new());
    for (i, p) in o.iter().enumerate() {
        let mut group = vec![f[j]];
        j += 1;
        while split.contains(&(i + 1)) && j < lines.len() && inserted(lines[j]) {
            group.push(f[j]);
            j += 1;
        }
        if p.is_some() {
            out.push(group.into_iter().map(Option::unwrap).collect());
        }
    }
    assert_eq!(j, lines.len(), "lines left over");
    out
}

/// The position after each line, where it moves.
fn line_positions(text: &str) -> Vec<Option<Vector3<f64>>> {
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
        out.push(moved.then_some(p));
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

/// A program of 42 moves: absolute, then a G91 section, back to G90, some blocks naming one or
/// two axes only, an arc in each section.
fn program(seed: u64) -> (String, usize, Vec<Arc>) {
    let mut arcs = Vec::new();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut s = String::from("; delta test part\nG21 G90 (mm, absolute)\nM104 S200\nG0 X0 Y0 Z120.000 F6000\n");
    let mut n = 1;
    let mut p: [f64; 3] = [0.0, 0.0, 120.0];
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
        // Arcs from where the machine stands (the block after each names X Y Z, unlike the lines
        // the filter inserts): clockwise by I J (absolute section), anticlockwise
        // by R with Z rising (a helix, incremental section).
        if k == 8 || k == 18 {
            let (ci, cj) = (-8.0, 6.0);
            let (cx, cy) = (p[0] + ci, p[1] + cj);
            let a0 = (p[1] - cy).atan2(p[0] - cx);
            let a1 = if k == 8 { a0 - 1.4 } else { a0 + 1.1 };
            let end = [cx + 10.0 * a1.cos(), cy + 10.0 * a1.sin(), p[2] + if k == 8 { 0.0 } else { 4.0 }];
            if k == 8 {
                s += &format!("G2 X{:.3} Y{:.3} I{ci:.3} J{cj:.3} E2.5 ; arc\n", end[0], end[1]);
            } else {
                s += &format!("G3 X{:.3} Y{:.3} Z{:.3} R10\n", end[0] - p[0], end[1] - p[1], end[2] - p[2]);
            }
            arcs.push(([cx, cy], p, end, s.lines().count()));
            p = end;
            n += 1;
        }
    }
    s += "M84 (motors off)\n";
    (s, n, arcs)
}

/// An arc of the test program: centre (x, y), start, end (mm) and line; radius 10 mm.
type Arc = ([f64; 2], [f64; 3], [f64; 3], usize);

/// The linear delta (`examples/models/linear-delta.toml`) with a tracker's frames, a prototype
/// (±0.3 mm, seed 4) measured at 40 poses (5 µm) and calibrated in `d`: `delta.toml` (nominal),
/// `truth.toml`, `cal.toml`. Returns the nominal model, and the prototype's tool point at inputs
/// `q` read through the calibration's frames.
fn delta(d: &Path, noise_mm: &str) -> (Box<dyn Mechanism>, impl Fn(&[f64]) -> Vector3<f64>) {
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
            noise_mm,
            "--noise-deg",
            "0.003",
            "--out",
            "ident.csv",
            "--truth",
            "truth.toml",
        ],
    );
    ok(d, &["identify", "m.toml", "ident.csv", "--out", "cal.toml"]);
    let nominal = ModelFile::load(&d.join("delta.toml")).unwrap().build();
    let truth = ModelFile::load(&d.join("truth.toml")).unwrap().build();
    let f = ModelFile::load(&d.join("cal.toml")).unwrap().frames.unwrap();
    let reached = move |q: &[f64]| {
        (f.measurement.inverse() * truth.forward(q).unwrap() * f.tool.inverse())
            .translation
            .vector
    };
    (nominal, reached)
}

/// The prototype driven by the nominal controller along its straight line from `a` to `b`
/// (filtered positions), `n` samples: the largest distance from the segment `p`–`q`.
fn path_deviation(
    nominal: &dyn Mechanism,
    reached: &dyn Fn(&[f64]) -> Vector3<f64>,
    (a, b): (Vector3<f64>, Vector3<f64>),
    (p, q): (Vector3<f64>, Vector3<f64>),
    n: usize,
) -> f64 {
    (0..=n)
        .map(|i| {
            let x = a.lerp(&b, i as f64 / n as f64);
            let at = reached(&nominal.inverse(&Pose::translation(x.x, x.y, x.z), None).unwrap());
            let s = ((at - p).dot(&(q - p)) / (q - p).norm_squared()).clamp(0.0, 1.0);
            (at - (p + (q - p) * s)).norm()
        })
        .fold(0.0, f64::max)
}

#[test]
fn linear_delta_gcode_filtered_reaches_the_targets_as_compensate_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (nominal, reached) = delta(d, "0.005");
    let (prog, n, arcs) = program(9);
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
    eprintln!("{out}");
    assert!(out.contains("2 arcs linearised into "), "{out}");
    assert!(out.contains("largest deviation expected between points"), "{out}");
    let filtered = std::fs::read_to_string(d.join("part_cal.gcode")).unwrap();
    // Byte for byte outside the numbers, but for the axis words added, the arcs' G2/G3 → G1
    // and I J R removed, and the lines of their chords.
    let arc_lines: Vec<usize> = arcs.iter().map(|a| a.3).collect();
    let all = moves(&prog, &filtered, &arc_lines);
    let mut kept: Vec<&str> = Vec::new();
    let mut lines = filtered.lines().peekable();
    for (k, _) in prog.lines().enumerate() {
        kept.push(lines.next().unwrap());
        while arc_lines.contains(&(k + 1)) && lines.peek().is_some_and(|l| inserted(l)) {
            lines.next();
        }
    }
    for (k, (a, b)) in prog.lines().zip(&kept).enumerate() {
        if let Some(arc) = arcs.iter().find(|x| x.3 == k + 1) {
            assert!(b.starts_with("G1 X") && !b.contains('I') && !b.contains('R'), "line {}: {b}", arc.3);
            assert_eq!(a.contains("; arc"), b.contains("; arc"));
            continue;
        }
        assert_eq!(skeleton(a), skeleton(&without_added(b, a)), "{a} → {b}");
    }
    let orig = positions(&prog);
    let corr: Vec<Vector3<f64>> = all.iter().map(|g| *g.last().unwrap()).collect();
    assert_eq!(orig.len(), n);
    assert_eq!(corr.len(), n);
    // The nominal controller (the nominal delta's inverse) at the filtered positions, and
    // compensate at the originals; the prototype read through the calibration's frames.
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
    // The arcs: every chord end the prototype reaches on its circle (radius 10 mm about the
    // centre written, Z along the helix), within the chord tolerance and the calibration's error.
    let (mut chords, mut off_arc) = (0, 0.0f64);
    for (centre, start, end, line) in &arcs {
        let k = line_positions(&prog)[..*line].iter().flatten().count() - 1;
        for p in &all[k] {
            let q = nominal.inverse(&Pose::translation(p.x, p.y, p.z), None).unwrap();
            let r = reached(&q);
            let radius = (r.x - centre[0]).hypot(r.y - centre[1]);
            let a = |v: &[f64; 3]| (v[1] - centre[1]).atan2(v[0] - centre[0]);
            let t = ((r.y - centre[1]).atan2(r.x - centre[0]) - a(start)) / (a(end) - a(start));
            let z = start[2] + (end[2] - start[2]) * t;
            off_arc = off_arc.max((radius - 10.0).hypot(r.z - z));
            chords += 1;
        }
    }
    eprintln!(
        "linear delta G-code, {n} moves: max error unfiltered {before:.4} mm, compensate {comp:.5} mm, filtered {filt:.5} mm; 2 arcs: {chords} chord ends, the prototype within {off_arc:.5} mm of the arcs"
    );
    assert!(chords >= 10, "{chords} chords");
    assert!(off_arc <= 0.005 + comp, "chord ends {off_arc} mm off the arcs");
    assert!(filt <= 1.1 * comp, "filtered {filt} against compensate's {comp}");
    assert!(before > 5.0 * filt);
    // An arc whose end is off its circle by more than half the tolerance: one line naming it,
    // nothing written.
    let arc_line = arcs[0].3;
    let bad: String = prog
        .lines()
        .enumerate()
        .map(|(k, l)| if k + 1 == arc_line { l.replacen(" I-8.000", " I-8.300", 1) } else { l.to_string() } + "\n")
        .collect();
    std::fs::write(d.join("arc.gcode"), &bad).unwrap();
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
    assert!(e.starts_with(&format!("arc.gcode:{arc_line}: an arc (G2, G17)")), "{e}");
    assert!(!d.join("arc_cal.gcode").exists());
    // Absolute arc centres (G90.1) are refused.
    std::fs::write(d.join("abs.gcode"), prog.replacen("M104", "G90.1\nM104", 1)).unwrap();
    let e = fails(
        d,
        &[
            "filter",
            "cal.toml",
            "abs.gcode",
            "--nominal",
            "delta.toml",
            "--out",
            "abs_cal.gcode",
        ],
    );
    assert!(e.starts_with("abs.gcode:3: G90.1"), "{e}");
}

/// A long straight move of the delta (115 mm; calibrated from 1 µm data, so that the
/// calibration's own error is small beside the tolerance): without `--max-deviation-mm` the largest
/// deviation between its filtered ends is printed; with 0.01 mm the move is split, and the
/// prototype driven by the nominal controller along the filtered pieces (sampled) stays within
/// 0.01 mm of the commanded line.
#[test]
fn a_long_move_split_stays_within_the_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (nominal, reached) = delta(d, "0.001");
    let prog = "G21 G90\nG0 X-40 Y-30 Z75 F6000\nG1 X40.5 Y35 Z125 E12.5 F1200 ; long move\nM84\n";
    std::fs::write(d.join("long.gcode"), prog).unwrap();
    let args = ["filter", "cal.toml", "long.gcode", "--nominal", "delta.toml", "--out"];
    let unsplit = ok(d, &[&args[..], &["unsplit.gcode"]].concat());
    eprintln!("{unsplit}");
    let printed: f64 = unsplit
        .split("largest deviation expected between points (the machine's path from the commanded line, on the calibrated model): ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    let split = ok(d, &[&args[..], &["split.gcode", "--max-deviation-mm", "0.01"]].concat());
    eprintln!("{split}");
    let text = std::fs::read_to_string(d.join("split.gcode")).unwrap();
    let pieces = moves(prog, &text, &[3]);
    let unsplit_pieces = moves(prog, &std::fs::read_to_string(d.join("unsplit.gcode")).unwrap(), &[]);
    assert_eq!(pieces.len(), 2);
    assert!(pieces[1].len() > 1, "the move was not split: {text}");
    // The extrusion shared along the pieces, the last at the block's value.
    let es: Vec<f64> = text
        .lines()
        .filter_map(|l| l.split_whitespace().find(|w| w.starts_with('E')))
        .map(|w| w[1..].parse().unwrap())
        .collect();
    assert_eq!(es.len(), pieces[1].len());
    assert!(
        es.windows(2).all(|w| w[0] < w[1]) && (es.last().unwrap() - 12.5).abs() < 1e-9,
        "{es:?}"
    );
    let (p, q) = (Vector3::new(-40.0, -30.0, 75.0), Vector3::new(40.5, 35.0, 125.0));
    let nominal = &*nominal;
    let mut worst = 0.0f64;
    let mut from = pieces[0][0];
    for to in &pieces[1] {
        worst = worst.max(path_deviation(nominal, &reached, (from, *to), (p, q), 60));
        from = *to;
    }
    let before = path_deviation(nominal, &reached, (unsplit_pieces[0][0], unsplit_pieces[1][0]), (p, q), 200);
    eprintln!(
        "a 115 mm move: printed {printed} mm; the prototype along the unsplit filtered move {before:.4} mm from the line; split into {} pieces: {worst:.4} mm",
        pieces[1].len()
    );
    assert!(before > 0.01, "the unsplit move stays within {before} mm: no test");
    assert!(worst <= 0.01, "the split move leaves the line by {worst} mm");
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
