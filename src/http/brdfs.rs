//! The `/v1/brdfs` resource: submit a spec, watch its job, fetch its table.

use super::AppState;
use super::error::ApiError;
use super::problem::Problem;
use super::results::{IMMUTABLE, require_done, row_of, stored_bytes, table_of};
use crate::jobs::evict::Deleted;
use crate::jobs::{FailureRecord, Submission};
use crate::material::{self, ScattererSpec, Spec};
use crate::plan;
use crate::storage::{JobRow, Status, rfc3339};
use axum::Json;
use axum::body::Bytes;
use axum::extract::rejection::{BytesRejection, QueryRejection};
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

/// A material spec (docs/spec.md); its optional `needs` member is
/// `NeedsDocument`.
#[derive(ToSchema)]
#[schema(value_type = Object, example = json!({
    "layers": [{"optical_thickness": 1.0, "scatterer": {"rayleigh": {"albedo": 1.0}}}],
    "base": {"lambertian": {"albedo": 0.5}},
    "solver": {"streams": 8}
}))]
pub struct SpecDocument(pub serde_json::Value);

/// State of a job.
#[derive(Clone, Copy, Debug, Serialize, ToSchema, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum JobStatus {
    /// Waiting for a worker.
    Queued,
    /// Being solved.
    Running,
    /// Solved: the table is available.
    Done,
    /// The solve failed: see `error`.
    Failed,
}

impl From<Status> for JobStatus {
    fn from(s: Status) -> Self {
        match s {
            Status::Queued => JobStatus::Queued,
            Status::Running => JobStatus::Running,
            Status::Done => JobStatus::Done,
            Status::Failed => JobStatus::Failed,
        }
    }
}

/// Related resources.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct Links {
    /// This resource.
    #[serde(rename = "self")]
    pub self_: String,
    /// The result bytes (available when `status` is `done`).
    pub table: String,
}

impl Links {
    /// The links of result `id`.
    pub(crate) fn of(id: &str) -> Self {
        Self {
            self_: format!("/v1/brdfs/{id}"),
            table: format!("/v1/brdfs/{id}/table"),
        }
    }
}

/// The stored result.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct ResultInfo {
    /// SHA-256 of the bytes (lowercase hex); the table's ETag.
    pub digest: String,
    /// Size in bytes.
    pub size: i64,
    /// Media type of the bytes.
    pub media_type: String,
}

/// A BRDF job and, once done, its result.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct BrdfResource {
    /// Content address of the canonical spec (docs/service.md).
    pub id: String,
    /// Job state.
    pub status: JobStatus,
    /// Fraction of wavelengths solved, `[0, 1]`.
    pub progress: f64,
    /// The canonical spec (defaults filled in).
    #[schema(value_type = Object)]
    pub spec: serde_json::Value,
    /// Largest estimated error of f11 relative to max f11 over the
    /// wavelengths (`null` until the solver provides one).
    pub error_estimate: Option<f64>,
    /// Solver wall time per finished wavelength (ms).
    pub wall_time_ms: Vec<f64>,
    /// Number of wavelengths (solves) of the job.
    pub wavelengths: i64,
    /// The typed error of a failed job.
    pub error: Option<Problem>,
    /// The stored result of a done job.
    pub result: Option<ResultInfo>,
    /// RFC 3339.
    pub created_at: String,
    /// RFC 3339.
    pub updated_at: String,
    /// RFC 3339, when the job became done or failed.
    pub finished_at: Option<String>,
    /// The instance (`--instance-id`) solving the job, while it is
    /// running.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worker: Option<String>,
    /// Related resources.
    pub links: Links,
    /// In the answer to `POST /v1/brdfs` only: the ids of the cached
    /// per-wavelength results this result was assembled from, with no
    /// solve (`[]` when the id itself was cached; docs/service.md,
    /// "Per-wavelength results").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub covered_by: Option<Vec<String>>,
}

impl BrdfResource {
    fn of(row: &JobRow) -> Self {
        let result = match (&row.digest, row.size, &row.media_type) {
            (Some(d), Some(size), Some(m)) if row.status == Status::Done => Some(ResultInfo {
                digest: d.clone(),
                size,
                media_type: m.clone(),
            }),
            _ => None,
        };
        Self {
            id: row.id.clone(),
            status: row.status.into(),
            progress: row.progress,
            spec: serde_json::from_str(&row.spec).unwrap_or(serde_json::Value::Null),
            error_estimate: row.error_estimate,
            wall_time_ms: row.wall_time_ms.clone(),
            wavelengths: row.wavelengths,
            error: FailureRecord::of_row(row).map(Problem::from),
            result,
            created_at: rfc3339(row.created_at),
            updated_at: rfc3339(row.updated_at),
            finished_at: row.finished_at.map(rfc3339),
            worker: row.worker.clone().filter(|_| row.status == Status::Running),
            links: Links::of(&row.id),
            covered_by: None,
        }
    }
}

/// A submission that is being solved.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct Accepted {
    /// Spec id.
    pub id: String,
    /// `queued` or `running`.
    pub status: JobStatus,
    /// Related resources.
    pub links: Links,
    /// The ids of the cached per-wavelength results the job reuses: only
    /// the other wavelengths are solved (docs/service.md, "Per-wavelength
    /// results").
    pub covered_by: Vec<String>,
}

/// Check the service caps (`--max-streams`, `--max-layers`,
/// `--max-wavelengths`, `--max-expansion-terms`, `--max-size-parameter`) on
/// a parsed spec, before any work starts.
pub fn check_limits(spec: &Spec, limits: &super::config::Limits) -> Result<(), ApiError> {
    let over = |path: String, message: String| ApiError::LimitExceeded { path, message };
    if spec.layers.len() > limits.max_layers {
        return Err(over(
            "layers".into(),
            format!(
                "{} layers exceed this service's limit: allowed 1 to {} (--max-layers)",
                spec.layers.len(),
                limits.max_layers
            ),
        ));
    }
    if let Some(w) = &spec.wavelengths_nm
        && w.len() > limits.max_wavelengths
    {
        return Err(over(
            "wavelengths_nm".into(),
            format!(
                "{} wavelengths exceed this service's limit: allowed 1 to {} (--max-wavelengths)",
                w.len(),
                limits.max_wavelengths
            ),
        ));
    }
    if let Some(n) = spec.solver.streams
        && n > limits.max_streams
    {
        return Err(over(
            "solver.streams".into(),
            format!(
                "{n} is outside this service's allowed range [1, {}] (--max-streams)",
                limits.max_streams
            ),
        ));
    }
    let x = crate::plan::max_size_parameter(spec);
    if x > limits.max_size_parameter {
        let path = (spec.layers.iter().enumerate())
            .flat_map(|(i, l)| crate::plan::populations(i, l))
            .map(|(path, _)| path)
            .next()
            .unwrap_or_else(|| "layers[0]".into());
        return Err(over(
            path,
            format!(
                "the Mie size parameter 2π r n_host/λ reaches {x:.1} (largest radius at the shortest wavelength), over this service's limit {} (--max-size-parameter)",
                limits.max_size_parameter
            ),
        ));
    }
    for (i, layer) in spec.layers.iter().enumerate() {
        if let Some(ScattererSpec::Expansion(e)) = layer.optical_scatterer() {
            for (name, v) in [
                ("beta", &e.beta),
                ("alpha", &e.alpha),
                ("zeta", &e.zeta),
                ("delta", &e.delta),
                ("gamma", &e.gamma),
                ("epsilon", &e.epsilon),
            ] {
                if v.len() > limits.max_expansion_terms {
                    return Err(over(
                        format!("layers[{i}].scatterer.expansion.{name}"),
                        format!(
                            "{} terms exceed this service's limit: allowed at most {} (--max-expansion-terms)",
                            v.len(),
                            limits.max_expansion_terms
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

fn location(id: &str) -> HeaderValue {
    HeaderValue::from_str(&format!("/v1/brdfs/{id}")).expect("ASCII id")
}

/// Submit a spec.
///
/// The spec is parsed, validated and reduced to its canonical form; its id
/// is the SHA-256 of that form (docs/service.md). A known id is answered
/// from the cache (200, the resource); otherwise a job is queued, or the
/// submission joins the queued or running job of the same id (202).
#[utoipa::path(
    post,
    path = "/v1/brdfs",
    tag = "brdfs",
    request_body(content = SpecDocument, content_type = "application/json"),
    responses(
        (status = 200, description = "Known spec: the resource (done or failed)", body = BrdfResource,
         headers(("Content-Location" = String, description = "The resource"))),
        (status = 202, description = "Queued or running", body = Accepted,
         headers(("Location" = String, description = "The resource to poll"))),
        (status = 401, description = "Missing or wrong bearer token", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body over --max-body-bytes", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Content type is not JSON", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid spec or over a service limit; `path` names the field", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Queue full or shutting down", body = Problem, content_type = "application/problem+json",
         headers(("Retry-After" = u64, description = "Seconds"))),
    ),
    security((), ("bearer" = []))
)]
pub async fn create_brdf(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    require_json(&headers)?;
    let body = body.map_err(|e| ApiError::from_body(e, state.0.config.max_body_bytes))?;
    let text = std::str::from_utf8(&body).map_err(|e| {
        ApiError::InvalidSpec(material::SpecError {
            path: "$".into(),
            message: format!("the body is not UTF-8: {e}"),
        })
    })?;
    let spec = material::parse(text).map_err(ApiError::InvalidSpec)?;
    match submit(&state, &spec).await? {
        Submission::Cached { row, covered_by } => {
            let mut resource = BrdfResource::of(&row);
            resource.covered_by = Some(covered_by);
            let mut res = Json(resource).into_response();
            res.headers_mut()
                .insert(header::CONTENT_LOCATION, location(&row.id));
            Ok(res)
        }
        Submission::Pending {
            id,
            status,
            covered_by,
        } => {
            let body = Accepted {
                links: Links::of(&id),
                status: status.into(),
                id,
                covered_by,
            };
            let loc = location(&body.id);
            let mut res = (StatusCode::ACCEPTED, Json(body)).into_response();
            res.headers_mut().insert(header::LOCATION, loc);
            Ok(res)
        }
    }
}

/// 415 unless the request's `Content-Type`, when given, is JSON
/// (`application/json` or a `+json` type).
pub(crate) fn require_json(headers: &HeaderMap) -> Result<(), ApiError> {
    if let Some(ct) = headers.get(header::CONTENT_TYPE) {
        let ct = ct.to_str().unwrap_or("");
        let essence = ct
            .split(';')
            .next()
            .unwrap_or("")
            .trim()
            .to_ascii_lowercase();
        if essence != "application/json" && !essence.ends_with("+json") {
            return Err(ApiError::UnsupportedMediaType(ct.to_string()));
        }
    }
    Ok(())
}

/// What `POST /v1/brdfs` does with a parsed spec: the service caps, the
/// checks before solving, the id, and the job (cached, joined or queued).
/// `POST /v1/scenes` submits each material's reduced request through it.
pub(crate) async fn submit(state: &AppState, spec: &Spec) -> Result<Submission, ApiError> {
    check_limits(spec, &state.0.config.limits)?;
    plan::check_solvable(spec, state.0.config.limits.max_streams).map_err(ApiError::InvalidSpec)?;
    let (canonical_json, id) = plan::id_of_spec(spec);
    tracing::debug!(%id, "submission");
    Ok(state.0.jobs.submit(spec, &canonical_json, &id).await?)
}

/// [`submit`], answered as the id, its job state and the cached results it
/// was answered from (`covered_by`, docs/service.md).
pub(crate) async fn submit_spec(
    state: &AppState,
    spec: &Spec,
) -> Result<(String, JobStatus, Vec<String>), ApiError> {
    Ok(match submit(state, spec).await? {
        Submission::Cached { row, covered_by } => (row.id.clone(), row.status.into(), covered_by),
        Submission::Pending {
            id,
            status,
            covered_by,
        } => (id, status.into(), covered_by),
    })
}

/// Delete a result (its row and its blob; docs/service.md "Cache size"):
/// the next submission of its spec solves it again. Behind the write token.
#[utoipa::path(
    delete,
    path = "/v1/brdfs/{id}",
    tag = "brdfs",
    params(("id" = String, Path, description = "Spec id (64 lowercase hex digits)")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, description = "Token required (--token)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown id", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The job is queued or running (`job-in-progress`)", body = Problem, content_type = "application/problem+json"),
    ),
    security((), ("bearer" = []))
)]
pub async fn delete_brdf(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    if !plan::is_id(&id) {
        return Err(ApiError::NotFound(id));
    }
    match state.0.jobs.delete(&id).await? {
        Deleted::Gone => {
            state.0.tables.forget(&id);
            Ok(StatusCode::NO_CONTENT.into_response())
        }
        Deleted::NotFound => Err(ApiError::NotFound(id)),
        Deleted::InProgress(status) => Err(ApiError::InProgress {
            id,
            status: status.as_str(),
        }),
    }
}

/// A BRDF job: state, progress, canonical spec, timings, error estimate,
/// the typed error of a failed job, and the result digest once done.
#[utoipa::path(
    get,
    path = "/v1/brdfs/{id}",
    tag = "brdfs",
    params(("id" = String, Path, description = "Spec id (64 lowercase hex digits)")),
    responses(
        (status = 200, description = "The resource", body = BrdfResource),
        (status = 401, description = "Token required for reads (--token-reads)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown id", body = Problem, content_type = "application/problem+json"),
    ),
    security((), ("bearer" = []))
)]
pub async fn get_brdf(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let row = row_of(&state, &id).await?;
    let mut res = Json(BrdfResource::of(&row)).into_response();
    res.headers_mut()
        .insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    Ok(res)
}

pub(crate) fn etag_of(digest: &str) -> HeaderValue {
    HeaderValue::from_str(&format!("\"{digest}\"")).expect("hex digest")
}

/// Does an `If-None-Match` header match this digest (weak comparison)?
pub(crate) fn none_match(headers: &HeaderMap, digest: &str) -> bool {
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .map(|t| t.trim().trim_start_matches("W/").trim_matches('"'))
        .any(|t| t == "*" || t == digest)
}

/// Media type of `format=mitsuba` (a Mitsuba 3 tensor file has no
/// registered type).
pub const MITSUBA_MEDIA_TYPE: &str = "application/octet-stream";

/// Formats of `GET …/table`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum TableFormat {
    /// The stored table (docs/table-format.md): Fourier coefficients on the
    /// polar grid, lossless, with the specular term and metadata.
    #[default]
    Binary,
    /// NumPy `.npy`, shape `(W, Ti, To, P, 4, 4)` on a regular grid
    /// (`polbrdf export --format npy`).
    Npy,
    /// JSON: metadata, axes, shape and the same dense values (flat, C order).
    Json,
    /// Mitsuba 3 `measured_polarized` tensor file (docs/mitsuba.md):
    /// needs a table with exactly five whole-nm wavelengths unless
    /// `resample_wavelengths=true`.
    Mitsuba,
}

/// Element type of `format=npy`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum DenseType {
    /// float32.
    #[default]
    F32,
    /// float64.
    F64,
}

/// Query of `GET …/table`.
#[derive(Clone, Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct TableQuery {
    /// `binary` (default), `npy`, `json` or `mitsuba`.
    pub format: Option<TableFormat>,
    /// Element type of `npy`: `f32` (default) or `f64`.
    pub dtype: Option<DenseType>,
    /// Polar angles of the dense grid (midpoints of equal steps of 0..90°,
    /// for both directions; default 51, as in Collin et al. 2014).
    pub theta_count: Option<usize>,
    /// Azimuths `φ_o − φ_i` of the dense grid, 0..360° inclusive (default 61).
    pub phi_count: Option<usize>,
    /// `format=mitsuba`: resample to five evenly spaced whole-nm wavelengths
    /// of the table's range (default false: the table must have five).
    pub resample_wavelengths: Option<bool>,
}

/// Bytes of a table response (the stored table, an npy array or a Mitsuba
/// tensor file).
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct TableBytes(pub Vec<u8>);

/// Allowed parameters of `GET …/table`, for error messages.
const TABLE_PARAMS: &str = "format=binary|npy|json|mitsuba, dtype=f32|f64 (npy), theta_count, phi_count (npy, json), resample_wavelengths=true|false (mitsuba)";

/// The query of `GET …/table`, parameter by parameter, so that an error
/// names the parameter and what it allows.
fn table_query(pairs: Vec<(String, String)>) -> Result<TableQuery, ApiError> {
    let bad = |path: &str, message: String| ApiError::InvalidTableQuery {
        path: path.into(),
        message,
    };
    let mut q = TableQuery::default();
    let mut seen: Vec<String> = Vec::new();
    for (k, v) in pairs {
        if seen.contains(&k) {
            return Err(bad(&k, "given more than once".into()));
        }
        seen.push(k.clone());
        let count = |v: &str| {
            v.parse::<usize>()
                .map_err(|_| bad(&k, format!("'{v}' is not a whole number ≥ 0")))
        };
        match k.as_str() {
            "format" => {
                q.format = Some(match v.as_str() {
                    "binary" => TableFormat::Binary,
                    "npy" => TableFormat::Npy,
                    "json" => TableFormat::Json,
                    "mitsuba" => TableFormat::Mitsuba,
                    _ => {
                        return Err(bad(
                            "format",
                            format!(
                                "'{v}' is not a table format: allowed binary, npy, json, mitsuba"
                            ),
                        ));
                    }
                })
            }
            "dtype" => {
                q.dtype = Some(match v.as_str() {
                    "f32" => DenseType::F32,
                    "f64" => DenseType::F64,
                    _ => return Err(bad("dtype", format!("'{v}' is not allowed: f32 or f64"))),
                })
            }
            "theta_count" => q.theta_count = Some(count(&v)?),
            "phi_count" => q.phi_count = Some(count(&v)?),
            "resample_wavelengths" => {
                q.resample_wavelengths = Some(match v.as_str() {
                    "true" => true,
                    "false" => false,
                    _ => {
                        return Err(bad(
                            "resample_wavelengths",
                            format!("'{v}' is not allowed: true or false"),
                        ));
                    }
                })
            }
            _ => {
                return Err(bad(
                    &k,
                    format!("unknown parameter; allowed: {TABLE_PARAMS}"),
                ));
            }
        }
    }
    Ok(q)
}

/// Derived exports (npy, json, mitsuba) of recent requests, by result digest
/// and query: a Mitsuba export takes seconds, so a render farm asking for the
/// same file many times gets it computed once.
#[derive(Debug, Default)]
pub struct ExportCache {
    entries: std::sync::Mutex<std::collections::VecDeque<(String, Export)>>,
}

/// Headers describing a derived export (`format=mitsuba`:
/// [`RESAMPLING_ERROR_HEADER`], [`WARNING_HEADER`]), name and value.
type ExportHeaders = Vec<(&'static str, String)>;

/// One derived export: bytes, media type, SHA-256 (hex) of the bytes, and
/// its [`ExportHeaders`].
type Export = (std::sync::Arc<Vec<u8>>, &'static str, String, ExportHeaders);

/// `format=mitsuba`: the relative resampling error of the file against the
/// table (`brdf::mitsuba::ResamplingError::relative`, the
/// `resampling_check.relative` that `polbrdf export --format mitsuba`
/// prints for the same table), always sent.
pub const RESAMPLING_ERROR_HEADER: &str = "x-polbrdf-resampling-error";
/// `format=mitsuba`: one caveat per header (`brdf::mitsuba::export_warnings`):
/// a resampling error over 1 %, a mirror base's specular delta left out.
pub const WARNING_HEADER: &str = "x-polbrdf-warning";

/// How a client of the service gets a finer Mitsuba grid (the service
/// exports the default grid), for `brdf::mitsuba::export_warnings`.
fn finer_grid_hint() -> String {
    let n = crate::brdf::mitsuba::FINER_THETA_NODES;
    format!(
        "export with the command line, polbrdf export http://HOST/v1/brdfs/ID --format mitsuba --theta-d-nodes {n} --theta-h-nodes {n} (the service writes the default grid)"
    )
}

/// Exports kept by [`ExportCache`].
const CACHED_EXPORTS: usize = 4;

impl ExportCache {
    fn get(&self, key: &str) -> Option<Export> {
        let q = self.entries.lock().expect("export cache");
        q.iter().find(|(k, _)| k == key).map(|(_, e)| e.clone())
    }

    fn put(&self, key: String, export: Export) {
        let mut q = self.entries.lock().expect("export cache");
        q.retain(|(k, _)| *k != key);
        q.push_back((key, export));
        while q.len() > CACHED_EXPORTS {
            q.pop_front();
        }
    }
}

/// A dense export of a parsed table (npy or JSON), checked against
/// `--max-dense-values` before any work.
fn dense_bytes(
    table: &crate::brdf::Table,
    q: &TableQuery,
    format: TableFormat,
    max_values: usize,
) -> Result<(Vec<u8>, &'static str, ExportHeaders), ApiError> {
    use crate::brdf::export::{self, DenseGrid, NpyType};
    let invalid = |path: &str, message: String| ApiError::InvalidTableQuery {
        path: path.into(),
        message,
    };
    if format == TableFormat::Mitsuba {
        if q.dtype.is_some() || q.theta_count.is_some() || q.phi_count.is_some() {
            return Err(invalid(
                "format",
                "dtype, theta_count and phi_count apply to format=npy|json; a Mitsuba file has its own grid (docs/mitsuba.md)".into(),
            ));
        }
        let opts = crate::brdf::mitsuba::MitsubaOptions {
            resample_wavelengths: q.resample_wavelengths.unwrap_or(false),
            ..Default::default()
        };
        use crate::brdf::mitsuba;
        table
            .require_complete("the Mitsuba export")
            .map_err(|e| invalid("format", e.to_string()))?;
        let mt = mitsuba::build(table, &opts).map_err(|e| match e {
            crate::brdf::BrdfError::Query(m) => invalid("resample_wavelengths", m),
            other => invalid("format", other.to_string()),
        })?;
        let check =
            mitsuba::resampling_error(table, &mt, mitsuba::CHECK_PAIRS, mitsuba::CHECK_SEED)
                .map_err(|e| ApiError::Internal(e.to_string()))?;
        let mut headers = vec![(RESAMPLING_ERROR_HEADER, check.relative.to_string())];
        for w in mitsuba::export_warnings(table, &check, &finer_grid_hint()) {
            headers.push((WARNING_HEADER, w));
        }
        return Ok((mt.to_bytes(), MITSUBA_MEDIA_TYPE, headers));
    }
    if q.resample_wavelengths.is_some() {
        return Err(invalid(
            "resample_wavelengths",
            "resample_wavelengths applies to format=mitsuba only".into(),
        ));
    }
    let thetas = q.theta_count.unwrap_or(51);
    let phis = q.phi_count.unwrap_or(61);
    let grid =
        DenseGrid::regular(thetas, phis).map_err(|e| invalid("theta_count", e.to_string()))?;
    let values = grid
        .values_per_wavelength()
        .saturating_mul(table.wavelengths.len());
    if values > max_values {
        return Err(invalid(
            "theta_count",
            format!(
                "{} wavelengths x {thetas} x {thetas} x {phis} x 16 = {values} values exceed this service's limit of {max_values} per export (--max-dense-values); ask for fewer angles",
                table.wavelengths.len()
            ),
        ));
    }
    if q.dtype.is_some() && format != TableFormat::Npy {
        return Err(invalid("dtype", "dtype applies to format=npy only".into()));
    }
    let d = export::dense(table, &grid).map_err(|e| invalid("theta_count", e.to_string()))?;
    match format {
        TableFormat::Npy => {
            let ty = match q.dtype.unwrap_or_default() {
                DenseType::F32 => NpyType::F32,
                DenseType::F64 => NpyType::F64,
            };
            let bytes = export::npy_bytes(&d.shape(), &d.data, ty)
                .map_err(|e| ApiError::Internal(e.to_string()))?;
            Ok((bytes, "application/x-npy", Vec::new()))
        }
        _ => {
            let v = serde_json::json!({
                "id": table.metadata.spec_hash,
                "metadata": table.metadata,
                "units": "1/sr",
                "frames": export::FRAMES,
                "shape": d.shape(),
                "order": "C: wavelength, theta_i, theta_o, phi, row (outgoing Stokes), column (incident Stokes)",
                "axes": {
                    "wavelength_nm": d.wavelength_nm,
                    "theta_i_deg": grid.theta_i_deg,
                    "theta_o_deg": grid.theta_o_deg,
                    "phi_deg": grid.phi_deg,
                    "phi_note": "phi = phi_o - phi_i (graphics convention, phi_i = 0; 180 = mirror side)",
                },
                "specular_note": "the specular delta of a mirror base or a smooth top_interface is not part of dense values; see the binary table or eval",
                "data": d.data,
            });
            Ok((
                serde_json::to_vec(&v).expect("JSON"),
                "application/json",
                Vec::new(),
            ))
        }
    }
}

/// The result bytes of a done job, or a dense export of them.
///
/// `format=binary` (default) serves the stored table; `npy` and `json` a
/// dense regular grid (`theta_count` × `theta_count` × `phi_count`, default
/// 51 × 51 × 61, the table size of Collin et al. 2014) of the Mueller BRDF. The ETag is the SHA-256 of
/// the bytes served; results never change, so they are served `immutable`
/// and `If-None-Match` gives 304. HEAD is supported. The stored bytes are
/// verified against their digest on every read: a missing or corrupt blob
/// is never served; the job is queued again (409 until it is done).
#[utoipa::path(
    get,
    path = "/v1/brdfs/{id}/table",
    tag = "brdfs",
    params(
        ("id" = String, Path, description = "Spec id"),
        ("If-None-Match" = Option<String>, Header, description = "ETag(s) the client holds"),
        TableQuery,
    ),
    responses(
        (status = 200, description = "The BRDF table (docs/table-format.md), Content-Type application/vnd.polbrdf.table; version=4 (version=5 for a table under a smooth top_interface, version=6 under a rough one); or with format=npy (application/x-npy) or format=json (application/json) a dense export; or with format=mitsuba a Mitsuba 3 measured_polarized tensor file (docs/mitsuba.md), application/octet-stream",
         content(
             (TableBytes = "application/vnd.polbrdf.table; version=4"),
             (TableBytes = "application/x-npy"),
             (Object = "application/json"),
             (TableBytes = "application/octet-stream"),
         ),
         headers(("ETag" = String, description = "\"<sha256 of the bytes>\""),
                 ("Cache-Control" = String, description = "public, max-age=31536000, immutable"),
                 ("X-Polbrdf-Resampling-Error" = f64, description = "format=mitsuba only: max |error of f cos(theta_i)| of the file against the table relative to max f11 cos(theta_i), at 2000 seeded direction pairs x 5 wavelengths (the resampling_check.relative of polbrdf export --format mitsuba; docs/mitsuba.md)"),
                 ("X-Polbrdf-Warning" = String, description = "format=mitsuba only, one header per caveat: the resampling error is over 1 % (and how to get a finer grid), or the table's mirror base has a specular delta that is not in the file (docs/mitsuba.md)"))),
        (status = 304, description = "The client's copy is current",
         headers(("ETag" = String), ("Cache-Control" = String))),
        (status = 401, description = "Token required for reads (--token-reads)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown id", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not done yet (queued, running, or being solved again), or failed", body = Problem, content_type = "application/problem+json",
         headers(("Retry-After" = u64, description = "Seconds (not ready)"))),
        (status = 422, description = "Unknown format or parameter, or a dense grid over --max-dense-values (`invalid-table-query`); `path` names the parameter", body = Problem, content_type = "application/problem+json"),
    ),
    security((), ("bearer" = []))
)]
pub async fn get_table(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    query: Result<Query<Vec<(String, String)>>, QueryRejection>,
) -> Result<Response, ApiError> {
    let Query(pairs) = query.map_err(|e| ApiError::InvalidTableQuery {
        path: "query".into(),
        message: format!("{}; allowed: {TABLE_PARAMS}", e.body_text()),
    })?;
    let q = table_query(pairs)?;
    let format = q.format.unwrap_or_default();
    if format != TableFormat::Binary {
        let (row, table) = table_of(&state, &id).await?;
        state.0.jobs.served(&id);
        let key = format!(
            "{}?{format:?}&{:?}&{:?}&{:?}&{:?}",
            row.digest.as_deref().unwrap_or(""),
            q.dtype,
            q.theta_count,
            q.phi_count,
            q.resample_wavelengths
        );
        let (bytes, media, digest, extra) = match state.0.exports.get(&key) {
            Some(hit) => hit,
            None => {
                let max = state.0.config.limits.max_dense_values;
                let export = tokio::task::spawn_blocking(move || {
                    dense_bytes(&table, &q, format, max).map(|(bytes, media, extra)| {
                        let digest = crate::digest::sha256_hex(&bytes);
                        (std::sync::Arc::new(bytes), media, digest, extra)
                    })
                })
                .await
                .map_err(|e| ApiError::Internal(e.to_string()))??;
                state.0.exports.put(key, export.clone());
                export
            }
        };
        let mut res = if none_match(&headers, &digest) {
            StatusCode::NOT_MODIFIED.into_response()
        } else {
            let mut r = axum::body::Body::from(bytes.as_ref().clone()).into_response();
            r.headers_mut()
                .insert(header::CONTENT_TYPE, HeaderValue::from_static(media));
            r
        };
        let h = res.headers_mut();
        h.insert(header::ETAG, etag_of(&digest));
        h.insert(header::CACHE_CONTROL, HeaderValue::from_static(IMMUTABLE));
        for (name, value) in extra {
            let value = HeaderValue::from_str(&value)
                .map_err(|e| ApiError::Internal(format!("header {name}: {e}")))?;
            h.append(name, value);
        }
        return Ok(res);
    }
    if q.dtype.is_some()
        || q.theta_count.is_some()
        || q.phi_count.is_some()
        || q.resample_wavelengths.is_some()
    {
        return Err(ApiError::InvalidTableQuery {
            path: "format".into(),
            message: "dtype, theta_count, phi_count (npy, json) and resample_wavelengths (mitsuba) do not apply to the binary table".into(),
        });
    }
    let row = row_of(&state, &id).await?;
    require_done(&row, &id)?;
    state.0.jobs.served(&id);
    let digest = row.digest.clone().unwrap_or_default();
    if none_match(&headers, &digest) {
        let mut res = StatusCode::NOT_MODIFIED.into_response();
        let h = res.headers_mut();
        h.insert(header::ETAG, etag_of(&digest));
        h.insert(header::CACHE_CONTROL, HeaderValue::from_static(IMMUTABLE));
        return Ok(res);
    }
    let bytes = stored_bytes(&state, &row).await?;
    let media = row
        .media_type
        .as_deref()
        .and_then(|m| HeaderValue::from_str(m).ok())
        .unwrap_or(HeaderValue::from_static("application/octet-stream"));
    let mut res = bytes.into_response();
    let h = res.headers_mut();
    h.insert(header::CONTENT_TYPE, media);
    h.insert(header::ETAG, etag_of(&digest));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static(IMMUTABLE));
    Ok(res)
}
