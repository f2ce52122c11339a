//! Local shading frame: evaluation from unit vectors and re-expression of a
//! Mueller BRDF in caller-supplied Stokes reference frames (conventions §5).
//!
//! A renderer works in a local frame with `z` = the surface normal and both
//! directions pointing away from the surface (`ω_i` towards the light,
//! `ω_o` towards the viewer). [`Table::eval_vectors`] returns the BRDF in the
//! meridian frames of conventions §5; [`rotate_to_frames`] turns the
//! incident and outgoing Stokes frames about their propagation directions
//! `k_in = −ω_i`, `k_out = ω_o`:
//!
//! ```text
//! M' = L(σ_out) · M · L(−σ_in),   σ = atan2(x'·y, x'·x)            (F1)
//! ```
//!
//! with `(x, y)` the meridian frame of the ray, `x'` the new x-axis and
//! `L(σ)` the rotation of conventions §5 (`s_new = L(σ) s_old` for a frame
//! turned by `σ` from `x` towards `y`): incident Stokes vectors given in the
//! new frame are first taken back to the meridian frame (`L(−σ_in)`), the
//! result is taken to the new outgoing frame (`L(σ_out)`).

use super::BrdfError;
use super::angles::{Vec3, angles_of, cross, dot, incident_frame, normalize, outgoing_frame};
use super::table::{Directions, Table};
use crate::physics::stokes::{Mueller, mul, rotation};

/// Tolerance on `|x̂·k̂|` for a caller-supplied x-axis to count as
/// perpendicular to the propagation direction.
pub const PERPENDICULAR_TOLERANCE: f64 = 1e-6;

/// Graphics angles of a direction pair given as vectors pointing away from
/// the surface (`z ≥ 0`, any length > 0). On the normal `φ = 0`, so the
/// meridian frame there is the `θ → 0` limit at `φ = 0`: `x = (1, 0, 0)`.
pub fn directions_of_vectors(wi: Vec3, wo: Vec3) -> Result<Directions, BrdfError> {
    for (name, w) in [("wi", wi), ("wo", wo)] {
        let n2 = dot(w, w);
        if !(n2.is_finite() && n2 > 0.0) || w[2] < -1e-12 * n2.sqrt() {
            return Err(BrdfError::Query(format!(
                "{name} = {w:?} must be a non-zero vector with z ≥ 0 (pointing away from the surface)"
            )));
        }
    }
    let (theta_i_deg, phi_i_deg) = angles_of(wi);
    let (theta_o_deg, phi_o_deg) = angles_of(wo);
    Ok(Directions {
        theta_i_deg: theta_i_deg.min(90.0),
        phi_i_deg,
        theta_o_deg: theta_o_deg.min(90.0),
        phi_o_deg,
    })
}

/// The rotation angle `σ = atan2(x'·y, x'·x)` taking the frame `(x, y, k)`
/// to one with x-axis `x'` (which must be perpendicular to `k`).
fn frame_angle(x: Vec3, y: Vec3, k: Vec3, new_x: Vec3, name: &str) -> Result<f64, BrdfError> {
    let n2 = dot(new_x, new_x);
    if !(n2.is_finite() && n2 > 0.0) {
        return Err(BrdfError::Query(format!(
            "{name} = {new_x:?} is not a direction"
        )));
    }
    let nx = normalize(new_x);
    let along = dot(nx, normalize(k));
    if along.abs() > PERPENDICULAR_TOLERANCE {
        return Err(BrdfError::Query(format!(
            "{name} is not perpendicular to its propagation direction (cosine {along:e})"
        )));
    }
    Ok(dot(nx, y).atan2(dot(nx, x)))
}

/// Re-express a Mueller BRDF `m` given in the meridian frames of
/// conventions §5 (as returned by [`Table::eval_vectors`] for `wi`, `wo`) in
/// the frames with x-axes `x_in` (perpendicular to `k_in = −ω_i`) and
/// `x_out` (perpendicular to `k_out = ω_o`), by (F1); the y-axes complete
/// right-handed frames `y = k × x`.
pub fn rotate_to_frames(
    m: &Mueller,
    wi: Vec3,
    wo: Vec3,
    x_in: Vec3,
    x_out: Vec3,
) -> Result<Mueller, BrdfError> {
    let d = directions_of_vectors(wi, wo)?;
    let (xi, yi) = incident_frame(d.theta_i_deg, d.phi_i_deg);
    let (xo, yo) = outgoing_frame(d.theta_o_deg, d.phi_o_deg);
    let k_in = cross(xi, yi);
    let k_out = cross(xo, yo);
    let s_in = frame_angle(xi, yi, k_in, x_in, "x_in")?;
    let s_out = frame_angle(xo, yo, k_out, x_out, "x_out")?;
    Ok(mul(&mul(&rotation(s_out), m), &rotation(-s_in)))
}

impl Table {
    /// The diffuse Mueller BRDF for unit vectors in the local shading frame
    /// (`z` = normal, both pointing away from the surface), in the meridian
    /// frames of conventions §5: incident ray `k = −ω_i`, outgoing `k = ω_o`
    /// (use [`rotate_to_frames`] for other frames).
    pub fn eval_vectors(
        &self,
        wi: Vec3,
        wo: Vec3,
        wavelength_nm: Option<f64>,
    ) -> Result<Mueller, BrdfError> {
        self.eval(&directions_of_vectors(wi, wo)?, wavelength_nm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::angles::direction;

    fn some_mueller() -> Mueller {
        let mut m = [[0.0; 4]; 4];
        for (i, row) in m.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                *x = 0.1 + 0.37 * i as f64 - 0.21 * j as f64 + 0.05 * (i * j) as f64;
            }
        }
        m
    }

    /// Hand-computed: turning the outgoing frame by 30° (from `e_ϑ` towards
    /// `e_ϕ`) and the incident frame by −50° gives
    /// `L(30°) M L(+50°)`, with `L` written out element by element.
    #[test]
    fn rotation_by_hand() {
        let (ti, pi, to, po) = (35.0, 20.0, 60.0, 250.0);
        let wi = direction(ti, pi);
        let wo = direction(to, po);
        let (xi, yi) = incident_frame(ti, pi);
        let (xo, yo) = outgoing_frame(to, po);
        let r = |x: Vec3, y: Vec3, deg: f64| {
            let (s, c) = deg.to_radians().sin_cos();
            [
                c * x[0] + s * y[0],
                c * x[1] + s * y[1],
                c * x[2] + s * y[2],
            ]
        };
        let m = some_mueller();
        let got = rotate_to_frames(&m, wi, wo, r(xi, yi, -50.0), r(xo, yo, 30.0)).unwrap();
        // L(σ) by hand: cos 2σ, sin 2σ at σ = 30° and σ = +50° (= −(−50°)).
        let (c60, s60) = (0.5, 3f64.sqrt() / 2.0);
        let (c100, s100) = (100f64.to_radians().cos(), 100f64.to_radians().sin());
        let l_out = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, c60, s60, 0.0],
            [0.0, -s60, c60, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let l_in = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, c100, s100, 0.0],
            [0.0, -s100, c100, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let expect = mul(&mul(&l_out, &m), &l_in);
        for i in 0..4 {
            for j in 0..4 {
                assert!((got[i][j] - expect[i][j]).abs() < 1e-14, "{i}{j}");
            }
        }
        // A frame turned by 90° flips Q and U: L(90°) = diag(1, −1, −1, 1).
        let got = rotate_to_frames(&m, wi, wo, xi, yo).unwrap();
        for i in 0..4 {
            for j in 0..4 {
                let sign = if i == 1 || i == 2 { -1.0 } else { 1.0 };
                assert!((got[i][j] - sign * m[i][j]).abs() < 1e-14);
            }
        }
        // Not perpendicular: an error.
        assert!(rotate_to_frames(&m, wi, wo, wi, xo).is_err());
    }

    /// Physical check of the sign: a beam linearly polarized along the new
    /// incident x-axis is, in the meridian frame, at angle σ_in from `x`
    /// towards `y`: its Stokes vector there is `(1, cos 2σ, sin 2σ, 0)`.
    #[test]
    fn rotated_frames_describe_the_same_light() {
        let (ti, pi, to, po) = (50.0, -30.0, 20.0, 80.0);
        let (wi, wo) = (direction(ti, pi), direction(to, po));
        let (xi, yi) = incident_frame(ti, pi);
        let (xo, _) = outgoing_frame(to, po);
        let sig = 0.4f64;
        let new_x = [
            sig.cos() * xi[0] + sig.sin() * yi[0],
            sig.cos() * xi[1] + sig.sin() * yi[1],
            sig.cos() * xi[2] + sig.sin() * yi[2],
        ];
        let m = some_mueller();
        let r = rotate_to_frames(&m, wi, wo, new_x, xo).unwrap();
        let in_new = [1.0, 1.0, 0.0, 0.0];
        let in_meridian = [1.0, (2.0 * sig).cos(), (2.0 * sig).sin(), 0.0];
        let a = crate::physics::stokes::apply(&r, in_new);
        let b = crate::physics::stokes::apply(&m, in_meridian);
        for k in 0..4 {
            assert!((a[k] - b[k]).abs() < 1e-14);
        }
    }
}
