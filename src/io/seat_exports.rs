//! Seat exports joined into one data file ([`join_seat_exports`]): one file per seat (a socket,
//! cone or nest the tool ball was placed in), each the list of joint configurations at which the
//! ball sat there — what a robot's controller logs while someone guides the ball into each seat.
//!
//! | file | rows | columns | unit |
//! |---|---|---|---|
//! | seat `k` (the `k`-th file, seat number `k`) | one per configuration | one per joint input, in the model's order; an optional header line; `,` or blanks between values; `#` comments | [`AngleUnit`] for revolute inputs, [`LengthUnit`] for prismatic ones |
//!
//! Ids are the rows' order over all files (1, 2, …); approach directions, where the model has
//! them, follow from that order ([`crate::model::kind::approach_from_order`]).
use super::data_file::{check_limits, DataSet};
use super::model_file::{AngleUnit, InputSpec, LengthUnit};
use super::IoError;
use crate::measure::{Measurement, Observation};
use crate::params::Unit;
use std::path::PathBuf;

/// Join the seat exports `seats` (seat `k` is `seats[k]`) for a model whose data columns are
/// `columns` ([`crate::io::model_file::ModelFile::data_columns`]): a data set of
/// [`Observation::Seat`] rows, inputs in rad and mm.
pub fn join_seat_exports(seats: &[PathBuf], angles: AngleUnit, lengths: LengthUnit, columns: &[InputSpec]) -> Result<DataSet, IoError> {
    // The columns a controller logs: the joint inputs (not approach directions, not observed joints).
    let joints: Vec<(usize, &InputSpec)> = columns
        .iter()
        .enumerate()
        .filter(|(_, i)| i.approach_of.is_none() && !i.observed)
        .collect();
    let n_inputs = columns.iter().filter(|i| !i.observed).count();
    // Each input's unit factor as the exports state it (none for approach directions).
    let factors: Vec<Option<f64>> = (columns[..n_inputs].iter())
        .map(|i| match i.unit {
            _ if i.approach_of.is_some() => None,
            Unit::Angle => Some(angles.to_rad()),
            Unit::Length => Some(lengths.to_mm()),
            Unit::Dimensionless => Some(1.0),
        })
        .collect();
    // A file given twice would count its seat twice, under two numbers.
    let canonical: Vec<PathBuf> = seats.iter().map(|p| p.canonicalize().unwrap_or_else(|_| p.clone())).collect();
    for (j, c) in canonical.iter().enumerate() {
        if let Some(i) = canonical[..j].iter().position(|d| d == c) {
            return Err(IoError::Invalid {
                path: seats[j].clone(),
                message: format!("given twice (seats {i} and {j}): give each seat's export once, seat k as the k-th --seat"),
            });
        }
    }
    let mut texts: Vec<String> = Vec::new();
    let mut measurements = Vec::new();
    let mut lines = Vec::new();
    // Where each file's rows start.
    let mut starts = Vec::new();
    for (seat, path) in seats.iter().enumerate() {
        starts.push(measurements.len());
        let text = std::fs::read_to_string(path).map_err(|source| IoError::Read {
            path: path.clone(),
            source,
        })?;
        if let Some(i) = texts.iter().position(|t| t.trim() == text.trim() && !t.trim().is_empty()) {
            return Err(IoError::Invalid {
                path: path.clone(),
                message: format!(
                    "the same rows as seat {i}'s export ({}): the same file given twice?",
                    seats[i].display()
                ),
            });
        }
        texts.push(text.clone());
        let before = measurements.len();
        for (n, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            if line.contains(';') {
                return Err(IoError::AtLine {
                    path: path.clone(),
                    line: n + 1,
                    message: super::other_separator(line).unwrap_or_default(),
                });
            }
            let fields: Vec<&str> = line
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|f| !f.is_empty())
                .collect();
            let values: Result<Vec<f64>, _> = fields.iter().map(|f| f.parse::<f64>()).collect();
            let Ok(values) = values else {
                // A header before the first row.
                if measurements.len() == before
                    && fields
                        .iter()
                        .any(|f| f.parse::<f64>().is_err() && f.chars().any(char::is_alphabetic))
                {
                    continue;
                }
                let (column, value) = fields
                    .iter()
                    .enumerate()
                    .find(|(_, f)| f.parse::<f64>().is_err())
                    .map(|(k, f)| (joints.get(k).map_or(format!("{}", k + 1), |(_, i)| i.name.clone()), f.to_string()))
                    .unwrap_or_default();
                return Err(IoError::NotANumber {
                    path: path.clone(),
                    line: n + 1,
                    column,
                    value,
                });
            };
            if values.len() != joints.len() {
                return Err(IoError::AtLine {
                    path: path.clone(),
                    line: n + 1,
                    message: format!(
                        "{} values, the model has {} joint inputs ({}): one column per joint, in the model's order",
                        values.len(),
                        joints.len(),
                        joints.iter().map(|(_, i)| i.name.as_str()).collect::<Vec<_>>().join(", ")
                    ),
                });
            }
            let mut q = vec![0.0; n_inputs];
            for ((k, input), v) in joints.iter().zip(&values) {
                if !v.is_finite() {
                    return Err(IoError::NonFinite {
                        path: path.clone(),
                        line: n + 1,
                        column: input.name.clone(),
                        value: v.to_string(),
                    });
                }
                q[*k] = match input.unit {
                    Unit::Angle => v * angles.to_rad(),
                    Unit::Length => v * lengths.to_mm(),
                    Unit::Dimensionless => *v,
                };
            }
            measurements.push(Measurement {
                q,
                joints: Vec::new(),
                obs: Observation::Seat(seat),
            });
            lines.push(n + 1);
        }
        if measurements.len() - before < crate::instrument::MIN_SEAT_ROWS {
            return Err(IoError::Invalid {
                path: path.clone(),
                message: format!(
                    "{} configuration{}: a seat needs at least {} (the ball placed in it from several orientations)",
                    measurements.len() - before,
                    if measurements.len() - before == 1 { "" } else { "s" },
                    crate::instrument::MIN_SEAT_ROWS
                ),
            });
        }
    }
    let mut qs: Vec<Vec<f64>> = measurements.iter().map(|m| m.q.clone()).collect();
    crate::model::kind::approach_from_order(&columns[..n_inputs], &vec![false; n_inputs], &mut qs);
    for (m, q) in measurements.iter_mut().zip(qs) {
        m.q = q;
    }
    let name = match seats {
        [one] => one.display().to_string(),
        _ => format!("{} seat exports", seats.len()),
    };
    let mut set = DataSet::from_measurements(&name, measurements);
    set.ids = (1..=set.measurements.len() as i64).collect();
    set.lines = lines;
    // Rows beyond the model's limits: a mistake refused with its file and line, else one
    // warning per input over every file ([`super::data_file::BeyondLimits`]).
    let qs: Vec<Vec<f64>> = set.measurements.iter().map(|m| m.q.clone()).collect();
    starts.push(qs.len());
    for (k, path) in seats.iter().enumerate() {
        let rows = starts[k]..starts[k + 1];
        check_limits(
            path,
            &columns[..n_inputs],
            &factors,
            &qs[rows.clone()],
            &set.lines[rows.clone()],
            &set.ids[rows],
        )?;
    }
    set.beyond_limits = check_limits(&set.path, &columns[..n_inputs], &factors, &qs, &set.lines, &set.ids)?;
    Ok(set)
}

/// A warning when some seat has far fewer rows than the others (a seat of 2 rows beside seats of
/// 30: a truncated export, or a file of another seat's leftovers): the seats, their rows and the
/// median. `None` when the seats are even, or are too few rows to tell.
pub fn uneven_seats(set: &DataSet) -> Option<String> {
    let mut rows: std::collections::BTreeMap<usize, usize> = std::collections::BTreeMap::new();
    for m in &set.measurements {
        if let Observation::Seat(k) = m.obs {
            *rows.entry(k).or_default() += 1;
        }
    }
    let mut counts: Vec<usize> = rows.values().copied().collect();
    counts.sort_unstable();
    let median = *counts.get(counts.len() / 2)?;
    if rows.len() < 3 || median < 10 {
        return None;
    }
    let thin: Vec<String> = rows
        .iter()
        .filter(|(_, &n)| n * 5 < median)
        .map(|(k, n)| format!("seat {k} ({n} rows)"))
        .collect();
    (!thin.is_empty()).then(|| {
        format!(
            "{} beside a median of {median} rows per seat: a truncated export or another seat's leftovers? (a seat needs rows from several orientations to place it)",
            thin.join(", ")
        )
    })
}
