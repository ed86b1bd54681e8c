//! kinecal integration tests (one binary, one module per concern).
mod chain;
mod identify;
mod model_file;
mod se3_props;
mod workflow;
