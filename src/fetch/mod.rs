//! Tables of a running service on a render node: a verified download
//! ([`download`]) and a read-through cache directory ([`fetch`]) shared by
//! every process of the node (docs/deploy.md, "Render nodes"). Used by
//! `polbrdf fetch` and by every command that takes a service URL as its
//! table (`eval`, `export`, `render`, …).
//!
//! What a cached table is trusted for: results are content-addressed and
//! immutable (docs/service.md, "Ids and versions"), so a table stored
//! under its id stays the right one. A download is accepted only when the
//! SHA-256 of its bytes equals the service's digest (the `ETag`, else
//! `result.digest` of the resource) and the bytes parse as a table
//! (docs/table-format.md: magic, version and the file's own SHA-256); a
//! cached file is parsed, and so checked, at every use, and one that fails
//! is downloaded again. Revalidation (`If-None-Match` with the SHA-256 of
//! the cached file) is therefore optional: asked for, a 304 keeps the file,
//! a 200 replaces it after the same verification, and an unreachable or
//! failing service leaves the cached file in use with a warning.

pub mod cache;
pub mod remote;
pub mod url;

pub use url::ResultUrl;

use crate::brdf::{Table, format};
use crate::digest::sha256_hex;
use cache::CachePaths;
use remote::{Remote, TableAnswer};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Why a table could not be fetched.
#[derive(Debug, thiserror::Error)]
pub enum FetchError {
    /// Not a result URL of the service.
    #[error("{url}: {why}")]
    BadUrl { url: String, why: String },
    /// A file of the cache directory.
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    /// No answer from the service (and nothing cached to fall back on).
    #[error("{url}: the service is unreachable: {message}")]
    Unreachable { url: String, message: String },
    /// The job has no result yet (409 not-ready, status queued/running).
    #[error("{url}: the result is not ready yet ({detail}); try again later or pass --wait")]
    NotReady { url: String, detail: String },
    /// `--wait` ran out.
    #[error("{url}: the result is still not ready after {waited_s} s")]
    WaitTimedOut { url: String, waited_s: u64 },
    /// The job failed: there will be no table.
    #[error("{url}: the job failed: {detail}")]
    JobFailed { url: String, detail: String },
    /// Any other HTTP answer.
    #[error("{url}: HTTP {status}: {detail}")]
    Status {
        url: String,
        status: u16,
        detail: String,
    },
    /// The bytes are not what the service said they are.
    #[error("{url}: digest mismatch: the bytes hash to {actual}, the service says {expected}")]
    Digest {
        url: String,
        expected: String,
        actual: String,
    },
    /// The service named no digest to check the bytes against.
    #[error("{url}: no ETag and no result.digest to verify the table against")]
    NoDigest { url: String },
    /// The bytes are not a table.
    #[error("{url}: {message}")]
    Table { url: String, message: String },
}

/// How [`fetch`] treats the cache and a job that is not done.
#[derive(Clone, Debug, Default)]
pub struct FetchOptions {
    /// Ask the service about a cached table (`If-None-Match`) instead of
    /// using it as it is.
    pub revalidate: bool,
    /// Poll a queued or running job this long for its result instead of
    /// failing at once.
    pub wait: Option<Duration>,
    /// Bearer token for a service that requires one for reads
    /// (`--token-reads`).
    pub token: Option<String>,
}

/// What [`fetch`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Not cached (or the cached file was invalid): downloaded, verified, stored.
    Miss,
    /// Served from the cache without asking the service (also when a
    /// revalidation was asked for and failed: see `revalidation_error`).
    Hit,
    /// Revalidated: the service confirmed the cached bytes.
    Revalidated,
    /// Revalidated: the service sent other bytes, verified and stored.
    Replaced,
}

impl Outcome {
    /// Its name in the CLI's JSON (`"cache"`).
    pub fn name(self) -> &'static str {
        match self {
            Outcome::Miss => "miss",
            Outcome::Hit => "hit",
            Outcome::Revalidated => "revalidated",
            Outcome::Replaced => "replaced",
        }
    }
}

/// A table from the cache.
#[derive(Debug)]
pub struct Fetched {
    /// The result it is.
    pub url: ResultUrl,
    /// `DIR/<id>.pbrdf`.
    pub path: PathBuf,
    /// Hit, miss, …
    pub outcome: Outcome,
    /// Size of the file (bytes).
    pub size_bytes: usize,
    /// SHA-256 (hex) of the file: the result's digest.
    pub sha256: String,
    /// The parsed table.
    pub table: Table,
    /// Why a cached file was thrown away and downloaded again.
    pub discarded: Option<String>,
    /// Why a revalidation that was asked for did not happen (the cached
    /// file was used).
    pub revalidation_error: Option<String>,
}

/// Check bytes against the digest the service named and parse them.
pub fn verify(url: &str, bytes: &[u8], expected: &str) -> Result<Table, FetchError> {
    let actual = sha256_hex(bytes);
    if actual != expected {
        return Err(FetchError::Digest {
            url: url.to_string(),
            expected: expected.to_string(),
            actual,
        });
    }
    format::from_bytes(bytes).map_err(|e| FetchError::Table {
        url: url.to_string(),
        message: e.to_string(),
    })
}

/// The digest to verify a 200 answer against: its `ETag`, else the
/// resource's `result.digest`.
fn expected_digest(
    remote: &Remote,
    r: &ResultUrl,
    etag: Option<String>,
) -> Result<String, FetchError> {
    if let Some(e) = etag.filter(|e| !e.is_empty()) {
        return Ok(e);
    }
    let (code, v) = remote.get_resource(&r.resource())?;
    match v["result"]["digest"].as_str() {
        Some(d) if code == 200 => Ok(d.to_string()),
        _ => Err(FetchError::NoDigest { url: r.table() }),
    }
}

/// Download and verify a table without a cache. `source` is a service URL
/// in either form; the bytes are checked against the `ETag` when the
/// answer has one (a URL that is not of the `…/v1/brdfs/ID` form is read
/// as it is, as `polbrdf eval` always did). `token` is sent as the bearer
/// token (a service started with `--token-reads` wants it).
pub fn download(source: &str, token: Option<&str>) -> Result<Table, FetchError> {
    let remote = Remote::new(token);
    let (url, parsed) = match ResultUrl::parse(source) {
        Ok(r) => (r.table(), Some(r)),
        Err(_) => {
            let base = source.trim_end_matches('/');
            let url = if base.ends_with("/table") {
                base.to_string()
            } else {
                format!("{base}/table")
            };
            (url, None)
        }
    };
    match remote.get_table(&url, None)? {
        TableAnswer::Body { bytes, etag } => {
            let expected = match (etag, &parsed) {
                (Some(e), _) => e,
                (None, Some(r)) => expected_digest(&remote, r, None)?,
                (None, None) => sha256_hex(&bytes),
            };
            verify(&url, &bytes, &expected)
        }
        TableAnswer::NotReady { detail } => Err(FetchError::NotReady { url, detail }),
        other => Err(unexpected(&url, other)),
    }
}

/// The error of an answer that is neither a table nor "not ready".
fn unexpected(url: &str, a: TableAnswer) -> FetchError {
    match a {
        TableAnswer::Status {
            status: 409,
            problem: Some(p),
            detail,
        } if p == "job-failed" => FetchError::JobFailed {
            url: url.to_string(),
            detail,
        },
        TableAnswer::Status { status, detail, .. } => FetchError::Status {
            url: url.to_string(),
            status,
            detail,
        },
        TableAnswer::NotModified => FetchError::Status {
            url: url.to_string(),
            status: 304,
            detail: "Not Modified to an unconditional request".into(),
        },
        TableAnswer::NotReady { detail } => FetchError::NotReady {
            url: url.to_string(),
            detail,
        },
        TableAnswer::Body { .. } => unreachable!("a body is a table"),
    }
}

/// Poll the job until it is done (`Ok`), failed or `deadline` passes.
fn wait_done(
    remote: &Remote,
    r: &ResultUrl,
    started: Instant,
    deadline: Instant,
) -> Result<(), FetchError> {
    loop {
        let (code, v) = remote.get_resource(&r.resource())?;
        match v["status"].as_str() {
            Some("done") if code == 200 => return Ok(()),
            Some("failed") if code == 200 => {
                return Err(FetchError::JobFailed {
                    url: r.resource(),
                    detail: v["error"]["detail"]
                        .as_str()
                        .map_or_else(|| v["error"].to_string(), str::to_string),
                });
            }
            Some("queued" | "running") if code == 200 => {}
            _ => {
                return Err(FetchError::Status {
                    url: r.resource(),
                    status: code,
                    detail: v.to_string(),
                });
            }
        }
        if Instant::now() >= deadline {
            return Err(FetchError::WaitTimedOut {
                url: r.resource(),
                waited_s: started.elapsed().as_secs(),
            });
        }
        std::thread::sleep(Duration::from_millis(250));
    }
}

/// The cached table of a result, downloading it into `cache_dir` first
/// when it is missing or invalid (see the module documentation for what is
/// verified). Safe for many processes on one cache directory at once: a
/// download happens under the id's lock, so one process downloads and the
/// others wait and read its file.
pub fn fetch(url: &str, cache_dir: &Path, opts: &FetchOptions) -> Result<Fetched, FetchError> {
    let r = ResultUrl::parse(url)?;
    let paths = CachePaths::new(cache_dir, &r.id);
    cache::create_dirs(&paths)?;
    let done = |outcome, bytes: &[u8], table, discarded, revalidation_error| Fetched {
        url: r.clone(),
        path: paths.table.clone(),
        outcome,
        size_bytes: bytes.len(),
        sha256: sha256_hex(bytes),
        table,
        discarded,
        revalidation_error,
    };
    // The common case needs no lock: files appear whole, by rename.
    if !opts.revalidate
        && let Some(b) = cache::read(&paths)?
        && let Ok(t) = format::from_bytes(&b)
    {
        return Ok(done(Outcome::Hit, &b, t, None, None));
    }
    let remote = Remote::new(opts.token.as_deref());
    let started = Instant::now();
    let table_url = r.table();
    let mut discarded = None;
    loop {
        let lock = cache::lock(&paths)?;
        cache::remove_stale_temps(&paths, &lock);
        let cached = match cache::read(&paths)? {
            None => None,
            Some(b) => match format::from_bytes(&b) {
                Ok(t) => Some((b, t)),
                Err(e) => {
                    discarded = Some(format!("{}: {e}", paths.table.display()));
                    None
                }
            },
        };
        let inm = match cached {
            Some((b, t)) if !opts.revalidate => {
                return Ok(done(Outcome::Hit, &b, t, discarded, None));
            }
            Some(ref c) => Some(sha256_hex(&c.0)),
            None => None,
        };
        let answer = remote.get_table(&table_url, inm.as_deref());
        let answer = match (answer, cached) {
            (Ok(TableAnswer::NotModified), Some((b, t))) => {
                return Ok(done(Outcome::Revalidated, &b, t, discarded, None));
            }
            (Ok(TableAnswer::Body { bytes, etag }), cached) => {
                let expected = expected_digest(&remote, &r, etag)?;
                let table = verify(&table_url, &bytes, &expected)?;
                let outcome = match &cached {
                    None => Outcome::Miss,
                    Some((b, _)) if *b == bytes => Outcome::Revalidated,
                    Some(_) => Outcome::Replaced,
                };
                if outcome != Outcome::Revalidated {
                    cache::store(&paths, &bytes, &lock)?;
                }
                return Ok(done(outcome, &bytes, table, discarded, None));
            }
            // A retired version is the service's answer, not an outage.
            (Ok(a @ TableAnswer::Status { status: 410, .. }), _) => {
                return Err(unexpected(&table_url, a));
            }
            (Err(e), Some((b, t))) => {
                return Ok(done(Outcome::Hit, &b, t, discarded, Some(e.to_string())));
            }
            (Ok(a), Some((b, t))) => {
                let e = match a {
                    TableAnswer::NotReady { detail } => FetchError::NotReady {
                        url: table_url.clone(),
                        detail,
                    },
                    a => unexpected(&table_url, a),
                };
                return Ok(done(Outcome::Hit, &b, t, discarded, Some(e.to_string())));
            }
            (a, None) => a?,
        };
        match answer {
            TableAnswer::NotReady { detail } => {
                let Some(wait) = opts.wait else {
                    return Err(FetchError::NotReady {
                        url: table_url,
                        detail,
                    });
                };
                // Others may use the cache (or wait too) meanwhile.
                drop(lock);
                wait_done(&remote, &r, started, started + wait)?;
                std::thread::sleep(Duration::from_millis(100));
            }
            a => return Err(unexpected(&table_url, a)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_digest_mismatch_names_both_digests() {
        let e = verify("u", b"abc", &"0".repeat(64)).unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains(&sha256_hex(b"abc")) && m.contains(&"0".repeat(64)),
            "{m}"
        );
    }

    #[test]
    fn matching_bytes_that_are_no_table_are_refused() {
        let e = verify("u", b"abc", &sha256_hex(b"abc")).unwrap_err();
        assert!(matches!(e, FetchError::Table { .. }), "{e}");
    }

    #[test]
    fn a_bad_url_touches_no_directory() {
        let d = std::env::temp_dir().join(format!("polbrdf-fetch-none-{}", std::process::id()));
        let e = fetch("http://h/v1/brdfs/abc", &d, &FetchOptions::default()).unwrap_err();
        assert!(matches!(e, FetchError::BadUrl { .. }), "{e}");
        assert!(!d.exists());
    }

    #[test]
    fn nothing_cached_and_no_service_is_an_error_naming_the_url() {
        let d = std::env::temp_dir().join(format!("polbrdf-fetch-down-{}", std::process::id()));
        let id = "0".repeat(64);
        // Port 9 (discard) on loopback: nothing listens in a test sandbox.
        let url = format!("http://127.0.0.1:9/v1/brdfs/{id}");
        let e = fetch(&url, &d, &FetchOptions::default()).unwrap_err();
        assert!(matches!(e, FetchError::Unreachable { .. }), "{e}");
        assert!(e.to_string().contains(&url), "{e}");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
