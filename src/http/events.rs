//! `GET /v1/events`: the queue's changes as server-sent events (the
//! console's live progress bars; docs/service.md, "Events").
//!
//! Every [`TICK`] the stream reads the index: the queued and running jobs,
//! the newest [`RECENT`] jobs (a job that is queued and done within one
//! tick is still seen) and, once, each job that left the active set (its
//! final state). A job whose state, progress or last change differs from
//! what this stream last sent is sent again, as `event: job` with a
//! [`BrdfSummary`] as data. The first events are the active jobs. Reading
//! the index rather than the local workers' channels makes every instance
//! of a farm show the whole farm's queue.

use super::AppState;
use super::error::ApiError;
use super::listing::BrdfSummary;
use crate::storage::{JobRow, Status};
use axum::extract::State;
use axum::response::sse::{Event, KeepAlive, Sse};
use futures_util::stream::{self, Stream};
use std::collections::HashMap;
use std::convert::Infallible;
use std::time::Duration;

/// How often the index is read.
pub const TICK: Duration = Duration::from_millis(500);
/// The newest jobs read each tick besides the active ones.
const RECENT: i64 = 20;

/// What a job looked like when it was last sent.
type Seen = (Status, u64, i64);

fn seen(row: &JobRow) -> Seen {
    (row.status, row.progress.to_bits(), row.updated_at)
}

/// The per-connection state: what was sent, and which jobs were active.
struct Watch {
    state: AppState,
    sent: HashMap<String, Seen>,
    active: Vec<String>,
    pending: Vec<Event>,
    first: bool,
}

impl Watch {
    /// One read of the index: the events of what changed.
    async fn tick(&mut self) -> Vec<Event> {
        let index = self.state.0.jobs.index();
        let mut rows: Vec<JobRow> = match index.unfinished().await {
            Ok(r) => r,
            Err(e) => {
                tracing::warn!(error = %e, "events: index read failed");
                return Vec::new();
            }
        };
        let active: Vec<String> = rows.iter().map(|r| r.id.clone()).collect();
        if !self.first {
            if let Ok(recent) = index.list(None, RECENT).await {
                rows.extend(recent);
            }
            for id in &self.active {
                if !active.contains(id)
                    && let Ok(Some(row)) = index.get(id).await
                {
                    rows.push(row);
                }
            }
        }
        self.first = false;
        self.active = active;
        let mut events = Vec::new();
        for row in rows {
            let now = seen(&row);
            if self.sent.get(&row.id) == Some(&now) {
                continue;
            }
            self.sent.insert(row.id.clone(), now);
            let data = serde_json::to_string(&BrdfSummary::of_row(&row)).unwrap_or_default();
            events.push(Event::default().event("job").data(data));
        }
        // A job followed through many ticks stays in `sent`; forget the
        // final ones no longer read so the map stays the size of the queue.
        if self.sent.len() > 4 * RECENT as usize + self.active.len() {
            let active = &self.active;
            self.sent.retain(|id, (s, _, _)| {
                active.contains(id) || matches!(s, Status::Queued | Status::Running)
            });
        }
        events
    }
}

/// Live job changes, as server-sent events.
///
/// `event: job`, `data:` one listing entry (as in `GET /v1/brdfs`) each
/// time a job's state, progress or last change differs from what this
/// stream last sent; first the queued and running jobs. A comment every
/// 15 s keeps idle connections open. Browsers' `EventSource` cannot send
/// a bearer token: with `--token-reads` poll `GET /v1/brdfs?status=…`
/// instead.
#[utoipa::path(
    get,
    path = "/v1/events",
    tag = "brdfs",
    responses(
        (status = 200, description = "`text/event-stream`: `event: job` with a `BrdfSummary` as data", content_type = "text/event-stream", body = String),
        (status = 401, description = "Token required for reads (--token-reads)", body = super::problem::Problem, content_type = "application/problem+json"),
    ),
    security((), ("bearer" = []))
)]
pub async fn events(
    State(state): State<AppState>,
) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, ApiError> {
    let watch = Watch {
        state,
        sent: HashMap::new(),
        active: Vec::new(),
        pending: Vec::new(),
        first: true,
    };
    let stream = stream::unfold(watch, |mut w| async move {
        loop {
            if let Some(e) = w.pending.pop() {
                return Some((Ok(e), w));
            }
            if !w.first {
                tokio::time::sleep(TICK).await;
            }
            // A graceful shutdown waits for open connections: end here.
            if w.state.0.jobs.is_stopping() {
                return None;
            }
            let mut events = w.tick().await;
            events.reverse();
            w.pending = events;
        }
    });
    Ok(Sse::new(stream).keep_alive(KeepAlive::new().interval(Duration::from_secs(15))))
}
