//! kinecal integration tests (one binary, one module per concern).
mod chain;
mod identify;
mod se3_props;
mod t3r1;
