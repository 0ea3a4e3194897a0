//! The library's one error type: what went wrong ([`ErrorKind`]), where when it is
//! known (file, line, key), and the message the command line prints.
//!
//! The modules keep their own precise errors (`ExperimentError`, `LoadError`,
//! `OutputError`, ...); each converts into [`Error`] with `?`, so a program built on the
//! facade handles one type and can still tell a bad key from a missing device.

use std::fmt;
use std::path::Path;

/// What kind of failure an [`Error`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// A file could not be read (missing, not a regular file, too large, not UTF-8).
    Io,
    /// An experiment file that is not TOML.
    Syntax,
    /// A key the format does not have.
    UnknownKey,
    /// A value of the wrong type or outside its range, or a missing key.
    Invalid,
    /// A scene file (.vox, mesh) that cannot be read or used, or a scene that is not
    /// consistent.
    Scene,
    /// No GPU adapter, or the device refused or lost the work.
    Device,
    /// An output that could not be written.
    Output,
    /// A render stopped on request (its [`Watch`](crate::progress::Watch)): no image.
    Interrupted,
    /// Anything else (the message says what).
    Other,
}

/// A voxlab error: its kind, where it is (file, line, key) where known, and the message.
///
/// ```
/// use voxlab::{ErrorKind, Experiment};
///
/// let err = Experiment::from_str("[render]\nwidth = 0\n", "mine.toml").unwrap_err();
/// let err = voxlab::Error::from(err);
/// assert_eq!(err.kind(), ErrorKind::Invalid);
/// assert_eq!(err.file(), Some("mine.toml"));
/// assert_eq!(err.line(), Some(2));
/// assert_eq!(err.key(), Some("render.width"));
/// assert!(err.to_string().contains("must be an integer in 1..=16384"));
/// ```
#[derive(Debug)]
pub struct Error {
    kind: ErrorKind,
    file: Option<String>,
    line: Option<usize>,
    key: Option<String>,
    message: String,
}

/// `Result` with voxlab's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An error of `kind` with the whole message (as printed).
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Self {
            kind,
            file: None,
            line: None,
            key: None,
            message: message.into(),
        }
    }

    fn in_file(mut self, file: &Path) -> Self {
        self.file = Some(file.display().to_string());
        self
    }

    /// The error located in `file` (as its message names it), at `key` where known: for
    /// the layers above this one, whose errors this module does not know.
    pub(crate) fn located(mut self, file: String, key: Option<String>) -> Self {
        self.file = Some(file);
        self.key = key;
        self
    }

    pub fn kind(&self) -> ErrorKind {
        self.kind
    }

    /// The file the error is in, as its message names it.
    pub fn file(&self) -> Option<&str> {
        self.file.as_deref()
    }

    /// The line (1-based) the error points at.
    pub fn line(&self) -> Option<usize> {
        self.line
    }

    /// The dotted key (`render.width`, `lights[1].intensity`).
    pub fn key(&self) -> Option<&str> {
        self.key.as_deref()
    }

    /// The message, as `Display` prints it.
    pub fn message(&self) -> &str {
        &self.message
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Error {}

impl From<crate::experiment::ExperimentError> for Error {
    fn from(e: crate::experiment::ExperimentError) -> Self {
        use crate::experiment::ExperimentError as E;
        let message = e.to_string();
        let (kind, file, key) = match &e {
            E::Io { path, .. } => (ErrorKind::Io, path.display().to_string(), None),
            E::Syntax { file, .. } => (ErrorKind::Syntax, file.clone(), None),
            E::UnknownKey { file, key, .. } => (ErrorKind::UnknownKey, file.clone(), Some(key)),
            E::Invalid { file, key, .. } => (ErrorKind::Invalid, file.clone(), Some(key)),
        };
        Self {
            kind,
            file: Some(file),
            line: e.line(),
            key: key.cloned(),
            message,
        }
    }
}

impl From<crate::scene::LoadError> for Error {
    fn from(e: crate::scene::LoadError) -> Self {
        let kind = match &e.kind {
            crate::scene::LoadErrorKind::Read(_) | crate::scene::LoadErrorKind::Input(_) => {
                ErrorKind::Io
            }
            crate::scene::LoadErrorKind::Write(_) => ErrorKind::Output,
            _ => ErrorKind::Scene,
        };
        Self::new(kind, e.to_string()).in_file(&e.path)
    }
}

impl From<crate::scene::SceneError> for Error {
    fn from(e: crate::scene::SceneError) -> Self {
        Self::new(ErrorKind::Scene, e.0)
    }
}

impl From<crate::output::OutputError> for Error {
    fn from(e: crate::output::OutputError) -> Self {
        Self::new(ErrorKind::Output, e.to_string())
    }
}

impl From<crate::experiment::WriteError> for Error {
    fn from(e: crate::experiment::WriteError) -> Self {
        Self::new(ErrorKind::Output, e.to_string())
    }
}

/// The modules' plain-text refusals (an override that is not `KEY=VALUE`, a plan's
/// check).
impl From<String> for Error {
    fn from(message: String) -> Self {
        Self::new(ErrorKind::Other, message)
    }
}

impl From<std::io::Error> for Error {
    fn from(e: std::io::Error) -> Self {
        Self::new(ErrorKind::Io, e.to_string())
    }
}

/// The modules that report with `anyhow` (the GPU tracer, ablate): the chain of causes
/// in one message. A voxlab error inside keeps its kind and place.
impl From<anyhow::Error> for Error {
    fn from(e: anyhow::Error) -> Self {
        match e.downcast::<Error>() {
            Ok(inner) => inner,
            Err(e) => match e.downcast::<crate::experiment::ExperimentError>() {
                Ok(inner) => inner.into(),
                Err(e) => Self::new(ErrorKind::Other, format!("{e:#}")),
            },
        }
    }
}
