//! The accuracy a calibration predicts at poses nobody measured.
//!
//! A calibration leaves its parameters uncertain by their covariance `Σ` (`[covariance]` of the
//! calibrated model file, [`crate::io::model_file::Covariance`]). At a configuration `q` the
//! predicted tool pose moves with the parameters through the identification Jacobian
//! `J(q)` (position rows in mm, orientation rows in rad, [`crate::measure::residual_jacobian`]
//! of a pose), so its covariance is
//!
//! ```text
//! Σ_pose(q) = J(q) · Σ · J(q)ᵀ        (6 × 6: position mm², orientation rad²)
//! ```
//!
//! [`PoseAccuracy::position_mm`] is `sqrt(trace Σ_position)`: the RMS length of the 3-D
//! position error the calibration leaves at that pose (what the spread of calibrated models'
//! predictions there would show over repeated calibrations); [`PoseAccuracy::orientation_deg`]
//! likewise of the rotation. A measurement at that pose differs from the prediction also by the
//! instrument's noise: [`PredictedAccuracy::noise_position_mm`] (`√3·σ_position`), kept as a
//! separate figure (`kinecal check` adds the two).
//!
//! The poses are those of the model the file builds: in the measurement frame with the
//! measured tool where the file has `[frames]`.
use crate::error::CalibError;
use crate::io::model_file::ModelFile;
use crate::measure::{self, Noise, Observation};
use crate::model::Mechanism;
use nalgebra::{DMatrix, Matrix3, Matrix6};
use serde::Serialize;
use thiserror::Error;

/// Why a prediction could not be made.
#[derive(Debug, Error)]
pub enum PredictError {
    /// The model file carries no covariance (it was not written by `kinecal identify`).
    #[error("{0} has no [covariance]: only a calibrated model file written by kinecal identify predicts its accuracy")]
    NoCovariance(String),
    /// The covariance does not match the model's parameters.
    #[error("the covariance is {rows} × {cols}, the model has {params} parameters")]
    Shape {
        /// Rows of the covariance.
        rows: usize,
        /// Columns.
        cols: usize,
        /// Parameters of the model.
        params: usize,
    },
    /// A configuration with the wrong number of inputs.
    #[error("configuration {index}: {got} values, the model has {inputs} inputs")]
    Inputs {
        /// Which configuration.
        index: usize,
        /// Values given.
        got: usize,
        /// Inputs of the model.
        inputs: usize,
    },
    /// A target of a targets file without an orientation, or out of reach.
    #[error("{0}")]
    Targets(String),
    /// The model could not be evaluated at a configuration.
    #[error(transparent)]
    Kinematics(#[from] CalibError),
}

/// The predicted accuracy at one configuration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PoseAccuracy {
    /// The configuration (rad / mm, the model's input order).
    pub q: Vec<f64>,
    /// The predicted tool position (mm).
    pub position: [f64; 3],
    /// `sqrt(trace Σ_position)` (mm): RMS length of the 3-D position error the parameters'
    /// uncertainty leaves.
    pub position_mm: f64,
    /// `sqrt(λ_max(Σ_position))` (mm): the σ along the worst direction.
    pub position_worst_axis_mm: f64,
    /// `sqrt(trace Σ_orientation)` (degrees).
    pub orientation_deg: f64,
    /// `Σ_pose` (position mm, orientation rad; row-major 6 × 6).
    #[serde(skip)]
    pub covariance: Matrix6<f64>,
}

/// The predicted accuracy at a set of configurations, and the measurement noise beside it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PredictedAccuracy {
    /// Per configuration, in the order given.
    pub poses: Vec<PoseAccuracy>,
    /// The 3-D length of one measurement's position noise, `√3·σ_position` (mm): what a
    /// measurement adds to [`PoseAccuracy::position_mm`] (in quadrature).
    pub noise_position_mm: f64,
    /// The same of the orientation noise (degrees).
    pub noise_orientation_deg: f64,
}

impl PredictedAccuracy {
    /// Largest and RMS of [`PoseAccuracy::position_mm`] over the poses (mm); `(0, 0)` for none.
    pub fn position_summary(&self) -> (f64, f64) {
        let n = self.poses.len().max(1) as f64;
        let max = self.poses.iter().map(|p| p.position_mm).fold(0.0, f64::max);
        let rms = (self.poses.iter().map(|p| p.position_mm.powi(2)).sum::<f64>() / n).sqrt();
        (max, rms)
    }
}

/// Configurations a covariance is carried over at ([`carry_covariance`]): by
/// [`crate::drift::Prior::from_calibration`] and for the calibrated model file's `[covariance]`.
pub const CARRY_CONFIGURATIONS: usize = 40;

/// The covariance `covariance` of `fitted`'s parameters carried to `model`'s, the same machine
/// with the same predictions in other coordinates (a calibrated model file rebuilt: a chain's
/// errors restart from zero at the calibrated geometry, so its Jacobian is not the fitted one's):
/// `T·P·Tᵀ` with `T` the least-squares solution of `J_model·T = J_fitted` over the tool poses at
/// `configurations`, `T`'s rows on `model`'s parameters `onto` only (column-scaled, the
/// minimum-norm one where they are dependent; the other rows zero). Both then predict the same
/// covariance of the tool pose there, as far as `onto` spans what `fitted`'s uncertain
/// parameters move.
pub fn carry_covariance(
    model: &dyn Mechanism,
    fitted: &dyn Mechanism,
    covariance: &DMatrix<f64>,
    configurations: &[Vec<f64>],
    onto: &[usize],
) -> Result<DMatrix<f64>, CalibError> {
    let (p, pf) = (model.n_params(), fitted.n_params());
    if covariance.shape() != (pf, pf) {
        return Err(CalibError::InvalidOption(format!(
            "a covariance of {} × {} for {pf} parameters",
            covariance.nrows(),
            covariance.ncols()
        )));
    }
    if let Some(&c) = onto.iter().find(|&&c| c >= p) {
        return Err(CalibError::InvalidOption(format!("parameter {c} of a model of {p}")));
    }
    let rows = 6 * configurations.len();
    let (mut jm, mut jf) = (DMatrix::zeros(rows, p), DMatrix::zeros(rows, pf));
    for (i, q) in configurations.iter().enumerate() {
        let kin = |source| CalibError::Kinematics { pose: i, source };
        let (tm, am) = model.forward_with_jacobian(q).map_err(kin)?;
        let (tf, af) = fitted.forward_with_jacobian(q).map_err(kin)?;
        jm.view_mut((6 * i, 0), (6, p))
            .copy_from(&measure::residual_jacobian(&Observation::Pose(tm), &tm, &am));
        jf.view_mut((6 * i, 0), (6, pf))
            .copy_from(&measure::residual_jacobian(&Observation::Pose(tf), &tf, &af));
    }
    let norms: Vec<f64> = onto.iter().map(|&c| jm.column(c).norm()).collect();
    let scaled = DMatrix::from_fn(
        rows,
        onto.len(),
        |r, k| if norms[k] > 0.0 { jm[(r, onto[k])] / norms[k] } else { 0.0 },
    );
    let svd = scaled.svd(true, true);
    let top = svd.singular_values.iter().copied().fold(0.0, f64::max);
    let t = svd
        .solve(&jf, 1e-10 * top)
        .map_err(|e| CalibError::Numerical(format!("carrying the covariance over: {e}")))?;
    let mut full = DMatrix::zeros(p, pf);
    for (k, &c) in onto.iter().enumerate() {
        if norms[k] > 0.0 {
            full.row_mut(c).copy_from(&(t.row(k) / norms[k]));
        }
    }
    Ok(&full * covariance * full.transpose())
}

/// The covariance of the predicted pose at each configuration of `poses`: `model`'s parameters
/// with covariance `covariance` (over `model.params()`, mm and rad) carried through its
/// identification Jacobian ([module docs](self)); `noise` gives the separate measurement figure.
pub fn accuracy(
    model: &dyn Mechanism,
    covariance: &DMatrix<f64>,
    noise: &Noise,
    poses: &[Vec<f64>],
) -> Result<PredictedAccuracy, PredictError> {
    let p = model.n_params();
    if covariance.shape() != (p, p) {
        return Err(PredictError::Shape {
            rows: covariance.nrows(),
            cols: covariance.ncols(),
            params: p,
        });
    }
    let inputs = model.input_names().len();
    let mut out = Vec::with_capacity(poses.len());
    for (index, q) in poses.iter().enumerate() {
        if q.len() != inputs {
            return Err(PredictError::Inputs {
                index,
                got: q.len(),
                inputs,
            });
        }
        let (pose, jac) = model
            .forward_with_jacobian(q)
            .map_err(|source| CalibError::Kinematics { pose: index, source })?;
        crate::identify::check_jacobian(index, &jac)?;
        let a = measure::residual_jacobian(&Observation::Pose(pose), &pose, &jac);
        let s = &a * covariance * a.transpose();
        let sigma = Matrix6::from_fn(|i, j| 0.5 * (s[(i, j)] + s[(j, i)]));
        let position: Matrix3<f64> = sigma.fixed_view::<3, 3>(0, 0).into_owned();
        let orientation: Matrix3<f64> = sigma.fixed_view::<3, 3>(3, 3).into_owned();
        let worst = position.symmetric_eigenvalues().max().max(0.0);
        let t = pose.translation.vector;
        out.push(PoseAccuracy {
            q: q.clone(),
            position: [t.x, t.y, t.z],
            position_mm: position.trace().max(0.0).sqrt(),
            position_worst_axis_mm: worst.sqrt(),
            orientation_deg: orientation.trace().max(0.0).sqrt().to_degrees(),
            covariance: sigma,
        });
    }
    Ok(PredictedAccuracy {
        poses: out,
        noise_position_mm: 3f64.sqrt() * noise.position,
        noise_orientation_deg: 3f64.sqrt() * noise.orientation.to_degrees(),
    })
}

/// [`accuracy`] of a calibrated model file: its model, its `[covariance]` and its `[noise]`
/// (kinecal's default noise where it has none). `name` names the file in the error.
pub fn accuracy_of_file(file: &ModelFile, name: &str, poses: &[Vec<f64>]) -> Result<PredictedAccuracy, PredictError> {
    let c = file
        .covariance
        .as_ref()
        .ok_or_else(|| PredictError::NoCovariance(name.to_string()))?;
    let model = file.build();
    let params: Vec<String> = model.params().into_iter().map(|p| p.name).collect();
    let noise = file.noise.unwrap_or_else(crate::simulate::default_noise);
    accuracy(&*model, &c.over(&params), &noise, poses)
}

/// The rows of a CSV of predicted accuracy ([`write_csv`]): a header and one row per pose.
pub const CSV_HEADER: &str = "pose,x_mm,y_mm,z_mm,sigma_position_mm,sigma_worst_axis_mm,sigma_orientation_deg";

/// The predicted accuracy as CSV: one row per configuration, the predicted tool position (mm),
/// `sigma_position_mm` ([`PoseAccuracy::position_mm`]), `sigma_worst_axis_mm`,
/// `sigma_orientation_deg`; then the model's inputs in the file's units (`input_headers`,
/// `input_values`: degrees for revolute inputs, mm for prismatic ones).
pub fn csv(acc: &PredictedAccuracy, input_headers: &[String], input_values: impl Fn(&[f64]) -> Vec<f64>) -> String {
    use std::fmt::Write as _;
    let mut out = String::from(CSV_HEADER);
    for h in input_headers {
        out.push(',');
        out.push_str(h);
    }
    out.push('\n');
    for (k, p) in acc.poses.iter().enumerate() {
        let _ = write!(
            out,
            "{k},{:.4},{:.4},{:.4},{:.6},{:.6},{:.6}",
            p.position[0], p.position[1], p.position[2], p.position_mm, p.position_worst_axis_mm, p.orientation_deg
        );
        for v in input_values(&p.q) {
            let _ = write!(out, ",{v:.6}");
        }
        out.push('\n');
    }
    out
}

/// Configurations spread over a workspace box of `file`'s mechanism, as `kinecal plan` samples
/// it ([`crate::design::sample_candidates`]: a box of tool poses, a 5-DOF machine's platform
/// box, or the inputs within their limits for a mechanism without a box of its own).
pub fn configurations_in(file: &ModelFile, sampling: &crate::design::CandidateSampling) -> Result<Vec<Vec<f64>>, PredictError> {
    let (_, cands) = crate::design::sample_candidates(file, sampling, None)?;
    Ok(cands.candidates.into_iter().map(|c| c.q).collect())
}

/// The configurations of a targets or data set: its inputs where it has them, else its target
/// poses solved by `file`'s model ([`crate::compensate::compensate`]). `Err(i)` with the index of
/// a target that has no orientation, or that cannot be reached.
pub fn configurations_of(file: &ModelFile, data: &crate::io::data_file::DataSet) -> Result<Vec<Vec<f64>>, PredictError> {
    if data.has_inputs {
        return Ok(data.measurements.iter().map(|m| m.q.clone()).collect());
    }
    let targets = crate::compensate::target_poses(&data.measurements).map_err(|i| {
        PredictError::Targets(format!(
            "line {}: a target needs an orientation (qw,qx,qy,qz or roll,pitch,yaw), or the file the model's input columns",
            data.lines[i]
        ))
    })?;
    crate::compensate::compensate(&*file.build(), &file.inputs(), &targets, None, &|_| ()).map_err(|e| {
        PredictError::Targets(format!(
            "line {}: target {}: {}",
            data.lines[e.target], data.ids[e.target], e.source
        ))
    })
}
