//! Plots of BRDF results (`polbrdf plot ...`): the figures of Collin,
//! Pattanaik, LiKamWa and Bouatouch, "Computation of Polarized Subsurface
//! BRDF for Rendering" (Graphics Interface 2014) as SVG/PNG with the plotted
//! numbers next to them as CSV (issue 7).
//!
//! * [`figures`]: each figure from specs or tables: spec edits, solves,
//!   curves, titles, axes, CSV columns and a summary; no files.
//! * [`curves`]: the plotted quantities as numbers (DOP, scalar-RTE error,
//!   lobe samples) from direct solves or BRDF tables; pure.
//! * [`figure`]: what a figure shows (panels, curves, maps) as plain data and
//!   its geometry; pure.
//! * [`csv`]: the numbers as CSV text; pure.
//! * [`draw`]: a figure to SVG or PNG (plotters; reads a font, writes files).

pub mod csv;
pub mod curves;
pub mod draw;
pub mod figure;
pub mod figures;
