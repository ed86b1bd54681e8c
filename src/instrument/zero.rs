//! A length from a pivot with an unknown zero: a draw-wire or string-pot sensor, or a ballbar
//! whose certified length is unknown (data column `reading_mm`, [`Observation::Distance`] with
//! `relative`). The true length is the reading plus the pivot's zero `z_k`, one more artifact
//! unknown (`pivot3.zero`, mm, group [`super::ARTIFACT_GROUP`]); the residual is
//! `R_i + z_k − |p_i − c_k|`.
//!
//! A distance residual is `L − |t|` of the predicted translation `t`, and a norm is never
//! negative while a reading may be. So the rows of such a pivot carry their reading plus a fixed
//! reference `ρ_k` ([`Zero::reference`], chosen from the data so that every shifted reading is at
//! least [`REFERENCE_MM`]), and [`super::Artifact`] predicts the translation `d + (ρ_k − z_k)·d̂`
//! (`d = p − c_k`), of length `|d| − z_k + ρ_k`: the residual is then `R_i + ρ_k − |d| + z_k − ρ_k`,
//! the one above, and no prediction near a solution comes near a zero length.
//!
//! What such a pivot cannot see: its readings' common part. A pivot whose readings are all equal
//! (a fixed bar of unknown length) leaves its zero and the machine's scale to each other, and
//! the rows only say that the tool point stays on some sphere: [`super::index_points`] refuses it.
use super::{Artifact, ArtifactPoint};
use crate::measure::Observation;
use crate::se3::Pose;
use nalgebra::{DMatrix, DVector, Matrix6xX, Translation3, Vector3};

/// The least shifted reading of a pivot with an unknown zero (mm): far from a zero length.
pub const REFERENCE_MM: f64 = 1000.0;

/// Rows a pivot with an unknown zero needs at least: four unknowns (centre and zero) place it,
/// the fifth row is the first that tells something about the machine.
pub const MIN_ZERO_PIVOT_ROWS: usize = 5;

/// The smallest spread (max − min, mm) of a pivot's readings with an unknown zero: below it the
/// readings say nothing the zero does not.
pub const MIN_READING_SPREAD_MM: f64 = 1e-6;

/// A pivot's unknown zero: the true length is the reading plus `value`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Zero {
    /// The zero (mm): length = reading + value.
    pub value: f64,
    /// The constant added to the pivot's readings in the rows the fit uses (mm, module docs).
    pub reference: f64,
}

impl Zero {
    /// For readings whose least is `min` (mm): the reference that puts it at [`REFERENCE_MM`],
    /// the zero started there (the start places it, [`super::start_points`]).
    pub fn for_readings(min: f64) -> Zero {
        let reference = REFERENCE_MM - min;
        Zero {
            value: reference,
            reference,
        }
    }
}

/// The centre `c` and the zero `e` with `|p_i − c| = L_i + e` over rows `(p_i, L_i)`: the linear
/// solution of `|p_i|² − L_i² = 2·p_i·c + 2·L_i·e + (e² − |c|²)`, then Gauss–Newton on
/// `L_i + e − |p_i − c|` while it lowers the cost. `None` when the rows do not place them.
pub fn sphere_and_zero(rows: &[(Vector3<f64>, f64)]) -> Option<(Vector3<f64>, f64)> {
    let n = rows.len();
    if n < 5 {
        return None;
    }
    let mut a = DMatrix::zeros(n, 5);
    let mut b = DVector::zeros(n);
    for (r, (p, l)) in rows.iter().enumerate() {
        for i in 0..3 {
            a[(r, i)] = 2.0 * p[i];
        }
        a[(r, 3)] = 2.0 * l;
        a[(r, 4)] = 1.0;
        b[r] = p.norm_squared() - l * l;
    }
    let svd = a.svd(true, true);
    if svd.singular_values.min() <= 1e-12 * svd.singular_values.max() {
        return None;
    }
    let x = svd.solve(&b, 0.0).ok()?;
    let mut c = Vector3::new(x[0], x[1], x[2]);
    let mut e = x[3];
    let linearise = |c: &Vector3<f64>, e: f64| -> Option<(DMatrix<f64>, DVector<f64>)> {
        let mut j = DMatrix::zeros(n, 4);
        let mut r = DVector::zeros(n);
        for (k, (p, l)) in rows.iter().enumerate() {
            let d = p - c;
            let u = d.try_normalize(1e-12)?;
            r[k] = l + e - d.norm();
            for i in 0..3 {
                j[(k, i)] = u[i];
            }
            j[(k, 3)] = 1.0;
        }
        Some((j, r))
    };
    let (mut j, mut r) = linearise(&c, e)?;
    for _ in 0..30 {
        let step = j.clone().svd(true, true).solve(&r, 1e-12).ok()?;
        let (trial_c, trial_e) = (c - Vector3::new(step[0], step[1], step[2]), e - step[3]);
        let Some((jt, rt)) = linearise(&trial_c, trial_e) else { break };
        if rt.norm_squared().is_nan() || rt.norm_squared() >= r.norm_squared() {
            break;
        }
        (c, e, j, r) = (trial_c, trial_e, jt, rt);
        if step.norm() < 1e-13 * (1.0 + c.norm()) {
            break;
        }
    }
    (c.iter().all(|v| v.is_finite()) && e.is_finite()).then_some((c, e))
}

/// `(relative, length)` of a distance row.
pub(super) fn readings(obs: &Observation) -> Option<(bool, f64)> {
    match obs {
        Observation::Distance { relative, length, .. } => Some((*relative, *length)),
        _ => None,
    }
}

impl<M> Artifact<M> {
    /// How many points have an unknown zero (one parameter each, after the points' centres).
    pub fn n_zeros(&self) -> usize {
        self.points.iter().filter(|p| p.zero.is_some()).count()
    }

    /// The parameter offset (past the inner mechanism's and the centres') of point `k`'s zero.
    pub(super) fn zero_index(&self, k: usize) -> Option<usize> {
        self.points[k].zero?;
        Some(self.points[..k].iter().filter(|p| p.zero.is_some()).count())
    }

    /// Point `k`'s relative pose `(pose, jac)` (translation `d`, spatial Jacobian over every
    /// parameter) with its length moved by `ρ_k − z_k` along `d` when `k` has an unknown zero
    /// (module docs); the zero's column at `zero_column`.
    pub(super) fn with_zero(&self, k: usize, zero_column: usize, (pose, mut jac): (Pose, Matrix6xX<f64>)) -> (Pose, Matrix6xX<f64>) {
        let Some(z) = self.points[k].zero else { return (pose, jac) };
        let d = pose.translation.vector;
        let Some(u) = d.try_normalize(1e-12) else { return (pose, jac) };
        let (a, len) = (z.reference - z.value, d.norm());
        let t = d + a * u;
        for c in 0..jac.ncols() {
            let (v, w) = (jac.fixed_view::<3, 1>(0, c).into_owned(), jac.fixed_view::<3, 1>(3, c).into_owned());
            // The point's velocity, then the moved point's (the length's rate added along u).
            let pv = v + w.cross(&d);
            let mut moved = pv + a * (pv - u * u.dot(&pv)) / len;
            if c == zero_column {
                moved -= u;
            }
            jac.fixed_view_mut::<3, 1>(0, c).copy_from(&(moved - w.cross(&t)));
        }
        (Pose::from_parts(Translation3::from(t), pose.rotation), jac)
    }

    /// Point `k`'s relative pose with its length moved (as [`Self::with_zero`]), without a Jacobian.
    pub(super) fn moved(&self, k: usize, pose: Pose) -> Pose {
        let Some(z) = self.points[k].zero else { return pose };
        let d = pose.translation.vector;
        let Some(u) = d.try_normalize(1e-12) else { return pose };
        Pose::from_parts(Translation3::from(d + (z.reference - z.value) * u), pose.rotation)
    }

    /// The inverse of [`Self::moved`] (a pose near the moved one, back to the unmoved frame).
    pub(super) fn unmoved(&self, k: usize, pose: &Pose) -> Pose {
        let Some(z) = self.points[k].zero else { return *pose };
        let t = pose.translation.vector;
        let Some(u) = t.try_normalize(1e-12) else { return *pose };
        Pose::from_parts(Translation3::from(t - (z.reference - z.value) * u), pose.rotation)
    }
}

/// An artifact point of `kind` and number `id`, centre to be placed; `least_reading`: the least
/// reading of a pivot whose rows are readings relative to an unknown zero (`None` otherwise).
pub(super) fn pivot_point(kind: super::PointKind, id: usize, least_reading: Option<f64>) -> ArtifactPoint {
    ArtifactPoint {
        kind,
        id,
        centre: Vector3::zeros(),
        zero: least_reading.map(Zero::for_readings),
        rotation: kind.oriented().then(nalgebra::UnitQuaternion::identity),
    }
}
