//! Data files: measurement sets, targets and actuator commands as CSV with a header line.
//!
//! # Columns
//! Every column name that carries a physical value ends with its unit:
//!
//! * **inputs** (one per [`Mechanism::input_names`](crate::Mechanism::input_names), actuators
//!   first, then sensed passive joints for mechanisms that have them): `<name>_deg` or
//!   `<name>_rad` for angular inputs, `<name>_mm` or `<name>_m` for linear ones (`q1_deg`,
//!   `d3_mm`);
//! * **observed joints' readings** (one per
//!   [`Mechanism::observed_joints`](crate::Mechanism::observed_joints), named and suffixed like
//!   inputs, `u1_deg`): optional, all of them or none; read into
//!   [`Measurement::joints`](crate::measure::Measurement::joints). Pass a model's
//!   [`data_columns`](crate::io::model_file::ModelFile::data_columns) (inputs, then observed
//!   joints) to read them;
//! * **the measurement**, one of
//!   - a pose: position `x_mm, y_mm, z_mm` (or `_m`) and a unit quaternion `qw, qx, qy, qz`
//!     (normalised on reading; a norm off by more than 1e-3 is an error), or roll/pitch/yaw
//!     `roll_deg, pitch_deg, yaw_deg` (or `_rad`) meaning `R = Rz(yaw)·Ry(pitch)·Rx(roll)`;
//!   - a position: `x_mm, y_mm, z_mm` alone (the tool-frame origin);
//!   - three reflector centres `m1x_mm … m3z_mm`, turned into the tool frame by
//!     [`frame_from_reflectors`] (the model's tool frame must be that reflector frame);
//!   - `seat`: the number of the fixed seat the tool point sat in ([`crate::instrument`]);
//!   - `pivot, length_mm`: a ballbar's or draw-wire sensor's length from pivot number `pivot`;
//!   - `pivot, reading_mm`: a draw-wire sensor's reading relative to an unknown zero (one more
//!     unknown per pivot, estimated with the geometry: [`crate::instrument`]);
//! * optionally `id` (a pose number, kept for messages and written back).
//!
//! Blank lines and `#` comments are skipped. Any other column, a missing one, a wrong unit
//! suffix, a short row, a value that is not a finite number is one [`IoError`] naming the file,
//! the line and the column. Values are converted to mm and rad on reading.
use super::model_file::InputSpec;
use super::table::{read_table, Table};
use super::IoError;
use crate::error::CalibError;
use crate::measure::{frame_from_reflectors, Measurement, Observation};
use crate::params::Unit;
use crate::se3::Pose;
use nalgebra::{Quaternion, Translation3, UnitQuaternion, Vector3};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// How the measurement is given in a data file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeasurementFormat {
    /// `x, y, z` and `qw, qx, qy, qz`.
    PoseQuaternion,
    /// `x, y, z` and `roll, pitch, yaw`.
    PoseRpy,
    /// `x, y, z`.
    Position,
    /// `m1x … m3z`.
    Reflectors,
    /// `seat`: the tool point in a fixed seat ([`Observation::Seat`]).
    Seat,
    /// `pivot, length`: a ballbar's or draw-wire sensor's length ([`Observation::Distance`]).
    Distance,
    /// Rows of several kinds, each filling one kind's cells (`mixed`).
    Mixed,
    /// A touch probe's touches on spheres, planes or a datum cube ([`Observation::Touch`]).
    Touch,
}

/// A data file read into memory (mm and rad).
#[derive(Debug, Clone, PartialEq)]
pub struct DataSet {
    /// The file.
    pub path: PathBuf,
    /// One measurement per row. For targets files without input columns, `q` is empty.
    pub measurements: Vec<Measurement>,
    /// 1-based line of each row.
    pub lines: Vec<usize>,
    /// Pose ids (the `id` column, or row numbers from 0).
    pub ids: Vec<i64>,
    /// How the measurement was given.
    pub format: MeasurementFormat,
    /// Whether the file had the input columns.
    pub has_inputs: bool,
    /// Lines of rows dropped as lost measurements (an empty measurement cell, or all measurement
    /// values exactly zero: what trackers write when the beam was lost).
    pub dropped: Vec<usize>,
    /// The three reflector centres of each row (mm, measurement frame) when the file gave them
    /// (`m1x_mm … m3z_mm`); empty otherwise. `measurements` holds their frame.
    pub reflectors: Vec<[Vector3<f64>; 3]>,
    /// Inputs the file did not hold and that were derived from its row order (the approach
    /// directions `dir_<joint>` of a model with lost motion).
    pub derived: Vec<String>,
    /// Inputs with rows beyond the model's limits, kept as measured: a model file's limits are
    /// the vendor's software limits, not the robot's ([`BeyondLimits`]; one warning line each,
    /// [`DataSet::limit_warnings`]).
    pub beyond_limits: Vec<BeyondLimits>,
}

impl DataSet {
    /// A data set made in memory (e.g. from arrays, or simulated): ids 0, 1, …; `name` stands
    /// for the file in messages. Pose observations are marked as poses, positions as positions.
    pub fn from_measurements(name: &str, measurements: Vec<Measurement>) -> DataSet {
        let format = match measurements.first().map(|m| &m.obs) {
            _ if mixed::needs_mixed(&measurements) && !mixed::touches_only(&measurements) => MeasurementFormat::Mixed,
            Some(Observation::Position(_)) => MeasurementFormat::Position,
            Some(Observation::Seat(_)) => MeasurementFormat::Seat,
            Some(Observation::Distance { .. }) => MeasurementFormat::Distance,
            Some(Observation::Touch(_)) => MeasurementFormat::Touch,
            _ => MeasurementFormat::PoseQuaternion,
        };
        DataSet {
            path: name.into(),
            lines: (1..=measurements.len()).collect(),
            ids: (0..measurements.len() as i64).collect(),
            format,
            has_inputs: measurements.first().is_some_and(|m| !m.q.is_empty()),
            dropped: Vec::new(),
            reflectors: Vec::new(),
            derived: Vec::new(),
            beyond_limits: Vec::new(),
            measurements,
        }
    }

    /// One line per input with rows beyond the model's limits, naming the file:
    /// `d.csv: panda_joint4: 12 rows beyond the model's limits […] rad, by up to 0.1623 rad (9.30°) …`.
    pub fn limit_warnings(&self) -> Vec<String> {
        self.beyond_limits.iter().map(|b| format!("{}: {b}", self.path.display())).collect()
    }

    /// A line saying which rows were dropped as lost measurements, if any:
    /// `d.csv: 3 rows dropped as lost measurements (empty or all-zero cells): lines 4, 17, 90`.
    pub fn dropped_note(&self) -> Option<String> {
        if self.dropped.is_empty() {
            return None;
        }
        let shown: Vec<String> = self.dropped.iter().take(20).map(|l| l.to_string()).collect();
        let more = if self.dropped.len() > 20 { ", …" } else { "" };
        Some(format!(
            "{}: {} rows dropped as lost measurements (empty or all-zero measurement cells): lines {}{more}",
            self.path.display(),
            self.dropped.len(),
            shown.join(", ")
        ))
    }

    /// A line saying which inputs were derived from the row order, if any:
    /// `d.csv: dir_q1, dir_q2 not in the file: taken from its row order (the motion order?)`.
    pub fn derived_note(&self) -> Option<String> {
        if self.derived.is_empty() {
            return None;
        }
        Some(format!(
            "{}: {} not in the file: taken from its row order, as the order the robot moved in (give the columns when it is not)",
            self.path.display(),
            self.derived.join(", ")
        ))
    }

    /// The measurements as three-point observations of the reflectors (9 rows per pose: the
    /// tracker's own measurement model) instead of their frame: each reflector's position in the
    /// reflector frame is its mean over the set ([`crate::measure::reflector_offsets`]). `None`
    /// when the file did not give three reflector centres.
    pub fn reflector_points(&self) -> Option<Vec<Measurement>> {
        if self.reflectors.len() != self.measurements.len() || self.reflectors.is_empty() {
            return None;
        }
        let offsets = crate::measure::reflector_offsets(&self.reflectors)?;
        Some(
            self.measurements
                .iter()
                .zip(&self.reflectors)
                .map(|(m, r)| Measurement {
                    joints: Vec::new(),
                    q: m.q.clone(),
                    obs: Observation::Points((0..3).map(|k| (offsets[k], r[k])).collect()),
                })
                .collect(),
        )
    }

    /// An error of a computation on this data set, located: a failure at one pose names the
    /// file and that pose's line; any other error names the file.
    pub fn locate(&self, e: CalibError) -> IoError {
        match e {
            CalibError::Kinematics { pose, source } if pose < self.lines.len() => IoError::AtLine {
                path: self.path.clone(),
                line: self.lines[pose],
                message: format!("pose {}: {source}", self.ids[pose]),
            },
            e => IoError::Invalid {
                path: self.path.clone(),
                message: e.to_string(),
            },
        }
    }
}

/// Whether the input columns must be present.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputColumns {
    /// Every input column is required (measurement data).
    Required,
    /// All input columns or none (targets: when present they seed the inverse kinematics).
    Optional,
}

/// Join an inputs file (`id` and the input columns, e.g. a controller log) and a measurement
/// file (`id` and the measurement columns, e.g. a tracker export) row by row into one data set.
///
/// Both files must have the same number of rows ([`IoError::RowCountMismatch`]); when both have
/// an `id` column the ids must agree row by row ([`IoError::IndexMismatch`]). A column in the
/// wrong file is an [`IoError::UnknownColumn`] of that file.
pub fn join_files(inputs_path: &Path, measurements_path: &Path, inputs: &[InputSpec]) -> Result<DataSet, IoError> {
    let a = read_table(inputs_path)?;
    let b = read_table(measurements_path)?;
    let input_names: Vec<String> = input_headers(inputs).iter().map(|h| format!("{h}|_rad|_m")).collect();
    for col in &a.columns {
        match classify(&a.path, col, inputs)? {
            (Slot::Id, _) | (Slot::Input(_), _) => {}
            _ => {
                return Err(IoError::UnknownColumn {
                    path: a.path.clone(),
                    column: col.clone(),
                    expected: format!("id and the inputs only: {}", input_headers(inputs).join(",")),
                })
            }
        }
    }
    for (k, inp) in inputs.iter().enumerate() {
        if !a
            .columns
            .iter()
            .any(|c| matches!(classify(&a.path, c, inputs), Ok((Slot::Input(j), _)) if j == k))
        {
            // (Observed joints' readings are optional: checked when the tables are merged.)
            if inp.approach_of.is_some() || inp.observed {
                continue;
            }
            return Err(IoError::MissingColumn {
                path: a.path.clone(),
                column: header_of(inp),
                header: a.columns.join(","),
            });
        }
    }
    for col in &b.columns {
        if let (Slot::Input(_), _) = classify(&b.path, col, inputs)? {
            return Err(IoError::UnknownColumn {
                path: b.path.clone(),
                column: col.clone(),
                expected: format!(
                    "id and the measurement columns only (the inputs {} belong in {})",
                    input_names.join(","),
                    a.path.display()
                ),
            });
        }
    }
    if a.len() != b.len() {
        return Err(IoError::RowCountMismatch {
            path: b.path.clone(),
            found: b.len(),
            other: a.path.clone(),
            expected: a.len(),
        });
    }
    let (ia, ib) = (a.columns.iter().position(|c| c == "id"), b.columns.iter().position(|c| c == "id"));
    if let (Some(ia), Some(ib)) = (ia, ib) {
        for r in 0..a.len() {
            if a.rows[r][ia] != b.rows[r][ib] {
                return Err(IoError::IndexMismatch {
                    path: b.path.clone(),
                    line: b.lines[r],
                    found: b.rows[r][ib] as i64,
                    other: a.path.clone(),
                    expected: a.rows[r][ia] as i64,
                });
            }
        }
    }
    // Merged table: the inputs file's columns, then the measurement file's without its id.
    let keep_b: Vec<usize> = (0..b.columns.len()).filter(|&c| ia.is_none() || Some(c) != ib).collect();
    let mut columns = a.columns.clone();
    columns.extend(keep_b.iter().map(|&c| b.columns[c].clone()));
    let rows = a
        .rows
        .iter()
        .zip(&b.rows)
        .map(|(ra, rb)| ra.iter().copied().chain(keep_b.iter().map(|&c| rb[c])).collect())
        .collect();
    let merged = Table {
        path: b.path.clone(),
        columns,
        rows,
        lines: b.lines.clone(),
    };
    data_from_table(&merged, inputs, InputColumns::Required)
}

/// Largest measured coordinate a data file may hold (mm): 100 km, far beyond any tracker's range;
/// a larger value is a corrupted number or a wrong unit, not a measurement.
pub const MAX_COORDINATE_MM: f64 = 1e8;

/// Read a measurement data file for a mechanism with `inputs` (see the module docs for columns).
pub fn read_data(path: &Path, inputs: &[InputSpec], input_columns: InputColumns) -> Result<DataSet, IoError> {
    let table = super::table::read_table_with_gaps(path)?;
    data_from_table(&table, inputs, input_columns)
}

/// A model's data columns ([`crate::io::model_file::ModelFile::data_columns`]) split into its
/// inputs and the observed joints' readings that follow them.
pub(crate) fn split_observed(columns: &[InputSpec]) -> (&[InputSpec], &[InputSpec]) {
    columns.split_at(columns.iter().take_while(|c| !c.observed).count())
}

/// A line saying which columns of the data file at `path` are in metres or radians (`x_m`,
/// `yaw_rad`: read and converted to mm and rad, as the column docs above say), so that a file
/// written in metres by mistake is seen; `None` when every column is in mm and degrees.
pub fn si_units_note(path: &Path) -> Option<String> {
    let text = super::read_text(path).ok()?;
    let header = text.lines().map(str::trim).find(|l| !l.is_empty() && !l.starts_with('#'))?;
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let metres: Vec<&str> = cols.iter().copied().filter(|c| c.ends_with("_m") && !c.ends_with("_mm")).collect();
    let radians: Vec<&str> = cols.iter().copied().filter(|c| c.ends_with("_rad")).collect();
    let mut parts = Vec::new();
    if !metres.is_empty() {
        parts.push(format!("{} read as metres (× 1000 to mm)", metres.join(", ")));
    }
    if !radians.is_empty() {
        parts.push(format!("{} read as radians", radians.join(", ")));
    }
    (!parts.is_empty()).then(|| format!("{}: {}", path.display(), parts.join("; ")))
}

/// [`read_data`] on a table already read.
pub fn data_from_table(table: &Table, columns: &[InputSpec], input_columns: InputColumns) -> Result<DataSet, IoError> {
    let path = &table.path;
    // The inputs, then the observed joints' readings (optional: all of them or none).
    let (inputs, observed) = split_observed(columns);
    let n_q = inputs.len();
    if observed.iter().any(|c| !c.observed) {
        return Err(IoError::Invalid {
            path: path.clone(),
            message: "internal: observed-joint columns must follow the inputs".into(),
        });
    }
    let at_header = |message: String| IoError::AtLine {
        path: path.clone(),
        line: 1,
        message,
    };
    let mut slots: Vec<(Slot, f64)> = Vec::with_capacity(table.columns.len());
    for (k, col) in table.columns.iter().enumerate() {
        if table.columns[..k].contains(col) {
            return Err(at_header(format!("column '{col}' appears twice")));
        }
        slots.push(classify(path, col, columns)?);
    }
    let present_joints: Vec<usize> = slots
        .iter()
        .filter_map(|(s, _)| match s {
            Slot::Input(k) if *k >= n_q => Some(*k - n_q),
            _ => None,
        })
        .collect();
    if !present_joints.is_empty() && present_joints.len() < observed.len() {
        let missing: Vec<String> = (0..observed.len())
            .filter(|k| !present_joints.contains(k))
            .map(|k| header_of(&observed[k]))
            .collect();
        return Err(at_header(format!(
            "observed-joint columns missing: {} (give every observed joint's reading, or none)",
            missing.join(", ")
        )));
    }
    let has_joints = !present_joints.is_empty();
    let has = |pred: &dyn Fn(&Slot) -> bool| slots.iter().filter(|(s, _)| pred(s)).count();
    let n_inputs = has(&|s| matches!(s, Slot::Input(k) if *k < n_q));
    let missing = |column: String| IoError::MissingColumn {
        path: path.clone(),
        column,
        header: table.columns.join(","),
    };
    let has_inputs = n_inputs > 0 || input_columns == InputColumns::Required;
    if has_inputs {
        for (k, inp) in inputs.iter().enumerate() {
            if !slots.iter().any(|(s, _)| matches!(s, Slot::Input(j) if *j == k)) && inp.approach_of.is_none() {
                return Err(missing(header_of(inp)));
            }
        }
    }
    // Rows of several kinds (a mixed file, or touches of several kinds): each row read as one
    // kind, the other kinds' cells empty.
    let is_mixed = mixed::is_mixed(&slots);
    let format = match is_mixed {
        true => mixed::check_columns(table, &slots)?,
        false => columns::measurement_format(table, &slots)?,
    };

    if table.is_empty() {
        return Err(IoError::Invalid {
            path: path.clone(),
            message: "no data rows after the header; a data file needs one row per pose".into(),
        });
    }
    // Approach directions not in the file: from the row order (the motion order), over every row
    // (a lost measurement was still a motion).
    let present: Vec<bool> = (0..inputs.len())
        .map(|k| slots.iter().any(|(s, _)| matches!(s, Slot::Input(j) if *j == k)))
        .collect();
    let mut derived = Vec::new();
    let approach_rows: Vec<Vec<f64>> = if has_inputs && inputs.iter().zip(&present).any(|(i, p)| i.approach_of.is_some() && !p) {
        let mut all: Vec<Vec<f64>> = table
            .rows
            .iter()
            .map(|row| {
                let mut q = vec![0.0; inputs.len()];
                for ((slot, f), v) in slots.iter().zip(row) {
                    match slot {
                        Slot::Input(k) if *k < n_q => q[*k] = v * f,
                        _ => {}
                    }
                }
                q
            })
            .collect();
        crate::model::kind::approach_from_order(inputs, &present, &mut all);
        derived = inputs
            .iter()
            .zip(&present)
            .filter(|(i, p)| i.approach_of.is_some() && !**p)
            .map(|(i, _)| i.name.clone())
            .collect();
        all
    } else {
        Vec::new()
    };
    let mut measurements = Vec::with_capacity(table.len());
    let mut ids = Vec::with_capacity(table.len());
    let mut first_line_of_id = std::collections::HashMap::new();
    let mut dropped = Vec::new();
    let mut reflectors = Vec::new();
    let mut kept_lines = Vec::with_capacity(table.len());
    for (r, row) in table.rows.iter().enumerate() {
        let line = table.lines[r];
        // Empty cells: an error in the id or an input column; a lost measurement elsewhere.
        let mut lost = false;
        let mut all_zero = true;
        for ((slot, _), (v, col)) in slots.iter().zip(row.iter().zip(&table.columns)) {
            // (A mixed file's rows leave the other kinds' cells empty.)
            let measured =
                !matches!(slot, Slot::Id | Slot::Input(_)) && (is_mixed || !matches!(slot, Slot::Seat | Slot::Pivot | Slot::Touched(_)));
            if v.is_nan() {
                if !measured {
                    return Err(IoError::AtLine {
                        path: path.clone(),
                        line,
                        message: format!("column '{col}': empty cell; every pose needs its id and input values"),
                    });
                }
                lost = true;
            } else if measured && *v != 0.0 {
                all_zero = false;
            }
        }
        if !is_mixed && lost
            || !is_mixed
                && (all_zero
                    && slots.iter().any(|(s, _)| {
                        !matches!(
                            s,
                            Slot::Id
                                | Slot::Input(_)
                                | Slot::Seat
                                | Slot::Pivot
                                | Slot::Reading
                                | Slot::Touched(_)
                                | Slot::Size
                                | Slot::Probe
                        )
                    }))
        {
            dropped.push(line);
            continue;
        }
        kept_lines.push(line);
        let mut q = vec![0.0; if has_inputs { inputs.len() } else { 0 }];
        let mut joints = vec![0.0; if has_joints { observed.len() } else { 0 }];
        let (mut p, mut quat, mut rpy) = (Vector3::zeros(), [0.0; 4], [0.0; 3]);
        let mut refl = [Vector3::zeros(); 3];
        let mut id = r as i64;
        let (mut point, mut length, mut relative) = (0usize, 0.0, false);
        let (mut touched, mut size, mut probe) = (crate::measure::PointKind::Plane, 0.0, 0.0);
        for (((slot, f), v), col) in slots.iter().zip(row).zip(&table.columns) {
            let v = v * f;
            if matches!(slot, Slot::Pos(_) | Slot::Reflector(..)) && v.abs() > MAX_COORDINATE_MM {
                return Err(IoError::AtLine {
                    path: path.clone(),
                    line,
                    message: format!(
                        "column '{col}': {v:.4e} mm is not a plausible coordinate (more than 100 km from the instrument; check the number and the column's unit)"
                    ),
                });
            }
            match *slot {
                Slot::Id => {
                    if v.fract() != 0.0 {
                        return Err(IoError::AtLine {
                            path: path.clone(),
                            line,
                            message: format!("column 'id': '{v}' is not an integer"),
                        });
                    }
                    id = v as i64;
                }
                Slot::Input(k) if k >= n_q => joints[k - n_q] = v,
                Slot::Input(k) => q[k] = v,
                Slot::Pos(i) => p[i] = v,
                Slot::Quat(i) => quat[i] = v,
                Slot::Rpy(i) => rpy[i] = v,
                Slot::Reflector(m, a) => refl[m][a] = v,
                Slot::Seat | Slot::Pivot | Slot::Touched(_) | Slot::Size | Slot::Probe if is_mixed => {}
                Slot::Seat | Slot::Pivot => point = columns::point_number(path, line, col, v)?,
                Slot::Length => length = v,
                Slot::Reading => (length, relative) = (v, true),
                Slot::Touched(k) => (point, touched) = (columns::point_number(path, line, col, v)?, k),
                Slot::Size => size = v,
                Slot::Probe => probe = v,
            }
        }
        if let Some(first) = first_line_of_id.insert(id, line) {
            return Err(IoError::AtLine {
                path: path.clone(),
                line,
                message: format!("id {id} appears twice (first on line {first}); every pose needs its own id"),
            });
        }
        if let Some(a) = approach_rows.get(r) {
            for (k, p) in present.iter().enumerate() {
                if !p {
                    q[k] = a[k];
                }
            }
        }
        let obs = match format {
            // Touches of several kinds are read row by row as a mixed file's.
            MeasurementFormat::Mixed => mixed::observation(path, line, &slots, &table.columns, row)?,
            MeasurementFormat::Touch if is_mixed => mixed::observation(path, line, &slots, &table.columns, row)?,
            MeasurementFormat::Position => Observation::Position(p),
            MeasurementFormat::Seat => Observation::Seat(point),
            MeasurementFormat::Touch => columns::touch(touched, point, size, probe),
            MeasurementFormat::Distance => Observation::Distance {
                pivot: point,
                length,
                relative,
            },
            MeasurementFormat::PoseQuaternion => {
                let qn = Quaternion::new(quat[0], quat[1], quat[2], quat[3]);
                if (qn.norm() - 1.0).abs() > 1e-3 {
                    return Err(IoError::AtLine {
                        path: path.clone(),
                        line,
                        message: format!("qw,qx,qy,qz: not a unit quaternion (norm {:.6})", qn.norm()),
                    });
                }
                Observation::Pose(Pose::from_parts(Translation3::from(p), UnitQuaternion::from_quaternion(qn)))
            }
            MeasurementFormat::PoseRpy => Observation::Pose(Pose::from_parts(
                Translation3::from(p),
                UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
            )),
            MeasurementFormat::Reflectors => {
                Observation::Pose(frame_from_reflectors(&refl[0], &refl[1], &refl[2]).ok_or_else(|| IoError::AtLine {
                    path: path.clone(),
                    line,
                    message: "m1..m3: the three reflector centres are (nearly) collinear; no frame".into(),
                })?)
            }
        };
        if format == MeasurementFormat::Reflectors {
            reflectors.push(refl);
        }
        measurements.push(Measurement { joints, q, obs });
        ids.push(id);
    }
    if measurements.is_empty() {
        return Err(IoError::Invalid {
            path: path.clone(),
            message: format!(
                "all {} rows are lost measurements (empty or all-zero measurement cells)",
                dropped.len()
            ),
        });
    }
    let beyond_limits = if has_inputs {
        // Each input's unit factor as the file states it (none for an input it does not hold).
        let factors: Vec<Option<f64>> = (0..n_q)
            .map(|k| slots.iter().find(|(s, _)| matches!(s, Slot::Input(j) if *j == k)).map(|(_, f)| *f))
            .collect();
        let qs: Vec<Vec<f64>> = measurements.iter().map(|m| m.q.clone()).collect();
        limits::check(path, inputs, &factors, &qs, &kept_lines, &ids)?
    } else {
        Vec::new()
    };
    Ok(DataSet {
        beyond_limits,
        path: path.clone(),
        measurements,
        lines: kept_lines,
        ids,
        format,
        has_inputs,
        dropped,
        reflectors,
        derived,
    })
}

mod columns;
mod commands;
mod limits;
mod mixed;
mod unassembled;
mod write;
use columns::{classify, Slot};
pub use columns::{expected_columns, is_measurement_column};
pub use commands::{read_commands, read_configurations, read_inputs};
pub use limits::{check as check_limits, BeyondLimits, FAR_BEYOND_RANGE};
pub use unassembled::Unassembled;
pub use write::{csv_text, data_text, header_of, input_headers, input_values_for_file, write_csv, write_data};

#[cfg(test)]
mod tests;
