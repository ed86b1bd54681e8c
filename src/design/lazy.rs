//! Lazy evaluation of D-optimality gains for forward selection over very large candidate sets.
//!
//! The gain of candidate `i`, `log det(I + A_i (M + εI)⁻¹ A_iᵀ)`, can only **decrease** when
//! configurations are added (`M` grows in the positive semidefinite order, so `(M + εI)⁻¹`
//! shrinks): `log det` is submodular. A gain computed at an earlier step is therefore an upper
//! bound at every later step of a forward search. To find the best `need` candidates, gains are
//! recomputed exactly, in parallel batches of the largest bounds, until the `need`-th best exact
//! gain exceeds every remaining bound; the answer is exactly the one a full evaluation would give,
//! usually after evaluating a small fraction of the candidates (all of them in the first steps,
//! while the ridge dominates).
use super::information::{gain_with_factor, inverse_factor};
use super::jacobians::CandidateJacobians;
use crate::error::CalibError;
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Upper bounds of the D-optimality gains of all candidates during a forward search.
#[derive(Debug, Clone)]
pub struct LazyGains<'a> {
    blocks: &'a CandidateJacobians,
    ridge: f64,
    bound: Vec<f64>,
    stamp: Vec<u32>,
    excluded: Vec<bool>,
    step: u32,
    /// Exact gain evaluations made so far.
    pub evaluations: usize,
}

/// Relative margin by which the `need`-th exact gain must exceed the remaining bounds (guards
/// against round-off in the bounds).
const MARGIN: f64 = 1e-10;

impl<'a> LazyGains<'a> {
    /// No candidate evaluated yet (all bounds infinite).
    pub fn new(blocks: &'a CandidateJacobians, ridge: f64) -> Self {
        let n = blocks.len();
        LazyGains {
            blocks,
            ridge,
            bound: vec![f64::INFINITY; n],
            stamp: vec![u32::MAX; n],
            excluded: vec![false; n],
            step: 0,
            evaluations: 0,
        }
    }

    /// Never consider candidate `i` again (it was selected).
    pub fn exclude(&mut self, i: usize) {
        self.excluded[i] = true;
    }

    /// The `need` candidates of largest exact gain for the information matrix `m` (which must
    /// contain at least the information of the matrices of every earlier call), best first, ties
    /// by lower index, with their gains.
    pub fn top(&mut self, m: &DMatrix<f64>, need: usize) -> Result<Vec<(usize, f64)>, CalibError> {
        let (f, _) = inverse_factor(m, self.ridge)?;
        self.step = self.step.wrapping_add(1);
        let step = self.step;
        let k = self.blocks.n_columns();
        let r = self.blocks.rows_per_candidate();
        let order = |a: &(usize, f64), b: &(usize, f64)| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0));
        let mut evaluated: Vec<(usize, f64)> = Vec::new();
        let mut batch = (4 * need).max(512);
        loop {
            let mut rest: Vec<(usize, f64)> = self
                .bound
                .par_iter()
                .enumerate()
                .with_min_len(4096)
                .filter(|(i, _)| !self.excluded[*i] && self.stamp[*i] != step)
                .map(|(i, &b)| (i, b))
                .collect();
            if rest.is_empty() {
                break;
            }
            let take = batch.min(rest.len());
            if take < rest.len() {
                rest.select_nth_unstable_by(take - 1, order);
                rest.truncate(take);
            }
            let blocks = self.blocks;
            let gains: Vec<f64> = rest
                .par_iter()
                .with_min_len(64)
                .map_init(
                    || vec![0.0; r * k],
                    |w, &(i, _)| {
                        let a = blocks.block(i);
                        if r == 3 {
                            gain_with_factor::<3>(a, k, &f, w)
                        } else {
                            gain_with_factor::<6>(a, k, &f, w)
                        }
                    },
                )
                .collect();
            self.evaluations += rest.len();
            for (&(i, _), &g) in rest.iter().zip(&gains) {
                self.bound[i] = g;
                self.stamp[i] = step;
                evaluated.push((i, g));
            }
            evaluated.sort_by(order);
            if evaluated.len() >= need {
                let threshold = evaluated[need - 1].1;
                let max_rest = self
                    .bound
                    .par_iter()
                    .enumerate()
                    .with_min_len(4096)
                    .filter(|(i, _)| !self.excluded[*i] && self.stamp[*i] != step)
                    .map(|(_, &b)| b)
                    .reduce(|| f64::NEG_INFINITY, f64::max);
                if threshold > max_rest + MARGIN * (1.0 + max_rest.abs()) {
                    break;
                }
            }
            batch *= 2;
        }
        evaluated.truncate(need);
        Ok(evaluated)
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
                    if r == 3 {
                        gain_with_factor::<3>(a, k, &f, w)
                    } else {
                        gain_with_factor::<6>(a, k, &f, w)
                    }
                },
            )
            .collect())
    }
}
