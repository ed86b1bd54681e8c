//! Data-file columns: names, unit suffixes and what each column holds.
use super::*;
use crate::measure::PointKind;

fn length_factor(suffix: &str) -> Option<f64> {
    match suffix {
        "mm" => Some(1.0),
        "m" => Some(1000.0),
        _ => None,
    }
}

fn angle_factor(suffix: &str) -> Option<f64> {
    match suffix {
        "deg" => Some(std::f64::consts::PI / 180.0),
        "rad" => Some(1.0),
        _ => None,
    }
}

/// The column's base name and unit suffix, split at the last `_`.
pub(super) fn split_unit(col: &str) -> (&str, Option<&str>) {
    match col.rsplit_once('_') {
        Some((b, u)) if length_factor(u).is_some() || angle_factor(u).is_some() => (b, Some(u)),
        _ => (col, None),
    }
}

/// The names (with unit alternatives) a data file for `inputs` may hold, for messages.
pub fn expected_columns(inputs: &[InputSpec]) -> String {
    let mut v: Vec<String> = inputs
        .iter()
        .map(|i| match i.unit {
            Unit::Angle => format!("{}_deg|_rad", i.name),
            Unit::Dimensionless => format!("{} (optional: -1, 0, +1)", i.name),
            Unit::Length => format!("{}_mm|_m", i.name),
        })
        .collect();
    v.push("x_mm,y_mm,z_mm (+ qw,qx,qy,qz or roll_deg,pitch_deg,yaw_deg) or m1x_mm..m3z_mm or seat or pivot,length_mm or pivot,reading_mm or a probe's touches (sphere,sphere_diameter_mm / plane / face,cube_edge_mm, each with probe_radius_mm); optional id".into());
    v.join(", ")
}

/// A resolved column: where its values go and the factor to mm or rad.
#[derive(Clone, Copy)]
pub(super) enum Slot {
    Id,
    Input(usize),
    Pos(usize),
    Quat(usize),
    Rpy(usize),
    Reflector(usize, usize),
    /// The seat number of an instrument row.
    Seat,
    /// The pivot number of a distance row.
    Pivot,
    /// The length of a distance row.
    Length,
    /// A distance row's reading relative to an unknown zero (`reading_mm`).
    Reading,
    /// The artifact a probe touched: `sphere`, `plane` or `face` (of the datum cube).
    Touched(PointKind),
    /// A touched sphere's diameter (`sphere_diameter_mm`) or the cube's edge (`cube_edge_mm`).
    Size,
    /// The probe tip's radius (`probe_radius_mm`).
    Probe,
}

/// The touch columns: the artifact's number column, its size column (none for a plane).
const TOUCH_COLUMNS: [(&str, PointKind, Option<&str>); 3] = [
    ("sphere", PointKind::Sphere, Some("sphere_diameter")),
    ("plane", PointKind::Plane, None),
    ("face", PointKind::Cube, Some("cube_edge")),
];

/// Whether `stem` (a column's name without its unit) names a measurement column of a data file:
/// an input of that name would take the measurement's column (`z` → `z_mm`, `roll` → `roll_deg`).
pub fn is_measurement_column(stem: &str) -> bool {
    matches!(
        stem,
        "id" | "seat"
            | "pivot"
            | "sphere"
            | "plane"
            | "face"
            | "sphere_diameter"
            | "cube_edge"
            | "probe_radius"
            | "length"
            | "reading"
            | "x"
            | "y"
            | "z"
            | "qw"
            | "qx"
            | "qy"
            | "qz"
            | "roll"
            | "pitch"
            | "yaw"
    ) || reflector_column(stem).is_some()
}

/// What a column holds and its factor to mm / rad; errors name the file (line 1) and column.
pub(super) fn classify(path: &Path, col: &str, inputs: &[InputSpec]) -> Result<(Slot, f64), IoError> {
    let at_header = |message: String| IoError::AtLine {
        path: path.to_path_buf(),
        line: 1,
        message,
    };
    let (base, unit) = split_unit(col);
    let slot = if col == "id" {
        (Slot::Id, 1.0)
    } else if col == "seat" {
        (Slot::Seat, 1.0)
    } else if col == "pivot" {
        (Slot::Pivot, 1.0)
    } else if let Some(t) = TOUCH_COLUMNS.iter().find(|t| t.0 == col) {
        (Slot::Touched(t.1), 1.0)
    } else if matches!(base, "sphere_diameter" | "cube_edge" | "probe_radius") {
        match unit.and_then(length_factor) {
            Some(f) if base == "probe_radius" => (Slot::Probe, f),
            Some(f) => (Slot::Size, f),
            None => {
                return Err(at_header(format!(
                    "column '{col}': a {base} needs a length unit ({base}_mm or {base}_m)"
                )))
            }
        }
    } else if base == "length" || base == "reading" {
        match unit.and_then(length_factor) {
            Some(f) if base == "length" => (Slot::Length, f),
            Some(f) => (Slot::Reading, f),
            None => {
                return Err(at_header(format!(
                    "column '{col}': a {base} needs a length unit ({base}_mm or {base}_m)"
                )))
            }
        }
    } else if let Some(k) = inputs.iter().position(|i| i.name == base) {
        let inp = &inputs[k];
        let (factor, want) = match inp.unit {
            Unit::Angle => (unit.and_then(angle_factor), "deg or rad"),
            Unit::Dimensionless => (unit.is_none().then_some(1.0), "no unit"),
            Unit::Length => (unit.and_then(length_factor), "mm or m"),
        };
        match factor {
            Some(f) => (Slot::Input(k), f),
            None => {
                let kind = if inp.unit == Unit::Angle { "angular" } else { "linear" };
                let found = unit.map(|u| format!("unit '{u}'")).unwrap_or_else(|| "no unit suffix".into());
                return Err(at_header(format!(
                    "column '{col}': {found} for the {kind} input '{base}' (use {base}_{})",
                    want.replace(" or ", &format!(" or {base}_"))
                )));
            }
        }
    } else if let Some(i) = ["x", "y", "z"].iter().position(|c| *c == base) {
        match unit.and_then(length_factor) {
            Some(f) => (Slot::Pos(i), f),
            None => {
                return Err(at_header(format!(
                    "column '{col}': a position needs a length unit ({base}_mm or {base}_m)"
                )))
            }
        }
    } else if let Some(i) = ["qw", "qx", "qy", "qz"].iter().position(|c| *c == col) {
        (Slot::Quat(i), 1.0)
    } else if let Some(i) = ["roll", "pitch", "yaw"].iter().position(|c| *c == base) {
        match unit.and_then(angle_factor) {
            Some(f) => (Slot::Rpy(i), f),
            None => {
                return Err(at_header(format!(
                    "column '{col}': an angle needs an angle unit ({base}_deg or {base}_rad)"
                )))
            }
        }
    } else if let Some((r, a)) = reflector_column(base) {
        match unit.and_then(length_factor) {
            Some(f) => (Slot::Reflector(r, a), f),
            None => {
                return Err(at_header(format!(
                    "column '{col}': a reflector coordinate needs a length unit ({base}_mm)"
                )))
            }
        }
    } else {
        return Err(IoError::UnknownColumn {
            path: path.to_path_buf(),
            column: col.to_string(),
            expected: expected_columns(inputs),
        });
    };
    Ok(slot)
}

fn reflector_column(base: &str) -> Option<(usize, usize)> {
    let b = base.as_bytes();
    if b.len() == 3 && b[0] == b'm' && (b'1'..=b'3').contains(&b[1]) {
        let a = ["x", "y", "z"].iter().position(|c| c.as_bytes()[0] == b[2])?;
        return Some(((b[1] - b'1') as usize, a));
    }
    None
}

/// The measurement format the columns hold (each kind's columns complete, kinds not mixed).
pub(super) fn measurement_format(table: &Table, slots: &[(Slot, f64)]) -> Result<MeasurementFormat, IoError> {
    let path = &table.path;
    let at_header = |message: String| IoError::AtLine {
        path: path.clone(),
        line: 1,
        message,
    };
    let missing = |column: String| IoError::MissingColumn {
        path: path.clone(),
        column,
        header: table.columns.join(","),
    };
    let has = |pred: &dyn Fn(&Slot) -> bool| slots.iter().filter(|(s, _)| pred(s)).count();
    let n_seat = has(&|s: &Slot| matches!(s, Slot::Seat));
    let n_pivot = has(&|s: &Slot| matches!(s, Slot::Pivot));
    let n_length = has(&|s: &Slot| matches!(s, Slot::Length | Slot::Reading));
    let n_other = has(&|s: &Slot| matches!(s, Slot::Pos(_) | Slot::Quat(_) | Slot::Rpy(_) | Slot::Reflector(..)));
    let touched: Vec<PointKind> = slots
        .iter()
        .filter_map(|(s, _)| if let Slot::Touched(k) = s { Some(*k) } else { None })
        .collect();
    let n_touch = touched.len() + has(&|s: &Slot| matches!(s, Slot::Size | Slot::Probe));
    if n_touch > 0 {
        let [kind] = touched.as_slice() else {
            return Err(at_header(
                "touch rows need one column naming what each touched: 'sphere' (with sphere_diameter_mm), 'plane' or 'face' (with cube_edge_mm), each with probe_radius_mm".into(),
            ));
        };
        let (name, _, size) = TOUCH_COLUMNS.iter().find(|t| t.1 == *kind).expect("a touch kind");
        if n_other + n_seat + n_pivot + n_length > 0 {
            return Err(at_header(format!(
                "give one kind of measurement per file: '{name}' touches, seats, distances or tracker columns"
            )));
        }
        if has(&|s: &Slot| matches!(s, Slot::Probe)) != 1 {
            return Err(at_header(format!(
                "{name} touches need one 'probe_radius_mm' column: the radius of the probe's tip ball in mm (0 for a pointed tip)"
            )));
        }
        let n_size = has(&|s: &Slot| matches!(s, Slot::Size));
        return match size {
            Some(size) if n_size != 1 || !table.columns.iter().any(|c| split_unit(c).0 == *size) => {
                Err(at_header(format!("{name} touches need one '{size}_mm' column (mm)")))
            }
            None if n_size > 0 => Err(at_header(
                "plane touches take no size column (sphere_diameter_mm, cube_edge_mm)".into(),
            )),
            _ => Ok(MeasurementFormat::Touch),
        };
    }
    if n_seat + n_pivot + n_length > 0 {
        if n_other > 0 || (n_seat > 0 && n_pivot + n_length > 0) {
            return Err(at_header(
                "give one kind of measurement per file: 'seat' alone, 'pivot' with 'length_mm', or tracker columns (x_mm … / m1x_mm …)"
                    .into(),
            ));
        }
        if n_seat > 0 {
            return Ok(MeasurementFormat::Seat);
        }
        if n_pivot == 0 {
            return Err(missing("pivot".into()));
        }
        if n_length == 0 {
            return Err(missing("length_mm".into()));
        }
        if n_length > 1 {
            return Err(at_header(
                "give one length column: 'length_mm' (a certified length) or 'reading_mm' (a reading relative to an unknown zero, e.g. a draw-wire), not both".into(),
            ));
        }
        return Ok(MeasurementFormat::Distance);
    }
    let n_pos = has(&|s: &Slot| matches!(s, Slot::Pos(_)));
    let n_quat = has(&|s: &Slot| matches!(s, Slot::Quat(_)));
    let n_rpy = has(&|s: &Slot| matches!(s, Slot::Rpy(_)));
    let n_refl = has(&|s: &Slot| matches!(s, Slot::Reflector(..)));
    let format = if n_refl > 0 {
        if n_pos + n_quat + n_rpy > 0 {
            return Err(at_header(
                "give either reflector columns m1x..m3z or x,y,z (+ orientation), not both".into(),
            ));
        }
        for r in 1..=3 {
            for a in ["x", "y", "z"] {
                if !table.columns.iter().any(|c| split_unit(c).0 == format!("m{r}{a}")) {
                    return Err(missing(format!("m{r}{a}_mm")));
                }
            }
        }
        MeasurementFormat::Reflectors
    } else {
        for a in ["x", "y", "z"] {
            if !table.columns.iter().any(|c| split_unit(c).0 == a) {
                return Err(missing(format!("{a}_mm")));
            }
        }
        match (n_quat > 0, n_rpy > 0) {
            (true, true) => {
                return Err(at_header(
                    "give the orientation as qw,qx,qy,qz or as roll,pitch,yaw, not both".into(),
                ))
            }
            (true, false) => {
                for c in ["qw", "qx", "qy", "qz"] {
                    table.column(c)?;
                }
                MeasurementFormat::PoseQuaternion
            }
            (false, true) => {
                for c in ["roll", "pitch", "yaw"] {
                    if !table.columns.iter().any(|x| split_unit(x).0 == c) {
                        return Err(missing(format!("{c}_deg")));
                    }
                }
                MeasurementFormat::PoseRpy
            }
            (false, false) => MeasurementFormat::Position,
        }
    };

    Ok(format)
}

/// The observation of a touch row: the artifact's kind and number, its size (diameter or edge,
/// mm) and the probe's radius (mm).
pub(super) fn touch(kind: PointKind, point: usize, size: f64, probe: f64) -> Observation {
    use crate::measure::Touch;
    match kind {
        PointKind::Sphere => Observation::Touch(Touch::Sphere {
            sphere: point,
            diameter: size,
            probe,
        }),
        PointKind::Cube => Observation::Touch(Touch::Face {
            face: point,
            edge: size,
            probe,
        }),
        _ => Observation::Touch(Touch::Plane { plane: point, probe }),
    }
}

/// A seat or pivot number: a non-negative integer.
pub(super) fn point_number(path: &Path, line: usize, col: &str, v: f64) -> Result<usize, IoError> {
    if v < 0.0 || v.fract() != 0.0 || v > 1e9 {
        return Err(IoError::AtLine {
            path: path.to_path_buf(),
            line,
            message: format!("column '{col}': '{v}' is not a {col} number (a non-negative integer)"),
        });
    }
    Ok(v as usize)
}

/// The columns of a touch row ([`Observation::Touch`]).
pub(super) fn touch_columns(t: &crate::measure::Touch) -> Vec<&'static str> {
    use crate::measure::Touch;
    match t {
        Touch::Sphere { .. } => vec!["sphere", "sphere_diameter_mm", "probe_radius_mm"],
        Touch::Plane { .. } => vec!["plane", "probe_radius_mm"],
        Touch::Face { .. } => vec!["face", "cube_edge_mm", "probe_radius_mm"],
    }
}

/// The values of a touch row in the order of [`touch_columns`].
pub(super) fn touch_values(t: &crate::measure::Touch) -> Vec<f64> {
    use crate::measure::Touch;
    match *t {
        Touch::Sphere { sphere, diameter, probe } => vec![sphere as f64, diameter, probe],
        Touch::Plane { plane, probe } => vec![plane as f64, probe],
        Touch::Face { face, edge, probe } => vec![face as f64, edge, probe],
    }
}

impl MeasurementFormat {
    /// A short description, e.g. `"pose (x,y,z + quaternion)"`.
    pub fn describe(self) -> &'static str {
        match self {
            MeasurementFormat::PoseQuaternion => "pose (x,y,z + quaternion)",
            MeasurementFormat::PoseRpy => "pose (x,y,z + roll,pitch,yaw)",
            MeasurementFormat::Position => "position (x,y,z)",
            MeasurementFormat::Reflectors => "three reflector centres (m1..m3)",
            MeasurementFormat::Seat => "seat numbers (the tool point in a fixed seat)",
            MeasurementFormat::Distance => "distances (pivot, length)",
            MeasurementFormat::Mixed => "rows of several kinds (tracker, seat, distance, touch)",
            MeasurementFormat::Touch => "touches (sphere, plane or cube face; probe radius)",
        }
    }
}
