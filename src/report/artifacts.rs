//! An instrument calibration in the report (seats, pivots, spheres, planes, a datum cube:
//! [`crate::instrument`]). Its rows measure no coordinates, so the report places them itself:
//! each row's tool point where the model puts it in the machine's base frame, the artifacts at
//! their places there, and the known distances between seats apart from the poses.
//!
//! A model fitted to instrument data ([`crate::instrument::Artifact`]) predicts a row's tool
//! frame `R` relative to its artifact's frame `F`; the same row with its artifact index replaced
//! by [`NO_POINT`] is predicted as a tracker row is, by the machine alone: its tool frame `T` in
//! the base frame. The artifact's frame is then `F = T·R⁻¹`, exact for every kind but a pivot
//! whose rows are readings relative to an unknown zero: its relative frame is moved along the bar
//! by the zero's offset `s`, and its centre `c` and `s` solve `c − s·u_i = T_i − |R_i|·u_i`
//! (`u_i` the bar's direction) over its rows, by least squares (exact on the model's own
//! predictions).
//!
//! No instrument here sees where the machine stands; `calibrate` therefore writes the
//! calibrated model placed as drawn (the rigid motion that best takes its tool points at the
//! data's configurations onto the starting model's goes into its measurement frame). The report
//! draws the calibrated machine, its artifacts and its tool points through the same motion
//! (`CalibrationReport::place_as_drawn`), so that the view shows the calibrated model file's
//! base frame, the one targets are given in.
use super::{CalibrationReport, SetErrors};
use crate::error::{CalibError, KinError};
use crate::instrument::NO_POINT;
use crate::measure::{Measurement, Observation, PointKind, Touch, KNOWN_DISTANCE};
use crate::model::Mechanism;
use crate::se3::Pose;
use nalgebra::{DMatrix, DVector, Vector3};
use serde::Serialize;

/// One artifact of an instrument calibration as the 3-D view draws it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArtifactView {
    /// Its name: `seat 3`, `pivot 0`, `sphere 1`, `plane 0`, `cube 0`.
    pub name: String,
    /// Its kind ([`PointKind::name`]).
    pub kind: String,
    /// Its frame where the calibration put it (origin, then its x, y, z unit axes; mm): a seat's,
    /// a pivot's or a sphere's centre, a plane's origin on the plane with `z` its normal, the
    /// cube's centre along its edges.
    pub frame: [[f64; 3]; 4],
    /// The same where the starting model put it (the artifact placed from the data at the
    /// nominal geometry).
    pub frame_nominal: [[f64; 3]; 4],
    /// Its size (mm): a sphere's diameter, the cube's edge, a plane's half-width over its
    /// touches; 0 for a seat or a pivot.
    pub size: f64,
    /// Rows of the identification data referring to it.
    pub rows: usize,
}

/// A known distance between two seats (`--seat-distance`): a certified dimension the fit holds,
/// not a measured pose.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KnownDistance {
    /// The two seats' numbers.
    pub seats: (usize, usize),
    /// The stated distance (mm).
    pub known_mm: f64,
    /// Their centres' distance as the starting model placed them (mm).
    pub nominal_mm: f64,
    /// Their centres' distance after calibration (mm).
    pub fitted_mm: f64,
    /// `fitted_mm − known_mm`.
    pub error_mm: f64,
    /// Set aside by the robust fit as a blunder (then it did not hold the scale).
    pub set_aside: bool,
}

/// Whether `m` is a known distance between two seats ([`KNOWN_DISTANCE`]), a row of the fit that
/// is no pose: not counted, plotted or listed with the poses.
pub fn is_known_distance(m: &Measurement) -> bool {
    matches!(m.obs, Observation::Distance { pivot: KNOWN_DISTANCE, .. })
}

/// The artifact index of an instrument's row (its last input); `None` for a tracker row and a
/// known distance.
pub(super) fn artifact_index(m: &Measurement) -> Option<usize> {
    if is_known_distance(m) || m.obs.artifact_point().is_none() {
        return None;
    }
    m.q.last().filter(|k| **k >= 0.0 && k.fract() == 0.0).map(|k| *k as usize)
}

/// The machine's own tool frame at row `m` (module docs): for an instrument's row, the row
/// predicted without its artifact; any other row as it is.
pub fn machine_pose(model: &(impl Mechanism + ?Sized), m: &Measurement) -> Result<Pose, KinError> {
    if artifact_index(m).is_none() {
        return model.forward(&m.q);
    }
    let mut q = m.q.clone();
    if let Some(k) = q.last_mut() {
        *k = NO_POINT;
    }
    model.forward(&q)
}

fn arr(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// A frame as its origin and unit axes.
pub(super) fn axes(x: &Pose) -> [[f64; 3]; 4] {
    let r = x.rotation.to_rotation_matrix();
    let m = r.matrix();
    [
        arr(&x.translation.vector),
        arr(&m.column(0).into()),
        arr(&m.column(1).into()),
        arr(&m.column(2).into()),
    ]
}

/// The measured tool position of an observation and its position error against the model's
/// pose `t`, measured minus model (mm); for reflector points, their means.
pub fn position_and_error(obs: &Observation, t: &Pose) -> ([f64; 3], [f64; 3]) {
    let p = t.translation.vector;
    match obs {
        Observation::Pose(m) => (arr(&m.translation.vector), arr(&(m.translation.vector - p))),
        Observation::Position(m) => (arr(m), arr(&(m - p))),
        // Instrument rows: `t` is the tool point relative to the seat or pivot (its centre at
        // the origin); the error is the seat's centre minus the tool point, or the length's
        // error along the bar.
        Observation::Seat(_) => (arr(&p), arr(&-p)),
        Observation::Distance { length, .. } => {
            let u = p.try_normalize(1e-12).unwrap_or_else(Vector3::zeros);
            (arr(&p), arr(&(u * (length - p.norm()))))
        }
        // A touch: its error along the surface's normal at the tool point.
        Observation::Touch(t) => (arr(&p), arr(&(t.gradient(&p) * t.residual(&p)))),
        Observation::Points(pts) => {
            let n = pts.len().max(1) as f64;
            let mean = pts.iter().map(|(_, m)| *m).sum::<Vector3<f64>>() / n;
            let err = pts
                .iter()
                .map(|(r, m)| m - t.transform_point(&(*r).into()).coords)
                .sum::<Vector3<f64>>()
                / n;
            (arr(&mean), arr(&err))
        }
    }
}

/// Where a model puts an instrument's rows: per row its tool point in the base frame and the
/// error vector there (as [`position_and_error`] gives it, turned into the base
/// frame), and per artifact index its frame.
pub(super) struct Placed {
    /// Per row: the tool point (instrument rows) or the measured position (tracker rows).
    pub points: Vec<[f64; 3]>,
    /// Per row: measured minus modelled, in the base frame.
    pub errors: Vec<[f64; 3]>,
    /// Per artifact index: its frame (`None` for an index no row refers to).
    pub frames: Vec<Option<Pose>>,
}

/// The rows of `data` placed by `model`, `relative` its predictions of them (its `forward`).
pub(super) fn place(model: &(impl Mechanism + ?Sized), data: &[Measurement], relative: &[Pose]) -> Result<Placed, CalibError> {
    let n = data.iter().filter_map(artifact_index).max().map_or(0, |k| k + 1);
    // The machine's tool frame at each instrument row.
    let machine: Vec<Option<Pose>> = data
        .iter()
        .enumerate()
        .map(|(i, m)| match artifact_index(m) {
            Some(_) => machine_pose(model, m)
                .map(Some)
                .map_err(|source| CalibError::Kinematics { pose: i, source }),
            None => Ok(None),
        })
        .collect::<Result<_, _>>()?;
    let frames: Vec<Option<Pose>> = (0..n).map(|k| frame_of(k, data, &machine, relative)).collect();
    let (points, errors) = data
        .iter()
        .zip(relative)
        .zip(&machine)
        .map(|((m, rel), abs)| {
            let (p, e) = position_and_error(&m.obs, rel);
            match (abs, artifact_index(m).and_then(|k| frames.get(k).copied().flatten())) {
                (Some(t), Some(f)) => (arr(&t.translation.vector), arr(&(f.rotation * Vector3::from(e)))),
                _ => (p, e),
            }
        })
        .unzip();
    Ok(Placed { points, errors, frames })
}

/// Artifact `k`'s frame from its rows (module docs); `None` without rows.
fn frame_of(k: usize, data: &[Measurement], machine: &[Option<Pose>], relative: &[Pose]) -> Option<Pose> {
    let rows: Vec<usize> = (0..data.len())
        .filter(|&i| artifact_index(&data[i]) == Some(k) && machine[i].is_some())
        .collect();
    let first = *rows.first()?;
    if !matches!(data[first].obs, Observation::Distance { relative: true, .. }) {
        return machine[first].map(|t| t * relative[first].inverse());
    }
    // A pivot of readings: c − s·u_i = T_i − |R_i|·u_i over its rows.
    let mut a = DMatrix::zeros(3 * rows.len(), 4);
    let mut b = DVector::zeros(3 * rows.len());
    for (r, &i) in rows.iter().enumerate() {
        let (t, d) = (machine[i]?.translation.vector, relative[i].translation.vector);
        let u = d.try_normalize(1e-12)?;
        for j in 0..3 {
            a[(3 * r + j, j)] = 1.0;
            a[(3 * r + j, 3)] = -u[j];
            b[3 * r + j] = t[j] - d.norm() * u[j];
        }
    }
    let x = a.svd(true, true).solve(&b, 1e-12).ok()?;
    Some(Pose::translation(x[0], x[1], x[2]))
}

/// The artifacts of `data` (identification rows) as the view draws them, by artifact index:
/// frames under `calibrated` and `nominal` (their placements `after` and `before`), sizes from
/// the rows.
pub(super) fn artifact_views(data: &[Measurement], after: &Placed, before: &Placed) -> Vec<ArtifactView> {
    let identity = axes(&Pose::identity());
    (0..after.frames.len())
        .map(|k| {
            let rows: Vec<usize> = (0..data.len()).filter(|&i| artifact_index(&data[i]) == Some(k)).collect();
            let (kind, id) = rows
                .first()
                .and_then(|&i| data[i].obs.artifact_point())
                .unwrap_or((PointKind::Seat, k));
            let frame = after.frames[k];
            let size = match rows.first().map(|&i| &data[i].obs) {
                Some(Observation::Touch(Touch::Sphere { diameter, .. })) => *diameter,
                Some(Observation::Touch(Touch::Face { edge, .. })) => *edge,
                Some(Observation::Touch(Touch::Plane { .. })) => frame.map_or(0.0, |f| {
                    let local = |i: &usize| f.inverse_transform_point(&Vector3::from(after.points[*i]).into()).coords;
                    1.15 * rows.iter().map(|i| local(i).xy().amax()).fold(0.0, f64::max)
                }),
                _ => 0.0,
            };
            ArtifactView {
                name: format!("{} {id}", kind.name()),
                kind: kind.name().into(),
                frame: frame.map_or(identity, |f| axes(&f)),
                frame_nominal: before.frames.get(k).copied().flatten().map_or(identity, |f| axes(&f)),
                size,
                rows: rows.len(),
            }
        })
        .collect()
}

/// The known distances between seats among `data`'s rows ([`is_known_distance`], in order; the
/// `k`-th is between `seats[k]`), their centres' distances under `nominal` and `calibrated`, and
/// whether the fit set each aside (`in_fit`, per row of `data`).
pub fn known_distances(
    nominal: &(impl Mechanism + ?Sized),
    calibrated: &(impl Mechanism + ?Sized),
    data: &[Measurement],
    seats: &[(usize, usize)],
    in_fit: &[bool],
) -> Vec<KnownDistance> {
    data.iter()
        .enumerate()
        .filter(|(_, m)| is_known_distance(m))
        .zip(seats)
        .map(|((i, m), &seats)| {
            let known_mm = match m.obs {
                Observation::Distance { length, .. } => length,
                _ => f64::NAN,
            };
            let distance = |p: Result<Pose, KinError>| p.map_or(f64::NAN, |p| p.translation.vector.norm());
            let fitted_mm = distance(calibrated.forward(&m.q));
            KnownDistance {
                seats,
                known_mm,
                nominal_mm: distance(nominal.forward(&m.q)),
                fitted_mm,
                error_mm: fitted_mm - known_mm,
                set_aside: !in_fit.get(i).copied().unwrap_or(true),
            }
        })
        .collect()
}

impl CalibrationReport {
    /// The known distances between seats ([`known_distances`]), each set aside by the robust fit
    /// a warning: the scale it should hold rests on the others alone.
    pub fn set_known_distances(&mut self, distances: Vec<KnownDistance>) {
        for d in distances.iter().filter(|d| d.set_aside) {
            self.warn(format!(
                "the known distance between seats {} and {} ({} mm) was set aside as a blunder: the calibrated seats are {:.4} mm apart; check the stated distance and the seat numbers",
                d.seats.0, d.seats.1, d.known_mm, d.fitted_mm
            ));
        }
        self.known_distances = distances;
    }

    /// Express the calibrated parts of the view (machine, artifacts, tool points, error vectors
    /// after calibration) through `motion`: where `calibrate` places an instrument calibration
    /// that nothing else places (module docs). The view's world frame is then the machine's
    /// base frame as drawn, and the fit's base frame (the identity moved by `motion`) is not
    /// drawn apart: the skeleton shows where the calibrated machine stands in it.
    pub(super) fn place_as_drawn(&mut self, motion: &Pose) {
        let point = |p: &mut [f64; 3]| *p = arr(&motion.transform_point(&Vector3::from(*p).into()).coords);
        let frame = |f: &mut [[f64; 3]; 4]| {
            point(&mut f[0]);
            for a in &mut f[1..] {
                *a = arr(&(motion.rotation * Vector3::from(*a)));
            }
        };
        self.machine.skeleton.iter_mut().flatten().for_each(point);
        self.machine.base = None;
        self.machine.tool.iter_mut().for_each(frame);
        self.machine.artifacts.iter_mut().for_each(|a| frame(&mut a.frame));
        for s in std::iter::once(&mut self.identification).chain(self.validation.as_mut()) {
            s.measured.iter_mut().for_each(point);
            for e in &mut s.error_after {
                *e = arr(&(motion.rotation * Vector3::from(*e)));
            }
        }
    }
}

/// The rigid motion `calibrate` puts an instrument calibration through so that it stands where
/// the drawing stands (module docs): from the calibrated tool points of `s`'s rows onto the
/// starting model's. `None` when a row is a tracker's (the tracker placed the machine) or the
/// points fix no motion.
pub(super) fn drawn_placement(s: &SetErrors) -> Option<Pose> {
    if s.artifact.is_empty() || s.artifact.iter().any(Option::is_none) {
        return None;
    }
    let v = |p: &[[f64; 3]]| p.iter().map(|x| Vector3::from(*x)).collect::<Vec<_>>();
    crate::measure::register_points(&v(&s.measured), &v(&s.nominal_point))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::instrument::{Artifact, ArtifactPoint, Zero};
    use crate::model::framed::Framed;
    use nalgebra::UnitQuaternion;

    /// A seat, a pivot of readings (its relative frame moved by its zero) and a tilted plane on
    /// the IRB 120 with a tool point off the flange: each artifact's frame and each row's tool
    /// point come back exactly from the model's predictions.
    #[test]
    fn the_artifacts_and_tool_points_come_back_from_the_predictions() {
        let tool = Pose::translation(15.0, -10.0, 120.0);
        let inner = Framed::new(crate::model::irb120::nominal(), Pose::identity(), tool);
        let point = |kind, id, centre: [f64; 3], zero, rotation| ArtifactPoint {
            kind,
            id,
            centre: Vector3::from(centre),
            zero,
            rotation,
        };
        let tilt = UnitQuaternion::from_euler_angles(0.3, -0.2, 0.7);
        let model = Artifact {
            inner: inner.clone(),
            points: vec![
                point(PointKind::Seat, 0, [400.0, 20.0, 300.0], None, None),
                point(
                    PointKind::Pivot,
                    0,
                    [380.0, -50.0, 250.0],
                    Some(Zero {
                        value: 93.0,
                        reference: 3.5,
                    }),
                    None,
                ),
                point(PointKind::Plane, 0, [420.0, 0.0, 150.0], None, Some(tilt)),
            ],
            pairs: Vec::new(),
        };
        let obs = [
            Observation::Seat(0),
            Observation::Distance {
                pivot: 0,
                length: 100.0,
                relative: true,
            },
            Observation::Touch(Touch::Plane { plane: 0, probe: 1.5 }),
        ];
        let data: Vec<Measurement> = (0..12)
            .map(|i| {
                let x = i as f64;
                let mut q = vec![
                    0.1 * x.sin(),
                    0.3 + 0.05 * x,
                    0.2 - 0.04 * x,
                    0.3 * x.cos(),
                    1.0 + 0.02 * x,
                    0.1 * x,
                ];
                q.push((i % 3) as f64);
                Measurement {
                    q,
                    obs: obs[i % 3].clone(),
                    joints: Vec::new(),
                }
            })
            .collect();
        let relative = crate::validate::forward_all(&model, &data).unwrap();
        let placed = place(&model, &data, &relative).unwrap();
        for (k, p) in model.points.iter().enumerate() {
            let f = placed.frames[k].expect("placed");
            let (want, got) = (p.frame(), f);
            assert!(
                (want.translation.vector - got.translation.vector).norm() < 1e-9,
                "artifact {k}: {got:?}"
            );
            assert!(want.rotation.angle_to(&got.rotation) < 1e-12, "artifact {k}");
        }
        for (m, p) in data.iter().zip(&placed.points) {
            let t = inner.forward(&m.q[..6]).unwrap().translation.vector;
            assert!((t - Vector3::from(*p)).norm() < 1e-9);
        }
        assert!(data.iter().all(|m| artifact_index(m).is_some()));
        let known = Measurement {
            q: vec![0.0; 7],
            obs: Observation::Distance {
                pivot: KNOWN_DISTANCE,
                length: 50.0,
                relative: false,
            },
            joints: Vec::new(),
        };
        assert!(is_known_distance(&known) && artifact_index(&known).is_none());
    }
}
