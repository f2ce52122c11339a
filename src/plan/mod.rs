//! Lowering: a validated spec (`crate::material`), once, into what the table
//! builder and the job layer run (docs/service.md, docs/solver.md).
//!
//! A [`Plan`] holds the canonical physical spec and its id ([`id`]), the
//! stream policy and the solver settings, and per wavelength the solver
//! problem with Mie theory and the expansion done. Before, the table
//! builder lowered the spec again only to read its settings, and the job
//! layer once more per wavelength; now each runs once.
//!
//! * [`problem`] lowers one wavelength (`lower`): layer optics, the base,
//!   the settings;
//! * Mie layers and size distributions (`mie`), with
//!   [`max_size_parameter`], the cost the service caps;
//! * paint films ([`film`]): thickness, pigments by volume fraction and a
//!   binder, mixed into one layer per wavelength;
//! * [`check_solvable`] (`solvable`): what the physics and the solver would
//!   refuse that the spec alone decides, checked before any solve;
//! * [`id`]: the content address of the canonical form and the version
//!   label of every stored result;
//! * [`wavelength_parts`] (`parts`): the one-wavelength requests a
//!   multi-wavelength request is made of, each a cached result of its own;
//! * [`spec_may_cover`] (`cover`): which cached results of the same
//!   [`family_of_spec`] may answer a request.

mod cover;
pub mod film;
pub mod id;
mod lower;
mod mie;
mod parts;
mod solvable;

pub use cover::{CoverCheck, family_of_canonical, family_of_spec, spec_may_cover, stokes_contains};
pub use film::{DENSE_PVC, FilmOptics, PigmentOptics, film_optics, film_warnings};
pub use id::{
    SCHEMA_VERSION, SOLVER_VERSION, id_of_canonical, id_of_spec, id_preimage, is_id, result_version,
};
pub use lower::{
    StreamPolicy, fresnel_indices, fresnel_mirror, layer_optics, problem, settings, stream_policy,
    surface_indices, wavelengths,
};
pub use mie::{max_size_parameter, populations};
pub use parts::{WavelengthPart, wavelength_parts};
pub use solvable::check_solvable;

use crate::material::needs::Needs;
use crate::material::{Spec, SpecError};
use crate::physics::RefractiveIndex;
use crate::solver::{Problem, Settings};

/// A spec lowered for solving.
#[derive(Clone)]
pub struct Plan {
    /// The canonical physical spec (JSON text) the id hashes.
    pub canonical_json: String,
    /// The result id: SHA-256 of the canonical form and the result version.
    pub id: String,
    /// Fixed streams or a tolerance.
    pub policy: StreamPolicy,
    /// The solver settings (the same at every wavelength).
    pub settings: Settings,
    /// Per wavelength, in the spec's order.
    pub wavelengths: Vec<Lowered>,
    /// What the request needs of its result (normalized).
    pub needs: Needs,
}

/// One wavelength of a [`Plan`].
#[derive(Clone)]
pub struct Lowered {
    /// `None` for a wavelength-free spec.
    pub wavelength_nm: Option<f64>,
    /// The solver problem (Mie and expansion done).
    pub problem: Problem,
    /// A Fresnel base's `(n_above, n_base)` at this wavelength.
    pub mirror_indices: Option<(f64, RefractiveIndex)>,
}

impl Plan {
    /// Lower a validated spec (`crate::material::parse`); fails as [`problem`]
    /// does (a Mie or expansion refusal, naming the layer).
    pub fn lower(spec: &Spec) -> Result<Self, SpecError> {
        Self::lower_naming_wavelength(spec).map_err(|(e, _)| e)
    }

    /// [`Plan::lower`], its error with the wavelength being lowered.
    pub fn lower_naming_wavelength(spec: &Spec) -> Result<Self, (SpecError, Option<f64>)> {
        let (canonical_json, id) = id_of_spec(spec);
        let mut lowered = Vec::new();
        for wl in wavelengths(spec) {
            let at = |e| (e, wl);
            lowered.push(Lowered {
                wavelength_nm: wl,
                problem: problem(spec, wl).map_err(at)?,
                mirror_indices: fresnel_indices(spec, wl).map_err(at)?,
            });
        }
        Ok(Self {
            canonical_json,
            id,
            policy: stream_policy(spec),
            settings: settings(spec),
            wavelengths: lowered,
            needs: spec.needs.normalized(),
        })
    }

    /// The canonical spec as a JSON value (what a table's metadata stores).
    pub fn canonical_spec(&self) -> serde_json::Value {
        serde_json::from_str(&self.canonical_json).expect("canonical JSON")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::parse;

    #[test]
    fn a_plan_holds_one_problem_per_wavelength_and_the_service_id() {
        let s = parse(
            r#"{"layers":[{"optical_thickness":1,"scatterer":{"mie":{"material":"TiO2","radius_um":0.2}}}],
                "base":{"fresnel":{"material":"silver"}},"wavelengths_nm":[650,450,550],
                "solver":{"streams":8}}"#,
        )
        .unwrap();
        let plan = Plan::lower(&s).unwrap();
        assert_eq!(plan.id, id_of_spec(&s).1);
        let wl: Vec<_> = plan.wavelengths.iter().map(|w| w.wavelength_nm).collect();
        assert_eq!(wl, [Some(650.0), Some(450.0), Some(550.0)]);
        for w in &plan.wavelengths {
            // The same problem a separate lowering of that wavelength gives.
            let p = problem(&s, w.wavelength_nm).unwrap();
            assert_eq!(w.problem.layers[0].coef.beta, p.layers[0].coef.beta);
            assert_eq!(w.problem.layers[0].albedo, p.layers[0].albedo);
            assert!(w.mirror_indices.is_some());
        }
        // Mie at 450 nm and 650 nm differ: each wavelength was lowered itself.
        assert_ne!(
            plan.wavelengths[0].problem.layers[0].coef.beta,
            plan.wavelengths[1].problem.layers[0].coef.beta
        );
        assert_eq!(plan.settings.streams, 8);
        assert_eq!(plan.policy, StreamPolicy::Fixed(8));
    }
}
