//! Spectra: the reflectance and the degree of polarization of each spec
//! against wavelength, at every wavelength the spec lists
//! (`polbrdf plot spectrum`; docs/gallery.md, White paint).
//!
//! Per spec and wavelength, one solve at the user cosines `{μ0, μ}` gives
//!
//! * the **plane albedo** `A(μ0)`, the directional–hemispherical
//!   reflectance for unpolarized light: reflected over incident flux, the
//!   mirror beam of a Fresnel base included (`solver::stream_fluxes` at the
//!   solve's streams; with delta-M, that of the truncated problem, whose
//!   truncated forward peak travels with the direct beam);
//! * the **reflectance factor** `R = π f11(μ0 → μ, φ_o)` at one viewing
//!   direction, the ratio to a white Lambertian surface (1 for it), the
//!   mirror beam left out (it reaches only the specular direction);
//! * the **degree of polarization** there for unpolarized incidence,
//!   `√(f21² + f31² + f41²) / f11` (Collin et al. 2014, eq. 1).
//!
//! The wavelengths are solved in parallel.

use super::labels::{base_name, file_name, material_name, policy_text};
use super::shared::{min_max_by, percent_axis, push_stokes_cells, stokes_csv};
use super::{Plot, PlotError, SolveOptions, SolverSummary};
use crate::material::Spec;
use crate::plan::{self, StreamPolicy};
use crate::plot::csv::Cell;
use crate::plot::curves::{self, UNPOLARIZED, brdf_at, reflect_with_streams};
use crate::plot::figure::{Axis, Dash, Figure, Legend, LinePanel, Panel, Series};
use crate::solver;
use rayon::prelude::*;
use serde::Serialize;

/// Image size unless the caller gives one: two panels, one above the other.
const SIZE: (u32, u32) = (900, 860);
/// Curves with at most this many wavelengths get a marker at each.
const MARKERS_UP_TO: usize = 12;

/// One spec of a spectrum figure; it must list `wavelengths_nm`.
pub type SpectrumInput<'a> = super::LabelledSpec<'a>;

/// What [`spectrum`] plots.
#[derive(Clone, Debug, PartialEq)]
pub struct SpectrumOptions {
    /// Cosine of the incident polar angle, `(0, 1]`.
    pub mu0: f64,
    /// Cosine of the viewing polar angle, `(0, 1]`.
    pub mu: f64,
    /// Viewing azimuth (degrees, `φ_i = 0`; 180 = mirror side).
    pub phi_o_deg: f64,
    /// Streams (the wavelength option does not apply: every listed
    /// wavelength is plotted).
    pub solve: SolveOptions,
    /// Image size in pixels (`None`: 900×860).
    pub size: Option<(u32, u32)>,
}

/// One wavelength of one spec.
#[derive(Clone, Debug, PartialEq)]
pub struct SpectrumSample {
    /// Vacuum wavelength, nm.
    pub wavelength_nm: f64,
    /// Streams per hemisphere of the solve.
    pub streams: usize,
    /// Plane albedo `A(μ0)`.
    pub albedo: f64,
    /// `f11(μ0 → μ, φ_o)`, 1/sr.
    pub f11: f64,
    /// Reflected Stokes radiance per unit unpolarized irradiance, 1/sr.
    pub stokes_out: [f64; 4],
    /// Its degree of polarization.
    pub dop: f64,
}

impl SpectrumSample {
    /// The reflectance factor `π f11`.
    pub fn reflectance_factor(&self) -> f64 {
        std::f64::consts::PI * self.f11
    }
}

/// The summary of a spectrum figure.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SpectrumSummary {
    /// Incident cosine.
    pub mu0: f64,
    /// Viewing cosine.
    pub mu: f64,
    /// Viewing azimuth (degrees).
    pub phi_o_deg: f64,
    /// Rows of the CSV.
    pub rows: usize,
    /// One per spec, in legend order.
    pub curves: Vec<SpectrumCurve>,
}

/// The extremes of one spec's spectra.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SpectrumCurve {
    /// Legend label.
    pub label: String,
    /// Solver settings.
    pub solver: SolverSummary,
    /// Wavelengths plotted.
    pub wavelengths: usize,
    /// Smallest plane albedo and its wavelength.
    pub albedo_min: f64,
    /// Wavelength of `albedo_min`, nm.
    pub wavelength_at_albedo_min_nm: f64,
    /// Largest plane albedo.
    pub albedo_max: f64,
    /// Wavelength of `albedo_max`, nm.
    pub wavelength_at_albedo_max_nm: f64,
    /// Smallest reflectance factor at the viewing direction.
    pub reflectance_factor_min: f64,
    /// Largest reflectance factor at the viewing direction.
    pub reflectance_factor_max: f64,
    /// Smallest DOP at the viewing direction (fraction).
    pub dop_min: f64,
    /// Wavelength of `dop_min`, nm.
    pub wavelength_at_dop_min_nm: f64,
    /// Largest DOP at the viewing direction (fraction).
    pub dop_max: f64,
    /// Wavelength of `dop_max`, nm.
    pub wavelength_at_dop_max_nm: f64,
}

/// The samples of one spec at every listed wavelength (module doc).
///
/// # Errors
/// A spec without `wavelengths_nm`, or one that cannot be lowered or
/// solved at one of them.
pub fn spectrum_samples(
    path: &str,
    spec: &Spec,
    o: &SpectrumOptions,
) -> Result<Vec<SpectrumSample>, PlotError> {
    let wavelengths: Vec<f64> = plan::wavelengths(spec).into_iter().flatten().collect();
    if wavelengths.is_empty() {
        return Err(PlotError::spec(
            path,
            "a spectrum needs `wavelengths_nm` in the spec",
        ));
    }
    let policy = o
        .solve
        .streams
        .map_or_else(|| plan::stream_policy(spec), StreamPolicy::Fixed);
    let user = curves::distinct([o.mu0, o.mu]);
    wavelengths
        .par_iter()
        .map(|&wl| {
            let at = |e: &dyn std::fmt::Display| PlotError::spec(path, format!("{wl} nm: {e}"));
            let mut problem = plan::problem(spec, Some(wl)).map_err(|e| at(&e))?;
            let (r, streams) = reflect_with_streams(&problem, policy, &user).map_err(|e| at(&e))?;
            problem.settings.streams = streams;
            let fluxes = solver::stream_fluxes(&problem, &[o.mu0]).map_err(|e| at(&e))?;
            let f = brdf_at(&r, o.mu0, o.mu, o.phi_o_deg);
            let stokes_out = curves::reflected(&f, UNPOLARIZED);
            Ok(SpectrumSample {
                wavelength_nm: wl,
                streams,
                albedo: fluxes.reflected[0],
                f11: f[0][0],
                stokes_out,
                dop: curves::dop(&f, UNPOLARIZED),
            })
        })
        .collect()
}

/// Reflectance (plane albedo solid, reflectance factor dashed) and DOP
/// against wavelength, one colour per spec.
pub fn spectrum(
    inputs: &[SpectrumInput<'_>],
    o: &SpectrumOptions,
) -> Result<Plot<SpectrumSummary>, PlotError> {
    if inputs.is_empty() {
        return Err(PlotError::Options("give at least one spec".into()));
    }
    let mut csv = stokes_csv(&HEADER);
    let mut reflectance = Vec::new();
    let mut dop = Vec::new();
    let mut curves_out = Vec::new();
    let mut settings = Vec::new();
    let mut n_rows = 0;
    let (mut wl_lo, mut wl_hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (k, input) in inputs.iter().enumerate() {
        let rows = spectrum_samples(input.path, input.spec, o)?;
        let label = input.label.clone().unwrap_or_else(|| {
            format!("{} on {}", material_name(input.spec), base_name(input.spec))
        });
        let policy = o
            .solve
            .streams
            .map_or_else(|| plan::stream_policy(input.spec), StreamPolicy::Fixed);
        settings.push(format!(
            "{}: {}",
            file_name(input.path),
            policy_text(policy)
        ));
        let markers = rows.len() <= MARKERS_UP_TO;
        let line = |points: Vec<(f64, f64)>, label: String, dash: Dash| Series {
            label,
            points,
            color: k,
            dash,
            markers,
        };
        reflectance.push(line(
            rows.iter()
                .map(|r| (r.wavelength_nm, 100.0 * r.albedo))
                .collect(),
            format!("{label}: plane albedo"),
            Dash::Solid,
        ));
        reflectance.push(line(
            rows.iter()
                .map(|r| (r.wavelength_nm, 100.0 * r.reflectance_factor()))
                .collect(),
            format!("{label}: π f11"),
            Dash::Dashed,
        ));
        dop.push(line(
            rows.iter()
                .map(|r| (r.wavelength_nm, 100.0 * r.dop))
                .collect(),
            label.clone(),
            Dash::Solid,
        ));
        for r in &rows {
            wl_lo = wl_lo.min(r.wavelength_nm);
            wl_hi = wl_hi.max(r.wavelength_nm);
            let mut row: Vec<Cell> = vec![
                Cell::Text(label.clone()),
                r.wavelength_nm.into(),
                (r.streams as f64).into(),
                o.mu0.into(),
                o.mu.into(),
                o.phi_o_deg.into(),
                r.albedo.into(),
                r.reflectance_factor().into(),
            ];
            push_stokes_cells(&mut row, r.f11, &r.stokes_out, r.dop);
            csv.push(row);
            n_rows += 1;
        }
        let (a_lo, a_hi) = min_max_by(&rows, |r| r.albedo).expect("wavelengths");
        let (r_lo, r_hi) = min_max_by(&rows, |r| r.reflectance_factor()).expect("wavelengths");
        let (d_lo, d_hi) = min_max_by(&rows, |r| r.dop).expect("wavelengths");
        curves_out.push(SpectrumCurve {
            label,
            solver: policy.into(),
            wavelengths: rows.len(),
            albedo_min: a_lo.albedo,
            wavelength_at_albedo_min_nm: a_lo.wavelength_nm,
            albedo_max: a_hi.albedo,
            wavelength_at_albedo_max_nm: a_hi.wavelength_nm,
            reflectance_factor_min: r_lo.reflectance_factor(),
            reflectance_factor_max: r_hi.reflectance_factor(),
            dop_min: d_lo.dop,
            wavelength_at_dop_min_nm: d_lo.wavelength_nm,
            dop_max: d_hi.dop,
            wavelength_at_dop_max_nm: d_hi.wavelength_nm,
        });
    }
    if wl_lo == wl_hi {
        (wl_lo, wl_hi) = (wl_lo - 10.0, wl_hi + 10.0);
    }
    let x = Axis {
        label: "vacuum wavelength λ (nm)".into(),
        lo: wl_lo,
        hi: wl_hi,
        log: false,
    };
    let theta = |mu: f64| curves::theta_deg(mu).round();
    let view = format!(
        "θ_i = {}° → θ_o = {}°, φ_o = {}°",
        theta(o.mu0),
        theta(o.mu),
        o.phi_o_deg
    );
    let reflectance_panel = LinePanel {
        title: format!(
            "Reflectance, unpolarized light at θ_i = {}°: plane albedo (solid), π f11 at {view} (dashed)",
            theta(o.mu0)
        ),
        x: x.clone(),
        y: tight_percent_axis(
            "reflectance (%)",
            reflectance
                .iter()
                .flat_map(|s: &Series| s.points.iter().map(|p| p.1)),
        ),
        series: reflectance,
        legend: Legend::LowerLeft,
    };
    let dop_panel = LinePanel {
        title: format!("Degree of polarization of the reflected light, {view}"),
        x,
        y: percent_axis(
            "degree of polarization (%)",
            dop.iter().flat_map(|s| s.points.iter().map(|p| p.1)),
        ),
        series: dop,
        legend: Legend::UpperLeft,
    };
    Ok(Plot {
        figure: Figure {
            size: o.size.unwrap_or(SIZE),
            rows: 2,
            cols: 1,
            panels: vec![Panel::Line(reflectance_panel), Panel::Line(dop_panel)],
            footnote: settings.join("; "),
        },
        summary: SpectrumSummary {
            mu0: o.mu0,
            mu: o.mu,
            phi_o_deg: o.phi_o_deg,
            rows: n_rows,
            curves: curves_out,
        },
        csv,
    })
}

/// A percent axis around the data, on whole percent: a paint's
/// reflectance varies by a few percent across the spectrum, which an axis
/// from 0 would flatten. At least 2 points wide; within `[0, 100]` for data
/// within it.
fn tight_percent_axis(label: &str, values: impl Iterator<Item = f64>) -> Axis {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if lo > hi {
        return percent_axis(label, std::iter::empty());
    }
    let pad = (0.1 * (hi - lo)).max(1.0);
    let (mut a, mut b) = ((lo - pad).floor(), (hi + pad).ceil());
    if lo >= 0.0 {
        a = a.max(0.0);
    }
    if hi <= 100.0 {
        b = b.min(100.0);
    }
    Axis {
        label: label.into(),
        lo: a,
        hi: b.max(a + 2.0),
        log: false,
    }
}

/// Leading columns of the spectrum CSV (the Stokes columns follow).
const HEADER: [&str; 8] = [
    "label",
    "wavelength_nm",
    "streams",
    "mu0",
    "mu",
    "phi_o_deg",
    "plane_albedo",
    "reflectance_factor",
];
