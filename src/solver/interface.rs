//! A smooth dielectric interface on top of the stack: the layers lie in a
//! binder of real index `n ≥ 1` under air (docs/conventions.md §8).
//!
//! The Fresnel maps of a horizontal interface keep the azimuth, so in
//! meridian frames they act on every Fourier order alike, block-diagonal in
//! the IQ and UV pairs (`physics::fresnel`). Per order:
//!
//! - A beam of unit flux normal to it along the external cosine `μ_e`
//!   enters as a beam along `μ_i = √(1 − (1 − μ_e²)/n²)` whose Stokes flux
//!   normal to it is `B(μ_e) = n M(t_{1→n})`
//!   ([`fresnel::beam_transmission_mueller`]).
//! - The stack (layers and base) seen from inside the binder responds with
//!   the blocks of [`layer::add`]: `r` (quadrature up ← quadrature down),
//!   `rb` (quadrature up ← beam), `ru` (user up ← quadrature down), `ruu`
//!   (user up ← beam).
//! - Light going up along a quadrature cosine `μ_q` is reflected back down
//!   by `R_q = M(r_{n→1}(μ_q))`, totally beyond the critical angle
//!   `μ_q < √(1 − 1/n²)`; its multiple reflections sum to
//!   `D = R_q (I − r R_q)^{-1} rb` going down, so the radiance going up
//!   along the internal user cosines is
//!   `L = ruu + ru R_q (I − r R_q)^{-1} rb` (the adding equation with the
//!   interface as the upper slab, van de Hulst 1980 ch. 4).
//! - It leaves into air by `A(μ_i) = (1/n)³ (μ_e/μ_i) M(t_{n→1})`
//!   ([`fresnel::radiance_transmission_mueller`]: radiance over `n²` is
//!   transmitted as flux).
//!
//! The external response is `ρ = A L B`, one linear solve per order: the
//! cost of one more layer. The interface's own reflection from above,
//! `M(r_{1→n}(μ_e))`, is a delta in the mirror direction, reported apart
//! ([`InterfaceMaps::specular`]). Zero-weight user radiance is an output
//! only: its reflection at the interface is part of the quadrature field
//! `R_q U` (the same radiance, sampled at the nodes).
//!
//! Over a mirror base the beam bounces between the two surfaces as a beam:
//! the beam going down along an internal user cosine `μ` comes back up as
//! `P b` (`P = e^{−2τ/μ} M_b(μ)`, through the stack twice and off the
//! base), and the interface sends `R(μ) P b` down again along the same
//! direction. Every pass is a fresh incident beam, so the stack's response
//! to the beam is multiplied by the 4×4 gain `G = (I − R P)^{-1}` on the
//! right, and the light leaving through the interface adds `M_out P G M_in`
//! to the delta term ([`InterfaceMaps::through`]). Reciprocally, diffuse
//! light reaching the interface along a user direction is partly reflected
//! down and comes back off the base along the same direction, unscattered:
//! the gain `(I − P R)^{-1}` on the left ([`mirror_gains`]).

use super::layer::{TopResponse, identity_minus_product, mm, refined_solve};
use crate::physics::RefractiveIndex;
use crate::physics::fresnel;
use crate::physics::stokes::{Mueller, mul};
use faer::Mat;
use faer::prelude::*;

/// The interface's maps at the user directions.
#[derive(Clone, Debug)]
pub struct InterfaceMaps {
    /// Binder index `n`.
    pub index: f64,
    /// Internal cosine of each user direction, `√(1 − (1 − μ_e²)/n²)`.
    pub mu_internal: Vec<f64>,
    /// Radiance map binder → air at each user direction, `A(μ_i)`.
    pub out: Vec<Mueller>,
    /// Beam map air → binder at each user direction, `B(μ_e)`.
    pub inp: Vec<Mueller>,
    /// Reflection from above at each user direction (the delta term).
    pub specular: Vec<Mueller>,
    /// Over a mirror base: the part of the delta term that crossed the
    /// interface twice, per user direction (`M_out P G M_in`).
    pub through: Option<Vec<Mueller>>,
}

/// The internal cosine of the direction refracted from the external cosine
/// `mu_external` into a medium of index `index ≥ 1` (Snell).
pub fn internal_cosine(index: f64, mu_external: f64) -> f64 {
    (1.0 - (1.0 - mu_external * mu_external) / (index * index))
        .max(0.0)
        .sqrt()
}

fn physics(e: crate::physics::PhysicsError) -> super::SolverError {
    super::SolverError::Invalid(format!("top interface: {e}"))
}

impl InterfaceMaps {
    /// The maps of a binder of index `index` at the external user cosines.
    pub fn new(index: f64, mu_external: &[f64]) -> Result<Self, super::SolverError> {
        let binder = RefractiveIndex { n: index, k: 0.0 };
        let mu_internal: Vec<f64> = mu_external
            .iter()
            .map(|&mu| internal_cosine(index, mu))
            .collect();
        let mut out = Vec::with_capacity(mu_external.len());
        let mut inp = Vec::with_capacity(mu_external.len());
        let mut specular = Vec::with_capacity(mu_external.len());
        for (&mu_e, &mu_i) in mu_external.iter().zip(&mu_internal) {
            out.push(fresnel::radiance_transmission_mueller(index, 1.0, mu_i).map_err(physics)?);
            inp.push(fresnel::beam_transmission_mueller(1.0, index, mu_e).map_err(physics)?);
            specular.push(fresnel::mueller(1.0, binder, mu_e).map_err(physics)?);
        }
        Ok(Self {
            index,
            mu_internal,
            out,
            inp,
            specular,
            through: None,
        })
    }

    /// The whole delta term at user direction `iv`: the interface's
    /// reflection plus, over a mirror base, what came back through it.
    pub fn delta(&self, iv: usize) -> Mueller {
        let mut s = self.specular[iv];
        if let Some(t) = &self.through {
            for (row, trow) in s.iter_mut().zip(&t[iv]) {
                for (x, y) in row.iter_mut().zip(trow) {
                    *x += y;
                }
            }
        }
        s
    }

    /// Set [`InterfaceMaps::through`] for a mirror base `base` under a
    /// stack whose direct beam transmittance is `e^{−τ/μ}` (`tau`: the
    /// stack's optical thickness).
    pub fn set_mirror_base(
        &mut self,
        tau: f64,
        base: &dyn Fn(f64) -> Mueller,
    ) -> Result<(), super::SolverError> {
        let gains = mirror_gains(self.index, &self.mu_internal, tau, base, 4)?;
        let mut through = Vec::with_capacity(gains.beam.len());
        for (iv, g) in gains.beam.iter().enumerate() {
            let mu_i = self.mu_internal[iv];
            let exit =
                fresnel::beam_transmission_mueller(self.index, 1.0, mu_i).map_err(physics)?;
            let p = round_trip(tau, mu_i, base);
            through.push(mul(&exit, &mul(&p, &mul(g, &self.inp[iv]))));
        }
        self.through = Some(through);
        Ok(())
    }

    /// `ρ = A x B`: a user-by-beam matrix at the internal cosines (per unit
    /// internal beam flux) as the response to external beams observed in
    /// air.
    pub fn to_external(&self, x: &Mat<f64>, ns: usize) -> Mat<f64> {
        let u = self.mu_internal.len();
        let mut y = Mat::<f64>::zeros(u * ns, u * ns);
        // y = A x, then y B: both maps block-diagonal.
        for a in 0..u {
            for j in 0..u * ns {
                for p in 0..ns {
                    y[(a * ns + p, j)] = (0..ns)
                        .map(|q| self.out[a][p][q] * x[(a * ns + q, j)])
                        .sum();
                }
            }
        }
        let mut z = Mat::<f64>::zeros(u * ns, u * ns);
        for b in 0..u {
            for i in 0..u * ns {
                for q in 0..ns {
                    z[(i, b * ns + q)] = (0..ns)
                        .map(|p| y[(i, b * ns + p)] * self.inp[b][p][q])
                        .sum();
                }
            }
        }
        z
    }

    /// A single-scattering BRDF `f_int` at the internal cosines of user
    /// directions `iu`, `iv` (per unit internal beam flux, `f μ_i0` is the
    /// radiance) as the external BRDF: `A f_int B μ_i0/μ_e0`.
    pub fn external_brdf(&self, iu: usize, iv: usize, mu_e0: f64, f_int: &Mueller) -> Mueller {
        let s = self.mu_internal[iv] / mu_e0;
        let a = &self.out[iu];
        let b = &self.inp[iv];
        let mut f = [[0.0; 4]; 4];
        for (p, row) in f.iter_mut().enumerate() {
            for (q, x) in row.iter_mut().enumerate() {
                let mut v = 0.0;
                for k in 0..4 {
                    for l in 0..4 {
                        v += a[p][k] * f_int[k][l] * b[l][q];
                    }
                }
                *x = s * v;
            }
        }
        f
    }
}

/// `P = e^{−2τ/μ} M_b(μ)`: a beam down along `μ` back up after crossing the
/// stack twice and reflecting off the base.
fn round_trip(tau: f64, mu: f64, base: &dyn Fn(f64) -> Mueller) -> Mueller {
    let e = if mu > 0.0 {
        (-2.0 * tau / mu).exp()
    } else {
        0.0
    };
    let mut p = base(mu);
    for row in &mut p {
        for x in row.iter_mut() {
            *x *= e;
        }
    }
    p
}

/// The gains of a mirror base under the interface per internal user cosine
/// (module doc), their leading `ns × ns` blocks meaningful (`ns = 1`: the
/// scalar `1/(1 − R₁₁ P₁₁)` in `[0][0]`): `beam[iv] = (I − R P)^{-1}` for
/// the beam going down, `radiance[iu] = (I − P R)^{-1}` for radiance that
/// reaches the interface from below along a user direction (reflected
/// down, it returns off the base along the same direction unscattered: a
/// path the quadrature field cannot hold).
pub struct MirrorGains {
    /// Right factor of the beam column block of every user direction.
    pub beam: Vec<Mueller>,
    /// Left factor of the user row block of every user direction.
    pub radiance: Vec<Mueller>,
}

/// [`MirrorGains`] of a mirror base `base` under a stack of optical
/// thickness `tau`.
pub fn mirror_gains(
    index: f64,
    mu_internal: &[f64],
    tau: f64,
    base: &dyn Fn(f64) -> Mueller,
    ns: usize,
) -> Result<MirrorGains, super::SolverError> {
    let air = RefractiveIndex { n: 1.0, k: 0.0 };
    let inverse = |x: &Mueller| -> Mueller {
        let a = Mat::<f64>::from_fn(ns, ns, |p, q| f64::from(p == q) - x[p][q]);
        let inv = a.partial_piv_lu().solve(Mat::<f64>::identity(ns, ns));
        let mut g = [[0.0; 4]; 4];
        for (p, row) in g.iter_mut().enumerate().take(ns) {
            for (q, v) in row.iter_mut().enumerate().take(ns) {
                *v = inv[(p, q)];
            }
        }
        g
    };
    let (mut beam, mut radiance) = (Vec::new(), Vec::new());
    for &mu in mu_internal {
        let r = fresnel::mueller(index, air, mu).map_err(physics)?;
        let p = round_trip(tau, mu, base);
        beam.push(inverse(&mul(&r, &p)));
        radiance.push(inverse(&mul(&p, &r)));
    }
    Ok(MirrorGains { beam, radiance })
}

/// Apply [`MirrorGains`] to a user-by-beam matrix `l` (`ns` rows and
/// columns per user direction): `G_rad[iu] l[iu, iv] G_beam[iv]`.
pub fn apply_mirror_gains(l: &mut Mat<f64>, gains: &MirrorGains, ns: usize) {
    let u = gains.beam.len();
    let mut block = [[0.0; 4]; 4];
    for iu in 0..u {
        for iv in 0..u {
            for (p, row) in block.iter_mut().enumerate().take(ns) {
                for (q, x) in row.iter_mut().enumerate().take(ns) {
                    *x = l[(iu * ns + p, iv * ns + q)];
                }
            }
            let (a, b) = (&gains.radiance[iu], &gains.beam[iv]);
            for p in 0..ns {
                for q in 0..ns {
                    let mut v = 0.0;
                    for k in 0..ns {
                        for j in 0..ns {
                            v += a[p][k] * block[k][j] * b[j][q];
                        }
                    }
                    l[(iu * ns + p, iv * ns + q)] = v;
                }
            }
        }
    }
}

/// Internal reflection `R_q` on the quadrature cosines (block diagonal).
pub fn internal_reflection(
    index: f64,
    mu_q: &[f64],
    ns: usize,
) -> Result<Mat<f64>, super::SolverError> {
    let air = RefractiveIndex { n: 1.0, k: 0.0 };
    let blocks: Vec<Mueller> = mu_q
        .iter()
        .map(|&mu| fresnel::mueller(index, air, mu).map_err(physics))
        .collect::<Result<_, _>>()?;
    let mut m = Mat::zeros(mu_q.len() * ns, mu_q.len() * ns);
    for (i, f) in blocks.iter().enumerate() {
        for p in 0..ns {
            for q in 0..ns {
                m[(i * ns + p, i * ns + q)] = f[p][q];
            }
        }
    }
    Ok(m)
}

/// `L = ruu + ru R_q (I − r R_q)^{-1} rb`: the radiance going up along the
/// internal user cosines under the interface, per unit internal beam flux.
pub fn under_interface(stack: &TopResponse, rq: &Mat<f64>) -> Mat<f64> {
    let g = identity_minus_product(stack.r.as_ref(), rq.as_ref());
    let lu = g.partial_piv_lu();
    let up = refined_solve(&g, &lu, &stack.rb);
    let down = mm(rq.as_ref(), up.as_ref());
    let mut l = stack.ruu.clone();
    l += mm(stack.ru.as_ref(), down.as_ref());
    l
}
