//! A scratch PostgreSQL schema for the service tests that run on a
//! PostgreSQL index: in the database `POLBRDF_TEST_DATABASE_URL` names, a
//! schema of the test's own (dropped at the end), reached through
//! `search_path` in the URL handed to `polbrdf serve --database-url`.
//! Without the variable the test prints SKIPPED and passes; under `CI=true`
//! it fails (.ci/run starts a PostgreSQL).

use std::io::Write;
use std::time::{SystemTime, UNIX_EPOCH};

/// A schema of one test.
pub struct PgSchema {
    /// The URL of the test database with the schema as its `search_path`.
    pub url: String,
    admin: sqlx::PgPool,
    name: String,
}

impl PgSchema {
    /// A fresh schema, or `None` (after a loud SKIPPED line) when no test
    /// database is named.
    pub async fn create(test: &str) -> Option<PgSchema> {
        let base = match std::env::var("POLBRDF_TEST_DATABASE_URL") {
            Ok(u) if !u.is_empty() => u,
            _ if std::env::var("CI").as_deref() == Ok("true") => {
                panic!(
                    "{test}: CI=true but POLBRDF_TEST_DATABASE_URL is unset (.ci/run starts one)"
                )
            }
            _ => {
                // To stderr itself, not eprintln!: the test harness
                // captures the macros' output of a passing test.
                let _ = writeln!(
                    std::io::stderr(),
                    "SKIPPED: {test}: set POLBRDF_TEST_DATABASE_URL=postgres://USER@HOST:PORT/DB \
                     to run it on PostgreSQL"
                );
                return None;
            }
        };
        let admin = sqlx::PgPool::connect(&base)
            .await
            .unwrap_or_else(|e| panic!("POLBRDF_TEST_DATABASE_URL: {e}"));
        let nanos = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap()
            .as_nanos();
        let name = format!("polbrdf_test_{test}_{}_{nanos}", std::process::id());
        sqlx::query(sqlx::AssertSqlSafe(format!("CREATE SCHEMA {name}")))
            .execute(&admin)
            .await
            .unwrap();
        let sep = if base.contains('?') { '&' } else { '?' };
        Some(PgSchema {
            url: format!("{base}{sep}options=-c%20search_path%3D{name}"),
            admin,
            name,
        })
    }

    /// The `status` column of a row, read directly from the schema.
    pub async fn status_of(&self, id: &str) -> Option<String> {
        sqlx::query_scalar(sqlx::AssertSqlSafe(format!(
            "SELECT status FROM {}.jobs WHERE id = $1",
            self.name
        )))
        .bind(id)
        .fetch_optional(&self.admin)
        .await
        .unwrap()
    }

    /// The `attempts` column of a row (claims so far).
    pub async fn attempts_of(&self, id: &str) -> Option<i64> {
        sqlx::query_scalar(sqlx::AssertSqlSafe(format!(
            "SELECT attempts FROM {}.jobs WHERE id = $1",
            self.name
        )))
        .bind(id)
        .fetch_optional(&self.admin)
        .await
        .unwrap()
    }

    /// Rows in the schema's `jobs` table.
    pub async fn row_count(&self) -> i64 {
        sqlx::query_scalar(sqlx::AssertSqlSafe(format!(
            "SELECT COUNT(*) FROM {}.jobs",
            self.name
        )))
        .fetch_one(&self.admin)
        .await
        .unwrap()
    }

    /// Drop the schema and everything in it.
    pub async fn drop_schema(self) {
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "DROP SCHEMA {} CASCADE",
            self.name
        )))
        .execute(&self.admin)
        .await
        .unwrap();
        self.admin.close().await;
    }
}
