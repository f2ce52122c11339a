//! Why a job failed: the typed failure, and the record of it the index keeps
//! in the row's `error` column (migrations/0001_init.sql).
//!
//! The record has the shape of an RFC 9457 problem object (type, title,
//! status, detail, and the optional path, wavelength and retryable flag)
//! because that is what every failed row has stored since the first
//! version; [`FailureRecord`] reads and writes exactly that JSON, so rows
//! of earlier versions read back unchanged. The HTTP layer turns a record
//! into its problem+json body (`http::error`); this layer only decides
//! what the record of each failure says, and whether submitting the spec
//! again solves it again ([`FailureRecord::retryable`]).

use super::result::{SolveFailure, SolveFailureKind};
use crate::material::SpecError;
use crate::storage::JobRow;
use serde::{Deserialize, Serialize};

/// Why a job failed.
#[derive(Clone, Debug, PartialEq)]
pub enum JobFailure {
    /// The spec cannot be solved at some wavelength, or the solver refused
    /// the problem: deterministic, so final.
    Solve(SolveFailure),
    /// The stored spec of an unfinished row no longer parses (found when
    /// the queue is recovered at start-up): final.
    InvalidSpec(SpecError),
    /// The solve was started this many times without finishing (it stopped
    /// the service each time, `--max-attempts`): retryable.
    Abandoned {
        /// Starts so far.
        attempts: i64,
    },
    /// The solve panicked or its result could not be stored (the details
    /// are logged): retryable.
    Internal,
    /// The solve ended without reporting an outcome: retryable.
    NoOutcome,
    /// The result was evicted to keep the cache within `--max-cache-bytes`
    /// (its row says so, so that the next submission solves it again):
    /// retryable.
    Evicted,
}

/// The stored record of a [`JobFailure`]: the JSON object of the row's
/// `error` column, field for field.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FailureRecord {
    /// Problem type: `/problems/<slug>`.
    #[serde(rename = "type")]
    pub type_: String,
    /// Short summary of the problem type.
    pub title: String,
    /// The HTTP status the problem was stored with.
    pub status: u16,
    /// What went wrong.
    pub detail: String,
    /// JSON path of the offending field of the spec.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<String>,
    /// The wavelength whose solve failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wavelength_nm: Option<f64>,
    /// Whether submitting the spec again solves it again.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retryable: Option<bool>,
}

impl FailureRecord {
    fn new(slug: &str, title: &str, status: u16, detail: impl Into<String>) -> Self {
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

    /// What the record of a failure says.
    pub fn of(failure: &JobFailure) -> Self {
        match failure {
            JobFailure::Solve(f) => {
                let (slug, title) = match f.kind {
                    SolveFailureKind::Spec => ("invalid-spec", "Invalid spec"),
                    SolveFailureKind::Solver => ("solver-error", "Solver error"),
                };
                Self {
                    path: f.path.clone(),
                    wavelength_nm: f.wavelength_nm,
                    retryable: Some(false),
                    ..Self::new(slug, title, 422, f.message.clone())
                }
            }
            JobFailure::InvalidSpec(e) => Self {
                path: Some(e.path.clone()),
                ..Self::new("invalid-spec", "Invalid spec", 422, e.message.clone())
            },
            JobFailure::Abandoned { attempts } => Self {
                retryable: Some(true),
                ..Self::new(
                    "job-abandoned",
                    "Job abandoned",
                    500,
                    format!(
                        "the solve was started {attempts} times without finishing (the service stopped during each)"
                    ),
                )
            },
            JobFailure::Internal => Self {
                retryable: Some(true),
                ..Self::new(
                    "internal-error",
                    "Internal error",
                    500,
                    "the solve failed unexpectedly; submitting the spec again retries it",
                )
            },
            JobFailure::Evicted => Self {
                retryable: Some(true),
                ..Self::new(
                    "evicted",
                    "Result evicted",
                    410,
                    "the result was evicted from the cache (--max-cache-bytes); submitting the spec again solves it again",
                )
            },
            JobFailure::NoOutcome => Self {
                retryable: Some(true),
                ..Self::new(
                    "internal-error",
                    "Internal error",
                    500,
                    "the solve ended without an outcome; submitting the spec again retries it",
                )
            },
        }
    }

    /// The JSON text stored in the row.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("failure record JSON")
    }

    /// The record of a failed row (`None` without one, or when the stored
    /// text is not a record).
    pub fn of_row(row: &JobRow) -> Option<Self> {
        row.error
            .as_deref()
            .and_then(|e| serde_json::from_str(e).ok())
    }

    /// Whether submitting the spec again solves it again.
    pub fn retryable(&self) -> bool {
        self.retryable == Some(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stored JSON of every failure, byte for byte what the service
    /// wrote before the failure was typed (a `jobs::Problem` serialized
    /// with `serde_json::to_string`).
    #[test]
    fn records_are_stored_as_before() {
        let solve = |kind| {
            JobFailure::Solve(SolveFailure {
                kind,
                path: Some("layers[0].scatterer.mie".into()),
                message: "m = 1: the particle must differ".into(),
                wavelength_nm: Some(550.0),
            })
        };
        for (failure, json) in [
            (
                solve(SolveFailureKind::Spec),
                r#"{"type":"/problems/invalid-spec","title":"Invalid spec","status":422,"detail":"m = 1: the particle must differ","path":"layers[0].scatterer.mie","wavelength_nm":550.0,"retryable":false}"#,
            ),
            (
                JobFailure::Solve(SolveFailure {
                    kind: SolveFailureKind::Solver,
                    path: None,
                    message: "not reached".into(),
                    wavelength_nm: None,
                }),
                r#"{"type":"/problems/solver-error","title":"Solver error","status":422,"detail":"not reached","retryable":false}"#,
            ),
            (
                JobFailure::InvalidSpec(SpecError::new("layers", "at least one layer is required")),
                r#"{"type":"/problems/invalid-spec","title":"Invalid spec","status":422,"detail":"at least one layer is required","path":"layers"}"#,
            ),
            (
                JobFailure::Abandoned { attempts: 3 },
                r#"{"type":"/problems/job-abandoned","title":"Job abandoned","status":500,"detail":"the solve was started 3 times without finishing (the service stopped during each)","retryable":true}"#,
            ),
            (
                JobFailure::Internal,
                r#"{"type":"/problems/internal-error","title":"Internal error","status":500,"detail":"the solve failed unexpectedly; submitting the spec again retries it","retryable":true}"#,
            ),
            (
                JobFailure::NoOutcome,
                r#"{"type":"/problems/internal-error","title":"Internal error","status":500,"detail":"the solve ended without an outcome; submitting the spec again retries it","retryable":true}"#,
            ),
        ] {
            let record = FailureRecord::of(&failure);
            assert_eq!(record.to_json(), json, "{failure:?}");
            // And it reads back as itself.
            assert_eq!(serde_json::from_str::<FailureRecord>(json).unwrap(), record);
        }
        assert!(!FailureRecord::of(&solve(SolveFailureKind::Spec)).retryable());
        assert!(FailureRecord::of(&JobFailure::Internal).retryable());
        // A final failure found at start-up has no flag: not retryable.
        let e = JobFailure::InvalidSpec(SpecError::new("$", "x"));
        assert!(!FailureRecord::of(&e).retryable());
    }
}
