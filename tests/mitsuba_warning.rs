//! The caveats of a Mitsuba export reach the user (issue 15): the CLI warns
//! on stderr when the file reproduces the table worse than 1 % of max
//! `f11 cos θ_i` (naming the value and the flags of a finer grid) and when a
//! mirror base's specular delta is left out; the service sends the error as
//! `X-Polbrdf-Resampling-Error` with every `format=mitsuba` response and each
//! caveat as an `X-Polbrdf-Warning` header. Drives the real binary and the
//! real `polbrdf serve`.

mod common;
mod service_support;

use common::{ok, run, scratch_dir};
use serde_json::{Value, json};
use service_support::{Server, TempDir, client, post, sha256_hex, wait_done};
use std::path::Path;

const FIVE: [f64; 5] = [450.0, 500.0, 550.0, 600.0, 650.0];

/// The warning threshold, 1 % of max f11 cos θ_i.
const WARN: f64 = polbrdf::brdf::mitsuba::RESAMPLING_WARNING;

/// A Rayleigh layer of optical thickness `tau` on `base` at five whole-nm
/// wavelengths, 8 streams (a table in about a second).
fn spec(tau: f64, base: Value) -> Value {
    json!({
        "layers": [{"optical_thickness": tau, "scatterer": {"rayleigh": {"albedo": 0.9}}}],
        "base": base, "wavelengths_nm": FIVE, "solver": {"streams": 8}
    })
}

fn table_of(d: &Path, name: &str, spec: &Value) -> String {
    let s = d.join(format!("{name}.json"));
    std::fs::write(&s, spec.to_string()).unwrap();
    let t = d
        .join(format!("{name}.pbrdf"))
        .to_string_lossy()
        .into_owned();
    ok(&["solve", &s.to_string_lossy(), "--table", &t]);
    t
}

/// A coarse grid, quick to build and far from 1 %.
const COARSE: [&str; 6] = [
    "--phi-d-nodes",
    "9",
    "--theta-d-nodes",
    "7",
    "--theta-h-nodes",
    "7",
];

/// `polbrdf export TABLE --format mitsuba [extra]`: (summary, stderr lines).
fn export(table: &str, out: &str, extra: &[&str]) -> (Value, Vec<String>) {
    let mut args = vec!["export", table, "--format", "mitsuba", "-o", out];
    args.extend_from_slice(extra);
    let (code, stdout, err) = run(&args);
    assert_eq!(code, 0, "{err}");
    (
        serde_json::from_str(&stdout).unwrap(),
        err.lines().map(str::to_string).collect(),
    )
}

fn relative(summary: &Value) -> f64 {
    summary["resampling_check"]["result"]["relative"]
        .as_f64()
        .unwrap()
}

/// Over 1 %: one warning line with the summary's value, where the error
/// sits, and a finer grid given by flags that `export` really has.
#[test]
fn a_coarse_grid_is_warned_about_with_the_value_and_real_flags() {
    let d = scratch_dir("mitsuba-warning-coarse");
    let t = table_of(
        &d,
        "paint",
        &spec(1.0, json!({"lambertian": {"albedo": 0.5}})),
    );
    let out = d.join("c.pbsdf").to_string_lossy().into_owned();
    let (summary, err) = export(&t, &out, &COARSE);
    let rel = relative(&summary);
    assert!(rel > WARN, "the coarse grid should be over 1 %: {rel}");
    assert_eq!(err.len(), 1, "{err:?}");
    let w = &err[0];
    assert!(w.starts_with("polbrdf: warning: "), "{w}");
    assert!(w.contains(&format!("{rel:.1e}")), "{rel} not in {w}");
    let inner = summary["resampling_check"]["result"]["relative_within_80_deg"]
        .as_f64()
        .unwrap();
    assert!(inner <= rel && w.contains(&format!("{inner:.1e}")), "{w}");
    assert!(w.contains("--theta-d-nodes 91 --theta-h-nodes 91"), "{w}");
    let (_, help, _) = run(&["export", "--help"]);
    let flags: Vec<&str> = w
        .split_whitespace()
        .filter(|x| x.starts_with("--"))
        .collect();
    assert!(!flags.is_empty());
    for f in flags {
        assert!(
            help.contains(f),
            "{f} named in the warning is not a flag of export"
        );
    }
    assert!(!w.contains("specular"), "{w}");
}

/// A BRDF the grid interpolates almost exactly (an empty layer on a
/// Lambertian base: a constant matrix; any scattering layer, however thin,
/// diverges at grazing incidence and exit, where its optical path is not
/// thin): no warning, stderr empty.
#[test]
fn an_exact_export_is_silent() {
    let d = scratch_dir("mitsuba-warning-exact");
    let t = table_of(
        &d,
        "flat",
        &spec(0.0, json!({"lambertian": {"albedo": 0.5}})),
    );
    let out = d.join("f.pbsdf").to_string_lossy().into_owned();
    let (summary, err) = export(&t, &out, &COARSE);
    assert!(relative(&summary) < WARN, "{summary}");
    assert!(err.is_empty(), "{err:?}");
}

/// A mirror base: a warning that the delta is not in the file and what a
/// renderer must add, besides the resampling warning.
#[test]
fn a_mirror_base_is_warned_about_its_delta() {
    let d = scratch_dir("mitsuba-warning-mirror");
    let t = table_of(
        &d,
        "metal",
        &spec(1.0, json!({"fresnel": {"material": "aluminium"}})),
    );
    let out = d.join("m.pbsdf").to_string_lossy().into_owned();
    let (summary, err) = export(&t, &out, &COARSE);
    assert!(relative(&summary) > WARN);
    assert_eq!(err.len(), 2, "{err:?}");
    let delta = err
        .iter()
        .find(|l| l.contains("specular delta"))
        .expect("a specular warning");
    assert!(delta.starts_with("polbrdf: warning: "), "{delta}");
    assert!(
        delta.contains("S = exp(-2 tau/mu_i) M_F(mu_i)") && delta.contains("docs/mitsuba.md"),
        "{delta}"
    );
    assert!(
        summary["specular_delta"]
            .as_str()
            .unwrap()
            .starts_with("NOT INCLUDED")
    );
}

fn header_values(h: &reqwest::header::HeaderMap, name: &str) -> Vec<String> {
    h.get_all(name)
        .iter()
        .map(|v| v.to_str().unwrap().to_string())
        .collect()
}

/// `GET …/table?format=mitsuba` (default grid): the resampling error in a
/// header, equal to what the CLI prints for the same table (read from the
/// service), and a warning header per caveat; none for an exact export.
/// The 304 of a revalidation carries the same headers.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_service_sends_the_error_and_the_warnings_as_headers() {
    let dir = TempDir::new("mitsuba-warning");
    let s = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();
    let submit = |v: Value| {
        let c = c.clone();
        let s = &s;
        async move {
            let (code, body, _) = post(&c, s, &v.to_string()).await;
            assert_eq!(code, 202, "{body}");
            let id = body["id"].as_str().unwrap().to_string();
            wait_done(&c, s, &id).await;
            id
        }
    };
    let metal = submit(spec(1.0, json!({"fresnel": {"material": "aluminium"}}))).await;
    let flat = submit(spec(0.0, json!({"lambertian": {"albedo": 0.5}}))).await;

    // Mirror base, default grid.
    let url = s.url(&format!("/v1/brdfs/{metal}/table?format=mitsuba"));
    let r = c.get(&url).send().await.unwrap();
    assert_eq!(r.status(), 200);
    let h = r.headers().clone();
    let body = r.bytes().await.unwrap();
    let errors = header_values(&h, "x-polbrdf-resampling-error");
    assert_eq!(errors.len(), 1, "{h:?}");
    let rel: f64 = errors[0].parse().unwrap();
    let warnings = header_values(&h, "x-polbrdf-warning");
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("specular delta") && w.contains("exp(-2 tau/mu_i)")),
        "{warnings:?}"
    );
    let over = rel > WARN;
    assert_eq!(warnings.len(), 1 + usize::from(over), "{rel} {warnings:?}");
    if over {
        let w = warnings.iter().find(|w| !w.contains("specular")).unwrap();
        assert!(w.contains(&format!("{rel:.1e}")), "{w}");
        assert!(
            w.contains("polbrdf export") && w.contains("--theta-d-nodes 91"),
            "{w}"
        );
    }

    // The CLI on the same result (read from the service): the same number
    // and the same file.
    let d = scratch_dir("mitsuba-warning-http");
    let out = d.join("metal.pbsdf").to_string_lossy().into_owned();
    let (summary, err) = export(&s.url(&format!("/v1/brdfs/{metal}")), &out, &[]);
    assert_eq!(relative(&summary), rel, "CLI {summary} vs header {rel}");
    assert_eq!(err.len(), warnings.len(), "{err:?} vs {warnings:?}");
    assert_eq!(sha256_hex(&std::fs::read(&out).unwrap()), sha256_hex(&body));
    eprintln!("aluminium under Rayleigh tau = 1, default grid: relative {rel}");

    // Revalidation: 304 with the same headers.
    let etag = h["etag"].to_str().unwrap().to_string();
    let r = c
        .get(&url)
        .header("if-none-match", &etag)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 304);
    assert_eq!(
        header_values(r.headers(), "x-polbrdf-resampling-error"),
        errors
    );
    assert_eq!(header_values(r.headers(), "x-polbrdf-warning"), warnings);

    // An exact export: the error header, no warning.
    let r = c
        .get(s.url(&format!("/v1/brdfs/{flat}/table?format=mitsuba")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let rel: f64 = header_values(r.headers(), "x-polbrdf-resampling-error")[0]
        .parse()
        .unwrap();
    assert!(rel < WARN, "{rel}");
    assert!(header_values(r.headers(), "x-polbrdf-warning").is_empty());

    // Other formats have neither header.
    let r = c
        .get(s.url(&format!(
            "/v1/brdfs/{flat}/table?format=npy&theta_count=3&phi_count=3"
        )))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert!(r.headers().get("x-polbrdf-resampling-error").is_none());
    assert!(r.headers().get("x-polbrdf-warning").is_none());
}
