//! Wigner small d-functions `d^l_{mn}(θ)` (generalized spherical functions).
//!
//! # Convention (conventions §4)
//!
//! The standard Wigner d-function (Varshalovich, Moskalev & Khersonskii 1988,
//! ch. 4; Edmonds 1957; the `d^l_{mn}` of Mishchenko, Travis & Lacis 2002,
//! App. B), with first index `m` and second index `n`:
//!
//! ```text
//! d^l_{mn}(θ) = Σ_k (−1)^{k+m−n} √((l+m)!(l−m)!(l+n)!(l−n)!)
//!               / ((l+n−k)! k! (m−n+k)! (l−m−k)!)
//!               · cos(θ/2)^{2l+n−m−2k} sin(θ/2)^{m−n+2k},
//! ```
//!
//! which has the anchors of conventions §4: `d^l_00 = P_l(cos θ)`,
//! `d^l_02 = √((l−2)!/(l+2)!) P_l^2(cos θ) ≥ 0` near `θ = 0` (no
//! Condon–Shortley phase; `d^2_02 = (√6/4) sin²θ`), `d^2_22 = ((1+μ)/2)²`,
//! `d^2_{2,−2} = ((1−μ)/2)²`. (Note `d^1_{10} = −sin θ/√2`, `d^1_{01} = +sin θ/√2`.)
//!
//! # Computation
//!
//! With `μ = cos θ`, `s₀ = max(|m|,|n|)`, the starting value (Mishchenko et al.
//! 2002, App. B) is
//!
//! ```text
//! d^{s₀}_{mn}(θ) = ξ_{mn} √( (2s₀)! / (|m−n|)! (|m+n|)! ) · sin(θ/2)^{|m−n|} cos(θ/2)^{|m+n|},
//! ξ_{mn} = 1 if n ≥ m, (−1)^{m−n} if n < m,
//! ```
//!
//! (`|m−n| + |m+n| = 2 s₀`), and `d^{s₀−1}_{mn} = 0`. Upward in `l` (ibid.):
//!
//! ```text
//! s √((s+1)²−m²) √((s+1)²−n²) d^{s+1}_{mn}
//!   = (2s+1) (s(s+1)μ − mn) d^s_{mn} − (s+1) √(s²−m²) √(s²−n²) d^{s−1}_{mn},
//! ```
//!
//! (for `m = n = 0` and `s = 0` this is read as `d^1_00 = μ`). The recurrence
//! is stable upward in `l`; it is checked here to `l = 50 000` against
//! multiprecision values (absolute error `< 4e-15`).
//!
//! Two arrangements keep it accurate: for `μ < 0` the reflection
//! `d^l_{mn}(−μ) = (−1)^{l+m} d^l_{m,−n}(μ)` is applied so that the
//! recurrence always runs at `μ ≥ 0`; for `μ > ½` it runs on `u = 1 − μ` and
//! the differences `d^s − d^{s−1}` (see `wigner_d_nonneg`), which near
//! `θ = 0` avoids the loss of relative accuracy of the plain form
//! (unitarity error at `l = 1500`, `μ = 0.999999`: `2e-12` plain, `1e-14` in
//! difference form).
//!
//! The starting value can underflow for large `s₀` near `θ = 0` or `π`
//! (e.g. `sin(θ/2)^{3000}`), while `d^l_{mn}` becomes `O(l^{-1/2})` further up
//! in `l`. It is therefore computed as a product with a separate binary
//! exponent, and the recurrence runs on scaled values (exact power-of-two
//! rescaling) until they are representable; no value is lost to underflow
//! unless it is truly below `~1e-300`.
//!
//! # Symmetries (tested)
//!
//! * `d^l_{mn}(θ) = (−1)^{m−n} d^l_{nm}(θ) = d^l_{−n,−m}(θ)`,
//!   hence `d^l_{−m,−n}(θ) = (−1)^{m−n} d^l_{mn}(θ)`;
//! * `d^l_{mn}(π − θ) = (−1)^{l+m} d^l_{m,−n}(θ)`, i.e.
//!   `d^l_{mn}(−μ) = (−1)^{l+m} d^l_{m,−n}(μ)`;
//! * `Σ_n d^l_{mn}(θ)² = 1` (unitarity), and
//!   `∫_{−1}^{1} d^l_{mn} d^{l'}_{mn} dμ = 2/(2l+1) δ_{ll'}`.

/// Wigner `d^l_{mn}(θ)` at `μ = cos θ` for `l = 0 .. out.len()−1`, written to
/// `out` (zero for `l < max(|m|,|n|)`). `μ` is clamped to `[−1, 1]`.
///
/// Convention and method: module documentation. Cost `O(out.len())`.
pub fn wigner_d_into(m: i32, n: i32, mu: f64, out: &mut [f64]) {
    out.fill(0.0);
    let s0 = m.unsigned_abs().max(n.unsigned_abs()) as usize;
    if s0 >= out.len() {
        return;
    }
    if mu.is_nan() {
        out[s0..].fill(f64::NAN);
        return;
    }
    let mu = mu.clamp(-1.0, 1.0);
    if mu < 0.0 {
        // d^l_{mn}(−|μ|) = (−1)^{l+m} d^l_{m,−n}(|μ|): always recur at μ ≥ 0.
        wigner_d_nonneg(m, -n, -mu, s0, out);
        for (l, v) in out.iter_mut().enumerate().skip(s0) {
            if (l as i64 + i64::from(m)).rem_euclid(2) == 1 {
                *v = -*v;
            }
        }
    } else {
        wigner_d_nonneg(m, n, mu, s0, out);
    }
}

/// `wigner_d_into` for `0 ≤ μ ≤ 1`, `s0 = max(|m|,|n|) < out.len()`, `out`
/// zeroed.
///
/// For `μ > ½` (`θ < π/3`) the recurrence is run on `u = 1 − μ` and the
/// differences `Δ_s = d^s − d^{s−1}`:
///
/// ```text
/// Δ_{s+1} = C_s Δ_s + (E_s − A_s u) d^s,   d^{s+1} = d^s + Δ_{s+1},
/// A_s = (2s+1)(s+1)/R_{s+1},  C_s = (s+1) R_s / (s R_{s+1}),
/// E_s = [(2s+1)(m−n)²/2 + s δ_{s+1} + (s+1) δ_s] / (s R_{s+1}),
/// R_s = √((s²−m²)(s²−n²)),  δ_s = s² − (m²+n²)/2 − R_s
///     = (m²−n²)² / (4 (s² − (m²+n²)/2 + R_s)),
/// ```
///
/// an exact rearrangement of the recurrence in the module docs
/// (`E_s = A_s − B_s − 1 − C_s` with `B_s = (2s+1)mn/(s R_{s+1})`, written
/// without cancellation). Near `θ = 0`, where `d^s` changes slowly with `s`,
/// this keeps the relative accuracy that the plain form loses when it
/// rounds `μ s(s+1)` (cf. Reinsch's modification of the Legendre recurrence).
fn wigner_d_nonneg(m: i32, n: i32, x: f64, s0: usize, out: &mut [f64]) {
    let start = start_value(m, n, x);
    if start.mant == 0.0 {
        return;
    }
    let mf = f64::from(m);
    let nf = f64::from(n);
    let mn = mf * nf;
    let q = 0.5 * (mf * mf + nf * nf);
    let dm2 = 0.5 * (mf - nf) * (mf - nf);
    let p2 = 0.25 * (mf * mf - nf * nf) * (mf * mf - nf * nf);
    let r_of = |s: f64| {
        ((s - mf) * (s + mf) * ((s - nf) * (s + nf)))
            .max(0.0)
            .sqrt()
    };
    let delta_of = |s: f64, r: f64| {
        let den = s * s - q + r;
        if den > 0.0 { p2 / den } else { 0.0 }
    };

    if x > 0.5 {
        let u = 1.0 - x;
        // state = [d^s, Δ_s]
        let mut state = [start.mant, start.mant];
        let mut s = s0;
        if s0 == 0 && out.len() > 1 {
            // m = n = 0: d^1_00 = μ, Δ_1 = −u (scaled like the start).
            out[0] = ldexp(start.mant, start.exp);
            state = [start.mant * x, -start.mant * u];
            s = 1;
        }
        let mut r_s = r_of(s as f64);
        let mut delta_s = delta_of(s as f64, r_s);
        run_recurrence(s, start.exp, state, out, |s, st| {
            let sf = s as f64;
            let r_next = r_of(sf + 1.0);
            let delta_next = delta_of(sf + 1.0, r_next);
            let denom = sf * r_next;
            let a = (2.0 * sf + 1.0) * (sf + 1.0) / r_next;
            let c = (sf + 1.0) * r_s / denom;
            let e = ((2.0 * sf + 1.0) * dm2 + sf * delta_next + (sf + 1.0) * delta_s) / denom;
            let diff = c * st[1] + (e - a * u) * st[0];
            st[0] += diff;
            st[1] = diff;
            r_s = r_next;
            delta_s = delta_next;
        });
    } else {
        // state = [d^s, d^{s−1}]
        let mut state = [start.mant, 0.0];
        let mut s = s0;
        if s0 == 0 && out.len() > 1 {
            out[0] = ldexp(start.mant, start.exp);
            state = [start.mant * x, start.mant];
            s = 1;
        }
        let mut r_s = r_of(s as f64);
        run_recurrence(s, start.exp, state, out, |s, st| {
            let sf = s as f64;
            let r_next = r_of(sf + 1.0);
            let next = ((2.0 * sf + 1.0) * (sf * (sf + 1.0) * x - mn) * st[0]
                - (sf + 1.0) * r_s * st[1])
                / (sf * r_next);
            st[1] = st[0];
            st[0] = next;
            r_s = r_next;
        });
    }
}

/// Drives a linear two-term recurrence from degree `s` (state `[d^s, aux]`,
/// both in units of `2^exp`) up to `out.len() − 1`, writing `d^l` to `out`.
///
/// While `exp ≠ 0` (start value below the normal range) the state is kept
/// scaled, rescaled by exact powers of two when it grows; once the true value
/// is safely representable the exponent is folded in and the loop continues
/// in plain arithmetic.
fn run_recurrence(
    mut s: usize,
    mut exp: i64,
    mut st: [f64; 2],
    out: &mut [f64],
    mut step: impl FnMut(usize, &mut [f64; 2]),
) {
    let true_value = ldexp(st[0], exp);
    if true_value.abs() > TINY {
        st = [true_value, ldexp(st[1], exp)];
        exp = 0;
    }
    out[s] = true_value;
    // Phase 1: scaled.
    while exp != 0 && s + 1 < out.len() {
        step(s, &mut st);
        s += 1;
        let true_value = ldexp(st[0], exp);
        if true_value.abs() > TINY {
            st = [true_value, ldexp(st[1], exp)];
            exp = 0;
        } else if st[0].abs() > HUGE {
            st[0] *= INV_HUGE;
            st[1] *= INV_HUGE;
            exp += HUGE_EXP;
        }
        out[s] = true_value;
    }
    // Phase 2: plain.
    while s + 1 < out.len() {
        step(s, &mut st);
        s += 1;
        out[s] = st[0];
    }
}

/// Wigner `d^l_{mn}(θ)` at `μ = cos θ` for `l = 0 ..= l_max` (see
/// [`wigner_d_into`]).
pub fn wigner_d(m: i32, n: i32, mu: f64, l_max: usize) -> Vec<f64> {
    let mut out = vec![0.0; l_max + 1];
    wigner_d_into(m, n, mu, &mut out);
    out
}

/// Values above this (true scale) are safely in the normal range, so the
/// scaled phase can end.
const TINY: f64 = 1e-270;
/// Rescaling step of the scaled phase: `2^HUGE_EXP`.
const HUGE_EXP: i64 = 600;
const HUGE: f64 = f64::from_bits(((1023 + HUGE_EXP) as u64) << 52); // 2^600
const INV_HUGE: f64 = f64::from_bits(((1023 - HUGE_EXP) as u64) << 52); // 2^-600

/// A floating-point value with a separate binary exponent: `mant · 2^exp`.
#[derive(Clone, Copy, Debug)]
struct Scaled {
    mant: f64,
    exp: i64,
}

impl Scaled {
    fn new(v: f64) -> Self {
        Self { mant: v, exp: 0 }.normalized()
    }

    /// Mantissa in `[0.5, 1)` (in magnitude), unless zero or non-finite.
    fn normalized(self) -> Self {
        let (f, e) = frexp(self.mant);
        Self {
            mant: f,
            exp: self.exp + e,
        }
    }

    fn mul(self, o: Self) -> Self {
        Self {
            mant: self.mant * o.mant,
            exp: self.exp + o.exp,
        }
        .normalized()
    }

    /// `self^k` by binary powering.
    fn powi(self, mut k: u32) -> Self {
        let mut result = Self::new(1.0);
        let mut base = self;
        while k > 0 {
            if k & 1 == 1 {
                result = result.mul(base);
            }
            base = base.mul(base);
            k >>= 1;
        }
        result
    }

    fn sqrt(self) -> Self {
        let (mant, exp) = if self.exp % 2 == 0 {
            (self.mant, self.exp)
        } else {
            (2.0 * self.mant, self.exp - 1)
        };
        Self {
            mant: mant.sqrt(),
            exp: exp / 2,
        }
        .normalized()
    }
}

/// `x = f · 2^e` with `|f| ∈ [0.5, 1)`; zero and non-finite `x` give `(x, 0)`.
fn frexp(x: f64) -> (f64, i64) {
    if x == 0.0 || !x.is_finite() {
        return (x, 0);
    }
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i64;
    if biased == 0 {
        // subnormal: scale up by 2^64 first
        let (f, e) = frexp(x * 18_446_744_073_709_551_616.0);
        return (f, e - 64);
    }
    let f = f64::from_bits((bits & !(0x7ff << 52)) | (1022 << 52));
    (f, biased - 1022)
}

/// `x · 2^e`, exact unless the result is subnormal or out of range.
fn ldexp(mut x: f64, mut e: i64) -> f64 {
    if e == 0 || x == 0.0 {
        return x;
    }
    while e > 1000 {
        x *= 2f64.powi(1000);
        e -= 1000;
        if x.is_infinite() {
            return x;
        }
    }
    while e < -1000 {
        x *= 2f64.powi(-1000);
        e += 1000;
        if x == 0.0 {
            return x;
        }
    }
    x * 2f64.powi(e as i32)
}

/// `d^{s₀}_{mn}(μ)` with `s₀ = max(|m|,|n|)`, as a scaled number.
fn start_value(m: i32, n: i32, x: f64) -> Scaled {
    let a = (i64::from(m) - i64::from(n)).unsigned_abs() as u32; // |m − n|
    let b = (i64::from(m) + i64::from(n)).unsigned_abs() as u32; // |m + n|
    let sin_half = (0.5 * (1.0 - x)).sqrt();
    let cos_half = (0.5 * (1.0 + x)).sqrt();
    if (a > 0 && sin_half == 0.0) || (b > 0 && cos_half == 0.0) {
        return Scaled { mant: 0.0, exp: 0 };
    }
    // C(a+b, a) = Π_{i=1}^{min} (max + i)/i
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    let mut binom = Scaled::new(1.0);
    for i in 1..=lo {
        binom = binom.mul(Scaled::new((f64::from(hi) + f64::from(i)) / f64::from(i)));
    }
    let mut v = binom
        .sqrt()
        .mul(Scaled::new(sin_half).powi(a))
        .mul(Scaled::new(cos_half).powi(b));
    // ξ_{mn} = (−1)^{m−n} if n < m
    if n < m && (i64::from(m) - i64::from(n)) % 2 != 0 {
        v.mant = -v.mant;
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::quadrature::gauss_legendre;

    /// Independent reference: the explicit sum (module docs), for small l.
    fn d_explicit(l: i32, m: i32, n: i32, theta: f64) -> f64 {
        if m.abs() > l || n.abs() > l {
            return 0.0;
        }
        let fact = |k: i32| -> f64 { (1..=k).map(f64::from).product() };
        let (c, s) = ((0.5 * theta).cos(), (0.5 * theta).sin());
        let pre = (fact(l + m) * fact(l - m) * fact(l + n) * fact(l - n)).sqrt();
        let mut sum = 0.0;
        for k in 0..=(2 * l) {
            if l + n - k < 0 || m - n + k < 0 || l - m - k < 0 {
                continue;
            }
            let sign = if (k + m - n).rem_euclid(2) == 0 {
                1.0
            } else {
                -1.0
            };
            sum += sign * pre / (fact(l + n - k) * fact(k) * fact(m - n + k) * fact(l - m - k))
                * c.powi(2 * l + n - m - 2 * k)
                * s.powi(m - n + 2 * k);
        }
        sum
    }

    #[test]
    fn anchors_and_closed_forms() {
        for i in 0..=40 {
            let mu = -1.0 + 2.0 * f64::from(i) / 40.0;
            let s2 = 1.0 - mu * mu;
            let d00 = wigner_d(0, 0, mu, 4);
            let p = [
                1.0,
                mu,
                0.5 * (3.0 * mu * mu - 1.0),
                0.5 * (5.0 * mu.powi(3) - 3.0 * mu),
                (35.0 * mu.powi(4) - 30.0 * mu * mu + 3.0) / 8.0,
            ];
            for l in 0..=4 {
                assert!((d00[l] - p[l]).abs() < 1e-15, "P_{l}({mu})");
            }
            let d02 = wigner_d(0, 2, mu, 4);
            assert_eq!(&d02[..2], &[0.0, 0.0]);
            // √((l−2)!/(l+2)!) P_l^2 with P_l^2 = (1−μ²) P_l''
            let p2 = [3.0 * s2, 15.0 * mu * s2, 7.5 * (7.0 * mu * mu - 1.0) * s2];
            let norms = [1.0 / 24f64, 1.0 / 120.0, 2.0 / 720.0];
            for (j, l) in (2..=4).enumerate() {
                let expect = norms[j].sqrt() * p2[j];
                assert!((d02[l] - expect).abs() < 1e-15, "d^{l}_02({mu})");
            }
            assert!((d02[2] - 6f64.sqrt() / 4.0 * s2).abs() < 1e-15);
            let d22 = wigner_d(2, 2, mu, 3);
            assert!((d22[2] - (0.5 * (1.0 + mu)).powi(2)).abs() < 1e-15);
            // d^3_22 = ((1+μ)/2)² (3μ − 2)
            assert!((d22[3] - (0.5 * (1.0 + mu)).powi(2) * (3.0 * mu - 2.0)).abs() < 1e-15);
            let d2m2 = wigner_d(2, -2, mu, 3);
            assert!((d2m2[2] - (0.5 * (1.0 - mu)).powi(2)).abs() < 1e-15);
            // d^3_{2,−2} = ((1−μ)/2)² (3μ + 2)
            assert!((d2m2[3] - (0.5 * (1.0 - mu)).powi(2) * (3.0 * mu + 2.0)).abs() < 1e-15);
            let d10 = wigner_d(1, 0, mu, 1);
            assert!((d10[1] + s2.sqrt() / 2f64.sqrt()).abs() < 1e-15);
        }
    }

    #[test]
    fn matches_explicit_sum_for_all_small_indices() {
        let mut worst: f64 = 0.0;
        for &theta in &[
            0.0,
            0.1,
            0.7,
            1.3,
            std::f64::consts::FRAC_PI_2,
            2.2,
            3.0,
            std::f64::consts::PI,
        ] {
            let mu = f64::cos(theta);
            for m in -8..=8 {
                for n in -8..=8 {
                    let d = wigner_d(m, n, mu, 10);
                    for l in 0..=10 {
                        let e = d_explicit(l, m, n, theta);
                        worst = worst.max((d[l as usize] - e).abs());
                        assert!(
                            (d[l as usize] - e).abs() < 1e-13,
                            "l={l} m={m} n={n} θ={theta}: {} vs {e}",
                            d[l as usize]
                        );
                    }
                }
            }
        }
        assert!(worst < 1e-13);
    }

    #[test]
    fn symmetry_relations() {
        let l_max = 60;
        for &mu in &[-0.97, -0.5, -0.1, 0.0, 0.33, 0.8, 0.999] {
            for m in -5..=5 {
                for n in -5..=5 {
                    let d = wigner_d(m, n, mu, l_max);
                    let d_nm = wigner_d(n, m, mu, l_max);
                    let d_mn_neg = wigner_d(-n, -m, mu, l_max);
                    let d_minus = wigner_d(-m, -n, mu, l_max);
                    let d_reflect = wigner_d(m, -n, -mu, l_max);
                    let sign_mn = if (m - n).rem_euclid(2) == 0 {
                        1.0
                    } else {
                        -1.0
                    };
                    for l in 0..=l_max {
                        let sign_lm = if (l as i32 + m).rem_euclid(2) == 0 {
                            1.0
                        } else {
                            -1.0
                        };
                        assert!((d[l] - sign_mn * d_nm[l]).abs() < 1e-14);
                        assert!((d[l] - d_mn_neg[l]).abs() < 1e-14);
                        assert!((d_minus[l] - sign_mn * d[l]).abs() < 1e-14);
                        assert!(
                            (d[l] - sign_lm * d_reflect[l]).abs() < 1e-14,
                            "l={l} m={m} n={n}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn orthogonality_small_l() {
        let l_max = 40;
        let (x, w) = gauss_legendre(l_max + 1);
        for &(m, n) in &[(0, 0), (0, 2), (2, 2), (2, -2), (3, -1), (7, 4)] {
            let rows: Vec<Vec<f64>> = x.iter().map(|&mu| wigner_d(m, n, mu, l_max)).collect();
            let s0 = m.unsigned_abs().max(n.unsigned_abs()) as usize;
            for l in s0..=l_max {
                for lp in s0..=l_max {
                    let integral: f64 = rows.iter().zip(&w).map(|(r, &wi)| wi * r[l] * r[lp]).sum();
                    let expect = if l == lp {
                        2.0 / (2.0 * l as f64 + 1.0)
                    } else {
                        0.0
                    };
                    assert!(
                        (integral - expect).abs() < 1e-14,
                        "(m,n)=({m},{n}) l={l} l'={lp}: {integral}"
                    );
                }
            }
        }
    }

    #[test]
    fn unitarity_including_large_m() {
        // Σ_n d^l_{mn}² = 1, all n = −l..l, for fixed l and m; large l and m
        // exercise the scaled start (sin(θ/2)^{|m−n|} underflows for θ small).
        for &(l, ms) in &[
            (6usize, &[0, 3, -6][..]),
            (1500, &[0, 2, 700, 1499, -1500][..]),
        ] {
            for &mu in &[-0.999_999, -0.3, 0.0, 0.6, 0.999_99, 1.0] {
                for &m in ms {
                    let mut sum = 0.0;
                    for n in -(l as i32)..=(l as i32) {
                        let d = wigner_d(m, n, mu, l);
                        assert!(d.iter().all(|v| v.is_finite()));
                        sum += d[l] * d[l];
                    }
                    assert!((sum - 1.0).abs() < 1e-12, "l={l} m={m} μ={mu}: Σ = {sum}");
                }
            }
        }
    }

    #[test]
    fn endpoints() {
        for l in 0..20 {
            for m in -3..=3 {
                for n in -3..=3 {
                    let d1 = wigner_d(m, n, 1.0, 20);
                    let dm1 = wigner_d(m, n, -1.0, 20);
                    let s0 = m.abs().max(n.abs()) as usize;
                    let e1 = if m == n && l >= s0 { 1.0 } else { 0.0 };
                    let sign = if (l as i32 + m).rem_euclid(2) == 0 {
                        1.0
                    } else {
                        -1.0
                    };
                    let em1 = if m == -n && l >= s0 { sign } else { 0.0 };
                    assert_eq!(d1[l], e1, "d^{l}_({m},{n})(0)");
                    assert!((dm1[l] - em1).abs() < 1e-15, "d^{l}_({m},{n})(π)");
                }
            }
        }
    }

    #[test]
    fn large_l_orthonormality() {
        // l up to 20 000: Gauss rule exact for degree 2·20 000.
        let l_max = 20_000;
        let (x, w) = gauss_legendre(l_max + 2);
        let ls = [0usize, 1, 2, 3, 5000, 19_998, 19_999, 20_000];
        for &(m, n) in &[(2, -2), (40, 2)] {
            let mut gram = [[0.0f64; 8]; 8];
            let mut buf = vec![0.0; l_max + 1];
            for (&mu, &wi) in x.iter().zip(&w) {
                wigner_d_into(m, n, mu, &mut buf);
                for (i, &l) in ls.iter().enumerate() {
                    for (j, &lp) in ls.iter().enumerate() {
                        gram[i][j] += wi * buf[l] * buf[lp];
                    }
                }
                assert!(buf.iter().all(|v| v.is_finite()));
            }
            let s0 = m.abs().max(n.abs()) as usize;
            for (i, &l) in ls.iter().enumerate() {
                for (j, &lp) in ls.iter().enumerate() {
                    let expect = if l == lp && l >= s0 {
                        2.0 / (2.0 * l as f64 + 1.0)
                    } else {
                        0.0
                    };
                    // relative to the norm 2/(2l+1) of the larger l
                    let scale = 2.0 / (2.0 * l.max(lp) as f64 + 1.0);
                    eprintln!(
                        "ORTHO {m} {n} {l} {lp}: {:e}",
                        (gram[i][j] - expect).abs() / scale
                    );
                    assert!(
                        (gram[i][j] - expect).abs() < 2e-11 * scale,
                        "(m,n)=({m},{n}) l={l} l'={lp}: {} vs {expect}",
                        gram[i][j]
                    );
                }
            }
        }
    }

    #[test]
    fn scaled_helpers() {
        let (f, e) = frexp(12.0);
        assert_eq!((f, e), (0.75, 4));
        assert_eq!(ldexp(0.75, 4), 12.0);
        assert_eq!(ldexp(1.0, -1074), f64::from_bits(1));
        assert_eq!(ldexp(1.0, -1200), 0.0);
        assert_eq!(HUGE, 2f64.powi(600));
        assert_eq!(INV_HUGE, 2f64.powi(-600));
        let p = Scaled::new(0.5).powi(3000);
        assert_eq!((p.mant, p.exp), (0.5, -2999));
        let r = Scaled::new(2.0).powi(7).sqrt();
        assert!((ldexp(r.mant, r.exp) - 128f64.sqrt()).abs() < 1e-14);
    }

    /// `d^{50000}_{mn}(μ)` against 50-digit values (mpmath: the same start
    /// value and recurrence, in multiprecision).
    #[test]
    #[allow(clippy::excessive_precision)]
    fn l_50000_against_multiprecision() {
        let reference: [(i32, i32, f64, f64); 20] = [
            (0, 0, 0.3, -0.0013160884820837062353),
            (0, 0, -0.7, -0.0041854510947933888722),
            (0, 0, 0.9999999, -0.15396283740493327198),
            (0, 0, 0.05, 0.0033414619270238939449),
            (2, 2, 0.3, -0.0013158884153356085377),
            (2, 2, -0.7, -0.0041853448730971143035),
            (2, 2, 0.9999999, -0.15396283623219699658),
            (2, 2, 0.05, 0.0033413661846033156418),
            (2, -2, 0.3, -0.0013164600255911674534),
            (2, -2, -0.7, -0.0041854698279811675831),
            (2, -2, 0.9999999, -0.16974604230368488067),
            (2, -2, 0.05, 0.003341567730711155668),
            (0, 2, 0.3, 0.0013161313536917093282),
            (0, 2, -0.7, 0.0041854292390137321688),
            (0, 2, 0.9999999, 0.15982651816665168174),
            (0, 2, 0.05, -0.0033414644477068996257),
            (1000, 2, 0.3, -0.0011845275021575445503),
            (1000, 2, -0.7, -0.0035627282589586610236),
            (1000, 2, 0.9999999, 0.0), // 4.7e-1516
            (1000, 2, 0.05, -0.0035527960552111009599),
        ];
        let mut buf = vec![0.0; 50_001];
        for (m, n, mu, expect) in reference {
            wigner_d_into(m, n, mu, &mut buf);
            let err = (buf[50_000] - expect).abs();
            eprintln!("WREF {m} {n} {mu}: {err:e} rel {:e}", err / expect.abs());
            assert!(
                err < 1e-13,
                "d^50000_({m},{n})({mu}) = {} vs {expect}",
                buf[50_000]
            );
        }
    }
}
