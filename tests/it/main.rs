//! kinecal integration tests (one binary, one module per concern).
mod chain;
mod closed;
mod identify;
mod irb120;
mod model_file;
mod parallel_workflow;
mod se3_props;
mod study;
mod workflow;
