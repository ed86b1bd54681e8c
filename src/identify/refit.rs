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
//!
//! Where the data are far cleaner than their stated noise and neither continuation is decisive,
//! the rank is analysed once more at the converged geometry with a finer tolerance
//! ([`seen_more_finely`]): parameters seen there only through the product of two small errors
//! (a rail's tilt where the start's platform only translates) are descended the same nested way
//! and the fit finished on the identifiable subset. The same test decides.
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
    // A geometry where nothing new is seen, or one the model no longer evaluates at every pose,
    // goes on to the finer analysis (then the first fit stands unless that one is decisive).
    if let Ok(seen) = sampled_analysis(&first.model, data, &opts.noise, opts, free) {
        if seen.rank > first.identifiability.rank {
            if let Some(out) = continued(&first, &seen, data, opts, free)? {
                return Ok(out);
            }
        }
    }
    Ok(match seen_more_finely(&first, data, opts, free)? {
        Some(out) => out,
        None => first,
    })
}

/// The continuation of `first` on the set `seen` finds at its geometry, when it fits
/// [`DECISIVE`]ly better: minimum-norm stages (orientation rows pinned, then as stated), else
/// the search of a placement the start could not see ([`placements_searched`]).
fn continued<M: Mechanism + Clone>(
    first: &Identification<M>,
    seen: &Identifiability,
    data: &[Measurement],
    opts: &Options,
    free: &[usize],
) -> Result<Option<Identification<M>>, CalibError> {
    let mut stage = opts.clone();
    stage.max_iterations = stage.max_iterations.min(STAGE_ITERATIONS);
    let mut pinned = stage.clone();
    pinned.noise.orientation /= ORIENTATION_WEIGHT;
    let weak = &first.identifiability.weak;
    let Ok(a) = gauss_newton(&first.model, data, &pinned, free, Some(weak), Steps::MinimumNorm) else {
        return Ok(None);
    };
    let Ok(b) = gauss_newton(&a.model, data, &stage, free, Some(weak), Steps::MinimumNorm) else {
        return Ok(None);
    };
    if !decisive(first, &b) {
        // The continuation crept: a placement the start could not see is far from where the
        // start put it. Searched with everything else fitted again at each trial.
        return Ok(placements_searched(first, seen, data, opts, free)?.filter(|f| decisive(first, f)));
    }
    let mut out = b;
    out.delta += &first.delta + &a.delta;
    let mut iterations = first.iterations.clone();
    iterations.extend(a.iterations);
    iterations.extend(std::mem::take(&mut out.iterations));
    out.iterations = iterations;
    Ok(Some(out))
}

/// Whether `f` explains the data [`DECISIVE`]ly better than `first`.
fn decisive<M: Mechanism>(first: &Identification<M>, f: &Identification<M>) -> bool {
    f.converged && f.sigma0 < DECISIVE * first.sigma0
}

/// The identifiable parameters of `seen` not held as seen too weakly (`held`).
fn unheld(seen: &Identifiability, held: &[usize]) -> Vec<usize> {
    seen.identifiable.iter().copied().filter(|c| !held.contains(c)).collect()
}

/// The relative rank tolerance of [`seen_more_finely`]: singular values of the column-scaled
/// Jacobian this far below the largest are still far above round-off (its orthogonal factor
/// puts exactly redundant directions at 3e-15 of the largest and below: the 3T1R machine's start).
const FINE_RANK_TOLERANCE: f64 = 1e-10;
/// [`seen_more_finely`] runs on a first fit whose σ̂₀ is below this: data far cleaner than their
/// stated noise. A fit at the noise cannot become [`DECISIVE`]ly better.
const FINE_BELOW: f64 = 1e-2;

/// The continuation of `first` on the parameters its geometry shows at [`FINE_RANK_TOLERANCE`]
/// rather than at the stated rank tolerance, when it fits [`DECISIVE`]ly better. Parameters
/// that act at second order only at the start are seen where the fit converged with singular
/// values far below the stated tolerance, yet they are what is left of a fit to data cleaner
/// than their noise. On the whole 3T1R machine measured by one reflector in a far frame, the
/// tilts and the shift of rail 3 (`b3.0-1.wy`, `wz`, `vx`) are redundant at the start (rank 35)
/// and seen where the first fit converged: the 36th and 37th singular values are 3.3e-6 and
/// 2.8e-8 of the largest (the 38th 5e-13). Those newly seen parameters are the outer variables
/// of a nested fit ([`Nested`]; its joint step from the orthogonal factor: `AᵀA` squares the
/// singular values, and the 37th would sit at 8e-16 of the largest, at round-off), and
/// Gauss–Newton on the identifiable subset of the geometry it reaches, in priority order,
/// finishes. Gauss–Newton on the larger set straight from the first fit creeps there
/// (minimum-norm steps: σ̂₀ 3.1e-4 → 4.6e-5 in 100 iterations; on the subset: 2.0e-5 in 300),
/// the directions redundant to first order bending the path more than the weakly seen ones move
/// it.
fn seen_more_finely<M: Mechanism + Clone>(
    first: &Identification<M>,
    data: &[Measurement],
    opts: &Options,
    free: &[usize],
) -> Result<Option<Identification<M>>, CalibError> {
    if first.sigma0 >= FINE_BELOW {
        return Ok(None);
    }
    let fine = Options {
        rank_tolerance: FINE_RANK_TOLERANCE,
        ..opts.clone()
    };
    let weak = &first.identifiability.weak;
    let Ok(seen) = sampled_analysis(&first.model, data, &opts.noise, &fine, free) else {
        return Ok(None);
    };
    let kept = unheld(&seen, weak);
    if kept.len() <= first.identifiability.identifiable.len() {
        return Ok(None);
    }
    let start = &first.identifiability.identifiable;
    let outer: Vec<usize> = kept.iter().copied().filter(|c| !start.contains(c)).collect();
    let nested = Nested {
        data,
        opts,
        held: weak,
        inner: free.iter().copied().filter(|c| !outer.contains(c)).collect(),
        outer,
        cols: kept,
        form: Form::Triangular,
    };
    let now = nested.cost(&first.model)?;
    let Some((model, delta, iterations)) = nested.descend(first.model.clone(), now)? else {
        return Ok(None);
    };
    let Ok(seen) = sampled_analysis(&model, data, &opts.noise, &fine, free) else {
        return Ok(None);
    };
    let kept = unheld(&seen, weak);
    let Ok(mut out) = gauss_newton(&model, data, opts, free, Some(weak), Steps::Subset(&kept)) else {
        return Ok(None);
    };
    out.delta += &delta;
    let mut all = first.iterations.clone();
    all.extend(iterations);
    all.append(&mut out.iterations);
    out.iterations = all;
    if !decisive(first, &out) {
        return Ok(None);
    }
    out.delta += &first.delta;
    Ok(Some(out))
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
    let cols = unheld(seen, held);
    if outer.is_empty() {
        return Ok(None);
    }
    let nested = Nested {
        data,
        opts,
        held,
        inner: free.iter().copied().filter(|c| !outer.contains(c)).collect(),
        outer,
        cols,
        form: Form::Gram,
    };
    let mut model = first.model.clone();
    let mut now = nested.cost(&model)?;
    let mut delta = first.delta.clone();
    let mut iterations = first.iterations.clone();
    let mut moved = false;
    // Where the start put the placement, and around it at the lengths of tools and
    // reflectors: the best of those, each with the rest fitted briefly, starts the descent.
    let mut best: Option<(M, DVector<f64>, f64)> = None;
    for offset in search_offsets(nested.outer.len()) {
        let mut step = DVector::zeros(first.delta.len());
        for (&c, v) in nested.outer.iter().zip(&offset) {
            step[c] = *v;
        }
        let mut trial = first.model.clone();
        trial.retract(&step);
        let brief = Options {
            max_iterations: SEARCH_ITERATIONS,
            ..opts.clone()
        };
        let Ok(fit) = gauss_newton(&trial, data, &brief, &nested.inner, Some(held), Steps::MinimumNorm) else {
            continue;
        };
        let Ok(c) = nested.cost(&fit.model) else { continue };
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
    if let Some((m, d, its)) = nested.descend(model.clone(), now)? {
        model = m;
        delta += d;
        iterations.extend(its);
        moved = true;
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

/// A nested (variable-projection) fit: the `outer` parameters step, every `inner` one is fitted
/// again at each trial.
struct Nested<'a> {
    data: &'a [Measurement],
    opts: &'a Options,
    /// Held as seen too weakly.
    held: &'a [usize],
    outer: Vec<usize>,
    inner: Vec<usize>,
    /// The identifiable columns of the joint step whose `outer` part is the outer step.
    cols: Vec<usize>,
    /// The joint step from the normal equations, or from an orthogonal factor (directions seen
    /// with singular values far below the largest are resolved there, not in `AᵀA`).
    form: Form,
}

impl Nested<'_> {
    fn cost<M: Mechanism>(&self, m: &M) -> Result<f64, CalibError> {
        reduced::evaluate(m, self.data, &self.opts.noise, self.opts.loss).map(|e| e.cost)
    }

    /// Outer steps from `model` (cost `now`): each the outer part of the joint Gauss–Newton
    /// step (the Schur complement of the inner parameters), the inner ones fitted again at the
    /// trial, halved while it does not lower the cost. The model reached, the change and the
    /// iterations, or `None` when no step lowered the cost.
    #[allow(clippy::type_complexity)]
    fn descend<M: Mechanism + Clone>(
        &self,
        mut model: M,
        mut now: f64,
    ) -> Result<Option<(M, DVector<f64>, Vec<super::Iteration>)>, CalibError> {
        let (data, opts) = (self.data, self.opts);
        let mut delta = DVector::zeros(model.n_params());
        let mut iterations = Vec::new();
        let mut moved = false;
        for _ in 0..OUTER_STEPS {
            let ev = reduced::evaluate(&model, data, &opts.noise, opts.loss)?;
            let system = reduced::factor(&model, data, &opts.noise, &ev, self.form)?;
            let joint = system.solve(&self.cols, 0.0, Some(self.cols.len()))?;
            let mut step = DVector::zeros(joint.len());
            for &c in &self.outer {
                step[c] = joint[c];
            }
            let mut taken = None;
            for _ in 0..HALVINGS {
                let mut trial = model.clone();
                trial.retract(&step);
                if let Ok(fit) = gauss_newton(&trial, data, opts, &self.inner, Some(self.held), Steps::MinimumNorm) {
                    let c = self.cost(&fit.model)?;
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
        Ok(moved.then_some((model, delta, iterations)))
    }
}
