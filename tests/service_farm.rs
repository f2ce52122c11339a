//! A miniature render farm of real `polbrdf serve` processes on one
//! PostgreSQL index and one S3-compatible bucket (docs/service.md, "The
//! shared queue"): two worker instances and a serve-only one (`--workers
//! 0`), each with a data directory of its own, as on separate machines.
//! Work submitted anywhere is solved once, somewhere; every instance serves
//! every result; a job whose instance is killed is finished by another
//! after its lease lapses; an outage of the database or of the blob store
//! loses nothing. Needs `POLBRDF_TEST_DATABASE_URL` and `POLBRDF_TEST_S3`
//! (service_support: SKIPPED without them, a failure under `CI=true`).

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

/// Three instances on one schema and one bucket, each with its own data
/// directory under `dir`; `workers[k]` threads each, `--lease-secs lease`.
fn farm(
    pg: &PgSchema,
    store: &str,
    dir: &std::path::Path,
    workers: [&str; 3],
    lease: &str,
) -> Vec<Server> {
    workers
        .iter()
        .enumerate()
        .map(|(k, w)| {
            let instance = format!("farm-{k}");
            Server::start(
                &dir.join(&instance),
                &[
                    "--database-url",
                    pg.url.as_str(),
                    "--blob-store",
                    store,
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

/// Both services of a farm test, or `None` (each skips loudly).
async fn services(test: &str) -> Option<(PgSchema, String)> {
    let store = s3_store(test);
    let pg = PgSchema::create(test).await;
    match (pg, store) {
        (Some(pg), Some(store)) => Some((pg, store)),
        (Some(pg), None) => {
            pg.drop_schema().await;
            None
        }
        _ => None,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn three_instances_solve_each_spec_once_and_serve_every_result() {
    let Some((pg, store)) = services("service_farm_once").await else {
        return;
    };
    let dir = TempDir::new("farm-once");
    let servers = farm(&pg, &store, &dir.0, ["1", "1", "0"], "30");
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
    let Some((pg, store)) = services("service_farm_kill").await else {
        return;
    };
    let dir = TempDir::new("farm-kill");
    let mut servers = farm(&pg, &store, &dir.0, ["1", "1", "0"], "2");
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
    // One row per id (the request and its per-wavelength results), one
    // object per result, each under its digest: no temporary object left.
    assert_eq!(pg.row_count().await, 1 + wavelengths as i64);
    let keys = s3_keys(&c, &store).await;
    assert_eq!(keys.len(), 1 + wavelengths, "{keys:?}");
    for k in &keys {
        let tail: Vec<&str> = k.rsplitn(3, '/').collect();
        let digest = format!("{}{}", tail[1], tail[0]);
        assert!(
            tail[1].len() == 2
                && digest.len() == 64
                && digest.bytes().all(|b| b.is_ascii_hexdigit()),
            "not a blob key: {k}"
        );
    }
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

/// The database cut off mid-job (its connections dropped, new ones refused
/// for seconds, as in a restart): readiness turns 503 while it is away and
/// 200 after, and the job that was running is done, once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_database_outage_loses_no_accepted_job() {
    let Some((pg, store)) = services("service_farm_pg_outage").await else {
        return;
    };
    // The test database is on loopback (.ci/postgres.sh): relay its port.
    let after = pg
        .url
        .split("127.0.0.1:")
        .nth(1)
        .expect("a loopback database");
    let port: u16 = after
        .split(|ch: char| !ch.is_ascii_digit())
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let proxy = proxy::Proxy::start(([127, 0, 0, 1], port).into()).await;
    let url = pg
        .url
        .replacen(&format!("127.0.0.1:{port}"), &proxy.addr.to_string(), 1);
    let dir = TempDir::new("farm-pg-outage");
    let s = Server::start(
        &dir.0.join("data"),
        &[
            "--database-url",
            url.as_str(),
            "--blob-store",
            store.as_str(),
            "--workers",
            "1",
        ],
        &[],
    );
    let c = client();
    let wavelengths = 40;
    let (code, v, _) = post(&c, &s, &slow_spec(wavelengths, 0.45)).await;
    assert_eq!(code, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    wait_for(&c, &s, &id, Duration::from_secs(30), |v| {
        v["status"] == "running"
    })
    .await;

    proxy.down();
    let ready = |c: reqwest::Client, u: String| async move {
        c.get(u).send().await.unwrap().status().as_u16()
    };
    let t0 = std::time::Instant::now();
    while ready(c.clone(), s.url("/readyz")).await != 503 {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "readiness stayed 200"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    tokio::time::sleep(Duration::from_secs(3)).await;
    proxy.up();
    let t0 = std::time::Instant::now();
    while ready(c.clone(), s.url("/readyz")).await != 200 {
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "readiness stayed 503\n{}",
            s.log_text()
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let done = wait_for(&c, &s, &id, Duration::from_secs(120), |v| {
        v["status"] == "done" || v["status"] == "failed"
    })
    .await;
    assert_eq!(done["status"], "done", "{done}\n{}", s.log_text());
    assert_eq!(
        pg.attempts_of(&id).await,
        Some(1),
        "solved by its first claim"
    );
    assert_eq!(metric(&c, &s, "polbrdf_solves_succeeded_total").await, 1.0);
    let t = c
        .get(s.url(&format!("/v1/brdfs/{id}/table")))
        .send()
        .await
        .unwrap();
    assert_eq!(t.status(), 200);
    drop(s);
    pg.drop_schema().await;
}

/// The S3 server unreachable for seconds while a job stores its blobs:
/// the writes wait it out (retries with backoff), the job is not done
/// before its blob is stored, and then it is, with every blob intact.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_s3_outage_delays_blob_writes_and_loses_nothing() {
    let Some(store) = s3_store("service_farm_s3_outage") else {
        return;
    };
    let proxy = proxy::Proxy::start(aws_endpoint_addr()).await;
    let endpoint = format!("http://{}", proxy.addr);
    let dir = TempDir::new("farm-s3-outage");
    let s = Server::start(
        &dir.0.join("data"),
        &["--blob-store", store.as_str(), "--workers", "1"],
        &[("AWS_ENDPOINT_URL", endpoint.as_str())],
    );
    let c = client();
    let wavelengths = 30;
    let (code, v, _) = post(&c, &s, &slow_spec(wavelengths, 0.35)).await;
    assert_eq!(code, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    wait_for(&c, &s, &id, Duration::from_secs(30), |v| {
        v["status"] == "running" && v["progress"].as_f64().unwrap() > 0.0
    })
    .await;

    proxy.down();
    let t0 = std::time::Instant::now();
    while t0.elapsed() < Duration::from_secs(3) {
        let (_, v) = get_json(&c, &s, &format!("/v1/brdfs/{id}")).await;
        assert_ne!(
            v["status"], "done",
            "done while its blobs could not be stored"
        );
        assert_ne!(v["status"], "failed", "{v}");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    proxy.up();
    let done = wait_for(&c, &s, &id, Duration::from_secs(120), |v| {
        v["status"] == "done" || v["status"] == "failed"
    })
    .await;
    assert_eq!(done["status"], "done", "{done}\n{}", s.log_text());
    // A write waited out the outage.
    let put_seconds = metric_sum(&c, &s, "polbrdf_blob_store_request_duration_seconds_sum").await;
    assert!(put_seconds > 2.0, "blob calls took {put_seconds} s in all");
    let t = c
        .get(s.url(&format!("/v1/brdfs/{id}/table")))
        .send()
        .await
        .unwrap();
    assert_eq!(t.status(), 200);
    let digest = done["result"]["digest"].as_str().unwrap().to_string();
    assert_eq!(sha256_hex(&t.bytes().await.unwrap()), digest);
    let keys = s3_keys(&c, &store).await;
    assert_eq!(
        keys.len(),
        1 + wavelengths,
        "{keys:?}\nlog:\n{}",
        s.log_text()
    );
}
