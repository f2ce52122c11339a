//! A rough (GGX) binder/air `top_interface` (docs/spec.md, Top interface;
//! docs/solver.md, "A rough top interface") driven through the real binary:
//! the bare interface is its microfacet reflection (the GGX formula of
//! `common::ggx`, written independently of `physics::microfacet`) in a
//! solve and in a table, at grazing pairs included; a table of a layer under
//! it serves what the solve gives; a layer over a rough metal under it is
//! reciprocal; and what is not supported is refused by name.

mod common;

use common::ggx::{dir, ggx, rp_rs};
use common::{max_diff, ok, reversed, scratch_dir, solve_points};
use serde_json::{Value, json};
use std::path::PathBuf;

fn write(name: &str, v: &Value) -> PathBuf {
    let p = scratch_dir("rough-interface").join(name);
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

fn points(geometry: &[(f64, f64, f64, f64)]) -> Value {
    let pts: Vec<Value> = geometry
        .iter()
        .map(|&(ti, pi, to, po)| {
            json!({"theta_i_deg": ti, "phi_i_deg": pi, "theta_o_deg": to, "phi_o_deg": po})
        })
        .collect();
    json!({ "points": pts })
}

/// `spec` solved at the direction pairs `geometry` and as a table: the
/// solved matrices and the table's path (files named after `name`).
fn solve_and_table(
    name: &str,
    spec: &Value,
    geometry: &[(f64, f64, f64, f64)],
) -> (Vec<[[f64; 4]; 4]>, PathBuf) {
    let s = write(&format!("{name}.json"), spec);
    let p = write(&format!("{name}-points.json"), &points(geometry));
    let solved = solve_points(s.to_str().unwrap(), p.to_str().unwrap());
    let t = scratch_dir("rough-interface").join(format!("{name}.pbrdf"));
    ok(&["solve", s.to_str().unwrap(), "--table", t.to_str().unwrap()]);
    (solved, t)
}

fn eval(table: &str, (ti, pi, to, po): (f64, f64, f64, f64)) -> Value {
    let (ti, pi, to, po) = (
        ti.to_string(),
        pi.to_string(),
        to.to_string(),
        po.to_string(),
    );
    ok(&[
        "eval",
        table,
        "--theta-i",
        &ti,
        "--phi-i",
        &pi,
        "--theta-o",
        &to,
        "--phi-o",
        &po,
    ])
}

/// The microfacet reflection of air over a binder of index `n`: f11
/// anywhere; in the plane of incidence (where facet and meridian frames
/// agree) the whole Fresnel Mueller matrix times `D G₂ / (4 cosθ_i cosθ_o)`.
fn microfacet(
    n: f64,
    alpha: f64,
    (ti, pi, to, po): (f64, f64, f64, f64),
) -> (f64, Option<[[f64; 4]; 4]>) {
    let (scale, cd) = ggx(alpha, dir(ti, pi), dir(to, po));
    let (rp, rs) = rp_rs(n, cd);
    let a = scale * 0.5 * (rp * rp + rs * rs);
    let in_plane = ((po - pi) % 180.0).abs() < 1e-9;
    let full = in_plane.then(|| {
        let b = scale * 0.5 * (rp * rp - rs * rs);
        let c = scale * rp * rs;
        [
            [a, b, 0.0, 0.0],
            [b, a, 0.0, 0.0],
            [0.0, 0.0, c, 0.0],
            [0.0, 0.0, 0.0, c],
        ]
    });
    (a, full)
}

fn check(label: &str, got: &[[f64; 4]; 4], f11: f64, full: Option<[[f64; 4]; 4]>, rel: f64) {
    assert!(
        (got[0][0] - f11).abs() <= rel * f11,
        "{label}: f11 {} vs {f11}",
        got[0][0]
    );
    if let Some(want) = full {
        assert!(
            max_diff(got, &want) <= rel * f11,
            "{label}: {got:?} vs {want:?}"
        );
    }
}

/// Nothing under the interface (a vanishing layer over black): a solve and
/// a table both give the GGX reflection of the binder, the gloss lobe at
/// grazing pairs included (where its azimuthal series would need thousands
/// of orders: the table carries it in closed form, docs/table-format.md
/// T4), and no delta term.
#[test]
fn a_bare_rough_interface_is_the_ggx_reflection_in_a_solve_and_a_table() {
    let (n, alpha) = (1.5, 0.3);
    let spec = json!({
        "layers": [{"optical_thickness": 0, "scatterer": {"rayleigh": {"albedo": 1}}}],
        "top_interface": {"rough": {"index": n, "alpha": alpha}},
        "solver": {"streams": 8}
    });
    let geometry = [
        (30.0, 0.0, 30.0, 180.0),
        (50.0, 20.0, 35.0, 200.0),
        (10.0, 0.0, 70.0, 180.0),
        (60.0, 0.0, 40.0, 0.0),
        (45.0, 0.0, 45.0, 120.0),
        (85.0, 0.0, 85.0, 180.0),
        (88.0, 0.0, 87.0, 181.5),
        (89.0, 10.0, 80.0, 190.0),
    ];
    let (solved, t) = solve_and_table("bare", &spec, &geometry);
    for (&g, m) in geometry.iter().zip(&solved) {
        let (f11, full) = microfacet(n, alpha, g);
        check(&format!("solve {g:?}"), m, f11, full, 1e-10);
        let e = eval(t.to_str().unwrap(), g);
        check(
            &format!("table {g:?}"),
            &matrix(&e["mueller"]),
            f11,
            full,
            1e-10,
        );
        assert!(e["specular"].is_null(), "{g:?}: {e}");
    }
}

/// A TiO2-like layer in the binder under the rough interface: the table
/// serves the direct solve between its nodes (within its interpolation,
/// 1e-4 of f11 as under the smooth interface), and the particles add light
/// to the bare surface's reflection everywhere.
#[test]
fn a_table_under_a_rough_interface_serves_the_solve() {
    let (n, alpha) = (1.5, 0.3);
    let spec = json!({
        "layers": [{"optical_thickness": 1, "scatterer": {"mie": {
            "material": {"n": 2.6, "k": 0.001}, "radius_um": 0.15, "host_index": n}}}],
        "top_interface": {"rough": {"alpha": alpha}},
        "wavelengths_nm": [550],
        "solver": {"streams": 8}
    });
    let geometry = [
        (30.0, 0.0, 30.0, 180.0),
        (30.0, 0.0, 50.0, 100.0),
        (70.0, 0.0, 20.0, 10.0),
        (80.0, 0.0, 75.0, 180.0),
    ];
    let (solved, t) = solve_and_table("layer", &spec, &geometry);
    for (&g, m) in geometry.iter().zip(&solved) {
        let e = matrix(&eval(t.to_str().unwrap(), g)["mueller"]);
        assert!(max_diff(&e, m) < 1e-4 * m[0][0], "{g:?}: {e:?} vs {m:?}");
        let (bare, _) = microfacet(n, alpha, g);
        assert!(
            m[0][0] > bare,
            "{g:?}: {} vs the bare surface {bare}",
            m[0][0]
        );
    }
}

/// A layer over a rough aluminium base under the rough interface (both
/// rough operators at once): `f(i → o) = Δ f(o → i)ᵀ Δ` in air.
#[test]
fn a_layer_over_a_rough_metal_under_a_rough_interface_is_reciprocal() {
    let spec = json!({
        "layers": [{"optical_thickness": 0.5, "scatterer": {"rayleigh": {"albedo": 0.9}}}],
        "base": {"rough_fresnel": {"material": {"n": 1.2, "k": 7.0}, "alpha": 0.4}},
        "top_interface": {"rough": {"index": 1.5, "alpha": 0.3}},
        "solver": {"streams": 8}
    });
    let forward = [
        (20.0, 0.0, 55.0, 150.0),
        (60.0, 0.0, 35.0, 40.0),
        (40.0, 0.0, 70.0, 200.0),
    ];
    let backward: Vec<_> = forward
        .iter()
        .map(|&(ti, pi, to, po)| (to, po, ti, pi))
        .collect();
    let all: Vec<_> = forward.iter().copied().chain(backward).collect();
    let s = write("recip.json", &spec);
    let p = write("recip-points.json", &points(&all));
    let m = solve_points(s.to_str().unwrap(), p.to_str().unwrap());
    for k in 0..forward.len() {
        let (a, b) = (&m[k], reversed(&m[k + forward.len()]));
        assert!(a[0][0] > 0.0);
        // The solver's reciprocity holds to 2e-10 of max f11
        // (solver::rough_interface_tests); the points are solved at their
        // own cosines, so it holds here to the projection's precision.
        assert!(
            max_diff(a, &b) < 1e-6 * a[0][0],
            "{:?}: {a:?} vs {b:?}",
            forward[k]
        );
    }
}

fn refusal(spec: &Value) -> String {
    common::refused("rough-interface", spec)
}

/// A roughness out of range, a binder index below 1.1 and a mirror base
/// under the interface are refused by name, with the reason.
#[test]
fn what_a_rough_interface_cannot_carry_is_refused_by_name() {
    let layer = json!({"optical_thickness": 1, "scatterer": {"rayleigh": {"albedo": 1}}});
    for alpha in [0.01, 1.5] {
        let err = refusal(&json!({"layers": [layer],
            "top_interface": {"rough": {"index": 1.5, "alpha": alpha}}}));
        assert!(err.contains("top_interface.rough.alpha"), "{err}");
    }
    // Below air, and so close to it that the refracted lobe is a delta.
    for index in [0.8, 1.05] {
        let err = refusal(&json!({"layers": [layer],
            "top_interface": {"rough": {"index": index, "alpha": 0.3}}}));
        assert!(err.contains("top_interface.rough.index"), "{err}");
    }
    let err = refusal(&json!({"layers": [layer],
        "base": {"fresnel": {"material": {"n": 1.2, "k": 7.0}}},
        "top_interface": {"rough": {"index": 1.5, "alpha": 0.3}}}));
    assert!(
        err.contains("base.fresnel") && err.contains("rough_fresnel"),
        "{err}"
    );
}
