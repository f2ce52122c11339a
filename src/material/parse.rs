//! Reading JSON: the one reader of JSON inputs (specs, eval bodies, points
//! and field files, scenes: exactly one JSON document, errors naming the
//! JSON path, `$` for the document, and nothing but whitespace after it),
//! and [`parse`], which reads a spec: the objects of the schema with exactly
//! one key (a scatterer, a base, a size distribution) named as such, no
//! struct written as an array, then [`super::validate`].

use super::validate::{with_allowed_range, without_indices};
use super::{
    BaseSpec, SCATTERERS, ScattererSpec, SizeDistributionSpec, Spec, SpecError, TOP_INTERFACES,
    TopInterfaceSpec, validate,
};
use serde::Deserialize;
use serde::de::DeserializeOwned;

/// Parse JSON text into a spec; errors carry the JSON path. Exactly one
/// JSON document: trailing data is an error ([`from_json_str`]).
pub fn parse(text: &str) -> Result<Spec, SpecError> {
    // serde accepts a struct written as an array too; a spec is an object.
    if let Some(c) = text.trim_start().chars().next()
        && c != '{'
    {
        return Err(SpecError::new("$", "the spec must be a JSON object"));
    }
    let spec: Spec = from_json_str(text).map_err(with_allowed_range)?;
    let tree: serde_json::Value = from_json_str(text)?;
    objects_not_arrays(&tree, &mut String::new())?;
    validate(&spec)?;
    Ok(spec)
}

/// The spec's arrays: `layers`, `wavelengths_nm`, the Greek coefficients,
/// a list of incident angles (`needs.theta_i_deg`), a film's `pigments`
/// and a material table (of a particle, a host, a binder or the base) with
/// its `[wavelength_nm, n, k]` rows.
const ARRAYS: [&str; 24] = [
    "layers",
    "wavelengths_nm",
    "needs.theta_i_deg",
    "layers[].scatterer.expansion.beta",
    "layers[].scatterer.expansion.alpha",
    "layers[].scatterer.expansion.zeta",
    "layers[].scatterer.expansion.delta",
    "layers[].scatterer.expansion.gamma",
    "layers[].scatterer.expansion.epsilon",
    "layers[].scatterer.mie.material.table",
    "layers[].scatterer.mie.material.table[]",
    "base.fresnel.material.table",
    "base.fresnel.material.table[]",
    "layers[].scatterer.mie.host_index.table",
    "layers[].scatterer.mie.host_index.table[]",
    "layers[].pigments",
    "layers[].pigments[].material.table",
    "layers[].pigments[].material.table[]",
    "layers[].binder.table",
    "layers[].binder.table[]",
    "top_interface.smooth.index.table",
    "top_interface.smooth.index.table[]",
    "top_interface.rough.index.table",
    "top_interface.rough.index.table[]",
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

/// Parse one JSON document from `bytes` into `T`. Errors carry the JSON path
/// of the problem; anything but whitespace after the document is refused
/// with "trailing data after the JSON document at line L column C".
pub fn from_json_slice<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, SpecError> {
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let value: T = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let path = e.path().to_string();
        SpecError::new(
            if path == "." { "$".into() } else { path },
            e.inner().to_string(),
        )
    })?;
    de.end().map_err(|e| trailing(&e))?;
    Ok(value)
}

/// [`from_json_slice`] of a string.
pub fn from_json_str<T: DeserializeOwned>(text: &str) -> Result<T, SpecError> {
    from_json_slice(text.as_bytes())
}

/// The error of [`serde_json::Deserializer::end`]: where the trailing data
/// starts (1-based line and column, as serde_json counts them).
fn trailing(e: &serde_json::Error) -> SpecError {
    SpecError::new(
        "$",
        format!(
            "trailing data after the JSON document at line {} column {}",
            e.line(),
            e.column()
        ),
    )
}

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
pub(super) fn one_key<'de, D, T>(d: D) -> Result<T, D::Error>
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
pub(super) fn some_one_key<'de, D, T>(d: D) -> Result<Option<T>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de> + OneOf,
{
    one_key(d).map(Some)
}

/// The keys of a one-key object and which one a value was written with.
pub(super) trait OneOf {
    const KEYS: &'static [&'static str];
    fn key_of(&self) -> &'static str;
}

impl OneOf for BaseSpec {
    const KEYS: &'static [&'static str] = &["black", "lambertian", "fresnel", "rough_fresnel"];
    fn key_of(&self) -> &'static str {
        match self {
            Self::Black => "black",
            Self::Lambertian { .. } => "lambertian",
            Self::Fresnel { .. } => "fresnel",
            Self::RoughFresnel { .. } => "rough_fresnel",
        }
    }
}

impl OneOf for TopInterfaceSpec {
    const KEYS: &'static [&'static str] = &TOP_INTERFACES;
    fn key_of(&self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Smooth { .. } => "smooth",
            Self::Rough { .. } => "rough",
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

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    struct Doc {
        #[allow(dead_code)]
        a: u32,
    }

    #[test]
    fn whitespace_after_the_document_is_fine() {
        assert!(from_json_str::<Doc>("  {\"a\": 1} \n\t \r\n").is_ok());
    }

    #[test]
    fn trailing_data_is_refused_where_it_starts() {
        // The second document starts on line 2, column 3 (1-based).
        let e = from_json_str::<Doc>("{\"a\": 1}\n  {\"a\": 2}").unwrap_err();
        assert_eq!(e.path, "$");
        assert_eq!(
            e.message,
            "trailing data after the JSON document at line 2 column 3"
        );
        let e = from_json_str::<Doc>("{\"a\": 1} xx").unwrap_err();
        assert_eq!(
            e.message,
            "trailing data after the JSON document at line 1 column 10"
        );
    }

    #[test]
    fn unknown_key_names_path() {
        let e = parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1,"depol":0}}}]}"#)
            .unwrap_err();
        assert!(e.path.starts_with("layers[0].scatterer"), "{e}");
        assert!(e.message.contains("depol"), "{e}");
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
                "exactly one of black, lambertian, fresnel, rough_fresnel (found lambertian and fresnel)"
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
            Some(ScattererSpec::Rayleigh {
                albedo: 1.0,
                depolarization: 0.0
            })
        );
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
