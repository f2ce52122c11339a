//! Where a CLI command reads a BRDF table from: a local table file
//! (docs/table-format.md) or a running service (`http://HOST:PORT/v1/brdfs/ID`,
//! with or without the trailing `/table`), directly or through a render
//! node's cache directory (`--cache-dir DIR` or `POLBRDF_CACHE_DIR`;
//! `crate::fetch`, docs/deploy.md "Render nodes"). Either way the bytes
//! are verified (magic, version, SHA-256; a download also against the
//! service's digest) before use.

use crate::brdf::Table;
use crate::brdf::format;
use crate::fetch::{self, FetchOptions};
use clap::Args;
use std::path::PathBuf;

/// The environment variable naming the cache directory when `--cache-dir`
/// is not given.
pub const CACHE_DIR_ENV: &str = "POLBRDF_CACHE_DIR";
/// The bearer token sent with downloads from a service URL: the service's
/// own `POLBRDF_TOKEN`, which a service started with `--token-reads` asks
/// of every read (docs/deploy.md, Render nodes).
pub const TOKEN_ENV: &str = "POLBRDF_TOKEN";

/// The token of [`TOKEN_ENV`], if set and not empty.
pub fn token_from_env() -> Option<String> {
    std::env::var(TOKEN_ENV).ok().filter(|t| !t.is_empty())
}

/// The cache flags of the commands that take a table (`eval`, `export`,
/// `render`).
#[derive(Clone, Debug, Default, Args)]
pub struct CacheArgs {
    /// Read tables named by a service URL through this cache directory
    /// (DIR/<id>.pbrdf, locks DIR/<id>.lock, downloads in DIR/tmp/; see
    /// `polbrdf fetch --help` and docs/deploy.md, "Render nodes") [env
    /// POLBRDF_CACHE_DIR]. Without it a service table is downloaded every
    /// time.
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
    /// With a cache directory: ask the service whether a cached table is
    /// current (If-None-Match) instead of using it as it is; an unreachable
    /// service leaves the cached table in use, with a warning on stderr.
    #[arg(long)]
    pub revalidate: bool,
}

/// Where and how service tables are cached for one command.
#[derive(Clone, Debug)]
pub struct Cache {
    /// The cache directory.
    pub dir: PathBuf,
    /// What `crate::fetch::fetch` is asked to do.
    pub options: FetchOptions,
}

/// The cache directory: the flag, else a non-empty `POLBRDF_CACHE_DIR`
/// (`env` looks a variable up).
pub fn cache_dir_from(
    flag: Option<&PathBuf>,
    env: impl Fn(&str) -> Option<String>,
) -> Option<PathBuf> {
    flag.cloned().or_else(|| {
        env(CACHE_DIR_ENV)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    })
}

impl CacheArgs {
    /// The cache of these flags and the process environment; `None`
    /// without a directory (`--revalidate` alone is then an error).
    pub fn resolve(&self) -> Result<Option<Cache>, String> {
        let dir = cache_dir_from(self.cache_dir.as_ref(), |k| std::env::var(k).ok());
        match dir {
            Some(dir) => Ok(Some(Cache {
                dir,
                options: FetchOptions {
                    revalidate: self.revalidate,
                    wait: None,
                    token: token_from_env(),
                },
            })),
            None if self.revalidate => Err(format!(
                "--revalidate needs --cache-dir DIR (or {CACHE_DIR_ENV})"
            )),
            None => Ok(None),
        }
    }
}

/// The URL of the binary table for a source that names a service result.
/// `None` for a local path.
pub fn table_url(source: &str) -> Option<String> {
    if !(source.starts_with("http://") || source.starts_with("https://")) {
        return None;
    }
    let base = source.trim_end_matches('/');
    Some(if base.ends_with("/table") {
        base.to_string()
    } else {
        format!("{base}/table")
    })
}

/// Read and verify a table from a file path or a service URL (downloaded
/// every time).
pub fn load_table(source: &str) -> Result<Table, String> {
    load_table_with(source, None)
}

/// Read and verify a table from a file path or a service URL, the latter
/// through `cache` when given. A warning of the cache (a revalidation that
/// failed) goes to stderr.
pub fn load_table_with(source: &str, cache: Option<&Cache>) -> Result<Table, String> {
    if table_url(source).is_none() {
        return format::read_file(source).map_err(|e| e.to_string());
    }
    let Some(c) = cache else {
        return fetch::download(source, token_from_env().as_deref()).map_err(|e| e.to_string());
    };
    let f = fetch::fetch(source, &c.dir, &c.options).map_err(|e| e.to_string())?;
    warn(&f);
    Ok(f.table)
}

/// The stderr warnings of a fetch: a cached file that was invalid, a
/// revalidation that could not be made.
pub fn warn(f: &fetch::Fetched) {
    if let Some(d) = &f.discarded {
        eprintln!("polbrdf: warning: discarded an invalid cached table ({d}); downloaded it again");
    }
    if let Some(e) = &f.revalidation_error {
        eprintln!(
            "polbrdf: warning: could not revalidate {} ({e}); using the cached table",
            f.path.display()
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn service_urls_point_at_the_table_resource() {
        assert_eq!(
            table_url("http://127.0.0.1:8080/v1/brdfs/abc").as_deref(),
            Some("http://127.0.0.1:8080/v1/brdfs/abc/table")
        );
        assert_eq!(
            table_url("http://h/v1/brdfs/abc/table/").as_deref(),
            Some("http://h/v1/brdfs/abc/table")
        );
        assert_eq!(table_url("results/paint.pbrdf"), None);
    }

    #[test]
    fn a_missing_file_names_the_path() {
        let e = load_table("/nonexistent/x.pbrdf").unwrap_err();
        assert!(e.contains("/nonexistent/x.pbrdf"), "{e}");
    }

    #[test]
    fn the_flag_wins_over_the_environment_and_empty_is_unset() {
        let env = |v: &'static str| move |k: &str| (k == CACHE_DIR_ENV).then(|| v.to_string());
        let flag = PathBuf::from("/flag");
        assert_eq!(cache_dir_from(Some(&flag), env("/env")), Some(flag.clone()));
        assert_eq!(
            cache_dir_from(None, env("/env")),
            Some(PathBuf::from("/env"))
        );
        assert_eq!(cache_dir_from(None, env("")), None);
        assert_eq!(cache_dir_from(None, |_| None), None);
    }
}
