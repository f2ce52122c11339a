//! Export of a table for Mitsuba 3's `measured_polarized` BSDF
//! (docs/mitsuba.md; frames: docs/conventions.md §9).
//!
//! The plugin (Mitsuba 3.9.1, `src/bsdfs/measured_polarized.cpp`) reads a
//! `tensor_file` with the fields
//!
//! | field | dtype | shape | content |
//! |---|---|---|---|
//! | `phi_d` | float32 | `(1, P)` | Rusinkiewicz difference azimuth (rad), increasing, `[−π, π]` |
//! | `theta_d` | float32 | `(1, D)` | difference angle (rad), `[0, π/2]` |
//! | `theta_h` | float32 | `(1, H)` | half-vector polar angle (rad), `[0, π/2]` |
//! | `wvls` | uint16 | `(5,)` | wavelengths (nm); the plugin reads exactly five |
//! | `M` | float32 | `(P, D, H, 5, 4, 4)` | Mueller BRDF (1/sr, **no** cosine), row = outgoing Stokes |
//!
//! and interpolates `M` multilinearly in `(φ_d, θ_d, θ_h, λ)` (weights
//! clamped to the node range: no extrapolation). Its eval, for the light
//! direction `ω_i` (Mitsuba's `wo` in radiance mode) and the viewer
//! direction `ω_o` (Mitsuba's `si.wi`), is
//!
//! ```text
//! h = normalize(ω_i + ω_o),  θ_h = acos h_z,  θ_d = acos(h·ω_i),
//! b = normalize(ẑ × h),  t = b × h,  φ_d = atan2(b·ω_i⊥, t·ω_i⊥)        (R1)
//! ```
//!
//! (`ω_i⊥` the part of `ω_i` perpendicular to `h`), and takes the
//! interpolated matrix to be referred to Stokes frames with the **same x-axis
//! for the incident ray `k_in = −ω_i` and the outgoing ray `k_out = ω_o`**,
//! `x = normalize(ω_i × ω_o)`, `y = k × x`; it then rotates it into its own
//! implicit Stokes bases and multiplies by `cos θ_i`. Mitsuba's circular
//! component has the opposite sign of ours (conventions §9: Mitsuba's `V > 0`
//! turns clockwise seen facing the source, ours counter-clockwise; checked
//! against Mitsuba's own Fresnel conductor in `tests/mitsuba_export.rs`).
//! So each stored matrix is
//!
//! ```text
//! M_mitsuba = D_V · L(σ_out) · f · L(−σ_in) · D_V,   D_V = diag(1, 1, 1, −1)   (R2)
//! ```
//!
//! with `f` the table's BRDF in the meridian frames of conventions §5 and
//! `σ` the angles of [`rotate_to_frames`] from the meridian x-axes to
//! `x = normalize(ω_i × ω_o)`.
//!
//! **Node directions.** For a node `(φ_d, θ_d, θ_h)` (any rotation about the
//! normal gives the same values: the BRDF is isotropic and the frames turn
//! with the directions) take `h = (sin θ_h, 0, cos θ_h)`,
//! `t = (cos θ_h, 0, −sin θ_h)`, `b = (0, 1, 0)`,
//! `u = cos φ_d t + sin φ_d b`:
//!
//! ```text
//! ω_i = cos θ_d h + sin θ_d u,   ω_o = cos θ_d h − sin θ_d u,   x = sin φ_d t − cos φ_d b   (R3)
//! ```
//!
//! (`x = u × h = normalize(ω_i × ω_o)`, also the limit at `θ_d → 0` where
//! the cross product vanishes).
//!
//! **Horizon.** Nodes with `ω_i` or `ω_o` below the horizon are never
//! asked for by the plugin (it returns 0 there) but enter the interpolation
//! cells that straddle the horizon, and a NaN anywhere in a cell blanks the
//! whole cell (the plugin zeroes any result whose `M00` is NaN), so they hold
//! finite numbers, by [`BelowHorizon`]: the default
//! [`BelowHorizon::Extend`] continues the BRDF smoothly, evaluating such a
//! node at its directions moved up to the horizon (same azimuth);
//! [`BelowHorizon::Zero`] stores 0, which pulls the interpolation towards 0
//! next to the horizon. Every node is evaluated with its direction cosines
//! raised to at least `μ_floor = sin(Δθ_h/4)` ([`node_mu_floor`]; 0.0087 for
//! the default 2° step): the BRDF of a thin layer grows like
//! `1/(μ_i + μ_o)` at the double-grazing corner, so a node exactly on the
//! horizon (e.g. `θ_h = 90°`, `φ_d = ±90°`) would carry `f(μ = 10⁻⁶) ~ 10⁵ f`
//! into the cells around it. Errors measured in docs/mitsuba.md.
//!
//! **Specular delta.** The specular term of a mirror base (conventions §6)
//! is a Dirac delta and cannot be sampled on this grid: it is left out, and
//! the file's metadata says so (`specular_delta`); [`export_warnings`] says
//! so to the user, with the resampling error when it is over
//! [`RESAMPLING_WARNING`].

use super::BrdfError;
use super::angles::{Vec3, cross, dot, normalize};
use super::frames::rotate_to_frames;
use super::table::Table;
use crate::physics::stokes::{Mueller, mul, rotation};
use rayon::prelude::*;
use serde_json::{Value, json};
use std::f64::consts::{FRAC_PI_2, PI};

/// The first 12 bytes of a `tensor_file`.
pub const MAGIC: &[u8; 12] = b"tensor_file\0";

/// Number of wavelengths the plugin reads (it copies exactly five values of
/// `wvls`, whatever the field's length).
pub const WAVELENGTHS: usize = 5;

/// Name of the extra field holding polbrdf's metadata (UTF-8 JSON as
/// uint8); the plugin looks fields up by name and ignores it.
pub const METADATA_FIELD: &str = "polbrdf_metadata";

/// Default number of `φ_d` nodes: 5° steps over `[−180°, 180°]`
/// (0° and ±90° are nodes). Sizes measured in docs/mitsuba.md.
pub const DEFAULT_PHI_D: usize = 73;
/// Default number of `θ_d` nodes: 2° steps over `[0°, 90°]`.
pub const DEFAULT_THETA_D: usize = 46;
/// Default number of `θ_h` nodes: 2° steps over `[0°, 90°]`.
pub const DEFAULT_THETA_H: usize = 46;

/// Struct-type codes of Mitsuba's `tensor_file` (as `mitsuba.tensor_io`).
const DTYPE_U8: u8 = 1;
const DTYPE_U16: u8 = 3;
const DTYPE_F32: u8 = 10;
/// Field data start at multiples of this many bytes.
const ALIGN: usize = 64;
/// A direction with `z ≥ −HORIZON_EPS` counts as above the horizon.
const HORIZON_EPS: f64 = 1e-12;

/// What nodes below the horizon hold (module doc, "Horizon").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BelowHorizon {
    /// The BRDF at the node's directions moved up to the horizon (a
    /// continuous extension).
    Extend,
    /// Zero.
    Zero,
}

impl BelowHorizon {
    /// Name used in the CLI and the metadata.
    pub fn name(self) -> &'static str {
        match self {
            Self::Extend => "extend",
            Self::Zero => "zero",
        }
    }
}

/// Options of the export.
#[derive(Clone, Debug, PartialEq)]
pub struct MitsubaOptions {
    /// Nodes in `φ_d`, uniform over `[−π, π]` (≥ 2).
    pub phi_d: usize,
    /// Nodes in `θ_d`, uniform over `[0, π/2]` (≥ 2).
    pub theta_d: usize,
    /// Nodes in `θ_h`, uniform over `[0, π/2]` (≥ 2).
    pub theta_h: usize,
    /// Interpolate the table linearly onto five evenly spaced integer
    /// wavelengths in its range instead of requiring exactly five integer
    /// wavelengths ([`export_wavelengths`]).
    pub resample_wavelengths: bool,
    /// Values of the nodes below the horizon.
    pub below_horizon: BelowHorizon,
}

impl Default for MitsubaOptions {
    fn default() -> Self {
        Self {
            phi_d: DEFAULT_PHI_D,
            theta_d: DEFAULT_THETA_D,
            theta_h: DEFAULT_THETA_H,
            resample_wavelengths: false,
            below_horizon: BelowHorizon::Extend,
        }
    }
}

/// Rusinkiewicz half/difference angles (radians) as the plugin computes
/// them (R1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rusinkiewicz {
    /// Difference azimuth, `(−π, π]`.
    pub phi_d: f64,
    /// Difference angle `acos(h·ω_i)`.
    pub theta_d: f64,
    /// Half-vector polar angle `acos h_z`.
    pub theta_h: f64,
}

fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn scaled(a: Vec3, s: f64) -> Vec3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}

/// The plugin's map (R1) from the light direction `wi` and the viewer
/// direction `wo` (graphics convention, any length) to `(φ_d, θ_d, θ_h)`.
/// `None` where the plugin itself gets NaN: `ω_i = −ω_o`, `h` on the
/// normal (`θ_h = 0`, `b` undefined) or `ω_i = ω_o` (`θ_d = 0`, `ω_i⊥ = 0`).
pub fn rusinkiewicz(wi: Vec3, wo: Vec3) -> Option<Rusinkiewicz> {
    let (i, o) = (normalize(wi), normalize(wo));
    let sum = [i[0] + o[0], i[1] + o[1], i[2] + o[2]];
    if norm(sum) == 0.0 {
        return None;
    }
    let h = normalize(sum);
    let nb = cross([0.0, 0.0, 1.0], h);
    let ip = sub(i, scaled(h, dot(i, h)));
    if norm(nb) == 0.0 || norm(ip) == 0.0 {
        return None;
    }
    let b = normalize(nb);
    let t = normalize(cross(b, h));
    let ip = normalize(ip);
    Some(Rusinkiewicz {
        phi_d: dot(b, ip).atan2(dot(t, ip)),
        theta_d: dot(h, i).clamp(-1.0, 1.0).acos(),
        theta_h: h[2].clamp(-1.0, 1.0).acos(),
    })
}

/// The node directions (R3): `(ω_i, ω_o, x)` with `x = normalize(ω_i × ω_o)`
/// (or its limit at `θ_d = 0`), the half vector in the `x–z` plane.
pub fn directions_of(r: &Rusinkiewicz) -> (Vec3, Vec3, Vec3) {
    let (sh, ch) = r.theta_h.sin_cos();
    let (sd, cd) = r.theta_d.sin_cos();
    let (sp, cp) = r.phi_d.sin_cos();
    let h = [sh, 0.0, ch];
    let t = [ch, 0.0, -sh];
    let b = [0.0, 1.0, 0.0];
    let u = [
        cp * t[0] + sp * b[0],
        cp * t[1] + sp * b[1],
        cp * t[2] + sp * b[2],
    ];
    let wi = [
        cd * h[0] + sd * u[0],
        cd * h[1] + sd * u[1],
        cd * h[2] + sd * u[2],
    ];
    let wo = [
        cd * h[0] - sd * u[0],
        cd * h[1] - sd * u[1],
        cd * h[2] - sd * u[2],
    ];
    let x = [
        sp * t[0] - cp * b[0],
        sp * t[1] - cp * b[1],
        sp * t[2] - cp * b[2],
    ];
    (wi, wo, x)
}

/// `D_V m D_V` with `D_V = diag(1, 1, 1, −1)`: the sign of the circular
/// component between our convention and Mitsuba's (conventions §9).
pub fn flip_v(m: &Mueller) -> Mueller {
    let mut o = *m;
    for (i, row) in o.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            if (i == 3) != (j == 3) {
                *x = -*x;
            }
        }
    }
    o
}

/// (R2): a BRDF `m` in our meridian frames (conventions §5, as
/// [`Table::eval_vectors`] returns it for `wi`, `wo`) expressed as the
/// plugin stores it: both Stokes x-axes `x` (perpendicular to `ω_i` and
/// `ω_o`, normally `normalize(ω_i × ω_o)`), Mitsuba's sign of `V`.
pub fn to_mitsuba(m: &Mueller, wi: Vec3, wo: Vec3, x: Vec3) -> Result<Mueller, BrdfError> {
    Ok(flip_v(&rotate_to_frames(m, wi, wo, x, x)?))
}

/// Re-express a Mueller matrix for other Stokes x-axes, as Mitsuba's
/// `mueller::rotate_mueller_basis`: the incident ray travels along `k_in`
/// with current x-axis `x_in` and new `x_in_new`, likewise the outgoing ray;
/// `M' = L(σ_out) M L(−σ_in)` with `σ` the angle from the current to the new
/// axis, positive from `x` towards `k × x` (conventions §5). All vectors
/// unit and each `x` perpendicular to its `k`.
pub fn rebase(
    m: &Mueller,
    k_in: Vec3,
    x_in: Vec3,
    x_in_new: Vec3,
    k_out: Vec3,
    x_out: Vec3,
    x_out_new: Vec3,
) -> Mueller {
    let angle = |k: Vec3, x: Vec3, new: Vec3| dot(new, cross(k, x)).atan2(dot(new, x));
    let s_in = angle(k_in, x_in, x_in_new);
    let s_out = angle(k_out, x_out, x_out_new);
    mul(&mul(&rotation(s_out), m), &rotation(-s_in))
}

/// The five wavelengths (nm) of the export and whether they were resampled.
///
/// * A table with exactly five wavelengths, all integers in nm (the plugin
///   stores them as uint16), is exported as is.
/// * With `resample`, five evenly spaced integer wavelengths from
///   `ceil(λ_min)` to `floor(λ_max)` (interior ones rounded), at which the
///   table is interpolated linearly ([`Table::eval`]); the range must hold
///   at least five integers.
/// * Anything else is an error naming the option.
pub fn export_wavelengths(table: &Table, resample: bool) -> Result<(Vec<u16>, bool), BrdfError> {
    let known: Vec<f64> = table
        .wavelengths
        .iter()
        .filter_map(|w| w.wavelength_nm)
        .collect();
    if known.len() != table.wavelengths.len() {
        return Err(BrdfError::Query(
            "the table is wavelength-free; Mitsuba's measured_polarized needs five wavelengths in nm: solve the spec with \"wavelengths_nm\" (five of them)".into(),
        ));
    }
    let list = known
        .iter()
        .map(|w| format!("{w}"))
        .collect::<Vec<_>>()
        .join(", ");
    let integral = |w: f64| (w - w.round()).abs() <= 1e-9 * w.abs().max(1.0);
    if !resample {
        if known.len() == WAVELENGTHS
            && known
                .iter()
                .all(|&w| integral(w) && (1.0..=f64::from(u16::MAX)).contains(&w.round()))
        {
            return Ok((known.iter().map(|w| w.round() as u16).collect(), false));
        }
        let why = if known.len() == WAVELENGTHS {
            "they must be whole nanometres (the file stores them as uint16)".to_string()
        } else {
            format!("it has {}", known.len())
        };
        return Err(BrdfError::Query(format!(
            "Mitsuba's measured_polarized reads exactly five wavelengths; this table has [{list}] nm ({why}). Solve the spec at five whole-nm wavelengths, or pass --resample-wavelengths to interpolate the table linearly onto five evenly spaced whole-nm wavelengths in its range (docs/mitsuba.md)"
        )));
    }
    let (lo, hi) = (known[0].ceil(), known[known.len() - 1].floor());
    if hi - lo < (WAVELENGTHS - 1) as f64 || lo < 1.0 || hi > f64::from(u16::MAX) {
        return Err(BrdfError::Query(format!(
            "--resample-wavelengths needs a wavelength range holding five whole nanometres within 1..65535 nm; the table has [{list}] nm"
        )));
    }
    let out: Vec<u16> = (0..WAVELENGTHS)
        .map(|k| {
            let w = lo + (hi - lo) * k as f64 / (WAVELENGTHS - 1) as f64;
            w.round().clamp(lo, hi) as u16
        })
        .collect();
    Ok((out, true))
}

/// Uniform nodes `a + (b − a) k/(n − 1)`.
fn uniform(a: f64, b: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| a + (b - a) * k as f64 / (n - 1) as f64)
        .collect()
}

/// The exported tensor: axes, wavelengths, `M` and the metadata text.
#[derive(Clone, Debug, PartialEq)]
pub struct MitsubaTable {
    /// `φ_d` nodes (rad).
    pub phi_d: Vec<f32>,
    /// `θ_d` nodes (rad).
    pub theta_d: Vec<f32>,
    /// `θ_h` nodes (rad).
    pub theta_h: Vec<f32>,
    /// Wavelengths (nm).
    pub wavelengths_nm: Vec<u16>,
    /// `M`, shape `(P, D, H, W, 4, 4)`, C order.
    pub m: Vec<f32>,
    /// polbrdf's metadata (JSON text) stored as the extra field.
    pub metadata: String,
}

/// Build the tensor (module doc): every node of the `(φ_d, θ_d, θ_h)` grid
/// at every export wavelength, by [`Table::eval_vectors`] and (R2).
pub fn build(table: &Table, opts: &MitsubaOptions) -> Result<MitsubaTable, BrdfError> {
    // Mitsuba samples every direction pair and the whole matrix (R2).
    table.require_complete("the Mitsuba export")?;
    for (name, n) in [
        ("phi_d", opts.phi_d),
        ("theta_d", opts.theta_d),
        ("theta_h", opts.theta_h),
    ] {
        if !(2..=4096).contains(&n) {
            return Err(BrdfError::Query(format!(
                "{name} nodes = {n}: give 2..4096"
            )));
        }
    }
    let (wvls, resampled) = export_wavelengths(table, opts.resample_wavelengths)?;
    let phi_d = uniform(-PI, PI, opts.phi_d);
    let theta_d = uniform(0.0, FRAC_PI_2, opts.theta_d);
    let theta_h = uniform(0.0, FRAC_PI_2, opts.theta_h);
    let nh = theta_h.len();
    let mu_floor = node_mu_floor(opts);
    let per_node = WAVELENGTHS * 16;
    let columns: Vec<(f64, f64)> = phi_d
        .iter()
        .flat_map(|&p| theta_d.iter().map(move |&d| (p, d)))
        .collect();
    let blocks: Vec<Vec<f32>> = columns
        .par_iter()
        .map(|&(p, d)| column(table, &wvls, p, d, &theta_h, opts.below_horizon, mu_floor))
        .collect::<Result<_, _>>()?;
    let mut m = Vec::with_capacity(columns.len() * nh * per_node);
    for b in blocks {
        m.extend(b);
    }
    let metadata = metadata(table, opts, &wvls, resampled);
    Ok(MitsubaTable {
        phi_d: phi_d.iter().map(|&x| x as f32).collect(),
        theta_d: theta_d.iter().map(|&x| x as f32).collect(),
        theta_h: theta_h.iter().map(|&x| x as f32).collect(),
        wavelengths_nm: wvls,
        m,
        metadata: serde_json::to_string_pretty(&metadata).expect("JSON"),
    })
}

/// The smallest direction cosine at which nodes are evaluated: a quarter
/// of the `θ_h` step, `μ_floor = sin(π/(8(H − 1)))` (module doc, "Horizon").
pub fn node_mu_floor(opts: &MitsubaOptions) -> f64 {
    (PI / (8.0 * (opts.theta_h - 1) as f64)).sin()
}

/// A unit vector `w` with `z < mu_floor` moved to `z = mu_floor` at the same
/// azimuth (`w` must not be vertical).
fn lift(w: Vec3, mu_floor: f64) -> Vec3 {
    if w[2] >= mu_floor {
        return w;
    }
    let r = w[0].hypot(w[1]);
    let s = (1.0 - mu_floor * mu_floor).sqrt() / r;
    [w[0] * s, w[1] * s, mu_floor]
}

/// One `(φ_d, θ_d)` column: `H × 5 × 16` values.
fn column(
    table: &Table,
    wvls: &[u16],
    phi_d: f64,
    theta_d: f64,
    theta_h: &[f64],
    below: BelowHorizon,
    mu_floor: f64,
) -> Result<Vec<f32>, BrdfError> {
    let per_node = WAVELENGTHS * 16;
    let mut out = vec![0.0f32; theta_h.len() * per_node];
    for (k, &th) in theta_h.iter().enumerate() {
        let r = Rusinkiewicz {
            phi_d,
            theta_d,
            theta_h: th,
        };
        let (wi, wo, x) = directions_of(&r);
        let under = wi[2] < -HORIZON_EPS || wo[2] < -HORIZON_EPS;
        // A vertical direction below the horizon (only at θ_d = θ_h = 90°,
        // φ_d = 0, a node whose cells never reach the hemisphere) has no
        // azimuth to keep: 0.
        let vertical = wi[0].hypot(wi[1]) < 1e-9 || wo[0].hypot(wo[1]) < 1e-9;
        if under && (below == BelowHorizon::Zero || vertical) {
            continue;
        }
        let (wi, wo) = (lift(wi, mu_floor), lift(wo, mu_floor));
        // The Stokes axis of the moved pair (for θ_d = 0 the limit axis of
        // (R3), made perpendicular again).
        let c = cross(wi, wo);
        let x = if norm(c) > 1e-9 {
            normalize(c)
        } else {
            normalize(sub(x, scaled(wi, dot(x, wi))))
        };
        for (l, &w) in wvls.iter().enumerate() {
            let f = table.eval_vectors(wi, wo, Some(f64::from(w)))?;
            let g = to_mitsuba(&f, wi, wo, x)?;
            let base = k * per_node + l * 16;
            for (a, v) in g.iter().flatten().enumerate() {
                out[base + a] = *v as f32;
            }
        }
    }
    Ok(out)
}

fn metadata(table: &Table, opts: &MitsubaOptions, wvls: &[u16], resampled: bool) -> Value {
    let mirror = table.wavelengths.iter().any(|w| w.specular.is_some());
    let table_wl: Vec<Option<f64>> = table.wavelengths.iter().map(|w| w.wavelength_nm).collect();
    json!({
        "generator": format!("polbrdf {}", env!("CARGO_PKG_VERSION")),
        "format": "Mitsuba 3 measured_polarized tensor_file (docs/mitsuba.md)",
        "spec_hash": table.metadata.spec_hash,
        "spec": table.metadata.spec,
        "units": "M: Mueller BRDF in 1/sr without the cosine factor (the plugin multiplies by cos theta of the light direction)",
        "parametrisation": "Rusinkiewicz angles of the plugin: h = normalize(w_light + w_view), theta_h = acos(h_z), theta_d = acos(h . w_light), phi_d = atan2(b . w_light_perp, t . w_light_perp) with b = normalize(z x h), t = b x h",
        "frames": "row = outgoing Stokes, column = incident; both Stokes x-axes = normalize(w_light x w_view), y = k x x (k = -w_light incident, w_view outgoing); circular component V in Mitsuba's sign, the opposite of polbrdf's (docs/conventions.md sec. 9)",
        "grid": {
            "phi_d": format!("{} nodes uniform in [-pi, pi]", opts.phi_d),
            "theta_d": format!("{} nodes uniform in [0, pi/2]", opts.theta_d),
            "theta_h": format!("{} nodes uniform in [0, pi/2]", opts.theta_h),
        },
        "below_horizon": match opts.below_horizon {
            BelowHorizon::Extend => "extend: a node with a direction below the horizon holds the BRDF at its directions moved up to the horizon (same azimuth)",
            BelowHorizon::Zero => "zero: nodes with a direction below the horizon hold 0",
        },
        "horizon_floor": format!("nodes are evaluated with direction cosines raised to at least mu_floor = sin(theta_h step / 4) = {:.6} (the BRDF of a thin layer diverges at the double-grazing corner)", node_mu_floor(opts)),
        "wavelengths_nm": wvls,
        "table_wavelengths_nm": table_wl,
        "wavelength_policy": if resampled {
            "resampled: the table interpolated linearly in wavelength onto five evenly spaced whole-nm wavelengths in its range"
        } else {
            "exact: the table's five wavelengths"
        },
        "specular_delta": if mirror && has_top_interface(table) {
            "NOT INCLUDED: the table has a smooth top interface; its specular reflection is a Dirac delta (docs/conventions.md sec. 8) that a measured_polarized grid cannot represent. Only the diffuse part is in M; a renderer must add a delta lobe at the mirror direction with weight S = M(r_1n(mu_i)), the Fresnel Mueller matrix of air over the binder at the light's cosine mu_i (docs/mitsuba.md)."
        } else if mirror {
            "NOT INCLUDED: the table's base is a mirror; its specular reflection is a Dirac delta (docs/conventions.md sec. 6) that a measured_polarized grid cannot represent. Only the diffuse part is in M; a renderer must add a delta lobe at the mirror direction with weight S = exp(-2 tau/mu_i) M_F(mu_i): tau the stack's optical thickness, M_F the base's Fresnel Mueller matrix at the light's cosine mu_i (docs/mitsuba.md)."
        } else {
            "none: the table has no mirror base"
        },
    })
}

fn field_header(out: &mut Vec<u8>, name: &str, dtype: u8, shape: &[usize]) -> usize {
    out.extend((name.len() as u16).to_le_bytes());
    out.extend(name.as_bytes());
    out.extend((shape.len() as u16).to_le_bytes());
    out.push(dtype);
    let at = out.len();
    out.extend(0u64.to_le_bytes());
    for &s in shape {
        out.extend((s as u64).to_le_bytes());
    }
    at
}

impl MitsubaTable {
    /// `(P, D, H, W, 4, 4)`.
    pub fn shape(&self) -> [usize; 6] {
        [
            self.phi_d.len(),
            self.theta_d.len(),
            self.theta_h.len(),
            self.wavelengths_nm.len(),
            4,
            4,
        ]
    }

    /// The `tensor_file` bytes: magic `tensor_file\0`, version `1, 0`,
    /// `u32` field count, per field `u16` name length, name, `u16` rank,
    /// `u8` type, `u64` data offset, `u64` sizes; then the data, each field
    /// starting at a multiple of 64 bytes. Little-endian.
    pub fn to_bytes(&self) -> Vec<u8> {
        let meta = self.metadata.as_bytes();
        let mut out = Vec::with_capacity(self.m.len() * 4 + meta.len() + 4096);
        out.extend(MAGIC);
        out.extend([1u8, 0u8]);
        out.extend(6u32.to_le_bytes());
        let f32_bytes = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let fields: Vec<(&str, u8, Vec<usize>, Vec<u8>)> = vec![
            (
                "phi_d",
                DTYPE_F32,
                vec![1, self.phi_d.len()],
                f32_bytes(&self.phi_d),
            ),
            (
                "theta_d",
                DTYPE_F32,
                vec![1, self.theta_d.len()],
                f32_bytes(&self.theta_d),
            ),
            (
                "theta_h",
                DTYPE_F32,
                vec![1, self.theta_h.len()],
                f32_bytes(&self.theta_h),
            ),
            (
                "wvls",
                DTYPE_U16,
                vec![self.wavelengths_nm.len()],
                self.wavelengths_nm
                    .iter()
                    .flat_map(|x| x.to_le_bytes())
                    .collect(),
            ),
            ("M", DTYPE_F32, self.shape().to_vec(), f32_bytes(&self.m)),
            (METADATA_FIELD, DTYPE_U8, vec![meta.len()], meta.to_vec()),
        ];
        let slots: Vec<usize> = fields
            .iter()
            .map(|(name, ty, shape, _)| field_header(&mut out, name, *ty, shape))
            .collect();
        for ((_, _, _, data), slot) in fields.iter().zip(slots) {
            let start = out.len().div_ceil(ALIGN) * ALIGN;
            out.resize(start, 0);
            out[slot..slot + 8].copy_from_slice(&(start as u64).to_le_bytes());
            out.extend(data);
        }
        out
    }

    /// Parse a `tensor_file` written by [`MitsubaTable::to_bytes`] (or any
    /// with the plugin's fields), checking the plugin's requirements.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, BrdfError> {
        let bad = |m: &str| BrdfError::Format(format!("tensor_file: {m}"));
        let take = |at: &mut usize, n: usize| -> Result<&[u8], BrdfError> {
            let s = bytes
                .get(*at..*at + n)
                .ok_or_else(|| bad("truncated header"))?;
            *at += n;
            Ok(s)
        };
        let mut at = 0;
        if take(&mut at, 12)? != MAGIC {
            return Err(bad("bad magic"));
        }
        if take(&mut at, 2)? != [1, 0] {
            return Err(bad("version is not 1.0"));
        }
        let n = u32::from_le_bytes(take(&mut at, 4)?.try_into().unwrap());
        let mut fields = std::collections::HashMap::new();
        for _ in 0..n {
            let len = u16::from_le_bytes(take(&mut at, 2)?.try_into().unwrap()) as usize;
            let name = String::from_utf8(take(&mut at, len)?.to_vec())
                .map_err(|_| bad("field name is not UTF-8"))?;
            let rank = u16::from_le_bytes(take(&mut at, 2)?.try_into().unwrap()) as usize;
            let ty = take(&mut at, 1)?[0];
            let offset = u64::from_le_bytes(take(&mut at, 8)?.try_into().unwrap()) as usize;
            let mut shape = Vec::with_capacity(rank);
            for _ in 0..rank {
                shape.push(u64::from_le_bytes(take(&mut at, 8)?.try_into().unwrap()) as usize);
            }
            fields.insert(name, (ty, offset, shape));
        }
        let get = |name: &str, ty: u8, size: usize| -> Result<(&[u8], Vec<usize>), BrdfError> {
            let (t, off, shape) = fields
                .get(name)
                .ok_or_else(|| bad(&format!("no field {name}")))?;
            if *t != ty {
                return Err(bad(&format!("field {name} has type {t}, expected {ty}")));
            }
            let count: usize = shape.iter().product();
            let data = bytes
                .get(*off..off + count * size)
                .ok_or_else(|| bad(&format!("field {name} runs past the end")))?;
            Ok((data, shape.clone()))
        };
        let f32s = |d: &[u8]| {
            d.chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                .collect::<Vec<f32>>()
        };
        let axis = |name: &str| -> Result<Vec<f32>, BrdfError> {
            let (d, shape) = get(name, DTYPE_F32, 4)?;
            if shape.len() != 2 || shape[0] != 1 {
                return Err(bad(&format!("{name} must have shape (1, n)")));
            }
            Ok(f32s(d))
        };
        let (phi_d, theta_d, theta_h) = (axis("phi_d")?, axis("theta_d")?, axis("theta_h")?);
        let (w, wshape) = get("wvls", DTYPE_U16, 2)?;
        if wshape != [WAVELENGTHS] {
            return Err(bad("wvls must have shape (5,)"));
        }
        let wavelengths_nm = w
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes(c.try_into().unwrap()))
            .collect();
        let (m, mshape) = get("M", DTYPE_F32, 4)?;
        let expect = [phi_d.len(), theta_d.len(), theta_h.len(), WAVELENGTHS, 4, 4];
        if mshape != expect {
            return Err(bad(&format!("M has shape {mshape:?}, expected {expect:?}")));
        }
        let metadata = match get(METADATA_FIELD, DTYPE_U8, 1) {
            Ok((d, _)) => String::from_utf8_lossy(d).into_owned(),
            Err(_) => String::new(),
        };
        Ok(Self {
            phi_d,
            theta_d,
            theta_h,
            wavelengths_nm,
            m: f32s(m),
            metadata,
        })
    }

    /// The plugin's multilinear interpolation of `M` at `(φ_d, θ_d, θ_h, λ)`
    /// (Mitsuba's `Marginal2D::eval` with parameters: interval search, weights
    /// clamped to `[0, 1]`), in the stored frames and convention.
    pub fn lookup(&self, phi_d: f64, theta_d: f64, theta_h: f64, wavelength_nm: f64) -> Mueller {
        let wl: Vec<f32> = self.wavelengths_nm.iter().map(|&w| f32::from(w)).collect();
        let axes: [(&[f32], f64); 4] = [
            (&self.phi_d, phi_d),
            (&self.theta_d, theta_d),
            (&self.theta_h, theta_h),
            (&wl, wavelength_nm),
        ];
        let dims = [
            self.phi_d.len(),
            self.theta_d.len(),
            self.theta_h.len(),
            self.wavelengths_nm.len(),
        ];
        let cells: Vec<(usize, f64)> = axes.iter().map(|(v, x)| interval(v, *x)).collect();
        let mut out = [[0.0; 4]; 4];
        for corner in 0..16usize {
            let mut weight = 1.0;
            let mut index = 0;
            for (a, &(i0, w1)) in cells.iter().enumerate() {
                let up = (corner >> a) & 1 == 1;
                weight *= if up { w1 } else { 1.0 - w1 };
                let i = if up { (i0 + 1).min(dims[a] - 1) } else { i0 };
                index = index * dims[a] + i;
            }
            if weight == 0.0 {
                continue;
            }
            let base = index * 16;
            for (k, x) in out.iter_mut().flatten().enumerate() {
                *x += weight * f64::from(self.m[base + k]);
            }
        }
        out
    }

    /// What the plugin's eval returns for light direction `wi` and viewer
    /// direction `wo`, **before** its rotation into Mitsuba's implicit
    /// Stokes bases and **without** its `cos θ_i` factor: the interpolated
    /// matrix in the frames `x = normalize(ω_i × ω_o)` (Mitsuba's sign of
    /// `V`), `M00` clamped at 0; zero below the horizon and where the
    /// plugin gets NaN ([`rusinkiewicz`]).
    pub fn eval_vectors(&self, wi: Vec3, wo: Vec3, wavelength_nm: f64) -> Mueller {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return [[0.0; 4]; 4];
        }
        let Some(r) = rusinkiewicz(wi, wo) else {
            return [[0.0; 4]; 4];
        };
        let mut m = self.lookup(r.phi_d, r.theta_d, r.theta_h, wavelength_nm);
        if m[0][0].is_nan() {
            return [[0.0; 4]; 4];
        }
        m[0][0] = m[0][0].max(0.0);
        m
    }
}

/// Mitsuba's `find_interval` and clamped linear weight on one axis:
/// `(i, w)` with `i` the number of nodes `1..n−1` below `x` and `w` the
/// weight of node `i + 1`.
fn interval(v: &[f32], x: f64) -> (usize, f64) {
    let n = v.len();
    if n == 1 {
        return (0, 0.0);
    }
    let xf = x as f32;
    let i = v[1..n - 1].iter().take_while(|&&a| a < xf).count();
    let (p0, p1) = (f64::from(v[i]), f64::from(v[i + 1]));
    (i, ((x - p0) / (p1 - p0)).clamp(0.0, 1.0))
}

/// The export as `tensor_file` bytes ([`build`], [`MitsubaTable::to_bytes`]):
/// pure, for the CLI and the service.
pub fn mitsuba_bytes(table: &Table, opts: &MitsubaOptions) -> Result<Vec<u8>, BrdfError> {
    Ok(build(table, opts)?.to_bytes())
}

/// Agreement of an export with its table at random direction pairs.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ResamplingError {
    /// Direction pairs × wavelengths compared.
    pub samples: usize,
    /// `max |Δ(f cos θ_i)|` over all 16 elements (1/sr).
    pub max_abs: f64,
    /// `max f11 cos θ_i` over the samples (1/sr).
    pub max_f11_cos: f64,
    /// `max_abs / max_f11_cos`.
    pub relative: f64,
    /// The same over the pairs with both polar angles at most
    /// [`INNER_THETA_DEG`] (same denominator): without the cells next to
    /// the horizon, where the error of a linear interpolant is largest
    /// (docs/mitsuba.md, "Grid and accuracy").
    pub relative_within_80_deg: f64,
}

/// Polar angle (deg) bounding the inner region of
/// [`ResamplingError::relative_within_80_deg`].
pub const INNER_THETA_DEG: f64 = 80.0;

/// Direction pairs of the resampling check that `polbrdf export --format
/// mitsuba` prints and the service sends as `X-Polbrdf-Resampling-Error`
/// ([`resampling_error`] with [`CHECK_SEED`]), so that both report the
/// same number for the same table.
pub const CHECK_PAIRS: usize = 2000;
/// Seed of that check.
pub const CHECK_SEED: u64 = 1;

/// Relative resampling error ([`ResamplingError::relative`]) above which the
/// export warns (CLI stderr, the service's `X-Polbrdf-Warning`).
pub const RESAMPLING_WARNING: f64 = 0.01;

/// `θ_d`, `θ_h` nodes of the finer grid the warning suggests: 1° steps,
/// which quarter the error away from the horizon (docs/mitsuba.md).
pub const FINER_THETA_NODES: usize = 91;

/// The caveats of an export, one sentence each (ASCII, so that they fit in
/// an HTTP header): the resampling error when it exceeds
/// [`RESAMPLING_WARNING`], with `finer_grid` saying how the caller's front
/// door asks for a finer grid; and, for a mirror base, the specular delta
/// left out of the file and what a renderer must add for it.
pub fn export_warnings(table: &Table, check: &ResamplingError, finer_grid: &str) -> Vec<String> {
    let mut out = Vec::new();
    if check.relative.is_nan() || check.relative > RESAMPLING_WARNING {
        out.push(format!(
            "the Mitsuba grid reproduces the table to {:.1e} of max f11 cos(theta_i) (resampling_check.relative, over {} %), {:.1e} with both directions within {INNER_THETA_DEG} deg of the normal: the error sits next to the horizon; a finer grid lowers it: {finer_grid} (docs/mitsuba.md)",
            check.relative,
            RESAMPLING_WARNING * 100.0,
            check.relative_within_80_deg,
        ));
    }
    if table.wavelengths.iter().any(|w| w.specular.is_some()) {
        out.push(if has_top_interface(table) {
            "the table has a smooth top interface; its specular reflection is a delta that cannot be represented in a measured_polarized table and is left out: only the diffuse BRDF is in the file. A renderer must add a delta lobe at the mirror direction with weight S = M(r_1n(mu_i)), the Fresnel Mueller matrix of air over the binder (docs/conventions.md sec. 8; polbrdf eval's specular; docs/mitsuba.md)".into()
        } else {
            "the table's base is a mirror; its specular delta cannot be represented in a measured_polarized table and is left out: only the diffuse BRDF is in the file. A renderer must add a delta lobe at the mirror direction with weight S = exp(-2 tau/mu_i) M_F(mu_i) (docs/conventions.md sec. 6; polbrdf eval's specular; docs/mitsuba.md)".into()
        });
    }
    out
}

/// Whether the table's spec has a top interface (whose reflection is then
/// its delta term, conventions §8).
fn has_top_interface(table: &Table) -> bool {
    table.metadata.spec.get("top_interface").is_some()
}

/// A small deterministic generator (SplitMix64) for sampling directions.
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// Next uniform number in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A direction uniform in solid angle over the upper hemisphere.
    pub fn hemisphere(&mut self) -> Vec3 {
        let z = 1.0 - self.uniform();
        let p = 2.0 * PI * self.uniform();
        let r = (1.0 - z * z).max(0.0).sqrt();
        [r * p.cos(), r * p.sin(), z]
    }
}

/// Compare the plugin's interpolation of `mt` ([`MitsubaTable::eval_vectors`])
/// with the table itself (in the same frames, (R2)) at `pairs` random
/// direction pairs (uniform in solid angle, seeded) at each export
/// wavelength, on the quantity the plugin returns, `f cos θ_i`.
pub fn resampling_error(
    table: &Table,
    mt: &MitsubaTable,
    pairs: usize,
    seed: u64,
) -> Result<ResamplingError, BrdfError> {
    let mut rng = SplitMix64(seed);
    let mut max_abs = 0.0f64;
    let mut max_abs_inner = 0.0f64;
    let mut max_f11 = 0.0f64;
    let mut samples = 0;
    let cos_inner = INNER_THETA_DEG.to_radians().cos();
    for _ in 0..pairs {
        let (wi, wo) = (rng.hemisphere(), rng.hemisphere());
        let x = cross(wi, wo);
        if norm(x) < 1e-9 {
            continue;
        }
        let x = normalize(x);
        let inner = wi[2] >= cos_inner && wo[2] >= cos_inner;
        for &w in &mt.wavelengths_nm {
            let w = f64::from(w);
            let exact = to_mitsuba(&table.eval_vectors(wi, wo, Some(w))?, wi, wo, x)?;
            let got = mt.eval_vectors(wi, wo, w);
            for (a, b) in exact.iter().flatten().zip(got.iter().flatten()) {
                let d = (a - b).abs() * wi[2];
                max_abs = max_abs.max(d);
                if inner {
                    max_abs_inner = max_abs_inner.max(d);
                }
            }
            max_f11 = max_f11.max(exact[0][0] * wi[2]);
            samples += 1;
        }
    }
    Ok(ResamplingError {
        samples,
        max_abs,
        max_f11_cos: max_f11,
        relative: max_abs / max_f11,
        relative_within_80_deg: max_abs_inner / max_f11,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::PolarGrid;
    use crate::brdf::angles::incident_frame;
    use crate::brdf::angles::outgoing_frame;

    fn some_mueller() -> Mueller {
        let mut m = [[0.0; 4]; 4];
        for (i, row) in m.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                *x = 0.3 + 0.17 * i as f64 - 0.11 * j as f64 + 0.07 * (i * j) as f64;
            }
        }
        m
    }

    fn table(wavelengths: &[f64], base: &str) -> Table {
        let wl = if wavelengths.is_empty() {
            String::new()
        } else {
            format!(r#""wavelengths_nm": {wavelengths:?},"#)
        };
        let text = format!(
            r#"{{"layers": [{{"optical_thickness": 0.5,
                 "scatterer": {{"rayleigh": {{"albedo": 0.9}}}}}}],
                "base": {base}, {wl}
                "solver": {{"streams": 4}}}}"#
        );
        let spec = crate::material::parse(&text).unwrap();
        Table::from_spec(&spec, PolarGrid::graded(12).unwrap()).unwrap()
    }

    /// (R1) and (R3) are inverse to each other, the x-axis of (R3) is
    /// `normalize(ω_i × ω_o)`, and (R1) does not change when both
    /// directions turn about the normal (the plugin turns them first).
    #[test]
    fn rusinkiewicz_map_and_inverse() {
        let mut rng = SplitMix64(7);
        for _ in 0..500 {
            let r = Rusinkiewicz {
                phi_d: PI * (2.0 * rng.uniform() - 1.0),
                theta_d: 0.01 + 1.55 * rng.uniform(),
                theta_h: 0.01 + 1.55 * rng.uniform(),
            };
            let (wi, wo, x) = directions_of(&r);
            for w in [wi, wo, x] {
                assert!((norm(w) - 1.0).abs() < 1e-14);
            }
            let c = normalize(cross(wi, wo));
            assert!(norm(sub(c, x)) < 1e-12, "{r:?}");
            let back = rusinkiewicz(wi, wo).unwrap();
            assert!((back.theta_h - r.theta_h).abs() < 1e-12);
            assert!((back.theta_d - r.theta_d).abs() < 1e-12);
            assert!((back.phi_d - r.phi_d).abs() < 1e-12, "{r:?} {back:?}");
            // Turning both directions about z leaves the angles unchanged.
            let a = 2.0 * PI * rng.uniform();
            let (s, co) = a.sin_cos();
            let rot = |w: Vec3| [co * w[0] - s * w[1], s * w[0] + co * w[1], w[2]];
            let turned = rusinkiewicz(rot(wi), rot(wo)).unwrap();
            assert!((turned.phi_d - r.phi_d).abs() < 1e-12);
            assert!((turned.theta_h - r.theta_h).abs() < 1e-12);
        }
        // θ_d = 0: the limit axis is still perpendicular to ω_i = ω_o = h.
        let (wi, wo, x) = directions_of(&Rusinkiewicz {
            phi_d: 0.4,
            theta_d: 0.0,
            theta_h: 0.3,
        });
        assert!(norm(sub(wi, wo)) < 1e-15 && dot(x, wi).abs() < 1e-15);
        assert!(rusinkiewicz(wi, wo).is_none());
        // Reciprocity: swapping the directions shifts φ_d by π.
        let (wi, wo, _) = directions_of(&Rusinkiewicz {
            phi_d: 0.4,
            theta_d: 0.5,
            theta_h: 0.3,
        });
        let sw = rusinkiewicz(wo, wi).unwrap();
        assert!((sw.phi_d - (0.4 - PI)).abs() < 1e-12);
    }

    /// The frame rotations of (R2) are orthogonal (`L Lᵀ = 1`), leave the
    /// unpolarized-in/intensity-out element `M00` unchanged, and `flip_v`
    /// is an involution that changes only the V row and column.
    #[test]
    fn frame_conversion_identities() {
        let mut rng = SplitMix64(11);
        let m = some_mueller();
        for _ in 0..200 {
            let (wi, wo) = (rng.hemisphere(), rng.hemisphere());
            let x = normalize(cross(wi, wo));
            let g = to_mitsuba(&m, wi, wo, x).unwrap();
            assert!((g[0][0] - m[0][0]).abs() < 1e-15);
            assert!((g[3][3] - m[3][3]).abs() < 1e-12);
            // The rotation of each side is orthogonal: row 0 norm over the
            // Q, U columns and the Q, U norm of column 0 are kept.
            let n_row = m[0][1].hypot(m[0][2]);
            assert!((g[0][1].hypot(g[0][2]) - n_row).abs() < 1e-12);
            let n_col = m[1][0].hypot(m[2][0]);
            assert!((g[1][0].hypot(g[2][0]) - n_col).abs() < 1e-12);
            assert!((g[0][3] + m[0][3]).abs() < 1e-15 && (g[3][0] + m[3][0]).abs() < 1e-15);
        }
        for s in [0.3, -1.2, 2.0] {
            let l = rotation(s);
            let llt = mul(&l, &crate::physics::stokes::transpose(&l));
            for (i, row) in llt.iter().enumerate() {
                for (j, x) in row.iter().enumerate() {
                    let id = if i == j { 1.0 } else { 0.0 };
                    assert!((x - id).abs() < 1e-15);
                }
            }
        }
        assert_eq!(flip_v(&flip_v(&m)), m);
    }

    /// `rebase` is Mitsuba's `rotate_mueller_basis` and agrees with
    /// [`rotate_to_frames`] when starting from the meridian frames.
    #[test]
    fn rebase_matches_rotate_to_frames() {
        let (ti, pi, to, po) = (35.0f64, 20.0f64, 60.0f64, 250.0f64);
        let wi = crate::brdf::angles::direction(ti, pi);
        let wo = crate::brdf::angles::direction(to, po);
        let (xi, _) = incident_frame(ti, pi);
        let (xo, _) = outgoing_frame(to, po);
        let x = normalize(cross(wi, wo));
        let m = some_mueller();
        let a = rotate_to_frames(&m, wi, wo, x, x).unwrap();
        let b = rebase(&m, scaled(wi, -1.0), xi, x, wo, xo, x);
        for i in 0..4 {
            for j in 0..4 {
                assert!((a[i][j] - b[i][j]).abs() < 1e-14);
            }
        }
    }

    /// Five whole-nm wavelengths pass; other counts and fractional
    /// wavelengths are errors naming `--resample-wavelengths`, which picks
    /// five evenly spaced whole-nm wavelengths inside the range.
    #[test]
    fn wavelength_policy() {
        let t5 = table(&[450.0, 500.0, 550.0, 600.0, 650.0], r#""black""#);
        assert_eq!(
            export_wavelengths(&t5, false).unwrap(),
            (vec![450, 500, 550, 600, 650], false)
        );
        let t2 = table(&[450.5, 649.5], r#""black""#);
        let e = export_wavelengths(&t2, false).unwrap_err().to_string();
        assert!(
            e.contains("five") && e.contains("--resample-wavelengths"),
            "{e}"
        );
        assert_eq!(
            export_wavelengths(&t2, true).unwrap(),
            (vec![451, 501, 550, 600, 649], true)
        );
        let narrow = table(&[500.0, 503.0], r#""black""#);
        assert!(export_wavelengths(&narrow, true).is_err());
        let free = table(&[], r#""black""#);
        assert!(export_wavelengths(&free, true).is_err());
    }

    /// The tensor_file bytes parse back (header layout, offsets aligned,
    /// shapes, dtypes), nodes hold the table converted by (R2), the plugin's
    /// interpolation reproduces nodes exactly, and nodes below the horizon
    /// are finite.
    #[test]
    fn tensor_round_trip_and_nodes() {
        let t = table(
            &[450.0, 500.0, 550.0, 600.0, 650.0],
            r#"{"lambertian": {"albedo": 0.5}}"#,
        );
        let opts = MitsubaOptions {
            phi_d: 9,
            theta_d: 7,
            theta_h: 7,
            ..Default::default()
        };
        let mt = build(&t, &opts).unwrap();
        let bytes = mt.to_bytes();
        assert_eq!(&bytes[..12], MAGIC);
        assert_eq!(&bytes[12..14], &[1, 0]);
        assert_eq!(u32::from_le_bytes(bytes[14..18].try_into().unwrap()), 6);
        // First field: "phi_d", rank 2, float32, offset, shape (1, 9).
        assert_eq!(u16::from_le_bytes(bytes[18..20].try_into().unwrap()), 5);
        assert_eq!(&bytes[20..25], b"phi_d");
        assert_eq!(u16::from_le_bytes(bytes[25..27].try_into().unwrap()), 2);
        assert_eq!(bytes[27], DTYPE_F32);
        let off = u64::from_le_bytes(bytes[28..36].try_into().unwrap()) as usize;
        assert_eq!(off % ALIGN, 0);
        assert_eq!(u64::from_le_bytes(bytes[44..52].try_into().unwrap()), 9);
        assert_eq!(
            f32::from_le_bytes(bytes[off..off + 4].try_into().unwrap()),
            -PI as f32
        );
        let back = MitsubaTable::from_bytes(&bytes).unwrap();
        assert_eq!(back, mt);
        let meta: Value = serde_json::from_str(&back.metadata).unwrap();
        assert!(meta["specular_delta"].as_str().unwrap().starts_with("none"));
        assert!(mt.m.iter().all(|x| x.is_finite()));
        // A node above the horizon: φ_d = 45°, θ_d = 30°, θ_h = 15°.
        let r = Rusinkiewicz {
            phi_d: f64::from(mt.phi_d[5]),
            theta_d: f64::from(mt.theta_d[2]),
            theta_h: f64::from(mt.theta_h[1]),
        };
        let (wi, wo, x) = directions_of(&r);
        let exact = to_mitsuba(&t.eval_vectors(wi, wo, Some(550.0)).unwrap(), wi, wo, x).unwrap();
        let node = mt.lookup(r.phi_d, r.theta_d, r.theta_h, 550.0);
        for i in 0..4 {
            for j in 0..4 {
                assert!(
                    (node[i][j] - exact[i][j]).abs() <= 1e-6 * exact[0][0],
                    "{i}{j}: {} {}",
                    node[i][j],
                    exact[i][j]
                );
            }
        }
        // The same values through the plugin-like eval of the directions.
        let via = mt.eval_vectors(wi, wo, 550.0);
        assert!((via[0][0] - exact[0][0]).abs() <= 1e-5 * exact[0][0]);
        // Below the horizon: zero from the plugin, finite in the file.
        assert_eq!(mt.eval_vectors([0.5, 0.0, -0.1], wo, 550.0), [[0.0; 4]; 4]);
    }

    /// The below-horizon policy: `Extend` holds the table at the node's
    /// directions moved up to `μ_floor`, `Zero` holds zeros; nodes above the
    /// horizon agree, and a node exactly on the horizon is evaluated at
    /// `μ_floor`, not at the divergent double-grazing value.
    #[test]
    fn below_horizon_policies() {
        let t = table(
            &[450.0, 500.0, 550.0, 600.0, 650.0],
            r#"{"lambertian": {"albedo": 0.5}}"#,
        );
        let mut opts = MitsubaOptions {
            phi_d: 5,
            theta_d: 7,
            theta_h: 7,
            ..Default::default()
        };
        let floor = node_mu_floor(&opts);
        assert!((floor - (15f64 / 4.0).to_radians().sin()).abs() < 1e-15);
        let ext = build(&t, &opts).unwrap();
        opts.below_horizon = BelowHorizon::Zero;
        let zero = build(&t, &opts).unwrap();
        let per = WAVELENGTHS * 16;
        let node = |mt: &MitsubaTable, p: usize, d: usize, k: usize| {
            let at = ((p * 7 + d) * 7 + k) * per + 2 * 16; // 550 nm
            mt.m[at..at + 16].to_vec()
        };
        let (mut above, mut under) = (0, 0);
        for p in 0..5 {
            for d in 0..7 {
                for k in 0..7 {
                    // The f64 nodes the export used (the file holds them as f32).
                    let r = Rusinkiewicz {
                        phi_d: uniform(-PI, PI, 5)[p],
                        theta_d: uniform(0.0, FRAC_PI_2, 7)[d],
                        theta_h: uniform(0.0, FRAC_PI_2, 7)[k],
                    };
                    let (wi, wo, _) = directions_of(&r);
                    let is_under = wi[2] < -HORIZON_EPS || wo[2] < -HORIZON_EPS;
                    let (a, b) = (node(&ext, p, d, k), node(&zero, p, d, k));
                    if !is_under {
                        assert_eq!(a, b);
                        above += 1;
                        continue;
                    }
                    under += 1;
                    assert!(b.iter().all(|&x| x == 0.0));
                    if wi[0].hypot(wi[1]) < 1e-9 || wo[0].hypot(wo[1]) < 1e-9 {
                        continue;
                    }
                    let (li, lo) = (lift(wi, floor), lift(wo, floor));
                    assert!((li[2] - floor).abs() < 1e-15 || (lo[2] - floor).abs() < 1e-15);
                    let x = normalize(cross(li, lo));
                    let f = to_mitsuba(&t.eval_vectors(li, lo, Some(550.0)).unwrap(), li, lo, x)
                        .unwrap();
                    for (u, v) in a.iter().zip(f.iter().flatten()) {
                        assert!((f64::from(*u) - v).abs() <= 1e-6 * f[0][0], "{p} {d} {k}");
                    }
                }
            }
        }
        assert!(above > 50 && under > 50, "{above} {under}");
        // θ_h = 90°, φ_d = −90°: both directions on the horizon.
        let (wi, wo, _) = directions_of(&Rusinkiewicz {
            phi_d: uniform(-PI, PI, 5)[1],
            theta_d: uniform(0.0, FRAC_PI_2, 7)[2],
            theta_h: FRAC_PI_2,
        });
        assert!(wi[2].abs() < 1e-15 && wo[2].abs() < 1e-15);
        let corner = node(&ext, 1, 2, 6);
        let (li, lo) = (lift(wi, floor), lift(wo, floor));
        let f = t.eval_vectors(li, lo, Some(550.0)).unwrap();
        assert!((f64::from(corner[0]) - f[0][0]).abs() <= 1e-6 * f[0][0]);
        let divergent = t.eval_vectors(wi, wo, Some(550.0)).unwrap();
        assert!(divergent[0][0] > 100.0 * f[0][0]);
    }

    /// A mirror base is noted in the metadata (its delta is not in `M`).
    #[test]
    fn mirror_base_is_noted() {
        let t = table(
            &[450.0, 500.0, 550.0, 600.0, 650.0],
            r#"{"fresnel": {"material": {"n": 1.5, "k": 0.0}}}"#,
        );
        let opts = MitsubaOptions {
            phi_d: 3,
            theta_d: 2,
            theta_h: 2,
            ..Default::default()
        };
        let mt = build(&t, &opts).unwrap();
        let meta: Value = serde_json::from_str(&mt.metadata).unwrap();
        assert!(
            meta["specular_delta"]
                .as_str()
                .unwrap()
                .starts_with("NOT INCLUDED")
        );
    }

    /// The warnings: the resampling error only over 1 % (ASCII, naming the
    /// value and the caller's remedy), the mirror's delta whenever the base
    /// is a mirror; and the inner error never exceeds the whole
    /// hemisphere's (same denominator, a subset of the samples).
    #[test]
    fn export_warnings_follow_the_check_and_the_base() {
        let five = [450.0, 500.0, 550.0, 600.0, 650.0];
        let lambertian = table(&five, r#"{"lambertian": {"albedo": 0.5}}"#);
        let mirror = table(&five, r#"{"fresnel": {"material": {"n": 1.5, "k": 0.0}}}"#);
        let coarse = MitsubaOptions {
            phi_d: 9,
            theta_d: 7,
            theta_h: 7,
            ..Default::default()
        };
        let check =
            resampling_error(&lambertian, &build(&lambertian, &coarse).unwrap(), 300, 1).unwrap();
        assert!(check.relative > RESAMPLING_WARNING, "{check:?}");
        assert!(check.relative_within_80_deg <= check.relative, "{check:?}");
        assert!(check.relative_within_80_deg > 0.0, "{check:?}");
        let w = export_warnings(&lambertian, &check, "--finer");
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains(&format!("{:.1e}", check.relative)),
            "{}",
            w[0]
        );
        assert!(w[0].contains("--finer") && w[0].is_ascii(), "{}", w[0]);
        let under = ResamplingError {
            relative: RESAMPLING_WARNING,
            ..check.clone()
        };
        assert!(export_warnings(&lambertian, &under, "--finer").is_empty());
        let w = export_warnings(&mirror, &under, "--finer");
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("specular delta") && w[0].contains("exp(-2 tau/mu_i)"));
        assert!(w[0].is_ascii());
        assert_eq!(export_warnings(&mirror, &check, "--finer").len(), 2);
    }
}
