//! The slab geometry of double scattering (module docs of
//! `solver::secondary`, "Equations"): `G_{jk}` in closed form, its tables
//! for every triple of cosines of a layer pair, and the `ν` quadratures
//! with their geometry weights.

use super::super::depth::{divided_difference, e_int, segment};
use crate::physics::quadrature::gauss_legendre_on;

/// Double-scattering geometry `G_{jk}` (module docs): beam down at
/// `μ0 = 1/a`, first scattering in layer `j = (top, thickness)` into the
/// intermediate direction of cosine magnitude `1/c` (upwards if `up`),
/// second in layer `k` up into `μ = 1/b`; scaled depths.
pub(crate) fn geometry(a: f64, b: f64, c: f64, up: bool, j: (f64, f64), k: (f64, f64)) -> f64 {
    let ((ta, tt), (ka, kt)) = (j, k);
    if ta == ka {
        // Both scatterings in one layer of thickness T, top at A.
        let shift = (-(a + b) * ta).exp();
        if shift == 0.0 {
            return 0.0;
        }
        if !up {
            b * c * shift * divided_difference(a + b, b + c, tt)
        } else {
            let back = if tt.is_infinite() {
                0.0
            } else if b >= c {
                (-(a + c) * tt).exp() * e_int(b - c, tt)
            } else {
                (-(a + b) * tt).exp() * e_int(c - b, tt)
            };
            b * c * shift * (e_int(a + b, tt) - back) / (a + c)
        }
    } else if !up && ta < ka {
        // Down from layer j (above) to layer k.
        let bot_j = ta + tt;
        b * c
            * segment(c * bot_j, a - c, ta, tt)
            * (-c * (ka - bot_j)).exp()
            * segment(-c * ka, b + c, ka, kt)
    } else if up && ta > ka {
        // Up from layer j (below) to layer k.
        let bot_k = ka + kt;
        b * c
            * segment(-c * ta, a + c, ta, tt)
            * (-c * (ta - bot_k)).exp()
            * segment(c * bot_k, b - c, ka, kt)
    } else {
        0.0
    }
}

/// A `ν` quadrature over both hemispheres: node `q < k` is `+x[q]` (up),
/// node `q ≥ k` is `−x[q − k]` (down), and the geometry weights
/// `w_q G_{jk}(μ_v, ν_q, μ_u)` per layer pair.
pub(super) struct Nodes {
    pub(super) x: Vec<f64>,
    pub(super) k: usize,
    /// Per pair (index into the pair list): `wq[(u nu + v) 2k + q]`, for
    /// `v ≥ u` (the half the contraction uses; zero below).
    pub(super) weights: Vec<Vec<f64>>,
}

/// [`geometry`] for every `(μ_u, μ_v, ν_q)` of one layer pair, from
/// tables of its factors: two layers separate into a factor of `(μ_v, ν)`
/// and one of `(μ_u, ν)`; one layer into exponentials and `E_T` integrals
/// of two of the three cosines each (the divided difference near `c = a`
/// falls back to [`geometry`]). `O(n_u n_ν + n_u²)` exponentials instead of
/// `O(n_u² n_ν)`; the values are [`geometry`]'s to rounding (unit test).
pub(super) struct PairGeometry<'a> {
    /// `1/μ_u` (the incident `a` for index `v`, the outgoing `b` for `u`).
    inv_mu: &'a [f64],
    /// `1/ν_q` on one hemisphere (`c`).
    inv_x: &'a [f64],
    j: (f64, f64),
    k: (f64, f64),
    kind: PairKind,
}

pub(super) enum PairKind {
    /// Layer `j` above `k`: down paths only, `G = F[v, q] H[u, q]`.
    Down { f: Vec<f64>, h: Vec<f64> },
    /// Layer `j` below `k`: up paths only, `G = F[v, q] H[u, q]`.
    Up { f: Vec<f64>, h: Vec<f64> },
    /// One layer of thickness `T`: `shift[u, v] = e^{−(a+b)A}`,
    /// `e_ab[u, v] = E_T(a + b)`, `e_bc[u, q] = E_T(b + c)`,
    /// `e_back[u, q] = E_T(|b − c|)`, `x_a[v] = e^{−aT}`, `x_c[q] = e^{−cT}`,
    /// `x_ab[u, v] = e^{−(a+b)T}`.
    Same {
        shift: Vec<f64>,
        e_ab: Vec<f64>,
        e_bc: Vec<f64>,
        e_back: Vec<f64>,
        x_a: Vec<f64>,
        x_c: Vec<f64>,
        x_ab: Vec<f64>,
    },
}

impl<'a> PairGeometry<'a> {
    pub(super) fn new(inv_mu: &'a [f64], inv_x: &'a [f64], j: (f64, f64), k: (f64, f64)) -> Self {
        let (nu, nx) = (inv_mu.len(), inv_x.len());
        let ((ta, tt), (ka, kt)) = (j, k);
        let table = |f: &dyn Fn(f64, f64) -> f64, rows: &[f64], cols: &[f64]| -> Vec<f64> {
            rows.iter()
                .flat_map(|&r| cols.iter().map(move |&c| (r, c)))
                .map(|(r, c)| f(r, c))
                .collect()
        };
        let kind = if ta == ka {
            PairKind::Same {
                shift: table(&|b, a| (-(a + b) * ta).exp(), inv_mu, inv_mu),
                e_ab: table(&|b, a| e_int(a + b, tt), inv_mu, inv_mu),
                e_bc: table(&|b, c| e_int(b + c, tt), inv_mu, inv_x),
                e_back: table(&|b, c| e_int((b - c).abs(), tt), inv_mu, inv_x),
                x_a: inv_mu.iter().map(|a| (-a * tt).exp()).collect(),
                x_c: inv_x.iter().map(|c| (-c * tt).exp()).collect(),
                x_ab: table(&|b, a| (-(a + b) * tt).exp(), inv_mu, inv_mu),
            }
        } else if ta < ka {
            let bot_j = ta + tt;
            PairKind::Down {
                f: table(
                    &|a, c| c * segment(c * bot_j, a - c, ta, tt) * (-c * (ka - bot_j)).exp(),
                    inv_mu,
                    inv_x,
                ),
                h: table(&|b, c| b * segment(-c * ka, b + c, ka, kt), inv_mu, inv_x),
            }
        } else {
            let bot_k = ka + kt;
            PairKind::Up {
                f: table(
                    &|a, c| c * segment(-c * ta, a + c, ta, tt) * (-c * (ta - bot_k)).exp(),
                    inv_mu,
                    inv_x,
                ),
                h: table(&|b, c| b * segment(c * bot_k, b - c, ka, kt), inv_mu, inv_x),
            }
        };
        debug_assert!(nu > 0 && nx > 0);
        Self {
            inv_mu,
            inv_x,
            j,
            k,
            kind,
        }
    }

    /// `G_{jk}` for incident `μ_v`, outgoing `μ_u`, intermediate `±ν_q`.
    pub(super) fn at(&self, u: usize, v: usize, q: usize, up: bool) -> f64 {
        let (nu, nx) = (self.inv_mu.len(), self.inv_x.len());
        match &self.kind {
            PairKind::Down { f, h } if !up => f[v * nx + q] * h[u * nx + q],
            PairKind::Up { f, h } if up => f[v * nx + q] * h[u * nx + q],
            PairKind::Down { .. } | PairKind::Up { .. } => 0.0,
            PairKind::Same {
                shift,
                e_ab,
                e_bc,
                e_back,
                x_a,
                x_c,
                x_ab,
            } => {
                let (a, b, c) = (self.inv_mu[v], self.inv_mu[u], self.inv_x[q]);
                let tt = self.j.1;
                let shift = shift[u * nu + v];
                if shift == 0.0 {
                    return 0.0;
                }
                if !up {
                    let dd = if tt.is_infinite() {
                        1.0 / ((a + b) * (b + c))
                    } else if ((c - a) * tt).abs() > 1e-3 {
                        (e_ab[u * nu + v] - e_bc[u * nx + q]) / (c - a)
                    } else {
                        return geometry(a, b, c, up, self.j, self.k);
                    };
                    b * c * shift * dd
                } else {
                    let back = if tt.is_infinite() {
                        0.0
                    } else if b >= c {
                        x_a[v] * x_c[q] * e_back[u * nx + q]
                    } else {
                        x_ab[u * nu + v] * e_back[u * nx + q]
                    };
                    b * c * shift * (e_ab[u * nu + v] - back) / (a + c)
                }
            }
        }
    }
}

impl Nodes {
    pub(super) fn new(
        (x, w): (Vec<f64>, Vec<f64>),
        mu: &[f64],
        pairs: &[(usize, usize)],
        bounds: &[(f64, f64)],
    ) -> Self {
        let k = x.len();
        let nu = mu.len();
        let nq = 2 * k;
        let inv_mu: Vec<f64> = mu.iter().map(|m| 1.0 / m).collect();
        let inv_x: Vec<f64> = x.iter().map(|v| 1.0 / v).collect();
        let weights = pairs
            .iter()
            .map(|&(j, kk)| {
                let mut wq = vec![0.0; nu * nu * nq];
                let g = PairGeometry::new(&inv_mu, &inv_x, bounds[j], bounds[kk]);
                // Pairs v ≥ u only, as the contraction uses them.
                for u in 0..nu {
                    for v in u..nu {
                        for q in 0..nq {
                            let at = g.at(u, v, q % k, q < k);
                            wq[(u * nu + v) * nq + q] = w[q % k] * at;
                        }
                    }
                }
                wq
            })
            .collect();
        Self { x, k, weights }
    }

    pub(super) fn nq(&self) -> usize {
        2 * self.k
    }
}

/// Gauss–Legendre nodes and weights on `(0, 1)`, `n` per panel, on panels
/// graded towards the horizon for a thin layer: `(0, τ), (τ, 10τ), …,
/// (…, 1)` when the thinnest layer's thickness is `τ < 0.1`, one panel
/// otherwise. Each panel integrates the kernel product (a polynomial)
/// exactly; the grading resolves the geometry near `ν = 0`, where in a layer
/// of thickness `τ` it varies on the scale `τ` and falls like `1/ν` beyond
/// (the `ln(1/τ)` of thin-layer double scattering; measured: a layer of
/// τ = 1e-3 was off by 25 % of its double scattering on one panel).
pub(crate) fn graded_gauss(n: usize, tau: f64) -> (Vec<f64>, Vec<f64>) {
    let mut edges = vec![0.0];
    if tau < 0.1 {
        let mut e = tau.max(1e-8);
        while e < 1.0 {
            edges.push(e);
            e *= 10.0;
        }
    }
    edges.push(1.0);
    let (mut x, mut w) = (Vec::new(), Vec::new());
    for pair in edges.windows(2) {
        let (xp, wp) = gauss_legendre_on(n, pair[0], pair[1]);
        x.extend(xp);
        w.extend(wp);
    }
    (x, w)
}
