//! DISORT self-test problems in scalar mode (`disort_tests.json`: the
//! "correct answers" of cdisort's `disotest.c`, 6 significant digits).
//!
//! Conventions of the file (its `conventions` block) and how they map to ours:
//!
//! - DISORT's `umu > 0` is **upward**: we read `FieldFourier::up` for it and
//!   `down` for `umu < 0`, at `|umu|`.
//! - `utau` is the optical depth from the top, as our `depths`.
//! - `fbeam` is the beam flux normal to the beam: DISORT's `uu` for a beam is
//!   `fbeam · fourier_sum(..)[0][0]` (our radiance per unit flux normal to
//!   the beam). Its azimuth `phi − phi0` is our propagation-azimuth
//!   difference (`0` = forward side).
//! - `fisot` is an isotropic incident radiance at the top. DISORT treats it as
//!   a boundary condition of the *diffuse* field, so its `uu` (downward) and
//!   `rfldn` **include** the unscattered isotropic light (`uu = fisot` at the
//!   top, `rfldn(0) = π fisot`): `uu = fisot · iso_down` (which includes the
//!   unscattered part), `fisot · iso_up` upward.
//! - For a beam, `uu` and `rfldn` are diffuse only (the direct beam is a
//!   delta along the beam, reported separately as `rfldir = fbeam μ0
//!   e^{−τ/μ0}`).
//! - Fluxes: the azimuthal average of the beam radiance is `fbeam ρ⁰/(2π)`
//!   (order 0 of the Fourier sum), so a flux `2π ∫ I μ dμ` is
//!   `fbeam Σ_j w_j μ_j ρ⁰[j, beam]` over a Gauss rule `(μ_j, w_j)` on (0, 1)
//!   added to the user directions; for the isotropic illumination
//!   `2π fisot Σ_j w_j μ_j iso[j]`.
//! - `dfdt = (1 − ω) 4π J` with `4π J = fbeam e^{−τ/μ0} + 2π ∫_{−1}^{1} I dμ`
//!   (direct beam included; DISORT's `c_fluxes`, no thermal source), `ω` of
//!   the layer DISORT assigns to the level: the first layer whose bottom is
//!   at or below it (`LAYRU`: the *upper* layer at an interface).
//!
//! Two kinds of test:
//!
//! 1. **DISORT's numerics** (`Numerics::disort`): `nstr/2` streams per
//!    hemisphere, fluxes summed over those nodes, DISORT's delta-M scaling
//!    (`f = pmom[nstr]`, zero for cases 1, 2, 8, 9a; 3e-6 for 9b). This is
//!    the same discretized problem DISORT solves, so every printed value is
//!    reproduced at the printed precision: relative 1e-5 with an absolute
//!    floor of 5e-7 × the largest value of the same table of the case
//!    (fluxes; dfdt; uu). Intensities for cases 1, 2, 8, 9 (at most `nstr`
//!    moments: DISORT's Nakajima–Tanaka correction does nothing there);
//!    fluxes only for the peaked cases 3–5, whose printed intensities carry
//!    that correction, which we do not do.
//! 2. **Converged** (32–150 streams, full phase function, no delta-M, checked
//!    against a higher stream count): DISORT's answers are not converged in
//!    the stream number (nstr = 16 for cases 1–3, 8 for cases 8–9), so they
//!    deviate from ours by DISORT's own discretization error, up to 1.3e-3
//!    (nstr = 16) and 3.4e-3 (nstr = 8), exactly the difference between our
//!    solution at DISORT's numerics and our converged one (printed). These
//!    tests assert looser bounds documented at each test. For cases 3–5 the
//!    converged fluxes (full phase function) agree with DISORT's delta-M
//!    fluxes to 2.3e-5.

mod common;

use std::f64::consts::PI;

use common::{Worst, benchmark, floats};
use polbrdf::physics::expansion::GreekCoefficients;
use polbrdf::physics::quadrature::double_gauss;
use polbrdf::solver::{
    Base, FieldFourier, Layer, Problem, Settings, Thickness, fourier_sum, internal_field,
};
use serde_json::Value;

/// The DISORT outputs of one case, in the file's layout.
#[derive(Debug, Default)]
struct Outputs {
    rfldir: Vec<f64>,
    rfldn: Vec<f64>,
    flup: Vec<f64>,
    dfdt: Vec<f64>,
    /// `uu[iu][lu][j]`; empty if not computed.
    uu: Vec<Vec<Vec<f64>>>,
}

/// `fbeam` / `fisot`: a number or one of the symbolic strings of the file.
fn source_value(v: &Value, umu0: f64) -> f64 {
    if let Some(x) = v.as_f64() {
        return x;
    }
    let s = v.as_str().expect("number or string");
    if s.starts_with("pi/umu0") {
        PI / umu0
    } else if s == "pi" {
        PI
    } else if s == "1/pi" {
        1.0 / PI
    } else {
        panic!("unknown source value {s:?}")
    }
}

/// Greek coefficients (scalar: `beta` only) from Legendre coefficients `β_l`.
fn scalar_coef(beta: Vec<f64>) -> GreekCoefficients {
    let mut c = GreekCoefficients::zeros(beta.len());
    c.beta = beta;
    c
}

/// The phase function of a case with all the moments it has (not only the
/// `nmom` given to DISORT: for the peaked cases DISORT's delta-M result is an
/// approximation to the full phase function, which the cited tables use).
fn phase(data: &Value, test: &Value) -> GreekCoefficients {
    let id = test["id"].as_str().unwrap();
    let pf = &data["phase_functions"];
    let with_beta0 = |rest: Vec<f64>| {
        let mut beta = vec![1.0];
        beta.extend(rest);
        scalar_coef(beta)
    };
    match &id[..1] {
        "1" | "8" => scalar_coef(vec![1.0]),
        // pmom = [1, 0, 0.1]: beta_2 = 5 * 0.1.
        "2" => scalar_coef(vec![1.0, 0.0, 0.5]),
        // g^l < 1e-13 beyond l = 105.
        "3" => GreekCoefficients::henyey_greenstein(0.75, 105),
        "4" => with_beta0(floats(&pf["haze_L_garcia_siewert"]["beta_k_for_k_1_to_82"])),
        "5" => {
            // DISORT uses the first 298 of the 299 listed values.
            let mut b = floats(&pf["cloud_C1_garcia_siewert"]["beta_k_for_k_1_to_299"]);
            b.truncate(298);
            with_beta0(b)
        }
        "9" if id == "9a" => scalar_coef(vec![1.0]),
        "9" => {
            // 9b: beta_l as listed in the case's `phase` text.
            let beta = vec![
                1.0, 2.00916, 1.56339, 0.67407, 0.22215, 0.04725, 0.00671, 0.00068, 0.00005,
            ];
            let text = test["inputs"]["phase"].as_str().unwrap();
            for b in &beta[1..] {
                assert!(
                    text.contains(&format!("{b}/")),
                    "9b moment {b} not in {text:?}"
                );
            }
            scalar_coef(beta)
        }
        _ => panic!("no phase function for case {id}"),
    }
}

/// Position of `mu` in `list` (exact up to rounding).
fn index_of(list: &[f64], mu: f64) -> usize {
    list.iter()
        .position(|&m| (m - mu).abs() < 1e-12)
        .unwrap_or_else(|| panic!("{mu} not among the user directions"))
}

/// How to solve a case.
#[derive(Clone, Copy, Debug)]
struct Numerics {
    /// Our discrete ordinates per hemisphere.
    streams: usize,
    /// Gauss nodes on (0, 1) added to the user directions for the fluxes.
    flux_nodes: usize,
    /// Compute intensities (all Fourier orders) or fluxes only (order 0).
    intensities: bool,
    /// `Settings::start_factor`.
    start_factor: f64,
    /// Apply DISORT's delta-M scaling with `nstr` moments.
    delta_m: bool,
}

impl Numerics {
    /// DISORT's own discretization: `nstr/2` double-Gauss streams per
    /// hemisphere, fluxes summed over those same nodes (DISORT's `c_fluxes`
    /// sums its quadrature intensities), delta-M with `f = pmom[nstr]`. The
    /// thin start layer is made 10 times thinner than the default: with
    /// only 4–8 streams the smallest cosine is large and the default start
    /// error (~1e-5 at 8 streams) would show at the printed precision.
    fn disort(test: &Value, intensities: bool) -> Self {
        let nstr = test["inputs"]["nstr"].as_u64().unwrap() as usize;
        Self {
            streams: nstr / 2,
            flux_nodes: nstr / 2,
            intensities,
            start_factor: 0.01,
            delta_m: true,
        }
    }

    /// Our own (converged) discretization, full phase function.
    fn converged(streams: usize, flux_nodes: usize, intensities: bool) -> Self {
        Self {
            streams,
            flux_nodes,
            intensities,
            start_factor: Settings::default().start_factor,
            delta_m: false,
        }
    }
}

/// DISORT's delta-M scaling (`c_setdis`): `f = pmom[nstr]`, `ω' = ω(1−f)/(1−ωf)`,
/// `τ' = (1−ωf)τ`, `pmom'_k = (pmom_k − f)/(1−f)` for `k < nstr` (higher
/// moments dropped). Returns `(f, scaled coefficients)`.
fn delta_m(coef: &GreekCoefficients, nstr: usize) -> (f64, GreekCoefficients) {
    let chi = |l: usize| coef.beta.get(l).map_or(0.0, |b| b / (2 * l + 1) as f64);
    let f = chi(nstr);
    if f == 0.0 {
        let mut c = coef.clone();
        if c.len() > nstr {
            c = scalar_coef(c.beta[..nstr].to_vec());
        }
        return (f, c);
    }
    let beta = (0..nstr)
        .map(|l| (2 * l + 1) as f64 * (chi(l) - f) / (1.0 - f))
        .collect();
    (f, scalar_coef(beta))
}

/// Solve one DISORT case and return its outputs in DISORT's units.
fn solve(data: &Value, test: &Value, num: Numerics) -> Outputs {
    let inp = &test["inputs"];
    let dtauc = floats(&inp["dtauc"]);
    let ssalb = floats(&inp["ssalb"]);
    let nstr = inp["nstr"].as_u64().unwrap() as usize;
    assert_eq!(inp["nlyr"].as_u64().unwrap() as usize, dtauc.len());
    assert_eq!(inp["albedo"].as_f64(), Some(0.0), "black ground only");
    assert_eq!(inp["planck"].as_bool(), Some(false));
    let utau = floats(&inp["utau"]);
    let umu = floats(&inp["umu"]);
    let phis = floats(&inp["phi"]);
    let umu0 = inp["umu0"].as_f64().unwrap();
    let phi0 = inp["phi0"].as_f64().unwrap();
    let fbeam = source_value(&inp["fbeam"], umu0);
    let fisot = source_value(&inp["fisot"], umu0);
    let coef = phase(data, test);
    let (f, scaled) = if num.delta_m {
        delta_m(&coef, nstr)
    } else {
        (0.0, coef)
    };
    // Scaled layers (f = 0: unchanged) and the scaled depths of the output
    // levels (DISORT's UTAUPR, in the layer LAYRU: the upper one at an
    // interface).
    let layers: Vec<Layer> = dtauc
        .iter()
        .zip(&ssalb)
        .map(|(&t, &w)| Layer {
            thickness: Thickness::Finite((1.0 - w * f) * t),
            albedo: w * (1.0 - f) / (1.0 - w * f),
            coef: scaled.clone(),
        })
        .collect();
    let layer_of = |tau: f64| {
        let mut bottom = 0.0;
        for (lc, &t) in dtauc.iter().enumerate() {
            bottom += t;
            if tau <= bottom + 1e-12 {
                return lc;
            }
        }
        dtauc.len() - 1
    };
    let scaled_depth = |tau: f64| {
        let lc = layer_of(tau);
        let top: f64 = dtauc[..lc].iter().sum();
        let top_scaled: f64 = (0..lc).map(|i| (1.0 - ssalb[i] * f) * dtauc[i]).sum();
        top_scaled + (1.0 - ssalb[lc] * f) * (tau - top)
    };
    let depths: Vec<f64> = utau.iter().map(|&t| scaled_depth(t)).collect();
    let problem = Problem {
        layers,
        base: Base::Black,
        settings: Settings {
            streams: num.streams,
            polarized: false,
            max_order: if num.intensities { None } else { Some(0) },
            start_factor: num.start_factor,
            ..Settings::default()
        },
        top_interface: None,
    };
    // User directions: beam, |umu|, flux quadrature (duplicates skipped).
    let mut mu_user: Vec<f64> = Vec::new();
    let push = |list: &mut Vec<f64>, m: f64| {
        if !list.iter().any(|&x| (x - m).abs() < 1e-12) {
            list.push(m);
        }
    };
    push(&mut mu_user, umu0);
    if num.intensities {
        for &m in &umu {
            push(&mut mu_user, m.abs());
        }
    }
    let (gq, gw) = double_gauss(num.flux_nodes);
    for &m in &gq {
        push(&mut mu_user, m);
    }
    let field: FieldFourier = internal_field(&problem, &mu_user, &depths).expect("solve");
    assert_eq!(field.ns, 1);
    let iv = index_of(&mu_user, umu0);
    let ig: Vec<usize> = gq.iter().map(|&m| index_of(&mu_user, m)).collect();

    let mut out = Outputs::default();
    for (k, (&tau, &tau_scaled)) in utau.iter().zip(&depths).enumerate() {
        let up0 = &field.up[k][0];
        let down0 = &field.down[k][0];
        // The azimuthal average of the beam radiance is order 0 alone.
        let j = ig[0];
        let only_m0 = fourier_sum(&field.up[k][..1], 1, j, iv, 1.234)[0][0];
        assert!((only_m0 - up0[(j, iv)] / (2.0 * PI)).abs() <= 1e-15 * only_m0.abs());
        // Azimuthal averages of the radiance at the flux nodes.
        let avg = |j: usize, upward: bool| {
            let beam = if upward { up0[(j, iv)] } else { down0[(j, iv)] } / (2.0 * PI);
            let iso = if upward {
                field.iso_up[k][j]
            } else {
                field.iso_down[k][j]
            };
            fbeam * beam + fisot * iso
        };
        let mut fdn = 0.0;
        let mut fup = 0.0;
        let mut sphere = 0.0;
        for (&j, (&m, &w)) in ig.iter().zip(gq.iter().zip(&gw)) {
            let (d, u) = (avg(j, false), avg(j, true));
            fdn += 2.0 * PI * w * m * d;
            fup += 2.0 * PI * w * m * u;
            sphere += 2.0 * PI * w * (d + u);
        }
        // Direct beam, true and (delta-M) scaled: DISORT's rfldn is the
        // scaled total downward flux minus the true direct flux.
        let direct = fbeam * (-tau / umu0).exp();
        let direct_scaled = fbeam * (-tau_scaled / umu0).exp();
        out.rfldir.push(umu0 * direct);
        out.rfldn.push(fdn + umu0 * (direct_scaled - direct));
        out.flup.push(fup);
        out.dfdt
            .push((1.0 - ssalb[layer_of(tau)]) * (direct_scaled + sphere));
    }
    if num.intensities {
        out.uu = umu
            .iter()
            .map(|&m| {
                let iu = index_of(&mu_user, m.abs());
                let upward = m > 0.0;
                (0..utau.len())
                    .map(|k| {
                        let rho = if upward { &field.up[k] } else { &field.down[k] };
                        let iso = if upward {
                            field.iso_up[k][iu]
                        } else {
                            field.iso_down[k][iu]
                        };
                        phis.iter()
                            .map(|&phi| {
                                let dphi = (phi - phi0).to_radians();
                                fbeam * fourier_sum(rho, 1, iu, iv, dphi)[0][0] + fisot * iso
                            })
                            .collect()
                    })
                    .collect()
            })
            .collect();
    }
    out
}

fn test_by_id<'a>(data: &'a Value, id: &str) -> &'a Value {
    data["tests"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["id"] == id)
        .unwrap_or_else(|| panic!("case {id} not in the file"))
}

/// The expected outputs of a case.
fn expected(test: &Value) -> Outputs {
    let e = &test["expected"];
    Outputs {
        rfldir: floats(&e["rfldir"]),
        rfldn: floats(&e["rfldn"]),
        flup: floats(&e["flup"]),
        dfdt: floats(&e["dfdt"]),
        uu: e["uu_[iu][lu][j]"]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| a.as_array().unwrap().iter().map(floats).collect())
            .collect(),
    }
}

fn max_abs<'a>(v: impl IntoIterator<Item = &'a f64>) -> f64 {
    v.into_iter().fold(0.0, |a, x| a.max(x.abs()))
}

/// Printed precision: 6 significant digits, i.e. relative 1e-5 ...
const REL: f64 = 1e-5;
/// ... with an absolute floor of `FLOOR ×` the largest value of the same
/// table of the case (fluxes rfldir/rfldn/flup; dfdt; uu).
const FLOOR: f64 = 5e-7;

/// Deviations of `got` from `reference`, each `|g − r| / max(|r|, FLOOR/REL ×
/// table max)` with the table maxima of `scales` (the expected values), so
/// that `dev ≤ REL` is "relative 1e-5 or absolute 5e-7 × table max". Fluxes
/// always; `uu` if `with_uu`.
fn compare(
    id: &str,
    got: &Outputs,
    reference: &Outputs,
    scales: &Outputs,
    with_uu: bool,
    worst: &mut Worst,
) {
    let flux_max = max_abs(
        scales
            .rfldir
            .iter()
            .chain(&scales.rfldn)
            .chain(&scales.flup),
    );
    // dfdt is identically 0 for omega = 1: then the flux floor.
    let dfdt_max = match max_abs(&scales.dfdt) {
        0.0 => flux_max,
        x => x,
    };
    let mut see = |g: f64, r: f64, scale: f64, at: &dyn Fn() -> String| {
        let dev = (g - r).abs() / r.abs().max(FLOOR / REL * scale);
        worst.see(dev, || {
            format!("{id} {}: got {g:.7e}, reference {r:.6e}", at())
        });
    };
    for (name, g, r, scale) in [
        ("rfldir", &got.rfldir, &reference.rfldir, flux_max),
        ("rfldn", &got.rfldn, &reference.rfldn, flux_max),
        ("flup", &got.flup, &reference.flup, flux_max),
        ("dfdt", &got.dfdt, &reference.dfdt, dfdt_max),
    ] {
        assert_eq!(g.len(), r.len());
        for (lu, (&g, &r)) in g.iter().zip(r).enumerate() {
            see(g, r, scale, &|| format!("{name}[lu={lu}]"));
        }
    }
    if with_uu {
        let scale = max_abs(scales.uu.iter().flatten().flatten());
        for (iu, a) in reference.uu.iter().enumerate() {
            for (lu, b) in a.iter().enumerate() {
                for (j, &r) in b.iter().enumerate() {
                    see(got.uu[iu][lu][j], r, scale, &|| {
                        format!("uu[iu={iu}][lu={lu}][j={j}]")
                    });
                }
            }
        }
    }
}

/// Merge the worst of a case into the worst of a group.
fn merge(all: &mut Worst, w: Worst) {
    if w.value >= all.value || !w.value.is_finite() {
        all.value = w.value;
        all.at = w.at;
    }
    all.count += w.count;
}

/// With DISORT's own numerics (`Numerics::disort`) every printed value is
/// reproduced at the printed precision: fluxes always, intensities if
/// `with_uu` (cases whose phase function has at most `nstr` moments, where
/// DISORT's intensity correction does nothing).
fn at_disort_numerics(ids: &[&str], with_uu: bool) {
    let data = benchmark("disort_tests.json");
    let mut all = Worst::default();
    for &id in ids {
        let test = test_by_id(&data, id);
        let got = solve(&data, test, Numerics::disort(test, with_uu));
        let exp = expected(test);
        let mut w = Worst::default();
        compare(id, &got, &exp, &exp, with_uu, &mut w);
        eprintln!(
            "{id} (DISORT numerics, nstr = {}): worst {:.2e} over {} values at {}",
            test["inputs"]["nstr"], w.value, w.count, w.at
        );
        merge(&mut all, w);
    }
    eprintln!(
        "{ids:?} at DISORT numerics: worst {:.2e} over {} values at {}",
        all.value, all.count, all.at
    );
    assert!(all.value <= REL, "worst point: {all:?}");
}

/// Our converged solution (`streams`, checked against `check_streams`) of the
/// full phase function against DISORT's printed answers. Asserts that the
/// solution is converged (change below `REL / 5` of the printed precision)
/// and that DISORT deviates from it by at most `bound` (same deviation
/// measure as [`compare`]); prints DISORT's discretization error as we
/// measure it (our solution with DISORT's numerics minus the converged one),
/// which is what the deviation is.
fn converged_vs_disort(
    ids: &[&str],
    streams: usize,
    check_streams: usize,
    flux_nodes: usize,
    with_uu: bool,
    bound: f64,
) {
    let data = benchmark("disort_tests.json");
    let mut all = Worst::default();
    let mut all_conv = Worst::default();
    for &id in ids {
        let test = test_by_id(&data, id);
        let exp = expected(test);
        let got = solve(
            &data,
            test,
            Numerics::converged(streams, flux_nodes, with_uu),
        );
        let check = solve(
            &data,
            test,
            Numerics::converged(check_streams, flux_nodes, with_uu),
        );
        let emulated = solve(&data, test, Numerics::disort(test, with_uu));
        let (mut w, mut conv, mut disc) = Default::default();
        compare(id, &got, &exp, &exp, with_uu, &mut w);
        compare(id, &got, &check, &exp, with_uu, &mut conv);
        compare(id, &emulated, &got, &exp, with_uu, &mut disc);
        eprintln!(
            "{id}: converged ({streams} streams) vs DISORT (nstr = {}): worst {:.2e} at {}\n    \
             DISORT's own error (ours at DISORT's numerics vs converged): worst {:.2e} at {}\n    \
             convergence ({streams} vs {check_streams} streams): worst {:.2e}",
            test["inputs"]["nstr"], w.value, w.at, disc.value, disc.at, conv.value
        );
        merge(&mut all, w);
        merge(&mut all_conv, conv);
    }
    eprintln!(
        "{ids:?} converged vs DISORT: worst {:.2e} over {} values at {}",
        all.value, all.count, all.at
    );
    assert!(all_conv.value <= REL / 5.0, "not converged: {all_conv:?}");
    assert!(all.value <= bound, "worst point: {all:?}");
}

// ---------------------------------------------------------------------------
// DISORT's numerics: reproduce the printed answers to the printed precision.

#[test]
fn disort_1_isotropic_at_disort_numerics() {
    at_disort_numerics(&["1a", "1b", "1c", "1d", "1e", "1f"], true);
}

#[test]
fn disort_2_rayleigh_at_disort_numerics() {
    at_disort_numerics(&["2a", "2b", "2c", "2d"], true);
}

#[test]
fn disort_8_two_layers_at_disort_numerics() {
    at_disort_numerics(&["8a", "8b", "8c"], true);
}

#[test]
fn disort_9_six_layers_at_disort_numerics() {
    at_disort_numerics(&["9a", "9b"], true);
}

/// Peaked phase functions: fluxes (the intensities, which carry the
/// Nakajima–Tanaka correction, are checked with the solver's own
/// truncation below).
#[test]
fn disort_3_4_5_fluxes_at_disort_numerics_with_delta_m() {
    at_disort_numerics(&["3a", "3b", "4a", "4b", "4c", "5a", "5b"], false);
}

// ---------------------------------------------------------------------------
// Our converged solution vs DISORT: looser bounds, DISORT's own error.

/// DISORT ran cases 1 and 2 with nstr = 16 (8 streams per hemisphere) and
/// cases 8 and 9 with nstr = 8 (4 per hemisphere). Its printed answers carry
/// that discretization error, up to about 1e-3 (nstr = 16: thin layers at
/// grazing incidence, 1b uu, 2b uu, 1c flup) and 3e-3 (nstr = 8: 8a dfdt),
/// as both the DISORT-numerics tests above (which reproduce the printed
/// values to 1e-5) and the printed "DISORT's own error" show. Bounds: 2e-3
/// for nstr = 16 and 5e-3 for nstr = 8.
#[test]
fn disort_1_2_converged_within_disort_16_stream_error() {
    converged_vs_disort(
        &["1a", "1b", "1c", "1d", "1e", "1f", "2a", "2b", "2c", "2d"],
        32,
        48,
        64,
        true,
        2e-3,
    );
}

#[test]
fn disort_8_9_converged_within_disort_8_stream_error() {
    converged_vs_disort(&["8a", "8b", "8c", "9a", "9b"], 32, 48, 64, true, 5e-3);
}

/// Fluxes of the peaked cases from the full, untruncated phase function (no
/// delta-M) against DISORT's delta-M fluxes (nstr = 16 for HG, 32 for Haze-L,
/// 48 for Cloud C.1). The deviation is DISORT's delta-M + discretization flux
/// error, which we measure at about 2.4e-5 (3a flup, nstr = 16) and below
/// 5e-6 for Haze-L and Cloud; bound 1e-4 (10 × the printed precision).
///
/// Without delta-M the number of streams must resolve every moment of the
/// phase function (2N ≥ L + 1): Cloud C.1 has L = 298, and at 64 streams
/// per hemisphere its fluxes are off by 5–20 % (the quadrature no longer
/// integrates the phase function); 150 streams give 2e-6.
#[test]
fn disort_3_4_fluxes_converged_full_phase_function() {
    converged_vs_disort(&["3a", "3b", "4a", "4b", "4c"], 64, 96, 64, false, 1e-4);
}

#[test]
fn disort_5_cloud_fluxes_converged_full_phase_function() {
    converged_vs_disort(&["5a", "5b"], 150, 200, 150, false, 1e-4);
}

/// Peaked phase functions, reflected intensities at the top with the
/// solver's own truncation: delta-M of the phase function DISORT was given
/// (`nmom` moments) at DISORT's `nstr` (`f = χ_nstr`) plus the
/// Nakajima–Tanaka single-scattering correction (`solver::truncation`),
/// against DISORT's printed intensities,
/// which come from the same two ingredients at the same `nstr` (DISORT's
/// "intensity correction"; its IMS part acts on downward radiance near the
/// beam only). This is the check of the truncation + correction used for
/// Mie particles.
#[test]
fn disort_3_4_5_reflected_intensities_with_delta_m_and_single_scattering_correction() {
    let data = benchmark("disort_tests.json");
    let mut all = Worst::default();
    for id in ["3a", "3b", "4a", "4b", "4c", "5a"] {
        let test = test_by_id(&data, id);
        let inp = &test["inputs"];
        let nstr = inp["nstr"].as_u64().unwrap() as usize;
        let dtauc = floats(&inp["dtauc"]);
        let ssalb = floats(&inp["ssalb"]);
        let umu = floats(&inp["umu"]);
        let phis = floats(&inp["phi"]);
        let utau = floats(&inp["utau"]);
        let umu0 = inp["umu0"].as_f64().unwrap();
        let phi0 = inp["phi0"].as_f64().unwrap();
        let fbeam = source_value(&inp["fbeam"], umu0);
        assert_eq!(utau[0], 0.0);
        // DISORT's "exact" phase function in its correction is the series
        // it was given: pmom(0..=nmom).
        let nmom = inp["nmom"].as_u64().unwrap() as usize;
        let full = phase(&data, test);
        let coef = scalar_coef(full.beta[..(nmom + 1).min(full.len())].to_vec());
        let problem = Problem {
            layers: dtauc
                .iter()
                .zip(&ssalb)
                .map(|(&t, &w)| Layer {
                    thickness: Thickness::Finite(t),
                    albedo: w,
                    coef: coef.clone(),
                })
                .collect(),
            base: Base::Black,
            settings: Settings {
                streams: nstr / 2,
                polarized: false,
                delta_m: true,
                // DISORT corrects single scattering only (its IMS term acts
                // on downward radiance near the beam).
                secondary_scattering: false,
                start_factor: 0.01,
                ..Settings::default()
            },
            top_interface: None,
        };
        let up: Vec<f64> = umu.iter().copied().filter(|&m| m > 0.0).collect();
        let mut mu_user = up.clone();
        if !mu_user.iter().any(|&m| (m - umu0).abs() < 1e-12) {
            mu_user.push(umu0);
        }
        let r = polbrdf::solver::reflection(&problem, &mu_user).expect("solve");
        let iv = index_of(&mu_user, umu0);
        let want = expected(test);
        let scale = max_abs(want.uu.iter().flat_map(|a| a[0].iter()));
        let mut w = Worst::default();
        for (k, &m) in umu.iter().enumerate() {
            if m <= 0.0 {
                continue;
            }
            let iu = index_of(&mu_user, m);
            for (j, &phi) in phis.iter().enumerate() {
                let dphi = (phi - phi0).to_radians();
                let got = fbeam * umu0 * r.brdf(iu, iv, dphi)[0][0];
                let exp = want.uu[k][0][j];
                let dev = (got - exp).abs() / scale.max(exp.abs());
                w.see(dev, || {
                    format!("{id} umu={m} phi={phi}: {got:.6e} vs DISORT {exp:.6e}")
                });
            }
        }
        eprintln!("[disort {id}] worst {:.2e} ({})", w.value, w.at);
        merge(&mut all, w);
    }
    // The two methods share nstr, delta-M and the single-scattering
    // correction, so they differ by DISORT's printing (6–7 digits) and by
    // the start-layer error of adding-doubling (the bound of the other
    // at-DISORT-numerics tests). Measured: 2.5e-6 (3a, umu = 0.5). With the
    // unscaled single scattering (ω, τ) instead of NT's scaled one the
    // exact-backscatter values differed by 2e-2 (5a).
    assert!(all.value <= 5e-6, "worst {:.2e} ({})", all.value, all.at);
}
