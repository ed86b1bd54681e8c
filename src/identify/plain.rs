//! A plain fit for ranking poses: [`fit_residuals`].
use super::{free_columns, gauss_newton, Identification, Method, Options, Steps};
use crate::error::CalibError;
use crate::measure::Measurement;
use crate::model::Mechanism;

/// Gauss–Newton alone from `initial` on the free parameters of `opts` (minimum-norm steps,
/// nothing held as seen too weakly, none of [`identify`](super::identify())'s refinements where the fit
/// converged): the residual of the converged geometry, which those refinements change by no more
/// than noise. What a fit needs whose only use is ranking the poses by their residual (the
/// trimmed fits against hidden blunders), at a third of the iterations on hopeless data.
///
/// Errors: as [`identify`](super::identify()).
pub fn fit_residuals<M: Mechanism + Clone>(initial: &M, data: &[Measurement], opts: &Options) -> Result<Identification<M>, CalibError> {
    let free = free_columns(initial, opts)?;
    let plain = Options {
        weak: None,
        method: Method::GaussNewton,
        ..opts.clone()
    };
    gauss_newton(initial, data, &plain, &free, None, Steps::MinimumNorm)
}
