//! `kinecal filter`: a virtual IRB 120 calibrated from simulated tracker data (a tracker frame
//! and a reflector offset), its programs filtered, and the prototype driven by its *nominal*
//! controller to the filtered targets. The files written are read back here by independent code
//! (RAPID robtargets, quaternions w first, ABB configuration data, CSV cells), not by kinecal's
//! readers.
use crate::cli::{fails, ok};
use kinecal::io::model_file::ModelFile;
use kinecal::model::builtin::irb120;
use kinecal::se3::Pose;
use kinecal::Mechanism;
use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Where the tracker stood and its reflector on the flange: the instrument's frames.
const TRACKER: &str = "
[frames]
[frames.measurement]
position = [2500.0, -800.0, 300.0]
rpy = [5.0, -10.0, 120.0]
[frames.tool]
position = [30.0, 40.0, 100.0]
rpy = [3.0, -4.0, 20.0]
";

/// The program's tool and work object (RAPID text of their frames).
pub const TOOL: ([f64; 3], [f64; 4]) = ([12.5, -8.0, 135.25], [0.996195, 0.0, 0.087156, 0.0]);
pub const UFRAME: ([f64; 3], [f64; 4]) = ([420.0, -150.0, 80.5], [0.965926, 0.0, 0.0, 0.258819]);
pub const OFRAME: ([f64; 3], [f64; 4]) = ([10.0, 20.0, 0.0], [1.0, 0.0, 0.0, 0.0]);

/// A pose from a position and a quaternion w first, by the quaternion's rotation matrix
/// written out (independent of kinecal's readers).
pub fn pose_wxyz(p: [f64; 3], q: [f64; 4]) -> Pose {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let [w, x, y, z] = q.map(|v| v / n);
    let r = Matrix3::new(
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y - w * z),
        2.0 * (x * z + w * y),
        2.0 * (x * y + w * z),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z - w * x),
        2.0 * (x * z - w * y),
        2.0 * (y * z + w * x),
        1.0 - 2.0 * (x * x + y * y),
    );
    Pose::from_parts(
        Translation3::new(p[0], p[1], p[2]),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)),
    )
}

/// ABB's configuration data of IRB 120 joint values (rad), from the arm's geometry written out
/// here: quadrants of axes 1, 4, 6; the wrist centre behind axis 1 (4), behind the lower arm
/// (2), axis 5 negative (1).
pub fn irb120_conf(q: &[f64]) -> [i32; 4] {
    let quadrant = |a: f64| (a.to_degrees() / 90.0).floor() as i32;
    let t = q[1] + q[2];
    // In the arm's plane (x forward, z up), about axis 2: upper arm 270 mm, forearm (302, 70) mm.
    let (ux, uz) = (270.0 * q[1].sin(), 270.0 * q[1].cos());
    let (fx, fz) = (302.0 * t.cos() + 70.0 * t.sin(), -302.0 * t.sin() + 70.0 * t.cos());
    let behind_axis1 = ux + fx < 0.0;
    let behind_lower_arm = uz * fx - ux * fz < 0.0;
    [
        quadrant(q[0]),
        quadrant(q[3]),
        quadrant(q[5]),
        4 * behind_axis1 as i32 + 2 * behind_lower_arm as i32 + (q[4] < 0.0) as i32,
    ]
}

/// The nominal controller: the nominal IRB 120's inverse kinematics for the flange pose
/// `flange`, on the configuration `conf` (from starting points at the quadrants' middles; the
/// solution whose configuration is `conf`).
pub fn nominal_controller(flange: &Pose, conf: [i32; 4]) -> Option<Vec<f64>> {
    let arm = irb120();
    let mid = |k: i32| ((k as f64 + 0.5) * 90.0).to_radians();
    let q5 = if conf[3] & 1 == 1 { -0.6 } else { 0.6 };
    for q2 in [0.0, 0.6, -0.6, 1.2, -1.2] {
        for q3 in [0.0, 0.8, -0.8, -2.0] {
            let seed = [mid(conf[0]), q2, q3, mid(conf[1]), q5, mid(conf[2])];
            let Ok(mut q) = arm.inverse(flange, Some(&seed)) else { continue };
            for k in 0..6 {
                q[k] += ((seed[k] - q[k]) / std::f64::consts::TAU).round() * std::f64::consts::TAU;
            }
            let reached = arm.forward(&q).unwrap();
            let ok = (reached.translation.vector - flange.translation.vector).norm() < 1e-7;
            if ok && irb120_conf(&q) == conf {
                return Some(q);
            }
        }
    }
    None
}

/// The calibration every test here shares: the IRB 120 with the tracker's frames, a prototype
/// (±0.3 mm / ±0.05°, seed 3) measured at 60 poses (10 µm / 0.005°) and calibrated with the
/// frames estimated.
pub struct Calibrated {
    pub dir: PathBuf,
    pub truth: Box<dyn Mechanism>,
    pub cal: ModelFile,
}

pub fn calibrated() -> &'static Calibrated {
    static CAL: OnceLock<Calibrated> = OnceLock::new();
    CAL.get_or_init(|| {
        // Under the build's own scratch directory (a static is never dropped, so a TempDir
        // would be left behind in /tmp by every run); made afresh by each test process.
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("filter-fixture-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let d = dir.as_path();
        let text = kinecal::io::builtin::model_file("irb120").unwrap().to_toml().unwrap();
        std::fs::write(d.join("m.toml"), text + TRACKER).unwrap();
        ok(
            d,
            &[
                "simulate",
                "m.toml",
                "--poses",
                "60",
                "--seed",
                "3",
                "--error-mm",
                "0.3",
                "--error-deg",
                "0.05",
                "--noise-mm",
                "0.01",
                "--noise-deg",
                "0.005",
                "--out",
                "ident.csv",
                "--truth",
                "truth.toml",
            ],
        );
        ok(d, &["identify", "m.toml", "ident.csv", "--out", "cal.toml"]);
        Calibrated {
            truth: ModelFile::load(&d.join("truth.toml")).unwrap().build(),
            cal: ModelFile::load(&d.join("cal.toml")).unwrap(),
            dir,
        }
    })
}

impl Calibrated {
    /// The prototype's pose of the tool `tool` (on the flange as the calibration defines it)
    /// at joint values `q`, in the calibrated base frame: the tracker's reading through the
    /// calibration's frames.
    pub fn reached(&self, q: &[f64], tool: &Pose) -> Pose {
        let f = self.cal.frames.unwrap();
        f.measurement.inverse() * self.truth.forward(q).unwrap() * f.tool.inverse() * tool
    }
}

/// Targets for the program: IRB 120 joint values drawn in a working region (seed), as
/// (q, tool pose in the base frame).
pub fn program_configurations(n: usize, seed: u64, tool: &Pose) -> Vec<(Vec<f64>, Pose)> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let arm = irb120();
    let mut out = Vec::new();
    let mut r = |lo: f64, hi: f64| rng.random_range(lo..hi).to_radians();
    while out.len() < n {
        let q5 = if out.len() % 5 == 4 { r(-100.0, -25.0) } else { r(25.0, 100.0) };
        let q = vec![
            r(-120.0, 120.0),
            r(-30.0, 60.0),
            r(-70.0, 40.0),
            r(-150.0, 150.0),
            q5,
            r(-300.0, 300.0),
        ];
        let conf = irb120_conf(&q);
        // Keep away from the quadrant boundaries the nominal and calibrated solutions may straddle.
        let near = [0, 3, 5].iter().any(|&k| {
            let d = q[k].to_degrees().rem_euclid(90.0);
            !(2.0..=88.0).contains(&d)
        });
        if near || conf[3] & 2 != 0 {
            continue;
        }
        out.push((q.clone(), arm.forward(&q).unwrap() * tool));
    }
    out
}

/// Numbers and everything else of a text: (the text with each number replaced by `#`, the
/// numbers). A number: an optional minus, digits, a fraction, an exponent, not part of a name.
pub fn split_numbers(text: &str) -> (String, Vec<String>) {
    let b = text.as_bytes();
    let (mut skeleton, mut numbers) = (String::new(), Vec::new());
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c.is_ascii_alphabetic() || c == b'_' {
            let s = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                i += 1;
            }
            skeleton.push_str(&text[s..i]);
            continue;
        }
        let signed = c == b'-' && b.get(i + 1).is_some_and(u8::is_ascii_digit);
        if c.is_ascii_digit() || signed {
            let s = i;
            i += 1;
            while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.') {
                i += 1;
            }
            if i + 1 < b.len() && (b[i] == b'E' || b[i] == b'e') {
                i += 1;
                if b[i] == b'+' || b[i] == b'-' {
                    i += 1;
                }
                while i < b.len() && b[i].is_ascii_digit() {
                    i += 1;
                }
            }
            numbers.push(text[s..i].to_string());
            skeleton.push('#');
            continue;
        }
        let n = text[i..].chars().next().unwrap().len_utf8();
        skeleton.push_str(&text[i..i + n]);
        i += n;
    }
    (skeleton, numbers)
}

/// A robtarget's text `[[x,y,z],[qw,qx,qy,qz],[cf1,cf4,cf6,cfx],[…]]` read here: position,
/// quaternion, configuration.
pub fn read_robtarget(s: &str) -> ([f64; 3], [f64; 4], [i32; 4]) {
    let inner = s.trim().trim_start_matches('[').trim_end_matches(']');
    let groups: Vec<Vec<f64>> = inner
        .split("],[")
        .map(|g| g.split(',').map(|v| v.trim().parse().unwrap()).collect())
        .collect();
    (
        [groups[0][0], groups[0][1], groups[0][2]],
        [groups[1][0], groups[1][1], groups[1][2], groups[1][3]],
        [groups[2][0] as i32, groups[2][1] as i32, groups[2][2] as i32, groups[2][3] as i32],
    )
}

/// Every robtarget literal of a RAPID text (declared or inline), in order of appearance.
pub fn robtargets(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(k) = rest.find("[[") {
        let tail = &rest[k..];
        let mut depth = 0;
        let end = tail
            .char_indices()
            .find(|&(_, c)| {
                match c {
                    '[' => depth += 1,
                    ']' => depth -= 1,
                    _ => {}
                }
                depth == 0
            })
            .unwrap()
            .0;
        let lit = &tail[..=end];
        // Four groups: a robtarget (a tooldata or wobjdata aggregate starts with TRUE/FALSE).
        if lit.matches("],[").count() == 3 && !lit.contains('"') {
            out.push(lit.to_string());
        }
        rest = &tail[end + 1..];
    }
    out
}

fn fmt_q(q: &UnitQuaternion<f64>) -> [f64; 4] {
    let q = q.into_inner();
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    [q.w * s, q.i * s, q.j * s, q.k * s]
}

/// A RAPID module with `n` robtargets in a work object, with a tool, some inline targets, a
/// circular move, a joint target, a run-time target, comments and CRLF line ends.
pub fn rapid_module(n: usize, seed: u64) -> (String, Vec<Vec<f64>>) {
    let tool = pose_wxyz(TOOL.0, TOOL.1);
    let wobj = pose_wxyz(UFRAME.0, UFRAME.1) * pose_wxyz(OFRAME.0, OFRAME.1);
    let cfgs = program_configurations(n, seed, &tool);
    let lit = |p: &Pose, conf: [i32; 4]| {
        let l = wobj.inverse() * p;
        let t = l.translation.vector;
        let q = fmt_q(&l.rotation);
        format!(
            "[[{:.3},{:.3},{:.3}],[{:.6},{:.6},{:.6},{:.6}],[{},{},{},{}],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]",
            t.x, t.y, t.z, q[0], q[1], q[2], q[3], conf[0], conf[1], conf[2], conf[3]
        )
    };
    let arr = |a: [f64; 3]| format!("{},{},{}", a[0], a[1], a[2]);
    let arr4 = |a: [f64; 4]| format!("{},{},{},{}", a[0], a[1], a[2], a[3]);
    let mut m = String::from("%%%\r\n  VERSION:1\r\n  LANGUAGE:ENGLISH\r\n%%%\r\n\r\nMODULE Filtered\r\n  ! tool, work object and targets (a comment with 1.5 numbers: kept)\r\n");
    m += &format!(
        "  PERS tooldata tGrip:=[TRUE,[[{}],[{}]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\r\n",
        arr(TOOL.0),
        arr4(TOOL.1)
    );
    m += &format!(
        "  TASK PERS wobjdata wTable:=[FALSE,TRUE,\"\",[[{}],[{}]],[[{}],[{}]]];\r\n",
        arr(UFRAME.0),
        arr4(UFRAME.1),
        arr(OFRAME.0),
        arr4(OFRAME.1)
    );
    m += "  CONST jointtarget jHome:=[[0,0,0,0,30,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];\r\n";
    let inline = n - 4;
    for (k, (q, p)) in cfgs.iter().enumerate().take(inline) {
        m += &format!("  CONST robtarget p{k}:={};\r\n", lit(p, irb120_conf(q)));
    }
    m += "\r\n  PROC main()\r\n    MoveAbsJ jHome, v500, fine, tool0;\r\n";
    for k in 0..inline {
        match k % 3 {
            0 => m += &format!("    MoveJ p{k}, v1000, z50, tGrip\\WObj:=wTable;\r\n"),
            1 => m += &format!("    MoveL p{k}, v200\\T:=3, z10, tGrip\\WObj:=wTable; ! 2.5 s\r\n"),
            _ => m += &format!("    MoveLDO p{k}, v200, fine, tGrip\\WObj:=wTable, doGrip, 1;\r\n"),
        }
    }
    let (c0, c1, c2, c3) = (&cfgs[inline], &cfgs[inline + 1], &cfgs[inline + 2], &cfgs[inline + 3]);
    m += &format!(
        "    MoveC {}, {}, v100, z5, tGrip\\WObj:=wTable;\r\n",
        lit(&c0.1, irb120_conf(&c0.0)),
        lit(&c1.1, irb120_conf(&c1.0))
    );
    m += &format!(
        "    MoveL\\Conc, {}, v100, fine, tGrip\\WObj:=wTable;\r\n",
        lit(&c2.1, irb120_conf(&c2.0))
    );
    m += &format!("    MoveJ {},v100,fine,tGrip\\WObj:=wTable;\r\n", lit(&c3.1, irb120_conf(&c3.0)));
    m += "    MoveL Offs(p1,0,0,50), v100, fine, tGrip\\WObj:=wTable;\r\n  ENDPROC\r\nENDMODULE\r\n";
    (m, cfgs.into_iter().map(|(q, _)| q).collect())
}

/// The targets of a RAPID module in the base frame with their configurations, read here.
pub fn base_targets(text: &str) -> Vec<(Pose, [i32; 4])> {
    let wobj = pose_wxyz(UFRAME.0, UFRAME.1) * pose_wxyz(OFRAME.0, OFRAME.1);
    robtargets(text)
        .iter()
        .map(|s| {
            let (p, q, c) = read_robtarget(s);
            (wobj * pose_wxyz(p, q), c)
        })
        .collect()
}

fn errors(a: &Pose, b: &Pose) -> (f64, f64) {
    let e = kinecal::se3::pose_error(a, b);
    (kinecal::se3::lin(&e).norm(), kinecal::se3::ang(&e).norm().to_degrees())
}

fn commands_rad(path: &Path) -> Vec<Vec<f64>> {
    kinecal::io::table::read_table(path)
        .unwrap()
        .rows
        .iter()
        .map(|r| r[1..].iter().map(|v| v.to_radians()).collect())
        .collect()
}

/// A RAPID module with 54 targets (a tooldata and a wobjdata) filtered; the prototype driven by
/// the nominal controller to the filtered targets (on the configurations written) reaches the
/// originals within 1.1× the error of `compensate`'s commands, far better than the unfiltered
/// program; every byte outside the changed numbers is the original's.
#[test]
fn rapid_module_filtered_reaches_the_targets_as_compensate_does() {
    let c = calibrated();
    let d = c.dir.join("rapid");
    std::fs::create_dir_all(&d).unwrap();
    let (module, _) = rapid_module(54, 11);
    std::fs::write(d.join("prog.mod"), &module).unwrap();
    let out = ok(
        &d,
        &["filter", "../cal.toml", "prog.mod", "--nominal", "irb120", "--out", "filtered.mod"],
    );
    eprintln!("{out}");
    let filtered = std::fs::read_to_string(d.join("filtered.mod")).unwrap();
    // Byte for byte outside the numbers; the same count of numbers.
    let (a, na) = split_numbers(&module);
    let (b, nb) = split_numbers(&filtered);
    assert_eq!(a, b, "the text outside the numbers changed");
    assert_eq!(na.len(), nb.len());
    let changed = na.iter().zip(&nb).filter(|(x, y)| x != y).count();
    let originals = base_targets(&module);
    let corrected = base_targets(&filtered);
    assert_eq!(originals.len(), 54);
    assert_eq!(corrected.len(), 54);
    // Joint targets, tool, work object and external axes unchanged: the changed numbers are in
    // the robtargets' position, quaternion and configuration only.
    assert!(filtered.contains("jHome:=[[0,0,0,0,30,0],"));
    assert!(changed >= 54 * 3, "{changed} numbers changed");
    let tool = pose_wxyz(TOOL.0, TOOL.1);
    // compensate on the same targets (base frame, the program's tool), seeded with the nominal
    // controller's joint values so it stays on the program's branch.
    let mut csv = String::from("id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm,qw,qx,qy,qz\n");
    let mut nominal_q = Vec::new();
    for (k, (t, conf)) in originals.iter().enumerate() {
        let q = nominal_controller(&(t * tool.inverse()), *conf).unwrap_or_else(|| panic!("original target {k} on {conf:?}"));
        let r = fmt_q(&t.rotation);
        let p = t.translation.vector;
        let deg: Vec<String> = q.iter().map(|v| format!("{:.12}", v.to_degrees())).collect();
        csv += &format!(
            "{k},{},{:.9},{:.9},{:.9},{:.12},{:.12},{:.12},{:.12}\n",
            deg.join(","),
            p.x,
            p.y,
            p.z,
            r[0],
            r[1],
            r[2],
            r[3]
        );
        nominal_q.push(q);
    }
    std::fs::write(d.join("targets.csv"), csv).unwrap();
    let rpy = tool.rotation.euler_angles();
    let tool_arg = format!(
        "{},{},{},{:.12},{:.12},{:.12}",
        TOOL.0[0],
        TOOL.0[1],
        TOOL.0[2],
        rpy.0.to_degrees(),
        rpy.1.to_degrees(),
        rpy.2.to_degrees()
    );
    ok(
        &d,
        &["compensate", "../cal.toml", "targets.csv", "--tool", &tool_arg, "--out", "cmd.csv"],
    );
    let compensated = commands_rad(&d.join("cmd.csv"));
    let (mut before, mut comp, mut filt) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64), (0.0f64, 0.0f64));
    let (mut comp_ss, mut filt_ss) = (0.0, 0.0);
    for (k, ((t, _), (t2, conf2))) in originals.iter().zip(&corrected).enumerate() {
        // The nominal controller sent the filtered target on the configuration written.
        let q = nominal_controller(&(t2 * tool.inverse()), *conf2).unwrap_or_else(|| panic!("filtered target {k} on {conf2:?}"));
        // The configuration written is the branch reached: compensate's joint values.
        let dq = q.iter().zip(&compensated[k]).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(
            dq < 1e-4,
            "target {k}: the nominal controller's joints differ from compensate's by {dq:e} rad"
        );
        let e = errors(t, &c.reached(&q, &tool));
        let ec = errors(t, &c.reached(&compensated[k], &tool));
        let en = errors(t, &c.reached(&nominal_q[k], &tool));
        filt = (filt.0.max(e.0), filt.1.max(e.1));
        comp = (comp.0.max(ec.0), comp.1.max(ec.1));
        before = (before.0.max(en.0), before.1.max(en.1));
        filt_ss += e.0 * e.0;
        comp_ss += ec.0 * ec.0;
    }
    eprintln!("RAPID, 54 targets: max error unfiltered {before:?}, compensate {comp:?}, filtered {filt:?} (mm, deg); RMS compensate {:.5}, filtered {:.5} mm", (comp_ss / 54.0f64).sqrt(), (filt_ss / 54.0f64).sqrt());
    assert!(
        filt.0 <= 1.1 * comp.0 && filt.1 <= 1.1 * comp.1,
        "filtered {filt:?} against compensate's {comp:?}"
    );
    assert!(filt_ss <= 1.21 * comp_ss);
    assert!(before.0 > 5.0 * filt.0, "unfiltered {before:?}, filtered {filt:?}");
}

/// CSV targets: the corrected cells read back here, in the base frame with the tool of
/// `--tool`; the ids, the input columns and every other byte kept.
#[test]
fn csv_targets_filtered_in_the_base_frame_with_a_tool() {
    let c = calibrated();
    let d = c.dir.join("csv");
    std::fs::create_dir_all(&d).unwrap();
    let tool = pose_wxyz(TOOL.0, TOOL.1);
    let cfgs = program_configurations(20, 5, &tool);
    // The nominal joint values (rounded, as a controller log gives them) say the branch.
    let mut csv =
        String::from("# targets of the program\nid,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n");
    for (k, (q, p)) in cfgs.iter().enumerate() {
        let (r, pi, y) = p.rotation.euler_angles();
        let t = p.translation.vector;
        let deg: Vec<String> = q.iter().map(|v| format!("{:.2}", v.to_degrees())).collect();
        csv += &format!(
            "{},{:.3},{:.3},{:.3},{:.4},{:.4},{:.4},{}\n",
            100 + k,
            t.x,
            t.y,
            t.z,
            r.to_degrees(),
            pi.to_degrees(),
            y.to_degrees(),
            deg.join(",")
        );
    }
    std::fs::write(d.join("t.csv"), &csv).unwrap();
    let rpy = tool.rotation.euler_angles();
    let tool_arg = format!(
        "{},{},{},{:.12},{:.12},{:.12}",
        TOOL.0[0],
        TOOL.0[1],
        TOOL.0[2],
        rpy.0.to_degrees(),
        rpy.1.to_degrees(),
        rpy.2.to_degrees()
    );
    ok(
        &d,
        &[
            "filter",
            "../cal.toml",
            "t.csv",
            "--nominal",
            "irb120",
            "--tool",
            &tool_arg,
            "--out",
            "f.csv",
        ],
    );
    let out = std::fs::read_to_string(d.join("f.csv")).unwrap();
    let (a, _) = split_numbers(&csv);
    let (b, _) = split_numbers(&out);
    assert_eq!(a, b);
    let read = |s: &str| -> Vec<(String, Pose)> {
        s.lines()
            .skip(2)
            .map(|l| {
                let v: Vec<&str> = l.split(',').collect();
                let f: Vec<f64> = v[1..7].iter().map(|x| x.parse().unwrap()).collect();
                // R = Rz(yaw)·Ry(pitch)·Rx(roll), written out.
                let rot = Rotation3::from_axis_angle(&Vector3::z_axis(), f[5].to_radians())
                    * Rotation3::from_axis_angle(&Vector3::y_axis(), f[4].to_radians())
                    * Rotation3::from_axis_angle(&Vector3::x_axis(), f[3].to_radians());
                (
                    v[0].to_string(),
                    Pose::from_parts(Translation3::new(f[0], f[1], f[2]), UnitQuaternion::from_rotation_matrix(&rot)),
                )
            })
            .collect()
    };
    let (orig, filt) = (read(&csv), read(&out));
    let mut worst = (0.0f64, 0.0f64);
    for ((id, t), (id2, t2)) in orig.iter().zip(&filt) {
        assert_eq!(id, id2);
        // The nominal controller on the branch of the original target's solution.
        let q0 = cfgs[id.parse::<usize>().unwrap() - 100].0.clone();
        let q = nominal_controller(&(t2 * tool.inverse()), irb120_conf(&q0)).unwrap();
        let e = errors(t, &c.reached(&q, &tool));
        worst = (worst.0.max(e.0), worst.1.max(e.1));
    }
    eprintln!("CSV, 20 targets: filtered max error {worst:?} (mm, deg)");
    assert!(worst.0 < 0.05 && worst.1 < 0.01, "{worst:?}");
    // compensate in the base frame: the same program tool, the commands reach the targets on
    // the calibrated model (before, the targets were read in the tracker frame: unreachable).
    ok(
        &d,
        &[
            "compensate",
            "../cal.toml",
            "t.csv",
            "--nominal",
            "irb120",
            "--tool",
            &tool_arg,
            "--out",
            "cmd.csv",
        ],
    );
}

/// Malformed programs and targets that cannot be corrected: one line naming the file and line,
/// exit 1, nothing written.
#[test]
fn malformed_programs_give_one_line_and_write_nothing() {
    let c = calibrated();
    let d = c.dir.join("bad");
    std::fs::create_dir_all(&d).unwrap();
    let (module, _) = rapid_module(6, 2);
    let line_of = |text: &str, needle: &str| text.lines().position(|l| l.contains(needle)).unwrap() + 1;
    let p0 = robtargets(&module)[0].clone();
    let cases: Vec<(&str, String, String)> = vec![
        (
            "unparsable.mod",
            module.replacen(&p0, "[[1,2],[1,0,0,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]", 1),
            "p0:=".into(),
        ),
        (
            "tool.mod",
            module.replacen("MoveJ p0, v1000, z50, tGrip", "MoveJ p0, v1000, z50, tGripper", 1),
            "tGripper".into(),
        ),
        (
            "reach.mod",
            module.replacen(&p0, "[[5000,0,300],[1,0,0,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]", 1),
            "p0:=".into(),
        ),
        (
            "quat.mod",
            module.replacen(&p0, "[[500,0,300],[1,0,0.5,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]", 1),
            "p0:=".into(),
        ),
    ];
    for (name, text, needle) in cases {
        std::fs::write(d.join(name), &text).unwrap();
        let e = fails(&d, &["filter", "../cal.toml", name, "--nominal", "irb120", "--out", "out.mod"]);
        let line = line_of(&text, &needle);
        eprintln!("{e}");
        assert!(e.starts_with(&format!("{name}:{line}: ")), "{name}: {e}");
        assert!(!d.join("out.mod").exists(), "{name}: something was written");
    }
    // Never over an input.
    std::fs::write(d.join("ok.mod"), &module).unwrap();
    let e = fails(
        &d,
        &[
            "filter",
            "../cal.toml",
            "ok.mod",
            "--nominal",
            "irb120",
            "--out",
            "ok.mod",
            "--force",
        ],
    );
    assert!(e.contains("ok.mod"), "{e}");
    assert_eq!(std::fs::read_to_string(d.join("ok.mod")).unwrap(), module);
}
