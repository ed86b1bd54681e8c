//! `kinecal filter` on URScript: pose literals in metres and rotation vectors, `set_tcp`, pose
//! variables, `movec`; the controller's branch the nearest solution to where the arm is (from a
//! `movej` joint list, then each previous target). Read back here by independent code.
use crate::cli::ok;
use crate::filter::{calibrated, split_numbers};
use kinecal::model::builtin::irb120;
use kinecal::se3::Pose;
use kinecal::Mechanism;
use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};

/// The tool: 12.5, −8, 135.25 mm, turned 10° about y.
fn tool() -> Pose {
    Pose::from_parts(
        Translation3::new(12.5, -8.0, 135.25),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 10f64.to_radians()),
    )
}

/// A pose from `p[x, y, z, rx, ry, rz]` (metres, rotation vector), by Rodrigues' formula written out.
fn pose_p(v: &[f64]) -> Pose {
    let w = Vector3::new(v[3], v[4], v[5]);
    let t = w.norm();
    let k = if t > 0.0 { w / t } else { Vector3::x() };
    let kx = Matrix3::new(0.0, -k.z, k.y, k.z, 0.0, -k.x, -k.y, k.x, 0.0);
    let r = Matrix3::identity() + kx * t.sin() + kx * kx * (1.0 - t.cos());
    Pose::from_parts(
        Translation3::new(v[0] * 1000.0, v[1] * 1000.0, v[2] * 1000.0),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)),
    )
}

/// Every `p[…]` literal of a text in order, read here.
fn pose_literals(text: &str) -> Vec<Vec<f64>> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(k) = rest.find("p[") {
        let tail = &rest[k + 2..];
        let end = tail.find(']').unwrap();
        out.push(tail[..end].split(',').map(|x| x.trim().parse().unwrap()).collect());
        rest = &tail[end..];
    }
    out
}

/// The controller: the nominal inverse kinematics from where the arm is, each joint taking the
/// turn nearest it.
fn nearest_solution(flange: &Pose, from: &[f64]) -> Vec<f64> {
    let arm = irb120();
    let mut q = arm.inverse(flange, Some(from)).unwrap();
    for (v, f) in q.iter_mut().zip(from) {
        *v += ((f - *v) / std::f64::consts::TAU).round() * std::f64::consts::TAU;
    }
    assert!((arm.forward(&q).unwrap().translation.vector - flange.translation.vector).norm() < 1e-7);
    q
}

fn fmt_p(p: &Pose) -> String {
    let t = p.translation.vector / 1000.0;
    let r = kinecal::se3::so3_log(&p.rotation);
    format!("p[{:.6}, {:.6}, {:.6}, {:.6}, {:.6}, {:.6}]", t.x, t.y, t.z, r.x, r.y, r.z)
}

/// A URScript program of 53 targets (a joint move first, pose variables, a circular move, a
/// run-time pose), filtered: the prototype driven by the nominal controller to the filtered
/// poses reaches the originals within 1.1× the error of `compensate`'s commands.
#[test]
fn urscript_filtered_reaches_the_targets_as_compensate_does() {
    let c = calibrated();
    let d = c.dir.join("urscript");
    std::fs::create_dir_all(&d).unwrap();
    let tool = tool();
    let arm = irb120();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
    let lim: [(f64, f64); 6] = [
        (-100.0, 100.0),
        (-30.0, 60.0),
        (-70.0, 40.0),
        (-140.0, 140.0),
        (25.0, 100.0),
        (-250.0, 250.0),
    ];
    let mut q: Vec<f64> = [20.0, 10.0, -10.0, 30.0, 50.0, 40.0].map(f64::to_radians).to_vec();
    let start = q.clone();
    let mut prog = String::from("def pick():\n  # tool and targets (comments kept: 0.5 m)\n");
    let r = kinecal::se3::so3_log(&tool.rotation);
    prog += &format!("  set_tcp(p[0.0125, -0.008, 0.13525, {:.9}, {:.9}, {:.9}])\n", r.x, r.y, r.z);
    let joints: Vec<String> = start.iter().map(|v| format!("{v:.9}")).collect();
    prog += &format!("  movej([{}], a=1.4, v=1.05)\n", joints.join(", "));
    let n = 53;
    for k in 0..n {
        for (j, (lo, hi)) in lim.iter().enumerate() {
            let step: f64 = rng.random_range(-12.0f64..12.0).to_radians();
            q[j] = (q[j] + step).clamp(lo.to_radians(), hi.to_radians());
        }
        let p = fmt_p(&(arm.forward(&q).unwrap() * tool));
        match k % 4 {
            0 => prog += &format!("  wp{k} = {p}\n  movel(wp{k}, a=1.2, v=0.25, r=0.001)\n"),
            1 => prog += &format!("  movel({p}, a=1.2, v=0.25)\n"),
            2 => prog += &format!("  movej({p}, a=1.4, v=1.05, r=0.01)\n"),
            _ => {}
        }
        if k % 4 == 3 {
            // The via point of a circle (this target), its end point the next.
            prog += &format!("  via{k} = {p}\n");
        }
        if k % 4 == 0 && k > 0 {
            let via = format!("via{}", k - 1);
            prog = prog.replacen(
                &format!("  movel(wp{k}, a=1.2, v=0.25, r=0.001)\n"),
                &format!("  movec({via}, wp{k}, a=1.2, v=0.25, r=0.05, mode=0)\n"),
                1,
            );
        }
    }
    prog += "  movel(pose_trans(wp0, p[0, 0, 0.05, 0, 0, 0]), a=1.2, v=0.25)\nend\npick()\n";
    std::fs::write(d.join("pick.script"), &prog).unwrap();
    let out = ok(
        &d,
        &[
            "filter",
            "../cal.toml",
            "pick.script",
            "--nominal",
            "irb120",
            "--out",
            "filtered.script",
            "--report",
        ],
    );
    eprintln!("{}", out.lines().take(3).collect::<Vec<_>>().join("\n"));
    let filtered = std::fs::read_to_string(d.join("filtered.script")).unwrap();
    assert_eq!(
        split_numbers(&prog).0,
        split_numbers(&filtered).0,
        "the text outside the numbers changed"
    );
    // The targets in the order the moves reach them: the literals but the tool's (first) and
    // the run-time offset's (last); a via point is reached before its end point.
    let targets = |text: &str| -> Vec<Pose> {
        let lits = pose_literals(text);
        lits[1..lits.len() - 1].iter().map(|v| pose_p(v)).collect()
    };
    let (originals, corrected) = (targets(&prog), targets(&filtered));
    assert_eq!(originals.len(), n);
    // The controller from the joint move on, and compensate seeded with its joint values.
    let (mut from, mut from2) = (start.clone(), start.clone());
    let mut csv = String::from("id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm,qw,qx,qy,qz\n");
    let mut reached_filtered = Vec::new();
    for (k, (t, t2)) in originals.iter().zip(&corrected).enumerate() {
        let q0 = nearest_solution(&(t * tool.inverse()), &from);
        from = q0.clone();
        let q1 = nearest_solution(&(t2 * tool.inverse()), &from2);
        from2 = q1.clone();
        reached_filtered.push(q1);
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
    std::fs::write(d.join("targets.csv"), csv).unwrap();
    let tool_arg = "12.5,-8,135.25,0,10,0";
    ok(
        &d,
        &["compensate", "../cal.toml", "targets.csv", "--tool", tool_arg, "--out", "cmd.csv"],
    );
    let commands: Vec<Vec<f64>> = kinecal::io::table::read_table(&d.join("cmd.csv"))
        .unwrap()
        .rows
        .iter()
        .map(|r| r[1..].iter().map(|v| v.to_radians()).collect())
        .collect();
    let err = |a: &Pose, b: &Pose| {
        let e = kinecal::se3::pose_error(a, b);
        (kinecal::se3::lin(&e).norm(), kinecal::se3::ang(&e).norm().to_degrees())
    };
    let (mut comp, mut filt) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64));
    for (k, t) in originals.iter().enumerate() {
        let e = err(t, &c.reached(&reached_filtered[k], &tool));
        let ec = err(t, &c.reached(&commands[k], &tool));
        filt = (filt.0.max(e.0), filt.1.max(e.1));
        comp = (comp.0.max(ec.0), comp.1.max(ec.1));
    }
    eprintln!("URScript, {n} targets: max error compensate {comp:?}, filtered {filt:?} (mm, deg)");
    assert!(
        filt.0 <= 1.1 * comp.0 && filt.1 <= 1.1 * comp.1,
        "filtered {filt:?} against compensate's {comp:?}"
    );
}

/// `--joints`: a joint list `movej([…])` taught on the nominal controller names the tool pose
/// `FK_nominal(q)`; corrected, the prototype at the joint values written reaches that pose far
/// better than at the values taught, and nothing else of the program changes.
#[test]
fn urscript_joint_lists_corrected_with_joints() {
    let c = calibrated();
    let d = c.dir.join("urscript-joints");
    std::fs::create_dir_all(&d).unwrap();
    let tool = tool();
    let r = kinecal::se3::so3_log(&tool.rotation);
    let taught: Vec<Vec<f64>> = [[20.0, 10.0, -10.0, 30.0, 50.0, 40.0], [-35.0, 25.0, -30.0, -60.0, 70.0, 100.0]]
        .iter()
        .map(|q| q.map(f64::to_radians).to_vec())
        .collect();
    let mut prog = format!(
        "def j():\n  set_tcp(p[0.0125, -0.008, 0.13525, {:.9}, {:.9}, {:.9}])\n",
        r.x, r.y, r.z
    );
    for q in &taught {
        let v: Vec<String> = q.iter().map(|x| format!("{x:.6}")).collect();
        prog += &format!("  movej([{}], a=1.4, v=1.05) # taught\n", v.join(", "));
    }
    prog += "end\n";
    std::fs::write(d.join("j.script"), &prog).unwrap();
    let args = ["filter", "../cal.toml", "j.script", "--nominal", "irb120", "--out"];
    let kept = ok(&d, &[&args[..], &["kept.script"]].concat());
    assert!(kept.contains("a joint target is left as it is"), "{kept}");
    assert_eq!(std::fs::read_to_string(d.join("kept.script")).unwrap(), prog);
    ok(&d, &[&args[..], &["joints.script", "--joints"]].concat());
    let out = std::fs::read_to_string(d.join("joints.script")).unwrap();
    assert_eq!(split_numbers(&prog).0, split_numbers(&out).0);
    let lists: Vec<Vec<f64>> = out
        .lines()
        .filter(|l| l.contains("movej(["))
        .map(|l| {
            let inner = &l[l.find("([").unwrap() + 2..l.find(']').unwrap()];
            inner.split(',').map(|x| x.trim().parse().unwrap()).collect()
        })
        .collect();
    let arm = irb120();
    for (q, q2) in taught.iter().zip(&lists) {
        let target = arm.forward(q).unwrap() * tool;
        let e = |x: &[f64]| kinecal::se3::lin(&kinecal::se3::pose_error(&target, &c.reached(x, &tool))).norm();
        let (before, after) = (e(q), e(q2));
        eprintln!("URScript joint list: the prototype {before:.4} mm from FK_nominal(q) at q taught, {after:.4} mm at q corrected");
        assert!(before > 0.1 && after < 0.05 && after < before / 5.0, "{before} → {after}");
    }
}
