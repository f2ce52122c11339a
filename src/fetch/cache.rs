//! The cache directory of a render node (docs/deploy.md, "Render nodes"):
//!
//! ```text
//! DIR/<id>.pbrdf          the table of result <id>, exactly the service's bytes
//! DIR/<id>.lock           lock file of <id> (empty; kept: removing it would race)
//! DIR/tmp/<id>.<pid>.<n>.part   a download being written
//! ```
//!
//! A table appears under its final name only by `rename` of a complete,
//! fsynced temp file, so a reader never needs the lock to see a whole
//! file. Whoever downloads or replaces `<id>` holds an exclusive lock on
//! `<id>.lock` (`std::fs::File::lock`, an `flock` on Linux: released when
//! the process exits, however it exits), so of many processes asking for
//! one id at once exactly one downloads.

use super::FetchError;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The files of one id in a cache directory.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CachePaths {
    /// `DIR/<id>.pbrdf`.
    pub table: PathBuf,
    /// `DIR/<id>.lock`.
    pub lock: PathBuf,
    /// `DIR/tmp`.
    pub tmp_dir: PathBuf,
    /// The id (the prefix of this id's temp files).
    id: String,
}

impl CachePaths {
    /// The paths of `id` (already checked to be 64 hex digits, so it is a
    /// plain file name) under `dir`.
    pub fn new(dir: &Path, id: &str) -> Self {
        CachePaths {
            table: dir.join(format!("{id}.pbrdf")),
            lock: dir.join(format!("{id}.lock")),
            tmp_dir: dir.join("tmp"),
            id: id.to_string(),
        }
    }

    /// A temp file name of this id for this process, unique within it.
    pub fn temp(&self, n: u64) -> PathBuf {
        self.tmp_dir
            .join(format!("{}.{}.{n}.part", self.id, std::process::id()))
    }

    /// Is `name` (a file name in `tmp/`) one of this id's temp files?
    pub fn is_own_temp(&self, name: &str) -> bool {
        name.strip_prefix(&self.id)
            .is_some_and(|r| r.starts_with('.') && r.ends_with(".part"))
    }
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> FetchError + '_ {
    move |source| FetchError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// Create `DIR` and `DIR/tmp`.
pub fn create_dirs(p: &CachePaths) -> Result<(), FetchError> {
    std::fs::create_dir_all(&p.tmp_dir).map_err(io(&p.tmp_dir))
}

/// An exclusive lock on `<id>.lock`, held until dropped (or the process
/// ends). Blocks while another process holds it.
pub struct IdLock {
    _file: File,
}

/// Take the lock of an id (creating its lock file), waiting for it.
pub fn lock(p: &CachePaths) -> Result<IdLock, FetchError> {
    let f = OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&p.lock)
        .map_err(io(&p.lock))?;
    f.lock().map_err(io(&p.lock))?;
    Ok(IdLock { _file: f })
}

/// Remove this id's temp files left by processes that died while
/// downloading. Only the holder of the id's lock may call it: nobody else
/// writes them.
pub fn remove_stale_temps(p: &CachePaths, _lock: &IdLock) {
    let Ok(entries) = std::fs::read_dir(&p.tmp_dir) else {
        return;
    };
    for e in entries.flatten() {
        if e.file_name().to_str().is_some_and(|n| p.is_own_temp(n)) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// Put `bytes` under `<id>.pbrdf`: write a temp file in `tmp/`, fsync it,
/// rename it into place and fsync the directory, so the final name holds
/// either the old complete file or the new one, also after a crash.
pub fn store(p: &CachePaths, bytes: &[u8], _lock: &IdLock) -> Result<(), FetchError> {
    let tmp = p.temp(0);
    let write = || -> Result<(), FetchError> {
        let mut f = File::create(&tmp).map_err(io(&tmp))?;
        f.write_all(bytes).map_err(io(&tmp))?;
        f.sync_all().map_err(io(&tmp))?;
        std::fs::rename(&tmp, &p.table).map_err(io(&p.table))?;
        if let Some(dir) = p.table.parent() {
            File::open(dir)
                .and_then(|d| d.sync_all())
                .map_err(io(dir))?;
        }
        Ok(())
    };
    write().inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
}

/// The cached bytes of the id, `None` when there is no such file.
pub fn read(p: &CachePaths) -> Result<Option<Vec<u8>>, FetchError> {
    match std::fs::read(&p.table) {
        Ok(b) => Ok(Some(b)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(io(&p.table)(e)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ID: &str = "068718c4a5b8827e98565b6b05f362baf8aaa97be541dfec1dbc4b2100e7ba0a";

    fn scratch(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("polbrdf-fetch-cache-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn layout() {
        let p = CachePaths::new(Path::new("/c"), ID);
        assert_eq!(p.table, PathBuf::from(format!("/c/{ID}.pbrdf")));
        assert_eq!(p.lock, PathBuf::from(format!("/c/{ID}.lock")));
        assert_eq!(p.tmp_dir, PathBuf::from("/c/tmp"));
        let t = p.temp(3);
        assert_eq!(t.parent(), Some(Path::new("/c/tmp")));
        let name = t.file_name().unwrap().to_str().unwrap();
        assert!(p.is_own_temp(name), "{name}");
        assert!(!p.is_own_temp(&format!("{ID}.pbrdf")));
        assert!(!CachePaths::new(Path::new("/c"), &ID.replace('0', "1")).is_own_temp(name));
    }

    #[test]
    fn store_replaces_whole_files_and_leaves_no_temp() {
        let d = scratch("store");
        let p = CachePaths::new(&d, ID);
        create_dirs(&p).unwrap();
        assert_eq!(read(&p).unwrap(), None);
        let l = lock(&p).unwrap();
        std::fs::write(p.temp(7), b"left by a crash").unwrap();
        remove_stale_temps(&p, &l);
        store(&p, b"first", &l).unwrap();
        store(&p, b"second", &l).unwrap();
        assert_eq!(read(&p).unwrap().as_deref(), Some(&b"second"[..]));
        assert_eq!(std::fs::read_dir(&p.tmp_dir).unwrap().count(), 0);
        drop(l);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn the_lock_is_exclusive() {
        let d = scratch("lock");
        let p = CachePaths::new(&d, ID);
        create_dirs(&p).unwrap();
        let held = lock(&p).unwrap();
        let other = File::options().write(true).open(&p.lock).unwrap();
        assert!(matches!(
            other.try_lock(),
            Err(std::fs::TryLockError::WouldBlock)
        ));
        drop(held);
        other.try_lock().unwrap();
        std::fs::remove_dir_all(&d).unwrap();
    }
}
