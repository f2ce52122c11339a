//! `polbrdf report experiment`: the seed's experiment (Collin et al. 2014,
//! §4.2 and Table 1) recomputed. A laser beam of linear polarization at a
//! sweep of angles hits a paint over a metal; a detector splits the
//! reflected light into its horizontal and vertical components. The seed
//! states no geometry: the defaults are 45° incidence with the detector in
//! the plane of incidence at the mirror direction (`--theta-o`, `--phi-o`
//! move it), and the bench is taken to be horizontal, so "horizontal" is
//! polarization in the plane of incidence, `x = e_ϑ` of conventions §5 for
//! both beams, and "vertical" is `y` (`s`).
//!
//! At the mirror direction two things reach a detector: the diffuse BRDF
//! (1/sr, the table) and the delta terms (the base's mirror beam through
//! the layer, the interface's reflection), whose share depends on the
//! detector's solid angle. The report gives the split of each apart. The
//! seed subtracted a thick layer's reading to remove the surface's
//! reflection, so its measured column is closest to the diffuse split; its
//! own solver had no delta term.

use super::solve::delta_term;
use crate::brdf::angles::{dphi_prop_rad, mu_of_theta_deg};
use crate::physics::stokes::{Mueller, apply};
use crate::{material, plan, solver};
use clap::{Args, Subcommand};
use serde_json::{Value, json};

/// Reports that recompute a published experiment.
#[derive(Debug, Subcommand)]
pub enum ReportCommand {
    /// The seed's Table 1: horizontal/vertical split of the light a paint over
    /// a metal reflects, for a sweep of incident linear polarizations.
    ///
    /// Without --spec, the seed's guess (aluminium spheres, optical thickness
    /// 0.5, over chromium) twice: the particles alone (the seed's case) and in
    /// a binder under its smooth surface. Prints the seed's layout as text, or
    /// {"rows": [...], "variants": [...]} with --json.
    Experiment(ExperimentArgs),
}

#[derive(Debug, Args)]
pub struct ExperimentArgs {
    /// A paint spec of your own instead of the seed's guess (its wavelengths
    /// are replaced by --wavelength-nm).
    #[arg(long)]
    pub spec: Option<String>,
    /// Laser vacuum wavelength (nm; He–Ne).
    #[arg(long, default_value_t = 632.8)]
    pub wavelength_nm: f64,
    /// Incidence polar angle (deg, graphics convention; incident azimuth 0).
    #[arg(long, default_value_t = 45.0)]
    pub theta_i: f64,
    /// Detector polar angle (deg) [default: --theta-i, the mirror direction].
    #[arg(long)]
    pub theta_o: Option<f64>,
    /// Detector azimuth (deg; 180 is the plane of incidence on the mirror side).
    #[arg(long, default_value_t = 180.0)]
    pub phi_o: f64,
    /// Optical thickness of the seed's guess.
    #[arg(long, default_value_t = 0.5)]
    pub tau: f64,
    /// Particle radius of the seed's guess (µm; the seed states none, 0.2 is
    /// the size of all its other figures).
    #[arg(long, default_value_t = 0.2)]
    pub radius_um: f64,
    /// Particle material of the seed's guess.
    #[arg(long, default_value = "aluminium")]
    pub particles: String,
    /// Base metal of the seed's guess.
    #[arg(long, default_value = "chromium")]
    pub base: String,
    /// Binder index of the second variant (host of the particles and index of
    /// its smooth top interface).
    #[arg(long, default_value_t = 1.5)]
    pub binder_index: f64,
    /// Streams per hemisphere of every solve.
    #[arg(long, default_value_t = 32)]
    pub streams: usize,
    /// Print JSON instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// The seed's Table 1, as printed: incident horizontal %, measured
/// horizontal %, the seed's simulated horizontal % (vertical = 100 − each).
pub const SEED_TABLE_1: [(f64, f64, f64); 7] = [
    (0.0, 11.0, 28.0),
    (7.0, 19.0, 32.0),
    (25.0, 24.0, 41.0),
    (50.0, 37.0, 54.0),
    (75.0, 63.0, 66.0),
    (93.0, 98.0, 74.0),
    (100.0, 86.0, 77.0),
];

/// Incident Stokes vector of linear polarization with horizontal fraction
/// `h` (`cos²χ`, `χ` from `x` towards `y`).
pub fn incident_stokes(h: f64) -> [f64; 4] {
    [
        1.0,
        2.0 * h - 1.0,
        2.0 * (h * (1.0 - h)).max(0.0).sqrt(),
        0.0,
    ]
}

/// Horizontal share (%) of the light `m` sends out for incidence `s`, or
/// `None` when nothing is sent.
pub fn horizontal_percent(m: &Mueller, s: [f64; 4]) -> Option<f64> {
    let out = apply(m, s);
    (out[0] > 0.0).then(|| 100.0 * 0.5 * (out[0] + out[1]) / out[0])
}

struct Variant {
    name: &'static str,
    label: String,
    spec: Value,
}

fn seed_guess(a: &ExperimentArgs, binder: bool) -> Value {
    let mut mie = json!({"material": a.particles, "radius_um": a.radius_um});
    let mut spec = json!({
        "layers": [{"optical_thickness": a.tau, "scatterer": {"mie": mie.clone()}}],
        "base": {"fresnel": {"material": a.base}},
        "wavelengths_nm": [a.wavelength_nm],
        "solver": {"streams": a.streams}
    });
    if binder {
        mie["host_index"] = json!(a.binder_index);
        spec["layers"][0]["scatterer"]["mie"] = mie;
        spec["top_interface"] = json!({"smooth": {"index": a.binder_index}});
    }
    spec
}

fn variants(a: &ExperimentArgs) -> Result<Vec<Variant>, String> {
    if let Some(path) = &a.spec {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
        let mut spec: Value = serde_json::from_str(&text).map_err(|e| format!("{path}: {e}"))?;
        let Some(obj) = spec.as_object_mut() else {
            return Err(format!("{path}: a spec is a JSON object"));
        };
        obj.insert("wavelengths_nm".into(), json!([a.wavelength_nm]));
        return Ok(vec![Variant {
            name: "spec",
            label: path.clone(),
            spec,
        }]);
    }
    Ok(vec![
        Variant {
            name: "particles",
            label: "particles alone".into(),
            spec: seed_guess(a, false),
        },
        Variant {
            name: "binder",
            label: format!("in binder {} under its surface", a.binder_index),
            spec: seed_guess(a, true),
        },
    ])
}

/// The diffuse Mueller BRDF at the detector and the delta terms' Mueller
/// matrix there (when the detector is at the mirror direction), with the
/// solve's estimate.
struct Solved {
    diffuse: Mueller,
    specular: Option<Mueller>,
    estimate: Value,
}

fn solve_variant(a: &ExperimentArgs, v: &Variant) -> Result<Solved, String> {
    let text = serde_json::to_string(&v.spec).expect("JSON");
    let spec = material::parse(&text).map_err(|e| format!("{}: {e}", v.label))?;
    plan::check_solvable(&spec, super::solve::default_max_streams().max(a.streams))
        .map_err(|e| format!("{}: {e}", v.label))?;
    let problem =
        plan::problem(&spec, Some(a.wavelength_nm)).map_err(|e| format!("{}: {e}", v.label))?;
    let theta_o = a.theta_o.unwrap_or(a.theta_i);
    let (mu_i, mu_o) = (mu_of_theta_deg(a.theta_i), mu_of_theta_deg(theta_o));
    let mut mus = vec![mu_i];
    if mu_o != mu_i {
        mus.push(mu_o);
    }
    let solved = solver::accuracy::reflection_with_estimate_observed(&problem, &mus, &|_| {})
        .map_err(|e| format!("{}: {e}", v.label))?;
    let refl = &solved.reflection;
    let iu = mus.iter().position(|&m| m == mu_o).expect("listed");
    let diffuse = refl.brdf(iu, 0, dphi_prop_rad(0.0, a.phi_o));
    let mirror = mu_o == mu_i && (a.phi_o - 180.0).rem_euclid(360.0) == 0.0;
    let specular = if mirror {
        delta_term(refl, &problem.base, 0, mu_i)
    } else {
        None
    };
    Ok(Solved {
        diffuse,
        specular,
        estimate: serde_json::to_value(&solved.estimate).expect("JSON"),
    })
}

fn split(p: Option<f64>) -> Value {
    match p {
        Some(h) => json!({"horizontal_percent": h, "vertical_percent": 100.0 - h}),
        None => Value::Null,
    }
}

/// Run the report: the JSON document (the text table is drawn from it).
pub fn run(a: &ExperimentArgs) -> Result<Value, String> {
    let variants = variants(a)?;
    let solved: Vec<Solved> = variants
        .iter()
        .map(|v| solve_variant(a, v))
        .collect::<Result<_, _>>()?;
    let rows: Vec<Value> = SEED_TABLE_1
        .iter()
        .map(|&(h_in, measured, seed)| {
            let s = incident_stokes(h_in / 100.0);
            let mut row = json!({
                "incident": split(Some(h_in)),
                "measured": split(Some(measured)),
                "seed_simulated": split(Some(seed)),
            });
            for (v, r) in variants.iter().zip(&solved) {
                row[v.name] = json!({
                    "diffuse": split(horizontal_percent(&r.diffuse, s)),
                    "specular": split(r.specular.as_ref().and_then(|m| horizontal_percent(m, s))),
                });
            }
            row
        })
        .collect();
    let theta_o = a.theta_o.unwrap_or(a.theta_i);
    Ok(json!({
        "wavelength_nm": a.wavelength_nm,
        "theta_i_deg": a.theta_i, "phi_i_deg": 0.0,
        "theta_o_deg": theta_o, "phi_o_deg": a.phi_o,
        "horizontal": "polarized in the plane of incidence (x = e_theta of docs/conventions.md §5, p); vertical is y (s)",
        "variants": variants.iter().zip(&solved).map(|(v, r)| json!({
            "name": v.name, "label": v.label, "spec": v.spec,
            "diffuse_mueller": r.diffuse, "diffuse_units": "1/sr",
            "specular_mueller": r.specular,
            "error_estimate": r.estimate,
        })).collect::<Vec<_>>(),
        "rows": rows,
    }))
}

/// One `H V` cell, right-aligned in `width` characters.
fn cell(v: &Value, width: usize) -> String {
    let s = match v["horizontal_percent"].as_f64() {
        Some(h) => format!("{:>5.1} {:>5.1}", h, 100.0 - h),
        None => format!("{:>5} {:>5}", "-", "-"),
    };
    format!("{s:>width$}")
}

/// The report as the seed's Table 1 layout.
pub fn text(doc: &Value) -> String {
    let mut out = String::new();
    let variants = doc["variants"].as_array().expect("variants");
    out.push_str(&format!(
        "Seed Table 1 (Collin et al. 2014, §4.2): {} nm, incidence {}°, detector at θ_o = {}°, φ_o − φ_i = {}°.\n",
        doc["wavelength_nm"], doc["theta_i_deg"], doc["theta_o_deg"], doc["phi_o_deg"]
    ));
    out.push_str("Horizontal (H) = polarized in the plane of incidence (p); vertical (V) = s. Percent of the reflected light.\n");
    for v in variants {
        out.push_str(&format!(
            "  {}: {}; estimated error {:.1e} of max f11\n",
            v["name"].as_str().unwrap_or(""),
            v["label"].as_str().unwrap_or(""),
            v["error_estimate"]["max_err_f11"]
                .as_f64()
                .unwrap_or(f64::NAN)
        ));
    }
    // Columns: (header, where in a row); each as wide as its header.
    let mut columns: Vec<(String, Vec<&str>)> = vec![
        ("incident".into(), vec!["incident"]),
        ("measured".into(), vec!["measured"]),
        ("seed solver".into(), vec!["seed_simulated"]),
    ];
    for v in variants {
        let n = v["name"].as_str().unwrap_or("");
        columns.push((format!("{n} diffuse"), vec![n, "diffuse"]));
        columns.push((format!("{n} mirror"), vec![n, "specular"]));
    }
    let widths: Vec<usize> = columns
        .iter()
        .map(|(h, _)| h.chars().count().max(11))
        .collect();
    let line = |cells: Vec<String>| cells.join(" | ") + "\n";
    out.push_str(&line(
        columns
            .iter()
            .zip(&widths)
            .map(|((h, _), &w)| format!("{h:>w$}"))
            .collect(),
    ));
    out.push_str(&line(
        widths
            .iter()
            .map(|&w| format!("{:>w$}", "H     V"))
            .collect(),
    ));
    for row in doc["rows"].as_array().expect("rows") {
        out.push_str(&line(
            columns
                .iter()
                .zip(&widths)
                .map(|((_, path), &w)| {
                    let v = path.iter().fold(row, |v, k| &v[*k]);
                    cell(v, w)
                })
                .collect(),
        ));
    }
    out.push_str("diffuse = the diffuse BRDF at the detector; mirror = the delta terms there (the base's beam through the layer, the interface's reflection), whose share of a reading grows with the detector's solid angle.\n");
    out
}

/// `polbrdf report ...`: print and return the exit code.
pub fn main(c: &ReportCommand) -> i32 {
    let ReportCommand::Experiment(a) = c;
    super::finish(run(a).map(|doc| {
        if a.json {
            serde_json::to_string_pretty(&doc).expect("JSON")
        } else {
            text(&doc)
        }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn incident_states_have_the_asked_split_and_full_polarization() {
        for (h, _, _) in SEED_TABLE_1 {
            let s = incident_stokes(h / 100.0);
            let identity = [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, 1.0, 0.0],
                [0.0, 0.0, 0.0, 1.0],
            ];
            assert!((horizontal_percent(&identity, s).unwrap() - h).abs() < 1e-12);
            let p = (s[1] * s[1] + s[2] * s[2] + s[3] * s[3]).sqrt();
            assert!((p - 1.0).abs() < 1e-12, "{h}: {p}");
        }
        // A perfect horizontal polarizer passes all of H, none of V.
        let pol = [
            [0.5, 0.5, 0.0, 0.0],
            [0.5, 0.5, 0.0, 0.0],
            [0.0; 4],
            [0.0; 4],
        ];
        assert_eq!(horizontal_percent(&pol, incident_stokes(0.3)), Some(100.0));
        assert_eq!(horizontal_percent(&pol, incident_stokes(0.0)), None);
    }
}
