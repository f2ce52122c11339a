//! Stokes reference frames along rays and the polarizing elements of the
//! renderer (docs/render.md, "Stokes frames"; conventions §5).
//!
//! A Stokes vector travelling along the unit vector `k` is referred to a
//! right-handed frame `(x, y = k × x, k)`; only `x` is carried (a unit
//! vector perpendicular to `k`). Re-expressing it in a frame with x-axis
//! `x'` turned by `σ` from `x` towards `y` is conventions §5's rotation
//!
//! ```text
//! s' = L(σ) s,   σ = atan2(x'·y, x'·x),   y = k × x                        (R1)
//! ```
//!
//! (the seed's eq. 2 with the sign of conventions §5).

use super::geometry::{Vec3, cross, dot, normalize, reject};
use crate::physics::stokes::{Mueller, apply, rotation};

/// A Stokes vector `[I, Q, U, V]`.
pub type Stokes = [f64; 4];

/// Smallest `|reference ⟂ k|` for which the projection of a reference
/// vector defines a frame axis (else the fallback axis is used).
const DEGENERATE: f64 = 1e-9;

/// The x-axis of the Stokes frame of a ray along `k` given by a reference
/// vector: `reference` projected perpendicular to `k`, normalised. When
/// `reference` is (anti)parallel to `k` the world axis least aligned with `k`
/// is projected instead, so every direction gets a frame.
pub fn frame_x_from(k: Vec3, reference: Vec3) -> Vec3 {
    let r = reject(reference, k);
    if dot(r, r).sqrt() > DEGENERATE * dot(reference, reference).sqrt() {
        return normalize(r);
    }
    let axis = if k[0].abs() <= k[1].abs() && k[0].abs() <= k[2].abs() {
        [1.0, 0.0, 0.0]
    } else if k[1].abs() <= k[2].abs() {
        [0.0, 1.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    normalize(reject(axis, k))
}

/// Angle `σ` (radians) of (R1) turning the frame with x-axis `from_x`
/// into the one with x-axis `to_x`, both perpendicular to `k`.
pub fn frame_angle(k: Vec3, from_x: Vec3, to_x: Vec3) -> f64 {
    let y = cross(k, from_x);
    dot(to_x, y).atan2(dot(to_x, from_x))
}

/// `s` re-expressed from the frame with x-axis `from_x` to the one with
/// x-axis `to_x` (both perpendicular to the propagation direction `k`), (R1).
pub fn rotate_stokes(s: Stokes, k: Vec3, from_x: Vec3, to_x: Vec3) -> Stokes {
    if s[1] == 0.0 && s[2] == 0.0 {
        return s;
    }
    apply(&rotation(frame_angle(k, from_x, to_x)), s)
}

/// Ideal linear polarizer with its transmission axis at `angle_rad` from
/// the frame's `x` towards `y`:
///
/// ```text
///              | 1    c    s    0 |
/// P(a) = (1/2) | c    c²   cs   0 |,   c = cos 2a,  s = sin 2a
///              | s    cs   s²   0 |
///              | 0    0    0    0 |
/// ```
///
/// (Bass et al., Handbook of Optics vol. 2, ch. 22; seed ref. 4). On a beam
/// fully linearly polarized at `b`, `(1, cos 2b, sin 2b, 0)`, it transmits
/// `I = (1 + cos 2(a − b))/2 = cos²(a − b)` (Malus' law).
pub fn linear_polarizer(angle_rad: f64) -> Mueller {
    let (s, c) = (2.0 * angle_rad).sin_cos();
    [
        [0.5, 0.5 * c, 0.5 * s, 0.0],
        [0.5 * c, 0.5 * c * c, 0.5 * c * s, 0.0],
        [0.5 * s, 0.5 * c * s, 0.5 * s * s, 0.0],
        [0.0, 0.0, 0.0, 0.0],
    ]
}

/// Validate a Stokes vector of a source: finite, `I ≥ 0` and
/// `I ≥ √(Q² + U² + V²)` (up to 1e-12 relative), i.e. physically realizable.
pub fn check_stokes(s: Stokes) -> Result<(), String> {
    if s.iter().any(|x| !x.is_finite()) {
        return Err(format!("{s:?} is not finite"));
    }
    let p = (s[1] * s[1] + s[2] * s[2] + s[3] * s[3]).sqrt();
    if s[0] < 0.0 || p > s[0] * (1.0 + 1e-12) {
        return Err(format!(
            "{s:?} is not a physical Stokes vector (needs I >= sqrt(Q^2 + U^2 + V^2) >= 0)"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::stokes::{degree_of_polarization, mul};

    fn close(a: Stokes, b: Stokes, tol: f64) -> bool {
        a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= tol)
    }

    /// `L(σ₁) L(σ₂) = L(σ₁ + σ₂)`, `L(π) = 1`, rotations keep `I`, `V` and
    /// the degree of polarization.
    #[test]
    fn rotation_identities() {
        let s = [1.0, 0.3, -0.5, 0.2];
        for (a, b) in [(0.3, 0.9), (-1.2, 2.0), (0.0, std::f64::consts::PI)] {
            let ab = mul(&rotation(a), &rotation(b));
            let direct = rotation(a + b);
            for i in 0..4 {
                for j in 0..4 {
                    assert!((ab[i][j] - direct[i][j]).abs() < 1e-15);
                }
            }
            let r = apply(&rotation(a), s);
            assert_eq!((r[0], r[3]), (s[0], s[3]));
            assert!((degree_of_polarization(r) - degree_of_polarization(s)).abs() < 1e-15);
        }
        let pi = apply(&rotation(std::f64::consts::PI), s);
        assert!(close(pi, s, 1e-15));
    }

    /// A beam polarized along the old `x` is, in a frame turned by `σ`, at
    /// angle `−σ`: `(1, cos 2σ, −sin 2σ, 0)`; rotating there and back is the
    /// identity; the frame angle follows from the axes.
    #[test]
    fn frame_rotation_describes_the_same_beam() {
        let k = normalize([0.2, -0.3, 0.9]);
        let x = frame_x_from(k, [0.0, 0.0, 1.0]);
        let y = cross(k, x);
        let sig = 0.7f64;
        let x2 = normalize([
            sig.cos() * x[0] + sig.sin() * y[0],
            sig.cos() * x[1] + sig.sin() * y[1],
            sig.cos() * x[2] + sig.sin() * y[2],
        ]);
        assert!((frame_angle(k, x, x2) - sig).abs() < 1e-14);
        let s = rotate_stokes([1.0, 1.0, 0.0, 0.0], k, x, x2);
        assert!(close(
            s,
            [1.0, (2.0 * sig).cos(), -(2.0 * sig).sin(), 0.0],
            1e-14
        ));
        let t = [2.0, 0.4, -0.9, 0.3];
        let back = rotate_stokes(rotate_stokes(t, k, x, x2), k, x2, x);
        assert!(close(back, t, 1e-14));
        // x and −x are the same frame for Stokes vectors.
        let flipped = rotate_stokes(t, k, x, [-x[0], -x[1], -x[2]]);
        assert!(close(flipped, t, 1e-14));
    }

    /// Malus' law: a polarizer at `a` on a beam fully linearly polarized at
    /// `b` transmits `cos²(a − b)`, fully polarized along `a`; unpolarized
    /// light loses half; crossed polarizers transmit nothing.
    #[test]
    fn malus_law() {
        for b in [0.0f64, 0.4, 1.3, -2.0] {
            let beam = [1.0, (2.0 * b).cos(), (2.0 * b).sin(), 0.0];
            for a in [0.0f64, 0.25, 1.0, 2.9] {
                let out = apply(&linear_polarizer(a), beam);
                assert!((out[0] - (a - b).cos().powi(2)).abs() < 1e-15, "{a} {b}");
                if out[0] > 1e-6 {
                    let expect = [
                        out[0],
                        out[0] * (2.0 * a).cos(),
                        out[0] * (2.0 * a).sin(),
                        0.0,
                    ];
                    assert!(close(out, expect, 1e-14));
                }
            }
        }
        let un = apply(&linear_polarizer(0.3), [1.0, 0.0, 0.0, 0.0]);
        assert!((un[0] - 0.5).abs() < 1e-15);
        let crossed = mul(
            &linear_polarizer(0.3),
            &linear_polarizer(0.3 + std::f64::consts::FRAC_PI_2),
        );
        assert!(crossed.iter().flatten().all(|x| x.abs() < 1e-15));
        // Circular light: half passes whatever the angle.
        let c = apply(&linear_polarizer(1.1), [1.0, 0.0, 0.0, 1.0]);
        assert!((c[0] - 0.5).abs() < 1e-15);
    }

    #[test]
    fn frames_exist_for_every_direction() {
        for k in [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            normalize([1.0, 1.0, 0.0]),
        ] {
            let x = frame_x_from(k, [0.0, 0.0, 1.0]);
            assert!(dot(x, k).abs() < 1e-15 && (dot(x, x) - 1.0).abs() < 1e-15);
        }
        assert!(check_stokes([1.0, 0.6, 0.8, 0.0]).is_ok());
        assert!(check_stokes([1.0, 0.6, 0.8, 0.1]).is_err());
        assert!(check_stokes([-1.0, 0.0, 0.0, 0.0]).is_err());
    }
}
