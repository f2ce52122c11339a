//! `polbrdf serve`: the HTTP service (docs/service.md).
//!
//! Configuration precedence: flag, then `POLBRDF_<FLAG>` environment
//! variable (e.g. `--max-queue` / `POLBRDF_MAX_QUEUE`), then the embedded
//! default. This module is the only reader of the environment; the result
//! is one [`Config`]. Logs go to stderr; stdout carries one line,
//! `listening on http://ADDR`, once the socket is bound (with
//! `--listen 127.0.0.1:0` it names the port chosen by the OS).

use crate::http::{self, Config, LogFormat};
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

/// Flags of `polbrdf serve`; each also reads `POLBRDF_<NAME>` (upper
/// case, `_` for `-`).
#[derive(Debug, Default, clap::Args)]
pub struct ServeArgs {
    /// Address to listen on [env POLBRDF_LISTEN; default 127.0.0.1:8080; port 0 picks a free port].
    #[arg(long)]
    pub listen: Option<String>,
    /// Data directory: SQLite index and result blobs [env POLBRDF_DATA_DIR; default ./polbrdf-data].
    #[arg(long)]
    pub data_dir: Option<PathBuf>,
    /// Database of the index: sqlite:PATH or postgres://USER@HOST/DB [env POLBRDF_DATABASE_URL; default sqlite://DATA_DIR/polbrdf.sqlite].
    #[arg(long)]
    pub database_url: Option<String>,
    /// Solver threads; 0 serves without solving (other instances on the same database solve) [env POLBRDF_WORKERS; default: the number of cores].
    #[arg(long)]
    pub workers: Option<usize>,
    /// Jobs allowed to wait for a worker; beyond it POST gets 503 [env POLBRDF_MAX_QUEUE; default 1024].
    #[arg(long)]
    pub max_queue: Option<usize>,
    /// Largest request body in bytes; beyond it 413 [env POLBRDF_MAX_BODY_BYTES; default 1048576].
    #[arg(long)]
    pub max_body_bytes: Option<usize>,
    /// Most streams: the cap on an explicit solver.streams and on what a solver.tolerance may pick [env POLBRDF_MAX_STREAMS; default 128].
    #[arg(long)]
    pub max_streams: Option<usize>,
    /// Most layers per spec [env POLBRDF_MAX_LAYERS; default 16].
    #[arg(long)]
    pub max_layers: Option<usize>,
    /// Most wavelengths per spec [env POLBRDF_MAX_WAVELENGTHS; default 128].
    #[arg(long)]
    pub max_wavelengths: Option<usize>,
    /// Longest expansion series of an expansion scatterer [env POLBRDF_MAX_EXPANSION_TERMS; default 10000].
    #[arg(long)]
    pub max_expansion_terms: Option<usize>,
    /// Largest Mie size parameter 2 pi r n_host / lambda [env POLBRDF_MAX_SIZE_PARAMETER; default 2000].
    #[arg(long)]
    pub max_size_parameter: Option<f64>,
    /// Most values (W x Ti x To x P x 16) of one dense table export [env POLBRDF_MAX_DENSE_VALUES; default 64000000].
    #[arg(long)]
    pub max_dense_values: Option<usize>,
    /// Most direction pairs of one POST .../eval [env POLBRDF_MAX_EVAL_POINTS; default 100000].
    #[arg(long)]
    pub max_eval_points: Option<usize>,
    /// Bearer token required for POST (prefer the env var POLBRDF_TOKEN: flags are visible in ps).
    #[arg(long)]
    pub token: Option<String>,
    /// Require the token for GET of results and /metrics too [env POLBRDF_TOKEN_READS=true].
    #[arg(long)]
    pub token_reads: bool,
    /// Log format: json or text [env POLBRDF_LOG_FORMAT; default text].
    #[arg(long)]
    pub log_format: Option<String>,
    /// Log filter, tracing EnvFilter syntax [env POLBRDF_LOG; default info].
    #[arg(long)]
    pub log: Option<String>,
    /// Seconds running jobs may take to finish at shutdown before they are re-queued [env POLBRDF_SHUTDOWN_GRACE_SECS; default 30].
    #[arg(long)]
    pub shutdown_grace_secs: Option<u64>,
    /// Claims of one job before it is abandoned (crash-loop guard) [env POLBRDF_MAX_ATTEMPTS; default 3].
    #[arg(long)]
    pub max_attempts: Option<i64>,
    /// This instance's id, the owner of its job leases, in logs and metrics [env POLBRDF_INSTANCE_ID; default HOSTNAME-PID].
    #[arg(long)]
    pub instance_id: Option<String>,
    /// Where result blobs live: file:///PATH or s3://BUCKET/PREFIX, configured by AWS_ENDPOINT_URL, AWS_REGION, AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY, AWS_ALLOW_HTTP [env POLBRDF_BLOB_STORE; default file://DATA_DIR/blobs].
    #[arg(long)]
    pub blob_store: Option<String>,
    /// Bound on the bytes of stored results: the least recently served are evicted beyond it [env POLBRDF_MAX_CACHE_BYTES; default unbounded].
    #[arg(long)]
    pub max_cache_bytes: Option<u64>,
    /// Seconds after its last serve (or its solve) during which a result is never evicted [env POLBRDF_EVICTION_GRACE_SECS; default 60].
    #[arg(long)]
    pub eviction_grace_secs: Option<u64>,
    /// Seconds a running job's lease holds without renewal; a job whose instance died is solved elsewhere after it [env POLBRDF_LEASE_SECS; default 30].
    #[arg(long)]
    pub lease_secs: Option<u64>,
}

fn pick<T: std::str::FromStr>(
    flag: Option<T>,
    name: &str,
    env: &dyn Fn(&str) -> Option<String>,
) -> Result<Option<T>, String>
where
    T::Err: std::fmt::Display,
{
    if flag.is_some() {
        return Ok(flag);
    }
    let var = format!("POLBRDF_{}", name.to_ascii_uppercase().replace('-', "_"));
    match env(&var) {
        None => Ok(None),
        Some(s) if s.is_empty() => Ok(None),
        Some(s) => s
            .parse()
            .map(Some)
            .map_err(|e| format!("{var}={s}: {e} (flag --{name})")),
    }
}

fn at_least(v: Option<usize>, name: &str, lo: usize, hi: usize) -> Result<Option<usize>, String> {
    match v {
        Some(x) if x < lo || x > hi => Err(format!("--{name} = {x} is outside [{lo}, {hi}]")),
        _ => Ok(v),
    }
}

/// The configuration from flags, then `env`, then defaults.
pub fn config_from(
    args: &ServeArgs,
    env: &dyn Fn(&str) -> Option<String>,
) -> Result<Config, String> {
    let data_dir = pick(args.data_dir.clone(), "data-dir", env)?
        .unwrap_or_else(|| PathBuf::from(http::config::DEFAULT_DATA_DIR));
    let mut c = Config::with_data_dir(&data_dir);
    if let Some(l) = pick(args.listen.clone(), "listen", env)? {
        c.listen = l
            .parse()
            .map_err(|e| format!("--listen {l}: {e} (give IP:PORT, e.g. 127.0.0.1:8080)"))?;
    }
    if let Some(u) = pick(args.database_url.clone(), "database-url", env)? {
        if crate::storage::Backend::of_url(&u).is_none() {
            // Not echoed: a URL may hold a password.
            return Err(
                "--database-url: give a sqlite:, postgres:// or postgresql:// URL".to_string(),
            );
        }
        c.database_url = u;
    }
    let n = |v: Option<usize>, name: &str, lo: usize, hi: usize| -> Result<Option<usize>, String> {
        at_least(pick(v, name, env)?, name, lo, hi)
    };
    if let Some(w) = n(args.workers, "workers", 0, 4096)? {
        c.workers = w;
    }
    if let Some(q) = n(args.max_queue, "max-queue", 0, 1 << 24)? {
        c.max_queue = q;
    }
    if let Some(b) = n(args.max_body_bytes, "max-body-bytes", 1, 1 << 30)? {
        c.max_body_bytes = b;
    }
    if let Some(s) = n(
        args.max_streams,
        "max-streams",
        1,
        crate::material::MAX_STREAMS,
    )? {
        c.limits.max_streams = s;
    }
    if let Some(l) = n(args.max_layers, "max-layers", 1, 1 << 20)? {
        c.limits.max_layers = l;
    }
    if let Some(w) = n(args.max_wavelengths, "max-wavelengths", 1, 1000)? {
        c.limits.max_wavelengths = w;
    }
    if let Some(t) = n(args.max_expansion_terms, "max-expansion-terms", 1, 100_000)? {
        c.limits.max_expansion_terms = t;
    }
    if let Some(x) = pick(args.max_size_parameter, "max-size-parameter", env)? {
        if !(x.is_finite() && (1.0..=crate::physics::mie::SIZE_PARAMETER_MAX).contains(&x)) {
            return Err(format!(
                "--max-size-parameter = {x} is outside [1, {:e}]",
                crate::physics::mie::SIZE_PARAMETER_MAX
            ));
        }
        c.limits.max_size_parameter = x;
    }
    if let Some(d) = n(args.max_dense_values, "max-dense-values", 16, 1 << 34)? {
        c.limits.max_dense_values = d;
    }
    if let Some(p) = n(args.max_eval_points, "max-eval-points", 1, 10_000_000)? {
        c.limits.max_eval_points = p;
    }
    c.token = pick(args.token.clone(), "token", env)?;
    if c.token.as_deref().is_some_and(|t| t.trim().is_empty()) {
        c.token = None;
    }
    c.token_reads = args.token_reads || pick::<bool>(None, "token-reads", env)?.unwrap_or(false);
    if c.token_reads && c.token.is_none() {
        return Err("--token-reads needs --token (or POLBRDF_TOKEN)".into());
    }
    if let Some(f) = pick(args.log_format.clone(), "log-format", env)? {
        c.log_format = match f.as_str() {
            "json" => LogFormat::Json,
            "text" => LogFormat::Text,
            other => return Err(format!("--log-format {other}: give json or text")),
        };
    }
    if let Some(f) = pick(args.log.clone(), "log", env)? {
        c.log_filter = f;
    }
    if let Some(s) = pick(args.shutdown_grace_secs, "shutdown-grace-secs", env)? {
        c.shutdown_grace = Duration::from_secs(s);
    }
    if let Some(a) = pick(args.max_attempts, "max-attempts", env)? {
        if a < 1 {
            return Err(format!("--max-attempts = {a} must be at least 1"));
        }
        c.max_attempts = a;
    }
    if let Some(i) = pick(args.instance_id.clone(), "instance-id", env)? {
        let ok = !i.is_empty() && i.len() <= 128 && i.chars().all(|ch| ch.is_ascii_graphic());
        if !ok {
            return Err(format!(
                "--instance-id {i:?}: give 1 to 128 printable ASCII characters without spaces"
            ));
        }
        c.instance_id = i;
    }
    if let Some(l) = pick(args.lease_secs, "lease-secs", env)? {
        if !(1..=86_400).contains(&l) {
            return Err(format!("--lease-secs = {l} is outside [1, 86400]"));
        }
        c.lease = Duration::from_secs(l);
    }
    if let Some(m) = pick(args.max_cache_bytes, "max-cache-bytes", env)? {
        if m == 0 {
            return Err("--max-cache-bytes = 0: give a positive number of bytes".into());
        }
        c.max_cache_bytes = Some(m);
    }
    if let Some(g) = pick(args.eviction_grace_secs, "eviction-grace-secs", env)? {
        c.eviction_grace = Duration::from_secs(g);
    }
    if let Some(b) = pick(args.blob_store.clone(), "blob-store", env)? {
        c.blob_store =
            crate::storage::BlobLocation::parse(&b).map_err(|e| format!("--blob-store {e}"))?;
    }
    if matches!(c.blob_store, crate::storage::BlobLocation::S3 { .. }) {
        c.s3_options = http::config::S3Options(
            S3_ENV
                .iter()
                .filter_map(|k| env(k).filter(|v| !v.is_empty()).map(|v| (k.to_string(), v)))
                .collect(),
        );
    }
    Ok(c)
}

/// The standard AWS variables an S3 blob store reads (`object_store`'s
/// names for them).
const S3_ENV: [&str; 7] = [
    "AWS_ENDPOINT_URL",
    "AWS_REGION",
    "AWS_DEFAULT_REGION",
    "AWS_ACCESS_KEY_ID",
    "AWS_SECRET_ACCESS_KEY",
    "AWS_SESSION_TOKEN",
    "AWS_ALLOW_HTTP",
];

fn init_logging(c: &Config) -> Result<(), String> {
    let filter = tracing_subscriber::EnvFilter::try_new(&c.log_filter)
        .map_err(|e| format!("--log {}: {e}", c.log_filter))?;
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_writer(std::io::stderr);
    let r = match c.log_format {
        LogFormat::Json => builder.json().try_init(),
        LogFormat::Text => builder.try_init(),
    };
    r.map_err(|e| format!("logging: {e}"))
}

/// Resolves on SIGINT or SIGTERM.
async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => tracing::info!("SIGINT"),
        _ = term => tracing::info!("SIGTERM"),
    }
}

/// Run the service; returns the process exit code (0 after a graceful
/// shutdown).
pub fn main(args: &ServeArgs) -> i32 {
    let env = |k: &str| std::env::var(k).ok();
    let config = match config_from(args, &env) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("polbrdf serve: {e}");
            return 2;
        }
    };
    if let Err(e) = init_logging(&config) {
        eprintln!("polbrdf serve: {e}");
        return 2;
    }
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .thread_name("polbrdf-http")
        .build()
    {
        Ok(r) => r,
        Err(e) => {
            eprintln!("polbrdf serve: async runtime: {e}");
            return 1;
        }
    };
    let result = runtime.block_on(http::serve(
        config,
        |addr| {
            let mut out = std::io::stdout().lock();
            let _ = writeln!(out, "listening on http://{addr}");
            let _ = out.flush();
        },
        shutdown_signal(),
    ));
    // Solver threads still busy with an abandoned job must not delay exit.
    runtime.shutdown_timeout(Duration::from_secs(1));
    match result {
        Ok(()) => 0,
        Err(e) => {
            tracing::error!(error = %e, "polbrdf serve failed");
            eprintln!("polbrdf serve: {e}");
            1
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_win_over_env_over_defaults() {
        let env = |k: &str| match k {
            "POLBRDF_MAX_QUEUE" => Some("7".to_string()),
            "POLBRDF_WORKERS" => Some("3".to_string()),
            "POLBRDF_DATA_DIR" => Some("/tmp/x".to_string()),
            "POLBRDF_TOKEN" => Some("s3cret".to_string()),
            _ => None,
        };
        let args = ServeArgs {
            workers: Some(2),
            ..Default::default()
        };
        let c = config_from(&args, &env).unwrap();
        assert_eq!(c.workers, 2);
        assert_eq!(c.max_queue, 7);
        assert_eq!(c.data_dir, PathBuf::from("/tmp/x"));
        assert_eq!(c.database_url, "sqlite:///tmp/x/polbrdf.sqlite");
        assert_eq!(c.token.as_deref(), Some("s3cret"));
        assert_eq!(c.listen.to_string(), "127.0.0.1:8080");
        assert_eq!(c.lease, Duration::from_secs(30));
        assert!(c.instance_id.ends_with(&format!("-{}", std::process::id())));
        let farm = |k: &str| match k {
            "POLBRDF_WORKERS" => Some("0".to_string()),
            "POLBRDF_INSTANCE_ID" => Some("render-api-1".to_string()),
            "POLBRDF_LEASE_SECS" => Some("5".to_string()),
            _ => None,
        };
        let c = config_from(&ServeArgs::default(), &farm).unwrap();
        assert_eq!(
            (c.workers, c.instance_id.as_str(), c.lease),
            (0, "render-api-1", Duration::from_secs(5))
        );
        let d = config_from(&ServeArgs::default(), &|_| None).unwrap();
        assert_eq!(d, Config::default());
        assert_eq!(
            d.blob_store,
            crate::storage::BlobLocation::File(PathBuf::from("./polbrdf-data/blobs"))
        );
    }

    #[test]
    fn an_s3_blob_store_takes_the_aws_environment_and_hides_secrets() {
        let env = |k: &str| match k {
            "POLBRDF_BLOB_STORE" => Some("s3://polbrdf/farm".to_string()),
            "AWS_ENDPOINT_URL" => Some("http://127.0.0.1:9000".to_string()),
            "AWS_SECRET_ACCESS_KEY" => Some("hunter2".to_string()),
            "AWS_ALLOW_HTTP" => Some("true".to_string()),
            _ => None,
        };
        let c = config_from(&ServeArgs::default(), &env).unwrap();
        assert_eq!(
            c.blob_store,
            crate::storage::BlobLocation::S3 {
                bucket: "polbrdf".into(),
                prefix: "farm".into()
            }
        );
        let names: Vec<&str> = c.s3_options.0.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(
            names,
            [
                "AWS_ENDPOINT_URL",
                "AWS_SECRET_ACCESS_KEY",
                "AWS_ALLOW_HTTP"
            ]
        );
        assert!(!format!("{c:?}").contains("hunter2"));
    }

    #[test]
    fn database_url_names_a_backend() {
        for url in [
            "sqlite:///tmp/x.sqlite",
            "postgres://polbrdf@127.0.0.1:5432/polbrdf",
            "postgresql://db.internal/polbrdf",
        ] {
            let env = |k: &str| (k == "POLBRDF_DATABASE_URL").then(|| url.to_string());
            assert_eq!(
                config_from(&ServeArgs::default(), &env)
                    .unwrap()
                    .database_url,
                url
            );
        }
        let args = ServeArgs {
            database_url: Some("mysql://u:hunter2@h/db".into()),
            ..Default::default()
        };
        let e = config_from(&args, &|_| None).unwrap_err();
        assert!(
            e.contains("--database-url") && !e.contains("hunter2"),
            "{e}"
        );
    }

    #[test]
    fn bad_values_name_the_flag() {
        let e = config_from(&ServeArgs::default(), &|k| {
            (k == "POLBRDF_MAX_QUEUE").then(|| "many".to_string())
        })
        .unwrap_err();
        assert!(
            e.contains("POLBRDF_MAX_QUEUE") && e.contains("--max-queue"),
            "{e}"
        );
        let args = ServeArgs {
            max_streams: Some(100_000),
            ..Default::default()
        };
        assert!(
            config_from(&args, &|_| None)
                .unwrap_err()
                .contains("--max-streams")
        );
        let args = ServeArgs {
            token_reads: true,
            ..Default::default()
        };
        assert!(config_from(&args, &|_| None).is_err());
        let e = config_from(&ServeArgs::default(), &|k| {
            (k == "POLBRDF_BLOB_STORE").then(|| "gs://bucket".into())
        })
        .unwrap_err();
        assert!(e.contains("--blob-store gs://bucket"), "{e}");
        for (var, value) in [("POLBRDF_LEASE_SECS", "0"), ("POLBRDF_INSTANCE_ID", "a b")] {
            let e = config_from(&ServeArgs::default(), &|k| (k == var).then(|| value.into()))
                .unwrap_err();
            let flag = if var.contains("LEASE") {
                "--lease-secs"
            } else {
                "--instance-id"
            };
            assert!(e.contains(flag), "{e}");
        }
    }
}
