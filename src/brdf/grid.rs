//! The polar grid of a BRDF table and its 1-D interpolation scheme
//! (docs/table-format.md, "Polar grid").
//!
//! Incident and outgoing polar angles share one grid. Interpolation is in the
//! variable
//!
//! ```text
//! s(θ) = (2/π) asin(θ / 90°),   θ = 90° · sin(π s / 2),   s ∈ [0, 1],
//! ```
//!
//! by a local Lagrange polynomial of degree `K − 1` through the `K` nodes
//! nearest to the point ([`STENCIL`]). The default nodes are uniform in `s`
//! ([`PolarGrid::graded`]): about uniform in `θ` near the normal, and graded
//! towards the horizon where `μ = cos θ ≈ (π³/16)(1 − s)²` — so functions
//! with a `μ ln μ` term (the H-functions of multiple scattering) or an
//! `exp(−τ/μ)` factor become smooth in `s`. Node `θ = 90°` is evaluated at
//! `μ = MU_FLOOR` (conventions §5).
//!
//! The same weights are used on both axes, so a tensor-product interpolant
//! of reciprocal node data is reciprocal (docs/table-format.md).

use super::angles::mu_of_theta_deg;

/// Number of nodes of the default Lagrange stencil (degree `STENCIL − 1`).
pub const STENCIL: usize = 6;

/// Largest stencil [`PolarGrid::stencil_of_size`] accepts.
pub const MAX_STENCIL: usize = 8;

/// Default number of polar nodes.
pub const DEFAULT_NODES: usize = 64;

/// `s(θ) = (2/π) asin(θ/90°)`.
pub fn s_of_theta_deg(theta_deg: f64) -> f64 {
    (theta_deg / 90.0).clamp(0.0, 1.0).asin() * std::f64::consts::FRAC_2_PI
}

/// `θ(s) = 90° sin(πs/2)`.
pub fn theta_deg_of_s(s: f64) -> f64 {
    90.0 * (s * std::f64::consts::FRAC_PI_2).sin()
}

/// Polar nodes shared by incident and outgoing directions.
#[derive(Clone, Debug, PartialEq)]
pub struct PolarGrid {
    /// Polar angles in degrees, strictly increasing, in `[0, 90]`.
    pub theta_deg: Vec<f64>,
    /// `μ = cos θ` floored at `MU_FLOOR` (strictly decreasing).
    pub mu: Vec<f64>,
    /// Interpolation coordinates `s(θ)`.
    pub s: Vec<f64>,
}

/// Interpolation weights of one point on one axis: node `start + k` has
/// weight `w[k]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stencil {
    /// First node.
    pub start: usize,
    /// Number of nodes used.
    pub len: usize,
    /// Weights (the first `len` are used).
    pub w: [f64; MAX_STENCIL],
}

impl Default for PolarGrid {
    fn default() -> Self {
        Self::graded(DEFAULT_NODES).expect("default grid")
    }
}

impl PolarGrid {
    /// `n ≥ 2` nodes uniform in `s`: `θ_k = 90° sin(π k / (2(n − 1)))`,
    /// `k = 0..n` (includes `θ = 0` and `θ = 90°`).
    pub fn graded(n: usize) -> Result<Self, String> {
        if n < 2 {
            return Err(format!("a polar grid needs at least 2 nodes, got {n}"));
        }
        let theta = (0..n)
            .map(|k| {
                if k + 1 == n {
                    90.0
                } else {
                    theta_deg_of_s(k as f64 / (n - 1) as f64)
                }
            })
            .collect();
        Self::from_theta_deg(theta)
    }

    /// A grid from explicit polar angles (strictly increasing, in `[0, 90]`,
    /// distinct cosines after the floor).
    pub fn from_theta_deg(theta_deg: Vec<f64>) -> Result<Self, String> {
        if theta_deg.len() < 2 {
            return Err("a polar grid needs at least 2 nodes".into());
        }
        for (k, &t) in theta_deg.iter().enumerate() {
            if !(t.is_finite() && (0.0..=90.0).contains(&t)) {
                return Err(format!("theta_deg[{k}] = {t} is outside [0, 90]"));
            }
            if k > 0 && t <= theta_deg[k - 1] {
                return Err(format!("theta_deg[{k}] = {t} is not increasing"));
            }
        }
        let mu: Vec<f64> = theta_deg.iter().map(|&t| mu_of_theta_deg(t)).collect();
        if mu.windows(2).any(|w| w[1] >= w[0]) {
            return Err("two polar nodes share a cosine (after the horizon floor)".into());
        }
        let s = theta_deg.iter().map(|&t| s_of_theta_deg(t)).collect();
        Ok(Self { theta_deg, mu, s })
    }

    /// Where the interpolation error of a table on this grid is measured:
    /// halfway (in `s`) between consecutive nodes, where the Lagrange
    /// remainder of a smooth function peaks, and more densely in the two
    /// intervals next to the horizon, where the BRDF is least smooth
    /// (`μ ln μ` terms; a semi-infinite Rayleigh layer on 8 nodes errs
    /// most within 0.2° of the horizon, over 4× its error at the last
    /// midpoint, 89.4°): the quarter points of both, and 0.9, 0.97 and
    /// 0.99 of the last (in `s`).
    pub fn probe_theta_deg(&self) -> Vec<f64> {
        let n = self.len();
        let mut probes = Vec::new();
        for (k, w) in self.s.windows(2).enumerate() {
            let fractions: &[f64] = if k + 2 == n {
                &[0.25, 0.5, 0.75, 0.9, 0.97, 0.99]
            } else if k + 3 == n {
                &[0.25, 0.5, 0.75]
            } else {
                &[0.5]
            };
            probes.extend(
                fractions
                    .iter()
                    .map(|t| theta_deg_of_s(w[0] + t * (w[1] - w[0]))),
            );
        }
        probes
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.theta_deg.len()
    }

    /// Always false (a grid has ≥ 2 nodes).
    pub fn is_empty(&self) -> bool {
        self.theta_deg.is_empty()
    }

    /// Lagrange weights at polar angle `theta_deg` (clamped to the grid):
    /// `w_k = Π_{j≠k} (s − s_j)/(s_k − s_j)` over the `STENCIL` nodes
    /// nearest to `s(θ)` (centred on the enclosing interval, shifted inwards
    /// at the ends). At a node the weights are exactly `(…, 0, 1, 0, …)`.
    pub fn stencil(&self, theta_deg: f64) -> Stencil {
        self.stencil_of_size(theta_deg, STENCIL)
    }

    /// [`PolarGrid::stencil`] with `size` nodes (`1..=MAX_STENCIL`, capped
    /// at the number of nodes): degree `size − 1`.
    pub fn stencil_of_size(&self, theta_deg: f64, size: usize) -> Stencil {
        let n = self.len();
        let k = size.clamp(1, MAX_STENCIL).min(n);
        let t = theta_deg.clamp(self.theta_deg[0], self.theta_deg[n - 1]);
        let s = s_of_theta_deg(t);
        // Enclosing interval [j, j+1].
        let j = match self.theta_deg.iter().position(|&x| x > t) {
            Some(p) => p.saturating_sub(1),
            None => n - 2,
        };
        let start = (j + 1).saturating_sub(k / 2).min(n - k);
        let mut w = [0.0; MAX_STENCIL];
        if let Some(hit) = (start..start + k).find(|&i| self.theta_deg[i] == t) {
            w[hit - start] = 1.0;
            return Stencil { start, len: k, w };
        }
        for (a, wa) in w.iter_mut().enumerate().take(k) {
            let sa = self.s[start + a];
            let mut v = 1.0;
            for b in 0..k {
                if b != a {
                    let sb = self.s[start + b];
                    v *= (s - sb) / (sa - sb);
                }
            }
            *wa = v;
        }
        Stencil { start, len: k, w }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn graded_grid_has_the_ends_and_is_uniform_in_s() {
        let g = PolarGrid::graded(11).unwrap();
        assert_eq!(g.theta_deg[0], 0.0);
        assert_eq!(g.theta_deg[10], 90.0);
        for k in 0..11 {
            assert!((g.s[k] - k as f64 / 10.0).abs() < 1e-12);
        }
        assert!(PolarGrid::from_theta_deg(vec![0.0, 50.0, 40.0]).is_err());
        assert!(PolarGrid::from_theta_deg(vec![0.0, 91.0]).is_err());
    }

    /// Lagrange weights of degree K−1 reproduce polynomials of that degree
    /// in `s` exactly, and are a partition of unity.
    #[test]
    fn stencil_reproduces_polynomials_in_s() {
        let g = PolarGrid::graded(20).unwrap();
        let p = |s: f64| 0.3 - 1.7 * s + 2.0 * s.powi(3) + 0.5 * s.powi(STENCIL as i32 - 1);
        for t in [0.0, 0.3, 7.7, 45.0, 80.1, 89.99, 90.0] {
            let st = g.stencil(t);
            let v: f64 = (0..st.len).map(|k| st.w[k] * p(g.s[st.start + k])).sum();
            assert!((v - p(s_of_theta_deg(t))).abs() < 1e-12, "{t}");
            let sum: f64 = st.w[..st.len].iter().sum();
            assert!((sum - 1.0).abs() < 1e-12);
        }
        let st = g.stencil(g.theta_deg[7]);
        assert_eq!(st.w[7 - st.start], 1.0);
        assert_eq!(st.w.iter().filter(|&&w| w != 0.0).count(), 1);
    }
}
