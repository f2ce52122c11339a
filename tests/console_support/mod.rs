//! Headless Chromium for the console's tests (tests/console_browser.rs),
//! its screenshots and its benchmark (benches/console.rs): Debian's
//! `chromium` driven through `chromedriver` (W3C WebDriver, fantoccini).
//!
//! `POLBRDF_TEST_CHROMEDRIVER` names the driver (default
//! `/usr/bin/chromedriver`) and `POLBRDF_TEST_CHROMIUM` the browser
//! (default `/usr/bin/chromium`). Without them the tests print SKIPPED
//! and pass, except under `CI=true` (.ci/run installs both).
#![allow(dead_code)]

use fantoccini::{Client, ClientBuilder};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The driver and browser binaries, or `None` after a loud SKIPPED line.
pub fn binaries(test: &str) -> Option<(PathBuf, PathBuf)> {
    let pick = |var: &str, default: &str| {
        std::env::var(var)
            .ok()
            .filter(|v| !v.is_empty())
            .map_or_else(|| PathBuf::from(default), PathBuf::from)
    };
    let driver = pick("POLBRDF_TEST_CHROMEDRIVER", "/usr/bin/chromedriver");
    let browser = pick("POLBRDF_TEST_CHROMIUM", "/usr/bin/chromium");
    if driver.is_file() && browser.is_file() {
        return Some((driver, browser));
    }
    if std::env::var("CI").as_deref() == Ok("true") {
        panic!(
            "{test}: CI=true but {} or {} is missing (.ci/run installs chromium and chromium-driver)",
            driver.display(),
            browser.display()
        );
    }
    eprintln!(
        "SKIPPED: {test}: needs {} and {} (Debian: apt-get install chromium chromium-driver; \
         or set POLBRDF_TEST_CHROMEDRIVER and POLBRDF_TEST_CHROMIUM)",
        driver.display(),
        browser.display()
    );
    None
}

/// A chromedriver process and one browser session through it.
pub struct Browser {
    driver: Child,
    /// The WebDriver session.
    pub client: Client,
    /// `http://127.0.0.1:PORT` of chromedriver.
    pub driver_url: String,
    /// Where downloads land.
    pub downloads: PathBuf,
    profile: PathBuf,
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

impl Browser {
    /// Start chromedriver and a headless Chromium of `width × height`
    /// whose downloads go to `scratch/downloads`.
    pub async fn start(
        driver: &Path,
        browser: &Path,
        scratch: &Path,
        (width, height): (u32, u32),
    ) -> Browser {
        let port = free_port();
        let downloads = scratch.join("downloads");
        let profile = scratch.join("profile");
        std::fs::create_dir_all(&downloads).unwrap();
        std::fs::create_dir_all(&profile).unwrap();
        let log = std::fs::File::create(scratch.join("chromedriver.log")).unwrap();
        let child = Command::new(driver)
            .arg(format!("--port={port}"))
            .stdin(Stdio::null())
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .spawn()
            .expect("spawn chromedriver");
        let driver_url = format!("http://127.0.0.1:{port}");
        let t0 = Instant::now();
        let http = reqwest::Client::new();
        loop {
            let ready = http
                .get(format!("{driver_url}/status"))
                .send()
                .await
                .ok()
                .filter(|r| r.status().is_success());
            if ready.is_some() {
                break;
            }
            assert!(
                t0.elapsed() < Duration::from_secs(20),
                "chromedriver did not start"
            );
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        // The flags of a closed network (docs/console.md): no background
        // connections, no first-run or sync traffic.
        let caps = json!({
            "browserName": "chrome",
            "goog:chromeOptions": {
                "binary": browser,
                "args": [
                    "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic",
                    "--no-first-run", "--disable-background-networking",
                    "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage",
                    "--hide-scrollbars",
                    format!("--user-data-dir={}", profile.display()),
                    format!("--window-size={width},{height}"),
                ],
                "prefs": {
                    "download.default_directory": downloads,
                    "download.prompt_for_download": false,
                    "safebrowsing.enabled": false,
                },
            },
            "goog:loggingPrefs": { "browser": "ALL" },
        });
        let caps = match caps {
            Value::Object(m) => m,
            _ => unreachable!(),
        };
        let client = ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
            .capabilities(caps)
            .connect(&driver_url)
            .await
            .expect("a WebDriver session");
        Browser {
            driver: child,
            client,
            driver_url,
            downloads,
            profile,
        }
    }

    /// The browser's console messages since the last call (chromedriver's
    /// log endpoint): `(level, message)`.
    pub async fn console_log(&self) -> Vec<(String, String)> {
        let id = self.client.session_id().await.unwrap().unwrap();
        let v: Value = reqwest::Client::new()
            .post(format!("{}/session/{id}/se/log", self.driver_url))
            .json(&json!({"type": "browser"}))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        v["value"]
            .as_array()
            .cloned()
            .unwrap_or_default()
            .iter()
            .map(|e| {
                (
                    e["level"].as_str().unwrap_or("").to_string(),
                    e["message"].as_str().unwrap_or("").to_string(),
                )
            })
            .collect()
    }

    /// Console errors since the last call (level SEVERE).
    pub async fn console_errors(&self) -> Vec<String> {
        self.console_log()
            .await
            .into_iter()
            .filter(|(level, _)| level == "SEVERE")
            .map(|(_, m)| m)
            .collect()
    }

    /// Wait until `script` (a function body returning a value) returns a
    /// truthy value; panics with `what` after `timeout`.
    pub async fn wait_until(&self, what: &str, script: &str, timeout: Duration) -> Value {
        let t0 = Instant::now();
        loop {
            let v = self.client.execute(script, vec![]).await.unwrap();
            let truthy = match &v {
                Value::Null => false,
                Value::Bool(b) => *b,
                Value::Number(n) => n.as_f64() != Some(0.0),
                Value::String(s) => !s.is_empty(),
                _ => true,
            };
            if truthy {
                return v;
            }
            if t0.elapsed() > timeout {
                let body = self
                    .client
                    .execute("return document.body.innerText", vec![])
                    .await
                    .unwrap_or_default();
                panic!("timed out waiting for {what}; page text:\n{body}");
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    }

    /// Go to the console page `hash` (`#/cache`) of the service at `base`.
    pub async fn open(&self, base: &str, hash: &str) {
        self.client.goto(&format!("{base}/{hash}")).await.unwrap();
    }

    /// End the session and the driver.
    pub async fn close(mut self) {
        let _ = self.client.clone().close().await;
        let _ = self.driver.kill();
        let _ = self.driver.wait();
    }
}

/// A script body: are all `<img>` matching `selector` loaded with pixels?
pub fn images_loaded(selector: &str) -> String {
    format!(
        "const imgs = [...document.querySelectorAll({sel})]; \
         return imgs.length > 0 && imgs.every(i => i.dataset.loaded === 'true' && i.complete && i.naturalWidth > 0) \
         ? imgs.map(i => [i.naturalWidth, i.naturalHeight]) : null;",
        sel = serde_json::to_string(selector).unwrap()
    )
}
