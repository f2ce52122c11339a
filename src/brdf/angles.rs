//! Graphics angles ↔ solver quantities, written once (conventions §5).
//!
//! Graphics convention: a direction `(θ, φ)` (degrees) is the unit vector
//! `ω = (sinθ cosφ, sinθ sinφ, cosθ)` pointing **away from the surface**
//! (`z` = outward normal). The incident light travels along `k_in = −ω_i`,
//! the reflected light along `k_out = ω_o`. The solver works with cosines
//! `μ = cos θ` and the **propagation** azimuth difference
//! `Δφ_prop = (φ_o − φ_i) − 180°` (0 = forward / mirror side).

/// Smallest direction cosine evaluated: directions closer to the horizon are
/// evaluated at this cosine (conventions §5). The one definition: the table,
/// the CLI and the renderer all use it.
pub const MU_FLOOR: f64 = 1e-6;

/// A 3-vector.
pub type Vec3 = [f64; 3];

/// `μ = cos θ`, floored at [`MU_FLOOR`] (conventions §5).
pub fn mu_of_theta_deg(theta_deg: f64) -> f64 {
    theta_deg.to_radians().cos().clamp(MU_FLOOR, 1.0)
}

/// `Δφ_prop = (φ_o − φ_i) − 180°` in radians (conventions §5).
pub fn dphi_prop_rad(phi_i_deg: f64, phi_o_deg: f64) -> f64 {
    (phi_o_deg - phi_i_deg - 180.0).to_radians()
}

/// `ω = (sinθ cosφ, sinθ sinφ, cosθ)` for graphics angles in degrees.
pub fn direction(theta_deg: f64, phi_deg: f64) -> Vec3 {
    let (st, ct) = theta_deg.to_radians().sin_cos();
    let (sp, cp) = phi_deg.to_radians().sin_cos();
    [st * cp, st * sp, ct]
}

/// Graphics angles `(θ, φ)` in degrees of a direction pointing away from the
/// surface (`z ≥ 0`; it need not be normalised). `φ = atan2(y, x)` in
/// `(−180°, 180°]`, and `φ = 0` on the normal itself.
pub fn angles_of(w: Vec3) -> (f64, f64) {
    let rho = w[0].hypot(w[1]);
    let theta = rho.atan2(w[2]).to_degrees();
    let phi = if rho == 0.0 {
        0.0
    } else {
        w[1].atan2(w[0]).to_degrees()
    };
    (theta, phi)
}

/// Meridian Stokes frame `(x, y)` of the **incident** ray (conventions §5):
/// for `k_in = −ω_i`, whose own polar angle is `ϑ = 180° − θ_i` and azimuth
/// `ϕ = φ_i + 180°`, `x = e_ϑ = (cosθ_i cosφ_i, cosθ_i sinφ_i, −sinθ_i)` and
/// `y = e_ϕ = (sinφ_i, −cosφ_i, 0)`; at `θ_i = 0` this is the limit
/// `x = (cosφ_i, sinφ_i, 0)`, `y = −ẑ × x`.
pub fn incident_frame(theta_i_deg: f64, phi_i_deg: f64) -> (Vec3, Vec3) {
    let (st, ct) = theta_i_deg.to_radians().sin_cos();
    let (sp, cp) = phi_i_deg.to_radians().sin_cos();
    ([ct * cp, ct * sp, -st], [sp, -cp, 0.0])
}

/// Meridian Stokes frame `(x, y)` of the **outgoing** ray `k_out = ω_o`
/// (conventions §5): `x = e_ϑ = (cosθ_o cosφ_o, cosθ_o sinφ_o, −sinθ_o)`,
/// `y = e_ϕ = (−sinφ_o, cosφ_o, 0)`.
pub fn outgoing_frame(theta_o_deg: f64, phi_o_deg: f64) -> (Vec3, Vec3) {
    let (st, ct) = theta_o_deg.to_radians().sin_cos();
    let (sp, cp) = phi_o_deg.to_radians().sin_cos();
    ([ct * cp, ct * sp, -st], [-sp, cp, 0.0])
}

/// Dot product.
pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Cross product `a × b`.
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `a / |a|`.
pub fn normalize(a: Vec3) -> Vec3 {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

/// Angle in radians between two directions (robust for tiny angles:
/// `2 atan2(|a − b|, |a + b|)` of the normalised vectors).
pub fn angle_between(a: Vec3, b: Vec3) -> f64 {
    let (a, b) = (normalize(a), normalize(b));
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let s = [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
    2.0 * dot(d, d).sqrt().atan2(dot(s, s).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosines_are_floored_at_the_horizon_only() {
        assert_eq!(mu_of_theta_deg(90.0), MU_FLOOR);
        // Past the horizon (rounding of an input) still the floor.
        assert_eq!(mu_of_theta_deg(90.0 + 1e-9), MU_FLOOR);
        assert_eq!(mu_of_theta_deg(0.0), 1.0);
        // Just above the floor's angle the cosine itself.
        let theta = (2.0 * MU_FLOOR).acos().to_degrees();
        assert!((mu_of_theta_deg(theta) - 2.0 * MU_FLOOR).abs() < 1e-15);
        assert_eq!(dphi_prop_rad(10.0, 190.0), 0.0);
    }

    /// The frames are right-handed `(x, y, k)` with `k_in = −ω_i`,
    /// `k_out = ω_o`, and the normal-incidence limits of conventions §5.
    #[test]
    fn frames_are_right_handed_meridian_frames() {
        for (t, p) in [(0.0, 0.0), (0.0, 40.0), (30.0, 110.0), (89.0, -70.0)] {
            let w = direction(t, p);
            let (xi, yi) = incident_frame(t, p);
            let k_in = [-w[0], -w[1], -w[2]];
            let c = cross(xi, yi);
            for a in 0..3 {
                assert!((c[a] - k_in[a]).abs() < 1e-15, "{t} {p}");
            }
            // x lies in the meridian plane (contains z and k).
            assert!(dot(cross([0.0, 0.0, 1.0], k_in), xi).abs() < 1e-15);
            let (xo, yo) = outgoing_frame(t, p);
            let c = cross(xo, yo);
            for a in 0..3 {
                assert!((c[a] - w[a]).abs() < 1e-15);
            }
        }
        let (x, y) = incident_frame(0.0, 30.0);
        let (s, c) = 30f64.to_radians().sin_cos();
        let minus_z_cross_x = [s, -c, 0.0];
        for a in 0..3 {
            assert!((x[a] - [c, s, 0.0][a]).abs() < 1e-15);
            assert!((y[a] - minus_z_cross_x[a]).abs() < 1e-15);
        }
    }

    #[test]
    fn angles_round_trip() {
        for (t, p) in [(0.0, 0.0), (12.0, 170.0), (60.0, -45.0), (90.0, 90.0)] {
            let (t2, p2) = angles_of(direction(t, p));
            assert!(
                (t2 - t).abs() < 1e-12 && (p2 - p).abs() < 1e-12,
                "{t2} {p2}"
            );
        }
        assert!((angle_between(direction(10.0, 0.0), direction(10.0, 1e-9)) - 0.0).abs() < 1e-10);
    }
}
