//! Which cached results may cover a request (docs/service.md, "Covering
//! results"): the spec-level half of the rule. The table-level half (the
//! incident nodes held, the orders stored, the estimate stated) needs the
//! cached table and is `brdf::Table::cover`.
//!
//! A result covers a request when it holds everything the request needs,
//! at least as accurately:
//!
//! * the same **family**: the same canonical physical spec, wavelengths and
//!   solver settings except the accuracy choice (`solver.streams`,
//!   `solver.tolerance`) and `needs` ([`family_of_spec`]);
//! * **accuracy**: a request with fixed streams only by a result of the
//!   same streams (the computation it names); a request with
//!   `solver.tolerance = t` by any result whose stated estimate is at most
//!   `t` at every wavelength (checked on the table);
//! * **estimate**: a request that needs one only by a result that has one;
//! * **stokes**: `full` ⊇ `unpolarized_in` ⊇ `intensity`;
//! * **grid**: a result on as many or more polar nodes (more nodes: served
//!   by interpolation onto the request's grid, its error measured and
//!   stated); at least the request's Fourier orders (a result with more is
//!   cut, unless the request needs an estimate: the estimate of a cut
//!   series is not the estimate of the whole one);
//! * **incident angles**: every incident node the request holds can be
//!   evaluated on the result (checked on the table).

use super::id::id_of_canonical;
use crate::material::Spec;
use crate::material::canonical::{canonical_value, write_canonical};
use crate::material::needs::StokesNeed;

/// The family of a canonical spec: the id of its canonical form without
/// `needs` and without `solver.streams` and `solver.tolerance`. Results of
/// one family are the same physics at the same wavelengths, solved the same
/// way up to their accuracy and their needs. `None` for a text that is not
/// a JSON object.
pub fn family_of_canonical(canonical_json: &str) -> Option<String> {
    let mut v: serde_json::Value = serde_json::from_str(canonical_json).ok()?;
    let o = v.as_object_mut()?;
    o.remove("needs");
    if let Some(solver) = o.get_mut("solver").and_then(|s| s.as_object_mut()) {
        solver.remove("streams");
        solver.remove("tolerance");
    }
    let mut text = String::new();
    write_canonical(&v, &mut text);
    Some(id_of_canonical(&format!("family\n{text}")))
}

/// [`family_of_canonical`] of a spec's canonical form.
pub fn family_of_spec(spec: &Spec) -> String {
    let mut text = String::new();
    write_canonical(&canonical_value(spec), &mut text);
    family_of_canonical(&text).expect("a canonical spec is a JSON object")
}

/// Does stokes need `held` contain `asked`?
pub fn stokes_contains(held: StokesNeed, asked: StokesNeed) -> bool {
    let rank = |s: StokesNeed| match s {
        StokesNeed::Intensity => 0,
        StokesNeed::UnpolarizedIn => 1,
        StokesNeed::Full => 2,
    };
    rank(held) >= rank(asked)
}

/// What the table-level check must still see for `candidate` to cover a
/// request ([`spec_may_cover`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoverCheck {
    /// The request's `solver.tolerance`: every wavelength of the candidate
    /// must state an estimate at most this.
    pub max_estimate: Option<f64>,
    /// The candidate is on more polar nodes: resample onto the request's.
    pub resample: bool,
}

/// The spec-level rule (module doc): `Ok` with what the table must still
/// show, or why `candidate` cannot cover `request`.
pub fn spec_may_cover(candidate: &Spec, request: &Spec) -> Result<CoverCheck, String> {
    if family_of_spec(candidate) != family_of_spec(request) {
        return Err("another physical spec".into());
    }
    let (c, r) = (candidate.needs.normalized(), request.needs.normalized());
    let max_estimate = match (request.solver.streams, request.solver.tolerance) {
        (None, Some(t)) => Some(t),
        _ => {
            let streams = |s: &Spec| super::settings(s).streams;
            let fixed = |s: &Spec| s.solver.streams.is_some() || s.solver.tolerance.is_none();
            if !fixed(candidate) || streams(candidate) != streams(request) {
                return Err("other streams".into());
            }
            None
        }
    };
    if (r.error_estimate || max_estimate.is_some()) && !c.error_estimate {
        return Err("no error estimate".into());
    }
    if !stokes_contains(c.stokes, r.stokes) {
        return Err(format!(
            "stokes {} does not hold {}",
            c.stokes.name(),
            r.stokes.name()
        ));
    }
    let (cn, rn) = (c.polar_nodes(), r.polar_nodes());
    if cn < rn {
        return Err(format!("{cn} polar nodes, fewer than {rn}"));
    }
    match (c.max_order(), r.max_order()) {
        (Some(_), None) => return Err("a capped Fourier series".into()),
        (Some(a), Some(b)) if a < b => return Err("fewer Fourier orders".into()),
        _ => {}
    }
    Ok(CoverCheck {
        max_estimate,
        resample: cn != rn,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::parse;

    fn spec(solver: &str, needs: &str) -> Spec {
        parse(&format!(
            r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"mie":{{"material":"TiO2","radius_um":0.2}}}}}}],
                "wavelengths_nm":[550],"solver":{solver},"needs":{needs}}}"#
        ))
        .unwrap()
    }

    #[test]
    fn the_family_ignores_needs_and_accuracy_only() {
        let full = spec(r#"{"streams":16}"#, "{}");
        let f = family_of_spec(&full);
        assert_eq!(
            f,
            family_of_spec(&spec(
                r#"{"tolerance":1e-3}"#,
                r#"{"stokes":"intensity","grid":{"polar_nodes":16}}"#
            ))
        );
        assert_ne!(f, family_of_spec(&spec(r#"{"polarized":false}"#, "{}")));
        assert_ne!(
            f,
            family_of_spec(&spec(r#"{"secondary_scattering":false}"#, "{}"))
        );
        let mut other = full.clone();
        other.wavelengths_nm = Some(vec![551.0]);
        assert_ne!(f, family_of_spec(&other));
        // Not an id of any spec.
        assert_ne!(f, super::super::id_of_spec(&full).1);
    }

    #[test]
    fn more_covers_less_and_never_the_reverse() {
        let full = spec("{}", "{}");
        let reduced = spec(
            "{}",
            r#"{"stokes":"unpolarized_in","theta_i_deg":[30],"error_estimate":false,
                "grid":{"polar_nodes":16,"max_fourier_orders":4}}"#,
        );
        let check = spec_may_cover(&full, &reduced).unwrap();
        assert!(check.resample);
        assert_eq!(check.max_estimate, None);
        assert!(spec_may_cover(&reduced, &full).is_err());
        assert!(spec_may_cover(&full, &full).is_ok());
        // Each need on its own.
        for (held, asked) in [
            (
                r#"{"stokes":"intensity"}"#,
                r#"{"stokes":"unpolarized_in"}"#,
            ),
            (r#"{"error_estimate":false}"#, "{}"),
            (
                r#"{"grid":{"polar_nodes":16}}"#,
                r#"{"grid":{"polar_nodes":17}}"#,
            ),
            (
                r#"{"grid":{"max_fourier_orders":3}}"#,
                r#"{"grid":{"max_fourier_orders":4}}"#,
            ),
            (r#"{"grid":{"max_fourier_orders":3}}"#, "{}"),
        ] {
            let e = spec_may_cover(&spec("{}", held), &spec("{}", asked));
            assert!(e.is_err(), "{held} must not cover {asked}");
        }
    }

    #[test]
    fn fixed_streams_are_the_computation_a_tolerance_is_a_bound() {
        let s16 = spec(r#"{"streams":16}"#, "{}");
        let s32 = spec(r#"{"streams":32}"#, "{}");
        let default = spec("{}", "{}");
        let tol = spec(r#"{"tolerance":1e-3}"#, "{}");
        assert!(spec_may_cover(&s32, &s16).is_err());
        assert!(spec_may_cover(&default, &s16).is_ok());
        assert!(spec_may_cover(&tol, &s16).is_err());
        for candidate in [&s16, &s32, &spec(r#"{"tolerance":1e-5}"#, "{}")] {
            let c = spec_may_cover(candidate, &tol).unwrap();
            assert_eq!(c.max_estimate, Some(1e-3));
        }
        let no_estimate = spec(r#"{"streams":32}"#, r#"{"error_estimate":false}"#);
        assert!(spec_may_cover(&no_estimate, &tol).is_err());
    }
}
