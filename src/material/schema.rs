//! The material spec as users write it (docs/spec.md): the types JSON
//! deserializes into. Reading them (one JSON document, objects with exactly
//! one key where the schema says so) is `material::parse`; the ranges are
//! `material::validate`.

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
    #[serde(
        default,
        deserialize_with = "crate::material::parse::one_key::<_, BaseSpec>"
    )]
    pub base: BaseSpec,
    /// Vacuum wavelengths in nm; required when anything depends on wavelength.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wavelengths_nm: Option<Vec<f64>>,
    /// Numerical settings.
    #[serde(default)]
    pub solver: SolverSpec,
    /// A binder/air interface above the layers ([`TopInterfaceSpec`]);
    /// absent or `"none"`: the seed's model, and then out of the canonical
    /// form.
    #[serde(
        default,
        skip_serializing_if = "TopInterfaceSpec::is_none",
        deserialize_with = "crate::material::parse::one_key::<_, TopInterfaceSpec>"
    )]
    pub top_interface: TopInterfaceSpec,
    /// What the request needs of its result ([`super::needs`]); absent:
    /// the full product, and then out of the canonical form.
    #[serde(default, skip_serializing_if = "super::needs::Needs::is_full")]
    pub needs: super::needs::Needs,
}

/// One homogeneous layer, in one of two forms (docs/spec.md, Layers):
/// optical (`optical_thickness` and one `scatterer`) or a paint film
/// (`thickness_um`, `pigments` and a `binder`), whose optical thickness,
/// albedo and mixed phase matrix follow per wavelength from the pigments'
/// volume fractions (`crate::plan`). [`LayerSpec::form`] says which.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerSpec {
    /// Optical form: a number ≥ 0 or the string `"infinite"` (last layer only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub optical_thickness: Option<ThicknessSpec>,
    /// Optical form: what scatters in the layer.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scatterer: Option<ScattererSpec>,
    /// Film form: the film's geometric thickness in µm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thickness_um: Option<f64>,
    /// Film form: the pigment populations, mixed in the one film.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pigments: Option<Vec<PigmentSpec>>,
    /// Film form: the medium between the pigments (default 1, air).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub binder: Option<HostSpec>,
}

/// The two forms of a [`LayerSpec`], borrowed from it.
#[derive(Clone, Copy, Debug)]
pub enum LayerForm<'a> {
    /// Optical thickness and one scatterer.
    Optical {
        /// `optical_thickness`.
        thickness: &'a ThicknessSpec,
        /// `scatterer`.
        scatterer: &'a ScattererSpec,
    },
    /// A paint film.
    Film {
        /// `thickness_um`.
        thickness_um: f64,
        /// `pigments` (at least one).
        pigments: &'a [PigmentSpec],
        /// `binder`, or its default.
        binder: &'a HostSpec,
    },
}

/// The binder of a film without one: air.
pub static DEFAULT_BINDER: HostSpec = HostSpec::Index(1.0);

/// The keys of the optical form and of the film form of a layer.
pub const OPTICAL_KEYS: [&str; 2] = ["optical_thickness", "scatterer"];
/// See [`OPTICAL_KEYS`].
pub const FILM_KEYS: [&str; 3] = ["thickness_um", "pigments", "binder"];

impl LayerSpec {
    /// An optical layer.
    pub fn optical(thickness: ThicknessSpec, scatterer: ScattererSpec) -> Self {
        Self {
            optical_thickness: Some(thickness),
            scatterer: Some(scatterer),
            thickness_um: None,
            pigments: None,
            binder: None,
        }
    }

    /// Which form the layer is written in; the error (a field name and a
    /// message) when it mixes the two or misses a field of its form.
    pub fn form(&self) -> Result<LayerForm<'_>, (&'static str, String)> {
        let film = self.thickness_um.is_some() || self.pigments.is_some() || self.binder.is_some();
        let optical = self.optical_thickness.is_some() || self.scatterer.is_some();
        let forms = || {
            format!(
                "a layer is either {{{}}} or {{{}}}",
                OPTICAL_KEYS.join(", "),
                FILM_KEYS.join(", ")
            )
        };
        match (optical, film) {
            (true, true) => Err(("", format!("{}, not both", forms()))),
            (false, false) => Err(("", forms())),
            (true, false) => match (&self.optical_thickness, &self.scatterer) {
                (Some(thickness), Some(scatterer)) => Ok(LayerForm::Optical {
                    thickness,
                    scatterer,
                }),
                (None, _) => Err(("optical_thickness", "missing field".into())),
                (_, None) => Err(("scatterer", "missing field".into())),
            },
            (false, true) => match (self.thickness_um, &self.pigments) {
                (Some(thickness_um), Some(pigments)) => Ok(LayerForm::Film {
                    thickness_um,
                    pigments,
                    binder: self.binder.as_ref().unwrap_or(&DEFAULT_BINDER),
                }),
                (None, _) => Err(("thickness_um", "missing field".into())),
                (_, None) => Err(("pigments", "missing field".into())),
            },
        }
    }

    /// [`LayerSpec::form`] of a validated spec.
    ///
    /// # Panics
    /// If the layer was not validated (`material::validate`).
    pub fn valid_form(&self) -> LayerForm<'_> {
        self.form().expect("a validated layer has one form")
    }

    /// The scatterer of an optical layer.
    pub fn optical_scatterer(&self) -> Option<&ScattererSpec> {
        match self.form() {
            Ok(LayerForm::Optical { scatterer, .. }) => Some(scatterer),
            _ => None,
        }
    }

    /// The medium the layer's particles sit in: a Mie scatterer's host or a
    /// film's binder (`None` for other scatterers).
    pub fn host(&self) -> Option<&HostSpec> {
        match self.form() {
            Ok(LayerForm::Optical {
                scatterer: ScattererSpec::Mie(m),
                ..
            }) => Some(&m.host_index),
            Ok(LayerForm::Film { binder, .. }) => Some(binder),
            _ => None,
        }
    }
}

/// One pigment of a film: spheres of one material and size (or size
/// distribution) making up `volume_fraction` of the film's volume.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PigmentSpec {
    /// Particle material.
    pub material: MaterialSpec,
    /// Radius of monodisperse spheres (µm); exclusive with `size_distribution`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius_um: Option<f64>,
    /// Size distribution; exclusive with `radius_um`.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "crate::material::parse::some_one_key"
    )]
    pub size_distribution: Option<SizeDistributionSpec>,
    /// Share of the film's volume the particles fill, in (0, 1); the sum over
    /// a film's pigments is its pigment volume concentration (PVC).
    pub volume_fraction: f64,
}

impl PigmentSpec {
    /// The pigment's spheres as a Mie population in `binder`.
    pub fn in_binder(&self, binder: &HostSpec) -> MieSpec {
        MieSpec {
            material: self.material.clone(),
            radius_um: self.radius_um,
            size_distribution: self.size_distribution.clone(),
            host_index: binder.clone(),
        }
    }
}

/// The medium around particles (`host_index` of a Mie scatterer, `binder`
/// of a film): a real index, or a material in any [`MaterialSpec`] form (a
/// built-in name such as `"acrylic"` or `"water"`, `{name, source}`,
/// `{n, k}`, a table). Mie theory sees its real part; a film's binder also
/// absorbs with its imaginary part (docs/spec.md, Absorbing binders).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum HostSpec {
    /// A real index ≥ 1, the same at every wavelength.
    Index(f64),
    /// A material.
    Material(MaterialSpec),
}

impl HostSpec {
    /// Whether the index is the same at every wavelength.
    pub fn is_constant(&self) -> bool {
        match self {
            HostSpec::Index(_) => true,
            HostSpec::Material(m) => m.is_constant(),
        }
    }

    /// The complex index at `wavelength_nm` (ignored when constant).
    ///
    /// # Errors
    /// As [`MaterialSpec::index_at`].
    pub fn index_at(
        &self,
        wavelength_nm: f64,
    ) -> Result<crate::physics::RefractiveIndex, crate::physics::PhysicsError> {
        match self {
            HostSpec::Index(n) => Ok(crate::physics::RefractiveIndex::new(*n, 0.0)),
            HostSpec::Material(m) => m.index_at(wavelength_nm),
        }
    }

    /// A short label for plots and messages.
    pub fn label(&self) -> String {
        match self {
            HostSpec::Index(n) => format!("{n}"),
            HostSpec::Material(m) => m.label(),
        }
    }
}

impl Default for HostSpec {
    fn default() -> Self {
        DEFAULT_BINDER.clone()
    }
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

/// A material given by name, by index or by a table (docs/spec.md).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum MaterialSpec {
    /// Built-in material (`physics::materials`): its measured table.
    Name(String),
    /// Explicit complex index `n + i k`, the same at every wavelength.
    Index {
        /// Real part.
        n: f64,
        /// Imaginary part (≥ 0 absorbs).
        k: f64,
    },
    /// Built-in material with a choice of data: `"source": "seed"` is the
    /// seed's Table 2 (`physics::materials::find_seed`), `"measured"` (the
    /// default) the same as the plain name.
    Named {
        /// Material name or alias.
        name: String,
        /// `"measured"` or `"seed"`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        source: Option<String>,
    },
    /// A dispersive material: rows `[wavelength_nm, n, k]`, wavelengths
    /// strictly increasing, interpolated as a measured table.
    Table {
        /// The rows.
        table: Vec<[f64; 3]>,
    },
}

/// The data a [`MaterialSpec::Named`] asks for.
pub const MATERIAL_SOURCES: [&str; 2] = ["measured", "seed"];

impl MaterialSpec {
    /// Whether the index is the same at every wavelength (an explicit
    /// `{n, k}`): the others need the spec's wavelengths.
    pub fn is_constant(&self) -> bool {
        matches!(self, MaterialSpec::Index { .. })
    }

    /// The complex index at `wavelength_nm` (vacuum).
    ///
    /// # Errors
    /// An unknown name or source, or a wavelength outside the data
    /// (`PhysicsError::OutOfRange` naming the range).
    pub fn index_at(
        &self,
        wavelength_nm: f64,
    ) -> Result<crate::physics::RefractiveIndex, crate::physics::PhysicsError> {
        use crate::physics::{RefractiveIndex, materials};
        match self {
            MaterialSpec::Index { n, k } => Ok(RefractiveIndex::new(*n, *k)),
            MaterialSpec::Name(name) => materials::refractive_index(name, wavelength_nm),
            MaterialSpec::Named { name, source } => match source.as_deref() {
                None | Some("measured") => materials::refractive_index(name, wavelength_nm),
                Some("seed") => materials::find_seed(name)?.index_at(wavelength_nm),
                Some(other) => Err(crate::physics::PhysicsError::Invalid(format!(
                    "source '{other}' is not one of {}",
                    MATERIAL_SOURCES.join(", ")
                ))),
            },
            MaterialSpec::Table { table } => materials::table_index(table, wavelength_nm),
        }
    }

    /// A short label for plots and messages.
    pub fn label(&self) -> String {
        match self {
            MaterialSpec::Name(n) => n.clone(),
            MaterialSpec::Index { n, k } => format!("n = {n} + {k}i"),
            MaterialSpec::Named { name, source } => match source.as_deref() {
                Some("seed") => format!("{name} (seed)"),
                _ => name.clone(),
            },
            MaterialSpec::Table { table } => format!("table of {} rows", table.len()),
        }
    }
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
        deserialize_with = "crate::material::parse::some_one_key"
    )]
    pub size_distribution: Option<SizeDistributionSpec>,
    /// The binder: a real index ≥ 1 (default 1) or a material
    /// ([`HostSpec`]); Mie theory sees its real part.
    #[serde(default)]
    pub host_index: HostSpec,
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
    /// Rough (GGX microfacet, isotropic) Fresnel surface with the binder
    /// above it (docs/spec.md, Bases).
    RoughFresnel {
        /// Base material.
        material: MaterialSpec,
        /// GGX roughness `α` in `[0.05, 1]`.
        alpha: f64,
        /// As for `fresnel`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ambient_index: Option<f64>,
    },
}

impl BaseSpec {
    /// A reflecting surface's key (`"fresnel"`, `"rough_fresnel"`), material
    /// and ambient index; `None` for `black` and `lambertian`.
    pub fn surface(&self) -> Option<(&'static str, &MaterialSpec, Option<f64>)> {
        match self {
            BaseSpec::Fresnel {
                material,
                ambient_index,
            } => Some(("fresnel", material, *ambient_index)),
            BaseSpec::RoughFresnel {
                material,
                ambient_index,
                ..
            } => Some(("rough_fresnel", material, *ambient_index)),
            BaseSpec::Black | BaseSpec::Lambertian { .. } => None,
        }
    }

    /// [`BaseSpec::surface`]'s material and ambient index, to rewrite.
    pub fn surface_mut(&mut self) -> Option<(&mut MaterialSpec, &mut Option<f64>)> {
        match self {
            BaseSpec::Fresnel {
                material,
                ambient_index,
            }
            | BaseSpec::RoughFresnel {
                material,
                ambient_index,
                ..
            } => Some((material, ambient_index)),
            BaseSpec::Black | BaseSpec::Lambertian { .. } => None,
        }
    }
}

/// The surface above the layers (docs/spec.md, Top interface): `"none"`
/// (the layers face air directly) or an object with exactly one of
/// [`TOP_INTERFACES`] besides `none`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum TopInterfaceSpec {
    /// No interface.
    #[default]
    None,
    /// A smooth (flat) binder/air interface.
    Smooth {
        /// The binder's index, in any [`HostSpec`] form; default: the
        /// layers' `host_index` (or a film's `binder`) when that is one
        /// value for the whole stack. The interface sees its real part.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        index: Option<HostSpec>,
    },
    /// A rough (GGX, isotropic) interface: read so that it is refused
    /// with its own message; not solved yet.
    Rough {
        /// As for `smooth`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        index: Option<HostSpec>,
        /// GGX roughness.
        alpha: f64,
    },
}

/// The keys of a `top_interface` object (or its one word, `"none"`).
pub const TOP_INTERFACES: [&str; 3] = ["none", "smooth", "rough"];

impl TopInterfaceSpec {
    /// Whether there is no interface (the default, left out of the
    /// canonical form).
    pub fn is_none(&self) -> bool {
        matches!(self, TopInterfaceSpec::None)
    }

    /// The index as written (`None`: absent, or no interface).
    pub fn index(&self) -> Option<&HostSpec> {
        match self {
            TopInterfaceSpec::None => None,
            TopInterfaceSpec::Smooth { index } | TopInterfaceSpec::Rough { index, .. } => {
                index.as_ref()
            }
        }
    }
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
