//! `polbrdf convergence SPEC.json [--json] [--plot out.svg]`: error against
//! run time. Solves the spec in three families of settings (streams with the
//! spec's truncation; streams without delta-M; Fourier orders at the largest
//! stream count), compares each with a high-resolution reference on a probe
//! grid, and reports the error the solver itself estimated next to the true
//! one.

use crate::plot::draw;
use crate::plot::figure::{Axis, Dash, Figure, Legend, LinePanel, Panel, Series};
use crate::solver::{self, Problem, ReflectionFourier};
use crate::{material, plan};
use clap::Args;
use serde_json::{Value, json};
use std::time::Instant;

#[derive(Debug, Args)]
pub struct ConvergenceArgs {
    /// The material spec (its first wavelength is used).
    spec: String,
    /// Stream counts.
    #[arg(long, value_delimiter = ',', default_value = "4,8,16,32")]
    streams: Vec<usize>,
    /// Streams of the reference solve [default: twice the largest of --streams].
    #[arg(long)]
    reference_streams: Option<usize>,
    /// Print {"rows": [...]} as JSON.
    #[arg(long)]
    json: bool,
    /// Write an error-versus-time chart (log-log; .svg or .png).
    #[arg(long)]
    plot: Option<String>,
    /// Most streams of any solve, the reference's included (the HTTP service's
    /// default cap unless raised; at most 512).
    #[arg(long, default_value_t = super::solve::default_max_streams(), value_parser = super::solve::max_streams_parser())]
    max_streams: usize,
}

/// Probe grid of docs/accuracy.md: cosines of 11 polar angles at the
/// midpoints of 0..90°, 13 propagation azimuths over 0..180° (tests compare
/// on the same grid).
pub fn probe_grid() -> (Vec<f64>, Vec<f64>) {
    let mu: Vec<f64> = (0..11)
        .map(|k| (90.0 * (k as f64 + 0.5) / 11.0).to_radians().cos())
        .collect();
    let dphi: Vec<f64> = (0..13)
        .map(|k| std::f64::consts::PI * k as f64 / 12.0)
        .collect();
    (mu, dphi)
}

/// (f11, degree of polarization for unpolarized input) on the probe grid.
fn sample(r: &ReflectionFourier, dphi: &[f64]) -> Vec<(f64, f64)> {
    let n = r.mu.len();
    let mut out = Vec::new();
    for iu in 0..n {
        for iv in 0..n {
            for &d in dphi {
                let f = r.brdf(iu, iv, d);
                let dop = (f[1][0].powi(2) + f[2][0].powi(2) + f[3][0].powi(2)).sqrt() / f[0][0];
                out.push((f[0][0], dop));
            }
        }
    }
    out
}

fn with_streams(p: &Problem, n: usize) -> Problem {
    let mut q = p.clone();
    q.settings.streams = n;
    q
}

/// One row: a solve at `problem`'s settings, timed, compared with the
/// reference (`scale` = max f11 of the reference).
fn row(
    family: &str,
    p: &Problem,
    mu: &[f64],
    dphi: &[f64],
    reference: &[(f64, f64)],
    scale: f64,
    estimate: bool,
) -> Result<Value, String> {
    let t0 = Instant::now();
    let r = solver::reflection(p, mu).map_err(|e| e.to_string())?;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    let est = if estimate {
        json!(
            solver::accuracy::reflection_with_estimate(p, mu)
                .map_err(|e| e.to_string())?
                .estimate
                .max_err_f11
        )
    } else {
        Value::Null
    };
    let got = sample(&r, dphi);
    let (mut max_err, mut sq, mut max_dop) = (0.0f64, 0.0f64, 0.0f64);
    for (g, e) in got.iter().zip(reference) {
        let d = (g.0 - e.0).abs();
        max_err = max_err.max(d);
        sq += d * d;
        max_dop = max_dop.max((g.1 - e.1).abs());
    }
    Ok(json!({
        "family": family,
        "streams": p.settings.streams,
        "fourier_orders": r.rho.len(),
        "delta_m": p.settings.delta_m,
        "wall_time_ms": ms,
        "max_err_f11": max_err / scale,
        "rms_err_f11": (sq / got.len() as f64).sqrt() / scale,
        "max_err_dop": max_dop,
        "estimated_err": est,
    }))
}

pub fn run(a: &ConvergenceArgs) -> Result<Value, String> {
    let text = std::fs::read_to_string(&a.spec).map_err(|e| format!("{}: {e}", a.spec))?;
    let spec = material::parse(&text).map_err(|e| format!("{}: {e}", a.spec))?;
    let wl = plan::wavelengths(&spec)[0];
    let problem = plan::problem(&spec, wl).map_err(|e| format!("{}: {e}", a.spec))?;
    let (mu, dphi) = probe_grid();
    let max_streams = *a.streams.iter().max().ok_or("--streams is empty")?;
    if a.streams.contains(&0) {
        return Err("--streams: stream counts must be ≥ 1".into());
    }
    let reference_streams = a.reference_streams.unwrap_or(2 * max_streams);
    if reference_streams <= max_streams {
        return Err(format!(
            "--reference-streams {reference_streams} must exceed the largest of --streams ({max_streams})"
        ));
    }
    if reference_streams > a.max_streams {
        return Err(format!(
            "the reference solve needs {reference_streams} streams (--reference-streams, default twice the largest of --streams), over --max-streams {}: raise --max-streams or lower --streams",
            a.max_streams
        ));
    }
    let reference_problem = with_streams(&problem, reference_streams);
    let reference = sample(
        &solver::reflection(&reference_problem, &mu).map_err(|e| e.to_string())?,
        &dphi,
    );
    let scale = reference.iter().map(|x| x.0).fold(0.0, f64::max);
    let mut rows = Vec::new();
    // Family 1: streams, with the spec's truncation (delta-M + single-
    // scattering correction), with the solver's own estimate.
    for &n in &a.streams {
        rows.push(row(
            "streams",
            &with_streams(&problem, n),
            &mu,
            &dphi,
            &reference,
            scale,
            true,
        )?);
    }
    // Family 2: streams without truncation (what delta-M buys).
    if problem.settings.delta_m {
        for &n in &a.streams {
            let mut p = with_streams(&problem, n);
            p.settings.delta_m = false;
            rows.push(row(
                "streams, no delta-M",
                &p,
                &mu,
                &dphi,
                &reference,
                scale,
                false,
            )?);
        }
    }
    // Family 3: Fourier orders 0..=m at the largest stream count.
    let full_orders = rows
        .iter()
        .find(|r| r["family"] == "streams" && r["streams"] == max_streams)
        .and_then(|r| r["fourier_orders"].as_u64())
        .unwrap_or(1) as usize;
    let mut m = 1;
    while m < full_orders.saturating_sub(1) {
        let mut p = with_streams(&problem, max_streams);
        p.settings.max_order = Some(m);
        rows.push(row(
            "fourier orders",
            &p,
            &mu,
            &dphi,
            &reference,
            scale,
            false,
        )?);
        m *= 2;
    }
    if let Some(path) = &a.plot {
        let path = std::path::Path::new(path);
        draw::format_of(path)?;
        draw::register_font(None)?;
        draw::write(&chart(&rows, &a.spec), path)?;
    }
    let _ = a.json; // the output is always JSON
    Ok(
        json!({"rows": rows, "reference_streams": reference_streams, "wavelength_nm": wl,
              "probe": {"polar_angles": mu.len(), "azimuths": dphi.len()},
              "errors": "relative to max f11 of the reference; DOP absolute, for unpolarized incident light",
              "estimated_err": "the solver's a-posteriori estimate (solver::accuracy), for the streams family only"}),
    )
}

/// Error against wall time, log-log: the true max error of each family of
/// settings and the solver's estimate (streams family), one point per
/// setting; SVG or PNG by the extension (the plot module's renderer).
fn chart(rows: &[Value], spec: &str) -> Figure {
    let pts = |family: &str, key: &str| -> Vec<(f64, f64)> {
        rows.iter()
            .filter(|r| r["family"] == family && r[key].is_number())
            .map(|r| {
                (
                    r["wall_time_ms"].as_f64().unwrap_or(1.0).max(1e-3),
                    r[key].as_f64().unwrap_or(1e-16).max(1e-16),
                )
            })
            .collect()
    };
    let series: Vec<Series> = [
        ("streams: true error", "streams", "max_err_f11", Dash::Solid),
        (
            "streams: solver's estimate",
            "streams",
            "estimated_err",
            Dash::Dashed,
        ),
        (
            "streams, no delta-M",
            "streams, no delta-M",
            "max_err_f11",
            Dash::Solid,
        ),
        (
            "Fourier orders (largest streams)",
            "fourier orders",
            "max_err_f11",
            Dash::Solid,
        ),
    ]
    .iter()
    .enumerate()
    .map(|(k, (label, family, key, dash))| Series {
        label: label.to_string(),
        points: pts(family, key),
        color: k,
        dash: *dash,
        markers: true,
    })
    .filter(|s| !s.points.is_empty())
    .collect();
    let all: Vec<(f64, f64)> = series.iter().flat_map(|s| s.points.clone()).collect();
    let decade = |v: f64, up: bool| {
        let l = v.log10();
        10f64.powf(if up { l.ceil() } else { l.floor() })
    };
    let (x0, x1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (y0, y1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
    let (x0, x1) = if all.is_empty() {
        (1.0, 10.0)
    } else {
        (
            decade(x0, false),
            decade(x1, true).max(10.0 * decade(x0, false)),
        )
    };
    let (y0, y1) = if all.is_empty() {
        (1e-3, 1.0)
    } else {
        (
            decade(y0, false),
            decade(y1, true).max(10.0 * decade(y0, false)),
        )
    };
    Figure {
        size: (800, 520),
        rows: 1,
        cols: 1,
        panels: vec![Panel::Line(LinePanel {
            title: format!("error against run time: {spec}"),
            x: Axis {
                label: "wall time (ms)".into(),
                lo: x0,
                hi: x1,
                log: true,
            },
            y: Axis {
                label: "max |error of f11| / max f11".into(),
                lo: y0,
                hi: y1,
                log: true,
            },
            series,
            legend: Legend::UpperRight,
        })],
        footnote: "polbrdf convergence: each point one solve; reference at --reference-streams"
            .into(),
    }
}
