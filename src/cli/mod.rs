//! One module per subcommand: each parses its arguments, calls the library and prints.
pub mod compensate;
pub mod data;
pub mod identifiability;
pub mod identify;
pub mod irb120;
pub mod model;
pub mod plan;
pub mod progress;
pub mod simulate;
pub mod study;
pub mod study_t3r1;
pub mod validate;
