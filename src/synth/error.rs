//! Why a synthesis could not be made.

use std::fmt;

/// A method's failure. Messages name what the user can change (a parameter, the sample).
#[derive(Clone, Debug, PartialEq)]
pub enum SynthError {
    /// A parameter (by its job-file name) is unusable; `message` says why and what would do.
    Param { key: String, message: String },
    /// The sample cannot give what was asked (too small for the blocks, no lattice, …).
    Sample(String),
    /// The method could not finish for another stated reason.
    Failed(String),
}

impl SynthError {
    pub fn param(key: &str, message: impl Into<String>) -> SynthError {
        SynthError::Param { key: key.to_string(), message: message.into() }
    }
    pub fn sample(message: impl Into<String>) -> SynthError {
        SynthError::Sample(message.into())
    }
}

impl fmt::Display for SynthError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SynthError::Param { key, message } => write!(f, "`{key}`: {message}"),
            SynthError::Sample(m) | SynthError::Failed(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for SynthError {}
