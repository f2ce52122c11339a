//! BRDF tables through the real binary: `polbrdf solve --table`, `eval`,
//! `export` (docs/table-format.md). The reference is always
//! `polbrdf solve --points` on the same directions (a direct solve).

mod common;

use common::{ok, run, scratch_dir};

use polbrdf::brdf::grid::PolarGrid;
use serde_json::{Value, json};
use std::path::PathBuf;

type M4 = [[f64; 4]; 4];

/// Interpolation bound of the default grid relative to max f11
/// (tests/brdf_interpolation.rs and docs/table-format.md: measured ≤ 2.1e-6
/// for the materials of Collin et al. 2014; 1e-5 leaves a factor ~5, ten times below the
/// 1e-4 target).
const INTERPOLATION_BOUND: f64 = 1e-5;

fn dir() -> PathBuf {
    scratch_dir("cli-table")
}

fn write_json(d: &std::path::Path, name: &str, v: &Value) -> String {
    let p = d.join(name);
    std::fs::write(&p, v.to_string()).unwrap();
    p.to_string_lossy().into_owned()
}

fn m4(v: &Value) -> M4 {
    let mut m = [[0.0; 4]; 4];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = v[i][j].as_f64().expect("number");
        }
    }
    m
}

fn max_diff(a: &M4, b: &M4) -> f64 {
    let mut e = 0.0f64;
    for i in 0..4 {
        for j in 0..4 {
            e = e.max((a[i][j] - b[i][j]).abs());
        }
    }
    e
}

/// Build a table with `solve --table` and return its path.
fn table_of(d: &std::path::Path, spec: &Value) -> String {
    let s = write_json(d, "spec.json", spec);
    let t = d.join("table.pbrdf").to_string_lossy().into_owned();
    let v = ok(&["solve", &s, "--table", &t]);
    assert_eq!(v["table"]["file"], json!(t));
    t
}

fn eval(table: &str, p: &[f64; 4], wl: Option<f64>) -> Value {
    let a: Vec<String> = p.iter().map(|x| x.to_string()).collect();
    let mut args = vec![
        "eval",
        table,
        "--theta-i",
        &a[0],
        "--phi-i",
        &a[1],
        "--theta-o",
        &a[2],
        "--phi-o",
        &a[3],
    ];
    let w = wl.map(|w| w.to_string());
    if let Some(w) = &w {
        args.push("--wavelength-nm");
        args.push(w);
    }
    ok(&args)
}

fn points_json(points: &[[f64; 4]]) -> Value {
    json!({"points": points.iter().map(|p| json!({
        "theta_i_deg": p[0], "phi_i_deg": p[1], "theta_o_deg": p[2], "phi_o_deg": p[3]
    })).collect::<Vec<_>>()})
}

fn tio2(wavelengths: &[f64]) -> Value {
    json!({
        "layers": [{"optical_thickness": 1.0,
                    "scatterer": {"mie": {"material": "TiO2", "radius_um": 0.2}}}],
        "base": {"lambertian": {"albedo": 0.8}},
        "wavelengths_nm": wavelengths,
    })
}

/// `eval` on a table equals `solve --points` on the same directions: to
/// the solver's Fourier truncation at grid nodes (1e-8 of max f11) and to
/// the interpolation bound off the grid.
#[test]
fn eval_matches_solve_points() {
    let d = dir();
    let spec = tio2(&[550.0, 650.0]);
    let table = table_of(&d, &spec);
    let g = PolarGrid::default();
    let nodes: Vec<[f64; 4]> = vec![
        [g.theta_deg[0], 0.0, g.theta_deg[20], 37.0],
        [g.theta_deg[41], 10.0, g.theta_deg[41], 190.0],
        [g.theta_deg[63], -50.0, g.theta_deg[10], 100.0],
        [g.theta_deg[55], 200.0, g.theta_deg[62], 20.0],
    ];
    let off: Vec<[f64; 4]> = vec![
        [12.5, 0.0, 47.3, 180.0],
        [65.0, 30.0, 65.0, 210.0],
        [88.7, 10.0, 89.6, 150.0],
        [5.0, -20.0, 84.0, 300.0],
        [33.0, 0.0, 0.0, 0.0],
    ];
    for (points, bound) in [(&nodes, 1e-8), (&off, INTERPOLATION_BOUND)] {
        let pf = write_json(&d, "points.json", &points_json(points));
        let s = write_json(&d, "spec.json", &spec);
        let reference = ok(&["solve", &s, "--points", &pf]);
        for (w, res) in reference["results"].as_array().unwrap().iter().enumerate() {
            let wl = res["wavelength_nm"].as_f64().unwrap();
            let (mut err, mut fmax) = (0.0f64, 0.0f64);
            for (k, p) in points.iter().enumerate() {
                let want = m4(&res["points"][k]["mueller"]);
                let got = eval(&table, p, Some(wl));
                assert_eq!(got["wavelength_nm"].as_f64(), Some(wl));
                assert!(got["frames"].as_str().unwrap().contains("meridian"));
                assert!(got["specular"].is_null());
                fmax = fmax.max(want[0][0]);
                err = err.max(max_diff(&m4(&got["mueller"]), &want));
            }
            assert!(
                err <= bound * fmax,
                "wavelength {w}: {:.2e} of max f11 > {bound:e}",
                err / fmax
            );
        }
    }
    // Between the wavelengths: linear interpolation of the two.
    let p = [20.0, 0.0, 40.0, 90.0];
    let a = m4(&eval(&table, &p, Some(550.0))["mueller"]);
    let b = m4(&eval(&table, &p, Some(650.0))["mueller"]);
    let c = m4(&eval(&table, &p, Some(625.0))["mueller"]);
    for i in 0..4 {
        for j in 0..4 {
            assert!((c[i][j] - (0.25 * a[i][j] + 0.75 * b[i][j])).abs() <= 1e-14 * a[0][0]);
        }
    }
    let (code, _, err) = run(&[
        "eval",
        &table,
        "--theta-i",
        "10",
        "--phi-i",
        "0",
        "--theta-o",
        "10",
        "--phi-o",
        "0",
        "--wavelength-nm",
        "700",
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("outside the table's range"), "{err}");
}

/// A mirror base: `eval` reports the specular term exactly at the mirror
/// direction (and `null` elsewhere), equal to `solve --points`'s at a grid
/// node.
#[test]
fn eval_reports_the_specular_term() {
    let d = dir();
    let spec = json!({
        "layers": [{"optical_thickness": 0.3,
                    "scatterer": {"mie": {"material": "iron oxide", "radius_um": 0.2,
                                          "host_index": 1.5}}}],
        "base": {"fresnel": {"material": "aluminium"}},
        "wavelengths_nm": [550.0],
        "solver": {"streams": 8},
    });
    let table = table_of(&d, &spec);
    let t = PolarGrid::default().theta_deg[30];
    let p = [t, 25.0, t, 205.0];
    let pf = write_json(&d, "points.json", &points_json(&[p]));
    let s = write_json(&d, "spec.json", &spec);
    let reference = ok(&["solve", &s, "--points", &pf]);
    let want = m4(&reference["results"][0]["specular"][0]["mueller"]);
    let got = eval(&table, &p, None);
    let spec_m = m4(&got["specular"]);
    assert!(max_diff(&spec_m, &want) <= 1e-12 * want[0][0]);
    let diffuse_want = m4(&reference["results"][0]["points"][0]["mueller"]);
    let diffuse_got = m4(&got["mueller"]);
    assert!(max_diff(&diffuse_got, &diffuse_want) <= 1e-8 * diffuse_want[0][0]);
    let off = eval(&table, &[t, 25.0, t, 206.0], None);
    assert!(off["specular"].is_null());
}

/// npy (own header parser), JSON and CSV exports parse back and agree with
/// `eval` at the same directions.
#[test]
fn exports_parse_back() {
    let d = dir();
    let table = table_of(&d, &tio2(&[550.0, 650.0]));
    let theta = |k: usize| 90.0 * (k as f64 + 0.5) / 51.0;

    // npy, float64.
    let npy = d.join("dense.npy").to_string_lossy().into_owned();
    let v = ok(&[
        "export", &table, "--format", "npy", "-o", &npy, "--dtype", "f64",
    ]);
    assert_eq!(v["shape"], json!([2, 51, 51, 61, 4, 4]));
    let b = std::fs::read(&npy).unwrap();
    assert_eq!(&b[..8], b"\x93NUMPY\x01\x00");
    let hlen = u16::from_le_bytes([b[8], b[9]]) as usize;
    let header = std::str::from_utf8(&b[10..10 + hlen]).unwrap();
    assert!(header.contains("'descr': '<f8'"), "{header}");
    assert!(header.contains("'fortran_order': False"));
    assert!(
        header.contains("'shape': (2, 51, 51, 61, 4, 4)"),
        "{header}"
    );
    let data: Vec<f64> = b[10 + hlen..]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(data.len(), 2 * 51 * 51 * 61 * 16);
    for (w, wl) in [(0usize, 550.0), (1, 650.0)] {
        for (ti, to, p) in [(0usize, 50usize, 30usize), (17, 3, 7), (50, 50, 60)] {
            let e = eval(
                &table,
                &[theta(ti), 0.0, theta(to), 6.0 * p as f64],
                Some(wl),
            );
            let m = m4(&e["mueller"]);
            let base = ((((w * 51) + ti) * 51 + to) * 61 + p) * 16;
            for k in 0..16 {
                assert!((data[base + k] - m[k / 4][k % 4]).abs() <= 1e-12 * m[0][0]);
            }
        }
    }
    // npy, float32: same header with '<f4' and half the data.
    let npy32 = d.join("dense32.npy").to_string_lossy().into_owned();
    ok(&["export", &table, "--format", "npy", "-o", &npy32]);
    let b32 = std::fs::read(&npy32).unwrap();
    assert!(
        std::str::from_utf8(&b32[10..10 + hlen])
            .unwrap()
            .contains("'<f4'")
    );
    assert_eq!(b32.len() - 10 - hlen, 2 * 51 * 51 * 61 * 16 * 4);

    // JSON point set.
    let pts = [[10.0, 0.0, 70.0, 45.0], [60.0, 90.0, 60.0, 270.0]];
    let pf = write_json(&d, "points.json", &points_json(&pts));
    let out = d.join("points_out.json").to_string_lossy().into_owned();
    ok(&[
        "export", &table, "--format", "json", "-o", &out, "--points", &pf,
    ]);
    let j: Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(j["results"].as_array().unwrap().len(), 2);
    for res in j["results"].as_array().unwrap() {
        let wl = res["wavelength_nm"].as_f64().unwrap();
        for (k, p) in pts.iter().enumerate() {
            let e = eval(&table, p, Some(wl));
            assert_eq!(res["points"][k]["mueller"], e["mueller"]);
            assert!(res["points"][k]["specular"].is_null());
        }
    }

    // CSV slice: the plane of incidence at theta_i = 35.
    let csv = d.join("slice.csv").to_string_lossy().into_owned();
    ok(&[
        "export",
        &table,
        "--format",
        "csv",
        "-o",
        &csv,
        "--theta-i-deg",
        "35",
    ]);
    let text = std::fs::read_to_string(&csv).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("wavelength_nm,theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg"));
    assert_eq!(lines.len(), 1 + 2 * 102);
    for l in [lines[1], lines[60], lines[150]] {
        let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
        assert_eq!(f[1], 35.0);
        let e = eval(&table, &[f[1], f[2], f[3], f[4]], Some(f[0]));
        let m = m4(&e["mueller"]);
        for k in 0..16 {
            assert!((f[6 + k] - m[k / 4][k % 4]).abs() <= 1e-12 * m[0][0]);
        }
    }
    // Missing arguments are errors.
    let (code, _, err) = run(&["export", &table, "--format", "csv", "-o", &csv]);
    assert_ne!(code, 0);
    assert!(err.contains("--theta-i-deg"), "{err}");
}

/// A damaged table file makes `eval` and `export` fail with a message that
/// says what is wrong.
#[test]
fn corrupted_tables_are_rejected() {
    let d = dir();
    let spec = json!({
        "layers": [{"optical_thickness": 0.5,
                    "scatterer": {"rayleigh": {"albedo": 0.9}}}],
        "solver": {"streams": 4},
    });
    let table = table_of(&d, &spec);
    let good = std::fs::read(&table).unwrap();
    let bad = d.join("bad.pbrdf").to_string_lossy().into_owned();
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (
            {
                let mut b = good.clone();
                let k = good.len() / 2;
                b[k] ^= 0x01;
                b
            },
            "checksum mismatch",
        ),
        (good[..good.len() - 100].to_vec(), "truncated"),
        (
            {
                let mut b = good.clone();
                b[0] = b'X';
                b
            },
            "not a polbrdf table",
        ),
        (
            {
                let mut b = good.clone();
                b[8] = 9;
                b
            },
            "unsupported table format version 9",
        ),
    ];
    for (bytes, msg) in cases {
        std::fs::write(&bad, &bytes).unwrap();
        let (code, out, err) = run(&[
            "eval",
            &bad,
            "--theta-i",
            "10",
            "--phi-i",
            "0",
            "--theta-o",
            "20",
            "--phi-o",
            "0",
        ]);
        assert_ne!(code, 0, "{msg}: {out}");
        assert!(err.contains(msg) && err.contains(&bad), "{msg}: {err}");
        let out_file = d.join("x.npy").to_string_lossy().into_owned();
        let (code, _, err) = run(&["export", &bad, "--format", "npy", "-o", &out_file]);
        assert_ne!(code, 0);
        assert!(err.contains(msg), "{msg}: {err}");
    }
    // The good file still evaluates.
    ok(&[
        "eval",
        &table,
        "--theta-i",
        "10",
        "--phi-i",
        "0",
        "--theta-o",
        "20",
        "--phi-o",
        "0",
    ]);
}

/// Every number a user can print is a value (issue 20): `--phi-i -1.5e-05`
/// gives what `--phi-i=-1.5e-05` gives, and a negative number outside the
/// range reaches the range check, not clap's unknown-flag error.
#[test]
fn eval_takes_negative_numbers_in_scientific_notation() {
    let d = scratch_dir("cli-table-negative");
    let mut spec = tio2(&[550.0]);
    spec["solver"] = json!({"streams": 8});
    let table = table_of(&d, &spec);
    let spaced = ok(&[
        "eval",
        &table,
        "--theta-i",
        "30",
        "--phi-i",
        "-1.5e-05",
        "--theta-o",
        "40",
        "--phi-o",
        "-1.8E+2",
    ]);
    let joined = ok(&[
        "eval",
        &table,
        "--theta-i=30",
        "--phi-i=-1.5e-05",
        "--theta-o=40",
        "--phi-o=-180",
    ]);
    assert_eq!(spaced["mueller"], joined["mueller"]);
    assert!(spaced["mueller"][0][0].as_f64().unwrap() > 0.0);
    let (code, _, err) = run(&[
        "eval",
        &table,
        "--theta-i",
        "30",
        "--phi-i",
        "-1e+3",
        "--theta-o",
        "40",
        "--phi-o",
        "0",
    ]);
    assert_ne!(code, 0);
    assert!(
        err.contains("phi") && !err.contains("unexpected argument"),
        "{err}"
    );
}
