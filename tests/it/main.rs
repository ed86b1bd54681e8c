//! kinecal integration tests (one binary, one module per concern).
mod chain;
mod design;
mod identify;
mod se3_props;
