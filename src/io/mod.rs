//! Files: numeric CSV tables with line-accurate errors, laser-tracker data sets, model files,
//! URDF.
pub mod builtin;
pub mod controllers;
pub mod data_file;
pub mod exports;
pub mod model_file;
pub mod output;
pub mod seat_exports;
pub mod split;
pub mod table;
pub mod test_poses;
pub mod tracker;
pub mod urdf;

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

/// The separator a CSV line uses when it is not ',': `;` (a spreadsheet in a locale with decimal
/// commas) or tabs. `None` for a line with commas, or a single field.
pub(crate) fn other_separator(line: &str) -> Option<String> {
    let sep = [(';', "';'"), ('\t', "tabs")]
        .into_iter()
        .find(|(c, _)| !line.contains(',') && line.contains(*c))?;
    Some(format!(
        "fields separated by {} (`{}`): kinecal reads comma-separated files (replace the separator by ',' and any decimal commas by points)",
        sep.1,
        line.trim().chars().take(60).collect::<String>()
    ))
}

/// Read a text file the way users' tools write them: a UTF-8 byte-order mark (Excel's
/// "CSV UTF-8") is dropped, and bytes that are not UTF-8 are an error naming the line and what to
/// do, instead of a confusing message about the first column.
pub fn read_text(path: &std::path::Path) -> Result<String, IoError> {
    let bytes = std::fs::read(path).map_err(|source| IoError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
    match std::str::from_utf8(bytes) {
        Ok(s) => Ok(s.to_string()),
        Err(e) => {
            let at = e.valid_up_to();
            let line = 1 + bytes[..at].iter().filter(|&&b| b == b'\n').count();
            Err(IoError::AtLine {
                path: path.to_path_buf(),
                line,
                message: format!(
                    "byte {:#04x} is not UTF-8 text; save the file as UTF-8 (or plain ASCII) and try again",
                    bytes[at]
                ),
            })
        }
    }
}

/// Write `contents` to `path` whole or not at all: to a temporary file in the same directory,
/// flushed, then renamed over `path`. A failure (full disk, missing directory) leaves any
/// existing file at `path` untouched and no temporary file behind.
pub fn write_atomic(path: &std::path::Path, contents: &[u8]) -> Result<(), IoError> {
    use std::io::Write as _;
    let err = |source| IoError::Write {
        path: path.to_path_buf(),
        source,
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let tmp = dir.join(format!(".{name}.kinecal-{}.tmp", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(contents)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(err(e));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bom_is_dropped_and_bad_bytes_name_their_line() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.csv");
        std::fs::write(&p, b"\xEF\xBB\xBFid,x\n1,2\n").unwrap();
        assert_eq!(read_text(&p).unwrap(), "id,x\n1,2\n");
        std::fs::write(&p, b"id,x\n1,2\n3,\xFF\n").unwrap();
        let e = read_text(&p).unwrap_err().to_string();
        assert!(e.contains("a.csv:3:") && e.contains("0xff") && e.contains("UTF-8"), "{e}");
    }

    #[test]
    fn atomic_write_leaves_the_old_file_on_failure() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.toml");
        write_atomic(&p, b"old").unwrap();
        write_atomic(&p, b"new").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"new");
        let bad = dir.path().join("no-such-dir").join("x.toml");
        assert!(write_atomic(&bad, b"x").is_err());
        assert!(!bad.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "no temporary file left");
    }
}
