//! Why a scene could not be processed: one error type for every input format, with a code from
//! one closed set, [`ProblemCode`], that both transports answer with (the HTTP server as a
//! problem+json `code` and a `/problems/<code>` page, the CLI as `(code)` and in `--report`).
//!
//! The set also holds the service's own codes (`not-found`, `overloaded`…): they share the slug
//! namespace, the `/problems/` pages and the documentation table, and one table here keeps a code
//! from existing without its status and title. Nothing here depends on HTTP; the status numbers
//! are data that the server reads.

use serde::{Serialize, Serializer};
use std::fmt;

/// What kind of failure, from the caller's point of view, whatever the transport.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorClass {
    /// The bytes are not a well-formed file or request of the kind they claim to be.
    Malformed,
    /// Well-formed, but of a kind tspace does not read (a body that is not a scene).
    Unsupported,
    /// Well-formed, but tspace cannot do what was asked with it: a required extension it does
    /// not decode, a buffer that was not supplied, an OBJ that cannot be converted.
    Unprocessable,
    /// Over a configured limit, or over a format's own.
    TooLarge,
    /// The request named a route or method that does not exist.
    NoSuchRoute,
    /// The service requires an API key, and the request did not carry a valid one.
    Unauthorized,
    /// The request, or the work it asked for, took longer than allowed.
    OutOfTime,
    /// Every worker is busy; the same request may succeed later.
    Busy,
    /// A bug in tspace.
    Internal,
}

/// Defines [`ProblemCode`] from one table, so that the enum, [`ProblemCode::ALL`] and each
/// code's slug, class, status and title cannot drift apart: a variant without a row does not
/// compile, and `ALL` is generated from the same rows.
macro_rules! problem_codes {
    ($($variant:ident => $slug:literal, $class:ident, $status:literal, $title:literal;)*) => {
        /// Every error code tspace answers with, on the command line and over HTTP.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum ProblemCode {
            $(#[doc = $title] $variant,)*
        }

        impl ProblemCode {
            /// Every code, in the order of the documentation's table (by status).
            pub const ALL: &'static [ProblemCode] = &[$(ProblemCode::$variant,)*];

            const fn row(self) -> (&'static str, ErrorClass, u16, &'static str) {
                match self {
                    $(ProblemCode::$variant => ($slug, ErrorClass::$class, $status, $title),)*
                }
            }
        }
    };
}

problem_codes! {
    MalformedGlb => "malformed-glb", Malformed, 400, "The GLB container is malformed";
    MalformedJson => "malformed-json", Malformed, 400, "The glTF JSON is malformed";
    MalformedGltf => "malformed-gltf", Malformed, 400, "The glTF document is malformed";
    MalformedUri => "malformed-uri", Malformed, 400, "A URI in the file is malformed";
    MalformedObj => "malformed-obj", Malformed, 400, "The OBJ file is malformed";
    MalformedMtl => "malformed-mtl", Malformed, 400, "The MTL file is malformed";
    MalformedMeshopt => "malformed-meshopt", Malformed, 400, "Meshopt-compressed data is malformed";
    MalformedDraco => "malformed-draco", Malformed, 400, "A Draco-compressed stream is malformed";
    InvalidDracoExtension => "invalid-draco-extension", Malformed, 400, "A primitive's KHR_draco_mesh_compression extension is invalid";
    DracoAttributeMissing => "draco-attribute-missing", Malformed, 400, "A Draco stream lacks an attribute its extension names";
    DracoCountMismatch => "draco-count-mismatch", Malformed, 400, "A Draco stream's counts disagree with its accessors";
    DracoTypeMismatch => "draco-type-mismatch", Malformed, 400, "A Draco stream's values do not fit their accessor's type";
    MalformedMultipart => "malformed-multipart", Malformed, 400, "The multipart body is malformed";
    MalformedEncoding => "malformed-encoding", Malformed, 400, "The body's gzip or zstd stream does not decode";
    InvalidAccessor => "invalid-accessor", Malformed, 400, "An accessor is invalid";
    InvalidPrimitive => "invalid-primitive", Malformed, 400, "A primitive is invalid";
    InvalidBufferView => "invalid-buffer-view", Malformed, 400, "A buffer view is invalid";
    BufferTooShort => "buffer-too-short", Malformed, 400, "A buffer is shorter than it declares";
    InvalidOption => "invalid-option", Malformed, 400, "A query option is invalid";
    MissingFile => "missing-file", Malformed, 400, "The request carries no scene";
    // RFC 9457 asks an `about:blank` problem for its status's own phrase as the title.
    Unauthorized => "unauthorized", Unauthorized, 401, "The request needs a valid API key";
    NotFound => "not-found", NoSuchRoute, 404, "Not Found";
    MethodNotAllowed => "method-not-allowed", NoSuchRoute, 405, "Method Not Allowed";
    RequestTimeout => "request-timeout", OutOfTime, 408, "The request body arrived too slowly";
    BodyTooLarge => "body-too-large", TooLarge, 413, "The request body is over the limit";
    BufferTooLarge => "buffer-too-large", TooLarge, 413, "A buffer is over the limit";
    TooManyVertices => "too-many-vertices", TooLarge, 413, "An accessor has more elements than allowed";
    TooManyTriangles => "too-many-triangles", TooLarge, 413, "The scene has more triangles than allowed";
    DracoTooLarge => "draco-too-large", TooLarge, 413, "A Draco stream decodes to more than allowed";
    TooLarge => "too-large", TooLarge, 413, "The scene is over a limit";
    OutputTooLarge => "output-too-large", TooLarge, 413, "The output would be over the format's size limit";
    UnsupportedMediaType => "unsupported-media-type", Unsupported, 415, "The body's media type is not a scene tspace reads";
    UnsupportedEncoding => "unsupported-encoding", Unsupported, 415, "The body's content encoding is not one tspace decodes";
    MissingResource => "missing-resource", Unprocessable, 422, "A file the scene refers to was not supplied";
    RefusedUri => "refused-uri", Unprocessable, 422, "A URI in the scene is refused";
    UnsupportedVersion => "unsupported-version", Unprocessable, 422, "The glTF version is not supported";
    ObjNotConvertible => "obj-not-convertible", Unprocessable, 422, "The OBJ cannot be converted to glTF";
    NothingToDraw => "nothing-to-draw", Unprocessable, 422, "The scene has no geometry to draw as asked";
    InternalEdit => "internal-edit", Internal, 500, "tspace could not edit the document";
    Internal => "internal", Internal, 500, "An internal error occurred";
    Overloaded => "overloaded", Busy, 503, "The server is busy; retry shortly";
    Timeout => "timeout", OutOfTime, 504, "The request took longer than the server allows";
}

impl ProblemCode {
    /// The stable, machine-readable word clients match on (`missing-resource`).
    pub const fn code(self) -> &'static str {
        self.row().0
    }

    pub const fn class(self) -> ErrorClass {
        self.row().1
    }

    /// The HTTP status the service answers this code with.
    pub const fn status(self) -> u16 {
        self.row().2
    }

    /// One fixed line for people, the same for every occurrence of the code.
    pub const fn title(self) -> &'static str {
        self.row().3
    }

    /// The code whose slug is `slug`, if there is one.
    pub fn from_slug(slug: &str) -> Option<ProblemCode> {
        Self::ALL.iter().copied().find(|c| c.code() == slug)
    }
}

impl fmt::Display for ProblemCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.code())
    }
}

/// As the slug: what problem+json and the `--report` document carry.
impl Serialize for ProblemCode {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.code())
    }
}

/// Lets callers and tests compare with the slug they document (`error.code == "missing-resource"`).
impl PartialEq<&str> for ProblemCode {
    fn eq(&self, other: &&str) -> bool {
        self.code() == *other
    }
}

/// A scene-level error: a code clients can match on (its class and status come with it), and a
/// message for people that names what is wrong and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneError {
    pub code: ProblemCode,
    pub message: String,
}

impl SceneError {
    pub fn new(code: ProblemCode, message: impl Into<String>) -> Self {
        SceneError {
            code,
            message: message.into(),
        }
    }

    pub fn class(&self) -> ErrorClass {
        self.code.class()
    }

    /// The work stopped because [`crate::scene::SceneOptions::cancel`] was set: whoever waited
    /// for it has stopped waiting, so this error is for the log, never for a client.
    pub fn cancelled() -> Self {
        SceneError::new(
            ProblemCode::Timeout,
            "the work was cancelled: its request timed out or its client went away",
        )
    }

    /// `Err(cancelled)` once `cancel` is set: called between the steps of the work.
    pub fn check(cancel: &tspace_tangent::Cancel) -> Result<(), SceneError> {
        if cancel.is_cancelled() {
            Err(SceneError::cancelled())
        } else {
            Ok(())
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for SceneError {}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    #[test]
    fn every_code_has_a_distinct_slug_a_title_and_an_error_status() {
        let mut slugs = HashSet::new();
        for &code in ProblemCode::ALL {
            assert!(slugs.insert(code.code()), "{code} appears twice");
            assert!(!code.title().is_empty(), "{code} has no title");
            assert!((400..600).contains(&code.status()), "{code}");
            assert_eq!(ProblemCode::from_slug(code.code()), Some(code));
            // Slugs go into URL paths and `(code)` messages as they are.
            assert!(
                code.code()
                    .bytes()
                    .all(|b| b.is_ascii_lowercase() || b == b'-'),
                "{code}"
            );
        }
        assert_eq!(ProblemCode::from_slug("no-such-code"), None);
    }

    #[test]
    fn the_classes_agree_with_the_statuses() {
        for &code in ProblemCode::ALL {
            let expected: &[u16] = match code.class() {
                ErrorClass::Malformed => &[400],
                ErrorClass::Unsupported => &[415],
                ErrorClass::Unprocessable => &[422],
                ErrorClass::TooLarge => &[413],
                ErrorClass::NoSuchRoute => &[404, 405],
                ErrorClass::Unauthorized => &[401],
                ErrorClass::OutOfTime => &[408, 504],
                ErrorClass::Busy => &[503],
                ErrorClass::Internal => &[500],
            };
            assert!(expected.contains(&code.status()), "{code}");
        }
    }

    #[test]
    fn a_code_serializes_as_its_slug() {
        let json = serde_json::to_string(&ProblemCode::OutputTooLarge).unwrap();
        assert_eq!(json, "\"output-too-large\"");
    }
}
