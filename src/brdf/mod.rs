//! BRDF tables that renderers load: build from a material spec, evaluate at
//! any direction pair, export (docs/table-format.md).
//!
//! * [`table`]: per wavelength the Fourier coefficients `f^m(μ_o, μ_i)` of
//!   the 4×4 Mueller BRDF on a polar grid ([`grid`]), point evaluation by
//!   interpolation in the cosines and an exact Fourier sum in azimuth.
//! * [`metadata`]: the JSON metadata of a table and the direction pairs it
//!   is queried at.
//! * [`build`]: solving a spec into a table's blocks (the kept part).
//! * [`frames`]: evaluation from local-frame unit vectors and rotation of the
//!   Stokes reference frames (conventions §5).
//! * [`format`]: the binary table file (magic, version, SHA-256).
//! * [`export`]: dense NumPy arrays, JSON point sets, CSV slices.
//! * [`coverage`]: the part of a table a request needs (`needs.stokes`,
//!   `needs.theta_i_deg`): elements and incident nodes kept, queries allowed.
//! * [`angles`]: graphics angles ↔ solver quantities (conventions §5).
//! * [`mitsuba`]: Mitsuba 3 `measured_polarized` tensor files (docs/mitsuba.md).
//!
//! Layering: `cli` → `brdf` → `plan`, `material`, `solver` → `physics`. Everything but
//! the file helpers in [`format`] and [`export`] is pure.

pub mod angles;
mod assemble;
pub mod build;
mod cover;
pub mod coverage;
pub mod export;
pub mod format;
pub mod frames;
pub mod grid;
pub mod metadata;
pub mod mitsuba;
pub mod table;

pub use frames::rotate_to_frames;
pub use grid::PolarGrid;
pub use table::{Directions, Table, WavelengthTable, build};

use crate::material::SpecError;
use crate::solver::SolverError;

/// Errors of table building, evaluation and files.
#[derive(Debug, thiserror::Error)]
pub enum BrdfError {
    /// The spec cannot be turned into a problem.
    #[error("{0}")]
    Spec(#[from] SpecError),
    /// The solver failed.
    #[error("{0}")]
    Solver(#[from] SolverError),
    /// A query (angles, wavelength, vectors) is invalid for this table.
    #[error("{0}")]
    Query(String),
    /// A table file is malformed (truncated, bad magic, version or checksum).
    #[error("{0}")]
    Format(String),
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
}
