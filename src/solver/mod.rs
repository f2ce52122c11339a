//! Vector radiative transfer by discrete ordinates (seed §3.5–3.6; Siewert
//! 2000; adding–doubling after Hansen & Travis 1974 and de Haan et al. 1987).
//!
//! Per Fourier azimuth order `m` the solver builds the phase-matrix kernel of
//! every homogeneous layer ([`phase`]), the layer's reflection/transmission
//! operators by a thin-layer start and doubling ([`layer`]), combines the
//! layers and the base by the adding equations, and keeps the response of the
//! whole stack in user directions to beams in user directions. The BRDF at
//! any azimuth is then the Fourier sum (conventions §6).
//!
//! Pure: no I/O, deterministic. Parallel over Fourier orders (rayon) with
//! faer sequential underneath.
//!
//! Files: the problem and its errors (`problem`), what is refused before
//! solving (`validate`), the per-order setup of kernels and operators
//! (`orders`), the main loop over orders (here), the result and its BRDF
//! (`result`), the streams' energy budget (`fluxes`), the internal field
//! (`field`); the operators themselves (`layer`), phase kernels (`phase`),
//! delta-M and the single-scattering correction (`truncation`), the
//! secondary correction (`secondary`), their shared depth integrals
//! (`depth`), and the error estimate (`accuracy`).

pub mod accuracy;
mod azimuth;
mod depth;
mod field;
mod fluxes;
pub mod interface;
#[cfg(test)]
mod interface_tests;
#[cfg(test)]
mod law_tests;
pub mod layer;
mod orders;
pub mod phase;
mod problem;
mod result;
mod rough_base;
#[cfg(test)]
mod rough_base_tests;
mod rough_interface;
#[cfg(test)]
mod rough_interface_tests;
pub mod secondary;
#[cfg(test)]
mod symmetry_tests;
pub mod truncation;
mod validate;

pub use field::{FieldFourier, internal_field};
pub use fluxes::{StreamFluxes, stream_fluxes};
use orders::*;
pub use orders::{discrete_ordinates, interface_split, quadrature_split};
pub use problem::{Base, Layer, Problem, Settings, SolverError, Thickness, TopInterface};
pub use result::{REALIZABILITY_TOL, ReflectionFourier, fourier_sum, make_realizable};
pub use rough_interface::MIN_INDEX as ROUGH_INTERFACE_MIN_INDEX;
use validate::validate;
pub use validate::{UNRESOLVED_TOLERANCE, check_resolved};

use faer::Mat;
use layer::{TopResponse, add, add_mirror};
use rayon::prelude::*;

/// The delta-M truncated problem when the settings ask for it.
fn truncate(problem: &Problem) -> Result<Option<truncation::Truncated>, SolverError> {
    if problem.settings.delta_m {
        truncation::delta_m(problem).map(Some)
    } else {
        Ok(None)
    }
}

/// Progress of one solve: called on the solving thread after each batch of
/// Fourier orders with `(orders done, upper bound on the orders)`. The bound
/// is the expansion length; the Fourier series usually converges (and the
/// solve ends) before it, so the ratio is a lower bound on the fraction done.
pub type OnOrders<'a> = &'a (dyn Fn(usize, usize) + Sync);

/// Reflection of the stack for beams and observers along the user cosines
/// `mu_user` (each in `(0, 1]`), all Fourier orders.
pub fn reflection(problem: &Problem, mu_user: &[f64]) -> Result<ReflectionFourier, SolverError> {
    reflection_observed(problem, mu_user, &|_, _| {})
}

/// [`reflection`], reporting progress per batch of Fourier orders to
/// `on_orders` (the caller decides what to do with it; the solver does no
/// I/O).
///
/// Under a [`Problem::top_interface`] the user cosines are those in air;
/// [`ReflectionFourier::interface`] then holds the interface's maps and its
/// delta term.
pub fn reflection_observed(
    problem: &Problem,
    mu_user: &[f64],
    on_orders: OnOrders,
) -> Result<ReflectionFourier, SolverError> {
    validate(problem, mu_user)?;
    let original = problem;
    let truncated = truncate(problem)?;
    let problem = truncated.as_ref().map_or(problem, |t| &t.problem);
    let s = &problem.settings;
    let ns = if s.polarized { 4 } else { 1 };
    // Under a top interface the layers see the user directions refracted
    // into the binder (`interface`); the response is mapped back to air.
    let tau_total: f64 = original.layers.iter().map(|l| l.thickness.value()).sum();
    let mut maps = match &problem.top_interface {
        Some(i) if i.alpha.is_none() => Some(interface::InterfaceMaps::new(i.index, mu_user)?),
        _ => None,
    };
    // Over a mirror base the beam bounces between base and interface: the
    // delta term's part through the interface (with the true direct
    // transmittance) and the gains of the beam and of the radiance along
    // the user directions (with the solved problem's, delta-M scaled: its
    // forward peak travels with the beam).
    let mut gain = None;
    if let (Some(m), Base::Mirror { mueller }) = (maps.as_mut(), &problem.base) {
        m.set_mirror_base(tau_total, mueller.as_ref())?;
        let tau_solved: f64 = problem.layers.iter().map(|l| l.thickness.value()).sum();
        gain = Some(interface::mirror_gains(
            m.index,
            &m.mu_internal,
            tau_solved,
            mueller.as_ref(),
            ns,
        )?);
    }
    let grid = Grid::split(
        s,
        maps.as_ref().map_or(mu_user, |m| &m.mu_internal),
        quadrature_split(problem),
    );
    let rq = match &problem.top_interface {
        Some(i) if i.alpha.is_none() => {
            Some(interface::internal_reflection(i.index, &grid.mu_q, ns)?)
        }
        _ => None,
    };
    let (semi_infinite, full) = base_coupling(problem);
    let rough = match &problem.base {
        Base::Rough { surface } if !semi_infinite => {
            Some(rough_base::RoughProjection::new(surface, &grid, grid.split))
        }
        _ => None,
    };
    // The orders the stack (base included) reflects into; beyond them its
    // `r^m` is zero.
    let orders = capped_orders(
        problem,
        layer_orders(problem).max(rough.as_ref().map_or(0, |r| r.order_count())),
    );
    // A rough interface: user cosines in air, quadrature in the binder; what
    // comes through it has the stack's orders, its own reflection is
    // evaluated in closed form (`rough_interface`).
    let rough_top = match &problem.top_interface {
        Some(TopInterface {
            index,
            alpha: Some(alpha),
        }) => Some(rough_interface::RoughInterface::new(
            *index, *alpha, &grid, grid.split, orders,
        )?),
        _ => None,
    };
    let one_order = |m: usize| -> Mat<f64> {
        let stack = stack_ops(problem, &grid, m, full);
        let top = match &problem.base {
            _ if semi_infinite => TopResponse::of(stack),
            Base::Black => TopResponse::of(stack),
            Base::Lambertian { albedo } => {
                TopResponse::of(add(&stack, &lambertian_ops(&grid, *albedo, m), false))
            }
            Base::Mirror { mueller } => {
                let mq = mirror_blocks(&grid.mu_q, ns, mueller.as_ref());
                let mu = mirror_blocks(&grid.mu_u, ns, mueller.as_ref());
                add_mirror(&stack, &mq, &mu)
            }
            Base::Rough { .. } => {
                let base = rough.as_ref().expect("projected above").ops(m);
                TopResponse::of(add(&stack, &base, false))
            }
        };
        if let Some(rough_top) = &rough_top {
            return rough_top.over(m, &top.r);
        }
        match (&maps, &rq) {
            (Some(maps), Some(rq)) => {
                let mut l = interface::under_interface(&top, rq);
                if let Some(g) = &gain {
                    interface::apply_mirror_gains(&mut l, g, ns);
                }
                maps.to_external(&l, ns)
            }
            _ => top.ruu,
        }
    };
    let mut rho = fourier_orders(
        orders,
        s.fourier_tolerance,
        ns,
        mu_user,
        one_order,
        on_orders,
    )?;
    // The secondary-scattering correction of truncated layers is a Fourier
    // series at the user cosines (inside the binder under an interface):
    // added to the solve's coefficients (all orders of the full series), so
    // that tables carry it too.
    let correction = truncated.and_then(|t| t.correction);
    if let Some(c) = correction
        .as_ref()
        .filter(|_| original.settings.secondary_scattering)
    {
        for (m, x) in c
            .secondary(&grid.mu_u, original.settings.max_order)
            .into_iter()
            .enumerate()
        {
            let x = match &maps {
                Some(maps) => maps.to_external(&x, ns),
                None => x,
            };
            match rho.get_mut(m) {
                Some(r) => *r += &x,
                None => rho.push(x),
            }
        }
    }
    Ok(ReflectionFourier {
        ns,
        mu: mu_user.to_vec(),
        rho,
        direct: grid.mu_u.iter().map(|m| (-tau_total / m).exp()).collect(),
        correction,
        interface: maps,
        surface: rough_top.map(|t| t.surface()),
    })
}

/// The Fourier orders `0..orders` of a user-by-beam response, computed in
/// parallel batches by `one_order`; stops once two consecutive orders add
/// less than `fourier_tolerance` of the largest coefficient of order 0
/// (each column scaled by `1/μ0` of its beam, `mu_beam`, as in the BRDF).
fn fourier_orders(
    orders: usize,
    fourier_tolerance: f64,
    ns: usize,
    mu_beam: &[f64],
    one_order: impl Fn(usize) -> Mat<f64> + Sync + Send,
    on_orders: OnOrders,
) -> Result<Vec<Mat<f64>>, SolverError> {
    let batch = rayon::current_num_threads().max(1);
    let scaled_max = |r: &Mat<f64>| -> f64 {
        let mut v: f64 = 0.0;
        for j in 0..r.ncols() {
            let inv = 1.0 / mu_beam[j / ns];
            for i in 0..r.nrows() {
                let x = r[(i, j)];
                if !x.is_finite() {
                    return f64::NAN;
                }
                v = v.max(x.abs() * inv);
            }
        }
        v
    };
    let mut rho: Vec<Mat<f64>> = Vec::new();
    let mut reference = 0.0;
    let mut small_run = 0;
    'orders: while rho.len() < orders {
        let lo = rho.len();
        let hi = (lo + batch).min(orders);
        let part: Vec<Mat<f64>> = (lo..hi).into_par_iter().map(&one_order).collect();
        for (k, r) in part.into_iter().enumerate() {
            let size = scaled_max(&r);
            if !size.is_finite() {
                return Err(SolverError::NonFinite(format!("Fourier order {}", lo + k)));
            }
            if lo + k == 0 {
                reference = size;
            }
            rho.push(r);
            small_run = if size <= fourier_tolerance * reference {
                small_run + 1
            } else {
                0
            };
            if small_run >= 2 {
                break 'orders;
            }
        }
        on_orders(rho.len(), orders);
    }
    on_orders(orders, orders);
    Ok(rho)
}
