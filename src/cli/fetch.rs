//! `polbrdf fetch URL --cache-dir DIR [--revalidate] [--wait]`: put a
//! service result's table into a render node's cache directory (or find it
//! there) and say where it is (`crate::fetch`, docs/deploy.md "Render
//! nodes").

use super::source::{CACHE_DIR_ENV, cache_dir_from, warn};
use crate::fetch::{self, FetchOptions};
use clap::Args;
use serde_json::{Value, json};
use std::path::PathBuf;
use std::time::Duration;

/// Arguments of `polbrdf fetch`.
#[derive(Debug, Args)]
#[command(after_long_help = "\
Cache layout (one directory per node, on a local disk, shared by every process of the node):
  DIR/<id>.pbrdf   the table, exactly the service's bytes (SHA-256 = the service's ETag)
  DIR/<id>.lock    lock file: whoever downloads <id> holds an exclusive lock on it, so of many
                   processes fetching one id at once one downloads and the others wait and read
  DIR/tmp/         downloads being written (fsynced, then renamed to DIR/<id>.pbrdf)

Results are immutable, so a cached table is used without asking the service (it is checked
at every use: magic, version and its own SHA-256; an invalid file is downloaded again), also
when the service is down. --revalidate asks the service first (If-None-Match).

Prints {\"id\", \"url\", \"path\", \"cache\": \"miss\"|\"hit\"|\"revalidated\"|\"replaced\", \"bytes\",
\"sha256\"}, plus \"discarded\" (why a cached file was thrown away) and \"revalidation_error\"
(why --revalidate could not ask; the cached table was used) when they happened.")]
pub struct FetchArgs {
    /// The result: http://HOST:PORT/v1/brdfs/ID (or .../ID/table).
    pub url: String,
    /// The cache directory (created if missing) [env POLBRDF_CACHE_DIR].
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
    /// Ask the service whether a cached table is current (If-None-Match):
    /// 304 keeps it, 200 replaces it after verification; if the service
    /// cannot answer, the cached table is used with a warning on stderr.
    #[arg(long)]
    pub revalidate: bool,
    /// If the job is queued or running, poll until it is done instead of
    /// failing at once.
    #[arg(long)]
    pub wait: bool,
    /// With --wait: give up after this many seconds.
    #[arg(long, default_value_t = 3600, value_name = "SECONDS")]
    pub wait_timeout_secs: u64,
}

/// Run `fetch`.
pub fn run(a: &FetchArgs) -> Result<Value, String> {
    let dir = cache_dir_from(a.cache_dir.as_ref(), |k| std::env::var(k).ok())
        .ok_or_else(|| format!("fetch needs --cache-dir DIR (or {CACHE_DIR_ENV})"))?;
    let options = FetchOptions {
        revalidate: a.revalidate,
        wait: a.wait.then(|| Duration::from_secs(a.wait_timeout_secs)),
        token: super::source::token_from_env(),
    };
    let f = fetch::fetch(&a.url, &dir, &options).map_err(|e| e.to_string())?;
    warn(&f);
    Ok(summary(&f))
}

/// The JSON `fetch` prints.
fn summary(f: &fetch::Fetched) -> Value {
    let mut v = json!({
        "id": f.url.id,
        "url": f.url.table(),
        "path": f.path,
        "cache": f.outcome.name(),
        "bytes": f.size_bytes,
        "sha256": f.sha256,
    });
    if let Some(d) = &f.discarded {
        v["discarded"] = json!(d);
    }
    if let Some(e) = &f.revalidation_error {
        v["revalidation_error"] = json!(e);
    }
    v
}
