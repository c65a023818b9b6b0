//! Why a scene could not be processed: one error type for every input format, with a stable
//! machine-readable code and a class that tells a transport how to answer (the HTTP server maps
//! classes to status codes, the CLI to exit codes).

use std::fmt;

/// What kind of failure, from the caller's point of view.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorClass {
    /// The bytes are not a well-formed file of the kind they claim to be (HTTP 400).
    Malformed,
    /// Well-formed, but tspace cannot do what was asked with it: a required extension it does
    /// not decode, a buffer that was not supplied, no triangles at all (HTTP 422).
    Unprocessable,
    /// Over a configured limit (HTTP 413).
    TooLarge,
}

/// A scene-level error: a class, a stable code (`missing-resource`, `draco-required`…) that
/// clients can match on, and a message for people that names what is wrong and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneError {
    pub class: ErrorClass,
    pub code: &'static str,
    pub message: String,
}

impl SceneError {
    pub fn new(class: ErrorClass, code: &'static str, message: impl Into<String>) -> Self {
        SceneError {
            class,
            code,
            message: message.into(),
        }
    }

    pub fn malformed(code: &'static str, message: impl Into<String>) -> Self {
        Self::new(ErrorClass::Malformed, code, message)
    }

    pub fn unprocessable(code: &'static str, message: impl Into<String>) -> Self {
        Self::new(ErrorClass::Unprocessable, code, message)
    }

    pub fn too_large(code: &'static str, message: impl Into<String>) -> Self {
        Self::new(ErrorClass::TooLarge, code, message)
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for SceneError {}
