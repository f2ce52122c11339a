//! The one configuration struct of the service, built once at start-up
//! from flags and `POLBRDF_*` environment variables (`polbrdf serve`,
//! src/cli/serve.rs); nothing else reads the environment.

use crate::storage::BlobLocation;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

/// Log line format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogFormat {
    /// One JSON object per line.
    Json,
    /// Human-readable lines.
    Text,
}

/// Settings of `polbrdf serve` (docs/service.md, "Configuration").
#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// Address to listen on (port 0: any free port; the bound address is
    /// printed on stdout).
    pub listen: SocketAddr,
    /// Data directory: the SQLite index and the blob directory `blobs/` (by
    /// default).
    pub data_dir: PathBuf,
    /// sqlx URL of the index: `sqlite:…` or `postgres://…` / `postgresql://…`
    /// (`storage::Backend::of_url`).
    pub database_url: String,
    /// Solver threads (`0`: serve only; other instances solve).
    pub workers: usize,
    /// Jobs allowed to wait for a worker; more submissions get 503.
    pub max_queue: usize,
    /// Largest request body (bytes); larger bodies get 413.
    pub max_body_bytes: usize,
    /// Service caps on a spec (422 beyond them).
    pub limits: Limits,
    /// Bearer token required for submissions (`None`: open).
    pub token: Option<String>,
    /// Require the token for reads as well (GET of results and /metrics).
    pub token_reads: bool,
    /// Log format.
    pub log_format: LogFormat,
    /// Log filter (tracing-subscriber `EnvFilter` syntax).
    pub log_filter: String,
    /// How long running jobs may take to finish at shutdown before they
    /// are re-queued.
    pub shutdown_grace: Duration,
    /// Claims of one job before it is abandoned (crash-loop guard).
    pub max_attempts: i64,
    /// This instance's id: the owner of its leases, in logs and in the
    /// `instance` label of its metrics.
    pub instance_id: String,
    /// How long a claimed job's lease holds without a renewal.
    pub lease: Duration,
    /// Where result blobs live (`--blob-store`; default `<data-dir>/blobs`).
    pub blob_store: BlobLocation,
    /// The `AWS_*` settings of an S3 blob store, from the environment.
    pub s3_options: S3Options,
    /// Bound on the stored results' bytes (`None`: unbounded).
    pub max_cache_bytes: Option<u64>,
    /// Results served or written this recently are never evicted.
    pub eviction_grace: Duration,
}

/// `AWS_*` settings (name, value) of the S3 blob store. Its `Debug` shows
/// the names only: the values hold credentials.
#[derive(Clone, Default, PartialEq)]
pub struct S3Options(pub Vec<(String, String)>);

impl std::fmt::Debug for S3Options {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list()
            .entries(self.0.iter().map(|(k, _)| format!("{k}=…")))
            .finish()
    }
}

/// Caps on what one spec may ask for.
#[derive(Clone, Debug, PartialEq)]
pub struct Limits {
    /// Streams: explicit `solver.streams` above it are refused; a
    /// `solver.tolerance` may pick up to it (not reaching the tolerance
    /// there fails the job with the solver's `ToleranceNotMet`).
    pub max_streams: usize,
    /// Number of layers.
    pub max_layers: usize,
    /// Number of wavelengths.
    pub max_wavelengths: usize,
    /// Length of each expansion series of an `expansion` scatterer.
    pub max_expansion_terms: usize,
    /// Largest Mie size parameter `2π r n_host/λ` (`plan::max_size_parameter`;
    /// the Mie series and expansion grow with it).
    pub max_size_parameter: f64,
    /// Values (`W·Ti·To·P·16`) of one dense export (`GET …/table?format=npy|json`).
    pub max_dense_values: usize,
    /// Direction pairs of one `POST …/eval`.
    pub max_eval_points: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_streams: 128,
            max_layers: 16,
            max_wavelengths: 128,
            max_expansion_terms: 10_000,
            max_size_parameter: 2_000.0,
            max_dense_values: 64_000_000,
            max_eval_points: 100_000,
        }
    }
}

/// Default listen address.
pub const DEFAULT_LISTEN: &str = "127.0.0.1:8080";
/// Default data directory.
pub const DEFAULT_DATA_DIR: &str = "./polbrdf-data";

impl Config {
    /// The embedded defaults for a data directory.
    pub fn with_data_dir(data_dir: impl Into<PathBuf>) -> Self {
        let data_dir = data_dir.into();
        Self {
            listen: DEFAULT_LISTEN.parse().expect("default address"),
            database_url: default_database_url(&data_dir),
            blob_store: BlobLocation::File(data_dir.join("blobs")),
            data_dir,
            workers: std::thread::available_parallelism().map_or(1, |n| n.get()),
            max_queue: 1024,
            max_body_bytes: 1 << 20,
            limits: Limits::default(),
            token: None,
            token_reads: false,
            log_format: LogFormat::Text,
            log_filter: "info".into(),
            shutdown_grace: Duration::from_secs(30),
            max_attempts: 3,
            instance_id: crate::jobs::default_instance_id(),
            lease: Duration::from_secs(30),
            s3_options: S3Options::default(),
            max_cache_bytes: None,
            eviction_grace: Duration::from_secs(60),
        }
    }
}

impl Default for Config {
    fn default() -> Self {
        Self::with_data_dir(DEFAULT_DATA_DIR)
    }
}

/// `sqlite://<data-dir>/polbrdf.sqlite`.
pub fn default_database_url(data_dir: &std::path::Path) -> String {
    format!("sqlite://{}", data_dir.join("polbrdf.sqlite").display())
}
