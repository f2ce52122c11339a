//! RFC 9457 problem details: the error body of every HTTP error
//! (`application/problem+json`). [`super::error`] maps every [`super::ApiError`]
//! and the stored failure of a job to one.

use serde::{Deserialize, Serialize};

/// A problem details object (`application/problem+json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Problem {
    /// Problem type: `/problems/<slug>` (docs/service.md, "Errors").
    #[serde(rename = "type")]
    pub type_: String,
    /// Short summary of the problem type.
    pub title: String,
    /// HTTP status.
    pub status: u16,
    /// What went wrong in this instance, naming the field and the allowed
    /// range where there is one.
    pub detail: String,
    /// JSON path of the offending field (`layers[0].scatterer.mie.radius_um`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<String>,
    /// The wavelength whose solve failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wavelength_nm: Option<f64>,
    /// For failed jobs: whether submitting the spec again solves it again
    /// (internal errors) or returns this failure (deterministic errors).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retryable: Option<bool>,
}

/// Media type of problem bodies.
pub const MEDIA_TYPE: &str = "application/problem+json";

impl Problem {
    /// A problem of type `/problems/<slug>`.
    pub fn new(slug: &str, title: &str, status: u16, detail: impl Into<String>) -> Self {
        Self {
            type_: format!("/problems/{slug}"),
            title: title.into(),
            status,
            detail: detail.into(),
            path: None,
            wavelength_nm: None,
            retryable: None,
        }
    }

    /// With the JSON path of the offending field.
    pub fn at(mut self, path: impl Into<String>) -> Self {
        self.path = Some(path.into());
        self
    }
}
