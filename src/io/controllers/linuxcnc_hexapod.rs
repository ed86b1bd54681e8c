//! (in progress)
use super::{ControllerError, Export};
use crate::io::model_file::ModelFile;

/// Not yet.
pub fn export(_file: &ModelFile) -> Result<Export, ControllerError> {
    Err(ControllerError::Unsupported("not yet".into()))
}

/// Not yet.
pub fn import(_text: &str) -> Result<ModelFile, ControllerError> {
    Err(ControllerError::Unsupported("not yet".into()))
}
