//! Choosing `n` configurations out of `N` candidates: greedy forward search, sequential forward
//! floating search (SFFS) and a Fedorov/DETMAX-like exchange.
//!
//! # How a move is scored
//! * **D and O1** are monotone in `log det M` for sets of equal size, so a move is scored by the
//!   regularised `log det(M + εI)`, for every candidate at once via the matrix determinant lemma:
//!   adding `i` changes it by `log det(I + A_i (M + εI)⁻¹ A_iᵀ)`, removing by
//!   `log det(I − A_i (M + εI)⁻¹ A_iᵀ)`.
//! * **O2–O5** depend on the extreme eigenvalues; evaluating them exactly for each of `N`
//!   candidates would need `N` eigendecompositions per step. Additions are therefore
//!   **screened**: the `shortlist` candidates of largest D-optimality gain (the gain is
//!   `Σ log(1 + μ_j)` over the eigenvalues `μ_j` of `A_i (M + εI)⁻¹ A_iᵀ`, dominated by information
//!   added along the weakest directions of `M`) are evaluated exactly (eigenvalues of
//!   `M + A_iᵀA_i`) and the best of them is taken. Removals (at most `n + 1` members) are always
//!   evaluated exactly.
//!
//! # How it is made fast
//! * **Greedy** runs on all `N` candidates with [`LazyGains`]: D-gains only decrease as the set
//!   grows (submodularity), so stale gains are upper bounds and only the candidates whose bound
//!   beats the current best are brought up to date — by the stored rank-`r` Woodbury factors of
//!   the additions they missed, or from the Cholesky factor of `M + εI`. The result is exactly
//!   the greedy choice (up to round-off in near-ties).
//! * **SFFS and exchange** add *and remove*, which breaks the bounds. On more than
//!   [`SelectOptions::pool`] candidates they first run the greedy pass on all candidates, then
//!   search a **pool**: the greedy set plus the `pool` candidates of largest D-gain with respect
//!   to it ([`candidate_pool`]). Inside the pool every move is a Sherman–Morrison–Woodbury update
//!   of all leverage blocks ([`InformationState`]). The greedy set is returned instead if it is
//!   better, so neither method is ever worse than greedy.
//!
//! # Before full rank
//! Until the set's information matrix has full rank (at least `⌈k/r⌉` configurations) O2–O5 are
//! all zero and cannot rank additions: these first configurations are chosen D-optimally (with the
//! ridge `ε`, [`super::information::DEFAULT_RIDGE`]); [`Selection::warm_up`] says how many.
//!
//! Ties are broken towards the lower candidate index and every parallel reduction is
//! order-independent, so a selection is deterministic (the seed only matters for the exchange's
//! random start).
use super::indices::{Criterion, ObservabilityIndices};
use super::information::{better, InformationState, DEFAULT_REFRESH_EVERY, DEFAULT_RIDGE};
use super::jacobians::{add_gram, CandidateJacobians};
use super::lazy::LazyGains;
use crate::error::CalibError;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

/// Selection algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum SelectionMethod {
    /// Forward selection: add the best candidate until `n` are chosen.
    Greedy,
    /// Sequential forward floating search (Pudil et al.; Fig. 13 of the 5-DOF paper).
    Sffs,
    /// Exchange (Fedorov / DETMAX with excursions of one): add the best candidate, drop the
    /// least useful member, while that improves the index.
    Exchange,
}

impl std::str::FromStr for SelectionMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "greedy" => Ok(SelectionMethod::Greedy),
            "sffs" => Ok(SelectionMethod::Sffs),
            "exchange" | "detmax" | "fedorov" => Ok(SelectionMethod::Exchange),
            _ => Err(format!("unknown selection method '{s}' (expected greedy, sffs or exchange)")),
        }
    }
}

/// Starting set of the exchange method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
pub enum ExchangeStart {
    /// The greedy selection.
    #[default]
    Greedy,
    /// `n` distinct candidates drawn uniformly with this seed.
    Random {
        /// RNG seed.
        seed: u64,
    },
}

/// Options of a selection.
#[derive(Debug, Clone, PartialEq)]
pub struct SelectOptions {
    /// Number of configurations to choose.
    pub n: usize,
    /// Index to maximise.
    pub criterion: Criterion,
    /// Ridge `ε` of the regularised information matrix.
    pub ridge: f64,
    /// Candidates evaluated exactly per addition for O2–O5 (screened by D-optimality gain).
    pub shortlist: usize,
    /// Maximum add/remove moves of SFFS after its greedy pass, and exchange iterations.
    pub max_cycles: usize,
    /// Low-rank updates between exact refreshes of the information state.
    pub refresh_every: usize,
    /// Relative improvement a floating removal or an exchange must bring to be accepted.
    pub tolerance: f64,
    /// Start of the exchange method.
    pub exchange_start: ExchangeStart,
    /// On more candidates than this, SFFS and the exchange search a pool: the greedy (or start)
    /// set plus the `pool` candidates of largest D-optimality gain with respect to it
    /// ([`candidate_pool`]). The greedy pass itself always runs on all candidates.
    pub pool: usize,
}

impl Default for SelectOptions {
    fn default() -> Self {
        SelectOptions {
            n: 30,
            criterion: Criterion::O2,
            ridge: DEFAULT_RIDGE,
            shortlist: 32,
            max_cycles: 200,
            refresh_every: DEFAULT_REFRESH_EVERY,
            tolerance: 1e-9,
            exchange_start: ExchangeStart::Greedy,
            pool: 10_000,
        }
    }
}

/// A move of a selection.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Action {
    /// A configuration was added.
    Add,
    /// A configuration was removed.
    Remove,
}

/// One move, reported to the progress callback and kept in [`Selection::history`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Step {
    /// Added or removed.
    pub action: Action,
    /// Candidate index.
    pub candidate: usize,
    /// Set size after the move.
    pub size: usize,
    /// Score of the set after the move (criterion value; regularised log det for D and O1).
    pub score: f64,
}

/// Result of a selection.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Selection {
    /// Algorithm used.
    pub method: SelectionMethod,
    /// Index maximised.
    pub criterion: Criterion,
    /// Chosen candidates (indices into the candidate set).
    pub selected: Vec<usize>,
    /// Exact indices of the chosen set.
    pub indices: ObservabilityIndices,
    /// Configurations chosen D-optimally before the set reached full rank.
    pub warm_up: usize,
    /// Every move made.
    pub history: Vec<Step>,
}

impl Selection {
    /// The exact value of the criterion reached.
    pub fn value(&self) -> f64 {
        self.indices.value(self.criterion)
    }
}

/// Progress callback, called after every move.
pub type StepFn<'a> = &'a mut dyn FnMut(&Step);

/// Select with `method`.
pub fn select(
    blocks: &CandidateJacobians,
    method: SelectionMethod,
    opts: &SelectOptions,
    progress: StepFn,
) -> Result<Selection, CalibError> {
    match method {
        SelectionMethod::Greedy => greedy(blocks, opts, progress),
        SelectionMethod::Sffs => sffs(blocks, opts, progress),
        SelectionMethod::Exchange => exchange(blocks, opts, progress),
    }
}

fn check(blocks: &CandidateJacobians, opts: &SelectOptions) -> Result<(), CalibError> {
    if opts.n == 0 || opts.n > blocks.len() {
        return Err(CalibError::InvalidOption(format!(
            "cannot choose {} of {} candidates",
            opts.n,
            blocks.len()
        )));
    }
    if opts.shortlist == 0 {
        return Err(CalibError::InvalidOption("shortlist must be at least 1".into()));
    }
    if opts.pool == 0 {
        return Err(CalibError::InvalidOption("pool must be at least 1 candidate".into()));
    }
    let (k, rows) = (blocks.n_columns(), blocks.rows_per_candidate());
    if opts.n * rows < k {
        return Err(CalibError::InvalidOption(format!(
            "{} configurations give {} measurement rows for {k} identifiable parameters: choose at least {}",
            opts.n,
            opts.n * rows,
            k.div_ceil(rows)
        )));
    }
    Ok(())
}

fn new_state<'a>(blocks: &'a CandidateJacobians, set: &[usize], opts: &SelectOptions) -> Result<InformationState<'a>, CalibError> {
    let mut s = InformationState::with_set(blocks, set, opts.ridge)?;
    s.refresh_every = opts.refresh_every.max(1);
    Ok(s)
}

/// Whether the set's information matrix is rank-deficient (O2–O5 are zero).
fn rank_deficient(state: &InformationState) -> bool {
    state.rank_deficient()
}

/// Score of the current set.
fn score(state: &InformationState, c: Criterion) -> f64 {
    if c.is_determinant_based() {
        state.log_det_regularized()
    } else {
        state.indices().value(c)
    }
}

/// The best addition and the score after it; `None` when no candidate is left.
fn best_addition(state: &InformationState, c: Criterion, shortlist: usize) -> Option<(usize, f64)> {
    if c.is_determinant_based() || rank_deficient(state) {
        let (i, g) = state.best_gain()?;
        let s = if c.is_determinant_based() {
            state.log_det_regularized() + g
        } else {
            state.indices_after(Some(i), None).value(c)
        };
        return Some((i, s));
    }
    let top = state.top_gains(shortlist);
    top.par_iter()
        .map(|&(i, _)| (i, state.indices_after(Some(i), None).value(c)))
        .reduce_with(better)
}

/// The member whose removal leaves the best score, and that score.
fn best_removal(state: &InformationState, c: Criterion) -> Option<(usize, f64)> {
    let r = state.blocks().rows_per_candidate();
    state
        .selected()
        .par_iter()
        .map(|&j| {
            let s = if c.is_determinant_based() {
                let g = nalgebra::DMatrix::from_row_slice(r, r, state.leverage(j));
                let s = nalgebra::DMatrix::identity(r, r) - g;
                match s.cholesky() {
                    Some(ch) => state.log_det_regularized() + ch.l().diagonal().iter().map(|d| 2.0 * d.ln()).sum::<f64>(),
                    None => f64::NEG_INFINITY,
                }
            } else {
                state.indices_after(None, Some(j)).value(c)
            };
            (j, s)
        })
        .reduce_with(better)
}

fn improves(new: f64, old: f64, tol: f64) -> bool {
    new.is_finite() && (!old.is_finite() || new > old + tol * old.abs().max(1e-300))
}

fn finish(
    blocks: &CandidateJacobians,
    set: Vec<usize>,
    method: SelectionMethod,
    opts: &SelectOptions,
    warm_up: usize,
    history: Vec<Step>,
) -> Selection {
    let indices = ObservabilityIndices::from_information(&blocks.information(&set), set.len() * blocks.rows_per_candidate());
    Selection {
        method,
        criterion: opts.criterion,
        selected: set,
        indices,
        warm_up,
        history,
    }
}

/// Greedy additions on `state` until it holds `n`; returns the number of warm-up additions.
fn grow(
    state: &mut InformationState,
    opts: &SelectOptions,
    history: &mut Vec<Step>,
    progress: &mut dyn FnMut(&Step),
) -> Result<usize, CalibError> {
    let mut warm = 0;
    while state.selected().len() < opts.n {
        if !opts.criterion.is_determinant_based() && rank_deficient(state) {
            warm += 1;
        }
        let (i, _) = best_addition(state, opts.criterion, opts.shortlist)
            .ok_or_else(|| CalibError::InvalidOption("ran out of candidates".into()))?;
        state.add(i)?;
        let step = Step {
            action: Action::Add,
            candidate: i,
            size: state.selected().len(),
            score: score(state, opts.criterion),
        };
        progress(&step);
        history.push(step);
    }
    Ok(warm)
}

/// Greedy forward selection of `opts.n` configurations, over any number of candidates.
///
/// Each step adds the candidate of best score (see the module docs): the D-optimality gains it
/// needs are found by lazy evaluation ([`LazyGains`], exact thanks to submodularity), so a step
/// usually brings only a fraction of the `N` gains up to date.
pub fn greedy(blocks: &CandidateJacobians, opts: &SelectOptions, progress: StepFn) -> Result<Selection, CalibError> {
    check(blocks, opts)?;
    Ok(greedy_lazy(blocks, opts, progress)?.0)
}

/// The greedy selection and the lazy-gain state it ends in.
fn greedy_lazy<'a>(
    blocks: &'a CandidateJacobians,
    opts: &SelectOptions,
    progress: StepFn,
) -> Result<(Selection, LazyGains<'a>), CalibError> {
    let c = opts.criterion;
    let r = blocks.rows_per_candidate();
    let mut lazy = LazyGains::new(blocks, opts.ridge)?;
    let mut history = Vec::with_capacity(opts.n);
    let mut warm = 0;
    while lazy.selected().len() < opts.n {
        let size = lazy.selected().len();
        let rank_def = lazy.rank_deficient();
        let screened = !c.is_determinant_based() && !rank_def;
        if !c.is_determinant_based() && rank_def {
            warm += 1;
        }
        let top = lazy.top(if screened { opts.shortlist } else { 1 });
        let m = lazy.information();
        let pick = if screened {
            let rows = (size + 1) * r;
            top.par_iter()
                .map(|&(i, _)| {
                    let mut mi = m.clone();
                    add_gram(&mut mi, blocks.block(i), r, 1.0);
                    (i, ObservabilityIndices::from_information(&mi, rows).value(c))
                })
                .reduce_with(better)
        } else {
            top.first().copied()
        };
        let (i, _) = pick.ok_or_else(|| CalibError::InvalidOption("ran out of candidates".into()))?;
        lazy.add(i)?;
        let m = lazy.information();
        let score = if c.is_determinant_based() {
            super::information::inverse_factor(m, opts.ridge)?.1
        } else {
            ObservabilityIndices::from_information(m, (size + 1) * r).value(c)
        };
        let step = Step {
            action: Action::Add,
            candidate: i,
            size: size + 1,
            score,
        };
        progress(&step);
        history.push(step);
    }
    let set = lazy.selected().to_vec();
    Ok((finish(blocks, set, SelectionMethod::Greedy, opts, warm, history), lazy))
}

/// The candidate pool of the floating and exchange searches on a large set: the `size`
/// candidates of largest D-optimality gain with respect to the design `base` (the greedy or
/// start set), together with `base` itself, in increasing index order.
pub fn candidate_pool(blocks: &CandidateJacobians, base: &[usize], size: usize, ridge: f64) -> Result<Vec<usize>, CalibError> {
    if size >= blocks.len() {
        return Ok((0..blocks.len()).collect());
    }
    let mut lazy = LazyGains::new(blocks, ridge)?;
    for &i in base {
        lazy.add(i)?;
    }
    Ok(pool_from(&mut lazy, size))
}

/// The pool of [`candidate_pool`] from a lazy-gain state whose design is the base set.
fn pool_from(lazy: &mut LazyGains, size: usize) -> Vec<usize> {
    let mut pool: Vec<usize> = lazy.top(size).into_iter().map(|p| p.0).collect();
    pool.extend_from_slice(lazy.selected());
    pool.sort_unstable();
    pool.dedup();
    pool
}

/// Sequential forward floating search (Pudil et al. 1994, Fig. 13 of the 5-DOF paper).
///
/// SFFS keeps, for every set size `s`, the best set of that size seen so far. It alternates an
/// **inclusion** (add the best candidate) with **conditional exclusions**: the member whose
/// removal leaves the best index is removed (and exclusions repeated) only while the reduced set
/// beats the best set recorded for its size and the member is not the one just added. It stops
/// when the set has `n` members and no exclusion is accepted, and returns the best set of size
/// `n` seen. Every accepted exclusion strictly improves an entry of the table, which guarantees
/// termination; `max_cycles` bounds the moves as well (the set is then completed greedily).
///
/// Until the first accepted exclusion SFFS walks the greedy path. kinecal keeps the set just
/// before that exclusion and, at the end, completes it greedily to `n` (which reproduces the plain
/// greedy selection): the better of that and SFFS's own set is returned, so SFFS is never worse
/// than greedy.
pub fn sffs(blocks: &CandidateJacobians, opts: &SelectOptions, progress: StepFn) -> Result<Selection, CalibError> {
    check(blocks, opts)?;
    if blocks.len() <= opts.pool {
        return sffs_full(blocks, opts, progress);
    }
    let (g, mut lazy) = greedy_lazy(blocks, opts, progress)?;
    let pool = pool_from(&mut lazy, opts.pool);
    drop(lazy);
    let sub = blocks.subset(&pool);
    let inner = sffs_full(&sub, opts, &mut |s| progress(&remap(s, &pool)))?;
    Ok(merge_pooled(blocks, g, inner, &pool, SelectionMethod::Sffs, opts))
}

/// A step of a pooled search in the indices of the full candidate set.
fn remap(s: &Step, pool: &[usize]) -> Step {
    Step {
        candidate: pool[s.candidate],
        ..*s
    }
}

/// The result of a search on a pool, mapped back to the full set; the greedy set `g` if it is
/// better.
fn merge_pooled(
    blocks: &CandidateJacobians,
    g: Selection,
    inner: Selection,
    pool: &[usize],
    method: SelectionMethod,
    opts: &SelectOptions,
) -> Selection {
    let mut history = g.history.clone();
    history.extend(inner.history.iter().map(|s| remap(s, pool)));
    let set: Vec<usize> = if inner.value() >= g.value() {
        inner.selected.iter().map(|&i| pool[i]).collect()
    } else {
        g.selected.clone()
    };
    finish(blocks, set, method, opts, g.warm_up, history)
}

fn sffs_full(blocks: &CandidateJacobians, opts: &SelectOptions, progress: StepFn) -> Result<Selection, CalibError> {
    let c = opts.criterion;
    let mut state = new_state(blocks, &[], opts)?;
    let mut history = Vec::new();
    // best[s] = (score, set) of the best set of size s.
    let mut best: Vec<(f64, Vec<usize>)> = vec![(f64::NEG_INFINITY, Vec::new()); opts.n + 1];
    let mut last_added = None;
    let mut cycles = 0;
    let mut warm = 0;
    let mut greedy_prefix: Option<Vec<usize>> = None;
    loop {
        if state.selected().len() < opts.n {
            if cycles >= opts.max_cycles {
                break;
            }
            if !c.is_determinant_based() && rank_deficient(&state) {
                warm += 1;
            }
            let Some((x, _)) = best_addition(&state, c, opts.shortlist) else {
                break;
            };
            state.add(x)?;
            cycles += 1;
            last_added = Some(x);
            let size = state.selected().len();
            let s = score(&state, c);
            if improves(s, best[size].0, 0.0) {
                best[size] = (s, state.selected().to_vec());
            }
            let step = Step {
                action: Action::Add,
                candidate: x,
                size,
                score: s,
            };
            progress(&step);
            history.push(step);
        }
        let mut excluded = false;
        while state.selected().len() > 1 && cycles < opts.max_cycles {
            let Some((x, s)) = best_removal(&state, c) else { break };
            let size = state.selected().len() - 1;
            if Some(x) == last_added || !improves(s, best[size].0, opts.tolerance) {
                break;
            }
            if greedy_prefix.is_none() {
                greedy_prefix = Some(state.selected().to_vec());
            }
            state.remove(x)?;
            cycles += 1;
            last_added = None;
            excluded = true;
            best[size] = (s, state.selected().to_vec());
            let step = Step {
                action: Action::Remove,
                candidate: x,
                size,
                score: s,
            };
            progress(&step);
            history.push(step);
        }
        if state.selected().len() >= opts.n && !excluded {
            break;
        }
    }
    // Out of moves before reaching n: complete greedily.
    if state.selected().len() < opts.n {
        let mut tail = Vec::new();
        grow(&mut state, opts, &mut tail, progress)?;
        history.extend(tail);
        let s = score(&state, c);
        if improves(s, best[opts.n].0, 0.0) {
            best[opts.n] = (s, state.selected().to_vec());
        }
    }
    // The greedy set (SFFS's own path up to its first exclusion, completed greedily).
    if let Some(prefix) = greedy_prefix {
        let mut g = new_state(blocks, &prefix, opts)?;
        grow(&mut g, opts, &mut Vec::new(), &mut |_| {})?;
        let s = score(&g, c);
        if improves(s, best[opts.n].0, 0.0) {
            best[opts.n] = (s, g.selected().to_vec());
        }
    }
    let set = best[opts.n].1.clone();
    Ok(finish(blocks, set, SelectionMethod::Sffs, opts, warm, history))
}

/// Exchange method: from the start set (greedy, or seeded random), repeatedly add the best
/// candidate and remove the member whose removal leaves the best index, while that strictly
/// improves the index (a DETMAX excursion of one; for D-optimality this is Fedorov's exchange
/// restricted to the best addition). Stops when the removed member is the one just added, when
/// the exchange does not improve, or after `max_cycles` exchanges.
pub fn exchange(blocks: &CandidateJacobians, opts: &SelectOptions, progress: StepFn) -> Result<Selection, CalibError> {
    check(blocks, opts)?;
    let large = blocks.len() > opts.pool;
    let (start, pool) = match opts.exchange_start {
        ExchangeStart::Greedy => {
            let (g, mut lazy) = greedy_lazy(blocks, opts, progress)?;
            let pool = if large {
                pool_from(&mut lazy, opts.pool)
            } else {
                (0..blocks.len()).collect()
            };
            (g, pool)
        }
        ExchangeStart::Random { seed } => {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut set = Vec::with_capacity(opts.n);
            let mut taken = std::collections::HashSet::new();
            while set.len() < opts.n {
                let i = rng.random_range(0..blocks.len());
                if taken.insert(i) {
                    set.push(i);
                }
            }
            let pool = if large {
                candidate_pool(blocks, &set, opts.pool, opts.ridge)?
            } else {
                (0..blocks.len()).collect()
            };
            (finish(blocks, set, SelectionMethod::Exchange, opts, 0, Vec::new()), pool)
        }
    };
    let sub = blocks.subset(&pool);
    let local_start: Vec<usize> = start
        .selected
        .iter()
        .map(|i| pool.binary_search(i).expect("the start set is in the pool"))
        .collect();
    let inner = exchange_from(&sub, local_start, opts, &mut |s| progress(&remap(s, &pool)))?;
    Ok(merge_pooled(blocks, start, inner, &pool, SelectionMethod::Exchange, opts))
}

fn exchange_from(blocks: &CandidateJacobians, start: Vec<usize>, opts: &SelectOptions, progress: StepFn) -> Result<Selection, CalibError> {
    let c = opts.criterion;
    let mut history = Vec::new();
    let mut state = new_state(blocks, &start, opts)?;
    let mut current = score(&state, c);
    for _ in 0..opts.max_cycles {
        // A rank-deficient random start is repaired D-optimally first.
        let crit = if !c.is_determinant_based() && rank_deficient(&state) {
            Criterion::DOptimal
        } else {
            c
        };
        if crit != c {
            current = state.log_det_regularized();
        }
        let Some((plus, _)) = best_addition(&state, crit, opts.shortlist) else {
            break;
        };
        state.add(plus)?;
        let (minus, s) = best_removal(&state, crit).expect("the set is not empty");
        if minus == plus || !improves(s, current, opts.tolerance) {
            state.remove(plus)?;
            break;
        }
        state.remove(minus)?;
        current = score(&state, c);
        for (action, candidate, size) in [(Action::Add, plus, opts.n + 1), (Action::Remove, minus, opts.n)] {
            let step = Step {
                action,
                candidate,
                size,
                score: current,
            };
            progress(&step);
            history.push(step);
        }
    }
    let set = state.selected().to_vec();
    Ok(finish(blocks, set, SelectionMethod::Exchange, opts, 0, history))
}
