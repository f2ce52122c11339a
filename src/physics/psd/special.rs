//! Special functions of the size distributions: `ln Γ`, the regularized
//! incomplete gamma functions and the quantiles built on them.

use std::f64::consts::PI;

/// `ln Γ(x)` for `x > 0`: Lanczos approximation (g = 7, 9 terms; relative
/// error ~1e-15), with `Γ(x) = Γ(x+1)/x` below 0.5.
pub(crate) fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return ln_gamma(x + 1.0) - x.ln();
    }
    let x = x - 1.0;
    let mut a = C[0];
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    let t = x + G + 0.5;
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised incomplete gamma functions `(P(a, x), Q(a, x))`, by the series
/// for `x < a + 1` and Lentz's continued fraction otherwise (Numerical
/// Recipes, 3rd ed., §6.2).
pub(crate) fn gamma_pq(a: f64, x: f64) -> (f64, f64) {
    if x <= 0.0 {
        return (0.0, 1.0);
    }
    let ln_pref = -x + a * x.ln() - ln_gamma(a);
    if x < a + 1.0 {
        let (mut ap, mut del) = (a, 1.0 / a);
        let mut sum = del;
        for _ in 0..100_000_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        let p = (sum.ln() + ln_pref).exp();
        (p, 1.0 - p)
    } else {
        const TINY: f64 = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..100_000_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < TINY {
                d = TINY;
            }
            c = b + an / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        let q = (h.ln() + ln_pref).exp();
        (1.0 - q, q)
    }
}

/// `y` with `P(a, y) = p` (`lower`) or `Q(a, y) = p`, by bisection in `ln y`.
pub(super) fn gamma_quantile(a: f64, p: f64, lower: bool) -> f64 {
    let tail = |ln_y: f64| {
        let (pp, qq) = gamma_pq(a, ln_y.exp());
        if lower { pp } else { qq }
    };
    // The tail grows with y for the lower tail and shrinks for the upper.
    let (mut lo, mut hi) = ((1e-300f64).ln(), (a + 60.0 * a.sqrt() + 800.0).ln());
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        let below = tail(mid) < p;
        if below == lower {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-12 {
            break;
        }
    }
    (0.5 * (lo + hi)).exp()
}

/// `z > 0` with `Pr(Z > z) = p` for a standard normal `Z`
/// (`Pr(Z > z) = ½ Q(½, z²/2)`), by bisection.
pub(super) fn normal_upper_quantile(p: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if 0.5 * gamma_pq(0.5, 0.5 * mid * mid).1 > p {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-13 {
            break;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs()
    }

    /// Published values: Γ(½) = √π, Γ(10) = 9!, Γ(1/3) = 2.678938534707747…
    /// (Abramowitz & Stegun, Table 6.1); erf(1) = 0.8427007929497149 and
    /// erf(0.5) = 0.5204998778130465 (A&S Table 7.1, P(½, x²) = erf x);
    /// P(1, x) = 1 − e^{−x}; the standard normal upper quantile at 1e-6,
    /// 4.753424308822899 (A&S 26.2.23 tables).
    #[test]
    fn special_functions_match_published_values() {
        assert!((ln_gamma(0.5) - PI.sqrt().ln()).abs() < 1e-14);
        assert!((ln_gamma(10.0) - 362_880f64.ln()).abs() < 1e-13);
        assert!((ln_gamma(1.0 / 3.0) - 2.678_938_534_707_747_6f64.ln()).abs() < 1e-14);
        assert!(ln_gamma(1.0).abs() < 1e-15 && ln_gamma(2.0).abs() < 1e-15);
        assert!((gamma_pq(0.5, 1.0).0 - 0.842_700_792_949_714_9).abs() < 1e-14);
        assert!((gamma_pq(0.5, 0.25).0 - 0.520_499_877_813_046_5).abs() < 1e-14);
        for x in [0.01, 0.5, 2.0, 7.5, 40.0] {
            let (p, q) = gamma_pq(1.0, x);
            assert!((p - (1.0 - (-x).exp())).abs() < 1e-14, "x={x}");
            assert!(rel(q, (-x).exp()) < 1e-12, "x={x}");
        }
        assert!((normal_upper_quantile(1e-6) - 4.753_424_308_822_899).abs() < 1e-9);
        // Quantiles invert P and Q, also for a narrow (large-shape) law.
        for a in [0.3, 3.0, 1e6] {
            let lo = gamma_quantile(a, 1e-6, true);
            let hi = gamma_quantile(a, 1e-6, false);
            assert!(rel(gamma_pq(a, lo).0, 1e-6) < 1e-6, "a={a}");
            assert!(rel(gamma_pq(a, hi).1, 1e-6) < 1e-6, "a={a}");
        }
    }
}
