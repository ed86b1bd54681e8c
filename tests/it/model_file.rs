//! Model files: export → load round trip, units, and one-line errors naming file and line.
use approx::assert_relative_eq;
use kinecal::io::builtin;
use kinecal::io::model_file::{select_params, ModelFile};
use kinecal::se3;
use kinecal::Mechanism;
use nalgebra::DVector;
use std::path::Path;

fn irb120_text() -> String {
    builtin::model_file("irb120").unwrap().to_toml().unwrap()
}

fn load(text: &str) -> Result<ModelFile, String> {
    ModelFile::load_str(Path::new("m.toml"), text).map_err(|e| e.to_string())
}

fn same_kinematics(a: &dyn Mechanism, b: &dyn Mechanism, tol: f64) {
    assert_eq!(a.input_names(), b.input_names());
    assert_eq!(a.params(), b.params());
    for k in 0..20 {
        let q: Vec<f64> = (0..a.input_names().len())
            .map(|j| ((k * 7 + j * 3) as f64 * 0.37).sin() * 2.0)
            .collect();
        let (ta, tb) = (a.forward(&q).unwrap(), b.forward(&q).unwrap());
        assert_relative_eq!(ta.to_homogeneous(), tb.to_homogeneous(), epsilon = tol);
    }
}

#[test]
fn builtin_export_load_round_trip() {
    let original = builtin::model_file("irb120").unwrap();
    let loaded = load(&irb120_text()).unwrap();
    assert_eq!(loaded.name, "irb120");
    assert_eq!(loaded.inputs(), original.inputs());
    same_kinematics(&*original.build(), &*loaded.build(), 1e-12);
    // Written again, the text is identical.
    assert_eq!(loaded.to_toml().unwrap(), irb120_text());
}

#[test]
fn calibrated_model_round_trips_in_metres_and_radians() {
    let original = builtin::model_file("irb120").unwrap();
    let mut m = original.build();
    let delta = DVector::from_fn(m.n_params(), |i, _| ((i as f64) * 1.7).sin() * 0.01);
    m.retract(&delta);
    let mut cal = original.with_geometry_of(&*m).unwrap();
    cal.units.length = kinecal::io::model_file::LengthUnit::M;
    cal.units.angle = kinecal::io::model_file::AngleUnit::Rad;
    let text = cal.to_toml().unwrap();
    assert!(text.contains("length = \"m\""));
    let back = load(&text).unwrap();
    same_kinematics(&*m, &*back.build(), 1e-9);
    // Limits survive the unit change.
    assert_eq!(back.inputs().len(), 6);
    for (a, b) in back.inputs().iter().zip(original.inputs()) {
        let (x, y) = (a.limits.unwrap(), b.limits.unwrap());
        assert_relative_eq!(x.0, y.0, epsilon = 1e-12);
        assert_relative_eq!(x.1, y.1, epsilon = 1e-12);
    }
}

#[test]
fn units_are_converted_to_mm_and_rad() {
    let text = r#"
name = "rp"
[units]
length = "m"
angle = "deg"
[mechanism]
kind = "serial"
[[mechanism.joints]]
name = "q1"
type = "revolute"
axis = [0, 0, 1]
[[mechanism.joints]]
name = "d2"
type = "prismatic"
axis = [1, 0, 0]
limits = [0.0, 0.5]
position = [0.1, 0, 0]
rotvec = [0, 0, 90]
[mechanism.tool]
position = [0.01, 0, 0]
[noise]
position = 0.00002
orientation = 0.01
"#;
    let f = load(text).unwrap();
    let m = f.build();
    // q1 = 0, d2 = 5 mm: base → (100,0,0), rotated 90° about z, slide along local x = world y.
    let t = m.forward(&[0.0, 5.0]).unwrap();
    assert_relative_eq!(t.translation.vector, nalgebra::Vector3::new(100.0, 15.0, 0.0), epsilon = 1e-9);
    assert_eq!(f.inputs()[1].limits, Some((0.0, 500.0)));
    let n = f.noise.unwrap();
    assert_relative_eq!(n.position, 0.02, epsilon = 1e-12);
    assert_relative_eq!(n.orientation, 0.01_f64.to_radians(), epsilon = 1e-15);
    let _ = se3::log(&t);
}

#[test]
fn free_and_fixed_patterns_select_parameters() {
    let mut f = builtin::model_file("irb120").unwrap();
    f.free = vec!["1-2.*".into(), "*".into()];
    f.fixed = vec!["0-1.*".into(), "6-T.v?".into()];
    let idx = f.free_indices().unwrap();
    let params = f.build().params();
    assert_eq!(params[idx[0]].name, "1-2.vx");
    assert_eq!(idx.len(), 42 - 6 - 3);
    assert!(idx.iter().all(|&i| !params[i].name.starts_with("0-1.")));
    assert_eq!(select_params(&params, &["7-8.*".into()], &[]), Err("7-8.*".to_string()));
}

#[test]
fn typo_in_a_key_names_file_line_and_key() {
    let text = irb120_text().replacen("axis = ", "axsi = ", 2);
    let e = load(&text).unwrap_err();
    let line = irb120_text().lines().position(|l| l.starts_with("axis")).unwrap();
    assert!(e.starts_with(&format!("m.toml:{}:", line + 1)), "{e}");
    assert!(e.contains("axsi"), "{e}");
    assert_eq!(e.lines().count(), 1, "{e}");
}

#[test]
fn unknown_unit_and_bad_values_are_one_line() {
    let t = irb120_text();
    let e = load(&t.replace("length = \"mm\"", "length = \"inch\"")).unwrap_err();
    let line = t.lines().position(|l| l.starts_with("length")).unwrap() + 1;
    assert_eq!(
        e,
        format!("m.toml:{line}: units.length: unknown length unit 'inch' (use \"mm\" or \"m\")")
    );
    let e = load(&t.replace("type = \"revolute\"", "type = \"helical\"")).unwrap_err();
    assert!(e.starts_with("m.toml:") && e.contains("helical"), "{e}");
    let e = load(&t.replace("limits = [-165.0, 165.0]", "limits = [165.0, -165.0]")).unwrap_err();
    assert!(e.contains("mechanism.joints[0] ('q1').limits"), "{e}");
    let e = load(&t.replace("fixed = []", "fixed = [\"9-9.*\"]")).unwrap_err();
    assert!(e.contains("calibration.fixed: '9-9.*' matches no parameter"), "{e}");
    let e = load(&t.replace("kind = \"serial\"", "kind = \"delta\"")).unwrap_err();
    assert!(e.contains("unknown mechanism kind 'delta'"), "{e}");
    assert_eq!(e.lines().count(), 1);
    // A joint named as a measurement's column (a quill 'z', a wrist 'roll', a reflector 'm1x')
    // would take that column of every data file and plan.
    for name in ["z", "roll", "m1x"] {
        let e = load(&t.replace("name = \"q3\"", &format!("name = \"{name}\""))).unwrap_err();
        assert!(e.contains(&format!("joint '{name}'")) && e.contains("rename the joint"), "{e}");
        assert_eq!(e.lines().count(), 1);
    }
}

/// The encoders' noise of observed joints in `[noise]` (file units), read and written back; a
/// bad value is a one-line error.
#[test]
fn encoder_noise_in_the_model_file() {
    let text = include_str!("../../examples/models/t3r1.toml").to_string()
        + "\n[noise]\nposition = 0.01\norientation = 0.005\nencoder_angle = 0.004\n";
    let f = load(&text).unwrap();
    let n = f.noise.unwrap();
    assert_relative_eq!(n.joint_angle, 0.004f64.to_radians(), epsilon = 1e-15);
    assert_relative_eq!(n.joint_length, 0.01, epsilon = 1e-15);
    let back = load(&f.to_toml().unwrap()).unwrap().noise.unwrap();
    assert_relative_eq!(back.joint_angle, n.joint_angle, epsilon = 1e-15);
    let bad = load(
        &(include_str!("../../examples/models/t3r1.toml").to_string()
            + "\n[noise]\nposition = 0.01\norientation = 0.005\nencoder_angle = -1\n"),
    )
    .unwrap_err();
    assert!(bad.contains("encoder_angle") && bad.lines().count() == 1, "{bad}");
}
