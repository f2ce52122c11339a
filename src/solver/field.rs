//! The diffuse radiance field inside the stack.

use super::layer::{Ops, add};
use super::*;
use faer::Mat;

/// Diffuse radiance field inside the stack at given optical depths for beams
/// along the user directions, as Fourier coefficients: `up[k][m]` and
/// `down[k][m]` are `nu × nu` (rows: user direction travelling up / down at
/// depth `depths[k]`, columns: beam direction at the top).
#[derive(Clone, Debug)]
pub struct FieldFourier {
    /// Stokes components per direction.
    pub ns: usize,
    /// User cosines.
    pub mu: Vec<f64>,
    /// Depths (optical depth from the top).
    pub depths: Vec<f64>,
    /// Upward radiance per depth and order.
    pub up: Vec<Vec<Mat<f64>>>,
    /// Downward radiance per depth and order.
    pub down: Vec<Vec<Mat<f64>>>,
    /// Upward radiance (Stokes vector per user direction, length `nu`) at
    /// each depth for unpolarized isotropic illumination of unit radiance on
    /// the top (azimuth-independent: order 0 only).
    pub iso_up: Vec<Vec<f64>>,
    /// Downward radiance for the same illumination, including its
    /// unscattered part `e^{−τ/μ}` along the user directions.
    pub iso_down: Vec<Vec<f64>>,
}

/// Operators of the layers between optical depths `from` and `to` (from the
/// top), in order `m`; `to = ∞` runs to the bottom of the stack.
pub(super) fn slab_ops(grid: &Grid, problem: &Problem, m: usize, from: f64, to: f64) -> Ops {
    let ns = grid.ns;
    let n = grid.mu_q.len() * ns;
    let nu = grid.mu_u.len() * ns;
    let mut stack: Option<Ops> = None;
    let mut top = 0.0;
    for layer in &problem.layers {
        let (bottom, infinite) = match layer.thickness {
            Thickness::Finite(t) => (top + t, false),
            Thickness::Infinite => (f64::INFINITY, true),
        };
        let lo = top.max(from);
        let hi = bottom.min(to);
        if hi > lo {
            let part = if infinite && hi.is_infinite() {
                Layer {
                    thickness: Thickness::Infinite,
                    ..layer.clone()
                }
            } else {
                Layer {
                    thickness: Thickness::Finite(hi - lo),
                    ..layer.clone()
                }
            };
            let ops = layer_ops(grid, &part, m, &problem.settings, true);
            stack = Some(match stack {
                None => ops,
                Some(s) => add(&s, &ops, true),
            });
        }
        top = bottom;
    }
    stack.unwrap_or_else(|| Ops::vacuum(n, nu, ns))
}

/// The internal diffuse field (seed §4.1 validation; Siewert 2000 tables) at
/// optical depths `depths` for beams and observers along `mu_user`.
/// Mirror bases are not supported here.
pub fn internal_field(
    problem: &Problem,
    mu_user: &[f64],
    depths: &[f64],
) -> Result<FieldFourier, SolverError> {
    validate(problem, mu_user)?;
    if problem.top_interface.is_some() {
        return Err(SolverError::Invalid(
            "the internal field under a top interface is not supported yet".into(),
        ));
    }
    if matches!(problem.base, Base::Mirror { .. } | Base::Rough { .. }) {
        return Err(SolverError::Invalid(
            "the internal field is not available over a mirror or rough base".into(),
        ));
    }
    let s = &problem.settings;
    let ns = if s.polarized { 4 } else { 1 };
    let grid = Grid::new(s, mu_user);
    let orders = order_count(problem);
    let per_order: Vec<Vec<(Mat<f64>, Mat<f64>)>> = (0..orders)
        .into_par_iter()
        .map(|m| {
            depths
                .iter()
                .map(|&tau| {
                    let a = slab_ops(&grid, problem, m, 0.0, tau);
                    let mut b = slab_ops(&grid, problem, m, tau, f64::INFINITY);
                    if let Base::Lambertian { albedo } = problem.base {
                        b = add(&b, &lambertian_ops(&grid, albedo, m), true);
                    }
                    interface_field(&a, &b)
                })
                .collect()
        })
        .collect();
    let mut up = vec![Vec::with_capacity(orders); depths.len()];
    let mut down = vec![Vec::with_capacity(orders); depths.len()];
    let mut iso_up = vec![Vec::new(); depths.len()];
    let mut iso_down = vec![Vec::new(); depths.len()];
    let nu = grid.mu_u.len() * ns;
    for (m, order) in per_order.into_iter().enumerate() {
        for (k, (u, d)) in order.into_iter().enumerate() {
            if !layer::max_abs(u.as_ref()).is_finite() || !layer::max_abs(d.as_ref()).is_finite() {
                return Err(SolverError::NonFinite(format!(
                    "field at depth {}",
                    depths[k]
                )));
            }
            if m == 0 {
                iso_up[k] = (0..nu).map(|i| u[(i, nu)]).collect();
                iso_down[k] = (0..nu).map(|i| d[(i, nu)]).collect();
            }
            up[k].push(u.as_ref().submatrix(0, 0, nu, nu).to_owned());
            down[k].push(d.as_ref().submatrix(0, 0, nu, nu).to_owned());
        }
    }
    Ok(FieldFourier {
        ns,
        mu: grid.mu_u,
        depths: depths.to_vec(),
        up,
        down,
        iso_up,
        iso_down,
    })
}

/// Diffuse user radiance at the interface between `a` (above) and `b`
/// (below, base included) for a beam entering the top of `a`:
/// `D = G (Tb_a + R*_a Rb_b E_a)`, `U = R_b D + Rb_b E_a`; upward user radiance
/// is `Ru_b D + Ruu_b E_a`, downward `Tuu_a + Ru*_a U`.
///
/// The last column of both results is the response to unpolarized isotropic
/// illumination of unit radiance on the top in quadrature directions
/// (`x = 1` on every I component), meaningful for order 0 only; its downward
/// part includes the unscattered illumination along the user directions.
pub(super) fn interface_field(a: &Ops, b: &Ops) -> (Mat<f64>, Mat<f64>) {
    use faer::prelude::*;
    let n = a.n;
    let ns = a.ns;
    let nu = a.nu;
    let mut x = Mat::<f64>::zeros(n, 1);
    for i in (0..n).step_by(ns) {
        x[(i, 0)] = 1.0;
    }
    let mut rbb_ea = b.rb.clone();
    for (v, &e) in a.eu.iter().enumerate() {
        for s in 0..ns {
            for i in 0..n {
                rbb_ea[(i, v * ns + s)] *= e;
            }
        }
    }
    let g = layer::identity_minus_product(a.rs.as_ref(), b.r.as_ref());
    let mut rhs = Mat::<f64>::zeros(n, nu + 1);
    let beam = &a.tb + layer::mm(a.rs.as_ref(), rbb_ea.as_ref());
    rhs.as_mut()
        .submatrix_mut(0, 0, n, nu)
        .copy_from(beam.as_ref());
    let tx = layer::mm(a.t.as_ref(), x.as_ref());
    rhs.as_mut()
        .submatrix_mut(0, nu, n, 1)
        .copy_from(tx.as_ref());
    let d = g.partial_piv_lu().solve(&rhs);
    let mut rbb_ea_x = Mat::<f64>::zeros(n, nu + 1);
    rbb_ea_x
        .as_mut()
        .submatrix_mut(0, 0, n, nu)
        .copy_from(rbb_ea.as_ref());
    let u = layer::mm(b.r.as_ref(), d.as_ref()) + &rbb_ea_x;
    let mut ruub_ea = b.ruu.clone();
    for (v, &e) in a.eu.iter().enumerate() {
        for s in 0..ns {
            for i in 0..ruub_ea.nrows() {
                ruub_ea[(i, v * ns + s)] *= e;
            }
        }
    }
    let mut up = layer::mm(b.ru.as_ref(), d.as_ref());
    let mut down = layer::mm(a.rus.as_ref(), u.as_ref());
    for j in 0..nu {
        for i in 0..nu {
            up[(i, j)] += ruub_ea[(i, j)];
            down[(i, j)] += a.tuu[(i, j)];
        }
    }
    let tux = layer::mm(a.tu.as_ref(), x.as_ref());
    for i in 0..nu {
        down[(i, nu)] += tux[(i, 0)];
        if i % ns == 0 {
            down[(i, nu)] += a.eu[i / ns];
        }
    }
    (up, down)
}
