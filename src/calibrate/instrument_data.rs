//! Instrument data as [`super::calibrate`] fits and judges them: the identification rows indexed
//! on their artifact points, and a validation file split into the tracker rows it may hold
//! (judged as poses in the tracker's frame the fit placed) and its instrument rows, whose
//! artifacts are its own: they are never matched to the identification's by number, but placed
//! by their own rows with the model fixed ([`crate::instrument::held_out`]), under the nominal
//! and the calibrated model ([`held_out_placements`]).
use crate::instrument::{ArtifactPoint, SeatDistance};
use crate::io::data_file::DataSet;
use crate::io::model_file::ModelFile;
use crate::io::split::subset;
use crate::io::IoError;
use crate::report::HeldOutPlacements;

/// Instrument data (seats, distances, touches) with each row's artifact point appended to its
/// inputs ([`crate::instrument::index_points`]), and the validation data split as the module
/// docs say.
pub(super) struct InstrumentData {
    pub points: Vec<ArtifactPoint>,
    pub pairs: Vec<(usize, usize)>,
    pub data: DataSet,
    /// The validation file's tracker rows (point index [`crate::instrument::NO_POINT`]).
    pub validation: Option<DataSet>,
    /// The validation file's instrument rows, as read: held-out artifacts of their own.
    pub held_out: Option<DataSet>,
}

impl InstrumentData {
    /// Whether the data hold tracker rows besides the instrument's ([`crate::instrument::mixed`]).
    pub fn tracked(&self) -> bool {
        crate::instrument::has_tracker_rows(&self.data.measurements)
    }

    /// `None` for tracker data. `distances` are the identification data's known seat
    /// distances, `held_distances` the validation data's (their own seat numbers).
    pub fn of(
        data: &DataSet,
        validation: Option<&DataSet>,
        distances: &[SeatDistance],
        held_distances: &[SeatDistance],
    ) -> Result<Option<InstrumentData>, IoError> {
        let Some((points, pairs, indexed)) = crate::instrument::index_points(&data.measurements, distances).map_err(|e| data.locate(e))?
        else {
            return Ok(None);
        };
        // The known distances' rows: ids −1, −2, … after the file's rows.
        let mut ids = data.ids.clone();
        let mut lines = data.lines.clone();
        for k in 0..pairs.len() {
            ids.push(-(k as i64) - 1);
            lines.push(0);
        }
        let tracked = crate::instrument::has_tracker_rows(&indexed);
        let (validation, held_out) = match validation {
            None => (None, None),
            Some(v) => split_validation(v, tracked, held_distances)?,
        };
        Ok(Some(InstrumentData {
            points,
            pairs,
            data: DataSet {
                measurements: indexed,
                ids,
                lines,
                ..data.clone()
            },
            validation,
            held_out,
        }))
    }
}

/// A validation file of an instrument calibration (the identification data hold tracker rows
/// when `tracked`): its tracker rows indexed as tracker rows, and its instrument rows as read,
/// checked as identification rows are (each artifact's minimum rows, the seats of the known
/// distances `held_distances` present when there are instrument rows).
fn split_validation(v: &DataSet, tracked: bool, held_distances: &[SeatDistance]) -> Result<(Option<DataSet>, Option<DataSet>), IoError> {
    let (rows, tracker): (Vec<usize>, Vec<usize>) =
        (0..v.measurements.len()).partition(|&i| v.measurements[i].obs.artifact_point().is_some());
    if !tracked {
        if rows.is_empty() {
            return Err(IoError::Invalid {
                path: v.path.clone(),
                message: "the identification data are an instrument's (seats, distances or touches); the validation data must be an instrument's too".into(),
            });
        }
        if let Some(&i) = tracker.first() {
            return Err(IoError::AtLine {
                path: v.path.clone(),
                line: v.lines[i],
                message: "a tracker row, and the identification data hold none: the tracker's frame is not placed for it (give tracker rows in the identification data too)".into(),
            });
        }
    }
    let tracker = (!tracker.is_empty()).then(|| {
        let s = subset(v, &tracker);
        DataSet {
            measurements: crate::instrument::mixed::tracker_only(&s.measurements),
            ..s
        }
    });
    let held = (!rows.is_empty()).then(|| subset(v, &rows));
    // Known distances without held-out seats are refused by `calibrate` (with or without
    // validation data).
    if let Some(h) = &held {
        crate::instrument::index_points(&h.measurements, held_distances).map_err(|e| h.locate(e))?;
    }
    Ok((tracker, held))
}

/// The held-out instrument rows `rows` judged under `nominal` and `calibrated`, each artifact
/// placed by its own rows ([`crate::instrument::held_out`]); `distances` are the known
/// distances between their seats.
pub(super) fn held_out_placements(
    nominal: &ModelFile,
    calibrated: &ModelFile,
    rows: &DataSet,
    distances: &[SeatDistance],
) -> Result<HeldOutPlacements, IoError> {
    let judge = |m: &ModelFile| crate::instrument::held_out(&*m.build(), &rows.measurements, distances).map_err(|e| rows.locate(e));
    Ok(HeldOutPlacements::new(
        rows.path.display().to_string(),
        judge(nominal)?,
        judge(calibrated)?,
    ))
}
