//! The rows as a queue shared by every instance on one database
//! (docs/service.md, "The shared queue").
//!
//! * **Enqueue** is an upsert on the spec id ([`Index::enqueue`]): one row
//!   per id whatever the number of instances and concurrent submissions.
//! * **Claim** ([`Index::claim`]) turns the oldest queued row of the current
//!   version into a running one in one statement, and records a *lease*:
//!   the claiming instance (`--instance-id`) and an expiry. On PostgreSQL
//!   the row is locked with `FOR UPDATE SKIP LOCKED`, so instances claiming
//!   at once take different rows; SQLite has one writer.
//! * **Renew** ([`Index::renew`]): the owner pushes the expiry forward while
//!   it solves (a heartbeat); `false` tells it the lease is no longer its.
//! * **Expire** ([`Index::release_expired`]): any instance queues again the
//!   running rows whose lease lapsed (their owner died or lost the
//!   database); the next claim counts the attempt, and the jobs layer ends a
//!   crash loop after `--max-attempts` claims.
//! * **Wake-up**: on PostgreSQL an enqueue or a release sends `NOTIFY`
//!   on [`super::postgres::QUEUE_CHANNEL`] ([`QueueListener`]); workers poll
//!   as well, so a lost notification delays a job by one poll at most.
//!
//! No job-queue crate fitted (apalis and the like keep their own job table
//! keyed by a generated id): the row here is also the cached result,
//! deduplicated by its content address and carrying the job's progress.

use super::{Index, JobRow, StorageError};

/// Notifications of queued work from other instances.
#[derive(Debug)]
pub enum QueueListener {
    /// A PostgreSQL `LISTEN` connection.
    Postgres(Box<sqlx::postgres::PgListener>),
}

impl QueueListener {
    /// The next notification (after a lost connection, the listener
    /// reconnects and this returns once it is listening again or fails).
    pub async fn recv(&mut self) -> Result<(), StorageError> {
        match self {
            QueueListener::Postgres(l) => {
                l.recv().await?;
                Ok(())
            }
        }
    }
}

impl Index {
    /// Claim the oldest queued row of the current version for `owner`, with
    /// a lease until `now + lease_ms`: the row becomes running, its attempts
    /// grow by one and its progress starts again. `None` when nothing is
    /// queued (or every queued row is being claimed by another instance).
    pub async fn claim(
        &self,
        owner: &str,
        now: i64,
        lease_ms: i64,
    ) -> Result<Option<JobRow>, StorageError> {
        on_backend!(self, ix => ix.claim(owner, now, lease_ms).await)
    }

    /// Extend `owner`'s lease of running row `id` to `expires_at`; `false`
    /// when the row is no longer running under that lease (it expired and
    /// was released, or it finished).
    pub async fn renew(
        &self,
        id: &str,
        owner: &str,
        expires_at: i64,
    ) -> Result<bool, StorageError> {
        on_backend!(self, ix => ix.renew(id, owner, expires_at).await)
    }

    /// Give back `owner`'s running row `id` to the queue (a graceful
    /// shutdown that could not wait for the solve).
    pub async fn release(&self, id: &str, owner: &str, now: i64) -> Result<(), StorageError> {
        on_backend!(self, ix => ix.release(id, owner, now).await)
    }

    /// Queue again every running row whose lease lapsed before `now` (or
    /// that has none); the ids released by this call. Each row is released
    /// by one caller, however many instances call at once.
    pub async fn release_expired(&self, now: i64) -> Result<Vec<String>, StorageError> {
        on_backend!(self, ix => ix.release_expired(now).await)
    }

    /// At start: queue again the running rows an earlier run of this
    /// instance left. SQLite is one instance's file, so that is every
    /// running row; on PostgreSQL it is the rows leased to `owner` (the
    /// others belong to live instances, or expire).
    pub async fn release_orphans(
        &self,
        owner: &str,
        now: i64,
    ) -> Result<Vec<String>, StorageError> {
        on_backend!(self, ix => ix.release_orphans(owner, now).await)
    }

    /// Queued rows of the current version, over all instances.
    pub async fn queue_depth(&self) -> Result<i64, StorageError> {
        on_backend!(self, ix => ix.queue_depth().await)
    }

    /// Connections of the pool: `(in use, idle)`.
    pub fn pool_connections(&self) -> (u32, u32) {
        on_backend!(self, ix => ix.pool_connections())
    }

    /// A listener for work queued by other instances: `None` where there
    /// are none (SQLite).
    pub async fn queue_listener(&self) -> Result<Option<QueueListener>, StorageError> {
        match self {
            Index::Sqlite(_) => Ok(None),
            Index::Postgres(ix) => Ok(Some(QueueListener::Postgres(Box::new(
                ix.listener().await?,
            )))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::Status;
    use super::super::tests::on_both;
    use super::*;

    /// Enqueue is idempotent, a claim takes the oldest row once, a lease
    /// is renewed by its owner only, and a lapsed lease is released once.
    async fn claims_and_leases(url: String) {
        let ix = Index::open(&url).await.unwrap();
        let id = |c: char| c.to_string().repeat(64);
        assert!(ix.enqueue(&id('1'), "{}", 1, 10).await.unwrap());
        assert!(ix.enqueue(&id('2'), "{}", 1, 20).await.unwrap());
        // Joining a queued row leaves it as it is.
        assert!(!ix.enqueue(&id('1'), "{}", 1, 30).await.unwrap());
        assert_eq!(ix.queue_depth().await.unwrap(), 2);

        let a = ix.claim("A", 100, 1000).await.unwrap().unwrap();
        assert_eq!(a.id, id('1'), "the oldest first");
        assert_eq!(
            (
                a.status,
                a.attempts,
                a.worker.as_deref(),
                a.lease_expires_at
            ),
            (Status::Running, 1, Some("A"), Some(1100))
        );
        // Joining a running row does not reset it.
        assert!(!ix.enqueue(&id('1'), "{}", 1, 110).await.unwrap());
        let b = ix.claim("B", 120, 1000).await.unwrap().unwrap();
        assert_eq!(b.id, id('2'));
        assert_eq!(ix.claim("C", 130, 1000).await.unwrap(), None);
        assert_eq!(ix.queue_depth().await.unwrap(), 0);

        // Only the owner renews, and progress is the owner's to write.
        assert!(ix.renew(&id('1'), "A", 2000).await.unwrap());
        assert!(!ix.renew(&id('1'), "B", 9000).await.unwrap());
        ix.progress(&id('1'), "B", 0.9, &[1.0], 140).await.unwrap();
        ix.progress(&id('1'), "A", 0.5, &[2.0], 150).await.unwrap();
        let r = ix.get(&id('1')).await.unwrap().unwrap();
        assert_eq!((r.progress, r.lease_expires_at), (0.5, Some(2000)));

        // At 1500 B's lease (1120) has lapsed, A's (2000) has not.
        assert_eq!(ix.release_expired(1500).await.unwrap(), vec![id('2')]);
        assert!(ix.release_expired(1500).await.unwrap().is_empty());
        let r = ix.get(&id('2')).await.unwrap().unwrap();
        assert_eq!((r.status, r.worker, r.attempts), (Status::Queued, None, 1));
        // B finds out at its next heartbeat, and cannot fail the row.
        assert!(!ix.renew(&id('2'), "B", 9000).await.unwrap());
        ix.fail(&id('2'), "B", "{}", 1510).await.unwrap();
        assert_eq!(
            ix.get(&id('2')).await.unwrap().unwrap().status,
            Status::Queued
        );
        // The next claim counts the second attempt.
        let c = ix.claim("C", 1600, 1000).await.unwrap().unwrap();
        assert_eq!((c.id.clone(), c.attempts), (id('2'), 2));

        // A graceful release by its owner only; done clears the lease.
        ix.release(&id('2'), "A", 1700).await.unwrap();
        assert_eq!(
            ix.get(&id('2')).await.unwrap().unwrap().status,
            Status::Running
        );
        ix.release(&id('2'), "C", 1700).await.unwrap();
        assert_eq!(
            ix.get(&id('2')).await.unwrap().unwrap().status,
            Status::Queued
        );
        ix.finish(&id('1'), &"d".repeat(64), 3, "x/y", &[1.0], None, 1800)
            .await
            .unwrap();
        let r = ix.get(&id('1')).await.unwrap().unwrap();
        assert_eq!(
            (r.status, r.worker, r.lease_expires_at),
            (Status::Done, None, None)
        );
        // A done row is queued again by enqueue (its blob went missing).
        assert!(ix.enqueue(&id('1'), "{}", 1, 1900).await.unwrap());
        ix.close().await;
    }

    #[tokio::test]
    async fn claims_and_leases_on_both() {
        on_both("claims_and_leases", claims_and_leases).await;
    }

    /// Orphans at start: every running row on SQLite (one instance's
    /// file), only the instance's own on PostgreSQL.
    async fn orphans_at_start(url: String) {
        let ix = Index::open(&url).await.unwrap();
        let id = |c: char| c.to_string().repeat(64);
        for (c, at) in [('1', 10), ('2', 20)] {
            ix.enqueue(&id(c), "{}", 1, at).await.unwrap();
        }
        ix.claim("A", 100, 60_000).await.unwrap().unwrap();
        ix.claim("B", 100, 60_000).await.unwrap().unwrap();
        let released = ix.release_orphans("A", 200).await.unwrap();
        match ix.backend() {
            super::super::Backend::Sqlite => assert_eq!(released, vec![id('1'), id('2')]),
            super::super::Backend::Postgres => assert_eq!(released, vec![id('1')]),
        }
        ix.close().await;
    }

    #[tokio::test]
    async fn orphans_at_start_on_both() {
        on_both("orphans_at_start", orphans_at_start).await;
    }

    /// Instances claiming at once on PostgreSQL take distinct rows.
    #[tokio::test]
    async fn concurrent_claims_take_distinct_rows() {
        let Some(s) = super::super::tests::Scratch::postgres("concurrent_claims").await else {
            return;
        };
        let ix = Index::open(&s.url).await.unwrap();
        for i in 0..20 {
            ix.enqueue(&format!("{i:064}"), "{}", 1, i).await.unwrap();
        }
        let claimers = (0..4).map(|k| {
            let ix = ix.clone();
            tokio::spawn(async move {
                let mut mine = Vec::new();
                while let Some(r) = ix.claim(&format!("I{k}"), 100, 60_000).await.unwrap() {
                    mine.push(r.id);
                }
                mine
            })
        });
        let mut all = Vec::new();
        for c in claimers {
            all.extend(c.await.unwrap());
        }
        all.sort();
        let n = all.len();
        all.dedup();
        assert_eq!((n, all.len()), (20, 20), "each row claimed once");
        ix.close().await;
        s.remove().await;
    }
}
