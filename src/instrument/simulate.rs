//! Instrument measurements of a virtual prototype: configurations that put the true tool point
//! in a seat, or on a sphere of known radius about a pivot, from many orientations.
use crate::error::{CalibError, KinError};
use crate::instrument::SeatDistance;
use crate::measure::{Measurement, Observation};
use crate::model::kind::InputSpec;
use crate::model::Mechanism;
use crate::se3::{self, Pose};
use nalgebra::Vector3;
use rand::{Rng, RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};

mod touch;
pub(crate) use touch::seeded_noise;
pub use touch::{random_touches, touch_planned, touch_rows, TouchSpec, Touched};

/// How instrument rows are drawn ([`seat_rows`], [`distance_rows`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Placement {
    /// Rows per seat or pivot.
    pub per_point: usize,
    /// The configuration the orientations are drawn about (and the inverse kinematics starts
    /// from): the tool's orientation there, turned by up to `max_tilt` about a random axis.
    pub reference: Vec<f64>,
    /// Largest tilt (rad) of the tool from the reference orientation.
    pub max_tilt: f64,
    /// Noise (mm, per axis for a seat: where the ball settles; along the bar for a distance).
    pub noise_mm: f64,
    /// Seed of every random draw.
    pub seed: u64,
    /// The model's inputs (e.g. [`crate::io::model_file::ModelFile::inputs`]): a configuration
    /// outside their limits is brought within them by whole turns of its angles, or drawn again.
    /// Empty: no limits.
    pub inputs: Vec<InputSpec>,
}

/// `q` within the limits of `inputs` (angles moved by whole turns where that brings them in),
/// or `None`.
fn within_limits(mut q: Vec<f64>, inputs: &[InputSpec]) -> Option<Vec<f64>> {
    for (v, i) in q.iter_mut().zip(inputs) {
        let Some((lo, hi)) = i.limits else { continue };
        if i.unit == crate::params::Unit::Angle && !(lo..=hi).contains(v) {
            let turn = std::f64::consts::TAU;
            *v -= ((*v - lo) / turn).floor() * turn;
        }
        if !(lo..=hi).contains(v) {
            return None;
        }
    }
    Some(q)
}

/// Attempts per requested row before [`seat_rows`] or [`distance_rows`] gives up.
const ATTEMPTS: usize = 50;

/// Configurations of `truth` (the real machine with its tool, e.g. a [`crate::model::framed::Framed`]
/// prototype) that put its tool point in each seat of `seats` (mm, base frame), orientations
/// drawn as `how` says; one [`Observation::Seat`] row each, the seat's number its index.
pub fn seat_rows(truth: &dyn Mechanism, seats: &[Vector3<f64>], how: &Placement) -> Result<Vec<Measurement>, CalibError> {
    draw_rows(truth, seats, how, "seat", |_, _| None)
}

/// The range a telescoping ballbar measures over (mm, ±, about its certified length) when none
/// is given: a little inside the ±1 mm of common ballbars, so that every commanded length is
/// within the sensor's travel.
pub const DEFAULT_BALLBAR_RANGE_MM: f64 = 0.8;

/// Configurations of `truth` whose tool point lies at a length from each pivot of `pivots`
/// drawn uniformly in `length ± range` (mm; a telescoping ballbar's travel about its certified
/// length, 0 for a fixed bar), in directions within 60° of the pivot's direction toward the
/// reference tool point; one [`Observation::Distance`] row each with the true length plus noise
/// along the bar.
///
/// With one fixed length every row of a pivot reads the same, and a machine whose tool point
/// stands still over those rows fits them exactly ([`crate::instrument::collapsed_pivots`]);
/// lengths that vary rule such a machine out.
///
/// A machine that does not command the whole tool position (e.g. a head commanding its height
/// and axis) is then moved along its inputs until the tool point is at the drawn length, wherever
/// that puts it.
pub fn distance_rows(
    truth: &dyn Mechanism,
    pivots: &[Vector3<f64>],
    length: f64,
    range: f64,
    how: &Placement,
) -> Result<Vec<Measurement>, CalibError> {
    if length.is_nan() || length <= 0.0 {
        return Err(CalibError::InvalidOption(format!("ballbar length {length} mm: must be positive")));
    }
    if !(range.is_finite() && range >= 0.0 && range < length) {
        return Err(CalibError::InvalidOption(format!(
            "ballbar range ±{range} mm: must be at least 0 and below the length ({length} mm)"
        )));
    }
    let home = truth
        .forward(&how.reference)
        .map_err(|source| CalibError::Kinematics { pose: 0, source })?;
    draw_rows(truth, pivots, how, "pivot", |pivot, rng| {
        let axis = (home.translation.vector - pivot).try_normalize(1e-9).unwrap_or_else(Vector3::z);
        let l = if range > 0.0 {
            rng.random_range(length - range..=length + range)
        } else {
            length
        };
        Some(pivot + se3::so3_exp(&random_tilt(rng, 60f64.to_radians())) * axis * l)
    })
}

/// A rotation vector of random axis and angle up to `max`.
fn random_tilt<R: Rng>(rng: &mut R, max: f64) -> Vector3<f64> {
    let normal = Normal::new(0.0, 1.0).expect("unit normal");
    let axis = Vector3::new(normal.sample(rng), normal.sample(rng), normal.sample(rng))
        .try_normalize(1e-12)
        .unwrap_or_else(Vector3::z);
    axis * rng.random_range(0.0..=max)
}

/// The rows for every point: the target point (`target`, or the point itself for a seat), the
/// reference orientation tilted at random, the inverse kinematics of `truth`.
fn draw_rows(
    truth: &dyn Mechanism,
    points: &[Vector3<f64>],
    how: &Placement,
    name: &str,
    mut target: impl FnMut(&Vector3<f64>, &mut rand_chacha::ChaCha8Rng) -> Option<Vector3<f64>>,
) -> Result<Vec<Measurement>, CalibError> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(how.seed);
    let noise = Normal::new(0.0, how.noise_mm.max(0.0)).map_err(|e| CalibError::InvalidOption(e.to_string()))?;
    let home = truth
        .forward(&how.reference)
        .map_err(|source| CalibError::Kinematics { pose: 0, source })?;
    let mut out = Vec::new();
    for (k, point) in points.iter().enumerate() {
        let mut found = 0;
        for _ in 0..ATTEMPTS * how.per_point {
            if found == how.per_point {
                break;
            }
            let aim = target(point, &mut rng);
            let settle = Vector3::new(noise.sample(&mut rng), noise.sample(&mut rng), noise.sample(&mut rng));
            let place = aim.unwrap_or(*point) + if aim.is_none() { settle } else { Vector3::zeros() };
            let rotation = se3::so3_exp(&random_tilt(&mut rng, how.max_tilt)) * home.rotation;
            let goal = Pose::from_parts(place.into(), rotation);
            // A machine with fewer inputs than its task commands (a 5-axis serial arm) reaches a
            // point, not an arbitrary orientation there: it is moved onto the point from the
            // reference turned at random, the orientation being what it reaches.
            let solved = match truth.inverse(&goal, Some(&how.reference)) {
                Err(_) if aim.is_none() && truth.input_names().len() < truth.task().dof() => {
                    let start: Vec<f64> = how
                        .reference
                        .iter()
                        .map(|v| v + rng.random_range(-how.max_tilt..=how.max_tilt))
                        .collect();
                    onto_point(truth, &start, &place)
                }
                other => other.ok(),
            };
            let Some(q) = solved
                .and_then(|q| within_limits(q, &how.inputs))
                .and_then(|q| approached(truth, &goal, q, out.last().map(|m: &Measurement| m.q.as_slice()), &how.inputs))
            else {
                continue;
            };
            let Ok(mut reached) = truth.forward(&q) else { continue };
            let mut q = q;
            if (reached.translation.vector - place).norm() > 1e-9 {
                // A machine that does not command the whole tool position (a head commanding its
                // height and axis) puts the point elsewhere. A seat needs the point itself; a
                // distance row only its length, reached by moving the inputs.
                let Some(at) = aim.and_then(|aim| onto_length(truth, &q, point, (aim - point).norm(), &how.inputs)) else {
                    continue;
                };
                (q, reached) = at;
            }
            let obs = match aim {
                None => Observation::Seat(k),
                Some(_) => Observation::Distance {
                    pivot: k,
                    length: (reached.translation.vector - point).norm() + settle.x,
                    relative: false,
                },
            };
            out.push(Measurement {
                q,
                obs,
                joints: Vec::new(),
            });
            found += 1;
        }
        if found < how.per_point {
            return Err(CalibError::Kinematics {
                pose: out.len(),
                source: KinError::Unreachable(format!(
                    "{name} {k} at ({:.1}, {:.1}, {:.1}) mm: {found} of {} configurations reached it (move it into the workspace or tilt less)",
                    point.x, point.y, point.z, how.per_point
                )),
            });
        }
    }
    Ok(out)
}

/// `q` with its approach-direction inputs ([`InputSpec::approach_of`]) set as the machine
/// arrives from `previous` (the row measured before; none: from below), solved again with those
/// directions (lost motion moves the tool a little), or `None` when the directions the new
/// solution implies differ from those it was solved with. Without such inputs, `q` itself.
fn approached(truth: &dyn Mechanism, goal: &Pose, mut q: Vec<f64>, previous: Option<&[f64]>, inputs: &[InputSpec]) -> Option<Vec<f64>> {
    let directions = |q: &[f64]| -> Vec<(usize, f64)> {
        inputs
            .iter()
            .enumerate()
            .filter_map(|(k, i)| {
                let j = i.approach_of?;
                let from = previous.and_then(|p| p.get(j).copied()).unwrap_or(f64::NEG_INFINITY);
                Some((k, if q[j] >= from { 1.0 } else { -1.0 }))
            })
            .collect()
    };
    let wanted = directions(&q);
    if wanted.is_empty() {
        return Some(q);
    }
    for &(k, d) in &wanted {
        q[k] = d;
    }
    let q = within_limits(truth.inverse(goal, Some(&q)).ok()?, inputs)?;
    (directions(&q) == wanted && wanted.iter().all(|&(k, d)| q[k] == d)).then_some(q)
}

/// Inputs near `q` where `residual` (of the tool pose) vanishes: Gauss–Newton over the inputs
/// (those `fixed` marks kept as they are, e.g. approach directions), minimum-norm steps
/// (singular values below 1e-9 dropped), the Jacobian by central differences; at most
/// `iterations` steps, done when `converged` holds. `None` when the forward kinematics fails on
/// the way or it does not get there.
fn onto(
    truth: &dyn Mechanism,
    q: &[f64],
    fixed: &[bool],
    iterations: usize,
    residual: impl Fn(&Pose) -> nalgebra::DVector<f64>,
    converged: impl Fn(&nalgebra::DVector<f64>) -> bool,
) -> Option<(Vec<f64>, Pose)> {
    let at = |q: &[f64]| truth.forward(q).ok().map(|p| (residual(&p), p));
    let mut q = q.to_vec();
    for _ in 0..iterations {
        let (r, pose) = at(&q)?;
        if converged(&r) {
            return Some((q, pose));
        }
        let h = 1e-6;
        let mut j = nalgebra::DMatrix::zeros(r.len(), q.len());
        for k in (0..q.len()).filter(|&k| !fixed.get(k).copied().unwrap_or(false)) {
            let (mut up, mut down) = (q.clone(), q.clone());
            up[k] += h;
            down[k] -= h;
            j.set_column(k, &((at(&up)?.0 - at(&down)?.0) / (2.0 * h)));
        }
        let step = j.svd(true, true).solve(&(-r), 1e-9).ok()?;
        for (v, d) in q.iter_mut().zip(step.iter()) {
            *v += d;
        }
    }
    None
}

/// Inputs near `q` whose tool point is at `point` ([`onto`]).
fn onto_point(truth: &dyn Mechanism, q: &[f64], point: &Vector3<f64>) -> Option<Vec<f64>> {
    let residual = |p: &Pose| nalgebra::DVector::from_column_slice((p.translation.vector - point).as_slice());
    onto(truth, q, &[], 50, residual, |r| r.norm() < 1e-11).map(|(q, _)| q)
}

/// Inputs near `q` whose tool point lies at `length` from `pivot` ([`onto`]), within the limits
/// of `inputs`, and the pose there.
fn onto_length(truth: &dyn Mechanism, q: &[f64], pivot: &Vector3<f64>, length: f64, inputs: &[InputSpec]) -> Option<(Vec<f64>, Pose)> {
    let residual = |p: &Pose| nalgebra::DVector::from_element(1, (p.translation.vector - pivot).norm() - length);
    let (q, pose) = onto(truth, q, &[], 30, residual, |r| r[0].abs() < 1e-11 * length)?;
    within_limits(q, inputs).map(|q| (q, pose))
}

/// Points (mm) from text `X,Y,Z;X,Y,Z;…` (e.g. `400,0,300;400,100,300`), for a command line.
/// The error names the first malformed point.
pub fn parse_points(text: &str) -> Result<Vec<Vector3<f64>>, String> {
    let mut out = Vec::new();
    for (k, part) in text.split(';').map(str::trim).enumerate() {
        if part.is_empty() && k > 0 {
            continue;
        }
        let values: Vec<f64> = part
            .split(',')
            .map(|v| v.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("'{part}': a point is X,Y,Z in mm (numbers), points are separated by ';'"))?;
        match values.as_slice() {
            [x, y, z] if values.iter().all(|v| v.is_finite()) => out.push(Vector3::new(*x, *y, *z)),
            _ => {
                return Err(format!(
                    "'{part}': a point is X,Y,Z in mm (three numbers), points are separated by ';'"
                ))
            }
        }
    }
    if out.is_empty() {
        return Err("no point given: X,Y,Z;X,Y,Z;… in mm".into());
    }
    Ok(out)
}

/// The distances from the first seat to every other one ([`SeatDistance`] `0:k`): the known
/// dimensions of an artifact whose seats are at `seats` (mm), which give seat data its scale.
pub fn seat_distances(seats: &[Vector3<f64>]) -> Vec<SeatDistance> {
    seats
        .iter()
        .enumerate()
        .skip(1)
        .map(|(k, s)| SeatDistance {
            a: 0,
            b: k,
            length: (s - seats[0]).norm(),
        })
        .collect()
}

/// The configuration of `text` (the model's inputs in file units, deg for angles and mm for
/// lengths, comma-separated) in the model's units (rad, mm), or the middle of each input's
/// limits without one ([`middle_of_limits`]): a reference configuration for a command line. The
/// error names the option and what it expects.
pub fn reference_configuration(text: Option<&str>, inputs: &[InputSpec]) -> Result<Vec<f64>, String> {
    let Some(text) = text else { return Ok(middle_of_limits(inputs)) };
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| {
            format!(
                "--reference '{text}': the model's {} inputs in deg / mm, comma-separated",
                inputs.len()
            )
        })?;
    if values.len() != inputs.len() {
        return Err(format!(
            "--reference '{text}': {} values, the model has {} inputs ({})",
            values.len(),
            inputs.len(),
            crate::io::data_file::input_headers(inputs).join(", ")
        ));
    }
    Ok(inputs
        .iter()
        .zip(values)
        .map(|(i, v)| if i.unit == crate::params::Unit::Angle { v.to_radians() } else { v })
        .collect())
}

/// The middle of each input's limits (0 where it has none, and for an approach direction): a reference configuration
/// ([`Placement::reference`]) when none is given.
pub fn middle_of_limits(inputs: &[InputSpec]) -> Vec<f64> {
    inputs.iter().map(|i| i.limits.map_or(0.0, |(lo, hi)| 0.5 * (lo + hi))).collect()
}

/// Distance rows as a draw-wire's readings ([`super::zero`]): each row's length minus its
/// pivot's zero (`zeros[pivot]`, mm; one value for every pivot when `zeros` has one), marked as
/// relative to an unknown zero.
pub fn as_readings(rows: Vec<Measurement>, zeros: &[f64]) -> Vec<Measurement> {
    rows.into_iter()
        .map(|mut m| {
            if let Observation::Distance { pivot, length, relative } = &mut m.obs {
                *length -= zeros.get(*pivot).or(zeros.last()).copied().unwrap_or(0.0);
                *relative = true;
            }
            m
        })
        .collect()
}
