//! The dashboard: one static page over the JSON API (`/`), its script and styles, and the
//! vendored uPlot, all embedded in the binary. The page needs no token to load; what it reads
//! and writes goes through the REST API with the token the person gives it.

use axum::Router;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;

/// What a browser may do with any response of the REST port. The page loads its script,
/// styles and uPlot from `/ui/` and reads the API on its own origin, so 'self' is all it
/// needs: no inline script or `style=` (uPlot styles elements through the CSSOM, which a
/// policy does not restrict), no images but the favicon (no `data:`), downloads through
/// `blob:` links (a navigation, not a fetch the policy governs). Nothing may frame it.
pub const CONTENT_SECURITY_POLICY: &str = "default-src 'self'; object-src 'none'; \
     base-uri 'none'; form-action 'self'; frame-ancestors 'none'";

/// The policy, no MIME sniffing (a JSON answer quoting caller text is never taken for HTML
/// or a script) and no framing for browsers older than `frame-ancestors`; a layer over every
/// REST response, errors included.
pub async fn security_headers(mut resp: Response) -> Response {
    let headers = resp.headers_mut();
    headers.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(CONTENT_SECURITY_POLICY),
    );
    headers.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    headers.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    resp
}

/// Files served without a token: the page needs them before it can ask for one.
pub fn is_open(path: &str) -> bool {
    path == "/" || path == "/favicon.ico" || path.starts_with("/ui/")
}

const FILES: [(&str, &str, &str); 6] = [
    (
        "/",
        "text/html; charset=utf-8",
        include_str!("static/index.html"),
    ),
    (
        "/ui/app.js",
        "text/javascript; charset=utf-8",
        include_str!("static/app.js"),
    ),
    (
        "/ui/style.css",
        "text/css; charset=utf-8",
        include_str!("static/style.css"),
    ),
    (
        "/ui/uPlot.iife.min.js",
        "text/javascript; charset=utf-8",
        include_str!("static/vendor/uPlot.iife.min.js"),
    ),
    (
        "/ui/uPlot.min.css",
        "text/css; charset=utf-8",
        include_str!("static/vendor/uPlot.min.css"),
    ),
    (
        "/favicon.ico",
        "image/svg+xml",
        include_str!("static/favicon.svg"),
    ),
];

pub fn routes<S: Clone + Send + Sync + 'static>() -> Router<S> {
    FILES
        .iter()
        .fold(Router::new(), |r, &(path, content_type, body)| {
            r.route(
                path,
                get(move || async move {
                    (
                        [
                            (header::CONTENT_TYPE, content_type),
                            (header::CACHE_CONTROL, "no-cache"),
                        ],
                        body,
                    )
                        .into_response()
                }),
            )
        })
}
