//! The web console end to end (docs/console.md): a real `polbrdf serve` on
//! loopback, driven in headless Chromium through chromedriver. Skipped
//! loudly without Chromium (tests/console_support), required under
//! `CI=true`.
//!
//! `screenshots` (ignored) writes the pictures of docs/console.md; run it
//! with docs/console/screenshots.sh.

mod console_support;
mod service_support;

use console_support::{Browser, binaries, images_loaded};
use fantoccini::Locator;
use serde_json::Value;
use service_support::{Server, TempDir, client, get_json, sha256_hex, wait_done};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const WAIT: Duration = Duration::from_secs(60);

/// TiO2 over black at three wavelengths: a job with visible progress.
const PAINT: &str = r#"{"layers": [{"optical_thickness": 1.0,
  "scatterer": {"mie": {"material": "TiO2", "radius_um": 0.2}}}],
  "base": "black", "wavelengths_nm": [450, 550, 650], "solver": {"streams": 12}}"#;

/// A spec the API refuses at `layers[0].scatterer.mie.radius_um`.
const BAD: &str = r#"{"layers": [{"optical_thickness": 1.0,
  "scatterer": {"mie": {"material": "TiO2", "radius_um": -1}}}],
  "wavelengths_nm": [550]}"#;

/// Replace the submit page's editor text (typed, as a user would paste it)
/// and press Submit.
async fn submit_text(b: &Browser, text: &str) {
    let editor = b
        .client
        .wait()
        .at_most(WAIT)
        .for_element(Locator::Css("#spec-editor"))
        .await
        .unwrap();
    editor.clear().await.unwrap();
    editor.send_keys(text).await.unwrap();
    b.client
        .find(Locator::Css("#submit-form button[type=submit]"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
}

/// The file that appears in `dir` (a finished download: no `.crdownload`).
async fn downloaded(dir: &Path) -> PathBuf {
    let t0 = Instant::now();
    loop {
        let files: Vec<PathBuf> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        if let [f] = files.as_slice()
            && f.extension().is_none_or(|e| e != "crdownload")
            && std::fs::metadata(f).unwrap().len() > 0
        {
            return f.clone();
        }
        assert!(
            t0.elapsed() < WAIT,
            "no download in {}: {files:?}",
            dir.display()
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

#[tokio::test]
async fn the_console_submits_watches_shows_and_downloads() {
    let Some((driver, chromium)) = binaries("the_console_submits_watches_shows_and_downloads")
    else {
        return;
    };
    let dir = TempDir::new("console-e2e");
    let server = Server::start(&dir.0.join("data"), &["--workers", "1"], &[]);
    let b = Browser::start(&driver, &chromium, &dir.0, (1280, 900)).await;
    let c = client();

    // Submit through the form.
    b.open(&server.base, "#/submit").await;
    b.wait_until(
        "the templates",
        "return document.querySelectorAll('#template option').length",
        WAIT,
    )
    .await;
    submit_text(&b, PAINT).await;
    let hash = b
        .wait_until(
            "the result page after submitting",
            "return location.hash.startsWith('#/result/') ? location.hash : null",
            WAIT,
        )
        .await;
    let id = hash
        .as_str()
        .unwrap()
        .trim_start_matches("#/result/")
        .to_string();
    assert_eq!(id.len(), 64, "{hash}");

    // Its progress reaches done on the queue page, live.
    b.open(&server.base, "#/queue").await;
    let row = format!("#jobs tr[data-id='{id}']");
    let mode = b
        .wait_until(
            "the queue's update mode",
            "return document.querySelector('#queue-mode')?.textContent",
            WAIT,
        )
        .await;
    assert!(mode.as_str().unwrap().starts_with("Live"), "{mode}");
    let progress = b
        .wait_until(
            "the job done on the queue page",
            &format!(
                "const r = document.querySelector(\"{row}\"); \
                 return r && r.dataset.status === 'done' ? r.querySelector('progress').value : null;"
            ),
            WAIT,
        )
        .await;
    assert_eq!(progress.as_f64(), Some(100.0));

    // The result page: thumbnails and the lobe plot load.
    b.open(&server.base, &format!("#/result/{id}")).await;
    let thumbs = b
        .wait_until("the thumbnails", &images_loaded("img.thumb"), WAIT)
        .await;
    assert_eq!(thumbs.as_array().unwrap().len(), 2, "{thumbs}");
    for size in thumbs.as_array().unwrap() {
        assert_eq!(size, &serde_json::json!([96, 96]));
    }
    let plot = b
        .wait_until("the lobe plot", &images_loaded("#plot"), WAIT)
        .await;
    assert!(plot[0][0].as_f64().unwrap() > 100.0, "{plot}");
    // A slider move draws another angle.
    let first_src = b
        .client
        .execute("return document.querySelector('#plot').src", vec![])
        .await
        .unwrap();
    b.client
        .execute(
            "const s = document.querySelector('#theta-i'); s.value = 20; \
             s.dispatchEvent(new Event('input'));",
            vec![],
        )
        .await
        .unwrap();
    b.wait_until(
        "the plot at 20 degrees",
        &format!(
            "const p = document.querySelector('#plot'); \
             return p.dataset.src.includes('theta_i_deg=20') && p.dataset.loaded === 'true' && p.src !== {first_src};"
        ),
        WAIT,
    )
    .await;
    let per_wl = b
        .client
        .execute(
            "return document.querySelectorAll('table[aria-label^=\"Per-wavelength\"] tbody tr').length",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(per_wl.as_u64(), Some(3));

    // A download is the API's bytes: its SHA-256 is the ETag.
    b.client
        .find(Locator::Css("a[data-format='binary']"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    let file = downloaded(&b.downloads).await;
    let bytes = std::fs::read(&file).unwrap();
    let res = c
        .get(server.url(&format!("/v1/brdfs/{id}/table")))
        .send()
        .await
        .unwrap();
    let etag = res.headers()["etag"].to_str().unwrap().to_string();
    assert_eq!(
        format!("\"{}\"", sha256_hex(&bytes)),
        etag,
        "{}",
        file.display()
    );
    assert_eq!(bytes, res.bytes().await.unwrap().to_vec());

    // The cache page lists it with its thumbnails; filters find it or not.
    b.open(&server.base, "#/cache?material=tio2&wavelength_nm=550")
        .await;
    b.wait_until(
        "the filtered cache page",
        &format!("return document.querySelector(\"#results tr[data-id='{id}']\")"),
        WAIT,
    )
    .await;
    b.wait_until(
        "cache thumbnails",
        &images_loaded("#results img.thumb"),
        WAIT,
    )
    .await;
    b.open(&server.base, "#/cache?material=Fe2O3").await;
    b.wait_until(
        "an empty filtered page",
        "return document.querySelector('#results')?.textContent.includes('No results match')",
        WAIT,
    )
    .await;

    let errors = b.console_errors().await;
    assert!(errors.is_empty(), "console errors: {errors:#?}");

    // A bad spec: the API's field-level error, pointed at in the editor.
    b.open(&server.base, "#/submit").await;
    submit_text(&b, BAD).await;
    let alert = b
        .wait_until(
            "the field error",
            "return document.querySelector('#submit-result [role=alert]')?.textContent",
            WAIT,
        )
        .await;
    let alert = alert.as_str().unwrap();
    assert!(
        alert.starts_with("layers[0].scatterer.mie.radius_um: "),
        "{alert}"
    );
    assert!(alert.contains("outside the allowed range"), "{alert}");
    let marked = b
        .client
        .execute(
            "const e = document.querySelector('#spec-editor'); \
             return [e.getAttribute('aria-invalid'), e.value.slice(e.selectionStart, e.selectionEnd)];",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(marked, serde_json::json!(["true", "radius_um"]));
    // The browser logs the refused POST itself; nothing else.
    let errors = b.console_errors().await;
    let refused = format!(
        "{}/v1/brdfs - Failed to load resource: the server responded with a status of 422",
        server.base
    );
    assert!(
        errors.iter().all(|m| m.starts_with(&refused)) && errors.len() == 1,
        "console errors: {errors:#?}"
    );
    b.close().await;
}

#[tokio::test]
async fn with_a_token_the_form_without_it_is_refused() {
    let Some((driver, chromium)) = binaries("with_a_token_the_form_without_it_is_refused") else {
        return;
    };
    let dir = TempDir::new("console-token");
    let server = Server::start(
        &dir.0.join("data"),
        &["--workers", "1"],
        &[("POLBRDF_TOKEN", "s3cret")],
    );
    let b = Browser::start(&driver, &chromium, &dir.0, (1280, 900)).await;
    let c = client();
    b.open(&server.base, "#/submit").await;
    b.wait_until(
        "the templates",
        "return document.querySelectorAll('#template option').length",
        WAIT,
    )
    .await;
    submit_text(&b, service_support::TINY).await;
    let alert = b
        .wait_until(
            "the refusal",
            "return document.querySelector('#submit-result [role=alert]')?.textContent",
            WAIT,
        )
        .await;
    assert!(
        alert.as_str().unwrap().to_lowercase().contains("token"),
        "{alert}"
    );
    let (_, list) = get_json(&c, &server, "/v1/brdfs").await;
    assert_eq!(list["items"], serde_json::json!([]), "nothing was queued");

    // With the token entered the same form is accepted.
    let field = b.client.find(Locator::Css("#token")).await.unwrap();
    field.send_keys("s3cret").await.unwrap();
    b.client
        .find(Locator::Css("#token-form button"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    b.wait_until(
        "the form drawn again with the token",
        "return document.querySelector('#submit-form')?.textContent.includes('with the token entered above')",
        WAIT,
    )
    .await;
    submit_text(&b, service_support::TINY).await;
    let hash = b
        .wait_until(
            "the result page",
            "return location.hash.startsWith('#/result/') ? location.hash : null",
            WAIT,
        )
        .await;
    let id = hash
        .as_str()
        .unwrap()
        .trim_start_matches("#/result/")
        .to_string();
    let done: Value = wait_done(&c, &server, &id).await;
    assert_eq!(done["status"], "done");
    let errors: Vec<String> = b
        .console_errors()
        .await
        .into_iter()
        // The refused POST itself is logged by the browser as a 401.
        .filter(|m| {
            !m.starts_with(&format!(
                "{}/v1/brdfs - Failed to load resource: the server responded with a status of 401",
                server.base
            ))
        })
        .collect();
    assert!(errors.is_empty(), "console errors: {errors:#?}");
    b.close().await;
}

/// The pictures of docs/console.md: `POLBRDF_SCREENSHOTS=DIR` (default
/// `docs/console`).
#[tokio::test]
#[ignore = "writes docs/console/*.png: run docs/console/screenshots.sh"]
async fn screenshots() {
    let Some((driver, chromium)) = binaries("screenshots") else {
        return;
    };
    let out = PathBuf::from(
        std::env::var("POLBRDF_SCREENSHOTS").unwrap_or_else(|_| "docs/console".into()),
    );
    std::fs::create_dir_all(&out).unwrap();
    let dir = TempDir::new("console-shots");
    let server = Server::start(&dir.0.join("data"), &["--workers", "1"], &[]);
    let c = client();
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("api/examples");
    let mut ids = Vec::new();
    for f in [
        "tio2_black.json",
        "rust_on_silver.json",
        "two_layers_lambertian.json",
    ] {
        let spec = std::fs::read_to_string(examples.join(f)).unwrap();
        let (_, v, _) = service_support::post(&c, &server, &spec).await;
        ids.push(v["id"].as_str().unwrap().to_string());
    }
    for id in &ids {
        wait_done(&c, &server, id).await;
    }
    let b = Browser::start(&driver, &chromium, &dir.0, (1366, 860)).await;
    let shot = |name: &'static str| {
        let (b, out) = (&b, out.clone());
        async move {
            let png = b.client.screenshot().await.unwrap();
            std::fs::write(out.join(format!("{name}.png")), png).unwrap();
        }
    };
    // The queue with a job running.
    let (_, v, _) = service_support::post(&c, &server, &service_support::slow_spec(12, 0.7)).await;
    let slow = v["id"].as_str().unwrap().to_string();
    b.open(&server.base, "#/queue").await;
    b.wait_until(
        "a running job",
        &format!(
            "return document.querySelector(\"#jobs tr[data-id='{slow}'][data-status='running']\")"
        ),
        WAIT,
    )
    .await;
    shot("queue").await;
    wait_done(&c, &server, &slow).await;
    b.open(&server.base, "#/cache").await;
    b.wait_until(
        "the visible cache thumbnails",
        "const imgs = [...document.querySelectorAll('#results img.thumb')] \
           .filter(i => i.getBoundingClientRect().top < innerHeight); \
         return imgs.length > 0 && imgs.every(i => i.dataset.loaded === 'true');",
        WAIT,
    )
    .await;
    shot("cache").await;
    b.open(&server.base, &format!("#/result/{}", ids[1])).await;
    b.wait_until("the lobe plot", &images_loaded("#plot"), WAIT)
        .await;
    b.wait_until("the thumbnails", &images_loaded("img.thumb"), WAIT)
        .await;
    shot("result").await;
    b.open(&server.base, "#/submit").await;
    b.wait_until(
        "the templates",
        "return document.querySelectorAll('#template option').length",
        WAIT,
    )
    .await;
    submit_text(&b, BAD).await;
    b.wait_until(
        "the field error",
        "return document.querySelector('#submit-result [role=alert]')",
        WAIT,
    )
    .await;
    shot("submit").await;
    b.close().await;
    eprintln!("screenshots in {}", out.display());
}
