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
//!
//! Without orientation rows (one reflector's positions) nothing holds that path, and the
//! continuation creeps. A tool or reflector offset the start could not see is then searched
//! ([`placements_searched`]): offsets of tool lengths around where the start put it, each with
//! the other parameters fitted again, the best descended by a nested (variable-projection)
//! Gauss–Newton on the offset alone, and a joint fit to finish. The same [`DECISIVE`] test
//! decides.
use super::reduced::{self, Form};
use super::{gauss_newton, sampled_analysis, Identification, Options, Steps};
use crate::error::CalibError;
use crate::identifiability::Identifiability;
use crate::measure::Measurement;
use crate::model::Mechanism;
use nalgebra::DVector;

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
    let seen = match sampled_analysis(&first.model, data, &opts.noise, opts, free) {
        Ok(seen) if seen.rank > first.identifiability.rank => seen,
        _ => return Ok(first),
    };
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
        Steps::MinimumNorm,
    ) else {
        return Ok(first);
    };
    let Ok(b) = gauss_newton(&a.model, data, &stage, free, Some(&first.identifiability.weak), Steps::MinimumNorm) else {
        return Ok(first);
    };
    if !(b.converged && b.sigma0 < DECISIVE * first.sigma0) {
        // The continuation crept: a placement the start could not see is far from where the
        // start put it. Searched with everything else fitted again at each trial.
        return Ok(match placements_searched(&first, &seen, data, opts, free)? {
            Some(out) if out.converged && out.sigma0 < DECISIVE * first.sigma0 => out,
            _ => first,
        });
    }
    let mut out = b;
    out.delta += &first.delta + &a.delta;
    let mut iterations = first.iterations;
    iterations.extend(a.iterations);
    iterations.extend(std::mem::take(&mut out.iterations));
    out.iterations = iterations;
    Ok(out)
}

/// Outer steps of [`placements_searched`], at most.
const OUTER_STEPS: usize = 50;
/// Lengths (mm) of the offsets tried from the start's placement (see [`search_offsets`]).
const SEARCH_RADII: [f64; 4] = [50.0, 100.0, 200.0, 400.0];
/// Iterations of the brief fit at each offset tried.
const SEARCH_ITERATIONS: usize = 30;
/// Up to this many coordinates are searched on a grid of directions; more are descended from
/// the start alone.
const SEARCH_DIMENSIONS: usize = 3;

/// The offsets tried from the start's placement of `k` coordinates: none, and for up to
/// [`SEARCH_DIMENSIONS`] coordinates every direction of the cube's grid (each coordinate −1, 0
/// or 1, not all 0: 26 in three dimensions) at each of [`SEARCH_RADII`].
fn search_offsets(k: usize) -> Vec<Vec<f64>> {
    let mut out = vec![vec![0.0; k]];
    if k == 0 || k > SEARCH_DIMENSIONS {
        return out;
    }
    for code in 1..3usize.pow(k as u32) {
        let d: Vec<f64> = (0..k).map(|i| (code / 3usize.pow(i as u32) % 3) as f64 - 1.0).collect();
        let n = d.iter().map(|v| v * v).sum::<f64>().sqrt();
        if n == 0.0 {
            continue;
        }
        out.extend(SEARCH_RADII.iter().map(|r| d.iter().map(|v| r * v / n).collect()));
    }
    out
}

/// Halvings of an outer step that does not lower the cost, at most.
const HALVINGS: usize = 8;

/// The fit continued where a placement's translation (a tool or reflector offset, an artifact
/// point: a length without a drawn value) was not seen at the start but is where `first`
/// converged: a translating platform's tool offset, seen only through the platform's small
/// turns. The start puts such an offset anywhere along what it could not see (the registration's
/// minimum-norm choice), possibly hundreds of millimetres from the machine's, and a joint
/// Gauss–Newton step cannot reach it: the parameters that follow the offset bend the path
/// (a product of two corrections the linear model leaves out, far above the residual), and the
/// fit creeps. Here the offset is the outer variable of a nested (variable-projection) fit: its
/// step is the offset's part of the joint Gauss–Newton step (the Schur complement of the other
/// parameters), every other free parameter is fitted again at each trial offset, and a trial
/// that does not lower the cost is halved. A final joint fit finishes from there. `None` when no
/// such placement is newly seen, or when nothing lowered the cost.
fn placements_searched<M: Mechanism + Clone>(
    first: &Identification<M>,
    seen: &Identifiability,
    data: &[Measurement],
    opts: &Options,
    free: &[usize],
) -> Result<Option<Identification<M>>, CalibError> {
    let params = first.model.params();
    let held = &first.identifiability.weak;
    let start = &first.identifiability;
    let outer: Vec<usize> = (seen.identifiable.iter().copied())
        .filter(|c| !start.identifiable.contains(c) && !held.contains(c))
        .filter(|&c| params[c].is_placement() && params[c].unit == crate::params::Unit::Length)
        .collect();
    let cols: Vec<usize> = seen.identifiable.iter().copied().filter(|c| !held.contains(c)).collect();
    if outer.is_empty() {
        return Ok(None);
    }
    let inner: Vec<usize> = free.iter().copied().filter(|c| !outer.contains(c)).collect();
    let cost = |m: &M| reduced::evaluate(m, data, &opts.noise, opts.loss).map(|e| e.cost);
    let mut model = first.model.clone();
    let mut now = cost(&model)?;
    let mut delta = first.delta.clone();
    let mut iterations = first.iterations.clone();
    let mut moved = false;
    // Where the start put the placement, and around it at the lengths of tools and
    // reflectors: the best of those, each with the rest fitted briefly, starts the descent.
    let mut best: Option<(M, DVector<f64>, f64)> = None;
    for offset in search_offsets(outer.len()) {
        let mut step = DVector::zeros(first.delta.len());
        for (&c, v) in outer.iter().zip(&offset) {
            step[c] = *v;
        }
        let mut trial = first.model.clone();
        trial.retract(&step);
        let brief = Options {
            max_iterations: SEARCH_ITERATIONS,
            ..opts.clone()
        };
        let Ok(fit) = gauss_newton(&trial, data, &brief, &inner, Some(held), Steps::MinimumNorm) else {
            continue;
        };
        let Ok(c) = cost(&fit.model) else { continue };
        if best.as_ref().is_none_or(|b| c < b.2) {
            best = Some((fit.model, step + fit.delta, c));
        }
    }
    if let Some((m, d, c)) = best.filter(|b| b.2 < now) {
        model = m;
        delta += d;
        now = c;
        moved = true;
    }
    for _ in 0..OUTER_STEPS {
        let ev = reduced::evaluate(&model, data, &opts.noise, opts.loss)?;
        let system = reduced::factor(&model, data, &opts.noise, &ev, Form::Gram)?;
        let joint = system.solve(&cols, 0.0, Some(cols.len()))?;
        let mut step = DVector::zeros(joint.len());
        for &c in &outer {
            step[c] = joint[c];
        }
        let mut taken = None;
        for _ in 0..HALVINGS {
            let mut trial = model.clone();
            trial.retract(&step);
            if let Ok(fit) = gauss_newton(&trial, data, opts, &inner, Some(held), Steps::MinimumNorm) {
                let c = cost(&fit.model)?;
                if c < now {
                    taken = Some((fit, c));
                    break;
                }
            }
            step *= 0.5;
        }
        let Some((fit, c)) = taken else { break };
        let relative = (now - c) / now.max(f64::MIN_POSITIVE);
        delta += &step + &fit.delta;
        iterations.extend(fit.iterations);
        model = fit.model;
        now = c;
        moved = true;
        if relative < 1e-3 || (2.0 * c / ev.residual.len() as f64).sqrt() < EXACT * 1e-3 {
            break;
        }
    }
    if !moved {
        return Ok(None);
    }
    let Ok(mut out) = gauss_newton(&model, data, opts, free, Some(held), Steps::MinimumNorm) else {
        return Ok(None);
    };
    out.delta += &delta;
    iterations.extend(std::mem::take(&mut out.iterations));
    out.iterations = iterations;
    Ok(Some(out))
}
