//! The `rough_fresnel` base (docs/spec.md, Bases; conventions §10) driven
//! through the real binary: with no light scattered above it the BRDF is
//! the GGX microfacet model, written out here from Walter et al. (2007)
//! and Heitz (2014) in graphics angles, independently of
//! `physics::microfacet`; and its refusals name their paths.

mod common;

use common::ggx::{dir, ggx, rp_rs};
use common::{scratch_dir, solve_points};
use serde_json::{Value, json};
use std::path::PathBuf;

fn write(name: &str, v: &Value) -> PathBuf {
    let p = scratch_dir("rough-base").join(name);
    std::fs::write(&p, serde_json::to_string(v).unwrap()).unwrap();
    p
}

fn spec(alpha: f64) -> Value {
    json!({
        "layers": [{"optical_thickness": 0, "scatterer": {"rayleigh": {"albedo": 1}}}],
        "base": {"rough_fresnel": {"material": {"n": 1.5, "k": 0.0}, "alpha": alpha}},
        "solver": {"streams": 8}
    })
}

/// Nothing scatters above the base: every point is the microfacet BRDF,
/// `f₁₁ = D G₂ R(ω_i·h) / (4 cosθ_i cosθ_o)` anywhere, and in the plane of
/// incidence (where the facet and meridian frames agree) the whole Fresnel
/// Mueller matrix times that factor, with `φ_o − φ_i = 180°` the mirror side
/// (conventions §5).
#[test]
fn a_bare_rough_base_is_the_ggx_microfacet_model() {
    for alpha in [0.15, 0.4] {
        let s = write("spec.json", &spec(alpha));
        let geometry = [
            (30.0, 0.0, 30.0, 180.0),
            (50.0, 20.0, 35.0, 200.0),
            (10.0, 0.0, 70.0, 180.0),
            (60.0, 0.0, 40.0, 0.0),
            (45.0, 0.0, 45.0, 120.0),
            (70.0, 30.0, 20.0, 260.0),
        ];
        let pts: Vec<Value> = geometry
            .iter()
            .map(|&(ti, pi, to, po)| {
                json!({"theta_i_deg": ti, "phi_i_deg": pi, "theta_o_deg": to, "phi_o_deg": po})
            })
            .collect();
        let p = write("points.json", &json!({ "points": pts }));
        let got = solve_points(s.to_str().unwrap(), p.to_str().unwrap());
        for (&(ti, pi, to, po), m) in geometry.iter().zip(&got) {
            let (scale, cd) = ggx(alpha, dir(ti, pi), dir(to, po));
            let (rp, rs) = rp_rs(1.5, cd);
            let f11 = scale * 0.5 * (rp * rp + rs * rs);
            let label = format!("alpha {alpha}, ({ti}, {pi}) -> ({to}, {po})");
            // The azimuthal projection is converged to 1e-8 in units of
            // f cosθ_i cosθ_o per coefficient (solver::rough_base): an
            // absolute floor besides the relative 1e-5.
            let tol = 1e-5 * f11 + 1e-7;
            assert!(
                (m[0][0] - f11).abs() <= tol,
                "{label}: f11 {} vs {f11}",
                m[0][0]
            );
            let in_plane = ((po - pi) % 180.0).abs() < 1e-9;
            if in_plane {
                let a = scale * 0.5 * (rp * rp + rs * rs);
                let b = scale * 0.5 * (rp * rp - rs * rs);
                let c = scale * rp * rs;
                let want = [
                    [a, b, 0.0, 0.0],
                    [b, a, 0.0, 0.0],
                    [0.0, 0.0, c, 0.0],
                    [0.0, 0.0, 0.0, c],
                ];
                for i in 0..4 {
                    for j in 0..4 {
                        assert!(
                            (m[i][j] - want[i][j]).abs() <= tol,
                            "{label}: m{i}{j} {} vs {}",
                            m[i][j],
                            want[i][j]
                        );
                    }
                }
            }
        }
    }
}

fn refusal(spec: &Value) -> String {
    common::refused("rough-base", spec)
}

/// A roughness out of range or missing is refused with its path; a
/// smoother surface is pointed to the `fresnel` base.
#[test]
fn bad_roughness_is_refused_by_name() {
    let err = refusal(&spec(0.01));
    assert!(
        err.contains("base.rough_fresnel.alpha") && err.contains("fresnel"),
        "{err}"
    );
    let err = refusal(&spec(f64::MAX));
    assert!(err.contains("base.rough_fresnel.alpha"), "{err}");
    let mut s = spec(0.2);
    s["base"]["rough_fresnel"]
        .as_object_mut()
        .unwrap()
        .remove("alpha");
    let err = refusal(&s);
    assert!(err.contains("alpha") && err.contains("missing"), "{err}");
}
