//! The scene file of `polbrdf render` (docs/render.md): parsing and
//! validation only. Loading the tables and images it names is the caller's
//! business (`cli::render`), so this module stays free of I/O.
//!
//! World frame: right-handed, `+z` up (the floor is a horizontal plane);
//! lengths in arbitrary scene units; angles in degrees.

use serde::Deserialize;

/// A whole scene (docs/render.md, "Scene file").
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    /// The pinhole camera.
    pub camera: CameraDesc,
    /// Directional and point lights.
    #[serde(default)]
    pub lights: Vec<LightDesc>,
    /// Light from infinitely far away in all directions; none: black.
    #[serde(default)]
    pub environment: Option<EnvironmentDesc>,
    /// Spheres, each with its BRDF table.
    #[serde(default)]
    pub spheres: Vec<SphereDesc>,
    /// The horizontal depolarizing floor; none: no floor.
    #[serde(default)]
    pub floor: Option<FloorDesc>,
    /// Further depolarizing planes (walls).
    #[serde(default)]
    pub walls: Vec<WallDesc>,
    /// Paths per pixel.
    #[serde(default = "default_spp")]
    pub samples_per_pixel: u32,
    /// Seed of the per-pixel random streams.
    #[serde(default)]
    pub seed: u64,
    /// Indirect bounces after the camera ray's first hit (0: direct light only).
    #[serde(default = "default_bounces")]
    pub max_bounces: u32,
    /// Channel wavelengths (1 or 3, nm); none: see docs/render.md.
    #[serde(default)]
    pub wavelengths_nm: Option<Vec<f64>>,
    /// The `solver.tolerance` the scene needs of its material spheres
    /// (max error of f11 relative to max f11); none: each spec's own
    /// solver settings (docs/render.md, "Materials and `scene plan`").
    #[serde(default)]
    pub tolerance: Option<f64>,
}

fn default_spp() -> u32 {
    16
}

fn default_bounces() -> u32 {
    1
}

/// Pinhole camera.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// Eye point.
    pub position: [f64; 3],
    /// A point the optical axis goes through.
    pub look_at: [f64; 3],
    /// Up reference (the image's up is its part perpendicular to the axis).
    #[serde(default = "default_up")]
    pub up: [f64; 3],
    /// Vertical field of view (degrees).
    pub fov_deg: f64,
    /// Image width (pixels).
    pub width: u32,
    /// Image height (pixels).
    pub height: u32,
    /// Transmission axis of an ideal linear polarizer in front of the lens,
    /// degrees from the image's right towards its up; none: no polarizer.
    #[serde(default)]
    pub polarizer_deg: Option<f64>,
}

fn default_up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// A light source; `stokes` is in the frame whose x-axis is `frame_up`
/// projected perpendicular to the propagation direction (docs/render.md).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
pub enum LightDesc {
    /// Parallel light from direction `toward` (pointing from the scene to
    /// the light); `stokes` is the irradiance on a plane normal to the beam.
    Directional {
        /// Direction towards the light.
        toward: [f64; 3],
        /// `[I, Q, U, V]` irradiance normal to the beam.
        stokes: [f64; 4],
        /// Stokes frame reference (default `+z`).
        #[serde(default = "default_up")]
        frame_up: [f64; 3],
    },
    /// Isotropic point light; `stokes` is the radiant intensity (per sr),
    /// the irradiance normal to the beam at distance `r` is `stokes / r²`.
    Point {
        /// Position.
        position: [f64; 3],
        /// `[I, Q, U, V]` radiant intensity.
        stokes: [f64; 4],
        /// Stokes frame reference (default `+z`).
        #[serde(default = "default_up")]
        frame_up: [f64; 3],
    },
}

/// Light from infinitely far away.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
pub enum EnvironmentDesc {
    /// The same radiance from every direction: `radiance` (unpolarized) or
    /// `stokes` (in the frame with x-axis `+z` projected perpendicular to
    /// the propagation direction).
    Uniform {
        /// Unpolarized radiance.
        #[serde(default)]
        radiance: Option<f64>,
        /// Polarized radiance `[I, Q, U, V]`.
        #[serde(default)]
        stokes: Option<[f64; 4]>,
    },
    /// An unpolarized latitude–longitude map: column `u` ↔ azimuth
    /// `atan2(y, x)` from `−180°` (left edge) to `180°`, row `v` ↔ polar angle
    /// from `+z` (top row) to `−z`.
    Equirectangular {
        /// PNG (8/16 bit, sRGB-decoded) or `.npy` float image (`H×W` or
        /// `H×W×3`, linear); relative to the scene file.
        path: String,
        /// Radiance of a pixel value 1.
        #[serde(default = "one")]
        scale: f64,
        /// Turn the map about `+z` (degrees).
        #[serde(default)]
        rotation_deg: f64,
    },
}

fn one() -> f64 {
    1.0
}

/// A sphere with a BRDF table or a material spec (exactly one).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereDesc {
    /// Centre.
    pub center: [f64; 3],
    /// Radius (> 0).
    pub radius: f64,
    /// Name in the plan and the summary; none: `spheres[k]`.
    #[serde(default)]
    pub name: Option<String>,
    /// Table file (relative to the scene file) or service URL
    /// `http://HOST:PORT/v1/brdfs/ID`.
    #[serde(default)]
    pub table: Option<String>,
    /// A material spec (docs/spec.md): inline, or the path of a spec file
    /// relative to the scene file. Solved for what the scene needs
    /// (`render::scene_plan`).
    #[serde(default)]
    pub material: Option<MaterialDesc>,
}

/// Where a sphere's material spec is.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum MaterialDesc {
    /// A spec file, relative to the scene file.
    Path(String),
    /// The spec itself (validated by `material::parse` when loaded).
    Inline(serde_json::Map<String, serde_json::Value>),
}

/// What a sphere's BRDF comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SurfaceSource<'a> {
    /// A table file or service URL.
    Table(&'a str),
    /// A material spec.
    Material(&'a MaterialDesc),
}

impl SphereDesc {
    /// The table or the material (validated: exactly one is given).
    pub fn source(&self) -> SurfaceSource<'_> {
        match (&self.table, &self.material) {
            (Some(t), _) => SurfaceSource::Table(t),
            (None, Some(m)) => SurfaceSource::Material(m),
            (None, None) => SurfaceSource::Table(""),
        }
    }
}

/// The name of sphere `k` in plans and summaries: its `name`, else
/// `spheres[k]`.
pub fn sphere_name(desc: &SceneDesc, k: usize) -> String {
    desc.spheres[k]
        .name
        .clone()
        .unwrap_or_else(|| format!("spheres[{k}]"))
}

/// Albedo: one value for all channels or one per channel.
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum Albedo {
    /// All channels.
    One(f64),
    /// Per channel (as many as the image has).
    PerChannel(Vec<f64>),
}

/// The floor: the plane `z = height`, depolarizing Lambertian.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FloorDesc {
    /// Height of the plane.
    #[serde(default)]
    pub height: f64,
    /// Lambertian albedo in `[0, 1]`.
    pub albedo: Albedo,
}

/// A depolarizing Lambertian plane through `point` facing `normal`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallDesc {
    /// A point of the plane.
    pub point: [f64; 3],
    /// The lit side's normal.
    pub normal: [f64; 3],
    /// Lambertian albedo in `[0, 1]`.
    pub albedo: Albedo,
}

/// Largest image side (pixels).
pub const MAX_SIDE: u32 = 16384;
/// Largest number of samples per pixel.
pub const MAX_SPP: u32 = 1 << 16;
/// Largest number of indirect bounces.
pub const MAX_BOUNCES: u32 = 16;

/// Smallest and largest scene `tolerance` (those of `solver.tolerance`,
/// docs/spec.md).
pub const MIN_TOLERANCE: f64 = 1e-10;
/// See [`MIN_TOLERANCE`].
pub const MAX_TOLERANCE: f64 = 0.5;

/// Exactly one of `table` and `material`, neither empty.
fn sphere_source(k: usize, sp: &SphereDesc) -> Result<(), String> {
    match (&sp.table, &sp.material) {
        (Some(_), Some(_)) | (None, None) => Err(format!(
            "spheres[{k}]: give exactly one of `table` (a table file or service URL) and \
             `material` (a spec, or the path of a spec file)"
        )),
        (Some(t), None) if t.is_empty() => Err(format!("spheres[{k}].table: empty")),
        (None, Some(MaterialDesc::Path(p))) if p.is_empty() => {
            Err(format!("spheres[{k}].material: empty"))
        }
        _ => Ok(()),
    }
}

/// Parse and validate a scene; errors name the JSON path
/// (`lights[0].directional.stokes: …`).
pub fn parse(text: &str) -> Result<SceneDesc, String> {
    let scene: SceneDesc = crate::material::from_json_str(text).map_err(|e| e.to_string())?;
    validate(&scene)?;
    Ok(scene)
}

fn finite3(path: &str, v: [f64; 3]) -> Result<(), String> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(format!("{path}: {v:?} is not finite"))
    }
}

fn nonzero3(path: &str, v: [f64; 3]) -> Result<(), String> {
    finite3(path, v)?;
    if v.iter().all(|&x| x == 0.0) {
        return Err(format!("{path}: the zero vector is not a direction"));
    }
    Ok(())
}

fn in_range(path: &str, v: f64, lo: f64, hi: f64) -> Result<(), String> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(format!(
            "{path}: {v} is outside the allowed range [{lo}, {hi}]"
        ))
    }
}

fn stokes(path: &str, s: [f64; 4]) -> Result<(), String> {
    super::polarization::check_stokes(s).map_err(|e| format!("{path}: {e}"))
}

fn albedo(path: &str, a: &Albedo) -> Result<(), String> {
    let values: Vec<f64> = match a {
        Albedo::One(x) => vec![*x],
        Albedo::PerChannel(v) => {
            if v.is_empty() || v.len() > super::material::MAX_CHANNELS {
                return Err(format!("{path}: give 1 to 3 values, got {}", v.len()));
            }
            v.clone()
        }
    };
    for (k, x) in values.iter().enumerate() {
        in_range(&format!("{path}[{k}]"), *x, 0.0, 1.0)?;
    }
    Ok(())
}

/// Ranges and consistency not expressed by the types.
pub fn validate(s: &SceneDesc) -> Result<(), String> {
    let c = &s.camera;
    finite3("camera.position", c.position)?;
    finite3("camera.look_at", c.look_at)?;
    nonzero3("camera.up", c.up)?;
    let axis = super::geometry::sub(c.look_at, c.position);
    nonzero3("camera.look_at - camera.position", axis)?;
    if super::geometry::length(super::geometry::cross(
        super::geometry::normalize(axis),
        super::geometry::normalize(c.up),
    )) < 1e-6
    {
        return Err("camera.up: parallel to the viewing direction".into());
    }
    in_range("camera.fov_deg", c.fov_deg, 1e-3, 179.0)?;
    in_range("camera.width", c.width.into(), 1.0, MAX_SIDE.into())?;
    in_range("camera.height", c.height.into(), 1.0, MAX_SIDE.into())?;
    if let Some(a) = c.polarizer_deg {
        in_range("camera.polarizer_deg", a, -360.0, 360.0)?;
    }
    for (k, l) in s.lights.iter().enumerate() {
        match l {
            LightDesc::Directional {
                toward,
                stokes: st,
                frame_up,
            } => {
                nonzero3(&format!("lights[{k}].directional.toward"), *toward)?;
                stokes(&format!("lights[{k}].directional.stokes"), *st)?;
                nonzero3(&format!("lights[{k}].directional.frame_up"), *frame_up)?;
            }
            LightDesc::Point {
                position,
                stokes: st,
                frame_up,
            } => {
                finite3(&format!("lights[{k}].point.position"), *position)?;
                stokes(&format!("lights[{k}].point.stokes"), *st)?;
                nonzero3(&format!("lights[{k}].point.frame_up"), *frame_up)?;
            }
        }
    }
    match &s.environment {
        Some(EnvironmentDesc::Uniform {
            radiance,
            stokes: st,
        }) => match (radiance, st) {
            (Some(r), None) => in_range("environment.uniform.radiance", *r, 0.0, 1e30)?,
            (None, Some(v)) => stokes("environment.uniform.stokes", *v)?,
            _ => {
                return Err(
                    "environment.uniform: give exactly one of `radiance` (unpolarized) and `stokes`".into(),
                );
            }
        },
        Some(EnvironmentDesc::Equirectangular {
            path,
            scale,
            rotation_deg,
        }) => {
            if path.is_empty() {
                return Err("environment.equirectangular.path: empty".into());
            }
            in_range("environment.equirectangular.scale", *scale, 0.0, 1e30)?;
            in_range(
                "environment.equirectangular.rotation_deg",
                *rotation_deg,
                -360.0,
                360.0,
            )?;
        }
        None => {}
    }
    for (k, sp) in s.spheres.iter().enumerate() {
        finite3(&format!("spheres[{k}].center"), sp.center)?;
        in_range(&format!("spheres[{k}].radius"), sp.radius, 1e-9, 1e9)?;
        sphere_source(k, sp)?;
        if let Some(name) = &sp.name {
            if name.is_empty() {
                return Err(format!("spheres[{k}].name: empty"));
            }
            if let Some(j) = s.spheres[..k]
                .iter()
                .position(|o| o.name.as_ref() == Some(name))
            {
                return Err(format!(
                    "spheres[{k}].name: {name:?} already names spheres[{j}]"
                ));
            }
        }
    }
    if let Some(f) = &s.floor {
        in_range("floor.height", f.height, -1e9, 1e9)?;
        albedo("floor.albedo", &f.albedo)?;
    }
    for (k, w) in s.walls.iter().enumerate() {
        finite3(&format!("walls[{k}].point"), w.point)?;
        nonzero3(&format!("walls[{k}].normal"), w.normal)?;
        albedo(&format!("walls[{k}].albedo"), &w.albedo)?;
    }
    in_range(
        "samples_per_pixel",
        s.samples_per_pixel.into(),
        1.0,
        MAX_SPP.into(),
    )?;
    in_range("max_bounces", s.max_bounces.into(), 0.0, MAX_BOUNCES.into())?;
    if let Some(t) = s.tolerance {
        in_range("tolerance", t, MIN_TOLERANCE, MAX_TOLERANCE)?;
    }
    if let Some(w) = &s.wavelengths_nm {
        if w.len() != 1 && w.len() != 3 {
            return Err(format!(
                "wavelengths_nm: give 1 or 3 wavelengths, got {}",
                w.len()
            ));
        }
        for (k, x) in w.iter().enumerate() {
            in_range(&format!("wavelengths_nm[{k}]"), *x, 100.0, 1e5)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = r#"{"camera": {"position": [0, -5, 1], "look_at": [0, 0, 1],
        "fov_deg": 40, "width": 8, "height": 6}}"#;

    #[test]
    fn minimal_scene_has_defaults() {
        let s = parse(MINIMAL).unwrap();
        assert_eq!(s.samples_per_pixel, 16);
        assert_eq!(s.max_bounces, 1);
        assert_eq!(s.camera.up, [0.0, 0.0, 1.0]);
        assert!(s.lights.is_empty() && s.spheres.is_empty() && s.floor.is_none());
    }

    /// Errors name the JSON path and the rule.
    #[test]
    fn errors_name_the_path() {
        let e = parse(r#"{"camera": {"position": [0, 0, 0]}}"#).unwrap_err();
        assert!(e.contains("camera") && e.contains("look_at"), "{e}");
        let bad = MINIMAL.replace("\"fov_deg\": 40", "\"fov_deg\": 400");
        let e = parse(&bad).unwrap_err();
        assert!(e.starts_with("camera.fov_deg: 400"), "{e}");
        let bad = MINIMAL.replace(
            "}}",
            r#"}, "lights": [{"directional": {"toward": [0, 0, 1], "stokes": [1, 1, 1, 0]}}]}"#,
        );
        let e = parse(&bad).unwrap_err();
        assert!(e.starts_with("lights[0].directional.stokes"), "{e}");
        let bad = MINIMAL.replace("}}", r#"}, "lamps": []}"#);
        let e = parse(&bad).unwrap_err();
        assert!(e.contains("lamps"), "{e}");
        let bad = MINIMAL.replace("}}", r#"}, "environment": {"uniform": {}}}"#);
        assert!(parse(&bad).unwrap_err().contains("exactly one"));
        let bad = MINIMAL.replace("}}", r#"}, "floor": {"albedo": [0.5, 1.5]}}"#);
        assert!(parse(&bad).unwrap_err().starts_with("floor.albedo[1]"));
    }
}
