//! The starting values of an instrument fit ([`start_points`]): first the tool point, found by
//! whichever instruments of the data can find it, then every artifact placed for that tool
//! point, whatever the kinds and whatever the row order.
//!
//! Who finds the tool point, in this order (the first the data hold):
//! 1. **Seats**: the linear pivot calibration `R_i·t − c_s = −p_i` over every seat row, exact on
//!    exact data and free of local minima.
//! 2. **Tracker rows**: the frames registered on them ([`crate::register`]) already put the tool
//!    point where the tracker saw it.
//! 3. **Distances** (ballbar, draw-wire): the offset and the pivots fitted together on the
//!    lengths, from several starts ([`super::offset`]).
//! 4. **Touches** (spheres, planes, a datum cube, any mix of them): the offset and the touched
//!    artifacts fitted together on the touches, from several starts ([`super::touch`]).
//!
//! With tracker rows, a tool point the seats found moves the tracker's frame with it: the frame
//! is registered again on the tracker rows for that tool point (a tracker's own registration
//! trades the tool point along the tool's axis against its frame where the tool turns little:
//! 8.3 mm RMS on the Stewart platform's tracker rows until it was).
//!
//! The other instruments' artifacts are then placed for that tool point: each pivot by a sphere
//! fit of the tool points to its lengths, each touched artifact from its touches
//! ([`super::touch::place`]). Spheres and planes placed from the flange instead of the probe
//! centre the seats or the ballbar found left the touches 27.5 mm RMS off on the IRB 120 and
//! 85 mm on the 6-RUS hexapod at the start (a probe 120 mm out), and the fit set many of them
//! aside as blunders.
use super::offset::{self, fit_offset_and_pivots};
use super::{has_tracker_rows, mixed, sphere_and_zero, sphere_centre, touch, Artifact, ArtifactPoint, PointKind, Zero};
use crate::error::CalibError;
use crate::measure::{Measurement, Observation};
use crate::model::framed::Framed;
use crate::model::Mechanism;
use crate::se3::Pose;
use nalgebra::{DMatrix, DVector, Translation3, Vector3};

/// Start the tool offset of `framed` and the artifacts of `points` from `indexed` measurements
/// ([`super::index_points`]) at the nominal geometry (module docs): the tool point from the
/// first instrument that finds it, then every artifact placed for it. Returns the framed
/// mechanism with its tool offset moved, and the points placed.
pub fn start_points<M: Mechanism + Clone + 'static>(
    mut framed: Framed<M>,
    mut points: Vec<ArtifactPoint>,
    pairs: Vec<(usize, usize)>,
    indexed: &[Measurement],
) -> Result<Artifact<Framed<M>>, CalibError> {
    let n_q = framed.inner.input_names().len();
    // The rows of the machine (not the known distances between seats, last).
    let indexed = &indexed[..indexed.len() - pairs.len()];
    // With tracker rows the frames were registered on them: the tool point is placed.
    let tracked = has_tracker_rows(indexed);
    // Every instrument row: its artifact point, its tool pose at the starting model (the tool
    // frame as given), its observation.
    let rows: Vec<Row> = indexed
        .iter()
        .enumerate()
        .filter(|(_, m)| !mixed::is_tracker_row(&m.q, n_q))
        .map(|(i, m)| {
            let pose = framed
                .forward(&m.q[..n_q])
                .map_err(|source| CalibError::Kinematics { pose: i, source })?;
            Ok((m.q[n_q] as usize, pose, &m.obs))
        })
        .collect::<Result<_, CalibError>>()?;
    let has = |kind: PointKind| points.iter().any(|p| p.kind == kind);
    let (seats, pivots) = (has(PointKind::Seat), has(PointKind::Pivot));
    let touched = points.iter().any(|p| p.kind > PointKind::Pivot);
    // The tool-point offset (tool frame, from the given tool point) and the kinds its finder
    // placed on the way.
    let (t, placed) = if seats {
        (seats_and_offset(&rows, &mut points)?, Placed::Seats)
    } else if tracked {
        (Vector3::zeros(), Placed::Nothing)
    } else if pivots {
        (pivots_and_offset(&rows, &mut points)?, Placed::Pivots)
    } else if touched {
        let flange = touch_rows(&rows, &framed.tool, &Vector3::zeros());
        (touch::offset_and_touched(&flange, &mut points)?, Placed::Touched)
    } else {
        (Vector3::zeros(), Placed::Nothing)
    };
    let mut rows = rows;
    if tracked && placed == Placed::Seats {
        // The tracker's frame registered anew for the tool point the seats found (the
        // registration's own tool point trades against its frame where the tool turns little),
        // the rows and the seats moved with it.
        let tracker: Vec<&Measurement> = indexed.iter().filter(|m| mixed::is_tracker_row(&m.q, n_q)).collect();
        let tool = framed.tool * Translation3::from(t);
        if let Some(x) = tracker_frame(&framed.inner, &tool, &tracker, n_q) {
            let moved = x * framed.measurement.inverse();
            framed.measurement = x;
            for row in rows.iter_mut() {
                row.1 = moved * row.1;
            }
            for p in points.iter_mut().filter(|p| p.kind == PointKind::Seat) {
                p.centre = moved.transform_point(&p.centre.into()).coords;
            }
        }
    }
    if pivots && placed != Placed::Pivots {
        place_pivots(&distance_rows(&rows), &t, &mut points)?;
    }
    if touched && placed != Placed::Touched {
        touch::place(&touch_rows(&rows, &framed.tool, &t), &mut points)?;
    }
    framed.tool *= Translation3::from(t);
    Ok(Artifact {
        inner: framed,
        points,
        pairs,
    })
}

/// The artifacts of `points` placed for the mechanism `inner` as it is (its tool point not
/// moved): each seat at the mean of its rows' tool points, each pivot by a sphere fit of them to
/// its lengths (and its zero where the readings are relative), each touched artifact from its
/// touches ([`touch::place`], `flanges` the flange's position at each row, which side of a
/// surface the probe came from). What a check of an instrument's rows against a calibration
/// starts from ([`crate::drift::check`]): the machine is the calibration's, the artifact is
/// wherever it now stands. Tracker rows are refused (`InvalidOption`).
pub fn place_points<M: Mechanism + Clone + 'static>(
    inner: M,
    mut points: Vec<ArtifactPoint>,
    indexed: &[Measurement],
    flanges: &[Vector3<f64>],
) -> Result<Artifact<M>, CalibError> {
    let n_q = inner.input_names().len();
    if has_tracker_rows(indexed) {
        return Err(CalibError::InvalidOption(
            "tracker rows and instrument rows together: check each kind on its own".into(),
        ));
    }
    let rows: Vec<Row> = indexed
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let pose = inner
                .forward(&m.q[..n_q])
                .map_err(|source| CalibError::Kinematics { pose: i, source })?;
            Ok((m.q[n_q] as usize, pose, &m.obs))
        })
        .collect::<Result<_, CalibError>>()?;
    for (k, point) in points.iter_mut().enumerate() {
        if point.kind != PointKind::Seat {
            continue;
        }
        let at: Vec<Vector3<f64>> = rows.iter().filter(|r| r.0 == k).map(|r| r.1.translation.vector).collect();
        point.centre = at.iter().sum::<Vector3<f64>>() / at.len().max(1) as f64;
    }
    place_pivots(&distance_rows(&rows), &Vector3::zeros(), &mut points)?;
    let touched: Vec<touch::TouchRow> = rows
        .iter()
        .zip(flanges)
        .filter(|((_, _, obs), _)| matches!(obs, Observation::Touch(_)))
        .map(|(&(k, pose, obs), flange)| (k, pose, *flange, obs))
        .collect();
    touch::place(&touched, &mut points)?;
    Ok(Artifact {
        inner,
        points,
        pairs: Vec::new(),
    })
}

/// The measurement frame that best takes the points `tool` of mechanism `inner` at the
/// `tracker` rows' inputs onto the positions those rows measured (a pose's origin); `None` when
/// they do not fix one (fewer than three points, or on a line).
fn tracker_frame<M: Mechanism>(inner: &M, tool: &Pose, tracker: &[&Measurement], n_q: usize) -> Option<Pose> {
    let (mut model, mut measured) = (Vec::new(), Vec::new());
    for m in tracker {
        let p = match &m.obs {
            Observation::Position(p) => *p,
            Observation::Pose(t) => t.translation.vector,
            _ => continue,
        };
        model.push((inner.forward(&m.q[..n_q]).ok()? * tool).translation.vector);
        measured.push(p);
    }
    crate::measure::register_points(&model, &measured)
}

/// An instrument row at the starting model: its artifact point, its tool pose (the tool frame
/// as given, before the offset is found), its observation.
type Row<'a> = (usize, Pose, &'a Observation);

/// Which artifacts the tool point's finder placed with it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Placed {
    Nothing,
    Seats,
    Pivots,
    Touched,
}

/// The touch rows of `rows` as [`touch::place`] takes them: the tool pose moved by offset `t`
/// (tool frame), the flange's position (the pose without the tool frame `tool` it was computed
/// with).
fn touch_rows<'a>(rows: &[Row<'a>], tool: &Pose, t: &Vector3<f64>) -> Vec<touch::TouchRow<'a>> {
    let inverse = tool.inverse();
    rows.iter()
        .filter(|(_, _, obs)| matches!(obs, Observation::Touch(_)))
        .map(|&(k, pose, obs)| (k, pose * Translation3::from(*t), (pose * inverse).translation.vector, obs))
        .collect()
}

/// The distance rows of `rows`: point, tool pose, length (as the fit carries it).
fn distance_rows(rows: &[Row]) -> Vec<(usize, Pose, f64)> {
    rows.iter()
        .filter_map(|&(k, pose, obs)| match obs {
            Observation::Distance { length, .. } => Some((k, pose, *length)),
            _ => None,
        })
        .collect()
}

/// The seats and the tool-point offset `t` (tool frame) together, by linear least squares over
/// every seat row: `R_i·t − c_s = −p_i`. Places the seats, returns `t`.
fn seats_and_offset(rows: &[Row], points: &mut [ArtifactPoint]) -> Result<Vector3<f64>, CalibError> {
    let seats: Vec<usize> = (0..points.len()).filter(|&k| points[k].kind == PointKind::Seat).collect();
    // Unknowns: the tool-point offset t (tool frame), then each seat's centre.
    let col = |k: usize| 3 + 3 * seats.iter().position(|&s| s == k).expect("a seat");
    let on_seats: Vec<&Row> = rows.iter().filter(|(k, ..)| points[*k].kind == PointKind::Seat).collect();
    let mut a = DMatrix::zeros(3 * on_seats.len(), 3 + 3 * seats.len());
    let mut b = DVector::zeros(3 * on_seats.len());
    for (r, (k, pose, _)) in on_seats.iter().enumerate() {
        let rot = pose.rotation.to_rotation_matrix();
        a.view_mut((3 * r, 0), (3, 3)).copy_from(rot.matrix());
        for i in 0..3 {
            a[(3 * r + i, col(*k) + i)] = -1.0;
            b[3 * r + i] = -pose.translation.vector[i];
        }
    }
    let x = a
        .svd(true, true)
        .solve(&b, 1e-10)
        .map_err(|e| CalibError::Numerical(format!("placing the seats: {e}")))?;
    for &k in &seats {
        let c = col(k);
        points[k].centre = Vector3::new(x[c], x[c + 1], x[c + 2]);
    }
    Ok(Vector3::new(x[0], x[1], x[2]))
}

/// The tool-point offset and the pivots fitted together on the lengths (Levenberg–Marquardt
/// over the offset and every pivot's centre, [`offset_and_pivots`]). That fit has local minima
/// (a head that only tilts, started at its platform's centre, stops 100 mm off), so it starts
/// from the flange origin and from one bar length along each axis of the tool frame either
/// way, and keeps a clearly lower cost. Places the pivots, returns the offset.
fn pivots_and_offset(rows: &[Row], points: &mut Vec<ArtifactPoint>) -> Result<Vector3<f64>, CalibError> {
    let rows = distance_rows(rows);
    place_pivots(&rows, &Vector3::zeros(), points)?;
    // A reading's row: its length as placed for the flange origin.
    let length = |(k, _, l): &(usize, Pose, f64)| points[*k].zero.map_or(*l, |z| l - z.reference + z.value);
    let bar = rows.iter().map(length).sum::<f64>() / rows.len().max(1) as f64;
    let mut best: Option<(Vector3<f64>, f64, Vec<ArtifactPoint>)> = None;
    for t0 in std::iter::once(Vector3::zeros()).chain(offset::along_each_axis(bar)) {
        let mut candidate = points.clone();
        if let Some((t, cost)) = offset_and_pivots(&rows, t0, &mut candidate) {
            // Another start replaces the first (the flange origin) only at a clearly lower
            // cost: a machine that never turns its tool (a delta) cannot tell the offset from
            // the pivots, and keeps the flange origin.
            if best.as_ref().is_none_or(|b| cost < 0.5 * b.1) {
                best = Some((t, cost, candidate));
            }
        }
    }
    Ok(match best {
        Some((t, _, placed)) => {
            *points = placed;
            t
        }
        None => Vector3::zeros(),
    })
}

/// Rounds of placing the pivots for the current tool-point offset and fitting both again
/// ([`offset_and_pivots`]).
const OFFSET_ROUNDS: usize = 5;

/// Each pivot of `points` placed by a sphere fit of the tool points at offset `t` to its rows'
/// lengths (rows: point index, tool pose, length).
fn place_pivots(rows: &[(usize, Pose, f64)], t: &Vector3<f64>, points: &mut [ArtifactPoint]) -> Result<(), CalibError> {
    for (k, point) in points.iter_mut().enumerate() {
        if point.kind != PointKind::Pivot {
            continue;
        }
        let sphere: Vec<(Vector3<f64>, f64)> = rows
            .iter()
            .filter(|(j, ..)| *j == k)
            .map(|(_, pose, l)| (pose.translation.vector + pose.rotation * t, *l))
            .collect();
        let placed = match point.zero {
            // The rows carry reading + reference: e = zero − reference.
            Some(z) => sphere_and_zero(&sphere).map(|(c, e)| {
                (
                    c,
                    Some(Zero {
                        value: z.reference + e,
                        ..z
                    }),
                )
            }),
            None => sphere_centre(&sphere).map(|c| (c, None)),
        };
        (point.centre, point.zero) = placed.ok_or_else(|| {
            CalibError::InvalidOption(format!(
                "pivot {}: its rows do not place it (the tool points lie in a plane or on a line); measure from more spread poses",
                point.id
            ))
        })?;
    }
    Ok(())
}

/// The tool-point offset and the pivots from offset `t0`: the pivots placed for the offset,
/// then both fitted together; where that stalls with pivots placed for an offset far from the
/// one it reached, placing them again and fitting again moves on (rounds while the cost falls).
/// The offset and the cost `Σ r²` reached, the centres moved; `None` when no pivot could be placed.
fn offset_and_pivots(rows: &[(usize, Pose, f64)], t0: Vector3<f64>, points: &mut [ArtifactPoint]) -> Option<(Vector3<f64>, f64)> {
    place_pivots(rows, &t0, points).ok()?;
    let (mut t, mut cost, mut best) = (t0, f64::INFINITY, None);
    for _ in 0..OFFSET_ROUNDS {
        let (t_next, c) = fit_offset_and_pivots(rows, t, points);
        if c.is_nan() || c >= cost * (1.0 - 1e-9) {
            break;
        }
        (cost, t) = (c, t_next);
        best = Some((t, c, points.to_vec()));
        if place_pivots(rows, &t, points).is_err() {
            break;
        }
    }
    let (t, c, placed) = best?;
    points.clone_from_slice(&placed);
    Some((t, c))
}
