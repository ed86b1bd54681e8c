//! Planning for an instrument without a tracker (docs/instruments.md "Planning"): the
//! orientations to measure at each seat, or the directions about each ballbar pivot.
//!
//! 1. **Candidates** ([`instrument_candidates`]) from the *nominal* model with the nominal ball
//!    offset: for each seat, configurations that put the tool point in the seat, in orientations
//!    tilted up to [`Placement::max_tilt`] from the reference's; for each pivot, configurations on
//!    the sphere of the bar length about it. They are drawn as a virtual prototype's rows are
//!    ([`seat_rows`], [`distance_rows`]), noise-free, on the nominal.
//! 2. **Blocks** ([`instrument_blocks`]): each candidate's weighted residual Jacobian of the
//!    [`Artifact`]-wrapped nominal, with the tool-point offset, the model's free parameters and
//!    every seat's or pivot's centre free, on the identifiable columns. The rank test removes what
//!    no such instrument sees (where the machine stands; with seats alone on a machine of revolute
//!    joints, the scale, which a known seat distance gives).
//! 3. **Selection** ([`plan_instrument`]): the selection of [`super::select()`] on those blocks,
//!    then a repair that gives every point its minimum rows ([`MIN_SEAT_ROWS`], [`MIN_PIVOT_ROWS`]
//!    or more, [`InstrumentPlanOptions::min_per_point`]).
//!
//! # Why the full Jacobian, artifact columns included
//! The information on the geometry left after estimating the artifact points is the Schur
//! complement `S = M_gg − M_ga·M_aa⁻¹·M_ag` of the full information matrix `M` over the geometry
//! (`g`) and the artifact points (`a`). `S` is not a sum over rows, so the low-rank updates the
//! selection runs on do not apply to it; `M` is. And `log det M = log det M_aa + log det S`:
//! for seats `M_aa` is `n_s·I/σ²` per seat (a row moves its seat's residual by the identity),
//! fixed by the rows per seat, so at given counts the D-criterion on `M` *is* the D-criterion on
//! `S`. (For pivots `M_aa` depends on the directions as well: the criterion then also rewards
//! placing the pivots well, which the fit needs too.) This is the matrix `calibrate` fits and
//! `kinecal identifiability` analyses for instrument data ([`crate::calibrate::instrument_model`]).
//! Removing the redundant columns fixes a gauge (where the machine stands); the columns removed
//! are combinations of the kept ones with coefficients that do not depend on the rows, so the
//! D-criterion changes by a constant factor only.
use super::indices::{Criterion, ObservabilityIndices};
use super::jacobians::CandidateJacobians;
use super::plan::COLUMN_SAMPLE;
use super::select::{select, SelectOptions, Selection, SelectionMethod};
use crate::error::CalibError;
use crate::identifiability::{analyze, DEFAULT_RANK_TOLERANCE};
use crate::instrument::simulate::{distance_rows, seat_rows, Placement};
use crate::instrument::{Artifact, ArtifactPoint, PointKind, MIN_PIVOT_ROWS, MIN_SEAT_ROWS};
use crate::io::model_file::{free_params, ModelFile};
use crate::measure::{self, Measurement, Noise, Observation};
use crate::model::framed::{Framed, FRAME_PARAMS, TOOL_TRANSLATION};
use crate::model::Mechanism;
use crate::se3::Pose;
use nalgebra::{DMatrix, Translation3, Vector3};

/// Where the instrument stands and what it measures, on the nominal model.
#[derive(Debug, Clone, PartialEq)]
pub struct InstrumentLayout {
    /// The seats' or the pivots' centres (mm, the model's base frame); the data's point `k` is
    /// the `k`-th.
    pub points: Vec<Vector3<f64>>,
    /// The ballbar's length (mm) for pivots; `None` for seats.
    pub bar_length: Option<f64>,
    /// The ball's centre on the flange or platform (mm, in the model file's tool frame): the
    /// nominal tool point.
    pub ball: Vector3<f64>,
}

impl InstrumentLayout {
    /// Seats or pivots.
    pub fn kind(&self) -> PointKind {
        if self.bar_length.is_some() {
            PointKind::Pivot
        } else {
            PointKind::Seat
        }
    }

    /// The rows a point needs at least ([`MIN_SEAT_ROWS`], [`MIN_PIVOT_ROWS`]).
    pub fn min_rows(&self) -> usize {
        match self.kind() {
            PointKind::Seat => MIN_SEAT_ROWS,
            _ => MIN_PIVOT_ROWS,
        }
    }

    /// An error unless there are points, all finite, and a bar length is finite and positive.
    pub fn check(&self) -> Result<(), CalibError> {
        if self.points.is_empty() {
            return Err(CalibError::InvalidOption("no seat or pivot given".into()));
        }
        if let Some(p) = self.points.iter().position(|p| p.iter().any(|v| !v.is_finite())) {
            return Err(CalibError::InvalidOption(format!("point {p}: its coordinates must be finite")));
        }
        match self.bar_length {
            Some(l) if !(l.is_finite() && l > 0.0) => Err(CalibError::InvalidOption(format!("ballbar length {l} mm: must be positive"))),
            _ if self.ball.iter().any(|v| !v.is_finite()) => Err(CalibError::InvalidOption("the ball offset must be finite".into())),
            _ => Ok(()),
        }
    }
}

/// How an instrument plan is made.
#[derive(Debug, Clone, PartialEq)]
pub struct InstrumentPlanOptions {
    /// How candidates are drawn: [`Placement::per_point`] candidates per seat or pivot, about
    /// [`Placement::reference`], tilted up to [`Placement::max_tilt`], within
    /// [`Placement::inputs`]' limits, from [`Placement::seed`]; [`Placement::noise_mm`] is the
    /// measurement noise the rows are weighted by (per axis at a seat, along the bar).
    pub draw: Placement,
    /// Rows each point gets at least; below the instrument's minimum, that minimum.
    pub min_per_point: usize,
    /// Selection algorithm.
    pub method: SelectionMethod,
    /// Size (`n`, the rows of the plan), criterion and tuning of the selection.
    pub select: SelectOptions,
}

/// A chosen instrument plan.
#[derive(Debug, Clone)]
pub struct InstrumentPlan {
    /// Every candidate row (nominal, noise-free), points in order.
    pub candidates: Vec<Measurement>,
    /// The chosen rows, in candidate order: the plan.
    pub rows: Vec<Measurement>,
    /// The selection on the candidates (indices into `candidates`), its indices after the repair.
    pub selection: Selection,
    /// The identifiable columns the selection ran on (indices into the [`instrument_model`]'s
    /// parameters).
    pub columns: Vec<usize>,
    /// Their names.
    pub column_names: Vec<String>,
    /// Moves of the repair that gave each point its minimum rows (0: the selection did).
    pub repairs: usize,
}

/// The nominal model with the ball on its tool and the instrument's points ([`instrument_model`]).
pub type NominalArtifact = Artifact<Framed<Box<dyn Mechanism>>>;

/// The nominal model of `file` with the ball of `layout` on its tool, wrapped with the layout's
/// points as parameters ([`Artifact`]), and its free columns: the tool point's offset, the
/// file's free parameters, the points' centres (as [`crate::calibrate`] fits instrument data).
pub fn instrument_model(file: &ModelFile, layout: &InstrumentLayout) -> Result<(NominalArtifact, Vec<usize>), CalibError> {
    layout.check()?;
    let inner = file.mechanism.build();
    let inner_free = free_params(&*inner, &file.free, &file.fixed)
        .map_err(|message| CalibError::InvalidOption(format!("model '{}': {message}", file.name)))?;
    let tool = file.frames.map_or(Pose::identity(), |f| f.tool) * Translation3::from(layout.ball);
    let framed = Framed::new(inner, Pose::identity(), tool);
    let kind = layout.kind();
    let points: Vec<ArtifactPoint> = layout
        .points
        .iter()
        .enumerate()
        .map(|(id, c)| ArtifactPoint {
            kind,
            id,
            centre: *c,
            zero: None,
            rotation: None,
        })
        .collect();
    let p_inner = FRAME_PARAMS + framed.inner.n_params();
    let mut free: Vec<usize> = TOOL_TRANSLATION.collect();
    free.extend(inner_free.iter().map(|k| k + FRAME_PARAMS));
    free.extend(p_inner..p_inner + 3 * points.len());
    Ok((
        Artifact {
            inner: framed,
            points,
            pairs: Vec::new(),
        },
        free,
    ))
}

/// Candidate rows for `layout` on the nominal model of `file` (module docs, step 1):
/// `draw.per_point` per point, noise-free, a [`Observation::Seat`] or [`Observation::Distance`]
/// row each (the bar length the nominal one). A point the nominal model cannot reach in enough
/// orientations is an error naming it.
pub fn instrument_candidates(file: &ModelFile, layout: &InstrumentLayout, draw: &Placement) -> Result<Vec<Measurement>, CalibError> {
    candidates_on(&instrument_model(file, layout)?.0, layout, draw)
}

/// [`instrument_candidates`] on the [`instrument_model`] `model`.
fn candidates_on(model: &NominalArtifact, layout: &InstrumentLayout, draw: &Placement) -> Result<Vec<Measurement>, CalibError> {
    let exact = Placement {
        noise_mm: 0.0,
        ..draw.clone()
    };
    match layout.bar_length {
        Some(l) => distance_rows(&model.inner, &layout.points, l, 0.0, &exact),
        None => seat_rows(&model.inner, &layout.points, &exact),
    }
}

/// The weighted, column-scaled Jacobian blocks of instrument `rows` (module docs, step 2): the
/// residual Jacobian of each row for the [`instrument_model`] of `file` and `layout`, rows divided
/// by `noise_mm`, 3 rows per block (a distance's one row and two of zeros), on `columns` (indices
/// into the [`instrument_model`]'s parameters, e.g. a plan's [`InstrumentPlan::columns`], to
/// compare sets on one footing) or, without them, on the columns the rank test finds identifiable
/// over up to [`COLUMN_SAMPLE`] rows spread over the set.
pub fn instrument_blocks(
    file: &ModelFile,
    layout: &InstrumentLayout,
    rows: &[Measurement],
    noise_mm: f64,
    columns: Option<&[usize]>,
) -> Result<CandidateJacobians, CalibError> {
    let (model, free) = instrument_model(file, layout)?;
    blocks_on(&model, &free, layout, rows, noise_mm, columns)
}

/// [`instrument_blocks`] on the [`instrument_model`] `model` and its free columns `free`.
fn blocks_on(
    model: &NominalArtifact,
    free: &[usize],
    layout: &InstrumentLayout,
    rows: &[Measurement],
    noise_mm: f64,
    columns: Option<&[usize]>,
) -> Result<CandidateJacobians, CalibError> {
    if rows.is_empty() {
        return Err(CalibError::InvalidOption("no seat or distance row to plan from".into()));
    }
    if let Some(i) = rows.iter().position(|m| !row_matches(layout, m)) {
        return Err(CalibError::InvalidOption(format!(
            "row {i} is not a row of one of the layout's {} {}s",
            layout.points.len(),
            layout.kind().name()
        )));
    }
    artifact_blocks(model, free, rows, noise_mm, columns, |m| {
        m.obs.artifact_point().expect("checked above").1
    })
}

/// [`instrument_blocks`] on an [`Artifact`]-wrapped `model` whose free columns are `free`: row
/// `m` refers to the model's point `point_of(m)`.
pub(super) fn artifact_blocks(
    model: &NominalArtifact,
    free: &[usize],
    rows: &[Measurement],
    noise_mm: f64,
    columns: Option<&[usize]>,
    point_of: impl Fn(&Measurement) -> usize,
) -> Result<CandidateJacobians, CalibError> {
    if !(noise_mm.is_finite() && noise_mm > 0.0) {
        return Err(CalibError::InvalidOption(format!(
            "the measurement noise must be finite and > 0, got {noise_mm} mm"
        )));
    }
    let noise = Noise {
        position: noise_mm,
        ..Noise::default()
    };
    let p = model.n_params();
    let raw: Vec<DMatrix<f64>> = rows
        .iter()
        .enumerate()
        .map(|(i, m)| {
            // The wrapper's inputs: the machine's, then the row's point.
            let mut q = m.q.clone();
            q.push(point_of(m) as f64);
            let (pose, jac) = model
                .forward_with_jacobian(&q)
                .map_err(|source| CalibError::Kinematics { pose: i, source })?;
            let a = measure::residual_jacobian(&m.obs, &pose, &jac);
            let w = measure::row_weights(&m.obs, &noise);
            let mut block = DMatrix::zeros(3, p);
            for (r, w) in w.iter().enumerate().take(a.nrows().min(3)) {
                block.row_mut(r).copy_from(&(a.row(r) * *w));
            }
            Ok(block)
        })
        .collect::<Result<_, CalibError>>()?;
    let columns = match columns {
        Some(c) => {
            if let Some(&bad) = c.iter().find(|&&c| c >= p) {
                return Err(CalibError::InvalidOption(format!(
                    "parameter index {bad} out of range (the model has {p})"
                )));
            }
            c.to_vec()
        }
        None => {
            let step = (raw.len() / COLUMN_SAMPLE).max(1);
            let sample: Vec<&DMatrix<f64>> = raw.iter().step_by(step).collect();
            let mut stacked = DMatrix::zeros(3 * sample.len(), p);
            for (k, b) in sample.iter().enumerate() {
                stacked.view_mut((3 * k, 0), (3, p)).copy_from(b);
            }
            analyze(&stacked, free, DEFAULT_RANK_TOLERANCE).identifiable
        }
    };
    let mut data = Vec::with_capacity(raw.len() * 3 * columns.len());
    for b in &raw {
        for r in 0..3 {
            data.extend(columns.iter().map(|&c| b[(r, c)]));
        }
    }
    CandidateJacobians::from_raw(3, columns, data)
}

/// The criterion's value of the rows `set` of `blocks`, then the regularised `log det` (which
/// ranks sets whose criterion is zero before full rank).
pub(super) fn score(blocks: &CandidateJacobians, set: &[usize], criterion: Criterion) -> (f64, f64) {
    let m = blocks.information(set);
    let value = ObservabilityIndices::from_information(&m, blocks.rows_per_candidate() * set.len()).value(criterion);
    let k = m.nrows();
    let regular = m + DMatrix::identity(k, k) * super::information::DEFAULT_RIDGE;
    let log_det = regular
        .cholesky()
        .map_or(f64::NEG_INFINITY, |c| c.l().diagonal().iter().map(|d| 2.0 * d.ln()).sum());
    (value, log_det)
}

/// Give every point `k` at least `min[k]` rows of `selected` (each row's point in `point_of`):
/// for a point short of them, add its candidate that scores best, then drop the member (of a
/// point above its minimum) whose removal scores best. Returns the moves made.
fn give_each_point(
    blocks: &CandidateJacobians,
    point_of: &[usize],
    min: &[usize],
    criterion: Criterion,
    selected: &mut Vec<usize>,
) -> usize {
    let points = min.len();
    let better = |a: (f64, f64), b: (f64, f64)| a.0 > b.0 || (a.0 == b.0 && a.1 > b.1);
    let mut moves = 0;
    loop {
        let mut counts = vec![0usize; points];
        for &i in selected.iter() {
            counts[point_of[i]] += 1;
        }
        let Some(short) = (0..points).find(|&k| counts[k] < min[k]) else {
            return moves;
        };
        let mut best: Option<(usize, (f64, f64))> = None;
        for i in (0..point_of.len()).filter(|&i| point_of[i] == short && !selected.contains(&i)) {
            let mut trial = selected.clone();
            trial.push(i);
            let s = score(blocks, &trial, criterion);
            if best.is_none_or(|(_, b)| better(s, b)) {
                best = Some((i, s));
            }
        }
        let Some((add, _)) = best else { return moves };
        selected.push(add);
        let mut drop: Option<(usize, (f64, f64))> = None;
        for (pos, &j) in selected.iter().enumerate() {
            if point_of[j] == short || counts[point_of[j]] <= min[point_of[j]] {
                continue;
            }
            let trial: Vec<usize> = selected.iter().enumerate().filter(|&(p, _)| p != pos).map(|(_, &x)| x).collect();
            let s = score(blocks, &trial, criterion);
            if drop.is_none_or(|(_, b)| better(s, b)) {
                drop = Some((pos, s));
            }
        }
        if let Some((pos, _)) = drop {
            selected.remove(pos);
        }
        moves += 1;
    }
}

/// Plan `opts.select.n` instrument rows for `layout` on the nominal model of `file` (module
/// docs): candidates, blocks, the selection, then the repair that gives each point its minimum.
/// Errors: a bad layout or noise, fewer candidates than asked for, a size below the points'
/// minimum rows, or a point the nominal model cannot reach.
pub fn plan_instrument(file: &ModelFile, layout: &InstrumentLayout, opts: &InstrumentPlanOptions) -> Result<InstrumentPlan, CalibError> {
    layout.check()?;
    let min = opts.min_per_point.max(layout.min_rows());
    let n = opts.select.n;
    let need = min * layout.points.len();
    if n < need {
        return Err(CalibError::InvalidOption(format!(
            "{n} rows cannot give each of the {} {}s its {min} rows (at least {need} are needed)",
            layout.points.len(),
            layout.kind().name()
        )));
    }
    if opts.draw.per_point < min {
        return Err(CalibError::InvalidOption(format!(
            "{} candidates per {} cannot give each its {min} rows (draw at least {min})",
            opts.draw.per_point,
            layout.kind().name()
        )));
    }
    let (model, free) = instrument_model(file, layout)?;
    let candidates = candidates_on(&model, layout, &opts.draw)?;
    if candidates.len() < n {
        return Err(CalibError::InvalidOption(format!(
            "only {} candidates, fewer than the {n} rows asked for (raise the candidates per point)",
            candidates.len()
        )));
    }
    let blocks = blocks_on(&model, &free, layout, &candidates, opts.draw.noise_mm, None)?;
    let selection = select(&blocks, opts.method, &opts.select, &mut |_| {})?;
    let point_of: Vec<usize> = candidates
        .iter()
        .map(|m| m.obs.artifact_point().expect("an instrument row").1)
        .collect();
    let mins = vec![min; layout.points.len()];
    let params = model.params();
    Ok(repaired_plan(
        &blocks,
        candidates,
        selection,
        &point_of,
        &mins,
        opts.select.criterion,
        &params,
    ))
}

/// The plan of a selection on `blocks` of `candidates` once [`give_each_point`] has given each
/// point `k` (each candidate's in `point_of`) its `mins[k]` rows: the rows in candidate order,
/// the indices of the set, the columns named from `params`.
pub(super) fn repaired_plan(
    blocks: &CandidateJacobians,
    candidates: Vec<Measurement>,
    mut selection: Selection,
    point_of: &[usize],
    mins: &[usize],
    criterion: Criterion,
    params: &[crate::params::Param],
) -> InstrumentPlan {
    let repairs = give_each_point(blocks, point_of, mins, criterion, &mut selection.selected);
    selection.selected.sort_unstable();
    let m = blocks.information(&selection.selected);
    selection.indices = ObservabilityIndices::from_information(&m, blocks.rows_per_candidate() * selection.selected.len());
    InstrumentPlan {
        rows: selection.selected.iter().map(|&i| candidates[i].clone()).collect(),
        column_names: blocks.columns().iter().map(|&c| params[c].name.clone()).collect(),
        columns: blocks.columns().to_vec(),
        candidates,
        selection,
        repairs,
    }
}

/// Whether `m` is a row of one of `layout`'s points (a seat row for seats, a distance for pivots).
fn row_matches(layout: &InstrumentLayout, m: &Measurement) -> bool {
    match (&m.obs, layout.kind()) {
        (Observation::Seat(k), PointKind::Seat) => *k < layout.points.len(),
        (Observation::Distance { pivot, .. }, PointKind::Pivot) => *pivot < layout.points.len(),
        _ => false,
    }
}
