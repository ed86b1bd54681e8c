//! Rows at which a model does not assemble (its forward kinematics fails: a closed loop that
//! does not close there, a Newton solve from home that does not converge), set aside with a line
//! as a blunder is, instead of rejecting the whole file, when the rest is enough.
use super::DataSet;
use crate::error::CalibError;
use crate::Mechanism;

/// Rows set aside by [`DataSet::set_aside_unassembled`]: their lines and ids, and the first
/// row's reason.
#[derive(Debug, Clone, PartialEq)]
pub struct Unassembled {
    /// 1-based lines of the rows set aside.
    pub lines: Vec<usize>,
    /// Their ids.
    pub ids: Vec<i64>,
    /// Why the first of them failed.
    pub reason: String,
}

impl Unassembled {
    /// One line naming the file, the rows (at most 20 lines shown) and the reason.
    pub fn note(&self, data: &DataSet) -> String {
        let shown: Vec<String> = self.lines.iter().take(20).map(ToString::to_string).collect();
        let more = if self.lines.len() > 20 { ", …" } else { "" };
        format!(
            "{}: {} set aside: the model does not assemble there ({}): line{} {}{more}",
            data.path.display(),
            match self.lines.len() {
                1 => "1 row".to_string(),
                n => format!("{n} rows"),
            },
            self.reason,
            if self.lines.len() == 1 { "" } else { "s" },
            shown.join(", ")
        )
    }
}

impl DataSet {
    /// Set aside the rows at which `model`'s forward kinematics fails, when they are fewer than
    /// half of the rows (the rest is then enough to go on: what is left is checked as any data
    /// set is). `Ok(None)` when every row assembles; an error naming the first failing row when
    /// too many fail (then the model, not a few rows, is wrong).
    pub fn set_aside_unassembled(&mut self, model: &dyn Mechanism) -> Result<Option<Unassembled>, CalibError> {
        let failed: Vec<(usize, String)> = self
            .measurements
            .iter()
            .enumerate()
            .filter_map(|(i, m)| model.forward(&m.q).err().map(|e| (i, e.to_string())))
            .collect();
        let Some((first, reason)) = failed.first().cloned() else {
            return Ok(None);
        };
        if 2 * failed.len() >= self.measurements.len() {
            return Err(CalibError::InvalidOption(format!(
                "{}:{}: {} of {} rows do not assemble on the model (first: {reason}): check the model against the data",
                self.path.display(),
                self.lines.get(first).copied().unwrap_or(first + 1),
                failed.len(),
                self.measurements.len()
            )));
        }
        let out: Vec<usize> = failed.iter().map(|(i, _)| *i).collect();
        let aside = Unassembled {
            lines: out.iter().map(|&i| self.lines.get(i).copied().unwrap_or(i + 1)).collect(),
            ids: out.iter().map(|&i| self.ids.get(i).copied().unwrap_or(i as i64)).collect(),
            reason,
        };
        let mut keep = vec![true; self.measurements.len()];
        for &i in &out {
            keep[i] = false;
        }
        retain_rows(&mut self.measurements, &keep);
        retain_rows(&mut self.lines, &keep);
        retain_rows(&mut self.ids, &keep);
        if self.reflectors.len() == keep.len() {
            retain_rows(&mut self.reflectors, &keep);
        }
        Ok(Some(aside))
    }
}

/// Keep the rows whose flag is set.
fn retain_rows<T>(v: &mut Vec<T>, keep: &[bool]) {
    let mut k = 0;
    v.retain(|_| {
        k += 1;
        keep.get(k - 1).copied().unwrap_or(true)
    });
}
