//! The shipped nginx front end (deploy/nginx/polbrdf.conf, docs/deploy.md
//! "nginx") in front of a real `polbrdf serve`: a table is fetched from the
//! service once (MISS) and then served from nginx's cache (HIT, the same
//! bytes, also while the service is down); job status, the listing and
//! submissions are never served from the cache; a request carrying a bearer
//! token bypasses the cache, so under `--token-reads` a client without the
//! token never gets a result from it.
//!
//! Runs Debian's nginx (`POLBRDF_TEST_NGINX`, default `/usr/sbin/nginx`) on
//! 127.0.0.1 with a temporary prefix, on a copy of polbrdf.conf whose
//! upstream `server` lines, `listen` line and cache path are replaced.
//! Without nginx it prints SKIPPED and passes; under `CI=true` it fails
//! (.ci/nginx.sh installs it).

mod service_support;

use service_support::*;
use std::io::Write;
use std::net::TcpStream;
use std::os::unix::fs::{MetadataExt, PermissionsExt};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const SHIPPED: &str = include_str!("../deploy/nginx/polbrdf.conf");

/// The nginx binary to run, or `None` (after a loud SKIPPED line) when
/// there is none; panics under `CI=true`.
fn nginx_binary(test: &str) -> Option<PathBuf> {
    let named = std::env::var("POLBRDF_TEST_NGINX")
        .ok()
        .filter(|s| !s.is_empty());
    let path = named
        .clone()
        .map(PathBuf::from)
        .or_else(|| Some(PathBuf::from("/usr/sbin/nginx")).filter(|p| p.exists()));
    match path {
        Some(p) if p.exists() => Some(p),
        Some(p) if named.is_some() => panic!("POLBRDF_TEST_NGINX={} does not exist", p.display()),
        _ if std::env::var("CI").as_deref() == Ok("true") => {
            panic!("{test}: CI=true but there is no /usr/sbin/nginx (.ci/nginx.sh installs it)")
        }
        _ => {
            // To stderr itself, not eprintln!: the test harness captures
            // the macros' output of a passing test.
            let _ = writeln!(
                std::io::stderr(),
                "SKIPPED: {test}: no /usr/sbin/nginx: install nginx-light \
                 (or set POLBRDF_TEST_NGINX=/path/to/nginx)"
            );
            None
        }
    }
}

/// Replace the one line of `text` that starts (after indentation) with
/// `prefix` by `with` (indentation kept).
fn replace_line(text: &str, prefix: &str, with: &str) -> String {
    let hits = text
        .lines()
        .filter(|l| l.trim_start().starts_with(prefix))
        .count();
    assert_eq!(hits, 1, "polbrdf.conf: {hits} lines start with {prefix:?}");
    text.lines()
        .map(|l| {
            if l.trim_start().starts_with(prefix) {
                let indent = &l[..l.len() - l.trim_start().len()];
                format!("{indent}{with}\n")
            } else {
                format!("{l}\n")
            }
        })
        .collect()
}

/// The shipped polbrdf.conf with its upstream servers replaced by
/// `upstream`, its listen address by `listen` and its cache by `cache`.
fn adapted_config(upstream: &str, listen: &str, cache: &Path) -> String {
    let (head, rest) = SHIPPED
        .split_once("# BEGIN polbrdf servers\n")
        .expect("BEGIN polbrdf servers marker");
    let (_, tail) = rest
        .split_once("# END polbrdf servers\n")
        .expect("END polbrdf servers marker");
    let text = format!("{head}server {upstream};\n{tail}");
    let text = replace_line(&text, "listen ", &format!("listen {listen};"));
    let cache_line = SHIPPED
        .lines()
        .find(|l| l.starts_with("proxy_cache_path "))
        .expect("proxy_cache_path line");
    let (_, params) = cache_line
        .trim_start_matches("proxy_cache_path ")
        .split_once(' ')
        .unwrap();
    replace_line(
        &text,
        "proxy_cache_path ",
        &format!("proxy_cache_path {} {params}", cache.display()),
    )
}

/// A running nginx (master and workers in a process group of their own),
/// stopped on drop.
struct Nginx {
    child: Child,
    /// `http://127.0.0.1:PORT`.
    base: String,
    prefix: PathBuf,
}

impl Nginx {
    /// nginx in front of `upstream` (`127.0.0.1:PORT`), its prefix (config,
    /// logs, cache, temporary files) under `dir`.
    fn start(binary: &Path, dir: &Path, upstream: &str) -> Nginx {
        let prefix = dir.join("nginx");
        std::fs::create_dir_all(prefix.join("tmp")).unwrap();
        // As root, the workers run as nobody (nginx chowns the cache and
        // temporary directories to them, but they must be able to reach
        // them whatever the umask); otherwise nginx ignores `user`.
        let root = std::fs::metadata(&prefix).unwrap().uid() == 0;
        if root {
            for d in [dir, prefix.as_path()] {
                std::fs::set_permissions(d, std::fs::Permissions::from_mode(0o755)).unwrap();
            }
        }
        let group = if std::fs::read_to_string("/etc/group")
            .unwrap_or_default()
            .lines()
            .any(|l| l.starts_with("nogroup:"))
        {
            "nogroup"
        } else {
            "nobody"
        };
        let user = if root {
            format!("user nobody {group};")
        } else {
            String::new()
        };
        let p = prefix.display();
        let main = format!(
            "{user}\nworker_processes 1;\npid {p}/nginx.pid;\nerror_log {p}/error.log info;\n\
             events {{ worker_connections 256; }}\n\
             http {{\n  access_log {p}/access.log;\n\
             client_body_temp_path {p}/tmp/body;\n  proxy_temp_path {p}/tmp/proxy;\n\
             fastcgi_temp_path {p}/tmp/fastcgi;\n  uwsgi_temp_path {p}/tmp/uwsgi;\n\
             scgi_temp_path {p}/tmp/scgi;\n  include polbrdf.conf;\n}}\n"
        );
        std::fs::write(prefix.join("nginx.conf"), main).unwrap();
        // A free port: bound and released here, so another process may take
        // it before nginx does; then nginx exits and the next port is tried.
        for _ in 0..5 {
            let port = std::net::TcpListener::bind("127.0.0.1:0")
                .unwrap()
                .local_addr()
                .unwrap()
                .port();
            let listen = format!("127.0.0.1:{port}");
            std::fs::write(
                prefix.join("polbrdf.conf"),
                adapted_config(upstream, &listen, &prefix.join("cache")),
            )
            .unwrap();
            let mut child = Command::new(binary)
                .arg("-p")
                .arg(&prefix)
                .arg("-e")
                .arg(prefix.join("error.log"))
                .arg("-c")
                .arg(prefix.join("nginx.conf"))
                .args(["-g", "daemon off; master_process on;"])
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(std::fs::File::create(prefix.join("stderr.log")).unwrap())
                .process_group(0)
                .spawn()
                .expect("spawn nginx");
            let t0 = Instant::now();
            loop {
                if let Some(status) = child.try_wait().unwrap() {
                    let log = std::fs::read_to_string(prefix.join("error.log")).unwrap_or_default();
                    assert!(
                        log.contains("Address already in use"),
                        "nginx exited with {status}:\n{log}{}",
                        std::fs::read_to_string(prefix.join("stderr.log")).unwrap_or_default()
                    );
                    break;
                }
                if TcpStream::connect(&listen).is_ok() {
                    return Nginx {
                        child,
                        base: format!("http://{listen}"),
                        prefix,
                    };
                }
                assert!(
                    t0.elapsed() < Duration::from_secs(10),
                    "nginx did not listen on {listen}"
                );
                std::thread::sleep(Duration::from_millis(20));
            }
        }
        panic!("no free port for nginx after 5 tries");
    }

    fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    fn error_log(&self) -> String {
        std::fs::read_to_string(self.prefix.join("error.log")).unwrap_or_default()
    }
}

impl Drop for Nginx {
    fn drop(&mut self) {
        // SIGTERM: the master stops its workers and exits; if it does not
        // within 5 s, SIGKILL the whole process group.
        let pid = self.child.id().to_string();
        let _ = Command::new("kill").args(["-TERM", &pid]).status();
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(5) {
            if self.child.try_wait().ok().flatten().is_some() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = Command::new("kill")
            .args(["-KILL", "--", &format!("-{pid}")])
            .status();
        let _ = self.child.wait();
    }
}

/// An answer: status, `X-Cache-Status` (if any), headers, body.
struct Answer {
    status: u16,
    cache: Option<String>,
    headers: reqwest::header::HeaderMap,
    body: Vec<u8>,
}

async fn send(req: reqwest::RequestBuilder) -> Answer {
    let r = req.send().await.unwrap();
    let status = r.status().as_u16();
    let headers = r.headers().clone();
    let cache = headers
        .get("x-cache-status")
        .map(|v| v.to_str().unwrap().to_string());
    let body = r.bytes().await.unwrap().to_vec();
    Answer {
        status,
        cache,
        headers,
        body,
    }
}

fn header<'a>(a: &'a Answer, name: &str) -> &'a str {
    a.headers.get(name).map_or("", |v| v.to_str().unwrap_or(""))
}

fn json(a: &Answer) -> serde_json::Value {
    serde_json::from_slice(&a.body).unwrap_or_else(|_| {
        panic!(
            "{}: not JSON: {}",
            a.status,
            String::from_utf8_lossy(&a.body)
        )
    })
}

/// Poll the job's status through nginx until it is done; no answer on the
/// way may come from the cache.
async fn wait_done_via(c: &reqwest::Client, ng: &Nginx, id: &str, token: Option<&str>) {
    let t0 = Instant::now();
    loop {
        let mut req = c.get(ng.url(&format!("/v1/brdfs/{id}")));
        if let Some(t) = token {
            req = req.bearer_auth(t);
        }
        let a = send(req).await;
        assert_eq!(a.status, 200, "{}", String::from_utf8_lossy(&a.body));
        assert_eq!(a.cache, None, "job status went through the cache");
        assert_eq!(header(&a, "cache-control"), "no-cache");
        let v = json(&a);
        if v["status"] == "done" {
            return;
        }
        assert_ne!(v["status"], "failed", "{v}");
        assert!(t0.elapsed() < Duration::from_secs(120), "timed out: {v}");
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn nginx_caches_results_and_nothing_else() {
    let Some(binary) = nginx_binary("service_nginx_cache") else {
        return;
    };
    let dir = TempDir::new("nginx-cache");
    let mut server = Server::start(&dir.0.join("data"), &[], &[]);
    let upstream = server.base.trim_start_matches("http://").to_string();
    let ng = Nginx::start(&binary, &dir.0, &upstream);
    let c = client();

    // Submissions pass through: the first queues the job, the second
    // joins or finds it; neither is a cache answer.
    let submit = || {
        c.post(ng.url("/v1/brdfs"))
            .header("content-type", "application/json")
            .body(TINY)
    };
    let first = send(submit()).await;
    assert!(matches!(first.status, 200 | 202), "{}", first.status);
    assert_eq!(first.cache, None);
    let id = json(&first)["id"].as_str().unwrap().to_string();
    wait_done_via(&c, &ng, &id, None).await;
    let again = send(submit()).await;
    assert_eq!(again.status, 200);
    assert_eq!(again.cache, None);
    let resource = wait_done(&c, &server, &id).await;
    let digest = resource["result"]["digest"].as_str().unwrap().to_string();

    // The table: fetched from the service once, then from the cache.
    let table = format!("/v1/brdfs/{id}/table");
    let direct = c
        .get(server.url(&table))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let miss = send(c.get(ng.url(&table))).await;
    assert_eq!(miss.status, 200);
    assert_eq!(miss.cache.as_deref(), Some("MISS"));
    assert_eq!(sha256_hex(&miss.body), digest);
    assert_eq!(miss.body, direct.as_ref());
    assert_eq!(header(&miss, "etag"), format!("\"{digest}\""));
    let hit = send(c.get(ng.url(&table))).await;
    assert_eq!(hit.status, 200);
    assert_eq!(hit.cache.as_deref(), Some("HIT"));
    assert_eq!(hit.body, miss.body);
    assert_eq!(header(&hit, "etag"), format!("\"{digest}\""));
    assert_eq!(
        header(&hit, "cache-control"),
        "public, max-age=31536000, immutable"
    );
    assert_eq!(
        header(&hit, "content-type"),
        header(&miss, "content-type"),
        "content type kept in the cache"
    );
    // Revalidation is answered by nginx from the entry.
    let not_modified = send(
        c.get(ng.url(&table))
            .header("if-none-match", format!("\"{digest}\"")),
    )
    .await;
    assert_eq!(not_modified.status, 304);
    assert_eq!(not_modified.cache.as_deref(), Some("HIT"));
    // HEAD shares the GET entry.
    let head = send(c.head(ng.url(&table))).await;
    assert_eq!(head.status, 200);
    assert_eq!(head.cache.as_deref(), Some("HIT"));

    // A dense export is an entry of its own (the query is in the key).
    let npy = format!("{table}?format=npy&theta_count=5&phi_count=7");
    let npy_miss = send(c.get(ng.url(&npy))).await;
    assert_eq!(npy_miss.status, 200);
    assert_eq!(npy_miss.cache.as_deref(), Some("MISS"));
    let npy_hit = send(c.get(ng.url(&npy))).await;
    assert_eq!(npy_hit.cache.as_deref(), Some("HIT"));
    assert_eq!(npy_hit.body, npy_miss.body);

    // GET …/eval is immutable too; POST …/eval is never cached.
    let eval =
        format!("/v1/brdfs/{id}/eval?theta_i_deg=30&phi_i_deg=0&theta_o_deg=45&phi_o_deg=180");
    let eval_miss = send(c.get(ng.url(&eval))).await;
    assert_eq!(eval_miss.status, 200);
    assert_eq!(eval_miss.cache.as_deref(), Some("MISS"));
    let eval_hit = send(c.get(ng.url(&eval))).await;
    assert_eq!(eval_hit.cache.as_deref(), Some("HIT"));
    assert_eq!(eval_hit.body, eval_miss.body);
    let points = r#"{"points":[{"theta_i_deg":0,"phi_i_deg":0,"theta_o_deg":60,"phi_o_deg":90}]}"#;
    for _ in 0..2 {
        let a = send(
            c.post(ng.url(&format!("/v1/brdfs/{id}/eval")))
                .header("content-type", "application/json")
                .body(points),
        )
        .await;
        assert_eq!(a.status, 200);
        assert_ne!(
            a.cache.as_deref(),
            Some("HIT"),
            "POST …/eval from the cache"
        );
    }

    // Never from the cache: job status, the listing, operations, and
    // answers that are not results (an unknown id is 404 until it is
    // submitted).
    let unknown = format!("/v1/brdfs/{}/table", "0".repeat(64));
    for path in [
        format!("/v1/brdfs/{id}"),
        "/v1/brdfs?limit=5".to_string(),
        "/healthz".to_string(),
        "/readyz".to_string(),
        "/metrics".to_string(),
        unknown.clone(),
    ] {
        for _ in 0..2 {
            let a = send(c.get(ng.url(&path))).await;
            let want = if path == unknown { 404 } else { 200 };
            assert_eq!(a.status, want, "{path}");
            assert_ne!(a.cache.as_deref(), Some("HIT"), "{path} from the cache");
        }
    }

    // With the service stopped, the cache still serves the results.
    assert!(server.terminate(Duration::from_secs(30)).success());
    for _ in 0..2 {
        let a = send(c.get(ng.url(&table))).await;
        assert_eq!(a.status, 200, "{}", ng.error_log());
        assert_eq!(a.cache.as_deref(), Some("HIT"));
        assert_eq!(a.body, miss.body);
    }
    let a = send(c.get(ng.url(&eval))).await;
    assert_eq!((a.status, a.cache.as_deref()), (200, Some("HIT")));
    // …and nothing else: job status needs the service.
    let a = send(c.get(ng.url(&format!("/v1/brdfs/{id}")))).await;
    assert_eq!(a.status, 502);
    assert_ne!(a.cache.as_deref(), Some("HIT"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_request_with_a_token_bypasses_the_cache() {
    let Some(binary) = nginx_binary("service_nginx_token") else {
        return;
    };
    let dir = TempDir::new("nginx-token");
    let server = Server::start(
        &dir.0.join("data"),
        &["--token-reads"],
        &[("POLBRDF_TOKEN", "s3cret")],
    );
    let upstream = server.base.trim_start_matches("http://").to_string();
    let ng = Nginx::start(&binary, &dir.0, &upstream);
    let c = client();

    let posted = send(
        c.post(ng.url("/v1/brdfs"))
            .bearer_auth("s3cret")
            .header("content-type", "application/json")
            .body(TINY),
    )
    .await;
    assert!(matches!(posted.status, 200 | 202), "{}", posted.status);
    let id = json(&posted)["id"].as_str().unwrap().to_string();
    wait_done_via(&c, &ng, &id, Some("s3cret")).await;

    // Authorized reads go to the service every time and are not stored.
    let table = format!("/v1/brdfs/{id}/table");
    let mut bytes = Vec::new();
    for _ in 0..2 {
        let a = send(c.get(ng.url(&table)).bearer_auth("s3cret")).await;
        assert_eq!(a.status, 200);
        assert_eq!(a.cache.as_deref(), Some("BYPASS"));
        bytes = a.body;
    }
    assert!(!bytes.is_empty());
    // So a client without the token (or with a wrong one) gets 401, never
    // the table, and the 401 is not stored either.
    for _ in 0..2 {
        let a = send(c.get(ng.url(&table))).await;
        assert_eq!(a.status, 401);
        assert_eq!(a.cache.as_deref(), Some("MISS"));
        assert_ne!(a.body, bytes);
        let a = send(c.get(ng.url(&table)).bearer_auth("wrong")).await;
        assert_eq!(a.status, 401);
        assert_eq!(a.cache.as_deref(), Some("BYPASS"));
    }
}
