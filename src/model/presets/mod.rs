//! Ready-made mechanisms of the seed papers.
pub mod t3r1;
