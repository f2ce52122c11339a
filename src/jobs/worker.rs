//! The workers of one instance: claim a queued row, solve it on the rayon
//! pool under a renewed lease, write its outcome; and, on every instance,
//! release the leases that lapsed (docs/service.md, "The shared queue").

use super::parts::{StoredPart, store_part};
use super::result::{self, PartInput, SolveFailure};
use super::{JobFailure, Jobs};
use crate::material::{self, Spec};
use crate::plan;
use crate::storage::{BlobStore, JobRow, StorageError, index::queue::QueueListener, now_ms};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use tokio::sync::{OwnedSemaphorePermit, mpsc, oneshot};
use tracing::Instrument;

/// How often idle workers look for queued rows when no notification came.
pub const POLL: Duration = Duration::from_millis(500);

/// A claimed row, ready to solve.
struct Claimed {
    row: JobRow,
    spec: Spec,
    parts: Vec<PartInput>,
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

/// How long the outcome of a job is written again while the database
/// refuses it.
const RECORD_RETRY_FOR: Duration = Duration::from_secs(120);

/// What the row of a finished job becomes.
enum Record {
    Done {
        digest: String,
        size: i64,
        media_type: &'static str,
        wall_time_ms: Vec<f64>,
        error_estimate: Option<f64>,
    },
    Failed(JobFailure),
    Release,
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

/// The interval at which lapsed leases are looked for: a quarter of the
/// lease, within [250 ms, 5 s].
fn expiry_interval(lease: Duration) -> Duration {
    (lease / 4).clamp(Duration::from_millis(250), Duration::from_secs(5))
}

impl Jobs {
    /// The tasks of this instance: the lease expiry scan, the listener of
    /// other instances' notifications, and the claim loop when it has
    /// workers.
    pub(super) fn start_background(self: Arc<Self>, listener: Option<QueueListener>) {
        tokio::spawn(self.clone().expire_leases());
        if let Some(l) = listener {
            tokio::spawn(self.clone().listen(l));
        }
        if let Some(max) = self.config.max_cache_bytes {
            tokio::spawn(self.clone().evict_loop(max));
        }
        if self.config.workers > 0 {
            if !solves_on_the_farm_kernels() {
                tracing::warn!(
                    "this CPU lacks AVX2 or FMA: its results are correct, but may differ in the \
                     last bits from those of x86-64-v3 machines (docs/service.md, \"The same \
                     bytes on every node\"); in a farm, solve on x86-64-v3 or newer"
                );
            }
            tokio::spawn(self.dispatch());
        } else {
            tracing::info!("serve only (--workers 0): other instances solve");
        }
    }

    /// Resolve when the instance stops (at once if it has).
    pub(super) async fn stopped(&self) {
        let mut rx = self.stop_tx.subscribe();
        let _ = rx.wait_for(|s| *s).await;
    }

    /// Queue again the rows whose lease lapsed, on every instance.
    async fn expire_leases(self: Arc<Self>) {
        let every = expiry_interval(self.config.lease);
        loop {
            tokio::select! {
                _ = tokio::time::sleep(every) => {}
                _ = self.stopped() => return,
            }
            match self.index.release_expired(now_ms()).await {
                Ok(ids) if !ids.is_empty() => {
                    for id in &ids {
                        tracing::warn!(%id, "lease expired (its instance stopped renewing it); job queued again");
                    }
                    self.metrics
                        .leases_expired
                        .fetch_add(ids.len() as u64, Ordering::Relaxed);
                    self.wake.notify_one();
                }
                Ok(_) => {}
                Err(e) => tracing::warn!(error = %e, "could not look for expired leases"),
            }
        }
    }

    /// Wake the workers on other instances' notifications.
    async fn listen(self: Arc<Self>, mut listener: QueueListener) {
        loop {
            let got = tokio::select! {
                r = listener.recv() => r,
                _ = self.stopped() => return,
            };
            match got {
                Ok(()) => self.wake.notify_one(),
                Err(e) => {
                    tracing::debug!(error = %e, "queue notifications interrupted; polling meanwhile");
                    tokio::select! {
                        _ = tokio::time::sleep(Duration::from_secs(1)) => {}
                        _ = self.stopped() => return,
                    }
                }
            }
        }
    }

    /// Claim and start jobs while a worker is free.
    async fn dispatch(self: Arc<Self>) {
        loop {
            let permit = tokio::select! {
                p = self.slots.clone().acquire_owned() => p.expect("the semaphore is never closed"),
                _ = self.stopped() => return,
            };
            if self.is_stopping() {
                return;
            }
            match self.claim_one().await {
                Ok(Some(job)) => {
                    self.run(job, permit);
                    continue;
                }
                Ok(None) => {}
                Err(e) => tracing::warn!(error = %e, "could not claim a job"),
            }
            drop(permit);
            tokio::select! {
                _ = self.wake.notified() => {}
                _ = tokio::time::sleep(POLL) => {}
                _ = self.stopped() => return,
            }
        }
    }

    /// Claim the next row this instance can solve; rows past
    /// `--max-attempts` and rows whose spec no longer parses are failed on
    /// the way.
    async fn claim_one(&self) -> Result<Option<Claimed>, StorageError> {
        loop {
            let now = now_ms();
            let Some(row) = self
                .index
                .claim(&self.config.instance_id, now, self.config.lease_ms())
                .await?
            else {
                return Ok(None);
            };
            // `attempts` counts this claim: the earlier ones did not finish.
            let earlier = row.attempts - 1;
            if earlier >= self.config.max_attempts {
                tracing::error!(id = %row.id, attempts = earlier, "job abandoned");
                let failure = JobFailure::Abandoned { attempts: earlier };
                self.fail(&row.id, &failure, now).await?;
                continue;
            }
            if earlier > 0 {
                self.metrics.reclaimed.fetch_add(1, Ordering::Relaxed);
                tracing::info!(id = %row.id, attempts = row.attempts, "job claimed again");
            }
            let spec = match material::parse(&row.spec) {
                Ok(s) => s,
                Err(e) => {
                    self.fail(&row.id, &JobFailure::InvalidSpec(e), now).await?;
                    continue;
                }
            };
            // Its wavelengths cached meanwhile (or by an attempt that
            // stopped) are read, not solved again.
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
            return Ok(Some(Claimed { row, spec, parts }));
        }
    }

    /// Solve a claimed job on the pool; its task writes the row.
    fn run(self: &Arc<Self>, job: Claimed, permit: OwnedSemaphorePermit) {
        let Claimed { row, spec, parts } = job;
        let id = row.id.clone();
        let (done_tx, done_rx) = oneshot::channel::<Outcome>();
        let (event_tx, event_rx) = mpsc::unbounded_channel::<Event>();
        // A root span: a job outlives the request that queued it.
        let span =
            tracing::info_span!(parent: None, "job", id = %id, instance = %self.config.instance_id);
        self.active.send_modify(|n| *n += 1);
        self.running
            .lock()
            .expect("running lock")
            .insert(id.clone());
        // The pool thread holds what the solve needs, not the queue.
        let (blobs, stopping) = (self.blobs.clone(), self.stopping.clone());
        let max_streams = self.config.max_streams;
        let solve_span = span.clone();
        let canonical = row.spec;
        let id_for_solve = id.clone();
        self.pool.spawn(move || {
            let _entered = solve_span.enter();
            let outcome = if stopping.load(Ordering::SeqCst) {
                Outcome::Cancelled
            } else {
                let _ = event_tx.send(Event::Started);
                let job = SolveJob {
                    spec: &spec,
                    canonical: &canonical,
                    id: &id_for_solve,
                    max_streams,
                };
                solve_job(&blobs, job, parts, &event_tx)
            };
            let _ = done_tx.send(outcome);
        });
        let jobs = self.clone();
        tokio::spawn(
            async move {
                jobs.follow(&id, event_rx, done_rx).await;
                jobs.running.lock().expect("running lock").remove(&id);
                drop(permit);
                jobs.active.send_modify(|n| *n -= 1);
            }
            .instrument(span),
        );
    }

    /// Write a job's events and outcome to its row, renewing its lease
    /// meanwhile.
    async fn follow(
        &self,
        id: &str,
        mut events: mpsc::UnboundedReceiver<Event>,
        mut done: oneshot::Receiver<Outcome>,
    ) {
        let owner = self.config.instance_id.as_str();
        let lease_ms = self.config.lease_ms();
        let mut heartbeat = tokio::time::interval(self.config.lease / 3);
        heartbeat.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        heartbeat.tick().await;
        let mut lost = false;
        let mut wall = Vec::new();
        let mut progress = 0.0;
        let outcome = loop {
            tokio::select! {
                biased;
                Some(ev) = events.recv() => self.on_event(id, ev, &mut wall, &mut progress).await,
                o = &mut done => break o,
                _ = heartbeat.tick() => match self.index.renew(id, owner, now_ms() + lease_ms).await {
                    Ok(true) => {}
                    Ok(false) if !lost => {
                        lost = true;
                        tracing::warn!("lease lost (it expired and the job was queued again); solving on");
                    }
                    Ok(false) => {}
                    Err(e) => tracing::warn!(error = %e, "could not renew the lease"),
                },
            }
        };
        while let Ok(ev) = events.try_recv() {
            self.on_event(id, ev, &mut wall, &mut progress).await;
        }
        // The outcome to record, counted once however many writes it takes.
        let record = match outcome {
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
                Record::Done {
                    digest,
                    size,
                    media_type,
                    wall_time_ms,
                    error_estimate,
                }
            }
            Ok(Outcome::Failed(f)) => {
                self.metrics.solves_failed.fetch_add(1, Ordering::Relaxed);
                tracing::info!(detail = %f.message, "job failed");
                Record::Failed(JobFailure::Solve(f))
            }
            // Stopping before the solve began: back to the queue.
            Ok(Outcome::Cancelled) => Record::Release,
            Ok(Outcome::Internal(message)) => {
                self.metrics.solves_failed.fetch_add(1, Ordering::Relaxed);
                tracing::error!(%message, "job failed with an internal error");
                Record::Failed(JobFailure::Internal)
            }
            Err(_) => {
                self.metrics.solves_failed.fetch_add(1, Ordering::Relaxed);
                tracing::error!("the solve ended without an outcome");
                Record::Failed(JobFailure::NoOutcome)
            }
        };
        // The database may be down (restarting): write again with backoff
        // rather than leave the row to a lapsed lease and a second solve.
        let mut wait = Duration::from_millis(250);
        let give_up = Instant::now() + RECORD_RETRY_FOR;
        loop {
            let now = now_ms();
            let written = match &record {
                Record::Done {
                    digest,
                    size,
                    media_type,
                    wall_time_ms,
                    error_estimate,
                } => {
                    self.index
                        .finish(
                            id,
                            digest,
                            *size,
                            media_type,
                            wall_time_ms,
                            *error_estimate,
                            now,
                        )
                        .await
                }
                Record::Failed(failure) => self.fail(id, failure, now).await,
                Record::Release => self.index.release(id, owner, now).await,
            };
            match written {
                Ok(()) => return,
                Err(e) if Instant::now() + wait < give_up && !self.is_stopping() => {
                    tracing::warn!(error = %e, retry_in_ms = wait.as_millis() as u64, "could not record the job's outcome; retrying");
                    tokio::time::sleep(wait).await;
                    wait = (wait * 2).min(Duration::from_secs(5));
                }
                Err(e) => {
                    tracing::error!(error = %e, "could not record the job's outcome; its lease will lapse and it is solved again");
                    return;
                }
            }
        }
    }

    async fn on_event(&self, id: &str, ev: Event, wall: &mut Vec<f64>, progress: &mut f64) {
        let owner = self.config.instance_id.as_str();
        let now = now_ms();
        let r = match ev {
            Event::Started => {
                tracing::info!("job running");
                Ok(())
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
                        p.media_type,
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
                self.index.progress(id, owner, *progress, wall, now).await
            }
            Event::Progress(x) if x > *progress => {
                *progress = x.min(1.0);
                self.index.progress(id, owner, *progress, wall, now).await
            }
            Event::Progress(_) => Ok(()),
        };
        if let Err(e) = r {
            tracing::error!(error = %e, "could not record job progress");
        }
    }
}

/// Does this CPU run the solver's x86-64-v3 kernels (AVX2 + FMA), those of
/// every x86-64-v3 and -v4 machine? (The SIMD layer is built without its
/// AVX-512 kernels, so v4 machines run the v3 ones: the same bytes.)
fn solves_on_the_farm_kernels() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// What a pool thread solves.
struct SolveJob<'a> {
    spec: &'a Spec,
    canonical: &'a str,
    id: &'a str,
    max_streams: usize,
}

/// The solve of one job on a pool thread, its blob stored before the
/// outcome says so.
fn solve_job(
    blobs: &BlobStore,
    job: SolveJob<'_>,
    parts: Vec<PartInput>,
    event_tx: &mpsc::UnboundedSender<Event>,
) -> Outcome {
    let SolveJob {
        spec,
        canonical,
        id,
        max_streams,
    } = job;
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
            return result::solve(spec, max_streams, &on_progress, &mut on_wavelength);
        }
        result::solve_parts(
            canonical,
            id,
            parts,
            max_streams,
            result::PartSinks {
                on_solve_start: &mut || {
                    let _ = event_tx.send(Event::SolveStarted);
                },
                on_part_solved: &mut |p| match store_part(blobs, p) {
                    Ok(stored) => {
                        let _ = event_tx.send(Event::PartStored(stored));
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
    match solved {
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
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expiry_is_looked_for_a_few_times_per_lease() {
        assert_eq!(
            expiry_interval(Duration::from_secs(30)),
            Duration::from_secs(5)
        );
        assert_eq!(
            expiry_interval(Duration::from_secs(2)),
            Duration::from_millis(500)
        );
        assert_eq!(
            expiry_interval(Duration::from_millis(100)),
            Duration::from_millis(250)
        );
    }
}
