//! The PostgreSQL backend of the index: the same `jobs` table and methods
//! as [`super::sqlite`], with migrations in `migrations/postgres/` (the
//! schema SQLite has after its own migrations, in PostgreSQL's types).
//! Several instances may open the same database; they do not yet share the
//! queue (each re-queues every unfinished row at start: docs/service.md,
//! "PostgreSQL").
//!
//! Differences from the SQLite SQL, all to give the same answers: `$N`
//! placeholders; `id` collates as `"C"` (byte order, as SQLite compares
//! text), so keyset pages and ties order alike; `NULLS LAST` where SQLite
//! sorts NULL below every value in a descending order.

use super::{
    COLUMNS, Done, JobRow, SQL_COUNTS, SQL_PING, SQL_WITHOUT_FAMILY, Status, decode_counts,
    decode_row, json_array,
};
use crate::plan::{family_of_canonical, result_version};
use crate::storage::StorageError;
use sqlx::postgres::{PgConnectOptions, PgPoolOptions};
use sqlx::{PgPool, Row};
use std::str::FromStr;
use std::time::Duration;

/// The index in a PostgreSQL database.
#[derive(Clone, Debug)]
pub struct PgIndex {
    pool: PgPool,
}

impl PgIndex {
    /// Connect and run the embedded migrations of `migrations/postgres/`.
    ///
    /// Several instances may start at once: sqlx's PostgreSQL migrator
    /// holds `pg_advisory_lock` (keyed on the database name) from before it
    /// reads `_sqlx_migrations` until it has applied the pending ones
    /// (`Migrator::run` with `locking`, on by default; sqlx-postgres 0.9,
    /// `migrate.rs`), so each migration is applied once and the others
    /// wait, then find it applied.
    pub(super) async fn open(database_url: &str) -> Result<Self, StorageError> {
        let options = PgConnectOptions::from_str(database_url)?;
        let pool = PgPoolOptions::new()
            .max_connections(4)
            .acquire_timeout(Duration::from_secs(10))
            .connect_with(options)
            .await?;
        sqlx::migrate!("migrations/postgres").run(&pool).await?;
        Ok(Self { pool })
    }

    /// The family backfill of [`super::sqlite::SqliteIndex`], so that
    /// [`super::Index::open`] means the same on both. This schema always had
    /// the column: only rows whose spec has no family (not a JSON object)
    /// are ever without one.
    pub(super) async fn backfill_families(&self) -> Result<(), StorageError> {
        let rows = sqlx::query(SQL_WITHOUT_FAMILY)
            .fetch_all(&self.pool)
            .await?;
        for r in rows {
            let (id, spec): (String, String) = (r.try_get("id")?, r.try_get("spec")?);
            sqlx::query("UPDATE jobs SET family = $2 WHERE id = $1")
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
             WHERE family = $1 AND status = 'done' AND result_version = $2 AND id != $3
             ORDER BY finished_at DESC NULLS LAST, id LIMIT $4"
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
        let sql = format!("SELECT {COLUMNS} FROM jobs WHERE id = $1");
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
            "SELECT {COLUMNS} FROM jobs WHERE result_version = $1
               AND (created_at < $2 OR (created_at = $2 AND id < $3) OR $4 = 0)
             ORDER BY created_at DESC, id DESC LIMIT $5"
        );
        let rows = sqlx::query(sqlx::AssertSqlSafe(sql))
            .bind(result_version())
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
            "SELECT {COLUMNS} FROM jobs WHERE status IN ('queued', 'running') AND result_version = $1
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
    ) -> Result<(), StorageError> {
        sqlx::query(
            "INSERT INTO jobs (id, status, spec, wavelengths, created_at, updated_at, result_version,
               family)
             VALUES ($1, 'queued', $2, $3, $4, $4, $5, $6)
             ON CONFLICT (id) DO UPDATE SET
               status = 'queued', progress = 0, wall_time_ms = '[]', error_estimate = NULL,
               error = NULL, digest = NULL, size = NULL, media_type = NULL,
               updated_at = $4, finished_at = NULL, result_version = $5, family = $6",
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

    pub(super) async fn requeue(&self, id: &str, now: i64) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET status = 'queued', updated_at = $2
             WHERE id = $1 AND status IN ('queued', 'running')",
        )
        .bind(id)
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    pub(super) async fn start(&self, id: &str, now: i64) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET status = 'running', attempts = attempts + 1, progress = 0,
               wall_time_ms = '[]', updated_at = $2
             WHERE id = $1",
        )
        .bind(id)
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    pub(super) async fn progress(
        &self,
        id: &str,
        progress: f64,
        wall_time_ms: &[f64],
        now: i64,
    ) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET progress = $2, wall_time_ms = $3, updated_at = $4
             WHERE id = $1 AND status = 'running'",
        )
        .bind(id)
        .bind(progress)
        .bind(json_array(wall_time_ms))
        .bind(now)
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
            "UPDATE jobs SET status = 'done', progress = 1, digest = $2, size = $3,
               media_type = $4, wall_time_ms = $5, error_estimate = $6, error = NULL,
               updated_at = $7, finished_at = $7
             WHERE id = $1",
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
             VALUES ($1, 'done', $2, $3, 1, $4, $5, $6, $7, $8, $9, $9, $9, $10, $11)
             ON CONFLICT (id) DO UPDATE SET
               status = 'done', progress = 1, digest = $4, size = $5, media_type = $6,
               wall_time_ms = $7, error_estimate = $8, error = NULL, updated_at = $9,
               finished_at = $9, result_version = $10, family = $11
             WHERE jobs.status != 'done' OR jobs.result_version != $10",
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
        error_json: &str,
        now: i64,
    ) -> Result<(), StorageError> {
        sqlx::query(
            "UPDATE jobs SET status = 'failed', error = $2, digest = NULL, size = NULL,
               media_type = NULL, updated_at = $3, finished_at = $3
             WHERE id = $1",
        )
        .bind(id)
        .bind(error_json)
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    pub(super) async fn counts(&self) -> Result<Vec<(Status, i64)>, StorageError> {
        let rows = sqlx::query(SQL_COUNTS).fetch_all(&self.pool).await?;
        decode_counts(&rows)
    }
}
