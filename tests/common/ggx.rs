//! The GGX microfacet reflection of a dielectric, written out from Walter
//! et al. (2007) and Heitz (2014) in graphics angles, independently of
//! `physics::microfacet` (tests/rough_base.rs, tests/rough_interface.rs).

use std::f64::consts::PI;

/// Air over a dielectric of real index `n` at local incidence cosine `c`:
/// `(r_p, r_s)` in the signs of conventions §5 (Born & Wolf).
pub fn rp_rs(n: f64, c: f64) -> (f64, f64) {
    let w = (n * n - 1.0 + c * c).sqrt();
    ((n * n * c - w) / (n * n * c + w), (c - w) / (c + w))
}

/// The unit vector at graphics polar angle `theta_deg` and azimuth
/// `phi_deg` (pointing away from the surface).
pub fn dir(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

/// `D(h) G₂ / (4 cosθ_i cosθ_o)` of isotropic GGX with height-correlated
/// Smith shadowing, and the local cosine `ω_i·h`.
pub fn ggx(alpha: f64, wi: [f64; 3], wo: [f64; 3]) -> (f64, f64) {
    let h: Vec<f64> = (0..3).map(|k| wi[k] + wo[k]).collect();
    let len = h.iter().map(|x| x * x).sum::<f64>().sqrt();
    let h: Vec<f64> = h.iter().map(|x| x / len).collect();
    let a2 = alpha * alpha;
    let c2 = h[2] * h[2];
    let d = a2 / (PI * (c2 * (a2 - 1.0) + 1.0).powi(2));
    let lambda = |mu: f64| 0.5 * ((1.0 + a2 * (1.0 - mu * mu) / (mu * mu)).sqrt() - 1.0);
    let g = 1.0 / (1.0 + lambda(wi[2]) + lambda(wo[2]));
    let cd = (0..3).map(|k| wi[k] * h[k]).sum::<f64>();
    (d * g / (4.0 * wi[2] * wo[2]), cd)
}
