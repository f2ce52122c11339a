//! Expansion of the scattering matrix in generalized spherical functions
//! (Greek coefficients), conventions §4.
//!
//! With the Wigner functions `d^l_{mn}` of [`super::wigner`] (conventions §4
//! anchors) and `μ = cos Θ`, the six series are (Siewert / VLIDORT sign
//! convention, seed eq. 22):
//!
//! ```text
//! a1      = Σ β_l d^l_00          a4      = Σ δ_l d^l_00
//! a2 + a3 = Σ (α_l + ζ_l) d^l_22  a2 − a3 = Σ (α_l − ζ_l) d^l_{2,−2}
//! b1      = Σ γ_l d^l_02          b2      = −Σ ε_l d^l_02
//! ```
//!
//! (`b2` with a minus sign: conventions §4 derives it from the published
//! de Rooij & van der Stap ↔ Siewert conversion, which negates both `γ` and
//! `ε`, and from `b2 = c Im(S2 S1*)` in our frames.)
//!
//! By the orthogonality `∫_{−1}^{1} d^l_{mn} d^{l'}_{mn} dμ = 2/(2l+1) δ_{ll'}`
//! the coefficients are the projections
//!
//! ```text
//! β_l = (2l+1)/2 ∫ a1 d^l_00 dμ,            δ_l = (2l+1)/2 ∫ a4 d^l_00 dμ,
//! α_l ± ζ_l = (2l+1)/2 ∫ (a2 ± a3) d^l_{2,±2} dμ,
//! γ_l = (2l+1)/2 ∫ b1 d^l_02 dμ,            ε_l = −(2l+1)/2 ∫ b2 d^l_02 dμ,
//! ```
//!
//! evaluated by Gauss–Legendre quadrature in [`expand`]; [`expand_adaptive`]
//! chooses the number of nodes and terms. The normalisation of conventions §3
//! (`½ ∫ a1 dμ = 1`) is `β_0 = 1`.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::quadrature::gauss_legendre;
use super::wigner::wigner_d_into;
use super::{PhysicsError, ScatteringMatrixSamples};

/// Greek (generalized-spherical-function) expansion coefficients of the
/// scattering matrix, `l = 0 ..= L`, in the Siewert / VLIDORT convention of
/// conventions §4 (module documentation). All six vectors have the same
/// length `L + 1`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GreekCoefficients {
    /// `β_l`: `a1 = Σ β_l d^l_00` (`β_0 = 1` for a normalised matrix).
    pub beta: Vec<f64>,
    /// `α_l`: `a2 ± a3 = Σ (α_l ± ζ_l) d^l_{2,±2}`.
    pub alpha: Vec<f64>,
    /// `ζ_l`: see `alpha`.
    pub zeta: Vec<f64>,
    /// `δ_l`: `a4 = Σ δ_l d^l_00`.
    pub delta: Vec<f64>,
    /// `γ_l`: `b1 = Σ γ_l d^l_02` (Rayleigh: `γ_2 = −√6/2`).
    pub gamma: Vec<f64>,
    /// `ε_l`: `b2 = −Σ ε_l d^l_02` (conventions §4; de Rooij's `β_2^l = −ε_l`).
    pub epsilon: Vec<f64>,
}

/// What [`expand_adaptive`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExpansionReport {
    /// Number of coefficients kept, `L + 1`.
    pub n_terms: usize,
    /// Number of Gauss–Legendre nodes of the final projection.
    pub n_nodes: usize,
    /// Largest change of any coefficient (relative to `β_0`) between the
    /// final projection and the previous one with fewer nodes.
    pub projection_change: f64,
    /// Number of points of the round-trip check grid (uniform in `Θ`,
    /// including `Θ = 0` and `π`).
    pub n_check_points: usize,
    /// Largest deviation of the summed series from the sampler over the six
    /// functions and the check grid, relative to `max a1` on that grid.
    pub round_trip_error: f64,
}

impl GreekCoefficients {
    /// All-zero coefficients for `l = 0 .. n_terms − 1`.
    pub fn zeros(n_terms: usize) -> Self {
        Self {
            beta: vec![0.0; n_terms],
            alpha: vec![0.0; n_terms],
            zeta: vec![0.0; n_terms],
            delta: vec![0.0; n_terms],
            gamma: vec![0.0; n_terms],
            epsilon: vec![0.0; n_terms],
        }
    }

    /// Number of coefficients per series, `L + 1`.
    pub fn len(&self) -> usize {
        self.beta.len()
    }

    /// `true` if there are no coefficients at all.
    pub fn is_empty(&self) -> bool {
        self.beta.is_empty()
    }

    /// The six series in the order `beta, alpha, zeta, delta, gamma, epsilon`.
    pub fn series(&self) -> [&[f64]; 6] {
        [
            &self.beta,
            &self.alpha,
            &self.zeta,
            &self.delta,
            &self.gamma,
            &self.epsilon,
        ]
    }

    /// Rayleigh–Cabannes scattering with depolarization factor `ρ`
    /// (`depolarization`), Hansen & Travis 1974 (Space Sci. Rev. 16, 527),
    /// eqs. 2.15–2.16: with `Δ = (1−ρ)/(1+ρ/2)`, `Δ' = (1−2ρ)/(1−ρ)`,
    /// `F = Δ F_Rayleigh + (1−Δ) diag(1,0,0,0)` except `F44 = Δ Δ' (3/2) μ`;
    /// i.e. `β_0 = 1`, `β_2 = (1−ρ)/(2+ρ)`, `α_2 = 6(1−ρ)/(2+ρ)`,
    /// `γ_2 = −√6 (1−ρ)/(2+ρ)`, `δ_1 = 3(1−2ρ)/(2+ρ)`, all others zero (the
    /// values used by VLIDORT). `ρ = 0`: `β_2 = ½`, `α_2 = 3`, `δ_1 = 3/2`,
    /// `γ_2 = −√6/2`. `L = 2`.
    ///
    /// # Panics
    /// If `ρ` is not in `[0, 6/7]` (see [`Self::try_rayleigh`]).
    pub fn rayleigh(depolarization: f64) -> Self {
        match Self::try_rayleigh(depolarization) {
            Ok(c) => c,
            Err(e) => panic!("{e}"),
        }
    }

    /// [`Self::rayleigh`], with an error instead of a panic for `ρ` outside
    /// `[0, 6/7]` (the range of the depolarization factor for natural light).
    pub fn try_rayleigh(depolarization: f64) -> Result<Self, PhysicsError> {
        let rho = depolarization;
        if !(0.0..=6.0 / 7.0).contains(&rho) {
            return Err(PhysicsError::OutOfRange {
                name: "depolarization",
                value: rho,
                range: "[0, 6/7]".into(),
            });
        }
        let mut c = Self::zeros(3);
        let f = (1.0 - rho) / (2.0 + rho);
        c.beta[0] = 1.0;
        c.beta[2] = f;
        c.alpha[2] = 6.0 * f;
        c.gamma[2] = -6f64.sqrt() * f;
        c.delta[1] = 3.0 * (1.0 - 2.0 * rho) / (2.0 + rho);
        Ok(c)
    }

    /// Henyey–Greenstein phase function with asymmetry `g` as a scalar
    /// scatterer: `β_l = (2l+1) g^l`, `l = 0 ..= l_max`, all other series zero.
    pub fn henyey_greenstein(g: f64, l_max: usize) -> Self {
        let mut c = Self::zeros(l_max + 1);
        let mut gl = 1.0;
        for (l, b) in c.beta.iter_mut().enumerate() {
            *b = (2 * l + 1) as f64 * gl;
            gl *= g;
        }
        c
    }

    /// Sums the series at the scattering-angle cosines `mu`, giving
    /// `a1, a2, a3, a4, b1, b2` (conventions §3). Cost `O(len · mu.len())`,
    /// parallel over `mu` (one angle: [`GreekCoefficients::evaluate_at`]).
    pub fn evaluate(&self, mu: &[f64]) -> ScatteringMatrixSamples {
        let rows: Vec<[f64; 6]> = mu
            .par_iter()
            .map_init(
                || vec![0.0; self.len()],
                |buf, &x| self.evaluate_with(x, buf),
            )
            .collect();
        let col = |k: usize| rows.iter().map(|r| r[k]).collect::<Vec<f64>>();
        ScatteringMatrixSamples {
            mu: mu.to_vec(),
            a1: col(0),
            a2: col(1),
            a3: col(2),
            a4: col(3),
            b1: col(4),
            b2: col(5),
        }
    }

    /// `[a1, a2, a3, a4, b1, b2]` at one scattering-angle cosine: the
    /// serial kernel of [`GreekCoefficients::evaluate`], for callers that
    /// sum the series at one angle at a time (the single-scattering
    /// correction at each direction pair, `solver::truncation`).
    pub fn evaluate_at(&self, x: f64) -> [f64; 6] {
        self.evaluate_with(x, &mut vec![0.0; self.len()])
    }

    /// `Σ_t w_t [a1, a2, a3, a4, b1, b2]_t` at one scattering-angle cosine
    /// for several coefficient sets with weights, on one set of Wigner
    /// functions (those of the longest series; a shorter one uses its
    /// first terms, the same values). `polarized = false`: `a1` only, the
    /// rest zero.
    pub fn weighted_sum_at(
        sets: &[(&GreekCoefficients, f64)],
        x: f64,
        polarized: bool,
    ) -> [f64; 6] {
        let n = sets.iter().map(|(c, _)| c.len()).max().unwrap_or(0);
        let mut buf = vec![0.0; n];
        let mut out = [0.0; 6];
        let mut add = |k: usize, buf: &[f64], f: &dyn Fn(&GreekCoefficients, &[f64]) -> f64| {
            for (c, w) in sets {
                out[k] += w * f(c, &buf[..c.len()]);
            }
        };
        wigner_d_into(0, 0, x, &mut buf);
        add(0, &buf, &|c, d| dot(&c.beta, d));
        if !polarized {
            return out;
        }
        add(3, &buf, &|c, d| dot(&c.delta, d));
        wigner_d_into(2, 2, x, &mut buf);
        let plus = |c: &GreekCoefficients, d: &[f64]| -> f64 {
            (0..d.len()).map(|l| (c.alpha[l] + c.zeta[l]) * d[l]).sum()
        };
        add(1, &buf, &|c, d| 0.5 * plus(c, d));
        add(2, &buf, &|c, d| 0.5 * plus(c, d));
        wigner_d_into(2, -2, x, &mut buf);
        let minus = |c: &GreekCoefficients, d: &[f64]| -> f64 {
            (0..d.len()).map(|l| (c.alpha[l] - c.zeta[l]) * d[l]).sum()
        };
        add(1, &buf, &|c, d| 0.5 * minus(c, d));
        add(2, &buf, &|c, d| -0.5 * minus(c, d));
        wigner_d_into(0, 2, x, &mut buf);
        add(4, &buf, &|c, d| dot(&c.gamma, d));
        add(5, &buf, &|c, d| -dot(&c.epsilon, d));
        out
    }

    /// [`GreekCoefficients::evaluate_at`] with a scratch buffer of
    /// `self.len()` values: `a2, a3` from `α ± ζ` on `d^l_{2,±2}`
    /// (conventions §3), `b2 = −Σ ε_l d^l_02` (the Siewert sign, §4).
    fn evaluate_with(&self, x: f64, buf: &mut [f64]) -> [f64; 6] {
        let (alpha, zeta) = (&self.alpha, &self.zeta);
        wigner_d_into(0, 0, x, buf);
        let a1 = dot(&self.beta, buf);
        let a4 = dot(&self.delta, buf);
        wigner_d_into(2, 2, x, buf);
        let plus: f64 = (0..buf.len()).map(|l| (alpha[l] + zeta[l]) * buf[l]).sum();
        wigner_d_into(2, -2, x, buf);
        let minus: f64 = (0..buf.len()).map(|l| (alpha[l] - zeta[l]) * buf[l]).sum();
        wigner_d_into(0, 2, x, buf);
        let b1 = dot(&self.gamma, buf);
        let b2 = -dot(&self.epsilon, buf);
        [a1, 0.5 * (plus + minus), 0.5 * (plus - minus), a4, b1, b2]
    }

    /// Asymmetry parameter `g = β_1 / 3` (0 if there is no `l = 1` term).
    pub fn asymmetry(&self) -> f64 {
        self.beta.get(1).map_or(0.0, |b| b / 3.0)
    }

    /// The first `l_max + 1` coefficients (all of them if there are fewer).
    pub fn truncated(&self, l_max: usize) -> Self {
        let n = (l_max + 1).min(self.len());
        Self {
            beta: self.beta[..n].to_vec(),
            alpha: self.alpha[..n].to_vec(),
            zeta: self.zeta[..n].to_vec(),
            delta: self.delta[..n].to_vec(),
            gamma: self.gamma[..n].to_vec(),
            epsilon: self.epsilon[..n].to_vec(),
        }
    }
}

fn dot(c: &[f64], d: &[f64]) -> f64 {
    c.iter().zip(d).map(|(a, b)| a * b).sum()
}

/// Checks that the six vectors have the length of `mu` and that all values
/// are finite.
fn validate_samples(s: &ScatteringMatrixSamples) -> Result<(), PhysicsError> {
    let n = s.mu.len();
    for (name, v) in [
        ("a1", &s.a1),
        ("a2", &s.a2),
        ("a3", &s.a3),
        ("a4", &s.a4),
        ("b1", &s.b1),
        ("b2", &s.b2),
    ] {
        if v.len() != n {
            return Err(PhysicsError::Invalid(format!(
                "scattering-matrix samples: {name} has {} values for {n} angles",
                v.len()
            )));
        }
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(PhysicsError::Invalid(format!(
                "scattering-matrix samples: {name}[{i}] = {} at mu = {} is not finite",
                v[i], s.mu[i]
            )));
        }
    }
    Ok(())
}

/// `acc[l] += f[l mod 2] · d[l]`.
fn axpy(acc: &mut [f64], f: [f64; 2], d: &[f64]) {
    if f == [0.0, 0.0] {
        return;
    }
    for (pair_a, pair_d) in acc.chunks_mut(2).zip(d.chunks(2)) {
        for ((a, dl), fk) in pair_a.iter_mut().zip(pair_d).zip(f) {
            *a += fk * dl;
        }
    }
}

/// Number of fixed chunks of the projection sum: the nodes are split into
/// this many contiguous blocks, summed in parallel, and the block sums are
/// added in order, so the result does not depend on the thread count.
const PROJECTION_CHUNKS: usize = 16;

/// Greek coefficients `l = 0 ..= l_max` of the sampled matrix by Gauss
/// quadrature of the projections in the module documentation:
/// `samples.mu` are the quadrature nodes on `[−1, 1]` and `weights` their
/// weights (e.g. from [`gauss_legendre`]). With `n` Gauss nodes, the
/// coefficient `l` is exact if the sampled functions are polynomials (series)
/// of degree `≤ 2n − 1 − l`; in particular `n = l_max + 1` nodes reproduce
/// a series of length `l_max + 1` exactly.
///
/// No normalisation is imposed (`β_0` is whatever `½ ∫ a1 dμ` is).
///
/// # Panics
/// If `weights` or any of the six sample vectors differ in length from
/// `samples.mu`.
pub fn expand(
    samples: &ScatteringMatrixSamples,
    weights: &[f64],
    l_max: usize,
) -> GreekCoefficients {
    let n = samples.mu.len();
    assert_eq!(
        weights.len(),
        n,
        "expand: {} weights for {n} nodes",
        weights.len()
    );
    for (name, v) in [
        ("a1", &samples.a1),
        ("a2", &samples.a2),
        ("a3", &samples.a3),
        ("a4", &samples.a4),
        ("b1", &samples.b1),
        ("b2", &samples.b2),
    ] {
        assert_eq!(
            v.len(),
            n,
            "expand: {name} has {} values for {n} nodes",
            v.len()
        );
    }
    let n_terms = l_max + 1;
    // Symmetric node sets (every Gauss rule from `gauss_legendre`) are
    // processed in pairs (μ, −μ): with d^l_00(−μ) = (−1)^l d^l_00(μ),
    // d^l_02(−μ) = (−1)^l d^l_02(μ) and d^l_{2,−2}(±μ) = (−1)^l d^l_22(∓μ),
    // four recurrences serve both nodes (instead of eight).
    let symmetric = (0..n / 2).all(|i| samples.mu[i] == -samples.mu[n - 1 - i]);
    // Work items: (node, Some(mirror node)) for pairs, (node, None) for singles.
    let items: Vec<(usize, Option<usize>)> = if symmetric {
        let mut v: Vec<_> = (0..n / 2).map(|i| (n - 1 - i, Some(i))).collect();
        if n % 2 == 1 {
            v.push((n / 2, None));
        }
        v
    } else {
        (0..n).map(|i| (i, None)).collect()
    };
    let chunk = items.len().div_ceil(PROJECTION_CHUNKS).max(1);
    // Per block: [β, δ, α+ζ, α−ζ, γ, ε] unnormalised sums.
    let blocks: Vec<[Vec<f64>; 6]> = items
        .par_chunks(chunk)
        .map(|block| {
            let mut acc: [Vec<f64>; 6] = std::array::from_fn(|_| vec![0.0; n_terms]);
            let mut d = vec![0.0; n_terms];
            let mut e = vec![0.0; n_terms];
            let s = samples;
            for &(j, mirror) in block {
                let x = s.mu[j];
                let wj = weights[j];
                match mirror {
                    None => {
                        wigner_d_into(0, 0, x, &mut d);
                        axpy(&mut acc[0], [wj * s.a1[j]; 2], &d);
                        axpy(&mut acc[1], [wj * s.a4[j]; 2], &d);
                        wigner_d_into(2, 2, x, &mut d);
                        axpy(&mut acc[2], [wj * (s.a2[j] + s.a3[j]); 2], &d);
                        wigner_d_into(2, -2, x, &mut d);
                        axpy(&mut acc[3], [wj * (s.a2[j] - s.a3[j]); 2], &d);
                        wigner_d_into(0, 2, x, &mut d);
                        axpy(&mut acc[4], [wj * s.b1[j]; 2], &d);
                        axpy(&mut acc[5], [wj * s.b2[j]; 2], &d);
                    }
                    Some(i) => {
                        let wi = weights[i];
                        // [even l, odd l] coefficients of f(μ) + f(−μ) (−1)^l
                        let even_odd = |fj: f64, fi: f64| [wj * fj + wi * fi, wj * fj - wi * fi];
                        wigner_d_into(0, 0, x, &mut d);
                        axpy(&mut acc[0], even_odd(s.a1[j], s.a1[i]), &d);
                        axpy(&mut acc[1], even_odd(s.a4[j], s.a4[i]), &d);
                        // D = d_22(μ), E = d_22(−μ):
                        // (α+ζ): w_j p_j D + w_i p_i E;  (α−ζ): (−1)^l (w_j q_j E + w_i q_i D)
                        let (pj, pi) = (s.a2[j] + s.a3[j], s.a2[i] + s.a3[i]);
                        let (qj, qi) = (s.a2[j] - s.a3[j], s.a2[i] - s.a3[i]);
                        wigner_d_into(2, 2, x, &mut d);
                        wigner_d_into(2, 2, -x, &mut e);
                        axpy(&mut acc[2], [wj * pj; 2], &d);
                        axpy(&mut acc[2], [wi * pi; 2], &e);
                        axpy(&mut acc[3], [wj * qj, -wj * qj], &e);
                        axpy(&mut acc[3], [wi * qi, -wi * qi], &d);
                        wigner_d_into(0, 2, x, &mut d);
                        axpy(&mut acc[4], even_odd(s.b1[j], s.b1[i]), &d);
                        axpy(&mut acc[5], even_odd(s.b2[j], s.b2[i]), &d);
                    }
                }
            }
            acc
        })
        .collect();
    let mut sums: [Vec<f64>; 6] = std::array::from_fn(|_| vec![0.0; n_terms]);
    for block in &blocks {
        for (s, b) in sums.iter_mut().zip(block) {
            for (x, y) in s.iter_mut().zip(b) {
                *x += y;
            }
        }
    }
    let norm = |l: usize| (2 * l + 1) as f64 / 2.0;
    let project =
        |sum: &[f64]| -> Vec<f64> { sum.iter().enumerate().map(|(l, v)| norm(l) * v).collect() };
    let plus = project(&sums[2]);
    let minus = project(&sums[3]);
    GreekCoefficients {
        beta: project(&sums[0]),
        alpha: plus
            .iter()
            .zip(&minus)
            .map(|(p, m)| 0.5 * (p + m))
            .collect(),
        zeta: plus
            .iter()
            .zip(&minus)
            .map(|(p, m)| 0.5 * (p - m))
            .collect(),
        delta: project(&sums[1]),
        gamma: project(&sums[4]),
        epsilon: project(&sums[5]).into_iter().map(|v| -v).collect(),
    }
}

/// Largest number of Gauss nodes [`expand_adaptive`] will use.
pub const MAX_ADAPTIVE_NODES: usize = 100_000;

/// Greek coefficients with automatically chosen quadrature and truncation.
///
/// `sampler(mu)` returns the scattering matrix at the given cosines (any
/// order; it is called with Gauss nodes and with the check grid). Starting
/// from `max(l_hint + 1, 16)` nodes, the number of nodes `n` grows by 3/2
/// until
///
/// 1. the projection has converged: every coefficient `l < n_prev` changes by
///    at most `tolerance · |β_0|` from the previous projection (`n_prev`
///    nodes) to this one;
/// 2. the series has a tail: the last `l` at which any of the six series
///    exceeds `tolerance · |β_0|` (the truncation point `L`) is below
///    `n_prev − 1`, so the kept terms are all converged; terms above `L` are
///    dropped;
/// 3. the truncated series summed on a check grid (`2L + 65` points uniform
///    in `Θ`, including `Θ = 0, π`) reproduces all six functions from the
///    sampler to `tolerance · max a1`. If it does not, the truncation
///    threshold is lowered (÷10, up to three times) before growing `n`.
///
/// For Mie scattering at size parameter `x`, `l_hint ≈ 2x + 10` is a good
/// start (the number of terms needed is about `2 (x + 4 x^{1/3} + 2)`).
///
/// The attainable tolerance is limited by round-off: the Gauss nodes are
/// doubles, so near a steep forward peak `1 − μ` of a node carries a relative
/// error `~ε/(1 − μ)` and the sampled value a corresponding error. Measured
/// floors (relative to `β_0`): Henyey–Greenstein `g = 0.9`: `< 1e-12`;
/// `g = 0.99` (`max a1 ≈ 2e4`, like Mie at `x ≈ 100`): `7.5e-9`;
/// `g = 0.998` (`max a1 ≈ 5e5`): `1e-6`. Below the floor the projection
/// stalls and an error naming the attainable level is returned.
///
/// # Errors
/// `tolerance` not in `(0, 1)`; a sampler error or malformed / non-finite
/// samples; the projection stalling above `tolerance` (round-off floor,
/// reported as `OutOfRange` with the attainable level); no convergence
/// within [`MAX_ADAPTIVE_NODES`] nodes.
pub fn expand_adaptive(
    sampler: impl Fn(&[f64]) -> Result<ScatteringMatrixSamples, PhysicsError>,
    l_hint: usize,
    tolerance: f64,
) -> Result<(GreekCoefficients, ExpansionReport), PhysicsError> {
    if !(tolerance > 0.0 && tolerance < 1.0) {
        return Err(PhysicsError::OutOfRange {
            name: "tolerance",
            value: tolerance,
            range: "(0, 1)".into(),
        });
    }
    let sample = |mu: &[f64]| -> Result<ScatteringMatrixSamples, PhysicsError> {
        let s = sampler(mu)?;
        if s.mu.len() != mu.len() {
            return Err(PhysicsError::Invalid(format!(
                "sampler returned {} angles for {} requested",
                s.mu.len(),
                mu.len()
            )));
        }
        validate_samples(&s)?;
        Ok(s)
    };

    let mut n = (l_hint.saturating_add(1)).clamp(16, MAX_ADAPTIVE_NODES);
    let mut prev: Option<GreekCoefficients> = None;
    let mut last_change = f64::INFINITY;
    loop {
        let (x, w) = gauss_legendre(n);
        let samples = sample(&x)?;
        let coeffs = expand(&samples, &w, n - 1);
        let beta0 = coeffs.beta[0].abs();
        if beta0 == 0.0 || !beta0.is_finite() {
            return Err(PhysicsError::Invalid(format!(
                "expand_adaptive: beta_0 = {} (the phase function a1 integrates to zero)",
                coeffs.beta[0]
            )));
        }
        if let Some(p) = &prev {
            let change = max_change(&coeffs, p) / beta0;
            // Round-off floor: the change is small against the coefficients
            // and no longer decreases, although all coefficients above 10×
            // the change fit well inside the previous projection (so more
            // nodes cannot help).
            let l_sig = last_significant(&coeffs, 10.0 * change * beta0);
            let largest = coeffs
                .series()
                .iter()
                .flat_map(|s| s.iter())
                .fold(0.0f64, |m, v| m.max(v.abs()));
            if change > tolerance
                && change * beta0 < 1e-4 * largest
                && change > 0.5 * last_change
                && 2 * (l_sig + 1) < p.len()
            {
                return Err(PhysicsError::OutOfRange {
                    name: "tolerance",
                    value: tolerance,
                    range: format!(
                        "[{change:.1e}, 1): the projection stalls at that level \
                         (round-off of the sampled functions)"
                    ),
                });
            }
            last_change = change;
            if change <= tolerance {
                let mut threshold = tolerance;
                for _ in 0..4 {
                    let l_cut = last_significant(&coeffs, threshold * beta0);
                    if l_cut + 1 >= p.len() {
                        break; // tail not inside the converged range
                    }
                    let kept = coeffs.truncated(l_cut);
                    let (err, n_check) = round_trip_error(&kept, &sample)?;
                    if err <= tolerance {
                        let report = ExpansionReport {
                            n_terms: kept.len(),
                            n_nodes: n,
                            projection_change: change,
                            n_check_points: n_check,
                            round_trip_error: err,
                        };
                        return Ok((kept, report));
                    }
                    threshold /= 10.0;
                }
            }
        }
        if n >= MAX_ADAPTIVE_NODES {
            return Err(PhysicsError::Invalid(format!(
                "expand_adaptive: no convergence to tolerance {tolerance:e} with \
                 {MAX_ADAPTIVE_NODES} Gauss nodes"
            )));
        }
        prev = Some(coeffs);
        n = (n + n / 2).min(MAX_ADAPTIVE_NODES);
    }
}

/// Largest absolute difference of any coefficient over the common range.
fn max_change(a: &GreekCoefficients, b: &GreekCoefficients) -> f64 {
    let mut m: f64 = 0.0;
    for (sa, sb) in a.series().iter().zip(b.series()) {
        for (x, y) in sa.iter().zip(sb) {
            m = m.max((x - y).abs());
        }
    }
    m
}

/// Last `l` at which any series exceeds `threshold` in magnitude (0 if none).
fn last_significant(c: &GreekCoefficients, threshold: f64) -> usize {
    (0..c.len())
        .rev()
        .find(|&l| c.series().iter().any(|s| s[l].abs() > threshold))
        .unwrap_or(0)
}

/// Round trip on a grid uniform in `Θ` with `2 len + 65` points including
/// both ends: `(max deviation / max a1, number of points)`.
fn round_trip_error(
    c: &GreekCoefficients,
    sample: &impl Fn(&[f64]) -> Result<ScatteringMatrixSamples, PhysicsError>,
) -> Result<(f64, usize), PhysicsError> {
    let m = 2 * c.len() + 65;
    let mu: Vec<f64> = (0..m)
        .map(|j| {
            if j == 0 {
                1.0
            } else if j == m - 1 {
                -1.0
            } else {
                (std::f64::consts::PI * j as f64 / (m - 1) as f64).cos()
            }
        })
        .collect();
    let reference = sample(&mu)?;
    let series = c.evaluate(&mu);
    let scale = reference.a1.iter().fold(0.0f64, |a, &v| a.max(v.abs()));
    let mut err: f64 = 0.0;
    for (r, s) in [
        (&reference.a1, &series.a1),
        (&reference.a2, &series.a2),
        (&reference.a3, &series.a3),
        (&reference.a4, &series.a4),
        (&reference.b1, &series.b1),
        (&reference.b2, &series.b2),
    ] {
        for (x, y) in r.iter().zip(s) {
            err = err.max((x - y).abs());
        }
    }
    Ok((err / scale, m))
}

#[cfg(test)]
mod tests {
    use super::test_data::garcia_siewert;
    use super::*;
    use std::f64::consts::PI;

    fn rayleigh_matrix(mu: &[f64]) -> ScatteringMatrixSamples {
        ScatteringMatrixSamples {
            mu: mu.to_vec(),
            a1: mu.iter().map(|m| 0.75 * (1.0 + m * m)).collect(),
            a2: mu.iter().map(|m| 0.75 * (1.0 + m * m)).collect(),
            a3: mu.iter().map(|m| 1.5 * m).collect(),
            a4: mu.iter().map(|m| 1.5 * m).collect(),
            b1: mu.iter().map(|m| -0.75 * (1.0 - m * m)).collect(),
            b2: vec![0.0; mu.len()],
        }
    }

    /// Hansen & Travis 1974 eq. 2.15 with depolarization factor `rho`.
    fn rayleigh_cabannes_matrix(mu: &[f64], rho: f64) -> ScatteringMatrixSamples {
        let d = (1.0 - rho) / (1.0 + 0.5 * rho);
        let dp = (1.0 - 2.0 * rho) / (1.0 - rho);
        let r = rayleigh_matrix(mu);
        ScatteringMatrixSamples {
            mu: mu.to_vec(),
            a1: r.a1.iter().map(|v| d * v + (1.0 - d)).collect(),
            a2: r.a2.iter().map(|v| d * v).collect(),
            a3: r.a3.iter().map(|v| d * v).collect(),
            a4: r.a4.iter().map(|v| d * dp * v).collect(),
            b1: r.b1.iter().map(|v| d * v).collect(),
            b2: vec![0.0; mu.len()],
        }
    }

    fn max_coeff_diff(a: &GreekCoefficients, b: &GreekCoefficients) -> f64 {
        assert_eq!(a.len(), b.len());
        max_change(a, b)
    }

    /// The one-angle kernels are the vector evaluation at each angle, and a
    /// weighted sum of sets of different lengths on shared Wigner functions
    /// is the sum of their evaluations.
    #[test]
    fn one_angle_and_weighted_sums_equal_the_vector_evaluation() {
        let a = test_data::garcia_siewert();
        let b = GreekCoefficients::henyey_greenstein(0.7, 40);
        let x = [-1.0, -0.93, -0.2, 0.0, 0.31, 0.77, 0.999, 1.0];
        let (sa, sb) = (a.evaluate(&x), b.evaluate(&x));
        let six = |s: &ScatteringMatrixSamples, k: usize| {
            [s.a1[k], s.a2[k], s.a3[k], s.a4[k], s.b1[k], s.b2[k]]
        };
        for (k, &xk) in x.iter().enumerate() {
            assert_eq!(a.evaluate_at(xk), six(&sa, k));
            let w = GreekCoefficients::weighted_sum_at(&[(&a, 0.3), (&b, -1.7)], xk, true);
            let scalar = GreekCoefficients::weighted_sum_at(&[(&a, 0.3), (&b, -1.7)], xk, false);
            let (ea, eb) = (six(&sa, k), six(&sb, k));
            for e in 0..6 {
                let want = 0.3 * ea[e] - 1.7 * eb[e];
                assert!(
                    (w[e] - want).abs() <= 1e-14 * (1.0 + want.abs()),
                    "{xk} {e}"
                );
            }
            assert_eq!(scalar[0], w[0]);
            assert_eq!(scalar[1..], [0.0; 5]);
        }
    }

    #[test]
    fn rayleigh_from_sampled_matrix() {
        for n in [3usize, 10, 41] {
            let (x, w) = gauss_legendre(n);
            let c = expand(&rayleigh_matrix(&x), &w, n - 1);
            let mut expect = GreekCoefficients::zeros(n);
            expect.beta[0] = 1.0;
            expect.beta[2] = 0.5;
            expect.alpha[2] = 3.0;
            expect.delta[1] = 1.5;
            expect.gamma[2] = -6f64.sqrt() / 2.0;
            let diff = max_coeff_diff(&c, &expect);
            assert!(diff < 1e-13, "n={n}: max deviation {diff:e}\n{c:?}");
            let r = GreekCoefficients::rayleigh(0.0);
            assert!(max_coeff_diff(&c.truncated(2), &r) < 1e-13);
        }
        let r = GreekCoefficients::rayleigh(0.0);
        assert_eq!(r.len(), 3);
        assert_eq!(r.gamma[2], -6f64.sqrt() / 2.0);
        assert_eq!(r.asymmetry(), 0.0);
    }

    #[test]
    fn rayleigh_with_depolarization() {
        let (x, w) = gauss_legendre(8);
        for rho in [0.0, 0.0279, 0.1, 0.5, 6.0 / 7.0] {
            let c = GreekCoefficients::rayleigh(rho);
            let e = expand(&rayleigh_cabannes_matrix(&x, rho), &w, 2);
            assert!(max_coeff_diff(&c, &e) < 1e-14, "rho={rho}");
            // and the forward direction: evaluate reproduces the matrix
            let mu: Vec<f64> = (0..=20).map(|i| -1.0 + 0.1 * f64::from(i)).collect();
            let s = c.evaluate(&mu);
            let r = rayleigh_cabannes_matrix(&mu, rho);
            for (a, b) in [
                (&s.a1, &r.a1),
                (&s.a2, &r.a2),
                (&s.a3, &r.a3),
                (&s.a4, &r.a4),
                (&s.b1, &r.b1),
                (&s.b2, &r.b2),
            ] {
                for (p, q) in a.iter().zip(b) {
                    assert!((p - q).abs() < 1e-14, "rho={rho}");
                }
            }
        }
        assert!(GreekCoefficients::try_rayleigh(-0.1).is_err());
        assert!(GreekCoefficients::try_rayleigh(0.9).is_err());
        assert!(GreekCoefficients::try_rayleigh(f64::NAN).is_err());
    }

    #[test]
    fn henyey_greenstein_round_trip() {
        let g = 0.9;
        let l_max = 400; // (2l+1) g^l ≈ 4e-16 at l = 400
        let c = GreekCoefficients::henyey_greenstein(g, l_max);
        assert!((c.asymmetry() - g).abs() < 1e-15);
        // the series sums to the closed form
        let mu: Vec<f64> = (0..=50).map(|i| (PI * f64::from(i) / 50.0).cos()).collect();
        let s = c.evaluate(&mu);
        for (m, a1) in mu.iter().zip(&s.a1) {
            let exact = (1.0 - g * g) / (1.0 + g * g - 2.0 * g * m).powf(1.5);
            assert!(
                (a1 - exact).abs() < 1e-12 * exact.max(1.0),
                "μ={m}: {a1} vs {exact}"
            );
        }
        assert!(s.b1.iter().chain(&s.a2).all(|v| *v == 0.0));
        // coefficients → matrix at Gauss nodes → coefficients
        let (x, w) = gauss_legendre(l_max + 1);
        let back = expand(&c.evaluate(&x), &w, l_max);
        let diff = max_coeff_diff(&back, &c);
        eprintln!("HGRT {diff:e}");
        assert!(diff < 1e-11, "max deviation {diff:e}");
        let rel = back
            .beta
            .iter()
            .zip(&c.beta)
            .take(60)
            .map(|(a, b)| (a / b - 1.0).abs())
            .fold(0.0, f64::max);
        eprintln!("HGRT rel {rel:e}");
        assert!(rel < 1e-11, "relative {rel:e}");
    }

    #[test]
    fn garcia_siewert_round_trip() {
        let c = garcia_siewert();
        for n in [12usize, 13, 40] {
            let (x, w) = gauss_legendre(n);
            let back = expand(&c.evaluate(&x), &w, 11);
            let diff = max_coeff_diff(&back, &c);
            assert!(diff < 1e-14, "n={n}: {diff:e}");
        }
    }

    #[test]
    fn garcia_siewert_physical_values() {
        let c = garcia_siewert();
        assert_eq!(c.beta[0], 1.0);
        assert!((c.asymmetry() - 0.701344).abs() < 1e-6);
        // normalisation: ½ ∫ a1 dμ = 1
        let (x, w) = gauss_legendre(20);
        let s = c.evaluate(&x);
        let norm: f64 = 0.5 * s.a1.iter().zip(&w).map(|(a, wi)| a * wi).sum::<f64>();
        assert!((norm - 1.0).abs() < 1e-14, "½∫a1 = {norm}");
        // README physical check values, 4 decimals
        let checks = [
            (20.0, 6.0461, -0.1700),
            (40.0, 3.0280, -0.3104),
            (60.0, 1.0122, -0.1668),
            (120.0, 0.0984, -0.0055),
        ];
        let mu: Vec<f64> = checks.iter().map(|c| f64::to_radians(c.0).cos()).collect();
        let s = c.evaluate(&mu);
        for (i, &(deg, f11, f12)) in checks.iter().enumerate() {
            assert!(
                (s.a1[i] - f11).abs() <= 5e-5,
                "F11({deg}°) = {} vs {f11}",
                s.a1[i]
            );
            assert!(
                (s.b1[i] - f12).abs() <= 5e-5,
                "F12({deg}°) = {} vs {f12}",
                s.b1[i]
            );
        }
        // fine grid: smooth, non-negative a1 and the matrix inequalities
        let mu: Vec<f64> = (0..=3600)
            .map(|i| (PI * f64::from(i) / 3600.0).cos())
            .collect();
        let s = c.evaluate(&mu);
        let slack = 2e-5; // the coefficients are printed to 6 decimals
        for (i, &m) in mu.iter().enumerate() {
            let a1 = s.a1[i];
            assert!(a1 > 0.0, "a1 < 0 at μ={m}");
            assert!(s.b1[i].abs() <= a1 + slack, "|b1| > a1 at μ={m}");
            assert!(s.a2[i].abs() <= a1 + slack, "|a2| > a1 at μ={m}");
            assert!(s.a3[i].abs() <= a1 + slack, "|a3| > a1 at μ={m}");
            assert!(s.a4[i].abs() <= a1 + slack, "|a4| > a1 at μ={m}");
            assert!(s.b2[i].abs() <= a1 + slack, "|b2| > a1 at μ={m}");
            if i > 0 {
                // smooth: no jumps between neighbouring grid points (Δθ = 0.05°)
                assert!((a1 - s.a1[i - 1]).abs() < 0.01 * a1.max(s.a1[i - 1]) + 1e-3);
            }
        }
    }

    #[test]
    fn adaptive_recovers_finite_series() {
        let c = garcia_siewert();
        let sampler = |mu: &[f64]| Ok(c.evaluate(mu));
        for tol in [1e-8, 1e-12] {
            let (e, report) = expand_adaptive(sampler, 4, tol).unwrap();
            assert_eq!(e.len(), 12, "{report:?}");
            assert!(max_coeff_diff(&e, &c) < 1e-13, "{report:?}");
            assert!(report.round_trip_error < 1e-13, "{report:?}");
        }
        // Rayleigh: exactly three terms
        let (e, report) = expand_adaptive(|mu: &[f64]| Ok(rayleigh_matrix(mu)), 0, 1e-12).unwrap();
        assert_eq!(e.len(), 3, "{report:?}");
        assert!(max_coeff_diff(&e, &GreekCoefficients::rayleigh(0.0)) < 1e-13);
    }

    #[test]
    fn adaptive_henyey_greenstein_closed_form() {
        let g = 0.9;
        let sampler = |mu: &[f64]| {
            // 1 + g² − 2gμ written without cancellation near μ = 1
            let a1: Vec<f64> = mu
                .iter()
                .map(|m| (1.0 - g * g) / ((1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - m)).powf(1.5))
                .collect();
            let z = vec![0.0; mu.len()];
            Ok(ScatteringMatrixSamples {
                mu: mu.to_vec(),
                a1,
                a2: z.clone(),
                a3: z.clone(),
                a4: z.clone(),
                b1: z.clone(),
                b2: z,
            })
        };
        let tol = 1e-10;
        let (e, report) = expand_adaptive(sampler, 20, tol).unwrap();
        // last kept term: (2l+1) g^l > 1e-10 → l ≈ 270
        let l_last = e.len() - 1;
        assert!(
            (2 * l_last + 1) as f64 * g.powi(l_last as i32) > tol,
            "{report:?}"
        );
        assert!(
            (2 * l_last + 3) as f64 * g.powi(l_last as i32 + 1) <= tol,
            "{report:?}"
        );
        for (l, b) in e.beta.iter().enumerate() {
            let exact = (2 * l + 1) as f64 * g.powi(l as i32);
            assert!((b - exact).abs() < 0.1 * tol, "l={l}: {b} vs {exact}");
        }
        assert!(report.round_trip_error <= tol, "{report:?}");
        assert!(report.projection_change <= tol, "{report:?}");
        eprintln!(
            "HGAD {report:?} maxerr {:e}",
            e.beta
                .iter()
                .enumerate()
                .map(|(l, b)| (b - (2 * l + 1) as f64 * g.powi(l as i32)).abs())
                .fold(0.0, f64::max)
        );
    }

    #[test]
    fn adaptive_errors() {
        let ok = |mu: &[f64]| Ok(rayleigh_matrix(mu));
        assert!(expand_adaptive(ok, 10, 0.0).is_err());
        assert!(expand_adaptive(ok, 10, f64::NAN).is_err());
        let bad_len = |mu: &[f64]| {
            let mut s = rayleigh_matrix(mu);
            s.b2.pop();
            Ok(s)
        };
        let e = expand_adaptive(bad_len, 10, 1e-8).unwrap_err();
        assert!(e.to_string().contains("b2"), "{e}");
        let nan = |mu: &[f64]| {
            let mut s = rayleigh_matrix(mu);
            s.a3[0] = f64::NAN;
            Ok(s)
        };
        assert!(expand_adaptive(nan, 10, 1e-8).is_err());
        let failing = |_: &[f64]| -> Result<ScatteringMatrixSamples, PhysicsError> {
            Err(PhysicsError::Invalid("sampler failed".into()))
        };
        assert_eq!(
            expand_adaptive(failing, 10, 1e-8).unwrap_err(),
            PhysicsError::Invalid("sampler failed".into())
        );
    }

    #[test]
    fn truncation_and_serde() {
        let c = garcia_siewert();
        let t = c.truncated(5);
        assert_eq!(t.len(), 6);
        assert_eq!(t.beta[..], c.beta[..6]);
        assert_eq!(c.truncated(100), c);
        let json = serde_json::to_string(&c).unwrap();
        let back: GreekCoefficients = serde_json::from_str(&json).unwrap();
        assert_eq!(back, c);
        assert!(!c.is_empty() && GreekCoefficients::zeros(0).is_empty());
    }

    #[test]
    fn unordered_nodes_match_paired_path() {
        let c = garcia_siewert();
        let (x, w) = gauss_legendre(31);
        // a permutation breaks the (μ, −μ) pairing: single-node path
        let perm: Vec<usize> = (0..31).map(|i| (i * 7) % 31).collect();
        let xs: Vec<f64> = perm.iter().map(|&i| x[i]).collect();
        let ws: Vec<f64> = perm.iter().map(|&i| w[i]).collect();
        let paired = expand(&c.evaluate(&x), &w, 20);
        let single = expand(&c.evaluate(&xs), &ws, 20);
        assert!(max_coeff_diff(&paired, &single) < 1e-14);
        assert!(max_coeff_diff(&paired.truncated(11), &c) < 1e-14);
        // odd number of nodes: middle node μ = 0 handled singly in the paired path
        let (x, w) = gauss_legendre(12);
        assert!(max_coeff_diff(&expand(&c.evaluate(&x), &w, 11), &c) < 1e-14);
    }

    #[test]
    fn adaptive_reports_round_off_floor() {
        // Garcia–Siewert matrix with relative noise 1e-9 on a1 (a stand-in for
        // round-off in a sampler): 1e-13 relative to β_0 is unattainable.
        let c = garcia_siewert();
        let sampler = |mu: &[f64]| {
            let mut s = c.evaluate(mu);
            for (a, m) in s.a1.iter_mut().zip(mu) {
                let noise = ((m * 12_345.678).sin() * 43_758.545_3).fract() - 0.5;
                *a *= 1.0 + 1e-9 * noise;
            }
            Ok(s)
        };
        let t0 = std::time::Instant::now();
        let err = expand_adaptive(sampler, 4, 1e-13).unwrap_err();
        assert!(
            matches!(
                err,
                PhysicsError::OutOfRange {
                    name: "tolerance",
                    ..
                }
            ),
            "{err}"
        );
        assert!(t0.elapsed().as_secs_f64() < 5.0);
        // and a tolerance above the floor works
        let (e, report) = expand_adaptive(sampler, 4, 1e-7).unwrap();
        assert_eq!(e.len(), 12, "{report:?}");
    }
}

/// Published coefficient sets the unit tests of several layers read
/// (vendored in `tests/data/benchmarks`, each with its source and citation).
#[cfg(test)]
pub(crate) mod test_data {
    use super::GreekCoefficients;

    /// The Garcia–Siewert L=13 aerosol (Siewert 2000 Problem IIA), in the
    /// Siewert/VLIDORT sign of conventions §4.
    pub fn garcia_siewert() -> GreekCoefficients {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/data/benchmarks/garcia_siewert_L13_coeffs.json"
        );
        let text = std::fs::read_to_string(path)
            .unwrap_or_else(|e| panic!("vendored benchmark file {path} is unreadable: {e}"));
        let v: serde_json::Value = serde_json::from_str(&text).expect("benchmark JSON parses");
        let get = |name: &str| -> Vec<f64> {
            v["coefficients"][name]
                .as_array()
                .unwrap_or_else(|| panic!("coefficients.{name} missing in {path}"))
                .iter()
                .map(|x| x.as_f64().expect("number"))
                .collect()
        };
        let c = GreekCoefficients {
            beta: get("beta"),
            alpha: get("alpha"),
            zeta: get("zeta"),
            delta: get("delta"),
            gamma: get("gamma"),
            epsilon: get("epsilon"),
        };
        assert!(c.series().iter().all(|s| s.len() == 12));
        c
    }
}
