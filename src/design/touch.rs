//! Planning where to touch: which configurations a touch probe should touch each
//! reference sphere, unknown plane or datum-cube face from, as [`super::instrument`] plans the
//! orientations at seats.
//!
//! 1. **Candidates** ([`touch_candidates`]) on the *nominal* model with the nominal probe offset:
//!    random configurations within the limits, for each artifact the ones whose probe centre
//!    comes nearest its surface, moved onto it ([`touch_rows`], noise-free), so that each
//!    artifact is approached from the orientations the machine reaches it in.
//! 2. **Blocks**: each candidate's weighted residual Jacobian of the [`Artifact`]-wrapped
//!    nominal with the tool-point offset, the model's free parameters and every artifact's
//!    unknowns free (as [`crate::calibrate`] fits touches), on the identifiable columns.
//! 3. **Selection** ([`plan_touches`]): [`super::select()`] on those blocks, then the repair that
//!    gives every sphere, plane and cube face its minimum touches ([`min_rows`]).
//!
//! The D-criterion on the full information matrix is the criterion on the geometry once the
//! artifacts are estimated, up to `log det` of the artifacts' own block (module docs of
//! [`super::instrument`]); for touches that block depends on where each artifact is touched,
//! so the criterion also rewards touches that place the artifacts well, which the fit needs too.
use super::instrument::{artifact_blocks, repaired_plan, InstrumentPlan, InstrumentPlanOptions, NominalArtifact};
use super::select::select;
use crate::error::CalibError;
use crate::instrument::simulate::{touch_rows, Touched};
use crate::instrument::touch::min_rows;
use crate::instrument::{Artifact, ArtifactPoint, PointKind};
use crate::io::model_file::{free_params, ModelFile};
use crate::measure::{Measurement, Observation, Touch};
use crate::model::framed::{Framed, FRAME_PARAMS, TOOL_TRANSLATION};
use crate::model::Mechanism;
use crate::se3::Pose;
use nalgebra::{Translation3, Vector3};
use rand::SeedableRng;

/// What a probe touches, on the nominal model.
#[derive(Debug, Clone, PartialEq)]
pub struct TouchLayout {
    /// The artifacts (mm, the model's base frame): spheres, planes, a datum cube's faces.
    pub artifacts: Vec<Touched>,
    /// The probe ball's centre on the flange or platform (mm, in the model file's tool frame):
    /// the nominal tool point.
    pub ball: Vector3<f64>,
}

impl TouchLayout {
    /// An error unless there are artifacts, their frames and the ball are finite, and every
    /// size is plausible in mm.
    pub fn check(&self) -> Result<(), CalibError> {
        if self.artifacts.is_empty() {
            return Err(CalibError::InvalidOption("no sphere, plane or cube face to touch".into()));
        }
        let finite = |a: &Touched| {
            a.frame
                .translation
                .vector
                .iter()
                .chain(a.frame.rotation.coords.iter())
                .all(|v| v.is_finite())
        };
        if let Some(a) = self.artifacts.iter().find(|a| !finite(a)) {
            let (kind, id) = a.touch.artifact();
            return Err(CalibError::InvalidOption(format!("{} {id}: its frame must be finite", kind.name())));
        }
        if self.ball.iter().any(|v| !v.is_finite()) {
            return Err(CalibError::InvalidOption("the probe offset must be finite".into()));
        }
        Ok(())
    }

    /// The artifact points of the layout, one per artifact (the cube's faces are one point),
    /// in order of first appearance, in the frames the layout gives them.
    fn points(&self) -> Vec<ArtifactPoint> {
        let mut points: Vec<ArtifactPoint> = Vec::new();
        for a in &self.artifacts {
            let (kind, id) = a.touch.artifact();
            if points.iter().any(|p| p.kind == kind && p.id == id) {
                continue;
            }
            points.push(ArtifactPoint {
                kind,
                id,
                centre: a.frame.translation.vector,
                zero: None,
                rotation: (kind != PointKind::Sphere).then_some(a.frame.rotation),
            });
        }
        points
    }
}

/// The group a touch row's minimum is counted in: its artifact, and for the cube its face.
fn group_of(m: &Measurement) -> Option<(PointKind, usize, usize)> {
    match m.obs {
        Observation::Touch(t) => Some(touch_group(t)),
        _ => None,
    }
}

/// A touch's group ([`group_of`]).
fn touch_group(t: Touch) -> (PointKind, usize, usize) {
    let (kind, id) = t.artifact();
    let face = match t {
        Touch::Face { face, .. } => face,
        _ => 0,
    };
    (kind, id, face)
}

/// The nominal model of `file` with the probe of `layout` on its tool, wrapped with the layout's
/// artifacts as parameters ([`Artifact`]), and its free columns: the tool point's offset, the
/// file's free parameters, the artifacts' unknowns (as [`crate::calibrate`] fits touches).
pub fn touch_model(file: &ModelFile, layout: &TouchLayout) -> Result<(NominalArtifact, Vec<usize>), CalibError> {
    layout.check()?;
    let inner = file.mechanism.build();
    let inner_free = free_params(&*inner, &file.free, &file.fixed)
        .map_err(|message| CalibError::InvalidOption(format!("model '{}': {message}", file.name)))?;
    let tool = file.frames.map_or(Pose::identity(), |f| f.tool) * Translation3::from(layout.ball);
    let model = Artifact {
        inner: Framed::new(inner, Pose::identity(), tool),
        points: layout.points(),
        pairs: Vec::new(),
    };
    let mut free: Vec<usize> = TOOL_TRANSLATION.collect();
    free.extend(inner_free.iter().map(|k| k + FRAME_PARAMS));
    free.extend(model.artifact_columns());
    Ok((model, free))
}

/// Candidate touches for `layout` on the nominal model of `file` (module docs, step 1):
/// `per_artifact` per sphere, plane or cube face, chosen among `30 · per_artifact` random
/// configurations per artifact (seed `seed`). An artifact the nominal model does not reach
/// often enough is an error naming it.
pub fn touch_candidates(file: &ModelFile, layout: &TouchLayout, per_artifact: usize, seed: u64) -> Result<Vec<Measurement>, CalibError> {
    candidates_on(&touch_model(file, layout)?.0, file, layout, per_artifact, seed)
}

/// [`touch_candidates`] on the [`touch_model`] `model`.
fn candidates_on(
    model: &NominalArtifact,
    file: &ModelFile,
    layout: &TouchLayout,
    per_artifact: usize,
    seed: u64,
) -> Result<Vec<Measurement>, CalibError> {
    let inputs = file.inputs();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let drawn = crate::simulate::random_configurations(&model.inner, &inputs, 30 * per_artifact * layout.artifacts.len(), &mut rng)
        .map_err(|source| CalibError::Kinematics { pose: 0, source })?;
    touch_rows(&model.inner, &drawn, &layout.artifacts, per_artifact, 0.0, seed, &inputs)
}

/// The weighted, column-scaled Jacobian blocks of touch `rows` (module docs, step 2) for the
/// [`touch_model`] of `file` and `layout`, rows divided by `noise_mm`, 3 rows per block (a
/// touch's one row and two of zeros), on `columns` (e.g. a plan's [`InstrumentPlan::columns`],
/// to compare sets on one footing) or on the identifiable ones. A row that touches no artifact
/// of the layout is an error naming it.
pub fn touch_blocks(
    file: &ModelFile,
    layout: &TouchLayout,
    rows: &[Measurement],
    noise_mm: f64,
    columns: Option<&[usize]>,
) -> Result<super::CandidateJacobians, CalibError> {
    let (model, free) = touch_model(file, layout)?;
    blocks_on(&model, &free, rows, noise_mm, columns)
}

/// [`touch_blocks`] on the [`touch_model`] `model` and its free columns `free`.
fn blocks_on(
    model: &NominalArtifact,
    free: &[usize],
    rows: &[Measurement],
    noise_mm: f64,
    columns: Option<&[usize]>,
) -> Result<super::CandidateJacobians, CalibError> {
    let index = |m: &Measurement| {
        let (kind, id) = m.obs.artifact_point()?;
        model.points.iter().position(|p| p.kind == kind && p.id == id)
    };
    if rows.is_empty() {
        return Err(CalibError::InvalidOption("no touch to plan from".into()));
    }
    if let Some(i) = rows.iter().position(|m| group_of(m).is_none() || index(m).is_none()) {
        return Err(CalibError::InvalidOption(format!(
            "row {i} is not a touch of one of the layout's artifacts"
        )));
    }
    artifact_blocks(model, free, rows, noise_mm, columns, |m| index(m).expect("checked above"))
}

/// Plan `opts.select.n` touches for `layout` on the nominal model of `file` (module docs):
/// candidates (`opts.draw.per_point` per artifact, seed `opts.draw.seed`; the draw's reference
/// and tilt are not used), blocks weighted by `opts.draw.noise_mm`, the selection, then the
/// repair that gives each sphere, plane and cube face its minimum (at least
/// `opts.min_per_point`). Errors: a bad layout or noise, too few candidates, a size below the
/// minimum touches.
pub fn plan_touches(file: &ModelFile, layout: &TouchLayout, opts: &InstrumentPlanOptions) -> Result<InstrumentPlan, CalibError> {
    layout.check()?;
    let mut groups: Vec<(PointKind, usize, usize)> = layout.artifacts.iter().map(|a| touch_group(a.touch)).collect();
    groups.dedup();
    let min = |g: &(PointKind, usize, usize)| min_rows(g.0).max(opts.min_per_point);
    let need: usize = groups.iter().map(min).sum();
    let n = opts.select.n;
    if n < need {
        return Err(CalibError::InvalidOption(format!(
            "{n} touches cannot give each of the {} spheres, planes or cube faces its minimum ({need} are needed)",
            groups.len()
        )));
    }
    let per = opts.draw.per_point;
    if let Some(g) = groups.iter().find(|g| per < min(g)) {
        return Err(CalibError::InvalidOption(format!(
            "{per} candidates per artifact cannot give {} {} its {} touches (draw at least that many)",
            g.0.name(),
            g.1,
            min(g)
        )));
    }
    let (model, free) = touch_model(file, layout)?;
    let candidates = candidates_on(&model, file, layout, per, opts.draw.seed)?;
    if candidates.len() < n {
        return Err(CalibError::InvalidOption(format!(
            "only {} candidates, fewer than the {n} touches asked for (raise the candidates per artifact)",
            candidates.len()
        )));
    }
    let blocks = blocks_on(&model, &free, &candidates, opts.draw.noise_mm, None)?;
    let selection = select(&blocks, opts.method, &opts.select, &mut |_| {})?;
    let group_index: Vec<usize> = candidates
        .iter()
        .map(|m| groups.iter().position(|g| Some(*g) == group_of(m)).expect("a group of the layout"))
        .collect();
    let mins: Vec<usize> = groups.iter().map(min).collect();
    let params = model.params();
    Ok(repaired_plan(
        &blocks,
        candidates,
        selection,
        &group_index,
        &mins,
        opts.select.criterion,
        &params,
    ))
}
