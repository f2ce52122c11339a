//! Fig. 13 of Collin et al. 2014: the BRDF (f11) and the degree of
//! polarization of the reflected light for unpolarized incident light, as
//! lobes in the plane of incidence and as maps over the outgoing
//! hemisphere, one per spec or table. Both go through a BRDF table
//! (`Table::from_spec` for a spec): the hemisphere needs every direction.

use super::labels::{base_name, file_name, material_name, policy_text};
use super::shared::{push_stokes_cells, spec_wavelength, stokes_csv, table_spec, table_wavelength};
use super::{PlotError, SolveOptions, Source};
use crate::brdf::{Directions, PolarGrid, Table};
use crate::physics::stokes::Mueller;
use crate::plot::csv::{Cell, Csv};
use crate::plot::curves::{self, LobeSample};
use crate::plot::figure::{Dash, Figure, LobePanel, MapPanel, Panel, Series, lobe_xy, nice_ceil};
use crate::{material, plan};
use rayon::prelude::*;
use serde::Serialize;
use std::borrow::Cow;

/// One lobe of a [`lobe`] figure.
#[derive(Clone, Copy, Debug)]
pub struct LobeInput<'a> {
    /// A spec (a table is built from it) or a table.
    pub source: Source<'a>,
    /// Legend label (`None`: material on base).
    pub label: Option<&'a str>,
}

/// What [`lobe`] plots.
#[derive(Clone, Debug, PartialEq)]
pub struct LobeOptions {
    /// Incident polar angle (degrees) in `[0, 90)`; the incident azimuth is 0.
    pub theta_i_deg: f64,
    /// Step of the outgoing angle in the plane of incidence (degrees), in
    /// `[0.05, 30]`.
    pub step_deg: f64,
    /// Hemisphere map cells `(polar, azimuthal)`: cells of `90°/n × 360°/m`.
    pub map_cells: (usize, usize),
    /// Polar grid of the tables built from specs.
    pub grid: PolarGrid,
    /// Wavelength and streams (streams: specs only).
    pub solve: SolveOptions,
    /// Size of the lobe image in pixels (`None`: 900×800); the map image
    /// is 320 pixels per lobe (at least two) by 640.
    pub size: Option<(u32, u32)>,
}

/// The two figures of [`lobe`], their numbers and the summary.
#[derive(Clone, Debug, PartialEq)]
pub struct LobePlot {
    /// f11 and DOP in the plane of incidence (two lobe panels).
    pub figure: Figure,
    /// Its numbers, one row per lobe and outgoing angle.
    pub csv: Csv,
    /// f11 and DOP over the hemisphere (a row of maps each).
    pub map_figure: Figure,
    /// Its numbers, one row per lobe and map cell.
    pub map_csv: Csv,
    /// Settings and the key numbers of each lobe.
    pub summary: LobeSummary,
}

/// The summary of a lobe figure.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LobeSummary {
    /// Incident polar angle (degrees).
    pub theta_i_deg: f64,
    /// Rows of the lobe CSV.
    pub rows: usize,
    /// Rows of the map CSV.
    pub map_rows: usize,
    /// One per lobe.
    pub curves: Vec<LobeCurve>,
}

/// The key numbers of one lobe in the plane of incidence.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LobeCurve {
    /// Legend label.
    pub label: String,
    /// Where it came from (file and streams).
    pub source: String,
    /// The wavelength plotted.
    pub wavelength_nm: Option<f64>,
    /// Largest f11 (1/sr).
    pub f11_max: f64,
    /// Signed outgoing angle (degrees) where it is.
    pub theta_o_signed_at_f11_max: f64,
    /// Largest DOP (fraction).
    pub dop_max: f64,
    /// Signed outgoing angle (degrees) where it is.
    pub theta_o_signed_at_dop_max: f64,
    /// The sample nearest the normal.
    pub normal: Option<LobePoint>,
    /// The sample nearest the mirror direction.
    pub mirror: Option<LobePoint>,
    /// The sample nearest the backscattering direction.
    pub backscatter: Option<LobePoint>,
    /// The specular (delta) reflection of a mirror base at the mirror
    /// direction, not drawn; `None` without one.
    pub specular: Option<Mueller>,
}

/// One sample of a lobe.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LobePoint {
    /// Signed outgoing angle (degrees; `+` mirror side).
    pub theta_o_signed_deg: f64,
    /// f11 (1/sr).
    pub f11: f64,
    /// DOP (fraction).
    pub dop: f64,
}

/// A lobe's table (built here or the caller's) and its words.
struct Lobe<'a> {
    label: String,
    origin: String,
    table: Cow<'a, Table>,
    wavelength_nm: Option<f64>,
}

/// Fig. 13 of Collin et al. 2014 for up to eight specs and tables. Every
/// spec is set to the plotted wavelength (and streams) and checked before
/// any table is built; the tables of specs are built in parallel.
pub fn lobe(inputs: &[LobeInput<'_>], o: &LobeOptions) -> Result<LobePlot, PlotError> {
    let lobes = lobes(inputs, o)?;
    let theta_i = o.theta_i_deg;
    let (n_theta, n_phi) = o.map_cells;

    // Samples.
    let mut in_plane = Vec::new();
    let mut maps = Vec::new();
    for s in &lobes {
        let table = s.table.as_ref();
        in_plane.push(
            curves::lobe_in_plane(table, s.wavelength_nm, theta_i, o.step_deg)
                .map_err(PlotError::Table)?,
        );
        maps.push(
            curves::lobe_map(table, s.wavelength_nm, theta_i, n_theta, n_phi)
                .map_err(PlotError::Table)?,
        );
    }

    // CSVs.
    let mut csv = stokes_csv(&[
        "label",
        "theta_i_deg",
        "theta_o_deg",
        "phi_o_deg",
        "theta_o_signed_deg",
    ]);
    let mut map_csv = Csv::new(&[
        "label",
        "theta_i_deg",
        "theta_o_deg",
        "phi_o_deg",
        "f11_per_sr",
        "dop",
    ]);
    for (s, (lobe, map)) in lobes.iter().zip(in_plane.iter().zip(&maps)) {
        for r in lobe {
            let mut row: Vec<Cell> = vec![
                s.label.as_str().into(),
                theta_i.into(),
                r.theta_o_deg.into(),
                r.phi_o_deg.into(),
                signed(r).into(),
            ];
            push_stokes_cells(&mut row, r.f11, &r.stokes_out, r.dop);
            csv.push(row);
        }
        for r in map {
            map_csv.push(vec![
                s.label.as_str().into(),
                theta_i.into(),
                r.theta_o_deg.into(),
                r.phi_o_deg.into(),
                r.f11.into(),
                r.dop.into(),
            ]);
        }
    }

    // In-plane lobes.
    let f11_max = in_plane.iter().flatten().map(|r| r.f11).fold(0.0, f64::max);
    let dop_max = in_plane
        .iter()
        .flatten()
        .map(|r| 100.0 * r.dop)
        .fold(0.0, f64::max);
    let lobe_series = |value: &dyn Fn(&LobeSample) -> f64| -> Vec<Series> {
        lobes
            .iter()
            .zip(&in_plane)
            .enumerate()
            .map(|(k, (s, lobe))| Series {
                label: s.label.clone(),
                points: lobe.iter().map(|r| lobe_xy(signed(r), value(r))).collect(),
                color: k,
                dash: Dash::Solid,
                markers: false,
            })
            .collect()
    };
    let mut wls: Vec<String> = lobes
        .iter()
        .map(|s| s.wavelength_nm.map_or("-".into(), |w| format!("{w}")))
        .collect();
    wls.dedup();
    let origins = lobes
        .iter()
        .map(|s| s.origin.clone())
        .collect::<Vec<_>>()
        .join(", ");
    let mirror_note = if lobes
        .iter()
        .any(|s| s.table.wavelengths.iter().any(|w| w.specular.is_some()))
    {
        "; the specular reflection (a delta) of a mirror base or a top interface is not drawn"
    } else {
        ""
    };
    let footnote = format!(
        "{origins}; λ = {} nm; unpolarized light incident at θ_i = {theta_i}°{mirror_note}",
        wls.join("/"),
    );
    let figure = Figure {
        size: o.size.unwrap_or((900, 800)),
        rows: 2,
        cols: 1,
        panels: vec![
            Panel::Lobe(LobePanel {
                title: "BRDF f11 in the plane of incidence".into(),
                radius_label: "f11 (1/sr)".into(),
                r_max: nice_ceil(f11_max),
                series: lobe_series(&|r| r.f11),
                theta_i_deg: theta_i,
            }),
            Panel::Lobe(LobePanel {
                title: "Degree of polarization in the plane of incidence".into(),
                radius_label: "DOP (%)".into(),
                r_max: nice_ceil(dop_max),
                series: lobe_series(&|r| 100.0 * r.dop),
                theta_i_deg: theta_i,
            }),
        ],
        footnote: footnote.clone(),
    };

    // Hemisphere maps: f11 on one scale, DOP on another, for all lobes.
    let map_f11_max = maps.iter().flatten().map(|r| r.f11).fold(0.0, f64::max);
    let map_dop_max = maps
        .iter()
        .flatten()
        .map(|r| 100.0 * r.dop)
        .fold(0.0, f64::max);
    let mut panels = Vec::new();
    for (row, (name, unit)) in [("f11", "f11 (1/sr)"), ("DOP", "DOP (%)")]
        .into_iter()
        .enumerate()
    {
        for (s, map) in lobes.iter().zip(&maps) {
            let values: Vec<f64> = map
                .iter()
                .map(|r| if row == 0 { r.f11 } else { 100.0 * r.dop })
                .collect();
            panels.push(Panel::Map(MapPanel {
                title: format!("{name}: {}", s.label),
                n_theta,
                n_phi,
                values,
                lo: 0.0,
                hi: nice_ceil(if row == 0 { map_f11_max } else { map_dop_max }),
                colorbar_label: unit.into(),
                theta_i_deg: theta_i,
            }));
        }
    }
    let n = lobes.len() as u32;
    let map_figure = Figure {
        size: (320 * n.max(2), 640),
        rows: 2,
        cols: lobes.len(),
        panels,
        footnote: format!(
            "{footnote}; hemisphere seen from above, polar angle = distance from the centre (horizon = outer circle)"
        ),
    };

    let curves = lobes
        .iter()
        .zip(&in_plane)
        .map(|(s, lobe)| lobe_curve(s, lobe, theta_i))
        .collect();
    Ok(LobePlot {
        summary: LobeSummary {
            theta_i_deg: theta_i,
            rows: csv.rows.len(),
            map_rows: map_csv.rows.len(),
            curves,
        },
        figure,
        csv,
        map_figure,
        map_csv,
    })
}

/// The lobes' tables and words, in input order; labels from the inputs.
fn lobes<'a>(inputs: &[LobeInput<'a>], o: &LobeOptions) -> Result<Vec<Lobe<'a>>, PlotError> {
    // Every spec at the plotted wavelength and streams, checked before any solve.
    let mut specs = Vec::new();
    for i in inputs {
        if let Source::Spec { path, spec } = i.source {
            let mut spec = spec.clone();
            let wl = spec_wavelength(&spec, o.solve.wavelength_nm);
            if let Some(w) = wl {
                spec.wavelengths_nm = Some(vec![w]);
            }
            if let Some(n) = o.solve.streams {
                spec.solver.streams = Some(n);
            }
            material::validate(&spec).map_err(|e| PlotError::spec(path, e))?;
            specs.push((path, spec, wl));
        }
    }
    let built: Vec<Result<Lobe<'a>, PlotError>> = specs
        .par_iter()
        .map(|(path, spec, wl)| {
            let table =
                Table::from_spec(spec, o.grid.clone()).map_err(|e| PlotError::spec(path, e))?;
            Ok(Lobe {
                label: format!("{} on {}", material_name(spec), base_name(spec)),
                origin: format!(
                    "{} ({})",
                    file_name(path),
                    policy_text(plan::stream_policy(spec))
                ),
                table: Cow::Owned(table),
                wavelength_nm: *wl,
            })
        })
        .collect();
    let mut built = built.into_iter();
    let mut lobes = Vec::with_capacity(inputs.len());
    for i in inputs {
        let mut lobe = match i.source {
            Source::Spec { .. } => built.next().expect("one table per spec")?,
            Source::Table { path, table } => {
                if o.solve.streams.is_some() {
                    return Err(PlotError::Options(
                        "streams apply to specs: a table is already solved".into(),
                    ));
                }
                let streams = table.metadata.solver.streams;
                Lobe {
                    label: table_spec(table).map_or("spec unknown".into(), |s| {
                        format!("{} on {}", material_name(&s), base_name(&s))
                    }),
                    origin: format!("table {} ({streams} streams)", file_name(path)),
                    wavelength_nm: table_wavelength(table, o.solve.wavelength_nm)?,
                    table: Cow::Borrowed(table),
                }
            }
        };
        if let Some(l) = i.label {
            lobe.label = l.to_string();
        }
        lobes.push(lobe);
    }
    Ok(lobes)
}

/// Signed outgoing angle of a sample (`+` mirror side).
fn signed(r: &LobeSample) -> f64 {
    curves::signed_theta_deg(r.theta_o_deg, r.phi_o_deg)
}

/// The key numbers of one in-plane lobe (at least one sample).
fn lobe_curve(s: &Lobe<'_>, lobe: &[LobeSample], theta_i: f64) -> LobeCurve {
    let by = |key: fn(&LobeSample) -> f64| {
        lobe.iter()
            .max_by(|a, b| key(a).total_cmp(&key(b)))
            .expect("a lobe has samples")
    };
    let fmax = by(|r| r.f11);
    let dmax = by(|r| r.dop);
    let at = |signed_deg: f64| {
        lobe.iter()
            .min_by(|x, y| {
                (signed(x) - signed_deg)
                    .abs()
                    .total_cmp(&(signed(y) - signed_deg).abs())
            })
            .map(|r| LobePoint {
                theta_o_signed_deg: signed(r),
                f11: r.f11,
                dop: r.dop,
            })
    };
    let mirror = Directions {
        theta_i_deg: theta_i,
        phi_i_deg: 0.0,
        theta_o_deg: theta_i,
        phi_o_deg: 180.0,
    };
    LobeCurve {
        label: s.label.clone(),
        source: s.origin.clone(),
        wavelength_nm: s.wavelength_nm,
        f11_max: fmax.f11,
        theta_o_signed_at_f11_max: signed(fmax),
        dop_max: dmax.dop,
        theta_o_signed_at_dop_max: signed(dmax),
        normal: at(0.0),
        mirror: at(theta_i),
        backscatter: at(-theta_i),
        specular: s.table.specular(&mirror, s.wavelength_nm).ok().flatten(),
    }
}
