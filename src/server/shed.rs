//! Refusing scene requests while the service is saturated, at next to no cost.
//!
//! Under a flood most requests are refused, and the server's core pays for each refusal out of
//! its workers' share. Going through the whole stack (a request id, a span and two log lines,
//! the router, the metrics middleware, the problem serialised anew) a refusal cost 185 µs of
//! server CPU on this project's 2-core machine, against 50 µs for a bare accept, canned answer
//! and close; at four times the capacity, 500 refusals a second took a tenth of the core.
//! So the outermost layer looks first: a scene request that arrives while every in-flight slot
//! or every place in the pool is taken is answered here, with a problem document made once,
//! counted in the metrics like any other answer, and summarised in the log at most once a
//! second instead of two lines per refusal. The handler checks again when it takes its slot,
//! since the service may fill between the two, and refuses through [`refuse`] as well.

use super::App;
use super::held::LingeringBody;
use super::problem::Problem;
use axum::body::{Body, Bytes};
use axum::extract::{Request, State};
use axum::http::{HeaderValue, Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::Response;
use std::sync::Arc;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The routes that take a scene, and so take a worker: the only ones refused when saturated.
/// `/healthz`, `/readyz`, `/metrics` and the documents stay answered for probes and scrapers.
pub const SCENE_ROUTES: [&str; 3] = ["/v1/tangents", "/v1/analyze", "/v1/uv-layout"];

/// How long a refused request's connection stays open, unread, after its 503.
pub const LINGER: Duration = Duration::from_secs(1);

/// The refusal's answer, made once, and the log's count of refusals since its last line.
pub struct Refusals {
    problem: Bytes,
    unlogged: Mutex<(u64, Option<Instant>)>,
}

impl Default for Refusals {
    fn default() -> Self {
        let problem = serde_json::to_vec(&Problem::overloaded()).unwrap_or_default();
        Refusals {
            problem: Bytes::from(problem),
            unlogged: Mutex::new((0, None)),
        }
    }
}

impl Refusals {
    /// Counts a refusal in the log: the first after a quiet second is logged at once, the
    /// rest of a flood once a second, with their number. Returns the number logged, if any.
    fn log(&self, now: Instant) -> Option<u64> {
        let mut unlogged = self.unlogged.lock().ok()?;
        let (count, since) = &mut *unlogged;
        *count += 1;
        if since.is_some_and(|t| now.duration_since(t) < Duration::from_secs(1)) {
            return None;
        }
        let seconds = since.map_or(0.0, |t| now.duration_since(t).as_secs_f64());
        tracing::warn!(
            refused = *count,
            seconds = format_args!("{seconds:.1}"),
            "saturated: scene requests refused with 503 since the last such line"
        );
        *since = Some(now);
        Some(std::mem::take(count))
    }

    fn response(&self) -> Response {
        let mut response = Response::new(Body::from(self.problem.clone()));
        *response.status_mut() = StatusCode::SERVICE_UNAVAILABLE;
        let headers = response.headers_mut();
        headers.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/problem+json"),
        );
        headers.insert(header::RETRY_AFTER, HeaderValue::from_static("1"));
        response
    }
}

/// Whether a scene request would be refused now.
fn saturated(app: &App) -> bool {
    app.in_flight.available_permits() == 0 || app.pool.is_full()
}

/// The outermost layer: answers a scene request at once when the service is saturated, and
/// passes everything else on. A request the service would answer 401 (no valid key) is passed
/// on too: whether the service is busy is not for it to learn before it has a key.
pub async fn shed_when_saturated(
    State(app): State<Arc<App>>,
    request: Request,
    next: Next,
) -> Response {
    let path = request.uri().path();
    let Some(route) = SCENE_ROUTES.iter().copied().find(|route| *route == path) else {
        return next.run(request).await;
    };
    if request.method() != Method::POST || !saturated(&app) || !app.admits_key(request.headers()) {
        return next.run(request).await;
    }
    let started = Instant::now();
    let response = refuse(&app, request).await;
    app.metrics
        .record(route, response.status().as_u16(), started.elapsed());
    response
}

/// The 503 for a request refused before its body was read. While the drain budget lasts
/// ([`super::budget`]), the body is read and thrown away (within the read timeout) and the
/// connection stays usable: a burst of refusals gets clean 503s. Beyond it the body is left
/// unread, so that under a flood refusing costs next to nothing (reading every refused upload
/// left a fifth of the capacity for accepted requests at four times the capacity): the answer
/// says `Connection: close`, and the connection lingers for [`LINGER`] after the 503 is sent,
/// unread, so that the client can read its 503 before the close, then closes. A client whose
/// body does not fit in the socket buffers may still see its write fail; it is being refused
/// either way. A client waiting for `100 Continue` (curl, for any body over 1 MiB) has sent no
/// body, and is answered at once: its refusal costs both sides one round trip.
pub async fn refuse(app: &App, request: Request) -> Response {
    app.metrics.reject("overloaded");
    app.refusals.log(Instant::now());
    answer_unread(app, request, app.refusals.response(), Drain::WithinBudget).await
}

/// Whether the body of a request answered unread is drained whenever it fits the body limit,
/// or only while the drain budget lasts.
#[derive(Clone, Copy)]
pub enum Drain {
    /// A request that passed the door (its key, the service's capacity) with options the
    /// route refuses: reading its body costs what reading it for the scene would have.
    Always,
    /// A request refused at the door: under a flood of them, reading every body would cost
    /// the capacity the refusals protect.
    WithinBudget,
}

/// `response` for a request answered before its body was read (a refusal, a missing key, an
/// option the route does not take). Closing a connection that still holds unread bytes resets
/// it, and the reset can overtake the answer: the client sees its upload fail instead of the
/// problem. So the body is drained as `drain` allows, or else the connection lingers
/// after the answer ([`closing_after_linger`]); a client waiting for `100 Continue` has sent no
/// body, and is answered at once.
pub async fn answer_unread(
    app: &App,
    request: Request,
    mut response: Response,
    drain: Drain,
) -> Response {
    use http_body_util::BodyExt;
    let headers = request.headers();
    let waits_for_continue = headers
        .get(header::EXPECT)
        .is_some_and(|v| v.as_bytes().eq_ignore_ascii_case(b"100-continue"));
    let declared_length = super::routes::content_length(headers);
    if waits_for_continue {
        // Its body will not come: the connection ends with this answer (HTTP says to tell the
        // client so; hyper closes it either way, the body being unread).
        response
            .headers_mut()
            .insert(header::CONNECTION, HeaderValue::from_static("close"));
        return response;
    }
    let limit = app.config.body_limit as u64;
    // A chunked body declares no length: one that passed the door is drained up to the limit.
    let affordable = match (declared_length, drain) {
        (Some(n), _) if n > limit => false,
        (Some(n), Drain::WithinBudget) => app.drain_budget.take(n),
        (_, Drain::Always) => true,
        (None, Drain::WithinBudget) => false,
    };
    if affordable {
        let mut body = request.into_body();
        let drain = async {
            let mut read = 0u64;
            while let Some(frame) = body.frame().await {
                let Ok(frame) = frame else { return false };
                read += frame.data_ref().map_or(0, |data| data.len() as u64);
                if read > limit {
                    return false;
                }
            }
            true
        };
        // A body cut off (over the limit, too slow, broken) still has bytes on their way.
        if let Ok(true) = tokio::time::timeout(app.config.read_timeout, drain).await {
            return response;
        }
    }
    closing_after_linger(response)
}

/// `response`, for a request whose body is left partly unread: with `Connection: close`, the
/// connection kept open for [`LINGER`] after the answer so that the client can read it before
/// the close (a close with unread bytes is a reset, which can overtake the answer).
pub fn closing_after_linger(response: Response) -> Response {
    let (parts, body) = response.into_parts();
    let mut response = Response::from_parts(parts, Body::new(LingeringBody::new(body, LINGER)));
    response
        .headers_mut()
        .insert(header::CONNECTION, HeaderValue::from_static("close"));
    response
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flood_of_refusals_is_logged_once_a_second_with_its_count() {
        let refusals = Refusals::default();
        let start = Instant::now();
        assert_eq!(refusals.log(start), Some(1), "the first is logged at once");
        for ms in 1..=500 {
            assert_eq!(refusals.log(start + Duration::from_millis(ms)), None);
        }
        assert_eq!(refusals.log(start + Duration::from_millis(1000)), Some(501));
        assert_eq!(refusals.log(start + Duration::from_millis(1500)), None);
        assert_eq!(refusals.log(start + Duration::from_secs(60)), Some(2));
    }

    #[test]
    fn the_refusal_is_the_overloaded_problem() {
        let response = Refusals::default().response();
        assert_eq!(response.status(), StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(response.headers()[header::RETRY_AFTER], "1");
        let Refusals { problem, .. } = Refusals::default();
        let body: serde_json::Value = serde_json::from_slice(&problem).unwrap_or_default();
        assert_eq!(body["code"], "overloaded", "{body}");
        assert_eq!(body["status"], 503, "{body}");
    }

    /// The layer refuses exactly the routes that take a scene: every POST route the API
    /// describes, and nothing else.
    #[test]
    fn the_scene_routes_are_the_apis_post_routes() {
        use utoipa::OpenApi;
        let api = super::super::openapi::ApiDoc::openapi();
        let mut posts: Vec<&str> = api
            .paths
            .paths
            .iter()
            .filter(|(_, item)| item.post.is_some())
            .map(|(path, _)| path.as_str())
            .collect();
        posts.sort_unstable();
        let mut scene_routes = SCENE_ROUTES.to_vec();
        scene_routes.sort_unstable();
        assert_eq!(posts, scene_routes);
    }
}
