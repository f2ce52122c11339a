//! Particle optics: everything that turns "particles of material X, radius r,
//! in a binder of index n" into single-scattering inputs of the solver.
//!
//! Pure: no I/O, no global state. Conventions: `docs/conventions.md`.

pub mod expansion;
pub mod fresnel;
pub mod materials;
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
/// forward-peaked ones down to the round-off floor of the projection
/// (`expansion::expand_adaptive`: about `7.5e-9` at `x ≈ 100`; measured
/// floors of the size-distribution path: 1.3e-6 at `x = 2000`, 2.8e-5 at
/// 5000, 2.2e-4 at 10000).
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
/// integrand has degree `≤ 4N`). One projection replaces the adaptive search.
/// Trailing terms below `tolerance · β_0` in all six series are dropped; the
/// round trip is checked on `min(2L + 65, 4001)` angles uniform in `Θ`.
pub fn expand_sphere(
    res: &mie::MieResult,
    tolerance: f64,
) -> Result<(expansion::GreekCoefficients, expansion::ExpansionReport), PhysicsError> {
    if !(tolerance > 0.0 && tolerance < 1.0) {
        return Err(PhysicsError::OutOfRange {
            name: "expansion_tolerance",
            value: tolerance,
            range: "(0, 1)".into(),
        });
    }
    let l_max = 2 * res.n_terms;
    let n_nodes = l_max + 2;
    let (nodes, weights) = quadrature::gauss_legendre(n_nodes);
    let samples = res.scattering_matrix(&nodes)?;
    let full = expansion::expand(&samples, &weights, l_max);
    let beta0 = full.beta[0].abs();
    let series = full.series();
    let last = (0..full.len())
        .rev()
        .find(|&l| series.iter().any(|c| c[l].abs() > tolerance * beta0))
        .unwrap_or(0);
    let coefficients = full.truncated(last);
    let n_check = (2 * last + 65).min(4001);
    let theta: Vec<f64> = (0..n_check)
        .map(|k| (std::f64::consts::PI * k as f64 / (n_check - 1) as f64).cos())
        .collect();
    let exact = res.scattering_matrix(&theta)?;
    let approx = coefficients.evaluate(&theta);
    let scale = exact.a1.iter().cloned().fold(0.0, f64::max);
    let mut worst: f64 = 0.0;
    for (e, a) in [
        (&exact.a1, &approx.a1),
        (&exact.a2, &approx.a2),
        (&exact.a3, &approx.a3),
        (&exact.a4, &approx.a4),
        (&exact.b1, &approx.b1),
        (&exact.b2, &approx.b2),
    ] {
        for (x, y) in e.iter().zip(a.iter()) {
            worst = worst.max((x - y).abs());
        }
    }
    Ok((
        coefficients,
        expansion::ExpansionReport {
            n_terms: last + 1,
            n_nodes,
            projection_change: 0.0,
            n_check_points: n_check,
            round_trip_error: worst / scale,
        },
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
            let tol = tolerance.unwrap_or_else(|| default_expansion_tolerance(x));
            let (coefficients, report) = expand_sphere(&res, tol)?;
            Ok(MieOptics {
                albedo: res.albedo,
                g: res.g,
                size_parameter: x,
                coefficients,
                report,
            })
        }
        (None, Some(dist)) => {
            let quad = psd::PsdQuadrature::default();
            // Bulk quantities (and the largest size parameter) from one pass.
            let probe = psd::bulk_optics(&dist, index, host_index, wavelength_nm, &[1.0], &quad)?;
            let x = probe.size_parameter_max;
            let tol = tolerance.unwrap_or_else(|| default_expansion_tolerance(x));
            let l_hint = (2.0 * x + 10.0).ceil() as usize;
            let (coefficients, report) = expansion::expand_adaptive(
                |mu| {
                    psd::bulk_optics(&dist, index, host_index, wavelength_nm, mu, &quad)
                        .map(|b| b.matrix)
                },
                l_hint,
                tol,
            )?;
            Ok(MieOptics {
                albedo: probe.albedo,
                g: probe.g,
                size_parameter: x,
                coefficients,
                report,
            })
        }
        _ => Err(PhysicsError::Invalid(
            "give exactly one of radius_um and size_distribution".into(),
        )),
    }
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
