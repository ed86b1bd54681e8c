//! The closed-loop presets as model-file kinds (`kind = "pm5"`, `kind = "stewart"`): export →
//! load round trips (nominal and calibrated geometry, any units), the whole workflow through the
//! binary with the numbers checked, and the one-line errors of bad inputs.
use crate::cli::{fails, json, ok};
use crate::support::nominal_targets;
use kinecal::io::builtin;
use kinecal::io::model_file::{MechanismSpec, ModelFile};
use kinecal::io::table::read_table;
use kinecal::model::presets::pm5::{Parasitic, Pm5};
use kinecal::se3;
use kinecal::simulate::random_configurations;
use kinecal::simulate::{perturbed, random_errors};
use kinecal::validate::tool_axis_angle;
use kinecal::Mechanism;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;

fn load(text: &str) -> Result<ModelFile, String> {
    ModelFile::load_str(Path::new("m.toml"), text).map_err(|e| e.to_string())
}

/// Same inputs, parameters and tool poses at `n` configurations drawn in `a`'s workspace.
fn same_kinematics(a: &dyn Mechanism, b: &dyn Mechanism, tol: f64, seed: u64) {
    assert_eq!(a.input_names(), b.input_names());
    assert_eq!(a.params(), b.params());
    let qs = a.sample_configurations(15, seed).unwrap().unwrap();
    for q in &qs {
        let (ta, tb) = (a.forward(q).unwrap(), b.forward(q).unwrap());
        let e = se3::pose_error(&ta, &tb);
        assert!(se3::lin(&e).norm() < tol && se3::ang(&e).norm() < tol * 1e-3, "{e}");
    }
}

#[test]
fn builtins_export_load_round_trip() {
    for name in ["pm5", "stewart"] {
        let original = builtin::model_file(name).unwrap();
        let text = original.to_toml().unwrap();
        assert!(text.contains(&format!("kind = \"{name}\"")), "{text}");
        let loaded = load(&text).unwrap();
        assert_eq!(loaded.mechanism.kind(), name);
        assert_eq!(loaded.inputs(), original.inputs());
        same_kinematics(&*original.build(), &*loaded.build(), 1e-9, 1);
        // Written again, the text is identical.
        assert_eq!(loaded.to_toml().unwrap(), text);
    }
    let pm5 = builtin::model_file("pm5").unwrap();
    let inputs = pm5.inputs();
    assert_eq!(
        inputs.iter().map(|i| i.name.as_str()).collect::<Vec<_>>(),
        ["g1", "g2", "g3", "g4", "g5"]
    );
    assert_eq!(inputs[0].limits, Some((300.0, 550.0)));
    assert_eq!(pm5.build().params().len(), 44);
    assert_eq!(builtin::model_file("stewart").unwrap().build().params().len(), 42);
}

/// A calibrated (perturbed) geometry is written with its current values and loads back to the
/// same kinematics and the same parameter values, in metres/radians too, and in the paper's
/// parasitic mode (whose reference geometry must survive the round trip).
#[test]
fn calibrated_geometry_round_trips_in_any_units() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let paper = Pm5::mechanism(Parasitic::NominalGeometry);
    let models: Vec<(ModelFile, Box<dyn Mechanism>)> = ["pm5", "stewart"]
        .iter()
        .map(|n| {
            let f = builtin::model_file(n).unwrap();
            let m = f.build();
            (f, m)
        })
        .chain(std::iter::once((
            ModelFile::new("pm5-paper", MechanismSpec::Pm5(paper.clone())),
            Box::new(paper) as Box<dyn Mechanism>,
        )))
        .collect();
    for (file, nominal) in models {
        let delta = random_errors(&*nominal, &mut rng, 0.5, 0.2f64.to_radians(), None);
        let truth = perturbed(&nominal, &delta);
        let mut written = file.with_geometry_of(&*truth).unwrap();
        for (l, a) in [("mm", "deg"), ("m", "rad")] {
            written.units.length = kinecal::io::model_file::LengthUnit::parse(l).unwrap();
            written.units.angle = kinecal::io::model_file::AngleUnit::parse(a).unwrap();
            let text = written.to_toml().unwrap();
            let back = load(&text).unwrap();
            let m = back.build();
            same_kinematics(&*truth, &*m, 1e-9, 2);
            let values = |m: &dyn Mechanism| -> Vec<f64> { m.geometry().unwrap() };
            for (a, b) in values(&*truth).iter().zip(values(&*m)) {
                assert!((a - b).abs() <= 1e-12 * a.abs().max(1.0), "{a} vs {b} ({l}, {a})");
            }
            // Not the nominal kinematics: the errors were written.
            let q = truth.sample_configurations(1, 3).unwrap().unwrap().remove(0);
            let e = se3::pose_error(&nominal.forward(&q).unwrap(), &m.forward(&q).unwrap());
            assert!(se3::lin(&e).norm() > 0.05, "{e}");
        }
    }
}

fn simulate(d: &Path, model: &str, poses: &str, validation: &str) {
    ok(
        d,
        &[
            "simulate",
            model,
            "--poses",
            poses,
            "--seed",
            "5",
            "--error-mm",
            "0.3",
            "--error-deg",
            "0.05",
            "--out",
            "ident.csv",
            "--truth",
            "truth.toml",
            "--validation-poses",
            validation,
            "--validation-out",
            "valid.csv",
        ],
    );
}

/// Commands (mm) of a commands file.
fn commands(path: &Path) -> Vec<Vec<f64>> {
    read_table(path).unwrap().rows.iter().map(|r| r[1..].to_vec()).collect()
}

#[test]
fn pm5_model_file_through_the_whole_workflow() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let list = ok(d, &["model", "list"]);
    assert!(list.contains("pm5") && list.contains("stewart"), "{list}");
    ok(d, &["model", "export", "pm5", "--out", "pm5.toml"]);
    simulate(d, "pm5.toml", "30", "20");
    let header = std::fs::read_to_string(d.join("ident.csv")).unwrap();
    assert!(header.starts_with("id,g1_mm,g2_mm,g3_mm,g4_mm,g5_mm,x_mm,y_mm,z_mm,qw,qx,qy,qz\n"));

    // Identifiability: the physical model's rank 32 of 44, on the data and on random poses.
    for args in [
        &["identifiability", "pm5.toml", "ident.csv"][..],
        &["identifiability", "pm5.toml", "--poses", "40"],
    ] {
        let id = json(d, args);
        assert_eq!(id["rank"], 32, "{id}");
        let red: Vec<&str> = id["redundant"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
        assert_eq!(
            red,
            ["db1y", "db2y", "dl4", "dl5", "db3y", "dl8", "dl9", "dty", "dx0", "dy0", "dz0", "dγ0"]
        );
    }

    // Identify (noise-free): the validation set is reproduced to round-off, tool axis included.
    let rep = json(
        d,
        &[
            "identify",
            "--frames",
            "model",
            "pm5.toml",
            "ident.csv",
            "--validation",
            "valid.csv",
            "--out",
            "cal.toml",
            "--report",
            "r.html",
        ],
    );
    assert_eq!(rep["converged"], true);
    assert_eq!(rep["rank"], 32);
    let v = &rep["validation"];
    assert!(v["before_stats"]["position_rms_mm"].as_f64().unwrap() > 0.2, "{v}");
    assert!(v["before_stats"]["tool_axis_max_deg"].as_f64().unwrap() > 0.01, "{v}");
    let after_mm = v["after_stats"]["position_max_mm"].as_f64().unwrap();
    let after_axis = v["after_stats"]["tool_axis_max_deg"].as_f64().unwrap();
    assert!(
        after_mm < 1e-6 && after_axis < 1e-6,
        "after: {after_mm} mm, tool axis {after_axis} deg"
    );
    let html = std::fs::read_to_string(d.join("r.html")).unwrap();
    assert!(html.contains("dφ1") && html.contains("tool axis max deg"));

    // The calibrated file is a pm5 model file with the identified geometry.
    let cal_text = std::fs::read_to_string(d.join("cal.toml")).unwrap();
    assert!(cal_text.contains("kind = \"pm5\""));
    let cal = ModelFile::load(&d.join("cal.toml")).unwrap();
    let truth = ModelFile::load(&d.join("truth.toml")).unwrap().build();
    same_kinematics(&*truth, &*cal.build(), 1e-6, 4);

    // Validate.
    let val = json(d, &["validate", "cal.toml", "valid.csv"]);
    assert!(val["stats"]["position_max_mm"].as_f64().unwrap() < 1e-6);
    assert!(val["stats"]["tool_axis_max_deg"].as_f64().unwrap() < 1e-6);
    assert_eq!(val["stats"]["poses"], 20);

    // Compensate: the commands put the TRUE machine on the targets' position and tool axis; the
    // nominal commands miss them by tenths of a millimetre.
    let model = ModelFile::load(&d.join("pm5.toml")).unwrap();
    let targets = nominal_targets(d, &model);
    let c = json(d, &["compensate", "cal.toml", "targets.csv", "--out", "cmd.csv"]);
    assert_eq!(c["count"], 20);
    assert_eq!(c["commanded"], "position and tool axis");
    assert!(c["rotation_about_tool_axis_max_deg"].as_f64().unwrap() > 0.0);
    let text = ok(d, &["compensate", "cal.toml", "targets.csv", "--out", "cmd.csv", "--force"]);
    assert!(text.contains("5-DOF machine"), "{text}");
    ok(d, &["compensate", "pm5.toml", "targets.csv", "--out", "nom.csv"]);
    let inputs = model.inputs();
    let (mut worst_mm, mut worst_axis, mut nominal_mm) = (0.0_f64, 0.0_f64, 0.0_f64);
    for ((q, q0), t) in commands(&d.join("cmd.csv")).iter().zip(commands(&d.join("nom.csv"))).zip(&targets) {
        for (v, i) in q.iter().zip(&inputs) {
            let (lo, hi) = i.limits.unwrap();
            assert!(*v >= lo - 1e-9 && *v <= hi + 1e-9);
        }
        let reached = truth.forward(q).unwrap();
        worst_mm = worst_mm.max((reached.translation.vector - t.translation.vector).norm());
        worst_axis = worst_axis.max(tool_axis_angle(t, &reached).to_degrees());
        let off = truth.forward(&q0).unwrap();
        nominal_mm = nominal_mm.max((off.translation.vector - t.translation.vector).norm());
    }
    assert!(worst_mm < 1e-6 && worst_axis < 1e-6, "compensated: {worst_mm} mm, {worst_axis} deg");
    assert!(nominal_mm > 0.1, "nominal commands should miss: {nominal_mm}");
}

#[test]
fn stewart_model_file_through_the_workflow() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ok(d, &["model", "export", "stewart", "--length", "m", "--out", "stewart.toml"]);
    simulate(d, "stewart.toml", "25", "8");
    let rep = json(
        d,
        &[
            "identify",
            "stewart.toml",
            "ident.csv",
            "--validation",
            "valid.csv",
            "--out",
            "cal.toml",
        ],
    );
    assert_eq!(rep["rank"], 42);
    let after = &rep["validation"]["after_stats"];
    assert!(
        after["position_max_mm"].as_f64().unwrap() < 1e-6 && after["orientation_max_deg"].as_f64().unwrap() < 1e-6,
        "{after}"
    );
    assert!(std::fs::read_to_string(d.join("cal.toml")).unwrap().contains("length = \"m\""));
    let truth = ModelFile::load(&d.join("truth.toml")).unwrap().build();
    let model = ModelFile::load(&d.join("stewart.toml")).unwrap();
    let targets = nominal_targets(d, &model);
    let c = json(d, &["compensate", "cal.toml", "targets.csv", "--out", "cmd.csv"]);
    assert_eq!(c["commanded"], "pose");
    for (q, t) in commands(&d.join("cmd.csv")).iter().zip(&targets) {
        let e = se3::pose_error(t, &truth.forward(q).unwrap());
        assert!(se3::lin(&e).norm() < 1e-6 && se3::ang(&e).norm() < 1e-8, "{e}");
    }
}

#[test]
fn bad_pm5_inputs_give_one_line() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let text = builtin::model_file("pm5").unwrap().to_toml().unwrap();
    let line_of = |needle: &str| text.lines().position(|l| l.starts_with(needle)).unwrap() + 1;

    // A typo in a key: the file and the line of the key.
    std::fs::write(d.join("typo.toml"), text.replacen("phi = 45.0", "phii = 45.0", 1)).unwrap();
    let e = fails(d, &["simulate", "typo.toml", "--out", "x.csv", "--truth", "t.toml"]);
    assert!(e.starts_with(&format!("typo.toml:{}:", line_of("phi = 45.0"))), "{e}");
    assert!(e.contains("unknown field `phii`"), "{e}");

    // A wrong unit.
    std::fs::write(d.join("unit.toml"), text.replace("length = \"mm\"", "length = \"cm\"")).unwrap();
    let e = fails(d, &["validate", "unit.toml", "x.csv"]);
    assert!(e.starts_with(&format!("unit.toml:{}:", line_of("length = \"mm\""))), "{e}");
    assert!(e.contains("unknown length unit 'cm'"), "{e}");

    // A bad value and an unknown parasitic mode.
    std::fs::write(d.join("neg.toml"), text.replace("l = 450.0", "l = -450.0")).unwrap();
    let e = fails(d, &["identifiability", "neg.toml"]);
    assert!(
        e.starts_with("neg.toml:") && e.contains("mechanism.limb1.l: must be a finite length > 0"),
        "{e}"
    );
    std::fs::write(
        d.join("par.toml"),
        text.replace("parasitic = \"physical\"", "parasitic = \"exact\""),
    )
    .unwrap();
    let e = fails(d, &["identifiability", "par.toml"]);
    assert!(
        e.starts_with(&format!("par.toml:{}:", line_of("parasitic = "))) && e.contains("'exact'"),
        "{e}"
    );
    // A calibration name that is not one of the paper's.
    std::fs::write(d.join("name.toml"), text.replace("fixed = []", "fixed = [\"dq1\"]")).unwrap();
    let e = fails(d, &["identifiability", "name.toml"]);
    assert!(e.contains("calibration.fixed: 'dq1' matches no parameter"), "{e}");

    // ASCII spellings of the paper's Greek names are accepted.
    std::fs::write(d.join("pm5.toml"), text.replace("fixed = []", "fixed = [\"dphi?\", \"dgamma0\"]")).unwrap();
    let id = json(d, &["identifiability", "pm5.toml", "--poses", "30"]);
    assert_eq!(id["free"], 40);

    // Targets the machine cannot reach: beyond the PUU rod, and beyond a stroke (a 40° tilt).
    std::fs::write(
        d.join("targets.csv"),
        "id,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg\n1,0,0,500,0,0,0\n2,0,0,900,0,0,0\n",
    )
    .unwrap();
    let e = fails(d, &["compensate", "pm5.toml", "targets.csv", "--out", "c.csv"]);
    assert!(
        e.starts_with("targets.csv:3: target 2:") && e.contains("farther than the rod length"),
        "{e}"
    );
    std::fs::write(
        d.join("tilt.csv"),
        "id,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg\n7,0,0,500,0,40,0\n",
    )
    .unwrap();
    let e = fails(d, &["compensate", "pm5.toml", "tilt.csv", "--out", "c.csv"]);
    assert!(e.starts_with("tilt.csv:2: target 7:") && e.contains("outside its stroke"), "{e}");
    assert!(!d.join("c.csv").exists());
}

/// `random_configurations` draws assembling inputs for closed loops (uniform inputs would not).
#[test]
fn closed_loop_configurations_assemble() {
    let f = builtin::model_file("pm5").unwrap();
    let m = f.build();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let qs = random_configurations(&*m, &f.inputs(), 25, &mut rng).unwrap();
    assert_eq!(qs.len(), 25);
    for q in &qs {
        let t = m.forward(q).unwrap();
        let back = m.inverse(&t, None).unwrap();
        assert!(q.iter().zip(&back).all(|(a, b)| (a - b).abs() < 1e-8));
    }
    // Reproducible from the seed.
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    assert_eq!(random_configurations(&*m, &f.inputs(), 25, &mut rng).unwrap(), qs);
}
