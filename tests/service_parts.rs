//! Per-wavelength results (docs/service.md, "Per-wavelength results"),
//! through the real server: a request for wavelengths [a, b, c] stores each
//! wavelength as a result of its own; a request for a subset is answered
//! from them at once (200, `covered_by`, no solve, counted through
//! `/metrics`); a superset solves only the missing wavelength; and the
//! assembled tables hold exactly what a solve of the whole request holds.

mod service_support;

use polbrdf::brdf::format;
use polbrdf::brdf::table::{BuildOptions, Table};
use polbrdf::material;
use serde_json::Value;
use service_support::*;

/// TiO2 spheres over silver on a small grid (a solve per wavelength is a
/// fraction of a second).
fn spec(wavelengths: &str) -> String {
    format!(
        r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"mie":{{"material":"TiO2","radius_um":0.2}}}}}}],
            "base":{{"fresnel":{{"material":"silver"}}}},"wavelengths_nm":{wavelengths},
            "solver":{{"streams":6}},"needs":{{"error_estimate":false,"grid":{{"polar_nodes":8}}}}}}"#
    )
}

async fn table(c: &reqwest::Client, s: &Server, id: &str) -> Table {
    let r = c
        .get(s.url(&format!("/v1/brdfs/{id}/table")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    format::from_bytes(&r.bytes().await.unwrap()).unwrap()
}

fn ids(v: &Value) -> Vec<String> {
    v.as_array()
        .unwrap_or_else(|| panic!("covered_by is not an array: {v}"))
        .iter()
        .map(|x| x.as_str().unwrap().to_string())
        .collect()
}

/// The table a solve of the whole spec writes, with the timings the
/// service leaves out of its bytes set to 0.
fn solved_locally(text: &str) -> Table {
    let mut t =
        Table::from_spec_needs(&material::parse(text).unwrap(), &BuildOptions::default()).unwrap();
    for w in &mut t.wavelengths {
        w.wall_time_ms = 0.0;
    }
    for w in &mut t.metadata.wavelengths {
        w.wall_time_ms = 0.0;
    }
    t
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn wavelengths_are_results_of_their_own() {
    let dir = TempDir::new("parts");
    let s = Server::start(&dir.0, &["--workers", "1"], &[]);
    let c = client();
    let solves = || metric(&c, &s, "polbrdf_solves_started_total");

    // Three wavelengths: three solves, and the table of the whole request.
    let (code, v, _) = post(&c, &s, &spec("[450, 550, 650]")).await;
    assert_eq!(code, 202, "{v}");
    assert_eq!(ids(&v["covered_by"]), Vec::<String>::new());
    let whole_id = v["id"].as_str().unwrap().to_string();
    wait_done(&c, &s, &whole_id).await;
    assert_eq!(solves().await, 3.0);
    let whole = table(&c, &s, &whole_id).await;
    assert_eq!(whole, solved_locally(&spec("[450, 550, 650]")));

    // One of them alone: its own cached result, no solve.
    let (code, v, _) = post(&c, &s, &spec("[550]")).await;
    assert_eq!(code, 200, "{v}");
    assert_eq!(v["status"], "done");
    let id_550 = v["id"].as_str().unwrap().to_string();
    assert_eq!(solves().await, 3.0);
    let one = table(&c, &s, &id_550).await;
    assert_eq!(one.wavelengths, [whole.wavelengths[1].clone()]);
    assert_eq!(one.metadata.spec_hash, id_550);

    // Two of them: assembled at once from the cached wavelengths, no solve,
    // naming them; its table is those two blocks of the whole table.
    let (_, v450, _) = post(&c, &s, &spec("[450]")).await;
    let (_, v650, _) = post(&c, &s, &spec("[650]")).await;
    let (id_450, id_650) = (v450["id"].as_str().unwrap(), v650["id"].as_str().unwrap());
    let (code, v, _) = post(&c, &s, &spec("[650, 450]")).await;
    assert_eq!(code, 200, "{v}");
    assert_eq!(v["status"], "done");
    let mut covered = ids(&v["covered_by"]);
    covered.sort();
    let mut expected = vec![id_450.to_string(), id_650.to_string()];
    expected.sort();
    assert_eq!(covered, expected);
    assert_eq!(solves().await, 3.0);
    let pair_id = v["id"].as_str().unwrap().to_string();
    let pair = table(&c, &s, &pair_id).await;
    assert_eq!(
        pair.wavelengths,
        [whole.wavelengths[0].clone(), whole.wavelengths[2].clone()]
    );
    assert_eq!(pair, solved_locally(&spec("[650, 450]")));
    // Its resource is a done result like any other.
    let (code, r) = get_json(&c, &s, &format!("/v1/brdfs/{pair_id}")).await;
    assert_eq!(code, 200);
    assert_eq!(r["status"], "done");
    assert_eq!(r["wavelengths"], 2);

    // A superset: only the missing wavelength is solved.
    let (code, v, _) = post(&c, &s, &spec("[450, 500, 550, 650]")).await;
    assert_eq!(code, 202, "{v}");
    assert_eq!(ids(&v["covered_by"]).len(), 3, "{v}");
    let big_id = v["id"].as_str().unwrap().to_string();
    wait_done(&c, &s, &big_id).await;
    assert_eq!(solves().await, 4.0);
    let big = table(&c, &s, &big_id).await;
    assert_eq!(big, solved_locally(&spec("[450, 500, 550, 650]")));
    // ... and 500 nm is now a result of its own.
    let (code, _, _) = post(&c, &s, &spec("[500]")).await;
    assert_eq!(code, 200);
    assert_eq!(solves().await, 4.0);
}

/// A request that needs no error estimate is answered from the cached
/// result of the same request with one (the same N-stream solve): 200,
/// `covered_by` naming it, no solve; the numbers are those of a direct
/// solve without the estimate (to round-off), and the table states no
/// estimate.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_result_with_the_estimate_covers_a_request_without_it() {
    let dir = TempDir::new("parts-cover");
    let s = Server::start(&dir.0, &["--workers", "1"], &[]);
    let c = client();
    let solves = || metric(&c, &s, "polbrdf_solves_started_total");
    let with = |wl: &str| spec(wl).replace(r#""error_estimate":false,"#, "");
    assert!(!with("[550]").contains("error_estimate"));

    let (code, v, _) = post(&c, &s, &with("[450, 550]")).await;
    assert_eq!(code, 202, "{v}");
    wait_done(&c, &s, v["id"].as_str().unwrap()).await;
    assert_eq!(solves().await, 2.0);
    let (_, v550, _) = post(&c, &s, &with("[550]")).await;
    let (_, v450, _) = post(&c, &s, &with("[450]")).await;
    let with_id = |v: &Value| v["id"].as_str().unwrap().to_string();

    // [550] without the estimate: cut from [550] with it (and stored as a
    // result of its own, which [450, 550] without the estimate then reads).
    let mut reduced_550 = String::new();
    for wl in ["[550]", "[450, 550]"] {
        let (code, v, _) = post(&c, &s, &spec(wl)).await;
        assert_eq!(code, 200, "{wl}: {v}");
        let covering = if wl == "[550]" {
            reduced_550 = with_id(&v);
            vec![with_id(&v550)]
        } else {
            vec![with_id(&v450), reduced_550.clone()]
        };
        assert_eq!(ids(&v["covered_by"]), covering, "{wl}");
        let served = table(&c, &s, v["id"].as_str().unwrap()).await;
        assert_eq!(served.metadata.spec_hash, v["id"].as_str().unwrap());
        let direct = solved_locally(&spec(wl));
        assert_eq!(served.metadata.spec, direct.metadata.spec);
        assert_eq!(served.metadata.wavelengths, direct.metadata.wavelengths);
        for (a, b) in served.wavelengths.iter().zip(&direct.wavelengths) {
            let scale = b.f.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            let d =
                a.f.iter()
                    .zip(&b.f)
                    .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
            assert!(d <= 1e-12 * scale, "{wl}: {d:e} of {scale:e}");
            assert_eq!(a.specular, b.specular);
        }
    }
    assert_eq!(solves().await, 2.0, "the covered requests solved nothing");
}

/// TiO2 over silver at 550 nm on a 24-node grid with the estimate, plus
/// `solver` and `needs` fields.
fn family_member(solver: &str, needs: &str) -> String {
    format!(
        r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"mie":{{"material":"TiO2","radius_um":0.2}}}}}}],
            "base":{{"fresnel":{{"material":"silver"}}}},"wavelengths_nm":[550],
            "solver":{{{solver}}},"needs":{{"grid":{{"polar_nodes":24}}{needs}}}}}"#
    )
}

/// One full result covers every smaller request of its family through the
/// server (docs/service.md, "Covering results"): fewer elements and
/// incident angles (copies: the direct solve's numbers exactly), a coarser
/// grid (interpolated: within the stated interpolation errors of a direct
/// solve) and a looser tolerance (its estimate meets it), each 200 with
/// `covered_by` naming it and no solve; what it cannot hold (a finer grid)
/// is solved.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_result_covers_fewer_elements_angles_nodes_and_a_looser_tolerance() {
    let dir = TempDir::new("parts-family");
    let s = Server::start(&dir.0, &["--workers", "1"], &[]);
    let c = client();
    let solves = || metric(&c, &s, "polbrdf_solves_started_total");
    let full_spec = family_member(r#""streams":8"#, "");
    let (code, v, _) = post(&c, &s, &full_spec).await;
    assert_eq!(code, 202, "{v}");
    let full_id = v["id"].as_str().unwrap().to_string();
    wait_done(&c, &s, &full_id).await;
    assert_eq!(solves().await, 1.0);
    let full = table(&c, &s, &full_id).await;
    let estimate = full.metadata.wavelengths[0]
        .error_estimate
        .as_ref()
        .unwrap()
        .max_err_f11;

    let cut = family_member(
        r#""streams":8"#,
        r#","stokes":"unpolarized_in","theta_i_deg":[0, 30]"#,
    );
    let coarse = family_member(r#""streams":8"#, "").replace("24", "12");
    let loose = family_member(&format!(r#""tolerance":{}"#, 2.0 * estimate), "");
    for text in [&cut, &coarse, &loose] {
        let (code, v, _) = post(&c, &s, text).await;
        assert_eq!(code, 200, "{text}: {v}");
        assert_eq!(ids(&v["covered_by"]), vec![full_id.clone()], "{text}");
        let served = table(&c, &s, v["id"].as_str().unwrap()).await;
        let direct = solved_locally(text);
        assert_eq!(served.metadata.spec, direct.metadata.spec);
        assert_eq!(served.grid, direct.grid);
        if text == &cut {
            assert_eq!(served.wavelengths, direct.wavelengths);
            assert_eq!(served.metadata, direct.metadata);
        } else if text == &coarse {
            let stated = served.metadata.wavelengths[0].interpolation_error.unwrap()
                + direct.metadata.wavelengths[0].interpolation_error.unwrap();
            let (a, b) = (&served.wavelengths[0], &direct.wavelengths[0]);
            let (mut worst, mut f11_max) = (0.0_f64, 0.0_f64);
            for ti in [0.0, 17.0, 45.0, 63.0, 80.0, 88.0] {
                for to in [5.0, 30.0, 52.0, 74.0, 86.0] {
                    for dphi in [0.0, 1.3, std::f64::consts::PI] {
                        let (x, y) = (
                            a.eval(&served.grid, ti, to, dphi)[0][0],
                            b.eval(&direct.grid, ti, to, dphi)[0][0],
                        );
                        f11_max = f11_max.max(y);
                        worst = worst.max((x - y).abs());
                    }
                }
            }
            assert!(
                worst <= stated * f11_max,
                "{:e} > {stated:e}",
                worst / f11_max
            );
        } else {
            // The tolerance is met by the cached 8-stream solve (a direct
            // solve picks its own streams: not compared number for number).
            assert_eq!(served.metadata.solver.tolerance, Some(2.0 * estimate));
            assert_eq!(served.metadata.wavelengths[0].streams, 8);
            assert_eq!(served.wavelengths[0].f, full.wavelengths[0].f);
        }
    }
    assert_eq!(solves().await, 1.0, "the covered requests solved nothing");

    // A finer grid is not held by the 24-node result: solved.
    let finer = family_member(r#""streams":8"#, "").replace("24", "32");
    let (code, v, _) = post(&c, &s, &finer).await;
    assert_eq!(code, 202, "{v}");
    assert_eq!(ids(&v["covered_by"]), Vec::<String>::new());
    wait_done(&c, &s, v["id"].as_str().unwrap()).await;
    assert_eq!(solves().await, 2.0);
}
