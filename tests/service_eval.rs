//! Point evaluation of stored BRDF tables through the real `polbrdf serve`:
//! `GET`/`POST /v1/brdfs/{id}/eval` agree with evaluating the downloaded
//! table locally (`polbrdf::brdf`), report the specular term of a mirror
//! base at mirror pairs only, and refuse bad parameters with a problem
//! naming the parameter.

mod service_support;

use polbrdf::brdf::{Directions, Table, format};
use serde_json::{Value, json};
use service_support::*;

async fn done_table(c: &reqwest::Client, s: &Server, spec: &str) -> (String, Table) {
    let (code, v, _) = post(c, s, spec).await;
    assert!(code == 202 || code == 200, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    wait_done(c, s, &id).await;
    let bytes = c
        .get(s.url(&format!("/v1/brdfs/{id}/table")))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    (id, format::from_bytes(&bytes).unwrap())
}

fn mueller(v: &Value) -> [[f64; 4]; 4] {
    serde_json::from_value(v.clone()).unwrap()
}

/// Equal up to the last bit lost by serde_json's default float parser.
fn same(a: [[f64; 4]; 4], b: [[f64; 4]; 4]) {
    for (ra, rb) in a.iter().zip(&b) {
        for (x, y) in ra.iter().zip(rb) {
            assert!(
                (x - y).abs() <= 1e-15 * x.abs().max(y.abs()),
                "{a:?}\n{b:?}"
            );
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn eval_agrees_with_the_table_and_names_bad_parameters() {
    let dir = TempDir::new("eval");
    let s = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();

    // Before the job is done: 409; unknown id: 404.
    let (code, v, _) = post(&c, &s, &slow_spec(2, 0.5)).await;
    assert_eq!(code, 202, "{v}");
    let pending = v["id"].as_str().unwrap().to_string();
    let (code, p) = get_json(
        &c,
        &s,
        &format!(
            "/v1/brdfs/{pending}/eval?theta_i_deg=0&phi_i_deg=0&theta_o_deg=0&phi_o_deg=0&wavelength_nm=400"
        ),
    )
    .await;
    assert!(code == 409 || code == 200, "{code} {p}");
    let (code, _) = get_json(
        &c,
        &s,
        &format!(
            "/v1/brdfs/{}/eval?theta_i_deg=0&phi_i_deg=0&theta_o_deg=0&phi_o_deg=0",
            "0".repeat(64)
        ),
    )
    .await;
    assert_eq!(code, 404);

    let (id, table) = done_table(&c, &s, TINY).await;

    // GET: one pair, immutable, equal to the local evaluation.
    let r = c
        .get(s.url(&format!(
            "/v1/brdfs/{id}/eval?theta_i_deg=30&phi_i_deg=10&theta_o_deg=47.5&phi_o_deg=200"
        )))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(
        r.headers()["cache-control"],
        "public, max-age=31536000, immutable"
    );
    let v: Value = r.json().await.unwrap();
    assert_eq!(v["units"], "1/sr");
    assert_eq!(v["id"], id.as_str());
    let d = Directions {
        theta_i_deg: 30.0,
        phi_i_deg: 10.0,
        theta_o_deg: 47.5,
        phi_o_deg: 200.0,
    };
    let local = table.eval(&d, None).unwrap();
    same(mueller(&v["points"][0]["mueller"]), local);
    assert!(local[0][0] > 0.0);
    assert!(v["points"][0]["specular"].is_null());

    // POST: many pairs, in order.
    let pts = json!([
        {"theta_i_deg": 0, "phi_i_deg": 0, "theta_o_deg": 0, "phi_o_deg": 0},
        {"theta_i_deg": 60, "phi_i_deg": 0, "theta_o_deg": 89.9, "phi_o_deg": 90},
        {"theta_i_deg": 10, "phi_i_deg": -30, "theta_o_deg": 20, "phi_o_deg": 330}
    ]);
    let r = c
        .post(s.url(&format!("/v1/brdfs/{id}/eval")))
        .json(&json!({ "points": pts }))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let v: Value = r.json().await.unwrap();
    let got = v["points"].as_array().unwrap();
    assert_eq!(got.len(), 3);
    for (g, p) in got.iter().zip(pts.as_array().unwrap()) {
        let d: Directions = serde_json::from_value(p.clone()).unwrap();
        same(mueller(&g["mueller"]), table.eval(&d, None).unwrap());
        assert_eq!(g["theta_o_deg"].as_f64(), p["theta_o_deg"].as_f64());
    }

    // Bad parameters: 422 naming the parameter.
    let bad = |q: &str| {
        let (c, url) = (c.clone(), s.url(&format!("/v1/brdfs/{id}/eval?{q}")));
        async move {
            let r = c.get(url).send().await.unwrap();
            let code = r.status().as_u16();
            let ct = r.headers()["content-type"].to_str().unwrap().to_string();
            (code, ct, r.json::<Value>().await.unwrap())
        }
    };
    let (code, ct, p) = bad("theta_i_deg=95&phi_i_deg=0&theta_o_deg=0&phi_o_deg=0").await;
    assert_eq!(
        (code, ct.as_str()),
        (422, "application/problem+json"),
        "{p}"
    );
    assert_eq!(p["type"], "/problems/invalid-query");
    assert_eq!(p["path"], "theta_i_deg", "{p}");
    assert!(p["detail"].as_str().unwrap().contains("[0, 90]"), "{p}");
    let (code, _, p) = bad("theta_i_deg=10&phi_i_deg=0&theta_o_deg=0").await;
    assert_eq!(code, 422, "{p}");
    assert!(p["detail"].as_str().unwrap().contains("phi_o_deg"), "{p}");
    let (code, _, p) = bad("theta_i_deg=abc&phi_i_deg=0&theta_o_deg=0&phi_o_deg=0").await;
    assert_eq!(code, 422, "{p}");
    let r = c
        .post(s.url(&format!("/v1/brdfs/{id}/eval")))
        .json(&json!({"points": [
            {"theta_i_deg": 0, "phi_i_deg": 0, "theta_o_deg": 0, "phi_o_deg": 0},
            {"theta_i_deg": 0, "phi_i_deg": 0, "theta_o_deg": -3, "phi_o_deg": 0}
        ]}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 422);
    let p: Value = r.json().await.unwrap();
    assert_eq!(p["path"], "points[1].theta_o_deg", "{p}");
    let r = c
        .post(s.url(&format!("/v1/brdfs/{id}/eval")))
        .json(&json!({"points": [], "colour": 1}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 422);
    let p: Value = r.json().await.unwrap();
    assert_eq!(p["path"], "colour", "{p}");

    // A multi-wavelength table: inside the range interpolates, outside is
    // refused naming the wavelength.
    let (id2, table2) = done_table(&c, &s, &slow_spec(2, 0.5)).await;
    assert_eq!(id2, pending);
    let (code, v) = get_json(
        &c,
        &s,
        &format!(
            "/v1/brdfs/{id2}/eval?theta_i_deg=20&phi_i_deg=0&theta_o_deg=40&phi_o_deg=90&wavelength_nm=405"
        ),
    )
    .await;
    assert_eq!(code, 200, "{v}");
    let d = Directions {
        theta_i_deg: 20.0,
        phi_i_deg: 0.0,
        theta_o_deg: 40.0,
        phi_o_deg: 90.0,
    };
    same(
        mueller(&v["points"][0]["mueller"]),
        table2.eval(&d, Some(405.0)).unwrap(),
    );
    assert_eq!(v["wavelength_nm"], 405.0);
    let (code, p) = get_json(
        &c,
        &s,
        &format!(
            "/v1/brdfs/{id2}/eval?theta_i_deg=20&phi_i_deg=0&theta_o_deg=40&phi_o_deg=90&wavelength_nm=800"
        ),
    )
    .await;
    assert_eq!(code, 422, "{p}");
    assert_eq!(p["path"], "wavelength_nm", "{p}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn mirror_base_reports_the_specular_term_at_mirror_pairs() {
    let dir = TempDir::new("eval-mirror");
    let s = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();
    let spec = r#"{"layers":[{"optical_thickness":0.2,"scatterer":{"rayleigh":{"albedo":0.9}}}],
                   "base":{"fresnel":{"material":{"n":1.5,"k":0}}},"solver":{"streams":4}}"#;
    let (id, table) = done_table(&c, &s, spec).await;
    let (code, v) = get_json(
        &c,
        &s,
        &format!("/v1/brdfs/{id}/eval?theta_i_deg=40&phi_i_deg=15&theta_o_deg=40&phi_o_deg=195"),
    )
    .await;
    assert_eq!(code, 200, "{v}");
    let d = Directions {
        theta_i_deg: 40.0,
        phi_i_deg: 15.0,
        theta_o_deg: 40.0,
        phi_o_deg: 195.0,
    };
    let local = table.specular(&d, None).unwrap().unwrap();
    same(mueller(&v["points"][0]["specular"]), local);
    assert!(local[0][0] > 0.0);
    let (_, v) = get_json(
        &c,
        &s,
        &format!("/v1/brdfs/{id}/eval?theta_i_deg=40&phi_i_deg=15&theta_o_deg=41&phi_o_deg=195"),
    )
    .await;
    assert!(v["points"][0]["specular"].is_null(), "{v}");
}
