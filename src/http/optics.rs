//! `POST /v1/optics`: the optics of every layer of a spec at its
//! wavelengths, what the solver would be given (`plan::film::optics_report`,
//! docs/spec.md, Layer optics report): for a paint film the derived optical
//! thickness, albedo and asymmetry parameter per wavelength, its mixed
//! expansion and each pigment's number density and cross section. Nothing
//! is queued or stored: Mie theory runs on the blocking pool and the
//! answer is returned.

use super::brdfs::{SpecDocument, check_limits, require_json};
use super::{AppState, error::ApiError, problem::Problem};
use crate::material::{self, SpecError};
use axum::Json;
use axum::body::Bytes;
use axum::extract::State;
use axum::extract::rejection::BytesRejection;
use axum::http::HeaderMap;
use utoipa::ToSchema;

/// The layer optics report (docs/spec.md, Layer optics report).
#[derive(ToSchema)]
#[schema(value_type = Object, example = json!({
    "wavelengths_nm": [550.0],
    "layers": [{"path": "layers[0]", "form": "film", "thickness_um": 25.0,
        "pigment_volume_concentration": 0.2,
        "optics": [{"wavelength_nm": 550.0, "optical_thickness": 170.6, "albedo": 1.0, "g": 0.55,
            "binder_index": {"n": 1.4946, "k": 1.74e-7}, "binder_absorption_per_um": 3.2e-6,
            "pigments": [{"number_density_per_um3": 5.97, "c_ext_um2": 1.14, "volume_um3": 0.0335,
                "extinction_per_um": 6.8, "albedo": 1.0, "g": 0.55, "size_parameter": 3.41}],
            "expansion": {"beta": [1.0, 1.65], "alpha": [0.0, 0.0], "zeta": [0.0, 0.0],
                "delta": [0.9, 1.2], "gamma": [0.0, 0.0], "epsilon": [0.0, 0.0]}}]}],
    "warnings": [{"path": "layers[0].pigments", "message": "pigment volume concentration 20.0 % is above 10 %: …"}]
}))]
pub struct OpticsReport(pub serde_json::Value);

/// The optics of a spec's layers.
///
/// The spec is parsed, validated and checked as `POST /v1/brdfs` does
/// (service limits included); then each layer is lowered at each
/// wavelength, as the solver would get it, and reported. Nothing is
/// solved or stored. `warnings` lists films denser than independent
/// scattering describes well (pigment volume concentration above 10 %).
#[utoipa::path(
    post,
    path = "/v1/optics",
    tag = "brdfs",
    request_body(content = SpecDocument, content_type = "application/json"),
    responses(
        (status = 200, description = "The layers' optics per wavelength", body = OpticsReport),
        (status = 401, description = "Missing or wrong bearer token", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body over --max-body-bytes", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Content type is not JSON", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid spec, or over a service limit; `path` names the field", body = Problem, content_type = "application/problem+json"),
    ),
    security((), ("bearer" = []))
)]
pub async fn post_optics(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<serde_json::Value>, ApiError> {
    require_json(&headers)?;
    let body = body.map_err(|e| ApiError::from_body(e, state.0.config.max_body_bytes))?;
    let text = std::str::from_utf8(&body).map_err(|e| {
        ApiError::InvalidSpec(SpecError::new("$", format!("the body is not UTF-8: {e}")))
    })?;
    let spec = material::parse(text).map_err(ApiError::InvalidSpec)?;
    check_limits(&spec, &state.0.config.limits)?;
    crate::plan::check_solvable(&spec, state.0.config.limits.max_streams)
        .map_err(ApiError::InvalidSpec)?;
    let report = tokio::task::spawn_blocking(move || crate::plan::film::optics_report(&spec))
        .await
        .map_err(|e| ApiError::Internal(format!("optics report: {e}")))?
        .map_err(ApiError::InvalidSpec)?;
    Ok(Json(report))
}
