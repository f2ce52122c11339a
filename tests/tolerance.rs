//! `solver.tolerance` against an independent reference: for the seed's
//! cases of docs/accuracy.md (including the hardest, a thin layer over
//! silver whose error is not monotone in the streams), the picked solution
//! is within the requested tolerance of a 64-stream solve, the estimate it
//! reports is at least half its true error (the estimate rule) and within
//! 3× of it where the convergence is regular (docs/accuracy.md says where
//! it is not), and a tolerance stops at the first level that meets it.

mod common;
use polbrdf::solver::{self, ReflectionFourier, accuracy};
use polbrdf::{material, plan};

fn f11(r: &ReflectionFourier, dphi: &[f64]) -> Vec<f64> {
    let n = r.mu.len();
    let mut v = Vec::new();
    for iu in 0..n {
        for iv in 0..n {
            for &d in dphi {
                v.push(r.brdf(iu, iv, d)[0][0]);
            }
        }
    }
    v
}

fn problem(name: &str) -> solver::Problem {
    let path = format!(
        "{}/docs/accuracy/specs/{name}.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let s = material::parse(&std::fs::read_to_string(&path).unwrap()).unwrap();
    plan::problem(&s, plan::wavelengths(&s)[0]).unwrap()
}

/// Max |Δf11| relative to max f11 of the reference.
fn true_error(got: &[f64], reference: &[f64]) -> f64 {
    let scale = reference.iter().cloned().fold(0.0, f64::max);
    got.iter()
        .zip(reference)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
        / scale
}

#[test]
fn requested_tolerances_are_met() {
    let (mu, dphi) = common::probe_grid();
    let mut report = Vec::new();
    for name in ["TiO2_0.1_silver", "TiO2_1.0_black", "iron_oxide_0.1_black"] {
        let p = problem(name);
        let mut reference_problem = p.clone();
        reference_problem.settings.streams = 64;
        let reference = f11(&solver::reflection(&reference_problem, &mu).unwrap(), &dphi);
        for tol in [1e-3, 1e-4, 1e-5, 1e-6] {
            let e = accuracy::reflection_to_tolerance(&p, &mu, tol, 64, &|_| {}).unwrap();
            let err = true_error(&f11(&e.reflection, &dphi), &reference);
            report.push(format!(
                "{name} tol {tol:e}: {} streams, estimate {:.2e}, true {err:.2e}",
                e.estimate.streams[2], e.estimate.max_err_f11
            ));
            assert!(err <= tol, "{}", report.join("\n"));
            assert!(e.estimate.max_err_f11 <= tol);
        }
    }
    eprintln!("{}", report.join("\n"));
}

/// At the default 16 streams, the estimate of the regular cases (layers of
/// τ = 1 and 10, where the error falls like `N^−6`) never understates (the
/// estimate rule: at least half the true error) and, there, overstates at
/// most 3× (docs/accuracy.md).
#[test]
fn estimates_at_16_streams_never_understate() {
    let (mu, dphi) = common::probe_grid();
    for name in [
        "TiO2_1.0_black",
        "iron_oxide_10.0_lambertian",
        "TiO2_1.0_silver",
    ] {
        let p = problem(name);
        let mut reference_problem = p.clone();
        reference_problem.settings.streams = 64;
        let reference = f11(&solver::reflection(&reference_problem, &mu).unwrap(), &dphi);
        let mut at16 = p.clone();
        at16.settings.streams = 16;
        let e = accuracy::reflection_with_estimate(&at16, &mu).unwrap();
        let err = true_error(&f11(&e.reflection, &dphi), &reference);
        let ratio = e.estimate.max_err_f11 / err;
        eprintln!(
            "{name}: estimate {:.2e}, true {err:.2e}, ratio {ratio:.2}",
            e.estimate.max_err_f11
        );
        assert!((0.5..=3.0).contains(&ratio), "{name}: ratio {ratio}");
    }
}

/// A tolerance stops at the first level that meets it: a non-absorbing
/// sphere of x = 13.5 (n = 1.739, r = 1.178 µm, 550 nm; 40 expansion terms)
/// in a layer of τ = 20.7 over glass (n = 1.559). Its answers at 16, 24 and
/// 32 streams are 7.9e-5, 2.9e-7 and 5.4e-8 from a 96-stream solve; a
/// tolerance of 1e-4 is met at 32 (estimate 9.3e-6). Until solver version
/// 5 the last change was measured from the estimate's 16-stream level
/// re-solved without the secondary correction (5e-4 off), which is above
/// 3 × 1e-4, and it went on to 64 streams (1.2e5× below the tolerance).
#[test]
fn a_tolerance_stops_where_it_is_met() {
    let spec = r#"{"layers": [{"optical_thickness": 20.725108456656194, "scatterer":
        {"mie": {"material": {"n": 1.7392460940370182, "k": 0.0}, "radius_um": 1.1778151873417084}}}],
        "base": {"fresnel": {"material": {"n": 1.5593677357528661, "k": 0.0}}},
        "wavelengths_nm": [550.0], "solver": {"streams": 16, "polarized": true}}"#;
    let s = material::parse(spec).unwrap();
    let p = plan::problem(&s, plan::wavelengths(&s)[0]).unwrap();
    let (mu, dphi) = common::probe_grid();
    let mut reference_problem = p.clone();
    reference_problem.settings.streams = 96;
    let reference = f11(&solver::reflection(&reference_problem, &mu).unwrap(), &dphi);
    let tol = 1e-4;
    let e = accuracy::reflection_to_tolerance(&p, &mu, tol, 64, &|_| {}).unwrap();
    let err = true_error(&f11(&e.reflection, &dphi), &reference);
    let n = e.estimate.streams[2];
    eprintln!(
        "{n} streams, estimate {:.2e}, true {err:.2e}",
        e.estimate.max_err_f11
    );
    assert!(err <= tol && e.estimate.max_err_f11 >= err / 2.0);
    assert!(n <= 32, "picked {n} streams");
}
