//! Where to measure a check: the few configurations, among candidates, at which [`super::check()`]
//! tells a calibration's patterns of change apart best.
//!
//! Five poses anywhere detect a drift; naming it is harder. A drifted pattern `i` of size `δᵢ`
//! and another pattern `j` fitted in its place differ on the check's rows by what `j` cannot
//! absorb of `i`'s effect: `sᵢⱼ = δᵢ²·(gᵢᵀC⁻¹gᵢ − (gⱼᵀC⁻¹gᵢ)²/gⱼᵀC⁻¹gⱼ)`, with `g` a pattern's
//! effect on the noise-weighted rows and `C = I + A·P·Aᵀ` their predicted covariance (the
//! calibration's own uncertainty included, as the check judges). Two hypotheses `√sᵢⱼ` apart
//! (in standard deviations) are confused with probability `Φ(−√sᵢⱼ/2)`. The plan minimises the
//! sum of these over every ordered pair of the one-coefficient patterns ([`super::patterns`]:
//! each input's offset, the uniform scale, each parameter), each drift sized to move the tool by
//! the same `drift_mm` (RMS over the candidates): the expected number of wrong names, bounded by
//! the union over the alternatives. Pairs that all the candidates together do not tell apart
//! (the wrong pattern leaves them χ² below 1: a rail's point along the rail and its slider's
//! zero act alike everywhere) no choice separates; they are left out.
//!
//! Greedy additions, then exchanges while one lowers the sum.
use super::{patterns, Prior};
use crate::error::CalibError;
use crate::identify::linearize;
use crate::measure::{self, Measurement};
use crate::simulate::{synthesize, Instrument};
use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::Serialize;

/// A pair whose wrong pattern leaves less χ² than this over every candidate together is one no
/// choice among them tells apart.
const ALIKE: f64 = 1.0;

/// Options of [`plan_check_poses`].
#[derive(Debug, Clone, Copy)]
pub struct CheckPlanOptions {
    /// Configurations to choose.
    pub n: usize,
    /// What the check will measure (its rows and their noise).
    pub instrument: Instrument,
    /// The size of the drifts to name apart, as the RMS displacement of the tool they cause over
    /// the candidates (mm).
    pub drift_mm: f64,
    /// Exchange passes after the greedy additions (each tries every candidate in every place).
    pub exchange_passes: usize,
    /// Seed of the patterns' sample configurations ([`super::patterns`]).
    pub seed: u64,
}

impl Default for CheckPlanOptions {
    fn default() -> Self {
        CheckPlanOptions {
            n: 5,
            instrument: Instrument::Pose,
            drift_mm: 0.1,
            exchange_passes: 3,
            seed: 1,
        }
    }
}

/// Two patterns at a set of configurations: how far apart a drift of the first leaves them.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairSeparation {
    /// The pattern that drifted (by the plan's `drift_mm` of tool motion).
    pub drifted: String,
    /// The pattern fitted in its place.
    pub taken_for: String,
    /// `sᵢⱼ`: the χ² the wrong pattern leaves (naming one alone at 1 % needs 6.6).
    pub chi2: f64,
}

/// The configurations [`plan_check_poses`] chose and what they achieve.
#[derive(Debug, Clone, Serialize)]
pub struct CheckPlan {
    /// Indices into the candidates, in the order chosen.
    pub selected: Vec<usize>,
    /// The expected number of wrong names at the chosen configurations, per pattern (the sum of
    /// `Φ(−√sᵢⱼ/2)` over the pairs divided by the patterns): 0 when every drift is told apart
    /// from every other; a union bound, so beyond 1 where many patterns crowd together.
    pub wrong_names: f64,
    /// The same for the first `n` candidates (a plan that does not choose).
    pub wrong_names_unplanned: f64,
    /// The one-coefficient patterns weighed.
    pub patterns: usize,
    /// Ordered pairs weighed, and pairs left out (alike at every candidate).
    pub pairs: usize,
    /// Ordered pairs all the candidates together do not tell apart (left out).
    pub alike: usize,
    /// The least separated pairs at the chosen configurations (at most 5, least first).
    pub weakest: Vec<PairSeparation>,
}

/// Precomputed per-candidate rows: the prior's share `A·L` and the patterns' effects `A·D`.
struct Rows {
    b: Vec<DMatrix<f64>>,
    g: Vec<DMatrix<f64>>,
    delta: Vec<f64>,
    pairs: Vec<(usize, usize)>,
}

impl Rows {
    /// The Gram matrix `Gᵀ·C⁻¹·G` of the patterns' effects at `set` (`None`: `C` singular).
    fn gram(&self, set: &[usize]) -> Option<DMatrix<f64>> {
        let rows: usize = set.iter().map(|&c| self.b[c].nrows()).sum();
        let (rl, k) = (self.b[set[0]].ncols(), self.g[set[0]].ncols());
        let mut b = DMatrix::zeros(rows, rl);
        let mut g = DMatrix::zeros(rows, k);
        let mut at = 0;
        for &c in set {
            let n = self.b[c].nrows();
            b.view_mut((at, 0), (n, rl)).copy_from(&self.b[c]);
            g.view_mut((at, 0), (n, k)).copy_from(&self.g[c]);
            at += n;
        }
        let c = DMatrix::identity(rows, rows) + &b * b.transpose();
        let ch = c.cholesky()?;
        let w = ch.l().solve_lower_triangular(&g)?;
        Some(w.transpose() * w)
    }

    /// `sᵢⱼ` of every weighed pair from a Gram matrix.
    fn separations(&self, m: &DMatrix<f64>) -> Vec<f64> {
        self.pairs
            .iter()
            .map(|&(i, j)| {
                let within = if m[(j, j)] > 0.0 { m[(i, j)] * m[(i, j)] / m[(j, j)] } else { 0.0 };
                self.delta[i] * self.delta[i] * (m[(i, i)] - within).max(0.0)
            })
            .collect()
    }

    /// The sum of `Φ(−√sᵢⱼ/2)` over the weighed pairs at `set` (∞ where `C` is singular).
    fn wrong_names(&self, set: &[usize]) -> f64 {
        self.gram(set).map_or(f64::INFINITY, |m| {
            self.separations(&m).iter().map(|&s| normal_tail(s.sqrt() / 2.0)).sum()
        })
    }
}

/// `Φ(−x)`, the standard normal's upper tail, from the complementary error function (Numerical
/// Recipes' Chebyshev fit, relative error below 1.2e-7).
fn normal_tail(x: f64) -> f64 {
    let z = x.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07 + t * (-1.135_203_98 + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let erfc = t * poly.exp();
    if x >= 0.0 {
        0.5 * erfc
    } else {
        1.0 - 0.5 * erfc
    }
}

/// Choose `opts.n` of `configurations` (the calibrated model's inputs, rad / mm) at which a check
/// names a drift best (see the [module docs](self)).
///
/// Errors: fewer candidates than asked, a candidate the calibrated model cannot reach, a prior
/// that does not match the model, no pattern the candidates see.
pub fn plan_check_poses(prior: &Prior, configurations: &[Vec<f64>], opts: &CheckPlanOptions) -> Result<CheckPlan, CalibError> {
    let n = opts.n;
    if n == 0 || configurations.len() < n {
        return Err(CalibError::InvalidOption(format!(
            "choosing {n} check poses takes at least that many candidates (there are {})",
            configurations.len()
        )));
    }
    if !(opts.drift_mm > 0.0 && opts.drift_mm.is_finite()) {
        return Err(CalibError::InvalidOption(format!(
            "the drift to name must be a positive size in mm (it is {})",
            opts.drift_mm
        )));
    }
    let model = prior.model.build();
    prior.check_size(model.n_params())?;
    let l = prior.factor();
    let none = measure::Noise {
        position: 0.0,
        orientation: 0.0,
        ..prior.noise
    };
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(opts.seed);
    let data: Vec<Measurement> = synthesize(&*model, configurations.to_vec(), opts.instrument, &none, &mut rng, &|_| {})?.measurements;
    let lin = linearize(&*model, &data, &prior.noise)?;
    let all: Vec<_> = patterns(&*model, &prior.model.inputs(), opts.seed)?
        .into_iter()
        .filter(|p| p.directions.ncols() == 1)
        .collect();
    let d = DMatrix::from_fn(model.n_params(), all.len(), |r, c| all[c].directions[(r, 0)]);
    let block = |i: usize| {
        let at = lin.pose_rows(i);
        (at.start, at.len())
    };
    let mut b = Vec::with_capacity(data.len());
    let mut g = Vec::with_capacity(data.len());
    // Each pattern's tool displacement, summed in squares over the candidates (mm²).
    let mut moved = vec![0.0; all.len()];
    for (i, m) in data.iter().enumerate() {
        let (s, len) = block(i);
        let a = lin.jacobian.rows(s, len);
        let gi = a * &d;
        let weights = measure::row_weights(&m.obs, &prior.noise);
        for (k, w) in weights.iter().enumerate().take(3.min(len)) {
            for (c, total) in moved.iter_mut().enumerate() {
                *total += (gi[(k, c)] / w).powi(2);
            }
        }
        b.push(a * &l);
        g.push(gi);
    }
    let seen: Vec<usize> = (0..all.len()).filter(|&c| moved[c] > 1e-24).collect();
    if seen.is_empty() {
        return Err(CalibError::NothingToIdentify(
            "no pattern of change moves the tool at these candidates".into(),
        ));
    }
    let delta: Vec<f64> = seen
        .iter()
        .map(|&c| opts.drift_mm / (moved[c] / data.len() as f64).sqrt())
        .collect();
    let g: Vec<DMatrix<f64>> = g.into_iter().map(|gi| gi.select_columns(&seen)).collect();
    // The pairs the candidates tell apart: all of them together, without the prior.
    let mut full = DMatrix::zeros(seen.len(), seen.len());
    for gi in &g {
        full += gi.transpose() * gi;
    }
    let mut pairs = Vec::new();
    let mut alike = 0;
    for i in 0..seen.len() {
        for j in 0..seen.len() {
            if i == j {
                continue;
            }
            let left = delta[i] * delta[i] * (full[(i, i)] - full[(i, j)] * full[(i, j)] / full[(j, j)]);
            if left >= ALIKE {
                pairs.push((i, j));
            } else {
                alike += 1;
            }
        }
    }
    let rows = Rows { b, g, delta, pairs };
    let candidates = configurations.len();
    let best_with = |set: &Vec<usize>, place: Option<usize>| -> (f64, usize) {
        (0..candidates)
            .into_par_iter()
            .filter(|c| !set.contains(c))
            .map(|c| {
                let mut trial = set.clone();
                match place {
                    Some(p) => trial[p] = c,
                    None => trial.push(c),
                }
                (rows.wrong_names(&trial), c)
            })
            .reduce(
                || (f64::INFINITY, usize::MAX),
                |a, b| if b.0 < a.0 || (b.0 == a.0 && b.1 < a.1) { b } else { a },
            )
    };
    let mut selected: Vec<usize> = Vec::with_capacity(n);
    for _ in 0..n {
        let (_, c) = best_with(&selected, None);
        if c == usize::MAX {
            return Err(CalibError::Numerical("no candidate gives the check's rows a covariance".into()));
        }
        selected.push(c);
    }
    let mut score = rows.wrong_names(&selected);
    for _ in 0..opts.exchange_passes {
        let mut improved = false;
        for p in 0..n {
            let (s, c) = best_with(&selected, Some(p));
            if s < score * (1.0 - 1e-12) {
                selected[p] = c;
                score = s;
                improved = true;
            }
        }
        if !improved {
            break;
        }
    }
    let per_pattern = seen.len() as f64;
    let first: Vec<usize> = (0..n).collect();
    let m = rows
        .gram(&selected)
        .ok_or_else(|| CalibError::Numerical("the chosen rows' covariance is singular".into()))?;
    let s = rows.separations(&m);
    let mut order: Vec<usize> = (0..s.len()).collect();
    order.sort_by(|&a, &b| s[a].total_cmp(&s[b]));
    let weakest = order
        .iter()
        .take(5)
        .map(|&k| {
            let (i, j) = rows.pairs[k];
            PairSeparation {
                drifted: all[seen[i]].name.clone(),
                taken_for: all[seen[j]].name.clone(),
                chi2: s[k],
            }
        })
        .collect();
    Ok(CheckPlan {
        selected,
        wrong_names: score / per_pattern,
        wrong_names_unplanned: rows.wrong_names(&first) / per_pattern,
        patterns: seen.len(),
        pairs: rows.pairs.len(),
        alike,
        weakest,
    })
}

/// The χ² left of `e` once `g` is fitted to it, in the metric `C⁻¹`: the tests' reference.
#[cfg(test)]
fn chi2_left(e: &nalgebra::DVector<f64>, g: &nalgebra::DVector<f64>, c: &DMatrix<f64>) -> f64 {
    let ci = c.clone().try_inverse().expect("invertible");
    let beta = g.dot(&(&ci * e)) / g.dot(&(&ci * g));
    let left = e - g * beta;
    left.dot(&(&ci * &left))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DVector;

    #[test]
    fn the_normal_tail_matches_known_values() {
        for (x, want) in [
            (0.0, 0.5),
            (1.0, 0.158_655_253_931_457),
            (2.0, 0.022_750_131_948_179),
            (-1.0, 0.841_344_746_068_543),
        ] {
            assert!((normal_tail(x) - want).abs() < 2e-8, "Φ(−{x}) = {} ≠ {want}", normal_tail(x));
        }
    }

    #[test]
    fn a_separation_is_the_chi2_the_wrong_pattern_leaves() {
        // Two candidates of three rows, a prior of rank 2, two patterns.
        let b = vec![
            DMatrix::from_row_slice(3, 2, &[0.3, 0.1, -0.2, 0.5, 0.4, 0.0]),
            DMatrix::from_row_slice(3, 2, &[0.1, -0.3, 0.2, 0.2, 0.0, 0.6]),
        ];
        let g = vec![
            DMatrix::from_row_slice(3, 2, &[1.0, 0.8, 0.5, 0.6, -0.2, 0.1]),
            DMatrix::from_row_slice(3, 2, &[0.3, 0.2, 1.1, 1.0, 0.4, -0.5]),
        ];
        let rows = Rows {
            b: b.clone(),
            g: g.clone(),
            delta: vec![0.7, 1.3],
            pairs: vec![(0, 1), (1, 0)],
        };
        let m = rows.gram(&[0, 1]).expect("gram");
        let s = rows.separations(&m);
        let stack = |v: &[DMatrix<f64>]| {
            let mut out = DMatrix::zeros(6, v[0].ncols());
            out.view_mut((0, 0), (3, v[0].ncols())).copy_from(&v[0]);
            out.view_mut((3, 0), (3, v[0].ncols())).copy_from(&v[1]);
            out
        };
        let (bb, gg) = (stack(&b), stack(&g));
        let c = DMatrix::identity(6, 6) + &bb * bb.transpose();
        for (k, &(i, j)) in rows.pairs.iter().enumerate() {
            let e: DVector<f64> = gg.column(i) * rows.delta[i];
            let want = chi2_left(&e, &gg.column(j).into_owned(), &c);
            assert!((s[k] - want).abs() < 1e-12 * want.max(1.0), "pair {i},{j}: {} ≠ {want}", s[k]);
        }
    }
}
