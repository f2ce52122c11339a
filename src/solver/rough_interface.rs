//! A rough (GGX) binder/air interface on top of the stack
//! (docs/solver.md, "A rough top interface"): the layers lie in a binder of
//! real index `n` under air, and the surface between them is rough.
//!
//! Unlike the smooth interface ([`super::interface`]) nothing crosses it as
//! a beam: the incident beam is spread by the facets into a lobe of width
//! `~α` inside the binder, and what leaves comes from every internal
//! direction. Per Fourier order the interface has four operators, each
//! projected on the solver's grid exactly as a rough base is
//! ([`super::rough_base`]; the user cosines are those in air, the
//! quadrature is the binder's):
//!
//! - `R_t` (user ← beam): reflection from above,
//!   `RoughSurface { ambient: 1, index: n }` ([`RoughSurface::mueller`]);
//! - `T_d` (quadrature ← beam): transmission air → binder
//!   ([`RoughSurface::transmission`], downward);
//! - `T_u` (user ← quadrature): transmission binder → air (upward);
//! - `R_b` (quadrature ← quadrature): reflection from below, total internal
//!   reflection included. It is the reflection of `RoughSurface { ambient:
//!   n, index: 1 }` mirrored in `z`: the mirror maps each meridian frame
//!   `(e_ϑ, e_ϕ)` to `(−e_ϑ, e_ϕ)`, so `R_b(Δφ) = D R(Δφ) D = R(−Δφ)`,
//!   `D = diag(1, 1, −1, −1)`.
//!
//! With the stack's reflection `r` seen from inside the binder (quadrature
//! up ← quadrature down), the radiance going up under the interface is
//! `U = (I − r R_b)^{-1} r T_d` and the reflection in air is
//! `ρ = R_t + T_u U`: one linear solve per order, the cost of one more
//! layer plus the projection.
//!
//! **`R_t` in closed form.** The reflection from above is the surface's own
//! BRDF at the user directions: it is not projected, and not part of the
//! Fourier series. [`super::ReflectionFourier::brdf`] (and a table, at
//! every query direction) adds it exactly. At a grazing pair of user
//! directions its gloss lobe is a few milliradians wide in azimuth
//! (`~α(μ_o + μ_i)` about the forward direction): 2 048 orders and more,
//! where the rest of the response needs the stack's. Since order `m` of
//! `T_u U` is a product that holds the stack's `r^m`, it vanishes wherever
//! `r^m` does: the series of `T_d`, `T_u` and `R_b` are kept up to the
//! stack's orders only (`max_orders`), resolved in full, and those of
//! `R_b` also stop where `T_d`'s or `T_u`'s do (it only ever stands
//! between them; over a rough metal, ~200 orders instead of 2 048 where
//! its pairs cross a total-reflection edge).

use super::layer::{Ops, identity_minus_product, mm, refined_solve};
use super::orders::Grid;
use super::rough_base::{Kernels, Lobe, PANEL_NODES, Panels, RoughProjection, panel_width};
use crate::physics::RefractiveIndex;
use crate::physics::microfacet::RoughSurface;
use faer::Mat;

/// Least binder index of a rough interface: the transmitted lobe is about
/// `α(1 − 1/n)` wide in the binder ([`crossing_panel_width`]), and its
/// panels with it; below this a binder so close to air needs no interface.
pub const MIN_INDEX: f64 = 1.1;

/// Fine panels of the transmission kernels. A facet tilted by `θ_h` turns
/// a ray by about `θ_h (1 − 1/n)` in the binder (normal incidence: the
/// refracted lobe's half maximum is at 3.75° for `α = 0.3`, `n = 1.5`,
/// where the reflected lobe's is at ~22°), so the distribution's poles
/// (`tan θ_h = ±iα`) lie `~α(1 − 1/n)` from the real axis in the binder
/// angle, against `~2α` for a reflection: the panels are that much
/// narrower than [`panel_width`]. With reflection's width the 6-node rule
/// left 0.9e-6 1/sr at normal incidence (f11 = 0.12; TiO2 in binder 1.5,
/// `α = 0.3`, against 12 nodes), with this one 3e-9.
pub(super) fn crossing_panel_width(alpha: f64, index: f64) -> f64 {
    panel_width(alpha) * (1.0 - 1.0 / index)
}

/// The projected operators of a rough interface of binder index `index`
/// and roughness `alpha` (`R_t` in `ruu`, `T_d` in `rb`, `T_u` in `ru`,
/// `R_b` in `r` of each order's [`Ops`]).
pub(super) struct RoughInterface {
    projection: RoughProjection,
    /// The surface seen from air: `R_t` in closed form.
    above: RoughSurface,
}

impl RoughInterface {
    /// Project the interface on `grid` (binder quadrature split at
    /// `split`, user cosines in air), orders `m < max_orders` (those of
    /// the stack beneath).
    pub(super) fn new(
        index: f64,
        alpha: f64,
        grid: &Grid,
        split: Option<f64>,
        max_orders: usize,
    ) -> Result<Self, super::SolverError> {
        Self::with_nodes(index, alpha, grid, split, max_orders, PANEL_NODES)
    }

    /// [`RoughInterface::new`] with `nodes` Gauss nodes per fine panel.
    pub(super) fn with_nodes(
        index: f64,
        alpha: f64,
        grid: &Grid,
        split: Option<f64>,
        max_orders: usize,
        nodes: usize,
    ) -> Result<Self, super::SolverError> {
        let invalid = |e: crate::physics::PhysicsError| {
            super::SolverError::Invalid(format!("top_interface: {e}"))
        };
        if index.is_nan() || index < MIN_INDEX {
            return Err(super::SolverError::Invalid(format!(
                "top_interface: a rough interface needs a binder index of at least \
                 {MIN_INDEX} (got {index}): its transmitted lobe, about α(1 − 1/n) wide, \
                 becomes a delta as n → 1"
            )));
        }
        let binder = RefractiveIndex { n: index, k: 0.0 };
        let air = RefractiveIndex { n: 1.0, k: 0.0 };
        let above = RoughSurface::new(1.0, binder, alpha).map_err(invalid)?;
        let below = RoughSurface::new(index, air, alpha).map_err(invalid)?;
        let r_b = |mu_out: f64, mu_in: f64, d: f64| below.mueller(mu_out, mu_in, -d);
        let t_d = |mu_out: f64, mu_in: f64, d: f64| above.transmission(mu_out, mu_in, d, true);
        let t_u = |mu_out: f64, mu_in: f64, d: f64| above.transmission(mu_out, mu_in, d, false);
        // Where the kernels are not smooth in the binder cosine: the
        // transmission's jump and kinks at a given air cosine (the same
        // both ways), the reflection's total-reflection edges.
        let crossing = |mu_air: f64| above.transmission_edges(mu_air);
        let reflection = |mu: f64| below.reflection_edges(mu);
        // R_b(Δφ) = R(−Δφ): the edge is at the same |Δφ|.
        let edge = |mu_out: f64, mu_in: f64| below.reflection_azimuth_edge(mu_out, mu_in);
        let smooth = |f| Lobe {
            f,
            azimuth_edge: None,
        };
        let kernels = Kernels {
            r: Lobe {
                f: &r_b,
                azimuth_edge: Some(&edge),
            },
            rb: smooth(&t_d),
            ru: smooth(&t_u),
            ruu: None,
            crossing_edges: Some(&crossing),
            reflection_edges: Some(&reflection),
            r_within_crossing_orders: true,
        };
        let panels = Panels {
            reflection: panel_width(alpha),
            crossing: crossing_panel_width(alpha, index),
            nodes,
        };
        Ok(Self {
            projection: RoughProjection::of_kernels(&kernels, grid, split, panels, max_orders),
            above,
        })
    }

    /// The projected `T_d` (`rb`), `T_u` (`ru`) and `R_b` (`r`) of order `m`.
    #[cfg(test)]
    pub(super) fn operators(&self, m: usize) -> Ops {
        self.projection.ops(m)
    }

    /// The surface's reflection from above, `R_t`, left out of
    /// [`RoughInterface::over`]: evaluate it at the user directions.
    pub(super) fn surface(&self) -> RoughSurface {
        self.above
    }

    /// The reflection in air of order `m` over a stack whose reflection
    /// seen from inside the binder is `r`, without the surface's own
    /// ([`RoughInterface::surface`]): `T_u (I − r R_b)^{-1} r T_d`.
    pub(super) fn over(&self, m: usize, r: &Mat<f64>) -> Mat<f64> {
        let Ops {
            r: r_b,
            rb: t_d,
            ru: t_u,
            ..
        } = self.projection.ops(m);
        let g = identity_minus_product(r.as_ref(), r_b.as_ref());
        let lu = g.partial_piv_lu();
        let src = mm(r.as_ref(), t_d.as_ref());
        let up = refined_solve(&g, &lu, &src);
        mm(t_u.as_ref(), up.as_ref())
    }
}
