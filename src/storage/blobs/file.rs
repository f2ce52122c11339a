//! The blob directory (`file://`, the default): a blob is a file named
//! by the lowercase hex SHA-256 of its bytes, `blobs/ab/cdef…` (the first two
//! digits name a fan-out directory). Writes go to `blobs/tmp/`, are fsynced
//! and renamed into place (then the directory is fsynced), so a reader never
//! sees a partial blob under its final name. Reads re-hash the bytes: a blob
//! whose bytes do not match its name is removed and reported absent.
//!
//! Synchronous file I/O: call it from a blocking context (the solve's rayon
//! thread or `tokio::task::spawn_blocking`), never on the async runtime.

use crate::digest::{is_sha256_hex, sha256_hex};
use std::fs::{self, File};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A blob directory.
#[derive(Debug)]
pub struct FileBlobs {
    root: PathBuf,
    counter: AtomicU64,
}

/// Age beyond which a temporary write is a leftover: a write takes
/// milliseconds (one result, written and fsynced).
pub const STALE_TEMP: std::time::Duration = std::time::Duration::from_secs(60);

impl FileBlobs {
    /// Open (and create) the blob directory `root`; leftovers of interrupted
    /// writes in `root/tmp` older than [`STALE_TEMP`] are removed. Younger
    /// ones may be another instance's writes in progress (instances of one
    /// machine may share the directory).
    pub fn open(root: impl Into<PathBuf>) -> io::Result<Self> {
        let root = root.into();
        let tmp = root.join("tmp");
        fs::create_dir_all(&tmp)?;
        for entry in fs::read_dir(&tmp)? {
            let entry = entry?;
            let stale = entry
                .metadata()
                .and_then(|m| m.modified())
                .is_ok_and(|t| t.elapsed().is_ok_and(|age| age > STALE_TEMP));
            if stale {
                match fs::remove_file(entry.path()) {
                    Ok(()) => {}
                    Err(e) if e.kind() == io::ErrorKind::NotFound => {}
                    Err(e) => return Err(e),
                }
            }
        }
        Ok(Self {
            root,
            counter: AtomicU64::new(0),
        })
    }

    /// The directory.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Where the blob with this digest lives (`root/ab/cdef…`).
    pub fn path(&self, digest: &str) -> PathBuf {
        self.root.join(&digest[..2]).join(&digest[2..])
    }

    /// Store bytes; returns their digest. Idempotent: an intact blob with the
    /// same digest is kept as it is.
    pub fn put(&self, bytes: &[u8]) -> io::Result<String> {
        let digest = sha256_hex(bytes);
        let path = self.path(&digest);
        if self.get(&digest)?.is_some() {
            return Ok(digest);
        }
        let dir = path.parent().expect("fan-out directory");
        fs::create_dir_all(dir)?;
        let n = self.counter.fetch_add(1, Ordering::Relaxed);
        let tmp = self
            .root
            .join("tmp")
            .join(format!("{digest}.{}.{n}", std::process::id()));
        {
            let mut f = File::create(&tmp)?;
            f.write_all(bytes)?;
            f.sync_all()?;
        }
        fs::rename(&tmp, &path)?;
        // Make the rename itself durable.
        File::open(dir)?.sync_all()?;
        Ok(digest)
    }

    /// The bytes of a blob, verified against its digest. `None` when the
    /// blob is missing or its bytes do not match (the corrupt file is
    /// removed so that the next write replaces it).
    pub fn get(&self, digest: &str) -> io::Result<Option<Vec<u8>>> {
        if !is_sha256_hex(digest) {
            return Ok(None);
        }
        let path = self.path(digest);
        let bytes = match fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(e),
        };
        if sha256_hex(&bytes) != digest {
            tracing::warn!(digest, path = %path.display(), "blob does not match its digest; removed");
            match fs::remove_file(&path) {
                Ok(()) => {}
                Err(e) if e.kind() == io::ErrorKind::NotFound => {}
                Err(e) => return Err(e),
            }
            return Ok(None);
        }
        Ok(Some(bytes))
    }

    /// Remove a blob (absent already: nothing to do).
    pub fn delete(&self, digest: &str) -> io::Result<()> {
        if !is_sha256_hex(digest) {
            return Ok(());
        }
        match fs::remove_file(self.path(digest)) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
            Err(e) => Err(e),
        }
    }

    /// Cheap presence check (exists with the expected size); [`Self::get`]
    /// verifies the bytes.
    pub fn looks_present(&self, digest: &str, size: u64) -> io::Result<bool> {
        if !is_sha256_hex(digest) {
            return Ok(false);
        }
        match fs::metadata(self.path(digest)) {
            Ok(m) => Ok(m.len() == size),
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(false),
            Err(e) => Err(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!(
            "polbrdf-blobs-{name}-{}-{}",
            std::process::id(),
            crate::storage::now_ms()
        ));
        let _ = fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn put_get_and_corruption() {
        let dir = temp_dir("roundtrip");
        let store = FileBlobs::open(&dir).unwrap();
        let digest = store.put(b"hello").unwrap();
        assert_eq!(
            digest,
            "2cf24dba5fb0a30e26e83b2ac5b9e29e1b161e5c1fa7425e73043362938b9824"
        );
        assert!(store.path(&digest).starts_with(dir.join("2c")));
        assert_eq!(store.get(&digest).unwrap().unwrap(), b"hello");
        assert!(store.looks_present(&digest, 5).unwrap());
        assert!(!store.looks_present(&digest, 6).unwrap());
        // Idempotent.
        assert_eq!(store.put(b"hello").unwrap(), digest);
        // Corrupt: not served, removed, and a new put repairs it.
        fs::write(store.path(&digest), b"hellO").unwrap();
        assert_eq!(store.get(&digest).unwrap(), None);
        assert!(!store.path(&digest).exists());
        store.put(b"hello").unwrap();
        assert_eq!(store.get(&digest).unwrap().unwrap(), b"hello");
        // Missing and malformed digests are absent.
        assert_eq!(store.get(&"0".repeat(64)).unwrap(), None);
        assert_eq!(store.get("../etc").unwrap(), None);
        assert!(fs::read_dir(dir.join("tmp")).unwrap().next().is_none());
        fs::remove_dir_all(&dir).unwrap();
    }

    /// Opening removes leftovers of interrupted writes, not the writes
    /// another instance sharing the directory has in progress.
    #[test]
    fn open_removes_only_stale_temporaries() {
        let dir = temp_dir("stale");
        FileBlobs::open(&dir).unwrap();
        let (old, young) = (dir.join("tmp/old.1.0"), dir.join("tmp/young.2.0"));
        fs::write(&old, b"x").unwrap();
        fs::write(&young, b"y").unwrap();
        let long_ago = std::time::SystemTime::now() - STALE_TEMP * 2;
        File::options()
            .write(true)
            .open(&old)
            .unwrap()
            .set_modified(long_ago)
            .unwrap();
        FileBlobs::open(&dir).unwrap();
        assert!(!old.exists() && young.exists());
        fs::remove_dir_all(&dir).unwrap();
    }
}
