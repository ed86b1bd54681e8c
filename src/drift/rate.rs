//! The decision of [`super::check()`] at its stated false-alarm rate.
//!
//! Two statistics judge the new rows: `T` over all of them, and each pattern's drop `Δᵢ` (how much
//! releasing it lowers `T`). A drift of one pattern concentrates in its few coefficients, which
//! `T` spreads over as many degrees of freedom as rows; a drift no pattern describes shows only
//! in `T`. Both are taken as normal deviates (Wilson–Hilferty: `T` against χ² of its rows, `Δᵢ`
//! against χ² of the pattern's size) and the largest is the statistic. Its distribution for a
//! machine as calibrated is simulated: in whitened rows `w = C^{-1/2}·e` (`C` the rows' predicted
//! covariance) `w` is standard normal, `T = |w|²` and `Δᵢ = |Qᵢᵀ·w|²` with `Qᵢ` an orthonormal
//! basis of the pattern's whitened effect; so drawing `w` draws every statistic at once, with the
//! correlations the patterns share (a leg's length and its rail point act alike). The threshold
//! is the quantile of the simulated largest deviate at one minus the rate: the rate holds for the
//! tests together, without splitting it between them or dividing it among the patterns.
use super::chi2_z;
use super::reference::{basis, NullRows, Reference};
use crate::error::CalibError;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_distr::{ChiSquared, Distribution, StandardNormal};

/// Draws of the simulated distribution: the false-alarm rate it sets is within about 0.1 % of
/// the one asked for at 1 % (the binomial spread of 10 000 draws).
pub const NULL_DRAWS: usize = 10_000;

/// What [`decide`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Decision {
    /// The normal deviate every statistic is held to: beyond it, drifted.
    pub z: f64,
    /// `T = |w|²`.
    pub chi2: f64,
    /// Each pattern's drop `Δᵢ` and its size (coefficients seen by the rows); `None` for a
    /// pattern the rows do not see whole.
    pub drops: Vec<Option<(f64, usize)>>,
}

/// The decision on noise-weighted residual rows `e` whose predicted covariance is `I + B·Bᵀ`
/// (`B` the rows' Jacobian times the prior's factor), for patterns whose effects on the rows are
/// `effects` (each rows × k), at the false-alarm rate `alpha`; the simulation drawn from `seed`.
/// With `reference` (the rows' layout, rows per pose, and the calibration's residuals) the
/// rows' noise is also drawn from the calibration's own poses ([`super::reference`]), and the
/// higher of the two thresholds holds.
///
/// Errors: the predicted covariance is not positive definite.
pub fn decide(
    b: &DMatrix<f64>,
    e: &DVector<f64>,
    effects: &[DMatrix<f64>],
    alpha: f64,
    seed: u64,
    reference: Option<(&[usize], &Reference)>,
) -> Result<Decision, CalibError> {
    let rows = e.len();
    let c = DMatrix::identity(rows, rows) + b * b.transpose();
    let chol = c
        .cholesky()
        .ok_or_else(|| CalibError::Numerical("the rows' predicted covariance is not positive definite".into()))?;
    let l = chol.l();
    let whiten = |m: &DMatrix<f64>| l.solve_lower_triangular(m);
    let w = whiten(&DMatrix::from_column_slice(rows, 1, e.as_slice()))
        .ok_or_else(|| CalibError::Numerical("the rows' predicted covariance is singular".into()))?;
    let w = w.column(0).into_owned();
    // Each pattern's whitened effect, orthonormalised: its drop is |Qᵀw|².
    let bases: Vec<Option<DMatrix<f64>>> = effects
        .iter()
        .map(|g| {
            if g.norm() <= 1e-12 || g.ncols() > rows {
                return None;
            }
            basis(&whiten(g)?)
        })
        .collect();
    let drops: Vec<Option<(f64, usize)>> = bases
        .iter()
        .map(|q| q.as_ref().map(|q| ((q.transpose() * &w).norm_squared(), q.ncols())))
        .collect();
    let chi2 = w.norm_squared();
    let at = (((1.0 - alpha) * NULL_DRAWS as f64).ceil() as usize).clamp(1, NULL_DRAWS) - 1;
    // With a reference, its rows' threshold where that is above the normal rows' one: a
    // reference of a few poses under-represents the tail a normal distribution has, and the
    // rows are never judged more strictly than as normal.
    let from_reference = match reference {
        Some((layout, reference)) => {
            let null = NullRows::new(b, layout, Some(reference))
                .ok_or_else(|| CalibError::Numerical("the rows' predicted covariance is not positive definite".into()))?;
            let seen: Vec<(DMatrix<f64>, usize)> = bases.iter().flatten().map(|q| (q.transpose(), q.ncols())).collect();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut largest: Vec<f64> = (0..NULL_DRAWS)
                .map(|_| {
                    let w = null.draw(&mut rng);
                    seen.iter()
                        .map(|(qt, k)| chi2_z((qt * &w).norm_squared(), *k))
                        .fold(chi2_z(w.norm_squared(), rows), f64::max)
                })
                .collect();
            largest.sort_by(f64::total_cmp);
            largest[at]
        }
        None => f64::NEG_INFINITY,
    };
    // The span of every pattern's basis: the drops depend on w only through its part there;
    // the rest adds to T as χ² of the remaining rows.
    let seen: Vec<&DMatrix<f64>> = bases.iter().flatten().collect();
    let total: usize = seen.iter().map(|q| q.ncols()).sum();
    let (span, d) = if total == 0 {
        (DMatrix::zeros(rows, 0), 0)
    } else {
        let mut all = DMatrix::zeros(rows, total);
        let mut at = 0;
        for q in &seen {
            all.view_mut((0, at), (rows, q.ncols())).copy_from(*q);
            at += q.ncols();
        }
        let svd = all.svd(true, false);
        let u = svd.u.expect("left singular vectors were asked for");
        let largest = svd.singular_values.max();
        let keep: Vec<usize> = (0..svd.singular_values.len())
            .filter(|&j| svd.singular_values[j] > 1e-10 * largest)
            .collect();
        let span = DMatrix::from_fn(rows, keep.len(), |i, j| u[(i, keep[j])]);
        let d = keep.len();
        (span, d)
    };
    let projected: Vec<(DMatrix<f64>, usize)> = seen.iter().map(|q| (q.transpose() * &span, q.ncols())).collect();
    let rest = (rows > d).then(|| ChiSquared::new((rows - d) as f64).expect("positive degrees of freedom"));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut largest: Vec<f64> = (0..NULL_DRAWS)
        .map(|_| {
            let u = DVector::from_fn(d, |_, _| StandardNormal.sample(&mut rng));
            let t = u.norm_squared() + rest.as_ref().map_or(0.0, |r| r.sample(&mut rng));
            projected
                .iter()
                .map(|(m, k)| chi2_z((m * &u).norm_squared(), *k))
                .fold(chi2_z(t, rows), f64::max)
        })
        .collect();
    largest.sort_by(f64::total_cmp);
    Ok(Decision {
        z: largest[at].max(from_reference),
        chi2,
        drops,
    })
}

impl Decision {
    /// The pattern (index into the effects) whose drop is the largest normal deviate, with the
    /// deviate; `None` when the rows see no pattern whole.
    pub fn strongest(&self) -> Option<(usize, f64)> {
        (self.drops.iter().enumerate())
            .filter_map(|(i, d)| d.map(|(x, k)| (i, chi2_z(x, k))))
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// The largest normal deviate of the observed statistics.
    pub fn deviate(&self, rows: usize) -> f64 {
        let t = chi2_z(self.chi2, rows);
        self.strongest().map_or(t, |(_, z)| z.max(t))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    /// Rows with a prior of 4 directions and 6 patterns, two of them nearly alike.
    fn problem(rows: usize, rng: &mut rand_chacha::ChaCha8Rng) -> (DMatrix<f64>, Vec<DMatrix<f64>>) {
        let mut m = |r: usize, c: usize| DMatrix::from_fn(r, c, |_, _| rng.random_range(-1.0..1.0));
        let b = m(rows, 4) * 0.3;
        let g0 = m(rows, 1);
        let near = &g0 + m(rows, 1) * 0.05;
        let effects = vec![g0, near, m(rows, 1), m(rows, 3), m(rows, 1), m(rows, 2)];
        (b, effects)
    }

    #[test]
    fn the_drops_are_the_stacked_solutions_and_the_rate_holds() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let rows = 24;
        let (b, effects) = problem(rows, &mut rng);
        // A drop by projection against the least-squares fit of the pattern with the prior:
        // min over β of (e − Gβ)ᵀC⁻¹(e − Gβ), subtracted from eᵀC⁻¹e.
        let c = DMatrix::identity(rows, rows) + &b * b.transpose();
        let ci = c.clone().try_inverse().unwrap();
        let e = DVector::from_fn(rows, |_, _| rng.random_range(-2.0..2.0));
        let dec = decide(&b, &e, &effects, 0.01, 1, None).unwrap();
        assert!((dec.chi2 - e.dot(&(&ci * &e))).abs() < 1e-9 * dec.chi2);
        for (g, drop) in effects.iter().zip(&dec.drops) {
            let (x, k) = drop.unwrap();
            let n = g.transpose() * &ci * g;
            let beta = n.clone().try_inverse().unwrap() * (g.transpose() * &ci * &e);
            let left = &e - g * beta;
            let expected = dec.chi2 - left.dot(&(&ci * &left));
            assert_eq!(k, g.ncols());
            assert!((x - expected).abs() < 1e-9 * dec.chi2, "{x} vs {expected}");
        }
        // Residuals drawn as a machine as calibrated gives them: false alarms at the rate asked.
        let chol = c.cholesky().unwrap();
        let draws = 2000;
        let mut alarms = 0;
        for k in 0..draws {
            let n = DVector::from_fn(rows, |_, _| StandardNormal.sample(&mut rng));
            let e = chol.l() * n;
            let dec = decide(&b, &e, &effects, 0.05, 100 + k, None).unwrap();
            if dec.deviate(rows) > dec.z {
                alarms += 1;
            }
        }
        // 5 % of 2000 is 100, binomial σ 9.7: within 3.5 σ.
        assert!((alarms as f64 - 100.0).abs() < 34.0, "{alarms} false alarms in {draws}");
    }

    #[test]
    fn heavy_tailed_rows_keep_the_rate_when_judged_by_their_reference() {
        // Poses of 3 rows: most at a third of the unit scale, one in ten at 2.8 (mean square 1
        // per row, as σ̂₀ scales them), like a real robot's residual. Judged as Gaussian they
        // raise many more alarms than the rate; judged by a reference of such poses, the rate.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let scale = |rng: &mut rand_chacha::ChaCha8Rng| if rng.random_range(0.0..1.0) < 0.1 { 2.8 } else { 0.33 };
        let pose = |rng: &mut rand_chacha::ChaCha8Rng| {
            let s = scale(rng);
            (0..3)
                .map(|_| {
                    let z: f64 = StandardNormal.sample(rng);
                    s * z
                })
                .collect::<Vec<f64>>()
        };
        let stored: Vec<Vec<f64>> = (0..20_000).map(|_| pose(&mut rng)).collect();
        let reference = Reference::from_residuals(&stored).unwrap();
        let rows = 15;
        let layout = [3; 5];
        let (b, effects) = problem(rows, &mut rng);
        let draws = 1000;
        let (mut gaussian, mut referenced) = (0, 0);
        for k in 0..draws {
            let n = DVector::from_iterator(rows, (0..5).flat_map(|_| pose(&mut rng)));
            let e = n + &b * DVector::from_fn(b.ncols(), |_, _| StandardNormal.sample(&mut rng));
            let g = decide(&b, &e, &effects, 0.05, 300 + k, None).unwrap();
            gaussian += usize::from(g.deviate(rows) > g.z);
            let r = decide(&b, &e, &effects, 0.05, 300 + k, Some((&layout, &reference))).unwrap();
            referenced += usize::from(r.deviate(rows) > r.z);
        }
        // 5 % of 1000 is 50, binomial σ 6.9.
        assert!(
            (referenced as f64 - 50.0).abs() < 25.0,
            "{referenced} alarms judged by the reference, {gaussian} as Gaussian"
        );
        assert!(gaussian > 100, "{gaussian} alarms judged as Gaussian");
    }

    #[test]
    fn one_pattern_drifting_is_seen_sooner_than_by_the_test_over_all_rows() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let rows = 30;
        let (b, effects) = problem(rows, &mut rng);
        let c = DMatrix::identity(rows, rows) + &b * b.transpose();
        let chol = c.clone().cholesky().unwrap();
        // A drift along pattern 2 of a size the test over all rows alone catches about half the
        // time.
        let g = &effects[2];
        let ci = c.try_inverse().unwrap();
        let size = (25.0 / (g.transpose() * &ci * g)[(0, 0)]).sqrt();
        let (mut both, mut all_rows) = (0, 0);
        for k in 0..200 {
            let n = DVector::from_fn(rows, |_, _| StandardNormal.sample(&mut rng));
            let e = chol.l() * n + g.column(0) * size;
            let dec = decide(&b, &e, &effects, 0.01, 7 + k, None).unwrap();
            both += usize::from(dec.deviate(rows) > dec.z);
            all_rows += usize::from(dec.chi2 > super::super::chi2_quantile(rows, 0.99));
        }
        assert!(both > all_rows + 50, "combined {both}, over all rows alone {all_rows} of 200");
    }
}
