//! The calibration report: everything an identification produced, as data ([`CalibrationReport`],
//! serialisable to JSON) and as one self-contained HTML file with inline SVG plots
//! ([`CalibrationReport::to_html`]).
pub mod plot;

use crate::error::CalibError;
use crate::identify::Identification;
use crate::io::model_file::Tolerances;
use crate::measure::{Measurement, Noise};
use crate::model::Mechanism;
use crate::params::Unit;
use crate::workflow::{outliers, pose_errors, ErrorStats, Outlier, PoseErrors};
use plot::Series;
use serde::Serialize;
use std::fmt::Write as _;

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
}

impl SetErrors {
    /// Errors of `nominal` and `calibrated` on `data`, with outliers beyond `3σ` flagged.
    pub fn compute<A: Mechanism + ?Sized, B: Mechanism + ?Sized>(
        source: impl Into<String>,
        nominal: &A,
        calibrated: &B,
        data: &[Measurement],
    ) -> Result<SetErrors, CalibError> {
        let before = pose_errors(nominal, data)?;
        let after = pose_errors(calibrated, data)?;
        Ok(SetErrors {
            source: source.into(),
            before_stats: ErrorStats::of(&before),
            after_stats: ErrorStats::of(&after),
            before,
            after,
            outliers: outliers(calibrated, data, 3.0)?,
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

/// The covariance of the identified parameters, `σ̂₀²·(JᵀWJ)⁻¹`, in display units: rows and
/// columns follow `params` (identified parameters, in priority order), entry `(i, j)` in
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

/// The overall judgement of a calibration, shown first in the report and deciding the exit code
/// of `kinecal identify`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// Converged, residual consistent with the noise, nothing flagged.
    Calibrated,
    /// Usable, but look at the reasons (residual above the noise, poorly determined parameters,
    /// outliers).
    UsableWithWarnings,
    /// Not usable: not converged, or the residual is far beyond the stated noise.
    Failed,
}

impl Status {
    /// `"calibrated"`, `"usable with warnings"`, `"failed"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Calibrated => "calibrated",
            Status::UsableWithWarnings => "usable with warnings",
            Status::Failed => "failed",
        }
    }
}

/// A [`Status`] and the reasons for it, most serious first.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Verdict {
    /// The judgement.
    pub status: Status,
    /// Why (empty when calibrated).
    pub reasons: Vec<String>,
}

/// σ̂₀ above this fails a calibration: the residual is an order of magnitude beyond the stated
/// noise, which a wrong unit, swapped columns, a wrong model or an unregistered frame gives, and
/// real unmodelled errors of a sound setup do not.
pub const SIGMA0_FAIL: f64 = 10.0;
/// σ̂₀ above this (and up to [`SIGMA0_FAIL`]) is a warning: errors the model does not describe
/// remain, or the stated noise is optimistic.
pub const SIGMA0_WARN: f64 = 3.0;

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
    /// A-posteriori standard deviation of unit weight.
    pub sigma0: f64,
    /// Noise used as weights: position (mm), orientation (deg).
    pub noise_mm_deg: (f64, f64),
    /// Number of free (candidate) parameters.
    pub free: usize,
    /// Numerical rank = number of identified parameters.
    pub rank: usize,
    /// Condition number of the column-scaled Jacobian on the identified parameters.
    pub condition: f64,
    /// Singular values of the column-scaled Jacobian on the free parameters.
    pub singular_values: Vec<f64>,
    /// Names of redundant parameters.
    pub redundant: Vec<String>,
    /// Names of free parameters with no effect.
    pub no_effect: Vec<String>,
    /// Every parameter.
    pub params: Vec<ParamRow>,
    /// Covariance of the identified parameters.
    pub covariance: ParamCovariance,
    /// Identification set.
    pub identification: SetErrors,
    /// Validation set, if one was given.
    pub validation: Option<SetErrors>,
}

impl CalibrationReport {
    /// Assemble the report of `result`, identified from `nominal` with the free parameters
    /// `free`; `validation` is an optional independent data set.
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
                let (f, unit) = match p.unit {
                    Unit::Length => (1.0, "mm"),
                    Unit::Angle => (180.0 / std::f64::consts::PI, "deg"),
                    Unit::Dimensionless => (1.0, ""),
                };
                let status = if id.identifiable.contains(&i) {
                    ParamStatus::Identified
                } else if id.redundant.contains(&i) {
                    ParamStatus::Redundant
                } else if id.no_effect.contains(&i) {
                    ParamStatus::NoEffect
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
        let display = |i: usize| match params[i].unit {
            Unit::Angle => (180.0 / std::f64::consts::PI, "deg"),
            Unit::Length => (1.0, "mm"),
            Unit::Dimensionless => (1.0, ""),
        };
        let covariance = ParamCovariance {
            params: names(&id.identifiable),
            units: id.identifiable.iter().map(|&i| display(i).1.to_string()).collect(),
            matrix: id
                .identifiable
                .iter()
                .map(|&i| {
                    id.identifiable
                        .iter()
                        .map(|&j| result.covariance[(i, j)] * display(i).0 * display(j).0)
                        .collect()
                })
                .collect(),
        };
        let Noise { position, orientation } = result.noise;
        let mut report = CalibrationReport {
            verdict: Verdict {
                status: Status::Calibrated,
                reasons: Vec::new(),
            },
            model: nominal.name().to_string(),
            method: method.to_string(),
            converged: result.converged,
            iterations: result.iterations.len(),
            sigma0: result.sigma0,
            noise_mm_deg: (position, orientation.to_degrees()),
            free: free.len(),
            rank: id.rank,
            condition: id.condition,
            singular_values: id.singular_values.clone(),
            redundant: names(&id.redundant),
            no_effect: names(&id.no_effect),
            params: rows,
            covariance,
            identification: SetErrors::compute(data_source, nominal, &result.model, data)?,
            validation: match validation {
                Some((src, v)) => Some(SetErrors::compute(src, nominal, &result.model, v)?),
                None => None,
            },
        };
        report.assess(&result.noise, &Tolerances::default());
        Ok(report)
    }

    /// Judge the calibration ([`CalibrationReport::verdict`]) against the noise the user stated
    /// (`stated`; with re-estimated weights the estimate is compared with it).
    pub fn assess(&mut self, stated: &Noise, tolerances: &Tolerances) {
        let mut failed = Vec::new();
        let mut warnings = Vec::new();
        let short = |names: &[&str]| {
            if names.len() > 6 {
                format!("{} … ({} in all)", names[..6].join(" "), names.len())
            } else {
                names.join(" ")
            }
        };
        let beyond: Vec<String> = self
            .params
            .iter()
            .filter(|p| p.status == ParamStatus::Identified && !p.group.ends_with(" frame"))
            .filter(|p| match p.unit.as_str() {
                "mm" => p.value.abs() > tolerances.length_mm,
                "deg" => p.value.abs() > tolerances.angle_deg,
                _ => false,
            })
            .map(|p| format!("{} {:+.3} {}", p.name, p.value, p.unit))
            .collect();
        if !beyond.is_empty() {
            let names: Vec<&str> = beyond.iter().map(String::as_str).collect();
            failed.push(format!(
                "corrections beyond the model's tolerances ({} mm, {} deg): {}: is the model of this machine, and are the joint columns in the right order and unit?",
                tolerances.length_mm,
                tolerances.angle_deg,
                short(&names)
            ));
        }
        if !self.converged {
            failed.push(format!(
                "the identification did not converge after {} iterations (too few or badly spread poses, or a model that does not fit the data)",
                self.iterations
            ));
        }
        let ratio = [
            self.noise_mm_deg.0 / stated.position,
            self.noise_mm_deg.1.to_radians() / stated.orientation,
        ]
        .into_iter()
        .filter(|r| r.is_finite())
        .fold(1.0, f64::max);
        let excess = self.sigma0 * ratio;
        if !excess.is_finite() {
            failed.push("the residual is not finite".into());
        } else if excess > SIGMA0_FAIL {
            failed.push(format!(
                "the residual is {excess:.1}× the stated noise (σ̂₀ {:.2}{}): a wrong unit or column order, a model of another machine, or data in an unregistered frame",
                self.sigma0,
                if ratio > 1.0 { format!(", re-estimated weights {ratio:.1}× the stated noise") } else { String::new() }
            ));
        } else if excess > SIGMA0_WARN {
            warnings.push(format!(
                "the residual is {excess:.1}× the stated noise: errors the geometric model does not describe remain (see the residual plots), or the stated noise is optimistic"
            ));
        }
        let poor: Vec<&str> = self
            .params
            .iter()
            .filter(|p| p.status == ParamStatus::Identified && p.std_dev > p.value.abs())
            .map(|p| p.name.as_str())
            .collect();
        if !poor.is_empty() {
            warnings.push(format!(
                "{} identified parameters have a standard deviation larger than their value (poorly determined): {}",
                poor.len(),
                short(&poor)
            ));
        }
        if let Some(v) = &self.validation {
            if v.after_stats.position_rms_mm > v.before_stats.position_rms_mm {
                warnings.push(format!(
                    "the validation error grew ({:.4} → {:.4} mm RMS)",
                    v.before_stats.position_rms_mm, v.after_stats.position_rms_mm
                ));
            }
        }
        let flagged = self.identification.outliers.len() + self.validation.as_ref().map_or(0, |v| v.outliers.len());
        if flagged > 0 {
            warnings.push(format!("{flagged} poses flagged as outliers (residual beyond 3σ)"));
        }
        self.verdict = if !failed.is_empty() {
            failed.extend(warnings);
            Verdict {
                status: Status::Failed,
                reasons: failed,
            }
        } else if !warnings.is_empty() {
            Verdict {
                status: Status::UsableWithWarnings,
                reasons: warnings,
            }
        } else {
            Verdict {
                status: Status::Calibrated,
                reasons: Vec::new(),
            }
        };
    }

    /// The report as one self-contained HTML page (inline CSS and SVG, no external resources).
    pub fn to_html(&self) -> Result<String, String> {
        let mut h = String::new();
        h.push_str("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">");
        let _ = write!(h, "<title>kinecal calibration report: {}</title>", esc(&self.model));
        h.push_str(
            "<style>body{font-family:sans-serif;margin:24px;max-width:1180px;color:#222}\
             h1{font-size:22px}h2{font-size:18px;border-bottom:1px solid #ccc;padding-bottom:4px;margin-top:28px}\
             table{border-collapse:collapse;font-size:13px;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}\
             th{background:#f0f0f0}td.l,th.l{text-align:left}.plots{display:flex;flex-wrap:wrap;gap:8px}\
             .plots svg{border:1px solid #ddd}.muted{color:#888}.warn{color:#b00}</style></head><body>\n",
        );
        let _ = writeln!(h, "<h1>Calibration report: {}</h1>", esc(&self.model));
        let (colour, label) = match self.verdict.status {
            Status::Calibrated => ("#1a7f37", "Calibrated"),
            Status::UsableWithWarnings => ("#9a6700", "Usable with warnings"),
            Status::Failed => ("#b00", "FAILED — do not use this model"),
        };
        let _ = write!(
            h,
            "<div id=\"verdict\" style=\"border:2px solid {colour};padding:8px 12px;margin:8px 0\"><b style=\"color:{colour};font-size:18px\">Verdict: {label}</b>"
        );
        if !self.verdict.reasons.is_empty() {
            h.push_str("<ul>");
            for r in &self.verdict.reasons {
                let _ = write!(h, "<li>{}</li>", esc(r));
            }
            h.push_str("</ul>");
        }
        h.push_str("</div>\n<h2>Summary</h2>\n<table>");
        let kv = |h: &mut String, k: &str, v: String| {
            let _ = write!(h, "<tr><th class=\"l\">{k}</th><td class=\"l\">{v}</td></tr>");
        };
        kv(&mut h, "identification data", esc(&self.identification.source));
        if let Some(v) = &self.validation {
            kv(&mut h, "validation data", esc(&v.source));
        }
        kv(&mut h, "poses (identification)", self.identification.before_stats.poses.to_string());
        kv(
            &mut h,
            "method",
            format!(
                "{} — {} after {} iterations",
                esc(&self.method),
                if self.converged {
                    "converged"
                } else {
                    "<span class=\"warn\">NOT converged</span>"
                },
                self.iterations
            ),
        );
        kv(
            &mut h,
            "weights (noise σ)",
            format!("{} mm, {} deg", sig(self.noise_mm_deg.0), sig(self.noise_mm_deg.1)),
        );
        kv(&mut h, "σ̂₀ (a-posteriori, 1 = noise model right)", sig(self.sigma0));
        kv(
            &mut h,
            "identified / free parameters",
            format!("{} of {} (rank of the identification Jacobian)", self.rank, self.free),
        );
        kv(&mut h, "condition number (column-scaled)", format!("{:.3e}", self.condition));
        h.push_str("</table>\n<h2>Errors before and after calibration</h2>\n<table><tr><th class=\"l\">set</th><th class=\"l\">model</th><th>poses</th><th>mean mm</th><th>RMS mm</th><th>max mm</th><th>rotation mean deg</th><th>rotation max deg</th><th>tool axis mean deg</th><th>tool axis max deg</th></tr>");
        let mut sets = vec![("identification", &self.identification)];
        if let Some(v) = &self.validation {
            sets.push(("validation", v));
        }
        for (name, s) in &sets {
            for (which, st) in [("nominal", &s.before_stats), ("calibrated", &s.after_stats)] {
                let o = |v: Option<f64>| v.map(sig).unwrap_or_else(|| "—".into());
                let _ = write!(
                    h,
                    "<tr><td class=\"l\">{name}</td><td class=\"l\">{which}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    st.poses,
                    sig(st.position_mean_mm),
                    sig(st.position_rms_mm),
                    sig(st.position_max_mm),
                    o(st.orientation_mean_deg),
                    o(st.orientation_max_deg),
                    o(st.tool_axis_mean_deg),
                    o(st.tool_axis_max_deg)
                );
            }
        }
        h.push_str("</table>\n");
        let before = (200, 80, 60);
        let after = (30, 90, 200);
        for (name, s) in &sets {
            let _ = write!(h, "<h2>Per-pose errors, {name} set</h2>\n<div class=\"plots\">");
            let (pb, pa) = (&s.before.position, &s.after.position);
            h.push_str(&plot::per_pose_chart(
                &format!("Position error, {name} (mm)"),
                "mm",
                &[
                    Series {
                        name: "nominal",
                        color: before,
                        values: pb,
                    },
                    Series {
                        name: "calibrated",
                        color: after,
                        values: pa,
                    },
                ],
            )?);
            h.push_str(&plot::per_pose_chart(
                &format!("Position error after calibration, {name} (mm)"),
                "mm",
                &[Series {
                    name: "calibrated",
                    color: after,
                    values: pa,
                }],
            )?);
            let ob: Vec<f64> = s.before.orientation.iter().flatten().map(|v| v.to_degrees()).collect();
            let oa: Vec<f64> = s.after.orientation.iter().flatten().map(|v| v.to_degrees()).collect();
            if !ob.is_empty() {
                h.push_str(&plot::per_pose_chart(
                    &format!("Orientation error, {name} (deg)"),
                    "deg",
                    &[
                        Series {
                            name: "nominal",
                            color: before,
                            values: &ob,
                        },
                        Series {
                            name: "calibrated",
                            color: after,
                            values: &oa,
                        },
                    ],
                )?);
                h.push_str(&plot::per_pose_chart(
                    &format!("Orientation error after calibration, {name} (deg)"),
                    "deg",
                    &[Series {
                        name: "calibrated",
                        color: after,
                        values: &oa,
                    }],
                )?);
            }
            h.push_str(&plot::histogram(
                &format!("Histogram of position errors after calibration, {name}"),
                "position error (mm)",
                &[Series {
                    name: "calibrated",
                    color: after,
                    values: pa,
                }],
                20,
            )?);
            if !oa.is_empty() {
                h.push_str(&plot::histogram(
                    &format!("Histogram of orientation errors after calibration, {name}"),
                    "orientation error (deg)",
                    &[Series {
                        name: "calibrated",
                        color: after,
                        values: &oa,
                    }],
                    20,
                )?);
            }
            h.push_str("</div>\n");
        }
        h.push_str("<h2>Outliers (a residual component beyond 3σ after calibration)</h2>\n");
        let mut any = false;
        for (name, s) in &sets {
            if s.outliers.is_empty() {
                continue;
            }
            if !any {
                h.push_str(
                    "<table><tr><th class=\"l\">set</th><th>pose (row, from 0)</th><th>score (σ)</th><th>position mm</th><th>orientation deg</th></tr>",
                );
                any = true;
            }
            for o in &s.outliers {
                let _ = write!(
                    h,
                    "<tr><td class=\"l\">{name}</td><td>{}</td><td>{:.2}</td><td>{}</td><td>{}</td></tr>",
                    o.pose,
                    o.score,
                    sig(o.position_mm),
                    o.orientation_deg.map(sig).unwrap_or_else(|| "—".into())
                );
            }
        }
        h.push_str(if any { "</table>\n" } else { "<p>None.</p>\n" });
        h.push_str("<h2>Identifiability</h2>\n");
        let _ = write!(
            h,
            "<p>Rank {} of {} free parameters; condition number {:.3e}.</p><p><b>Redundant</b> (combinations of parameters earlier in priority order, not identified): {}</p>",
            self.rank,
            self.free,
            self.condition,
            if self.redundant.is_empty() { "none".into() } else { esc(&self.redundant.join(", ")) }
        );
        if !self.no_effect.is_empty() {
            let _ = write!(
                h,
                "<p><b>Without effect</b> on these measurements: {}</p>",
                esc(&self.no_effect.join(", "))
            );
        }
        if !self.singular_values.is_empty() {
            h.push_str("<div class=\"plots\">");
            let smax = self.singular_values.iter().copied().fold(0.0, f64::max).max(f64::MIN_POSITIVE);
            let lg: Vec<f64> = self.singular_values.iter().map(|s| (s / smax).max(1e-17).log10()).collect();
            h.push_str(&plot::per_pose_chart_with_x(
                "Singular values σ/σmax of the column-scaled Jacobian (log10, floor 1e-17)",
                "index",
                "log10 σ/σmax",
                &lg,
            )?);
            h.push_str("</div>");
        }
        h.push_str("<h2>Parameters</h2>\n<p class=\"muted\">Identified change of each error coordinate (local coordinates of the model's error parameters) with its standard deviation σ̂₀·√diag((AᵀA)⁻¹). Redundant parameters move with the minimum-norm solution; their values are not individually meaningful and have no standard deviation.</p><table><tr><th class=\"l\">parameter</th><th class=\"l\">group</th><th>value</th><th>std. dev.</th><th class=\"l\">unit</th><th class=\"l\">status</th></tr>");
        for p in &self.params {
            let status = match p.status {
                ParamStatus::Identified => "identified",
                ParamStatus::Redundant => "redundant",
                ParamStatus::NoEffect => "no effect",
                ParamStatus::Fixed => "fixed",
            };
            let cls = if p.status == ParamStatus::Identified {
                ""
            } else {
                " class=\"muted\""
            };
            let _ = write!(
                h,
                "<tr{cls}><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{status}</td></tr>",
                esc(&p.name),
                esc(&p.group),
                sig(p.value),
                if p.status == ParamStatus::Identified { sig(p.std_dev) } else { "—".into() },
                p.unit
            );
        }
        h.push_str("</table>\n<p class=\"muted\">Generated by kinecal.</p></body></html>\n");
        Ok(h)
    }
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A number with 4 significant digits (scientific notation outside 1e-3..1e5).
fn sig(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.3e}")
    } else {
        let d = (3 - a.log10().floor() as i32).max(0) as usize;
        format!("{v:.d$}")
    }
}
