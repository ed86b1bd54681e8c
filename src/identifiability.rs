//! Identifiability of error parameters from a stacked identification Jacobian.
//!
//! Columns are first scaled to unit Euclidean norm (so the result does not depend on the units of
//! the parameters), then
//!
//! * the **numerical rank** is the number of singular values above `tol·σ_max`;
//! * the **identifiable subset** is chosen in *priority order*, as in §3.2 of the 5-DOF paper: a QR
//!   decomposition processes the columns in the order given and a parameter whose diagonal
//!   element `|R_jj|` (its distance from the span of the parameters kept before it) is below `tol`
//!   is redundant. Reordering the parameters changes which ones are called redundant, never how
//!   many;
//! * the rank-revealing **column-pivoted QR** gives the alternative subset that a pure numerical
//!   choice makes ([`Identifiability::pivoted`]);
//! * the **condition number** is `σ_max/σ_min` of the scaled Jacobian restricted to the identifiable
//!   subset.
use nalgebra::DMatrix;
use serde::Serialize;

/// Default relative tolerance for rank decisions on unit-norm columns. A direction weaker than
/// this (a condition number above 10⁶) is unidentifiable in any real calibration, and fitting
/// it makes Gauss–Newton chase second-order effects: a linear delta whose parallel joint axes
/// make some parameters redundant only at the nominal geometry shows four directions at 10⁻⁷
/// of the strongest (they were fitted with 10⁻⁸ and the fit diverged).
pub const DEFAULT_RANK_TOLERANCE: f64 = 1e-6;

/// Result of an identifiability analysis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Identifiability {
    /// Parameters analysed (indices into the model's parameter list), in priority order.
    pub candidates: Vec<usize>,
    /// Numerical rank of the scaled Jacobian over the candidates.
    pub rank: usize,
    /// Singular values of the column-scaled Jacobian over the candidates, largest first.
    pub singular_values: Vec<f64>,
    /// Identifiable parameters chosen in priority order.
    pub identifiable: Vec<usize>,
    /// Redundant parameters (linearly dependent on earlier ones, or without any effect).
    pub redundant: Vec<usize>,
    /// Parameters whose column is (numerically) zero: they do not affect the measurements at all.
    pub no_effect: Vec<usize>,
    /// Identifiable subset of the column-pivoted QR (a purely numerical choice).
    pub pivoted: Vec<usize>,
    /// Condition number `σ_max/σ_min` of the scaled Jacobian on the identifiable subset.
    pub condition: f64,
    /// Parameters of full rank that the data see too weakly to fix, held as drawn
    /// ([`crate::identify::weakly_seen`]); not in [`Self::identifiable`]. Empty unless the
    /// identification holds such parameters.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub weak: Vec<usize>,
    /// Parameters held as drawn as where the machine stands, a motion no instrument of the data
    /// sees ([`crate::identify::Options::gauge`]); not in [`Self::identifiable`]. Empty unless
    /// the identification holds such parameters.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub gauge: Vec<usize>,
    /// Tolerance used.
    pub tolerance: f64,
}

/// Scale the given columns of `a` to unit norm; returns the scaled matrix and the norms.
pub fn scale_columns(a: &DMatrix<f64>, cols: &[usize]) -> (DMatrix<f64>, Vec<f64>) {
    let mut out = DMatrix::zeros(a.nrows(), cols.len());
    let mut norms = Vec::with_capacity(cols.len());
    for (k, &c) in cols.iter().enumerate() {
        let col = a.column(c);
        let n = col.norm();
        norms.push(n);
        if n > 0.0 {
            out.set_column(k, &(col / n));
        }
    }
    (out, norms)
}

/// Singular values of a matrix, largest first.
pub fn singular_values(a: &DMatrix<f64>) -> Vec<f64> {
    if a.ncols() == 0 || a.nrows() == 0 {
        return Vec::new();
    }
    // nalgebra's SVD does not return on NaN / infinite input: report such a matrix as having no
    // information (all singular values NaN compare false against every tolerance, rank 0).
    if a.iter().any(|v| !v.is_finite()) {
        return vec![f64::NAN; a.ncols().min(a.nrows())];
    }
    // Work on the smaller Gram side when tall: the SVD of AᵀA squares the condition number, so use
    // a thin QR first and the SVD of its small R factor instead.
    let r = if a.nrows() > a.ncols() { a.clone().qr().r() } else { a.clone() };
    let mut s: Vec<f64> = r.singular_values().iter().copied().collect();
    s.sort_by(|x, y| y.total_cmp(x));
    s
}

/// Analyse the columns `candidates` (in priority order) of the stacked Jacobian `a`.
pub fn analyze(a: &DMatrix<f64>, candidates: &[usize], tol: f64) -> Identifiability {
    let max_norm = candidates.iter().map(|&c| a.column(c).norm()).fold(0.0, f64::max);
    let no_effect: Vec<usize> = candidates
        .iter()
        .copied()
        .filter(|&c| a.column(c).norm() <= tol * max_norm.max(f64::MIN_POSITIVE))
        .collect();
    // Columns without effect are left out of the rank computation: scaled to unit norm, their
    // round-off would look like independent information.
    let effective: Vec<usize> = candidates.iter().copied().filter(|c| !no_effect.contains(c)).collect();
    let (scaled, _) = scale_columns(a, &effective);
    let sv = singular_values(&scaled);
    let smax = sv.first().copied().unwrap_or(0.0);
    let rank = sv.iter().filter(|&&s| s > tol * smax).count();

    // Ordered QR (modified Gram–Schmidt with one re-orthogonalisation pass), skipping dependents.
    let mut basis: Vec<nalgebra::DVector<f64>> = Vec::new();
    let mut identifiable = Vec::new();
    let mut redundant = Vec::new();
    let mut k = 0;
    for &c in candidates {
        if no_effect.contains(&c) {
            redundant.push(c);
            continue;
        }
        let mut v = scaled.column(k).into_owned();
        k += 1;
        for _ in 0..2 {
            for b in &basis {
                let d = b.dot(&v);
                v.axpy(-d, b, 1.0);
            }
        }
        let rjj = v.norm();
        if rjj > tol && identifiable.len() < rank {
            basis.push(v / rjj);
            identifiable.push(c);
        } else {
            redundant.push(c);
        }
    }

    // Column-pivoted QR.
    let pivoted = {
        let qr = scaled.clone().col_piv_qr();
        let r = qr.r();
        let mut perm = DMatrix::<f64>::identity(effective.len(), effective.len());
        qr.p().permute_columns(&mut perm);
        let mut order = Vec::new();
        for j in 0..rank.min(r.nrows()).min(r.ncols()) {
            let col = perm.column(j);
            let idx = col.iter().position(|&x| x == 1.0).unwrap_or(j);
            order.push(effective[idx]);
        }
        order.sort_unstable();
        order
    };

    let condition = {
        let (sub, _) = scale_columns(a, &identifiable);
        let s = singular_values(&sub);
        match (s.first(), s.last()) {
            (Some(&hi), Some(&lo)) if lo > 0.0 => hi / lo,
            _ => f64::INFINITY,
        }
    };

    Identifiability {
        candidates: candidates.to_vec(),
        rank,
        singular_values: sv,
        identifiable,
        redundant,
        no_effect,
        pivoted,
        condition,
        weak: Vec::new(),
        gauge: Vec::new(),
        tolerance: tol,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dependent_column_is_redundant_in_priority_order() {
        // c2 = c0 + c1 → with order (0,1,2) the last is redundant; with (2,0,1) the last again.
        let a = DMatrix::from_row_slice(4, 3, &[1.0, 0.0, 1.0, 0.0, 1.0, 1.0, 2.0, 1.0, 3.0, 0.0, 3.0, 3.0]);
        let r = analyze(&a, &[0, 1, 2], 1e-10);
        assert_eq!(r.rank, 2);
        assert_eq!(r.identifiable, vec![0, 1]);
        assert_eq!(r.redundant, vec![2]);
        let r = analyze(&a, &[2, 0, 1], 1e-10);
        assert_eq!(r.identifiable, vec![2, 0]);
        assert_eq!(r.redundant, vec![1]);
        assert_eq!(r.pivoted.len(), 2);
    }

    #[test]
    fn zero_column_has_no_effect() {
        let a = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 2.0, 0.0, 3.0, 0.0]);
        let r = analyze(&a, &[0, 1], 1e-10);
        assert_eq!(r.rank, 1);
        assert_eq!(r.no_effect, vec![1]);
        assert_eq!(r.identifiable, vec![0]);
    }
}
