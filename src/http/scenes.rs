//! `POST /v1/scenes` (issue 16, "Whole scenes"): a render scene
//! (docs/render.md) whose spheres name material specs; each material's
//! reduced request (what the scene needs of it, `render::scene_plan`) is
//! submitted, or found, through the same path as `POST /v1/brdfs`
//! ([`super::brdfs::submit_spec`]).

use super::AppState;
use super::brdfs::{JobStatus, Links, submit_spec};
use super::error::ApiError;
use super::problem::Problem;
use crate::material::{self, SpecError};
use crate::render::scene::{self, MaterialDesc, SurfaceSource};
use crate::render::scene_plan::{self, MaterialInput};
use axum::Json;
use axum::body::Bytes;
use axum::extract::State;
use axum::extract::rejection::BytesRejection;
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

/// A render scene (docs/render.md) with inline material specs.
#[derive(ToSchema)]
#[schema(value_type = Object, example = json!({
    "camera": {"position": [0, -6, 2], "look_at": [0, 0, 0.8], "fov_deg": 30, "width": 64, "height": 64},
    "lights": [{"point": {"position": [3, -3, 4], "stokes": [10, 0, 0, 0]}}],
    "spheres": [{"center": [0, 0, 1], "radius": 1, "name": "paint",
                 "material": {"layers": [{"optical_thickness": 0.3, "scatterer": {"rayleigh": {"albedo": 1.0}}}],
                              "solver": {"streams": 4}}}],
    "floor": {"albedo": 0.5},
    "wavelengths_nm": [550],
    "tolerance": 0.01
}))]
pub struct SceneDocument(pub serde_json::Value);

/// One material sphere of a submitted scene.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct SceneMaterial {
    /// The sphere's `name`, else `spheres[k]`.
    pub name: String,
    /// Id of the reduced request (`/v1/brdfs/{id}`).
    pub id: String,
    /// Its job state.
    pub status: JobStatus,
    /// The cached results the request was answered from or reuses
    /// (per-wavelength and covering results, docs/service.md).
    pub covered_by: Vec<String>,
    /// The result and its table.
    pub links: Links,
}

/// The answer of `POST /v1/scenes`.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct SceneSubmission {
    /// The material spheres in scene order (table spheres are not listed).
    pub materials: Vec<SceneMaterial>,
}

/// A scene error (`"path: message"`) as a 422 naming the path.
fn invalid(text: &str) -> ApiError {
    let (path, message) = text.split_once(": ").unwrap_or(("$", text));
    ApiError::InvalidSpec(SpecError::new(path, message))
}

/// Submit a scene's materials.
///
/// The scene is parsed and validated as `polbrdf render` does; every
/// material must be inline (the service reads no files); each material's
/// reduced spec (`polbrdf scene plan`) is submitted as `POST /v1/brdfs`
/// would submit it. **200** when every result is final, **202** when some
/// job is queued or running.
#[utoipa::path(
    post,
    path = "/v1/scenes",
    tag = "scenes",
    request_body(content = SceneDocument, description = "A render scene (docs/render.md)", content_type = "application/json"),
    responses(
        (status = 200, description = "Every material's result is final", body = SceneSubmission),
        (status = 202, description = "Some material's job is queued or running", body = SceneSubmission),
        (status = 401, description = "Missing or wrong bearer token", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body over --max-body-bytes", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Content type is not JSON", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid scene or material, or over a service limit; `path` names the field", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Queue full or shutting down", body = Problem, content_type = "application/problem+json"),
    ),
    security((), ("bearer" = []))
)]
pub async fn create_scene(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    super::brdfs::require_json(&headers)?;
    let body = body.map_err(|e| ApiError::from_body(e, state.0.config.max_body_bytes))?;
    let text = std::str::from_utf8(&body)
        .map_err(|e| invalid(&format!("$: the body is not UTF-8: {e}")))?;
    let desc = scene::parse(text).map_err(|e| invalid(&e))?;
    let mut materials = Vec::new();
    for (k, s) in desc.spheres.iter().enumerate() {
        materials.push(match s.source() {
            SurfaceSource::Table(_) => None,
            SurfaceSource::Material(MaterialDesc::Path(_)) => {
                return Err(invalid(&format!(
                    "spheres[{k}].material: a spec file cannot be read by the service; give the spec inline"
                )));
            }
            SurfaceSource::Material(MaterialDesc::Inline(obj)) => {
                let json = serde_json::Value::Object(obj.clone());
                let spec = material::parse(&json.to_string()).map_err(|e| {
                    ApiError::InvalidSpec(SpecError::new(
                        format!("spheres[{k}].material.{}", e.path).replace(".$", ""),
                        e.message,
                    ))
                })?;
                Some(MaterialInput {
                    source: "inline".into(),
                    json,
                    spec,
                })
            }
        });
    }
    let plan = scene_plan::plan_scene(&desc, &materials, None).map_err(|e| invalid(&e))?;
    let mut out: Vec<SceneMaterial> = Vec::new();
    for (k, entry) in plan.materials.iter().enumerate() {
        let Some(reduced) = &entry.spec else { continue };
        if let Some(same) = &entry.same_as
            && let Some(m) = out.iter().find(|m| &m.name == same)
        {
            let mut m = m.clone();
            m.name = entry.name.clone();
            out.push(m);
            continue;
        }
        let spec_text = reduced.to_string();
        let prefix = |e: SpecError| {
            ApiError::InvalidSpec(SpecError::new(
                format!("spheres[{k}].material (reduced for the scene).{}", e.path),
                e.message,
            ))
        };
        let spec = material::parse(&spec_text).map_err(prefix)?;
        let (id, status, covered_by) = submit_spec(&state, &spec).await?;
        out.push(SceneMaterial {
            name: entry.name.clone(),
            links: Links::of(&id),
            id,
            status,
            covered_by,
        });
    }
    let pending = out
        .iter()
        .any(|m| matches!(m.status, JobStatus::Queued | JobStatus::Running));
    let code = if pending {
        StatusCode::ACCEPTED
    } else {
        StatusCode::OK
    };
    Ok((code, Json(SceneSubmission { materials: out })).into_response())
}
