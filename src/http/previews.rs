//! Pictures of a done result for the console (docs/service.md,
//! "Previews"):
//!
//! * `GET /v1/brdfs/{id}/thumbnail?kind=intensity|dop`: a sphere rendered
//!   with the result ([`crate::render::thumbnail`]), PNG. Both kinds come
//!   from one render and are stored as blobs of their own, recorded in the
//!   index under the result's digest ([`crate::storage::Index::preview`]):
//!   rendered once per result for every instance of a farm.
//! * `GET /v1/brdfs/{id}/plot?theta_i_deg=…[&wavelength_nm=…]`: the BRDF
//!   (f11) and DOP lobes in the plane of incidence
//!   ([`crate::plot::figures::lobe`]), SVG; kept in memory.
//! * `GET /v1/brdfs/{id}/metadata`: the table's metadata (per-wavelength
//!   streams, times and error estimates), JSON.

use super::AppState;
use super::brdfs::{etag_of, none_match};
use super::error::ApiError;
use super::problem::Problem;
use super::results::{require_done, row_of, table_of};
use crate::brdf::PolarGrid;
use crate::plot::figures::{self, LobeInput, LobeOptions, SolveOptions, Source};
use crate::render::thumbnail::{THUMBNAIL_PX, THUMBNAIL_VERSION, thumbnails};
use crate::storage::now_ms;
use axum::Json;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use utoipa::IntoParams;

/// Query of `GET …/thumbnail`.
#[derive(Clone, Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct ThumbnailQuery {
    /// `intensity` (default) or `dop`.
    pub kind: Option<String>,
}

/// The two thumbnails of one render.
const KINDS: [&str; 2] = ["intensity", "dop"];

/// The index key of a thumbnail kind (names the renderer version).
fn preview_key(kind: &str) -> String {
    format!("thumbnail-{kind}-{THUMBNAIL_VERSION}")
}

fn invalid(path: &str, message: String) -> ApiError {
    ApiError::InvalidQuery {
        path: path.into(),
        message,
    }
}

fn blocking_err(e: impl std::fmt::Display) -> ApiError {
    ApiError::Internal(e.to_string())
}

/// An image answer with its ETag (its SHA-256) and a day of caching: the
/// bytes of a result's picture change only with the renderer's version.
fn image(bytes: Vec<u8>, media_type: &'static str, digest: &str, headers: &HeaderMap) -> Response {
    let mut res = if none_match(headers, digest) {
        StatusCode::NOT_MODIFIED.into_response()
    } else {
        ([(header::CONTENT_TYPE, media_type)], bytes).into_response()
    };
    let h = res.headers_mut();
    h.insert(header::ETAG, etag_of(digest));
    h.insert(
        header::CACHE_CONTROL,
        HeaderValue::from_static("public, max-age=86400"),
    );
    res
}

/// A sphere rendered with the result: intensity or degree of polarization.
///
/// A PNG of 96 × 96 pixels: one sphere, a directional light from the upper
/// left, a dim uniform sky, direct light only (`render::thumbnail`). The
/// first request renders both kinds and stores them; later ones (on any
/// instance sharing the index and blobs) read them.
#[utoipa::path(
    get,
    path = "/v1/brdfs/{id}/thumbnail",
    tag = "brdfs",
    params(("id" = String, Path, description = "Spec id (64 lowercase hex digits)"), ThumbnailQuery),
    responses(
        (status = 200, description = "The thumbnail", content_type = "image/png", body = Vec<u8>),
        (status = 304, description = "Not modified (`If-None-Match`)"),
        (status = 401, description = "Token required for reads (--token-reads)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown id", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not done yet", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Unknown `kind`, or a result the sphere cannot be rendered from (`path` names `kind`)", body = Problem, content_type = "application/problem+json"),
    ),
    security((), ("bearer" = []))
)]
pub async fn get_thumbnail(
    State(state): State<AppState>,
    Path(id): Path<String>,
    query: Result<Query<ThumbnailQuery>, QueryRejection>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let Query(q) =
        query.map_err(|e| invalid("query", format!("{}; allowed: kind", e.body_text())))?;
    let kind = q.kind.as_deref().unwrap_or("intensity");
    let k = KINDS.iter().position(|k| *k == kind).ok_or_else(|| {
        invalid(
            "kind",
            format!("'{kind}' is not a thumbnail: use intensity or dop"),
        )
    })?;
    let row = row_of(&state, &id).await?;
    require_done(&row, &id)?;
    let result_digest = row.digest.clone().unwrap_or_default();
    let index = state.0.jobs.index();
    let blobs = state.0.jobs.blobs().clone();
    if let Some((digest, _)) = index.preview(&result_digest, &preview_key(kind)).await? {
        let (b, d) = (blobs.clone(), digest.clone());
        let stored = tokio::task::spawn_blocking(move || b.get(&d))
            .await
            .map_err(blocking_err)?
            .map_err(blocking_err)?;
        if let Some(bytes) = stored {
            return Ok(image(bytes, "image/png", &digest, &headers));
        }
        // The blob went missing: render again below (the record stays;
        // the same bytes get the same digest).
    }
    let (_, table) = table_of(&state, &id).await?;
    let t0 = std::time::Instant::now();
    let pictures = tokio::task::spawn_blocking(move || -> Result<_, String> {
        let (intensity, dop) = thumbnails(table, THUMBNAIL_PX)?;
        let stored = [intensity, dop]
            .into_iter()
            .map(|png| {
                let digest = blobs.put(&png).map_err(|e| format!("blob store: {e}"))?;
                Ok((png, digest))
            })
            .collect::<Result<Vec<_>, String>>()?;
        Ok(stored)
    })
    .await
    .map_err(blocking_err)?
    .map_err(|e| {
        if e.starts_with("blob store") {
            ApiError::Internal(e)
        } else {
            invalid(
                "kind",
                format!("the sphere cannot be rendered from this result: {e}"),
            )
        }
    })?;
    tracing::info!(%id, ms = t0.elapsed().as_millis() as u64, "thumbnails rendered");
    let now = now_ms();
    for (kind, (png, digest)) in KINDS.iter().zip(&pictures) {
        let record = (digest.clone(), png.len() as i64);
        index
            .put_preview(&result_digest, &preview_key(kind), &record, now)
            .await?;
    }
    let (png, digest) = pictures.into_iter().nth(k).expect("two kinds");
    Ok(image(png, "image/png", &digest, &headers))
}

/// Query of `GET …/plot`.
#[derive(Clone, Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct PlotQuery {
    /// Incident polar angle (degrees) in `[0, 90)`; default 45.
    #[param(value_type = Option<f64>)]
    pub theta_i_deg: Option<String>,
    /// The wavelength to plot (nm; default the result's first).
    #[param(value_type = Option<f64>)]
    pub wavelength_nm: Option<String>,
}

/// A drawn plot: its SVG text and the text's SHA-256 (the ETag).
type Plot = Arc<(String, String)>;

/// Plots kept in memory, by result digest and query.
#[derive(Debug, Default)]
pub struct PlotCache {
    entries: Mutex<VecDeque<(String, Plot)>>,
}

/// SVG plots kept by [`PlotCache`].
const PLOT_CACHE_ENTRIES: usize = 256;

impl PlotCache {
    fn get(&self, key: &str) -> Option<Plot> {
        let e = self.entries.lock().unwrap_or_else(|p| p.into_inner());
        e.iter().find(|(k, _)| k == key).map(|(_, v)| v.clone())
    }

    fn put(&self, key: String, v: Plot) {
        let mut e = self.entries.lock().unwrap_or_else(|p| p.into_inner());
        e.retain(|(k, _)| *k != key);
        e.push_back((key, v));
        while e.len() > PLOT_CACHE_ENTRIES {
            e.pop_front();
        }
    }
}

fn number(name: &str, v: Option<&str>) -> Result<Option<f64>, ApiError> {
    v.map(|s| {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| invalid(name, format!("'{s}' is not a number")))
    })
    .transpose()
}

/// The BRDF (f11) and the DOP of the reflected light for unpolarized
/// incident light, in the plane of incidence at one incident angle.
///
/// SVG, two lobe panels (as `polbrdf plot lobe --table`), drawn by the
/// service's plot code; a 1° step in the outgoing angle.
#[utoipa::path(
    get,
    path = "/v1/brdfs/{id}/plot",
    tag = "brdfs",
    params(("id" = String, Path, description = "Spec id (64 lowercase hex digits)"), PlotQuery),
    responses(
        (status = 200, description = "The lobes", content_type = "image/svg+xml", body = String),
        (status = 304, description = "Not modified (`If-None-Match`)"),
        (status = 401, description = "Token required for reads (--token-reads)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown id", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not done yet", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "`theta_i_deg` outside [0, 90), a wavelength the result lacks, or no font for the labels; `path` names the parameter", body = Problem, content_type = "application/problem+json"),
    ),
    security((), ("bearer" = []))
)]
pub async fn get_plot(
    State(state): State<AppState>,
    Path(id): Path<String>,
    query: Result<Query<PlotQuery>, QueryRejection>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let Query(q) = query.map_err(|e| {
        invalid(
            "query",
            format!("{}; allowed: theta_i_deg, wavelength_nm", e.body_text()),
        )
    })?;
    let theta_i_deg = number("theta_i_deg", q.theta_i_deg.as_deref())?.unwrap_or(45.0);
    if !(0.0..90.0).contains(&theta_i_deg) {
        return Err(invalid(
            "theta_i_deg",
            format!("{theta_i_deg} is outside [0, 90) degrees"),
        ));
    }
    let wavelength_nm = number("wavelength_nm", q.wavelength_nm.as_deref())?;
    let (row, table) = table_of(&state, &id).await?;
    let key = format!(
        "{}|{theta_i_deg}|{wavelength_nm:?}",
        row.digest.as_deref().unwrap_or_default()
    );
    if let Some(hit) = state.0.plots.get(&key) {
        return Ok(image(
            hit.0.clone().into_bytes(),
            "image/svg+xml",
            &hit.1,
            &headers,
        ));
    }
    let label = id[..12].to_string();
    let svg = tokio::task::spawn_blocking(move || -> Result<String, (String, String)> {
        crate::plot::draw::register_font(None).map_err(|e| ("font".to_string(), e))?;
        let o = LobeOptions {
            theta_i_deg,
            step_deg: 1.0,
            map_cells: (1, 1),
            grid: PolarGrid::graded(64).map_err(|e| ("grid".to_string(), e.to_string()))?,
            solve: SolveOptions {
                wavelength_nm,
                streams: None,
            },
            size: Some((720, 640)),
        };
        let input = LobeInput {
            source: Source::Table {
                path: &label,
                table: &table,
            },
            label: Some(&label),
        };
        let plot =
            figures::lobe(&[input], &o).map_err(|e| ("wavelength_nm".into(), e.to_string()))?;
        crate::plot::draw::svg_string(&plot.figure).map_err(|e| ("plot".into(), e))
    })
    .await
    .map_err(blocking_err)?
    .map_err(|(path, message)| invalid(&path, message))?;
    let digest = crate::digest::sha256_hex(svg.as_bytes());
    let entry = Arc::new((svg, digest));
    state.0.plots.put(key, entry.clone());
    Ok(image(
        entry.0.clone().into_bytes(),
        "image/svg+xml",
        &entry.1,
        &headers,
    ))
}

/// The table's metadata: spec, solver settings, per-wavelength streams,
/// Fourier orders, wall time and error estimate (docs/table-format.md).
#[utoipa::path(
    get,
    path = "/v1/brdfs/{id}/metadata",
    tag = "brdfs",
    params(("id" = String, Path, description = "Spec id (64 lowercase hex digits)")),
    responses(
        (status = 200, description = "The table's metadata (docs/table-format.md)", body = Object),
        (status = 401, description = "Token required for reads (--token-reads)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown id", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not done yet", body = Problem, content_type = "application/problem+json"),
    ),
    security((), ("bearer" = []))
)]
pub async fn get_metadata(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let (_, table) = table_of(&state, &id).await?;
    let mut res = Json(&table.metadata).into_response();
    res.headers_mut().insert(
        header::CACHE_CONTROL,
        HeaderValue::from_static(super::results::IMMUTABLE),
    );
    Ok(res)
}
