//! `kinecal check --plan`: the configurations of a check chosen to tell patterns apart.
use super::drift_check::scenario::{calibrated, configurations, drifted, machine, measure, Drift};
use kinecal::drift::{check, plan_check_poses, CheckOptions, CheckPlanOptions};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

#[test]
fn planned_check_poses_name_apart_better_than_unplanned_ones_and_check_as_any() {
    let m = machine("pm5", 1000);
    let zero = vec![0.0; m.file.inputs().len()];
    let prior = calibrated(&m, &*m.truth, &zero, 60, 2000);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let candidates = configurations(&m, 200, &mut rng);
    let opts = CheckPlanOptions::default();
    let plan = plan_check_poses(&prior, &candidates, &opts).unwrap();
    assert_eq!(plan.selected.len(), 5);
    let mut distinct = plan.selected.clone();
    distinct.sort_unstable();
    distinct.dedup();
    assert_eq!(distinct.len(), 5, "{:?}", plan.selected);
    assert!(plan.selected.iter().all(|&i| i < candidates.len()));
    // The chosen five name apart better than the first five (the objective's own figure), and
    // the call is deterministic.
    assert!(
        plan.wrong_names < 0.9 * plan.wrong_names_unplanned,
        "{} vs {}",
        plan.wrong_names,
        plan.wrong_names_unplanned
    );
    assert!(
        plan.patterns > 20 && plan.pairs > 0,
        "{} patterns, {} pairs",
        plan.patterns,
        plan.pairs
    );
    let again = plan_check_poses(&prior, &candidates, &opts).unwrap();
    assert_eq!(again.selected, plan.selected);
    // The least apart pairs come first.
    assert!(plan.weakest.windows(2).all(|w| w[0].chi2 <= w[1].chi2));
    // The planned poses are poses like any: unchanged, still calibrated; a longer rod, drifted.
    let chosen: Vec<Vec<f64>> = plan.selected.iter().map(|&i| candidates[i].clone()).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let same = measure(&*m.truth, &zero, &chosen, Some(&m.noise), &mut rng);
    assert!(!check(&prior, &same, &CheckOptions::default()).unwrap().drifted);
    let (truth, shift) = drifted(&m, Drift::Parameter { name: "dl1", amount: 0.1 }, &mut rng);
    let five = measure(&*truth, &shift, &chosen, Some(&m.noise), &mut rng);
    assert!(check(&prior, &five, &CheckOptions::default()).unwrap().drifted);
    // Asking for more than there are candidates is the caller's mistake.
    let few = CheckPlanOptions { n: 300, ..opts };
    assert!(matches!(
        plan_check_poses(&prior, &candidates, &few),
        Err(kinecal::CalibError::InvalidOption(_))
    ));
}

#[test]
fn cli_plans_a_check_whose_file_commands_the_machine_and_checks() {
    use assert_cmd::Command;
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| {
        Command::cargo_bin("kinecal")
            .unwrap()
            .current_dir(dir.path())
            .args(args)
            .output()
            .unwrap()
    };
    let ok = |args: &[&str]| {
        let out = run(args);
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let noise = ["--noise-mm", "0.02", "--noise-deg", "0.02"];
    let mut sim = vec!["simulate", "irb120", "--poses", "60", "--error-mm", "0.2", "--error-deg", "0.02"];
    sim.extend(noise);
    sim.extend(["--seed", "1", "-o", "cal.csv", "--truth", "truth.toml"]);
    ok(&sim);
    let mut id = vec!["identify", "irb120", "cal.csv", "-o", "cal.toml"];
    id.extend(noise);
    ok(&id);
    let text = ok(&["check", "cal.toml", "--plan", "5", "--candidates", "300", "--out", "five.csv"]);
    assert!(text.contains("5 check configurations chosen among 300 candidates"), "{text}");
    assert!(text.contains("expected wrong names per pattern"), "{text}");
    // Read back with the csv crate alone: the inputs in degrees, within the IRB 120's limits, the
    // tool pose the calibrated model reaches there.
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_path(dir.path().join("five.csv"))
        .unwrap();
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(header[0], "id");
    assert_eq!(&header[1..7], &["q1_deg", "q2_deg", "q3_deg", "q4_deg", "q5_deg", "q6_deg"]);
    assert_eq!(&header[7..], &["x_mm", "y_mm", "z_mm", "roll_deg", "pitch_deg", "yaw_deg"]);
    let cal = kinecal::io::model_file::ModelFile::load(&dir.path().join("cal.toml")).unwrap();
    let model = cal.build();
    let rows: Vec<csv::StringRecord> = reader.records().map(|r| r.unwrap()).collect();
    assert_eq!(rows.len(), 5);
    for r in &rows {
        let v: Vec<f64> = r.iter().map(|x| x.parse().unwrap()).collect();
        let q: Vec<f64> = v[1..7].iter().map(|d| d.to_radians()).collect();
        for (spec, x) in cal.inputs().iter().zip(&q) {
            let (lo, hi) = spec.limits.unwrap();
            assert!(*x >= lo - 1e-6 && *x <= hi + 1e-6, "{} = {x} beyond its limits", spec.name);
        }
        let p = model.forward(&q).unwrap().translation.vector;
        assert!((p.x - v[7]).abs() < 1e-5 && (p.y - v[8]).abs() < 1e-5 && (p.z - v[9]).abs() < 1e-5);
    }
    // Measured there on the machine as calibrated: still calibrated.
    let mut again = vec!["simulate", "truth.toml", "--at", "five.csv", "--error-mm", "0", "--error-deg", "0"];
    again.extend(noise);
    again.extend(["--seed", "2", "-o", "again.csv"]);
    ok(&again);
    let verdict = ok(&["check", "cal.toml", "again.csv"]);
    assert!(verdict.contains("verdict: still calibrated"), "{verdict}");
    // Not overwritten without --force; neither data nor --plan is a usage mistake (exit 1).
    let out = run(&["check", "cal.toml", "--plan", "5", "--candidates", "300", "--out", "five.csv"]);
    assert_eq!(out.status.code(), Some(1));
    let out = run(&["check", "cal.toml"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--plan"));
}
