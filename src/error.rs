//! Error types of the crate. Bad input is an [`Error::InvalidScene`] or
//! [`Error::InvalidArgument`] that names the field; numerical failure is an
//! [`Error::NotConverged`] (only raised when the caller asked for it).

use thiserror::Error;

/// Everything that can go wrong in softspine.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Error {
    /// A scene field is missing, unknown, of the wrong shape or out of range.
    #[error("{key}: {reason}")]
    InvalidScene { key: String, reason: String },
    /// An argument of a call (not a scene field) is invalid.
    #[error("{name}: {reason}")]
    InvalidArgument { name: String, reason: String },
    /// A scene file could not be read or parsed.
    #[error("{0}")]
    Parse(String),
    /// The solver stopped without an answer (see the status for how).
    #[error("solve did not converge ({}) after {iterations} iterations (relative residual {residual:.3e}): {reason}", status.name())]
    NotConverged {
        status: crate::status::Status,
        iterations: usize,
        residual: f64,
        reason: String,
    },
    /// The caller's interrupt check asked to stop (Ctrl-C in Python).
    #[error("interrupted")]
    Interrupted,
    /// A buffer of the requested size could not be allocated.
    #[error("{what}: out of memory allocating {bytes} bytes")]
    OutOfMemory { what: String, bytes: usize },
}

impl Error {
    pub(crate) fn scene(key: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::InvalidScene {
            key: key.into(),
            reason: reason.into(),
        }
    }

    pub(crate) fn argument(name: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::InvalidArgument {
            name: name.into(),
            reason: reason.into(),
        }
    }

    /// A refusal of the parameter `name`, said as entry `i` of the caller's
    /// `parameters` (a sensitivity's, a calibration's).
    pub(crate) fn of_parameter(self, i: usize, name: &str) -> Self {
        match self {
            Error::InvalidArgument { reason, .. } | Error::InvalidScene { reason, .. } => {
                Error::argument(format!("parameters[{i}]"), format!("'{name}': {reason}"))
            }
            other => other,
        }
    }
}

/// Result alias of the crate.
pub type Result<T> = std::result::Result<T, Error>;
