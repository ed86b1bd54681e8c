//! One call from candidates to a chosen set: the identifiable columns, the scaled Jacobian
//! blocks of every candidate, then the selection ([`plan`]). `kinecal plan` is this call between
//! candidate generation ([`super::candidates`], [`super::closed`]) and the CSV
//! ([`super::write_plan_csv`]).
use super::candidates::{Candidate, ProgressFn};
use super::jacobians::{identifiable_columns, CandidateJacobians};
use super::select::{select, SelectOptions, Selection, SelectionMethod, StepFn};
use crate::error::CalibError;
use crate::identifiability::DEFAULT_RANK_TOLERANCE;
use crate::measure::Noise;
use crate::model::Mechanism;
use crate::simulate::ObservationKind;
use std::time::Instant;

/// Candidates sampled to find the identifiable columns (a rank test on a subset is enough).
pub const COLUMN_SAMPLE: usize = 200;

/// What a plan measures and how it chooses.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOptions {
    /// What the instrument observes (its rows per configuration).
    pub observe: ObservationKind,
    /// Measurement noise: rows are divided by it.
    pub noise: Noise,
    /// Selection algorithm.
    pub method: SelectionMethod,
    /// Size, criterion and tuning of the selection.
    pub select: SelectOptions,
}

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            observe: ObservationKind::Pose,
            noise: Noise::default(),
            method: SelectionMethod::Sffs,
            select: SelectOptions::default(),
        }
    }
}

/// A chosen set and how it was reached.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Identifiable parameter columns (indices into the mechanism's parameters).
    pub columns: Vec<usize>,
    /// Rows of one candidate's Jacobian block.
    pub rows_per_candidate: usize,
    /// The selection (chosen candidate indices, indices reached, history).
    pub selection: Selection,
    /// Seconds spent on the identifiable columns and the Jacobian blocks.
    pub jacobian_seconds: f64,
    /// Seconds spent selecting.
    pub selection_seconds: f64,
}

/// Choose `opts.select.n` of `candidates` for `mech`: the identifiable columns (on up to
/// [`COLUMN_SAMPLE`] candidates), one weighted, column-scaled Jacobian block per candidate
/// (`jacobians` is called with the number of blocks done), then the selection (`step` is called
/// on every move). Fewer candidates than asked for is [`CalibError::InvalidOption`].
pub fn plan<M: Mechanism + ?Sized>(
    mech: &M,
    candidates: &[Candidate],
    opts: &PlanOptions,
    jacobians: Option<ProgressFn>,
    step: StepFn,
) -> Result<Plan, CalibError> {
    if candidates.len() < opts.select.n {
        return Err(CalibError::InvalidOption(format!(
            "only {} candidates survived the filters, fewer than the {} configurations asked for",
            candidates.len(),
            opts.select.n
        )));
    }
    let t = Instant::now();
    let columns = identifiable_columns(
        mech,
        candidates,
        opts.observe,
        &opts.noise,
        None,
        COLUMN_SAMPLE,
        DEFAULT_RANK_TOLERANCE,
    )?;
    let blocks = CandidateJacobians::build(mech, candidates, opts.observe, &opts.noise, &columns, jacobians)?;
    let jacobian_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let selection = select(&blocks, opts.method, &opts.select, step)?;
    Ok(Plan {
        columns,
        rows_per_candidate: blocks.rows_per_candidate(),
        selection,
        jacobian_seconds,
        selection_seconds: t.elapsed().as_secs_f64(),
    })
}
