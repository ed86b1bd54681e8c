//! Candidate configurations of closed-loop mechanisms ([`ClosedLoop`], e.g. the 5-DOF preset
//! [`crate::model::presets::pm5`]) sampled in **platform coordinates** `X = (x, y, z, α, β, γ)`.
//!
//! The prescribed workspace of a closed-loop preset is a box of platform coordinates (for the
//! 5-DOF machine `x, y ∈ [−50, 50] mm`, `z ∈ [350, 450] mm`, `α, β ∈ [−5°, 5°]`, γ parasitic),
//! not a box of tool poses, so this module samples that box directly:
//!
//! 1. sample point `X` ([`Sampling`]: Halton or a full grid; a coordinate with `min == max`, such
//!    as the parasitic γ, is fixed), target = the tool pose of `X`;
//! 2. **reachability**: the mechanism's inverse kinematics ([`ClosedLoop::inverse_with_pose`]:
//!    Newton on the constraints and the task equations; for a 5-DOF task the rotation about the
//!    tool axis follows from the constraints) must converge — else *unreachable*;
//! 3. **strokes**: the inputs must lie in the actuator strokes (and in
//!    [`CandidateFilter::input_limits`] if given) — else *out of limits*;
//! 4. **FK∘IK**: the forward kinematics from the home pose (what identification uses) must
//!    return the same tool pose, within [`CandidateFilter::fk_tolerance`] — else *unreachable*
//!    (another assembly mode). With [`CandidateFilter::check_forward`] off this check is left to
//!    [`super::plan()`], which makes it on the chosen candidates only;
//! 5. **distance from singularity**: [`actuator_condition`] at most
//!    [`CandidateFilter::max_condition`] — else *near singular*;
//! 6. the custom predicate, if any.
//!
//! The kept candidate's target is the tool pose actually reached (with its parasitic rotation),
//! i.e. what a tracker would measure on the nominal machine.
use super::candidates::{Candidate, CandidateFilter, GenerationReport, ProgressFn, Sampling};
use crate::error::{CalibError, KinError};
use crate::model::closed::{ClosedLoop, ConstraintSystem, Task, Workspace as PlatformBox};
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Condition number of the actuator Jacobian `∂X_c/∂q` of a closed-loop mechanism at an assembled
/// configuration `(x, q)`: by the implicit function theorem `∂X/∂q = −F_X⁻¹·F_q`, restricted to
/// the commanded coordinates `X_c` (all six for [`Task::Full`], `x, y, z, α, β` for
/// [`Task::PositionAndAxis`]), angle rows multiplied by `length_scale` (mm/rad). It grows
/// without bound at both kinds of singularity (`F_X` singular: the platform gains a freedom;
/// `F_q` rank-deficient: it loses one). `None` when `F_X` is singular.
pub fn actuator_condition<C: ConstraintSystem>(mech: &ClosedLoop<C>, x: &[f64; 6], q: &[f64], length_scale: f64) -> Option<f64> {
    let (fx, fq) = mech.actuator_jacobians(x, q).ok()?;
    condition_of(fx, &fq, mech.system().task().dof(), length_scale)
}

/// The actuator-Jacobian condition number of [`actuator_condition`] from `F_X` and `F_q`.
fn condition_of(fx: DMatrix<f64>, fq: &DMatrix<f64>, rows: usize, length_scale: f64) -> Option<f64> {
    let dxdq = fx.lu().solve(&(-fq))?;
    let mut m = DMatrix::zeros(rows, fq.ncols());
    for r in 0..rows {
        let s = if r < 3 { 1.0 } else { length_scale };
        for c in 0..fq.ncols() {
            m[(r, c)] = dxdq[(r, c)] * s;
        }
    }
    if m.iter().any(|v| !v.is_finite()) {
        return None;
    }
    // The square 5- and 6-input cases from the eigenvalues of the fixed-size Gram matrix `mᵀm`
    // (no allocation, several times cheaper than the SVD); far from the well-conditioned range,
    // where squaring loses digits, the SVD decides.
    let sv: Vec<f64> = match (rows, fq.ncols()) {
        (5, 5) => {
            let s = nalgebra::Matrix5::from_fn(|r, c| m[(r, c)]);
            from_gram((s.transpose() * s).symmetric_eigenvalues().as_slice(), || {
                s.singular_values().as_slice().to_vec()
            })
        }
        (6, 6) => {
            let s = nalgebra::Matrix6::from_fn(|r, c| m[(r, c)]);
            from_gram((s.transpose() * s).symmetric_eigenvalues().as_slice(), || {
                s.singular_values().as_slice().to_vec()
            })
        }
        _ => crate::identifiability::singular_values(&m),
    };
    if sv.is_empty() {
        return None;
    }
    let hi = sv.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let lo = sv.iter().copied().fold(f64::INFINITY, f64::min);
    Some(if lo > 0.0 { hi / lo } else { f64::INFINITY })
}

/// Singular values of a small square matrix from the eigenvalues `ev` of its Gram matrix `mᵀm`:
/// their square roots while the condition number is below 10⁶ (relative error under 10⁻⁴ there),
/// else the matrix's SVD (`svd`).
fn from_gram(ev: &[f64], svd: impl FnOnce() -> Vec<f64>) -> Vec<f64> {
    let hi = ev.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let lo = ev.iter().copied().fold(f64::INFINITY, f64::min);
    if hi > 0.0 && lo > 1e-12 * hi {
        return ev.iter().map(|&l| l.sqrt()).collect();
    }
    svd()
}

enum Outcome {
    Kept(Candidate, f64),
    Unreachable,
    OutOfLimits,
    NearSingular,
    Rejected,
}

fn classify<C: ConstraintSystem>(mech: &ClosedLoop<C>, x: &[f64; 6], filter: &CandidateFilter) -> Outcome {
    let target = mech.tool_pose_of(x);
    let (q, xs, jac) = match mech.inverse_with_jacobian(&target) {
        Ok(r) => r,
        Err(KinError::OutOfWorkspace(_)) => return Outcome::OutOfLimits,
        Err(_) => return Outcome::Unreachable,
    };
    if let Some(lim) = &filter.input_limits {
        if lim.len() != q.len() || q.iter().zip(lim).any(|(v, (a, b))| v < a || v > b) {
            return Outcome::OutOfLimits;
        }
    }
    let reached = mech.tool_pose_of(&xs);
    if filter.check_forward && !super::plan::forward_agrees(mech, &q, &reached, filter.fk_tolerance) {
        return Outcome::Unreachable;
    }
    // F_X and F_q are the upper blocks of the inverse solve's Jacobian at (X, q).
    let fx = jac.view((0, 0), (6, 6)).into_owned();
    let fq = jac.view((0, 6), (6, q.len())).into_owned();
    let cond = match condition_of(fx, &fq, mech.system().task().dof(), filter.length_scale) {
        Some(c) => c,
        None => return Outcome::NearSingular,
    };
    if cond.is_nan() || filter.max_condition.is_some_and(|max| cond > max) {
        return Outcome::NearSingular;
    }
    // The platform coordinates solved: the Jacobian block starts there, without a forward solve.
    let cand = Candidate {
        q,
        target: reached,
        solution: Some(xs.to_vec()),
    };
    if let Some(f) = &filter.custom {
        if !f(&cand) {
            return Outcome::Rejected;
        }
    }
    Outcome::Kept(cand, cond)
}

/// Counts of a closed-loop candidate generation, with the range of the actuator-Jacobian
/// condition number over the kept candidates.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlatformGeneration {
    /// Counts per outcome.
    pub report: GenerationReport,
    /// Smallest actuator-Jacobian condition number of a kept candidate.
    pub condition_min: f64,
    /// Largest actuator-Jacobian condition number of a kept candidate.
    pub condition_max: f64,
}

/// Candidates of a closed-loop mechanism in a box of platform coordinates (see the
/// [module docs](self) for the filters). In parallel (rayon); the result does not depend on the
/// number of threads. `progress` is called with the number of samples just processed.
pub fn candidates_in_platform_box<C: ConstraintSystem>(
    mech: &ClosedLoop<C>,
    workspace: &PlatformBox,
    sampling: &Sampling,
    filter: &CandidateFilter,
    progress: Option<ProgressFn>,
) -> Result<(Vec<Candidate>, PlatformGeneration), CalibError> {
    if mech.system().task() == Task::PositionAndAxis && workspace.min[5] != workspace.max[5] {
        return Err(CalibError::InvalidOption(
            "γ is parasitic for a 5-DOF (position and tool axis) mechanism: give it a fixed value (min = max)".into(),
        ));
    }
    let points = sampling.points(&workspace.min, &workspace.max)?;
    let outcomes: Vec<Outcome> = points
        .into_par_iter()
        .with_min_len(256)
        .map(|c| {
            let out = classify(mech, &[c[0], c[1], c[2], c[3], c[4], c[5]], filter);
            if let Some(p) = progress {
                p(1);
            }
            out
        })
        .collect();
    let mut gen = PlatformGeneration {
        report: GenerationReport {
            sampled: outcomes.len(),
            ..Default::default()
        },
        condition_min: f64::INFINITY,
        condition_max: 0.0,
    };
    let mut kept = Vec::new();
    for o in outcomes {
        let rep = &mut gen.report;
        match o {
            Outcome::Kept(c, cond) => {
                gen.condition_min = gen.condition_min.min(cond);
                gen.condition_max = gen.condition_max.max(cond);
                kept.push(c);
            }
            Outcome::Unreachable => rep.unreachable += 1,
            Outcome::OutOfLimits => rep.out_of_limits += 1,
            Outcome::NearSingular => rep.near_singular += 1,
            Outcome::Rejected => rep.rejected += 1,
        }
    }
    gen.report.kept = kept.len();
    if kept.is_empty() {
        gen.condition_min = 0.0;
    }
    Ok((kept, gen))
}

#[cfg(test)]
mod tests {
    use super::from_gram;
    use nalgebra::Matrix5;
    use rand::{RngExt, SeedableRng};

    /// The Gram-matrix condition number agrees with the SVD's to a relative 1e-15·cond² (1e-11 at
    /// the default limit of 100), and the SVD takes over for a matrix far from well conditioned.
    #[test]
    fn gram_singular_values_match_the_svd() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for n in 0..200 {
            let mut m = Matrix5::from_fn(|_, _| rng.random_range(-1.0..1.0));
            // Shrink one column to spread condition numbers over 1 … 1e9.
            let shrink = 10f64.powf(-(n as f64) * 9.0 / 200.0);
            for r in 0..5 {
                m[(r, 2)] *= shrink;
            }
            let svd = m.singular_values();
            let cond = |s: &[f64]| s.iter().copied().fold(0.0, f64::max) / s.iter().copied().fold(f64::INFINITY, f64::min);
            let want = cond(svd.as_slice());
            let got = cond(&from_gram((m.transpose() * m).symmetric_eigenvalues().as_slice(), || {
                svd.as_slice().to_vec()
            }));
            let tol = 1e-15 * want * want + 1e-13;
            assert!(((got - want) / want).abs() < tol, "condition {got} against the SVD's {want}");
        }
    }
}
