//! The job/result index (docs/service.md, "Storage"): one row per spec id,
//! kept by one of two backends behind the one type [`Index`], chosen by the
//! URL scheme at [`Index::open`]:
//!
//! * [`sqlite`] (`sqlite:`), the single-node default: a file in the data
//!   directory that must not live on a network filesystem;
//! * [`postgres`] (`postgres://`, `postgresql://`), a server that several
//!   instances can reach.
//!
//! The jobs and http layers see only [`Index`]; every method means the same
//! on both backends (the tests below run each on both). Short statements
//! only: every state change is a single `UPDATE` (or upsert), so a crash
//! leaves each row in a state any instance understands. The rows are the
//! queue that all instances on one database share ([`queue`]: claims,
//! leases, their expiry).
//!
//! Each backend writes its SQL plainly (`?N` against `$N` placeholders,
//! each its own column types); what is the same text on both lives here.

pub mod postgres;
pub mod sqlite;

use super::StorageError;
use crate::plan::result_version;
use sqlx::{ColumnIndex, Decode, Row, Type};
use std::str::FromStr;

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
    /// The instance (`--instance-id`) holding the lease of a running row.
    pub worker: Option<String>,
    /// When that lease lapses unless renewed (ms since the epoch).
    pub lease_expires_at: Option<i64>,
}

impl JobRow {
    /// Made by the running version; rows of older versions are never served
    /// nor solved (docs/service.md, "Ids and versions").
    pub fn is_current(&self) -> bool {
        self.result_version == result_version()
    }
}

/// Which database keeps the index.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// `sqlite:` URLs.
    Sqlite,
    /// `postgres://` and `postgresql://` URLs.
    Postgres,
}

impl Backend {
    /// The backend a database URL names by its scheme, if any.
    pub fn of_url(database_url: &str) -> Option<Backend> {
        if database_url.starts_with("sqlite:") {
            Some(Backend::Sqlite)
        } else if database_url.starts_with("postgres://")
            || database_url.starts_with("postgresql://")
        {
            Some(Backend::Postgres)
        } else {
            None
        }
    }
}

/// The job/result index, in whichever database the URL named.
#[derive(Clone, Debug)]
pub enum Index {
    /// A SQLite file.
    Sqlite(sqlite::SqliteIndex),
    /// A PostgreSQL database.
    Postgres(postgres::PgIndex),
}

/// `$e` with `$ix` bound to the backend of `$index`.
macro_rules! on_backend {
    ($index:expr, $ix:ident => $e:expr) => {
        match $index {
            Index::Sqlite($ix) => $e,
            Index::Postgres($ix) => $e,
        }
    };
}

// After the macro: the queue and eviction methods dispatch with it too.
pub mod evict;
pub mod previews;
pub mod queue;

impl Index {
    /// Connect to the database `database_url` names (`sqlite:`, creating
    /// the file if needed; or `postgres://` / `postgresql://`), run that
    /// backend's embedded migrations and give rows without a family theirs
    /// (migrations/0003).
    pub async fn open(database_url: &str) -> Result<Self, StorageError> {
        let index = match Backend::of_url(database_url) {
            Some(Backend::Sqlite) => Index::Sqlite(sqlite::SqliteIndex::open(database_url).await?),
            Some(Backend::Postgres) => {
                Index::Postgres(postgres::PgIndex::open(database_url).await?)
            }
            None => return Err(StorageError::UnsupportedUrl(scheme_of(database_url))),
        };
        on_backend!(&index, ix => ix.backfill_families().await)?;
        Ok(index)
    }

    /// Which database this is.
    pub fn backend(&self) -> Backend {
        match self {
            Index::Sqlite(_) => Backend::Sqlite,
            Index::Postgres(_) => Backend::Postgres,
        }
    }

    /// Close the pool (SQLite: checkpoints the WAL).
    pub async fn close(&self) {
        on_backend!(self, ix => ix.close().await)
    }

    /// Is the database answering?
    pub async fn ping(&self) -> Result<(), StorageError> {
        on_backend!(self, ix => ix.ping().await)
    }

    /// The row of an id.
    pub async fn get(&self, id: &str) -> Result<Option<JobRow>, StorageError> {
        on_backend!(self, ix => ix.get(id).await)
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
        on_backend!(self, ix => ix.list(after, limit).await)
    }

    /// Queued and running rows of the current version, oldest first (the
    /// start-up scan; rows of older versions are never solved).
    pub async fn unfinished(&self) -> Result<Vec<JobRow>, StorageError> {
        on_backend!(self, ix => ix.unfinished().await)
    }

    /// Insert a queued row, or reset a final row (a result whose blob went
    /// missing, a retried failure) or a row of another version to queued.
    /// Keeps `created_at` and `attempts`. Idempotent across instances: a
    /// queued or running row of this version is left as it is (the
    /// submission joins it). `true` when this call queued the row.
    pub async fn enqueue(
        &self,
        id: &str,
        spec: &str,
        wavelengths: i64,
        now: i64,
    ) -> Result<bool, StorageError> {
        on_backend!(self, ix => ix.enqueue(id, spec, wavelengths, now).await)
    }

    /// A wavelength finished (written only while `owner` holds the lease).
    pub async fn progress(
        &self,
        id: &str,
        owner: &str,
        progress: f64,
        wall_time_ms: &[f64],
        now: i64,
    ) -> Result<(), StorageError> {
        on_backend!(self, ix => ix.progress(id, owner, progress, wall_time_ms, now).await)
    }

    /// The result blob is stored: the row is a cached result from now on
    /// (whoever holds the lease: the bytes of an id are the same whoever
    /// solved them), and its lease is cleared.
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
        let done = Done {
            digest,
            size,
            media_type,
            wall_time_ms,
            error_estimate,
        };
        on_backend!(self, ix => ix.finish(id, &done, now).await)
    }

    /// Record a result computed elsewhere (a per-wavelength part solved by
    /// a multi-wavelength job, or a request assembled from cached parts) as
    /// a done row: inserted, or an existing row that is not done (or of
    /// another version) made done. A done row of the current version is
    /// left as it is (same id, same bytes).
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
        let done = Done {
            digest,
            size,
            media_type,
            wall_time_ms,
            error_estimate,
        };
        on_backend!(self, ix => ix.record_done(id, spec, &done, now).await)
    }

    /// The solve by `owner` failed with this JSON problem. A row whose
    /// lease another instance holds now (this one's lapsed) is left to it.
    pub async fn fail(
        &self,
        id: &str,
        owner: &str,
        error_json: &str,
        now: i64,
    ) -> Result<(), StorageError> {
        on_backend!(self, ix => ix.fail(id, owner, error_json, now).await)
    }

    /// Number of rows per state (all states, zeros included).
    pub async fn counts(&self) -> Result<Vec<(Status, i64)>, StorageError> {
        on_backend!(self, ix => ix.counts().await)
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
        on_backend!(self, ix => ix.done_in_family(family, except, limit).await)
    }
}

/// What a done row records of its result.
pub(crate) struct Done<'a> {
    /// SHA-256 of the result blob.
    pub digest: &'a str,
    /// Bytes of the result blob.
    pub size: i64,
    /// Media type of the result blob.
    pub media_type: &'a str,
    /// Wall time per wavelength (ms).
    pub wall_time_ms: &'a [f64],
    /// The result's error estimate, if it has one.
    pub error_estimate: Option<f64>,
}

/// The columns of [`JobRow`], in its order (`SELECT {COLUMNS} FROM jobs`).
const COLUMNS: &str = "id, status, spec, wavelengths, progress, wall_time_ms, error_estimate, \
     error, digest, size, media_type, attempts, created_at, updated_at, finished_at, result_version, \
     lease_owner, lease_expires_at";

/// Rows written before the `family` column existed (the family backfill).
const SQL_WITHOUT_FAMILY: &str = "SELECT id, spec FROM jobs WHERE family IS NULL";

/// Rows per state (`counts`).
const SQL_COUNTS: &str = "SELECT status, COUNT(*) AS n FROM jobs GROUP BY status";

/// The liveness probe (`ping`).
const SQL_PING: &str = "SELECT 1";

/// A JSON array of finite numbers (the `wall_time_ms` column).
fn json_array(v: &[f64]) -> String {
    serde_json::to_string(v).expect("finite numbers")
}

/// [`JobRow`] from a row of `SELECT {COLUMNS}`, in either backend (both
/// store integers as 64-bit, reals as doubles and the rest as text).
fn decode_row<R: Row>(r: &R) -> Result<JobRow, StorageError>
where
    for<'n> &'n str: ColumnIndex<R>,
    for<'v> String: Decode<'v, R::Database> + Type<R::Database>,
    for<'v> i64: Decode<'v, R::Database> + Type<R::Database>,
    for<'v> f64: Decode<'v, R::Database> + Type<R::Database>,
{
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
        worker: r.try_get("lease_owner")?,
        lease_expires_at: r.try_get("lease_expires_at")?,
    })
}

/// [`Status`] counts from rows of [`SQL_COUNTS`], every state present.
fn decode_counts<R: Row>(rows: &[R]) -> Result<Vec<(Status, i64)>, StorageError>
where
    for<'n> &'n str: ColumnIndex<R>,
    for<'v> String: Decode<'v, R::Database> + Type<R::Database>,
    for<'v> i64: Decode<'v, R::Database> + Type<R::Database>,
{
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

/// The `id` column of each row (`UPDATE … RETURNING id`).
fn decode_ids<R: Row>(rows: &[R]) -> Result<Vec<String>, StorageError>
where
    for<'n> &'n str: ColumnIndex<R>,
    for<'v> String: Decode<'v, R::Database> + Type<R::Database>,
{
    rows.iter()
        .map(|r| r.try_get("id").map_err(Into::into))
        .collect()
}

/// The scheme of a URL, for an error message that must not echo a password.
fn scheme_of(url: &str) -> String {
    url.split_once(':')
        .map_or_else(|| "(none)".to_string(), |(s, _)| format!("{s}:"))
}

#[cfg(test)]
mod tests {
    //! Every test runs on SQLite, and on PostgreSQL when
    //! `POLBRDF_TEST_DATABASE_URL` names a database (each test in a schema of
    //! its own, dropped at the end). Unset, the PostgreSQL half prints
    //! SKIPPED and passes, except under `CI=true`, where it fails.
    use super::*;
    use std::io::Write;
    use std::path::PathBuf;

    /// A scratch database (a SQLite file or a PostgreSQL schema), removed
    /// by [`Scratch::remove`].
    pub(super) struct Scratch {
        pub(super) url: String,
        cleanup: Cleanup,
    }

    enum Cleanup {
        Dir(PathBuf),
        Schema(sqlx::PgPool, String),
    }

    impl Scratch {
        fn sqlite(test: &str) -> Scratch {
            let dir = std::env::temp_dir().join(format!(
                "polbrdf-index-{test}-{}-{}",
                std::process::id(),
                crate::storage::now_ms()
            ));
            std::fs::create_dir_all(&dir).unwrap();
            Scratch {
                url: format!("sqlite://{}", dir.join("i.sqlite").display()),
                cleanup: Cleanup::Dir(dir),
            }
        }

        /// A fresh schema in the test database, and the URL whose
        /// connections use it (`search_path`); `None` when no test
        /// database is named.
        pub(super) async fn postgres(test: &str) -> Option<Scratch> {
            let base = postgres_test_url(test)?;
            let admin = sqlx::PgPool::connect(&base).await.unwrap();
            let nanos = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .as_nanos();
            let schema = format!("polbrdf_test_{test}_{}_{nanos}", std::process::id());
            sqlx::query(sqlx::AssertSqlSafe(format!("CREATE SCHEMA {schema}")))
                .execute(&admin)
                .await
                .unwrap();
            let sep = if base.contains('?') { '&' } else { '?' };
            Some(Scratch {
                url: format!("{base}{sep}options=-c%20search_path%3D{schema}"),
                cleanup: Cleanup::Schema(admin, schema),
            })
        }

        pub(super) async fn remove(self) {
            match self.cleanup {
                Cleanup::Dir(d) => std::fs::remove_dir_all(d).unwrap(),
                Cleanup::Schema(admin, schema) => {
                    sqlx::query(sqlx::AssertSqlSafe(format!("DROP SCHEMA {schema} CASCADE")))
                        .execute(&admin)
                        .await
                        .unwrap();
                    admin.close().await;
                }
            }
        }
    }

    /// `POLBRDF_TEST_DATABASE_URL`, or `None` after a loud SKIPPED line;
    /// unset under `CI=true` is a failure (CI starts a PostgreSQL).
    fn postgres_test_url(test: &str) -> Option<String> {
        match std::env::var("POLBRDF_TEST_DATABASE_URL") {
            Ok(u) if !u.is_empty() => Some(u),
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
                    "SKIPPED: storage::index::tests::{test} on PostgreSQL: \
                     set POLBRDF_TEST_DATABASE_URL=postgres://USER@HOST:PORT/DB to run it"
                );
                None
            }
        }
    }

    /// `check` on a fresh SQLite index, then on a fresh PostgreSQL one.
    pub(super) async fn on_both<F, Fut>(test: &str, check: F)
    where
        F: Fn(String) -> Fut,
        Fut: std::future::Future<Output = ()>,
    {
        let s = Scratch::sqlite(test);
        check(s.url.clone()).await;
        s.remove().await;
        if let Some(s) = Scratch::postgres(test).await {
            assert_eq!(Backend::of_url(&s.url), Some(Backend::Postgres));
            check(s.url.clone()).await;
            s.remove().await;
        }
    }

    /// Queued → running → done → re-queued → failed, and a reopen.
    async fn row_lifecycle(url: String) {
        let ix = Index::open(&url).await.unwrap();
        ix.ping().await.unwrap();
        let id = "a".repeat(64);
        assert_eq!(ix.get(&id).await.unwrap(), None);
        ix.enqueue(&id, "{}", 2, 10).await.unwrap();
        let r = ix.get(&id).await.unwrap().unwrap();
        assert_eq!(
            (r.status, r.attempts, r.created_at),
            (Status::Queued, 0, 10)
        );
        assert!(r.is_current());
        let claimed = ix.claim("A", 11, 1000).await.unwrap().unwrap();
        assert_eq!(claimed.id, id);
        ix.progress(&id, "A", 0.5, &[1.5], 12).await.unwrap();
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
        assert_eq!(r.wall_time_ms, vec![1.5, 2.5]);
        assert!(ix.unfinished().await.unwrap().is_empty());
        // A done row is not released (only running rows are).
        assert!(ix.release_expired(i64::MAX).await.unwrap().is_empty());
        assert_eq!(ix.get(&id).await.unwrap().unwrap().status, Status::Done);
        // Enqueue again resets the result but keeps created_at and attempts.
        ix.enqueue(&id, "{}", 2, 15).await.unwrap();
        let r = ix.get(&id).await.unwrap().unwrap();
        assert_eq!(
            (r.status, r.digest, r.created_at, r.attempts),
            (Status::Queued, None, 10, 1)
        );
        ix.claim("A", 16, 1000).await.unwrap().unwrap();
        ix.fail(&id, "A", r#"{"type":"x"}"#, 16).await.unwrap();
        let counts = ix.counts().await.unwrap();
        assert_eq!(
            counts,
            vec![
                (Status::Queued, 0),
                (Status::Running, 0),
                (Status::Done, 0),
                (Status::Failed, 1)
            ]
        );
        ix.close().await;
        // Reopening runs the (already applied) migrations again: a no-op.
        let ix = Index::open(&url).await.unwrap();
        let r = ix.get(&id).await.unwrap().unwrap();
        assert_eq!(
            (r.status, r.error.as_deref()),
            (Status::Failed, Some(r#"{"type":"x"}"#))
        );
        ix.close().await;
    }

    #[tokio::test]
    async fn row_lifecycle_on_both() {
        on_both("row_lifecycle", row_lifecycle).await;
    }

    /// Keyset pages, `record_done` over each state, and `done_in_family`'s
    /// filter and order: the queries whose SQL differs most between the
    /// backends.
    async fn listing_and_families(url: String) {
        let ix = Index::open(&url).await.unwrap();
        let id = |c: char| c.to_string().repeat(64);
        // Two rows share created_at = 20: the id breaks the tie.
        for (c, at) in [('1', 10), ('2', 20), ('b', 20), ('4', 30)] {
            ix.enqueue(&id(c), "{}", 1, at).await.unwrap();
        }
        let ids = |rows: Vec<JobRow>| rows.into_iter().map(|r| r.id).collect::<Vec<_>>();
        let page1 = ids(ix.list(None, 2).await.unwrap());
        assert_eq!(page1, [id('4'), id('b')]);
        let page2 = ids(ix.list(Some((20, &id('b'))), 2).await.unwrap());
        assert_eq!(page2, [id('2'), id('1')]);
        assert!(ix.list(Some((10, &id('1'))), 2).await.unwrap().is_empty());
        assert_eq!(
            ids(ix.unfinished().await.unwrap()),
            [id('1'), id('2'), id('b'), id('4')]
        );

        // record_done makes a queued row done, inserts a new one, and
        // leaves a done row of the current version as it is.
        let spec = r#"{"layers":[]}"#;
        ix.record_done(&id('2'), spec, "d2", 5, "x/y", &[1.0], None, 40)
            .await
            .unwrap();
        ix.record_done(&id('c'), spec, "dc", 6, "x/y", &[2.0, 3.0], Some(0.5), 50)
            .await
            .unwrap();
        ix.record_done(&id('c'), spec, "other", 7, "x/y", &[9.0], None, 60)
            .await
            .unwrap();
        let c = ix.get(&id('c')).await.unwrap().unwrap();
        assert_eq!(
            (c.status, c.digest.as_deref(), c.size, c.wavelengths),
            (Status::Done, Some("dc"), Some(6), 2)
        );
        assert_eq!(
            (c.created_at, c.finished_at, c.progress),
            (50, Some(50), 1.0)
        );
        let two = ix.get(&id('2')).await.unwrap().unwrap();
        assert_eq!((two.status, two.created_at), (Status::Done, 20));

        // Both done rows are of the spec's family; newest first, `except`
        // left out; rows that are not done are not results.
        let family = crate::plan::family_of_canonical(spec).unwrap();
        let fam = ids(ix.done_in_family(&family, "", 10).await.unwrap());
        assert_eq!(fam, [id('c'), id('2')]);
        let fam = ids(ix.done_in_family(&family, &id('c'), 10).await.unwrap());
        assert_eq!(fam, [id('2')]);
        assert_eq!(ix.done_in_family(&family, "", 1).await.unwrap().len(), 1);
        assert!(ix.done_in_family("none", "", 10).await.unwrap().is_empty());
        ix.enqueue(&id('c'), spec, 2, 70).await.unwrap();
        let fam = ids(ix.done_in_family(&family, "", 10).await.unwrap());
        assert_eq!(fam, [id('2')]);

        let counts = ix.counts().await.unwrap();
        assert!(counts.contains(&(Status::Queued, 4)) && counts.contains(&(Status::Done, 1)));
        ix.close().await;
    }

    #[tokio::test]
    async fn listing_and_families_on_both() {
        on_both("listing_and_families", listing_and_families).await;
    }

    /// Instances starting at once on one PostgreSQL database: sqlx's
    /// advisory lock makes one apply the migrations, the others find them
    /// applied (SQLite is one process's file: not tried there).
    #[tokio::test]
    async fn postgres_opens_at_once_migrate_once() {
        let Some(s) = Scratch::postgres("opens_at_once").await else {
            return;
        };
        let open = || Index::open(&s.url);
        let (a, b, c, d) = tokio::join!(open(), open(), open(), open());
        let indexes = [a, b, c, d].map(Result::unwrap);
        for ix in &indexes {
            assert_eq!(ix.backend(), Backend::Postgres);
            ix.ping().await.unwrap();
        }
        let Cleanup::Schema(admin, schema) = &s.cleanup else {
            unreachable!("a PostgreSQL scratch is a schema")
        };
        let applied: i64 = sqlx::query_scalar(sqlx::AssertSqlSafe(format!(
            "SELECT COUNT(*) FROM {schema}._sqlx_migrations WHERE success"
        )))
        .fetch_one(admin)
        .await
        .unwrap();
        let embedded = sqlx::migrate!("migrations/postgres").iter().count();
        assert_eq!(applied, embedded as i64);
        for ix in indexes {
            ix.close().await;
        }
        s.remove().await;
    }

    #[test]
    fn backends_by_scheme() {
        assert_eq!(Backend::of_url("sqlite://x.db"), Some(Backend::Sqlite));
        assert_eq!(Backend::of_url("sqlite::memory:"), Some(Backend::Sqlite));
        assert_eq!(
            Backend::of_url("postgres://u@h/db"),
            Some(Backend::Postgres)
        );
        assert_eq!(
            Backend::of_url("postgresql://h/db"),
            Some(Backend::Postgres)
        );
        assert_eq!(Backend::of_url("mysql://u:pw@h/db"), None);
        assert_eq!(scheme_of("mysql://u:pw@h/db"), "mysql:");
    }

    #[tokio::test]
    async fn an_unknown_scheme_is_refused_without_its_password() {
        let e = Index::open("mysql://u:hunter2@h/db").await.unwrap_err();
        let text = e.to_string();
        assert!(
            matches!(e, StorageError::UnsupportedUrl(_)) && !text.contains("hunter2"),
            "{text}"
        );
    }
}
