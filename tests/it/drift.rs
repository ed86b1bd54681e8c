//! Staying calibrated: what a calibrated model file carries for a later check or update (the
//! covariance of its identified parameters, the noise), and the accuracy it predicts.
use crate::registration::{data_set, tool, tracker, Kind};
use kinecal::calibrate::{calibrate, Calibration, CalibrationOptions};
use kinecal::io::builtin;
use kinecal::io::model_file::{Held, ModelFile};
use kinecal::measure::Noise;
use kinecal::model::framed::Framed;
use kinecal::simulate::{random_configurations, virtual_prototype};
use kinecal::Mechanism;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;

/// A virtual IRB 120 (0.5 mm / 0.1° errors, seed 7) seen by a tracker 2 m away through a tool
/// 150 mm out, calibrated from `poses` noisy poses.
fn calibrated_irb120(poses: usize) -> Calibration {
    let file = builtin::model_file("irb120").unwrap();
    let nominal = file.build();
    let free = file.free_indices().unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (proto, _) = virtual_prototype(&nominal, &free, 0.5, 0.1f64.to_radians(), &mut rng);
    let truth = Framed::new(proto, tracker(), tool());
    let qs = random_configurations(&*nominal, &file.inputs(), poses, &mut rng).unwrap();
    let noise = Noise::default();
    let data = data_set("ident.csv", &truth, &qs, Kind::Pose, Some(noise), 1);
    let opts = CalibrationOptions {
        noise,
        ..CalibrationOptions::default()
    };
    calibrate(&file, &data, None, &opts).unwrap()
}

#[test]
fn calibrated_model_file_carries_the_covariance() {
    let cal = calibrated_irb120(40);
    let text = cal.model_file.to_toml().unwrap();
    // Read by a plain TOML reader, not by ModelFile.
    let doc: toml::Table = text.parse().unwrap();
    let cov = doc["covariance"].as_table().expect("a [covariance] section");
    let names: Vec<&str> = cov["parameters"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    let units: Vec<&str> = cov["units"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    let matrix: Vec<Vec<f64>> = cov["matrix"]
        .as_array()
        .unwrap()
        .iter()
        .map(|row| row.as_array().unwrap().iter().map(|v| v.as_float().unwrap()).collect())
        .collect();
    let held = cov["held"].as_table().unwrap();
    let params = cal.identification.model.params();
    let index = |name: &str| params.iter().position(|p| p.name == name).unwrap();
    let c = &cal.identification.covariance;
    assert!(names.len() > 20, "{} identified parameters", names.len());
    assert_eq!(names.len() + held.len(), params.len(), "every parameter identified or held");
    assert_eq!(matrix.len(), names.len());
    for (i, a) in names.iter().enumerate() {
        assert_eq!(matrix[i].len(), names.len());
        let p = &params[index(a)];
        assert_eq!(units[i], p.unit.symbol(), "{a}");
        assert!(matrix[i][i] > 0.0, "{a}: variance {}", matrix[i][i]);
        assert!(c[(index(a), index(a))] > 0.0, "{a} identified");
        let written = &cal.model_file.covariance.as_ref().unwrap().matrix;
        for j in 0..names.len() {
            // The numbers read back bit for bit.
            assert_eq!(matrix[i][j], written[(i, j)], "({a}, {})", names[j]);
        }
    }
    // In the coordinates of the model the file builds: it predicts the covariance of the tool
    // pose that the identification predicts with its own model, at configurations of neither.
    let built = cal.model_file.build();
    let over: Vec<String> = built.params().into_iter().map(|p| p.name).collect();
    let file_cov = cal.model_file.covariance.as_ref().unwrap().over(&over);
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let qs = random_configurations(&*built, &cal.model_file.inputs(), 20, &mut rng).unwrap();
    let pose_cov = |m: &dyn Mechanism, p: &nalgebra::DMatrix<f64>, q: &[f64]| {
        let (t, a) = m.forward_with_jacobian(q).unwrap();
        let j = kinecal::measure::residual_jacobian(&kinecal::measure::Observation::Pose(t), &t, &a);
        &j * p * j.transpose()
    };
    let (mut worst, mut uncarried) = (0.0f64, 0.0f64);
    for q in &qs {
        let fitted = pose_cov(&*cal.identification.model, c, q);
        let scale = fitted.norm();
        worst = worst.max((pose_cov(&*built, &file_cov, q) - &fitted).norm() / scale);
        uncarried = uncarried.max((pose_cov(&*built, c, q) - &fitted).norm() / scale);
    }
    eprintln!("tool-pose covariance from the file against the identification's: {worst:.2e} (taken uncarried: {uncarried:.2e})");
    assert!(worst < 1e-6, "{worst:e}");
    // Held parameters have no variance in the identification either, and a stated reason.
    for (name, why) in held {
        let k = index(name);
        assert_eq!(c[(k, k)], 0.0, "{name} held but with variance");
        assert!(["fixed", "redundant", "weak", "placement"].contains(&why.as_str().unwrap()));
    }
    assert_eq!(cov["sigma0"].as_float().unwrap(), cal.identification.sigma0);
    // The stated noise beside it, in the file's units (mm, deg).
    let noise = doc["noise"].as_table().unwrap();
    assert_eq!(noise["position"].as_float().unwrap(), Noise::default().position);

    // Read back by ModelFile: the same numbers, and written again the same text.
    let back = ModelFile::load_str(Path::new("cal.toml"), &text).unwrap();
    let covariance = back.covariance.as_ref().unwrap();
    assert_eq!(covariance.names, names);
    let built: Vec<String> = back.build().params().into_iter().map(|p| p.name).collect();
    assert_eq!(covariance.over(&built), file_cov);
    assert!(covariance.held.iter().any(|(_, h)| *h == Held::Redundant));
    // Written again, the same text byte for byte (the covariance is kept in the units it is
    // written in, so every number reads back bit for bit; the angles of the poses are written so
    // that the rotations rebuilt from them give them again).
    assert_eq!(back.to_toml().unwrap(), text);
}

#[test]
fn a_covariance_that_does_not_fit_the_model_is_one_line() {
    let cal = calibrated_irb120(30);
    let text = cal.model_file.to_toml().unwrap();
    let load = |t: &str| ModelFile::load_str(Path::new("cal.toml"), t).map_err(|e| e.to_string());
    let first = cal.model_file.covariance.as_ref().unwrap().names[0].clone();
    let renamed = text.replacen(&format!("parameters = [\"{first}\""), "parameters = [\"nonesuch\"", 1);
    let e = load(&renamed).unwrap_err();
    assert!(
        e.contains("'nonesuch' is no parameter of this model") && e.contains("cal.toml:"),
        "{e}"
    );
    let unit = text.replacen("units = [\"mm\"", "units = [\"rad\"", 1);
    let e = load(&unit).unwrap_err();
    assert!(e.contains("not that parameter's unit"), "{e}");
    let start = text.find("matrix = [\n").unwrap() + "matrix = [\n".len();
    let end = start + text[start..].find('\n').unwrap() + 1;
    let short = format!("{}{}", &text[..start], &text[end..]);
    let e = load(&short).unwrap_err();
    assert!(e.contains("covariance.matrix: expected"), "{e}");
}

/// The predicted σ against the spread of repeated calibrations (`kinecal::studies::predicted`;
/// `examples/predicted_spread.rs` runs the same with 200 draws).
fn spread_matches(model: &str, draws: usize) {
    use kinecal::studies::predicted::{predicted_against_spread, SpreadOptions};
    let check = predicted_against_spread(&SpreadOptions::new(model, draws)).unwrap();
    assert_eq!(check.poses.len(), 50);
    assert!(
        check.draws >= draws * 9 / 10,
        "{model}: {} of {draws} draws calibrated",
        check.draws
    );
    let (lo, hi) = check.ratio_range();
    let mean = check.poses.iter().map(|p| p.ratio()).sum::<f64>() / 50.0;
    eprintln!(
        "{model}, {} draws: predicted/observed position σ {lo:.3}..{hi:.3}, mean {mean:.3}",
        check.draws
    );
    // With few draws an observed spread is itself uncertain by about 1/√(2·draws·3) per pose:
    // the mean over the poses within 20 %, each pose within 40 %.
    assert!((mean - 1.0).abs() <= 0.2, "{model}: mean ratio {mean}");
    assert!(lo >= 0.6 && hi <= 1.4, "{model}: ratios {lo}..{hi}");
    for p in &check.poses {
        assert!(p.predicted_mm > 0.0 && p.observed_mm > 0.0);
    }
}

#[test]
fn predicted_accuracy_matches_the_spread_of_calibrations_irb120() {
    spread_matches("irb120", 40);
}

#[test]
fn predicted_accuracy_matches_the_spread_of_calibrations_pm5() {
    spread_matches("pm5", 30);
}

#[test]
fn validate_predict_writes_the_accuracy_over_a_box_and_a_file() {
    use crate::cli::{fails, ok};
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ok(d, &["model", "export", "irb120", "--out", "m.toml"]);
    crate::cli::simulate(d, "m.toml", 40, 10, 3, 0.02, &["--error-mm", "0.5", "--error-deg", "0.1"]);
    ok(d, &["identify", "m.toml", "d.csv", "--out", "cal.toml", "--report", "r.html"]);
    let out = ok(
        d,
        &["validate", "cal.toml", "--predict", "box", "--points", "30", "--out", "box.csv"],
    );
    assert!(
        out.contains("predicted accuracy at 30 configurations") && out.contains("(mm, deg)"),
        "{out}"
    );
    let text = std::fs::read_to_string(d.join("box.csv")).unwrap();
    let mut lines = text.lines();
    assert!(lines.next().unwrap().starts_with(kinecal::predict::CSV_HEADER));
    let sigmas: Vec<f64> = lines.map(|l| l.split(',').nth(4).unwrap().parse().unwrap()).collect();
    assert_eq!(sigmas.len(), 30);
    assert!(sigmas.iter().all(|s| *s > 0.0 && *s < 1.0), "{sigmas:?}");
    // A file's configurations: the held-out poses.
    ok(d, &["validate", "cal.toml", "--predict", "v.csv", "--out", "v-pred.csv"]);
    assert_eq!(std::fs::read_to_string(d.join("v-pred.csv")).unwrap().lines().count(), 11);
    // The report shows the map beside the measured errors.
    let html = std::fs::read_to_string(d.join("r.html")).unwrap();
    assert!(html.contains("id=\"predicted\"") && html.contains("predicted position σ"));
    // A nominal model has no covariance: one line, exit 1.
    let e = fails(d, &["validate", "m.toml", "--predict", "box", "--out", "n.csv"]);
    assert!(e.contains("has no [covariance]"), "{e}");
}
