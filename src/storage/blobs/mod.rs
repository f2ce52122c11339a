//! Content-addressed blobs (as in bazel-remote's CAS): a result's bytes are
//! stored under the lowercase hex SHA-256 of the bytes, `ab/cdef…` (the
//! first two digits name a fan-out directory or key prefix), and every read
//! re-hashes them: a blob whose bytes do not match its name is removed and
//! reported absent, never served.
//!
//! Two stores behind the one type [`BlobStore`], chosen by `--blob-store`
//! ([`BlobLocation::parse`]):
//!
//! * [`file`] (`file:///PATH`, the default `<data-dir>/blobs`): a directory;
//! * [`s3`] (`s3://BUCKET/PREFIX`): an S3-compatible object store, which
//!   every instance of a farm reaches.
//!
//! Synchronous: call it from a blocking context (the solve's rayon thread
//! or `tokio::task::spawn_blocking`), never on the async runtime. Each call
//! is timed for `polbrdf_blob_store_request_duration_seconds{op}` through
//! the observer the jobs layer sets ([`BlobStore::with_observer`]).

pub mod file;
pub mod s3;

pub use file::FileBlobs;
pub use s3::S3Blobs;

use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Where the blobs live, as `--blob-store` names it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BlobLocation {
    /// A directory (`file:///PATH`).
    File(PathBuf),
    /// A bucket and key prefix of an S3-compatible store
    /// (`s3://BUCKET/PREFIX`).
    S3 {
        /// Bucket name.
        bucket: String,
        /// Key prefix, without leading or trailing `/` (may be empty).
        prefix: String,
    },
}

impl BlobLocation {
    /// `file:///ABSOLUTE/PATH` or `s3://BUCKET[/PREFIX]`.
    pub fn parse(url: &str) -> Result<Self, String> {
        if let Some(path) = url.strip_prefix("file://") {
            if !path.starts_with('/') {
                return Err(format!(
                    "{url}: a file URL names an absolute path (file:///var/lib/polbrdf/blobs)"
                ));
            }
            return Ok(BlobLocation::File(PathBuf::from(path)));
        }
        if let Some(rest) = url.strip_prefix("s3://") {
            let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
            let valid = (3..=63).contains(&bucket.len())
                && bucket
                    .chars()
                    .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-' || c == '.');
            if !valid {
                return Err(format!(
                    "{url}: '{bucket}' is not an S3 bucket name (3-63 of a-z, 0-9, '-', '.')"
                ));
            }
            return Ok(BlobLocation::S3 {
                bucket: bucket.to_string(),
                prefix: prefix.trim_matches('/').to_string(),
            });
        }
        Err(format!("{url}: give file:///PATH or s3://BUCKET/PREFIX"))
    }
}

/// Receives the operation (`get`, `put`, `head`, `delete`) and duration of each
/// blob-store call.
pub type Observer = Arc<dyn Fn(&'static str, Duration) + Send + Sync>;

enum Store {
    File(FileBlobs),
    S3(S3Blobs),
}

/// The blob store of the service.
pub struct BlobStore {
    store: Store,
    observer: Option<Observer>,
}

impl std::fmt::Debug for BlobStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BlobStore")
            .field("url", &self.url())
            .finish_non_exhaustive()
    }
}

impl BlobStore {
    /// A blob directory (created if needed).
    pub fn open(root: impl Into<PathBuf>) -> io::Result<Self> {
        Ok(Self {
            store: Store::File(FileBlobs::open(root)?),
            observer: None,
        })
    }

    /// The store `location` names; an S3 store is configured by
    /// `s3_options` (`AWS_*` names) and checked to be reachable. Call it
    /// from a blocking context of the runtime its requests run on.
    pub fn at(location: &BlobLocation, s3_options: &[(String, String)]) -> io::Result<Self> {
        match location {
            BlobLocation::File(root) => Self::open(root),
            BlobLocation::S3 { bucket, prefix } => {
                let runtime = tokio::runtime::Handle::try_current()
                    .map_err(|e| io::Error::other(format!("s3 blob store: {e}")))?;
                let s3 = S3Blobs::open(bucket, prefix, s3_options, runtime)?;
                s3.check()?;
                Ok(Self {
                    store: Store::S3(s3),
                    observer: None,
                })
            }
        }
    }

    /// Time every call with `observer`.
    pub fn with_observer(mut self, observer: Observer) -> Self {
        self.observer = Some(observer);
        self
    }

    /// `file:///PATH` or `s3://BUCKET/PREFIX`.
    pub fn url(&self) -> String {
        match &self.store {
            Store::File(f) => format!("file://{}", f.root().display()),
            Store::S3(s) => s.url(),
        }
    }

    /// The directory of a file store.
    pub fn root(&self) -> Option<&Path> {
        match &self.store {
            Store::File(f) => Some(f.root()),
            Store::S3(_) => None,
        }
    }

    fn timed<T>(&self, op: &'static str, f: impl FnOnce() -> T) -> T {
        let t0 = Instant::now();
        let r = f();
        if let Some(o) = &self.observer {
            o(op, t0.elapsed());
        }
        r
    }

    /// Store bytes; returns their digest. Idempotent: an intact blob with
    /// the same digest is kept as it is. Returns once the blob is durable.
    pub fn put(&self, bytes: &[u8]) -> io::Result<String> {
        self.timed("put", || match &self.store {
            Store::File(f) => f.put(bytes),
            Store::S3(s) => s.put(bytes),
        })
    }

    /// The bytes of a blob, verified against its digest; `None` when it is
    /// missing or corrupt (a corrupt one is removed).
    pub fn get(&self, digest: &str) -> io::Result<Option<Vec<u8>>> {
        self.timed("get", || match &self.store {
            Store::File(f) => f.get(digest),
            Store::S3(s) => s.get(digest),
        })
    }

    /// Remove a blob (evicted or deleted); absent already is no error.
    pub fn delete(&self, digest: &str) -> io::Result<()> {
        self.timed("delete", || match &self.store {
            Store::File(f) => f.delete(digest),
            Store::S3(s) => s.delete(digest),
        })
    }

    /// Cheap presence check (exists with the expected size); [`Self::get`]
    /// verifies the bytes. An error means the store did not answer, not
    /// that the blob is absent.
    pub fn looks_present(&self, digest: &str, size: u64) -> io::Result<bool> {
        self.timed("head", || match &self.store {
            Store::File(f) => f.looks_present(digest, size),
            Store::S3(s) => s.looks_present(digest, size),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locations_parse_or_say_what_to_give() {
        assert_eq!(
            BlobLocation::parse("file:///var/lib/polbrdf/blobs"),
            Ok(BlobLocation::File("/var/lib/polbrdf/blobs".into()))
        );
        assert_eq!(
            BlobLocation::parse("s3://polbrdf-cache/farm/blobs/"),
            Ok(BlobLocation::S3 {
                bucket: "polbrdf-cache".into(),
                prefix: "farm/blobs".into()
            })
        );
        assert_eq!(
            BlobLocation::parse("s3://polbrdf"),
            Ok(BlobLocation::S3 {
                bucket: "polbrdf".into(),
                prefix: String::new()
            })
        );
        for bad in [
            "file://relative/path",
            "s3://Upper/x",
            "s3://",
            "gs://b/p",
            "/tmp/x",
        ] {
            let e = BlobLocation::parse(bad).unwrap_err();
            assert!(e.starts_with(bad), "{e}");
        }
    }

    #[test]
    fn calls_are_timed_by_operation() {
        let dir = std::env::temp_dir().join(format!(
            "polbrdf-blobstore-timed-{}-{}",
            std::process::id(),
            crate::storage::now_ms()
        ));
        let seen = Arc::new(std::sync::Mutex::new(Vec::new()));
        let log = seen.clone();
        let store = BlobStore::open(&dir)
            .unwrap()
            .with_observer(Arc::new(move |op, _| log.lock().unwrap().push(op)));
        let d = store.put(b"x").unwrap();
        assert!(store.looks_present(&d, 1).unwrap());
        assert_eq!(store.get(&d).unwrap().unwrap(), b"x");
        store.delete(&d).unwrap();
        store.delete(&d).unwrap();
        assert_eq!(store.get(&d).unwrap(), None);
        assert_eq!(
            *seen.lock().unwrap(),
            ["put", "head", "get", "delete", "delete", "get"]
        );
        assert_eq!(store.url(), format!("file://{}", dir.display()));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
