//! Phase matrix of a layer: the geometric form (seed eq. 11) and its Fourier
//! components in azimuth from the Greek coefficients (seed eq. 19–23,
//! Siewert 2000 eq. 10–17).
//!
//! Directions are given by `nu`, the cosine of the polar angle of the
//! **propagation** direction measured from the outward normal `+z`
//! (`nu > 0` travels up, out of the material), and by the propagation azimuth.
//! Stokes vectors refer to the meridian frames of conventions §5.
//!
//! ## Fourier representation used by the solver
//! For azimuth order `m` the solver works with the "S1" set of Fourier
//! components `x = (I^c, Q^c, U^s, V^s)` (cosine terms of I, Q and sine terms of
//! U, V). Integrating `Z(φ − φ')` against `cos mφ'` / `sin mφ'` maps this set
//! onto itself with the kernel `2π A^m(ν, ν')`, where
//! `A^m(ν, ν') = Σ_l P_l^m(ν) B_l P_l^m(ν')` (seed eq. 21). The other set
//! `(I^s, Q^s, U^c, V^c)` obeys the same equations with `D A^m D`,
//! `D = diag(1, 1, −1, −1)`, so one solve per order serves all four incident
//! Stokes states. The phase matrix itself is
//! `Z(Δφ) = Σ_m (2 − δ_m0) [bd(A^m) cos mΔφ + od(A^m) sin mΔφ]` where `bd`
//! keeps the IQ/IQ and UV/UV blocks and `od(A)` is `A` restricted to the
//! off-diagonal blocks with the IQ/UV block negated.

use crate::physics::expansion::GreekCoefficients;
use crate::physics::stokes::Mueller;
use crate::physics::wigner::wigner_d_into;

/// Generalized spherical functions of one direction for one Fourier order:
/// `p[l] = P_l^m(ν)`, `r[l] = R_l^m(ν)`, `t[l] = T_l^m(ν)` (seed eq. 23), for
/// `l = 0..=l_max`.
#[derive(Clone, Debug)]
pub struct Gsf {
    /// `P_l^m`: normalised associated Legendre function, `d^l_{m0}` up to sign.
    pub p: Vec<f64>,
    /// `R_l^m = ½ (d^l_{m2} + d^l_{m,−2})` up to sign.
    pub r: Vec<f64>,
    /// `T_l^m = ½ (d^l_{m2} − d^l_{m,−2})` up to sign.
    pub t: Vec<f64>,
}

impl Gsf {
    /// Evaluate at direction cosine `nu` for order `m`, `l = 0..=l_max`.
    ///
    /// In terms of Wigner's d-functions at `θ = arccos ν`:
    /// `P_l^m = d^l_{m0}`, `R_l^m = ½ (d^l_{m2} + d^l_{m,−2})`,
    /// `T_l^m = ½ (d^l_{m2} − d^l_{m,−2})`; these signs are the ones for which
    /// the Fourier sum reproduces the geometric phase matrix in our frames
    /// (unit test `fourier_sum_matches_geometric_phase_matrix`).
    pub fn new(m: usize, nu: f64, l_max: usize, polarized: bool) -> Self {
        let mut p = vec![0.0; l_max + 1];
        let mi = m as i32;
        wigner_d_into(mi, 0, nu, &mut p);
        if !polarized {
            return Self {
                p,
                r: Vec::new(),
                t: Vec::new(),
            };
        }
        let mut dp = vec![0.0; l_max + 1];
        let mut dm = vec![0.0; l_max + 1];
        wigner_d_into(mi, 2, nu, &mut dp);
        wigner_d_into(mi, -2, nu, &mut dm);
        let r = dp.iter().zip(&dm).map(|(a, b)| 0.5 * (a + b)).collect();
        let t = dp.iter().zip(&dm).map(|(a, b)| 0.5 * (a - b)).collect();
        Self { p, r, t }
    }
}

/// `A^m(ν, ν') = Σ_{l=m}^{L} P_l^m(ν) B_l P_l^m(ν')` (seed eq. 21) as a 4×4
/// matrix (or its (1,1) element in the scalar case, returned in `[0][0]`).
///
/// With `P = [[p,0,0,0],[0,r,−t,0],[0,−t,r,0],[0,0,0,p]]` the product expands
/// to the sums below (written out so that each `l` costs a few multiply-adds).
/// `B_l` is seed eq. 22 as printed (Siewert 2000 eq. 17), lower block
/// `[[ζ, −ε], [ε, δ]]`; with `P_l^m = d^l_{m0}` it reproduces
/// `F34 = b2 = −Σ ε_l d^l_02` (conventions §4) in our frames. The test
/// `fourier_sum_matches_geometric_phase_matrix` pins every sign against the
/// geometric phase matrix.
pub fn a_matrix(coef: &GreekCoefficients, m: usize, a: &Gsf, b: &Gsf, polarized: bool) -> Mueller {
    let mut out = [[0.0; 4]; 4];
    let l_max = coef.beta.len().min(a.p.len());
    if !polarized {
        let mut s = 0.0;
        for l in m..l_max {
            s += a.p[l] * coef.beta[l] * b.p[l];
        }
        out[0][0] = s;
        return out;
    }
    for l in m..l_max {
        let (p, r, t) = (a.p[l], a.r[l], a.t[l]);
        let (q, s, u) = (b.p[l], b.r[l], b.t[l]);
        let (be, al, ze, de, ga, ep) = (
            coef.beta[l],
            coef.alpha[l],
            coef.zeta[l],
            coef.delta[l],
            coef.gamma[l],
            coef.epsilon[l],
        );
        out[0][0] += p * be * q;
        out[0][1] += p * ga * s;
        out[0][2] -= p * ga * u;
        out[1][0] += r * ga * q;
        out[1][1] += r * al * s + t * ze * u;
        out[1][2] -= r * al * u + t * ze * s;
        out[1][3] += t * ep * q;
        out[2][0] -= t * ga * q;
        out[2][1] -= t * al * s + r * ze * u;
        out[2][2] += t * al * u + r * ze * s;
        out[2][3] -= r * ep * q;
        out[3][1] -= p * ep * u;
        out[3][2] += p * ep * s;
        out[3][3] += p * de * q;
    }
    out
}

/// Unit propagation vector for cosine `nu` (from +z) and azimuth `phi_rad`.
fn direction(nu: f64, phi_rad: f64) -> [f64; 3] {
    let s = (1.0 - nu * nu).max(0.0).sqrt();
    [s * phi_rad.cos(), s * phi_rad.sin(), nu]
}

/// Meridian frame `(e_ϑ, e_ϕ)` of a propagation direction (conventions §5).
fn meridian_frame(nu: f64, phi_rad: f64) -> ([f64; 3], [f64; 3]) {
    let s = (1.0 - nu * nu).max(0.0).sqrt();
    let (sp, cp) = phi_rad.sin_cos();
    ([nu * cp, nu * sp, -s], [-sp, cp, 0.0])
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `(cos 2σ, sin 2σ)` of the angle from the meridian `x` axis of direction `k`
/// to the scattering-plane `x` axis `n × k` (rotation about `k`, from `x`
/// towards `y`).
fn rotation_to_scattering_plane(k: [f64; 3], nu: f64, phi: f64, n: [f64; 3]) -> (f64, f64) {
    let (ex, ey) = meridian_frame(nu, phi);
    let xs = cross(n, k);
    let c = dot(ex, xs);
    let s = dot(ey, xs);
    let norm = c * c + s * s;
    ((c * c - s * s) / norm, 2.0 * c * s / norm)
}

/// Rotation of the Stokes reference frame by `σ` given `(cos 2σ, sin 2σ)`
/// (conventions §5): `L(σ)`.
fn rot(c2: f64, s2: f64) -> Mueller {
    [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, c2, s2, 0.0],
        [0.0, -s2, c2, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

fn mul(a: &Mueller, b: &Mueller) -> Mueller {
    let mut o = [[0.0; 4]; 4];
    for i in 0..4 {
        for k in 0..4 {
            let aik = a[i][k];
            if aik == 0.0 {
                continue;
            }
            for j in 0..4 {
                o[i][j] += aik * b[k][j];
            }
        }
    }
    o
}

/// The phase matrix `Z` (seed eq. 11) from the scattering matrix
/// `F(Θ)` (conventions §3) for incident propagation direction
/// `(nu_in, phi_in)` and scattered `(nu_out, phi_out)`, both in meridian
/// frames: `Z = L(−σ_out) F(Θ) L(σ_in)` where `σ_in` turns the incident meridian
/// frame into the scattering-plane frame and `σ_out` does the same for the
/// scattered ray. The scattering-plane normal is `n = k_in × k_out`; in the
/// forward and backward directions any `n ⟂ k_in` gives the same result.
///
/// `f` maps `cos Θ` to `[a1, a2, a3, a4, b1, b2]`.
pub fn geometric_phase_matrix(
    f: &dyn Fn(f64) -> [f64; 6],
    nu_in: f64,
    phi_in: f64,
    nu_out: f64,
    phi_out: f64,
) -> Mueller {
    let ki = direction(nu_in, phi_in);
    let ko = direction(nu_out, phi_out);
    let cos_theta = dot(ki, ko).clamp(-1.0, 1.0);
    let mut n = cross(ki, ko);
    if dot(n, n) < 1e-24 {
        // Forward/backward: any normal to k_in.
        let (ex, _) = meridian_frame(nu_in, phi_in);
        n = cross(ki, ex);
    }
    let [a1, a2, a3, a4, b1, b2] = f(cos_theta);
    let fm: Mueller = [
        [a1, b1, 0.0, 0.0],
        [b1, a2, 0.0, 0.0],
        [0.0, 0.0, a3, b2],
        [0.0, 0.0, -b2, a4],
    ];
    let (c_in, s_in) = rotation_to_scattering_plane(ki, nu_in, phi_in, n);
    let (c_out, s_out) = rotation_to_scattering_plane(ko, nu_out, phi_out, n);
    // L(−σ_out) has cos 2σ unchanged and sin 2σ negated.
    mul(&rot(c_out, -s_out), &mul(&fm, &rot(c_in, s_in)))
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::physics::expansion::test_data::garcia_siewert;

    /// The Fourier sum `Σ_m (2 − δ_m0)[bd(A^m) cos mΔφ + od(A^m) sin mΔφ]`
    /// equals the geometric phase matrix built from the summed scattering
    /// matrix, element by element, for generic directions (seed eq. 11 vs 14, 19–23).
    #[test]
    fn fourier_sum_matches_geometric_phase_matrix() {
        let coef = garcia_siewert();
        let l_max = coef.beta.len() - 1;
        let f = |mu: f64| {
            let s = coef.evaluate(&[mu]);
            [s.a1[0], s.a2[0], s.a3[0], s.a4[0], s.b1[0], s.b2[0]]
        };
        let dirs = [
            (0.3, 0.0),
            (-0.7, 0.4),
            (0.95, 2.0),
            (-0.2, -1.3),
            (0.55, 3.0),
        ];
        let mut worst: f64 = 0.0;
        for &(nu_i, phi_i) in &dirs {
            for &(nu_o, phi_o) in &dirs {
                let zg = geometric_phase_matrix(&f, nu_i, phi_i, nu_o, phi_o + 0.17);
                let dphi: f64 = phi_o + 0.17 - phi_i;
                let mut zf = [[0.0; 4]; 4];
                for m in 0..=l_max {
                    let gi = Gsf::new(m, nu_i, l_max, true);
                    let go = Gsf::new(m, nu_o, l_max, true);
                    let a = a_matrix(&coef, m, &go, &gi, true);
                    let w = if m == 0 { 1.0 } else { 2.0 };
                    let (s, c) = (m as f64 * dphi).sin_cos();
                    for i in 0..4 {
                        for j in 0..4 {
                            let iq_i = i < 2;
                            let iq_j = j < 2;
                            let v = if iq_i == iq_j {
                                a[i][j] * c
                            } else if iq_i {
                                -a[i][j] * s
                            } else {
                                a[i][j] * s
                            };
                            zf[i][j] += w * v;
                        }
                    }
                }
                for i in 0..4 {
                    for j in 0..4 {
                        worst = worst.max((zf[i][j] - zg[i][j]).abs());
                    }
                }
            }
        }
        assert!(worst < 1e-10, "max |Z_fourier - Z_geometric| = {worst:e}");
    }

    /// Independent check of the sign of U in our frames (conventions §5):
    /// single Rayleigh scattering polarizes perpendicular to the scattering
    /// plane, i.e. along `n = k_in × k_out`. Expressed in the meridian frame
    /// of `k_out` (x = e_ϑ, y = e_ϕ), that direction has angle χ with
    /// `tan χ = (n·y)/(n·x)` and the scattered Stokes vector is ∝
    /// `(1, p cos 2χ, p sin 2χ, 0)`. For a beam going down at μ0 = 0.6 with
    /// azimuth 0, observed going up at μ = 0.5 and azimuth 90°, χ ≈ 33°, so
    /// `U > 0` and `Q > 0`. (VLIDORT's tables have U < 0 here: its U is the
    /// negative of ours.)
    #[test]
    fn single_scattering_u_sign_in_our_frames() {
        let rayleigh = |mu: f64| {
            let a = 0.75 * (1.0 + mu * mu);
            [a, a, 1.5 * mu, 1.5 * mu, -0.75 * (1.0 - mu * mu), 0.0]
        };
        let (nu_i, nu_o) = (-0.6, 0.5);
        let z = geometric_phase_matrix(&rayleigh, nu_i, 0.0, nu_o, std::f64::consts::FRAC_PI_2);
        let ki = direction(nu_i, 0.0);
        let ko = direction(nu_o, std::f64::consts::FRAC_PI_2);
        let n = cross(ki, ko);
        let (ex, ey) = meridian_frame(nu_o, std::f64::consts::FRAC_PI_2);
        let chi = dot(n, ey).atan2(dot(n, ex));
        let p = -z[1][0].hypot(z[2][0]) / z[0][0];
        assert!(p < 0.0);
        let (q, u) = (z[1][0] / z[0][0], z[2][0] / z[0][0]);
        // Polarized along n: (Q, U) = |p| (cos 2χ, sin 2χ).
        assert!((q - (-p) * (2.0 * chi).cos()).abs() < 1e-12, "q={q}");
        assert!((u - (-p) * (2.0 * chi).sin()).abs() < 1e-12, "u={u}");
        assert!(u > 0.0 && q > 0.0);
    }

    /// Reciprocity of the Fourier kernel: `A^m(ν', ν) = Δ4 A^m(ν, ν')ᵀ Δ4`
    /// with `Δ4 = diag(1, 1, 1, −1)` (follows from `Bᵀ = Δ4 B Δ4` and the
    /// symmetry of `P_l^m`).
    #[test]
    fn a_matrix_reciprocity() {
        let coef = garcia_siewert();
        let l_max = coef.beta.len() - 1;
        for m in 0..=l_max {
            let ga = Gsf::new(m, 0.37, l_max, true);
            let gb = Gsf::new(m, -0.81, l_max, true);
            let ab = a_matrix(&coef, m, &ga, &gb, true);
            let ba = a_matrix(&coef, m, &gb, &ga, true);
            let d = [1.0, 1.0, 1.0, -1.0];
            for i in 0..4 {
                for j in 0..4 {
                    let expect = d[i] * ab[j][i] * d[j];
                    assert!((ba[i][j] - expect).abs() < 1e-13, "m={m} ({i},{j})");
                }
            }
        }
    }
}
