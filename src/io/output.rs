//! A command's output files, written all together or not at all.
//!
//! The rules every kinecal command follows (the command line documents them under `--force`):
//!
//! * an output path may not be one of the command's inputs, nor another of its outputs;
//! * an existing file is replaced only with `force` (otherwise the command stops before it
//!   computes anything, naming the file);
//! * outputs are first written to temporary files beside their destinations and renamed into
//!   place only when every one of them has been written, so a failed command (a full disk, a
//!   missing directory, a failed check) leaves no new or changed file behind.
use super::IoError;
use std::path::{Path, PathBuf};

/// The outputs of one command, declared up front and committed together.
#[derive(Debug)]
pub struct Outputs {
    force: bool,
    inputs: Vec<(PathBuf, PathBuf)>,
    outputs: Vec<(PathBuf, PathBuf)>,
    staged: Vec<(PathBuf, PathBuf)>,
}

/// A path's comparable form: the canonical directory joined with the file name (the file itself
/// may not exist yet).
fn identity(path: &Path) -> PathBuf {
    if let Ok(p) = path.canonicalize() {
        return p;
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let dir = dir.canonicalize().unwrap_or(dir);
    match path.file_name() {
        Some(n) => dir.join(n),
        None => dir,
    }
}

impl Outputs {
    /// No outputs yet; `force` allows replacing existing files.
    pub fn new(force: bool) -> Self {
        Outputs {
            force,
            inputs: Vec::new(),
            outputs: Vec::new(),
            staged: Vec::new(),
        }
    }

    /// Declare a file the command reads (outputs may not replace it).
    pub fn input(&mut self, path: &Path) -> &mut Self {
        self.inputs.push((path.to_path_buf(), identity(path)));
        self
    }

    /// Declare a file the command will write: refused when it is an input, another output, an
    /// existing file without `force`, a directory, or in a directory that does not exist.
    pub fn output(&mut self, path: &Path) -> Result<&mut Self, IoError> {
        let id = identity(path);
        let invalid = |message: String| IoError::Invalid {
            path: path.to_path_buf(),
            message,
        };
        if let Some((p, _)) = self.inputs.iter().find(|(_, i)| *i == id) {
            return Err(invalid(format!(
                "this output would replace the input {}; choose another output file",
                p.display()
            )));
        }
        if let Some((p, _)) = self.outputs.iter().find(|(_, i)| *i == id) {
            return Err(invalid(format!(
                "given for two outputs (also {}); choose different files",
                p.display()
            )));
        }
        if path.is_dir() {
            return Err(invalid("is a directory; give a file name".into()));
        }
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            if !dir.is_dir() {
                return Err(invalid(format!("directory {} does not exist; create it first", dir.display())));
            }
        }
        if path.exists() && !self.force {
            return Err(invalid("exists already; pass --force to replace it, or choose another file".into()));
        }
        self.outputs.push((path.to_path_buf(), id));
        Ok(self)
    }

    /// Declare an optional output.
    pub fn output_opt(&mut self, path: Option<&Path>) -> Result<&mut Self, IoError> {
        match path {
            Some(p) => self.output(p),
            None => Ok(self),
        }
    }

    /// Write the contents of a declared output to its temporary file.
    pub fn stage(&mut self, path: &Path, contents: &[u8]) -> Result<(), IoError> {
        use std::io::Write as _;
        let id = identity(path);
        if !self.outputs.iter().any(|(_, i)| *i == id) {
            return Err(IoError::Invalid {
                path: path.to_path_buf(),
                message: "internal: output written without being declared".into(),
            });
        }
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let tmp = dir.join(format!(".{name}.kinecal-{}-{}.tmp", std::process::id(), self.staged.len()));
        // Remember the temporary file before writing it, so a failed write is cleaned up too.
        self.staged.push((tmp.clone(), path.to_path_buf()));
        let result = (|| {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(contents)?;
            f.sync_all()
        })();
        result.map_err(|source| IoError::Write {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Move every staged file into place. Call it once everything succeeded.
    pub fn commit(mut self) -> Result<(), IoError> {
        let staged = std::mem::take(&mut self.staged);
        for (k, (tmp, dest)) in staged.iter().enumerate() {
            if let Err(source) = std::fs::rename(tmp, dest) {
                for (t, _) in &staged[k..] {
                    let _ = std::fs::remove_file(t);
                }
                return Err(IoError::Write {
                    path: dest.clone(),
                    source,
                });
            }
        }
        Ok(())
    }
}

impl Drop for Outputs {
    /// Staged but uncommitted files are removed: a failed command leaves nothing behind.
    fn drop(&mut self) {
        for (tmp, _) in &self.staged {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_refuse_inputs_duplicates_and_existing_files() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("data.csv"), "x").unwrap();
        let mut o = Outputs::new(false);
        o.input(&d.join("data.csv"));
        let e = o.output(&d.join("data.csv")).unwrap_err().to_string();
        assert!(e.contains("would replace the input"), "{e}");
        o.output(&d.join("a.toml")).unwrap();
        let e = o.output(&d.join(".").join("a.toml")).unwrap_err().to_string();
        assert!(e.contains("two outputs"), "{e}");
        std::fs::write(d.join("old.toml"), "x").unwrap();
        let e = o.output(&d.join("old.toml")).unwrap_err().to_string();
        assert!(e.contains("--force"), "{e}");
        let e = o.output(&d.join("nodir").join("r.html")).unwrap_err().to_string();
        assert!(e.contains("does not exist"), "{e}");
        assert!(Outputs::new(true).output(&d.join("old.toml")).is_ok());
    }

    #[test]
    fn nothing_is_written_unless_committed() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        {
            let mut o = Outputs::new(false);
            o.output(&d.join("a.toml")).unwrap().output(&d.join("b.csv")).unwrap();
            o.stage(&d.join("a.toml"), b"a").unwrap();
            // dropped without commit: a later step failed
        }
        assert_eq!(std::fs::read_dir(d).unwrap().count(), 0);
        let mut o = Outputs::new(false);
        o.output(&d.join("a.toml")).unwrap().output(&d.join("b.csv")).unwrap();
        o.stage(&d.join("a.toml"), b"a").unwrap();
        o.stage(&d.join("b.csv"), b"b").unwrap();
        o.commit().unwrap();
        assert_eq!(std::fs::read(d.join("a.toml")).unwrap(), b"a");
        assert_eq!(std::fs::read(d.join("b.csv")).unwrap(), b"b");
        assert_eq!(std::fs::read_dir(d).unwrap().count(), 2);
    }
}
