//! The API the web console stands on (docs/service.md, "Listing",
//! "Events", "Previews"), over plain HTTP against the real server: the
//! listing's filters and orders, the server-sent events, thumbnails stored
//! once and removed with their result, lobe plots, metadata, and the
//! console's assets open under `--token-reads`.

mod service_support;

use serde_json::Value;
use service_support::{Server, TempDir, client, get_json, post, wait_done};
use std::time::{Duration, Instant};

/// A Rayleigh layer of optical thickness `tau` over `base` at 4 streams.
fn spec(tau: f64, base: &str, wavelengths: &str) -> String {
    format!(
        r#"{{"layers":[{{"optical_thickness":{tau},"scatterer":{{"rayleigh":{{"albedo":0.9}}}}}}],
            "base":{base},{wavelengths}"solver":{{"streams":4}}}}"#
    )
}

fn ids(v: &Value) -> Vec<String> {
    v["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["id"].as_str().unwrap().to_string())
        .collect()
}

async fn submit_done(c: &reqwest::Client, s: &Server, body: &str) -> String {
    let (code, v, _) = post(c, s, body).await;
    assert!(code == 202 || code == 200, "{code} {v}");
    let id = v["id"].as_str().unwrap().to_string();
    wait_done(c, s, &id).await;
    id
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_listing_filters_sorts_and_pages() {
    let dir = TempDir::new("console-listing");
    let s = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();
    let black = submit_done(&c, &s, &spec(0.5, r#""black""#, "")).await;
    let lamb = submit_done(&c, &s, &spec(2.0, r#"{"lambertian":{"albedo":0.3}}"#, "")).await;
    let mirror = submit_done(
        &c,
        &s,
        &spec(
            0.5,
            r#"{"fresnel":{"material":"Al"}}"#,
            r#""wavelengths_nm":[450,550],"#,
        ),
    )
    .await;
    let find = |q: &str| {
        let (c, s, q) = (&c, &s, q.to_string());
        async move {
            let (code, v) = get_json(c, s, &format!("/v1/brdfs?{q}")).await;
            assert_eq!(code, 200, "{q}: {v}");
            let mut got = ids(&v);
            got.sort();
            got
        }
    };
    let sorted = |mut v: Vec<&String>| {
        v.sort();
        v.into_iter().cloned().collect::<Vec<_>>()
    };
    // The two-wavelength job is listed with its per-wavelength parts
    // (results of their own); filters on the spec pick them apart.
    assert_eq!(find("base=black").await, vec![black.clone()]);
    assert_eq!(find("base=lambertian").await, vec![lamb.clone()]);
    let over_al = find("base=Al").await;
    assert!(over_al.contains(&mirror), "{over_al:?}");
    assert_eq!(find("base=fresnel:al").await, over_al);
    assert_eq!(
        find("wavelength_nm=550&base=fresnel").await.len(),
        2,
        "the job and its 550 nm part"
    );
    assert_eq!(find("thickness=2").await, vec![lamb.clone()]);
    assert_eq!(find("thickness=0.5&base=black").await, vec![black.clone()]);
    assert_eq!(
        find("material=RAYLEIGH&base=black").await,
        vec![black.clone()]
    );
    assert_eq!(
        find("material=rayleigh&thickness=2").await,
        vec![lamb.clone()]
    );
    assert_eq!(find("material=TiO2").await, Vec::<String>::new());
    assert_eq!(
        find(&format!("q={}", &black[..10])).await,
        vec![black.clone()]
    );
    assert_eq!(find("status=failed").await, Vec::<String>::new());
    let all = find("status=done").await;
    assert_eq!(all, find("").await);
    assert!(
        sorted(vec![&black, &lamb, &mirror])
            .iter()
            .all(|i| all.contains(i))
    );

    // An entry carries what the pages show.
    let (_, v) = get_json(&c, &s, &format!("/v1/brdfs?q={lamb}")).await;
    let e = &v["items"][0];
    assert_eq!(e["materials"], serde_json::json!(["rayleigh"]));
    assert_eq!(e["base"], "lambertian");
    assert_eq!(
        e["layers"],
        serde_json::json!([{"materials": ["rayleigh"], "optical_thickness": 2.0}])
    );
    assert_eq!(e["streams"], 4);
    assert!(e["size"].as_i64().unwrap() > 0, "{e}");
    assert!(e["solve_time_ms"].as_f64().unwrap() > 0.0, "{e}");
    assert_eq!(
        e["links"]["thumbnail"],
        format!("/v1/brdfs/{lamb}/thumbnail?kind=intensity")
    );

    // Largest first, in pages: sizes never increase and no entry repeats.
    let mut seen = Vec::new();
    let mut sizes = Vec::new();
    let mut cursor = String::new();
    loop {
        let (code, v) = get_json(&c, &s, &format!("/v1/brdfs?sort=size&limit=2{cursor}")).await;
        assert_eq!(code, 200, "{v}");
        for i in v["items"].as_array().unwrap() {
            seen.push(i["id"].as_str().unwrap().to_string());
            sizes.push(i["size"].as_i64().unwrap_or(-1));
        }
        match v["next"].as_str() {
            Some(n) => cursor = format!("&cursor={n}"),
            None => break,
        }
    }
    assert!(sizes.windows(2).all(|w| w[0] >= w[1]), "{sizes:?}");
    let mut unique = seen.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), seen.len());
    assert_eq!(unique, all);
    // A filtered page continues with the same filter.
    let (_, p1) = get_json(&c, &s, "/v1/brdfs?base=fresnel&limit=1").await;
    let next = p1["next"]
        .as_str()
        .expect("more fresnel entries")
        .to_string();
    let (_, p2) = get_json(
        &c,
        &s,
        &format!("/v1/brdfs?base=fresnel&limit=1&cursor={next}"),
    )
    .await;
    assert_eq!(p2["items"].as_array().unwrap().len(), 1, "{p2}");
    assert_ne!(ids(&p1), ids(&p2));

    for (q, path) in [
        ("status=sleeping", "status"),
        ("wavelength_nm=green", "wavelength_nm"),
        ("thickness=-2", "thickness"),
        ("sort=alphabetical", "sort"),
        ("colour=red", "query"),
    ] {
        let (code, v) = get_json(&c, &s, &format!("/v1/brdfs?{q}")).await;
        assert_eq!((code, v["path"].as_str()), (422, Some(path)), "{q}: {v}");
    }
    // A recency cursor is not a size cursor.
    let (_, v) = get_json(&c, &s, "/v1/brdfs?limit=1").await;
    let recent = v["next"].as_str().unwrap().to_string();
    let (code, v) = get_json(&c, &s, &format!("/v1/brdfs?sort=size&cursor={recent}")).await;
    assert_eq!((code, v["path"].as_str()), (422, Some("cursor")), "{v}");
}

/// The events of one `GET /v1/events` connection until `done(events)`.
async fn events_until(
    c: &reqwest::Client,
    s: &Server,
    done: impl Fn(&[Value]) -> bool,
    submit: impl std::future::Future<Output = ()>,
) -> Vec<Value> {
    let mut res = c.get(s.url("/v1/events")).send().await.unwrap();
    assert_eq!(res.status(), 200);
    assert_eq!(res.headers()["content-type"], "text/event-stream");
    submit.await;
    let (mut buf, mut events) = (String::new(), Vec::new());
    let t0 = Instant::now();
    while !done(&events) {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "events so far: {events:#?}"
        );
        let chunk = tokio::time::timeout(Duration::from_secs(30), res.chunk())
            .await
            .expect("an event within 30 s")
            .unwrap()
            .expect("the stream stays open");
        buf.push_str(std::str::from_utf8(&chunk).unwrap());
        while let Some(end) = buf.find("\n\n") {
            let block: String = buf.drain(..end + 2).collect();
            let mut kind = "";
            let mut data = String::new();
            for line in block.lines() {
                if let Some(k) = line.strip_prefix("event: ") {
                    kind = k;
                } else if let Some(d) = line.strip_prefix("data: ") {
                    data.push_str(d);
                }
            }
            if kind == "job" {
                events.push(serde_json::from_str(&data).unwrap());
            }
        }
    }
    events
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn events_follow_a_job_to_done() {
    let dir = TempDir::new("console-events");
    let s = Server::start(&dir.0.join("data"), &["--workers", "1"], &[]);
    let c = client();
    let body = service_support::slow_spec(12, 0.8);
    let id_cell = std::sync::Mutex::new(String::new());
    let events = events_until(
        &c,
        &s,
        |ev| {
            let id = id_cell.lock().unwrap().clone();
            ev.iter()
                .any(|e| e["id"] == id.as_str() && e["status"] == "done")
        },
        async {
            let (code, v, _) = post(&c, &s, &body).await;
            assert_eq!(code, 202, "{v}");
            *id_cell.lock().unwrap() = v["id"].as_str().unwrap().to_string();
        },
    )
    .await;
    let id = id_cell.lock().unwrap().clone();
    let mine: Vec<&Value> = events.iter().filter(|e| e["id"] == id.as_str()).collect();
    let states: Vec<&str> = mine.iter().map(|e| e["status"].as_str().unwrap()).collect();
    assert_eq!(states.last(), Some(&"done"), "{states:?}");
    let progress: Vec<f64> = mine
        .iter()
        .map(|e| e["progress"].as_f64().unwrap())
        .collect();
    assert!(progress.windows(2).all(|w| w[0] <= w[1]), "{progress:?}");
    assert_eq!(progress.last(), Some(&1.0));
    // Each event is a listing entry; a running one says where and how long.
    for e in &mine {
        assert_eq!(e["wavelengths"], 12);
        if e["status"] == "running" {
            assert!(
                e["worker"].is_string() && e["elapsed_ms"].as_f64().unwrap() >= 0.0,
                "{e}"
            );
        }
    }
    // No event repeats the one before it for the same job.
    for w in mine.windows(2) {
        assert!(
            (&w[0]["status"], &w[0]["progress"], &w[0]["updated_at"])
                != (&w[1]["status"], &w[1]["progress"], &w[1]["updated_at"]),
            "{w:?}"
        );
    }
}

fn is_png(b: &[u8]) -> bool {
    b.starts_with(b"\x89PNG\r\n\x1a\n")
}

/// The files under the data directory's blob store.
fn blob_count(data: &std::path::Path) -> usize {
    fn walk(p: &std::path::Path) -> usize {
        std::fs::read_dir(p)
            .map(|d| {
                d.map(|e| {
                    let p = e.unwrap().path();
                    if p.is_dir() { walk(&p) } else { 1 }
                })
                .sum()
            })
            .unwrap_or(0)
    }
    walk(&data.join("blobs"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn thumbnails_are_stored_once_and_leave_with_their_result() {
    let dir = TempDir::new("console-previews");
    let data = dir.0.join("data");
    let s = Server::start(&data, &[], &[]);
    let c = client();
    let id = submit_done(&c, &s, &spec(1.0, r#"{"lambertian":{"albedo":0.3}}"#, "")).await;
    let blobs_before = blob_count(&data);
    let get = |q: String| {
        let c = &c;
        let url = s.url(&q);
        async move {
            let r = c.get(url).send().await.unwrap();
            let (code, h) = (r.status().as_u16(), r.headers().clone());
            (code, h, r.bytes().await.unwrap().to_vec())
        }
    };
    let (code, h, intensity) = get(format!("/v1/brdfs/{id}/thumbnail")).await;
    assert_eq!(code, 200);
    assert_eq!(h["content-type"], "image/png");
    assert!(is_png(&intensity));
    let etag = h["etag"].to_str().unwrap().to_string();
    assert_eq!(
        etag,
        format!("\"{}\"", service_support::sha256_hex(&intensity))
    );
    // Both kinds were rendered and stored at once.
    assert_eq!(blob_count(&data), blobs_before + 2);
    let (code, _, dop) = get(format!("/v1/brdfs/{id}/thumbnail?kind=dop")).await;
    assert_eq!(code, 200);
    assert!(is_png(&dop) && dop != intensity);
    assert_eq!(s.log_text().matches("thumbnails rendered").count(), 1);
    // A restarted service reads the stored ones (the same bytes), renders nothing.
    drop(s);
    let s = Server::start(&data, &[], &[]);
    let r = c
        .get(s.url(&format!("/v1/brdfs/{id}/thumbnail?kind=intensity")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.bytes().await.unwrap().to_vec(), intensity);
    assert_eq!(s.log_text().matches("thumbnails rendered").count(), 0);
    let r = c
        .get(s.url(&format!("/v1/brdfs/{id}/thumbnail")))
        .header("if-none-match", &etag)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 304);
    let (code, v) = get_json(&c, &s, &format!("/v1/brdfs/{id}/thumbnail?kind=sepia")).await;
    assert_eq!((code, v["path"].as_str()), (422, Some("kind")), "{v}");

    // The lobe plot: SVG at the angle asked for; the metadata: per wavelength.
    let r = c
        .get(s.url(&format!("/v1/brdfs/{id}/plot?theta_i_deg=30")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["content-type"], "image/svg+xml");
    let svg = r.text().await.unwrap();
    assert!(
        svg.starts_with("<svg") && svg.contains("</svg>"),
        "{}",
        &svg[..200.min(svg.len())]
    );
    assert!(svg.contains("30"), "the incident angle is labelled");
    let (code, v) = get_json(&c, &s, &format!("/v1/brdfs/{id}/plot?theta_i_deg=90")).await;
    assert_eq!(
        (code, v["path"].as_str()),
        (422, Some("theta_i_deg")),
        "{v}"
    );
    let (code, meta) = get_json(&c, &s, &format!("/v1/brdfs/{id}/metadata")).await;
    assert_eq!(code, 200);
    assert_eq!(meta["spec_hash"], id.as_str());
    assert_eq!(meta["wavelengths"][0]["streams"], 4);

    // Deleting the result removes its thumbnails' blobs too.
    let r = c
        .delete(s.url(&format!("/v1/brdfs/{id}")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 204);
    assert_eq!(
        blob_count(&data),
        blobs_before - 1,
        "the table and both thumbnails gone"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_console_is_served_without_a_token_its_data_only_with_one() {
    let dir = TempDir::new("console-assets");
    let s = Server::start(
        &dir.0.join("data"),
        &["--token-reads"],
        &[("POLBRDF_TOKEN", "t0ken")],
    );
    let c = client();
    for (path, media) in [
        ("/", "text/html; charset=utf-8"),
        ("/console/app.js", "text/javascript; charset=utf-8"),
        ("/console/app.css", "text/css; charset=utf-8"),
        ("/console/icon.svg", "image/svg+xml"),
        ("/console/examples.json", "application/json"),
    ] {
        let r = c.get(s.url(path)).send().await.unwrap();
        assert_eq!(r.status(), 200, "{path}");
        assert_eq!(r.headers()["content-type"], media, "{path}");
    }
    let (_, examples) = get_json(&c, &s, "/console/examples.json").await;
    assert!(
        examples
            .as_array()
            .unwrap()
            .iter()
            .any(|e| e["spec"]["layers"].is_array())
    );
    for path in ["/v1/brdfs", "/v1/events"] {
        let r = c.get(s.url(path)).send().await.unwrap();
        assert_eq!(r.status(), 401, "{path}");
    }
    let r = c
        .get(s.url("/v1/brdfs"))
        .bearer_auth("t0ken")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
}
