//! Typed errors of the kinecal library.
use thiserror::Error;

/// Errors of kinematic computations (forward / inverse kinematics, Jacobians).
#[derive(Debug, Clone, Error, PartialEq)]
pub enum KinError {
    /// An iterative solve did not converge.
    #[error("{what} did not converge after {iterations} iterations (residual {residual:.3e}); start closer to a valid configuration or check the geometry")]
    NoConvergence {
        /// What was being solved.
        what: String,
        /// Iterations spent.
        iterations: usize,
        /// Final residual norm.
        residual: f64,
    },
    /// The constraint or joint Jacobian is singular at this configuration.
    #[error("singular configuration in {what} (condition number {condition:.3e})")]
    Singular {
        /// Where it happened.
        what: String,
        /// Condition number reached.
        condition: f64,
    },
    /// A target or configuration lies outside the workspace, strokes or joint limits.
    #[error("out of workspace: {0}")]
    OutOfWorkspace(String),
    /// A target cannot be reached by the mechanism.
    #[error("unreachable target: {0}")]
    Unreachable(String),
    /// Wrong number of actuator / joint values.
    #[error("expected {expected} joint values, got {got}")]
    InputLength {
        /// Expected count.
        expected: usize,
        /// Given count.
        got: usize,
    },
    /// A value is NaN or infinite.
    #[error("non-finite value in {0}")]
    NonFinite(String),
}

/// Errors of identification, identifiability and design.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum CalibError {
    /// Kinematics failed at one measurement pose.
    #[error("pose {pose}: {source}")]
    Kinematics {
        /// Index of the pose in the data set.
        pose: usize,
        /// The kinematic error.
        #[source]
        source: KinError,
    },
    /// Not enough measurement rows for the parameters to identify.
    #[error("too few measurements: {rows} residual rows from {poses} poses for {params} identifiable parameters; measure at least {needed} poses")]
    TooFewMeasurements {
        /// Poses given.
        poses: usize,
        /// Residual rows they give.
        rows: usize,
        /// Parameters to identify.
        params: usize,
        /// Poses needed.
        needed: usize,
    },
    /// No parameter is free, or every free parameter is unidentifiable.
    #[error("nothing to identify: {0}")]
    NothingToIdentify(String),
    /// An unknown parameter name.
    #[error("unknown parameter '{0}'")]
    UnknownParam(String),
    /// A numerical failure (NaN in a solve, failed factorisation).
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// Invalid option values.
    #[error("invalid option: {0}")]
    InvalidOption(String),
}
