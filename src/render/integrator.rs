//! The scene at render time and the polarized path tracer
//! (docs/render.md, "What is computed").
//!
//! **Radiance with a frame.** [`Scene::radiance`]`(o, d, x)` returns, per
//! channel, the Stokes radiance arriving at `o` from direction `d`, i.e.
//! travelling along `k = −d`, referred to the frame `(x, k × x, k)` chosen by
//! the caller (`x ⟂ d`). At a surface point with normal `n`:
//!
//! * **Table sphere.** The local shading frame has `z = n`; `ω_o = −d` and
//!   the light direction `ω_i` are expressed in it, the table gives the
//!   Mueller BRDF in the meridian frames of conventions §5
//!   (`TableBrdf::eval` = `Table::eval_vectors`), and `brdf::frames::
//!   rotate_to_frames` re-expresses it for the incoming light's own frame
//!   and the caller's outgoing frame `x`: `M' = L(σ_out) M L(−σ_in)` (F1).
//!   Then `L_o = M' E cos θ_i` for a light of Stokes irradiance `E` normal
//!   to its beam (conventions §6) and `L_o = π M' L_i` for a cosine-sampled
//!   incident radiance `L_i` (pdf `cos θ_i/π`). A mirror base adds its delta:
//!   `L_o = S' L_i(ω_mirror)` (conventions §6: `f_spec = S δ / cos θ_i`).
//! * **Floor and walls.** Depolarizing Lambertian, `f = (a/π) diag(1,0,0,0)`:
//!   only `I` of the incident light matters and the result `[I, 0, 0, 0]`
//!   is the same in every frame.
//! * **Escaping rays** see the environment (rotated from its own frame to
//!   `x` by (R1), docs/render.md).
//!
//! **Paths.** Camera ray, then at each hit: every light with a shadow ray
//! (next-event estimation) and, while fewer than `max_bounces` indirect
//! bounces were made, one cosine-weighted indirect ray (plus the mirror ray
//! of a mirror base). So `max_bounces = 1` is "direct light plus one
//! bounce"; lights are never hit by rays (they are deltas).

use super::geometry::{
    Basis, Vec3, cross, dot, hit_plane, hit_sphere, madd, neg, normalize, reject, sub,
};
use super::material::{MAX_CHANNELS, TableBrdf};
use super::polarization::{Stokes, frame_x_from, rotate_stokes};
use super::sampling::{SplitMix64, cosine_hemisphere};
use crate::brdf::frames::rotate_to_frames;
use crate::physics::stokes::{Mueller, apply};
use rayon::prelude::*;
use std::f64::consts::PI;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Per-channel Stokes radiance.
pub type Radiance = [Stokes; MAX_CHANNELS];

const ZERO: Radiance = [[0.0; 4]; MAX_CHANNELS];

/// World up: the reference of the environment's Stokes frame.
pub const WORLD_UP: Vec3 = [0.0, 0.0, 1.0];

/// Relative offset of secondary ray origins off the surface.
const OFFSET: f64 = 1e-7;

/// Pinhole camera with its Stokes frame (docs/render.md).
#[derive(Clone, Debug)]
pub struct Camera {
    /// Eye point.
    pub position: Vec3,
    /// Unit optical axis.
    pub forward: Vec3,
    /// Unit image right, `forward × up` normalised.
    pub right: Vec3,
    /// Unit image up, `right × forward`.
    pub up: Vec3,
    /// `tan(fov/2)` (vertical).
    pub tan_half: f64,
    /// Width (pixels).
    pub width: usize,
    /// Height (pixels).
    pub height: usize,
    /// Polarizer in front of the lens (in the camera's Stokes frame).
    pub polarizer: Option<Mueller>,
}

impl Camera {
    /// A camera at `position` looking at `look_at`.
    pub fn new(
        position: Vec3,
        look_at: Vec3,
        up: Vec3,
        fov_deg: f64,
        width: usize,
        height: usize,
        polarizer_deg: Option<f64>,
    ) -> Self {
        let forward = normalize(sub(look_at, position));
        let right = normalize(cross(forward, up));
        let up = cross(right, forward);
        Self {
            position,
            forward,
            right,
            up,
            tan_half: (0.5 * fov_deg).to_radians().tan(),
            width,
            height,
            polarizer: polarizer_deg.map(|a| super::polarization::linear_polarizer(a.to_radians())),
        }
    }

    /// The ray through image point `(px, py)` (pixels, `(0, 0)` the top-left
    /// corner) and the x-axis of the camera's Stokes frame for the light
    /// arriving along it: the image right projected perpendicular to the
    /// ray; `y = k × x` is then the image up projected (exactly so on the
    /// optical axis).
    pub fn ray(&self, px: f64, py: f64) -> (Vec3, Vec3) {
        let aspect = self.width as f64 / self.height as f64;
        let sx = (2.0 * px / self.width as f64 - 1.0) * self.tan_half * aspect;
        let sy = (1.0 - 2.0 * py / self.height as f64) * self.tan_half;
        let d = normalize(madd(madd(self.forward, self.right, sx), self.up, sy));
        (d, self.frame_x(d))
    }

    /// Stokes x-axis for light arriving along `−d`: the image right
    /// projected perpendicular to `d`.
    pub fn frame_x(&self, d: Vec3) -> Vec3 {
        normalize(reject(self.right, d))
    }
}

/// A light source (docs/render.md).
#[derive(Clone, Debug)]
pub enum Light {
    /// Parallel light; `stokes` is the irradiance normal to the beam.
    Directional {
        /// Unit direction towards the light.
        toward: Vec3,
        /// `[I, Q, U, V]`.
        stokes: Stokes,
        /// Stokes x-axis of the beam.
        frame_x: Vec3,
    },
    /// Point light; `stokes` is the radiant intensity (per sr).
    Point {
        /// Position.
        position: Vec3,
        /// `[I, Q, U, V]`.
        stokes: Stokes,
        /// Stokes frame reference vector.
        frame_up: Vec3,
    },
}

impl Light {
    /// A directional light: unit `toward`, frame x-axis from `frame_up`.
    pub fn directional(toward: Vec3, stokes: Stokes, frame_up: Vec3) -> Self {
        let toward = normalize(toward);
        Light::Directional {
            toward,
            stokes,
            frame_x: frame_x_from(neg(toward), frame_up),
        }
    }

    /// From a shading point `p`: unit direction towards the light, its
    /// distance, the Stokes irradiance normal to the beam at `p` and the
    /// x-axis of its frame (perpendicular to the beam).
    fn sample(&self, p: Vec3) -> (Vec3, f64, Stokes, Vec3) {
        match self {
            Light::Directional {
                toward,
                stokes,
                frame_x,
            } => (*toward, f64::INFINITY, *stokes, *frame_x),
            Light::Point {
                position,
                stokes,
                frame_up,
            } => {
                let v = sub(*position, p);
                let r2 = dot(v, v);
                let r = r2.sqrt();
                let wi = [v[0] / r, v[1] / r, v[2] / r];
                let e = stokes.map(|x| x / r2);
                (wi, r, e, frame_x_from(neg(wi), *frame_up))
            }
        }
    }
}

/// An equirectangular environment map (linear radiance per channel).
#[derive(Clone, Debug)]
pub struct EnvMap {
    /// Width (texels).
    pub width: usize,
    /// Height (texels).
    pub height: usize,
    /// Row-major texels, already in channel order and scaled.
    pub texels: Vec<[f64; MAX_CHANNELS]>,
    /// Turn about `+z` (radians).
    pub rotation_rad: f64,
}

impl EnvMap {
    /// Bilinear lookup for the direction `d` (unit): `u = (φ + π)/2π` with
    /// `φ = atan2(d_y, d_x) − rotation`, `v = θ/π` from `+z`; wraps in `u`.
    pub fn lookup(&self, d: Vec3) -> [f64; MAX_CHANNELS] {
        let phi = d[1].atan2(d[0]) - self.rotation_rad;
        let u = (phi + PI).rem_euclid(2.0 * PI) / (2.0 * PI);
        let v = d[2].clamp(-1.0, 1.0).acos() / PI;
        let x = u * self.width as f64 - 0.5;
        let y = (v * self.height as f64 - 0.5).clamp(0.0, (self.height - 1) as f64);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let xi = |k: f64| (k as i64).rem_euclid(self.width as i64) as usize;
        let yi = |k: f64| (k as usize).min(self.height - 1);
        let t = |a: usize, b: usize| self.texels[b * self.width + a];
        let (a0, a1, b0, b1) = (xi(x0), xi(x0 + 1.0), yi(y0), yi(y0 + 1.0));
        let mut out = [0.0; MAX_CHANNELS];
        for (c, o) in out.iter_mut().enumerate() {
            *o = (1.0 - fy) * ((1.0 - fx) * t(a0, b0)[c] + fx * t(a1, b0)[c])
                + fy * ((1.0 - fx) * t(a0, b1)[c] + fx * t(a1, b1)[c]);
        }
        out
    }
}

/// Light from infinitely far away.
#[derive(Clone, Debug)]
pub enum Environment {
    /// None.
    Black,
    /// Uniform Stokes radiance in the frame with x-axis [`WORLD_UP`]
    /// projected perpendicular to the propagation direction.
    Uniform(Stokes),
    /// Unpolarized map.
    Map(EnvMap),
}

/// A sphere with a table BRDF.
#[derive(Clone, Debug)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius.
    pub radius: f64,
    /// Its BRDF at the image's channels.
    pub brdf: Arc<TableBrdf>,
}

/// A depolarizing Lambertian plane (floor or wall).
#[derive(Clone, Debug)]
pub struct Plane {
    /// `floor` or `walls[k]` (for reports).
    pub name: String,
    /// A point of it.
    pub point: Vec3,
    /// Unit normal of the lit side.
    pub normal: Vec3,
    /// Albedo per channel.
    pub albedo: [f64; MAX_CHANNELS],
}

/// The scene at render time.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Camera.
    pub camera: Camera,
    /// Lights.
    pub lights: Vec<Light>,
    /// Environment.
    pub environment: Environment,
    /// Spheres.
    pub spheres: Vec<Sphere>,
    /// Floor and walls.
    pub planes: Vec<Plane>,
    /// Colour channels (1 or 3).
    pub channels: usize,
    /// Paths per pixel.
    pub samples_per_pixel: usize,
    /// Seed.
    pub seed: u64,
    /// Indirect bounces.
    pub max_bounces: usize,
}

/// What a ray hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Object {
    /// Sphere index.
    Sphere(usize),
    /// Plane index (floor first, then walls).
    Plane(usize),
}

/// A rendered Stokes image: `data[((y·W + x)·C + c)·4 + s]`.
#[derive(Clone, Debug, PartialEq)]
pub struct StokesImage {
    /// Width.
    pub width: usize,
    /// Height.
    pub height: usize,
    /// Channels.
    pub channels: usize,
    /// Stokes components, row-major from the top row.
    pub data: Vec<f64>,
    /// Per pixel the object hit by the ray through the pixel centre.
    pub objects: Vec<Option<Object>>,
}

impl StokesImage {
    /// Stokes vector of channel `c` at pixel `(x, y)`.
    pub fn stokes(&self, x: usize, y: usize, c: usize) -> Stokes {
        let b = ((y * self.width + x) * self.channels + c) * 4;
        [
            self.data[b],
            self.data[b + 1],
            self.data[b + 2],
            self.data[b + 3],
        ]
    }
}

fn offset(p: Vec3, n: Vec3) -> Vec3 {
    let s = 1.0 + p.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    madd(p, n, OFFSET * s)
}

impl Scene {
    /// Nearest hit along `o + t d`, `t ∈ (0, t_max)`.
    pub fn intersect(&self, o: Vec3, d: Vec3, t_max: f64) -> Option<(f64, Object)> {
        let mut best: Option<(f64, Object)> = None;
        let mut t_hi = t_max;
        for (k, s) in self.spheres.iter().enumerate() {
            if let Some(t) = hit_sphere(o, d, s.center, s.radius, 0.0, t_hi) {
                best = Some((t, Object::Sphere(k)));
                t_hi = t;
            }
        }
        for (k, p) in self.planes.iter().enumerate() {
            if let Some(t) = hit_plane(o, d, p.point, p.normal, 0.0, t_hi) {
                best = Some((t, Object::Plane(k)));
                t_hi = t;
            }
        }
        best
    }

    fn occluded(&self, o: Vec3, d: Vec3, t_max: f64) -> bool {
        self.spheres
            .iter()
            .any(|s| hit_sphere(o, d, s.center, s.radius, 0.0, t_max).is_some())
            || self
                .planes
                .iter()
                .any(|p| hit_plane(o, d, p.point, p.normal, 0.0, t_max).is_some())
    }

    /// Environment radiance arriving along `k = −d`, in the frame with
    /// x-axis `x`.
    fn environment(&self, d: Vec3, x: Vec3) -> Radiance {
        let mut out = ZERO;
        match &self.environment {
            Environment::Black => {}
            Environment::Uniform(s) => {
                let k = neg(d);
                let r = rotate_stokes(*s, k, frame_x_from(k, WORLD_UP), x);
                out[..self.channels].fill(r);
            }
            Environment::Map(m) => {
                let v = m.lookup(d);
                for c in 0..self.channels {
                    out[c][0] = v[c];
                }
            }
        }
        out
    }

    /// Stokes radiance per channel arriving at `o` from direction `d` (unit),
    /// in the frame with x-axis `x` (unit, perpendicular to `d`); `depth`
    /// indirect bounces have been made to get here.
    pub fn radiance(
        &self,
        o: Vec3,
        d: Vec3,
        x: Vec3,
        depth: usize,
        rng: &mut SplitMix64,
    ) -> Radiance {
        let Some((t, obj)) = self.intersect(o, d, f64::INFINITY) else {
            return self.environment(d, x);
        };
        let p = madd(o, d, t);
        match obj {
            Object::Plane(k) => self.shade_plane(&self.planes[k], p, d, depth, rng),
            Object::Sphere(k) => self.shade_sphere(&self.spheres[k], p, d, x, depth, rng),
        }
    }

    fn shade_plane(
        &self,
        pl: &Plane,
        p: Vec3,
        d: Vec3,
        depth: usize,
        rng: &mut SplitMix64,
    ) -> Radiance {
        let n = pl.normal;
        if dot(d, n) >= 0.0 {
            return ZERO; // the unlit back of a plane
        }
        let po = offset(p, n);
        let mut irradiance = [0.0; MAX_CHANNELS];
        // Direct light: E_I cos θ_i, shadowed.
        for l in &self.lights {
            let (wi, dist, e, _) = l.sample(p);
            let cos = dot(n, wi);
            if cos <= 0.0 || self.occluded(po, wi, dist) {
                continue;
            }
            irradiance[..self.channels]
                .iter_mut()
                .for_each(|x| *x += e[0] * cos);
        }
        let mut out = ZERO;
        for c in 0..self.channels {
            out[c][0] = pl.albedo[c] / PI * irradiance[c];
        }
        // One indirect ray: a/π · L_i cos θ / (cos θ/π) = a L_i.
        if depth < self.max_bounces {
            let basis = Basis::around(n);
            let wi = basis.to_world(cosine_hemisphere(rng.next_f64(), rng.next_f64()));
            let li = self.radiance(po, wi, frame_x_from(neg(wi), n), depth + 1, rng);
            for c in 0..self.channels {
                out[c][0] += pl.albedo[c] * li[c][0];
            }
        }
        out
    }

    fn shade_sphere(
        &self,
        s: &Sphere,
        p: Vec3,
        d: Vec3,
        x: Vec3,
        depth: usize,
        rng: &mut SplitMix64,
    ) -> Radiance {
        let n = normalize(sub(p, s.center));
        if dot(d, n) >= 0.0 {
            return ZERO; // from inside, or exactly grazing
        }
        let nc = self.channels;
        let po = offset(p, n);
        let basis = Basis::around(n);
        let wo = basis.to_local(neg(d));
        let x_out = basis.to_local(x);
        let mut out = ZERO;
        let mut m = [[[0.0; 4]; 4]; MAX_CHANNELS];
        // Adds M' s w for every channel, with M' the BRDF (or specular
        // matrix) `m` re-expressed for the incident frame `x_in` and the
        // caller's outgoing frame (F1).
        let mut add =
            |m: &[Mueller; MAX_CHANNELS], wi_l: Vec3, x_in_l: Vec3, s: &Radiance, w: f64| {
                for c in 0..nc {
                    match rotate_to_frames(&m[c], wi_l, wo, x_in_l, x_out) {
                        Ok(mr) => {
                            let r = apply(&mr, s[c]);
                            for (o, v) in out[c].iter_mut().zip(r) {
                                *o += w * v;
                            }
                        }
                        Err(e) => debug_assert!(false, "frames: {e}"),
                    }
                }
            };
        // Direct light.
        for l in &self.lights {
            let (wi, dist, e, x_l) = l.sample(p);
            let cos = dot(n, wi);
            if cos <= 0.0 || self.occluded(po, wi, dist) {
                continue;
            }
            let wi_l = basis.to_local(wi);
            if s.brdf.eval(wi_l, wo, &mut m).is_err() {
                continue;
            }
            add(&m, wi_l, basis.to_local(x_l), &[e; MAX_CHANNELS], cos);
        }
        if depth < self.max_bounces {
            // One cosine-weighted indirect ray: f L_i cos θ / (cos θ/π) = π f L_i.
            let wi_l = cosine_hemisphere(rng.next_f64(), rng.next_f64());
            let wi = basis.to_world(wi_l);
            let x_in = frame_x_from(neg(wi), n);
            if s.brdf.eval(wi_l, wo, &mut m).is_ok() {
                let li = self.radiance(po, wi, x_in, depth + 1, rng);
                add(&m, wi_l, basis.to_local(x_in), &li, PI);
            }
            // The mirror base's delta: L_o = S L_i(ω_mirror).
            let wm_l = [-wo[0], -wo[1], wo[2]];
            if s.brdf.has_specular() && matches!(s.brdf.specular(wm_l, wo, &mut m), Ok(true)) {
                let wm = basis.to_world(wm_l);
                let x_in = frame_x_from(neg(wm), n);
                let li = self.radiance(po, wm, x_in, depth + 1, rng);
                add(&m, wm_l, basis.to_local(x_in), &li, 1.0);
            }
        }
        out
    }

    /// The Stokes radiance through pixel `(px, py)` averaged over
    /// `samples_per_pixel` jittered rays, after the polarizer if any, in the
    /// camera's Stokes frame.
    pub fn pixel(&self, px: usize, py: usize) -> Radiance {
        let cam = &self.camera;
        let mut rng = SplitMix64::for_pixel(self.seed, (py * cam.width + px) as u64);
        let mut acc = ZERO;
        for _ in 0..self.samples_per_pixel {
            let (jx, jy) = (rng.next_f64(), rng.next_f64());
            let (d, x) = cam.ray(px as f64 + jx, py as f64 + jy);
            let mut l = self.radiance(cam.position, d, x, 0, &mut rng);
            if let Some(pol) = &cam.polarizer {
                for s in l.iter_mut().take(self.channels) {
                    *s = apply(pol, *s);
                }
            }
            for c in 0..self.channels {
                for k in 0..4 {
                    acc[c][k] += l[c][k];
                }
            }
        }
        let inv = 1.0 / self.samples_per_pixel as f64;
        acc.map(|s| s.map(|v| v * inv))
    }

    /// Render every pixel (rows in parallel on the rayon pool), calling
    /// `progress(rows_done, rows)` after each row.
    pub fn render(&self, progress: &(dyn Fn(usize, usize) + Sync)) -> StokesImage {
        let (w, h, nc) = (self.camera.width, self.camera.height, self.channels);
        let mut data = vec![0.0; w * h * nc * 4];
        let done = AtomicUsize::new(0);
        data.par_chunks_mut(w * nc * 4)
            .enumerate()
            .for_each(|(y, row)| {
                for x in 0..w {
                    let l = self.pixel(x, y);
                    for c in 0..nc {
                        row[(x * nc + c) * 4..(x * nc + c) * 4 + 4].copy_from_slice(&l[c]);
                    }
                }
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, h);
            });
        let objects = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let (d, _) = self.camera.ray(x as f64 + 0.5, y as f64 + 0.5);
                self.intersect(self.camera.position, d, f64::INFINITY)
                    .map(|(_, o)| o)
            })
            .collect();
        StokesImage {
            width: w,
            height: h,
            channels: nc,
            data,
            objects,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::stokes::{degree_of_polarization, rotation};
    use crate::render::polarization::linear_polarizer;

    fn close(a: Stokes, b: Stokes, tol: f64) -> bool {
        a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= tol)
    }

    /// A unit sphere at the origin with a thin Rayleigh layer on a black
    /// base (mostly single scattering), lit by an unpolarized directional
    /// light from `+x`; camera on the `−y` axis looking `+y`, up `+z`.
    fn rayleigh_scene(max_bounces: usize) -> Scene {
        let text = r#"{"layers": [{"optical_thickness": 0.05,
                 "scatterer": {"rayleigh": {"albedo": 1.0}}}], "solver": {"streams": 8}}"#;
        let spec = crate::material::parse(text).unwrap();
        let table =
            crate::brdf::Table::from_spec(&spec, crate::brdf::grid::PolarGrid::graded(24).unwrap())
                .unwrap();
        Scene {
            camera: Camera::new(
                [0.0, -10.0, 0.0],
                [0.0; 3],
                [0.0, 0.0, 1.0],
                20.0,
                16,
                16,
                None,
            ),
            lights: vec![Light::directional(
                [1.0, 0.0, 0.0],
                [1.0, 0.0, 0.0, 0.0],
                WORLD_UP,
            )],
            environment: Environment::Black,
            spheres: vec![Sphere {
                center: [0.0; 3],
                radius: 1.0,
                brdf: Arc::new(TableBrdf::new(Arc::new(table), &[None]).unwrap()),
            }],
            planes: vec![],
            channels: 1,
            samples_per_pixel: 1,
            seed: 3,
            max_bounces,
        }
    }

    /// Physical law through the whole chain (table meridian frames →
    /// rotation into the light's and the camera's frames): singly
    /// Rayleigh-scattered light at `Θ = 90°` is polarized perpendicular to
    /// the scattering plane. The ray hits the sphere where `n = (1, −1, 0)/√2`:
    /// light along `k_in = −x̂`, towards the camera along `k_out = −ŷ`, the
    /// scattering plane is horizontal, so the light is vertically polarized:
    /// `Q/I ≈ −DOP` in the camera frame (x = right = `+x̂`); the scene is
    /// mirror-symmetric about `z = 0`, so `U = V = 0` up to rounding.
    #[test]
    fn rayleigh_polarization_is_perpendicular_to_the_scattering_plane() {
        let scene = rayleigh_scene(0);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let mut rng = SplitMix64::new(1);
        let l = scene.radiance(
            [h, -10.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            0,
            &mut rng,
        )[0];
        assert!(l[0] > 0.0);
        assert!(l[1] / l[0] < -0.8, "{l:?}");
        assert!(
            l[2].abs() < 1e-12 * l[0] && l[3].abs() < 1e-12 * l[0],
            "{l:?}"
        );
        assert!(degree_of_polarization(l) > 0.8);
    }

    /// A mirror base under a zero-thickness layer (glass, n = 1.5) under a
    /// uniform unpolarized sky: the camera sees the sky in the specular
    /// delta only, `S' [1, 0, 0, 0]` with `S` the Fresnel Mueller matrix. At
    /// Brewster's angle `θ_B = atan 1.5` the p-wave is not reflected: the
    /// light is fully polarized perpendicular to the plane of incidence
    /// (here horizontal, so vertical: `Q/I = −1`, `U = V = 0`) with
    /// `I = R_s/2`, `R_s = ((cos θ − n cos θ_t)/(cos θ + n cos θ_t))²`.
    /// Tolerance 1e-6: the table interpolates `S(μ_i)` on its 64-node grid.
    #[test]
    fn mirror_base_reflects_the_sky_polarized_at_brewster() {
        let spec = crate::material::parse(
            r#"{"layers": [{"optical_thickness": 0, "scatterer": {"rayleigh": {"albedo": 1.0}}}],
                "base": {"fresnel": {"material": {"n": 1.5, "k": 0.0}}}, "solver": {"streams": 4}}"#,
        )
        .unwrap();
        let table =
            crate::brdf::Table::from_spec(&spec, crate::brdf::grid::PolarGrid::default()).unwrap();
        let mut scene = rayleigh_scene(1);
        scene.lights.clear();
        scene.environment = Environment::Uniform([1.0, 0.0, 0.0, 0.0]);
        scene.spheres[0].brdf = Arc::new(TableBrdf::new(Arc::new(table), &[None]).unwrap());
        let tb = 1.5f64.atan();
        let mut rng = SplitMix64::new(1);
        let s = scene.radiance(
            [tb.sin(), -10.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            0,
            &mut rng,
        )[0];
        let (ct, st) = (tb.cos(), tb.sin());
        let ctt = (1.0 - (st / 1.5).powi(2)).sqrt();
        let rs = ((ct - 1.5 * ctt) / (ct + 1.5 * ctt)).powi(2);
        assert!(
            (s[0] - rs / 2.0).abs() < 1e-6,
            "{s:?} vs R_s/2 = {}",
            rs / 2.0
        );
        assert!((s[1] / s[0] + 1.0).abs() < 1e-6, "{s:?}");
        assert!(s[2].abs() < 1e-12 && s[3].abs() < 1e-12, "{s:?}");
    }

    /// Re-expressing the answer in an outgoing frame turned by `σ` is the
    /// rotation `L(σ)` of conventions §5: asking `radiance` for the turned
    /// frame gives `L(σ) s` (direct light only: no random numbers).
    #[test]
    fn outgoing_frame_follows_the_rotation_matrix() {
        let scene = rayleigh_scene(0);
        let o = [0.3, -10.0, 0.45];
        let d = [0.0, 1.0, 0.0];
        let x = [1.0, 0.0, 0.0];
        let k = neg(d);
        let y = cross(k, x);
        let mut rng = SplitMix64::new(1);
        let s = scene.radiance(o, d, x, 0, &mut rng)[0];
        assert!(degree_of_polarization(s) > 0.1);
        for sig in [0.4f64, -1.1, 2.5] {
            let x2 = [
                sig.cos() * x[0] + sig.sin() * y[0],
                sig.cos() * x[1] + sig.sin() * y[1],
                sig.cos() * x[2] + sig.sin() * y[2],
            ];
            let s2 = scene.radiance(o, d, x2, 0, &mut rng)[0];
            assert!(close(s2, apply(&rotation(sig), s), 1e-14 * s[0]), "{sig}");
        }
    }

    /// Mirror symmetry: the scene is symmetric about the plane `z = 0`
    /// (camera, light and sphere on it); mirrored rays see mirrored light:
    /// same `I` and `Q`, opposite `U` and `V` (the mirror keeps the frame's
    /// `x = +x̂` and turns `y` into `−y`: a left-handed frame, i.e. the sign
    /// of the angles and of the helicity flips). The local shading frames at
    /// the two points are unrelated, so this also checks that the result
    /// does not depend on the tangent of the shading frame.
    #[test]
    fn mirrored_pixels_have_opposite_u_and_v() {
        let scene = rayleigh_scene(0);
        let mut rng = SplitMix64::new(1);
        for (px, pz) in [(0.3, 0.45), (0.6, -0.2), (0.5, 0.7), (0.05, 0.9)] {
            let x = [1.0, 0.0, 0.0];
            let up = scene.radiance([px, -10.0, pz], [0.0, 1.0, 0.0], x, 0, &mut rng)[0];
            let down = scene.radiance([px, -10.0, -pz], [0.0, 1.0, 0.0], x, 0, &mut rng)[0];
            assert!(up[0] > 0.0 && (up[2].abs() > 1e-3 * up[0]), "{up:?}");
            let mirrored = [up[0], up[1], -up[2], -up[3]];
            assert!(close(down, mirrored, 1e-12 * up[0]), "{up:?} {down:?}");
        }
    }

    /// Hand-computed pixel: a uniform sky polarized along its frame's `x`
    /// (world `+z` projected), `[1, 1, 0, 0]`, seen along `d = (1, 1, 1)/√3`
    /// by a camera looking `+y` with right `+x̂`. By hand: camera x-axis
    /// `x_c = (2, −1, −1)/√6`, `y_c = k × x_c = (0, −1, 1)/√2` with
    /// `k = −d`; the sky's axis `x_s = (−1, −1, 2)/√6`;
    /// `x_s·x_c = −1/2`, `x_s·y_c = √3/2`: the sky light is polarized at
    /// `ψ = 120°` in the camera frame, `S = (1, cos 240°, sin 240°, 0) =
    /// (1, −1/2, −√3/2, 0)`; a polarizer at `a` passes `cos²(a − 120°)`.
    #[test]
    fn hand_computed_sky_pixel() {
        let mut scene = rayleigh_scene(0);
        scene.spheres.clear();
        scene.environment = Environment::Uniform([1.0, 1.0, 0.0, 0.0]);
        let cam = &scene.camera;
        assert!(close(
            [cam.right[0], cam.right[1], cam.right[2], 0.0],
            [1.0, 0.0, 0.0, 0.0],
            1e-15
        ));
        let d = normalize([1.0, 1.0, 1.0]);
        let x = cam.frame_x(d);
        let r6 = 6f64.sqrt();
        assert!(close(
            [x[0], x[1], x[2], 0.0],
            [2.0 / r6, -1.0 / r6, -1.0 / r6, 0.0],
            1e-15
        ));
        let mut rng = SplitMix64::new(1);
        let s = scene.radiance(cam.position, d, x, 0, &mut rng)[0];
        let expect = [1.0, -0.5, -(3f64.sqrt()) / 2.0, 0.0];
        assert!(close(s, expect, 1e-14), "{s:?}");
        for a_deg in [0.0f64, 30.0, 75.0, 120.0, 200.0] {
            let t = apply(&linear_polarizer(a_deg.to_radians()), s)[0];
            let malus = (a_deg - 120.0).to_radians().cos().powi(2);
            assert!((t - malus).abs() < 1e-14, "{a_deg}: {t} vs {malus}");
        }
    }

    /// Only depolarizing surfaces and unpolarized sources: every pixel has
    /// `S1 = S2 = S3 = 0` exactly (no rounding can create them: the
    /// Lambertian kernel only ever writes `I`).
    #[test]
    fn unpolarized_lambertian_scene_is_exactly_unpolarized() {
        let mut scene = rayleigh_scene(2);
        scene.spheres.clear();
        scene.samples_per_pixel = 2;
        scene.environment = Environment::Uniform([0.3, 0.0, 0.0, 0.0]);
        scene.lights.push(Light::Point {
            position: [1.0, -2.0, 3.0],
            stokes: [5.0, 0.0, 0.0, 0.0],
            frame_up: WORLD_UP,
        });
        scene.planes = vec![
            Plane {
                name: "floor".into(),
                point: [0.0, 0.0, -1.0],
                normal: [0.0, 0.0, 1.0],
                albedo: [0.7; MAX_CHANNELS],
            },
            Plane {
                name: "walls[0]".into(),
                point: [0.0, 3.0, 0.0],
                normal: [0.0, -1.0, 0.0],
                albedo: [0.5; MAX_CHANNELS],
            },
        ];
        let img = scene.render(&|_, _| {});
        let mut lit = 0;
        for px in img.data.chunks(4) {
            assert_eq!(&px[1..], &[0.0, 0.0, 0.0]);
            lit += usize::from(px[0] > 0.0);
        }
        assert_eq!(lit, 16 * 16);
    }

    /// Equirectangular lookup: the top row is `+z`, the left edge azimuth
    /// `−180°`, the centre column `+x`; `rotation` turns the map about `+z`.
    #[test]
    fn equirectangular_orientation() {
        // 8 × 4 texels; value = column + 10 · row (one channel).
        let (w, h) = (8, 4);
        let texels = (0..w * h)
            .map(|k| [(k % w) as f64 + 10.0 * (k / w) as f64, 0.0, 0.0])
            .collect();
        let mut m = EnvMap {
            width: w,
            height: h,
            texels,
            rotation_rad: 0.0,
        };
        // Straight up: row 0 (clamped); along +x at the horizon: between
        // columns 3 and 4 and rows 1 and 2.
        assert!((m.lookup([0.0, 0.0, 1.0])[0] - 3.5).abs() < 1e-12);
        assert!((m.lookup([1.0, 0.0, 0.0])[0] - 18.5).abs() < 1e-12);
        // Azimuth +90° (+y) is a quarter of the width to the right.
        assert!((m.lookup([0.0, 1.0, 0.0])[0] - 20.5).abs() < 1e-12);
        // Turning the map by +90° brings the +x texels to +y.
        m.rotation_rad = std::f64::consts::FRAC_PI_2;
        assert!((m.lookup([0.0, 1.0, 0.0])[0] - 18.5).abs() < 1e-12);
    }

    /// Same seed, same image, whatever the number of threads; another seed
    /// gives another image (indirect light is sampled).
    #[test]
    fn render_is_deterministic() {
        let mut scene = rayleigh_scene(1);
        scene.samples_per_pixel = 2;
        scene.planes.push(Plane {
            name: "floor".into(),
            point: [0.0, 0.0, -1.0],
            normal: [0.0, 0.0, 1.0],
            albedo: [0.5; MAX_CHANNELS],
        });
        let a = scene.render(&|_, _| {});
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let b = one.install(|| scene.render(&|_, _| {}));
        assert_eq!(a, b);
        scene.seed += 1;
        assert_ne!(a.data, scene.render(&|_, _| {}).data);
    }
}
