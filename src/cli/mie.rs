//! `polbrdf mie`: Mie theory for one particle population (a sphere of one
//! radius, or a log-normal / gamma size distribution) at one wavelength:
//! efficiencies or mean cross sections, the normalised scattering matrix at
//! chosen angles, and its Greek expansion.
//!
//! ```text
//! polbrdf mie --material TiO2 --wavelength-nm 550 --radius-um 0.2 \
//!     [--host-index 1.5] [--angles-deg 0,1,2,180] [--expansion-tolerance 1e-10]
//! polbrdf mie --n 2.954 --k 0 --wavelength-nm 550 --radius-um 0.2
//! polbrdf mie ... --lognormal-rg-um 0.2 --lognormal-sigma 1.3   (instead of --radius-um)
//! polbrdf mie ... --gamma-reff-um 0.2 --gamma-veff 0.05         (instead of --radius-um)
//! polbrdf mie ... --gamma-reff-um 1.05 --gamma-veff 0.07 \
//!     --radius-min-um 0.0616236 --radius-max-um 3.3845421       (explicit integration limits)
//! ```
//!
//! `--radius-min-um` / `--radius-max-um` (both or neither, distributions
//! only, `1e-6 ≤ min < max ≤ 1e4` µm) replace the tail cuts of the radius
//! integral (`physics::psd`, Truncation); `n(r)` keeps its normalisation
//! over `(0, ∞)`, so the mean cross sections are those of the particles
//! inside the limits per particle of the whole distribution, while the
//! normalised matrix, `g`, the albedo and the expansion do not depend on it.
//!
//! # Output (JSON, conventions §1–§4)
//!
//! Inputs echoed: `material` (canonical name or `null`), `particle_index`
//! `{n, k}`, `host_index`, `wavelength_nm`, and `radius_um` or
//! `size_distribution` (`{kind: "log_normal", r_g_um, sigma_g}` or
//! `{kind: "gamma", r_eff_um, v_eff}`).
//!
//! * `size_parameter` `x = 2π r n_host/λ` (for a distribution: the largest,
//!   at the upper cut of the radius integral), `relative_index` `{n, k}` of
//!   `m = m_particle / n_host`.
//! * One sphere: efficiencies (per geometric cross section `π r²`) `qext`,
//!   `qsca`, `qabs`, `qback` (`4|S1(180°)|²/x²`), and `n_mie_terms`.
//! * A size distribution: **mean cross sections per particle in µm²**
//!   instead of efficiencies: `c_ext_um2`, `c_sca_um2`, `c_abs_um2`,
//!   `c_back_um2` (`= c_sca · a1(180°)`, the same definition as `qback`), and
//!   `radius_min_um`, `radius_max_um` (integration limits), `n_radius_nodes`,
//!   `quadrature_rel_error_estimate` (see `physics::psd`).
//! * `g`, `albedo`.
//! * `phase_matrix` (only with `--angles-deg`): `theta_deg` and the six
//!   normalised functions `a1, a2, a3, a4, b1, b2` (conventions §3,
//!   `½∫a1 dμ = 1`) at those scattering angles.
//! * `expansion`: Greek coefficients `beta, alpha, zeta, delta, gamma,
//!   epsilon`, `l = 0..L`, Siewert / VLIDORT convention (conventions §4;
//!   `β_0 = 1`, `g = β_1/3`), from `physics::mie_optics` (the same call the
//!   solver makes).
//! * `expansion_report`: `n_terms`, `n_nodes`, `round_trip_error`,
//!   `tolerance` (the one used: `--expansion-tolerance` or
//!   `physics::default_expansion_tolerance(x)`), `projection_change`,
//!   `n_check_points`.
//!
//! For a distribution, the bulk quantities come from one radius quadrature
//! (with the requested angles and 180°) and the expansion from the fixed
//! radius rule of `physics::mie_optics_distribution`; the two agree to the
//! quadrature tolerance (~1e-6 relative).
//!
//! `polbrdf mie --spec SPEC.json` instead reports the optics of every layer
//! of a spec at its wavelengths, what the solver is given
//! (`plan::film::optics_report`, docs/spec.md, Layer optics report): for a
//! film (`thickness_um`, `pigments`, `binder`) the derived `τ(λ)`, `ω(λ)`,
//! `g(λ)`, the mixed expansion and each pigment's number density and
//! cross section; warnings (a dense film) also go to stderr.
//!
//! Errors (one line, non-zero exit) name the offending flag.

use crate::physics::{
    self, PhysicsError, RefractiveIndex, materials,
    mie::{self, MieResult},
    psd::{self, SizeDistribution},
};
use clap::Args;
use serde_json::{Value, json};

/// Arguments of `polbrdf mie`. The particle index is `--material` or
/// `--n` with `--k`; the size is `--radius-um`, or `--lognormal-rg-um` with
/// `--lognormal-sigma`, or `--gamma-reff-um` with `--gamma-veff`.
#[derive(Debug, Args)]
pub struct MieArgs {
    /// Instead of one population: the optics of every layer of a spec file
    /// at its wavelengths (τ, ω, g, the expansion; a film's pigments and
    /// binder), what the solver is given.
    #[arg(long, value_name = "SPEC.json", conflicts_with_all = [
        "material", "material_table", "n", "k", "wavelength_nm", "radius_um",
        "lognormal_rg_um", "gamma_reff_um", "angles_deg",
    ])]
    spec: Option<std::path::PathBuf>,
    /// Built-in particle material (case-insensitive, e.g. TiO2, gold, silver).
    #[arg(long, value_name = "NAME")]
    material: Option<String>,
    /// Data of --material: `measured` (default) or `seed` (the seed's Table 2).
    #[arg(long, value_name = "SOURCE", requires = "material")]
    material_source: Option<String>,
    /// Dispersive particle material from a file of rows `wavelength_nm, n, k`
    /// (commas or spaces; `#` starts a comment), wavelengths increasing.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["material", "n", "k"])]
    material_table: Option<std::path::PathBuf>,
    /// Particle refractive index, real part (> 0); requires --k, excludes --material.
    #[arg(long)]
    n: Option<f64>,
    /// Particle refractive index, imaginary part (>= 0 absorbs); requires --n.
    #[arg(long)]
    k: Option<f64>,
    /// Vacuum wavelength in nm (required).
    #[arg(long)]
    wavelength_nm: Option<f64>,
    /// Real refractive index of the host / binder (>= 1).
    #[arg(long, default_value_t = 1.0)]
    host_index: f64,
    /// Sphere radius in µm (one sphere).
    #[arg(long)]
    radius_um: Option<f64>,
    /// Log-normal size distribution: geometric mean radius r_g in µm.
    #[arg(long)]
    lognormal_rg_um: Option<f64>,
    /// Log-normal size distribution: geometric standard deviation sigma_g (> 1).
    #[arg(long)]
    lognormal_sigma: Option<f64>,
    /// Gamma size distribution (Hansen & Travis): effective radius in µm.
    #[arg(long)]
    gamma_reff_um: Option<f64>,
    /// Gamma size distribution: effective variance in (0, 0.5).
    #[arg(long)]
    gamma_veff: Option<f64>,
    /// Scattering angles in degrees, within [0, 180], comma-separated: print
    /// the scattering matrix there.
    #[arg(long, value_delimiter = ',', value_name = "DEG,...")]
    angles_deg: Option<Vec<f64>>,
    /// Size distribution only: explicit lower limit of the radius integral
    /// in µm (requires --radius-max-um; default: the tail cuts of physics::psd)
    #[arg(long)]
    radius_min_um: Option<f64>,
    /// Size distribution only: explicit upper limit of the radius integral
    /// in µm (requires --radius-min-um)
    #[arg(long)]
    radius_max_um: Option<f64>,
    /// Truncation tolerance of the Greek expansion, in (0, 1) (default:
    /// 1e-10 for x < 20, relaxed for larger particles).
    #[arg(long)]
    expansion_tolerance: Option<f64>,
}

/// Run `polbrdf mie`; the error is a one-line message naming the flag.
pub fn run(a: &MieArgs) -> Result<Value, String> {
    if let Some(path) = &a.spec {
        return spec_report(path);
    }
    let wavelength_nm = a
        .wavelength_nm
        .ok_or("--wavelength-nm is required (vacuum wavelength in nm)")?;
    positive("--wavelength-nm", wavelength_nm)?;
    if !(a.host_index.is_finite() && a.host_index >= 1.0) {
        return Err(format!(
            "--host-index = {}: must be a finite number >= 1",
            number(a.host_index)
        ));
    }
    let (material, index) = particle_index(a, wavelength_nm)?;
    let size = size_spec(a)?;
    let angles = a.angles_deg.clone();
    if let Some(th) = &angles {
        if th.is_empty() {
            return Err("--angles-deg: give at least one angle".into());
        }
        if let Some(t) = th
            .iter()
            .find(|t| !(t.is_finite() && (0.0..=180.0).contains(*t)))
        {
            return Err(format!(
                "--angles-deg: {} is outside [0, 180] degrees",
                number(*t)
            ));
        }
    }
    if let Some(t) = a.expansion_tolerance
        && !(t.is_finite() && t > 0.0 && t < 1.0)
    {
        return Err(format!(
            "--expansion-tolerance = {}: must be in (0, 1)",
            number(t)
        ));
    }
    let mu: Vec<f64> = angles
        .iter()
        .flatten()
        .map(|t| t.to_radians().cos())
        .collect();
    let (_, m) = mie::wavenumber_and_index(index, a.host_index, wavelength_nm).map_err(err)?;
    let quad = psd::PsdQuadrature {
        radius_range_um: radius_limits(a, &size)?,
        ..Default::default()
    };

    let mut out = json!({
        "material": material,
        "particle_index": {"n": index.n, "k": index.k},
        "host_index": a.host_index,
        "wavelength_nm": wavelength_nm,
        "relative_index": {"n": m.re, "k": m.im},
    });
    let o = out.as_object_mut().expect("object");
    let (radius_um, distribution, matrix) = match size {
        Size::Radius(r) => {
            let res = MieResult::for_sphere(index, a.host_index, wavelength_nm, r).map_err(err)?;
            o.insert("radius_um".into(), json!(r));
            for (key, v) in [
                ("size_parameter", res.size_parameter),
                ("qext", res.qext),
                ("qsca", res.qsca),
                ("qabs", res.qabs),
                ("qback", res.qback),
                ("g", res.g),
                ("albedo", res.albedo),
            ] {
                o.insert(key.into(), json!(v));
            }
            o.insert("n_mie_terms".into(), json!(res.n_terms));
            let matrix = match angles {
                Some(_) => Some(res.scattering_matrix(&mu).map_err(err)?),
                None => None,
            };
            (Some(r), None, matrix)
        }
        Size::Distribution(dist) => {
            dist.validate().map_err(err)?;
            // 180° first (for c_back), then the requested angles.
            let mut mu_all = vec![-1.0];
            mu_all.extend_from_slice(&mu);
            let b = psd::bulk_optics(&dist, index, a.host_index, wavelength_nm, &mu_all, &quad)
                .map_err(err)?;
            o.insert("size_distribution".into(), json!(dist));
            for (key, v) in [
                ("size_parameter", b.size_parameter_max),
                ("c_ext_um2", b.c_ext_um2),
                ("c_sca_um2", b.c_sca_um2),
                ("c_abs_um2", b.c_abs_um2),
                ("c_back_um2", b.c_sca_um2 * b.matrix.a1[0]),
                ("g", b.g),
                ("albedo", b.albedo),
                ("radius_min_um", b.radius_min_um),
                ("radius_max_um", b.radius_max_um),
                ("quadrature_rel_error_estimate", b.rel_error_estimate),
            ] {
                o.insert(key.into(), json!(v));
            }
            o.insert("n_radius_nodes".into(), json!(b.n_radius_nodes));
            let matrix = angles.as_ref().map(|_| {
                let s = &b.matrix;
                let tail = |v: &[f64]| v[1..].to_vec();
                physics::ScatteringMatrixSamples {
                    mu: tail(&s.mu),
                    a1: tail(&s.a1),
                    a2: tail(&s.a2),
                    a3: tail(&s.a3),
                    a4: tail(&s.a4),
                    b1: tail(&s.b1),
                    b2: tail(&s.b2),
                }
            });
            (None, Some(dist), matrix)
        }
    };
    if let (Some(th), Some(f)) = (&angles, matrix) {
        o.insert(
            "phase_matrix".into(),
            json!({
                "theta_deg": th, "a1": f.a1, "a2": f.a2, "a3": f.a3,
                "a4": f.a4, "b1": f.b1, "b2": f.b2,
            }),
        );
    }
    let optics = match distribution {
        Some(d) => physics::mie_optics_distribution(
            index,
            a.host_index,
            wavelength_nm,
            &d,
            &quad,
            a.expansion_tolerance,
        ),
        None => physics::mie_optics(
            index,
            a.host_index,
            wavelength_nm,
            radius_um,
            None,
            a.expansion_tolerance,
        ),
    }
    .map_err(err)?;
    let tolerance = optics.tolerance;
    let r = &optics.report;
    o.insert(
        "expansion".into(),
        serde_json::to_value(&optics.coefficients).map_err(|e| e.to_string())?,
    );
    o.insert(
        "expansion_report".into(),
        json!({
            "n_terms": r.n_terms,
            "n_nodes": r.n_nodes,
            "round_trip_error": r.round_trip_error,
            "tolerance": tolerance,
            "projection_change": r.projection_change,
            "n_check_points": r.n_check_points,
        }),
    );
    Ok(out)
}

/// The particle size: one radius or a distribution.
enum Size {
    Radius(f64),
    Distribution(SizeDistribution),
}

/// `Ok` for a finite `v > 0`, else an error naming `flag`.
/// `--spec`: `plan::film::optics_report` of the spec file, its warnings
/// also on stderr.
fn spec_report(path: &std::path::Path) -> Result<Value, String> {
    let shown = path.display();
    let text = std::fs::read_to_string(path).map_err(|e| format!("{shown}: {e}"))?;
    let spec = crate::material::parse(&text).map_err(|e| format!("{shown}: {e}"))?;
    crate::plan::check_solvable(&spec, crate::material::MAX_STREAMS)
        .map_err(|e| format!("{shown}: {e}"))?;
    let report = crate::plan::film::optics_report(&spec).map_err(|e| format!("{shown}: {e}"))?;
    for (p, message) in crate::plan::film_warnings(&spec) {
        eprintln!("warning: {shown}: {p}: {message}");
    }
    Ok(report)
}

fn positive(flag: &str, v: f64) -> Result<(), String> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(format!(
            "{flag} = {}: must be a finite number > 0",
            number(v)
        ))
    }
}

/// Rows `[wavelength_nm, n, k]` of a `--material-table` file, validated as
/// a spec's `{"table"}` (docs/spec.md).
fn read_material_table(path: &std::path::Path) -> Result<Vec<[f64; 3]>, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("--material-table {}: {e}", path.display()))?;
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let v: Vec<f64> = line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|x| !x.is_empty())
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|e| format!("--material-table {}:{}: {e}", path.display(), i + 1))?;
        let [w, n, k] = v[..] else {
            return Err(format!(
                "--material-table {}:{}: three numbers (wavelength_nm, n, k), got {}",
                path.display(),
                i + 1,
                v.len()
            ));
        };
        rows.push([w, n, k]);
    }
    crate::material::validate_material_table("--material-table", &rows)?;
    Ok(rows)
}

/// Canonical material name (if any) and particle index from `--material`,
/// `--material-table` or `--n`/`--k`.
fn particle_index(
    a: &MieArgs,
    wavelength_nm: f64,
) -> Result<(Option<&'static str>, RefractiveIndex), String> {
    if let Some(path) = &a.material_table {
        let table = read_material_table(path)?;
        let spec = crate::material::MaterialSpec::Table { table };
        let index = spec
            .index_at(wavelength_nm)
            .map_err(|e| format!("--wavelength-nm: {e}"))?;
        return Ok((None, index));
    }
    match (&a.material, a.n, a.k) {
        (Some(_), Some(_), _) | (Some(_), _, Some(_)) => {
            Err("--material conflicts with --n/--k: give one of them".into())
        }
        (Some(name), None, None) => {
            let mat = match a.material_source.as_deref() {
                None | Some("measured") => materials::find(name),
                Some("seed") => materials::find_seed(name),
                Some(other) => {
                    return Err(format!(
                        "--material-source = {other}: must be measured or seed"
                    ));
                }
            }
            .map_err(|e| format!("--material: {e}"))?;
            let index = mat
                .index_at(wavelength_nm)
                .map_err(|e| format!("--wavelength-nm: {e}"))?;
            Ok((Some(mat.name), index))
        }
        (None, Some(n), Some(k)) => {
            positive("--n", n)?;
            if !(k.is_finite() && k >= 0.0) {
                return Err(format!("--k = {}: must be a finite number >= 0", number(k)));
            }
            Ok((None, RefractiveIndex::new(n, k)))
        }
        (None, Some(_), None) => Err("--n requires --k (imaginary part, 0 if none)".into()),
        (None, None, Some(_)) => Err("--k requires --n (real part)".into()),
        (None, None, None) => {
            Err("missing particle index: give --material NAME, or --n N with --k K".into())
        }
    }
}

/// `--radius-min-um` / `--radius-max-um`: both or neither, only with a
/// distribution, `0 < min < max` (the range is checked by `physics::psd`).
fn radius_limits(a: &MieArgs, size: &Size) -> Result<Option<[f64; 2]>, String> {
    match (a.radius_min_um, a.radius_max_um) {
        (None, None) => Ok(None),
        (Some(_), None) => Err("--radius-min-um requires --radius-max-um".into()),
        (None, Some(_)) => Err("--radius-max-um requires --radius-min-um".into()),
        (Some(lo), Some(hi)) => {
            if let Size::Radius(_) = size {
                return Err(
                    "--radius-min-um/--radius-max-um: only with a size distribution \
                            (--lognormal-* or --gamma-*), not --radius-um"
                        .into(),
                );
            }
            positive("--radius-min-um", lo)?;
            positive("--radius-max-um", hi)?;
            if lo >= hi {
                return Err(format!(
                    "--radius-max-um = {}: must be greater than --radius-min-um = {}",
                    number(hi),
                    number(lo)
                ));
            }
            Ok(Some([lo, hi]))
        }
    }
}

/// The size from `--radius-um` or one complete distribution pair.
fn size_spec(a: &MieArgs) -> Result<Size, String> {
    let given = |v: Option<f64>, flag: &'static str| v.map(|_| flag);
    let chosen: Vec<&str> = [
        given(a.radius_um, "--radius-um"),
        given(a.lognormal_rg_um.or(a.lognormal_sigma), "--lognormal-*"),
        given(a.gamma_reff_um.or(a.gamma_veff), "--gamma-*"),
    ]
    .into_iter()
    .flatten()
    .collect();
    match chosen.as_slice() {
        [] => Err(
            "missing particle size: give --radius-um, or --lognormal-rg-um with \
                   --lognormal-sigma, or --gamma-reff-um with --gamma-veff"
                .into(),
        ),
        [_] => {
            if let Some(r) = a.radius_um {
                positive("--radius-um", r)?;
                return Ok(Size::Radius(r));
            }
            let pair = |p: Option<f64>, fp: &str, q: Option<f64>, fq: &str| match (p, q) {
                (Some(p), Some(q)) => {
                    positive(fp, p)?;
                    positive(fq, q)?;
                    Ok((p, q))
                }
                (Some(_), None) => Err(format!("{fp} requires {fq}")),
                (None, _) => Err(format!("{fq} requires {fp}")),
            };
            if a.lognormal_rg_um.is_some() || a.lognormal_sigma.is_some() {
                let (r_g_um, sigma_g) = pair(
                    a.lognormal_rg_um,
                    "--lognormal-rg-um",
                    a.lognormal_sigma,
                    "--lognormal-sigma",
                )?;
                Ok(Size::Distribution(SizeDistribution::LogNormal {
                    r_g_um,
                    sigma_g,
                }))
            } else {
                let (r_eff_um, v_eff) = pair(
                    a.gamma_reff_um,
                    "--gamma-reff-um",
                    a.gamma_veff,
                    "--gamma-veff",
                )?;
                Ok(Size::Distribution(SizeDistribution::Gamma {
                    r_eff_um,
                    v_eff,
                }))
            }
        }
        [first, second, ..] => Err(format!(
            "{first} conflicts with {second}: give one particle size (a radius or one distribution)"
        )),
    }
}

/// A physics error as a one-line message led by the flag(s) it concerns.
fn err(e: PhysicsError) -> String {
    let flag = match &e {
        PhysicsError::OutOfRange { name, .. } => match *name {
            "radius_um" => "--radius-um",
            "wavelength_nm" => "--wavelength-nm",
            "host_index" => "--host-index",
            "particle_index.n" => "--n",
            "particle_index.k" => "--k",
            "r_g_um" => "--lognormal-rg-um",
            "sigma_g" => "--lognormal-sigma",
            "r_eff_um" => "--gamma-reff-um",
            "v_eff" => "--gamma-veff",
            "tolerance" => "--expansion-tolerance",
            "radius_min_um" => "--radius-min-um",
            "radius_max_um" => "--radius-max-um",
            n if n.starts_with("size_parameter") => {
                "size parameter 2π r n_host/λ (--radius-um or distribution, --wavelength-nm, --host-index)"
            }
            n if n.contains("relative_index") => {
                "relative index m/n_host (--material or --n/--k, --host-index)"
            }
            _ => "",
        },
        PhysicsError::UnknownMaterial { .. } => "--material",
        PhysicsError::Invalid(s) if s.contains("no convergence to tolerance") => {
            "--expansion-tolerance"
        }
        PhysicsError::Invalid(_) => "",
    };
    let msg = match &e {
        PhysicsError::OutOfRange { name, value, range } => {
            format!(
                "{name} = {} is outside the validated range {range}",
                number(*value)
            )
        }
        _ => e.to_string().replace('\n', " "),
    };
    if flag.is_empty() {
        msg
    } else {
        format!("{flag}: {msg}")
    }
}

/// `v` in plain notation for moderate magnitudes, else in scientific notation.
fn number(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-4..1e6).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}
