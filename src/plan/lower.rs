//! Lowering of one wavelength: the spec's layers, base and settings as the
//! solver's [`Problem`] (docs/spec.md). Layer optics come from the
//! scatterer as written (Rayleigh, Henyey–Greenstein, explicit Greek
//! coefficients) or from Mie theory (`plan::mie`); a Fresnel base becomes
//! the mirror Mueller matrix of `physics::fresnel`.

use super::film::film_optics;
use super::mie::mie_optics;
use crate::material::{
    BaseSpec, DEFAULT_STREAMS, LayerForm, LayerSpec, MaterialSpec, ScattererSpec, Spec, SpecError,
    ThicknessSpec,
};
use crate::physics::expansion::GreekCoefficients;
use crate::physics::microfacet::RoughSurface;
use crate::physics::{RefractiveIndex, fresnel};
use crate::solver::{self, Base, Layer, Problem, Settings, Thickness};
use std::sync::Arc;

pub(super) fn resolve_index(
    path: &str,
    m: &MaterialSpec,
    wavelength_nm: Option<f64>,
) -> Result<RefractiveIndex, SpecError> {
    let wl = match (m.is_constant(), wavelength_nm) {
        (true, _) => f64::NAN,
        (false, Some(wl)) => wl,
        (false, None) => {
            return Err(SpecError::new(
                "wavelengths_nm",
                "required for named and tabulated materials",
            ));
        }
    };
    m.index_at(wl)
        .map_err(|e| SpecError::new(path, e.to_string()))
}

/// Zero-pad a coefficient array to `len`.
fn padded(v: &[f64], len: usize) -> Vec<f64> {
    let mut out = v.to_vec();
    out.resize(len, 0.0);
    out
}

/// Single-scattering albedo and Greek coefficients of one layer at one
/// wavelength.
pub fn layer_optics(
    path: &str,
    scatterer: &ScattererSpec,
    wavelength_nm: Option<f64>,
) -> Result<(f64, GreekCoefficients), SpecError> {
    match scatterer {
        ScattererSpec::Expansion(e) => {
            let len = [&e.beta, &e.alpha, &e.zeta, &e.delta, &e.gamma, &e.epsilon]
                .iter()
                .map(|v| v.len())
                .max()
                .unwrap_or(1);
            Ok((
                e.albedo,
                GreekCoefficients {
                    beta: padded(&e.beta, len),
                    alpha: padded(&e.alpha, len),
                    zeta: padded(&e.zeta, len),
                    delta: padded(&e.delta, len),
                    gamma: padded(&e.gamma, len),
                    epsilon: padded(&e.epsilon, len),
                },
            ))
        }
        ScattererSpec::Rayleigh {
            albedo,
            depolarization,
        } => Ok((*albedo, GreekCoefficients::rayleigh(*depolarization))),
        ScattererSpec::HenyeyGreenstein { albedo, g } => {
            // Enough terms that the series tail is below 1e-12.
            let l_max = if g.abs() < 1e-12 {
                0
            } else {
                ((1e-12f64).ln() / g.abs().ln()).ceil().max(1.0) as usize
            };
            Ok((
                *albedo,
                GreekCoefficients::henyey_greenstein(*g, l_max.min(20_000)),
            ))
        }
        ScattererSpec::Mie(m) => mie_optics(&format!("{path}.mie"), m, wavelength_nm),
    }
}

/// The solver layer of `spec.layers[i]` at one wavelength: an optical
/// layer as written, a film through [`film_optics`].
fn layer(i: usize, l: &LayerSpec, wavelength_nm: Option<f64>) -> Result<Layer, SpecError> {
    match l.valid_form() {
        LayerForm::Optical {
            thickness,
            scatterer,
        } => {
            let path = format!("layers[{i}].scatterer");
            let (albedo, coef) = layer_optics(&path, scatterer, wavelength_nm)?;
            let thickness = match thickness {
                ThicknessSpec::Number(t) => Thickness::Finite(*t),
                ThicknessSpec::Word(_) => Thickness::Infinite,
            };
            Ok(Layer {
                thickness,
                albedo,
                coef,
            })
        }
        LayerForm::Film {
            thickness_um,
            pigments,
            binder,
        } => {
            let wl = wavelength_nm
                .ok_or_else(|| SpecError::new("wavelengths_nm", "required for films"))?;
            let f = film_optics(&format!("layers[{i}]"), thickness_um, pigments, binder, wl)?;
            Ok(Layer {
                thickness: Thickness::Finite(f.optical_thickness),
                albedo: f.albedo,
                coef: f.coefficients,
            })
        }
    }
}

/// The ambient (real) and base (complex) refractive indices of a Fresnel
/// (mirror) base at one wavelength, validated; `None` for other bases
/// ([`surface_indices`]).
pub fn fresnel_indices(
    spec: &Spec,
    wavelength_nm: Option<f64>,
) -> Result<Option<(f64, RefractiveIndex)>, SpecError> {
    if !matches!(spec.base, BaseSpec::Fresnel { .. }) {
        return Ok(None);
    }
    surface_indices(spec, wavelength_nm)
}

/// The ambient (real) and base (complex) refractive indices of a smooth or
/// rough Fresnel base at one wavelength, validated; `None` for other bases.
/// The ambient index defaults to the real part of the medium of the last
/// layer's particles (a Mie host, a film's binder) at that wavelength,
/// else 1.
pub fn surface_indices(
    spec: &Spec,
    wavelength_nm: Option<f64>,
) -> Result<Option<(f64, RefractiveIndex)>, SpecError> {
    let Some((key, material, ambient_index)) = spec.base.surface() else {
        return Ok(None);
    };
    let n2 = resolve_index(&format!("base.{key}.material"), material, wavelength_nm)?;
    let n1 = match (ambient_index, spec.layers.last().and_then(|l| l.host())) {
        (Some(n), _) => n,
        (None, Some(host)) => {
            let i = spec.layers.len() - 1;
            super::mie::host_real_index(
                &format!("layers[{i}]"),
                host,
                wavelength_nm.unwrap_or(f64::NAN),
            )?
        }
        (None, None) => 1.0,
    };
    fresnel::mueller(n1, n2, 0.5)
        .map_err(|e| SpecError::new(format!("base.{key}"), e.to_string()))?;
    Ok(Some((n1, n2)))
}

/// The Fresnel reflection Mueller matrix of a mirror base as a function of
/// `μ` (indices validated by [`fresnel_indices`], so it cannot fail).
pub fn fresnel_mirror(n1: f64, n2: RefractiveIndex) -> solver::truncation::MirrorFn {
    Arc::new(move |mu: f64| fresnel::mueller(n1, n2, mu.clamp(0.0, 1.0)).unwrap_or([[0.0; 4]; 4]))
}

/// The solver problem at one wavelength (`None` for a wavelength-free spec).
pub fn problem(spec: &Spec, wavelength_nm: Option<f64>) -> Result<Problem, SpecError> {
    let mut layers = Vec::with_capacity(spec.layers.len());
    for (i, l) in spec.layers.iter().enumerate() {
        layers.push(layer(i, l, wavelength_nm)?);
    }
    let base = match &spec.base {
        BaseSpec::Black => Base::Black,
        BaseSpec::Lambertian { albedo } => Base::Lambertian { albedo: *albedo },
        BaseSpec::Fresnel { .. } => {
            let (n1, n2) =
                fresnel_indices(spec, wavelength_nm)?.expect("a Fresnel base has indices");
            Base::Mirror {
                mueller: fresnel_mirror(n1, n2),
            }
        }
        BaseSpec::RoughFresnel { alpha, .. } => {
            let (n1, n2) =
                surface_indices(spec, wavelength_nm)?.expect("a rough Fresnel base has indices");
            Base::Rough {
                surface: RoughSurface::new(n1, n2, *alpha)
                    .map_err(|e| SpecError::new("base.rough_fresnel", e.to_string()))?,
            }
        }
    };
    Ok(Problem {
        layers,
        base,
        settings: settings(spec),
        top_interface: top_interface(spec, wavelength_nm)?,
    })
}

/// The `top_interface` at one wavelength: the real part of its binder index
/// ([`crate::material::interface_index`]), which must be ≥ 1, and a rough
/// one's `alpha`.
fn top_interface(
    spec: &Spec,
    wavelength_nm: Option<f64>,
) -> Result<Option<solver::TopInterface>, SpecError> {
    let Some(host) = crate::material::interface_index(spec)? else {
        return Ok(None);
    };
    let alpha = match &spec.top_interface {
        crate::material::TopInterfaceSpec::Rough { alpha, .. } => Some(*alpha),
        _ => None,
    };
    let path = if alpha.is_some() {
        "top_interface.rough.index"
    } else {
        "top_interface.smooth.index"
    };
    let index = super::mie::host_real_index(path, &host, wavelength_nm.unwrap_or(f64::NAN))?;
    if !(index.is_finite() && index >= 1.0) {
        let at = wavelength_nm.map_or(String::new(), |w| format!(" at {w} nm"));
        return Err(SpecError::new(
            path,
            format!("the real part {index}{at} is below 1 (a binder under air has n ≥ 1)"),
        ));
    }
    Ok(Some(solver::TopInterface { index, alpha }))
}

/// The share of a `solver.tolerance` the Fourier azimuth series may leave
/// out: a tolerance `t` stops the series after two consecutive orders below
/// `1e-2 t` of order 0 (`Settings::fourier_tolerance`, never below its
/// default 1e-9). Measured (24 user cosines × 13 azimuths against the
/// converged series): the left-out tail is at most 0.24× the stopping
/// threshold (a semi-infinite conservative HG layer, g = 0.7), so at most
/// 0.0024 t; TiO2 (r = 0.2 µm) at `t = 1e-2` keeps 11 of 14 orders.
pub const FOURIER_SHARE_OF_TOLERANCE: f64 = 1e-2;

/// The solver settings of a spec (the same at every wavelength): a
/// `solver.tolerance` also bounds the Fourier orders synthesized
/// ([`FOURIER_SHARE_OF_TOLERANCE`]).
pub fn settings(spec: &Spec) -> Settings {
    let default = Settings::default();
    let fourier_tolerance = match stream_policy(spec) {
        StreamPolicy::Tolerance(t) => {
            (FOURIER_SHARE_OF_TOLERANCE * t).max(default.fourier_tolerance)
        }
        StreamPolicy::Fixed(_) => default.fourier_tolerance,
    };
    Settings {
        streams: spec.solver.streams.unwrap_or(DEFAULT_STREAMS),
        polarized: spec.solver.polarized,
        secondary_scattering: spec.solver.secondary_scattering,
        max_order: spec.needs.max_order(),
        fourier_tolerance,
        // No beam crosses a rough interface, so there is no direct beam for
        // delta-M's truncated peak to travel with: solved untruncated
        // (docs/solver.md, "A rough top interface").
        delta_m: !matches!(
            spec.top_interface,
            crate::material::TopInterfaceSpec::Rough { .. }
        ),
        ..default
    }
}

/// How the number of streams is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StreamPolicy {
    /// Exactly this many streams (given, or the default).
    Fixed(usize),
    /// The cheapest level of `solver::accuracy::tolerance_ladder` (4, 6, 8,
    /// 12, …) up to [`crate::material::MAX_STREAMS`] meeting this
    /// estimated relative error of f11.
    Tolerance(f64),
}

/// The stream policy of a spec: explicit streams win over a tolerance.
pub fn stream_policy(spec: &Spec) -> StreamPolicy {
    match (spec.solver.streams, spec.solver.tolerance) {
        (Some(n), _) => StreamPolicy::Fixed(n),
        (None, Some(t)) => StreamPolicy::Tolerance(t),
        (None, None) => StreamPolicy::Fixed(DEFAULT_STREAMS),
    }
}

/// The wavelengths to solve: the listed ones, or one wavelength-free run.
pub fn wavelengths(spec: &Spec) -> Vec<Option<f64>> {
    match &spec.wavelengths_nm {
        Some(w) => w.iter().map(|&x| Some(x)).collect(),
        None => vec![None],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::canonical::canonical_json;
    use crate::material::parse;

    /// The canonical form writes the stream count the solver is given when
    /// the spec names neither `streams` nor `tolerance`.
    #[test]
    fn the_canonical_default_streams_are_the_solved_ones() {
        let s =
            parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}]}"#)
                .unwrap();
        let streams = problem(&s, None).unwrap().settings.streams;
        assert_eq!(streams, DEFAULT_STREAMS);
        assert_eq!(stream_policy(&s), StreamPolicy::Fixed(streams));
        assert!(canonical_json(&s).contains(&format!(r#""streams":{streams}"#)));
    }

    /// `solver.secondary_scattering` reaches the solver's settings.
    #[test]
    fn secondary_scattering_reaches_the_settings() {
        let layers = r#""wavelengths_nm":[550],"layers":[{"optical_thickness":1,"scatterer":{"mie":{"material":{"n":1.5,"k":0.001},"radius_um":3.0}}}]"#;
        let on = parse(&format!("{{{layers}}}")).unwrap();
        let off = parse(&format!(
            r#"{{{layers},"solver":{{"secondary_scattering":false}}}}"#
        ))
        .unwrap();
        let settings = |s: &Spec| problem(s, Some(550.0)).unwrap().settings;
        assert!(settings(&on).secondary_scattering);
        assert!(!settings(&off).secondary_scattering);
    }

    fn mie_spec(material: &str, base: &str) -> Result<Spec, SpecError> {
        parse(&format!(
            r#"{{"wavelengths_nm":[550],"layers":[{{"optical_thickness":1,"scatterer":{{"mie":{{"material":{material},"radius_um":0.2}}}}}}],"base":{base}}}"#
        ))
    }

    fn layer(spec: &Spec) -> Layer {
        problem(spec, Some(550.0)).unwrap().layers[0].clone()
    }

    /// The four material forms (docs/spec.md "Materials"): a plain name is
    /// the measured table, `"source": "measured"` the same (and the same
    /// canonical form), `"source": "seed"` the seed's Table 2 (its own
    /// canonical form), a table that is constant equals the `{n, k}` it
    /// repeats, and a table equal to a built-in's rows equals the built-in.
    #[test]
    fn material_forms_lower_to_their_indices() {
        let plain = mie_spec(r#""TiO2""#, r#""black""#).unwrap();
        let measured = mie_spec(r#"{"name":"rutile","source":"measured"}"#, r#""black""#).unwrap();
        let seed = mie_spec(r#"{"name":"titania","source":"seed"}"#, r#""black""#).unwrap();
        assert_eq!(canonical_json(&plain), canonical_json(&measured));
        assert_ne!(canonical_json(&plain), canonical_json(&seed));
        assert!(canonical_json(&seed).contains(r#""material":{"name":"TiO2","source":"seed"}"#));
        assert_eq!(layer(&plain).coef, layer(&measured).coef);
        let seed_index = mie_spec(r#"{"n":2.954,"k":0.0}"#, r#""black""#).unwrap();
        assert_eq!(layer(&seed).coef, layer(&seed_index).coef);
        assert_ne!(layer(&plain).coef, layer(&seed).coef);
        let table = mie_spec(r#"{"table":[[500,2.954,0],[600,2.954,0]]}"#, r#""black""#).unwrap();
        assert_eq!(layer(&table).coef, layer(&seed_index).coef);
        let rows = crate::physics::materials::find("TiO2").unwrap().table;
        let as_table = serde_json::json!({ "table": rows }).to_string();
        let tab = mie_spec(&as_table, r#""black""#).unwrap();
        assert_eq!(layer(&tab).coef, layer(&plain).coef);
        // A Fresnel base takes the same forms.
        let silver = mie_spec(
            r#""TiO2""#,
            r#"{"fresnel":{"material":{"name":"Ag","source":"seed"}}}"#,
        );
        assert!(canonical_json(&silver.unwrap()).contains(r#"{"name":"silver","source":"seed"}"#));
    }

    /// Bad material inputs are refused with the path of the bad value.
    #[test]
    fn bad_materials_name_their_path() {
        let err = |m: &str| mie_spec(m, r#""black""#).unwrap_err();
        let q = "layers[0].scatterer.mie.material";
        for (m, path) in [
            (
                r#"{"name":"chromium","source":"seed"}"#,
                format!("{q}.source"),
            ),
            (r#"{"name":"TiO2","source":"guess"}"#, format!("{q}.source")),
            (r#"{"name":"unobtainium"}"#, format!("{q}.name")),
            (r#"{"table":[]}"#, format!("{q}.table")),
            (
                r#"{"table":[[500,1.5,0],[400,1.5,0]]}"#,
                format!("{q}.table[1][0]"),
            ),
            (r#"{"table":[[500,1.5,-0.1]]}"#, format!("{q}.table[0][2]")),
            (r#"{"table":[[500,0,0]]}"#, format!("{q}.table[0][1]")),
        ] {
            assert_eq!(err(m).path, path, "{m}");
        }
        // A table that does not cover the wavelength is refused before solving.
        let s = mie_spec(r#"{"table":[[600,1.5,0],[700,1.6,0]]}"#, r#""black""#).unwrap();
        let e = crate::plan::check_solvable(&s, crate::material::MAX_STREAMS).unwrap_err();
        assert!(e.path.starts_with("wavelengths_nm"), "{e:?}");
        assert!(e.message.contains("[600, 700] nm"), "{e:?}");
    }
}
