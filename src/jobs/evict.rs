//! Bounding the cache (`--max-cache-bytes`, docs/service.md "Cache size"):
//! when the blobs of done rows exceed the bound, the least recently served
//! results are evicted (their rows marked `evicted`, retryable, so that the
//! next submission solves them again; then their blobs deleted) down to
//! [`LOW_WATER`] of the bound. Results served or written within the grace
//! period (`--eviction-grace-secs`, default 60) are never evicted: they
//! may be in the middle of a download.
//! Every instance runs the same loop on the shared index; each row is
//! evicted by one of them (the marking is a conditional `UPDATE`).
//! `DELETE /v1/brdfs/{id}` removes one result at once ([`Jobs::delete`]).

use super::{FailureRecord, JobError, JobFailure, Jobs};
use crate::storage::{JobRow, Status, now_ms};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// Eviction stops once the cache holds at most this share of the bound.
pub const LOW_WATER: f64 = 0.9;
/// How often each instance compares the cache with its bound: half the
/// grace period, within [0.5 s, 10 s].
fn every(grace: Duration) -> Duration {
    (grace / 2).clamp(Duration::from_millis(500), Duration::from_secs(10))
}
/// Served times are written at most this often per result and instance.
const TOUCH_EVERY: Duration = Duration::from_secs(60);

/// What `DELETE` found.
#[derive(Debug, PartialEq, Eq)]
pub enum Deleted {
    /// The row (and its blob) are gone.
    Gone,
    /// No such id.
    NotFound,
    /// Queued or running: not deleted.
    InProgress(Status),
}

impl Jobs {
    /// Record that result `id` was served (at most once per [`TOUCH_EVERY`]
    /// per instance; in the background, off the request's path).
    pub fn served(self: &Arc<Self>, id: &str) {
        if self.config.max_cache_bytes.is_none() {
            return;
        }
        {
            let mut touched = self.touched.lock().expect("touched lock");
            let now = Instant::now();
            if touched
                .get(id)
                .is_some_and(|t| now.duration_since(*t) < TOUCH_EVERY)
            {
                return;
            }
            if touched.len() > 100_000 {
                touched.retain(|_, t| now.duration_since(*t) < TOUCH_EVERY);
            }
            touched.insert(id.to_string(), now);
        }
        let (jobs, id) = (self.clone(), id.to_string());
        tokio::spawn(async move {
            let every = TOUCH_EVERY.as_millis() as i64;
            if let Err(e) = jobs.index.touch(&id, now_ms(), every).await {
                tracing::debug!(%id, error = %e, "could not record a serve");
            }
        });
    }

    /// The eviction loop of this instance (when `--max-cache-bytes` is set).
    pub(super) async fn evict_loop(self: Arc<Self>, max_bytes: u64) {
        loop {
            tokio::select! {
                _ = tokio::time::sleep(every(self.config.eviction_grace)) => {}
                _ = self.stopped() => return,
            }
            if let Err(e) = self.evict_to(max_bytes).await {
                tracing::warn!(error = %e, "eviction failed");
            }
        }
    }

    /// Evict least-recently-served results until the cache holds at most
    /// [`LOW_WATER`] × `max_bytes` (if it holds more than `max_bytes`);
    /// the bytes evicted by this call.
    pub async fn evict_to(&self, max_bytes: u64) -> Result<u64, JobError> {
        let mut held = self.index.cache_bytes().await?.max(0) as u64;
        if held <= max_bytes {
            return Ok(0);
        }
        let target = (max_bytes as f64 * LOW_WATER) as u64;
        let record = FailureRecord::of(&JobFailure::Evicted).to_json();
        let mut evicted = 0;
        while held > target {
            let now = now_ms();
            let cutoff = now - self.config.eviction_grace.as_millis() as i64;
            let candidates = self.index.eviction_candidates(cutoff, 64).await?;
            if candidates.is_empty() {
                tracing::warn!(
                    held,
                    max_bytes,
                    "cache over its bound, but every result is recent"
                );
                break;
            }
            for (id, digest, size) in candidates {
                if held <= target {
                    break;
                }
                if !self.index.evict(&id, &digest, cutoff, &record, now).await? {
                    continue;
                }
                self.delete_blob_if_unused(&digest).await?;
                let size = size.max(0) as u64;
                held = held.saturating_sub(size);
                evicted += size;
                self.metrics.evicted.fetch_add(1, Ordering::Relaxed);
                tracing::info!(%id, size, "result evicted (least recently served)");
            }
        }
        Ok(evicted)
    }

    /// `DELETE /v1/brdfs/{id}`: remove a final row and its blob.
    pub async fn delete(&self, id: &str) -> Result<Deleted, JobError> {
        let Some(row) = self.index.get(id).await? else {
            return Ok(Deleted::NotFound);
        };
        if matches!(row.status, Status::Queued | Status::Running) {
            return Ok(Deleted::InProgress(row.status));
        }
        let Some(JobRow { digest, .. }) = self.index.delete(id).await? else {
            // Queued again meanwhile, or deleted by another request.
            return Ok(match self.index.get(id).await? {
                Some(r) => Deleted::InProgress(r.status),
                None => Deleted::NotFound,
            });
        };
        if let Some(d) = digest {
            self.delete_blob_if_unused(&d).await?;
        }
        tracing::info!(id, "result deleted");
        Ok(Deleted::Gone)
    }

    /// Delete a blob no done row points at any more, and its previews
    /// (the console's thumbnails).
    async fn delete_blob_if_unused(&self, digest: &str) -> Result<(), JobError> {
        if self.index.digest_in_use(digest).await? {
            return Ok(());
        }
        let mut doomed = self.index.take_previews(digest).await?;
        doomed.push(digest.to_string());
        let blobs = self.blobs.clone();
        tokio::task::spawn_blocking(move || doomed.iter().try_for_each(|d| blobs.delete(d)))
            .await
            .map_err(|e| JobError::Storage(e.to_string()))?
            .map_err(|e| JobError::Storage(e.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bound_is_checked_a_few_times_per_grace_period() {
        assert_eq!(every(Duration::from_secs(60)), Duration::from_secs(10));
        assert_eq!(every(Duration::from_secs(2)), Duration::from_secs(1));
        assert_eq!(every(Duration::ZERO), Duration::from_millis(500));
    }
}
