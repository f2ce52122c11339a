//! What `polbrdf solve` and `polbrdf export --format npy` print (issue 15),
//! through the real binary: each result says what was computed and carries
//! nothing else; `--table` reports the table build per wavelength; the npy
//! export prints a short summary; a spec over the service's stream cap is
//! refused unless `--max-streams` raises it; stderr stays empty without a
//! terminal, and on a terminal (a pseudo-terminal from util-linux `script`)
//! a one-line summary appears while stdout is unchanged.

mod common;

use common::{ok, run, scratch_dir};
use serde_json::{Value, json};
use std::path::Path;

fn write(d: &Path, name: &str, v: &Value) -> String {
    let p = d.join(name);
    std::fs::write(&p, v.to_string()).unwrap();
    p.to_string_lossy().into_owned()
}

/// A Rayleigh layer on a Lambertian base: solves in well under a second.
fn rayleigh(streams: usize, wavelengths: Option<&[f64]>) -> Value {
    let mut s = json!({
        "layers": [{"optical_thickness": 1.0, "scatterer": {"rayleigh": {"albedo": 0.9}}}],
        "base": {"lambertian": {"albedo": 0.5}},
        "solver": {"streams": streams}
    });
    if let Some(w) = wavelengths {
        s["wavelengths_nm"] = json!(w);
    }
    s
}

fn points() -> Value {
    json!({"points": [
        {"theta_i_deg": 30, "phi_i_deg": 0, "theta_o_deg": 45, "phi_o_deg": 180},
        {"theta_i_deg": 60, "phi_i_deg": 10, "theta_o_deg": 20, "phi_o_deg": 100}
    ]})
}

fn keys(v: &Value) -> Vec<String> {
    let mut k: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
    k.sort();
    k
}

/// Drop the timings (they differ from run to run) before comparing outputs.
fn without_timings(v: &mut Value) {
    match v {
        Value::Object(m) => {
            m.remove("wall_time_ms");
            m.values_mut().for_each(without_timings);
        }
        Value::Array(a) => a.iter_mut().for_each(without_timings),
        _ => {}
    }
}

/// `solve --table` alone: every result lists "table" and only it, with the
/// streams of the spec and the orders, timing and error estimate that the
/// written file's own metadata records for that wavelength; no points,
/// field or solver block (nothing was solved at direction pairs).
#[test]
fn solve_table_reports_the_table_build_per_wavelength() {
    let d = scratch_dir("cli-output-table");
    let s = write(&d, "spec.json", &rayleigh(8, Some(&[600.0, 500.0])));
    let t = d.join("t.pbrdf").to_string_lossy().into_owned();
    let (code, out, err) = run(&["solve", &s, "--table", &t]);
    assert_eq!(code, 0, "{err}");
    assert!(err.is_empty(), "stderr without a terminal: {err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    let file = polbrdf::brdf::format::read_file(&t).unwrap();
    let results = v["results"].as_array().unwrap();
    // In the spec's order (600, 500), the file's metadata sorted (500, 600).
    assert_eq!(results.len(), 2);
    for (r, wl) in results.iter().zip([600.0, 500.0]) {
        assert_eq!(r["wavelength_nm"], json!(wl));
        assert_eq!(r["computed"], json!(["table"]), "{r}");
        assert_eq!(keys(r), ["computed", "table", "wavelength_nm"], "{r}");
        let meta = file
            .metadata
            .wavelengths
            .iter()
            .find(|m| m.wavelength_nm == Some(wl))
            .unwrap();
        let tb = &r["table"];
        assert_eq!(tb["streams"], json!(8));
        assert_eq!(tb["fourier_orders"], json!(meta.fourier_orders));
        assert!(meta.fourier_orders >= 1);
        assert_eq!(tb["wall_time_ms"], json!(meta.wall_time_ms));
        let e = meta.error_estimate.as_ref().unwrap();
        assert_eq!(tb["error_estimate"]["max_err_f11"], json!(e.max_err_f11));
        assert_eq!(tb["error_estimate"]["streams"], json!([4, 6, 8]));
    }
    // The top-level table block stays: the file, its size and digest.
    assert_eq!(v["table"]["file"], json!(t));
    let bytes = std::fs::read(&t).unwrap();
    assert_eq!(v["table"]["bytes"], json!(bytes.len()));
    use sha2::Digest;
    let digest: String = sha2::Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(v["table"]["sha256_of_file"], json!(digest));
}

/// Points and a table: both listed, the solver block describes the direct
/// solve (with its estimate) and the table block the table's.
#[test]
fn points_and_table_are_both_listed() {
    let d = scratch_dir("cli-output-both");
    let s = write(&d, "spec.json", &rayleigh(8, None));
    let p = write(&d, "points.json", &points());
    let t = d.join("t.pbrdf").to_string_lossy().into_owned();
    let v = ok(&["solve", &s, "--points", &p, "--table", &t]);
    let r = &v["results"][0];
    assert_eq!(r["computed"], json!(["points", "table"]));
    assert_eq!(
        keys(r),
        [
            "computed",
            "points",
            "solver",
            "specular",
            "table",
            "wavelength_nm"
        ]
    );
    assert_eq!(r["points"].as_array().unwrap().len(), 2);
    assert_eq!(r["solver"]["streams"], json!(8));
    assert_eq!(r["table"]["streams"], json!(8));
    assert!(r["solver"]["fourier_orders"].as_u64().unwrap() >= 1);
    let e = r["solver"]["error_estimate"]["max_err_f11"]
        .as_f64()
        .unwrap();
    assert!(e.is_finite() && e > 0.0, "{e}");
}

/// Nothing asked for: the spec is checked, and no fake zeros, nulls or
/// empty lists are printed for what was not computed.
#[test]
fn without_points_nothing_pretends_to_be_solved() {
    let d = scratch_dir("cli-output-none");
    let s = write(&d, "spec.json", &rayleigh(8, Some(&[550.0])));
    let (code, out, err) = run(&["solve", &s]);
    assert_eq!(code, 0, "{err}");
    assert!(err.is_empty(), "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    let r = &v["results"][0];
    assert_eq!(keys(r), ["computed", "wavelength_nm"], "{r}");
    assert_eq!(r["computed"], json!([]));
    for fake in ["fourier_orders", "error_estimate", "\"points\"", "null"] {
        assert!(!out.contains(fake), "{fake} in {out}");
    }
    // A field alone: a solver block without an error estimate (none was made).
    let f = write(
        &d,
        "field.json",
        &json!({"mu0": 0.5, "tau": [0.0], "mu": [0.5], "phi_deg": [0.0]}),
    );
    let v = ok(&["solve", &s, "--field", &f]);
    let r = &v["results"][0];
    assert_eq!(r["computed"], json!(["field"]));
    assert_eq!(keys(r), ["computed", "field", "solver", "wavelength_nm"]);
    assert_eq!(
        keys(&r["solver"]),
        ["fourier_orders", "polarized", "streams", "wall_time_ms"]
    );
    assert!(r["solver"]["fourier_orders"].as_u64().unwrap() >= 1);
}

/// `export --format npy` prints a summary: a few dozen lines (it printed
/// every axis value: 191 lines for this table, 44 now), and what it says matches
/// the file: the header's shape, the byte count, the digest.
#[test]
fn npy_export_prints_a_short_summary_that_matches_the_file() {
    let d = scratch_dir("cli-output-npy");
    let s = write(&d, "spec.json", &rayleigh(4, Some(&[500.0, 600.0])));
    let t = d.join("t.pbrdf").to_string_lossy().into_owned();
    ok(&["solve", &s, "--table", &t]);
    let npy = d.join("t.npy").to_string_lossy().into_owned();
    let (code, out, err) = run(&["export", &t, "--format", "npy", "-o", &npy]);
    assert_eq!(code, 0, "{err}");
    assert!(err.is_empty(), "{err}");
    let lines = out.lines().count();
    assert!(lines < 60, "{lines} lines:\n{out}");
    let v: Value = serde_json::from_str(&out).unwrap();
    let b = std::fs::read(&npy).unwrap();
    assert_eq!(&b[..8], b"\x93NUMPY\x01\x00");
    let hlen = u16::from_le_bytes([b[8], b[9]]) as usize;
    let header = std::str::from_utf8(&b[10..10 + hlen]).unwrap();
    let shape: Vec<usize> = serde_json::from_value(v["shape"].clone()).unwrap();
    let dims: Vec<String> = shape.iter().map(|x| x.to_string()).collect();
    assert!(
        header.contains(&format!("'shape': ({})", dims.join(", "))),
        "{header} vs {shape:?}"
    );
    assert_eq!(shape, [2, 51, 51, 61, 4, 4]);
    assert_eq!(v["bytes"], json!(b.len()));
    assert_eq!(b.len() - 10 - hlen, shape.iter().product::<usize>() * 4);
    use sha2::Digest;
    let digest: String = sha2::Sha256::digest(&b)
        .iter()
        .map(|x| format!("{x:02x}"))
        .collect();
    assert_eq!(v["sha256_of_file"], json!(digest));
    let axes = &v["axes"];
    assert_eq!(axes["wavelength_nm"]["count"], json!(2));
    assert_eq!(axes["wavelength_nm"]["first"], json!(500.0));
    assert_eq!(axes["wavelength_nm"]["last"], json!(600.0));
    assert_eq!(axes["theta_i_deg"]["count"], json!(51));
    assert_eq!(axes["phi_deg"]["count"], json!(61));
    assert_eq!(axes["phi_deg"]["last"], json!(360.0));
    // θ at the midpoints of 51 steps of 90°.
    let first = axes["theta_o_deg"]["first"].as_f64().unwrap();
    assert!((first - 45.0 / 51.0).abs() < 1e-12, "{first}");
}

/// The service refuses more than 128 streams by default
/// (`polbrdf serve --max-streams`); so does `solve`, with exit 2 and one
/// line naming the field and the cap, unless `--max-streams` raises it.
#[test]
fn stream_cap_is_the_services_unless_raised() {
    let d = scratch_dir("cli-output-cap");
    // Scalar, three expansion terms: 256 streams solve in seconds.
    let mut spec = rayleigh(256, None);
    spec["solver"]["polarized"] = json!(false);
    let s = write(&d, "spec.json", &spec);
    let p = write(
        &d,
        "points.json",
        &json!({"points": [{"theta_i_deg": 30, "phi_i_deg": 0, "theta_o_deg": 45, "phi_o_deg": 180}]}),
    );
    let (code, out, err) = run(&["solve", &s, "--points", &p]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(out.is_empty(), "{out}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    for part in ["solver.streams", "256", "[1, 128]", "--max-streams"] {
        assert!(err.contains(part), "{part} not in {err}");
    }
    // A lower cap refuses what the default allows.
    let s128 = write(&d, "spec128.json", &rayleigh(128, None));
    let (code, _, err) = run(&["solve", &s128, "--max-streams", "100"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("[1, 100]"), "{err}");
    // Beyond the spec's own hard limit the flag itself is refused.
    let (code, _, err) = run(&["solve", &s, "--max-streams", "513"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--max-streams"), "{err}");
    // Raised: solved at 256 streams.
    let v = ok(&["solve", &s, "--points", &p, "--max-streams", "256"]);
    assert_eq!(v["results"][0]["solver"]["streams"], json!(256));
    let f = &v["results"][0]["points"][0]["mueller"][0][0];
    assert!(f.as_f64().unwrap() > 0.0, "{f}");
    // convergence: its reference solve is capped too.
    let (code, _, err) = run(&["convergence", &s128, "--streams", "64,128"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("256 streams") && err.contains("--max-streams 128"),
        "{err}"
    );
}

/// Single-quoted for `sh -c`.
fn sh_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// On a terminal (util-linux `script` gives the command a pseudo-terminal;
/// stdout goes to a file): a one-line summary on the terminal naming what
/// was solved, and stdout the same JSON as without a terminal, whose
/// stderr is empty.
#[test]
fn a_terminal_gets_a_summary_and_stdout_is_unchanged() {
    let has_script = std::process::Command::new("script")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_script {
        eprintln!(
            "SKIPPED a_terminal_gets_a_summary_and_stdout_is_unchanged: util-linux `script` is missing (no pseudo-terminal)"
        );
        return;
    }
    let d = scratch_dir("cli-output-tty");
    let s = write(&d, "spec.json", &rayleigh(8, Some(&[500.0, 600.0])));
    let p = write(&d, "points.json", &points());
    let bin = env!("CARGO_BIN_EXE_polbrdf");

    let plain_table = d.join("plain.pbrdf").to_string_lossy().into_owned();
    let (code, plain, err) = run(&["solve", &s, "--points", &p, "--table", &plain_table]);
    assert_eq!(code, 0, "{err}");
    assert!(err.is_empty(), "stderr without a terminal: {err}");

    let tty_table = d.join("tty.pbrdf").to_string_lossy().into_owned();
    let stdout_file = d.join("stdout.json").to_string_lossy().into_owned();
    let command = format!(
        "{} solve {} --points {} --table {} > {}",
        sh_quote(bin),
        sh_quote(&s),
        sh_quote(&p),
        sh_quote(&tty_table),
        sh_quote(&stdout_file)
    );
    let o = std::process::Command::new("script")
        .args(["-qec", &command, "/dev/null"])
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap();
    let terminal = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "script: {terminal}");
    // The bar is drawn and erased with carriage returns and escapes; the
    // summary is the last thing on the terminal, one line.
    let last = terminal
        .split(['\r', '\n'])
        .map(|l| l.trim_start_matches("\x1b[2K"))
        .rfind(|l| !l.trim().is_empty())
        .unwrap_or_default()
        .to_string();
    assert!(
        last.starts_with("polbrdf: solved 2 wavelengths at 2 direction pairs, 8 streams"),
        "{last:?} in {terminal:?}"
    );
    assert!(
        last.contains(&format!("table {tty_table} at 2 wavelengths")),
        "{last:?}"
    );
    assert!(last.contains("error estimate at most"), "{last:?}");
    assert!(
        !terminal.contains('{'),
        "JSON on the terminal: {terminal:?}"
    );

    let mut a: Value = serde_json::from_str(&plain).unwrap();
    let mut b: Value =
        serde_json::from_str(&std::fs::read_to_string(&stdout_file).unwrap()).unwrap();
    without_timings(&mut a);
    without_timings(&mut b);
    // The files differ in name and in the timings of their metadata.
    for v in [&mut a, &mut b] {
        for k in ["file", "bytes", "sha256_of_file"] {
            v["table"][k] = json!(null);
        }
    }
    assert_eq!(a, b, "stdout differs on a terminal");
}
