//! `needs` (docs/spec.md): a request's reduced result equals the matching
//! part of the full result, a coarser grid states an interpolation error
//! that the true one does not exceed by more than 2× (the estimate rule),
//! needs at their defaults keep a spec's id, and what cannot be served is
//! refused at submission (HTTP 422, CLI exit 2) naming the field.

mod service_support;

use polbrdf::brdf::angles::mu_of_theta_deg;
use polbrdf::brdf::table::{BuildOptions, Table};
use polbrdf::{material, plan};
use service_support::*;
use std::f64::consts::PI;

/// TiO2 spheres (14 Greek terms: nothing truncated at 16 streams).
fn tio2(base: &str, needs: &str) -> String {
    format!(
        r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"mie":{{"material":"TiO2","radius_um":0.2}}}}}}],
            "base":{base},"wavelengths_nm":[550],"solver":{{"streams":16}}{needs}}}"#
    )
}

fn table(text: &str) -> Table {
    let s = material::parse(text).unwrap();
    Table::from_spec_needs(&s, &BuildOptions::default()).unwrap()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |a, x| a.max(x.abs()))
}

#[test]
fn needs_at_their_defaults_keep_the_id() {
    let id = |needs: &str| plan::id_of_spec(&material::parse(&tio2("\"black\"", needs)).unwrap());
    let (canonical, plain) = id("");
    assert!(!canonical.contains("needs"), "{canonical}");
    for same in [
        r#","needs":{}"#,
        r#","needs":{"error_estimate":true}"#,
        r#","needs":{"grid":{"polar_nodes":64}}"#,
    ] {
        assert_eq!(id(same).1, plain, "{same}");
    }
    let mut others = std::collections::HashSet::new();
    for other in [
        r#","needs":{"error_estimate":false}"#,
        r#","needs":{"grid":{"polar_nodes":32}}"#,
        r#","needs":{"grid":{"max_fourier_orders":4}}"#,
    ] {
        let (c, i) = id(other);
        assert_ne!(i, plain, "{other}");
        assert!(c.contains("\"needs\""), "{c}");
        assert!(others.insert(i), "two needs share an id: {other}");
    }
}

/// Without the estimate, and with fewer Fourier orders, the table holds the
/// same numbers as the full one (the same N-stream solve), minus what was
/// left out.
#[test]
fn reduced_tables_are_parts_of_the_full_table() {
    for base in [r#""black""#, r#"{"fresnel":{"material":"silver"}}"#] {
        let grid = r#""grid":{"polar_nodes":12}"#;
        let full = table(&tio2(base, &format!(r#","needs":{{{grid}}}"#)));
        let no_est = table(&tio2(
            base,
            &format!(r#","needs":{{{grid},"error_estimate":false}}"#),
        ));
        let few = table(&tio2(
            base,
            r#","needs":{"grid":{"polar_nodes":12,"max_fourier_orders":3}}"#,
        ));
        let (f, e, o) = (
            &full.wavelengths[0],
            &no_est.wavelengths[0],
            &few.wavelengths[0],
        );
        let scale = max_abs(&f.f);
        assert!(full.metadata.wavelengths[0].error_estimate.is_some());
        assert!(no_est.metadata.wavelengths[0].error_estimate.is_none());
        assert_eq!(e.orders, f.orders);
        let d = f.f.iter().zip(&e.f).map(|(a, b)| (a - b).abs());
        assert!(d.fold(0.0, f64::max) <= 1e-12 * scale, "{base}");
        assert_eq!(e.specular, f.specular, "{base}");
        assert!(f.orders > 3, "the full series is longer than the cap");
        assert_eq!(o.orders, 3);
        let part = &f.f[..o.f.len()];
        let d = part.iter().zip(&o.f).map(|(a, b)| (a - b).abs());
        assert!(d.fold(0.0, f64::max) <= 1e-12 * scale, "{base}");
        assert_eq!(few.metadata.wavelengths[0].fourier_orders, 3);
    }
}

/// A coarse grid's stated interpolation error against the truth: the
/// table's f11 at off-grid direction pairs against a direct solve there at
/// the same streams (so only interpolation differs), relative to the
/// largest f11 of the table. The rule: the true error may be below the
/// statement by any factor, above it by at most 2×.
#[test]
fn a_coarse_grid_states_its_interpolation_error() {
    let cases = [
        tio2(r#""black""#, ""),
        tio2(r#"{"fresnel":{"material":"silver"}}"#, ""),
        r#"{"layers":[{"optical_thickness":"infinite","scatterer":{"rayleigh":{"albedo":0.99}}}],
            "base":"black","solver":{"streams":16}}"#
            .to_string(),
        r#"{"layers":[{"optical_thickness":0.3,"scatterer":{"henyey_greenstein":{"albedo":0.9,"g":0.5}}}],
            "base":{"lambertian":{"albedo":0.5}},"solver":{"streams":32}}"#
            .to_string(),
    ];
    for nodes in [8, 16] {
        for (seed, case) in cases.iter().enumerate() {
            let text = {
                let mut v: serde_json::Value = serde_json::from_str(case).unwrap();
                v["needs"] = serde_json::json!({"grid": {"polar_nodes": nodes}});
                v.to_string()
            };
            let s = material::parse(&text).unwrap();
            let t = Table::from_spec_needs(&s, &BuildOptions::default()).unwrap();
            let stated = t.metadata.wavelengths[0]
                .interpolation_error
                .expect("a coarse grid states its interpolation error");
            let w = &t.wavelengths[0];
            // Largest f11 of the table (nodes, Δφ = 0 and π).
            let mut f11_max: f64 = 0.0;
            for &a in &t.grid.theta_deg {
                for &b in &t.grid.theta_deg {
                    for dphi in [0.0, PI] {
                        f11_max = f11_max.max(w.eval(&t.grid, a, b, dphi)[0][0].abs());
                    }
                }
            }
            // Off-grid pairs: a fixed pseudo-random sample, some near the horizon.
            let mut x = 0.271_828_f64 + 0.1 * seed as f64;
            let mut next = || {
                x = (x * 9_301.0 + 0.492_113).fract();
                x
            };
            let theta: Vec<f64> = (0..12)
                .map(|k| match k {
                    0..8 => 90.0 * next(),
                    8..10 => 89.0 + next(),
                    _ => 90.0 - 0.1 * next(),
                })
                .collect();
            let mu: Vec<f64> = theta.iter().map(|&d| mu_of_theta_deg(d)).collect();
            let p = plan::problem(&s, s.wavelengths_nm.as_ref().map(|w| w[0])).unwrap();
            let direct = polbrdf::solver::reflection(&p, &mu).unwrap();
            let mut worst: f64 = 0.0;
            for (o, &to) in theta.iter().enumerate() {
                for (i, &ti) in theta.iter().enumerate() {
                    for dphi in [0.0, 0.7, PI] {
                        let a = w.eval(&t.grid, ti, to, dphi)[0][0];
                        let b = direct.brdf(o, i, dphi)[0][0];
                        worst = worst.max((a - b).abs() / f11_max);
                    }
                }
            }
            eprintln!("[needs] {nodes} nodes: true {worst:.2e}, stated {stated:.2e}: {case}");
            assert!(
                worst <= 2.0 * stated + 1e-13,
                "{nodes} nodes: true interpolation error {worst:e} > 2 × stated {stated:e}: {case}"
            );
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn what_cannot_be_served_is_refused_at_submission() {
    let dir = TempDir::new("needs");
    let s = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();
    let tolerance = r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}],
        "solver":{"tolerance":1e-4},"needs":{"error_estimate":false}}"#;
    let nodes = r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}],
        "needs":{"grid":{"polar_nodes":3}}}"#;
    for (body, path) in [
        (tolerance, "needs.error_estimate"),
        (nodes, "needs.grid.polar_nodes"),
    ] {
        let (code, v, _) = post(&c, &s, body).await;
        assert_eq!(code, 422, "{v}");
        assert_eq!(v["path"], path, "{v}");
        let file = dir.0.join("bad.json");
        std::fs::write(&file, body).unwrap();
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_polbrdf"))
            .args(["solve", file.to_str().unwrap()])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2));
        assert!(String::from_utf8_lossy(&out.stderr).contains(path));
    }
    // A need this build does not know is refused, never ignored.
    let unknown = r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}],
        "needs":{"theta_o_deg":[10]}}"#;
    let (code, v, _) = post(&c, &s, unknown).await;
    assert_eq!(code, 422, "{v}");
    assert!(v["detail"].as_str().unwrap().contains("theta_o_deg"), "{v}");
    // Explicit streams without the estimate: solved, and says it has none.
    let ok = r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}],
        "solver":{"streams":8,"tolerance":1e-4},"needs":{"error_estimate":false,"grid":{"polar_nodes":16}}}"#;
    let (code, v, _) = post(&c, &s, ok).await;
    assert!(code == 202 || code == 200, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    let done = wait_done(&c, &s, &id).await;
    assert!(done["error_estimate"].is_null(), "{done}");
    let bytes = c
        .get(s.url(&format!("/v1/brdfs/{id}/table")))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let t = polbrdf::brdf::format::from_bytes(&bytes).unwrap();
    assert_eq!(t.grid.len(), 16);
    assert!(t.metadata.wavelengths[0].error_estimate.is_none());
    assert!(t.metadata.wavelengths[0].interpolation_error.is_some());
}
