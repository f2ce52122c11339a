//! A cached table answering another request of its family (docs/service.md,
//! "Covering results"; the spec-level rule is `plan::spec_may_cover`): cut
//! to the elements, incident nodes and Fourier orders the request holds,
//! resampled onto its coarser grid, its estimate dropped when not needed,
//! under the request's canonical spec, id and solver metadata.
//!
//! * **Same grid.** Elements, incident nodes and orders are copies of the
//!   cached ones: a direct solve of the request computes the same numbers
//!   (the Fourier orders are solved independently, `synthesize` only
//!   copies `ρ^m/μ_i`), so nothing is interpolated and the cached
//!   statements (estimate, interpolation error) hold as they are.
//! * **Coarser grid.** The request's nodes are evaluated on the cached
//!   table (T2, its 6-node stencil), the specular matrices are rebuilt
//!   exactly (`e^{−2τ/μ} M_F(μ)`, the attenuation read off the cached
//!   node nearest the zenith), and the interpolation error is measured as
//!   a direct solve measures it (`build::interpolation_error`): at the
//!   coarse grid's probe angles, against the cached table there; the
//!   cached table's own stated interpolation error is added.
//! * **Fewer orders** are cut only without an estimate: the estimate of a
//!   cut series is not the cached one (a cached series that stopped at or
//!   below the request's cap is the series the request would get).

use super::build::{interpolation_error, plan_nodes_grid};
use super::coverage;
use super::grid::PolarGrid;
use super::table::{Table, WavelengthTable, scale, solver_meta};
use crate::material::Spec;
use crate::physics::stokes::Mueller;
use crate::plan;

impl Table {
    /// This table as the result of `request` (canonical spec `spec`, id
    /// `spec_hash`), or why it does not cover it (module doc). Refusals
    /// are ordinary: the request is then solved.
    pub fn cover(
        self,
        request: &Spec,
        spec: serde_json::Value,
        spec_hash: &str,
    ) -> Result<Table, String> {
        let candidate: Spec = serde_json::from_value(self.metadata.spec.clone())
            .map_err(|e| format!("the cached spec does not parse: {e}"))?;
        let check = plan::spec_may_cover(&candidate, request)?;
        let needs = request.needs.normalized();
        if let Some(t) = check.max_estimate {
            for w in &self.metadata.wavelengths {
                match &w.error_estimate {
                    Some(e) if e.max_err_f11 <= t => {}
                    Some(e) => {
                        return Err(format!(
                            "estimate {:e} above tolerance {t:e}",
                            e.max_err_f11
                        ));
                    }
                    None => return Err("no estimate".into()),
                }
            }
        }
        let grid = if check.resample {
            plan_nodes_grid(needs.polar_nodes())
        } else {
            self.grid.clone()
        };
        let incident = coverage::incident_nodes(&grid, needs.theta_i_deg.as_ref());
        let solve_ns = if request.solver.polarized { 4 } else { 1 };
        let (rows, cols) = needs.stokes.shape(solve_ns);
        let cap = needs.max_order().map(|m| m + 1);
        let mut metadata = self.metadata.clone();
        let mut blocks = Vec::with_capacity(self.wavelengths.len());
        for (b, meta) in self.wavelengths.iter().zip(&mut metadata.wavelengths) {
            if b.ns < rows || b.cols < cols {
                return Err("fewer Mueller elements".into());
            }
            let orders = cap.map_or(b.orders, |c| c.min(b.orders));
            if orders < b.orders && needs.error_estimate {
                return Err("a cut series with an estimate".into());
            }
            // The cached statement is relative to the largest f11 of the
            // whole series, the served one to that of the cut series.
            if orders < b.orders {
                let ratio = largest_f11(b, b.orders) / largest_f11(b, orders);
                if let Some(e) = &mut meta.interpolation_error {
                    *e *= ratio.max(1.0);
                }
            }
            let shape = Shape {
                rows,
                cols,
                orders,
                incident: &incident,
            };
            let block = if check.resample {
                if !b.is_complete_incident() {
                    return Err("resampling needs every incident node".into());
                }
                let wl = b.wavelength_nm;
                let mirror = plan::fresnel_indices(request, wl)
                    .map_err(|e| e.to_string())?
                    .map(|(n1, n2)| plan::fresnel_mirror(n1, n2));
                let (block, measured) = resample(b, &self.grid, &grid, &shape, mirror.as_deref())?;
                meta.interpolation_error = Some(measured + meta.interpolation_error.unwrap_or(0.0));
                block
            } else {
                if let Some(i) = incident
                    .iter()
                    .find(|i| b.incident.binary_search(i).is_err())
                {
                    return Err(format!("incident node {i} is not held"));
                }
                cut(b, &shape)
            };
            meta.fourier_orders = block.orders;
            if !needs.error_estimate {
                meta.error_estimate = None;
            }
            blocks.push(block);
        }
        metadata.solver = solver_meta(&plan::settings(request), plan::stream_policy(request));
        metadata.grid = super::table::grid_description(&grid);
        metadata.spec = spec;
        metadata.spec_hash = spec_hash.to_string();
        metadata.stokes = needs.stokes;
        metadata.theta_i_deg = needs.theta_i_deg.clone();
        Ok(Table {
            metadata,
            grid,
            wavelengths: blocks,
        })
    }
}

/// What a covered block holds: the first `rows × cols` elements, the first
/// `orders` orders, at the held `incident` nodes of its grid.
struct Shape<'a> {
    rows: usize,
    cols: usize,
    orders: usize,
    incident: &'a [usize],
}

impl WavelengthTable {
    fn is_complete_incident(&self) -> bool {
        self.incident.len() == self.nodes
    }
}

/// The largest `|f11|` at `Δφ = 0` and `π` of the first `orders` orders
/// over the nodes a block holds (T1), the scale of its relative statements.
fn largest_f11(b: &WavelengthTable, orders: usize) -> f64 {
    let mut max: f64 = 0.0;
    for o in 0..b.nodes {
        for &i in &b.incident {
            let (mut at0, mut at_pi) = (0.0, 0.0);
            for m in 0..orders {
                let w = if m == 0 { 1.0 } else { 2.0 } / (2.0 * std::f64::consts::PI);
                let v = w * b.node(m, o, i)[0][0];
                at0 += v;
                at_pi += if m % 2 == 0 { v } else { -v };
            }
            max = max.max(at0.abs()).max(at_pi.abs());
        }
    }
    max
}

/// `m` cut to its first `rows × cols` elements, as a row-major block.
fn push_block(f: &mut Vec<f64>, m: &Mueller, rows: usize, cols: usize) {
    for row in m.iter().take(rows) {
        f.extend_from_slice(&row[..cols]);
    }
}

/// The same grid: copies of the held elements, nodes and orders.
fn cut(b: &WavelengthTable, s: &Shape) -> WavelengthTable {
    let mut f = Vec::with_capacity(s.orders * b.nodes * s.incident.len() * s.rows * s.cols);
    for m in 0..s.orders {
        for o in 0..b.nodes {
            for &i in s.incident {
                push_block(&mut f, &b.node(m, o, i), s.rows, s.cols);
            }
        }
    }
    let specular = b.specular.as_ref().map(|sp| {
        s.incident
            .iter()
            .map(|&i| coverage::keep(&sp[b.incident_position(i)], s.rows, s.cols))
            .collect()
    });
    WavelengthTable {
        ns: s.rows,
        cols: s.cols,
        incident: s.incident.to_vec(),
        orders: s.orders,
        f,
        specular,
        correction: b.correction.clone(),
        surface: b.surface,
        ..b.clone_shape()
    }
}

/// The block on the coarser grid `to` (module doc) and its measured
/// interpolation error relative to the largest f11.
fn resample(
    b: &WavelengthTable,
    from: &PolarGrid,
    to: &PolarGrid,
    s: &Shape,
    mirror: Option<&(dyn Fn(f64) -> Mueller + Send + Sync)>,
) -> Result<(WavelengthTable, f64), String> {
    let n = to.len();
    // Every order of every stored element at every pair of nodes and
    // probes of `to` (outgoing, incident), from the cached table.
    let probes = to.probe_theta_deg();
    let theta: Vec<f64> = to.theta_deg.iter().chain(&probes).copied().collect();
    let at = |a: usize, i: usize| b.coefficients(from, theta[a], theta[i]);
    let mut f = vec![0.0; s.orders * n * s.incident.len() * s.rows * s.cols];
    let len = s.rows * s.cols;
    for o in 0..n {
        for (k, &i) in s.incident.iter().enumerate() {
            let c = at(o, i);
            for (m, cm) in c.iter().take(s.orders).enumerate() {
                let base = ((m * n + o) * s.incident.len() + k) * len;
                let mut block = Vec::with_capacity(len);
                push_block(&mut block, cm, s.rows, s.cols);
                f[base..base + len].copy_from_slice(&block);
            }
        }
    }
    // f11 of every order at every pair, nodes then probes.
    let np = theta.len();
    let mut f11 = vec![0.0; np * np * s.orders];
    for a in 0..np {
        for i in 0..np {
            for (m, cm) in at(a, i).iter().take(s.orders).enumerate() {
                f11[(a * np + i) * s.orders + m] = cm[0][0];
            }
        }
    }
    let all: Vec<usize> = (0..n).collect();
    let nodes_f11 = WavelengthTable {
        ns: 1,
        cols: 1,
        nodes: n,
        incident: all.clone(),
        orders: s.orders,
        f: (0..s.orders)
            .flat_map(|m| (0..n).flat_map(move |o| (0..n).map(move |i| (m, o, i))))
            .map(|(m, o, i)| f11[(o * np + i) * s.orders + m])
            .collect(),
        specular: None,
        correction: None,
        ..b.clone_shape()
    };
    let measured = interpolation_error(&nodes_f11, to, &theta, s.orders, &|m, a, i| {
        f11[(a * np + i) * s.orders + m]
    });
    let specular = match (&b.specular, mirror) {
        (None, _) => None,
        (Some(sp), Some(mirror)) => Some(specular_resampled(sp, from, to, s, mirror)?),
        (Some(_), None) => return Err("a specular part without a Fresnel base".into()),
    };
    Ok((
        WavelengthTable {
            ns: s.rows,
            cols: s.cols,
            nodes: n,
            incident: s.incident.to_vec(),
            orders: s.orders,
            f,
            specular,
            correction: b.correction.clone(),
            surface: b.surface,
            ..b.clone_shape()
        },
        measured,
    ))
}

/// `e^{−2τ/μ} M_F(μ)` at the held nodes of `to`, from the cached specular
/// matrices on `from` (all of its nodes): `e^{−2τ/μ} = r^{μ_0/μ}` with
/// `r = S_11(μ_0) / M_F,11(μ_0)` at the node nearest the zenith.
fn specular_resampled(
    sp: &[Mueller],
    from: &PolarGrid,
    to: &PolarGrid,
    s: &Shape,
    mirror: &(dyn Fn(f64) -> Mueller + Send + Sync),
) -> Result<Vec<Mueller>, String> {
    let zenith = (0..from.len())
        .max_by(|&a, &b| from.mu[a].total_cmp(&from.mu[b]))
        .ok_or("an empty grid")?;
    let mu0 = from.mu[zenith];
    let m0 = mirror(mu0)[0][0];
    if m0 <= 0.0 {
        return Err("a mirror that reflects nothing at the zenith".into());
    }
    let ln_r = (sp[zenith][0][0] / m0).ln();
    Ok(s.incident
        .iter()
        .map(|&i| {
            let mu = to.mu[i];
            let attenuation = if ln_r == f64::NEG_INFINITY {
                0.0
            } else {
                (ln_r * mu0 / mu).exp()
            };
            coverage::keep(&scale(&mirror(mu), attenuation), s.rows, s.cols)
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use crate::brdf::table::{BuildOptions, Table};
    use crate::material::parse;

    fn spec(base: &str, solver: &str, needs: &str) -> crate::material::Spec {
        parse(&format!(
            r#"{{"layers":[{{"optical_thickness":0.5,"scatterer":{{"mie":{{"material":"TiO2","radius_um":0.2}}}}}}],
                "base":{base},"wavelengths_nm":[550],"solver":{solver},"needs":{needs}}}"#
        ))
        .unwrap()
    }

    fn built(s: &crate::material::Spec) -> Table {
        Table::from_spec_needs(s, &BuildOptions::default()).unwrap()
    }

    fn covered(from: &Table, request: &crate::material::Spec) -> Result<Table, String> {
        let (c, id) = crate::plan::id_of_spec(request);
        from.clone()
            .cover(request, serde_json::from_str(&c).unwrap(), &id)
    }

    fn without_times(mut t: Table) -> Table {
        for w in &mut t.wavelengths {
            w.wall_time_ms = 0.0;
        }
        for w in &mut t.metadata.wavelengths {
            w.wall_time_ms = 0.0;
        }
        t
    }

    const SILVER: &str = r#"{"fresnel":{"material":"silver"}}"#;

    /// On the same grid a covered result is the table a direct solve of the
    /// request writes, number for number: elements, incident nodes, orders
    /// and metadata (wall times aside).
    #[test]
    fn a_cut_on_the_same_grid_is_the_direct_solve() {
        let full = built(&spec(
            SILVER,
            r#"{"streams":6}"#,
            r#"{"grid":{"polar_nodes":12}}"#,
        ));
        for needs in [
            r#"{"grid":{"polar_nodes":12},"stokes":"unpolarized_in","theta_i_deg":[0, 35]}"#,
            r#"{"grid":{"polar_nodes":12},"stokes":"intensity","theta_i_deg":{"min":20,"max":40}}"#,
            r#"{"grid":{"polar_nodes":12,"max_fourier_orders":3},"error_estimate":false}"#,
        ] {
            let request = spec(SILVER, r#"{"streams":6}"#, needs);
            let direct = without_times(built(&request));
            let mut cut = without_times(covered(&full, &request).unwrap());
            assert_eq!(cut.wavelengths, direct.wavelengths, "{needs}");
            // A cut series keeps the statement measured on all orders,
            // rescaled to its own largest f11: at least what the cut orders
            // alone measure (the same pairs, fewer non-negative terms).
            let (c, d) = (
                cut.metadata.wavelengths[0].interpolation_error.unwrap(),
                direct.metadata.wavelengths[0].interpolation_error.unwrap(),
            );
            assert!(c >= d, "{needs}: {c:e} < {d:e}");
            cut.metadata.wavelengths[0].interpolation_error = Some(d);
            assert_eq!(cut.metadata, direct.metadata, "{needs}");
        }
    }

    /// A coarser grid from a finer one: within the stated interpolation
    /// errors of the direct coarse solve at every direction, the specular
    /// matrices exact, and the error it states at least what it is.
    #[test]
    fn a_resampled_grid_is_within_its_stated_error_of_the_direct_solve() {
        let fine = built(&spec(
            SILVER,
            r#"{"streams":8}"#,
            r#"{"grid":{"polar_nodes":40}}"#,
        ));
        let request = spec(SILVER, r#"{"streams":8}"#, r#"{"grid":{"polar_nodes":14}}"#);
        let direct = built(&request);
        let coarse = covered(&fine, &request).unwrap();
        assert_eq!(coarse.grid, direct.grid);
        let (wc, wd) = (&coarse.wavelengths[0], &direct.wavelengths[0]);
        let stated = coarse.metadata.wavelengths[0].interpolation_error.unwrap();
        let direct_stated = direct.metadata.wavelengths[0].interpolation_error.unwrap();
        assert!(stated > 0.0 && stated < 1e-2, "{stated:e}");
        for (a, b) in wc
            .specular
            .as_ref()
            .unwrap()
            .iter()
            .zip(wd.specular.as_ref().unwrap())
        {
            for (x, y) in a.iter().flatten().zip(b.iter().flatten()) {
                assert!((x - y).abs() <= 1e-13 * (1.0 + y.abs()), "{x} {y}");
            }
        }
        let mut f11_max: f64 = 0.0;
        let mut worst: f64 = 0.0;
        for ti in [0.0, 7.0, 23.0, 41.0, 58.0, 71.0, 84.0, 89.0] {
            for to in [0.0, 12.0, 33.0, 50.0, 66.0, 79.0, 88.0] {
                for dphi in [0.0, 1.0, 2.2, std::f64::consts::PI] {
                    let c = wc.eval(&coarse.grid, ti, to, dphi);
                    let d = wd.eval(&direct.grid, ti, to, dphi);
                    f11_max = f11_max.max(d[0][0]);
                    worst = worst.max((c[0][0] - d[0][0]).abs());
                }
            }
        }
        assert!(
            worst <= (stated + direct_stated) * f11_max,
            "difference {:e} of max f11, stated {stated:e} + {direct_stated:e}",
            worst / f11_max
        );
        assert_eq!(
            coarse.metadata.wavelengths[0].error_estimate,
            fine.metadata.wavelengths[0].error_estimate
        );
    }

    #[test]
    fn a_tolerance_is_covered_by_any_result_that_meets_it() {
        let fixed = built(&spec(
            "\"black\"",
            r#"{"streams":8}"#,
            r#"{"grid":{"polar_nodes":10}}"#,
        ));
        let estimate = fixed.metadata.wavelengths[0]
            .error_estimate
            .as_ref()
            .unwrap()
            .max_err_f11;
        let loose = spec(
            "\"black\"",
            &format!(r#"{{"tolerance":{}}}"#, estimate * 2.0),
            r#"{"grid":{"polar_nodes":10}}"#,
        );
        let t = covered(&fixed, &loose).unwrap();
        assert_eq!(t.metadata.solver.tolerance, Some(estimate * 2.0));
        assert_eq!(t.metadata.wavelengths[0].streams, 8);
        let tight = spec(
            "\"black\"",
            &format!(r#"{{"tolerance":{}}}"#, estimate / 2.0),
            r#"{"grid":{"polar_nodes":10}}"#,
        );
        assert!(
            covered(&fixed, &tight)
                .unwrap_err()
                .contains("above tolerance")
        );
    }

    #[test]
    fn less_never_covers_more() {
        let reduced = built(&spec(
            SILVER,
            r#"{"streams":6}"#,
            r#"{"grid":{"polar_nodes":12},"theta_i_deg":[30],"stokes":"unpolarized_in"}"#,
        ));
        for needs in [
            r#"{"grid":{"polar_nodes":12},"theta_i_deg":[31]}"#,
            r#"{"grid":{"polar_nodes":12},"theta_i_deg":[30]}"#,
            r#"{"grid":{"polar_nodes":8},"theta_i_deg":[30],"stokes":"unpolarized_in"}"#,
        ] {
            let request = spec(SILVER, r#"{"streams":6}"#, needs);
            assert!(covered(&reduced, &request).is_err(), "{needs}");
        }
        let full = built(&spec(
            SILVER,
            r#"{"streams":6}"#,
            r#"{"grid":{"polar_nodes":12}}"#,
        ));
        let cut = spec(
            SILVER,
            r#"{"streams":6}"#,
            r#"{"grid":{"polar_nodes":12,"max_fourier_orders":2}}"#,
        );
        assert!(full.wavelengths[0].orders > 2);
        assert!(covered(&full, &cut).unwrap_err().contains("estimate"));
    }
}
