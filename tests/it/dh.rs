//! DH and modified-DH tables as model files: built into the local-POE chain, written back where
//! the geometry allows, Hayati's β for nearly parallel axes.
use kinecal::identifiability;
use kinecal::identify::linearize;
use kinecal::io::builtin;
use kinecal::io::model_file::{MechanismSpec, ModelFile};
use kinecal::measure::{Measurement, Noise, Observation};
use kinecal::model::dh::{DhConvention, DhError, DhOptions};
use kinecal::se3::{self, Pose};
use kinecal::simulate::random_inputs;
use kinecal::Mechanism;
use nalgebra::{DVector, Matrix4};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;

fn load(text: &str) -> Result<ModelFile, String> {
    ModelFile::load_str(Path::new("m.toml"), text).map_err(|e| e.to_string())
}

/// The UR5e's published standard DH table (Universal Robots), in metres and degrees.
pub const UR5E_DH: &str = r#"
name = "ur5e"
[units]
length = "m"
angle = "deg"
[mechanism]
kind = "serial"
[[mechanism.dh]]
name = "shoulder_pan_joint"
type = "revolute"
a = 0.0
alpha = 90.0
d = 0.1625
theta = 0.0
limits = [-360.0, 360.0]
[[mechanism.dh]]
name = "shoulder_lift_joint"
type = "revolute"
a = -0.425
alpha = 0.0
d = 0.0
theta = 0.0
limits = [-360.0, 360.0]
[[mechanism.dh]]
name = "elbow_joint"
type = "revolute"
a = -0.3922
alpha = 0.0
d = 0.0
theta = 0.0
limits = [-180.0, 180.0]
[[mechanism.dh]]
name = "wrist_1_joint"
type = "revolute"
a = 0.0
alpha = 90.0
d = 0.1333
theta = 0.0
limits = [-360.0, 360.0]
[[mechanism.dh]]
name = "wrist_2_joint"
type = "revolute"
a = 0.0
alpha = -90.0
d = 0.0997
theta = 0.0
limits = [-360.0, 360.0]
[[mechanism.dh]]
name = "wrist_3_joint"
type = "revolute"
a = 0.0
alpha = 0.0
d = 0.0996
theta = 0.0
limits = [-360.0, 360.0]
"#;

/// Standard DH by 4×4 matrices, written out independently of the library (mm, rad).
fn dh_matrix(theta: f64, d: f64, a: f64, alpha: f64) -> Matrix4<f64> {
    let (ct, st, ca, sa) = (theta.cos(), theta.sin(), alpha.cos(), alpha.sin());
    Matrix4::new(
        ct,
        -st * ca,
        st * sa,
        a * ct,
        st,
        ct * ca,
        -ct * sa,
        a * st,
        0.0,
        sa,
        ca,
        d,
        0.0,
        0.0,
        0.0,
        1.0,
    )
}

/// Modified DH (Craig) by 4×4 matrices: Rx(α)·Tx(a)·Rz(θ)·Tz(d).
fn mdh_matrix(alpha: f64, a: f64, theta: f64, d: f64) -> Matrix4<f64> {
    let (ct, st, ca, sa) = (theta.cos(), theta.sin(), alpha.cos(), alpha.sin());
    Matrix4::new(
        ct,
        -st,
        0.0,
        a,
        st * ca,
        ct * ca,
        -sa,
        -sa * d,
        st * sa,
        ct * sa,
        ca,
        ca * d,
        0.0,
        0.0,
        0.0,
        1.0,
    )
}

fn position_gap(a: &Pose, m: &Matrix4<f64>) -> f64 {
    (a.translation.vector - m.fixed_view::<3, 1>(0, 3)).norm()
}

fn configurations(file: &ModelFile, n: usize, seed: u64) -> Vec<Vec<f64>> {
    random_inputs(&file.inputs(), n, &mut ChaCha8Rng::seed_from_u64(seed))
}

#[test]
fn ur5e_dh_file_equals_the_dh_formula() {
    let file = load(UR5E_DH).unwrap();
    let chain = file.build();
    let a = [0.0, -425.0, -392.2, 0.0, 0.0, 0.0];
    let d = [162.5, 0.0, 0.0, 133.3, 99.7, 99.6];
    let alpha = [90f64, 0.0, 0.0, 90.0, -90.0, 0.0].map(f64::to_radians);
    let mut worst: f64 = 0.0;
    for q in configurations(&file, 1000, 1) {
        let mut m = Matrix4::<f64>::identity();
        for i in 0..6 {
            m *= dh_matrix(q[i], d[i], a[i], alpha[i]);
        }
        let g = chain.forward(&q).unwrap();
        worst = worst.max(position_gap(&g, &m));
        assert!((g.to_homogeneous().fixed_view::<3, 3>(0, 0) - m.fixed_view::<3, 3>(0, 0)).amax() < 1e-12);
    }
    assert!(worst < 1e-9, "{worst:e} mm");
    // Limits in degrees became radians.
    assert_eq!(file.inputs()[2].limits, Some((-std::f64::consts::PI, std::f64::consts::PI)));
}

/// The IRB 120 in Craig's modified DH (α_{i-1}, a_{i-1}, θ_i, d_i as in pybotics' model), with
/// its flange as the tool: equal to the built-in local-POE IRB 120.
#[test]
fn irb120_modified_dh_equals_the_builtin() {
    use std::f64::consts::{FRAC_PI_2, PI};
    let rows = [
        (0.0, 0.0, 0.0, 290.0),
        (-FRAC_PI_2, 0.0, -FRAC_PI_2, 0.0),
        (0.0, 270.0, 0.0, 0.0),
        (-FRAC_PI_2, 70.0, 0.0, 302.0),
        (FRAC_PI_2, 0.0, 0.0, 0.0),
        (-FRAC_PI_2, 0.0, PI, 0.0),
    ];
    let mut text = String::from("name = \"irb120\"\n[units]\nlength = \"mm\"\nangle = \"rad\"\n[mechanism]\nkind = \"serial\"\n");
    for (i, (alpha, a, theta, d)) in rows.iter().enumerate() {
        text += &format!(
            "[[mechanism.mdh]]\nname = \"q{}\"\ntype = \"revolute\"\nalpha = {alpha:?}\na = {a:?}\ntheta = {theta:?}\nd = {d:?}\n",
            i + 1
        );
    }
    // pybotics' flange frame is the built-in's turned by Ry(90°) (z out of the flange), 72 mm on.
    text += "[mechanism.tool]\nposition = [0.0, 0.0, 72.0]\nrpy = [0.0, 0.0, 0.0]\n";
    let file = load(&text).unwrap();
    let mdh = file.build();
    let builtin = builtin::irb120();
    let turn = Pose::from_parts(
        nalgebra::Translation3::identity(),
        nalgebra::UnitQuaternion::from_axis_angle(&nalgebra::Vector3::y_axis(), FRAC_PI_2),
    );
    let mut worst: f64 = 0.0;
    for q in configurations(&builtin::model_file("irb120").unwrap(), 1000, 2) {
        // The formula by matrices, independently of the library.
        let mut m = Matrix4::<f64>::identity();
        for (i, (alpha, a, theta, d)) in rows.iter().enumerate() {
            m *= mdh_matrix(*alpha, *a, theta + q[i], *d);
        }
        let g = mdh.forward(&q).unwrap();
        let via_matrices = m * se3::translation(0.0, 0.0, 72.0).to_homogeneous();
        worst = worst.max(position_gap(&g, &via_matrices));
        let b = builtin.forward(&q).unwrap() * turn;
        let e = se3::pose_error(&g, &b);
        worst = worst.max(se3::lin(&e).norm());
        assert!(se3::ang(&e).norm() < 1e-12, "{e}");
    }
    assert!(worst < 1e-9, "{worst:e} mm");
}

fn same_fk(a: &dyn Mechanism, b: &dyn Mechanism, configurations: &[Vec<f64>]) -> f64 {
    configurations
        .iter()
        .map(|q| {
            let e = se3::pose_error(&a.forward(q).unwrap(), &b.forward(q).unwrap());
            assert!(se3::ang(&e).norm() < 1e-11, "{} rad", se3::ang(&e).norm());
            se3::lin(&e).norm()
        })
        .fold(0.0, f64::max)
}

#[test]
fn written_as_dh_and_mdh_and_loaded_back_the_kinematics_are_the_same() {
    for name in ["irb120"] {
        let file = builtin::model_file(name).unwrap();
        let qs = configurations(&file, 1000, 3);
        for convention in [DhConvention::Standard, DhConvention::Modified] {
            let text = file.to_toml_dh(convention, DhOptions::default()).unwrap();
            assert!(text.contains(&format!("[[mechanism.{}]]", convention.key())), "{text}");
            let back = load(&text).unwrap();
            assert_eq!(back.inputs(), file.inputs());
            let gap = same_fk(&*file.build(), &*back.build(), &qs);
            assert!(gap < 1e-9, "{convention:?}: {gap:e} mm");
        }
    }
    // The UR5e's own table comes back as published, in its own units.
    let ur = load(UR5E_DH).unwrap();
    let again = ur.to_toml_dh(DhConvention::Standard, DhOptions::default()).unwrap();
    for line in ["a = -0.425", "a = -0.3922", "d = 0.1333", "alpha = -90.0", "d = 0.0996"] {
        assert!(again.contains(line), "{line} missing from\n{again}");
    }
}

/// A calibrated IRB 120 (every dyad moved): joints 2 and 3 are no longer exactly parallel, so
/// plain DH fails naming them, and Hayati's β reproduces the calibrated kinematics.
#[test]
fn nearly_parallel_axes_need_hayati() {
    let file = builtin::model_file("irb120").unwrap();
    let mut m = file.build();
    let delta = DVector::from_fn(m.n_params(), |i, _| ((i as f64) * 1.3).sin() * 2e-3);
    m.retract(&delta);
    let cal = file.with_geometry_of(&*m).unwrap();
    for convention in [DhConvention::Standard, DhConvention::Modified] {
        let err = cal.to_toml_dh(convention, DhOptions::default()).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, DhError::NearlyParallel { .. }), "{msg}");
        assert!(
            msg.contains("joints q2 and q3") && msg.contains("Hayati") && !msg.contains('\n'),
            "{msg}"
        );
    }
    let text = cal.to_toml_dh(DhConvention::Standard, DhOptions { hayati: true }).unwrap();
    assert_eq!(text.matches("beta = ").count(), 1, "{text}");
    let back = load(&text).unwrap();
    let gap = same_fk(&*m, &*back.build(), &configurations(&file, 1000, 4));
    assert!(gap < 1e-9, "{gap:e} mm");
}

#[test]
fn a_dh_model_has_the_parameters_and_identifiability_of_the_chain() {
    let ur = load(UR5E_DH).unwrap();
    let MechanismSpec::Serial(chain) = &ur.mechanism else { panic!() };
    let poe = load(&ur.to_toml().unwrap()).unwrap();
    assert_eq!(ur.build().params(), poe.build().params());
    assert_eq!(ur.build().n_params(), 42);
    let data: Vec<Measurement> = configurations(&ur, 40, 5)
        .into_iter()
        .map(|q| {
            let t = chain.forward(&q).unwrap();
            Measurement {
                joints: Vec::new(),
                q,
                obs: Observation::Pose(t),
            }
        })
        .collect();
    let lin = linearize(chain, &data, &Noise::default()).unwrap();
    let all: Vec<usize> = (0..42).collect();
    let id = identifiability::analyze(&lin.jacobian, &all, identifiability::DEFAULT_RANK_TOLERANCE);
    assert_eq!(id.rank, 4 * 6 + 6);
}

#[test]
fn dh_file_mistakes_are_one_line() {
    let both = UR5E_DH.replace(
        "[[mechanism.dh]]\nname = \"shoulder_pan_joint\"",
        "[[mechanism.joints]]\nname = \"j\"\ntype = \"revolute\"\naxis = [0, 0, 1]\n[[mechanism.dh]]\nname = \"shoulder_pan_joint\"",
    );
    let e = load(&both).unwrap_err();
    assert!(e.contains("exactly one of") && !e.contains('\n'), "{e}");
    let e = load(
        &UR5E_DH
            .replace("theta = 0.0\nlimits = [-180.0", "theta = 0.0\nbeta = 1.0\nlimits = [-180.0")
            .replace("mechanism.dh", "mechanism.mdh"),
    )
    .unwrap_err();
    assert!(e.contains("m.toml:") && e.contains("beta") && e.contains("standard DH"), "{e}");
    let e = load(&UR5E_DH.replace("d = 0.1625\n", "")).unwrap_err();
    assert!(e.contains("m.toml:") && e.contains("missing field `d`"), "{e}");
    let e = load(&UR5E_DH.replace("theta = 0.0\nlimits = [-180.0", "theta_offset = 0.0\nlimits = [-180.0")).unwrap_err();
    assert!(e.contains("m.toml:") && e.contains("theta_offset"), "{e}");
}
