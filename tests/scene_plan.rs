//! Whole scenes (issue 16, docs/render.md "Materials and `scene plan`"):
//! the needs `polbrdf scene plan` derives from a scene (the stokes rule on
//! polarized and unpolarized lights and skies, a camera polarizer, one
//! sphere among depolarizing surfaces, two spheres with and without
//! bounces; wavelengths and tolerance), the stokes rule checked against the
//! renderer itself, bad scenes, the gallery scene, and `polbrdf render` of
//! a material spec against the render of the table `polbrdf solve --table`
//! makes of the same spec.

mod common;

use common::{ok, run, scratch_dir};
use polbrdf::plan::StreamPolicy;
use polbrdf::render::scene_plan::{
    MEASURED_TIMES_MS, model_streams_for_tolerance, solve_time_ms, solves,
};
use serde_json::{Value, json};
use std::path::Path;

fn write_json(d: &Path, name: &str, v: &Value) -> String {
    let p = d.join(name);
    std::fs::write(&p, serde_json::to_string_pretty(v).unwrap()).unwrap();
    p.to_string_lossy().into_owned()
}

/// A Rayleigh layer on a black base, wavelength-free, 4 streams: polarizes
/// strongly and solves in milliseconds.
fn rayleigh_spec() -> Value {
    json!({"layers": [{"optical_thickness": 0.3,
                       "scatterer": {"rayleigh": {"albedo": 1.0}}}],
           "solver": {"streams": 4}})
}

/// One sphere (material `material`) on a floor under a wall, unpolarized
/// lights and sky, 24×16.
fn one_sphere(material: Value) -> Value {
    json!({
        "camera": {"position": [0, -6, 2], "look_at": [0, 0, 0.8], "fov_deg": 30,
                   "width": 24, "height": 16},
        "lights": [{"directional": {"toward": [-1, -0.5, 1.2], "stokes": [1, 0, 0, 0]}},
                   {"point": {"position": [3, -3, 4], "stokes": [10, 0, 0, 0]}}],
        "environment": {"uniform": {"radiance": 0.1}},
        "spheres": [{"center": [0, 0, 1], "radius": 1, "material": material}],
        "floor": {"albedo": 0.5},
        "walls": [{"point": [0, 3, 0], "normal": [0, -1, 0], "albedo": 0.7}],
        "samples_per_pixel": 2,
        "seed": 5,
        "max_bounces": 1
    })
}

/// `scene` with a second sphere of the same material.
fn two_spheres(mut scene: Value) -> Value {
    let mut second = scene["spheres"][0].clone();
    second["center"] = json!([2.2, 0.5, 1]);
    scene["spheres"].as_array_mut().unwrap().push(second);
    scene
}

/// `polbrdf scene plan` of `scene` written to `d`.
fn plan(d: &Path, scene: &Value) -> Value {
    let s = write_json(d, "scene.json", scene);
    ok(&["scene", "plan", &s])
}

/// The stokes need and its why for every sphere.
fn stokes(plan: &Value) -> Vec<(String, String)> {
    plan["materials"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            let s = &m["needs"]["stokes"];
            (
                s["value"].as_str().unwrap().to_string(),
                s["why"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

#[test]
fn the_stokes_rule_follows_lights_sky_and_other_spheres() {
    let d = scratch_dir("scene-plan-stokes");
    let base = one_sphere(rayleigh_spec());
    let with = |f: &dyn Fn(&mut Value)| {
        let mut v = base.clone();
        f(&mut v);
        v
    };
    // (scene, expected need per sphere, a word of the why)
    let cases: Vec<(&str, Value, &str, usize, &str)> = vec![
        (
            "one sphere, depolarizing floor and wall",
            base.clone(),
            "unpolarized_in",
            1,
            "depolarizing",
        ),
        (
            "circularly polarized directional light",
            with(&|v| v["lights"][0]["directional"]["stokes"] = json!([1, 0, 0, 1])),
            "full",
            1,
            "lights[0].directional.stokes",
        ),
        (
            "linearly polarized point light, no bounces",
            with(&|v| {
                v["lights"][1]["point"]["stokes"] = json!([10, 0, 3, 0]);
                v["max_bounces"] = json!(0);
            }),
            "full",
            1,
            "lights[1].point.stokes",
        ),
        (
            "polarized sky, one bounce",
            with(&|v| v["environment"] = json!({"uniform": {"stokes": [1, 0.3, 0, 0]}})),
            "full",
            1,
            "environment.uniform.stokes",
        ),
        (
            "polarized sky, no bounces: it never reaches the sphere",
            with(&|v| {
                v["environment"] = json!({"uniform": {"stokes": [1, 0.3, 0, 0]}});
                v["max_bounces"] = json!(0);
            }),
            "unpolarized_in",
            1,
            "max_bounces 0",
        ),
        (
            "unpolarized sky given as Stokes",
            with(&|v| v["environment"] = json!({"uniform": {"stokes": [1, 0, 0, 0]}})),
            "unpolarized_in",
            1,
            "unpolarized",
        ),
        (
            "an equirectangular map is unpolarized (not read by the plan)",
            with(&|v| v["environment"] = json!({"equirectangular": {"path": "nowhere.png"}})),
            "unpolarized_in",
            1,
            "unpolarized",
        ),
        (
            "two spheres, one bounce: sphere→sphere paths",
            two_spheres(base.clone()),
            "full",
            2,
            "sphere→sphere",
        ),
        (
            "two spheres, three bounces",
            with(&|v| {
                *v = two_spheres(v.clone());
                v["max_bounces"] = json!(3);
            }),
            "full",
            2,
            "sphere→sphere",
        ),
        (
            "two spheres, no bounces",
            with(&|v| {
                *v = two_spheres(v.clone());
                v["max_bounces"] = json!(0);
            }),
            "unpolarized_in",
            2,
            "max_bounces 0",
        ),
        (
            "one material sphere and one table sphere, one bounce",
            with(&|v| {
                v["spheres"]
                    .as_array_mut()
                    .unwrap()
                    .push(json!({"center": [2.2, 0.5, 1], "radius": 1, "table": "t.pbrdf"}));
                v["wavelengths_nm"] = json!([550]);
            }),
            "full",
            2,
            "sphere→sphere",
        ),
    ];
    for (what, scene, need, n, why) in cases {
        let p = plan(&d, &scene);
        let got = stokes(&p);
        assert_eq!(got.len(), n, "{what}");
        for (value, reason) in &got {
            assert_eq!(value, need, "{what}: {reason}");
            assert!(reason.contains(why), "{what}: {reason}");
        }
        // The reduced spec asks for it (or, for "full", says nothing).
        let spec = &p["materials"][0]["spec"];
        match need {
            "full" => assert!(spec.get("needs").is_none(), "{what}: {spec}"),
            _ => assert_eq!(spec["needs"]["stokes"], json!(need), "{what}"),
        }
    }
}

/// A polarizer in front of the camera acts after the last interaction:
/// it changes no need.
#[test]
fn a_camera_polarizer_changes_no_need() {
    let d = scratch_dir("scene-plan-polarizer");
    for scene in [
        one_sphere(rayleigh_spec()),
        two_spheres(one_sphere(rayleigh_spec())),
    ] {
        let without = plan(&d, &scene);
        let mut polarized = scene.clone();
        polarized["camera"]["polarizer_deg"] = json!(30);
        let with = plan(&d, &polarized);
        assert_eq!(without["materials"], with["materials"]);
        assert_eq!(without["total"], with["total"]);
    }
}

/// Scale the columns 1–3 of every stored Mueller coefficient (the response
/// to polarized incident light) by `c`.
fn scale_polarized_columns(t: &mut polbrdf::brdf::Table, c: f64) {
    for w in &mut t.wavelengths {
        let ns = w.ns;
        assert_eq!(ns, 4);
        for block in w.f.chunks_mut(ns * ns) {
            for p in 0..ns {
                for q in 1..ns {
                    block[p * ns + q] *= c;
                }
            }
        }
    }
}

/// The stokes rule against the renderer: where the plan says
/// `unpolarized_in`, a table without its polarized-input columns renders
/// exactly the same image; where it says `full` (two spheres, one bounce;
/// a polarized light), the image changes.
#[test]
fn unpolarized_in_is_what_the_renderer_uses() {
    use polbrdf::render::{build, scene};
    use std::sync::Arc;
    let d = scratch_dir("scene-plan-renderer");
    let spec = polbrdf::material::parse(&rayleigh_spec().to_string()).unwrap();
    let full =
        polbrdf::brdf::Table::from_spec(&spec, polbrdf::brdf::PolarGrid::graded(16).unwrap())
            .unwrap();
    let mut first_column = full.clone();
    scale_polarized_columns(&mut first_column, 0.0);
    let render = |v: &Value, t: &polbrdf::brdf::Table| {
        let desc = scene::parse(&v.to_string()).unwrap();
        // Every sphere shares the one table.
        let shared = Arc::new(t.clone());
        let tables: Vec<_> = desc.spheres.iter().map(|_| shared.clone()).collect();
        build(&desc, &tables, None).unwrap().render(&|_, _| {}).data
    };
    let mut polarized_light = one_sphere(rayleigh_spec());
    polarized_light["lights"][0]["directional"]["stokes"] = json!([1, 0.6, 0, 0.6]);
    let mut polarized_camera = one_sphere(rayleigh_spec());
    polarized_camera["camera"]["polarizer_deg"] = json!(60);
    for (scene, need) in [
        (one_sphere(rayleigh_spec()), "unpolarized_in"),
        (polarized_camera, "unpolarized_in"),
        (
            {
                let mut v = two_spheres(one_sphere(rayleigh_spec()));
                v["max_bounces"] = json!(0);
                v
            },
            "unpolarized_in",
        ),
        (two_spheres(one_sphere(rayleigh_spec())), "full"),
        (polarized_light, "full"),
    ] {
        let p = plan(&d, &scene);
        assert!(stokes(&p).iter().all(|(v, _)| v == need), "{p}");
        // The renderer reads tables: the same scene with table spheres.
        let mut v = scene.clone();
        for s in v["spheres"].as_array_mut().unwrap() {
            s.as_object_mut().unwrap().remove("material");
            s["table"] = json!("in-memory");
        }
        let (a, b) = (render(&v, &full), render(&v, &first_column));
        let largest = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let diff = a
            .iter()
            .zip(&b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        if need == "unpolarized_in" {
            assert_eq!(diff, 0.0, "{need}: {scene}");
        } else {
            assert!(diff > 1e-3 * largest, "{need}: {diff} of {largest}");
        }
    }
}

#[test]
fn wavelengths_and_tolerance_propagate() {
    let d = scratch_dir("scene-plan-propagate");
    let spec = json!({
        "layers": [{"optical_thickness": 1,
                    "scatterer": {"mie": {"material": "TiO2", "radius_um": 0.2}}}],
        "base": "black",
        "wavelengths_nm": [700, 400, 450, 500, 550, 600, 650],
        "solver": {"streams": 16},
        "needs": {"error_estimate": false}
    });
    write_json(&d, "tio2.json", &spec);
    let mut scene = one_sphere(json!("tio2.json"));
    scene["wavelengths_nm"] = json!([650, 450, 550]);
    scene["tolerance"] = json!(1e-3);
    let p = plan(&d, &scene);
    let m = &p["materials"][0];
    assert_eq!(p["wavelengths_nm"], json!([450.0, 550.0, 650.0]));
    assert_eq!(
        m["needs"]["wavelengths_nm"]["value"],
        json!([450.0, 550.0, 650.0])
    );
    assert_eq!(m["needs"]["tolerance"]["value"], json!(1e-3));
    let r = &m["spec"];
    assert_eq!(r["wavelengths_nm"], json!([450.0, 550.0, 650.0]));
    assert_eq!(r["solver"], json!({"tolerance": 1e-3}), "streams would win");
    // `error_estimate: false` is refused with a tolerance: dropped.
    assert_eq!(r["needs"], json!({"stokes": "unpolarized_in"}));
    assert_eq!(r["layers"], spec["layers"]);
    assert_eq!(
        m["source"]["material"],
        json!(d.join("tio2.json").to_string_lossy())
    );
    let c = &m["cost"];
    assert_eq!(c["full"]["wavelengths"], 7);
    assert_eq!(c["reduced"]["wavelengths"], 3);
    assert_eq!(c["full"]["solves"], json!([16]), "no estimate asked");
    // 1e-3: the model's 4-stream estimate 9.1e-4 (docs/accuracy.md) meets it.
    assert_eq!(c["reduced"]["solves"], json!([2, 3, 4]));
    let (f, r_ms) = (
        c["full"]["model_ms"].as_f64().unwrap(),
        c["reduced"]["model_ms"].as_f64().unwrap(),
    );
    assert!(
        r_ms / 3.0 < f / 7.0,
        "4 streams cost less than 16 per wavelength"
    );
    assert_eq!(c["relative_time"].as_f64().unwrap(), r_ms / f);
    assert_eq!(c["relative_table_size"].as_f64().unwrap(), 3.0 / 7.0 * 0.25);
    // The reduced spec is a valid spec.
    let s = write_json(&d, "reduced.json", r);
    assert_eq!(ok(&["solve", &s])["results"].as_array().unwrap().len(), 3);

    // No scene wavelengths and no tolerance: the first sphere's first
    // wavelength (seven, not three), the spec's own solver settings.
    let mut scene = one_sphere(json!("tio2.json"));
    scene["max_bounces"] = json!(2);
    let p = plan(&d, &scene);
    let r = &p["materials"][0]["spec"];
    assert_eq!(r["wavelengths_nm"], json!([400.0]));
    assert_eq!(r["solver"], json!({"streams": 16}));
    assert_eq!(r["needs"]["error_estimate"], json!(false));
    // Two spheres of the same spec: one solve in the total.
    let p = plan(&d, &two_spheres(scene));
    assert_eq!(p["materials"][1]["same_as"], json!("spheres[0]"));
    let one = p["materials"][0]["cost"]["reduced"]["model_ms"]
        .as_f64()
        .unwrap();
    assert_eq!(p["total"]["reduced_model_ms"].as_f64().unwrap(), one);
}

#[test]
fn bad_scenes_exit_2_naming_the_path() {
    let d = scratch_dir("scene-plan-errors");
    write_json(&d, "bad-spec.json", &json!({"layers": []}));
    let good = one_sphere(rayleigh_spec());
    let with = |f: &dyn Fn(&mut Value)| {
        let mut v = good.clone();
        f(&mut v);
        v
    };
    let cases: Vec<(Value, &str)> = vec![
        (
            with(&|v| v["spheres"][0]["table"] = json!("t.pbrdf")),
            "spheres[0]: give exactly one of `table`",
        ),
        (
            with(&|v| {
                v["spheres"][0].as_object_mut().unwrap().remove("material");
            }),
            "spheres[0]: give exactly one of `table`",
        ),
        (
            with(&|v| v["spheres"][0]["material"] = json!("missing.json")),
            "spheres[0].material: ",
        ),
        (
            with(&|v| v["spheres"][0]["material"] = json!("bad-spec.json")),
            "spheres[0].material: ",
        ),
        (
            with(&|v| v["spheres"][0]["material"]["layers"][0]["optical_thickness"] = json!(-1)),
            "spheres[0].material.layers[0].optical_thickness: -1",
        ),
        (
            with(&|v| v["spheres"][0]["material"]["colour"] = json!("red")),
            "spheres[0].material",
        ),
        (
            with(&|v| v["tolerance"] = json!(0.9)),
            "tolerance: 0.9 is outside",
        ),
        (
            with(&|v| {
                *v = two_spheres(v.clone());
                v["spheres"][0]["name"] = json!("paint");
                v["spheres"][1]["name"] = json!("paint");
            }),
            "spheres[1].name: \"paint\" already names spheres[0]",
        ),
        (
            with(&|v| v["spheres"][0]["material"] = json!(3)),
            "spheres[0].material",
        ),
    ];
    for (scene, expect) in cases {
        let s = write_json(&d, "bad.json", &scene);
        let out = d.join("x").to_string_lossy().into_owned();
        for args in [
            vec!["scene", "plan", s.as_str()],
            vec!["render", s.as_str(), "-o", out.as_str(), "--no-progress"],
        ] {
            let (code, stdout, err) = run(&args);
            assert_eq!(code, 2, "{args:?} {scene}: {err}");
            assert!(stdout.is_empty(), "{stdout}");
            assert!(err.contains(expect), "{args:?}: {err} lacks {expect}");
            assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        }
    }
}

/// The gallery's Figure 10 scene (four table spheres, one bounce): every
/// sphere needs the full matrix, whether or not its tables were built.
#[test]
fn plan_of_the_gallery_scene() {
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/docs/gallery/scenes/render-fig10.json"
    );
    let p = ok(&["scene", "plan", scene]);
    let m = p["materials"].as_array().unwrap();
    assert_eq!(m.len(), 4);
    for (k, e) in m.iter().enumerate() {
        assert_eq!(e["name"], json!(format!("spheres[{k}]")));
        assert_eq!(e["needs"]["stokes"]["value"], "full");
        assert!(e["source"]["table"].as_str().unwrap().ends_with(".pbrdf"));
        assert!(e.get("spec").is_none() && e.get("cost").is_none());
    }
}

fn render(scene: &str, out: &str) -> Value {
    ok(&["render", scene, "-o", out, "--no-progress"])
}

/// A sphere named by its spec renders exactly as the same sphere with the
/// table `polbrdf solve --table` makes of that spec (same seed, same
/// pixels): once with the scene taking the spec's own settings, once with
/// a scene tolerance (then the table of the reduced spec the plan prints).
#[test]
fn a_material_renders_as_its_table() {
    let d = scratch_dir("scene-plan-render");
    let spec = json!({
        "layers": [{"optical_thickness": 1,
                    "scatterer": {"mie": {"material": "TiO2", "radius_um": 0.2}}}],
        "base": {"lambertian": {"albedo": 0.3}},
        "wavelengths_nm": [650.0],
        "solver": {"streams": 8}
    });
    write_json(&d, "paint.json", &spec);
    for tolerance in [None, Some(1e-2)] {
        let mut by_spec = one_sphere(json!("paint.json"));
        if let Some(t) = tolerance {
            by_spec["tolerance"] = json!(t);
        }
        let scene_spec = write_json(&d, "by-spec.json", &by_spec);
        // The table of what the plan asks for, made by `polbrdf solve`.
        let reduced = &ok(&["scene", "plan", &scene_spec])["materials"][0]["spec"];
        match tolerance {
            // Unpolarized lights, one sphere among depolarizing surfaces.
            None => {
                let mut expect = spec.clone();
                expect["needs"] = json!({"stokes": "unpolarized_in"});
                assert_eq!(reduced, &expect);
            }
            Some(t) => assert_eq!(reduced["solver"], json!({"tolerance": t})),
        }
        let s = write_json(&d, "reduced.json", reduced);
        let t = d.join("paint.pbrdf").to_string_lossy().into_owned();
        ok(&["solve", &s, "--table", &t]);
        let mut by_table = by_spec.clone();
        by_table["spheres"][0] = json!({"center": [0, 0, 1], "radius": 1, "table": "paint.pbrdf"});
        let scene_table = write_json(&d, "by-table.json", &by_table);

        let a = render(&scene_spec, &d.join("a").to_string_lossy());
        let b = render(&scene_table, &d.join("b").to_string_lossy());
        assert_eq!(a["solved"].as_array().unwrap().len(), 1);
        assert_eq!(a["wavelengths_nm"], json!([650.0]));
        for f in ["stokes", "intensity", "dop"] {
            let fa = std::fs::read(a["files"][f].as_str().unwrap()).unwrap();
            let fb = std::fs::read(b["files"][f].as_str().unwrap()).unwrap();
            assert!(fa == fb, "{f} differs (tolerance {tolerance:?})");
        }
        assert_eq!(a["objects"], b["objects"]);
    }
}

/// The float32 values of a `.npy` file (version 1 header).
fn npy_f32(path: &str) -> Vec<f32> {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[..6], b"\x93NUMPY");
    let header = u16::from_le_bytes([b[8], b[9]]) as usize;
    b[10 + header..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// The render from the reduced table the plan asks for (`unpolarized_in`:
/// Mueller column 0 only) equals the render from the full table of the same
/// material, pixel for pixel, on every Stokes component: the light that
/// reaches the sphere is unpolarized, so the columns left out meet zeros.
/// (The full table's matrices are Cloude-filtered and the reduced ones,
/// with 4 of 16 elements, cannot be: the difference allowed is round-off of
/// the float32 image, 1e-6 of its largest value.)
#[test]
fn a_reduced_table_renders_as_the_full_table() {
    let d = scratch_dir("scene-plan-reduced");
    let spec = json!({
        "layers": [{"optical_thickness": 1,
                    "scatterer": {"mie": {"material": "TiO2", "radius_um": 0.2}}}],
        "base": {"fresnel": {"material": "silver"}},
        "wavelengths_nm": [650.0],
        "solver": {"streams": 8}
    });
    let scene = one_sphere(spec.clone());
    let reduced = &plan(&d, &scene)["materials"][0]["spec"];
    assert_eq!(reduced["needs"]["stokes"], "unpolarized_in", "{reduced}");
    let mut images = Vec::new();
    for (name, s) in [("full", spec), ("reduced", reduced.clone())] {
        let spec_path = write_json(&d, &format!("{name}.json"), &s);
        let t = d
            .join(format!("{name}.pbrdf"))
            .to_string_lossy()
            .into_owned();
        ok(&["solve", &spec_path, "--table", &t]);
        let mut by_table = scene.clone();
        by_table["spheres"][0] = json!({"center": [0, 0, 1], "radius": 1, "table": t});
        let scene_path = write_json(&d, &format!("{name}-scene.json"), &by_table);
        let out = render(&scene_path, &d.join(name).to_string_lossy());
        images.push(npy_f32(out["files"]["stokes"].as_str().unwrap()));
    }
    let (full, reduced) = (&images[0], &images[1]);
    assert_eq!(full.len(), reduced.len());
    let peak = full.iter().fold(0.0f32, |m, x| m.max(x.abs()));
    let worst = full
        .iter()
        .zip(reduced)
        .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
    assert!(peak > 0.0 && worst <= 1e-6 * peak, "{worst:e} of {peak:e}");
    // The images see polarization (the test could tell columns apart).
    assert!(
        full.chunks(4)
            .any(|p| p[1].abs() + p[2].abs() + p[3].abs() > 1e-3 * peak)
    );
}

// The cost model and the stokes switch (`polbrdf::render::scene_plan`).

#[test]
fn model_time_passes_through_the_measured_points() {
    for &(n, t) in &MEASURED_TIMES_MS {
        assert!((solve_time_ms(n) - t).abs() < 1e-9 * t, "{n}");
    }
    assert!(solve_time_ms(12) > 32.8 && solve_time_ms(12) < 60.2);
    assert!(solve_time_ms(128) > 1347.0 && solve_time_ms(4) < 32.8);
    // Below 8 streams with the 8–16 slope: 32.8 (4/8)^log2(60.2/32.8).
    let expect = 32.8 * 0.5f64.powf((60.2f64 / 32.8).log2());
    assert!((solve_time_ms(4) - expect).abs() < 1e-9);
}

#[test]
fn tolerances_pick_streams_like_the_measured_ladder() {
    // The ladder 4, 6, 8, 12, 16, 24, 32, 48, …; a level is taken when its
    // estimate is within t and the true error at N/2 within 3t.
    // 9.1e-4 ≤ 1e-2 at 4 streams.
    assert_eq!(model_streams_for_tolerance(1e-2), 4);
    // 6 streams: 8.4e-5, but 3 streams are 2.5e-4 (4/3)^6 = 1.4e-3 off;
    // 8: 8.5e-5, last change 2.5e-4 ≤ 3e-4.
    assert_eq!(model_streams_for_tolerance(1e-4), 8);
    // 12 streams: 4.1e-6 ≤ 1e-5, last change 1.7e-5 ≤ 3e-5.
    assert_eq!(model_streams_for_tolerance(1e-5), 12);
    // 16 streams: last change 2.7e-5 > 3e-6; 24: 3.2e-8, 4.9e-7 ≤ 3e-6.
    assert_eq!(model_streams_for_tolerance(1e-6), 24);
    // 24 streams: last change 4.9e-7 > 3e-7; 32: 3.0e-9, 1.7e-7 ≤ 3e-7.
    assert_eq!(model_streams_for_tolerance(1e-7), 32);
    // 1e-8: at 32 the last change 1.7e-7 > 3e-8; at 48 (N^-6 beyond 32)
    // 2.6e-10 and 1.6e-8 ≤ 3e-8.
    assert_eq!(model_streams_for_tolerance(1e-8), 48);
    assert_eq!(
        solves(&StreamPolicy::Tolerance(1e-4), true),
        vec![2, 3, 4, 6, 8]
    );
    // 12 and 24 add their 3N/4 levels (9, 18); 16 and 32 reuse answers.
    assert_eq!(
        solves(&StreamPolicy::Tolerance(1e-7), true),
        vec![2, 3, 4, 6, 8, 9, 12, 16, 18, 24, 32]
    );
    assert_eq!(solves(&StreamPolicy::Fixed(16), true), vec![8, 12, 16]);
    assert_eq!(solves(&StreamPolicy::Fixed(16), false), vec![16]);
}
