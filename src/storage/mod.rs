//! The service's storage (docs/service.md, "Storage"): an index of jobs and
//! results in SQLite or PostgreSQL ([`index`]) and a content-addressed blob
//! store, a directory or an S3-compatible bucket ([`blobs`]).
//!
//! ```text
//! <data-dir>/
//!   polbrdf.sqlite         the index (default --database-url), WAL mode
//!   blobs/ab/cdef…         result bytes, named by the SHA-256 of their bytes
//!   blobs/tmp/             partial writes, renamed into place when complete
//! ```
//!
//! The index row of a spec id points at its result blob by digest; a blob is
//! verified against its name on every read and a missing or corrupt blob is
//! treated as absent (the job is solved again), never served.

pub mod blobs;
pub mod index;

pub use blobs::{BlobLocation, BlobStore};
pub use index::{Backend, Index, JobRow, Status};

/// Storage errors (logged in full; clients see a generic 500).
#[derive(Debug, thiserror::Error)]
pub enum StorageError {
    /// The index database (SQLite or PostgreSQL) failed.
    #[error("database: {0}")]
    Database(#[from] sqlx::Error),
    /// A database URL of a scheme no backend serves.
    #[error("database URL of scheme '{0}': give sqlite:PATH, postgres://… or postgresql://…")]
    UnsupportedUrl(String),
    /// Embedded migrations could not be applied.
    #[error("database migration: {0}")]
    Migrate(#[from] sqlx::migrate::MigrateError),
    /// A blob could not be written or read.
    #[error("blob store: {0}")]
    Io(#[from] std::io::Error),
    /// A row holds a value the code does not know.
    #[error("database row: {0}")]
    Corrupt(String),
}

/// Milliseconds since the Unix epoch.
pub fn now_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as i64)
}

/// RFC 3339 UTC timestamp (`2026-01-02T03:04:05.678Z`) of a time in ms
/// since the Unix epoch (proleptic Gregorian; Hinnant's `civil_from_days`).
pub fn rfc3339(ms: i64) -> String {
    let secs = ms.div_euclid(1000);
    let milli = ms.rem_euclid(1000);
    let days = secs.div_euclid(86_400);
    let sod = secs.rem_euclid(86_400);
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{milli:03}Z",
        sod / 3600,
        sod % 3600 / 60,
        sod % 60
    )
}

#[cfg(test)]
mod tests {
    use super::rfc3339;

    #[test]
    fn rfc3339_known_instants() {
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00.000Z");
        assert_eq!(rfc3339(951_782_400_000), "2000-02-29T00:00:00.000Z");
        assert_eq!(rfc3339(1_767_323_045_678), "2026-01-02T03:04:05.678Z");
        assert_eq!(rfc3339(-1), "1969-12-31T23:59:59.999Z");
    }
}
