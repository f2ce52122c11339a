//! The HTTP front door (`polbrdf serve`, docs/service.md).
//!
//! * [`routes`] is the one function that lists every route; the axum
//!   [`router`] and the OpenAPI document ([`openapi`], committed at
//!   `api/openapi.json` and snapshot-tested) are both built from it.
//! * Handlers share [`AppState`]`(Arc<`[`App`]`>)`: the configuration, the
//!   job queue and the metrics.
//! * Every error is an [`error::ApiError`], mapped in one place to a status
//!   and an RFC 9457 problem+json body ([`problem::Problem`]); so is the
//!   stored failure of a job.
//! * The routes that read results ([`brdfs`], [`eval`]) share [`results`]:
//!   the row of an id (its version and status checked), its verified bytes
//!   and its parsed table.
//! * [`scenes`]: `POST /v1/scenes`, a render scene's materials submitted
//!   through the path of `POST /v1/brdfs` as their reduced requests.
//! * [`serve`] opens the storage, starts the workers, binds, and shuts down
//!   gracefully when its `shutdown` future resolves.

pub mod brdfs;
pub mod config;
pub mod console;
pub mod error;
pub mod eval;
pub mod events;
pub mod listing;
pub mod needs_doc;
pub mod ops;
pub mod optics;
pub mod previews;
pub mod problem;
pub mod results;
pub mod scenes;
pub mod summary;

pub use config::{Config, Limits, LogFormat};
pub use error::ApiError;

use crate::jobs::{Jobs, JobsConfig, Metrics};
use crate::storage::{BlobStore, Index, StorageError};
use axum::Router;
use axum::extract::{DefaultBodyLimit, MatchedPath, Request, State};
use axum::http::{Method, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Instant;
use utoipa::OpenApi;
use utoipa::openapi::security::{Http, HttpAuthScheme, SecurityScheme};
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes as api;

/// Everything the handlers share.
#[derive(Debug)]
pub struct App {
    /// The configuration.
    pub config: Config,
    /// The job queue (with the index, the blobs and the metrics).
    pub jobs: Arc<Jobs>,
    /// Parsed tables of recent evaluations.
    pub tables: results::TableCache,
    /// Recent derived exports (`GET …/table?format=…`).
    pub exports: brdfs::ExportCache,
    /// Recent lobe plots (`GET …/plot`).
    pub plots: previews::PlotCache,
}

/// Handler state: a cheap clone of the shared [`App`].
#[derive(Clone, Debug)]
pub struct AppState(pub Arc<App>);

#[derive(OpenApi)]
#[openapi(
    info(
        title = "polbrdf",
        description = "Polarized (4x4 Mueller) BRDFs of paint layers from first principles, \
                       computed once per canonical spec and served as immutable, content-addressed \
                       results (docs/service.md).",
        license(name = "MIT OR Apache-2.0")
    ),
    modifiers(&BearerAuth),
    components(schemas(
        problem::Problem,
        brdfs::TableFormat,
        brdfs::DenseType,
        brdfs::TableBytes,
        needs_doc::NeedsDocument
    )),
    tags(
        (name = "brdfs", description = "Submit specs, follow jobs, fetch results"),
        (name = "scenes", description = "Submit the materials of a render scene, reduced to what it needs"),
        (name = "operations", description = "Health, readiness, metrics")
    )
)]
struct ApiDoc;

struct BearerAuth;

impl utoipa::Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(Http::new(HttpAuthScheme::Bearer)),
        );
    }
}

/// Every route of the service, with its OpenAPI description.
pub fn routes() -> OpenApiRouter<AppState> {
    OpenApiRouter::with_openapi(ApiDoc::openapi())
        .routes(api!(brdfs::create_brdf, listing::list_brdfs))
        .routes(api!(brdfs::get_brdf, brdfs::delete_brdf))
        .routes(api!(brdfs::get_table))
        .routes(api!(previews::get_thumbnail))
        .routes(api!(previews::get_plot))
        .routes(api!(previews::get_metadata))
        .routes(api!(events::events))
        .routes(api!(scenes::create_scene))
        .routes(api!(optics::post_optics))
        .routes(api!(eval::get_eval, eval::post_eval))
        .routes(api!(ops::healthz))
        .routes(api!(ops::readyz))
        .routes(api!(ops::metrics))
}

/// The OpenAPI document (the content of `api/openapi.json`).
pub fn openapi() -> utoipa::openapi::OpenApi {
    let (_, mut doc) = routes().split_for_parts();
    doc.info.version = "v1".into();
    doc
}

/// The axum router with its middleware: request spans, bearer-token
/// checks, request metrics, the body cap, problem+json for unknown routes.
pub fn router(state: AppState) -> Router {
    let (router, _) = routes().split_for_parts();
    router
        .merge(console::router())
        .route_layer(middleware::from_fn_with_state(state.clone(), authorize))
        .route_layer(middleware::from_fn_with_state(state.clone(), track))
        .fallback(no_route)
        .layer(middleware::from_fn_with_state(
            Arc::new(allowed_methods()),
            method_not_allowed,
        ))
        .layer(DefaultBodyLimit::max(state.0.config.max_body_bytes))
        .layer(
            tower_http::trace::TraceLayer::new_for_http().make_span_with(|req: &Request| {
                tracing::info_span!("request", method = %req.method(), path = %req.uri().path())
            }),
        )
        .with_state(state)
}

async fn no_route(req: Request) -> ApiError {
    ApiError::NoRoute(format!("{} {}", req.method(), req.uri().path()))
}

/// Every route template (split into segments) with the methods it answers,
/// from the same [`routes`] as the router (`GET` implies `HEAD`).
type AllowTable = Vec<(Vec<String>, String)>;

fn allowed_methods() -> AllowTable {
    openapi()
        .paths
        .paths
        .iter()
        .map(|(path, item)| {
            let mut methods = Vec::new();
            for (m, op) in [
                ("GET", &item.get),
                ("HEAD", &item.head),
                ("POST", &item.post),
                ("PUT", &item.put),
                ("PATCH", &item.patch),
                ("DELETE", &item.delete),
                ("OPTIONS", &item.options),
            ] {
                if op.is_some() {
                    methods.push(m);
                }
            }
            if item.get.is_some() && item.head.is_none() {
                methods.insert(1, "HEAD");
            }
            let segments = path.split('/').map(str::to_string).collect();
            (segments, methods.join(","))
        })
        .collect()
}

/// The methods of the route template matching `path` (`{x}` matches one
/// segment).
fn allow_of(table: &AllowTable, path: &str) -> Option<String> {
    let segments: Vec<&str> = path.split('/').collect();
    table.iter().find_map(|(template, allow)| {
        let matches = template.len() == segments.len()
            && template
                .iter()
                .zip(&segments)
                .all(|(t, s)| t == s || (t.starts_with('{') && t.ends_with('}') && !s.is_empty()));
        matches.then(|| allow.clone())
    })
}

/// A known route asked with another method: axum answers 405 with an empty
/// body; make it the problem+json of every other error, with `Allow`.
async fn method_not_allowed(
    State(table): State<Arc<AllowTable>>,
    req: Request,
    next: Next,
) -> Response {
    let (method, path) = (req.method().to_string(), req.uri().path().to_string());
    let res = next.run(req).await;
    if res.status() != axum::http::StatusCode::METHOD_NOT_ALLOWED
        || res.headers().contains_key(header::CONTENT_TYPE)
    {
        return res;
    }
    let allow = allow_of(&table, &path).unwrap_or_default();
    ApiError::MethodNotAllowed {
        method,
        path,
        allow,
    }
    .into_response()
}

/// Count the request and its latency under its route template.
async fn track(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map_or_else(|| "unmatched".to_string(), |p| p.as_str().to_string());
    let method = req.method().clone();
    let t0 = Instant::now();
    let res = next.run(req).await;
    state.0.jobs.metrics().observe_request(
        method.as_str(),
        &route,
        res.status().as_u16(),
        t0.elapsed().as_secs_f64(),
    );
    res
}

/// Bearer-token check: submissions need `--token` when it is set; reads
/// (results, metrics) need it too with `--token-reads`; `/healthz` and
/// `/readyz` and the console's assets (`/`, `/console/…`) are always open.
async fn authorize(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let config = &state.0.config;
    let Some(token) = config.token.as_deref() else {
        return next.run(req).await;
    };
    let path = req.uri().path();
    let open = path == "/healthz" || path == "/readyz" || console::is_console_path(path);
    let write = !matches!(*req.method(), Method::GET | Method::HEAD);
    if open || !(write || config.token_reads) {
        return next.run(req).await;
    }
    let given = req
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "))
        .map(str::trim);
    match given {
        Some(g) if constant_time_eq(g.as_bytes(), token.as_bytes()) => next.run(req).await,
        _ => ApiError::Unauthorized.into_response(),
    }
}

fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// Start-up and serving errors.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The data directory or the index could not be opened.
    #[error("{0}")]
    Storage(#[from] StorageError),
    /// The listen address could not be bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// The OS error.
        source: std::io::Error,
    },
    /// The server failed.
    #[error("server: {0}")]
    Io(#[from] std::io::Error),
}

/// Open the storage, start the workers (re-queuing unfinished jobs), bind
/// `config.listen` and serve until `shutdown` resolves; then stop accepting,
/// let running jobs finish within `config.shutdown_grace` (re-queuing the
/// rest) and close the index. `on_bound` receives the bound address.
pub async fn serve(
    config: Config,
    on_bound: impl FnOnce(SocketAddr),
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), ServeError> {
    std::fs::create_dir_all(&config.data_dir)?;
    let index = Index::open(&config.database_url).await?;
    let metrics = Arc::new(Metrics::default());
    let blobs = {
        let (location, options) = (config.blob_store.clone(), config.s3_options.0.clone());
        // Blocking: an S3 store is checked to be reachable.
        let store = tokio::task::spawn_blocking(move || BlobStore::at(&location, &options))
            .await
            .map_err(std::io::Error::other)??;
        let m = metrics.clone();
        Arc::new(store.with_observer(Arc::new(move |op, d| m.observe_blob(op, d.as_secs_f64()))))
    };
    tracing::info!(blob_store = %blobs.url(), "blob store open");
    let jobs = Jobs::start(
        index.clone(),
        blobs,
        metrics,
        JobsConfig {
            workers: config.workers,
            max_queue: config.max_queue,
            max_attempts: config.max_attempts,
            max_streams: config.limits.max_streams,
            instance_id: config.instance_id.clone(),
            lease: config.lease,
            max_cache_bytes: config.max_cache_bytes,
            eviction_grace: config.eviction_grace,
        },
    )
    .await?;
    let listener = tokio::net::TcpListener::bind(config.listen)
        .await
        .map_err(|source| ServeError::Bind {
            addr: config.listen,
            source,
        })?;
    let addr = listener.local_addr()?;
    let grace = config.shutdown_grace;
    tracing::info!(%addr, data_dir = %config.data_dir.display(), workers = config.workers,
        instance = %config.instance_id, "serving");
    on_bound(addr);
    let state = AppState(Arc::new(App {
        config,
        jobs: jobs.clone(),
        tables: results::TableCache::default(),
        exports: brdfs::ExportCache::default(),
        plots: previews::PlotCache::default(),
    }));
    let stopping = jobs.clone();
    axum::serve(listener, router(state))
        .with_graceful_shutdown(async move {
            shutdown.await;
            tracing::info!("shutting down: no new connections");
            // Readiness turns 503 and submissions are refused from here.
            stopping.stop_accepting();
        })
        .await?;
    jobs.shutdown(grace).await;
    index.close().await;
    tracing::info!("stopped");
    Ok(())
}
