//! `POST /v1/scenes` (docs/service.md): a scene's material spheres are
//! submitted as their reduced requests through the path `POST /v1/brdfs`
//! uses (same ids, same jobs), and bad scenes are 422 naming the path.

mod common;
mod service_support;

use serde_json::{Value, json};
use service_support::{Server, TempDir, client, post, wait_done};

fn rayleigh_spec(albedo: f64) -> Value {
    json!({"layers": [{"optical_thickness": 0.3,
                       "scatterer": {"rayleigh": {"albedo": albedo}}}],
           "solver": {"streams": 4}})
}

/// Two spheres of one material, one of another, and a table sphere.
fn scene() -> Value {
    json!({
        "camera": {"position": [0, -6, 2], "look_at": [0, 0, 0.8], "fov_deg": 30,
                   "width": 8, "height": 8},
        "lights": [{"point": {"position": [3, -3, 4], "stokes": [10, 0, 0, 0]}}],
        "spheres": [
            {"center": [0, 0, 1], "radius": 1, "name": "a", "material": rayleigh_spec(1.0)},
            {"center": [2, 0, 1], "radius": 1, "name": "b", "material": rayleigh_spec(1.0)},
            {"center": [4, 0, 1], "radius": 1, "name": "c", "material": rayleigh_spec(0.5)},
            {"center": [6, 0, 1], "radius": 1, "table": "http://example.invalid/v1/brdfs/x"}
        ],
        "floor": {"albedo": 0.5},
        "wavelengths_nm": [550],
        "tolerance": 1e-2
    })
}

async fn post_scene(c: &reqwest::Client, s: &Server, body: &str) -> (u16, Value) {
    let r = c
        .post(s.url("/v1/scenes"))
        .header("content-type", "application/json")
        .body(body.to_string())
        .send()
        .await
        .unwrap();
    let code = r.status().as_u16();
    let text = r.text().await.unwrap();
    (
        code,
        serde_json::from_str(&text).unwrap_or(Value::String(text)),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scene_submits_its_reduced_requests() {
    let d = TempDir::new("service-scenes");
    let s = Server::start(&d.0.join("data"), &[], &[]);
    let c = client();
    let (code, v) = post_scene(&c, &s, &scene().to_string()).await;
    assert!(code == 202 || code == 200, "{code} {v}");
    let m = v["materials"].as_array().unwrap();
    let names: Vec<&str> = m.iter().map(|x| x["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["a", "b", "c"], "table spheres are not submitted");
    assert_eq!(m[0]["id"], m[1]["id"], "one request for one reduced spec");
    assert_ne!(m[0]["id"], m[2]["id"]);
    for x in m {
        assert_eq!(x["covered_by"], json!([]));
        let id = x["id"].as_str().unwrap();
        assert_eq!(x["links"]["self"], json!(format!("/v1/brdfs/{id}")));
    }
    // The same path as POST /v1/brdfs: the reduced spec the plan prints,
    // submitted there, is the same id.
    let dir = d.0.clone();
    let plan = tokio::task::spawn_blocking(move || {
        let p = dir.join("scene.json");
        std::fs::write(&p, scene().to_string()).unwrap();
        common::ok(&["scene", "plan", p.to_str().unwrap()])
    })
    .await
    .unwrap();
    for (k, x) in m.iter().enumerate() {
        let reduced = plan["materials"][k]["spec"].clone();
        assert_eq!(reduced["solver"], json!({"tolerance": 1e-2}));
        let (code, r, _) = post(&c, &s, &reduced.to_string()).await;
        assert!(code == 200 || code == 202, "{r}");
        assert_eq!(r["id"], x["id"]);
    }
    for x in m {
        wait_done(&c, &s, x["id"].as_str().unwrap()).await;
    }
    let (code, v2) = post_scene(&c, &s, &scene().to_string()).await;
    assert_eq!(code, 200, "{v2}");
    assert!(
        v2["materials"]
            .as_array()
            .unwrap()
            .iter()
            .all(|x| x["status"] == "done")
    );

    // Bad scenes: 422 naming the path.
    let mut bad = scene();
    bad["spheres"][0]["material"] = json!("paint.json");
    let (code, p) = post_scene(&c, &s, &bad.to_string()).await;
    assert_eq!(code, 422, "{p}");
    assert_eq!(p["path"], "spheres[0].material", "{p}");
    let mut bad = scene();
    bad["spheres"][2]["material"]["layers"][0]["optical_thickness"] = json!(-1);
    let (code, p) = post_scene(&c, &s, &bad.to_string()).await;
    assert_eq!(code, 422, "{p}");
    assert_eq!(
        p["path"], "spheres[2].material.layers[0].optical_thickness",
        "{p}"
    );
    let mut bad = scene();
    bad["camera"]["fov_deg"] = json!(500);
    let (code, p) = post_scene(&c, &s, &bad.to_string()).await;
    assert_eq!(code, 422, "{p}");
    assert_eq!(p["path"], "camera.fov_deg", "{p}");
}

/// `polbrdf render --server URL` solves the material spheres on the
/// service and renders exactly what the local solve renders.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn render_with_a_server_equals_the_local_render() {
    let d = TempDir::new("service-scenes-render");
    let s = Server::start(&d.0.join("data"), &[], &[]);
    let url = s.url("");
    let dir = d.0.clone();
    tokio::task::spawn_blocking(move || {
        std::fs::write(dir.join("paint.json"), rayleigh_spec(0.9).to_string()).unwrap();
        let mut v = scene();
        v["spheres"] = json!([
            {"center": [0, 0, 1], "radius": 1, "material": "paint.json"},
            {"center": [2, 0, 1], "radius": 1, "material": rayleigh_spec(1.0)}
        ]);
        let p = dir.join("scene.json");
        std::fs::write(&p, v.to_string()).unwrap();
        let p = p.to_string_lossy().into_owned();
        let (a, b) = (
            dir.join("a").to_string_lossy().into_owned(),
            dir.join("b").to_string_lossy().into_owned(),
        );
        let remote = common::ok(&["render", &p, "-o", &a, "--no-progress", "--server", &url]);
        let local = common::ok(&["render", &p, "-o", &b, "--no-progress"]);
        assert!(
            remote["solved"].as_array().unwrap().is_empty(),
            "solved remotely"
        );
        assert_eq!(local["solved"].as_array().unwrap().len(), 2);
        let ra = std::fs::read(format!("{a}_stokes.npy")).unwrap();
        let rb = std::fs::read(format!("{b}_stokes.npy")).unwrap();
        assert!(ra == rb, "remote and local renders differ");
    })
    .await
    .unwrap();
}
