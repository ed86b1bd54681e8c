//! The robust identification: a Huber fit, then the poses it down-weighted as blunders set
//! aside and the rest fitted again, until the set is stable.
use super::{BLUNDER_WEIGHT, MAX_REJECTION_ROUNDS};
use crate::error::CalibError;
use crate::identify::{identify, Identification, Options};
use crate::io::data_file::DataSet;
use crate::io::IoError;
use crate::measure::Measurement;
use crate::model::Mechanism;

/// A fit on the poses that are not blunders.
pub struct RobustFit {
    /// The identification on the kept poses (its `delta` counted from the start).
    pub identification: Identification<Box<dyn Mechanism>>,
    /// Indices (into the measurements) of the poses kept in the fit.
    pub kept: Vec<usize>,
}

/// Identify `start` from `measurements` with the loss of `opts`; poses the robust loss weighs
/// below [`BLUNDER_WEIGHT`] are set aside and the fit repeated on the rest, until none is left
/// to set aside (a Huber fit alone still lets many blunders pull together). Each round starts
/// from the start again, not from the previous round's solution, so blunders that pulled the
/// first fit far away (beyond the tolerances) do not leave it in a wrong minimum. Errors are
/// located in `data`.
pub fn fit_setting_blunders_aside(
    start: &dyn Mechanism,
    measurements: &[Measurement],
    opts: &Options,
    data: &DataSet,
) -> Result<RobustFit, IoError> {
    let start = start.box_clone();
    let mut kept: Vec<usize> = (0..measurements.len()).collect();
    let mut identification = identify(&start, measurements, opts).map_err(|e| data.locate(e))?;
    for _ in 0..MAX_REJECTION_ROUNDS {
        let rejected: std::collections::HashSet<usize> = kept
            .iter()
            .zip(&identification.pose_weights)
            .filter(|(_, w)| **w < BLUNDER_WEIGHT)
            .map(|(i, _)| *i)
            .collect();
        if rejected.is_empty() {
            break;
        }
        kept.retain(|i| !rejected.contains(i));
        let subset: Vec<Measurement> = kept.iter().map(|&i| measurements[i].clone()).collect();
        let locate = |e: CalibError| match e {
            CalibError::Kinematics { pose, source } => data.locate(CalibError::Kinematics { pose: kept[pose], source }),
            other => data.locate(other),
        };
        identification = identify(&start, &subset, opts).map_err(locate)?;
    }
    Ok(RobustFit { identification, kept })
}
