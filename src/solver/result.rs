//! The solver's result: the reflection matrices per Fourier order at the
//! user cosines, the BRDF they sum to, and realizability.

use super::*;
use crate::physics::microfacet::RoughSurface;
use crate::physics::stokes::Mueller;
use faer::Mat;

/// The Fourier coefficients of the reflected radiance for beams along user
/// directions, observed along user directions: `rho[m]` is `nu × nu` with rows
/// `(u, Stokes out)` and columns `(v, Stokes in)` (the S1 set of
/// [`phase`]), for a beam whose Fourier input is a unit delta in `ν`.
#[derive(Clone, Debug)]
pub struct ReflectionFourier {
    /// Stokes components per direction (4 or 1).
    pub ns: usize,
    /// User cosines (outgoing and incident).
    pub mu: Vec<f64>,
    /// One matrix per order `m = 0..`, including the secondary-scattering
    /// correction of delta-M truncated layers ([`secondary`]).
    pub rho: Vec<Mat<f64>>,
    /// Total direct transmission of the stack along each user direction
    /// (down and back up is its square), for the specular term.
    pub direct: Vec<f64>,
    /// Exact-minus-truncated single scattering when delta-M truncated a
    /// layer; [`ReflectionFourier::brdf`] adds it.
    pub correction: Option<truncation::SingleScatterCorrection>,
    /// The top interface's maps at the user directions when the problem has
    /// one ([`interface`]): `mu` are then cosines in air, `rho` the response
    /// to beams in air, and [`ReflectionFourier::brdf`] evaluates the
    /// single-scattering correction inside the binder.
    pub interface: Option<interface::InterfaceMaps>,
    /// A rough top interface's own reflection from above (`R_t` of
    /// [`super::rough_interface`]), not in `rho`:
    /// [`ReflectionFourier::brdf`] adds its BRDF at the exact directions.
    pub surface: Option<RoughSurface>,
}

impl ReflectionFourier {
    /// `cos mΔφ` and `sin mΔφ` for every order and the given propagation
    /// azimuth differences: `basis[k][m] = (cos, sin)`; reuse it for many
    /// direction pairs with [`ReflectionFourier::brdf_with_basis`].
    pub fn azimuth_basis(&self, dphi_prop: &[f64]) -> Vec<Vec<(f64, f64)>> {
        dphi_prop
            .iter()
            .map(|&d| {
                (0..self.rho.len())
                    .map(|m| {
                        let (s, c) = (m as f64 * d).sin_cos();
                        (c, s)
                    })
                    .collect()
            })
            .collect()
    }

    /// [`ReflectionFourier::brdf`] with precomputed `cos mΔφ`, `sin mΔφ`:
    /// the Fourier part only. When [`ReflectionFourier::correction`] or
    /// [`ReflectionFourier::surface`] is set, add its value at the same
    /// angles.
    pub fn brdf_with_basis(&self, iu: usize, iv: usize, basis: &[(f64, f64)]) -> Mueller {
        let ns = self.ns;
        let mut f = [[0.0; 4]; 4];
        let inv = 1.0 / (2.0 * std::f64::consts::PI * self.mu[iv]);
        for (m, rho) in self.rho.iter().enumerate() {
            let w = if m == 0 { inv } else { 2.0 * inv };
            let (c, s) = basis[m];
            let (wc, ws) = (w * c, w * s);
            for q in 0..ns {
                let col = rho.col(iv * ns + q);
                for (p, row) in f.iter_mut().enumerate().take(ns) {
                    let v = col[iu * ns + p];
                    row[q] += match (p < 2, q < 2) {
                        (true, true) | (false, false) => v * wc,
                        (false, true) => v * ws,
                        (true, false) => -v * ws,
                    };
                }
            }
        }
        f
    }

    /// The Mueller BRDF (1/sr, conventions §6) for incident cosine `mu[iv]`,
    /// outgoing `mu[iu]` and **propagation** azimuth difference `dphi_prop`
    /// (radians, 0 = forward side), including the single-scattering
    /// correction of a delta-M truncated solve and a rough top interface's
    /// own reflection. Scalar results fill `[0][0]` only.
    ///
    /// `f μ_0 = Σ_m (2 − δ_m0)/(2π) [bd(ρ^m) cos mΔφ + od(ρ^m) sin mΔφ]`
    /// with `od` as in [`phase`] (UV←IQ block `+`, IQ←UV block `−`).
    pub fn brdf(&self, iu: usize, iv: usize, dphi_prop: f64) -> Mueller {
        let ns = self.ns;
        let mut f = fourier_sum(&self.rho, ns, iu, iv, dphi_prop);
        let mu0 = self.mu[iv];
        for row in &mut f {
            for x in row.iter_mut() {
                *x /= mu0;
            }
        }
        if let Some(c) = &self.correction {
            let d = match &self.interface {
                None => c.brdf(self.mu[iu], mu0, dphi_prop),
                Some(i) => {
                    let inside = c.brdf(i.mu_internal[iu], i.mu_internal[iv], dphi_prop);
                    i.external_brdf(iu, iv, mu0, &inside)
                }
            };
            for p in 0..ns {
                for q in 0..ns {
                    f[p][q] += d[p][q];
                }
            }
        }
        if let Some(s) = &self.surface {
            let g = s.mueller(self.mu[iu], mu0, dphi_prop);
            for p in 0..ns {
                for q in 0..ns {
                    f[p][q] += g[p][q];
                }
            }
        }
        if ns == 4 {
            make_realizable(&mut f);
        }
        f
    }
}

impl ReflectionFourier {
    /// The delta term of the mirror direction for a beam along `mu[iv]`
    /// under a top interface (Mueller matrix of reflected over incident
    /// flux): its reflection plus, over a mirror base, the base's beam that
    /// came back through it ([`interface::InterfaceMaps::delta`]). Without
    /// an interface a mirror base's term is the caller's (its matrix and
    /// `direct`²).
    pub fn interface_specular(&self, iv: usize) -> Option<Mueller> {
        self.interface.as_ref().map(|i| i.delta(iv))
    }
}

/// Coherency eigenvalues below `−REALIZABILITY_TOL · m11` are projected
/// away by [`make_realizable`].
pub const REALIZABILITY_TOL: f64 = 1e-12;

/// Replace a BRDF Mueller matrix that is not physically realizable (a
/// coherency eigenvalue below `−REALIZABILITY_TOL · m11`) by the nearest
/// realizable one (`physics::stokes::realizable_projection`, Cloude
/// filtering). The exact BRDF is realizable; a discrete-ordinate solution
/// with few streams need not be (property sweep: Stokes criterion −1.2 % of
/// f11 for a Mie layer at 4 streams, grazing backscatter). The projection
/// onto the convex set of realizable matrices never moves the result away
/// from the exact one (in the Frobenius norm of the coherency matrix) and
/// commutes with reciprocity; it changes nothing when the solution is
/// realizable, as every converged one is.
pub fn make_realizable(f: &mut Mueller) {
    if let Some(p) = crate::physics::stokes::realizable_projection(f, REALIZABILITY_TOL) {
        *f = p;
    }
}

/// Fourier sum of a user-by-beam response (no `1/μ_0`): the Stokes radiance
/// along user direction `iu` for a beam along `iv` of unit flux normal to the
/// beam, as a Mueller matrix acting on the beam's Stokes vector, at
/// propagation azimuth difference `dphi_prop`.
pub fn fourier_sum(rho: &[Mat<f64>], ns: usize, iu: usize, iv: usize, dphi_prop: f64) -> Mueller {
    let mut f = [[0.0; 4]; 4];
    for (m, r) in rho.iter().enumerate() {
        let w = if m == 0 { 1.0 } else { 2.0 } / (2.0 * std::f64::consts::PI);
        let (s, c) = (m as f64 * dphi_prop).sin_cos();
        for p in 0..ns {
            for q in 0..ns {
                let v = r[(iu * ns + p, iv * ns + q)];
                let term = match (p < 2, q < 2) {
                    (true, true) | (false, false) => v * c,
                    (false, true) => v * s,
                    (true, false) => -v * s,
                };
                f[p][q] += w * term;
            }
        }
    }
    f
}
