//! The two requests a render node makes of the service: the table bytes
//! (`GET /v1/brdfs/{id}/table`, conditional with `If-None-Match`) and the
//! job's state (`GET /v1/brdfs/{id}`: `status`, `result.digest`).
//! Blocking HTTP/1.1 (ureq, no TLS); HTTP error statuses are answers
//! here, only transport failures are errors.

use super::FetchError;
use serde_json::Value;
use std::io::Read;
use std::time::Duration;

/// Largest table accepted from a server (bytes).
pub const MAX_TABLE_BYTES: u64 = 4 << 30;

/// Largest error or status body read (bytes).
const MAX_SMALL_BODY: u64 = 1 << 20;

/// An agent with the timeouts of table transfers: 10 s to connect (an
/// unreachable service is noticed quickly, so a node falls back on its
/// cache), 600 s for a whole transfer.
pub fn agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .timeout_connect(Some(Duration::from_secs(10)))
        .timeout_global(Some(Duration::from_secs(600)))
        .http_status_as_error(false)
        .build()
        .into()
}

/// The service as a render node talks to it: the [`agent`] and, for a
/// service started with `--token-reads`, the bearer token sent with every
/// request (docs/service.md, Authentication).
#[derive(Clone, Debug)]
pub struct Remote {
    agent: ureq::Agent,
    token: Option<String>,
}

impl Remote {
    /// A client that sends `token` (if any) as `Authorization: Bearer`.
    pub fn new(token: Option<&str>) -> Self {
        Self {
            agent: agent(),
            token: token.filter(|t| !t.is_empty()).map(str::to_string),
        }
    }

    fn get(&self, url: &str) -> ureq::RequestBuilder<ureq::typestate::WithoutBody> {
        let req = self.agent.get(url);
        match &self.token {
            Some(t) => req.header("Authorization", format!("Bearer {t}")),
            None => req,
        }
    }
}

/// What `GET …/table` answered.
#[derive(Debug)]
pub enum TableAnswer {
    /// 200: the bytes, and the digest of the `ETag` (quotes and a `W/`
    /// removed) when there is one.
    Body {
        bytes: Vec<u8>,
        etag: Option<String>,
    },
    /// 304: the cached bytes are current.
    NotModified,
    /// 409 `not-ready`: queued or running (or being solved again).
    NotReady { detail: String },
    /// Any other status, with the problem's `type` and `detail` (or the
    /// start of the body).
    Status {
        status: u16,
        problem: Option<String>,
        detail: String,
    },
}

/// The digest an `ETag` header value names: `"<hex>"` or `W/"<hex>"`.
pub fn etag_digest(etag: &str) -> String {
    etag.trim()
        .trim_start_matches("W/")
        .trim_matches('"')
        .to_string()
}

fn transport(url: &str, e: impl std::fmt::Display) -> FetchError {
    FetchError::Unreachable {
        url: url.to_string(),
        message: e.to_string(),
    }
}

/// The problem `type` (without `/problems/`) and `detail` of an error
/// body, or the start of the body when it is not a problem.
fn problem_of(body: &[u8]) -> (Option<String>, String) {
    match serde_json::from_slice::<Value>(body) {
        Ok(v) if v["type"].is_string() => (
            v["type"]
                .as_str()
                .map(|t| t.trim_start_matches("/problems/").to_string()),
            v["detail"].as_str().unwrap_or_default().to_string(),
        ),
        _ => (
            None,
            String::from_utf8_lossy(&body[..body.len().min(2000)]).into_owned(),
        ),
    }
}

impl Remote {
    /// `GET url` (a table URL), with `If-None-Match: "<digest>"` when given.
    pub fn get_table(
        &self,
        url: &str,
        if_none_match: Option<&str>,
    ) -> Result<TableAnswer, FetchError> {
        let mut req = self.get(url);
        if let Some(d) = if_none_match {
            req = req.header("If-None-Match", format!("\"{d}\""));
        }
        let mut resp = req.call().map_err(|e| transport(url, e))?;
        let status = resp.status().as_u16();
        let etag = resp
            .headers()
            .get("etag")
            .and_then(|v| v.to_str().ok())
            .map(etag_digest);
        let limit = if status == 200 {
            MAX_TABLE_BYTES
        } else {
            MAX_SMALL_BODY
        };
        let mut body = Vec::new();
        resp.body_mut()
            .as_reader()
            .take(limit)
            .read_to_end(&mut body)
            .map_err(|e| transport(url, format!("reading the body: {e}")))?;
        Ok(match status {
            200 => TableAnswer::Body { bytes: body, etag },
            304 => TableAnswer::NotModified,
            _ => match problem_of(&body) {
                (Some(p), detail) if status == 409 && p == "not-ready" => {
                    TableAnswer::NotReady { detail }
                }
                (problem, detail) => TableAnswer::Status {
                    status,
                    problem,
                    detail,
                },
            },
        })
    }

    /// `GET url` (a resource URL): the status code and the JSON body.
    pub fn get_resource(&self, url: &str) -> Result<(u16, Value), FetchError> {
        let mut resp = self.get(url).call().map_err(|e| transport(url, e))?;
        let status = resp.status().as_u16();
        let mut body = Vec::new();
        resp.body_mut()
            .as_reader()
            .take(MAX_SMALL_BODY)
            .read_to_end(&mut body)
            .map_err(|e| transport(url, format!("reading the body: {e}")))?;
        let v = serde_json::from_slice(&body)
            .unwrap_or_else(|_| Value::String(String::from_utf8_lossy(&body).into_owned()));
        Ok((status, v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn etags_name_digests() {
        assert_eq!(etag_digest("\"ab12\""), "ab12");
        assert_eq!(etag_digest("W/\"ab12\""), "ab12");
        assert_eq!(etag_digest(" \"ab12\" "), "ab12");
    }

    #[test]
    fn problems_are_read_and_other_bodies_kept() {
        let (t, d) = problem_of(br#"{"type":"/problems/not-ready","detail":"queued"}"#);
        assert_eq!(t.as_deref(), Some("not-ready"));
        assert_eq!(d, "queued");
        let (t, d) = problem_of(b"<html>bad gateway</html>");
        assert_eq!(t, None);
        assert_eq!(d, "<html>bad gateway</html>");
    }
}
