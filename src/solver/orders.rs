//! Per-order setup: the discretisation grid, each layer's phase kernel and
//! operators, the base's operators, and the stack added together.

use super::layer::{
    DiffusionWatch, Kernel, Ops, TopOps, add, double_top, extrapolation_length, finish_top,
    thin_layer,
};
use super::phase::{Gsf, a_matrix};
use super::*;
use crate::physics::expansion::GreekCoefficients;
use crate::physics::quadrature::{double_gauss, split_gauss};
use crate::physics::stokes::Mueller;
use faer::Mat;

/// Directions of the discretisation.
pub(super) struct Grid {
    pub(super) ns: usize,
    pub(super) mu_q: Vec<f64>,
    pub(super) w_q: Vec<f64>,
    pub(super) mu_u: Vec<f64>,
    /// Where the ordinates are split ([`discrete_ordinates`]).
    pub(super) split: Option<f64>,
}

/// The discrete ordinates of one hemisphere: [`double_gauss`] of
/// `streams`, or with a split cosine (under a top interface, its critical
/// cosine) `streams` Gauss nodes on either side of it
/// ([`crate::physics::quadrature::split_gauss`]).
pub fn discrete_ordinates(streams: usize, split: Option<f64>) -> (Vec<f64>, Vec<f64>) {
    match split {
        Some(c) => split_gauss(streams, c),
        None => double_gauss(streams),
    }
}

/// Where the discrete ordinates of `problem` are split: the critical cosine
/// `√(1 − 1/n²)` of a top interface of index `n > 1` (internal directions
/// below it are totally reflected).
pub fn quadrature_split(problem: &Problem) -> Option<f64> {
    interface_split(problem.top_interface.as_ref())
}

/// [`quadrature_split`] of a top interface.
pub fn interface_split(interface: Option<&TopInterface>) -> Option<f64> {
    interface
        .filter(|i| i.index > 1.0)
        .map(|i| (1.0 - 1.0 / (i.index * i.index)).sqrt())
}

impl Grid {
    /// The double-Gauss streams of `settings` and the user cosines `mu_u`.
    pub(super) fn new(settings: &Settings, mu_u: &[f64]) -> Self {
        Self::split(settings, mu_u, None)
    }

    /// The discrete ordinates of `settings`, split at `split`
    /// ([`discrete_ordinates`]), and the user cosines `mu_u`.
    pub(super) fn split(settings: &Settings, mu_u: &[f64], split: Option<f64>) -> Self {
        let (mu_q, w_q) = discrete_ordinates(settings.streams, split);
        Self {
            ns: if settings.polarized { 4 } else { 1 },
            mu_q,
            w_q,
            mu_u: mu_u.to_vec(),
            split,
        }
    }
}

/// Phase kernel of one layer for order `m`.
///
/// With `full = false` only the blocks the top-only path reads are built
/// (the others are left empty): quadrature ← quadrature, user-up ←
/// quadrature, quadrature ← beam-down and user-up ← beam-down.
pub(super) fn kernel(
    grid: &Grid,
    coef: &GreekCoefficients,
    albedo: f64,
    m: usize,
    polarized: bool,
    full: bool,
) -> Kernel {
    let ns = grid.ns;
    let l_max = coef.beta.len().saturating_sub(1);
    let gsf = |mus: &[f64], sign: f64| -> Vec<Gsf> {
        mus.iter()
            .map(|&mu| Gsf::new(m, sign * mu, l_max, polarized))
            .collect()
    };
    // Index 0 = upward (+μ), 1 = downward (−μ).
    let gq = [gsf(&grid.mu_q, 1.0), gsf(&grid.mu_q, -1.0)];
    let gu = [gsf(&grid.mu_u, 1.0), gsf(&grid.mu_u, -1.0)];
    let block = |out: &[Gsf], inp: &[Gsf], w: Option<&[f64]>| -> Mat<f64> {
        let mut mat = Mat::zeros(out.len() * ns, inp.len() * ns);
        for (i, go) in out.iter().enumerate() {
            for (j, gi) in inp.iter().enumerate() {
                let a = a_matrix(coef, m, go, gi, polarized);
                let f = 0.5 * albedo * w.map_or(1.0, |w| w[j]);
                for p in 0..ns {
                    for q in 0..ns {
                        mat[(i * ns + p, j * ns + q)] = f * a[p][q];
                    }
                }
            }
        }
        mat
    };
    let wq = Some(grid.w_q.as_slice());
    // `need(s, t)`: is block (output direction s, input direction t) read?
    let b4 = |out: &[Vec<Gsf>; 2],
              inp: &[Vec<Gsf>; 2],
              w: Option<&[f64]>,
              need: &dyn Fn(usize, usize) -> bool|
     -> [[Mat<f64>; 2]; 2] {
        std::array::from_fn(|s| {
            std::array::from_fn(|t| {
                if full || need(s, t) {
                    block(&out[s], &inp[t], w)
                } else {
                    Mat::zeros(0, 0)
                }
            })
        })
    };
    const UP: usize = 0;
    const DN: usize = 1;
    Kernel {
        qq: b4(&gq, &gq, wq, &|_, _| true),
        uq: b4(&gu, &gq, wq, &|s, _| s == UP),
        qb: b4(&gq, &gu, None, &|_, t| t == DN),
        ub: b4(&gu, &gu, None, &|s, t| s == UP && t == DN),
    }
}

/// Operators of one homogeneous layer for one order: thin start + doubling.
/// `full = false` carries only what the response at the top needs
/// ([`layer::double_top`], [`layer::finish_top`]); `full = true` carries every
/// block (internal fields, mirror bases).
pub(super) fn layer_ops(
    grid: &Grid,
    layer: &Layer,
    m: usize,
    settings: &Settings,
    full: bool,
) -> Ops {
    let ns = grid.ns;
    let n = grid.mu_q.len() * ns;
    let nu = grid.mu_u.len() * ns;
    let k = kernel(grid, &layer.coef, layer.albedo, m, settings.polarized, full);
    let d_max = settings.start_factor * grid.mu_q[0];
    let (start, doublings, tau) = match layer.thickness {
        Thickness::Finite(tau) => {
            if tau <= 0.0 {
                return Ops::vacuum(n, nu, ns);
            }
            let mut doublings = 0u32;
            let mut delta = tau;
            while delta > d_max && doublings < 200 {
                delta *= 0.5;
                doublings += 1;
            }
            (delta, Some(doublings), tau)
        }
        Thickness::Infinite => (d_max, None, f64::INFINITY),
    };
    // Start layer: thin layers of δ, δ/2 and δ/4 by the diamond scheme,
    // doubled to δ and Richardson extrapolated twice (`layer::richardson`):
    // the diamond scheme's error is even in δ, so
    // A = (4 L_{δ/2} − L_δ)/3 cancels δ² and (16 A_{δ/2} − A_δ)/15 cancels δ⁴.
    // Every term conserves flux exactly, hence so does the combination.
    let thin = |d: f64| thin_layer(&k, &grid.mu_q, &grid.mu_u, ns, d, full);
    let (coarse, half, quarter) = (thin(start), thin(0.5 * start), thin(0.25 * start));
    // A conservative layer (ω = 1, order 0) has a diffusion regime: once in
    // it, thick and semi-infinite layers follow in closed form
    // (`layer::DiffusionWatch`) instead of doubling on and accumulating
    // round-off. Every other layer's transmission decays exponentially.
    let conservative = m == 0 && layer.albedo == 1.0;
    let direct = |tau: Option<f64>| -> Vec<f64> {
        grid.mu_u
            .iter()
            .map(|&mu| tau.map_or(0.0, |t| (-t / mu).exp()))
            .collect()
    };
    // Semi-infinite: double until nothing is transmitted.
    let done = |t: &Mat<f64>, steps: u32, thick: f64| match doublings {
        Some(d) => steps >= d,
        None => steps >= 200 || (thick > 1.0 && layer::max_abs(t.as_ref()) < 1e-15),
    };
    let mut ops = if full {
        let double = |o: &Ops| add(o, o, true);
        let a = layer::richardson(&double(&half), &coarse, 2);
        let a_half = layer::richardson(&double(&quarter), &half, 2);
        let mut ops = layer::richardson(&double(&a_half), &a, 4);
        let (mut steps, mut thick) = (0u32, start);
        let mut watch = conservative.then(DiffusionWatch::default);
        while !done(&ops.t, steps, thick) {
            ops = add(&ops, &ops, true);
            steps += 1;
            thick *= 2.0;
            let Some(w) = watch.as_mut() else { continue };
            if !w.asymptotic(thick, &ops.r, &ops.t, ns) {
                continue;
            }
            // Diffusion regime (`layer::DiffusionWatch`): continue from here.
            match doublings {
                None => return ops.diffusion_continuation(thick, 0.0, None, direct(None)),
                Some(d) if steps + 1 < d => {
                    let next = add(&ops, &ops, true);
                    let b = extrapolation_length(thick, &ops.t, &next.t, &grid.mu_q, &grid.w_q, ns);
                    return ops.diffusion_continuation(thick, b, Some(tau), direct(Some(tau)));
                }
                Some(_) => watch = None,
            }
        }
        ops
    } else {
        let [c, h, q] = [&coarse, &half, &quarter].map(TopOps::from_ops);
        let double = |o: &TopOps| double_top(o, ns);
        let a = layer::richardson_top(&double(&h), &c, 2);
        let a_half = layer::richardson_top(&double(&q), &h, 2);
        let mut top = layer::richardson_top(&double(&a_half), &a, 4);
        let (mut steps, mut thick) = (0u32, start);
        let mut watch = conservative.then(DiffusionWatch::default);
        while !done(&top.t, steps, thick) {
            top = double_top(&top, ns);
            steps += 1;
            thick *= 2.0;
            let Some(w) = watch.as_mut() else { continue };
            if !w.asymptotic(thick, &top.r, &top.t, ns) {
                continue;
            }
            // Diffusion regime (`layer::DiffusionWatch`): continue from here.
            match doublings {
                None => {
                    top = top.diffusion_continuation(thick, 0.0, None, direct(None), ns);
                    break;
                }
                Some(d) if steps + 1 < d => {
                    let next = double_top(&top, ns);
                    let b = extrapolation_length(thick, &top.t, &next.t, &grid.mu_q, &grid.w_q, ns);
                    top = top.diffusion_continuation(thick, b, Some(tau), direct(Some(tau)), ns);
                    break;
                }
                Some(_) => watch = None,
            }
        }
        if tau.is_infinite() {
            top.t.fill(0.0);
            top.tus.fill(0.0);
            top.eu.iter_mut().for_each(|e| *e = 0.0);
        }
        finish_top(&top, &k, &grid.mu_q, &grid.w_q, &grid.mu_u, ns, tau)
    };
    if tau.is_infinite() {
        // A semi-infinite layer transmits nothing.
        for b in [
            &mut ops.t,
            &mut ops.ts,
            &mut ops.tb,
            &mut ops.tbs,
            &mut ops.tu,
            &mut ops.tus,
            &mut ops.tuu,
            &mut ops.tuus,
        ] {
            b.fill(0.0);
        }
        ops.eu.iter_mut().for_each(|e| *e = 0.0);
    }
    ops
}

/// Operators of a Lambertian base for order `m` (only `m = 0` reflects):
/// `I_up = (a/π) ∫ I_down μ' dΩ' = 2a Σ_j w_j μ_j x_j` on the I component.
pub(super) fn lambertian_ops(grid: &Grid, albedo: f64, m: usize) -> Ops {
    let ns = grid.ns;
    let n = grid.mu_q.len() * ns;
    let nu = grid.mu_u.len() * ns;
    let mut o = Ops::reflector(n, nu, ns);
    if m != 0 {
        return o;
    }
    for i in 0..grid.mu_q.len() {
        for (j, (&mu, &w)) in grid.mu_q.iter().zip(&grid.w_q).enumerate() {
            o.r[(i * ns, j * ns)] = 2.0 * albedo * w * mu;
        }
        for (v, &mv) in grid.mu_u.iter().enumerate() {
            o.rb[(i * ns, v * ns)] = 2.0 * albedo * mv;
        }
    }
    for u in 0..grid.mu_u.len() {
        for (j, (&mu, &w)) in grid.mu_q.iter().zip(&grid.w_q).enumerate() {
            o.ru[(u * ns, j * ns)] = 2.0 * albedo * w * mu;
        }
        for (v, &mv) in grid.mu_u.iter().enumerate() {
            o.ruu[(u * ns, v * ns)] = 2.0 * albedo * mv;
        }
    }
    o
}

/// Block-diagonal matrix of 4×4 (or 1×1) specular maps for the cosines `mus`.
pub(super) fn mirror_blocks(mus: &[f64], ns: usize, mueller: &dyn Fn(f64) -> Mueller) -> Mat<f64> {
    let mut m = Mat::zeros(mus.len() * ns, mus.len() * ns);
    for (i, &mu) in mus.iter().enumerate() {
        let f = mueller(mu);
        for p in 0..ns {
            for q in 0..ns {
                m[(i * ns + p, i * ns + q)] = f[p][q];
            }
        }
    }
    m
}

/// Highest order any layer's phase matrix carries (a rough base's orders
/// come on top: [`rough_base::RoughProjection::order_count`]).
pub(super) fn order_count(problem: &Problem) -> usize {
    capped_orders(problem, layer_orders(problem))
}

/// Orders any layer's phase matrix reaches, whatever the settings.
pub(super) fn layer_orders(problem: &Problem) -> usize {
    problem
        .layers
        .iter()
        .map(|l| l.coef.beta.len())
        .max()
        .unwrap_or(1)
}

/// `orders` capped by [`Settings::max_order`], at least one.
pub(super) fn capped_orders(problem: &Problem, orders: usize) -> usize {
    let m = problem
        .settings
        .max_order
        .map_or(orders, |mo| (mo + 1).min(orders));
    m.max(1)
}

/// `(semi_infinite, full)`: whether the bottom layer is semi-infinite, and
/// whether the adding needs every block (a mirror base: light reflected up
/// by the mirror scatters in the stack from below; under a semi-infinite
/// layer the base is irrelevant).
pub(super) fn base_coupling(problem: &Problem) -> (bool, bool) {
    let semi_infinite = matches!(
        problem.layers.last().map(|l| l.thickness),
        Some(Thickness::Infinite)
    );
    let full = matches!(problem.base, Base::Mirror { .. }) && !semi_infinite;
    (semi_infinite, full)
}

/// The operators of the whole stack (base excluded) for Fourier order `m`,
/// layers of thickness 0 skipped, vacuum for an empty stack.
///
/// In an order no layer's phase matrix reaches (only a rough base reflects
/// there) the stack only attenuates, in closed form ([`Ops::attenuator`]).
pub(super) fn stack_ops(problem: &Problem, grid: &Grid, m: usize, full: bool) -> Ops {
    if m >= layer_orders(problem) {
        let tau: f64 = problem.layers.iter().map(|l| l.thickness.value()).sum();
        return Ops::attenuator(tau, &grid.mu_q, &grid.mu_u, grid.ns);
    }
    let mut stack: Option<Ops> = None;
    for layer in &problem.layers {
        if matches!(layer.thickness, Thickness::Finite(t) if t <= 0.0) {
            continue;
        }
        let ops = layer_ops(grid, layer, m, &problem.settings, full);
        stack = Some(match stack {
            None => ops,
            Some(top) => add(&top, &ops, full),
        });
    }
    let ns = grid.ns;
    stack.unwrap_or_else(|| Ops::vacuum(grid.mu_q.len() * ns, grid.mu_u.len() * ns, ns))
}
