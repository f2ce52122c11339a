//! Polarized Fresnel reflection of a plane interface.
//!
//! Light in an ambient medium of real index `n1 ≥ 1` (air or the binder)
//! falls on a medium of complex index `n2 = n + i k` (conventions §2,
//! `exp(−iωt)`, `k ≥ 0`; dielectric or conductor) at incidence cosine
//! `μ = cos θ_i ∈ [0, 1]`.
//!
//! # Amplitude coefficients and frames
//!
//! In the meridian Stokes frames of conventions §5 (`x = e_ϑ` in the plane of
//! incidence = "p", `y = e_ϕ` = "s"), the Jones matrix of the reflection from
//! the horizontal surface is `diag(r_p, r_s)` with
//!
//! ```text
//! r_p = (n2 cosθ_i − n1 cosθ_t) / (n2 cosθ_i + n1 cosθ_t),
//! r_s = (n1 cosθ_i − n2 cosθ_t) / (n1 cosθ_i + n2 cosθ_t),
//! n2 cosθ_t = w = √(n2² − n1² (1 − μ²)),   Im w ≥ 0 (Re w ≥ 0 if Im w = 0),
//! ```
//!
//! computed as `r_p = (n2² μ − n1 w)/(n2² μ + n1 w)`, `r_s = (n1 μ − w)/(n1 μ + w)`.
//! The branch `Im w ≥ 0` makes the transmitted wave `exp(−i k0 w z)` decay
//! into the medium (`z < 0`) for `exp(−iωt)`; it also gives the evanescent
//! wave of total internal reflection when `n1 > n2` (real) beyond the
//! critical angle (`|r_p| = |r_s| = 1` there).
//!
//! Why these signs: for propagation azimuth 0 the incident ray
//! `k_in = (sinθ, 0, −cosθ)` has `e_ϑ = (−cosθ, 0, −sinθ)`, the reflected ray
//! `k_out = (sinθ, 0, cosθ)` has `e_ϑ = (cosθ, 0, −sinθ)`, and both share
//! `e_ϕ = (0, 1, 0)`. In both frames `k̂ × e_ϑ = +ŷ`, so the magnetic fields
//! of p-waves are `+n E ŷ`; continuity of `E_x` and `H_y` at `z = 0` gives
//! exactly the `r_p` above, and continuity of `E_y`, `H_x` the `r_s`. At
//! normal incidence the incident `e_ϑ = (−1, 0, 0)` and the reflected
//! `e_ϑ = (+1, 0, 0)` while `e_ϕ` is shared, so a perfect conductor
//! (`E_tangential = 0`, `E_out = −E_in` in world coordinates) has Jones
//! `diag(+1, −1)`: `r_p → +1`, `r_s → −1` as `n2 → i∞`. At normal incidence
//! `r_p = −r_s = (n2 − n1)/(n2 + n1)`.
//!
//! # Mueller matrix
//!
//! With the Stokes vector of conventions §3/§5 (`S_i = tr(σ_i ρ)`, see
//! [`crate::physics::stokes`]) a Jones matrix `J` maps Stokes vectors by
//! `m_ij = ½ tr(σ_i J σ_j J†)`. For `J = diag(r_p, r_s)` the non-zero
//! products are (`σ_1 = diag(1,−1)`, `σ_2 = [[0,1],[1,0]]`,
//! `σ_3 = [[0,−i],[i,0]]`):
//!
//! ```text
//! J J†        = diag(|r_p|², |r_s|²)            -> M11 = M22 = (|r_p|² + |r_s|²)/2
//! σ_1 J J†    = diag(|r_p|², −|r_s|²)           -> M12 = M21 = (|r_p|² − |r_s|²)/2
//! J σ_2 J†    = [[0, r_p r_s*], [r_s r_p*, 0]]  -> M33 = ½ tr(σ_2 ·) = Re(r_p r_s*)
//!                                                  M43 = ½ tr(σ_3 ·) = −Im(r_p r_s*)
//! J σ_3 J†    = [[0, −i r_p r_s*], [i r_s r_p*, 0]]
//!                                               -> M34 = ½ tr(σ_2 ·) = Im(r_p r_s*)
//!                                                  M44 = ½ tr(σ_3 ·) = Re(r_p r_s*)
//! ```
//!
//! (1-based element names; all others vanish.) This is the form of
//! conventions §3 with `(S2, S1) → (r_p, r_s)`; it is checked against the
//! generic [`crate::physics::stokes::jones_to_mueller`] in the tests. The matrix
//! is non-depolarizing: `M11² = M12² + M33² + M34²`.

use super::stokes::Mueller;
use super::{C64, PhysicsError, RefractiveIndex};

/// Complex Fresnel amplitude reflection coefficients in the meridian frames
/// (module doc): Jones matrix `diag(r_p, r_s)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FresnelCoefficients {
    /// p (in the plane of incidence, Stokes `x`) amplitude coefficient.
    pub r_p: C64,
    /// s (perpendicular, Stokes `y`) amplitude coefficient.
    pub r_s: C64,
}

impl FresnelCoefficients {
    /// `R_p = |r_p|²`.
    pub fn reflectance_p(&self) -> f64 {
        self.r_p.norm_sqr()
    }

    /// `R_s = |r_s|²`.
    pub fn reflectance_s(&self) -> f64 {
        self.r_s.norm_sqr()
    }

    /// Unpolarized reflectance `R = (R_s + R_p)/2`.
    pub fn reflectance(&self) -> f64 {
        0.5 * (self.reflectance_s() + self.reflectance_p())
    }

    /// The 4×4 Mueller matrix (row = outgoing Stokes), see
    /// [`mueller_from_coefficients`].
    pub fn mueller(&self) -> Mueller {
        mueller_from_coefficients(self.r_p, self.r_s)
    }
}

/// Intensity reflectances.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reflectances {
    /// `R_s = |r_s|²`.
    pub r_s: f64,
    /// `R_p = |r_p|²`.
    pub r_p: f64,
    /// `R = (R_s + R_p)/2` (unpolarized incident light).
    pub r: f64,
}

/// Fresnel amplitude coefficients `r_p`, `r_s` (module doc) for ambient
/// index `n1` (real, `≥ 1`, finite), medium index `n2` (`n > 0`, `k ≥ 0`,
/// finite) and incidence cosine `mu ∈ [0, 1]` (values above 1 by at most
/// `1e-12` are clamped to 1).
///
/// If `n2 = n1` exactly (no interface) both coefficients are 0, including the
/// otherwise undefined grazing limit.
///
/// # Errors
/// [`PhysicsError::OutOfRange`] naming `n1`, `n2.n`, `n2.k` or `mu`.
pub fn coefficients(
    n1: f64,
    n2: RefractiveIndex,
    mu: f64,
) -> Result<FresnelCoefficients, PhysicsError> {
    if !(n1.is_finite() && n1 >= 1.0) {
        return Err(out_of_range("n1", n1, "[1, ∞) (real ambient index)"));
    }
    if !(n2.n.is_finite() && n2.n > 0.0) {
        return Err(out_of_range("n2.n", n2.n, "(0, ∞)"));
    }
    if !(n2.k.is_finite() && n2.k >= 0.0) {
        return Err(out_of_range("n2.k", n2.k, "[0, ∞)"));
    }
    if !(mu.is_finite() && (0.0..=1.0 + 1e-12).contains(&mu)) {
        return Err(out_of_range("mu", mu, "[0, 1]"));
    }
    let mu = mu.min(1.0);
    if n2.k == 0.0 && n2.n == n1 {
        let zero = C64::new(0.0, 0.0);
        return Ok(FresnelCoefficients {
            r_p: zero,
            r_s: zero,
        });
    }
    let (n, k) = (n2.n, n2.k);
    let sin2 = (1.0 - mu * mu).max(0.0);
    // n2² − n1² sin²θ with Im = 2nk ≥ 0 (abs: never −0.0), principal sqrt:
    // Re w ≥ 0 and Im w ≥ 0.
    let n2sq = C64::new(n * n - k * k, (2.0 * n * k).abs());
    let w = C64::new(n2sq.re - n1 * n1 * sin2, n2sq.im).sqrt();
    let r_p = (n2sq * mu - n1 * w) / (n2sq * mu + n1 * w);
    let r_s = (n1 * mu - w) / (n1 * mu + w);
    Ok(FresnelCoefficients { r_p, r_s })
}

/// Reflectances `R_s`, `R_p`, `R = (R_s + R_p)/2`; arguments and errors as
/// [`coefficients`].
pub fn reflectances(n1: f64, n2: RefractiveIndex, mu: f64) -> Result<Reflectances, PhysicsError> {
    let c = coefficients(n1, n2, mu)?;
    Ok(Reflectances {
        r_s: c.reflectance_s(),
        r_p: c.reflectance_p(),
        r: c.reflectance(),
    })
}

/// The 4×4 Fresnel reflection Mueller matrix (row = outgoing Stokes, frames
/// of conventions §5); arguments and errors as [`coefficients`].
pub fn mueller(n1: f64, n2: RefractiveIndex, mu: f64) -> Result<Mueller, PhysicsError> {
    Ok(coefficients(n1, n2, mu)?.mueller())
}

/// Mueller matrix of the Jones matrix `diag(r_p, r_s)` (module doc):
///
/// ```text
/// | (|rp|²+|rs|²)/2  (|rp|²−|rs|²)/2        0              0        |
/// | (|rp|²−|rs|²)/2  (|rp|²+|rs|²)/2        0              0        |
/// |        0                0          Re(rp rs*)     Im(rp rs*)    |
/// |        0                0         −Im(rp rs*)     Re(rp rs*)    |
/// ```
pub fn mueller_from_coefficients(r_p: C64, r_s: C64) -> Mueller {
    let (a, b) = (r_p.norm_sqr(), r_s.norm_sqr());
    let x = r_p * r_s.conj();
    let (m11, m12) = (0.5 * (a + b), 0.5 * (a - b));
    [
        [m11, m12, 0.0, 0.0],
        [m12, m11, 0.0, 0.0],
        [0.0, 0.0, x.re, x.im],
        [0.0, 0.0, -x.im, x.re],
    ]
}

/// Fresnel amplitude transmission coefficients of a dielectric interface
/// (both indices real) in the meridian frames of the incident and the
/// refracted directions (module doc; the frames of both are `e_ϑ`, `e_ϕ` of
/// their own propagation direction, from either side):
///
/// ```text
/// t_p = 2 n1 μ / (n2 μ + n1 μ_t),   t_s = 2 n1 μ / (n1 μ + n2 μ_t),
/// n2 μ_t = √(n2² − n1² (1 − μ²))   (Snell; Born & Wolf §1.5.2, eq. 20)
/// ```
///
/// the same continuity of `E_x`, `H_y` (p) and `E_y`, `H_x` (s) that gives
/// [`coefficients`], for light going down or up (the equations are the same
/// up to a common sign). `None` beyond the critical angle (`n1 > n2`, total
/// internal reflection: no transmitted wave).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transmission {
    /// p (in the plane of incidence) amplitude coefficient.
    pub t_p: f64,
    /// s (perpendicular) amplitude coefficient.
    pub t_s: f64,
    /// Cosine of the refracted direction.
    pub mu_t: f64,
}

impl Transmission {
    /// Flux transmittance `T = (n2 μ_t / n1 μ) (|t_p|² + |t_s|²)/2` of
    /// unpolarized light (the power through a patch of the interface; `R +
    /// T = 1`).
    pub fn transmittance(&self, n1: f64, n2: f64, mu: f64) -> f64 {
        n2 * self.mu_t / (n1 * mu) * 0.5 * (self.t_p * self.t_p + self.t_s * self.t_s)
    }
}

/// [`Transmission`] for real indices `n1` (incident side) and `n2` (`n1 =
/// 1.5`, `n2 = 1` is binder to air) and incidence cosine `mu ∈ (0, 1]`.
///
/// # Errors
/// [`PhysicsError::OutOfRange`] naming `n1`, `n2` or `mu`.
pub fn transmission(n1: f64, n2: f64, mu: f64) -> Result<Option<Transmission>, PhysicsError> {
    for (name, v) in [("n1", n1), ("n2", n2)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(out_of_range(name, v, "(0, ∞) (real index)"));
        }
    }
    if !(mu.is_finite() && mu > 0.0 && mu <= 1.0 + 1e-12) {
        return Err(out_of_range("mu", mu, "(0, 1]"));
    }
    let mu = mu.min(1.0);
    let w2 = n2 * n2 - n1 * n1 * (1.0 - mu * mu);
    if w2 <= 0.0 {
        return Ok(None);
    }
    let w = w2.sqrt();
    Ok(Some(Transmission {
        t_p: 2.0 * n1 * mu / (n2 * mu + n1 * w / n2),
        t_s: 2.0 * n1 * mu / (n1 * mu + w),
        mu_t: w / n2,
    }))
}

/// Mueller matrix of the real Jones matrix `diag(t_p, t_s)` (the form of
/// [`mueller_from_coefficients`] with no phase).
fn real_jones_mueller(t_p: f64, t_s: f64) -> Mueller {
    let (a, b) = (t_p * t_p, t_s * t_s);
    let (m11, m12, m33) = (0.5 * (a + b), 0.5 * (a - b), t_p * t_s);
    [
        [m11, m12, 0.0, 0.0],
        [m12, m11, 0.0, 0.0],
        [0.0, 0.0, m33, 0.0],
        [0.0, 0.0, 0.0, m33],
    ]
}

/// The transmitted collimated beam: its Stokes vector of irradiance normal
/// to the beam from the incident beam's, `(n2/n1) M(t)` (irradiance in a
/// medium of index `n` is `∝ n |E|²`). Its flux through the interface is
/// `μ_t` times that, the transmitted part of `μ` times the incident one.
/// The zero matrix beyond the critical angle. Arguments as [`transmission`].
pub fn beam_transmission_mueller(n1: f64, n2: f64, mu: f64) -> Result<Mueller, PhysicsError> {
    Ok(match transmission(n1, n2, mu)? {
        Some(t) => scale(real_jones_mueller(t.t_p, t.t_s), n2 / n1),
        None => [[0.0; 4]; 4],
    })
}

/// Power through the interface: the Stokes flux through a patch of the
/// interface from the incident one, `(n2 μ_t / n1 μ) M(t)`; its unpolarized
/// element is the transmittance `T = 1 − R` (the factor a microfacet
/// transmission model puts on each facet). The zero matrix beyond the
/// critical angle. Arguments as [`transmission`].
pub fn power_transmission_mueller(n1: f64, n2: f64, mu: f64) -> Result<Mueller, PhysicsError> {
    Ok(match transmission(n1, n2, mu)? {
        Some(t) => scale(
            real_jones_mueller(t.t_p, t.t_s),
            n2 * t.mu_t / (n1 * mu.min(1.0)),
        ),
        None => [[0.0; 4]; 4],
    })
}

/// Radiance across the interface: the Stokes radiance refracted into `μ_t`
/// from the incident radiance along `μ`, `(n2/n1)³ (μ_t/μ) M(t)`: the beam
/// map of [`beam_transmission_mueller`] divided by the solid-angle ratio
/// `dΩ_t/dΩ = (n1/n2)² μ/μ_t` (Snell in solid angle, `n² μ dΩ` conserved).
/// Its unpolarized element is `(n2/n1)² T`: radiance over `n²` is
/// transmitted as flux (the `n²` law, docs/conventions.md). The zero matrix
/// beyond the critical angle. Arguments as [`transmission`].
pub fn radiance_transmission_mueller(n1: f64, n2: f64, mu: f64) -> Result<Mueller, PhysicsError> {
    Ok(match transmission(n1, n2, mu)? {
        Some(t) => scale(
            real_jones_mueller(t.t_p, t.t_s),
            (n2 / n1).powi(3) * t.mu_t / mu.min(1.0),
        ),
        None => [[0.0; 4]; 4],
    })
}

fn scale(mut m: Mueller, f: f64) -> Mueller {
    for row in &mut m {
        for x in row.iter_mut() {
            *x *= f;
        }
    }
    m
}

fn out_of_range(name: &'static str, value: f64, range: &str) -> PhysicsError {
    PhysicsError::OutOfRange {
        name,
        value,
        range: range.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::stokes::{coherency_eigenvalues, is_realizable, jones_to_mueller};

    fn ri(n: f64, k: f64) -> RefractiveIndex {
        RefractiveIndex::new(n, k)
    }

    /// Independent real-arithmetic reflectances for `n1 = 1` (Born & Wolf,
    /// *Principles of Optics*, §14.2): with `A = n² − k² − sin²θ`,
    /// `2u² = √(A² + 4n²k²) + A`, `2v² = √(A² + 4n²k²) − A` (`u, v ≥ 0`),
    /// `R_s = ((cosθ − u)² + v²)/((cosθ + u)² + v²)`,
    /// `R_p = (((n²−k²)cosθ − u)² + (2nk cosθ − v)²) /
    ///        (((n²−k²)cosθ + u)² + (2nk cosθ + v)²)`.
    fn born_wolf(n: f64, k: f64, mu: f64) -> (f64, f64) {
        let s2 = 1.0 - mu * mu;
        let a = n * n - k * k - s2;
        let root = (a * a + 4.0 * n * n * k * k).sqrt();
        let u = (0.5 * (root + a)).max(0.0).sqrt();
        let v = (0.5 * (root - a)).max(0.0).sqrt();
        let rs = ((mu - u).powi(2) + v * v) / ((mu + u).powi(2) + v * v);
        let e1 = n * n - k * k;
        let e2 = 2.0 * n * k;
        let rp = ((e1 * mu - u).powi(2) + (e2 * mu - v).powi(2))
            / ((e1 * mu + u).powi(2) + (e2 * mu + v).powi(2));
        (rs, rp)
    }

    const SAMPLES: [(f64, f64); 9] = [
        (1.5, 0.0),
        (2.86, 0.0),
        (0.139, 4.129),  // silver 650 nm (seed Table 2)
        (1.4482, 7.537), // aluminium 632.8 nm
        (3.1399, 3.315), // chromium 632.8 nm
        (0.023, 0.218),  // seed "iron oxide" 650 nm
        (1.0, 1e-3),
        (0.5, 0.0),
        (3.832, 0.183),
    ];

    #[test]
    fn brewster_angle_dielectric() {
        let n2: f64 = 1.5;
        let mu_b = 1.0 / (1.0 + n2 * n2).sqrt(); // tan θB = 1.5
        let r = reflectances(1.0, ri(n2, 0.0), mu_b).unwrap();
        assert!(r.r_p < 1e-28, "R_p(θB) = {:e}", r.r_p);
        assert!(r.r_s > 0.1);
        // A minimum: neighbours are larger.
        let theta_b = mu_b.acos();
        for d in [-0.01, 0.01] {
            let rp = reflectances(1.0, ri(n2, 0.0), (theta_b + d).cos())
                .unwrap()
                .r_p;
            assert!(rp > 1e-6);
        }
        // Same from the dense side: tan θB = 1/1.5, and in a binder n1 = 1.5
        // onto n2 = 2.25: tan θB = 1.5.
        let mu_b2 = 1.5 / (1.0 + 1.5f64 * 1.5).sqrt();
        assert!(reflectances(1.5, ri(1.0, 0.0), mu_b2).unwrap().r_p < 1e-28);
        assert!(reflectances(1.5, ri(2.25, 0.0), mu_b).unwrap().r_p < 1e-28);
    }

    #[test]
    fn total_internal_reflection() {
        // n1 = 1.5 onto n2 = 1: critical sinθc = 1/1.5.
        let sin_c: f64 = 1.0 / 1.5;
        let mut worst = 0.0_f64;
        for i in 1..=50 {
            let s = sin_c + (1.0 - sin_c) * i as f64 / 50.0;
            let mu = (1.0 - s * s).max(0.0).sqrt();
            let c = coefficients(1.5, ri(1.0, 0.0), mu).unwrap();
            worst = worst.max((c.r_s.norm() - 1.0).abs());
            worst = worst.max((c.r_p.norm() - 1.0).abs());
        }
        assert!(worst < 1e-14, "|r| − 1 up to {worst:e}");
        // Below the critical angle: partial reflection, and Stokes' relation
        // r(1→2, θ1) = −r(2→1, θ2) with 1.5 sinθ1 = sinθ2.
        for s1 in [0.0_f64, 0.2, 0.4, 0.6] {
            let mu1 = (1.0 - s1 * s1).sqrt();
            let s2: f64 = 1.5 * s1;
            let mu2 = (1.0 - s2 * s2).sqrt();
            let a = coefficients(1.5, ri(1.0, 0.0), mu1).unwrap();
            let b = coefficients(1.0, ri(1.5, 0.0), mu2).unwrap();
            assert!(a.reflectance() < 1.0);
            assert!((a.r_s + b.r_s).norm() < 1e-14 && (a.r_p + b.r_p).norm() < 1e-14);
        }
    }

    #[test]
    fn normal_incidence_reflectance() {
        let mut worst = 0.0_f64;
        for n1 in [1.0, 1.33, 1.5] {
            for (n, k) in SAMPLES {
                let n2 = C64::new(n, k);
                let expect = ((n2 - n1) / (n2 + n1)).norm_sqr();
                let c = coefficients(n1, ri(n, k), 1.0).unwrap();
                worst = worst.max((c.reflectance_s() - expect).abs());
                worst = worst.max((c.reflectance_p() - expect).abs());
                // r_p = −r_s at normal incidence in the meridian frames.
                worst = worst.max((c.r_p + c.r_s).norm());
            }
        }
        assert!(worst < 1e-15, "worst {worst:e}");
    }

    #[test]
    fn energy_bound_and_grazing_limit() {
        for n1 in [1.0, 1.5] {
            for (n, k) in SAMPLES {
                if k == 0.0 && n == n1 {
                    continue; // no interface
                }
                for i in 0..=200 {
                    let mu = i as f64 / 200.0;
                    let r = reflectances(n1, ri(n, k), mu).unwrap();
                    assert!(
                        r.r_s <= 1.0 + 1e-14 && r.r_p <= 1.0 + 1e-14,
                        "{n1} {n} {k} {mu}"
                    );
                    assert!(r.r_s >= 0.0 && r.r_p >= 0.0);
                }
                // Grazing incidence: R -> 1.
                let r = reflectances(n1, ri(n, k), 0.0).unwrap();
                assert!((r.r - 1.0).abs() < 1e-14, "grazing {n1} {n} {k}: {r:?}");
                let r = reflectances(n1, ri(n, k), 1e-4).unwrap();
                assert!(r.r > 0.99, "near-grazing {n1} {n} {k}: {r:?}");
            }
        }
        // Index-matched: no reflection at any angle.
        for mu in [0.0, 0.5, 1.0] {
            let r = reflectances(1.5, ri(1.5, 0.0), mu).unwrap();
            assert_eq!(r.r, 0.0);
        }
    }

    #[test]
    fn perfect_conductor_limit() {
        let n2 = ri(1e-3, 1e7);
        for mu in [1.0, 0.7, 0.3, 0.05] {
            let c = coefficients(1.0, n2, mu).unwrap();
            assert!((c.r_p - 1.0).norm() < 1e-5, "mu {mu}: r_p {}", c.r_p);
            assert!((c.r_s + 1.0).norm() < 1e-5, "mu {mu}: r_s {}", c.r_s);
            // Mueller -> diag(1, 1, −1, −1) (the mirror).
            let m = c.mueller();
            let expect = [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, -1.0, 0.0],
                [0.0, 0.0, 0.0, -1.0],
            ];
            for i in 0..4 {
                for j in 0..4 {
                    assert!((m[i][j] - expect[i][j]).abs() < 1e-5);
                }
            }
        }
    }

    #[test]
    fn absorbing_branch_matches_born_wolf() {
        let mut worst = 0.0_f64;
        for (n, k) in SAMPLES {
            for i in 0..=100 {
                let mu = i as f64 / 100.0;
                let r = reflectances(1.0, ri(n, k), mu).unwrap();
                let (rs, rp) = born_wolf(n, k, mu);
                worst = worst.max((r.r_s - rs).abs()).max((r.r_p - rp).abs());
            }
        }
        assert!(worst < 1e-13, "worst {worst:e}");
        // The transmitted wave decays: Im(n2 cosθt) ≥ 0. Check via r_s:
        // w = n1 μ (1 − r_s)/(1 + r_s).
        for (n, k) in SAMPLES {
            for mu in [0.1, 0.5, 0.9] {
                let c = coefficients(1.0, ri(n, k), mu).unwrap();
                let w = mu * (1.0 - c.r_s) / (1.0 + c.r_s);
                assert!(w.im >= -1e-12 && w.re >= -1e-12, "{n} {k} {mu}: w = {w}");
            }
        }
    }

    #[test]
    fn published_metal_reflectance() {
        // refractiveindex.info (M. Polyanskiy, forum "Reflection coefficient",
        // https://refractiveindex.info/forum/viewtopic.php?f=9&t=37): aluminium
        // at 0.6 µm (Rakić 1995 data) n = 1.26232, k = 7.1855, normal-incidence
        // R = 0.91103.
        let r = reflectances(1.0, ri(1.26232, 7.1855), 1.0).unwrap().r;
        assert!((r - 0.91103).abs() < 5e-6, "R = {r}");
    }

    #[test]
    fn mueller_matrix_is_pure_and_matches_jones() {
        let mut worst_jones = 0.0_f64;
        let mut worst_pure = 0.0_f64;
        let mut worst_eig = 0.0_f64;
        for n1 in [1.0, 1.5] {
            for (n, k) in SAMPLES {
                for i in 0..=20 {
                    let mu = i as f64 / 20.0;
                    let c = coefficients(n1, ri(n, k), mu).unwrap();
                    let m = c.mueller();
                    let z = C64::new(0.0, 0.0);
                    let mj = jones_to_mueller(&[[c.r_p, z], [z, c.r_s]]);
                    for a in 0..4 {
                        for b in 0..4 {
                            worst_jones = worst_jones.max((m[a][b] - mj[a][b]).abs());
                        }
                    }
                    // Structure: M22 = M11, M21 = M12, M44 = M33, M43 = −M34.
                    assert_eq!(m[1][1], m[0][0]);
                    assert_eq!(m[1][0], m[0][1]);
                    assert_eq!(m[3][3], m[2][2]);
                    assert_eq!(m[3][2], -m[2][3]);
                    // Non-depolarizing: M11² = M12² + M33² + M34².
                    let d = m[0][0].powi(2) - m[0][1].powi(2) - m[2][2].powi(2) - m[2][3].powi(2);
                    worst_pure = worst_pure.max(d.abs());
                    // Cloude: one non-zero coherency eigenvalue = M11.
                    if m[0][0] > 0.0 {
                        assert!(is_realizable(&m, 1e-12));
                        let ev = coherency_eigenvalues(&m);
                        worst_eig = worst_eig.max((ev[0] - m[0][0]).abs());
                        for &l in &ev[1..] {
                            worst_eig = worst_eig.max(l.abs());
                        }
                    }
                }
            }
        }
        assert!(worst_jones < 1e-15, "jones {worst_jones:e}");
        assert!(worst_pure < 1e-14, "purity {worst_pure:e}");
        assert!(worst_eig < 1e-14, "eigen {worst_eig:e}");
    }

    #[test]
    fn invalid_inputs() {
        assert!(coefficients(0.9, ri(1.5, 0.0), 0.5).is_err());
        assert!(coefficients(f64::NAN, ri(1.5, 0.0), 0.5).is_err());
        assert!(coefficients(1.0, ri(0.0, 1.0), 0.5).is_err());
        assert!(coefficients(1.0, ri(1.5, -0.1), 0.5).is_err());
        assert!(coefficients(1.0, ri(1.5, 0.0), -0.1).is_err());
        assert!(coefficients(1.0, ri(1.5, 0.0), 1.1).is_err());
        assert!(coefficients(1.0, ri(1.5, 0.0), f64::NAN).is_err());
        match coefficients(1.0, ri(1.5, 0.0), 2.0) {
            Err(PhysicsError::OutOfRange { name, .. }) => assert_eq!(name, "mu"),
            other => panic!("{other:?}"),
        }
        // Rounding above 1 is tolerated.
        assert!(coefficients(1.0, ri(1.5, 0.0), 1.0 + 1e-13).is_ok());
        // k = −0.0 is accepted and treated as a dielectric (TIR branch intact).
        let c = coefficients(1.5, ri(1.0, -0.0), 0.1).unwrap();
        assert!((c.r_s.norm() - 1.0).abs() < 1e-14);
    }

    /// Energy across a dielectric interface, from both sides and for each
    /// incident Stokes vector: the reflected flux `μ R·S` plus the
    /// transmitted beam's flux `μ_t T_beam·S` equals the incident `μ S_0`;
    /// beyond the critical angle nothing is transmitted and `|r| = 1`.
    #[test]
    fn transmission_conserves_flux_from_both_sides() {
        for (n1, n2) in [(1.0, 1.5), (1.5, 1.0), (1.0, 2.6), (1.33, 1.0)] {
            for mu in [1.0, 0.9, 0.5, 0.2, 0.05, 1e-3] {
                let r = mueller(n1, ri(n2, 0.0), mu).unwrap();
                let tb = beam_transmission_mueller(n1, n2, mu).unwrap();
                let mu_t = transmission(n1, n2, mu).unwrap().map_or(0.0, |t| t.mu_t);
                for j in 0..4 {
                    let flux = mu * r[0][j] + mu_t * tb[0][j];
                    let want = if j == 0 { mu } else { 0.0 };
                    assert!((flux - want).abs() < 1e-14, "{n1} {n2} {mu} {j}: {flux}");
                }
            }
        }
        // Critical angle of 1.5 → 1: μ_c = √(1 − 1/2.25).
        let mu_c = (1.0 - 1.0 / 2.25f64).sqrt();
        assert!(transmission(1.5, 1.0, mu_c - 1e-9).unwrap().is_none());
        assert!(transmission(1.5, 1.0, mu_c + 1e-9).unwrap().is_some());
    }

    /// The power map is the beam map times `μ_t/μ`: reflected plus
    /// transmitted power is the incident power, for every Stokes vector.
    #[test]
    fn power_transmission_is_the_flux_left_by_reflection() {
        for (n1, n2) in [(1.0, 1.5), (1.5, 1.0), (1.33, 1.0)] {
            for mu in [1.0, 0.6, 0.1] {
                let r = mueller(n1, ri(n2, 0.0), mu).unwrap();
                let t = power_transmission_mueller(n1, n2, mu).unwrap();
                for j in 0..4 {
                    let want = if j == 0 { 1.0 } else { 0.0 };
                    assert!(
                        (r[0][j] + t[0][j] - want).abs() < 1e-14,
                        "{n1} {n2} {mu} {j}"
                    );
                }
            }
        }
    }

    /// Normal incidence `t = 2 n1/(n1 + n2)` for both polarizations; Brewster
    /// angle: `r_p = 0`, so p-light is transmitted in full (`T_p = 1`).
    #[test]
    fn transmission_normal_incidence_and_brewster() {
        let t = transmission(1.0, 1.5, 1.0).unwrap().unwrap();
        assert!((t.t_p - 0.8).abs() < 1e-15 && (t.t_s - 0.8).abs() < 1e-15);
        assert!((t.transmittance(1.0, 1.5, 1.0) - 0.96).abs() < 1e-15);
        for (n1, n2) in [(1.0f64, 1.5f64), (1.5, 1.0)] {
            let mu_b = (n2 / n1).atan().cos();
            let t = transmission(n1, n2, mu_b).unwrap().unwrap();
            let tp = n2 * t.mu_t / (n1 * mu_b) * t.t_p * t.t_p;
            assert!((tp - 1.0).abs() < 1e-14, "{n1} → {n2}: T_p = {tp}");
        }
    }

    /// Reciprocity of refraction: the flux transmittance from 1 to 2 along
    /// `μ` equals that from 2 to 1 along the refracted `μ_t`, element by
    /// element of the Mueller matrices (the Stokes relation `n1 μ t₂₁ = n2
    /// μ_t t₁₂`): `(n1/n2)² M_rad(1→2, μ) = (n2/n1)² M_rad(2→1, μ_t)ᵀ`, both
    /// the flux transmittance matrix (the `n²` law of radiance).
    #[test]
    fn radiance_transmission_is_reciprocal_with_the_n_squared_law() {
        for (n1, n2) in [(1.0, 1.5), (1.0, 2.4)] {
            for mu in [1.0, 0.7, 0.3, 0.01] {
                let t = transmission(n1, n2, mu).unwrap().unwrap();
                let down = radiance_transmission_mueller(n1, n2, mu).unwrap();
                let up = radiance_transmission_mueller(n2, n1, t.mu_t).unwrap();
                let back = transmission(n2, n1, t.mu_t).unwrap().unwrap();
                // μ_t = √(1 − n²(1 − μ²))/…: cancellation costs ~eps/μ² at grazing μ.
                assert!((back.mu_t - mu).abs() < 1e-12);
                for i in 0..4 {
                    for j in 0..4 {
                        let a = down[i][j] * (n1 / n2).powi(2);
                        let b = up[j][i] * (n2 / n1).powi(2);
                        assert!((a - b).abs() < 1e-11, "{mu} {i}{j}: {a} vs {b}");
                    }
                }
                let unpolarized = down[0][0] * (n1 / n2).powi(2);
                assert!((unpolarized - t.transmittance(n1, n2, mu)).abs() < 1e-14);
            }
        }
    }
}
