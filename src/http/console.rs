//! The web console (docs/console.md): static pages at `/` that read and
//! submit through the API itself. The assets are compiled into the binary
//! (no build step, no CDN, nothing fetched from outside the service), and
//! are open without the token even under `--token-reads`: they hold no
//! data; the pages send the token the user enters with each API call.

use axum::Router;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;

const INDEX_HTML: &str = include_str!("console/index.html");
const APP_JS: &str = include_str!("console/app.js");
const APP_CSS: &str = include_str!("console/app.css");
const ICON_SVG: &str = include_str!("console/icon.svg");

/// The submit page's templates: the specs of `api/examples`.
const EXAMPLES: [(&str, &str); 4] = [
    (
        "TiO2 over black",
        include_str!("../../api/examples/tio2_black.json"),
    ),
    (
        "two layers over Lambertian",
        include_str!("../../api/examples/two_layers_lambertian.json"),
    ),
    (
        "Rayleigh, scalar",
        include_str!("../../api/examples/rayleigh_scalar.json"),
    ),
    (
        "rust on silver",
        include_str!("../../api/examples/rust_on_silver.json"),
    ),
];

/// Paths the console answers without a token.
pub fn is_console_path(path: &str) -> bool {
    path == "/" || path.starts_with("/console/")
}

fn asset(body: &'static str, media_type: &'static str) -> Response {
    let mut res = ([(header::CONTENT_TYPE, media_type)], body).into_response();
    // Assets change with the binary: revalidate rather than cache long.
    res.headers_mut()
        .insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    res
}

/// `[{"name", "spec"}]` of [`EXAMPLES`].
pub fn examples_json() -> String {
    let list: Vec<serde_json::Value> = EXAMPLES
        .iter()
        .map(|(name, text)| {
            let spec: serde_json::Value =
                serde_json::from_str(text).expect("api/examples are valid JSON");
            serde_json::json!({ "name": name, "spec": spec })
        })
        .collect();
    serde_json::Value::Array(list).to_string()
}

/// The console's routes.
pub fn router<S: Clone + Send + Sync + 'static>() -> Router<S> {
    Router::new()
        .route(
            "/",
            get(|| async { asset(INDEX_HTML, "text/html; charset=utf-8") }),
        )
        .route(
            "/console/app.js",
            get(|| async { asset(APP_JS, "text/javascript; charset=utf-8") }),
        )
        .route(
            "/console/app.css",
            get(|| async { asset(APP_CSS, "text/css; charset=utf-8") }),
        )
        .route(
            "/console/icon.svg",
            get(|| async { asset(ICON_SVG, "image/svg+xml") }),
        )
        .route(
            "/console/examples.json",
            get(|| async {
                let mut res = (
                    [(header::CONTENT_TYPE, "application/json")],
                    examples_json(),
                )
                    .into_response();
                res.headers_mut()
                    .insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
                res
            }),
        )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_template_is_a_valid_spec() {
        let list: Vec<serde_json::Value> = serde_json::from_str(&examples_json()).unwrap();
        assert_eq!(list.len(), EXAMPLES.len());
        for e in list {
            let text = e["spec"].to_string();
            crate::material::parse(&text).unwrap_or_else(|err| panic!("{}: {err:?}", e["name"]));
        }
    }

    #[test]
    fn the_page_loads_only_its_own_assets() {
        for line in INDEX_HTML.lines().chain(APP_CSS.lines()) {
            assert!(
                !line.contains("http://") && !line.contains("https://"),
                "{line}"
            );
        }
        assert!(INDEX_HTML.contains("/console/app.js") && INDEX_HTML.contains("/console/app.css"));
    }
}
