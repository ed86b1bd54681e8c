//! The simulation study of §5.1 of the 5-DOF paper, reproduced on the [`pm5`] preset.
//!
//! Procedure (one *trial*):
//! 1. random geometric errors dW, uniform in `±0.2 mm` / `±0.02°` on all 44 parameters; the
//!    virtual prototype ("truth") is the same constraint model with the erroneous parameters;
//! 2. target configurations: platform poses drawn uniformly in the prescribed workspace, their
//!    nominal tool poses `Q` are the targets and the nominal inverse kinematics gives the commands;
//!    the first `identification` ones are measured on the truth (full tool pose, with or without
//!    Gaussian noise `N(0, σ_p²)`, `N(0, σ_θ²)` per axis), the other `verification` ones are used
//!    only to evaluate;
//! 3. identification of dW′ (the identifiable subset in the natural priority order, see
//!    [`pm5::natural_priority`]) with kinecal's iterated Gauss–Newton, residuals weighted by the
//!    noise (maximum likelihood);
//! 4. compensation, two ways: **exact** — the calibrated model's inverse kinematics gives the
//!    commands for each target — and the paper's **first order** — `Q_a = Q − dQ′` with
//!    `dQ′ = H′·dW′` (the nominal identification Jacobian times the identified errors), commands
//!    from the nominal inverse kinematics of `Q_a`;
//! 5. errors of the truth's tool pose against the target: position (mm), full rotation
//!    `|log(R·R_Qᵀ)|` and tool-axis (z-axis direction) angle (deg). Rotation about the tool axis
//!    is a parasitic motion the 5-DOF machine cannot command, so with base-rotation errors present
//!    the full rotation error cannot reach zero; the tool-axis error can.
//!
//! # Reading the results
//! * Noise-free, the iterated identification recovers the pose map exactly: after exact
//!   compensation the position and tool-axis errors are at round-off (≈1e-12 mm, 1e-12°). The
//!   full rotation error keeps the uncommandable rotation about the tool axis.
//! * With noise and dW′ keeping `dl2, dl3, dg4` (the default), `dl2, dl3`
//!   (`dl6, dl7`) are poorly determined (standard deviations of 10–20 mm: their Jacobian
//!   `∂(A, B)/∂(l2, l3)` of `L22² = A − B·g4²` has determinant `∝ (l2 + l5)² − l3²`), so the
//!   identified dW′ can be millimetres away from the truth along a direction the poses hardly
//!   see. Exact compensation does not mind; the paper's first-order compensation `Q − H′·dW′`
//!   does (second-order terms of mm-sized errors). Keeping `dl4, dl5, dg4` instead
//!   ([`SubLoopChoice::KeepL4L5`], the paper's dW′) gives the same exact-compensation accuracy and
//!   small identified values, and then the first-order compensation is close to the exact one.
//!
//! The paper's figures (noise-free 0.515 → 0.004 mm and 0.249° → 0.001°; with noise 0.015 mm and
//! 0.019°) are averages over its 30 identification configurations; kinecal reports the same set
//! and the held-out verification set, plus a Monte-Carlo over independent trials (each seeded).
use crate::error::CalibError;
use crate::identify::{identify, Options};
use crate::measure::Noise;
use crate::model::closed::ClosedLoop;
use crate::model::presets::pm5::{self, Parasitic, Pm5};
use crate::model::Mechanism;
use crate::se3::{self, Pose};
use crate::simulate::{self, ObservationKind};
use nalgebra::DVector;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

/// Options of [`pm5_study`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyOptions {
    /// Seed of the single-trial table; Monte-Carlo draw `k` uses `seed + 1 + k`.
    pub seed: u64,
    /// Identification configurations per trial.
    pub identification: usize,
    /// Verification configurations per trial.
    pub verification: usize,
    /// Monte-Carlo draws (0: none).
    pub draws: usize,
    /// Half-width of the uniform length errors (mm).
    pub error_length: f64,
    /// Half-width of the uniform angle errors (rad).
    pub error_angle: f64,
    /// Measurement noise of the noisy runs (also the residual weights).
    pub noise: Noise,
    /// Parasitic-constraint model (the same for the truth and the identified model).
    pub parasitic: Parasitic,
    /// Which sub-loop parameters dW′ keeps.
    pub sub_loop: SubLoopChoice,
    /// Identification configurations (actuator inputs) to use in every trial instead of random
    /// ones, e.g. a planned set from [`pm5_plan`]; `None`: `identification` random
    /// configurations per trial.
    pub planned: Option<Vec<Vec<f64>>>,
}

/// Which two of the five sub-loop parameters (`dl2…dl5, dg4`, likewise for limb 3) dW′ drops.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum SubLoopChoice {
    /// Keep `dl2, dl3, dg4`, drop `dl4, dl5` ([`pm5::natural_priority`]).
    #[default]
    KeepL2L3,
    /// Keep `dl4, dl5, dg4`, drop `dl2, dl3` (the paper's dW′; [`pm5::paper_priority`]).
    KeepL4L5,
}

impl Default for StudyOptions {
    fn default() -> Self {
        StudyOptions {
            seed: 2024,
            identification: 30,
            verification: 20,
            draws: 100,
            error_length: 0.2,
            error_angle: 0.02f64.to_radians(),
            noise: Noise::default(),
            parasitic: Parasitic::Physical,
            sub_loop: SubLoopChoice::KeepL2L3,
            planned: None,
        }
    }
}

/// Mean and maximum pose errors after the study's exact compensation over a set of configurations
/// (mm and degrees; the general statistics are [`crate::validate::ErrorStats`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct CompensatedErrorStats {
    /// Mean position error (mm).
    pub position_mean: f64,
    /// Maximum position error (mm).
    pub position_max: f64,
    /// Mean full rotation error (deg).
    pub rotation_mean: f64,
    /// Maximum full rotation error (deg).
    pub rotation_max: f64,
    /// Mean tool-axis direction error (deg).
    pub axis_mean: f64,
    /// Maximum tool-axis direction error (deg).
    pub axis_max: f64,
}

impl CompensatedErrorStats {
    fn from_errors(e: &[(f64, f64, f64)]) -> Self {
        let n = e.len().max(1) as f64;
        let mut s = CompensatedErrorStats::default();
        for &(p, r, a) in e {
            s.position_mean += p / n;
            s.rotation_mean += r / n;
            s.axis_mean += a / n;
            s.position_max = s.position_max.max(p);
            s.rotation_max = s.rotation_max.max(r);
            s.axis_max = s.axis_max.max(a);
        }
        s
    }
}

/// Errors before and after both compensations on one set of configurations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Compensation {
    /// Before calibration (nominal commands).
    pub before: CompensatedErrorStats,
    /// After exact compensation (calibrated inverse kinematics).
    pub exact: CompensatedErrorStats,
    /// After the paper's first-order compensation `Q_a = Q − H′·dW′`.
    pub first_order: CompensatedErrorStats,
}

/// One trial of the study.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Trial {
    /// On the identification configurations (as the paper reports).
    pub identification_set: Compensation,
    /// On the held-out verification configurations.
    pub verification_set: Compensation,
    /// Gauss–Newton iterations.
    pub iterations: usize,
    /// Whether the solver's convergence test was met.
    pub converged: bool,
    /// A-posteriori standard deviation of unit weight.
    pub sigma0: f64,
}

/// Mean and 95th percentile of a quantity over Monte-Carlo draws.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct Spread {
    /// Mean over draws.
    pub mean: f64,
    /// 95th percentile over draws.
    pub p95: f64,
}

impl Spread {
    fn of(mut v: Vec<f64>) -> Self {
        if v.is_empty() {
            return Spread::default();
        }
        v.sort_by(f64::total_cmp);
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let k = ((0.95 * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1;
        Spread { mean, p95: v[k] }
    }
}

/// Monte-Carlo summary of the per-draw mean errors after exact compensation, with noise.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MonteCarlo {
    /// Draws that completed.
    pub draws: usize,
    /// Draws that failed (kinematics or identification error), with their messages.
    pub failures: Vec<String>,
    /// Verification set: position (mm).
    pub verification_position: Spread,
    /// Verification set: tool axis (deg).
    pub verification_axis: Spread,
    /// Verification set: full rotation (deg).
    pub verification_rotation: Spread,
    /// Identification set: position (mm).
    pub identification_position: Spread,
    /// Identification set: tool axis (deg).
    pub identification_axis: Spread,
    /// Identification set: full rotation (deg).
    pub identification_rotation: Spread,
    /// Verification set after first-order compensation: position (mm).
    pub first_order_position: Spread,
    /// Verification set after first-order compensation: tool axis (deg).
    pub first_order_axis: Spread,
}

/// The paper's reported averages (§5.1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PaperFigures {
    /// Noise-free, before: position (mm), orientation (deg).
    pub before: (f64, f64),
    /// Noise-free, after.
    pub after_noise_free: (f64, f64),
    /// With noise, after.
    pub after_noisy: (f64, f64),
}

/// The paper's §5.1 averages.
pub const PAPER: PaperFigures = PaperFigures {
    before: (0.515, 0.249),
    after_noise_free: (0.004, 0.001),
    after_noisy: (0.015, 0.019),
};

/// Result of [`pm5_study`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Pm5Study {
    /// Options used.
    pub options: StudyOptions,
    /// Rank of the identification Jacobian (of 44) of the model used.
    pub rank: usize,
    /// The identified vector dW′, by name.
    pub identified: Vec<String>,
    /// Identifiability of both parasitic models (physical first, then the paper's) in the
    /// priority order of [`StudyOptions::sub_loop`], 40 random configurations.
    pub identifiability: Vec<Pm5Identifiability>,
    /// Noise-free trial.
    pub noise_free: Trial,
    /// Trial with noise (same errors and configurations as the noise-free one).
    pub noisy: Trial,
    /// Monte-Carlo over independent draws of errors, configurations and noise.
    pub monte_carlo: MonteCarlo,
    /// The paper's figures.
    pub paper: PaperFigures,
}

fn pose_errors(reached: &Pose, target: &Pose) -> (f64, f64, f64) {
    let e = se3::pose_error(reached, target);
    let za = se3::rotation_matrix(reached).column(2).into_owned();
    let zb = se3::rotation_matrix(target).column(2).into_owned();
    let axis = za.cross(&zb).norm().atan2(za.dot(&zb));
    (se3::lin(&e).norm(), se3::ang(&e).norm().to_degrees(), axis.to_degrees())
}

fn kin(pose: usize) -> impl Fn(crate::KinError) -> CalibError {
    move |source| CalibError::Kinematics { pose, source }
}

/// Evaluate nominal, exact and first-order compensation on `targets` (with nominal commands `qs`).
fn compensate(
    nominal: &ClosedLoop<Pm5>,
    truth: &ClosedLoop<Pm5>,
    calibrated: &ClosedLoop<Pm5>,
    identified: &DVector<f64>,
    targets: &[Pose],
    qs: &[Vec<f64>],
) -> Result<Compensation, CalibError> {
    let mut before = Vec::new();
    let mut exact = Vec::new();
    let mut first = Vec::new();
    for (i, (target, q)) in targets.iter().zip(qs).enumerate() {
        before.push(pose_errors(&truth.forward(q).map_err(kin(i))?, target));
        let qc = calibrated.inverse(target, Some(q)).map_err(kin(i))?;
        exact.push(pose_errors(&truth.forward(&qc).map_err(kin(i))?, target));
        // dQ′ = H′·dW′ at the nominal model, as a pose error (dp, dφ).
        let (pose, jac) = nominal.forward_with_jacobian(q).map_err(kin(i))?;
        let dq = se3::spatial_to_pose_error(&pose.translation.vector) * (jac * identified);
        let adjusted = Pose::from_parts(
            (target.translation.vector - se3::lin(&dq)).into(),
            se3::so3_exp(&(-se3::ang(&dq))) * target.rotation,
        );
        let qa = nominal.inverse(&adjusted, Some(q)).map_err(kin(i))?;
        first.push(pose_errors(&truth.forward(&qa).map_err(kin(i))?, target));
    }
    Ok(Compensation {
        before: CompensatedErrorStats::from_errors(&before),
        exact: CompensatedErrorStats::from_errors(&exact),
        first_order: CompensatedErrorStats::from_errors(&first),
    })
}

/// Random targets in the workspace: nominal tool poses and nominal commands.
fn targets(nominal: &ClosedLoop<Pm5>, rng: &mut ChaCha8Rng, n: usize) -> Result<(Vec<Pose>, Vec<Vec<f64>>), CalibError> {
    let ws = crate::model::closed::ConstraintSystem::workspace(nominal.system());
    let mut poses = Vec::with_capacity(n);
    let mut qs = Vec::with_capacity(n);
    for i in 0..n {
        let x = ws.sample(rng);
        let t = nominal.tool_pose_of(&x);
        let q = nominal.inverse(&t, None).map_err(kin(i))?;
        // The nominal machine reaches the target exactly (its own γ follows from the constraint).
        poses.push(nominal.forward(&q).map_err(kin(i))?);
        qs.push(q);
    }
    Ok((poses, qs))
}

/// Targets of given nominal commands: the nominal tool poses they reach.
fn planned_targets(nominal: &ClosedLoop<Pm5>, qs: &[Vec<f64>]) -> Result<(Vec<Pose>, Vec<Vec<f64>>), CalibError> {
    let poses = qs
        .iter()
        .enumerate()
        .map(|(i, q)| nominal.forward(q).map_err(kin(i)))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((poses, qs.to_vec()))
}

/// One trial with errors, configurations and (optionally) noise drawn from `rng`; returns the
/// noise-free and/or noisy results on the same errors and configurations.
fn trial(opts: &StudyOptions, free: &[usize], seed: u64, noisy_only: bool) -> Result<(Option<Trial>, Trial), CalibError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nominal = Pm5::mechanism(opts.parasitic);
    let delta = simulate::random_errors(&nominal, &mut rng, opts.error_length, opts.error_angle, None);
    let truth = simulate::perturbed(&nominal, &delta);
    let (t_id, q_id) = match &opts.planned {
        Some(qs) => planned_targets(&nominal, qs)?,
        None => targets(&nominal, &mut rng, opts.identification)?,
    };
    let (t_ver, q_ver) = targets(&nominal, &mut rng, opts.verification)?;
    let run = |noise: Option<&Noise>, rng: &mut ChaCha8Rng| -> Result<Trial, CalibError> {
        let data = simulate::measure(&truth, &q_id, ObservationKind::Pose, noise, rng)?;
        let res = identify(
            &nominal,
            &data,
            &Options {
                free: Some(free.to_vec()),
                noise: opts.noise,
                ..Options::default()
            },
        )?;
        Ok(Trial {
            identification_set: compensate(&nominal, &truth, &res.model, &res.delta, &t_id, &q_id)?,
            verification_set: compensate(&nominal, &truth, &res.model, &res.delta, &t_ver, &q_ver)?,
            iterations: res.iterations.len(),
            converged: res.converged,
            sigma0: res.sigma0,
        })
    };
    let clean = if noisy_only { None } else { Some(run(None, &mut rng)?) };
    let noisy = run(Some(&opts.noise), &mut rng)?;
    Ok((clean, noisy))
}

/// Run the §5.1 study: one noise-free and one noisy trial on the same errors and configurations,
/// and a Monte-Carlo of `draws` noisy trials (in parallel, each seeded).
pub fn pm5_study(opts: &StudyOptions) -> Result<Pm5Study, CalibError> {
    if opts.planned.as_ref().is_some_and(|p| p.len() != opts.identification) {
        return Err(CalibError::InvalidOption(format!(
            "{} planned configurations for {} identification configurations",
            opts.planned.as_ref().map_or(0, Vec::len),
            opts.identification
        )));
    }
    if opts.identification == 0 || opts.verification == 0 {
        return Err(CalibError::InvalidOption(
            "the study needs identification and verification configurations".into(),
        ));
    }
    let priority = match opts.sub_loop {
        SubLoopChoice::KeepL2L3 => pm5::natural_priority(),
        SubLoopChoice::KeepL4L5 => pm5::paper_priority(),
    };
    let both = [Parasitic::Physical, Parasitic::NominalGeometry]
        .iter()
        .map(|&p| pm5_identifiability(p, 40, opts.seed, &priority))
        .collect::<Result<Vec<_>, _>>()?;
    let ident = both
        .iter()
        .find(|a| a.parasitic == opts.parasitic)
        .cloned()
        .ok_or_else(|| CalibError::Numerical("identifiability missing".into()))?;
    let free = ident.identifiable_indices.clone();
    let (clean, noisy) = trial(opts, &free, opts.seed, false)?;
    let noise_free = clean.ok_or_else(|| CalibError::Numerical("noise-free trial missing".into()))?;
    let results: Vec<Result<Trial, CalibError>> = (0..opts.draws)
        .into_par_iter()
        .map(|k| trial(opts, &free, opts.seed.wrapping_add(1 + k as u64), true).map(|r| r.1))
        .collect();
    let mut ok = Vec::new();
    let mut failures = Vec::new();
    for (k, r) in results.into_iter().enumerate() {
        match r {
            Ok(t) => ok.push(t),
            Err(e) => failures.push(format!("draw {k}: {e}")),
        }
    }
    let pick = |f: &dyn Fn(&Trial) -> f64| Spread::of(ok.iter().map(f).collect());
    let monte_carlo = MonteCarlo {
        draws: ok.len(),
        failures: failures.clone(),
        verification_position: pick(&|t| t.verification_set.exact.position_mean),
        verification_axis: pick(&|t| t.verification_set.exact.axis_mean),
        verification_rotation: pick(&|t| t.verification_set.exact.rotation_mean),
        identification_position: pick(&|t| t.identification_set.exact.position_mean),
        identification_axis: pick(&|t| t.identification_set.exact.axis_mean),
        identification_rotation: pick(&|t| t.identification_set.exact.rotation_mean),
        first_order_position: pick(&|t| t.verification_set.first_order.position_mean),
        first_order_axis: pick(&|t| t.verification_set.first_order.axis_mean),
    };
    Ok(Pm5Study {
        options: opts.clone(),
        rank: ident.rank,
        identified: ident.identifiable,
        identifiability: both,
        noise_free,
        noisy,
        monte_carlo,
        paper: PAPER,
    })
}

/// Options of [`pm5_plan`]: measurement planning on the 5-DOF preset.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlanOptions {
    /// Halton samples of the prescribed workspace (before filtering).
    pub candidates: usize,
    /// Sample the workspace on the paper-sized grid [`crate::model::presets::pm5::CANDIDATE_GRID`] (304,920 points,
    /// corners included) instead of `candidates` Halton points.
    pub paper_grid: bool,
    /// Seed of the Halton shift.
    pub seed: u64,
    /// Configurations to choose.
    pub n: usize,
    /// Largest actuator-Jacobian condition number of a candidate (see
    /// [`crate::design::actuator_condition`]).
    pub max_condition: f64,
    /// Measurement noise (the row weights of the design; the paper's 20 µm / 0.02° by default).
    pub noise: Noise,
    /// Parasitic-constraint model of the nominal machine.
    pub parasitic: Parasitic,
    /// Which sub-loop parameters dW′ keeps (the design is on exactly the identified columns).
    pub sub_loop: SubLoopChoice,
}

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            candidates: 300_000,
            paper_grid: false,
            seed: 1,
            n: 30,
            max_condition: 100.0,
            noise: Noise::default(),
            parasitic: Parasitic::Physical,
            sub_loop: SubLoopChoice::KeepL2L3,
        }
    }
}

/// One planned set of configurations.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlannedSet {
    /// Selection method.
    pub method: crate::design::SelectionMethod,
    /// Criterion maximised.
    pub criterion: crate::design::Criterion,
    /// Actuator inputs of the chosen configurations (mm).
    pub inputs: Vec<Vec<f64>>,
    /// Indices reached (scaled problem).
    pub indices: crate::design::ObservabilityIndices,
    /// Selection time (s).
    pub seconds: f64,
}

/// Planned configuration sets of the 5-DOF preset: one per `(method, criterion)`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Pm5Plan {
    /// Options used.
    pub options: PlanOptions,
    /// Candidate counts.
    pub generation: crate::design::GenerationReport,
    /// Parameter columns of the design (the identified dW′, indices into the 44).
    pub columns: Vec<usize>,
    /// Candidate generation time (s).
    pub candidate_seconds: f64,
    /// Jacobian-block time (s).
    pub jacobian_seconds: f64,
    /// The planned sets.
    pub sets: Vec<PlannedSet>,
}

/// The free parameters (dW′) of the study for a parasitic model and sub-loop choice.
fn identified_columns(parasitic: Parasitic, sub_loop: SubLoopChoice, seed: u64) -> Result<Vec<usize>, CalibError> {
    let priority = match sub_loop {
        SubLoopChoice::KeepL2L3 => pm5::natural_priority(),
        SubLoopChoice::KeepL4L5 => pm5::paper_priority(),
    };
    Ok(pm5_identifiability(parasitic, 40, seed, &priority)?.identifiable_indices)
}

/// Plan measurement configurations for the 5-DOF preset: Halton (or paper-grid) candidates over
/// its prescribed workspace ([`crate::design::candidates_in_platform_box`], strokes and the condition bound
/// applied), full-pose identification Jacobian blocks on the identified dW′, and one selection
/// per entry of `methods` (each a method and a criterion).
pub fn pm5_plan(opts: &PlanOptions, methods: &[(crate::design::SelectionMethod, crate::design::Criterion)]) -> Result<Pm5Plan, CalibError> {
    use crate::design::{self, CandidateFilter, CandidateJacobians, Sampling, SelectOptions};
    use crate::model::closed::ConstraintSystem;
    use std::time::Instant;
    let mech = Pm5::mechanism(opts.parasitic);
    let t = Instant::now();
    let filter = CandidateFilter {
        input_limits: Some(mech.system().strokes()),
        max_condition: Some(opts.max_condition),
        ..Default::default()
    };
    let (cands, gen) = design::candidates_in_platform_box(
        &mech,
        &mech.system().workspace(),
        &if opts.paper_grid {
            Sampling::Grid {
                counts: crate::model::presets::pm5::CANDIDATE_GRID.to_vec(),
            }
        } else {
            Sampling::Halton {
                n: opts.candidates,
                seed: opts.seed,
            }
        },
        &filter,
        None,
    )?;
    if cands.len() < opts.n {
        return Err(CalibError::InvalidOption(format!(
            "only {} candidates for {} configurations",
            cands.len(),
            opts.n
        )));
    }
    let candidate_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let columns = identified_columns(opts.parasitic, opts.sub_loop, 2024)?;
    let blocks = CandidateJacobians::build(&mech, &cands, ObservationKind::Pose, &opts.noise, &columns, None)?;
    let jacobian_seconds = t.elapsed().as_secs_f64();
    let mut sets = Vec::new();
    for &(method, criterion) in methods {
        let t = Instant::now();
        let sel = design::select(
            &blocks,
            method,
            &SelectOptions {
                n: opts.n,
                criterion,
                ..Default::default()
            },
            &mut |_| {},
        )?;
        sets.push(PlannedSet {
            method,
            criterion,
            inputs: sel.selected.iter().map(|&i| cands[i].q.clone()).collect(),
            indices: sel.indices.clone(),
            seconds: t.elapsed().as_secs_f64(),
        });
    }
    Ok(Pm5Plan {
        options: opts.clone(),
        generation: gen.report,
        columns,
        candidate_seconds,
        jacobian_seconds,
        sets,
    })
}

/// Options of [`pm5_design_study`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DesignStudyOptions {
    /// Seed: draw `k` uses `seed + k`.
    pub seed: u64,
    /// Monte-Carlo draws of geometric errors and noise.
    pub draws: usize,
    /// Verification configurations per draw (random, fresh per draw).
    pub verification: usize,
    /// Half-width of the uniform length errors (mm).
    pub error_length: f64,
    /// Half-width of the uniform angle errors (rad).
    pub error_angle: f64,
}

impl Default for DesignStudyOptions {
    fn default() -> Self {
        DesignStudyOptions {
            seed: 7,
            draws: 200,
            verification: 50,
            error_length: 0.2,
            error_angle: 0.02f64.to_radians(),
        }
    }
}

/// Verification errors of one identification set over the Monte-Carlo draws.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DesignRow {
    /// `"random"` or `"<method> <criterion>"`.
    pub set: String,
    /// O2 of the set's scaled Jacobian on the nominal model (mean over draws for random sets).
    pub o2: f64,
    /// Per-draw mean verification position error after exact compensation (mm).
    pub position: Spread,
    /// Per-draw mean verification tool-axis error after exact compensation (deg).
    pub axis: Spread,
    /// Per-draw maximum verification position error (mm).
    pub position_max: Spread,
    /// Fraction of the draws (where both succeeded) in which this set's mean verification
    /// position error is below the random set's (same errors, same verification
    /// configurations: a paired comparison); 0.5 for the random row itself.
    pub beats_random: f64,
    /// Draws whose identification or compensation failed.
    pub failures: usize,
}

/// Result of [`pm5_design_study`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DesignStudy {
    /// Options used.
    pub options: DesignStudyOptions,
    /// The plan the optimised sets come from.
    pub plan: Pm5Plan,
    /// One row per optimised set, then the random sets (fresh per draw).
    pub rows: Vec<DesignRow>,
}

/// Does measurement planning matter? For each draw: random geometric errors (uniform
/// `±error_length` / `±error_angle` on all 44 parameters), the truth, `verification` fresh random
/// verification configurations, and one identification per set — each optimised set of `plan`
/// and a fresh random set of the same size — measured on the truth with the plan's noise
/// (full pose), identified with the iterated Gauss–Newton on dW′ (weighted by the noise), then
/// exact compensation (calibrated inverse kinematics) evaluated on the verification
/// configurations. In parallel over draws; every draw is seeded, and a set's noise comes from
/// its own seeded stream, so adding a set does not change the others' numbers.
pub fn pm5_design_study(plan: Pm5Plan, opts: &DesignStudyOptions) -> Result<DesignStudy, CalibError> {
    let po = &plan.options;
    let n = po.n;
    let free = plan.columns.clone();
    if opts.verification == 0 || opts.draws == 0 {
        return Err(CalibError::InvalidOption(
            "the design study needs draws and verification configurations".into(),
        ));
    }
    let nominal = Pm5::mechanism(po.parasitic);
    let o2_of = |qs: &[Vec<f64>]| -> f64 {
        let lin = qs
            .iter()
            .map(|q| {
                nominal.forward_with_jacobian(q).map(|(pose, jac)| {
                    let obs = crate::measure::Observation::Pose(pose);
                    let a = crate::measure::residual_jacobian(&obs, &pose, &jac);
                    let w = crate::measure::row_weights(&obs, &po.noise);
                    (a, w)
                })
            })
            .collect::<Result<Vec<_>, _>>();
        let Ok(blocks) = lin else { return f64::NAN };
        let mut m = nalgebra::DMatrix::zeros(6 * blocks.len(), free.len());
        for (b, (a, w)) in blocks.iter().enumerate() {
            for r in 0..6 {
                for (j, &c) in free.iter().enumerate() {
                    m[(6 * b + r, j)] = a[(r, c)] * w[r];
                }
            }
        }
        // Column scaling by the column norms of this set (unit-free comparison of sets).
        for mut col in m.column_iter_mut() {
            let s = col.norm();
            if s > 0.0 {
                col /= s;
            }
        }
        let sv = crate::identifiability::singular_values(&m);
        sv.last().copied().unwrap_or(0.0) / sv.first().copied().unwrap_or(1.0)
    };
    let nsets = plan.sets.len();
    type DrawResult = Vec<Result<(f64, f64, f64, f64), CalibError>>;
    let per_draw: Vec<DrawResult> = (0..opts.draws)
        .into_par_iter()
        .map(|k| {
            let draw_seed = opts.seed.wrapping_add(k as u64);
            let mut rng = ChaCha8Rng::seed_from_u64(draw_seed);
            let delta = simulate::random_errors(&nominal, &mut rng, opts.error_length, opts.error_angle, None);
            let truth = simulate::perturbed(&nominal, &delta);
            let ver = targets(&nominal, &mut rng, opts.verification);
            let random = targets(&nominal, &mut rng, n);
            let (Ok((t_ver, q_ver)), Ok((_, q_rand))) = (ver, random) else {
                return vec![Err(CalibError::Numerical("random targets failed".into())); nsets + 1];
            };
            let sets: Vec<&[Vec<f64>]> = plan
                .sets
                .iter()
                .map(|s| s.inputs.as_slice())
                .chain(std::iter::once(q_rand.as_slice()))
                .collect();
            sets.iter()
                .enumerate()
                .map(|(j, qs)| {
                    let mut noise_rng = ChaCha8Rng::seed_from_u64(draw_seed.wrapping_mul(1_000_003).wrapping_add(j as u64));
                    let data = simulate::measure(&truth, qs, ObservationKind::Pose, Some(&po.noise), &mut noise_rng)?;
                    let res = identify(
                        &nominal,
                        &data,
                        &Options {
                            free: Some(free.clone()),
                            noise: po.noise,
                            ..Options::default()
                        },
                    )?;
                    let mut pos = Vec::with_capacity(t_ver.len());
                    for (i, (target, q)) in t_ver.iter().zip(&q_ver).enumerate() {
                        let qc = res.model.inverse(target, Some(q)).map_err(kin(i))?;
                        pos.push(pose_errors(&truth.forward(&qc).map_err(kin(i))?, target));
                    }
                    let st = CompensatedErrorStats::from_errors(&pos);
                    let o2 = if j == nsets { o2_of(qs) } else { f64::NAN };
                    Ok((st.position_mean, st.axis_mean, st.position_max, o2))
                })
                .collect()
        })
        .collect();
    let mut rows = Vec::new();
    for j in 0..=nsets {
        let ok: Vec<(f64, f64, f64, f64)> = per_draw.iter().filter_map(|d| d[j].as_ref().ok().copied()).collect();
        let failures = per_draw.len() - ok.len();
        let (set, o2) = if j < nsets {
            let s = &plan.sets[j];
            (format!("{:?} {}", s.method, s.criterion), o2_of(&s.inputs))
        } else {
            let v: Vec<f64> = ok.iter().map(|r| r.3).filter(|v| v.is_finite()).collect();
            ("random".to_string(), v.iter().sum::<f64>() / v.len().max(1) as f64)
        };
        let paired: Vec<bool> = per_draw
            .iter()
            .filter_map(|d| match (&d[j], &d[nsets]) {
                (Ok(a), Ok(r)) => Some(a.0 < r.0),
                _ => None,
            })
            .collect();
        let beats_random = if j == nsets {
            0.5
        } else {
            paired.iter().filter(|&&b| b).count() as f64 / paired.len().max(1) as f64
        };
        rows.push(DesignRow {
            set,
            o2,
            beats_random,
            position: Spread::of(ok.iter().map(|r| r.0).collect()),
            axis: Spread::of(ok.iter().map(|r| r.1).collect()),
            position_max: Spread::of(ok.iter().map(|r| r.2).collect()),
            failures,
        });
    }
    Ok(DesignStudy {
        options: opts.clone(),
        plan,
        rows,
    })
}

/// Identifiability of the 5-DOF machine (§3.2).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Pm5Identifiability {
    /// Parasitic-constraint mode analysed.
    pub parasitic: Parasitic,
    /// Configurations used.
    pub configurations: usize,
    /// Rank of the identification Jacobian (of 44).
    pub rank: usize,
    /// Redundant parameters, by name, for the given priority order.
    pub redundant: Vec<String>,
    /// The identifiable vector dW′, by name.
    pub identifiable: Vec<String>,
    /// Indices of dW′ in the 44-parameter vector.
    pub identifiable_indices: Vec<usize>,
    /// Smallest kept singular value of the column-scaled Jacobian relative to the largest.
    pub weakest: f64,
}

/// Rank, redundant parameters and dW′ over `n` random workspace configurations (seeded), with
/// full-pose measurements weighted by the paper's noise (20 µm, 0.02°).
pub fn pm5_identifiability(
    parasitic: Parasitic,
    n: usize,
    seed: u64,
    priority: &[usize],
) -> Result<Pm5Identifiability, crate::error::CalibError> {
    use rand::SeedableRng;
    let m = pm5::Pm5::mechanism(parasitic);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let qs = m
        .random_configurations(&mut rng, n)
        .map_err(|source| crate::error::CalibError::Kinematics { pose: 0, source })?;
    let a = crate::identify::identifiability_at(
        &m,
        &qs,
        priority,
        &crate::measure::Noise::default(),
        crate::identifiability::DEFAULT_RANK_TOLERANCE,
    )?;
    let smax = a.singular_values.first().copied().unwrap_or(1.0);
    let weakest = a.singular_values.get(a.rank.saturating_sub(1)).copied().unwrap_or(0.0) / smax;
    Ok(Pm5Identifiability {
        parasitic,
        configurations: n,
        rank: a.rank,
        redundant: a.redundant.iter().map(|&i| pm5::PARAM_NAMES[i].to_string()).collect(),
        identifiable: a.identifiable.iter().map(|&i| pm5::PARAM_NAMES[i].to_string()).collect(),
        identifiable_indices: a.identifiable.clone(),
        weakest,
    })
}
