//! # kinecal — kinematic calibration of parallel and serial manipulators
//!
//! model → identifiability → measurement planning → identification → validation → compensation.
//!
//! Units inside the library: millimetres and radians. Twists are ordered (v, ω) (see [`se3`]).
//!
//! One call per step: [`calibrate::calibrate`] identifies a model file's geometry (and the
//! measurement and tool frames) from a data set; the CLI and the Python bindings are thin layers
//! over such calls. A complete calibration of the built-in IRB 120 on simulated tracker data:
//!
//! ```
//! use kinecal::calibrate::{calibrate, CalibrationOptions};
//! use kinecal::io::{builtin, data_file::DataSet};
//! use kinecal::measure::{Measurement, Observation};
//! use kinecal::simulate::{perturbed, random_errors};
//! use kinecal::simulate::random_configurations;
//! use kinecal::Mechanism;
//! use rand::SeedableRng;
//!
//! let file = builtin::model_file("irb120").unwrap();
//! let nominal = file.build();
//! let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
//! // A virtual prototype: ±0.5 mm / ±0.1° errors on every geometric parameter.
//! let truth = perturbed(&nominal, &random_errors(&*nominal, &mut rng, 0.5, 0.1f64.to_radians(), None));
//! let measure = |qs: Vec<Vec<f64>>| -> Vec<Measurement> {
//!     qs.into_iter().map(|q| Measurement { joints: Vec::new(), obs: Observation::Pose(truth.forward(&q).unwrap()), q }).collect()
//! };
//! let ident = measure(random_configurations(&*nominal, &file.inputs(), 40, &mut rng).unwrap());
//! let valid = measure(random_configurations(&*nominal, &file.inputs(), 10, &mut rng).unwrap());
//!
//! let cal = calibrate(
//!     &file,
//!     &DataSet::from_measurements("ident", ident),
//!     Some(&DataSet::from_measurements("valid", valid)),
//!     &CalibrationOptions::default(),
//! )
//! .unwrap();
//! let held_out = cal.report.validation.as_ref().unwrap().after_stats.position_max_mm;
//! assert!(held_out < 1e-6, "held-out error {held_out} mm");
//! println!("{}", cal.report.verdict.status.as_str()); // "calibrated"
//! let calibrated_toml = cal.model_file.to_toml().unwrap(); // the calibrated model file
//! assert!(calibrated_toml.contains("[frames"));
//! ```
#![warn(missing_docs)]

pub mod assess;
pub mod calibrate;
pub mod compensate;
pub mod design;
pub mod drift;
pub mod error;
pub mod filter;
pub mod identifiability;
pub mod identify;
pub mod instrument;
pub mod io;
pub mod measure;
pub mod model;
pub mod params;
pub mod predict;
pub mod register;
pub mod report;
pub mod se3;
pub mod simulate;
#[cfg(feature = "studies")]
pub mod studies;
pub mod validate;

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
