//! kinecal integration tests (one binary, one module per concern).
mod chain;
mod cli;
mod closed;
mod design;
mod dh;
mod identify;
mod irb120;
mod model_file;
mod parallel_workflow;
mod plan_pm5;
mod quickstart;
mod registration;
mod robustness;
mod se3_props;
mod study;
mod t3r1;
mod workflow;
