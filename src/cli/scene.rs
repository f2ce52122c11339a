//! `polbrdf scene plan SCENE.json`: what a render scene needs of each
//! sphere's material and what that saves (docs/render.md, "Materials and
//! `scene plan`"; the rules are `render::scene_plan`). Also the reading of
//! material specs named by a scene, shared with `polbrdf render`.

use super::source::{Cache, load_table_with};
use crate::material::{self, SpecError};
use crate::render::scene::{self, MaterialDesc, SceneDesc, SurfaceSource};
use crate::render::scene_plan::{self, MaterialInput, ScenePlan};
use clap::{Args, Subcommand};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// `polbrdf scene …`.
#[derive(Debug, Subcommand)]
pub enum SceneCommand {
    /// Print, per sphere, what the scene needs of its material (wavelengths,
    /// Stokes part, tolerance, each with why), the reduced spec and its
    /// model cost against the full request (JSON, docs/render.md).
    Plan(PlanArgs),
}

/// Arguments of `polbrdf scene plan`.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// The scene (JSON, docs/render.md).
    pub scene: String,
}

/// Run `scene …`.
pub fn run(cmd: &SceneCommand) -> Result<Value, String> {
    match cmd {
        SceneCommand::Plan(a) => plan(a),
    }
}

/// The directory relative paths of a scene file are relative to.
pub fn scene_dir(scene_path: &str) -> PathBuf {
    Path::new(scene_path)
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default()
}

/// A spec error inside `spheres[k].material` (an inline spec): the path
/// prefixed.
fn inline_error(k: usize, e: &SpecError) -> String {
    if e.path == "$" {
        format!("spheres[{k}].material: {}", e.message)
    } else {
        format!("spheres[{k}].material.{}: {}", e.path, e.message)
    }
}

/// Read and validate sphere `k`'s material spec.
pub fn load_material(k: usize, m: &MaterialDesc, dir: &Path) -> Result<MaterialInput, String> {
    let (source, text) = match m {
        MaterialDesc::Path(p) => {
            let path = if Path::new(p).is_absolute() {
                PathBuf::from(p)
            } else {
                dir.join(p)
            };
            let shown = path.to_string_lossy().into_owned();
            let text = std::fs::read_to_string(&path)
                .map_err(|e| format!("spheres[{k}].material: {shown}: {e}"))?;
            (shown, text)
        }
        MaterialDesc::Inline(obj) => ("inline".to_string(), Value::Object(obj.clone()).to_string()),
    };
    let spec = material::parse(&text).map_err(|e| match m {
        MaterialDesc::Path(_) => format!("spheres[{k}].material: {source}: {e}"),
        MaterialDesc::Inline(_) => inline_error(k, &e),
    })?;
    let json: Value = serde_json::from_str(&text).map_err(|e| format!("{source}: {e}"))?;
    Ok(MaterialInput { source, json, spec })
}

/// Every sphere's material spec (`None` for table spheres).
pub fn load_materials(desc: &SceneDesc, dir: &Path) -> Result<Vec<Option<MaterialInput>>, String> {
    desc.spheres
        .iter()
        .enumerate()
        .map(|(k, s)| match s.source() {
            SurfaceSource::Material(m) => load_material(k, m, dir).map(Some),
            SurfaceSource::Table(_) => Ok(None),
        })
        .collect()
}

/// Resolve a table source of the scene: URLs and absolute paths as they
/// are, other paths relative to the scene's directory.
pub fn resolve(dir: &Path, p: &str) -> String {
    if super::source::table_url(p).is_some() || Path::new(p).is_absolute() {
        p.to_string()
    } else {
        dir.join(p).to_string_lossy().into_owned()
    }
}

/// The plan of a scene whose materials are loaded. Without a scene
/// `wavelengths_nm` and with a table as the first sphere, that table
/// decides the channels: it is read, and must be when material spheres
/// depend on it (otherwise a table that cannot be read is reported as not
/// read). Service tables are read through `cache` when given.
pub fn plan_loaded(
    desc: &SceneDesc,
    materials: &[Option<MaterialInput>],
    dir: &Path,
    cache: Option<&Cache>,
) -> Result<ScenePlan, String> {
    let first_table: Option<Vec<Option<f64>>> = match desc.spheres.first().map(|s| s.source()) {
        Some(SurfaceSource::Table(t)) if desc.wavelengths_nm.is_none() => {
            match load_table_with(&resolve(dir, t), cache) {
                Ok(table) => Some(table.wavelengths.iter().map(|w| w.wavelength_nm).collect()),
                Err(e) if materials.iter().any(Option::is_some) => {
                    return Err(format!("spheres[0].table: {e}"));
                }
                Err(_) => None,
            }
        }
        _ => None,
    };
    scene_plan::plan_scene(desc, materials, first_table.as_deref())
}

/// The cost model, as printed with every plan.
fn cost_model() -> Value {
    json!({
        "relative_time": "wavelengths × stokes time factor × Σ model solve times of the stream policy's solves, reduced over full",
        "solve_time_ms": "whole table jobs of the seed's TiO2 layer (r = 0.2 µm, τ = 1, black; polbrdf bench table, docs/performance.md): 32.8, 60.2, 232.8, 1347 ms at 8, 16, 32, 64 streams, log-log interpolated and extrapolated",
        "tolerance_to_streams": "the first of 4, 6, 8, 12, 16, 24, 32, … whose measured estimate of that case on the probe of docs/accuracy.md (9.1e-4, 8.4e-5, 8.5e-5, 4.1e-6, 4.3e-7, 3.2e-8, 3.0e-9; N^-6 beyond) is within the tolerance and whose true error at half the streams is within 3× it",
        "solves": "fixed N with the error estimate: N/2, 3N/4, N; a tolerance: 2, 3, 4, 6, 8, …, N",
        "stokes_time_factor": {"full": 1, "unpolarized_in": scene_plan::stokes_time_factor(scene_plan::StokesNeed::UnpolarizedIn)},
        "stokes_table_factor": {"full": 1, "unpolarized_in": scene_plan::stokes_bytes_factor(scene_plan::StokesNeed::UnpolarizedIn)},
        "docs": "docs/render.md, \"Materials and scene plan\"",
    })
}

fn plan(a: &PlanArgs) -> Result<Value, String> {
    let text = std::fs::read_to_string(&a.scene).map_err(|e| format!("{}: {e}", a.scene))?;
    let desc = scene::parse(&text).map_err(|e| format!("{}: {e}", a.scene))?;
    let dir = scene_dir(&a.scene);
    let materials = load_materials(&desc, &dir).map_err(|e| format!("{}: {e}", a.scene))?;
    let plan =
        plan_loaded(&desc, &materials, &dir, None).map_err(|e| format!("{}: {e}", a.scene))?;
    let mut doc = serde_json::to_value(&plan).expect("JSON");
    doc["scene"] = json!(a.scene);
    doc["cost_model"] = cost_model();
    Ok(doc)
}
