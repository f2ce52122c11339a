//! `polbrdf render SCENE.json -o PREFIX`: the polarized preview renderer
//! (docs/render.md). Reads the scene, loads its tables (files relative to
//! the scene, or service URLs) and environment image, renders on the rayon
//! pool with a progress bar on a terminal's stderr, writes the images and
//! prints a JSON summary.

use super::source::load_table;
use crate::brdf::Table;
use crate::render::{self, Overrides, output, scene};
use clap::Args;
use serde_json::{Value, json};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
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
    #[arg(long, allow_hyphen_values = true)]
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
}

/// A path in the scene file: relative to the scene's directory.
fn resolve(scene_dir: &Path, p: &str) -> String {
    if super::source::table_url(p).is_some() || Path::new(p).is_absolute() {
        p.to_string()
    } else {
        scene_dir.join(p).to_string_lossy().into_owned()
    }
}

fn write(path: &str, bytes: &[u8]) -> Result<(), String> {
    std::fs::write(path, bytes).map_err(|e| format!("{path}: {e}"))
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
    let scene_dir: PathBuf = Path::new(&a.scene)
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();

    // Tables: each distinct source once.
    let mut loaded: Vec<(String, Arc<Table>)> = Vec::new();
    let mut tables = Vec::new();
    for (k, s) in desc.spheres.iter().enumerate() {
        let src = resolve(&scene_dir, &s.table);
        let t = match loaded.iter().find(|(p, _)| *p == src) {
            Some((_, t)) => t.clone(),
            None => {
                let t = Arc::new(load_table(&src).map_err(|e| format!("spheres[{k}].table: {e}"))?);
                loaded.push((src.clone(), t.clone()));
                t
            }
        };
        tables.push(t);
    }
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
        "time_s": {"load": load_s, "render": render_s, "write": write_s, "total": t0.elapsed().as_secs_f64()},
        "objects": render::object_statistics(&scene, &img),
        "files": files,
    }))
}
