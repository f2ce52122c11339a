//! Particle optics: everything that turns "particles of material X, radius r,
//! in a binder of index n" into single-scattering inputs of the solver.
//!
//! Pure: no I/O, no global state. Conventions: `docs/conventions.md`.

pub mod expansion;
pub mod fresnel;
pub mod materials;
pub mod microfacet;
pub mod mie;
pub mod psd;
pub mod quadrature;
pub mod stokes;
pub mod wigner;

use serde::{Deserialize, Serialize};

/// Complex number type used for refractive indices and Mie amplitudes.
pub type C64 = num_complex::Complex64;

/// Complex refractive index `m = n + i k` (conventions §2: `exp(-iωt)`, `k ≥ 0` absorbs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RefractiveIndex {
    /// Real part.
    pub n: f64,
    /// Imaginary part, `≥ 0` for absorbing media.
    pub k: f64,
}

impl RefractiveIndex {
    /// A new index `n + i k`.
    pub const fn new(n: f64, k: f64) -> Self {
        Self { n, k }
    }

    /// As a complex number.
    pub fn as_complex(self) -> C64 {
        C64::new(self.n, self.k)
    }
}

/// The six normalised scattering-matrix functions (conventions §3) sampled at
/// the cosines `mu` of the scattering angle.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ScatteringMatrixSamples {
    /// `cos Θ` of each sample.
    pub mu: Vec<f64>,
    /// `F11`.
    pub a1: Vec<f64>,
    /// `F22`.
    pub a2: Vec<f64>,
    /// `F33`.
    pub a3: Vec<f64>,
    /// `F44`.
    pub a4: Vec<f64>,
    /// `F12`.
    pub b1: Vec<f64>,
    /// `F34`.
    pub b2: Vec<f64>,
}

/// Errors of the physics layer. Each names the quantity and the allowed range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PhysicsError {
    /// A parameter is outside the range in which the method is validated.
    #[error("{name} = {value} is outside the validated range {range}")]
    OutOfRange {
        /// Parameter name, as in the API (e.g. `size_parameter`).
        name: &'static str,
        /// The offending value.
        value: f64,
        /// Human-readable allowed range.
        range: String,
    },
    /// A material name that is not in the built-in library.
    #[error("unknown material '{name}' (known: {known})")]
    UnknownMaterial {
        /// The name asked for.
        name: String,
        /// Comma-separated list of known names.
        known: String,
    },
    /// Any other invalid input, with a message naming the argument.
    #[error("{0}")]
    Invalid(String),
}

/// Default truncation tolerance of the Greek expansion for a Mie population
/// of largest size parameter `x`: `1e-10` for small particles, relaxed for
/// forward-peaked ones (fewer terms for the solver). Both Mie paths project
/// exactly ([`expand_polynomial`]), and the tolerance used is never below
/// ten times the round-off floor measured for the case at hand.
pub fn default_expansion_tolerance(x: f64) -> f64 {
    if x < 20.0 {
        1e-10
    } else if x < 60.0 {
        1e-9
    } else if x < 300.0 {
        1e-7
    } else if x < 1500.0 {
        1e-6
    } else if x < 4000.0 {
        1e-4
    } else {
        1e-3
    }
}

/// The exact Greek expansion of one sphere's scattering matrix.
///
/// With `N` Mie terms, `S1` and `S2` are polynomials of degree `N` in
/// `μ = cos Θ` (`π_n` has degree `n − 1`, `τ_n` degree `n`), so a1…b2 are
/// polynomials of degree `2N`, the series ends at `l = 2N`, and Gauss–Legendre
/// quadrature with `2N + 2` nodes projects every coefficient exactly (the
/// integrand has degree `≤ 4N`). One projection replaces the adaptive search;
/// truncation and the round-off floor are those of [`expand_polynomial`].
pub fn expand_sphere(
    res: &mie::MieResult,
    tolerance: f64,
) -> Result<(expansion::GreekCoefficients, expansion::ExpansionReport), PhysicsError> {
    check_tolerance(tolerance)?;
    let (c, r, _) = expand_sphere_with(res, Ok(tolerance))?;
    Ok((c, r))
}

/// An expansion, its report and the achieved round-trip floor.
type Expanded = (
    expansion::GreekCoefficients,
    expansion::ExpansionReport,
    f64,
);

/// [`expand_sphere`] with the tolerance rule of [`expand_polynomial`].
fn expand_sphere_with(
    res: &mie::MieResult,
    tolerance: Result<f64, f64>,
) -> Result<Expanded, PhysicsError> {
    let l_max = 2 * res.n_terms;
    let (nodes, weights) = quadrature::gauss_legendre(l_max + 2);
    let samples = res.scattering_matrix(&nodes)?;
    expand_polynomial(&samples, &weights, l_max, tolerance, |mu| {
        res.scattering_matrix(mu)
    })
}

fn check_tolerance(tolerance: f64) -> Result<(), PhysicsError> {
    if tolerance > 0.0 && tolerance < 1.0 {
        Ok(())
    } else {
        Err(PhysicsError::OutOfRange {
            name: "expansion_tolerance",
            value: tolerance,
            range: "(0, 1)".into(),
        })
    }
}

/// Truncated Greek expansion of a scattering matrix that is a polynomial of
/// degree `≤ l_max` in `μ` (one sphere, or a fixed finite sum of spheres),
/// from its `samples` at the `l_max + 2` Gauss–Legendre nodes with `weights`
/// (an exact projection, [`expansion::expand`]); `exact(mu)` samples the same
/// function on the check grid.
///
/// 1. **Round-off floor.** The full series (`l = 0..l_max`) reproduces the
///    function up to rounding only; its largest deviation on a grid of
///    `min(2 l_max + 65, 4001)` angles uniform in `Θ`, relative to `max a1`
///    there, is the attainable accuracy `floor` of this case.
/// 2. **Tolerance.** `Ok(t)`: `t`, which must not be below `floor` (else
///    `OutOfRange` naming the attainable range); `Err(default)`:
///    `max(default, 10 floor)`.
/// 3. **Truncation.** Trailing terms below `t · β_0` in all six series are
///    dropped; the round trip of the kept series on the same grid is reported.
///
/// Returns the coefficients, the report and the tolerance used.
pub fn expand_polynomial(
    samples: &ScatteringMatrixSamples,
    weights: &[f64],
    l_max: usize,
    tolerance: Result<f64, f64>,
    exact: impl Fn(&[f64]) -> Result<ScatteringMatrixSamples, PhysicsError>,
) -> Result<Expanded, PhysicsError> {
    let full = expansion::expand(samples, weights, l_max);
    let n_check = (2 * l_max + 65).min(4001);
    // Cosines of equally spaced angles, made exactly antisymmetric
    // (`μ_{n−1−k} = −μ_k`) so that a sphere's or a size distribution's
    // amplitudes take both signs from one recurrence (`mie::MieResult::amplitudes_at`).
    let mut theta: Vec<f64> = (0..n_check)
        .map(|k| (std::f64::consts::PI * k as f64 / (n_check - 1) as f64).cos())
        .collect();
    for k in 0..n_check / 2 {
        theta[n_check - 1 - k] = -theta[k];
    }
    if n_check % 2 == 1 {
        theta[n_check / 2] = 0.0;
    }
    let reference = exact(&theta)?;
    let scale = reference.a1.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let round_trip = |c: &expansion::GreekCoefficients| -> f64 {
        let approx = c.evaluate(&theta);
        let mut worst: f64 = 0.0;
        for (e, a) in [
            (&reference.a1, &approx.a1),
            (&reference.a2, &approx.a2),
            (&reference.a3, &approx.a3),
            (&reference.a4, &approx.a4),
            (&reference.b1, &approx.b1),
            (&reference.b2, &approx.b2),
        ] {
            for (x, y) in e.iter().zip(a.iter()) {
                worst = worst.max((x - y).abs());
            }
        }
        worst / scale
    };
    let floor = round_trip(&full);
    let tol = match tolerance {
        Ok(t) if t < floor => {
            return Err(PhysicsError::OutOfRange {
                name: "tolerance",
                value: t,
                range: format!(
                    "[{floor:.1e}, 1): the exact projection reproduces the scattering \
                     matrix only to that level (round-off of the sampled functions)"
                ),
            });
        }
        Ok(t) => t,
        Err(default) => default.max(10.0 * floor).min(0.5),
    };
    let beta0 = full.beta[0].abs();
    let series = full.series();
    let last = (0..full.len())
        .rev()
        .find(|&l| series.iter().any(|c| c[l].abs() > tol * beta0))
        .unwrap_or(0);
    let coefficients = full.truncated(last);
    let round_trip_error = round_trip(&coefficients);
    Ok((
        coefficients,
        expansion::ExpansionReport {
            n_terms: last + 1,
            n_nodes: weights.len(),
            projection_change: 0.0,
            n_check_points: n_check,
            round_trip_error,
        },
        tol,
    ))
}

/// A Mie population with its expansion: everything the solver needs, plus
/// the report of the expansion.
#[derive(Clone, Debug)]
pub struct MieOptics {
    /// Single-scattering albedo.
    pub albedo: f64,
    /// Asymmetry parameter.
    pub g: f64,
    /// Largest size parameter of the population.
    pub size_parameter: f64,
    /// Greek coefficients (conventions §4).
    pub coefficients: expansion::GreekCoefficients,
    /// How the expansion was obtained.
    pub report: expansion::ExpansionReport,
    /// Truncation tolerance used (the requested one, or the default of
    /// [`expand_polynomial`]).
    pub tolerance: f64,
    /// Mean extinction cross section per particle, µm² (`Q_ext π r²` for one
    /// sphere, `psd::BulkOptics::c_ext_um2` for a distribution).
    pub c_ext_um2: f64,
    /// Mean particle volume, µm³, over the same radii and normalisation as
    /// `c_ext_um2` (`psd::RadiusRule::mean_volume_um3`), so that a volume
    /// fraction `f` of these particles has the extinction coefficient
    /// `f c_ext_um2 / volume_um3` per µm.
    pub volume_um3: f64,
}

/// Single-scattering albedo and Greek coefficients of a Mie population
/// (monodisperse `radius_um` or a size distribution) at one wavelength: the
/// glue between [`mie`]/[`psd`] and [`expansion`]. `tolerance = None` uses
/// [`default_expansion_tolerance`].
pub fn mie_optics(
    index: RefractiveIndex,
    host_index: f64,
    wavelength_nm: f64,
    radius_um: Option<f64>,
    distribution: Option<psd::SizeDistribution>,
    tolerance: Option<f64>,
) -> Result<MieOptics, PhysicsError> {
    match (radius_um, distribution) {
        (Some(r), None) => {
            let res = mie::MieResult::for_sphere(index, host_index, wavelength_nm, r)?;
            let x = res.size_parameter;
            if let Some(t) = tolerance {
                check_tolerance(t)?;
            }
            let tol = tolerance.ok_or_else(|| default_expansion_tolerance(x));
            let (coefficients, report, tolerance) = expand_sphere_with(&res, tol)?;
            Ok(MieOptics {
                albedo: res.albedo,
                g: res.g,
                size_parameter: x,
                coefficients,
                report,
                tolerance,
                c_ext_um2: res.qext * std::f64::consts::PI * r * r,
                volume_um3: 4.0 / 3.0 * std::f64::consts::PI * r.powi(3),
            })
        }
        (None, Some(dist)) => mie_optics_distribution(
            index,
            host_index,
            wavelength_nm,
            &dist,
            &psd::PsdQuadrature::default(),
            tolerance,
        ),
        _ => Err(PhysicsError::Invalid(
            "give exactly one of radius_um and size_distribution".into(),
        )),
    }
}

/// [`mie_optics`] of a size distribution with explicit quadrature settings
/// (e.g. integration limits, `psd::PsdQuadrature::radius_range_um`).
///
/// One adaptive radius quadrature ([`psd::bulk_optics_with_rule`]) is run
/// at the `2N + 2` Gauss nodes (`N` the series length at the upper cut), and
/// the rule it settles on is kept fixed: the averaged matrix is then a
/// polynomial of degree `2N` in `μ`, projected exactly by those nodes and
/// checked on a grid with the same rule ([`expand_polynomial`]). Sampling it
/// by separate adaptive quadratures per angle set (as up to solver version 3)
/// mixed rules whose nodes differ with the angles, a noise of ~1e-8 relative
/// that stalled the projection above the default tolerance.
///
/// The coefficients are those of the rule's average to rounding and the
/// truncation tolerance; the rule differs from the exact size average by the
/// quadrature error `psd::BulkOptics::rel_error_estimate` (≤ `quad.rel_tol`),
/// an error of the optical input (like the Mie series' truncation), not of
/// the expansion: it does not enter the solver's discretization estimate.
pub fn mie_optics_distribution(
    index: RefractiveIndex,
    host_index: f64,
    wavelength_nm: f64,
    dist: &psd::SizeDistribution,
    quad: &psd::PsdQuadrature,
    tolerance: Option<f64>,
) -> Result<MieOptics, PhysicsError> {
    if let Some(t) = tolerance {
        check_tolerance(t)?;
    }
    dist.validate()?;
    let (k, _) = mie::wavenumber_and_index(index, host_index, wavelength_nm)?;
    let [_, r_max] = psd::radius_limits_um(dist, k, quad)?;
    // Out-of-range sizes are reported by the quadrature; do not size the
    // Gauss rule beyond the validated range.
    let x_cut = (k * r_max).min(mie::SIZE_PARAMETER_MAX);
    let l_max = 2 * mie::series_length(x_cut);
    let (nodes, weights) = quadrature::gauss_legendre(l_max + 2);
    let (bulk, rule) =
        psd::bulk_optics_with_rule(dist, index, host_index, wavelength_nm, &nodes, quad)?;
    let x = bulk.size_parameter_max;
    let tol = tolerance.ok_or_else(|| default_expansion_tolerance(x));
    let (coefficients, report, tolerance) =
        expand_polynomial(&bulk.matrix, &weights, l_max, tol, |mu| rule.matrix(mu))?;
    Ok(MieOptics {
        albedo: bulk.albedo,
        g: bulk.g,
        size_parameter: x,
        coefficients,
        report,
        tolerance,
        c_ext_um2: bulk.c_ext_um2,
        volume_um3: rule.mean_volume_um3(),
    })
}

/// [`mie_optics`] with the default tolerance, returning `(albedo, coefficients)`.
pub fn mie_expansion(
    index: RefractiveIndex,
    host_index: f64,
    wavelength_nm: f64,
    radius_um: Option<f64>,
    distribution: Option<psd::SizeDistribution>,
) -> Result<(f64, expansion::GreekCoefficients), PhysicsError> {
    let o = mie_optics(
        index,
        host_index,
        wavelength_nm,
        radius_um,
        distribution,
        None,
    )?;
    Ok((o.albedo, o.coefficients))
}
