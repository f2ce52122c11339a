//! A rough (microfacet) base per Fourier order: the operators of
//! [`crate::physics::microfacet::RoughSurface`] on the solver's grid
//! (docs/solver.md, "Rough bases").
//!
//! **Azimuth.** For each pair of cosines the kernel's Fourier series in
//! propagation azimuth ([`super::azimuth::pair_series`]: an FFT, or split
//! Gauss rules across a total-reflection edge), `ρ^m = 2π μ' F^m` in the
//! S1 set of conventions §7.
//!
//! **Polar angle.** The lobe is as narrow as `α` in angle, far narrower
//! than the gaps between discrete ordinates at small `α`, so neither its
//! input nor its output is sampled at the ordinates alone. The radiance
//! coming in is the interpolant of the ordinates (Lagrange `ℓ_j`, on each
//! part of a split quadrature); the radiance going out is projected back
//! onto them so that its flux-weighted moments are kept,
//! `Σ_i w_i μ_i g(μ_i) L_i = ∫ g μ L dμ` for `g` of degree `< N`. Both
//! integrals run over fine composite Gauss nodes `μ_k` (weights `v_k`,
//! panels of width `α/2` in polar angle, at most 0.2 rad, ending at every
//! second ordinate, every ordinate part on its own):
//!
//! ```text
//! r_ij   = Σ_k Σ_l v_k μ_k ℓ_i(μ_k) ρ(μ_k, μ_l) v_l ℓ_j(μ_l) / (w_i μ_i)   quadrature ← quadrature
//! rb_iv  = Σ_k v_k μ_k ℓ_i(μ_k) ρ(μ_k, μ_v) / (w_i μ_i)                      quadrature ← beam
//! ru_uj  = Σ_l ρ(μ_u, μ_l) v_l ℓ_j(μ_l)                                        user ← quadrature
//! ruu_uv = ρ(μ_u, μ_v)                                                         user ← beam
//! ```
//!
//! For a smooth BRDF these are the collocation blocks of a Lambertian base
//! (`r_ij ≈ ρ(μ_i, μ_j) w_j`). `w_i μ_i r_ij` is symmetric as reciprocity
//! asks (up to `Δ·ᵀΔ`), every column keeps the fine grid's flux exactly
//! (`Σ_i ℓ_i = 1`), and as `α → 0`, since the Gauss rule integrates
//! `ℓ_i ℓ_j μ` exactly (`= w_i μ_i δ_ij`), the blocks tend to the mirror's
//! `δ_ij M_F(μ_i)` wherever the beam lands, between ordinates included.
//!
//! **Edges.** The Gauss rule of a panel is spectrally accurate only where
//! the integrand is smooth. A kernel's Fourier coefficients in one cosine
//! at a fixed other stop being smooth where one of the kernel's edges
//! (facet total reflection, [`RoughSurface::reflection_edges`]; the
//! transmission's jump and largest deviation,
//! [`RoughSurface::transmission_edges`]) enters or leaves the azimuth
//! range: a fine panel ends at each (docs/solver.md, "Edges, and panels as
//! narrow as the lobe"). Before they did, the 6-node rule left 1.5–2.9e-6
//! 1/sr under a rough interface, ~7× the stated stream error.

use super::azimuth::pair_series;
use super::layer::Ops;
use super::orders::Grid;
use crate::physics::microfacet::RoughSurface;
use crate::physics::quadrature::gauss_legendre_on;
use crate::physics::stokes::Mueller;
use faer::Mat;
use rayon::prelude::*;
use realfft::RealFftPlanner;
use std::borrow::Cow;

/// Gauss nodes per fine panel.
pub(super) const PANEL_NODES: usize = 6;

/// A fine panel ends at every `ORDINATE_STEP`-th ordinate of a part
/// ([`parts`]; docs/solver.md, "Where light is trapped").
const ORDINATE_STEP: usize = 2;

/// The rough base's operators for every Fourier order it reflects into:
/// each `ns × ns` entry of each block as its own Fourier series (most
/// pairs of directions need few orders; grazing ones many).
pub struct RoughProjection {
    ns: usize,
    nq: usize,
    nu: usize,
    /// Series of `r` (`i·nq + j`), `rb` (`i·nu + v`), `ru` (`u·nq + j`),
    /// `ruu` (`u·nu + v`).
    blocks: [Vec<Series>; 4],
}

/// A Fourier series `m = 0..` of one `ns × ns` entry, flattened row-major.
pub(super) type Series = Vec<[f64; 16]>;

/// `dst += a · src`, growing `dst` to the length of `src`.
fn add_series(dst: &mut Series, a: f64, src: &[[f64; 16]]) {
    if dst.len() < src.len() {
        dst.resize(src.len(), [0.0; 16]);
    }
    for (d, s) in dst.iter_mut().zip(src) {
        for (x, y) in d.iter_mut().zip(s) {
            *x += a * y;
        }
    }
}

/// Fine nodes of one part of the ordinates: cosines, weights, and the part's
/// ordinates' Lagrange basis at each (`basis[k][j]` for the part's `j`-th
/// ordinate, its index in the grid `first + j`).
#[derive(Clone)]
struct Part {
    first: usize,
    mu: Vec<f64>,
    v: Vec<f64>,
    basis: Vec<Vec<f64>>,
}

/// Lagrange basis polynomials of `nodes` at `x` (barycentric form).
fn lagrange(nodes: &[f64], x: f64) -> Vec<f64> {
    if let Some(j) = nodes.iter().position(|&t| t == x) {
        let mut e = vec![0.0; nodes.len()];
        e[j] = 1.0;
        return e;
    }
    let bw: Vec<f64> = (0..nodes.len())
        .map(|j| {
            1.0 / (0..nodes.len())
                .filter(|&l| l != j)
                .map(|l| nodes[j] - nodes[l])
                .product::<f64>()
        })
        .collect();
    let terms: Vec<f64> = nodes.iter().zip(&bw).map(|(&t, &b)| b / (x - t)).collect();
    let sum: f64 = terms.iter().sum();
    terms.iter().map(|t| t / sum).collect()
}

/// The parts of the ordinates (split at `split`) with their fine nodes:
/// panels of width at most `panel_rad` in polar angle, and a panel
/// boundary at each cosine of `cuts` where the kernel jumps or has a kink
/// ([`Kernels`]).
fn parts(
    mu_q: &[f64],
    split: Option<f64>,
    panel_rad: f64,
    panel_nodes: usize,
    cuts: &[f64],
) -> Vec<Part> {
    let bounds: Vec<f64> = match split {
        Some(c) => vec![0.0, c, 1.0],
        None => vec![0.0, 1.0],
    };
    let mut out = Vec::new();
    for w in bounds.windows(2) {
        let (lo, hi) = (w[0], w[1]);
        let idx: Vec<usize> = (0..mu_q.len())
            .filter(|&i| mu_q[i] > lo && mu_q[i] < hi)
            .collect();
        let nodes: Vec<f64> = idx.iter().map(|&i| mu_q[i]).collect();
        // Polar-angle stretches of the part, split at the cuts (one closer
        // than 1e-9 rad to another edge is that edge), each edge marked
        // if it is a cut.
        let mut edges = vec![(hi.acos(), false), (lo.acos(), false)];
        for &c in cuts.iter().filter(|&&c| c >= lo && c <= hi) {
            let t = c.acos();
            match edges.iter_mut().find(|(e, _)| (e - t).abs() <= 1e-9) {
                Some(e) => e.1 = true,
                None => edges.push((t, true)),
            }
        }
        // A panel also ends at every second ordinate of the part: the
        // Lagrange basis oscillates on the ordinates' spacing, which
        // panels as wide as the lobe do not follow at many streams.
        for &x in nodes.iter().skip(ORDINATE_STEP / 2).step_by(ORDINATE_STEP) {
            let t = x.acos();
            if edges.iter().all(|(e, _)| (e - t).abs() > 1e-9) {
                edges.push((t, false));
            }
        }
        edges.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (mut mu, mut v) = (Vec::new(), Vec::new());
        for e in edges.windows(2) {
            let ((th_lo, cut_lo), (th_hi, cut_hi)) = (e[0], e[1]);
            for (a, b) in stretch_panels(th_lo, th_hi, panel_rad, cut_lo, cut_hi) {
                let (x, wx) = gauss_legendre_on(panel_nodes, a, b);
                for (&t, &wt) in x.iter().zip(&wx) {
                    mu.push(t.cos());
                    v.push(wt * t.sin());
                }
            }
        }
        let basis = mu.iter().map(|&x| lagrange(&nodes, x)).collect();
        out.push(Part {
            first: idx.first().copied().unwrap_or(0),
            mu,
            v,
            basis,
        });
    }
    out
}

/// Levels of the geometric grading of a panel towards a cut, and their
/// ratio ([`stretch_panels`]).
const GRADING: (usize, f64) = (3, 0.15);

/// The panels `(a, b)` of the polar-angle stretch `[lo, hi]`: equal ones
/// at most `panel_rad` wide, the one at an end that is a cut graded
/// geometrically towards it (widths `h σ^L, …, h σ(1 − σ), h(1 − σ)` of its
/// width `h`, [`GRADING`]). At a cut the kernel's coefficients are not
/// smooth (`x log x`, `x^{3/4}` in the distance where an edge enters the
/// azimuth range, docs/solver.md), which a Gauss rule on a panel of
/// uniform width integrates only algebraically.
fn stretch_panels(lo: f64, hi: f64, panel_rad: f64, cut_lo: bool, cut_hi: bool) -> Vec<(f64, f64)> {
    let mut panels = ((hi - lo) / panel_rad).ceil().max(1.0) as usize;
    if cut_lo && cut_hi {
        panels = panels.max(2);
    }
    let at = |p: usize| lo + (hi - lo) * p as f64 / panels as f64;
    let (levels, ratio) = GRADING;
    // The breakpoints of the panel from `start` to `end`, graded towards
    // `start`, in ascending order.
    let graded = |start: f64, end: f64| -> Vec<f64> {
        let mut pts = vec![start];
        pts.extend(
            (1..=levels)
                .rev()
                .map(|l| start + (end - start) * ratio.powi(l as i32)),
        );
        pts.push(end);
        if start > end {
            pts.reverse();
        }
        pts
    };
    let mut pts = Vec::new();
    for p in 0..panels {
        let (a, b) = (at(p), at(p + 1));
        let piece = match (p == 0 && cut_lo, p + 1 == panels && cut_hi) {
            (true, _) => graded(a, b),
            (false, true) => graded(b, a),
            (false, false) => vec![a, b],
        };
        if pts.is_empty() {
            pts.extend(piece);
        } else {
            pts.extend(&piece[1..]);
        }
    }
    pts.windows(2).map(|w| (w[0], w[1])).collect()
}

/// A BRDF or BTDF `f(μ_out, μ_in, Δφ_prop)` (1/sr, meridian frames) obeying
/// the mirror symmetry `f(−Δφ) = D f(Δφ) D`.
pub(super) type Kernel<'a> = dyn Fn(f64, f64, f64) -> Mueller + Sync + 'a;

/// The propagation azimuth in `(0, π)` at which a kernel has a
/// square-root edge at a pair of cosines `(μ_out, μ_in)`, if it has one
/// there ([`RoughSurface::reflection_azimuth_edge`]).
pub(super) type AzimuthEdge<'a> = dyn Fn(f64, f64) -> Option<f64> + Sync + 'a;

/// A block's kernel, and its edge in azimuth if it can have one (facet
/// total reflection): the pair's series is then integrated across it by
/// split rules ([`super::azimuth`]).
#[derive(Clone, Copy)]
pub(super) struct Lobe<'a> {
    pub f: &'a Kernel<'a>,
    pub azimuth_edge: Option<&'a AzimuthEdge<'a>>,
}

impl Lobe<'_> {
    /// The pair's Fourier series, orders `m < max_orders` ([`pair_series`]).
    fn series(
        &self,
        mu_out: f64,
        mu_in: f64,
        ns: usize,
        max_orders: usize,
        planner: &mut RealFftPlanner<f64>,
    ) -> Vec<[f64; 16]> {
        let edge = self.azimuth_edge.and_then(|e| e(mu_out, mu_in));
        pair_series(self.f, edge, mu_out, mu_in, ns, max_orders, planner)
    }
}

/// The kernels of the four blocks (module doc): `r` (quadrature ←
/// quadrature), `rb` (quadrature ← beam), `ru` (user ← quadrature), `ruu`
/// (user ← beam). A base uses its BRDF for all four; a rough interface
/// puts its operators there (`solver::rough_interface`), all but `ruu`,
/// which it evaluates in closed form (`None`: the block stays zero).
pub(super) struct Kernels<'a> {
    pub r: Lobe<'a>,
    pub rb: Lobe<'a>,
    pub ru: Lobe<'a>,
    pub ruu: Option<Lobe<'a>>,
    /// Where `rb` and `ru` jump or have a kink in the fine cosine they are
    /// integrated over, given the user or beam cosine (a transmission's
    /// edges, [`RoughSurface::transmission_edges`]): a fine panel ends at
    /// each, so that no Gauss rule straddles one (module doc, "Edges").
    pub crossing_edges: Option<&'a Edges<'a>>,
    /// The same for `r` in one fine cosine given the other (a reflection's
    /// total-reflection edges, [`RoughSurface::reflection_edges`]).
    pub reflection_edges: Option<&'a Edges<'a>>,
    /// `r` is only ever used between `rb` and `ru` of the same order (a
    /// rough interface's `T_u (I − r R_b)^{-1} r T_d`): its orders stop
    /// where either of theirs does.
    pub r_within_crossing_orders: bool,
}

/// Cosines where a kernel is not smooth in one cosine, given the other.
pub(super) type Edges<'a> = dyn Fn(f64) -> Vec<f64> + Sync + 'a;

/// Fine panels of a lobe of width `alpha`: `α/2` in polar angle, at most 0.2 rad.
pub(super) fn panel_width(alpha: f64) -> f64 {
    0.5 * alpha.min(0.4)
}

/// Widths (rad) of the fine panels of the reflection kernels (`r`, and a
/// base's `rb`, `ru`) and of the crossing ones (an interface's `rb`, `ru`).
#[derive(Clone, Copy)]
pub(super) struct Panels {
    pub reflection: f64,
    pub crossing: f64,
    /// Gauss nodes per panel ([`PANEL_NODES`]).
    pub nodes: usize,
}

impl RoughProjection {
    /// The projection of `surface` on `grid` (its ordinates split at
    /// `split`, as the grid was built), `ns` Stokes components.
    pub(super) fn new(surface: &RoughSurface, grid: &Grid, split: Option<f64>) -> Self {
        Self::with_panels(surface, grid, split, panel_width(surface.alpha))
    }

    /// [`RoughProjection::new`] with fine panels of width `panel_rad`.
    pub(super) fn with_panels(
        surface: &RoughSurface,
        grid: &Grid,
        split: Option<f64>,
        panel_rad: f64,
    ) -> Self {
        let f = |mu_out: f64, mu_in: f64, d: f64| surface.mueller(mu_out, mu_in, d);
        let edges = |mu: f64| surface.reflection_edges(mu);
        let edge = |mu_out: f64, mu_in: f64| surface.reflection_azimuth_edge(mu_out, mu_in);
        let lobe = Lobe {
            f: &f,
            azimuth_edge: Some(&edge),
        };
        let kernels = Kernels {
            r: lobe,
            rb: lobe,
            ru: lobe,
            ruu: Some(lobe),
            crossing_edges: Some(&edges),
            reflection_edges: Some(&edges),
            r_within_crossing_orders: false,
        };
        let panels = Panels {
            reflection: panel_rad,
            crossing: panel_rad,
            nodes: PANEL_NODES,
        };
        Self::of_kernels(&kernels, grid, split, panels, usize::MAX)
    }

    /// The projection of four kernels (one per block) on `grid`, orders
    /// `m < max_orders` kept (each pair's series is still resolved in
    /// full, so that the kept orders are free of aliasing).
    pub(super) fn of_kernels(
        kernels: &Kernels<'_>,
        grid: &Grid,
        split: Option<f64>,
        panels: Panels,
        max_orders: usize,
    ) -> Self {
        let ns = grid.ns;
        let (nq, nu) = (grid.mu_q.len(), grid.mu_u.len());
        let edges = |e: Option<&Edges<'_>>, mu: f64| e.map(|e| e(mu)).unwrap_or_default();
        let parts_at = |mu: f64| {
            parts(
                &grid.mu_q,
                split,
                panels.crossing,
                panels.nodes,
                &edges(kernels.crossing_edges, mu),
            )
        };
        // Inner parts of a row of `r`: the plain ones, built once, where no
        // edge falls at that row (a conductor base: every row).
        let plain = parts(&grid.mu_q, split, panels.reflection, panels.nodes, &[]);
        let parts_r = |mu: f64| -> Cow<'_, [Part]> {
            let e = edges(kernels.reflection_edges, mu);
            if e.is_empty() {
                Cow::Borrowed(&plain)
            } else {
                Cow::Owned(parts(
                    &grid.mu_q,
                    split,
                    panels.reflection,
                    panels.nodes,
                    &e,
                ))
            }
        };
        // The rows of `r`: the inner integral at a fine cosine is not
        // smooth where one of its edges meets an end of an inner part.
        let row_cuts: Vec<f64> = [Some(1.0), split, Some(0.0)]
            .into_iter()
            .flatten()
            .flat_map(|b| edges(kernels.reflection_edges, b))
            .collect();
        let parts = parts(
            &grid.mu_q,
            split,
            panels.reflection,
            panels.nodes,
            &row_cuts,
        );
        // Work items: every fine node `(part, k)` as a row of `r`, every
        // user direction as a row of `ru` and `ruu`, every beam as a column
        // of `rb`.
        #[derive(Clone, Copy)]
        enum Item {
            Fine(usize, usize),
            User(usize),
            Beam(usize),
        }
        let rows: Vec<Item> = parts
            .iter()
            .enumerate()
            .flat_map(|(p, part)| (0..part.mu.len()).map(move |k| Item::Fine(p, k)))
            .chain((0..nu).map(Item::User))
            .chain((0..nu).map(Item::Beam))
            .collect();
        let empty = || -> [Vec<Series>; 4] {
            [
                vec![Series::new(); nq * nq],
                vec![Series::new(); nq * nu],
                vec![Series::new(); nu * nq],
                vec![Series::new(); nu * nu],
            ]
        };
        // Towards the ordinates: t_j = Σ_l ρ(μ_out, μ_l) v_l ℓ_j(μ_l).
        let towards = |kernel: Lobe<'_>,
                       mu_out: f64,
                       parts: &[Part],
                       max_orders: usize,
                       planner: &mut RealFftPlanner<f64>| {
            let mut t = vec![Series::new(); nq];
            for part in parts {
                for (l, &mu_in) in part.mu.iter().enumerate() {
                    let c = kernel.series(mu_out, mu_in, ns, max_orders, planner);
                    for (j, &lj) in part.basis[l].iter().enumerate() {
                        add_series(&mut t[part.first + j], part.v[l] * lj, &c);
                    }
                }
            }
            t
        };
        // From fine node `k` of `part` back to the ordinates:
        // `v_k μ_k ℓ_i(μ_k) / (w_i μ_i)` for each ordinate `i` of the part.
        let back = |part: &Part, k: usize| -> Vec<(usize, f64)> {
            part.basis[k]
                .iter()
                .enumerate()
                .map(|(i, &li)| {
                    let gi = part.first + i;
                    (
                        gi,
                        part.v[k] * part.mu[k] * li / (grid.w_q[gi] * grid.mu_q[gi]),
                    )
                })
                .collect()
        };
        // One work item, projected into `acc`.
        let row_into = |acc: &mut [Vec<Series>; 4],
                        planner: &mut RealFftPlanner<f64>,
                        row: usize,
                        orders_r: usize| {
            let [r, rb, ru, ruu] = acc;
            match rows[row] {
                Item::Fine(p, k) => {
                    let mu_out = parts[p].mu[k];
                    let t = towards(kernels.r, mu_out, &parts_r(mu_out), orders_r, planner);
                    for (gi, a) in back(&parts[p], k) {
                        for (j, tj) in t.iter().enumerate() {
                            add_series(&mut r[gi * nq + j], a, tj);
                        }
                    }
                }
                Item::User(u) => {
                    let mu_out = grid.mu_u[u];
                    let t = towards(kernels.ru, mu_out, &parts_at(mu_out), max_orders, planner);
                    for (j, tj) in t.iter().enumerate() {
                        add_series(&mut ru[u * nq + j], 1.0, tj);
                    }
                    if let Some(k) = kernels.ruu {
                        for (v, &mu_in) in grid.mu_u.iter().enumerate() {
                            let c = k.series(mu_out, mu_in, ns, max_orders, planner);
                            add_series(&mut ruu[u * nu + v], 1.0, &c);
                        }
                    }
                }
                Item::Beam(v) => {
                    let mu_in = grid.mu_u[v];
                    for part in &parts_at(mu_in) {
                        for (k, &mu_out) in part.mu.iter().enumerate() {
                            let c = kernels.rb.series(mu_out, mu_in, ns, max_orders, planner);
                            for (gi, a) in back(part, k) {
                                add_series(&mut rb[gi * nu + v], a, &c);
                            }
                        }
                    }
                }
            }
        };
        let merge = |mut a: [Vec<Series>; 4], b: [Vec<Series>; 4]| {
            for (x, y) in a.iter_mut().zip(&b) {
                for (p, q) in x.iter_mut().zip(y) {
                    add_series(p, 1.0, q);
                }
            }
            a
        };
        // One accumulator per thread, rows dealt round-robin: grazing rows
        // cost the most.
        let threads = rayon::current_num_threads().max(1);
        let pass = |items: &[usize], orders_r: usize| {
            (0..threads)
                .into_par_iter()
                .map(|first| {
                    let mut acc = empty();
                    let mut planner = RealFftPlanner::<f64>::new();
                    for &row in items.iter().skip(first).step_by(threads) {
                        row_into(&mut acc, &mut planner, row, orders_r);
                    }
                    acc
                })
                .reduce(empty, merge)
        };
        let (fine, crossing): (Vec<usize>, Vec<usize>) =
            (0..rows.len()).partition(|&row| matches!(rows[row], Item::Fine(..)));
        let outer = pass(&crossing, max_orders);
        let orders_r = if kernels.r_within_crossing_orders {
            let len = |block: &[Series]| block.iter().map(Vec::len).max().unwrap_or(0);
            len(&outer[1]).min(len(&outer[2])).min(max_orders)
        } else {
            max_orders
        };
        let blocks = merge(outer, pass(&fine, orders_r));
        Self { ns, nq, nu, blocks }
    }

    /// Number of Fourier orders the base reflects into (0 for none).
    pub(super) fn order_count(&self) -> usize {
        self.blocks
            .iter()
            .flatten()
            .map(Vec::len)
            .max()
            .unwrap_or(0)
    }

    /// The base's operators for order `m` (zero beyond
    /// [`RoughProjection::order_count`]).
    pub(super) fn ops(&self, m: usize) -> Ops {
        let (ns, nq, nu) = (self.ns, self.nq, self.nu);
        let mut o = Ops::reflector(nq * ns, nu * ns, ns);
        let fill = |mat: &mut Mat<f64>, series: &[Series], cols: usize| {
            for (idx, x) in series.iter().enumerate() {
                let Some(c) = x.get(m) else { continue };
                let (i, j) = (idx / cols, idx % cols);
                for s in 0..ns {
                    for t in 0..ns {
                        mat[(i * ns + s, j * ns + t)] = c[s * ns + t];
                    }
                }
            }
        };
        let [r, rb, ru, ruu] = &self.blocks;
        fill(&mut o.r, r, nq);
        fill(&mut o.rb, rb, nu);
        fill(&mut o.ru, ru, nq);
        fill(&mut o.ruu, ruu, nu);
        o
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The panels tile the stretch; at a cut the first is `σ^L` of its
    /// panel's width and each next `1/σ` times the one before; an end that
    /// is not a cut keeps equal panels.
    #[test]
    fn panels_are_graded_towards_cuts_only() {
        let (levels, ratio) = GRADING;
        for (cut_lo, cut_hi) in [(false, false), (true, false), (false, true), (true, true)] {
            let p = stretch_panels(0.2, 0.9, 0.15, cut_lo, cut_hi);
            assert_eq!(p[0].0, 0.2);
            assert!((p.last().unwrap().1 - 0.9).abs() < 1e-15);
            assert!(p.windows(2).all(|w| w[0].1 == w[1].0 && w[0].0 < w[0].1));
            let width = |q: (f64, f64)| q.1 - q.0;
            let h = 0.7 / 5.0;
            assert_eq!(p.len(), 5 + levels * (cut_lo as usize + cut_hi as usize));
            for (cut, first, next) in [
                (cut_lo, p[0], p[1]),
                (cut_hi, p[p.len() - 1], p[p.len() - 2]),
            ] {
                let want = if cut {
                    h * ratio.powi(levels as i32)
                } else {
                    h
                };
                assert!((width(first) - want).abs() < 1e-12, "{p:?}");
                if cut {
                    assert!(
                        (width(next) - want * (1.0 / ratio - 1.0)).abs() < 1e-12,
                        "{p:?}"
                    );
                }
            }
        }
    }
}
