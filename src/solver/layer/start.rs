//! The start of a layer's doubling: the phase kernel it is built from, the
//! thin layer by the diamond scheme with exact beam and user-direction
//! source integrals, and the Richardson extrapolation of start layers.

use super::*;
use faer::Mat;

/// Phase-matrix blocks of one homogeneous layer for one order, already
/// multiplied by `ω/2` and (for quadrature columns) by the weights `w_j`:
/// `k[σ][σ']` with `σ = 0` for upward and `1` for downward travel of the
/// output (first index) and input (second index).
#[derive(Clone, Debug)]
pub struct Kernel {
    /// Quadrature ← quadrature (n×n).
    pub qq: [[Mat<f64>; 2]; 2],
    /// User ← quadrature (nu×n).
    pub uq: [[Mat<f64>; 2]; 2],
    /// Quadrature ← beam (n×nu), no weights.
    pub qb: [[Mat<f64>; 2]; 2],
    /// User ← beam (nu×nu), no weights.
    pub ub: [[Mat<f64>; 2]; 2],
}

/// Weights of the exponential source integration over a thin layer:
/// `∫_0^δ λ e^{−λt} (1 − t/δ) dt` and `∫_0^δ λ e^{−λt} t/δ dt` with
/// `h = λδ`, i.e. the exact integral of a linearly varying source seen from
/// the face at `t = 0`.
pub fn linear_source_weights(h: f64) -> (f64, f64) {
    // a1 = (1 − (1 + h) e^{−h}) / h = Σ_{j≥2} (−1)^j (j−1)/j! h^{j−1}
    let a1 = if h < 0.1 {
        let mut term = 1.0; // h^{j-1}/j! built incrementally
        let mut sum = 0.0;
        let mut fact = 1.0;
        for j in 2..20 {
            fact *= j as f64;
            term = if j == 2 { h } else { term * h };
            let sign = if j % 2 == 0 { 1.0 } else { -1.0 };
            sum += sign * (j as f64 - 1.0) / fact * term;
        }
        sum
    } else {
        (1.0 - (1.0 + h) * (-h).exp()) / h
    };
    let total = -(-h).exp_m1();
    (total - a1, a1)
}

/// `(e^{−δa} − e^{−δb}) / (b − a)`, stable when `a ≈ b` (limit `δ e^{−δa}`).
pub fn exp_divided_difference(delta: f64, a: f64, b: f64) -> f64 {
    let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
    let d = (hi - lo) * delta;
    // e^{−δ lo} (1 − e^{−d}) / (hi − lo) = δ e^{−δ lo} (1 − e^{−d})/d
    let phi = if d < 1e-8 {
        1.0 - 0.5 * d
    } else {
        -(-d).exp_m1() / d
    };
    delta * (-delta * lo).exp() * phi
}

/// Operators of a thin homogeneous layer of optical thickness `delta`.
///
/// Quadrature blocks by the diamond (trapezoidal) scheme of Wiscombe (1976,
/// "On initialization, error and flux conservation in the doubling method",
/// JQSRT 16, 637): one 2n×2n system relating the outgoing to the incoming
/// radiance, which conserves flux exactly for `ω = 1`. Beam sources enter
/// with their exact depth integral `∫_0^δ e^{−t/μ_b} dt`. User radiance is
/// the exact integral of the source function along the user direction with
/// the source interpolated linearly between the faces (weights
/// [`linear_source_weights`]) plus the exact single-scattering integral of
/// the beam, so grazing user directions (`δ ≫ μ_u`) stay accurate.
///
/// `mu_q`, `mu_u`: quadrature and user cosines (> 0). With `full = false`
/// only the blocks [`TopOps`] needs are computed (no beam columns, no user
/// rows leaving the bottom); the others are returned empty or zero.
pub fn thin_layer(
    k: &Kernel,
    mu_q: &[f64],
    mu_u: &[f64],
    ns: usize,
    delta: f64,
    full: bool,
) -> Ops {
    let n = mu_q.len() * ns;
    let nu = mu_u.len() * ns;
    // Number of beam columns.
    let nb = if full { nu } else { 0 };
    const UP: usize = 0;
    const DN: usize = 1;
    let inv_mu_q = |i: usize| 1.0 / mu_q[i / ns];
    let lam_u: Vec<f64> = mu_u.iter().map(|m| 1.0 / m).collect();

    // K [I−(δ); I+(0)] = RHS [x | b | y | c].
    let h = 0.5 * delta;
    let mut kmat = Mat::<f64>::zeros(2 * n, 2 * n);
    for i in 0..n {
        let f = h * inv_mu_q(i);
        for j in 0..n {
            let id = if i == j { 1.0 } else { 0.0 };
            // Row block 0: (I + a−−) I−(δ) − b−+ I+(0)
            kmat[(i, j)] = id + f * (id - k.qq[DN][DN][(i, j)]);
            kmat[(i, n + j)] = -f * k.qq[DN][UP][(i, j)];
            // Row block 1: −b+− I−(δ) + (I + a++) I+(0)
            kmat[(n + i, j)] = -f * k.qq[UP][DN][(i, j)];
            kmat[(n + i, n + j)] = id + f * (id - k.qq[UP][UP][(i, j)]);
        }
    }
    let cols = Cols { n, nu: nb };
    let w = cols.width();
    let off = cols.offsets();
    let mut rhs = Mat::<f64>::zeros(2 * n, w);
    let beam_int: Vec<f64> = mu_u.iter().map(|&m| m * -(-delta / m).exp_m1()).collect();
    for i in 0..n {
        let f = h * inv_mu_q(i);
        for j in 0..n {
            let id = if i == j { 1.0 } else { 0.0 };
            // x columns: [(I − a−−); b+−]
            rhs[(i, off[0] + j)] = id - f * (id - k.qq[DN][DN][(i, j)]);
            rhs[(n + i, off[0] + j)] = f * k.qq[UP][DN][(i, j)];
            // y columns: [b−+; (I − a++)]
            rhs[(i, off[2] + j)] = f * k.qq[DN][UP][(i, j)];
            rhs[(n + i, off[2] + j)] = id - f * (id - k.qq[UP][UP][(i, j)]);
        }
        for j in 0..nb {
            let bi = beam_int[j / ns] * inv_mu_q(i);
            // b columns (beam down from the top), c columns (beam up from the bottom).
            rhs[(i, off[1] + j)] = bi * k.qb[DN][DN][(i, j)];
            rhs[(n + i, off[1] + j)] = bi * k.qb[UP][DN][(i, j)];
            rhs[(i, off[3] + j)] = bi * k.qb[DN][UP][(i, j)];
            rhs[(n + i, off[3] + j)] = bi * k.qb[UP][UP][(i, j)];
        }
    }
    let z = kmat.partial_piv_lu().solve(&rhs);
    let dn_bottom = z.as_ref().submatrix(0, 0, n, w).to_owned(); // I−(δ)
    let up_top = z.as_ref().submatrix(n, 0, n, w).to_owned(); // I+(0)

    // Quadrature radiance at both faces for every input column.
    let mut dn_top = Mat::<f64>::zeros(n, w); // I−(0): the x input itself
    let mut up_bottom = Mat::<f64>::zeros(n, w); // I+(δ): the y input itself
    for i in 0..n {
        dn_top[(i, off[0] + i)] = 1.0;
        up_bottom[(i, off[2] + i)] = 1.0;
    }
    // Diffuse sources along user directions at both faces.
    let src = |sig: usize, top: bool| -> Mat<f64> {
        let (d, u) = if top {
            (&dn_top, &up_top)
        } else {
            (&dn_bottom, &up_bottom)
        };
        let mut s = mm(k.uq[sig][DN].as_ref(), d.as_ref());
        mm_into(&mut s, Accum::Add, k.uq[sig][UP].as_ref(), u.as_ref());
        s
    };
    let s_up_0 = src(UP, true);
    let s_up_d = src(UP, false);
    let (s_dn_0, s_dn_d) = if full {
        (src(DN, true), src(DN, false))
    } else {
        (Mat::zeros(nu, w), Mat::zeros(nu, w))
    };
    let mut top_u = Mat::<f64>::zeros(nu, w);
    let mut bot_u = Mat::<f64>::zeros(nu, w);
    for i in 0..nu {
        let lu = lam_u[i / ns];
        let (a0, a1) = linear_source_weights(lu * delta);
        for j in 0..w {
            // Upward user radiance at the top: source at t=0 weighs a0.
            top_u[(i, j)] = a0 * s_up_0[(i, j)] + a1 * s_up_d[(i, j)];
            // Downward user radiance at the bottom: source at t=δ weighs a0.
            bot_u[(i, j)] = a1 * s_dn_0[(i, j)] + a0 * s_dn_d[(i, j)];
        }
        // Exact single scattering of the beams.
        for j in 0..nb {
            let lv = lam_u[j / ns];
            let same_side = lu * -(-delta * (lu + lv)).exp_m1() / (lu + lv);
            let cross_side = lu * exp_divided_difference(delta, lv, lu);
            top_u[(i, off[1] + j)] += same_side * k.ub[UP][DN][(i, j)];
            top_u[(i, off[3] + j)] += cross_side * k.ub[UP][UP][(i, j)];
            bot_u[(i, off[1] + j)] += cross_side * k.ub[DN][DN][(i, j)];
            bot_u[(i, off[3] + j)] += same_side * k.ub[DN][UP][(i, j)];
        }
    }
    let eu = mu_u.iter().map(|m| (-delta / m).exp()).collect();
    Ops::from_column_blocks(&cols, ns, [&up_top, &dn_bottom, &top_u, &bot_u], eu)
}

/// Richardson extrapolation `(2^p F − C)/(2^p − 1)` of two computations of
/// the same operator whose error is `c δ^p + O(δ^{p+2})`: `fine` with the start
/// thickness `δ/2`, `coarse` with `δ` (the direct transmission `eu` is exact in
/// both). The weights sum to 1, so flux conservation is kept.
fn extrapolate(fine: &Mat<f64>, coarse: &Mat<f64>, p: i32) -> Mat<f64> {
    let w = 2f64.powi(p);
    let mut out = fine * w;
    out -= coarse;
    out * (1.0 / (w - 1.0))
}

/// [`extrapolate`] on every block of [`Ops`].
pub fn richardson(fine: &Ops, coarse: &Ops, p: i32) -> Ops {
    let x = |f: &Mat<f64>, c: &Mat<f64>| extrapolate(f, c, p);
    Ops {
        n: coarse.n,
        nu: coarse.nu,
        ns: coarse.ns,
        r: x(&fine.r, &coarse.r),
        t: x(&fine.t, &coarse.t),
        rs: x(&fine.rs, &coarse.rs),
        ts: x(&fine.ts, &coarse.ts),
        ru: x(&fine.ru, &coarse.ru),
        tu: x(&fine.tu, &coarse.tu),
        rus: x(&fine.rus, &coarse.rus),
        tus: x(&fine.tus, &coarse.tus),
        rb: x(&fine.rb, &coarse.rb),
        tb: x(&fine.tb, &coarse.tb),
        rbs: x(&fine.rbs, &coarse.rbs),
        tbs: x(&fine.tbs, &coarse.tbs),
        ruu: x(&fine.ruu, &coarse.ruu),
        tuu: x(&fine.tuu, &coarse.tuu),
        ruus: x(&fine.ruus, &coarse.ruus),
        tuus: x(&fine.tuus, &coarse.tuus),
        eu: coarse.eu.clone(),
    }
}

/// [`extrapolate`] on every block of [`TopOps`].
pub fn richardson_top(fine: &TopOps, coarse: &TopOps, p: i32) -> TopOps {
    let x = |f: &Mat<f64>, c: &Mat<f64>| extrapolate(f, c, p);
    TopOps {
        r: x(&fine.r, &coarse.r),
        t: x(&fine.t, &coarse.t),
        ru: x(&fine.ru, &coarse.ru),
        tus: x(&fine.tus, &coarse.tus),
        eu: coarse.eu.clone(),
    }
}
