//! Instruments without a laser tracker: a fixed **seat** (cone, socket, magnetic nest) the tool
//! ball is placed in from many orientations, and a **distance** (ballbar, draw-wire sensor)
//! between the tool point and a fixed pivot.
//!
//! Both bring unknowns of their own: the centre of every seat and every pivot (the *artifact
//! points*, in the mechanism's base frame). [`Artifact`] wraps a mechanism and appends them to its
//! parameters, three per point, so that identification estimates them with the geometry and
//! reports their σ like any parameter ([`ARTIFACT_GROUP`]). A measurement says which point it
//! refers to through one extra input, the point's index ([`index_points`] appends it), and the
//! wrapper predicts the tool frame *relative to* that point: a seat's residual is then `c − p`,
//! a distance's `L − |p − c|` ([`crate::measure::residual`]).
//!
//! A draw-wire's readings relative to an unknown zero (`reading_mm`) add one unknown per pivot,
//! its zero (`pivot3.zero`, [`zero`]).
//!
//! The points are started from the data, not from a guess ([`start_points`]): the seats and the
//! tool offset together by the linear pivot calibration (`R_i·t − c_s = −p_i` over every row of
//! every seat), each pivot by a sphere fit of the nominal tool points to the measured lengths.
//!
//! What an instrument cannot see: where the machine stands (no instrument here places its base:
//! the artifact is somewhere unknown, so the mechanism's base placement and the points move
//! together), and, with seats alone, the scale of a machine of revolute joints (every length and
//! every seat scaled alike leave each ball in its seat). Identification removes such directions
//! by its rank analysis (minimum-norm steps on the identifiable directions only); the report
//! names the parameters that are redundant.
use crate::error::{CalibError, KinError};
use crate::measure::{Measurement, Observation};
use crate::model::{ForwardAndObserved, Mechanism, Task};
use crate::params::{Param, Unit};
use crate::se3::Pose;
use nalgebra::{DMatrix, DVector, Matrix6xX, Translation3, Vector3};
use std::collections::BTreeMap;

mod held_out;
pub mod mixed;
mod offset;
mod planned;
pub mod simulate;
mod start;
pub mod touch;
pub mod zero;
pub use held_out::{held_out, CubeFit, HeldOut, PivotFit, SeatSpread};
pub use mixed::{has_tracker_rows, NO_POINT};
#[cfg(test)]
use offset::fit_offset_and_pivots;
pub use planned::measure_planned;
pub use start::{place_points, start_points};
pub use zero::{sphere_and_zero, Zero, MIN_ZERO_PIVOT_ROWS};

pub use crate::measure::PointKind;
pub use crate::params::ARTIFACT_GROUP;

/// Rows a seat needs at least: one row places the seat and tells nothing about the machine.
pub const MIN_SEAT_ROWS: usize = 2;

/// Rows a pivot needs at least: three lengths place a pivot (up to a mirror image), the fourth
/// is the first that tells something about the machine.
pub const MIN_PIVOT_ROWS: usize = 4;

/// A known distance between two seats of one artifact (a certified bar with several seats, a
/// printed tool with two sockets): it gives the scale that seats alone do not.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SeatDistance {
    /// One seat's number.
    pub a: usize,
    /// The other seat's number.
    pub b: usize,
    /// Their centres' distance (mm).
    pub length: f64,
}

impl std::str::FromStr for SeatDistance {
    type Err = String;
    /// `A:B:MM`, e.g. `0:1:50`.
    fn from_str(s: &str) -> Result<Self, String> {
        let parts: Vec<&str> = s.split(':').map(str::trim).collect();
        let bad = || format!("'{s}': a seat distance is A:B:MM (two seat numbers and the distance in mm, e.g. 0:1:50)");
        let [a, b, l] = parts.as_slice() else { return Err(bad()) };
        let (a, b, length) = (
            a.parse().map_err(|_| bad())?,
            b.parse().map_err(|_| bad())?,
            l.parse::<f64>().map_err(|_| bad())?,
        );
        if a == b || !(length.is_finite() && length > 0.0) {
            return Err(bad());
        }
        Ok(SeatDistance { a, b, length })
    }
}

/// One artifact point: a seat's or a pivot's centre (mm, the mechanism's base frame).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ArtifactPoint {
    /// Seat or pivot.
    pub kind: PointKind,
    /// Its number in the data (`seat` or `pivot` column).
    pub id: usize,
    /// Its centre (mm).
    pub centre: Vector3<f64>,
    /// A pivot whose rows are readings relative to an unknown zero: that zero ([`zero`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub zero: Option<Zero>,
    /// A plane's or a cube's orientation (its frame's, [`touch`]); `centre` is its origin.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rotation: Option<nalgebra::UnitQuaternion<f64>>,
}

/// A mechanism with the artifact points of its instrument as extra parameters (module docs).
/// Its inputs are the mechanism's, then the index of the artifact point the measurement refers
/// to; its tool pose is the mechanism's relative to that point.
#[derive(Debug, Clone)]
pub struct Artifact<M> {
    /// The mechanism (usually seen through its frames, [`Framed`]: the tool offset).
    pub inner: M,
    /// The artifact points, in index order.
    pub points: Vec<ArtifactPoint>,
    /// Pairs of points (indices) whose known distance is a row of the data: the input index
    /// `points.len() + k` refers to pair `k`, whose "tool pose" is the translation between them.
    pub pairs: Vec<(usize, usize)>,
}

/// The artifact points of a data set, the pairs of known distances, and its measurements with
/// their point index appended (a known distance's row last).
pub type Indexed = (Vec<ArtifactPoint>, Vec<(usize, usize)>, Vec<Measurement>);

/// The artifact points the measurements refer to (sorted by kind, then number) and the
/// measurements with each one's point index appended to its inputs, then one row per known
/// seat distance (inputs zero, the pair's index, [`Observation::Distance`]); `None` when no
/// measurement is an instrument's. A tracker row among them refers to no point: its index is
/// [`NO_POINT`] ([`mixed`]). A distance between seats the data do not hold is an error.
pub fn index_points(measurements: &[Measurement], distances: &[SeatDistance]) -> Result<Option<Indexed>, CalibError> {
    let with_point = measurements.iter().filter(|m| m.obs.artifact_point().is_some()).count();
    if with_point == 0 {
        return Ok(None);
    }
    touch::check(measurements)?;
    let mut counts: BTreeMap<(PointKind, usize), usize> = BTreeMap::new();
    // Per pivot: rows with a reading relative to an unknown zero, the least and greatest.
    let mut relative: BTreeMap<usize, (usize, f64, f64)> = BTreeMap::new();
    for m in measurements {
        let Some(key) = m.obs.artifact_point() else { continue };
        *counts.entry(key).or_default() += 1;
        if let Some((true, r)) = zero::readings(&m.obs) {
            let e = relative.entry(key.1).or_insert((0, r, r));
            *e = (e.0 + 1, e.1.min(r), e.2.max(r));
        }
    }
    for (&(kind, id), &n) in &counts {
        let rel = relative.get(&id).filter(|_| kind == PointKind::Pivot);
        if let Some(&(n_rel, lo, hi)) = rel {
            if n_rel < n {
                return Err(CalibError::InvalidOption(format!(
                    "pivot {id} has {n_rel} reading rows (zero unknown) and {} length rows; give one kind per pivot",
                    n - n_rel
                )));
            }
            if n >= MIN_ZERO_PIVOT_ROWS && hi - lo < zero::MIN_READING_SPREAD_MM {
                return Err(CalibError::InvalidOption(format!(
                    "pivot {id}: every reading is {lo:.4} mm; with its zero unknown equal readings only say the tool point stays on some sphere (they do not give the scale): vary the length, or give its certified length (length_mm instead of reading_mm)"
                )));
            }
        }
        let least = match (kind, rel) {
            (PointKind::Seat, _) => MIN_SEAT_ROWS,
            (PointKind::Sphere | PointKind::Plane | PointKind::Cube, _) => touch::min_rows(kind),
            (_, Some(_)) => MIN_ZERO_PIVOT_ROWS,
            _ => MIN_PIVOT_ROWS,
        };
        if n < least {
            return Err(CalibError::InvalidOption(format!(
                "{} {id} has {n} row{}; at least {least} are needed to place it and learn from it (add rows, or remove that {})",
                kind.name(),
                if n == 1 { "" } else { "s" },
                kind.name()
            )));
        }
    }
    let points: Vec<ArtifactPoint> = counts
        .keys()
        .map(|&(kind, id)| zero::pivot_point(kind, id, relative.get(&id).filter(|_| kind == PointKind::Pivot).map(|r| r.1)))
        .collect();
    let index: BTreeMap<(PointKind, usize), usize> = counts.keys().enumerate().map(|(k, &key)| (key, k)).collect();
    let mut indexed: Vec<Measurement> = measurements
        .iter()
        .map(|m| {
            let mut q = m.q.clone();
            let Some(point) = m.obs.artifact_point() else {
                q.push(NO_POINT);
                return Measurement { q, ..m.clone() };
            };
            let k = index[&point];
            q.push(k as f64);
            let mut obs = m.obs.clone();
            // A reading's row carries the reading plus its pivot's reference ([`zero`]).
            if let (Observation::Distance { length, .. }, Some(z)) = (&mut obs, points[k].zero) {
                *length += z.reference;
            }
            Measurement { q, obs, ..m.clone() }
        })
        .collect();
    let mut pairs = Vec::new();
    let n_inputs = measurements[0].q.len();
    for d in distances {
        let seat = |id: usize| {
            index
                .get(&(PointKind::Seat, id))
                .copied()
                .ok_or_else(|| CalibError::InvalidOption(format!("seat distance {}:{}:{}: the data hold no seat {id}", d.a, d.b, d.length)))
        };
        let (a, b) = (seat(d.a)?, seat(d.b)?);
        let mut q = vec![0.0; n_inputs];
        q.push((points.len() + pairs.len()) as f64);
        pairs.push((a, b));
        indexed.push(Measurement {
            q,
            obs: Observation::Distance {
                pivot: crate::measure::KNOWN_DISTANCE,
                length: d.length,
                relative: false,
            },
            joints: Vec::new(),
        });
    }
    Ok(Some((points, pairs, indexed)))
}

/// A fitted tool point counts as collapsed onto its pivot's other rows when its spread is below
/// this share of the starting model's.
pub const COLLAPSE: f64 = 0.1;

/// The pivots (indices into the artifact points) whose tool points `fitted` puts at nearly one
/// place while `start` spreads them ([`COLLAPSE`]), with both spreads (mm, RMS about their mean).
/// Every row of a fixed-length bar has the same length, so a machine whose tool point stands
/// still over a pivot's rows fits them all exactly: such a fit is a wrong machine, not a
/// calibration. `indexed`: the measurements as the fit used them ([`index_points`]).
pub fn collapsed_pivots(start: &dyn Mechanism, fitted: &dyn Mechanism, indexed: &[Measurement]) -> Vec<(usize, f64, f64)> {
    // The measured rows of each pivot (not the known distances between seats).
    let mut rows: BTreeMap<usize, Vec<&Measurement>> = BTreeMap::new();
    for m in indexed {
        if let (Observation::Distance { pivot, .. }, Some(&k)) = (&m.obs, m.q.last()) {
            if *pivot != crate::measure::KNOWN_DISTANCE {
                rows.entry(k as usize).or_default().push(m);
            }
        }
    }
    let rms = |model: &dyn Mechanism, rows: &[&Measurement]| -> Option<f64> {
        let points = rows
            .iter()
            .map(|m| model.forward(&m.q).ok().map(|t| t.translation.vector))
            .collect::<Option<Vec<_>>>()?;
        Some(spread(&points).1)
    };
    rows.into_iter()
        .filter_map(|(k, rows)| {
            let (s, f) = (rms(start, &rows)?, rms(fitted, &rows)?);
            (f < COLLAPSE * s).then_some((k, s, f))
        })
        .collect()
}

/// The mean of `points`, their RMS distance from it and the largest (mm): how far a model puts
/// one seat's (or one pivot's) tool points apart.
pub fn spread(points: &[Vector3<f64>]) -> (Vector3<f64>, f64, f64) {
    let n = points.len().max(1) as f64;
    let mean = points.iter().sum::<Vector3<f64>>() / n;
    let d: Vec<f64> = points.iter().map(|p| (p - mean).norm()).collect();
    let (rms, max) = rms_and_max(&d);
    (mean, rms, max)
}

/// The RMS of `values` and the largest magnitude (0 for none).
fn rms_and_max(values: &[f64]) -> (f64, f64) {
    let rms = (values.iter().map(|x| x * x).sum::<f64>() / values.len().max(1) as f64).sqrt();
    (rms, values.iter().map(|x| x.abs()).fold(0.0, f64::max))
}

/// The centre `c` of the sphere on which points `p_i` lie at distances `L_i` (least squares:
/// the linear solution of `2·p_i·c − |c|² = |p_i|² − L_i²`, then Gauss–Newton on `L_i − |p_i − c|`).
pub fn sphere_centre(rows: &[(Vector3<f64>, f64)]) -> Option<Vector3<f64>> {
    let n = rows.len();
    let mut a = DMatrix::zeros(n, 4);
    let mut b = DVector::zeros(n);
    for (r, (p, l)) in rows.iter().enumerate() {
        for i in 0..3 {
            a[(r, i)] = 2.0 * p[i];
        }
        a[(r, 3)] = -1.0;
        b[r] = p.norm_squared() - l * l;
    }
    let svd = a.svd(true, true);
    let smax = svd.singular_values.max();
    if svd.singular_values.min() <= 1e-9 * smax {
        return None;
    }
    let x = svd.solve(&b, 0.0).ok()?;
    let mut c = Vector3::new(x[0], x[1], x[2]);
    // The residuals `L_i − |p_i − c|` and their Jacobian: moving c by δ along the unit vector
    // u_i = (p_i − c)/|p_i − c| shortens |p_i − c| by u_i·δ, so the row is +u_i.
    let linearise = |c: &Vector3<f64>| -> Option<(DMatrix<f64>, DVector<f64>)> {
        let mut j = DMatrix::zeros(n, 3);
        let mut r = DVector::zeros(n);
        for (k, (p, l)) in rows.iter().enumerate() {
            let d = p - c;
            let u = d.try_normalize(1e-12)?;
            r[k] = l - d.norm();
            for i in 0..3 {
                j[(k, i)] = u[i];
            }
        }
        Some((j, r))
    };
    let (mut j, mut r) = linearise(&c)?;
    for _ in 0..20 {
        let step = j.clone().svd(true, true).solve(&r, 1e-12).ok()?;
        // Gauss–Newton: c − (JᵀJ)⁻¹Jᵀr, kept only while it lowers the cost.
        let trial = c - Vector3::new(step[0], step[1], step[2]);
        let Some((jt, rt)) = linearise(&trial) else { break };
        if rt.norm_squared().is_nan() || rt.norm_squared() >= r.norm_squared() {
            break;
        }
        (c, j, r) = (trial, jt, rt);
        if step.norm() < 1e-13 * (1.0 + c.norm()) {
            break;
        }
    }
    c.iter().all(|v| v.is_finite()).then_some(c)
}

impl<M: Mechanism> Artifact<M> {
    /// The inner inputs and the artifact point of inputs `q` (an index past the points is a
    /// known distance's pair: [`Self::pair`]).
    fn split<'q>(&self, q: &'q [f64]) -> Result<(&'q [f64], usize), KinError> {
        let n = self.inner.input_names().len();
        crate::model::check_inputs(q, n + 1)?;
        let k = q[n];
        if !(k >= 0.0 && k.fract() == 0.0 && (k as usize) < self.points.len() + self.pairs.len()) {
            return Err(KinError::OutOfWorkspace(format!(
                "artifact point index {k} (the data refer to {} points)",
                self.points.len()
            )));
        }
        Ok((&q[..n], k as usize))
    }

    /// The columns of the artifact's own parameters, after the mechanism's: the points' (three
    /// each, six for a cube), then the zeros of pivots with readings.
    pub fn artifact_columns(&self) -> std::ops::Range<usize> {
        let p = self.inner.n_params();
        p..p + self.n_point_params() + self.n_zeros()
    }

    /// For index `k` past the points, the translation from its pair's second seat to its first
    /// and the Jacobian (the machine's columns zero).
    fn pair(&self, k: usize) -> Option<(Pose, Matrix6xX<f64>)> {
        let &(a, b) = self.pairs.get(k.checked_sub(self.points.len())?)?;
        let p = self.inner.n_params();
        let mut jac = Matrix6xX::zeros(self.artifact_columns().end);
        for i in 0..3 {
            jac[(i, p + self.point_offset(a) + i)] = 1.0;
            jac[(i, p + self.point_offset(b) + i)] = -1.0;
        }
        let d = self.points[a].centre - self.points[b].centre;
        Some((Pose::from_parts(Translation3::from(d), nalgebra::UnitQuaternion::identity()), jac))
    }

    /// The pose relative to point `k` and the Jacobian with the points' columns appended.
    fn relative(&self, k: usize, (pose, jac): (Pose, Matrix6xX<f64>)) -> (Pose, Matrix6xX<f64>) {
        let p = jac.ncols();
        let shift = self.shift(k);
        let mut out = Matrix6xX::zeros(self.artifact_columns().end);
        // The inner twists are about the base origin; relative to the point they are seen through
        // the shift's adjoint.
        out.columns_mut(0, p)
            .copy_from(&crate::se3::mul6(&crate::se3::adjoint(&shift), &jac));
        // Moving the point's frame by a local twist ξ (a point's centre by δc: ξ = (δc, 0))
        // moves the relative pose by −ξ: P⁻¹·T becomes exp(−ξ)·P⁻¹·T.
        for (i, &row) in self.points[k].kind.twist_rows().iter().enumerate() {
            out[(row, p + self.point_offset(k) + i)] = -1.0;
        }
        let zero_column = self.zero_index(k).map_or(usize::MAX, |z| p + self.n_point_params() + z);
        self.with_zero(k, zero_column, (shift * pose, out))
    }
}

impl<M: Mechanism + Clone + 'static> Mechanism for Artifact<M> {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn input_names(&self) -> Vec<String> {
        let mut out = self.inner.input_names();
        out.push("artifact point".into());
        out
    }
    fn params(&self) -> Vec<Param> {
        let mut out = self.inner.params();
        for p in &self.points {
            for a in p.kind.param_names() {
                let unit = if a.starts_with('r') { Unit::Angle } else { Unit::Length };
                out.push(Param::new(format!("{}{}.{a}", p.kind.name(), p.id), unit, ARTIFACT_GROUP));
            }
        }
        for p in self.points.iter().filter(|p| p.zero.is_some()) {
            out.push(Param::new(format!("{}{}.zero", p.kind.name(), p.id), Unit::Length, ARTIFACT_GROUP));
        }
        out
    }
    fn n_params(&self) -> usize {
        self.artifact_columns().end
    }
    fn assembly_breaking(&self) -> Vec<usize> {
        self.inner.assembly_breaking()
    }
    fn forward(&self, q: &[f64]) -> Result<Pose, KinError> {
        if let Some(qi) = self.tracker_inputs(q) {
            return self.inner.forward(qi);
        }
        let (qi, k) = self.split(q)?;
        if let Some((pose, _)) = self.pair(k) {
            return Ok(pose);
        }
        Ok(self.moved(k, self.shift(k) * self.inner.forward(qi)?))
    }
    fn forward_with_jacobian(&self, q: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        if let Some(qi) = self.tracker_inputs(q) {
            let (pose, jac) = self.inner.forward_with_jacobian(qi)?;
            return Ok((pose, self.padded(jac)));
        }
        let (qi, k) = self.split(q)?;
        if let Some(pair) = self.pair(k) {
            return Ok(pair);
        }
        Ok(self.relative(k, self.inner.forward_with_jacobian(qi)?))
    }
    fn forward_with_jacobian_near(&self, q: &[f64], near: &Pose) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        if let Some(qi) = self.tracker_inputs(q) {
            let (pose, jac) = self.inner.forward_with_jacobian_near(qi, near)?;
            return Ok((pose, self.padded(jac)));
        }
        let (qi, k) = self.split(q)?;
        if let Some(pair) = self.pair(k) {
            return Ok(pair);
        }
        let inner_near = self.shift(k).inverse() * self.unmoved(k, near);
        Ok(self.relative(k, self.inner.forward_with_jacobian_near(qi, &inner_near)?))
    }
    fn retract(&mut self, delta: &DVector<f64>) {
        let p = self.inner.n_params();
        self.inner.retract(&delta.rows(0, p).into_owned());
        let mut z = p + self.n_point_params();
        let mut at = p;
        for point in self.points.iter_mut() {
            let n = point.kind.twist_rows().len();
            touch::retract_point(point, &delta.rows(at, n));
            at += n;
            if let Some(zero) = point.zero.as_mut() {
                zero.value += delta[z];
                z += 1;
            }
        }
    }
    /// Not defined: an artifact point is no target (command the mechanism itself).
    fn inverse(&self, _target: &Pose, _seed: Option<&[f64]>) -> Result<Vec<f64>, KinError> {
        Err(KinError::Unreachable(
            "inverse kinematics relative to an instrument's artifact point; compensate with the calibrated model file instead".into(),
        ))
    }
    fn box_clone(&self) -> Box<dyn Mechanism> {
        Box::new(self.clone())
    }
    fn geometry(&self) -> Option<Vec<f64>> {
        self.inner.geometry()
    }
    fn frames(&self) -> Option<(Pose, Pose)> {
        self.inner.frames()
    }
    fn task(&self) -> Task {
        self.inner.task()
    }
    /// The machine's drawing (the artifacts are the report's to draw).
    fn skeleton(&self) -> Vec<Vec<Vector3<f64>>> {
        self.inner.skeleton()
    }
    fn observed_joints(&self) -> Vec<(String, Unit)> {
        self.inner.observed_joints()
    }
    fn observed_joint_values(&self, q: &[f64]) -> Result<Vec<f64>, KinError> {
        if let Some(qi) = self.tracker_inputs(q) {
            return self.inner.observed_joint_values(qi);
        }
        let (qi, k) = self.split(q)?;
        if self.pair(k).is_some() {
            return Ok(Vec::new());
        }
        self.inner.observed_joint_values(qi)
    }
    fn observed_joints_with_jacobian(&self, q: &[f64]) -> Result<(Vec<f64>, DMatrix<f64>), KinError> {
        let qi = match self.tracker_inputs(q) {
            Some(qi) => qi,
            None => self.split(q)?.0,
        };
        let (values, rows) = self.inner.observed_joints_with_jacobian(qi)?;
        Ok((values, self.padded_rows(&rows)))
    }
    fn forward_with_jacobian_and_observed(&self, q: &[f64], near: Option<&Pose>) -> Result<ForwardAndObserved, KinError> {
        if let Some(qi) = self.tracker_inputs(q) {
            let (pose, jac, values, rows) = self.inner.forward_with_jacobian_and_observed(qi, near)?;
            return Ok((pose, self.padded(jac), values, self.padded_rows(&rows)));
        }
        let (qi, k) = self.split(q)?;
        if let Some((pose, jac)) = self.pair(k) {
            return Ok((pose, jac, Vec::new(), DMatrix::zeros(0, self.n_params())));
        }
        let inner_near = near.map(|n| self.shift(k).inverse() * self.unmoved(k, n));
        let (pose, jac, values, rows) = self.inner.forward_with_jacobian_and_observed(qi, inner_near.as_ref())?;
        let (pose, jac) = self.relative(k, (pose, jac));
        Ok((pose, jac, values, self.padded_rows(&rows)))
    }
}

#[cfg(test)]
mod tests;
