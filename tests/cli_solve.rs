//! `polbrdf solve` driven as a user would: the real binary, JSON in and out.

mod common;

use common::run;

use serde_json::{Value, json};
use std::path::PathBuf;

/// A fresh file per call (tests run in parallel).
fn tmp(name: &str, v: &Value) -> PathBuf {
    let p = common::scratch_dir("cli-solve").join(name);
    std::fs::write(&p, serde_json::to_string(v).unwrap()).unwrap();
    p
}

fn solve(spec: &Value, points: Option<&Value>, field: Option<&Value>) -> Value {
    let s = tmp("spec.json", spec);
    let mut args = vec!["solve".to_string(), s.to_string_lossy().into_owned()];
    if let Some(p) = points {
        args.push("--points".into());
        args.push(tmp("points.json", p).to_string_lossy().into_owned());
    }
    if let Some(f) = field {
        args.push("--field".into());
        args.push(tmp("field.json", f).to_string_lossy().into_owned());
    }
    let argv: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
    let (code, out, err) = run(&argv);
    assert_eq!(code, 0, "stderr: {err}");
    serde_json::from_str(&out).expect("JSON output")
}

fn mueller(v: &Value) -> [[f64; 4]; 4] {
    let mut m = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            m[i][j] = v[i][j].as_f64().unwrap();
        }
    }
    m
}

/// The Garcia–Siewert aerosol from tests/data/benchmarks as an `expansion` layer.
fn gs_spec(base: Value) -> Value {
    let c = common::benchmark("garcia_siewert_L13_coeffs.json")["coefficients"].clone();
    let mut exp = c.as_object().unwrap().clone();
    exp.insert("albedo".into(), json!(0.973527));
    json!({
        "layers": [{"optical_thickness": 0.7, "scatterer": {"expansion": exp}}],
        "base": base,
        "solver": {"streams": 16}
    })
}

/// The validation of Collin et al. 2014 (§4.1): the BRDF from four Stokes inputs predicts
/// the field for a fifth. The field path (full doubling, internal field at
/// tau = 0 for a beam of flux pi) and the BRDF path (top-only doubling,
/// Chandrasekhar's relation) are independent code paths:
/// `I_up = pi mu0 f S_in`.
#[test]
fn five_vector_check() {
    let spec = gs_spec(json!({"lambertian": {"albedo": 0.3}}));
    let mu0: f64 = 0.6;
    let theta_i = mu0.acos().to_degrees();
    let stokes = [1.0, 0.3, -0.5, 0.2];
    let mus = [0.2, 0.5, 0.9];
    let phis = [0.0, 40.0, 130.0];
    let field = json!({"mu0": mu0, "phi0_deg": 0.0, "stokes": stokes, "tau": [0.0], "mu": mus, "phi_deg": phis});
    let mut pts = Vec::new();
    for &mu in &mus {
        for &phi in &phis {
            // Propagation azimuth phi relative to the beam's = graphics phi_o - phi_i - 180.
            pts.push(json!({"theta_i_deg": theta_i, "phi_i_deg": 0.0,
                            "theta_o_deg": f64::acos(mu).to_degrees(), "phi_o_deg": phi + 180.0}));
        }
    }
    let out = solve(&spec, Some(&json!({"points": pts})), Some(&field));
    let r = &out["results"][0];
    let mut worst: f64 = 0.0;
    let mut k = 0;
    for &mu in &mus {
        for &phi in &phis {
            let f = mueller(&r["points"][k]["mueller"]);
            k += 1;
            let fe = r["field"]
                .as_array()
                .unwrap()
                .iter()
                .find(|e| {
                    (e["mu"].as_f64().unwrap() - mu).abs() < 1e-12
                        && (e["phi_deg"].as_f64().unwrap() - phi).abs() < 1e-12
                })
                .unwrap();
            for p in 0..4 {
                let predicted: f64 = (0..4)
                    .map(|q| std::f64::consts::PI * mu0 * f[p][q] * stokes[q])
                    .sum();
                let got = fe["stokes"][p].as_f64().unwrap();
                worst = worst.max((predicted - got).abs() / fe["stokes"][0].as_f64().unwrap());
            }
        }
    }
    assert!(
        worst < 1e-6,
        "fifth Stokes vector predicted to {worst:e} (relative to I)"
    );
}

/// A Fresnel base under a vanishing layer reproduces the Fresnel Mueller
/// matrix as the specular term and has no diffuse reflection.
#[test]
fn fresnel_base_under_vanishing_layer() {
    let spec = json!({
        "layers": [{"optical_thickness": 1e-10, "scatterer": {"rayleigh": {"albedo": 1.0}}}],
        "base": {"fresnel": {"material": {"n": 1.5, "k": 0.0}}},
        "solver": {"streams": 8}
    });
    let pts = json!({"points": [{"theta_i_deg": 56.309932474, "phi_i_deg": 0, "theta_o_deg": 30, "phi_o_deg": 100}]});
    let out = solve(&spec, Some(&pts), None);
    let r = &out["results"][0];
    let s = mueller(&r["specular"][0]["mueller"]);
    // Brewster angle of n = 1.5: R_p = 0, so M11 = -M12 = R_s/2.
    let rs = {
        let (ci, ni) = (56.309932474f64.to_radians().cos(), 1.5f64);
        let ct = (1.0 - (1.0 - ci * ci) / (ni * ni)).sqrt();
        ((ci - ni * ct) / (ci + ni * ct)).powi(2)
    };
    assert!((s[0][0] - rs / 2.0).abs() < 1e-8, "{s:?}");
    assert!((s[0][1] + rs / 2.0).abs() < 1e-8, "{s:?}");
    let f = mueller(&r["points"][0]["mueller"]);
    assert!(f.iter().flatten().all(|x| x.abs() < 1e-8), "diffuse {f:?}");
}

#[test]
fn output_keys_and_solver_block() {
    let spec = gs_spec(json!("black"));
    let pts = json!({"points": [{"theta_i_deg": 53.13, "phi_i_deg": 0, "theta_o_deg": 30, "phi_o_deg": 180}]});
    let out = solve(&spec, Some(&pts), None);
    let r = &out["results"][0];
    assert!(r["wavelength_nm"].is_null());
    assert_eq!(r["points"][0]["theta_i_deg"].as_f64(), Some(53.13));
    assert_eq!(r["solver"]["streams"].as_u64(), Some(16));
    assert!(r["solver"]["fourier_orders"].as_u64().unwrap() >= 1);
    assert!(r["solver"]["wall_time_ms"].as_f64().unwrap() > 0.0);
    assert_eq!(r["specular"].as_array().unwrap().len(), 0);
    let f = mueller(&r["points"][0]["mueller"]);
    assert!(f[0][0] > 0.0);
}

#[test]
fn bad_specs_exit_nonzero_with_the_json_path() {
    for (spec, path) in [
        (
            json!({"layers": [{"optical_thickness": -1, "scatterer": {"rayleigh": {"albedo": 1}}}]}),
            "layers[0].optical_thickness",
        ),
        (
            json!({"layers": [{"optical_thickness": 1, "scatterer": {"rayleigh": {"albedo": 1, "colour": 2}}}]}),
            "layers[0].scatterer",
        ),
        (
            json!({"layers": [{"optical_thickness": 1, "scatterer": {"mie": {"material": "unobtainium", "radius_um": 0.2}}}], "wavelengths_nm": [550]}),
            "layers[0].scatterer.mie.material",
        ),
        (
            json!({"layers": [{"optical_thickness": 1, "scatterer": {"rayleigh": {"albedo": 1}}}], "solver": {"streams": 0}}),
            "solver.streams",
        ),
        (json!({"layers": []}), "layers"),
    ] {
        let p = tmp("bad.json", &spec);
        let (code, out, err) = run(&["solve", p.to_str().unwrap()]);
        assert_ne!(code, 0, "accepted {spec}");
        assert!(out.is_empty());
        assert!(
            err.contains(path),
            "error for {spec} does not name {path}: {err}"
        );
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
    let (code, _, err) = run(&["solve", "/nonexistent/spec.json"]);
    assert_ne!(code, 0);
    assert!(err.contains("/nonexistent/spec.json"));
}

/// Wavelength-dependent spec: one result per wavelength, TiO2 by name.
#[test]
fn mie_spec_gives_one_result_per_wavelength() {
    let spec = json!({
        "layers": [{"optical_thickness": 1.0, "scatterer": {"mie": {"material": "TiO2", "radius_um": 0.2}}}],
        "wavelengths_nm": [450, 550, 650],
        "solver": {"streams": 8}
    });
    let pts = json!({"points": [{"theta_i_deg": 45, "phi_i_deg": 0, "theta_o_deg": 20, "phi_o_deg": 180}]});
    let out = solve(&spec, Some(&pts), None);
    let res = out["results"].as_array().unwrap();
    assert_eq!(res.len(), 3);
    for (r, wl) in res.iter().zip([450.0, 550.0, 650.0]) {
        assert_eq!(r["wavelength_nm"].as_f64(), Some(wl));
        let f = mueller(&r["points"][0]["mueller"]);
        assert!(f[0][0] > 0.0 && f[0][0].is_finite());
        // Realizable: |f12| ≤ f11.
        assert!(f[0][1].abs() <= f[0][0]);
    }
}

/// Run `polbrdf solve` on files with these contents; (exit code, stderr).
fn solve_texts(spec: &str, points: Option<&str>, field: Option<&str>) -> (i32, String) {
    let dir = common::scratch_dir("cli-solve-text");
    let write = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p.to_string_lossy().into_owned()
    };
    let mut args = vec!["solve".to_string(), write("spec.json", spec)];
    if let Some(p) = points {
        args.push("--points".into());
        args.push(write("points.json", p));
    }
    if let Some(f) = field {
        args.push("--field".into());
        args.push(write("field.json", f));
    }
    let argv: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
    let (code, out, err) = run(&argv);
    if code != 0 {
        assert!(out.is_empty(), "{out}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
    (code, err)
}

const RAYLEIGH4: &str = r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":0.9}}}],"solver":{"streams":4}}"#;

/// Anything but whitespace after the JSON document of a spec, points or
/// field file: exit 2, naming the file and where the trailing data starts.
#[test]
fn trailing_data_in_any_input_file_is_refused() {
    let points = r#"{"points":[{"theta_i_deg":10,"phi_i_deg":0,"theta_o_deg":20,"phi_o_deg":30}]}"#;
    let field = r#"{"mu0":0.5,"tau":[0],"mu":[0.5],"phi_deg":[0]}"#;
    // (line, column) of the trailing text after `first` + " ", counted here.
    let at = |first: &str| {
        format!(
            "trailing data after the JSON document at line 1 column {}",
            first.len() + 2
        )
    };
    let (code, err) = solve_texts(&format!("{RAYLEIGH4} xx"), None, None);
    assert_eq!(code, 2);
    assert!(
        err.contains("spec.json") && err.contains(&at(RAYLEIGH4)),
        "{err}"
    );
    let (code, err) = solve_texts(RAYLEIGH4, Some(&format!("{points} {{}}")), None);
    assert_eq!(code, 2);
    assert!(
        err.contains("points.json") && err.contains(&at(points)),
        "{err}"
    );
    let (code, err) = solve_texts(RAYLEIGH4, None, Some(&format!("{field} 1")));
    assert_eq!(code, 2);
    assert!(
        err.contains("field.json") && err.contains(&at(field)),
        "{err}"
    );
    // Trailing whitespace is fine.
    let (code, err) = solve_texts(&format!("{RAYLEIGH4}\n\n "), Some(points), Some(field));
    assert_eq!(code, 0, "{err}");
}

/// What the solver would refuse, and the spec alone decides, is refused
/// before solving: exit 2, one line naming the field and what would work.
#[test]
fn solve_time_refusals_exit_2_before_solving() {
    let hg = |g: f64, solver: &str| {
        format!(
            r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"henyey_greenstein":{{"albedo":1,"g":{g}}}}}}}],"solver":{solver}}}"#
        )
    };
    // β_l = (2l+1) g^l with g = -0.995: |g|^l > 1e-4 up to l = 1837, so it
    // needs 919 streams, more than the 512 a tolerance may pick.
    let beta: Vec<String> = (0..2000)
        .map(|l| format!("{}", (2 * l + 1) as f64 * (-0.995f64).powi(l)))
        .collect();
    let expansion = format!(
        r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"expansion":{{"albedo":1,"beta":[{}]}}}}}}],"solver":{{"tolerance":1e-3}}}}"#,
        beta.join(",")
    );
    let (lo, hi) = polbrdf::physics::materials::find("TiO2")
        .unwrap()
        .wavelength_range_nm();
    let tio2 = format!(
        r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"mie":{{"material":"TiO2","radius_um":0.2}}}}}}],"wavelengths_nm":[{}]}}"#,
        hi + 100.0
    );
    for (spec, path, fragment) in [
        (
            hg(-0.8, "{}"),
            "solver.streams",
            "at least 21 streams".to_string(),
        ),
        (
            expansion,
            "solver.tolerance",
            "at least 919 streams".to_string(),
        ),
        (tio2, "wavelengths_nm[0]", format!("[{lo}, {hi}] nm")),
    ] {
        let t0 = std::time::Instant::now();
        let (code, err) = solve_texts(&spec, None, None);
        assert_eq!(code, 2, "{err}");
        assert!(err.contains(&format!("{path}: ")), "{path} not in {err}");
        assert!(err.contains(&fragment), "{fragment} not in {err}");
        assert!(
            t0.elapsed().as_secs_f64() < 10.0,
            "refused only after solving?"
        );
    }
    let (code, err) = solve_texts(&hg(-0.8, r#"{"streams":21}"#), None, None);
    assert_eq!(code, 0, "{err}");
}
