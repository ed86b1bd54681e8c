//! Lazy evaluation of D-optimality gains for forward selection over very large candidate sets.
//!
//! The gain of candidate `i`, `log det(I + G_i)` with `G_i = A_i (M + εI)⁻¹ A_iᵀ`, can only
//! **decrease** when configurations are added (`M` grows in the positive semidefinite order, so
//! `(M + εI)⁻¹` shrinks): `log det` is submodular. A gain computed at an earlier step is therefore
//! an upper bound at every later step of a forward search. To find the best `need` candidates,
//! gains are brought up to date in parallel batches of the largest bounds until the `need`-th
//! best current gain exceeds every remaining bound: the answer is exactly the one a full
//! evaluation would give, usually after evaluating a fraction of the candidates.
//!
//! Bringing a candidate up to date reuses its last leverage block `G_i`: every addition `t` is
//! stored as its Woodbury factor `U_t` (`k × r`, `P_{t+1} = P_t − U_t U_tᵀ`), and a block that
//! missed a few additions is updated by `G_i ← G_i − (A_i U_t)(A_i U_t)ᵀ` (`r²k` operations
//! each); a block that missed many is recomputed from the Cholesky factor of `M + εI`
//! (`r k²/2`).
use super::indices::ObservabilityIndices;
use super::information::{exact_one, inverse_factor, log_det_identity_plus, low_rank_one};
use super::jacobians::{add_gram, CandidateJacobians};
use crate::error::CalibError;
use nalgebra::DMatrix;
use rayon::prelude::*;

/// A forward search's design and the (possibly stale) gains of all candidates.
#[derive(Debug, Clone)]
pub struct LazyGains<'a> {
    blocks: &'a CandidateJacobians,
    ridge: f64,
    m: DMatrix<f64>,
    /// `P = (M + εI)⁻¹ = F Fᵀ`, `F` upper triangular row-major.
    f: Vec<f64>,
    selected: Vec<usize>,
    leverage: Vec<f64>,
    version: Vec<u32>,
    updates: Vec<Vec<f64>>,
    bound: Vec<f64>,
    excluded: Vec<bool>,
    /// The unselected candidates by decreasing bound (ties by index).
    order: Vec<usize>,
    /// Whether the next [`Self::top`] brings every candidate up to date in one sequential pass
    /// (the last one evaluated most of them).
    full_pass_next: bool,
    /// Whether the bounds are gains of a rank-deficient design: true until a full pass is made
    /// at full rank (each full pass records whether its design was deficient).
    bounds_before_full_rank: bool,
    /// Whether `order` waits to be sorted again (every bound changed in a full pass).
    order_stale: bool,
    /// Blocks older than this many additions are recomputed exactly: set when the design
    /// reaches full rank, because blocks of the rank-deficient phase are of order `1/ε` and
    /// updating them down to order 1 would cancel most of their digits.
    exact_since: usize,
    /// Candidate evaluations (gains brought up to date) made so far.
    pub evaluations: usize,
}

/// Smallest batch of candidates brought up to date at once (batches then grow with the number
/// already evaluated, so the last batch overshoots by at most an eighth).
const MIN_BATCH: usize = 4096;

/// A step that brought more than `1/FULL_PASS` of the candidates up to date is followed by a
/// full sequential pass (measured on 300,000 candidates: a pass in index order takes about as
/// long as a scattered fifth of it).
const FULL_PASS: usize = 5;

/// Relative margin by which the `need`-th gain must exceed the remaining bounds (guards against
/// round-off in the bounds).
const MARGIN: f64 = 1e-10;

/// Whether a current `gain` beats every candidate whose stale bound is at most `bound`.
fn settles(gain: f64, bound: f64) -> bool {
    gain > bound + MARGIN * (1.0 + bound.abs())
}

/// Larger gain first, then lower index.
fn by_gain(a: &(usize, f64), b: &(usize, f64)) -> std::cmp::Ordering {
    b.1.total_cmp(&a.1).then(a.0.cmp(&b.0))
}

/// A block that missed more additions than this is recomputed from `F` instead of updated.
fn max_pending(k: usize, r: usize) -> usize {
    // Update: r²k per addition; recompute: r·k²/2 + r²k/2.
    (k / (2 * r)).max(1) + 1
}

impl<'a> LazyGains<'a> {
    /// The empty design: `G_i = A_iA_iᵀ/ε` for every candidate.
    pub fn new(blocks: &'a CandidateJacobians, ridge: f64) -> Result<Self, CalibError> {
        if !(ridge > 0.0 && ridge.is_finite()) {
            return Err(CalibError::InvalidOption(format!("ridge must be positive, got {ridge}")));
        }
        let n = blocks.len();
        let k = blocks.n_columns();
        let r = blocks.rows_per_candidate();
        let mut leverage = vec![0.0; n * r * r];
        leverage
            .par_chunks_mut(r * r)
            .zip(blocks.data().par_chunks(r * k))
            .with_min_len(1024)
            .for_each(|(g, a)| {
                for p in 0..r {
                    for q in p..r {
                        let d: f64 = a[p * k..(p + 1) * k].iter().zip(&a[q * k..(q + 1) * k]).map(|(x, y)| x * y).sum();
                        g[p * r + q] = d / ridge;
                        g[q * r + p] = d / ridge;
                    }
                }
            });
        let bound: Vec<f64> = leverage
            .par_chunks(r * r)
            .with_min_len(1024)
            .map(|g| {
                if r == 3 {
                    log_det_identity_plus::<3>(g, 1.0)
                } else {
                    log_det_identity_plus::<6>(g, 1.0)
                }
            })
            .collect();
        let m = DMatrix::zeros(k, k);
        let (f, _) = inverse_factor(&m, ridge)?;
        let mut order: Vec<usize> = (0..n).collect();
        order.par_sort_unstable_by(|a, b| by_gain(&(*a, bound[*a]), &(*b, bound[*b])));
        Ok(LazyGains {
            blocks,
            ridge,
            m,
            f,
            selected: Vec::new(),
            leverage,
            version: vec![0; n],
            updates: Vec::new(),
            bound,
            excluded: vec![false; n],
            order,
            full_pass_next: false,
            bounds_before_full_rank: true,
            order_stale: false,
            exact_since: 0,
            evaluations: 0,
        })
    }

    /// `M` of the selected set.
    pub fn information(&self) -> &DMatrix<f64> {
        &self.m
    }

    /// Selected candidates, in order.
    pub fn selected(&self) -> &[usize] {
        &self.selected
    }

    /// The current leverage block and gain of candidate `i`: `g` holds its stored block on entry
    /// and the current one on return (brought up to date by the additions it missed, or
    /// recomputed); `w` is scratch of length `r·k`.
    fn current<const R: usize>(&self, i: usize, w: &mut [f64], g: &mut [f64]) -> f64 {
        let k = self.blocks.n_columns();
        let a = self.blocks.block(i);
        let from = self.version[i] as usize;
        if from >= self.exact_since && self.updates.len() - from <= max_pending(k, R) {
            for u in &self.updates[from..] {
                low_rank_one::<R>(a, k, u, g, -1.0);
            }
        } else {
            exact_one::<R>(a, k, &self.f, w, g);
        }
        log_det_identity_plus::<R>(g, 1.0)
    }

    /// Bring the candidates `idx` (increasing, distinct) up to date, in place; their gains.
    fn refresh_batch(&mut self, idx: &[usize]) -> Vec<f64> {
        let r = self.blocks.rows_per_candidate();
        let k = self.blocks.n_columns();
        let rr = r * r;
        let mut leverage = std::mem::take(&mut self.leverage);
        // The blocks of `idx`, as disjoint mutable slices of the leverage buffer.
        let mut slots: Vec<&mut [f64]> = Vec::with_capacity(idx.len());
        let mut rest: &mut [f64] = &mut leverage;
        let mut at = 0;
        for &i in idx {
            let (_, tail) = std::mem::take(&mut rest).split_at_mut((i - at) * rr);
            let (slot, tail) = tail.split_at_mut(rr);
            slots.push(slot);
            rest = tail;
            at = i + 1;
        }
        let mut gains = vec![0.0; idx.len()];
        let this = &*self;
        slots
            .par_iter_mut()
            .zip(gains.par_iter_mut())
            .zip(idx.par_iter())
            .with_min_len(64)
            .for_each_init(
                || vec![0.0; r * k],
                |w, ((g, gain), &i)| {
                    *gain = if r == 3 {
                        this.current::<3>(i, w, g)
                    } else {
                        this.current::<6>(i, w, g)
                    };
                },
            );
        drop(slots);
        self.leverage = leverage;
        let now = self.updates.len() as u32;
        for &i in idx {
            self.version[i] = now;
        }
        self.evaluations += idx.len();
        gains
    }

    /// Bring the candidates `idx` (increasing, distinct) up to date, record their gains as their
    /// bounds, and return the `need` best of them (in no particular order).
    fn refresh_top(&mut self, idx: &[usize], need: usize) -> Vec<(usize, f64)> {
        let gains = self.refresh_batch(idx);
        let mut fresh: Vec<(usize, f64)> = idx.iter().copied().zip(gains).collect();
        for &(i, g) in &fresh {
            self.bound[i] = g;
        }
        if fresh.len() > need {
            fresh.select_nth_unstable_by(need - 1, by_gain);
            fresh.truncate(need);
        }
        fresh
    }

    /// The `need` unselected candidates of largest current gain, best first (ties by lower
    /// index), with their gains.
    pub fn top(&mut self, need: usize) -> Vec<(usize, f64)> {
        if self.full_pass_next {
            return self.top_by_full_pass(need);
        }
        if self.order_stale {
            let len = self.order.len();
            self.reorder(len);
            self.order_stale = false;
        }
        // `order` holds the unselected candidates by decreasing bound: walk it in batches, every
        // candidate not yet reached has a bound ≤ that of the next one.
        let mut best: Vec<(usize, f64)> = Vec::new();
        let mut pos = 0;
        while pos < self.order.len() {
            if best.len() >= need && settles(best[need - 1].1, self.bound[self.order[pos]]) {
                break;
            }
            let batch = (4 * need).max(MIN_BATCH).max(pos / 8);
            let end = (pos + batch).min(self.order.len());
            // In index order, so the blocks and leverages are read sequentially.
            let mut idx = self.order[pos..end].to_vec();
            idx.sort_unstable();
            best.extend(self.refresh_top(&idx, need));
            best.sort_by(by_gain);
            best.truncate(need);
            pos = end;
        }
        // Scattered evaluation of a fifth of the candidates costs about a full sequential pass.
        self.full_pass_next = FULL_PASS * pos > self.order.len();
        self.reorder(pos);
        best
    }

    /// [`Self::top`] when most bounds are about to be brought up to date anyway: one pass over
    /// every unselected candidate in index order reads the blocks sequentially instead of
    /// scattered (several times faster).
    fn top_by_full_pass(&mut self, need: usize) -> Vec<(usize, f64)> {
        let idx: Vec<usize> = (0..self.excluded.len()).filter(|&i| !self.excluded[i]).collect();
        let stale: Vec<f64> = idx.iter().map(|&i| self.bound[i]).collect();
        let mut best = self.refresh_top(&idx, need);
        best.sort_by(by_gain);
        // How many the lazy walk would have evaluated: the bounds the answer's last gain does
        // not settle.
        let last = best.last().map_or(f64::NEG_INFINITY, |b| b.1);
        let walked = stale.iter().filter(|&&b| !settles(last, b)).count();
        // Bounds from before full rank (of order 1/ε) settle nothing, and say nothing of how far
        // the next walk goes: after the first pass at full rank every bound is a fresh gain.
        self.full_pass_next = FULL_PASS * walked > idx.len() && !self.bounds_before_full_rank;
        self.bounds_before_full_rank = self.rank_deficient();
        // Every bound changed: the order is sorted again when a walk next needs it (before full
        // rank every step is a full pass, and sorting after each was wasted).
        self.order_stale = true;
        best
    }

    /// Restore the order by decreasing bound after the first `done` entries got new (smaller)
    /// bounds: sort them and merge them with the untouched, still sorted rest.
    fn reorder(&mut self, done: usize) {
        let bound = &self.bound;
        let key = |i: usize| (i, bound[i]);
        let mut head: Vec<(usize, f64)> = self.order[..done].iter().map(|&i| key(i)).collect();
        head.par_sort_unstable_by(by_gain);
        let tail = &self.order[done..];
        let mut merged = Vec::with_capacity(self.order.len());
        let mut h = head.iter().peekable();
        for &t in tail {
            let kt = key(t);
            while let Some(&&x) = h.peek() {
                if by_gain(&x, &kt) == std::cmp::Ordering::Greater {
                    break;
                }
                merged.push(x.0);
                h.next();
            }
            merged.push(t);
        }
        merged.extend(h.map(|x| x.0));
        self.order = merged;
    }

    /// Add candidate `j` to the design (its Woodbury factor is stored for the other candidates).
    pub fn add(&mut self, j: usize) -> Result<(), CalibError> {
        if j >= self.excluded.len() || self.excluded[j] {
            return Err(CalibError::InvalidOption(format!("candidate {j} cannot be added")));
        }
        let r = self.blocks.rows_per_candidate();
        let k = self.blocks.n_columns();
        self.refresh_batch(&[j]);
        let g = DMatrix::from_row_slice(r, r, &self.leverage[j * r * r..(j + 1) * r * r]);
        let chol = (DMatrix::identity(r, r) + g)
            .cholesky()
            .ok_or_else(|| CalibError::Numerical("leverage block is not positive definite".into()))?;
        let linv = chol
            .l()
            .solve_lower_triangular(&DMatrix::identity(r, r))
            .ok_or_else(|| CalibError::Numerical("triangular solve in a low-rank update".into()))?;
        let f = DMatrix::from_row_slice(k, k, &self.f);
        let a = self.blocks.block_matrix(j);
        let u = &f * (f.transpose() * a.transpose()) * linv.transpose(); // P Aᵀ L⁻ᵀ, k × r
        let mut u_rows = Vec::with_capacity(k * r);
        for c in 0..k {
            for b in 0..r {
                u_rows.push(u[(c, b)]);
            }
        }
        self.updates.push(u_rows);
        let was_deficient = self.rank_deficient();
        add_gram(&mut self.m, self.blocks.block(j), r, 1.0);
        self.f = inverse_factor(&self.m, self.ridge)?.0;
        self.selected.push(j);
        self.excluded[j] = true;
        self.order.retain(|&i| i != j);
        let deficient = self.rank_deficient();
        if was_deficient && !deficient {
            self.exact_since = self.updates.len();
        }
        // Before full rank an addition changes every gain by orders of magnitude (and the first
        // one at full rank needs every block recomputed): no bound prunes, pass over all.
        if was_deficient {
            self.full_pass_next = true;
        }
        Ok(())
    }

    /// Whether `M` is rank-deficient (see [`ObservabilityIndices::from_information`]).
    pub fn rank_deficient(&self) -> bool {
        let r = self.blocks.rows_per_candidate();
        self.selected.len() * r < self.blocks.n_columns()
            || ObservabilityIndices::from_information(&self.m, self.selected.len() * r).o3 == 0.0
    }

    /// Exact gains of every candidate for the information matrix `m` (no laziness).
    pub fn all_exact(blocks: &CandidateJacobians, m: &DMatrix<f64>, ridge: f64) -> Result<Vec<f64>, CalibError> {
        let (f, _) = inverse_factor(m, ridge)?;
        let k = blocks.n_columns();
        let r = blocks.rows_per_candidate();
        Ok(blocks
            .data()
            .par_chunks(r * k)
            .with_min_len(256)
            .map_init(
                || vec![0.0; r * k],
                |w, a| {
                    let mut g = [0.0f64; 36];
                    if r == 3 {
                        exact_one::<3>(a, k, &f, w, &mut g[..9]);
                        log_det_identity_plus::<3>(&g[..9], 1.0)
                    } else {
                        exact_one::<6>(a, k, &f, w, &mut g);
                        log_det_identity_plus::<6>(&g, 1.0)
                    }
                },
            )
            .collect())
    }
}
