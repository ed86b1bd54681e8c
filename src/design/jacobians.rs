//! Per-candidate identification Jacobian blocks, weighted and column-scaled, in one contiguous
//! buffer.
//!
//! # Rows, weights and columns
//! Candidate `i` contributes the block `A_i` (`r × k`, `r = 6` for full-pose and `r = 3` for
//! position measurements): the residual Jacobian of [`crate::measure::residual_jacobian`] at its
//! nominal pose, each row divided by its measurement standard deviation
//! ([`crate::measure::row_weights`]), restricted to the `k` identifiable parameter columns.
//!
//! # Column scaling
//! Column `j` is then divided by `c_j = sqrt(mean_i |A_i[:, j]|²)`, the root-mean-square effect of
//! parameter `j` per configuration over the **whole candidate set**. In these units every
//! parameter contributes on average one unit of information per configuration, so a set of `n`
//! configurations has an information matrix with diagonal ≈ `n`; the observability indices do not
//! depend on the parameters' units (mm or rad), and, being a property of the candidate set, the
//! scaling is the same for every subset compared during selection.
use super::candidates::{Candidate, ProgressFn};
use crate::error::CalibError;
use crate::identifiability;
use crate::measure::{self, Noise, Observation};
use crate::model::Mechanism;
use crate::se3;
use crate::simulate::ObservationKind;
use nalgebra::{DMatrix, Vector6};
use rayon::prelude::*;

/// Blocks per partial sum of the column norms in [`CandidateJacobians::from_raw`]: a fixed
/// partition, independent of the thread count.
const NORM_CHUNK: usize = 1024;

/// The weighted, column-scaled identification Jacobian blocks of a candidate set.
#[derive(Debug, Clone, PartialEq)]
pub struct CandidateJacobians {
    rows: usize,
    columns: Vec<usize>,
    scale: Vec<f64>,
    data: Vec<f64>,
}

impl CandidateJacobians {
    /// Blocks from raw weighted rows: `raw` holds `N` blocks of `rows × columns.len()` values,
    /// row-major within a block. Computes and applies the column scaling (see the module docs).
    /// Errors: `rows` not 3 or 6, a buffer of the wrong length, a non-finite value, or a column
    /// that is zero over the whole set.
    pub fn from_raw(rows: usize, columns: Vec<usize>, mut raw: Vec<f64>) -> Result<Self, CalibError> {
        let k = columns.len();
        if rows != 3 && rows != 6 {
            return Err(CalibError::InvalidOption(format!("blocks must have 3 or 6 rows, got {rows}")));
        }
        if k == 0 || raw.is_empty() || raw.len() % (rows * k) != 0 {
            return Err(CalibError::InvalidOption(format!(
                "block buffer of {} values is not a whole number of {rows}×{k} blocks",
                raw.len()
            )));
        }
        if raw.iter().any(|v| !v.is_finite()) {
            return Err(CalibError::Numerical("non-finite identification Jacobian entry".into()));
        }
        let n = raw.len() / (rows * k);
        // Partial sums over a fixed partition, added in order: the column norms (and so every
        // scaled block) do not depend on the number of threads or their scheduling. (A rayon
        // `fold`/`reduce` splits where work is stolen, and a different association order of the
        // sums changed the last bits of the scales and, through near-ties, the chosen set.)
        let partial: Vec<Vec<f64>> = raw
            .par_chunks(rows * k * NORM_CHUNK)
            .map(|c| {
                let mut acc = vec![0.0; k];
                for row in c.chunks_exact(k) {
                    for (a, v) in acc.iter_mut().zip(row) {
                        *a += v * v;
                    }
                }
                acc
            })
            .collect();
        let mut sums = vec![0.0; k];
        for p in &partial {
            for (x, y) in sums.iter_mut().zip(p) {
                *x += y;
            }
        }
        let scale: Vec<f64> = sums.iter().map(|s| (s / n as f64).sqrt()).collect();
        if let Some(j) = scale.iter().position(|&s| s <= 0.0) {
            return Err(CalibError::NothingToIdentify(format!(
                "parameter {} has no effect at any candidate",
                columns[j]
            )));
        }
        let inv: Vec<f64> = scale.iter().map(|s| 1.0 / s).collect();
        raw.par_chunks_mut(k).with_min_len(4096).for_each(|row| {
            for (v, s) in row.iter_mut().zip(&inv) {
                *v *= s;
            }
        });
        Ok(CandidateJacobians {
            rows,
            columns,
            scale,
            data: raw,
        })
    }

    /// Compute the blocks of `candidates` for `mech` (in parallel): residual Jacobian of a `kind`
    /// observation at each candidate's nominal pose, rows weighted by `noise`, restricted to
    /// `columns` (parameter indices, e.g. the identifiable subset), then column-scaled.
    pub fn build<M: Mechanism + ?Sized>(
        mech: &M,
        candidates: &[Candidate],
        kind: ObservationKind,
        noise: &Noise,
        columns: &[usize],
        progress: Option<ProgressFn>,
    ) -> Result<Self, CalibError> {
        let rows = match kind {
            ObservationKind::Pose => 6,
            ObservationKind::Position => 3,
        };
        let k = columns.len();
        let p = mech.n_params();
        if let Some(&c) = columns.iter().find(|&&c| c >= p) {
            return Err(CalibError::InvalidOption(format!(
                "parameter index {c} out of range (model has {p})"
            )));
        }
        if candidates.is_empty() || k == 0 {
            return Err(CalibError::InvalidOption("no candidates or no columns".into()));
        }
        let mut raw = vec![0.0; candidates.len() * rows * k];
        raw.par_chunks_mut(rows * k)
            .zip(candidates.par_iter())
            .enumerate()
            .with_min_len(256)
            .try_for_each(|(i, (block, cand))| {
                let solved = match &cand.solution {
                    Some(rest) => mech.forward_with_jacobian_at(&cand.q, &cand.target, rest),
                    None => mech.forward_with_jacobian_near(&cand.q, &cand.target),
                };
                let (pose, jac) = solved.map_err(|source| CalibError::Kinematics { pose: i, source })?;
                let obs = match kind {
                    ObservationKind::Pose => Observation::Pose(pose),
                    ObservationKind::Position => Observation::Position(pose.translation.vector),
                };
                // The rows of measure::residual_jacobian (the pose-error map times each column,
                // the same products), for the chosen columns only.
                let map = se3::spatial_to_pose_error(&pose.translation.vector);
                let mut w = [0.0; 6];
                for (r, v) in w.iter_mut().enumerate().take(rows) {
                    *v = measure::row_weight(&obs, r, noise);
                }
                for (j, &c) in columns.iter().enumerate() {
                    let col: Vector6<f64> = jac.column(c).into_owned();
                    let a = map * col;
                    for r in 0..rows {
                        block[r * k + j] = a[r] * w[r];
                    }
                }
                if let Some(f) = progress {
                    f(1);
                }
                Ok(())
            })?;
        Self::from_raw(rows, columns.to_vec(), raw)
    }

    /// The blocks of the candidates `idx` (in that order), keeping this set's column scaling.
    pub fn subset(&self, idx: &[usize]) -> Self {
        let s = self.rows * self.columns.len();
        let mut data = Vec::with_capacity(idx.len() * s);
        for &i in idx {
            data.extend_from_slice(self.block(i));
        }
        CandidateJacobians {
            rows: self.rows,
            columns: self.columns.clone(),
            scale: self.scale.clone(),
            data,
        }
    }

    /// Number of candidates `N`.
    pub fn len(&self) -> usize {
        self.data.len() / (self.rows * self.columns.len())
    }

    /// Whether there is no candidate.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Rows per candidate `r` (6 for poses, 3 for positions).
    pub fn rows_per_candidate(&self) -> usize {
        self.rows
    }

    /// Number of columns `k`.
    pub fn n_columns(&self) -> usize {
        self.columns.len()
    }

    /// Parameter indices (model order) of the columns.
    pub fn columns(&self) -> &[usize] {
        &self.columns
    }

    /// Column scales `c_j` (a scaled column is the weighted column divided by `c_j`).
    pub fn column_scale(&self) -> &[f64] {
        &self.scale
    }

    /// The whole buffer: `N` blocks of `r × k`, row-major within a block.
    pub fn data(&self) -> &[f64] {
        &self.data
    }

    /// Block `i` as a slice (`r × k`, row-major).
    pub fn block(&self, i: usize) -> &[f64] {
        let s = self.rows * self.columns.len();
        &self.data[i * s..(i + 1) * s]
    }

    /// Block `i` as a matrix.
    pub fn block_matrix(&self, i: usize) -> DMatrix<f64> {
        DMatrix::from_row_slice(self.rows, self.columns.len(), self.block(i))
    }

    /// The stacked scaled Jacobian of a set of candidates (`r·|set| × k`).
    pub fn stacked(&self, set: &[usize]) -> DMatrix<f64> {
        let k = self.columns.len();
        let mut out = DMatrix::zeros(self.rows * set.len(), k);
        for (s, &i) in set.iter().enumerate() {
            let b = self.block(i);
            for r in 0..self.rows {
                for c in 0..k {
                    out[(s * self.rows + r, c)] = b[r * k + c];
                }
            }
        }
        out
    }

    /// The information matrix `Σ A_iᵀA_i` of a set (`k × k`).
    pub fn information(&self, set: &[usize]) -> DMatrix<f64> {
        let k = self.columns.len();
        let mut m = DMatrix::zeros(k, k);
        for &i in set {
            add_gram(&mut m, self.block(i), self.rows, 1.0);
        }
        m
    }
}

/// `m += sign·AᵀA` for one `rows × k` row-major block.
pub(crate) fn add_gram(m: &mut DMatrix<f64>, block: &[f64], rows: usize, sign: f64) {
    let k = m.nrows();
    for r in 0..rows {
        let row = &block[r * k..(r + 1) * k];
        for a in 0..k {
            let x = sign * row[a];
            if x == 0.0 {
                continue;
            }
            for b in 0..k {
                m[(a, b)] += x * row[b];
            }
        }
    }
}

/// The identifiable parameters of `mech` for measurements of `kind` over the candidate set:
/// [`identifiability::analyze`] (priority order = `priority`, default model order) on the stacked
/// weighted Jacobian of `sample` candidates evenly spaced through the set, without the parameters
/// the mechanism cannot take alone ([`Mechanism::assembly_breaking`]).
pub fn identifiable_columns<M: Mechanism + ?Sized>(
    mech: &M,
    candidates: &[Candidate],
    kind: ObservationKind,
    noise: &Noise,
    priority: Option<&[usize]>,
    sample: usize,
    tolerance: f64,
) -> Result<Vec<usize>, CalibError> {
    if candidates.is_empty() {
        return Err(CalibError::InvalidOption("no candidates".into()));
    }
    let p = mech.n_params();
    let step = (candidates.len() / sample.max(1)).max(1);
    let data: Vec<measure::Measurement> = candidates
        .iter()
        .step_by(step)
        .take(sample.max(1))
        .map(|c| measure::Measurement {
            joints: Vec::new(),
            q: c.q.clone(),
            obs: match kind {
                ObservationKind::Pose => Observation::Pose(c.target),
                ObservationKind::Position => Observation::Position(c.target.translation.vector),
            },
        })
        .collect();
    let lin = crate::identify::linearize(mech, &data, noise)?;
    // Parameters an overconstrained mechanism cannot take alone are not planned for.
    let held = mech.assembly_breaking();
    let all: Vec<usize> = (0..p).collect();
    let order: Vec<usize> = priority.unwrap_or(&all).iter().copied().filter(|c| !held.contains(c)).collect();
    let id = identifiability::analyze(&lin.jacobian, &order, tolerance);
    let mut cols = id.identifiable;
    cols.sort_unstable();
    Ok(cols)
}
