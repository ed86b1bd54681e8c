//! # kinecal — kinematic calibration of parallel and serial manipulators
//!
//! model → identifiability → measurement planning → identification → validation → compensation.
//!
//! Units inside the library: millimetres and radians. Twists are ordered (v, ω) (see [`se3`]).
#![warn(missing_docs)]

pub mod calibrate;
pub mod design;
pub mod error;
pub mod identifiability;
pub mod identify;
pub mod io;
pub mod measure;
pub mod model;
pub mod params;
pub mod register;
pub mod report;
pub mod se3;
pub mod simulate;
#[cfg(feature = "studies")]
pub mod studies;
pub mod workflow;

/// The IRB 120 dataset pipeline ([`studies::irb120`]), under its earlier name.
#[cfg(feature = "studies")]
pub use studies::irb120 as tracker_calibration;
/// The 5-DOF paper's study ([`studies::pm5`]), under its earlier name.
#[cfg(feature = "studies")]
pub use studies::pm5 as study;
/// The 3T1R study ([`studies::t3r1`]).
#[cfg(feature = "studies")]
pub use studies::t3r1;

pub use error::{CalibError, KinError};
pub use model::Mechanism;
