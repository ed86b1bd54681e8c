//! Data-file columns: names, unit suffixes and what each column holds.
use super::*;

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
    v.push("x_mm,y_mm,z_mm (+ qw,qx,qy,qz or roll_deg,pitch_deg,yaw_deg) or m1x_mm..m3z_mm; optional id".into());
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
