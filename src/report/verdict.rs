//! The verdict of a calibration: what separates a wrong result from an imperfect one.
//!
//! | verdict | evidence it needs |
//! |---|---|
//! | failed | the result is wrong or cannot be trusted: no convergence; a residual that is not finite; a residual far beyond the stated noise ([`SIGMA0_FAIL`]) *together with* hardly any improvement over the nominal model (on held-out poses, else held-out instrument rows, else the identification poses; [`FAIL_IMPROVEMENT`]; between it and [`CLEAR_IMPROVEMENT`] a warning) or a residual larger than any error the tolerances allow; corrections far beyond the tolerances ([`FAR_BEYOND`]) in every split of the redundant parameters and frames ([`ToleranceCheck`]); starts that reach different predictions (set by `calibrate`) |
//! | usable with warnings | the result improves the machine but leaves something to look at: a residual above the stated noise ([`SIGMA0_WARN`]: real machines leave one after a geometric calibration), fewer residual rows beyond the identified parameters than there are parameters (the fit can follow the data, and nothing checks it), corrections somewhat beyond the tolerances in every split, a held-out error that grew (held-out poses; a validation file's instrument rows, its own artifacts placed by its rows; known distances between its seats) or stayed far above the identification's, poses set aside as blunders, more outliers than chance gives |
//! | calibrated | converged, residual consistent with the stated noise, nothing of the above |
//!
//! A large σ̂₀ alone never fails a calibration: a real robot always leaves more residual than its
//! tracker's noise (lost motion, compliance, temperature), and σ̂₀ against a default noise cannot
//! tell that apart from a wrong model. What tells them apart is whether the calibration explains
//! the data (a clear improvement on held-out poses) with a machine the tolerances allow.
use super::{CalibrationReport, ParamStatus, STRONG_CORRELATION};
use crate::io::model_file::Tolerances;
use crate::measure::Noise;
use serde::Serialize;

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
    /// Not usable: evidence that the result is wrong (see the module docs).
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

/// A residual this many times the stated noise is large enough to be a mistake (a wrong unit or
/// column order, a model of another machine): it fails the calibration when the calibration
/// does not also clearly improve on the nominal model, or leaves a residual beyond the
/// tolerances; with a clear improvement it is a warning.
pub const SIGMA0_FAIL: f64 = 10.0;

/// Probability that a Gaussian residual component lies beyond 3σ.
pub const CHANCE_BEYOND_3_SIGMA: f64 = 0.0027;
/// σ̂₀ above this is a warning: errors the model does not describe remain, or the stated noise
/// is optimistic.
pub const SIGMA0_WARN: f64 = 3.0;

/// A calibration clearly improves on the nominal model when its RMS position error (held-out
/// poses when there are, else the identification poses) is at most this fraction of the nominal
/// model's, or its mean orientation error is. Real geometric calibrations do far better (the
/// IRB 120's real tracker data: 0.64 held-out, the simulations: below 0.1).
pub const CLEAR_IMPROVEMENT: f64 = 0.8;

/// With a residual beyond [`SIGMA0_FAIL`], a calibration whose RMS position error (or mean
/// orientation error) is at most this fraction of the nominal model's still improves the machine:
/// too weak to be clear, but evidence that the model is of this machine and the data are in
/// order, so a warning, not a failure. (The real IRB 120's 30 position poses of one reflector:
/// held-out 0.9792 → 0.7912 mm, 0.81 of the nominal.) Above it the calibration fails.
pub const FAIL_IMPROVEMENT: f64 = 0.9;

/// Held-out poses that keep more than this many times the identification poses' RMS residual
/// (or the stated position noise, if larger) are a warning: they see parameters the
/// identification poses could not (the IRB 120's real data: 0.57 against 0.53 mm).
pub const HELD_OUT_GAP: f64 = 3.0;

/// Corrections this many times the tolerance, in the split that keeps them smallest, fail the
/// calibration (a model of another machine); between 1 and this, a warning.
pub const FAR_BEYOND: f64 = 2.0;

/// A correction that stays beyond its tolerance in every equivalent split of the parameters.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Beyond {
    /// Parameter name.
    pub name: String,
    /// Its value in the consistent split that keeps the corrections smallest (display unit).
    pub value: f64,
    /// `mm` or `deg`.
    pub unit: String,
    /// |value| / tolerance in that split, which may move the corrections as far as the noise
    /// could have (two standard deviations along any combination, `calibrate::tolerances`).
    pub ratio: f64,
}

/// The corrections judged against the tolerances in the split of redundant parameters and
/// frames that keeps them smallest (`calibrate::tolerances`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ToleranceCheck {
    /// Largest |correction| / tolerance in that split (≤ 1: a machine within its tolerances
    /// explains the data).
    pub ratio: f64,
    /// The corrections beyond their tolerance there, largest ratio first.
    pub beyond: Vec<Beyond>,
}

/// `names` joined, at most six of them.
fn short<S: AsRef<str>>(names: &[S]) -> String {
    let names: Vec<&str> = names.iter().map(AsRef::as_ref).collect();
    if names.len() > 6 {
        format!("{} … ({} in all)", names[..6].join(" "), names.len())
    } else {
        names.join(" ")
    }
}

impl CalibrationReport {
    /// Judge the calibration ([`CalibrationReport::verdict`]) against the noise the user stated
    /// (`stated`; with re-estimated weights the estimate is compared with it) and the model's
    /// tolerances (through [`CalibrationReport::tolerance_check`] when `calibrate` computed it,
    /// else on the reported values): see the module docs.
    pub fn assess(&mut self, stated: &Noise, tolerances: &Tolerances) {
        let mut failed = Vec::new();
        let mut warnings = Vec::new();
        self.flags.clear();
        let ratio = [
            self.noise_mm_deg.0 / stated.position,
            self.noise_mm_deg.1.to_radians() / stated.orientation,
        ]
        .into_iter()
        .filter(|r| r.is_finite())
        .fold(1.0, f64::max);
        let excess = self.sigma0 * ratio;
        // The set the improvement is judged on: held-out poses when there are, else held-out
        // instrument rows (their artifacts placed by their own rows), else the identification's.
        let orientation_ratio = |s: &super::SetErrors| match (s.before_stats.orientation_mean_deg, s.after_stats.orientation_mean_deg) {
            (Some(b), Some(a)) if b > 0.0 => a / b,
            _ => f64::INFINITY,
        };
        let of = |s: &super::SetErrors| (s.before_stats.position_rms_mm, s.after_stats.position_rms_mm, orientation_ratio(s));
        let (set, (before_rms, after_rms, orientation_ratio)) = match (&self.validation, &self.held_out) {
            (Some(v), _) if v.after_stats.poses > 0 => ("held-out", of(v)),
            (_, Some(h)) if h.rows > 0 => ("held-out", (h.before_rms_mm, h.after_rms_mm, f64::INFINITY)),
            _ => ("identification", of(&self.identification)),
        };
        let improvement = after_rms / before_rms;
        let clear = improvement <= CLEAR_IMPROVEMENT || orientation_ratio <= CLEAR_IMPROVEMENT;
        let improves = improvement <= FAIL_IMPROVEMENT || orientation_ratio <= FAIL_IMPROVEMENT;
        let left_mm = self.identification.after_stats.position_rms_mm;
        self.tolerance_verdict(tolerances, excess, &mut failed, &mut warnings);
        if let Some(why) = &self.stalled {
            failed.push(format!(
                "the identification never left the nominal model: every step it tried, down to the shortest, made the model fail ({why}); a model that cannot take the errors it is asked to identify (fix them in [calibration], kinecal identifiability), or a nominal model far from the machine measured"
            ));
        } else if !self.converged {
            failed.push(format!(
                "the identification did not converge after {} iterations (too few or badly spread poses, or a model that does not fit the data)",
                self.iterations
            ));
        }
        let reweighted = if ratio > 1.0 {
            format!(", re-estimated weights {ratio:.1}× the stated noise")
        } else {
            String::new()
        };
        if !excess.is_finite() {
            failed.push("the residual is not finite".into());
        } else if excess > SIGMA0_FAIL && !improves {
            failed.push(format!(
                "the residual is {excess:.1}× the stated noise (σ̂₀ {:.2}{reweighted}) and the calibration does not clearly improve on the nominal model ({set} RMS {before_rms:.4} → {after_rms:.4} mm): a wrong unit or column order, a model of another machine, or data in an unregistered frame",
                self.sigma0
            ));
        } else {
            if excess > SIGMA0_FAIL && !clear {
                warnings.push(format!(
                    "the calibration improves the {set} poses by only {:.0} % (RMS {before_rms:.4} → {after_rms:.4} mm) while the residual is {excess:.1}× the stated noise: too few or badly spread poses for the {} parameters identified (kinecal plan), or errors the model does not describe",
                    100.0 * (1.0 - improvement),
                    self.rank
                ));
            }
            if excess > SIGMA0_FAIL && left_mm > tolerances.length_mm {
                failed.push(format!(
                    "the residual left ({left_mm:.3} mm RMS, {excess:.1}× the stated noise) is larger than any error the model's tolerances allow ({} mm): a wrong unit or column order, a model of another machine, or data in an unregistered frame",
                    tolerances.length_mm
                ));
            } else if excess > SIGMA0_WARN {
                let advice = if self.serial_chain {
                    "lost motion and gravity compliance in the joints, which joint terms describe ([mechanism.joint_terms] in the model file, docs/joint-terms.md), temperature"
                } else {
                    "compliance, backlash, temperature"
                };
                warnings.push(format!(
                    "the residual is {excess:.1}× the stated noise (σ̂₀ {:.2}{reweighted}; {left_mm:.4} mm RMS left on the identification poses, {set} RMS {before_rms:.4} → {after_rms:.4} mm): real machines leave such a residual after a geometric calibration ({advice}), or the stated noise is optimistic (--noise-mm, --noise-deg)",
                    self.sigma0
                ));
            }
        }
        if self.redundancy < self.rank {
            warnings.push(format!(
                "only {} residual rows beyond the {} identified parameters: the fit can follow the data, σ̂₀ and the σ of the parameters rest on few numbers, and nothing checks the result; measure more poses (at least as many rows beyond the parameters as there are parameters)",
                self.redundancy, self.rank
            ));
        }
        self.parameter_flags();
        if let Some(v) = &self.validation {
            if v.after_stats.position_rms_mm > v.before_stats.position_rms_mm {
                warnings.push(format!(
                    "the validation error grew ({:.4} → {:.4} mm RMS)",
                    v.before_stats.position_rms_mm, v.after_stats.position_rms_mm
                ));
            } else if v.after_stats.poses > 0 && v.after_stats.position_rms_mm > HELD_OUT_GAP * left_mm.max(self.noise_mm_deg.0) {
                // A real machine leaves about the same residual on poses it was not fitted on; far
                // more means the held-out poses see what the identification poses did not.
                let unseen = if self.redundant.is_empty() {
                    String::new()
                } else {
                    format!(" (not identified from them: {})", short(&self.redundant))
                };
                warnings.push(format!(
                    "the held-out poses keep {:.4} mm RMS against {left_mm:.4} mm on the identification poses: parameters the identification poses cannot show act on the held-out ones{unseen}; measure poses that vary what these held fixed (with position data, the tool orientation: at one orientation a tool offset moves every point alike)",
                    v.after_stats.position_rms_mm
                ));
            }
        }
        self.held_out_verdict(left_mm, &mut warnings);
        if !self.blunders.is_empty() {
            let ids: Vec<String> = self.blunders.iter().map(|i| i.to_string()).collect();
            warnings.push(format!(
                "{} poses set aside as gross blunders (ids {}): check those readings",
                self.blunders.len(),
                short(&ids)
            ));
        }
        self.outlier_verdict(&mut warnings);
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

    /// Corrections against the tolerances: in the split that keeps them smallest
    /// ([`CalibrationReport::tolerance_check`]) when there is one, else as reported.
    fn tolerance_verdict(&mut self, tolerances: &Tolerances, excess: f64, failed: &mut Vec<String>, warnings: &mut Vec<String>) {
        let reported: Vec<Beyond> = self
            .params
            .iter()
            .filter(|p| p.status == ParamStatus::Identified && !crate::params::is_placement_group(&p.group))
            .filter_map(|p| {
                let t = match p.unit.as_str() {
                    "mm" => tolerances.length_mm,
                    "deg" => tolerances.angle_deg,
                    _ => return None,
                };
                (p.value.abs() > t).then(|| Beyond {
                    name: p.name.clone(),
                    value: p.value,
                    unit: p.unit.clone(),
                    ratio: p.value.abs() / t,
                })
            })
            .collect();
        let check = self.tolerance_check.clone().unwrap_or_else(|| ToleranceCheck {
            ratio: reported.iter().map(|b| b.ratio).fold(0.0, f64::max),
            beyond: reported.clone(),
        });
        let list = |b: &[Beyond]| {
            short(
                &b.iter()
                    .map(|b| format!("{} {:+.3} {}", b.name, b.value, b.unit))
                    .collect::<Vec<_>>(),
            )
        };
        let limits = format!("({} mm, {} deg)", tolerances.length_mm, tolerances.angle_deg);
        if check.ratio > FAR_BEYOND {
            // A fit down to the noise with such corrections: the link took up the difference.
            let advice = if excess <= SIGMA0_WARN {
                format!(
                    "the fit matches the data (σ̂₀ {:.3}): a model of another machine (check its dimensions; raise the tolerances if the machine really is this far from its drawing), or a combination of parameters the poses barely separate (fix one of them in [calibration] fixed, or add or spread poses)",
                    self.sigma0
                )
            } else if !self.radian_like_columns.is_empty() {
                format!(
                    "are the joint columns in the right unit? {} (else: is the model of this machine, are the columns in the right order?)",
                    self.radian_like_columns.join(", ")
                )
            } else {
                "is the model of this machine, and are the joint columns in the right order and unit? (if the machine really is this far from its drawing, raise [calibration] tolerance_mm / tolerance_deg in the model file)".to_string()
            };
            failed.push(format!(
                "corrections beyond the model's tolerances {limits}, in whatever split of the redundant parameters and frames: {}: {advice}",
                list(&check.beyond)
            ));
        } else if check.ratio > 1.0 {
            warnings.push(format!(
                "corrections up to {:.2}× the model's tolerances {limits}, in whatever split of the redundant parameters and frames: {}: check these parts of the machine, or raise the tolerances if it really is this far from its drawing",
                check.ratio,
                list(&check.beyond)
            ));
        } else if !reported.is_empty() {
            self.flags.push(format!(
                "reported corrections beyond the tolerances {limits}: {}: one split of parameters the data see only together (with the frames or each other); an equivalent split within the tolerances exists",
                list(&reported)
            ));
        }
    }

    /// Held-out instrument rows (a validation file's own artifacts, [`super::HeldOutPlacements`]):
    /// predicted worse than by the nominal model, or far worse than the identification rows, is a
    /// warning; so are known distances between held-out seats further off than the nominal's.
    fn held_out_verdict(&self, left_mm: f64, warnings: &mut Vec<String>) {
        let Some(h) = self.held_out.as_ref().filter(|h| h.rows > 0) else {
            return;
        };
        let (before, after) = (h.before_rms_mm, h.after_rms_mm);
        if after > before {
            warnings.push(format!(
                "the calibrated model predicts the held-out data ({}, each artifact placed by its own rows) worse than the nominal model ({before:.4} → {after:.4} mm RMS): it is not calibrated for what these rows see; identify on placements that span the ones held out, or with fewer free parameters",
                h.source
            ));
        } else if after > HELD_OUT_GAP * left_mm.max(self.noise_mm_deg.0) {
            warnings.push(format!(
                "the held-out data ({}) keep {after:.4} mm RMS against {left_mm:.4} mm on the identification rows (nominal {before:.4} mm): parameters the identification rows cannot show act on the held-out placements; measure placements that vary what these held fixed",
                h.source
            ));
        }
        if let Some((b, a)) = h.distance_error_rms_mm().filter(|(b, a)| a > b) {
            warnings.push(format!(
                "the known distances between held-out seats are further off with the calibrated model than with the nominal one (error {b:.4} → {a:.4} mm RMS): the calibration's scale does not hold there"
            ));
        }
    }

    /// Flags on the parameters: poorly determined, strongly correlated.
    fn parameter_flags(&mut self) {
        let poor: Vec<&str> = self
            .params
            .iter()
            .filter(|p| p.status == ParamStatus::Identified && p.std_dev > p.value.abs())
            .map(|p| p.name.as_str())
            .collect();
        if !poor.is_empty() {
            let line = format!(
                "{} identified parameters have a standard deviation larger than their value (not distinguished from zero by these data): {}",
                poor.len(),
                short(&poor)
            );
            self.flags.push(line);
        }
        if !self.correlated.is_empty() {
            let pairs: Vec<String> = self.correlated.iter().map(|(a, b, r)| format!("{a}/{b} {r:+.3}")).collect();
            self.flags.push(format!(
                "{} pairs of identified parameters correlated beyond ±{STRONG_CORRELATION}: {} (their sum or difference is better determined than each)",
                pairs.len(),
                short(&pairs)
            ));
        }
    }

    /// More outliers than chance gives is a warning; as many, a flag.
    fn outlier_verdict(&mut self, warnings: &mut Vec<String>) {
        // A residual component beyond 3σ happens to 0.27 % of components by chance, so to
        // 1 − 0.9973^c of poses with c components (1.6 % of full poses, 0.8 % of positions):
        // only more than 3 + twice that many flagged poses is a warning.
        let flagged = self.identification.outliers.len() + self.validation.as_ref().map_or(0, |v| v.outliers.len());
        let poses = self.identification.after_stats.poses + self.validation.as_ref().map_or(0, |v| v.after_stats.poses);
        let components = if self.identification.after_stats.orientation_mean_deg.is_some() {
            6
        } else {
            3
        };
        let chance = 1.0 - (1.0 - CHANCE_BEYOND_3_SIGMA).powi(components);
        if flagged as f64 > 3.0 + 2.0 * chance * poses as f64 {
            warnings.push(format!(
                "{flagged} of {poses} poses flagged as outliers (a residual component beyond 3σ; Gaussian noise flags about {:.1} %)",
                100.0 * chance
            ));
        } else if flagged > 0 {
            self.flags.push(format!(
                "{flagged} poses with a residual component beyond 3σ (as many as chance gives)"
            ));
        }
    }

    /// A warning for `reason`: "calibrated" becomes "usable with warnings" (a failed verdict
    /// stays failed); the reason is added last.
    pub fn warn(&mut self, reason: String) {
        if self.verdict.status == Status::Calibrated {
            self.verdict.status = Status::UsableWithWarnings;
        }
        self.verdict.reasons.push(reason);
    }

    /// Fail the verdict for `reason` (put first among the reasons), whatever it was.
    pub fn fail(&mut self, reason: String) {
        self.verdict.status = Status::Failed;
        self.verdict.reasons.insert(0, reason);
    }
}
