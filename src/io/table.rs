//! Numeric CSV tables with a header line.
use super::IoError;
use std::path::{Path, PathBuf};

/// A numeric table read from a CSV file with a header.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// The file it came from.
    pub path: PathBuf,
    /// Column names, as in the header.
    pub columns: Vec<String>,
    /// Rows of values.
    pub rows: Vec<Vec<f64>>,
    /// 1-based line number of each row in the file.
    pub lines: Vec<usize>,
}

impl Table {
    /// Index of a column, or a [`IoError::MissingColumn`] naming the file.
    pub fn column(&self, name: &str) -> Result<usize, IoError> {
        self.columns.iter().position(|c| c == name).ok_or_else(|| IoError::MissingColumn {
            path: self.path.clone(),
            column: name.to_string(),
            header: self.columns.join(","),
        })
    }

    /// Values of one column.
    pub fn values(&self, name: &str) -> Result<Vec<f64>, IoError> {
        let c = self.column(name)?;
        Ok(self.rows.iter().map(|r| r[c]).collect())
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }
}

/// Read a CSV file whose every field is a number, with a header line. Blank lines and lines
/// starting with `#` are skipped. Every row must have as many fields as the header; every field
/// must parse as a finite number. Errors name the file, the line and the column.
pub fn read_table(path: &Path) -> Result<Table, IoError> {
    let text = super::read_text(path)?;
    parse_table(path, &text)
}

/// [`read_table`], except that an empty field is read as NaN (a tracker's lost beam): the caller
/// decides what an empty cell means.
pub fn read_table_with_gaps(path: &Path) -> Result<Table, IoError> {
    let text = super::read_text(path)?;
    parse(path, &text, true)
}

/// [`read_table`] on text already in memory (`path` is only used in messages).
pub fn parse_table(path: &Path, text: &str) -> Result<Table, IoError> {
    parse(path, text, false)
}

/// [`read_table_with_gaps`] on text already in memory.
pub fn parse_table_with_gaps(path: &Path, text: &str) -> Result<Table, IoError> {
    parse(path, text, true)
}

fn parse(path: &Path, text: &str, gaps: bool) -> Result<Table, IoError> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let (_, header) = lines.next().ok_or_else(|| IoError::Empty {
        path: path.to_path_buf(),
        expected: "(any)".into(),
    })?;
    if let Some(message) = super::other_separator(header) {
        return Err(IoError::Invalid {
            path: path.to_path_buf(),
            message,
        });
    }
    let columns: Vec<String> = header.split(',').map(|s| s.trim().to_string()).collect();
    let mut rows = Vec::new();
    let mut line_numbers = Vec::new();
    for (i, line) in lines {
        let lineno = i + 1;
        let fields: Vec<&str> = line.split(',').map(|s| s.trim()).collect();
        if fields.len() != columns.len() {
            return Err(IoError::RowLength {
                path: path.to_path_buf(),
                line: lineno,
                expected: columns.len(),
                found: fields.len(),
            });
        }
        let mut row = Vec::with_capacity(fields.len());
        for (f, col) in fields.iter().zip(&columns) {
            if gaps && f.is_empty() {
                row.push(f64::NAN);
                continue;
            }
            let v: f64 = f.parse().map_err(|_| IoError::NotANumber {
                path: path.to_path_buf(),
                line: lineno,
                column: col.clone(),
                value: f.to_string(),
            })?;
            if !v.is_finite() {
                return Err(IoError::NonFinite {
                    path: path.to_path_buf(),
                    line: lineno,
                    column: col.clone(),
                    value: f.to_string(),
                });
            }
            row.push(v);
        }
        rows.push(row);
        line_numbers.push(lineno);
    }
    Ok(Table {
        path: path.to_path_buf(),
        columns,
        rows,
        lines: line_numbers,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_reports_lines() {
        let p = Path::new("t.csv");
        let t = parse_table(p, "idx,x\n0,1.5\n\n1,2\n").unwrap();
        assert_eq!(t.rows, vec![vec![0.0, 1.5], vec![1.0, 2.0]]);
        assert_eq!(t.lines, vec![2, 4]);
        let e = parse_table(p, "idx,x\n0,1.5\n1\n").unwrap_err().to_string();
        assert_eq!(e, "t.csv:3: expected 2 fields, found 1");
        let e = parse_table(p, "idx,x\n0,abc\n").unwrap_err().to_string();
        assert_eq!(e, "t.csv:2: column 'x': 'abc' is not a number");
        let e = parse_table(p, "idx,x\n0,NaN\n").unwrap_err().to_string();
        assert_eq!(e, "t.csv:2: column 'x': non-finite value 'NaN'");
    }
}
