//! The canonical form and id test vector of docs/service.md: the documented
//! spec gives the documented canonical JSON, and the documented id is the
//! SHA-256 (computed here with the sha2 crate, independently of the
//! service) of the documented recipe over those literal bytes.

use sha2::{Digest, Sha256};

/// The body of the fenced block whose info string is `info`.
fn block(doc: &str, info: &str) -> String {
    let start = doc
        .find(&format!("```{info}\n"))
        .unwrap_or_else(|| panic!("docs/service.md has no ```{info} block"));
    let body = &doc[start + info.len() + 4..];
    body[..body.find("\n```").expect("closing fence")].to_string()
}

#[test]
fn documented_test_vector() {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/service.md"))
        .expect("docs/service.md");
    let spec_text = block(&doc, "json test-vector-spec");
    let canonical = block(&doc, "json test-vector-canonical");
    let id = block(&doc, "text test-vector-id");

    // The recipe, over the literal documented bytes.
    let preimage = format!("polbrdf-spec/3\npolbrdf-solver/7\n{canonical}");
    let independent: String = Sha256::digest(preimage.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(independent, id.trim(), "documented id vs the recipe");

    // The implementation agrees with the documentation.
    let spec = polbrdf::material::parse(&spec_text).expect("documented spec parses");
    let (c, i) = polbrdf::plan::id_of_spec(&spec);
    assert_eq!(c, canonical, "canonical JSON of the documented spec");
    assert_eq!(i, id.trim());
    assert_eq!(polbrdf::plan::SCHEMA_VERSION, "3");
    assert_eq!(polbrdf::plan::SOLVER_VERSION, "7");
}
