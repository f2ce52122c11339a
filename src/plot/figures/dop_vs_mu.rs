//! Fig. 8 of Collin et al. 2014: the degree of polarization of the
//! reflected light, eq. (1) `DOP = √(Q² + U² + V²) / I`, against the
//! outgoing cosine `μ` at incident cosine `μ0`, one curve per optical
//! thickness of the top layer and outgoing azimuth (or one per azimuth
//! from a table, at the table's own thickness).

use super::labels::{
    base_name, file_name, material_name, policy_text, spec_thickness, stokes_name, tau_text,
    wl_text,
};
use super::shared::{
    dash_of, dop_csv, line_figure, min_max_by, percent_axis, solvable, table_spec, table_wavelength,
};
use super::{Plot, PlotError, SolveOptions, SolverSummary, Source};
use crate::plot::curves::{self, DopSample};
use crate::plot::figure::{Axis, Legend, LinePanel, Series};
use crate::solver::Thickness;
use serde::Serialize;

/// What [`dop_vs_mu`] plots.
#[derive(Clone, Debug, PartialEq)]
pub struct DopVsMuOptions {
    /// Optical thicknesses of the top layer, one curve each (`None`: the
    /// spec's own). Specs only: a table holds one thickness.
    pub taus: Option<Vec<Thickness>>,
    /// Cosine of the incident polar angle, `(0, 1]`.
    pub mu0: f64,
    /// Outgoing azimuths (degrees, `φ_i = 0`; 180 = mirror side), one curve
    /// each; odd positions are drawn dashed.
    pub phi_o_deg: Vec<f64>,
    /// Incident Stokes irradiance.
    pub stokes: [f64; 4],
    /// Number of outgoing cosines, `μ = k/n` for `k = 1..n`.
    pub mu_samples: usize,
    /// Wavelength and streams.
    pub solve: SolveOptions,
    /// Image size in pixels (`None`: 900×540).
    pub size: Option<(u32, u32)>,
}

/// The summary of a DOP-against-μ figure.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DopVsMuSummary {
    /// The wavelength plotted.
    pub wavelength_nm: Option<f64>,
    /// Solver settings (a table's: its streams).
    pub solver: SolverSummary,
    /// Incident cosine.
    pub mu0: f64,
    /// Incident Stokes irradiance.
    pub stokes_in: [f64; 4],
    /// Rows of the CSV.
    pub rows: usize,
    /// One per curve, in legend order.
    pub curves: Vec<DopVsMuCurve>,
}

/// The extremes of one curve.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DopVsMuCurve {
    /// Optical thickness of the top layer (`null` in JSON: semi-infinite).
    pub tau: f64,
    /// Outgoing azimuth (degrees).
    pub phi_o_deg: f64,
    /// Smallest DOP (fraction).
    pub dop_min: f64,
    /// The outgoing cosine where it is.
    pub mu_at_min: f64,
    /// Largest DOP (fraction).
    pub dop_max: f64,
    /// The outgoing cosine where it is.
    pub mu_at_max: f64,
}

/// Fig. 8 of Collin et al. 2014 from a spec (one solve per thickness) or a
/// table: one curve per `(τ, φ_o)`, coloured by `τ`, dashed by `φ_o`.
pub fn dop_vs_mu(
    source: Source<'_>,
    o: &DopVsMuOptions,
) -> Result<Plot<DopVsMuSummary>, PlotError> {
    let mus = curves::mu_samples(o.mu_samples);
    let (rows, what, wl, settings, solver) = match source {
        Source::Spec { path, spec } => {
            let s = solvable(path, spec, &o.solve)?;
            let taus = o
                .taus
                .clone()
                .unwrap_or_else(|| vec![spec_thickness(spec, s.wavelength_nm)]);
            let rows = curves::dop_vs_mu(
                &s.problem,
                s.policy,
                o.mu0,
                &taus,
                &mus,
                &o.phi_o_deg,
                o.stokes,
            )
            .map_err(|e| PlotError::spec(path, e))?;
            let what = format!(
                "{} ({} on {} base)",
                file_name(path),
                material_name(spec),
                base_name(spec)
            );
            let settings = policy_text(s.policy);
            (rows, what, s.wavelength_nm, settings, s.policy.into())
        }
        Source::Table { path, table } => {
            if o.taus.is_some() || o.solve.streams.is_some() {
                return Err(PlotError::Options(
                    "thicknesses and streams apply to specs: a table holds one solve".into(),
                ));
            }
            let wl = table_wavelength(table, o.solve.wavelength_nm)?;
            let (tau, label) = match table_spec(table) {
                Some(s) => (
                    spec_thickness(&s, wl).value(),
                    format!("{} on {} base", material_name(&s), base_name(&s)),
                ),
                None => (f64::NAN, "spec unknown".into()),
            };
            let rows = curves::dop_vs_mu_table(table, wl, tau, o.mu0, &mus, &o.phi_o_deg, o.stokes)
                .map_err(PlotError::Table)?;
            let n = table.metadata.solver.streams;
            let what = format!("table {} ({label})", file_name(path));
            let settings = format!("{n} streams (table)");
            (rows, what, wl, settings, SolverSummary::Streams(n))
        }
    };

    // One curve per (τ, φ_o): colour by τ, dash by φ_o.
    let mut taus: Vec<f64> = Vec::new();
    for r in &rows {
        if !taus.iter().any(|t| t.total_cmp(&r.tau).is_eq()) {
            taus.push(r.tau);
        }
    }
    let several_phi = o.phi_o_deg.len() > 1;
    let mut series = Vec::new();
    let mut summary = Vec::new();
    for (ti, &tau) in taus.iter().enumerate() {
        for (pi, &phi) in o.phi_o_deg.iter().enumerate() {
            let curve: Vec<&DopSample> = rows
                .iter()
                .filter(|r| r.tau.total_cmp(&tau).is_eq() && r.phi_o_deg == phi)
                .collect();
            let label = if several_phi {
                format!("τ = {}, φ_o = {phi}°", tau_text(tau))
            } else {
                format!("τ = {}", tau_text(tau))
            };
            series.push(Series {
                label,
                points: curve.iter().map(|r| (r.mu, 100.0 * r.dop)).collect(),
                color: ti,
                dash: dash_of(pi),
                markers: false,
            });
            if let Some((lo, hi)) = min_max_by(&curve, |r| r.dop) {
                summary.push(DopVsMuCurve {
                    tau,
                    phi_o_deg: phi,
                    dop_min: lo.dop,
                    mu_at_min: lo.mu,
                    dop_max: hi.dop,
                    mu_at_max: hi.mu,
                });
            }
        }
    }
    let phis = o
        .phi_o_deg
        .iter()
        .enumerate()
        .map(|(i, p)| format!("{p}°{}", if i % 2 == 0 { " solid" } else { " dashed" }))
        .collect::<Vec<_>>()
        .join(", ");
    let panel = LinePanel {
        title: format!(
            "Degree of polarization of the reflected light, μ0 = {}, incident {}",
            o.mu0,
            stokes_name(o.stokes)
        ),
        x: Axis {
            label: "outgoing μ = cos θ_o".into(),
            lo: 0.0,
            hi: 1.0,
            log: false,
        },
        y: percent_axis(
            "degree of polarization (%)",
            rows.iter().map(|r| 100.0 * r.dop),
        ),
        series,
        legend: Legend::UpperLeft,
    };
    let footnote = format!(
        "{what}{}, {settings}; φ_o (φ_i = 0): {phis} (180° = mirror side)",
        wl_text(wl)
    );
    Ok(Plot {
        figure: line_figure(o.size, panel, footnote),
        csv: dop_csv(&rows),
        summary: DopVsMuSummary {
            wavelength_nm: wl,
            solver,
            mu0: o.mu0,
            stokes_in: o.stokes,
            rows: rows.len(),
            curves: summary,
        },
    })
}
