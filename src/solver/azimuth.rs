//! A kernel's Fourier coefficients in azimuth at one pair of cosines
//! (docs/solver.md, "Rough bases" and "Edges"), for the projections of
//! [`super::rough_base`].
//!
//! **Smooth kernels: an FFT.** The kernel is sampled at `P` equally spaced
//! propagation azimuths and its coefficients taken by a real FFT (the
//! trapezoidal rule, spectrally accurate for a smooth periodic function).
//! `P` doubles from 32 until the coefficients of the top quarter of the
//! band are below [`AZIMUTH_TOLERANCE`] (the function is resolved, so the
//! aliasing error is below it too), at most [`MAX_AZIMUTHS`]. When only the
//! orders `m < M` are kept (a rough interface over a stack of `M` orders)
//! the series is still resolved in full: the aliases of a kept order come
//! from orders `P ± m`. The mirror symmetry `f(−Δφ) = D f(Δφ) D` halves
//! the evaluations. In the S1 set of conventions §7 order `m` of the
//! response to a unit delta in `μ'` is `ρ^m = 2π μ' F^m` with
//! `F^m = (1/2π)∫ f cos mΔφ` in the IQ/IQ and UV/UV blocks, `+(1/2π)∫ f
//! sin mΔφ` in the UV←IQ block and `−` that in IQ←UV.
//!
//! **A square-root edge: split Gauss rules.** Where facets reflect totally
//! ([`RoughSurface::reflection_azimuth_edge`]) the kernel is
//! `a(Δφ) + b(Δφ)√|Δφ − Δφ_e|` on each side of the edge `Δφ_e`: its
//! coefficients fall only as `m^−3/2`, so the FFT never resolves it and
//! its aliasing error falls as `P^−3/2` (measured: the kept orders of
//! `R_b` under a rough binder surface were off by ~1e-6 of their size at
//! `P` = 8 192). There the kept orders are the integrals over `[0, Δφ_e]`
//! and `[Δφ_e, π]`, each in the variable `s` of `Δφ = Δφ_e ∓ (…)s²`,
//! which makes the edge smooth, by composite Gauss rules of
//! [`SPLIT_NODES`] nodes whose panels double until the coefficients move
//! by less than the FFT's tolerance: the first [`SPLIT_ORDERS`] orders
//! (those of a layer stack; orders above them keep the FFT's).
//!
//! [`RoughSurface::reflection_azimuth_edge`]: crate::physics::microfacet::RoughSurface::reflection_azimuth_edge

use super::rough_base::Kernel;
use crate::physics::quadrature::gauss_legendre_on;
use realfft::RealFftPlanner;
use std::f64::consts::PI;

/// Size of the Fourier coefficients at which a pair's azimuthal series
/// counts as resolved, in units of the cosine-weighted BRDF `f μ_out μ_in`
/// (at most `1/π` for a white Lambertian surface). A BRDF value at a
/// grazing pair is that over `μ_out μ_in`, summed over its orders:
/// measured on a glass surface (α = 0.3) at `μ = 0.15` both ways, 5.7e-5 f
/// (2.3e-7 in `f μ_out μ_in`); at `1e-10` 4e-7 f, for the same order
/// count where the series converges, but tables' grazing nodes then hit
/// [`MAX_AZIMUTHS`].
pub const AZIMUTH_TOLERANCE: f64 = 1e-8;

/// Most azimuth samples per pair of cosines (the FFT's, and the split
/// rules' nodes together).
pub const MAX_AZIMUTHS: usize = 1 << 13;

/// Gauss nodes per panel of the split rules.
pub(super) const SPLIT_NODES: usize = 8;

/// Orders of a pair with an edge that the split rules integrate (their
/// cost is nodes × orders, the FFT's nodes × log nodes). When the caller
/// keeps at most this many (a rough interface over a layer stack) the FFT
/// is not run; beyond them (a rough base's grazing pairs, a rough
/// interface over one, up to [`MAX_AZIMUTHS`]/4 orders) the FFT's
/// coefficients are kept, aliased by `~P^−3/2` of the edge's strength.
const SPLIT_ORDERS: usize = 64;

/// Sign of element `(p, q)` under `f(−Δφ) = D f(Δφ) D`, `D = diag(1,1,−1,−1)`:
/// `+1` for the even (cosine) blocks, `−1` for the odd (sine) ones.
fn parity(p: usize, q: usize) -> f64 {
    if (p < 2) == (q < 2) { 1.0 } else { -1.0 }
}

/// The S1-set Fourier coefficients `ρ^m = 2π μ_in F^m` (module doc) of the
/// kernel at one pair of cosines, `m = 0..max_orders`, each `ns × ns`
/// flattened row-major; `edge` is the kernel's square-root edge in
/// azimuth at this pair, if any (module doc).
pub(super) fn pair_series(
    kernel: &Kernel<'_>,
    edge: Option<f64>,
    mu_out: f64,
    mu_in: f64,
    ns: usize,
    max_orders: usize,
    planner: &mut RealFftPlanner<f64>,
) -> Vec<[f64; 16]> {
    let small = 2.0 * PI * AZIMUTH_TOLERANCE / mu_out;
    let edge = edge.filter(|&e| e > 0.0 && e < PI);
    let mut coef = match edge {
        Some(e) if max_orders <= SPLIT_ORDERS => {
            split_series(kernel, e, mu_out, mu_in, ns, max_orders, small)
        }
        Some(e) => {
            let mut coef = fft_series(kernel, mu_out, mu_in, ns, max_orders, small, planner);
            let low = coef.len().min(SPLIT_ORDERS);
            let split = split_series(kernel, e, mu_out, mu_in, ns, low, small);
            coef[..low].copy_from_slice(&split);
            coef
        }
        None => fft_series(kernel, mu_out, mu_in, ns, max_orders, small, planner),
    };
    while coef
        .last()
        .is_some_and(|c| c.iter().all(|x| x.abs() <= small))
    {
        coef.pop();
    }
    coef
}

/// [`pair_series`] of a smooth kernel by the FFT (module doc), orders
/// `m < max_orders` of those resolved.
fn fft_series(
    kernel: &Kernel<'_>,
    mu_out: f64,
    mu_in: f64,
    ns: usize,
    max_orders: usize,
    small: f64,
    planner: &mut RealFftPlanner<f64>,
) -> Vec<[f64; 16]> {
    let eval = |k: usize, p: usize| kernel(mu_out, mu_in, 2.0 * PI * k as f64 / p as f64);
    let mut size = 32;
    // Samples at Δφ_k = 2πk/size for k = 0..=size/2.
    let mut half: Vec<_> = (0..=size / 2).map(|k| eval(k, size)).collect();
    loop {
        let fft = planner.plan_fft_forward(size);
        let mut input = fft.make_input_vec();
        let mut spectrum = fft.make_output_vec();
        let bands = size / 2 + 1;
        let mut coef = vec![[0.0; 16]; bands];
        for p in 0..ns {
            for q in 0..ns {
                let sign = parity(p, q);
                for (k, x) in input.iter_mut().enumerate() {
                    *x = if k <= size / 2 {
                        half[k][p][q]
                    } else {
                        sign * half[size - k][p][q]
                    };
                }
                fft.process(&mut input, &mut spectrum)
                    .expect("buffers from the plan");
                let scale = 2.0 * PI * mu_in / size as f64;
                for (m, z) in spectrum.iter().enumerate() {
                    // (1/2π)∫ f cos = Re X/P; (1/2π)∫ f sin = −Im X/P.
                    let x = match (p < 2, q < 2) {
                        (true, true) | (false, false) => z.re,
                        (false, true) => -z.im,
                        (true, false) => z.im,
                    };
                    coef[m][p * ns + q] = scale * x;
                }
            }
        }
        let top: f64 = coef[size / 4..]
            .iter()
            .flat_map(|c| c.iter())
            .fold(0.0, |a, &x| a.max(x.abs()));
        // In units of the cosine-weighted BRDF: |ρ^m| μ_out = 2π |F^m| μ_out μ_in.
        if top <= small || size >= MAX_AZIMUTHS {
            coef.truncate((size / 4).min(max_orders));
            return coef;
        }
        let doubled = 2 * size;
        half = (0..=size)
            .map(|k| {
                if k % 2 == 0 {
                    half[k / 2]
                } else {
                    eval(k, doubled)
                }
            })
            .collect();
        size = doubled;
    }
}

/// [`pair_series`] of a kernel with a square-root edge at `edge ∈ (0, π)`,
/// orders `m < orders`: `ρ^m = 2 μ_in ∫_0^π f(Δφ) c_m(Δφ) dΔφ` (`c_m` the
/// cosine or ± sine of the element's block, module doc; the integrand is
/// even), split at the edge, `Δφ = edge − edge·s²` below it and
/// `edge + (π − edge)s²` above, `s ∈ [0, 1]` on equal panels that double
/// from 4 until no coefficient moves by more than `small`.
fn split_series(
    kernel: &Kernel<'_>,
    edge: f64,
    mu_out: f64,
    mu_in: f64,
    ns: usize,
    orders: usize,
    small: f64,
) -> Vec<[f64; 16]> {
    let rule = |panels: usize| {
        let mut coef = vec![[0.0; 16]; orders];
        for (a, b) in [(edge, -edge), (edge, PI - edge)] {
            for p in 0..panels {
                let (lo, hi) = (p as f64 / panels as f64, (p + 1) as f64 / panels as f64);
                let (s, w) = gauss_legendre_on(SPLIT_NODES, lo, hi);
                for (&s, &w) in s.iter().zip(&w) {
                    // Δφ = a + b s², dΔφ = 2|b| s ds.
                    let d = a + b * s * s;
                    let weight = 2.0 * mu_in * w * 2.0 * b.abs() * s;
                    accumulate(&mut coef, &kernel(mu_out, mu_in, d), d, weight, ns);
                }
            }
        }
        coef
    };
    let mut panels = 4;
    let mut coef = rule(panels);
    loop {
        panels *= 2;
        let finer = rule(panels);
        let moved = coef
            .iter()
            .zip(&finer)
            .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
            .fold(0.0, f64::max);
        if moved <= small || 4 * panels * SPLIT_NODES >= MAX_AZIMUTHS {
            return finer;
        }
        coef = finer;
    }
}

/// `coef[m] += weight · f · c_m(d)` for every order, `c_m` the cosine or
/// ± sine of each element's block (module doc), by the angle-addition
/// recurrence.
fn accumulate(coef: &mut [[f64; 16]], f: &[[f64; 4]; 4], d: f64, weight: f64, ns: usize) {
    let (s1, c1) = d.sin_cos();
    let (mut sm, mut cm) = (0.0f64, 1.0f64);
    for c in coef.iter_mut() {
        for p in 0..ns {
            for q in 0..ns {
                let trig = match (p < 2, q < 2) {
                    (true, true) | (false, false) => cm,
                    (false, true) => sm,
                    (true, false) => -sm,
                };
                c[p * ns + q] += weight * f[p][q] * trig;
            }
        }
        (sm, cm) = (sm * c1 + cm * s1, cm * c1 - sm * s1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::RefractiveIndex;
    use crate::physics::microfacet::RoughSurface;

    /// `ρ^m` of one element by composite Gauss rules graded geometrically
    /// towards the edge (panels `[e − e/2^k, e − e/2^{k+1}]`, 50 levels,
    /// each cut to at most 0.02 rad, 16 nodes): the edge's square root is
    /// resolved without the split rules' substitution.
    fn reference(
        f: &Kernel<'_>,
        e: f64,
        mu_out: f64,
        mu_in: f64,
        m: usize,
        p: usize,
        q: usize,
    ) -> f64 {
        let trig = |d: f64| match (p < 2, q < 2) {
            (true, true) | (false, false) => (m as f64 * d).cos(),
            (false, true) => (m as f64 * d).sin(),
            (true, false) => -(m as f64 * d).sin(),
        };
        let mut sum = 0.0;
        for (len, dir) in [(e, -1.0), (PI - e, 1.0)] {
            for k in 0..50 {
                let (near, far) = (len / 2f64.powi(k + 1), len / 2f64.powi(k));
                let (near, far) = if k == 49 { (0.0, far) } else { (near, far) };
                let pieces = ((far - near) / 0.02).ceil().max(1.0) as usize;
                for j in 0..pieces {
                    let a = near + (far - near) * j as f64 / pieces as f64;
                    let b = near + (far - near) * (j + 1) as f64 / pieces as f64;
                    let (x, w) = gauss_legendre_on(16, a, b);
                    for (&t, &w) in x.iter().zip(&w) {
                        let d = e + dir * t;
                        sum += w * f(mu_out, mu_in, d)[p][q] * trig(d);
                    }
                }
            }
        }
        2.0 * mu_in * sum
    }

    /// Across a total-reflection edge (the binder side of a rough
    /// binder/air surface, `α = 0.3`) the split rules give the kept orders
    /// to the tolerance of an independent graded rule; the FFT, even at
    /// [`MAX_AZIMUTHS`], does not.
    #[test]
    fn split_rules_integrate_across_the_total_reflection_edge() {
        let below = RoughSurface::new(1.5, RefractiveIndex { n: 1.0, k: 0.0 }, 0.3).unwrap();
        let f = |mu_out: f64, mu_in: f64, d: f64| below.mueller(mu_out, mu_in, -d);
        let orders = 16;
        let mut planner = RealFftPlanner::new();
        for (mu_out, mu_in) in [(0.9, 0.2), (0.5, 0.5), (0.2, 0.3), (0.97, 0.1)] {
            let e = below.reflection_azimuth_edge(mu_out, mu_in).unwrap();
            let small = 2.0 * PI * AZIMUTH_TOLERANCE / mu_out;
            let split = pair_series(&f, Some(e), mu_out, mu_in, 4, orders, &mut planner);
            let fft = fft_series(&f, mu_out, mu_in, 4, orders, small, &mut planner);
            let (mut worst_split, mut worst_fft, mut most) = (0.0f64, 0.0f64, 0.0f64);
            for m in 0..orders {
                for p in 0..4 {
                    for q in 0..4 {
                        let want = reference(&f, e, mu_out, mu_in, m, p, q);
                        let got = |c: &[[f64; 16]]| c.get(m).map_or(0.0, |c| c[p * 4 + q]);
                        most = most.max(want.abs());
                        worst_split = worst_split.max((got(&split) - want).abs());
                        worst_fft = worst_fft.max((got(&fft) - want).abs());
                    }
                }
            }
            eprintln!(
                "({mu_out}, {mu_in}): edge {:.2}°, largest {most:.2e}, split off by {worst_split:.1e}, \
                 FFT by {worst_fft:.1e}; tolerance {small:.1e}",
                e.to_degrees()
            );
            assert!(worst_split <= small, "split {worst_split:e} > {small:e}");
            assert!(worst_fft > 10.0 * worst_split);
        }
    }
}
