//! The starting model of data mixing tracker rows with an instrument's
//! ([`crate::instrument::mixed`]).
use super::{nominal_mechanism, StartingModel};
use crate::error::CalibError;
use crate::instrument::mixed::is_tracker_row;
use crate::instrument::ArtifactPoint;
use crate::io::data_file::DataSet;
use crate::io::model_file::ModelFile;
use crate::io::IoError;
use crate::measure::Measurement;
use crate::model::framed::{Framed, FRAME_PARAMS};
use crate::model::Mechanism;
use crate::register::register;

/// The starting model of data mixing tracker and instrument rows (`data` indexed by
/// [`crate::instrument::index_points`], `points` and `pairs` its artifact points and known distances): the
/// frames registered on the tracker rows ([`crate::register`]), then the tool point and the
/// artifact points started from the instrument rows ([`crate::instrument::start_points`], in the tracker's
/// frame; a tool point found by seats moves that frame with it). Free, in priority order: the frames, the artifact points, the model's free parameters.
pub(super) fn start(
    model: &ModelFile,
    data: &DataSet,
    points: &[ArtifactPoint],
    pairs: &[(usize, usize)],
) -> Result<StartingModel, IoError> {
    let (inner, inner_free, tool_guess) = nominal_mechanism(model)?;
    let n_q = inner.input_names().len();
    // The tracker rows without their point index, and where each stands in the data.
    let (at, tracker): (Vec<usize>, Vec<Measurement>) = data
        .measurements
        .iter()
        .enumerate()
        .filter(|(_, m)| is_tracker_row(&m.q, n_q))
        .map(|(i, m)| {
            let mut m = m.clone();
            m.q.pop();
            (i, m)
        })
        .unzip();
    let reg = register(&inner, &tracker, &tool_guess).map_err(|e| match e {
        CalibError::Kinematics { pose, source } => data.locate(CalibError::Kinematics { pose: at[pose], source }),
        e => data.locate(CalibError::InvalidOption(format!(
            "registering the frames on the {} tracker rows: {e}",
            tracker.len()
        ))),
    })?;
    let framed = Framed::new(inner, reg.measurement, reg.tool);
    let artifact =
        crate::instrument::start_points(framed, points.to_vec(), pairs.to_vec(), &data.measurements).map_err(|e| data.locate(e))?;
    let mut free: Vec<usize> = (0..FRAME_PARAMS).collect();
    free.extend(artifact.artifact_columns());
    free.extend(inner_free.iter().map(|k| k + FRAME_PARAMS));
    Ok((Box::new(artifact), free, Some(reg)))
}
