//! Per-wavelength results (docs/service.md, "Per-wavelength results"): a
//! request for wavelengths `[a, b, c]` is the set of the one-wavelength
//! requests `[a]`, `[b]`, `[c]` with the same physical spec, needs and
//! solver settings. Each is a result of its own, content-addressed like any
//! spec (its id is the id of the spec with `wavelengths_nm: [λ]`), so a
//! later request that shares wavelengths reuses them, and a request whose
//! wavelengths are all cached is assembled without a solve.
//!
//! A wavelength is solved independently of the others (`Plan::lower`
//! lowers each on its own, the table builder solves each on its own), so a
//! table assembled from its parts holds the same numbers as the table
//! solved in one go (`tests/service_parts.rs` checks it byte for byte).

use super::id::id_of_spec;
use crate::material::Spec;

/// One wavelength of a multi-wavelength request, as a request of its own.
#[derive(Clone, Debug, PartialEq)]
pub struct WavelengthPart {
    /// The vacuum wavelength (nm).
    pub wavelength_nm: f64,
    /// The request's spec with `wavelengths_nm: [wavelength_nm]`.
    pub spec: Spec,
    /// Its canonical JSON.
    pub canonical_json: String,
    /// Its id.
    pub id: String,
}

/// The one-wavelength parts of a spec, in the spec's order; empty for a
/// spec with at most one wavelength (it is its own part).
pub fn wavelength_parts(spec: &Spec) -> Vec<WavelengthPart> {
    let Some(wavelengths) = spec.wavelengths_nm.as_ref().filter(|w| w.len() > 1) else {
        return Vec::new();
    };
    wavelengths
        .iter()
        .map(|&wavelength_nm| {
            let mut one = spec.clone();
            one.wavelengths_nm = Some(vec![wavelength_nm]);
            let (canonical_json, id) = id_of_spec(&one);
            WavelengthPart {
                wavelength_nm,
                spec: one,
                canonical_json,
                id,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::parse;

    fn spec(wavelengths: &str) -> Spec {
        parse(&format!(
            r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"mie":{{"material":"TiO2","radius_um":0.2}}}}}}],
                "wavelengths_nm":{wavelengths},"solver":{{"streams":8}}}}"#
        ))
        .unwrap()
    }

    #[test]
    fn a_part_is_the_one_wavelength_request() {
        let parts = wavelength_parts(&spec("[650, 450]"));
        assert_eq!(parts.len(), 2);
        assert_eq!(parts[0].wavelength_nm, 650.0);
        // The id a client submitting `[650]` alone gets.
        assert_eq!(parts[0].id, id_of_spec(&spec("[650]")).1);
        assert_eq!(parts[1].id, id_of_spec(&spec("[450.0]")).1);
        assert_ne!(parts[0].id, parts[1].id);
    }

    #[test]
    fn one_wavelength_or_none_has_no_parts() {
        assert!(wavelength_parts(&spec("[550]")).is_empty());
        let free =
            parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}]}"#)
                .unwrap();
        assert!(wavelength_parts(&free).is_empty());
    }
}
