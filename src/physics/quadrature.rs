//! Gauss–Legendre quadrature.
//!
//! [`gauss_legendre`] returns the `n` nodes (ascending) and weights of the
//! `n`-point Gauss–Legendre rule on `[-1, 1]` for `n = 1 ..= 100 000` in
//! `O(n)` time. Nodes are accurate to `≲ 2e-16` absolute; weights to a few
//! ulps relative, except the ~32 outermost weights of very large rules, which
//! carry the rounding of an `O(n)` recurrence (relative `1e-14` at
//! `n = 40 000`, i.e. `5e-23` absolute). Method:
//!
//! * `n ≤ 100`: Newton's method in `θ` (`x = cos θ`) on `P_n(cos θ)`, with
//!   `P_n` from the three-term recurrence (`O(n²)`, negligible at this size).
//! * `n > 100`: the same Newton iteration, but `P_n(cos θ)` and `dP_n/dθ` are
//!   evaluated in `O(1)` by the Stieltjes asymptotic series (Szegő,
//!   *Orthogonal Polynomials*, §8.21; the "interior" expansion used by Hale &
//!   Townsend 2013, SIAM J. Sci. Comput. 35, A652):
//!
//!   ```text
//!   P_n(cos θ) = C_n Σ_{m≥0} h_{n,m} cos α_{n,m} / (2 sin θ)^{m+½},
//!   α_{n,m} = (n+m+½)θ − (m+½)π/2,   C_n = (2/√π) Γ(n+1)/Γ(n+3/2),
//!   h_{n,0} = 1,  h_{n,m} = h_{n,m−1} (m−½)² / (m (n+m+½)),
//!   ```
//!
//!   used where `n sin θ ≥ 100` (the terms then fall below `1e-17` of the
//!   leading one within a dozen terms). The `O(1)` nodes nearest to `±1`
//!   (about 32 at each end) are done with the recurrence, `O(n)` each, so the
//!   whole rule is `O(n)`. Initial guesses: Olver's uniform approximation
//!   `θ_k ≈ ψ + (ψ cot ψ − 1)/(8ψ ν²)`, `ψ = j_{0,k}/ν`, `ν = n+½`, with the
//!   Bessel zeros `j_{0,k}` from McMahon's expansion (as in Bogaert 2014,
//!   SIAM J. Sci. Comput. 36, A1008, whose iteration-free method is the
//!   alternative to this one).
//!
//! Weights: `w_k = 2 / (dP_n/dθ)²` at `θ_k` (equivalent to
//! `2/((1−x²) P_n'(x)²)`), which is free of cancellation near `x = ±1`.

use std::f64::consts::{FRAC_PI_2, PI};

/// Largest `n` handled entirely by Newton on the three-term recurrence.
const NEWTON_ONLY_MAX: usize = 100;

/// The asymptotic series is used where `n sin θ` is at least this.
const ASYMPTOTIC_MIN_N_SIN: f64 = 100.0;

/// The `n`-point Gauss–Legendre rule on `[-1, 1]`: `(nodes, weights)`, nodes
/// ascending, symmetric about 0 (bit-exact mirror images), weights summing to
/// 2. Exact for polynomials of degree `≤ 2n − 1`. `n = 0` gives empty vectors.
///
/// See the module documentation for the method (Newton / Stieltjes
/// asymptotics, `O(n)`).
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    if n <= NEWTON_ONLY_MAX {
        gauss_legendre_impl(n, f64::INFINITY)
    } else {
        gauss_legendre_impl(n, ASYMPTOTIC_MIN_N_SIN)
    }
}

/// The `n`-point Gauss–Legendre rule mapped linearly onto `[a, b]`: nodes
/// ascending (if `a < b`), weights summing to `b − a`.
pub fn gauss_legendre_on(n: usize, a: f64, b: f64) -> (Vec<f64>, Vec<f64>) {
    let (x, w) = gauss_legendre(n);
    let half = 0.5 * (b - a);
    let mid = 0.5 * (a + b);
    let nodes = x.iter().map(|&t| mid + half * t).collect();
    let weights = w.iter().map(|&wi| half * wi).collect();
    (nodes, weights)
}

/// The per-hemisphere ("double-Gauss") quadrature of discrete ordinates: the
/// `n`-point Gauss–Legendre rule on `(0, 1)`, nodes ascending, weights
/// summing to 1. The full double-Gauss set on `[-1, 1]` is these nodes and
/// their negatives (`2n` streams).
pub fn double_gauss(n: usize) -> (Vec<f64>, Vec<f64>) {
    gauss_legendre_on(n, 0.0, 1.0)
}

/// The per-hemisphere quadrature split at the cosine `split ∈ (0, 1)`: the
/// `n`-point Gauss–Legendre rule on `(0, split)` and on `(split, 1)`, nodes
/// ascending, weights summing to 1. Exact on each part for polynomials of
/// degree `≤ 2n − 1`, hence on `(0, 1)` at least as far as
/// [`double_gauss`]`(n)`, and exponentially convergent for integrands smooth
/// on each side of `split` (light under a binder/air interface, whose
/// internal reflection has a square-root kink at the critical cosine:
/// Jin & Stamnes 1994, the split quadrature of coupled atmosphere–ocean
/// discrete ordinates).
pub fn split_gauss(n: usize, split: f64) -> (Vec<f64>, Vec<f64>) {
    let (mut x, mut w) = gauss_legendre_on(n, 0.0, split);
    let (x2, w2) = gauss_legendre_on(n, split, 1.0);
    x.extend(x2);
    w.extend(w2);
    (x, w)
}

/// Shared driver. Nodes with `n sin θ ≥ asym_min` use the asymptotic series;
/// `asym_min = ∞` forces the recurrence everywhere.
fn gauss_legendre_impl(n: usize, asym_min: f64) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    if n == 0 {
        return (x, w);
    }
    let nf = n as f64;
    let nu = nf + 0.5;
    let cn = stieltjes_constant(n);
    let half = n / 2;
    // k = 1..=half: θ_k ascending in (0, π/2), i.e. the k-th largest node.
    for k in 1..=half {
        let psi = bessel_j0_zero(k) / nu;
        let mut theta = psi + (psi / psi.tan() - 1.0) / (8.0 * psi * nu * nu);
        if !(theta > 0.0 && theta < FRAC_PI_2) {
            theta = PI * (4.0 * k as f64 - 1.0) / (4.0 * nf + 2.0);
        }
        let use_asym = nf * theta.sin() >= asym_min;
        let (theta, dp) = if use_asym {
            newton_theta(theta, |t| stieltjes(n, t))
        } else {
            newton_theta(theta, |t| legendre_theta(n, t))
        };
        let dp = if use_asym { cn * dp } else { dp };
        let xk = theta.cos();
        let wk = 2.0 / (dp * dp);
        x[n - k] = xk;
        x[k - 1] = -xk;
        w[n - k] = wk;
        w[k - 1] = wk;
    }
    if n % 2 == 1 {
        // Middle node x = 0 exactly: dP_n/dθ at θ = π/2 is ±n P_{n−1}(0).
        let (_, dp) = legendre_theta(n, FRAC_PI_2);
        x[half] = 0.0;
        w[half] = 2.0 / (dp * dp);
    }
    (x, w)
}

/// Newton's method in `θ` on `f(θ)`, where `eval` returns `(f, df/dθ)`.
/// Returns the root and `df/dθ` evaluated there.
fn newton_theta(mut theta: f64, eval: impl Fn(f64) -> (f64, f64)) -> (f64, f64) {
    let mut last_step = f64::INFINITY;
    for _ in 0..50 {
        let (f, df) = eval(theta);
        let step = f / df;
        theta -= step;
        // Converged once the step is at the rounding level of θ, or once the
        // steps stop shrinking (rounding noise).
        if step.abs() <= 4.0 * f64::EPSILON * theta.abs() || step.abs() >= last_step {
            break;
        }
        last_step = step.abs();
    }
    let (_, df) = eval(theta);
    (theta, df)
}

/// `(P_n(cos θ), dP_n/dθ)` by the three-term recurrence (`O(n)`), `n ≥ 1`,
/// for `0 < θ < π`.
///
/// For `θ < π/3` the recurrence is run on `u = 1 − cos θ = 2 sin²(θ/2)` and
/// the differences `D_j = P_j − P_{j−1}`
/// (`D_{j+1} = (j D_j − (2j+1) u P_j)/(j+1)`), so that near `θ = 0` the result
/// depends on `θ` itself and not on the rounded `cos θ` (whose `1 − x` has
/// only absolute accuracy `ε`); elsewhere the plain recurrence in `x` is
/// the more accurate one.
fn legendre_theta(n: usize, theta: f64) -> (f64, f64) {
    let nf = n as f64;
    if theta < std::f64::consts::FRAC_PI_3 {
        let half_sin = (0.5 * theta).sin();
        let u = 2.0 * half_sin * half_sin;
        let mut p = 1.0 - u; // P_1
        let mut d = -u; // D_1 = P_1 − P_0
        for j in 1..n {
            let jf = j as f64;
            d = (jf * d - (2.0 * jf + 1.0) * u * p) / (jf + 1.0);
            p += d;
        }
        // dP_n/dθ = −sin θ P_n'(x) = n (x P_n − P_{n−1}) / sin θ = n (D_n − u P_n) / sin θ
        (p, nf * (d - u * p) / theta.sin())
    } else {
        let (s, x) = theta.sin_cos();
        let mut p_prev = 1.0;
        let mut p = x;
        for j in 1..n {
            let jf = j as f64;
            let p_next = ((2.0 * jf + 1.0) * x * p - jf * p_prev) / (jf + 1.0);
            p_prev = p;
            p = p_next;
        }
        (p, nf * (x * p - p_prev) / s)
    }
}

/// `(P_n(x), P_{n−1}(x))` by the three-term recurrence, `n ≥ 1`.
#[cfg(test)]
fn legendre_pair(n: usize, x: f64) -> (f64, f64) {
    let mut p_prev = 1.0;
    let mut p = x;
    for j in 1..n {
        let jf = j as f64;
        let p_next = ((2.0 * jf + 1.0) * x * p - jf * p_prev) / (jf + 1.0);
        p_prev = p;
        p = p_next;
    }
    (p, p_prev)
}

/// The Stieltjes series without its constant `C_n`: returns
/// `(P_n(cos θ)/C_n, (dP_n/dθ)/C_n)`, valid where `n sin θ ≫ 1`.
fn stieltjes(n: usize, theta: f64) -> (f64, f64) {
    let nf = n as f64;
    let (s, c) = theta.sin_cos();
    let cot = c / s;
    let two_s = 2.0 * s;
    // term_m = h_{n,m} / (2 sin θ)^{m+½}
    let term0 = 1.0 / two_s.sqrt();
    let mut term = term0;
    let mut f = 0.0;
    let mut df = 0.0;
    for m in 0..60 {
        let mf = m as f64;
        let k = nf + mf + 0.5;
        let alpha = k * theta - (mf + 0.5) * FRAC_PI_2;
        let (sa, ca) = alpha.sin_cos();
        f += term * ca;
        df -= term * (k * sa + (mf + 0.5) * cot * ca);
        term *= (mf + 0.5) * (mf + 0.5) / ((mf + 1.0) * (nf + mf + 1.5) * two_s);
        if term < 1e-18 * term0 {
            break;
        }
    }
    (f, df)
}

/// `C_n = (2/√π) Γ(n+1)/Γ(n+3/2)`, to a few ulps.
///
/// Small `n`: the exact product `(2/√π) Π_{j=1}^n j/(j+½)`. Large `n`: Stirling's
/// series for `ln Γ(n+1) − ln Γ(n+3/2)`, arranged without cancellation as
/// `½ − (n+½) ln(1 + 1/(2n+2)) − ½ ln(n+3/2) + S(n+1) − S(n+3/2)`.
fn stieltjes_constant(n: usize) -> f64 {
    let two_over_sqrt_pi = std::f64::consts::FRAC_2_SQRT_PI;
    if n < 64 {
        // Π_{j=1}^n j/(j+½) = Γ(n+1) Γ(3/2) / Γ(n+3/2)
        let mut r = 4.0 / PI;
        for j in 1..=n {
            let jf = j as f64;
            r *= jf / (jf + 0.5);
        }
        return r;
    }
    let nf = n as f64;
    let expo = 0.5 - (nf + 0.5) * (0.5 / (nf + 1.0)).ln_1p() + stirling_tail(nf + 1.0)
        - stirling_tail(nf + 1.5);
    two_over_sqrt_pi * expo.exp() / (nf + 1.5).sqrt()
}

/// `S(z) = ln Γ(z) − [(z − ½) ln z − z + ½ ln 2π]` for `z ≥ 60` (Bernoulli series).
fn stirling_tail(z: f64) -> f64 {
    let r = 1.0 / z;
    let r2 = r * r;
    r * (1.0 / 12.0
        + r2 * (-1.0 / 360.0 + r2 * (1.0 / 1260.0 + r2 * (-1.0 / 1680.0 + r2 * (1.0 / 1188.0)))))
}

/// `k`-th positive zero of the Bessel function `J_0` (`k ≥ 1`): tabulated for
/// `k ≤ 10`, McMahon's asymptotic expansion beyond (error < 1e-12 there).
fn bessel_j0_zero(k: usize) -> f64 {
    const J0_ZEROS: [f64; 10] = [
        2.404_825_557_695_773,
        5.520_078_110_286_311,
        8.653_727_912_911_013,
        11.791_534_439_014_28,
        14.930_917_708_487_79,
        18.071_063_967_910_92,
        21.211_636_629_879_26,
        24.352_471_530_749_3,
        27.493_479_132_040_25,
        30.634_606_468_431_98,
    ];
    if k >= 1 && k <= J0_ZEROS.len() {
        return J0_ZEROS[k - 1];
    }
    let beta = (k as f64 - 0.25) * PI;
    let r = 1.0 / (8.0 * beta);
    let r2 = r * r;
    beta + r * (1.0 + r2 * (-124.0 / 3.0 + r2 * (120_928.0 / 15.0 + r2 * (-401_743_168.0 / 105.0))))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn small_n_closed_forms() {
        let (x, w) = gauss_legendre(1);
        assert_eq!(x, vec![0.0]);
        assert!((w[0] - 2.0).abs() < 1e-15);

        let (x, w) = gauss_legendre(2);
        let r = 1.0 / 3f64.sqrt();
        assert!(
            (x[0] + r).abs() < 2e-16 && (x[1] - r).abs() < 2e-16,
            "{x:?}"
        );
        assert!((w[0] - 1.0).abs() < 1e-15 && (w[1] - 1.0).abs() < 1e-15);

        let (x, w) = gauss_legendre(3);
        let r = (0.6f64).sqrt();
        assert!((x[0] + r).abs() < 1e-16 && x[1] == 0.0 && (x[2] - r).abs() < 1e-16);
        assert!((w[0] - 5.0 / 9.0).abs() < 1e-15 && (w[1] - 8.0 / 9.0).abs() < 1e-15);

        let (x, w) = gauss_legendre(4);
        let a = 2.0 / 7.0 * (6.0f64 / 5.0).sqrt();
        let x_ref = [
            -(3.0 / 7.0 + a).sqrt(),
            -(3.0 / 7.0 - a).sqrt(),
            (3.0 / 7.0 - a).sqrt(),
            (3.0 / 7.0 + a).sqrt(),
        ];
        let s30 = 30f64.sqrt();
        let w_ref = [
            (18.0 - s30) / 36.0,
            (18.0 + s30) / 36.0,
            (18.0 + s30) / 36.0,
            (18.0 - s30) / 36.0,
        ];
        assert!(max_abs_diff(&x, &x_ref) < 2e-16);
        assert!(max_abs_diff(&w, &w_ref) < 4e-16);

        assert_eq!(gauss_legendre(0), (vec![], vec![]));
    }

    #[test]
    fn polynomial_exactness_and_weight_sum() {
        for n in [1usize, 2, 3, 5, 8, 13, 20, 50, 99, 100, 101, 150, 257] {
            let (x, w) = gauss_legendre(n);
            assert_eq!(x.len(), n);
            let sum: f64 = w.iter().sum();
            assert!((sum - 2.0).abs() < 1e-14, "n={n}: Σw = {sum}");
            // ascending, symmetric
            for i in 1..n {
                assert!(x[i] > x[i - 1], "n={n}: not ascending at {i}");
            }
            for i in 0..n {
                assert_eq!(x[i], -x[n - 1 - i]);
                assert_eq!(w[i], w[n - 1 - i]);
            }
            // ∫ P_k dx = 2 δ_k0 for k ≤ 2n − 1 (orthogonality; robust for large k)
            for k in 1..(2 * n) {
                let integral: f64 = x
                    .iter()
                    .zip(&w)
                    .map(|(&xi, &wi)| wi * legendre_pair(k, xi).0)
                    .sum();
                assert!(integral.abs() < 2e-14, "n={n}, k={k}: ∫P_k = {integral}");
            }
            // monomials: ∫ x^k dx = 2/(k+1) for even k ≤ 2n − 1
            for k in (0..(2 * n).min(40)).step_by(2) {
                let integral: f64 = x
                    .iter()
                    .zip(&w)
                    .map(|(&xi, &wi)| wi * xi.powi(k as i32))
                    .sum();
                let exact = 2.0 / (k as f64 + 1.0);
                assert!((integral - exact).abs() < 2e-14, "n={n}, x^{k}: {integral}");
            }
            // one degree beyond is not exact (sanity of the test itself)
            if n <= 8 {
                let k = 2 * n;
                let integral: f64 = x
                    .iter()
                    .zip(&w)
                    .map(|(&xi, &wi)| wi * xi.powi(k as i32))
                    .sum();
                assert!((integral - 2.0 / (k as f64 + 1.0)).abs() > 1e-10);
            }
        }
    }

    #[test]
    fn stieltjes_constant_matches_product() {
        let mut r = 4.0 / PI;
        for j in 1..=400usize {
            let jf = j as f64;
            r *= jf / (jf + 0.5);
            if j >= 64 {
                let c = stieltjes_constant(j);
                assert!((c / r - 1.0).abs() < 3e-15, "n={j}: {c} vs {r}");
            }
        }
    }

    #[test]
    fn stieltjes_series_matches_recurrence() {
        // θ ≤ π/2 only: beyond, the recurrence in x = cos θ (the reference
        // here) loses accuracy as θ → π.
        for n in [200usize, 1000, 5000] {
            let cn = stieltjes_constant(n);
            for i in 1..=25 {
                let theta = i as f64 / 50.0 * PI;
                if (n as f64) * theta.sin() < ASYMPTOTIC_MIN_N_SIN {
                    continue;
                }
                let (f, df) = stieltjes(n, theta);
                let (p, dp) = legendre_theta(n, theta);
                // compare on the amplitude scale sqrt(2/(π n sin θ))
                let amp = (2.0 / (PI * n as f64 * theta.sin())).sqrt();
                let ef = (cn * f - p).abs() / amp;
                let edf = (cn * df - dp).abs() / (amp * n as f64);
                // The phase (n+½)θ carries a rounding error ~ε nθ (equivalent to
                // a one-ulp change of θ, harmless for the nodes; for dP/dθ at the
                // zeros, where it matters for the weights, it is second order).
                let tol = 1e-13 + 4.0 * f64::EPSILON * (n as f64 + 0.5) * theta;
                assert!(ef < tol && edf < tol, "n={n} θ={theta}: {ef:e} {edf:e}");
            }
        }
    }

    #[test]
    fn asymptotic_path_matches_newton() {
        for n in [101usize, 200, 537, 1000] {
            let (xa, wa) = gauss_legendre(n);
            let (xn, wn) = gauss_legendre_impl(n, f64::INFINITY);
            let dx = max_abs_diff(&xa, &xn);
            let dw = xa
                .iter()
                .enumerate()
                .map(|(i, _)| (wa[i] / wn[i] - 1.0).abs())
                .fold(0.0, f64::max);
            assert!(dx < 1e-15, "n={n}: max |Δx| = {dx:e}");
            assert!(dw < 1e-13, "n={n}: max rel Δw = {dw:e}");
        }
    }

    #[test]
    fn large_n_fast_and_accurate() {
        let t0 = std::time::Instant::now();
        let (x, w) = gauss_legendre(40_000);
        let elapsed = t0.elapsed().as_secs_f64();
        assert!(elapsed < 0.5, "n = 40000 took {elapsed} s");
        let sum: f64 = w.iter().sum();
        assert!((sum - 2.0).abs() < 1e-13, "Σw = {sum}");
        // Spot-check nodes and weights against Newton on the recurrence.
        let n = 40_000;
        for &i in &[0usize, 1, 5, 40, 41, 100, 1000, 7777, 19_999] {
            let theta0 = x[n - 1 - i].acos();
            let (theta, dp) = newton_theta(theta0, |t| legendre_theta(n, t));
            let wr = 2.0 / (dp * dp);
            assert!(
                (theta.cos() - x[n - 1 - i]).abs() < 2e-16,
                "node {i}: {:e} vs {:e}",
                theta.cos(),
                x[n - 1 - i]
            );
            assert!(
                (wr / w[n - 1 - i] - 1.0).abs() < 1e-12,
                "weight {i}: {wr} vs {}",
                w[n - 1 - i]
            );
        }
        // smooth integrand: ∫ cos(1000 x) dx = 2 sin(1000)/1000
        let integral: f64 = x
            .iter()
            .zip(&w)
            .map(|(&xi, &wi)| wi * (1000.0 * xi).cos())
            .sum();
        assert!((integral - 2.0 * 1000f64.sin() / 1000.0).abs() < 1e-14);
    }

    #[test]
    fn n_100000() {
        let t0 = std::time::Instant::now();
        let (x, w) = gauss_legendre(100_000);
        eprintln!(
            "gauss_legendre(100000): {:.3} s",
            t0.elapsed().as_secs_f64()
        );
        assert_eq!(x.len(), 100_000);
        let sum: f64 = w.iter().sum();
        assert!((sum - 2.0).abs() < 1e-13, "Σw = {sum}");
        for i in 1..x.len() {
            assert!(x[i] > x[i - 1]);
        }
        let integral: f64 = x.iter().zip(&w).map(|(&xi, &wi)| wi * xi.powi(10)).sum();
        assert!((integral - 2.0 / 11.0).abs() < 1e-14);
    }

    #[test]
    fn mapped_and_double_gauss() {
        let (x, w) = double_gauss(8);
        assert_eq!(x.len(), 8);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!(x.iter().all(|&t| t > 0.0 && t < 1.0));
        for i in 1..8 {
            assert!(x[i] > x[i - 1]);
        }
        // ∫_0^1 μ^k dμ = 1/(k+1) exactly up to k = 15
        for k in 0..16 {
            let s: f64 = x.iter().zip(&w).map(|(&t, &wi)| wi * t.powi(k)).sum();
            assert!((s - 1.0 / (k as f64 + 1.0)).abs() < 1e-15, "k={k}");
        }
        let (x, w) = gauss_legendre_on(5, 2.0, 5.0);
        assert!((w.iter().sum::<f64>() - 3.0).abs() < 1e-14);
        let s: f64 = x.iter().zip(&w).map(|(&t, &wi)| wi * t.powi(9)).sum();
        let exact = (5f64.powi(10) - 2f64.powi(10)) / 10.0;
        assert!((s / exact - 1.0).abs() < 1e-14);
    }

    /// Nodes and weights against 45-digit values (mpmath: Newton on the
    /// recurrence in multiprecision), `(n, k, x_k, w_k)` with `k` counted
    /// from the largest node.
    #[test]
    #[allow(clippy::excessive_precision)]
    fn against_multiprecision_reference() {
        let reference: [(usize, usize, f64, f64); 8] = [
            (
                1000,
                1,
                0.999_997_111_298_075_510_569_9,
                7.413_338_416_432_071_517e-6,
            ),
            (
                1000,
                2,
                0.999_984_779_632_917_418_324_3,
                1.725_676_977_373_923_012e-5,
            ),
            (
                1000,
                33,
                0.994_716_939_057_330_542_744_9,
                3.223_376_848_612_676_801e-4,
            ),
            (
                1000,
                250,
                0.707_938_826_618_098_962_664_8,
                2.217_715_028_859_311_319e-3,
            ),
            (
                1000,
                500,
                1.570_010_480_083_193_829_005e-3,
                3.140_018_380_182_867_787e-3,
            ),
            (
                40_000,
                1,
                0.999_999_998_192_799_567_510_8,
                4.637_859_906_879_042_179e-9,
            ),
            (
                40_000,
                40,
                0.999_995_126_737_729_963_222,
                2.451_914_563_442_243_819e-7,
            ),
            (
                40_000,
                20_000,
                3.926_941_728_899_548_146_344e-5,
                7.853_883_453_761_972_078e-5,
            ),
        ];
        let mut cache: Option<(usize, Vec<f64>, Vec<f64>)> = None;
        for (n, k, x_ref, w_ref) in reference {
            if cache.as_ref().is_none_or(|c| c.0 != n) {
                let (x, w) = gauss_legendre(n);
                cache = Some((n, x, w));
            }
            let (_, x, w) = cache.as_ref().unwrap();
            let (xk, wk) = (x[n - k], w[n - k]);
            assert!(
                (xk - x_ref).abs() < 2.5e-16,
                "n={n} k={k}: x {xk:e} vs {x_ref:e}"
            );
            assert!(
                (wk / w_ref - 1.0).abs() < 2e-14,
                "n={n} k={k}: w {wk:e} vs {w_ref:e}"
            );
        }
    }
}
