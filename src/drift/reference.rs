//! What an unchanged machine leaves: the residuals of the calibration's own poses, by which a
//! real machine's new rows are judged.
//!
//! A Gaussian test at the calibration's `σ̂₀` assumes that the residual a real machine leaves is
//! Gaussian. It is not: compliance, backlash and temperature leave most poses closer than `σ̂₀`
//! and a few much further (on the real IRB 120 of docs/irb120.md a pose's χ² over its six rows
//! has a variance of 112 where Gaussian rows give 12). Judged as Gaussian, groups of unchanged
//! poses are called drifted far more often than the false-alarm rate stated. A [`Reference`]
//! holds each identification pose's residual rows (`[covariance] residuals` of the calibrated
//! model file): the null distribution of new rows is drawn from them, a stored pose with as many
//! rows for each new pose (rows of a kind the calibration did not measure are drawn Gaussian).
use nalgebra::{DMatrix, DVector};
use rand::{Rng, RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use std::collections::BTreeMap;

/// The calibration's poses' residual rows, in units of the noise new rows are judged against
/// ([`super::judged_noise`]), grouped by their number of rows.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    residuals: Vec<Vec<f64>>,
    /// The indices into `residuals` of the poses of each number of rows.
    by_rows: BTreeMap<usize, Vec<usize>>,
}

impl Reference {
    /// The reference of `residuals` (each pose's rows); `None` when there are none.
    pub fn from_residuals(residuals: &[Vec<f64>]) -> Option<Reference> {
        let residuals: Vec<Vec<f64>> = residuals.iter().filter(|r| !r.is_empty()).cloned().collect();
        let mut by_rows: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
        for (i, r) in residuals.iter().enumerate() {
            by_rows.entry(r.len()).or_default().push(i);
        }
        (!residuals.is_empty()).then_some(Reference { residuals, by_rows })
    }

    /// Each stored pose's rows (what a calibrated model file's `[covariance] residuals` holds).
    pub fn residuals(&self) -> &[Vec<f64>] {
        &self.residuals
    }

    /// How many stored poses have `rows` rows.
    pub fn poses_with(&self, rows: usize) -> usize {
        self.by_rows.get(&rows).map_or(0, Vec::len)
    }

    /// Rows for poses of `layout` rows each, as an unchanged machine leaves them: for each pose
    /// a stored pose with as many rows drawn uniformly, standard normal rows where none has.
    pub fn draw<R: Rng + ?Sized>(&self, layout: &[usize], rng: &mut R) -> DVector<f64> {
        let total = layout.iter().sum();
        let mut out = DVector::zeros(total);
        let mut at = 0;
        for &n in layout {
            match self.by_rows.get(&n) {
                Some(poses) => {
                    let r = &self.residuals[poses[rng.random_range(0..poses.len())]];
                    out.rows_mut(at, n).copy_from_slice(r);
                }
                None => out.rows_mut(at, n).iter_mut().for_each(|v| *v = StandardNormal.sample(rng)),
            }
            at += n;
        }
        out
    }
}

/// Draws of whitened null rows `w = C^{-1/2}(n + B·ξ)`: `n` the new rows' noise (drawn from a
/// [`Reference`], or standard normal without one), `ξ` standard normal over the prior's
/// coordinates, `C = I + B·Bᵀ` (`B` the rows' Jacobian times the prior's factor).
pub struct NullRows<'a> {
    /// Lower Cholesky factor of `C`.
    l: DMatrix<f64>,
    /// `L⁻¹·B`.
    lb: DMatrix<f64>,
    layout: Vec<usize>,
    reference: Option<&'a Reference>,
}

impl<'a> NullRows<'a> {
    /// The draws for rows of `layout` (rows per pose) with `B = b`; `None` when `I + B·Bᵀ` is
    /// not positive definite.
    pub fn new(b: &DMatrix<f64>, layout: &[usize], reference: Option<&'a Reference>) -> Option<NullRows<'a>> {
        let rows = b.nrows();
        let l = (DMatrix::identity(rows, rows) + b * b.transpose()).cholesky()?.l();
        let lb = l.solve_lower_triangular(b)?;
        Some(NullRows {
            l,
            lb,
            layout: layout.to_vec(),
            reference,
        })
    }

    /// `C^{-1/2}·m` (`m` rows × k): rows, or a pattern's effect, whitened.
    pub fn whiten(&self, m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
        self.l.solve_lower_triangular(m)
    }

    /// `Qᵀ·w` drawn without `w` (`q`: rows × k, orthonormal columns, in the whitened rows):
    /// `Qᵀ·L⁻¹` and `Qᵀ·L⁻¹·B` once, then k numbers a draw.
    pub fn projection(&self, q: &DMatrix<f64>) -> Option<Projection> {
        let m1 = self.l.tr_solve_lower_triangular(q)?.transpose();
        let m2 = q.transpose() * &self.lb;
        Some(Projection { m1, m2 })
    }

    /// One draw of `Qᵀ·w` for a [`Self::projection`].
    pub fn draw_projected<R: Rng + ?Sized>(&self, p: &Projection, rng: &mut R) -> DVector<f64> {
        let (n, xi) = self.draw_noise(rng);
        &p.m1 * n + &p.m2 * xi
    }

    /// One draw of `w`.
    pub fn draw<R: Rng + ?Sized>(&self, rng: &mut R) -> DVector<f64> {
        let (n, xi) = self.draw_noise(rng);
        let mut w = self.l.solve_lower_triangular(&n).unwrap_or_else(|| DVector::zeros(n.len()));
        w += &self.lb * xi;
        w
    }

    /// The rows' noise `n` and the prior's coordinates `ξ` of one draw, in that order.
    fn draw_noise<R: Rng + ?Sized>(&self, rng: &mut R) -> (DVector<f64>, DVector<f64>) {
        let n = match self.reference {
            Some(r) => r.draw(&self.layout, rng),
            None => DVector::from_fn(self.l.nrows(), |_, _| StandardNormal.sample(rng)),
        };
        let xi = DVector::from_fn(self.lb.ncols(), |_, _| StandardNormal.sample(rng));
        (n, xi)
    }
}

/// `Qᵀ·C^{-1/2}` and `Qᵀ·C^{-1/2}·B` of [`NullRows::projection`].
pub struct Projection {
    m1: DMatrix<f64>,
    m2: DMatrix<f64>,
}

/// The `p` quantile of `draws` values of `stat` (each drawn with `rng`).
pub fn quantile<R: Rng + ?Sized>(draws: usize, p: f64, rng: &mut R, mut stat: impl FnMut(&mut R) -> f64) -> f64 {
    let mut v: Vec<f64> = (0..draws.max(1)).map(|_| stat(rng)).collect();
    v.sort_by(f64::total_cmp);
    let at = ((p * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1;
    v[at]
}

/// Orthonormal basis of the columns of `m` (rows × k); `None` when they are not independent.
pub fn basis(m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    if m.ncols() == 0 || m.ncols() > m.nrows() || m.norm() <= 1e-12 {
        return None;
    }
    let qr = m.clone().qr();
    let r = qr.r();
    let largest = (0..r.ncols()).map(|j| r[(j, j)].abs()).fold(0.0, f64::max);
    ((0..r.ncols()).all(|j| r[(j, j)].abs() > 1e-10 * largest.max(1e-300))).then(|| qr.q())
}

/// The null distribution of a check's or an update's statistics where the prior has a
/// [`Reference`]: the new rows' noise drawn from the calibration's own poses.
pub(super) struct Null<'a> {
    pub(super) reference: &'a Reference,
    /// The new rows' pose layout.
    pub(super) layout: &'a [usize],
    /// The prior's factor.
    pub(super) l: &'a DMatrix<f64>,
    /// The new rows' noise-weighted Jacobian.
    pub(super) jacobian: &'a DMatrix<f64>,
}

impl Null<'_> {
    /// The `p` quantile over `draws` null draws (from `seed`) of, with the patterns `released`
    /// (their directions) free: the drop that releasing `tested` too brings, or without `tested`
    /// the statistic left (`T` less what the released patterns take). `None` where the rows do
    /// not see the patterns whole.
    pub(super) fn bound(&self, released: &DMatrix<f64>, tested: Option<&DMatrix<f64>>, p: f64, draws: usize, seed: u64) -> Option<f64> {
        let null = NullRows::new(&(self.jacobian * self.l), self.layout, Some(self.reference))?;
        let k = released.ncols();
        let effects = match tested {
            Some(t) => DMatrix::from_columns(&released.column_iter().chain(t.column_iter()).collect::<Vec<_>>()),
            None => released.clone(),
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        if effects.ncols() == 0 {
            return Some(quantile(draws, p, &mut rng, |rng| null.draw(rng).norm_squared()));
        }
        // The first k columns of the basis span the released patterns' effects.
        let q = basis(&null.whiten(&(self.jacobian * effects))?)?;
        match tested {
            Some(_) => {
                let projection = null.projection(&q)?;
                Some(quantile(draws, p, &mut rng, |rng| {
                    null.draw_projected(&projection, rng).rows_range(k..).norm_squared()
                }))
            }
            None => Some(quantile(draws, p, &mut rng, |rng| {
                let w = null.draw(rng);
                w.norm_squared() - (q.transpose() * w).norm_squared()
            })),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn draws_take_whole_poses_of_their_size_and_normal_rows_for_others() {
        let r = Reference::from_residuals(&[vec![1.0, 2.0, 3.0], vec![-1.0, -2.0, -3.0], vec![]]).unwrap();
        assert_eq!(r.poses_with(3), 2);
        assert_eq!(r.poses_with(6), 0);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let mut seen = [false; 2];
        for _ in 0..50 {
            let d = r.draw(&[3, 2, 3], &mut rng);
            assert_eq!(d.len(), 8);
            for block in [0, 5] {
                let first = d[block];
                assert!(first == 1.0 || first == -1.0);
                assert_eq!(d[block + 2], 3.0 * first);
                seen[usize::from(first < 0.0)] = true;
            }
            // The middle pose's two rows: no stored pose has two rows.
            assert!(d[3] != d[4] && d[3].abs() < 6.0);
        }
        assert!(seen[0] && seen[1]);
        assert!(Reference::from_residuals(&[]).is_none());
    }

    #[test]
    fn gaussian_null_rows_have_the_quantiles_of_chi2() {
        // With no reference the whitened draws are standard normal: |w|² is χ² of the rows.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let b = DMatrix::from_fn(6, 2, |i, j| 0.3 * (i as f64 - j as f64));
        let null = NullRows::new(&b, &[6], None).unwrap();
        let q = quantile(40_000, 0.95, &mut rng, |rng| null.draw(rng).norm_squared());
        // χ²(6) at 0.95: 12.59.
        assert!((q - 12.59).abs() < 0.4, "{q}");
    }

    #[test]
    fn a_projected_draw_is_the_projection_of_a_draw() {
        let reference = Reference::from_residuals(&[vec![0.5, -1.0, 2.0, 0.1], vec![1.5, 0.2, -0.3, 0.7]]).unwrap();
        let b = DMatrix::from_fn(8, 3, |i, j| ((i * 3 + j) as f64).sin());
        let null = NullRows::new(&b, &[4, 4], Some(&reference)).unwrap();
        let g = DMatrix::from_fn(8, 2, |i, j| ((i + 5 * j) as f64).cos());
        let q = basis(&null.whiten(&g).unwrap()).unwrap();
        let p = null.projection(&q).unwrap();
        for seed in 0..5 {
            let w = null.draw(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
            let u = null.draw_projected(&p, &mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
            assert!((q.transpose() * w - u).norm() < 1e-12);
        }
    }
}
