//! Where the machine stands, which no seat, ballbar or touch sees.
//!
//! An instrument without a tracker measures the tool point relative to artifacts that stand
//! somewhere unknown: a rigid motion of the whole machine, its artifacts with it, changes
//! nothing measured. Which parameters carry that motion depends on the model (a chain's base
//! dyad, a parallel machine's base frame), and the rank analysis alone does not always name
//! them: at a start whose tool points scatter millimetres about each seat, a turn of the base
//! looks like information (it changes the scatter), and the fit would report it as an
//! identified correction of several degrees with a standard deviation larger still.
//!
//! [`placement_params`] finds them from the model itself: the free parameters whose columns
//! lie in the span of the measurement frame's (a rigid motion of the machine) — precisely, those
//! the rank analysis calls redundant once the measurement frame's six columns come first, and
//! not without them. They are held where the drawing puts them: never identified, counted or
//! judged against tolerances.
use crate::error::CalibError;
use crate::identifiability::{analyze, DEFAULT_RANK_TOLERANCE};
use crate::measure::{Measurement, Noise};
use crate::model::Mechanism;

/// Rows the analysis runs on at most (an evenly spread subset of larger sets).
const GAUGE_POSES: usize = 2_000;

/// The parameters of `free` (indices into `model`'s parameters) that place the machine as a
/// whole, given the measurement frame's columns `frame` (six, `model`'s indices): see the
/// [module docs](self). Kinematic failures at a pose are errors.
pub fn placement_params(
    model: &dyn Mechanism,
    data: &[Measurement],
    frame: std::ops::Range<usize>,
    free: &[usize],
    noise: &Noise,
) -> Result<Vec<usize>, CalibError> {
    let stride = data.len().div_ceil(GAUGE_POSES).max(1);
    let sample: Vec<Measurement> = data.iter().step_by(stride).cloned().collect();
    let lin = crate::identify::linearize(model, &sample, noise)?;
    // The machine's own parameters: not the frames, not the artifact points (which a rigid
    // motion moves too, but which stand where the artifact happens to be).
    let params = model.params();
    let machine: Vec<usize> = free
        .iter()
        .copied()
        .filter(|&c| !frame.contains(&c) && !params[c].is_placement())
        .collect();
    let with_frame: Vec<usize> = frame.clone().chain(machine.iter().copied()).collect();
    let alone = analyze(&lin.jacobian, &machine, DEFAULT_RANK_TOLERANCE);
    let framed = analyze(&lin.jacobian, &with_frame, DEFAULT_RANK_TOLERANCE);
    Ok(machine
        .into_iter()
        .filter(|c| framed.redundant.contains(c) && alone.identifiable.contains(c))
        .collect())
}
