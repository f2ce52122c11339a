//! The content address of a spec and the version of its result
//! (docs/service.md, "Canonical form and id", step 3; "Ids and versions").
//!
//! The id is the lowercase hex SHA-256 ([`crate::digest`]) of
//! `"polbrdf-spec/" + SCHEMA_VERSION + "\n" + "polbrdf-solver/" + SOLVER_VERSION + "\n" + canonical_json`,
//! with the canonical JSON of `crate::material::canonical` (steps 1 and 2).
//!
//! Mixing both versions into the hash (as sccache does) retires every cached
//! result at once when the meaning of a spec or the solver's output changes:
//! bump [`SCHEMA_VERSION`] when a field's meaning or default changes, and
//! [`SOLVER_VERSION`] when results change beyond round-off.

use crate::digest;
use crate::material::Spec;
use crate::material::canonical::canonical_json;

/// Version of the spec schema mixed into every id. Version 3: a plain
/// `"AlGaAs"` means Aspnes et al.'s measured Al₀.₈₀₄Ga₀.₁₉₆As (version 2
/// meant the seed's three values for it). Version 2: a plain
/// built-in material name means its measured table (`physics::materials`,
/// monotone cubic in wavelength); the seed's Table 2 values are
/// `{"name", "source": "seed"}`. Version 1 meant the seed's values for TiO2,
/// gold, iron oxide, AlGaAs and silver, interpolated linearly.
pub const SCHEMA_VERSION: &str = "3";

/// Version of the solver's results mixed into every id. Version 7: a
/// pair's azimuth series across a facet total-reflection edge is
/// integrated by split Gauss rules (`solver::azimuth`), not the FFT, and
/// fine panels are graded geometrically towards every kernel edge
/// (`solver::rough_base::stretch_panels`), and every second ordinate ends
/// one too (the Lagrange basis of a many-stream part is resolved): results
/// under a rough interface and over any rough base moved (by up to 2.5e-5
/// of the largest value where light is trapped over a polarizing mirror,
/// at 32 streams). Version 6: the
/// fine panels of a rough surface's projection end at its kernels' edges
/// (facet total reflection, the transmission's jump and largest
/// deviation) and a rough interface's transmission panels are as narrow
/// as its refracted lobe (`solver::rough_base`, "Edges"): results under a
/// rough interface and over a rough dielectric base of lower index than
/// its ambient moved by up to 3e-6 1/sr. Version 5: the
/// error estimate also credits the levels' observed algebraic order
/// (`solver::accuracy` (A3)), so stated estimates of pre-asymptotic solves
/// grew, and a `solver.tolerance` level's last change is measured from the
/// previous level's answer (with its secondary correction), not from the
/// estimate's re-solved coarse level: tolerance specs may stop elsewhere.
/// Version 4: a
/// `solver.tolerance` also bounds the Fourier orders synthesized
/// (`plan::FOURIER_SHARE_OF_TOLERANCE`), so results of tolerance specs
/// changed. Version 3: the Greek coefficient `ε` is read and written in the
/// Siewert sign of conventions §4 (`b2 = −Σ ε_l d^l_02`); version 2 read a
/// user's `ε` with the opposite sign.
pub const SOLVER_VERSION: &str = "7";

/// The version label stored with every cached row: `"polbrdf-spec/S
/// polbrdf-solver/V"`. A row with another label is never served (docs/service.md).
pub fn result_version() -> String {
    format!("polbrdf-spec/{SCHEMA_VERSION} polbrdf-solver/{SOLVER_VERSION}")
}

/// The bytes that are hashed into an id: the two version lines and the
/// canonical JSON (step 3 of the module documentation).
pub fn id_preimage(canonical_json: &str) -> String {
    format!("polbrdf-spec/{SCHEMA_VERSION}\npolbrdf-solver/{SOLVER_VERSION}\n{canonical_json}")
}

/// The id of a canonical JSON text.
pub fn id_of_canonical(canonical_json: &str) -> String {
    digest::sha256_hex(id_preimage(canonical_json).as_bytes())
}

/// The content address of a spec: its canonical JSON and its id.
pub fn id_of_spec(spec: &Spec) -> (String, String) {
    let c = canonical_json(spec);
    let id = id_of_canonical(&c);
    (c, id)
}

/// True for a well-formed id (64 lowercase hex digits).
pub fn is_id(s: &str) -> bool {
    digest::is_sha256_hex(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::parse;

    #[test]
    fn equal_canonical_forms_have_equal_ids() {
        let a =
            parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}]}"#)
                .unwrap();
        let b = parse(
            r#"{ "solver": {"polarized": true, "streams": 16}, "base": "black",
                 "layers": [ {"scatterer": {"rayleigh": {"depolarization": 0.0, "albedo": 1.0}},
                              "optical_thickness": 1.0} ] }"#,
        )
        .unwrap();
        assert_eq!(id_of_spec(&a), id_of_spec(&b));
        let (c, id) = id_of_spec(&a);
        assert_eq!(id, digest::sha256_hex(id_preimage(&c).as_bytes()));
        assert!(id_preimage(&c).starts_with("polbrdf-spec/3\npolbrdf-solver/7\n{"));
    }

    #[test]
    fn different_physics_different_id() {
        let a =
            parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}]}"#)
                .unwrap();
        let b = parse(
            r#"{"layers":[{"optical_thickness":1.0000000000000002,"scatterer":{"rayleigh":{"albedo":1}}}]}"#,
        )
        .unwrap();
        assert_ne!(id_of_spec(&a).1, id_of_spec(&b).1);
        assert!(is_id(&id_of_spec(&a).1));
    }

    /// `solver.secondary_scattering = false` is another computation: another id.
    #[test]
    fn secondary_scattering_off_is_another_id() {
        let layers = r#""wavelengths_nm":[550],"layers":[{"optical_thickness":1,"scatterer":{"mie":{"material":{"n":1.5,"k":0.001},"radius_um":3.0}}}]"#;
        let on = parse(&format!("{{{layers}}}")).unwrap();
        let off = parse(&format!(
            r#"{{{layers},"solver":{{"secondary_scattering":false}}}}"#
        ))
        .unwrap();
        assert_ne!(id_of_spec(&on).1, id_of_spec(&off).1);
    }
}
