//! `GET /v1/brdfs`: the cache and the queue, newest first (or largest
//! first), filtered, in pages; each entry carries what the console's queue
//! and cache pages show ([`BrdfSummary`]).

use super::AppState;
use super::brdfs::{JobStatus, Links};
use super::error::ApiError;
use super::problem::Problem;
use super::summary::{Filter, LayerSummary, STATUSES, SpecSummary, Thickness};
use crate::plan;
use crate::storage::{JobRow, Status, now_ms, rfc3339};
use axum::Json;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, State};
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

/// Links of a listing entry: the resource, its table and its thumbnails.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct SummaryLinks {
    /// The resource.
    #[serde(rename = "self")]
    pub self_: String,
    /// The result bytes (when `status` is `done`).
    pub table: String,
    /// A sphere rendered with the result, intensity (PNG, when done).
    pub thumbnail: String,
    /// The same sphere's degree of polarization (PNG, when done).
    pub dop_thumbnail: String,
}

/// One entry of the cache listing.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct BrdfSummary {
    /// Spec id.
    pub id: String,
    /// Job state.
    pub status: JobStatus,
    /// Fraction of wavelengths solved, `[0, 1]`.
    pub progress: f64,
    /// RFC 3339.
    pub created_at: String,
    /// RFC 3339.
    pub updated_at: String,
    /// RFC 3339, when the job became done or failed.
    pub finished_at: Option<String>,
    /// Number of wavelengths (solves) of the job.
    pub wavelengths: i64,
    /// The spec's wavelengths (nm; `[]` for a wavelength-free result).
    pub wavelengths_nm: Vec<f64>,
    /// Largest estimated relative error of f11 (`null` until done, or
    /// when the request asked for none).
    pub error_estimate: Option<f64>,
    /// Size of the stored result (bytes), when done.
    pub size: Option<i64>,
    /// Solver wall time over the finished wavelengths (ms).
    pub solve_time_ms: f64,
    /// `solver.streams` of the spec (`null` when a tolerance picks them).
    pub streams: Option<i64>,
    /// `solver.tolerance` of the spec.
    pub tolerance: Option<f64>,
    /// Every population's material (or scatterer kind), each once.
    pub materials: Vec<String>,
    /// The base: `black`, `lambertian`, `fresnel:Al`, `rough_fresnel:Ag`.
    pub base: String,
    /// The top interface (`smooth`, `rough`), when there is one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub top_interface: Option<String>,
    /// The layers, top to bottom, with their thickness.
    pub layers: Vec<LayerSummary>,
    /// The instance (`--instance-id`) solving a running job.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worker: Option<String>,
    /// A running job's wall time so far (ms): its finished wavelengths'
    /// solve times plus the time since the last one finished (or it was
    /// claimed).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub elapsed_ms: Option<f64>,
    /// A running job's estimated remaining time (ms): the mean solve time
    /// of its finished wavelengths times those left, less the time spent
    /// on the current one; absent until one wavelength is done.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub remaining_ms: Option<f64>,
    /// The typed error of a failed job.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<Problem>,
    /// Related resources.
    pub links: SummaryLinks,
}

impl BrdfSummary {
    /// The entry of a row, timed against `now` (ms since the epoch).
    pub fn of(row: &JobRow, spec: &SpecSummary, now: i64) -> Self {
        let solve_time_ms = row.wall_time_ms.iter().fold(0.0, |a, b| a + b);
        let running = row.status == Status::Running;
        let since_last = (now - row.updated_at).max(0) as f64;
        let done = row.wall_time_ms.len() as i64;
        let remaining_ms = (running && done > 0).then(|| {
            let mean = solve_time_ms / done as f64;
            (mean * (row.wavelengths - done).max(0) as f64 - since_last).max(0.0)
        });
        let links = Links::of(&row.id);
        Self {
            id: row.id.clone(),
            status: row.status.into(),
            progress: row.progress,
            created_at: rfc3339(row.created_at),
            updated_at: rfc3339(row.updated_at),
            finished_at: row.finished_at.map(rfc3339),
            wavelengths: row.wavelengths,
            wavelengths_nm: spec.wavelengths_nm.clone(),
            error_estimate: row.error_estimate,
            size: row.size.filter(|_| row.status == Status::Done),
            solve_time_ms,
            streams: spec.streams,
            tolerance: spec.tolerance,
            materials: spec.materials(),
            base: spec.base.clone(),
            top_interface: spec.top_interface.clone(),
            layers: spec.layers.clone(),
            worker: row.worker.clone().filter(|_| running),
            elapsed_ms: running.then_some(solve_time_ms + since_last),
            remaining_ms,
            error: crate::jobs::FailureRecord::of_row(row).map(Problem::from),
            links: SummaryLinks {
                thumbnail: format!("{}/thumbnail?kind=intensity", links.self_),
                dop_thumbnail: format!("{}/thumbnail?kind=dop", links.self_),
                self_: links.self_,
                table: links.table,
            },
        }
    }

    /// The entry of a row, its spec parsed and timed now.
    pub fn of_row(row: &JobRow) -> Self {
        let spec = serde_json::from_str(&row.spec).unwrap_or(serde_json::Value::Null);
        Self::of(row, &SpecSummary::of(&spec), now_ms())
    }
}

/// A page of the cache listing.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct BrdfList {
    /// The entries of this page.
    pub items: Vec<BrdfSummary>,
    /// Cursor of the next page (`?cursor=`), `null` on the last page.
    pub next: Option<String>,
}

/// Query of `GET /v1/brdfs`.
#[derive(Clone, Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct ListQuery {
    /// Entries per page, `[1, 500]` (default 50).
    #[param(value_type = Option<u32>, minimum = 1, maximum = 500)]
    pub limit: Option<String>,
    /// The `next` of the previous page (of the same filters and sort).
    pub cursor: Option<String>,
    /// Only jobs in these states: `queued`, `running`, `done`, `failed`,
    /// comma-separated.
    pub status: Option<String>,
    /// Only results with a population of this material (or scatterer
    /// kind: `rayleigh`, `expansion`, `henyey_greenstein`),
    /// case-insensitive.
    pub material: Option<String>,
    /// Only results over this base: its kind (`black`, `lambertian`,
    /// `fresnel`, `rough_fresnel`), its material (`Al`) or both
    /// (`fresnel:Al`), case-insensitive.
    pub base: Option<String>,
    /// Only results with this wavelength (nm).
    #[param(value_type = Option<f64>)]
    pub wavelength_nm: Option<String>,
    /// Only results with a layer of this optical thickness or film
    /// thickness (µm), or `infinite`.
    pub thickness: Option<String>,
    /// Free text: a prefix of the id, or part of a material, the base or
    /// the top interface (case-insensitive).
    pub q: Option<String>,
    /// `recent` (newest first, the default) or `size` (largest stored
    /// result first; jobs without a result last).
    pub sort: Option<String>,
}

/// Entries per page of `GET /v1/brdfs` unless `?limit=` says otherwise.
pub const LIST_DEFAULT_LIMIT: usize = 50;
/// Most entries per page.
pub const LIST_MAX_LIMIT: usize = 500;
/// Rows read from the index per round while filling a filtered page.
const SCAN_BATCH: i64 = 500;

/// The order of a listing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Sort {
    Recent,
    Size,
}

/// Where the next page starts: after this entry of the order.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Cursor {
    /// `<created_at ms>-<id>`.
    Recent(i64, String),
    /// `size:<bytes>-<id>` (`-1` for no result).
    Size(i64, String),
}

fn size_key(row: &JobRow) -> i64 {
    row.size
        .filter(|_| row.status == Status::Done)
        .unwrap_or(-1)
}

impl Cursor {
    fn after(sort: Sort, row: &JobRow) -> Self {
        match sort {
            Sort::Recent => Cursor::Recent(row.created_at, row.id.clone()),
            Sort::Size => Cursor::Size(size_key(row), row.id.clone()),
        }
    }

    fn text(&self) -> String {
        match self {
            Cursor::Recent(at, id) => format!("{at}-{id}"),
            Cursor::Size(size, id) => format!("size:{size}-{id}"),
        }
    }

    fn parse(c: &str) -> Option<Self> {
        let (size, rest) = match c.strip_prefix("size:") {
            Some(rest) => (true, rest),
            None => (false, c),
        };
        let (key, id) = rest.rsplit_once('-')?;
        let key: i64 = key.parse().ok()?;
        if !plan::is_id(id) {
            return None;
        }
        Some(if size {
            Cursor::Size(key, id.into())
        } else {
            Cursor::Recent(key, id.into())
        })
    }
}

fn invalid(path: &str, message: String) -> ApiError {
    ApiError::InvalidQuery {
        path: path.into(),
        message,
    }
}

/// A built-in material's canonical name (`Al` → `aluminium`, as the
/// canonical specs hold it), or the name as given.
fn canonical_material(name: &str) -> String {
    crate::physics::materials::find(name).map_or_else(|_| name.to_string(), |m| m.name.to_string())
}

/// The filters of a query, checked.
fn filter_of(q: &ListQuery) -> Result<Filter, ApiError> {
    let status = match q.status.as_deref() {
        None => Vec::new(),
        Some(s) => s
            .split(',')
            .map(|w| {
                let w = w.trim().to_ascii_lowercase();
                if STATUSES.contains(&w.as_str()) {
                    Ok(w)
                } else {
                    Err(invalid(
                        "status",
                        format!("'{w}' is not a job state: use {}", STATUSES.join(", ")),
                    ))
                }
            })
            .collect::<Result<_, _>>()?,
    };
    let wavelength_nm = match q.wavelength_nm.as_deref() {
        None => None,
        Some(w) => Some(
            w.trim()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| invalid("wavelength_nm", format!("'{w}' is not a number (nm)")))?,
        ),
    };
    let thickness = match q.thickness.as_deref().map(str::trim) {
        None => None,
        Some("infinite") => Some(Thickness::Infinite),
        Some(t) => Some(Thickness::Value(
            t.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite() && *x >= 0.0)
                .ok_or_else(|| {
                    invalid(
                        "thickness",
                        format!("'{t}' is not a thickness: a number ≥ 0 or 'infinite'"),
                    )
                })?,
        )),
    };
    let text = |v: &Option<String>| {
        v.as_deref()
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(String::from)
    };
    Ok(Filter {
        status,
        material: text(&q.material).map(|m| canonical_material(&m)),
        base: text(&q.base).map(|b| match b.split_once(':') {
            Some((kind, m)) => format!("{kind}:{}", canonical_material(m)),
            None => canonical_material(&b),
        }),
        wavelength_nm,
        thickness,
        q: text(&q.q),
    })
}

/// The cache: every job of the running version, newest first (or largest
/// first with `sort=size`), filtered.
///
/// Pages of `limit` entries (default 50, at most 500); `next` is the
/// cursor of the following page, `null` on the last one. Each given
/// filter must match.
#[utoipa::path(
    get,
    path = "/v1/brdfs",
    tag = "brdfs",
    params(ListQuery),
    responses(
        (status = 200, description = "A page of the cache, newest first", body = BrdfList),
        (status = 401, description = "Token required for reads (--token-reads)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "`limit` outside [1, 500], a malformed `cursor`, `status`, `wavelength_nm`, `thickness` or `sort`, or an unknown parameter; `path` names it", body = Problem, content_type = "application/problem+json"),
    ),
    security((), ("bearer" = []))
)]
pub async fn list_brdfs(
    State(state): State<AppState>,
    query: Result<Query<ListQuery>, QueryRejection>,
) -> Result<Response, ApiError> {
    let Query(q) = query.map_err(|e| {
        invalid(
            "query",
            format!(
                "{}; allowed: limit, cursor, status, material, base, wavelength_nm, thickness, q, sort",
                e.body_text()
            ),
        )
    })?;
    let limit = match q.limit.as_deref() {
        None => LIST_DEFAULT_LIMIT,
        Some(l) => l
            .parse::<usize>()
            .ok()
            .filter(|n| (1..=LIST_MAX_LIMIT).contains(n))
            .ok_or_else(|| {
                invalid(
                    "limit",
                    format!(
                        "'{l}' is outside the allowed range [1, {LIST_MAX_LIMIT}] (whole number)"
                    ),
                )
            })?,
    };
    let sort = match q.sort.as_deref() {
        None | Some("recent") => Sort::Recent,
        Some("size") => Sort::Size,
        Some(other) => {
            return Err(invalid(
                "sort",
                format!("'{other}' is not an order: use recent or size"),
            ));
        }
    };
    let after = match q.cursor.as_deref() {
        None => None,
        Some(c) => Some(
            Cursor::parse(c)
                .filter(|k| matches!((k, sort), (Cursor::Recent(..), Sort::Recent) | (Cursor::Size(..), Sort::Size)))
                .ok_or_else(|| {
                    invalid(
                        "cursor",
                        format!("'{c}' is not a cursor of this order: give the `next` of the previous page"),
                    )
                })?,
        ),
    };
    let filter = filter_of(&q)?;
    let (items, next) = page(&state, &filter, sort, after, limit).await?;
    let mut res = Json(BrdfList { items, next }).into_response();
    res.headers_mut()
        .insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    Ok(res)
}

/// The matching rows of one page and the cursor after it.
///
/// Newest first reads the index in keyset batches until the page is full
/// (a filter that matches little reads more of the index); largest first
/// reads every row of the version and sorts them.
async fn page(
    state: &AppState,
    filter: &Filter,
    sort: Sort,
    after: Option<Cursor>,
    limit: usize,
) -> Result<(Vec<BrdfSummary>, Option<String>), ApiError> {
    // Newest first stops once the page (and one more, to know of a next
    // page) is filled; largest first needs every row.
    let (start, stop_at) = match (&after, sort) {
        (Some(Cursor::Recent(at, id)), Sort::Recent) => (Some((*at, id.clone())), Some(limit)),
        (_, Sort::Recent) => (None, Some(limit)),
        (_, Sort::Size) => (None, None),
    };
    let mut matched = scan(state, filter, start, stop_at).await?;
    if sort == Sort::Size {
        matched.sort_by(|(a, _), (b, _)| (size_key(b), &b.id).cmp(&(size_key(a), &a.id)));
        if let Some(Cursor::Size(size, id)) = &after {
            matched.retain(|(r, _)| (size_key(r), &r.id) < (*size, id));
        }
    }
    let next = (matched.len() > limit).then(|| Cursor::after(sort, &matched[limit - 1].0).text());
    matched.truncate(limit);
    let now = now_ms();
    let items = matched
        .iter()
        .map(|(row, s)| BrdfSummary::of(row, s, now))
        .collect();
    Ok((items, next))
}

/// The rows passing `filter`, newest first, strictly after the
/// `(created_at, id)` key `start`, read in keyset batches of [`SCAN_BATCH`]
/// until more than `stop_at` have matched (`None`: to the end).
async fn scan(
    state: &AppState,
    filter: &Filter,
    mut start: Option<(i64, String)>,
    stop_at: Option<usize>,
) -> Result<Vec<(JobRow, SpecSummary)>, ApiError> {
    let index = state.0.jobs.index();
    let mut matched = Vec::new();
    loop {
        let rows = index
            .list(
                start.as_ref().map(|(at, id)| (*at, id.as_str())),
                SCAN_BATCH,
            )
            .await?;
        let full = rows.len() as i64 == SCAN_BATCH;
        start = rows.last().map(|r| (r.created_at, r.id.clone()));
        for row in rows {
            let spec = serde_json::from_str(&row.spec).unwrap_or(serde_json::Value::Null);
            let summary = SpecSummary::of(&spec);
            if filter.matches(&row.id, row.status.as_str(), &summary) {
                matched.push((row, summary));
            }
        }
        if !full || stop_at.is_some_and(|n| matched.len() > n) {
            return Ok(matched);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cursors_round_trip_and_refuse_garbage() {
        let id = "a".repeat(64);
        for c in [
            Cursor::Recent(1700000000000, id.clone()),
            Cursor::Size(-1, id.clone()),
            Cursor::Size(4096, id.clone()),
        ] {
            assert_eq!(Cursor::parse(&c.text()), Some(c));
        }
        assert_eq!(Cursor::parse("12-xyz"), None);
        assert_eq!(Cursor::parse(&format!("x-{id}")), None);
        assert_eq!(Cursor::parse(&id), None);
    }

    #[test]
    fn bad_filters_name_their_parameter() {
        let q = |f: fn(&mut ListQuery)| {
            let mut x = ListQuery::default();
            f(&mut x);
            filter_of(&x)
        };
        let path = |r: Result<Filter, ApiError>| match r {
            Err(ApiError::InvalidQuery { path, .. }) => path,
            other => panic!("{other:?}"),
        };
        assert_eq!(
            path(q(|x| x.status = Some("done,sleeping".into()))),
            "status"
        );
        assert_eq!(
            path(q(|x| x.wavelength_nm = Some("green".into()))),
            "wavelength_nm"
        );
        assert_eq!(path(q(|x| x.thickness = Some("-1".into()))), "thickness");
        let ok = q(|x| {
            x.status = Some("Done, failed".into());
            x.thickness = Some("infinite".into());
            x.material = Some("  ".into());
        })
        .unwrap();
        assert_eq!(ok.status, ["done", "failed"]);
        assert_eq!(ok.thickness, Some(Thickness::Infinite));
        assert_eq!(ok.material, None);
    }
}
