//! A smooth binder/air `top_interface` (docs/spec.md, Top interface;
//! conventions §8) driven through the real binary: the interface alone, a
//! Lambertian base under it against the closed form of light trapped by
//! internal reflection, the table against the direct solve, and the spec's
//! refusals. The Fresnel coefficients here are written out from Born & Wolf
//! in the signs of conventions §5, independently of `physics::fresnel`.

mod common;

use common::{ok, run, scratch_dir};
use serde_json::{Value, json};
use std::path::PathBuf;

fn write(name: &str, v: &Value) -> PathBuf {
    let p = scratch_dir("top-interface").join(name);
    std::fs::write(&p, serde_json::to_string(v).unwrap()).unwrap();
    p
}

fn matrix(v: &Value) -> [[f64; 4]; 4] {
    let mut m = [[0.0; 4]; 4];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = v[i][j].as_f64().expect("a number");
        }
    }
    m
}

/// Air over a dielectric of real index `n` at incidence cosine `mu`:
/// `(r_p, r_s)` with `r_p = (n²μ − w)/(n²μ + w)`, `r_s = (μ − w)/(μ + w)`,
/// `w = √(n² − 1 + μ²)` (r_p → +1, r_s → −1 for a perfect conductor).
fn rp_rs(n: f64, mu: f64) -> (f64, f64) {
    let w = (n * n - 1.0 + mu * mu).sqrt();
    ((n * n * mu - w) / (n * n * mu + w), (mu - w) / (mu + w))
}

/// The Mueller matrix of `diag(r_p, r_s)` (real coefficients).
fn fresnel_mueller(n: f64, mu: f64) -> [[f64; 4]; 4] {
    let (p, s) = rp_rs(n, mu);
    let (a, b) = (0.5 * (p * p + s * s), 0.5 * (p * p - s * s));
    [
        [a, b, 0.0, 0.0],
        [b, a, 0.0, 0.0],
        [0.0, 0.0, p * s, 0.0],
        [0.0, 0.0, 0.0, p * s],
    ]
}

/// Unpolarized energy reflectance of air over index `n`.
fn reflectance(n: f64, mu: f64) -> f64 {
    let (p, s) = rp_rs(n, mu);
    0.5 * (p * p + s * s)
}

fn points(pairs: &[(f64, f64, f64)]) -> Value {
    let pts: Vec<Value> = pairs
        .iter()
        .map(|&(ti, to, phi_o)| {
            json!({"theta_i_deg": ti, "phi_i_deg": 0.0, "theta_o_deg": to, "phi_o_deg": phi_o})
        })
        .collect();
    json!({ "points": pts })
}

fn solve(spec: &Value, pairs: &[(f64, f64, f64)]) -> Value {
    let s = write("spec.json", spec);
    let p = write("points.json", &points(pairs));
    ok(&[
        "solve",
        s.to_str().unwrap(),
        "--points",
        p.to_str().unwrap(),
    ])["results"][0]
        .clone()
}

fn brewster_deg(n: f64) -> f64 {
    n.atan().to_degrees()
}

/// A layer of zero thickness under the interface is the interface alone:
/// no diffuse light, and the delta term is the Fresnel reflection of air
/// over the binder (to 1e-10), which vanishes for p-polarized light
/// (`Q = +1`, conventions §5) at Brewster's angle.
#[test]
fn a_vanishing_layer_leaves_the_interface_alone() {
    let n = 1.5;
    let spec = json!({
        "layers": [{"optical_thickness": 0, "scatterer": {"rayleigh": {"albedo": 1}}}],
        "top_interface": {"smooth": {"index": n}},
        "solver": {"streams": 8}
    });
    let angles = [0.0, 30.0, brewster_deg(n), 75.0, 88.0];
    let pairs: Vec<(f64, f64, f64)> = angles.iter().map(|&t| (t, t, 180.0)).collect();
    let r = solve(&spec, &pairs);
    for p in r["points"].as_array().unwrap() {
        let m = matrix(&p["mueller"]);
        assert!(m.iter().flatten().all(|x| x.abs() < 1e-14), "{m:?}");
    }
    let spec_terms = r["specular"].as_array().unwrap();
    assert_eq!(spec_terms.len(), angles.len());
    for (t, s) in angles.iter().zip(spec_terms) {
        let got = matrix(&s["mueller"]);
        let want = fresnel_mueller(n, t.to_radians().cos());
        assert!(
            common::max_diff(&got, &want) < 1e-10,
            "{t}°: {got:?} vs {want:?}"
        );
    }
    let at_brewster = matrix(&spec_terms[2]["mueller"]);
    let p_reflected = at_brewster[0][0] + at_brewster[0][1];
    assert!(p_reflected.abs() < 1e-12, "{p_reflected}");
    assert!(at_brewster[0][0] - at_brewster[0][1] > 0.1);
}

/// A Lambertian base of albedo `a` under a layer of zero thickness and an
/// interface of index `n`: light enters with the energy transmittance
/// `T(μ_i) = 1 − R(μ_i)`, is reflected diffusely, and bounces between the
/// base and the interface's inside, whose hemispherical reflectance is
/// `r_i = 1 − (1 − r_e)/n²` (`r_e = 2∫R μ dμ` from air); radiance leaves
/// divided by `n²`. So `f11 = a T(μ_i) T(μ_o) / (π n² (1 − a r_i))`
/// (Saunderson's correction), against which the solve is within twice its
/// stated error (the estimate rule).
#[test]
fn light_trapped_under_the_interface_matches_the_closed_form() {
    let (n, a) = (1.5_f64, 0.8);
    let spec = json!({
        "layers": [{"optical_thickness": 0, "scatterer": {"rayleigh": {"albedo": 1}}}],
        "base": {"lambertian": {"albedo": a}},
        "top_interface": {"smooth": {"index": n}},
        "solver": {"streams": 16}
    });
    // r_e by composite Simpson on 20 000 intervals (R is smooth from air).
    let steps = 20_000;
    let h = 1.0 / steps as f64;
    let r_e: f64 = (0..=steps)
        .map(|k| {
            let mu = k as f64 * h;
            let w = if k == 0 || k == steps {
                1.0
            } else if k % 2 == 1 {
                4.0
            } else {
                2.0
            };
            w * 2.0 * reflectance(n, mu) * mu
        })
        .sum::<f64>()
        * h
        / 3.0;
    let r_i = 1.0 - (1.0 - r_e) / (n * n);
    let closed = |ti: f64, to: f64| {
        let t = |deg: f64| 1.0 - reflectance(n, f64::to_radians(deg).cos());
        a * t(ti) * t(to) / (std::f64::consts::PI * n * n * (1.0 - a * r_i))
    };
    let pairs = [
        (0.0, 0.0, 180.0),
        (30.0, 60.0, 90.0),
        (60.0, 10.0, 0.0),
        (80.0, 85.0, 250.0),
    ];
    let r = solve(&spec, &pairs);
    let stated = r["solver"]["error_estimate"]["max_err_f11"]
        .as_f64()
        .unwrap();
    let max_f11 = closed(0.0, 0.0);
    for (p, &(ti, to, _)) in r["points"].as_array().unwrap().iter().zip(&pairs) {
        let m = matrix(&p["mueller"]);
        let err = (m[0][0] - closed(ti, to)).abs() / max_f11;
        assert!(
            err <= 2.0 * stated,
            "{ti}°→{to}°: f11 {} vs {} (error {err:.2e}, stated {stated:.2e})",
            m[0][0],
            closed(ti, to)
        );
        // Unpolarized light leaves the Lambertian base; the interface
        // polarizes it on the way out, never into U or V.
        assert!(m[2][0].abs() < 1e-12 && m[3][0].abs() < 1e-12, "{m:?}");
    }
}

/// A table under the interface serves what the direct solve gives (within
/// the table's measured interpolation error) and the interface's delta term
/// at the mirror pair.
#[test]
fn a_table_under_the_interface_serves_the_solve_and_the_delta_term() {
    let spec = json!({
        "layers": [{"optical_thickness": 1, "scatterer": {"mie": {
            "material": {"n": 2.6, "k": 0.001}, "radius_um": 0.15, "host_index": 1.5}}}],
        "top_interface": {"smooth": {}},
        "wavelengths_nm": [550],
        "solver": {"streams": 8}
    });
    let s = write("table-spec.json", &spec);
    let t = scratch_dir("top-interface").join("t.pbrdf");
    ok(&["solve", s.to_str().unwrap(), "--table", t.to_str().unwrap()]);
    let pairs = [(30.0, 30.0, 180.0), (30.0, 50.0, 100.0), (70.0, 20.0, 10.0)];
    let direct = solve(&spec, &pairs);
    for (p, &(ti, to, po)) in direct["points"].as_array().unwrap().iter().zip(&pairs) {
        let args = [
            "eval",
            t.to_str().unwrap(),
            "--theta-i",
            &ti.to_string(),
            "--phi-i",
            "0",
            "--theta-o",
            &to.to_string(),
            "--phi-o",
            &po.to_string(),
        ];
        let e = ok(&args);
        let (a, b) = (matrix(&e["mueller"]), matrix(&p["mueller"]));
        assert!(common::max_diff(&a, &b) < 1e-4 * b[0][0], "{a:?} vs {b:?}");
        if po == 180.0 && ti == to {
            let want = fresnel_mueller(1.5, ti.to_radians().cos());
            assert!(common::max_diff(&matrix(&e["specular"]), &want) < 1e-8);
        } else {
            assert!(e["specular"].is_null());
        }
    }
}

fn refusal(spec: &Value) -> String {
    let s = write("bad.json", spec);
    let (code, _, err) = run(&["solve", s.to_str().unwrap()]);
    assert_ne!(code, 0);
    err
}

/// What is not solved yet, or does not make sense, is refused by name.
#[test]
fn inconsistent_or_unsupported_interfaces_are_refused_by_name() {
    let mie = |host: f64| {
        json!({"optical_thickness": 1, "scatterer": {"mie": {
        "material": {"n": 2.6, "k": 0.0}, "radius_um": 0.15, "host_index": host}}})
    };
    let err = refusal(&json!({"layers": [mie(1.5)], "wavelengths_nm": [550],
        "top_interface": {"smooth": {"index": 1.4}}}));
    assert!(
        err.contains("layers[0].scatterer.mie.host_index")
            && err.contains("top_interface.smooth.index"),
        "{err}"
    );
    let err = refusal(
        &json!({"layers": [mie(1.5), mie(1.3)], "wavelengths_nm": [550],
        "top_interface": {"smooth": {}}}),
    );
    assert!(
        err.contains("layers[1].scatterer.mie.host_index") && err.contains("layers[0]"),
        "{err}"
    );
    let err = refusal(&json!({"layers": [{"optical_thickness": 1,
        "scatterer": {"rayleigh": {"albedo": 1}}}], "top_interface": {"smooth": {}}}));
    assert!(
        err.contains("top_interface.smooth.index") && err.contains("missing"),
        "{err}"
    );
    let err = refusal(&json!({"layers": [mie(1.5)], "wavelengths_nm": [550],
        "top_interface": {"rough": {"index": 1.5, "alpha": 0.01}}}));
    assert!(err.contains("top_interface.rough.alpha"), "{err}");
    let err = refusal(&json!({"layers": [mie(1.5)], "wavelengths_nm": [550],
        "top_interface": {"smooth": {"index": 1.5}, "rough": {"alpha": 0.1}}}));
    assert!(err.contains("exactly one of none, smooth, rough"), "{err}");
    let err = refusal(&json!({"layers": [mie(1.5)], "wavelengths_nm": [550],
        "top_interface": {"smooth": {"index": 0.9}}}));
    assert!(err.contains("top_interface.smooth.index"), "{err}");
}

/// A Fresnel base under the interface: the delta term is the interface's
/// reflection plus the base's beam that came back through it (listed
/// apart, summing to it), the interface part is the Fresnel matrix of air
/// over the binder, and the base part is attenuated along the refracted
/// direction.
#[test]
fn a_fresnel_base_under_the_interface_adds_its_beam_to_the_delta_term() {
    let layer = |tau: f64| {
        json!({
            "layers": [{"optical_thickness": tau, "scatterer": {"mie": {
                "material": {"n": 2.6, "k": 0.001}, "radius_um": 0.15, "host_index": 1.5}}}],
            "base": {"fresnel": {"material": {"n": 0.13, "k": 3.99}}},
            "top_interface": {"smooth": {}},
            "wavelengths_nm": [550],
            "solver": {"streams": 8}
        })
    };
    for tau in [0.2, 30.0] {
        let r = solve(&layer(tau), &[(40.0, 40.0, 180.0)]);
        let term = &r["specular"][0];
        let (sum, a, b) = (
            matrix(&term["mueller"]),
            matrix(&term["parts"]["interface"]),
            matrix(&term["parts"]["base_through_interface"]),
        );
        for i in 0..4 {
            for j in 0..4 {
                assert!((sum[i][j] - a[i][j] - b[i][j]).abs() < 1e-15);
            }
        }
        let want = fresnel_mueller(1.5, 40f64.to_radians().cos());
        assert!(common::max_diff(&a, &want) < 1e-12, "{a:?}");
        // Through the layer twice along the internal cosine, `E =
        // e^{−2τ/μ_i}`, in and out through the interface (T ≈ 0.95 each)
        // and off silver (R ≈ 0.95): between 0.7 E and E.
        let mu_i = (1.0 - (40f64.to_radians().sin() / 1.5).powi(2)).sqrt();
        let e = (-2.0 * tau / mu_i).exp();
        assert!(
            b[0][0] > 0.7 * e && b[0][0] < e,
            "τ = {tau}: {} vs E = {e:e}",
            b[0][0]
        );
    }
}
