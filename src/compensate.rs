//! Compensation: target poses → actuator commands through a (calibrated) model's inverse
//! kinematics, from several starts where the inverse depends on its seed, within the joint
//! limits and on the nominal controller's branch.
use crate::error::KinError;
use crate::measure::{Measurement, Observation};
use crate::model::kind::InputSpec;
use crate::model::Mechanism;
use crate::params::Unit;
use crate::se3::Pose;
use crate::simulate::random_inputs;
use crate::validate::commanded_error;
use rand::SeedableRng;
use std::f64::consts::PI;

/// Why a target could not be compensated.
#[derive(Debug, Clone, PartialEq)]
pub struct CompensationError {
    /// Index of the target.
    pub target: usize,
    /// The reason.
    pub source: KinError,
}

/// Add whole turns to each revolute input so that it is as close as possible to `reference`
/// (the seed, or 0) while inside its limits when the limits allow it.
pub(crate) fn wrap_near(inputs: &[InputSpec], q: &mut [f64], reference: &[f64]) {
    for (k, (i, v)) in inputs.iter().zip(q.iter_mut()).enumerate() {
        if i.unit != Unit::Angle {
            continue;
        }
        let r = reference.get(k).copied().unwrap_or(0.0);
        let turns = ((r - *v) / (2.0 * PI)).round();
        let mut best = *v + turns * 2.0 * PI;
        if let Some((lo, hi)) = i.limits {
            if best < lo - 1e-9 || best > hi + 1e-9 {
                // The nearest equivalent angle is outside the limits: take the nearest one inside.
                let candidates = (-3..=3)
                    .map(|t| best + t as f64 * 2.0 * PI)
                    .filter(|c| *c >= lo - 1e-9 && *c <= hi + 1e-9);
                if let Some(c) = candidates.min_by(|a, b| (a - r).abs().total_cmp(&(b - r).abs())) {
                    best = c;
                }
            }
        }
        *v = best;
    }
}

pub(crate) fn check_limits(inputs: &[InputSpec], q: &[f64]) -> Result<(), KinError> {
    for (i, v) in inputs.iter().zip(q) {
        if let Some((lo, hi)) = i.limits {
            if *v < lo - 1e-9 || *v > hi + 1e-9 {
                let (f, u) = if i.unit == Unit::Angle { (180.0 / PI, "deg") } else { (1.0, "mm") };
                return Err(KinError::OutOfWorkspace(format!(
                    "{} = {:.3} {u} outside its limits [{:.3}, {:.3}] {u}",
                    i.name,
                    v * f,
                    lo * f,
                    hi * f
                )));
            }
        }
    }
    Ok(())
}

/// Number of random fall-back starting points of [`compensate`]'s inverse kinematics.
pub const COMPENSATION_STARTS: usize = 24;

/// The zero configuration, then `n` pseudo-random points within the limits (a fixed seed, so
/// results do not change from run to run): [`compensate`]'s fall-back starting points.
pub(crate) fn fixed_starts(inputs: &[InputSpec], n: usize) -> Vec<Vec<f64>> {
    let mut starts: Vec<Vec<f64>> = vec![vec![0.0; inputs.len()]];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x6b696e65);
    starts.extend(random_inputs(inputs, n, &mut rng));
    starts
}

/// One target's inverse kinematics from each of `starts` in turn (their approach-direction
/// inputs set to `approach`) until one reaches the target within the limits; on failure the
/// limit violation met, if any, and the last error.
#[allow(clippy::type_complexity)]
fn solve_one<M: Mechanism + ?Sized>(
    model: &M,
    inputs: &[InputSpec],
    target: &Pose,
    starts: &[Vec<f64>],
    approach: &[f64],
    seed: Option<&Vec<f64>>,
) -> Result<Vec<f64>, (Option<KinError>, KinError)> {
    let n = inputs.len();
    let slots: Vec<usize> = inputs
        .iter()
        .enumerate()
        .filter(|(_, i)| i.approach_of.is_some())
        .map(|(k, _)| k)
        .collect();
    let mut last_err = KinError::Unreachable("no starting point".into());
    // A solution outside the limits says more than a failed convergence: report it first.
    let mut limit_err: Option<KinError> = None;
    for s in starts.iter().filter(|s| s.len() == n) {
        let mut s = s.clone();
        for (&k, &a) in slots.iter().zip(approach) {
            s[k] = a;
        }
        match model.inverse(target, Some(&s)) {
            Ok(mut q) => {
                wrap_near(inputs, &mut q, seed.map_or(&[][..], |x| x.as_slice()));
                // Compared in the mechanism's base frame: a commanded height is along its z.
                let base = model.frames().map_or(Pose::identity(), |(x, _)| x.inverse());
                let reached = model
                    .forward(&q)
                    .map(|t| commanded_error(model.task(), &(base * target), &(base * t)));
                match reached {
                    Ok((dp, dw)) if dp < 1e-6 && dw < 1e-8 => match check_limits(inputs, &q) {
                        Ok(()) => return Ok(q),
                        Err(e) => limit_err = Some(e),
                    },
                    Ok((dp, dw)) => {
                        last_err = KinError::Unreachable(format!("inverse kinematics ended {dp:.3e} mm / {dw:.3e} rad from the target"))
                    }
                    Err(e) => last_err = e,
                }
            }
            Err(e) => last_err = e,
        }
    }
    Err((limit_err, last_err))
}

/// Actuator commands that bring the (calibrated) `model`'s tool to each target pose: inverse
/// kinematics from `seeds[k]` when given (e.g. the nominal commands), else from the previous
/// solution, else from the zero configuration and [`COMPENSATION_STARTS`] fixed pseudo-random
/// points within the limits (tried in that order until one gives a valid solution; only the first
/// when the mechanism's inverse ignores its seed, [`Mechanism::inverse_ignores_seed`]). Revolute
/// inputs are moved by whole turns to the equivalent angle nearest the seed (or 0) within their
/// limits; every solution is checked against the limits and against the forward kinematics
/// (1e-6 mm, 1e-8 rad; for a 5-DOF mechanism, [`crate::model::Task::PositionAndAxis`], the position and the tool
/// axis only: see [`commanded_error`]). `progress` is called after each target.
pub fn compensate<M: Mechanism + ?Sized>(
    model: &M,
    inputs: &[InputSpec],
    targets: &[Pose],
    seeds: Option<&[Vec<f64>]>,
    progress: &dyn Fn(usize),
) -> Result<Vec<Vec<f64>>, CompensationError> {
    let n = inputs.len();
    let mut out: Vec<Vec<f64>> = Vec::with_capacity(targets.len());
    // Deterministic fall-back starting points: the zero configuration, then random points
    // within the limits (a fixed seed, so results do not change from run to run).
    let fixed_starts = fixed_starts(inputs, COMPENSATION_STARTS);
    // Approach-direction inputs (a model with lost motion): given by the seed (the commands'
    // order), else those of moving from the previous solution to this one (a fixed point: solve
    // with the previous approach, then again if the motion turns out to come from the other side).
    let approach: Vec<(usize, usize)> = inputs
        .iter()
        .enumerate()
        .filter_map(|(k, i)| i.approach_of.map(|j| (k, j)))
        .collect();
    for (k, target) in targets.iter().enumerate() {
        let seed = seeds.and_then(|s| s.get(k)).filter(|s| s.len() == n);
        let mut starts: Vec<Vec<f64>> = Vec::new();
        if let Some(s) = seed {
            starts.push(s.clone());
        }
        if let Some(prev) = out.last() {
            starts.push(prev.clone());
        }
        starts.extend(fixed_starts.iter().cloned());
        if model.inverse_ignores_seed() {
            // One attempt says all: other starting points would give the same answer.
            starts.truncate(1);
        }
        let assumed: Vec<f64> = approach.iter().map(|&(a, _)| seed.or(out.last()).map_or(0.0, |s| s[a])).collect();
        let mut attempt = solve_one(model, inputs, target, &starts, &assumed, seed);
        if let (None, Some(prev), Ok(q)) = (seed, out.last(), &attempt) {
            let moved: Vec<f64> = approach
                .iter()
                .zip(&assumed)
                .map(|(&(_, j), &s)| {
                    if (q[j] - prev[j]).abs() > 1e-12 {
                        (q[j] - prev[j]).signum()
                    } else {
                        s
                    }
                })
                .collect();
            if moved != assumed {
                attempt = solve_one(model, inputs, target, &starts, &moved, seed);
            }
        }
        let (found, limit_err, last_err) = match attempt {
            Ok(q) => (Some(q), None, KinError::Unreachable(String::new())),
            Err((l, e)) => (None, l, e),
        };
        let tried = starts.len();
        match found {
            Some(q) => out.push(q),
            None => {
                let from = if tried == 1 {
                    String::new()
                } else {
                    format!(" from {tried} starting points")
                };
                let limit_err = limit_err.map(|e| match e {
                    KinError::OutOfWorkspace(m) => KinError::OutOfWorkspace(format!("no solution within the limits{from} (one had {m})")),
                    e => e,
                });
                let source = match limit_err.unwrap_or(last_err) {
                    KinError::NoConvergence { residual, .. } => KinError::Unreachable(format!(
                        "inverse kinematics found no solution{from} (residual {residual:.3e}); the target is probably outside the workspace"
                    )),
                    e => e,
                };
                return Err(CompensationError { target: k, source });
            }
        }
        progress(k);
    }
    Ok(out)
}

/// The target poses of a data set (pose observations only).
pub fn target_poses(data: &[Measurement]) -> Result<Vec<Pose>, usize> {
    data.iter()
        .enumerate()
        .map(|(i, m)| match &m.obs {
            Observation::Pose(t) => Ok(*t),
            Observation::Position(_)
            | Observation::Points(_)
            | Observation::Seat(_)
            | Observation::Distance { .. }
            | Observation::Touch(_) => Err(i),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::builtin::irb120;
    use crate::se3;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn compensation_inverts_forward_within_limits() {
        let m = irb120();
        let inputs = crate::io::model_file::MechanismSpec::Serial(m.clone()).inputs();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let qs: Vec<Vec<f64>> = random_inputs(&inputs, 10, &mut rng)
            .into_iter()
            .map(|q| q.iter().map(|v| v * 0.5).collect())
            .collect();
        let targets: Vec<Pose> = qs.iter().map(|q| m.forward(q).unwrap()).collect();
        let seeds: Vec<Vec<f64>> = qs.iter().map(|q| q.iter().map(|v| v + 0.05).collect()).collect();
        let sol = compensate(&m, &inputs, &targets, Some(&seeds), &|_| {}).unwrap();
        for (q, t) in sol.iter().zip(&targets) {
            let e = se3::pose_error(t, &m.forward(q).unwrap());
            assert!(e.norm() < 1e-8);
        }
        let far = vec![se3::translation(5000.0, 0.0, 0.0)];
        let err = compensate(&m, &inputs, &far, None, &|_| {}).unwrap_err();
        assert_eq!(err.target, 0);
        assert!(matches!(err.source, KinError::Unreachable(_)), "{:?}", err.source);
    }

    #[test]
    fn revolute_values_wrap_to_the_turn_nearest_the_seed_within_limits() {
        let d = PI / 180.0;
        let inp = |lo: f64, hi: f64| InputSpec {
            name: "q".into(),
            unit: Unit::Angle,
            limits: Some((lo * d, hi * d)),
            approach_of: None,
            observed: false,
        };
        let inputs = [inp(-400.0, 400.0), inp(-110.0, 70.0), inp(-400.0, 400.0)];
        let mut q = [350.0 * d, 300.0 * d, -10.0 * d];
        wrap_near(&inputs, &mut q, &[0.0, 0.0, 355.0 * d]);
        let deg: Vec<f64> = q.iter().map(|v| (v / d * 1e9).round() / 1e9).collect();
        assert_eq!(deg, vec![-10.0, -60.0, 350.0]);
        // Prismatic inputs are never wrapped.
        let lin = [InputSpec {
            name: "d".into(),
            unit: Unit::Length,
            limits: Some((0.0, 1.0)),
            approach_of: None,
            observed: false,
        }];
        let mut x = [7.0];
        wrap_near(&lin, &mut x, &[]);
        assert_eq!(x, [7.0]);
    }
}
