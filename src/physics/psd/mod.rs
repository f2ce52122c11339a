//! Particle size distributions and size-averaged Mie optics (conventions §1, §3).
//!
//! A [`SizeDistribution`] is a number density `n(r)` per µm of radius,
//! normalised to one particle over `0 < r < ∞`. [`bulk_optics`] returns the
//! number-weighted mean cross sections `⟨C⟩ = ∫ n(r) C(r) dr` (µm² per
//! particle), the albedo `⟨C_sca⟩/⟨C_ext⟩`, the asymmetry parameter
//! `⟨g C_sca⟩/⟨C_sca⟩` and the averaged normalised scattering matrix: the
//! amplitude products `|S1|², |S2|², S2 S1*` are averaged with weight `n(r)`
//! and normalised with `c = 4π / (k² ⟨C_sca⟩)`, `k = 2π n_host/λ`, so that
//! `½∫a1 dμ = 1` exactly as for one sphere.
//!
//! # Truncation
//!
//! The radius integral runs over `[r_min, r_max]`:
//! * `r_min`: a fraction `tail_fraction` of the **r²-weighted** distribution
//!   lies below it. Every cross section grows at least as fast as `r²`
//!   (`r³` absorption and `r⁶` scattering in the Rayleigh regime), so the
//!   relative loss is at most about `tail_fraction`.
//! * `r_max = max(r₄, min(r₆, r(x = 2)))`, where `r₄`, `r₆` leave a fraction
//!   `tail_fraction` of the `r⁴`- and `r⁶`-weighted distributions above them:
//!   `r⁶` is the heaviest weight in the Rayleigh regime (`x ≲ 2`), `r⁴` the
//!   heaviest beyond it (the forward diffraction peak `|S(0)|² ∝ x⁴`; cross
//!   sections and side scattering go as `r²`).
//!
//! The mean cross sections are `∫_{r_min}^{r_max} n C dr` with `n` normalised
//! over the whole axis (no renormalisation of the truncated distribution).
//! Measured effect of the default `tail_fraction = 1e-6` (against 1e-8):
//! ~1e-6 relative on the cross sections, up to ~6e-6 of `a1` on the matrix
//! at back-scattering minima of `⟨S11⟩`, where the tails weigh more.
//!
//! # Quadrature
//!
//! Adaptive Simpson rule in `u = ln r + x(r)/5` (`x = k r`): a step `h` in
//! `u` is at most `Δ ln r = h` for small particles and `Δx = 5h` for large
//! ones. The first level has panels of width `h₀ = 0.1` (nodes every
//! `Δx ≤ 0.25` with the panel midpoints), i.e.
//! `⌈10 ln(r_max/r_min) + 2 (x_max − x_min)⌉` panels (at least 16): the
//! number of radius nodes grows linearly with the largest size parameter and
//! the spacing is below the period of the Mie ripple. Each panel is bisected
//! until the Simpson values of its two halves agree with the whole to
//! `15 · rel_tol · (panel share of the u range) · scale` for every quantity:
//! `⟨C_ext⟩`, `⟨C_sca⟩`, `⟨C_abs⟩` (scale `⟨C_ext⟩`), `⟨g C_sca⟩` (scale
//! `⟨C_sca⟩`) and each averaged amplitude product at each requested angle
//! (scale `⟨S11(μ)⟩`), the scales being the composite Simpson values of the
//! first level. Resonances that a node falls on are thereby resolved
//! locally; those narrower than the first-level spacing that no node touches
//! are missed, their weight being their width times their height: halving
//! `h₀` changes the results by less than `rel_tol` (tested, also for `k = 0`).
//!
//! Cost: ~2 600 nodes for a log-normal `r_g = 0.2 µm`, `σ_g = 1.3` of
//! TiO2-like spheres in a binder at 550 nm (`x_max = 16`), ~8 000 for a
//! gamma law `r_eff = 0.8 µm`, `v_eff = 0.05` (`x_max = 36`); `k = 0` takes
//! ~3 600 and ~24 000 (sharp resonances); `rel_tol = 1e-8` about three times
//! as many. The densest case measured is a broad log-normal of
//! non-absorbing spheres (`σ_g = 1.98`, `m = 2.86` in vacuum, `x_max =
//! 571`): 195 000 nodes in 43 s on one core, nine in ten of the bisections
//! for the back-scattering angles (`θ > 162°`), where every resonant term
//! of the series adds with its full weight; `rel_tol = 1e-5` and `1e-4`
//! save only a half and three quarters of the nodes (to `x = 57`: 77 000,
//! 41 000, 20 000). The default node limit grows with `x_max`
//! ([`default_max_nodes`]).
//!
//! Layout: the quadrature is `integrator.rs`, the special functions of the
//! distributions `special.rs`, the tests `tests.rs`.

use super::mie::{self, AmplitudeTable, MieResult};
use super::{C64, PhysicsError, RefractiveIndex, ScatteringMatrixSamples};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Smallest effective variance accepted for the gamma distribution.
pub const GAMMA_V_EFF_MIN: f64 = 1e-6;
/// Largest geometric standard deviation accepted for the log-normal.
pub const LOG_NORMAL_SIGMA_G_MAX: f64 = 10.0;

/// Number-weighted particle size distribution (radii in µm).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SizeDistribution {
    /// `n(r) = exp(−(ln r − ln r_g)² / (2 ln² σ_g)) / (√(2π) r ln σ_g)`.
    LogNormal {
        /// Geometric mean (median) radius `r_g`, µm.
        r_g_um: f64,
        /// Geometric standard deviation `σ_g > 1`.
        sigma_g: f64,
    },
    /// Hansen & Travis (1974, Space Sci. Rev. 16, 527, eq. 2.56):
    /// `n(r) ∝ r^{(1−3b)/b} exp(−r/(a b))` with effective radius `a` and
    /// effective variance `0 < b < 1/2`, i.e. a gamma law of shape
    /// `α = (1−2b)/b` and scale `θ = a b`.
    Gamma {
        /// Effective radius `a = ⟨r³⟩/⟨r²⟩`, µm.
        r_eff_um: f64,
        /// Effective variance `b = ⟨(r−a)² r²⟩ / (a² ⟨r²⟩)`.
        v_eff: f64,
    },
}

impl SizeDistribution {
    /// Checks the parameters; each error names the offending field.
    pub fn validate(&self) -> Result<(), PhysicsError> {
        match *self {
            Self::LogNormal { r_g_um, sigma_g } => {
                if !(r_g_um.is_finite() && r_g_um > 0.0) {
                    return Err(out_of_range("r_g_um", r_g_um, "(0, ∞)".into()));
                }
                if !(sigma_g.is_finite() && sigma_g > 1.0 && sigma_g <= LOG_NORMAL_SIGMA_G_MAX) {
                    return Err(out_of_range(
                        "sigma_g",
                        sigma_g,
                        format!("(1, {LOG_NORMAL_SIGMA_G_MAX}]"),
                    ));
                }
            }
            Self::Gamma { r_eff_um, v_eff } => {
                if !(r_eff_um.is_finite() && r_eff_um > 0.0) {
                    return Err(out_of_range("r_eff_um", r_eff_um, "(0, ∞)".into()));
                }
                if !(v_eff.is_finite() && (GAMMA_V_EFF_MIN..0.5).contains(&v_eff)) {
                    return Err(out_of_range(
                        "v_eff",
                        v_eff,
                        format!("[{GAMMA_V_EFF_MIN:e}, 0.5)"),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Number density `n(r)` per µm, normalised to 1 over `(0, ∞)`.
    pub fn number_density(&self, r_um: f64) -> f64 {
        if r_um.is_nan() || r_um <= 0.0 {
            return 0.0;
        }
        match *self {
            Self::LogNormal { r_g_um, sigma_g } => {
                let s = sigma_g.ln();
                let t = (r_um / r_g_um).ln() / s;
                (-0.5 * t * t).exp() / ((2.0 * PI).sqrt() * r_um * s)
            }
            Self::Gamma { r_eff_um, v_eff } => {
                let (alpha, theta) = gamma_shape_scale(r_eff_um, v_eff);
                let y = r_um / theta;
                ((alpha - 1.0) * y.ln() - y - ln_gamma(alpha)).exp() / theta
            }
        }
    }

    /// Moment `⟨r^k⟩` in µm^k.
    pub fn moment(&self, k: f64) -> f64 {
        match *self {
            Self::LogNormal { r_g_um, sigma_g } => {
                let s = sigma_g.ln();
                r_g_um.powf(k) * (0.5 * k * k * s * s).exp()
            }
            Self::Gamma { r_eff_um, v_eff } => {
                let (alpha, theta) = gamma_shape_scale(r_eff_um, v_eff);
                theta.powf(k) * (ln_gamma(alpha + k) - ln_gamma(alpha)).exp()
            }
        }
    }

    /// Radius (µm) below which a fraction `p` of the `r^k`-weighted
    /// distribution lies (`lower = true`), or above which it lies.
    /// The upper cut `r_max` of the radius integral (module doc) for `k`
    /// size parameter per µm and tail fraction `eps`: the largest radius
    /// whose Mie series is summed, so `k r_max` is the size parameter that
    /// sets the cost.
    pub fn upper_cut_um(&self, k_per_um: f64, eps: f64) -> f64 {
        let r4 = self.weighted_quantile(4.0, eps, false);
        let r6 = self.weighted_quantile(6.0, eps, false);
        r4.max(r6.min(2.0 / k_per_um))
    }

    fn weighted_quantile(&self, k: f64, p: f64, lower: bool) -> f64 {
        match *self {
            Self::LogNormal { r_g_um, sigma_g } => {
                // r^k n(r) is log-normal with ln-mean ln r_g + k s².
                let s = sigma_g.ln();
                let z = normal_upper_quantile(p);
                let sign = if lower { -1.0 } else { 1.0 };
                r_g_um * (k * s * s + sign * z * s).exp()
            }
            Self::Gamma { r_eff_um, v_eff } => {
                // r^k n(r) is a gamma law of shape α + k, same scale.
                let (alpha, theta) = gamma_shape_scale(r_eff_um, v_eff);
                theta * gamma_quantile(alpha + k, p, lower)
            }
        }
    }
}

fn gamma_shape_scale(r_eff: f64, v_eff: f64) -> (f64, f64) {
    ((1.0 - 2.0 * v_eff) / v_eff, r_eff * v_eff)
}

/// Quadrature and truncation settings of [`bulk_optics`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PsdQuadrature {
    /// Fraction of the weighted distribution left out at each end (see the
    /// module doc). Default `1e-6`.
    pub tail_fraction: f64,
    /// Relative accuracy asked of every integrated quantity (see the module
    /// doc). Default `1e-6`.
    pub rel_tol: f64,
    /// Largest number of radius nodes (Mie evaluations) before giving up
    /// with an error. Default `None`: [`default_max_nodes`] of the upper-cut
    /// size parameter.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_nodes: Option<usize>,
    /// Explicit integration limits `[r_min, r_max]` in µm, replacing the
    /// tail-fraction cuts (module doc, Truncation). `n(r)` keeps its
    /// normalisation over `(0, ∞)`; the normalised matrix, albedo and `g` do
    /// not depend on it. Default `None`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius_range_um: Option<[f64; 2]>,
}

impl Default for PsdQuadrature {
    fn default() -> Self {
        Self {
            tail_fraction: 1e-6,
            rel_tol: 1e-6,
            max_nodes: None,
            radius_range_um: None,
        }
    }
}

/// Radius nodes allowed by default up to the upper-cut size parameter
/// `x_max`: `200 000 + 500 x_max`. The node count grows linearly with
/// `x_max` (module doc, Cost); the slope covers the densest case measured,
/// non-absorbing spheres of a broad distribution, whose ripple resonances
/// are resolved at ~340 nodes per unit of `x` (log-normal `σ_g = 1.98`,
/// `m = 2.86`, `x_max = 571`: 195 000 nodes, 43 s on one core), so the
/// limit stops a runaway bisection, not a distribution the quadrature can
/// integrate.
pub fn default_max_nodes(x_max: f64) -> usize {
    200_000 + (500.0 * x_max.max(0.0)).ceil() as usize
}

/// Size-averaged single-scattering properties.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BulkOptics {
    /// Mean extinction cross section per particle, µm².
    pub c_ext_um2: f64,
    /// Mean scattering cross section per particle, µm².
    pub c_sca_um2: f64,
    /// Mean absorption cross section per particle, µm² (0 when `k = 0`).
    pub c_abs_um2: f64,
    /// `⟨C_sca⟩ / ⟨C_ext⟩`.
    pub albedo: f64,
    /// Asymmetry parameter `⟨g C_sca⟩ / ⟨C_sca⟩`.
    pub g: f64,
    /// Averaged normalised scattering matrix at the requested cosines.
    pub matrix: ScatteringMatrixSamples,
    /// Lower integration limit, µm.
    pub radius_min_um: f64,
    /// Upper integration limit, µm.
    pub radius_max_um: f64,
    /// Size parameter at `radius_max_um`.
    pub size_parameter_max: f64,
    /// Radius nodes (Mie evaluations) used.
    pub n_radius_nodes: usize,
    /// Estimated relative error of the quadrature: the sum over panels of the
    /// Richardson corrections, relative to each quantity's scale, worst
    /// quantity (≤ `rel_tol` by construction).
    pub rel_error_estimate: f64,
    /// Panels bisected down to the float resolution of `u` (~3e-15) without
    /// meeting the tolerance: resonances of (nearly) non-absorbing spheres
    /// narrower than that, whose weight (width × height) is negligible.
    pub unresolved_panels: usize,
}

/// Size-averaged optics of `dist` (radii in µm) of particles of index
/// `particle` in a host of real index `n_host ≥ 1` at vacuum wavelength
/// `wavelength_nm`, with the averaged matrix at the scattering-angle cosines
/// `mu` (see the module doc for truncation, quadrature and normalisation).
pub fn bulk_optics(
    dist: &SizeDistribution,
    particle: RefractiveIndex,
    n_host: f64,
    wavelength_nm: f64,
    mu: &[f64],
    quad: &PsdQuadrature,
) -> Result<BulkOptics, PhysicsError> {
    Ok(bulk_optics_with_rule(dist, particle, n_host, wavelength_nm, mu, quad)?.0)
}

/// [`bulk_optics`], also returning the radius quadrature it settled on as a
/// fixed [`RadiusRule`]: the averaged matrix of the rule at any other
/// cosines is the same function of `μ` as at `mu` (see [`RadiusRule`]).
pub fn bulk_optics_with_rule(
    dist: &SizeDistribution,
    particle: RefractiveIndex,
    n_host: f64,
    wavelength_nm: f64,
    mu: &[f64],
    quad: &PsdQuadrature,
) -> Result<(BulkOptics, RadiusRule), PhysicsError> {
    let mut integ = Integrator::new(dist, particle, n_host, wavelength_nm, mu, quad)?;
    let t = integ.integrate()?;
    Ok((integ.finish(&t), integ.rule()))
}

/// A radius quadrature fixed once: `⟨f⟩ = ∫ n(r) f(r) dr ≈ Σ_i W_i f(r_i)`.
///
/// The adaptive Simpson rule of [`bulk_optics`] with its Richardson
/// correction is, on each accepted panel `[a, b]` of `u`, Boole's rule on the
/// five nodes `a, a + h/4, …, b` with weights `(b − a)(7, 32, 12, 32, 7)/90`;
/// `W_i` is that weight times `n(r) dr/du`. Where the adaptive rule places its
/// nodes depends on the angles it was asked for, so sampling the averaged
/// matrix through repeated adaptive integrations at different angle sets
/// mixes different rules (relative noise ~`rel_tol` between the sets, which
/// no angular projection can converge below). The fixed rule instead gives
/// one function of `μ` at every cosine: a finite sum of single-sphere
/// matrices, i.e. a polynomial of degree `2 N(x_max)` (`N` of
/// [`mie::series_length`]) that Gauss quadrature projects exactly. It
/// differs from the exact size average by the quadrature error of
/// [`BulkOptics::rel_error_estimate`] at the angles the rule was chosen for.
#[derive(Clone, Debug, PartialEq)]
pub struct RadiusRule {
    /// Relative index of the spheres.
    m: C64,
    /// Size parameter per µm of radius.
    k: f64,
    /// Size parameters `x_i = k r_i` of the nodes, increasing.
    size_parameter: Vec<f64>,
    /// Weights `W_i` (per particle; `Σ W_i ≈` the number fraction inside the limits).
    weight: Vec<f64>,
}

/// Fixed number of node blocks summed in parallel by [`RadiusRule::matrix`]
/// (added in order, so the sum does not depend on the thread count).
const RULE_CHUNKS: usize = 32;

impl RadiusRule {
    /// Number of radius nodes.
    pub fn len(&self) -> usize {
        self.weight.len()
    }

    /// `true` if the rule has no nodes.
    pub fn is_empty(&self) -> bool {
        self.weight.is_empty()
    }

    /// Largest Mie series length `N` over the nodes: the averaged matrix is a
    /// polynomial of degree `≤ 2N` in `μ`.
    pub fn n_terms_max(&self) -> usize {
        self.size_parameter
            .last()
            .map_or(0, |&x| mie::series_length(x))
    }

    /// Mean particle volume `⟨V⟩ = Σ_i W_i (4π/3) r_i³` in µm³, `r_i = x_i/k`:
    /// the same limits and normalisation as the mean cross sections
    /// ([`BulkOptics`]), so `⟨C_ext⟩/⟨V⟩` is the extinction per unit
    /// particle volume of the population inside the limits.
    pub fn mean_volume_um3(&self) -> f64 {
        let c = 4.0 / 3.0 * PI / self.k.powi(3);
        self.size_parameter
            .iter()
            .zip(&self.weight)
            .map(|(x, w)| w * x.powi(3))
            .sum::<f64>()
            * c
    }

    /// The averaged normalised scattering matrix of the rule at the cosines
    /// `mu`, `c Σ W_i [products_i(μ)]` with `c = 4π/(k² Σ W_i C_sca,i)`
    /// (module doc), so that `½∫a1 dμ = 1` to rounding.
    pub fn matrix(&self, mu: &[f64]) -> Result<ScatteringMatrixSamples, PhysicsError> {
        use rayon::prelude::*;
        let n = self.len();
        let chunk = n.div_ceil(RULE_CHUNKS).max(1);
        let idx: Vec<usize> = (0..n).collect();
        let x_max = self.size_parameter.last().copied().unwrap_or(0.0);
        let table = AmplitudeTable::new(mu, integrator::table_terms(x_max))?;
        let blocks: Vec<(f64, Vec<[f64; 4]>)> = idx
            .par_chunks(chunk)
            .map(|block| {
                let mut c_sca = 0.0;
                let mut acc = vec![[0.0; 4]; mu.len()];
                // A few table batches at a time bound the coefficients held.
                for part in block.chunks(256) {
                    let spheres: Vec<MieResult> = part
                        .iter()
                        .map(|&i| MieResult::from_size_parameter(self.size_parameter[i], self.m))
                        .collect::<Result<_, _>>()?;
                    for (&i, sphere) in part.iter().zip(&spheres) {
                        let r = self.size_parameter[i] / self.k;
                        c_sca += self.weight[i] * PI * r * r * sphere.qsca;
                    }
                    table.products_with(&spheres, |j, k, q| {
                        let w = self.weight[part[j]];
                        for (a, q) in acc[k].iter_mut().zip(q) {
                            *a += w * q;
                        }
                    })?;
                }
                Ok((c_sca, acc))
            })
            .collect::<Result<_, PhysicsError>>()?;
        let mut c_sca = 0.0;
        let mut p = vec![[0.0; 4]; mu.len()];
        for (c, acc) in &blocks {
            c_sca += c;
            for (a, q) in p.iter_mut().zip(acc) {
                for j in 0..4 {
                    a[j] += q[j];
                }
            }
        }
        let c = 4.0 * PI / (self.k * self.k * c_sca);
        Ok(mie::matrix_from_products(mu, &p, c))
    }
}

/// Smallest radius accepted as an explicit integration limit, µm.
pub const RADIUS_LIMIT_MIN_UM: f64 = 1e-6;
/// Largest radius accepted as an explicit integration limit, µm.
pub const RADIUS_LIMIT_MAX_UM: f64 = 1e4;

/// The limits `[r_min, r_max]` (µm) of the radius integral of `dist` at `k`
/// size parameter per µm: `quad.radius_range_um` when given (validated:
/// `RADIUS_LIMIT_MIN_UM ≤ r_min < r_max ≤ RADIUS_LIMIT_MAX_UM`), else the
/// tail-fraction cuts of the module doc.
pub fn radius_limits_um(
    dist: &SizeDistribution,
    k_per_um: f64,
    quad: &PsdQuadrature,
) -> Result<[f64; 2], PhysicsError> {
    let range = format!("[{RADIUS_LIMIT_MIN_UM:e}, {RADIUS_LIMIT_MAX_UM:e}] µm");
    match quad.radius_range_um {
        Some([lo, hi]) => {
            let ok =
                |v: f64| v.is_finite() && (RADIUS_LIMIT_MIN_UM..=RADIUS_LIMIT_MAX_UM).contains(&v);
            if !ok(lo) {
                return Err(out_of_range("radius_min_um", lo, range));
            }
            if !ok(hi) {
                return Err(out_of_range("radius_max_um", hi, range));
            }
            if lo >= hi {
                return Err(out_of_range(
                    "radius_max_um",
                    hi,
                    format!("({lo:e}, {RADIUS_LIMIT_MAX_UM:e}] µm (above radius_min_um)"),
                ));
            }
            Ok([lo, hi])
        }
        None => {
            let eps = quad.tail_fraction;
            Ok([
                dist.weighted_quantile(2.0, eps, true),
                dist.upper_cut_um(k_per_um, eps),
            ])
        }
    }
}

fn out_of_range(name: &'static str, value: f64, range: String) -> PhysicsError {
    PhysicsError::OutOfRange { name, value, range }
}

mod integrator;
pub(crate) mod special;
#[cfg(test)]
mod tests;

use integrator::Integrator;
use special::{gamma_quantile, ln_gamma, normal_upper_quantile};
