//! [`update()`]: a calibration brought up to date from a few new poses.
use super::check::{best_pattern, PatternFit};
use super::patterns::{patterns, Pattern};
use super::rate;
use super::reference::Null;
use super::stacked::Stacked;
use super::{chi2_quantile, Prior, DEFAULT_FALSE_ALARM};
use crate::error::CalibError;
use crate::identify::linearize;
use crate::io::model_file::ModelFile;
use crate::measure::Measurement;
use crate::model::Mechanism;
use crate::validate::{pose_errors, ErrorStats};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// Options of [`update()`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateOptions {
    /// False-alarm rate of each release (divided by the number of patterns tried) and of the
    /// final test of the residual.
    pub false_alarm: f64,
    /// Patterns released at most.
    pub max_releases: usize,
    /// Gauss–Newton iterations of each fit at most.
    pub max_iterations: usize,
    /// Seed of the configurations the patterns are found at, and of the simulated bounds where
    /// the prior has a [`Reference`](super::Reference).
    pub seed: u64,
}

impl Default for UpdateOptions {
    fn default() -> Self {
        UpdateOptions {
            false_alarm: DEFAULT_FALSE_ALARM,
            max_releases: 3,
            max_iterations: 50,
            seed: 1,
        }
    }
}

/// A parameter the update moved.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Moved {
    /// Its name.
    pub name: String,
    /// `"mm"` or `"deg"`.
    pub unit: &'static str,
    /// The change.
    pub change: f64,
    /// Its standard deviation before (the prior's; 0 for a parameter the calibration held).
    pub prior_sigma: f64,
    /// Its standard deviation after.
    pub sigma: f64,
}

/// What [`update()`] produced.
#[derive(Debug, Clone)]
pub struct Update {
    /// The updated model file: the prior's with the new geometry and frames, the update's
    /// covariance, the noise and the calibration's residuals ([`super::with_covariance`]), what a
    /// later check or update reads.
    pub model_file: ModelFile,
    /// The change of every parameter (model units, local coordinates at the prior's model).
    pub delta: DVector<f64>,
    /// The covariance of the updated parameters (p × p, model units).
    pub covariance: DMatrix<f64>,
    /// The patterns released, in order, as fitted by the final fit.
    pub releases: Vec<PatternFit>,
    /// The best pattern not released (its release was not significant), if any was tried.
    pub declined: Option<PatternFit>,
    /// Every parameter that moved by more than its prior σ (or moved without a prior), the
    /// largest move relative to its prior σ first.
    pub moved: Vec<Moved>,
    /// Largest change relative to the prior σ over the parameters with a prior.
    pub largest_move_sigmas: f64,
    /// The prior's and the new rows' cost at the solution (χ² with `rows − released`
    /// degrees of freedom when the update is right).
    pub chi2: f64,
    /// New rows.
    pub rows: usize,
    /// The χ² quantile of `chi2` at the false-alarm rate.
    pub bound: f64,
    /// Whether the last fit converged.
    pub converged: bool,
    /// A pose the update set aside: the new poses disagreed with every update beyond noise, and
    /// without this one alone they agree (a blunder, or an error local to that pose: measure it
    /// again). The update, its statistic and its errors are then over the other poses.
    pub set_aside: Option<SetAside>,
    /// The new poses' errors under the prior's model.
    pub before: ErrorStats,
    /// … and under the updated model.
    pub after: ErrorStats,
}

impl Update {
    /// The new poses and the prior agree (after the releases) within noise.
    pub fn passed(&self) -> bool {
        self.converged && self.chi2 <= self.bound
    }
}

/// A new pose an [`Update`] set aside.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SetAside {
    /// Its index in the new poses.
    pub index: usize,
    /// Its position error under the update made without it (mm).
    pub position_mm: f64,
    /// Its rows' χ² under that update (weighted by the judged noise).
    pub chi2: f64,
    /// Its rows.
    pub rows: usize,
}

/// One fit of the prior and the new rows with the patterns `released` free.
struct Fit {
    /// `[z; β]`.
    u: DVector<f64>,
    model: Box<dyn Mechanism>,
    delta: DVector<f64>,
    stacked: Stacked,
    jacobian: DMatrix<f64>,
    cost: f64,
    /// Unit-weight covariance of `[z; β]`.
    cov: Option<DMatrix<f64>>,
    converged: bool,
}

/// A Gauss–Newton step no shorter step along which lowers the cost is at the minimum when it is
/// below this in the stacked, whitened rows: it would lower χ² by less than its square (1e-6) and
/// move every prediction by less than a thousandth of its σ.
const NEGLIGIBLE_STEP: f64 = 1e-3;

/// A model moved from the prior's, its change, the stacked rows there and the new rows' Jacobian.
type State = (Box<dyn Mechanism>, DVector<f64>, Stacked, DMatrix<f64>);

/// Gauss–Newton on the stacked rows, from the prior's model: the parameters move by
/// `L·z + D·β`.
fn fit(prior: &Prior, l: &DMatrix<f64>, d: &DMatrix<f64>, data: &[Measurement], max_iterations: usize) -> Result<Fit, CalibError> {
    let (r, g) = (l.ncols(), d.ncols());
    let mut u = DVector::zeros(r + g);
    let mut converged = false;
    let at = |u: &DVector<f64>| -> Result<State, CalibError> {
        let delta = l * u.rows(0, r) + d * u.rows(r, g);
        let mut model = prior.model.build();
        model.retract(&delta);
        let lin = linearize(&*model, data, &prior.noise)?;
        let stacked = Stacked::new(&lin, l, d, &u.rows(0, r).into_owned());
        Ok((model, delta, stacked, lin.jacobian))
    };
    let mut state = at(&u)?;
    for _ in 0..max_iterations {
        let Some(sol) = state.2.solve(None)? else {
            return Err(CalibError::Numerical(
                "the prior and the new poses do not determine the released patterns".into(),
            ));
        };
        let before = state.2.rhs.norm_squared();
        // The step, halved while it raises the cost (a curved closed loop overshoots).
        let mut alpha = 1.0;
        let mut accepted = None;
        for _ in 0..12 {
            let trial_u = &u + &sol.u * alpha;
            let trial = at(&trial_u)?;
            if trial.2.rhs.norm_squared() <= before {
                accepted = Some((trial_u, trial));
                break;
            }
            alpha *= 0.5;
        }
        let Some((next_u, next)) = accepted else {
            // No shorter step lowers the cost: at the minimum to round-off (or to the tolerance
            // a closed loop's kinematics are solved to), or stuck.
            let scale = 1.0 + state.2.rhs.norm();
            converged = (&state.2.k * &sol.u).norm() <= (1e-5 * scale).max(NEGLIGIBLE_STEP);
            break;
        };
        let size = alpha * (&state.2.k * &sol.u).norm();
        u = next_u;
        state = next;
        let after = state.2.rhs.norm_squared();
        // Converged: a step below 1e-10 of the residual, or a short step that no longer lowers
        // the cost (a closed loop's kinematics are solved to a tolerance of their own).
        let scale = 1.0 + state.2.rhs.norm();
        if size <= 1e-10 * scale || (size <= 1e-5 * scale && before - after <= 1e-9 * before) {
            converged = true;
            break;
        }
    }
    let (model, delta, stacked, jacobian) = state;
    let cost = stacked.rhs.norm_squared();
    let cov = stacked.covariance(None);
    Ok(Fit {
        u,
        model,
        delta,
        stacked,
        jacobian,
        cost,
        cov,
        converged,
    })
}

/// The prior's estimate updated by `data` (see the [module docs](super)): the prior as
/// information, the new poses as data, iterated to convergence; where the new poses contradict
/// the prior, the pattern that explains it best is released (its prior dropped) while the release
/// lowers the cost beyond the χ² quantile of its size at `opts.false_alarm` divided by the number
/// of patterns (noise releases nothing), at most `opts.max_releases` of them. When the new poses
/// still disagree with the converged update beyond noise, and an update without the pose that disagrees
/// most (of three or more) agrees with the others, that pose is set aside
/// ([`Update::set_aside`]) and that update returned.
///
/// Errors: the covariance does not match the model, kinematics failing at a pose, a numerical
/// failure.
pub fn update(prior: &Prior, data: &[Measurement], opts: &UpdateOptions) -> Result<Update, CalibError> {
    let all = update_all(prior, data, opts)?;
    if all.passed() || !all.converged || data.len() < 3 {
        return Ok(all);
    }
    let model = all.model_file.build();
    let lin = linearize(&*model, data, &prior.noise)?;
    let chi2 = |i: usize| lin.residual.rows_range(lin.pose_rows(i)).norm_squared();
    let Some(worst) = (0..data.len()).max_by(|&a, &b| chi2(a).total_cmp(&chi2(b))) else {
        return Ok(all);
    };
    let rest: Vec<Measurement> = data
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != worst)
        .map(|(_, m)| m.clone())
        .collect();
    let mut without = update_all(prior, &rest, opts)?;
    if !without.passed() {
        return Ok(all);
    }
    // The pose against the update made without it.
    let updated = without.model_file.build();
    let alone = &data[worst..=worst];
    let own = linearize(&*updated, alone, &prior.noise)?;
    without.set_aside = Some(SetAside {
        index: worst,
        position_mm: pose_errors(&*updated, alone)?.position[0],
        chi2: own.residual.norm_squared(),
        rows: own.residual.len(),
    });
    Ok(without)
}

/// [`update()`] on every pose given.
fn update_all(prior: &Prior, data: &[Measurement], opts: &UpdateOptions) -> Result<Update, CalibError> {
    if !(opts.false_alarm > 0.0 && opts.false_alarm < 1.0) {
        return Err(CalibError::InvalidOption(format!(
            "the false-alarm rate must be between 0 and 1 (it is {})",
            opts.false_alarm
        )));
    }
    if data.is_empty() {
        return Err(CalibError::NothingToIdentify("no new poses".into()));
    }
    let start = prior.model.build();
    let p = start.n_params();
    prior.check_size(p)?;
    let l = prior.factor();
    let all: Vec<Pattern> = patterns(&*start, &prior.model.inputs(), opts.seed)?;
    let mut released: Vec<usize> = Vec::new();
    let directions = |released: &[usize]| -> DMatrix<f64> {
        let cols: Vec<_> = released.iter().flat_map(|&i| all[i].directions.column_iter()).collect();
        if cols.is_empty() {
            DMatrix::zeros(p, 0)
        } else {
            DMatrix::from_columns(&cols)
        }
    };
    let mut current = fit(prior, &l, &directions(&released), data, opts.max_iterations)?;
    let rows = current.jacobian.nrows();
    let layout = linearize(&*start, data, &prior.noise)?.layout();
    let tried = all.len().max(1) as f64;
    let mut declined = None;
    // What the new poses could not tell each release from, when it was released.
    let mut alternatives = Vec::new();
    while released.len() < opts.max_releases {
        let best = best_pattern(
            &current.stacked,
            &current.jacobian,
            &all,
            &released,
            current.cost,
            rows,
            opts.false_alarm,
        )?;
        // Judged by the calibration's own residuals where it has them: the release's drop
        // against its simulated distribution, where that is above the χ² quantile (a reference of
        // a few poses under-represents a normal tail; no release is judged more strictly).
        let best = match (best, &prior.reference) {
            (Some(mut b), Some(reference)) => {
                let null = Null {
                    reference,
                    layout: &layout,
                    l: &l,
                    jacobian: &current.jacobian,
                };
                let draws = rate::NULL_DRAWS.max((20.0 * tried / opts.false_alarm).ceil() as usize);
                if let Some(bound) = null.bound(
                    &directions(&released),
                    Some(&all[b.index].directions),
                    1.0 - opts.false_alarm / tried,
                    draws,
                    opts.seed,
                ) {
                    b.bound = b.bound.max(bound);
                }
                Some(b)
            }
            (best, _) => best,
        };
        match best {
            Some(b) if b.significant() => {
                let mut trial = released.clone();
                trial.push(b.index);
                match fit(prior, &l, &directions(&trial), data, opts.max_iterations) {
                    Ok(f) => {
                        released = trial;
                        current = f;
                        alternatives.push(b.alternatives);
                    }
                    Err(CalibError::Numerical(_)) => {
                        declined = Some(b);
                        break;
                    }
                    Err(e) => return Err(e),
                }
            }
            other => {
                declined = other;
                break;
            }
        }
    }
    let r = l.ncols();
    // The released patterns as the final fit has them.
    let u_cov = current.cov.clone();
    let mut releases = Vec::new();
    let mut col = r;
    let beta_all = &current.u;
    for (&i, alternatives) in released.iter().zip(alternatives) {
        let pat = &all[i];
        let k = pat.directions.ncols();
        let values = pat
            .coefficients
            .iter()
            .enumerate()
            .map(|(j, c)| super::check::PatternValue {
                label: c.label.clone(),
                value: beta_all[col + j] * c.factor,
                sigma: u_cov
                    .as_ref()
                    .map_or(f64::NAN, |m| m[(col + j, col + j)].max(0.0).sqrt() * c.factor.abs()),
                unit: c.unit,
            })
            .collect();
        releases.push(PatternFit {
            name: pat.name.clone(),
            kind: pat.kind,
            values,
            chi2_drop: f64::NAN,
            bound: f64::NAN,
            chi2_after: current.cost,
            bound_after: f64::NAN,
            alternatives,
            index: i,
        });
        col += k;
    }
    // The parameters' covariance after: M·cov(u)·Mᵀ with M = [L D].
    let d = directions(&released);
    let m = DMatrix::from_fn(p, r + d.ncols(), |i, j| if j < r { l[(i, j)] } else { d[(i, j - r)] });
    let covariance = u_cov.as_ref().map_or_else(|| DMatrix::zeros(p, p), |c| &m * c * m.transpose());
    let params = start.params();
    let mut moved = Vec::new();
    let mut largest: f64 = 0.0;
    for (k, par) in params.iter().enumerate() {
        let change = current.delta[k];
        let prior_sigma = prior.covariance[(k, k)].max(0.0).sqrt();
        let sigma = covariance[(k, k)].max(0.0).sqrt();
        if prior_sigma > 0.0 {
            largest = largest.max(change.abs() / prior_sigma);
        }
        let beyond = if prior_sigma > 0.0 {
            change.abs() > prior_sigma
        } else {
            change.abs() > 1e-12
        };
        if beyond {
            let (f, unit) = par.unit.display();
            moved.push(Moved {
                name: par.name.clone(),
                unit,
                change: change * f,
                prior_sigma: prior_sigma * f,
                sigma: sigma * f,
            });
        }
    }
    let rel = |m: &Moved| {
        if m.prior_sigma > 0.0 {
            m.change.abs() / m.prior_sigma
        } else {
            f64::INFINITY
        }
    };
    moved.sort_by(|a, b| rel(b).total_cmp(&rel(a)));
    let mut model_file = prior
        .model
        .with_geometry_of(&*current.model)
        .map_err(|message| CalibError::InvalidOption(format!("the updated model: {message}")))?;
    model_file.description = Some(format!("'{}' updated from {} new poses", prior.model.name, data.len()));
    let model_file = super::with_covariance(model_file, &covariance, &prior.noise, prior.reference.as_ref());
    let before = ErrorStats::of(&pose_errors(&*start, data)?);
    let after = ErrorStats::of(&pose_errors(&*current.model, data)?);
    let dof = rows.saturating_sub(d.ncols()).max(1);
    let chi2_bound = prior
        .reference
        .as_ref()
        .and_then(|reference| {
            let null = Null {
                reference,
                layout: &layout,
                l: &l,
                jacobian: &current.jacobian,
            };
            null.bound(&d, None, 1.0 - opts.false_alarm, rate::NULL_DRAWS, opts.seed)
        })
        .map_or(f64::NEG_INFINITY, |b| b)
        .max(chi2_quantile(dof, 1.0 - opts.false_alarm));
    Ok(Update {
        model_file,
        delta: current.delta,
        covariance,
        releases,
        declined,
        moved,
        largest_move_sigmas: largest,
        chi2: current.cost,
        rows,
        bound: chi2_bound,
        converged: current.converged,
        set_aside: None,
        before,
        after,
    })
}
