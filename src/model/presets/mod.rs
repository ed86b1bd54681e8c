//! Ready-made mechanisms: the 5-DOF PUU-2PR(RPRR)S machine of the 5-DOF paper ([`pm5`]) and a
//! 6-UPS Stewart platform ([`stewart`]), both through [`crate::model::closed`]. (The 3T1R machine
//! of the 3T1R paper, not yet a model-file kind, lives with its study in `crate::studies`.)
pub mod pm5;
pub mod stewart;
