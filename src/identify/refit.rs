//! A second fit where the first converged at a geometry that sees more than its start did.
//!
//! The rank is decided once, at the start, and every step is truncated there. Where the start is
//! a special geometry (a platform that only translates, axes exactly parallel), some parameters
//! act there at second order only and are set aside, although the machine the data come from
//! shows them (a tool offset seen through the small turns of a linear delta's platform). Once
//! the fit has converged, the rank is analysed again at its geometry; where it is larger there,
//! the fit is continued on the larger set: first with the orientation rows weighted
//! [`ORIENTATION_WEIGHT`] times more (the measured turns then hold the path out of the curved
//! valley along which the tool offset and the turns trade), then with the stated weights. The
//! continuation replaces the first fit only when it explains the data [`DECISIVE`] times
//! better: a fit the first could not reach, never noise fitted into weakly seen directions.
use super::{gauss_newton, sampled_analysis, Identification, Options};
use crate::error::CalibError;
use crate::measure::Measurement;
use crate::model::Mechanism;

/// A first fit with σ̂₀ at or below this is exact already.
const EXACT: f64 = 1e-6;
/// The continuation must lower σ̂₀ by this factor to replace the first fit.
const DECISIVE: f64 = 1e-3;
/// How much more the orientation rows weigh in the intermediate fit.
const ORIENTATION_WEIGHT: f64 = 100.0;
/// Iterations of each stage of the continuation, at most (a fit it can make exact takes a few
/// dozen; one that creeps would not become decisive in hundreds either).
const STAGE_ITERATIONS: usize = 100;

/// `first`, or its continuation on the larger identifiable set of its own geometry when that
/// fits decisively better (see the [module docs](self)). Extra starts (`opts.agree_with`) and
/// exact fits are returned as they are.
pub(super) fn refit_where_more_is_seen<M: Mechanism + Clone>(
    first: Identification<M>,
    data: &[Measurement],
    opts: &Options,
    free: &[usize],
) -> Result<Identification<M>, CalibError> {
    if opts.agree_with.is_some() || !first.converged || first.sigma0 <= EXACT {
        return Ok(first);
    }
    // A geometry where nothing new is seen, or one the model no longer evaluates at every pose
    // (then the first fit stands), ends here.
    match sampled_analysis(&first.model, data, &opts.noise, opts, free) {
        Ok(seen) if seen.rank > first.identifiability.rank => {}
        _ => return Ok(first),
    }
    let mut stage = opts.clone();
    stage.max_iterations = stage.max_iterations.min(STAGE_ITERATIONS);
    let mut pinned = stage.clone();
    pinned.noise.orientation /= ORIENTATION_WEIGHT;
    let Ok(a) = gauss_newton(
        &first.model,
        data,
        &pinned,
        free,
        Some(&first.identifiability.weak),
        super::Steps::MinimumNorm,
    ) else {
        return Ok(first);
    };
    let Ok(b) = gauss_newton(
        &a.model,
        data,
        &stage,
        free,
        Some(&first.identifiability.weak),
        super::Steps::MinimumNorm,
    ) else {
        return Ok(first);
    };
    if !(b.converged && b.sigma0 < DECISIVE * first.sigma0) {
        return Ok(first);
    }
    let mut out = b;
    out.delta += &first.delta + &a.delta;
    let mut iterations = first.iterations;
    iterations.extend(a.iterations);
    iterations.extend(std::mem::take(&mut out.iterations));
    out.iterations = iterations;
    Ok(out)
}
