//! The built-in models ([`crate::model::builtin`]) as model files.
use super::model_file::ModelFile;
use super::IoError;
pub use crate::model::builtin::irb120;
use std::path::Path;

/// Parallel machines that exist only as model files (`kind = "limbs"`, `examples/models/`):
/// name, description, text.
const FILES: [(&str, &str, &str); 8] = [
    (
        "hexapod-6rus",
        "6-RUS rotary hexapod as limbs (cranks 60 mm, rods 250 mm; 126 error parameters, rank 66)",
        include_str!("../../examples/models/hexapod-6rus.toml"),
    ),
    (
        "head-3prs",
        "3-PRS tilting head as limbs (height and tool axis; 63 error parameters, rank 33)",
        include_str!("../../examples/models/head-3prs.toml"),
    ),
    (
        "linear-delta",
        "linear delta 3-PUU as limbs (position; 72 error parameters, rank 30)",
        include_str!("../../examples/models/linear-delta.toml"),
    ),
    (
        "stewart-limbs",
        "the 'stewart' platform written as limbs (90 error parameters, rank 42)",
        include_str!("../../examples/models/stewart-limbs.toml"),
    ),
    (
        "pm5-limbs",
        "the 'pm5' machine written as limbs, its RPRR sub-closed loops as limbs on the legs (120 error parameters, rank 48)",
        include_str!("../../examples/models/pm5-limbs.toml"),
    ),
    (
        "t3r1-chain",
        "one chain of the 3T1R machine (slider, two parallelograms, revolute; every joint sensed) as limbs (36 error parameters, rank 20)",
        include_str!("../../examples/models/t3r1-chain.toml"),
    ),
    (
        "t3r1",
        "3T1R machine of the 3T1R paper, four sliders and five observed encoders, as limbs (its minimal-constraint equivalent; 117 error parameters, rank 43 with the encoders read, 38 from poses alone)",
        include_str!("../../examples/models/t3r1.toml"),
    ),
    (
        "planar-3rrr",
        "planar 3-RRR as limbs (x, y and yaw; overconstrained: 36 of its 72 error parameters held as drawn, rank 21)",
        include_str!("../../examples/models/planar-3rrr.toml"),
    ),
];

/// Names and one-line descriptions of the built-in models: the presets
/// ([`crate::model::builtin::list`]) and the machines shipped as limbs files.
pub fn list() -> Vec<(&'static str, &'static str)> {
    let mut out = crate::model::builtin::list();
    out.extend(FILES.iter().map(|(n, d, _)| (*n, *d)));
    out
}

/// The built-in model called `name` as a model file, if there is one.
pub fn model_file(name: &str) -> Option<ModelFile> {
    if let Some((_, _, text)) = FILES.iter().find(|(n, _, _)| *n == name) {
        return ModelFile::load_str(Path::new(name), text).ok();
    }
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
