//! Built-in closed-loop mechanisms: the 5-DOF PUU-2PR(RPRR)S machine of the 5-DOF paper
//! ([`pm5`]) and a 6-UPS Stewart platform ([`stewart`]), both through [`crate::model::closed`].
pub mod pm5;
pub mod stewart;
