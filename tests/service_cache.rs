//! The cache bound of the real `polbrdf serve` (docs/service.md, "Cache
//! size"): beyond `--max-cache-bytes` the least recently served result is
//! evicted (row marked `evicted`, retryable; blob deleted) and a later
//! POST solves it again; a recently served one is kept. `DELETE
//! /v1/brdfs/{id}` removes a final result, refuses a job in progress, and
//! needs the write token.

mod service_support;

use serde_json::Value;
use service_support::*;
use std::time::Duration;

fn tiny(albedo: f64) -> String {
    TINY.replace("\"albedo\":0.3", &format!("\"albedo\":{albedo}"))
}

async fn done_id(c: &reqwest::Client, s: &Server, spec: &str) -> (String, Value) {
    let (code, v, _) = post(c, s, spec).await;
    assert!(code == 202 || code == 200, "{code} {v}");
    let id = v["id"].as_str().unwrap().to_string();
    let done = wait_done(c, s, &id).await;
    (id, done)
}

fn blob_path(s: &Server, digest: &str) -> std::path::PathBuf {
    s.data_dir
        .join("blobs")
        .join(&digest[..2])
        .join(&digest[2..])
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_least_recently_served_result_is_evicted_and_solved_again() {
    let dir = TempDir::new("cache-bound");
    let data = dir.0.join("data");
    let c = client();
    // Measure one result's size on a server without a bound.
    let probe = Server::start(&data.with_extension("probe"), &[], &[]);
    let (_, v) = done_id(&c, &probe, &tiny(0.31)).await;
    let size = v["result"]["size"].as_u64().unwrap();
    drop(probe);

    // Room for one and a half results.
    let max = (size * 3 / 2).to_string();
    let s = Server::start(
        &data,
        &[
            "--max-cache-bytes",
            max.as_str(),
            "--eviction-grace-secs",
            "1",
        ],
        &[],
    );
    let (a, va) = done_id(&c, &s, &tiny(0.32)).await;
    let (b, vb) = done_id(&c, &s, &tiny(0.33)).await;
    let (da, db) = (
        va["result"]["digest"].as_str().unwrap().to_string(),
        vb["result"]["digest"].as_str().unwrap().to_string(),
    );
    // `a` is served after `b` was made: `b` is the least recently served.
    let t = c
        .get(s.url(&format!("/v1/brdfs/{a}/table")))
        .send()
        .await
        .unwrap();
    assert_eq!(t.status(), 200);
    let evicted = wait_for(&c, &s, &b, Duration::from_secs(30), |v| {
        v["status"] == "failed"
    })
    .await;
    assert_eq!(evicted["error"]["type"], "/problems/evicted", "{evicted}");
    assert_eq!(evicted["error"]["retryable"], true);
    assert!(!blob_path(&s, &db).exists(), "the evicted blob is deleted");
    assert!(
        blob_path(&s, &da).exists(),
        "the recently served result is kept"
    );
    let (_, kept) = get_json(&c, &s, &format!("/v1/brdfs/{a}")).await;
    assert_eq!(kept["status"], "done");
    assert_eq!(metric(&c, &s, "polbrdf_cache_evictions_total").await, 1.0);
    let size_a = va["result"]["size"].as_f64().unwrap();
    assert_eq!(metric(&c, &s, "polbrdf_cache_bytes").await, size_a);
    // Its table is gone (the job's problem says why) until it is solved again.
    let t = c
        .get(s.url(&format!("/v1/brdfs/{b}/table")))
        .send()
        .await
        .unwrap();
    assert_eq!(t.status(), 409);
    let (code, v, _) = post(&c, &s, &tiny(0.33)).await;
    assert_eq!(code, 202, "evicted means solved again: {v}");
    let again = wait_done(&c, &s, &b).await;
    assert!(blob_path(&s, again["result"]["digest"].as_str().unwrap()).exists());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn delete_removes_a_final_result_and_refuses_a_job_in_progress() {
    let dir = TempDir::new("cache-delete");
    let c = client();
    let mut s = Server::start(&dir.0.join("data"), &["--workers", "1"], &[]);
    let (id, v) = done_id(&c, &s, &tiny(0.34)).await;
    let digest = v["result"]["digest"].as_str().unwrap().to_string();
    assert!(blob_path(&s, &digest).exists());

    // An eval keeps the table in the instance's memory.
    let eval = s.url(&format!(
        "/v1/brdfs/{id}/eval?theta_i_deg=30&phi_i_deg=0&theta_o_deg=30&phi_o_deg=180"
    ));
    assert_eq!(c.get(&eval).send().await.unwrap().status(), 200);
    let url = s.url(&format!("/v1/brdfs/{id}"));
    let r = c.delete(&url).send().await.unwrap();
    assert_eq!(r.status(), 204);
    assert_eq!(
        c.get(&eval).send().await.unwrap().status(),
        404,
        "not served from memory"
    );
    assert!(!blob_path(&s, &digest).exists());
    assert_eq!(get_json(&c, &s, &format!("/v1/brdfs/{id}")).await.0, 404);
    assert_eq!(c.delete(&url).send().await.unwrap().status(), 404);
    assert_eq!(
        c.delete(s.url("/v1/brdfs/not-an-id"))
            .send()
            .await
            .unwrap()
            .status(),
        404
    );

    // A running job is not deleted.
    let (code, v, _) = post(&c, &s, &slow_spec(20, 0.65)).await;
    assert_eq!(code, 202, "{v}");
    let slow = v["id"].as_str().unwrap().to_string();
    wait_for(&c, &s, &slow, Duration::from_secs(30), |v| {
        v["status"] == "running"
    })
    .await;
    let r = c
        .delete(s.url(&format!("/v1/brdfs/{slow}")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 409);
    let p: Value = r.json().await.unwrap();
    assert_eq!(p["type"], "/problems/job-in-progress", "{p}");
    s.kill();

    // With a token, DELETE needs it.
    let s = Server::start(&dir.0.join("data2"), &[], &[("POLBRDF_TOKEN", "s3cret")]);
    let r = c
        .post(s.url("/v1/brdfs"))
        .header("content-type", "application/json")
        .header("authorization", "Bearer s3cret")
        .body(tiny(0.35))
        .send()
        .await
        .unwrap();
    let id = r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    wait_done(&c, &s, &id).await;
    let url = s.url(&format!("/v1/brdfs/{id}"));
    assert_eq!(c.delete(&url).send().await.unwrap().status(), 401);
    let r = c
        .delete(&url)
        .header("authorization", "Bearer s3cret")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 204);
}
