//! `POST /v1/optics` on the real `polbrdf serve`: the layer optics report
//! of a paint film (docs/spec.md, Layer optics report) is the one
//! `polbrdf mie --spec` prints for the same file, its optical thickness is
//! `d (Σ N_i C_ext,i + binder absorption)` of its own pigment rows, a dense
//! film is warned about, nothing is queued or stored, and bad input gets
//! the problem+json of `POST /v1/brdfs`.

mod service_support;

use serde_json::{Value, json};
use service_support::*;

/// The gallery's white paint: rutile at 20 % PVC, 25 µm of acrylic.
fn white_paint() -> Value {
    json!({
        "wavelengths_nm": [450, 550, 650],
        "layers": [{
            "thickness_um": 25,
            "pigments": [{"material": "TiO2",
                          "size_distribution": {"lognormal": {"r_g_um": 0.12, "sigma_g": 1.35}},
                          "volume_fraction": 0.2}],
            "binder": "acrylic",
        }],
        "base": "black",
        "solver": {"streams": 16},
    })
}

async fn post_optics(c: &reqwest::Client, s: &Server, body: &str, ct: &str) -> (u16, Value) {
    let r = c
        .post(s.url("/v1/optics"))
        .header("content-type", ct)
        .body(body.to_string())
        .send()
        .await
        .unwrap();
    let status = r.status().as_u16();
    let text = r.text().await.unwrap();
    (
        status,
        serde_json::from_str(&text).unwrap_or(Value::String(text)),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn optics_report_of_a_film_over_http() {
    let dir = TempDir::new("optics");
    let s = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();
    let spec = white_paint();
    let (code, v) = post_optics(&c, &s, &spec.to_string(), "application/json").await;
    assert_eq!(code, 200, "{v}");

    // The same report as the CLI's for the same spec.
    let file = dir.0.join("paint.json");
    std::fs::write(&file, spec.to_string()).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_polbrdf"))
        .args(["mie", "--spec", file.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cli: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v, cli);

    let layer = &v["layers"][0];
    assert_eq!(layer["path"], "layers[0]");
    assert_eq!(layer["form"], "film");
    assert_eq!(layer["pigment_volume_concentration"], json!(0.2));
    let optics = layer["optics"].as_array().unwrap();
    assert_eq!(optics.len(), 3);
    for (o, wl) in optics.iter().zip([450.0, 550.0, 650.0]) {
        assert_eq!(o["wavelength_nm"].as_f64(), Some(wl));
        let p = &o["pigments"][0];
        let n = p["number_density_per_um3"].as_f64().unwrap();
        let c_ext = p["c_ext_um2"].as_f64().unwrap();
        let v_um3 = p["volume_um3"].as_f64().unwrap();
        let binder = o["binder_absorption_per_um"].as_f64().unwrap();
        let tau = o["optical_thickness"].as_f64().unwrap();
        assert!((n * v_um3 - 0.2).abs() < 1e-14, "N V = {}", n * v_um3);
        let want = 25.0 * (n * c_ext + binder);
        assert!((tau - want).abs() <= 1e-12 * want, "{tau} vs {want}");
        // A white paint: rutile scatters forward and hardly absorbs; the
        // acrylic absorbs a little.
        let (albedo, g) = (o["albedo"].as_f64().unwrap(), o["g"].as_f64().unwrap());
        assert!(albedo > 0.999 && albedo < 1.0, "{albedo}");
        assert!(g > 0.0 && g < 1.0, "{g}");
        assert!(binder > 0.0, "acrylic absorbs: {binder}");
        let beta0 = o["expansion"]["beta"][0].as_f64().unwrap();
        assert!((beta0 - 1.0).abs() < 1e-12, "beta_0 = {beta0}");
    }
    // 20 % PVC is above the independent-scattering limit.
    let w = v["warnings"].as_array().unwrap();
    assert_eq!(w.len(), 1, "{v}");
    assert_eq!(w[0]["path"], "layers[0].pigments");
    assert!(w[0]["message"].as_str().unwrap().contains("20.0 %"), "{v}");

    // Nothing was queued or stored.
    let (code, list) = get_json(&c, &s, "/v1/brdfs").await;
    assert_eq!(code, 200);
    assert_eq!(list["items"], json!([]), "{list}");

    // Bad input: the problem+json of POST /v1/brdfs, with the path.
    let mut bad = white_paint();
    bad["layers"][0]["pigments"][0]["volume_fraction"] = json!(0);
    let (code, p) = post_optics(&c, &s, &bad.to_string(), "application/json").await;
    assert_eq!(code, 422, "{p}");
    assert_eq!(p["path"], "layers[0].pigments[0].volume_fraction", "{p}");
    let mut short = white_paint();
    short["wavelengths_nm"] = json!([350]);
    let (code, p) = post_optics(&c, &s, &short.to_string(), "application/json").await;
    assert_eq!(code, 422, "{p}");
    // The wavelength is the value to change; the detail names the data.
    assert_eq!(p["path"], "wavelengths_nm[0]", "{p}");
    let detail = p["detail"].as_str().unwrap();
    assert!(
        detail.contains("layers[0].pigments[0].material") && detail.contains("[430, 1530] nm"),
        "{p}"
    );
    let (code, _) = post_optics(&c, &s, &spec.to_string(), "text/plain").await;
    assert_eq!(code, 415);
}
