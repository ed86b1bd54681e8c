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
pub mod study;
pub mod t3r1;
pub mod tracker_calibration;
pub mod workflow;

pub use error::{CalibError, KinError};
pub use model::Mechanism;
