//! One module per subcommand: each parses its arguments, calls the library and prints.
pub mod irb120;
pub mod plan;
