//! What a table file says about itself (docs/table-format.md,
//! "Metadata"), and the direction pairs it is queried at.

use super::BrdfError;
use crate::material::needs::{IncidentNeed, StokesNeed};
use serde::{Deserialize, Serialize};

/// A direction pair in the graphics convention (degrees; both directions
/// point away from the surface, conventions §5). The field names are those
/// of `polbrdf solve --points`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Directions {
    /// Incident polar angle, `[0, 90]`.
    pub theta_i_deg: f64,
    /// Incident azimuth.
    pub phi_i_deg: f64,
    /// Outgoing polar angle, `[0, 90]`.
    pub theta_o_deg: f64,
    /// Outgoing azimuth.
    pub phi_o_deg: f64,
}

impl Directions {
    /// Check the ranges of `polbrdf solve --points` (θ in `[0, 90]`, φ in
    /// `[−360, 360]`, finite).
    pub fn validate(&self) -> Result<(), BrdfError> {
        let check = |what: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(BrdfError::Query(format!(
                    "{what} = {v} is outside [{lo}, {hi}]"
                )))
            }
        };
        check("theta_i_deg", self.theta_i_deg, 0.0, 90.0)?;
        check("theta_o_deg", self.theta_o_deg, 0.0, 90.0)?;
        check("phi_i_deg", self.phi_i_deg, -360.0, 360.0)?;
        check("phi_o_deg", self.phi_o_deg, -360.0, 360.0)
    }
}

/// The solver's error estimate (`solver::accuracy::ErrorEstimate`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EstimateMeta {
    /// Estimated max |error of f11| relative to max f11.
    pub max_err_f11: f64,
    /// Streams of the solves used (`N/2`, `3N/4`, `N`; `N/2`, `N/2`, `N`
    /// for a truncation-dominated answer, `solver::accuracy`).
    pub streams: [usize; 3],
    /// Observed contraction `d(3N/4, N)/d(N/2, 3N/4)` (informational;
    /// `null` when undefined).
    #[serde(default)]
    pub contraction: Option<f64>,
}

/// Numerical settings of the solver, as recorded in the metadata.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolverMeta {
    /// Quadrature points per hemisphere (the fixed or default count; with
    /// a tolerance see the per-wavelength `streams`).
    pub streams: usize,
    /// `solver.tolerance` of the spec, if any (streams chosen per wavelength).
    pub tolerance: Option<f64>,
    /// Vector or scalar RTE.
    pub polarized: bool,
    /// Thin start layer relative to the smallest quadrature cosine.
    pub start_factor: f64,
    /// Fourier series stopping tolerance.
    pub fourier_tolerance: f64,
    /// Highest order requested (`null`: all).
    pub max_order: Option<usize>,
}

/// Per-wavelength metadata.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WavelengthMeta {
    /// Vacuum wavelength (nm), `null` for a wavelength-free spec.
    pub wavelength_nm: Option<f64>,
    /// Fourier orders stored.
    pub fourier_orders: usize,
    /// Solver wall time (ms).
    pub wall_time_ms: f64,
    /// Quadrature streams of the solve.
    pub streams: usize,
    /// The solver's a-posteriori error estimate, when one was made (specs
    /// with `solver.tolerance`, docs/spec.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error_estimate: Option<EstimateMeta>,
    /// Measured interpolation error of f11 relative to max f11, for a grid
    /// the request chose (`needs.grid`): the largest error at probe angles
    /// between the nodes (`PolarGrid::probe_theta_deg`), against the
    /// solver there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interpolation_error: Option<f64>,
}

/// The JSON metadata of a table file (docs/table-format.md).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Metadata {
    /// `polbrdf <version>`.
    pub generator: String,
    /// The material spec the table was built from (docs/spec.md).
    pub spec: serde_json::Value,
    /// The spec's id (SHA-256 of its canonical form, `plan::id`).
    pub spec_hash: String,
    /// Solver settings.
    pub solver: SolverMeta,
    /// How the polar grid was made.
    pub grid: String,
    /// How the table is interpolated.
    pub interpolation: String,
    /// Frames and normalisation.
    pub conventions: String,
    /// Per wavelength: orders and timings.
    pub wavelengths: Vec<WavelengthMeta>,
    /// Which Mueller elements the table holds (`needs.stokes`; absent:
    /// all of them). The binary layout says the same (`ns`, flag bit 2).
    #[serde(default, skip_serializing_if = "StokesNeed::is_full")]
    pub stokes: StokesNeed,
    /// The incident polar angles the table may be evaluated at
    /// (`needs.theta_i_deg`, normalized; absent: all).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub theta_i_deg: Option<IncidentNeed>,
}
