//! The real `polbrdf serve` on a PostgreSQL index (`--database-url
//! postgres://…`, docs/service.md "PostgreSQL"): a job is solved and its
//! table served, the same spec again is a cache hit, and the index outlives
//! a restart. Needs `POLBRDF_TEST_DATABASE_URL` (service_support/postgres.rs:
//! SKIPPED without it, a failure under `CI=true`).

mod service_support;

use service_support::postgres::PgSchema;
use service_support::*;
use std::time::Duration;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_postgres_index_serves_and_caches_results() {
    let Some(pg) = PgSchema::create("service_postgres").await else {
        return;
    };
    let dir = TempDir::new("postgres");
    let data = dir.0.join("data");
    let args = ["--database-url", pg.url.as_str()];
    let mut s = Server::start(&data, &args, &[]);
    let c = client();

    let (code, v, _) = post(&c, &s, TINY).await;
    assert_eq!(code, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    let r = wait_done(&c, &s, &id).await;
    let digest = r["result"]["digest"].as_str().unwrap().to_string();
    let t = c
        .get(s.url(&format!("/v1/brdfs/{id}/table")))
        .send()
        .await
        .unwrap();
    assert_eq!(t.status(), 200);
    assert_eq!(sha256_hex(&t.bytes().await.unwrap()), digest);

    // The row is in PostgreSQL, and no SQLite file was made.
    assert_eq!(pg.status_of(&id).await.as_deref(), Some("done"));
    assert!(!data.join("polbrdf.sqlite").exists());

    let (code, v, _) = post(&c, &s, TINY).await;
    assert_eq!(code, 200, "a cache hit: {v}");
    assert_eq!(v["result"]["digest"], digest.as_str());
    assert_eq!(metric(&c, &s, "polbrdf_solves_started_total").await, 1.0);
    assert!(s.terminate(Duration::from_secs(30)).success());

    // A new process on the same index and blobs: still a hit, no solve.
    let s = Server::start(&data, &args, &[]);
    let (code, v, _) = post(&c, &s, TINY).await;
    assert_eq!(code, 200, "{v}\nlog:\n{}", s.log_text());
    assert_eq!(metric(&c, &s, "polbrdf_solves_started_total").await, 0.0);
    drop(s);
    pg.drop_schema().await;
}
