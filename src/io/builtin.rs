//! The built-in models ([`crate::model::builtin`]) as model files.
use super::model_file::ModelFile;
use super::IoError;
pub use crate::model::builtin::{irb120, list};
use std::path::Path;

/// The built-in model called `name` as a model file, if there is one.
pub fn model_file(name: &str) -> Option<ModelFile> {
    let description = list().into_iter().find(|(n, _)| *n == name)?.1;
    let mut file = ModelFile::new(name, crate::model::builtin::spec(name)?);
    file.description = Some(description.to_string());
    Some(file)
}

impl ModelFile {
    /// A model file path, or the name of a built-in model ([`crate::model::builtin`]) when no
    /// file of that name exists.
    pub fn load_or_builtin(arg: &str) -> Result<ModelFile, IoError> {
        let path = Path::new(arg);
        if path.exists() {
            return ModelFile::load(path);
        }
        model_file(arg).ok_or_else(|| IoError::Invalid {
            path: path.to_path_buf(),
            message: format!(
                "no such file, and not a built-in model (built-in: {})",
                list().iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
            ),
        })
    }
}
