//! The library's one error type.
//!
//! Every fallible public function returns [`Error`]. Each variant carries what a user needs to act
//! (the file, the key, the reason) and, where the failure came from the OS or a decoder, that
//! error as its [`source`](std::error::Error::source). The CLI maps variants to exit codes in one
//! place (`src/cli/mod.rs`); the library never prints and never exits.

use crate::image::io::ImageError;
use crate::synth::error::SynthError;
use crate::synth::params::ParamError;
use std::fmt;
use std::path::PathBuf;

#[derive(Debug)]
pub enum Error {
    /// A file or directory could not be read, created or written.
    Io { path: PathBuf, action: &'static str, source: std::io::Error },
    /// A sample or image file could not be decoded or encoded.
    Image { path: PathBuf, source: ImageError },
    /// No job files under the given paths.
    NoJobFiles { inputs: Vec<PathBuf> },
    /// The output directory is held by another run.
    Locked { dir: PathBuf, holder: Option<u32> },
    /// A path that would leave the output directory, or a symlink pointing out of it.
    Containment { path: PathBuf, reason: String },
    /// A manifest (or golden file, or tile-set index) that cannot be used; `reason` says why.
    Manifest { path: PathBuf, reason: String },
    /// Parameters refused by a method's table or checks (same messages as for job files).
    Params { method: String, errors: Vec<ParamError> },
    /// An unknown method name.
    UnknownMethod { name: String, known: Vec<&'static str> },
    /// Metrics that do not exist or cannot be computed with the given parameters.
    Metrics(crate::metrics::MetricError),
    /// A method failed.
    Synthesis { method: String, source: SynthError },
    /// An option or argument that makes no sense.
    Usage(String),
}

impl Error {
    pub fn io(path: impl Into<PathBuf>, action: &'static str, source: std::io::Error) -> Error {
        Error::Io { path: path.into(), action, source }
    }
    pub fn manifest(path: impl Into<PathBuf>, reason: impl Into<String>) -> Error {
        Error::Manifest { path: path.into(), reason: reason.into() }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Io { path, action, source } => write!(f, "cannot {action} {}: {source}", path.display()),
            Error::Image { path, source } => write!(f, "`{}`: {source}", path.display()),
            Error::NoJobFiles { inputs } => write!(
                f,
                "no job files (*.toml) found in {}",
                inputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
            ),
            Error::Locked { dir, holder } => {
                let who = holder.map(|p| format!(" (process {p})")).unwrap_or_default();
                write!(
                    f,
                    "another texsyn run is using the output directory {}{who}; wait for it to finish or choose another --out",
                    dir.display()
                )
            }
            Error::Containment { path, reason } => write!(f, "{}: {reason}", path.display()),
            Error::Manifest { path, reason } => write!(f, "{}: {reason}", path.display()),
            Error::Params { method, errors } => {
                let lines: Vec<String> = errors.iter().map(|e| format!("{method}: `{}`: {}", e.key, e.message)).collect();
                f.write_str(&lines.join("\n"))
            }
            Error::UnknownMethod { name, known } => write!(f, "unknown method `{name}`; known methods: {}", known.join(", ")),
            Error::Metrics(e) => write!(f, "{e}"),
            Error::Synthesis { method, source } => write!(f, "{method} failed: {source}"),
            Error::Usage(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            Error::Image { source, .. } => Some(source),
            Error::Synthesis { source, .. } => Some(source),
            Error::Metrics(e) => Some(e),
            _ => None,
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
