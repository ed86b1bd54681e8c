//! Parameter identification: one-shot linear least squares (eq. (32) of both seeds), recursive
//! least squares (3T1R paper §5), and the iterated nonlinear solver kinecal uses by default
//! (Gauss–Newton with a Levenberg–Marquardt fallback) on the identifiable subset.
//!
//! # Weighting
//! Every residual row is divided by the standard deviation of its measurement ([`Noise`]): mm rows
//! by `σ_p` (mm), rad rows by `σ_θ` (rad). The weighted problem is dimensionless and its solution
//! is the maximum-likelihood estimate under independent Gaussian noise. With
//! [`Options::reweight`] the two standard deviations are re-estimated from the residuals
//! (variance-component estimation), which is what real data needs when the unmodelled error, not
//! the tracker, dominates.
//!
//! # Uncertainty
//! Parameter standard deviations are `sqrt(diag(σ̂₀²·(AᵀA)⁻¹))` on the identifiable subset, with
//! `A` the weighted Jacobian at the solution and `σ̂₀² = |r|²/(m − k)` the a-posteriori variance of
//! unit weight (the textbook `σ²(JᵀJ)⁻¹`).
//!
//! # Scale
//! Gauss–Newton never holds the rows × p weighted Jacobian: each linearisation is a residual pass
//! (forward kinematics only; a rejected step costs nothing more) and a pass that folds the
//! Jacobian pose block by pose block into the normal equations, in parallel over fixed chunks of
//! poses (same digits on any thread count). The rank and the named redundant parameters come
//! from a Householder factor of the same rows, computed once (on an evenly spread subset of
//! [`ANALYSIS_POSES`] poses for larger sets). Memory grows with p², not with the poses; a million
//! IRB 120 poses identify in about 11 s in-process.
//!
//! # A start that sees less than the machine
//! The rank is decided at the start. Where the start is a special geometry (a platform that only
//! translates, axes exactly parallel) and the converged fit is not exact, the rank is analysed
//! again where the fit converged, and the fit continued on the larger set when that explains the
//! data a thousand times better (`identify/refit.rs`; docs/parallel-machines.md, a platform
//! that only translates).
use crate::error::{CalibError, KinError};
use crate::identifiability::{self, Identifiability};
use crate::measure::{self, Measurement, Noise};
use crate::model::Mechanism;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

mod drawn;
mod joints;
mod linearization;
mod loss;
mod plain;
mod recursive;
mod reduced;
mod refit;
mod solve;
mod weak;
pub use linearization::{linearize, Linearization};
use loss::reestimate_noise;
pub use loss::{apply_loss, Loss};
pub(crate) use loss::{huber_threshold, loss_weights, pose_rms};
pub use plain::fit_residuals;
pub use recursive::rls_solve;
use reduced::{Form, System};
use solve::{covariance, solve_subset};
pub use weak::{weakly_seen, WeakHold, WEAK_SEEN};

/// Poses the rank analysis of [`identify`]'s Gauss–Newton runs on at most: an orthogonal
/// factorisation costs rows × p², so larger sets are analysed on an evenly spread subset (the
/// steps and the covariance always use every pose).
pub const ANALYSIS_POSES: usize = 10_000;

/// Longest multiple of a Gauss–Newton step the line search along it tries.
const MAX_EXTENSION: f64 = 10.0;

/// Identification algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
pub enum Method {
    /// Iterated Gauss–Newton with Levenberg–Marquardt damping when a step does not decrease the
    /// cost; converges to the nonlinear least-squares solution (the default).
    #[default]
    GaussNewton,
    /// One linearisation at the starting model, batch least squares, one update (the seeds' method).
    Linear,
    /// One linearisation, solved by recursive least squares pose after pose (3T1R paper §5).
    Recursive,
}

/// Options of [`identify`].
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Algorithm.
    pub method: Method,
    /// Measurement noise (weights).
    pub noise: Noise,
    /// Re-estimate the position / orientation standard deviations from the residuals.
    pub reweight: bool,
    /// Parameters allowed to change, in priority order (default: all, in model order).
    pub free: Option<Vec<usize>>,
    /// Maximum iterations of the nonlinear solver (default 300: a safety net — most fits stop
    /// within ten, but Gauss–Newton creeps along weakly determined, curved directions at noise
    /// level, and 1000 noisy pm5 calibrations of 30 poses needed up to 290).
    pub max_iterations: usize,
    /// Convergence: stop when the predicted change of the weighted residual is below
    /// `step_tolerance·(1 + |r|)`.
    pub step_tolerance: f64,
    /// Relative rank tolerance for the identifiable subset.
    pub rank_tolerance: f64,
    /// Loss on each pose's residual: least squares, or Huber against gross blunders.
    pub loss: Loss,
    /// Stop as soon as the fit's predictions come this close to another solution's (Gauss–Newton
    /// only): a start that enters the basin of a known minimum will end there, so it is not
    /// iterated to the end (what [`crate::calibrate`]'s extra starts test). Counted as converged.
    pub agree_with: Option<Agreement>,
    /// Hold as drawn the parameters the data see too weakly to fix ([`weakly_seen`]), decided at
    /// the start and again where the fit converged (Gauss–Newton only). `None`: every parameter
    /// of full rank is fitted.
    pub weak: Option<WeakHold>,
    /// Parameters that, with the others, only place the machine where no instrument of the data
    /// sees it (a gauge: seats, spheres or a ballbar absorb the base's pose): held as drawn, and
    /// listed in [`Identifiability::gauge`]. Freed again where the fit with them held explains
    /// the data worse than noise can (they were not a pure gauge at this geometry).
    pub gauge: Vec<usize>,
}

/// How [`gauss_newton`] steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Steps<'a> {
    /// Minimum-norm over every free parameter with an effect (those held as seen too weakly
    /// excepted), truncated at the identified rank: robust along a path on which the set of
    /// identifiable parameters changes.
    MinimumNorm,
    /// On this identifiable subset only (the parameters the analysis at the start would not
    /// all choose, where the set is kept from an earlier geometry): the others stay where they
    /// are.
    Subset(&'a [usize]),
}

/// Predictions of a known solution, for [`Options::agree_with`].
#[derive(Debug, Clone, PartialEq)]
pub struct Agreement {
    /// The point the known solution predicts at each measurement ([`measure::compared_point`]:
    /// the tool position, mm, measurement frame; a distance's length).
    pub positions: Vec<nalgebra::Vector3<f64>>,
    /// Largest distance (mm) at which the fit agrees.
    pub tolerance_mm: f64,
    /// The known solution's identifiability analysis on the same poses and free parameters,
    /// reused for the rank and the redundant parameters (the start skips its own orthogonal
    /// factor; the rank is structural, the same at both geometries).
    pub identifiability: Option<Identifiability>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            method: Method::GaussNewton,
            noise: Noise::default(),
            reweight: false,
            free: None,
            max_iterations: 300,
            step_tolerance: 1e-12,
            rank_tolerance: identifiability::DEFAULT_RANK_TOLERANCE,
            loss: Loss::Squares,
            agree_with: None,
            weak: None,
            gauge: Vec::new(),
        }
    }
}

/// One iteration of the solver.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Iteration {
    /// Weighted cost `½|r|²` before the step.
    pub cost: f64,
    /// Norm of the weighted predicted change `|A·δ|`.
    pub step: f64,
    /// Levenberg–Marquardt damping used (0 for a pure Gauss–Newton step).
    pub damping: f64,
}

/// Result of an identification.
#[derive(Debug, Clone)]
pub struct Identification<M> {
    /// The calibrated model.
    pub model: M,
    /// Identifiability at the starting model on the free parameters.
    pub identifiability: Identifiability,
    /// Sum of all increments applied, per parameter (local coordinates; for additive models the
    /// identified error itself).
    pub delta: DVector<f64>,
    /// Standard deviation per parameter, from [`Identification::covariance`] (0 for parameters
    /// without effect or not free).
    pub std_dev: DVector<f64>,
    /// Covariance of the identified change (model units: mm, rad), `σ̂₀²·(AᵀA)⁻¹` on the weighted
    /// Jacobian at the solution, on the identifiable subset (the parameters the fit moved). Zero
    /// outside it: redundant parameters and those held as seen too weakly stay as drawn.
    pub covariance: DMatrix<f64>,
    /// Solver history.
    pub iterations: Vec<Iteration>,
    /// Whether the convergence test was met.
    pub converged: bool,
    /// Why the fit never left its start, when every step it tried (down to the shortest) put a
    /// pose where the model cannot be evaluated: that pose's kinematic error. The fit then
    /// counts as not converged.
    pub stalled: Option<String>,
    /// A-posteriori standard deviation of unit weight `σ̂₀` (1 when the noise model is right).
    pub sigma0: f64,
    /// Noise model used for the final weights (after re-estimation when asked).
    pub noise: Noise,
    /// Weight of each pose under the loss (1: full weight; below 1: a pose the robust loss
    /// treated as a blunder).
    pub pose_weights: Vec<f64>,
    /// The information matrix `AᵀA` (p × p) of the noise- and loss-weighted Jacobian the
    /// covariance was taken from (the last linearisation): what the report's analysis of
    /// absorbed parameters needs, without a new pass over the poses.
    pub information: DMatrix<f64>,
}

/// The predicted pose and the spatial identification Jacobian of measurement `m`, number `i`,
/// the forward kinematics started from `near` when given: a kinematic failure or a non-finite
/// Jacobian is [`CalibError::Kinematics`].
pub(crate) fn spatial_jacobian_near<M: Mechanism + ?Sized>(
    model: &M,
    i: usize,
    m: &Measurement,
    near: Option<&crate::se3::Pose>,
) -> Result<(crate::se3::Pose, nalgebra::Matrix6xX<f64>), CalibError> {
    let (pose, jac) = match near {
        Some(p) => model.forward_with_jacobian_near(&m.q, p),
        None => model.forward_with_jacobian(&m.q),
    }
    .map_err(|source| CalibError::Kinematics { pose: i, source })?;
    check_jacobian(i, &jac)?;
    Ok((pose, jac))
}

/// A non-finite identification Jacobian at pose `i` is [`CalibError::Kinematics`].
pub(crate) fn check_jacobian(i: usize, jac: &nalgebra::Matrix6xX<f64>) -> Result<(), CalibError> {
    if jac.iter().any(|v| !v.is_finite()) {
        let source = KinError::NonFinite("the identification Jacobian (check the model's geometry for extreme values)".into());
        return Err(CalibError::Kinematics { pose: i, source });
    }
    Ok(())
}

/// Identify the free parameters of `initial` from `data`. Those an overconstrained mechanism
/// cannot take alone ([`Mechanism::assembly_breaking`]) stay at their drawn values.
///
/// Errors: kinematics failing at a pose, fewer residual rows than identifiable parameters,
/// nothing free or identifiable, a numerical failure.
pub fn identify<M: Mechanism + Clone>(initial: &M, data: &[Measurement], opts: &Options) -> Result<Identification<M>, CalibError> {
    let free = free_columns(initial, opts)?;
    match opts.method {
        Method::GaussNewton => drawn::fitted_with_gauge(initial, data, opts, &free),
        Method::Linear | Method::Recursive => one_step(initial, data, opts, &free),
    }
}

/// The free parameters of `opts` (all by default) but those `initial` cannot take alone; errors:
/// nothing free, a free index beyond the parameters, a noise that is not positive.
fn free_columns<M: Mechanism>(initial: &M, opts: &Options) -> Result<Vec<usize>, CalibError> {
    let p = initial.n_params();
    let held = initial.assembly_breaking();
    let free: Vec<usize> = opts
        .free
        .clone()
        .unwrap_or_else(|| (0..p).collect())
        .into_iter()
        .filter(|c| !held.contains(c))
        .collect();
    if free.is_empty() {
        return Err(CalibError::NothingToIdentify("no free parameters".into()));
    }
    if let Some(&bad) = free.iter().find(|&&c| c >= p) {
        return Err(CalibError::InvalidOption(format!("free parameter index {bad} ≥ {p} parameters")));
    }
    if !(opts.noise.position > 0.0 && opts.noise.orientation > 0.0) {
        return Err(CalibError::InvalidOption("noise standard deviations must be positive".into()));
    }
    Ok(free)
}

/// The identifiable columns of `ident` and the share of residual degrees of freedom, or why
/// there are none.
fn identifiable_subset(ident: &Identifiability, rows: usize, poses: usize) -> Result<(Vec<usize>, f64), CalibError> {
    let cols = ident.identifiable.clone();
    if cols.is_empty() {
        return Err(CalibError::NothingToIdentify(
            "every free parameter is unidentifiable from these measurements".into(),
        ));
    }
    if rows <= cols.len() {
        let per_pose = rows.max(1).checked_div(poses).unwrap_or(6);
        let needed = cols.len() / per_pose.max(1) + 1;
        return Err(CalibError::TooFewMeasurements {
            poses,
            rows,
            params: cols.len(),
            needed,
        });
    }
    let dof_ratio = (rows - cols.len()) as f64 / rows as f64;
    Ok((cols, dof_ratio))
}

/// The one-linearisation methods (batch least squares, recursive least squares) on the
/// identifiable subset, on the full weighted Jacobian.
fn one_step<M: Mechanism + Clone>(
    initial: &M,
    data: &[Measurement],
    opts: &Options,
    free: &[usize],
) -> Result<Identification<M>, CalibError> {
    let p = initial.n_params();
    let mut model = initial.clone();
    let noise = opts.noise;
    let mut lin = linearize(&model, data, &noise)?;
    let ident = identifiability::analyze(&lin.jacobian, free, opts.rank_tolerance);
    let rows = lin.residual.len();
    let (cols, _) = identifiable_subset(&ident, rows, data.len())?;
    let (_, pose_weights) = apply_loss(&mut lin, opts.loss);
    let step = if opts.method == Method::Linear {
        solve_subset(&lin.jacobian, &lin.residual, &cols, 0.0, None)?
    } else {
        rls_solve(&lin, &cols)?
    };
    let pred = (&lin.jacobian * &step).norm();
    let iterations = vec![Iteration {
        cost: 0.5 * lin.residual.norm_squared(),
        step: pred,
        damping: 0.0,
    }];
    model.retract(&step);
    let lin = linearize(&model, data, &noise)?;
    let sigma0 = (lin.residual.norm_squared() / (rows - cols.len()) as f64).sqrt();
    let covariance = covariance(&lin.jacobian, &cols, None) * (sigma0 * sigma0);
    let std_dev = DVector::from_iterator(p, (0..p).map(|i| covariance[(i, i)].max(0.0).sqrt()));
    let information = lin.jacobian.tr_mul(&lin.jacobian);
    Ok(Identification {
        model,
        identifiability: ident,
        delta: step,
        std_dev,
        covariance,
        iterations,
        converged: true,
        stalled: None,
        sigma0,
        noise,
        pose_weights,
        information,
    })
}

/// Iterated Gauss–Newton with Levenberg–Marquardt damping, on the reduced problem
/// ([`reduced`]: the triangular factor of the weighted Jacobian, never the Jacobian itself).
/// Steps are taken on the identifiable subset in priority order: a redundant parameter stays
/// as drawn and the parameters before it in priority (frames, tool, artifact points) take up
/// what they share with it. With [`Options::weak`] the parameters seen too weakly are held too:
/// `held` when given (decided where an earlier fit converged), else decided here at the start.
fn gauss_newton<M: Mechanism + Clone>(
    initial: &M,
    data: &[Measurement],
    opts: &Options,
    free: &[usize],
    held: Option<&[usize]>,
    steps: Steps<'_>,
) -> Result<Identification<M>, CalibError> {
    let p = initial.n_params();
    let mut model = initial.clone();
    let mut noise = opts.noise;
    let mut ev = reduced::evaluate(&model, data, &noise, opts.loss)?;
    // The orthogonal factor once, for the rank and the named redundant parameters (on an evenly
    // spread subset of ANALYSIS_POSES poses when there are more); then the normal equations,
    // whose eigenvalues on the identifiable directions are far above round-off.
    let stride = data.len().div_ceil(ANALYSIS_POSES).max(1);
    let known = opts.agree_with.as_ref().and_then(|a| a.identifiability.clone());
    let is_known = known.is_some();
    let (mut ident, mut system) = if let Some(ident) = known {
        (ident, reduced::factor(&model, data, &noise, &ev, Form::Gram)?)
    } else if stride == 1 {
        let system = reduced::factor(&model, data, &noise, &ev, Form::Triangular)?;
        let System::Triangular { r, .. } = &system else {
            unreachable!("a triangular factor was asked for")
        };
        (identifiability::analyze(r, free, opts.rank_tolerance), system)
    } else {
        let ident = sampled_analysis(&model, data, &noise, opts, free)?;
        (ident, reduced::factor(&model, data, &noise, &ev, Form::Gram)?)
    };
    if let (Some(hold), false) = (&opts.weak, is_known) {
        let weak: Vec<usize> = match held {
            Some(h) => h.iter().copied().filter(|c| ident.identifiable.contains(c)).collect(),
            None => weakly_seen(&system.gram(), &ident.identifiable, hold, 1.0),
        };
        if !weak.is_empty() {
            ident.identifiable.retain(|c| !weak.contains(c));
            ident.condition = weak::condition(&system.gram(), &ident.identifiable);
        }
        ident.weak = weak;
    }
    if let Steps::Subset(set) = steps {
        ident.weak = held.unwrap_or(&[]).iter().copied().filter(|c| free.contains(c)).collect();
        ident.redundant = (free.iter().copied())
            .filter(|c| !set.contains(c) && !ident.weak.contains(c) && !ident.no_effect.contains(c))
            .chain(ident.no_effect.iter().copied())
            .collect();
        ident.identifiable = set.to_vec();
        ident.condition = weak::condition(&system.gram(), set);
    }
    let rows = ev.residual.len();
    let (cols, dof_ratio) = identifiable_subset(&ident, rows, data.len())?;
    // Minimum-norm steps move every parameter with an effect but those held as seen too weakly,
    // on as many directions as are identified.
    let (solved, rank) = match steps {
        Steps::MinimumNorm => (
            (free.iter().copied())
                .filter(|c| !ident.no_effect.contains(c) && !ident.weak.contains(c))
                .collect::<Vec<usize>>(),
            cols.len(),
        ),
        Steps::Subset(_) => (cols.clone(), cols.len()),
    };
    let mut delta_total = DVector::zeros(p);
    let mut iterations = Vec::new();
    let mut converged = false;
    // The first kinematic failure of a trial step, whether any step was taken, and whether the
    // first step was already below the convergence tolerance (a start at the minimum).
    let mut trial_failure: Option<String> = None;
    let mut moved = false;
    let mut first_tiny = None;
    let mut damping = 0.0;
    let mut growth = 2.0;
    let mut stalls = 0;
    let mut previous_pred = None;
    for _ in 0..opts.max_iterations {
        if opts.reweight {
            noise = reestimate_noise(&ev.residual, &ev.angular_rows, &ev.joint_rows, &noise, dof_ratio);
            ev = reduced::evaluate(&model, data, &noise, opts.loss)?;
            system = reduced::factor(&model, data, &noise, &ev, Form::Gram)?;
        }
        let cost = ev.cost;
        let step = system.solve(&solved, damping, Some(rank))?;
        let pred = system.predicted(&step);
        let mut trial = model.clone();
        trial.retract(&step);
        // A step into geometry where a pose no longer assembles (closed loops) is a step too
        // long: rejected like one that raises the cost.
        let trial_ev = match reduced::evaluate(&trial, data, &noise, opts.loss) {
            Ok(e) => Some(e),
            Err(e @ CalibError::Kinematics { .. }) => {
                trial_failure.get_or_insert_with(|| e.to_string());
                None
            }
            Err(e) => return Err(e),
        };
        let mut trial_cost = trial_ev.as_ref().map_or(f64::INFINITY, |e| e.cost);
        let mut trial_ev = trial_ev;
        let mut step = step;
        // Where the cost curves more than the linear model says (a weakly determined direction
        // with some curvature: the step overshoots), the minimum of the parabola through the
        // cost, its slope and the trial cost along the step is tried too; likewise where it
        // curves less (residuals at noise level bend weakly determined directions the other
        // way: Gauss–Newton then creeps, each step a fraction of the way), up to ten steps.
        let slope = -(system.predicted_reduction(&step) + 0.5 * pred * pred);
        let curvature = trial_cost - cost - slope;
        if trial_cost.is_finite() && slope < 0.0 && curvature > 0.0 {
            let alpha = (-slope / (2.0 * curvature)).clamp(0.1, MAX_EXTENSION);
            if !(0.9..=1.1).contains(&alpha) {
                let shorter = &step * alpha;
                let mut t2 = model.clone();
                t2.retract(&shorter);
                if let Ok(e2) = reduced::evaluate(&t2, data, &noise, opts.loss) {
                    if e2.cost < trial_cost {
                        trial_cost = e2.cost;
                        trial_ev = Some(e2);
                        trial = t2;
                        step = shorter;
                    }
                }
            }
        }
        iterations.push(Iteration { cost, step: pred, damping });
        let r_norm = ev.residual.norm();
        let tiny = pred <= opts.step_tolerance * (1.0 + r_norm);
        first_tiny.get_or_insert(tiny);
        // At round-off level the cost no longer decreases; a step that small is converged.
        let negligible = pred <= 1e-6 * (1.0 + r_norm) && trial_cost >= cost * (1.0 - 1e-12);
        // Levenberg–Marquardt damping by the gain ratio ρ = actual / predicted reduction
        // (Nielsen's rule): kept where the linear model predicts poorly, so that a weakly
        // determined, curved direction does not make full steps fail again and again.
        let predicted_reduction = system.predicted_reduction(&step);
        // Converged: a step below the tolerance, or a negligible step that did not lower the
        // cost (trying it again would change nothing), came second in a row, or is a thousand
        // times shorter than the one before (the iteration contracts so fast that what is left,
        // about the next step, is far below round-off of the parameters).
        let accepted_now = trial_ev.is_some() && trial_cost <= cost;
        let contracting = previous_pred.is_some_and(|p: f64| pred <= 1e-3 * p);
        let agrees = accepted_now
            && opts.agree_with.as_ref().is_some_and(|a| {
                let poses = &trial_ev.as_ref().expect("an accepted step was evaluated").poses;
                a.positions.len() == poses.len()
                    && poses
                        .iter()
                        .zip(&a.positions)
                        .zip(data)
                        .all(|((t, p), m)| (measure::compared_point(&m.obs, t) - p).norm() <= a.tolerance_mm)
            });
        let ends = agrees || tiny || (negligible && (stalls >= 1 || !accepted_now || contracting));
        previous_pred = Some(pred);
        if let Some(accepted) = trial_ev.filter(|_| trial_cost <= cost) {
            let rho = if predicted_reduction > 0.0 {
                (cost - trial_cost) / predicted_reduction
            } else {
                1.0
            };
            model = trial;
            ev = accepted;
            moved = true;
            // A fit that ends with this step keeps the Jacobian it moved along for the
            // covariance (it differs from the new one by the step, at round-off).
            if !ends {
                system = reduced::factor(&model, data, &noise, &ev, Form::Gram)?;
            }
            delta_total += step;
            damping *= (1.0f64 / 3.0).max(1.0 - (2.0 * rho - 1.0).powi(3));
            if damping < 1e-9 {
                damping = 0.0;
            }
            growth = 2.0;
        } else if !negligible {
            damping = if damping == 0.0 { 1e-3 } else { damping * growth };
            growth *= 2.0;
        }
        if ends {
            converged = true;
            break;
        }
        if negligible {
            stalls += 1;
        } else {
            stalls = 0;
        }
        if damping > 1e12 {
            break;
        }
    }
    if opts.reweight {
        noise = reestimate_noise(&ev.residual, &ev.angular_rows, &ev.joint_rows, &noise, dof_ratio);
        ev = reduced::evaluate(&model, data, &noise, opts.loss)?;
        system = reduced::factor(&model, data, &noise, &ev, Form::Gram)?;
    }
    // Stuck at the start: every step tried failed to evaluate (not a start already at the
    // minimum, whose first step passed the convergence test).
    let stalled = trial_failure.filter(|_| !moved && first_tiny == Some(false));
    if stalled.is_some() {
        converged = false;
    }
    let sigma0 = (ev.residual.norm_squared() / (rows - cols.len()) as f64).sqrt();
    // The covariance of the solution the steps took.
    let covariance = system.covariance(&solved, Some(rank)) * (sigma0 * sigma0);
    let std_dev = DVector::from_iterator(p, (0..p).map(|i| covariance[(i, i)].max(0.0).sqrt()));
    let information = system.gram();
    Ok(Identification {
        model,
        identifiability: ident,
        delta: delta_total,
        std_dev,
        covariance,
        iterations,
        converged,
        stalled,
        sigma0,
        noise,
        pose_weights: ev.pose_weights,
        information,
    })
}

/// The information (Gram) matrix `AᵀA` (p × p) of the noise-weighted Jacobian of `model` at
/// `data`, accumulated pose block by pose block: what [`linearize`] followed by `AᵀA` gives,
/// without holding the rows × p Jacobian (memory grows with the parameters, not the poses).
pub fn information<M: Mechanism + ?Sized>(model: &M, data: &[Measurement], noise: &Noise) -> Result<DMatrix<f64>, CalibError> {
    let ev = reduced::evaluate(model, data, noise, Loss::Squares)?;
    Ok(reduced::factor(model, data, noise, &ev, Form::Gram)?.gram())
}

/// The identifiability analysis of `model` on `data` (an orthogonal factor of the weighted
/// Jacobian), on an evenly spread subset of [`ANALYSIS_POSES`] poses when there are more.
fn sampled_analysis<M: Mechanism + ?Sized>(
    model: &M,
    data: &[Measurement],
    noise: &Noise,
    opts: &Options,
    free: &[usize],
) -> Result<Identifiability, CalibError> {
    let stride = data.len().div_ceil(ANALYSIS_POSES).max(1);
    let sample: Vec<Measurement>;
    let rows = if stride == 1 {
        data
    } else {
        sample = data.iter().step_by(stride).cloned().collect();
        &sample
    };
    let ev = reduced::evaluate(model, rows, noise, opts.loss)?;
    match reduced::factor(model, rows, noise, &ev, Form::Triangular)? {
        System::Triangular { r, .. } => Ok(identifiability::analyze(&r, free, opts.rank_tolerance)),
        System::Gram { .. } => unreachable!("a triangular factor was asked for"),
    }
}

/// Identifiability of a mechanism's parameters from full-pose measurements at `inputs`: the
/// noise-weighted stacked identification Jacobian analysed in `priority` order
/// ([`crate::identifiability::analyze`]).
pub fn identifiability_at<M: Mechanism + ?Sized>(
    mechanism: &M,
    inputs: &[Vec<f64>],
    priority: &[usize],
    noise: &crate::measure::Noise,
    tolerance: f64,
) -> Result<crate::identifiability::Identifiability, crate::error::CalibError> {
    use crate::measure::{Measurement, Observation};
    let data = inputs
        .iter()
        .enumerate()
        .map(|(i, q)| {
            let (t, joints) = mechanism
                .forward_and_observed(q)
                .map_err(|source| crate::error::CalibError::Kinematics { pose: i, source })?;
            Ok(Measurement {
                joints,
                q: q.clone(),
                obs: Observation::Pose(t),
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let lin = linearize(mechanism, &data, noise)?;
    Ok(crate::identifiability::analyze(&lin.jacobian, priority, tolerance))
}
