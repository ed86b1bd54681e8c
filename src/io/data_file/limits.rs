//! Input values against the model's limits. A model file's joint limits are usually the
//! vendor's software limits (a URDF's `<limit>`), not where the robot can go: its own log may
//! pass them. Rows beyond them in the unit the file states are data, kept and named in one
//! warning per input ([`BeyondLimits`]). What is refused is what a mistake gives:
//! - values that fit the limits read in the other unit of their kind (degrees for radians,
//!   metres for millimetres, or back) where the stated unit puts them far beyond, or degrees
//!   that all stay within ±2π as radians do: the unit hint;
//! - values beyond the limits by more than half the limits' range ([`FAR_BEYOND_RANGE`]): no
//!   software margin is that wide; a wrong column order or a model of another machine.
use super::IoError;
use crate::io::model_file::InputSpec;
use crate::params::Unit;
use serde::Serialize;
use std::f64::consts::PI;
use std::path::Path;

/// Values beyond the limits by more than this fraction of the limits' range are refused: a
/// vendor's software limits sit a few degrees inside the robot's travel, not half a range.
pub const FAR_BEYOND_RANGE: f64 = 0.5;

/// One input's rows beyond the model's limits: kept, and said once.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BeyondLimits {
    /// The input's name.
    pub input: String,
    /// Rows beyond the limits.
    pub rows: usize,
    /// The id of each of those rows (the data's `id` column, or row numbers from 0).
    pub ids: Vec<i64>,
    /// The limits (the unit the file states, `unit`).
    pub limits: (f64, f64),
    /// The largest distance of a row beyond them (the unit the file states).
    pub max_excess: f64,
    /// The unit the file states (`deg`, `rad`, `mm`, `m` or empty).
    pub unit: String,
}

impl std::fmt::Display for BeyondLimits {
    /// `panda_joint4: 12 rows beyond the model's limits [-2.0892, 2.0892] rad, by up to 0.1623
    /// rad (9.30°) (ids 5, 17, …): …`
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let u = &self.unit;
        let other = match u.as_str() {
            "rad" => format!(" ({:.2}°)", self.max_excess.to_degrees()),
            "deg" => format!(" ({:.4} rad)", self.max_excess.to_radians()),
            _ => String::new(),
        };
        let shown: Vec<String> = self.ids.iter().take(5).map(|l| l.to_string()).collect();
        let more = if self.ids.len() > 5 { ", …" } else { "" };
        write!(
            f,
            "{}: {} row{} beyond the model's limits [{:.4}, {:.4}] {u}, by up to {:.4} {u}{other} (id{} {}{more}): the limits are taken as the vendor's software limits, not the robot's, and the rows are used as measured",
            self.input,
            self.rows,
            if self.rows == 1 { "" } else { "s" },
            self.limits.0,
            self.limits.1,
            self.max_excess,
            if self.ids.len() == 1 { "" } else { "s" },
            shown.join(", ")
        )
    }
}

/// Check every input of the rows `qs` (mm, rad; the row on line `lines[r]`, id `ids[r]`) against
/// its limits.
/// `factors[k]` is the factor that took input `k`'s column from the unit the file states to mm or
/// rad (`None` for an input the file does not hold: derived, no unit stated). Returns the inputs
/// with rows beyond their limits, or the error a mistake gives (module docs).
pub fn check(
    path: &Path,
    inputs: &[InputSpec],
    factors: &[Option<f64>],
    qs: &[Vec<f64>],
    lines: &[usize],
    ids: &[i64],
) -> Result<Vec<BeyondLimits>, IoError> {
    let mut out = Vec::new();
    for (k, inp) in inputs.iter().enumerate() {
        let Some((lo, hi)) = inp.limits else { continue };
        let slack = 1e-9 * (1.0 + lo.abs().max(hi.abs()));
        let excess = |v: f64| (lo - v).max(v - hi);
        let beyond: Vec<usize> = (0..qs.len())
            .filter(|&r| qs[r].get(k).is_some_and(|&v| excess(v) > slack))
            .collect();
        let Some(&first) = beyond.first() else { continue };
        let f = factors.get(k).copied().flatten();
        // Shown in the unit the file states.
        let (unit, to_file) = match (inp.unit, f) {
            (Unit::Angle, Some(f)) if f != 1.0 => ("deg", 1.0 / f),
            (Unit::Angle, _) => ("rad", 1.0),
            (Unit::Length, Some(f)) if f != 1.0 => ("m", 1.0 / f),
            (Unit::Length, _) => ("mm", 1.0),
            (Unit::Dimensionless, _) => ("", 1.0),
        };
        let max_excess = beyond.iter().map(|&r| excess(qs[r][k])).fold(0.0, f64::max);
        let range = hi - lo;
        let far = |v: f64| excess(v) > FAR_BEYOND_RANGE * range;
        // The other unit of the kind, as a factor on the values (mm, rad) and its name.
        let other = match (inp.unit, f) {
            (Unit::Angle, Some(f)) if f != 1.0 => Some((1.0 / f, "rad")),
            (Unit::Angle, Some(_)) => Some((PI / 180.0, "deg")),
            (Unit::Length, Some(f)) if f != 1.0 => Some((1.0 / f, "mm")),
            (Unit::Length, Some(_)) => Some((1000.0, "m")),
            _ => None,
        };
        let column: Vec<f64> = qs.iter().filter_map(|q| q.get(k).copied()).collect();
        let hint = other.filter(|(a, name)| {
            let fits = column.iter().all(|v| excess(v * a) <= slack);
            // Degrees that all stay within ±2π are radians, whatever else.
            let like_radians = *name == "rad" && column.iter().all(|v| (v * a).abs() <= 2.0 * PI);
            fits && (like_radians || beyond.iter().any(|&r| far(qs[r][k])))
        });
        let at = |r: usize, message: String| IoError::AtLine {
            path: path.to_path_buf(),
            line: lines[r],
            message,
        };
        let said = |r: usize| {
            format!(
                "{}: {:.4} {unit} is outside the model's limits [{:.4}, {:.4}] {unit}",
                inp.name,
                qs[r][k] * to_file,
                lo * to_file,
                hi * to_file
            )
        };
        if let Some((_, name)) = hint {
            return Err(at(
                first,
                format!(
                    "{}, and every value of the column fits them read in {name}: check the column's unit",
                    said(first)
                ),
            ));
        }
        if let Some(&r) = beyond.iter().find(|&&r| far(qs[r][k])) {
            return Err(at(
                r,
                format!(
                    "{} by {:.4} {unit}, more than half their range: no software limit is that far inside a robot's travel; check the joint order and the model (if the machine really goes there, widen the limits in the model file)",
                    said(r),
                    excess(qs[r][k]) * to_file
                ),
            ));
        }
        out.push(BeyondLimits {
            input: inp.name.clone(),
            rows: beyond.len(),
            ids: beyond.iter().map(|&r| ids[r]).collect(),
            limits: (lo * to_file, hi * to_file),
            max_excess: max_excess * to_file,
            unit: unit.to_string(),
        });
    }
    Ok(out)
}
