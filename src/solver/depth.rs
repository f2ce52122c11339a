//! Depth integrals of exponential attenuation through a slab, shared by
//! the single-scattering correction (`truncation`) and the double
//! scattering of the secondary correction (`secondary`).

/// `∫_a^{a+τ} exp(−(α + c t)) dt`, without overflow for either sign of `c`
/// (`τ` may be infinite when `c > 0`).
pub(crate) fn segment(alpha: f64, c: f64, a: f64, tau: f64) -> f64 {
    if tau <= 0.0 {
        return 0.0;
    }
    if (c * tau).abs() < 1e-12 {
        return (-(alpha + c * a)).exp() * tau;
    }
    if c > 0.0 {
        let through = if tau.is_finite() {
            -(-c * tau).exp_m1()
        } else {
            1.0
        };
        (-(alpha + c * a)).exp() * through / c
    } else {
        (-(alpha + c * (a + tau))).exp() * -(c * tau).exp_m1() / -c
    }
}

/// `E_T(s) = ∫_0^T e^{−st} dt` for `s ≥ 0` (`T` may be infinite when `s > 0`).
pub(crate) fn e_int(s: f64, t: f64) -> f64 {
    if t.is_infinite() {
        return 1.0 / s;
    }
    let x = s * t;
    if x.abs() < 1e-8 {
        t * (1.0 - 0.5 * x)
    } else {
        -(-x).exp_m1() / s
    }
}

/// `M_n(s) = ∫_0^T tⁿ e^{−st} dt` for `n = 1, 3`, `s > 0`, `T` finite.
fn moment(n: i32, s: f64, t: f64) -> f64 {
    let x = s * t;
    if x < 1.0 {
        // T^{n+1} Σ_k (−x)^k / (k! (n + 1 + k))
        let (mut term, mut sum) = (1.0, 0.0);
        for k in 0..40 {
            sum += term / (n + 1 + k) as f64;
            term *= -x / (k + 1) as f64;
        }
        t.powi(n + 1) * sum
    } else {
        let e = (-x).exp();
        match n {
            1 => (1.0 - e * (1.0 + x)) / (s * s),
            _ => (6.0 - e * (6.0 + x * (6.0 + x * (3.0 + x)))) / s.powi(4),
        }
    }
}

/// The divided difference `(E_T(x) − E_T(y))/(y − x)` for `x, y > 0`, stable
/// as `y → x` (then `−E'` at the midpoint plus its `(y − x)²` term).
pub(crate) fn divided_difference(x: f64, y: f64, t: f64) -> f64 {
    if t.is_infinite() {
        return 1.0 / (x * y);
    }
    let d = y - x;
    if (d * t).abs() > 1e-3 {
        return (e_int(x, t) - e_int(y, t)) / d;
    }
    let s = 0.5 * (x + y);
    moment(1, s, t) + d * d / 24.0 * moment(3, s, t)
}
