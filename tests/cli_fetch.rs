//! `polbrdf fetch` and `--cache-dir` against a real `polbrdf serve`: a miss
//! downloads and verifies, a hit asks the service nothing, eight processes
//! at once make one download, the cache works with the service stopped, a
//! corrupted file is downloaded again (or refused offline), `eval` /
//! `export` through the cache agree with a local file, and a service with
//! private reads (`--token-reads`) is read with `POLBRDF_TOKEN`.

mod service_support;

use serde_json::Value;
use service_support::*;
use std::path::Path;
use std::process::{Command, Output};

/// The direction pair the `eval` commands here ask for.
const EVAL_PAIR: [&str; 8] = [
    "--theta-i",
    "30",
    "--phi-i",
    "0",
    "--theta-o",
    "45",
    "--phi-o",
    "180",
];

const TABLE_GETS: &str =
    "polbrdf_http_requests_total{method=\"GET\",route=\"/v1/brdfs/{id}/table\",status=\"200\"}";

fn polbrdf(args: &[&str]) -> Output {
    polbrdf_with(args, None)
}

/// The binary with `POLBRDF_TOKEN` set to `token` (or unset).
fn polbrdf_with(args: &[&str], token: Option<&str>) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_polbrdf"));
    c.args(args);
    c.env_remove("POLBRDF_CACHE_DIR");
    match token {
        Some(t) => c.env("POLBRDF_TOKEN", t),
        None => c.env_remove("POLBRDF_TOKEN"),
    };
    c.output().unwrap()
}

fn ok_json(o: &Output) -> Value {
    assert!(
        o.status.success(),
        "exit {:?}\nstdout {}\nstderr {}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

fn fetch(url: &str, dir: &Path, extra: &[&str]) -> Output {
    let mut a = vec!["fetch", url, "--cache-dir", dir.to_str().unwrap()];
    a.extend_from_slice(extra);
    polbrdf(&a)
}

async fn table_gets(c: &reqwest::Client, s: &Server) -> f64 {
    metrics_text(c, s)
        .await
        .lines()
        .find_map(|l| {
            l.strip_prefix(TABLE_GETS)
                .map(|v| v.trim().parse().unwrap())
        })
        .unwrap_or(0.0)
}

#[tokio::test(flavor = "multi_thread")]
async fn fetch_caches_verifies_locks_and_works_offline() {
    let data = TempDir::new("fetch-data");
    let cache = TempDir::new("fetch-cache");
    let crowd = TempDir::new("fetch-crowd");
    let scratch = TempDir::new("fetch-scratch");
    let mut s = Server::start(&data.0, &[], &[]);
    let c = client();
    let (_, v, _) = post(&c, &s, TINY).await;
    let id = v["id"].as_str().unwrap().to_string();
    let done = wait_done(&c, &s, &id).await;
    let digest = done["result"]["digest"].as_str().unwrap().to_string();
    let url = s.url(&format!("/v1/brdfs/{id}"));
    let truth = c
        .get(format!("{url}/table"))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    assert_eq!(sha256_hex(&truth), digest);
    let local = scratch.0.join("local.pbrdf");
    std::fs::write(&local, &truth).unwrap();
    let gets0 = table_gets(&c, &s).await;

    // Miss: one download, verified, stored under DIR/<id>.pbrdf.
    let v = ok_json(&fetch(&url, &cache.0, &[]));
    assert_eq!(v["cache"], "miss", "{v}");
    assert_eq!(v["id"], id.as_str());
    assert_eq!(v["sha256"], digest.as_str());
    let path = cache.0.join(format!("{id}.pbrdf"));
    assert_eq!(v["path"], path.to_str().unwrap());
    assert_eq!(std::fs::read(&path).unwrap(), truth.to_vec());
    assert!(cache.0.join(format!("{id}.lock")).exists());
    assert_eq!(std::fs::read_dir(cache.0.join("tmp")).unwrap().count(), 0);
    assert_eq!(table_gets(&c, &s).await, gets0 + 1.0);

    // Hit, also through the /table form: no request for the table.
    let v = ok_json(&fetch(&format!("{url}/table"), &cache.0, &[]));
    assert_eq!(v["cache"], "hit", "{v}");
    assert_eq!(table_gets(&c, &s).await, gets0 + 1.0);

    // Revalidation: 304, the file kept.
    let v = ok_json(&fetch(&url, &cache.0, &["--revalidate"]));
    assert_eq!(v["cache"], "revalidated", "{v}");
    assert_eq!(table_gets(&c, &s).await, gets0 + 1.0);

    // Eight processes on an empty cache: one download.
    let children: Vec<_> = (0..8)
        .map(|_| {
            Command::new(env!("CARGO_BIN_EXE_polbrdf"))
                .args(["fetch", &url, "--cache-dir", crowd.0.to_str().unwrap()])
                .env_remove("POLBRDF_CACHE_DIR")
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    let outcomes: Vec<String> = children
        .into_iter()
        .map(|ch| {
            ok_json(&ch.wait_with_output().unwrap())["cache"]
                .as_str()
                .unwrap()
                .to_string()
        })
        .collect();
    assert_eq!(
        outcomes.iter().filter(|o| *o == "miss").count(),
        1,
        "{outcomes:?}"
    );
    assert_eq!(
        outcomes.iter().filter(|o| *o == "hit").count(),
        7,
        "{outcomes:?}"
    );
    assert_eq!(table_gets(&c, &s).await, gets0 + 2.0);
    assert_eq!(
        std::fs::read(crowd.0.join(format!("{id}.pbrdf"))).unwrap(),
        truth.to_vec()
    );

    // eval and export through the cache (the env var) = on the local file.
    let eval_args = EVAL_PAIR;
    let mut a = vec!["eval", local.to_str().unwrap()];
    a.extend_from_slice(&eval_args);
    let want = ok_json(&polbrdf(&a));
    let fresh = TempDir::new("fetch-env");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_polbrdf"));
    cmd.arg("eval")
        .arg(&url)
        .args(eval_args)
        .env("POLBRDF_CACHE_DIR", &fresh.0);
    assert_eq!(ok_json(&cmd.output().unwrap()), want);
    assert!(fresh.0.join(format!("{id}.pbrdf")).exists());
    let mut a = vec!["eval", &url, "--cache-dir", cache.0.to_str().unwrap()];
    a.extend_from_slice(&eval_args);
    assert_eq!(ok_json(&polbrdf(&a)), want);
    let csv_local = scratch.0.join("local.csv");
    let csv_remote = scratch.0.join("remote.csv");
    ok_json(&polbrdf(&[
        "export",
        local.to_str().unwrap(),
        "--format",
        "csv",
        "--theta-i-deg",
        "30",
        "-o",
        csv_local.to_str().unwrap(),
    ]));
    ok_json(&polbrdf(&[
        "export",
        &url,
        "--format",
        "csv",
        "--theta-i-deg",
        "30",
        "-o",
        csv_remote.to_str().unwrap(),
        "--cache-dir",
        cache.0.to_str().unwrap(),
    ]));
    assert_eq!(
        std::fs::read(&csv_local).unwrap(),
        std::fs::read(&csv_remote).unwrap()
    );
    let gets1 = table_gets(&c, &s).await;
    assert_eq!(gets1, gets0 + 3.0, "only the fresh cache downloaded");

    // A corrupted cached file is detected and downloaded again.
    let mut bad = truth.to_vec();
    let k = bad.len() / 2;
    bad[k] ^= 0xff;
    std::fs::write(&path, &bad).unwrap();
    let o = fetch(&url, &cache.0, &[]);
    let v = ok_json(&o);
    assert_eq!(v["cache"], "miss", "{v}");
    assert!(v["discarded"].is_string(), "{v}");
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("warning"),
        "{o:?}"
    );
    assert_eq!(std::fs::read(&path).unwrap(), truth.to_vec());
    assert_eq!(table_gets(&c, &s).await, gets1 + 1.0);

    // A job that is not done: a clear error (an unknown id: 404).
    let other = "0".repeat(64);
    let o = fetch(&s.url(&format!("/v1/brdfs/{other}")), &cache.0, &[]);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("HTTP 404"),
        "{o:?}"
    );

    // Offline: the service stopped.
    s.kill();
    let v = ok_json(&fetch(&url, &cache.0, &[]));
    assert_eq!(v["cache"], "hit", "{v}");
    let o = fetch(&url, &cache.0, &["--revalidate"]);
    let v = ok_json(&o);
    assert_eq!(v["cache"], "hit", "{v}");
    assert!(
        v["revalidation_error"]
            .as_str()
            .unwrap()
            .contains("unreachable"),
        "{v}"
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("polbrdf: warning: could not revalidate"),
        "{err}"
    );
    let mut a = vec!["eval", &url, "--cache-dir", cache.0.to_str().unwrap()];
    a.extend_from_slice(&eval_args);
    assert_eq!(ok_json(&polbrdf(&a)), want);
    // … and a corrupted file offline is reported, not used.
    std::fs::write(&path, &bad).unwrap();
    let o = fetch(&url, &cache.0, &[]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("unreachable"), "{err}");
    // A URL of nothing cached, offline.
    let o = fetch(&url, &scratch.0.join("empty"), &[]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("unreachable"));
}

#[test]
fn bad_urls_and_missing_cache_dirs_are_refused() {
    let o = polbrdf(&[
        "fetch",
        "http://127.0.0.1:9/v1/brdfs/abc",
        "--cache-dir",
        "/tmp/x",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("64 lowercase hex"),
        "{o:?}"
    );
    let id = "0".repeat(64);
    let o = polbrdf(&["fetch", &format!("http://127.0.0.1:9/v1/brdfs/{id}")]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("--cache-dir"),
        "{o:?}"
    );
}

#[tokio::test(flavor = "multi_thread")]
async fn a_service_with_private_reads_is_read_with_polbrdf_token() {
    let data = TempDir::new("fetch-private");
    let cache = TempDir::new("fetch-private-cache");
    let s = Server::start(&data.0, &["--token-reads"], &[("POLBRDF_TOKEN", "s3cret")]);
    let mut h = reqwest::header::HeaderMap::new();
    h.insert(
        reqwest::header::AUTHORIZATION,
        "Bearer s3cret".parse().unwrap(),
    );
    let c = reqwest::Client::builder()
        .default_headers(h)
        .build()
        .unwrap();
    let (code, v, _) = post(&c, &s, TINY).await;
    assert!(code == 200 || code == 202, "{code} {v}");
    let id = v["id"].as_str().unwrap().to_string();
    wait_done(&c, &s, &id).await;
    let url = s.url(&format!("/v1/brdfs/{id}"));
    let mut eval = vec!["eval", url.as_str()];
    eval.extend(EVAL_PAIR);
    // Without the token every read is refused, and the message says why.
    for o in [
        polbrdf_with(&eval, None),
        polbrdf_with(
            &["fetch", &url, "--cache-dir", cache.0.to_str().unwrap()],
            None,
        ),
    ] {
        assert!(!o.status.success(), "{o:?}");
        assert!(String::from_utf8_lossy(&o.stderr).contains("401"), "{o:?}");
    }
    // With it: a download, and a fetch through the cache (miss, then hit).
    let direct = ok_json(&polbrdf_with(&eval, Some("s3cret")));
    let f = ok_json(&polbrdf_with(
        &["fetch", &url, "--cache-dir", cache.0.to_str().unwrap()],
        Some("s3cret"),
    ));
    assert_eq!(f["cache"], "miss", "{f}");
    let mut cached_eval = eval.clone();
    cached_eval.extend(["--cache-dir", cache.0.to_str().unwrap()]);
    let cached = ok_json(&polbrdf_with(&cached_eval, Some("s3cret")));
    assert_eq!(cached["mueller"], direct["mueller"]);
    let again = ok_json(&polbrdf_with(
        &[
            "fetch",
            &url,
            "--cache-dir",
            cache.0.to_str().unwrap(),
            "--revalidate",
        ],
        Some("s3cret"),
    ));
    assert_eq!(again["cache"], "revalidated", "{again}");
}
