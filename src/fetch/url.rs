//! The service URLs a render node is given for a result:
//! `http://HOST:PORT[/PREFIX]/v1/brdfs/ID`, with or without a trailing
//! `/table` (docs/service.md, "Endpoints"). Only the id and the base are
//! kept: the cache stores the binary table of an id, nothing else.

use super::FetchError;
use crate::digest::is_sha256_hex;

/// A result on a service, as named by its URL.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ResultUrl {
    /// Everything before `/v1/brdfs/`: `http://HOST:PORT` (plus a path
    /// prefix when the service sits under one behind a proxy).
    pub base: String,
    /// The result's id: 64 lowercase hex digits (the hash of the canonical
    /// spec), so it is also a safe file name.
    pub id: String,
}

impl ResultUrl {
    /// Parse `http://HOST:PORT/v1/brdfs/ID` or `…/ID/table` (a trailing
    /// `/` allowed). Refused: other schemes (`https` too: this build has
    /// no TLS client), a query string (dense exports are not cached), and
    /// anything that is not a 64-hex-digit id.
    pub fn parse(url: &str) -> Result<Self, FetchError> {
        let bad = |why: &str| FetchError::BadUrl {
            url: url.to_string(),
            why: why.to_string(),
        };
        if url.starts_with("https://") {
            return Err(bad(
                "https is not supported (no TLS client in this build): use http to the service or a TLS-terminating proxy",
            ));
        }
        let Some(rest) = url.strip_prefix("http://") else {
            return Err(bad("expected http://HOST:PORT/v1/brdfs/ID"));
        };
        if rest.contains(['?', '#']) {
            return Err(bad(
                "a query or fragment is not allowed: only the binary table of an id is cached",
            ));
        }
        let path = rest.trim_end_matches('/');
        let path = path.strip_suffix("/table").unwrap_or(path);
        let Some((base, id)) = path.rsplit_once("/v1/brdfs/") else {
            return Err(bad("expected http://HOST:PORT/v1/brdfs/ID"));
        };
        if base.is_empty() || base.starts_with('/') {
            return Err(bad("no host"));
        }
        if !is_sha256_hex(id) {
            return Err(bad("the id must be 64 lowercase hex digits"));
        }
        Ok(ResultUrl {
            base: format!("http://{base}"),
            id: id.to_string(),
        })
    }

    /// `GET` this for the job's state (`status`, `result.digest`).
    pub fn resource(&self) -> String {
        format!("{}/v1/brdfs/{}", self.base, self.id)
    }

    /// `GET` this for the table bytes.
    pub fn table(&self) -> String {
        format!("{}/table", self.resource())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ID: &str = "068718c4a5b8827e98565b6b05f362baf8aaa97be541dfec1dbc4b2100e7ba0a";

    #[test]
    fn both_forms_name_the_same_result() {
        for u in [
            format!("http://127.0.0.1:8080/v1/brdfs/{ID}"),
            format!("http://127.0.0.1:8080/v1/brdfs/{ID}/"),
            format!("http://127.0.0.1:8080/v1/brdfs/{ID}/table"),
            format!("http://127.0.0.1:8080/v1/brdfs/{ID}/table/"),
        ] {
            let r = ResultUrl::parse(&u).unwrap();
            assert_eq!(r.base, "http://127.0.0.1:8080", "{u}");
            assert_eq!(r.id, ID);
            assert_eq!(
                r.table(),
                format!("http://127.0.0.1:8080/v1/brdfs/{ID}/table")
            );
            assert_eq!(r.resource(), format!("http://127.0.0.1:8080/v1/brdfs/{ID}"));
        }
    }

    #[test]
    fn a_path_prefix_is_kept() {
        let r = ResultUrl::parse(&format!("http://farm/polbrdf/v1/brdfs/{ID}")).unwrap();
        assert_eq!(r.base, "http://farm/polbrdf");
    }

    #[test]
    fn refusals_say_why() {
        let why = |u: &str| match ResultUrl::parse(u) {
            Err(FetchError::BadUrl { why, .. }) => why,
            other => panic!("{u}: {other:?}"),
        };
        assert!(why(&format!("https://h/v1/brdfs/{ID}")).contains("TLS"));
        assert!(why(&format!("http://h/v1/brdfs/{ID}/table?format=npy")).contains("query"));
        assert!(why("http://h/v1/brdfs/abc").contains("64"));
        assert!(why(&format!("http://h/v1/brdfs/{}", ID.to_uppercase())).contains("64"));
        assert!(why("http://h/v1/brdfs/../../etc/passwd").contains("64"));
        assert!(why(&format!("http:///v1/brdfs/{ID}")).contains("host"));
        assert!(why("ftp://h/x").contains("http://"));
        assert!(why("http://h/v1/scenes").contains("v1/brdfs"));
    }
}
