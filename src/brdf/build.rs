//! Building a table: one solve per wavelength at the grid's cosines (and
//! a coarse grid's probe angles), the kept part of `f^m = ρ^m / μ_i` (T0 of
//! docs/table-format.md; `brdf::coverage` for what a request keeps), the
//! specular matrices of a mirror base and the measured interpolation error.

use super::BrdfError;
use super::angles::mu_of_theta_deg;
use super::coverage;
use super::grid::PolarGrid;
use super::table::{EstimateMeta, StoredCorrection, WavelengthTable, scale};
use crate::material::{self, Spec};
use crate::plan::{self, Plan};
use crate::solver::{self, Base};
use std::f64::consts::PI;
use std::time::Instant;

/// Solve the spec once per wavelength at the grid cosines
/// ([`solver::reflection`] with `mu_user` = the grid's `μ`; for a spec with
/// `solver.tolerance` and no `solver.streams`,
/// `solver::accuracy::reflection_to_tolerance`, as `polbrdf solve` does) and
/// keep `f^m = ρ^m/μ_i` (T0) and, for a mirror base, `e^{−2τ/μ} M_F(μ)` per
/// node.
pub fn build(spec: &Spec, grid: &PolarGrid) -> Result<Vec<WavelengthTable>, BrdfError> {
    let plan = Plan::lower(spec)?;
    (0..plan.wavelengths.len())
        .map(|k| build_wavelength(&plan, k, grid, &BuildOptions::default()).map(|b| b.block))
        .collect()
}

/// The polar grid a plan's table is built on: the default 64 nodes, or
/// `needs.grid.polar_nodes` (validated: at least 6).
pub fn plan_grid(plan: &Plan) -> PolarGrid {
    plan_nodes_grid(plan.needs.polar_nodes())
}

/// The graded grid of `n` polar nodes a request's `needs.grid.polar_nodes`
/// names (validated: at least 6).
pub fn plan_nodes_grid(n: usize) -> PolarGrid {
    PolarGrid::graded(n).expect("validated polar_nodes")
}

/// How [`Table::from_spec_with`] builds a table.
pub struct BuildOptions<'a> {
    /// Most streams a `solver.tolerance` may pick (explicit
    /// `solver.streams` are the spec's own business).
    pub max_streams: usize,
    /// Progress: `(wavelength index, total wavelengths, fraction of that
    /// wavelength done)`, called on the solving thread after each batch of
    /// Fourier orders (approximate; see [`solver::OnOrders`]).
    pub on_progress: &'a (dyn Fn(usize, usize, f64) + Sync),
}

impl Default for BuildOptions<'_> {
    fn default() -> Self {
        Self {
            max_streams: material::MAX_STREAMS,
            on_progress: &|_, _, _| {},
        }
    }
}

/// One wavelength of a table, solved: the block, the streams used and the
/// solver's error estimate.
pub struct BuiltWavelength {
    /// The stored coefficients.
    pub block: WavelengthTable,
    /// Streams of the solve (the policy's fixed count, or what a tolerance
    /// picked).
    pub streams: usize,
    /// The solver's a-posteriori estimate (`None` with
    /// `needs.error_estimate: false`).
    pub error_estimate: Option<EstimateMeta>,
    /// Measured interpolation error of a grid other than the default
    /// ([`interpolation_error`]); `None` on the default grid.
    pub interpolation_error: Option<f64>,
}

/// Solve wavelength `k` of a plan at the grid cosines (see [`build`]).
/// `options.on_progress` gets `(k, plan wavelengths, fraction)`.
pub fn build_wavelength(
    plan: &Plan,
    k: usize,
    grid: &PolarGrid,
    options: &BuildOptions,
) -> Result<BuiltWavelength, BrdfError> {
    let total = plan.wavelengths.len();
    let lowered = &plan.wavelengths[k];
    let (wl, problem) = (lowered.wavelength_nm, &lowered.problem);
    let t0 = Instant::now();
    let progress = |x: f64| (options.on_progress)(k, total, x);
    // A grid other than the default (`needs.grid.polar_nodes`) is also
    // solved at probe angles between its nodes (`PolarGrid::probe_theta_deg`),
    // where its interpolation error is measured (`interpolation_error`);
    // the table stores the nodes only. That is 2n + 6 user directions:
    // fewer than the default grid's 64 for n ≤ 28 nodes.
    let probes = if grid.len() != crate::brdf::grid::DEFAULT_NODES {
        grid.probe_theta_deg()
    } else {
        Vec::new()
    };
    let mut mu_user = grid.mu.clone();
    mu_user.extend(probes.iter().map(|&t| mu_of_theta_deg(t)));
    let estimate_meta = |e: solver::accuracy::ErrorEstimate| EstimateMeta {
        max_err_f11: e.max_err_f11,
        streams: e.streams,
        contraction: e.contraction,
    };
    let (mut refl, streams, error_estimate) = match plan.policy {
        // `needs.error_estimate: false`: one solve instead of three.
        plan::StreamPolicy::Fixed(_) if !plan.needs.error_estimate => {
            let r = solver::reflection_observed(problem, &mu_user, &|done, bound| {
                progress(done as f64 / bound.max(1) as f64)
            })?;
            (r, problem.settings.streams, None)
        }
        plan::StreamPolicy::Fixed(_) => {
            let e =
                solver::accuracy::reflection_with_estimate_observed(problem, &mu_user, &progress)?;
            (
                e.reflection,
                problem.settings.streams,
                Some(estimate_meta(e.estimate)),
            )
        }
        plan::StreamPolicy::Tolerance(t) => {
            let e = solver::accuracy::reflection_to_tolerance(
                problem,
                &mu_user,
                t,
                options.max_streams,
                &progress,
            )?;
            (
                e.reflection,
                e.estimate.streams[2],
                Some(estimate_meta(e.estimate)),
            )
        }
    };
    // Only the elements and incident nodes the request needs
    // (`needs.stokes`, `needs.theta_i_deg`) are synthesized and stored.
    let (rows, cols) = plan.needs.stokes.shape(refl.ns);
    let incident = coverage::incident_nodes(grid, plan.needs.theta_i_deg.as_ref());
    let n = grid.len();
    let orders = refl.rho.len();
    let f = coverage::synthesize(&refl, grid, rows, cols, &incident);
    let specular = match &problem.base {
        // A smooth top interface reflects the beam before it enters (a
        // mirror base beneath it is refused by the solver).
        _ if refl.interface.is_some() => Some(
            incident
                .iter()
                .map(|&i| {
                    let s = refl.interface_specular(i).expect("an interface");
                    coverage::keep(&s, rows, cols)
                })
                .collect(),
        ),
        Base::Mirror { mueller } => Some(
            incident
                .iter()
                .map(|&i| {
                    let e = refl.direct[i];
                    coverage::keep(&scale(&mueller(grid.mu[i]), e * e), rows, cols)
                })
                .collect(),
        ),
        _ => None,
    };
    let correction = match refl.correction.take() {
        Some(correction) => Some(StoredCorrection {
            mirror_indices: match correction.mirror {
                Some(_) => lowered.mirror_indices,
                None => None,
            },
            correction,
            interface_index: problem.top_interface.map(|i| i.index),
        }),
        None => None,
    };
    let block = WavelengthTable {
        wavelength_nm: wl,
        ns: rows,
        cols,
        nodes: n,
        incident,
        orders,
        f,
        specular,
        wall_time_ms: t0.elapsed().as_secs_f64() * 1e3,
        correction,
        surface: refl.surface,
    };
    // Measured on f11 alone, from an f11 block on every incident node (the
    // statement covers the grid, whatever part of it is stored).
    let interpolation_error = (!probes.is_empty()).then(|| {
        let f11 = WavelengthTable {
            ns: 1,
            cols: 1,
            incident: (0..n).collect(),
            f: coverage::synthesize(&refl, grid, 1, 1, &(0..n).collect::<Vec<_>>()),
            specular: None,
            correction: None,
            ..block.clone_shape()
        };
        let theta: Vec<f64> = grid.theta_deg.iter().chain(&probes).copied().collect();
        let ns = refl.ns;
        let solved = |m: usize, a: usize, b: usize| refl.rho[m][(a * ns, b * ns)] / refl.mu[b];
        interpolation_error(&f11, grid, &theta, orders, &solved)
    });
    Ok(BuiltWavelength {
        block,
        streams,
        error_estimate,
        interpolation_error,
    })
}

/// Measured interpolation error of a table block (T2): the largest
/// `Σ_m w_m |f^m_11(interpolated) − f^m_11(reference)|`, `w_m = (2 − δ_m0)/(2π)`
/// (a bound on the error of f11 at every azimuth, (T1)), over every pair of
/// directions with at least one at a probe angle, relative to the largest
/// f11 at `Δφ = 0` and `π` over all pairs. `theta` lists the grid's nodes
/// then the probe angles ([`PolarGrid::probe_theta_deg`]); `reference(m, a,
/// b)` is `f^m_11` at outgoing `theta[a]` and incident `theta[b]`: the
/// solver's, solved in the same solve after the nodes, or a finer cached
/// table's (`brdf::cover`). The single-scattering correction (T3) is exact
/// at any direction and not part of it.
pub(super) fn interpolation_error(
    block: &WavelengthTable,
    grid: &PolarGrid,
    theta: &[f64],
    orders: usize,
    reference: &dyn Fn(usize, usize, usize) -> f64,
) -> f64 {
    let n = grid.len();
    let orders = block.orders.min(orders);
    let weight = |m: usize| if m == 0 { 1.0 } else { 2.0 } / (2.0 * PI);
    let mut f11_max: f64 = 0.0;
    for a in 0..theta.len() {
        for b in 0..theta.len() {
            let (mut at0, mut at_pi) = (0.0, 0.0);
            for m in 0..orders {
                let v = weight(m) * reference(m, a, b);
                at0 += v;
                at_pi += if m % 2 == 0 { v } else { -v };
            }
            f11_max = f11_max.max(at0.abs()).max(at_pi.abs());
        }
    }
    let mut err: f64 = 0.0;
    for a in 0..theta.len() {
        for b in 0..theta.len() {
            if a < n && b < n {
                continue;
            }
            let c = block.coefficients(grid, theta[a], theta[b]);
            let e: f64 = (0..orders)
                .map(|m| weight(m) * (c[m][0][0] - reference(m, a, b)).abs())
                .sum();
            err = err.max(e);
        }
    }
    if f11_max > 0.0 { err / f11_max } else { 0.0 }
}
