//! The S3-compatible blob store of a farm (`s3://BUCKET/PREFIX`), through
//! the `object_store` crate: a blob is the object `PREFIX/ab/cdef…` (the
//! key layout of the blob directory), verified against its name on every
//! read.
//!
//! * **Visible only complete.** A blob is written with one `PUT` (results
//!   are megabytes at most), which S3 makes visible atomically and only
//!   once complete, so there is no temporary key to leave behind; an
//!   overwrite by another instance writes the same bytes (the key is their
//!   digest).
//! * **Retried.** `object_store` retries a request that could not be sent
//!   or got a 5xx or a throttle, up to 10 times with jittered exponential
//!   backoff from 100 ms (about 2 s in all when the server refuses
//!   connections, measured), and a write that still fails, or was cut off
//!   mid-transfer, is written again here up to [`PUT_ATTEMPTS`] times with
//!   backoff from 250 ms: an S3 server unavailable for ten seconds or so
//!   delays a write. A write that still fails fails the job
//!   (`internal-error`, retryable), which is marked done only once its blob
//!   is stored.
//! * **Configured from the standard environment**, read once by
//!   `polbrdf serve` and handed over as options: `AWS_ENDPOINT_URL`,
//!   `AWS_REGION`, `AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`,
//!   `AWS_SESSION_TOKEN`, `AWS_ALLOW_HTTP=true` for a plain-HTTP endpoint
//!   (and the other `AWS_*` keys `object_store` knows).
//!
//! Synchronous like the blob directory: the calls block on the service's
//! tokio runtime from a blocking context (the solve's rayon thread or
//! `tokio::task::spawn_blocking`), never from an async task.

use crate::digest::{is_sha256_hex, sha256_hex};
use object_store::aws::{AmazonS3, AmazonS3Builder};
use object_store::path::Path;
use object_store::{ObjectStoreExt, PutPayload};
use std::io;

/// A bucket (and key prefix) of an S3-compatible store.
#[derive(Debug)]
pub struct S3Blobs {
    store: AmazonS3,
    bucket: String,
    prefix: String,
    runtime: tokio::runtime::Handle,
}

/// Writes of one blob before its error is the job's (with backoff from
/// 250 ms doubling: 3.75 s of waiting in all).
const PUT_ATTEMPTS: u32 = 5;

fn io_error(e: object_store::Error) -> io::Error {
    io::Error::other(e)
}

impl S3Blobs {
    /// A client of `bucket` with keys under `prefix` (no leading or
    /// trailing `/`; empty for the bucket's root), configured by
    /// `options` (`AWS_*` names, case-insensitive), running its requests
    /// on `runtime`.
    pub fn open(
        bucket: &str,
        prefix: &str,
        options: &[(String, String)],
        runtime: tokio::runtime::Handle,
    ) -> io::Result<Self> {
        let mut builder = AmazonS3Builder::new().with_bucket_name(bucket);
        for (k, v) in options {
            let key = k
                .to_ascii_lowercase()
                .parse()
                .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, format!("{k}: {e}")))?;
            builder = builder.with_config(key, v);
        }
        let store = builder.build().map_err(|e| {
            io::Error::new(io::ErrorKind::InvalidInput, format!("s3://{bucket}: {e}"))
        })?;
        Ok(Self {
            store,
            bucket: bucket.to_string(),
            prefix: prefix.trim_matches('/').to_string(),
            runtime,
        })
    }

    /// `s3://BUCKET/PREFIX`.
    pub fn url(&self) -> String {
        format!("s3://{}/{}", self.bucket, self.prefix)
    }

    /// The key of a digest: `PREFIX/ab/cdef…`.
    pub fn key(&self, digest: &str) -> Path {
        let tail = format!("{}/{}", &digest[..2], &digest[2..]);
        if self.prefix.is_empty() {
            Path::from(tail)
        } else {
            Path::from(format!("{}/{tail}", self.prefix))
        }
    }

    /// Is the bucket reachable with these credentials? (A missing key is
    /// an answer; anything else is an error.)
    pub fn check(&self) -> io::Result<()> {
        let probe = self.key(&"0".repeat(64));
        match self.runtime.block_on(self.store.head(&probe)) {
            Ok(_) | Err(object_store::Error::NotFound { .. }) => Ok(()),
            Err(e) => Err(io_error(e)),
        }
    }

    /// Store bytes; returns their digest. An object of the same digest and
    /// size is kept as it is.
    pub fn put(&self, bytes: &[u8]) -> io::Result<String> {
        let digest = sha256_hex(bytes);
        // Present already: keep it. Unknown (the store did not answer):
        // write anyway, with the write's own retries.
        if self
            .looks_present(&digest, bytes.len() as u64)
            .unwrap_or(false)
        {
            return Ok(digest);
        }
        let key = self.key(&digest);
        let payload = PutPayload::from(bytes.to_vec());
        // `object_store` retries a request it could not send; one cut off
        // mid-transfer it does not (a PUT is not a safe method). The key is
        // the bytes' digest, so writing again is harmless: retry that too.
        let mut wait = std::time::Duration::from_millis(250);
        for attempt in 1.. {
            match self.runtime.block_on(self.store.put(&key, payload.clone())) {
                Ok(_) => break,
                Err(e) if attempt < PUT_ATTEMPTS => {
                    tracing::warn!(%key, attempt, error = %e, "blob write failed; retrying");
                    std::thread::sleep(wait);
                    wait *= 2;
                }
                Err(e) => return Err(io_error(e)),
            }
        }
        Ok(digest)
    }

    /// The bytes of a blob, verified against its digest. `None` when it is
    /// missing or its bytes do not match (the object is then deleted, so
    /// that the next write replaces it).
    pub fn get(&self, digest: &str) -> io::Result<Option<Vec<u8>>> {
        if !is_sha256_hex(digest) {
            return Ok(None);
        }
        let key = self.key(digest);
        let read = self.runtime.block_on(async {
            match self.store.get(&key).await {
                Ok(r) => r.bytes().await.map(Some),
                Err(object_store::Error::NotFound { .. }) => Ok(None),
                Err(e) => Err(e),
            }
        });
        let Some(bytes) = read.map_err(io_error)? else {
            return Ok(None);
        };
        if sha256_hex(&bytes) != digest {
            tracing::warn!(digest, key = %key, "blob does not match its digest; deleted");
            match self.runtime.block_on(self.store.delete(&key)) {
                Ok(()) | Err(object_store::Error::NotFound { .. }) => {}
                Err(e) => return Err(io_error(e)),
            }
            return Ok(None);
        }
        Ok(Some(bytes.to_vec()))
    }

    /// Delete a blob (absent already: nothing to do).
    pub fn delete(&self, digest: &str) -> io::Result<()> {
        if !is_sha256_hex(digest) {
            return Ok(());
        }
        match self.runtime.block_on(self.store.delete(&self.key(digest))) {
            Ok(()) | Err(object_store::Error::NotFound { .. }) => Ok(()),
            Err(e) => Err(io_error(e)),
        }
    }

    /// Cheap presence check (`HEAD`: exists with the expected size). An
    /// answer other than found or not found is an error, not an absence:
    /// a blob that exists is never solved again because S3 did not answer.
    pub fn looks_present(&self, digest: &str, size: u64) -> io::Result<bool> {
        if !is_sha256_hex(digest) {
            return Ok(false);
        }
        match self.runtime.block_on(self.store.head(&self.key(digest))) {
            Ok(m) => Ok(m.size == size),
            Err(object_store::Error::NotFound { .. }) => Ok(false),
            Err(e) => Err(io_error(e)),
        }
    }
}
