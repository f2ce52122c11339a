//! Physical laws the solver must obey (issue "done means"): reciprocity,
//! energy conservation, the single-scattering limit, the mirror image.
use super::*;
use crate::physics::expansion::GreekCoefficients;
use crate::physics::quadrature::double_gauss;
use crate::physics::stokes::Mueller;
use std::f64::consts::PI;

fn gs() -> GreekCoefficients {
    crate::physics::expansion::test_data::garcia_siewert()
}

/// A backward-peaked HG series the streams cannot integrate is refused
/// with the streams it needs; with those streams it solves and conserves
/// energy on the quadrature; forward peaks are delta-M's business.
#[test]
fn unresolved_backward_peaks_are_refused_with_the_streams_they_need() {
    let hg = |g: f64| GreekCoefficients::henyey_greenstein(g, 300);
    let mu = [0.3, 1.0];
    let p = problem(Thickness::Finite(1.0), 1.0, hg(-0.9), Base::Black, 9);
    let Err(SolverError::Unresolved {
        needed, streams, ..
    }) = reflection(&p, &mu)
    else {
        panic!("g = -0.9 at 9 streams must be refused");
    };
    assert_eq!(streams, 9);
    // Smallest N with 0.9^l <= 1e-4 for every l >= 2N: l >= 88 -> N = 44.
    assert_eq!(needed, 44);
    let ok = problem(Thickness::Finite(1.0), 1.0, hg(-0.9), Base::Black, needed);
    assert!(reflection(&ok, &mu).is_ok());
    let fwd = problem(Thickness::Finite(1.0), 1.0, hg(0.9), Base::Black, 9);
    assert!(reflection(&fwd, &mu).is_ok());
    // A zero-albedo or empty layer has no phase function to resolve.
    let dark = problem(Thickness::Finite(1.0), 0.0, hg(-0.9), Base::Black, 4);
    assert!(reflection(&dark, &mu).is_ok());
}

/// One layer on `base` at `streams` (no top interface).
pub(super) fn problem(
    tau: Thickness,
    albedo: f64,
    coef: GreekCoefficients,
    base: Base,
    streams: usize,
) -> Problem {
    Problem {
        layers: vec![Layer {
            thickness: tau,
            albedo,
            coef,
        }],
        base,
        settings: Settings {
            streams,
            ..Settings::default()
        },
        top_interface: None,
    }
}

/// Polarized reciprocity (Hovenier 1969): reversing the path swaps the
/// directions and negates the propagation-azimuth difference; in
/// meridian frames `f(μ, μ0, Δφ) = Δ f(μ0, μ, −Δφ)ᵀ Δ`,
/// `Δ = diag(1, 1, −1, 1)`. The mirror base runs the full doubling path.
#[test]
fn brdf_is_reciprocal() {
    let mu = [0.15, 0.4, 0.77, 1.0];
    let silver = crate::physics::RefractiveIndex::new(0.139, 4.129);
    let fresnel = Base::Mirror {
        mueller: std::sync::Arc::new(move |m: f64| {
            crate::physics::fresnel::mueller(1.0, silver, m).unwrap()
        }),
    };
    for base in [Base::Black, Base::Lambertian { albedo: 0.6 }, fresnel] {
        let label = format!("{base:?}");
        let mut p = problem(Thickness::Finite(0.8), 0.97, gs(), base, 16);
        // The mirror runs the full doubling path, whose beam columns and
        // user rows come from two discretisations of the start layer that
        // agree to O(δ²) (4e-8 relative at the default start layer): test
        // the law with a thin start layer.
        p.settings.start_factor = 1e-3;
        let r = reflection(&p, &mu).unwrap();
        let (worst, scale) = super::symmetry_tests::reciprocity_defect(&r);
        assert!(
            worst < 1e-8 * scale,
            "{label}: reciprocity violated by {worst:e} (scale {scale:e})"
        );
    }
}

/// Flux of the beam columns (order 0, I component) for conservative
/// scattering: reflected + diffusely transmitted + direct = incident, for
/// thin to very thick layers (no exp(+τ) anywhere).
#[test]
fn conservative_layers_conserve_energy() {
    for (coef, l) in [(GreekCoefficients::rayleigh(0.0), "rayleigh"), (gs(), "gs")] {
        // τ ≥ ~250 continue in the diffusion regime (`layer::DiffusionWatch`).
        for tau in [1e-6, 0.5, 1.0, 30.0, 1e3, 1e4, 1e6, f64::INFINITY] {
            let (mu_q, w_q) = double_gauss(16);
            let grid = Grid {
                ns: 4,
                mu_q: mu_q.clone(),
                w_q: w_q.clone(),
                mu_u: vec![0.2, 0.6, 1.0],
                split: None,
            };
            let layer = Layer {
                thickness: if tau.is_finite() {
                    Thickness::Finite(tau)
                } else {
                    Thickness::Infinite
                },
                albedo: 1.0,
                coef: coef.clone(),
            };
            let o = layer_ops(&grid, &layer, 0, &Settings::default(), true);
            for (v, &mv) in grid.mu_u.iter().enumerate() {
                let mut flux = mv * (-tau / mv).exp();
                for i in 0..mu_q.len() {
                    flux += w_q[i] * mu_q[i] * (o.rb[(i * 4, v * 4)] + o.tb[(i * 4, v * 4)]);
                }
                let err = (flux - mv).abs() / mv;
                eprintln!("{l} tau={tau} mu0={mv}: {err:.2e}");
                assert!(
                    err < 1e-9,
                    "{l} tau={tau} mu0={mv}: relative flux error {err:e}"
                );
            }
            // Quadrature inputs: Σ_i w_i μ_i (R + T)_ij = w_j μ_j.
            for j in 0..mu_q.len() {
                let mut flux = 0.0;
                for i in 0..mu_q.len() {
                    flux += w_q[i] * mu_q[i] * (o.r[(i * 4, j * 4)] + o.t[(i * 4, j * 4)]);
                }
                let err = (flux - w_q[j] * mu_q[j]).abs() / (w_q[j] * mu_q[j]);
                assert!(err < 1e-9, "{l} tau={tau} column {j}: {err:e}");
            }
        }
    }
}

/// The diffusion continuation of a conservative layer (`layer::
/// DiffusionWatch`) agrees with carrying on doubling, where doubling is
/// still accurate: a layer of 0.75 · 2¹⁰ = 768 (continued from ~250)
/// against the layer of 0.75 doubled ten times with `add` (the same start
/// layer), every block, both paths; and the semi-infinite layer's
/// reflection is the τ → ∞ limit of the finite ones.
#[test]
fn diffusion_continuation_matches_doubling() {
    let (mu_q, w_q) = double_gauss(8);
    let grid = Grid {
        ns: 4,
        mu_q,
        w_q,
        mu_u: vec![0.2, 0.6, 1.0],
        split: None,
    };
    let s = Settings::default();
    for coef in [GreekCoefficients::rayleigh(0.0), gs()] {
        let at = |tau: Thickness, full: bool| {
            let l = Layer {
                thickness: tau,
                albedo: 1.0,
                coef: coef.clone(),
            };
            layer_ops(&grid, &l, 0, &s, full)
        };
        for full in [true, false] {
            let mut doubled = at(Thickness::Finite(0.75), full);
            for _ in 0..10 {
                doubled = add(&doubled, &doubled, full);
            }
            let continued = at(Thickness::Finite(0.75 * 1024.0), full);
            // Pairs (reflection, transmission) with the same input; both
            // measured against the reflection's size (T ~ 1/τ is small, its
            // absolute error is what carries energy).
            let pairs = [
                (&doubled.r, &continued.r, &doubled.t, &continued.t),
                (&doubled.ru, &continued.ru, &doubled.tus, &continued.tus),
                (&doubled.rb, &continued.rb, &doubled.tb, &continued.tb),
            ];
            for (k, (ra, rb, ta, tb)) in pairs.into_iter().enumerate() {
                let scale = layer::max_abs(ra.as_ref());
                let dr = layer::max_abs((ra - rb).as_ref());
                let dt = layer::max_abs((ta - tb).as_ref());
                // Doubling's own round-off at τ = 768 is ~1e-10.
                assert!(
                    dr.max(dt) <= 1e-9 * scale,
                    "full={full} pair {k}: {dr:e}, {dt:e} of {scale:e}"
                );
            }
            let scale = layer::max_abs(doubled.ruu.as_ref());
            let d = layer::max_abs((&doubled.ruu - &continued.ruu).as_ref());
            eprintln!("full={full}: ruu {:.2e} relative", d / scale);
            assert!(d <= 1e-9 * scale, "full={full} ruu: {d:e} of {scale:e}");
            // R(τ) → R∞ like 1/τ: the semi-infinite layer lies beyond.
            let inf = at(Thickness::Infinite, full);
            let d1 = &inf.ruu - &continued.ruu;
            let d2 = &inf.ruu - &at(Thickness::Finite(0.75 * 2048.0), full).ruu;
            let (n1, n2) = (layer::max_abs(d1.as_ref()), layer::max_abs(d2.as_ref()));
            assert!(
                (n1 / n2 - 2.0).abs() < 0.02,
                "full={full}: deficits {n1:e} at 768 and {n2:e} at 1536"
            );
        }
    }
}

/// A very thin layer reflects by single scattering:
/// `f = ω Z(Ω_o, Ω_i) (1 − e^{−τ(1/μ + 1/μ0)}) / (4π (μ + μ0))` with `Z`
/// the geometric phase matrix (seed eq. 11), an independent path.
#[test]
fn thin_layer_is_single_scattering() {
    let coef = gs();
    let tau = 1e-5;
    let omega = 0.9;
    let mu = [0.2, 0.5, 0.9];
    let p = problem(Thickness::Finite(tau), omega, coef.clone(), Base::Black, 16);
    let r = reflection(&p, &mu).unwrap();
    let f = |c: f64| {
        let s = coef.evaluate(&[c]);
        [s.a1[0], s.a2[0], s.a3[0], s.a4[0], s.b1[0], s.b2[0]]
    };
    let mut worst: f64 = 0.0;
    for iu in 0..3 {
        for iv in 0..3 {
            for dphi in [0.0, 1.1, 2.5] {
                let z = phase::geometric_phase_matrix(&f, -mu[iv], 0.0, mu[iu], dphi);
                let fac = omega * (-(-tau * (1.0 / mu[iu] + 1.0 / mu[iv])).exp_m1())
                    / (4.0 * PI * (mu[iu] + mu[iv]));
                let got = r.brdf(iu, iv, dphi);
                for i in 0..4 {
                    for j in 0..4 {
                        let expect = fac * z[i][j];
                        worst = worst.max((got[i][j] - expect).abs() / (fac * z[0][0]));
                    }
                }
            }
        }
    }
    // Double scattering is O(τ/μ) relative.
    assert!(worst < 1e-3, "single-scattering limit off by {worst:e}");
}

/// Mirror image: a layer of thickness τ on a perfect conductor (Jones
/// diag(1, −1) in our frames, Mueller `S = diag(1, 1, −1, −1)`) reflects
/// like a layer of thickness 2τ whose transmitted light is mapped by `S`.
#[test]
fn perfect_mirror_equals_doubled_layer() {
    let (mu_q, w_q) = double_gauss(12);
    let grid = Grid {
        ns: 4,
        mu_q,
        w_q,
        mu_u: vec![0.3, 0.7, 1.0],
        split: None,
    };
    let s_mat: Mueller = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, -1.0, 0.0],
        [0.0, 0.0, 0.0, -1.0],
    ];
    for m in [0usize, 1, 4] {
        let one = Layer {
            thickness: Thickness::Finite(0.6),
            albedo: 0.95,
            coef: gs(),
        };
        let two = Layer {
            thickness: Thickness::Finite(1.2),
            ..one.clone()
        };
        let s = Settings::default();
        let a = layer_ops(&grid, &one, m, &s, true);
        let mq = mirror_blocks(&grid.mu_q, 4, &|_| s_mat);
        let mu = mirror_blocks(&grid.mu_u, 4, &|_| s_mat);
        let top = add_mirror(&a, &mq, &mu);
        let b = layer_ops(&grid, &two, m, &s, true);
        let expect = &b.ruu + layer::mm(mu.as_ref(), b.tuu.as_ref());
        let diff = layer::max_abs((&top.ruu - &expect).as_ref());
        let scale = layer::max_abs(expect.as_ref());
        assert!(diff < 1e-8 * scale, "m={m}: {diff:e} vs {scale:e}");
    }
}
