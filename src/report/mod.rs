//! The calibration report: everything an identification produced, as data ([`CalibrationReport`],
//! serialisable to JSON) and as one self-contained HTML file with inline SVG plots
//! ([`CalibrationReport::to_html`]).
pub mod artifacts;
pub mod assess;
mod held_out;
mod html;
pub mod kinds;
pub mod plan;
pub mod plot;
mod predicted;
mod verdict;
mod view;
pub mod weak_cause;

pub use artifacts::{is_known_distance, ArtifactView, KnownDistance};
pub use held_out::HeldOutPlacements;
pub use predicted::PredictedMap;
pub use verdict::{Beyond, Status, ToleranceCheck, Verdict, CHANCE_BEYOND_3_SIGMA, SIGMA0_FAIL, SIGMA0_WARN};
pub use view::{MachineView, VIEW_POINTS, VIEW_WORST};

use crate::error::CalibError;
use crate::identify::Identification;
use crate::io::model_file::Tolerances;
use crate::measure::{Measurement, Noise};
use crate::model::Mechanism;
use crate::params::Unit;
use crate::validate::{errors_at, forward_all, outliers_at, ErrorStats, Outlier, PoseErrors};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// Errors of one data set before and after calibration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SetErrors {
    /// Data file (for display).
    pub source: String,
    /// Per-pose errors of the starting (nominal) model.
    pub before: PoseErrors,
    /// Per-pose errors of the calibrated model.
    pub after: PoseErrors,
    /// Statistics of `before`.
    pub before_stats: ErrorStats,
    /// Statistics of `after`.
    pub after_stats: ErrorStats,
    /// Poses whose residual after calibration exceeds 3σ.
    pub outliers: Vec<Outlier>,
    /// Pose ids (the data file's `id` column; row numbers from 0 until
    /// [`CalibrationReport::set_ids`] is called).
    pub ids: Vec<i64>,
    /// Input values of each pose (internal units: rad, mm), for errors against each input.
    pub inputs: Vec<Vec<f64>>,
    /// Observed joints' readings against the starting model (empty without readings).
    pub joints_before: Vec<crate::validate::JointErrors>,
    /// Observed joints' readings against the calibrated model.
    pub joints_after: Vec<crate::validate::JointErrors>,
    /// Measured tool position of each pose (mm, in the measurement frame; for reflector points,
    /// their mean), where the 3-D view draws it. An instrument's row (seat, pivot, touch)
    /// measures no coordinates: its entry is the calibrated model's tool point at the row's
    /// configuration, in the machine's base frame ([`artifacts`]).
    pub measured: Vec<[f64; 3]>,
    /// Position error vector of each pose before calibration: measured minus the starting
    /// model's position (mm; for reflector points, the mean of the points' errors). Its length
    /// is `before.position` for a position or pose observation. For an instrument's row: where
    /// the instrument puts the tool point minus where the model does (the seat's centre minus
    /// the tool point, the length's error along the bar, the touch's along the surface's
    /// normal), in the base frame.
    pub error_before: Vec<[f64; 3]>,
    /// The same after calibration (measured minus the calibrated model's position).
    pub error_after: Vec<[f64; 3]>,
    /// Per pose, the index of its artifact in [`MachineView::artifacts`] for an instrument's
    /// row, `None` for a tracker's; empty when no row is an instrument's.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub artifact: Vec<Option<usize>>,
    /// Per pose, the starting model's tool point (mm; an instrument's row in the base frame, a
    /// tracker's in the measurement frame); empty when no row is an instrument's.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub nominal_point: Vec<[f64; 3]>,
}

impl SetErrors {
    /// Errors of `nominal` and `calibrated` on `data`, with outliers beyond `3σ` flagged. Known
    /// distances between seats ([`is_known_distance`]) are no poses: left out (the poses are the
    /// other rows, in their order).
    pub fn compute<A: Mechanism + ?Sized, B: Mechanism + ?Sized>(
        source: impl Into<String>,
        nominal: &A,
        calibrated: &B,
        data: &[Measurement],
    ) -> Result<SetErrors, CalibError> {
        let poses: Vec<Measurement>;
        let data = if data.iter().any(is_known_distance) {
            poses = data.iter().filter(|m| !is_known_distance(m)).cloned().collect();
            &poses[..]
        } else {
            data
        };
        let start = forward_all(nominal, data)?;
        let before = errors_at(&start, data);
        // The calibrated poses once, for the errors and the outliers.
        let reached = forward_all(calibrated, data)?;
        let after = errors_at(&reached, data);
        let (mut artifact, mut nominal_point) = (Vec::new(), Vec::new());
        let (measured, error_before, error_after) = if data.iter().any(|m| artifacts::artifact_index(m).is_some()) {
            let (b, a) = (
                artifacts::place(nominal, data, &start)?,
                artifacts::place(calibrated, data, &reached)?,
            );
            artifact = data.iter().map(artifacts::artifact_index).collect();
            nominal_point = b.points;
            (a.points, b.errors, a.errors)
        } else {
            let (measured, error_before) = data
                .iter()
                .zip(&start)
                .map(|(m, t)| artifacts::position_and_error(&m.obs, t))
                .unzip();
            let error_after = data
                .iter()
                .zip(&reached)
                .map(|(m, t)| artifacts::position_and_error(&m.obs, t).1)
                .collect();
            (measured, error_before, error_after)
        };
        Ok(SetErrors {
            measured,
            error_before,
            error_after,
            artifact,
            nominal_point,
            joints_before: crate::validate::observed_joint_errors(nominal, data)?,
            joints_after: crate::validate::observed_joint_errors(calibrated, data)?,
            source: source.into(),
            before_stats: ErrorStats::of(&before),
            after_stats: ErrorStats::of(&after),
            before,
            after,
            outliers: outliers_at(&reached, data, 3.0),
            ids: (0..data.len() as i64).collect(),
            inputs: data.iter().map(|m| m.q.clone()).collect(),
        })
    }
}

/// Status of a parameter after identification.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ParamStatus {
    /// In the identifiable subset.
    Identified,
    /// Free, but a combination of parameters before it in priority order.
    Redundant,
    /// Free, but without any effect on the measurements.
    NoEffect,
    /// Free and of full rank, but seen too weakly to fix: held as drawn
    /// ([`crate::identify::weakly_seen`]).
    Weak,
    /// Not free (fixed in the model file).
    Fixed,
}

/// One parameter row of the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamRow {
    /// Parameter name.
    pub name: String,
    /// Report group.
    pub group: String,
    /// Display unit (`mm`, `deg` or empty).
    pub unit: String,
    /// Identified change, in the display unit.
    pub value: f64,
    /// Its standard deviation, in the display unit (0 when not identified).
    pub std_dev: f64,
    /// Status.
    pub status: ParamStatus,
}

/// The covariance of the identified parameters ([`Identification::covariance`] restricted to
/// them), in display units: rows and columns follow `params` (identified parameters, in
/// priority order, as [`CalibrationReport::correlation_names`]), entry `(i, j)` in
/// `units[i]·units[j]` (mm, deg). Its diagonal is the square of [`ParamRow::std_dev`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamCovariance {
    /// Names of the identified parameters.
    pub params: Vec<String>,
    /// Their display units (`mm`, `deg` or empty).
    pub units: Vec<String>,
    /// The matrix, row by row.
    pub matrix: Vec<Vec<f64>>,
}

/// Everything an identification produced.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationReport {
    /// The verdict (see [`CalibrationReport::assess`]).
    pub verdict: Verdict,
    /// Model name.
    pub model: String,
    /// Identification method.
    pub method: String,
    /// Whether the solver converged.
    pub converged: bool,
    /// Solver iterations.
    pub iterations: usize,
    /// Why the solver never left its start (every step it tried put a pose where the model
    /// cannot be evaluated), when that happened ([`crate::identify::Identification::stalled`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stalled: Option<String>,
    /// A-posteriori standard deviation of unit weight.
    pub sigma0: f64,
    /// Noise used as weights: position (mm), orientation (deg).
    pub noise_mm_deg: (f64, f64),
    /// Number of free (candidate) parameters.
    pub free: usize,
    /// Numerical rank = number of identified parameters.
    pub rank: usize,
    /// Residual rows of the fit beyond the identified parameters (rows − rank): how many numbers
    /// σ̂₀ rests on.
    pub redundancy: usize,
    /// Condition number of the column-scaled Jacobian on the identified parameters.
    pub condition: f64,
    /// Singular values of the column-scaled Jacobian on the free parameters.
    pub singular_values: Vec<f64>,
    /// Names of redundant parameters.
    pub redundant: Vec<String>,
    /// Names of free parameters with no effect.
    pub no_effect: Vec<String>,
    /// Names of the parameters an overconstrained machine cannot take alone, held as drawn
    /// ([`Mechanism::assembly_breaking`]); empty for every other machine.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub held_by_assembly: Vec<String>,
    /// Names of the parameters seen too weakly to fix, held as drawn
    /// ([`crate::identify::weakly_seen`]).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub weak: Vec<String>,
    /// The likely cause of [`Self::weak`] and what would reveal them, where it is a known one
    /// ([`weak_cause::known_cause`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub weak_cause: Option<String>,
    /// Names of the parameters that place the machine as a whole, held as drawn because no
    /// instrument in the data sees where the machine stands ([`crate::calibrate::gauge`]); not
    /// counted among the free parameters.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub placement: Vec<String>,
    /// Every parameter.
    pub params: Vec<ParamRow>,
    /// Covariance of the identified parameters.
    pub covariance: ParamCovariance,
    /// Identification set.
    pub identification: SetErrors,
    /// Validation set, if one was given (for instrument data: its tracker rows, if any).
    pub validation: Option<SetErrors>,
    /// A validation file's instrument rows (seats, pivots, touches): its own artifacts placed by
    /// its rows under the nominal and the calibrated model (set by `calibrate`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out: Option<HeldOutPlacements>,
    /// Notes that do not change the verdict but deserve a look (poorly determined parameters,
    /// strongly correlated pairs).
    pub flags: Vec<String>,
    /// Names of the identified parameters, in the order of [`CalibrationReport::correlation`].
    pub correlation_names: Vec<String>,
    /// Correlation matrix of the identified parameters (from the covariance of the solution).
    pub correlation: Vec<Vec<f64>>,
    /// Pairs of identified parameters correlated beyond [`STRONG_CORRELATION`]: (a, b, ρ).
    pub correlated: Vec<(String, String, f64)>,
    /// Each redundant parameter and the identified parameters whose combination has the same
    /// effect on the measurements (what it is absorbed into), e.g. `("0-1.vx", "≈ +1·mx")`.
    pub absorbed: Vec<(String, String)>,
    /// The inputs (name, display unit `deg` or `mm`), for errors against each input.
    pub inputs: Vec<(String, String)>,
    /// Where the calibration came from (command line, version, date, data), when known.
    pub provenance: Option<crate::io::model_file::Provenance>,
    /// Ids of the identification poses set aside as gross blunders (not in the final fit).
    pub blunders: Vec<i64>,
    /// For a model with joint terms: the same data fitted by the geometric model alone and with
    /// each kind of term alone (empty otherwise), to show what each term contributes.
    pub variants: Vec<ModelVariant>,
    /// The corrections judged against the model's tolerances in the split of redundant
    /// parameters and frames that keeps them smallest (set by `calibrate`; without it the
    /// verdict judges the reported values).
    pub tolerance_check: Option<ToleranceCheck>,
    /// The model is a serial chain without joint terms: a residual above the noise then points
    /// at them in the verdict.
    pub serial_chain: bool,
    /// Angle columns of the data that look like radians read as degrees
    /// (`calibrate::checks::radian_like_columns`): named in the verdict where corrections come
    /// out far beyond the tolerances.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub radian_like_columns: Vec<String>,
    /// The machine and its frames as the report's 3-D view draws them.
    pub machine: MachineView,
    /// Each measurement kind's residual against its own stated noise (set by `calibrate`).
    pub kinds: Vec<kinds::KindResidual>,
    /// The known distances between seats the fit held (set by `calibrate`; empty without them):
    /// rows of the fit, not poses.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub known_distances: Vec<KnownDistance>,
    /// The predicted position σ over the workspace ([`PredictedMap`]), when the calibrated
    /// model carries a covariance.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted: Option<PredictedMap>,
}

/// The same data fitted by a model with fewer terms (see [`CalibrationReport::variants`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelVariant {
    /// What the model holds, e.g. `"geometric only"`, `"geometry + backlash"`.
    pub name: String,
    /// Identified parameters (rank) of the free ones.
    pub rank: usize,
    /// Free parameters.
    pub free: usize,
    /// A-posteriori standard deviation of unit weight.
    pub sigma0: f64,
    /// Errors on the identification set after calibration.
    pub identification: ErrorStats,
    /// Errors on the validation set after calibration, when there is one.
    pub validation: Option<ErrorStats>,
}

/// Identified parameters correlated beyond this (in absolute value) are flagged.
pub const STRONG_CORRELATION: f64 = 0.95;

impl CalibrationReport {
    /// Assemble the report of `result`, identified from `nominal` with the free parameters
    /// `free`; `validation` is an optional independent data set. For instrument data
    /// ([`artifacts`]) the view draws the artifacts and the tool points in the machine's base
    /// frame, the calibrated ones placed as `calibrate` places the calibrated model.
    #[allow(clippy::too_many_arguments)]
    pub fn new<M: Mechanism + Clone>(
        nominal: &M,
        result: &Identification<M>,
        free: &[usize],
        method: &str,
        data_source: &str,
        data: &[Measurement],
        validation: Option<(&str, &[Measurement])>,
    ) -> Result<CalibrationReport, CalibError> {
        let params = nominal.params();
        let id = &result.identifiability;
        let rows = params
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let (f, unit) = p.unit.display();
                let status = if id.identifiable.contains(&i) {
                    ParamStatus::Identified
                } else if id.redundant.contains(&i) {
                    ParamStatus::Redundant
                } else if id.no_effect.contains(&i) {
                    ParamStatus::NoEffect
                } else if id.weak.contains(&i) {
                    ParamStatus::Weak
                } else if free.contains(&i) {
                    ParamStatus::Redundant
                } else {
                    ParamStatus::Fixed
                };
                ParamRow {
                    name: p.name.clone(),
                    group: p.group.clone(),
                    unit: unit.into(),
                    value: result.delta[i] * f,
                    std_dev: result.std_dev[i] * f,
                    status,
                }
            })
            .collect();
        let names = |v: &[usize]| v.iter().map(|&i| params[i].name.clone()).collect::<Vec<_>>();
        let display = |i: usize| params[i].unit.display();
        let covariance = ParamCovariance {
            params: names(&id.identifiable),
            units: id.identifiable.iter().map(|&i| display(i).1.to_string()).collect(),
            matrix: id
                .identifiable
                .iter()
                .map(|&i| {
                    id.identifiable
                        .iter()
                        .map(|&j| match result.covariance.get((i, j)) {
                            Some(c) => c * display(i).0 * display(j).0,
                            None => f64::NAN,
                        })
                        .collect()
                })
                .collect(),
        };
        let Noise { position, orientation, .. } = result.noise;
        let mut report = CalibrationReport {
            verdict: Verdict {
                status: Status::Calibrated,
                reasons: Vec::new(),
            },
            model: nominal.name().to_string(),
            method: method.to_string(),
            converged: result.converged,
            iterations: result.iterations.len(),
            stalled: result.stalled.clone(),
            sigma0: result.sigma0,
            noise_mm_deg: (position, orientation.to_degrees()),
            free: free.len(),
            rank: id.identifiable.len(),
            redundancy: data
                .iter()
                .map(|m| m.obs.rows() + m.joints.len())
                .sum::<usize>()
                .saturating_sub(id.identifiable.len()),
            condition: id.condition,
            singular_values: id.singular_values.clone(),
            redundant: names(&id.redundant),
            no_effect: names(&id.no_effect),
            held_by_assembly: names(&nominal.assembly_breaking()),
            weak: names(&id.weak),
            weak_cause: None,
            placement: Vec::new(),
            params: rows,
            covariance,
            identification: SetErrors::compute(data_source, nominal, &result.model, data)?,
            validation: match validation {
                Some((src, v)) => Some(SetErrors::compute(src, nominal, &result.model, v)?),
                None => None,
            },
            held_out: None,
            flags: Vec::new(),
            correlation_names: Vec::new(),
            correlation: Vec::new(),
            correlated: Vec::new(),
            absorbed: Vec::new(),
            inputs: nominal.input_names().into_iter().map(|n| (n, String::new())).collect(),
            provenance: None,
            blunders: Vec::new(),
            variants: Vec::new(),
            tolerance_check: None,
            serial_chain: false,
            radian_like_columns: Vec::new(),
            machine: MachineView::of(nominal, &result.model, data.first()),
            kinds: Vec::new(),
            known_distances: Vec::new(),
            predicted: None,
        };
        // An instrument's artifacts, placed by both models (the rows of tracker data are not
        // evaluated again).
        if !report.identification.artifact.is_empty() {
            let (b, a) = (
                artifacts::place(nominal, data, &forward_all(nominal, data)?)?,
                artifacts::place(&result.model, data, &forward_all(&result.model, data)?)?,
            );
            report.machine.artifacts = artifacts::artifact_views(data, &a, &b);
        }
        if let Some(motion) = artifacts::drawn_placement(&report.identification) {
            report.place_as_drawn(&motion);
        }
        report.correlations(result, &params);
        report.absorbed = absorbed(result, &params);
        report.assess(&result.noise, &Tolerances::default());
        Ok(report)
    }

    /// The correlation matrix of the identified parameters and the strongly correlated pairs.
    fn correlations<M: Mechanism>(&mut self, result: &Identification<M>, params: &[crate::params::Param]) {
        let ids = &result.identifiability.identifiable;
        let c = &result.covariance;
        if c.nrows() != params.len() {
            return;
        }
        self.correlation_names = ids.iter().map(|&i| params[i].name.clone()).collect();
        self.correlation = ids
            .iter()
            .map(|&i| {
                ids.iter()
                    .map(|&j| {
                        let d = (c[(i, i)] * c[(j, j)]).sqrt();
                        if d > 0.0 && d.is_finite() {
                            c[(i, j)] / d
                        } else {
                            0.0
                        }
                    })
                    .collect()
            })
            .collect();
        for a in 0..ids.len() {
            for b in a + 1..ids.len() {
                let r = self.correlation[a][b];
                if r.abs() > STRONG_CORRELATION {
                    self.correlated
                        .push((self.correlation_names[a].clone(), self.correlation_names[b].clone(), r));
                }
            }
        }
    }

    /// Label the poses with the data's ids (identification set, validation set).
    pub fn set_ids(&mut self, identification: &[i64], validation: Option<&[i64]>) {
        if identification.len() == self.identification.ids.len() {
            self.identification.ids = identification.to_vec();
        }
        if let (Some(v), Some(ids)) = (self.validation.as_mut(), validation) {
            if ids.len() == v.ids.len() {
                v.ids = ids.to_vec();
            }
        }
    }

    /// Name the inputs and their display units (`deg` for angles, `mm` for lengths).
    pub fn set_inputs(&mut self, inputs: &[crate::io::model_file::InputSpec]) {
        self.inputs = inputs
            .iter()
            .map(|i| (i.name.clone(), if i.unit == Unit::Angle { "deg" } else { "mm" }.to_string()))
            .collect();
    }
}

/// For each redundant parameter, the identified parameters whose combination has the same effect
/// on the measurements: least squares of its (column-scaled) Jacobian column on the identified
/// columns at the solution, the largest three terms in model units.
fn absorbed<M: Mechanism>(result: &Identification<M>, params: &[crate::params::Param]) -> Vec<(String, String)> {
    let id = &result.identifiability;
    if id.redundant.is_empty() || id.identifiable.is_empty() {
        return Vec::new();
    }
    // Least squares of each redundant column on the identified ones, from the information matrix
    // AᵀA of the fit (the normal equations of that fit, in column-scaled form): no pass over the
    // poses.
    let gram = &result.information;
    if gram.nrows() != params.len() || gram.ncols() != params.len() {
        return Vec::new();
    }
    let ident = &id.identifiable;
    let norms: Vec<f64> = ident.iter().map(|&c| gram[(c, c)].max(0.0).sqrt()).collect();
    if gram.iter().any(|v| !v.is_finite()) || norms.contains(&0.0) {
        return Vec::new();
    }
    let k = ident.len();
    let n_ii = DMatrix::from_fn(k, k, |i, j| gram[(ident[i], ident[j])] / (norms[i] * norms[j]));
    let svd = n_ii.clone().svd(true, true);
    let unit = |p: &crate::params::Param| match p.unit {
        Unit::Length => "mm",
        Unit::Angle => "rad",
        Unit::Dimensionless => "",
    };
    id.redundant
        .iter()
        .map(|&j| {
            let nj = gram[(j, j)].max(0.0).sqrt();
            if nj == 0.0 || !nj.is_finite() {
                return (params[j].name.clone(), "no effect".to_string());
            }
            let n_ij = DVector::from_fn(k, |i, _| gram[(ident[i], j)] / (norms[i] * nj));
            let Ok(c) = svd.solve(&n_ij, 1e-12) else {
                return (params[j].name.clone(), "—".to_string());
            };
            // |A_I·c − a_j/|a_j||² = 1 − 2cᵀ(A_Iᵀa_j)/|a_j| + cᵀ(A_IᵀA_I)c, all column-scaled.
            let fit = (1.0 - 2.0 * c.dot(&n_ij) + c.dot(&(&n_ii * &c))).max(0.0).sqrt();
            // In model units: a change δ of this parameter acts like changes coef_k·δ of those.
            let mut terms: Vec<(f64, usize)> = c.iter().enumerate().map(|(k, v)| (v * nj / norms[k], k)).collect();
            let weight = |t: &(f64, usize)| (c[t.1]).abs();
            terms.sort_by(|x, y| weight(y).total_cmp(&weight(x)));
            let top = weight(&terms[0]).max(f64::MIN_POSITIVE);
            let shown: Vec<String> = terms
                .iter()
                .filter(|t| weight(t) > 1e-3 * top)
                .take(3)
                .map(|(v, k)| {
                    let p = &params[id.identifiable[*k]];
                    let u = if unit(p) == unit(&params[j]) {
                        String::new()
                    } else {
                        format!(" {}/{}", unit(p), unit(&params[j]))
                    };
                    format!("{v:+.3}{u}·{}", p.name)
                })
                .collect();
            let more = terms.iter().filter(|t| weight(t) > 1e-3 * top).count().saturating_sub(3);
            let partial = if fit > 1e-3 {
                format!(" (only partly: {:.0} % of its effect remains)", 100.0 * fit)
            } else {
                String::new()
            };
            (
                params[j].name.clone(),
                format!(
                    "≈ {}{}{partial}",
                    shown.join(" "),
                    if more > 0 { format!(" + {more} more") } else { String::new() }
                ),
            )
        })
        .collect()
}
