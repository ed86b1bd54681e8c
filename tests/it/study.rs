//! The §5.1 simulation study of the 5-DOF paper.
use kinecal::model::presets::pm5::Parasitic;
use kinecal::study::{pm5_study, StudyOptions, SubLoopChoice};

#[test]
fn pm5_study_is_exact_noise_free_and_noise_limited_with_noise() {
    for parasitic in [Parasitic::Physical, Parasitic::NominalGeometry] {
        let opts = StudyOptions {
            draws: 4,
            parasitic,
            ..StudyOptions::default()
        };
        let s = pm5_study(&opts).unwrap();
        assert_eq!(s.rank, if parasitic == Parasitic::Physical { 32 } else { 35 });
        for set in [&s.noise_free.identification_set, &s.noise_free.verification_set] {
            assert!(set.before.position_mean > 0.1, "errors must be visible before calibration");
            // Noise-free: position and tool axis at numerical precision after exact compensation.
            assert!(set.exact.position_max < 1e-6, "{:?}", set.exact);
            assert!(set.exact.axis_max < 1e-6, "{:?}", set.exact);
            // The paper's first-order compensation leaves µm-level errors.
            assert!(set.first_order.position_mean < 0.02);
        }
        assert!(s.noise_free.converged && s.noisy.converged);
        // With noise: of the order of the noise, far below the errors before calibration.
        let v = &s.noisy.verification_set.exact;
        assert!(v.position_mean < 0.04 && v.axis_mean < 0.03, "{v:?}");
        assert_eq!(s.monte_carlo.draws, 4);
        assert!(s.monte_carlo.failures.is_empty());
        assert!(s.monte_carlo.verification_position.mean < 0.04);
        assert!(s.monte_carlo.verification_position.p95 >= s.monte_carlo.verification_position.mean * 0.5);
    }
}

#[test]
fn cli_study_prints_paper_and_kinecal() {
    let out = assert_cmd::Command::cargo_bin("kinecal")
        .unwrap()
        .args(["study", "pm5", "--draws", "2", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["rank"], 32);
    assert_eq!(v["paper"]["before"][0], 0.515);
    assert!(v["noise_free"]["verification_set"]["exact"]["position_max"].as_f64().unwrap() < 1e-6);
}

#[test]
fn paper_sub_loop_choice_keeps_first_order_compensation_working() {
    let opts = StudyOptions {
        draws: 4,
        sub_loop: SubLoopChoice::KeepL4L5,
        ..StudyOptions::default()
    };
    let s = pm5_study(&opts).unwrap();
    assert!(s.identified.iter().any(|n| n == "dl4") && !s.identified.iter().any(|n| n == "dl2"));
    assert!(s.noise_free.verification_set.exact.position_max < 1e-6);
    // First-order compensation close to the exact one with noise.
    let v = &s.noisy.verification_set;
    assert!(v.first_order.position_mean < 1.5 * v.exact.position_mean + 0.005, "{v:?}");
}
