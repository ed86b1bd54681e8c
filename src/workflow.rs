//! The names of the earlier catch-all `workflow` module, kept for code written against it: the
//! items now live in [`crate::validate`] (errors, statistics, outliers), [`crate::compensate`]
//! (commands from targets) and [`crate::simulate`] (virtual prototypes, configurations).
pub use crate::compensate::{compensate, target_poses, CompensationError, COMPENSATION_STARTS};
pub use crate::simulate::{
    default_noise, input_range, random_configurations, random_inputs, reflector_centres, virtual_prototype, REFLECTORS,
};
pub use crate::validate::{commanded_error, outliers, pose_errors, tool_axis_angle, ErrorStats, Outlier, PoseErrors};
