//! The job queue of the service: one job per spec id, solved once by one
//! instance of however many share the index.
//!
//! * **Rows are jobs** ([`crate::storage::index::queue`]). A job is its row in
//!   the index: `queued → running → done | failed`. Workers of every
//!   instance on the database *claim* queued rows (the oldest first) with a
//!   lease that they renew while they solve; a lease that lapses (its
//!   instance died) is released by any instance and the row claimed again,
//!   and a row claimed more than `--max-attempts` times without finishing
//!   is marked failed (`job-abandoned`). Progress (wavelengths done, wall
//!   time per wavelength) is written to the row as the solve advances. At
//!   start, the running rows an earlier run of this instance left are
//!   queued again, so a crash or restart loses no accepted job.
//! * **Serve-only instances** (`--workers 0`) accept and serve; the
//!   instances with workers solve. Workers wake on a local enqueue, on a
//!   `NOTIFY` from another instance (PostgreSQL), and poll every
//!   [`worker::POLL`] in case a notification was lost.
//! * **Solves never block the async runtime.** Each claimed job runs on a
//!   dedicated rayon pool (`--workers` threads; the solver's own parallel
//!   level, Fourier orders, runs inside that pool) and reports back through
//!   a tokio channel (progress) and a oneshot (outcome); an async task per
//!   job writes the row and renews the lease. The blob is written on the
//!   rayon thread, before the row says done.
//! * **Identical submissions join.** Concurrent POSTs of the same id in one
//!   process share one decision (a per-id single-flight cell); a POST that
//!   finds the row queued or running joins it, and the enqueue itself is an
//!   upsert on the id, so instances deciding at once make one row.
//! * **Per-wavelength results.** A request for several wavelengths is made
//!   of one-wavelength requests (`plan::wavelength_parts`), each stored as a
//!   result of its own under its id. A job reads the parts that are cached
//!   when it is claimed and solves only the others ([`result::solve_parts`]);
//!   a request whose parts are all cached is assembled at submission, with
//!   no solve, and answered as a cache hit naming them (`covered_by`).
//!   `polbrdf_solves_started_total` counts per-wavelength solves.
//! * **Bounded.** At most `--max-queue` rows wait for a worker (over all
//!   instances); beyond that submissions are refused
//!   ([`JobError::QueueFull`], HTTP 503).
//! * **Graceful shutdown** ([`Jobs::shutdown`]): no new claims; running jobs
//!   get a grace period to finish, and are released to the queue if they
//!   do not.

pub mod evict;
pub mod failure;
pub mod metrics;
mod parts;
pub mod result;
mod worker;

pub use failure::{FailureRecord, JobFailure};
pub use metrics::{Gauges, Metrics};

use crate::material::{self, Spec};
use crate::plan;
use crate::storage::{BlobStore, Index, JobRow, Status, StorageError, now_ms};
use parts::CachedPart;
use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::{Notify, OnceCell, Semaphore, watch};

/// Settings of the queue.
#[derive(Clone, Debug)]
pub struct JobsConfig {
    /// Solver threads (`0`: serve only, solve nothing).
    pub workers: usize,
    /// Jobs allowed to wait for a worker (over all instances).
    pub max_queue: usize,
    /// Claims of one job before it is given up (crash-loop guard).
    pub max_attempts: i64,
    /// Most streams a `solver.tolerance` may pick (`--max-streams`).
    pub max_streams: usize,
    /// This instance's id (`--instance-id`): the owner of its leases.
    pub instance_id: String,
    /// How long a claim holds without a renewal (`--lease-secs`).
    pub lease: Duration,
    /// The bound on the blobs of done rows (`--max-cache-bytes`; `None`:
    /// unbounded).
    pub max_cache_bytes: Option<u64>,
    /// Results served or written this recently are never evicted
    /// (`--eviction-grace-secs`).
    pub eviction_grace: Duration,
}

impl JobsConfig {
    /// The lease in ms (at least 1).
    fn lease_ms(&self) -> i64 {
        (self.lease.as_millis() as i64).max(1)
    }
}

/// The default instance id: the host name and the process id.
pub fn default_instance_id() -> String {
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .map(|h| h.trim().to_string())
        .filter(|h| !h.is_empty())
        .or_else(|| std::env::var("HOSTNAME").ok().filter(|h| !h.is_empty()))
        .unwrap_or_else(|| "polbrdf".into());
    format!("{host}-{}", std::process::id())
}

/// Why a submission was not accepted.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum JobError {
    /// `--max-queue` jobs are already waiting.
    #[error("the queue is full: {capacity} jobs are waiting")]
    QueueFull {
        /// The capacity.
        capacity: usize,
    },
    /// The service is stopping.
    #[error("the service is shutting down")]
    ShuttingDown,
    /// The index or blob store failed (details in the log).
    #[error("storage: {0}")]
    Storage(String),
}

impl From<StorageError> for JobError {
    fn from(e: StorageError) -> Self {
        JobError::Storage(e.to_string())
    }
}

/// The answer to a submission.
#[derive(Clone, Debug)]
pub enum Submission {
    /// The id is final in the index (done with its blob present, or failed
    /// deterministically).
    Cached {
        /// The row.
        row: Box<JobRow>,
        /// The per-wavelength results it was assembled from now (empty
        /// when the id itself was cached).
        covered_by: Vec<String>,
    },
    /// The job is queued or running (queued now or joined).
    Pending {
        /// Spec id.
        id: String,
        /// `queued` or `running`.
        status: Status,
        /// The per-wavelength results the job reuses instead of solving.
        covered_by: Vec<String>,
    },
}

#[derive(Clone, Debug)]
enum Decision {
    Cached(Box<JobRow>, Vec<String>),
    Pending(Status, Vec<String>),
}

/// The single-flight cell of one id's decision.
type Flight = OnceCell<Result<Decision, JobError>>;

/// The queue of this instance: its submissions, its workers and the jobs
/// they run.
pub struct Jobs {
    index: Index,
    blobs: Arc<BlobStore>,
    metrics: Arc<Metrics>,
    config: JobsConfig,
    pool: rayon::ThreadPool,
    flights: Mutex<HashMap<String, Arc<Flight>>>,
    /// Ids this instance is solving (under its lease).
    running: Mutex<HashSet<String>>,
    /// When this instance last recorded a serve of each result.
    touched: Mutex<HashMap<String, std::time::Instant>>,
    /// One permit per worker: a claim takes one, the job's end gives it back.
    slots: Arc<Semaphore>,
    /// Work may be waiting: a local enqueue, a notification, a release.
    wake: Notify,
    stopping: Arc<AtomicBool>,
    stop_tx: watch::Sender<bool>,
    active: watch::Sender<usize>,
}

impl std::fmt::Debug for Jobs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Jobs")
            .field("config", &self.config)
            .field("running", &self.running)
            .finish_non_exhaustive()
    }
}

impl Jobs {
    /// Build the worker pool, queue again the running rows an earlier run
    /// of this instance left, and start claiming (unless `workers` is 0)
    /// and releasing lapsed leases.
    pub async fn start(
        index: Index,
        blobs: Arc<BlobStore>,
        metrics: Arc<Metrics>,
        config: JobsConfig,
    ) -> Result<Arc<Self>, StorageError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(config.workers.max(1))
            .thread_name(|i| format!("polbrdf-solve-{i}"))
            .build()
            .map_err(|e| StorageError::Corrupt(format!("worker pool: {e}")))?;
        let released = index.release_orphans(&config.instance_id, now_ms()).await?;
        for id in &released {
            tracing::info!(%id, "job left running by an earlier run; queued again");
        }
        let listener = index.queue_listener().await?;
        let jobs = Arc::new(Self {
            index,
            blobs,
            metrics,
            slots: Arc::new(Semaphore::new(config.workers)),
            config,
            pool,
            flights: Mutex::new(HashMap::new()),
            running: Mutex::new(HashSet::new()),
            touched: Mutex::new(HashMap::new()),
            wake: Notify::new(),
            stopping: Arc::new(AtomicBool::new(false)),
            stop_tx: watch::channel(false).0,
            active: watch::channel(0).0,
        });
        jobs.clone().start_background(listener);
        Ok(jobs)
    }

    /// The index.
    pub fn index(&self) -> &Index {
        &self.index
    }

    /// The blob store.
    pub fn blobs(&self) -> &Arc<BlobStore> {
        &self.blobs
    }

    /// The metrics registry.
    pub fn metrics(&self) -> &Arc<Metrics> {
        &self.metrics
    }

    /// This instance's id.
    pub fn instance_id(&self) -> &str {
        &self.config.instance_id
    }

    /// Is the queue accepting work?
    pub fn is_stopping(&self) -> bool {
        self.stopping.load(Ordering::SeqCst)
    }

    /// Queue depth, running jobs and capacity (for /metrics).
    pub async fn gauges(&self) -> Result<Gauges, JobError> {
        let counts = self.index.counts().await?;
        let depth = self.index.queue_depth().await?;
        let (in_use, idle) = self.index.pool_connections();
        let cache_bytes = self.index.cache_bytes().await?;
        let running = self.running.lock().expect("running lock").len();
        Ok(Gauges {
            queue_depth: depth.max(0) as usize,
            queue_capacity: self.config.max_queue,
            running,
            workers: self.config.workers,
            jobs_by_state: counts.into_iter().map(|(s, n)| (s.as_str(), n)).collect(),
            instance: self.config.instance_id.clone(),
            db_connections_in_use: in_use,
            db_connections_idle: idle,
            cache_bytes,
            cache_max_bytes: self.config.max_cache_bytes,
        })
    }

    /// Submit a parsed spec with its canonical JSON and id
    /// ([`crate::plan::id_of_spec`]).
    pub async fn submit(
        self: &Arc<Self>,
        spec: &Spec,
        canonical: &str,
        id: &str,
    ) -> Result<Submission, JobError> {
        if self.is_stopping() {
            return Err(JobError::ShuttingDown);
        }
        let flight = self
            .flights
            .lock()
            .expect("flights lock")
            .entry(id.to_string())
            .or_insert_with(|| Arc::new(Flight::new()))
            .clone();
        let mut leader = false;
        let decision = flight
            .get_or_init(|| {
                leader = true;
                self.decide(spec, canonical, id)
            })
            .await
            .clone();
        // Decided: later submissions read the row.
        self.forget(id, &flight);
        match decision? {
            Decision::Cached(row, covered_by) => {
                if !leader {
                    self.metrics.cache_hits.fetch_add(1, Ordering::Relaxed);
                }
                Ok(Submission::Cached { row, covered_by })
            }
            Decision::Pending(status, covered_by) => {
                if !leader {
                    self.metrics.joined.fetch_add(1, Ordering::Relaxed);
                }
                Ok(Submission::Pending {
                    id: id.to_string(),
                    status,
                    covered_by,
                })
            }
        }
    }

    /// The leader's look-up: a final row is a cache hit, a queued or
    /// running one is joined, anything else (absent, result blob missing,
    /// retryable failure) is queued.
    async fn decide(
        self: &Arc<Self>,
        spec: &Spec,
        canonical: &str,
        id: &str,
    ) -> Result<Decision, JobError> {
        if let Some(row) = self.index.get(id).await? {
            match row.status {
                Status::Done => {
                    let present = match (&row.digest, row.size) {
                        // A result in an older format is stale: solve again.
                        _ if !result::is_current_media_type(row.media_type.as_deref()) => false,
                        (Some(d), Some(size)) => {
                            let (blobs, d) = (self.blobs.clone(), d.clone());
                            // The store not answering is an error (503/500),
                            // never a reason to solve an existing blob again.
                            tokio::task::spawn_blocking(move || {
                                blobs.looks_present(&d, size as u64)
                            })
                            .await
                            .map_err(|e| JobError::Storage(e.to_string()))?
                            .map_err(|e| JobError::Storage(e.to_string()))?
                        }
                        _ => false,
                    };
                    if present {
                        self.metrics.cache_hits.fetch_add(1, Ordering::Relaxed);
                        return Ok(Decision::Cached(Box::new(row), Vec::new()));
                    }
                    self.metrics.blobs_invalid.fetch_add(1, Ordering::Relaxed);
                    tracing::warn!(id, "result blob missing; solving again");
                }
                Status::Failed if !is_retryable(&row) => {
                    self.metrics.cache_hits.fetch_add(1, Ordering::Relaxed);
                    return Ok(Decision::Cached(Box::new(row), Vec::new()));
                }
                Status::Queued | Status::Running if row.is_current() => {
                    self.metrics.joined.fetch_add(1, Ordering::Relaxed);
                    return Ok(Decision::Pending(row.status, Vec::new()));
                }
                _ => {}
            }
        }
        let (parts, walls, covered_by) = self.part_inputs(spec).await?;
        // What is cached is assembled now: every wavelength of a request
        // (its parts), or a one-wavelength request covered by another.
        let cached: Option<Vec<CachedPart>> = if parts.is_empty() {
            self.cached_covering(spec, canonical, id)
                .await?
                .map(|c| vec![c])
        } else if covered_by.len() == parts.len() {
            Some(
                parts
                    .into_iter()
                    .zip(&walls)
                    .zip(&covered_by)
                    .map(|((p, &wall_time_ms), cover)| CachedPart {
                        bytes: p.cached.expect("every part cached"),
                        wall_time_ms,
                        id: cover.clone(),
                    })
                    .collect(),
            )
        } else {
            None
        };
        let mut covered_by = covered_by;
        if let Some(cached) = cached {
            let from: Vec<String> = cached.iter().map(|c| c.id.clone()).collect();
            let walls: Vec<f64> = cached.iter().map(|c| c.wall_time_ms).collect();
            let bytes = cached.into_iter().map(|c| c.bytes).collect();
            match self.assemble_now(canonical, id, bytes, &walls).await {
                Ok(row) => {
                    self.metrics.cache_hits.fetch_add(1, Ordering::Relaxed);
                    tracing::info!(id, from = from.len(), "answered from cached results");
                    return Ok(Decision::Cached(Box::new(row), from));
                }
                // Not expected (the parts are results of one request);
                // solve them again rather than fail the request.
                Err(e) => {
                    tracing::warn!(id, error = %e, "cached results do not assemble; solving");
                    covered_by.clear();
                }
            }
        }
        let capacity = self.config.max_queue;
        if self.index.queue_depth().await? >= capacity as i64 {
            self.metrics.rejected.fetch_add(1, Ordering::Relaxed);
            return Err(JobError::QueueFull { capacity });
        }
        let wavelengths = plan::wavelengths(spec).len() as i64;
        let queued = self
            .index
            .enqueue(id, canonical, wavelengths, now_ms())
            .await?;
        if queued {
            self.metrics.cache_misses.fetch_add(1, Ordering::Relaxed);
            tracing::info!(id, wavelengths, reused = covered_by.len(), "job queued");
            self.wake.notify_one();
        } else {
            // Another instance queued it meanwhile.
            self.metrics.joined.fetch_add(1, Ordering::Relaxed);
        }
        Ok(Decision::Pending(Status::Queued, covered_by))
    }

    /// Remove the flight of `id` if it is still this one.
    fn forget(&self, id: &str, flight: &Arc<Flight>) {
        let mut map = self.flights.lock().expect("flights lock");
        if map.get(id).is_some_and(|f| Arc::ptr_eq(f, flight)) {
            map.remove(id);
        }
    }

    /// The verified bytes of a done row's result. `None` when the blob is
    /// missing or corrupt, or the result is in an older format than
    /// [`result::is_current_media_type`]: the job is then queued again (and the bytes
    /// are never served).
    pub async fn result_bytes(self: &Arc<Self>, row: &JobRow) -> Result<Option<Vec<u8>>, JobError> {
        let bytes = match row.digest.clone() {
            Some(digest) if result::is_current_media_type(row.media_type.as_deref()) => {
                let blobs = self.blobs.clone();
                tokio::task::spawn_blocking(move || blobs.get(&digest))
                    .await
                    .map_err(|e| JobError::Storage(e.to_string()))?
                    .map_err(|e| JobError::Storage(e.to_string()))?
            }
            // No blob, or a result in an older format.
            _ => None,
        };
        if bytes.is_none() {
            tracing::warn!(id = %row.id, "result blob missing, corrupt or stale; solving again");
            if let Ok(spec) = material::parse(&row.spec) {
                // Not a cache hit: `decide` sees the blob gone and enqueues.
                match self.submit(&spec, &row.spec, &row.id).await {
                    Ok(_) | Err(JobError::QueueFull { .. }) | Err(JobError::ShuttingDown) => {}
                    Err(e) => return Err(e),
                }
            }
        }
        Ok(bytes)
    }

    /// Mark a row this instance holds failed with the record of `failure`.
    async fn fail(&self, id: &str, failure: &JobFailure, now: i64) -> Result<(), StorageError> {
        self.index
            .fail(
                id,
                &self.config.instance_id,
                &FailureRecord::of(failure).to_json(),
                now,
            )
            .await
    }

    /// Refuse new submissions and claim nothing more.
    pub fn stop_accepting(&self) {
        self.stopping.store(true, Ordering::SeqCst);
        self.stop_tx.send_replace(true);
    }

    /// Stop taking work: queued rows stay queued for any instance; running
    /// jobs get `grace` to finish and are released to the queue if they do
    /// not (this or another instance solves them again).
    pub async fn shutdown(&self, grace: Duration) {
        self.stop_accepting();
        let mut rx = self.active.subscribe();
        let drained = tokio::time::timeout(grace, rx.wait_for(|n| *n == 0)).await;
        if drained.is_err() {
            let running: Vec<String> = self
                .running
                .lock()
                .expect("running lock")
                .iter()
                .cloned()
                .collect();
            for id in running {
                tracing::warn!(%id, "job still running at shutdown; released to the queue");
                if let Err(e) = self
                    .index
                    .release(&id, &self.config.instance_id, now_ms())
                    .await
                {
                    tracing::error!(%id, error = %e, "could not release");
                }
            }
        }
    }
}

/// A failed row is solved again unless its record says the failure is
/// final (a row without a readable record is retried).
fn is_retryable(row: &JobRow) -> bool {
    FailureRecord::of_row(row).is_none_or(|r| r.retryable())
}
