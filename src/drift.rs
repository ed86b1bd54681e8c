//! Staying calibrated: whether a few re-measured poses still agree with a calibration
//! ([`check()`]), and an update of the calibration from a few new poses ([`update()`]).
//!
//! Both start from a [`Prior`]: the calibrated model, the covariance of its identified parameters
//! and the noise the measurements are judged against.
//!
//! # The prediction a check judges against
//! At the new poses the calibration predicts the measurement with two uncertainties: the
//! parameters' covariance `P` carried to the pose (`J·P·Jᵀ`) and the measurement noise `Σ`. With
//! `P = L·Lᵀ` and the rows weighted by the noise (`A = Σ^{-1/2}·J`, `e = Σ^{-1/2}·r`), the
//! statistic over all rows is `T = eᵀ(I + A·L·Lᵀ·Aᵀ)⁻¹e`, χ² with as many degrees of freedom as
//! rows when the machine is as calibrated. It is computed as a least-squares problem in
//! square-root form: the prior as rows `I·z = 0` over whitened coordinates `z` (the parameters'
//! change is `L·z`), stacked over the new rows `A·L·z = e`; `T` is the minimum of
//! `|z|² + |e − A·L·z|²`. Each pose's own statistic uses its block of the same matrix. The check
//! judges `T` together with each pattern's drop below (a drift of one pattern concentrates in a
//! few coefficients, which `T` spreads over as many degrees of freedom as rows), at one threshold
//! that holds the false-alarm rate for all of them together ([`rate`]).
//!
//! # Judged by what the calibration left
//! A real machine leaves more than its instrument's noise after a geometric calibration
//! (compliance, backlash, temperature), and not as Gaussian noise: most poses closer, a few much
//! further. New rows are weighted by the stated noise times `σ̂₀` where that is above 1
//! ([`judged_noise`]), and the distributions of every statistic (over all rows, each pattern's
//! drop, each pose, an update's releases and its final test) are simulated with each new pose's
//! noise drawn from the residual rows the calibration's own poses left ([`reference`]), which the
//! calibrated model file carries, and hold where they are above those of Gaussian rows (a
//! reference of a few poses under-represents a normal tail: rows are never judged more strictly
//! than as Gaussian at the judged noise). Without them (a calibration whose residual the stated
//! noise explains) the rows are taken as Gaussian.
//!
//! # Patterns
//! What changed is looked for among named patterns ([`patterns`]): an input's offset (a joint
//! offset), a uniform scale of the machine's lengths about its base (temperature), the tool's
//! position, and every single parameter. Each is a direction in the model's parameters; released
//! (its prior dropped, its size free), it lowers `T` by `Δ`. A pattern explains the change when
//! `Δ` is beyond the χ² quantile of its size at the false-alarm rate divided by the number of
//! patterns tried (so that noise releases nothing), and the best is the one that leaves the least,
//! `T − Δ + k·ln(rows)` for a pattern of `k` coefficients (Schwarz's criterion: a pattern of more
//! coefficients is named only where it explains clearly more).
//!
//! # An instrument's rows
//! A check takes seat and ballbar (or draw-wire) rows as it takes a tracker's: the artifact,
//! put back somewhere unknown, is placed by the new rows at the calibrated model and projected
//! out of them ([`artifact_rows`]); each artifact point's rows are then judged together, as a
//! pose's are.
//!
//! # Where to measure a check
//! Any few poses detect a drift; naming it takes poses at which the patterns act differently.
//! [`plan_check_poses`] chooses, among candidate configurations, those at which a check is
//! least likely to name one pattern for another ([`check_plan`]).
//!
//! # The update
//! [`update()`] minimises the same sum — the prior's rows and the new rows — iterated to
//! convergence on the non-linear model (Gauss–Newton on the stacked rows, each step the square-root
//! recursive least squares of [`crate::identify::rls_solve`]). Where the new poses contradict the
//! prior, the best pattern is released and the fit repeated, as long as a release is significant.
pub mod artifact_rows;
pub mod check;
pub mod check_plan;
pub mod patterns;
pub mod rate;
pub mod reference;
mod stacked;
pub mod update;

pub use artifact_rows::ArtifactRows;
pub use check::{check, Alternative, CheckOptions, CheckReport, OnePose, PatternFit, PatternTest, PoseCheck};
pub use check_plan::{plan_check_poses, CheckPlan, CheckPlanOptions, PairSeparation};
pub use patterns::{patterns, Pattern, PatternKind};
pub use reference::Reference;
pub use update::{update, Moved, SetAside, Update, UpdateOptions};

use crate::error::CalibError;
use crate::io::model_file::ModelFile;
use crate::measure::Noise;
use nalgebra::DMatrix;

/// Default false-alarm rate of [`check()`] and of each release of [`update()`].
pub const DEFAULT_FALSE_ALARM: f64 = 0.01;

/// An earlier calibration as prior knowledge: its model, the covariance of its parameters and the
/// measurement noise.
#[derive(Debug, Clone)]
pub struct Prior {
    /// The calibrated model (its parameters' values are the estimate).
    pub model: ModelFile,
    /// Covariance (p × p, model units: mm, rad) of the change of the model's parameters, in the
    /// local coordinates of [`crate::model::Mechanism::retract`] at the calibrated model; zero
    /// rows for parameters held as drawn (as [`crate::identify::Identification::covariance`]).
    pub covariance: DMatrix<f64>,
    /// The noise new rows are judged against: the calibration's stated noise, times its
    /// a-posteriori σ of unit weight `σ̂₀` where that is above 1 ([`judged_noise`]).
    pub noise: Noise,
    /// What the calibration's own poses left, by which new rows are judged: the calibrated model
    /// file's `[covariance] residuals`, written where the calibration left more than its stated
    /// noise (`σ̂₀` above 1); `None`: new rows are judged as Gaussian at [`Self::noise`].
    pub reference: Option<Reference>,
}

impl Prior {
    /// The prior a calibration gives: its calibrated model file, the covariance of its
    /// identification and its noise. Only for calibrations whose fitted mechanism is the
    /// calibrated model file's (tracker data); an instrument calibration's artifact points are
    /// not in the model file ([`Prior::check_size`] fails then).
    ///
    /// The identification's covariance is in the coordinates of the fitted mechanism; the model
    /// file rebuilt has the same predictions but its own coordinates at the calibrated geometry
    /// (a chain's errors restart from zero there): the covariance is carried over
    /// ([`covariance_in`]) at configurations drawn from seed 1.
    pub fn from_calibration(cal: &crate::calibrate::Calibration) -> Result<Prior, CalibError> {
        let model = cal.model_file.build();
        if cal.identification.model.input_names().len() != model.input_names().len() {
            // An instrument's fit: its model takes the artifact point as one more input, and
            // the written file's covariance is over the machine's own parameters.
            return Prior::from_model_file(&cal.model_file);
        }
        let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(1);
        let q = crate::simulate::random_configurations(&*model, &cal.model_file.inputs(), CARRY_CONFIGURATIONS, &mut rng)
            .map_err(|source| CalibError::Kinematics { pose: 0, source })?;
        let covariance = covariance_in(&*model, &*cal.identification.model, &cal.identification.covariance, &q)?;
        Ok(Prior {
            model: cal.model_file.clone(),
            covariance,
            noise: judged_noise(&cal.identification.noise, cal.identification.sigma0),
            reference: cal
                .model_file
                .covariance
                .as_ref()
                .and_then(|c| Reference::from_residuals(&c.residuals)),
        })
    }

    /// The prior a calibrated model file carries (written by `kinecal identify`): its geometry,
    /// the covariance of its parameters and its noise.
    ///
    /// The file's `[covariance]` is over the identified parameters of the model the file builds;
    /// as [`Prior::from_calibration`] does, it is carried over ([`covariance_in`], at
    /// configurations drawn from seed 1) onto every parameter the model can take alone, the
    /// minimum-norm share of each: the same predictions, and the same prior as the calibration
    /// in memory gives.
    pub fn from_model_file(file: &ModelFile) -> Result<Prior, CalibError> {
        let Some(c) = &file.covariance else {
            return Err(CalibError::InvalidOption(format!(
                "the model file '{}' carries no covariance of its parameters ([covariance]: a calibrated model file written by kinecal identify does)",
                file.name
            )));
        };
        let model = file.build();
        let names: Vec<String> = model.params().into_iter().map(|p| p.name).collect();
        let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(1);
        let q = crate::simulate::random_configurations(&*model, &file.inputs(), CARRY_CONFIGURATIONS, &mut rng)
            .map_err(|source| CalibError::Kinematics { pose: 0, source })?;
        Ok(Prior {
            model: file.clone(),
            covariance: covariance_in(&*model, &*model, &c.over(&names), &q)?,
            noise: judged_noise(&file.noise.unwrap_or_default(), c.sigma0),
            reference: Reference::from_residuals(&c.residuals),
        })
    }

    /// The covariance must match the model's parameters.
    pub fn check_size(&self, p: usize) -> Result<(), CalibError> {
        let (r, c) = self.covariance.shape();
        if r != p || c != p {
            return Err(CalibError::InvalidOption(format!(
                "the calibration's covariance is {r} × {c}, its model '{}' has {p} parameters (a covariance of an instrument calibration's artifact points is not one of the machine's)",
                self.model.name
            )));
        }
        if self.covariance.iter().any(|v| !v.is_finite()) {
            return Err(CalibError::InvalidOption(
                "the calibration's covariance holds non-finite values".into(),
            ));
        }
        Ok(())
    }

    /// A square-root factor `L` (p × r) of the covariance, `P = L·Lᵀ`, from the eigen-decomposition
    /// of its diagonally scaled form (lengths and angles mixed); eigenvalues below 1e-12 of the
    /// largest are dropped.
    pub fn factor(&self) -> DMatrix<f64> {
        let p = self.covariance.nrows();
        let s: Vec<f64> = (0..p).map(|i| self.covariance[(i, i)].max(0.0).sqrt()).collect();
        let support: Vec<usize> = (0..p).filter(|&i| s[i] > 0.0).collect();
        let k = support.len();
        if k == 0 {
            return DMatrix::zeros(p, 0);
        }
        let n = DMatrix::from_fn(k, k, |i, j| {
            let (a, b) = (support[i], support[j]);
            self.covariance[(a, b)] / (s[a] * s[b])
        });
        let eig = n.symmetric_eigen();
        let top = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
        let keep: Vec<usize> = (0..k).filter(|&i| eig.eigenvalues[i] > 1e-12 * top).collect();
        let mut l = DMatrix::zeros(p, keep.len());
        for (c, &i) in keep.iter().enumerate() {
            let f = eig.eigenvalues[i].sqrt();
            for (row, &a) in support.iter().enumerate() {
                l[(a, c)] = eig.eigenvectors[(row, i)] * f * s[a];
            }
        }
        l
    }
}

/// The noise a calibration's new rows are judged against: its stated `noise`, times `sigma0`
/// (its a-posteriori σ of unit weight, by which its covariance is scaled too) where `sigma0`
/// exceeds one. A real machine leaves more than its instrument's noise after a geometric
/// calibration (compliance, backlash, temperature: errors the model does not describe); poses
/// measured again leave as much, and judged against the instrument's noise alone they would
/// always say "drifted". Otherwise the stated noise stands: new rows are never judged by less.
pub fn judged_noise(noise: &Noise, sigma0: f64) -> Noise {
    if sigma0.is_finite() && sigma0 > 1.0 {
        noise.scaled(sigma0)
    } else {
        *noise
    }
}

/// `file` carrying `covariance` (over its model's parameters), `noise` and the residuals of
/// `reference` (in units of that noise) for a later [`Prior::from_model_file`]: `[covariance]` over the parameters with a variance, the others
/// held as [`crate::io::model_file::Held::Fixed`] (they stay as they are).
pub fn with_covariance(file: ModelFile, covariance: &DMatrix<f64>, noise: &Noise, reference: Option<&Reference>) -> ModelFile {
    let params = file.build().params();
    let (with, without): (Vec<usize>, Vec<usize>) = (0..params.len()).partition(|&k| covariance[(k, k)] > 0.0);
    let matrix = DMatrix::from_fn(with.len(), with.len(), |i, j| {
        let (a, b) = (with[i].min(with[j]), with[i].max(with[j]));
        covariance[(a, b)]
    });
    let c = crate::io::model_file::Covariance {
        names: with.iter().map(|&k| params[k].name.clone()).collect(),
        units: with.iter().map(|&k| params[k].unit).collect(),
        matrix,
        sigma0: 1.0,
        residuals: reference.map(|r| r.residuals().to_vec()).unwrap_or_default(),
        held: without
            .iter()
            .map(|&k| (params[k].name.clone(), crate::io::model_file::Held::Fixed))
            .collect(),
    };
    ModelFile {
        noise: Some(*noise),
        covariance: Some(c),
        ..file
    }
}

pub use crate::predict::CARRY_CONFIGURATIONS;

/// The covariance `covariance` of `fitted`'s parameters carried to `model`'s (the same machine,
/// the same predictions, other coordinates): [`crate::predict::carry_covariance`] onto every
/// parameter `model` can take alone (not [`crate::model::Mechanism::assembly_breaking`]), the
/// minimum-norm carrier over them.
pub fn covariance_in(
    model: &dyn crate::model::Mechanism,
    fitted: &dyn crate::model::Mechanism,
    covariance: &DMatrix<f64>,
    configurations: &[Vec<f64>],
) -> Result<DMatrix<f64>, CalibError> {
    let held = model.assembly_breaking();
    let onto: Vec<usize> = (0..model.n_params()).filter(|c| !held.contains(c)).collect();
    crate::predict::carry_covariance(model, fitted, covariance, configurations, &onto)
}

/// The standard normal quantile (Acklam's rational approximation, relative error below 1.2e-9).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383_577_518_672_69e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [7.784695709041462e-3, 3.224671290700398e-1, 2.445134137142996, 3.754408661907416];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5]) / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    const LOW: f64 = 0.02425;
    if p <= 0.0 {
        f64::NEG_INFINITY
    } else if p >= 1.0 {
        f64::INFINITY
    } else if p < LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p <= 1.0 - LOW {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    }
}

/// The χ² quantile with `k` degrees of freedom at probability `p` (Wilson–Hilferty).
pub fn chi2_quantile(k: usize, p: f64) -> f64 {
    chi2_at_z(k, normal_quantile(p))
}

/// The value of the χ² distribution with `k` degrees of freedom that lies `z` standard normal
/// deviates above it (Wilson–Hilferty; the inverse of [`chi2_z`]).
pub fn chi2_at_z(k: usize, z: f64) -> f64 {
    let k = k.max(1) as f64;
    let a = 2.0 / (9.0 * k);
    (k * (1.0 - a + z * a.sqrt()).powi(3)).max(0.0)
}

/// How many standard normal deviates `x` lies above the χ² distribution with `k` degrees of
/// freedom (Wilson–Hilferty).
pub fn chi2_z(x: f64, k: usize) -> f64 {
    let k = k.max(1) as f64;
    let a = 2.0 / (9.0 * k);
    ((x.max(0.0) / k).cbrt() - (1.0 - a)) / a.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles() {
        assert!((normal_quantile(0.975) - 1.959964).abs() < 1e-6);
        assert!((normal_quantile(0.01) + 2.326348).abs() < 1e-6);
        // χ²₃₀ at 99 %: 50.892; χ²₁ at 99 %: 6.635 (Wilson–Hilferty within 1 %).
        assert!((chi2_quantile(30, 0.99) - 50.892).abs() < 0.05);
        assert!((chi2_quantile(1, 0.99) - 6.635).abs() < 0.07);
        assert!((chi2_z(chi2_quantile(12, 0.99), 12) - normal_quantile(0.99)).abs() < 1e-9);
    }
}
