//! Data files (written next).
