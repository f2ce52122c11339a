//! Stokes vectors and Mueller matrices: small pure kernels.
//!
//! Conventions (`docs/conventions.md` §5): a Stokes vector `s = [I, Q, U, V]`
//! is referred to a right-handed frame `(x, y, k)`; `Q = I_x − I_y`,
//! `U = I_{+45°} − I_{−45°}` (`+45°` from `x` towards `y`), `V = I_R − I_L`
//! in the sign of Bohren & Huffman (1983) §2.8 with `(∥, ⊥) = (x, y)`.
//! For a field with complex amplitudes `(E_x, E_y)` (time factor `exp(−iωt)`,
//! conventions §2) and the 2×2 coherency matrix `ρ = E E†` this is
//!
//! ```text
//! I = |E_x|² + |E_y|²,  Q = |E_x|² − |E_y|²,
//! U = 2 Re(E_x E_y*),   V = −2 Im(E_x E_y*) = i (E_x E_y* − E_y E_x*),
//! ```
//!
//! i.e. `S_i = tr(σ_i ρ)` with the Pauli matrices in the order
//! `σ_0 = 1`, `σ_1 = diag(1, −1)`, `σ_2 = [[0, 1], [1, 0]]`,
//! `σ_3 = [[0, −i], [i, 0]]` (this ordering is what [`PAULI`] holds).
//!
//! A Mueller matrix `M` is `[[f64; 4]; 4]` indexed `M[row][col]`; the row is
//! the outgoing Stokes component, the column the incoming one: `s' = M s`.

use super::C64;
use faer::{Mat, Side};

/// A 4×4 Mueller matrix, `M[row][col]`, row = outgoing Stokes component.
pub type Mueller = [[f64; 4]; 4];

/// A 2×2 complex Jones matrix `J[row][col]` acting on `(E_x, E_y)`.
pub type Jones = [[C64; 2]; 2];

/// The 4×4 identity Mueller matrix.
pub const IDENTITY: Mueller = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

const Z: C64 = C64::new(0.0, 0.0);
const O: C64 = C64::new(1.0, 0.0);
const I: C64 = C64::new(0.0, 1.0);

/// The Pauli basis `σ_0..σ_3` matched to the Stokes definitions of this
/// module (`S_i = tr(σ_i ρ)`, see the module doc).
pub const PAULI: [[[C64; 2]; 2]; 4] = [
    [[O, Z], [Z, O]],
    [[O, Z], [Z, C64::new(-1.0, 0.0)]],
    [[Z, O], [O, Z]],
    [[Z, C64::new(0.0, -1.0)], [I, Z]],
];

/// Rotation of the reference frame by `sigma_rad` (conventions §5, seed eq. 2):
///
/// ```text
///        | 1     0        0     0 |
/// L(σ) = | 0   cos2σ    sin2σ   0 |
///        | 0  −sin2σ    cos2σ   0 |
///        | 0     0        0     1 |
/// ```
///
/// `σ` turns the frame counter-clockwise looking against the propagation
/// direction (from `x` towards `y`); `s_new = L(σ) s_old`. (The seed prints
/// eq. 2 with the opposite sign of the `sin` terms, i.e. for the opposite
/// sense of `σ`; conventions §5 is binding here.)
pub fn rotation(sigma_rad: f64) -> Mueller {
    let (s, c) = (2.0 * sigma_rad).sin_cos();
    [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, c, s, 0.0],
        [0.0, -s, c, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// [`rotation`] by the angle `σ` with `cos σ = c`, `sin σ = s` (`c² + s² = 1`):
/// the frame turned from `x` to `x' = c x + s y`, without an `atan2`.
pub fn rotation_cs(c: f64, s: f64) -> Mueller {
    let (cos2, sin2) = (c * c - s * s, 2.0 * c * s);
    [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, cos2, sin2, 0.0],
        [0.0, -sin2, cos2, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// Matrix product `a · b` (`(a b)_ij = Σ_k a_ik b_kj`): apply `b` first, then `a`.
pub fn mul(a: &Mueller, b: &Mueller) -> Mueller {
    let mut c = [[0.0; 4]; 4];
    for (i, row) in c.iter_mut().enumerate() {
        for (j, cij) in row.iter_mut().enumerate() {
            *cij = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// `s' = M s` (`s'_i = Σ_j m_ij s_j`).
pub fn apply(m: &Mueller, s: [f64; 4]) -> [f64; 4] {
    let mut out = [0.0; 4];
    for (i, o) in out.iter_mut().enumerate() {
        *o = (0..4).map(|j| m[i][j] * s[j]).sum();
    }
    out
}

/// Transpose `Mᵀ` (`(Mᵀ)_ij = m_ji`).
pub fn transpose(m: &Mueller) -> Mueller {
    let mut t = [[0.0; 4]; 4];
    for (i, row) in t.iter_mut().enumerate() {
        for (j, tij) in row.iter_mut().enumerate() {
            *tij = m[j][i];
        }
    }
    t
}

/// Degree of polarization `P = √(Q² + U² + V²) / I`; `0` when `I ≤ 0`.
pub fn degree_of_polarization(s: [f64; 4]) -> f64 {
    if s[0] > 0.0 {
        (s[1] * s[1] + s[2] * s[2] + s[3] * s[3]).sqrt() / s[0]
    } else {
        0.0
    }
}

/// Degree of linear polarization `√(Q² + U²) / I`; `0` when `I ≤ 0`.
pub fn dolp(s: [f64; 4]) -> f64 {
    if s[0] > 0.0 {
        s[1].hypot(s[2]) / s[0]
    } else {
        0.0
    }
}

/// Degree of circular polarization `|V| / I` (unsigned; the handedness is the
/// sign of `V`); `0` when `I ≤ 0`.
pub fn docp(s: [f64; 4]) -> f64 {
    if s[0] > 0.0 { s[3].abs() / s[0] } else { 0.0 }
}

/// Mueller matrix of a Jones matrix: `m_ij = ½ tr(σ_i J σ_j J†)`
/// (from `ρ' = J ρ J†`, `ρ = ½ Σ_j S_j σ_j` and `S'_i = tr(σ_i ρ')`, with
/// [`PAULI`]).
pub fn jones_to_mueller(j: &Jones) -> Mueller {
    let jh = adjoint2(j);
    let mut m = [[0.0; 4]; 4];
    for (a, row) in m.iter_mut().enumerate() {
        for (b, mab) in row.iter_mut().enumerate() {
            let p = mul2(&mul2(&mul2(&PAULI[a], j), &PAULI[b]), &jh);
            *mab = 0.5 * (p[0][0] + p[1][1]).re;
        }
    }
    m
}

/// The Hermitian covariance ("coherency") matrix of a Mueller matrix,
/// `H = ¼ Σ_ij m_ij (σ_i ⊗ σ_j*)`, with `⊗` the Kronecker product
/// (`(A ⊗ B)_{2a+b, 2c+d} = A_ac B_bd`) and [`PAULI`] (S. R. Cloude, "Group
/// theory and polarisation algebra", Optik 75, 26–36, 1986; J. J. Gil and
/// R. Ossikovski, *Polarized Light and the Mueller Matrix Approach*, CRC
/// 2016). Cloude's "target coherency matrix" `T` (Jones matrix expanded on
/// the Pauli basis instead of element-wise) is a unitary transform of this
/// `H` and has the same eigenvalues.
///
/// For a Jones system `M = jones_to_mueller(J)` one finds, from the Pauli
/// completeness relation `Σ_i (σ_i)_ac (σ_i)_ef = 2 δ_af δ_ce`,
/// `H_{2a+b, 2c+d} = ½ J_ab J_cd*`, i.e. `H = ½ vec(J) vec(J)†`: Hermitian,
/// rank one, eigenvalues `(m_11, 0, 0, 0)`. A Mueller matrix is physically
/// realizable (a convex sum of Jones systems) iff `H ⪰ 0`; `tr H = m_11`.
pub fn coherency_matrix(m: &Mueller) -> [[C64; 4]; 4] {
    let mut h = [[Z; 4]; 4];
    for (i, mrow) in m.iter().enumerate() {
        for (j, &mij) in mrow.iter().enumerate() {
            if mij == 0.0 {
                continue;
            }
            let si = &PAULI[i];
            let sj = &PAULI[j];
            for a in 0..2 {
                for b in 0..2 {
                    for c in 0..2 {
                        for d in 0..2 {
                            h[2 * a + b][2 * c + d] += 0.25 * mij * si[a][c] * sj[b][d].conj();
                        }
                    }
                }
            }
        }
    }
    h
}

/// Eigenvalues of [`coherency_matrix`], sorted **decreasing**
/// (`λ_0 ≥ λ_1 ≥ λ_2 ≥ λ_3`, `Σ λ = m_11`). Uses faer's self-adjoint
/// eigensolver on the complex 4×4 Hermitian matrix. A non-finite input gives
/// `NaN`s.
pub fn coherency_eigenvalues(m: &Mueller) -> [f64; 4] {
    if m.iter().flatten().any(|x| !x.is_finite()) {
        return [f64::NAN; 4];
    }
    // Divided to unit size first (1/s overflows for subnormal s): subnormal inputs (e.g. e^{−700} behind a
    // thick absorber) would otherwise lose the eigensolver (NaN).
    let s = max_abs(m);
    if s == 0.0 {
        return [0.0; 4];
    }
    let h = coherency_matrix(&m.map(|row| row.map(|x| x / s)));
    let mat = Mat::<C64>::from_fn(4, 4, |i, j| h[i][j]);
    match mat.self_adjoint_eigenvalues(Side::Lower) {
        Ok(ev) => [ev[3] * s, ev[2] * s, ev[1] * s, ev[0] * s],
        Err(_) => [f64::NAN; 4],
    }
}

/// Cloude's criterion: `true` iff every coherency eigenvalue is
/// `≥ −tol · m_11` (so `m_11 < 0` or `NaN` input is never realizable).
pub fn is_realizable(m: &Mueller, tol: f64) -> bool {
    let ev = coherency_eigenvalues(m);
    ev.iter().all(|&l| l >= -tol * m[0][0])
}

/// The Mueller matrix of a coherency matrix, the inverse of
/// [`coherency_matrix`]: `m_ij = tr(H (σ_i ⊗ σ_j*)†)` (the 16 products
/// `σ_i ⊗ σ_j*` are orthogonal with norm² 4 and `H = ¼ Σ m_ij σ_i ⊗ σ_j*`).
pub fn mueller_of_coherency(h: &[[C64; 4]; 4]) -> Mueller {
    let mut m = [[0.0; 4]; 4];
    for (i, mrow) in m.iter_mut().enumerate() {
        for (j, mij) in mrow.iter_mut().enumerate() {
            let (si, sj) = (&PAULI[i], &PAULI[j]);
            let mut acc = Z;
            for a in 0..2 {
                for b in 0..2 {
                    for c in 0..2 {
                        for d in 0..2 {
                            // B = σ_i ⊗ σ_j*, B_{2a+b, 2c+d} = σ_i[a][c] σ_j[b][d]*.
                            let bel = si[a][c] * sj[b][d].conj();
                            acc += h[2 * a + b][2 * c + d] * bel.conj();
                        }
                    }
                }
            }
            *mij = acc.re;
        }
    }
    m
}

/// Whether the Hermitian `h + shift·1` is positive definite (a Cholesky
/// factorisation `LL†` succeeds with positive pivots): `λ_min(h) > −shift`.
fn positive_definite_shifted(h: &[[C64; 4]; 4], shift: f64) -> bool {
    let mut l = [[Z; 4]; 4];
    for j in 0..4 {
        let mut d = h[j][j].re + shift;
        for lj in l[j].iter().take(j) {
            d -= lj.norm_sqr();
        }
        if d.is_nan() || d <= 0.0 {
            return false;
        }
        let djj = d.sqrt();
        l[j][j] = C64::new(djj, 0.0);
        for i in j + 1..4 {
            let mut v = h[i][j];
            let (li, lj) = (l[i], l[j]);
            for (a, b) in li.iter().zip(&lj).take(j) {
                v -= *a * b.conj();
            }
            l[i][j] = v / djj;
        }
    }
    true
}

/// The nearest physically realizable Mueller matrix (Cloude 1986; "Cloude
/// filtering", Gil & Ossikovski 2016 §6.7): negative eigenvalues of the
/// coherency matrix are set to zero, `H → Σ max(λ_k, 0) u_k u_k†`, and the
/// Mueller matrix rebuilt. This is the orthogonal projection onto the convex
/// cone of realizable matrices in the Frobenius norm of `H` (`‖H‖² = ¼ Σ m_ij²`),
/// so it never moves a result further from any realizable matrix, the
/// exact answer included. `None` when `m` is realizable to within
/// `rel_tol · m_11` already (checked by a Cholesky factorisation of
/// `H + rel_tol m_11 1`, a few hundred flops; the eigendecomposition runs
/// only for the rest), or not finite.
pub fn realizable_projection(m: &Mueller, rel_tol: f64) -> Option<Mueller> {
    if m.iter().flatten().any(|x| !x.is_finite()) {
        return None;
    }
    // Work at unit size (subnormal entries would underflow in the squares
    // of the factorisation and lose the eigensolver); scale back at the end.
    let scale = max_abs(m);
    if scale == 0.0 {
        return None;
    }
    let unit = m.map(|row| row.map(|x| x / scale));
    let h = coherency_matrix(&unit);
    if positive_definite_shifted(&h, rel_tol * unit[0][0].max(0.0)) {
        return None;
    }
    let mat = Mat::<C64>::from_fn(4, 4, |i, j| h[i][j]);
    let evd = mat.self_adjoint_eigen(Side::Lower).ok()?;
    let (u, lam) = (evd.U(), evd.S().column_vector());
    let mut p = [[Z; 4]; 4];
    for k in 0..4 {
        let l = lam[k].re;
        if l <= 0.0 {
            continue;
        }
        for (a, prow) in p.iter_mut().enumerate() {
            for (b, pab) in prow.iter_mut().enumerate() {
                *pab += u[(a, k)] * u[(b, k)].conj() * l;
            }
        }
    }
    Some(scaled(&mueller_of_coherency(&p), scale))
}

fn max_abs(m: &Mueller) -> f64 {
    m.iter().flatten().fold(0.0, |a: f64, x| a.max(x.abs()))
}

fn scaled(m: &Mueller, a: f64) -> Mueller {
    m.map(|row| row.map(|x| x * a))
}

/// Stokes criterion (necessary, weaker than Cloude's): the minimum over
/// `n_samples` fully polarized unit inputs `s = (1, q, u, v)`,
/// `q² + u² + v² = 1` (a Fibonacci lattice on the Poincaré sphere), of
/// `I_out − √(Q_out² + U_out² + V_out²)`, where `s_out = M s`. A Mueller
/// matrix that maps every Stokes vector to a Stokes vector gives a value
/// `≥ 0` (up to sampling); by linearity checking fully polarized inputs is
/// enough. `n_samples` is raised to at least 2.
pub fn stokes_criterion_min(m: &Mueller, n_samples: usize) -> f64 {
    // At unit scale: the squares of entries ~1e-162 (values behind a thick
    // absorber) underflow and would give a spurious negative value.
    let s = max_abs(m);
    if !(s > 0.0 && s.is_finite()) {
        return if s == 0.0 { 0.0 } else { f64::NAN };
    }
    let m = &m.map(|row| row.map(|x| x / s));
    let n = n_samples.max(2);
    let golden = std::f64::consts::PI * (3.0 - 5.0_f64.sqrt());
    let mut min = f64::INFINITY;
    for i in 0..n {
        let v = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let r = (1.0 - v * v).max(0.0).sqrt();
        let (sp, cp) = (golden * i as f64).sin_cos();
        let out = apply(m, [1.0, r * cp, r * sp, v]);
        let d = out[0] - (out[1] * out[1] + out[2] * out[2] + out[3] * out[3]).sqrt();
        min = min.min(d);
    }
    min * s
}

fn mul2(a: &Jones, b: &Jones) -> Jones {
    let mut c = [[Z; 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j];
        }
    }
    c
}

fn adjoint2(a: &Jones) -> Jones {
    [
        [a[0][0].conj(), a[1][0].conj()],
        [a[0][1].conj(), a[1][1].conj()],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    /// Subnormal matrices (values behind a thick absorber) are handled at
    /// unit scale: finite eigenvalues, and the projection of a
    /// non-realizable one is realizable.
    #[test]
    fn subnormal_matrices_keep_finite_eigenvalues_and_project() {
        let bad: Mueller = [
            [1.0, 0.3, 0.0, 0.0],
            [1.05, 0.9, 0.1, 0.0],
            [0.0, -0.1, 0.4, 0.2],
            [0.0, 0.05, -0.2, 0.3],
        ];
        let tiny = bad.map(|r| r.map(|x| x * 1e-310));
        let ev = coherency_eigenvalues(&tiny);
        assert!(ev.iter().all(|x| x.is_finite()), "{ev:?}");
        assert!(ev[3] < 0.0);
        let p = realizable_projection(&tiny, 1e-12).expect("projected");
        assert!(stokes_criterion_min(&p, 500) >= -1e-6 * p[0][0], "{p:?}");
        let ev = coherency_eigenvalues(&p);
        assert!(ev[3] >= -1e-9 * p[0][0], "{ev:?}");
    }

    /// `mueller_of_coherency` inverts `coherency_matrix` exactly.
    #[test]
    fn coherency_round_trip() {
        let m: Mueller = [
            [1.0, 0.2, -0.1, 0.05],
            [0.3, 0.7, 0.11, -0.2],
            [-0.05, 0.13, 0.6, 0.25],
            [0.02, -0.3, 0.21, 0.5],
        ];
        assert!(max_diff(&mueller_of_coherency(&coherency_matrix(&m)), &m) < 1e-15);
    }

    /// The projection: realizable matrices are left alone; a matrix with a
    /// negative coherency eigenvalue becomes realizable (smallest eigenvalue
    /// ≥ −1e-15 m11), moves by no more than it must (not further than the
    /// rescaled identity, a realizable matrix), and commutes with the
    /// reciprocity map `M → Q Mᵀ Q`, `Q = diag(1, 1, −1, 1)` (so reciprocal
    /// BRDFs stay reciprocal).
    #[test]
    fn projection_makes_realizable_and_commutes_with_reciprocity() {
        let ok = jones_to_mueller(&[
            [C64::new(0.8, 0.1), C64::new(0.1, -0.2)],
            [C64::new(-0.05, 0.3), C64::new(0.6, 0.0)],
        ]);
        assert!(realizable_projection(&ok, 1e-12).is_none());
        // Over-polarizing: the Stokes criterion fails for m12 > m11.
        let bad: Mueller = [
            [1.0, 0.3, 0.0, 0.0],
            [1.05, 0.9, 0.1, 0.0],
            [0.0, -0.1, 0.4, 0.2],
            [0.0, 0.05, -0.2, 0.3],
        ];
        assert!(coherency_eigenvalues(&bad)[3] < -1e-3);
        let p = realizable_projection(&bad, 1e-12).expect("projected");
        let ev = coherency_eigenvalues(&p);
        assert!(ev[3] >= -1e-15 * p[0][0], "{ev:?}");
        assert!(stokes_criterion_min(&p, 2000) >= -1e-12 * p[0][0]);
        let fro = |a: &Mueller, b: &Mueller| -> f64 {
            a.iter()
                .flatten()
                .zip(b.iter().flatten())
                .map(|(x, y)| (x - y).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let depol: Mueller = std::array::from_fn(|i| {
            std::array::from_fn(|j| if i == 0 && j == 0 { bad[0][0] } else { 0.0 })
        });
        assert!(fro(&p, &bad) <= fro(&depol, &bad));
        let q = |m: &Mueller| -> Mueller {
            let s = [1.0, 1.0, -1.0, 1.0];
            std::array::from_fn(|i| std::array::from_fn(|j| s[i] * m[j][i] * s[j]))
        };
        let a = realizable_projection(&q(&bad), 1e-12).unwrap();
        assert!(max_diff(&a, &q(&p)) < 1e-14, "{a:?} vs {:?}", q(&p));
    }

    fn max_diff(a: &Mueller, b: &Mueller) -> f64 {
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    }

    /// Ideal linear polarizer transmitting along `x` (Jones diag(1, 0)).
    fn polarizer_x() -> Mueller {
        [
            [0.5, 0.5, 0.0, 0.0],
            [0.5, 0.5, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
        ]
    }

    /// Polarizer with its axis at `alpha` from `x` towards `y`:
    /// go to the frame whose x is the axis, apply, come back.
    fn polarizer_at(alpha: f64) -> Mueller {
        mul(&rotation(-alpha), &mul(&polarizer_x(), &rotation(alpha)))
    }

    /// A deterministic pseudo-random Jones matrix.
    fn pseudo_jones(seed: u64) -> Jones {
        let mut x = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut next = || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        [
            [C64::new(next(), next()), C64::new(next(), next())],
            [C64::new(next(), next()), C64::new(next(), next())],
        ]
    }

    #[test]
    fn identity_is_pure_and_realizable() {
        let ev = coherency_eigenvalues(&IDENTITY);
        assert!(close(ev[0], 1.0, 1e-14), "{ev:?}");
        for &l in &ev[1..] {
            assert!(l.abs() < 1e-14, "{ev:?}");
        }
        assert!(is_realizable(&IDENTITY, 1e-12));
        assert!(close(stokes_criterion_min(&IDENTITY, 500), 0.0, 1e-12));
        let s = [2.0, 0.3, -0.4, 0.5];
        assert_eq!(apply(&IDENTITY, s), s);
    }

    #[test]
    fn jones_to_mueller_known_cases() {
        // Identity Jones -> identity Mueller.
        let id: Jones = [[O, Z], [Z, O]];
        assert!(max_diff(&jones_to_mueller(&id), &IDENTITY) < 1e-15);
        // x-polarizer.
        let px: Jones = [[O, Z], [Z, Z]];
        assert!(max_diff(&jones_to_mueller(&px), &polarizer_x()) < 1e-15);
        // Quarter-wave retarder J = diag(1, i) on +45° linear light (U = 1):
        // E = (1, 1)/√2 -> (1, i)/√2, so V = −2 Im(E_x E_y*) = −Im(−i) = +1.
        let qwp: Jones = [[O, Z], [Z, I]];
        let out = apply(&jones_to_mueller(&qwp), [1.0, 0.0, 1.0, 0.0]);
        let expect = [1.0, 0.0, 0.0, 1.0];
        for k in 0..4 {
            assert!(close(out[k], expect[k], 1e-15), "{out:?}");
        }
        // Diagonal Jones diag(a, b): the closed form used by physics::fresnel.
        let (a, b) = (C64::new(0.3, -0.7), C64::new(-0.9, 0.2));
        let m = jones_to_mueller(&[[a, Z], [Z, b]]);
        let (na, nb, ab) = (a.norm_sqr(), b.norm_sqr(), a * b.conj());
        let expect = [
            [(na + nb) / 2.0, (na - nb) / 2.0, 0.0, 0.0],
            [(na - nb) / 2.0, (na + nb) / 2.0, 0.0, 0.0],
            [0.0, 0.0, ab.re, ab.im],
            [0.0, 0.0, -ab.im, ab.re],
        ];
        assert!(max_diff(&m, &expect) < 1e-15);
    }

    #[test]
    fn jones_mueller_has_rank_one_coherency() {
        let mut worst = 0.0_f64;
        for seed in 0..50 {
            let j = pseudo_jones(seed);
            let m = jones_to_mueller(&j);
            let ev = coherency_eigenvalues(&m);
            let scale = m[0][0];
            worst = worst.max((ev[0] - scale).abs() / scale);
            for &l in &ev[1..] {
                worst = worst.max(l.abs() / scale);
            }
            // H = ½ vec(J) vec(J)† element-wise.
            let h = coherency_matrix(&m);
            let v = [j[0][0], j[0][1], j[1][0], j[1][1]];
            for r in 0..4 {
                for c in 0..4 {
                    let e = 0.5 * v[r] * v[c].conj();
                    assert!((h[r][c] - e).norm() < 1e-14 * scale.max(1.0));
                }
            }
            assert!(is_realizable(&m, 1e-12));
            assert!(stokes_criterion_min(&m, 400) > -1e-12);
            // Non-depolarizing: every pure input stays pure.
            let out = apply(&m, [1.0, 0.6, 0.0, 0.8]);
            assert!(close(degree_of_polarization(out), 1.0, 1e-12));
        }
        assert!(worst < 1e-13, "worst relative deviation {worst:e}");
    }

    #[test]
    fn pure_depolarizer_has_four_equal_eigenvalues() {
        let m: Mueller = [[1.0, 0.0, 0.0, 0.0], [0.0; 4], [0.0; 4], [0.0; 4]];
        // H = ¼ σ_0 ⊗ σ_0 = ¼ 1_4.
        let ev = coherency_eigenvalues(&m);
        for &l in &ev {
            assert!(close(l, 0.25, 1e-15), "{ev:?}");
        }
        assert!(is_realizable(&m, 0.0));
        assert!(close(stokes_criterion_min(&m, 100), 1.0, 1e-15));
    }

    #[test]
    fn mirror_matrix_is_realizable() {
        // Perfect mirror in the meridian frames: Jones diag(1, −1) -> diag(1,1,−1,−1).
        let m: Mueller = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, -1.0, 0.0],
            [0.0, 0.0, 0.0, -1.0],
        ];
        let ev = coherency_eigenvalues(&m);
        assert!(close(ev[0], 1.0, 1e-15) && ev[1..].iter().all(|l| l.abs() < 1e-15));
        assert!(is_realizable(&m, 0.0));
    }

    #[test]
    fn non_physical_matrices_are_rejected() {
        // (a) Polarizing part scaled by 1.5: diag(1, 1.5, 1.5, 1.5).
        // H = ¼(1 + 1.5(σ1⊗σ1 + σ2⊗σ2 − σ3⊗σ3)); on the Bell basis the bracket is
        // (3, −1, −1, −1), so λ = (1.375, −0.125, −0.125, −0.125).
        let a: Mueller = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.5, 0.0, 0.0],
            [0.0, 0.0, 1.5, 0.0],
            [0.0, 0.0, 0.0, 1.5],
        ];
        let ev = coherency_eigenvalues(&a);
        let expect = [1.375, -0.125, -0.125, -0.125];
        for k in 0..4 {
            assert!(close(ev[k], expect[k], 1e-14), "{ev:?}");
        }
        assert!(!is_realizable(&a, 1e-6));
        assert!(close(stokes_criterion_min(&a, 200), -0.5, 1e-12));

        // (b) Output with I = 0 but Q = 1 for the input (1, −1, 0, 0).
        let b: Mueller = [
            [1.0, 1.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
        ];
        assert!(!is_realizable(&b, 1e-6));
        assert!(stokes_criterion_min(&b, 2000) < -0.5);

        // (c) diag(1, 1, 1, −1): maps every Stokes vector to a Stokes vector
        // (passes the Stokes criterion) but is NOT a convex sum of Jones
        // systems: H = ½ SWAP, λ = (½, ½, ½, −½); det M = −1 while every
        // Jones-derived matrix has det M = |det J|⁴ ≥ 0. It is complex
        // conjugation of the Jones vector (V → −V in a right-handed frame),
        // not a reflection (the mirror is diag(1, 1, −1, −1), above).
        let c: Mueller = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, -1.0],
        ];
        let ev = coherency_eigenvalues(&c);
        let expect = [0.5, 0.5, 0.5, -0.5];
        for k in 0..4 {
            assert!(close(ev[k], expect[k], 1e-14), "{ev:?}");
        }
        assert!(!is_realizable(&c, 1e-6));
        assert!(stokes_criterion_min(&c, 500).abs() < 1e-12);
    }

    #[test]
    fn malus_law() {
        // Unpolarized light through an x-polarizer then an analyser at alpha:
        // I = ½ cos²(alpha).
        let mut worst = 0.0_f64;
        for i in 0..=36 {
            let alpha = i as f64 * PI / 36.0;
            let s = apply(
                &polarizer_at(alpha),
                apply(&polarizer_x(), [1.0, 0.0, 0.0, 0.0]),
            );
            worst = worst.max((s[0] - 0.5 * alpha.cos().powi(2)).abs());
            // Light leaving a polarizer is fully polarized along its axis.
            if s[0] > 1e-6 {
                assert!(close(degree_of_polarization(s), 1.0, 1e-12));
            }
        }
        assert!(worst < 1e-15, "worst {worst:e}");
        // Any polarizer is a realizable, rank-one system.
        let ev = coherency_eigenvalues(&polarizer_at(0.3));
        assert!(close(ev[0], 0.5, 1e-14) && ev[1..].iter().all(|l| l.abs() < 1e-14));
    }

    #[test]
    fn rotation_composition_and_inverse() {
        let mut worst = 0.0_f64;
        for (a, b) in [(0.3, 0.5), (-1.2, 2.0), (PI / 4.0, PI / 8.0), (3.0, -7.0)] {
            worst = worst.max(max_diff(&mul(&rotation(a), &rotation(b)), &rotation(a + b)));
            worst = worst.max(max_diff(&mul(&rotation(a), &rotation(-a)), &IDENTITY));
            // Orthogonal: Lᵀ = L⁻¹.
            worst = worst.max(max_diff(&transpose(&rotation(a)), &rotation(-a)));
        }
        assert!(worst < 1e-15, "worst {worst:e}");
        // Period π.
        assert!(max_diff(&rotation(PI), &IDENTITY) < 1e-15);
    }

    #[test]
    fn rotating_linear_polarization() {
        // x-polarized light (Q = 1). Turning the frame by +45° (x towards y)
        // makes the field lie at −45° in the new frame: U = −1.
        let s = apply(&rotation(PI / 4.0), [1.0, 1.0, 0.0, 0.0]);
        assert!(close(s[1], 0.0, 1e-15) && close(s[2], -1.0, 1e-15), "{s:?}");
        // By 90°: new x = old y, new y = −old x, so the field lies along the
        // new y axis (up to sign): Q = −1.
        let s = apply(&rotation(PI / 2.0), [1.0, 1.0, 0.0, 0.0]);
        assert!(close(s[1], -1.0, 1e-15) && close(s[2], 0.0, 1e-15), "{s:?}");
        // Cross-check with the field picture: E at angle 30° in the old frame,
        // frame turned by 50° -> angle −20° in the new frame:
        // Q = cos(−40°), U = sin(−40°).
        let t = 30f64.to_radians();
        let s0 = [1.0, (2.0 * t).cos(), (2.0 * t).sin(), 0.0];
        let s = apply(&rotation(50f64.to_radians()), s0);
        let e = -20f64.to_radians();
        assert!(close(s[1], (2.0 * e).cos(), 1e-15) && close(s[2], (2.0 * e).sin(), 1e-15));
        // DOP, DOLP, DOCP unchanged; I and V untouched.
        assert!(close(dolp(s), 1.0, 1e-15) && docp(s) == 0.0 && s[0] == 1.0);
    }

    #[test]
    fn polarization_degrees() {
        let s = [2.0, 0.6, 0.8, -1.0];
        assert!(close(dolp(s), 0.5, 1e-15));
        assert!(close(docp(s), 0.5, 1e-15));
        assert!(close(degree_of_polarization(s), 2f64.sqrt() / 2.0, 1e-15));
        assert_eq!(degree_of_polarization([0.0; 4]), 0.0);
        assert_eq!(dolp([0.0, 1.0, 0.0, 0.0]), 0.0);
        assert_eq!(docp([-1.0, 0.0, 0.0, 1.0]), 0.0);
    }

    #[test]
    fn mul_and_transpose_basics() {
        let a = rotation(0.4);
        let b = polarizer_x();
        let s = [1.0, 0.2, -0.3, 0.1];
        let lhs = apply(&mul(&a, &b), s);
        let rhs = apply(&a, apply(&b, s));
        for k in 0..4 {
            assert!(close(lhs[k], rhs[k], 1e-15));
        }
        // (AB)ᵀ = BᵀAᵀ.
        assert!(
            max_diff(
                &transpose(&mul(&a, &b)),
                &mul(&transpose(&b), &transpose(&a))
            ) < 1e-15
        );
        assert!(!is_realizable(&[[f64::NAN; 4]; 4], 1e-9));
    }
}
