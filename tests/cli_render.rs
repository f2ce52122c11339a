//! `polbrdf render` through the real binary on small images (docs/render.md):
//! analytic cases (an unpolarized scene of depolarizing surfaces has zero
//! DOP; a linear polarizer follows Malus' law on a polarized source and its
//! four angles recover the Stokes vector), determinism, tables from a
//! running service, and clear errors for bad scenes.

mod common;

use common::{ok, run};

mod service_support;

use serde_json::{Value, json};
use service_support::{Server, TempDir, client, post, wait_done};
use std::path::Path;

fn write_json(d: &Path, name: &str, v: &Value) -> String {
    let p = d.join(name);
    std::fs::write(&p, v.to_string()).unwrap();
    p.to_string_lossy().into_owned()
}

/// `polbrdf solve SPEC --table d/NAME.pbrdf`; returns the table's file name.
fn table(d: &Path, name: &str, spec: &Value) -> String {
    let s = write_json(d, &format!("{name}.json"), spec);
    let t = d
        .join(format!("{name}.pbrdf"))
        .to_string_lossy()
        .into_owned();
    ok(&["solve", &s, "--table", &t]);
    format!("{name}.pbrdf")
}

/// A `.npy` float32 Stokes image: (shape, values).
fn read_npy(path: &str) -> (Vec<usize>, Vec<f32>) {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[..8], b"\x93NUMPY\x01\x00");
    let hlen = u16::from_le_bytes([b[8], b[9]]) as usize;
    let header = std::str::from_utf8(&b[10..10 + hlen]).unwrap();
    assert!(header.contains("'descr': '<f4'"), "{header}");
    let shape: Vec<usize> = header
        .split("'shape': (")
        .nth(1)
        .unwrap()
        .split(')')
        .next()
        .unwrap()
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| s.trim().parse().unwrap())
        .collect();
    let data: Vec<f32> = b[10 + hlen..]
        .chunks(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(data.len(), shape.iter().product::<usize>());
    (shape, data)
}

fn render(scene: &str, out: &str, extra: &[&str]) -> Value {
    let mut args = vec!["render", scene, "-o", out, "--no-progress"];
    args.extend_from_slice(extra);
    ok(&args)
}

/// A Rayleigh layer on a black base, wavelength-free, 4 streams: polarizes
/// strongly and solves in milliseconds.
fn rayleigh_spec() -> Value {
    json!({"layers": [{"optical_thickness": 0.3,
                       "scatterer": {"rayleigh": {"albedo": 1.0}}}],
           "solver": {"streams": 4}})
}

/// One sphere on a floor under a wall, 32×32.
fn sphere_scene(table: &str, light_stokes: [f64; 4]) -> Value {
    json!({
        "camera": {"position": [0, -6, 2], "look_at": [0, 0, 0.8], "fov_deg": 30,
                   "width": 32, "height": 32},
        "lights": [{"directional": {"toward": [-1, -0.5, 1.2], "stokes": light_stokes}},
                   {"point": {"position": [3, -3, 4], "stokes": [10, 0, 0, 0]}}],
        "environment": {"uniform": {"radiance": 0.1}},
        "spheres": [{"center": [0, 0, 1], "radius": 1, "table": table}],
        "floor": {"albedo": 0.5},
        "walls": [{"point": [0, 3, 0], "normal": [0, -1, 0], "albedo": [0.7]}],
        "samples_per_pixel": 2,
        "seed": 5,
        "max_bounces": 1
    })
}

/// A sphere whose table is a Lambertian base under a zero-thickness layer
/// (the table is exactly `(0.8/π) diag(1, 0, 0, 0)`), and a sphere under a
/// scalar Henyey–Greenstein layer on the same base (a Lambertian-like
/// depolarizing material), on a Lambertian floor, under unpolarized light:
/// every pixel has DOP 0. Tolerance 1e-12: the tables' polarized elements
/// are zeros and every frame rotation of a zero `Q, U` gives zero, so the
/// exact answer is 0; 1e-12 only leaves room for rounding-level elements a
/// future solver might store (1e-16 of `f11`) and is ten orders of
/// magnitude below any physical DOP (the Rayleigh sphere below shows
/// DOP ≈ 0.3).
#[test]
fn depolarizing_spheres_under_unpolarized_light_have_zero_dop() {
    let d = TempDir::new("render-lambert");
    let lam = table(
        &d.0,
        "lambert",
        &json!({"layers": [{"optical_thickness": 0,
                            "scatterer": {"rayleigh": {"albedo": 1.0}}}],
                "base": {"lambertian": {"albedo": 0.8}}, "solver": {"streams": 4}}),
    );
    let hg = table(
        &d.0,
        "hg",
        &json!({"layers": [{"optical_thickness": 1,
                            "scatterer": {"henyey_greenstein": {"albedo": 0.9, "g": 0.5}}}],
                "base": {"lambertian": {"albedo": 0.8}}, "solver": {"streams": 4}}),
    );
    for t in [lam, hg] {
        let scene = write_json(&d.0, "scene.json", &sphere_scene(&t, [1.0, 0.0, 0.0, 0.0]));
        let out = d.0.join("lam").to_string_lossy().into_owned();
        let v = render(&scene, &out, &[]);
        let sphere = &v["objects"][0];
        assert_eq!(sphere["object"], "spheres[0]");
        assert!(sphere["pixels"].as_u64().unwrap() > 100, "{v}");
        let (shape, px) = read_npy(&format!("{out}_stokes.npy"));
        assert_eq!(shape, vec![32, 32, 4]);
        let mut lit = 0;
        for s in px.chunks(4) {
            let p = (s[1] as f64).hypot(s[2] as f64).hypot(s[3] as f64);
            assert!(p <= 1e-12 * s[0] as f64, "{t}: {s:?}");
            lit += usize::from(s[0] > 0.0);
        }
        // (A few floor pixels deep under the sphere get no light at 2 paths.)
        assert!(lit > 1000, "{t}: {lit} lit pixels");
        for o in v["objects"].as_array().unwrap() {
            assert!(o["max_dop"].as_f64().unwrap() <= 1e-12, "{o}");
        }
    }
    // The same scene with a polarizing (Rayleigh) sphere is polarized: the
    // check above can fail.
    let r = table(&d.0, "rayleigh", &rayleigh_spec());
    let scene = write_json(&d.0, "scene.json", &sphere_scene(&r, [1.0, 0.0, 0.0, 0.0]));
    let v = render(&scene, &d.0.join("r").to_string_lossy(), &[]);
    assert!(v["objects"][0]["max_dop"].as_f64().unwrap() > 0.2, "{v}");
}

/// Malus' law on a source seen directly: a uniform sky fully linearly
/// polarized at `β` in its frame (x = world up projected, docs/render.md)
/// seen by a level camera (2° field of view, 9×9) is polarized at
/// `ψ = 90° + β` in the camera frame (the sky frame is `(up, −right)`, the
/// camera frame `(right, up)`), so a polarizer at `a` passes
/// `cos²(a − 90° − β)` at the centre pixel. Tolerance 1e-6: the float32
/// output (6e-8 relative) and the frame's variation across the centre pixel
/// (angles ~1e-8 rad at this field of view).
#[test]
fn polarizer_follows_malus_law_on_a_polarized_sky() {
    let d = TempDir::new("render-malus");
    for beta_deg in [0.0f64, 30.0, -55.0] {
        let b = beta_deg.to_radians();
        let scene = json!({
            "camera": {"position": [0, 0, 1], "look_at": [0, 5, 1], "fov_deg": 2,
                       "width": 9, "height": 9},
            "environment": {"uniform": {"stokes": [1.0, (2.0 * b).cos(), (2.0 * b).sin(), 0.0]}},
            "samples_per_pixel": 4
        });
        let s = write_json(&d.0, "sky.json", &scene);
        for a_deg in [0.0f64, 30.0, 90.0, 135.0, -20.0] {
            let out = d.0.join("sky").to_string_lossy().into_owned();
            render(&s, &out, &["--polarizer-deg", &a_deg.to_string()]);
            let (shape, px) = read_npy(&format!("{out}_stokes.npy"));
            assert_eq!(shape, vec![9, 9, 4]);
            let c = &px[(4 * 9 + 4) * 4..(4 * 9 + 4) * 4 + 4];
            let malus = (a_deg - 90.0 - beta_deg).to_radians().cos().powi(2);
            assert!(
                (c[0] as f64 - malus).abs() < 1e-6,
                "β {beta_deg} a {a_deg}: {c:?} vs {malus}"
            );
            // Behind the polarizer the light is polarized along its axis.
            let a = a_deg.to_radians();
            assert!((c[1] as f64 - malus * (2.0 * a).cos()).abs() < 1e-6);
            assert!((c[2] as f64 - malus * (2.0 * a).sin()).abs() < 1e-6);
        }
    }
}

/// A linearly polarized light on a polarizing (Rayleigh) sphere, seen
/// through a polarizer at 0°, 45°, 90° and 135°: the same seed gives the
/// same paths, so per pixel `I₀ + I₉₀ = I₄₅ + I₁₃₅ = I`, `I₀ − I₉₀ = Q`,
/// `I₄₅ − I₁₃₅ = U` of the image without polarizer (Malus' law for partially
/// polarized light, `I(a) = (I + Q cos 2a + U sin 2a)/2`), to float32
/// rounding (1e-5 of the brightest pixel).
#[test]
fn four_polarizer_angles_recover_the_stokes_image() {
    let d = TempDir::new("render-four");
    let t = table(&d.0, "rayleigh", &rayleigh_spec());
    let scene = write_json(&d.0, "scene.json", &sphere_scene(&t, [1.0, 0.6, 0.8, 0.0]));
    let img = |pol: Option<f64>| {
        let out = d.0.join("p").to_string_lossy().into_owned();
        let a = pol.map(|a| a.to_string());
        let extra: Vec<&str> = match &a {
            Some(a) => vec!["--polarizer-deg", a],
            None => vec![],
        };
        render(&scene, &out, &extra);
        read_npy(&format!("{out}_stokes.npy")).1
    };
    let full = img(None);
    let [i0, i45, i90, i135] = [0.0, 45.0, 90.0, 135.0].map(|a| img(Some(a)));
    let max_i = full.chunks(4).fold(0.0f32, |m, s| m.max(s[0])) as f64;
    let tol = 1e-5 * max_i;
    let mut polarized = 0;
    for p in 0..32 * 32 {
        let at = |v: &Vec<f32>| v[4 * p] as f64;
        let s = &full[4 * p..4 * p + 4];
        assert!((at(&i0) + at(&i90) - s[0] as f64).abs() < tol, "pixel {p}");
        assert!(
            (at(&i45) + at(&i135) - s[0] as f64).abs() < tol,
            "pixel {p}"
        );
        assert!((at(&i0) - at(&i90) - s[1] as f64).abs() < tol, "pixel {p}");
        assert!(
            (at(&i45) - at(&i135) - s[2] as f64).abs() < tol,
            "pixel {p}"
        );
        polarized += usize::from((s[1] as f64).hypot(s[2] as f64) > 0.1 * s[0] as f64);
    }
    assert!(polarized > 50, "{polarized} polarized pixels");
}

/// Same seed: identical bytes (Stokes and PNGs); another seed: another
/// image.
#[test]
fn same_seed_same_bytes() {
    let d = TempDir::new("render-determinism");
    let t = table(&d.0, "rayleigh", &rayleigh_spec());
    let scene = write_json(&d.0, "scene.json", &sphere_scene(&t, [1.0, 0.0, 0.0, 1.0]));
    let files = |out: &str| {
        ["stokes.npy", "intensity.png", "dop.png", "s3.png"]
            .map(|f| std::fs::read(format!("{out}_{f}")).unwrap())
    };
    let a = d.0.join("a").to_string_lossy().into_owned();
    let b = d.0.join("b").to_string_lossy().into_owned();
    let c = d.0.join("c").to_string_lossy().into_owned();
    let va = render(&scene, &a, &["--stokes-png"]);
    render(&scene, &b, &["--stokes-png"]);
    render(&scene, &c, &["--stokes-png", "--seed", "6"]);
    assert_eq!(files(&a), files(&b));
    assert_ne!(files(&a)[0], files(&c)[0]);
    // The summary names what was written.
    assert_eq!(va["pixels"], 32 * 32);
    assert_eq!(va["samples_per_pixel"], 2);
    assert_eq!(va["files"]["stokes"], json!(format!("{a}_stokes.npy")));
    assert!(va["time_s"]["render"].as_f64().unwrap() > 0.0);
}

/// A table fetched from a running service by id renders exactly as the
/// same table read from a file.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tables_from_a_running_service() {
    let d = TempDir::new("render-service");
    let s = Server::start(&d.0.join("data"), &[], &[]);
    let c = client();
    let (code, v, _) = post(&c, &s, &rayleigh_spec().to_string()).await;
    assert!(code == 202 || code == 200, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    wait_done(&c, &s, &id).await;
    let url = s.url(&format!("/v1/brdfs/{id}"));
    let dir = d.0.clone();
    tokio::task::spawn_blocking(move || {
        let local = table(&dir, "local", &rayleigh_spec());
        let remote_scene = write_json(
            &dir,
            "remote.json",
            &sphere_scene(&url, [1.0, 0.6, 0.8, 0.0]),
        );
        let local_scene = write_json(
            &dir,
            "local.json",
            &sphere_scene(&local, [1.0, 0.6, 0.8, 0.0]),
        );
        let a = dir.join("remote").to_string_lossy().into_owned();
        let b = dir.join("local").to_string_lossy().into_owned();
        render(&remote_scene, &a, &[]);
        render(&local_scene, &b, &[]);
        let ra = std::fs::read(format!("{a}_stokes.npy")).unwrap();
        let rb = std::fs::read(format!("{b}_stokes.npy")).unwrap();
        assert_eq!(ra, rb);
    })
    .await
    .unwrap();
}

/// Bad scenes fail with exit code 2 and one line naming the problem.
#[test]
fn bad_scenes_are_clear_errors() {
    let d = TempDir::new("render-errors");
    let good = sphere_scene("missing.pbrdf", [1.0, 0.0, 0.0, 0.0]);
    let out = d.0.join("x").to_string_lossy().into_owned();
    let cases: Vec<(Value, &str)> = vec![
        (
            {
                let mut v = good.clone();
                v["camera"]["fov_deg"] = json!(200);
                v
            },
            "camera.fov_deg: 200 is outside the allowed range",
        ),
        (
            {
                let mut v = good.clone();
                v["lights"][0]["directional"]["stokes"] = json!([1, 1, 1, 0]);
                v
            },
            "lights[0].directional.stokes",
        ),
        (
            {
                let mut v = good.clone();
                v["spheres"][0]["colour"] = json!("red");
                v
            },
            "unknown field `colour`",
        ),
        (
            {
                let mut v = good.clone();
                v["walls"][0]["albedo"] = json!([0.1, 0.2]);
                v["spheres"] = json!([]);
                v
            },
            "walls[0].albedo",
        ),
        (good.clone(), "spheres[0].table"),
    ];
    for (scene, needle) in cases {
        let s = write_json(&d.0, "bad.json", &scene);
        let (code, stdout, stderr) = run(&["render", &s, "-o", &out, "--no-progress"]);
        assert_eq!(code, 2, "{needle}: {stderr}");
        assert!(stdout.is_empty());
        assert!(stderr.contains(needle), "expected {needle:?} in {stderr:?}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    }
    std::fs::write(d.0.join("broken.json"), "{\"camera\": ").unwrap();
    let (code, _, stderr) = run(&[
        "render",
        &d.0.join("broken.json").to_string_lossy(),
        "-o",
        &out,
    ]);
    assert_eq!(code, 2);
    assert!(stderr.contains("broken.json"), "{stderr}");
}

/// Equirectangular environments from a PNG (sRGB-decoded) and from a float
/// `.npy` (linear), seen directly: a constant map gives every pixel
/// `scale · value`, unpolarized (float32 output: 1e-6 relative).
#[test]
fn equirectangular_environment_from_png_and_npy() {
    use polbrdf::brdf::export::{NpyType, npy_bytes};
    use polbrdf::render::output::{png_rgb8, srgb_decode};
    let d = TempDir::new("render-env");
    std::fs::write(
        d.0.join("sky.png"),
        png_rgb8(4, 2, &[128u8; 4 * 2 * 3]).unwrap(),
    )
    .unwrap();
    std::fs::write(
        d.0.join("sky.npy"),
        npy_bytes(&[2, 4], &[0.75; 8], NpyType::F32).unwrap(),
    )
    .unwrap();
    for (file, value) in [("sky.png", srgb_decode(128.0 / 255.0)), ("sky.npy", 0.75)] {
        let scene = json!({
            "camera": {"position": [0, 0, 1], "look_at": [1, 2, 1.5], "fov_deg": 60,
                       "width": 8, "height": 6},
            "environment": {"equirectangular": {"path": file, "scale": 2.0, "rotation_deg": 10}},
            "samples_per_pixel": 1
        });
        let s = write_json(&d.0, "env.json", &scene);
        let out = d.0.join("env").to_string_lossy().into_owned();
        render(&s, &out, &[]);
        let (_, px) = read_npy(&format!("{out}_stokes.npy"));
        for p in px.chunks(4) {
            assert!(
                (p[0] as f64 - 2.0 * value).abs() < 1e-6 * value,
                "{file}: {p:?}"
            );
            assert_eq!(&p[1..], &[0.0, 0.0, 0.0]);
        }
    }
}
