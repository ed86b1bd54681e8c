//! Calibrated kinematics written into the files controllers read (`kinecal model export
//! --format ur-yaml | linuxcnc-hexapod | klipper-delta`) and read back: each file evaluated by
//! kinematics written here from the file's documented convention (not kinecal's), round trips
//! byte for byte, one line with file:line for a malformed file.
use crate::cli::{fails, ok};
use crate::registration::{data_set, tool, tracker, Kind};
use kinecal::calibrate::{calibrate, CalibrationOptions};
use kinecal::io::controllers::{self, Controller, ControllerError};
use kinecal::io::model_file::ModelFile;
use kinecal::model::framed::Framed;
use kinecal::simulate::{random_configurations, virtual_prototype};
use kinecal::Mechanism;
use nalgebra::{Matrix3, Matrix4, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::Path;

/// A homogeneous transform from a rotation and a translation.
fn hom(r: Matrix3<f64>, t: Vector3<f64>) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    m.fixed_view_mut::<3, 1>(0, 3).copy_from(&t);
    m
}

fn rx(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}
fn ry(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}
fn rz(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// URDF `<origin xyz rpy>`: `Trans(xyz)·Rz(yaw)·Ry(pitch)·Rx(roll)`.
fn urdf_origin(xyz: [f64; 3], rpy: [f64; 3]) -> Matrix4<f64> {
    hom(rz(rpy[2]) * ry(rpy[1]) * rx(rpy[0]), Vector3::from(xyz))
}

fn matrix_of(p: &kinecal::se3::Pose) -> Matrix4<f64> {
    p.to_homogeneous()
}

/// Position (mm) and rotation (rad) apart.
fn apart(a: &Matrix4<f64>, b: &Matrix4<f64>) -> (f64, f64) {
    let dp = (a.fixed_view::<3, 1>(0, 3) - b.fixed_view::<3, 1>(0, 3)).norm();
    let r = a.fixed_view::<3, 3>(0, 0).transpose() * b.fixed_view::<3, 3>(0, 0);
    let c = ((r.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
    // acos loses digits near 0: the skew part instead.
    let s = Vector3::new(r[(2, 1)] - r[(1, 2)], r[(0, 2)] - r[(2, 0)], r[(1, 0)] - r[(0, 1)]).norm() / 2.0;
    (dp, s.atan2(c))
}

// ---------------------------------------------------------------- Universal Robots

/// The UR kinematics YAML read here, by line: segment → [x y z roll pitch yaw].
fn read_ur_yaml(text: &str) -> BTreeMap<String, [f64; 6]> {
    let keys = ["x", "y", "z", "roll", "pitch", "yaw"];
    let mut out: BTreeMap<String, [f64; 6]> = BTreeMap::new();
    let mut seg = String::new();
    for line in text.lines().filter(|l| !l.trim_start().starts_with('#') && !l.trim().is_empty()) {
        let (k, v) = line.split_once(':').unwrap();
        let indent = line.len() - line.trim_start().len();
        if indent == 2 && v.trim().is_empty() {
            seg = k.trim().to_string();
        } else if indent == 4 {
            let i = keys.iter().position(|x| *x == k.trim()).unwrap();
            out.entry(seg.clone()).or_insert([0.0; 6])[i] = v.trim().parse().unwrap();
        }
    }
    out
}

/// ur_description's forward kinematics from base_link to tool0 (metres → mm).
fn ur_forward(seg: &BTreeMap<String, [f64; 6]>, q: &[f64]) -> Matrix4<f64> {
    let names = ["shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"];
    let mut t = urdf_origin([0.0; 3], [0.0, 0.0, PI]);
    for (k, n) in names.iter().enumerate() {
        let s = seg[*n];
        t = t * urdf_origin([s[0] * 1000.0, s[1] * 1000.0, s[2] * 1000.0], [s[3], s[4], s[5]]) * hom(rz(q[k]), Vector3::zeros());
    }
    t * urdf_origin([0.0; 3], [0.0, -PI / 2.0, -PI / 2.0]) * urdf_origin([0.0; 3], [PI / 2.0, 0.0, PI / 2.0])
}

/// A UR5e with random geometric errors, calibrated from noise-free tracker poses (tracker 2 m
/// away, tool 150 mm off the flange), written as the UR YAML: the YAML's own forward kinematics
/// with the calibrated measurement and tool frames give the calibrated model's measured poses
/// to 1e-9 mm / 1e-9 rad, and the printed difference is round-off.
#[test]
fn calibrated_ur5e_written_as_ur_yaml_is_the_calibrated_model() {
    let file = kinecal::io::urdf::import(&crate::urdf::ur5e_urdf(), None, None).unwrap();
    let nominal = file.build();
    let mut rng = ChaCha8Rng::seed_from_u64(47);
    let (proto, _) = virtual_prototype(&nominal, &file.free_indices().unwrap(), 0.5, 0.1f64.to_radians(), &mut rng);
    let truth = Framed::new(proto, tracker(), tool());
    let inputs = file.inputs();
    let qs = random_configurations(&*nominal, &inputs, 60, &mut rng).unwrap();
    let data = data_set("ident.csv", &truth, &qs, Kind::Pose, None, 1);
    let cal = calibrate(&file, &data, None, &CalibrationOptions::default()).unwrap();
    let calibrated = cal.model_file;
    let export = controllers::export(&calibrated, Controller::UrYaml).unwrap();
    let seg = read_ur_yaml(&export.text);
    assert_eq!(seg.len(), 6, "{}", export.text);
    let frames = calibrated.frames.as_ref().expect("tracker calibration has frames");
    let model = calibrated.build();
    // The calibrated chain's own tool, seen from tool0 (the written file leaves it to the TCP).
    let kinecal::io::model_file::MechanismSpec::Serial(chain) = &calibrated.mechanism else {
        panic!("serial")
    };
    let leftover = ur_forward(&seg, &[0.0; 6]).try_inverse().unwrap() * matrix_of(&chain.forward(&[0.0; 6]).unwrap());
    let (mut pmax, mut rmax) = (0.0f64, 0.0f64);
    for q in random_configurations(&*nominal, &inputs, 200, &mut rng).unwrap() {
        let yaml = matrix_of(&frames.measurement) * ur_forward(&seg, &q) * leftover * matrix_of(&frames.tool);
        let (dp, dr) = apart(&yaml, &matrix_of(&model.forward(&q).unwrap()));
        pmax = pmax.max(dp);
        rmax = rmax.max(dr);
    }
    eprintln!(
        "UR5e calibrated → ur-yaml: independent FK vs calibrated model {pmax:.2e} mm, {rmax:.2e} rad; printed {}",
        export.projection.difference
    );
    assert!(pmax < 1e-9 && rmax < 1e-9, "{pmax:e} mm, {rmax:e} rad");
    // The chain's tool stays where the calibration put it: only a small leftover (the frames
    // carry the tool), and the library says so.
    let d = export.projection.difference;
    assert!(d.position_max_mm < 1e-9 && d.rotation_max_rad.unwrap() < 1e-9, "{d}");
    assert!(export.projection.not_represented.is_empty());
    assert!(export.projection.not_written.iter().any(|l| l.starts_with("measurement frame")));
    // The truth's joint geometry is what the file holds: the same tool0 poses as the truth's
    // chain up to the frames, i.e. the calibration reached the truth through the file too.
    let truth_poses: Vec<_> = qs.iter().take(5).map(|q| truth.forward(q).unwrap()).collect();
    for (q, t) in qs.iter().take(5).zip(truth_poses) {
        let yaml = matrix_of(&frames.measurement) * ur_forward(&seg, q) * leftover * matrix_of(&frames.tool);
        let (dp, _) = apart(&yaml, &matrix_of(&t));
        assert!(dp < 1e-6, "against the truth: {dp:e} mm");
    }
}

/// ur_description's default kinematics of a UR5e (the nominal values, as the factory file
/// writes them: π/2 to 10 digits).
const UR5E_DEFAULT: &str = "kinematics:
  shoulder:
    x: 0
    y: 0
    z: 0.1625
    roll: 0
    pitch: 0
    yaw: 0
  upper_arm:
    x: 0
    y: 0
    z: 0
    roll: 1.570796327
    pitch: 0
    yaw: 0
  forearm:
    x: -0.425
    y: 0
    z: 0
    roll: 0
    pitch: 0
    yaw: 0
  wrist_1:
    x: -0.3922
    y: 0
    z: 0.1333
    roll: 0
    pitch: 0
    yaw: 0
  wrist_2:
    x: 0
    y: -0.0997
    z: 0
    roll: 1.570796327
    pitch: 0
    yaw: 0
  wrist_3:
    x: 0
    y: 0.0996
    z: 0
    roll: 1.570796326589793
    pitch: 3.141592653589793
    yaw: 3.141592653589793
  hash: \"calib_12345678901234567890\"
";

/// The factory (nominal) YAML of a UR5e imports to the URDF's geometry.
#[test]
fn factory_ur5e_yaml_imports_to_the_urdf_geometry() {
    let from_yaml = controllers::import(UR5E_DEFAULT, Controller::UrYaml).unwrap().build();
    let from_urdf = kinecal::io::urdf::import(&crate::urdf::ur5e_urdf(), None, None).unwrap().build();
    assert_eq!(from_yaml.input_names(), from_urdf.input_names());
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let file = kinecal::io::urdf::import(&crate::urdf::ur5e_urdf(), None, None).unwrap();
    let (mut pmax, mut rmax) = (0.0f64, 0.0f64);
    for q in random_configurations(&*from_urdf, &file.inputs(), 200, &mut rng).unwrap() {
        let (dp, dr) = apart(
            &matrix_of(&from_yaml.forward(&q).unwrap()),
            &matrix_of(&from_urdf.forward(&q).unwrap()),
        );
        pmax = pmax.max(dp);
        rmax = rmax.max(dr);
    }
    // The file's π/2 has 10 digits: 3.3e-10 rad per joint.
    assert!(pmax < 2e-6 && rmax < 2e-9, "{pmax:e} mm, {rmax:e} rad");
}

/// Written, imported, written again: byte for byte (also through the model file's TOML), for
/// the nominal UR5e and a calibrated-like one with errors in every joint frame.
#[test]
fn ur_yaml_round_trips_byte_for_byte() {
    let file = kinecal::io::urdf::import(&crate::urdf::ur5e_urdf(), None, None).unwrap();
    let nominal = file.build();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (proto, _) = virtual_prototype(&nominal, &file.free_indices().unwrap(), 2.0, 0.5f64.to_radians(), &mut rng);
    for f in [file.clone(), file.with_geometry_of(&*proto).unwrap()] {
        let text = controllers::export(&f, Controller::UrYaml).unwrap().text;
        let back = controllers::import(&text, Controller::UrYaml).unwrap();
        assert_eq!(controllers::export(&back, Controller::UrYaml).unwrap().text, text);
        let toml = back.to_toml().unwrap();
        let again = ModelFile::load_str(Path::new("ur.toml"), &toml).unwrap();
        assert_eq!(controllers::export(&again, Controller::UrYaml).unwrap().text, text);
    }
}

/// Every broken UR YAML: one error naming its line.
#[test]
fn malformed_ur_yaml_names_the_line() {
    let good = controllers::export(
        &kinecal::io::urdf::import(&crate::urdf::ur5e_urdf(), None, None).unwrap(),
        Controller::UrYaml,
    )
    .unwrap()
    .text;
    let line_of = |needle: &str| good.lines().position(|l| l.contains(needle)).unwrap() + 1;
    let forearm_x = line_of("    x: -0.4250000000000");
    let cases: Vec<(String, usize)> = vec![
        (good.replace("    x: -0.4250000000000", "    x: abc"), forearm_x),
        (good.replace("    x: -0.4250000000000", "    q: 1"), forearm_x),
        (good.replace("  forearm:", "  elbow:"), line_of("  forearm:")),
        (good.replace("    x: -0.4250000000000\n", ""), line_of("  forearm:")),
        (good.replace("    x: -0.4250000000000", "    x: nan"), forearm_x),
        (good.replace("    x: -0.4250000000000", "    just text"), forearm_x),
    ];
    for (text, line) in cases {
        match controllers::import(&text, Controller::UrYaml) {
            Err(ControllerError::Parse { line: l, message }) => assert_eq!(l, line, "{message}"),
            other => panic!("expected a parse error at line {line}, got {other:?}"),
        }
    }
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.yaml"), good.replace("    x: -0.4250000000000", "    x: abc")).unwrap();
    let err = fails(dir.path(), &["model", "import", "bad.yaml", "--format", "ur-yaml"]);
    assert!(err.starts_with(&format!("bad.yaml:{forearm_x}: ")), "{err}");
}

/// The command: export prints the difference and the frames left out; import reads the file.
#[test]
fn ur_yaml_through_the_cli() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("ur5e.urdf"), crate::urdf::ur5e_urdf()).unwrap();
    ok(dir.path(), &["model", "import", "ur5e.urdf", "--out", "ur5e.toml"]);
    let out = ok(
        dir.path(),
        &["model", "export", "ur5e.toml", "--format", "ur-yaml", "--out", "ur5e.yaml"],
    );
    assert!(out.contains("ur-yaml: tool position max"), "{out}");
    ok(
        dir.path(),
        &["model", "import", "ur5e.yaml", "--format", "ur-yaml", "--out", "back.toml"],
    );
    let again = ok(dir.path(), &["model", "export", "back.toml", "--format", "ur-yaml"]);
    assert_eq!(again, std::fs::read_to_string(dir.path().join("ur5e.yaml")).unwrap());
}

// ---------------------------------------------------------------- LinuxCNC genhexkins

/// The genhexkins HAL file read here: (base, platform, offset) per strut.
fn read_genhex(text: &str) -> ([[f64; 3]; 6], [[f64; 3]; 6], [f64; 6]) {
    let (mut b, mut p, mut o) = ([[0.0; 3]; 6], [[0.0; 3]; 6], [0.0; 6]);
    for line in text.lines().filter(|l| l.starts_with("setp ")) {
        let w: Vec<&str> = line.split_whitespace().collect();
        let v: f64 = w[2].parse().unwrap();
        let n: Vec<&str> = w[1].split('.').collect();
        let i: usize = n[n.len() - 2].parse().unwrap_or_else(|_| n[1].parse().unwrap());
        match n.as_slice() {
            ["genhexkins", "base", _, a] => b[i][["x", "y", "z"].iter().position(|x| x == a).unwrap()] = v,
            ["genhexkins", "platform", _, a] => p[i][["x", "y", "z"].iter().position(|x| x == a).unwrap()] = v,
            ["offset", _, "offset"] => o[i] = v,
            _ => panic!("{line}"),
        }
    }
    (b, p, o)
}

/// genhexkins's inverse kinematics (strut length) plus the documented offset: the actuator
/// positions at platform pose `t`.
fn genhex_inputs(g: &([[f64; 3]; 6], [[f64; 3]; 6], [f64; 6]), t: &Matrix4<f64>) -> [f64; 6] {
    std::array::from_fn(|i| {
        let a = t * nalgebra::Vector4::new(g.1[i][0], g.1[i][1], g.1[i][2], 1.0);
        (Vector3::new(a.x, a.y, a.z) - Vector3::from(g.0[i])).norm() + g.2[i]
    })
}

/// The built-in Stewart platform with random errors in all 42 joint points and lengths,
/// calibrated from noise-free tracker poses: genhexkins's inverse kinematics with the written
/// parameters gives kinecal's calibrated inverse kinematics to 1e-9 mm.
#[test]
fn calibrated_stewart_written_for_genhexkins_gives_the_calibrated_leg_lengths() {
    let file = kinecal::io::builtin::model_file("stewart").unwrap();
    let nominal = file.build();
    let mut rng = ChaCha8Rng::seed_from_u64(48);
    let (proto, _) = virtual_prototype(&nominal, &file.free_indices().unwrap(), 0.5, 0.1f64.to_radians(), &mut rng);
    let truth = Framed::new(proto, tracker(), tool());
    let inputs = file.inputs();
    let qs = random_configurations(&*nominal, &inputs, 60, &mut rng).unwrap();
    let data = data_set("ident.csv", &truth, &qs, Kind::Pose, None, 1);
    let cal = calibrate(&file, &data, None, &CalibrationOptions::default()).unwrap();
    let export = controllers::export(&cal.model_file, Controller::LinuxcncHexapod).unwrap();
    let g = read_genhex(&export.text);
    let machine = cal.model_file.mechanism.build();
    let mut worst = 0.0f64;
    for q in random_configurations(&*machine, &inputs, 200, &mut rng).unwrap() {
        let t = machine.forward(&q).unwrap();
        let kinecal_ik = machine.inverse(&t, None).unwrap();
        let genhex = genhex_inputs(&g, &matrix_of(&t));
        for i in 0..6 {
            worst = worst.max((genhex[i] - kinecal_ik[i]).abs());
        }
    }
    eprintln!(
        "calibrated stewart → linuxcnc-hexapod: independent IK vs calibrated IK {worst:.2e} mm; printed {}",
        export.projection.difference
    );
    assert!(worst < 1e-9, "{worst:e} mm");
    assert!(export.projection.not_represented.is_empty());
    assert!(
        export.projection.difference.position_max_mm < 1e-8,
        "{}",
        export.projection.difference
    );
    // Round trip byte for byte, also through the model file.
    let back = controllers::import(&export.text, Controller::LinuxcncHexapod).unwrap();
    assert_eq!(controllers::export(&back, Controller::LinuxcncHexapod).unwrap().text, export.text);
    let again = ModelFile::load_str(Path::new("h.toml"), &back.to_toml().unwrap()).unwrap();
    assert_eq!(controllers::export(&again, Controller::LinuxcncHexapod).unwrap().text, export.text);
}

/// The Stewart platform as limbs with random errors of every kind its free parameters allow:
/// the per-leg projection leaves a strut-length residual where a limb is more than two points
/// and a length; genhexkins's inverse kinematics with the written parameters is within that
/// residual of the model's, and the pose difference printed is the forward kinematics'.
#[test]
fn stewart_limbs_projected_for_genhexkins_leave_the_printed_residual() {
    let file = kinecal::io::builtin::model_file("stewart-limbs").unwrap();
    let nominal = file.build();
    let mut rng = ChaCha8Rng::seed_from_u64(49);
    // Every error coordinate of the limbs, also those the calibration holds as drawn (actuator
    // axes off the universal joints' centres, joint axes): not all of them are genhexkins's.
    let all: Vec<usize> = (0..nominal.n_params()).collect();
    let (proto, _) = virtual_prototype(&nominal, &all, 0.5, 0.2f64.to_radians(), &mut rng);
    let model = file.with_geometry_of(&*proto).unwrap();
    let export = controllers::export(&model, Controller::LinuxcncHexapod).unwrap();
    let fit = export.projection.fit_residual_mm.expect("a least-squares projection");
    let g = read_genhex(&export.text);
    let machine = model.mechanism.build();
    let mut worst = 0.0f64;
    for q in random_configurations(&*machine, &model.inputs(), 200, &mut rng).unwrap() {
        let t = machine.forward(&q).unwrap();
        let genhex = genhex_inputs(&g, &matrix_of(&t));
        for i in 0..6 {
            worst = worst.max((genhex[i] - q[i]).abs());
        }
    }
    eprintln!(
        "stewart-limbs with errors → linuxcnc-hexapod: strut residual {fit:.2e} mm (fit), {worst:.2e} mm (independent IK, other poses); printed {}; {:?}",
        export.projection.difference, export.projection.not_represented
    );
    assert!(worst <= 1.5 * fit + 1e-9, "independent {worst:e} mm vs printed {fit:e} mm");
    assert!(fit > 1e-6, "these errors are not all representable: residual {fit:e} mm");
    assert!(!export.projection.not_represented.is_empty());
    assert!(export.projection.difference.position_max_mm > 1e-6);
}

/// Every broken genhexkins file: one error naming its line; the command prints file:line.
#[test]
fn malformed_genhexkins_file_names_the_line() {
    let good = controllers::export(&kinecal::io::builtin::model_file("stewart").unwrap(), Controller::LinuxcncHexapod)
        .unwrap()
        .text;
    let target = good
        .lines()
        .find(|l| l.starts_with("setp genhexkins.platform.3.y"))
        .unwrap()
        .to_string();
    let line = good.lines().position(|l| l == target).unwrap() + 1;
    for bad in [
        "setp genhexkins.platform.3.y x1".to_string(),
        "setp genhexkins.platform.9.y 1".into(),
        "setp genhexkins.platform.3.w 1".into(),
        "net genhexkins.platform.3.y 1".into(),
        "setp genhexkins.platform.3.y".into(),
        "setp genhexkins.platform.0.x 1".into(),
    ] {
        let text = good.replace(&target, &bad);
        match controllers::import(&text, Controller::LinuxcncHexapod) {
            Err(ControllerError::Parse { line: l, message }) => assert_eq!(l, line, "{bad}: {message}"),
            other => panic!("{bad}: expected a parse error at line {line}, got {other:?}"),
        }
    }
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("hex.hal"), good.replace(&target, "setp genhexkins.platform.3.y x1")).unwrap();
    let err = fails(dir.path(), &["model", "import", "hex.hal", "--format", "linuxcnc-hexapod"]);
    assert!(err.starts_with(&format!("hex.hal:{line}: ")), "{err}");
}

// ---------------------------------------------------------------- Klipper delta

/// A Klipper delta's parameters read here from printer.cfg text: (R, angles °, arms, endstops).
fn read_klipper(text: &str) -> (f64, [f64; 3], [f64; 3], [f64; 3]) {
    let (mut r, mut a, mut l, mut e) = (0.0, [0.0; 3], [0.0; 3], [0.0; 3]);
    let mut tower = 0;
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        if let Some(t) = line.strip_prefix("[stepper_") {
            tower = ["a]", "b]", "c]"].iter().position(|x| *x == t).unwrap();
        } else if let Some((k, v)) = line.split_once(':') {
            let v = v.trim();
            match k {
                "delta_radius" => r = v.parse().unwrap(),
                "angle" => a[tower] = v.parse().unwrap(),
                "arm_length" => l[tower] = v.parse().unwrap(),
                "position_endstop" => e[tower] = v.parse().unwrap(),
                _ => {}
            }
        }
    }
    (r, a, l, e)
}

/// Klipper's delta forward kinematics, written here by Newton on the three rod equations from
/// below the towers' centre: the nozzle at carriage heights `h`.
fn delta_forward(k: &(f64, [f64; 3], [f64; 3], [f64; 3]), h: &[f64; 3]) -> Vector3<f64> {
    let towers: Vec<Vector3<f64>> = (0..3)
        .map(|i| {
            let a = k.1[i].to_radians();
            Vector3::new(k.0 * a.cos(), k.0 * a.sin(), h[i])
        })
        .collect();
    let mut p = Vector3::new(0.0, 0.0, h.iter().sum::<f64>() / 3.0 - k.2[0]);
    for _ in 0..100 {
        let f = Vector3::from_fn(|i, _| (p - towers[i]).norm_squared() - k.2[i] * k.2[i]);
        let j = Matrix3::from_fn(|i, c| 2.0 * (p - towers[i])[c]);
        let step = j.lu().solve(&-f).unwrap();
        p += step;
        if step.norm() < 1e-13 {
            break;
        }
    }
    p
}

/// Errors of exactly the kinds Klipper models (radius, tower angles, arm lengths, endstops) on a
/// delta from printer.cfg: the projection recovers them to 1e-9 mm (noise-free, as fitted).
#[test]
fn klipper_kinds_of_error_are_recovered() {
    use kinecal::io::controllers::klipper_delta::{from_model, KlipperDelta, KlipperOptions};
    let mut rng = ChaCha8Rng::seed_from_u64(50);
    let mut u = || rand::RngExt::random_range(&mut rng, -1.0..1.0);
    let truth = KlipperDelta {
        radius: 140.0 + u(),
        angle: [210.0 + 0.5 * u(), 330.0 + 0.5 * u(), 90.0 + 0.5 * u()],
        arm_length: [250.0 + u(), 250.0 + u(), 250.0 + u()],
        position_endstop: [250.0 + u(), 250.0 + u(), 250.0 + u()],
    };
    let model = truth.model_file().unwrap();
    let fit = from_model(&model, &KlipperOptions::default()).unwrap();
    let (k, origin, residual, lost) = (fit.delta, fit.frame.translation.vector, fit.fit_residual_mm, fit.lost);
    let wrap = |a: f64| (a + 540.0).rem_euclid(360.0) - 180.0;
    let mut worst = (k.radius - truth.radius).abs();
    for i in 0..3 {
        worst = worst
            .max(wrap(k.angle[i] - truth.angle[i]).to_radians().abs() * truth.radius)
            .max((k.arm_length[i] - truth.arm_length[i]).abs())
            .max((k.position_endstop[i] - truth.position_endstop[i]).abs());
    }
    eprintln!("Klipper-kind errors: recovered to {worst:.2e} mm (fit residual {residual:.2e} mm)");
    assert!(worst < 1e-9, "{worst:e} mm: {k:?} vs {truth:?}");
    assert!(origin[0].abs() < 1e-9 && origin[1].abs() < 1e-9, "{origin:?}");
    assert!(
        !lost.iter().any(|l| l.starts_with("geometry beyond") || l.contains("leans")),
        "{lost:?}"
    );
    // Round trip byte for byte, also through the model file.
    let text = controllers::export(&model, Controller::KlipperDelta).unwrap().text;
    let back = controllers::import(&text, Controller::KlipperDelta).unwrap();
    assert_eq!(controllers::export(&back, Controller::KlipperDelta).unwrap().text, text);
    let again = ModelFile::load_str(Path::new("k.toml"), &back.to_toml().unwrap()).unwrap();
    assert_eq!(controllers::export(&again, Controller::KlipperDelta).unwrap().text, text);
}

/// The built-in linear delta with random errors in every free parameter (rail tilts and joint
/// axes among them), calibrated from noise-free tracker positions: the written parameters,
/// evaluated by the delta forward kinematics written here, leave the printed difference.
#[test]
fn calibrated_linear_delta_written_for_klipper_leaves_the_printed_residual() {
    use kinecal::io::controllers::klipper_delta::{from_model, KlipperOptions};
    let file = kinecal::io::builtin::model_file("linear-delta").unwrap();
    let nominal = file.build();
    let mut rng = ChaCha8Rng::seed_from_u64(51);
    let (proto, _) = virtual_prototype(&nominal, &file.free_indices().unwrap(), 0.5, 0.1f64.to_radians(), &mut rng);
    let truth = Framed::new(proto, tracker(), tool());
    let inputs = file.inputs();
    let qs = random_configurations(&*nominal, &inputs, 60, &mut rng).unwrap();
    let data = data_set("ident.csv", &truth, &qs, Kind::Position, None, 1);
    let cal = calibrate(&file, &data, None, &CalibrationOptions::default()).unwrap();
    let export = controllers::export(&cal.model_file, Controller::KlipperDelta).unwrap();
    let printed = export.projection.difference;
    let k = read_klipper(&export.text);
    let origin = from_model(&cal.model_file, &KlipperOptions::default())
        .unwrap()
        .frame
        .translation
        .vector;
    let machine = cal.model_file.mechanism.build();
    let upper: Vec<f64> = inputs.iter().map(|i| i.limits.unwrap().1).collect();
    let mut worst = 0.0f64;
    for q in random_configurations(&*machine, &inputs, 200, &mut rng).unwrap() {
        // Carriage heights in Klipper: the endstop input (upper limit) is the endstop height.
        let h: [f64; 3] = std::array::from_fn(|i| q[i] - upper[i] + k.3[i] + (k.2[i] * k.2[i] - k.0 * k.0).sqrt());
        let p = delta_forward(&k, &h) + Vector3::new(origin[0], origin[1], 0.0);
        worst = worst.max((p - machine.forward(&q).unwrap().translation.vector).norm());
    }
    eprintln!(
        "calibrated linear-delta → klipper-delta: independent FK vs calibrated model {worst:.3e} mm; printed {printed}; {:?}",
        export.projection.not_represented
    );
    assert!(worst <= 1.5 * printed.position_max_mm + 1e-6, "{worst:e} vs printed {printed}");
    assert!(printed.position_max_mm > 1e-4, "rail tilts are not Klipper's: {printed}");
    // The rail tilts are named among what Klipper cannot represent.
    let named = &export.projection.not_represented;
    assert!(named.iter().any(|l| l.starts_with("arm1.0-1.wy:")), "{named:?}");
}

/// Every broken printer.cfg: one error naming its line; the command prints file:line.
#[test]
fn malformed_printer_cfg_names_the_line() {
    let good = controllers::export(&kinecal::io::builtin::model_file("linear-delta").unwrap(), Controller::KlipperDelta)
        .unwrap()
        .text;
    let target = "arm_length: 250.0000000000";
    let line = good.lines().position(|l| l == target).unwrap() + 1;
    for bad in ["arm_length: long", "arm_length: 10", "arm_length 250", "[stepper_a"] {
        let text = good.replacen(target, bad, 1);
        match controllers::import(&text, Controller::KlipperDelta) {
            Err(ControllerError::Parse { line: l, message }) => assert_eq!(l, line, "{bad}: {message}"),
            other => panic!("{bad}: expected a parse error at line {line}, got {other:?}"),
        }
    }
    let text = good.replace("kinematics: delta", "kinematics: corexy");
    let kline = good.lines().position(|l| l == "kinematics: delta").unwrap() + 1;
    assert!(matches!(controllers::import(&text, Controller::KlipperDelta), Err(ControllerError::Parse { line, .. }) if line == kline));
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("printer.cfg"), good.replacen(target, "arm_length: long", 1)).unwrap();
    let err = fails(dir.path(), &["model", "import", "printer.cfg", "--format", "klipper-delta"]);
    assert!(err.starts_with(&format!("printer.cfg:{line}: ")), "{err}");
}

// ---------------------------------------------------------------- mutated files

/// A valid file of each format: (format, text).
fn controller_fixtures() -> &'static Vec<(Controller, String)> {
    static F: std::sync::OnceLock<Vec<(Controller, String)>> = std::sync::OnceLock::new();
    F.get_or_init(|| {
        let ur = kinecal::io::urdf::import(&crate::urdf::ur5e_urdf(), None, None).unwrap();
        vec![
            (Controller::UrYaml, controllers::export(&ur, Controller::UrYaml).unwrap().text),
            (
                Controller::LinuxcncHexapod,
                controllers::export(&kinecal::io::builtin::model_file("stewart").unwrap(), Controller::LinuxcncHexapod)
                    .unwrap()
                    .text,
            ),
            (
                Controller::KlipperDelta,
                controllers::export(&kinecal::io::builtin::model_file("linear-delta").unwrap(), Controller::KlipperDelta)
                    .unwrap()
                    .text,
            ),
        ]
    })
}

/// Import, and export what imports: a value or a typed error within the watchdog, no panic.
fn controller_answer(c: Controller, text: String) -> Result<(), String> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let r = std::panic::catch_unwind(|| {
            if let Ok(file) = controllers::import(&text, c) {
                let _ = controllers::export(&file, c);
            }
        });
        let _ = tx.send(r.is_ok());
    });
    match rx.recv_timeout(std::time::Duration::from_secs(20)) {
        Ok(true) => Ok(()),
        Ok(false) => Err("panicked".into()),
        Err(_) => Err("no answer within 20 s".into()),
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { rng_seed: proptest::test_runner::RngSeed::Fixed(20261129), ..proptest::prelude::ProptestConfig::with_cases(48) })]

    #[test]
    fn mutated_controller_files_get_an_answer(kind in 0usize..3, at in 0.0..1.0f64, len in 0usize..6,
        with in proptest::sample::select(vec!["0", "-0", "1e308", "-1e308", "1e-308", "NaN", "inf", "", "x", ":", "[", "\n", "-", "  "])) {
        let (c, text) = controller_fixtures()[kind].clone();
        let chars: Vec<char> = text.chars().collect();
        let i = ((at * chars.len() as f64) as usize).min(chars.len());
        let j = (i + len).min(chars.len());
        let mutated = chars[..i].iter().collect::<String>() + with + &chars[j..].iter().collect::<String>();
        let r = controller_answer(c, mutated);
        proptest::prop_assert!(r.is_ok(), "{:?}: {} mutated at {at:.3} ({len} chars → {with:?})", r, c.name());
    }
}
