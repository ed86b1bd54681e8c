//! Built-in models: nominal geometries a user can export as model files
//! (`kinecal model list`, `kinecal model export NAME`, through [`crate::io::builtin`]), edit and
//! load back.
use crate::model::chain::SerialChain;
use crate::model::kind::MechanismSpec;
use crate::model::presets::pm5::{Parasitic, Pm5};
use crate::model::presets::stewart::{Stewart, StewartGeometry};

/// Names and one-line descriptions of the built-in models.
pub fn list() -> Vec<(&'static str, &'static str)> {
    vec![
        (
            "irb120",
            "ABB IRB 120 6R serial arm, nominal (d1 290, a2 270, a3 70, d4 302, d6 72 mm), tool at the flange",
        ),
        (
            "pm5",
            "5-DOF PUU-2PR(RPRR)S parallel machine of the 5-DOF paper, nominal (44 error parameters, physical parasitic constraint)",
        ),
        (
            "stewart",
            "6-UPS Stewart platform, nominal (base r 200 mm, platform r 100 mm, home z 300 mm; 42 error parameters)",
        ),
    ]
}

/// The built-in model called `name`, if there is one.
pub fn spec(name: &str) -> Option<MechanismSpec> {
    Some(match name {
        "irb120" => MechanismSpec::Serial(irb120()),
        "pm5" => MechanismSpec::Pm5(Pm5::mechanism(Parasitic::Physical)),
        "stewart" => MechanismSpec::Stewart(Stewart::mechanism(StewartGeometry::default())),
        _ => return None,
    })
}

/// The nominal ABB IRB 120 (see [`crate::model::irb120`]).
pub fn irb120() -> SerialChain {
    crate::model::irb120::nominal()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Mechanism;
    use approx::assert_relative_eq;
    use nalgebra::Vector3;

    #[test]
    fn irb120_home_flange() {
        let t = irb120().forward(&[0.0; 6]).unwrap();
        assert_relative_eq!(t.translation.vector, Vector3::new(374.0, 0.0, 630.0), epsilon = 1e-12);
    }

    #[test]
    fn every_listed_model_exists() {
        for (n, _) in list() {
            assert!(spec(n).is_some(), "{n}");
        }
        assert!(spec("nope").is_none());
    }
}
