//! The SQLite backend of the index: a file in WAL mode, migrations in
//! `migrations/` (`sqlx::migrate!()` reads only the files of that folder,
//! not `migrations/postgres/`). The single-node store: it must not live on a
//! network filesystem.

use super::{
    COLUMNS, Done, JobRow, SQL_COUNTS, SQL_PING, SQL_WITHOUT_FAMILY, Status, decode_counts,
    decode_ids, decode_row, json_array,
};
use crate::plan::{family_of_canonical, result_version};
use crate::storage::StorageError;
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use sqlx::{Row, SqlitePool};
use std::str::FromStr;
use std::time::Duration;

/// The index in a SQLite file.
#[derive(Clone, Debug)]
pub struct SqliteIndex {
    pub(super) pool: SqlitePool,
}

impl SqliteIndex {
    /// Connect (creating the database file if needed), switch to WAL and run
    /// the embedded migrations.
    pub(super) async fn open(database_url: &str) -> Result<Self, StorageError> {
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
        Ok(Self { pool })
    }

    /// Give rows written before the `family` column existed their family
    /// (migrations/0003), so that they can cover requests too.
    pub(super) async fn backfill_families(&self) -> Result<(), StorageError> {
        let rows = sqlx::query(SQL_WITHOUT_FAMILY)
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

    pub(super) async fn done_in_family(
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
        rows.iter().map(decode_row).collect()
    }

    pub(super) async fn close(&self) {
        self.pool.close().await;
    }

    pub(super) async fn ping(&self) -> Result<(), StorageError> {
        sqlx::query(SQL_PING).execute(&self.pool).await?;
        Ok(())
    }

    pub(super) async fn get(&self, id: &str) -> Result<Option<JobRow>, StorageError> {
        let sql = format!("SELECT {COLUMNS} FROM jobs WHERE id = ?");
        let row = sqlx::query(sqlx::AssertSqlSafe(sql))
            .bind(id)
            .fetch_optional(&self.pool)
            .await?;
        row.map(|r| decode_row(&r)).transpose()
    }

    pub(super) async fn list(
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
        rows.iter().map(decode_row).collect()
    }

    pub(super) async fn unfinished(&self) -> Result<Vec<JobRow>, StorageError> {
        let sql = format!(
            "SELECT {COLUMNS} FROM jobs WHERE status IN ('queued', 'running') AND result_version = ?
             ORDER BY created_at, id"
        );
        let rows = sqlx::query(sqlx::AssertSqlSafe(sql))
            .bind(result_version())
            .fetch_all(&self.pool)
            .await?;
        rows.iter().map(decode_row).collect()
    }

    pub(super) async fn enqueue(
        &self,
        id: &str,
        spec: &str,
        wavelengths: i64,
        now: i64,
    ) -> Result<bool, StorageError> {
        let r = sqlx::query(
            "INSERT INTO jobs (id, status, spec, wavelengths, created_at, updated_at, result_version,
               family)
             VALUES (?1, 'queued', ?2, ?3, ?4, ?4, ?5, ?6)
             ON CONFLICT (id) DO UPDATE SET
               status = 'queued', progress = 0, wall_time_ms = '[]', error_estimate = NULL,
               error = NULL, digest = NULL, size = NULL, media_type = NULL,
               updated_at = ?4, finished_at = NULL, result_version = ?5, family = ?6,
               lease_owner = NULL, lease_expires_at = NULL
             WHERE jobs.status IN ('done', 'failed') OR jobs.result_version != ?5",
        )
        .bind(id)
        .bind(spec)
        .bind(wavelengths)
        .bind(now)
        .bind(result_version())
        .bind(family_of_canonical(spec))
        .execute(&self.pool)
        .await?;
        Ok(r.rows_affected() == 1)
    }

    pub(super) async fn progress(
        &self,
        id: &str,
        owner: &str,
        progress: f64,
        wall_time_ms: &[f64],
        now: i64,
    ) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET progress = ?2, wall_time_ms = ?3, updated_at = ?4
             WHERE id = ?1 AND status = 'running' AND lease_owner = ?5",
        )
        .bind(id)
        .bind(progress)
        .bind(json_array(wall_time_ms))
        .bind(now)
        .bind(owner)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    pub(super) async fn finish(
        &self,
        id: &str,
        done: &Done<'_>,
        now: i64,
    ) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET status = 'done', progress = 1, digest = ?2, size = ?3,
               media_type = ?4, wall_time_ms = ?5, error_estimate = ?6, error = NULL,
               updated_at = ?7, finished_at = ?7, lease_owner = NULL, lease_expires_at = NULL
             WHERE id = ?1",
        )
        .bind(id)
        .bind(done.digest)
        .bind(done.size)
        .bind(done.media_type)
        .bind(json_array(done.wall_time_ms))
        .bind(done.error_estimate)
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    pub(super) async fn record_done(
        &self,
        id: &str,
        spec: &str,
        done: &Done<'_>,
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
               finished_at = ?9, result_version = ?10, family = ?11,
               lease_owner = NULL, lease_expires_at = NULL
             WHERE jobs.status != 'done' OR jobs.result_version != ?10",
        )
        .bind(id)
        .bind(spec)
        .bind(done.wall_time_ms.len() as i64)
        .bind(done.digest)
        .bind(done.size)
        .bind(done.media_type)
        .bind(json_array(done.wall_time_ms))
        .bind(done.error_estimate)
        .bind(now)
        .bind(result_version())
        .bind(family_of_canonical(spec))
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    pub(super) async fn fail(
        &self,
        id: &str,
        owner: &str,
        error_json: &str,
        now: i64,
    ) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET status = 'failed', error = ?2, digest = NULL, size = NULL,
               media_type = NULL, updated_at = ?3, finished_at = ?3, lease_owner = NULL,
               lease_expires_at = NULL
             WHERE id = ?1 AND status = 'running' AND lease_owner = ?4",
        )
        .bind(id)
        .bind(error_json)
        .bind(now)
        .bind(owner)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    pub(super) async fn counts(&self) -> Result<Vec<(Status, i64)>, StorageError> {
        let rows = sqlx::query(SQL_COUNTS).fetch_all(&self.pool).await?;
        decode_counts(&rows)
    }
}

/// The queue of [`super::queue`]: one process's file, so a claim is a
/// single `UPDATE … WHERE id = (SELECT …) RETURNING`, atomic under SQLite's
/// one writer.
impl SqliteIndex {
    pub(super) async fn claim(
        &self,
        owner: &str,
        now: i64,
        lease_ms: i64,
    ) -> Result<Option<JobRow>, StorageError> {
        let sql = format!(
            "UPDATE jobs SET status = 'running', attempts = attempts + 1, progress = 0,
               wall_time_ms = '[]', lease_owner = ?1, lease_expires_at = ?2 + ?3, updated_at = ?2
             WHERE id = (SELECT id FROM jobs WHERE status = 'queued' AND result_version = ?4
                         ORDER BY created_at, id LIMIT 1)
             RETURNING {COLUMNS}"
        );
        let row = sqlx::query(sqlx::AssertSqlSafe(sql))
            .bind(owner)
            .bind(now)
            .bind(lease_ms)
            .bind(result_version())
            .fetch_optional(&self.pool)
            .await?;
        row.map(|r| decode_row(&r)).transpose()
    }

    pub(super) async fn renew(
        &self,
        id: &str,
        owner: &str,
        expires_at: i64,
    ) -> Result<bool, StorageError> {
        let r = sqlx::query(
            "UPDATE jobs SET lease_expires_at = ?3
             WHERE id = ?1 AND status = 'running' AND lease_owner = ?2",
        )
        .bind(id)
        .bind(owner)
        .bind(expires_at)
        .execute(&self.pool)
        .await?;
        Ok(r.rows_affected() == 1)
    }

    pub(super) async fn release(
        &self,
        id: &str,
        owner: &str,
        now: i64,
    ) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET status = 'queued', lease_owner = NULL, lease_expires_at = NULL,
               updated_at = ?3
             WHERE id = ?1 AND status = 'running' AND lease_owner = ?2",
        )
        .bind(id)
        .bind(owner)
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    pub(super) async fn release_expired(&self, now: i64) -> Result<Vec<String>, StorageError> {
        let rows = sqlx::query(
            "UPDATE jobs SET status = 'queued', lease_owner = NULL, lease_expires_at = NULL,
               updated_at = ?1
             WHERE status = 'running' AND (lease_expires_at IS NULL OR lease_expires_at < ?1)
             RETURNING id",
        )
        .bind(now)
        .fetch_all(&self.pool)
        .await?;
        decode_ids(&rows)
    }

    /// One instance's file: every running row was left by an earlier run
    /// of this service, whatever its instance id was.
    pub(super) async fn release_orphans(
        &self,
        _owner: &str,
        now: i64,
    ) -> Result<Vec<String>, StorageError> {
        let rows = sqlx::query(
            "UPDATE jobs SET status = 'queued', lease_owner = NULL, lease_expires_at = NULL,
               updated_at = ?1
             WHERE status = 'running'
             RETURNING id",
        )
        .bind(now)
        .fetch_all(&self.pool)
        .await?;
        decode_ids(&rows)
    }

    pub(super) async fn queue_depth(&self) -> Result<i64, StorageError> {
        let n: i64 = sqlx::query_scalar(
            "SELECT COUNT(*) FROM jobs WHERE status = 'queued' AND result_version = ?1",
        )
        .bind(result_version())
        .fetch_one(&self.pool)
        .await?;
        Ok(n)
    }

    pub(super) fn pool_connections(&self) -> (u32, u32) {
        let idle = self.pool.num_idle() as u32;
        (self.pool.size().saturating_sub(idle), idle)
    }
}

/// The cache-size methods of [`super::evict`].
impl SqliteIndex {
    pub(super) async fn touch(
        &self,
        id: &str,
        now: i64,
        every_ms: i64,
    ) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET last_served_at = ?2
             WHERE id = ?1 AND status = 'done'
               AND (last_served_at IS NULL OR last_served_at < ?2 - ?3)",
        )
        .bind(id)
        .bind(now)
        .bind(every_ms)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    pub(super) async fn cache_bytes(&self) -> Result<i64, StorageError> {
        let n: Option<i64> = sqlx::query_scalar(
            "SELECT CAST(SUM(size) AS BIGINT) FROM jobs WHERE status = 'done' AND digest IS NOT NULL",
        )
        .fetch_one(&self.pool)
        .await?;
        Ok(n.unwrap_or(0))
    }

    pub(super) async fn eviction_candidates(
        &self,
        cutoff: i64,
        limit: i64,
    ) -> Result<Vec<(String, String, i64)>, StorageError> {
        let rows = sqlx::query(
            "SELECT id, digest, size FROM jobs
             WHERE status = 'done' AND digest IS NOT NULL AND size IS NOT NULL
               AND COALESCE(last_served_at, finished_at, 0) < ?1
             ORDER BY COALESCE(last_served_at, finished_at, 0), id LIMIT ?2",
        )
        .bind(cutoff)
        .bind(limit)
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|r| Ok((r.try_get("id")?, r.try_get("digest")?, r.try_get("size")?)))
            .collect()
    }

    pub(super) async fn evict(
        &self,
        id: &str,
        digest: &str,
        cutoff: i64,
        error_json: &str,
        now: i64,
    ) -> Result<bool, StorageError> {
        let r = sqlx::query(
            "UPDATE jobs SET status = 'failed', error = ?4, digest = NULL, size = NULL,
               media_type = NULL, updated_at = ?5, finished_at = ?5
             WHERE id = ?1 AND status = 'done' AND digest = ?2
               AND COALESCE(last_served_at, finished_at, 0) < ?3",
        )
        .bind(id)
        .bind(digest)
        .bind(cutoff)
        .bind(error_json)
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(r.rows_affected() == 1)
    }

    pub(super) async fn digest_in_use(&self, digest: &str) -> Result<bool, StorageError> {
        let n: i64 =
            sqlx::query_scalar("SELECT COUNT(*) FROM jobs WHERE digest = ?1 AND status = 'done'")
                .bind(digest)
                .fetch_one(&self.pool)
                .await?;
        Ok(n > 0)
    }

    pub(super) async fn delete(&self, id: &str) -> Result<Option<JobRow>, StorageError> {
        let sql = format!(
            "DELETE FROM jobs WHERE id = ?1 AND status IN ('done', 'failed') RETURNING {COLUMNS}"
        );
        let row = sqlx::query(sqlx::AssertSqlSafe(sql))
            .bind(id)
            .fetch_optional(&self.pool)
            .await?;
        row.map(|r| decode_row(&r)).transpose()
    }
}
