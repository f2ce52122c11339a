//! Greek coefficients of `polbrdf mie` against two other Mie codes, with the
//! conversions of docs/conventions.md §4 ("Other conventions"):
//!
//! * **Meerhoff Mie program 3.1** (de Rooij & van der Stap lineage; PyMieDAP
//!   test data `C.sc.01.100`, `meerhoff_pymiedap_gamma_reff1p05_veff0p07_lam1p1_m1p44.json`):
//!   gamma distribution `r_eff = 1.05`, `v_eff = 0.07`, λ = 1.1 µm,
//!   `m = 1.44`, radius integral over the printed `[0.0616236, 3.3845421]` µm,
//!   l = 0..58 to 14 decimals. Conversion: **negate both** `γ = −β1`,
//!   `ε = −β2`; `β, α, ζ, δ = α1, α2, α3, α4`.
//! * **Mishchenko's spher.f** (a run stored in PyMieDAP,
//!   `mishchenko_spher_print_monodisperse_x5_m1p5_0p005i.json`): one sphere
//!   `r = 0.397887` µm at λ = 0.5 µm (`x ≈ 5`), `m = 1.5 + 0.005i`, l = 0..18
//!   to 5 decimals. Conversion:
//!   **negate γ only**, `γ = −β1`, `ε = +β2` (spher.f's `β2` has the opposite
//!   sign to the Meerhoff code's).

mod common;

use common::benchmark;
use polbrdf::physics::{self, RefractiveIndex, psd};
use serde_json::Value;

/// The printed strings of one series as numbers.
fn column(data: &Value, name: &str) -> Vec<f64> {
    data["coefficients"][name]
        .as_array()
        .unwrap_or_else(|| panic!("series {name}"))
        .iter()
        .map(|v| v.as_str().unwrap().trim().parse::<f64>().unwrap())
        .collect()
}

/// `(largest |ours − printed|, at l)` over one series, our coefficient being
/// `sign · ours[l]` (0 beyond our truncation).
fn worst(ours: &[f64], sign: f64, printed: &[f64]) -> (f64, usize) {
    printed
        .iter()
        .enumerate()
        .map(|(l, p)| ((sign * ours.get(l).copied().unwrap_or(0.0) - p).abs(), l))
        .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a })
}

/// Our six series with the other code's names and the sign that maps them.
fn mapping(
    c: &physics::expansion::GreekCoefficients,
    eps_sign: f64,
) -> [(&'static str, &[f64], f64); 6] {
    [
        ("alpha1", &c.beta, 1.0),
        ("alpha2", &c.alpha, 1.0),
        ("alpha3", &c.zeta, 1.0),
        ("alpha4", &c.delta, 1.0),
        ("beta1", &c.gamma, -1.0),
        ("beta2", &c.epsilon, eps_sign),
    ]
}

/// Meerhoff's gamma distribution with its printed integration limits.
///
/// Achieved: every coefficient within 7e-7 of the printed value (largest
/// at l = 8…12, where the series peak; 4e-14 at l = 0), `g` within 3e-8.
/// Not the printed precision (5e-14), and the limit is not our radius
/// quadrature: with `rel_tol` 1e-6 (the default) and 1e-10 the differences
/// agree to 1e-9, and our truncation and projection are at 1e-12. The
/// difference is not a normalisation (l = 0 agrees to 4e-14) nor a simple
/// scale of `x` (its ratio to `∂c_l/∂ ln λ` varies with l). The file's own
/// single-scattering albedo of these non-absorbing spheres is printed as
/// `0.99999990628963`: the Meerhoff program's `Q_ext` and `Q_sca` (equal
/// term by term for real `m`) differ by 9.4e-8, so its Mie sums or its
/// angular integration carry errors of that order, which the 14 printed
/// decimals do not resolve. The bound below is that achieved level with a
/// margin of 1.4×, not a tolerance chosen to pass.
#[test]
fn meerhoff_gamma_distribution_with_printed_limits() {
    let data = benchmark("meerhoff_pymiedap_gamma_reff1p05_veff0p07_lam1p1_m1p44.json");
    let dist = psd::SizeDistribution::Gamma {
        r_eff_um: 1.05,
        v_eff: 0.07,
    };
    let quad = psd::PsdQuadrature {
        rel_tol: 1e-10,
        radius_range_um: Some([0.0616236, 3.3845421]),
        ..Default::default()
    };
    let o = physics::mie_optics_distribution(
        RefractiveIndex::new(1.44, 0.0),
        1.0,
        1100.0,
        &dist,
        &quad,
        Some(1e-12),
    )
    .expect("mie optics");
    let mut all: f64 = 0.0;
    for (name, ours, sign) in mapping(&o.coefficients, -1.0) {
        let printed = column(&data, name);
        assert_eq!(printed.len(), 59);
        let (d, l) = worst(ours, sign, &printed);
        eprintln!("[meerhoff] {name}: max |Δ| = {d:.2e} at l = {l}");
        all = all.max(d);
    }
    let g_printed = 0.725_900_653_009_99;
    eprintln!(
        "[meerhoff] g = {:.14} (printed {g_printed}), terms {}",
        o.g,
        o.coefficients.len()
    );
    assert!(all <= MEERHOFF_BOUND, "max |Δ| = {all:e}");
    assert!((o.g - g_printed).abs() <= MEERHOFF_G_BOUND);
}

/// Achieved agreement with the Meerhoff file (see the test's doc).
const MEERHOFF_BOUND: f64 = 1e-6;
/// Achieved agreement of `g` with the file's `<cos th>`.
const MEERHOFF_G_BOUND: f64 = 5e-8;

/// spher.f for one sphere, x = 5, m = 1.5 + 0.005i: every coefficient to
/// half a unit of the 5th decimal, with `ε = +β2` (negating `ε` as for the
/// Meerhoff code fails from l = 2 on, where `|β2| ≈ 0.12`).
#[test]
fn mishchenko_spher_monodisperse_x5() {
    let data = benchmark("mishchenko_spher_print_monodisperse_x5_m1p5_0p005i.json");
    // The run's radius is the printed R1 = R2 = REFF = 0.397887 µm
    // (x = 4.9999955), not x = 5 exactly (r = 0.3978873577 µm): the
    // coefficients change by ~3 per unit of x, and at x = 5 they differ by
    // up to 2.4e-5; over r = 0.3978865 … 0.3978875 the largest difference is
    // smallest (5.0e-6) at 0.397887 and 1.5e-5 at ±2e-7 µm from it.
    let o = physics::mie_optics(
        RefractiveIndex::new(1.5, 0.005),
        1.0,
        500.0,
        Some(0.397_887),
        None,
        Some(1e-12),
    )
    .expect("mie optics");
    for (name, ours, sign) in mapping(&o.coefficients, 1.0) {
        let printed = column(&data, name);
        assert_eq!(printed.len(), 19);
        let (d, l) = worst(ours, sign, &printed);
        eprintln!("[spher.f] {name}: max |Δ| = {d:.2e} at l = {l}");
        assert!(d <= 0.5e-5 + 1e-12, "{name}: |Δ| = {d:e} at l = {l}");
        // The tail beyond the printed l = 18 is below the print resolution.
        assert!(
            ours.iter().skip(19).all(|v| v.abs() < 0.5e-5),
            "{name} tail"
        );
    }
    // The other sign of ε is wrong (the test can tell the conventions apart).
    let printed = column(&data, "beta2");
    assert!(worst(&o.coefficients.epsilon, -1.0, &printed).0 > 0.1);
}
