//! Tests of the size-distribution optics (physics::psd).

use super::integrator::{Integrator, U_STEP0};
use super::*;
use crate::physics::mie::tests::gauss_legendre;

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

const LAMBDA: f64 = 550.0;
const N_HOST: f64 = 1.5;

fn k_host() -> f64 {
    2.0 * PI * 1000.0 * N_HOST / LAMBDA
}

/// The rule's mean volume is the third moment of the distribution:
/// log-normal `⟨r³⟩ = r_g³ exp(9/2 ln²σ_g)`, gamma (Hansen & Travis
/// 1974, `α = (1 − 3b)/b`) `⟨r³⟩ = (ab)³ (α+1)(α+2)(α+3)`, both over
/// limits wide enough that the cut tails are below 1e-12.
#[test]
fn the_rule_mean_volume_is_the_third_moment() {
    let quad = PsdQuadrature {
        radius_range_um: Some([1e-4, 20.0]),
        ..Default::default()
    };
    let m = RefractiveIndex::new(2.0, 0.01);
    let mu = [-1.0, 0.0, 1.0];
    let (r_g, s) = (0.2f64, 1.4f64);
    let ln = SizeDistribution::LogNormal {
        r_g_um: r_g,
        sigma_g: s,
    };
    let (a, b) = (0.3f64, 0.1f64);
    let alpha = (1.0 - 3.0 * b) / b;
    let gamma = SizeDistribution::Gamma {
        r_eff_um: a,
        v_eff: b,
    };
    for (d, r3) in [
        (ln, r_g.powi(3) * (4.5 * s.ln().powi(2)).exp()),
        (
            gamma,
            (a * b).powi(3) * (alpha + 1.0) * (alpha + 2.0) * (alpha + 3.0),
        ),
    ] {
        let (_, rule) = bulk_optics_with_rule(&d, m, N_HOST, LAMBDA, &mu, &quad).unwrap();
        let v = 4.0 / 3.0 * PI * r3;
        assert!(
            rel(rule.mean_volume_um3(), v) < 1e-6,
            "{d:?}: {} vs {v}",
            rule.mean_volume_um3()
        );
    }
}

#[test]
fn distributions_are_normalised_with_the_stated_moments() {
    let dists = [
        SizeDistribution::LogNormal {
            r_g_um: 0.2,
            sigma_g: 1.5,
        },
        SizeDistribution::Gamma {
            r_eff_um: 0.3,
            v_eff: 0.1,
        },
        SizeDistribution::Gamma {
            r_eff_um: 0.3,
            v_eff: 0.4,
        },
    ];
    for d in dists {
        // ∫ r^k n dr on a fine log grid (midpoint in ln r) vs ⟨r^k⟩.
        let (t0, t1, n) = ((1e-18f64).ln(), (50.0f64).ln(), 400_000);
        let h = (t1 - t0) / n as f64;
        for k in [0.0, 1.0, 2.0, 3.0] {
            let s: f64 = (0..n)
                .map(|i| {
                    let r = (t0 + h * (i as f64 + 0.5)).exp();
                    r.powf(k) * d.number_density(r) * r * h
                })
                .sum();
            assert!(
                rel(s, d.moment(k)) < 1e-6,
                "{d:?} k={k}: {s} vs {}",
                d.moment(k)
            );
        }
        if let SizeDistribution::Gamma { r_eff_um, v_eff } = d {
            // Hansen & Travis definitions of r_eff and v_eff.
            let (m2, m3, m4) = (d.moment(2.0), d.moment(3.0), d.moment(4.0));
            assert!(rel(m3 / m2, r_eff_um) < 1e-12);
            let v =
                (m4 - 2.0 * r_eff_um * m3 + r_eff_um * r_eff_um * m2) / (r_eff_um * r_eff_um * m2);
            assert!(rel(v, v_eff) < 1e-10);
        }
    }
}

// ------------------------------------------------------------ bulk optics
/// In the Rayleigh regime the averages are analytic: ⟨C_sca⟩ =
/// (8/3)π k⁴ |K|² ⟨r⁶⟩, ⟨C_abs⟩ = 4π k Im K ⟨r³⟩, a1 = ¾(1+μ²),
/// b1 = −¾(1−μ²). Tests truncation (r⁶ and r³ tails) and quadrature.
#[test]
fn rayleigh_regime_matches_analytic_moments() {
    let mu: Vec<f64> = (0..=8).map(|i| -1.0 + 0.25 * i as f64).collect();
    let p = RefractiveIndex::new(2.0, 0.1);
    let m = p.as_complex() / N_HOST;
    let kk = (m * m - 1.0) / (m * m + 2.0);
    let k = k_host();
    for d in [
        SizeDistribution::LogNormal {
            r_g_um: 2e-5,
            sigma_g: 1.5,
        },
        SizeDistribution::Gamma {
            r_eff_um: 5e-5,
            v_eff: 0.2,
        },
    ] {
        let b = bulk_optics(&d, p, N_HOST, LAMBDA, &mu, &PsdQuadrature::default()).unwrap();
        let c_sca = 8.0 / 3.0 * PI * k.powi(4) * kk.norm_sqr() * d.moment(6.0);
        let c_abs = 4.0 * PI * k * kk.im * d.moment(3.0);
        assert!(
            b.size_parameter_max < 0.02,
            "{d:?}: x_max {}",
            b.size_parameter_max
        );
        assert!(
            rel(b.c_sca_um2, c_sca) < 5e-6,
            "{d:?}: C_sca {} vs {c_sca}",
            b.c_sca_um2
        );
        assert!(
            rel(b.c_abs_um2, c_abs) < 5e-6,
            "{d:?}: C_abs {} vs {c_abs}",
            b.c_abs_um2
        );
        assert!(rel(b.c_ext_um2, c_sca + c_abs) < 5e-6);
        for (i, &u) in mu.iter().enumerate() {
            assert!((b.matrix.a1[i] - 0.75 * (1.0 + u * u)).abs() < 1e-5);
            assert!((b.matrix.b1[i] + 0.75 * (1.0 - u * u)).abs() < 1e-5);
        }
    }
}

/// A very narrow distribution reproduces the single sphere at its radius.
/// The difference is ½ s² C''/C for a relative width s, and C''/C reaches
/// ~1e3 near a resonance (m = 1.8, x = 4.3 here), so the widths are chosen
/// to keep it below the tolerance; the tails are cut at 1e-9.
#[test]
fn narrow_distributions_reproduce_single_sphere() {
    let mu: Vec<f64> = (0..=12)
        .map(|i| (15.0 * i as f64 * PI / 180.0).cos())
        .collect();
    let quad = PsdQuadrature {
        tail_fraction: 1e-9,
        ..Default::default()
    };
    for (d, p, tol, tol_matrix) in [
        // s = 1e-5: ½ s² C''/C ~ 5e-8.
        (
            SizeDistribution::LogNormal {
                r_g_um: 0.25,
                sigma_g: 1.00001,
            },
            RefractiveIndex::new(2.7, 0.01),
            1e-6,
            1e-6,
        ),
        // s = √v_eff = 1e-3 (the narrowest gamma law accepted) with an
        // absorbing sphere: ~1e-5 for the cross sections, ~3e-4 for the
        // angular pattern, whose structure shifts faster with x.
        (
            SizeDistribution::Gamma {
                r_eff_um: 0.25,
                v_eff: 1e-6,
            },
            RefractiveIndex::new(2.7, 0.3),
            1e-4,
            1e-3,
        ),
    ] {
        let r = 0.25;
        let b = bulk_optics(&d, p, N_HOST, LAMBDA, &mu, &quad).unwrap();
        let s = MieResult::for_sphere(p, N_HOST, LAMBDA, r).unwrap();
        let geo = PI * r * r;
        let dev = [
            rel(b.c_ext_um2, s.qext * geo),
            rel(b.c_sca_um2, s.qsca * geo),
            rel(b.c_abs_um2, s.qabs * geo),
            (b.g - s.g).abs(),
        ];
        assert!(dev.iter().all(|&v| v < tol), "{d:?}: {dev:?}");
        let f = s.scattering_matrix(&mu).unwrap();
        let mut worst: f64 = 0.0;
        for i in 0..mu.len() {
            for (u, v) in [
                (b.matrix.a1[i], f.a1[i]),
                (b.matrix.b1[i], f.b1[i]),
                (b.matrix.a3[i], f.a3[i]),
                (b.matrix.b2[i], f.b2[i]),
            ] {
                worst = worst.max((u - v).abs() / f.a1[i]);
            }
        }
        eprintln!(
            "{d:?}: deviations from the single sphere: C_ext {:.1e}, C_sca {:.1e}, C_abs {:.1e}, g {:.1e}, matrix {worst:.1e}",
            dev[0], dev[1], dev[2], dev[3]
        );
        assert!(worst < tol_matrix, "{d:?}: matrix {worst}");
    }
}

/// The averaged matrix is normalised, a1 = a2 and a3 = a4, and g agrees
/// with ½∫a1 μ dμ.
#[test]
fn averaged_matrix_is_normalised() {
    let d = SizeDistribution::LogNormal {
        r_g_um: 0.15,
        sigma_g: 1.4,
    };
    let p = RefractiveIndex::new(2.0, 0.0);
    let quad = PsdQuadrature {
        rel_tol: 1e-7,
        ..Default::default()
    };
    let probe = bulk_optics(&d, p, N_HOST, LAMBDA, &[], &quad).unwrap();
    let n_max = mie::series_length(probe.size_parameter_max);
    let (mu, w) = gauss_legendre(n_max + 20);
    let b = bulk_optics(&d, p, N_HOST, LAMBDA, &mu, &quad).unwrap();
    let norm: f64 = 0.5 * b.matrix.a1.iter().zip(&w).map(|(a, w)| a * w).sum::<f64>();
    assert!((norm - 1.0).abs() < 1e-10, "½∫a1 = {norm}");
    let g: f64 = 0.5
        * b.matrix
            .a1
            .iter()
            .zip(&w)
            .zip(&mu)
            .map(|((a, w), u)| a * w * u)
            .sum::<f64>();
    assert!((g - b.g).abs() < 1e-10, "g {g} vs {}", b.g);
    assert_eq!(b.matrix.a1, b.matrix.a2);
    assert_eq!(b.matrix.a3, b.matrix.a4);
    assert_eq!(b.albedo, 1.0);
    assert_eq!(b.c_abs_um2, 0.0);
    // Same bulk numbers with or without angles.
    assert!(rel(b.c_sca_um2, probe.c_sca_um2) < 1e-6);
}

/// Convergence: the error estimate is below rel_tol; a run at rel_tol/100
/// and a run with the first-level spacing halved (twice the nodes from the
/// start) agree to rel_tol; cutting the tails at 1e-8 instead of 1e-6
/// changes C_ext by ~1e-6 and the matrix by < 1e-5 of a1 (at back-
/// scattering minima of ⟨S11⟩ the tails weigh a few times more). Weakly
/// absorbing and non-absorbing TiO2-like spheres (m = 1.97 relative:
/// sharp resonances).
#[test]
fn quadrature_converges_under_refinement() {
    let mu: Vec<f64> = (0..=18)
        .map(|i| (10.0 * i as f64 * PI / 180.0).cos())
        .collect();
    let cases = [
        (
            SizeDistribution::LogNormal {
                r_g_um: 0.2,
                sigma_g: 1.3,
            },
            RefractiveIndex::new(2.954, 0.003),
        ),
        (
            SizeDistribution::Gamma {
                r_eff_um: 0.8,
                v_eff: 0.05,
            },
            RefractiveIndex::new(2.954, 0.003),
        ),
        (
            SizeDistribution::LogNormal {
                r_g_um: 0.2,
                sigma_g: 1.3,
            },
            RefractiveIndex::new(2.954, 0.0),
        ),
        (
            SizeDistribution::Gamma {
                r_eff_um: 0.8,
                v_eff: 0.05,
            },
            RefractiveIndex::new(2.954, 0.0),
        ),
    ];
    let worst_dev = |a: &BulkOptics, b: &BulkOptics| {
        let mut w = rel(a.c_ext_um2, b.c_ext_um2)
            .max(rel(a.c_sca_um2, b.c_sca_um2))
            .max((a.c_abs_um2 - b.c_abs_um2).abs() / b.c_ext_um2)
            .max((a.g - b.g).abs());
        for i in 0..a.matrix.mu.len() {
            let s = b.matrix.a1[i];
            for (u, v) in [
                (a.matrix.a1[i], b.matrix.a1[i]),
                (a.matrix.b1[i], b.matrix.b1[i]),
                (a.matrix.a3[i], b.matrix.a3[i]),
                (a.matrix.b2[i], b.matrix.b2[i]),
            ] {
                w = w.max((u - v).abs() / s);
            }
        }
        w
    };
    for (d, p) in cases {
        let quad = PsdQuadrature::default();
        let b = bulk_optics(&d, p, N_HOST, LAMBDA, &mu, &quad).unwrap();
        assert!(b.rel_error_estimate <= quad.rel_tol);
        if p.k > 0.0 {
            assert_eq!(b.unresolved_panels, 0);
        }
        let tight_tol = 1e-8;
        let tight = PsdQuadrature {
            rel_tol: tight_tol,
            max_nodes: Some(1_000_000),
            ..quad
        };
        let bt = bulk_optics(&d, p, N_HOST, LAMBDA, &mu, &tight).unwrap();
        let dev_tight = worst_dev(&b, &bt);
        let mut integ = Integrator::new(&d, p, N_HOST, LAMBDA, &mu, &quad).unwrap();
        integ.step0 = 0.5 * U_STEP0;
        let t = integ.integrate().unwrap();
        let bd = integ.finish(&t);
        let dev_doubled = worst_dev(&b, &bd);
        let thin = PsdQuadrature {
            tail_fraction: 1e-8,
            ..quad
        };
        let bs = bulk_optics(&d, p, N_HOST, LAMBDA, &mu, &thin).unwrap();
        let dev_tail = worst_dev(&b, &bs);
        eprintln!(
            "{d:?} k={}: {} nodes (x_max {:.1}, {} unresolved panels), error estimate \
             {:.1e}; deviation from rel_tol {tight_tol:e} ({} nodes) {dev_tight:.1e}, from halved \
             h0 ({} nodes) {dev_doubled:.1e}, from tail 1e-8 {dev_tail:.1e}",
            p.k,
            b.n_radius_nodes,
            b.size_parameter_max,
            b.unresolved_panels,
            b.rel_error_estimate,
            bt.n_radius_nodes,
            bd.n_radius_nodes
        );
        assert!(
            dev_tight < quad.rel_tol,
            "{d:?} {p:?}: vs tight {dev_tight}"
        );
        assert!(
            dev_doubled < quad.rel_tol,
            "{d:?} {p:?}: vs doubled {dev_doubled}"
        );
        assert!(dev_tail < 1e-5, "{d:?} {p:?}: vs thinner tails {dev_tail}");
    }
}

#[test]
fn invalid_inputs_are_errors() {
    let p = RefractiveIndex::new(1.5, 0.0);
    let q = PsdQuadrature::default();
    let name = |r: Result<BulkOptics, PhysicsError>| match r {
        Err(PhysicsError::OutOfRange { name, .. }) => name,
        other => panic!("{other:?}"),
    };
    let ln = |r, s| SizeDistribution::LogNormal {
        r_g_um: r,
        sigma_g: s,
    };
    let ga = |r, v| SizeDistribution::Gamma {
        r_eff_um: r,
        v_eff: v,
    };
    assert_eq!(
        name(bulk_optics(&ln(0.1, 1.0), p, 1.5, 550.0, &[], &q)),
        "sigma_g"
    );
    assert_eq!(
        name(bulk_optics(&ln(-0.1, 1.5), p, 1.5, 550.0, &[], &q)),
        "r_g_um"
    );
    assert_eq!(
        name(bulk_optics(&ga(0.1, 0.5), p, 1.5, 550.0, &[], &q)),
        "v_eff"
    );
    assert_eq!(
        name(bulk_optics(&ga(0.0, 0.1), p, 1.5, 550.0, &[], &q)),
        "r_eff_um"
    );
    assert_eq!(
        name(bulk_optics(&ga(0.1, 0.1), p, 0.5, 550.0, &[], &q)),
        "host_index"
    );
    assert_eq!(
        name(bulk_optics(&ga(0.1, 0.1), p, 1.5, 550.0, &[2.0], &q)),
        "mu"
    );
    assert_eq!(
        name(bulk_optics(
            &ga(0.1, 0.1),
            RefractiveIndex::new(1.5, 0.0),
            1.5,
            550.0,
            &[],
            &q
        )),
        "|relative_index - 1|"
    );
    assert_eq!(
        name(bulk_optics(&ln(500.0, 2.0), p, 1.0, 550.0, &[], &q)),
        "size_parameter at the upper cut of the size distribution"
    );
    assert_eq!(
        name(bulk_optics(
            &ln(1e-8, 1.5),
            RefractiveIndex::new(2.0, 0.0),
            1.0,
            550.0,
            &[],
            &q
        )),
        "size_parameter at the lower cut of the size distribution"
    );
    let tiny = PsdQuadrature {
        max_nodes: Some(200),
        ..q
    };
    let r = bulk_optics(
        &ln(0.5, 1.5),
        RefractiveIndex::new(2.0, 0.0),
        1.5,
        550.0,
        &[],
        &tiny,
    );
    assert!(matches!(r, Err(PhysicsError::Invalid(_))), "{r:?}");
}

#[test]
fn serde_forms_are_tagged_and_round_trip() {
    let d = SizeDistribution::Gamma {
        r_eff_um: 0.3,
        v_eff: 0.1,
    };
    let s = serde_json::to_string(&d).unwrap();
    assert_eq!(s, r#"{"kind":"gamma","r_eff_um":0.3,"v_eff":0.1}"#);
    let d2: SizeDistribution =
        serde_json::from_str(r#"{"kind":"log_normal","r_g_um":0.2,"sigma_g":1.5}"#).unwrap();
    assert_eq!(
        d2,
        SizeDistribution::LogNormal {
            r_g_um: 0.2,
            sigma_g: 1.5
        }
    );
    let b = bulk_optics(
        &d2,
        RefractiveIndex::new(2.0, 0.01),
        1.5,
        550.0,
        &[1.0, 0.0],
        &PsdQuadrature::default(),
    )
    .unwrap();
    let back: BulkOptics = serde_json::from_str(&serde_json::to_string(&b).unwrap()).unwrap();
    assert!(rel(back.c_ext_um2, b.c_ext_um2) < 1e-15);
}
