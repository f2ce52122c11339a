//! Point evaluation of a done job's BRDF table (`src/brdf`): one direction
//! pair by query string (`GET`), many by body (`POST`).

use super::AppState;
use super::error::ApiError;
use super::problem::Problem;
use super::results::{IMMUTABLE, table_of};
use crate::brdf::coverage::nested;
use crate::brdf::export::FRAMES;
use crate::brdf::{BrdfError, Directions, Table};
use axum::Json;
use axum::body::Bytes;
use axum::extract::rejection::{BytesRejection, QueryRejection};
use axum::extract::{Path, Query, State};
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

/// One direction pair (graphics convention, degrees; conventions §5) and
/// an optional wavelength.
#[derive(Clone, Debug, Deserialize, ToSchema, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct EvalQuery {
    /// Incident polar angle, `[0, 90]`.
    pub theta_i_deg: f64,
    /// Incident azimuth, `[-360, 360]`.
    pub phi_i_deg: f64,
    /// Outgoing polar angle, `[0, 90]`.
    pub theta_o_deg: f64,
    /// Outgoing azimuth, `[-360, 360]`.
    pub phi_o_deg: f64,
    /// Vacuum wavelength (nm) inside the table's range (linear between
    /// its wavelengths); may be omitted for a one-wavelength table.
    pub wavelength_nm: Option<f64>,
}

/// A direction pair of a `POST …/eval` body.
#[derive(Clone, Debug, Deserialize, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EvalPoint {
    /// Incident polar angle, `[0, 90]`.
    pub theta_i_deg: f64,
    /// Incident azimuth, `[-360, 360]`.
    pub phi_i_deg: f64,
    /// Outgoing polar angle, `[0, 90]`.
    pub theta_o_deg: f64,
    /// Outgoing azimuth, `[-360, 360]`.
    pub phi_o_deg: f64,
}

/// Body of `POST …/eval`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EvalRequest {
    /// Direction pairs (at most `--max-eval-points`, default 100000).
    pub points: Vec<EvalPoint>,
    /// Vacuum wavelength (nm); may be omitted for a one-wavelength table.
    #[serde(default)]
    pub wavelength_nm: Option<f64>,
}

/// The BRDF at one direction pair.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct EvalValue {
    /// Incident polar angle (deg).
    pub theta_i_deg: f64,
    /// Incident azimuth (deg).
    pub phi_i_deg: f64,
    /// Outgoing polar angle (deg).
    pub theta_o_deg: f64,
    /// Outgoing azimuth (deg).
    pub phi_o_deg: f64,
    /// Diffuse Mueller BRDF (1/sr), nested rows, row = outgoing Stokes
    /// component: 4 × 4, or what the result's `needs.stokes` kept (4 × 1
    /// `[[m00], [m10], [m20], [m30]]` for `"unpolarized_in"`, 1 × 1
    /// `[[m00]]` for `"intensity"`).
    pub mueller: Vec<Vec<f64>>,
    /// Specular matrix `S` (conventions §6), in the same shape as
    /// `mueller`, when the base is a mirror and the pair is a mirror pair,
    /// else `null`.
    pub specular: Option<Vec<Vec<f64>>>,
}

/// Answer of the eval endpoints.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct EvalResponse {
    /// Spec id.
    pub id: String,
    /// The wavelength evaluated (`null` for a wavelength-free table).
    pub wavelength_nm: Option<f64>,
    /// `1/sr`.
    pub units: String,
    /// The Stokes reference frames.
    pub frames: String,
    /// One entry per direction pair.
    pub points: Vec<EvalValue>,
}

/// A query error of `brdf` as a 422 naming the field: the angle the
/// message starts with (after `prefix`, e.g. `points[3].`), else the
/// wavelength.
fn query_error(e: BrdfError, prefix: &str) -> ApiError {
    let message = e.to_string();
    let path = message
        .split(" = ")
        .next()
        .filter(|f| f.ends_with("_deg") && f.chars().all(|c| c.is_ascii_lowercase() || c == '_'))
        .map_or_else(|| "wavelength_nm".to_string(), |f| format!("{prefix}{f}"));
    ApiError::InvalidQuery { path, message }
}

fn evaluate(
    table: &Table,
    points: &[EvalPoint],
    wavelength_nm: Option<f64>,
    prefix: impl Fn(usize) -> String,
) -> Result<Vec<EvalValue>, ApiError> {
    let shape = table.shape();
    let mut out = Vec::with_capacity(points.len());
    for (k, p) in points.iter().enumerate() {
        let d = Directions {
            theta_i_deg: p.theta_i_deg,
            phi_i_deg: p.phi_i_deg,
            theta_o_deg: p.theta_o_deg,
            phi_o_deg: p.phi_o_deg,
        };
        let mueller = table
            .eval(&d, wavelength_nm)
            .map_err(|e| query_error(e, &prefix(k)))?;
        let specular = table
            .specular(&d, wavelength_nm)
            .map_err(|e| query_error(e, &prefix(k)))?;
        out.push(EvalValue {
            theta_i_deg: p.theta_i_deg,
            phi_i_deg: p.phi_i_deg,
            theta_o_deg: p.theta_o_deg,
            phi_o_deg: p.phi_o_deg,
            mueller: nested(&mueller, shape),
            specular: specular.map(|s| nested(&s, shape)),
        });
    }
    Ok(out)
}

fn response(
    id: String,
    table: &Table,
    wavelength_nm: Option<f64>,
    points: Vec<EvalValue>,
) -> EvalResponse {
    EvalResponse {
        id,
        wavelength_nm: wavelength_nm.or_else(|| {
            (table.wavelengths.len() == 1)
                .then(|| table.wavelengths[0].wavelength_nm)
                .flatten()
        }),
        units: "1/sr".into(),
        frames: FRAMES.into(),
        points,
    }
}

/// The Mueller BRDF of a done job at one direction pair.
///
/// Interpolated from the stored table (docs/table-format.md): polar
/// cosines by the table's scheme, exact Fourier sum in azimuth, linear in
/// wavelength. Results never change for an id: cacheable as immutable.
#[utoipa::path(
    get,
    path = "/v1/brdfs/{id}/eval",
    tag = "brdfs",
    params(("id" = String, Path, description = "Spec id"), EvalQuery),
    responses(
        (status = 200, description = "The BRDF at the pair (one entry in `points`)", body = EvalResponse),
        (status = 404, description = "Unknown id", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not done yet, or failed", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Angle or wavelength out of range, or an incident angle outside the result's `needs.theta_i_deg`; `path` names the parameter", body = Problem, content_type = "application/problem+json"),
    ),
    security((), ("bearer" = []))
)]
pub async fn get_eval(
    State(state): State<AppState>,
    Path(id): Path<String>,
    query: Result<Query<EvalQuery>, QueryRejection>,
) -> Result<Response, ApiError> {
    let Query(q) = query.map_err(|e| ApiError::InvalidQuery {
        path: "query".into(),
        message: format!(
            "{}; give theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg and optionally wavelength_nm",
            e.body_text()
        ),
    })?;
    let (_, table) = table_of(&state, &id).await?;
    state.0.jobs.served(&id);
    let p = EvalPoint {
        theta_i_deg: q.theta_i_deg,
        phi_i_deg: q.phi_i_deg,
        theta_o_deg: q.theta_o_deg,
        phi_o_deg: q.phi_o_deg,
    };
    let points = evaluate(&table, &[p], q.wavelength_nm, |_| String::new())?;
    let mut res = Json(response(id, &table, q.wavelength_nm, points)).into_response();
    res.headers_mut()
        .insert(header::CACHE_CONTROL, HeaderValue::from_static(IMMUTABLE));
    Ok(res)
}

/// The Mueller BRDF of a done job at many direction pairs.
#[utoipa::path(
    post,
    path = "/v1/brdfs/{id}/eval",
    tag = "brdfs",
    params(("id" = String, Path, description = "Spec id")),
    request_body(content = EvalRequest, content_type = "application/json"),
    responses(
        (status = 200, description = "The BRDF at every pair, in order", body = EvalResponse),
        (status = 404, description = "Unknown id", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not done yet, or failed", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body over --max-body-bytes", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Malformed body, too many points, angle or wavelength out of range, or an incident angle outside the result's `needs.theta_i_deg`; `path` names the field", body = Problem, content_type = "application/problem+json"),
    ),
    security((), ("bearer" = []))
)]
pub async fn post_eval(
    State(state): State<AppState>,
    Path(id): Path<String>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let body = body.map_err(|e| ApiError::from_body(e, state.0.config.max_body_bytes))?;
    let req: EvalRequest =
        crate::material::from_json_slice(&body).map_err(|e| ApiError::InvalidQuery {
            path: e.path,
            message: e.message,
        })?;
    if req.points.len() > state.0.config.limits.max_eval_points {
        return Err(ApiError::InvalidQuery {
            path: "points".into(),
            message: format!(
                "{} points exceed this service's limit of {} per request (--max-eval-points)",
                req.points.len(),
                state.0.config.limits.max_eval_points
            ),
        });
    }
    let (_, table) = table_of(&state, &id).await?;
    state.0.jobs.served(&id);
    let wl = req.wavelength_nm;
    let t = table.clone();
    let points = tokio::task::spawn_blocking(move || {
        evaluate(&t, &req.points, wl, |k| format!("points[{k}]."))
    })
    .await
    .map_err(|e| ApiError::Internal(e.to_string()))??;
    Ok(Json(response(id, &table, wl, points)).into_response())
}
