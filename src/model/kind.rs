//! The mechanism kinds a model file can describe ([`MechanismSpec`]) and their inputs
//! ([`InputSpec`]): the model layer's catalogue of kinds. Reading and writing them is
//! [`crate::io::model_file`]'s job; computing with them is [`MechanismSpec::build`]'s.
use crate::model::chain::{JointKind, SerialChain};
use crate::model::closed::{ClosedLoop, ConstraintSystem};
use crate::model::joint_terms::WithJointTerms;
use crate::model::limbs::LimbMechanism;
use crate::model::presets::pm5::Pm5;
use crate::model::presets::stewart::Stewart;
use crate::model::Mechanism;
use crate::params::Unit;

/// One input (actuator or sensed joint) of a mechanism: its name, unit kind and limits.
#[derive(Debug, Clone, PartialEq)]
pub struct InputSpec {
    /// Name, as in [`Mechanism::input_names`].
    pub name: String,
    /// [`Unit::Angle`] (rad) for revolute, [`Unit::Length`] (mm) for prismatic inputs.
    pub unit: Unit,
    /// Limits (rad or mm), if any.
    pub limits: Option<(f64, f64)>,
    /// For an approach-direction input (`dir_<joint>`, [`Unit::Dimensionless`], values −1, 0,
    /// +1: the sign of that joint's last motion before the pose): the index of the joint input
    /// it belongs to. A data file without the column gets it from its row order
    /// ([`crate::io::data_file`]).
    pub approach_of: Option<usize>,
    /// An observed joint's reading, not an input ([`Mechanism::observed_joints`]): a data
    /// column compared with the model. Listed after the inputs by
    /// [`MechanismSpec::data_columns`]; never among [`MechanismSpec::inputs`].
    pub observed: bool,
}

/// The kind-specific part of a model file (values in mm and rad).
#[derive(Debug, Clone, PartialEq)]
pub enum MechanismSpec {
    /// `kind = "serial"`: a local-POE serial chain.
    Serial(SerialChain),
    /// `kind = "serial"` with `[mechanism.joint_terms]`: a local-POE serial chain with
    /// non-geometric joint terms (lost motion, gravity compliance, first harmonic).
    SerialTerms(WithJointTerms),
    /// `kind = "pm5"`: the 5-DOF PUU-2PR(RPRR)S machine (44 parameters with the paper's names).
    Pm5(ClosedLoop<Pm5>),
    /// `kind = "stewart"`: a 6-UPS Stewart platform (42 parameters).
    Stewart(ClosedLoop<Stewart>),
    /// `kind = "limbs"`: any parallel (or hybrid) mechanism written as its limbs, each a chain of
    /// joints ([`LimbMechanism`]).
    Limbs(LimbMechanism),
}

/// The mechanism kinds a model file can hold, as written in `[mechanism] kind`.
pub const KINDS: [&str; 4] = ["serial", "pm5", "stewart", "limbs"];

fn closed_loop_inputs<C: ConstraintSystem>(m: &ClosedLoop<C>) -> Vec<InputSpec> {
    let s = m.system();
    s.input_names()
        .into_iter()
        .zip(s.strokes())
        .map(|(name, st)| InputSpec {
            name,
            unit: Unit::Length,
            limits: Some(st),
            approach_of: None,
            observed: false,
        })
        .collect()
}

/// Fill the approach-direction inputs that are not `present` from the order of `rows`: the sign
/// of the last change of their joint's value before each row (0 before the first change).
pub fn approach_from_order(inputs: &[InputSpec], present: &[bool], rows: &mut [Vec<f64>]) {
    for (k, inp) in inputs.iter().enumerate() {
        let Some(j) = inp.approach_of else { continue };
        if present.get(k).copied().unwrap_or(false) {
            continue;
        }
        let mut sign = 0.0;
        let mut prev: Option<f64> = None;
        for q in rows.iter_mut() {
            let v = q[j];
            if let Some(p) = prev {
                if (v - p).abs() > 1e-12 * (1.0 + v.abs()) {
                    sign = (v - p).signum();
                }
            }
            prev = Some(v);
            q[k] = sign;
        }
    }
}

fn chain_inputs(c: &SerialChain) -> Vec<InputSpec> {
    c.joints()
        .iter()
        .map(|j| InputSpec {
            name: j.name.clone(),
            unit: match j.kind {
                JointKind::Revolute => Unit::Angle,
                JointKind::Prismatic => Unit::Length,
            },
            limits: j.limits,
            approach_of: None,
            observed: false,
        })
        .collect()
}

impl From<SerialChain> for MechanismSpec {
    fn from(chain: SerialChain) -> Self {
        MechanismSpec::Serial(chain)
    }
}

impl MechanismSpec {
    /// The kind's name as written in files.
    pub fn kind(&self) -> &'static str {
        match self {
            MechanismSpec::Serial(_) | MechanismSpec::SerialTerms(_) => "serial",
            MechanismSpec::Pm5(_) => "pm5",
            MechanismSpec::Stewart(_) => "stewart",
            MechanismSpec::Limbs(_) => "limbs",
        }
    }

    /// The mechanism, ready to compute with.
    pub fn build(&self) -> Box<dyn Mechanism> {
        match self {
            MechanismSpec::Serial(c) => Box::new(c.clone()),
            MechanismSpec::SerialTerms(m) => Box::new(m.clone()),
            MechanismSpec::Pm5(m) => Box::new(m.clone()),
            MechanismSpec::Stewart(m) => Box::new(m.clone()),
            MechanismSpec::Limbs(m) => Box::new(m.clone()),
        }
    }

    /// The inputs with their units and limits.
    pub fn inputs(&self) -> Vec<InputSpec> {
        match self {
            MechanismSpec::Serial(c) => chain_inputs(c),
            MechanismSpec::SerialTerms(m) => {
                let mut out = chain_inputs(m.chain());
                for (&j, name) in m.terms().backlash.iter().zip(m.approach_names()) {
                    out.push(InputSpec {
                        name,
                        unit: Unit::Dimensionless,
                        limits: Some((-1.0, 1.0)),
                        approach_of: Some(j),
                        observed: false,
                    });
                }
                out
            }
            MechanismSpec::Pm5(m) => closed_loop_inputs(m),
            MechanismSpec::Stewart(m) => closed_loop_inputs(m),
            MechanismSpec::Limbs(m) => m
                .input_joints()
                .iter()
                .map(|&(i, j)| {
                    let joint = &m.limbs()[i].chain.joints()[j];
                    InputSpec {
                        name: joint.name.clone(),
                        unit: if joint.kind == JointKind::Revolute {
                            Unit::Angle
                        } else {
                            Unit::Length
                        },
                        limits: joint.limits,
                        approach_of: None,
                        observed: false,
                    }
                })
                .collect(),
        }
    }

    /// The columns of a measurement data file: the inputs, then the observed joints' readings
    /// ([`InputSpec::observed`]; optional in a file: all of them or none).
    pub fn data_columns(&self) -> Vec<InputSpec> {
        let mut out = self.inputs();
        if let MechanismSpec::Limbs(m) = self {
            out.extend(m.observed_joints().into_iter().map(|(name, unit)| InputSpec {
                name,
                unit,
                limits: None,
                approach_of: None,
                observed: true,
            }));
        }
        out
    }

    /// The same kind with the geometry of `model` (e.g. a calibrated copy of [`Self::build`]'s
    /// mechanism). Fails when `model` is not of this kind.
    pub fn with_geometry_of(&self, model: &dyn Mechanism) -> Result<MechanismSpec, String> {
        let not = |what: &str| format!("model '{}' is not {what}", model.name());
        let values = model.geometry().ok_or_else(|| not("a mechanism a model file describes"))?;
        match self {
            MechanismSpec::Serial(c) => c
                .with_geometry(&values)
                .map(MechanismSpec::Serial)
                .map_err(|e| format!("{}: {e}", not("this serial chain"))),
            MechanismSpec::SerialTerms(m) => m
                .with_geometry(&values)
                .map(MechanismSpec::SerialTerms)
                .map_err(|e| format!("{}: {e}", not("this serial chain with joint terms"))),
            MechanismSpec::Pm5(m) if model.name() == m.name() => m.with_geometry(&values).map(MechanismSpec::Pm5),
            MechanismSpec::Stewart(m) if model.name() == m.name() => m.with_geometry(&values).map(MechanismSpec::Stewart),
            MechanismSpec::Pm5(_) => Err(not("a pm5 machine")),
            MechanismSpec::Stewart(_) => Err(not("a Stewart platform")),
            MechanismSpec::Limbs(m) if model.name() == m.name() => m.with_geometry(&values).map(MechanismSpec::Limbs),
            MechanismSpec::Limbs(_) => Err(not("a limbs mechanism")),
        }
    }
}
