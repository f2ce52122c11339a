//! What a job computes and the bytes it stores: the one place to swap the
//! result format.
//!
//! **Interim format** (`application/vnd.polbrdf.fourier+json`, until the
//! binary table format of `src/brdf` is used here): per wavelength the
//! Fourier coefficients `f^m(μ_o, μ_i) = ρ^m(μ_o, μ_i)/μ_i` (1/sr) of the
//! Mueller BRDF on [`DEFAULT_THETA_DEG`] (conventions §7; `ρ^m` from
//! [`solver::ReflectionFourier::rho`]), flattened as
//! `f[(((m·N + o)·N + i)·ns + p)·ns + q]`, and for a mirror base the
//! specular matrix `e^{−2τ/μ_i} M_F(μ_i)` per incident node (conventions §6).
//! The bytes are a deterministic function of the spec (no timings), so a
//! re-solve reproduces the same digest.
//!
//! Not included: the exact single-scattering correction that
//! [`solver::ReflectionFourier::brdf`] adds after a delta-M truncation (a
//! no-op when the phase-function series fits the quadrature, as for
//! Rayleigh).

use crate::solver::{self, Base, accuracy};
use crate::spec::{self, Spec, StreamPolicy};
use serde_json::{Value, json};
use std::time::Instant;

/// Media type of the stored bytes.
pub const MEDIA_TYPE: &str = "application/vnd.polbrdf.fourier+json";

/// Name and version of the stored format.
pub const FORMAT: &str = "polbrdf-fourier-json/1";

/// Polar angles of the nodes (degrees), incident and outgoing: every 6°.
pub const DEFAULT_THETA_DEG: [f64; 16] = [
    0.0, 6.0, 12.0, 18.0, 24.0, 30.0, 36.0, 42.0, 48.0, 54.0, 60.0, 66.0, 72.0, 78.0, 84.0, 90.0,
];

/// Smallest cosine evaluated (conventions §5, "Directions at the horizon").
pub const MU_FLOOR: f64 = 1e-6;

/// A finished solve.
#[derive(Clone, Debug)]
pub struct Solved {
    /// The result bytes.
    pub bytes: Vec<u8>,
    /// Their media type.
    pub media_type: &'static str,
    /// Wall time per wavelength (ms).
    pub wall_time_ms: Vec<f64>,
    /// Largest estimated relative error of f11 over the wavelengths
    /// (`solver::accuracy`), when available.
    pub error_estimate: Option<f64>,
}

/// Why a solve failed: the spec cannot be solved at some wavelength, or the
/// solver rejected the problem. Deterministic, so final.
#[derive(Clone, Debug, PartialEq)]
pub struct SolveFailure {
    /// `spec` or `solver`.
    pub kind: &'static str,
    /// JSON path in the spec, when known.
    pub path: Option<String>,
    /// What went wrong.
    pub message: String,
    /// The wavelength (nm) being solved.
    pub wavelength_nm: Option<f64>,
}

/// Solve every wavelength of a spec; a `solver.tolerance` may pick at most
/// `max_streams` streams; `on_wavelength(done, total, ms)` is called after
/// each wavelength.
pub fn solve(
    spec: &Spec,
    max_streams: usize,
    on_wavelength: &mut dyn FnMut(usize, usize, f64),
) -> Result<Solved, SolveFailure> {
    let theta = DEFAULT_THETA_DEG;
    let mu: Vec<f64> = theta
        .iter()
        .map(|t| t.to_radians().cos().clamp(MU_FLOOR, 1.0))
        .collect();
    let n = mu.len();
    let wavelengths = spec::wavelengths(spec);
    let total = wavelengths.len();
    let mut blocks = Vec::with_capacity(total);
    let mut wall = Vec::with_capacity(total);
    let mut estimate: Option<f64> = None;
    for (k, wl) in wavelengths.into_iter().enumerate() {
        let t0 = Instant::now();
        let problem = spec::problem(spec, wl).map_err(|e| SolveFailure {
            kind: "spec",
            path: Some(e.path.clone()),
            message: e.message.clone(),
            wavelength_nm: wl,
        })?;
        let solver_failure = |e: solver::SolverError| SolveFailure {
            kind: "solver",
            path: None,
            message: e.to_string(),
            wavelength_nm: wl,
        };
        let solved = match spec::stream_policy(spec) {
            StreamPolicy::Fixed(_) => accuracy::reflection_with_estimate(&problem, &mu),
            StreamPolicy::Tolerance(t) => {
                accuracy::reflection_to_tolerance(&problem, &mu, t, max_streams)
            }
        }
        .map_err(solver_failure)?;
        let e = solved.estimate.max_err_f11;
        if e.is_finite() {
            estimate = Some(estimate.map_or(e, |x: f64| x.max(e)));
        }
        let refl = solved.reflection;
        let ns = refl.ns;
        let orders = refl.rho.len();
        let mut f = vec![0.0; orders * n * n * ns * ns];
        for (m, rho) in refl.rho.iter().enumerate() {
            for o in 0..n {
                for i in 0..n {
                    let base = ((m * n + o) * n + i) * ns * ns;
                    for p in 0..ns {
                        for q in 0..ns {
                            f[base + p * ns + q] = rho[(o * ns + p, i * ns + q)] / mu[i];
                        }
                    }
                }
            }
        }
        if f.iter().any(|x| !x.is_finite()) {
            return Err(solver_failure(solver::SolverError::NonFinite(
                "BRDF coefficients".into(),
            )));
        }
        let specular = match &problem.base {
            Base::Mirror { mueller } => Value::from(
                mu.iter()
                    .zip(&refl.direct)
                    .map(|(&m, &d)| {
                        let s = mueller(m).map(|row| row.map(|x| x * d * d));
                        json!(s)
                    })
                    .collect::<Vec<_>>(),
            ),
            _ => Value::Null,
        };
        blocks.push(json!({
            "wavelength_nm": wl,
            "ns": ns,
            "orders": orders,
            "streams": solved.estimate.streams[2],
            "f": f,
            "specular": specular,
        }));
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        wall.push(ms);
        on_wavelength(k + 1, total, ms);
    }
    let doc = json!({
        "format": FORMAT,
        "quantity": "f^m(mu_o, mu_i) = rho^m(mu_o, mu_i) / mu_i in 1/sr (docs/conventions.md §7): \
                     f(mu_o, mu_i, dphi) = sum_m (2 - delta_m0)/(2 pi) [bd(f^m) cos m dphi + od(f^m) sin m dphi], \
                     dphi = phi_o - phi_i - 180 deg",
        "layout": "f[(((m*N + o)*N + i)*ns + p)*ns + q], o outgoing node, i incident node, p outgoing Stokes, q incident Stokes",
        "theta_deg": theta,
        "mu": mu,
        "wavelengths": blocks,
    });
    Ok(Solved {
        bytes: serde_json::to_vec(&doc).expect("finite JSON"),
        media_type: MEDIA_TYPE,
        wall_time_ms: wall,
        error_estimate: estimate,
    })
}
