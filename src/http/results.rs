//! The stored results the read routes share (`brdfs`: the resource and its
//! table; `eval`): a row by id, checked for its version and status, its
//! verified bytes, and its parsed table, cached.

use super::AppState;
use super::error::ApiError;
use super::problem::Problem;
use crate::brdf::{Table, format};
use crate::jobs::FailureRecord;
use crate::plan;
use crate::storage::{JobRow, Status};
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

/// Immutable results: cacheable by any HTTP cache for a year.
pub const IMMUTABLE: &str = "public, max-age=31536000, immutable";

/// A result is served only from a done row: queued/running → not ready
/// (409 with Retry-After), failed → the job's typed problem.
pub fn require_done(row: &JobRow, id: &str) -> Result<(), ApiError> {
    match row.status {
        Status::Queued | Status::Running => Err(ApiError::NotReady {
            id: id.to_string(),
            status: row.status.as_str(),
        }),
        Status::Failed => {
            let problem = FailureRecord::of_row(row)
                .map(Problem::from)
                .unwrap_or_else(|| Problem::new("job-failed", "BRDF job failed", 409, "unknown"));
            Err(ApiError::JobFailed {
                id: id.to_string(),
                problem: Box::new(problem),
            })
        }
        Status::Done => Ok(()),
    }
}

/// The row of an id of the running version: 404 for an unknown or
/// malformed id, 410 `retired-version` for a row of another version.
pub async fn row_of(state: &AppState, id: &str) -> Result<JobRow, ApiError> {
    if !plan::is_id(id) {
        return Err(ApiError::NotFound(id.to_string()));
    }
    let row = state
        .0
        .jobs
        .index()
        .get(id)
        .await?
        .ok_or_else(|| ApiError::NotFound(id.to_string()))?;
    if !row.is_current() {
        return Err(ApiError::Retired {
            id: row.id,
            version: row.result_version,
            current: plan::result_version(),
            current_id: plan::id_of_canonical(&row.spec),
        });
    }
    Ok(row)
}

/// The verified bytes of a done row's result; 409 while a missing, corrupt
/// or stale blob is being solved again (`Jobs::result_bytes` queues it).
pub async fn stored_bytes(state: &AppState, row: &JobRow) -> Result<Vec<u8>, ApiError> {
    state
        .0
        .jobs
        .result_bytes(row)
        .await?
        .ok_or_else(|| ApiError::NotReady {
            id: row.id.clone(),
            status: "being solved again (the stored result was missing or corrupt)",
        })
}

/// The parsed table of a done row (verified bytes, cached by digest).
pub async fn table_of(state: &AppState, id: &str) -> Result<(JobRow, Arc<Table>), ApiError> {
    if !plan::is_id(id) {
        return Err(ApiError::NotFound(id.to_string()));
    }
    let app = &state.0;
    if let Some(hit) = app.tables.get_done(id) {
        return Ok(hit);
    }
    let row = row_of(state, id).await?;
    require_done(&row, id)?;
    let digest = row.digest.clone().unwrap_or_default();
    if let Some(t) = app.tables.get(&digest) {
        app.tables.put_done(id, row.clone(), t.clone());
        return Ok((row, t));
    }
    let bytes = stored_bytes(state, &row).await?;
    let table = tokio::task::spawn_blocking(move || format::from_bytes(&bytes))
        .await
        .map_err(|e| ApiError::Internal(e.to_string()))?
        .map_err(|e| ApiError::Internal(format!("stored table {digest}: {e}")))?;
    let table = Arc::new(table);
    app.tables.put(digest, table.clone());
    app.tables.put_done(id, row.clone(), table.clone());
    Ok((row, table))
}

/// Parsed tables kept in memory, by digest (most recently used last), and
/// the done rows that point at them, by id: a done result never changes
/// (the id is the spec's hash and the solve is deterministic), so a hot
/// eval or export path needs no database round trip.
#[derive(Debug, Default)]
pub struct TableCache {
    tables: Mutex<VecDeque<(String, Arc<Table>)>>,
    done: Mutex<VecDeque<DoneEntry>>,
}

/// A done row kept by [`TableCache`]: its id, row and table, and when it
/// was read from the index.
type DoneEntry = (String, JobRow, Arc<Table>, std::time::Instant);

/// How long a done row is taken from [`TableCache`] without asking the
/// index again: a result deleted or evicted on any instance of a farm stops
/// being served here within this time.
const DONE_TTL: std::time::Duration = std::time::Duration::from_secs(10);

/// Tables kept by [`TableCache`].
const CACHED_TABLES: usize = 8;

impl TableCache {
    fn get(&self, digest: &str) -> Option<Arc<Table>> {
        let mut q = self.tables.lock().expect("table cache");
        let k = q.iter().position(|(d, _)| d == digest)?;
        let e = q.remove(k).expect("entry");
        let t = e.1.clone();
        q.push_back(e);
        Some(t)
    }

    fn get_done(&self, id: &str) -> Option<(JobRow, Arc<Table>)> {
        let q = self.done.lock().expect("done cache");
        q.iter()
            .find(|(i, _, _, at)| i == id && at.elapsed() < DONE_TTL)
            .map(|(_, row, t, _)| (row.clone(), t.clone()))
    }

    fn put_done(&self, id: &str, row: JobRow, table: Arc<Table>) {
        let mut q = self.done.lock().expect("done cache");
        q.retain(|(i, _, _, _)| i != id);
        q.push_back((id.to_string(), row, table, std::time::Instant::now()));
        while q.len() > CACHED_TABLES {
            q.pop_front();
        }
    }

    /// Drop what is kept of result `id` (deleted here).
    pub fn forget(&self, id: &str) {
        self.done
            .lock()
            .expect("done cache")
            .retain(|(i, _, _, _)| i != id);
    }

    fn put(&self, digest: String, table: Arc<Table>) {
        let mut q = self.tables.lock().expect("table cache");
        q.retain(|(d, _)| *d != digest);
        q.push_back((digest, table));
        while q.len() > CACHED_TABLES {
            q.pop_front();
        }
    }
}
