//! Laser-tracker data sets (written next).
