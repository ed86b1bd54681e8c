//! A touch probe (a ball of radius `r` on a stylus; its centre is the tool point) on reference
//! artifacts: spheres of known diameter at unknown centres, unknown planes, a datum cube of known
//! edge in an unknown pose ([`crate::measure::touch`] for the residuals).
//!
//! Each artifact is one [`ArtifactPoint`] of [`super::Artifact`] with a frame `P`: a sphere's is
//! its centre (3 unknowns, `sphere0.x …`, like a pivot's); a plane's has its origin on the plane
//! and `z` along its normal, moved by a local twist of 3 components (`plane0.rx plane0.ry` the
//! tilts, `plane0.z` the offset along the normal); the cube's is at its centre along its edges,
//! moved by a full local twist (`cube0.x … cube0.rz`). `P ← P·exp(ξ)` moves the relative pose
//! `P⁻¹·T` by `−ξ` ([`super::Artifact`]'s Jacobian).
//!
//! The frames are started from the data ([`super::start_points`]) at the nominal geometry: each sphere by a
//! sphere fit of the tool points to `D/2 + r`; each plane by the plane through its tool points
//! (least squares), its normal toward the flange (the probe reaches the surface from outside);
//! the cube from its touched faces fitted as planes (opposite faces orient each other, a face
//! without its opposite takes the flange's side), its rotation the one that best turns the
//! faces' normals in its frame onto them, its centre by least squares on every touch.
use super::{Artifact, ArtifactPoint, PointKind};
use crate::error::CalibError;
use crate::measure::touch::{face_normal, Touch, FACE_NAMES};
use crate::measure::{Measurement, Observation};
use crate::se3::{self, Pose};
use nalgebra::{DMatrix, DVector, DVectorView, Matrix3, Translation3, UnitQuaternion, Vector3};
use std::collections::BTreeMap;

/// Whether nothing in `measurements` gives a length, so that a machine whose inputs all turn
/// has no scale: every row an unknown plane's touch or a seat, no known distance between seats
/// (`seat_distances`). A plane's offset absorbs any scale and the probe radius holds it only
/// weakly; with noise the fit shrinks the machine (module docs of [`crate::instrument`]). A
/// cube's edge, a sphere's diameter, a ballbar's lengths and tracker rows all give one.
pub fn no_length(measurements: &[Measurement], seat_distances: &[super::SeatDistance]) -> bool {
    seat_distances.is_empty()
        && measurements
            .iter()
            .any(|m| matches!(m.obs, Observation::Touch(Touch::Plane { .. })))
        && measurements
            .iter()
            .all(|m| matches!(m.obs, Observation::Touch(Touch::Plane { .. }) | Observation::Seat(_)))
}

/// Touches a plane needs at least: three not on a line place it.
pub const MIN_PLANE_ROWS: usize = 3;

/// Touches a sphere needs at least: its centre is three unknowns, the fourth touch is the first
/// that tells something about the machine.
pub const MIN_SPHERE_ROWS: usize = 4;

/// The smallest sphere diameter or cube edge taken as mm: below it the number is taken for
/// metres written in a mm column.
pub const MIN_ARTIFACT_MM: f64 = 1.0;

/// The touches of a data set checked as a whole: every face of the cube touched at least
/// [`MIN_PLANE_ROWS`] times, one diameter per sphere and one edge for the cube (mm, at least
/// [`MIN_ARTIFACT_MM`]), a probe radius not negative. One-line errors.
pub fn check(measurements: &[Measurement]) -> Result<(), CalibError> {
    let bad = |m: String| Err(CalibError::InvalidOption(m));
    let mut sizes: BTreeMap<(PointKind, usize), f64> = BTreeMap::new();
    let mut faces = [0usize; 6];
    for m in measurements {
        let Observation::Touch(t) = &m.obs else { continue };
        let probe = t.probe();
        if !(probe.is_finite() && probe >= 0.0) {
            return bad(format!(
                "probe radius {probe} mm: the radius of the probe's tip ball (probe_radius_mm, mm; 0 for a pointed tip) is needed and cannot be negative"
            ));
        }
        let (what, size) = match *t {
            Touch::Sphere { diameter, .. } => ("sphere diameter", diameter),
            Touch::Face { face, edge, .. } => {
                if face >= 6 {
                    return bad(format!(
                        "cube face {face}: faces are 0..5 (+x, -x, +y, -y, +z, -z of the cube's frame)"
                    ));
                }
                faces[face] += 1;
                ("cube edge", edge)
            }
            Touch::Plane { .. } => continue,
        };
        let (kind, id) = t.artifact();
        if !(size.is_finite() && size >= MIN_ARTIFACT_MM) {
            let column = if kind == PointKind::Sphere {
                "sphere_diameter"
            } else {
                "cube_edge"
            };
            return bad(format!(
                "{} {id}: {what} {size} mm is not a plausible size in mm (under {MIN_ARTIFACT_MM} mm): is it in metres? give it in mm ({column}_mm), or in metres as {column}_m",
                kind.name(),
            ));
        }
        if let Some(&other) = sizes.get(&(kind, id)) {
            if (other - size).abs() > 1e-9 * size {
                return bad(format!(
                    "{} {id}: its rows give {what}s {other} and {size} mm; one artifact has one size",
                    kind.name()
                ));
            }
        }
        sizes.insert((kind, id), size);
    }
    for (j, &n) in faces.iter().enumerate() {
        if n > 0 && n < MIN_PLANE_ROWS {
            return bad(format!(
                "cube face {j} ({}) has {n} touch{}; at least {MIN_PLANE_ROWS} not on a line are needed to place a face (add touches, or remove that face's)",
                FACE_NAMES[j],
                if n == 1 { "" } else { "es" }
            ));
        }
    }
    Ok(())
}

/// Rows an artifact of `kind` needs at least (the cube: [`check`] counts its faces').
pub fn min_rows(kind: PointKind) -> usize {
    match kind {
        PointKind::Sphere => MIN_SPHERE_ROWS,
        _ => MIN_PLANE_ROWS,
    }
}

/// Point `point` moved by `delta` (its parameters' step): a centre by `δ`; a frame `P` by
/// `P·exp(ξ)`, `ξ` the local twist whose components [`PointKind::twist_rows`] names.
pub(super) fn retract_point(point: &mut ArtifactPoint, delta: &DVectorView<f64>) {
    if point.rotation.is_none() {
        point.centre += Vector3::new(delta[0], delta[1], delta[2]);
        return;
    }
    let mut xi = se3::Twist::zeros();
    for (i, &row) in point.kind.twist_rows().iter().enumerate() {
        xi[row] = delta[i];
    }
    let moved = point.frame() * se3::exp(&xi);
    (point.centre, point.rotation) = (moved.translation.vector, Some(moved.rotation));
}

impl ArtifactPoint {
    /// Its frame: its centre, turned by its rotation (planes, the cube).
    pub fn frame(&self) -> Pose {
        Pose::from_parts(
            Translation3::from(self.centre),
            self.rotation.unwrap_or_else(UnitQuaternion::identity),
        )
    }
}

impl<M> Artifact<M> {
    /// Point `k`'s frame ([`ArtifactPoint::frame`]).
    pub(super) fn frame(&self, k: usize) -> Pose {
        self.points[k].frame()
    }

    /// The inverse of point `k`'s frame ([`Self::frame`]): for a seat or a pivot, the translation
    /// by minus its centre.
    pub(super) fn shift(&self, k: usize) -> Pose {
        self.frame(k).inverse()
    }

    /// How many parameters the points have (three each, six for a cube).
    pub fn n_point_params(&self) -> usize {
        self.point_offset(self.points.len())
    }

    /// The offset of point `k`'s parameters among the points'.
    pub(super) fn point_offset(&self, k: usize) -> usize {
        self.points[..k].iter().map(|p| p.kind.twist_rows().len()).sum()
    }
}

/// The plane through `points` (least squares): their mean and the unit normal (either sign),
/// or `None` when they lie on a line (or are fewer than three).
pub fn fit_plane(points: &[Vector3<f64>]) -> Option<(Vector3<f64>, Vector3<f64>)> {
    if points.len() < 3 {
        return None;
    }
    let (mean, m) = scatter(points);
    let eig = m.symmetric_eigen();
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    // The middle spread against the largest: a line has none.
    let (mid, max) = (eig.eigenvalues[order[1]], eig.eigenvalues[order[2]]);
    if !(mid > 1e-12 * max && mid > 1e-18) {
        return None;
    }
    Some((mean, eig.eigenvectors.column(order[0]).into_owned()))
}

/// The mean of `points` and their scatter matrix about it (`Σ (p − mean)(p − mean)ᵀ`).
fn scatter(points: &[Vector3<f64>]) -> (Vector3<f64>, Matrix3<f64>) {
    let mean = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    (
        mean,
        points.iter().fold(Matrix3::zeros(), |a, p| a + (p - mean) * (p - mean).transpose()),
    )
}

/// The rotation taking `z` onto `n` (a unit vector).
fn z_onto(n: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(&Vector3::z(), n)
        .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI))
}

/// Place the touched artifacts of `points` (module docs) from rows `(point index, tool pose,
/// flange position, observation)` at the starting geometry.
pub(super) fn place(rows: &[TouchRow], points: &mut [ArtifactPoint]) -> Result<(), CalibError> {
    let of = |k: usize| rows.iter().filter(move |r| r.0 == k);
    for (k, point) in points.iter_mut().enumerate() {
        let (kind, id) = (point.kind, point.id);
        let not_placed = |why: &str| CalibError::InvalidOption(format!("{} {id}: {why}", kind.name()));
        match point.kind {
            PointKind::Sphere => {
                let sphere: Vec<(Vector3<f64>, f64)> = of(k)
                    .filter_map(|(_, pose, _, obs)| match obs {
                        Observation::Touch(t) => Some((pose.translation.vector, t.measured())),
                        _ => None,
                    })
                    .collect();
                point.centre = super::sphere_centre(&sphere).ok_or_else(|| {
                    not_placed("its touches do not place it (they lie in a plane or on a line): touch it from more directions")
                })?;
            }
            PointKind::Plane => {
                let tips: Vec<Vector3<f64>> = of(k).map(|r| r.1.translation.vector).collect();
                let flange = of(k).map(|r| r.2).sum::<Vector3<f64>>() / tips.len().max(1) as f64;
                let (mean, mut n) = fit_plane(&tips)
                    .ok_or_else(|| not_placed("its touches lie on a line; touch it at three points or more not in a line"))?;
                if n.dot(&(flange - mean)) < 0.0 {
                    n = -n;
                }
                let probe = of(k).map(|r| touch_of(r.3).probe()).sum::<f64>() / tips.len() as f64;
                point.centre = mean - probe * n;
                point.rotation = Some(z_onto(&n));
            }
            PointKind::Cube => place_cube(&of(k).collect::<Vec<_>>(), point)?,
            PointKind::Seat | PointKind::Pivot => {}
        }
    }
    Ok(())
}

fn touch_of(obs: &Observation) -> Touch {
    match obs {
        Observation::Touch(t) => *t,
        _ => unreachable!("a touched artifact's rows are touches"),
    }
}

/// A touched face: its tool points' mean, its normal (either sign), the flange's mean.
type FittedFace = (Vector3<f64>, Vector3<f64>, Vector3<f64>);

/// The cube's frame from its touches (module docs).
fn place_cube(rows: &[&(usize, Pose, Vector3<f64>, &Observation)], cube: &mut ArtifactPoint) -> Result<(), CalibError> {
    let face_of = |r: &&(usize, Pose, Vector3<f64>, &Observation)| match touch_of(r.3) {
        Touch::Face { face, .. } => face,
        _ => 6,
    };
    // Each touched face: its tool points' mean and the fitted normal (either sign), the flange's mean.
    let mut fitted: [Option<FittedFace>; 6] = [None; 6];
    for (j, slot) in fitted.iter_mut().enumerate() {
        let on: Vec<_> = rows.iter().filter(|r| face_of(r) == j).collect();
        if on.is_empty() {
            continue;
        }
        let tips: Vec<Vector3<f64>> = on.iter().map(|r| r.1.translation.vector).collect();
        let (mean, n) = fit_plane(&tips).ok_or_else(|| {
            CalibError::InvalidOption(format!(
                "cube face {j} ({}): its touches lie on a line; touch it at three points or more not in a line",
                FACE_NAMES[j]
            ))
        })?;
        let flange = on.iter().map(|r| r.2).sum::<Vector3<f64>>() / on.len() as f64;
        *slot = Some((mean, n, flange));
    }
    // Outward normals: away from the opposite face when it is touched, else toward the flange.
    let mut normals = Vec::new();
    for j in 0..6 {
        let Some((mean, n, flange)) = fitted[j] else { continue };
        let away = match fitted[j ^ 1] {
            Some((opposite, ..)) => mean - opposite,
            None => flange - mean,
        };
        normals.push((j, if n.dot(&away) < 0.0 { -n } else { n }));
    }
    // The rotation that best turns the faces' normals in the cube's frame onto the fitted ones.
    let mut h = Matrix3::zeros();
    for (j, n) in &normals {
        h += n * face_normal(*j).transpose();
    }
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u.expect("u"), svd.v_t.expect("v"));
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = u * d * vt;
    // The centre: (R·f_j)·(p_i − c) = r + e/2 over every touch.
    let mut a = DMatrix::zeros(rows.len(), 3);
    let mut b = DVector::zeros(rows.len());
    for (i, row) in rows.iter().enumerate() {
        let t = touch_of(row.3);
        let n = r * face_normal(face_of(row));
        let p = row.1.translation.vector;
        for c in 0..3 {
            a[(i, c)] = n[c];
        }
        b[i] = n.dot(&p) - t.measured();
    }
    let x = a
        .svd(true, true)
        .solve(&b, 1e-9)
        .map_err(|e| CalibError::Numerical(format!("placing the cube: {e}")))?;
    cube.centre = Vector3::new(x[0], x[1], x[2]);
    cube.rotation = Some(UnitQuaternion::from_matrix(&r));
    Ok(())
}

/// A touch row: point index, tool pose at the starting geometry, flange position, observation.
pub(super) type TouchRow<'a> = (usize, Pose, Vector3<f64>, &'a Observation);

/// The lengths (mm) along each axis of the tool frame, either way, that the tool-point offset is
/// started from besides the flange's tool point ([`offset_and_touched`]).
const OFFSET_STARTS_MM: [f64; 2] = [100.0, 200.0];

/// The tool-point offset `t` (tool frame, added to the starting tool point) and the touched
/// artifacts fitted together on the touches, Levenberg–Marquardt over `t` and the artifacts'
/// parameters (Jacobian by central differences), from `t = 0` and from [`OFFSET_STARTS_MM`]
/// along each axis of the tool frame either way; another start replaces the first only at a
/// clearly lower cost (a machine that never turns its tool cannot tell the offset from the
/// artifacts). Returns `t` and moves the points; an error when no start can place them.
pub(super) fn offset_and_touched(rows: &[TouchRow], points: &mut [ArtifactPoint]) -> Result<Vector3<f64>, CalibError> {
    let starts = std::iter::once(Vector3::zeros()).chain(OFFSET_STARTS_MM.into_iter().flat_map(super::offset::along_each_axis));
    let mut best: Option<(Vector3<f64>, f64, Vec<ArtifactPoint>)> = None;
    let mut first_error = None;
    let mut flat_offset = None;
    for t0 in starts {
        let mut candidate = points.to_vec();
        let moved: Vec<TouchRow> = rows.iter().map(|r| (r.0, r.1 * Translation3::from(t0), r.2, r.3)).collect();
        if let Err(e) = place(&moved, &mut candidate) {
            first_error.get_or_insert(e);
            continue;
        }
        let (t, cost) = fit_touches(rows, t0, &mut candidate, true);
        if planes_collapse(rows, &t, &candidate) {
            flat_offset.get_or_insert(t);
            continue;
        }
        if best.as_ref().is_none_or(|b| cost < 0.5 * b.1) {
            best = Some((t, cost, candidate));
        }
    }
    let (t, _, placed) = best.ok_or_else(|| match (flat_offset, first_error) {
        (Some(t), _) => CalibError::InvalidOption(format!(
            "the touched planes cannot be told apart: every tool-point offset found (e.g. {:.1}, {:.1}, {:.1} mm) puts the probe centre of every touch in one plane, \
             a point the machine keeps in a plane (such as a 3-PRS head's spherical joints); give the probe's offset in the model's tool frame, or touch spheres or a datum cube",
            t.x, t.y, t.z
        )),
        (None, e) => e.expect("a start failed"),
    })?;
    points.clone_from_slice(&placed);
    Ok(t)
}

/// Whether, at tool-point offset `t`, the probe centres of two or more touched planes all lie in
/// one plane: a degenerate fit (each plane's touches on a line, or the planes one plane) that a
/// point the machine keeps in a plane gives at zero cost, whatever the planes touched (a 3-PRS
/// head's spherical joints move in fixed planes). Distinct planes with the right offset cannot
/// do it: a plane's touches in a second plane lie on their line of intersection.
pub(super) fn planes_collapse(rows: &[TouchRow], t: &Vector3<f64>, points: &[ArtifactPoint]) -> bool {
    let on_planes = |k: &usize| points[*k].kind == PointKind::Plane;
    let tips: Vec<Vector3<f64>> = rows
        .iter()
        .filter(|r| on_planes(&r.0))
        .map(|(_, pose, _, _)| pose.translation.vector + pose.rotation * t)
        .collect();
    let planes = rows
        .iter()
        .map(|r| r.0)
        .filter(on_planes)
        .collect::<std::collections::BTreeSet<_>>();
    if planes.len() < 2 {
        return false;
    }
    let eig = scatter(&tips).1.symmetric_eigen().eigenvalues;
    let (lo, hi) = (eig.min(), eig.max());
    // Thicknesses (square roots): below a millionth of the spread is one plane to round-off.
    lo.max(0.0).sqrt() <= 1e-6 * hi.sqrt()
}

/// The touches' residuals for tool-point offset `t` and artifacts `points`.
fn touch_residuals(rows: &[TouchRow], t: &Vector3<f64>, points: &[ArtifactPoint]) -> DVector<f64> {
    DVector::from_iterator(
        rows.len(),
        rows.iter().map(|(k, pose, _, obs)| {
            let tip = pose.translation.vector + pose.rotation * t;
            touch_of(obs).residual(&points[*k].frame().inverse_transform_point(&tip.into()).coords)
        }),
    )
}

/// The touched artifacts `points` placed on their touches `rows` for the tool points as they
/// are (a model judged on held-out touches, [`super::held_out`]): started as identification
/// starts them ([`place`]), then refined by Levenberg–Marquardt on the touches' residuals
/// ([`fit_touches`] without the offset). Returns the residuals (mm, one per row).
pub(super) fn placed_residuals(rows: &[TouchRow], points: &mut [ArtifactPoint]) -> Result<DVector<f64>, CalibError> {
    place(rows, points)?;
    fit_touches(rows, Vector3::zeros(), points, false);
    Ok(touch_residuals(rows, &Vector3::zeros(), points))
}

/// Levenberg–Marquardt from `t0` ([`offset_and_touched`]) over the touched artifacts and, when
/// `free_offset`, the tool-point offset (else it stays `t0`): the offset and the cost `Σ r²`.
fn fit_touches(rows: &[TouchRow], t0: Vector3<f64>, points: &mut [ArtifactPoint], free_offset: bool) -> (Vector3<f64>, f64) {
    let touched: Vec<usize> = (0..points.len()).filter(|&k| points[k].kind > PointKind::Pivot).collect();
    let first = if free_offset { 3 } else { 0 };
    let n = first + touched.iter().map(|&k| points[k].kind.twist_rows().len()).sum::<usize>();
    let step = |t: &Vector3<f64>, pts: &[ArtifactPoint], x: &DVector<f64>| -> (Vector3<f64>, Vec<ArtifactPoint>) {
        let mut moved = pts.to_vec();
        let mut at = first;
        for &k in &touched {
            let m = moved[k].kind.twist_rows().len();
            retract_point(&mut moved[k], &x.rows(at, m));
            at += m;
        }
        let dt = if free_offset {
            Vector3::new(x[0], x[1], x[2])
        } else {
            Vector3::zeros()
        };
        (t + dt, moved)
    };
    let (mut t, mut pts) = (t0, points.to_vec());
    let mut r = touch_residuals(rows, &t, &pts);
    let mut lambda = 1e-3;
    for _ in 0..100 {
        let h = 1e-6;
        let mut j = DMatrix::zeros(rows.len(), n);
        for c in 0..n {
            let mut e = DVector::zeros(n);
            e[c] = h;
            let (tp, pp) = step(&t, &pts, &e);
            let (tm, pm) = step(&t, &pts, &(-e));
            j.set_column(
                c,
                &((touch_residuals(rows, &tp, &pp) - touch_residuals(rows, &tm, &pm)) / (2.0 * h)),
            );
        }
        let (jtj, g, cost) = (j.transpose() * &j, j.transpose() * &r, r.norm_squared());
        let improved = super::offset::damped_step(&jtj, &g, &mut lambda, |dx| {
            let (tt, pt) = step(&t, &pts, dx);
            let rt = touch_residuals(rows, &tt, &pt);
            let lower = rt.norm_squared() < cost;
            if lower {
                (t, pts, r) = (tt, pt, rt);
            }
            lower
        });
        if !improved || cost - r.norm_squared() <= 1e-15 * (1.0 + cost) {
            break;
        }
    }
    points.clone_from_slice(&pts);
    (t, r.norm_squared())
}
