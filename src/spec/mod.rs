//! The material spec: the one input format of the CLI and the HTTP API
//! (docs/spec.md). Parsing with JSON paths in every error, validation of
//! ranges, and conversion into solver problems, one per wavelength.

pub mod canonical;
pub mod json;

use crate::physics::materials;
use serde::{Deserialize, Serialize};

/// A spec error: the JSON path of the problem and what is allowed there.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{path}: {message}")]
pub struct SpecError {
    /// JSON path, e.g. `layers[0].scatterer.mie.radius_um`.
    pub path: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

impl SpecError {
    pub(crate) fn new(path: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            message: message.into(),
        }
    }
}

/// The material spec (docs/spec.md).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    /// Layers, top to bottom.
    pub layers: Vec<LayerSpec>,
    /// Lower boundary.
    #[serde(default, deserialize_with = "one_key::<_, BaseSpec>")]
    pub base: BaseSpec,
    /// Vacuum wavelengths in nm; required when anything depends on wavelength.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wavelengths_nm: Option<Vec<f64>>,
    /// Numerical settings.
    #[serde(default)]
    pub solver: SolverSpec,
}

/// One homogeneous layer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerSpec {
    /// A number ≥ 0 or the string `"infinite"` (last layer only).
    pub optical_thickness: ThicknessSpec,
    /// What scatters in the layer.
    pub scatterer: ScattererSpec,
}

/// Optical thickness as written in JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ThicknessSpec {
    /// A finite thickness.
    Number(f64),
    /// Must be `"infinite"`.
    Word(String),
}

/// The scatterer of a layer: an object with exactly one of the keys
/// [`SCATTERERS`] (deserialized by hand so that a second key is named as
/// such, not as a JSON syntax error).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ScattererSpec {
    /// Mie spheres.
    Mie(MieSpec),
    /// Given Greek coefficients (conventions §4).
    Expansion(ExpansionSpec),
    /// Rayleigh–Cabannes scattering.
    Rayleigh {
        /// Single-scattering albedo.
        albedo: f64,
        /// Depolarization factor `ρ ∈ [0, 1)`.
        #[serde(default)]
        depolarization: f64,
    },
    /// Henyey–Greenstein phase function (a1 only, no polarization).
    HenyeyGreenstein {
        /// Single-scattering albedo.
        albedo: f64,
        /// Asymmetry parameter `g ∈ (−1, 1)`.
        g: f64,
    },
}

/// The keys of a `scatterer` object, one of which it must have.
pub const SCATTERERS: [&str; 4] = ["mie", "expansion", "rayleigh", "henyey_greenstein"];

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RayleighFields {
    albedo: f64,
    #[serde(default)]
    depolarization: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct HenyeyGreensteinFields {
    albedo: f64,
    g: f64,
}

impl<'de> Deserialize<'de> for ScattererSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::{Error, MapAccess, Visitor};
        struct OneOf;
        fn exactly_one<E: Error>(found: &str) -> E {
            E::custom(format!(
                "exactly one of {} ({found})",
                SCATTERERS.join(", ")
            ))
        }
        impl<'de> Visitor<'de> for OneOf {
            type Value = ScattererSpec;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "an object with exactly one of {}", SCATTERERS.join(", "))
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<ScattererSpec, A::Error> {
                let Some(key) = map.next_key::<String>()? else {
                    return Err(exactly_one("found none"));
                };
                let scatterer = match key.as_str() {
                    "mie" => ScattererSpec::Mie(map.next_value()?),
                    "expansion" => ScattererSpec::Expansion(map.next_value()?),
                    "rayleigh" => {
                        let r: RayleighFields = map.next_value()?;
                        ScattererSpec::Rayleigh {
                            albedo: r.albedo,
                            depolarization: r.depolarization,
                        }
                    }
                    "henyey_greenstein" => {
                        let h: HenyeyGreensteinFields = map.next_value()?;
                        ScattererSpec::HenyeyGreenstein {
                            albedo: h.albedo,
                            g: h.g,
                        }
                    }
                    other => return Err(A::Error::unknown_variant(other, &SCATTERERS)),
                };
                if let Some(second) = map.next_key::<String>()? {
                    return Err(exactly_one(&format!("found {key} and {second}")));
                }
                Ok(scatterer)
            }
        }
        d.deserialize_map(OneOf)
    }
}

/// An externally tagged enum written as an object with exactly one key (or,
/// for a unit variant, as its name: `"base": "black"`). serde's derived enums
/// report a second key as "expected value at line L column C", a JSON syntax
/// error it is not, and an empty object as "invalid type: map"; this names
/// both as what they are. Used through `deserialize_with`.
fn one_key<'de, D, T>(d: D) -> Result<T, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de> + OneOf,
{
    use serde::de::value::{MapAccessDeserializer, StrDeserializer};
    use serde::de::{Error, MapAccess, Visitor};
    struct V<T>(std::marker::PhantomData<T>);
    fn exactly_one<T: OneOf, E: Error>(found: &str) -> E {
        E::custom(format!("exactly one of {} ({found})", T::KEYS.join(", ")))
    }
    impl<'de, T: Deserialize<'de> + OneOf> Visitor<'de> for V<T> {
        type Value = T;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            write!(f, "an object with exactly one of {}", T::KEYS.join(", "))
        }
        fn visit_str<E: Error>(self, v: &str) -> Result<T, E> {
            T::deserialize(StrDeserializer::<E>::new(v))
        }
        fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<T, A::Error> {
            let value = T::deserialize(MapAccessDeserializer::new(&mut map)).map_err(|e| {
                let m = e.to_string();
                if m.starts_with("invalid type: map") {
                    exactly_one::<T, A::Error>("found none")
                } else {
                    e
                }
            })?;
            if let Some(second) = map.next_key::<String>()? {
                return Err(exactly_one::<T, A::Error>(&format!(
                    "found {} and {second}",
                    T::key_of(&value)
                )));
            }
            Ok(value)
        }
    }
    d.deserialize_any(V(std::marker::PhantomData))
}

/// [`one_key`] of an optional field (present: `Some`).
fn some_one_key<'de, D, T>(d: D) -> Result<Option<T>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de> + OneOf,
{
    one_key(d).map(Some)
}

/// The keys of a one-key object and which one a value was written with.
trait OneOf {
    const KEYS: &'static [&'static str];
    fn key_of(&self) -> &'static str;
}

impl OneOf for BaseSpec {
    const KEYS: &'static [&'static str] = &["black", "lambertian", "fresnel"];
    fn key_of(&self) -> &'static str {
        match self {
            Self::Black => "black",
            Self::Lambertian { .. } => "lambertian",
            Self::Fresnel { .. } => "fresnel",
        }
    }
}

impl OneOf for SizeDistributionSpec {
    const KEYS: &'static [&'static str] = &["lognormal", "gamma"];
    fn key_of(&self) -> &'static str {
        match self {
            Self::Lognormal { .. } => "lognormal",
            Self::Gamma { .. } => "gamma",
        }
    }
}

/// A material given by name or by index.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum MaterialSpec {
    /// Built-in material (`physics::materials`).
    Name(String),
    /// Explicit complex index `n + i k`.
    Index {
        /// Real part.
        n: f64,
        /// Imaginary part (≥ 0 absorbs).
        k: f64,
    },
}

/// Mie spheres in a binder.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MieSpec {
    /// Particle material.
    pub material: MaterialSpec,
    /// Radius of monodisperse spheres (µm); exclusive with `size_distribution`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius_um: Option<f64>,
    /// Size distribution; exclusive with `radius_um`.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "some_one_key"
    )]
    pub size_distribution: Option<SizeDistributionSpec>,
    /// Real refractive index of the binder (≥ 1).
    #[serde(default = "one")]
    pub host_index: f64,
}

fn one() -> f64 {
    1.0
}

/// Particle size distributions.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum SizeDistributionSpec {
    /// Log-normal number distribution.
    Lognormal {
        /// Geometric mean radius (µm).
        r_g_um: f64,
        /// Geometric standard deviation (> 1).
        sigma_g: f64,
        /// Explicit lower limit of the radius integral (µm); with
        /// `radius_max_um`, replaces the tail cuts of `physics::psd`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        radius_min_um: Option<f64>,
        /// Explicit upper limit of the radius integral (µm).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        radius_max_um: Option<f64>,
    },
    /// Gamma distribution (Hansen & Travis 1974).
    Gamma {
        /// Effective radius (µm).
        r_eff_um: f64,
        /// Effective variance (> 0, < 0.5).
        v_eff: f64,
        /// Explicit lower limit of the radius integral (µm); see `Lognormal`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        radius_min_um: Option<f64>,
        /// Explicit upper limit of the radius integral (µm).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        radius_max_um: Option<f64>,
    },
}

impl SizeDistributionSpec {
    /// The explicit integration limits `(radius_min_um, radius_max_um)`.
    pub fn radius_limits_um(&self) -> (Option<f64>, Option<f64>) {
        match *self {
            Self::Lognormal {
                radius_min_um,
                radius_max_um,
                ..
            }
            | Self::Gamma {
                radius_min_um,
                radius_max_um,
                ..
            } => (radius_min_um, radius_max_um),
        }
    }
}

/// Explicit expansion coefficients.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExpansionSpec {
    /// Single-scattering albedo.
    pub albedo: f64,
    /// β_l (β_0 = 1).
    pub beta: Vec<f64>,
    /// α_l (missing entries are 0).
    #[serde(default)]
    pub alpha: Vec<f64>,
    /// ζ_l.
    #[serde(default)]
    pub zeta: Vec<f64>,
    /// δ_l.
    #[serde(default)]
    pub delta: Vec<f64>,
    /// γ_l.
    #[serde(default)]
    pub gamma: Vec<f64>,
    /// ε_l.
    #[serde(default)]
    pub epsilon: Vec<f64>,
}

/// The lower boundary as written in JSON: `"black"` or an object.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum BaseSpec {
    /// No reflection.
    #[default]
    Black,
    /// Depolarizing Lambertian reflector.
    Lambertian {
        /// Hemispherical reflectance in `[0, 1]`.
        albedo: f64,
    },
    /// Smooth Fresnel interface with the binder above it.
    Fresnel {
        /// Base material.
        material: MaterialSpec,
        /// Real index of the medium above the base; default: the binder of
        /// the last layer if it is a Mie layer, else 1.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ambient_index: Option<f64>,
    },
}

/// Numerical settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    /// Quadrature points per hemisphere; explicit streams win over
    /// `tolerance`. Default 16 when neither is given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub streams: Option<usize>,
    /// Requested accuracy (estimated max error of f11 relative to max f11):
    /// the solver picks the cheapest stream count predicted to meet it
    /// (`solver::accuracy`). Ignored when `streams` is given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Vector (true) or scalar (false) radiative transfer.
    #[serde(default = "yes")]
    pub polarized: bool,
    /// Add the exact double scattering through a delta-M truncated forward
    /// peak at user angles (`solver::secondary`; docs/solver.md). Only
    /// layers whose series the streams cannot hold are affected; `false`
    /// saves its cost (seconds for Mie x ≈ 100 on a 64-node table) where
    /// the grazing forward directions do not matter. Written in the
    /// canonical form only when `false`.
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub secondary_scattering: bool,
}

/// Streams when neither `streams` nor `tolerance` is given.
pub const DEFAULT_STREAMS: usize = 16;
fn yes() -> bool {
    true
}
fn is_true(x: &bool) -> bool {
    *x
}

impl Default for SolverSpec {
    fn default() -> Self {
        Self {
            streams: None,
            polarized: true,
            tolerance: None,
            secondary_scattering: true,
        }
    }
}

/// Hard limits of the spec (the service adds its own, lower, caps).
pub const MAX_STREAMS: usize = 512;

/// Parse JSON text into a spec; errors carry the JSON path. Exactly one
/// JSON document: trailing data is an error ([`json::from_str`]).
pub fn parse(text: &str) -> Result<Spec, SpecError> {
    // serde accepts a struct written as an array too; a spec is an object.
    if let Some(c) = text.trim_start().chars().next()
        && c != '{'
    {
        return Err(SpecError::new("$", "the spec must be a JSON object"));
    }
    let spec: Spec = json::from_str(text).map_err(with_allowed_range)?;
    let tree: serde_json::Value = json::from_str(text)?;
    objects_not_arrays(&tree, &mut String::new())?;
    validate(&spec)?;
    Ok(spec)
}

/// The spec's arrays: `layers`, `wavelengths_nm` and the Greek coefficients.
const ARRAYS: [&str; 8] = [
    "layers",
    "wavelengths_nm",
    "layers[].scatterer.expansion.beta",
    "layers[].scatterer.expansion.alpha",
    "layers[].scatterer.expansion.zeta",
    "layers[].scatterer.expansion.delta",
    "layers[].scatterer.expansion.gamma",
    "layers[].scatterer.expansion.epsilon",
];

/// serde reads a struct written as an array of its fields in order
/// (`"solver": [8]`, a layer as `[1, {…}]`); the spec's objects are objects.
/// Refuses an array anywhere but [`ARRAYS`] (paths without indices), naming
/// its path; `path` is the JSON path of `v`.
fn objects_not_arrays(v: &serde_json::Value, path: &mut String) -> Result<(), SpecError> {
    use serde_json::Value;
    match v {
        Value::Object(map) => {
            for (k, x) in map {
                let len = path.len();
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(k);
                objects_not_arrays(x, path)?;
                path.truncate(len);
            }
        }
        Value::Array(items) => {
            if !ARRAYS.contains(&without_indices(path).as_str()) {
                return Err(SpecError::new(
                    path.clone(),
                    "expected an object with named fields, found an array",
                ));
            }
            let len = path.len();
            for (i, x) in items.iter().enumerate() {
                path.push_str(&format!("[{i}]"));
                objects_not_arrays(x, path)?;
                path.truncate(len);
            }
        }
        _ => {}
    }
    Ok(())
}

// Allowed ranges, one text per field: `validate` reports them, and so does
// a value that does not even parse there (`NaN`, `1e999`, a string).
const R_THICKNESS: &str = "[0, 1e12] (or \"infinite\")";
const R_UNIT: &str = "[0, 1]";
const R_INDEX_REAL: &str = "[1, 10]";
const R_RADIUS: &str = "[1e-6, 1e4] µm";
const R_SIGMA_G: &str = "[1.0001, 5]";
const R_V_EFF: &str = "[1e-4, 0.49]";
const R_DEPOLARIZATION: &str = "[0, 0.99]";
const R_G: &str = "[-0.999, 0.999]";
const R_N: &str = "(0, 100]";
const R_K: &str = "[0, 100]";
const R_WAVELENGTH: &str = "[100, 100000] nm";
const R_STREAMS: &str = "[1, 512] (integer)";
const R_TOLERANCE: &str = "[1e-10, 0.5]";
const R_COEFFICIENT: &str = "finite numbers with |x| ≤ 1e6";

/// A JSON path with its array indices left out: `layers[3].scatterer` →
/// `layers[].scatterer`.
fn without_indices(path: &str) -> String {
    let mut p = String::with_capacity(path.len());
    let mut in_index = false;
    for c in path.chars() {
        match c {
            '[' => {
                in_index = true;
                p.push('[');
            }
            ']' => {
                in_index = false;
                p.push(']');
            }
            _ if in_index => {}
            _ => p.push(c),
        }
    }
    p
}

/// The allowed range of the numeric field at a JSON path, if it is one.
fn allowed_range(path: &str) -> Option<&'static str> {
    let p = without_indices(path);
    let p = p.as_str();
    let tail = |suffix: &str| p.ends_with(suffix);
    Some(match p {
        "layers[].optical_thickness" => R_THICKNESS,
        "wavelengths_nm[]" => R_WAVELENGTH,
        "solver.streams" => R_STREAMS,
        "solver.tolerance" => R_TOLERANCE,
        "base.lambertian.albedo" => R_UNIT,
        "base.fresnel.ambient_index" => R_INDEX_REAL,
        _ if tail(".mie.host_index") => R_INDEX_REAL,
        _ if tail(".mie.radius_um") || tail(".r_g_um") || tail(".r_eff_um") => R_RADIUS,
        _ if tail(".sigma_g") => R_SIGMA_G,
        _ if tail(".v_eff") => R_V_EFF,
        _ if tail("material.n") => R_N,
        _ if tail("material.k") => R_K,
        _ if tail(".rayleigh.depolarization") => R_DEPOLARIZATION,
        _ if tail(".henyey_greenstein.g") => R_G,
        _ if tail(".albedo") => R_UNIT,
        _ if p.starts_with("layers[].scatterer.expansion.") && tail("[]") => R_COEFFICIENT,
        _ => return None,
    })
}

/// A value that did not parse at a numeric field: name what is allowed
/// there (`NaN`, `Infinity` and numbers beyond ±1.8e308 are not JSON numbers).
fn with_allowed_range(e: SpecError) -> SpecError {
    let Some(range) = allowed_range(&e.path) else {
        return e;
    };
    let not_a_number =
        e.message.starts_with("expected value") || e.message.starts_with("number out of range");
    let message = if not_a_number {
        format!(
            "not a finite JSON number ({}; NaN, Infinity and numbers beyond ±1.8e308 are not JSON); allowed: {range}",
            e.message
        )
    } else {
        format!("{}; allowed: {range}", e.message)
    };
    SpecError::new(e.path, message)
}

fn finite_in(path: &str, v: f64, lo: f64, hi: f64, what: &str) -> Result<(), SpecError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(SpecError::new(
            path,
            format!("{v} is outside the allowed range {what}"),
        ))
    }
}

fn needs_wavelength(spec: &Spec) -> bool {
    let named = |m: &MaterialSpec| matches!(m, MaterialSpec::Name(_));
    spec.layers
        .iter()
        .any(|l| matches!(l.scatterer, ScattererSpec::Mie(_)))
        || matches!(&spec.base, BaseSpec::Fresnel { material, .. } if named(material))
}

/// Check every range; the error names the JSON path.
pub fn validate(spec: &Spec) -> Result<(), SpecError> {
    if spec.layers.is_empty() {
        return Err(SpecError::new("layers", "at least one layer is required"));
    }
    let n_layers = spec.layers.len();
    for (i, layer) in spec.layers.iter().enumerate() {
        let p = format!("layers[{i}]");
        match &layer.optical_thickness {
            ThicknessSpec::Number(t) => finite_in(
                &format!("{p}.optical_thickness"),
                *t,
                0.0,
                1e12,
                R_THICKNESS,
            )?,
            ThicknessSpec::Word(w) => {
                if w != "infinite" {
                    return Err(SpecError::new(
                        format!("{p}.optical_thickness"),
                        format!("\"{w}\" is not allowed: give a number ≥ 0 or \"infinite\""),
                    ));
                }
                if i + 1 != n_layers {
                    return Err(SpecError::new(
                        format!("{p}.optical_thickness"),
                        "only the last layer may be \"infinite\"",
                    ));
                }
            }
        }
        let sp = format!("{p}.scatterer");
        match &layer.scatterer {
            ScattererSpec::Mie(m) => {
                let mp = format!("{sp}.mie");
                validate_material(&format!("{mp}.material"), &m.material)?;
                finite_in(
                    &format!("{mp}.host_index"),
                    m.host_index,
                    1.0,
                    10.0,
                    R_INDEX_REAL,
                )?;
                match (&m.radius_um, &m.size_distribution) {
                    (Some(r), None) => {
                        finite_in(&format!("{mp}.radius_um"), *r, 1e-6, 1e4, R_RADIUS)?
                    }
                    (
                        None,
                        Some(
                            d @ SizeDistributionSpec::Lognormal {
                                r_g_um, sigma_g, ..
                            },
                        ),
                    ) => {
                        let q = format!("{mp}.size_distribution.lognormal");
                        validate_radius_limits(&q, d)?;
                        finite_in(&format!("{q}.r_g_um"), *r_g_um, 1e-6, 1e4, R_RADIUS)?;
                        finite_in(&format!("{q}.sigma_g"), *sigma_g, 1.0001, 5.0, R_SIGMA_G)?;
                    }
                    (
                        None,
                        Some(
                            d @ SizeDistributionSpec::Gamma {
                                r_eff_um, v_eff, ..
                            },
                        ),
                    ) => {
                        let q = format!("{mp}.size_distribution.gamma");
                        validate_radius_limits(&q, d)?;
                        finite_in(&format!("{q}.r_eff_um"), *r_eff_um, 1e-6, 1e4, R_RADIUS)?;
                        finite_in(&format!("{q}.v_eff"), *v_eff, 1e-4, 0.49, R_V_EFF)?;
                    }
                    (Some(_), Some(_)) => {
                        return Err(SpecError::new(
                            mp,
                            "give either radius_um or size_distribution, not both",
                        ));
                    }
                    (None, None) => {
                        return Err(SpecError::new(
                            mp,
                            "missing field: radius_um or size_distribution is required",
                        ));
                    }
                }
            }
            ScattererSpec::Expansion(e) => {
                let ep = format!("{sp}.expansion");
                finite_in(&format!("{ep}.albedo"), e.albedo, 0.0, 1.0, R_UNIT)?;
                if e.beta.is_empty() {
                    return Err(SpecError::new(
                        format!("{ep}.beta"),
                        "at least beta_0 = 1 is required",
                    ));
                }
                if (e.beta[0] - 1.0).abs() > 1e-6 {
                    return Err(SpecError::new(
                        format!("{ep}.beta[0]"),
                        format!("{} must be 1 (normalised phase function)", e.beta[0]),
                    ));
                }
                for (name, v) in [
                    ("beta", &e.beta),
                    ("alpha", &e.alpha),
                    ("zeta", &e.zeta),
                    ("delta", &e.delta),
                    ("gamma", &e.gamma),
                    ("epsilon", &e.epsilon),
                ] {
                    if v.len() > 100_000 {
                        return Err(SpecError::new(
                            format!("{ep}.{name}"),
                            "at most 100000 terms",
                        ));
                    }
                    for (l, x) in v.iter().enumerate() {
                        if !x.is_finite() || x.abs() > 1e6 {
                            return Err(SpecError::new(
                                format!("{ep}.{name}[{l}]"),
                                format!("{x} is outside the allowed range: {R_COEFFICIENT}"),
                            ));
                        }
                    }
                }
            }
            ScattererSpec::Rayleigh {
                albedo,
                depolarization,
            } => {
                finite_in(&format!("{sp}.rayleigh.albedo"), *albedo, 0.0, 1.0, R_UNIT)?;
                finite_in(
                    &format!("{sp}.rayleigh.depolarization"),
                    *depolarization,
                    0.0,
                    0.99,
                    R_DEPOLARIZATION,
                )?;
            }
            ScattererSpec::HenyeyGreenstein { albedo, g } => {
                finite_in(
                    &format!("{sp}.henyey_greenstein.albedo"),
                    *albedo,
                    0.0,
                    1.0,
                    R_UNIT,
                )?;
                finite_in(&format!("{sp}.henyey_greenstein.g"), *g, -0.999, 0.999, R_G)?;
            }
        }
    }
    match &spec.base {
        BaseSpec::Black => {}
        BaseSpec::Lambertian { albedo } => {
            finite_in("base.lambertian.albedo", *albedo, 0.0, 1.0, R_UNIT)?
        }
        BaseSpec::Fresnel {
            material,
            ambient_index,
        } => {
            validate_material("base.fresnel.material", material)?;
            if let Some(a) = ambient_index {
                finite_in("base.fresnel.ambient_index", *a, 1.0, 10.0, R_INDEX_REAL)?;
            }
        }
    }
    match &spec.wavelengths_nm {
        Some(w) => {
            if w.is_empty() || w.len() > 1000 {
                return Err(SpecError::new(
                    "wavelengths_nm",
                    "give between 1 and 1000 wavelengths",
                ));
            }
            for (i, x) in w.iter().enumerate() {
                finite_in(
                    &format!("wavelengths_nm[{i}]"),
                    *x,
                    100.0,
                    100_000.0,
                    R_WAVELENGTH,
                )?;
            }
        }
        None => {
            if needs_wavelength(spec) {
                return Err(SpecError::new(
                    "wavelengths_nm",
                    "missing field: required because a layer or the base depends on wavelength",
                ));
            }
        }
    }
    if let Some(n) = spec.solver.streams
        && (n == 0 || n > MAX_STREAMS)
    {
        return Err(SpecError::new(
            "solver.streams",
            format!("{n} is outside the allowed range [1, {MAX_STREAMS}]"),
        ));
    }
    if let Some(t) = spec.solver.tolerance {
        finite_in("solver.tolerance", t, 1e-10, 0.5, R_TOLERANCE)?;
    }
    Ok(())
}

fn validate_material(path: &str, m: &MaterialSpec) -> Result<(), SpecError> {
    match m {
        MaterialSpec::Name(name) => {
            if materials::find(name).is_err() {
                return Err(SpecError::new(
                    path,
                    format!(
                        "unknown material '{name}' (known: {})",
                        materials::known_materials().join(", ")
                    ),
                ));
            }
            Ok(())
        }
        MaterialSpec::Index { n, k } => {
            finite_in(&format!("{path}.n"), *n, 1e-6, 100.0, R_N)?;
            finite_in(&format!("{path}.k"), *k, 0.0, 100.0, R_K)
        }
    }
}

/// `radius_min_um` / `radius_max_um` of a size distribution: both or
/// neither, each in `[1e-6, 1e4]` µm, `min < max`.
fn validate_radius_limits(q: &str, d: &SizeDistributionSpec) -> Result<(), SpecError> {
    match d.radius_limits_um() {
        (None, None) => Ok(()),
        (Some(lo), Some(hi)) => {
            finite_in(
                &format!("{q}.radius_min_um"),
                lo,
                1e-6,
                1e4,
                "[1e-6, 1e4] µm",
            )?;
            finite_in(
                &format!("{q}.radius_max_um"),
                hi,
                1e-6,
                1e4,
                "[1e-6, 1e4] µm",
            )?;
            if lo < hi {
                Ok(())
            } else {
                Err(SpecError::new(
                    format!("{q}.radius_max_um"),
                    format!("must be greater than radius_min_um = {lo}"),
                ))
            }
        }
        (Some(_), None) => Err(SpecError::new(
            format!("{q}.radius_max_um"),
            "missing field: radius_min_um requires radius_max_um",
        )),
        (None, Some(_)) => Err(SpecError::new(
            format!("{q}.radius_min_um"),
            "missing field: radius_max_um requires radius_min_um",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_key_names_path() {
        let e = parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1,"depol":0}}}]}"#)
            .unwrap_err();
        assert!(e.path.starts_with("layers[0].scatterer"), "{e}");
        assert!(e.message.contains("depol"), "{e}");
    }

    #[test]
    fn out_of_range_names_path_and_range() {
        let e =
            parse(r#"{"layers":[{"optical_thickness":-1,"scatterer":{"rayleigh":{"albedo":1}}}]}"#)
                .unwrap_err();
        assert_eq!(e.path, "layers[0].optical_thickness");
        assert!(e.message.contains("[0, 1e12]"), "{e}");
        let e = parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"henyey_greenstein":{"albedo":1.5,"g":0.5}}}]}"#)
            .unwrap_err();
        assert_eq!(e.path, "layers[0].scatterer.henyey_greenstein.albedo");
    }

    #[test]
    fn infinite_only_last_and_wavelength_required() {
        let e = parse(
            r#"{"layers":[{"optical_thickness":"infinite","scatterer":{"rayleigh":{"albedo":1}}},
                          {"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}]}"#,
        )
        .unwrap_err();
        assert_eq!(e.path, "layers[0].optical_thickness");
        let e = parse(
            r#"{"layers":[{"optical_thickness":1,"scatterer":{"mie":{"material":"TiO2","radius_um":0.2}}}]}"#,
        )
        .unwrap_err();
        assert_eq!(e.path, "wavelengths_nm");
    }

    const RAYLEIGH: &str = r#"{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}"#;

    #[test]
    fn a_spec_is_one_json_object() {
        let e = parse("[]").unwrap_err();
        assert_eq!(
            (e.path.as_str(), e.message.as_str()),
            ("$", "the spec must be a JSON object")
        );
        // The array form serde would accept for a struct is refused too.
        let e = parse(&format!("[[{RAYLEIGH}]]")).unwrap_err();
        assert_eq!(e.path, "$");
        let e = parse(&format!(r#"{{"layers":[{RAYLEIGH}]}} {{}}"#)).unwrap_err();
        assert!(
            e.message
                .starts_with("trailing data after the JSON document"),
            "{e}"
        );
    }

    #[test]
    fn a_base_and_a_size_distribution_have_exactly_one_key() {
        let layer = format!(r#"{{"layers":[{RAYLEIGH}],"base":"#);
        let e = parse(&format!(
            r#"{layer}{{"lambertian":{{"albedo":0.5}},"fresnel":{{"material":"silver"}}}}}}"#
        ))
        .unwrap_err();
        assert_eq!(e.path, "base");
        assert!(
            e.message.starts_with(
                "exactly one of black, lambertian, fresnel (found lambertian and fresnel)"
            ),
            "{e}"
        );
        let e = parse(&format!("{layer}{{}}}}")).unwrap_err();
        assert!(e.message.contains("found none"), "{e}");
        let e = parse(&format!(r#"{layer}"mirror"}}"#)).unwrap_err();
        assert!(e.message.contains("unknown variant `mirror`"), "{e}");
        // The accepted forms are unchanged.
        assert_eq!(
            parse(&format!(r#"{layer}"black"}}"#)).unwrap().base,
            BaseSpec::Black
        );
        assert_eq!(
            parse(&format!(r#"{layer}{{"lambertian":{{"albedo":0.5}}}}}}"#))
                .unwrap()
                .base,
            BaseSpec::Lambertian { albedo: 0.5 }
        );
        let e = parse(&format!(
            r#"{layer}{{"lambertian":{{"albedo":0.5,"x":1}}}}}}"#
        ))
        .unwrap_err();
        assert_eq!(e.path, "base.lambertian.x");
        let psd = r#"{"layers":[{"optical_thickness":1,"scatterer":{"mie":{"material":"TiO2","size_distribution":{"lognormal":{"r_g_um":0.2,"sigma_g":1.3},"gamma":{"r_eff_um":0.2,"v_eff":0.1}}}}}],"wavelengths_nm":[550]}"#;
        let e = parse(psd).unwrap_err();
        assert_eq!(e.path, "layers[0].scatterer.mie.size_distribution");
        assert!(
            e.message
                .starts_with("exactly one of lognormal, gamma (found lognormal and gamma)"),
            "{e}"
        );
    }

    #[test]
    fn structs_written_as_arrays_are_refused() {
        for (text, path) in [
            (
                r#"{"layers":[[1,{"rayleigh":{"albedo":0.9}}]]}"#,
                "layers[0]",
            ),
            (
                r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":[0.9]}}]}"#,
                "layers[0].scatterer.rayleigh",
            ),
            (
                r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":0.9}}}],"solver":[8]}"#,
                "solver",
            ),
        ] {
            let e = parse(text).unwrap_err();
            assert_eq!(e.path, path, "{text}: {e}");
            assert!(e.message.contains("found an array"), "{e}");
        }
        // The spec's own arrays are fine.
        let gs = r#"{"layers":[{"optical_thickness":1,"scatterer":{"expansion":{"albedo":1,"beta":[1,0.5],"gamma":[0,0.1]}}}],"wavelengths_nm":[550]}"#;
        parse(gs).unwrap();
    }

    #[test]
    fn a_scatterer_has_exactly_one_key() {
        let two = r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1},"henyey_greenstein":{"albedo":1,"g":0}}}]}"#;
        let e = parse(two).unwrap_err();
        assert!(
            e.to_string().starts_with(
                "layers[0].scatterer: exactly one of mie, expansion, rayleigh, henyey_greenstein"
            ),
            "{e}"
        );
        let e = parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{}}]}"#).unwrap_err();
        assert!(e.message.starts_with("exactly one of"), "{e}");
        let e = parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"lambert":{}}}]}"#)
            .unwrap_err();
        assert!(e.message.contains("henyey_greenstein"), "{e}");
        // Each variant still refuses unknown fields and keeps its defaults.
        let s = parse(&format!(r#"{{"layers":[{RAYLEIGH}]}}"#)).unwrap();
        assert_eq!(
            s.layers[0].scatterer,
            ScattererSpec::Rayleigh {
                albedo: 1.0,
                depolarization: 0.0
            }
        );
    }

    #[test]
    fn unparsable_numbers_name_the_allowed_range() {
        for (text, path, range) in [
            (
                r#"{"layers":[{"optical_thickness":NaN,"scatterer":{"rayleigh":{"albedo":1}}}]}"#,
                "layers[0].optical_thickness",
                R_THICKNESS,
            ),
            (
                r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1e999}}}]}"#,
                "layers[0].scatterer.rayleigh.albedo",
                "[0, 1]",
            ),
            (
                r#"{"layers":[{"optical_thickness":1,"scatterer":{"henyey_greenstein":{"albedo":1,"g":"x"}}}]}"#,
                "layers[0].scatterer.henyey_greenstein.g",
                "[-0.999, 0.999]",
            ),
            (
                r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}],"wavelengths_nm":[Infinity]}"#,
                "wavelengths_nm[0]",
                "[100, 100000] nm",
            ),
        ] {
            let e = parse(text).unwrap_err();
            assert_eq!(e.path, path, "{e}");
            assert!(e.message.ends_with(&format!("allowed: {range}")), "{e}");
        }
    }

    #[test]
    fn issue_example_parses() {
        let s = parse(
            r#"{
          "layers": [
            { "optical_thickness": 1.0,
              "scatterer": { "mie": { "material": "TiO2", "radius_um": 0.2, "host_index": 1.0 } } },
            { "optical_thickness": "infinite",
              "scatterer": { "expansion": { "albedo": 0.973527, "beta": [1.0, 2.104031], "alpha": [], "zeta": [], "delta": [], "gamma": [], "epsilon": [] } } }
          ],
          "base": { "lambertian": { "albedo": 0.5 } },
          "wavelengths_nm": [450, 550, 650],
          "solver": { "streams": 16, "polarized": true }
        }"#,
        )
        .unwrap();
        assert_eq!(s.layers.len(), 2);
        let s2 = parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}],"base":"black"}"#)
            .unwrap();
        assert_eq!(s2.base, BaseSpec::Black);
    }
}
