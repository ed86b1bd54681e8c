//! Named error parameters: what a model can be calibrated in.
//!
//! Every mechanism exposes its error coordinates as a list of [`Param`]s, in a fixed order that is
//! also the column order of its identification Jacobian. Lengths are in millimetres, angles in
//! radians, everywhere inside kinecal; files and reports convert at the edges.
use serde::{Deserialize, Serialize};

/// Physical kind of a parameter (decides its unit and its scale in weighting and reports).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Unit {
    /// A length, in millimetres.
    Length,
    /// An angle, in radians.
    Angle,
    /// A pure number.
    Dimensionless,
}

impl Unit {
    /// The unit symbol used inside kinecal.
    pub fn symbol(self) -> &'static str {
        match self {
            Unit::Length => "mm",
            Unit::Angle => "rad",
            Unit::Dimensionless => "",
        }
    }

    /// The factor from kinecal's unit to the one files and reports show, and that unit's symbol:
    /// `(180/π, "deg")` for angles, `(1, "mm")` for lengths, `(1, "")` for pure numbers.
    pub fn display(self) -> (f64, &'static str) {
        match self {
            Unit::Length => (1.0, "mm"),
            Unit::Angle => (180.0 / std::f64::consts::PI, "deg"),
            Unit::Dimensionless => (1.0, ""),
        }
    }
}

/// One error parameter of a mechanism.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Param {
    /// Unique name, e.g. `"2-3.wy"` (a local-POE dyad error) or `"dl1"` (a link length).
    pub name: String,
    /// Physical kind and unit.
    pub unit: Unit,
    /// Group for reports, e.g. `"base"`, `"tool"`, `"joint 2"`, `"limb 1"`.
    pub group: String,
}

impl Param {
    /// A new parameter.
    pub fn new(name: impl Into<String>, unit: Unit, group: impl Into<String>) -> Self {
        Param {
            name: name.into(),
            unit,
            group: group.into(),
        }
    }

    /// Whether the parameter places something outside the machine (a frame, a group ending in
    /// `" frame"`, or an instrument's artifact point, [`ARTIFACT_GROUP`]):
    /// where it happens to stand, not limited by the machine's tolerances.
    pub fn is_placement(&self) -> bool {
        is_placement_group(&self.group)
    }
}

/// The parameter group of an instrument's artifact points' coordinates
/// ([`crate::instrument::Artifact`]): not limited by the machine's tolerances, not perturbed by
/// the extra starts — like the frames, they are where the artifact happens to stand.
pub const ARTIFACT_GROUP: &str = "artifact";

/// Whether a parameter group places something outside the machine ([`Param::is_placement`]).
pub fn is_placement_group(group: &str) -> bool {
    group.ends_with(" frame") || group == ARTIFACT_GROUP
}

/// Index of the parameter called `name`, if any.
pub fn index_of(params: &[Param], name: &str) -> Option<usize> {
    params.iter().position(|p| p.name == name)
}
