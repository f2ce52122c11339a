//! The job/result index: one row per spec id in SQLite (migrations/, run at
//! start by [`Index::open`]). Short statements only; every state change is a
//! single `UPDATE`, so a crash leaves each row in a state the start-up scan
//! understands (queued/running rows are solved again).
//!
//! SQLite is the single-node store: it must not live on a network
//! filesystem. Several nodes would share PostgreSQL (claiming rows with
//! `FOR UPDATE SKIP LOCKED` and leases) behind the same methods.

use super::StorageError;
use crate::plan::{family_of_canonical, result_version};
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use sqlx::{Row, SqlitePool};
use std::str::FromStr;
use std::time::Duration;

/// State of a row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Status {
    /// Waiting for a worker.
    Queued,
    /// Being solved.
    Running,
    /// Solved; the result blob is `digest`.
    Done,
    /// The solve failed; `error` holds the problem.
    Failed,
}

impl Status {
    /// The database / API spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Queued => "queued",
            Status::Running => "running",
            Status::Done => "done",
            Status::Failed => "failed",
        }
    }

    /// All states, in lifecycle order.
    pub const ALL: [Status; 4] = [
        Status::Queued,
        Status::Running,
        Status::Done,
        Status::Failed,
    ];
}

impl FromStr for Status {
    type Err = StorageError;
    fn from_str(s: &str) -> Result<Self, StorageError> {
        Status::ALL
            .into_iter()
            .find(|x| x.as_str() == s)
            .ok_or_else(|| StorageError::Corrupt(format!("unknown status '{s}'")))
    }
}

/// One row of `jobs`.
#[derive(Clone, Debug, PartialEq)]
pub struct JobRow {
    /// Spec id.
    pub id: String,
    /// State.
    pub status: Status,
    /// Canonical JSON of the spec.
    pub spec: String,
    /// Number of wavelengths (solves).
    pub wavelengths: i64,
    /// Fraction of wavelengths done.
    pub progress: f64,
    /// Wall time per finished wavelength (ms).
    pub wall_time_ms: Vec<f64>,
    /// Error estimate of the result, when the solver provides one.
    pub error_estimate: Option<f64>,
    /// JSON problem object of a failed job.
    pub error: Option<String>,
    /// SHA-256 of the result blob.
    pub digest: Option<String>,
    /// Size of the result blob (bytes).
    pub size: Option<i64>,
    /// Media type of the result blob.
    pub media_type: Option<String>,
    /// Solves started.
    pub attempts: i64,
    /// Creation time (ms since the epoch).
    pub created_at: i64,
    /// Last change (ms since the epoch).
    pub updated_at: i64,
    /// When it became done or failed (ms since the epoch).
    pub finished_at: Option<i64>,
    /// The schema/solver version that made the row
    /// ([`crate::plan::result_version`]).
    pub result_version: String,
}

impl JobRow {
    /// Made by the running version; rows of older versions are never served
    /// nor solved (docs/service.md, "Ids and versions").
    pub fn is_current(&self) -> bool {
        self.result_version == result_version()
    }
}

/// The SQLite index.
#[derive(Clone, Debug)]
pub struct Index {
    pool: SqlitePool,
}

const COLUMNS: &str = "id, status, spec, wavelengths, progress, wall_time_ms, error_estimate, \
     error, digest, size, media_type, attempts, created_at, updated_at, finished_at, result_version";

impl Index {
    /// Connect (creating the database file if needed), switch to WAL and run
    /// the embedded migrations.
    pub async fn open(database_url: &str) -> Result<Self, StorageError> {
        let options = SqliteConnectOptions::from_str(database_url)?
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Normal)
            .busy_timeout(Duration::from_secs(10))
            .foreign_keys(true);
        let pool = SqlitePoolOptions::new()
            .max_connections(4)
            .connect_with(options)
            .await?;
        sqlx::migrate!().run(&pool).await?;
        let index = Self { pool };
        index.backfill_families().await?;
        Ok(index)
    }

    /// Give rows written before the `family` column existed their family
    /// (migrations/0003), so that they can cover requests too.
    async fn backfill_families(&self) -> Result<(), StorageError> {
        let rows = sqlx::query("SELECT id, spec FROM jobs WHERE family IS NULL")
            .fetch_all(&self.pool)
            .await?;
        for r in rows {
            let (id, spec): (String, String) = (r.try_get("id")?, r.try_get("spec")?);
            sqlx::query("UPDATE jobs SET family = ?2 WHERE id = ?1")
                .bind(id)
                .bind(family_of_canonical(&spec))
                .execute(&self.pool)
                .await?;
        }
        Ok(())
    }

    /// Done rows of the current version in `family`
    /// ([`crate::plan::family_of_canonical`]) other than `except`, newest
    /// first, at most `limit`: the results that may cover a request
    /// (docs/service.md, "Covering results").
    pub async fn done_in_family(
        &self,
        family: &str,
        except: &str,
        limit: i64,
    ) -> Result<Vec<JobRow>, StorageError> {
        let sql = format!(
            "SELECT {COLUMNS} FROM jobs
             WHERE family = ? AND status = 'done' AND result_version = ? AND id != ?
             ORDER BY finished_at DESC, id LIMIT ?"
        );
        let rows = sqlx::query(sqlx::AssertSqlSafe(sql))
            .bind(family)
            .bind(result_version())
            .bind(except)
            .bind(limit)
            .fetch_all(&self.pool)
            .await?;
        rows.iter().map(to_row).collect()
    }

    /// Close the pool (checkpoints the WAL).
    pub async fn close(&self) {
        self.pool.close().await;
    }

    /// Is the database answering?
    pub async fn ping(&self) -> Result<(), StorageError> {
        sqlx::query("SELECT 1").execute(&self.pool).await?;
        Ok(())
    }

    /// The row of an id.
    pub async fn get(&self, id: &str) -> Result<Option<JobRow>, StorageError> {
        let sql = format!("SELECT {COLUMNS} FROM jobs WHERE id = ?");
        let row = sqlx::query(sqlx::AssertSqlSafe(sql))
            .bind(id)
            .fetch_optional(&self.pool)
            .await?;
        row.map(|r| to_row(&r)).transpose()
    }

    /// Up to `limit` rows of the current version, newest first (by
    /// `created_at`, then id), strictly after the `(created_at, id)` key
    /// `after` of the previous page (keyset pagination: stable while rows
    /// are added).
    pub async fn list(
        &self,
        after: Option<(i64, &str)>,
        limit: i64,
    ) -> Result<Vec<JobRow>, StorageError> {
        let (at, id) = after.unwrap_or((i64::MAX, ""));
        let sql = format!(
            "SELECT {COLUMNS} FROM jobs WHERE result_version = ?
               AND (created_at < ? OR (created_at = ? AND id < ?) OR ? = 0)
             ORDER BY created_at DESC, id DESC LIMIT ?"
        );
        let rows = sqlx::query(sqlx::AssertSqlSafe(sql))
            .bind(result_version())
            .bind(at)
            .bind(at)
            .bind(id)
            .bind(i64::from(after.is_some()))
            .bind(limit)
            .fetch_all(&self.pool)
            .await?;
        rows.iter().map(to_row).collect()
    }

    /// Queued and running rows of the current version, oldest first (the
    /// start-up scan; rows of older versions are never solved).
    pub async fn unfinished(&self) -> Result<Vec<JobRow>, StorageError> {
        let sql = format!(
            "SELECT {COLUMNS} FROM jobs WHERE status IN ('queued', 'running') AND result_version = ?
             ORDER BY created_at, id"
        );
        let rows = sqlx::query(sqlx::AssertSqlSafe(sql))
            .bind(result_version())
            .fetch_all(&self.pool)
            .await?;
        rows.iter().map(to_row).collect()
    }

    /// Insert a queued row, or reset an existing row to queued (a result
    /// whose blob went missing, a retried failure). Keeps `created_at` and
    /// `attempts`.
    pub async fn enqueue(
        &self,
        id: &str,
        spec: &str,
        wavelengths: i64,
        now: i64,
    ) -> Result<(), StorageError> {
        sqlx::query(
            "INSERT INTO jobs (id, status, spec, wavelengths, created_at, updated_at, result_version,
               family)
             VALUES (?1, 'queued', ?2, ?3, ?4, ?4, ?5, ?6)
             ON CONFLICT (id) DO UPDATE SET
               status = 'queued', progress = 0, wall_time_ms = '[]', error_estimate = NULL,
               error = NULL, digest = NULL, size = NULL, media_type = NULL,
               updated_at = ?4, finished_at = NULL, result_version = ?5, family = ?6",
        )
        .bind(id)
        .bind(spec)
        .bind(wavelengths)
        .bind(now)
        .bind(result_version())
        .bind(family_of_canonical(spec))
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    /// Back to queued without touching anything else (shutdown, restart).
    pub async fn requeue(&self, id: &str, now: i64) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET status = 'queued', updated_at = ?2
             WHERE id = ?1 AND status IN ('queued', 'running')",
        )
        .bind(id)
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    /// A worker took the job.
    pub async fn start(&self, id: &str, now: i64) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET status = 'running', attempts = attempts + 1, progress = 0,
               wall_time_ms = '[]', updated_at = ?2
             WHERE id = ?1",
        )
        .bind(id)
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    /// A wavelength finished.
    pub async fn progress(
        &self,
        id: &str,
        progress: f64,
        wall_time_ms: &[f64],
        now: i64,
    ) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET progress = ?2, wall_time_ms = ?3, updated_at = ?4
             WHERE id = ?1 AND status = 'running'",
        )
        .bind(id)
        .bind(progress)
        .bind(json_array(wall_time_ms))
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    /// The result blob is stored: the row is a cached result from now on.
    #[allow(clippy::too_many_arguments)]
    pub async fn finish(
        &self,
        id: &str,
        digest: &str,
        size: i64,
        media_type: &str,
        wall_time_ms: &[f64],
        error_estimate: Option<f64>,
        now: i64,
    ) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET status = 'done', progress = 1, digest = ?2, size = ?3,
               media_type = ?4, wall_time_ms = ?5, error_estimate = ?6, error = NULL,
               updated_at = ?7, finished_at = ?7
             WHERE id = ?1",
        )
        .bind(id)
        .bind(digest)
        .bind(size)
        .bind(media_type)
        .bind(json_array(wall_time_ms))
        .bind(error_estimate)
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    /// Record a result computed elsewhere (a per-wavelength part solved by
    /// a multi-wavelength job, or a request assembled from cached parts) as
    /// a done row: inserted, or an existing row that is not done made done.
    /// A done row is left as it is (same id, same bytes).
    #[allow(clippy::too_many_arguments)]
    pub async fn record_done(
        &self,
        id: &str,
        spec: &str,
        digest: &str,
        size: i64,
        media_type: &str,
        wall_time_ms: &[f64],
        error_estimate: Option<f64>,
        now: i64,
    ) -> Result<(), StorageError> {
        sqlx::query(
            "INSERT INTO jobs (id, status, spec, wavelengths, progress, digest, size, media_type,
               wall_time_ms, error_estimate, created_at, updated_at, finished_at, result_version,
               family)
             VALUES (?1, 'done', ?2, ?3, 1, ?4, ?5, ?6, ?7, ?8, ?9, ?9, ?9, ?10, ?11)
             ON CONFLICT (id) DO UPDATE SET
               status = 'done', progress = 1, digest = ?4, size = ?5, media_type = ?6,
               wall_time_ms = ?7, error_estimate = ?8, error = NULL, updated_at = ?9,
               finished_at = ?9, result_version = ?10, family = ?11
             WHERE jobs.status != 'done' OR jobs.result_version != ?10",
        )
        .bind(id)
        .bind(spec)
        .bind(wall_time_ms.len() as i64)
        .bind(digest)
        .bind(size)
        .bind(media_type)
        .bind(json_array(wall_time_ms))
        .bind(error_estimate)
        .bind(now)
        .bind(result_version())
        .bind(family_of_canonical(spec))
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    /// The solve failed with this JSON problem.
    pub async fn fail(&self, id: &str, error_json: &str, now: i64) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET status = 'failed', error = ?2, digest = NULL, size = NULL,
               media_type = NULL, updated_at = ?3, finished_at = ?3
             WHERE id = ?1",
        )
        .bind(id)
        .bind(error_json)
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    /// Number of rows per state (all states, zeros included).
    pub async fn counts(&self) -> Result<Vec<(Status, i64)>, StorageError> {
        let rows = sqlx::query("SELECT status, COUNT(*) AS n FROM jobs GROUP BY status")
            .fetch_all(&self.pool)
            .await?;
        let mut out: Vec<(Status, i64)> = Status::ALL.iter().map(|&s| (s, 0)).collect();
        for r in rows {
            let s: Status = r.try_get::<String, _>("status")?.parse()?;
            let n: i64 = r.try_get("n")?;
            if let Some(e) = out.iter_mut().find(|e| e.0 == s) {
                e.1 = n;
            }
        }
        Ok(out)
    }
}

fn json_array(v: &[f64]) -> String {
    serde_json::to_string(v).expect("finite numbers")
}

fn to_row(r: &sqlx::sqlite::SqliteRow) -> Result<JobRow, StorageError> {
    let wall: String = r.try_get("wall_time_ms")?;
    Ok(JobRow {
        id: r.try_get("id")?,
        status: r.try_get::<String, _>("status")?.parse()?,
        spec: r.try_get("spec")?,
        wavelengths: r.try_get("wavelengths")?,
        progress: r.try_get("progress")?,
        wall_time_ms: serde_json::from_str(&wall)
            .map_err(|e| StorageError::Corrupt(format!("wall_time_ms: {e}")))?,
        error_estimate: r.try_get("error_estimate")?,
        error: r.try_get("error")?,
        digest: r.try_get("digest")?,
        size: r.try_get("size")?,
        media_type: r.try_get("media_type")?,
        attempts: r.try_get("attempts")?,
        created_at: r.try_get("created_at")?,
        updated_at: r.try_get("updated_at")?,
        finished_at: r.try_get("finished_at")?,
        result_version: r.try_get("result_version")?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn row_lifecycle() {
        let dir = std::env::temp_dir().join(format!(
            "polbrdf-index-{}-{}",
            std::process::id(),
            crate::storage::now_ms()
        ));
        std::fs::create_dir_all(&dir).unwrap();
        let url = format!("sqlite://{}", dir.join("i.sqlite").display());
        let ix = Index::open(&url).await.unwrap();
        let id = "a".repeat(64);
        assert_eq!(ix.get(&id).await.unwrap(), None);
        ix.enqueue(&id, "{}", 2, 10).await.unwrap();
        let r = ix.get(&id).await.unwrap().unwrap();
        assert_eq!(
            (r.status, r.attempts, r.created_at),
            (Status::Queued, 0, 10)
        );
        ix.start(&id, 11).await.unwrap();
        ix.progress(&id, 0.5, &[1.5], 12).await.unwrap();
        let r = ix.get(&id).await.unwrap().unwrap();
        assert_eq!(
            (r.status, r.attempts, r.progress),
            (Status::Running, 1, 0.5)
        );
        assert_eq!(r.wall_time_ms, vec![1.5]);
        assert_eq!(ix.unfinished().await.unwrap().len(), 1);
        ix.finish(&id, &"d".repeat(64), 3, "x/y", &[1.5, 2.5], Some(1e-6), 13)
            .await
            .unwrap();
        let r = ix.get(&id).await.unwrap().unwrap();
        assert_eq!(r.status, Status::Done);
        assert_eq!(
            (r.size, r.finished_at, r.error_estimate),
            (Some(3), Some(13), Some(1e-6))
        );
        assert!(ix.unfinished().await.unwrap().is_empty());
        // A done row is not re-queued by requeue (only queued/running are).
        ix.requeue(&id, 14).await.unwrap();
        assert_eq!(ix.get(&id).await.unwrap().unwrap().status, Status::Done);
        // Enqueue again resets the result but keeps created_at and attempts.
        ix.enqueue(&id, "{}", 2, 15).await.unwrap();
        let r = ix.get(&id).await.unwrap().unwrap();
        assert_eq!(
            (r.status, r.digest, r.created_at, r.attempts),
            (Status::Queued, None, 10, 1)
        );
        ix.fail(&id, r#"{"type":"x"}"#, 16).await.unwrap();
        let counts = ix.counts().await.unwrap();
        assert!(counts.contains(&(Status::Failed, 1)) && counts.contains(&(Status::Done, 0)));
        ix.close().await;
        // Reopening runs the (already applied) migrations again: a no-op.
        let ix = Index::open(&url).await.unwrap();
        assert_eq!(ix.get(&id).await.unwrap().unwrap().status, Status::Failed);
        ix.close().await;
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
