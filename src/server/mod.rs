//! The HTTP service: thin handlers over [`crate::scene::input::process`], errors as problem+json,
//! mesh work on a bounded pool, metrics, OpenAPI and Swagger UI.
//!
//! Routes: `POST /v1/tangents`, `POST /v1/analyze`, `POST /v1/uv-layout`, `GET /healthz`,
//! `GET /readyz`, `GET /metrics`, `GET /openapi.json`, `GET /docs`, `GET /problems/{code}`, and
//! the page: `GET /` with its `/page/` files.

pub mod budget;
pub mod encoding;
mod held;
pub mod keys;
pub(crate) mod memory;
pub mod metrics;
mod mixed;
pub mod openapi;
mod page;
pub mod pool;
pub mod problem;
mod routes;
mod shed;
mod stall;

use crate::config::{LogFormat, ServerConfig};
use crate::scene::error::ProblemCode;
use axum::Router;
use axum::extract::{DefaultBodyLimit, MatchedPath, Request, State};
use axum::http::{HeaderName, HeaderValue, Response, header};
use axum::middleware::{self, Next};
use axum::response::IntoResponse;
use metrics::Metrics;
use pool::WorkerPool;
use problem::Problem;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;
use tokio::net::TcpListener;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::request_id::{
    MakeRequestId, PropagateRequestIdLayer, RequestId, SetRequestIdLayer,
};
use tower_http::trace::TraceLayer;
use utoipa::OpenApi;
use utoipa_swagger_ui::SwaggerUi;

/// What every handler shares.
pub struct App {
    pub config: ServerConfig,
    pub pool: WorkerPool,
    pub metrics: Metrics,
    /// Set when shutdown begins: `/readyz` then answers 503.
    pub draining: AtomicBool,
    /// Scene requests in progress, from the body's first byte to the answer's last. A body is
    /// buffered whole before its job is queued, and an answer is held until the client has read
    /// it, so without this bound a burst of clients, or slow readers, could make the server hold
    /// one scene per connection.
    pub in_flight: Arc<tokio::sync::Semaphore>,
    /// The keys the scene routes require, when the service was given a key file.
    pub api_keys: Option<keys::ApiKeys>,
    /// How much of refused uploads is read, so that their clients get a clean 503.
    pub drain_budget: budget::DrainBudget,
    /// The answer refused scene requests get, and their count for the log.
    refusals: shed::Refusals,
}

impl App {
    /// Fails, naming the file, when the API key file cannot be read or holds no key: a
    /// service meant to require keys must not start without them.
    pub fn new(config: ServerConfig) -> std::io::Result<Self> {
        let api_keys = match &config.api_keys_file {
            Some(path) => Some(keys::ApiKeys::read(path).map_err(std::io::Error::other)?),
            None => None,
        };
        // 64 MiB/s of refused bodies is a few percent of a core; a burst of one body limit
        // (at least 64 MiB) answers a burst of refusals cleanly.
        let drain_budget =
            budget::DrainBudget::new(64.0 * MIB, (config.body_limit as f64).max(64.0 * MIB));
        Ok(App {
            drain_budget,
            api_keys,
            pool: WorkerPool::new(config.concurrency, config.queue)?,
            in_flight: Arc::new(tokio::sync::Semaphore::new(config.in_flight.max(1))),
            config,
            metrics: Metrics::default(),
            draining: AtomicBool::new(false),
            refusals: shed::Refusals::default(),
        })
    }
}

impl App {
    /// Whether a request with these headers may use the scene routes: the service has no keys,
    /// or its `Authorization` carries one of them.
    fn admits_key(&self, headers: &axum::http::HeaderMap) -> bool {
        self.api_keys.as_ref().is_none_or(|keys| {
            keys.allows(
                headers
                    .get(header::AUTHORIZATION)
                    .map(HeaderValue::as_bytes),
            )
        })
    }
}

const MIB: f64 = 1024.0 * 1024.0;

const REQUEST_ID: HeaderName = HeaderName::from_static("x-request-id");

/// Request ids: a per-process counter, short and sortable in logs.
#[derive(Clone, Default)]
struct Counter(Arc<AtomicU64>);

impl MakeRequestId for Counter {
    fn make_request_id<B>(&mut self, _: &axum::http::Request<B>) -> Option<RequestId> {
        let n = self.0.fetch_add(1, Ordering::Relaxed) + 1;
        HeaderValue::from_str(&format!("{n:08x}"))
            .ok()
            .map(RequestId::new)
    }
}

/// The scene routes' guard when the service has API keys: a request without `Authorization:
/// Bearer <key>` for one of them is answered 401 before its body is read. The problem says
/// what is needed, never which key was sent.
async fn require_api_key(
    State(app): State<Arc<App>>,
    request: Request,
    next: Next,
) -> axum::response::Response {
    if app.admits_key(request.headers()) {
        return next.run(request).await;
    }
    app.metrics.reject("unauthorized");
    let detail = if request.headers().contains_key(header::AUTHORIZATION) {
        "the Authorization header does not carry a valid API key; send Authorization: Bearer <key>"
    } else {
        "this service requires an API key; send Authorization: Bearer <key>"
    };
    let mut response = Problem::new(ProblemCode::Unauthorized, detail).into_response();
    response.headers_mut().insert(
        header::WWW_AUTHENTICATE,
        HeaderValue::from_static("Bearer realm=\"tspace\""),
    );
    shed::answer_unread(&app, request, response, shed::Drain::WithinBudget).await
}

async fn record_metrics(
    State(app): State<Arc<App>>,
    request: Request,
    next: Next,
) -> axum::response::Response {
    let route = request
        .extensions()
        .get::<MatchedPath>()
        .map_or_else(|| "unmatched".to_owned(), |p| p.as_str().to_owned());
    let started = Instant::now();
    let response = next.run(request).await;
    app.metrics
        .record(&route, response.status().as_u16(), started.elapsed());
    response
}

fn panic_response(payload: Box<dyn std::any::Any + Send + 'static>) -> Response<axum::body::Body> {
    let message = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_default();
    tracing::error!(panic = %message, "handler panicked");
    Problem::new(
        ProblemCode::Internal,
        "tspace failed unexpectedly; the error was logged",
    )
    .into_response()
}

/// The whole router, for a given state.
pub fn router(app: Arc<App>) -> Router {
    let body_limit = app.config.body_limit;
    let outermost = Arc::clone(&app);
    let scenes = Router::new()
        .route("/v1/tangents", axum::routing::post(routes::tangents))
        .route("/v1/analyze", axum::routing::post(routes::analyze))
        .route("/v1/uv-layout", axum::routing::post(routes::uv_layout))
        .route_layer(middleware::from_fn_with_state(
            Arc::clone(&app),
            require_api_key,
        ));
    let api = Router::new()
        .merge(scenes)
        .route("/", axum::routing::get(page::index))
        .route("/page/page.js", axum::routing::get(page::script))
        .route("/page/page.css", axum::routing::get(page::style))
        .route("/page/icon.svg", axum::routing::get(page::icon))
        .route("/page/view.js", axum::routing::get(page::view))
        .route("/page/vendor/three.min.js", axum::routing::get(page::three))
        .route("/healthz", axum::routing::get(routes::healthz))
        .route("/readyz", axum::routing::get(routes::readyz))
        .route("/metrics", axum::routing::get(routes::metrics))
        .route(
            "/problems/{code}",
            axum::routing::get(problem::problem_page),
        )
        .merge(SwaggerUi::new("/docs").url("/openapi.json", openapi::ApiDoc::openapi()))
        .fallback(problem::not_found)
        .method_not_allowed_fallback(problem::method_not_allowed)
        .layer(middleware::from_fn_with_state(
            Arc::clone(&app),
            record_metrics,
        ))
        .with_state(app);
    api.layer(DefaultBodyLimit::max(body_limit))
        .layer(encoding::compression())
        .layer(CatchPanicLayer::custom(panic_response))
        .layer(PropagateRequestIdLayer::new(REQUEST_ID))
        .layer(
            TraceLayer::new_for_http()
                .make_span_with(|request: &axum::http::Request<_>| {
                    let id = request
                        .headers()
                        .get(REQUEST_ID)
                        .and_then(|v| v.to_str().ok())
                        .unwrap_or("-");
                    tracing::info_span!("request", id = %id, method = %request.method(), uri = %request.uri())
                })
                // One line per request at INFO (status and latency); failures at ERROR.
                .on_response(
                    tower_http::trace::DefaultOnResponse::new()
                        .level(tracing::Level::INFO)
                        .latency_unit(tower_http::LatencyUnit::Millis),
                ),
        )
        .layer(SetRequestIdLayer::new(REQUEST_ID, Counter::default()))
        .layer(middleware::from_fn_with_state(
            outermost,
            shed::shed_when_saturated,
        ))
}

/// A server running in the background of the current runtime.
pub struct Running {
    pub addr: SocketAddr,
    pub app: Arc<App>,
    shutdown: Option<oneshot::Sender<()>>,
    handle: JoinHandle<std::io::Result<()>>,
}

impl Running {
    /// Stops accepting, lets in-flight requests finish, and waits for them: at most the request
    /// timeout and a few seconds more, since an idle keep-alive client could otherwise hold the
    /// server open indefinitely.
    pub async fn shutdown(mut self) -> std::io::Result<()> {
        self.app.draining.store(true, Ordering::Release);
        if let Some(sender) = self.shutdown.take() {
            let _ = sender.send(());
        }
        let grace = self.app.config.timeout + std::time::Duration::from_secs(5);
        match tokio::time::timeout(grace, &mut self.handle).await {
            Ok(joined) => joined.map_err(std::io::Error::other)?,
            Err(_) => {
                tracing::warn!("connections still open after the grace period; closing them");
                self.handle.abort();
                Ok(())
            }
        }
    }
}

/// Binds `config.addr` and serves until [`Running::shutdown`].
pub async fn start(config: ServerConfig) -> std::io::Result<Running> {
    let listener = TcpListener::bind(config.addr).await?;
    let addr = listener.local_addr()?;
    let app = Arc::new(App::new(config)?);
    memory::keep_freed_memory_for_reuse();
    let (sender, receiver) = oneshot::channel::<()>();
    let service = router(Arc::clone(&app));
    let listener = stall::GuardedListener {
        inner: listener,
        stall: app.config.read_timeout,
    };
    let handle = tokio::spawn(async move {
        axum::serve(listener, service)
            .with_graceful_shutdown(async {
                let _ = receiver.await;
            })
            .await
    });
    Ok(Running {
        addr,
        app,
        shutdown: Some(sender),
        handle,
    })
}

fn init_logging(format: LogFormat) {
    let filter = tracing_subscriber::EnvFilter::try_from_env("TSPACE_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,tower_http=info"));
    // Colour codes only for a terminal: in files, pipes and container logs they are noise.
    let ansi = std::io::IsTerminal::is_terminal(&std::io::stdout());
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(ansi);
    // A second initialisation (tests) is harmless and ignored.
    let _ = match format {
        LogFormat::Text => builder.try_init(),
        LogFormat::Json => builder.json().try_init(),
    };
}

async fn shutdown_signal() {
    let interrupt = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        let mut terminate =
            match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
                Ok(s) => s,
                Err(_) => {
                    let _ = interrupt.await;
                    return;
                }
            };
        tokio::select! {
            _ = interrupt => {},
            _ = terminate.recv() => {},
        }
    }
    #[cfg(not(unix))]
    {
        let _ = interrupt.await;
    }
}

/// `tspace serve`: runs until SIGINT or SIGTERM, then finishes in-flight requests.
pub fn run(config: ServerConfig) -> std::io::Result<()> {
    init_logging(config.log_format);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    runtime.block_on(async move {
        let running = start(config.clone()).await?;
        tracing::info!(
            addr = %running.addr,
            concurrency = config.concurrency,
            queue = config.queue,
            in_flight = config.in_flight,
            body_limit = config.body_limit,
            "tspace listening"
        );
        shutdown_signal().await;
        tracing::info!("shutting down: finishing in-flight requests");
        running.shutdown().await
    })
}

/// The media type of a response body in a header value.
pub(crate) fn content_type(value: &'static str) -> (header::HeaderName, HeaderValue) {
    (header::CONTENT_TYPE, HeaderValue::from_static(value))
}
