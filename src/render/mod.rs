//! A small CPU polarized preview renderer (`polbrdf render ...`, issue 7):
//! spheres with BRDF tables on a depolarizing floor, lit by directional and
//! point lights of any Stokes vector and an environment, seen by a pinhole
//! camera with an optional linear polarizer. Each path carries a Stokes
//! vector with its reference frame; BRDFs come out of the tables in the
//! meridian frames of conventions §5 and are rotated into the frames of the
//! incoming light and of the outgoing ray (Mueller calculus, seed §2.1).
//! docs/render.md has the scene format, the frames and the outputs.
//!
//! * [`scene`]: the scene file (parse + validate, no I/O).
//! * [`scene_plan`]: what a scene needs of its material specs (`scene plan`).
//! * [`integrator`]: the scene at render time and the path tracer.
//! * [`material`]: table BRDFs at the image's wavelengths (the hot path).
//! * [`polarization`]: Stokes frames along rays, rotations, the polarizer.
//! * [`geometry`], [`sampling`]: vectors, intersections, RNG.
//! * [`output`]: PNG / npy encoding, tone mapping, DOP colouring.

pub mod geometry;
pub mod integrator;
pub mod material;
pub mod output;
pub mod polarization;
pub mod sampling;
pub mod scene;
pub mod scene_plan;
pub mod thumbnail;

use crate::brdf::Table;
use crate::physics::stokes::degree_of_polarization;
use integrator::{Camera, EnvMap, Environment, Light, Object, Plane, Scene, Sphere, StokesImage};
use material::{MAX_CHANNELS, TableBrdf};
use output::LinearImage;
use scene::{Albedo, EnvironmentDesc, LightDesc, SceneDesc};
use serde_json::{Value, json};
use std::sync::Arc;

/// Settings that the command line may override.
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    /// Image width.
    pub width: Option<u32>,
    /// Image height.
    pub height: Option<u32>,
    /// Samples per pixel.
    pub samples_per_pixel: Option<u32>,
    /// Seed.
    pub seed: Option<u64>,
    /// Indirect bounces.
    pub max_bounces: Option<u32>,
    /// Polarizer angle (degrees).
    pub polarizer_deg: Option<f64>,
    /// Channel wavelengths (1 or 3).
    pub wavelengths_nm: Option<Vec<f64>>,
}

impl Overrides {
    /// Apply to a scene description and re-validate it.
    pub fn apply(&self, desc: &mut SceneDesc) -> Result<(), String> {
        if let Some(w) = self.width {
            desc.camera.width = w;
        }
        if let Some(h) = self.height {
            desc.camera.height = h;
        }
        if let Some(s) = self.samples_per_pixel {
            desc.samples_per_pixel = s;
        }
        if let Some(s) = self.seed {
            desc.seed = s;
        }
        if let Some(b) = self.max_bounces {
            desc.max_bounces = b;
        }
        if let Some(a) = self.polarizer_deg {
            desc.camera.polarizer_deg = Some(a);
        }
        if let Some(w) = &self.wavelengths_nm {
            desc.wavelengths_nm = Some(w.clone());
        }
        scene::validate(desc)
    }
}

/// The channel wavelengths (ascending): the scene's (or the command
/// line's) if given; else, with no spheres, one wavelength-free channel;
/// else from the first sphere's table: its three wavelengths if it has
/// exactly three (an RGB image), otherwise its first wavelength.
pub fn channel_wavelengths(desc: &SceneDesc, tables: &[Arc<Table>]) -> Vec<Option<f64>> {
    let first: Option<Vec<Option<f64>>> = tables
        .first()
        .map(|t| t.wavelengths.iter().map(|w| w.wavelength_nm).collect());
    channels_from(desc.wavelengths_nm.as_deref(), first.as_deref())
}

/// The rule of [`channel_wavelengths`] given the scene's `wavelengths_nm`
/// and the first sphere's wavelengths (its table's or its spec's; `None`:
/// no spheres).
pub fn channels_from(scene_nm: Option<&[f64]>, first: Option<&[Option<f64>]>) -> Vec<Option<f64>> {
    if let Some(w) = scene_nm {
        let mut w = w.to_vec();
        w.sort_by(f64::total_cmp);
        return w.into_iter().map(Some).collect();
    }
    let Some(wls) = first.filter(|w| !w.is_empty()) else {
        return vec![None];
    };
    if wls.len() == 3 && wls.iter().all(Option::is_some) {
        wls.to_vec()
    } else {
        vec![wls[0]]
    }
}

fn albedo_channels(a: &Albedo, channels: usize, path: &str) -> Result<[f64; MAX_CHANNELS], String> {
    let mut out = [0.0; MAX_CHANNELS];
    match a {
        Albedo::One(x) => out[..channels].fill(*x),
        Albedo::PerChannel(v) if v.len() == 1 => out[..channels].fill(v[0]),
        Albedo::PerChannel(v) if v.len() == channels => out[..channels].copy_from_slice(v),
        Albedo::PerChannel(v) => {
            return Err(format!(
                "{path}: {} values for an image of {channels} channel(s)",
                v.len()
            ));
        }
    }
    Ok(out)
}

/// The environment map in channel order: one channel takes the Rec. 709
/// luminance, three take (B, G, R) for ascending wavelengths.
pub fn env_map(img: &LinearImage, scale: f64, rotation_deg: f64, channels: usize) -> EnvMap {
    let l = output::LUMINANCE_RGB;
    let texels = img
        .rgb
        .iter()
        .map(|p| {
            let v = if channels == 3 {
                [p[2], p[1], p[0]]
            } else {
                [l[0] * p[0] + l[1] * p[1] + l[2] * p[2], 0.0, 0.0]
            };
            v.map(|x| x * scale)
        })
        .collect();
    EnvMap {
        width: img.width,
        height: img.height,
        texels,
        rotation_rad: rotation_deg.to_radians(),
    }
}

/// The scene at render time from its description, the loaded table of each
/// sphere (same order) and the decoded environment image (if the scene has
/// an equirectangular environment).
pub fn build(
    desc: &SceneDesc,
    tables: &[Arc<Table>],
    env: Option<&LinearImage>,
) -> Result<Scene, String> {
    if tables.len() != desc.spheres.len() {
        return Err(format!(
            "{} spheres but {} tables",
            desc.spheres.len(),
            tables.len()
        ));
    }
    let wavelengths = channel_wavelengths(desc, tables);
    let channels = wavelengths.len();
    let c = &desc.camera;
    let camera = Camera::new(
        c.position,
        c.look_at,
        c.up,
        c.fov_deg,
        c.width as usize,
        c.height as usize,
        c.polarizer_deg,
    );
    let lights = desc
        .lights
        .iter()
        .map(|l| match l {
            LightDesc::Directional {
                toward,
                stokes,
                frame_up,
            } => Light::directional(*toward, *stokes, *frame_up),
            LightDesc::Point {
                position,
                stokes,
                frame_up,
            } => Light::Point {
                position: *position,
                stokes: *stokes,
                frame_up: *frame_up,
            },
        })
        .collect();
    let environment = match &desc.environment {
        None => Environment::Black,
        Some(EnvironmentDesc::Uniform { radiance, stokes }) => {
            Environment::Uniform(stokes.unwrap_or([radiance.unwrap_or(0.0), 0.0, 0.0, 0.0]))
        }
        Some(EnvironmentDesc::Equirectangular {
            scale,
            rotation_deg,
            ..
        }) => {
            let img = env.ok_or("environment.equirectangular: the image was not loaded")?;
            Environment::Map(env_map(img, *scale, *rotation_deg, channels))
        }
    };
    // Spheres sharing a table share its evaluator.
    let mut brdfs: Vec<(*const Table, Arc<TableBrdf>)> = Vec::new();
    let mut spheres = Vec::new();
    for (k, (s, t)) in desc.spheres.iter().zip(tables).enumerate() {
        let brdf = match brdfs.iter().find(|(p, _)| *p == Arc::as_ptr(t)) {
            Some((_, b)) => b.clone(),
            None => {
                let b = Arc::new(
                    TableBrdf::new(t.clone(), &wavelengths)
                        .map_err(|e| format!("{}: {e}", source_path(k, s)))?,
                );
                brdfs.push((Arc::as_ptr(t), b.clone()));
                b
            }
        };
        spheres.push(Sphere {
            center: s.center,
            radius: s.radius,
            brdf,
        });
    }
    let mut planes = Vec::new();
    if let Some(f) = &desc.floor {
        planes.push(Plane {
            name: "floor".into(),
            point: [0.0, 0.0, f.height],
            normal: [0.0, 0.0, 1.0],
            albedo: albedo_channels(&f.albedo, channels, "floor.albedo")?,
        });
    }
    for (k, w) in desc.walls.iter().enumerate() {
        planes.push(Plane {
            name: format!("walls[{k}]"),
            point: w.point,
            normal: geometry::normalize(w.normal),
            albedo: albedo_channels(&w.albedo, channels, &format!("walls[{k}].albedo"))?,
        });
    }
    Ok(Scene {
        camera,
        lights,
        environment,
        spheres,
        planes,
        channels,
        samples_per_pixel: desc.samples_per_pixel as usize,
        seed: desc.seed,
        max_bounces: desc.max_bounces as usize,
    })
}

/// The JSON path (and table source) of sphere `k`'s BRDF, for errors.
fn source_path(k: usize, s: &scene::SphereDesc) -> String {
    match s.source() {
        scene::SurfaceSource::Table(t) => format!("spheres[{k}].table ({t})"),
        scene::SurfaceSource::Material(_) => format!("spheres[{k}].material"),
    }
}

/// Per object seen through pixel centres: pixel count, mean and max degree
/// of polarization and mean intensity of the visual Stokes vector
/// (`output::visual_stokes`), the DOP of its mean Stokes vector, the
/// number of pixels with DOP exactly 0 and, for several channels, per
/// channel (ascending wavelength) the mean DOP and the DOP of the mean
/// Stokes vector.
pub fn object_statistics(scene: &Scene, img: &StokesImage) -> Value {
    let mut rows = Vec::new();
    let mut objects: Vec<(String, Option<Object>)> = (0..scene.spheres.len())
        .map(|k| (format!("spheres[{k}]"), Some(Object::Sphere(k))))
        .collect();
    for (k, p) in scene.planes.iter().enumerate() {
        objects.push((p.name.clone(), Some(Object::Plane(k))));
    }
    objects.push(("background".into(), None));
    for (name, obj) in objects {
        let (mut n, mut zero, mut sum_dop, mut max_dop) = (0usize, 0usize, 0.0, 0.0f64);
        let mut sum = [0.0; 4];
        let mut per_channel = [[0.0; 4]; MAX_CHANNELS];
        let mut dop_per_channel = [0.0; MAX_CHANNELS];
        for y in 0..img.height {
            for x in 0..img.width {
                if img.objects[y * img.width + x] != obj {
                    continue;
                }
                let s = output::visual_stokes(img, x, y);
                let p = degree_of_polarization(s);
                n += 1;
                zero += usize::from(p == 0.0);
                sum_dop += p;
                max_dop = max_dop.max(p);
                for k in 0..4 {
                    sum[k] += s[k];
                }
                for (c, acc) in per_channel.iter_mut().enumerate().take(img.channels) {
                    let v = img.stokes(x, y, c);
                    dop_per_channel[c] += degree_of_polarization(v);
                    for k in 0..4 {
                        acc[k] += v[k];
                    }
                }
            }
        }
        if n == 0 {
            continue;
        }
        let mut row = json!({
            "object": name,
            "pixels": n,
            "mean_intensity": sum[0] / n as f64,
            "mean_dop": sum_dop / n as f64,
            "max_dop": max_dop,
            "dop_of_mean": degree_of_polarization(sum),
            "zero_dop_pixels": zero,
        });
        if img.channels > 1 {
            row["mean_dop_per_channel"] = json!(
                dop_per_channel[..img.channels]
                    .iter()
                    .map(|d| d / n as f64)
                    .collect::<Vec<_>>()
            );
            row["dop_of_mean_per_channel"] = json!(
                per_channel[..img.channels]
                    .iter()
                    .map(|s| degree_of_polarization(*s))
                    .collect::<Vec<_>>()
            );
        }
        rows.push(row);
    }
    Value::Array(rows)
}
