//! `kinecal filter` on a KUKA KRL pair (`.src` + `.dat`): E6POS/POS/FRAME points declared in the
//! `.dat` and inline in the `.src`, a declared tool FRAME then a TOOL_DATA given by option, a
//! BASE_DATA given by option, Status and Turn in decimal and binary; read back by independent
//! code (aggregates, A, B, C about Z, Y′, X″, Status and Turn of the IRB 120's joint values).
use crate::cli::{fails, ok};
use crate::filter::{calibrated, irb120_conf, program_configurations, split_numbers};
use kinecal::model::builtin::irb120;
use kinecal::se3::Pose;
use kinecal::Mechanism;
use nalgebra::{Rotation3, Translation3, UnitQuaternion, Vector3};

/// A frame from X, Y, Z (mm) and A, B, C (deg): `Rz(A)·Ry(B)·Rx(C)`, written out.
fn frame(v: [f64; 6]) -> Pose {
    let r = Rotation3::from_axis_angle(&Vector3::z_axis(), v[3].to_radians())
        * Rotation3::from_axis_angle(&Vector3::y_axis(), v[4].to_radians())
        * Rotation3::from_axis_angle(&Vector3::x_axis(), v[5].to_radians());
    Pose::from_parts(Translation3::new(v[0], v[1], v[2]), UnitQuaternion::from_rotation_matrix(&r))
}

/// A, B, C (deg) of a rotation `Rz(A)·Ry(B)·Rx(C)`.
fn abc(p: &Pose) -> [f64; 3] {
    let m = p.rotation.to_rotation_matrix().into_inner();
    let b = (-m[(2, 0)]).asin();
    [
        m[(1, 0)].atan2(m[(0, 0)]).to_degrees(),
        b.to_degrees(),
        m[(2, 1)].atan2(m[(2, 2)]).to_degrees(),
    ]
}

/// KUKA's Status and Turn of IRB 120 joint values, from the configuration bits written out in
/// `irb120_conf`.
fn status_turn(q: &[f64]) -> (i32, i32) {
    let cfx = irb120_conf(q)[3];
    let s = (cfx >> 2) & 1 | ((cfx >> 1) & 1) << 1 | (cfx & 1) << 2;
    let t = q.iter().enumerate().map(|(k, v)| ((*v < 0.0) as i32) << k).sum();
    (s, t)
}

/// The controller: the nominal inverse kinematics on a Status and Turn.
fn kuka_controller(flange: &Pose, st: (i32, i32)) -> Option<Vec<f64>> {
    let arm = irb120();
    let sign = |k: usize| if (st.1 >> k) & 1 == 1 { -1.0 } else { 1.0 };
    for m2 in [0.2, 0.6, 1.0] {
        for m3 in [0.2, 0.8, 1.5] {
            for m1 in [0.5, 1.5] {
                let seed: Vec<f64> = [m1, m2, m3, 0.8, 0.8, 0.8].iter().enumerate().map(|(k, v)| sign(k) * v).collect();
                let Ok(mut q) = arm.inverse(flange, Some(&seed)) else { continue };
                for (k, v) in q.iter_mut().enumerate() {
                    *v = (*v + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
                    if [0, 3, 5].contains(&k) && (*v < 0.0) != (sign(k) < 0.0) {
                        *v -= sign(k) * -std::f64::consts::TAU;
                    }
                }
                let ok = (arm.forward(&q).unwrap().translation.vector - flange.translation.vector).norm() < 1e-7;
                if ok && status_turn(&q) == st {
                    return Some(q);
                }
            }
        }
    }
    None
}

/// Every `{X …}` aggregate of a text holding X, Y, Z, A, B, C, read here: (pose, S and T).
fn points(text: &str) -> Vec<(Pose, Option<(i32, i32)>)> {
    let mut out = Vec::new();
    for chunk in text.split('{').skip(1) {
        let body = chunk.split('}').next().unwrap();
        let get = |k: &str| {
            body.split(',').find_map(|f| {
                let mut it = f.split_whitespace();
                (it.next() == Some(k)).then(|| it.next().unwrap().to_string())
            })
        };
        let num = |k: &str| get(k).map(|v| v.parse::<f64>().unwrap());
        let Some(v) = ["X", "Y", "Z", "A", "B", "C"].iter().map(|k| num(k)).collect::<Option<Vec<f64>>>() else {
            continue;
        };
        let int = |s: String| match s.strip_prefix("'B") {
            Some(b) => i32::from_str_radix(b.trim_end_matches('\''), 2).unwrap(),
            None => s.parse().unwrap(),
        };
        let st = get("S").zip(get("T")).map(|(s, t)| (int(s), int(t)));
        out.push((frame([v[0], v[1], v[2], v[3], v[4], v[5]]), st));
    }
    out
}

fn agg(p: &Pose, st: Option<(i32, i32)>, binary: bool) -> String {
    let t = p.translation.vector;
    let a = abc(p);
    let mut s = format!("X {:.3},Y {:.3},Z {:.3},A {:.4},B {:.4},C {:.4}", t.x, t.y, t.z, a[0], a[1], a[2]);
    if let Some((st, tt)) = st {
        if binary {
            s += &format!(",S 'B{st:03b}',T 'B{tt:06b}'");
        } else {
            s += &format!(",S {st},T {tt}");
        }
    }
    s
}

const BASE: [f64; 6] = [400.0, -100.0, 50.0, 30.0, 0.0, 0.0];
const TOOL1: [f64; 6] = [12.5, -8.0, 135.25, 0.0, 10.0, 0.0];
const TOOL2: [f64; 6] = [0.0, 30.0, 100.0, 0.0, 0.0, 0.0];

/// A KRL pair of 52 points filtered: the prototype driven by the nominal controller (on the
/// Status and Turn written) reaches the originals within 1.1× the error of `compensate`.
#[test]
fn krl_pair_filtered_reaches_the_targets_as_compensate_does() {
    let c = calibrated();
    let d = c.dir.join("krl");
    std::fs::create_dir_all(&d).unwrap();
    let base = frame(BASE);
    let tools = [frame(TOOL1), frame(TOOL2)];
    let n = 52;
    let cfgs1 = program_configurations(n / 2, 31, &tools[0]);
    let cfgs2 = program_configurations(n / 2, 32, &tools[1]);
    let mut dat = String::from("&ACCESS RVP\r\n&REL 1\r\nDEFDAT  weld\r\n;FOLD EXTERNAL DECLARATIONS;%{PE}%MKUKATPBASIS,%CEXT,%VCOMMON,%P\r\n;ENDFOLD (EXTERNAL DECLARATIONS)\r\n");
    dat += &format!(
        "DECL FRAME TCP_GRIP={{X {},Y {},Z {},A {},B {},C {}}}\r\n",
        TOOL1[0], TOOL1[1], TOOL1[2], TOOL1[3], TOOL1[4], TOOL1[5]
    );
    let mut src = String::from("&ACCESS RVP\r\n&REL 1\r\nDEF weld( )\r\n;FOLD INI;%{PE}\r\n  BAS (#INITMOV,0 )\r\n;ENDFOLD (INI)\r\n$BASE = BASE_DATA[1]\r\n$TOOL = TCP_GRIP\r\nPTP {A1 0,A2 -90,A3 90,A4 0,A5 30,A6 0}\r\n");
    let mut order = Vec::new();
    for (half, cfgs) in [&cfgs1, &cfgs2].iter().enumerate() {
        if half == 1 {
            src += "$TOOL = TOOL_DATA[2] ; the second tool\r\n";
        }
        for (k, (q, p)) in cfgs.iter().enumerate() {
            let id = half * 100 + k;
            let local = base.inverse() * p;
            let st = Some(status_turn(q));
            match k % 4 {
                0 => src += &format!("LIN {{{}}} C_DIS\r\n", agg(&local, st, false)),
                1 => {
                    dat += &format!("DECL POS XP{id}={{{}}}\r\n", agg(&local, st, true));
                    src += &format!(";FOLD LIN P{id};%{{PE}}\r\nLIN XP{id}\r\n;ENDFOLD\r\n");
                }
                _ => {
                    dat += &format!(
                        "DECL E6POS XP{id}={{{},E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}}\r\n",
                        agg(&local, st, false)
                    );
                    src += &format!("PTP XP{id}\r\n");
                }
            }
            order.push((half, k));
        }
    }
    src += "PTP XHOME\r\nEND\r\n";
    dat += "ENDDAT\r\n";
    std::fs::write(d.join("weld.src"), &src).unwrap();
    std::fs::write(d.join("weld.dat"), &dat).unwrap();
    let base_arg = format!("1={}", BASE.map(|v| v.to_string()).join(","));
    let tool_arg = format!("2={}", TOOL2.map(|v| v.to_string()).join(","));
    let out = ok(
        &d,
        &[
            "filter",
            "../cal.toml",
            "weld.src",
            "--nominal",
            "irb120",
            "--out",
            "out.src",
            "--base-data",
            &base_arg,
            "--tool-data",
            &tool_arg,
        ],
    );
    eprintln!("{}", out.lines().take(2).collect::<Vec<_>>().join("\n"));
    let (src2, dat2) = (
        std::fs::read_to_string(d.join("out.src")).unwrap(),
        std::fs::read_to_string(d.join("out.dat")).unwrap(),
    );
    assert_eq!(split_numbers(&src).0, split_numbers(&src2).0);
    assert_eq!(split_numbers(&dat).0, split_numbers(&dat2).0);
    // The points in program order: inline ones from the .src, declared ones from the .dat.
    let read = |s: &str, dt: &str| -> Vec<(Pose, (i32, i32))> {
        let (inline, declared) = (points(s), points(dt));
        // The .src's first aggregate is the axis target (no X); the .dat's first the tool frame.
        let (mut a, mut b) = (inline.into_iter(), declared.into_iter().skip(1));
        order
            .iter()
            .map(|(_, k)| if k % 4 == 0 { a.next().unwrap() } else { b.next().unwrap() })
            .map(|(p, st)| (base * p, st.unwrap()))
            .collect()
    };
    let (originals, corrected) = (read(&src, &dat), read(&src2, &dat2));
    assert_eq!(originals.len(), n);
    let mut csv = String::from("id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm,qw,qx,qy,qz\n");
    let mut reached = Vec::new();
    for (k, ((t, st), (t2, st2))) in originals.iter().zip(&corrected).enumerate() {
        let tool = tools[order[k].0];
        let q0 = kuka_controller(&(t * tool.inverse()), *st).unwrap_or_else(|| panic!("original {k} on {st:?}"));
        let q1 = kuka_controller(&(t2 * tool.inverse()), *st2).unwrap_or_else(|| panic!("filtered {k} on {st2:?}"));
        reached.push(q1);
        let r = t.rotation.into_inner();
        let p = t.translation.vector;
        let deg: Vec<String> = q0.iter().map(|v| format!("{:.12}", v.to_degrees())).collect();
        csv += &format!(
            "{k},{},{:.9},{:.9},{:.9},{:.12},{:.12},{:.12},{:.12}\n",
            deg.join(","),
            p.x,
            p.y,
            p.z,
            r.w,
            r.i,
            r.j,
            r.k
        );
    }
    // compensate per tool (its --tool is one tool per file).
    let (mut comp, mut filt) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64));
    let lines: Vec<&str> = csv.lines().collect();
    for (h, tool_values) in [TOOL1, TOOL2].iter().enumerate() {
        let rows: Vec<&str> = lines[1..]
            .iter()
            .enumerate()
            .filter(|(k, _)| order[*k].0 == h)
            .map(|(_, l)| *l)
            .collect();
        std::fs::write(d.join(format!("t{h}.csv")), format!("{}\n{}\n", lines[0], rows.join("\n"))).unwrap();
        // --tool takes roll, pitch, yaw: C, B, A.
        let arg = format!(
            "{},{},{},{},{},{}",
            tool_values[0], tool_values[1], tool_values[2], tool_values[5], tool_values[4], tool_values[3]
        );
        ok(
            &d,
            &[
                "compensate",
                "../cal.toml",
                &format!("t{h}.csv"),
                "--tool",
                &arg,
                "--out",
                &format!("c{h}.csv"),
                "--force",
            ],
        );
        let table = kinecal::io::table::read_table(&d.join(format!("c{h}.csv"))).unwrap();
        for row in &table.rows {
            let k = row[0] as usize;
            let q: Vec<f64> = row[1..].iter().map(|v| v.to_radians()).collect();
            let err = |q: &[f64]| {
                let e = kinecal::se3::pose_error(&originals[k].0, &c.reached(q, &tools[h]));
                (kinecal::se3::lin(&e).norm(), kinecal::se3::ang(&e).norm().to_degrees())
            };
            let (ec, e) = (err(&q), err(&reached[k]));
            comp = (comp.0.max(ec.0), comp.1.max(ec.1));
            filt = (filt.0.max(e.0), filt.1.max(e.1));
        }
    }
    eprintln!("KRL, {n} points: max error compensate {comp:?}, filtered {filt:?} (mm, deg)");
    assert!(
        filt.0 <= 1.1 * comp.0 && filt.1 <= 1.1 * comp.1,
        "filtered {filt:?} against compensate's {comp:?}"
    );
    // A TOOL_DATA neither file assigns: one line naming the .src's line, nothing written.
    let e = fails(
        &d,
        &[
            "filter",
            "../cal.toml",
            "weld.src",
            "--nominal",
            "irb120",
            "--out",
            "x.src",
            "--base-data",
            &base_arg,
        ],
    );
    let line = src.lines().position(|l| l.contains("TOOL_DATA[2]")).unwrap() + 1;
    assert!(e.starts_with(&format!("weld.src:{line}: TOOL_DATA[2] is not in the files")), "{e}");
    assert!(!d.join("x.src").exists() && !d.join("x.dat").exists());
}
