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
//! Not covered yet, refused by the solver's validation: a mirror base under
//! the interface (its beam would bounce between the two surfaces as a beam).

use super::layer::{TopResponse, identity_minus_product, mm, refined_solve};
use crate::physics::RefractiveIndex;
use crate::physics::fresnel;
use crate::physics::stokes::Mueller;
use faer::Mat;

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
        })
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
