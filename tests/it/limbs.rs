//! Parallel machines written only as model files (`kind = "limbs"`, `examples/models/`): the whole
//! workflow through the binary (plan → simulate → identify with frames estimated → validate →
//! compensate on the virtual prototype), and the one-line errors of a limb that cannot close, a
//! machine with the wrong mobility and other mistakes, each naming the limb and the line.
use crate::cli::{fails, json, ok};
use kinecal::io::data_file::{read_data, write_data, InputColumns};
use kinecal::io::model_file::ModelFile;
use kinecal::io::table::read_table;
use kinecal::measure::{Measurement, Observation};
use kinecal::validate::commanded_error;
use kinecal::Mechanism;
use std::path::Path;

const HEAD: &str = include_str!("../../examples/models/head-3prs.toml");
const HEXAPOD: &str = include_str!("../../examples/models/hexapod-6rus.toml");

/// Targets where the nominal model puts the validation commands; the commands as read.
fn nominal_targets(d: &Path, model: &ModelFile) -> Vec<kinecal::se3::Pose> {
    let inputs = model.inputs();
    let nominal = model.build();
    let val = read_data(&d.join("valid.csv"), &inputs, InputColumns::Required).unwrap();
    let targets: Vec<_> = val.measurements.iter().map(|m| nominal.forward(&m.q).unwrap()).collect();
    let rows: Vec<Measurement> = targets
        .iter()
        .map(|t| Measurement {
            q: vec![],
            obs: Observation::Pose(*t),
        })
        .collect();
    write_data(&d.join("targets.csv"), &inputs, &val.ids, &rows, None).unwrap();
    targets
}

fn commands(path: &Path, angle_inputs: &[bool]) -> Vec<Vec<f64>> {
    read_table(path)
        .unwrap()
        .rows
        .iter()
        .map(|r| {
            r[1..]
                .iter()
                .zip(angle_inputs)
                .map(|(v, a)| if *a { v.to_radians() } else { *v })
                .collect()
        })
        .collect()
}

fn whole_workflow(text: &str, rank: u64) {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("m.toml"), text).unwrap();
    let plan = ok(
        d,
        &[
            "plan",
            "--model",
            "m.toml",
            "-n",
            "30",
            "--candidates",
            "3000",
            "--output",
            "plan.csv",
        ],
    );
    assert!(plan.contains("wrote plan.csv"), "{plan}");
    ok(
        d,
        &[
            "simulate",
            "m.toml",
            "--at",
            "plan.csv",
            "--seed",
            "3",
            "--error-mm",
            "0.3",
            "--error-deg",
            "0.05",
            "--out",
            "ident.csv",
            "--truth",
            "truth.toml",
            "--validation-poses",
            "20",
            "--validation-out",
            "valid.csv",
        ],
    );
    // Noise-free, data in the model frame but frames estimated all the same: round-off.
    let rep = json(
        d,
        &[
            "identify",
            "m.toml",
            "ident.csv",
            "--validation",
            "valid.csv",
            "--out",
            "cal.toml",
            "--report",
            "r.html",
        ],
    );
    assert_eq!(rep["converged"], true, "{}", rep["verdict"]);
    // The frames add nothing: the limbs' base placements and platform points absorb them.
    assert_eq!(rep["rank"].as_u64().unwrap(), rank);
    let v = &rep["validation"];
    assert!(
        v["before_stats"]["position_rms_mm"].as_f64().unwrap() > 0.03,
        "{}",
        v["before_stats"]
    );
    let after = v["after_stats"]["position_max_mm"].as_f64().unwrap();
    assert!(after < 1e-6, "held-out after calibration: {after} mm");
    // Compensation: the calibrated commands put the true machine on the targets (what its task
    // commands); the nominal commands miss by tenths of a millimetre.
    let model = ModelFile::load(&d.join("m.toml")).unwrap();
    let truth = ModelFile::load(&d.join("truth.toml")).unwrap().build();
    let targets = nominal_targets(d, &model);
    // (A machine commanding less than a pose commands it in its base frame, which frames
    // estimated from the data leave free to tilt with the limbs' base placements: compensation
    // is checked with the model calibrated in the data's frame, the machine's base.)
    ok(d, &["identify", "m.toml", "ident.csv", "--frames", "model", "--out", "calm.toml"]);
    ok(d, &["compensate", "calm.toml", "targets.csv", "--out", "cmd.csv"]);
    let angles: Vec<bool> = model.inputs().iter().map(|i| i.unit == kinecal::params::Unit::Angle).collect();
    let val = read_data(&d.join("valid.csv"), &model.inputs(), InputColumns::Required).unwrap();
    let (mut worst, mut nominal) = (0.0f64, 0.0f64);
    for ((q, t), m) in commands(&d.join("cmd.csv"), &angles).iter().zip(&targets).zip(&val.measurements) {
        let (dp, dw) = commanded_error(truth.task(), t, &truth.forward(q).unwrap());
        worst = worst.max(dp).max(dw * 1e3);
        nominal = nominal.max(commanded_error(truth.task(), t, &truth.forward(&m.q).unwrap()).0);
    }
    assert!(worst < 1e-6, "compensated: {worst}");
    assert!(nominal > 0.05, "nominal commands should miss: {nominal}");
}

#[test]
fn a_3prs_head_from_its_model_file_through_the_whole_workflow() {
    whole_workflow(HEAD, 33);
}

#[test]
fn a_6rus_hexapod_from_its_model_file_through_the_whole_workflow() {
    whole_workflow(HEXAPOD, 66);
}

fn load(text: &str) -> Result<ModelFile, String> {
    ModelFile::load_str(Path::new("m.toml"), text).map_err(|e| e.to_string())
}

#[test]
fn mistakes_in_a_limbs_file_are_one_line_errors_naming_the_limb() {
    // A platform point 80 mm off: the limb cannot reach it at home.
    let e = load(&HEAD.replacen(
        "[mechanism.limbs.end_placement]",
        "platform_point = [140.0, 0.0, 0.0]\n\n[mechanism.limbs.end_placement]",
        1,
    ))
    .unwrap_err();
    assert!(e.contains("limb 'leg1' cannot close at the home pose"), "{e}");
    // An actuator made passive: the platform keeps a freedom.
    let e = load(&HEAD.replacen("role = \"actuated\"", "role = \"passive\"", 1)).unwrap_err();
    assert!(e.contains("wrong mobility"), "{e}");
    for (from, to, expect) in [
        ("role = \"passive\"", "role = \"pasive\"", "m.toml:"),
        ("type = \"revolute\"", "type = \"ball\"", "unknown joint type 'ball'"),
        ("end = \"point\"", "end = \"sphere\"", "unknown end 'sphere'"),
        ("task = \"height-and-axis\"", "task = \"3T\"", "unknown task '3T'"),
    ] {
        let e = load(&HEAD.replacen(from, to, 1)).unwrap_err();
        assert!(e.contains(expect) && !e.contains('\n'), "{from} → {to}: {e}");
        assert!(e.starts_with("m.toml:"), "a line number: {e}");
    }
    let e = load(&HEXAPOD.replacen("home = [0.0, -35.0]", "home = [0.0]", 1)).unwrap_err();
    assert!(e.contains("give 2 value(s)") && e.contains("leg1"), "{e}");
    // And through the binary: one line, non-zero exit.
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("bad.toml"),
        HEAD.replacen("role = \"actuated\"", "role = \"passive\"", 1),
    )
    .unwrap();
    let msg = fails(tmp.path(), &["identifiability", "bad.toml"]);
    assert!(msg.contains("wrong mobility") && msg.trim().lines().count() == 1, "{msg}");
}
