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
//! as many.

use super::mie::{self, MieResult};
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
/// `m = 2.86`, `x_max = 571`: 195 000 nodes, 95 s on one core), so the
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
        let blocks: Vec<(f64, Vec<[f64; 4]>)> = idx
            .par_chunks(chunk)
            .map(|block| {
                let mut c_sca = 0.0;
                let mut acc = vec![[0.0; 4]; mu.len()];
                for &i in block {
                    let (x, w) = (self.size_parameter[i], self.weight[i]);
                    let r = x / self.k;
                    let sphere = MieResult::from_size_parameter(x, self.m)?;
                    c_sca += w * PI * r * r * sphere.qsca;
                    for (a, q) in acc.iter_mut().zip(sphere.amplitude_products(mu)?) {
                        for j in 0..4 {
                            a[j] += w * q[j];
                        }
                    }
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

/// Integrand layout: `[C_ext, C_sca, C_abs, g C_sca, then 4 products per angle]`.
const N_BULK: usize = 4;
/// Size-parameter spacing of one unit of `u`.
const U_X_SCALE: f64 = 5.0;
/// Initial panel width in `u`.
const U_STEP0: f64 = 0.1;
/// Deepest bisection of a first-level panel (width 0.1 · 2⁻⁴⁵ ≈ 3e-15, the
/// float resolution of `u`).
const MAX_DEPTH: u32 = 45;

/// Adaptive Simpson integration in `u = ln r + k r / 5` (see the module doc).
struct Integrator<'a> {
    dist: &'a SizeDistribution,
    m: C64,
    k: f64,
    mu: &'a [f64],
    r_min: f64,
    r_max: f64,
    u_min: f64,
    u_max: f64,
    rel_tol: f64,
    max_nodes: usize,
    /// First-level panel width in `u`.
    step0: f64,
    /// Smallest share of the tolerance a panel is held to.
    share_floor: f64,
    /// Magnitude each component's error is measured against.
    scale: Vec<f64>,
    /// Integrand evaluations so far.
    evals: usize,
    /// Sum over accepted panels of |Richardson correction| / scale (max over
    /// components at the end).
    err: Vec<f64>,
    /// Panels accepted at `MAX_DEPTH` without meeting the tolerance.
    unresolved: usize,
    /// Accepted panels `[a, b]` in `u` of the last pass.
    panels: Vec<(f64, f64)>,
}

impl<'a> Integrator<'a> {
    fn new(
        dist: &'a SizeDistribution,
        particle: RefractiveIndex,
        n_host: f64,
        wavelength_nm: f64,
        mu: &'a [f64],
        quad: &PsdQuadrature,
    ) -> Result<Self, PhysicsError> {
        dist.validate()?;
        if !(quad.tail_fraction > 0.0 && quad.tail_fraction <= 1e-2) {
            return Err(out_of_range(
                "tail_fraction",
                quad.tail_fraction,
                "(0, 0.01]".into(),
            ));
        }
        if !(quad.rel_tol > 0.0 && quad.rel_tol < 1.0) {
            return Err(out_of_range("rel_tol", quad.rel_tol, "(0, 1)".into()));
        }
        for &u in mu {
            if !(u.is_finite() && u.abs() <= 1.0 + 1e-12) {
                return Err(out_of_range("mu", u, "[-1, 1]".into()));
            }
        }
        // k: size parameter per µm of radius.
        let (k, m) = mie::wavenumber_and_index(particle, n_host, wavelength_nm)?;
        let [r_min, r_max] = radius_limits_um(dist, k, quad)?;
        let (x_min, x_max) = (k * r_min, k * r_max);
        let range = |r: &str, v: f64| {
            format!(
                "[{:e}, {:e}] ({r} = {v:e} µm)",
                mie::SIZE_PARAMETER_MIN,
                mie::SIZE_PARAMETER_MAX
            )
        };
        if x_min < mie::SIZE_PARAMETER_MIN {
            return Err(out_of_range(
                "size_parameter at the lower cut of the size distribution",
                x_min,
                range("r_min", r_min),
            ));
        }
        if x_max > mie::SIZE_PARAMETER_MAX {
            return Err(out_of_range(
                "size_parameter at the upper cut of the size distribution",
                x_max,
                range("r_max", r_max),
            ));
        }
        let u = |r: f64| r.ln() + k * r / U_X_SCALE;
        let n = N_BULK + 4 * mu.len();
        Ok(Self {
            dist,
            m,
            k,
            mu,
            r_min,
            r_max,
            u_min: u(r_min),
            u_max: u(r_max),
            rel_tol: quad.rel_tol,
            max_nodes: quad.max_nodes.unwrap_or_else(|| default_max_nodes(x_max)),
            step0: U_STEP0,
            share_floor: 0.0,
            scale: vec![0.0; n],
            evals: 0,
            err: vec![0.0; n],
            unresolved: 0,
            panels: Vec::new(),
        })
    }

    /// Radius at `u` (safeguarded Newton on `t = ln r`).
    fn radius(&self, u: f64) -> f64 {
        let (mut lo, mut hi) = (self.r_min.ln(), self.r_max.ln());
        let mut t = u.min(hi).max(lo);
        for _ in 0..200 {
            let e = self.k * t.exp() / U_X_SCALE;
            let f = t + e - u;
            if f > 0.0 {
                hi = t;
            } else {
                lo = t;
            }
            let mut next = t - f / (1.0 + e);
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            let done = (next - t).abs() <= 1e-15 * t.abs().max(1.0);
            t = next;
            if done {
                break;
            }
        }
        t.exp()
    }

    /// `n(r) dr/du` at `u` and the radius there.
    fn jacobian(&self, u: f64) -> (f64, f64) {
        let r = self.radius(u);
        (
            self.dist.number_density(r) * r / (1.0 + self.k * r / U_X_SCALE),
            r,
        )
    }

    /// The accepted panels of the last pass as a fixed [`RadiusRule`]
    /// (Boole's rule per panel, nodes shared by neighbours merged).
    fn rule(&self) -> RadiusRule {
        const BOOLE: [f64; 5] = [7.0, 32.0, 12.0, 32.0, 7.0];
        let mut nodes: Vec<(f64, f64)> = Vec::with_capacity(4 * self.panels.len() + 1);
        for &(a, b) in &self.panels {
            let m = 0.5 * (a + b);
            for (u, c) in [a, 0.5 * (a + m), m, 0.5 * (m + b), b]
                .into_iter()
                .zip(BOOLE)
            {
                nodes.push((u, c * (b - a) / 90.0));
            }
        }
        nodes.sort_by(|p, q| p.0.total_cmp(&q.0));
        let mut merged: Vec<(f64, f64)> = Vec::with_capacity(nodes.len());
        for (u, w) in nodes {
            match merged.last_mut() {
                Some(last) if last.0 == u => last.1 += w,
                _ => merged.push((u, w)),
            }
        }
        let (mut size_parameter, mut weight) = (Vec::new(), Vec::new());
        for (u, w) in merged {
            let (jac, r) = self.jacobian(u);
            size_parameter
                .push((self.k * r).clamp(mie::SIZE_PARAMETER_MIN, mie::SIZE_PARAMETER_MAX));
            weight.push(w * jac);
        }
        RadiusRule {
            m: self.m,
            k: self.k,
            size_parameter,
            weight,
        }
    }

    /// Integrand at `u`: `n(r) dr/du · [C…, products…]`.
    fn eval(&mut self, u: f64) -> Result<Vec<f64>, PhysicsError> {
        self.evals += 1;
        if self.evals > self.max_nodes {
            return Err(PhysicsError::Invalid(format!(
                "size-distribution quadrature needs more than max_nodes = {} radius nodes \
                 for rel_tol = {:e} (x_max = {:.4})",
                self.max_nodes,
                self.rel_tol,
                self.k * self.r_max
            )));
        }
        let (w, r) = self.jacobian(u);
        let x = (self.k * r).clamp(mie::SIZE_PARAMETER_MIN, mie::SIZE_PARAMETER_MAX);
        let sphere = MieResult::from_size_parameter(x, self.m)?;
        let geo = PI * r * r * w;
        let mut out = Vec::with_capacity(self.scale.len());
        out.extend([
            sphere.qext * geo,
            sphere.qsca * geo,
            sphere.qabs * geo,
            sphere.g * sphere.qsca * geo,
        ]);
        if !self.mu.is_empty() {
            for q in sphere.amplitude_products(self.mu)? {
                out.extend(q.iter().map(|v| v * w));
            }
        }
        Ok(out)
    }

    /// Scales from an integral estimate: `C_ext` for `C_ext`, `C_abs`;
    /// `C_sca` for `C_sca`, `g C_sca`; `⟨S11(μ)⟩` for the products at `μ`.
    fn set_scale(&mut self, t: &[f64]) {
        let floor = f64::MIN_POSITIVE;
        self.scale[0] = t[0].abs().max(floor);
        self.scale[1] = t[1].abs().max(floor);
        self.scale[2] = self.scale[0];
        self.scale[3] = self.scale[1];
        for i in 0..self.mu.len() {
            let b = N_BULK + 4 * i;
            let s = t[b].abs().max(floor);
            self.scale[b..b + 4].fill(s);
        }
    }

    /// Composite Simpson on the initial panels for the scales, then adaptive
    /// Simpson on each panel.
    fn integrate(&mut self) -> Result<Vec<f64>, PhysicsError> {
        let span = self.u_max - self.u_min;
        let panels = ((span / self.step0).ceil() as usize).max(16);
        if 2 * panels + 1 > self.max_nodes {
            return Err(PhysicsError::Invalid(format!(
                "size-distribution quadrature needs {} radius nodes at its first level \
                 (x_max = {:.4}), more than max_nodes = {}",
                2 * panels + 1,
                self.k * self.r_max,
                self.max_nodes
            )));
        }
        let h = span / panels as f64;
        let mut f = Vec::with_capacity(2 * panels + 1);
        for i in 0..=2 * panels {
            f.push(self.eval(self.u_min + 0.5 * h * i as f64)?);
        }
        let simpson = |a: &[f64], m: &[f64], b: &[f64]| -> Vec<f64> {
            (0..a.len())
                .map(|j| h / 6.0 * (a[j] + 4.0 * m[j] + b[j]))
                .collect()
        };
        let wholes: Vec<Vec<f64>> = (0..panels)
            .map(|p| simpson(&f[2 * p], &f[2 * p + 1], &f[2 * p + 2]))
            .collect();
        let first = sum_vecs(self.scale.len(), wholes.iter());
        self.set_scale(&first);
        // A panel is held to its share of the tolerance, but not below the
        // share of a panel `floor_depth` bisections down: otherwise a node
        // that lands on a resonance far narrower than the panel (k = 0) is
        // bisected to the float resolution while the error it causes halves
        // with each level anyway. The estimate of the total error is still the
        // sum over all accepted panels; should it exceed rel_tol, the floor is
        // lowered and the pass repeated.
        let mut floor_depth = 8;
        loop {
            self.share_floor = (-(floor_depth as f64)).exp2() / panels as f64;
            self.err.fill(0.0);
            self.unresolved = 0;
            self.panels.clear();
            let mut total = vec![0.0; self.scale.len()];
            for (p, whole) in wholes.iter().enumerate() {
                let a = self.u_min + h * p as f64;
                // `b` is the next panel's `a` exactly, so the rule merges them.
                let part = self.adapt(
                    a,
                    self.u_min + h * (p + 1) as f64,
                    [&f[2 * p], &f[2 * p + 1], &f[2 * p + 2]],
                    whole,
                    0,
                )?;
                for (t, v) in total.iter_mut().zip(&part) {
                    *t += v;
                }
            }
            if self.rel_error_estimate() <= self.rel_tol || floor_depth >= MAX_DEPTH {
                return Ok(total);
            }
            floor_depth += 8;
        }
    }

    /// Sum of the accepted panels' error estimates relative to each quantity's
    /// scale, worst quantity.
    fn rel_error_estimate(&self) -> f64 {
        self.err
            .iter()
            .zip(&self.scale)
            .map(|(e, s)| e / s)
            .fold(0.0, f64::max)
    }

    fn adapt(
        &mut self,
        a: f64,
        b: f64,
        [fa, fm, fb]: [&[f64]; 3],
        whole: &[f64],
        depth: u32,
    ) -> Result<Vec<f64>, PhysicsError> {
        let m = 0.5 * (a + b);
        let flm = self.eval(0.5 * (a + m))?;
        let frm = self.eval(0.5 * (m + b))?;
        let w = (b - a) / 12.0;
        let n = whole.len();
        let left: Vec<f64> = (0..n).map(|j| w * (fa[j] + 4.0 * flm[j] + fm[j])).collect();
        let right: Vec<f64> = (0..n).map(|j| w * (fm[j] + 4.0 * frm[j] + fb[j])).collect();
        // |S_left + S_right − S_whole| ≈ 15 × error; the allowance is
        // proportional to the panel's share of the u range, but not below
        // that of a panel `floor_depth` levels down (see `integrate`).
        let share = ((b - a) / (self.u_max - self.u_min)).max(self.share_floor);
        let ok = (0..n).all(|j| {
            let d = (left[j] + right[j] - whole[j]).abs();
            d <= 15.0 * self.rel_tol * share * self.scale[j]
        });
        if ok || depth >= MAX_DEPTH {
            if !ok {
                self.unresolved += 1;
            }
            self.panels.push((a, b));
            let out: Vec<f64> = (0..n)
                .map(|j| {
                    let d = left[j] + right[j] - whole[j];
                    self.err[j] += d.abs() / 15.0;
                    left[j] + right[j] + d / 15.0
                })
                .collect();
            return Ok(out);
        }
        let l = self.adapt(a, m, [fa, &flm, fm], &left, depth + 1)?;
        let r = self.adapt(m, b, [fm, &frm, fb], &right, depth + 1)?;
        Ok(l.iter().zip(&r).map(|(x, y)| x + y).collect())
    }

    fn finish(&self, t: &[f64]) -> BulkOptics {
        let (c_ext, c_sca) = (t[0], t[1]);
        let (c_abs, albedo) = if self.m.im == 0.0 {
            (0.0, 1.0)
        } else {
            (t[2], (c_sca / c_ext).min(1.0))
        };
        let p: Vec<[f64; 4]> = (0..self.mu.len())
            .map(|i| {
                let b = N_BULK + 4 * i;
                [t[b], t[b + 1], t[b + 2], t[b + 3]]
            })
            .collect();
        let c = 4.0 * PI / (self.k * self.k * c_sca);
        let rel_error_estimate = self.rel_error_estimate();
        BulkOptics {
            c_ext_um2: c_ext,
            c_sca_um2: c_sca,
            c_abs_um2: c_abs,
            albedo,
            g: t[3] / c_sca,
            matrix: mie::matrix_from_products(self.mu, &p, c),
            radius_min_um: self.r_min,
            radius_max_um: self.r_max,
            size_parameter_max: self.k * self.r_max,
            n_radius_nodes: self.evals,
            rel_error_estimate,
            unresolved_panels: self.unresolved,
        }
    }
}

fn sum_vecs<'v>(n: usize, vs: impl Iterator<Item = &'v Vec<f64>>) -> Vec<f64> {
    let mut s = vec![0.0; n];
    for v in vs {
        for (a, b) in s.iter_mut().zip(v) {
            *a += b;
        }
    }
    s
}

// ------------------------------------------------------------ special functions

/// `ln Γ(x)` for `x > 0`: Lanczos approximation (g = 7, 9 terms; relative
/// error ~1e-15), with `Γ(x) = Γ(x+1)/x` below 0.5.
pub(crate) fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return ln_gamma(x + 1.0) - x.ln();
    }
    let x = x - 1.0;
    let mut a = C[0];
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    let t = x + G + 0.5;
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised incomplete gamma functions `(P(a, x), Q(a, x))`, by the series
/// for `x < a + 1` and Lentz's continued fraction otherwise (Numerical
/// Recipes, 3rd ed., §6.2).
pub(crate) fn gamma_pq(a: f64, x: f64) -> (f64, f64) {
    if x <= 0.0 {
        return (0.0, 1.0);
    }
    let ln_pref = -x + a * x.ln() - ln_gamma(a);
    if x < a + 1.0 {
        let (mut ap, mut del) = (a, 1.0 / a);
        let mut sum = del;
        for _ in 0..100_000_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        let p = (sum.ln() + ln_pref).exp();
        (p, 1.0 - p)
    } else {
        const TINY: f64 = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..100_000_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < TINY {
                d = TINY;
            }
            c = b + an / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        let q = (h.ln() + ln_pref).exp();
        (1.0 - q, q)
    }
}

/// `y` with `P(a, y) = p` (`lower`) or `Q(a, y) = p`, by bisection in `ln y`.
fn gamma_quantile(a: f64, p: f64, lower: bool) -> f64 {
    let tail = |ln_y: f64| {
        let (pp, qq) = gamma_pq(a, ln_y.exp());
        if lower { pp } else { qq }
    };
    // The tail grows with y for the lower tail and shrinks for the upper.
    let (mut lo, mut hi) = ((1e-300f64).ln(), (a + 60.0 * a.sqrt() + 800.0).ln());
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        let below = tail(mid) < p;
        if below == lower {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-12 {
            break;
        }
    }
    (0.5 * (lo + hi)).exp()
}

/// `z > 0` with `Pr(Z > z) = p` for a standard normal `Z`
/// (`Pr(Z > z) = ½ Q(½, z²/2)`), by bisection.
fn normal_upper_quantile(p: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if 0.5 * gamma_pq(0.5, 0.5 * mid * mid).1 > p {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-13 {
            break;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::mie::tests::gauss_legendre;

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs()
    }

    const LAMBDA: f64 = 550.0;
    const N_HOST: f64 = 1.5;

    fn k_host() -> f64 {
        2.0 * PI * 1000.0 * N_HOST / LAMBDA
    }

    /// The rule's mean volume is the third moment of the distribution:
    /// log-normal `⟨r³⟩ = r_g³ exp(9/2 ln²σ_g)`, gamma (Hansen & Travis
    /// 1974, `α = (1 − 3b)/b`) `⟨r³⟩ = (ab)³ (α+1)(α+2)(α+3)`, both over
    /// limits wide enough that the cut tails are below 1e-12.
    #[test]
    fn the_rule_mean_volume_is_the_third_moment() {
        let quad = PsdQuadrature {
            radius_range_um: Some([1e-4, 20.0]),
            ..Default::default()
        };
        let m = RefractiveIndex::new(2.0, 0.01);
        let mu = [-1.0, 0.0, 1.0];
        let (r_g, s) = (0.2f64, 1.4f64);
        let ln = SizeDistribution::LogNormal {
            r_g_um: r_g,
            sigma_g: s,
        };
        let (a, b) = (0.3f64, 0.1f64);
        let alpha = (1.0 - 3.0 * b) / b;
        let gamma = SizeDistribution::Gamma {
            r_eff_um: a,
            v_eff: b,
        };
        for (d, r3) in [
            (ln, r_g.powi(3) * (4.5 * s.ln().powi(2)).exp()),
            (
                gamma,
                (a * b).powi(3) * (alpha + 1.0) * (alpha + 2.0) * (alpha + 3.0),
            ),
        ] {
            let (_, rule) = bulk_optics_with_rule(&d, m, N_HOST, LAMBDA, &mu, &quad).unwrap();
            let v = 4.0 / 3.0 * PI * r3;
            assert!(
                rel(rule.mean_volume_um3(), v) < 1e-6,
                "{d:?}: {} vs {v}",
                rule.mean_volume_um3()
            );
        }
    }

    // ------------------------------------------------------ special functions
    /// Published values: Γ(½) = √π, Γ(10) = 9!, Γ(1/3) = 2.678938534707747…
    /// (Abramowitz & Stegun, Table 6.1); erf(1) = 0.8427007929497149 and
    /// erf(0.5) = 0.5204998778130465 (A&S Table 7.1, P(½, x²) = erf x);
    /// P(1, x) = 1 − e^{−x}; the standard normal upper quantile at 1e-6,
    /// 4.753424308822899 (A&S 26.2.23 tables).
    #[test]
    fn special_functions_match_published_values() {
        assert!((ln_gamma(0.5) - PI.sqrt().ln()).abs() < 1e-14);
        assert!((ln_gamma(10.0) - 362_880f64.ln()).abs() < 1e-13);
        assert!((ln_gamma(1.0 / 3.0) - 2.678_938_534_707_747_6f64.ln()).abs() < 1e-14);
        assert!(ln_gamma(1.0).abs() < 1e-15 && ln_gamma(2.0).abs() < 1e-15);
        assert!((gamma_pq(0.5, 1.0).0 - 0.842_700_792_949_714_9).abs() < 1e-14);
        assert!((gamma_pq(0.5, 0.25).0 - 0.520_499_877_813_046_5).abs() < 1e-14);
        for x in [0.01, 0.5, 2.0, 7.5, 40.0] {
            let (p, q) = gamma_pq(1.0, x);
            assert!((p - (1.0 - (-x).exp())).abs() < 1e-14, "x={x}");
            assert!(rel(q, (-x).exp()) < 1e-12, "x={x}");
        }
        assert!((normal_upper_quantile(1e-6) - 4.753_424_308_822_899).abs() < 1e-9);
        // Quantiles invert P and Q, also for a narrow (large-shape) law.
        for a in [0.3, 3.0, 1e6] {
            let lo = gamma_quantile(a, 1e-6, true);
            let hi = gamma_quantile(a, 1e-6, false);
            assert!(rel(gamma_pq(a, lo).0, 1e-6) < 1e-6, "a={a}");
            assert!(rel(gamma_pq(a, hi).1, 1e-6) < 1e-6, "a={a}");
        }
    }

    #[test]
    fn distributions_are_normalised_with_the_stated_moments() {
        let dists = [
            SizeDistribution::LogNormal {
                r_g_um: 0.2,
                sigma_g: 1.5,
            },
            SizeDistribution::Gamma {
                r_eff_um: 0.3,
                v_eff: 0.1,
            },
            SizeDistribution::Gamma {
                r_eff_um: 0.3,
                v_eff: 0.4,
            },
        ];
        for d in dists {
            // ∫ r^k n dr on a fine log grid (midpoint in ln r) vs ⟨r^k⟩.
            let (t0, t1, n) = ((1e-18f64).ln(), (50.0f64).ln(), 400_000);
            let h = (t1 - t0) / n as f64;
            for k in [0.0, 1.0, 2.0, 3.0] {
                let s: f64 = (0..n)
                    .map(|i| {
                        let r = (t0 + h * (i as f64 + 0.5)).exp();
                        r.powf(k) * d.number_density(r) * r * h
                    })
                    .sum();
                assert!(
                    rel(s, d.moment(k)) < 1e-6,
                    "{d:?} k={k}: {s} vs {}",
                    d.moment(k)
                );
            }
            if let SizeDistribution::Gamma { r_eff_um, v_eff } = d {
                // Hansen & Travis definitions of r_eff and v_eff.
                let (m2, m3, m4) = (d.moment(2.0), d.moment(3.0), d.moment(4.0));
                assert!(rel(m3 / m2, r_eff_um) < 1e-12);
                let v = (m4 - 2.0 * r_eff_um * m3 + r_eff_um * r_eff_um * m2)
                    / (r_eff_um * r_eff_um * m2);
                assert!(rel(v, v_eff) < 1e-10);
            }
        }
    }

    // ------------------------------------------------------------ bulk optics
    /// In the Rayleigh regime the averages are analytic: ⟨C_sca⟩ =
    /// (8/3)π k⁴ |K|² ⟨r⁶⟩, ⟨C_abs⟩ = 4π k Im K ⟨r³⟩, a1 = ¾(1+μ²),
    /// b1 = −¾(1−μ²). Tests truncation (r⁶ and r³ tails) and quadrature.
    #[test]
    fn rayleigh_regime_matches_analytic_moments() {
        let mu: Vec<f64> = (0..=8).map(|i| -1.0 + 0.25 * i as f64).collect();
        let p = RefractiveIndex::new(2.0, 0.1);
        let m = p.as_complex() / N_HOST;
        let kk = (m * m - 1.0) / (m * m + 2.0);
        let k = k_host();
        for d in [
            SizeDistribution::LogNormal {
                r_g_um: 2e-5,
                sigma_g: 1.5,
            },
            SizeDistribution::Gamma {
                r_eff_um: 5e-5,
                v_eff: 0.2,
            },
        ] {
            let b = bulk_optics(&d, p, N_HOST, LAMBDA, &mu, &PsdQuadrature::default()).unwrap();
            let c_sca = 8.0 / 3.0 * PI * k.powi(4) * kk.norm_sqr() * d.moment(6.0);
            let c_abs = 4.0 * PI * k * kk.im * d.moment(3.0);
            assert!(
                b.size_parameter_max < 0.02,
                "{d:?}: x_max {}",
                b.size_parameter_max
            );
            assert!(
                rel(b.c_sca_um2, c_sca) < 5e-6,
                "{d:?}: C_sca {} vs {c_sca}",
                b.c_sca_um2
            );
            assert!(
                rel(b.c_abs_um2, c_abs) < 5e-6,
                "{d:?}: C_abs {} vs {c_abs}",
                b.c_abs_um2
            );
            assert!(rel(b.c_ext_um2, c_sca + c_abs) < 5e-6);
            for (i, &u) in mu.iter().enumerate() {
                assert!((b.matrix.a1[i] - 0.75 * (1.0 + u * u)).abs() < 1e-5);
                assert!((b.matrix.b1[i] + 0.75 * (1.0 - u * u)).abs() < 1e-5);
            }
        }
    }

    /// A very narrow distribution reproduces the single sphere at its radius.
    /// The difference is ½ s² C''/C for a relative width s, and C''/C reaches
    /// ~1e3 near a resonance (m = 1.8, x = 4.3 here), so the widths are chosen
    /// to keep it below the tolerance; the tails are cut at 1e-9.
    #[test]
    fn narrow_distributions_reproduce_single_sphere() {
        let mu: Vec<f64> = (0..=12)
            .map(|i| (15.0 * i as f64 * PI / 180.0).cos())
            .collect();
        let quad = PsdQuadrature {
            tail_fraction: 1e-9,
            ..Default::default()
        };
        for (d, p, tol, tol_matrix) in [
            // s = 1e-5: ½ s² C''/C ~ 5e-8.
            (
                SizeDistribution::LogNormal {
                    r_g_um: 0.25,
                    sigma_g: 1.00001,
                },
                RefractiveIndex::new(2.7, 0.01),
                1e-6,
                1e-6,
            ),
            // s = √v_eff = 1e-3 (the narrowest gamma law accepted) with an
            // absorbing sphere: ~1e-5 for the cross sections, ~3e-4 for the
            // angular pattern, whose structure shifts faster with x.
            (
                SizeDistribution::Gamma {
                    r_eff_um: 0.25,
                    v_eff: 1e-6,
                },
                RefractiveIndex::new(2.7, 0.3),
                1e-4,
                1e-3,
            ),
        ] {
            let r = 0.25;
            let b = bulk_optics(&d, p, N_HOST, LAMBDA, &mu, &quad).unwrap();
            let s = MieResult::for_sphere(p, N_HOST, LAMBDA, r).unwrap();
            let geo = PI * r * r;
            let dev = [
                rel(b.c_ext_um2, s.qext * geo),
                rel(b.c_sca_um2, s.qsca * geo),
                rel(b.c_abs_um2, s.qabs * geo),
                (b.g - s.g).abs(),
            ];
            assert!(dev.iter().all(|&v| v < tol), "{d:?}: {dev:?}");
            let f = s.scattering_matrix(&mu).unwrap();
            let mut worst: f64 = 0.0;
            for i in 0..mu.len() {
                for (u, v) in [
                    (b.matrix.a1[i], f.a1[i]),
                    (b.matrix.b1[i], f.b1[i]),
                    (b.matrix.a3[i], f.a3[i]),
                    (b.matrix.b2[i], f.b2[i]),
                ] {
                    worst = worst.max((u - v).abs() / f.a1[i]);
                }
            }
            eprintln!(
                "{d:?}: deviations from the single sphere: C_ext {:.1e}, C_sca {:.1e}, C_abs {:.1e}, g {:.1e}, matrix {worst:.1e}",
                dev[0], dev[1], dev[2], dev[3]
            );
            assert!(worst < tol_matrix, "{d:?}: matrix {worst}");
        }
    }

    /// The averaged matrix is normalised, a1 = a2 and a3 = a4, and g agrees
    /// with ½∫a1 μ dμ.
    #[test]
    fn averaged_matrix_is_normalised() {
        let d = SizeDistribution::LogNormal {
            r_g_um: 0.15,
            sigma_g: 1.4,
        };
        let p = RefractiveIndex::new(2.0, 0.0);
        let quad = PsdQuadrature {
            rel_tol: 1e-7,
            ..Default::default()
        };
        let probe = bulk_optics(&d, p, N_HOST, LAMBDA, &[], &quad).unwrap();
        let n_max = mie::series_length(probe.size_parameter_max);
        let (mu, w) = gauss_legendre(n_max + 20);
        let b = bulk_optics(&d, p, N_HOST, LAMBDA, &mu, &quad).unwrap();
        let norm: f64 = 0.5 * b.matrix.a1.iter().zip(&w).map(|(a, w)| a * w).sum::<f64>();
        assert!((norm - 1.0).abs() < 1e-10, "½∫a1 = {norm}");
        let g: f64 = 0.5
            * b.matrix
                .a1
                .iter()
                .zip(&w)
                .zip(&mu)
                .map(|((a, w), u)| a * w * u)
                .sum::<f64>();
        assert!((g - b.g).abs() < 1e-10, "g {g} vs {}", b.g);
        assert_eq!(b.matrix.a1, b.matrix.a2);
        assert_eq!(b.matrix.a3, b.matrix.a4);
        assert_eq!(b.albedo, 1.0);
        assert_eq!(b.c_abs_um2, 0.0);
        // Same bulk numbers with or without angles.
        assert!(rel(b.c_sca_um2, probe.c_sca_um2) < 1e-6);
    }

    /// Convergence: the error estimate is below rel_tol; a run at rel_tol/100
    /// and a run with the first-level spacing halved (twice the nodes from the
    /// start) agree to rel_tol; cutting the tails at 1e-8 instead of 1e-6
    /// changes C_ext by ~1e-6 and the matrix by < 1e-5 of a1 (at back-
    /// scattering minima of ⟨S11⟩ the tails weigh a few times more). Weakly
    /// absorbing and non-absorbing TiO2-like spheres (m = 1.97 relative:
    /// sharp resonances).
    #[test]
    fn quadrature_converges_under_refinement() {
        let mu: Vec<f64> = (0..=18)
            .map(|i| (10.0 * i as f64 * PI / 180.0).cos())
            .collect();
        let cases = [
            (
                SizeDistribution::LogNormal {
                    r_g_um: 0.2,
                    sigma_g: 1.3,
                },
                RefractiveIndex::new(2.954, 0.003),
            ),
            (
                SizeDistribution::Gamma {
                    r_eff_um: 0.8,
                    v_eff: 0.05,
                },
                RefractiveIndex::new(2.954, 0.003),
            ),
            (
                SizeDistribution::LogNormal {
                    r_g_um: 0.2,
                    sigma_g: 1.3,
                },
                RefractiveIndex::new(2.954, 0.0),
            ),
            (
                SizeDistribution::Gamma {
                    r_eff_um: 0.8,
                    v_eff: 0.05,
                },
                RefractiveIndex::new(2.954, 0.0),
            ),
        ];
        let worst_dev = |a: &BulkOptics, b: &BulkOptics| {
            let mut w = rel(a.c_ext_um2, b.c_ext_um2)
                .max(rel(a.c_sca_um2, b.c_sca_um2))
                .max((a.c_abs_um2 - b.c_abs_um2).abs() / b.c_ext_um2)
                .max((a.g - b.g).abs());
            for i in 0..a.matrix.mu.len() {
                let s = b.matrix.a1[i];
                for (u, v) in [
                    (a.matrix.a1[i], b.matrix.a1[i]),
                    (a.matrix.b1[i], b.matrix.b1[i]),
                    (a.matrix.a3[i], b.matrix.a3[i]),
                    (a.matrix.b2[i], b.matrix.b2[i]),
                ] {
                    w = w.max((u - v).abs() / s);
                }
            }
            w
        };
        for (d, p) in cases {
            let quad = PsdQuadrature::default();
            let b = bulk_optics(&d, p, N_HOST, LAMBDA, &mu, &quad).unwrap();
            assert!(b.rel_error_estimate <= quad.rel_tol);
            if p.k > 0.0 {
                assert_eq!(b.unresolved_panels, 0);
            }
            let tight_tol = 1e-8;
            let tight = PsdQuadrature {
                rel_tol: tight_tol,
                max_nodes: Some(1_000_000),
                ..quad
            };
            let bt = bulk_optics(&d, p, N_HOST, LAMBDA, &mu, &tight).unwrap();
            let dev_tight = worst_dev(&b, &bt);
            let mut integ = Integrator::new(&d, p, N_HOST, LAMBDA, &mu, &quad).unwrap();
            integ.step0 = 0.5 * U_STEP0;
            let t = integ.integrate().unwrap();
            let bd = integ.finish(&t);
            let dev_doubled = worst_dev(&b, &bd);
            let thin = PsdQuadrature {
                tail_fraction: 1e-8,
                ..quad
            };
            let bs = bulk_optics(&d, p, N_HOST, LAMBDA, &mu, &thin).unwrap();
            let dev_tail = worst_dev(&b, &bs);
            eprintln!(
                "{d:?} k={}: {} nodes (x_max {:.1}, {} unresolved panels), error estimate \
                 {:.1e}; deviation from rel_tol {tight_tol:e} ({} nodes) {dev_tight:.1e}, from halved \
                 h0 ({} nodes) {dev_doubled:.1e}, from tail 1e-8 {dev_tail:.1e}",
                p.k,
                b.n_radius_nodes,
                b.size_parameter_max,
                b.unresolved_panels,
                b.rel_error_estimate,
                bt.n_radius_nodes,
                bd.n_radius_nodes
            );
            assert!(
                dev_tight < quad.rel_tol,
                "{d:?} {p:?}: vs tight {dev_tight}"
            );
            assert!(
                dev_doubled < quad.rel_tol,
                "{d:?} {p:?}: vs doubled {dev_doubled}"
            );
            assert!(dev_tail < 1e-5, "{d:?} {p:?}: vs thinner tails {dev_tail}");
        }
    }

    #[test]
    fn invalid_inputs_are_errors() {
        let p = RefractiveIndex::new(1.5, 0.0);
        let q = PsdQuadrature::default();
        let name = |r: Result<BulkOptics, PhysicsError>| match r {
            Err(PhysicsError::OutOfRange { name, .. }) => name,
            other => panic!("{other:?}"),
        };
        let ln = |r, s| SizeDistribution::LogNormal {
            r_g_um: r,
            sigma_g: s,
        };
        let ga = |r, v| SizeDistribution::Gamma {
            r_eff_um: r,
            v_eff: v,
        };
        assert_eq!(
            name(bulk_optics(&ln(0.1, 1.0), p, 1.5, 550.0, &[], &q)),
            "sigma_g"
        );
        assert_eq!(
            name(bulk_optics(&ln(-0.1, 1.5), p, 1.5, 550.0, &[], &q)),
            "r_g_um"
        );
        assert_eq!(
            name(bulk_optics(&ga(0.1, 0.5), p, 1.5, 550.0, &[], &q)),
            "v_eff"
        );
        assert_eq!(
            name(bulk_optics(&ga(0.0, 0.1), p, 1.5, 550.0, &[], &q)),
            "r_eff_um"
        );
        assert_eq!(
            name(bulk_optics(&ga(0.1, 0.1), p, 0.5, 550.0, &[], &q)),
            "host_index"
        );
        assert_eq!(
            name(bulk_optics(&ga(0.1, 0.1), p, 1.5, 550.0, &[2.0], &q)),
            "mu"
        );
        assert_eq!(
            name(bulk_optics(
                &ga(0.1, 0.1),
                RefractiveIndex::new(1.5, 0.0),
                1.5,
                550.0,
                &[],
                &q
            )),
            "|relative_index - 1|"
        );
        assert_eq!(
            name(bulk_optics(&ln(500.0, 2.0), p, 1.0, 550.0, &[], &q)),
            "size_parameter at the upper cut of the size distribution"
        );
        assert_eq!(
            name(bulk_optics(
                &ln(1e-8, 1.5),
                RefractiveIndex::new(2.0, 0.0),
                1.0,
                550.0,
                &[],
                &q
            )),
            "size_parameter at the lower cut of the size distribution"
        );
        let tiny = PsdQuadrature {
            max_nodes: Some(200),
            ..q
        };
        let r = bulk_optics(
            &ln(0.5, 1.5),
            RefractiveIndex::new(2.0, 0.0),
            1.5,
            550.0,
            &[],
            &tiny,
        );
        assert!(matches!(r, Err(PhysicsError::Invalid(_))), "{r:?}");
    }

    #[test]
    fn serde_forms_are_tagged_and_round_trip() {
        let d = SizeDistribution::Gamma {
            r_eff_um: 0.3,
            v_eff: 0.1,
        };
        let s = serde_json::to_string(&d).unwrap();
        assert_eq!(s, r#"{"kind":"gamma","r_eff_um":0.3,"v_eff":0.1}"#);
        let d2: SizeDistribution =
            serde_json::from_str(r#"{"kind":"log_normal","r_g_um":0.2,"sigma_g":1.5}"#).unwrap();
        assert_eq!(
            d2,
            SizeDistribution::LogNormal {
                r_g_um: 0.2,
                sigma_g: 1.5
            }
        );
        let b = bulk_optics(
            &d2,
            RefractiveIndex::new(2.0, 0.01),
            1.5,
            550.0,
            &[1.0, 0.0],
            &PsdQuadrature::default(),
        )
        .unwrap();
        let back: BulkOptics = serde_json::from_str(&serde_json::to_string(&b).unwrap()).unwrap();
        assert!(rel(back.c_ext_um2, b.c_ext_um2) < 1e-15);
    }
}
