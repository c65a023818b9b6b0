//! The page at `/`: a form for people who do not write curl, built into the binary (HTML, CSS
//! and one ES module from `page/`), so the service needs nothing beside itself to serve it and
//! the page needs no network but the service. It calls the same `/v1` routes a script does,
//! with the API key the person types, so it is open itself (it holds no data).

use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};

const INDEX: &str = include_str!("page/index.html");
const SCRIPT: &str = include_str!("page/page.js");
const STYLE: &str = include_str!("page/page.css");
const ICON: &str = include_str!("page/icon.svg");
const VIEW: &str = include_str!("page/view.js");
/// three.js 0.187.0 with OrbitControls and GLTFLoader, bundled and minified by
/// `scripts/vendor-three` (MIT; its licence is `page/vendor/three-LICENSE`).
const THREE: &str = include_str!("page/vendor/three.min.js");

/// Only the page's own files, and the pictures, downloads and textures it makes as `blob:` URLs
/// (three.js fetches its textures): a file name or mesh name shown on it cannot bring in
/// anything else.
const POLICY: &str = "default-src 'none'; script-src 'self'; style-src 'self'; \
    img-src 'self' blob:; connect-src 'self' blob:; base-uri 'none'; form-action 'none'; \
    frame-ancestors 'none'";

fn asset(body: &'static str, media_type: &'static str) -> Response {
    let mut response = body.into_response();
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(media_type));
    headers.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(POLICY),
    );
    headers.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    // Revalidated every time, so that an upgraded server's page is never mixed with an old
    // script.
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    response
}

pub async fn index() -> Response {
    asset(INDEX, "text/html; charset=utf-8")
}

pub async fn script() -> Response {
    asset(SCRIPT, "text/javascript; charset=utf-8")
}

pub async fn style() -> Response {
    asset(STYLE, "text/css; charset=utf-8")
}

pub async fn icon() -> Response {
    asset(ICON, "image/svg+xml")
}

pub async fn view() -> Response {
    asset(VIEW, "text/javascript; charset=utf-8")
}

pub async fn three() -> Response {
    asset(THREE, "text/javascript; charset=utf-8")
}
