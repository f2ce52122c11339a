//! Secondary-scattering correction of delta-M truncated layers: the
//! double-scattering BRDF of the exact phase matrices minus that of the
//! truncated ones, both in the δ-scaled medium, at user angles, for the full
//! 4×4 Mueller matrix.
//!
//! **Why.** Delta-M ([`super::truncation`]) replaces the phase matrix `P`
//! of a layer by `(1 − f) P' + f δ` (`P'`: the first `2N` terms, `δ`: a
//! forward delta) and the TMS term makes *single* scattering exact. In the
//! scaled medium (`τ' = (1 − ωf) τ`) the forward delta is unscattered light,
//! and the exact kernel is `ω̂ (P − f δ) = ω' P' + ω̂ R` with `ω̂ = ω/(1 − ωf)`,
//! `ω' = (1 − f) ω̂` and `R = P − (1 − f) P' − f δ` the residual: the part of
//! the forward peak finer than the quadrature resolves, the backscatter glory
//! and the ripple beyond `l = 2N − 1`. Paths with two scatterings of which at
//! least one is an `R` scattering are missing from the truncated solution:
//! measured for a Mie sphere with x = 100 (≈ 230 terms) at 32 streams they
//! are the whole 10 % error at the grazing forward pair and the 3 % at
//! backscatter that remained after the TMS correction. This is the idea of
//! Nakajima & Tanaka's (1988, JQSRT 40, 51, §3.2) IMS method; they
//! approximate the geometry so that the angular integral becomes a Legendre
//! convolution and DISORT applies it to transmitted aureole intensities
//! only. Here the geometry is exact, which matters at grazing angles (a 2°
//! deflection changes μ by a factor of 3 at 86°).
//!
//! **Equations.** Per Fourier order `m`, for the response to a unit delta in
//! `μ` (conventions §7; the Fourier sum and `1/μ0` give the BRDF), a beam
//! down at `μ0`, first scattering in layer `j` into the intermediate cosine
//! `ν` (either sign), second in layer `k` up into `μ`:
//!
//! `ρ₂^m(μ, μ0) = ¼ Σ_{j,k} ∫_{−1}^{1} A_k^m(μ, ν) A_j^m(ν, −μ0) G_{jk}(μ0, ν, μ) dν`
//!
//! with `A^m(ν, ν') = Σ_l P_l^m(ν) B_l P_l^m(ν')` (seed eq. 21, the kernel of
//! [`super::phase`], albedo included) and the slab geometry
//! `G = ∫∫ (dt₂/μ) e^{−t₂/μ} (dt₁/|ν|) e^{−t₁/μ0} e^{−|t₂ − t₁|/|ν|}` over
//! `t₁` in layer `j`, `t₂` in layer `k` (scaled depths, `t₁ < t₂` for `ν < 0`,
//! `t₁ > t₂` for `ν > 0`); within one layer of scaled thickness `T` with top
//! at `A`, `a = 1/μ0`, `b = 1/μ`, `c = 1/|ν|`, `E(s) = (1 − e^{−sT})/s`:
//!
//! `G↓ = bc e^{−(a+b)A} (E(a+b) − E(b+c))/(c − a)`,
//! `G↑ = bc e^{−(a+b)A} (E(a+b) − (e^{−(a+b)T} − e^{−(a+c)T})/(c − b))/(a + c)`
//!
//! (between layers the two depth integrals separate). The correction is this
//! double scattering with the exact kernel `ω̂ (P − f δ)` minus the double
//! scattering the discrete-ordinate solve of the truncated problem contains:
//! the same integral with `ω' P'`, its `ν` integral on the solve's own
//! `N`-point double-Gauss quadrature (the user-angle radiance is the exact
//! depth integral of a source built on the quadrature). So the corrected
//! BRDF carries the exact double scattering of the original layer, as the
//! TMS term makes single scattering exact (a thin layer: 1.3e-3 of the
//! double scattering instead of 0.61 at 3 streams, `truncation::tests`),
//! which also removes the quadrature error of the truncated problem's double
//! scattering (TiO2 at 4 streams, 14 terms cut to 8: max error 2.0e-3 →
//! 2.5e-4 of max f11; subtracting the exactly integrated `ω' P'` instead
//! gave 2.1e-3). The forward delta has the kernel `2 f D_g δ(ν − ν')`
//! (`D_g = diag(1, f₂₃/f, f₂₃/f, f₄/f)`, the forward polarization of
//! [`super::truncation`]); it cannot turn light upwards, so its terms are the
//! paths "δ then `P`" (`ν = −μ0`) and "`P` then δ" (`ν = μ`), in closed form:
//!
//! `Δρ^m = ¼ Σ_{jk} [ω̂_k ω̂_j ∫ A_{P,k} G A_{P,j} − ω'_k ω'_j Σ_N A_{P',k} G A_{P',j}]
//!        − ½ Σ_{jk} ω̂_j ω̂_k [f_j A_{P,k}(μ, −μ0) D_{g,j} G_{jk}(ν = −μ0)
//!                            + f_k D_{g,k} A_{P,j}(μ, −μ0) G_{jk}(ν = μ)]`.
//!
//! For a layer that is not truncated `ω̂ = ω' = ω`, `P' = P`, `f = 0`: its
//! terms (and pairs of such layers) are left out. The exact `ν` integral is
//! a Gauss rule with as many nodes per hemisphere as the longest series has
//! terms: the product of the two kernels is a polynomial of degree `2L` in
//! `ν` on each hemisphere, which that rule integrates exactly, and `G` is
//! smooth on each (measured for the x = 100 sphere, 225 terms: 100 nodes
//! leave 1.5e-3 of max f11, 150 nodes 3.5e-9); for layers thinner than 0.1
//! the rule is repeated on panels graded towards the horizon
//! ([`graded_gauss`]). `A(ν, −μ0)` follows from the table of `A(μ, ±ν)` by
//! the mirror and reciprocity symmetries of the kernel,
//! `A(ν, −μ0) = Δ A(μ0, −ν)ᵀ Δ`, `Δ = diag(1, 1, −1, 1)`.
//!
//! **Cost.** Per Fourier order of the full series, kernel tables on the
//! `ν` nodes (matrix products over `l`) and a contraction over `ν` for every
//! pair of user cosines: `O(L³ n_u)` and `O(L² n_u² · 64)` in all, independent
//! of the streams (x = 100, 11 user cosines: about 1.5 s on 2 cores). The
//! contraction is done for incident cosines `μ_v ≥ μ_u` only; the other
//! half follows from reciprocity ([`Contraction`]).
//!
//! Only paths inside the stack are corrected: over a mirror base the double
//! scattering that reflects at the base is not (the TMS term corrects the
//! mirror paths of single scattering), nor are paths via a Lambertian base
//! (it sees the azimuthal average, where the residual integrates to zero).

mod geometry;

use super::layer::mm;
use super::phase::Gsf;
use crate::physics::expansion::GreekCoefficients;
use faer::Mat;
use geometry::Nodes;
pub(crate) use geometry::{geometry, graded_gauss};
use rayon::prelude::*;

/// One layer as the secondary correction sees it, in scaled depths.
#[derive(Clone, Debug)]
pub(crate) struct ScaledLayer {
    /// Scaled depth of the top.
    pub top: f64,
    /// Scaled thickness (infinite for a semi-infinite layer).
    pub thickness: f64,
    /// The exact phase-matrix coefficients `P`.
    pub full: GreekCoefficients,
    /// `ω/(1 − ωf)`.
    pub omega_full: f64,
    /// The truncated coefficients `P'` (`= P` when not truncated).
    pub trunc: GreekCoefficients,
    /// `ω' = (1 − f) ω/(1 − ωf)`.
    pub omega_trunc: f64,
    /// The removed forward fraction per diagonal element
    /// `(f, f₂₃, f₂₃, f₄)`, zero when not truncated.
    pub fx: [f64; 4],
}

impl ScaledLayer {
    fn truncated(&self) -> bool {
        self.fx[0] > 0.0 || self.trunc != self.full || self.omega_trunc != self.omega_full
    }
}

/// The kernel `A^m(ν_i, ν'_j)` ([`super::phase::a_matrix`]) for every pair of
/// a left and a right list of directions, by matrix products over `l`: the
/// 16 elements, each `left × right`, in `out[4 p + q]` (scalar: `out[0]`).
/// `right[j] = (gsf, flip)`: with `flip` the direction is `−ν` (the parity
/// `d^l_{m,n}(−ν) = (−1)^{l+m} d^l_{m,−n}(ν)`).
fn a_table(
    coef: &GreekCoefficients,
    m: usize,
    left: &[Gsf],
    right: &[(&Gsf, bool)],
    polarized: bool,
) -> Vec<Mat<f64>> {
    let (nl, nr) = (left.len(), right.len());
    let len = coef.beta.len();
    let mut out: Vec<Mat<f64>> = (0..if polarized { 16 } else { 1 })
        .map(|_| Mat::zeros(nl, nr))
        .collect();
    if m >= len || nl == 0 || nr == 0 {
        return out;
    }
    let lm = len - m;
    let parity = |l: usize| if (l + m).is_multiple_of(2) { 1.0 } else { -1.0 };
    // Right factors: columns of the direction functions over l = m..len.
    let right_mat = |which: usize| -> Mat<f64> {
        Mat::from_fn(lm, nr, |i, j| {
            let l = m + i;
            let (g, flip) = right[j];
            let (v, odd) = match which {
                0 => (g.p[l], false),
                1 => (g.r[l], false),
                _ => (g.t[l], true),
            };
            if flip {
                let s = parity(l);
                if odd { -s * v } else { s * v }
            } else {
                v
            }
        })
    };
    let left_fn = |which: usize, u: usize, l: usize| -> f64 {
        let g = &left[u];
        match which {
            0 => g.p[l],
            1 => g.r[l],
            _ => g.t[l],
        }
    };
    if !polarized {
        let lmat = Mat::from_fn(nl, lm, |u, i| left_fn(0, u, m + i) * coef.beta[m + i]);
        out[0] = mm(lmat.as_ref(), right_mat(0).as_ref());
        return out;
    }
    const P: usize = 0;
    const R: usize = 1;
    const T: usize = 2;
    let c = [
        &coef.beta,
        &coef.gamma,
        &coef.epsilon,
        &coef.delta,
        &coef.alpha,
        &coef.zeta,
    ];
    let (be, ga, ep, de, al, ze) = (0, 1, 2, 3, 4, 5);
    // Left factors x_l(ν) c_l, stacked by combination.
    let stack = |combos: &[(usize, usize)]| -> Mat<f64> {
        Mat::from_fn(combos.len() * nl, lm, |row, i| {
            let (x, s) = combos[row / nl];
            left_fn(x, row % nl, m + i) * c[s][m + i]
        })
    };
    let with_q = [(P, be), (R, ga), (T, ep), (T, ga), (R, ep), (P, de)];
    let with_su = [(P, ga), (R, al), (T, ze), (T, al), (R, ze), (P, ep)];
    let pq = mm(stack(&with_q).as_ref(), right_mat(P).as_ref());
    let ls = stack(&with_su);
    let ps = mm(ls.as_ref(), right_mat(R).as_ref());
    let pu = mm(ls.as_ref(), right_mat(T).as_ref());
    let blk = |mat: &Mat<f64>, k: usize, i: usize, j: usize| mat[(k * nl + i, j)];
    for i in 0..nl {
        for j in 0..nr {
            let set = |o: &mut Vec<Mat<f64>>, e: usize, v: f64| o[e][(i, j)] = v;
            set(&mut out, 0, blk(&pq, 0, i, j));
            set(&mut out, 4, blk(&pq, 1, i, j));
            set(&mut out, 7, blk(&pq, 2, i, j));
            set(&mut out, 8, -blk(&pq, 3, i, j));
            set(&mut out, 11, -blk(&pq, 4, i, j));
            set(&mut out, 15, blk(&pq, 5, i, j));
            set(&mut out, 1, blk(&ps, 0, i, j));
            set(&mut out, 2, -blk(&pu, 0, i, j));
            set(&mut out, 5, blk(&ps, 1, i, j) + blk(&pu, 2, i, j));
            set(&mut out, 6, -(blk(&pu, 1, i, j) + blk(&ps, 2, i, j)));
            set(&mut out, 9, -(blk(&ps, 3, i, j) + blk(&pu, 4, i, j)));
            set(&mut out, 10, blk(&pu, 3, i, j) + blk(&ps, 4, i, j));
            set(&mut out, 13, -blk(&pu, 5, i, j));
            set(&mut out, 14, blk(&ps, 5, i, j));
        }
    }
    out
}

/// `out[i][l] += Σ_q w_q x_i(q) y_l(q)` for four rows `x` and four rows
/// `y` at once (one pass over `q`, 16 accumulators of 8 lanes; the scalar
/// solve uses the first row and column only). Inlined into the
/// [`pulp::Arch::dispatch`] of [`secondary`], so that it is compiled for the
/// CPU's vector extensions.
#[inline(always)]
fn block4x4(out: &mut [[f64; 4]; 4], w: &[f64], x: [&[f64]; 4], y: [&[f64]; 4], ns: usize) {
    if ns == 1 {
        out[0][0] += w
            .iter()
            .zip(x[0])
            .zip(y[0])
            .map(|((a, b), c)| a * b * c)
            .sum::<f64>();
        return;
    }
    const LANES: usize = 8;
    let n = w.len() / LANES * LANES;
    let mut acc = [[[0.0f64; LANES]; 4]; 4];
    for q0 in (0..n).step_by(LANES) {
        let wq: [f64; LANES] = w[q0..q0 + LANES].try_into().unwrap();
        let xs: [[f64; LANES]; 4] =
            std::array::from_fn(|i| x[i][q0..q0 + LANES].try_into().unwrap());
        let ys: [[f64; LANES]; 4] =
            std::array::from_fn(|i| y[i][q0..q0 + LANES].try_into().unwrap());
        for i in 0..4 {
            let mut wx = [0.0f64; LANES];
            for s in 0..LANES {
                wx[s] = wq[s] * xs[i][s];
            }
            for l in 0..4 {
                for s in 0..LANES {
                    acc[i][l][s] += wx[s] * ys[l][s];
                }
            }
        }
    }
    for i in 0..4 {
        for l in 0..4 {
            let mut sum = acc[i][l].iter().sum::<f64>();
            for q in n..w.len() {
                sum += w[q] * x[i][q] * y[l][q];
            }
            out[i][l] += sum;
        }
    }
}

/// Terms beyond which every series is negligible: `|x_l|/(2l + 1) ≤`
/// [`SERIES_TOLERANCE`] for all six (β₀ = 1). The double scattering of the
/// dropped tail is of that relative size.
pub const SERIES_TOLERANCE: f64 = 1e-8;

/// Longest (significant) series the correction is computed for: its cost
/// grows like `L³` (x = 100, 215 terms: about 1.5 s for 11 user cosines);
/// longer series (HG with g ≳ 0.96, Mie spheres with x ≳ 180) get the TMS
/// single-scattering correction only.
pub const MAX_TERMS: usize = 400;

fn significant_terms(c: &GreekCoefficients) -> usize {
    let big = |l: usize| {
        c.series()
            .iter()
            .any(|x| x[l].abs() > SERIES_TOLERANCE * (2 * l + 1) as f64)
    };
    (0..c.len()).rev().find(|&l| big(l)).map_or(1, |l| l + 1)
}

/// Kernel tables `A(μ_u, ν_q)` of one coefficient set on one node set in
/// SoA layout `t[(u ne + e) nq + q]`, and the copy with `ν_q → −ν_q` (the
/// first scattering, via `A(ν, −μ0) = Δ A(μ0, −ν)ᵀ Δ`).
fn kernel_tables(
    coef: &GreekCoefficients,
    m: usize,
    users: &[Gsf],
    nodes: &Nodes,
    gsf: &[Gsf],
    polarized: bool,
) -> (Vec<f64>, Vec<f64>) {
    let nq = nodes.nq();
    let k = nodes.k;
    let right: Vec<(&Gsf, bool)> = (0..nq).map(|q| (&gsf[q % k], q >= k)).collect();
    let tab = a_table(coef, m, users, &right, polarized);
    let nu = users.len();
    let ne = tab.len();
    let mut t = vec![0.0; nu * ne * nq];
    let mut tf = vec![0.0; nu * ne * nq];
    for u in 0..nu {
        for (e, mat) in tab.iter().enumerate() {
            let base = (u * ne + e) * nq;
            for q in 0..nq {
                t[base + q] = mat[(u, q)];
                tf[base + q] = mat[(u, (q + k) % nq)];
            }
        }
    }
    (t, tf)
}

/// `Σ_q W_q T_k[u](q) Δ T_j[v](−ν_q)ᵀ Δ`: element `(i, l)` is
/// `Δ_l Σ_jj Δ_jj Σ_q W_q T_k[u][i][jj](q) T_j[v][l][jj](q̄)`.
#[inline(always)]
fn contract(
    second: &[f64],
    first_flipped: &[f64],
    wts: &[f64],
    u: usize,
    v: usize,
    ns: usize,
) -> [[f64; 4]; 4] {
    let nq = wts.len();
    let ne = ns * ns;
    let delta = [1.0, 1.0, -1.0, 1.0];
    let sign = |e: usize| if ns == 4 { delta[e] } else { 1.0 };
    let rows = |d: usize, jj: usize| -> [std::ops::Range<usize>; 4] {
        std::array::from_fn(|i| {
            let o = (d * ne + i.min(ns - 1) * ns + jj) * nq;
            o..o + nq
        })
    };
    let mut out = [[0.0; 4]; 4];
    for jj in 0..ns {
        let (rs, rf) = (rows(u, jj), rows(v, jj));
        let mut part = [[0.0; 4]; 4];
        block4x4(
            &mut part,
            wts,
            std::array::from_fn(|i| &second[rs[i].clone()]),
            std::array::from_fn(|i| &first_flipped[rf[i].clone()]),
            ns,
        );
        for i in 0..ns {
            for l in 0..ns {
                out[i][l] += sign(jj) * sign(l) * part[i][l];
            }
        }
    }
    out
}

/// Kernel tables of one layer on one node set (`kernel_tables`).
type Tables = (Vec<f64>, Vec<f64>);

/// Step 3 of [`secondary`] for one Fourier order: the contraction over `ν`,
/// exact minus truncated, and the δ paths. A [`pulp::WithSimd`] operation
/// so that [`pulp::Arch::dispatch`] compiles it (and the inlined
/// [`contract`] and [`block4x4`]) for the CPU's vector extensions; a
/// closure passed to `dispatch` is not inlined there and ran as SSE2 code
/// (`perf`: 74 % of a Mie x = 100 table in it).
struct Contraction<'a> {
    mu: &'a [f64],
    pairs: &'a [(usize, usize)],
    active: &'a [&'a ScaledLayer],
    tables: &'a [(Tables, Option<Tables>)],
    user_a: &'a [Vec<Mat<f64>>],
    delta_geometry: &'a [(Vec<f64>, Vec<f64>)],
    exact: &'a Nodes,
    trunc_nodes: &'a Nodes,
    nu: usize,
    ns: usize,
    out: &'a mut Mat<f64>,
}

impl pulp::WithSimd for Contraction<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let Contraction {
            mu,
            pairs,
            active,
            tables,
            user_a,
            delta_geometry,
            exact,
            trunc_nodes,
            nu,
            ns,
            out,
        } = self;
        for (p, &(j, k)) in pairs.iter().enumerate() {
            let (lj, lk) = (active[j], active[k]);
            let (fj, tj) = &tables[j];
            let (fk, tk) = &tables[k];
            let w_full = 0.25 * lk.omega_full * lj.omega_full;
            let w_trunc = 0.25 * lk.omega_trunc * lj.omega_trunc;
            let wd = 0.5 * lj.omega_full * lk.omega_full;
            let (g_down, g_up) = &delta_geometry[p];
            let (we, wt) = (&exact.weights[p], &trunc_nodes.weights[p]);
            let (nqe, nqt) = (exact.nq(), trunc_nodes.nq());
            // Incident cosines v ≥ u only; the rest follows by reciprocity
            // (below).
            for u in 0..nu {
                for v in u..nu {
                    let uv = u * nu + v;
                    let full = contract(&fk.0, &fj.1, &we[uv * nqe..(uv + 1) * nqe], u, v, ns);
                    let trunc = match (tj, tk) {
                        (Some(tj), Some(tk)) => {
                            contract(&tk.0, &tj.1, &wt[uv * nqt..(uv + 1) * nqt], u, v, ns)
                        }
                        _ => [[0.0; 4]; 4],
                    };
                    // δ then P (first scattering a forward delta in
                    // j), P then δ (second a forward delta in k).
                    let (gd, gu) = (g_down[uv], g_up[uv]);
                    for i in 0..ns {
                        for l in 0..ns {
                            let ak = user_a[k][i * ns + l][(u, v)];
                            let aj = user_a[j][i * ns + l][(u, v)];
                            out[(u * ns + i, v * ns + l)] += w_full * full[i][l]
                                - w_trunc * trunc[i][l]
                                - wd * (ak * lj.fx[l] * gd + lk.fx[i] * aj * gu);
                        }
                    }
                }
            }
        }
        // Reciprocity of the double scattering (all layer pairs summed):
        // `ρ(μ_u, μ_v)_{il} = (μ_v/μ_u) Δ_i ρ(μ_v, μ_u)_{li} Δ_l`,
        // `Δ = diag(1, 1, −1, 1)` (BRDF `ρ/μ0` reciprocal, conventions §7;
        // exact for the exact part, the quadrature part and the δ paths
        // alike: 7e-17 of the largest element, measured before this half
        // was left out).
        let delta = [1.0, 1.0, -1.0, 1.0];
        for u in 0..nu {
            for v in 0..u {
                let ratio = mu[v] / mu[u];
                for i in 0..ns {
                    for l in 0..ns {
                        out[(u * ns + i, v * ns + l)] =
                            ratio * delta[i] * delta[l] * out[(v * ns + l, u * ns + i)];
                    }
                }
            }
        }
    }
}

/// The secondary-scattering correction `Δρ^m` (module docs) for every
/// Fourier order of the longest series, at the user cosines `mu` (rows:
/// outgoing direction × Stokes, columns: incident direction × Stokes, the
/// layout of [`super::ReflectionFourier::rho`]). Empty when no layer is
/// truncated.
///
/// With `discrete = Some(nodes, weights)` (the solve's discrete ordinates
/// of one hemisphere, [`super::discrete_ordinates`]) the truncated double
/// scattering is the one the discrete-ordinate solve itself contains (its
/// `ν` integral on that quadrature), so that the corrected solution carries the exact
/// double scattering whatever the quadrature; with `None` it is integrated
/// exactly.
pub(crate) fn secondary(
    layers: &[ScaledLayer],
    mu: &[f64],
    polarized: bool,
    discrete: Option<(Vec<f64>, Vec<f64>)>,
    max_order: Option<usize>,
) -> Vec<Mat<f64>> {
    let trimmed: Vec<ScaledLayer> = layers
        .iter()
        .filter(|l| l.thickness > 0.0 && l.omega_full > 0.0)
        .map(|l| {
            // Never shorter than the truncated series (the kernels of both
            // are tabulated to the same length).
            let keep = significant_terms(&l.full).max(l.trunc.len());
            let full = l.full.truncated(keep.saturating_sub(1));
            let trunc = if l.truncated() {
                l.trunc.clone()
            } else {
                full.clone()
            };
            ScaledLayer {
                full,
                trunc,
                ..l.clone()
            }
        })
        .collect();
    let active: Vec<&ScaledLayer> = trimmed.iter().collect();
    if !active.iter().any(|l| l.truncated()) || mu.is_empty() {
        return Vec::new();
    }
    let ns = if polarized { 4 } else { 1 };
    let nu = mu.len();
    let terms = active.iter().map(|l| l.full.beta.len()).max().unwrap_or(1);
    if terms > MAX_TERMS {
        return Vec::new();
    }
    let l_max = terms - 1;
    let orders = max_order.map_or(terms, |m| (m + 1).min(terms));
    // Step 1: layer pairs (j first, k second) with a truncated layer, and
    // the ν quadratures with their geometry weights: `terms` nodes per
    // hemisphere for the exact kernels (exact for the polynomial part), the
    // solver's own for the truncated ones.
    let bounds: Vec<(f64, f64)> = active.iter().map(|l| (l.top, l.thickness)).collect();
    let nl = active.len();
    let pairs: Vec<(usize, usize)> = (0..nl)
        .flat_map(|j| (0..nl).map(move |k| (j, k)))
        .filter(|&(j, k)| active[j].truncated() || active[k].truncated())
        .collect();
    let tau_min = active
        .iter()
        .map(|l| l.thickness)
        .fold(f64::INFINITY, f64::min);
    let exact = Nodes::new(graded_gauss(terms.max(8), tau_min), mu, &pairs, &bounds);
    let discrete = discrete.map(|q| Nodes::new(q, mu, &pairs, &bounds));
    let trunc_nodes = discrete.as_ref().unwrap_or(&exact);
    // The δ-path geometries G_{jk}(ν = −μ0) and G_{jk}(ν = μ).
    let delta_geometry: Vec<(Vec<f64>, Vec<f64>)> = pairs
        .iter()
        .map(|&(j, k)| {
            let mut down = vec![0.0; nu * nu];
            let mut up = vec![0.0; nu * nu];
            for u in 0..nu {
                for v in u..nu {
                    let (a, b) = (1.0 / mu[v], 1.0 / mu[u]);
                    down[u * nu + v] = geometry(a, b, a, false, bounds[j], bounds[k]);
                    up[u * nu + v] = geometry(a, b, b, true, bounds[j], bounds[k]);
                }
            }
            (down, up)
        })
        .collect();
    (0..orders)
        .into_par_iter()
        .map(|m| {
            // Step 2: the kernels A(μ_u, ±ν_q) of every layer (exact ones on
            // the exact nodes, truncated ones on theirs) and A(μ_u, −μ_v) of
            // the exact ones (δ paths).
            let users: Vec<Gsf> = mu
                .iter()
                .map(|&v| Gsf::new(m, v, l_max, polarized))
                .collect();
            let gsf_exact: Vec<Gsf> = exact
                .x
                .iter()
                .map(|&v| Gsf::new(m, v, l_max, polarized))
                .collect();
            let gsf_trunc: Vec<Gsf> = match &discrete {
                Some(d) => {
                    d.x.iter()
                        .map(|&v| Gsf::new(m, v, l_max, polarized))
                        .collect()
                }
                None => Vec::new(),
            };
            let gsf_t = if discrete.is_some() {
                &gsf_trunc
            } else {
                &gsf_exact
            };
            let down_users: Vec<(&Gsf, bool)> = users.iter().map(|g| (g, true)).collect();
            let tables: Vec<(Tables, Option<Tables>)> = active
                .iter()
                .map(|l| {
                    let full = kernel_tables(&l.full, m, &users, &exact, &gsf_exact, polarized);
                    let trunc = if m >= l.trunc.beta.len() {
                        None
                    } else if !l.truncated() && discrete.is_none() {
                        Some(full.clone())
                    } else {
                        Some(kernel_tables(
                            &l.trunc,
                            m,
                            &users,
                            trunc_nodes,
                            gsf_t,
                            polarized,
                        ))
                    };
                    (full, trunc)
                })
                .collect();
            let user_a: Vec<Vec<Mat<f64>>> = active
                .iter()
                .map(|l| a_table(&l.full, m, &users, &down_users, polarized))
                .collect();
            let mut out = Mat::<f64>::zeros(nu * ns, nu * ns);
            // Step 3: contraction over ν, exact minus truncated, and the δ
            // paths, compiled for the CPU's vector extensions.
            pulp::Arch::new().dispatch(Contraction {
                mu,
                pairs: &pairs,
                active: &active,
                tables: &tables,
                user_a: &user_a,
                delta_geometry: &delta_geometry,
                exact: &exact,
                trunc_nodes,
                nu,
                ns,
                out: &mut out,
            });
            out
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::expansion::test_data::garcia_siewert;
    use crate::solver::depth::segment;
    use crate::solver::phase::a_matrix;
    use geometry::PairGeometry;

    /// The matrix-product kernel table equals [`a_matrix`] element by
    /// element, for up and down (flipped) directions, polarized and scalar.
    #[test]
    fn a_table_matches_a_matrix() {
        let coef = garcia_siewert();
        let l_max = coef.beta.len() - 1;
        for polarized in [true, false] {
            for m in [0usize, 1, 3, 7] {
                let left: Vec<Gsf> = [0.2, 0.7, 1.0]
                    .iter()
                    .map(|&v| Gsf::new(m, v, l_max, polarized))
                    .collect();
                let r: Vec<Gsf> = [0.1, 0.55, 0.93]
                    .iter()
                    .map(|&v| Gsf::new(m, v, l_max, polarized))
                    .collect();
                let right: Vec<(&Gsf, bool)> =
                    r.iter().flat_map(|g| [(g, false), (g, true)]).collect();
                let tab = a_table(&coef, m, &left, &right, polarized);
                let nus = [0.1, 0.55, 0.93];
                for (i, gl) in left.iter().enumerate() {
                    for (j, &(_, flip)) in right.iter().enumerate() {
                        let nu = if flip { -nus[j / 2] } else { nus[j / 2] };
                        let gr = Gsf::new(m, nu, l_max, polarized);
                        let want = a_matrix(&coef, m, gl, &gr, polarized);
                        let ns = if polarized { 4 } else { 1 };
                        for p in 0..ns {
                            for q in 0..ns {
                                let got = tab[p * ns + q][(i, j)];
                                assert!(
                                    (got - want[p][q]).abs() < 1e-12 * (1.0 + want[p][q].abs()),
                                    "m={m} ({i},{j}) [{p}][{q}]: {got} vs {}",
                                    want[p][q]
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    /// The slab geometry against direct numerical integration of its
    /// defining double integral (module docs), within one layer, between
    /// layers, near the removable singularities `c = a`, `c = b` and for a
    /// semi-infinite layer.
    /// The factor tables give [`geometry`] at every triple of cosines, for
    /// one layer (thin, thick, semi-infinite; `c` next to `a` for the
    /// divided difference) and for layers above and below each other.
    #[test]
    fn pair_tables_equal_the_geometry() {
        let inv_mu: Vec<f64> = [1.0, 0.8, 0.45, 0.1, 0.0123, 0.45 + 1e-9]
            .iter()
            .map(|m| 1.0 / m)
            .collect();
        let inv_x: Vec<f64> = [0.99, 0.8 + 1e-7, 0.5, 0.2, 0.03]
            .iter()
            .map(|m| 1.0 / m)
            .collect();
        // A stack (top, thickness), every pair of its layers; and single
        // thick layers with themselves.
        let stack = [
            (0.0, 1e-4),
            (1e-4, 0.7),
            (0.7001, 2.0),
            (2.7001, f64::INFINITY),
        ];
        let mut pairs: Vec<((f64, f64), (f64, f64))> = stack
            .iter()
            .flat_map(|&j| stack.iter().map(move |&k| (j, k)))
            .collect();
        pairs.extend([((0.0, 40.0), (0.0, 40.0)), ((0.3, 2.0), (0.3, 2.0))]);
        let mut worst: f64 = 0.0;
        for &(j, k) in &pairs {
            let g = PairGeometry::new(&inv_mu, &inv_x, j, k);
            for u in 0..inv_mu.len() {
                for v in 0..inv_mu.len() {
                    for (q, &c) in inv_x.iter().enumerate() {
                        for up in [false, true] {
                            let (a, b) = (inv_mu[v], inv_mu[u]);
                            let want = geometry(a, b, c, up, j, k);
                            let got = g.at(u, v, q, up);
                            let err = (got - want).abs() / want.abs().max(1e-300);
                            // The up path of a thin layer is a difference of
                            // two O(T) terms of size O(T c): both forms round
                            // it to ~1e-16 / (T c) relative (1e-12 at T = 1e-4).
                            assert!(err < 1e-10 || got == want, "{j:?} {k:?} {got} {want}");
                            worst = worst.max(if got == want { 0.0 } else { err });
                        }
                    }
                }
            }
        }
        eprintln!("pair tables: worst relative difference {worst:e}");
    }

    #[test]
    fn geometry_is_the_double_depth_integral() {
        // Midpoint rule on a fine grid, with the inner integral exact.
        let brute = |a: f64, b: f64, c: f64, up: bool, j: (f64, f64), k: (f64, f64)| {
            let n = 20000;
            let (k0, kt) = (k.0, if k.1.is_finite() { k.1 } else { 40.0 / b });
            let (j0, jt) = (j.0, if j.1.is_finite() { j.1 } else { 40.0 / a });
            let h = kt / n as f64;
            let mut sum = 0.0;
            for i in 0..n {
                let t2 = k0 + (i as f64 + 0.5) * h;
                // inner: ∫ over t1 in j with t1 < t2 (down) or t1 > t2 (up)
                let (lo, hi) = if up {
                    (j0.max(t2), j0 + jt)
                } else {
                    (j0, (j0 + jt).min(t2))
                };
                if hi <= lo {
                    continue;
                }
                // ∫ c e^{−a t1} e^{−c |t2 − t1|} dt1, exact
                let inner = if up {
                    c * segment(-c * t2, a + c, lo, hi - lo)
                } else {
                    c * segment(c * t2, a - c, lo, hi - lo)
                };
                sum += h * b * (-b * t2).exp() * inner;
            }
            sum
        };
        let cases = [
            (
                1.0 / 0.3,
                1.0 / 0.6,
                1.0 / 0.45,
                false,
                (0.0, 0.8),
                (0.0, 0.8),
            ),
            (
                1.0 / 0.3,
                1.0 / 0.6,
                1.0 / 0.45,
                true,
                (0.0, 0.8),
                (0.0, 0.8),
            ),
            (
                1.0 / 0.3,
                1.0 / 0.6,
                1.0 / 0.3,
                false,
                (0.2, 0.5),
                (0.2, 0.5),
            ),
            (
                1.0 / 0.3,
                1.0 / 0.6,
                1.0 / 0.6,
                true,
                (0.2, 0.5),
                (0.2, 0.5),
            ),
            (
                1.0 / 0.9,
                1.0 / 0.2,
                1.0 / 0.05,
                false,
                (0.1, 0.3),
                (0.4, 0.6),
            ),
            (
                1.0 / 0.9,
                1.0 / 0.2,
                1.0 / 0.7,
                true,
                (0.4, 0.6),
                (0.1, 0.3),
            ),
            (
                1.0 / 0.5,
                1.0 / 0.5,
                1.0 / 0.8,
                false,
                (0.0, f64::INFINITY),
                (0.0, f64::INFINITY),
            ),
            (
                1.0 / 0.5,
                1.0 / 0.5,
                1.0 / 0.8,
                true,
                (0.0, f64::INFINITY),
                (0.0, f64::INFINITY),
            ),
            (
                1.0 / 0.5,
                1.0 / 0.7,
                1.0 / 0.8,
                false,
                (0.0, 0.5),
                (0.5, f64::INFINITY),
            ),
        ];
        for (a, b, c, up, j, k) in cases {
            let got = geometry(a, b, c, up, j, k);
            let want = brute(a, b, c, up, j, k);
            assert!(
                (got - want).abs() < 1e-6 * want.abs().max(1e-12),
                "a={a} b={b} c={c} up={up} {j:?} {k:?}: {got} vs {want}"
            );
        }
        // Wrong order of layers: no path.
        assert_eq!(geometry(2.0, 2.0, 2.0, false, (0.4, 0.6), (0.1, 0.3)), 0.0);
        assert_eq!(geometry(2.0, 2.0, 2.0, true, (0.1, 0.3), (0.4, 0.6)), 0.0);
    }
}
