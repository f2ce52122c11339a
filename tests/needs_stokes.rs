//! `needs.stokes` and `needs.theta_i_deg` (docs/spec.md): a reduced table
//! holds exactly the matching part of the full table (same solve), its
//! file says which elements and incident nodes it holds and is smaller by
//! that much, `eval` answers in the reduced shape (CLI and HTTP), asking
//! for what it lacks is refused naming the field, needs at their defaults
//! keep a spec's id, and bad needs are refused at submission (HTTP 422,
//! `polbrdf solve` exit 2) with their path.

mod service_support;

use polbrdf::brdf::format::{self, DataType};
use polbrdf::brdf::table::{BuildOptions, Directions, Table};
use polbrdf::{material, plan};
use serde_json::{Value, json};
use service_support::*;

/// TiO2 spheres, τ = 1, 16 streams, on a 12-node grid (fast), with `needs`
/// (a JSON object's members, merged with the grid).
fn tio2(base: &str, needs: &str) -> String {
    let sep = if needs.is_empty() { "" } else { "," };
    format!(
        r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"mie":{{"material":"TiO2","radius_um":0.2}}}}}}],
            "base":{base},"wavelengths_nm":[550],"solver":{{"streams":16}},
            "needs":{{"grid":{{"polar_nodes":12}}{sep}{needs}}}}}"#
    )
}

fn table(text: &str) -> Table {
    let s = material::parse(text).unwrap();
    Table::from_spec_needs(&s, &BuildOptions::default()).unwrap()
}

fn d(ti: f64, pi: f64, to: f64, po: f64) -> Directions {
    Directions {
        theta_i_deg: ti,
        phi_i_deg: pi,
        theta_o_deg: to,
        phi_o_deg: po,
    }
}

/// Direction pairs: on and off the nodes, the mirror pair (specular over
/// silver), grazing exit.
fn pairs(theta_i: &[f64]) -> Vec<Directions> {
    let mut v = Vec::new();
    for &ti in theta_i {
        for (to, po) in [
            (0.0, 0.0),
            (40.0, 100.0),
            (ti, 180.0),
            (88.5, 10.0),
            (63.0, 250.0),
        ] {
            v.push(d(ti, 15.0, to, po + 15.0));
        }
    }
    v
}

/// The largest |a − b| over the first `rows × cols` elements.
fn diff(a: &[[f64; 4]; 4], b: &[[f64; 4]; 4], rows: usize, cols: usize) -> f64 {
    let mut worst: f64 = 0.0;
    for p in 0..rows {
        for q in 0..cols {
            worst = worst.max((a[p][q] - b[p][q]).abs());
        }
    }
    worst
}

/// Each reduced table against the full one of the same spec: the stored
/// coefficients are the full table's, element for element and node for
/// node (the same deterministic solve: exactly equal), and so are the
/// evaluated BRDF and specular matrix in the kept elements (within
/// round-off of the interpolation sums); elements not kept are zero, and
/// the full table's are not (so a wrong element would be seen).
#[test]
fn reduced_tables_are_exactly_parts_of_the_full_table() {
    for base in [r#""black""#, r#"{"fresnel":{"material":"silver"}}"#] {
        let full = table(&tio2(base, ""));
        let fw = &full.wavelengths[0];
        let (n, m) = (fw.nodes, fw.orders);
        let mut scale: f64 = 0.0;
        for p in pairs(&[0.0, 30.0, 60.0]) {
            scale = scale.max(full.eval(&p, None).unwrap()[0][0].abs());
        }
        for (stokes, rows, cols) in [("unpolarized_in", 4, 1), ("intensity", 1, 1)] {
            let t = table(&tio2(base, &format!(r#""stokes":"{stokes}""#)));
            let w = &t.wavelengths[0];
            assert_eq!((w.ns, w.cols, w.orders), (rows, cols, m), "{stokes}");
            assert_eq!(t.shape(), (rows, cols));
            for mm in 0..m {
                for o in 0..n {
                    for i in 0..n {
                        let (a, b) = (fw.node(mm, o, i), w.node(mm, o, i));
                        for p in 0..4 {
                            for q in 0..4 {
                                let expect = if p < rows && q < cols { a[p][q] } else { 0.0 };
                                assert_eq!(
                                    b[p][q], expect,
                                    "{stokes} m={mm} o={o} i={i} ({p},{q})"
                                );
                            }
                        }
                    }
                }
            }
            for p in pairs(&[0.0, 30.0, 60.0]) {
                let (a, b) = (full.eval(&p, None).unwrap(), t.eval(&p, None).unwrap());
                assert!(diff(&a, &b, rows, cols) <= 1e-13 * scale, "{stokes} {p:?}");
                assert!(diff(&b, &[[0.0; 4]; 4], 4, 4) <= diff(&b, &[[0.0; 4]; 4], rows, cols));
                let (sa, sb) = (
                    full.specular(&p, None).unwrap(),
                    t.specular(&p, None).unwrap(),
                );
                assert_eq!(sa.is_some(), sb.is_some());
                if let (Some(sa), Some(sb)) = (sa, sb) {
                    assert!(diff(&sa, &sb, rows, cols) <= 1e-15, "{stokes} {p:?}");
                    assert!(
                        diff(&sb, &[[0.0; 4]; 4], 4, 4) == diff(&sb, &[[0.0; 4]; 4], rows, cols)
                    );
                }
            }
            // The full table's other elements are not zero: the check sees them.
            let a = full.eval(&d(30.0, 0.0, 40.0, 100.0), None).unwrap();
            assert!(a[0][1].abs() > 1e-3 * a[0][0] && a[1][1].abs() > 1e-3 * a[0][0]);
        }
        // Incident angles: a list (0 and 60 are nodes here? the test does
        // not assume it) and a range; inside them the reduced table is the
        // full one, weight for weight.
        for (need, inside) in [
            (r#""theta_i_deg":[60,0,30]"#, vec![0.0, 30.0, 60.0]),
            (
                r#""theta_i_deg":{"min":20,"max":40}"#,
                vec![20.0, 27.3, 33.0, 40.0],
            ),
        ] {
            let t = table(&tio2(base, need));
            let w = &t.wavelengths[0];
            assert!(w.incident.len() < n, "{need}: {:?}", w.incident);
            for p in pairs(&inside) {
                let (a, b) = (full.eval(&p, None).unwrap(), t.eval(&p, None).unwrap());
                assert!(diff(&a, &b, 4, 4) <= 1e-13 * scale, "{need} {p:?}");
                let (sa, sb) = (
                    full.specular(&p, None).unwrap(),
                    t.specular(&p, None).unwrap(),
                );
                assert_eq!(sa, sb, "{need} {p:?}");
            }
            for ti in [10.0, 45.0, 89.0] {
                let e = t
                    .eval(&d(ti, 0.0, 30.0, 0.0), None)
                    .unwrap_err()
                    .to_string();
                assert!(e.starts_with("theta_i_deg = "), "{e}");
                assert!(e.contains("needs.theta_i_deg"), "{e}");
            }
        }
    }
}

/// The file says what it holds and reads back exactly; a reduced table is
/// smaller by the elements and incident nodes it leaves out (the
/// coefficient block is `8 · M · N · K · rows · cols` bytes, f64), and a
/// full table is written exactly as format version 4 always was (flags
/// bits 0–1 only, no new metadata keys), so files of this version written
/// before still read.
#[test]
fn files_say_what_they_hold_and_shrink_by_it() {
    let base = r#""black""#;
    let full = table(&tio2(base, ""));
    let full_bytes = format::to_bytes(&full, DataType::F64).unwrap();
    let flags = |b: &[u8]| {
        let meta_len = u64::from_le_bytes(b[56..64].try_into().unwrap()) as usize;
        let at = 64 + meta_len + 12;
        let meta: Value = serde_json::from_slice(&b[64..64 + meta_len]).unwrap();
        (u32::from_le_bytes(b[at..at + 4].try_into().unwrap()), meta)
    };
    let (f, meta) = flags(&full_bytes);
    assert!(f <= 3, "{f}");
    assert!(meta.get("stokes").is_none() && meta.get("theta_i_deg").is_none());
    let coeff = |t: &Table| {
        let w = &t.wavelengths[0];
        8 * w.orders * w.nodes * w.incident.len() * w.ns * w.cols
    };
    let (n, m) = (full.wavelengths[0].nodes, full.wavelengths[0].orders);
    assert_eq!(coeff(&full), 8 * m * n * n * 16);
    for (need, bit, rows, cols) in [
        (r#""stokes":"unpolarized_in""#, 4, 4, 1),
        (r#""stokes":"intensity""#, 4, 1, 1),
        (r#""theta_i_deg":[0,30,60]"#, 8, 4, 4),
        (
            r#""stokes":"intensity","theta_i_deg":{"min":0,"max":10}"#,
            12,
            1,
            1,
        ),
    ] {
        let t = table(&tio2(base, need));
        let bytes = format::to_bytes(&t, DataType::F64).unwrap();
        let (f, meta) = flags(&bytes);
        assert_eq!(f & 12, bit, "{need}");
        assert_eq!(
            meta.get("stokes").is_some(),
            rows * cols < 16,
            "{need}: {meta}"
        );
        let back = format::from_bytes(&bytes).unwrap();
        assert_eq!(back, t, "{need}");
        let w = &t.wavelengths[0];
        assert_eq!(coeff(&t), 8 * m * n * w.incident.len() * rows * cols);
        // Everything but the coefficients is the same size to within the
        // metadata and the node list.
        let saved = full_bytes.len() as i64 - bytes.len() as i64;
        let expect = (coeff(&full) - coeff(&t)) as i64;
        assert!((saved - expect).abs() < 400, "{need}: {saved} vs {expect}");
        // A reader refuses a layout that disagrees with the metadata (a
        // column of 4 rows whose metadata claims the full matrix).
        if bit & 4 == 4 && rows == 4 {
            let mut bad = t.clone();
            bad.metadata.stokes = material::needs::StokesNeed::Full;
            assert!(format::from_bytes(&format::to_bytes(&bad, DataType::F64).unwrap()).is_err());
        }
    }
}

#[test]
fn needs_at_their_defaults_keep_the_id() {
    let spec = |needs: &str| {
        format!(
            r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"rayleigh":{{"albedo":1}}}}}}]{needs}}}"#
        )
    };
    let id = |needs: &str| plan::id_of_spec(&material::parse(&spec(needs)).unwrap());
    let (canonical, plain) = id("");
    assert!(!canonical.contains("needs"), "{canonical}");
    assert_eq!(id(r#","needs":{"stokes":"full"}"#).1, plain);
    let mut seen = std::collections::HashSet::new();
    for other in [
        r#","needs":{"stokes":"unpolarized_in"}"#,
        r#","needs":{"stokes":"intensity"}"#,
        r#","needs":{"theta_i_deg":[0,30,60]}"#,
        r#","needs":{"theta_i_deg":{"min":0,"max":60}}"#,
    ] {
        let (c, i) = id(other);
        assert_ne!(i, plain, "{other}");
        assert!(c.contains("\"needs\""), "{c}");
        assert!(seen.insert(i), "two needs share an id: {other}");
    }
    // Equivalent lists of angles are one need.
    assert_eq!(
        id(r#","needs":{"theta_i_deg":[60,0,30,30]}"#).1,
        id(r#","needs":{"theta_i_deg":[0,30,60]}"#).1
    );
}

fn polbrdf(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_polbrdf"))
        .args(args)
        .output()
        .unwrap()
}

/// A small spec for the CLI and the service: Rayleigh τ = 1 over a
/// dielectric mirror, 4 streams, 8 polar nodes.
fn small(needs: &str) -> String {
    format!(
        r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"rayleigh":{{"albedo":0.9}}}}}}],
            "base":{{"fresnel":{{"material":{{"n":1.5,"k":0}}}}}},"solver":{{"streams":4}},
            "needs":{{"grid":{{"polar_nodes":8}},{needs}}}}}"#
    )
}

/// `polbrdf eval` answers in the table's shape and refuses an incident
/// angle the table does not hold (exit 2, naming the need).
#[test]
fn cli_eval_answers_in_the_reduced_shape() {
    let dir = TempDir::new("needs_stokes_cli");
    let mut shapes = Vec::new();
    for (k, needs) in [
        r#""stokes":"full""#,
        r#""stokes":"unpolarized_in""#,
        r#""stokes":"intensity","theta_i_deg":[30]"#,
    ]
    .iter()
    .enumerate()
    {
        let spec = dir.0.join(format!("s{k}.json"));
        std::fs::write(&spec, small(needs)).unwrap();
        let out = dir.0.join(format!("t{k}.pbrdf"));
        let o = polbrdf(&[
            "solve",
            spec.to_str().unwrap(),
            "--table",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let mirror = [
            "--theta-i",
            "30",
            "--phi-i",
            "0",
            "--theta-o",
            "30",
            "--phi-o",
            "180",
        ];
        let o = polbrdf(&[&["eval", out.to_str().unwrap()], &mirror[..]].concat());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: Value = serde_json::from_slice(&o.stdout).unwrap();
        let shape = |m: &Value| {
            let rows = m.as_array().unwrap();
            (rows.len(), rows[0].as_array().unwrap().len())
        };
        assert_eq!(shape(&v["mueller"]), shape(&v["specular"]), "{v}");
        shapes.push(shape(&v["mueller"]));
        if k == 2 {
            let o = polbrdf(&[
                "eval",
                out.to_str().unwrap(),
                "--theta-i",
                "31",
                "--phi-i",
                "0",
                "--theta-o",
                "30",
                "--phi-o",
                "180",
            ]);
            assert_eq!(o.status.code(), Some(2));
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(
                err.contains("theta_i_deg") && err.contains("needs.theta_i_deg"),
                "{err}"
            );
            let o = polbrdf(&[
                "export",
                out.to_str().unwrap(),
                "--format",
                "mitsuba",
                "-o",
                dir.0.join("m.pbsdf").to_str().unwrap(),
            ]);
            assert!(!o.status.success());
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(
                err.contains("needs.stokes") && err.contains("Mitsuba"),
                "{err}"
            );
        }
    }
    assert_eq!(shapes, [(4, 4), (4, 1), (1, 1)]);
}

/// The service: `/eval` (GET and POST) answers in the reduced shape, and
/// a query outside the result is a 422 problem naming the field; a Mitsuba
/// export of a reduced result and a dense export of a result with few
/// incident angles are 422 naming what is missing; bad needs are refused
/// at POST (422) and by `polbrdf solve` (exit 2) with their path.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_service_answers_in_the_reduced_shape_and_refuses_the_rest() {
    let dir = TempDir::new("needs_stokes");
    let s = Server::start(&dir.0.join("data"), &[], &[]);
    let c = client();
    let mut ids = Vec::new();
    for needs in [
        r#""stokes":"unpolarized_in""#,
        r#""stokes":"intensity","theta_i_deg":{"min":10,"max":40}"#,
    ] {
        let (code, v, _) = post(&c, &s, &small(needs)).await;
        assert!(code == 202 || code == 200, "{v}");
        let id = v["id"].as_str().unwrap().to_string();
        wait_done(&c, &s, &id).await;
        ids.push(id);
    }
    let get = |id: &str, ti: f64| {
        format!("/v1/brdfs/{id}/eval?theta_i_deg={ti}&phi_i_deg=0&theta_o_deg={ti}&phi_o_deg=180")
    };
    let (code, v) = get_json(&c, &s, &get(&ids[0], 30.0)).await;
    assert_eq!(code, 200, "{v}");
    let m = &v["points"][0]["mueller"];
    assert_eq!(m.as_array().unwrap().len(), 4, "{v}");
    assert!(
        m.as_array()
            .unwrap()
            .iter()
            .all(|r| r.as_array().unwrap().len() == 1)
    );
    assert_eq!(
        v["points"][0]["specular"].as_array().unwrap().len(),
        4,
        "{v}"
    );
    let (code, v) = get_json(&c, &s, &get(&ids[1], 30.0)).await;
    assert_eq!(code, 200, "{v}");
    assert_eq!(v["points"][0]["mueller"].as_array().unwrap().len(), 1);
    assert_eq!(v["points"][0]["mueller"][0].as_array().unwrap().len(), 1);
    // Outside the incident range: 422 naming the field, GET and POST.
    let (code, v) = get_json(&c, &s, &get(&ids[1], 50.0)).await;
    assert_eq!(code, 422, "{v}");
    assert_eq!(v["path"], "theta_i_deg", "{v}");
    assert!(
        v["detail"].as_str().unwrap().contains("needs.theta_i_deg"),
        "{v}"
    );
    let body = json!({"points": [
        {"theta_i_deg": 20, "phi_i_deg": 0, "theta_o_deg": 10, "phi_o_deg": 0},
        {"theta_i_deg": 9, "phi_i_deg": 0, "theta_o_deg": 10, "phi_o_deg": 0}]});
    let r = c
        .post(s.url(&format!("/v1/brdfs/{}/eval", ids[1])))
        .json(&body)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 422);
    let v: Value = r.json().await.unwrap();
    assert_eq!(v["path"], "points[1].theta_i_deg", "{v}");
    // Exports that need more than the result holds.
    for (id, query, path, word) in [
        (&ids[0], "format=mitsuba", "format", "needs.stokes"),
        (&ids[1], "format=npy", "theta_count", "needs.theta_i_deg"),
    ] {
        let r = c
            .get(s.url(&format!("/v1/brdfs/{id}/table?{query}")))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status().as_u16(), 422, "{query}");
        let ct = r.headers()["content-type"].to_str().unwrap().to_string();
        assert!(ct.starts_with("application/problem+json"), "{ct}");
        let v: Value = r.json().await.unwrap();
        assert_eq!(v["path"], path, "{v}");
        assert!(v["detail"].as_str().unwrap().contains(word), "{v}");
    }
    // Bad needs: 422 at POST and exit 2 from `polbrdf solve`, with the path.
    let rayleigh = |needs: &str, solver: &str| {
        format!(
            r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"rayleigh":{{"albedo":1}}}}}}]{solver},"needs":{needs}}}"#
        )
    };
    for (body, path) in [
        (rayleigh(r#"{"stokes":"linear"}"#, ""), "needs.stokes"),
        (
            rayleigh(
                r#"{"stokes":"unpolarized_in"}"#,
                r#","solver":{"polarized":false}"#,
            ),
            "needs.stokes",
        ),
        (
            rayleigh(r#"{"theta_i_deg":[10,90]}"#, ""),
            "needs.theta_i_deg[1]",
        ),
        (rayleigh(r#"{"theta_i_deg":[]}"#, ""), "needs.theta_i_deg"),
        (
            rayleigh(r#"{"theta_i_deg":{"min":50,"max":40}}"#, ""),
            "needs.theta_i_deg.max",
        ),
        (
            rayleigh(r#"{"theta_i_deg":{"min":-5,"max":40}}"#, ""),
            "needs.theta_i_deg.min",
        ),
    ] {
        let (code, v, _) = post(&c, &s, &body).await;
        assert_eq!(code, 422, "{body}: {v}");
        assert!(v["path"].as_str().unwrap().starts_with(path), "{body}: {v}");
        let file = dir.0.join("bad.json");
        std::fs::write(&file, &body).unwrap();
        let out = polbrdf(&["solve", file.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(2), "{body}");
        assert!(
            String::from_utf8_lossy(&out.stderr).contains(path),
            "{body}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
