//! Deterministic random numbers and the one sampling routine of the
//! renderer.
//!
//! Each pixel owns a generator seeded from `(scene seed, pixel index)`, so an
//! image does not depend on how rayon schedules the rows: same seed, same
//! bytes. The generator is SplitMix64 (Steele, Lea & Flood 2014, "Fast
//! splittable pseudorandom number generators", OOPSLA; the constants of
//! Vigna's reference `splitmix64.c`): eight lines, 64-bit state, passes
//! BigCrush, and its output function doubles as the seed hash. A crate
//! (`rand_pcg`) would add a dependency for the same eight lines.

use super::geometry::Vec3;

/// SplitMix64 generator.
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

/// The SplitMix64 output function (a bijective 64-bit mixer).
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl SplitMix64 {
    /// A generator with the given state.
    pub fn new(state: u64) -> Self {
        Self { state }
    }

    /// The generator of pixel `index` for scene seed `seed`: state
    /// `mix64(seed) ⊕ mix64(index + 1)·φ` — distinct pixels get unrelated
    /// streams.
    pub fn for_pixel(seed: u64, index: u64) -> Self {
        Self::new(mix64(seed) ^ mix64(index.wrapping_add(1)).wrapping_mul(GOLDEN))
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN);
        mix64(self.state)
    }

    /// Uniform in `[0, 1)` with 53 random bits.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Cosine-weighted direction on the hemisphere around local `z` from two
/// uniform numbers (Malley's method: a uniform point on the unit disc lifted
/// to the hemisphere), `pdf = cos θ / π`:
/// `(√u₁ cos 2πu₂, √u₁ sin 2πu₂, √(1 − u₁))`.
pub fn cosine_hemisphere(u1: f64, u2: f64) -> Vec3 {
    let r = u1.sqrt();
    let (s, c) = (2.0 * std::f64::consts::PI * u2).sin_cos();
    [r * c, r * s, (1.0 - u1).max(0.0).sqrt()]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reference sequence of `splitmix64.c` seeded with 1234567.
    #[test]
    fn matches_the_reference_splitmix64() {
        let mut g = SplitMix64::new(1234567);
        let expect = [
            6457827717110365317u64,
            3203168211198807973,
            9817491932198370423,
            4593380528125082431,
            16408922859458223821,
        ];
        for e in expect {
            assert_eq!(g.next_u64(), e);
        }
    }

    /// Uniform numbers have mean 1/2 and variance 1/12 (to 4σ of 1e5
    /// samples); cosine-weighted directions have `E[cos θ] = 2/3` and
    /// `E[sin θ cos φ] = 0`.
    #[test]
    fn sample_moments() {
        let mut g = SplitMix64::for_pixel(7, 3);
        let n = 100_000;
        let (mut m, mut v, mut cz, mut cx) = (0.0, 0.0, 0.0, 0.0);
        for _ in 0..n {
            let u = g.next_f64();
            assert!((0.0..1.0).contains(&u));
            m += u;
            v += (u - 0.5) * (u - 0.5);
            let w = cosine_hemisphere(g.next_f64(), g.next_f64());
            assert!((w[0] * w[0] + w[1] * w[1] + w[2] * w[2] - 1.0).abs() < 1e-12);
            cz += w[2];
            cx += w[0];
        }
        let nf = n as f64;
        assert!((m / nf - 0.5).abs() < 4.0 * (1.0f64 / 12.0 / nf).sqrt());
        assert!((v / nf - 1.0 / 12.0).abs() < 1e-3);
        // Var(cos θ) = 1/2 − 4/9 = 1/18.
        assert!((cz / nf - 2.0 / 3.0).abs() < 4.0 * (1.0f64 / 18.0 / nf).sqrt());
        assert!((cx / nf).abs() < 4.0 * (0.25f64 / nf).sqrt());
        // Different pixels, different streams.
        assert_ne!(
            SplitMix64::for_pixel(7, 3).next_u64(),
            SplitMix64::for_pixel(7, 4).next_u64()
        );
        assert_ne!(
            SplitMix64::for_pixel(7, 3).next_u64(),
            SplitMix64::for_pixel(8, 3).next_u64()
        );
    }
}
