//! `polbrdf solve SPEC.json [--points POINTS.json] [--field FIELD.json]`.

use crate::brdf::angles::{MU_FLOOR, dphi_prop_rad, mu_of_theta_deg};
use crate::solver::{self, Base, fourier_sum};
use crate::spec;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use std::time::Instant;

/// One direction pair in the graphics convention (degrees, both directions
/// pointing away from the surface).
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Point {
    pub theta_i_deg: f64,
    pub phi_i_deg: f64,
    pub theta_o_deg: f64,
    pub phi_o_deg: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PointsFile {
    points: Vec<Point>,
}

/// A field request (`--field`): a collimated beam of flux pi normal to it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FieldFile {
    mu0: f64,
    #[serde(default)]
    phi0_deg: f64,
    #[serde(default = "unpolarized")]
    stokes: [f64; 4],
    tau: Vec<f64>,
    mu: Vec<f64>,
    phi_deg: Vec<f64>,
}

fn unpolarized() -> [f64; 4] {
    [1.0, 0.0, 0.0, 0.0]
}

/// Sorted distinct cosines and a lookup.
pub struct MuSet {
    pub mu: Vec<f64>,
}

impl MuSet {
    pub fn new(values: impl IntoIterator<Item = f64>) -> Self {
        let mut mu: Vec<f64> = values.into_iter().collect();
        mu.sort_by(|a, b| a.partial_cmp(b).expect("finite"));
        mu.dedup_by(|a, b| (*a - *b).abs() <= 1e-15);
        Self { mu }
    }
    pub fn index(&self, m: f64) -> usize {
        self.mu
            .iter()
            .position(|&x| (x - m).abs() <= 1e-15)
            .expect("cosine in set")
    }
}

fn read_json<T: for<'de> Deserialize<'de>>(path: &str) -> Result<T, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    spec::json::from_str(&text).map_err(|e| format!("{path}: {e}"))
}

fn check_angle(what: &str, v: f64, lo: f64, hi: f64) -> Result<(), String> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(format!("{what} = {v} is outside [{lo}, {hi}]"))
    }
}

/// Run `solve` and return the JSON document.
pub fn run(
    spec_path: &str,
    points_path: Option<&str>,
    field_path: Option<&str>,
) -> Result<Value, String> {
    let text = std::fs::read_to_string(spec_path).map_err(|e| format!("{spec_path}: {e}"))?;
    let spec = spec::parse(&text).map_err(|e| format!("{spec_path}: {e}"))?;
    // Refuse before solving what the solver would refuse (docs/spec.md).
    spec::check_solvable(&spec, spec::MAX_STREAMS).map_err(|e| format!("{spec_path}: {e}"))?;
    let points: Vec<Point> = match points_path {
        Some(p) => read_json::<PointsFile>(p)?.points,
        None => Vec::new(),
    };
    for (i, p) in points.iter().enumerate() {
        check_angle(
            &format!("points[{i}].theta_i_deg"),
            p.theta_i_deg,
            0.0,
            90.0,
        )?;
        check_angle(
            &format!("points[{i}].theta_o_deg"),
            p.theta_o_deg,
            0.0,
            90.0,
        )?;
        check_angle(
            &format!("points[{i}].phi_i_deg"),
            p.phi_i_deg,
            -360.0,
            360.0,
        )?;
        check_angle(
            &format!("points[{i}].phi_o_deg"),
            p.phi_o_deg,
            -360.0,
            360.0,
        )?;
    }
    let field: Option<FieldFile> = field_path.map(read_json).transpose()?;
    if let Some(f) = &field {
        check_angle("field.mu0", f.mu0, MU_FLOOR, 1.0)?;
        for (i, m) in f.mu.iter().enumerate() {
            check_angle(&format!("field.mu[{i}]"), *m, -1.0, 1.0)?;
        }
        for (i, t) in f.tau.iter().enumerate() {
            check_angle(&format!("field.tau[{i}]"), *t, 0.0, 1e12)?;
        }
    }

    let mut results = Vec::new();
    for wl in spec::wavelengths(&spec) {
        let start = Instant::now();
        let problem = spec::problem(&spec, wl).map_err(|e| format!("{spec_path}: {e}"))?;
        let mut out = serde_json::Map::new();
        out.insert("wavelength_nm".into(), json!(wl));
        let mut orders = 0;

        let set = MuSet::new(points.iter().flat_map(|p| {
            [
                mu_of_theta_deg(p.theta_i_deg),
                mu_of_theta_deg(p.theta_o_deg),
            ]
        }));
        let mut pts = Vec::new();
        let mut spec_terms = Vec::new();
        let mut estimate = Value::Null;
        let mut streams_used = problem.settings.streams;
        if !set.mu.is_empty() {
            let solved = match spec::stream_policy(&spec) {
                spec::StreamPolicy::Fixed(_) => {
                    solver::accuracy::reflection_with_estimate(&problem, &set.mu)
                }
                spec::StreamPolicy::Tolerance(t) => solver::accuracy::reflection_to_tolerance(
                    &problem,
                    &set.mu,
                    t,
                    spec::MAX_STREAMS,
                    &|_| {},
                ),
            }
            .map_err(|e| e.to_string())?;
            estimate = serde_json::to_value(&solved.estimate).expect("JSON");
            streams_used = solved.estimate.streams[2];
            let refl = solved.reflection;
            orders = refl.rho.len();
            for p in &points {
                let iu = set.index(mu_of_theta_deg(p.theta_o_deg));
                let iv = set.index(mu_of_theta_deg(p.theta_i_deg));
                let m = refl.brdf(iu, iv, dphi_prop_rad(p.phi_i_deg, p.phi_o_deg));
                pts.push(json!({
                    "theta_i_deg": p.theta_i_deg, "phi_i_deg": p.phi_i_deg,
                    "theta_o_deg": p.theta_o_deg, "phi_o_deg": p.phi_o_deg,
                    "mueller": m,
                }));
            }
            if let Base::Mirror { mueller } = &problem.base {
                let mut seen: Vec<f64> = Vec::new();
                for p in &points {
                    if seen.contains(&p.theta_i_deg) {
                        continue;
                    }
                    seen.push(p.theta_i_deg);
                    let mu = mu_of_theta_deg(p.theta_i_deg);
                    let e = refl.direct[set.index(mu)];
                    let mut s = mueller(mu);
                    for row in &mut s {
                        for x in row.iter_mut() {
                            *x *= e * e;
                        }
                    }
                    spec_terms.push(json!({"theta_i_deg": p.theta_i_deg, "mueller": s}));
                }
            }
        }
        out.insert("points".into(), Value::Array(pts));
        out.insert("specular".into(), Value::Array(spec_terms));

        if let Some(f) = &field {
            let fset = MuSet::new(
                f.mu.iter()
                    .map(|m| m.abs().clamp(MU_FLOOR, 1.0))
                    .chain(std::iter::once(f.mu0)),
            );
            let ff =
                solver::internal_field(&problem, &fset.mu, &f.tau).map_err(|e| e.to_string())?;
            orders = orders.max(ff.up.first().map_or(0, |v| v.len()));
            let iv = fset.index(f.mu0);
            let mut entries = Vec::new();
            for (k, &tau) in f.tau.iter().enumerate() {
                for &mu in &f.mu {
                    let iu = fset.index(mu.abs().clamp(MU_FLOOR, 1.0));
                    let rho = if mu > 0.0 { &ff.up[k] } else { &ff.down[k] };
                    for &phi in &f.phi_deg {
                        let m = fourier_sum(rho, ff.ns, iu, iv, (phi - f.phi0_deg).to_radians());
                        let s = crate::physics::stokes::apply(&m, f.stokes)
                            .map(|x| std::f64::consts::PI * x);
                        entries.push(json!({"tau": tau, "mu": mu, "phi_deg": phi, "stokes": s}));
                    }
                }
            }
            out.insert("field".into(), Value::Array(entries));
        } else {
            out.insert("field".into(), Value::Array(Vec::new()));
        }
        let ms = start.elapsed().as_secs_f64() * 1e3;
        out.insert(
            "solver".into(),
            json!({"streams": streams_used, "polarized": problem.settings.polarized,
                   "fourier_orders": orders, "wall_time_ms": ms, "error_estimate": estimate}),
        );
        results.push(Value::Object(out));
    }
    Ok(json!({ "results": results }))
}
