//! Instrument measurements of a virtual prototype: configurations that put the true tool point
//! in a seat, or on a sphere of known radius about a pivot, from many orientations.
use crate::error::{CalibError, KinError};
use crate::measure::{Measurement, Observation};
use crate::model::Mechanism;
use crate::se3::{self, Pose};
use nalgebra::Vector3;
use rand::{Rng, RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};

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
}

/// Attempts per requested row before [`seat_rows`] or [`distance_rows`] gives up.
const ATTEMPTS: usize = 50;

/// Configurations of `truth` (the real machine with its tool, e.g. a [`crate::model::framed::Framed`]
/// prototype) that put its tool point in each seat of `seats` (mm, base frame), orientations
/// drawn as `how` says; one [`Observation::Seat`] row each, the seat's number its index.
pub fn seat_rows(truth: &dyn Mechanism, seats: &[Vector3<f64>], how: &Placement) -> Result<Vec<Measurement>, CalibError> {
    draw_rows(truth, seats, how, |_, _| None)
}

/// Configurations of `truth` whose tool point lies at `length` (mm) from each pivot of `pivots`,
/// in directions within 60° of the pivot's direction toward the reference tool point; one
/// [`Observation::Distance`] row each with the true length plus noise along the bar.
pub fn distance_rows(truth: &dyn Mechanism, pivots: &[Vector3<f64>], length: f64, how: &Placement) -> Result<Vec<Measurement>, CalibError> {
    if length.is_nan() || length <= 0.0 {
        return Err(CalibError::InvalidOption(format!("ballbar length {length} mm: must be positive")));
    }
    let home = truth
        .forward(&how.reference)
        .map_err(|source| CalibError::Kinematics { pose: 0, source })?;
    draw_rows(truth, pivots, how, |pivot, rng| {
        let axis = (home.translation.vector - pivot).try_normalize(1e-9).unwrap_or_else(Vector3::z);
        Some(pivot + se3::so3_exp(&random_tilt(rng, 60f64.to_radians())) * axis * length)
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
            let Ok(q) = truth.inverse(&goal, Some(&how.reference)) else {
                continue;
            };
            let Ok(reached) = truth.forward(&q) else { continue };
            if (reached.translation.vector - place).norm() > 1e-9 {
                continue;
            }
            let obs = match aim {
                None => Observation::Seat(k),
                Some(_) => Observation::Distance {
                    pivot: k,
                    length: (reached.translation.vector - point).norm() + settle.x,
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
                    "point {k} at ({:.1}, {:.1}, {:.1}) mm: {found} of {} configurations reached it (move it into the workspace or tilt less)",
                    point.x, point.y, point.z, how.per_point
                )),
            });
        }
    }
    Ok(out)
}
