//! `polbrdf bench ...`: timings recorded in docs/performance.md.

use crate::physics::{self, RefractiveIndex};
use crate::solver::{self, Base, Layer, Problem, Settings, Thickness};
use clap::{Args, Subcommand};
use rayon::prelude::*;
use serde_json::{Value, json};
use std::time::Instant;

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Full-Mueller BRDF table of the TiO2 layer of Collin et al., "Computation
    /// of Polarized Subsurface BRDF for Rendering" (Graphics Interface 2014), on
    /// their 51 x 51 x 61 grid, at several stream counts, with the error against
    /// the 64-stream table.
    Table(TableArgs),
    /// Time per Mie + expansion at several size parameters.
    Mie(MieBenchArgs),
    /// The full request against each reduced request (`needs`, a subset of
    /// the wavelengths, a looser tolerance) for the TiO2 layer of Collin et
    /// al. 2014 over black and over silver, in one run
    /// (docs/performance.md, "Reduced requests").
    Needs(NeedsBenchArgs),
}

#[derive(Debug, Args)]
pub struct NeedsBenchArgs {
    /// Repetitions per request (the minimum time is reported).
    #[arg(long, default_value_t = 3)]
    repeat: usize,
}

#[derive(Debug, Args)]
pub struct TableArgs {
    /// Stream counts to time (default 8,16,32,64; the largest is the reference).
    #[arg(long, value_delimiter = ',')]
    streams: Option<Vec<usize>>,
    /// Print {"rows": [...]} as JSON (always JSON; kept for scripts).
    #[arg(long)]
    json: bool,
    /// Repetitions per setting (the minimum time is reported).
    #[arg(long, default_value_t = 3)]
    repeat: usize,
    /// Thin start layer relative to the smallest quadrature cosine (the
    /// reference always uses 1e-3).
    #[arg(long, default_value_t = 0.1)]
    start_factor: f64,
}

#[derive(Debug, Args)]
pub struct MieBenchArgs {
    /// Size parameters.
    #[arg(long, value_delimiter = ',', default_value = "1,10,100,1000,10000")]
    x: Vec<f64>,
    /// Relative index n (real part).
    #[arg(long, default_value_t = 1.5)]
    n: f64,
    /// Relative index k.
    #[arg(long, default_value_t = 0.01)]
    k: f64,
}

pub fn run(cmd: &BenchCommand) -> Result<Value, String> {
    match cmd {
        BenchCommand::Table(a) => table(a),
        BenchCommand::Mie(a) => mie(a),
        BenchCommand::Needs(a) => needs(a),
    }
}

/// `b` merged into `a` (objects key by key, anything else replaced).
fn merge(a: &mut Value, b: &Value) {
    match (a, b) {
        (Value::Object(a), Value::Object(b)) => {
            for (k, v) in b {
                merge(a.entry(k.clone()).or_insert(Value::Null), v);
            }
        }
        (a, b) => *a = b.clone(),
    }
}

/// The requests of `polbrdf bench needs`: `(label, baseline label, patch
/// of the seed's TiO2 spec)`. The baseline of each reduced request is the
/// full request it is a part of.
fn needs_requests() -> Vec<(&'static str, &'static str, Value)> {
    let full = "full";
    vec![
        (full, full, json!({})),
        (
            "three wavelengths (450, 550, 650 nm)",
            full,
            json!({"wavelengths_nm": [450, 550, 650]}),
        ),
        (
            "one wavelength of three",
            "three wavelengths (450, 550, 650 nm)",
            json!({}),
        ),
        (
            "stokes: unpolarized_in",
            full,
            json!({"needs": {"stokes": "unpolarized_in"}}),
        ),
        (
            "stokes: intensity",
            full,
            json!({"needs": {"stokes": "intensity"}}),
        ),
        (
            "theta_i_deg: [0, 30, 60]",
            full,
            json!({"needs": {"theta_i_deg": [0, 30, 60]}}),
        ),
        (
            "error_estimate: false",
            full,
            json!({"needs": {"error_estimate": false}}),
        ),
        (
            "grid.polar_nodes: 16",
            full,
            json!({"needs": {"grid": {"polar_nodes": 16}}}),
        ),
        (
            "grid.max_fourier_orders: 4",
            full,
            json!({"needs": {"grid": {"max_fourier_orders": 4}}}),
        ),
        (
            "tolerance 1e-5",
            "tolerance 1e-5",
            json!({"solver": {"streams": null, "tolerance": 1e-5}}),
        ),
        (
            "tolerance 1e-2",
            "tolerance 1e-5",
            json!({"solver": {"streams": null, "tolerance": 1e-2}}),
        ),
    ]
}

fn needs(a: &NeedsBenchArgs) -> Result<Value, String> {
    use crate::brdf::format::{self, DataType};
    use crate::brdf::table::{BuildOptions, Table};
    let seed = json!({
        "layers": [{"optical_thickness": 1.0,
                    "scatterer": {"mie": {"material": "TiO2", "radius_um": 0.2, "host_index": 1.0}}}],
        "wavelengths_nm": [550],
        "solver": {"streams": 16, "polarized": true}
    });
    let mut out = serde_json::Map::new();
    for (base_name, base) in [
        ("black", json!("black")),
        ("silver", json!({"fresnel": {"material": "silver"}})),
    ] {
        let mut rows: Vec<Value> = Vec::new();
        let mut times = std::collections::HashMap::new();
        for (label, baseline, patch) in needs_requests() {
            let mut spec = seed.clone();
            spec["base"] = base.clone();
            merge(&mut spec, &patch);
            if let Some(s) = spec["solver"].as_object_mut() {
                s.retain(|_, v| !v.is_null());
            }
            let parsed = match crate::material::parse(&spec.to_string()) {
                Ok(s) => s,
                Err(e) => {
                    rows.push(json!({"request": label, "refused": e.to_string()}));
                    continue;
                }
            };
            let mut best = f64::INFINITY;
            let mut table = None;
            for _ in 0..a.repeat.max(1) {
                let t0 = Instant::now();
                let t = Table::from_spec_needs(&parsed, &BuildOptions::default())
                    .map_err(|e| format!("{label} over {base_name}: {e}"))?;
                best = best.min(t0.elapsed().as_secs_f64() * 1e3);
                table = Some(t);
            }
            let table = table.expect("at least one repetition");
            let bytes = format::to_bytes(&table, DataType::F64)
                .map_err(|e| e.to_string())?
                .len();
            times.insert(label, best);
            let meta = &table.metadata.wavelengths;
            let estimate = meta
                .iter()
                .filter_map(|w| w.error_estimate.as_ref().map(|e| e.max_err_f11))
                .reduce(f64::max);
            let interpolation = meta
                .iter()
                .filter_map(|w| w.interpolation_error)
                .reduce(f64::max);
            let streams: Vec<usize> = meta.iter().map(|w| w.streams).collect();
            let speed_up = times.get(baseline).map(|t| t / best);
            rows.push(json!({
                "request": label, "baseline": baseline, "wall_time_ms": best,
                "speed_up": speed_up, "table_bytes": bytes, "streams": streams,
                "error_estimate": estimate, "interpolation_error": interpolation,
            }));
        }
        out.insert(base_name.to_string(), Value::Array(rows));
    }
    out.insert("repeat".into(), json!(a.repeat));
    Ok(Value::Object(out))
}

/// The table size of Collin et al. 2014 (Graphics Interface): 51 polar
/// angles (incident and outgoing) at the midpoints of 51 equal steps of
/// 0..90° (0.88°..89.12°: the horizon itself,
/// where the single-scattering BRDF diverges like 1/(μ + μ0), is left out so
/// that "relative to max f11" means something) and 61 azimuths 0..360°.
pub fn seed_grid() -> (Vec<f64>, Vec<f64>) {
    let theta: Vec<f64> = (0..51).map(|k| 90.0 * (k as f64 + 0.5) / 51.0).collect();
    let phi: Vec<f64> = (0..61).map(|k| 360.0 * k as f64 / 60.0).collect();
    (theta, phi)
}

/// The TiO2 benchmark problem (r = 0.2 µm, 550 nm, host 1.0, tau = 1, black).
fn tio2_problem(streams: usize, start_factor: f64) -> Result<Problem, String> {
    let index = physics::materials::refractive_index("TiO2", 550.0).map_err(|e| e.to_string())?;
    let (albedo, coef) =
        physics::mie_expansion(index, 1.0, 550.0, Some(0.2), None).map_err(|e| e.to_string())?;
    Ok(Problem {
        layers: vec![Layer {
            thickness: Thickness::Finite(1.0),
            albedo,
            coef,
        }],
        base: Base::Black,
        settings: Settings {
            streams,
            start_factor,
            ..Settings::default()
        },
        top_interface: None,
    })
}

/// f11 on the grid of [`seed_grid`]: [theta_i][theta_o][phi].
fn table_f11(problem: &Problem) -> Result<Vec<f64>, String> {
    let (theta, phi) = seed_grid();
    let mu: Vec<f64> = theta
        .iter()
        .map(|&t| crate::brdf::angles::mu_of_theta_deg(t))
        .collect();
    let set = super::solve::MuSet::new(mu.iter().cloned());
    let refl = solver::reflection(problem, &set.mu).map_err(|e| e.to_string())?;
    let dphi: Vec<f64> = phi.iter().map(|p| (p - 180.0).to_radians()).collect();
    let basis = refl.azimuth_basis(&dphi);
    // The full Mueller matrix is synthesised (f11 is what is compared).
    let out: Vec<Vec<f64>> = mu
        .par_iter()
        .map(|&mi| {
            let iv = set.index(mi);
            let mut row = Vec::with_capacity(mu.len() * phi.len());
            for &mo in &mu {
                let iu = set.index(mo);
                for (b, &d) in basis.iter().zip(&dphi) {
                    let mut f11 = refl.brdf_with_basis(iu, iv, b)[0][0];
                    if let Some(c) = &refl.correction {
                        f11 += c.brdf(set.mu[iu], set.mu[iv], d)[0][0];
                    }
                    if let Some(s) = &refl.surface {
                        f11 += s.mueller(set.mu[iu], set.mu[iv], d)[0][0];
                    }
                    row.push(f11);
                }
            }
            row
        })
        .collect();
    Ok(out.concat())
}

fn table(a: &TableArgs) -> Result<Value, String> {
    let streams = a.streams.clone().unwrap_or_else(|| vec![8, 16, 32, 64]);
    let reference_streams = *streams.iter().max().ok_or("no stream counts")?;
    let reference = table_f11(&tio2_problem(reference_streams, 1e-3)?)?;
    let scale = reference.iter().cloned().fold(0.0, f64::max);
    let mut rows = Vec::new();
    for &n in &streams {
        let problem = tio2_problem(n, a.start_factor)?;
        let mut best = f64::INFINITY;
        let mut table = Vec::new();
        for _ in 0..a.repeat.max(1) {
            let t0 = Instant::now();
            table = table_f11(&problem)?;
            best = best.min(t0.elapsed().as_secs_f64() * 1e3);
        }
        let max_err = table
            .iter()
            .zip(&reference)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
            / scale;
        rows.push(json!({"streams": n, "wall_time_ms": best, "max_err_f11": max_err, "points": table.len()}));
    }
    Ok(
        json!({"rows": rows, "reference_streams": reference_streams, "max_f11": scale,
              "start_factor": a.start_factor}),
    )
}

fn mie(a: &MieBenchArgs) -> Result<Value, String> {
    let mut rows = Vec::new();
    for &x in &a.x {
        // Radius for lambda = 1000 nm in vacuum, host 1.
        let radius_um = x / (2.0 * std::f64::consts::PI);
        let index = RefractiveIndex::new(a.n, a.k);
        let t0 = Instant::now();
        let mut reps = 0;
        let mut terms = 0;
        while reps == 0 || t0.elapsed().as_secs_f64() < 0.5 {
            let (_, coef) = physics::mie_expansion(index, 1.0, 1000.0, Some(radius_um), None)
                .map_err(|e| e.to_string())?;
            terms = coef.beta.len();
            reps += 1;
        }
        let ms = t0.elapsed().as_secs_f64() * 1e3 / reps as f64;
        rows.push(json!({"size_parameter": x, "wall_time_ms": ms, "expansion_terms": terms}));
    }
    Ok(json!({"rows": rows}))
}
