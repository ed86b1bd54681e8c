//! Directions the data see too weakly to fix: held as drawn.
//!
//! Rank decides which parameters the data cannot see at all. Between "not at all" and "well"
//! lie directions the data see only weakly: a tilt of the last axis when the tool ball sits a
//! fraction of a millimetre off it looks almost exactly like a shift, and a fit free to move
//! along such a direction wanders there by the noise (tens of millimetres, tens of degrees) or
//! never converges. A correction the data cannot tell from zero is no correction.
//!
//! The rule, the same for every kind of machine and instrument: in the parameters' priority
//! order, each parameter's *independent part* — its Jacobian column minus what the parameters
//! kept before it already explain (the diagonal `R_jj` of an ordered Cholesky factor of the
//! noise- and loss-weighted information matrix) — is measured against its tolerance. A
//! correction as large as the tolerance along that part changes the weighted residual by
//! `R_jj · tol_j`, in standard deviations of the noise. Where that is below [`WEAK_SEEN`] times
//! the noise the fit shows (σ̂₀, never below the stated noise), the data cannot tell a
//! tolerance-sized error there from noise: the parameter is held as drawn, its standard
//! deviation along that part being larger than its tolerance. Parameters without a tolerance
//! (frames, artifact points: where the instrument stands) are never held this way.
//!
//! The decision is made at the start with the stated noise and again where the fit converged,
//! with the noise it shows ([`super::identify`]): a direction that becomes visible is freed, one
//! that stays invisible is not left to wander. A held direction is also released where the
//! converged fit shows it beyond its own noise ([`seen_beyond_noise`]: the cost the held
//! parameters would take off, against a χ² bound at [`RELEASE_Z`] standard normal deviates):
//! data cleaner than their stated noise (a simulation, an instrument better than stated) see
//! more than the stated noise says, and noise alone releases nothing.
use super::reduced::{self, Form};
use super::Options;
use crate::error::CalibError;
use crate::measure::Measurement;
use crate::model::Mechanism;
use nalgebra::DMatrix;

/// Held directions are released when the weighted cost they would take off, in units of the
/// fit's own σ̂₀², is beyond the χ² quantile of this many standard normal deviates (Wilson–
/// Hilferty): 3.09, a 0.1 % chance that noise alone releases them.
pub const RELEASE_Z: f64 = 3.09;

/// A parameter is held when a correction of its tolerance along its independent part changes
/// the weighted residual by less than this many standard deviations of the noise: its own
/// standard deviation there is then larger than its tolerance.
pub const WEAK_SEEN: f64 = 1.0;

/// Which parameters may be held as seen too weakly, and the size of correction each is judged
/// at (its tolerance, model units: mm, rad).
#[derive(Debug, Clone, PartialEq)]
pub struct WeakHold {
    /// Per parameter (the mechanism's order): its tolerance, or `None` for a parameter that is
    /// never held this way (frames, artifact points, dimensionless terms).
    pub tolerance: Vec<Option<f64>>,
}

impl WeakHold {
    /// The tolerances of `params` under `of` (a parameter's unit → its tolerance), placements
    /// (frames, artifact points) excepted.
    pub fn from_params(params: &[crate::params::Param], of: impl Fn(crate::params::Unit) -> Option<f64>) -> WeakHold {
        WeakHold {
            tolerance: params.iter().map(|p| if p.is_placement() { None } else { of(p.unit) }).collect(),
        }
    }
}

/// The parameters of `candidates` (priority order) that `gram` (the weighted information
/// matrix `AᵀA`, p × p) sees too weakly under `hold`, with the noise scaled by `noise_factor`
/// (σ̂₀ where the fit shows more noise than stated, else 1). Ordered Cholesky on the
/// column-scaled matrix: a held parameter is left out of the basis the later ones are measured
/// against, so that each held direction is counted once.
pub fn weakly_seen(gram: &DMatrix<f64>, candidates: &[usize], hold: &WeakHold, noise_factor: f64) -> Vec<usize> {
    let norms: Vec<f64> = candidates.iter().map(|&c| gram[(c, c)].max(0.0).sqrt()).collect();
    // Rows of the factor kept so far, each over the candidates.
    let mut basis: Vec<Vec<f64>> = Vec::new();
    let mut held = Vec::new();
    let n = candidates.len();
    for (j, &cj) in candidates.iter().enumerate() {
        if norms[j] <= 0.0 {
            continue;
        }
        let scaled = |a: usize, b: usize| gram[(candidates[a], candidates[b])] / (norms[a] * norms[b]);
        // R_jj² = 1 − Σ_k R_kj² over the kept rows k (unit diagonal after scaling).
        let mut row = vec![0.0; n];
        let mut sum = 0.0;
        let mut coefficients = Vec::with_capacity(basis.len());
        for rk in &basis {
            coefficients.push(rk[j]);
            sum += rk[j] * rk[j];
        }
        let rjj = (1.0 - sum).max(0.0).sqrt();
        let seen = rjj * norms[j];
        let weak = hold
            .tolerance
            .get(cj)
            .copied()
            .flatten()
            .is_some_and(|tol| seen * tol < WEAK_SEEN * noise_factor.max(1.0));
        if weak || rjj <= 1e-12 {
            if weak {
                held.push(cj);
            }
            continue;
        }
        // The new row of R: R_ji = (S_ji − Σ_k R_kj R_ki) / R_jj for the later candidates i.
        for i in (j + 1)..n {
            let mut s = scaled(j, i);
            for (c, rk) in coefficients.iter().zip(&basis) {
                s -= c * rk[i];
            }
            row[i] = s / rjj;
        }
        row[j] = rjj;
        basis.push(row);
    }
    held
}

/// Whether the parameters `held`, freed beside `identifiable` at `model` (a converged fit with
/// noise σ̂₀ `sigma0`), would lower the weighted residual by more than noise can: the reduction
/// of `|r|²` (the Gauss–Newton step's, on both sets against the identifiable set alone) against
/// the χ² bound of [`RELEASE_Z`] for as many degrees of freedom as held parameters, in units of
/// `σ̂₀²`. A pose the model cannot evaluate is an error.
pub(super) fn seen_beyond_noise<M: Mechanism + ?Sized>(
    model: &M,
    data: &[Measurement],
    opts: &Options,
    noise: &crate::measure::Noise,
    identifiable: &[usize],
    held: &[usize],
    sigma0: f64,
) -> Result<bool, CalibError> {
    if held.is_empty() {
        return Ok(false);
    }
    let ev = reduced::evaluate(model, data, noise, opts.loss)?;
    let system = reduced::factor(model, data, noise, &ev, Form::Gram)?;
    let gradient = match &system {
        reduced::System::Gram { g, .. } => g.clone(),
        reduced::System::Triangular { r, z } => r.transpose() * z,
    };
    let both: Vec<usize> = identifiable.iter().chain(held).copied().collect();
    let with = gradient.dot(&system.solve(&both, 0.0, Some(both.len()))?);
    let without = gradient.dot(&system.solve(identifiable, 0.0, Some(identifiable.len()))?);
    Ok(with - without > chi2_bound(held.len()) * sigma0 * sigma0)
}

/// The χ² quantile of [`RELEASE_Z`] standard normal deviates for `k` degrees of freedom
/// (Wilson–Hilferty): how much `|r|²`, in units of σ̂₀², `k` parameters can take off by noise
/// alone.
pub(super) fn chi2_bound(k: usize) -> f64 {
    let k = k.max(1) as f64;
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + RELEASE_Z * a.sqrt()).powi(3)
}

/// Condition number `σ_max/σ_min` of the column-scaled Jacobian on `cols`, from its
/// information matrix `gram` (p × p): the square root of the scaled Gram matrix's eigenvalue
/// ratio.
pub fn condition(gram: &DMatrix<f64>, cols: &[usize]) -> f64 {
    let norms: Vec<f64> = cols.iter().map(|&c| gram[(c, c)].max(0.0).sqrt()).collect();
    if cols.is_empty() || norms.iter().any(|&n| n <= 0.0) {
        return f64::INFINITY;
    }
    let n = DMatrix::from_fn(cols.len(), cols.len(), |i, j| gram[(cols[i], cols[j])] / (norms[i] * norms[j]));
    let eig = n.symmetric_eigenvalues();
    let (lo, hi) = eig.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    if lo > 0.0 {
        (hi / lo).sqrt()
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Columns a, b (seen well) and c = a + ε·e₃: beyond a, c is seen along e₃ only, by ε.
    fn gram(eps: f64) -> DMatrix<f64> {
        let a = DMatrix::from_row_slice(4, 3, &[10.0, 0.0, 10.0, 0.0, 10.0, 0.0, 0.0, 0.0, eps, 20.0, 10.0, 20.0]);
        a.transpose() * a
    }

    #[test]
    fn a_parameter_seen_below_its_tolerance_is_held_and_one_seen_well_is_not() {
        let hold = WeakHold {
            tolerance: vec![Some(1.0); 3],
        };
        // c's independent part is ε: a correction of 1 (its tolerance) changes the residual by ε.
        assert_eq!(weakly_seen(&gram(0.5), &[0, 1, 2], &hold, 1.0), vec![2]);
        assert!(weakly_seen(&gram(3.0), &[0, 1, 2], &hold, 1.0).is_empty());
        // More noise than stated: the same 3.0 is now too weak.
        assert_eq!(weakly_seen(&gram(3.0), &[0, 1, 2], &hold, 4.0), vec![2]);
        // In another order the last one is held: the direction is counted once.
        assert_eq!(weakly_seen(&gram(0.5), &[2, 0, 1], &hold, 1.0), vec![0]);
    }

    #[test]
    fn parameters_without_a_tolerance_are_never_held() {
        let hold = WeakHold {
            tolerance: vec![Some(1.0), Some(1.0), None],
        };
        assert!(weakly_seen(&gram(0.5), &[0, 1, 2], &hold, 1.0).is_empty());
    }
}
