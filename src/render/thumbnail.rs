//! Thumbnails of a result (`GET /v1/brdfs/{id}/thumbnail`, the console's
//! cache page): one sphere with the table, lit by a polarization-free
//! directional light from the upper left and a dim uniform sky, seen by the
//! preview renderer ([`super::build`], [`super::integrator`]); the intensity
//! and the degree of polarization (seed eq. 1) of the same render.
//!
//! Deterministic: the same table gives the same bytes (fixed seed), so a
//! thumbnail is cached once per result and [`THUMBNAIL_VERSION`].

use super::output::{auto_exposure, dop_rgb8, intensity_rgb8, png_rgb8};
use super::scene;
use crate::brdf::Table;
use std::sync::Arc;

/// Bumped whenever the scene or the encoding below changes: part of the
/// cache key of stored thumbnails, so older ones are never served.
pub const THUMBNAIL_VERSION: u32 = 1;

/// Width and height of a thumbnail (pixels).
pub const THUMBNAIL_PX: u32 = 96;

/// The degree of polarization shown as full red.
pub const THUMBNAIL_DOP_MAX: f64 = 1.0;

/// The thumbnail scene with one sphere of `table`: camera on `−y`, light
/// from the upper left, no floor, direct light only.
fn scene_json(px: u32) -> String {
    format!(
        r#"{{
  "camera": {{ "position": [0, -6, 0.6], "look_at": [0, 0, 0], "up": [0, 0, 1],
              "fov_deg": 22, "width": {px}, "height": {px} }},
  "lights": [ {{ "directional": {{ "toward": [-0.45, -0.55, 0.7], "stokes": [3.0, 0, 0, 0] }} }} ],
  "environment": {{ "uniform": {{ "radiance": 0.08 }} }},
  "spheres": [ {{ "center": [0, 0, 0], "radius": 1, "table": "result" }} ],
  "samples_per_pixel": 4,
  "seed": 7,
  "max_bounces": 0
}}"#
    )
}

/// Intensity and DOP thumbnails (PNG bytes, `px × px`) of a table.
pub fn thumbnails(table: Arc<Table>, px: u32) -> Result<(Vec<u8>, Vec<u8>), String> {
    let desc = scene::parse(&scene_json(px))?;
    let scene = super::build(&desc, &[table], None)?;
    let img = scene.render(&|_, _| {});
    let (w, h) = (img.width, img.height);
    let intensity = png_rgb8(w, h, &intensity_rgb8(&img, auto_exposure(&img)))?;
    let dop = png_rgb8(w, h, &dop_rgb8(&img, THUMBNAIL_DOP_MAX))?;
    Ok((intensity, dop))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scene_parses_and_validates() {
        let desc = scene::parse(&scene_json(THUMBNAIL_PX)).unwrap();
        assert_eq!(desc.spheres.len(), 1);
        assert_eq!(desc.camera.width, THUMBNAIL_PX);
        assert_eq!(desc.max_bounces, 0);
    }
}
