//! Paint films (`thickness_um`, `pigments`, `binder`; docs/spec.md, Films)
//! through the real binary: a two-pigment film in an absorbing binder
//! equals its mixture computed here by hand from two `polbrdf mie` runs,
//! both in the layer optics report (`polbrdf mie --spec`) and in the solved
//! BRDF (`polbrdf solve` of the film against `polbrdf solve` of the
//! hand-mixed `expansion` layer).
//!
//! The hand mixture is independent scattering (docs/spec.md, Films):
//! `N_i = f_i / V_i`, `k_ext,i = N_i Q_ext,i π r_i²`, binder absorption
//! `4π κ_b / λ (1 − Σ f_i)`, `τ = d Σ k`, `ω = Σ ω_i k_ext,i / Σ k`, Greek
//! coefficients weighted by `ω_i k_ext,i`. The pigments are TiO2 (clear)
//! and hematite (absorbing at 550 nm), so a mixture weighted by extinction
//! instead of scattering, or a binder absorption left out or counted over
//! the whole volume, misses by far more than the tolerances.

mod common;

use common::{floats, ok, scratch_dir, solve_points};
use serde_json::{Value, json};
use std::f64::consts::PI;

const WAVELENGTH_NM: f64 = 550.0;
const THICKNESS_UM: f64 = 25.0;
const BINDER_N: f64 = 1.5;
const BINDER_K: f64 = 2e-4;
/// (material, radius µm, volume fraction).
const PIGMENTS: [(&str, f64, f64); 2] = [("TiO2", 0.15, 0.06), ("iron oxide", 0.1, 0.03)];
const KEYS: [&str; 6] = ["beta", "alpha", "zeta", "delta", "gamma", "epsilon"];

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

/// One `polbrdf mie` run of a pigment in the binder's real index.
fn mie(material: &str, radius_um: f64) -> Value {
    ok(&[
        "mie",
        "--material",
        material,
        "--radius-um",
        &radius_um.to_string(),
        "--wavelength-nm",
        &WAVELENGTH_NM.to_string(),
        "--host-index",
        &BINDER_N.to_string(),
    ])
}

/// The hand mixture: (τ, ω, the expansion as a JSON object with `albedo`).
fn hand_mixture() -> (f64, f64, Value) {
    let runs: Vec<(Value, f64, f64)> = PIGMENTS
        .iter()
        .map(|&(m, r, f)| (mie(m, r), r, f))
        .collect();
    let mut k_ext = Vec::new();
    let mut k_sca = Vec::new();
    for (v, r, f) in &runs {
        let volume = 4.0 / 3.0 * PI * r.powi(3);
        let c_ext = v["qext"].as_f64().unwrap() * PI * r * r;
        let k = f / volume * c_ext;
        k_ext.push(k);
        k_sca.push(v["albedo"].as_f64().unwrap() * k);
    }
    let pvc: f64 = PIGMENTS.iter().map(|p| p.2).sum();
    let k_binder = 4.0 * PI * BINDER_K / (WAVELENGTH_NM / 1000.0) * (1.0 - pvc);
    let k_total = k_ext.iter().sum::<f64>() + k_binder;
    let k_sca_total: f64 = k_sca.iter().sum();
    let mut expansion = serde_json::Map::new();
    for key in KEYS {
        let len = runs
            .iter()
            .map(|(v, _, _)| v["expansion"][key].as_array().unwrap().len())
            .max()
            .unwrap();
        let mut c = vec![0.0; len];
        for ((v, _, _), ks) in runs.iter().zip(&k_sca) {
            for (l, x) in floats(&v["expansion"][key]).into_iter().enumerate() {
                c[l] += ks / k_sca_total * x;
            }
        }
        expansion.insert(key.into(), json!(c));
    }
    let albedo = k_sca_total / k_total;
    expansion.insert("albedo".into(), json!(albedo));
    (THICKNESS_UM * k_total, albedo, Value::Object(expansion))
}

fn film_spec() -> Value {
    json!({
        "wavelengths_nm": [WAVELENGTH_NM],
        "layers": [{
            "thickness_um": THICKNESS_UM,
            "pigments": PIGMENTS.iter().map(|&(m, r, f)|
                json!({"material": m, "radius_um": r, "volume_fraction": f})).collect::<Vec<_>>(),
            "binder": {"n": BINDER_N, "k": BINDER_K},
        }],
        "base": {"lambertian": {"albedo": 0.5}},
        "solver": {"streams": 16},
    })
}

fn write(name: &str, v: &Value) -> String {
    let p = scratch_dir("cli-film").join(name);
    std::fs::write(&p, v.to_string()).unwrap();
    p.to_string_lossy().into_owned()
}

/// The layer optics report of the film equals the hand mixture: τ and ω to
/// 1e-12, every Greek coefficient to 1e-13 absolute; no dense-film warning
/// at 9 % PVC.
#[test]
fn film_report_equals_the_hand_mixture_of_two_mie_runs() {
    let (tau, albedo, expansion) = hand_mixture();
    let report = ok(&["mie", "--spec", &write("film.json", &film_spec())]);
    let layer = &report["layers"][0];
    assert_eq!(layer["form"], "film");
    assert_eq!(layer["thickness_um"].as_f64(), Some(THICKNESS_UM));
    assert!(
        rel(
            layer["pigment_volume_concentration"].as_f64().unwrap(),
            0.09
        ) < 1e-15
    );
    let o = &layer["optics"][0];
    let got_tau = o["optical_thickness"].as_f64().unwrap();
    let got_albedo = o["albedo"].as_f64().unwrap();
    assert!(rel(got_tau, tau) < 1e-12, "tau {got_tau} vs {tau}");
    assert!(
        rel(got_albedo, albedo) < 1e-12,
        "albedo {got_albedo} vs {albedo}"
    );
    // Extinction weighting would give another albedo-weighted mixture: the
    // hematite scatters a fraction of what it removes, so the check can fail.
    assert!(albedo < 0.99, "the mixture absorbs ({albedo})");
    for key in KEYS {
        let (g, w) = (floats(&o["expansion"][key]), floats(&expansion[key]));
        assert_eq!(g.len(), w.len(), "{key}");
        for (l, (a, b)) in g.iter().zip(&w).enumerate() {
            assert!((a - b).abs() <= 1e-13, "{key}[{l}]: {a} vs {b}");
        }
    }
    let g = o["g"].as_f64().unwrap();
    assert!((g - expansion["beta"][1].as_f64().unwrap() / 3.0).abs() < 1e-15);
    // Each pigment: N V = f.
    for (p, &(_, _, f)) in o["pigments"].as_array().unwrap().iter().zip(&PIGMENTS) {
        let n = p["number_density_per_um3"].as_f64().unwrap();
        let v = p["volume_um3"].as_f64().unwrap();
        assert!(rel(n * v, f) < 1e-14);
    }
    assert_eq!(report["warnings"], json!([]));
}

/// The solved film equals the solved `expansion` layer of the hand mixture
/// (same τ, ω and coefficients through the solver's public input), at
/// every point of the table, to 1e-10 of the largest f11.
#[test]
fn film_solves_like_its_hand_mixed_expansion_layer() {
    let (tau, _, expansion) = hand_mixture();
    let mut hand = film_spec();
    hand["layers"][0] = json!({"optical_thickness": tau, "scatterer": {"expansion": expansion}});
    let points = json!({"points": [
        {"theta_i_deg": 0, "phi_i_deg": 0, "theta_o_deg": 30, "phi_o_deg": 0},
        {"theta_i_deg": 45, "phi_i_deg": 0, "theta_o_deg": 45, "phi_o_deg": 180},
        {"theta_i_deg": 60, "phi_i_deg": 0, "theta_o_deg": 20, "phi_o_deg": 90},
        {"theta_i_deg": 75, "phi_i_deg": 0, "theta_o_deg": 70, "phi_o_deg": 10},
    ]});
    let pts = write("points.json", &points);
    let solve = |spec: &Value, name: &str| solve_points(&write(name, spec), &pts);
    let film = solve(&film_spec(), "film.json");
    let mixed = solve(&hand, "hand.json");
    let f11_max = mixed.iter().fold(0.0f64, |m, p| m.max(p[0][0]));
    assert!(f11_max > 0.0);
    for (k, (a, b)) in film.iter().zip(&mixed).enumerate() {
        for (e, (x, y)) in a.iter().flatten().zip(b.iter().flatten()).enumerate() {
            assert!(
                (x - y).abs() <= 1e-10 * f11_max,
                "point {k} element {e}: film {x} vs hand {y}"
            );
        }
    }
}
