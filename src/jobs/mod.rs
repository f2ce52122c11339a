//! The job queue of the service: one job per spec id, solved once.
//!
//! * **Rows are jobs.** A job is its row in the index ([`crate::storage`]):
//!   `queued → running → done | failed`. Progress (wavelengths done, wall
//!   time per wavelength) is written to the row as the solve advances. At
//!   start, queued and running rows are queued again ([`Jobs::start`]), so a
//!   crash or restart loses no accepted job; a row that has been started
//!   `max_attempts` times without finishing (it crashed the process each
//!   time) is marked failed instead.
//! * **Solves never block the async runtime.** Each job is spawned on a
//!   dedicated rayon pool (`--workers` threads; the solver's own parallel
//!   level, Fourier orders, runs inside that pool) and reports back through
//!   a tokio channel (progress) and a oneshot (outcome); an async task per
//!   job writes the row. The blob is written on the rayon thread.
//! * **Identical submissions join.** Concurrent POSTs of the same id share
//!   one decision (a per-id single-flight cell): the first looks the id up
//!   and enqueues it if needed, the others wait for that decision and join
//!   the same job. A job stays joinable until its row is final.
//! * **Per-wavelength results.** A request for several wavelengths is made
//!   of one-wavelength requests (`plan::wavelength_parts`), each stored as a
//!   result of its own under its id. A job reads the parts that are cached
//!   and solves only the others ([`result::solve_parts`]); a request whose
//!   parts are all cached is assembled at submission, with no solve, and
//!   answered as a cache hit naming them (`covered_by`).
//!   `polbrdf_solves_started_total` counts per-wavelength solves.
//! * **Bounded.** At most `--max-queue` jobs wait for a worker; beyond that
//!   submissions are refused ([`JobError::QueueFull`], HTTP 503).
//! * **Graceful shutdown** ([`Jobs::shutdown`]): jobs not yet started stay
//!   queued in the index; running jobs get a grace period to finish, and are
//!   re-queued in the index if they do not.

pub mod failure;
pub mod metrics;
mod parts;
pub mod result;

pub use failure::{FailureRecord, JobFailure};
pub use metrics::{Gauges, Metrics};

use crate::material::{self, Spec};
use crate::plan;
use crate::storage::{BlobStore, Index, JobRow, Status, StorageError, now_ms};
use parts::{CachedPart, StoredPart, store_part};
use result::{PartInput, SolveFailure};
use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::{OnceCell, mpsc, oneshot, watch};
use tracing::Instrument;

/// Settings of the queue.
#[derive(Clone, Debug)]
pub struct JobsConfig {
    /// Solver threads.
    pub workers: usize,
    /// Jobs allowed to wait for a worker.
    pub max_queue: usize,
    /// Starts of one job before it is given up (crash-loop guard).
    pub max_attempts: i64,
    /// Most streams a `solver.tolerance` may pick (`--max-streams`).
    pub max_streams: usize,
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
    /// The job is queued or running (started now or joined).
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
    Enqueued(Vec<String>),
}

const QUEUED: u8 = 0;
const RUNNING: u8 = 1;
const FINISHED: u8 = 2;

/// The single-flight cell of one id.
#[derive(Debug)]
struct Flight {
    decided: OnceCell<Result<Decision, JobError>>,
    state: AtomicU8,
}

impl Flight {
    fn new() -> Self {
        Self {
            decided: OnceCell::new(),
            state: AtomicU8::new(QUEUED),
        }
    }
}

/// Events from a solve to its async task.
enum Event {
    Started,
    /// A wavelength's solve starts (`polbrdf_solves_started_total`).
    SolveStarted,
    /// A per-wavelength part is solved and its blob stored: record its row
    /// now, so that it survives a later failure or a restart.
    PartStored(StoredPart),
    Wavelength {
        done: usize,
        total: usize,
        ms: f64,
    },
    /// Fraction of the whole job done (approximate, per batch of Fourier
    /// orders).
    Progress(f64),
}

/// Outcome of a solve.
enum Outcome {
    Solved {
        digest: String,
        size: i64,
        media_type: &'static str,
        wall_time_ms: Vec<f64>,
        error_estimate: Option<f64>,
        seconds: f64,
    },
    Failed(SolveFailure),
    Internal(String),
    Cancelled,
}

/// The queue, its workers and the in-flight jobs.
pub struct Jobs {
    index: Index,
    blobs: Arc<BlobStore>,
    metrics: Arc<Metrics>,
    config: JobsConfig,
    pool: rayon::ThreadPool,
    flights: Mutex<HashMap<String, Arc<Flight>>>,
    queued: AtomicUsize,
    running: AtomicUsize,
    stopping: Arc<AtomicBool>,
    active: watch::Sender<usize>,
}

impl std::fmt::Debug for Jobs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Jobs")
            .field("config", &self.config)
            .field("queued", &self.queued)
            .field("running", &self.running)
            .finish_non_exhaustive()
    }
}

impl Jobs {
    /// Build the worker pool and queue again every unfinished row of the
    /// index (crash/restart recovery).
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
        let jobs = Arc::new(Self {
            index,
            blobs,
            metrics,
            config,
            pool,
            flights: Mutex::new(HashMap::new()),
            queued: AtomicUsize::new(0),
            running: AtomicUsize::new(0),
            stopping: Arc::new(AtomicBool::new(false)),
            active: watch::channel(0).0,
        });
        jobs.recover().await?;
        Ok(jobs)
    }

    async fn recover(self: &Arc<Self>) -> Result<(), StorageError> {
        for row in self.index.unfinished().await? {
            let now = now_ms();
            if row.attempts >= self.config.max_attempts {
                tracing::error!(id = %row.id, attempts = row.attempts, "job abandoned");
                let failure = JobFailure::Abandoned {
                    attempts: row.attempts,
                };
                self.fail(&row.id, &failure, now).await?;
                continue;
            }
            let spec = match material::parse(&row.spec) {
                Ok(s) => s,
                Err(e) => {
                    self.fail(&row.id, &JobFailure::InvalidSpec(e), now).await?;
                    continue;
                }
            };
            self.index.requeue(&row.id, now).await?;
            // Its wavelengths cached meanwhile (or by the run that stopped)
            // are read, not solved again.
            let parts = match self.part_inputs(&spec).await {
                Ok((parts, _, _)) => parts,
                Err(e) => {
                    tracing::warn!(id = %row.id, error = %e, "cached wavelengths unreadable; solving all");
                    plan::wavelength_parts(&spec)
                        .into_iter()
                        .map(|part| PartInput { part, cached: None })
                        .collect()
                }
            };
            let flight = Arc::new(Flight::new());
            flight
                .decided
                .set(Ok(Decision::Enqueued(Vec::new())))
                .expect("fresh cell");
            self.flights
                .lock()
                .expect("flights lock")
                .insert(row.id.clone(), flight.clone());
            self.queued.fetch_add(1, Ordering::SeqCst);
            tracing::info!(id = %row.id, attempts = row.attempts, "job re-queued at start");
            let canonical = row.spec.clone();
            self.spawn(row.id.clone(), spec, canonical, parts, flight);
        }
        Ok(())
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

    /// Is the queue accepting work?
    pub fn is_stopping(&self) -> bool {
        self.stopping.load(Ordering::SeqCst)
    }

    /// Queue depth, running jobs and capacity (for /metrics).
    pub async fn gauges(&self) -> Result<Gauges, JobError> {
        let counts = self.index.counts().await?;
        Ok(Gauges {
            queue_depth: self.queued.load(Ordering::SeqCst),
            queue_capacity: self.config.max_queue,
            running: self.running.load(Ordering::SeqCst),
            workers: self.config.workers.max(1),
            jobs_by_state: counts.into_iter().map(|(s, n)| (s.as_str(), n)).collect(),
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
            .decided
            .get_or_init(|| {
                leader = true;
                self.decide(spec, canonical, id, flight.clone())
            })
            .await
            .clone();
        if !matches!(decision, Ok(Decision::Enqueued(_))) {
            self.forget(id, &flight);
        }
        match decision? {
            Decision::Cached(row, covered_by) => {
                if !leader {
                    self.metrics.cache_hits.fetch_add(1, Ordering::Relaxed);
                }
                Ok(Submission::Cached { row, covered_by })
            }
            Decision::Enqueued(covered_by) => {
                if !leader {
                    self.metrics.joined.fetch_add(1, Ordering::Relaxed);
                }
                let pending = |status| Submission::Pending {
                    id: id.to_string(),
                    status,
                    covered_by: covered_by.clone(),
                };
                match flight.state.load(Ordering::SeqCst) {
                    QUEUED => Ok(pending(Status::Queued)),
                    RUNNING => Ok(pending(Status::Running)),
                    // Finished while we joined: the row is final.
                    _ => match self.index.get(id).await? {
                        Some(row) => Ok(Submission::Cached {
                            row: Box::new(row),
                            covered_by,
                        }),
                        None => Err(JobError::Storage(format!("row {id} vanished"))),
                    },
                }
            }
        }
    }

    /// The leader's look-up: a final row is a cache hit, anything else
    /// (absent, result blob missing, retryable failure) is solved.
    async fn decide(
        self: &Arc<Self>,
        spec: &Spec,
        canonical: &str,
        id: &str,
        flight: Arc<Flight>,
    ) -> Result<Decision, JobError> {
        if let Some(row) = self.index.get(id).await? {
            match row.status {
                Status::Done => {
                    let present = match (&row.digest, row.size) {
                        // A result in an older format is stale: solve again.
                        _ if row.media_type.as_deref() != Some(result::MEDIA_TYPE) => false,
                        (Some(d), Some(size)) => {
                            let (blobs, d) = (self.blobs.clone(), d.clone());
                            tokio::task::spawn_blocking(move || {
                                blobs.looks_present(&d, size as u64)
                            })
                            .await
                            .unwrap_or(false)
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
                _ => {}
            }
        }
        let (mut parts, walls, mut covered_by) = self.part_inputs(spec).await?;
        // What is cached is assembled now: every wavelength of a request
        // (its parts), or a one-wavelength request covered by another.
        let cached: Option<Vec<CachedPart>> = if parts.is_empty() {
            self.cached_covering(spec, canonical, id)
                .await?
                .map(|c| vec![c])
        } else if covered_by.len() == parts.len() {
            Some(
                parts
                    .iter()
                    .zip(&walls)
                    .zip(&covered_by)
                    .map(|((p, &wall_time_ms), cover)| CachedPart {
                        bytes: p.cached.clone().expect("every part cached"),
                        wall_time_ms,
                        id: cover.clone(),
                    })
                    .collect(),
            )
        } else {
            None
        };
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
                    for p in &mut parts {
                        p.cached = None;
                    }
                    covered_by.clear();
                }
            }
        }
        self.metrics.cache_misses.fetch_add(1, Ordering::Relaxed);
        let capacity = self.config.max_queue;
        if self
            .queued
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |q| {
                (q < capacity).then_some(q + 1)
            })
            .is_err()
        {
            self.metrics.rejected.fetch_add(1, Ordering::Relaxed);
            return Err(JobError::QueueFull { capacity });
        }
        let wavelengths = plan::wavelengths(spec).len() as i64;
        if let Err(e) = self
            .index
            .enqueue(id, canonical, wavelengths, now_ms())
            .await
        {
            self.queued.fetch_sub(1, Ordering::SeqCst);
            return Err(e.into());
        }
        tracing::info!(id, wavelengths, reused = covered_by.len(), "job queued");
        self.spawn(
            id.to_string(),
            spec.clone(),
            canonical.to_string(),
            parts,
            flight,
        );
        Ok(Decision::Enqueued(covered_by))
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
    /// [`result::MEDIA_TYPE`]: the job is then queued again (and the bytes
    /// are never served).
    pub async fn result_bytes(self: &Arc<Self>, row: &JobRow) -> Result<Option<Vec<u8>>, JobError> {
        let bytes = match row.digest.clone() {
            Some(digest) if row.media_type.as_deref() == Some(result::MEDIA_TYPE) => {
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

    fn spawn(
        self: &Arc<Self>,
        id: String,
        spec: Spec,
        canonical: String,
        parts: Vec<PartInput>,
        flight: Arc<Flight>,
    ) {
        let (done_tx, done_rx) = oneshot::channel::<Outcome>();
        let (event_tx, event_rx) = mpsc::unbounded_channel::<Event>();
        // A root span: a job outlives the request that queued it.
        let span = tracing::info_span!(parent: None, "job", id = %id);
        self.active.send_modify(|n| *n += 1);
        let blobs = self.blobs.clone();
        let stopping = self.stopping.clone();
        let solve_span = span.clone();
        let max_streams = self.config.max_streams;
        let id_for_solve = id.clone();
        let blobs_for_parts = self.blobs.clone();
        self.pool.spawn(move || {
            let _entered = solve_span.enter();
            if stopping.load(Ordering::SeqCst) {
                let _ = done_tx.send(Outcome::Cancelled);
                return;
            }
            let _ = event_tx.send(Event::Started);
            let t0 = Instant::now();
            let solved = catch_unwind(AssertUnwindSafe(|| {
                // One event per percent at most: the row is written per event.
                let last = std::sync::Mutex::new(0.0_f64);
                let progress_tx = event_tx.clone();
                let on_progress = move |x: f64| {
                    let mut last = last.lock().expect("progress lock");
                    if x >= *last + 0.01 {
                        *last = x;
                        let _ = progress_tx.send(Event::Progress(x));
                    }
                };
                let mut on_wavelength = |done, total, ms| {
                    tracing::debug!(done, total, ms, "wavelength solved");
                    let _ = event_tx.send(Event::Wavelength { done, total, ms });
                };
                if parts.is_empty() {
                    let _ = event_tx.send(Event::SolveStarted);
                    return result::solve(&spec, max_streams, &on_progress, &mut on_wavelength);
                }
                let solve_tx = event_tx.clone();
                let stored_tx = event_tx.clone();
                result::solve_parts(
                    &canonical,
                    &id_for_solve,
                    parts,
                    max_streams,
                    result::PartSinks {
                        on_solve_start: &mut || {
                            let _ = solve_tx.send(Event::SolveStarted);
                        },
                        on_part_solved: &mut |p| match store_part(&blobs_for_parts, p) {
                            Ok(stored) => {
                                let _ = stored_tx.send(Event::PartStored(stored));
                            }
                            // The request's own result is still stored; the
                            // part is solved again when next needed.
                            Err(e) => tracing::error!(error = %e, "storing a wavelength's result"),
                        },
                        on_progress: &on_progress,
                        on_wavelength: &mut on_wavelength,
                    },
                )
            }));
            let outcome = match solved {
                Ok(Ok(s)) => match blobs.put(&s.bytes) {
                    Ok(digest) => Outcome::Solved {
                        digest,
                        size: s.bytes.len() as i64,
                        media_type: s.media_type,
                        wall_time_ms: s.wall_time_ms,
                        error_estimate: s.error_estimate,
                        seconds: t0.elapsed().as_secs_f64(),
                    },
                    Err(e) => Outcome::Internal(format!("storing the result: {e}")),
                },
                Ok(Err(f)) => Outcome::Failed(f),
                Err(panic) => Outcome::Internal(panic_message(panic.as_ref())),
            };
            let _ = done_tx.send(outcome);
        });
        let jobs = self.clone();
        tokio::spawn(
            async move {
                jobs.follow(&id, &flight, event_rx, done_rx).await;
                jobs.active.send_modify(|n| *n -= 1);
            }
            .instrument(span),
        );
    }

    /// Write a job's events and outcome to its row.
    async fn follow(
        &self,
        id: &str,
        flight: &Arc<Flight>,
        mut events: mpsc::UnboundedReceiver<Event>,
        mut done: oneshot::Receiver<Outcome>,
    ) {
        let mut started = false;
        let mut wall = Vec::new();
        let mut progress = 0.0;
        let outcome = loop {
            tokio::select! {
                biased;
                Some(ev) = events.recv() => self.on_event(id, flight, ev, &mut started, &mut wall, &mut progress).await,
                o = &mut done => break o,
            }
        };
        while let Ok(ev) = events.try_recv() {
            self.on_event(id, flight, ev, &mut started, &mut wall, &mut progress)
                .await;
        }
        let now = now_ms();
        let written = match outcome {
            Ok(Outcome::Solved {
                digest,
                size,
                media_type,
                wall_time_ms,
                error_estimate,
                seconds,
            }) => {
                self.metrics
                    .solves_succeeded
                    .fetch_add(1, Ordering::Relaxed);
                self.metrics.observe_solve(seconds);
                tracing::info!(%digest, size, seconds, "job done");
                self.index
                    .finish(
                        id,
                        &digest,
                        size,
                        media_type,
                        &wall_time_ms,
                        error_estimate,
                        now,
                    )
                    .await
            }
            Ok(Outcome::Failed(f)) => {
                self.metrics.solves_failed.fetch_add(1, Ordering::Relaxed);
                tracing::info!(detail = %f.message, "job failed");
                self.fail(id, &JobFailure::Solve(f), now).await
            }
            Ok(Outcome::Cancelled) => {
                // Shutdown before a worker took it: it stays queued.
                self.queued.fetch_sub(1, Ordering::SeqCst);
                self.index.requeue(id, now).await
            }
            Ok(Outcome::Internal(message)) => {
                self.metrics.solves_failed.fetch_add(1, Ordering::Relaxed);
                tracing::error!(%message, "job failed with an internal error");
                self.fail(id, &JobFailure::Internal, now).await
            }
            Err(_) => {
                self.metrics.solves_failed.fetch_add(1, Ordering::Relaxed);
                tracing::error!("the solve ended without an outcome");
                self.fail(id, &JobFailure::NoOutcome, now).await
            }
        };
        if let Err(e) = written {
            tracing::error!(error = %e, "could not record the job's outcome");
        }
        if started {
            self.running.fetch_sub(1, Ordering::SeqCst);
        }
        // Final (or back in the index as queued on shutdown): new
        // submissions read the row from now on.
        let mut map = self.flights.lock().expect("flights lock");
        flight.state.store(FINISHED, Ordering::SeqCst);
        if map.get(id).is_some_and(|f| Arc::ptr_eq(f, flight)) {
            map.remove(id);
        }
    }

    async fn on_event(
        &self,
        id: &str,
        flight: &Flight,
        ev: Event,
        started: &mut bool,
        wall: &mut Vec<f64>,
        progress: &mut f64,
    ) {
        let now = now_ms();
        let r = match ev {
            Event::Started => {
                *started = true;
                self.queued.fetch_sub(1, Ordering::SeqCst);
                self.running.fetch_add(1, Ordering::SeqCst);
                flight.state.store(RUNNING, Ordering::SeqCst);
                tracing::info!("job running");
                self.index.start(id, now).await
            }
            Event::SolveStarted => {
                self.metrics.solves_started.fetch_add(1, Ordering::Relaxed);
                Ok(())
            }
            Event::PartStored(p) => {
                self.index
                    .record_done(
                        &p.id,
                        &p.canonical_json,
                        &p.digest,
                        p.size,
                        result::MEDIA_TYPE,
                        &p.wall_time_ms,
                        p.error_estimate,
                        now,
                    )
                    .await
            }
            Event::Wavelength { done, total, ms } => {
                wall.push(ms);
                let x = done as f64 / total.max(1) as f64;
                *progress = progress.max(x);
                self.index.progress(id, *progress, wall, now).await
            }
            Event::Progress(x) if x > *progress => {
                *progress = x.min(1.0);
                self.index.progress(id, *progress, wall, now).await
            }
            Event::Progress(_) => Ok(()),
        };
        if let Err(e) = r {
            tracing::error!(error = %e, "could not record job progress");
        }
    }

    /// Mark a row failed with the record of `failure`.
    async fn fail(&self, id: &str, failure: &JobFailure, now: i64) -> Result<(), StorageError> {
        self.index
            .fail(id, &FailureRecord::of(failure).to_json(), now)
            .await
    }

    /// Refuse new submissions and let workers skip jobs they have not
    /// started (they stay queued in the index).
    pub fn stop_accepting(&self) {
        self.stopping.store(true, Ordering::SeqCst);
    }

    /// Stop taking work: jobs that have not started stay queued in the
    /// index; running jobs get `grace` to finish and are re-queued in the
    /// index if they do not (the next start solves them again).
    pub async fn shutdown(&self, grace: Duration) {
        self.stop_accepting();
        let mut rx = self.active.subscribe();
        let drained = tokio::time::timeout(grace, rx.wait_for(|n| *n == 0)).await;
        if drained.is_err() {
            let running: Vec<String> = self
                .flights
                .lock()
                .expect("flights lock")
                .iter()
                .filter(|(_, f)| f.state.load(Ordering::SeqCst) == RUNNING)
                .map(|(id, _)| id.clone())
                .collect();
            for id in running {
                tracing::warn!(%id, "job still running at shutdown; re-queued");
                if let Err(e) = self.index.requeue(&id, now_ms()).await {
                    tracing::error!(%id, error = %e, "could not re-queue");
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

fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        format!("panic: {s}")
    } else if let Some(s) = p.downcast_ref::<String>() {
        format!("panic: {s}")
    } else {
        "panic".into()
    }
}
