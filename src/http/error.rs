//! The one error enum of the HTTP boundary and its mapping to status codes
//! and RFC 9457 problem+json bodies, and the problem+json of a failed job's
//! stored record. Clients get the problem; the log gets the details of
//! internal errors.

use super::problem::{self, Problem};
use crate::jobs::{FailureRecord, JobError};
use crate::material::SpecError;
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};

/// Seconds a client should wait before retrying a refused submission.
pub const RETRY_AFTER_SECS: u64 = 5;

/// Everything an HTTP handler can fail with.
#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    /// The body is not a valid spec (malformed JSON, wrong type, unknown
    /// key, missing field, out of range): 422.
    #[error("{0}")]
    InvalidSpec(SpecError),
    /// Invalid evaluation parameters (angles, wavelength, body): 422.
    #[error("{path}: {message}")]
    InvalidQuery {
        /// The parameter or JSON path.
        path: String,
        /// What is allowed.
        message: String,
    },
    /// Invalid parameters of `GET …/table` (format, dtype, grid): 422.
    #[error("{path}: {message}")]
    InvalidTableQuery {
        /// The parameter.
        path: String,
        /// What is allowed.
        message: String,
    },
    /// The route exists but not for this method: 405 with `Allow`.
    #[error("{method} is not allowed on {path}; allowed: {allow}")]
    MethodNotAllowed {
        /// The method asked for.
        method: String,
        /// The request path.
        path: String,
        /// The methods the route answers (the `Allow` header).
        allow: String,
    },
    /// The spec is valid but exceeds a service cap: 422.
    #[error("{path}: {message}")]
    LimitExceeded {
        /// JSON path.
        path: String,
        /// What is allowed.
        message: String,
    },
    /// The body is larger than `--max-body-bytes`: 413.
    #[error("request body larger than {limit} bytes")]
    PayloadTooLarge {
        /// The cap.
        limit: usize,
    },
    /// The body could not be read: 400.
    #[error("could not read the request body: {0}")]
    BadBody(String),
    /// A content type other than JSON: 415.
    #[error("unsupported content type '{0}'")]
    UnsupportedMediaType(String),
    /// Missing or wrong bearer token: 401.
    #[error("missing or invalid bearer token")]
    Unauthorized,
    /// No such id: 404.
    #[error("no BRDF with id '{0}'")]
    NotFound(String),
    /// The id names a result of an older schema/solver version: 410. Such
    /// results are never served (docs/service.md, "Ids and versions").
    #[error(
        "BRDF {id} was computed by {version}, which this service ({current}) retired; submit the same spec again (POST /v1/brdfs) to compute it under the current version, id {current_id}"
    )]
    Retired {
        /// The requested (old) id.
        id: String,
        /// The version that made it.
        version: String,
        /// The running version.
        current: String,
        /// The id of the same canonical spec under the running version.
        current_id: String,
    },
    /// No such route: 404.
    #[error("no route {0}")]
    NoRoute(String),
    /// The job has no result yet: 409.
    #[error("BRDF {id} is {status}: the table is not available yet")]
    NotReady {
        /// Spec id.
        id: String,
        /// Its state.
        status: &'static str,
    },
    /// A queued or running job cannot be deleted: 409.
    #[error("BRDF {id} is {status}: a job in progress cannot be deleted")]
    InProgress {
        /// Spec id.
        id: String,
        /// Its state.
        status: &'static str,
    },
    /// The job failed: 409, with the job's error.
    #[error("BRDF {id} failed: {}", .problem.detail)]
    JobFailed {
        /// Spec id.
        id: String,
        /// The stored problem.
        problem: Box<Problem>,
    },
    /// `--max-queue` jobs are waiting: 503 with Retry-After.
    #[error("{0}")]
    QueueFull(JobError),
    /// Shutting down: 503 with Retry-After.
    #[error("the service is shutting down")]
    ShuttingDown,
    /// Anything else: 500 (details logged, not sent).
    #[error("internal error: {0}")]
    Internal(String),
}

impl From<JobError> for ApiError {
    fn from(e: JobError) -> Self {
        match e {
            JobError::QueueFull { .. } => ApiError::QueueFull(e),
            JobError::ShuttingDown => ApiError::ShuttingDown,
            JobError::Storage(m) => ApiError::Internal(m),
        }
    }
}

impl From<crate::storage::StorageError> for ApiError {
    fn from(e: crate::storage::StorageError) -> Self {
        ApiError::Internal(e.to_string())
    }
}

impl ApiError {
    /// The problem details of this error.
    pub fn problem(&self) -> Problem {
        match self {
            ApiError::InvalidSpec(e) => {
                Problem::new("invalid-spec", "Invalid spec", 422, e.to_string()).at(e.path.clone())
            }
            ApiError::InvalidQuery { path, message } => Problem::new(
                "invalid-query",
                "Invalid evaluation request",
                422,
                format!("{path}: {message}"),
            )
            .at(path.clone()),
            ApiError::InvalidTableQuery { path, message } => Problem::new(
                "invalid-table-query",
                "Invalid table request",
                422,
                format!("{path}: {message}"),
            )
            .at(path.clone()),
            ApiError::MethodNotAllowed { .. } => Problem::new(
                "method-not-allowed",
                "Method not allowed",
                405,
                self.to_string(),
            ),
            ApiError::LimitExceeded { path, message } => Problem::new(
                "limit-exceeded",
                "Spec exceeds a service limit",
                422,
                format!("{path}: {message}"),
            )
            .at(path.clone()),
            ApiError::PayloadTooLarge { .. } => Problem::new(
                "payload-too-large",
                "Request body too large",
                413,
                self.to_string(),
            ),
            ApiError::BadBody(_) => {
                Problem::new("bad-request", "Bad request", 400, self.to_string())
            }
            ApiError::UnsupportedMediaType(_) => Problem::new(
                "unsupported-media-type",
                "Unsupported media type",
                415,
                format!("{self}: send application/json"),
            ),
            ApiError::Unauthorized => {
                Problem::new("unauthorized", "Unauthorized", 401, self.to_string())
            }
            ApiError::NotFound(_) | ApiError::NoRoute(_) => {
                Problem::new("not-found", "Not found", 404, self.to_string())
            }
            ApiError::Retired { .. } => Problem::new(
                "retired-version",
                "Result of a retired solver version",
                410,
                self.to_string(),
            ),
            ApiError::NotReady { .. } => {
                Problem::new("not-ready", "Result not ready", 409, self.to_string())
            }
            ApiError::InProgress { .. } => {
                Problem::new("job-in-progress", "Job in progress", 409, self.to_string())
            }
            ApiError::JobFailed { problem, .. } => {
                let mut p = Problem::new("job-failed", "BRDF job failed", 409, self.to_string());
                p.path = problem.path.clone();
                p.wavelength_nm = problem.wavelength_nm;
                p.retryable = problem.retryable;
                p
            }
            ApiError::QueueFull(_) => Problem::new(
                "queue-full",
                "Queue full",
                503,
                format!("{self}; retry later"),
            ),
            ApiError::ShuttingDown => {
                Problem::new("shutting-down", "Shutting down", 503, self.to_string())
            }
            ApiError::Internal(_) => Problem::new(
                "internal-error",
                "Internal error",
                500,
                "an internal error occurred; it has been logged",
            ),
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        if let ApiError::Internal(detail) = &self {
            tracing::error!(%detail, "internal error");
        }
        let p = self.problem();
        let status = StatusCode::from_u16(p.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
        let body = serde_json::to_vec(&p).expect("problem JSON");
        let mut res = (status, body).into_response();
        let h = res.headers_mut();
        h.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static(problem::MEDIA_TYPE),
        );
        match self {
            ApiError::MethodNotAllowed { allow, .. } => {
                if let Ok(v) = HeaderValue::from_str(&allow) {
                    // Replaces axum's (empty under route layers) header.
                    h.insert(header::ALLOW, v);
                }
            }
            ApiError::QueueFull(_) | ApiError::ShuttingDown => {
                h.insert(header::RETRY_AFTER, HeaderValue::from(RETRY_AFTER_SECS));
            }
            ApiError::NotReady { .. } => {
                h.insert(header::RETRY_AFTER, HeaderValue::from(1u64));
            }
            ApiError::Unauthorized => {
                h.insert(
                    header::WWW_AUTHENTICATE,
                    HeaderValue::from_static("Bearer realm=\"polbrdf\""),
                );
            }
            _ => {}
        }
        res
    }
}

/// A failed job's stored record as problem+json: field for field, so a
/// row renders the same body whichever version of the service wrote it.
impl From<FailureRecord> for Problem {
    fn from(r: FailureRecord) -> Self {
        Problem {
            type_: r.type_,
            title: r.title,
            status: r.status,
            detail: r.detail,
            path: r.path,
            wavelength_nm: r.wavelength_nm,
            retryable: r.retryable,
        }
    }
}

impl ApiError {
    /// A body that could not be read: over `--max-body-bytes` is 413, any
    /// other failure 400.
    pub fn from_body(e: axum::extract::rejection::BytesRejection, limit: usize) -> Self {
        use axum::extract::rejection::{BytesRejection, FailedToBufferBody};
        match e {
            BytesRejection::FailedToBufferBody(FailedToBufferBody::LengthLimitError(_)) => {
                ApiError::PayloadTooLarge { limit }
            }
            other => ApiError::BadBody(other.body_text()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Stored records (as rows of every version hold them) render as the
    /// same JSON object.
    #[test]
    fn a_stored_record_renders_as_itself() {
        for stored in [
            r#"{"type":"/problems/invalid-spec","title":"Invalid spec","status":422,"detail":"m = 1","path":"layers[0].scatterer.mie","wavelength_nm":550.0,"retryable":false}"#,
            r#"{"type":"/problems/job-abandoned","title":"Job abandoned","status":500,"detail":"started 3 times","retryable":true}"#,
            r#"{"type":"/problems/invalid-spec","title":"Invalid spec","status":422,"detail":"x","path":"layers"}"#,
        ] {
            let record: FailureRecord = serde_json::from_str(stored).unwrap();
            let problem = Problem::from(record);
            assert_eq!(serde_json::to_string(&problem).unwrap(), stored);
        }
    }
}
