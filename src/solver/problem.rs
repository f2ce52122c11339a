//! The problem the solver takes: layers, base, settings, and its typed errors.

use crate::physics::expansion::GreekCoefficients;
use crate::physics::stokes::Mueller;

/// Optical thickness of a layer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Thickness {
    /// A finite slab, `τ ≥ 0`.
    Finite(f64),
    /// Semi-infinite (must be the last layer; the base is then irrelevant).
    Infinite,
}

impl Thickness {
    /// The optical thickness as a number (`+inf` for a semi-infinite layer).
    pub fn value(self) -> f64 {
        match self {
            Thickness::Finite(t) => t,
            Thickness::Infinite => f64::INFINITY,
        }
    }
}

/// One homogeneous layer: thickness, single-scattering albedo and the Greek
/// coefficients of its scattering matrix (conventions §4).
#[derive(Clone, Debug)]
pub struct Layer {
    /// Optical thickness.
    pub thickness: Thickness,
    /// Single-scattering albedo `ω ∈ [0, 1]`.
    pub albedo: f64,
    /// Expansion coefficients (β_0 = 1).
    pub coef: GreekCoefficients,
}

/// The lower boundary.
#[derive(Clone)]
pub enum Base {
    /// Nothing is reflected.
    Black,
    /// Depolarizing Lambertian reflector.
    Lambertian {
        /// Hemispherical reflectance in `[0, 1]`.
        albedo: f64,
    },
    /// Smooth specular interface (Fresnel); `mueller(μ)` is its reflection
    /// Mueller matrix at incidence cosine `μ` in meridian frames
    /// (`physics::fresnel`).
    Mirror {
        /// Reflection Mueller matrix as a function of the incidence cosine.
        mueller: std::sync::Arc<dyn Fn(f64) -> Mueller + Send + Sync>,
    },
    /// Rough surface of GGX microfacets
    /// ([`crate::physics::microfacet::RoughSurface`]), reflecting into
    /// every Fourier order ([`super::rough_base`]).
    Rough {
        /// The surface (its ambient index is the binder's).
        surface: crate::physics::microfacet::RoughSurface,
    },
}

impl std::fmt::Debug for Base {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Base::Black => write!(f, "Black"),
            Base::Lambertian { albedo } => write!(f, "Lambertian {{ albedo: {albedo} }}"),
            Base::Mirror { mueller } => {
                write!(f, "Mirror {{ normal incidence: {:?} }}", mueller(1.0))
            }
            Base::Rough { surface } => write!(f, "Rough {{ {surface:?} }}"),
        }
    }
}

/// Numerical settings.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Quadrature points per hemisphere.
    pub streams: usize,
    /// Vector (4 Stokes components) or scalar RTE with `a1` only.
    pub polarized: bool,
    /// Thickness of the thin starting layer relative to the smallest
    /// quadrature cosine (diamond start; its error scales as the square).
    pub start_factor: f64,
    /// Highest Fourier order to compute (`None`: all orders the phase
    /// matrices carry).
    pub max_order: Option<usize>,
    /// Stop the Fourier series after two consecutive orders whose largest
    /// BRDF coefficient is below this fraction of order 0's.
    pub fourier_tolerance: f64,
    /// Delta-M truncation of series longer than `2N` terms plus the exact
    /// single-scattering correction at user angles ([`truncation`]); a no-op
    /// when every series fits the quadrature.
    pub delta_m: bool,
    /// With delta-M, also correct double scattering through the truncated
    /// peak at user angles ([`secondary`]); off only to compare with codes
    /// that correct single scattering alone (DISORT's reflected intensities).
    pub secondary_scattering: bool,
    /// Solve even when a series is [`SolverError::Unresolved`]: only for the
    /// coarse solves of an error estimate (`accuracy`), whose job is to be
    /// worse than the answer.
    pub allow_unresolved: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            streams: 16,
            polarized: true,
            start_factor: 0.1,
            max_order: None,
            fourier_tolerance: 1e-9,
            delta_m: true,
            secondary_scattering: true,
            allow_unresolved: false,
        }
    }
}

/// A dielectric interface above the layers: the layers lie in a binder of
/// real index `index ≥ 1` under air (index 1). Smooth (`alpha: None`), light
/// enters and leaves the stack through it by Fresnel refraction, and light
/// scattered up is partly (beyond the critical angle, totally) reflected
/// back down ([`interface`](super::interface)); rough, its GGX facets do
/// the same in a lobe of width `~alpha`
/// ([`rough_interface`](super::rough_interface)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TopInterface {
    /// Refractive index of the binder (real; air above has index 1).
    pub index: f64,
    /// GGX roughness of a rough interface; `None` for a smooth one.
    pub alpha: Option<f64>,
}

/// A problem: layers top to bottom on a base, under an optional interface.
#[derive(Clone, Debug)]
pub struct Problem {
    /// Layers, top first.
    pub layers: Vec<Layer>,
    /// Lower boundary.
    pub base: Base,
    /// Numerical settings.
    pub settings: Settings,
    /// A smooth binder/air interface on top (`None`: the layers face the
    /// ambient medium directly, the seed's model).
    pub top_interface: Option<TopInterface>,
}

/// Typed solver errors.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SolverError {
    /// The input is not a valid problem.
    #[error("invalid problem: {0}")]
    Invalid(String),
    /// A non-finite number appeared (never returned silently).
    #[error("numerical failure: {0}")]
    NonFinite(String),
    /// A layer's phase matrix has terms the streams cannot integrate and no
    /// forward peak delta-M could remove (e.g. a backward-peaked
    /// Henyey–Greenstein function): solving would create or destroy energy
    /// and can give negative radiances.
    #[error(
        "layers[{layer}]: the phase function is not forward-peaked and has terms up to l = {terms} (|β_l|/(2l+1) up to {size:.1e} beyond l = 2N − 1 = {}), which {streams} streams cannot integrate; use at least {needed} streams (or solver.tolerance)",
        2 * streams - 1
    )]
    Unresolved {
        /// Index of the layer.
        layer: usize,
        /// Length of its series minus one.
        terms: usize,
        /// Largest `|β_l|/(2l+1)` beyond the quadrature's reach.
        size: f64,
        /// Streams of the problem.
        streams: usize,
        /// Fewest streams that resolve the series to [`UNRESOLVED_TOLERANCE`].
        needed: usize,
    },
    /// `solver.tolerance` was not reached within the allowed streams.
    #[error(
        "solver.tolerance {tolerance:e} was not reached: the estimated error at {streams} streams (the most allowed) is {estimate:.2e}; raise the stream cap or loosen the tolerance"
    )]
    ToleranceNotMet {
        /// The requested tolerance (max error of f11 relative to max f11).
        tolerance: f64,
        /// The estimate reached at the largest allowed stream count.
        estimate: f64,
        /// That stream count.
        streams: usize,
    },
}
