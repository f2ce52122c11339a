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

/// Every `$ref` of the committed document names a schema it defines (a
/// parameter type that is not registered would leave a dangling reference).
#[test]
fn every_reference_resolves() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/api/openapi.json");
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    fn walk(v: &serde_json::Value, refs: &mut Vec<String>) {
        match v {
            serde_json::Value::Object(m) => {
                if let Some(serde_json::Value::String(r)) = m.get("$ref") {
                    refs.push(r.clone());
                }
                m.values().for_each(|x| walk(x, refs));
            }
            serde_json::Value::Array(a) => a.iter().for_each(|x| walk(x, refs)),
            _ => {}
        }
    }
    let mut refs = Vec::new();
    walk(&doc, &mut refs);
    assert!(!refs.is_empty());
    for r in refs {
        let name = r
            .strip_prefix("#/components/schemas/")
            .unwrap_or_else(|| panic!("unexpected reference {r}"));
        assert!(
            doc["components"]["schemas"].get(name).is_some(),
            "dangling reference {r}"
        );
    }
}

/// The table route documents every media type it serves, and the cache
/// listing is documented next to the submission.
#[test]
fn table_media_types_and_the_listing_are_documented() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/api/openapi.json");
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let content = &doc["paths"]["/v1/brdfs/{id}/table"]["get"]["responses"]["200"]["content"];
    for media in [
        "application/vnd.polbrdf.table; version=4",
        "application/x-npy",
        "application/json",
        "application/octet-stream",
    ] {
        assert!(content.get(media).is_some(), "{media} missing: {content}");
    }
    let list = &doc["paths"]["/v1/brdfs"]["get"];
    assert!(list.is_object(), "GET /v1/brdfs missing");
    let params: Vec<&str> = list["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        params,
        [
            "limit",
            "cursor",
            "status",
            "material",
            "base",
            "wavelength_nm",
            "thickness",
            "q",
            "sort"
        ]
    );
    // The console's routes: live events and the pictures of a result.
    for (path, media) in [
        ("/v1/events", "text/event-stream"),
        ("/v1/brdfs/{id}/thumbnail", "image/png"),
        ("/v1/brdfs/{id}/plot", "image/svg+xml"),
        ("/v1/brdfs/{id}/metadata", "application/json"),
    ] {
        let ok = &doc["paths"][path]["get"]["responses"]["200"]["content"];
        assert!(ok.get(media).is_some(), "{path}: {media} missing: {ok}");
    }
}
