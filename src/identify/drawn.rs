//! What the fit holds as drawn, decided where it converged: the parameters seen too weakly
//! ([`super::weakly_seen`], decided again with the noise the fit shows) and the redundant ones
//! (back to their drawn values, the identifiable subset taking up their share).
use super::{gauss_newton, refit, sampled_analysis, solve, weak, weakly_seen, Identification, Options, Steps};
use crate::error::CalibError;
use crate::measure::Measurement;
use crate::model::Mechanism;
use nalgebra::DVector;

/// Gauss–Newton from `initial` on `free` with [`Options::gauge`] held as drawn ([`fitted`]),
/// unless holding it explains the data worse than noise can against the same fit with it free
/// ([`costs_more_than_noise`]): then the gauge was no pure gauge at this geometry, and the free
/// fit stands.
pub(super) fn fitted_with_gauge<M: Mechanism + Clone>(
    initial: &M,
    data: &[Measurement],
    opts: &Options,
    free: &[usize],
) -> Result<Identification<M>, CalibError> {
    let gauge: Vec<usize> = opts.gauge.iter().copied().filter(|c| free.contains(c)).collect();
    if gauge.is_empty() {
        return fitted(initial, data, opts, free);
    }
    let placed: Vec<usize> = free.iter().copied().filter(|c| !gauge.contains(c)).collect();
    let mut held = fitted(initial, data, opts, &placed)?;
    let freed = fitted(initial, data, opts, free)?;
    Ok(if costs_more_than_noise(&held, &freed, data, gauge.len()) {
        freed
    } else {
        held.identifiability.gauge = gauge;
        held
    })
}

/// Gauss–Newton from `initial` on `free`, the weak directions decided again where it converged,
/// refitted where more is seen there, and the redundant parameters back as drawn.
fn fitted<M: Mechanism + Clone>(
    initial: &M,
    data: &[Measurement],
    opts: &Options,
    free: &[usize],
) -> Result<Identification<M>, CalibError> {
    let fit = gauss_newton(initial, data, opts, free, None, Steps::MinimumNorm)?;
    let fit = weak_decided_again(fit, initial, data, opts, free)?;
    let fit = refit::refit_where_more_is_seen(fit, data, opts, free)?;
    redundant_as_drawn(fit, data, opts, free)
}

/// Rounds of deciding again, where the fit converged, which parameters are seen too weakly.
const WEAK_ROUNDS: usize = 3;

/// `fit` (from `initial`) fitted again until the parameters held as seen too weakly no longer
/// change: decided where the fit converged with the noise it shows, released where that fit
/// shows them beyond its noise ([`weak::seen_beyond_noise`]). Without [`Options::weak`], or for
/// an extra start ([`Options::agree_with`]), `fit` as it is.
pub(super) fn weak_decided_again<M: Mechanism + Clone>(
    mut fit: Identification<M>,
    initial: &M,
    data: &[Measurement],
    opts: &Options,
    free: &[usize],
) -> Result<Identification<M>, CalibError> {
    // Decided again where the fit converged, with the noise it shows: a direction that
    // became visible is freed, one that became too weak is held (from the start, so that
    // it stays as drawn).
    if let Some(hold) = opts.weak.as_ref().filter(|_| opts.agree_with.is_none()) {
        // Released once, a parameter stays free: the fit it then reaches shows it.
        let mut released: Vec<usize> = Vec::new();
        for _ in 0..WEAK_ROUNDS {
            let id = &fit.identifiability;
            let candidates: Vec<usize> = (free.iter().copied())
                .filter(|c| id.identifiable.contains(c) || id.weak.contains(c))
                .collect();
            let mut now = weakly_seen(&fit.information, &candidates, hold, fit.sigma0);
            now.retain(|c| !released.contains(c));
            let kept: Vec<usize> = candidates.iter().copied().filter(|c| !now.contains(c)).collect();
            if weak::seen_beyond_noise(&fit.model, data, opts, &fit.noise, &kept, &now, fit.sigma0)? {
                released.append(&mut now);
            }
            if now == id.weak {
                break;
            }
            // From the start again: newly held parameters are then as drawn, and a
            // released one is fitted with the rest (continuing from the held fit's
            // geometry can creep along the curved valley the hold left).
            fit = gauss_newton(initial, data, opts, free, Some(&now), Steps::MinimumNorm)?;
        }
        if !fit.identifiability.weak.is_empty() {
            return seen_when_freed(fit, initial, data, opts, free);
        }
    }
    Ok(fit)
}

/// The held fit `held`, or the fit with nothing held as seen too weakly where that one
/// explains the data better than noise can: the rise of the weighted cost `|r|²` the hold
/// brings, against the χ² bound of [`weak::RELEASE_Z`] for as many degrees of freedom as held
/// parameters, in units of the free fit's σ̂₀². The comparison of the two converged fits (not
/// of a linear prediction at one of them) lets curved valleys and data cleaner than their
/// stated noise (a simulation) free what they show; noise alone frees nothing.
fn seen_when_freed<M: Mechanism + Clone>(
    held: Identification<M>,
    initial: &M,
    data: &[Measurement],
    opts: &Options,
    free: &[usize],
) -> Result<Identification<M>, CalibError> {
    let unheld = Options {
        weak: None,
        ..opts.clone()
    };
    let Ok(freed) = gauss_newton(initial, data, &unheld, free, None, Steps::MinimumNorm) else {
        return Ok(held);
    };
    let k = held.identifiability.weak.len();
    Ok(if costs_more_than_noise(&held, &freed, data, k) {
        freed
    } else {
        held
    })
}

/// Whether `held` (a fit with `k` parameters held) explains `data` worse than `freed` (the same
/// with them free, converged) by more than noise can: the rise of the weighted cost `|r|²`
/// beyond the χ² bound of [`weak::RELEASE_Z`] for `k` degrees of freedom, in units of the
/// freed fit's σ̂₀².
pub(super) fn costs_more_than_noise<M>(held: &Identification<M>, freed: &Identification<M>, data: &[Measurement], k: usize) -> bool {
    let rows = rows_of(data) as f64;
    let cost = |f: &Identification<M>| f.sigma0.powi(2) * (rows - f.identifiability.identifiable.len() as f64).max(1.0);
    freed.converged && cost(held) - cost(freed) > weak::chi2_bound(k) * freed.sigma0.powi(2)
}

/// `fit` with its redundant parameters back as drawn. Minimum-norm steps share each redundant
/// direction among the parameters that act alike, so a parameter the analysis calls redundant
/// (the last link, where the reflector's offset takes up the same) would come out moved. At the
/// converged geometry, the identifiable subset in priority order takes up the redundant
/// parameters' share (the linear move that keeps the predictions), they go back to their drawn
/// values, and Gauss–Newton on that subset alone finishes from there. The held fit replaces
/// `fit` unless it explains the data worse (then `fit` stands).
pub(super) fn redundant_as_drawn<M: Mechanism + Clone>(
    fit: Identification<M>,
    data: &[Measurement],
    opts: &Options,
    free: &[usize],
) -> Result<Identification<M>, CalibError> {
    // The start's identifiable subset, or, where the converged geometry no longer sees it
    // (a special start: parallel axes, a platform that only translates), that geometry's own
    // in priority order.
    let weak = fit.identifiability.weak.clone();
    let start: Vec<usize> = fit.identifiability.identifiable.clone();
    let fit = match held_from(fit, &start, data, opts, free)? {
        Ok(held) => return Ok(held),
        Err(fit) => fit,
    };
    let Ok(at) = sampled_analysis(&fit.model, data, &fit.noise, opts, free) else {
        return Ok(fit);
    };
    let kept: Vec<usize> = at.identifiable.iter().copied().filter(|c| !weak.contains(c)).collect();
    if kept == start {
        return Ok(fit);
    }
    Ok(match held_from(fit, &kept, data, opts, free)? {
        Ok(held) => held,
        Err(fit) => fit,
    })
}

/// [`redundant_as_drawn`] on the identifiable subset `kept`: the held fit, or `fit` back when
/// it explains the data worse or cannot be had.
#[allow(clippy::type_complexity)]
fn held_from<M: Mechanism + Clone>(
    fit: Identification<M>,
    kept: &[usize],
    data: &[Measurement],
    opts: &Options,
    free: &[usize],
) -> Result<Result<Identification<M>, Identification<M>>, CalibError> {
    let weak = &fit.identifiability.weak;
    let moved: Vec<usize> = (free.iter().copied())
        .filter(|&c| !kept.contains(&c) && !weak.contains(&c) && fit.delta[c] != 0.0)
        .collect();
    if moved.is_empty() || kept.is_empty() {
        return Ok(Err(fit));
    }
    let p = fit.model.n_params();
    let mut back = DVector::zeros(p);
    for &c in &moved {
        back[c] = fit.delta[c];
    }
    let n = &fit.information;
    let Ok(mut shift) = solve::solve_gram(n, &(n * &back), kept, 0.0, Some(kept.len())) else {
        return Ok(Err(fit));
    };
    for &c in &moved {
        shift[c] = -fit.delta[c];
    }
    let mut model = fit.model.clone();
    model.retract(&shift);
    let held = gauss_newton(&model, data, opts, free, Some(weak), Steps::Subset(kept));
    let Ok(mut held) = held else {
        return Ok(Err(fit));
    };
    // As good as `fit`: within round-off, or within what noise alone gives for as many
    // parameters as were put back (the hold costs nothing the data can show).
    let dof = (rows_of(data) as f64 - kept.len() as f64).max(1.0);
    let cost_rise = (held.sigma0.powi(2) - fit.sigma0.powi(2)) * dof;
    let as_good = held.sigma0 <= fit.sigma0 * (1.0 + 1e-6) + 1e-9 || cost_rise <= weak::chi2_bound(moved.len()) * fit.sigma0.powi(2);
    if !(held.converged && as_good) {
        return Ok(Err(fit));
    }
    held.delta += &fit.delta + &shift;
    let mut iterations = fit.iterations;
    iterations.append(&mut held.iterations);
    held.iterations = iterations;
    Ok(Ok(held))
}

/// Residual rows of `data`.
fn rows_of(data: &[Measurement]) -> usize {
    data.iter().map(|m| m.obs.rows() + m.joints.len()).sum()
}
