//! Small vector kernels and ray–primitive intersections of the preview
//! renderer. Vectors are `brdf::angles::Vec3` (`[f64; 3]`); directions are
//! unit vectors unless a name says otherwise.

pub use crate::brdf::angles::{Vec3, cross, dot, normalize};

/// `a + b`.
pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a − b`.
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `s a`.
pub fn scale(a: Vec3, s: f64) -> Vec3 {
    [s * a[0], s * a[1], s * a[2]]
}

/// `a + t b` (a point along a ray).
pub fn madd(a: Vec3, b: Vec3, t: f64) -> Vec3 {
    [a[0] + t * b[0], a[1] + t * b[1], a[2] + t * b[2]]
}

/// `−a`.
pub fn neg(a: Vec3) -> Vec3 {
    [-a[0], -a[1], -a[2]]
}

/// Euclidean length `|a|`.
pub fn length(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}

/// The part of `v` perpendicular to the unit vector `k`: `v − (v·k) k`.
pub fn reject(v: Vec3, k: Vec3) -> Vec3 {
    madd(v, k, -dot(v, k))
}

/// A right-handed orthonormal basis `(t, b, n)` around the unit normal `n`
/// (`t × b = n`), branch-free and continuous except across `n_z = 0⁻/0⁺`
/// (Duff et al. 2017, "Building an orthonormal basis, revisited", listing 3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Basis {
    /// First tangent.
    pub t: Vec3,
    /// Second tangent, `n × t`.
    pub b: Vec3,
    /// The normal.
    pub n: Vec3,
}

impl Basis {
    /// The basis around `n` (unit length).
    pub fn around(n: Vec3) -> Self {
        let sign = 1f64.copysign(n[2]);
        let a = -1.0 / (sign + n[2]);
        let b = n[0] * n[1] * a;
        Self {
            t: [1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]],
            b: [b, sign + n[1] * n[1] * a, -n[1]],
            n,
        }
    }

    /// World vector → local coordinates `(v·t, v·b, v·n)`.
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        [dot(v, self.t), dot(v, self.b), dot(v, self.n)]
    }

    /// Local coordinates → world vector.
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        let w = madd(scale(self.t, v[0]), self.b, v[1]);
        madd(w, self.n, v[2])
    }
}

/// Nearest intersection distance `t ∈ (t_min, t_max)` of the ray
/// `o + t d` (`d` unit) with the sphere `|x − c| = r`, from
/// `t² + 2 b t + c' = 0`, `b = (o − c)·d`, `c' = |o − c|² − r²`, the root
/// of smaller magnitude taken as `c'/q` with `q = −b − sign(b) √(b² − c')`
/// to avoid cancellation (Press et al., Numerical Recipes §5.6).
pub fn hit_sphere(
    o: Vec3,
    d: Vec3,
    center: Vec3,
    radius: f64,
    t_min: f64,
    t_max: f64,
) -> Option<f64> {
    let oc = sub(o, center);
    let b = dot(oc, d);
    let c = dot(oc, oc) - radius * radius;
    let disc = b * b - c;
    if disc < 0.0 {
        return None;
    }
    let q = -b - disc.sqrt().copysign(b);
    let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q) };
    let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    [near, far].into_iter().find(|&t| t > t_min && t < t_max)
}

/// Intersection distance `t ∈ (t_min, t_max)` of the ray `o + t d` with
/// the plane through `p` with normal `n`: `t = (p − o)·n / (d·n)`; either
/// side of the plane counts.
pub fn hit_plane(o: Vec3, d: Vec3, p: Vec3, n: Vec3, t_min: f64, t_max: f64) -> Option<f64> {
    let dn = dot(d, n);
    if dn == 0.0 {
        return None;
    }
    let t = dot(sub(p, o), n) / dn;
    (t > t_min && t < t_max).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_is_right_handed_and_orthonormal() {
        for n in [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            normalize([0.3, -0.4, 0.8]),
            normalize([0.9, 0.1, -0.05]),
            [1.0, 0.0, 0.0],
        ] {
            let f = Basis::around(n);
            let c = cross(f.t, f.b);
            for a in 0..3 {
                assert!((c[a] - n[a]).abs() < 1e-15, "{n:?}");
            }
            assert!(dot(f.t, f.b).abs() < 1e-15);
            assert!((dot(f.t, f.t) - 1.0).abs() < 1e-15);
            assert!((dot(f.b, f.b) - 1.0).abs() < 1e-15);
            let v = [0.2, -0.7, 0.4];
            let back = f.to_world(f.to_local(v));
            for a in 0..3 {
                assert!((back[a] - v[a]).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn sphere_and_plane_hits() {
        let t = hit_sphere(
            [0.0, 0.0, -5.0],
            [0.0, 0.0, 1.0],
            [0.0; 3],
            1.0,
            1e-9,
            f64::INFINITY,
        );
        assert_eq!(t, Some(4.0));
        // From inside: the far root.
        let t = hit_sphere(
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [0.0; 3],
            2.0,
            1e-9,
            f64::INFINITY,
        );
        assert_eq!(t, Some(2.0));
        assert!(hit_sphere([0.0, 3.0, -5.0], [0.0, 0.0, 1.0], [0.0; 3], 1.0, 1e-9, 1e9).is_none());
        // Behind t_max.
        assert!(hit_sphere([0.0, 0.0, -5.0], [0.0, 0.0, 1.0], [0.0; 3], 1.0, 1e-9, 3.0).is_none());
        let t = hit_plane(
            [0.0, 0.0, 2.0],
            normalize([1.0, 0.0, -1.0]),
            [0.0; 3],
            [0.0, 0.0, 1.0],
            1e-9,
            1e9,
        );
        assert!((t.unwrap() - 2.0 * 2f64.sqrt()).abs() < 1e-14);
        assert!(
            hit_plane(
                [0.0, 0.0, 2.0],
                [1.0, 0.0, 0.0],
                [0.0; 3],
                [0.0, 0.0, 1.0],
                0.0,
                1e9
            )
            .is_none()
        );
    }
}
