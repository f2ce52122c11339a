//! `polbrdf render SCENE.json -o PREFIX`: the polarized preview renderer
//! (docs/render.md). Reads the scene, loads its tables (files relative to
//! the scene, or service URLs) and environment image, renders on the rayon
//! pool with a progress bar on a terminal's stderr, writes the images and
//! prints a JSON summary.

use super::scene::{load_materials, plan_loaded, resolve, scene_dir};
use super::source::load_table_with;
use crate::brdf::Table;
use crate::render::{self, Overrides, output, scene, scene_plan};
use clap::Args;
use serde_json::{Value, json};
use std::io::{IsTerminal, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Arguments of `polbrdf render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The scene (JSON, docs/render.md).
    pub scene: String,
    /// Output prefix: writes PREFIX_intensity.png, PREFIX_dop.png and
    /// PREFIX_stokes.npy (and PREFIX_s1/_s2/_s3.png with --stokes-png).
    #[arg(short = 'o', long = "out")]
    pub out: String,
    /// Override camera.width.
    #[arg(long)]
    pub width: Option<u32>,
    /// Override camera.height.
    #[arg(long)]
    pub height: Option<u32>,
    /// Override samples_per_pixel.
    #[arg(long)]
    pub spp: Option<u32>,
    /// Override seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Override max_bounces.
    #[arg(long)]
    pub max_bounces: Option<u32>,
    /// Put a linear polarizer in front of the camera at this angle
    /// (degrees from the image's right towards its up).
    #[arg(long)]
    pub polarizer_deg: Option<f64>,
    /// Channel wavelengths, one or three, comma-separated (nm).
    #[arg(long, value_delimiter = ',')]
    pub wavelength_nm: Option<Vec<f64>>,
    /// Exposure multiplier of the intensity image (default: automatic,
    /// the 99th percentile of lit pixels at 0.9).
    #[arg(long)]
    pub exposure: Option<f64>,
    /// Degree of polarization shown as full red in the DOP image.
    #[arg(long, default_value_t = 1.0)]
    pub dop_max: f64,
    /// Also write false-colour S1/S2/S3 images (|S_k/I| = 1 full colour).
    #[arg(long)]
    pub stokes_png: bool,
    /// No progress bar even on a terminal.
    #[arg(long)]
    pub no_progress: bool,
    /// Solve the material spheres on this service (`POST /v1/scenes`,
    /// waiting for the jobs) instead of locally, e.g. http://127.0.0.1:8080.
    #[arg(long)]
    pub server: Option<String>,
    // Cache for tables named by service URLs (in the scene, or the results of --server).
    #[command(flatten)]
    pub cache: super::source::CacheArgs,
}

fn write(path: &str, bytes: &[u8]) -> Result<(), String> {
    std::fs::write(path, bytes).map_err(|e| format!("{path}: {e}"))
}

/// Solve sphere `k`'s (reduced, solvable) spec into a table as
/// `polbrdf solve --table` does (`Table::from_spec_needs`); returns the
/// table and its per-wavelength metadata.
fn solve_material(k: usize, spec_json: &str) -> Result<(Table, Value), String> {
    let at = |e: String| format!("spheres[{k}].material (reduced for the scene): {e}");
    let spec = crate::material::parse(spec_json).map_err(|e| at(e.to_string()))?;
    let max = super::solve::default_max_streams();
    super::solve::check_stream_cap(&spec, max).map_err(|e| at(e.to_string()))?;
    crate::plan::check_solvable(&spec, max).map_err(|e| at(e.to_string()))?;
    let options = crate::brdf::table::BuildOptions {
        max_streams: max,
        on_progress: &|_, _, _| {},
    };
    let t = Table::from_spec_needs(&spec, &options).map_err(|e| at(e.to_string()))?;
    let info = serde_json::to_value(&t.metadata.wavelengths).expect("JSON");
    Ok((t, info))
}

/// `POST /v1/scenes` with the scene (`text`, its material specs inlined and
/// the command line's wavelengths and bounces, which decide the needs),
/// wait until every job is done, and return per sphere the URL of its
/// result (`None` for table spheres).
fn solve_on_server(
    server: &str,
    text: &str,
    desc: &scene::SceneDesc,
    materials: &[Option<scene_plan::MaterialInput>],
) -> Result<Vec<Option<String>>, String> {
    let base = server.trim_end_matches('/');
    let mut doc: Value = serde_json::from_str(text).map_err(|e| e.to_string())?;
    for (k, m) in materials.iter().enumerate() {
        if let Some(m) = m {
            doc["spheres"][k]["material"] = m.json.clone();
        }
    }
    doc["max_bounces"] = json!(desc.max_bounces);
    if let Some(w) = &desc.wavelengths_nm {
        doc["wavelengths_nm"] = json!(w);
    }
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .timeout_global(Some(std::time::Duration::from_secs(60)))
        .http_status_as_error(false)
        .build()
        .into();
    let at = |e: String| format!("--server {base}: {e}");
    let call =
        |r: Result<ureq::http::Response<ureq::Body>, ureq::Error>| -> Result<(u16, Value), String> {
            let mut r = r.map_err(|e| at(e.to_string()))?;
            let code = r.status().as_u16();
            let body = r
                .body_mut()
                .read_to_string()
                .map_err(|e| at(e.to_string()))?;
            Ok((
                code,
                serde_json::from_str(&body).unwrap_or(Value::String(body)),
            ))
        };
    let (code, v) = call(
        agent
            .post(&format!("{base}/v1/scenes"))
            .header("content-type", "application/json")
            .send(doc.to_string()),
    )?;
    if code != 200 && code != 202 {
        return Err(at(format!("POST /v1/scenes: HTTP {code}: {v}")));
    }
    let entries = v["materials"].as_array().cloned().unwrap_or_default();
    let started = Instant::now();
    for e in &entries {
        let id = e["id"]
            .as_str()
            .ok_or_else(|| at(format!("no id in {e}")))?;
        loop {
            let (code, r) = call(agent.get(&format!("{base}/v1/brdfs/{id}")).call())?;
            match r["status"].as_str() {
                Some("done") => break,
                Some("failed") => {
                    return Err(at(format!("{}: the job failed: {}", e["name"], r["error"])));
                }
                _ if code != 200 => {
                    return Err(at(format!("GET /v1/brdfs/{id}: HTTP {code}: {r}")));
                }
                _ if started.elapsed().as_secs() > 3600 => {
                    return Err(at(format!("{id}: not done after an hour")));
                }
                _ => std::thread::sleep(std::time::Duration::from_millis(200)),
            }
        }
    }
    let mut ids = entries.iter().map(|e| e["id"].as_str().unwrap_or_default());
    Ok(materials
        .iter()
        .map(|m| {
            m.as_ref()
                .and_then(|_| ids.next())
                .map(|id| format!("{base}/v1/brdfs/{id}"))
        })
        .collect())
}

/// Run `render`.
pub fn run(a: &RenderArgs) -> Result<Value, String> {
    let t0 = Instant::now();
    let text = std::fs::read_to_string(&a.scene).map_err(|e| format!("{}: {e}", a.scene))?;
    let mut desc = scene::parse(&text).map_err(|e| format!("{}: {e}", a.scene))?;
    Overrides {
        width: a.width,
        height: a.height,
        samples_per_pixel: a.spp,
        seed: a.seed,
        max_bounces: a.max_bounces,
        polarizer_deg: a.polarizer_deg,
        wavelengths_nm: a.wavelength_nm.clone(),
    }
    .apply(&mut desc)
    .map_err(|e| format!("{} (with the command-line overrides): {e}", a.scene))?;
    if !(a.dop_max.is_finite() && a.dop_max > 0.0) {
        return Err(format!("--dop-max {} must be > 0", a.dop_max));
    }
    if let Some(e) = a.exposure
        && !(e.is_finite() && e > 0.0)
    {
        return Err(format!("--exposure {e} must be > 0"));
    }
    let scene_dir = scene_dir(&a.scene);
    let cache = a.cache.resolve()?;

    // Tables: each distinct source once; material specs solved locally
    // for what the scene needs (`render::scene_plan`), each distinct
    // reduced spec once.
    let materials = load_materials(&desc, &scene_dir).map_err(|e| format!("{}: {e}", a.scene))?;
    if let Some(server) = &a.server
        && materials.iter().any(Option::is_some)
    {
        let urls = solve_on_server(server, &text, &desc, &materials)?;
        for (s, url) in desc.spheres.iter_mut().zip(urls) {
            if let Some(u) = url {
                s.material = None;
                s.table = Some(u);
            }
        }
    }
    let materials = load_materials(&desc, &scene_dir).map_err(|e| format!("{}: {e}", a.scene))?;
    let plan = if materials.iter().any(Option::is_some) {
        let p = plan_loaded(&desc, &materials, &scene_dir, cache.as_ref())
            .map_err(|e| format!("{}: {e}", a.scene))?;
        if p.wavelengths_nm.iter().all(Option::is_some) {
            desc.wavelengths_nm = Some(p.wavelengths_nm.iter().flatten().copied().collect());
        }
        Some(p)
    } else {
        None
    };
    let t_solve = Instant::now();
    let mut loaded: Vec<(String, Arc<Table>)> = Vec::new();
    let mut tables = Vec::new();
    let mut solved = Vec::new();
    for (k, s) in desc.spheres.iter().enumerate() {
        let (key, what) = match (s.source(), &plan) {
            (scene::SurfaceSource::Table(t), _) => (resolve(&scene_dir, t), None),
            (scene::SurfaceSource::Material(_), Some(p)) => {
                let reduced = p.materials[k].spec.as_ref().expect("a material entry");
                let spec = reduced.to_string();
                (format!("spec:{spec}"), Some(spec))
            }
            (scene::SurfaceSource::Material(_), None) => unreachable!("planned"),
        };
        let t = match loaded.iter().find(|(p, _)| *p == key) {
            Some((_, t)) => t.clone(),
            None => {
                let t = Arc::new(match &what {
                    None => load_table_with(&key, cache.as_ref())
                        .map_err(|e| format!("spheres[{k}].table: {e}"))?,
                    Some(spec) => {
                        let (t, info) = solve_material(k, spec)?;
                        solved.push(json!({"name": scene::sphere_name(&desc, k), "id": t.metadata.spec_hash, "wavelengths": info}));
                        t
                    }
                });
                loaded.push((key, t.clone()));
                t
            }
        };
        tables.push(t);
    }
    let solve_s = t_solve.elapsed().as_secs_f64();
    let env = match &desc.environment {
        Some(scene::EnvironmentDesc::Equirectangular { path, .. }) => {
            let p = resolve(&scene_dir, path);
            let bytes = std::fs::read(&p)
                .map_err(|e| format!("environment.equirectangular.path: {p}: {e}"))?;
            let img = if p.ends_with(".npy") {
                output::decode_npy(&bytes)
            } else {
                output::decode_png(&bytes)
            }
            .map_err(|e| format!("environment.equirectangular.path: {p}: {e}"))?;
            Some(img)
        }
        _ => None,
    };
    let scene =
        render::build(&desc, &tables, env.as_ref()).map_err(|e| format!("{}: {e}", a.scene))?;
    let load_s = t0.elapsed().as_secs_f64();

    // Render, with a progress bar on a terminal.
    let show = !a.no_progress && std::io::stderr().is_terminal();
    let last = AtomicUsize::new(usize::MAX);
    let progress = |done: usize, rows: usize| {
        if !show {
            return;
        }
        let pct = 100 * done / rows;
        if last.swap(pct, Ordering::Relaxed) != pct {
            let bar = 40 * done / rows;
            let mut e = std::io::stderr().lock();
            let _ = write!(
                e,
                "\rrender [{}{}] {pct:3}%",
                "#".repeat(bar),
                " ".repeat(40 - bar)
            );
            let _ = e.flush();
        }
    };
    let t1 = Instant::now();
    let img = scene.render(&progress);
    let render_s = t1.elapsed().as_secs_f64();
    if show {
        eprintln!();
    }

    // Outputs.
    let t2 = Instant::now();
    let exposure = a.exposure.unwrap_or_else(|| output::auto_exposure(&img));
    let (w, h) = (img.width, img.height);
    let mut files = serde_json::Map::new();
    let mut put = |key: &str, suffix: &str, bytes: Vec<u8>| -> Result<(), String> {
        let path = format!("{}_{suffix}", a.out);
        write(&path, &bytes)?;
        files.insert(key.into(), json!(path));
        Ok(())
    };
    put(
        "intensity",
        "intensity.png",
        output::png_rgb8(w, h, &output::intensity_rgb8(&img, exposure))?,
    )?;
    put(
        "dop",
        "dop.png",
        output::png_rgb8(w, h, &output::dop_rgb8(&img, a.dop_max))?,
    )?;
    if a.stokes_png {
        for k in 1..=3 {
            put(
                &format!("s{k}"),
                &format!("s{k}.png"),
                output::png_rgb8(w, h, &output::component_rgb8(&img, k, 1.0))?,
            )?;
        }
    }
    put("stokes", "stokes.npy", output::stokes_npy(&img)?)?;
    let write_s = t2.elapsed().as_secs_f64();

    let wavelengths: Vec<Value> = render::channel_wavelengths(&desc, &tables)
        .into_iter()
        .map(|w| json!(w))
        .collect();
    Ok(json!({
        "scene": a.scene,
        "width": w,
        "height": h,
        "pixels": w * h,
        "samples_per_pixel": scene.samples_per_pixel,
        "max_bounces": scene.max_bounces,
        "seed": scene.seed,
        "polarizer_deg": desc.camera.polarizer_deg,
        "wavelengths_nm": wavelengths,
        "threads": rayon::current_num_threads(),
        "exposure": exposure,
        "dop_max": a.dop_max,
        "solved": solved,
        "time_s": {"solve": solve_s, "load": load_s, "render": render_s, "write": write_s, "total": t0.elapsed().as_secs_f64()},
        "objects": render::object_statistics(&scene, &img),
        "files": files,
    }))
}
