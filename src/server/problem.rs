//! Errors as `application/problem+json` (RFC 9457), with a stable `type` per cause.
//!
//! `type` is `/problems/<code>`, relative to the server; `GET /problems/<code>` explains it. The
//! `code` member repeats the last segment for clients that only want the word.

use crate::scene::error::{ErrorClass, SceneError};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;

#[derive(Clone, Debug, Serialize)]
pub struct Problem {
    #[serde(rename = "type")]
    pub type_uri: String,
    pub title: &'static str,
    pub status: u16,
    pub detail: String,
    pub code: &'static str,
    #[serde(skip)]
    pub retry_after: Option<u64>,
}

/// Every problem code the server can answer with, its status and title.
pub const CODES: &[(&str, u16, &str)] = &[
    ("malformed-glb", 400, "The GLB container is malformed"),
    ("malformed-json", 400, "The glTF JSON is malformed"),
    ("malformed-gltf", 400, "The glTF document is malformed"),
    ("malformed-uri", 400, "A URI in the file is malformed"),
    ("malformed-obj", 400, "The OBJ file is malformed"),
    ("malformed-mtl", 400, "The MTL file is malformed"),
    (
        "malformed-meshopt",
        400,
        "Meshopt-compressed data is malformed",
    ),
    (
        "malformed-multipart",
        400,
        "The multipart body is malformed",
    ),
    ("invalid-accessor", 400, "An accessor is invalid"),
    ("invalid-primitive", 400, "A primitive is invalid"),
    ("invalid-buffer-view", 400, "A buffer view is invalid"),
    (
        "buffer-too-short",
        400,
        "A buffer is shorter than it declares",
    ),
    ("invalid-option", 400, "A query option is invalid"),
    ("missing-file", 400, "The request carries no scene"),
    (
        "unsupported-media-type",
        415,
        "The body's media type is not a scene tspace reads",
    ),
    (
        "missing-resource",
        422,
        "A file the scene refers to was not supplied",
    ),
    ("refused-uri", 422, "A URI in the scene is refused"),
    (
        "unsupported-version",
        422,
        "The glTF version is not supported",
    ),
    (
        "draco-required",
        422,
        "The scene requires Draco compression, which tspace does not decode",
    ),
    ("obj-without-uvs", 422, "The OBJ has no texture coordinates"),
    (
        "obj-not-convertible",
        422,
        "The OBJ cannot be converted to glTF",
    ),
    ("internal-edit", 500, "tspace could not edit the document"),
    ("body-too-large", 413, "The request body is over the limit"),
    ("buffer-too-large", 413, "A buffer is over the limit"),
    (
        "too-many-vertices",
        413,
        "An accessor has more elements than allowed",
    ),
    (
        "too-many-triangles",
        413,
        "The scene has more triangles than allowed",
    ),
    ("too-large", 413, "The scene is over a limit"),
    (
        "request-timeout",
        408,
        "The request body arrived too slowly",
    ),
    ("overloaded", 503, "The server is busy; retry shortly"),
    (
        "timeout",
        504,
        "The request took longer than the server allows",
    ),
    ("internal", 500, "An internal error occurred"),
];

fn title_of(code: &str) -> &'static str {
    CODES
        .iter()
        .find(|(c, _, _)| *c == code)
        .map_or("Error", |(_, _, t)| t)
}

impl Problem {
    pub fn new(status: StatusCode, code: &'static str, detail: impl Into<String>) -> Self {
        Problem {
            type_uri: format!("/problems/{code}"),
            title: title_of(code),
            status: status.as_u16(),
            detail: detail.into(),
            code,
            retry_after: None,
        }
    }

    pub fn overloaded() -> Self {
        Problem {
            retry_after: Some(1),
            ..Problem::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "overloaded",
                "every worker is busy and the queue is full; retry in a moment",
            )
        }
    }

    pub fn status(&self) -> StatusCode {
        StatusCode::from_u16(self.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR)
    }
}

impl From<SceneError> for Problem {
    fn from(error: SceneError) -> Self {
        let status = match error.class {
            ErrorClass::Malformed => StatusCode::BAD_REQUEST,
            ErrorClass::Unprocessable if error.code == "internal-edit" => {
                StatusCode::INTERNAL_SERVER_ERROR
            }
            ErrorClass::Unprocessable => StatusCode::UNPROCESSABLE_ENTITY,
            ErrorClass::TooLarge => StatusCode::PAYLOAD_TOO_LARGE,
        };
        Problem::new(status, error.code, error.message)
    }
}

impl IntoResponse for Problem {
    fn into_response(self) -> Response {
        let status = self.status();
        let body = serde_json::to_vec(&self).unwrap_or_default();
        let mut response = (status, body).into_response();
        let headers = response.headers_mut();
        headers.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/problem+json"),
        );
        if let Some(seconds) = self.retry_after {
            headers.insert(header::RETRY_AFTER, HeaderValue::from(seconds));
        }
        response
    }
}
