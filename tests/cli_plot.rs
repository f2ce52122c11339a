//! `polbrdf plot …` through the real binary: every subcommand writes a
//! non-empty SVG and PNG and the CSV of what it plotted; the CSV's numbers
//! are physically sensible and agree with an independent route to the same
//! quantity (`polbrdf solve --points` for the curves, `polbrdf eval` for the
//! lobe); bad input is a one-line error with a non-zero exit code.

mod common;

use common::{ok, run, scratch_dir};

use serde_json::json;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

fn dir() -> PathBuf {
    scratch_dir("cli-plot")
}

fn fails(args: &[&str]) -> String {
    let (code, out, err) = run(args);
    assert_ne!(code, 0, "polbrdf {args:?} should fail, printed {out}");
    assert!(out.trim().is_empty(), "nothing on stdout: {out}");
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    err
}

fn write(d: &Path, name: &str, text: &str) -> String {
    let p = d.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_string_lossy().into_owned()
}

/// TiO2 spheres (seed Table 2, 550 nm), r = 0.2 µm, on black, 8 streams.
fn tio2(tau: f64, polarized: bool) -> String {
    json!({
        "layers": [{"optical_thickness": tau,
                    "scatterer": {"mie": {"material": "TiO2", "radius_um": 0.2}}}],
        "base": "black", "wavelengths_nm": [550],
        "solver": {"streams": 8, "polarized": polarized}
    })
    .to_string()
}

/// One CSV row as column → cell text.
type Row = HashMap<String, String>;

/// RFC 4180 CSV (quoted cells with commas and doubled quotes).
fn parse_csv(path: &Path) -> Vec<Row> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let split = |line: &str| -> Vec<String> {
        let (mut cells, mut cell, mut quoted) = (Vec::new(), String::new(), false);
        let mut chars = line.chars().peekable();
        while let Some(c) = chars.next() {
            match (c, quoted) {
                ('"', true) if chars.peek() == Some(&'"') => {
                    cell.push('"');
                    chars.next();
                }
                ('"', _) => quoted = !quoted,
                (',', false) => cells.push(std::mem::take(&mut cell)),
                _ => cell.push(c),
            }
        }
        cells.push(cell);
        cells
    };
    let mut lines = text.lines();
    let header = split(lines.next().expect("header"));
    lines
        .map(|l| {
            let cells = split(l);
            assert_eq!(cells.len(), header.len(), "{l}");
            header.iter().cloned().zip(cells).collect()
        })
        .collect()
}

fn num(r: &Row, col: &str) -> f64 {
    r[col]
        .parse()
        .unwrap_or_else(|_| panic!("{col} = {:?} is not a number", r[col]))
}

fn assert_images(svg: &Path, png: &Path) {
    let s = std::fs::read_to_string(svg).unwrap();
    assert!(s.len() > 1000, "{} is {} bytes", svg.display(), s.len());
    assert!(s.trim_start().starts_with("<svg"), "SVG root");
    assert!(s.trim_end().ends_with("</svg>"), "SVG closed");
    let p = std::fs::read(png).unwrap();
    assert!(p.len() > 1000, "{} is {} bytes", png.display(), p.len());
    assert_eq!(&p[..8], b"\x89PNG\r\n\x1a\n", "PNG magic");
}

/// The Mueller BRDF of `polbrdf solve SPEC --points` at one direction pair.
fn solve_point(spec: &str, d: &Path, theta_i: f64, theta_o: f64, phi_o: f64) -> [[f64; 4]; 4] {
    let points = write(
        d,
        "points.json",
        &json!({"points": [{"theta_i_deg": theta_i, "phi_i_deg": 0.0,
                            "theta_o_deg": theta_o, "phi_o_deg": phi_o}]})
        .to_string(),
    );
    let v = ok(&["solve", spec, "--points", &points]);
    let m = &v["results"][0]["points"][0]["mueller"];
    let mut out = [[0.0; 4]; 4];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = m[i][j].as_f64().unwrap();
        }
    }
    out
}

fn dop_of(m: &[[f64; 4]; 4], e: [f64; 4]) -> f64 {
    let s: Vec<f64> = (0..4)
        .map(|p| (0..4).map(|q| m[p][q] * e[q]).sum())
        .collect();
    (s[1] * s[1] + s[2] * s[2] + s[3] * s[3]).sqrt() / s[0]
}

fn deg(mu: f64) -> f64 {
    mu.acos().to_degrees()
}

#[test]
fn dop_vs_mu_plots_what_solve_computes() {
    let d = dir();
    let spec = write(&d, "tio2.json", &tio2(1.0, true));
    let svg = d.join("fig8.svg");
    let png = d.join("fig8.png");
    let args = |out: &Path| -> Vec<String> {
        [
            "plot",
            "dop-vs-mu",
            &spec,
            "--taus",
            "0.5,2",
            "--mu0",
            "0.6",
            "--phi-o-deg",
            "180,0",
            "--mu-samples",
            "10",
            "-o",
            out.to_str().unwrap(),
        ]
        .map(String::from)
        .to_vec()
    };
    let v = ok(&args(&svg).iter().map(String::as_str).collect::<Vec<_>>());
    ok(&args(&png).iter().map(String::as_str).collect::<Vec<_>>());
    assert_images(&svg, &png);
    assert_eq!(v["csv"], json!(d.join("fig8.csv")));
    assert_eq!(v["curves"].as_array().unwrap().len(), 4);

    let rows = parse_csv(&d.join("fig8.csv"));
    assert_eq!(rows.len(), 2 * 2 * 10);
    for r in &rows {
        let dop = num(r, "dop");
        assert!(dop.is_finite() && (0.0..=1.0).contains(&dop), "{r:?}");
        assert!(num(r, "f11_per_sr") > 0.0, "{r:?}");
        assert_eq!(num(r, "f11_per_sr"), num(r, "i_per_sr"));
    }
    // Thinner layers polarize more (seed Fig. 8), on the mirror side at the normal.
    let at = |tau: f64, mu: f64, phi: f64| {
        rows.iter()
            .find(|r| num(r, "tau") == tau && num(r, "mu") == mu && num(r, "phi_o_deg") == phi)
            .unwrap_or_else(|| panic!("no row tau {tau} mu {mu} phi {phi}"))
    };
    assert!(num(at(0.5, 1.0, 180.0), "dop") > num(at(2.0, 1.0, 180.0), "dop"));

    // The same point from `polbrdf solve` on a spec with that thickness.
    let spec05 = write(&d, "tio2_05.json", &tio2(0.5, true));
    let m = solve_point(&spec05, &d, deg(0.6), deg(0.3), 0.0);
    let r = at(0.5, 0.3, 0.0);
    assert!(
        (num(r, "f11_per_sr") - m[0][0]).abs() <= 1e-7 * m[0][0],
        "{r:?} vs {m:?}"
    );
    assert!((num(r, "dop") - dop_of(&m, [1.0, 0.0, 0.0, 0.0])).abs() < 1e-7);
}

#[test]
fn dop_vs_tau_plots_every_input_state_and_the_semi_infinite_layer() {
    let d = dir();
    let spec = write(&d, "tio2.json", &tio2(1.0, true));
    let svg = d.join("fig4.svg");
    let png = d.join("fig4.png");
    for out in [&svg, &png] {
        ok(&[
            "plot",
            "dop-vs-tau",
            &spec,
            "--taus",
            "0.01,1",
            "--mu0",
            "0.6",
            "--mu",
            "0.8",
            "-o",
            out.to_str().unwrap(),
        ]);
    }
    assert_images(&svg, &png);
    let rows = parse_csv(&d.join("fig4.csv"));
    // 0.01, 1 and the semi-infinite layer, four incident states each.
    assert_eq!(rows.len(), 3 * 4);
    assert_eq!(rows.iter().filter(|r| r["tau"] == "inf").count(), 4);
    for r in &rows {
        let dop = num(r, "dop");
        assert!(
            dop.is_finite() && (0.0..=1.0 + 1e-9).contains(&dop),
            "{r:?}"
        );
        let polarized =
            num(r, "stokes_in_q").abs() + num(r, "stokes_in_u").abs() + num(r, "stokes_in_v").abs()
                > 0.0;
        if polarized && num(r, "tau") == 0.01 {
            // Single scattering by spheres keeps a fully polarized beam polarized.
            assert!(dop > 0.95, "{r:?}");
        }
    }
    let spec1 = write(&d, "tio2_1.json", &tio2(1.0, true));
    let m = solve_point(&spec1, &d, deg(0.6), deg(0.8), 180.0);
    let r = rows
        .iter()
        .find(|r| r["tau"] == "1" && r["stokes_in_v"] == "1")
        .expect("circular input at tau 1");
    assert!(
        (num(r, "dop") - dop_of(&m, [1.0, 0.0, 0.0, 1.0])).abs() < 1e-7,
        "{r:?}"
    );
    assert!((num(r, "v_per_sr") - (m[3][0] + m[3][3])).abs() <= 1e-7 * m[0][0]);
}

#[test]
fn scalar_error_is_zero_without_polarization_and_matches_scalar_solves() {
    let d = dir();
    let spec = write(&d, "tio2.json", &tio2(1.0, true));
    let hg = write(
        &d,
        "hg.json",
        &json!({"layers": [{"optical_thickness": 1.0,
                            "scatterer": {"henyey_greenstein": {"albedo": 0.9, "g": 0.5}}}],
                "base": {"lambertian": {"albedo": 0.5}}, "solver": {"streams": 8}})
        .to_string(),
    );
    let svg = d.join("fig7.svg");
    let png = d.join("fig7.png");
    for out in [&svg, &png] {
        ok(&[
            "plot",
            "scalar-error",
            &spec,
            &hg,
            "--labels",
            "TiO2,HG",
            "--taus",
            "0.1,1",
            "--pairs",
            "0.9:1.0,0.6:0.6",
            "-o",
            out.to_str().unwrap(),
        ]);
    }
    assert_images(&svg, &png);
    let rows = parse_csv(&d.join("fig7.csv"));
    assert_eq!(rows.len(), 2 * 2 * 2);
    for r in &rows {
        assert!(
            num(r, "e").is_finite() && num(r, "f_vector_per_sr") > 0.0,
            "{r:?}"
        );
        if r["label"] == "HG" {
            // A scalar phase function: the vector RTE's f11 is the scalar RTE's.
            assert!(num(r, "e").abs() < 1e-12, "{r:?}");
        }
    }
    // F_s and F_v of TiO2 at tau = 1, (0.6, 0.6) from `polbrdf solve`.
    let r = rows
        .iter()
        .find(|r| r["label"] == "TiO2" && r["tau"] == "1" && r["mu0"] == "0.6")
        .unwrap();
    let scalar = write(&d, "tio2_scalar.json", &tio2(1.0, false));
    let fs = solve_point(&scalar, &d, deg(0.6), deg(0.6), 180.0)[0][0];
    let fv = solve_point(&spec, &d, deg(0.6), deg(0.6), 180.0)[0][0];
    assert!(
        (num(r, "f_scalar_per_sr") - fs).abs() <= 1e-7 * fs,
        "{r:?} vs {fs}"
    );
    assert!(
        (num(r, "f_vector_per_sr") - fv).abs() <= 1e-7 * fv,
        "{r:?} vs {fv}"
    );
    assert!((num(r, "e") - (1.0 - fs / fv)).abs() < 1e-6);
}

#[test]
fn lobe_plots_tables_from_specs_and_files() {
    let d = dir();
    let spec = write(&d, "tio2.json", &tio2(1.0, true));
    let table = d.join("t.pbrdf");
    ok(&["solve", &spec, "--table", table.to_str().unwrap()]);
    let svg = d.join("fig13.svg");
    let png = d.join("fig13.png");
    for out in [&svg, &png] {
        let v = ok(&[
            "plot",
            "lobe",
            &spec,
            "--table",
            table.to_str().unwrap(),
            "--labels",
            "from spec,from table",
            "--theta-i",
            "45",
            "--step-deg",
            "10",
            "--map-cells",
            "6x12",
            "--nodes",
            "16",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(v["curves"].as_array().unwrap().len(), 2);
    }
    assert_images(&svg, &png);
    assert_images(&d.join("fig13-map.svg"), &d.join("fig13-map.png"));
    let rows = parse_csv(&d.join("fig13.csv"));
    assert_eq!(rows.len(), 2 * 19);
    let map = parse_csv(&d.join("fig13-map.csv"));
    assert_eq!(map.len(), 2 * 6 * 12);
    for r in rows.iter().chain(&map) {
        let dop = num(r, "dop");
        assert!(dop.is_finite() && (0.0..=1.0).contains(&dop), "{r:?}");
        assert!(num(r, "f11_per_sr") > 0.0, "{r:?}");
    }
    // The table's in-plane f11 is what `polbrdf eval` reads from the same file.
    let r = rows
        .iter()
        .find(|r| r["label"] == "from table" && r["theta_o_signed_deg"] == "30")
        .expect("mirror side, 30°");
    assert_eq!(r["phi_o_deg"], "180");
    let e = ok(&[
        "eval",
        table.to_str().unwrap(),
        "--theta-i",
        "45",
        "--phi-i",
        "0",
        "--theta-o",
        "30",
        "--phi-o",
        "180",
    ]);
    let m00 = e["mueller"][0][0].as_f64().unwrap();
    assert!(
        (num(r, "f11_per_sr") - m00).abs() <= 1e-12 * m00,
        "{r:?} vs {m00}"
    );
    // The spec's own table (16 nodes) agrees with the file's (64 nodes)
    // to interpolation accuracy.
    let s = rows
        .iter()
        .find(|r| r["label"] == "from spec" && r["theta_o_signed_deg"] == "30")
        .unwrap();
    assert!(
        (num(s, "f11_per_sr") - m00).abs() <= 1e-3 * m00,
        "{s:?} vs {m00}"
    );
}

/// `plot spectrum`: a hematite layer (measured, dispersive) at five
/// wavelengths over black and over a grey Lambertian base: images, one CSV
/// row per wavelength and spec, π f11 and the DOP as `polbrdf solve
/// --points` gives them at each wavelength, the plane albedo within (0, 1)
/// and above the grey base's share; the absorption edge shows (hematite
/// reflects more at 700 nm than at 450 nm).
#[test]
fn spectrum_plots_what_solve_computes_at_each_wavelength() {
    let d = dir();
    let spec = |base: serde_json::Value| {
        json!({
            "layers": [{"optical_thickness": 2.0,
                        "scatterer": {"mie": {"material": "iron oxide", "radius_um": 0.1,
                                              "host_index": 1.5}}}],
            "base": base, "wavelengths_nm": [450, 500, 550, 600, 700],
            "solver": {"streams": 8}
        })
        .to_string()
    };
    let black = write(&d, "hematite_black.json", &spec(json!("black")));
    let grey = write(
        &d,
        "hematite_grey.json",
        &spec(json!({"lambertian": {"albedo": 0.5}})),
    );
    let svg = d.join("spectrum.svg");
    let png = d.join("spectrum.png");
    for out in [&svg, &png] {
        let v = ok(&[
            "plot",
            "spectrum",
            &black,
            &grey,
            "--theta-i",
            "45",
            "--theta-o",
            "20",
            "--phi-o-deg",
            "180",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(v["plot"], "spectrum");
        assert_eq!(v["curves"].as_array().unwrap().len(), 2);
    }
    assert_images(&svg, &png);
    let rows = parse_csv(&d.join("spectrum.csv"));
    assert_eq!(rows.len(), 2 * 5);
    let points = write(
        &d,
        "points.json",
        &json!({"points": [{"theta_i_deg": 45, "phi_i_deg": 0,
                            "theta_o_deg": 20, "phi_o_deg": 180}]})
        .to_string(),
    );
    for (file, k0) in [(&black, 0), (&grey, 5)] {
        let v = ok(&["solve", file, "--points", &points]);
        for (w, r) in v["results"]
            .as_array()
            .unwrap()
            .iter()
            .zip(&rows[k0..k0 + 5])
        {
            assert_eq!(
                r["wavelength_nm"].parse::<f64>().unwrap(),
                w["wavelength_nm"].as_f64().unwrap()
            );
            let m = &w["points"][0]["mueller"];
            let f11 = m[0][0].as_f64().unwrap();
            let col = |i: usize| m[i][0].as_f64().unwrap();
            let dop = (col(1).powi(2) + col(2).powi(2) + col(3).powi(2)).sqrt() / f11;
            assert!((num(r, "f11_per_sr") - f11).abs() <= 1e-12 * f11, "{r:?}");
            assert!(
                (num(r, "reflectance_factor") - std::f64::consts::PI * f11).abs() <= 1e-12,
                "{r:?}"
            );
            assert!((num(r, "dop") - dop).abs() < 1e-12, "{r:?}");
            let a = num(r, "plane_albedo");
            assert!(a > 0.0 && a < 1.0, "{r:?}");
        }
    }
    for k in 0..5 {
        // The grey base adds reflection at every wavelength.
        assert!(num(&rows[5 + k], "plane_albedo") > num(&rows[k], "plane_albedo"));
    }
    assert!(num(&rows[4], "plane_albedo") > num(&rows[0], "plane_albedo"));
    let err = fails(&[
        "plot",
        "spectrum",
        &black,
        "--wavelength-nm",
        "550",
        "-o",
        svg.to_str().unwrap(),
    ]);
    assert!(err.contains("--wavelength-nm"), "{err}");
    let err = fails(&[
        "plot",
        "spectrum",
        &black,
        "--theta-i",
        "90",
        "-o",
        svg.to_str().unwrap(),
    ]);
    assert!(err.contains("--theta-i"), "{err}");
}

#[test]
fn bad_input_is_a_clear_error() {
    let d = dir();
    let spec = write(&d, "tio2.json", &tio2(1.0, true));
    let out = d.join("x.svg");
    let o = out.to_str().unwrap();
    let e = fails(&["plot", "dop-vs-mu", "/nonexistent/spec.json", "-o", o]);
    assert!(e.contains("/nonexistent/spec.json"), "{e}");
    let e = fails(&["plot", "dop-vs-mu", &spec, "--taus", "0.1,abc", "-o", o]);
    assert!(e.contains("'abc' is not a number"), "{e}");
    let e = fails(&["plot", "dop-vs-tau", &spec, "--taus", "-1", "-o", o]);
    assert!(e.contains("outside (0, 1e12]"), "{e}");
    let e = fails(&["plot", "scalar-error", &spec, "--pairs", "0.6", "-o", o]);
    assert!(e.contains("MU0:MU"), "{e}");
    let e = fails(&[
        "plot",
        "dop-vs-tau",
        &spec,
        "-o",
        d.join("x.pdf").to_str().unwrap(),
    ]);
    assert!(e.contains(".svg or .png"), "{e}");
    let e = fails(&["plot", "lobe", "-o", o]);
    assert!(e.contains("at least one spec or --table"), "{e}");
    // The service's stream cap, from the spec or --streams, unless --max-streams.
    let big = write(
        &d,
        "big.json",
        &tio2(1.0, true).replace("\"streams\":8", "\"streams\":256"),
    );
    let e = fails(&["plot", "dop-vs-mu", &big, "-o", o]);
    assert!(
        e.contains("solver.streams") && e.contains("[1, 128]") && e.contains("--max-streams"),
        "{e}"
    );
    let e = fails(&["plot", "dop-vs-tau", &spec, "--streams", "200", "-o", o]);
    assert!(e.contains("[1, 128] (--max-streams)"), "{e}");
    let e = fails(&[
        "plot",
        "dop-vs-tau",
        &spec,
        "--streams",
        "200",
        "--max-streams",
        "150",
        "-o",
        o,
    ]);
    assert!(e.contains("[1, 150]"), "{e}");
    assert!(!out.exists(), "no image for bad input");
    // Argument errors from clap also exit non-zero.
    let (code, _, err) = run(&["plot", "dop-vs-tau", "-o", o]);
    assert_ne!(code, 0);
    assert!(err.contains("SPEC"), "{err}");
}
