//! The OpenAPI document is generated from the handlers (utoipa) and
//! committed at api/openapi.json; this test fails when they drift.
//! Regenerate with `UPDATE_OPENAPI=1 cargo test --test service_openapi`.

#[test]
fn committed_openapi_document_matches_the_code() {
    let generated = polbrdf::http::openapi()
        .to_pretty_json()
        .expect("OpenAPI JSON")
        + "\n";
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/api/openapi.json");
    if std::env::var_os("UPDATE_OPENAPI").is_some() {
        std::fs::write(path, &generated).expect("write api/openapi.json");
        return;
    }
    let committed = std::fs::read_to_string(path).unwrap_or_default();
    assert!(
        committed == generated,
        "api/openapi.json differs from the document generated from the code; \
         regenerate with `UPDATE_OPENAPI=1 cargo test --test service_openapi` and review the diff"
    );
}

#[test]
fn every_route_is_documented() {
    let doc = polbrdf::http::openapi();
    let paths: Vec<&String> = doc.paths.paths.keys().collect();
    for p in [
        "/v1/brdfs",
        "/v1/brdfs/{id}",
        "/v1/brdfs/{id}/table",
        "/v1/brdfs/{id}/eval",
        "/healthz",
        "/readyz",
        "/metrics",
    ] {
        assert!(
            paths.iter().any(|q| q.as_str() == p),
            "{p} missing: {paths:?}"
        );
    }
}
