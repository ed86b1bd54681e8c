//! Observability indices of a set of measurement configurations.
//!
//! All indices are computed from the singular values `σ_1 ≥ … ≥ σ_k` of the stacked, weighted and
//! column-scaled identification Jacobian `A` (`m × k`, `m` residual rows, `k` identifiable
//! parameters; scaling in [`super::jacobians`]), equivalently from the eigenvalues `λ_i = σ_i²` of
//! the information matrix `M = AᵀA`. Every index is "larger is better":
//!
//! | index | definition | reference |
//! |---|---|---|
//! | O1 | `(σ_1⋯σ_k)^(1/k) / √m` | Borm & Menq |
//! | O2 | `σ_min / σ_max` (the reciprocal of the 5-DOF paper's `O_T`, eq. (37)) | Driels & Pathre |
//! | O3 | `σ_min` | Nahvi & Hollerbach |
//! | O4 | `σ_min² / σ_max` (noise amplification index) | Nahvi & Hollerbach |
//! | O5 | `1 / Σ 1/σ_i` | Sun & Hollerbach |
//! | D  | `log det M = 2 Σ log σ_i` (D-optimality) | |
//!
//! A rank-deficient set has `σ_min = 0`: O1–O5 are 0 and D is `−∞`.
use nalgebra::DMatrix;
use serde::Serialize;

/// Relative tolerance on `σ_min/σ_max` below which an information matrix counts as singular.
pub const INFORMATION_RANK_TOLERANCE: f64 = 1e-7;

/// Which index a selection maximises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
pub enum Criterion {
    /// D-optimality, `log det M`.
    #[default]
    DOptimal,
    /// Borm–Menq `(Πσ)^(1/k)/√m`.
    O1,
    /// `σ_min/σ_max` (minimising the paper's `O_T = 1/O2`).
    O2,
    /// `σ_min`.
    O3,
    /// `σ_min²/σ_max`.
    O4,
    /// `1/Σ(1/σ_i)`.
    O5,
}

impl Criterion {
    /// Whether the criterion is a monotone function of `log det M` for a fixed number of rows
    /// (D and O1), so its best single addition is found exactly by the determinant lemma.
    pub fn is_determinant_based(self) -> bool {
        matches!(self, Criterion::DOptimal | Criterion::O1)
    }
}

impl std::str::FromStr for Criterion {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "d" | "dopt" | "d-optimal" | "logdet" => Ok(Criterion::DOptimal),
            "o1" => Ok(Criterion::O1),
            "o2" => Ok(Criterion::O2),
            "o3" => Ok(Criterion::O3),
            "o4" => Ok(Criterion::O4),
            "o5" => Ok(Criterion::O5),
            _ => Err(format!("unknown criterion '{s}' (expected d, o1, o2, o3, o4 or o5)")),
        }
    }
}

impl std::fmt::Display for ObservabilityIndices {
    /// "O1 … O2 … (O_T …)  O3 …  O4 …  O5 …  log det …", as `kinecal plan` prints them.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "O1 {:.4e}  O2 {:.4e} (O_T {:.3})  O3 {:.4e}  O4 {:.4e}  O5 {:.4e}  log det {:.3}",
            self.o1, self.o2, self.o_t, self.o3, self.o4, self.o5, self.log_det
        )
    }
}

impl std::fmt::Display for Criterion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = match self {
            Criterion::DOptimal => "D (log det)",
            Criterion::O1 => "O1",
            Criterion::O2 => "O2",
            Criterion::O3 => "O3",
            Criterion::O4 => "O4",
            Criterion::O5 => "O5",
        };
        f.write_str(s)
    }
}

/// The observability indices of one configuration set.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ObservabilityIndices {
    /// `(σ_1⋯σ_k)^(1/k)/√m`.
    pub o1: f64,
    /// `σ_min/σ_max`.
    pub o2: f64,
    /// `σ_min`.
    pub o3: f64,
    /// `σ_min²/σ_max`.
    pub o4: f64,
    /// `1/Σ(1/σ_i)`.
    pub o5: f64,
    /// `log det(AᵀA)`.
    pub log_det: f64,
    /// The paper's `O_T = σ_max/σ_min` (eq. (37)); `∞` when rank-deficient.
    pub o_t: f64,
    /// Singular values, largest first (`k` of them).
    pub singular_values: Vec<f64>,
    /// Residual rows `m`.
    pub rows: usize,
}

impl ObservabilityIndices {
    /// The number of columns the set determines: all `k` when it has full rank (a finite
    /// `log det`), else the singular values above `1e-12·σ_max`.
    pub fn rank(&self) -> usize {
        if self.log_det.is_finite() {
            return self.singular_values.len();
        }
        let smax = self.singular_values.first().copied().unwrap_or(0.0);
        self.singular_values.iter().filter(|v| **v > 1e-12 * smax && **v > 0.0).count()
    }

    /// One line when the set cannot identify its `k` columns (rank below `k`), naming the
    /// rows, the rank and the remedy; `None` at full rank.
    pub fn rank_shortfall(&self, what: &str) -> Option<String> {
        let k = self.singular_values.len();
        let rank = self.rank();
        (!self.log_det.is_finite() || rank < k).then(|| {
            format!(
                "{what} determine only {rank} of the {k} identifiable columns (log det −∞): it cannot identify the model; plan more rows (-n), or --force to write it anyway"
            )
        })
    }

    /// Indices from the `k` singular values (any order; missing ones count as 0 when fewer than
    /// `k` are given) of an `rows × k` Jacobian.
    pub fn from_singular_values(sv: &[f64], k: usize, rows: usize) -> Self {
        Self::with_rank_tolerance(sv, k, rows, 0.0)
    }

    /// As [`Self::from_singular_values`], but a set whose `σ_min ≤ tol·σ_max` counts as
    /// rank-deficient (O1–O5 = 0, D = −∞).
    pub fn with_rank_tolerance(sv: &[f64], k: usize, rows: usize, tol: f64) -> Self {
        let mut s: Vec<f64> = sv.iter().map(|v| v.max(0.0)).collect();
        s.resize(k.max(s.len()), 0.0);
        s.sort_by(|a, b| b.total_cmp(a));
        let smax = s.first().copied().unwrap_or(0.0);
        let smin = s.last().copied().unwrap_or(0.0);
        let kf = s.len() as f64;
        let log_sum: f64 = s.iter().map(|v| v.ln()).sum();
        let full = smin > tol * smax && smin > 0.0;
        ObservabilityIndices {
            o1: if full { (log_sum / kf).exp() / (rows as f64).sqrt() } else { 0.0 },
            o2: if full { smin / smax } else { 0.0 },
            o3: if full { smin } else { 0.0 },
            o4: if full { smin * smin / smax } else { 0.0 },
            o5: if full { 1.0 / s.iter().map(|v| 1.0 / v).sum::<f64>() } else { 0.0 },
            log_det: if full { 2.0 * log_sum } else { f64::NEG_INFINITY },
            o_t: if full { smax / smin } else { f64::INFINITY },
            singular_values: s,
            rows,
        }
    }

    /// Indices of a stacked Jacobian by its SVD (the direct computation).
    pub fn from_jacobian(a: &DMatrix<f64>) -> Self {
        let sv = crate::identifiability::singular_values(a);
        Self::from_singular_values(&sv, a.ncols(), a.nrows())
    }

    /// Indices from an information matrix `M = AᵀA` (symmetric eigenvalues; `σ_i = √max(λ_i, 0)`)
    /// and the number of rows `m` of `A`.
    pub fn from_information(m: &DMatrix<f64>, rows: usize) -> Self {
        let ev = m.clone().symmetric_eigenvalues();
        let sv: Vec<f64> = ev.iter().map(|&l| l.max(0.0).sqrt()).collect();
        // Eigenvalues of M carry an absolute error of about ε·λ_max, so σ below ~1e-8·σ_max is
        // round-off: such a set counts as rank-deficient.
        Self::with_rank_tolerance(&sv, m.nrows(), rows, INFORMATION_RANK_TOLERANCE)
    }

    /// The value of `criterion`.
    pub fn value(&self, criterion: Criterion) -> f64 {
        match criterion {
            Criterion::DOptimal => self.log_det,
            Criterion::O1 => self.o1,
            Criterion::O2 => self.o2,
            Criterion::O3 => self.o3,
            Criterion::O4 => self.o4,
            Criterion::O5 => self.o5,
        }
    }
}
