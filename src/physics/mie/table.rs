//! The amplitudes of many spheres at one set of cosines as a matrix product.
//!
//! `S1(μ) = Σ_n c_n (a_n π_n(μ) + b_n τ_n(μ))` and
//! `S2(μ) = Σ_n c_n (a_n τ_n(μ) + b_n π_n(μ))`, `c_n = (2n+1)/(n(n+1))`
//! (BH eq. 4.74), are, for a batch of spheres at fixed cosines, the product
//! of a table of the angular functions `π_n(μ_k)`, `τ_n(μ_k)` (BH eq. 4.47,
//! computed once) with a matrix of the spheres' coefficients. A size average
//! evaluates ~10⁵ spheres at the same ~10³ cosines, so the product (faer's
//! blocked, SIMD matrix multiply) replaces one recurrence per sphere and
//! cosine ([`super::MieResult::amplitudes_at`]).
//!
//! Cosines that come in pairs `±μ` share their rows, as in
//! `AngularKernel::eval_pm`: with `π_n(−μ) = (−1)^{n−1} π_n(μ)` and
//! `τ_n(−μ) = (−1)^n τ_n(μ)` (BH eq. 4.48), the columns split into
//! `G₊ = {π_n, n odd; τ_n, n even}` (same sign at `−μ`) and
//! `G₋ = {π_n, n even; τ_n, n odd}` (opposite sign), and
//! `S(±μ) = G₊ R₊ ± G₋ R₋`: half the rows, the same two products.

use super::{C64, MieResult, PhysicsError, checked_mu, products};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};

/// Spheres multiplied at once: wide enough for the blocked kernel, small
/// enough that the product (rows × 4 columns per sphere) stays in cache.
const BATCH: usize = 64;

/// Angular functions of a fixed set of cosines for [`Self::products`].
#[derive(Clone, Debug)]
pub struct AmplitudeTable {
    /// Number of cosines.
    n_mu: usize,
    /// Index in `mu` of the cosine of each row (`+μ`).
    plus: Vec<usize>,
    /// Index in `mu` of `−μ` for the first `minus.len()` rows.
    minus: Vec<usize>,
    /// Largest series length the table holds.
    n_terms: usize,
    /// `G₊`: column `i` (`n = i + 1`) is `π_n` for odd `n`, `τ_n` for even `n`.
    same: Mat<f64>,
    /// `G₋`: column `i` is `τ_n` for odd `n`, `π_n` for even `n`.
    opposite: Mat<f64>,
}

impl AmplitudeTable {
    /// The table of `π_n`, `τ_n`, `n = 1..=n_terms`, at the cosines `mu`
    /// (each in `[-1, 1]`; values within 1e-12 outside are clamped).
    pub fn new(mu: &[f64], n_terms: usize) -> Result<Self, PhysicsError> {
        let checked: Vec<f64> = mu
            .iter()
            .map(|&u| checked_mu(u))
            .collect::<Result<_, _>>()?;
        let n = checked.len();
        let paired = (0..n / 2).all(|i| checked[i] == -checked[n - 1 - i] && checked[i] != 0.0);
        let (plus, minus): (Vec<usize>, Vec<usize>) = if paired {
            let mut plus: Vec<usize> = (0..n / 2).collect();
            if n % 2 == 1 {
                plus.push(n / 2);
            }
            (plus, (0..n / 2).map(|i| n - 1 - i).collect())
        } else {
            ((0..n).collect(), Vec::new())
        };
        let mut same = Mat::zeros(plus.len(), n_terms);
        let mut opposite = Mat::zeros(plus.len(), n_terms);
        for (row, &k) in plus.iter().enumerate() {
            let mu = checked[k];
            let (mut pi_prev, mut pi) = (0.0, 1.0); // π_0, π_1
            for i in 0..n_terms {
                let n = (i + 1) as f64;
                let tau = n * mu * pi - (n + 1.0) * pi_prev;
                let (s, o) = if i % 2 == 0 { (pi, tau) } else { (tau, pi) };
                same[(row, i)] = s;
                opposite[(row, i)] = o;
                let pi_next = (2.0 * n + 1.0) / n * mu * pi - (n + 1.0) / n * pi_prev;
                pi_prev = pi;
                pi = pi_next;
            }
        }
        Ok(Self {
            n_mu: n,
            plus,
            minus,
            n_terms,
            same,
            opposite,
        })
    }

    /// The products of [`MieResult::amplitude_products`] of each sphere at
    /// every cosine of the table, `out[sphere][cosine]`. The sums are grouped
    /// differently from the recurrence, so they differ from it by round-off
    /// (tested).
    pub fn products(&self, spheres: &[MieResult]) -> Result<Vec<Vec<[f64; 4]>>, PhysicsError> {
        let mut out = vec![vec![[0.0; 4]; self.n_mu]; spheres.len()];
        self.products_with(spheres, |j, k, p| out[j][k] = p)?;
        Ok(out)
    }

    /// [`Self::products`] handed to `sink(sphere, cosine, products)` as they
    /// are formed, without holding them (a size average sums them).
    pub fn products_with(
        &self,
        spheres: &[MieResult],
        mut sink: impl FnMut(usize, usize, [f64; 4]),
    ) -> Result<(), PhysicsError> {
        if let Some(s) = spheres.iter().find(|s| s.a.len() > self.n_terms) {
            return Err(PhysicsError::Invalid(format!(
                "amplitude table holds {} terms, a sphere at x = {} needs {}",
                self.n_terms,
                s.size_parameter,
                s.a.len()
            )));
        }
        for (b, batch) in spheres.chunks(BATCH).enumerate() {
            self.batch_products(batch, |j, k, p| sink(b * BATCH + j, k, p));
        }
        Ok(())
    }

    fn batch_products(&self, batch: &[MieResult], mut sink: impl FnMut(usize, usize, [f64; 4])) {
        let n_terms = batch.iter().map(|s| s.a.len()).max().unwrap_or(0);
        let cols = 4 * batch.len();
        // R₊ rows pair with G₊'s columns, R₋ with G₋'s: row i holds the
        // coefficients that multiply π_n or τ_n in (S1 re, S1 im, S2 re, S2 im).
        let mut r_same = Mat::<f64>::zeros(n_terms, cols);
        let mut r_opposite = Mat::<f64>::zeros(n_terms, cols);
        for (j, s) in batch.iter().enumerate() {
            for e in 0..4 {
                let (same, opposite) = (
                    r_same.col_as_slice_mut(4 * j + e),
                    r_opposite.col_as_slice_mut(4 * j + e),
                );
                for (i, (a, b)) in s.a.iter().zip(&s.b).enumerate() {
                    let n = (i + 1) as f64;
                    let c = (2.0 * n + 1.0) / (n * (n + 1.0));
                    // π_n multiplies a_n in S1 and b_n in S2; τ_n the other way.
                    let pi = [a.re, a.im, b.re, b.im][e] * c;
                    let tau = [b.re, b.im, a.re, a.im][e] * c;
                    (same[i], opposite[i]) = if i % 2 == 0 { (pi, tau) } else { (tau, pi) };
                }
            }
        }
        let rows = self.plus.len();
        let mut p_same = Mat::<f64>::zeros(rows, cols);
        let mut p_opposite = Mat::<f64>::zeros(rows, cols);
        if n_terms > 0 {
            matmul(
                p_same.as_mut(),
                Accum::Replace,
                self.same.as_ref().subcols(0, n_terms),
                r_same.as_ref(),
                1.0,
                Par::Seq,
            );
            matmul(
                p_opposite.as_mut(),
                Accum::Replace,
                self.opposite.as_ref().subcols(0, n_terms),
                r_opposite.as_ref(),
                1.0,
                Par::Seq,
            );
        }
        for j in 0..batch.len() {
            let same: [&[f64]; 4] = std::array::from_fn(|e| p_same.col_as_slice(4 * j + e));
            let opposite: [&[f64]; 4] = std::array::from_fn(|e| p_opposite.col_as_slice(4 * j + e));
            let at = |row: usize, sign: f64| {
                let s1 = C64::new(
                    same[0][row] + sign * opposite[0][row],
                    same[1][row] + sign * opposite[1][row],
                );
                let s2 = C64::new(
                    same[2][row] + sign * opposite[2][row],
                    same[3][row] + sign * opposite[3][row],
                );
                products(s1, s2)
            };
            for (row, &k) in self.plus.iter().enumerate() {
                sink(j, k, at(row, 1.0));
            }
            for (row, &k) in self.minus.iter().enumerate() {
                sink(j, k, at(row, -1.0));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spheres() -> Vec<MieResult> {
        [
            (0.3, C64::new(1.33, 0.0)),
            (7.5, C64::new(1.9, 0.02)),
            (41.0, C64::new(1.5, 1e-4)),
        ]
        .iter()
        .flat_map(|&(x, m)| {
            (0..3).map(move |k| MieResult::from_size_parameter(x * (1.0 + 0.1 * k as f64), m))
        })
        .collect::<Result<_, _>>()
        .unwrap()
    }

    /// Largest difference from the recurrence of `amplitude_products`,
    /// relative to the largest `S11` of that sphere.
    fn worst(mu: &[f64]) -> f64 {
        let s = spheres();
        let n = s.iter().map(|s| s.a.len()).max().unwrap();
        let table = AmplitudeTable::new(mu, n + 3).unwrap();
        let got = table.products(&s).unwrap();
        let mut worst: f64 = 0.0;
        for (sphere, g) in s.iter().zip(&got) {
            let want = sphere.amplitude_products(mu).unwrap();
            let scale = want.iter().map(|p| p[0]).fold(0.0, f64::max);
            for (w, g) in want.iter().zip(g) {
                for e in 0..4 {
                    worst = worst.max((w[e] - g[e]).abs() / scale);
                }
            }
        }
        worst
    }

    #[test]
    fn paired_cosines_match_the_recurrence() {
        let (mu, _) = crate::physics::quadrature::gauss_legendre(120);
        assert!(worst(&mu) < 1e-13, "{:e}", worst(&mu));
    }

    #[test]
    fn paired_cosines_with_a_zero_and_the_ends_match_the_recurrence() {
        let mu: Vec<f64> = (0..101)
            .map(|k| (std::f64::consts::PI * k as f64 / 100.0).cos())
            .collect();
        let mut mu = mu;
        for k in 0..50 {
            mu[100 - k] = -mu[k];
        }
        mu[50] = 0.0;
        assert!(worst(&mu) < 1e-13, "{:e}", worst(&mu));
    }

    #[test]
    fn unpaired_cosines_match_the_recurrence() {
        let mu = [0.3, -0.9, 1.0, 0.0, -1.0, 0.77];
        assert!(worst(&mu) < 1e-13, "{:e}", worst(&mu));
    }

    #[test]
    fn a_sphere_longer_than_the_table_is_an_error() {
        let s = spheres();
        let table = AmplitudeTable::new(&[0.5, -0.5], 10).unwrap();
        assert!(table.products(&s).is_err());
    }
}
