//! The real `polbrdf serve` driven over HTTP: submit → poll → table, the
//! cache, single-flight of identical submissions, every class of bad input
//! with its status and problem+json body, the body cap, token auth.

mod service_support;

use serde_json::Value;
use service_support::*;

fn assert_problem(status: u16, body: &Value, headers: &reqwest::header::HeaderMap, want: u16) {
    assert_eq!(status, want, "{body}");
    assert_eq!(
        headers
            .get("content-type")
            .map(|v| v.to_str().unwrap().to_string()),
        Some("application/problem+json".to_string()),
        "{body}"
    );
    assert_eq!(body["status"], want, "{body}");
    assert!(
        body["type"].as_str().unwrap().starts_with("/problems/"),
        "{body}"
    );
    assert!(
        body["title"].is_string() && body["detail"].is_string(),
        "{body}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn submit_poll_table_cache_and_conditional_get() {
    let dir = TempDir::new("api");
    let s = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();

    // Submit: queued (or already running), with Location.
    let (code, v, h) = post(&c, &s, TINY).await;
    assert_eq!(code, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    assert_eq!(id.len(), 64);
    assert!(v["status"] == "queued" || v["status"] == "running", "{v}");
    assert_eq!(h["location"], format!("/v1/brdfs/{id}").as_str());
    assert_eq!(v["links"]["table"], format!("/v1/brdfs/{id}/table"));

    // Poll until done: the resource carries the canonical spec, progress,
    // per-wavelength timings and the solver's error estimate (fixed streams
    // too: every result carries one).
    let r = wait_done(&c, &s, &id).await;
    assert_eq!(r["id"], id.as_str());
    assert_eq!(r["progress"], 1.0);
    assert_eq!(r["wall_time_ms"].as_array().unwrap().len(), 1);
    let e = r["error_estimate"].as_f64().expect("an estimate");
    assert!(e > 0.0 && e < 1.0, "{r}");
    assert_eq!(r["spec"]["solver"]["streams"], 4);
    assert_eq!(r["spec"]["solver"]["polarized"], true);
    assert_eq!(
        r["spec"]["layers"][0]["scatterer"]["rayleigh"]["depolarization"],
        0.0
    );
    assert!(r["error"].is_null());
    assert!(r["created_at"].as_str().unwrap().ends_with('Z'));
    let digest = r["result"]["digest"].as_str().unwrap().to_string();

    // The table: bytes whose SHA-256 is the ETag, immutable caching.
    let t = c
        .get(s.url(&format!("/v1/brdfs/{id}/table")))
        .send()
        .await
        .unwrap();
    assert_eq!(t.status(), 200);
    assert_eq!(t.headers()["etag"], format!("\"{digest}\"").as_str());
    assert_eq!(
        t.headers()["cache-control"],
        "public, max-age=31536000, immutable"
    );
    assert_eq!(
        t.headers()["content-type"],
        r["result"]["media_type"].as_str().unwrap()
    );
    let bytes = t.bytes().await.unwrap();
    assert_eq!(sha256_hex(&bytes), digest);
    assert_eq!(bytes.len() as i64, r["result"]["size"].as_i64().unwrap());
    // A BRDF table (docs/table-format.md) that names its spec.
    let table = polbrdf::brdf::format::from_bytes(&bytes).unwrap();
    assert_eq!(table.metadata.spec_hash, id);
    assert_eq!(table.metadata.spec, r["spec"]);
    assert_eq!(table.wavelengths.len(), 1);
    assert_eq!(table.wavelengths[0].ns, 4);

    // If-None-Match → 304; HEAD → headers only.
    let nm = c
        .get(s.url(&format!("/v1/brdfs/{id}/table")))
        .header("if-none-match", format!("\"{digest}\""))
        .send()
        .await
        .unwrap();
    assert_eq!(nm.status(), 304);
    assert_eq!(nm.headers()["etag"], format!("\"{digest}\"").as_str());
    let head = c
        .head(s.url(&format!("/v1/brdfs/{id}/table")))
        .send()
        .await
        .unwrap();
    assert_eq!(head.status(), 200);
    assert_eq!(head.headers()["etag"], format!("\"{digest}\"").as_str());
    assert_eq!(
        head.headers()["content-length"],
        bytes.len().to_string().as_str()
    );
    assert!(head.bytes().await.unwrap().is_empty());

    // The same material written differently: a cache hit (200, the
    // resource), no second solve, counted in /metrics.
    let same = r#"{"solver":{"polarized":true,"streams":4},"base":{"lambertian":{"albedo":0.30}},
                   "layers":[{"scatterer":{"rayleigh":{"albedo":0.9,"depolarization":0}},"optical_thickness":0.5}]}"#;
    let (code, v, h) = post(&c, &s, same).await;
    assert_eq!(code, 200, "{v}");
    assert_eq!(v["id"], id.as_str());
    assert_eq!(v["status"], "done");
    assert_eq!(v["result"]["digest"], digest.as_str());
    assert_eq!(h["content-location"], format!("/v1/brdfs/{id}").as_str());
    assert_eq!(metric(&c, &s, "polbrdf_solves_started_total").await, 1.0);
    assert_eq!(metric(&c, &s, "polbrdf_solves_succeeded_total").await, 1.0);
    assert_eq!(metric(&c, &s, "polbrdf_cache_hits_total").await, 1.0);
    assert_eq!(metric(&c, &s, "polbrdf_cache_misses_total").await, 1.0);
    let text = c
        .get(s.url("/metrics"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(text.contains("polbrdf_jobs{state=\"done\"} 1"), "{text}");
    assert!(text.contains("polbrdf_solve_seconds_count 1"), "{text}");
    assert!(
        text.contains(
            "polbrdf_http_requests_total{method=\"POST\",route=\"/v1/brdfs\",status=\"200\"} 1"
        ),
        "{text}"
    );
    assert!(text.contains("polbrdf_queue_depth 0"), "{text}");

    // Health and readiness.
    assert_eq!(get_json(&c, &s, "/healthz").await.0, 200);
    assert_eq!(get_json(&c, &s, "/readyz").await.0, 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn concurrent_identical_submissions_share_one_solve() {
    let dir = TempDir::new("flight");
    let s = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();
    let spec = slow_spec(2, 0.8);
    let mut tasks = Vec::new();
    for _ in 0..200 {
        let (c, url, spec) = (c.clone(), s.url("/v1/brdfs"), spec.clone());
        tasks.push(tokio::spawn(async move {
            let r = c
                .post(url)
                .header("content-type", "application/json")
                .body(spec)
                .send()
                .await
                .unwrap();
            let code = r.status().as_u16();
            (code, r.json::<Value>().await.unwrap())
        }));
    }
    let mut ids = std::collections::BTreeSet::new();
    for t in tasks {
        let (code, v) = t.await.unwrap();
        assert!(code == 202 || code == 200, "{code} {v}");
        ids.insert(v["id"].as_str().unwrap().to_string());
    }
    assert_eq!(ids.len(), 1);
    let id = ids.into_iter().next().unwrap();
    wait_done(&c, &s, &id).await;
    // One job: its two wavelengths solved once each (the counter counts
    // per-wavelength solves), one result.
    assert_eq!(metric(&c, &s, "polbrdf_solves_started_total").await, 2.0);
    assert_eq!(metric(&c, &s, "polbrdf_solves_succeeded_total").await, 1.0);
    assert_eq!(metric(&c, &s, "polbrdf_cache_misses_total").await, 1.0);
    let joined = metric(&c, &s, "polbrdf_jobs_joined_total").await;
    let hits = metric(&c, &s, "polbrdf_cache_hits_total").await;
    assert_eq!(joined + hits, 199.0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_input_gets_its_status_and_a_problem() {
    let dir = TempDir::new("bad");
    let s = Server::start(
        &dir.0.join("data"),
        &["--max-body-bytes", "2000", "--max-streams", "32"],
        &[],
    );
    let c = client();
    let layer = r#"{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}"#;
    // (body, expected JSON path or None, a fragment of the detail)
    let cases: Vec<(String, Option<&str>, &str)> = vec![
        // malformed JSON
        (r#"{"layers":[ "#.into(), None, "EOF"),
        // wrong type
        (
            r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":"high"}}}]}"#
                .into(),
            Some("layers[0].scatterer.rayleigh.albedo"),
            "invalid type",
        ),
        // unknown key
        (
            format!(r#"{{"layers":[{layer}],"colour":"red"}}"#),
            None,
            "colour",
        ),
        // NaN is not JSON
        (
            r#"{"layers":[{"optical_thickness":NaN,"scatterer":{"rayleigh":{"albedo":1}}}]}"#
                .into(),
            None,
            "",
        ),
        // a number too large for f64 (would be Inf)
        (
            r#"{"layers":[{"optical_thickness":1e999,"scatterer":{"rayleigh":{"albedo":1}}}]}"#
                .into(),
            None,
            "",
        ),
        // out of range: path and allowed range
        (
            r#"{"layers":[{"optical_thickness":-1,"scatterer":{"rayleigh":{"albedo":1}}}]}"#.into(),
            Some("layers[0].optical_thickness"),
            "[0, 1e12]",
        ),
        // missing field
        (r#"{"base":"black"}"#.into(), None, "layers"),
        // over a service cap
        (
            format!(r#"{{"layers":[{layer}],"solver":{{"streams":64}}}}"#),
            Some("solver.streams"),
            "[1, 32]",
        ),
        // not UTF-8 is handled below; an empty body
        (String::new(), None, ""),
    ];
    for (body, path, fragment) in cases {
        let (code, v, h) = post(&c, &s, &body).await;
        assert_problem(code, &v, &h, 422);
        if let Some(p) = path {
            assert_eq!(v["path"], p, "{body} -> {v}");
        } else {
            assert!(v["path"].is_string(), "{body} -> {v}");
        }
        assert!(
            v["detail"].as_str().unwrap().contains(fragment),
            "{body} -> {v}"
        );
    }
    let bytes = c
        .post(s.url("/v1/brdfs"))
        .header("content-type", "application/json")
        .body(vec![0xff, 0xfe, b'{'])
        .send()
        .await
        .unwrap();
    assert_eq!(bytes.status(), 422);

    // Body over the cap: 413, whether announced by Content-Length or not.
    let big = format!(
        r#"{{"layers":[{layer}],"wavelengths_nm":[{}]}}"#,
        vec!["500"; 1000].join(",")
    );
    let (code, v, h) = post(&c, &s, &big).await;
    assert_problem(code, &v, &h, 413);

    // Content type.
    let r = c
        .post(s.url("/v1/brdfs"))
        .header("content-type", "text/plain")
        .body(TINY)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 415);

    // Unknown and malformed ids, unknown routes: 404 problems.
    for path in [
        format!("/v1/brdfs/{}", "0".repeat(64)),
        format!("/v1/brdfs/{}/table", "0".repeat(64)),
        "/v1/brdfs/not-an-id".to_string(),
        "/v2/nothing".to_string(),
    ] {
        let r = c.get(s.url(&path)).send().await.unwrap();
        let (code, h) = (r.status().as_u16(), r.headers().clone());
        let v: Value = r.json().await.unwrap();
        assert_problem(code, &v, &h, 404);
    }
    // Nothing was queued by any of this.
    assert_eq!(metric(&c, &s, "polbrdf_cache_misses_total").await, 0.0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn full_queue_is_503_with_retry_after() {
    let dir = TempDir::new("full");
    let s = Server::start(&dir.0.join("data"), &["--max-queue", "0"], &[]);
    let c = client();
    let (code, v, h) = post(&c, &s, TINY).await;
    assert_problem(code, &v, &h, 503);
    assert_eq!(v["type"], "/problems/queue-full");
    assert!(h["retry-after"].to_str().unwrap().parse::<u64>().unwrap() >= 1);
    assert_eq!(metric(&c, &s, "polbrdf_jobs_rejected_total").await, 1.0);
    // Refused submissions leave no row behind.
    let id = v["id"].as_str();
    assert!(id.is_none());
    let text = c
        .get(s.url("/metrics"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(text.contains("polbrdf_jobs{state=\"queued\"} 0"), "{text}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bearer_token_guards_writes_and_optionally_reads() {
    let dir = TempDir::new("auth");
    let c = client();
    {
        let s = Server::start(&dir.0.join("a"), &[], &[("POLBRDF_TOKEN", "s3cret")]);
        let (code, v, h) = post(&c, &s, TINY).await;
        assert_problem(code, &v, &h, 401);
        assert!(h.contains_key("www-authenticate"));
        let r = c
            .post(s.url("/v1/brdfs"))
            .header("content-type", "application/json")
            .bearer_auth("wrong")
            .body(TINY)
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 401);
        let r = c
            .post(s.url("/v1/brdfs"))
            .header("content-type", "application/json")
            .bearer_auth("s3cret")
            .body(TINY)
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 202);
        let id = r.json::<Value>().await.unwrap()["id"]
            .as_str()
            .unwrap()
            .to_string();
        // Reads are open without --token-reads.
        wait_done(&c, &s, &id).await;
        assert_eq!(get_json(&c, &s, "/metrics").await.0, 200);
    }
    {
        let s = Server::start(
            &dir.0.join("b"),
            &["--token", "s3cret", "--token-reads"],
            &[],
        );
        let (code, _) = get_json(&c, &s, &format!("/v1/brdfs/{}", "0".repeat(64))).await;
        assert_eq!(code, 401);
        assert_eq!(get_json(&c, &s, "/metrics").await.0, 401);
        assert_eq!(get_json(&c, &s, "/healthz").await.0, 200);
        assert_eq!(get_json(&c, &s, "/readyz").await.0, 200);
        let r = c
            .get(s.url(&format!("/v1/brdfs/{}", "0".repeat(64))))
            .bearer_auth("s3cret")
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 404);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_failed_job_carries_its_typed_error() {
    let dir = TempDir::new("failed");
    // A tolerance may pick at most 4 streams here: whether 1e-10 is reached
    // there is known only by solving, so the job fails deterministically.
    let s = Server::start(&dir.0.join("data"), &["--max-streams", "4"], &[]);
    let c = client();
    let spec = r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":0.9}}}],
                   "base":{"lambertian":{"albedo":0.5}},"solver":{"tolerance":1e-10}}"#;
    let (code, v, _) = post(&c, &s, spec).await;
    assert_eq!(code, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    let r = wait_for(&c, &s, &id, std::time::Duration::from_secs(60), |v| {
        v["status"] == "failed"
    })
    .await;
    let e = &r["error"];
    assert_eq!(e["type"], "/problems/solver-error", "{r}");
    let detail = e["detail"].as_str().unwrap();
    assert!(
        detail.contains("solver.tolerance") && detail.contains("was not reached"),
        "{r}"
    );
    assert_eq!(e["retryable"], false, "{r}");
    assert!(r["result"].is_null());

    // The table of a failed job: 409 with the job's error.
    let t = c
        .get(s.url(&format!("/v1/brdfs/{id}/table")))
        .send()
        .await
        .unwrap();
    let (code, h) = (t.status().as_u16(), t.headers().clone());
    let p: Value = t.json().await.unwrap();
    assert_problem(code, &p, &h, 409);
    assert_eq!(p["type"], "/problems/job-failed");

    // Deterministic: a repeated POST answers from the cache, no new solve.
    let (code, v, _) = post(&c, &s, spec).await;
    assert_eq!(code, 200, "{v}");
    assert_eq!(v["status"], "failed");
    assert_eq!(metric(&c, &s, "polbrdf_solves_started_total").await, 1.0);
    assert_eq!(metric(&c, &s, "polbrdf_solves_failed_total").await, 1.0);
}

/// Smallest N with |g|^l ≤ 1e-4 for every l ≥ 2N: the streams a
/// Henyey–Greenstein series (|β_l|/(2l+1) = |g|^l) needs when it has no
/// forward peak (docs/spec.md, `solver.streams`).
fn hg_needs(g: f64) -> usize {
    let last_big = (0..)
        .take_while(|&l| g.abs().powi(l) > 1e-4)
        .last()
        .unwrap() as usize;
    (last_big + 1).div_ceil(2)
}

/// What the solver or the physics would refuse seconds after a 202, and the
/// spec alone decides, is refused at POST: 422 naming the field and what
/// would work; nothing is queued.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn solve_time_refusals_are_decided_at_submission() {
    let dir = TempDir::new("preflight");
    let s = Server::start(&dir.0.join("data"), &["--max-streams", "32"], &[]);
    let c = client();
    let hg = |g: f64, solver: &str| {
        format!(
            r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"henyey_greenstein":{{"albedo":1,"g":{g}}}}}}}],"solver":{solver}}}"#
        )
    };
    // The same backward-peaked series as an expansion layer, β_l = (2l+1) g^l.
    let backward: Vec<String> = (0..200)
        .map(|l| format!("{}", (2 * l + 1) as f64 * (-0.9f64).powi(l)))
        .collect();
    let expansion = format!(
        r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"expansion":{{"albedo":1,"beta":[{}]}}}}}}],"solver":{{"tolerance":1e-3}}}}"#,
        backward.join(",")
    );
    let (lo, hi) = polbrdf::physics::materials::find("silver")
        .unwrap()
        .wavelength_range_nm();
    let silver = format!(
        r#"{{"layers":[{{"optical_thickness":0.1,"scatterer":{{"rayleigh":{{"albedo":1}}}}}}],
            "base":{{"fresnel":{{"material":"silver"}}}},"wavelengths_nm":[{lo},5000],"solver":{{"streams":4}}}}"#
    );
    let matched = r#"{"layers":[{"optical_thickness":1,"scatterer":{"mie":{"material":{"n":1.33,"k":0},
                      "radius_um":0.2,"host_index":1.33}}}],"wavelengths_nm":[500]}"#;
    assert_eq!(hg_needs(-0.8), 21);
    assert!(hg_needs(-0.9) > 32);
    // (body, path, fragments of the detail)
    let cases: Vec<(String, &str, Vec<String>)> = vec![
        // HG g = -0.8 at the default 16 streams: needs 21 (docs/spec.md).
        (
            hg(-0.8, "{}"),
            "solver.streams",
            vec!["at least 21 streams".into()],
        ),
        // A tolerance picks at most 32 streams here; g = -0.9 needs more.
        (
            hg(-0.9, r#"{"tolerance":1e-3}"#),
            "solver.tolerance",
            vec![format!("at least {} streams", hg_needs(-0.9)), "32".into()],
        ),
        (
            expansion,
            "solver.tolerance",
            vec![format!("at least {} streams", hg_needs(-0.9))],
        ),
        // No refractive-index data at 5000 nm: name the wavelength and the range.
        (
            silver,
            "wavelengths_nm[1]",
            vec!["base.fresnel.material".into(), format!("[{lo}, {hi}] nm")],
        ),
        // An index-matched sphere does not scatter.
        (
            matched.into(),
            "layers[0].scatterer.mie.material",
            vec!["binder".into()],
        ),
    ];
    for (body, path, fragments) in cases {
        let (code, v, h) = post(&c, &s, &body).await;
        assert_problem(code, &v, &h, 422);
        assert_eq!(v["type"], "/problems/invalid-spec", "{v}");
        assert_eq!(v["path"], path, "{v}");
        let detail = v["detail"].as_str().unwrap();
        assert!(detail.starts_with(&format!("{path}: ")), "{v}");
        for f in fragments {
            assert!(detail.contains(&f), "{f:?} not in {v}");
        }
    }
    // With what the refusals name, the same materials are accepted.
    for ok in [
        hg(-0.8, r#"{"streams":21}"#),
        hg(-0.8, r#"{"tolerance":1e-3}"#),
    ] {
        let (code, v, _) = post(&c, &s, &ok).await;
        assert!(code == 202 || code == 200, "{ok} -> {code} {v}");
    }
    assert_eq!(metric(&c, &s, "polbrdf_cache_misses_total").await, 2.0);
}

/// A body with anything but whitespace after its JSON document is refused,
/// naming where the trailing data starts: specs and eval bodies.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn trailing_data_after_the_json_document_is_refused() {
    let dir = TempDir::new("trailing");
    let s = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();
    // Where the text after the first document starts (1-based), counted here.
    let position = |first: &str, gap: &str| {
        let before = format!("{first}{gap}");
        let line = before.matches('\n').count() + 1;
        let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
        format!("trailing data after the JSON document at line {line} column {column}")
    };
    for (gap, rest) in [
        ("", r#"{"solver":{"streams":99999}} garbage"#),
        ("\n  ", "xx"),
        (" ", "]"),
    ] {
        let body = format!("{TINY}{gap}{rest}");
        let (code, v, h) = post(&c, &s, &body).await;
        assert_problem(code, &v, &h, 422);
        assert_eq!(v["path"], "$", "{v}");
        assert!(
            v["detail"].as_str().unwrap().contains(&position(TINY, gap)),
            "{body:?} -> {v}"
        );
    }
    // Whitespace after the document is fine.
    let (code, v, _) = post(&c, &s, &format!("{TINY} \n\t\r\n")).await;
    assert_eq!(code, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    wait_done(&c, &s, &id).await;
    // Eval bodies.
    let points = r#"{"points":[{"theta_i_deg":10,"phi_i_deg":0,"theta_o_deg":20,"phi_o_deg":30}]}"#;
    let eval = |body: String| {
        c.post(s.url(&format!("/v1/brdfs/{id}/eval")))
            .header("content-type", "application/json")
            .body(body)
            .send()
    };
    let r = eval(points.to_string()).await.unwrap();
    assert_eq!(r.status(), 200);
    let r = eval(format!(r#"{points} {{"points":[]}}"#)).await.unwrap();
    let (code, h) = (r.status().as_u16(), r.headers().clone());
    let v: Value = r.json().await.unwrap();
    assert_problem(code, &v, &h, 422);
    assert_eq!(v["path"], "$", "{v}");
    assert!(
        v["detail"]
            .as_str()
            .unwrap()
            .contains(&position(points, " ")),
        "{v}"
    );
}

/// The smaller edges of the API: the cache listing, one-key scatterers,
/// non-object specs, unparsable numbers, table-query errors, 405s.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn listing_and_error_edges() {
    let dir = TempDir::new("edges");
    let s = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();

    // Three jobs, submitted in this order (a few ms apart: created_at is in ms).
    let mut ids = Vec::new();
    for albedo in [0.1, 0.2, 0.3] {
        let spec = TINY.replace("0.9", &albedo.to_string());
        let (code, v, _) = post(&c, &s, &spec).await;
        assert_eq!(code, 202, "{v}");
        ids.push(v["id"].as_str().unwrap().to_string());
        tokio::time::sleep(std::time::Duration::from_millis(5)).await;
    }
    for id in &ids {
        wait_done(&c, &s, id).await;
    }
    let newest_first: Vec<String> = ids.iter().rev().cloned().collect();
    let page_ids = |v: &Value| -> Vec<String> {
        v["items"]
            .as_array()
            .unwrap()
            .iter()
            .map(|i| i["id"].as_str().unwrap().to_string())
            .collect()
    };
    let (code, all) = get_json(&c, &s, "/v1/brdfs").await;
    assert_eq!(code, 200, "{all}");
    assert_eq!(page_ids(&all), newest_first);
    assert!(all["next"].is_null(), "{all}");
    let item = &all["items"][0];
    let mut keys: Vec<&str> = item
        .as_object()
        .unwrap()
        .keys()
        .map(|k| k.as_str())
        .collect();
    keys.sort();
    assert_eq!(
        keys,
        [
            "base",
            "created_at",
            "error_estimate",
            "finished_at",
            "id",
            "layers",
            "links",
            "materials",
            "progress",
            "size",
            "solve_time_ms",
            "status",
            "streams",
            "tolerance",
            "updated_at",
            "wavelengths",
            "wavelengths_nm"
        ]
    );
    assert_eq!(item["status"], "done");
    assert_eq!(item["wavelengths"], 1);
    assert!(item["error_estimate"].as_f64().unwrap() > 0.0);
    // Pages of two: the cursor continues where the first page ended.
    let (code, first) = get_json(&c, &s, "/v1/brdfs?limit=2").await;
    assert_eq!(code, 200, "{first}");
    assert_eq!(page_ids(&first), newest_first[..2]);
    let cursor = first["next"].as_str().expect("a next cursor").to_string();
    let (code, second) = get_json(&c, &s, &format!("/v1/brdfs?limit=2&cursor={cursor}")).await;
    assert_eq!(code, 200, "{second}");
    assert_eq!(page_ids(&second), newest_first[2..]);
    assert!(second["next"].is_null(), "{second}");
    for (query, path) in [
        ("limit=0", "limit"),
        ("limit=501", "limit"),
        ("limit=ten", "limit"),
        ("cursor=nonsense", "cursor"),
    ] {
        let r = c
            .get(s.url(&format!("/v1/brdfs?{query}")))
            .send()
            .await
            .unwrap();
        let (code, h) = (r.status().as_u16(), r.headers().clone());
        let v: Value = r.json().await.unwrap();
        assert_problem(code, &v, &h, 422);
        assert_eq!(v["path"], path, "{query} -> {v}");
    }
    let (_, v) = get_json(&c, &s, "/v1/brdfs?limit=501").await;
    assert!(v["detail"].as_str().unwrap().contains("[1, 500]"), "{v}");

    // Spec errors that name the field and what is allowed.
    let cases: Vec<(&str, &str, &str)> = vec![
        (
            r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1},"henyey_greenstein":{"albedo":1,"g":0.5}}}]}"#,
            "layers[0].scatterer",
            "layers[0].scatterer: exactly one of mie, expansion, rayleigh, henyey_greenstein",
        ),
        ("[]", "$", "the spec must be a JSON object"),
        (
            r#"{"layers":[{"optical_thickness":NaN,"scatterer":{"rayleigh":{"albedo":1}}}]}"#,
            "layers[0].optical_thickness",
            "[0, 1e12]",
        ),
        (
            r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1e999}}}]}"#,
            "layers[0].scatterer.rayleigh.albedo",
            "[0, 1]",
        ),
    ];
    for (body, path, fragment) in cases {
        let (code, v, h) = post(&c, &s, body).await;
        assert_problem(code, &v, &h, 422);
        assert_eq!(v["path"], path, "{body} -> {v}");
        assert!(
            v["detail"].as_str().unwrap().contains(fragment),
            "{body} -> {v}"
        );
    }

    // A bad table format: its own problem type and title, the allowed formats.
    let r = c
        .get(s.url(&format!("/v1/brdfs/{}/table?format=xml", ids[0])))
        .send()
        .await
        .unwrap();
    let (code, h) = (r.status().as_u16(), r.headers().clone());
    let v: Value = r.json().await.unwrap();
    assert_problem(code, &v, &h, 422);
    assert_eq!(v["title"], "Invalid table request", "{v}");
    assert_eq!(v["type"], "/problems/invalid-table-query", "{v}");
    assert_eq!(v["path"], "format", "{v}");
    for f in ["binary", "npy", "json", "mitsuba"] {
        assert!(v["detail"].as_str().unwrap().contains(f), "{v}");
    }
    let r = c
        .get(s.url(&format!("/v1/brdfs/{}/table?colour=red", ids[0])))
        .send()
        .await
        .unwrap();
    let v: Value = r.json().await.unwrap();
    assert_eq!(v["path"], "colour", "{v}");

    // A known route with another method: 405 problem+json with Allow.
    for (method, path, allowed) in [
        (
            reqwest::Method::DELETE,
            "/v1/brdfs".to_string(),
            vec!["GET", "POST"],
        ),
        (
            reqwest::Method::PUT,
            format!("/v1/brdfs/{}", ids[0]),
            vec!["GET"],
        ),
        (
            reqwest::Method::POST,
            format!("/v1/brdfs/{}/table", ids[0]),
            vec!["GET", "HEAD"],
        ),
        (reqwest::Method::POST, "/healthz".to_string(), vec!["GET"]),
    ] {
        let r = c
            .request(method.clone(), s.url(&path))
            .send()
            .await
            .unwrap();
        let (code, h) = (r.status().as_u16(), r.headers().clone());
        let v: Value = r.json().await.unwrap();
        assert_problem(code, &v, &h, 405);
        assert_eq!(v["type"], "/problems/method-not-allowed", "{v}");
        let allow = h["allow"].to_str().unwrap().to_string();
        for m in allowed {
            assert!(
                allow.split(',').any(|x| x.trim() == m),
                "{method} {path}: Allow {allow}"
            );
        }
        assert!(
            !allow.split(',').any(|x| x.trim() == method.as_str()),
            "{allow}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tolerance_spec_reports_the_solver_error_estimate() {
    let dir = TempDir::new("tolerance");
    let s = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();
    let spec = r#"{"layers":[{"optical_thickness":0.5,"scatterer":{"rayleigh":{"albedo":0.9}}}],
                   "solver":{"tolerance":1e-3}}"#;
    let (code, v, _) = post(&c, &s, spec).await;
    assert_eq!(code, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    let r = wait_done(&c, &s, &id).await;
    // The canonical spec keeps the tolerance (no explicit streams).
    assert_eq!(r["spec"]["solver"]["tolerance"], 1e-3, "{r}");
    assert!(r["spec"]["solver"]["streams"].is_null(), "{r}");
    let e = r["error_estimate"].as_f64().expect("an estimate");
    assert!((0.0..=1e-3).contains(&e), "{r}");
    // The table records the streams chosen and the same estimate.
    let bytes = c
        .get(s.url(&format!("/v1/brdfs/{id}/table")))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let table = polbrdf::brdf::format::from_bytes(&bytes).unwrap();
    let w = &table.metadata.wavelengths[0];
    assert_eq!(w.error_estimate.as_ref().unwrap().max_err_f11, e);
    assert_eq!(w.streams, w.error_estimate.as_ref().unwrap().streams[2]);
    assert_eq!(w.wall_time_ms, 0.0);
}
