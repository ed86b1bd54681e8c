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
use crate::se3::{self, Pose};
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
    /// Every chosen candidate's inputs must give back its target pose through the forward
    /// kinematics identification uses (from the home pose), within this position (mm) and
    /// rotation (rad); a chosen candidate that reaches another assembly mode is set aside and the
    /// selection repeated without it. `None`: no check.
    pub forward_tolerance: Option<(f64, f64)>,
}

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            observe: ObservationKind::Pose,
            noise: Noise::default(),
            method: SelectionMethod::Sffs,
            select: SelectOptions::default(),
            forward_tolerance: Some((1e-6, 1e-8)),
        }
    }
}

impl PlanOptions {
    /// An error unless the noise is finite and positive (it weights the rows).
    pub fn check(&self) -> Result<(), CalibError> {
        let ok = |v: f64| v > 0.0 && v.is_finite();
        if ok(self.noise.position) && ok(self.noise.orientation) {
            Ok(())
        } else {
            Err(CalibError::InvalidOption(format!(
                "the measurement noise must be finite and > 0, got {} mm and {} rad",
                self.noise.position, self.noise.orientation
            )))
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
    /// Candidates chosen at first but set aside because the forward kinematics from the home
    /// pose does not reach their target ([`PlanOptions::forward_tolerance`]).
    pub set_aside: Vec<usize>,
}

/// Rounds of [`plan`]'s forward check (each sets aside the chosen candidates that fail it).
const MAX_FORWARD_ROUNDS: usize = 8;

/// Whether the forward kinematics of `mech` at `q` (from its home pose, as identification runs
/// it) reaches `target` within `tolerance` (position mm, rotation rad).
pub fn forward_agrees<M: Mechanism + ?Sized>(mech: &M, q: &[f64], target: &Pose, tolerance: (f64, f64)) -> bool {
    match mech.forward(q) {
        Ok(t) => {
            let e = se3::pose_error(&t, target);
            se3::lin(&e).norm() <= tolerance.0 && se3::ang(&e).norm() <= tolerance.1
        }
        Err(_) => false,
    }
}

/// `sel`, made on the subset `keep` of the candidates, in the indices of the whole set.
fn remap(mut sel: Selection, keep: &[usize]) -> Selection {
    for i in &mut sel.selected {
        *i = keep[*i];
    }
    for s in &mut sel.history {
        s.candidate = keep[s.candidate];
    }
    sel
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
    opts.check()?;
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
    let mut selection = select(&blocks, opts.method, &opts.select, step)?;
    let mut set_aside: Vec<usize> = Vec::new();
    if let Some(tol) = opts.forward_tolerance {
        let mut excluded = vec![false; candidates.len()];
        for round in 0.. {
            let bad: Vec<usize> = selection
                .selected
                .iter()
                .copied()
                .filter(|&i| !forward_agrees(mech, &candidates[i].q, &candidates[i].target, tol))
                .collect();
            if bad.is_empty() {
                break;
            }
            if round == MAX_FORWARD_ROUNDS {
                return Err(CalibError::Numerical(format!(
                    "the forward kinematics from the home pose does not reach the targets of {} chosen candidates after {round} reselections (another assembly mode): sample a workspace closer to the home pose",
                    bad.len()
                )));
            }
            for &i in &bad {
                excluded[i] = true;
            }
            set_aside.extend(bad);
            let keep: Vec<usize> = (0..candidates.len()).filter(|&i| !excluded[i]).collect();
            if keep.len() < opts.select.n {
                return Err(CalibError::InvalidOption(format!(
                    "only {} candidates remain once {} that the forward kinematics from the home pose does not reach are set aside, fewer than the {} configurations asked for",
                    keep.len(),
                    set_aside.len(),
                    opts.select.n
                )));
            }
            selection = remap(select(&blocks.subset(&keep), opts.method, &opts.select, step)?, &keep);
        }
    }
    Ok(Plan {
        columns,
        rows_per_candidate: blocks.rows_per_candidate(),
        selection,
        jacobian_seconds,
        selection_seconds: t.elapsed().as_secs_f64(),
        set_aside,
    })
}
