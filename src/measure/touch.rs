//! Touches of a touch probe whose tip is a ball of radius `r` (its centre the tool point) on
//! reference artifacts ([`crate::instrument::touch`]):
//!
//! * **sphere** `k` of known diameter `D`, centre unknown: the tip's centre is at `D/2 + r`
//!   from the centre. Residual `D/2 + r − |p|` (`p` relative to the centre), as a distance's.
//! * **plane** `k`, unknown: the tip's centre is `r` above the plane, on its normal's side.
//!   Residual `r − p_z` (`p` in the plane's frame: origin on the plane, `z` its normal).
//! * **face** `j` of a datum cube of known edge `e` in an unknown pose: faces `0..5` are
//!   `+x, −x, +y, −y, +z, −z` of the cube's frame (origin at its centre), face `j` at `e/2` along
//!   its outward normal `s·x_a` (`a = j/2`, `s = +1` for even `j`). Residual `r + e/2 − s·p_a`
//!   (`p` in the cube's frame).
//!
//! Every residual is one row in mm: what was measured (the tip's radius, or the sphere's radius
//! plus the tip's) minus the tool point's predicted distance from the surface's reference.
use nalgebra::Vector3;

/// The faces of a datum cube in their order (data column `face`).
pub const FACE_NAMES: [&str; 6] = ["+x", "-x", "+y", "-y", "+z", "-z"];

/// One touch of the probe on an artifact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Touch {
    /// Sphere number `sphere` of diameter `diameter` (mm), touched by a tip of radius `probe`.
    Sphere {
        /// Sphere number.
        sphere: usize,
        /// The sphere's diameter (mm).
        diameter: f64,
        /// The probe tip's radius (mm).
        probe: f64,
    },
    /// Plane number `plane` (unknown), touched by a tip of radius `probe`.
    Plane {
        /// Plane number.
        plane: usize,
        /// The probe tip's radius (mm).
        probe: f64,
    },
    /// Face `face` (0..5: +x, −x, +y, −y, +z, −z) of the datum cube of edge `edge`.
    Face {
        /// Face number.
        face: usize,
        /// The cube's edge (mm).
        edge: f64,
        /// The probe tip's radius (mm).
        probe: f64,
    },
}

impl Touch {
    /// The artifact the touch refers to: its kind and number (the cube is number 0).
    pub fn artifact(&self) -> (super::PointKind, usize) {
        match *self {
            Touch::Sphere { sphere, .. } => (super::PointKind::Sphere, sphere),
            Touch::Plane { plane, .. } => (super::PointKind::Plane, plane),
            Touch::Face { .. } => (super::PointKind::Cube, 0),
        }
    }

    /// The probe tip's radius (mm).
    pub fn probe(&self) -> f64 {
        match *self {
            Touch::Sphere { probe, .. } | Touch::Plane { probe, .. } | Touch::Face { probe, .. } => probe,
        }
    }

    /// What the touch measures (mm): the distance of the tip's centre from the surface's
    /// reference (the sphere's centre, the plane, the cube face's plane through the centre).
    pub fn measured(&self) -> f64 {
        match *self {
            Touch::Sphere { diameter, probe, .. } => 0.5 * diameter + probe,
            Touch::Plane { probe, .. } => probe,
            Touch::Face { edge, probe, .. } => probe + 0.5 * edge,
        }
    }

    /// The same distance predicted for tool point `p` (relative to the artifact's frame).
    pub fn predicted(&self, p: &Vector3<f64>) -> f64 {
        match *self {
            Touch::Sphere { .. } => p.norm(),
            _ => self.gradient(p).dot(p),
        }
    }

    /// The derivative of [`Self::predicted`] by the tool point.
    pub fn gradient(&self, p: &Vector3<f64>) -> Vector3<f64> {
        match *self {
            Touch::Sphere { .. } => p.try_normalize(1e-12).unwrap_or_else(Vector3::zeros),
            Touch::Plane { .. } => Vector3::z(),
            Touch::Face { face, .. } => face_normal(face),
        }
    }

    /// Measured minus predicted (mm).
    pub fn residual(&self, p: &Vector3<f64>) -> f64 {
        self.measured() - self.predicted(p)
    }
}

/// The outward normal of cube face `face` in the cube's frame (module docs); a face past 5 has
/// none (zero).
pub fn face_normal(face: usize) -> Vector3<f64> {
    let mut n = Vector3::zeros();
    if face < 6 {
        n[face / 2] = if face % 2 == 0 { 1.0 } else { -1.0 };
    }
    n
}
