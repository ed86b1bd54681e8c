//! A planned instrument set measured on a virtual prototype ([`crate::design::instrument`] plans
//! it on the nominal model): what an operator does with the plan on the real machine.
//!
//! - **Seat row:** command the planned configuration, then jog the tool, keeping its orientation,
//!   until the ball sits in the seat. The recorded inputs are the truth's configuration that puts
//!   its tool point in the seat with the orientation it had at the planned configuration (inverse
//!   kinematics started there); the ball settles with the noise, per axis.
//! - **Distance row:** command the planned configuration, then move the tool point along the
//!   direction from the pivot until the bar has its length. The recorded inputs put the truth's
//!   tool point at the bar length from the pivot, in the direction it had from the pivot at the
//!   planned configuration (same orientation); the length read is the true one plus the noise.
use crate::error::{CalibError, KinError};
use crate::measure::{Measurement, Observation};
use crate::model::kind::InputSpec;
use crate::model::Mechanism;
use crate::se3::Pose;
use nalgebra::Vector3;
use rand_distr::Distribution;

/// The rows of `planned` (seat or distance rows of a plan, inputs the planned configurations)
/// measured on `truth` (the real machine with its tool), the points' true centres `points` (mm,
/// base frame: the plan's point `k` is the `k`-th), as the module docs say. `noise_mm`: per axis
/// at a seat, along the bar for a distance; `inputs`: the limits a recorded configuration must
/// respect (empty: none). A row the truth cannot reach is an error naming it.
pub fn measure_planned(
    truth: &dyn Mechanism,
    planned: &[Measurement],
    points: &[Vector3<f64>],
    noise_mm: f64,
    seed: u64,
    inputs: &[InputSpec],
) -> Result<Vec<Measurement>, CalibError> {
    let (mut rng, noise) = super::simulate::seeded_noise(noise_mm, seed)?;
    let unreachable = |i: usize, why: String| CalibError::Kinematics {
        pose: i,
        source: KinError::Unreachable(why),
    };
    planned
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let (kind, k) = m
                .obs
                .artifact_point()
                .ok_or_else(|| CalibError::InvalidOption(format!("row {i}: not a seat or distance row")))?;
            let centre = *points
                .get(k)
                .ok_or_else(|| CalibError::InvalidOption(format!("row {i}: {} {k}, but {} points are given", kind.name(), points.len())))?;
            let at = truth.forward(&m.q).map_err(|source| CalibError::Kinematics { pose: i, source })?;
            let settle = Vector3::new(noise.sample(&mut rng), noise.sample(&mut rng), noise.sample(&mut rng));
            let place = match m.obs {
                Observation::Distance { length, .. } => {
                    let u = (at.translation.vector - centre)
                        .try_normalize(1e-9)
                        .ok_or_else(|| unreachable(i, format!("the tool point is at pivot {k}: no direction from it")))?;
                    centre + u * length
                }
                _ => centre + settle,
            };
            let goal = Pose::from_parts(place.into(), at.rotation);
            let q = truth
                .inverse(&goal, Some(&m.q))
                .map_err(|source| CalibError::Kinematics { pose: i, source })?;
            let reached = truth.forward(&q).map_err(|source| CalibError::Kinematics { pose: i, source })?;
            if (reached.translation.vector - place).norm() > 1e-9 {
                return Err(unreachable(i, format!("the inverse kinematics misses {} {k}", kind.name())));
            }
            if let Some((j, v)) = q
                .iter()
                .zip(inputs)
                .enumerate()
                .find_map(|(j, (v, s))| s.limits.and_then(|(lo, hi)| (!(lo..=hi).contains(v)).then_some((j, *v))))
            {
                return Err(unreachable(i, format!("input {j} at {v:.6} is outside its limits there")));
            }
            let obs = match m.obs {
                Observation::Distance { pivot, .. } => Observation::Distance {
                    pivot,
                    length: (reached.translation.vector - centre).norm() + settle.x,
                    relative: false,
                },
                ref o => o.clone(),
            };
            Ok(Measurement {
                q,
                obs,
                joints: Vec::new(),
            })
        })
        .collect()
}
