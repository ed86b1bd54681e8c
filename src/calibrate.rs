//! One call from files to a calibrated model: [`calibrate`].
//!
//! model file + data set (+ validation set) + [`CalibrationOptions`] →
//! frame registration ([`crate::register`]) → iterated identification ([`crate::identify`]) →
//! the calibrated model file (with its `[frames]` and `[provenance]`), the report with its verdict
//! ([`CalibrationReport`]), from which the command line, the JSON output and the HTML are written.
pub mod checks;
mod covariance;
pub mod gauge;
mod instrument_data;
mod mixed;
mod robust;
pub mod scale;
pub mod sizes;
mod starts;
pub use starts::{start_agreement, StartAgreement, WORSE_MARGIN, WORSE_MINIMUM};
pub mod tolerances;
mod variants;

use crate::error::CalibError;
use crate::identify::{Identification, Loss, Method, Options};
use crate::io::data_file::DataSet;
use crate::io::model_file::{free_params, MechanismSpec, ModelFile};
use crate::io::IoError;
use crate::measure::{Measurement, Noise};
use crate::model::framed::{Framed, FRAME_PARAMS};
use crate::model::Mechanism;
use crate::register::{register, Registration};
use crate::report::CalibrationReport;
use crate::se3::Pose;
use instrument_data::InstrumentData;
use thiserror::Error;

/// Where the data's frames come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FrameMode {
    /// Find the measurement frame and the tool frame from the data ([`crate::register`]) and
    /// identify them with the geometry (the default: data straight from a tracker, in its frame).
    #[default]
    Estimate,
    /// The data are in the model's own frames (simulated data, or data already transformed): use
    /// the model file as it is.
    Model,
}

/// How three reflector centres per pose (`m1x_mm … m3z_mm`) enter the identification.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ReflectorFit {
    /// As the frame they define (6 residual rows per pose; the default).
    #[default]
    Frame,
    /// As three measured points (9 rows per pose, each reflector at its mean position in the
    /// reflector frame): the tracker's own measurement model. Validation stays on the frame.
    Points,
}

/// Default Huber threshold of [`calibrate`], in robust standard deviations of the per-pose
/// residuals: Gaussian data are untouched, blunders of many standard deviations lose their pull.
pub const DEFAULT_HUBER_K: f64 = 5.0;

/// Default number of starts of [`calibrate`] (see [`CalibrationOptions::starts`]).
pub const DEFAULT_STARTS: u64 = 3;

/// A pose is set aside as a blunder when the Huber loss weighs it below this, i.e. when its
/// residual is beyond twice the Huber threshold. Poses between one and two thresholds are only
/// down-weighted: real machines leave a heavy tail of residuals the geometric model cannot
/// explain (compliance, backlash), and those poses are data, not blunders.
pub const BLUNDER_WEIGHT: f64 = 0.5;

/// Rounds of setting blunders aside and fitting again.
const MAX_REJECTION_ROUNDS: usize = 5;

/// A start agrees with the first fit once its predictions come this close, as a fraction of
/// the stated position noise (see [`crate::identify::Options::agree_with`]).
pub const START_AGREEMENT: f64 = 0.01;

/// The starts disagree when their predictions differ, at some pose, by more than this many
/// standard deviations of the noise (the stated one, or the one the residual shows when that is
/// larger): the largest difference over hundreds of poses is compared with the data's own
/// scatter, and within three standard deviations the data cannot tell the predictions apart.
pub const START_COVERAGE: f64 = 3.0;

/// Poses the other starts run on at most (an evenly spread subset of larger sets).
pub const START_POSES: usize = 20_000;

/// Options of [`calibrate`].
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationOptions {
    /// Identification algorithm.
    pub method: Method,
    /// Measurement noise: the weights, and the scale the residual is judged against.
    pub noise: Noise,
    /// Re-estimate the position / orientation noise from the residuals.
    pub reweight: bool,
    /// Where the frames come from.
    pub frames: FrameMode,
    /// Loss on each pose's residual (Huber against blunders).
    pub loss: Loss,
    /// Starts of the identification: the registered (or model) start, plus `starts − 1` starts
    /// whose geometric parameters are perturbed at random within a third of the model's
    /// tolerances. The best is kept; predictions that disagree by more than the stated position
    /// noise fail the calibration (a wrong minimum, or data that do not determine the geometry).
    pub starts: u64,
    /// Seed of the perturbed starts.
    pub seed: u64,
    /// How reflector triples enter the fit (ignored for other measurement kinds).
    pub reflectors: ReflectorFit,
    /// For a model with joint terms: fit the geometric model alone and each kind of term alone
    /// too, for the report's comparison ([`crate::report::CalibrationReport::variants`]).
    pub compare_terms: bool,
    /// Known distances between seats (seat data only): the scale seats alone do not give.
    pub seat_distances: Vec<crate::instrument::SeatDistance>,
    /// Known distances between the seats of the validation data (numbered as in that file: its
    /// artifacts are its own), judged with the held-out placements.
    pub validation_seat_distances: Vec<crate::instrument::SeatDistance>,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        CalibrationOptions {
            method: Method::GaussNewton,
            noise: Noise::default(),
            reweight: false,
            frames: FrameMode::Estimate,
            loss: Loss::Huber { k: DEFAULT_HUBER_K },
            starts: DEFAULT_STARTS,
            seed: 1,
            reflectors: ReflectorFit::Frame,
            compare_terms: true,
            seat_distances: Vec::new(),
            validation_seat_distances: Vec::new(),
        }
    }
}

/// Errors of [`calibrate`]: a file problem (with its file and line) or a computation problem.
#[derive(Debug, Error)]
pub enum CalibrateError {
    /// A file problem.
    #[error(transparent)]
    Io(#[from] IoError),
    /// A computation problem not tied to one line of a file.
    #[error(transparent)]
    Calib(#[from] CalibError),
}

/// What [`calibrate`] produced.
pub struct Calibration {
    /// The calibrated model file (geometry, frames, noise, provenance status and reasons; the
    /// caller adds the command line).
    pub model_file: ModelFile,
    /// The identification itself (the calibrated mechanism is `identification.model`).
    pub identification: Identification<Box<dyn Mechanism>>,
    /// The starting model: the nominal geometry in the registered frames.
    pub start: Box<dyn Mechanism>,
    /// The frame registration, when the frames were estimated.
    pub registration: Option<Registration>,
    /// Free parameters, in priority order (indices into the calibrated mechanism's parameters).
    pub free: Vec<usize>,
    /// The report (statistics, parameter table, verdict).
    pub report: CalibrationReport,
    /// Ids of the poses set aside as blunders: beyond the Huber threshold of the robust loss at
    /// the solution, then left out of the final fit.
    pub blunders: Vec<i64>,
    /// What each start reached (the kept one first).
    pub starts: Vec<StartOutcome>,
    /// Starts whose predictions differ by more than this (mm) disagree: [`START_COVERAGE`] times
    /// the stated position noise, or the noise the residual shows when that is larger
    /// (predictions closer than the data's own scatter are not told apart by them).
    pub start_tolerance_mm: f64,
}

/// The outcome of one start of [`calibrate`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StartOutcome {
    /// A-posteriori standard deviation of unit weight reached.
    pub sigma0: f64,
    /// Whether that identification converged.
    pub converged: bool,
    /// Largest distance (mm) between this start's predicted tool positions and the kept
    /// solution's, over the identification poses; `None` when this start could not be compared
    /// ([`Self::unchecked`]).
    pub max_difference_mm: Option<f64>,
    /// Why this start was left out of the agreement check: its fit failed (a perturbed machine
    /// that does not assemble at some pose), or its solution cannot be evaluated at some pose.
    /// Such a start says nothing about other minima; it neither agrees nor disagrees.
    pub unchecked: Option<String>,
}

/// Calibrate `model` from `data` (and judge it on `validation`): the stages below, in order —
/// plausibility checks (`checks`), the starting model with its frames (`starting_model`),
/// the robust identification (`robust`), the other starts (`starts`), the report with its
/// verdict (`judge`). A calibration that fails while an artifact size read another way (a
/// sphere diameter in inches, a probe's diameter for its radius, a bar length in inches)
/// calibrates is an error naming that size ([`sizes::likely_mistake`]).
pub fn calibrate(
    model: &ModelFile,
    data: &DataSet,
    validation: Option<&DataSet>,
    opts: &CalibrationOptions,
) -> Result<Calibration, CalibrateError> {
    let cal = calibrate_as_stated(model, data, validation, opts)?;
    if cal.report.verdict.status == crate::report::Status::Failed {
        let why = cal.report.verdict.reasons.first().map_or("", String::as_str);
        if let Some(message) = sizes::likely_mistake(model, data, opts, cal.identification.sigma0, why) {
            return Err(IoError::Invalid {
                path: data.path.clone(),
                message,
            }
            .into());
        }
    }
    Ok(cal)
}

/// [`calibrate`] with the data's sizes as they are stated.
fn calibrate_as_stated(
    model: &ModelFile,
    data: &DataSet,
    validation: Option<&DataSet>,
    opts: &CalibrationOptions,
) -> Result<Calibration, CalibrateError> {
    checks::plausible_angles(model, data)?;
    checks::plausible_units(model, data)?;
    checks::plausible_seat_distances(model, data, &opts.seat_distances)?;
    let (raw, raw_validation) = (data, validation);
    let instrument = InstrumentData::of(data, validation, &opts.seat_distances, &opts.validation_seat_distances)?;
    if !opts.validation_seat_distances.is_empty() && instrument.as_ref().is_none_or(|i| i.held_out.is_none()) {
        return Err(CalibError::InvalidOption(
            "known distances between held-out seats need seat rows in the validation data (an instrument calibration's held-out placements)".into(),
        )
        .into());
    }
    let (data, validation) = match &instrument {
        Some(i) => (&i.data, i.validation.as_ref()),
        None => (data, validation),
    };
    let measurements = fitted_measurements(data, opts)?;
    let (start, mut free, registration) = match &instrument {
        Some(i) => instrument_start(model, i)?,
        None => starting_model(model, data, &measurements, opts)?,
    };
    // Where the machine stands, when no instrument sees it: held as drawn, never identified
    // (unless holding it costs the fit more than noise can: then it was no pure gauge).
    let placement = match &instrument {
        Some(i) if !i.tracked() => gauge::placement_params(&*start, &measurements, 0..6, &free, &opts.noise).map_err(|e| data.locate(e))?,
        _ => Vec::new(),
    };
    let id_opts = Options {
        method: opts.method,
        noise: opts.noise,
        reweight: opts.reweight,
        free: Some(free.clone()),
        loss: opts.loss,
        weak: Some(crate::identify::WeakHold::from_params(&start.params(), |u| model.tolerances.of(u))),
        gauge: placement,
        ..Options::default()
    };
    let robust::RobustFit { identification, kept } = robust::fit_setting_blunders_aside(&*start, &measurements, &id_opts, data)?;
    let setup = starts::StartSetup {
        start: &*start,
        free: &free,
        tolerances: &model.tolerances,
        opts: &id_opts,
        starts: opts.starts,
        seed: opts.seed,
    };
    let starts::Starts { identification, outcomes } = starts::other_starts(&setup, identification, &measurements, &kept, data)?;
    let placement = identification.identifiability.gauge.clone();
    free.retain(|c| !placement.contains(c));
    let mut in_fit = vec![false; data.measurements.len()];
    for &i in &kept {
        in_fit[i] = true;
    }
    // Poses set aside (a known distance set aside is the report's, not a pose).
    let pose = |i: &usize| !crate::report::is_known_distance(&data.measurements[*i]);
    let blunders: Vec<i64> = (0..data.measurements.len())
        .filter(|&i| !in_fit[i])
        .filter(pose)
        .map(|i| data.ids[i])
        .collect();
    let mut calibrated = model.with_geometry_of(&*identification.model).map_err(|message| IoError::Invalid {
        path: format!("model '{}'", model.name).into(),
        message,
    })?;
    // The nominal model of an instrument calibration: the drawing with the tool point found
    // from the data. With tracker rows the tracker placed the base: the frames stay where it
    // put them; without, the calibrated model is placed where the drawing puts it.
    let mut held_out = None;
    if let Some(i) = &instrument {
        let start_file = model.with_geometry_of(&*start).map_err(|message| IoError::Invalid {
            path: format!("model '{}'", model.name).into(),
            message,
        })?;
        if !i.tracked() {
            placed_as_drawn(&mut calibrated, &start_file, &raw.measurements);
        }
        if let Some(rows) = &i.held_out {
            held_out = Some(instrument_data::held_out_placements(
                &start_file,
                &calibrated,
                rows,
                &opts.validation_seat_distances,
            )?);
        }
    }
    calibrated.description = Some(format!("calibrated from '{}' on {}", model.name, data.path.display()));
    calibrated.noise = Some(identification.noise);
    // The poses whose residuals a later check judges by: tracker rows only (an instrument
    // calibration's fit holds its artifacts, which no check or update takes).
    let fitted: Vec<Measurement> = match &instrument {
        Some(_) => Vec::new(),
        None => kept.iter().map(|&i| measurements[i].clone()).collect(),
    };
    calibrated.covariance = Some(covariance::of(
        &calibrated,
        model,
        &identification,
        id_opts.free.as_deref().unwrap_or_default(),
        &fitted,
    ));
    let start_tolerance_mm = START_COVERAGE * opts.noise.position.max(identification.sigma0 * identification.noise.position);
    let judged = Judged {
        start: &start,
        identification: &identification,
        free: &free,
        placement: &placement,
        in_fit: &in_fit,
        blunders: &blunders,
        outcomes: &outcomes,
        start_tolerance_mm,
        held_out,
    };
    let mut report = judge(model, data, validation, opts, &judged)?;
    let names = start.params();
    report.placement = placement.iter().map(|&k| names[k].name.clone()).collect();
    let measured: Vec<&[Measurement]> = std::iter::once(data).chain(validation).map(|d| &d.measurements[..]).collect();
    report.predicted = covariance::predicted_map(&calibrated, model, &measured, opts.seed);
    if !report.weak.is_empty() {
        // On the calibrated model file: the machine with its tool point, whatever the
        // instrument's wrapping of the fitted model.
        let machine = calibrated.build();
        // At the first row that commands the machine (not a known distance's), its inputs
        // without what an instrument appends to them.
        let inputs = machine.input_names().len();
        let first = measurements
            .iter()
            .find(|m| m.q.len() >= inputs && !crate::report::is_known_distance(m));
        report.weak_cause = first.and_then(|m| crate::report::weak_cause::known_cause(&*machine, &m.q[..inputs]));
    }
    // Rows beyond the model's (the vendor's) limits, kept as measured: worth a look.
    report
        .flags
        .extend(std::iter::once(raw).chain(raw_validation).flat_map(DataSet::limit_warnings));
    if let Some(i) = &instrument {
        for (k, s, f) in crate::instrument::collapsed_pivots(&*start, &*identification.model, &i.data.measurements) {
            report.fail(format!(
                "the fit puts the tool point of every row of pivot {} at nearly one place ({f:.4} mm RMS about their mean, the nominal model {s:.4} mm): with one bar length, a machine that stands still over a pivot's rows fits them exactly, and this is such a machine, not the calibrated one; vary the lengths (a telescoping bar's range, a draw-wire), add seats, or measure from more pivots",
                i.points[k].id
            ));
        }
    }
    if opts.compare_terms && instrument.is_none() {
        report.variants = variants::variants(model, raw, validation, opts);
    }
    Ok(Calibration {
        blunders,
        model_file: calibrated,
        identification,
        start,
        registration,
        free,
        report,
        starts: outcomes,
        start_tolerance_mm,
    })
}

/// Express an instrument calibration `calibrated` where the drawing puts the machine. No
/// instrument here sees where the machine stands, so the fit may carry the whole machine along
/// that rigid motion (the artifact with it) at no cost; left so, a target given in the robot's
/// base frame would be compensated tens of millimetres off. The rigid motion that best takes
/// the calibrated tool points at the data's configurations onto the starting model's (the
/// nominal geometry with the started tool offset) is put into the measurement frame: the
/// calibrated model then agrees with the drawing wherever the data do not say otherwise.
/// Nothing changes when the tool points do not fix a rigid motion (fewer than three
/// non-collinear places).
fn placed_as_drawn(calibrated: &mut ModelFile, start: &ModelFile, measurements: &[Measurement]) {
    let (fitted, drawn) = (calibrated.build(), start.build());
    let points = |m: &dyn Mechanism| -> Option<Vec<nalgebra::Vector3<f64>>> {
        measurements
            .iter()
            .map(|r| m.forward(&r.q).ok().map(|p| p.translation.vector))
            .collect()
    };
    let (Some(a), Some(b)) = (points(&*fitted), points(&*drawn)) else {
        return;
    };
    let (Some(motion), Some(frames)) = (crate::measure::register_points(&a, &b), calibrated.frames.as_mut()) else {
        return;
    };
    frames.measurement = motion * frames.measurement;
}

/// The measurements as the fit uses them: as read, or each reflector triple as three points.
fn fitted_measurements(data: &DataSet, opts: &CalibrationOptions) -> Result<Vec<Measurement>, IoError> {
    match opts.reflectors {
        ReflectorFit::Frame => Ok(data.measurements.clone()),
        ReflectorFit::Points => data.reflector_points().ok_or_else(|| IoError::Invalid {
            path: data.path.clone(),
            message: format!(
                "fitting reflector points needs three reflector centres per pose (m1x_mm … m3z_mm); this file gives a {}",
                data.format.describe()
            ),
        }),
    }
}

/// The starting model, its free parameters and the frame registration: the model file as it is
/// ([`FrameMode::Model`]), or the nominal mechanism seen through the measurement and tool frames
/// registered from the data, those frames free ([`FrameMode::Estimate`]).
fn starting_model(
    model: &ModelFile,
    data: &DataSet,
    measurements: &[Measurement],
    opts: &CalibrationOptions,
) -> Result<StartingModel, IoError> {
    match opts.frames {
        FrameMode::Model => Ok((model.build(), model.free_indices()?, None)),
        FrameMode::Estimate => {
            let (inner, inner_free, tool_guess) = nominal_mechanism(model)?;
            let reg = register(&inner, measurements, &tool_guess).map_err(|e| data.locate(e))?;
            let framed = Framed::new(inner, reg.measurement, reg.tool);
            let mut free: Vec<usize> = (0..FRAME_PARAMS).collect();
            free.extend(inner_free.iter().map(|i| i + FRAME_PARAMS));
            Ok((Box::new(framed), free, Some(reg)))
        }
    }
}

/// A mechanism without frames, its free parameters, and a tool frame to start from.
type Nominal = (Box<dyn Mechanism>, Vec<usize>, Pose);

/// What [`instrument_model`] gives: the starting model, its free parameters, the measurements
/// as the fit uses them.
pub type InstrumentModel = (Box<dyn Mechanism>, Vec<usize>, Vec<Measurement>);

/// For instrument data (seats, distances; [`crate::instrument`]): the starting model
/// [`calibrate`] fits — the nominal mechanism with the tool-point offset and the artifact points
/// found from the data —, its free parameters, and the measurements as the fit uses them (each
/// row's artifact point appended, the known distances' rows last). `None` for tracker data.
pub fn instrument_model(
    model: &ModelFile,
    data: &DataSet,
    distances: &[crate::instrument::SeatDistance],
) -> Result<Option<InstrumentModel>, IoError> {
    let Some(i) = InstrumentData::of(data, None, distances, &[])? else {
        return Ok(None);
    };
    let (start, free, _) = instrument_start(model, &i)?;
    Ok(Some((start, free, i.data.measurements)))
}

/// The model file's mechanism without its frames, its free parameters, and the tool frame the
/// file gives (the identity without one): what frames found from the data start from.
fn nominal_mechanism(model: &ModelFile) -> Result<Nominal, IoError> {
    let inner = model.mechanism.build();
    let inner_free = free_params(&*inner, &model.free, &model.fixed).map_err(|message| IoError::Invalid {
        path: format!("model '{}'", model.name).into(),
        message,
    })?;
    Ok((inner, inner_free, model.frames.map_or(Pose::identity(), |f| f.tool)))
}

/// Unknown planes (with seats at most) on a machine whose inputs all turn: nothing gives a
/// length ([`crate::instrument::touch::no_length`]). [`instrument_start`] holds the scale at the
/// drawing by keeping one length parameter as drawn ([`scale::scale_gauge`]): a warning naming
/// it. Where none can be held, the fit drifts along the scale (noise-free IRB 120 planes ended
/// 3.3e-11 mm from the truth after a similarity but 71 mm after a rigid motion) and the verdict
/// fails, this reason first.
fn judge_scale<M: Mechanism>(model: &ModelFile, data: &DataSet, opts: &CalibrationOptions, j: &Judged<M>, report: &mut CalibrationReport) {
    if !turns_only(model) || !crate::instrument::touch::no_length(&data.measurements, &opts.seat_distances) {
        return;
    }
    let why = format!(
        "nothing measured gives a length: unknown planes' offsets absorb any scale and '{}' has no length input",
        model.name
    );
    let known = "touch something of known size as well: a datum cube (face, cube_edge_mm), spheres of known diameter, a ballbar, two seats at a known distance, or a few tracker points";
    // The parameter held: free in the model file, not in the fit.
    let held = nominal_mechanism(model).ok().and_then(|(_, inner_free, _)| {
        let params = j.start.params();
        (inner_free.iter().map(|k| k + FRAME_PARAMS))
            .find(|k| !j.free.contains(k) && !j.placement.contains(k))
            .and_then(|k| params.get(k).map(|p| p.name.clone()))
    });
    match held {
        Some(name) => report.warn(format!(
            "{why}, so the fit holds the scale at the model's drawing: {name} is kept as drawn, and the calibrated machine is only as true to size as that; {known}"
        )),
        None => report.fail(format!(
            "{why}, so the fit cannot tell the machine's scale (only the probe radius and the lengths its model file fixes hold it, weakly) and its result is right at most up to scale; {known}"
        )),
    }
}

/// Whether every input of `model` turns (no prismatic input, which would give a length).
fn turns_only(model: &ModelFile) -> bool {
    model.inputs().iter().all(|inp| inp.unit != crate::params::Unit::Length)
}

/// The starting model for instrument data: the nominal mechanism with its tool-point offset
/// and the artifact points started from the data ([`crate::instrument::start_points`]); free,
/// in priority order: the artifact points, the tool point's offset, the model's free parameters. The base is not
/// placed (no instrument here sees it): the measurement frame stays the identity. With tracker
/// rows ([`crate::instrument::mixed`]) the tracker places it: the frames are registered on those
/// rows as for tracker data and identified, first in priority, and the points live in its frame.
fn instrument_start(model: &ModelFile, i: &InstrumentData) -> Result<StartingModel, IoError> {
    if i.tracked() {
        return mixed::start(model, &i.data, &i.points, &i.pairs);
    }
    let only_seats = i.points.iter().all(|p| p.kind == crate::instrument::PointKind::Seat);
    let turns_only = turns_only(model);
    if only_seats && i.pairs.is_empty() && turns_only {
        return Err(IoError::Invalid {
            path: i.data.path.clone(),
            message: format!(
                "seats alone do not give the scale of '{}', whose inputs all turn: every length and every seat scaled alike leave each ball in its seat, and the fit would shrink the machine toward a point; state a known distance between two seats (--seat-distance A:B:MM), or measure with a ballbar (pivot, length_mm)",
                model.name
            ),
        });
    }
    let (inner, inner_free, tool_guess) = nominal_mechanism(model)?;
    let framed = Framed::new(inner, Pose::identity(), tool_guess);
    let artifact =
        crate::instrument::start_points(framed, i.points.clone(), i.pairs.clone(), &i.data.measurements).map_err(|e| i.data.locate(e))?;
    // The artifact points come first in priority: a rigid motion of the machine together with
    // its artifact changes nothing measured, and the rank analysis then names the machine's own
    // placement (its base) redundant rather than artifact coordinates, so that stays nominal.
    // The calibrated model stands where the nominal stood: its home still assembles, and
    // targets in its base frame mean what they meant.
    let mut free: Vec<usize> = artifact.artifact_columns().collect();
    free.extend(crate::model::framed::TOOL_TRANSLATION);
    free.extend(inner_free.iter().map(|k| k + FRAME_PARAMS));
    // Unknown planes on a machine whose inputs all turn: the scale held at the drawing.
    if turns_only && i.pairs.is_empty() && crate::instrument::touch::no_length(&i.data.measurements, &[]) {
        let n = artifact.inner.input_names().len();
        let plain: Vec<Measurement> = (i.data.measurements.iter())
            .map(|m| Measurement {
                q: m.q[..n.min(m.q.len())].to_vec(),
                ..m.clone()
            })
            .collect();
        if let Some(k) = scale::scale_gauge(&artifact.inner, &plain, &free, artifact.inner.n_params()) {
            free.remove(k);
        }
    }
    Ok((Box::new(artifact), free, None))
}

/// The starting model (nominal geometry, in the registered frames when they are estimated), its
/// free parameters, and the registration.
type StartingModel = (Box<dyn Mechanism>, Vec<usize>, Option<Registration>);

/// What the verdict is taken from, besides the files and options.
struct Judged<'a, M> {
    start: &'a M,
    identification: &'a Identification<M>,
    free: &'a [usize],
    /// Held where the machine stands ([`gauge`]): not free, not the scale's gauge either.
    placement: &'a [usize],
    in_fit: &'a [bool],
    blunders: &'a [i64],
    outcomes: &'a [StartOutcome],
    start_tolerance_mm: f64,
    /// A validation file's instrument rows judged with their own artifacts.
    held_out: Option<crate::report::HeldOutPlacements>,
}

/// The report and its verdict: errors before and after on both sets, the corrections against
/// the tolerances in the split that keeps them smallest ([`tolerances`]), the starts' agreement,
/// and for joint terms the variants fitted with fewer terms.
fn judge<M: Mechanism + Clone>(
    model: &ModelFile,
    data: &DataSet,
    validation: Option<&DataSet>,
    opts: &CalibrationOptions,
    j: &Judged<M>,
) -> Result<CalibrationReport, CalibError> {
    let validation_name = validation.map(|v| v.path.display().to_string());
    let mut report = CalibrationReport::new(
        j.start,
        j.identification,
        j.free,
        &format!("{:?}", opts.method),
        &data.path.display().to_string(),
        &data.measurements,
        validation.map(|v| (validation_name.as_deref().unwrap_or("validation"), v.measurements.as_slice())),
    )?;
    // Blunders are reported as such, not again as outliers of the identification set.
    report
        .identification
        .outliers
        .retain(|o| j.in_fit.get(o.pose).copied().unwrap_or(true));
    report.blunders = j.blunders.to_vec();
    // The poses' ids: the known distances' rows (ids −1, −2, … after the file's) are no poses.
    let pose_ids: Vec<i64> = (data.ids.iter().zip(&data.measurements))
        .filter(|(_, m)| !crate::report::is_known_distance(m))
        .map(|(id, _)| *id)
        .collect();
    report.set_ids(&pose_ids, validation.map(|v| v.ids.as_slice()));
    let seats: Vec<(usize, usize)> = opts.seat_distances.iter().map(|d| (d.a, d.b)).collect();
    let known = crate::report::artifacts::known_distances(j.start, &j.identification.model, &data.measurements, &seats, j.in_fit);
    report.set_known_distances(known);
    report.set_inputs(&model.inputs());
    report.tolerance_check = Some(tolerances::tolerance_check(j.identification, j.free, &model.tolerances));
    report.serial_chain = matches!(model.mechanism, MechanismSpec::Serial(_));
    report.radian_like_columns = checks::radian_like_columns(model, data);
    report.held_out = j.held_out.clone();
    report.assess(&opts.noise, &model.tolerances);
    report.judge_kinds(crate::report::kinds::kind_residuals(
        &j.identification.model,
        &data.measurements,
        &opts.noise,
    ));
    judge_scale(model, data, opts, j, &mut report);
    let agreement = starts::start_agreement(j.outcomes, j.start_tolerance_mm);
    report.flags.extend(agreement.flags);
    if let Some(w) = agreement.warning {
        report.warn(w);
    }
    if let Some(f) = agreement.failure {
        report.fail(f);
    }
    Ok(report)
}
