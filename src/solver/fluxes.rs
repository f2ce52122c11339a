//! The energy budget of the discrete-ordinate solution on its own streams.

use super::layer::{add, add_mirror};
use super::*;
use faer::Mat;

/// Energy budget of the discrete-ordinate solution for collimated beams,
/// measured on the quadrature streams (order 0, I component): the fluxes the
/// discrete system conserves exactly. See [`stream_fluxes`].
#[derive(Clone, Debug)]
pub struct StreamFluxes {
    /// Incident cosines.
    pub mu0: Vec<f64>,
    /// Plane albedo `A(μ0) = Σ_i w_i μ_i ρ⁰(μ_i, μ0) / μ0`: the flux leaving
    /// the top per unit incident flux, diffuse (on the quadrature) plus, over
    /// a mirror base, the specular beam `e^{−2τ/μ0} M_F,11(μ0)`.
    pub reflected: Vec<f64>,
    /// Flux leaving the bottom of the stack per unit incident flux, direct
    /// `e^{−τ/μ0}` plus diffuse on the quadrature, when the base is black
    /// (`0` under a semi-infinite layer); `None` over other bases.
    pub transmitted: Option<Vec<f64>>,
    /// The specular part of `reflected` (mirror base; else 0), with the
    /// depths of the (truncated) problem the fluxes refer to.
    pub specular: Vec<f64>,
}

/// [`StreamFluxes`] of a problem for beams along `mu0`.
///
/// The fluxes are sums over the double-Gauss streams, `Σ_i w_i μ_i I(μ_i)`,
/// of the quadrature radiances: for `ω = 1` over a black base the discrete
/// system conserves them exactly, `A + T = 1`, whatever the number of streams
/// (the quadrature integrates the order-0 phase function exactly, so every
/// scattering and every adding step conserves `Σ w μ I`; Wiscombe 1976 for
/// the start layer); likewise `A = 1` for a white Lambertian base or a
/// semi-infinite conservative layer. The plane albedo integrated over user
/// directions instead carries in addition the error of the Gauss rule on
/// the reflected radiance (`tests/stiff_cases.rs`, energy test). With delta-M
/// truncation the fluxes are those of the truncated problem (scaled depths
/// and albedo; the truncated forward peak travels with the direct beam).
pub fn stream_fluxes(problem: &Problem, mu0: &[f64]) -> Result<StreamFluxes, SolverError> {
    validate(problem, mu0)?;
    if problem.top_interface.is_some() {
        return Err(SolverError::Invalid(
            "stream fluxes under a top interface is not supported yet".into(),
        ));
    }
    let truncated = truncate(problem)?;
    let problem = truncated.as_ref().map_or(problem, |t| &t.problem);
    let s = &problem.settings;
    let ns = if s.polarized { 4 } else { 1 };
    let grid = Grid::new(s, mu0);
    let (semi_infinite, full) = base_coupling(problem);
    let stack = stack_ops(problem, &grid, 0, full);
    let tau: f64 = problem.layers.iter().map(|l| l.thickness.value()).sum();
    // Σ_i w_i μ_i X[(i, I), (v, I)] / μ_v for each beam v.
    let flux = |x: &Mat<f64>| -> Vec<f64> {
        (0..mu0.len())
            .map(|v| {
                let sum: f64 = (0..grid.mu_q.len())
                    .map(|i| grid.w_q[i] * grid.mu_q[i] * x[(i * ns, v * ns)])
                    .sum();
                sum / mu0[v]
            })
            .collect()
    };
    let mut specular = vec![0.0; mu0.len()];
    let (reflected, transmitted) = match (&problem.base, semi_infinite) {
        (_, true) => (flux(&stack.rb), Some(vec![0.0; mu0.len()])),
        (Base::Black, false) => {
            let t = flux(&stack.tb)
                .into_iter()
                .zip(mu0)
                .map(|(d, &m)| d + (-tau / m).exp())
                .collect();
            (flux(&stack.rb), Some(t))
        }
        (Base::Lambertian { albedo }, false) => (
            flux(&add(&stack, &lambertian_ops(&grid, *albedo, 0), false).rb),
            None,
        ),
        (Base::Rough { surface }, false) => {
            let base = super::rough_base::RoughProjection::new(surface, &grid, grid.split);
            (flux(&add(&stack, &base.ops(0), false).rb), None)
        }
        (Base::Mirror { mueller }, false) => {
            let mq = mirror_blocks(&grid.mu_q, ns, mueller.as_ref());
            let mu = mirror_blocks(&grid.mu_u, ns, mueller.as_ref());
            let diffuse = flux(&add_mirror(&stack, &mq, &mu).rb);
            for (s, &m) in specular.iter_mut().zip(mu0) {
                *s = (-2.0 * tau / m).exp() * mueller(m)[0][0];
            }
            let a = diffuse.iter().zip(&specular).map(|(d, s)| d + s).collect();
            (a, None)
        }
    };
    for x in reflected.iter().chain(transmitted.iter().flatten()) {
        if !x.is_finite() {
            return Err(SolverError::NonFinite("stream fluxes".into()));
        }
    }
    Ok(StreamFluxes {
        mu0: mu0.to_vec(),
        reflected,
        transmitted,
        specular,
    })
}
