//! The index's part in bounding the cache (`--max-cache-bytes`,
//! docs/service.md "Cache size"): when each result was last served, the
//! bytes the done rows hold, the least recently served results, and
//! marking one evicted or deleting it. Every step is one statement, so
//! instances evicting at once evict each row once.

use super::{Index, JobRow, StorageError};

impl Index {
    /// Record that result `id` was served at `now`; written only when the
    /// stored time is older than `every_ms` (a hot result is not a write
    /// per request).
    pub async fn touch(&self, id: &str, now: i64, every_ms: i64) -> Result<(), StorageError> {
        on_backend!(self, ix => ix.touch(id, now, every_ms).await)
    }

    /// Bytes of the blobs done rows point at.
    pub async fn cache_bytes(&self) -> Result<i64, StorageError> {
        on_backend!(self, ix => ix.cache_bytes().await)
    }

    /// Done rows last served (or, never served, finished) before `cutoff`,
    /// least recently first: `(id, digest, size)`, at most `limit`.
    pub async fn eviction_candidates(
        &self,
        cutoff: i64,
        limit: i64,
    ) -> Result<Vec<(String, String, i64)>, StorageError> {
        on_backend!(self, ix => ix.eviction_candidates(cutoff, limit).await)
    }

    /// Mark done row `id` failed with `error_json` (the retryable
    /// `evicted` record) if it still points at `digest` and was not served
    /// since `cutoff`; `false` when it changed meanwhile (served, evicted
    /// by another instance, solved again).
    pub async fn evict(
        &self,
        id: &str,
        digest: &str,
        cutoff: i64,
        error_json: &str,
        now: i64,
    ) -> Result<bool, StorageError> {
        on_backend!(self, ix => ix.evict(id, digest, cutoff, error_json, now).await)
    }

    /// Does a done row point at this blob?
    pub async fn digest_in_use(&self, digest: &str) -> Result<bool, StorageError> {
        on_backend!(self, ix => ix.digest_in_use(digest).await)
    }

    /// Remove a final (done or failed) row; the row removed, `None` when
    /// there is none or it is queued or running.
    pub async fn delete(&self, id: &str) -> Result<Option<JobRow>, StorageError> {
        on_backend!(self, ix => ix.delete(id).await)
    }
}

#[cfg(test)]
mod tests {
    use super::super::Status;
    use super::super::tests::on_both;
    use super::*;

    /// Served times, the byte count, least-recently-served order, the
    /// conditional eviction and deletion of final rows only.
    async fn eviction_bookkeeping(url: String) {
        let ix = Index::open(&url).await.unwrap();
        let id = |c: char| c.to_string().repeat(64);
        for (c, at, size) in [('1', 10, 100), ('2', 20, 200), ('3', 30, 300)] {
            ix.enqueue(&id(c), "{}", 1, at).await.unwrap();
            ix.finish(&id(c), &format!("d{c}"), size, "x/y", &[1.0], None, at)
                .await
                .unwrap();
        }
        ix.enqueue(&id('4'), "{}", 1, 40).await.unwrap();
        assert_eq!(ix.cache_bytes().await.unwrap(), 600);
        // '1' was served at 50: now the least recent is '2' (finished 20).
        ix.touch(&id('1'), 50, 60_000).await.unwrap();
        let order: Vec<String> = ix
            .eviction_candidates(1000, 10)
            .await
            .unwrap()
            .into_iter()
            .map(|c| c.0)
            .collect();
        assert_eq!(order, [id('2'), id('3'), id('1')]);
        // Touched again within `every_ms`: not written.
        ix.touch(&id('1'), 60, 60_000).await.unwrap();
        assert_eq!(ix.eviction_candidates(55, 10).await.unwrap().len(), 3);
        // Served at or after the cutoff: not a candidate.
        assert_eq!(ix.eviction_candidates(25, 10).await.unwrap().len(), 1);

        // Evict '2' once; a stale digest or a later serve refuses.
        assert!(!ix.evict(&id('2'), "other", 1000, "{}", 70).await.unwrap());
        assert!(!ix.evict(&id('1'), "d1", 40, "{}", 70).await.unwrap());
        assert!(
            ix.evict(&id('2'), "d2", 1000, r#"{"type":"e"}"#, 70)
                .await
                .unwrap()
        );
        assert!(!ix.evict(&id('2'), "d2", 1000, "{}", 71).await.unwrap());
        let r = ix.get(&id('2')).await.unwrap().unwrap();
        assert_eq!((r.status, r.digest), (Status::Failed, None));
        assert_eq!(ix.cache_bytes().await.unwrap(), 400);
        assert!(ix.digest_in_use("d1").await.unwrap());
        assert!(!ix.digest_in_use("d2").await.unwrap());

        // Delete: final rows only.
        assert_eq!(ix.delete(&id('4')).await.unwrap(), None);
        assert_eq!(
            ix.delete(&id('3'))
                .await
                .unwrap()
                .unwrap()
                .digest
                .as_deref(),
            Some("d3")
        );
        assert_eq!(ix.get(&id('3')).await.unwrap(), None);
        assert!(ix.delete(&id('2')).await.unwrap().is_some());
        assert_eq!(ix.delete(&id('9')).await.unwrap(), None);
        ix.close().await;
    }

    #[tokio::test]
    async fn eviction_bookkeeping_on_both() {
        on_both("eviction_bookkeeping", eviction_bookkeeping).await;
    }
}
