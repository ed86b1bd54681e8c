//! Validation: per-pose errors of a model against measurements, their statistics (one
//! [`ErrorStats`] for every command and report), the commanded-orientation error of 5-DOF
//! machines, and outliers.
use crate::error::CalibError;
use crate::measure::{self, Measurement, Observation};
use crate::model::{Mechanism, Task};
use crate::se3::{self, Pose};
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

/// Per-pose errors of a model against measurements: position error norm (mm) and rotation error
/// angle (rad; `None` for position measurements).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PoseErrors {
    /// `|p_meas − p_model|` per pose (mm).
    pub position: Vec<f64>,
    /// `|log(R_meas·R_modelᵀ)|` per pose (rad), when the pose was measured.
    pub orientation: Vec<Option<f64>>,
    /// Angle between the measured and the model's tool z-axes per pose (rad), when the pose was
    /// measured: the commanded orientation of a 5-DOF machine ([`Task::PositionAndAxis`]).
    pub tool_axis: Vec<Option<f64>>,
}

/// The forward kinematics of `model` at every measurement's inputs, in parallel; the first pose
/// (in data order) whose kinematics fail is the error.
pub fn forward_all<M: Mechanism + ?Sized>(model: &M, data: &[Measurement]) -> Result<Vec<Pose>, CalibError> {
    data.par_iter()
        .with_min_len(64)
        .enumerate()
        .map(|(i, m)| model.forward(&m.q).map_err(|source| CalibError::Kinematics { pose: i, source }))
        .collect::<Vec<_>>()
        .into_iter()
        .collect()
}

/// Errors of `model` at every measurement.
pub fn pose_errors<M: Mechanism + ?Sized>(model: &M, data: &[Measurement]) -> Result<PoseErrors, CalibError> {
    Ok(errors_at(&forward_all(model, data)?, data))
}

/// Errors of the predicted poses `reached` (one per measurement, e.g. from [`forward_all`])
/// against `data`.
pub fn errors_at(reached: &[Pose], data: &[Measurement]) -> PoseErrors {
    let mut position = Vec::with_capacity(data.len());
    let mut orientation = Vec::with_capacity(data.len());
    let mut tool_axis = Vec::with_capacity(data.len());
    for (t, m) in reached.iter().zip(data) {
        let (p, o) = measure::errors(&m.obs, t);
        position.push(p);
        orientation.push(o);
        tool_axis.push(match &m.obs {
            Observation::Pose(meas) => Some(tool_axis_angle(meas, t)),
            _ => None,
        });
    }
    PoseErrors {
        position,
        orientation,
        tool_axis,
    }
}

/// Summary statistics of [`PoseErrors`], in mm and degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Number of poses.
    pub poses: usize,
    /// Mean position error (mm).
    pub position_mean_mm: f64,
    /// RMS position error (mm).
    pub position_rms_mm: f64,
    /// Largest position error (mm).
    pub position_max_mm: f64,
    /// Mean orientation error (deg), when orientations were measured.
    pub orientation_mean_deg: Option<f64>,
    /// Largest orientation error (deg), when orientations were measured.
    pub orientation_max_deg: Option<f64>,
    /// Mean tool-axis direction error (deg), when orientations were measured.
    pub tool_axis_mean_deg: Option<f64>,
    /// Largest tool-axis direction error (deg), when orientations were measured.
    pub tool_axis_max_deg: Option<f64>,
}

impl ErrorStats {
    /// Statistics of per-pose errors.
    pub fn of(e: &PoseErrors) -> ErrorStats {
        let n = e.position.len().max(1) as f64;
        let o: Vec<f64> = e.orientation.iter().flatten().map(|v| v.to_degrees()).collect();
        let a: Vec<f64> = e.tool_axis.iter().flatten().map(|v| v.to_degrees()).collect();
        ErrorStats {
            poses: e.position.len(),
            position_mean_mm: e.position.iter().sum::<f64>() / n,
            position_rms_mm: (e.position.iter().map(|v| v * v).sum::<f64>() / n).sqrt(),
            position_max_mm: e.position.iter().copied().fold(0.0, f64::max),
            orientation_mean_deg: (!o.is_empty()).then(|| o.iter().sum::<f64>() / o.len() as f64),
            orientation_max_deg: (!o.is_empty()).then(|| o.iter().copied().fold(0.0, f64::max)),
            tool_axis_mean_deg: (!a.is_empty()).then(|| a.iter().sum::<f64>() / a.len() as f64),
            tool_axis_max_deg: (!a.is_empty()).then(|| a.iter().copied().fold(0.0, f64::max)),
        }
    }
}

impl std::fmt::Display for ErrorStats {
    /// `position mean 0.123 / RMS 0.150 / max 0.400 mm; orientation mean 0.010 / max 0.030 deg`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "position mean {:.4} / RMS {:.4} / max {:.4} mm",
            self.position_mean_mm, self.position_rms_mm, self.position_max_mm
        )?;
        if let (Some(m), Some(x)) = (self.orientation_mean_deg, self.orientation_max_deg) {
            write!(f, "; orientation mean {m:.5} / max {x:.5} deg")?;
        }
        Ok(())
    }
}

/// Position error (mm) and the error of the commanded orientation (rad) of a reached tool pose
/// against its target: the full rotation angle for [`Task::Full`], the angle between the tool
/// z-axes for [`Task::PositionAndAxis`] (the rotation about the tool axis is not commanded), 0
/// for [`Task::Position`] (no orientation is commanded); for [`Task::HeightAndAxis`] the height
/// error and the axis angle; for [`Task::PositionAndYaw`] the position error and the yaw
/// difference.
pub fn commanded_error(task: Task, target: &Pose, reached: &Pose) -> (f64, f64) {
    let e = se3::pose_error(target, reached);
    match task {
        Task::Full => (se3::lin(&e).norm(), se3::ang(&e).norm()),
        Task::PositionAndAxis => (se3::lin(&e).norm(), tool_axis_angle(target, reached)),
        Task::Position => (se3::lin(&e).norm(), 0.0),
        Task::HeightAndAxis => (se3::lin(&e).z.abs(), tool_axis_angle(target, reached)),
        Task::PositionAndYaw => (se3::lin(&e).norm(), se3::yaw_difference(target, reached).abs()),
    }
}

/// Angle (rad) between the tool z-axes of two poses.
pub fn tool_axis_angle(a: &Pose, b: &Pose) -> f64 {
    let za = a.rotation * Vector3::z();
    let zb = b.rotation * Vector3::z();
    za.cross(&zb).norm().atan2(za.dot(&zb))
}

/// A pose flagged as an outlier after identification.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outlier {
    /// Index of the pose in its data set.
    pub pose: usize,
    /// Largest standardised residual component `|r_k|/σ̂` of the pose.
    pub score: f64,
    /// Position error (mm).
    pub position_mm: f64,
    /// Orientation error (deg), if measured.
    pub orientation_deg: Option<f64>,
}

/// Poses whose residual has a component larger than `threshold` times the RMS of that kind of
/// component (position rows and orientation rows estimated separately) over the whole set —
/// e.g. `threshold = 3` flags residuals beyond 3σ. Components below 1e-6 mm / 1e-8 rad are never
/// flagged (noise-free data would otherwise flag round-off).
pub fn outliers<M: Mechanism + ?Sized>(model: &M, data: &[Measurement], threshold: f64) -> Result<Vec<Outlier>, CalibError> {
    Ok(outliers_at(&forward_all(model, data)?, data, threshold))
}

/// [`outliers`] of the predicted poses `reached` (one per measurement, e.g. from
/// [`forward_all`]).
pub fn outliers_at(reached: &[Pose], data: &[Measurement], threshold: f64) -> Vec<Outlier> {
    let res: Vec<_> = reached
        .iter()
        .zip(data)
        .map(|(t, m)| (measure::residual(&m.obs, t), measure::errors(&m.obs, t)))
        .collect();
    let (mut sp, mut np, mut so, mut no) = (0.0, 0usize, 0.0, 0usize);
    for (r, _) in &res {
        for (k, v) in r.iter().enumerate() {
            if k < 3 {
                sp += v * v;
                np += 1;
            } else {
                so += v * v;
                no += 1;
            }
        }
    }
    let sig_p = (sp / np.max(1) as f64).sqrt();
    let sig_o = (so / no.max(1) as f64).sqrt();
    let mut out = Vec::new();
    for (i, (r, (p, o))) in res.iter().enumerate() {
        let mut score: f64 = 0.0;
        for (k, v) in r.iter().enumerate() {
            let (sig, floor) = if k < 3 { (sig_p, 1e-6) } else { (sig_o, 1e-8) };
            if v.abs() > floor && sig > 0.0 {
                score = score.max(v.abs() / sig);
            }
        }
        if score > threshold {
            out.push(Outlier {
                pose: i,
                score,
                position_mm: *p,
                orientation_deg: o.map(f64::to_degrees),
            });
        }
    }
    out
}

/// Errors of one observed joint's readings against the model ([`Mechanism::observed_joints`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointErrors {
    /// The joint.
    pub name: String,
    /// Unit of the figures: `"deg"` or `"mm"`.
    pub unit: String,
    /// RMS of reading − model over the poses with readings.
    pub rms: f64,
    /// Largest |reading − model|.
    pub max: f64,
}

/// Per observed joint, how far its readings in `data` are from `model`'s values (degrees for
/// revolute, mm for prismatic joints); empty when the model has no observed joints or the data no
/// readings.
pub fn observed_joint_errors<M: Mechanism + ?Sized>(model: &M, data: &[Measurement]) -> Result<Vec<JointErrors>, CalibError> {
    let units = model.observed_joints();
    let with: Vec<(usize, &Measurement)> = data
        .iter()
        .enumerate()
        .filter(|(_, m)| m.joints.len() == units.len() && !units.is_empty())
        .collect();
    if with.is_empty() {
        return Ok(Vec::new());
    }
    let mut sums = vec![(0.0f64, 0.0f64); units.len()];
    for (i, m) in &with {
        let v = model
            .observed_joint_values(&m.q)
            .map_err(|source| CalibError::Kinematics { pose: *i, source })?;
        for (k, (r, x)) in m.joints.iter().zip(&v).enumerate() {
            let d = if units[k].1 == crate::params::Unit::Angle {
                crate::se3::wrap_angle(r - x).to_degrees()
            } else {
                r - x
            };
            sums[k].0 += d * d;
            sums[k].1 = sums[k].1.max(d.abs());
        }
    }
    Ok(units
        .iter()
        .zip(sums)
        .map(|((name, unit), (s2, max))| JointErrors {
            name: name.clone(),
            unit: if *unit == crate::params::Unit::Angle { "deg" } else { "mm" }.into(),
            rms: (s2 / with.len() as f64).sqrt(),
            max,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::builtin::irb120;
    use crate::simulate::random_inputs;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use std::f64::consts::PI;

    #[test]
    fn stats_and_outliers() {
        let e = PoseErrors {
            position: vec![1.0, 3.0],
            orientation: vec![Some(0.0), Some(PI / 180.0)],
            tool_axis: vec![Some(0.0), Some(0.5 * PI / 180.0)],
        };
        let s = ErrorStats::of(&e);
        assert_eq!(s.position_mean_mm, 2.0);
        assert!((s.position_rms_mm - 5.0_f64.sqrt()).abs() < 1e-15);
        assert_eq!(s.position_max_mm, 3.0);
        assert!((s.orientation_max_deg.unwrap() - 1.0).abs() < 1e-12);
        assert!((s.tool_axis_mean_deg.unwrap() - 0.25).abs() < 1e-12);
        // One grossly wrong measurement among good ones is flagged.
        let m = irb120();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let inputs = crate::io::model_file::MechanismSpec::Serial(m.clone()).inputs();
        let mut data: Vec<Measurement> = random_inputs(&inputs, 40, &mut rng)
            .into_iter()
            .enumerate()
            .map(|(i, q)| {
                let t = m.forward(&q).unwrap();
                let off = Vector3::new(0.01 * ((i * 7 % 5) as f64 - 2.0), 0.01, -0.01);
                Measurement {
                    joints: Vec::new(),
                    q,
                    obs: Observation::Position(t.translation.vector + off),
                }
            })
            .collect();
        if let Observation::Position(p) = &mut data[17].obs {
            p.x += 1.0;
        }
        let o = outliers(&m, &data, 3.0).unwrap();
        assert_eq!(o.iter().map(|o| o.pose).collect::<Vec<_>>(), vec![17]);
    }
}
