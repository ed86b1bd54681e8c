//! The user's workflow on any [`Mechanism`]: virtual prototypes, error statistics, outliers and
//! compensation. The command line (`kinecal simulate | identify | validate | compensate`) is a
//! thin layer over these functions; they take `&dyn Mechanism` or generic mechanisms, so every
//! mechanism kind a model file can describe works the same way.
use crate::error::{CalibError, KinError};
use crate::io::model_file::InputSpec;
use crate::measure::{self, Measurement, Noise, Observation};
use crate::model::{Mechanism, Task};
use crate::params::Unit;
use crate::se3::{self, Pose};
use nalgebra::{DVector, Vector3};
use rand::{Rng, RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::Serialize;
use std::f64::consts::PI;

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

/// Errors of `model` at every measurement.
pub fn pose_errors<M: Mechanism + ?Sized>(model: &M, data: &[Measurement]) -> Result<PoseErrors, CalibError> {
    let mut position = Vec::with_capacity(data.len());
    let mut orientation = Vec::with_capacity(data.len());
    let mut tool_axis = Vec::with_capacity(data.len());
    for (i, m) in data.iter().enumerate() {
        let t = model.forward(&m.q).map_err(|source| CalibError::Kinematics { pose: i, source })?;
        let (p, o) = measure::errors(&m.obs, &t);
        position.push(p);
        orientation.push(o);
        tool_axis.push(match &m.obs {
            Observation::Pose(meas) => Some(tool_axis_angle(meas, &t)),
            _ => None,
        });
    }
    Ok(PoseErrors {
        position,
        orientation,
        tool_axis,
    })
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

/// The range an input is drawn from: its limits, or ±π rad / ±100 mm without limits.
pub fn input_range(input: &InputSpec) -> (f64, f64) {
    input.limits.unwrap_or(match input.unit {
        Unit::Angle => (-PI, PI),
        _ => (-100.0, 100.0),
    })
}

/// `n` random input vectors, uniform within [`input_range`] of each input.
pub fn random_inputs<R: Rng>(inputs: &[InputSpec], n: usize, rng: &mut R) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| {
            inputs
                .iter()
                .map(|i| {
                    let (lo, hi) = input_range(i);
                    rng.random_range(lo..hi)
                })
                .collect()
        })
        .collect()
}

/// `n` input vectors at which `model` assembles: the mechanism's own draw
/// ([`Mechanism::sample_configurations`]: closed loops draw platform poses uniformly in their
/// workspace and solve the inverse kinematics) when it has one, else inputs uniform within
/// [`input_range`] ([`random_inputs`], drawn from `rng` directly). Reproducible: for a mechanism
/// that draws its own, one `u64` is drawn from `rng` as its seed.
pub fn random_configurations<M: Mechanism + ?Sized, R: Rng>(
    model: &M,
    inputs: &[InputSpec],
    n: usize,
    rng: &mut R,
) -> Result<Vec<Vec<f64>>, KinError> {
    // Asking for no configurations tells whether the mechanism draws its own, without using rng.
    if model.sample_configurations(0, 0).is_none() {
        return Ok(random_inputs(inputs, n, rng));
    }
    let seed: u64 = rng.random();
    model
        .sample_configurations(n, seed)
        .unwrap_or_else(|| Ok(random_inputs(inputs, n, rng)))
}

/// Position error (mm) and the error of the commanded orientation (rad) of a reached tool pose
/// against its target: the full rotation angle for [`Task::Full`], the angle between the tool
/// z-axes for [`Task::PositionAndAxis`] (the rotation about the tool axis is not commanded).
pub fn commanded_error(task: Task, target: &Pose, reached: &Pose) -> (f64, f64) {
    let e = se3::pose_error(target, reached);
    let angle = match task {
        Task::Full => se3::ang(&e).norm(),
        Task::PositionAndAxis => tool_axis_angle(target, reached),
    };
    (se3::lin(&e).norm(), angle)
}

/// Angle (rad) between the tool z-axes of two poses.
pub fn tool_axis_angle(a: &Pose, b: &Pose) -> f64 {
    let za = a.rotation * Vector3::z();
    let zb = b.rotation * Vector3::z();
    za.cross(&zb).norm().atan2(za.dot(&zb))
}

/// Reflector centres (mm) in the tool frame used for simulated three-reflector measurements:
/// their frame ([`measure::frame_from_reflectors`]) *is* the tool frame (centroid at the origin,
/// `M2 − M3` along x, `M1` on +y).
pub const REFLECTORS: [[f64; 3]; 3] = [[0.0, 60.0, 0.0], [40.0, -30.0, 0.0], [-40.0, -30.0, 0.0]];

/// The three reflector centres of [`REFLECTORS`] seen at tool pose `t`, each with Gaussian
/// position noise `sigma_mm` per axis (0: none).
pub fn reflector_centres<R: Rng>(t: &Pose, sigma_mm: f64, rng: &mut R) -> Result<[Vector3<f64>; 3], CalibError> {
    let normal = Normal::new(0.0, sigma_mm).map_err(|e| CalibError::InvalidOption(e.to_string()))?;
    let mut out = [Vector3::zeros(); 3];
    for (k, r) in REFLECTORS.iter().enumerate() {
        let p = t.transform_point(&Vector3::from(*r).into()).coords;
        let n = if sigma_mm > 0.0 {
            Vector3::new(normal.sample(rng), normal.sample(rng), normal.sample(rng))
        } else {
            Vector3::zeros()
        };
        out[k] = p + n;
    }
    Ok(out)
}

/// A virtual prototype: the nominal model with uniform random errors on the parameters `which`
/// (lengths in `±length_mm`, angles in `±angle_rad`). Returns the "true" model and the error.
pub fn virtual_prototype<M: Mechanism + Clone, R: Rng>(
    nominal: &M,
    which: &[usize],
    length_mm: f64,
    angle_rad: f64,
    rng: &mut R,
) -> (M, DVector<f64>) {
    let delta = crate::simulate::random_errors(nominal, rng, length_mm, angle_rad, Some(which));
    (crate::simulate::perturbed(nominal, &delta), delta)
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
    let mut res = Vec::with_capacity(data.len());
    for (i, m) in data.iter().enumerate() {
        let t = model.forward(&m.q).map_err(|source| CalibError::Kinematics { pose: i, source })?;
        res.push((measure::residual(&m.obs, &t), measure::errors(&m.obs, &t)));
    }
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
    Ok(out)
}

/// Why a target could not be compensated.
#[derive(Debug, Clone, PartialEq)]
pub struct CompensationError {
    /// Index of the target.
    pub target: usize,
    /// The reason.
    pub source: KinError,
}

/// Add whole turns to each revolute input so that it is as close as possible to `reference`
/// (the seed, or 0) while inside its limits when the limits allow it.
fn wrap_near(inputs: &[InputSpec], q: &mut [f64], reference: &[f64]) {
    for (k, (i, v)) in inputs.iter().zip(q.iter_mut()).enumerate() {
        if i.unit != Unit::Angle {
            continue;
        }
        let r = reference.get(k).copied().unwrap_or(0.0);
        let turns = ((r - *v) / (2.0 * PI)).round();
        let mut best = *v + turns * 2.0 * PI;
        if let Some((lo, hi)) = i.limits {
            if best < lo - 1e-9 || best > hi + 1e-9 {
                // The nearest equivalent angle is outside the limits: take the nearest one inside.
                let candidates = (-3..=3)
                    .map(|t| best + t as f64 * 2.0 * PI)
                    .filter(|c| *c >= lo - 1e-9 && *c <= hi + 1e-9);
                if let Some(c) = candidates.min_by(|a, b| (a - r).abs().total_cmp(&(b - r).abs())) {
                    best = c;
                }
            }
        }
        *v = best;
    }
}

fn check_limits(inputs: &[InputSpec], q: &[f64]) -> Result<(), KinError> {
    for (i, v) in inputs.iter().zip(q) {
        if let Some((lo, hi)) = i.limits {
            if *v < lo - 1e-9 || *v > hi + 1e-9 {
                let (f, u) = if i.unit == Unit::Angle { (180.0 / PI, "deg") } else { (1.0, "mm") };
                return Err(KinError::OutOfWorkspace(format!(
                    "{} = {:.3} {u} outside its limits [{:.3}, {:.3}] {u}",
                    i.name,
                    v * f,
                    lo * f,
                    hi * f
                )));
            }
        }
    }
    Ok(())
}

/// Number of random fall-back starting points of [`compensate`]'s inverse kinematics.
pub const COMPENSATION_STARTS: usize = 24;

/// Actuator commands that bring the (calibrated) `model`'s tool to each target pose: inverse
/// kinematics from `seeds[k]` when given (e.g. the nominal commands), else from the previous
/// solution, else from the zero configuration and [`COMPENSATION_STARTS`] fixed pseudo-random
/// points within the limits (tried in that order until one gives a valid solution; only the first
/// when the mechanism's inverse ignores its seed, [`Mechanism::inverse_ignores_seed`]). Revolute
/// inputs are moved by whole turns to the equivalent angle nearest the seed (or 0) within their
/// limits; every solution is checked against the limits and against the forward kinematics
/// (1e-6 mm, 1e-8 rad; for a 5-DOF mechanism, [`Task::PositionAndAxis`], the position and the tool
/// axis only: see [`commanded_error`]). `progress` is called after each target.
pub fn compensate<M: Mechanism + ?Sized>(
    model: &M,
    inputs: &[InputSpec],
    targets: &[Pose],
    seeds: Option<&[Vec<f64>]>,
    progress: &dyn Fn(usize),
) -> Result<Vec<Vec<f64>>, CompensationError> {
    let n = inputs.len();
    let mut out: Vec<Vec<f64>> = Vec::with_capacity(targets.len());
    // Deterministic fall-back starting points: the zero configuration, then random points
    // within the limits (a fixed seed, so results do not change from run to run).
    let mut fixed_starts: Vec<Vec<f64>> = vec![vec![0.0; n]];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x6b696e65);
    fixed_starts.extend(random_inputs(inputs, COMPENSATION_STARTS, &mut rng));
    for (k, target) in targets.iter().enumerate() {
        let mut starts: Vec<Vec<f64>> = Vec::new();
        if let Some(s) = seeds.and_then(|s| s.get(k)) {
            starts.push(s.clone());
        }
        if let Some(prev) = out.last() {
            starts.push(prev.clone());
        }
        starts.extend(fixed_starts.iter().cloned());
        if model.inverse_ignores_seed() {
            // One attempt says all: other starting points would give the same answer.
            starts.truncate(1);
        }
        let mut last_err = KinError::Unreachable("no starting point".into());
        // A solution outside the limits says more than a failed convergence: report it first.
        let mut limit_err: Option<KinError> = None;
        let mut found = None;
        for s in starts.iter().filter(|s| s.len() == n) {
            match model.inverse(target, Some(s)) {
                Ok(mut q) => {
                    wrap_near(inputs, &mut q, seeds.and_then(|x| x.get(k)).map_or(&[][..], |x| x.as_slice()));
                    let reached = model.forward(&q).map(|t| commanded_error(model.task(), target, &t));
                    match reached {
                        Ok((dp, dw)) if dp < 1e-6 && dw < 1e-8 => match check_limits(inputs, &q) {
                            Ok(()) => {
                                found = Some(q);
                                break;
                            }
                            Err(e) => limit_err = Some(e),
                        },
                        Ok((dp, dw)) => {
                            last_err = KinError::Unreachable(format!("inverse kinematics ended {dp:.3e} mm / {dw:.3e} rad from the target"))
                        }
                        Err(e) => last_err = e,
                    }
                }
                Err(e) => last_err = e,
            }
        }
        match found {
            Some(q) => out.push(q),
            None => {
                let tried = starts.len();
                let from = if tried == 1 {
                    String::new()
                } else {
                    format!(" from {tried} starting points")
                };
                let limit_err = limit_err.map(|e| match e {
                    KinError::OutOfWorkspace(m) => KinError::OutOfWorkspace(format!("no solution within the limits{from} (one had {m})")),
                    e => e,
                });
                let source = match limit_err.unwrap_or(last_err) {
                    KinError::NoConvergence { residual, .. } => KinError::Unreachable(format!(
                        "inverse kinematics found no solution{from} (residual {residual:.3e}); the target is probably outside the workspace"
                    )),
                    e => e,
                };
                return Err(CompensationError { target: k, source });
            }
        }
        progress(k);
    }
    Ok(out)
}

/// The target poses of a data set (pose observations only).
pub fn target_poses(data: &[Measurement]) -> Result<Vec<Pose>, usize> {
    data.iter()
        .enumerate()
        .map(|(i, m)| match &m.obs {
            Observation::Pose(t) => Ok(*t),
            Observation::Position(_) | Observation::Points(_) => Err(i),
        })
        .collect()
}

/// Default noise when neither the command line nor the model file gives one.
pub fn default_noise() -> Noise {
    Noise::default()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::builtin::irb120;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn compensation_inverts_forward_within_limits() {
        let m = irb120();
        let inputs = crate::io::model_file::MechanismSpec::Serial(m.clone()).inputs();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let qs: Vec<Vec<f64>> = random_inputs(&inputs, 10, &mut rng)
            .into_iter()
            .map(|q| q.iter().map(|v| v * 0.5).collect())
            .collect();
        let targets: Vec<Pose> = qs.iter().map(|q| m.forward(q).unwrap()).collect();
        let seeds: Vec<Vec<f64>> = qs.iter().map(|q| q.iter().map(|v| v + 0.05).collect()).collect();
        let sol = compensate(&m, &inputs, &targets, Some(&seeds), &|_| {}).unwrap();
        for (q, t) in sol.iter().zip(&targets) {
            let e = se3::pose_error(t, &m.forward(q).unwrap());
            assert!(e.norm() < 1e-8);
        }
        let far = vec![se3::translation(5000.0, 0.0, 0.0)];
        let err = compensate(&m, &inputs, &far, None, &|_| {}).unwrap_err();
        assert_eq!(err.target, 0);
        assert!(matches!(err.source, KinError::Unreachable(_)), "{:?}", err.source);
    }

    #[test]
    fn revolute_values_wrap_to_the_turn_nearest_the_seed_within_limits() {
        let d = PI / 180.0;
        let inp = |lo: f64, hi: f64| InputSpec {
            name: "q".into(),
            unit: Unit::Angle,
            limits: Some((lo * d, hi * d)),
        };
        let inputs = [inp(-400.0, 400.0), inp(-110.0, 70.0), inp(-400.0, 400.0)];
        let mut q = [350.0 * d, 300.0 * d, -10.0 * d];
        wrap_near(&inputs, &mut q, &[0.0, 0.0, 355.0 * d]);
        let deg: Vec<f64> = q.iter().map(|v| (v / d * 1e9).round() / 1e9).collect();
        assert_eq!(deg, vec![-10.0, -60.0, 350.0]);
        // Prismatic inputs are never wrapped.
        let lin = [InputSpec {
            name: "d".into(),
            unit: Unit::Length,
            limits: Some((0.0, 1.0)),
        }];
        let mut x = [7.0];
        wrap_near(&lin, &mut x, &[]);
        assert_eq!(x, [7.0]);
    }

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
