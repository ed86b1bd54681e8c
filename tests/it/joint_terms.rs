//! Non-geometric joint terms (lost motion, gravity compliance) on simulated IRB 120 prototypes:
//! recovered to the noise level, ≈ 0 on a purely geometric prototype, and used by compensation.
use kinecal::calibrate::{calibrate, Calibration, CalibrationOptions};
use kinecal::compensate::compensate;
use kinecal::io::builtin;
use kinecal::io::data_file::DataSet;
use kinecal::io::model_file::{MechanismSpec, ModelFile};
use kinecal::measure::{Measurement, Noise};
use kinecal::model::Mechanism;
use kinecal::simulate::{measure, perturbed, random_configurations, random_errors, ObservationKind};
use nalgebra::DVector;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The IRB 120 with lost motion on every joint and gravity compliance of joints 2 and 3.
fn with_terms() -> ModelFile {
    let text = builtin::model_file("irb120").unwrap().to_toml().unwrap().replace(
        "\n[calibration]",
        "\n[mechanism.joint_terms]\nbacklash = [\"q1\", \"q2\", \"q3\", \"q4\", \"q5\", \"q6\"]\ngravity = [\"q2\", \"q3\"]\n\n[calibration]",
    );
    ModelFile::load_str(std::path::Path::new("irb120-terms.toml"), &text).unwrap()
}

const NOISE_MM: f64 = 0.01;
const NOISE_RAD: f64 = 3e-5;

/// A prototype of `file`'s nominal with geometric errors (±0.2 mm, ±0.02°) and the term values
/// `terms` (rad; none for a purely geometric prototype).
fn prototype(file: &ModelFile, terms: Option<&[f64]>) -> Box<dyn Mechanism> {
    let nominal = file.build();
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let geometric: Vec<usize> = (0..42).collect();
    let mut delta: DVector<f64> = random_errors(&*nominal, &mut rng, 0.2, 0.02f64.to_radians(), Some(&geometric));
    if let Some(t) = terms {
        for (k, v) in t.iter().enumerate() {
            delta[42 + k] = *v;
        }
    }
    perturbed(&nominal, &delta)
}

/// Pose data of `truth` at `n` configurations of `file` (approach directions from their
/// order), with noise.
fn data(file: &ModelFile, truth: &dyn Mechanism, n: usize, seed: u64) -> DataSet {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let qs = random_configurations(truth, &file.inputs(), n, &mut rng).unwrap();
    let noise = Noise {
        position: NOISE_MM,
        orientation: NOISE_RAD,
        ..Noise::default()
    };
    let m = measure(truth, &qs, ObservationKind::Pose, Some(&noise), &mut rng).unwrap();
    DataSet::from_measurements("sim.csv", m)
}

/// `truth`'s measurements re-expressed for `file`'s inputs (dropping the approach columns when
/// `file` has none).
fn for_file(d: &DataSet, file: &ModelFile) -> DataSet {
    let n = file.inputs().len();
    let m: Vec<Measurement> = d
        .measurements
        .iter()
        .map(|m| Measurement {
            joints: Vec::new(),
            q: m.q[..n].to_vec(),
            obs: m.obs.clone(),
        })
        .collect();
    DataSet::from_measurements("sim.csv", m)
}

fn fit(file: &ModelFile, ident: &DataSet, valid: &DataSet) -> Calibration {
    let opts = CalibrationOptions {
        noise: Noise {
            position: NOISE_MM,
            orientation: NOISE_RAD,
            ..Noise::default()
        },
        ..CalibrationOptions::default()
    };
    calibrate(file, &for_file(ident, file), Some(&for_file(valid, file)), &opts).unwrap()
}

fn held_out_rms(c: &Calibration) -> f64 {
    c.report.validation.as_ref().unwrap().after_stats.position_rms_mm
}

/// Identified term values and standard deviations, by parameter name.
fn terms_of(c: &Calibration) -> Vec<(String, f64, f64)> {
    let MechanismSpec::SerialTerms(m) = &c.model_file.mechanism else {
        panic!("no terms")
    };
    let params = c.identification.model.params();
    let first = m.chain().n_params();
    m.params()[first..]
        .iter()
        .zip(&m.terms().values)
        .map(|(p, v)| {
            let k = params.iter().position(|x| x.name == p.name).unwrap();
            (p.name.clone(), *v, c.identification.std_dev[k])
        })
        .collect()
}

/// Lost motion 0.01–0.03°, gravity compliance 0.02–0.05° per metre of lever.
fn true_terms(file: &ModelFile) -> Vec<f64> {
    let MechanismSpec::SerialTerms(m) = &file.mechanism else {
        unreachable!()
    };
    let n = m.terms().values.len();
    (0..n)
        .map(|k| {
            if k < 6 {
                0.01 + 0.004 * k as f64
            } else {
                0.02 + 0.005 * (k - 6) as f64
            }
            .to_radians()
        })
        .collect()
}

#[test]
fn lost_motion_and_compliance_are_recovered_to_the_noise_level() {
    let file = with_terms();
    let t = true_terms(&file);
    let truth = prototype(&file, Some(&t));
    let (ident, valid) = (data(&file, &*truth, 300, 1), data(&file, &*truth, 200, 2));
    let c = fit(&file, &ident, &valid);
    let geometric = fit(&builtin::model_file("irb120").unwrap(), &ident, &valid);
    eprintln!(
        "held-out RMS: with terms {:.4} mm, geometric only {:.4} mm",
        held_out_rms(&c),
        held_out_rms(&geometric)
    );
    assert!(c.identification.converged);
    // At the noise level (RMS of a 3-D error with σ = 10 µm per axis: 17 µm).
    assert!(held_out_rms(&c) < 2.0 * NOISE_MM * 3f64.sqrt(), "{}", held_out_rms(&c));
    assert!(held_out_rms(&geometric) > 3.0 * held_out_rms(&c));
    let identifiable = c.identification.identifiability.identifiable.clone();
    let params = c.identification.model.params();
    for ((name, v, sd), truth) in terms_of(&c).into_iter().zip(&t) {
        let k = params.iter().position(|p| p.name == name).unwrap();
        eprintln!(
            "{name}: {:.5}° ± {:.5}° (true {:.5}°)",
            v.to_degrees(),
            sd.to_degrees(),
            truth.to_degrees()
        );
        if identifiable.contains(&k) {
            assert!((v - truth).abs() < 4.0 * sd + 1e-9, "{name}: {v} ± {sd}, true {truth}");
        }
    }
    // Every lost motion is identifiable; so is a gravity term of each compliant joint.
    for name in [
        "q1.backlash",
        "q2.backlash",
        "q3.backlash",
        "q4.backlash",
        "q5.backlash",
        "q6.backlash",
        "q2.gravity.q3",
        "q3.gravity.q5",
    ] {
        let k = params.iter().position(|p| p.name == name).unwrap();
        assert!(identifiable.contains(&k), "{name} not identifiable");
    }
}

#[test]
fn terms_on_a_purely_geometric_prototype_come_out_near_zero() {
    let file = with_terms();
    let truth = prototype(&file, None);
    let (ident, valid) = (data(&file, &*truth, 300, 3), data(&file, &*truth, 200, 4));
    let c = fit(&file, &ident, &valid);
    let geometric = fit(&builtin::model_file("irb120").unwrap(), &ident, &valid);
    let (a, b) = (held_out_rms(&c), held_out_rms(&geometric));
    eprintln!("held-out RMS: with terms {a:.5} mm, geometric only {b:.5} mm");
    assert!((a - b).abs() < 0.05 * b, "{a} vs {b}");
    for (name, v, sd) in terms_of(&c) {
        eprintln!("{name}: {:.5}° ± {:.5}°", v.to_degrees(), sd.to_degrees());
        assert!(v.abs() < 4.0 * sd + 1e-9, "{name}: {v} ± {sd}");
    }
}

#[test]
fn compensation_with_the_terms_reaches_the_targets() {
    let file = with_terms();
    let t = true_terms(&file);
    let truth = prototype(&file, Some(&t));
    let (ident, valid) = (data(&file, &*truth, 300, 5), data(&file, &*truth, 100, 6));
    let with = fit(&file, &ident, &valid);
    let geometric = fit(&builtin::model_file("irb120").unwrap(), &ident, &valid);
    // Targets: poses the prototype reaches away from the elbow's stretch (q3 = −76.95°, where a
    // pose the prototype just reaches may lie beyond a model's reach) and the wrist singularity;
    // commands in their order (approach directions from that order).
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut qs: Vec<Vec<f64>> = random_configurations(&*truth, &file.inputs(), 200, &mut rng)
        .unwrap()
        .into_iter()
        .filter(|q| (q[2].to_degrees() + 76.95).abs() > 10.0 && q[4].to_degrees().abs() > 10.0)
        .take(50)
        .collect();
    kinecal::model::kind::approach_from_order(&file.inputs(), &[false; 12], &mut qs);
    let targets: Vec<_> = qs.iter().map(|q| truth.forward(q).unwrap()).collect();
    let reached = |model: &dyn Mechanism, file: &ModelFile| -> f64 {
        let inputs = file.inputs();
        let seeds: Vec<Vec<f64>> = qs.iter().map(|q| q[..inputs.len()].to_vec()).collect();
        let commands = compensate(model, &inputs, &targets, Some(&seeds), &|_| {}).unwrap();
        // The prototype driven by the commands, in their order (its approach directions).
        let mut run: Vec<Vec<f64>> = commands.iter().map(|c| c[..6].iter().copied().chain([0.0; 6]).collect()).collect();
        kinecal::model::kind::approach_from_order(&with_terms().inputs(), &[false; 12], &mut run);
        let e: Vec<f64> = run
            .iter()
            .zip(&targets)
            .map(|(q, tgt)| (truth.forward(q).unwrap().translation.vector - tgt.translation.vector).norm())
            .collect();
        (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt()
    };
    let model_with = with.model_file.build();
    let model_geo = geometric.model_file.build();
    let (a, b) = (reached(&*model_with, &with.model_file), reached(&*model_geo, &geometric.model_file));
    eprintln!("compensated RMS error on the prototype: with terms {a:.4} mm, geometric only {b:.4} mm");
    assert!(a < 2.0 * NOISE_MM * 3f64.sqrt(), "{a}");
    assert!(b > 3.0 * a);
}

#[test]
fn the_report_compares_the_geometric_model_and_each_term() {
    let file = with_terms();
    let t = true_terms(&file);
    let truth = prototype(&file, Some(&t));
    let c = fit(&file, &data(&file, &*truth, 200, 8), &data(&file, &*truth, 100, 9));
    let names: Vec<&str> = c.report.variants.iter().map(|v| v.name.as_str()).collect();
    assert_eq!(names, ["geometric only", "geometry + backlash", "geometry + gravity"]);
    let rms = |v: &kinecal::report::ModelVariant| v.validation.as_ref().unwrap().position_rms_mm;
    let full = held_out_rms(&c);
    for v in &c.report.variants {
        assert!(rms(v) > 2.0 * full, "{}: {} against {full}", v.name, rms(v));
    }
    let html = c.report.to_html().unwrap();
    assert!(html.contains("What the joint terms contribute") && html.contains("geometry + backlash"));
}

#[test]
fn approach_directions_follow_the_motion_order() {
    let inputs = with_terms().inputs();
    let mut rows: Vec<Vec<f64>> = [0.0, 0.2, 0.2, 0.1, 0.1, 0.3]
        .iter()
        .map(|&v| {
            let mut q = vec![0.0; 12];
            q[1] = v;
            q
        })
        .collect();
    kinecal::model::kind::approach_from_order(&inputs, &[false; 12], &mut rows);
    let dir_q2: Vec<f64> = rows.iter().map(|q| q[7]).collect();
    // Unknown before the first motion; a joint at rest keeps the direction it came from.
    assert_eq!(dir_q2, [0.0, 1.0, 1.0, -1.0, -1.0, 1.0]);
    // Joints that never moved: unknown (0).
    assert!(rows.iter().all(|q| q[6] == 0.0));
}

#[test]
fn a_data_file_without_approach_columns_gets_them_from_its_row_order() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("d.csv");
    std::fs::write(
        &p,
        "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm\n0,0,0,0,0,10,0,1,2,3\n1,5,-3,0,0,10,0,1,2,3\n2,5,-1,0,0,12,0,1,2,3\n",
    )
    .unwrap();
    let d = kinecal::io::data_file::read_data(&p, &with_terms().inputs(), kinecal::io::data_file::InputColumns::Required).unwrap();
    assert_eq!(d.derived.len(), 6);
    let dirs: Vec<Vec<f64>> = d.measurements.iter().map(|m| m.q[6..].to_vec()).collect();
    assert_eq!(dirs[2], [1.0, 1.0, 0.0, 0.0, 1.0, 0.0]);
    assert_eq!(dirs[1], [1.0, -1.0, 0.0, 0.0, 0.0, 0.0]);
}

#[test]
fn mistakes_in_the_joint_terms_are_named_with_their_line() {
    let base = builtin::model_file("irb120").unwrap().to_toml().unwrap();
    let with = |section: &str| base.replace("\n[calibration]", &format!("\n[mechanism.joint_terms]\n{section}\n\n[calibration]"));
    let err = |section: &str| {
        ModelFile::load_str(std::path::Path::new("m.toml"), &with(section))
            .unwrap_err()
            .to_string()
    };
    let e = err("backlash = [\"q2\", \"q7\"]");
    assert!(e.contains("m.toml:6") && e.contains("no joint 'q7'") && e.contains("q1, q2"), "{e}");
    let e = err("gravity = [\"q2\"]\n[mechanism.joint_terms.values]\n\"q2.gravity.q9\" = 0.1");
    assert!(e.contains("'q2.gravity.q9' is not a term") && e.contains("q2.gravity.q3"), "{e}");
    let e = err("gravity = [\"q2\"]\nreference = [[0, 0, 0, 0, 0, 0]]");
    assert!(e.contains("1 rows for 6 joints"), "{e}");
    let e = err("stiffness = [\"q2\"]");
    assert!(e.contains("stiffness"), "{e}");
}
