//! [`Framed`](super::Framed)'s inverse kinematics for a machine that commands part of the tool
//! pose ([`Task::PositionAndAxis`], [`Task::Position`], [`Task::HeightAndAxis`],
//! [`Task::PositionAndYaw`]).
//!
//! The inner mechanism reaches the commanded part of the *platform* target `X⁻¹·T·Y⁻¹`; the rest
//! (the rotation about the tool axis, the tilts, x and y of a tilting head) its constraints
//! decide, and differs from the target's. Through a tool offset `Y` that difference moves the
//! measured tool point and tilts the measured tool axis: the commanded part of `X·M(q)·Y` misses
//! the target by the parasitic difference times the offset. Newton's method on the commanded
//! part: the unknowns are the commanded coordinates of the platform target sent to the inner
//! inverse (its position, height, axis or yaw), the equations the commanded part of the tool
//! pose reached minus the target's, in the mechanism's base frame; the Jacobian by forward
//! differences (one inner inverse per commanded coordinate), kept while it converges fast.
use super::super::{Mechanism, Task};
use crate::error::KinError;
use crate::se3::{self, Pose};
use nalgebra::{DMatrix, DVector, UnitQuaternion, Vector3};

/// Newton iterations of the framed inverse kinematics for a partial task.
pub(super) const MAX_ITERATIONS: usize = 20;
/// Stop: the commanded part reached to this (mm; rad scaled by [`ANGLE_SCALE`]).
const DONE: f64 = 1e-10;
/// Accept: what is reached at the end must be within this (mm; rad scaled by [`ANGLE_SCALE`]),
/// a hundredth of compensation's check (1e-6 mm, 1e-8 rad).
const ACCEPT: f64 = 1e-8;
/// Angles weigh as displacements at this lever arm (mm), as in the closed loops' task equations.
const ANGLE_SCALE: f64 = 1000.0;
/// Forward-difference steps: mm for a displacement, rad for a rotation.
const STEP_MM: f64 = 1e-4;
const STEP_RAD: f64 = 1e-7;

/// One commanded coordinate of the platform target: a displacement along, or a rotation about,
/// a base-frame direction.
#[derive(Clone, Copy)]
enum Coordinate {
    Move(Vector3<f64>),
    Turn(Vector3<f64>),
}

/// The commanded coordinates of `task` about the target `goal` (base frame): the base axes for
/// a position, base z for a height, the target's x and y axes for the tool axis (a rotation about
/// them tilts it), base z for a yaw.
fn coordinates(task: Task, goal: &Pose) -> Vec<Coordinate> {
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    let (tx, ty) = (goal.rotation * x, goal.rotation * y);
    match task {
        Task::Position => vec![Coordinate::Move(x), Coordinate::Move(y), Coordinate::Move(z)],
        Task::PositionAndAxis => vec![
            Coordinate::Move(x),
            Coordinate::Move(y),
            Coordinate::Move(z),
            Coordinate::Turn(tx),
            Coordinate::Turn(ty),
        ],
        Task::HeightAndAxis => vec![Coordinate::Move(z), Coordinate::Turn(tx), Coordinate::Turn(ty)],
        Task::PositionAndYaw => vec![Coordinate::Move(x), Coordinate::Move(y), Coordinate::Move(z), Coordinate::Turn(z)],
        Task::Full => Vec::new(),
    }
}

/// `p` moved by `amount` along each coordinate.
fn moved(p: &Pose, coords: &[Coordinate], amount: &[f64]) -> Pose {
    let mut shift = Vector3::zeros();
    let mut turn = Vector3::zeros();
    for (c, a) in coords.iter().zip(amount) {
        match c {
            Coordinate::Move(d) => shift += d * *a,
            Coordinate::Turn(w) => turn += w * *a,
        }
    }
    Pose::from_parts(
        (p.translation.vector + shift).into(),
        UnitQuaternion::from_scaled_axis(turn) * p.rotation,
    )
}

/// The commanded part of `reached` minus that of `goal` (both in the base frame), angles scaled
/// by [`ANGLE_SCALE`]: position (or height), then the tool axis' components along the goal's x
/// and y axes, or the yaw difference.
fn miss(task: Task, goal: &Pose, reached: &Pose) -> DVector<f64> {
    let d = reached.translation.vector - goal.translation.vector;
    let axis = reached.rotation * Vector3::z();
    let tilt = |k: Vector3<f64>| axis.dot(&(goal.rotation * k)) * ANGLE_SCALE;
    match task {
        Task::Position => DVector::from_column_slice(d.as_slice()),
        Task::PositionAndAxis => DVector::from_vec(vec![d.x, d.y, d.z, tilt(Vector3::x()), tilt(Vector3::y())]),
        Task::HeightAndAxis => DVector::from_vec(vec![d.z, tilt(Vector3::x()), tilt(Vector3::y())]),
        Task::PositionAndYaw => DVector::from_vec(vec![d.x, d.y, d.z, se3::yaw_difference(goal, reached) * ANGLE_SCALE]),
        Task::Full => DVector::zeros(0),
    }
}

/// Inputs that put the commanded part of `inner`'s platform, carried by `tool` (`Y`), on `goal`
/// (the target in the mechanism's base frame, `X⁻¹·T`), starting from the platform target
/// `goal·Y⁻¹`. Errors: the inner inverse's, or [`KinError::NoConvergence`] when Newton ends
/// farther than 1e-8 mm (1e-11 rad) from the goal.
pub(super) fn inverse<M: Mechanism>(inner: &M, tool: &Pose, goal: &Pose, seed: Option<&[f64]>) -> Result<Vec<f64>, KinError> {
    let task = inner.task();
    let coords = coordinates(task, goal);
    let n = coords.len();
    let evaluate = |platform: &Pose, seed: Option<&[f64]>| -> Result<(Vec<f64>, DVector<f64>), KinError> {
        let q = inner.inverse(platform, seed)?;
        let r = miss(task, goal, &(inner.forward(&q)? * tool));
        Ok((q, r))
    };
    let mut platform = goal * tool.inverse();
    let (mut q, mut r) = evaluate(&platform, seed)?;
    let mut norm = r.amax();
    let mut jacobian: Option<nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>> = None;
    for _ in 0..MAX_ITERATIONS {
        if norm <= DONE {
            return Ok(q);
        }
        let lu = match jacobian.take() {
            Some(lu) => lu,
            None => {
                let mut j = DMatrix::zeros(n, n);
                for (k, c) in coords.iter().enumerate() {
                    let h = match c {
                        Coordinate::Move(_) => STEP_MM,
                        Coordinate::Turn(_) => STEP_RAD,
                    };
                    let mut e = vec![0.0; n];
                    e[k] = h;
                    let (_, rk) = evaluate(&moved(&platform, &coords, &e), Some(&q))?;
                    j.set_column(k, &((rk - &r) / h));
                }
                j.lu()
            }
        };
        let Some(step) = lu.solve(&(-&r)) else { break };
        // Halve the step until the miss shrinks (a step across a fold of the inner inverse).
        let mut s = 1.0;
        let mut next = None;
        while s > 1e-3 {
            let amount: Vec<f64> = step.iter().map(|v| v * s).collect();
            let trial = moved(&platform, &coords, &amount);
            if let Ok((qt, rt)) = evaluate(&trial, Some(&q)) {
                if rt.amax() < norm {
                    next = Some((trial, qt, rt));
                    break;
                }
            }
            s *= 0.5;
        }
        let Some((trial, qt, rt)) = next else { break };
        let reached = rt.amax();
        let fast = reached < 0.1 * norm && s == 1.0;
        (platform, q, r, norm) = (trial, qt, rt, reached);
        // The chord method while it converges fast (the Jacobian hardly changes near the goal).
        if fast {
            jacobian = Some(lu);
        }
    }
    if norm <= ACCEPT {
        return Ok(q);
    }
    Err(KinError::NoConvergence {
        what: "inverse kinematics of the tool point".into(),
        iterations: MAX_ITERATIONS,
        residual: norm,
    })
}
