//! `polbrdf solve SPEC.json [--points POINTS.json] [--field FIELD.json]
//! [--table OUT] [--max-streams N]`.
//!
//! **Output** (stdout, one JSON document):
//!
//! ```text
//! {"results": [{"wavelength_nm", "computed": [...],
//!               "points": [...], "specular": [...],                       with --points
//!               "field": [...],                                           with --field
//!               "solver": {"streams", "polarized", "fourier_orders",
//!                          "wall_time_ms", "error_estimate"},             with --points or --field
//!               "table": {"streams", "fourier_orders", "wall_time_ms",
//!                         "error_estimate"}}],                            with --table
//!  "table": {"file", "bytes", "sha256_of_file", "polar_nodes", "wavelengths"}}   with --table
//! ```
//!
//! Each result says what was computed for its wavelength in `computed`
//! (`"points"`, `"field"`, `"table"`, in that order) and carries only those
//! parts: nothing that was not computed appears, not even as `[]`, `0` or
//! `null`. `solver` describes the direct solve at the direction pairs of
//! `--points` and/or the internal field of `--field` (both at the same
//! streams); `error_estimate` (the solver's a-posteriori estimate,
//! `solver::accuracy`) is present only when the direction pairs were solved,
//! as the field solve makes none. `specular` (with `--points`) lists the
//! specular term of a mirror base (conventions §6) or of a smooth top
//! interface (§8) per incident angle and is empty for other stacks; with
//! both, `mueller` is their sum and `parts` lists the interface's
//! reflection and the base's beam that came back through it. The per-result `table` object describes the table
//! build at that wavelength (its own solve on the table's polar grid, from
//! the table's metadata, docs/table-format.md); the top-level `table`
//! describes the file. Without `--points`, `--field` or `--table` the spec
//! is only checked (`computed: []`).

use super::progress::Progress;
use crate::brdf::angles::{MU_FLOOR, dphi_prop_rad, mu_of_theta_deg};
use crate::material::{self, Spec, SpecError};
use crate::physics::stokes::Mueller;
use crate::plan;
use crate::solver::{self, Base, fourier_sum};
use clap::Args;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use std::time::Instant;

/// `polbrdf solve` arguments.
#[derive(Debug, Args)]
pub struct SolveArgs {
    /// The material spec (JSON, docs/spec.md).
    pub spec: String,
    /// Direction pairs: {"points": [{"theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg"}]}.
    #[arg(long)]
    pub points: Option<String>,
    /// Internal field request: {"mu0", "phi0_deg", "stokes", "tau", "mu", "phi_deg"}.
    #[arg(long)]
    pub field: Option<String>,
    /// Also write the BRDF table (binary, docs/table-format.md) to this file.
    #[arg(long)]
    pub table: Option<String>,
    /// Most streams: a spec with more `solver.streams` is refused (exit 2), and
    /// a `solver.tolerance` may pick at most this many. The default is the HTTP
    /// service's default cap (`polbrdf serve --max-streams`); at most 512.
    #[arg(long, default_value_t = default_max_streams(), value_parser = max_streams_parser())]
    pub max_streams: usize,
}

/// The default of `--max-streams`: the service's default cap
/// (`http::config::Limits`), so that the command line refuses what the
/// service would.
pub fn default_max_streams() -> usize {
    crate::http::config::Limits::default().max_streams
}

/// `--max-streams` values: 1 to the spec's hard limit [`material::MAX_STREAMS`].
pub fn max_streams_parser() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new().range(1..=material::MAX_STREAMS as u64)
}

/// Refuse an explicit `solver.streams` over `max_streams` (`--max-streams`),
/// with the service's message but for the name of the cap's owner (the
/// service says "this service's allowed range").
pub fn check_stream_cap(spec: &Spec, max_streams: usize) -> Result<(), SpecError> {
    match spec.solver.streams {
        Some(n) if n > max_streams => Err(SpecError::new(
            "solver.streams",
            format!("{n} is outside the allowed range [1, {max_streams}] (--max-streams)"),
        )),
        _ => Ok(()),
    }
}

/// One direction pair in the graphics convention (degrees, both directions
/// pointing away from the surface).
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Point {
    pub theta_i_deg: f64,
    pub phi_i_deg: f64,
    pub theta_o_deg: f64,
    pub phi_o_deg: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PointsFile {
    points: Vec<Point>,
}

/// A field request (`--field`): a collimated beam of flux pi normal to it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FieldFile {
    mu0: f64,
    #[serde(default)]
    phi0_deg: f64,
    #[serde(default = "unpolarized")]
    stokes: [f64; 4],
    tau: Vec<f64>,
    mu: Vec<f64>,
    phi_deg: Vec<f64>,
}

fn unpolarized() -> [f64; 4] {
    [1.0, 0.0, 0.0, 0.0]
}

/// Sorted distinct cosines and a lookup.
pub struct MuSet {
    pub mu: Vec<f64>,
}

impl MuSet {
    pub fn new(values: impl IntoIterator<Item = f64>) -> Self {
        let mut mu: Vec<f64> = values.into_iter().collect();
        mu.sort_by(|a, b| a.partial_cmp(b).expect("finite"));
        mu.dedup_by(|a, b| (*a - *b).abs() <= 1e-15);
        Self { mu }
    }
    pub fn index(&self, m: f64) -> usize {
        self.mu
            .iter()
            .position(|&x| (x - m).abs() <= 1e-15)
            .expect("cosine in set")
    }
}

fn read_json<T: for<'de> Deserialize<'de>>(path: &str) -> Result<T, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    material::from_json_str(&text).map_err(|e| format!("{path}: {e}"))
}

fn check_angle(what: &str, v: f64, lo: f64, hi: f64) -> Result<(), String> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(format!("{what} = {v} is outside [{lo}, {hi}]"))
    }
}

fn read_points(path: &str) -> Result<Vec<Point>, String> {
    let points = read_json::<PointsFile>(path)?.points;
    for (i, p) in points.iter().enumerate() {
        check_angle(
            &format!("points[{i}].theta_i_deg"),
            p.theta_i_deg,
            0.0,
            90.0,
        )?;
        check_angle(
            &format!("points[{i}].theta_o_deg"),
            p.theta_o_deg,
            0.0,
            90.0,
        )?;
        check_angle(
            &format!("points[{i}].phi_i_deg"),
            p.phi_i_deg,
            -360.0,
            360.0,
        )?;
        check_angle(
            &format!("points[{i}].phi_o_deg"),
            p.phi_o_deg,
            -360.0,
            360.0,
        )?;
    }
    Ok(points)
}

fn read_field(path: &str) -> Result<FieldFile, String> {
    let f: FieldFile = read_json(path)?;
    check_angle("field.mu0", f.mu0, MU_FLOOR, 1.0)?;
    for (i, m) in f.mu.iter().enumerate() {
        check_angle(&format!("field.mu[{i}]"), *m, -1.0, 1.0)?;
    }
    for (i, t) in f.tau.iter().enumerate() {
        check_angle(&format!("field.tau[{i}]"), *t, 0.0, 1e12)?;
    }
    Ok(f)
}

/// Run `solve` and return the JSON document (module doc); with stderr a
/// terminal, a progress bar while solving and a one-line summary at the end
/// ([`summary_line`]).
pub fn run(a: &SolveArgs) -> Result<Value, String> {
    let spec_path = a.spec.as_str();
    let text = std::fs::read_to_string(spec_path).map_err(|e| format!("{spec_path}: {e}"))?;
    let spec = material::parse(&text).map_err(|e| format!("{spec_path}: {e}"))?;
    let points = a.points.as_deref().map(read_points).transpose()?;
    let field = a.field.as_deref().map(read_field).transpose()?;
    let doc = document(
        &spec,
        spec_path,
        points.as_deref(),
        field.as_ref(),
        a.table.as_deref(),
        a.max_streams,
    )?;
    Ok(doc)
}

/// What `solve` refuses before solving, as the service or the solver would
/// (docs/spec.md): more streams than `max_streams`, or a problem the solver
/// cannot take.
pub fn check(spec: &Spec, max_streams: usize) -> Result<(), SpecError> {
    check_stream_cap(spec, max_streams)?;
    plan::check_solvable(spec, max_streams)
}

/// The `solve --points` document (module doc) of a spec that [`check`]
/// accepted, at direction pairs, without files (the Python package's
/// `polbrdf.solve`); `label` names the spec in messages.
pub fn points_document(
    spec: &Spec,
    label: &str,
    points: &[Point],
    max_streams: usize,
) -> Result<Value, String> {
    checked_document(spec, label, Some(points), None, None, max_streams)
}

/// The document of `run` for a parsed spec and parsed requests.
fn document(
    spec: &Spec,
    spec_path: &str,
    points: Option<&[Point]>,
    field: Option<&FieldFile>,
    table: Option<&str>,
    max_streams: usize,
) -> Result<Value, String> {
    check(spec, max_streams).map_err(|e| format!("{spec_path}: {e}"))?;
    checked_document(spec, spec_path, points, field, table, max_streams)
}

/// [`document`] after [`check`].
fn checked_document(
    spec: &Spec,
    spec_path: &str,
    points: Option<&[Point]>,
    field: Option<&FieldFile>,
    table: Option<&str>,
    max_streams: usize,
) -> Result<Value, String> {
    let started = Instant::now();
    for (p, message) in plan::film_warnings(spec) {
        eprintln!("warning: {spec_path}: {p}: {message}");
    }

    let wavelengths = plan::wavelengths(spec);
    let direct = points.is_some() || field.is_some();
    let stages = wavelengths.len() * (usize::from(direct) + usize::from(table.is_some()));
    let progress = Progress::new(stages);

    let mut results = Vec::new();
    for (k, &wl) in wavelengths.iter().enumerate() {
        let mut out = serde_json::Map::new();
        out.insert("wavelength_nm".into(), json!(wl));
        if direct {
            progress.stage(k, &stage_message("solving", wl, k, wavelengths.len()));
            let solved = solve_direct(
                spec,
                spec_path,
                wl,
                points,
                field,
                max_streams,
                &progress.within(k),
            )?;
            out.extend(solved);
        }
        results.push(Value::Object(out));
    }
    let mut doc = json!({ "results": results });

    if let Some(path) = table {
        let offset = if direct { wavelengths.len() } else { 0 };
        let on_progress = |k: usize, total: usize, x: f64| {
            progress.stage(
                offset + k,
                &stage_message("building the table", wavelengths[k], k, total),
            );
            progress.within(offset + k)(x);
        };
        let options = crate::brdf::table::BuildOptions {
            max_streams,
            on_progress: &on_progress,
        };
        let (file, table) = super::export::write_table(spec, spec_path, path, &options)?;
        for r in doc["results"].as_array_mut().expect("results") {
            let wl = r["wavelength_nm"].as_f64();
            let meta = table
                .metadata
                .wavelengths
                .iter()
                .find(|m| m.wavelength_nm == wl)
                .ok_or("the table lacks a wavelength of the spec")?;
            let mut t = json!({
                "streams": meta.streams,
                "fourier_orders": meta.fourier_orders,
                "wall_time_ms": meta.wall_time_ms,
            });
            if let Some(e) = &meta.error_estimate {
                t["error_estimate"] = serde_json::to_value(e).expect("JSON");
            }
            r["table"] = t;
        }
        doc["table"] = file;
    }
    for r in doc["results"].as_array_mut().expect("results") {
        let computed: Vec<&str> = ["points", "field", "table"]
            .into_iter()
            .filter(|k| r.get(*k).is_some())
            .collect();
        r["computed"] = json!(computed);
    }
    progress.finish(summary_line(&doc, started.elapsed().as_secs_f64()));
    Ok(doc)
}

fn stage_message(what: &str, wl: Option<f64>, k: usize, total: usize) -> String {
    match wl {
        Some(w) => format!("{what}: {w} nm ({}/{total})", k + 1),
        None => what.to_string(),
    }
}

/// The direct solve of one wavelength: `points` and `specular` (with
/// `--points`), `field` (with `--field`) and the `solver` block (module doc).
fn solve_direct(
    spec: &Spec,
    spec_path: &str,
    wl: Option<f64>,
    points: Option<&[Point]>,
    field: Option<&FieldFile>,
    max_streams: usize,
    on_progress: &(dyn Fn(f64) + Sync),
) -> Result<serde_json::Map<String, Value>, String> {
    let start = Instant::now();
    let mut problem = plan::problem(spec, wl).map_err(|e| format!("{spec_path}: {e}"))?;
    let mut out = serde_json::Map::new();
    let mut orders = 0;
    let mut estimate = None;
    let mut solved_any = false;

    if let Some(points) = points {
        let set = MuSet::new(points.iter().flat_map(|p| {
            [
                mu_of_theta_deg(p.theta_i_deg),
                mu_of_theta_deg(p.theta_o_deg),
            ]
        }));
        let mut pts = Vec::new();
        let mut spec_terms = Vec::new();
        if !set.mu.is_empty() {
            let solved = match plan::stream_policy(spec) {
                plan::StreamPolicy::Fixed(_) => {
                    solver::accuracy::reflection_with_estimate_observed(
                        &problem,
                        &set.mu,
                        on_progress,
                    )
                }
                plan::StreamPolicy::Tolerance(t) => solver::accuracy::reflection_to_tolerance(
                    &problem,
                    &set.mu,
                    t,
                    max_streams,
                    on_progress,
                ),
            }
            .map_err(|e| e.to_string())?;
            solved_any = true;
            // The field (if asked for) at the streams the points were solved at.
            problem.settings.streams = solved.estimate.streams[2];
            estimate = Some(serde_json::to_value(&solved.estimate).expect("JSON"));
            let refl = solved.reflection;
            orders = refl.rho.len();
            for p in points {
                let iu = set.index(mu_of_theta_deg(p.theta_o_deg));
                let iv = set.index(mu_of_theta_deg(p.theta_i_deg));
                let m = refl.brdf(iu, iv, dphi_prop_rad(p.phi_i_deg, p.phi_o_deg));
                pts.push(json!({
                    "theta_i_deg": p.theta_i_deg, "phi_i_deg": p.phi_i_deg,
                    "theta_o_deg": p.theta_o_deg, "phi_o_deg": p.phi_o_deg,
                    "mueller": m,
                }));
            }
            let delta = |mu: f64| delta_term(&refl, &problem.base, set.index(mu), mu);
            let mut seen: Vec<f64> = Vec::new();
            for p in points {
                if seen.contains(&p.theta_i_deg) {
                    continue;
                }
                seen.push(p.theta_i_deg);
                let mu = mu_of_theta_deg(p.theta_i_deg);
                if let Some(s) = delta(mu) {
                    let mut term = json!({"theta_i_deg": p.theta_i_deg, "mueller": s});
                    // A mirror base under an interface: the sum and its parts.
                    if let Some(i) = &refl.interface
                        && let Some(through) = &i.through
                    {
                        let iv = set.index(mu);
                        term["parts"] = json!({
                            "interface": i.specular[iv],
                            "base_through_interface": through[iv],
                        });
                    }
                    spec_terms.push(term);
                }
            }
        }
        out.insert("points".into(), Value::Array(pts));
        out.insert("specular".into(), Value::Array(spec_terms));
    }

    if let Some(f) = field {
        let fset = MuSet::new(
            f.mu.iter()
                .map(|m| m.abs().clamp(MU_FLOOR, 1.0))
                .chain(std::iter::once(f.mu0)),
        );
        let ff = solver::internal_field(&problem, &fset.mu, &f.tau).map_err(|e| e.to_string())?;
        solved_any = true;
        orders = orders.max(ff.up.first().map_or(0, |v| v.len()));
        let iv = fset.index(f.mu0);
        let mut entries = Vec::new();
        for (k, &tau) in f.tau.iter().enumerate() {
            for &mu in &f.mu {
                let iu = fset.index(mu.abs().clamp(MU_FLOOR, 1.0));
                let rho = if mu > 0.0 { &ff.up[k] } else { &ff.down[k] };
                for &phi in &f.phi_deg {
                    let m = fourier_sum(rho, ff.ns, iu, iv, (phi - f.phi0_deg).to_radians());
                    let s = crate::physics::stokes::apply(&m, f.stokes)
                        .map(|x| std::f64::consts::PI * x);
                    entries.push(json!({"tau": tau, "mu": mu, "phi_deg": phi, "stokes": s}));
                }
            }
        }
        out.insert("field".into(), Value::Array(entries));
    }

    let ms = start.elapsed().as_secs_f64() * 1e3;
    let mut solver_block = json!({
        "streams": problem.settings.streams, "polarized": problem.settings.polarized,
        "fourier_orders": orders, "wall_time_ms": ms,
    });
    if let Some(e) = estimate {
        solver_block["error_estimate"] = e;
    }
    // An empty --points file solves nothing: no solver block for it.
    if solved_any {
        out.insert("solver".into(), solver_block);
    }
    Ok(out)
}

/// The delta term at user direction `iv` (cosine `mu`): a smooth top
/// interface's reflection (with, over a mirror base, the base's beam back
/// through it), or a mirror base's beam through the stack,
/// `e^{−2τ/μ} M_F(μ)`; `None` for a base that reflects diffusely.
pub fn delta_term(
    refl: &solver::ReflectionFourier,
    base: &Base,
    iv: usize,
    mu: f64,
) -> Option<Mueller> {
    if let Some(s) = refl.interface_specular(iv) {
        return Some(s);
    }
    let Base::Mirror { mueller } = base else {
        return None;
    };
    let e = refl.direct[iv];
    let mut s = mueller(mu);
    for row in &mut s {
        for x in row.iter_mut() {
            *x *= e * e;
        }
    }
    Some(s)
}

/// The one-line human summary of a `solve` document (printed on stderr when
/// it is a terminal): `polbrdf: solved W wavelength(s) [at P direction
/// pair(s)] [(internal field)], S streams, M Fourier orders[, error estimate
/// [at most] E of max f11][; table FILE at W wavelength(s), ...]; T s`, with
/// ranges `a-b` where the wavelengths differ. `None` when nothing was
/// computed.
pub fn summary_line(doc: &Value, seconds: f64) -> Option<String> {
    let results = doc["results"].as_array()?;
    let n = results.len();
    let wavelengths = if n == 1 {
        "1 wavelength".to_string()
    } else {
        format!("{n} wavelengths")
    };
    let mut parts = Vec::new();
    let solvers: Vec<&Value> = results.iter().filter_map(|r| r.get("solver")).collect();
    if !solvers.is_empty() {
        let mut what = format!("solved {wavelengths}");
        if let Some(p) = results[0].get("points").and_then(Value::as_array) {
            let s = if p.len() == 1 { "" } else { "s" };
            what += &format!(" at {} direction pair{s}", p.len());
        }
        if results[0].get("field").is_some() {
            what += " (internal field)";
        }
        parts.push(describe(&what, &solvers));
    }
    let tables: Vec<&Value> = results.iter().filter_map(|r| r.get("table")).collect();
    if !tables.is_empty() {
        let file = doc["table"]["file"].as_str().unwrap_or("?");
        parts.push(describe(&format!("table {file} at {wavelengths}"), &tables));
    }
    if parts.is_empty() {
        return None;
    }
    Some(format!("polbrdf: {}; {seconds:.2} s", parts.join("; ")))
}

/// `what, S streams, M Fourier orders, error estimate E of max f11` over the
/// blocks of several wavelengths (ranges where they differ, the largest
/// estimate).
fn describe(what: &str, blocks: &[&Value]) -> String {
    let range = |key: &str| -> Option<String> {
        let v: Vec<u64> = blocks.iter().filter_map(|b| b[key].as_u64()).collect();
        let (lo, hi) = (v.iter().min()?, v.iter().max()?);
        Some(if lo == hi {
            format!("{lo}")
        } else {
            format!("{lo}-{hi}")
        })
    };
    let mut s = what.to_string();
    if let Some(r) = range("streams") {
        s += &format!(", {r} streams");
    }
    if let Some(r) = range("fourier_orders") {
        s += &format!(", {r} Fourier orders");
    }
    let estimates: Vec<f64> = blocks
        .iter()
        .filter_map(|b| b["error_estimate"]["max_err_f11"].as_f64())
        .collect();
    if let Some(e) = estimates.iter().cloned().reduce(f64::max) {
        let bound = if estimates.len() > 1 { "at most " } else { "" };
        s += &format!(", error estimate {bound}{e:.1e} of max f11");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec_with_streams(n: usize) -> Spec {
        material::parse(&format!(
            r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"rayleigh":{{"albedo":0.9}}}}}}],"solver":{{"streams":{n}}}}}"#
        ))
        .unwrap()
    }

    #[test]
    fn the_stream_cap_refuses_only_above_it_and_names_the_field() {
        assert!(check_stream_cap(&spec_with_streams(128), 128).is_ok());
        let e = check_stream_cap(&spec_with_streams(129), 128).unwrap_err();
        assert_eq!(e.path, "solver.streams");
        assert!(e.message.contains("[1, 128]") && e.message.contains("--max-streams"));
        assert!(check_stream_cap(&spec_with_streams(256), 256).is_ok());
        // No explicit streams: nothing to cap here (a tolerance is capped by
        // check_solvable and the solver).
        let tol = material::parse(
            r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":0.9}}}],"solver":{"tolerance":1e-3}}"#,
        )
        .unwrap();
        assert!(check_stream_cap(&tol, 4).is_ok());
    }

    #[test]
    fn the_default_cap_is_the_services() {
        assert_eq!(
            default_max_streams(),
            crate::http::config::Limits::default().max_streams
        );
        assert!(default_max_streams() <= material::MAX_STREAMS);
    }

    #[test]
    fn the_summary_names_what_was_computed() {
        let doc = json!({"results": [
            {"wavelength_nm": 450.0, "computed": ["points", "table"],
             "points": [{}, {}], "specular": [],
             "solver": {"streams": 16, "fourier_orders": 12, "error_estimate": {"max_err_f11": 3.1e-5}},
             "table": {"streams": 16, "fourier_orders": 14, "error_estimate": {"max_err_f11": 2e-5}}},
            {"wavelength_nm": 550.0, "computed": ["points", "table"],
             "points": [{}, {}], "specular": [],
             "solver": {"streams": 32, "fourier_orders": 11, "error_estimate": {"max_err_f11": 4.2e-5}},
             "table": {"streams": 32, "fourier_orders": 13, "error_estimate": {"max_err_f11": 1e-5}}}],
            "table": {"file": "t.pbrdf"}});
        let s = summary_line(&doc, 1.234).unwrap();
        assert_eq!(
            s,
            "polbrdf: solved 2 wavelengths at 2 direction pairs, 16-32 streams, 11-12 Fourier orders, error estimate at most 4.2e-5 of max f11; table t.pbrdf at 2 wavelengths, 16-32 streams, 13-14 Fourier orders, error estimate at most 2.0e-5 of max f11; 1.23 s"
        );
        let checked = json!({"results": [{"wavelength_nm": null, "computed": []}]});
        assert_eq!(summary_line(&checked, 0.1), None);
        let one = json!({"results": [{"computed": ["field"], "field": [],
            "solver": {"streams": 8, "fourier_orders": 5}}]});
        assert_eq!(
            summary_line(&one, 0.5).unwrap(),
            "polbrdf: solved 1 wavelength (internal field), 8 streams, 5 Fourier orders; 0.50 s"
        );
    }
}
