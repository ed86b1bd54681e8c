//! Measurements: what a laser tracker (or any external device) observes, and the residuals and
//! residual Jacobians that identification minimises.
//!
//! * [`Observation::Pose`]: the full tool-frame pose, e.g. from three reflectors
//!   ([`frame_from_reflectors`], eq. (38) of the 5-DOF paper). Residual
//!   `(p_meas − p, log(R_meas·Rᵀ))`: 3 rows in mm, 3 rows in rad.
//! * [`Observation::Position`]: the position of the tool-frame origin (one reflector whose centre
//!   *is* the tool point). Residual `p_meas − p`, 3 rows in mm.
//!
//! * [`Observation::Seat`]: the tool point sat in a fixed seat (cone, socket, nest) whose centre
//!   is an unknown of the instrument ([`crate::instrument`]). Residual `c − p`, 3 rows in mm.
//! * [`Observation::Distance`]: a ballbar's or draw-wire sensor's length between the tool point
//!   and a fixed pivot, whose centre is an unknown of the instrument. Residual `L − |p − c|`,
//!   1 row in mm.
//!
//! * [`Observation::Touch`]: a touch probe's tip on a sphere, a plane or a datum cube's face
//!   ([`touch`]), 1 row in mm.
//!
//! For the instrument kinds the predicted pose is the tool frame *relative to* the artifact
//! point (its centre subtracted), which is what [`crate::instrument::Artifact`] predicts.
//!
//! Rows are weighted by the measurement noise ([`Noise`]): dividing each residual by its standard
//! deviation makes the least-squares solution the maximum-likelihood estimate under Gaussian
//! noise and puts millimetres and radians on one dimensionless scale.
use crate::se3::{self, Pose};
use nalgebra::{DMatrix, Matrix3, Matrix6xX, Vector3, Vector6};
use serde::{Deserialize, Serialize};

pub mod artifacts;
mod kind;
pub use artifacts::{artifact_rows, ArtifactRows};
pub use kind::{KindNoise, RowKind};
pub mod touch;
pub use touch::Touch;

/// One observation of the tool frame, expressed in the world (measurement) frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Observation {
    /// Full pose of the tool frame.
    Pose(Pose),
    /// Position of the tool-frame origin (mm).
    Position(Vector3<f64>),
    /// Positions of several points rigidly attached to the tool (e.g. tracker reflectors):
    /// `(point in the tool frame, measured position)` pairs, mm.
    Points(Vec<(Vector3<f64>, Vector3<f64>)>),
    /// The tool point sat in seat number `.0` of the instrument (its centre unknown).
    Seat(usize),
    /// The length (mm) measured between the tool point and pivot number `pivot` (its centre
    /// unknown): a ballbar's or a draw-wire sensor's reading.
    Distance {
        /// Pivot number.
        pivot: usize,
        /// Measured length (mm); with `relative`, the reading.
        length: f64,
        /// `length` is a reading relative to an unknown zero (a draw-wire or string-pot sensor, a
        /// ballbar whose certified length is unknown; data column `reading_mm`): the true length
        /// is the reading plus the pivot's zero, one more unknown of the instrument.
        relative: bool,
    },
    /// A touch probe's tip on a sphere, a plane or a datum cube's face ([`touch`]).
    Touch(Touch),
}

impl Observation {
    /// Number of residual rows.
    pub fn rows(&self) -> usize {
        match self {
            Observation::Pose(_) => 6,
            Observation::Position(_) => 3,
            Observation::Points(p) => 3 * p.len(),
            Observation::Seat(_) => 3,
            Observation::Distance { .. } | Observation::Touch(_) => 1,
        }
    }

    /// The artifact point (seat or pivot) an instrument observation refers to, with its kind.
    pub fn artifact_point(&self) -> Option<(PointKind, usize)> {
        match self {
            Observation::Seat(k) => Some((PointKind::Seat, *k)),
            Observation::Distance { pivot, .. } => Some((PointKind::Pivot, *pivot)),
            Observation::Touch(t) => Some(t.artifact()),
            _ => None,
        }
    }
}

/// What an artifact point is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
pub enum PointKind {
    /// A seat: the tool point sits at its centre ([`Observation::Seat`]).
    Seat,
    /// A pivot: a length is measured from its centre ([`Observation::Distance`]).
    Pivot,
    /// A reference sphere touched by a probe ([`Touch::Sphere`]): its centre.
    Sphere,
    /// A plane touched by a probe ([`Touch::Plane`]): a frame on it, `z` its normal.
    Plane,
    /// A datum cube touched by a probe ([`Touch::Face`]): its frame, at its centre.
    Cube,
}

impl PointKind {
    /// `"seat"` or `"pivot"`.
    pub fn name(self) -> &'static str {
        match self {
            PointKind::Seat => "seat",
            PointKind::Pivot => "pivot",
            PointKind::Sphere => "sphere",
            PointKind::Plane => "plane",
            PointKind::Cube => "cube",
        }
    }

    /// The names of its parameters (after `seat0.` …) and which of them are angles: a point's
    /// centre `x y z`; a plane's tilts about its frame's `x` and `y` and its offset along its
    /// normal `rx ry z`; a cube's local twist `x y z rx ry rz`.
    pub fn param_names(self) -> &'static [&'static str] {
        match self {
            PointKind::Plane => &["rx", "ry", "z"],
            PointKind::Cube => &["x", "y", "z", "rx", "ry", "rz"],
            _ => &["x", "y", "z"],
        }
    }

    /// The row of the artifact frame's spatial twist each parameter moves (the twist is `(v, ω)`).
    pub fn twist_rows(self) -> &'static [usize] {
        match self {
            PointKind::Plane => &[3, 4, 2],
            PointKind::Cube => &[0, 1, 2, 3, 4, 5],
            _ => &[0, 1, 2],
        }
    }

    /// Whether it has an orientation (a plane's, a cube's), not only a centre.
    pub fn oriented(self) -> bool {
        matches!(self, PointKind::Plane | PointKind::Cube)
    }
}

/// One measured pose of a mechanism: its inputs and what was observed.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// Input values (rad for revolute, mm for prismatic joints), in the mechanism's input order.
    pub q: Vec<f64>,
    /// What was observed.
    pub obs: Observation,
    /// Readings of the mechanism's observed joints ([`crate::model::Mechanism::observed_joints`],
    /// rad / mm, in that order): compared with the model like the tracker's observation. Empty
    /// when the mechanism has none or they were not read.
    pub joints: Vec<f64>,
}

/// Standard deviations of the measurement noise, used as residual weights.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Noise {
    /// Position noise (mm, per axis).
    pub position: f64,
    /// Orientation noise (rad, per axis).
    pub orientation: f64,
    /// Noise of an observed revolute joint's reading (rad; encoders of passive joints,
    /// [`crate::model::Mechanism::observed_joints`]).
    #[serde(default = "default_joint_angle")]
    pub joint_angle: f64,
    /// Noise of an observed prismatic joint's reading (mm).
    #[serde(default = "default_joint_length")]
    pub joint_length: f64,
    /// The σ of each instrument kind (seat, distance), when stated; a kind without its own
    /// falls back to [`Self::position`] ([`Self::sigma`]).
    #[serde(default)]
    pub kinds: KindNoise,
}

impl Noise {
    /// The σ (mm) rows of `kind` are weighted by: the kind's own ([`KindNoise`]), else the
    /// position noise.
    pub fn sigma(&self, kind: RowKind) -> f64 {
        self.kinds.get(kind).unwrap_or(self.position)
    }

    /// Every σ multiplied by `factor` (e.g. a calibration's a-posteriori σ of unit weight).
    pub fn scaled(&self, factor: f64) -> Noise {
        let kind = |s: Option<f64>| s.map(|s| s * factor);
        Noise {
            position: self.position * factor,
            orientation: self.orientation * factor,
            joint_angle: self.joint_angle * factor,
            joint_length: self.joint_length * factor,
            kinds: KindNoise {
                seat: kind(self.kinds.seat),
                distance: kind(self.kinds.distance),
                probe: kind(self.kinds.probe),
            },
        }
    }
}

fn default_joint_angle() -> f64 {
    0.01_f64.to_radians()
}

fn default_joint_length() -> f64 {
    0.01
}

impl Default for Noise {
    /// 20 µm and 0.02°, the noise of the 5-DOF paper's simulation study (§5.1); observed joints
    /// 0.01° and 0.01 mm (the 3T1R study's encoders).
    fn default() -> Self {
        Noise {
            position: 0.020,
            orientation: 0.02_f64.to_radians(),
            joint_angle: default_joint_angle(),
            joint_length: default_joint_length(),
            kinds: KindNoise::default(),
        }
    }
}

/// The unweighted residual of an observation against a predicted tool pose.
pub fn residual(obs: &Observation, predicted: &Pose) -> Vec<f64> {
    match obs {
        Observation::Pose(m) => se3::pose_error(m, predicted).as_slice().to_vec(),
        Observation::Position(p) => (p - predicted.translation.vector).as_slice().to_vec(),
        Observation::Points(pts) => pts
            .iter()
            .flat_map(|(r, m)| (m - predicted.transform_point(&(*r).into()).coords).as_slice().to_vec())
            .collect(),
        Observation::Seat(_) => (-predicted.translation.vector).as_slice().to_vec(),
        Observation::Distance { length, .. } => vec![length - predicted.translation.vector.norm()],
        Observation::Touch(t) => vec![t.residual(&predicted.translation.vector)],
    }
}

/// Rows of the residual Jacobian (`d residual / dδ`) from the spatial identification Jacobian
/// `J` (6 × p) at a predicted pose. The residual is "measured − predicted", so a model change `δ`
/// that moves the prediction by `J·δ` reduces the residual by the same amount: the returned
/// matrix is the derivative of the *prediction*, and least squares solves `A·δ ≈ r`.
pub fn residual_jacobian(obs: &Observation, predicted: &Pose, jac: &Matrix6xX<f64>) -> DMatrix<f64> {
    match obs {
        Observation::Pose(_) => {
            let full = se3::mul6(&se3::spatial_to_pose_error(&predicted.translation.vector), jac);
            DMatrix::from_iterator(6, jac.ncols(), full.iter().copied())
        }
        Observation::Position(_) | Observation::Seat(_) => {
            let full = se3::mul6(&se3::spatial_to_pose_error(&predicted.translation.vector), jac);
            DMatrix::from_fn(3, jac.ncols(), |i, j| full[(i, j)])
        }
        Observation::Distance { .. } => {
            let p = predicted.translation.vector;
            let full = se3::mul6(&se3::spatial_to_pose_error(&p), jac);
            let u = p.try_normalize(1e-12).unwrap_or_else(Vector3::zeros);
            DMatrix::from_fn(1, jac.ncols(), |_, j| u.dot(&full.fixed_view::<3, 1>(0, j)))
        }
        Observation::Touch(t) => {
            let p = predicted.translation.vector;
            let full = se3::mul6(&se3::spatial_to_pose_error(&p), jac);
            let g = t.gradient(&p);
            DMatrix::from_fn(1, jac.ncols(), |_, j| g.dot(&full.fixed_view::<3, 1>(0, j)))
        }
        Observation::Points(pts) => {
            let mut out = DMatrix::zeros(3 * pts.len(), jac.ncols());
            for (k, (r, _)) in pts.iter().enumerate() {
                let p = predicted.transform_point(&(*r).into()).coords;
                let full = se3::mul6(&se3::spatial_to_pose_error(&p), jac);
                out.view_mut((3 * k, 0), (3, jac.ncols())).copy_from(&full.rows(0, 3));
            }
            out
        }
    }
}

/// The point two solutions are compared at (the extra starts of [`crate::calibrate`]): the
/// predicted tool point, or for a distance its length along x (a ballbar does not see the
/// direction, and solutions that differ by where the unplaced base stands predict it alike).
pub fn compared_point(obs: &Observation, predicted: &Pose) -> Vector3<f64> {
    match obs {
        Observation::Distance { .. } => Vector3::x() * predicted.translation.vector.norm(),
        Observation::Touch(t) => Vector3::x() * t.predicted(&predicted.translation.vector),
        _ => predicted.translation.vector,
    }
}

/// Weights (1/σ) of observed-joint readings of these units ([`Noise::joint_angle`] for angles,
/// [`Noise::joint_length`] otherwise).
pub fn joint_weights(units: &[(String, crate::params::Unit)], noise: &Noise) -> Vec<f64> {
    units
        .iter()
        .map(|(_, u)| match u {
            crate::params::Unit::Angle => 1.0 / noise.joint_angle,
            _ => 1.0 / noise.joint_length,
        })
        .collect()
}

/// Weights (1/σ) of the residual rows of an observation.
pub fn row_weights(obs: &Observation, noise: &Noise) -> Vec<f64> {
    (0..obs.rows()).map(|k| row_weight(obs, k, noise)).collect()
}

/// The `pivot` of a [`Observation::Distance`] that is a known distance between two seats of an
/// artifact ([`crate::instrument::SeatDistance`]), not a measurement.
pub const KNOWN_DISTANCE: usize = usize::MAX;

/// How much more a known distance between seats weighs than a measured row: it is a certified
/// dimension of the artifact, and it must hold the scale against the pull of residuals a
/// geometric model leaves on a real machine (shrinking a machine whose scale the seats do not
/// fix shrinks every residual with it).
pub const KNOWN_DISTANCE_WEIGHT: f64 = 100.0;

/// The weight of row `k` of `obs`'s residual (see [`row_weights`]), without a vector.
pub fn row_weight(obs: &Observation, k: usize, noise: &Noise) -> f64 {
    match obs {
        Observation::Pose(_) if k >= 3 => 1.0 / noise.orientation,
        Observation::Distance { pivot: KNOWN_DISTANCE, .. } => KNOWN_DISTANCE_WEIGHT / noise.sigma(RowKind::Seat),
        _ => 1.0 / noise.sigma(RowKind::of(obs).unwrap_or(RowKind::Tracker)),
    }
}

/// Position error (mm) and rotation error (rad) of an observation against a predicted pose; the
/// rotation error is `None` for a position observation.
pub fn errors(obs: &Observation, predicted: &Pose) -> (f64, Option<f64>) {
    match obs {
        Observation::Pose(m) => {
            let e: Vector6<f64> = se3::pose_error(m, predicted);
            (se3::lin(&e).norm(), Some(se3::ang(&e).norm()))
        }
        Observation::Position(p) => ((p - predicted.translation.vector).norm(), None),
        Observation::Seat(_) => (predicted.translation.vector.norm(), None),
        Observation::Distance { length, .. } => ((length - predicted.translation.vector.norm()).abs(), None),
        Observation::Touch(t) => (t.residual(&predicted.translation.vector).abs(), None),
        Observation::Points(pts) => {
            // RMS over the points of their position errors.
            let s: f64 = pts
                .iter()
                .map(|(r, m)| (m - predicted.transform_point(&(*r).into()).coords).norm_squared())
                .sum();
            ((s / pts.len().max(1) as f64).sqrt(), None)
        }
    }
}

/// The tool frame of three reflector centres `M1, M2, M3` (eq. (38) of the 5-DOF paper): origin at
/// the centroid, `x` along `M2 − M3`, `y` toward `M1` from the midpoint of `M2 M3`, `z = x × y`.
///
/// Eq. (38) takes `r_y` as printed, which is orthogonal to `r_x` only when `|M1 M2| = |M1 M3|`;
/// kinecal keeps `r_x`, takes `r_z = r_x × r_y` normalised and re-derives `r_y = r_z × r_x`, so the
/// frame is orthonormal for any triangle and equals the paper's for an isosceles one.
pub fn frame_from_reflectors(m1: &Vector3<f64>, m2: &Vector3<f64>, m3: &Vector3<f64>) -> Option<Pose> {
    let origin = (m1 + m2 + m3) / 3.0;
    let rx = (m2 - m3).try_normalize(1e-9)?;
    let ry0 = m1 - (m2 + m3) * 0.5;
    let rz = rx.cross(&ry0).try_normalize(1e-9)?;
    let ry = rz.cross(&rx);
    let r = Matrix3::from_columns(&[rx, ry, rz]);
    // Orthonormal by construction: no projection onto the rotations needed.
    Some(se3::pose_from_rotation(&r, &origin))
}

/// The reflector centres in the reflector frame of [`frame_from_reflectors`], averaged over
/// every triple (the reflectors are rigid on the tool). `None` when a triple is collinear or
/// there is none.
pub fn reflector_offsets(triples: &[[Vector3<f64>; 3]]) -> Option<[Vector3<f64>; 3]> {
    if triples.is_empty() {
        return None;
    }
    let mut sum = [Vector3::zeros(); 3];
    for m in triples {
        let f = frame_from_reflectors(&m[0], &m[1], &m[2])?;
        for k in 0..3 {
            sum[k] += f.inverse_transform_point(&m[k].into()).coords;
        }
    }
    let n = triples.len() as f64;
    Some([sum[0] / n, sum[1] / n, sum[2] / n])
}

/// Rigid registration by SVD (eq. (39)–(44) of the 5-DOF paper, with the reflection guard of
/// Arun/Umeyama): the pose `T` minimising `Σ |T·src_i − dst_i|²`. Needs at least three points not
/// on one line; returns `None` otherwise.
pub fn register_points(src: &[Vector3<f64>], dst: &[Vector3<f64>]) -> Option<Pose> {
    if src.len() != dst.len() || src.len() < 3 {
        return None;
    }
    let n = src.len() as f64;
    let cs = src.iter().sum::<Vector3<f64>>() / n;
    let cd = dst.iter().sum::<Vector3<f64>>() / n;
    let mut z = Matrix3::zeros();
    for (s, d) in src.iter().zip(dst) {
        z += (d - cd) * (s - cs).transpose();
    }
    if z.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let svd = z.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let sv = svd.singular_values;
    if sv[1] < 1e-9 * sv[0].max(1e-300) {
        return None;
    }
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = u * d * vt;
    let p = cd - r * cs;
    Some(se3::pose_from_matrix(&r, &p))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn registration_recovers_a_pose() {
        let t = se3::exp(&se3::Twist::new(100.0, -20.0, 5.0, 0.3, -1.1, 2.0));
        let src: Vec<Vector3<f64>> = (0..10)
            .map(|i| {
                let f = i as f64;
                Vector3::new(f.sin() * 300.0, (2.0 * f).cos() * 200.0, f * 10.0)
            })
            .collect();
        let dst: Vec<Vector3<f64>> = src.iter().map(|p| t.transform_point(&(*p).into()).coords).collect();
        let est = register_points(&src, &dst).unwrap();
        assert_relative_eq!(est.to_homogeneous(), t.to_homogeneous(), epsilon = 1e-9);
    }

    #[test]
    fn reflector_frame_is_orthonormal_and_matches_paper_for_isosceles() {
        let m1 = Vector3::new(0.0, 100.0, 0.0);
        let m2 = Vector3::new(80.0, -50.0, 0.0);
        let m3 = Vector3::new(-80.0, -50.0, 0.0);
        let f = frame_from_reflectors(&m1, &m2, &m3).unwrap();
        assert_relative_eq!(se3::rotation_matrix(&f), Matrix3::identity(), epsilon = 1e-12);
        assert_relative_eq!(f.translation.vector, Vector3::new(0.0, 0.0, 0.0), epsilon = 1e-12);
        // Degenerate triangle: no frame.
        assert!(frame_from_reflectors(&m1, &m1, &m3).is_none());
    }
}
