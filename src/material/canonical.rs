//! Canonical form of a parsed spec (docs/service.md, "Canonical form and
//! id", steps 1 and 2; the id of step 3 is `crate::plan::id`).
//!
//! Two specs that mean the same computation get the same bytes, hence the
//! same id, so the service solves each material once:
//!
//! 1. defaults are filled in (`base`, `solver.polarized`, `solver.streams`
//!    unless a `tolerance` chooses it, `host_index`, `depolarization`, the
//!    Fresnel `ambient_index`; a `tolerance` next to explicit `streams` is
//!    ignored by the solver and dropped; `solver.secondary_scattering` is
//!    the exception, written only when `false`, so that specs older than
//!    the field keep their bytes), built-in material names
//!    are replaced by their canonical name (`"titania"` → `"TiO2"`), trailing
//!    zeros of expansion series are dropped (missing entries are 0) and `-0`
//!    is written `0`;
//! 2. the JSON text has its object keys sorted (byte order), no whitespace,
//!    and every number in serde_json's shortest round-trip form (`1.0`,
//!    `1e-6`, `0.973527`; integers such as `streams` without a fraction).

use super::{
    DEFAULT_STREAMS, ExpansionSpec, HostSpec, MaterialSpec, ScattererSpec, Spec, TopInterfaceSpec,
};
use crate::physics::materials;
use serde_json::Value;

/// The spec with the defaults of its own fields filled in and equivalent
/// spellings unified (step 1 of the module documentation, except the solver
/// defaults, which [`canonical_value`] makes explicit).
pub fn normalized(spec: &Spec) -> Spec {
    let mut s = spec.clone();
    for layer in &mut s.layers {
        if let Some(super::ThicknessSpec::Number(t)) = &mut layer.optical_thickness {
            *t = unsigned_zero(*t);
        }
        match &mut layer.scatterer {
            Some(ScattererSpec::Mie(m)) => {
                canonical_material(&mut m.material);
                canonical_host(&mut m.host_index);
            }
            Some(ScattererSpec::Expansion(e)) => trim_expansion(e),
            Some(ScattererSpec::Rayleigh { .. } | ScattererSpec::HenyeyGreenstein { .. })
            | None => {}
        }
        if let Some(pigments) = &mut layer.pigments {
            for p in pigments {
                canonical_material(&mut p.material);
            }
            canonical_host(layer.binder.get_or_insert_with(HostSpec::default));
        }
    }
    // The Fresnel base's ambient index defaults to the host of the last
    // layer's particles: written when it is one number, else left to the
    // lowering (a dispersive binder's real part at each wavelength).
    let last_host = match s.layers.last().and_then(|l| l.host()) {
        Some(HostSpec::Index(n)) => Some(*n),
        Some(HostSpec::Material(_)) => None,
        None => Some(1.0),
    };
    if let Some((material, ambient_index)) = s.base.surface_mut() {
        canonical_material(material);
        if let Some(n) = last_host {
            ambient_index.get_or_insert(n);
        }
    }
    // A smooth interface's index is written, from the layers' one host
    // when it defaults to it (`interface_index`), so that both spellings
    // share an id.
    if let TopInterfaceSpec::Smooth { index } | TopInterfaceSpec::Rough { index, .. } =
        &mut s.top_interface
        && let Ok(Some(host)) = super::interface_index(spec)
    {
        *index = Some(host);
    }
    s.needs = s.needs.normalized();
    s
}

fn unsigned_zero(x: f64) -> f64 {
    if x == 0.0 { 0.0 } else { x }
}

/// Names become canonical names; `{"name", "source": "measured"}` (or no
/// source) is the plain name; the seed's data keep `"source": "seed"`; a
/// table and an index are written as given.
fn canonical_material(m: &mut MaterialSpec) {
    match m {
        MaterialSpec::Name(name) => {
            if let Ok(found) = materials::find(name) {
                *name = found.name.to_string();
            }
        }
        MaterialSpec::Named { name, source } => {
            if let Ok(found) = materials::find(name) {
                *name = found.name.to_string();
            }
            if source.as_deref() != Some("seed") {
                *m = MaterialSpec::Name(name.clone());
            }
        }
        MaterialSpec::Index { .. } | MaterialSpec::Table { .. } => {}
    }
}

/// A host given as a material is canonical as that material; a real index
/// stays a number (`{"n": 1.5, "k": 0}` and `1.5` are different bytes but
/// the same computation, so the `{n, k = 0}` form is written as the number).
pub(super) fn canonical_host(h: &mut HostSpec) {
    match h {
        HostSpec::Index(_) => {}
        HostSpec::Material(MaterialSpec::Index { n, k }) if *k == 0.0 => *h = HostSpec::Index(*n),
        HostSpec::Material(m) => canonical_material(m),
    }
}

fn trim_expansion(e: &mut ExpansionSpec) {
    while e.beta.len() > 1 && e.beta.last() == Some(&0.0) {
        e.beta.pop();
    }
    for v in [
        &mut e.alpha,
        &mut e.zeta,
        &mut e.delta,
        &mut e.gamma,
        &mut e.epsilon,
    ] {
        while v.last() == Some(&0.0) {
            v.pop();
        }
    }
}

/// The JSON value of the canonical form: [`normalized`], then the solver
/// defaults made explicit. `streams` is written whenever it decides the
/// computation: an explicit `streams` wins over a `tolerance` (which is then
/// dropped), and with neither the default stream count
/// ([`DEFAULT_STREAMS`], what `crate::plan::settings` solves with) is
/// written.
pub fn canonical_value(spec: &Spec) -> Value {
    let mut v = serde_json::to_value(normalized(spec)).expect("a spec serializes to JSON");
    if let Some(solver) = v.get_mut("solver").and_then(Value::as_object_mut) {
        let streams = solver.get("streams").is_some_and(|s| !s.is_null());
        let tolerance = solver.get("tolerance").is_some_and(|t| !t.is_null());
        if streams {
            solver.remove("tolerance");
        } else if !tolerance {
            solver.insert("streams".into(), Value::from(DEFAULT_STREAMS));
        }
        solver.retain(|_, x| !x.is_null());
    }
    v
}

/// Canonical JSON text of a spec (steps 1 and 2 of the module
/// documentation).
pub fn canonical_json(spec: &Spec) -> String {
    let mut out = String::new();
    write_canonical(&canonical_value(spec), &mut out);
    out
}

/// Write a JSON value with sorted keys, no whitespace and numbers in
/// serde_json's shortest round-trip form; `-0` becomes `0`.
pub fn write_canonical(v: &Value, out: &mut String) {
    match v {
        Value::Null | Value::Bool(_) | Value::String(_) => {
            out.push_str(&serde_json::to_string(v).expect("JSON scalar"))
        }
        Value::Number(n) => match n.as_f64() {
            Some(x) if n.is_f64() => {
                out.push_str(&serde_json::to_string(&unsigned_zero(x)).expect("finite number"))
            }
            _ => out.push_str(&n.to_string()),
        },
        Value::Array(a) => {
            out.push('[');
            for (i, x) in a.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                write_canonical(x, out);
            }
            out.push(']');
        }
        Value::Object(o) => {
            let mut keys: Vec<&String> = o.keys().collect();
            keys.sort();
            out.push('{');
            for (i, k) in keys.into_iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                out.push_str(&serde_json::to_string(k).expect("JSON key"));
                out.push(':');
                write_canonical(&o[k], out);
            }
            out.push('}');
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::parse;

    #[test]
    fn defaults_order_and_spelling_do_not_change_the_form() {
        let a =
            parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}]}"#)
                .unwrap();
        let b = parse(
            r#"{ "solver": {"polarized": true, "streams": 16}, "base": "black",
                 "layers": [ {"scatterer": {"rayleigh": {"depolarization": 0.0, "albedo": 1.0}},
                              "optical_thickness": 1.0} ] }"#,
        )
        .unwrap();
        assert_eq!(canonical_json(&a), canonical_json(&b));
        assert_eq!(
            canonical_json(&a),
            r#"{"base":"black","layers":[{"optical_thickness":1.0,"scatterer":{"rayleigh":{"albedo":1.0,"depolarization":0.0}}}],"solver":{"polarized":true,"streams":16}}"#
        );
    }

    #[test]
    fn aliases_trailing_zeros_and_ambient_default() {
        let a = parse(
            r#"{"layers":[{"optical_thickness":-0.0,"scatterer":{"expansion":{"albedo":0.9,"beta":[1,0.5,0,0],"gamma":[0,0]}}}],
                "base":{"fresnel":{"material":"Ag"}},"wavelengths_nm":[550]}"#,
        )
        .unwrap();
        let b = parse(
            r#"{"layers":[{"optical_thickness":0,"scatterer":{"expansion":{"albedo":0.9,"beta":[1,0.5]}}}],
                "base":{"fresnel":{"material":"silver","ambient_index":1}},"wavelengths_nm":[550.0]}"#,
        )
        .unwrap();
        assert_eq!(canonical_json(&a), canonical_json(&b));
        assert!(canonical_json(&a).contains(r#""material":"silver""#));
    }

    #[test]
    fn canonical_form_parses_back_to_itself() {
        for text in [
            r#"{"layers":[{"optical_thickness":1,"scatterer":{"mie":{"material":"titania","radius_um":0.2}}},
                          {"optical_thickness":"infinite","scatterer":{"henyey_greenstein":{"albedo":0.9,"g":0.7}}}],
                "base":{"lambertian":{"albedo":0.5}},"wavelengths_nm":[450,550.5],"solver":{"streams":8,"polarized":false}}"#,
            r#"{"layers":[{"optical_thickness":2e-7,"scatterer":{"mie":{"material":{"n":1.5,"k":0.001},
                 "size_distribution":{"lognormal":{"r_g_um":0.1,"sigma_g":1.5}},"host_index":1.5}}}],
                "base":{"fresnel":{"material":{"n":0.2,"k":3}}},"wavelengths_nm":[1e3]}"#,
        ] {
            let s = parse(text).unwrap();
            let c = canonical_json(&s);
            let back = parse(&c).unwrap();
            assert_eq!(canonical_json(&back), c, "idempotent");
        }
    }

    #[test]
    fn explicit_streams_win_over_a_tolerance() {
        // Only where the schema has `solver.tolerance`.
        let both = r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}],"solver":{"streams":8,"tolerance":1e-3}}"#;
        if let Ok(s) = parse(both) {
            let only = parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}],"solver":{"streams":8}}"#).unwrap();
            assert_eq!(canonical_json(&s), canonical_json(&only));
            let tol = parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}],"solver":{"tolerance":1e-3}}"#).unwrap();
            assert!(canonical_json(&tol).contains(r#""tolerance":0.001"#));
            assert!(!canonical_json(&tol).contains("streams"));
        }
    }

    #[test]
    fn different_physics_different_form() {
        let a =
            parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}]}"#)
                .unwrap();
        let b = parse(
            r#"{"layers":[{"optical_thickness":1.0000000000000002,"scatterer":{"rayleigh":{"albedo":1}}}]}"#,
        )
        .unwrap();
        assert_ne!(canonical_json(&a), canonical_json(&b));
    }

    /// `solver.secondary_scattering`: the default `true` is the absent
    /// field (ids of earlier specs are unchanged); `false` is another
    /// computation, written out (`crate::plan` tests that it reaches the
    /// solver's settings and changes the id).
    #[test]
    fn secondary_scattering_default_is_implicit() {
        let layers = r#""wavelengths_nm":[550],"layers":[{"optical_thickness":1,"scatterer":{"mie":{"material":{"n":1.5,"k":0.001},"radius_um":3.0}}}]"#;
        let absent = parse(&format!("{{{layers}}}")).unwrap();
        let on = parse(&format!(
            r#"{{{layers},"solver":{{"secondary_scattering":true}}}}"#
        ))
        .unwrap();
        let off = parse(&format!(
            r#"{{{layers},"solver":{{"secondary_scattering":false}}}}"#
        ))
        .unwrap();
        assert_eq!(canonical_json(&absent), canonical_json(&on));
        assert!(!canonical_json(&absent).contains("secondary_scattering"));
        assert!(canonical_json(&off).contains(r#""secondary_scattering":false"#));
    }

    /// `top_interface`: `"none"` is the absent field (ids of earlier specs
    /// are unchanged); a smooth interface writes its index, taken from the
    /// layers' host when left out, so the spellings of one binder share
    /// an id.
    #[test]
    fn top_interface_default_is_implicit_and_its_index_explicit() {
        let layers = r#""wavelengths_nm":[550],"layers":[{"optical_thickness":1,"scatterer":{"mie":{"material":{"n":2.6,"k":0.001},"radius_um":0.15,"host_index":1.5}}}]"#;
        let with = |t: &str| canonical_json(&parse(&format!("{{{layers}{t}}}")).unwrap());
        let absent = with("");
        assert_eq!(with(r#","top_interface":"none""#), absent);
        assert!(!absent.contains("top_interface"));
        let smooth = with(r#","top_interface":{"smooth":{}}"#);
        assert_ne!(smooth, absent);
        assert!(
            smooth.contains(r#""top_interface":{"smooth":{"index":1.5}}"#),
            "{smooth}"
        );
        assert_eq!(with(r#","top_interface":{"smooth":{"index":1.5}}"#), smooth);
        assert_eq!(
            with(r#","top_interface":{"smooth":{"index":{"n":1.5,"k":0}}}"#),
            smooth
        );
    }
}
