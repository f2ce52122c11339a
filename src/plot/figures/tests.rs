//! The figure functions on cheap Rayleigh specs: the shape of what they
//! return (series, points, rows, axes), and one law: single scattering by
//! a conservative Rayleigh layer polarizes unpolarized light to
//! `DOP = sin²Θ / (1 + cos²Θ)` at scattering angle `Θ` (Chandrasekhar,
//! Radiative Transfer, §I.17; Hansen & Travis 1974, eq. 2.13 for the
//! Rayleigh phase matrix), which a very thin layer over black reproduces.

use super::shared::percent_range;
use super::*;
use crate::brdf::PolarGrid;
use crate::plot::curves::UNPOLARIZED;
use crate::plot::figure::{Dash, Panel};
use crate::solver::Thickness;

fn rayleigh(tau: f64, albedo: f64, base: &str) -> Spec {
    crate::material::parse(&format!(
        r#"{{"layers":[{{"optical_thickness":{tau},"scatterer":{{"rayleigh":{{"albedo":{albedo}}}}}}}],
            "base":{base},"solver":{{"streams":8}}}}"#
    ))
    .unwrap()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * b.abs()
}

fn line(fig: &Figure) -> &crate::plot::figure::LinePanel {
    assert_eq!((fig.rows, fig.cols, fig.panels.len()), (1, 1, 1));
    match &fig.panels[0] {
        Panel::Line(p) => p,
        other => panic!("a line panel, got {other:?}"),
    }
}

#[test]
fn dop_vs_mu_has_a_curve_per_thickness_and_azimuth() {
    let spec = rayleigh(1.0, 0.9, r#"{"lambertian":{"albedo":0.3}}"#);
    let o = DopVsMuOptions {
        taus: Some(vec![Thickness::Finite(0.5), Thickness::Finite(2.0)]),
        mu0: 0.6,
        phi_o_deg: vec![180.0, 0.0, 90.0],
        stokes: UNPOLARIZED,
        mu_samples: 5,
        solve: SolveOptions::default(),
        size: None,
    };
    let plot = dop_vs_mu(
        Source::Spec {
            path: "dir/r.json",
            spec: &spec,
        },
        &o,
    )
    .unwrap();
    let p = line(&plot.figure);
    assert_eq!(p.series.len(), 2 * 3);
    assert!(p.series.iter().all(|s| s.points.len() == 5));
    // Colour by thickness, dash by azimuth position.
    let styles: Vec<(usize, Dash)> = p.series.iter().map(|s| (s.color, s.dash)).collect();
    assert_eq!(
        styles,
        [
            (0, Dash::Solid),
            (0, Dash::Dashed),
            (0, Dash::Solid),
            (1, Dash::Solid),
            (1, Dash::Dashed),
            (1, Dash::Solid)
        ]
    );
    assert_eq!(p.series[4].label, "τ = 2, φ_o = 0°");
    assert!(p.y.hi <= 100.0 && p.y.lo == 0.0, "{:?}", p.y);
    assert_eq!(plot.figure.size, (900, 540));
    assert!(
        plot.figure
            .footnote
            .starts_with("r.json (Rayleigh on Lambertian 0.3 base), 8 streams")
    );
    assert_eq!(plot.csv.rows.len(), 30);
    assert_eq!(plot.summary.rows, 30);
    assert_eq!(plot.summary.curves.len(), 6);
    assert_eq!(plot.summary.solver, SolverSummary::Streams(8));
    for (c, s) in plot.summary.curves.iter().zip(&p.series) {
        let max = s.points.iter().map(|q| q.1).fold(f64::MIN, f64::max);
        assert_eq!(100.0 * c.dop_max, max);
        assert!(c.dop_min <= c.dop_max && c.dop_max <= 1.0);
    }
    // A table holds one thickness.
    let table = crate::brdf::Table::from_spec(&spec, PolarGrid::graded(6).unwrap()).unwrap();
    let e = dop_vs_mu(
        Source::Table {
            path: "t.pbrdf",
            table: &table,
        },
        &o,
    )
    .unwrap_err();
    assert!(matches!(e, PlotError::Options(_)), "{e}");
}

#[test]
fn thin_conservative_rayleigh_layer_polarizes_as_single_scattering() {
    let spec = rayleigh(1.0, 1.0, r#""black""#);
    // μ0 = 0.6, μ = 0.8: cos Θ = −μ0 μ + sin θ0 sin θ cos φ_o with φ_o from
    // the mirror side (180° → cos = 1).
    let cos_theta =
        |phi_o_deg: f64| -0.6 * 0.8 + 0.8 * 0.6 * (180.0 - phi_o_deg).to_radians().cos();
    for phi_o_deg in [180.0, 90.0, 0.0] {
        let o = DopVsTauOptions {
            taus: vec![Thickness::Finite(1e-4), Thickness::Finite(1e-3)],
            mu0: 0.6,
            mu: 0.8,
            phi_o_deg,
            stokes: vec![UNPOLARIZED, [1.0, 1.0, 0.0, 0.0]],
            solve: SolveOptions::default(),
            size: Some((400, 300)),
        };
        let plot = dop_vs_tau("r.json", &spec, &o).unwrap();
        let c = cos_theta(phi_o_deg);
        let single = (1.0 - c * c) / (1.0 + c * c);
        let thin = plot.summary.curves[0].dop_at_smallest_tau.unwrap();
        assert!(
            (thin - single).abs() < 1e-3,
            "φ_o = {phi_o_deg}: DOP {thin} vs {single}"
        );
        // One-layer spec: the semi-infinite layer is added, in the legend
        // and the CSV but not on the log axis.
        assert_eq!(plot.csv.rows.len(), 3 * 2);
        assert!(plot.summary.curves[0].dop_semi_infinite.is_some());
        let p = line(&plot.figure);
        assert_eq!(p.series.len(), 2);
        assert!(p.series.iter().all(|s| s.points.len() == 2 && s.markers));
        assert!(p.series[0].label.contains("τ = ∞"), "{}", p.series[0].label);
        assert!(
            p.x.log && close(p.x.lo, 1e-4) && close(p.x.hi, 1e-3),
            "{:?}",
            p.x
        );
        assert_eq!(plot.figure.size, (400, 300));
    }
}

#[test]
fn scalar_error_has_a_curve_per_spec_and_pair_on_whole_decades() {
    let a = rayleigh(1.0, 0.9, r#""black""#);
    let b = rayleigh(1.0, 0.5, r#"{"lambertian":{"albedo":0.5}}"#);
    let inputs = [
        ScalarErrorInput {
            path: "a.json",
            spec: &a,
            label: Some("A".into()),
        },
        ScalarErrorInput {
            path: "b.json",
            spec: &b,
            label: None,
        },
    ];
    let o = ScalarErrorOptions {
        taus: vec![Thickness::Finite(0.02), Thickness::Finite(3.0)],
        pairs: vec![(0.6, 0.6), (0.9, 1.0)],
        phi_o_deg: 180.0,
        solve: SolveOptions {
            wavelength_nm: None,
            streams: Some(4),
        },
        size: None,
    };
    let plot = scalar_error(&inputs, &o).unwrap();
    let p = line(&plot.figure);
    assert_eq!(p.series.len(), 4);
    assert_eq!(p.series[1].label, "A, (μ0, μ) = (0.9, 1)");
    assert_eq!(p.series[2].label, "Rayleigh, (μ0, μ) = (0.6, 0.6)");
    assert_eq!(
        p.series.iter().map(|s| s.dash).collect::<Vec<_>>(),
        [Dash::Solid, Dash::Dashed, Dash::Solid, Dash::Dashed]
    );
    assert!(
        p.x.log && close(p.x.lo, 0.01) && close(p.x.hi, 10.0),
        "{:?}",
        p.x
    );
    assert_eq!(plot.csv.rows.len(), 2 * 2 * 2);
    assert_eq!(plot.summary.curves.len(), 4);
    assert_eq!(plot.summary.curves[3].solver, SolverSummary::Streams(4));
    // Rayleigh polarizes, so the scalar RTE is off somewhere.
    assert!(plot.summary.curves.iter().any(|c| c.e_max.abs() > 1e-4));
    let none = ScalarErrorOptions {
        taus: vec![Thickness::Infinite],
        ..o
    };
    assert!(matches!(
        scalar_error(&inputs, &none),
        Err(PlotError::Options(_))
    ));
}

#[test]
fn lobe_has_two_lobe_panels_and_a_map_per_source_and_quantity() {
    let spec = rayleigh(0.5, 0.9, r#"{"lambertian":{"albedo":0.3}}"#);
    let grid = PolarGrid::graded(8).unwrap();
    let table = crate::brdf::Table::from_spec(&spec, grid.clone()).unwrap();
    let inputs = [
        LobeInput {
            source: Source::Spec {
                path: "r.json",
                spec: &spec,
            },
            label: None,
        },
        LobeInput {
            source: Source::Table {
                path: "x/t.pbrdf",
                table: &table,
            },
            label: Some("file"),
        },
    ];
    let o = LobeOptions {
        theta_i_deg: 30.0,
        step_deg: 30.0,
        map_cells: (2, 4),
        grid,
        solve: SolveOptions::default(),
        size: None,
    };
    let plot = lobe(&inputs, &o).unwrap();
    assert_eq!(plot.figure.panels.len(), 2);
    for panel in &plot.figure.panels {
        let Panel::Lobe(l) = panel else {
            panic!("a lobe panel")
        };
        assert_eq!(l.series.len(), 2);
        assert!(l.series.iter().all(|s| s.points.len() == 7));
    }
    assert_eq!((plot.map_figure.rows, plot.map_figure.cols), (2, 2));
    assert_eq!(plot.map_figure.size, (640, 640));
    assert_eq!(plot.csv.rows.len(), 2 * 7);
    assert_eq!(plot.map_csv.rows.len(), 2 * 2 * 4);
    let s = &plot.summary;
    assert_eq!((s.rows, s.map_rows), (14, 16));
    assert_eq!(s.curves[0].label, "Rayleigh on Lambertian 0.3");
    assert_eq!(s.curves[0].source, "r.json (8 streams)");
    assert_eq!(s.curves[1].label, "file");
    assert_eq!(s.curves[1].source, "table t.pbrdf (8 streams)");
    assert_eq!(
        s.curves[1].mirror.as_ref().unwrap().theta_o_signed_deg,
        30.0
    );
    assert_eq!(
        s.curves[1].backscatter.as_ref().unwrap().theta_o_signed_deg,
        -30.0
    );
    assert!(s.curves[1].specular.is_none());
    // The same spec at the same grid: the same lobe.
    assert!(close(s.curves[0].f11_max, s.curves[1].f11_max));
}

#[test]
fn words_and_ranges() {
    assert_eq!(
        stokes_name([1.0, 0.0, 0.0, 1.0]),
        "[1, 0, 0, 1] right circular"
    );
    assert_eq!(stokes_name([1.0, 0.5, 0.0, 0.0]), "[1, 0.5, 0, 0]");
    assert_eq!(percent_range([3.0, 47.0].into_iter()), (0.0, 50.0));
    assert_eq!(percent_range([-3.0, 9.0].into_iter()), (-5.0, 10.0));
    assert_eq!(percent_range([99.9].into_iter()), (0.0, 100.0));
    assert_eq!(
        serde_json::to_value(SolverSummary::Tolerance(1e-3)).unwrap(),
        serde_json::json!({"tolerance": 1e-3})
    );
}

/// A Rayleigh layer at the listed wavelengths (its optics do not depend on them).
fn rayleigh_spectrum(tau: f64, albedo: f64, base: &str) -> Spec {
    crate::material::parse(&format!(
        r#"{{"layers":[{{"optical_thickness":{tau},"scatterer":{{"rayleigh":{{"albedo":{albedo}}}}}}}],
            "base":{base},"wavelengths_nm":[450,550,650],"solver":{{"streams":8}}}}"#
    ))
    .unwrap()
}

fn spectrum_options(theta_i_deg: f64, theta_o_deg: f64) -> SpectrumOptions {
    SpectrumOptions {
        mu0: theta_i_deg.to_radians().cos(),
        mu: theta_o_deg.to_radians().cos(),
        phi_o_deg: 180.0,
        solve: SolveOptions::default(),
        size: None,
    }
}

/// Energy: a conservative layer over a white Lambertian base reflects all
/// the light, `A(μ0) = 1` at every wavelength (the stream fluxes conserve
/// it exactly); over black it reflects less and transmits the rest.
#[test]
fn spectrum_albedo_of_a_conservative_layer_on_white_is_one() {
    let o = spectrum_options(45.0, 0.0);
    let white = rayleigh_spectrum(1.0, 1.0, r#"{"lambertian":{"albedo":1}}"#);
    let rows = spectrum_samples("white.json", &white, &o).unwrap();
    assert_eq!(rows.len(), 3);
    for r in &rows {
        assert!(
            (r.albedo - 1.0).abs() < 1e-12,
            "{} nm: {}",
            r.wavelength_nm,
            r.albedo
        );
        assert_eq!(r.streams, 8);
    }
    let black = rayleigh_spectrum(1.0, 1.0, r#""black""#);
    for r in spectrum_samples("black.json", &black, &o).unwrap() {
        assert!(r.albedo > 0.2 && r.albedo < 0.8, "{}", r.albedo);
    }
}

/// Single scattering by a very thin Rayleigh layer over black, θ_i = 45°
/// to the normal (Θ = 135°): `DOP = sin²Θ/(1 + cos²Θ) = 1/3` and
/// `f11 = ω τ P(Θ) / (4π μ0 μ)` with `P = ¾(1 + cos²Θ)`.
#[test]
fn spectrum_of_a_thin_rayleigh_layer_is_single_scattering() {
    let tau = 1e-5;
    let spec = rayleigh_spectrum(tau, 1.0, r#""black""#);
    let o = spectrum_options(45.0, 0.0);
    let rows = spectrum_samples("thin.json", &spec, &o).unwrap();
    let cos_t = -(45f64.to_radians().cos());
    let p = 0.75 * (1.0 + cos_t * cos_t);
    let f11 = tau * p / (4.0 * std::f64::consts::PI * o.mu0 * o.mu);
    for r in &rows {
        assert!((r.dop - 1.0 / 3.0).abs() < 1e-4, "{}", r.dop);
        assert!((r.f11 / f11 - 1.0).abs() < 1e-4, "{} vs {f11}", r.f11);
    }
}

/// Two specs: two panels, three series per spec in all (albedo solid and
/// π f11 dashed above, DOP below), one CSV row per wavelength and spec;
/// a spec without wavelengths is refused by name.
#[test]
fn spectrum_has_two_panels_and_a_row_per_wavelength() {
    let a = rayleigh_spectrum(1.0, 0.9, r#""black""#);
    let b = rayleigh_spectrum(1.0, 0.9, r#"{"lambertian":{"albedo":0.5}}"#);
    let inputs = [
        SpectrumInput {
            path: "a.json",
            spec: &a,
            label: None,
        },
        SpectrumInput {
            path: "b.json",
            spec: &b,
            label: Some("on grey".into()),
        },
    ];
    let plot = spectrum(&inputs, &spectrum_options(45.0, 0.0)).unwrap();
    assert_eq!((plot.figure.rows, plot.figure.cols), (2, 1));
    let lines: Vec<_> = plot
        .figure
        .panels
        .iter()
        .map(|p| match p {
            Panel::Line(l) => l,
            other => panic!("line panels, got {other:?}"),
        })
        .collect();
    assert_eq!(lines[0].series.len(), 4);
    assert_eq!(lines[1].series.len(), 2);
    assert_eq!(lines[0].series[1].dash, Dash::Dashed);
    assert!(lines[1].series[1].label.contains("on grey"));
    assert_eq!(plot.summary.rows, 6);
    assert_eq!(plot.csv.text().lines().count(), 1 + 6);
    // The grey base reflects more than black.
    let (ca, cb) = (&plot.summary.curves[0], &plot.summary.curves[1]);
    assert!(cb.albedo_min > ca.albedo_max);
    let none = rayleigh(1.0, 0.9, r#""black""#);
    let e = spectrum_samples("none.json", &none, &spectrum_options(45.0, 0.0)).unwrap_err();
    assert!(e.to_string().contains("none.json") && e.to_string().contains("wavelengths_nm"));
}
