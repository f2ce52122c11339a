//! A small hand-written Prometheus registry (text exposition format 0.0.4):
//! HTTP requests and latencies, cache hits/misses, solves and their
//! duration. Gauges that are state (queue depth, jobs by state) are read at
//! scrape time and passed to [`Metrics::render`].

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// Upper bounds (seconds) of the request-latency histogram.
const LATENCY_BUCKETS: [f64; 10] = [0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.5, 1.0, 5.0];
/// Upper bounds (seconds) of the blob-store request histogram.
const BLOB_BUCKETS: [f64; 11] = [
    0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 1.0, 5.0,
];
/// Upper bounds (seconds) of the solve-duration histogram.
const SOLVE_BUCKETS: [f64; 8] = [0.01, 0.1, 1.0, 10.0, 60.0, 300.0, 1800.0, 7200.0];

#[derive(Clone, Debug, Default)]
struct Histogram {
    counts: Vec<u64>,
    sum: f64,
    count: u64,
}

impl Histogram {
    fn observe(&mut self, bounds: &[f64], v: f64) {
        if self.counts.is_empty() {
            self.counts = vec![0; bounds.len()];
        }
        for (c, b) in self.counts.iter_mut().zip(bounds) {
            if v <= *b {
                *c += 1;
            }
        }
        self.sum += v;
        self.count += 1;
    }

    fn render(&self, out: &mut String, name: &str, labels: &str, bounds: &[f64]) {
        let sep = if labels.is_empty() { "" } else { "," };
        for (i, b) in bounds.iter().enumerate() {
            let c = self.counts.get(i).copied().unwrap_or(0);
            let _ = writeln!(out, "{name}_bucket{{{labels}{sep}le=\"{b}\"}} {c}");
        }
        let _ = writeln!(
            out,
            "{name}_bucket{{{labels}{sep}le=\"+Inf\"}} {}",
            self.count
        );
        let braces = if labels.is_empty() {
            String::new()
        } else {
            format!("{{{labels}}}")
        };
        let _ = writeln!(out, "{name}_sum{braces} {}", self.sum);
        let _ = writeln!(out, "{name}_count{braces} {}", self.count);
    }
}

/// The registry.
#[derive(Debug, Default)]
pub struct Metrics {
    requests: Mutex<BTreeMap<(String, String, u16), u64>>,
    latency: Mutex<BTreeMap<String, Histogram>>,
    solve_seconds: Mutex<Histogram>,
    blob_seconds: Mutex<BTreeMap<&'static str, Histogram>>,
    /// POSTs answered from the index (result or final failure).
    pub cache_hits: AtomicU64,
    /// POSTs that started a solve.
    pub cache_misses: AtomicU64,
    /// POSTs that joined a queued or running job of the same id.
    pub joined: AtomicU64,
    /// POSTs refused because the queue was full.
    pub rejected: AtomicU64,
    /// Per-wavelength solves started.
    pub solves_started: AtomicU64,
    /// Solves that produced a result.
    pub solves_succeeded: AtomicU64,
    /// Solves that failed.
    pub solves_failed: AtomicU64,
    /// Stored results found missing or corrupt (and solved again).
    pub blobs_invalid: AtomicU64,
    /// Lapsed leases this instance found and released (their jobs queued
    /// again).
    pub leases_expired: AtomicU64,
    /// Claims by this instance of jobs an earlier claim did not finish.
    pub reclaimed: AtomicU64,
    /// Results this instance evicted (`--max-cache-bytes`).
    pub evicted: AtomicU64,
}

/// Gauges read at scrape time.
#[derive(Clone, Debug, Default)]
pub struct Gauges {
    /// Jobs waiting for a worker (over every instance on the index).
    pub queue_depth: usize,
    /// Queue capacity.
    pub queue_capacity: usize,
    /// Jobs being solved (in this process).
    pub running: usize,
    /// Worker threads.
    pub workers: usize,
    /// Rows per state in the index.
    pub jobs_by_state: Vec<(&'static str, i64)>,
    /// This instance's id (the `instance` label).
    pub instance: String,
    /// Database connections of the pool in use.
    pub db_connections_in_use: u32,
    /// Idle database connections of the pool.
    pub db_connections_idle: u32,
    /// Bytes of the blobs done rows point at.
    pub cache_bytes: i64,
    /// `--max-cache-bytes` (`None`: unbounded).
    pub cache_max_bytes: Option<u64>,
}

impl Metrics {
    /// Count one HTTP request (`route` is the matched route template).
    pub fn observe_request(&self, method: &str, route: &str, status: u16, seconds: f64) {
        *self
            .requests
            .lock()
            .expect("metrics lock")
            .entry((method.to_string(), route.to_string(), status))
            .or_default() += 1;
        self.latency
            .lock()
            .expect("metrics lock")
            .entry(route.to_string())
            .or_default()
            .observe(&LATENCY_BUCKETS, seconds);
    }

    /// Record the duration of a finished solve.
    pub fn observe_solve(&self, seconds: f64) {
        self.solve_seconds
            .lock()
            .expect("metrics lock")
            .observe(&SOLVE_BUCKETS, seconds);
    }

    /// Record the duration of a blob-store call (`op`: get, put, head).
    pub fn observe_blob(&self, op: &'static str, seconds: f64) {
        self.blob_seconds
            .lock()
            .expect("metrics lock")
            .entry(op)
            .or_default()
            .observe(&BLOB_BUCKETS, seconds);
    }

    /// The exposition text.
    pub fn render(&self, g: &Gauges) -> String {
        let mut out = String::new();
        let counter = |out: &mut String, name: &str, help: &str, v: u64| {
            let _ = writeln!(
                out,
                "# HELP {name} {help}\n# TYPE {name} counter\n{name} {v}"
            );
        };
        let gauge = |out: &mut String, name: &str, help: &str, v: f64| {
            let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} gauge\n{name} {v}");
        };
        out.push_str("# HELP polbrdf_http_requests_total HTTP requests by method, route and status.\n# TYPE polbrdf_http_requests_total counter\n");
        for ((m, r, s), n) in self.requests.lock().expect("metrics lock").iter() {
            let _ = writeln!(
                out,
                "polbrdf_http_requests_total{{method=\"{m}\",route=\"{}\",status=\"{s}\"}} {n}",
                escape(r)
            );
        }
        out.push_str("# HELP polbrdf_http_request_duration_seconds HTTP request latency by route.\n# TYPE polbrdf_http_request_duration_seconds histogram\n");
        for (r, h) in self.latency.lock().expect("metrics lock").iter() {
            h.render(
                &mut out,
                "polbrdf_http_request_duration_seconds",
                &format!("route=\"{}\"", escape(r)),
                &LATENCY_BUCKETS,
            );
        }
        gauge(
            &mut out,
            "polbrdf_queue_depth",
            "Jobs waiting for a worker (over every instance on the index).",
            g.queue_depth as f64,
        );
        gauge(
            &mut out,
            "polbrdf_queue_capacity",
            "Maximum number of waiting jobs (--max-queue).",
            g.queue_capacity as f64,
        );
        gauge(
            &mut out,
            "polbrdf_jobs_running",
            "Jobs being solved by this process.",
            g.running as f64,
        );
        gauge(
            &mut out,
            "polbrdf_workers",
            "Solver threads (--workers).",
            g.workers as f64,
        );
        out.push_str(
            "# HELP polbrdf_jobs Rows of the job index by state.\n# TYPE polbrdf_jobs gauge\n",
        );
        for (s, n) in &g.jobs_by_state {
            let _ = writeln!(out, "polbrdf_jobs{{state=\"{s}\"}} {n}");
        }
        let load = |a: &AtomicU64| a.load(Ordering::Relaxed);
        counter(
            &mut out,
            "polbrdf_cache_hits_total",
            "POSTs answered from the cache (result or final failure).",
            load(&self.cache_hits),
        );
        counter(
            &mut out,
            "polbrdf_cache_misses_total",
            "POSTs that started a solve.",
            load(&self.cache_misses),
        );
        counter(
            &mut out,
            "polbrdf_jobs_joined_total",
            "POSTs that joined a queued or running job with the same id.",
            load(&self.joined),
        );
        counter(
            &mut out,
            "polbrdf_jobs_rejected_total",
            "POSTs refused because the queue was full.",
            load(&self.rejected),
        );
        counter(
            &mut out,
            "polbrdf_solves_started_total",
            "Per-wavelength solves started (a wavelength read from the cache is not one).",
            load(&self.solves_started),
        );
        counter(
            &mut out,
            "polbrdf_solves_succeeded_total",
            "Solves that stored a result.",
            load(&self.solves_succeeded),
        );
        counter(
            &mut out,
            "polbrdf_solves_failed_total",
            "Solves that failed.",
            load(&self.solves_failed),
        );
        counter(
            &mut out,
            "polbrdf_blobs_invalid_total",
            "Stored results found missing or corrupt (solved again, never served).",
            load(&self.blobs_invalid),
        );
        gauge(
            &mut out,
            "polbrdf_cache_bytes",
            "Bytes of the stored results (over every instance on the index).",
            g.cache_bytes as f64,
        );
        if let Some(max) = g.cache_max_bytes {
            gauge(
                &mut out,
                "polbrdf_cache_max_bytes",
                "The bound on the stored results (--max-cache-bytes).",
                max as f64,
            );
        }
        counter(
            &mut out,
            "polbrdf_cache_evictions_total",
            "Results this instance evicted to keep the cache within --max-cache-bytes.",
            load(&self.evicted),
        );
        let instance = escape(&g.instance);
        let _ = writeln!(
            out,
            "# HELP polbrdf_leases_expired_total Lapsed leases this instance released (their jobs queued again).\n\
             # TYPE polbrdf_leases_expired_total counter\n\
             polbrdf_leases_expired_total{{instance=\"{instance}\"}} {}",
            load(&self.leases_expired)
        );
        let _ = writeln!(
            out,
            "# HELP polbrdf_jobs_reclaimed_total Jobs this instance claimed after an earlier claim did not finish.\n\
             # TYPE polbrdf_jobs_reclaimed_total counter\n\
             polbrdf_jobs_reclaimed_total{{instance=\"{instance}\"}} {}",
            load(&self.reclaimed)
        );
        let _ = writeln!(
            out,
            "# HELP polbrdf_db_pool_connections Connections of this instance's database pool by state.\n\
             # TYPE polbrdf_db_pool_connections gauge\n\
             polbrdf_db_pool_connections{{instance=\"{instance}\",state=\"in_use\"}} {}\n\
             polbrdf_db_pool_connections{{instance=\"{instance}\",state=\"idle\"}} {}",
            g.db_connections_in_use, g.db_connections_idle
        );
        out.push_str("# HELP polbrdf_blob_store_request_duration_seconds Blob store calls of this instance by operation.\n# TYPE polbrdf_blob_store_request_duration_seconds histogram\n");
        for (op, h) in self.blob_seconds.lock().expect("metrics lock").iter() {
            h.render(
                &mut out,
                "polbrdf_blob_store_request_duration_seconds",
                &format!("instance=\"{instance}\",op=\"{op}\""),
                &BLOB_BUCKETS,
            );
        }
        out.push_str("# HELP polbrdf_solve_seconds Wall time of finished solves.\n# TYPE polbrdf_solve_seconds histogram\n");
        self.solve_seconds.lock().expect("metrics lock").render(
            &mut out,
            "polbrdf_solve_seconds",
            "",
            &SOLVE_BUCKETS,
        );
        out
    }
}

fn escape(s: &str) -> String {
    s.replace('\\', "\\\\").replace('"', "\\\"")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_counters_and_histograms() {
        let m = Metrics::default();
        m.observe_request("GET", "/v1/brdfs/{id}", 200, 0.003);
        m.observe_request("GET", "/v1/brdfs/{id}", 200, 0.2);
        m.observe_solve(2.0);
        m.cache_hits.fetch_add(3, Ordering::Relaxed);
        let t = m.render(&Gauges {
            queue_depth: 2,
            jobs_by_state: vec![("done", 5)],
            ..Default::default()
        });
        assert!(t.contains(
            "polbrdf_http_requests_total{method=\"GET\",route=\"/v1/brdfs/{id}\",status=\"200\"} 2"
        ));
        assert!(t.contains(
            "polbrdf_http_request_duration_seconds_bucket{route=\"/v1/brdfs/{id}\",le=\"0.005\"} 1"
        ));
        assert!(t.contains(
            "polbrdf_http_request_duration_seconds_bucket{route=\"/v1/brdfs/{id}\",le=\"+Inf\"} 2"
        ));
        assert!(t.contains("polbrdf_solve_seconds_bucket{le=\"10\"} 1"));
        assert!(t.contains("polbrdf_solve_seconds_count 1"));
        assert!(t.contains("polbrdf_cache_hits_total 3"));
        assert!(t.contains("polbrdf_queue_depth 2"));
        assert!(t.contains("polbrdf_jobs{state=\"done\"} 5"));
        m.leases_expired.fetch_add(2, Ordering::Relaxed);
        m.observe_blob("put", 0.003);
        let t = m.render(&Gauges {
            instance: "node-\"7\"".into(),
            db_connections_in_use: 1,
            db_connections_idle: 3,
            ..Default::default()
        });
        assert!(
            t.contains("polbrdf_leases_expired_total{instance=\"node-\\\"7\\\"\"} 2"),
            "{t}"
        );
        assert!(t.contains("polbrdf_jobs_reclaimed_total{instance=\"node-\\\"7\\\"\"} 0"));
        assert!(t.contains(
            "polbrdf_blob_store_request_duration_seconds_bucket{instance=\"node-\\\"7\\\"\",op=\"put\",le=\"0.005\"} 1"
        ));
        assert!(
            t.contains("polbrdf_db_pool_connections{instance=\"node-\\\"7\\\"\",state=\"idle\"} 3")
        );
    }
}
