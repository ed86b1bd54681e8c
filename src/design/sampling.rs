//! Planning from a description of where to sample, for any mechanism a model file describes:
//! [`sample_candidates`] makes the candidates ([`CandidateSampling`]: a box of poses or of inputs,
//! Halton points or a grid) and [`plan_sampled`] runs [`super::plan()`] on them. `kinecal plan` and
//! Python's `plan_sampled` are this one call.
//!
//! What a box of poses means depends on the mechanism, and is decided here, not by the callers:
//! * a 5-DOF closed-loop machine of the 5-DOF paper samples its **platform coordinates**
//!   `(x, y, z, α, β, γ)` ([`super::candidates_in_platform_box`]; default: its prescribed workspace,
//!   γ parasitic at 0; strokes and an actuator-Jacobian condition ≤ [`PLATFORM_MAX_CONDITION`]
//!   applied; FK∘IK checked on the chosen set only); it offers the paper's grid
//!   ([`Points::PaperGrid`]);
//! * every other mechanism samples **tool poses** ([`super::candidates_in_workspace`]): positions in
//!   a box, roll/pitch/yaw about the world axes applied to the tool orientation at the start inputs
//!   (zero, or a limbs machine's home); a limbs machine's own workspace box is the default, as is
//!   a Stewart platform's (its Euler-angle ranges as roll/pitch/yaw offsets); the model's input
//!   limits applied. A mechanism without a box of its own, given no range at all, samples its
//!   inputs within their limits instead (a box of inputs, below), as `simulate` draws poses; it
//!   needs a range of x, y and z when an input has no limits.
//!
//! A box of inputs ([`Region::Inputs`]) is sampled directly by the forward kinematics
//! ([`super::candidates_in_input_box`]) for any mechanism.
use super::candidates::{Candidate, CandidateFilter, GenerationReport, Sampling, Workspace};
use super::plan::{plan, Plan, PlanOptions};
use super::select::Step;
use crate::error::CalibError;
use crate::io::model_file::ModelFile;
use crate::model::closed::Workspace as PlatformBox;
use crate::model::closed::{ClosedLoop, ConstraintSystem};
use crate::model::kind::MechanismSpec;
use crate::model::limbs::PoseBox;
use crate::model::presets::pm5::{Pm5, CANDIDATE_GRID};
use crate::model::Mechanism;
use crate::params::Unit;
use nalgebra::Vector3;
use std::time::Instant;

/// Largest actuator-Jacobian condition number of a platform-box candidate unless asked otherwise.
pub const PLATFORM_MAX_CONDITION: f64 = 100.0;

/// A range per coordinate of a box of poses; `None` takes the mechanism's own (see the
/// [module docs](self)). A range `(v, v)` is a fixed value.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PoseRanges {
    /// x, y, z (mm).
    pub position: [Option<(f64, f64)>; 3],
    /// Three angles (rad): roll, pitch, yaw about the world axes for a box of tool poses; the
    /// platform's α, β, γ for a platform box.
    pub angles: [Option<(f64, f64)>; 3],
}

/// Where candidates are drawn.
#[derive(Debug, Clone, PartialEq)]
pub enum Region {
    /// A box of poses in the mechanism's own coordinates.
    Poses(PoseRanges),
    /// A box of input values (rad / mm, in the mechanism's input order).
    Inputs {
        /// Lower bounds.
        lower: Vec<f64>,
        /// Upper bounds.
        upper: Vec<f64>,
    },
}

/// How the region is sampled.
#[derive(Debug, Clone, PartialEq)]
pub enum Points {
    /// Points of a shifted Halton sequence ([`Sampling::Halton`]).
    Halton {
        /// Number of points.
        n: usize,
        /// Seed of the shift.
        seed: u64,
    },
    /// A full grid, one count per coordinate ([`Sampling::Grid`]).
    Grid {
        /// Points per coordinate.
        counts: Vec<usize>,
    },
    /// The grid of the mechanism's paper (the 5-DOF machine: 11×11×21×12×10×1 = 304,920
    /// points); an error for a mechanism without one.
    PaperGrid,
}

/// A description of the candidates to make.
#[derive(Debug, Clone, PartialEq)]
pub struct CandidateSampling {
    /// Where.
    pub region: Region,
    /// How many points, and how placed.
    pub points: Points,
    /// Largest accepted input-Jacobian condition number; `None`: the mechanism's default
    /// ([`PLATFORM_MAX_CONDITION`] for a platform box, none otherwise).
    pub max_condition: Option<f64>,
}

/// The space actually sampled, every bound resolved.
#[derive(Debug, Clone, PartialEq)]
pub enum SampledSpace {
    /// Platform coordinates `(x, y, z, α, β, γ)` (mm, rad) of a closed-loop machine; with
    /// `parasitic` the rotation γ follows from the constraints.
    Platform {
        /// Lower bounds.
        min: [f64; 6],
        /// Upper bounds.
        max: [f64; 6],
        /// Whether γ is parasitic.
        parasitic: bool,
    },
    /// A box of tool poses.
    ToolPoses(Workspace),
    /// A box of inputs.
    Inputs {
        /// Lower bounds.
        lower: Vec<f64>,
        /// Upper bounds.
        upper: Vec<f64>,
    },
}

/// Candidates made from a [`CandidateSampling`], with what was sampled and what was kept.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidates {
    /// The kept candidates.
    pub candidates: Vec<Candidate>,
    /// The space sampled.
    pub space: SampledSpace,
    /// Points sampled.
    pub samples: usize,
    /// The condition bound applied (`None`: none).
    pub max_condition: Option<f64>,
    /// Counts per outcome.
    pub report: GenerationReport,
    /// Smallest and largest actuator-Jacobian condition number of the kept candidates (platform
    /// boxes only).
    pub condition: Option<(f64, f64)>,
    /// Seconds spent.
    pub seconds: f64,
}

/// What a sampled plan reports while it runs.
#[derive(Debug)]
pub enum PlanEvent<'a> {
    /// Candidate generation starts: `samples` points of `space`, `max_condition` applied.
    Sampling {
        /// The space sampled.
        space: &'a SampledSpace,
        /// Points to sample.
        samples: usize,
        /// The condition bound applied.
        max_condition: Option<f64>,
    },
    /// The candidates are made.
    Generated(&'a Candidates),
    /// The Jacobian blocks of `blocks` candidates start.
    Jacobians {
        /// Blocks to build.
        blocks: usize,
    },
    /// `k` more samples or blocks done (from any thread).
    Done(u64),
    /// A move of the selection.
    Step(&'a Step),
}

/// A callback receiving [`PlanEvent`]s (from any thread).
pub type PlanProgress<'a> = &'a (dyn Fn(PlanEvent<'_>) + Sync);

/// A plan made by [`plan_sampled`]: the candidates, the chosen set and what the CSV needs.
#[derive(Debug, Clone)]
pub struct SampledPlan {
    /// The name of the planned mechanism.
    pub mechanism: String,
    /// Its input names.
    pub input_names: Vec<String>,
    /// Which inputs are angles (written in degrees).
    pub angle_inputs: Vec<bool>,
    /// Its number of error parameters.
    pub parameters: usize,
    /// Their names (what [`Plan::columns`] index).
    pub parameter_names: Vec<String>,
    /// The mechanism drawn at home ([`Mechanism::skeleton`]; world frame, mm), for the plan's
    /// report.
    pub skeleton: Vec<Vec<Vector3<f64>>>,
    /// The candidates.
    pub candidates: Candidates,
    /// The chosen set.
    pub plan: Plan,
}

impl SampledPlan {
    /// The plan as JSON (what `kinecal plan --json` prints, without its timings of the whole run
    /// and output path): mechanism, candidates, identifiable parameters, method, criterion,
    /// configurations, chosen candidates, indices, selection seconds.
    pub fn summary(&self) -> serde_json::Value {
        let sel = &self.plan.selection;
        let ix = &sel.indices;
        serde_json::json!({
            "mechanism": self.mechanism,
            "candidates": self.candidates.candidates.len(),
            "identifiable_parameters": self.plan.columns.len(),
            "method": format!("{:?}", sel.method),
            "criterion": sel.criterion.to_string(),
            "configurations": sel.selected.len(),
            "chosen_candidates": sel.selected,
            "indices": {"o1": ix.o1, "o2": ix.o2, "o_t": ix.o_t, "o3": ix.o3, "o4": ix.o4, "o5": ix.o5, "log_det": ix.log_det},
            "selection_seconds": self.plan.selection_seconds,
        })
    }

    /// The chosen configurations as the CSV of [`super::write_plan_csv`].
    pub fn write_csv<W: std::io::Write>(&self, out: W) -> std::io::Result<()> {
        super::write_plan_csv(
            out,
            &self.input_names,
            &self.angle_inputs,
            &self.candidates.candidates,
            &self.plan.selection,
        )
    }
}

fn invalid(msg: String) -> CalibError {
    CalibError::InvalidOption(msg)
}

fn sampling_of(points: &Points, paper: Option<&[usize]>) -> Result<Sampling, CalibError> {
    Ok(match points {
        Points::Halton { n, seed } => Sampling::Halton { n: *n, seed: *seed },
        Points::Grid { counts } => Sampling::Grid { counts: counts.clone() },
        Points::PaperGrid => Sampling::Grid {
            counts: paper
                .ok_or_else(|| invalid("the paper's grid is only defined for the 5-DOF machine (pm5)".into()))?
                .to_vec(),
        },
    })
}

/// `given`, else the mechanism's own range, else an error naming the coordinate.
fn pick(given: Option<(f64, f64)>, own: Option<(f64, f64)>, what: &str, model: &str) -> Result<(f64, f64), CalibError> {
    given.or(own).ok_or_else(|| {
        invalid(format!(
            "a range of {what} is required: model '{model}' has no workspace of its own (MIN,MAX or VALUE; given no range at all, a model whose inputs all have limits is sampled within them)"
        ))
    })
}

/// Report `k` more items done.
fn done<'a>(progress: Option<PlanProgress<'a>>) -> impl Fn(u64) + Sync + 'a {
    move |k| {
        if let Some(p) = progress {
            p(PlanEvent::Done(k));
        }
    }
}

fn announce(progress: Option<PlanProgress>, space: &SampledSpace, samples: usize, max_condition: Option<f64>) {
    if let Some(p) = progress {
        p(PlanEvent::Sampling {
            space,
            samples,
            max_condition,
        });
    }
}

/// The candidates `generate` keeps of `samples` points of `space` (announced first), timed:
/// `generate` returns them, their report and, for a platform box, their condition range.
fn generated(
    progress: Option<PlanProgress>,
    space: SampledSpace,
    samples: usize,
    max_condition: Option<f64>,
    generate: impl FnOnce() -> Result<(Vec<Candidate>, GenerationReport, Option<(f64, f64)>), CalibError>,
) -> Result<Candidates, CalibError> {
    announce(progress, &space, samples, max_condition);
    let t = Instant::now();
    let (candidates, report, condition) = generate()?;
    Ok(Candidates {
        candidates,
        space,
        samples,
        max_condition,
        report,
        condition,
        seconds: t.elapsed().as_secs_f64(),
    })
}

/// Candidates of a 5-DOF machine in its platform-coordinate box.
fn platform_candidates(
    mech: &ClosedLoop<Pm5>,
    ranges: &PoseRanges,
    sampling: &CandidateSampling,
    progress: Option<PlanProgress>,
) -> Result<Candidates, CalibError> {
    let ws = mech.system().workspace();
    let own = |k: usize| Some((ws.min[k], ws.max[k]));
    let name = mech.name().to_string();
    let mut min = [0.0; 6];
    let mut max = [0.0; 6];
    for k in 0..6 {
        let (given, default) = if k < 3 {
            (ranges.position[k], own(k))
        } else {
            (ranges.angles[k - 3], if k < 5 { own(k) } else { Some((0.0, 0.0)) })
        };
        (min[k], max[k]) = pick(given, default, ["x", "y", "z", "α", "β", "γ"][k], &name)?;
    }
    let points = sampling_of(&sampling.points, Some(&CANDIDATE_GRID))?;
    // FK∘IK is checked on the chosen configurations (design::plan), not on every sample.
    let filter = CandidateFilter {
        input_limits: Some(mech.system().strokes()),
        max_condition: Some(sampling.max_condition.unwrap_or(PLATFORM_MAX_CONDITION)),
        check_forward: false,
        ..Default::default()
    };
    let samples = points.len(6)?;
    let space = SampledSpace::Platform { min, max, parasitic: true };
    generated(progress, space, samples, filter.max_condition, || {
        let (candidates, gen) =
            super::candidates_in_platform_box(mech, &PlatformBox { min, max }, &points, &filter, Some(&done(progress)))?;
        Ok((candidates, gen.report, Some((gen.condition_min, gen.condition_max))))
    })
}

/// A closed-loop machine's workspace as a box of tool poses, where its tool frame is its platform
/// frame (no tool offset, base at the origin): the platform positions, and its X-Y-Z Euler-angle
/// ranges as the roll, pitch and yaw offsets about the home orientation (the same rotations to
/// first order: the boxes of a workspace are a few degrees wide).
fn closed_loop_box<C: ConstraintSystem>(m: &ClosedLoop<C>) -> Option<PoseBox> {
    if m.tool() != [0.0; 3] || m.base() != [0.0; 6] {
        return None;
    }
    let ws = m.system().workspace();
    Some(PoseBox {
        position_min: Vector3::new(ws.min[0], ws.min[1], ws.min[2]),
        position_max: Vector3::new(ws.max[0], ws.max[1], ws.max[2]),
        rpy_min: [ws.min[3], ws.min[4], ws.min[5]],
        rpy_max: [ws.max[3], ws.max[4], ws.max[5]],
    })
}

/// The input limits of a model file, if any input has some.
fn input_limits(file: &ModelFile) -> Option<Vec<(f64, f64)>> {
    let inputs = file.inputs();
    inputs.iter().any(|i| i.limits.is_some()).then(|| {
        inputs
            .iter()
            .map(|i| i.limits.unwrap_or((f64::NEG_INFINITY, f64::INFINITY)))
            .collect()
    })
}

/// Candidates in a box of tool poses, solved by the inverse kinematics from the start inputs.
fn tool_pose_candidates(
    file: &ModelFile,
    mech: &dyn Mechanism,
    ranges: &PoseRanges,
    sampling: &CandidateSampling,
    progress: Option<PlanProgress>,
) -> Result<Candidates, CalibError> {
    // A limbs mechanism starts at its home inputs and defaults to its own workspace box.
    let (start, own) = match &file.mechanism {
        MechanismSpec::Limbs(m) => (m.home_inputs(), m.workspace().cloned()),
        MechanismSpec::Stewart(m) => (vec![0.0; file.inputs().len()], closed_loop_box(m)),
        _ => (vec![0.0; file.inputs().len()], None),
    };
    // Nothing to say where the tool goes: the inputs within their limits, as `simulate` draws them.
    let unbounded = ranges.position.iter().chain(&ranges.angles).all(Option::is_none);
    if let (None, true, Some(limits)) = (&own, unbounded, input_limits(file)) {
        if limits.iter().all(|(a, b)| a.is_finite() && b.is_finite()) {
            let (lower, upper): (Vec<f64>, Vec<f64>) = limits.into_iter().unzip();
            return input_candidates(file, mech, &lower, &upper, sampling, progress);
        }
    }
    let home = mech.forward(&start).map_err(|e| {
        invalid(format!(
            "{}: forward kinematics at its start inputs (zero, or a limbs mechanism's home): {e}",
            file.name
        ))
    })?;
    let mut lo = [0.0; 6];
    let mut hi = [0.0; 6];
    for k in 0..6 {
        let (given, default) = if k < 3 {
            (ranges.position[k], own.as_ref().map(|w| (w.position_min[k], w.position_max[k])))
        } else {
            let w = k - 3;
            (
                ranges.angles[w],
                Some(own.as_ref().map_or((0.0, 0.0), |o| (o.rpy_min[w], o.rpy_max[w]))),
            )
        };
        (lo[k], hi[k]) = pick(given, default, ["x", "y", "z", "roll", "pitch", "yaw"][k], &file.name)?;
    }
    let ws = Workspace {
        position_min: Vector3::new(lo[0], lo[1], lo[2]),
        position_max: Vector3::new(hi[0], hi[1], hi[2]),
        reference: home.rotation,
        rpy_min: [lo[3], lo[4], lo[5]],
        rpy_max: [hi[3], hi[4], hi[5]],
    };
    let filter = CandidateFilter {
        input_limits: input_limits(file),
        max_condition: sampling.max_condition,
        // Where the inverse kinematics gives its whole solution, FK∘IK is checked on the chosen set.
        check_forward: false,
        ..Default::default()
    };
    let points = sampling_of(&sampling.points, None)?;
    let samples = points.len(6)?;
    let space = SampledSpace::ToolPoses(ws.clone());
    generated(progress, space, samples, filter.max_condition, || {
        let (candidates, report) = super::candidates_in_workspace(mech, &ws, &points, Some(&start), &filter, Some(&done(progress)))?;
        Ok((candidates, report, None))
    })
}

/// Candidates in a box of inputs.
fn input_candidates(
    file: &ModelFile,
    mech: &dyn Mechanism,
    lower: &[f64],
    upper: &[f64],
    sampling: &CandidateSampling,
    progress: Option<PlanProgress>,
) -> Result<Candidates, CalibError> {
    let filter = CandidateFilter {
        input_limits: input_limits(file),
        max_condition: sampling.max_condition,
        ..Default::default()
    };
    let points = sampling_of(&sampling.points, None)?;
    let samples = points.len(lower.len())?;
    let space = SampledSpace::Inputs {
        lower: lower.to_vec(),
        upper: upper.to_vec(),
    };
    generated(progress, space, samples, filter.max_condition, || {
        let (candidates, report) = super::candidates_in_input_box(mech, lower, upper, &points, &filter, Some(&done(progress)))?;
        Ok((candidates, report, None))
    })
}

/// The mechanism of `file` that is planned (a 5-DOF machine without its frames: its candidates
/// live in its own platform coordinates) and its candidates from `sampling` (see the
/// [module docs](self)). `progress` receives [`PlanEvent::Sampling`], then
/// [`PlanEvent::Done`] per sample.
pub fn sample_candidates(
    file: &ModelFile,
    sampling: &CandidateSampling,
    progress: Option<PlanProgress>,
) -> Result<(Box<dyn Mechanism>, Candidates), CalibError> {
    if let (MechanismSpec::Pm5(m), Region::Poses(ranges)) = (&file.mechanism, &sampling.region) {
        let cands = platform_candidates(m, ranges, sampling, progress)?;
        return Ok((Box::new(m.clone()), cands));
    }
    let mech = file.build();
    let cands = match &sampling.region {
        Region::Poses(ranges) => tool_pose_candidates(file, &*mech, ranges, sampling, progress)?,
        Region::Inputs { lower, upper } => input_candidates(file, &*mech, lower, upper, sampling, progress)?,
    };
    Ok((mech, cands))
}

/// Candidates of `file` from `sampling` ([`sample_candidates`]), then [`plan`] on them with
/// `opts`. `progress` receives, in order: [`PlanEvent::Sampling`], [`PlanEvent::Done`] per
/// sample, [`PlanEvent::Generated`], [`PlanEvent::Jacobians`], [`PlanEvent::Done`] per block,
/// [`PlanEvent::Step`] per selection move.
pub fn plan_sampled(
    file: &ModelFile,
    sampling: &CandidateSampling,
    opts: &PlanOptions,
    progress: Option<PlanProgress>,
) -> Result<SampledPlan, CalibError> {
    opts.check()?;
    let (mech, candidates) = sample_candidates(file, sampling, progress)?;
    if let Some(p) = progress {
        p(PlanEvent::Generated(&candidates));
        p(PlanEvent::Jacobians {
            blocks: candidates.candidates.len(),
        });
    }
    let mut step = |s: &Step| {
        if let Some(p) = progress {
            p(PlanEvent::Step(s));
        }
    };
    let planned = plan(&*mech, &candidates.candidates, opts, Some(&done(progress)), &mut step)?;
    Ok(SampledPlan {
        mechanism: mech.name().to_string(),
        input_names: mech.input_names(),
        angle_inputs: file.inputs().iter().map(|i| i.unit == Unit::Angle).collect(),
        parameters: mech.n_params(),
        parameter_names: mech.params().into_iter().map(|p| p.name).collect(),
        skeleton: mech.skeleton(),
        candidates,
        plan: planned,
    })
}

impl std::fmt::Display for SampledSpace {
    /// The bounds in mm and degrees, e.g. "x (-50.0, 50.0) mm, …, γ (0.0, 0.0)° (parasitic)".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let deg = |a: f64, b: f64| (a.to_degrees(), b.to_degrees());
        let six = |f: &mut std::fmt::Formatter<'_>, lo: &[f64], hi: &[f64], names: [&str; 3]| {
            write!(f, "x {:?} mm, y {:?} mm, z {:?} mm", (lo[0], hi[0]), (lo[1], hi[1]), (lo[2], hi[2]))?;
            for k in 0..3 {
                write!(f, ", {} {:?}°", names[k], deg(lo[k + 3], hi[k + 3]))?;
            }
            Ok(())
        };
        match self {
            SampledSpace::Platform { min, max, parasitic } => {
                six(f, min, max, ["α", "β", "γ"])?;
                if *parasitic {
                    write!(f, " (parasitic)")?;
                }
                Ok(())
            }
            SampledSpace::ToolPoses(ws) => {
                let (lo, hi) = ws.bounds();
                six(f, &lo, &hi, ["roll", "pitch", "yaw"])?;
                write!(f, " about the world axes from the home orientation")
            }
            SampledSpace::Inputs { lower, upper } => {
                let list = |v: &[f64]| v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", ");
                write!(f, "inputs from [{}] to [{}] (rad / mm)", list(lower), list(upper))
            }
        }
    }
}
