//! The rough base against the microfacet model it projects, an independent
//! integration of its albedo, reciprocity, and its smooth limit.
use super::law_tests::problem;
use super::*;
use crate::physics::RefractiveIndex;
use crate::physics::expansion::GreekCoefficients;
use crate::physics::fresnel;
use crate::physics::microfacet::RoughSurface;
use crate::physics::quadrature::gauss_legendre_on;
use std::f64::consts::PI;

const ALUMINIUM: RefractiveIndex = RefractiveIndex { n: 1.2, k: 7.26 };

fn rough(alpha: f64) -> Base {
    Base::Rough {
        surface: RoughSurface::new(1.0, ALUMINIUM, alpha).unwrap(),
    }
}

fn smooth() -> Base {
    Base::Mirror {
        mueller: std::sync::Arc::new(|m: f64| fresnel::mueller(1.0, ALUMINIUM, m).unwrap()),
    }
}

/// No layer: the solved BRDF is the microfacet model's, summed back from
/// its Fourier projection.
#[test]
fn a_bare_rough_base_reproduces_the_microfacet_brdf() {
    let mu = [0.15, 0.5, 0.8, 1.0];
    for alpha in [0.1, 0.3] {
        let p = problem(
            Thickness::Finite(0.0),
            1.0,
            GreekCoefficients::rayleigh(0.0),
            rough(alpha),
            8,
        );
        let Base::Rough { surface } = &p.base else {
            unreachable!()
        };
        let r = reflection(&p, &mu).unwrap();
        let mut worst: f64 = 0.0;
        let mut scale: f64 = 0.0;
        for iu in 0..mu.len() {
            for iv in 0..mu.len() {
                for d in [0.0, 0.2, 1.0, 2.5, PI, -0.7] {
                    let got = r.brdf(iu, iv, d);
                    let want = surface.mueller(mu[iu], mu[iv], d);
                    scale = scale.max(want[0][0]);
                    for pq in 0..16 {
                        worst = worst.max((got[pq / 4][pq % 4] - want[pq / 4][pq % 4]).abs());
                    }
                }
            }
        }
        eprintln!(
            "alpha {alpha}: worst {worst:e} scale {scale:e} orders {}",
            r.rho.len()
        );
        assert!(
            worst <= 1e-6 * scale,
            "alpha {alpha}: {worst:e} of {scale:e}"
        );
    }
}

/// The directional albedo of the bare base, `A(μ_i) = ∫ f₁₁ μ_o dω_o`,
/// against the same integral in half-vector space,
/// `∫ D(h) G₂ R(i·h) (i·h)/μ_i dω_h` (`dω_o = 4 (i·h) dω_h`), on its own
/// quadrature (tan θ_h/α panels, composite Gauss in φ_h).
#[test]
fn the_bare_base_albedo_matches_an_independent_integration() {
    for alpha in [0.05, 0.2, 0.6] {
        let s = RoughSurface::new(1.0, ALUMINIUM, alpha).unwrap();
        let mu0 = [0.1, 0.45, 0.9];
        let p = problem(
            Thickness::Finite(0.0),
            1.0,
            GreekCoefficients::rayleigh(0.0),
            rough(alpha),
            16,
        );
        let got = stream_fluxes(&p, &mu0).unwrap().reflected;
        for (&mi, &a) in mu0.iter().zip(&got) {
            let i = [(1.0 - mi * mi).sqrt(), 0.0, mi];
            let mut sum = 0.0;
            let edges: Vec<f64> = (0..=80).map(|k| (k as f64 / 4.0).powi(2)).collect();
            for e in edges.windows(2) {
                let (xt, wt) = gauss_legendre_on(8, e[0], e[1]);
                for (&t, &w) in xt.iter().zip(&wt) {
                    let th = (alpha * t).atan();
                    let dth = alpha / (1.0 + alpha * alpha * t * t);
                    let (st, ct) = th.sin_cos();
                    for k in 0..64 {
                        let (xp, wp) =
                            gauss_legendre_on(8, PI * k as f64 / 32.0, PI * (k + 1) as f64 / 32.0);
                        for (&ph, &wph) in xp.iter().zip(&wp) {
                            let h = [st * ph.cos(), st * ph.sin(), ct];
                            let ih = i[0] * h[0] + i[2] * h[2];
                            let mo = 2.0 * ih * h[2] - i[2];
                            if ih <= 0.0 || mo <= 0.0 {
                                continue;
                            }
                            let r = fresnel::reflectances(1.0, ALUMINIUM, ih).unwrap().r;
                            sum += w
                                * dth
                                * st
                                * wph
                                * s.distribution(ct)
                                * s.shadowing(mi, mo)
                                * r
                                * ih
                                / mi;
                        }
                    }
                }
            }
            eprintln!(
                "alpha {alpha} mu0 {mi}: solver {a} independent {sum} diff {:e}",
                a - sum
            );
            assert!(
                (a - sum).abs() < 1e-4,
                "alpha {alpha} mu0 {mi}: {a} vs {sum}"
            );
        }
    }
}

/// Reciprocity of a layer over the rough base (the base's blocks are
/// symmetric in the flux-weighted form, `rough_base` module doc).
#[test]
fn a_layer_over_a_rough_base_is_reciprocal() {
    let mu = [0.15, 0.4, 0.77, 1.0];
    let gs = crate::physics::expansion::test_data::garcia_siewert();
    let mut p = problem(Thickness::Finite(0.8), 0.97, gs, rough(0.2), 16);
    p.settings.start_factor = 1e-3;
    let r = reflection(&p, &mu).unwrap();
    let (worst, scale) = super::symmetry_tests::reciprocity_defect(&r);
    eprintln!("reciprocity {worst:e} of {scale:e}");
    assert!(
        worst < 1e-8 * scale,
        "reciprocity violated by {worst:e} (scale {scale:e})"
    );
}

/// As `α → 0` a layer over the rough base tends to the same layer over the
/// smooth (Fresnel) base: its plane albedo (diffuse plus the delta term)
/// and its BRDF away from the mirror side (backscatter plane). Both errors
/// fall at least linearly in `α` (the shadowing deficit `1 − G₂ = O(α)`
/// and the lobe's tails move light by `O(α)`; the albedo falls faster,
/// about `α^1.7`): each halving of `α` must divide the albedo error by
/// 2.5 and the BRDF's by 1.8, and at `α = 0.05` the albedo is within 1 %.
#[test]
fn a_rough_base_tends_to_the_smooth_one_as_alpha_goes_to_zero() {
    let mu = [0.2, 0.5, 0.8];
    let layer = |base| {
        problem(
            Thickness::Finite(0.5),
            0.9,
            GreekCoefficients::rayleigh(0.0),
            base,
            12,
        )
    };
    let smooth_p = layer(smooth());
    let a_smooth = stream_fluxes(&smooth_p, &mu).unwrap().reflected;
    let r_smooth = reflection(&smooth_p, &mu).unwrap();
    let mut errors = Vec::new();
    for alpha in [0.2, 0.1, 0.05] {
        let p = layer(rough(alpha));
        let a = stream_fluxes(&p, &mu).unwrap().reflected;
        let r = reflection(&p, &mu).unwrap();
        let da = a
            .iter()
            .zip(&a_smooth)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        let mut df: f64 = 0.0;
        for iu in 0..mu.len() {
            for iv in 0..mu.len() {
                let x = r.brdf(iu, iv, PI);
                let y = r_smooth.brdf(iu, iv, PI);
                for pq in 0..16 {
                    df = df.max((x[pq / 4][pq % 4] - y[pq / 4][pq % 4]).abs());
                }
            }
        }
        eprintln!("alpha {alpha}: albedo error {da:e}, backscatter BRDF error {df:e}");
        errors.push((alpha, da, df));
    }
    for w in errors.windows(2) {
        let ((a0, da0, df0), (a1, da1, df1)) = (w[0], w[1]);
        assert!(da0 / da1 >= 2.5, "albedo: α {a0} → {a1}: {da0:e} → {da1:e}");
        assert!(df0 / df1 >= 1.8, "BRDF: α {a0} → {a1}: {df0:e} → {df1:e}");
    }
    assert!(errors[2].1 < 1e-2, "albedo at α = 0.05: {:e}", errors[2].1);
}
