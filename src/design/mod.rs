//! Measurement planning: choose the configurations at which to measure a mechanism so that
//! measurement noise leaks as little as possible into the identified parameters (§4 of the 5-DOF
//! paper).
//!
//! The pipeline, generic over any [`crate::Mechanism`]:
//!
//! 1. [`candidates`]: sample the workspace (or the joint space) on a grid or a Halton sequence and
//!    keep reachable, in-limit, non-singular configurations ([`Candidate`]); [`closed`] does the
//!    same in the platform-coordinate box of a closed-loop mechanism (the 5-DOF preset).
//! 2. [`jacobians`]: one weighted, column-scaled identification Jacobian block per candidate on
//!    the identifiable parameters, in one contiguous buffer ([`CandidateJacobians`]).
//! 3. [`indices`]: observability indices O1–O5 and D-optimality of a set
//!    ([`ObservabilityIndices`]).
//! 4. [`mod@select`]: greedy, SFFS and exchange selection, made fast by lazy (submodular) gain
//!    evaluation ([`lazy::LazyGains`]) and low-rank updates of the information matrix
//!    ([`information::InformationState`]).
//!
//! All indices are computed on the **scaled** problem: rows divided by the measurement noise,
//! columns by their root-mean-square over the candidate set ([`jacobians`]).
//!
//! [`plan()`] runs steps 2–4 in one call; [`plan_sampled`] runs steps 1–4 for any mechanism a
//! model file describes, from a description of where to sample ([`mod@sampling`]: what
//! `kinecal plan` and Python's `plan_sampled` call); [`write_plan_csv`] writes the chosen
//! configurations.
//!
//! For an instrument without a tracker (seats, a ballbar), [`plan_instrument`] chooses the
//! orientations at each seat or the directions about each pivot, with the artifact's unknowns
//! estimated alongside ([`mod@instrument`]).
pub mod candidates;
pub mod closed;
pub mod indices;
pub mod information;
pub mod instrument;
pub mod jacobians;
pub mod lazy;
pub mod plan;
pub mod sampling;
pub mod select;
pub mod touch;

pub use candidates::{candidates_in_input_box, candidates_in_workspace, Candidate, CandidateFilter, GenerationReport, Sampling, Workspace};
pub use closed::{actuator_condition, candidates_in_platform_box, PlatformGeneration};
pub use indices::{Criterion, ObservabilityIndices};
pub use information::InformationState;
pub use instrument::{instrument_blocks, instrument_candidates, plan_instrument, InstrumentLayout, InstrumentPlan, InstrumentPlanOptions};
pub use jacobians::{identifiable_columns, CandidateJacobians};
pub use plan::{forward_agrees, plan, Plan, PlanOptions};
pub use sampling::{
    plan_sampled, sample_candidates, CandidateSampling, Candidates, PlanEvent, PlanProgress, Points, PoseRanges, Region, SampledPlan,
    SampledSpace,
};
pub use select::{candidate_pool, exchange, greedy, select, sffs, ExchangeStart, SelectOptions, Selection, SelectionMethod, Step};
pub use touch::{plan_touches, touch_blocks, touch_candidates, touch_model, TouchLayout};

use std::io::Write;

/// Write the chosen configurations as CSV, in the data-file format of [`crate::io::data_file`] so
/// that the plan feeds `kinecal simulate --at` and `kinecal compensate` directly: `#` comment
/// lines with the method, criterion, every index reached and the candidate numbers, then the rows
/// of [`write_configurations_csv`].
pub fn write_plan_csv<W: Write>(
    out: W,
    input_names: &[String],
    angle_inputs: &[bool],
    candidates: &[Candidate],
    selection: &Selection,
) -> std::io::Result<()> {
    let ix = &selection.indices;
    let numbers: Vec<String> = selection.selected.iter().map(|i| i.to_string()).collect();
    let comments = [
        format!(
            "kinecal plan: {:?} on {}, {} configurations",
            selection.method,
            selection.criterion,
            selection.selected.len()
        ),
        format!(
            "O1 = {:.6e}, O2 = {:.6e} (O_T = 1/O2 = {:.6e}), O3 = {:.6e}, O4 = {:.6e}, O5 = {:.6e}, log det = {:.6}",
            ix.o1, ix.o2, ix.o_t, ix.o3, ix.o4, ix.o5, ix.log_det
        ),
        format!("candidate numbers: {}", numbers.join(" ")),
    ];
    let rows: Vec<&Candidate> = selection.selected.iter().map(|&i| &candidates[i]).collect();
    write_configurations_csv(out, input_names, angle_inputs, &comments, &rows)
}

/// Write configurations as CSV in the data-file format of [`crate::io::data_file`]: each of
/// `comments` as a `#` line, then a header `id,<inputs…>,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg`
/// and one row per configuration (its target pose). Inputs flagged in `angle_inputs` are written
/// in degrees (`<name>_deg`), the others in millimetres (`<name>_mm`). The orientation is
/// fixed-axes roll–pitch–yaw, `R = Rz(yaw)·Ry(pitch)·Rx(roll)`.
pub fn write_configurations_csv<W: Write>(
    mut out: W,
    input_names: &[String],
    angle_inputs: &[bool],
    comments: &[String],
    rows: &[&Candidate],
) -> std::io::Result<()> {
    for line in comments {
        writeln!(out, "# {line}")?;
    }
    write!(out, "id")?;
    for (i, name) in input_names.iter().enumerate() {
        let clean = name.replace(',', "_");
        if angle_inputs.get(i).copied().unwrap_or(false) {
            write!(out, ",{clean}_deg")?;
        } else {
            write!(out, ",{clean}_mm")?;
        }
    }
    writeln!(out, ",x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg")?;
    for (row, c) in rows.iter().enumerate() {
        write!(out, "{row}")?;
        for (j, v) in c.q.iter().enumerate() {
            if angle_inputs.get(j).copied().unwrap_or(false) {
                write!(out, ",{:.9}", v.to_degrees())?;
            } else {
                write!(out, ",{v:.9}")?;
            }
        }
        let p = c.target.translation.vector;
        let (r, pi, y) = c.target.rotation.euler_angles();
        writeln!(
            out,
            ",{:.6},{:.6},{:.6},{:.9},{:.9},{:.9}",
            p.x,
            p.y,
            p.z,
            r.to_degrees(),
            pi.to_degrees(),
            y.to_degrees()
        )?;
    }
    Ok(())
}
