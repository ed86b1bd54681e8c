//! Candidate measurement configurations: a sample of a mechanism's workspace (or joint space),
//! filtered by reachability, input limits and distance from singularity.
//!
//! Sampling is a pure function of the sample index ([`Sampling::points`]), so generation runs in
//! parallel (rayon) and gives the same candidates, in the same order, on any number of threads.
use crate::error::CalibError;
use crate::model::Mechanism;
use crate::se3::{self, Pose};
use nalgebra::{DMatrix, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::sync::Arc;

/// One candidate measurement configuration: the inputs and the tool pose they reach.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// Input values (rad / mm, in the mechanism's input order).
    pub q: Vec<f64>,
    /// Nominal tool pose at `q` (world frame).
    pub target: Pose,
    /// The rest of the forward solution at `q` with `target` its pose
    /// ([`Mechanism::forward_solution`]), when the candidate's check solved it: its Jacobian block
    /// ([`super::CandidateJacobians::build`]) is then computed there without solving again.
    /// `None`: solved again.
    pub solution: Option<Vec<f64>>,
}

/// A box of tool poses: positions in an axis-aligned box and orientations
/// `R = Rz(yaw)·Ry(pitch)·Rx(roll)·R_ref` (fixed-axes roll–pitch–yaw about the world axes, applied
/// to a reference orientation). A range with `min == max` is a fixed value.
#[derive(Debug, Clone, PartialEq)]
pub struct Workspace {
    /// Lower corner of the position box (mm).
    pub position_min: Vector3<f64>,
    /// Upper corner of the position box (mm).
    pub position_max: Vector3<f64>,
    /// Reference orientation `R_ref`.
    pub reference: UnitQuaternion<f64>,
    /// Lower bounds of (roll, pitch, yaw), rad.
    pub rpy_min: [f64; 3],
    /// Upper bounds of (roll, pitch, yaw), rad.
    pub rpy_max: [f64; 3],
}

impl Workspace {
    /// Lower and upper bounds of the six box coordinates `(x, y, z, roll, pitch, yaw)`.
    pub fn bounds(&self) -> ([f64; 6], [f64; 6]) {
        let p0 = self.position_min;
        let p1 = self.position_max;
        (
            [p0.x, p0.y, p0.z, self.rpy_min[0], self.rpy_min[1], self.rpy_min[2]],
            [p1.x, p1.y, p1.z, self.rpy_max[0], self.rpy_max[1], self.rpy_max[2]],
        )
    }

    /// The pose at box coordinates `(x, y, z, roll, pitch, yaw)` (mm, rad).
    pub fn pose(&self, c: &[f64; 6]) -> Pose {
        let r = UnitQuaternion::from_euler_angles(c[3], c[4], c[5]) * self.reference;
        Pose::from_parts(Translation3::new(c[0], c[1], c[2]), r)
    }
}

/// How to sample a box of `d` coordinates.
#[derive(Debug, Clone, PartialEq)]
pub enum Sampling {
    /// A full grid with `counts[j]` points along coordinate `j`, end points included (a count of
    /// 1 takes the midpoint). `N = Π counts`.
    Grid {
        /// Points per coordinate.
        counts: Vec<usize>,
    },
    /// `n` points of the Halton sequence (bases 2, 3, 5, …; index 0 skipped) with a
    /// Cranley–Patterson random shift drawn from `seed` (the same seed gives the same points).
    Halton {
        /// Number of points.
        n: usize,
        /// Seed of the random shift.
        seed: u64,
    },
}

const PRIMES: [u64; 16] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53];

fn radical_inverse(mut i: u64, base: u64) -> f64 {
    let inv = 1.0 / base as f64;
    let mut f = inv;
    let mut r = 0.0;
    while i > 0 {
        r += f * (i % base) as f64;
        i /= base;
        f *= inv;
    }
    r
}

impl Sampling {
    /// Number of sample points for a box of `dims` coordinates.
    pub fn len(&self, dims: usize) -> Result<usize, CalibError> {
        match self {
            Sampling::Grid { counts } => {
                if counts.len() != dims {
                    return Err(CalibError::InvalidOption(format!(
                        "grid sampling needs {dims} counts (one per coordinate), got {}",
                        counts.len()
                    )));
                }
                if counts.contains(&0) {
                    return Err(CalibError::InvalidOption("grid counts must be at least 1".into()));
                }
                counts
                    .iter()
                    .try_fold(1usize, |a, &c| a.checked_mul(c))
                    .ok_or_else(|| CalibError::InvalidOption("grid too large".into()))
            }
            Sampling::Halton { n, .. } => {
                if dims > PRIMES.len() {
                    return Err(CalibError::InvalidOption(format!(
                        "Halton sampling supports at most {} coordinates, got {dims}",
                        PRIMES.len()
                    )));
                }
                Ok(*n)
            }
        }
    }

    /// Whether the sampling yields no point.
    pub fn is_empty(&self, dims: usize) -> bool {
        self.len(dims).map(|n| n == 0).unwrap_or(true)
    }

    /// The random shift of the Halton sequence (zeros for a grid).
    fn shift(&self, dims: usize) -> Vec<f64> {
        match self {
            Sampling::Grid { .. } => vec![0.0; dims],
            Sampling::Halton { seed, .. } => {
                let mut rng = ChaCha8Rng::seed_from_u64(*seed);
                (0..dims).map(|_| rng.random_range(0.0..1.0)).collect()
            }
        }
    }

    /// Point `index` in the unit cube `[0, 1]^dims` (`shift` from [`Self::shift`]).
    fn unit_point(&self, index: usize, shift: &[f64], out: &mut [f64]) {
        match self {
            Sampling::Grid { counts } => {
                let mut rest = index;
                for (j, &c) in counts.iter().enumerate() {
                    let i = rest % c;
                    rest /= c;
                    out[j] = if c == 1 { 0.5 } else { i as f64 / (c - 1) as f64 };
                }
            }
            Sampling::Halton { .. } => {
                for (j, o) in out.iter_mut().enumerate() {
                    let u = radical_inverse(index as u64 + 1, PRIMES[j]) + shift[j];
                    *o = u - u.floor();
                }
            }
        }
    }

    /// All points in the box `[lower, upper]` (coordinates with `lower == upper` are fixed).
    pub fn points(&self, lower: &[f64], upper: &[f64]) -> Result<Vec<Vec<f64>>, CalibError> {
        let d = lower.len();
        if upper.len() != d {
            return Err(CalibError::InvalidOption("box bounds of different lengths".into()));
        }
        if lower.iter().zip(upper).any(|(a, b)| !(a.is_finite() && b.is_finite() && a <= b)) {
            return Err(CalibError::InvalidOption("box bounds must be finite with lower ≤ upper".into()));
        }
        let n = self.len(d)?;
        let shift = self.shift(d);
        Ok((0..n)
            .into_par_iter()
            .map(|i| {
                let mut u = vec![0.0; d];
                self.unit_point(i, &shift, &mut u);
                u.iter().enumerate().map(|(j, &t)| lower[j] + t * (upper[j] - lower[j])).collect()
            })
            .collect())
    }
}

/// A user-supplied acceptance test on a candidate.
pub type CandidatePredicate = Arc<dyn Fn(&Candidate) -> bool + Send + Sync>;

/// Which candidates to keep.
#[derive(Clone)]
pub struct CandidateFilter {
    /// Input limits `(min, max)` per input (actuator strokes, passive-joint limits); `None`: none.
    pub input_limits: Option<Vec<(f64, f64)>>,
    /// FK∘IK agreement required of a workspace sample: position (mm) and rotation (rad).
    pub fk_tolerance: (f64, f64),
    /// Check FK∘IK on every sample of a closed-loop platform box
    /// ([`super::candidates_in_platform_box`]), or of a workspace box whose mechanism's inverse
    /// gives its whole solution ([`Mechanism::inverse_solution`], a limbs machine's). Off, the
    /// check moves to the chosen set:
    /// [`super::plan()`] runs the forward kinematics identification uses on each chosen candidate
    /// and replaces any that reach another assembly mode (the same plan at a fraction of the
    /// cost: one forward solve per chosen candidate instead of one per sample).
    pub check_forward: bool,
    /// Largest accepted condition number `σ_max/σ_min` of the input Jacobian `∂(tool pose)/∂q`
    /// (central differences of [`Mechanism::forward`], orientation rows multiplied by
    /// `length_scale`); `None`: no singularity filter. Near a singularity this number grows
    /// without bound.
    pub max_condition: Option<f64>,
    /// Length (mm) that turns orientation rows (rad) into mm for the condition number.
    pub length_scale: f64,
    /// Finite-difference step of the input Jacobian (input units).
    pub step: f64,
    /// Any further test (e.g. a mechanism-specific singularity measure or collision check).
    pub custom: Option<CandidatePredicate>,
}

impl Default for CandidateFilter {
    fn default() -> Self {
        CandidateFilter {
            input_limits: None,
            fk_tolerance: (1e-6, 1e-8),
            check_forward: true,
            max_condition: None,
            length_scale: 100.0,
            step: 1e-6,
            custom: None,
        }
    }
}

impl std::fmt::Debug for CandidateFilter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CandidateFilter")
            .field("input_limits", &self.input_limits)
            .field("fk_tolerance", &self.fk_tolerance)
            .field("check_forward", &self.check_forward)
            .field("max_condition", &self.max_condition)
            .field("length_scale", &self.length_scale)
            .field("step", &self.step)
            .field("custom", &self.custom.as_ref().map(|_| "<closure>"))
            .finish()
    }
}

/// Counts of a candidate generation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct GenerationReport {
    /// Sample points drawn.
    pub sampled: usize,
    /// Rejected: inverse kinematics failed, or FK∘IK disagreed with the target.
    pub unreachable: usize,
    /// Rejected: outside the input limits.
    pub out_of_limits: usize,
    /// Rejected: input-Jacobian condition number above the limit.
    pub near_singular: usize,
    /// Rejected by the custom test.
    pub rejected: usize,
    /// Candidates kept.
    pub kept: usize,
}

impl std::fmt::Display for GenerationReport {
    /// "K candidates kept of N sampled (… unreachable, … outside strokes/limits, … near-singular, … rejected)".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} candidates kept of {} sampled ({} unreachable, {} outside strokes/limits, {} near-singular, {} rejected)",
            self.kept, self.sampled, self.unreachable, self.out_of_limits, self.near_singular, self.rejected
        )
    }
}

enum Outcome {
    Kept(Candidate),
    Unreachable,
    OutOfLimits,
    NearSingular,
    Rejected,
}

/// Condition number of the input Jacobian `∂(tool pose)/∂q` by central differences, orientation
/// rows scaled by `length_scale` (mm/rad). `None` when the forward kinematics fails nearby.
pub fn input_condition<M: Mechanism + ?Sized>(mech: &M, q: &[f64], step: f64, length_scale: f64) -> Option<f64> {
    let n = q.len();
    let mut j = DMatrix::zeros(6, n);
    let mut qp = q.to_vec();
    for c in 0..n {
        qp[c] = q[c] + step;
        let a = mech.forward(&qp).ok()?;
        qp[c] = q[c] - step;
        let b = mech.forward(&qp).ok()?;
        qp[c] = q[c];
        let e = se3::pose_error(&a, &b) / (2.0 * step);
        for r in 0..6 {
            j[(r, c)] = if r < 3 { e[r] } else { e[r] * length_scale };
        }
    }
    let sv = crate::identifiability::singular_values(&j);
    let (hi, lo) = (sv.first().copied()?, sv.last().copied()?);
    Some(if lo > 0.0 { hi / lo } else { f64::INFINITY })
}

/// `target` is the pose at `q` and `solution` the rest of its forward solution, unless `check_fk`
/// asks to solve the forward kinematics (then both come from it).
fn classify<M: Mechanism + ?Sized>(
    mech: &M,
    q: Vec<f64>,
    mut target: Pose,
    mut solution: Option<Vec<f64>>,
    check_fk: bool,
    filter: &CandidateFilter,
) -> Outcome {
    if check_fk {
        match mech.forward_solution(&q) {
            Ok((t, rest)) => {
                // Only what the inputs command must match (a 3- or 5-DOF machine's orientation
                // follows from its constraints); the target is then the pose actually reached.
                let (dp, dw) = crate::validate::commanded_error(mech.task(), &target, &t);
                if dp > filter.fk_tolerance.0 || dw > filter.fk_tolerance.1 {
                    return Outcome::Unreachable;
                }
                target = t;
                solution = Some(rest);
            }
            Err(_) => return Outcome::Unreachable,
        }
    }
    if let Some(lim) = &filter.input_limits {
        if lim.len() != q.len() || q.iter().zip(lim).any(|(v, (a, b))| v < a || v > b) {
            return Outcome::OutOfLimits;
        }
    }
    if let Some(max) = filter.max_condition {
        match input_condition(mech, &q, filter.step, filter.length_scale) {
            Some(c) if c <= max => {}
            _ => return Outcome::NearSingular,
        }
    }
    let cand = Candidate { q, target, solution };
    if let Some(f) = &filter.custom {
        if !f(&cand) {
            return Outcome::Rejected;
        }
    }
    Outcome::Kept(cand)
}

fn tally(outcomes: Vec<Outcome>) -> (Vec<Candidate>, GenerationReport) {
    let mut rep = GenerationReport {
        sampled: outcomes.len(),
        ..Default::default()
    };
    let mut kept = Vec::new();
    for o in outcomes {
        match o {
            Outcome::Kept(c) => kept.push(c),
            Outcome::Unreachable => rep.unreachable += 1,
            Outcome::OutOfLimits => rep.out_of_limits += 1,
            Outcome::NearSingular => rep.near_singular += 1,
            Outcome::Rejected => rep.rejected += 1,
        }
    }
    rep.kept = kept.len();
    (kept, rep)
}

/// Progress callback: called with the number of items just finished (from any thread).
pub type ProgressFn<'a> = &'a (dyn Fn(u64) + Sync);

/// Candidates from a workspace box: every sample pose is solved by [`Mechanism::inverse`] (from
/// `ik_seed`), kept when FK∘IK agrees with it and it passes `filter`. In parallel.
pub fn candidates_in_workspace<M: Mechanism + ?Sized>(
    mech: &M,
    workspace: &Workspace,
    sampling: &Sampling,
    ik_seed: Option<&[f64]>,
    filter: &CandidateFilter,
    progress: Option<ProgressFn>,
) -> Result<(Vec<Candidate>, GenerationReport), CalibError> {
    let (lo, hi) = workspace.bounds();
    let points = sampling.points(&lo, &hi)?;
    let outcomes: Vec<Outcome> = points
        .into_par_iter()
        .with_min_len(256)
        .map(|c| {
            let target = workspace.pose(&[c[0], c[1], c[2], c[3], c[4], c[5]]);
            let out = match mech.inverse_solution(&target, ik_seed) {
                // The inverse kinematics gave its whole solution: the forward check may wait.
                Ok((q, Some((reached, rest)))) if !filter.check_forward => classify(mech, q, reached, Some(rest), false, filter),
                Ok((q, _)) => classify(mech, q, target, None, true, filter),
                Err(_) => Outcome::Unreachable,
            };
            if let Some(p) = progress {
                p(1);
            }
            out
        })
        .collect();
    Ok(tally(outcomes))
}

/// Candidates drawn directly in input (joint) space, for serial chains and any mechanism whose
/// forward kinematics is cheap: every sample `q` of the box `[lower, upper]` whose forward
/// kinematics succeeds and that passes `filter` is kept, with its tool pose as target.
pub fn candidates_in_input_box<M: Mechanism + ?Sized>(
    mech: &M,
    lower: &[f64],
    upper: &[f64],
    sampling: &Sampling,
    filter: &CandidateFilter,
    progress: Option<ProgressFn>,
) -> Result<(Vec<Candidate>, GenerationReport), CalibError> {
    let n_inputs = mech.input_names().len();
    if lower.len() != n_inputs {
        return Err(CalibError::InvalidOption(format!(
            "input box has {} coordinates, the mechanism {n_inputs} inputs",
            lower.len()
        )));
    }
    let points = sampling.points(lower, upper)?;
    let outcomes: Vec<Outcome> = points
        .into_par_iter()
        .with_min_len(256)
        .map(|q| {
            let out = match mech.forward_solution(&q) {
                Ok((t, rest)) => classify(mech, q, t, Some(rest), false, filter),
                Err(_) => Outcome::Unreachable,
            };
            if let Some(p) = progress {
                p(1);
            }
            out
        })
        .collect();
    Ok(tally(outcomes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halton_points_fill_the_box_and_are_deterministic() {
        let s = Sampling::Halton { n: 1000, seed: 3 };
        let a = s.points(&[0.0, -1.0, 5.0], &[1.0, 1.0, 5.0]).unwrap();
        let b = s.points(&[0.0, -1.0, 5.0], &[1.0, 1.0, 5.0]).unwrap();
        assert_eq!(a, b);
        assert!(a
            .iter()
            .all(|p| (0.0..=1.0).contains(&p[0]) && (-1.0..=1.0).contains(&p[1]) && p[2] == 5.0));
        // Low discrepancy: every tenth of [0,1] in the first coordinate holds 100 ± 2 points.
        for bin in 0..10 {
            let c = a.iter().filter(|p| (p[0] * 10.0).floor() as usize == bin).count();
            assert!((98..=102).contains(&c), "bin {bin}: {c}");
        }
    }

    #[test]
    fn grid_includes_end_points() {
        let s = Sampling::Grid { counts: vec![3, 1] };
        let p = s.points(&[0.0, 0.0], &[2.0, 4.0]).unwrap();
        assert_eq!(p, vec![vec![0.0, 2.0], vec![1.0, 2.0], vec![2.0, 2.0]]);
        assert!(s.points(&[0.0], &[1.0]).is_err());
    }
}
