//! Error against run time: an a-posteriori error estimate for every BRDF and
//! the choice of streams that meets a requested tolerance.
//!
//! The discretisation error of the BRDF is dominated by the number of
//! streams `N`. With solves at `N/4`, `N/2` and `N`, the differences
//! `d₁ = ‖f(N/2) − f(N/4)‖` and `d₂ = ‖f(N) − f(N/2)‖` (max norm of f11 over a
//! probe set of user-direction pairs and azimuths) give the observed
//! contraction `r = d₂/d₁`; in the asymptotic regime the remaining error of
//! the `N`-stream solution is the geometric tail `d₂ r/(1 − r)`
//! (Richardson 1911; the usual estimate of convergent sequences). When the
//! differences do not contract (`r ≥ 1`, pre-asymptotic), `d₂` itself is
//! reported. Estimates are relative to max f11 on the probe set.
//!
//! **The contraction is bounded below by `2^−p` with `p` =
//! [`ASYMPTOTIC_ORDER`] = 6.** A doubling of the streams cannot reduce the
//! error by more than the method's asymptotic order allows: at user
//! directions near the horizon the radiance is not smooth in `μ` (the
//! boundary layer `e^{−τ/μ}`), so the double-Gauss discrete ordinates
//! converge algebraically, `e(N) ∝ N^{−p}`. We measured the local order
//! `p = d ln e / d ln N` between N = 16 and 48 against 96-stream references
//! on the TiO2 cases of docs/accuracy.md: 5.8–6.05, the largest error always
//! at the most grazing pair. Pre-asymptotic doublings can contract faster
//! (e.g. 160× from 8 to 16 streams), and a tail computed from such a
//! contraction understated the next doubling's error 3× (docs/accuracy.md,
//! before this bound); with the bound an estimate errs on the safe side.
//!
//! Cost: the two coarse solves cost about `(1/8 + 1/64)` of the fine one
//! (a solve scales like `N³`).

use super::{Problem, ReflectionFourier, SolverError, reflection, reflection_observed};

/// Propagation-azimuth differences of the probe set (radians).
const PROBE_AZIMUTHS: [f64; 5] = [
    0.0,
    std::f64::consts::FRAC_PI_4,
    std::f64::consts::FRAC_PI_2,
    3.0 * std::f64::consts::FRAC_PI_4,
    std::f64::consts::PI,
];

/// Observed asymptotic order of the stream error at grazing user
/// directions (module doc): a doubling contracts the error by at most
/// `2^ASYMPTOTIC_ORDER`.
pub const ASYMPTOTIC_ORDER: f64 = 6.0;

/// The error estimate of one solve.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ErrorEstimate {
    /// Estimated max |error of f11| over the probe set, relative to max f11.
    pub max_err_f11: f64,
    /// Streams of the three solves used (`N/4`, `N/2`, `N`).
    pub streams: [usize; 3],
    /// Contraction used: the observed `d₂/d₁` of successive differences,
    /// at least `2^−ASYMPTOTIC_ORDER`.
    pub contraction: f64,
}

/// A solve with its estimate.
#[derive(Clone, Debug)]
pub struct Estimated {
    /// The `N`-stream solution.
    pub reflection: ReflectionFourier,
    /// Its estimated error.
    pub estimate: ErrorEstimate,
}

/// f11 at every (outgoing, incident) user pair and probe azimuth.
fn probe(r: &ReflectionFourier) -> Vec<f64> {
    let n = r.mu.len();
    let mut out = Vec::with_capacity(n * n * PROBE_AZIMUTHS.len());
    for iu in 0..n {
        for iv in 0..n {
            for &d in &PROBE_AZIMUTHS {
                out.push(r.brdf(iu, iv, d)[0][0]);
            }
        }
    }
    out
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// The tail estimate from three probe vectors (coarse to fine).
pub fn tail_estimate(quarter: &[f64], half: &[f64], full: &[f64]) -> (f64, f64) {
    let scale = full
        .iter()
        .cloned()
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let d1 = max_diff(half, quarter);
    let d2 = max_diff(full, half);
    if d1 <= 0.0 {
        return (d2 / scale, 0.0);
    }
    let r = (d2 / d1).max(2f64.powf(-ASYMPTOTIC_ORDER));
    let est = if r < 1.0 { d2 * r / (1.0 - r) } else { d2 };
    (est / scale, r)
}

fn with_streams(problem: &Problem, n: usize) -> Problem {
    let mut p = problem.clone();
    p.settings.streams = n;
    p
}

/// A coarse level of an estimate: `n` streams, unresolved series allowed
/// (its error only makes the estimate larger).
fn coarse(problem: &Problem, n: usize) -> Problem {
    let mut p = with_streams(problem, n);
    p.settings.allow_unresolved = true;
    p
}

/// Solve at `problem.settings.streams` and estimate the error from two
/// coarser solves (`N/2`, `N/4`, at least 1 stream).
pub fn reflection_with_estimate(
    problem: &Problem,
    mu_user: &[f64],
) -> Result<Estimated, SolverError> {
    let n = problem.settings.streams;
    let levels = [(n / 4).max(1), (n / 2).max(1), n];
    let fine = reflection(problem, mu_user)?;
    let quarter = probe(&reflection(&coarse(problem, levels[0]), mu_user)?);
    let half = probe(&reflection(&coarse(problem, levels[1]), mu_user)?);
    let (max_err_f11, contraction) = tail_estimate(&quarter, &half, &probe(&fine));
    Ok(Estimated {
        reflection: fine,
        estimate: ErrorEstimate {
            max_err_f11,
            streams: levels,
            contraction,
        },
    })
}

/// The cheapest stream count `N = 4, 8, 16, …, max_streams` whose
/// estimated error is within `tolerance`; each doubling reuses the previous
/// solves. [`SolverError::ToleranceNotMet`] if the tolerance is not reached
/// by `max_streams` (never a silently less accurate result).
///
/// `on_progress` gets an approximate fraction in `[0, 1)` after each batch
/// of Fourier orders: with `k` stream levels done and the current one a
/// fraction `x` through its orders, `(k + x)/(k + 2)` (one more doubling
/// assumed to come). It is not monotone across levels; callers clamp.
pub fn reflection_to_tolerance(
    problem: &Problem,
    mu_user: &[f64],
    tolerance: f64,
    max_streams: usize,
    on_progress: &(dyn Fn(f64) + Sync),
) -> Result<Estimated, SolverError> {
    if !(tolerance > 0.0 && tolerance.is_finite()) {
        return Err(SolverError::Invalid(format!(
            "solver.tolerance = {tolerance} must be a positive number"
        )));
    }
    if max_streams < 8 {
        return Err(SolverError::Invalid(format!(
            "solver.tolerance needs solves at 2, 4 and 8 streams, but at most {max_streams} are allowed"
        )));
    }
    let mut probes: Vec<(usize, Vec<f64>)> = Vec::new();
    let mut n = 2;
    loop {
        let levels_done = probes.len() as f64;
        let report = |done: usize, bound: usize| {
            let within = done as f64 / bound.max(1) as f64;
            on_progress((levels_done + within) / (levels_done + 2.0));
        };
        let r = reflection_observed(&coarse(problem, n), mu_user, &report)?;
        probes.push((n, probe(&r)));
        if probes.len() >= 3 {
            let k = probes.len();
            let (est, contraction) =
                tail_estimate(&probes[k - 3].1, &probes[k - 2].1, &probes[k - 1].1);
            // The answer itself must resolve every series (the coarse
            // levels of the estimate need not).
            let resolved = problem
                .layers
                .iter()
                .enumerate()
                .try_for_each(|(i, l)| super::check_resolved(i, l, n));
            if 2 * n > max_streams {
                resolved.clone()?;
                if est > tolerance {
                    return Err(SolverError::ToleranceNotMet {
                        tolerance,
                        estimate: est,
                        streams: n,
                    });
                }
            }
            if est <= tolerance && resolved.is_ok() {
                return Ok(Estimated {
                    reflection: r,
                    estimate: ErrorEstimate {
                        max_err_f11: est,
                        streams: [probes[k - 3].0, probes[k - 2].0, n],
                        contraction,
                    },
                });
            }
        }
        n *= 2;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A geometric sequence `f_N = f_∞ + c r^k` (with `r` above the
    /// order bound): the tail estimate recovers the true remaining error
    /// exactly.
    #[test]
    fn tail_estimate_is_exact_for_geometric_convergence() {
        let limit = [1.0, 2.0, 0.5];
        let at = |k: i32| -> Vec<f64> { limit.iter().map(|x| x + 0.3 * 0.25f64.powi(k)).collect() };
        let (est, r) = tail_estimate(&at(0), &at(1), &at(2));
        // Remaining error c r², relative to max f of the finest level.
        let true_err = 0.3 * 0.25f64.powi(2) / (2.0 + 0.3 * 0.25f64.powi(2));
        assert!((r - 0.25).abs() < 1e-12);
        assert!(
            (est - true_err).abs() < 1e-12 * true_err.max(1.0),
            "{est} vs {true_err}"
        );
    }

    /// Faster-than-order contraction (1/1000 per doubling) is not
    /// extrapolated beyond the asymptotic order: the estimate is
    /// `d₂ 2^−6/(1 − 2^−6)`, larger than the geometric tail.
    #[test]
    fn contraction_is_bounded_by_the_asymptotic_order() {
        let at = |k: i32| -> Vec<f64> { vec![1.0 + 0.5 * 1e-3f64.powi(k)] };
        let (est, r) = tail_estimate(&at(0), &at(1), &at(2));
        let d2 = 0.5 * (1e-3 - 1e-6);
        let q = 1.0 / 64.0;
        assert_eq!(r, q);
        let want = d2 * q / (1.0 - q) / (1.0 + 0.5e-6);
        assert!((est - want).abs() < 1e-12 * want, "{est} vs {want}");
    }
}
