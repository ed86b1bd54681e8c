//! Measurement planning on the 5-DOF preset: candidates in its platform workspace, `kinecal plan
//! --preset pm5` end to end, planned configurations in the §5.1 study, the design Monte-Carlo.
use approx::assert_relative_eq;
use kinecal::design::{self, CandidateFilter, CandidateJacobians, Sampling};
use kinecal::measure::Noise;
use kinecal::model::closed::ConstraintSystem;
use kinecal::model::presets::pm5::{Parasitic, Pm5};
use kinecal::model::Mechanism;
use kinecal::se3;
use kinecal::simulate::ObservationKind;
use kinecal::study::{pm5_design_study, pm5_plan, pm5_study, DesignStudyOptions, PlanOptions, StudyOptions};

fn pm5_filter() -> CandidateFilter {
    CandidateFilter {
        input_limits: Some(Pm5::mechanism(Parasitic::Physical).system().strokes()),
        max_condition: Some(100.0),
        ..Default::default()
    }
}

#[test]
fn checking_forward_kinematics_on_the_chosen_set_gives_the_plan_of_checking_every_sample() {
    let mech = Pm5::mechanism(Parasitic::Physical);
    let ws = mech.system().workspace();
    let sampling = Sampling::Halton { n: 600, seed: 5 };
    let (every, _) = design::candidates_in_platform_box(&mech, &ws, &sampling, &pm5_filter(), None).unwrap();
    let deferred = CandidateFilter {
        check_forward: false,
        ..pm5_filter()
    };
    let (lazy, _) = design::candidates_in_platform_box(&mech, &ws, &sampling, &deferred, None).unwrap();
    assert_eq!(every.len(), lazy.len());
    let opts = design::PlanOptions::default();
    let a = design::plan(&mech, &every, &opts, None, &mut |_| {}).unwrap();
    let b = design::plan(&mech, &lazy, &opts, None, &mut |_| {}).unwrap();
    assert_eq!(a.selection.selected, b.selection.selected);
    assert!(b.set_aside.is_empty());
}

#[test]
fn pm5_candidates_are_reachable_in_stroke_and_round_trip() {
    let mech = Pm5::mechanism(Parasitic::Physical);
    let mut ws = mech.system().workspace();
    // Enlarge the box in z beyond the strokes so that some samples must be rejected.
    ws.max[2] = 650.0;
    let (cands, gen) = design::candidates_in_platform_box(&mech, &ws, &Sampling::Halton { n: 120, seed: 3 }, &pm5_filter(), None).unwrap();
    let r = gen.report;
    assert_eq!(r.sampled, 120);
    assert_eq!(r.kept + r.unreachable + r.out_of_limits + r.near_singular + r.rejected, 120);
    assert!(r.kept > 30 && r.kept < 120, "{r:?}");
    assert!(gen.condition_min >= 1.0 && gen.condition_max <= 100.0, "{gen:?}");
    let strokes = mech.system().strokes();
    for c in &cands {
        assert!(c.q.iter().zip(&strokes).all(|(v, (a, b))| v >= a && v <= b));
        // FK∘IK: the forward kinematics from home reaches the candidate's target.
        let t = mech.forward(&c.q).unwrap();
        let e = se3::pose_error(&t, &c.target);
        assert!(se3::lin(&e).norm() < 1e-6 && se3::ang(&e).norm() < 1e-8, "{e:?}");
        // The commanded coordinates lie in the box (γ is parasitic).
        let x = mech.platform_of_tool(&c.target);
        assert!(x[0].abs() <= 50.0 + 1e-6 && x[1].abs() <= 50.0 + 1e-6 && x[2] >= 350.0 - 1e-6 && x[2] <= 650.0 + 1e-6);
        assert!(x[3].abs() <= 5f64.to_radians() + 1e-9 && x[4].abs() <= 5f64.to_radians() + 1e-9);
    }
    // A condition bound below the workspace's minimum rejects everything as near-singular.
    let strict = CandidateFilter {
        max_condition: Some(1.0),
        ..pm5_filter()
    };
    let (none, g) = design::candidates_in_platform_box(
        &mech,
        &mech.system().workspace(),
        &Sampling::Halton { n: 10, seed: 3 },
        &strict,
        None,
    )
    .unwrap();
    assert!(none.is_empty());
    assert_eq!(g.report.near_singular, 10);
    // γ is parasitic: a range for it is an error.
    let mut bad = mech.system().workspace();
    bad.max[5] = 0.1;
    assert!(design::candidates_in_platform_box(&mech, &bad, &Sampling::Halton { n: 4, seed: 1 }, &pm5_filter(), None).is_err());
}

#[test]
fn actuator_condition_matches_finite_differences() {
    let mech = Pm5::mechanism(Parasitic::Physical);
    let x = [12.0, -20.0, 380.0, 0.03, -0.05, 0.0];
    let q = mech.inputs_for(&x).unwrap();
    let xs = mech.platform_pose(&q, None).unwrap();
    let c = design::actuator_condition(&mech, &xs, &q, 100.0).unwrap();
    // ∂X/∂q by central differences of the forward kinematics.
    let h = 1e-5;
    let mut m = nalgebra::DMatrix::zeros(5, 5);
    for j in 0..5 {
        let mut qp = q.clone();
        qp[j] += h;
        let a = mech.platform_pose(&qp, Some(&xs)).unwrap();
        qp[j] -= 2.0 * h;
        let b = mech.platform_pose(&qp, Some(&xs)).unwrap();
        for r in 0..5 {
            m[(r, j)] = (a[r] - b[r]) / (2.0 * h) * if r < 3 { 1.0 } else { 100.0 };
        }
    }
    let sv = kinecal::identifiability::singular_values(&m);
    assert_relative_eq!(c, sv[0] / sv[4], max_relative = 1e-5);
}

#[test]
fn plan_command_on_pm5_writes_reachable_configurations_with_their_index() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan.csv");
    let res = assert_cmd::Command::cargo_bin("kinecal")
        .unwrap()
        .args([
            "plan",
            "--preset",
            "pm5",
            "--candidates",
            "300",
            "-n",
            "12",
            "--method",
            "sffs",
            "--criterion",
            "o2",
            "--seed",
            "5",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let stdout = String::from_utf8_lossy(&res.stdout);
    assert!(stdout.contains("pm5") && stdout.contains("O_T"), "{stdout}");
    let text = std::fs::read_to_string(&out).unwrap();
    let table = kinecal::io::table::parse_table(&out, &text).unwrap();
    assert_eq!(table.len(), 12);
    let mech = Pm5::mechanism(Parasitic::Physical);
    let col = |n: &str| table.values(n).unwrap();
    let (g, x, y, z) = (
        ["g1_mm", "g2_mm", "g3_mm", "g4_mm", "g5_mm"].map(col),
        col("x_mm"),
        col("y_mm"),
        col("z_mm"),
    );
    for i in 0..12 {
        let q: Vec<f64> = g.iter().map(|c| c[i]).collect();
        mech.check_strokes(&q).unwrap();
        let t = mech.forward(&q).unwrap().translation.vector;
        assert!((t.x - x[i]).abs() < 1e-5 && (t.y - y[i]).abs() < 1e-5 && (t.z - z[i]).abs() < 1e-5);
    }
    // The index in the header against a direct SVD of the same candidates' scaled blocks.
    let (cands, _) = design::candidates_in_platform_box(
        &mech,
        &mech.system().workspace(),
        &Sampling::Halton { n: 300, seed: 5 },
        &pm5_filter(),
        None,
    )
    .unwrap();
    let noise = Noise::default();
    let cols = design::identifiable_columns(
        &mech,
        &cands,
        ObservationKind::Pose,
        &noise,
        None,
        200,
        kinecal::identifiability::DEFAULT_RANK_TOLERANCE,
    )
    .unwrap();
    let blocks = CandidateJacobians::build(&mech, &cands, ObservationKind::Pose, &noise, &cols, None).unwrap();
    let numbers = text
        .lines()
        .find_map(|l| l.strip_prefix("# candidate numbers: "))
        .expect("candidate numbers comment");
    let chosen: Vec<usize> = numbers.split_whitespace().map(|v| v.parse().unwrap()).collect();
    for (k, &i) in chosen.iter().enumerate() {
        assert_relative_eq!(cands[i].q[0], g[0][k], epsilon = 1e-6);
    }
    let sv = kinecal::identifiability::singular_values(&blocks.stacked(&chosen));
    let o2 = sv.last().unwrap() / sv[0];
    let header = text.lines().nth(1).unwrap();
    let written: f64 = header.split("O2 = ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    assert_relative_eq!(o2, written, max_relative = 1e-5);
}

#[test]
fn planned_configurations_drive_the_study_and_beat_random_sets() {
    let plan = pm5_plan(
        &PlanOptions {
            candidates: 400,
            ..PlanOptions::default()
        },
        &[(design::SelectionMethod::Sffs, design::Criterion::O2)],
    )
    .unwrap();
    assert_eq!(plan.sets[0].inputs.len(), 30);
    let study = pm5_study(&StudyOptions {
        draws: 2,
        planned: Some(plan.sets[0].inputs.clone()),
        ..StudyOptions::default()
    })
    .unwrap();
    // Noise-free, the planned set identifies exactly too.
    assert!(study.noise_free.verification_set.exact.position_max < 1e-6);
    assert!(study.noisy.verification_set.exact.position_mean < 0.05);
    // A wrong-sized plan is refused.
    assert!(pm5_study(&StudyOptions {
        draws: 0,
        identification: 20,
        planned: Some(plan.sets[0].inputs.clone()),
        ..StudyOptions::default()
    })
    .is_err());
    let d = pm5_design_study(
        plan,
        &DesignStudyOptions {
            draws: 6,
            verification: 10,
            ..DesignStudyOptions::default()
        },
    )
    .unwrap();
    assert_eq!(d.rows.len(), 2);
    assert!(d.rows.iter().all(|r| r.failures == 0));
    let (opt, rnd) = (&d.rows[0], &d.rows[1]);
    assert_eq!(rnd.set, "random");
    assert!(opt.o2 > rnd.o2, "{opt:?} {rnd:?}");
    assert!(opt.position.mean < rnd.position.mean, "{opt:?} {rnd:?}");
    assert!(opt.beats_random > 0.5 && rnd.beats_random == 0.5, "{opt:?}");
}

#[test]
fn plan_json_reports_the_chosen_set_and_its_indices() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan.csv");
    let res = assert_cmd::Command::cargo_bin("kinecal")
        .unwrap()
        .args([
            "plan",
            "--model",
            "pm5",
            "--candidates",
            "300",
            "-n",
            "10",
            "--method",
            "greedy",
            "--json",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let v: serde_json::Value = serde_json::from_slice(&res.stdout).expect("stdout is only JSON");
    assert_eq!(v["mechanism"], "pm5");
    assert_eq!(v["configurations"], 10);
    assert_eq!(v["chosen_candidates"].as_array().unwrap().len(), 10);
    assert_eq!(v["identifiable_parameters"], 32);
    let o2 = v["indices"]["o2"].as_f64().unwrap();
    assert!(o2 > 0.0 && (v["indices"]["o_t"].as_f64().unwrap() * o2 - 1.0).abs() < 1e-9);
    assert!(out.exists());
}

#[test]
fn plan_sampled_on_the_preset_is_its_platform_candidates_then_plan() {
    use kinecal::design::{CandidateSampling, PlanEvent, Points, PoseRanges, Region, SampledSpace, SelectOptions};
    let file = kinecal::io::builtin::model_file("pm5").unwrap();
    let sampling = CandidateSampling {
        region: Region::Poses(PoseRanges::default()),
        points: Points::Halton { n: 400, seed: 5 },
        max_condition: None,
    };
    let opts = design::PlanOptions {
        select: SelectOptions {
            n: 10,
            ..Default::default()
        },
        ..Default::default()
    };
    let events = std::sync::Mutex::new(Vec::new());
    let record = |e: PlanEvent| {
        let name = match e {
            PlanEvent::Sampling { space, .. } => format!("sampling {}", matches!(space, SampledSpace::Platform { .. })),
            PlanEvent::Generated(_) => "generated".into(),
            PlanEvent::Jacobians { blocks } => format!("jacobians {blocks}"),
            PlanEvent::Done(_) => return,
            PlanEvent::Step(_) => "step".into(),
        };
        let mut ev = events.lock().unwrap();
        if ev.last() != Some(&name) {
            ev.push(name);
        }
    };
    let sp = design::plan_sampled(&file, &sampling, &opts, Some(&record)).unwrap();
    // By hand: the preset's workspace, strokes, condition ≤ 100, FK∘IK left to the plan.
    let mech = Pm5::mechanism(Parasitic::Physical);
    let filter = CandidateFilter {
        check_forward: false,
        ..pm5_filter()
    };
    let (cands, gen) = design::candidates_in_platform_box(
        &mech,
        &mech.system().workspace(),
        &Sampling::Halton { n: 400, seed: 5 },
        &filter,
        None,
    )
    .unwrap();
    assert_eq!(sp.candidates.candidates, cands);
    assert_eq!(sp.candidates.report, gen.report);
    assert_eq!(sp.candidates.condition, Some((gen.condition_min, gen.condition_max)));
    let p = design::plan(&mech, &cands, &opts, None, &mut |_| {}).unwrap();
    assert_eq!(sp.plan.selection.selected, p.selection.selected);
    assert_eq!(sp.angle_inputs, vec![false; 5]);
    let n = cands.len();
    assert_eq!(
        *events.lock().unwrap(),
        [
            "sampling true".to_string(),
            "generated".into(),
            format!("jacobians {n}"),
            "step".into()
        ]
    );
}
