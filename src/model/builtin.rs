//! Built-in models: nominal geometries a user can export as model files
//! (`kinecal model list`, `kinecal model export NAME`), edit and load back.
use crate::io::model_file::{MechanismSpec, ModelFile};
use crate::model::chain::{ChainJoint, SerialChain};
use crate::se3::{self, Pose};
use nalgebra::Vector3;

/// Names and one-line descriptions of the built-in models.
pub fn list() -> Vec<(&'static str, &'static str)> {
    vec![(
        "irb120",
        "ABB IRB 120 6R serial arm, nominal (d1 290, a2 270, a3 70, d4 302, d6 72 mm), tool at the flange",
    )]
}

/// The built-in model called `name` as a model file, if there is one.
pub fn model_file(name: &str) -> Option<ModelFile> {
    let description = list().into_iter().find(|(n, _)| *n == name)?.1;
    let mechanism = match name {
        "irb120" => MechanismSpec::Serial(irb120()),
        _ => return None,
    };
    let mut file = ModelFile::new(name, mechanism);
    file.description = Some(description.to_string());
    Some(file)
}

/// The nominal ABB IRB 120 as a local-POE chain: joint axes z, y, y, x, y, x with frames at the
/// joint centres and axes parallel to the base frame at zero joint values (upper arm vertical,
/// forearm horizontal along x); d1 = 290, a2 = 270, a3 = 70, d4 = 302, d6 = 72 mm; the tool frame
/// is the flange (identity after joint 6). Limits from the product specification (deg):
/// ±165, ±110, −110…+70, ±160, ±120, ±400. At zero joint values the flange is at (374, 0, 630) mm.
pub fn irb120() -> SerialChain {
    let deg = std::f64::consts::PI / 180.0;
    // (name, axis, position in the previous joint frame (mm), limits (deg))
    type JointRow = (&'static str, Vector3<f64>, [f64; 3], (f64, f64));
    let spec: [JointRow; 6] = [
        ("q1", Vector3::z(), [0.0, 0.0, 0.0], (-165.0, 165.0)),
        ("q2", Vector3::y(), [0.0, 0.0, 290.0], (-110.0, 110.0)),
        ("q3", Vector3::y(), [0.0, 0.0, 270.0], (-110.0, 70.0)),
        ("q4", Vector3::x(), [0.0, 0.0, 70.0], (-160.0, 160.0)),
        ("q5", Vector3::y(), [302.0, 0.0, 0.0], (-120.0, 120.0)),
        ("q6", Vector3::x(), [72.0, 0.0, 0.0], (-400.0, 400.0)),
    ];
    let mut joints = Vec::new();
    let mut initial = Vec::new();
    for (name, axis, p, (lo, hi)) in spec {
        let mut j = ChainJoint::revolute(name, axis);
        j.limits = Some((lo * deg, hi * deg));
        joints.push(j);
        initial.push(se3::translation(p[0], p[1], p[2]));
    }
    SerialChain::new("irb120", joints, initial, Pose::identity())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Mechanism;
    use approx::assert_relative_eq;

    #[test]
    fn irb120_home_flange() {
        let t = irb120().forward(&[0.0; 6]).unwrap();
        assert_relative_eq!(t.translation.vector, Vector3::new(374.0, 0.0, 630.0), epsilon = 1e-12);
    }

    #[test]
    fn every_listed_model_exists() {
        for (n, _) in list() {
            assert!(model_file(n).is_some(), "{n}");
        }
        assert!(model_file("nope").is_none());
    }
}
