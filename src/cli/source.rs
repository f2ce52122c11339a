//! Where a CLI command reads a BRDF table from: a local table file
//! (docs/table-format.md) or a running service (`http://HOST:PORT/v1/brdfs/ID`,
//! with or without the trailing `/table`). Either way the bytes are verified
//! (magic, version, SHA-256) before use.

use crate::brdf::Table;
use crate::brdf::format;
use std::io::Read;
use std::time::Duration;

/// Largest table accepted from a server (bytes).
const MAX_REMOTE_BYTES: u64 = 4 << 30;

/// The URL of the binary table for a source that names a service result.
/// `None` for a local path.
pub fn table_url(source: &str) -> Option<String> {
    if !(source.starts_with("http://") || source.starts_with("https://")) {
        return None;
    }
    let base = source.trim_end_matches('/');
    Some(if base.ends_with("/table") {
        base.to_string()
    } else {
        format!("{base}/table")
    })
}

/// Read and verify a table from a file path or a service URL.
pub fn load_table(source: &str) -> Result<Table, String> {
    let Some(url) = table_url(source) else {
        return format::read_file(source).map_err(|e| e.to_string());
    };
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .timeout_global(Some(Duration::from_secs(600)))
        .http_status_as_error(false)
        .build()
        .into();
    let mut resp = agent.get(&url).call().map_err(|e| format!("{url}: {e}"))?;
    let status = resp.status().as_u16();
    let mut body = Vec::new();
    resp.body_mut()
        .as_reader()
        .take(MAX_REMOTE_BYTES)
        .read_to_end(&mut body)
        .map_err(|e| format!("{url}: reading the body: {e}"))?;
    if status != 200 {
        let text = String::from_utf8_lossy(&body[..body.len().min(2000)]).into_owned();
        return Err(format!("{url}: HTTP {status}: {text}"));
    }
    format::from_bytes(&body).map_err(|e| format!("{url}: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn service_urls_point_at_the_table_resource() {
        assert_eq!(
            table_url("http://127.0.0.1:8080/v1/brdfs/abc").as_deref(),
            Some("http://127.0.0.1:8080/v1/brdfs/abc/table")
        );
        assert_eq!(
            table_url("http://h/v1/brdfs/abc/table/").as_deref(),
            Some("http://h/v1/brdfs/abc/table")
        );
        assert_eq!(table_url("results/paint.pbrdf"), None);
    }

    #[test]
    fn a_missing_file_names_the_path() {
        let e = load_table("/nonexistent/x.pbrdf").unwrap_err();
        assert!(e.contains("/nonexistent/x.pbrdf"), "{e}");
    }
}
