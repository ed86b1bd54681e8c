//! A calibration judged on instrument data it was not fitted on (held-out placements of the
//! artifact), in the instrument's own terms: each seat's spread of the model's tool points about
//! their mean (one point if the model were exact), the error of the known distances between
//! seats, and for a ballbar each pivot's length residuals once the pivot is placed; a touch
//! probe's spheres like pivots, each plane by its flatness, a datum cube by the touches'
//! distances from its faces once the cube is placed on them.
use super::{rms_and_max, sphere_and_zero, sphere_centre, spread, ArtifactPoint, PointKind, SeatDistance};
use crate::error::CalibError;
use crate::measure::{Measurement, Observation};
use crate::model::Mechanism;
use nalgebra::Vector3;
use serde::Serialize;
use std::collections::BTreeMap;

/// One seat's tool points under a model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SeatSpread {
    /// Seat number.
    pub seat: usize,
    /// Rows in the seat.
    pub rows: usize,
    /// The mean tool point (mm, the model's base frame).
    pub centre: [f64; 3],
    /// 3-D RMS distance of the tool points from their mean (mm).
    pub rms_mm: f64,
    /// Largest distance from the mean (mm).
    pub max_mm: f64,
}

/// One pivot placed by the model's tool points and the measured lengths.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PivotFit {
    /// A ballbar's pivot, or a reference sphere touched by a probe (a known distance from its
    /// centre, `D/2 + r`).
    pub kind: PointKind,
    /// Pivot (or sphere) number.
    pub pivot: usize,
    /// Rows.
    pub rows: usize,
    /// RMS of measured − modelled length once the pivot is placed (mm).
    pub rms_mm: f64,
    /// Largest |measured − modelled length| (mm).
    pub max_mm: f64,
    /// For readings relative to an unknown zero (`reading_mm`): the zero placed with the pivot
    /// (mm; length = reading + zero).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub zero_mm: Option<f64>,
}

/// One unknown plane's touches under a model: the probe-ball centres' distances from the plane
/// that fits them best (0 if the model were exact: the centres lie on a plane `r` above the
/// touched one).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlaneFlatness {
    /// Plane number.
    pub plane: usize,
    /// Rows (touches).
    pub rows: usize,
    /// RMS distance from the best plane (mm).
    pub rms_mm: f64,
    /// Largest distance from the best plane (mm).
    pub max_mm: f64,
}

/// A datum cube's touches under a model: the cube (its edge known) placed on them by least
/// squares (6 unknowns, started as identification starts it, [`super::touch`]), the probe-ball
/// centres' distances from their faces (less `r`; 0 if the model were exact).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CubeFit {
    /// Cube number.
    pub cube: usize,
    /// Rows (touches, every face).
    pub rows: usize,
    /// RMS of the touches' residuals `r + e/2 − s·p_a` once the cube is placed (mm).
    pub rms_mm: f64,
    /// Largest |residual| (mm).
    pub max_mm: f64,
}

/// What [`held_out`] found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeldOut {
    /// Every seat, by number.
    pub seats: Vec<SeatSpread>,
    /// Each known distance between seats: `(a, b, known, modelled − known)` (mm).
    pub distances: Vec<(usize, usize, f64, f64)>,
    /// Every pivot (and reference sphere), by number.
    pub pivots: Vec<PivotFit>,
    /// Every unknown plane touched, by number.
    pub planes: Vec<PlaneFlatness>,
    /// Every datum cube touched, by number.
    pub cubes: Vec<CubeFit>,
}

impl HeldOut {
    /// 3-D RMS spread over every seat row (mm), `None` without seats.
    pub fn seat_rms_mm(&self) -> Option<f64> {
        self.kind_rms_mm(PointKind::Seat).map(|(_, _, rms)| rms)
    }

    /// Each artifact judged: its kind, rows and RMS residual (mm).
    fn groups(&self) -> impl Iterator<Item = (PointKind, usize, f64)> + '_ {
        let seats = self.seats.iter().map(|s| (PointKind::Seat, s.rows, s.rms_mm));
        let pivots = self.pivots.iter().map(|p| (p.kind, p.rows, p.rms_mm));
        let planes = self.planes.iter().map(|p| (PointKind::Plane, p.rows, p.rms_mm));
        let cubes = self.cubes.iter().map(|c| (PointKind::Cube, c.rows, c.rms_mm));
        seats.chain(pivots).chain(planes).chain(cubes)
    }

    /// Rows judged, every artifact.
    pub fn rows(&self) -> usize {
        self.groups().map(|g| g.1).sum()
    }

    /// RMS over every row of its residual (mm): a seat row's distance from its seat's mean, a
    /// pivot's or sphere's length residual, a plane touch's distance from its best plane, a cube
    /// touch's from its placed face. `None` without rows.
    pub fn rms_mm(&self) -> Option<f64> {
        pooled(self.groups())
    }

    /// Artifacts of `kind`, their rows and the RMS of those rows' residuals (mm, as
    /// [`HeldOut::rms_mm`]); `None` when there is none of that kind.
    pub fn kind_rms_mm(&self, kind: PointKind) -> Option<(usize, usize, f64)> {
        let of: Vec<_> = self.groups().filter(|g| g.0 == kind).collect();
        let rows = of.iter().map(|g| g.1).sum();
        pooled(of.iter().copied()).map(|rms| (of.len(), rows, rms))
    }

    /// RMS of the known distances' errors (mm), `None` without known distances.
    pub fn distance_error_rms_mm(&self) -> Option<f64> {
        let n = self.distances.len();
        (n > 0).then(|| (self.distances.iter().map(|d| d.3 * d.3).sum::<f64>() / n as f64).sqrt())
    }
}

/// The RMS over every row of groups given as (kind, rows, RMS).
fn pooled(groups: impl Iterator<Item = (PointKind, usize, f64)>) -> Option<f64> {
    let (rows, sum) = groups.fold((0usize, 0.0), |(n, s), (_, r, rms)| (n + r, s + rms * rms * r as f64));
    (rows > 0).then(|| (sum / rows as f64).sqrt())
}

/// `model`'s tool points at `measurements` (seat or distance rows, as read) judged as the module
/// docs say; `distances` are the known distances between seats.
pub fn held_out(model: &dyn Mechanism, measurements: &[Measurement], distances: &[SeatDistance]) -> Result<HeldOut, CalibError> {
    // Per seat or pivot: the model's tool points and the measured lengths.
    type Rows = Vec<(Vector3<f64>, f64)>;
    super::touch::check(measurements)?;
    // The datum cubes' rows: the model's tool pose, the flange's position, the touch.
    let mut cubes: BTreeMap<usize, Vec<super::touch::TouchRow>> = BTreeMap::new();
    let mut groups: BTreeMap<(PointKind, usize), Rows> = BTreeMap::new();
    // Pivots whose rows are readings relative to an unknown zero: placed with their zero.
    let mut relative = std::collections::BTreeSet::new();
    for (i, m) in measurements.iter().enumerate() {
        let Some(key) = m.obs.artifact_point() else {
            return Err(CalibError::InvalidOption(format!(
                "pose {i}: not a seat or distance row; judge tracker data with the tracker's errors (validate without instrument rows)"
            )));
        };
        let p = model.forward(&m.q).map_err(|source| CalibError::Kinematics { pose: i, source })?;
        if key.0 == PointKind::Cube {
            // The flange (toward which a face without its opposite is turned): the tool pose
            // without the model's tool frame.
            let flange = model.frames().map_or(p, |(_, tool)| p * tool.inverse()).translation.vector;
            cubes.entry(key.1).or_default().push((0, p, flange, &m.obs));
        }
        let p = p.translation.vector;
        let length = match m.obs {
            Observation::Distance { length, relative: r, .. } => {
                if r {
                    relative.insert(key.1);
                }
                length
            }
            Observation::Touch(t) => t.measured(),
            _ => 0.0,
        };
        groups.entry(key).or_default().push((p, length));
    }
    let mut out = HeldOut {
        seats: Vec::new(),
        distances: Vec::new(),
        pivots: Vec::new(),
        planes: Vec::new(),
        cubes: Vec::new(),
    };
    for (&(kind, id), rows) in &groups {
        match kind {
            PointKind::Seat => {
                let points: Vec<Vector3<f64>> = rows.iter().map(|r| r.0).collect();
                let (centre, rms_mm, max_mm) = spread(&points);
                out.seats.push(SeatSpread {
                    seat: id,
                    rows: rows.len(),
                    centre: [centre.x, centre.y, centre.z],
                    rms_mm,
                    max_mm,
                });
            }
            PointKind::Plane => {
                let points: Vec<Vector3<f64>> = rows.iter().map(|r| r.0).collect();
                let (mean, n) = super::touch::fit_plane(&points).ok_or_else(|| {
                    CalibError::InvalidOption(format!("plane {id}: its touches lie on a line; they do not place a plane"))
                })?;
                let d: Vec<f64> = points.iter().map(|p| (p - mean).dot(&n)).collect();
                let (rms_mm, max_mm) = rms_and_max(&d);
                out.planes.push(PlaneFlatness {
                    plane: id,
                    rows: rows.len(),
                    rms_mm,
                    max_mm,
                });
            }
            PointKind::Cube => {
                let mut cube = [ArtifactPoint {
                    kind,
                    id,
                    centre: Vector3::zeros(),
                    zero: None,
                    rotation: None,
                }];
                let e = super::touch::placed_residuals(&cubes[&id], &mut cube)?;
                let (rms_mm, max_mm) = rms_and_max(e.as_slice());
                out.cubes.push(CubeFit {
                    cube: id,
                    rows: rows.len(),
                    rms_mm,
                    max_mm,
                });
            }
            PointKind::Pivot | PointKind::Sphere => {
                let placed = if relative.contains(&id) {
                    sphere_and_zero(rows)
                } else {
                    sphere_centre(rows).map(|c| (c, 0.0))
                };
                let (c, zero) =
                    placed.ok_or_else(|| CalibError::InvalidOption(format!("{} {id}: its rows do not place it", kind.name())))?;
                let e: Vec<f64> = rows.iter().map(|(p, l)| l + zero - (p - c).norm()).collect();
                let (rms_mm, max_mm) = rms_and_max(&e);
                out.pivots.push(PivotFit {
                    kind,
                    pivot: id,
                    rows: rows.len(),
                    rms_mm,
                    max_mm,
                    zero_mm: relative.contains(&id).then_some(zero),
                });
            }
        }
    }
    for d in distances {
        let centre = |id: usize| {
            out.seats
                .iter()
                .find(|s| s.seat == id)
                .map(|s| Vector3::from(s.centre))
                .ok_or_else(|| CalibError::InvalidOption(format!("seat distance {}:{}:{}: the data hold no seat {id}", d.a, d.b, d.length)))
        };
        let modelled = (centre(d.a)? - centre(d.b)?).norm();
        out.distances.push((d.a, d.b, d.length, modelled - d.length));
    }
    Ok(out)
}
