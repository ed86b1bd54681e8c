//! The papers' studies and the dataset pipeline, apart from the core (feature `studies`, on by
//! default): the core never imports them; they use the core like any user would.
//!
//! * [`pm5`]: the simulation study of the 5-DOF paper (identifiability, Monte Carlo, design);
//! * [`t3r1_machine`] and [`t3r1`]: the 3T1R machine of the 3T1R paper as branched local-POE
//!   chains, and its §6 simulation study;
//! * [`irb120`]: the IRB 120 laser-tracker dataset pipeline (registration schemes side by side
//!   with the general path);
//! * [`predicted`]: the accuracy a calibration predicts against the spread of repeated
//!   calibrations (virtual prototypes, many noise draws).
pub mod irb120;
pub mod pm5;
pub mod predicted;
pub mod t3r1;
pub mod t3r1_machine;
pub mod t3r1_whole;
