//! Corrections judged against the model's tolerances without judging the gauge.
//!
//! The identified corrections are one split among parameters that act alike: the frames and the
//! geometry share directions (a base offset and the measurement frame), and redundant parameters
//! take the minimum-norm share of what they jointly explain. A tolerance on the values of that
//! split judges the split, not the machine: a machine whose every coordinate stays within 5 mm can
//! come out as `S1x +6.7 mm` once the frames took their minimum-norm share.
//!
//! The check here asks the gauge-invariant question instead: **is there a parameter set that
//! predicts the same measurements to first order and stays within the tolerances?** The
//! corrections `δ` can move freely along the null space `N` of the identification Jacobian (the
//! directions the data cannot see, found from the information matrix at the solution with the
//! fit's own rank), and the frames are not limited at all. Among `δ + N·z` it looks for the set
//! whose largest `|δᵢ| / tolᵢ` is smallest (a minimax problem, solved by Lawson's iteratively
//! re-weighted least squares), and reports each parameter that stays beyond its tolerance there
//! with its smallest value. A parameter beyond its tolerance in that set is beyond it in every
//! equivalent one. The ratio discounts [`COVERAGE`] standard deviations of each parameter (as
//! reported, in the minimum-norm split): what the noise alone could have moved is not evidence.
use crate::identify::Identification;
use crate::io::model_file::Tolerances;
use crate::model::Mechanism;
use crate::report::{Beyond, ToleranceCheck};
use nalgebra::{DMatrix, DVector};

/// Standard deviations of a correction the noise could explain: removed before it is compared
/// with its tolerance (two: a correction beyond the tolerance by less than that is not evidence).
pub const COVERAGE: f64 = 2.0;

/// Iterations of Lawson's re-weighting (each a small least-squares solve on the null space).
const LAWSON_ITERATIONS: usize = 60;

/// Judge the corrections of `id` (free parameters `free`) against `tolerances` in the gauge that
/// keeps them smallest relative to their tolerances (see the module docs). Parameters of frames
/// and artifact points ([`crate::params::Param::is_placement`]) and dimensionless ones are not
/// limited.
pub fn tolerance_check<M: Mechanism>(id: &Identification<M>, free: &[usize], tolerances: &Tolerances) -> ToleranceCheck {
    let params = id.model.params();
    let limit = |i: usize| (!params[i].is_placement()).then(|| tolerances.of(params[i].unit)).flatten();
    let null = null_space(&id.information, free, id.identifiability.rank);
    // Rows: the tolerance-limited free parameters, scaled by their tolerance.
    let limited: Vec<(usize, usize, f64)> = free
        .iter()
        .enumerate()
        .filter_map(|(k, &i)| limit(i).filter(|t| *t > 0.0).map(|t| (k, i, t)))
        .collect();
    let x0 = DVector::from_iterator(limited.len(), limited.iter().map(|&(_, i, t)| id.delta[i] / t));
    let n = DMatrix::from_fn(limited.len(), null.ncols(), |r, c| null[(limited[r].0, c)] / limited[r].2);
    let x = minimax(&x0, &n);
    // What the noise alone could have pushed there is no evidence: each ratio is taken after
    // removing COVERAGE standard deviations of the parameter.
    let excess: Vec<f64> = limited
        .iter()
        .zip(x.iter())
        .map(|(&(_, i, t), r)| (r.abs() - COVERAGE * id.std_dev[i].abs() / t).max(0.0))
        .collect();
    let mut beyond: Vec<Beyond> = limited
        .iter()
        .zip(x.iter())
        .zip(&excess)
        .filter(|(_, e)| **e > 1.0)
        .map(|((&(_, i, t), r), e)| {
            let (f, unit) = params[i].unit.display();
            Beyond {
                name: params[i].name.clone(),
                value: r * t * f,
                unit: unit.to_string(),
                ratio: *e,
            }
        })
        .collect();
    beyond.sort_by(|a, b| b.ratio.total_cmp(&a.ratio));
    ToleranceCheck {
        ratio: excess.iter().fold(0.0_f64, |m, v| m.max(*v)),
        beyond,
    }
}

/// Basis (columns, indexed like `free`) of the directions among the free parameters that the
/// data do not see: the eigenvectors of the column-scaled information matrix beyond the fit's
/// rank, and every parameter without any effect.
fn null_space(information: &DMatrix<f64>, free: &[usize], rank: usize) -> DMatrix<f64> {
    let n = free.len();
    if information.nrows() < free.iter().copied().max().map_or(0, |m| m + 1) || information.iter().any(|v| !v.is_finite()) {
        return DMatrix::zeros(n, 0);
    }
    let norms: Vec<f64> = free.iter().map(|&i| information[(i, i)].max(0.0).sqrt()).collect();
    let scale = norms.iter().fold(0.0_f64, |m, v| m.max(*v));
    let seen: Vec<usize> = (0..n).filter(|&k| norms[k] > 1e-12 * scale && scale > 0.0).collect();
    let mut columns: Vec<DVector<f64>> = (0..n)
        .filter(|k| !seen.contains(k))
        .map(|k| {
            let mut e = DVector::zeros(n);
            e[k] = 1.0;
            e
        })
        .collect();
    let m = seen.len();
    if m > rank {
        let g = DMatrix::from_fn(m, m, |a, b| {
            information[(free[seen[a]], free[seen[b]])] / (norms[seen[a]] * norms[seen[b]])
        });
        let eig = g.symmetric_eigen();
        let mut order: Vec<usize> = (0..m).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        for &e in order.iter().take(m - rank) {
            let mut v = DVector::zeros(n);
            for (a, &k) in seen.iter().enumerate() {
                v[k] = eig.eigenvectors[(a, e)] / norms[k];
            }
            columns.push(v);
        }
    }
    if columns.is_empty() {
        DMatrix::zeros(n, 0)
    } else {
        DMatrix::from_columns(&columns)
    }
}

/// The point of `x0 + N·z` with the smallest largest component (Lawson's algorithm: weighted
/// least squares whose weights grow where the components are largest), and never worse than
/// `x0` or the plain least-squares point. It stops as soon as a point within ±1 is found: only
/// whether the tolerances can be met, and by how much they are missed, matters.
fn minimax(x0: &DVector<f64>, n: &DMatrix<f64>) -> DVector<f64> {
    let inf = |x: &DVector<f64>| x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    if n.ncols() == 0 || x0.is_empty() {
        return x0.clone();
    }
    let mut best = x0.clone();
    let mut w = DVector::from_element(x0.len(), 1.0 / x0.len() as f64);
    for _ in 0..LAWSON_ITERATIONS {
        // min Σ wᵢ (x0 + N z)ᵢ²: (Nᵀ W N) z = −Nᵀ W x0, solved by SVD (N may be rank deficient
        // on the limited rows).
        let wn = DMatrix::from_fn(n.nrows(), n.ncols(), |r, c| w[r].sqrt() * n[(r, c)]);
        let wx = DVector::from_iterator(x0.len(), x0.iter().zip(w.iter()).map(|(x, w)| -w.sqrt() * x));
        let Ok(z) = wn.svd(true, true).solve(&wx, 1e-12) else {
            break;
        };
        let x = x0 + n * z;
        if !x.iter().all(|v| v.is_finite()) {
            break;
        }
        if inf(&x) < inf(&best) {
            best = x.clone();
        }
        // Within the tolerances already (the common case): no need for the minimax itself.
        if inf(&best) <= 1.0 {
            break;
        }
        let total: f64 = w.iter().zip(x.iter()).map(|(w, x)| w * x.abs()).sum();
        if total <= 0.0 {
            break;
        }
        for (wi, xi) in w.iter_mut().zip(x.iter()) {
            *wi = *wi * xi.abs() / total;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minimax_spreads_a_redundant_pair_evenly() {
        // Two parameters that act only through their sum: (4, 0) is the same as (2, 2).
        let x0 = DVector::from_vec(vec![4.0, 0.0]);
        let n = DMatrix::from_vec(2, 1, vec![1.0, -1.0]);
        let x = minimax(&x0, &n);
        assert!((x[0] - 2.0).abs() < 1e-6 && (x[1] - 2.0).abs() < 1e-6, "{x}");
    }

    #[test]
    fn minimax_without_freedom_keeps_the_values() {
        let x0 = DVector::from_vec(vec![3.0, -1.0]);
        let x = minimax(&x0, &DMatrix::zeros(2, 0));
        assert_eq!(x, x0);
    }

    #[test]
    fn minimax_reaches_the_l_infinity_optimum_of_three() {
        // x = (6, 0, 0) + z·(1, −1, −1) = (6 + z, −z, −z): the largest component is smallest at
        // z = −3, (3, 3, 3).
        let x0 = DVector::from_vec(vec![6.0, 0.0, 0.0]);
        let n = DMatrix::from_vec(3, 1, vec![1.0, -1.0, -1.0]);
        let x = minimax(&x0, &n);
        assert!(x.iter().all(|v| (v.abs() - 3.0).abs() < 1e-3), "{x}");
    }

    #[test]
    fn null_space_has_the_unseen_directions() {
        // Columns a, b, c with c = a + b seen only through a + b … a rank-2 information matrix.
        let a = DMatrix::from_row_slice(3, 3, &[1.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0]);
        let g = a.tr_mul(&a);
        let n = null_space(&g, &[0, 1, 2], 2);
        assert_eq!(n.ncols(), 1);
        let v = n.column(0);
        assert!((a * v).norm() < 1e-12 * v.norm());
    }
}
