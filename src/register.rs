//! Frame registration: where the measurement frame and the tool stand, found from the data.
//!
//! A laser tracker measures in its own frame, anywhere around the machine, and the reflectors sit
//! at unknown offsets from the flange or platform. Before the nonlinear identification, kinecal
//! finds both frames of [`Framed`] (`T = X · M(q) · Y`) from the nominal model and the data alone:
//!
//! 1. **Correspondences.** Every observation gives points: a position observation its point; a pose
//!    observation its origin and three points 100 mm along its axes; a point-set observation its
//!    points. Point `k` of every pose is one fixed point `s_k` of the flange/platform frame.
//! 2. **Alternation** (closed form at each step): with the flange points `s_k` fixed, the frame `X`
//!    is the SVD registration of the predicted points `M(q_i)·s_k` onto the measured ones; with `X`
//!    fixed, each `s_k` is the linear least-squares solution `mean_i R_iᵀ(X⁻¹·m_ik − p_i)`.
//!    It starts from two guesses (the points on the flange, and the model file's tool frame) and
//!    keeps the better.
//! 3. Gauss–Newton on `X` and the points `s_k` together from the alternation's estimate (the
//!    alternation converges linearly, slowly where the nominal geometry is off; Newton finishes in
//!    a few steps); `Y` is the rigid frame of the points `s_k`. The calibration then refines both
//!    frames with the geometry.
//!
//! Nothing depends on where the tracker stood: data in any rigid frame (any rotation, kilometres
//! away) gives the same frames relative to the data, so the same identified geometry.
use crate::error::CalibError;
use crate::measure::{register_points, Measurement, Observation};
use crate::model::framed::{Framed, FRAME_PARAMS};
use crate::model::Mechanism;
use crate::se3::Pose;
use nalgebra::{DMatrix, DVector, Point3, Vector3};

/// Length (mm) of the axis points a pose observation contributes: rotations then weigh like
/// position errors at 100 mm from the tool origin.
const AXIS_POINT_MM: f64 = 100.0;
/// Alternation steps before the Gauss–Newton refinement (enough to enter its basin).
const ALTERNATION_STEPS: usize = 20;

/// Poses the closed-form alternation runs on at most (an evenly spread subset of larger sets).
const REGISTRATION_POSES: usize = 2000;

/// The frames found from the data.
#[derive(Debug, Clone, PartialEq)]
pub struct Registration {
    /// `X`: the mechanism's base in the measurement frame.
    pub measurement: Pose,
    /// `Y`: the measured tool frame in the flange/platform frame (for position data only its
    /// translation is meaningful).
    pub tool: Pose,
    /// RMS of the point residuals after registration on the nominal geometry (mm).
    pub rms_mm: f64,
    /// RMS of the other start's registration (mm): a large disagreement with `rms_mm` means the
    /// data or the model is suspect.
    pub other_start_rms_mm: f64,
}

/// The point correspondences of one pose: `(k, measured point)`, `k` the index of the fixed
/// flange point it belongs to.
fn correspondences(obs: &Observation, classes: &mut Vec<Vector3<f64>>) -> Vec<(usize, Vector3<f64>)> {
    let axis = |t: &Pose, e: Vector3<f64>| t.transform_point(&Point3::from(e)).coords;
    match obs {
        Observation::Position(p) => vec![(0, *p)],
        Observation::Pose(t) => {
            let e = [
                Vector3::zeros(),
                Vector3::x() * AXIS_POINT_MM,
                Vector3::y() * AXIS_POINT_MM,
                Vector3::z() * AXIS_POINT_MM,
            ];
            e.iter().enumerate().map(|(k, v)| (k, axis(t, *v))).collect()
        }
        // Instrument rows are relative to unknown artifact points: no correspondence.
        Observation::Seat(_) | Observation::Distance { .. } | Observation::Touch(_) => Vec::new(),
        Observation::Points(pts) => pts
            .iter()
            .map(|(r, m)| {
                let k = match classes.iter().position(|c| (c - r).norm() < 1e-9) {
                    Some(k) => k,
                    None => {
                        classes.push(*r);
                        classes.len() - 1
                    }
                };
                (k, *m)
            })
            .collect(),
    }
}

/// The nominal tool points of each class for a tool frame `y` (what the alternation starts from).
fn class_points(obs: &Observation, classes: &[Vector3<f64>], y: &Pose) -> Vec<Vector3<f64>> {
    let at = |e: Vector3<f64>| y.transform_point(&Point3::from(e)).coords;
    match obs {
        Observation::Position(_) => vec![at(Vector3::zeros())],
        Observation::Pose(_) => [
            Vector3::zeros(),
            Vector3::x() * AXIS_POINT_MM,
            Vector3::y() * AXIS_POINT_MM,
            Vector3::z() * AXIS_POINT_MM,
        ]
        .map(at)
        .to_vec(),
        Observation::Points(_) => classes.iter().map(|c| at(*c)).collect(),
        Observation::Seat(_) | Observation::Distance { .. } | Observation::Touch(_) => Vec::new(),
    }
}

struct Problem {
    /// Flange poses of the nominal model, one per measurement.
    flange: Vec<Pose>,
    /// `(pose, class, measured point)`.
    points: Vec<(usize, usize, Vector3<f64>)>,
    classes: usize,
}

impl Problem {
    fn rms(&self, x: &Pose, s: &[Vector3<f64>]) -> f64 {
        let sum: f64 = self
            .points
            .iter()
            .map(|(i, k, m)| {
                (x.transform_point(&Point3::from(self.flange[*i].transform_point(&Point3::from(s[*k])).coords))
                    .coords
                    - m)
                    .norm_squared()
            })
            .sum();
        (sum / self.points.len().max(1) as f64).sqrt()
    }

    /// Alternate SVD registration and the linear solve for the flange points from `s`.
    fn alternate(&self, mut s: Vec<Vector3<f64>>) -> Option<(Pose, Vec<Vector3<f64>>, f64)> {
        let mut x = Pose::identity();
        let mut last = f64::INFINITY;
        for _ in 0..ALTERNATION_STEPS {
            let src: Vec<Vector3<f64>> = self
                .points
                .iter()
                .map(|(i, k, _)| self.flange[*i].transform_point(&Point3::from(s[*k])).coords)
                .collect();
            let dst: Vec<Vector3<f64>> = self.points.iter().map(|(_, _, m)| *m).collect();
            x = register_points(&src, &dst)?;
            let xinv = x.inverse();
            let mut sum = vec![Vector3::zeros(); self.classes];
            let mut count = vec![0usize; self.classes];
            for (i, k, m) in &self.points {
                let f = &self.flange[*i];
                let local = f.rotation.inverse() * (xinv.transform_point(&Point3::from(*m)).coords - f.translation.vector);
                sum[*k] += local;
                count[*k] += 1;
            }
            for k in 0..self.classes {
                if count[k] > 0 {
                    s[k] = sum[k] / count[k] as f64;
                }
            }
            let rms = self.rms(&x, &s);
            if (last - rms).abs() <= 1e-12 * (1.0 + rms) {
                break;
            }
            last = rms;
        }
        let rms = self.rms(&x, &s);
        rms.is_finite().then_some((x, s, rms))
    }
}

impl Problem {
    /// Gauss–Newton on the measurement frame `x` and the flange points `s` together, from the
    /// alternation's estimate (which converges linearly, slowly where the geometry is off): the
    /// residual `x·F_i·s_k − m`, with `x ← exp(δ)·x` and `s_k ← s_k + d_k`. At most 30 steps;
    /// stops when a step moves nothing by more than 1e-9 mm.
    fn refine(&self, mut x: Pose, mut s: Vec<Vector3<f64>>) -> (Pose, Vec<Vector3<f64>>) {
        let n = 6 + 3 * self.classes;
        let mut rms = self.rms(&x, &s);
        for _ in 0..30 {
            let mut h = DMatrix::<f64>::zeros(n, n);
            let mut g = DVector::<f64>::zeros(n);
            let rx = x.rotation.to_rotation_matrix().into_inner();
            for (i, k, m) in &self.points {
                let f = &self.flange[*i];
                let p = x
                    .transform_point(&Point3::from(f.transform_point(&Point3::from(s[*k])).coords))
                    .coords;
                let r = p - m;
                // Columns: δv (identity), δω (−[p]×), d_k (R_x·R_f).
                let mut j = nalgebra::SMatrix::<f64, 3, 9>::zeros();
                j.fixed_view_mut::<3, 3>(0, 0).fill_with_identity();
                j.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-crate::se3::skew(&p)));
                j.fixed_view_mut::<3, 3>(0, 6)
                    .copy_from(&(rx * f.rotation.to_rotation_matrix().into_inner()));
                let jtj = j.transpose() * j;
                let jtr = j.transpose() * r;
                let idx = |c: usize| if c < 6 { c } else { 6 + 3 * k + (c - 6) };
                for a in 0..9 {
                    g[idx(a)] += jtr[a];
                    for b in 0..9 {
                        h[(idx(a), idx(b))] += jtj[(a, b)];
                    }
                }
            }
            // Minimum-norm step: where the data do not separate the frame from the flange points
            // (position data at one tool orientation: a flange point and the frame's translation
            // move the measured points alike) the normal matrix is singular, and a Cholesky
            // solve, if it passed, would throw both to metres in opposite directions.
            let svd = h.svd(true, true);
            let tiny = 1e-10 * svd.singular_values.amax();
            let Ok(step) = svd.solve(&g, tiny).map(|d| -d) else { break };
            if !step.iter().all(|v| v.is_finite()) {
                break;
            }
            let dx = crate::se3::Twist::from_iterator(step.rows(0, 6).iter().copied());
            let x_new = crate::se3::exp(&dx) * x;
            let s_new: Vec<Vector3<f64>> = s
                .iter()
                .enumerate()
                .map(|(k, sk)| sk + Vector3::new(step[6 + 3 * k], step[7 + 3 * k], step[8 + 3 * k]))
                .collect();
            // Newton from the alternation's estimate only ever improves the fit; a step that
            // does not is round-off at the minimum.
            let rms_new = self.rms(&x_new, &s_new);
            if rms_new > rms * (1.0 + 1e-12) + 1e-12 {
                break;
            }
            (x, s, rms) = (x_new, s_new, rms_new);
            let moved = crate::se3::lin(&dx).norm() + 1e3 * crate::se3::ang(&dx).norm() + step.rows(6, n - 6).amax();
            if moved < 1e-9 {
                break;
            }
        }
        (x, s)
    }
}

/// The tool frame `Y` of the flange points `s` (the classes of `obs`'s kind).
fn tool_frame(obs: &Observation, classes: &[Vector3<f64>], s: &[Vector3<f64>]) -> Pose {
    let nominal = class_points(obs, classes, &Pose::identity());
    if s.len() >= 3 {
        if let Some(y) = register_points(&nominal, s) {
            return y;
        }
    }
    // One point (a single reflector): only the offset is defined.
    Pose::translation(s[0].x - nominal[0].x, s[0].y - nominal[0].y, s[0].z - nominal[0].z)
}

/// Find the measurement frame and the tool frame of `model` from `data` (see the module docs).
/// `initial_tool` is the model file's guess of `Y` (the identity when it has none).
///
/// Errors: kinematics failing at a pose, mixed observation kinds, or poses that do not span
/// enough space to fix a frame (all tool points on a line).
pub fn register<M: Mechanism + Clone + 'static>(model: &M, data: &[Measurement], initial_tool: &Pose) -> Result<Registration, CalibError> {
    if data.is_empty() {
        return Err(CalibError::TooFewMeasurements {
            poses: 0,
            rows: 0,
            params: FRAME_PARAMS,
            needed: 3,
        });
    }
    let kind = std::mem::discriminant(&data[0].obs);
    if data.iter().any(|m| std::mem::discriminant(&m.obs) != kind) {
        return Err(CalibError::InvalidOption(
            "frame registration needs one observation kind for every pose".into(),
        ));
    }
    // Registration only starts the frames (the calibration refines them with the geometry on
    // every pose): on large sets it runs on an evenly spread subset of REGISTRATION_POSES poses.
    let stride = data.len().div_ceil(REGISTRATION_POSES).max(1);
    let mut classes = Vec::new();
    let mut points = Vec::new();
    let mut flange = Vec::with_capacity(data.len().min(REGISTRATION_POSES));
    for (i, m) in data.iter().enumerate().step_by(stride) {
        let f = flange.len();
        flange.push(model.forward(&m.q).map_err(|source| CalibError::Kinematics { pose: i, source })?);
        for (k, p) in correspondences(&m.obs, &mut classes) {
            points.push((f, k, p));
        }
    }
    let n_classes = points.iter().map(|p| p.1 + 1).max().unwrap_or(1);
    let problem = Problem {
        flange,
        points,
        classes: n_classes,
    };
    plausible_scale(&problem)?;
    let starts = [
        class_points(&data[0].obs, &classes, &Pose::identity()),
        class_points(&data[0].obs, &classes, initial_tool),
    ];
    let mut results: Vec<(Pose, Vec<Vector3<f64>>, f64)> = starts.into_iter().filter_map(|s| problem.alternate(s)).collect();
    if results.is_empty() {
        return Err(CalibError::Numerical(
            "frame registration: the measured points do not span a plane (poses on a line?); measure poses spread in all directions".into(),
        ));
    }
    results.sort_by(|a, b| a.2.total_cmp(&b.2));
    let other_start_rms_mm = results.last().map_or(f64::NAN, |r| r.2);
    let (x, s, _) = results.swap_remove(0);
    let (x, s) = problem.refine(x, s);
    let y = tool_frame(&data[0].obs, &classes, &s);

    let (measurement, tool) = (x, y);
    let refined = Framed::new(model.clone(), measurement, tool);
    let mut sum = 0.0;
    let mut n = 0usize;
    for (i, m) in data.iter().enumerate() {
        let t = refined.forward(&m.q).map_err(|source| CalibError::Kinematics { pose: i, source })?;
        let (p, _) = crate::measure::errors(&m.obs, &t);
        sum += p * p;
        n += 1;
    }
    Ok(Registration {
        measurement,
        tool,
        rms_mm: (sum / n.max(1) as f64).sqrt(),
        other_start_rms_mm,
    })
}

/// The measured points and the model's predicted flange points must span comparable distances;
/// a factor of ~1000 is metres in millimetre columns, a tiny model spread is joint values in the
/// wrong unit.
fn plausible_scale(p: &Problem) -> Result<(), CalibError> {
    let spread = |pts: &[Vector3<f64>]| {
        let c = pts.iter().sum::<Vector3<f64>>() / pts.len().max(1) as f64;
        (pts.iter().map(|v| (v - c).norm_squared()).sum::<f64>() / pts.len().max(1) as f64).sqrt()
    };
    let measured: Vec<Vector3<f64>> = p.points.iter().filter(|q| q.1 == 0).map(|q| q.2).collect();
    let model: Vec<Vector3<f64>> = p.flange.iter().map(|f| f.translation.vector).collect();
    let (sm, sp) = (spread(&measured), spread(&model));
    if measured.len() < 3 || sp <= 0.0 || !sm.is_finite() {
        return Ok(());
    }
    let ratio = sm / sp;
    if ratio < 0.02 {
        return Err(CalibError::InvalidOption(format!(
            "the measured positions spread over {sm:.4} while the model's tool moves over {sp:.1} mm for these joint values: are the x,y,z columns in metres? (name them x_m, y_m, z_m)"
        )));
    }
    if ratio > 50.0 {
        return Err(CalibError::InvalidOption(format!(
            "the model's tool moves over only {sp:.2} mm for these joint values while the measurements spread over {sm:.1} mm: are angle columns in radians named _deg, or is this the wrong model?"
        )));
    }
    Ok(())
}
