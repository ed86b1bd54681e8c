//! Inverse kinematics on a branch: from each starting point in turn until a solution reaches the
//! target (compensation's check: 1e-6 mm, 1e-8 rad of the commanded task), lies within the
//! limits and is accepted (its configuration).
use crate::compensate::{check_limits, wrap_near};
use crate::error::KinError;
use crate::model::kind::InputSpec;
use crate::model::Mechanism;
use crate::se3::Pose;
use crate::validate::commanded_error;

/// Why no accepted solution was found.
#[derive(Debug)]
pub(super) enum SolveError {
    /// Solutions were found, none on the accepted branch.
    OtherBranch,
    /// None was found: the limit violation met, else the last failure.
    Kin(KinError),
}

/// The first accepted solution from `starts` (revolute values moved by whole turns to the
/// equivalent nearest `reference` within the limits).
pub(super) fn solve(
    model: &dyn Mechanism,
    inputs: &[InputSpec],
    target: &Pose,
    starts: &[Vec<f64>],
    reference: &[f64],
    accept: &dyn Fn(&[f64]) -> bool,
) -> Result<Vec<f64>, SolveError> {
    let n = inputs.len();
    let mut last = KinError::Unreachable("no starting point".into());
    let mut limit: Option<KinError> = None;
    let mut other_branch = false;
    let tries = if model.inverse_ignores_seed() { 1 } else { starts.len() };
    for s in starts.iter().filter(|s| s.len() == n).take(tries) {
        let mut q = match model.inverse(target, Some(s)) {
            Ok(q) => q,
            Err(e) => {
                last = e;
                continue;
            }
        };
        wrap_near(inputs, &mut q, if reference.len() == n { reference } else { s });
        match model.forward(&q).map(|t| commanded_error(model.task(), target, &t)) {
            Ok((dp, dw)) if dp < 1e-6 && dw < 1e-8 => {}
            Ok((dp, dw)) => {
                last = KinError::Unreachable(format!("inverse kinematics ended {dp:.3e} mm / {dw:.3e} rad from the target"));
                continue;
            }
            Err(e) => {
                last = e;
                continue;
            }
        }
        if let Err(e) = check_limits(inputs, &q) {
            limit = Some(e);
            continue;
        }
        if accept(&q) {
            return Ok(q);
        }
        other_branch = true;
    }
    if other_branch {
        return Err(SolveError::OtherBranch);
    }
    Err(SolveError::Kin(match limit.unwrap_or(last) {
        KinError::NoConvergence { residual, .. } => KinError::Unreachable(format!(
            "inverse kinematics found no solution (residual {residual:.3e}); the target is probably outside the workspace"
        )),
        e => e,
    }))
}
