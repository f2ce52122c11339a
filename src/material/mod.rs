//! The material spec: the one input format of the CLI and the HTTP API
//! (docs/spec.md), as users write it.
//!
//! * `schema`: the types ([`Spec`], its layers, scatterers, base and
//!   solver settings) and [`SpecError`], a JSON path and what is allowed
//!   there;
//! * `parse`: [`parse`] reads one JSON document into a [`Spec`], errors
//!   naming the JSON path, and validates it; [`from_json_str`] and
//!   [`from_json_slice`] are the reader every JSON input of the crate uses;
//! * `validate`: [`validate`], the allowed range of every field;
//! * [`needs`]: what a request needs of its result (`needs`);
//! * [`canonical`]: the canonical form, the bytes an id hashes.
//!
//! Lowering a spec into solver problems, and the checks that need it, is
//! `crate::plan`.

pub mod canonical;
pub mod needs;
mod parse;
mod schema;
mod validate;

pub use parse::{from_json_slice, from_json_str, parse};
pub use schema::{
    BaseSpec, DEFAULT_BINDER, DEFAULT_STREAMS, ExpansionSpec, FILM_KEYS, HostSpec, LayerForm,
    LayerSpec, MaterialSpec, MieSpec, OPTICAL_KEYS, PigmentSpec, SCATTERERS, ScattererSpec,
    SizeDistributionSpec, SolverSpec, Spec, SpecError, TOP_INTERFACES, ThicknessSpec,
    TopInterfaceSpec,
};
pub use validate::{
    MAX_STREAMS, MAX_TABLE_ROWS, interface_index, validate, validate_material_table,
};
