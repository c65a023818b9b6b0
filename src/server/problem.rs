//! Errors as `application/problem+json` (RFC 9457), with a stable `type` per cause.
//!
//! `type` is `/problems/<code>`, relative to the server; `GET /problems/<code>` explains it. The
//! `code` member repeats the last segment for clients that only want the word. Codes, statuses
//! and titles all come from [`ProblemCode`].

use crate::scene::error::{ErrorClass, ProblemCode, SceneError};
use axum::extract::Path;
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use std::borrow::Cow;
use utoipa::openapi::schema::{ObjectBuilder, Type};
use utoipa::openapi::{ContentBuilder, Header, Ref, RefOr, ResponseBuilder, Schema};
use utoipa::{PartialSchema, ToSchema};

/// An error, as `application/problem+json` (RFC 9457).
#[derive(Clone, Debug, Serialize, ToSchema)]
#[schema(example = json!({
    "type": "/problems/missing-resource",
    "title": "A file the scene refers to was not supplied",
    "status": 422,
    "detail": "buffer 0 refers to Avocado.bin, which the request does not carry; send it as a multipart part named Avocado.bin",
    "code": "missing-resource"
}))]
pub struct Problem {
    /// `/problems/<code>`, relative to the server (`GET` it for a line about the code);
    /// `about:blank` for `not-found` and `method-not-allowed`.
    #[serde(rename = "type")]
    pub type_uri: String,
    /// Fixed per code.
    pub title: &'static str,
    /// The HTTP status of the answer.
    #[schema(minimum = 400, maximum = 599)]
    pub status: u16,
    /// What happened in this request, and where.
    pub detail: String,
    pub code: ProblemCode,
    /// Sent as the `Retry-After` header, not in the body.
    #[serde(skip)]
    pub retry_after: Option<u64>,
}

/// The codes as a string enum, in the order of [`ProblemCode::ALL`], each with its status and
/// title.
impl PartialSchema for ProblemCode {
    fn schema() -> RefOr<Schema> {
        let explained: Vec<String> = ProblemCode::ALL
            .iter()
            .map(|c| format!("`{c}` ({}): {}", c.status(), c.title()))
            .collect();
        ObjectBuilder::new()
            .schema_type(Type::String)
            .description(Some(format!(
                "The problem's code, the last segment of its `type`: {}.",
                explained.join("; ")
            )))
            .enum_values(Some(ProblemCode::ALL.iter().map(|c| c.code())))
            .into()
    }
}

impl ToSchema for ProblemCode {
    fn name() -> Cow<'static, str> {
        "ProblemCode".into()
    }
}

impl Problem {
    /// The problem for `code`: its status and title come from the code, `detail` from this
    /// request.
    pub fn new(code: ProblemCode, detail: impl Into<String>) -> Self {
        Problem {
            type_uri: type_uri(code),
            title: code.title(),
            status: code.status(),
            detail: detail.into(),
            code,
            retry_after: seconds_to_retry(code),
        }
    }

    pub fn overloaded() -> Self {
        Problem::new(
            ProblemCode::Overloaded,
            "every worker is busy and the queue is full; retry in a moment",
        )
    }

    pub fn status(&self) -> StatusCode {
        StatusCode::from_u16(self.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR)
    }
}

/// The `Retry-After` of a code whose request may succeed as it is a moment later.
fn seconds_to_retry(code: ProblemCode) -> Option<u64> {
    match code.class() {
        ErrorClass::Busy => Some(1),
        _ => None,
    }
}

/// `/problems/<code>`, except for a route or method that does not exist: those mean no more
/// than their HTTP status, which RFC 9457 spells `about:blank`.
fn type_uri(code: ProblemCode) -> String {
    match code.class() {
        ErrorClass::NoSuchRoute => "about:blank".to_owned(),
        _ => format!("/problems/{code}"),
    }
}

impl From<SceneError> for Problem {
    fn from(error: SceneError) -> Self {
        Problem::new(error.code, error.message)
    }
}

impl IntoResponse for Problem {
    fn into_response(self) -> Response {
        let status = self.status();
        // Inside the request's span, so the line carries its id; the response line that follows
        // gives only the status, and several codes share one.
        tracing::info!(code = %self.code, status = self.status, "problem");
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
        // RFC 9110 (15.5.16): a 415 for a content coding names the codings that would do.
        if self.code == ProblemCode::UnsupportedEncoding {
            headers.insert(
                header::ACCEPT_ENCODING,
                HeaderValue::from_static(crate::server::encoding::ACCEPTED),
            );
        }
        response
    }
}

/// `GET /problems/{code}`: one line saying what a problem `type` means.
#[utoipa::path(
    get,
    path = "/problems/{code}",
    tag = "service",
    params(("code" = ProblemCode, Path, description = "A problem's code")),
    responses(
        (status = 200, description = "`<code> (HTTP <status>): <title>.`", body = String, content_type = "text/plain"),
        (status = 404, description = "`not-found`: no such code", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn problem_page(Path(slug): Path<String>) -> Response {
    match ProblemCode::from_slug(&slug) {
        Some(code) => (
            StatusCode::OK,
            format!("{code} (HTTP {}): {}.\n", code.status(), code.title()),
        )
            .into_response(),
        None => not_found().await.into_response(),
    }
}

pub async fn method_not_allowed() -> Problem {
    Problem::new(
        ProblemCode::MethodNotAllowed,
        "this route does not take that method; see /docs",
    )
}

pub async fn not_found() -> Problem {
    Problem::new(ProblemCode::NotFound, "no such route; see /docs")
}

/// Adds to every `POST` operation one response per error status, listing its codes, each
/// `application/problem+json` with the [`Problem`] schema, so that the OpenAPI document cannot
/// disagree with what the service answers. The 503 says when to retry.
pub struct ProblemCodes;

impl utoipa::Modify for ProblemCodes {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        for (path, item) in openapi.paths.paths.iter_mut() {
            // Only a route that writes a scene can find its output too large.
            let writes = path != "/v1/analyze";
            if let Some(operation) = item.post.as_mut() {
                for (status, response) in error_responses(writes) {
                    operation
                        .responses
                        .responses
                        .insert(status, response.into());
                }
            }
        }
    }
}

/// The codes a scene route can answer with: all but a route or method that does not exist,
/// and, for a route that writes nothing, an output over the limit.
fn scene_route_codes(writes: bool) -> impl Iterator<Item = ProblemCode> {
    ProblemCode::ALL
        .iter()
        .copied()
        .filter(|c| c.class() != ErrorClass::NoSuchRoute)
        .filter(move |c| writes || *c != ProblemCode::OutputTooLarge)
}

fn error_responses(writes: bool) -> Vec<(String, utoipa::openapi::Response)> {
    let mut statuses: Vec<u16> = scene_route_codes(writes).map(ProblemCode::status).collect();
    statuses.sort_unstable();
    statuses.dedup();
    statuses
        .into_iter()
        .map(|status| {
            let codes: Vec<ProblemCode> = scene_route_codes(writes)
                .filter(|c| c.status() == status)
                .collect();
            let listed: Vec<String> = codes
                .iter()
                .map(|c| format!("`{c}`: {}", c.title()))
                .collect();
            let content = ContentBuilder::new()
                .schema(Some(Ref::from_schema_name(Problem::name())))
                .build();
            let mut response = ResponseBuilder::new()
                .description(listed.join("; "))
                .content("application/problem+json", content);
            if codes.iter().any(|&c| seconds_to_retry(c).is_some()) {
                response = response.header("Retry-After", retry_after_header());
            }
            (status.to_string(), response.build())
        })
        .collect()
}

/// What a problem with [`seconds_to_retry`] sends besides the body.
fn retry_after_header() -> Header {
    Header::builder()
        .schema(
            ObjectBuilder::new()
                .schema_type(Type::Integer)
                .minimum(Some(0)),
        )
        .description(Some("Seconds to wait before sending the request again"))
        .build()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rows of the error table in docs/http-api.md: `(code, status, title)`.
    fn documented_codes() -> Vec<(String, u16, String)> {
        let page = include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/http-api.md"));
        let mut lines = page
            .lines()
            .skip_while(|l| *l != "| code | status | title |");
        assert!(lines.next().is_some(), "the error table's header");
        lines
            .skip(1)
            .take_while(|l| l.starts_with('|'))
            .map(|row| {
                let cells: Vec<&str> = row.trim_matches('|').split(" | ").map(str::trim).collect();
                let [code, status, title] = cells[..] else {
                    panic!("not three cells: {row}");
                };
                let status = status.parse().unwrap_or_else(|_| panic!("{row}"));
                (code.trim_matches('`').to_owned(), status, title.to_owned())
            })
            .collect()
    }

    #[test]
    fn the_documented_error_table_is_the_set_of_codes() {
        let documented = documented_codes();
        let expected: Vec<(String, u16, String)> = ProblemCode::ALL
            .iter()
            .map(|c| (c.code().to_owned(), c.status(), c.title().to_owned()))
            .collect();
        for row in &documented {
            assert!(expected.contains(row), "documented but not so: {row:?}");
        }
        for row in &expected {
            assert!(documented.contains(row), "not documented: {row:?}");
        }
        assert_eq!(documented.len(), expected.len(), "a code documented twice");
    }

    #[test]
    fn a_problem_serializes_as_before() {
        let problem = Problem::new(ProblemCode::MissingFile, "nothing");
        assert_eq!(
            serde_json::to_string(&problem).unwrap(),
            r#"{"type":"/problems/missing-file","title":"The request carries no scene","status":400,"detail":"nothing","code":"missing-file"}"#
        );
        let problem = Problem::from(SceneError::new(ProblemCode::InternalEdit, "x"));
        assert_eq!(
            (problem.status, problem.code.code()),
            (500, "internal-edit")
        );
    }

    #[tokio::test]
    async fn route_problems_keep_about_blank() {
        let problem = not_found().await;
        assert_eq!(
            serde_json::to_string(&problem).unwrap(),
            r#"{"type":"about:blank","title":"Not Found","status":404,"detail":"no such route; see /docs","code":"not-found"}"#
        );
        let problem = method_not_allowed().await;
        assert_eq!(
            (problem.type_uri.as_str(), problem.title),
            ("about:blank", "Method Not Allowed")
        );
    }

    #[test]
    fn the_openapi_document_lists_every_code() {
        use utoipa::OpenApi;
        let api = serde_json::to_value(crate::server::openapi::ApiDoc::openapi()).unwrap();
        let schemas = &api["components"]["schemas"];
        let slugs: Vec<&str> = ProblemCode::ALL.iter().map(|c| c.code()).collect();
        assert_eq!(schemas["ProblemCode"]["enum"], serde_json::json!(slugs));
        assert_eq!(
            schemas["Problem"]["properties"]["code"]["$ref"],
            "#/components/schemas/ProblemCode"
        );
        let mut required: Vec<&str> = schemas["Problem"]["required"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|v| v.as_str())
            .collect();
        required.sort_unstable();
        assert_eq!(required, ["code", "detail", "status", "title", "type"]);
        let responses = &api["paths"]["/v1/tangents"]["post"]["responses"];
        let described = responses["422"]["description"].as_str().unwrap_or_default();
        assert!(described.contains("`missing-resource`"), "{responses}");
        assert!(
            responses["404"].is_null(),
            "not-found is no answer of a scene route"
        );
        for (status, response) in responses.as_object().unwrap() {
            if status.starts_with(['4', '5']) {
                let schema = &response["content"]["application/problem+json"]["schema"];
                assert_eq!(schema["$ref"], "#/components/schemas/Problem", "{status}");
            }
        }
    }

    #[test]
    fn only_a_busy_server_says_when_to_retry() {
        for &code in ProblemCode::ALL {
            let retry = Problem::new(code, "").retry_after;
            assert_eq!(retry.is_some(), code == ProblemCode::Overloaded, "{code}");
        }
        let response = Problem::overloaded().into_response();
        assert_eq!(response.headers()[header::RETRY_AFTER], "1");
    }
}
