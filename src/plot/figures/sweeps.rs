//! The thickness sweeps of Collin et al. 2014: one solve per optical
//! thickness of the spec's top layer, plotted against that thickness on a
//! log axis.
//!
//! * Fig. 4, [`dop_vs_tau`]: the degree of polarization, eq. (1), for
//!   several incident Stokes vectors at one direction pair;
//! * Fig. 7, [`scalar_error`]: the error of the scalar RTE in f11,
//!   `e = 1 − F_s/F_v` (§4.3), per spec and `(μ0, μ)` pair.

use super::labels::{base_name, file_name, material_name, policy_text, stokes_name, wl_text};
use super::shared::{Solvable, dash_of, dop_csv, line_figure, min_max_by, percent_axis, solvable};
use super::{Plot, PlotError, SolveOptions, SolverSummary};
use crate::material::Spec;
use crate::plot::csv::Csv;
use crate::plot::curves::{self, DopSample, ErrorSample};
use crate::plot::figure::{Axis, Dash, Legend, LinePanel, Series};
use crate::solver::Thickness;
use rayon::prelude::*;
use serde::Serialize;

/// The log axis of a sweep: whole decades around the finite thicknesses
/// (one decade when they are all equal).
fn tau_axis(taus: impl Iterator<Item = f64>) -> Axis {
    let (mut t_lo, mut t_hi) = (f64::INFINITY, 0.0f64);
    for t in taus.filter(|t| t.is_finite()) {
        t_lo = t_lo.min(t);
        t_hi = t_hi.max(t);
    }
    let lo = 10f64.powf(t_lo.log10().floor());
    let hi = 10f64.powf(t_hi.log10().ceil());
    Axis {
        label: "optical thickness τ of the top layer".into(),
        lo,
        hi: if hi > lo { hi } else { 10.0 * lo },
        log: true,
    }
}

/// The panel of a sweep over `taus`: curves of a quantity in percent
/// (`percents`: every value, plotted or not, for the axis range) against
/// the thickness.
fn sweep_panel(
    title: String,
    y_label: &str,
    taus: &[Thickness],
    percents: impl Iterator<Item = f64>,
    series: Vec<Series>,
    legend: Legend,
) -> LinePanel {
    LinePanel {
        title,
        x: tau_axis(taus.iter().map(|t| t.value())),
        y: percent_axis(y_label, percents),
        series,
        legend,
    }
}

/// No curve can be drawn without a finite thickness.
fn check_finite(taus: &[Thickness]) -> Result<(), PlotError> {
    if taus.iter().any(|t| t.value().is_finite()) {
        Ok(())
    } else {
        Err(PlotError::Options(
            "a thickness sweep needs at least one finite thickness".into(),
        ))
    }
}

// ---------------------------------------------------------------------------
// Fig. 4: DOP against thickness.

/// What [`dop_vs_tau`] plots.
#[derive(Clone, Debug, PartialEq)]
pub struct DopVsTauOptions {
    /// Optical thicknesses of the top layer, at least one finite; a
    /// one-layer spec also gets the semi-infinite layer (its DOP is in the
    /// legend).
    pub taus: Vec<Thickness>,
    /// Incident cosine, `(0, 1]`.
    pub mu0: f64,
    /// Outgoing cosine, `(0, 1]`.
    pub mu: f64,
    /// Outgoing azimuth (degrees, `φ_i = 0`; 180 = mirror side).
    pub phi_o_deg: f64,
    /// Incident Stokes vectors, one curve each.
    pub stokes: Vec<[f64; 4]>,
    /// Wavelength and streams.
    pub solve: SolveOptions,
    /// Image size in pixels (`None`: 900×540).
    pub size: Option<(u32, u32)>,
}

/// The summary of a DOP-against-thickness figure.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DopVsTauSummary {
    /// The wavelength plotted.
    pub wavelength_nm: Option<f64>,
    /// Solver settings.
    pub solver: SolverSummary,
    /// Incident cosine.
    pub mu0: f64,
    /// Outgoing cosine.
    pub mu: f64,
    /// Outgoing azimuth (degrees).
    pub phi_o_deg: f64,
    /// Rows of the CSV.
    pub rows: usize,
    /// One per incident state.
    pub curves: Vec<DopVsTauCurve>,
}

/// The key numbers of one curve (DOP as fractions).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DopVsTauCurve {
    /// Incident Stokes irradiance.
    pub stokes_in: [f64; 4],
    /// DOP at the thinnest layer.
    pub dop_at_smallest_tau: Option<f64>,
    /// DOP at the thickest finite layer.
    pub dop_at_largest_tau: Option<f64>,
    /// Smallest DOP over the finite thicknesses.
    pub dop_min: f64,
    /// Where it is.
    pub tau_at_min: f64,
    /// DOP of the semi-infinite layer, when solved.
    pub dop_semi_infinite: Option<f64>,
}

/// Fig. 4 of Collin et al. 2014: one solve per thickness (in parallel)
/// serves every incident state.
pub fn dop_vs_tau(
    path: &str,
    spec: &Spec,
    o: &DopVsTauOptions,
) -> Result<Plot<DopVsTauSummary>, PlotError> {
    check_finite(&o.taus)?;
    let Solvable {
        wavelength_nm: wl,
        policy,
        problem,
    } = solvable(path, spec, &o.solve)?;
    let mut taus = o.taus.clone();
    if spec.layers.len() == 1 && !taus.contains(&Thickness::Infinite) {
        taus.push(Thickness::Infinite);
    }
    let rows = curves::dop_vs_tau(&problem, policy, o.mu0, o.mu, o.phi_o_deg, &taus, &o.stokes)
        .map_err(|e| PlotError::spec(path, e))?;

    let mut series = Vec::new();
    let mut summary = Vec::new();
    for (k, &e) in o.stokes.iter().enumerate() {
        let curve: Vec<&DopSample> = rows.iter().filter(|r| r.stokes_in == e).collect();
        let finite: Vec<&DopSample> = curve
            .iter()
            .copied()
            .filter(|r| r.tau.is_finite())
            .collect();
        let semi = curve.iter().find(|r| r.tau.is_infinite()).map(|r| r.dop);
        let label = match semi {
            Some(d) => format!("{}  (τ = ∞: {:.1}%)", stokes_name(e), 100.0 * d),
            None => stokes_name(e),
        };
        series.push(Series {
            label,
            points: finite.iter().map(|r| (r.tau, 100.0 * r.dop)).collect(),
            color: k,
            dash: Dash::Solid,
            markers: true,
        });
        let (lo, _) = min_max_by(&finite, |r| r.dop)
            .ok_or_else(|| PlotError::Options("no finite thickness was solved".into()))?;
        summary.push(DopVsTauCurve {
            stokes_in: e,
            dop_at_smallest_tau: finite.first().map(|r| r.dop),
            dop_at_largest_tau: finite.last().map(|r| r.dop),
            dop_min: lo.dop,
            tau_at_min: lo.tau,
            dop_semi_infinite: semi,
        });
    }
    let panel = sweep_panel(
        format!(
            "Degree of polarization against thickness, μ0 = {}, μ = {}, φ_o = {}°",
            o.mu0, o.mu, o.phi_o_deg
        ),
        "degree of polarization (%)",
        &taus,
        rows.iter().map(|r| 100.0 * r.dop),
        series,
        Legend::LowerLeft,
    );
    let footnote = format!(
        "{} ({} on {} base){}, {}; incident Stokes in the meridian frame (Q > 0: in the plane of incidence)",
        file_name(path),
        material_name(spec),
        base_name(spec),
        wl_text(wl),
        policy_text(policy)
    );
    Ok(Plot {
        figure: line_figure(o.size, panel, footnote),
        csv: dop_csv(&rows),
        summary: DopVsTauSummary {
            wavelength_nm: wl,
            solver: policy.into(),
            mu0: o.mu0,
            mu: o.mu,
            phi_o_deg: o.phi_o_deg,
            rows: rows.len(),
            curves: summary,
        },
    })
}

// ---------------------------------------------------------------------------
// Fig. 7: error of the scalar RTE against thickness.

/// One spec of a [`scalar_error`] figure; its top layer's thickness is
/// varied.
pub type ScalarErrorInput<'a> = super::LabelledSpec<'a>;

/// What [`scalar_error`] plots.
#[derive(Clone, Debug, PartialEq)]
pub struct ScalarErrorOptions {
    /// Optical thicknesses of the top layer, at least one finite.
    pub taus: Vec<Thickness>,
    /// Direction pairs `(μ0, μ)`, each cosine in `(0, 1]`; one curve each
    /// per spec, odd positions dashed.
    pub pairs: Vec<(f64, f64)>,
    /// Outgoing azimuth (degrees, `φ_i = 0`; 180 = mirror side).
    pub phi_o_deg: f64,
    /// Wavelength and streams.
    pub solve: SolveOptions,
    /// Image size in pixels (`None`: 900×540).
    pub size: Option<(u32, u32)>,
}

/// The summary of a scalar-error figure.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ScalarErrorSummary {
    /// Outgoing azimuth (degrees).
    pub phi_o_deg: f64,
    /// Rows of the CSV.
    pub rows: usize,
    /// One per spec and direction pair.
    pub curves: Vec<ScalarErrorCurve>,
}

/// The key numbers of one curve (`e` as a fraction).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ScalarErrorCurve {
    /// Legend label of the spec.
    pub label: String,
    /// How the caller named the spec.
    pub spec: String,
    /// The wavelength plotted.
    pub wavelength_nm: Option<f64>,
    /// Solver settings.
    pub solver: SolverSummary,
    /// The spec's base.
    pub base: String,
    /// Incident cosine.
    pub mu0: f64,
    /// Outgoing cosine.
    pub mu: f64,
    /// Largest `e`.
    pub e_max: f64,
    /// Where it is.
    pub tau_at_max: f64,
    /// Smallest `e`.
    pub e_min: f64,
    /// Where it is.
    pub tau_at_min: f64,
    /// `e` at the thinnest layer.
    pub e_at_smallest_tau: Option<f64>,
    /// `e` at the thickest layer.
    pub e_at_largest_tau: Option<f64>,
}

/// Fig. 7 of Collin et al. 2014: every spec is made ready (and checked)
/// before any is solved; the specs are then solved in parallel, per
/// thickness one polarized and one scalar solve with the same settings.
pub fn scalar_error(
    inputs: &[ScalarErrorInput<'_>],
    o: &ScalarErrorOptions,
) -> Result<Plot<ScalarErrorSummary>, PlotError> {
    check_finite(&o.taus)?;
    let ready = inputs
        .iter()
        .map(|i| solvable(i.path, i.spec, &o.solve))
        .collect::<Result<Vec<_>, _>>()?;
    let solved: Vec<Result<Vec<ErrorSample>, PlotError>> = inputs
        .par_iter()
        .zip(&ready)
        .map(|(i, s)| {
            curves::scalar_error_vs_tau(&s.problem, s.policy, &o.pairs, o.phi_o_deg, &o.taus)
                .map_err(|e| PlotError::spec(i.path, e))
        })
        .collect();
    let mut csv = Csv::new(&[
        "label",
        "tau",
        "mu0",
        "mu",
        "phi_o_deg",
        "f_vector_per_sr",
        "f_scalar_per_sr",
        "e",
    ]);
    let mut series = Vec::new();
    let mut summary = Vec::new();
    let mut percents = Vec::new();
    for (k, ((input, s), rows)) in inputs.iter().zip(&ready).zip(solved).enumerate() {
        let rows = rows?;
        let label = input
            .label
            .clone()
            .unwrap_or_else(|| material_name(input.spec));
        for r in &rows {
            csv.push(vec![
                label.as_str().into(),
                r.tau.into(),
                r.mu0.into(),
                r.mu.into(),
                r.phi_o_deg.into(),
                r.f_vector.into(),
                r.f_scalar.into(),
                r.e.into(),
            ]);
            percents.push(100.0 * r.e);
        }
        for (j, &(mu0, mu)) in o.pairs.iter().enumerate() {
            let curve: Vec<&ErrorSample> =
                rows.iter().filter(|r| r.mu0 == mu0 && r.mu == mu).collect();
            series.push(Series {
                label: format!("{label}, (μ0, μ) = ({mu0}, {mu})"),
                points: curve.iter().map(|r| (r.tau, 100.0 * r.e)).collect(),
                color: k,
                dash: dash_of(j),
                markers: false,
            });
            let (lo, hi) = min_max_by(&curve, |r| r.e)
                .ok_or_else(|| PlotError::Options("no thickness was solved".into()))?;
            summary.push(ScalarErrorCurve {
                label: label.clone(),
                spec: input.path.to_string(),
                wavelength_nm: s.wavelength_nm,
                solver: s.policy.into(),
                base: base_name(input.spec),
                mu0,
                mu,
                e_max: hi.e,
                tau_at_max: hi.tau,
                e_min: lo.e,
                tau_at_min: lo.tau,
                e_at_smallest_tau: curve.first().map(|r| r.e),
                e_at_largest_tau: curve.last().map(|r| r.e),
            });
        }
    }
    let details: Vec<String> = inputs
        .iter()
        .zip(&ready)
        .map(|(i, s)| {
            format!(
                "{} ({} base{}, {})",
                file_name(i.path),
                base_name(i.spec),
                wl_text(s.wavelength_nm),
                policy_text(s.policy)
            )
        })
        .collect();
    let panel = sweep_panel(
        format!(
            "Error of the scalar RTE in f11, e = 1 − F_s/F_v, φ_o = {}°",
            o.phi_o_deg
        ),
        "e = 1 − F_s/F_v (%)",
        &o.taus,
        percents.into_iter(),
        series,
        Legend::UpperLeft,
    );
    Ok(Plot {
        figure: line_figure(o.size, panel, details.join("; ")),
        summary: ScalarErrorSummary {
            phi_o_deg: o.phi_o_deg,
            rows: csv.rows.len(),
            curves: summary,
        },
        csv,
    })
}
