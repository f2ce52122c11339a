//! How long the console's cache page takes to load on loopback with many
//! results (issue: "aim for under a second"; docs/performance.md).
//!
//! `cargo bench --bench console` (needs chromium and chromedriver, as the
//! console tests). Fills a fresh service with `POLBRDF_BENCH_RESULTS`
//! (default 1,000) distinct small results, then loads `/#/cache` in
//! headless Chromium `POLBRDF_BENCH_RUNS` times (default 5), each a fresh
//! navigation, and prints per run: the first page of entries on screen
//! (`performance.now()` at render, from the navigation start) and the
//! visible thumbnails loaded (wall time from the navigation command), the
//! first run rendering them (cold), the rest reading them (warm). Also the
//! API's own time for one page, newest first and largest first.

#[path = "../tests/console_support/mod.rs"]
mod console_support;
#[path = "../tests/service_support/mod.rs"]
mod service_support;

use console_support::{Browser, binaries};
use service_support::{Server, TempDir, client, post};
use std::time::{Duration, Instant};

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

#[tokio::main]
async fn main() {
    // `cargo bench` passes `--bench`; `cargo test --benches` would too.
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let Some((driver, chromium)) = binaries("bench console") else {
        return;
    };
    let n = env_usize("POLBRDF_BENCH_RESULTS", 1000);
    let runs = env_usize("POLBRDF_BENCH_RUNS", 5);
    let dir = TempDir::new("console-bench");
    let server = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();
    let t0 = Instant::now();
    let mut ids = Vec::with_capacity(n);
    for k in 0..n {
        let spec = format!(
            r#"{{"layers":[{{"optical_thickness":{tau},"scatterer":{{"rayleigh":{{"albedo":0.9}}}}}}],
                "base":{{"lambertian":{{"albedo":0.3}}}},"solver":{{"streams":4}}}}"#,
            tau = 0.1 + k as f64 * 1e-3
        );
        let (code, v, _) = post(&c, &server, &spec).await;
        assert!(code == 202 || code == 200, "{code} {v}");
        ids.push(v["id"].as_str().unwrap().to_string());
    }
    for id in &ids {
        service_support::wait_done(&c, &server, id).await;
    }
    println!("filled {n} results in {:.1} s", t0.elapsed().as_secs_f64());
    for (label, q) in [("newest first", ""), ("largest first", "&sort=size")] {
        let mut best = f64::INFINITY;
        for _ in 0..5 {
            let t = Instant::now();
            let r = c
                .get(server.url(&format!("/v1/brdfs?limit=50{q}")))
                .send()
                .await
                .unwrap();
            assert!(r.status().is_success());
            r.bytes().await.unwrap();
            best = best.min(t.elapsed().as_secs_f64() * 1e3);
        }
        println!("GET /v1/brdfs?limit=50 ({label}): {best:.1} ms (best of 5)");
    }
    let b = Browser::start(&driver, &chromium, &dir.0, (1366, 860)).await;
    let url = format!("{}/#/cache", server.base);
    for run in 0..runs {
        b.client.goto("about:blank").await.unwrap();
        let t = Instant::now();
        b.client.goto(&url).await.unwrap();
        let first_page_ms = b
            .wait_until(
                "the first page",
                "return document.body.dataset.cacheLoadedMs",
                Duration::from_secs(60),
            )
            .await;
        b.wait_until(
            "the visible thumbnails",
            "const imgs = [...document.querySelectorAll('#results img.thumb')] \
               .filter(i => i.getBoundingClientRect().top < innerHeight); \
             return imgs.length > 0 && imgs.every(i => i.dataset.loaded);",
            Duration::from_secs(120),
        )
        .await;
        let thumbs_ms = t.elapsed().as_secs_f64() * 1e3;
        let rows = b
            .client
            .execute(
                "return document.querySelectorAll('#results tr').length",
                vec![],
            )
            .await
            .unwrap();
        println!(
            "run {run} ({}): first page ({rows} rows) {} ms; visible thumbnails {thumbs_ms:.0} ms",
            if run == 0 { "cold" } else { "warm" },
            first_page_ms.as_str().unwrap()
        );
    }
    b.close().await;
}
