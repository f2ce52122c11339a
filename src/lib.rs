//! polbrdf: polarized BRDFs of particulate layers from first principles.
//!
//! Layers (dependencies point downwards only): `cli`, `http` -> `jobs`,
//! `storage`, `fetch` -> `brdf` -> `plan` (lowering) -> `material` (the spec) ->
//! `solver` -> `physics`. `physics` and `solver` are pure: no I/O.
//! Conventions (units, Stokes frames, signs) are in `docs/conventions.md`.

pub mod brdf;
pub mod cli;
pub mod digest;
pub mod fetch;
pub mod http;
pub mod jobs;
pub mod material;
pub mod physics;
pub mod plan;
pub mod plot;
pub mod render;
pub mod solver;
pub mod storage;
