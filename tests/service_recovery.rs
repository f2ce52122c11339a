//! Crash/restart safety and integrity of the real `polbrdf serve`: accepted
//! jobs survive a SIGKILL and a graceful SIGTERM (exit 0), and a corrupted
//! result blob is detected, never served, and recomputed.

mod service_support;

use serde_json::Value;
use service_support::*;
use std::time::Duration;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn jobs_survive_a_crash_and_a_graceful_restart() {
    let dir = TempDir::new("restart");
    let data = dir.0.join("data");
    let c = client();
    let slow = slow_spec(3, 0.7);

    // One worker: `slow` runs, TINY waits in the queue.
    let mut s = Server::start(&data, &["--workers", "1"], &[]);
    let (code, v, _) = post(&c, &s, &slow).await;
    assert_eq!(code, 202, "{v}");
    let slow_id = v["id"].as_str().unwrap().to_string();
    wait_for(&c, &s, &slow_id, Duration::from_secs(60), |v| {
        v["status"] == "running"
    })
    .await;
    let (code, v, _) = post(&c, &s, TINY).await;
    assert_eq!(code, 202, "{v}");
    assert_eq!(v["status"], "queued");
    let tiny_id = v["id"].as_str().unwrap().to_string();

    // Crash.
    s.kill();

    // Restart: both rows are queued again and complete.
    let s = Server::start(&data, &["--workers", "1"], &[]);
    let a = wait_done(&c, &s, &slow_id).await;
    let b = wait_done(&c, &s, &tiny_id).await;
    assert_eq!(a["wall_time_ms"].as_array().unwrap().len(), 3);
    assert_eq!(b["progress"], 1.0);
    let log = s.log_text();
    assert!(
        log.contains("job left running by an earlier run; queued again"),
        "{log}"
    );

    // Graceful: SIGTERM with a running and a queued job exits 0 within the
    // grace period; whatever did not finish is solved after the restart.
    drop(s);
    let mut s = Server::start(
        &data,
        &["--workers", "1", "--shutdown-grace-secs", "0"],
        &[],
    );
    let slow2 = slow_spec(3, 0.6);
    let (_, v, _) = post(&c, &s, &slow2).await;
    let slow2_id = v["id"].as_str().unwrap().to_string();
    wait_for(&c, &s, &slow2_id, Duration::from_secs(60), |v| {
        v["status"] == "running"
    })
    .await;
    let tiny2 = TINY.replace("0.9", "0.8");
    let (_, v, _) = post(&c, &s, &tiny2).await;
    let tiny2_id = v["id"].as_str().unwrap().to_string();
    let status = s.terminate(Duration::from_secs(30));
    assert!(status.success(), "exit status {status:?}\n{}", s.log_text());

    let s = Server::start(&data, &["--workers", "1"], &[]);
    wait_done(&c, &s, &slow2_id).await;
    wait_done(&c, &s, &tiny2_id).await;
    // The earlier results are still served from the cache.
    let (code, v, _) = post(&c, &s, TINY).await;
    assert_eq!(code, 200, "{v}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_corrupted_blob_is_never_served_and_is_recomputed() {
    let dir = TempDir::new("corrupt");
    let data = dir.0.join("data");
    let s = Server::start(&data, &[], &[]);
    let c = client();
    let (_, v, _) = post(&c, &s, TINY).await;
    let id = v["id"].as_str().unwrap().to_string();
    let r = wait_done(&c, &s, &id).await;
    let digest = r["result"]["digest"].as_str().unwrap().to_string();

    // The blob lives at blobs/ab/cdef… and is named by its digest.
    let path = data.join("blobs").join(&digest[..2]).join(&digest[2..]);
    let mut bytes = std::fs::read(&path).unwrap();
    assert_eq!(sha256_hex(&bytes), digest);
    // Flip one byte, same size.
    let k = bytes.len() / 2;
    bytes[k] ^= 0x01;
    std::fs::write(&path, &bytes).unwrap();

    let url = s.url(&format!("/v1/brdfs/{id}/table"));
    let t = c.get(&url).send().await.unwrap();
    assert_eq!(t.status(), 409, "corrupt bytes must not be served");
    assert_eq!(t.headers()["content-type"], "application/problem+json");
    let p: Value = t.json().await.unwrap();
    assert_eq!(p["type"], "/problems/not-ready");

    // Solved again; the result is a deterministic function of the spec.
    wait_done(&c, &s, &id).await;
    let t = c.get(&url).send().await.unwrap();
    assert_eq!(t.status(), 200);
    assert_eq!(t.headers()["etag"], format!("\"{digest}\"").as_str());
    assert_eq!(sha256_hex(&t.bytes().await.unwrap()), digest);
    assert_eq!(metric(&c, &s, "polbrdf_solves_started_total").await, 2.0);
    assert!(metric(&c, &s, "polbrdf_blobs_invalid_total").await >= 1.0);

    // A deleted blob: the next POST sees it missing and solves again.
    std::fs::remove_file(&path).unwrap();
    let (code, v, _) = post(&c, &s, TINY).await;
    assert_eq!(code, 202, "{v}");
    wait_done(&c, &s, &id).await;
    assert_eq!(metric(&c, &s, "polbrdf_solves_started_total").await, 3.0);
}
