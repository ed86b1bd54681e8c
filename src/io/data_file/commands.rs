//! Files that hold the inputs of each row: plans, commands, the configurations to command.
use super::{classify, data_from_table, header_of, input_headers, InputColumns, Slot};
use crate::io::model_file::InputSpec;
use crate::io::table::{read_table, Table};
use crate::io::IoError;
use std::path::Path;

/// The configurations of a file that holds the inputs of each row: a plan, a measurement data
/// file (its measurement columns are not read) or an inputs-only file such as the commands of
/// `kinecal compensate`. Inputs in mm / rad, one per row.
pub fn read_configurations(path: &Path, inputs: &[InputSpec]) -> Result<Vec<Vec<f64>>, IoError> {
    Ok(read_commands(path, inputs)?.1)
}

/// The ids and inputs (mm / rad) of a file that holds the inputs of each row, as
/// [`read_configurations`] reads it: also a targets file holding the commands (the test poses of
/// `kinecal plan --iso9283`: `id`, pose and input columns). Ids: the file's (row numbers from 0
/// without an `id` column). These are configurations to command: in a data file, a row beyond
/// the model's limits is an error (a measured data file keeps it, [`BeyondLimits`]).
pub fn read_commands(path: &Path, inputs: &[InputSpec]) -> Result<(Vec<i64>, Vec<Vec<f64>>), IoError> {
    let text = crate::io::read_text(path)?;
    let table = crate::io::table::parse_table_with_gaps(path, &text)?;
    let inputs_only = table
        .columns
        .iter()
        .all(|c| matches!(classify(path, c, inputs), Ok((Slot::Id | Slot::Input(_), _))));
    if inputs_only {
        // Read as `read_inputs` reads it: an empty cell is an error, not a lost measurement.
        return inputs_from_table(path, &crate::io::table::parse_table(path, &text)?, inputs);
    }
    let data = data_from_table(&table, inputs, InputColumns::Required)?;
    // Configurations to command: kinecal commands a machine within its model's limits.
    if let Some(b) = data.beyond_limits.first() {
        let row = data.ids.iter().position(|id| Some(id) == b.ids.first()).unwrap_or(0);
        return Err(IoError::AtLine {
            path: path.to_path_buf(),
            line: data.lines[row],
            message: format!(
                "{}: {} configuration{} beyond the model's limits [{:.4}, {:.4}] {u} (by up to {:.4} {u}): kinecal commands a machine within its limits",
                b.input,
                b.rows,
                if b.rows == 1 { "" } else { "s" },
                b.limits.0,
                b.limits.1,
                b.max_excess,
                u = b.unit
            ),
        });
    }
    Ok((data.ids, data.measurements.into_iter().map(|m| m.q).collect()))
}

/// Read an inputs-only file (an optional `id` column and one column per input, with unit
/// suffixes), such as the commands `kinecal compensate` writes. Returns the ids (row numbers from
/// 0 without an `id` column) and the inputs in mm / rad. Any other column is an error.
pub fn read_inputs(path: &Path, inputs: &[InputSpec]) -> Result<(Vec<i64>, Vec<Vec<f64>>), IoError> {
    inputs_from_table(path, &read_table(path)?, inputs)
}

/// [`read_inputs`] of a table already read.
fn inputs_from_table(path: &Path, table: &Table, inputs: &[InputSpec]) -> Result<(Vec<i64>, Vec<Vec<f64>>), IoError> {
    let mut slots = Vec::with_capacity(table.columns.len());
    for col in &table.columns {
        match classify(path, col, inputs)? {
            (s @ (Slot::Id | Slot::Input(_)), f) => slots.push((s, f)),
            _ => {
                return Err(IoError::AtLine {
                    path: path.to_path_buf(),
                    line: 1,
                    message: format!(
                        "column '{col}': an inputs file holds only id and the input columns ({})",
                        input_headers(inputs).join(",")
                    ),
                })
            }
        }
    }
    for (k, inp) in inputs.iter().enumerate() {
        if !slots.iter().any(|(s, _)| matches!(s, Slot::Input(j) if *j == k)) {
            if inp.approach_of.is_some() {
                continue;
            }
            return Err(IoError::MissingColumn {
                path: path.to_path_buf(),
                column: header_of(inp),
                header: table.columns.join(","),
            });
        }
    }
    let mut ids = Vec::with_capacity(table.len());
    let mut qs = Vec::with_capacity(table.len());
    for (r, row) in table.rows.iter().enumerate() {
        let mut q = vec![0.0; inputs.len()];
        let mut id = r as i64;
        for ((slot, f), v) in slots.iter().zip(row) {
            match slot {
                Slot::Id => id = *v as i64,
                Slot::Input(k) => q[*k] = v * f,
                _ => {}
            }
        }
        ids.push(id);
        qs.push(q);
    }
    let present: Vec<bool> = (0..inputs.len())
        .map(|k| slots.iter().any(|(s, _)| matches!(s, Slot::Input(j) if *j == k)))
        .collect();
    crate::model::kind::approach_from_order(inputs, &present, &mut qs);
    Ok((ids, qs))
}
