//! Laser-tracker calibration of a serial robot, end to end: frame registration, the tool frame
//! from three reflectors, identification schemes, and held-out validation.
//!
//! # Frames
//! The tracker measures in its own frame `{W}`. The robot's base frame and the tool frame of the
//! reflectors are both unknown at first; the first dyad `T_{0,1}(0)` of the chain carries the
//! base (tracker ← joint 1), the last dyad the tool (flange ← reflector frame), so both are refined
//! by identification like every other dyad.
//!
//! # First guess ([`register`])
//! The SVD method of eq. (39)–(44) of the 5-DOF paper registers nominal and measured positions of
//! one tool point; the point's offset from the flange is unknown too, so kinecal alternates: SVD
//! registration with the current offset, then the offset and the translation by linear least
//! squares with the registration's rotation held — a few iterations converge. The tool
//! orientation follows as the chordal mean of `R_flangeᵀ·R_Wᵀ·R_measured`.
//!
//! # Schemes ([`Scheme`])
//! * `FramesOnly`: nominal geometry, only the base and tool dyads fitted (12 parameters for full
//!   pose, 9 for a position);
//! * `Full`: every dyad (the identifiable subset of `6(n+1)` coordinates: `4r + 2p + 6` for full
//!   pose, `4r + 2p + 3` for a position).
//!
//! # Weighting
//! Position rows are weighted by `1/σ_p`, orientation rows by `1/σ_θ`. On real data the
//! unmodelled error (compliance, gear play), not the tracker, dominates the residual, so by
//! default the two standard deviations are re-estimated from the residuals during the fit
//! (variance-component estimation, [`crate::identify::Options::reweight`]): each kind of row then
//! counts by how well the model can explain it.
use crate::error::CalibError;
use crate::identify::{self, Options};
use crate::io::tracker::TrackerData;
use crate::measure::{self, register_points, Measurement, Noise, Observation};
use crate::model::chain::SerialChain;
use crate::model::Mechanism;
use crate::se3::{self, Pose};
use crate::validate::{self, ErrorStats};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use serde::Serialize;
use std::time::Instant;

/// What is measured of the tool.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum ToolMeasurement {
    /// The full tool frame from the three reflectors (eq. (38)).
    FullPose,
    /// The position of one reflector (1-based).
    Reflector(usize),
    /// The full tool frame, fitted through the three reflector positions themselves (9 residual
    /// rows per pose: the tracker's own measurement model), validated as a frame.
    Reflectors,
}

/// Which parameters are fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Scheme {
    /// Nominal geometry; only the base and tool frames are fitted.
    FramesOnly,
    /// Full geometric calibration of every dyad.
    Full,
}

/// Statistics of the errors of `model` on `data` (see [`validate::ErrorStats`]).
pub fn error_stats<M: Mechanism + ?Sized>(model: &M, data: &[Measurement]) -> Result<ErrorStats, CalibError> {
    Ok(ErrorStats::of(&validate::pose_errors(model, data)?))
}

/// Result of [`register`]: the first guess of the base and tool frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Registration {
    /// Tracker ← robot base.
    pub base: Pose,
    /// Position of the registered tool point in the flange frame (mm).
    pub tool_point: Vector3<f64>,
    /// RMS distance between registered nominal and measured points (mm).
    pub rms: f64,
    /// Alternations used.
    pub iterations: usize,
}

/// Register the robot base in the tracker frame and locate one tool point on the flange from
/// measured positions of that point (see the module docs). Needs at least three poses whose
/// points are not on one line.
pub fn register(chain: &SerialChain, q: &[Vec<f64>], points: &[Vector3<f64>]) -> Result<Registration, CalibError> {
    if q.len() != points.len() || q.len() < 3 {
        return Err(CalibError::TooFewMeasurements {
            poses: q.len(),
            rows: 3 * q.len(),
            params: 9,
            needed: 3,
        });
    }
    let flanges: Vec<Pose> = q
        .iter()
        .enumerate()
        .map(|(i, qi)| chain.forward(qi).map_err(|source| CalibError::Kinematics { pose: i, source }))
        .collect::<Result<_, _>>()?;
    let mut y = Vector3::zeros();
    let mut base;
    let mut iterations = 0;
    for it in 0..200 {
        iterations = it + 1;
        let nominal: Vec<Vector3<f64>> = flanges.iter().map(|f| f.transform_point(&y.into()).coords).collect();
        base =
            register_points(&nominal, points).ok_or_else(|| CalibError::Numerical("registration: the tool points are collinear".into()))?;
        // points_i − R_W·p_i = R_W·R_i·y + p_W  (linear in y and p_W).
        let rw = se3::rotation_matrix(&base);
        let n = points.len();
        let mut a = DMatrix::zeros(3 * n, 6);
        let mut b = DVector::zeros(3 * n);
        for (i, (f, pt)) in flanges.iter().zip(points).enumerate() {
            let ri = se3::rotation_matrix(f);
            a.view_mut((3 * i, 0), (3, 3)).copy_from(&(rw * ri));
            a.view_mut((3 * i, 3), (3, 3)).copy_from(&Matrix3::identity());
            b.rows_mut(3 * i, 3).copy_from(&(pt - rw * f.translation.vector));
        }
        let sol = a
            .svd(true, true)
            .solve(&b, 1e-12)
            .map_err(|e| CalibError::Numerical(e.to_string()))?;
        let y_new = Vector3::new(sol[0], sol[1], sol[2]);
        let change = (y_new - y).norm();
        y = y_new;
        if change < 1e-9 {
            break;
        }
    }
    let nominal: Vec<Vector3<f64>> = flanges.iter().map(|f| f.transform_point(&y.into()).coords).collect();
    base = register_points(&nominal, points).ok_or_else(|| CalibError::Numerical("registration: the tool points are collinear".into()))?;
    let rms = (nominal
        .iter()
        .zip(points)
        .map(|(p, m)| (base.transform_point(&(*p).into()).coords - m).norm_squared())
        .sum::<f64>()
        / points.len() as f64)
        .sqrt();
    Ok(Registration {
        base,
        tool_point: y,
        rms,
        iterations,
    })
}

/// Chordal mean of rotations (projection of their sum onto SO(3)).
fn mean_rotation(rs: &[Matrix3<f64>]) -> Matrix3<f64> {
    let sum: Matrix3<f64> = rs.iter().sum();
    let svd = sum.svd(true, true);
    let (u, vt) = (svd.u.unwrap_or_else(Matrix3::identity), svd.v_t.unwrap_or_else(Matrix3::identity));
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    u * d * vt
}

/// Measurements of one kind from a tracker data set, for the poses selected by `keep`.
pub fn measurements(data: &TrackerData, what: ToolMeasurement, keep: impl Fn(i64) -> bool) -> Result<Vec<Measurement>, CalibError> {
    let mut out = Vec::new();
    for i in 0..data.len() {
        if !keep(data.idx[i]) {
            continue;
        }
        let [m1, m2, m3] = data.tool[i];
        let obs = match what {
            ToolMeasurement::FullPose | ToolMeasurement::Reflectors => Observation::Pose(
                measure::frame_from_reflectors(&m1, &m2, &m3)
                    .ok_or_else(|| CalibError::Numerical(format!("pose {}: the three reflectors are collinear", data.idx[i])))?,
            ),
            ToolMeasurement::Reflector(k) if (1..=3).contains(&k) => Observation::Position(data.tool[i][k - 1]),
            ToolMeasurement::Reflector(k) => return Err(CalibError::InvalidOption(format!("reflector {k} does not exist (1, 2 or 3)"))),
        };
        out.push(Measurement {
            joints: Vec::new(),
            q: data.joints[i].clone(),
            obs,
        });
    }
    Ok(out)
}

/// The reflector centres in the reflector frame (eq. (38)), averaged over every pose of the data
/// set (the reflectors are rigid on the tool).
pub fn reflector_offsets(data: &TrackerData) -> Result<[Vector3<f64>; 3], CalibError> {
    measure::reflector_offsets(&data.tool).ok_or_else(|| CalibError::Numerical("no poses, or three collinear reflectors".into()))
}

/// Three-point observations of the reflectors for the poses selected by `keep`.
pub fn reflector_measurements(data: &TrackerData, keep: impl Fn(i64) -> bool) -> Result<Vec<Measurement>, CalibError> {
    let offsets = reflector_offsets(data)?;
    Ok((0..data.len())
        .filter(|&i| keep(data.idx[i]))
        .map(|i| Measurement {
            joints: Vec::new(),
            q: data.joints[i].clone(),
            obs: Observation::Points((0..3).map(|k| (offsets[k], data.tool[i][k])).collect()),
        })
        .collect())
}

/// The nominal chain with base and tool dyads initialised from the measurements (see the module
/// docs): tracker ← base from the SVD registration, flange ← tool from the registered tool point
/// and, for full-pose data, the mean measured orientation.
pub fn initial_model(nominal: &SerialChain, data: &[Measurement]) -> Result<(SerialChain, Registration), CalibError> {
    let q: Vec<Vec<f64>> = data.iter().map(|m| m.q.clone()).collect();
    let points: Vec<Vector3<f64>> = data
        .iter()
        .map(|m| match &m.obs {
            Observation::Pose(t) => t.translation.vector,
            Observation::Position(p) => *p,
            Observation::Points(pts) => pts.iter().map(|(_, m)| *m).sum::<Vector3<f64>>() / pts.len().max(1) as f64,
            // The study's data are the tracker's: no instrument rows reach here.
            Observation::Seat(_) | Observation::Distance { .. } | Observation::Touch(_) => Vector3::from_element(f64::NAN),
        })
        .collect();
    let reg = register(nominal, &q, &points)?;
    let mut model = nominal.clone();
    model.set_initial_pose(0, reg.base * nominal.initial_poses()[0]);
    let rot = if matches!(data.first().map(|m| &m.obs), Some(Observation::Pose(_))) {
        let rw = se3::rotation_matrix(&reg.base);
        let rs: Vec<Matrix3<f64>> = data
            .iter()
            .zip(&q)
            .filter_map(|(m, qi)| match &m.obs {
                Observation::Pose(t) => nominal
                    .forward(qi)
                    .ok()
                    .map(|f| se3::rotation_matrix(&f).transpose() * rw.transpose() * se3::rotation_matrix(t)),
                _ => None,
            })
            .collect();
        // The nominal tool is the flange; the fitted tool is nominal tool · (R, y).
        mean_rotation(&rs)
    } else {
        Matrix3::identity()
    };
    let tool = nominal.tool() * se3::pose_from_matrix(&rot, &reg.tool_point);
    let n = nominal.n_joints();
    model.set_initial_pose(n, tool);
    Ok((model, reg))
}

/// Result of one calibration scheme.
#[derive(Debug, Clone, Serialize)]
pub struct SchemeResult {
    /// What was measured.
    pub measurement: ToolMeasurement,
    /// Which parameters were fitted.
    pub scheme: Scheme,
    /// Parameters identified (rank of the identification Jacobian on the free parameters).
    pub identified: usize,
    /// Free parameters.
    pub free: usize,
    /// Condition number of the column-scaled identification Jacobian on the identified subset.
    pub condition: f64,
    /// Solver iterations.
    pub iterations: usize,
    /// Whether the solver converged.
    pub converged: bool,
    /// Wall time of the identification (s).
    pub seconds: f64,
    /// Final noise model (re-estimated standard deviations: mm, and rad).
    pub noise: Noise,
    /// Identified parameters: (name, unit, value of the accumulated increment, standard deviation),
    /// in mm or rad, for the identifiable subset.
    pub parameters: Vec<(String, String, f64, f64)>,
    /// A-posteriori standard deviation of unit weight (1 when the weights match the residual).
    pub sigma0: f64,
    /// Errors on the identification poses.
    pub identification: ErrorStats,
    /// Errors on the held-out poses.
    pub validation: ErrorStats,
    /// The starting model: nominal geometry with the registered base and tool frames.
    #[serde(skip)]
    pub start: SerialChain,
    /// The free parameters, in priority order.
    #[serde(skip)]
    pub free_params: Vec<usize>,
    /// The full identification result: the calibrated model, history, identifiability,
    /// uncertainties.
    #[serde(skip)]
    pub fit: identify::Identification<SerialChain>,
}

/// Options of [`calibrate`].
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateOptions {
    /// Starting noise model (the weights before re-estimation).
    pub noise: Noise,
    /// Re-estimate the noise per row kind from the residuals (default true).
    pub reweight: bool,
}

impl Default for CalibrateOptions {
    fn default() -> Self {
        // 0.05 mm and 0.01° are typical tracker and three-reflector orientation accuracies; the
        // re-estimation replaces them by what the residual shows.
        CalibrateOptions {
            noise: Noise {
                position: 0.05,
                orientation: 0.01_f64.to_radians(),
                ..Noise::default()
            },
            reweight: true,
        }
    }
}

/// Run one scheme: initial frames from `train`, identification on `fit` (the same poses as
/// `train`, possibly observed differently, e.g. as reflector points), statistics on `train` and
/// `test`.
pub fn calibrate(
    nominal: &SerialChain,
    fit: &[Measurement],
    train: &[Measurement],
    test: &[Measurement],
    measurement: ToolMeasurement,
    scheme: Scheme,
    opts: &CalibrateOptions,
) -> Result<SchemeResult, CalibError> {
    let (start, _) = initial_model(nominal, train)?;
    let free: Vec<usize> = match scheme {
        Scheme::FramesOnly => start.frame_param_indices(),
        Scheme::Full => (0..start.n_params()).collect(),
    };
    let options = Options {
        noise: opts.noise,
        reweight: opts.reweight,
        free: Some(free.clone()),
        ..Options::default()
    };
    let t0 = Instant::now();
    let res = identify::identify(&start, fit, &options)?;
    let seconds = t0.elapsed().as_secs_f64();
    let params = start.params();
    let parameters = res
        .identifiability
        .identifiable
        .iter()
        .map(|&c| {
            (
                params[c].name.clone(),
                params[c].unit.symbol().to_string(),
                res.delta[c],
                res.std_dev[c],
            )
        })
        .collect();
    Ok(SchemeResult {
        parameters,
        sigma0: res.sigma0,
        measurement,
        scheme,
        identified: res.identifiability.rank,
        free: free.len(),
        condition: res.identifiability.condition,
        iterations: res.iterations.len(),
        converged: res.converged,
        seconds,
        noise: res.noise,
        identification: error_stats(&res.model, train)?,
        validation: error_stats(&res.model, test)?,
        start,
        free_params: free,
        fit: res,
    })
}

/// One calibration of [`general_path`].
#[derive(Debug, Clone, Serialize)]
pub struct GeneralRun {
    /// What is fitted: `"frame"`, `"3 points"` or `"reflector 1"`.
    pub fit: &'static str,
    /// Identified / free parameters (frames included).
    pub identified: usize,
    /// Free parameters.
    pub free: usize,
    /// Solver iterations.
    pub iterations: usize,
    /// The verdict (`calibrated`, `usable with warnings`, `failed`).
    pub status: &'static str,
    /// Held-out errors after calibration.
    pub validation: ErrorStats,
    /// Wall time of the calibration (s).
    pub seconds: f64,
}

/// The same data through the general path every user takes, for comparison with the schemes
/// above: the folder's exports joined by id ([`crate::io::exports::join_exports`]: joints,
/// `smr1..3.csv`, or `smr1.csv` alone), split by `rule`, and calibrated by
/// [`crate::calibrate::calibrate`] from the built-in IRB 120 model file with the frames
/// estimated from the data; three runs: the reflector frame, the three points, reflector 1's
/// position.
pub fn general_path(
    folder: &std::path::Path,
    rule: crate::io::split::SplitRule,
    noise: Noise,
) -> Result<Vec<GeneralRun>, crate::calibrate::CalibrateError> {
    use crate::calibrate::{calibrate, CalibrationOptions, ReflectorFit};
    use crate::io::exports::{join_exports, ExportFiles};
    use crate::io::model_file::{AngleUnit, LengthUnit};
    let model = crate::io::builtin::model_file("irb120").ok_or_else(|| CalibError::InvalidOption("no built-in irb120".into()))?;
    let files = |reflectors: &[usize]| ExportFiles {
        joints: folder.join("joints_deg.csv"),
        angles: AngleUnit::Deg,
        reflectors: reflectors.iter().map(|k| folder.join(format!("smr{k}.csv"))).collect(),
        references: Vec::new(),
        lengths: LengthUnit::Mm,
    };
    let three = join_exports(&files(&[1, 2, 3]), &model.inputs(), &folder.join("joined.csv"))?.data;
    let one = join_exports(&files(&[1]), &model.inputs(), &folder.join("joined-1.csv"))?.data;
    let mut runs = Vec::new();
    for (fit, data, reflectors) in [
        ("frame", &three, ReflectorFit::Frame),
        ("3 points", &three, ReflectorFit::Points),
        ("reflector 1", &one, ReflectorFit::Frame),
    ] {
        let (ident, valid) = crate::io::split::split(data, rule);
        let opts = CalibrationOptions {
            compare_terms: true,
            noise,
            reflectors,
            ..CalibrationOptions::default()
        };
        let t0 = Instant::now();
        let cal = calibrate(&model, &ident, Some(&valid), &opts)?;
        let seconds = t0.elapsed().as_secs_f64();
        let r = &cal.report;
        runs.push(GeneralRun {
            fit,
            identified: r.rank,
            free: r.free,
            iterations: r.iterations,
            status: r.verdict.status.as_str(),
            validation: r
                .validation
                .as_ref()
                .map(|v| v.after_stats)
                .ok_or_else(|| CalibError::InvalidOption("no validation pose".into()))?,
            seconds,
        });
    }
    Ok(runs)
}
