//! OpenAPI documentation of a spec's `needs` member (docs/spec.md, "What a
//! request needs"). Documentation only: specs are read by
//! `material::parse` (`material::needs`), these types mirror them.

use utoipa::ToSchema;

/// The spec's optional `needs` member (docs/spec.md, "What a request
/// needs"): what the request needs of its result. At their defaults (absent)
/// the result is the full product and the needs stay out of the canonical
/// form. Documentation only: the spec is read by `material::parse`.
#[derive(ToSchema)]
#[allow(dead_code)]
pub struct NeedsDocument {
    /// `false`: one solve, no error estimate (refused with
    /// `solver.tolerance`). Default `true`.
    error_estimate: Option<bool>,
    /// The table grid.
    grid: Option<GridNeedDocument>,
    /// Which Mueller elements the result holds; default `"full"`.
    stokes: Option<StokesNeedDocument>,
    /// The incident polar angles the result holds (degrees, each finite in
    /// `[0, 90)`); `eval` elsewhere is 422. Default: all.
    theta_i_deg: Option<IncidentNeedDocument>,
}

/// `needs.grid`.
#[derive(ToSchema)]
#[allow(dead_code)]
pub struct GridNeedDocument {
    /// Polar nodes of the table, `[6, 256]`; default 64.
    polar_nodes: Option<u32>,
    /// Fourier orders synthesized, `≥ 1`; default: until converged.
    max_fourier_orders: Option<u32>,
}

/// `needs.stokes`: `full` (4×4), `unpolarized_in` (Mueller column 0:
/// `eval` answers `[[m00],[m10],[m20],[m30]]`) or `intensity` (f11:
/// `[[m00]]`).
#[derive(ToSchema)]
#[allow(dead_code)]
#[serde(rename_all = "snake_case")]
pub enum StokesNeedDocument {
    /// All 16 elements.
    Full,
    /// Column 0: unpolarized light in, polarized response out.
    UnpolarizedIn,
    /// f11 alone.
    Intensity,
}

/// `needs.theta_i_deg`: a list of 1–256 angles, or a range.
#[derive(ToSchema)]
#[allow(dead_code)]
#[serde(untagged)]
pub enum IncidentNeedDocument {
    /// These angles only (evaluated within 1e-9° of one).
    Angles(Vec<f64>),
    /// Every angle in `[min, max]`.
    Range {
        /// Smallest angle.
        min: f64,
        /// Largest angle, `≥ min`.
        max: f64,
    },
}
