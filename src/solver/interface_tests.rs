//! Laws and closed forms of a stack under a smooth top interface
//! ([`interface`]).
use super::*;
use crate::physics::RefractiveIndex;
use crate::physics::expansion::GreekCoefficients;
use crate::physics::fresnel;
use crate::physics::quadrature::gauss_legendre_on;
use crate::physics::stokes::Mueller;
use std::f64::consts::PI;

fn gs() -> GreekCoefficients {
    crate::physics::expansion::test_data::garcia_siewert()
}

/// [`super::law_tests::problem`] under an interface of `index`.
fn under(
    tau: Thickness,
    albedo: f64,
    coef: GreekCoefficients,
    base: Base,
    streams: usize,
    index: Option<f64>,
) -> Problem {
    Problem {
        top_interface: index.map(|index| TopInterface { index, alpha: None }),
        ..super::law_tests::problem(tau, albedo, coef, base, streams)
    }
}

/// The plane albedo of the beam along user direction `iv` (cosine `mu0`):
/// the delta term's share plus the BRDF integrated over the outgoing
/// hemisphere on the quadrature `nodes` (the first user directions).
fn plane_albedo(r: &ReflectionFourier, nodes: &[(f64, f64)], iv: usize, mu0: f64) -> f64 {
    let diffuse: f64 = nodes
        .iter()
        .enumerate()
        .map(|(j, &(m, w))| w * m * r.rho[0][(j * 4, iv * 4)] / mu0)
        .sum();
    r.interface_specular(iv).unwrap()[0][0] + diffuse
}

/// Gauss–Legendre `(node, weight)` pairs on `[a, b]`.
fn gauss_on(n: usize, a: f64, b: f64) -> Vec<(f64, f64)> {
    let (x, w) = gauss_legendre_on(n, a, b);
    x.into_iter().zip(w).collect()
}

/// The internal diffuse reflectance of the interface for unpolarized
/// isotropic light from the binder, `r_i = ∫₀¹ R_{n→1}(μ) 2μ dμ`, by Gauss
/// rules on either side of the critical cosine (where `R` has a square-root
/// kink): independent of the solver's quadrature.
fn internal_diffuse_reflectance(n: f64) -> f64 {
    let mu_c = (1.0 - 1.0 / (n * n)).sqrt();
    let air = RefractiveIndex { n: 1.0, k: 0.0 };
    // Above μ_c, R − 1 ~ √(μ − μ_c): substitute μ = μ_c + s² on that side.
    let below: f64 = gauss_on(64, 0.0, mu_c)
        .iter()
        .map(|&(mu, w)| w * 2.0 * mu)
        .sum();
    let s_max = (1.0 - mu_c).sqrt();
    let above: f64 = gauss_on(64, 0.0, s_max)
        .iter()
        .map(|&(s, w)| {
            let mu = mu_c + s * s;
            let r = fresnel::reflectances(n, air, mu.min(1.0)).unwrap().r;
            w * 2.0 * s * 2.0 * mu * r
        })
        .sum();
    below + above
}

/// A binder of index 1 is no interface: the same response as without one.
#[test]
fn an_index_of_one_is_no_interface() {
    let mu = [0.2, 0.55, 1.0];
    let base = || Base::Lambertian { albedo: 0.6 };
    let plain = reflection(
        &under(Thickness::Finite(0.8), 0.97, gs(), base(), 12, None),
        &mu,
    )
    .unwrap();
    let one = reflection(
        &under(Thickness::Finite(0.8), 0.97, gs(), base(), 12, Some(1.0)),
        &mu,
    )
    .unwrap();
    let mut worst: f64 = 0.0;
    for iu in 0..mu.len() {
        for iv in 0..mu.len() {
            let (a, b) = (plain.brdf(iu, iv, 0.9), one.brdf(iu, iv, 0.9));
            for p in 0..4 {
                for q in 0..4 {
                    worst = worst.max((a[p][q] - b[p][q]).abs());
                }
            }
        }
        assert_eq!(one.interface_specular(iu), Some([[0.0; 4]; 4]));
    }
    assert!(worst < 1e-13, "{worst:e}");
}

/// A Lambertian base of albedo `a` under a vanishing layer in a binder of
/// index `n`: light is trapped by the interface's internal reflection, and
/// the Mueller BRDF has the closed form (every internal reflection returns
/// `r_i` of the unpolarized flux the base sends up; the base depolarizes)
///
/// `f[p][q] = A[p][0](μ_i) · a μ_i0 B[0][q](μ_e0) / (π μ_e0 (1 − a r_i))`
///
/// with `A`, `B` the interface's radiance and beam maps: the vanishing
/// layer reproduces the interface's Fresnel transmission matrices, and the
/// trapping agrees with an independent `r_i`. Its delta term is the Fresnel
/// reflection. The solver's quadrature crosses the critical angle's kink,
/// so it converges algebraically: the measured errors are printed, and the
/// stated error must cover them.
#[test]
fn a_lambertian_base_under_an_interface_traps_light_as_the_closed_form_says() {
    let (n, a) = (1.5, 0.8);
    let r_i = internal_diffuse_reflectance(n);
    // Reciprocity of the interface: r_i = 1 − (1 − r_e)/n², with r_e the
    // diffuse reflectance from air (a smooth integrand); ≈ 0.596 at 1.5.
    let r_e: f64 = gauss_on(64, 0.0, 1.0)
        .iter()
        .map(|&(m, w)| {
            let r = fresnel::reflectances(1.0, RefractiveIndex { n, k: 0.0 }, m);
            w * 2.0 * m * r.unwrap().r
        })
        .sum();
    assert!(
        (r_i - (1.0 - (1.0 - r_e) / (n * n))).abs() < 1e-9,
        "r_i = {r_i}, r_e = {r_e}"
    );
    let mu = [0.15, 0.4, 0.75, 1.0];
    let maps = interface::InterfaceMaps::new(n, &mu).unwrap();
    let closed = |iu: usize, iv: usize| -> Mueller {
        let mut f = [[0.0; 4]; 4];
        for (p, row) in f.iter_mut().enumerate() {
            for (q, x) in row.iter_mut().enumerate() {
                *x = maps.out[iu][p][0] * a * maps.mu_internal[iv] * maps.inp[iv][0][q]
                    / (PI * mu[iv] * (1.0 - a * r_i));
            }
        }
        f
    };
    let scale = closed(3, 3)[0][0];
    let mut last = f64::INFINITY;
    for streams in [8, 16, 32, 64] {
        let p = under(
            Thickness::Finite(0.0),
            0.0,
            gs(),
            Base::Lambertian { albedo: a },
            streams,
            Some(n),
        );
        let r = reflection(&p, &mu).unwrap();
        let mut worst: f64 = 0.0;
        for iu in 0..mu.len() {
            for iv in 0..mu.len() {
                let (got, want) = (r.brdf(iu, iv, 1.3), closed(iu, iv));
                for p in 0..4 {
                    for q in 0..4 {
                        worst = worst.max((got[p][q] - want[p][q]).abs() / scale);
                    }
                }
            }
            let spec = r.interface_specular(iu).unwrap();
            let fresnel = fresnel::mueller(1.0, RefractiveIndex { n, k: 0.0 }, mu[iu]).unwrap();
            assert_eq!(spec, fresnel);
        }
        let estimate = accuracy::reflection_with_estimate(&p, &mu).unwrap();
        let stated = estimate.estimate.max_err_f11;
        eprintln!(
            "N = {streams}: max |f − closed form| / f11(1,1) = {worst:.2e}, stated {stated:.2e}"
        );
        assert!(worst <= last, "N = {streams}: {worst:e} after {last:e}");
        assert!(worst < 2e-2, "N = {streams}: {worst:e}");
        last = worst;
    }
    assert!(last < 1e-4, "{last:e}");
}

/// A semi-infinite conservative layer under an interface reflects all the
/// light it receives: the plane albedo (the delta term's share plus the
/// BRDF integrated over the outgoing hemisphere in air) is 1.
#[test]
fn a_conservative_half_space_under_an_interface_conserves_energy() {
    let n = 1.5;
    let nodes = gauss_on(48, 0.0, 1.0);
    let beams = [0.3, 0.7, 1.0];
    let mut mu: Vec<f64> = nodes.iter().map(|&(m, _)| m).collect();
    mu.extend(beams);
    for streams in [8, 16, 32] {
        let p = under(
            Thickness::Infinite,
            1.0,
            gs(),
            Base::Black,
            streams,
            Some(n),
        );
        let r = reflection(&p, &mu).unwrap();
        let mut worst: f64 = 0.0;
        for (k, &mu0) in beams.iter().enumerate() {
            let albedo = plane_albedo(&r, &nodes, nodes.len() + k, mu0);
            worst = worst.max((albedo - 1.0).abs());
            eprintln!(
                "N = {streams}, μ0 = {mu0}: albedo − 1 = {:.2e}",
                albedo - 1.0
            );
        }
        assert!(worst < 1e-2, "N = {streams}: {worst:e}");
    }
}

/// Reciprocity in air, `f(μ, μ0, Δφ) = Δ f(μ0, μ, −Δφ)ᵀ Δ`: the n² factors
/// of the two crossings cancel.
#[test]
fn the_brdf_under_an_interface_is_reciprocal() {
    let mu = [0.15, 0.4, 0.77, 1.0];
    let silver = Base::Mirror {
        mueller: std::sync::Arc::new(|mu| {
            fresnel::mueller(1.5, RefractiveIndex { n: 0.13, k: 3.99 }, mu).unwrap()
        }),
    };
    for base in [Base::Black, Base::Lambertian { albedo: 0.6 }, silver] {
        let label = format!("{base:?}");
        let mut p = under(Thickness::Finite(0.8), 0.97, gs(), base, 16, Some(1.5));
        p.settings.start_factor = 1e-3;
        let r = reflection(&p, &mu).unwrap();
        let (worst, scale) = super::symmetry_tests::reciprocity_defect(&r);
        eprintln!("{label}: {worst:.2e} of {scale:.2e}");
        assert!(worst < 1e-8 * scale, "{label}: {worst:e} (scale {scale:e})");
    }
}

/// At Brewster's angle the interface reflects no p light (Q = +1 is p:
/// the field in the meridian plane, conventions §5); s light is reflected.
#[test]
fn no_p_light_is_reflected_at_brewsters_angle() {
    let n: f64 = 1.5;
    let mu_b = n.atan().cos();
    let p = under(Thickness::Finite(1.0), 0.9, gs(), Base::Black, 8, Some(n));
    let r = reflection(&p, &[mu_b]).unwrap();
    let s = r.interface_specular(0).unwrap();
    let out = |q: f64| s[0][0] + q * s[0][1];
    assert!(out(1.0).abs() < 1e-15, "p: {:e}", out(1.0));
    let r_s = ((1.0 - n * n) / (1.0 + n * n)).powi(2);
    assert!((out(-1.0) - r_s).abs() < 1e-15, "s: {} vs {r_s}", out(-1.0));
}

/// A bad index is refused with a reason.
#[test]
fn bad_indices_are_refused() {
    for bad in [0.5, f64::NAN, f64::INFINITY] {
        let p = under(Thickness::Finite(1.0), 0.9, gs(), Base::Black, 8, Some(bad));
        let e = reflection(&p, &[0.5]).unwrap_err().to_string();
        assert!(e.contains("top_interface.index"), "{e}");
    }
}

/// Real Fresnel amplitude coefficients `(r_p, r_s)` from index `n1` into
/// `n2` at incidence cosine `mu` inside the cone (Born & Wolf, the signs of
/// `physics::fresnel`), written out here.
fn rp_rs(n1: f64, n2: f64, mu: f64) -> (f64, f64) {
    let w = (n2 * n2 - n1 * n1 * (1.0 - mu * mu)).sqrt();
    (
        (n2 * n2 * mu - n1 * w) / (n2 * n2 * mu + n1 * w),
        (n1 * mu - w) / (n1 * mu + w),
    )
}

fn dielectric_mirror(n1: f64, n2: f64) -> Base {
    Base::Mirror {
        mueller: std::sync::Arc::new(move |mu| {
            fresnel::mueller(n1, RefractiveIndex { n: n2, k: 0.0 }, mu).unwrap()
        }),
    }
}

/// A non-scattering layer (τ = 0.3, ω = 0) in a binder of 1.5 over a
/// dielectric base of 2.2: the beam bounces between base and interface,
/// s and p apart (real coefficients), so the delta term is, per
/// polarization, `R_e + T² R_b E / (1 − R_i R_b E)` (`E = e^{−2τ/μ_i}`,
/// `T = 1 − R_e`, `R_i = R_e` by Stokes' relations), and nothing is diffuse.
#[test]
fn a_mirror_base_under_the_interface_bounces_the_beam_between_the_two() {
    let (n, nb, tau) = (1.5, 2.2, 0.3);
    let mu = [0.2, 0.55, 0.9, 1.0];
    let p = under(
        Thickness::Finite(tau),
        0.0,
        gs(),
        dielectric_mirror(n, nb),
        8,
        Some(n),
    );
    let r = reflection(&p, &mu).unwrap();
    for (iv, &mu_e) in mu.iter().enumerate() {
        let mu_i = (1.0 - (1.0 - mu_e * mu_e) / (n * n)).sqrt();
        let (ep, es) = rp_rs(1.0, n, mu_e);
        let (bp, bs) = rp_rs(n, nb, mu_i);
        let e = (-2.0 * tau / mu_i).exp();
        let total = |re: f64, rb: f64| re + (1.0 - re).powi(2) * rb * e / (1.0 - re * rb * e);
        let (tp, ts) = (total(ep * ep, bp * bp), total(es * es, bs * bs));
        let s = r.interface_specular(iv).unwrap();
        assert!(
            (s[0][0] - 0.5 * (tp + ts)).abs() < 1e-13,
            "μ = {mu_e}: {s:?}"
        );
        assert!(
            (s[0][1] - 0.5 * (tp - ts)).abs() < 1e-13,
            "μ = {mu_e}: {s:?}"
        );
        for iu in 0..mu.len() {
            let f = r.brdf(iu, iv, 0.7);
            assert!(f.iter().flatten().all(|x| x.abs() < 1e-14), "{f:?}");
        }
    }
}

/// A conservative layer over a perfect conductor (Jones `diag(1, −1)`)
/// under the interface loses nothing: the delta term plus the diffuse
/// reflection is all the incident light, and converges to it with the
/// streams.
#[test]
fn a_conservative_layer_over_a_perfect_mirror_under_the_interface_conserves_energy() {
    let perfect = Base::Mirror {
        mueller: std::sync::Arc::new(|_| {
            [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, -1.0, 0.0],
                [0.0, 0.0, 0.0, -1.0],
            ]
        }),
    };
    let nodes = gauss_on(64, 0.0, 1.0);
    let beams = [0.3, 0.7, 1.0];
    let mut mu: Vec<f64> = nodes.iter().map(|&(m, _)| m).collect();
    mu.extend(beams);
    let mut last = f64::INFINITY;
    for streams in [8, 16, 32] {
        let p = under(
            Thickness::Finite(0.5),
            1.0,
            gs(),
            perfect.clone(),
            streams,
            Some(1.5),
        );
        let r = reflection(&p, &mu).unwrap();
        let mut worst: f64 = 0.0;
        for (k, &mu0) in beams.iter().enumerate() {
            let albedo = plane_albedo(&r, &nodes, nodes.len() + k, mu0);
            worst = worst.max((albedo - 1.0).abs());
        }
        eprintln!("N = {streams}: |albedo − 1| ≤ {worst:.2e}");
        assert!(worst < 2e-3 && worst < last, "N = {streams}: {worst:e}");
        last = worst;
    }
}
