//! Shared by tests/service_*.rs: spawn the real `polbrdf serve` binary on
//! 127.0.0.1:0 with its own data directory, read the bound address from
//! its stdout, and talk to it with reqwest.
#![allow(dead_code)]

pub mod postgres;
pub mod proxy;

use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// A Rayleigh layer on a Lambertian base, 4 streams: solves in well under a
/// second even in a debug build.
pub const TINY: &str = r#"{"layers":[{"optical_thickness":0.5,"scatterer":{"rayleigh":{"albedo":0.9}}}],
  "base":{"lambertian":{"albedo":0.3}},"solver":{"streams":4}}"#;

/// The same physics solved `n` times (one per listed wavelength): a job
/// that stays running long enough to be interrupted.
pub fn slow_spec(n: usize, albedo: f64) -> String {
    let wl: Vec<String> = (0..n).map(|i| format!("{}", 400 + 10 * i)).collect();
    format!(
        r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"rayleigh":{{"albedo":{albedo}}}}}}}],
            "wavelengths_nm":[{}],"solver":{{"streams":8}}}}"#,
        wl.join(",")
    )
}

/// A scratch directory removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(name: &str) -> Self {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_nanos();
        let p = std::env::temp_dir().join(format!(
            "polbrdf-service-{name}-{}-{nanos}",
            std::process::id()
        ));
        std::fs::create_dir_all(&p).unwrap();
        Self(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A running `polbrdf serve`.
pub struct Server {
    child: Child,
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    /// Its data directory.
    pub data_dir: PathBuf,
    /// Its log file (stderr).
    pub log: PathBuf,
}

impl Server {
    /// Start on 127.0.0.1:0 with `data_dir` and extra flags / env vars.
    pub fn start(data_dir: &Path, args: &[&str], envs: &[(&str, &str)]) -> Server {
        Self::start_under(&[], data_dir, args, envs)
    }

    /// The same, run by `wrapper` (e.g. `qemu-x86_64 -cpu Haswell`; empty:
    /// directly).
    pub fn start_under(
        wrapper: &[&str],
        data_dir: &Path,
        args: &[&str],
        envs: &[(&str, &str)],
    ) -> Server {
        let log = data_dir.with_extension(format!(
            "{}.log",
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .as_nanos()
        ));
        let binary = env!("CARGO_BIN_EXE_polbrdf");
        let mut cmd = match wrapper.split_first() {
            Some((program, rest)) => {
                let mut c = Command::new(program);
                c.args(rest).arg(binary);
                c
            }
            None => Command::new(binary),
        };
        cmd.arg("serve")
            .arg("--listen")
            .arg("127.0.0.1:0")
            .arg("--data-dir")
            .arg(data_dir)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(&log).unwrap());
        for (k, _) in std::env::vars() {
            if k.starts_with("POLBRDF_") {
                cmd.env_remove(k);
            }
        }
        cmd.env("POLBRDF_LOG", "polbrdf=debug,info");
        for (k, v) in envs {
            cmd.env(k, v);
        }
        let mut child = cmd.spawn().expect("spawn polbrdf serve");
        let stdout = child.stdout.take().unwrap();
        let mut line = String::new();
        BufReader::new(stdout).read_line(&mut line).unwrap();
        let base = line
            .trim()
            .strip_prefix("listening on ")
            .unwrap_or_else(|| {
                panic!(
                    "unexpected first line {line:?}; log:\n{}",
                    std::fs::read_to_string(&log).unwrap_or_default()
                )
            })
            .to_string();
        Server {
            child,
            base,
            data_dir: data_dir.to_path_buf(),
            log,
        }
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// SIGKILL (a crash) and reap.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// SIGTERM and wait (up to `timeout`) for the exit status.
    pub fn terminate(&mut self, timeout: Duration) -> ExitStatus {
        let ok = Command::new("kill")
            .arg("-TERM")
            .arg(self.child.id().to_string())
            .status()
            .unwrap()
            .success();
        assert!(ok, "kill -TERM failed");
        let t0 = Instant::now();
        loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                return s;
            }
            assert!(
                t0.elapsed() < timeout,
                "server did not exit within {timeout:?}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            self.kill();
        }
        let _ = std::fs::remove_file(&self.log);
    }
}

pub fn client() -> reqwest::Client {
    reqwest::Client::builder()
        .timeout(Duration::from_secs(60))
        .build()
        .unwrap()
}

/// POST a spec; returns (status, JSON body, headers).
pub async fn post(
    c: &reqwest::Client,
    s: &Server,
    body: &str,
) -> (u16, Value, reqwest::header::HeaderMap) {
    let r = c
        .post(s.url("/v1/brdfs"))
        .header("content-type", "application/json")
        .body(body.to_string())
        .send()
        .await
        .unwrap();
    let status = r.status().as_u16();
    let headers = r.headers().clone();
    let text = r.text().await.unwrap();
    let v = serde_json::from_str(&text).unwrap_or(Value::String(text));
    (status, v, headers)
}

/// GET a JSON resource.
pub async fn get_json(c: &reqwest::Client, s: &Server, path: &str) -> (u16, Value) {
    let r = c.get(s.url(path)).send().await.unwrap();
    let status = r.status().as_u16();
    let text = r.text().await.unwrap();
    (
        status,
        serde_json::from_str(&text).unwrap_or(Value::String(text)),
    )
}

/// Poll `/v1/brdfs/{id}` until `pred(resource)` holds.
pub async fn wait_for(
    c: &reqwest::Client,
    s: &Server,
    id: &str,
    timeout: Duration,
    pred: impl Fn(&Value) -> bool,
) -> Value {
    let t0 = Instant::now();
    loop {
        let (code, v) = get_json(c, s, &format!("/v1/brdfs/{id}")).await;
        if code == 200 && pred(&v) {
            return v;
        }
        assert!(
            t0.elapsed() < timeout,
            "timed out waiting on {id}: last {code} {v}\nlog:\n{}",
            s.log_text()
        );
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
}

/// Poll until the job is done (panics if it fails).
pub async fn wait_done(c: &reqwest::Client, s: &Server, id: &str) -> Value {
    let v = wait_for(c, s, id, Duration::from_secs(120), |v| {
        v["status"] == "done" || v["status"] == "failed"
    })
    .await;
    assert_eq!(v["status"], "done", "{v}");
    v
}

/// The server's `/metrics` text.
pub async fn metrics_text(c: &reqwest::Client, s: &Server) -> String {
    c.get(s.url("/metrics"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap()
}

/// The value of an unlabelled metric.
pub async fn metric(c: &reqwest::Client, s: &Server, name: &str) -> f64 {
    let text = metrics_text(c, s).await;
    text.lines()
        .find_map(|l| {
            l.strip_prefix(name)
                .and_then(|r| r.strip_prefix(' '))
                .map(|v| v.trim().parse::<f64>().unwrap())
        })
        .unwrap_or_else(|| panic!("metric {name} missing in\n{text}"))
}

/// The sum of every sample of a metric, whatever its labels (0 when it
/// has none yet).
pub async fn metric_sum(c: &reqwest::Client, s: &Server, name: &str) -> f64 {
    metrics_text(c, s)
        .await
        .lines()
        .filter(|l| {
            l.strip_prefix(name)
                .is_some_and(|r| r.starts_with(' ') || r.starts_with('{'))
        })
        .map(|l| l.rsplit(' ').next().unwrap().parse::<f64>().unwrap())
        .sum()
}

/// `POLBRDF_TEST_S3` (`s3://BUCKET/PREFIX` of a real S3-compatible
/// server, with the `AWS_*` variables set) under a prefix of the test's
/// own, or `None` after a loud SKIPPED line; unset under `CI=true` is a
/// failure (.ci/run starts one).
pub fn s3_store(test: &str) -> Option<String> {
    match std::env::var("POLBRDF_TEST_S3") {
        Ok(u) if !u.is_empty() => {
            let nanos = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .as_nanos();
            Some(format!(
                "{}/{test}-{}-{nanos}",
                u.trim_end_matches('/'),
                std::process::id()
            ))
        }
        _ if std::env::var("CI").as_deref() == Ok("true") => {
            panic!("{test}: CI=true but POLBRDF_TEST_S3 is unset (.ci/run starts one)")
        }
        _ => {
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "SKIPPED: {test}: set POLBRDF_TEST_S3=s3://BUCKET/PREFIX and AWS_ENDPOINT_URL, \
                 AWS_REGION, AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY (AWS_ALLOW_HTTP=true) \
                 to run it on an S3-compatible server"
            );
            None
        }
    }
}

/// The keys under `s3://BUCKET/PREFIX`, listed from the server itself
/// (`ListObjectsV2` on `AWS_ENDPOINT_URL`, unsigned: the test server
/// accepts it).
pub async fn s3_keys(c: &reqwest::Client, store: &str) -> Vec<String> {
    let rest = store.strip_prefix("s3://").unwrap();
    let (bucket, prefix) = rest.split_once('/').unwrap();
    let endpoint = std::env::var("AWS_ENDPOINT_URL").unwrap();
    let xml = c
        .get(format!(
            "{}/{bucket}?list-type=2&prefix={prefix}/",
            endpoint.trim_end_matches('/')
        ))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        !xml.contains("<IsTruncated>true"),
        "more than one page: {xml}"
    );
    xml.split("<Key>")
        .skip(1)
        .map(|k| k.split("</Key>").next().unwrap().to_string())
        .collect()
}

/// The `host:port` of `AWS_ENDPOINT_URL`.
pub fn aws_endpoint_addr() -> std::net::SocketAddr {
    let url = std::env::var("AWS_ENDPOINT_URL").unwrap();
    let hostport = url
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string();
    std::net::ToSocketAddrs::to_socket_addrs(&hostport)
        .unwrap()
        .next()
        .unwrap()
}

/// Lowercase hex SHA-256, computed here independently of the service.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}
