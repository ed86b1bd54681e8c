//! The information matrix of a growing / shrinking configuration set, with low-rank updates.
//!
//! For the selected set `S` the state keeps
//!
//! * `M = Σ_{i∈S} A_iᵀA_i` (`k × k`),
//! * `P = (M + εI)⁻¹` and `log det(M + εI)`, with a small ridge `ε` (default
//!   [`DEFAULT_RIDGE`]) so that both exist before the set reaches full rank (fewer than `k/r`
//!   configurations),
//! * for **every** candidate `i` its leverage block `G_i = A_i P A_iᵀ` (`r × r`).
//!
//! Adding candidate `j` is a rank-`r` update. With `S_j = I + G_j = L Lᵀ` and
//! `U = P A_jᵀ L⁻ᵀ` (Sherman–Morrison–Woodbury):
//!
//! ```text
//! log det(M + εI + A_jᵀA_j) = log det(M + εI) + log det(I + G_j)    (matrix determinant lemma)
//! P ← P − U Uᵀ,          G_i ← G_i − (A_i U)(A_i U)ᵀ   for every candidate i
//! ```
//!
//! and removing `j` is the same with `I − G_j` and the signs flipped. So the D-optimality gain of
//! every candidate, `log det(I + G_i)`, is available after each step for `O(N·r²·k)` work (one
//! pass over the blocks, in parallel), instead of `O(N·k³)` for re-factorising `M` per candidate.
//! Round-off accumulates over many updates, so every [`InformationState::refresh_every`] updates
//! (and whenever an update is ill-conditioned) `M` is rebuilt from the set, `P` from its Cholesky
//! factor `M + εI = L Lᵀ` as `P = FFᵀ`, `F = L⁻ᵀ`, and every `G_i = (A_i F)(A_i F)ᵀ` afresh.
use super::indices::ObservabilityIndices;
use super::jacobians::{add_gram, CandidateJacobians};
use crate::error::CalibError;
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Default ridge `ε`, relative to the scaled information (about 1 per configuration and
/// parameter, see [`super::jacobians`]).
pub const DEFAULT_RIDGE: f64 = 1e-6;

/// Default number of low-rank updates between exact refreshes.
pub const DEFAULT_REFRESH_EVERY: usize = 12;

const MIN_CHUNK: usize = 512;

/// Information matrix, its regularised inverse and all candidates' leverage blocks.
#[derive(Debug, Clone)]
pub struct InformationState<'a> {
    blocks: &'a CandidateJacobians,
    ridge: f64,
    selected: Vec<usize>,
    in_set: Vec<bool>,
    m: DMatrix<f64>,
    p: DMatrix<f64>,
    log_det: f64,
    leverage: Vec<f64>,
    since_refresh: usize,
    full_rank: bool,
    /// Low-rank updates between exact refreshes.
    pub refresh_every: usize,
}

impl<'a> InformationState<'a> {
    /// The state of the empty set.
    pub fn new(blocks: &'a CandidateJacobians, ridge: f64) -> Result<Self, CalibError> {
        Self::with_set(blocks, &[], ridge)
    }

    /// The state of a given set (computed exactly).
    pub fn with_set(blocks: &'a CandidateJacobians, set: &[usize], ridge: f64) -> Result<Self, CalibError> {
        if !(ridge > 0.0 && ridge.is_finite()) {
            return Err(CalibError::InvalidOption(format!("ridge must be positive, got {ridge}")));
        }
        let n = blocks.len();
        let r = blocks.rows_per_candidate();
        let k = blocks.n_columns();
        let mut in_set = vec![false; n];
        for &i in set {
            if i >= n || in_set[i] {
                return Err(CalibError::InvalidOption(format!("invalid or repeated candidate {i} in a set")));
            }
            in_set[i] = true;
        }
        let mut s = InformationState {
            blocks,
            ridge,
            selected: set.to_vec(),
            in_set,
            m: DMatrix::zeros(k, k),
            p: DMatrix::zeros(k, k),
            log_det: 0.0,
            leverage: vec![0.0; n * r * r],
            since_refresh: 0,
            full_rank: false,
            refresh_every: DEFAULT_REFRESH_EVERY,
        };
        s.full_rank = !s.rank_deficient();
        s.refresh()?;
        Ok(s)
    }

    /// The candidate blocks.
    pub fn blocks(&self) -> &'a CandidateJacobians {
        self.blocks
    }

    /// The ridge `ε`.
    pub fn ridge(&self) -> f64 {
        self.ridge
    }

    /// Selected candidates, in order of addition.
    pub fn selected(&self) -> &[usize] {
        &self.selected
    }

    /// Whether candidate `i` is selected.
    pub fn contains(&self, i: usize) -> bool {
        self.in_set[i]
    }

    /// `M = Σ A_iᵀA_i` over the set (no ridge).
    pub fn information(&self) -> &DMatrix<f64> {
        &self.m
    }

    /// `P = (M + εI)⁻¹`.
    pub fn inverse(&self) -> &DMatrix<f64> {
        &self.p
    }

    /// `log det(M + εI)`.
    pub fn log_det_regularized(&self) -> f64 {
        self.log_det
    }

    /// Leverage block `G_i = A_i P A_iᵀ` of candidate `i` (`r × r`, row-major).
    pub fn leverage(&self, i: usize) -> &[f64] {
        let rr = self.blocks.rows_per_candidate().pow(2);
        &self.leverage[i * rr..(i + 1) * rr]
    }

    /// D-optimality gain of adding candidate `i`: `log det(I + G_i)` (with the ridge), i.e. the
    /// increase of `log det(M + εI)`.
    pub fn gain(&self, i: usize) -> f64 {
        let g = self.leverage(i);
        match self.blocks.rows_per_candidate() {
            3 => log_det_identity_plus::<3>(g, 1.0),
            _ => log_det_identity_plus::<6>(g, 1.0),
        }
    }

    /// The D-optimality gain of every candidate (`−∞` for selected ones), in parallel.
    pub fn gains(&self) -> Vec<f64> {
        let rr = self.blocks.rows_per_candidate().pow(2);
        let r = self.blocks.rows_per_candidate();
        self.leverage
            .par_chunks(rr)
            .zip(self.in_set.par_iter())
            .with_min_len(MIN_CHUNK)
            .map(|(g, &sel)| {
                if sel {
                    f64::NEG_INFINITY
                } else if r == 3 {
                    log_det_identity_plus::<3>(g, 1.0)
                } else {
                    log_det_identity_plus::<6>(g, 1.0)
                }
            })
            .collect()
    }

    /// The unselected candidate of largest D-optimality gain (lowest index among ties), with its
    /// gain; `None` when every candidate is selected.
    pub fn best_gain(&self) -> Option<(usize, f64)> {
        let gains = self.gains();
        gains
            .par_iter()
            .enumerate()
            .with_min_len(4096)
            .filter(|(_, g)| **g > f64::NEG_INFINITY)
            .map(|(i, &g)| (i, g))
            .reduce_with(better)
    }

    /// The `count` unselected candidates of largest D-optimality gain, best first (ties by
    /// lower index).
    pub fn top_gains(&self, count: usize) -> Vec<(usize, f64)> {
        let mut all: Vec<(usize, f64)> = self
            .gains()
            .into_iter()
            .enumerate()
            .filter(|(_, g)| *g > f64::NEG_INFINITY)
            .collect();
        let order = |a: &(usize, f64), b: &(usize, f64)| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0));
        if count < all.len() {
            all.select_nth_unstable_by(count, order);
            all.truncate(count);
        }
        all.sort_by(order);
        all
    }

    /// Observability indices of the current set (exact, from the eigenvalues of `M`).
    pub fn indices(&self) -> ObservabilityIndices {
        ObservabilityIndices::from_information(&self.m, self.rows())
    }

    /// Observability indices of the set with candidate `add` added and/or `remove` removed
    /// (exact, without changing the state).
    pub fn indices_after(&self, add: Option<usize>, remove: Option<usize>) -> ObservabilityIndices {
        let r = self.blocks.rows_per_candidate();
        let mut m = self.m.clone();
        let mut rows = self.rows();
        if let Some(i) = add {
            add_gram(&mut m, self.blocks.block(i), r, 1.0);
            rows += r;
        }
        if let Some(i) = remove {
            add_gram(&mut m, self.blocks.block(i), r, -1.0);
            rows -= r;
        }
        ObservabilityIndices::from_information(&m, rows)
    }

    /// Whether `M` is rank-deficient (see [`ObservabilityIndices::from_information`]).
    pub fn rank_deficient(&self) -> bool {
        self.rows() < self.blocks.n_columns() || self.indices().o3 == 0.0
    }

    /// Residual rows of the set.
    pub fn rows(&self) -> usize {
        self.selected.len() * self.blocks.rows_per_candidate()
    }

    /// Add candidate `j` (rank-`r` update of everything).
    pub fn add(&mut self, j: usize) -> Result<(), CalibError> {
        if j >= self.in_set.len() || self.in_set[j] {
            return Err(CalibError::InvalidOption(format!("candidate {j} cannot be added")));
        }
        self.in_set[j] = true;
        self.selected.push(j);
        add_gram(&mut self.m, self.blocks.block(j), self.blocks.rows_per_candidate(), 1.0);
        self.update(j, 1.0)
    }

    /// Remove candidate `j` (rank-`r` downdate of everything).
    pub fn remove(&mut self, j: usize) -> Result<(), CalibError> {
        let pos = self
            .selected
            .iter()
            .position(|&s| s == j)
            .ok_or_else(|| CalibError::InvalidOption(format!("candidate {j} is not selected")))?;
        self.selected.remove(pos);
        self.in_set[j] = false;
        add_gram(&mut self.m, self.blocks.block(j), self.blocks.rows_per_candidate(), -1.0);
        self.update(j, -1.0)
    }

    /// Low-rank update for adding (`sign = 1`) or removing (`sign = −1`) candidate `j`; `M`,
    /// the set and the mask are already changed.
    fn update(&mut self, j: usize, sign: f64) -> Result<(), CalibError> {
        self.since_refresh += 1;
        // Crossing between rank-deficient and full rank changes the leverage blocks from order
        // 1/ε to order 1 (or back): recompute instead of cancelling digits.
        let full = !self.rank_deficient();
        let crossed = full != self.full_rank;
        self.full_rank = full;
        if crossed || self.since_refresh >= self.refresh_every {
            return self.refresh();
        }
        let r = self.blocks.rows_per_candidate();
        let k = self.blocks.n_columns();
        let g = DMatrix::from_row_slice(r, r, self.leverage(j));
        let s = DMatrix::identity(r, r) + g * sign;
        let chol = match s.cholesky() {
            Some(c) => c,
            None => return self.refresh(),
        };
        let ld: f64 = chol.l().diagonal().iter().map(|d| 2.0 * d.ln()).sum();
        // A removal that takes away nearly all the information in some direction loses digits
        // in P: recompute exactly instead.
        if sign < 0.0 && ld < -(1e4f64).ln() {
            return self.refresh();
        }
        let a = self.blocks.block_matrix(j);
        let v = &self.p * a.transpose(); // k × r
        let linv = chol
            .l()
            .solve_lower_triangular(&DMatrix::identity(r, r))
            .ok_or_else(|| CalibError::Numerical("triangular solve in a low-rank update".into()))?;
        let u = v * linv.transpose(); // k × r
        self.p -= (&u * u.transpose()) * sign;
        self.log_det += ld;
        let mut u_rows = vec![0.0; k * r];
        for c in 0..k {
            for b in 0..r {
                u_rows[c * r + b] = u[(c, b)];
            }
        }
        match r {
            3 => low_rank_update::<3>(self.blocks.data(), k, &mut self.leverage, &u_rows, -sign),
            _ => low_rank_update::<6>(self.blocks.data(), k, &mut self.leverage, &u_rows, -sign),
        }
        Ok(())
    }

    /// Recompute `M`, `P`, `log det(M + εI)` and every leverage block exactly.
    pub fn refresh(&mut self) -> Result<(), CalibError> {
        let r = self.blocks.rows_per_candidate();
        let k = self.blocks.n_columns();
        self.m = self.blocks.information(&self.selected);
        let reg = &self.m + DMatrix::identity(k, k) * self.ridge;
        let chol = reg
            .cholesky()
            .ok_or_else(|| CalibError::Numerical("information matrix is not positive definite".into()))?;
        let l = chol.l();
        self.log_det = l.diagonal().iter().map(|d| 2.0 * d.ln()).sum();
        let linv = l
            .solve_lower_triangular(&DMatrix::identity(k, k))
            .ok_or_else(|| CalibError::Numerical("triangular solve of the information matrix".into()))?;
        let f = linv.transpose(); // upper triangular, P = F Fᵀ
        self.p = &f * f.transpose();
        let f_rows = row_major(&f);
        match r {
            3 => exact_leverage::<3>(self.blocks.data(), k, &mut self.leverage, &f_rows),
            _ => exact_leverage::<6>(self.blocks.data(), k, &mut self.leverage, &f_rows),
        }
        self.since_refresh = 0;
        Ok(())
    }
}

/// A matrix as a row-major buffer.
pub(crate) fn row_major(m: &DMatrix<f64>) -> Vec<f64> {
    let mut out = Vec::with_capacity(m.nrows() * m.ncols());
    for a in 0..m.nrows() {
        for b in 0..m.ncols() {
            out.push(m[(a, b)]);
        }
    }
    out
}

/// The upper-triangular factor `F` (row-major, `P = (M + εI)⁻¹ = F Fᵀ`, `F = L⁻ᵀ` with
/// `M + εI = L Lᵀ`) and `log det(M + εI)`.
pub(crate) fn inverse_factor(m: &DMatrix<f64>, ridge: f64) -> Result<(Vec<f64>, f64), CalibError> {
    let k = m.nrows();
    let reg = m + DMatrix::identity(k, k) * ridge;
    let chol = reg
        .cholesky()
        .ok_or_else(|| CalibError::Numerical("information matrix is not positive definite".into()))?;
    let l = chol.l();
    let log_det = l.diagonal().iter().map(|d| 2.0 * d.ln()).sum();
    let linv = l
        .solve_lower_triangular(&DMatrix::identity(k, k))
        .ok_or_else(|| CalibError::Numerical("triangular solve of the information matrix".into()))?;
    Ok((row_major(&linv.transpose()), log_det))
}

/// `g = (A F)(A F)ᵀ = A P Aᵀ` for one block `a` (`R × k`) with `P = F Fᵀ`, `f` upper triangular
/// row-major; `w` is scratch of length `R·k`, `g` receives `R × R` values.
pub(crate) fn exact_one<const R: usize>(a: &[f64], k: usize, f: &[f64], w: &mut [f64], g: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if wide_simd() {
        // SAFETY: the CPU supports AVX2 (checked at run time).
        return unsafe { exact_one_avx2::<R>(a, k, f, w, g) };
    }
    exact_one_body::<R>(a, k, f, w, g)
}

/// Whether the CPU has AVX2 (4-wide f64 vectors); the kernels below are compiled twice and the
/// wide version is chosen at run time. Both perform the same floating-point operations in the
/// same order (no fused multiply–add, no reassociation), so results are identical.
#[cfg(target_arch = "x86_64")]
fn wide_simd() -> bool {
    std::is_x86_feature_detected!("avx2")
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn exact_one_avx2<const R: usize>(a: &[f64], k: usize, f: &[f64], w: &mut [f64], g: &mut [f64]) {
    exact_one_body::<R>(a, k, f, w, g)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn low_rank_one_avx2<const R: usize>(a: &[f64], k: usize, u: &[f64], g: &mut [f64], sign: f64) {
    low_rank_one_body::<R>(a, k, u, g, sign)
}

#[inline(always)]
#[allow(clippy::needless_range_loop)] // fixed-size R×R kernels read best with indices
fn exact_one_body<const R: usize>(a: &[f64], k: usize, f: &[f64], w: &mut [f64], g: &mut [f64]) {
    // W = A F, F upper triangular: four columns j at a time with the R rows in registers. Each
    // w[r][j] is the sum over c = 0..=j in increasing c, as a plain row-by-row product gives it
    // (the lanes of columns j < c add an exact zero), so the result does not depend on the
    // blocking.
    let rows: [&[f64]; R] = std::array::from_fn(|r| &a[r * k..(r + 1) * k]);
    let mut j0 = 0;
    while j0 + 4 <= k {
        let mut acc = [[0.0f64; 4]; R];
        for c in 0..j0 + 4 {
            let mut fv: [f64; 4] = f[c * k + j0..c * k + j0 + 4].try_into().expect("four columns");
            if c > j0 {
                for (l, v) in fv.iter_mut().enumerate() {
                    if j0 + l < c {
                        *v = 0.0;
                    }
                }
            }
            for r in 0..R {
                let x = rows[r][c];
                for l in 0..4 {
                    acc[r][l] += x * fv[l];
                }
            }
        }
        for r in 0..R {
            w[r * k + j0..r * k + j0 + 4].copy_from_slice(&acc[r]);
        }
        j0 += 4;
    }
    for j in j0..k {
        for r in 0..R {
            let mut s = 0.0;
            for c in 0..=j {
                s += rows[r][c] * f[c * k + j];
            }
            w[r * k + j] = s;
        }
    }
    // G = W Wᵀ with independent accumulators (each entry still summed in column order).
    let mut acc = [[0.0f64; R]; R];
    for j in 0..k {
        let mut col = [0.0f64; R];
        for r in 0..R {
            col[r] = w[r * k + j];
        }
        for p in 0..R {
            for q in p..R {
                acc[p][q] += col[p] * col[q];
            }
        }
    }
    for p in 0..R {
        for q in p..R {
            g[p * R + q] = acc[p][q];
            g[q * R + p] = acc[p][q];
        }
    }
}

/// `g += sign·(A U)(A U)ᵀ` for one block `a` (`R × k`); `u` is `k × R`, row-major.
#[allow(clippy::needless_range_loop)] // fixed-size R×R kernels read best with indices
pub(crate) fn low_rank_one<const R: usize>(a: &[f64], k: usize, u: &[f64], g: &mut [f64], sign: f64) {
    #[cfg(target_arch = "x86_64")]
    if wide_simd() {
        // SAFETY: the CPU supports AVX2 (checked at run time).
        return unsafe { low_rank_one_avx2::<R>(a, k, u, g, sign) };
    }
    low_rank_one_body::<R>(a, k, u, g, sign)
}

#[inline(always)]
#[allow(clippy::needless_range_loop)] // fixed-size R×R kernels read best with indices
fn low_rank_one_body<const R: usize>(a: &[f64], k: usize, u: &[f64], g: &mut [f64], sign: f64) {
    let mut w = [[0.0f64; R]; R];
    for (r, wr) in w.iter_mut().enumerate() {
        let row = &a[r * k..(r + 1) * k];
        for (&x, ur) in row.iter().zip(u.chunks_exact(R)) {
            let ur: &[f64; R] = ur.try_into().expect("chunks of R");
            for b in 0..R {
                wr[b] += x * ur[b];
            }
        }
    }
    for p in 0..R {
        for q in p..R {
            let mut d = 0.0;
            for b in 0..R {
                d += w[p][b] * w[q][b];
            }
            g[p * R + q] += sign * d;
            if q != p {
                g[q * R + p] += sign * d;
            }
        }
    }
}

/// The better of two (candidate, value) pairs: larger value, then lower index.
pub(crate) fn better(a: (usize, f64), b: (usize, f64)) -> (usize, f64) {
    match a.1.total_cmp(&b.1) {
        std::cmp::Ordering::Greater => a,
        std::cmp::Ordering::Less => b,
        std::cmp::Ordering::Equal => {
            if a.0 <= b.0 {
                a
            } else {
                b
            }
        }
    }
}

/// `log det(I + sign·G)` of an `R × R` symmetric block by Cholesky; `−∞` if not positive definite.
#[allow(clippy::needless_range_loop)] // index form mirrors the Cholesky recurrences
pub(crate) fn log_det_identity_plus<const R: usize>(g: &[f64], sign: f64) -> f64 {
    let mut l = [[0.0f64; R]; R];
    let mut det = 1.0;
    for j in 0..R {
        let mut d = 1.0 + sign * g[j * R + j];
        for t in 0..j {
            d -= l[j][t] * l[j][t];
        }
        if d <= 0.0 || d.is_nan() {
            return f64::NEG_INFINITY;
        }
        let dj = d.sqrt();
        l[j][j] = dj;
        det *= d;
        for i in j + 1..R {
            let mut s = sign * g[i * R + j];
            for t in 0..j {
                s -= l[i][t] * l[j][t];
            }
            l[i][j] = s / dj;
        }
    }
    // One logarithm of the product of the pivots (each pivot is ≥ 1 for additions and the
    // product stays far inside the f64 range for R ≤ 6).
    det.ln()
}

/// `G_i += sign·(A_i U)(A_i U)ᵀ` for every candidate; `u` is `k × R`, row-major.
fn low_rank_update<const R: usize>(data: &[f64], k: usize, leverage: &mut [f64], u: &[f64], sign: f64) {
    leverage
        .par_chunks_mut(R * R)
        .zip(data.par_chunks(R * k))
        .with_min_len(MIN_CHUNK)
        .for_each(|(g, a)| low_rank_one::<R>(a, k, u, g, sign));
}

/// `G_i = (A_i F)(A_i F)ᵀ` for every candidate; `f` is `k × k` upper triangular, row-major.
fn exact_leverage<const R: usize>(data: &[f64], k: usize, leverage: &mut [f64], f: &[f64]) {
    leverage
        .par_chunks_mut(R * R)
        .zip(data.par_chunks(R * k))
        .with_min_len(MIN_CHUNK)
        .for_each_init(|| vec![0.0f64; R * k], |w, (g, a)| exact_one::<R>(a, k, f, w, g));
}
