//! One error type for the library. The adapters (REST, gRPC, the CLI's exit codes) map its
//! variants exhaustively, so a new variant forces every mapping to be decided; ARCHITECTURE.md
//! has the table.

use std::fmt;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The caller gave a bad value; `field` names it (e.g. "q[3]", "training.lr").
    #[error("{field}: {message}")]
    Invalid { field: String, message: String },
    /// Well-formed but semantically unacceptable (a job spec that cannot train, an
    /// idempotency key reused with another body); `field` names the part at fault.
    #[error("{field}: {message}")]
    Unprocessable { field: String, message: String },
    /// Something named does not exist.
    #[error("{0} not found")]
    NotFound(String),
    /// The request conflicts with the current state (deleting a dataset a job uses,
    /// cancelling a finished job).
    #[error("{0}")]
    Conflict(String),
    /// The target exists but is not ready for this (a job that has not produced a model).
    #[error("{0}")]
    FailedPrecondition(String),
    /// A request over a configured limit (rollout length, batch size).
    #[error("{0}")]
    ResourceExhausted(String),
    /// The database failed; callers may retry.
    #[error("storage error: {0}")]
    Storage(String),
    /// The service is at a bound its requests share (memory for data being read, calls
    /// waiting to compute): the same request may well succeed in a moment.
    #[error("{0}")]
    Busy(String),
    /// Training diverged or produced non-finite values.
    #[error("training failed: {0}")]
    Training(String),
    /// Training was cancelled through its cancel flag.
    #[error("cancelled")]
    Cancelled,
    #[error("i/o error: {0}")]
    Io(#[from] std::io::Error),
    /// The caller's deadline passed before the work finished.
    #[error("{0}")]
    DeadlineExceeded(String),
    /// A fault inside graybox itself (a task that died, a server that could not start).
    #[error("internal error: {0}")]
    Internal(String),
    /// A stored artifact (model file, checkpoint) could not be read.
    #[error("corrupt {what}: {message}")]
    Corrupt { what: String, message: String },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// What a client is told: the error's text, except for a storage fault, where it learns
    /// which shared service failed, never that service's address or its own error text (the
    /// log has both).
    pub fn public_message(&self) -> String {
        match self {
            Error::Storage(detail) if detail.starts_with("object store") => {
                "the object store is unavailable; try again later".into()
            }
            Error::Storage(_) => "the database is unavailable; try again later".into(),
            e => e.to_string(),
        }
    }

    /// The gRPC status a caller hears this error as (its code and name): one mapping for the
    /// service's status and the Python module's exception.
    pub fn code(&self) -> (i32, &'static str) {
        match self {
            Error::Invalid { .. } | Error::Unprocessable { .. } => (3, "INVALID_ARGUMENT"),
            Error::NotFound(_) => (5, "NOT_FOUND"),
            Error::FailedPrecondition(_) | Error::Conflict(_) => (9, "FAILED_PRECONDITION"),
            Error::ResourceExhausted(_) => (8, "RESOURCE_EXHAUSTED"),
            Error::Cancelled => (1, "CANCELLED"),
            Error::Storage(_) | Error::Busy(_) => (14, "UNAVAILABLE"),
            Error::DeadlineExceeded(_) => (4, "DEADLINE_EXCEEDED"),
            Error::Internal(_) | Error::Training(_) | Error::Io(_) | Error::Corrupt { .. } => {
                (13, "INTERNAL")
            }
        }
    }

    /// The input a caller's error names, if it names one.
    pub fn field(&self) -> Option<&str> {
        match self {
            Error::Invalid { field, .. } | Error::Unprocessable { field, .. } => Some(field),
            _ => None,
        }
    }

    pub fn invalid(field: impl Into<String>, message: impl fmt::Display) -> Self {
        Error::Invalid {
            field: field.into(),
            message: message.to_string(),
        }
    }

    /// The same error, reported as unprocessable (422) rather than malformed (400).
    pub fn unprocessable(self) -> Self {
        match self {
            Error::Invalid { field, message } => Error::Unprocessable { field, message },
            other => other,
        }
    }

    pub fn corrupt(what: impl Into<String>, message: impl fmt::Display) -> Self {
        Error::Corrupt {
            what: what.into(),
            message: message.to_string(),
        }
    }
}

// The database's errors are the cluster's (ARCHITECTURE.md's table: Storage). These live here,
// beside the type, because Rust lets a foreign error convert into this one only in its crate;
// the C library builds without the feature and links no database.
#[cfg(feature = "sqlx")]
impl From<sqlx::Error> for Error {
    fn from(e: sqlx::Error) -> Self {
        Error::Storage(e.to_string())
    }
}

#[cfg(feature = "sqlx")]
impl From<sqlx::migrate::MigrateError> for Error {
    fn from(e: sqlx::migrate::MigrateError) -> Self {
        Error::Storage(format!("migration failed: {e}"))
    }
}
