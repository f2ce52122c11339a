//! The figures of `polbrdf plot …` as data. Each function takes parsed
//! specs or BRDF tables ([`Source`]) and checked options, makes the spec
//! edits and runs the solves it needs, and returns what to draw
//! ([`Figure`]), the plotted numbers ([`Csv`]) and a summary (settings and
//! the key numbers of each curve, `Serialize`). No files and no drawing:
//! the CLI reads the inputs, writes the outputs and prints the summary.
//!
//! The figures are those of Collin, Pattanaik, LiKamWa and Bouatouch,
//! "Computation of Polarized Subsurface BRDF for Rendering", Graphics
//! Interface 2014 ("Collin et al. 2014"), from our own solves:
//!
//! * [`dop_vs_mu`]: Fig. 8, DOP against the outgoing cosine, one curve per
//!   optical thickness of the top layer (or one from a table);
//! * [`dop_vs_tau`]: Fig. 4, DOP against the top layer's optical thickness
//!   for several incident Stokes vectors;
//! * [`scalar_error`]: Fig. 7, the error of the scalar RTE against the top
//!   layer's optical thickness;
//! * [`lobe`]: Fig. 13, f11 and DOP lobes in the plane of incidence and over
//!   the hemisphere;
//!
//! and one of paints, not of the paper: [`spectrum`], the reflectance and
//! the DOP against wavelength.
//!
//! Thickness sweeps replace the optical thickness of the spec's **top**
//! layer ([`curves::with_top_thickness`](super::curves::with_top_thickness))
//! and solve once per thickness at the few user cosines the plot needs. The
//! lobe needs the whole hemisphere and goes through a BRDF table.
//!
//! Option values are checked by the caller (the CLI names its flags in its
//! messages); the functions report what can still fail: specs, solves and
//! table queries.
//!
//! [`Figure`]: super::figure::Figure
//! [`Csv`]: super::csv::Csv

mod dop_vs_mu;
mod labels;
mod lobe;
mod shared;
mod spectrum;
mod sweeps;

pub use dop_vs_mu::{DopVsMuCurve, DopVsMuOptions, DopVsMuSummary, dop_vs_mu};
pub use labels::{stokes_name, stokes_text};
pub use lobe::{LobeCurve, LobeInput, LobeOptions, LobePlot, LobePoint, LobeSummary, lobe};
pub use spectrum::{
    SpectrumCurve, SpectrumInput, SpectrumOptions, SpectrumSample, SpectrumSummary, spectrum,
    spectrum_samples,
};
pub use sweeps::{
    DopVsTauCurve, DopVsTauOptions, DopVsTauSummary, ScalarErrorCurve, ScalarErrorInput,
    ScalarErrorOptions, ScalarErrorSummary, dop_vs_tau, scalar_error,
};

use super::csv::Csv;
use super::figure::Figure;
use crate::brdf::Table;
use crate::material::Spec;
use crate::plan::StreamPolicy;
use serde::Serialize;

/// Why a figure cannot be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PlotError {
    /// A spec is invalid here or its solve failed.
    #[error("{path}: {message}")]
    Spec {
        /// How the caller named the spec (its file).
        path: String,
        /// What went wrong.
        message: String,
    },
    /// A table cannot be evaluated as asked (wavelength, directions).
    #[error("{0}")]
    Table(String),
    /// The options leave nothing to plot.
    #[error("{0}")]
    Options(String),
}

impl PlotError {
    fn spec(path: &str, message: impl ToString) -> Self {
        PlotError::Spec {
            path: path.to_string(),
            message: message.to_string(),
        }
    }
}

/// Where a figure's BRDF comes from.
#[derive(Clone, Copy, Debug)]
pub enum Source<'a> {
    /// A material spec, solved here. `path` names it in messages and
    /// footnotes (its file name).
    Spec {
        /// How the caller names the spec.
        path: &'a str,
        /// The parsed spec.
        spec: &'a Spec,
    },
    /// A solved BRDF table (a file or a service result), named by `path`.
    Table {
        /// How the caller names the table.
        path: &'a str,
        /// The table.
        table: &'a Table,
    },
}

/// One spec of a figure with a curve (or set of curves) per spec.
#[derive(Clone, Debug)]
pub struct LabelledSpec<'a> {
    /// How the caller names the spec (its file).
    pub path: &'a str,
    /// The spec.
    pub spec: &'a Spec,
    /// Legend label (`None`: from the spec, its top layer's material).
    pub label: Option<String>,
}

/// Wavelength and solver settings shared by every figure.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveOptions {
    /// Vacuum wavelength (nm) to plot; `None`: the spec's or the table's
    /// first.
    pub wavelength_nm: Option<f64>,
    /// Quadrature streams per hemisphere, in `[1, material::MAX_STREAMS]`,
    /// overriding the spec's `solver.streams` / `solver.tolerance` (specs
    /// only: a table is already solved).
    pub streams: Option<usize>,
}

/// A figure, the numbers it plots and its summary.
#[derive(Clone, Debug, PartialEq)]
pub struct Plot<S> {
    /// What to draw.
    pub figure: Figure,
    /// The plotted numbers (fractions where the figure shows percent).
    pub csv: Csv,
    /// Settings and the key numbers of each curve.
    pub summary: S,
}

/// The solver settings of a figure, as `{"streams": n}` or
/// `{"tolerance": t}`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SolverSummary {
    /// A fixed number of streams.
    Streams(usize),
    /// Streams chosen to meet this tolerance.
    Tolerance(f64),
}

impl From<StreamPolicy> for SolverSummary {
    fn from(p: StreamPolicy) -> Self {
        match p {
            StreamPolicy::Fixed(n) => SolverSummary::Streams(n),
            StreamPolicy::Tolerance(t) => SolverSummary::Tolerance(t),
        }
    }
}

#[cfg(test)]
mod tests;
