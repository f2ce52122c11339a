//! `polbrdf convergence SPEC.json [--json] [--plot out.svg]`: error against
//! run time. Solves the spec in three families of settings (streams with the
//! spec's truncation; streams without delta-M; Fourier orders at the largest
//! stream count), compares each with a high-resolution reference on a probe
//! grid, and reports the error the solver itself estimated next to the true
//! one.

use crate::solver::{self, Problem, ReflectionFourier};
use crate::spec;
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
    /// Write an error-versus-time chart (log-log SVG).
    #[arg(long)]
    plot: Option<String>,
}

/// Probe grid: 11 polar angles at the midpoints of 0..90°, 13 azimuths.
fn probe_grid() -> (Vec<f64>, Vec<f64>) {
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
    let spec = spec::parse(&text).map_err(|e| format!("{}: {e}", a.spec))?;
    let wl = spec::wavelengths(&spec)[0];
    let problem = spec::problem(&spec, wl).map_err(|e| format!("{}: {e}", a.spec))?;
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
        std::fs::write(path, svg(&rows)).map_err(|e| format!("{path}: {e}"))?;
    }
    let _ = a.json; // the output is always JSON
    Ok(
        json!({"rows": rows, "reference_streams": reference_streams, "wavelength_nm": wl,
              "probe": {"polar_angles": mu.len(), "azimuths": dphi.len()},
              "errors": "relative to max f11 of the reference; DOP absolute, for unpolarized incident light",
              "estimated_err": "the solver's a-posteriori estimate (solver::accuracy), for the streams family only"}),
    )
}

/// A minimal log-log chart of error against wall time: the true max error
/// of each family of settings and the solver's estimate (streams family),
/// one point per setting.
fn svg(rows: &[Value]) -> String {
    let pts = |family: &str, key: &str| -> Vec<(f64, f64, u64)> {
        rows.iter()
            .filter(|r| r["family"] == family && r[key].is_number())
            .map(|r| {
                (
                    r["wall_time_ms"].as_f64().unwrap_or(1.0).max(1e-3),
                    r[key].as_f64().unwrap_or(1e-16).max(1e-16),
                    if family == "fourier orders" {
                        r["fourier_orders"].as_u64().unwrap_or(0)
                    } else {
                        r["streams"].as_u64().unwrap_or(0)
                    },
                )
            })
            .collect()
    };
    let series = [
        (
            pts("streams", "max_err_f11"),
            "black",
            "streams: true error",
            "N=",
        ),
        (
            pts("streams", "estimated_err"),
            "red",
            "streams: estimate",
            "",
        ),
        (
            pts("streams, no delta-M", "max_err_f11"),
            "blue",
            "streams, no delta-M",
            "",
        ),
        (
            pts("fourier orders", "max_err_f11"),
            "green",
            "Fourier orders",
            "M=",
        ),
    ];
    let all: Vec<&(f64, f64, u64)> = series.iter().flat_map(|s| s.0.iter()).collect();
    if all.is_empty() {
        return "<svg xmlns='http://www.w3.org/2000/svg'/>\n".into();
    }
    let (tx0, tx1) = all.iter().fold((f64::MAX, f64::MIN), |(a, b), p| {
        (a.min(p.0.log10()), b.max(p.0.log10()))
    });
    let (ty0, ty1) = all.iter().fold((f64::MAX, f64::MIN), |(a, b), p| {
        (a.min(p.1.log10()), b.max(p.1.log10()))
    });
    let (x0, x1) = (tx0.floor(), tx1.ceil().max(tx0.floor() + 1.0));
    let (y0, y1) = (ty0.floor(), ty1.ceil().max(ty0.floor() + 1.0));
    let (w, h, m) = (640.0, 420.0, 60.0);
    let px = |t: f64| m + (t.log10() - x0) / (x1 - x0) * (w - 2.0 * m);
    let py = |e: f64| h - m - (e.log10() - y0) / (y1 - y0) * (h - 2.0 * m);
    let mut s = format!(
        "<svg xmlns='http://www.w3.org/2000/svg' width='{w}' height='{h}' font-family='sans-serif' font-size='12'>\n\
         <rect width='100%' height='100%' fill='white'/>\n\
         <line x1='{m}' y1='{}' x2='{}' y2='{}' stroke='black'/>\n<line x1='{m}' y1='{m}' x2='{m}' y2='{}' stroke='black'/>\n",
        h - m,
        w - m,
        h - m,
        h - m
    );
    for k in x0 as i32..=x1 as i32 {
        let x = m + (k as f64 - x0) / (x1 - x0) * (w - 2.0 * m);
        s += &format!(
            "<text x='{x}' y='{}' text-anchor='middle'>1e{k}</text>\n",
            h - m + 18.0
        );
    }
    for k in y0 as i32..=y1 as i32 {
        let y = h - m - (k as f64 - y0) / (y1 - y0) * (h - 2.0 * m);
        s += &format!(
            "<text x='{}' y='{y}' text-anchor='end'>1e{k}</text>\n",
            m - 6.0
        );
    }
    s += &format!(
        "<text x='{}' y='{}' text-anchor='middle'>wall time (ms)</text>\n",
        w / 2.0,
        h - 15.0
    );
    s += &format!(
        "<text x='15' y='{}' transform='rotate(-90 15 {})' text-anchor='middle'>max |error f11| / max f11</text>\n",
        h / 2.0,
        h / 2.0
    );
    for (k, (series, colour, label, tag)) in series.iter().enumerate() {
        if series.is_empty() {
            continue;
        }
        let dy = 16.0 * k as f64;
        let path: Vec<String> = series
            .iter()
            .map(|p| format!("{:.1},{:.1}", px(p.0), py(p.1)))
            .collect();
        s += &format!(
            "<polyline fill='none' stroke='{colour}' points='{}'/>\n",
            path.join(" ")
        );
        for p in series.iter() {
            s += &format!(
                "<circle cx='{:.1}' cy='{:.1}' r='3' fill='{colour}'/>\n",
                px(p.0),
                py(p.1)
            );
            if !tag.is_empty() {
                s += &format!(
                    "<text x='{:.1}' y='{:.1}' fill='{colour}'>{tag}{}</text>\n",
                    px(p.0) + 5.0,
                    py(p.1) - 5.0,
                    p.2
                );
            }
        }
        s += &format!(
            "<text x='{}' y='{}' fill='{colour}'>{label}</text>\n",
            w - m - 150.0,
            m + dy
        );
    }
    s + "</svg>\n"
}
