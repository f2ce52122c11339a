//! What a render scene needs of each sphere's material (issue 16, "Whole
//! scenes"; docs/render.md, "Materials and `scene plan`"): the channel
//! wavelengths, the Stokes part of the BRDF and the solver tolerance, each
//! with the reason, the reduced spec that asks for exactly that
//! (`needs`, docs/spec.md), and its estimated cost against the full
//! request. Pure: the caller reads the spec files (`cli::scene`).
//!
//! **The Stokes rule** follows the integrator (`render::integrator`,
//! `Scene::shade_sphere`): light arrives at a sphere from the lights (shadow
//! rays, at every vertex) and, while fewer than `max_bounces` indirect
//! bounces were made, along one cosine-weighted ray and the mirror ray,
//! which see the environment, a plane or another sphere. Planes are
//! depolarizing Lambertian (`[I, 0, 0, 0]` in every frame) and a convex
//! sphere never sees itself, so the light arriving at a sphere is
//! unpolarized unless a light is polarized, or (with `max_bounces ≥ 1`) the
//! environment is polarized or another sphere exists (its BRDF polarizes
//! what it reflects). Then only the first column of its Mueller BRDF (the
//! response to unpolarized light, all four outgoing components) is used:
//! `unpolarized_in`. The camera's polarizer acts on the radiance arriving at
//! the camera, after the last interaction (`Scene::pixel`), so it needs the
//! outgoing Stokes vector, which `unpolarized_in` keeps; it changes nothing.
//! `intensity` never applies: the renderer always writes the DOP and the
//! Stokes image, which need every outgoing component.

use super::scene::{EnvironmentDesc, LightDesc, SceneDesc};
use crate::material::Spec;
use crate::plan::StreamPolicy;
use serde::Serialize;
use serde_json::{Value, json};

/// The Stokes part of the BRDF a sphere needs (`needs.stokes`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StokesNeed {
    /// The whole 4×4 Mueller matrix.
    Full,
    /// Its first column: the response to unpolarized incident light.
    UnpolarizedIn,
}

impl StokesNeed {
    /// The `needs.stokes` value.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Full => "full",
            Self::UnpolarizedIn => "unpolarized_in",
        }
    }
}

/// One need and why the scene implies it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Need<T> {
    /// The value.
    pub value: T,
    /// Why.
    pub why: String,
}

/// Whether a Stokes vector carries polarization (`Q`, `U` or `V` ≠ 0).
pub fn is_polarized(s: [f64; 4]) -> bool {
    s[1..].iter().any(|&x| x != 0.0)
}

/// The Stokes need of sphere `k` (module doc, "The Stokes rule").
pub fn stokes_need(desc: &SceneDesc, k: usize) -> Need<StokesNeed> {
    let full = |why: String| Need {
        value: StokesNeed::Full,
        why,
    };
    for (j, l) in desc.lights.iter().enumerate() {
        let (kind, s) = match l {
            LightDesc::Directional { stokes, .. } => ("directional", *stokes),
            LightDesc::Point { stokes, .. } => ("point", *stokes),
        };
        if is_polarized(s) {
            return full(format!(
                "lights[{j}].{kind}.stokes {s:?} is polarized (Q, U or V ≠ 0) and lights the \
                 sphere directly"
            ));
        }
    }
    if desc.max_bounces == 0 {
        return Need {
            value: StokesNeed::UnpolarizedIn,
            why: "max_bounces 0: only the lights reach the sphere (shadow rays), and every light \
                  is unpolarized; the environment and other surfaces need an indirect ray"
                .into(),
        };
    }
    if let Some(EnvironmentDesc::Uniform {
        stokes: Some(s), ..
    }) = &desc.environment
        && is_polarized(*s)
    {
        return full(format!(
            "environment.uniform.stokes {s:?} is polarized and reaches the sphere along its \
             indirect rays (max_bounces {} ≥ 1)",
            desc.max_bounces
        ));
    }
    if let Some(j) = (0..desc.spheres.len()).find(|&j| j != k) {
        return full(format!(
            "{} other sphere(s) (e.g. spheres[{j}]) with max_bounces {} ≥ 1: sphere→sphere \
             paths exist, and light leaving a sphere is polarized by its BRDF",
            desc.spheres.len() - 1,
            desc.max_bounces
        ));
    }
    Need {
        value: StokesNeed::UnpolarizedIn,
        why: "every light and the environment are unpolarized and the only other surfaces \
              (floor, walls) are depolarizing Lambertian, so all light arriving at the sphere \
              is unpolarized; a camera polarizer acts after the last interaction and needs only \
              the outgoing Stokes vector, which unpolarized_in keeps"
            .into(),
    }
}

/// The wavelengths need: the image's channel wavelengths
/// (`render::channels_from`); `None` is one wavelength-free channel, or,
/// with `first_unread`, channels decided by the first sphere's table,
/// which was not read.
pub fn wavelengths_need(
    desc: &SceneDesc,
    channels: &[Option<f64>],
    first_unread: bool,
) -> Need<Option<Vec<f64>>> {
    let value: Option<Vec<f64>> = channels.iter().copied().collect();
    let why = match (&desc.wavelengths_nm, &value) {
        (Some(_), _) => "the scene's wavelengths_nm: the channels of the image".to_string(),
        (None, _) if first_unread => "the scene gives no wavelengths_nm: the first sphere's table \
                                      decides the channels (its three wavelengths if it has \
                                      three, else its first); not read for this plan"
            .to_string(),
        (None, Some(_)) => "the scene gives no wavelengths_nm: the channels come from the first \
                            sphere (its three wavelengths if it has three, else its first)"
            .to_string(),
        (None, None) => "one wavelength-free channel (the first sphere is wavelength-free)".into(),
    };
    Need { value, why }
}

/// The tolerance need: the scene's `tolerance`, else the spec's own solver
/// settings (`None`).
pub fn tolerance_need(desc: &SceneDesc) -> Need<Option<f64>> {
    match desc.tolerance {
        Some(t) => Need {
            value: Some(t),
            why: format!(
                "the scene's tolerance {t:e}: solver.tolerance of every material (explicit \
                 solver.streams dropped, since they would win)"
            ),
        },
        None => Need {
            value: None,
            why: "the scene gives no tolerance: the spec's own solver settings".into(),
        },
    }
}

/// The needs of one material sphere.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MaterialNeeds {
    /// Channel wavelengths (`None`: wavelength-free).
    pub wavelengths_nm: Need<Option<Vec<f64>>>,
    /// The Stokes part.
    pub stokes: Need<StokesNeed>,
    /// The solver tolerance (`None`: the spec's own settings).
    pub tolerance: Need<Option<f64>>,
}

/// The needs of sphere `k` in an image of these channels
/// ([`wavelengths_need`] for `first_unread`).
pub fn material_needs(
    desc: &SceneDesc,
    k: usize,
    channels: &[Option<f64>],
    first_unread: bool,
) -> MaterialNeeds {
    MaterialNeeds {
        wavelengths_nm: wavelengths_need(desc, channels, first_unread),
        stokes: stokes_need(desc, k),
        tolerance: tolerance_need(desc),
    }
}

/// The reduced request: the spec as written with the scene's wavelengths
/// (a wavelength-free image keeps the spec's), the scene's tolerance (then
/// without `solver.streams` and `needs.error_estimate: false`, which a
/// tolerance overrides or refuses) and `needs.stokes` unless `full`.
pub fn reduced_spec(spec: &Value, needs: &MaterialNeeds) -> Value {
    let mut s = spec.clone();
    let obj = s.as_object_mut().expect("a spec is an object");
    if let Some(w) = &needs.wavelengths_nm.value {
        obj.insert("wavelengths_nm".into(), json!(w));
    }
    if let Some(t) = needs.tolerance.value {
        let solver = obj
            .entry("solver")
            .or_insert_with(|| json!({}))
            .as_object_mut()
            .expect("solver is an object");
        solver.remove("streams");
        solver.insert("tolerance".into(), json!(t));
        if let Some(n) = obj.get_mut("needs").and_then(Value::as_object_mut) {
            n.remove("error_estimate");
        }
    }
    if needs.stokes.value != StokesNeed::Full {
        let n = obj
            .entry("needs")
            .or_insert_with(|| json!({}))
            .as_object_mut()
            .expect("needs is an object");
        n.insert("stokes".into(), json!(needs.stokes.value.as_str()));
    }
    s
}

// ---------------------------------------------------------------------
// Cost model.

/// Measured solves of the seed's TiO2 layer (r = 0.2 µm, 550 nm, τ = 1,
/// black base) on the 11-angle probe grid: `(streams, solver's estimate,
/// true max error of f11)`, both relative to max f11. 4, 8, 16, 32 streams:
/// docs/accuracy.md (true errors against 96 streams at commit 34c57bc,
/// estimates at solver version 5); 6, 12, 24 streams (the other levels of
/// the tolerance ladder): `tests/tolerance.rs` at solver version 5, against
/// 64 streams. The model's tolerance → streams.
pub const MEASURED_ERRORS: [(usize, f64, f64); 7] = [
    (4, 9.1e-4, 2.5e-4),
    (6, 8.4e-5, 1.7e-5),
    (8, 8.5e-5, 2.7e-5),
    (12, 4.1e-6, 4.9e-7),
    (16, 4.3e-7, 1.7e-7),
    (24, 3.2e-8, 1.6e-8),
    (32, 3.0e-9, 2.9e-9),
];

/// Measured whole table jobs of the same layer (Mie, the solve of every
/// Fourier order and the synthesis, 51 × 51 × 61 directions, no error
/// estimate): `(streams, wall time in ms)`, `polbrdf bench table`,
/// docs/performance.md (quiet machine). The model's time of one solve.
pub const MEASURED_TIMES_MS: [(usize, f64); 4] = [(8, 32.8), (16, 60.2), (32, 232.8), (64, 1347.0)];

/// Asymptotic order of the method (docs/solver.md, "Error estimate"):
/// beyond 32 streams the model's errors fall by `2^6` per doubling.
const ORDER: i32 = 6;

/// Largest stream count the model lets a tolerance pick.
const MAX_MODEL_STREAMS: usize = crate::material::MAX_STREAMS;

/// Model time (ms) of one `n`-stream solve: log–log interpolation of
/// [`MEASURED_TIMES_MS`], extrapolated with the slope of the nearest
/// interval (below 8 streams that of 8–16, about `N^0.88`: the fixed part,
/// Mie and the synthesis, does not fall with the streams).
pub fn solve_time_ms(n: usize) -> f64 {
    let pts: Vec<(f64, f64)> = MEASURED_TIMES_MS
        .iter()
        .map(|&(s, t)| ((s as f64).ln(), t.ln()))
        .collect();
    let x = (n.max(1) as f64).ln();
    let k = pts
        .windows(2)
        .position(|w| x <= w[1].0)
        .unwrap_or(pts.len() - 2);
    let ((x0, y0), (x1, y1)) = (pts[k], pts[k + 1]);
    (y0 + (y1 - y0) * (x - x0) / (x1 - x0)).exp()
}

/// Model (estimate, true error) at `n` streams: the measured values, log–log
/// interpolated between measured stream counts, and `N^−6` (the method's
/// order) from the nearest end outside them.
fn model_errors(n: usize) -> (f64, f64) {
    let m = &MEASURED_ERRORS;
    if let Some(&(_, e, t)) = m.iter().find(|p| p.0 == n) {
        return (e, t);
    }
    let x = (n as f64).ln();
    if let Some(w) = m.windows(2).find(|w| n > w[0].0 && n < w[1].0) {
        let (x0, x1) = ((w[0].0 as f64).ln(), (w[1].0 as f64).ln());
        let f = (x - x0) / (x1 - x0);
        let lerp = |a: f64, b: f64| (a.ln() + f * (b.ln() - a.ln())).exp();
        return (lerp(w[0].1, w[1].1), lerp(w[0].2, w[1].2));
    }
    let end = if n < m[0].0 { m[0] } else { m[m.len() - 1] };
    let f = (n as f64 / end.0 as f64).powf(-f64::from(ORDER));
    (end.1 * f, end.2 * f)
}

/// The stream count a tolerance picks in the model: the first level of
/// `solver::accuracy::tolerance_ladder` (4, 6, 8, 12, …) whose estimate is
/// within `t` and whose last change (taken as the true error at `N/2`; at 4
/// streams the estimate, which reports the last change there,
/// docs/accuracy.md) is within 3 `t`, as
/// `solver::accuracy::reflection_to_tolerance` accepts a level.
pub fn model_streams_for_tolerance(t: f64) -> usize {
    let ladder = crate::solver::accuracy::tolerance_ladder(MAX_MODEL_STREAMS);
    for &n in &ladder {
        let (est, _) = model_errors(n);
        let last_change = if n == 4 { est } else { model_errors(n / 2).1 };
        if est <= t && last_change <= 3.0 * t {
            return n;
        }
    }
    *ladder.last().expect("MAX_MODEL_STREAMS ≥ 4")
}

/// The solves a stream policy runs per wavelength (stream counts): fixed
/// `N` with the estimate: `N/2, 3N/4, N`; without: `N`; a tolerance: 2
/// streams, then each level of the ladder up to the model's pick with its
/// estimate levels `N/2, 3N/4`, each stream count once (a level reuses
/// earlier solves, `solver::accuracy::reflection_to_tolerance`):
/// `2, 3, 4, 6, 8, 9, 12, 16, 18, 24, …`.
pub fn solves(policy: &StreamPolicy, error_estimate: bool) -> Vec<usize> {
    use crate::solver::accuracy::coarse_levels;
    match *policy {
        StreamPolicy::Fixed(n) => match coarse_levels(n).filter(|_| error_estimate) {
            Some((a, b)) => vec![a, b, n],
            None => vec![n],
        },
        StreamPolicy::Tolerance(t) => {
            let top = model_streams_for_tolerance(t);
            let mut out = vec![2];
            for n in crate::solver::accuracy::tolerance_ladder(top) {
                let (a, b) = coarse_levels(n).expect("n ≥ 4");
                for m in [a, b, n] {
                    if !out.contains(&m) {
                        out.push(m);
                    }
                }
            }
            out
        }
    }
}

/// Fraction of the table's stored Mueller elements a Stokes need keeps
/// (16 for full, the 4 of the first column for `unpolarized_in`).
pub fn stokes_bytes_factor(s: StokesNeed) -> f64 {
    match s {
        StokesNeed::Full => 1.0,
        StokesNeed::UnpolarizedIn => 4.0 / 16.0,
    }
}

/// Solve-time factor of a Stokes need: 1, measured as "not had yet"
/// (docs/solver.md: the vector solve needs all four components of the
/// response either way; a saving in the user-beam columns is not built).
/// Update when `needs.stokes` saves time and is measured.
pub fn stokes_time_factor(_s: StokesNeed) -> f64 {
    1.0
}

/// A request's model cost.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Cost {
    /// Wavelengths solved.
    pub wavelengths: usize,
    /// Streams of the answer (for a tolerance: the model's pick).
    pub streams: usize,
    /// Stream counts of the solves per wavelength.
    pub solves: Vec<usize>,
    /// The Stokes need.
    pub stokes: StokesNeed,
    /// Model solve time (ms of the seed's TiO2 table job,
    /// [`MEASURED_TIMES_MS`]).
    pub model_ms: f64,
    /// Model table size relative to one full wavelength on the same grid.
    pub model_table_units: f64,
}

/// The model cost of a (parsed) spec with a Stokes need: wavelengths ×
/// Stokes factor × Σ solve times of its stream policy.
pub fn cost(spec: &Spec, stokes: StokesNeed) -> Cost {
    let w = crate::plan::wavelengths(spec).len();
    let policy = crate::plan::stream_policy(spec);
    let solves = solves(&policy, spec.needs.error_estimate);
    let per: f64 = solves.iter().map(|&n| solve_time_ms(n)).sum();
    Cost {
        wavelengths: w,
        streams: *solves.last().expect("one solve"),
        solves,
        stokes,
        model_ms: w as f64 * stokes_time_factor(stokes) * per,
        model_table_units: w as f64 * stokes_bytes_factor(stokes),
    }
}

// ---------------------------------------------------------------------
// The whole scene.

/// A material sphere's spec as the scene gives it.
#[derive(Clone, Debug)]
pub struct MaterialInput {
    /// Where it came from: the spec file's path, or `"inline"`.
    pub source: String,
    /// The spec as written (a JSON object).
    pub json: Value,
    /// The same, parsed and validated (`material::parse`).
    pub spec: Spec,
}

/// Cost of one material: the full request against the reduced one.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CostComparison {
    /// The spec as written (no `needs` from the scene).
    pub full: Cost,
    /// The reduced spec.
    pub reduced: Cost,
    /// `reduced.model_ms / full.model_ms`.
    pub relative_time: f64,
    /// `reduced.model_table_units / full.model_table_units`.
    pub relative_table_size: f64,
}

/// One sphere of the plan.
#[derive(Clone, Debug, Serialize)]
pub struct PlanEntry {
    /// The sphere's `name`, else `spheres[k]`.
    pub name: String,
    /// Index in `spheres`.
    pub sphere: usize,
    /// `{"material": path or "inline"}` or `{"table": source}`.
    pub source: Value,
    /// What the scene needs of this sphere's BRDF.
    pub needs: MaterialNeeds,
    /// The reduced spec (material spheres only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spec: Option<Value>,
    /// Its cost against the full request (material spheres only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cost: Option<CostComparison>,
    /// An earlier sphere with the same reduced spec (solved once).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub same_as: Option<String>,
}

/// The plan of a scene.
#[derive(Clone, Debug, Serialize)]
pub struct ScenePlan {
    /// The image's channel wavelengths (`null`: wavelength-free).
    pub wavelengths_nm: Vec<Option<f64>>,
    /// One entry per sphere.
    pub materials: Vec<PlanEntry>,
    /// Whole scene over distinct specs: `{"full_model_ms",
    /// "reduced_model_ms", "relative_time", "full_table_units",
    /// "reduced_table_units", "relative_table_size"}`.
    pub total: Value,
}

/// The image's channel wavelengths: the scene's, else the first sphere's
/// (its spec's, sorted, or `first_table`, its table's).
pub fn scene_channels(
    desc: &SceneDesc,
    materials: &[Option<MaterialInput>],
    first_table: Option<&[Option<f64>]>,
) -> Vec<Option<f64>> {
    let first: Option<Vec<Option<f64>>> = match materials.first() {
        Some(Some(m)) => {
            let mut w = crate::plan::wavelengths(&m.spec);
            w.sort_by(|a, b| a.partial_cmp(b).expect("finite"));
            Some(w)
        }
        Some(None) => first_table.map(<[_]>::to_vec),
        None => None,
    };
    super::channels_from(desc.wavelengths_nm.as_deref(), first.as_deref())
}

/// Plan every sphere (`materials[k]`: sphere `k`'s spec, `None` for a
/// table sphere; `first_table`: the first sphere's table's wavelengths,
/// needed when it is a table, the scene gives no `wavelengths_nm` and
/// material spheres exist). A reduced spec that does not parse is an error naming
/// `spheres[k].material`.
pub fn plan_scene(
    desc: &SceneDesc,
    materials: &[Option<MaterialInput>],
    first_table: Option<&[Option<f64>]>,
) -> Result<ScenePlan, String> {
    let channels = scene_channels(desc, materials, first_table);
    let first_unread = desc.wavelengths_nm.is_none()
        && matches!(materials.first(), Some(None))
        && first_table.is_none();
    if first_unread && materials.iter().any(Option::is_some) {
        return Err(
            "spheres[0].table: its wavelengths decide the channels of the material \
                    spheres (the scene gives no wavelengths_nm), but it was not read"
                .into(),
        );
    }
    let mut entries: Vec<PlanEntry> = Vec::new();
    let (mut full_ms, mut red_ms, mut full_u, mut red_u) = (0.0, 0.0, 0.0, 0.0);
    let mut seen_full: Vec<String> = Vec::new();
    for (k, sp) in desc.spheres.iter().enumerate() {
        let name = super::scene::sphere_name(desc, k);
        let needs = material_needs(desc, k, &channels, first_unread);
        let Some(m) = materials.get(k).and_then(Option::as_ref) else {
            entries.push(PlanEntry {
                name,
                sphere: k,
                source: json!({"table": sp.table}),
                needs,
                spec: None,
                cost: None,
                same_as: None,
            });
            continue;
        };
        let reduced = reduced_spec(&m.json, &needs);
        let parsed = crate::material::parse(&reduced.to_string())
            .map_err(|e| format!("spheres[{k}].material (reduced for the scene): {e}"))?;
        let full = cost(&m.spec, StokesNeed::Full);
        let red = cost(&parsed, needs.stokes.value);
        let same_as = entries
            .iter()
            .find(|e| e.spec.as_ref() == Some(&reduced))
            .map(|e| e.name.clone());
        if same_as.is_none() {
            red_ms += red.model_ms;
            red_u += red.model_table_units;
        }
        let full_key = m.json.to_string();
        if !seen_full.contains(&full_key) {
            full_ms += full.model_ms;
            full_u += full.model_table_units;
            seen_full.push(full_key);
        }
        entries.push(PlanEntry {
            name,
            sphere: k,
            source: json!({"material": m.source}),
            needs,
            spec: Some(reduced),
            cost: Some(CostComparison {
                relative_time: red.model_ms / full.model_ms,
                relative_table_size: red.model_table_units / full.model_table_units,
                full,
                reduced: red,
            }),
            same_as,
        });
    }
    let ratio = |a: f64, b: f64| if b > 0.0 { json!(a / b) } else { Value::Null };
    Ok(ScenePlan {
        wavelengths_nm: channels,
        materials: entries,
        total: json!({
            "full_model_ms": full_ms,
            "reduced_model_ms": red_ms,
            "relative_time": ratio(red_ms, full_ms),
            "full_table_units": full_u,
            "reduced_table_units": red_u,
            "relative_table_size": ratio(red_u, full_u),
        }),
    })
}
