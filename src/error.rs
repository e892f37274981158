//! One error type for the library. Adapters (CLI now; REST and gRPC later) map its variants
//! exhaustively, so a new variant forces every mapping to be decided.

use std::fmt;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The caller gave a bad value; `field` names it (e.g. "q[3]", "training.lr").
    #[error("{field}: {message}")]
    Invalid { field: String, message: String },
    /// Something named does not exist.
    #[error("{0} not found")]
    NotFound(String),
    /// Training diverged or produced non-finite values.
    #[error("training failed: {0}")]
    Training(String),
    /// Training was cancelled through its cancel flag.
    #[error("cancelled")]
    Cancelled,
    #[error("i/o error: {0}")]
    Io(#[from] std::io::Error),
    /// A stored artifact (model file, checkpoint) could not be read.
    #[error("corrupt {what}: {message}")]
    Corrupt { what: String, message: String },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn invalid(field: impl Into<String>, message: impl fmt::Display) -> Self {
        Error::Invalid {
            field: field.into(),
            message: message.to_string(),
        }
    }

    pub fn corrupt(what: impl Into<String>, message: impl fmt::Display) -> Self {
        Error::Corrupt {
            what: what.into(),
            message: message.to_string(),
        }
    }
}
