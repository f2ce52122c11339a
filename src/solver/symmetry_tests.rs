use super::*;
use crate::physics::quadrature::double_gauss;

/// `(max |f(u, v, Δφ) − Δ f(v, u, −Δφ)ᵀ Δ|, max |f|)` over the user
/// cosines of `r` and four azimuths: the defect of polarized
/// reciprocity (conventions §5) and its scale.
pub(crate) fn reciprocity_defect(r: &ReflectionFourier) -> (f64, f64) {
    let d = [1.0, 1.0, -1.0, 1.0];
    let n = r.mu.len();
    let (mut worst, mut scale): (f64, f64) = (0.0, 0.0);
    for iu in 0..n {
        for iv in 0..n {
            for dphi in [0.0, 0.7, 2.0, 3.5] {
                let a = r.brdf(iu, iv, dphi);
                let b = r.brdf(iv, iu, -dphi);
                for i in 0..4 {
                    for j in 0..4 {
                        scale = scale.max(a[i][j].abs());
                        worst = worst.max((a[i][j] - d[i] * b[j][i] * d[j]).abs());
                    }
                }
            }
        }
    }
    (worst, scale)
}

fn gs_layer(tau: f64) -> (Grid, Layer) {
    let coef = crate::physics::expansion::test_data::garcia_siewert();
    let (mu_q, w_q) = double_gauss(6);
    let grid = Grid {
        ns: 4,
        mu_q,
        w_q,
        mu_u: vec![0.1, 0.45, 0.8, 1.0],
        split: None,
    };
    (
        grid,
        Layer {
            thickness: Thickness::Finite(tau),
            albedo: 0.95,
            coef,
        },
    )
}

fn sign(i: usize) -> f64 {
    if i % 4 < 2 { 1.0 } else { -1.0 }
}

/// Probe which sign/transposition relations hold (exploration helper).
#[test]
fn mirror_symmetry_and_reciprocity() {
    let (grid, layer) = gs_layer(0.7);
    let s = Settings::default();
    for m in [0usize, 1, 3] {
        let o = layer_ops(&grid, &layer, m, &s, true);
        let n = o.n;
        let mut e_rs: f64 = 0.0;
        let mut e_ts: f64 = 0.0;
        for i in 0..n {
            for j in 0..n {
                e_rs = e_rs.max((o.rs[(i, j)] - sign(i) * o.r[(i, j)] * sign(j)).abs());
                e_ts = e_ts.max((o.ts[(i, j)] - sign(i) * o.t[(i, j)] * sign(j)).abs());
            }
        }
        eprintln!("m={m}: |rs - S r S| = {e_rs:.2e}, |ts - S t S| = {e_ts:.2e}");
        // Reciprocity candidates: rb[i,v] = (μv/μi) Δ ru[v,i]^T Δ / w_i.
        for (name, dd) in [
            ("D4", [1.0, 1.0, 1.0, -1.0]),
            ("D3", [1.0, 1.0, -1.0, 1.0]),
            ("I", [1.0; 4]),
        ] {
            let mut e_rb: f64 = 0.0;
            let mut e_tb: f64 = 0.0;
            let ns = 4;
            for i in 0..grid.mu_q.len() {
                for v in 0..grid.mu_u.len() {
                    for p in 0..ns {
                        for q in 0..ns {
                            let f = grid.mu_u[v] / grid.mu_q[i] / grid.w_q[i];
                            let rb = f * dd[p] * o.ru[(v * ns + q, i * ns + p)] * dd[q];
                            let tb = f * dd[p] * o.tus[(v * ns + q, i * ns + p)] * dd[q];
                            e_rb = e_rb.max((rb - o.rb[(i * ns + p, v * ns + q)]).abs());
                            e_tb = e_tb.max((tb - o.tb[(i * ns + p, v * ns + q)]).abs());
                        }
                    }
                }
            }
            eprintln!("   {name}: rb err {e_rb:.2e}, tb err {e_tb:.2e}");
        }
    }
}

/// The top-only path (symmetric doubling, reciprocity for beam columns,
/// Chandrasekhar's relation for `Ruu`) agrees with carrying every block
/// through the doubling, for thin, thick and semi-infinite layers.
#[test]
fn top_only_path_matches_full_doubling() {
    // A thin start layer so that both paths are converged in δ and the
    // comparison tests the identities, not the discretisation.
    let s = Settings {
        start_factor: 1e-3,
        ..Settings::default()
    };
    for (tau, thickness) in [
        (0.03, Thickness::Finite(0.03)),
        (0.7, Thickness::Finite(0.7)),
        (12.0, Thickness::Finite(12.0)),
        (f64::INFINITY, Thickness::Infinite),
    ] {
        let (grid, mut layer) = gs_layer(0.7);
        layer.thickness = thickness;
        for m in [0usize, 2, 5] {
            let full = layer_ops(&grid, &layer, m, &s, true);
            let top = layer_ops(&grid, &layer, m, &s, false);
            let scale = layer::max_abs(full.ruu.as_ref());
            let diff = layer::max_abs((&full.ruu - &top.ruu).as_ref());
            let dr = layer::max_abs((&full.r - &top.r).as_ref());
            let dru = layer::max_abs((&full.ru - &top.ru).as_ref());
            eprintln!(
                "tau={tau} m={m}: |ΔRuu|/max = {:.2e}, |ΔR| = {dr:.1e}, |ΔRu| = {dru:.1e}",
                diff / scale
            );
            assert!(
                diff <= 1e-7 * scale,
                "tau={tau} m={m}: {diff:e} vs {scale:e}"
            );
            assert!(dr < 1e-10 && dru < 1e-10);
        }
    }
}
