//! A miniature render farm of real `polbrdf serve` processes on one
//! PostgreSQL index and one blob store (docs/service.md, "The shared
//! queue"): two worker instances and a serve-only one (`--workers 0`).
//! Work submitted anywhere is solved once, somewhere; every instance serves
//! every result; a job whose instance is killed is finished by another
//! after its lease lapses. Needs `POLBRDF_TEST_DATABASE_URL`
//! (service_support/postgres.rs: SKIPPED without it, a failure under
//! `CI=true`).

mod service_support;

use service_support::postgres::PgSchema;
use service_support::*;
use std::collections::BTreeSet;
use std::time::Duration;

/// A distinct quick spec per `i`.
fn tiny(i: usize) -> String {
    format!(
        r#"{{"layers":[{{"optical_thickness":0.5,"scatterer":{{"rayleigh":{{"albedo":0.9}}}}}}],
            "base":{{"lambertian":{{"albedo":{}}}}},"solver":{{"streams":4}}}}"#,
        0.2 + 0.01 * i as f64
    )
}

/// Three instances on one schema and one data directory (the blob store
/// they share); `workers[k]` threads each, `--lease-secs lease`.
fn farm(pg: &PgSchema, data: &std::path::Path, workers: [&str; 3], lease: &str) -> Vec<Server> {
    workers
        .iter()
        .enumerate()
        .map(|(k, w)| {
            let instance = format!("farm-{k}");
            Server::start(
                data,
                &[
                    "--database-url",
                    pg.url.as_str(),
                    "--workers",
                    w,
                    "--instance-id",
                    instance.as_str(),
                    "--lease-secs",
                    lease,
                ],
                &[],
            )
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn three_instances_solve_each_spec_once_and_serve_every_result() {
    let Some(pg) = PgSchema::create("service_farm_once").await else {
        return;
    };
    let dir = TempDir::new("farm-once");
    let data = dir.0.join("data");
    let servers = farm(&pg, &data, ["1", "1", "0"], "30");
    let c = client();

    // 30 distinct specs, round-robin over the instances (a third of them
    // to the serve-only one).
    let mut ids = Vec::new();
    for i in 0..30 {
        let s = &servers[i % 3];
        let (code, v, _) = post(&c, s, &tiny(i)).await;
        assert!(code == 202 || code == 200, "{code} {v}");
        ids.push(v["id"].as_str().unwrap().to_string());
    }
    for (i, id) in ids.iter().enumerate() {
        wait_done(&c, &servers[(i + 1) % 3], id).await;
    }
    let mut solved = 0.0;
    for s in &servers {
        solved += metric(&c, s, "polbrdf_solves_succeeded_total").await;
    }
    assert_eq!(solved, 30.0, "each spec solved exactly once over the farm");
    assert_eq!(
        metric(&c, &servers[2], "polbrdf_solves_succeeded_total").await,
        0.0,
        "the serve-only instance solves nothing"
    );
    assert_eq!(pg.row_count().await, 30);

    // Every instance serves every table, with the same bytes and ETag.
    for id in &ids {
        let mut seen = BTreeSet::new();
        for s in &servers {
            let r = c
                .get(s.url(&format!("/v1/brdfs/{id}/table")))
                .send()
                .await
                .unwrap();
            assert_eq!(r.status(), 200);
            let etag = r.headers()["etag"].to_str().unwrap().to_string();
            let bytes = r.bytes().await.unwrap();
            assert_eq!(etag, format!("\"{}\"", sha256_hex(&bytes)));
            seen.insert((etag, bytes));
        }
        assert_eq!(seen.len(), 1, "one result for {id} on every instance");
    }

    // 40 concurrent identical POSTs over the three instances: one solve.
    let spec = tiny(50);
    let mut tasks = Vec::new();
    for k in 0..40 {
        let (c, url, spec) = (c.clone(), servers[k % 3].url("/v1/brdfs"), spec.clone());
        tasks.push(tokio::spawn(async move {
            let r = c
                .post(url)
                .header("content-type", "application/json")
                .body(spec)
                .send()
                .await
                .unwrap();
            let code = r.status().as_u16();
            let v: serde_json::Value = r.json().await.unwrap();
            let id = v["id"].as_str().map(str::to_string);
            (code, id.ok_or(v))
        }));
    }
    let mut one = BTreeSet::new();
    for t in tasks {
        let (code, id) = t.await.unwrap();
        assert!(code == 202 || code == 200, "{code} {id:?}");
        one.insert(id.unwrap());
    }
    assert_eq!(one.len(), 1);
    let id = one.into_iter().next().unwrap();
    wait_done(&c, &servers[2], &id).await;
    let mut solved = 0.0;
    for s in &servers {
        solved += metric(&c, s, "polbrdf_solves_succeeded_total").await;
    }
    assert_eq!(solved, 31.0, "the 40 identical POSTs made one solve");
    drop(servers);
    pg.drop_schema().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_of_a_killed_instance_is_finished_by_another_after_its_lease() {
    let Some(pg) = PgSchema::create("service_farm_kill").await else {
        return;
    };
    let dir = TempDir::new("farm-kill");
    let data = dir.0.join("data");
    let mut servers = farm(&pg, &data, ["1", "1", "0"], "2");
    let c = client();

    // ~65 ms per wavelength: a job of 100 wavelengths runs for seconds.
    let wavelengths = 100;
    let (code, v, _) = post(&c, &servers[2], &slow_spec(wavelengths, 0.55)).await;
    assert_eq!(code, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    let running = wait_for(&c, &servers[2], &id, Duration::from_secs(30), |v| {
        v["status"] == "running" && v["progress"].as_f64().unwrap() > 0.0
    })
    .await;
    // GET names the instance running it, on every instance.
    let worker = running["worker"].as_str().unwrap().to_string();
    let k: usize = worker.strip_prefix("farm-").unwrap().parse().unwrap();
    assert!(k < 2, "a worker instance runs it: {running}");
    servers[k].kill();

    // The other worker finishes it after the lease (2 s) lapses.
    let survivor = 1 - k;
    let done = wait_for(&c, &servers[2], &id, Duration::from_secs(120), |v| {
        v["status"] == "done" || v["status"] == "failed"
    })
    .await;
    assert_eq!(done["status"], "done", "{done}");
    assert!(done.get("worker").is_none(), "no worker once done: {done}");
    assert_eq!(done["wall_time_ms"].as_array().unwrap().len(), wavelengths);
    assert_eq!(pg.attempts_of(&id).await, Some(2), "the attempt is counted");
    let s = &servers[survivor];
    assert_eq!(metric(&c, s, "polbrdf_solves_succeeded_total").await, 1.0);
    assert_eq!(metric_sum(&c, s, "polbrdf_jobs_reclaimed_total").await, 1.0);
    let expired: f64 = metric_sum(&c, s, "polbrdf_leases_expired_total").await
        + metric_sum(&c, &servers[2], "polbrdf_leases_expired_total").await;
    assert_eq!(expired, 1.0, "one instance released the lapsed lease");
    // The wavelengths the killed instance stored were not solved again.
    let solved_again = metric(&c, s, "polbrdf_solves_started_total").await;
    assert!(
        solved_again < wavelengths as f64,
        "{solved_again} of {wavelengths} wavelengths solved again"
    );
    // One row per id (the request and its per-wavelength results), and no
    // temporary blob left behind.
    assert_eq!(pg.row_count().await, 1 + wavelengths as i64);
    let tmp: Vec<_> = std::fs::read_dir(data.join("blobs/tmp")).unwrap().collect();
    assert!(tmp.is_empty(), "{tmp:?}");
    // The result is served by every live instance.
    for s in [&servers[survivor], &servers[2]] {
        let r = c
            .get(s.url(&format!("/v1/brdfs/{id}/table")))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 200);
    }
    drop(servers);
    pg.drop_schema().await;
}
