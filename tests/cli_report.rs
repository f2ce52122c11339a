//! `polbrdf report experiment` (the seed's Table 1) through the real binary:
//! the seed's columns as printed, our columns recomputed here from
//! `polbrdf solve --points` and from Fresnel's formulas, and the symmetry
//! that makes the sign of the incident polarization angle irrelevant.

mod common;

use common::{ok, run, scratch_dir, solve_points};
use num_complex::Complex64 as C;
use serde_json::{Value, json};

/// Collin et al. (2014), Table 1: incident H %, measured H %, simulated H %.
const TABLE_1: [(f64, f64, f64); 7] = [
    (0.0, 11.0, 28.0),
    (7.0, 19.0, 32.0),
    (25.0, 24.0, 41.0),
    (50.0, 37.0, 54.0),
    (75.0, 63.0, 66.0),
    (93.0, 98.0, 74.0),
    (100.0, 86.0, 77.0),
];

fn report(extra: &[&str]) -> Value {
    let mut args = vec!["report", "experiment", "--json", "--streams", "16"];
    args.extend_from_slice(extra);
    ok(&args)
}

fn h(v: &Value) -> f64 {
    v["horizontal_percent"]
        .as_f64()
        .unwrap_or_else(|| panic!("a split in {v}"))
}

/// Horizontal share of `m` applied to linear polarization at angle `chi`
/// from the plane of incidence.
fn split(m: &[[f64; 4]; 4], chi: f64) -> f64 {
    let s = [1.0, (2.0 * chi).cos(), (2.0 * chi).sin(), 0.0];
    let o: Vec<f64> = (0..4)
        .map(|i| (0..4).map(|j| m[i][j] * s[j]).sum())
        .collect();
    100.0 * 0.5 * (o[0] + o[1]) / o[0]
}

#[test]
fn the_seed_columns_are_printed_as_the_seed_prints_them() {
    let r = report(&[]);
    let rows = r["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 7);
    for (row, &(inc, meas, sim)) in rows.iter().zip(&TABLE_1) {
        assert_eq!(h(&row["incident"]), inc);
        assert_eq!(h(&row["measured"]), meas);
        assert_eq!(h(&row["seed_simulated"]), sim);
        assert_eq!(
            row["measured"]["vertical_percent"].as_f64(),
            Some(100.0 - meas)
        );
    }
    let names: Vec<&str> = r["variants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["particles", "binder"]);
    assert_eq!(r["wavelength_nm"], json!(632.8));
    assert_eq!(r["theta_o_deg"], json!(45.0));
}

/// Our diffuse columns are the split of what `solve --points` returns for
/// the same spec and geometry, for either sign of the polarization angle
/// (in the plane of incidence the BRDF has no U→I or U→Q coupling).
#[test]
fn our_columns_are_the_split_of_the_solved_mueller_matrix() {
    let r = report(&[]);
    let dir = scratch_dir("report");
    let points = dir.join("points.json");
    std::fs::write(
        &points,
        json!({"points": [{"theta_i_deg": 45, "phi_i_deg": 0, "theta_o_deg": 45, "phi_o_deg": 180}]})
            .to_string(),
    )
    .unwrap();
    for v in r["variants"].as_array().unwrap() {
        let name = v["name"].as_str().unwrap();
        let spec = dir.join(format!("{name}.json"));
        std::fs::write(&spec, v["spec"].to_string()).unwrap();
        let m = solve_points(spec.to_str().unwrap(), points.to_str().unwrap())[0];
        assert!(
            m[0][2].abs() < 1e-9 * m[0][0] && m[1][2].abs() < 1e-9 * m[0][0],
            "{m:?}"
        );
        for (row, &(inc, _, _)) in r["rows"].as_array().unwrap().iter().zip(&TABLE_1) {
            let chi = (inc / 100.0f64).sqrt().acos();
            let ours = h(&row[name]["diffuse"]);
            for c in [chi, -chi] {
                let want = split(&m, c);
                assert!((ours - want).abs() < 1e-6, "{name} {inc}: {ours} vs {want}");
            }
        }
    }
}

/// The particles' mirror beam is chromium's Fresnel reflection attenuated
/// twice by the layer: its split is `R_p h / (R_p h + R_s (1 − h))` whatever
/// the layer, computed here from the complex index.
#[test]
fn the_mirror_beam_splits_as_chromium_reflects() {
    let r = report(&[]);
    let n = polbrdf::physics::materials::refractive_index("chromium", 632.8).unwrap();
    let eps = C::new(n.n, n.k).powi(2);
    let c = 45f64.to_radians().cos();
    let w = (eps - C::new(1.0 - c * c, 0.0)).sqrt();
    let rs = ((C::new(c, 0.0) - w) / (C::new(c, 0.0) + w)).norm_sqr();
    let rp = ((eps * c - w) / (eps * c + w)).norm_sqr();
    for (row, &(inc, _, _)) in r["rows"].as_array().unwrap().iter().zip(&TABLE_1) {
        let x = inc / 100.0;
        let want = 100.0 * rp * x / (rp * x + rs * (1.0 - x));
        let got = h(&row["particles"]["specular"]);
        assert!((got - want).abs() < 1e-9, "{inc}: {got} vs {want}");
    }
    // Away from the mirror direction there is no delta term.
    let off = report(&["--theta-o", "30"]);
    assert!(off["rows"][0]["particles"]["specular"].is_null());
    assert_eq!(off["variants"][0]["specular_mueller"], Value::Null);
}

#[test]
fn the_text_report_has_the_seed_layout_and_bad_input_is_refused() {
    let (code, out, err) = run(&["report", "experiment", "--streams", "8"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.starts_with("Seed Table 1"), "{out}");
    // Seven rows of numbers after the two header lines.
    let rows: Vec<&str> = out
        .lines()
        .filter(|l| l.trim_start().starts_with(|c: char| c.is_ascii_digit()))
        .collect();
    assert_eq!(rows.len(), 7, "{out}");
    assert!(
        rows[5].contains(" 93.0   7.0 |  98.0   2.0 |  74.0  26.0"),
        "{}",
        rows[5]
    );
    let (code, _, err) = run(&["report", "experiment", "--spec", "/nonexistent/paint.json"]);
    assert_eq!(code, 2);
    assert!(err.contains("/nonexistent/paint.json"), "{err}");
    let (code, _, err) = run(&["report", "experiment", "--tau", "-1"]);
    assert_eq!(code, 2);
    assert!(err.contains("optical_thickness"), "{err}");
}
