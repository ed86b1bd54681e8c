//! Files: numeric CSV tables with line-accurate errors, laser-tracker data sets.
pub mod data_file;
pub mod model_file;
pub mod table;
pub mod tracker;

use std::path::PathBuf;
use thiserror::Error;

/// Errors reading or writing kinecal's files. Every variant names the file, and the line or key
/// when there is one, so the command line can print one line that says what to fix.
#[derive(Debug, Error)]
pub enum IoError {
    /// The file cannot be opened or read.
    #[error("{}: cannot read: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The file cannot be written.
    #[error("{}: cannot write: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The file has no header line.
    #[error("{}: empty file (expected a header line with columns {expected})", path.display())]
    Empty {
        /// The file.
        path: PathBuf,
        /// Expected columns.
        expected: String,
    },
    /// A required column is missing from the header.
    #[error("{}:1: missing column '{column}' (header has: {header})", path.display())]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// Missing column name.
        column: String,
        /// The header as found.
        header: String,
    },
    /// A column the reader does not know.
    #[error("{}:1: unknown column '{column}' (expected: {expected})", path.display())]
    UnknownColumn {
        /// The file.
        path: PathBuf,
        /// The unknown column.
        column: String,
        /// Expected columns.
        expected: String,
    },
    /// A row with the wrong number of fields.
    #[error("{}:{line}: expected {expected} fields, found {found}", path.display())]
    RowLength {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Expected field count.
        expected: usize,
        /// Found field count.
        found: usize,
    },
    /// A field that is not a number.
    #[error("{}:{line}: column '{column}': '{value}' is not a number", path.display())]
    NotANumber {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Column name.
        column: String,
        /// The text found.
        value: String,
    },
    /// A NaN or infinite value.
    #[error("{}:{line}: column '{column}': non-finite value '{value}'", path.display())]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Column name.
        column: String,
        /// The text found.
        value: String,
    },
    /// Two files that must describe the same poses do not.
    #[error("{}: {found} rows but {} has {expected}; every file must have one row per pose", path.display(), other.display())]
    RowCountMismatch {
        /// The file.
        path: PathBuf,
        /// Its row count.
        found: usize,
        /// The reference file.
        other: PathBuf,
        /// The reference row count.
        expected: usize,
    },
    /// Pose indices that disagree between files.
    #[error("{}:{line}: pose index {found} where {} has {expected}", path.display(), other.display())]
    IndexMismatch {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Index found.
        found: i64,
        /// The reference file.
        other: PathBuf,
        /// Index expected.
        expected: i64,
    },
    /// A content problem at a known line (and, for TOML, key).
    #[error("{}:{line}: {message}", path.display())]
    AtLine {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong, naming the key or column.
        message: String,
    },
    /// Any other content problem.
    #[error("{}: {message}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}
