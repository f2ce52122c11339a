//! BRDF tables against direct solves (docs/table-format.md, "Interpolation
//! error"), and reciprocity of the interpolated BRDF.
//!
//! The reference is always an independent call of `solver::reflection` at
//! the off-grid cosines themselves; nothing here is compared with numbers
//! copied from the table's own output.

use polbrdf::brdf::grid::PolarGrid;
use polbrdf::brdf::table::{Directions, Interpolant, Table, WavelengthTable};
use polbrdf::material::{self, Spec};
use polbrdf::physics::stokes::Mueller;
use polbrdf::plan;
use polbrdf::solver;
use serde_json::json;

fn spec_of(material: &str, tau: f64, base: serde_json::Value, wavelengths: &[f64]) -> Spec {
    let v = json!({
        "layers": [{"optical_thickness": tau,
                    "scatterer": {"mie": {"material": material, "radius_um": 0.2}}}],
        "base": base,
        "wavelengths_nm": wavelengths,
    });
    material::parse(&v.to_string()).expect("spec")
}

/// The seed's polar angles: midpoints of 51 equal steps of 0..90° (as
/// `polbrdf bench table`), and 61 azimuths 0..360°.
fn seed_theta() -> Vec<f64> {
    (0..51).map(|k| 90.0 * (k as f64 + 0.5) / 51.0).collect()
}

struct Errors {
    /// max |Δf_pq| over all elements, pairs and azimuths / max f11.
    rel_max_f11: f64,
    /// max |Δf_pq| (μ_i + μ_o) / max(f11 (μ_i + μ_o)).
    rel_weighted: f64,
}

/// Compare one wavelength block with a direct solve at the seed's polar
/// angles, on the seed's 61 azimuths.
fn compare(
    wt: &WavelengthTable,
    grid: &PolarGrid,
    problem: &solver::Problem,
    what: Interpolant,
    stencil: usize,
) -> Errors {
    let theta = seed_theta();
    let mu: Vec<f64> = theta.iter().map(|t| t.to_radians().cos()).collect();
    let direct = solver::reflection(problem, &mu).expect("direct solve");
    let dphi: Vec<f64> = (0..61)
        .map(|k| (360.0 * k as f64 / 60.0 - 180.0).to_radians())
        .collect();
    let basis = direct.azimuth_basis(&dphi);
    let (mut err, mut werr, mut fmax, mut wmax) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (iv, &ti) in theta.iter().enumerate() {
        for (iu, &to) in theta.iter().enumerate() {
            let c = wt.coefficients_with(grid, to, ti, what, stencil);
            let wsum = mu[iu] + mu[iv];
            for (k, &d) in dphi.iter().enumerate() {
                let a = polbrdf::brdf::table::fourier_synthesis(&c, wt.ns, d);
                let b = direct.brdf_with_basis(iu, iv, &basis[k]);
                fmax = fmax.max(b[0][0]);
                wmax = wmax.max(b[0][0] * wsum);
                for p in 0..4 {
                    for q in 0..4 {
                        let e = (a[p][q] - b[p][q]).abs();
                        err = err.max(e);
                        werr = werr.max(e * wsum);
                    }
                }
            }
        }
    }
    Errors {
        rel_max_f11: err / fmax,
        rel_weighted: werr / wmax,
    }
}

fn cases() -> Vec<(String, Spec)> {
    let mut v = Vec::new();
    for material in ["TiO2", "iron oxide"] {
        for tau in [0.1, 1.0, 10.0] {
            for (bname, base) in [
                ("black", json!("black")),
                ("lambertian 0.8", json!({"lambertian": {"albedo": 0.8}})),
            ] {
                v.push((
                    format!("{material}, tau {tau}, {bname}"),
                    spec_of(material, tau, base, &[550.0, 650.0]),
                ));
            }
        }
    }
    v
}

/// The measurement behind docs/table-format.md (run with
/// `cargo test --release --test brdf_interpolation -- --ignored --nocapture`):
/// every seed material, both wavelengths, three thicknesses, two bases,
/// several grids, stencils and interpolants.
#[test]
#[ignore = "measurement for docs/table-format.md (minutes)"]
fn measure_interpolation_error() {
    let grids: Vec<usize> = std::env::var("POLBRDF_GRIDS")
        .ok()
        .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
        .unwrap_or_else(|| vec![32, 48, 64, 96]);
    let configs = [
        (Interpolant::SumOfCosines, 4usize),
        (Interpolant::SumOfCosines, 6),
        (Interpolant::SumOfCosines, 8),
        (Interpolant::Plain, 6),
    ];
    println!("| case | λ nm | N | interpolant | K | err / max f11 | weighted |");
    let mut worst = vec![(0.0f64, 0.0f64); grids.len() * configs.len()];
    for (name, spec) in cases() {
        for (gk, &n) in grids.iter().enumerate() {
            let grid = PolarGrid::graded(n).unwrap();
            let table = Table::from_spec(&spec, grid.clone()).unwrap();
            for wt in &table.wavelengths {
                let problem = plan::problem(&spec, wt.wavelength_nm).unwrap();
                for (ck, &(what, k)) in configs.iter().enumerate() {
                    let e = compare(wt, &grid, &problem, what, k);
                    let w = &mut worst[gk * configs.len() + ck];
                    w.0 = w.0.max(e.rel_max_f11);
                    w.1 = w.1.max(e.rel_weighted);
                    println!(
                        "| {name} | {} | {n} | {what:?} | {k} | {:.1e} | {:.1e} |",
                        wt.wavelength_nm.unwrap(),
                        e.rel_max_f11,
                        e.rel_weighted
                    );
                }
            }
        }
    }
    println!("worst over cases:");
    for (gk, &n) in grids.iter().enumerate() {
        for (ck, &(what, k)) in configs.iter().enumerate() {
            let w = worst[gk * configs.len() + ck];
            println!("| {n} | {what:?} | {k} | {:.1e} | {:.1e} |", w.0, w.1);
        }
    }
}

const DELTA: [f64; 4] = [1.0, 1.0, -1.0, 1.0];

/// `Δ Mᵀ Δ`, `Δ = diag(1, 1, −1, 1)` (conventions §5, reciprocity).
fn reciprocal(m: &Mueller) -> Mueller {
    let mut r = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            r[i][j] = DELTA[i] * m[j][i] * DELTA[j];
        }
    }
    r
}

fn max_abs_diff(a: &Mueller, b: &Mueller) -> f64 {
    let mut e = 0.0f64;
    for i in 0..4 {
        for j in 0..4 {
            e = e.max((a[i][j] - b[i][j]).abs());
        }
    }
    e
}

/// Polar angles off the default grid, from near the normal to 0.1° above
/// the horizon (the corner of two grazing directions is where the
/// interpolation error of the seed's materials is largest).
const OFF_GRID_THETA: [f64; 6] = [3.0, 27.5, 58.3, 78.5, 88.4, 89.9];
const PHI_O: [f64; 4] = [15.0, 100.0, 195.0, 290.0];
const PHI_I: f64 = 15.0;

/// Bound on the table's interpolation error at the default grid, relative
/// to the largest f11 among the compared points. docs/table-format.md
/// measures at most 2.1e-6 (relative to max f11) for the seed's materials on
/// the full 51 × 51 × 61 seed grid; 1e-5 leaves a factor ~5 for points
/// outside that grid (89.9°) and is ten times below the 1e-4 target.
const INTERPOLATION_BOUND: f64 = 1e-5;

/// Point evaluations of the default-grid table against direct solves at the
/// off-grid cosines, for the hardest measured case (TiO2, τ = 0.1, black) and
/// a multiply-scattering one over a Lambertian base, both wavelengths.
#[test]
fn off_grid_points_match_direct_solves() {
    let grid = PolarGrid::default();
    for t in OFF_GRID_THETA {
        // At least a tenth of the local node spacing away from any node.
        let j = grid.theta_deg.iter().rposition(|&g| g <= t).unwrap();
        let frac = (t - grid.theta_deg[j]) / (grid.theta_deg[j + 1] - grid.theta_deg[j]);
        assert!((0.1..=0.9).contains(&frac), "{t} is (nearly) a node");
    }
    for spec in [
        spec_of("TiO2", 0.1, json!("black"), &[550.0, 650.0]),
        spec_of(
            "iron oxide",
            1.0,
            json!({"lambertian": {"albedo": 0.8}}),
            &[550.0, 650.0],
        ),
    ] {
        let table = Table::from_spec(&spec, grid.clone()).unwrap();
        let mu: Vec<f64> = OFF_GRID_THETA
            .iter()
            .map(|t| t.to_radians().cos())
            .collect();
        for wl in [550.0, 650.0] {
            let problem = plan::problem(&spec, Some(wl)).unwrap();
            let direct = solver::reflection(&problem, &mu).unwrap();
            let (mut err, mut fmax) = (0.0f64, 0.0f64);
            for (iv, &ti) in OFF_GRID_THETA.iter().enumerate() {
                for (iu, &to) in OFF_GRID_THETA.iter().enumerate() {
                    for po in PHI_O {
                        let d = Directions {
                            theta_i_deg: ti,
                            phi_i_deg: PHI_I,
                            theta_o_deg: to,
                            phi_o_deg: po,
                        };
                        let got = table.eval(&d, Some(wl)).unwrap();
                        let want = direct.brdf(iu, iv, (po - PHI_I - 180.0).to_radians());
                        fmax = fmax.max(want[0][0]);
                        err = err.max(max_abs_diff(&got, &want));
                    }
                }
            }
            eprintln!("{wl} nm: error / max f11 = {:.2e}", err / fmax);
            assert!(
                err <= INTERPOLATION_BOUND * fmax,
                "{wl} nm: interpolation error {:.2e} of max f11",
                err / fmax
            );
        }
    }
}

/// At grid nodes the table is the solver's output: it equals a direct solve
/// at those cosines up to the Fourier truncation (orders stop below 1e-9 of
/// order 0, and two solves with different direction sets may stop at
/// different orders), here bounded by 1e-8 of max f11.
#[test]
fn nodes_match_direct_solves() {
    let grid = PolarGrid::default();
    let spec = spec_of("iron oxide", 1.0, json!("black"), &[650.0]);
    let table = Table::from_spec(&spec, grid.clone()).unwrap();
    let nodes = [0usize, 9, 31, 50, 62, 63];
    let theta: Vec<f64> = nodes.iter().map(|&k| grid.theta_deg[k]).collect();
    let mu: Vec<f64> = nodes.iter().map(|&k| grid.mu[k]).collect();
    let problem = plan::problem(&spec, Some(650.0)).unwrap();
    let direct = solver::reflection(&problem, &mu).unwrap();
    let (mut err, mut fmax) = (0.0f64, 0.0f64);
    for (iv, &ti) in theta.iter().enumerate() {
        for (iu, &to) in theta.iter().enumerate() {
            for po in PHI_O {
                let d = Directions {
                    theta_i_deg: ti,
                    phi_i_deg: PHI_I,
                    theta_o_deg: to,
                    phi_o_deg: po,
                };
                let got = table.eval(&d, None).unwrap();
                let want = direct.brdf(iu, iv, (po - PHI_I - 180.0).to_radians());
                fmax = fmax.max(want[0][0]);
                err = err.max(max_abs_diff(&got, &want));
            }
        }
    }
    assert!(err <= 1e-8 * fmax, "nodes: {:.2e} of max f11", err / fmax);
}

/// Reciprocity of the interpolated BRDF, `f(μ, μ0, Δφ) = Δ f(μ0, μ, −Δφ)ᵀ Δ`
/// (conventions §5). With the same 1-D weights on both axes the defect of
/// the interpolant is a weighted sum of the defects `D_jk` of the node data:
/// `|defect| ≤ Σ_jk |w_j(a) w_k(b)| (μ_j + μ_k)/(μ_a + μ_b) · max |D_jk|`;
/// this bound is computed per point from the table's own stencils, and the
/// node defects themselves must be within the solver's reciprocity on the
/// top-only path of black and Lambertian bases (docs/solver.md: < 1e-8).
/// Over a mirror base (the solver's full doubling path) the node data are
/// not reciprocal at grazing directions (measured 1e-7 of the local f11 at
/// 80°, 2e-4 at 89.97°, 1e-3 at 90°; docs/table-format.md): that is the
/// solver's, so only the interpolation law is asserted there.
#[test]
fn interpolated_brdf_is_reciprocal() {
    let grid = PolarGrid::default();
    let mirror = json!({"fresnel": {"material": "aluminium", "ambient_index": 1.0}});
    for (spec, node_bound) in [
        (spec_of("TiO2", 1.0, json!("black"), &[550.0]), Some(1e-8)),
        (
            spec_of(
                "iron oxide",
                0.1,
                json!({"lambertian": {"albedo": 0.8}}),
                &[650.0],
            ),
            Some(1e-8),
        ),
        (spec_of("TiO2", 0.5, mirror, &[650.0]), None),
    ] {
        let table = Table::from_spec(&spec, grid.clone()).unwrap();
        let wt = &table.wavelengths[0];
        let node = |o: usize, i: usize, dphi: f64| {
            let c: Vec<Mueller> = (0..wt.orders).map(|m| wt.node(m, o, i)).collect();
            polbrdf::brdf::table::fourier_synthesis(&c, wt.ns, dphi)
        };
        let mut fmax = 0.0f64;
        let mut node_defect = 0.0f64;
        for a in OFF_GRID_THETA {
            for b in OFF_GRID_THETA {
                for dphi in [0.3f64, 1.9, -2.6] {
                    let sa = grid.stencil(a);
                    let sb = grid.stencil(b);
                    let (mu_a, mu_b) = (a.to_radians().cos(), b.to_radians().cos());
                    let (mut lebesgue, mut dmax) = (0.0f64, 0.0f64);
                    for j in 0..sa.len {
                        for k in 0..sb.len {
                            let (o, i) = (sa.start + j, sb.start + k);
                            lebesgue += (sa.w[j] * sb.w[k]).abs() * (grid.mu[o] + grid.mu[i])
                                / (mu_a + mu_b);
                            let fd = node(o, i, dphi);
                            let d = max_abs_diff(&fd, &reciprocal(&node(i, o, -dphi)));
                            dmax = dmax.max(d);
                            fmax = fmax.max(fd[0][0]);
                            node_defect = node_defect.max(d);
                        }
                    }
                    let f = wt.eval(&grid, b, a, dphi);
                    let r = reciprocal(&wt.eval(&grid, a, b, -dphi));
                    let defect = max_abs_diff(&f, &r);
                    let rounding = 1e-13 * f[0][0].abs().max(r[0][0].abs());
                    assert!(
                        defect <= lebesgue * dmax + rounding,
                        "θ {a} {b} Δφ {dphi}: defect {defect:e} > {lebesgue} × {dmax:e}"
                    );
                }
            }
        }
        eprintln!(
            "node reciprocity defect {:.2e} of max f11",
            node_defect / fmax
        );
        let Some(node_bound) = node_bound else {
            continue;
        };
        assert!(
            node_defect <= node_bound * fmax,
            "node data: reciprocity defect {:.2e} of max f11",
            node_defect / fmax
        );
    }
}

/// The specular term of a Fresnel base: the table's interpolated
/// `e^{−2τ/μ} M_F(μ)` against the exact expression from the spec's own base
/// and optical thickness, at off-grid incidence angles.
#[test]
fn specular_matches_fresnel() {
    let v = json!({
        "layers": [{"optical_thickness": 0.2,
                    "scatterer": {"mie": {"material": "iron oxide", "radius_um": 0.2,
                                          "host_index": 1.5}}}],
        "base": {"fresnel": {"material": "aluminium"}},
        "wavelengths_nm": [550.0],
        "solver": {"streams": 8},
    });
    let spec = material::parse(&v.to_string()).unwrap();
    let table = Table::from_spec(&spec, PolarGrid::default()).unwrap();
    let problem = plan::problem(&spec, Some(550.0)).unwrap();
    let solver::Base::Mirror { mueller } = &problem.base else {
        panic!("mirror base expected")
    };
    let mut worst = 0.0f64;
    for t in OFF_GRID_THETA {
        let d = Directions {
            theta_i_deg: t,
            phi_i_deg: 40.0,
            theta_o_deg: t,
            phi_o_deg: 220.0,
        };
        let got = table.specular(&d, None).unwrap().expect("mirror pair");
        let mu = t.to_radians().cos();
        let e = (-2.0 * 0.2 / mu).exp();
        let want = mueller(mu).map(|r| r.map(|x| x * e));
        worst = worst.max(max_abs_diff(&got, &want));
        // Not the mirror direction: no specular term.
        let off = Directions {
            phi_o_deg: 220.01,
            ..d
        };
        assert!(table.specular(&off, None).unwrap().is_none());
    }
    eprintln!("specular: max abs error {worst:.2e}");
    // The BRDF's bound: the same 1-D scheme on a function of s bounded by 1
    // and free of the grazing-corner singularity (measured 3.8e-7,
    // docs/table-format.md).
    assert!(worst <= 1e-5, "specular error {worst:e}");
}

/// Informational numbers for docs/table-format.md: the error of linear
/// interpolation between wavelengths (a 550/650 nm table at 600 nm against a
/// direct solve at 600 nm) and the polar interpolation error for a larger
/// particle (r = 1 µm) than the seed's.
#[test]
#[ignore = "measurement for docs/table-format.md"]
fn measure_wavelength_and_large_particle_errors() {
    let grid = PolarGrid::default();
    let theta = seed_theta();
    for material in ["TiO2", "iron oxide"] {
        let spec = spec_of(material, 1.0, json!("black"), &[550.0, 650.0]);
        let table = Table::from_spec(&spec, grid.clone()).unwrap();
        let problem = plan::problem(&spec, Some(600.0)).unwrap();
        let mu: Vec<f64> = theta.iter().map(|t| t.to_radians().cos()).collect();
        let direct = solver::reflection(&problem, &mu).unwrap();
        let (mut err, mut fmax) = (0.0f64, 0.0f64);
        for (iv, &ti) in theta.iter().enumerate().step_by(5) {
            for (iu, &to) in theta.iter().enumerate().step_by(5) {
                for po in [0.0, 90.0, 180.0] {
                    let d = Directions {
                        theta_i_deg: ti,
                        phi_i_deg: 0.0,
                        theta_o_deg: to,
                        phi_o_deg: po,
                    };
                    let got = table.eval(&d, Some(600.0)).unwrap();
                    let want = direct.brdf(iu, iv, (po - 180.0f64).to_radians());
                    fmax = fmax.max(want[0][0]);
                    err = err.max(max_abs_diff(&got, &want));
                }
            }
        }
        println!(
            "{material} tau 1 black, 600 nm from 550/650: {:.1e} of max f11",
            err / fmax
        );
    }
    for material in ["TiO2", "iron oxide"] {
        let v = json!({
            "layers": [{"optical_thickness": 1.0,
                        "scatterer": {"mie": {"material": material, "radius_um": 1.0}}}],
            "base": "black", "wavelengths_nm": [550.0], "solver": {"streams": 32},
        });
        let spec = material::parse(&v.to_string()).unwrap();
        let table = Table::from_spec(&spec, grid.clone()).unwrap();
        let wt = &table.wavelengths[0];
        let problem = plan::problem(&spec, Some(550.0)).unwrap();
        let e = compare(wt, &grid, &problem, Interpolant::SumOfCosines, 6);
        println!(
            "{material} r = 1 um, tau 1, black, 32 streams, {} orders: {:.1e} of max f11 ({:.1e} weighted), build {:.0} ms",
            wt.orders, e.rel_max_f11, e.rel_weighted, wt.wall_time_ms
        );
    }
}
