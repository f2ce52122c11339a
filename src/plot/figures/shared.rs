//! What the figures share: a spec made ready to solve, the wavelength and
//! spec of a table, the percent axis, curve extremes, the one-panel line
//! figure and the DOP CSV.

use super::{PlotError, SolveOptions};
use crate::brdf::Table;
use crate::material::Spec;
use crate::plan::{self, StreamPolicy};
use crate::plot::csv::{Cell, Csv};
use crate::plot::curves::{self, DopSample};
use crate::plot::figure::{Axis, Dash, Figure, LinePanel, Panel, nice_ceil};
use crate::solver::Problem;

/// Image size of the one-panel line figures unless the caller gives one.
pub(super) const LINE_SIZE: (u32, u32) = (900, 540);

/// A spec made ready to solve at the figure's wavelength.
pub(super) struct Solvable {
    /// The wavelength plotted (`None`: a wavelength-free spec).
    pub wavelength_nm: Option<f64>,
    /// Streams: [`SolveOptions::streams`] over the spec's own policy.
    pub policy: StreamPolicy,
    /// The solver problem at that wavelength.
    pub problem: Problem,
}

/// The spec's problem at `opts.wavelength_nm` (else its first wavelength)
/// and its stream policy (`opts.streams` wins over the spec).
pub(super) fn solvable(
    path: &str,
    spec: &Spec,
    opts: &SolveOptions,
) -> Result<Solvable, PlotError> {
    let wavelength_nm = spec_wavelength(spec, opts.wavelength_nm);
    let policy = opts
        .streams
        .map_or_else(|| plan::stream_policy(spec), StreamPolicy::Fixed);
    let problem = plan::problem(spec, wavelength_nm).map_err(|e| PlotError::spec(path, e))?;
    Ok(Solvable {
        wavelength_nm,
        policy,
        problem,
    })
}

/// The wavelength to plot for a spec: the option, else the spec's first.
pub(super) fn spec_wavelength(spec: &Spec, opt: Option<f64>) -> Option<f64> {
    opt.or_else(|| plan::wavelengths(spec)[0])
}

/// The wavelength to evaluate a table at: the option (which the table must
/// cover), else its only (first) one.
pub(super) fn table_wavelength(table: &Table, opt: Option<f64>) -> Result<Option<f64>, PlotError> {
    match opt {
        Some(w) => {
            table
                .wavelength_weights(Some(w))
                .map_err(|e| PlotError::Table(e.to_string()))?;
            Ok(Some(w))
        }
        None => Ok(table.wavelengths.first().and_then(|w| w.wavelength_nm)),
    }
}

/// The spec a table was built from (its metadata), if it reads as one.
pub(super) fn table_spec(table: &Table) -> Option<Spec> {
    serde_json::from_value::<Spec>(table.metadata.spec.clone()).ok()
}

/// `(lo, hi)` of a percent axis: from 0 (or below, for negative data) to a
/// nice value above the data, at most 100 for data within 100 (a DOP).
pub(super) fn percent_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    let hi = if hi <= 100.0 {
        nice_ceil(hi * 1.05).min(100.0)
    } else {
        nice_ceil(hi * 1.05)
    };
    let lo = if lo < 0.0 {
        -nice_ceil(-lo * 1.05)
    } else {
        0.0
    };
    (lo, hi)
}

/// A linear axis in percent over `values` ([`percent_range`]).
pub(super) fn percent_axis(label: &str, values: impl Iterator<Item = f64>) -> Axis {
    let (lo, hi) = percent_range(values);
    Axis {
        label: label.into(),
        lo,
        hi,
        log: false,
    }
}

/// The items with the smallest and the largest key (the first of equals).
pub(super) fn min_max_by<T>(items: &[T], key: impl Fn(&T) -> f64) -> Option<(&T, &T)> {
    let lo = items.iter().min_by(|a, b| key(a).total_cmp(&key(b)))?;
    let hi = items.iter().max_by(|a, b| key(a).total_cmp(&key(b)))?;
    Some((lo, hi))
}

/// A figure of one line panel.
pub(super) fn line_figure(size: Option<(u32, u32)>, panel: LinePanel, footnote: String) -> Figure {
    Figure {
        size: size.unwrap_or(LINE_SIZE),
        rows: 1,
        cols: 1,
        panels: vec![Panel::Line(panel)],
        footnote,
    }
}

/// Solid for even positions, dashed for odd ones.
pub(super) fn dash_of(position: usize) -> Dash {
    if position.is_multiple_of(2) {
        Dash::Solid
    } else {
        Dash::Dashed
    }
}

/// The last columns of every CSV that reports a reflected Stokes vector:
/// `f11`, the vector for unpolarized (or the stated) incidence, its DOP.
const STOKES_OUT_COLUMNS: [&str; 6] = [
    "f11_per_sr",
    "i_per_sr",
    "q_per_sr",
    "u_per_sr",
    "v_per_sr",
    "dop",
];

/// A CSV whose columns are `leading` followed by [`STOKES_OUT_COLUMNS`].
pub(super) fn stokes_csv(leading: &[&str]) -> Csv {
    Csv::new(&[leading, &STOKES_OUT_COLUMNS[..]].concat())
}

/// The cells of [`STOKES_OUT_COLUMNS`], appended to `row`.
pub(super) fn push_stokes_cells(row: &mut Vec<Cell>, f11: f64, stokes_out: &[f64; 4], dop: f64) {
    row.push(f11.into());
    row.extend(stokes_out.iter().map(|&x| Cell::Num(x)));
    row.push(dop.into());
}

/// The DOP samples as CSV, one row each.
pub(super) fn dop_csv(rows: &[DopSample]) -> Csv {
    let mut c = stokes_csv(&[
        "tau",
        "mu0",
        "mu",
        "theta_o_deg",
        "phi_o_deg",
        "stokes_in_i",
        "stokes_in_q",
        "stokes_in_u",
        "stokes_in_v",
    ]);
    for r in rows {
        let mut row: Vec<Cell> = vec![
            r.tau.into(),
            r.mu0.into(),
            r.mu.into(),
            curves::theta_deg(r.mu).into(),
            r.phi_o_deg.into(),
        ];
        row.extend(r.stokes_in.iter().map(|&x| Cell::Num(x)));
        push_stokes_cells(&mut row, r.f11, &r.stokes_out, r.dop);
        c.push(row);
    }
    c
}
