//! Corrections judged against the model's tolerances without judging the gauge.
//!
//! The identified corrections are one split among parameters that act alike: the frames and the
//! geometry share directions (a base offset and the measurement frame), and redundant parameters
//! take the minimum-norm share of what they jointly explain. A tolerance on the values of that
//! split judges the split, not the machine: a machine whose every coordinate stays within 5 mm can
//! come out as `S1x +6.7 mm` once the frames took their minimum-norm share.
//!
//! The check here asks the gauge-invariant question instead: **is there a parameter set that
//! the data cannot tell from the identified one and that stays within the tolerances?** Two kinds
//! of moves `Δ` of the corrections `δ` leave the data explained:
//!
//! - moves along the null space of the identification Jacobian (the directions the data do not
//!   see at all, found from the information matrix at the solution with the fit's own rank);
//! - moves along directions the data see only weakly, as far as the noise could have put the
//!   solution there: `Δᵀ·(AᵀA/σ̂₀²)·Δ ≤ COVERAGE²`, the confidence ellipsoid of the fit
//!   (`AᵀA` the information matrix, `σ̂₀²·(AᵀA)⁺` the reported covariance). A direction with
//!   standard deviation σ may move by up to [`COVERAGE`]·σ; a parameter the data pin down
//!   (σ 0.08 mm) cannot move by more than about twice that.
//!
//! The frames and artifact points are not limited at all. Among the parameter sets `δ + Δ` so
//! consistent with the data, the check looks for the one whose largest `|δᵢ + Δᵢ| / tolᵢ` is
//! smallest, and reports that ratio and the parameters beyond their tolerance there.
//!
//! Why the ellipsoid and not only the null space: with only the exact null space, a direction the
//! data barely see (σ 13 mm on a real Panda calibrated from two sockets) is held at its
//! minimum-norm value, and the minimax pays for keeping it small by pushing parameters the data
//! pin down far beyond their tolerance (a link offset with σ 0.08 mm moved to −17.6 mm): a
//! split that no data support, so a failure found there is no evidence against the machine. A
//! per-parameter discount (COVERAGE standard deviations off each value of that split) does not
//! repair it: the deviations are those of the minimum-norm split, not of the directions the
//! minimax moved along. The ellipsoid is the statement "no linear combination of the parameters
//! moves by more than COVERAGE of its own standard deviation": it reduces to the per-parameter
//! rule for a single parameter, and is the distance (in standard deviations) from the fit to the
//! set of machines the tolerances allow. A machine beyond its tolerances in every set so
//! consistent with the data is beyond them: a real error of 120 mm in a link the data see stays
//! 120 mm, whatever its neighbours do.
//!
//! The search: the smallest scale `s` of the tolerances at which the scaled tolerance box meets
//! the consistent set, by bisection on `s`; at each `s` the smallest `Δᵀ·AᵀA·Δ` over the box
//! (a convex quadratic over a box) by accelerated projected gradient, stopped as soon as it is
//! within the ellipsoid (a point is found) or a lower bound from the gradient shows that it
//! cannot be (Frank–Wolfe gap). The unlimited parameters are minimised out exactly first (Schur
//! complement), and directions so weakly seen that no move within the tolerances could cost more
//! than 1 % of the ellipsoid's radius² are treated as unseen, the radius shrunk by that 1 %
//! (conservative: a set found is within the ellipsoid); without that, eigenvalues 10⁸ apart
//! (the Panda's) leave the gradient iteration far from converged. The exact-null-space minimax
//! (Lawson's iteratively re-weighted least squares) gives the starting upper bound, and is the
//! answer when it already meets the tolerances (the common case) or when σ̂₀ is zero.
use crate::identify::Identification;
use crate::io::model_file::Tolerances;
use crate::model::Mechanism;
use crate::report::{Beyond, ToleranceCheck};
use nalgebra::{DMatrix, DVector};

/// Standard deviations by which the noise could have moved any combination of the corrections:
/// the radius of the confidence ellipsoid the corrections may move in (two: a correction beyond
/// the tolerance by less than that is not evidence).
pub const COVERAGE: f64 = 2.0;

/// Bisection on the tolerance scale stops at this relative width.
const SCALE_PRECISION: f64 = 0.005;

/// Iterations of the accelerated projected gradient at one tolerance scale (undecided after
/// these counts as not within the ellipsoid: the ratio found can only be too large).
const QP_ITERATIONS: usize = 4000;

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
    let mut x = minimax(&x0, &n);
    let inf = |x: &DVector<f64>| x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    if inf(&x) > 1.0 {
        let tol: Vec<Option<f64>> = free.iter().map(|&i| limit(i).filter(|t| *t > 0.0)).collect();
        let delta: Vec<f64> = free.iter().map(|&i| id.delta[i]).collect();
        let upper = inf(&x);
        let ellipsoid = Ellipsoid::new(&id.information, free, id.identifiability.rank, id.sigma0, &delta, &tol, upper);
        if let Some(moved) = ellipsoid.and_then(|e| e.closest_scale(&delta, &tol, upper)) {
            x = DVector::from_iterator(limited.len(), limited.iter().map(|&(k, _, t)| moved[k] / t));
        }
    }
    let mut beyond: Vec<Beyond> = limited
        .iter()
        .zip(x.iter())
        .filter(|(_, r)| r.abs() > 1.0)
        .map(|(&(_, i, t), r)| {
            let (f, unit) = params[i].unit.display();
            Beyond {
                name: params[i].name.clone(),
                value: r * t * f,
                unit: unit.to_string(),
                ratio: r.abs(),
            }
        })
        .collect();
    beyond.sort_by(|a, b| b.ratio.total_cmp(&a.ratio).then_with(|| a.name.cmp(&b.name)));
    ToleranceCheck { ratio: inf(&x), beyond }
}

/// The confidence ellipsoid of the fit seen from the tolerance-limited parameters the data see,
/// in coordinates scaled by the square root of their information (`dₖ = Δₖ·normₖ`): the
/// unlimited parameters (frames, artifact points) are minimised out exactly (the Schur
/// complement of their block), so `dᵀ·h·d ≤ radius2` is consistent with the data for some value
/// of theirs.
struct Ellipsoid {
    /// Indices (into `free`) of the limited parameters the data see.
    seen: Vec<usize>,
    /// Square root of each one's information.
    norms: Vec<f64>,
    /// The scaled information on the fit's rank, the unlimited parameters minimised out, and
    /// the directions no move within the tolerances could make count dropped.
    h: DMatrix<f64>,
    /// Lipschitz constant of the gradient of `dᵀ·h·d` (twice the largest eigenvalue).
    lipschitz: f64,
    /// `(COVERAGE·σ̂₀)²`, less what the dropped directions could add.
    radius2: f64,
}

/// `m⁺` of a symmetric positive semi-definite matrix (eigenvalues below `1e-12` of the largest
/// count as zero).
fn pseudo_inverse(m: &DMatrix<f64>) -> DMatrix<f64> {
    let eig = m.clone().symmetric_eigen();
    let top = eig.eigenvalues.iter().fold(0.0_f64, |a, v| a.max(*v));
    let mut inv = DMatrix::zeros(m.nrows(), m.ncols());
    for (e, &l) in eig.eigenvalues.iter().enumerate() {
        if l > 1e-12 * top && top > 0.0 {
            let v = eig.eigenvectors.column(e);
            inv += v * v.transpose() / l;
        }
    }
    inv
}

impl Ellipsoid {
    /// For the corrections `delta` (indexed like `free`) and the tolerances `tol` up to the
    /// scale `upper`.
    fn new(
        information: &DMatrix<f64>,
        free: &[usize],
        rank: usize,
        sigma0: f64,
        delta: &[f64],
        tol: &[Option<f64>],
        upper: f64,
    ) -> Option<Ellipsoid> {
        let max = free.iter().copied().max()?;
        if information.nrows() <= max || information.iter().any(|v| !v.is_finite()) || !(sigma0 > 0.0 && sigma0.is_finite()) {
            return None;
        }
        let all: Vec<f64> = free.iter().map(|&i| information[(i, i)].max(0.0).sqrt()).collect();
        let scale = all.iter().fold(0.0_f64, |m, v| m.max(*v));
        let seen: Vec<usize> = (0..free.len()).filter(|&k| scale > 0.0 && all[k] > 1e-12 * scale).collect();
        let m = seen.len();
        let g = DMatrix::from_fn(m, m, |a, b| {
            information[(free[seen[a]], free[seen[b]])] / (all[seen[a]] * all[seen[b]])
        });
        // The information on the fit's rank.
        let eig = g.symmetric_eigen();
        let mut order: Vec<usize> = (0..m).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let mut full = DMatrix::zeros(m, m);
        for &e in order.iter().take(rank.min(m)) {
            let v = eig.eigenvectors.column(e);
            full += eig.eigenvalues[e].max(0.0) * v * v.transpose();
        }
        // The unlimited parameters take their best value for any move of the limited ones.
        let (lim, unl): (Vec<usize>, Vec<usize>) = (0..m).partition(|&a| tol[seen[a]].is_some());
        let block = |r: &[usize], c: &[usize]| DMatrix::from_fn(r.len(), c.len(), |i, j| full[(r[i], c[j])]);
        let mut h = block(&lim, &lim);
        if !unl.is_empty() {
            let lu = block(&lim, &unl);
            h -= &lu * pseudo_inverse(&block(&unl, &unl)) * lu.transpose();
        }
        let h = (&h + h.transpose()) * 0.5;
        let norms: Vec<f64> = lim.iter().map(|&a| all[seen[a]]).collect();
        let seen: Vec<usize> = lim.iter().map(|&a| seen[a]).collect();
        // Directions along which no move within the tolerances (scale `upper`) costs more than
        // 1 % of the radius² are as good as unseen: dropped (they leave a far better conditioned
        // problem), and the radius shrunk by what they could have cost.
        let reach2: f64 = seen
            .iter()
            .zip(&norms)
            .map(|(&k, n)| (n * (upper * tol[k].unwrap_or(0.0) + delta[k].abs())).powi(2))
            .sum();
        let radius2 = (COVERAGE * sigma0).powi(2);
        let cut = 0.01 * radius2 / reach2.max(f64::MIN_POSITIVE);
        let eig = h.symmetric_eigen();
        let mut h = DMatrix::zeros(seen.len(), seen.len());
        let mut top = 0.0_f64;
        for (e, &l) in eig.eigenvalues.iter().enumerate() {
            if l > cut {
                let v = eig.eigenvectors.column(e);
                h += l * v * v.transpose();
                top = top.max(l);
            }
        }
        (top > 0.0).then_some(Ellipsoid {
            seen,
            norms,
            h,
            lipschitz: 2.0 * top,
            radius2: 0.99 * radius2,
        })
    }

    /// The smallest scale `s ≤ upper` of the tolerances `tol` (indexed like `free`; `None`: not
    /// limited) at which a point of the ellipsoid around `delta` lies within `s·tol`, to
    /// [`SCALE_PRECISION`], and that point (values indexed like `free`; unseen parameters at 0
    /// when limited, else as identified). `None` when none is found below `upper`.
    fn closest_scale(&self, delta: &[f64], tol: &[Option<f64>], upper: f64) -> Option<Vec<f64>> {
        let (mut lo, mut hi) = (0.0, upper);
        let mut best: Option<DVector<f64>> = None;
        let mut d = DVector::zeros(self.seen.len());
        while hi - lo > SCALE_PRECISION * hi {
            let s = 0.5 * (lo + hi);
            match self.within(delta, tol, s, &d) {
                Some(found) => {
                    hi = s;
                    d = found.clone();
                    best = Some(found);
                }
                None => lo = s,
            }
        }
        let d = best?;
        // Limited parameters the data do not see at all can be set to zero.
        let mut moved: Vec<f64> = delta.iter().zip(tol).map(|(v, t)| if t.is_some() { 0.0 } else { *v }).collect();
        for (a, &k) in self.seen.iter().enumerate() {
            moved[k] = delta[k] + d[a] / self.norms[a];
        }
        Some(moved)
    }

    /// A point `d` of the ellipsoid with `delta + d/norms` within `s·tol`, searched by
    /// accelerated projected gradient on `dᵀ·h·d` over that box from `start`; `None` when the
    /// smallest value over the box is shown to lie outside the ellipsoid or none is found in
    /// [`QP_ITERATIONS`].
    fn within(&self, delta: &[f64], tol: &[Option<f64>], s: f64, start: &DVector<f64>) -> Option<DVector<f64>> {
        let bound = |a: usize, sign: f64| {
            let t = tol[self.seen[a]].unwrap_or(f64::INFINITY);
            self.norms[a] * (sign * s * t - delta[self.seen[a]])
        };
        let lo = DVector::from_fn(self.seen.len(), |a, _| bound(a, -1.0));
        let hi = DVector::from_fn(self.seen.len(), |a, _| bound(a, 1.0));
        let clamp = |v: DVector<f64>| v.zip_zip_map(&lo, &hi, |v, l, h| v.max(l).min(h));
        let mut x = clamp(start.clone());
        let mut y = x.clone();
        let (mut t, mut previous) = (1.0_f64, f64::INFINITY);
        for _ in 0..QP_ITERATIONS {
            let g = 2.0 * &self.h * &y;
            let next = clamp(&y - g / self.lipschitz);
            let hx = &self.h * &next;
            let value = next.dot(&hx);
            if value <= self.radius2 {
                return Some(next);
            }
            // Convexity: the value over the box is at least value + min over the box of the
            // gradient's linear form.
            let gap: f64 = (0..next.len())
                .map(|a| {
                    let ga = 2.0 * hx[a];
                    let to = if ga > 0.0 { lo[a] } else { hi[a] };
                    if ga == 0.0 {
                        0.0
                    } else {
                        ga * (to - next[a])
                    }
                })
                .sum();
            if value + gap > self.radius2 {
                return None;
            }
            let t_next = 0.5 * (1.0 + (1.0 + 4.0 * t * t).sqrt());
            y = if value > previous {
                // Adaptive restart: the momentum overshot.
                t = 1.0;
                next.clone()
            } else {
                &next + (t - 1.0) / t_next * (&next - &x)
            };
            if value <= previous {
                t = t_next;
            }
            previous = value;
            x = next;
        }
        None
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
    fn a_weakly_seen_correction_may_move_within_its_uncertainty() {
        // The second parameter is seen with σ 1000 (information 1e-6, σ̂₀ 1): its 10 can be 0.
        let info = DMatrix::from_diagonal(&DVector::from_vec(vec![1e6, 1e-6]));
        let (delta, tol) = ([0.5, 10.0], [Some(1.0), Some(1.0)]);
        let e = Ellipsoid::new(&info, &[0, 1], 2, 1.0, &delta, &tol, 10.0).unwrap();
        let moved = e.closest_scale(&delta, &tol, 10.0).unwrap();
        assert!(moved.iter().all(|v| v.abs() <= 1.0), "{moved:?}");
    }

    #[test]
    fn a_well_seen_correction_stays_beyond() {
        // σ 0.001 on both: 3 stays 3 (less the 2σ the noise could explain).
        let info = DMatrix::from_diagonal(&DVector::from_vec(vec![1e6, 1e6]));
        let (delta, tol) = ([3.0, 0.0], [Some(1.0), Some(1.0)]);
        let e = Ellipsoid::new(&info, &[0, 1], 2, 1.0, &delta, &tol, 3.0).unwrap();
        // Nothing below 3·(1 − SCALE_PRECISION) … only the upper bound itself, so none is found.
        let moved = e.closest_scale(&delta, &tol, 3.0);
        assert!(moved.as_ref().is_none_or(|m| m[0] > 2.98 && m[0] <= 3.0), "{moved:?}");
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
