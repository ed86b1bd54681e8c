//! Python bindings of kinecal: a thin layer over the library calls (`calibrate`, `validate`,
//! `compensate`, `simulate`, identifiability), with numpy arrays in and out. The Python package
//! `kinecal` (python/kinecal/__init__.py) wraps these into plain objects.
//!
//! Units are the library's: millimetres and radians (a data file read with [`Data::read`] is
//! converted from its own units). Poses are 4×4 homogeneous matrices (mm).
use kinecal::calibrate::{calibrate as lib_calibrate, CalibrationOptions, FrameMode, ReflectorFit};
use kinecal::identify::{linearize, Loss, Method};
use kinecal::io::data_file::{read_data, DataSet, InputColumns};
use kinecal::io::model_file::ModelFile;
use kinecal::measure::{Measurement, Noise, Observation};
use kinecal::model::Mechanism;
use kinecal::params::Unit;
use kinecal::se3::Pose;
use kinecal::simulate::{random_configurations, synthesize, virtual_prototype, Instrument};
use nalgebra::{Matrix3, Matrix4, Rotation3, UnitQuaternion, Vector3};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;

create_exception!(
    _kinecal,
    KinecalError,
    pyo3::exceptions::PyValueError,
    "An error of kinecal: bad input, a failed solve, a file that cannot be read. The message is the one the command line prints."
);

fn err<E: std::fmt::Display>(e: E) -> PyErr {
    KinecalError::new_err(e.to_string())
}

/// A 4×4 homogeneous matrix of a pose.
fn pose_matrix(p: &Pose) -> Matrix4<f64> {
    p.to_homogeneous()
}

/// A pose from a 4×4 homogeneous matrix (the rotation block re-orthonormalised; not finite or far
/// from a rotation is an error).
fn matrix_pose(m: &Matrix4<f64>, what: &str) -> PyResult<Pose> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(err(format!("{what}: the matrix holds NaN or infinite values")));
    }
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    if (r.transpose() * r - Matrix3::identity()).norm() > 1e-6 || r.determinant() < 0.0 {
        return Err(err(format!("{what}: the upper-left 3×3 block is not a rotation")));
    }
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&r));
    Ok(Pose::from_parts(Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]).into(), rot))
}

fn rows_2d(a: &PyReadonlyArray2<f64>, cols: usize, what: &str) -> PyResult<Vec<Vec<f64>>> {
    let shape = a.shape();
    if shape[1] != cols {
        return Err(err(format!(
            "{what}: expected an array of shape (n, {cols}), got ({}, {})",
            shape[0], shape[1]
        )));
    }
    let v = a.as_array();
    let rows: Vec<Vec<f64>> = v.rows().into_iter().map(|r| r.to_vec()).collect();
    if let Some(i) = rows.iter().position(|r| r.iter().any(|x| !x.is_finite())) {
        return Err(err(format!("{what}: row {i} holds NaN or infinite values")));
    }
    Ok(rows)
}

/// Input rows of `file`'s model: every input, or (a model with lost motion) the joint values
/// alone, the approach directions then taken from the row order as for a data file without them.
fn input_rows(a: &PyReadonlyArray2<f64>, file: &ModelFile, what: &str) -> PyResult<Vec<Vec<f64>>> {
    let inputs = file.inputs();
    let measured = inputs.iter().filter(|i| i.approach_of.is_none()).count();
    if measured == inputs.len() || a.shape()[1] != measured {
        return rows_2d(a, inputs.len(), what);
    }
    let mut rows: Vec<Vec<f64>> = rows_2d(a, measured, what)?
        .into_iter()
        .map(|mut r| {
            r.resize(inputs.len(), 0.0);
            r
        })
        .collect();
    kinecal::model::kind::approach_from_order(&inputs, &vec![false; inputs.len()], &mut rows);
    Ok(rows)
}

fn poses_3d(a: &PyReadonlyArray3<f64>, what: &str) -> PyResult<Vec<Pose>> {
    let shape = a.shape();
    if shape[1] != 4 || shape[2] != 4 {
        return Err(err(format!(
            "{what}: expected an array of shape (n, 4, 4), got ({}, {}, {})",
            shape[0], shape[1], shape[2]
        )));
    }
    let v = a.as_array();
    (0..shape[0])
        .map(|i| {
            let m = Matrix4::from_fn(|r, c| v[[i, r, c]]);
            matrix_pose(&m, &format!("{what}[{i}]"))
        })
        .collect()
}

fn poses_array<'py>(py: Python<'py>, poses: &[Pose]) -> Bound<'py, PyArray3<f64>> {
    let mut out = Array3::<f64>::zeros((poses.len(), 4, 4));
    for (i, p) in poses.iter().enumerate() {
        let m = pose_matrix(p);
        for r in 0..4 {
            for c in 0..4 {
                out[[i, r, c]] = m[(r, c)];
            }
        }
    }
    out.into_pyarray(py)
}

fn rows_array<'py>(py: Python<'py>, rows: &[Vec<f64>], cols: usize) -> Bound<'py, PyArray2<f64>> {
    let mut out = Array2::<f64>::zeros((rows.len(), cols));
    for (i, r) in rows.iter().enumerate() {
        for (k, v) in r.iter().enumerate().take(cols) {
            out[[i, k]] = *v;
        }
    }
    out.into_pyarray(py)
}

/// A mechanism model: a kinecal model file (serial, DH, pm5, stewart, or a calibrated one) or a
/// built-in model by name.
#[pyclass(module = "kinecal._kinecal")]
pub struct Model {
    file: ModelFile,
    mech: Box<dyn Mechanism>,
}

impl Model {
    fn of(file: ModelFile) -> Model {
        let mech = file.build();
        Model { file, mech }
    }
}

#[pymethods]
impl Model {
    /// Load a model file (TOML), or a built-in model by name (`irb120`, `pm5`, `stewart`).
    #[staticmethod]
    fn load(name_or_path: &str) -> PyResult<Model> {
        ModelFile::load_or_builtin(name_or_path).map(Model::of).map_err(err)
    }

    /// A model from the text of a model file (`name` stands for the file in messages).
    #[staticmethod]
    #[pyo3(signature = (text, name = "<string>"))]
    fn from_toml(text: &str, name: &str) -> PyResult<Model> {
        ModelFile::load_str(Path::new(name), text).map(Model::of).map_err(err)
    }

    /// The model file's text (TOML).
    fn to_toml(&self) -> PyResult<String> {
        self.file.to_toml().map_err(err)
    }

    /// The model written for a controller (`format`: "ur-yaml", "linuxcnc-hexapod",
    /// "klipper-delta"; `kinecal model export --format`): the file's text and what the projection
    /// leaves, as JSON (pose difference, parameters not represented, frames not written).
    fn to_controller(&self, format: &str) -> PyResult<(String, String)> {
        use kinecal::io::controllers::{self, Controller};
        let c =
            Controller::parse(format).ok_or_else(|| err(format!("format '{format}': use ur-yaml, linuxcnc-hexapod or klipper-delta")))?;
        let e = controllers::export(&self.file, c).map_err(|e| err(e.at(&self.file.name)))?;
        let d = e.projection.difference;
        let json = serde_json::json!({
            "poses": d.poses, "position_max_mm": d.position_max_mm, "position_rms_mm": d.position_rms_mm,
            "rotation_max_rad": d.rotation_max_rad, "rotation_rms_rad": d.rotation_rms_rad,
            "fit_residual_mm": e.projection.fit_residual_mm,
            "not_represented": e.projection.not_represented, "not_written": e.projection.not_written,
        });
        Ok((e.text, json.to_string()))
    }

    /// A model from a controller's kinematics file text (`format` as in `to_controller`;
    /// `name` stands for the file in messages, which give its line).
    #[staticmethod]
    #[pyo3(signature = (text, format, name = "<string>"))]
    fn from_controller(text: &str, format: &str, name: &str) -> PyResult<Model> {
        use kinecal::io::controllers::{self, Controller};
        let c =
            Controller::parse(format).ok_or_else(|| err(format!("format '{format}': use ur-yaml, linuxcnc-hexapod or klipper-delta")))?;
        controllers::import(text, c).map(Model::of).map_err(|e| err(e.at(name)))
    }

    /// The model's name.
    #[getter]
    fn name(&self) -> String {
        self.file.name.clone()
    }

    /// Input (joint / actuator) names, in order.
    #[getter]
    fn inputs(&self) -> Vec<String> {
        self.file.inputs().into_iter().map(|i| i.name).collect()
    }

    /// Observed joints (passive joints whose encoder readings are observations, `role =
    /// "observed"`), in the order of `Data.joints`.
    #[getter]
    fn observed(&self) -> Vec<String> {
        self.mech.observed_joints().into_iter().map(|(n, _)| n).collect()
    }

    /// Unit kind of each input: "angle" (rad) or "length" (mm).
    #[getter]
    fn input_units(&self) -> Vec<&'static str> {
        self.file
            .inputs()
            .iter()
            .map(|i| if i.unit == Unit::Angle { "angle" } else { "length" })
            .collect()
    }

    /// Names of the geometric error parameters (what a calibration can identify).
    #[getter]
    fn parameters(&self) -> Vec<String> {
        self.mech.params().into_iter().map(|p| p.name).collect()
    }

    /// Forward kinematics: tool poses (n, 4, 4) in mm of inputs `q` (n, inputs) in rad / mm.
    fn forward<'py>(&self, py: Python<'py>, q: PyReadonlyArray2<'py, f64>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let rows = input_rows(&q, &self.file, "q")?;
        let poses = rows
            .iter()
            .enumerate()
            .map(|(i, q)| self.mech.forward(q).map_err(|e| err(format!("q[{i}]: {e}"))))
            .collect::<PyResult<Vec<_>>>()?;
        Ok(poses_array(py, &poses))
    }

    /// Inverse kinematics: inputs (n, inputs) in rad / mm reaching tool poses (n, 4, 4), from
    /// optional seeds (n, inputs).
    #[pyo3(signature = (poses, seeds = None))]
    fn inverse<'py>(
        &self,
        py: Python<'py>,
        poses: PyReadonlyArray3<'py, f64>,
        seeds: Option<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let targets = poses_3d(&poses, "poses")?;
        let k = self.mech.input_names().len();
        let seeds = match &seeds {
            Some(s) => Some(rows_2d(s, k, "seeds")?),
            None => None,
        };
        if seeds.as_ref().is_some_and(|s| s.len() != targets.len()) {
            return Err(err("seeds: one row per pose"));
        }
        let qs = targets
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let seed = seeds.as_ref().map(|s| s[i].as_slice());
                self.mech.inverse(t, seed).map_err(|e| err(format!("poses[{i}]: {e}")))
            })
            .collect::<PyResult<Vec<_>>>()?;
        Ok(rows_array(py, &qs, k))
    }

    fn __repr__(&self) -> String {
        format!(
            "Model('{}', {} inputs, {} parameters)",
            self.file.name,
            self.file.inputs().len(),
            self.mech.n_params()
        )
    }
}

/// A measurement set: joint values and what the instrument measured at each pose.
#[pyclass(module = "kinecal._kinecal")]
pub struct Data {
    set: DataSet,
}

#[pymethods]
impl Data {
    /// Read a kinecal data file (CSV) for `model` (its input columns, in the file's units).
    #[staticmethod]
    fn read(path: &str, model: &Model) -> PyResult<Data> {
        read_data(Path::new(path), &model.file.data_columns(), InputColumns::Required)
            .map(|set| Data { set })
            .map_err(err)
    }

    /// Measurements from arrays: inputs `q` (n, inputs) in rad / mm and measured tool positions
    /// (n, 3) in mm, with measured rotations (n, 3, 3) for full poses; optional integer ids.
    #[staticmethod]
    #[pyo3(signature = (model, q, positions, rotations = None, ids = None, joints = None))]
    fn from_arrays<'py>(
        model: &Model,
        q: PyReadonlyArray2<'py, f64>,
        positions: PyReadonlyArray2<'py, f64>,
        rotations: Option<PyReadonlyArray3<'py, f64>>,
        ids: Option<Vec<i64>>,
        joints: Option<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<Data> {
        let qs = input_rows(&q, &model.file, "q")?;
        let n_obs = model.mech.observed_joints().len();
        let js = match &joints {
            Some(j) => {
                let rows = rows_2d(j, n_obs, "joints")?;
                if rows.len() != qs.len() {
                    return Err(err(format!("joints: {} rows for {} rows of q", rows.len(), qs.len())));
                }
                rows
            }
            None => vec![Vec::new(); qs.len()],
        };
        let ps = rows_2d(&positions, 3, "positions")?;
        if ps.len() != qs.len() {
            return Err(err(format!("positions: {} rows for {} rows of q", ps.len(), qs.len())));
        }
        let rots: Option<Vec<Matrix3<f64>>> = match &rotations {
            None => None,
            Some(r) => {
                let shape = r.shape();
                if shape[0] != qs.len() || shape[1] != 3 || shape[2] != 3 {
                    return Err(err(format!(
                        "rotations: expected shape ({}, 3, 3), got ({}, {}, {})",
                        qs.len(),
                        shape[0],
                        shape[1],
                        shape[2]
                    )));
                }
                let v = r.as_array();
                Some((0..qs.len()).map(|i| Matrix3::from_fn(|a, b| v[[i, a, b]])).collect())
            }
        };
        let mut measurements = Vec::with_capacity(qs.len());
        for (i, ((q, p), joints)) in qs.into_iter().zip(ps).zip(js).enumerate() {
            let p = Vector3::new(p[0], p[1], p[2]);
            let obs = match &rots {
                None => Observation::Position(p),
                Some(r) => {
                    let mut m = Matrix4::identity();
                    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&r[i]);
                    m.fixed_view_mut::<3, 1>(0, 3).copy_from(&p);
                    Observation::Pose(matrix_pose(&m, &format!("rotations[{i}]"))?)
                }
            };
            measurements.push(Measurement { joints, q, obs });
        }
        let mut set = DataSet::from_measurements("<arrays>", measurements);
        if let Some(ids) = ids {
            if ids.len() != set.measurements.len() {
                return Err(err(format!("ids: {} for {} poses", ids.len(), set.measurements.len())));
            }
            set.ids = ids;
        }
        Ok(Data { set })
    }

    fn __len__(&self) -> usize {
        self.set.measurements.len()
    }

    /// Pose ids.
    #[getter]
    fn ids(&self) -> Vec<i64> {
        self.set.ids.clone()
    }

    /// One line per input with rows beyond the model's limits (the vendor's software limits):
    /// kept as measured, said as `kinecal` says it on stderr.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.set.limit_warnings()
    }

    /// Inputs (n, inputs) in rad / mm.
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let rows: Vec<Vec<f64>> = self.set.measurements.iter().map(|m| m.q.clone()).collect();
        let k = rows.first().map_or(0, Vec::len);
        rows_array(py, &rows, k)
    }

    /// Observed joints' readings (n, observed) in rad / mm; (n, 0) without them.
    #[getter]
    fn joints<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let rows: Vec<Vec<f64>> = self.set.measurements.iter().map(|m| m.joints.clone()).collect();
        let k = rows.first().map_or(0, Vec::len);
        rows_array(py, &rows, k)
    }

    /// Measured tool positions (n, 3) in mm (for three-reflector data: the origin of their frame).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let rows: Vec<Vec<f64>> = self
            .set
            .measurements
            .iter()
            .map(|m| match &m.obs {
                Observation::Pose(p) => p.translation.vector.as_slice().to_vec(),
                Observation::Position(p) => p.as_slice().to_vec(),
                Observation::Points(pts) => pts.first().map_or(vec![f64::NAN; 3], |(_, m)| m.as_slice().to_vec()),
                // Instrument rows locate no point by themselves (the seat's or pivot's centre is
                // an unknown of the fit).
                Observation::Seat(_) | Observation::Distance { .. } | Observation::Touch(_) => vec![f64::NAN; 3],
            })
            .collect();
        rows_array(py, &rows, 3)
    }

    fn __repr__(&self) -> String {
        format!(
            "Data('{}', {} poses, {})",
            self.set.path.display(),
            self.set.measurements.len(),
            self.set.format.describe()
        )
    }
}

/// The result of [`calibrate`]: the calibrated model and the report.
#[pyclass(module = "kinecal._kinecal")]
pub struct Calibration {
    cal: kinecal::calibrate::Calibration,
}

#[pymethods]
impl Calibration {
    /// The calibrated model.
    #[getter]
    fn model(&self) -> Model {
        Model::of(self.cal.model_file.clone())
    }

    /// The report as JSON (the same document `kinecal identify --json` prints).
    fn report_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.cal.report).map_err(err)
    }

    /// The report as one self-contained HTML page.
    fn report_html(&self) -> PyResult<String> {
        self.cal.report.to_html().map_err(err)
    }

    /// Ids of the poses set aside as gross blunders.
    #[getter]
    fn blunders(&self) -> Vec<i64> {
        self.cal.blunders.clone()
    }
}

fn method_of(name: &str) -> PyResult<Method> {
    match name {
        "gauss-newton" | "gauss_newton" => Ok(Method::GaussNewton),
        "linear" => Ok(Method::Linear),
        "recursive" => Ok(Method::Recursive),
        _ => Err(err(format!("method: '{name}' is not one of gauss-newton, linear, recursive"))),
    }
}

/// Identify the model's free parameters from `data` (optionally validated on `validation`): the
/// library call behind `kinecal identify`, with the same options and defaults.
#[pyfunction]
#[pyo3(signature = (model, data, validation = None, *, noise_mm = None, noise_deg = None, encoder_noise_deg = None, encoder_noise_mm = None, method = "gauss-newton", frames = "estimate", reflectors = "frame", starts = 3, seed = 1, reweight = false, huber = 5.0, seat_distances = Vec::new(), kind_noise = Vec::new(), validation_seat_distances = Vec::new()))]
#[allow(clippy::too_many_arguments)]
fn calibrate(
    py: Python<'_>,
    model: &Model,
    data: &Data,
    validation: Option<&Data>,
    noise_mm: Option<f64>,
    noise_deg: Option<f64>,
    encoder_noise_deg: Option<f64>,
    encoder_noise_mm: Option<f64>,
    method: &str,
    frames: &str,
    reflectors: &str,
    starts: u64,
    seed: u64,
    reweight: bool,
    huber: f64,
    seat_distances: Vec<String>,
    kind_noise: Vec<String>,
    validation_seat_distances: Vec<String>,
) -> PyResult<Calibration> {
    let base = model.file.noise.unwrap_or_default();
    // Each kind's own σ, `KIND=MM` as `kinecal identify --kind-noise` takes it.
    let mut kinds = base.kinds;
    for k in &kind_noise {
        kinds.set_from(k).map_err(|e| err(format!("kind_noise: {e}")))?;
    }
    let noise = Noise {
        position: noise_mm.unwrap_or(base.position),
        orientation: noise_deg.map_or(base.orientation, f64::to_radians),
        joint_angle: encoder_noise_deg.map_or(base.joint_angle, f64::to_radians),
        joint_length: encoder_noise_mm.unwrap_or(base.joint_length),
        kinds,
    };
    if !(noise.position > 0.0 && noise.orientation > 0.0 && noise.position.is_finite() && noise.orientation.is_finite()) {
        return Err(err("noise_mm / noise_deg: must be finite and > 0"));
    }
    if !(noise.joint_angle > 0.0 && noise.joint_length > 0.0 && noise.joint_angle.is_finite() && noise.joint_length.is_finite()) {
        return Err(err("encoder_noise_deg / encoder_noise_mm: must be finite and > 0"));
    }
    if !huber.is_finite() || huber < 0.0 {
        return Err(err("huber: a finite number of standard deviations ≥ 0 (0 = off)"));
    }
    let distances = |list: &[String], what: &str| {
        list.iter()
            .map(|s| s.parse().map_err(|e: String| err(format!("{what}: {e}"))))
            .collect::<PyResult<Vec<_>>>()
    };
    let opts = CalibrationOptions {
        seat_distances: distances(&seat_distances, "seat_distances")?,
        validation_seat_distances: distances(&validation_seat_distances, "validation_seat_distances")?,
        compare_terms: true,
        method: method_of(method)?,
        noise,
        reweight,
        frames: match frames {
            "estimate" => FrameMode::Estimate,
            "model" => FrameMode::Model,
            f => return Err(err(format!("frames: '{f}' is not one of estimate, model"))),
        },
        loss: if huber > 0.0 { Loss::Huber { k: huber } } else { Loss::Squares },
        starts,
        seed,
        reflectors: match reflectors {
            "frame" => ReflectorFit::Frame,
            "points" => ReflectorFit::Points,
            r => return Err(err(format!("reflectors: '{r}' is not one of frame, points"))),
        },
    };
    // The calibration runs without the GIL: other Python threads go on meanwhile.
    let (file, set, valid) = (&model.file, &data.set, validation.map(|v| &v.set));
    py.detach(|| lib_calibrate(file, set, valid, &opts))
        .map(|cal| Calibration { cal })
        .map_err(err)
}

/// The prior of a `Calibration` (in memory) or of a calibrated `Model` (its file carries the
/// covariance of its parameters).
fn prior_of(prior: &Bound<'_, PyAny>) -> PyResult<kinecal::drift::Prior> {
    if let Ok(c) = prior.extract::<PyRef<'_, Calibration>>() {
        return kinecal::drift::Prior::from_calibration(&c.cal).map_err(err);
    }
    if let Ok(m) = prior.extract::<PyRef<'_, Model>>() {
        return kinecal::drift::Prior::from_model_file(&m.file).map_err(err);
    }
    Err(err("prior: a Calibration, or a Model loaded from a calibrated model file"))
}

/// Re-measured poses `data` judged against the prediction of `calibration` (a `Calibration`, or
/// a calibrated `Model`): the library call behind `kinecal check`. Returns the report as JSON.
#[pyfunction]
#[pyo3(signature = (calibration, data, *, false_alarm = 0.01))]
fn check(calibration: &Bound<'_, PyAny>, data: &Data, false_alarm: f64) -> PyResult<String> {
    let prior = prior_of(calibration)?;
    let opts = kinecal::drift::CheckOptions {
        false_alarm,
        ..Default::default()
    };
    let r = kinecal::drift::check(&prior, &data.set.measurements, &opts).map_err(|e| err(data.set.locate(e)))?;
    serde_json::to_string(&r).map_err(err)
}

/// The configurations among `configurations` (n, inputs; rad / mm) at which a check of
/// `calibration` names a drift best: the library call behind `kinecal check --plan`. Returns the
/// plan as JSON (`selected` indices into the rows, `wrong_names`, …).
#[pyfunction]
#[pyo3(signature = (calibration, configurations, *, n = 5, drift_mm = 0.1, observe = "pose"))]
fn plan_check(
    py: Python<'_>,
    calibration: &Bound<'_, PyAny>,
    configurations: PyReadonlyArray2<'_, f64>,
    n: usize,
    drift_mm: f64,
    observe: &str,
) -> PyResult<String> {
    let prior = prior_of(calibration)?;
    let instrument = match observe {
        "pose" => kinecal::simulate::Instrument::Pose,
        "position" => kinecal::simulate::Instrument::Position,
        other => return Err(err(format!("observe: 'pose' or 'position' (it is '{other}')"))),
    };
    let rows = input_rows(&configurations, &prior.model, "configurations")?;
    let opts = kinecal::drift::CheckPlanOptions {
        n,
        instrument,
        drift_mm,
        ..Default::default()
    };
    let plan = py.detach(|| kinecal::drift::plan_check_poses(&prior, &rows, &opts)).map_err(err)?;
    serde_json::to_string(&plan).map_err(err)
}

/// The result of an update (`calibrate(..., prior=...)`): the updated model and the report.
#[pyclass(module = "kinecal._kinecal")]
pub struct Update {
    up: kinecal::drift::Update,
}

#[pymethods]
impl Update {
    /// The updated model.
    #[getter]
    fn model(&self) -> Model {
        Model::of(self.up.model_file.clone())
    }

    /// What the update did, as JSON: the patterns released, the one declined, the parameters
    /// moved, the statistic and its bound, the new poses' errors before and after.
    fn report_json(&self) -> PyResult<String> {
        let u = &self.up;
        serde_json::to_string(&serde_json::json!({
            "released": u.releases, "declined": u.declined, "moved": u.moved,
            "largest_move_sigmas": u.largest_move_sigmas, "chi2": u.chi2, "rows": u.rows, "bound": u.bound,
            "converged": u.converged, "passed": u.passed(), "before": u.before, "after": u.after,
            "set_aside": u.set_aside}))
        .map_err(err)
    }
}

/// `prior` (a `Calibration` or a calibrated `Model`) updated by the new poses `data`: the
/// library call behind `kinecal identify --prior`.
#[pyfunction]
#[pyo3(signature = (prior, data, *, false_alarm = 0.01))]
fn update(py: Python<'_>, prior: &Bound<'_, PyAny>, data: &Data, false_alarm: f64) -> PyResult<Update> {
    let prior = prior_of(prior)?;
    let opts = kinecal::drift::UpdateOptions {
        false_alarm,
        ..Default::default()
    };
    let set = &data.set;
    py.detach(|| kinecal::drift::update(&prior, &set.measurements, &opts))
        .map(|up| Update { up })
        .map_err(|e| err(set.locate(e)))
}

/// Per-pose errors of `model` on `data`: (statistics as JSON, position errors (n,) in mm,
/// orientation errors (n,) in rad or None for position data).
#[pyfunction]
#[allow(clippy::type_complexity)]
fn validate<'py>(
    py: Python<'py>,
    model: &Model,
    data: &Data,
) -> PyResult<(String, Bound<'py, PyArray1<f64>>, Option<Bound<'py, PyArray1<f64>>>)> {
    let e = kinecal::validate::pose_errors(&*model.mech, &data.set.measurements).map_err(|e| err(data.set.locate(e)))?;
    let stats = kinecal::validate::ErrorStats::of(&e);
    let json = serde_json::to_string(&stats).map_err(err)?;
    let pos = Array1::from(e.position.clone()).into_pyarray(py);
    let ori = e
        .orientation
        .iter()
        .any(Option::is_some)
        .then(|| Array1::from(e.orientation.iter().map(|o| o.unwrap_or(f64::NAN)).collect::<Vec<_>>()).into_pyarray(py));
    Ok((json, pos, ori))
}

/// `model` judged on instrument rows in the instrument's own terms (`kinecal validate` of seat,
/// distance or touch data, [`kinecal::instrument::held_out`]): each seat's spread, the known
/// `seat_distances` ("A:B:MM"), each pivot's or sphere's length residuals, each plane's flatness,
/// each datum cube's fit. Returns the result as JSON.
#[pyfunction]
#[pyo3(signature = (model, data, seat_distances = Vec::new()))]
fn validate_instrument(model: &Model, data: &Data, seat_distances: Vec<String>) -> PyResult<String> {
    let distances = seat_distances
        .iter()
        .map(|s| s.parse().map_err(|e: String| err(format!("seat_distances: {e}"))))
        .collect::<PyResult<Vec<kinecal::instrument::SeatDistance>>>()?;
    let held = kinecal::instrument::held_out(&*model.mech, &data.set.measurements, &distances).map_err(|e| err(data.set.locate(e)))?;
    serde_json::to_string(&held).map_err(err)
}

/// ISO 9283 figures of an attained test file against a commanded one (`kinecal assess --json`),
/// with distance figures between the `(from, to)` test poses of `distances`. Attained poses
/// beyond any plausible accuracy (`kinecal::assess::implausible`: files that do not belong
/// together) are refused, as by `kinecal assess`, unless `force`.
#[pyfunction]
#[pyo3(signature = (commanded, attained, distances = Vec::new(), force = false))]
fn assess(commanded: &str, attained: &str, distances: Vec<(i64, i64)>, force: bool) -> PyResult<String> {
    use kinecal::io::test_poses::{read_attained, read_commanded};
    let c = read_commanded(std::path::Path::new(commanded)).map_err(err)?;
    let a = read_attained(std::path::Path::new(attained)).map_err(err)?;
    let r = kinecal::assess::iso9283(&c, &a, &distances).map_err(|e| err(format!("{attained}: {e}")))?;
    if let Some(why) = kinecal::assess::implausible(&r).filter(|_| !force) {
        return Err(err(format!("{attained}: {why}; force=True assesses it anyway")));
    }
    serde_json::to_string(&r).map_err(err)
}

/// ISO 230-4 figures of a circular test file (`kinecal assess --circle --json`): ballbar
/// readings or points about `centre` (mm) in `plane` ("xy", "yz", "zx"), nominal `radius` (mm).
#[pyfunction]
#[pyo3(signature = (circle, radius, centre = [0.0, 0.0, 0.0], plane = "xy"))]
fn assess_circle(circle: &str, radius: f64, centre: [f64; 3], plane: &str) -> PyResult<String> {
    let plane: kinecal::assess::Plane = plane.parse().map_err(err)?;
    let points = kinecal::io::test_poses::read_circle(std::path::Path::new(circle), plane, &centre.into(), radius).map_err(err)?;
    let t = kinecal::assess::iso230_4(&points, radius).map_err(|e| err(format!("{circle}: {e}")))?;
    serde_json::to_string(&t).map_err(err)
}

/// The ISO 9283 test poses in `model`'s workspace (`kinecal plan --iso9283`): a JSON summary
/// (cube, poses) and the commands (5, inputs) in rad / mm. `orientation_deg`: roll, pitch, yaw of
/// the tool; `region`: ((xmin, ymin, zmin), (xmax, ymax, zmax)) mm.
#[pyfunction]
#[pyo3(signature = (model, orientation_deg = None, region = None, grid = 10, samples = 500, seed = 1))]
fn plan_iso9283<'py>(
    py: Python<'py>,
    model: &Model,
    orientation_deg: Option<[f64; 3]>,
    region: Option<([f64; 3], [f64; 3])>,
    grid: usize,
    samples: usize,
    seed: u64,
) -> PyResult<(String, Bound<'py, PyArray2<f64>>)> {
    let request = kinecal::assess::CubeRequest {
        region: region.map(|(lo, hi)| (lo.into(), hi.into())),
        rotation: orientation_deg
            .map(|[r, p, y]| nalgebra::UnitQuaternion::from_euler_angles(r.to_radians(), p.to_radians(), y.to_radians())),
        grid,
        samples,
        seed,
    };
    let inputs = model.file.inputs();
    let plan = kinecal::assess::iso9283_commands(&*model.mech, &inputs, &request).map_err(err)?;
    let poses: Vec<_> = plan
        .poses
        .iter()
        .map(|p| serde_json::json!({"pose": p.pose, "position_mm": p.position.as_slice(), "angles_deg": p.angles}))
        .collect();
    let summary = serde_json::json!({"cube_min_mm": plan.cube_min.as_slice(), "side_mm": plan.side,
        "region_mm": [plan.region.0.as_slice(), plan.region.1.as_slice()], "grid_reachable": plan.reachable.0,
        "grid_points": plan.reachable.1, "poses": poses});
    Ok((summary.to_string(), rows_array(py, &plan.commands, inputs.len())))
}

/// Rank, identifiable and redundant parameters of `model` on `data` (as JSON).

#[pyfunction]
#[pyo3(signature = (model, data, tolerance = 1e-8))]
fn identifiability(model: &Model, data: &Data, tolerance: f64) -> PyResult<String> {
    let free = model.file.free_indices().map_err(err)?;
    let noise = model.file.noise.unwrap_or_default();
    let lin = linearize(&*model.mech, &data.set.measurements, &noise).map_err(|e| err(data.set.locate(e)))?;
    let id = kinecal::identifiability::analyze(&lin.jacobian, &free, tolerance);
    let params = model.mech.params();
    let names = |v: &[usize]| v.iter().map(|&i| params[i].name.clone()).collect::<Vec<_>>();
    serde_json::to_string(&serde_json::json!({
        "poses": data.set.measurements.len(), "free": free.len(), "rank": id.rank,
        "identifiable": names(&id.identifiable), "redundant": names(&id.redundant),
        "no_effect": names(&id.no_effect), "condition": id.condition,
    }))
    .map_err(err)
}

/// Actuator commands (n, inputs) in rad / mm that bring `model` to the target poses (n, 4, 4):
/// its inverse kinematics from several starts, within the joint limits.
#[pyfunction]
#[pyo3(signature = (model, targets, seeds = None))]
fn compensate<'py>(
    py: Python<'py>,
    model: &Model,
    targets: PyReadonlyArray3<'py, f64>,
    seeds: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let poses = poses_3d(&targets, "targets")?;
    let inputs = model.file.inputs();
    let seeds = match &seeds {
        Some(s) => Some(input_rows(s, &model.file, "seeds")?),
        None => None,
    };
    let q = kinecal::compensate::compensate(&*model.mech, &inputs, &poses, seeds.as_deref(), &|_| {})
        .map_err(|e| err(format!("targets[{}]: {}", e.target, e.source)))?;
    Ok(rows_array(py, &q, inputs.len()))
}

/// A program filtered for a controller that keeps its nominal kinematics (`kinecal filter`):
/// `text` in `format` (csv, rapid, krl, urscript, gcode), `path` naming it in messages,
/// `companion` a KRL program's `.dat` text. `tool` (4×4, mm) in the flange where the format has
/// none. Returns (the filtered text, the companion's, the report as JSON).
#[pyfunction]
#[pyo3(signature = (calibrated, nominal, text, format, *, path = "<string>", companion = None, tool = None, max_deviation_mm = None, force = false))]
#[allow(clippy::too_many_arguments)]
fn filter_program(
    calibrated: &Model,
    nominal: &Model,
    text: &str,
    format: &str,
    path: &str,
    companion: Option<&str>,
    tool: Option<PyReadonlyArray2<'_, f64>>,
    max_deviation_mm: Option<f64>,
    force: bool,
) -> PyResult<(String, Option<String>, String)> {
    use kinecal::filter::{FilterModels, FilterOptions, Format};
    let format: Format = format.parse().map_err(err)?;
    let models = FilterModels::new(&calibrated.file, &nominal.file).map_err(err)?;
    let mut opts = FilterOptions {
        force,
        max_deviation_mm,
        ..FilterOptions::default()
    };
    if let Some(t) = &tool {
        let rows = rows_2d(t, 4, "tool")?;
        let m = Matrix4::from_fn(|i, j| rows.get(i).map_or(f64::NAN, |r| r[j]));
        opts.tool = matrix_pose(&m, "tool")?;
    }
    let path = Path::new(path);
    let dat = path.with_extension("dat");
    let companion = companion.map(|c| (dat.as_path(), c));
    let f = kinecal::filter::filter_program(path, text, companion, format, &models, &opts).map_err(err)?;
    let report = serde_json::json!({
        "format": f.format, "targets": f.targets, "uncorrected": f.uncorrected, "notes": f.notes, "paths": f.paths,
    });
    Ok((f.text, f.companion, report.to_string()))
}

/// The accuracy a calibrated `model` predicts at `configurations` (n, inputs) in rad / mm
/// (`kinecal validate --predict`, [`kinecal::predict::accuracy_of_file`]): its `[covariance]`
/// carried to each pose. Returns the result as JSON.
#[pyfunction]
fn predict_accuracy(model: &Model, configurations: PyReadonlyArray2<'_, f64>) -> PyResult<String> {
    let q = input_rows(&configurations, &model.file, "configurations")?;
    let acc = kinecal::predict::accuracy_of_file(&model.file, &model.file.name, &q).map_err(err)?;
    serde_json::to_string(&acc).map_err(err)
}

/// A virtual prototype of `model` (uniform errors ±error_mm / ±error_deg on its free parameters)
/// measured at `poses` random configurations with Gaussian noise: (true model, data).
/// `measure`: "pose", "position" or "reflectors".
#[pyfunction]
#[pyo3(signature = (model, poses, *, seed = 1, error_mm = 0.5, error_deg = 0.1, noise_mm = 0.0, noise_deg = 0.0, encoder_noise_deg = 0.0, encoder_noise_mm = 0.0, measure = "pose"))]
#[allow(clippy::too_many_arguments)]
fn simulate(
    model: &Model,
    poses: usize,
    seed: u64,
    error_mm: f64,
    error_deg: f64,
    noise_mm: f64,
    noise_deg: f64,
    encoder_noise_deg: f64,
    encoder_noise_mm: f64,
    measure: &str,
) -> PyResult<(Model, Data)> {
    for (name, v) in [
        ("error_mm", error_mm),
        ("error_deg", error_deg),
        ("noise_mm", noise_mm),
        ("noise_deg", noise_deg),
        ("encoder_noise_deg", encoder_noise_deg),
        ("encoder_noise_mm", encoder_noise_mm),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(err(format!("{name}: must be a finite value ≥ 0, got {v}")));
        }
    }
    let instrument = match measure {
        "pose" => Instrument::Pose,
        "position" => Instrument::Position,
        "reflectors" => Instrument::Reflectors,
        m => return Err(err(format!("measure: '{m}' is not one of pose, position, reflectors"))),
    };
    let free = model.file.free_indices().map_err(err)?;
    let inputs = model.file.inputs();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (truth, _) = virtual_prototype(&model.mech, &free, error_mm, error_deg.to_radians(), &mut rng);
    let truth_file = model.file.with_geometry_of(&*truth).map_err(err)?;
    let qs = random_configurations(&*model.mech, &inputs, poses, &mut rng).map_err(err)?;
    let noise = Noise {
        position: noise_mm,
        orientation: noise_deg.to_radians(),
        joint_angle: encoder_noise_deg.to_radians(),
        joint_length: encoder_noise_mm,
        kinds: Default::default(),
    };
    let set = synthesize(&*truth, qs, instrument, &noise, &mut rng, &|_| {}).map_err(err)?;
    let mut data = DataSet::from_measurements("<simulated>", set.measurements);
    if let Some(r) = set.reflectors {
        data.reflectors = r;
    }
    Ok((Model::of(truth_file), Data { set: data }))
}

/// Choose `n` of the candidate configurations `candidates` (N, inputs; rad / mm) to measure at
/// (`kinecal plan`): identifiable columns, scaled Jacobian blocks, then greedy / SFFS / exchange
/// on a criterion (`d`, `o1` … `o5`). Returns (chosen row indices, observability indices as JSON).
#[pyfunction]
#[pyo3(signature = (model, candidates, n = 30, *, criterion = "o2", method = "sffs", observe = "pose", noise_mm = 0.02, noise_deg = 0.02))]
#[allow(clippy::too_many_arguments)]
fn plan<'py>(
    model: &Model,
    candidates: PyReadonlyArray2<'py, f64>,
    n: usize,
    criterion: &str,
    method: &str,
    observe: &str,
    noise_mm: f64,
    noise_deg: f64,
) -> PyResult<(Vec<usize>, String)> {
    use kinecal::design::{self, Candidate, SelectOptions};
    let rows = rows_2d(&candidates, model.mech.input_names().len(), "candidates")?;
    let cands = rows
        .into_iter()
        .enumerate()
        .map(|(i, q)| {
            let target = model.mech.forward(&q).map_err(|e| err(format!("candidates[{i}]: {e}")))?;
            Ok(Candidate { q, target, solution: None })
        })
        .collect::<PyResult<Vec<_>>>()?;
    let defaults = SelectOptions::default();
    let opts = plan_options(
        n,
        criterion,
        method,
        observe,
        noise_mm,
        noise_deg,
        defaults.pool,
        defaults.shortlist,
    )?;
    let planned = design::plan(&*model.mech, &cands, &opts, None, &mut |_| {}).map_err(err)?;
    let ix = &planned.selection.indices;
    let json = serde_json::to_string(&serde_json::json!({
        "o1": ix.o1, "o2": ix.o2, "o3": ix.o3, "o4": ix.o4, "o5": ix.o5, "o_t": ix.o_t, "log_det": ix.log_det,
        "identifiable_parameters": planned.columns.len(),
    }))
    .map_err(err)?;
    Ok((planned.selection.selected.clone(), json))
}

/// The planning options of `plan` and `plan_sampled`, their Python arguments checked.
#[allow(clippy::too_many_arguments)]
fn plan_options(
    n: usize,
    criterion: &str,
    method: &str,
    observe: &str,
    noise_mm: f64,
    noise_deg: f64,
    pool: usize,
    shortlist: usize,
) -> PyResult<kinecal::design::PlanOptions> {
    if !(noise_mm > 0.0 && noise_deg > 0.0 && noise_mm.is_finite() && noise_deg.is_finite()) {
        return Err(err("noise_mm / noise_deg: must be finite and > 0"));
    }
    Ok(kinecal::design::PlanOptions {
        observe: observe.parse().map_err(|e| err(format!("observe: {e}")))?,
        noise: Noise {
            position: noise_mm,
            orientation: noise_deg.to_radians(),
            ..Noise::default()
        },
        method: method.parse().map_err(err)?,
        select: kinecal::design::SelectOptions {
            n,
            criterion: criterion.parse().map_err(err)?,
            pool,
            shortlist,
            ..Default::default()
        },
        ..Default::default()
    })
}

/// A range argument: a number (a fixed value) or a pair (min, max), times `unit`.
fn py_range(value: Option<&Bound<'_, PyAny>>, what: &str, unit: f64) -> PyResult<Option<(f64, f64)>> {
    let Some(v) = value else { return Ok(None) };
    let (a, b) = match v.extract::<f64>() {
        Ok(x) => (x, x),
        Err(_) => v
            .extract::<(f64, f64)>()
            .map_err(|_| err(format!("{what}: expected a number or a pair (min, max)")))?,
    };
    if !(a.is_finite() && b.is_finite() && a <= b) {
        return Err(err(format!("{what}: need finite min ≤ max, got ({a}, {b})")));
    }
    Ok(Some((a * unit, b * unit)))
}

/// Sample candidates of `model` and choose `n` of them (`kinecal plan`, the same library call
/// `design::plan_sampled`): a box of poses (`x_mm` … `gamma_deg`, each a value or a pair; `None`
/// takes the model's own box: a 5-DOF machine's platform workspace, a limbs machine's workspace),
/// or with `joint_range_deg` every input in ±that range; Halton points (`candidates`, `seed`) or
/// a `grid` (six counts, or "paper"). Returns (chosen candidate numbers, summary JSON as
/// `kinecal plan --json` prints it plus the generation report, the plan CSV as `kinecal plan`
/// writes it).
#[pyfunction]
#[pyo3(signature = (model, n = 30, *, x_mm = None, y_mm = None, z_mm = None, alpha_deg = None, beta_deg = None, gamma_deg = None, joint_range_deg = None, grid = None, candidates = 300_000, seed = 1, max_condition = None, criterion = "o2", method = "sffs", observe = "pose", noise_mm = 0.02, noise_deg = 0.02, pool = 10_000, shortlist = 32))]
#[allow(clippy::too_many_arguments)]
fn plan_sampled(
    model: &Model,
    n: usize,
    x_mm: Option<&Bound<'_, PyAny>>,
    y_mm: Option<&Bound<'_, PyAny>>,
    z_mm: Option<&Bound<'_, PyAny>>,
    alpha_deg: Option<&Bound<'_, PyAny>>,
    beta_deg: Option<&Bound<'_, PyAny>>,
    gamma_deg: Option<&Bound<'_, PyAny>>,
    joint_range_deg: Option<f64>,
    grid: Option<&Bound<'_, PyAny>>,
    candidates: usize,
    seed: u64,
    max_condition: Option<f64>,
    criterion: &str,
    method: &str,
    observe: &str,
    noise_mm: f64,
    noise_deg: f64,
    pool: usize,
    shortlist: usize,
) -> PyResult<(Vec<usize>, String, String)> {
    use kinecal::design::{self, CandidateSampling, Points, PoseRanges, Region};
    let deg = 1f64.to_radians();
    let region = match joint_range_deg {
        Some(r) => {
            let k = model.file.inputs().len();
            Region::Inputs {
                lower: vec![-r.to_radians(); k],
                upper: vec![r.to_radians(); k],
            }
        }
        None => Region::Poses(PoseRanges {
            position: [
                py_range(x_mm, "x_mm", 1.0)?,
                py_range(y_mm, "y_mm", 1.0)?,
                py_range(z_mm, "z_mm", 1.0)?,
            ],
            angles: [
                py_range(alpha_deg, "alpha_deg", deg)?,
                py_range(beta_deg, "beta_deg", deg)?,
                py_range(gamma_deg, "gamma_deg", deg)?,
            ],
        }),
    };
    let points = match grid {
        None => Points::Halton { n: candidates, seed },
        Some(g) if g.extract::<String>().is_ok_and(|s| s == "paper") => Points::PaperGrid,
        Some(g) => Points::Grid {
            counts: g.extract::<Vec<usize>>().map_err(|_| err("grid: expected six counts or 'paper'"))?,
        },
    };
    let sampling = CandidateSampling {
        region,
        points,
        max_condition,
    };
    let opts = plan_options(n, criterion, method, observe, noise_mm, noise_deg, pool, shortlist)?;
    let planned = design::plan_sampled(&model.file, &sampling, &opts, None).map_err(err)?;
    let mut summary = planned.summary();
    summary["generation"] = serde_json::to_value(planned.candidates.report).map_err(err)?;
    let mut csv = Vec::new();
    planned.write_csv(&mut csv).map_err(err)?;
    Ok((
        planned.plan.selection.selected.clone(),
        summary.to_string(),
        String::from_utf8(csv).map_err(err)?,
    ))
}

/// Plan an instrument's rows on `model`'s nominal geometry (`kinecal plan --seats` / `--pivots`,
/// the same library call `design::plan_instrument`): `points` are the seats' (or, with
/// `ballbar_mm`, the pivots') centres (mm, base frame), `tool_mm` the ball on the flange,
/// `reference` the configuration orientations are drawn about (rad / mm; default the middle of
/// the limits). Returns (the chosen configurations (n, inputs) in rad / mm, each row's point,
/// summary JSON: rows per point, indices, identifiable columns, repair moves).
#[pyfunction]
#[pyo3(signature = (model, points, n = 40, *, ballbar_mm = None, tool_mm = [0.0, 0.0, 0.0], candidates_per_point = 100, tilt_deg = 30.0, reference = None, min_per_point = 0, criterion = "d", method = "sffs", noise_mm = 0.01, seed = 1))]
#[allow(clippy::too_many_arguments)]
fn plan_instrument<'py>(
    py: Python<'py>,
    model: &Model,
    points: Vec<[f64; 3]>,
    n: usize,
    ballbar_mm: Option<f64>,
    tool_mm: [f64; 3],
    candidates_per_point: usize,
    tilt_deg: f64,
    reference: Option<Vec<f64>>,
    min_per_point: usize,
    criterion: &str,
    method: &str,
    noise_mm: f64,
    seed: u64,
) -> PyResult<(Bound<'py, PyArray2<f64>>, Vec<usize>, String)> {
    use kinecal::design::{InstrumentLayout, InstrumentPlanOptions, SelectOptions};
    let inputs = model.file.inputs();
    let reference = reference.unwrap_or_else(|| kinecal::instrument::simulate::middle_of_limits(&inputs));
    if reference.len() != inputs.len() {
        return Err(err(format!(
            "reference: {} values, the model has {} inputs",
            reference.len(),
            inputs.len()
        )));
    }
    if !(tilt_deg.is_finite() && (0.0..=90.0).contains(&tilt_deg)) {
        return Err(err(format!("tilt_deg: must be between 0 and 90, got {tilt_deg}")));
    }
    let layout = InstrumentLayout {
        points: points.iter().map(|&p| p.into()).collect(),
        bar_length: ballbar_mm,
        ball: tool_mm.into(),
    };
    let opts = InstrumentPlanOptions {
        draw: kinecal::instrument::simulate::Placement {
            per_point: candidates_per_point,
            reference,
            max_tilt: tilt_deg.to_radians(),
            noise_mm,
            seed,
            inputs: inputs.clone(),
        },
        min_per_point,
        method: method.parse().map_err(err)?,
        select: SelectOptions {
            n,
            criterion: criterion.parse().map_err(err)?,
            ..Default::default()
        },
    };
    let plan = kinecal::design::plan_instrument(&model.file, &layout, &opts).map_err(err)?;
    let point_of: Vec<usize> = plan.rows.iter().map(|m| m.obs.artifact_point().map_or(0, |p| p.1)).collect();
    let per_point: Vec<usize> = (0..layout.points.len())
        .map(|k| point_of.iter().filter(|&&p| p == k).count())
        .collect();
    let summary = serde_json::json!({"instrument": layout.kind().name(), "rows": plan.rows.len(), "rows_per_point": per_point,
        "candidates": plan.candidates.len(), "repairs": plan.repairs, "indices": plan.selection.indices,
        "columns": plan.column_names});
    let q: Vec<Vec<f64>> = plan.rows.iter().map(|m| m.q.clone()).collect();
    Ok((rows_array(py, &q, inputs.len()), point_of, summary.to_string()))
}

/// The touched artifacts of the keyword arguments ([`kinecal::instrument::simulate::TouchSpec`]):
/// spheres (centres, one diameter), planes (point, normal), a cube (centre, edge, rotation in
/// degrees), the probe radius (mm).
#[allow(clippy::too_many_arguments)]
fn touch_spec(
    spheres: Vec<[f64; 3]>,
    sphere_diameter_mm: Option<f64>,
    planes: Vec<([f64; 3], [f64; 3])>,
    cube: Option<[f64; 3]>,
    cube_edge_mm: Option<f64>,
    cube_rotation_deg: [f64; 3],
    probe_radius_mm: f64,
) -> PyResult<Vec<kinecal::instrument::simulate::Touched>> {
    let spec = kinecal::instrument::simulate::TouchSpec {
        spheres: spheres.into_iter().map(Vector3::from).collect(),
        sphere_diameter_mm,
        planes: planes.into_iter().map(|(o, n)| (o.into(), n.into())).collect(),
        cube: cube.map(|c| {
            (
                c.into(),
                Vector3::from(cube_rotation_deg).map(f64::to_radians),
                cube_edge_mm.unwrap_or(f64::NAN),
            )
        }),
        probe_radius_mm,
    };
    spec.artifacts().map(|(_, a)| a).map_err(err)
}

/// Touch-probe data on a virtual prototype (`kinecal simulate --spheres / --planes / --cube`):
/// the prototype's errors (±`error_mm` / ±`error_deg`, seed `seed`), the probe ball at `tool_mm`
/// on its flange, `per_artifact` touches per sphere, plane or cube face at the random
/// configurations nearest it, moved onto it, noise σ `noise_mm` along the normal. Returns (true
/// model, data).
#[pyfunction]
#[pyo3(signature = (model, *, probe_radius_mm, spheres = Vec::new(), sphere_diameter_mm = None, planes = Vec::new(), cube = None, cube_edge_mm = None, cube_rotation_deg = [0.0, 0.0, 0.0], per_artifact = 20, tool_mm = [0.0, 0.0, 0.0], seed = 1, error_mm = 0.5, error_deg = 0.1, noise_mm = 0.0))]
#[allow(clippy::too_many_arguments)]
fn simulate_touches(
    model: &Model,
    probe_radius_mm: f64,
    spheres: Vec<[f64; 3]>,
    sphere_diameter_mm: Option<f64>,
    planes: Vec<([f64; 3], [f64; 3])>,
    cube: Option<[f64; 3]>,
    cube_edge_mm: Option<f64>,
    cube_rotation_deg: [f64; 3],
    per_artifact: usize,
    tool_mm: [f64; 3],
    seed: u64,
    error_mm: f64,
    error_deg: f64,
    noise_mm: f64,
) -> PyResult<(Model, Data)> {
    for (name, v) in [("error_mm", error_mm), ("error_deg", error_deg), ("noise_mm", noise_mm)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(err(format!("{name}: must be a finite value ≥ 0, got {v}")));
        }
    }
    if per_artifact == 0 {
        return Err(err("per_artifact: must be at least 1"));
    }
    let artifacts = touch_spec(
        spheres,
        sphere_diameter_mm,
        planes,
        cube,
        cube_edge_mm,
        cube_rotation_deg,
        probe_radius_mm,
    )?;
    let free = model.file.free_indices().map_err(err)?;
    let inputs = model.file.inputs();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (proto, _) = virtual_prototype(&model.mech, &free, error_mm, error_deg.to_radians(), &mut rng);
    let tool = kinecal::se3::pose_from_parts(Vector3::from(tool_mm), Vector3::zeros());
    let truth = kinecal::model::framed::Framed::new(proto, Pose::identity(), tool);
    let truth_file = model.file.with_geometry_of(&truth).map_err(err)?;
    let rows = kinecal::instrument::simulate::random_touches(&truth, &inputs, &artifacts, per_artifact, noise_mm, &mut rng).map_err(err)?;
    Ok((
        Model::of(truth_file),
        Data {
            set: DataSet::from_measurements("<simulated touches>", rows),
        },
    ))
}

/// Plan where to touch (`kinecal plan --spheres / --planes / --cube`, the same library call,
/// [`kinecal::design::plan_touches`]) on `model`'s nominal geometry with the probe ball at
/// `tool_mm`. Returns (the planned touches as data, summary as JSON).
#[pyfunction]
#[pyo3(signature = (model, n = 40, *, probe_radius_mm, spheres = Vec::new(), sphere_diameter_mm = None, planes = Vec::new(), cube = None, cube_edge_mm = None, cube_rotation_deg = [0.0, 0.0, 0.0], tool_mm = [0.0, 0.0, 0.0], candidates_per_artifact = 100, min_per_artifact = 0, criterion = "d", method = "sffs", noise_mm = 0.005, seed = 1))]
#[allow(clippy::too_many_arguments)]
fn plan_touches(
    model: &Model,
    n: usize,
    probe_radius_mm: f64,
    spheres: Vec<[f64; 3]>,
    sphere_diameter_mm: Option<f64>,
    planes: Vec<([f64; 3], [f64; 3])>,
    cube: Option<[f64; 3]>,
    cube_edge_mm: Option<f64>,
    cube_rotation_deg: [f64; 3],
    tool_mm: [f64; 3],
    candidates_per_artifact: usize,
    min_per_artifact: usize,
    criterion: &str,
    method: &str,
    noise_mm: f64,
    seed: u64,
) -> PyResult<(Data, String)> {
    use kinecal::design::{InstrumentPlanOptions, SelectOptions, TouchLayout};
    let artifacts = touch_spec(
        spheres,
        sphere_diameter_mm,
        planes,
        cube,
        cube_edge_mm,
        cube_rotation_deg,
        probe_radius_mm,
    )?;
    let layout = TouchLayout {
        artifacts,
        ball: tool_mm.into(),
    };
    let opts = InstrumentPlanOptions {
        draw: kinecal::instrument::simulate::Placement {
            per_point: candidates_per_artifact,
            reference: Vec::new(),
            max_tilt: 0.0,
            noise_mm,
            seed,
            inputs: model.file.inputs(),
        },
        min_per_point: min_per_artifact,
        method: method.parse().map_err(err)?,
        select: SelectOptions {
            n,
            criterion: criterion.parse().map_err(err)?,
            ..Default::default()
        },
    };
    let plan = kinecal::design::plan_touches(&model.file, &layout, &opts).map_err(err)?;
    let counts: std::collections::BTreeMap<String, usize> = (kinecal::measure::artifact_rows(&plan.rows).iter())
        .map(|a| (a.name(), a.rows))
        .collect();
    let summary = serde_json::json!({"rows": plan.rows.len(), "rows_per_artifact": counts, "candidates": plan.candidates.len(),
        "repairs": plan.repairs, "indices": plan.selection.indices, "columns": plan.column_names});
    Ok((
        Data {
            set: DataSet::from_measurements("<touch plan>", plan.rows),
        },
        summary.to_string(),
    ))
}

/// The compiled core of the `kinecal` package.
#[pymodule]
fn _kinecal(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("KinecalError", m.py().get_type::<KinecalError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<Model>()?;
    m.add_class::<Data>()?;
    m.add_class::<Calibration>()?;
    m.add_class::<Update>()?;
    m.add_function(wrap_pyfunction!(check, m)?)?;
    m.add_function(wrap_pyfunction!(plan_check, m)?)?;
    m.add_function(wrap_pyfunction!(update, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(validate, m)?)?;
    m.add_function(wrap_pyfunction!(predict_accuracy, m)?)?;
    m.add_function(wrap_pyfunction!(validate_instrument, m)?)?;
    m.add_function(wrap_pyfunction!(identifiability, m)?)?;
    m.add_function(wrap_pyfunction!(assess, m)?)?;
    m.add_function(wrap_pyfunction!(assess_circle, m)?)?;
    m.add_function(wrap_pyfunction!(plan_iso9283, m)?)?;
    m.add_function(wrap_pyfunction!(compensate, m)?)?;
    m.add_function(wrap_pyfunction!(filter_program, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(plan, m)?)?;
    m.add_function(wrap_pyfunction!(plan_sampled, m)?)?;
    m.add_function(wrap_pyfunction!(plan_instrument, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_touches, m)?)?;
    m.add_function(wrap_pyfunction!(plan_touches, m)?)?;
    Ok(())
}
