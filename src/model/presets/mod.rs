//! Ready-made mechanisms of the seed papers: the 5-DOF PUU-2PR(RPRR)S machine of the 5-DOF paper
//! ([`pm5`]) and a 6-UPS Stewart platform ([`stewart`]), both through [`crate::model::closed`],
//! and the 3T1R symmetrical machine of the 3T1R paper ([`t3r1`]), as local-POE branched chains.
pub mod pm5;
pub mod stewart;
pub mod t3r1;
