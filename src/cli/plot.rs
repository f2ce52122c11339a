//! `polbrdf plot {dop-vs-mu,dop-vs-tau,scalar-error,lobe,spectrum} ... -o OUT.svg|OUT.png`:
//! Figs. 8, 4, 7 and 13 of Collin, Pattanaik, LiKamWa and Bouatouch,
//! "Computation of Polarized Subsurface BRDF for Rendering" (Graphics
//! Interface 2014) from our own solves, and a paint's spectra (reflectance
//! and DOP against wavelength). Every command writes the image
//! (format from the extension), the plotted numbers next to it as CSV (same
//! stem, `.csv`; `lobe` also writes `STEM-map.{svg,png,csv}`) and prints a
//! JSON summary (files, settings, the key numbers of each curve). Images
//! show DOP and `e` in percent; the CSVs hold fractions.
//!
//! Thin: this module parses and checks the arguments, reads the specs and
//! tables, calls the figure functions of [`crate::plot::figures`] (which
//! make the spec edits, the solves and the figures) and writes what they
//! return.

use crate::brdf::{PolarGrid, grid::DEFAULT_NODES};
use crate::material::{self, Spec};
use crate::plan;
use crate::plot::csv::Csv;
use crate::plot::curves;
use crate::plot::draw;
use crate::plot::figure::Figure;
use crate::plot::figures::{
    self, DopVsMuOptions, DopVsTauOptions, LabelledSpec, LobeInput, LobeOptions,
    ScalarErrorOptions, SolveOptions, Source,
};
use crate::solver::Thickness;

mod spectrum;
use clap::{Args, Subcommand};
use serde::Serialize;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The paper whose figures these are, under each subcommand's help.
const COLLIN_2014: &str = "Collin et al. 2014: C. Collin, S. Pattanaik, P. LiKamWa, K. Bouatouch, \
    \"Computation of Polarized Subsurface BRDF for Rendering\", Graphics Interface 2014.";

/// The plot subcommands.
#[derive(Debug, Subcommand)]
pub enum PlotCommand {
    /// Degree of polarization against outgoing μ for incident μ0, one curve per
    /// optical thickness of the top layer (Fig. 8 of Collin et al. 2014). A table
    /// (--table) gives one curve at its own thickness.
    #[command(after_help = COLLIN_2014)]
    DopVsMu(DopVsMuArgs),
    /// Degree of polarization against the top layer's optical thickness for
    /// several incident Stokes vectors (Fig. 4 of Collin et al. 2014). Needs a
    /// spec: a table holds one thickness only.
    #[command(after_help = COLLIN_2014)]
    DopVsTau(DopVsTauArgs),
    /// Error of the scalar RTE, e = 1 − F_s/F_v of the (1,1) element, against the
    /// top layer's optical thickness, per spec and (μ0, μ) pair (Fig. 7 of
    /// Collin et al. 2014). Needs specs: each is solved polarized and scalar
    /// with the same settings.
    #[command(after_help = COLLIN_2014)]
    ScalarError(ScalarErrorArgs),
    /// BRDF (f11) and DOP lobes in the plane of incidence, and both over the
    /// outgoing hemisphere as polar maps (STEM-map.*), one per spec or table
    /// (Fig. 13 of Collin et al. 2014).
    #[command(after_help = COLLIN_2014)]
    Lobe(LobeArgs),
    /// Reflectance (plane albedo and π f11 at one viewing direction) and the
    /// degree of polarization against wavelength for unpolarized light, one
    /// colour per spec, at every wavelength the spec lists.
    Spectrum(spectrum::SpectrumArgs),
}

/// Output files.
#[derive(Debug, Args)]
pub struct OutputArgs {
    /// Image to write, .svg or .png; the plotted numbers go next to it (same stem, .csv).
    #[arg(short = 'o', long)]
    pub output: PathBuf,
    /// Image size in pixels, WIDTHxHEIGHT (default: per plot, about 900x520).
    #[arg(long)]
    pub size: Option<String>,
    /// TrueType font for the labels (default: DejaVu Sans or another common system font).
    #[arg(long)]
    pub font: Option<PathBuf>,
}

/// Wavelength and solver settings.
#[derive(Debug, Args)]
pub struct SolveArgs {
    /// Vacuum wavelength (nm) to plot (default: the spec's or the table's first).
    #[arg(long)]
    pub wavelength_nm: Option<f64>,
    /// Quadrature streams per hemisphere, overriding the spec's solver.streams / solver.tolerance.
    #[arg(long)]
    pub streams: Option<usize>,
    /// Most streams of a solve, from --streams or the spec (default: the service's cap).
    #[arg(long, default_value_t = super::solve::default_max_streams(), value_parser = super::solve::max_streams_parser())]
    pub max_streams: usize,
}

#[derive(Debug, Args)]
pub struct DopVsMuArgs {
    /// Material spec (docs/spec.md); or give --table.
    #[arg(required_unless_present = "table", conflicts_with = "table")]
    pub spec: Option<String>,
    /// A BRDF table file or a service result (http://HOST:PORT/v1/brdfs/ID): one curve at its thickness.
    #[arg(long)]
    pub table: Option<String>,
    /// Optical thicknesses of the top layer, one curve each (default: the spec's own), e.g. 0.1,0.5,1,10 or "infinite".
    #[arg(long, allow_hyphen_values = true)]
    pub taus: Option<String>,
    /// Cosine of the incident polar angle, (0, 1].
    #[arg(long, default_value_t = 0.6)]
    pub mu0: f64,
    /// Outgoing azimuths (deg, φ_i = 0): 180 = mirror side of the plane of incidence, 0 = backscattering side.
    #[arg(long, value_delimiter = ',', default_value = "180")]
    pub phi_o_deg: Vec<f64>,
    /// Incident Stokes irradiance I:Q:U:V (conventions §5 frames).
    #[arg(long, default_value = "1:0:0:0")]
    pub stokes: String,
    /// Number of outgoing cosines, μ = k/n for k = 1..n.
    #[arg(long, default_value_t = 50)]
    pub mu_samples: usize,
    #[command(flatten)]
    pub solve: SolveArgs,
    #[command(flatten)]
    pub out: OutputArgs,
}

#[derive(Debug, Args)]
pub struct DopVsTauArgs {
    /// Material spec (docs/spec.md); its top layer's thickness is varied.
    pub spec: String,
    /// Optical thicknesses, e.g. 0.01,0.1,1,10 (instead of --tau-range).
    #[arg(long, conflicts_with = "tau_range", allow_hyphen_values = true)]
    pub taus: Option<String>,
    /// Log-spaced thickness range LO:HI (the semi-infinite layer is added for one-layer specs).
    #[arg(long, allow_hyphen_values = true, default_value = "0.001:1000")]
    pub tau_range: String,
    /// Thicknesses per decade in --tau-range.
    #[arg(long, default_value_t = 6)]
    pub per_decade: usize,
    /// Cosine of the incident polar angle.
    #[arg(long, default_value_t = 0.6)]
    pub mu0: f64,
    /// Cosine of the outgoing polar angle (1 = normal: independent of azimuth).
    #[arg(long, default_value_t = 1.0)]
    pub mu: f64,
    /// Outgoing azimuth (deg, φ_i = 0; 180 = mirror side).
    #[arg(long, default_value_t = 180.0)]
    pub phi_o_deg: f64,
    /// Incident Stokes vectors I:Q:U:V, comma separated (default: the four of
    /// Fig. 4 of Collin et al. 2014).
    #[arg(long, default_value = "1:1:0:0,1:0:1:0,1:0:0:1,1:0:0:0")]
    pub stokes: String,
    #[command(flatten)]
    pub solve: SolveArgs,
    #[command(flatten)]
    pub out: OutputArgs,
}

#[derive(Debug, Args)]
pub struct ScalarErrorArgs {
    /// Material specs (docs/spec.md), one set of curves each; the top layer's thickness is varied.
    #[arg(required = true)]
    pub specs: Vec<String>,
    /// Legend labels, one per spec, comma separated (default: from each spec).
    #[arg(long, value_delimiter = ',')]
    pub labels: Vec<String>,
    /// Direction pairs μ0:μ (incident:outgoing cosines), comma separated.
    #[arg(long, allow_hyphen_values = true, default_value = "0.9:1.0,0.6:0.6")]
    pub pairs: String,
    /// Optical thicknesses, e.g. 0.01,0.1,1,10 (instead of --tau-range).
    #[arg(long, conflicts_with = "tau_range", allow_hyphen_values = true)]
    pub taus: Option<String>,
    /// Log-spaced thickness range LO:HI.
    #[arg(long, allow_hyphen_values = true, default_value = "0.0001:1000")]
    pub tau_range: String,
    /// Thicknesses per decade in --tau-range.
    #[arg(long, default_value_t = 6)]
    pub per_decade: usize,
    /// Outgoing azimuth (deg, φ_i = 0; 180 = mirror side).
    #[arg(long, default_value_t = 180.0)]
    pub phi_o_deg: f64,
    #[command(flatten)]
    pub solve: SolveArgs,
    #[command(flatten)]
    pub out: OutputArgs,
}

#[derive(Debug, Args)]
pub struct LobeArgs {
    /// Material specs (docs/spec.md), one lobe each (a table is built per spec).
    pub specs: Vec<String>,
    /// BRDF table files or service results (http://HOST:PORT/v1/brdfs/ID), one lobe each (repeatable).
    #[arg(long)]
    pub table: Vec<String>,
    /// Legend labels, one per spec then per table, comma separated (default: material on base).
    #[arg(long, value_delimiter = ',')]
    pub labels: Vec<String>,
    /// Incident polar angle (deg); the incident azimuth is 0.
    #[arg(long, default_value_t = 45.0)]
    pub theta_i: f64,
    /// Step of the outgoing angle in the plane of incidence (deg).
    #[arg(long, default_value_t = 1.0)]
    pub step_deg: f64,
    /// Hemisphere map cells, POLARxAZIMUTHAL (cells of 90°/n by 360°/m).
    #[arg(long, default_value = "30x60")]
    pub map_cells: String,
    /// Polar nodes of the tables built from specs.
    #[arg(long, default_value_t = DEFAULT_NODES)]
    pub nodes: usize,
    #[command(flatten)]
    pub solve: SolveArgs,
    #[command(flatten)]
    pub out: OutputArgs,
}

/// Run a plot subcommand.
pub fn run(c: &PlotCommand) -> Result<Value, String> {
    let out = match c {
        PlotCommand::DopVsMu(a) => &a.out,
        PlotCommand::DopVsTau(a) => &a.out,
        PlotCommand::ScalarError(a) => &a.out,
        PlotCommand::Lobe(a) => &a.out,
        PlotCommand::Spectrum(a) => &a.out,
    };
    // Fail on the output name and the font before any solve.
    draw::format_of(&out.output)?;
    let font = draw::register_font(out.font.as_deref())?;
    let start = Instant::now();
    let mut v = match c {
        PlotCommand::DopVsMu(a) => dop_vs_mu(a),
        PlotCommand::DopVsTau(a) => dop_vs_tau(a),
        PlotCommand::ScalarError(a) => scalar_error(a),
        PlotCommand::Lobe(a) => lobe(a),
        PlotCommand::Spectrum(a) => spectrum::spectrum(a),
    }?;
    v["font"] = json!(font.display().to_string());
    v["wall_time_ms"] = json!(start.elapsed().as_secs_f64() * 1e3);
    Ok(v)
}

// ---------------------------------------------------------------------------
// Argument parsing (pure).

/// Optical thicknesses: numbers in `(0, 1e12]`, or `infinite` (`inf`, `∞`).
pub fn parse_taus(s: &str) -> Result<Vec<Thickness>, String> {
    let hint = "give optical thicknesses > 0, comma separated, e.g. 0.1,0.5,1,10";
    let items: Vec<&str> = s
        .split(',')
        .map(str::trim)
        .filter(|x| !x.is_empty())
        .collect();
    if items.is_empty() {
        return Err(format!("--taus is empty: {hint}"));
    }
    items
        .iter()
        .map(|&x| match x.to_ascii_lowercase().as_str() {
            "inf" | "infinite" | "∞" => Ok(Thickness::Infinite),
            t => match t.parse::<f64>() {
                Ok(v) if v > 0.0 && v <= 1e12 => Ok(Thickness::Finite(v)),
                Ok(v) => Err(format!("--taus: {v} is outside (0, 1e12]: {hint}")),
                Err(_) => Err(format!("--taus: '{x}' is not a number: {hint}")),
            },
        })
        .collect()
}

/// `LO:HI` with `0 < LO < HI ≤ 1e12`.
pub fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let bad = || format!("--tau-range '{s}': give LO:HI with 0 < LO < HI <= 1e12, e.g. 0.001:1000");
    let (a, b) = s.split_once(':').ok_or_else(bad)?;
    let lo: f64 = a.trim().parse().map_err(|_| bad())?;
    let hi: f64 = b.trim().parse().map_err(|_| bad())?;
    if lo > 0.0 && hi > lo && hi <= 1e12 {
        Ok((lo, hi))
    } else {
        Err(bad())
    }
}

fn check_mu(what: &str, mu: f64) -> Result<f64, String> {
    if mu > 0.0 && mu <= 1.0 {
        Ok(mu)
    } else {
        Err(format!("{what} = {mu} is outside (0, 1]"))
    }
}

/// Direction pairs `μ0:μ,…`, each cosine in `(0, 1]`.
pub fn parse_pairs(s: &str) -> Result<Vec<(f64, f64)>, String> {
    let items: Vec<&str> = s
        .split(',')
        .map(str::trim)
        .filter(|x| !x.is_empty())
        .collect();
    if items.is_empty() {
        return Err("--pairs is empty: give MU0:MU pairs, e.g. 0.9:1.0,0.6:0.6".into());
    }
    items
        .iter()
        .map(|&x| {
            let bad = || format!("--pairs: '{x}' is not MU0:MU (e.g. 0.6:0.6)");
            let (a, b) = x.split_once(':').ok_or_else(bad)?;
            let mu0 = a.trim().parse().map_err(|_| bad())?;
            let mu = b.trim().parse().map_err(|_| bad())?;
            Ok((check_mu("--pairs μ0", mu0)?, check_mu("--pairs μ", mu)?))
        })
        .collect()
}

/// Stokes vectors `I:Q:U:V,…` with `I > 0` and `Q² + U² + V² ≤ I²`.
pub fn parse_stokes(s: &str) -> Result<Vec<[f64; 4]>, String> {
    let items: Vec<&str> = s
        .split(',')
        .map(str::trim)
        .filter(|x| !x.is_empty())
        .collect();
    if items.is_empty() {
        return Err("--stokes is empty: give I:Q:U:V vectors, e.g. 1:1:0:0".into());
    }
    items
        .iter()
        .map(|&x| {
            let bad = |why: &str| format!("--stokes: '{x}' {why} (give I:Q:U:V, e.g. 1:0:0:1)");
            let v: Vec<f64> = x
                .split(':')
                .map(|c| c.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| bad("is not four numbers"))?;
            let s: [f64; 4] = v.try_into().map_err(|_| bad("is not four numbers"))?;
            if !(s[0] > 0.0 && s.iter().all(|c| c.is_finite())) {
                return Err(bad("needs I > 0"));
            }
            if s[1] * s[1] + s[2] * s[2] + s[3] * s[3] > s[0] * s[0] * (1.0 + 1e-12) {
                return Err(bad("is more than fully polarized"));
            }
            Ok(s)
        })
        .collect()
}

/// `WIDTHxHEIGHT`, each in `[200, 4000]`.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad =
        || format!("--size '{s}': give WIDTHxHEIGHT in pixels, 200 to 4000 each, e.g. 900x520");
    let (a, b) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: u32 = a.trim().parse().map_err(|_| bad())?;
    let h: u32 = b.trim().parse().map_err(|_| bad())?;
    if (200..=4000).contains(&w) && (200..=4000).contains(&h) {
        Ok((w, h))
    } else {
        Err(bad())
    }
}

/// `NxM` map cells, `N ∈ [2, 180]`, `M ∈ [4, 360]`.
pub fn parse_cells(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("--map-cells '{s}': give POLARxAZIMUTHAL, e.g. 30x60 (2..180 x 4..360)");
    let (a, b) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let n: usize = a.trim().parse().map_err(|_| bad())?;
    let m: usize = b.trim().parse().map_err(|_| bad())?;
    if (2..=180).contains(&n) && (4..=360).contains(&m) {
        Ok((n, m))
    } else {
        Err(bad())
    }
}

fn check_phi(phi: f64) -> Result<f64, String> {
    if phi.is_finite() && (-360.0..=360.0).contains(&phi) {
        Ok(phi)
    } else {
        Err(format!("--phi-o-deg {phi} is outside [-360, 360]"))
    }
}

/// Thicknesses from `--taus`, else log-spaced from `--tau-range` and
/// `--per-decade`.
fn thicknesses(
    taus: Option<&str>,
    range: &str,
    per_decade: usize,
) -> Result<Vec<Thickness>, String> {
    match taus {
        Some(s) => parse_taus(s),
        None => {
            let (lo, hi) = parse_range(range)?;
            Ok(curves::log_space(lo, hi, per_decade)
                .map_err(|e| format!("--tau-range: {e}"))?
                .into_iter()
                .map(Thickness::Finite)
                .collect())
        }
    }
}

/// A sweep needs a finite thickness to draw.
fn check_finite(plot: &str, taus: &[Thickness]) -> Result<(), String> {
    if taus.iter().any(|t| t.value().is_finite()) {
        Ok(())
    } else {
        Err(format!(
            "{plot} needs at least one finite thickness (with --taus)"
        ))
    }
}

/// `--wavelength-nm` and `--streams` (checked).
fn solve_options(a: &SolveArgs) -> Result<SolveOptions, String> {
    if let Some(n) = a.streams
        && !(1..=a.max_streams).contains(&n)
    {
        return Err(format!(
            "--streams {n} is outside [1, {}] (--max-streams)",
            a.max_streams
        ));
    }
    Ok(SolveOptions {
        wavelength_nm: a.wavelength_nm,
        streams: a.streams,
    })
}

fn size(out: &OutputArgs) -> Result<Option<(u32, u32)>, String> {
    out.size.as_deref().map(parse_size).transpose()
}

// ---------------------------------------------------------------------------
// Files.

/// Read a spec; unless `--streams` replaces its streams, they are held to
/// `--max-streams` and the spec must pass `plan::check_solvable` there.
fn load_spec(path: &str, solve: &SolveArgs) -> Result<Spec, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let spec = material::parse(&text).map_err(|e| format!("{path}: {e}"))?;
    if solve.streams.is_none() {
        super::solve::check_stream_cap(&spec, solve.max_streams)
            .map_err(|e| format!("{path}: {e}"))?;
        // What the solve would refuse, refused before solving (as `solve`).
        plan::check_solvable(&spec, solve.max_streams).map_err(|e| format!("{path}: {e}"))?;
    }
    Ok(spec)
}

/// Every spec of a multi-spec plot, read (and checked) before any solve;
/// `--labels`, when given, has one entry per spec.
fn load_specs(paths: &[String], labels: &[String], solve: &SolveArgs) -> Result<Vec<Spec>, String> {
    if !labels.is_empty() && labels.len() != paths.len() {
        return Err(format!(
            "--labels has {} entries for {} specs",
            labels.len(),
            paths.len()
        ));
    }
    paths.iter().map(|p| load_spec(p, solve)).collect()
}

/// The specs with their paths and `--labels` entries.
fn labelled<'a>(
    paths: &'a [String],
    specs: &'a [Spec],
    labels: &[String],
) -> Vec<LabelledSpec<'a>> {
    paths
        .iter()
        .zip(specs)
        .enumerate()
        .map(|(k, (path, spec))| LabelledSpec {
            path,
            spec,
            label: labels.get(k).cloned(),
        })
        .collect()
}

/// `STEM-suffix.ext` next to `path`.
fn sibling(path: &Path, suffix: &str, ext: &str) -> PathBuf {
    let stem = path
        .file_stem()
        .map_or("plot".into(), |s| s.to_string_lossy().into_owned());
    path.with_file_name(format!("{stem}{suffix}.{ext}"))
}

/// Write the CSV next to `image` (same stem), then the image; the CSV's path.
fn write_plot(figure: &Figure, csv: &Csv, image: &Path) -> Result<PathBuf, String> {
    let csv_path = image.with_extension("csv");
    std::fs::write(&csv_path, csv.text()).map_err(|e| format!("{}: {e}", csv_path.display()))?;
    draw::write(figure, image)?;
    Ok(csv_path)
}

/// The printed JSON: the figure's summary with the plot's name and files.
fn report(plot: &str, summary: &impl Serialize, files: &[(&str, &Path)]) -> Result<Value, String> {
    let mut v = serde_json::to_value(summary).map_err(|e| e.to_string())?;
    v["plot"] = json!(plot);
    for (key, path) in files {
        v[*key] = json!(path);
    }
    Ok(v)
}

// ---------------------------------------------------------------------------
// The subcommands.

fn dop_vs_mu(a: &DopVsMuArgs) -> Result<Value, String> {
    let mu0 = check_mu("--mu0", a.mu0)?;
    let stokes = *parse_stokes(&a.stokes)?
        .first()
        .ok_or("--stokes: give one vector")?;
    if !(1..=2000).contains(&a.mu_samples) {
        return Err(format!(
            "--mu-samples {} is outside [1, 2000]",
            a.mu_samples
        ));
    }
    for &p in &a.phi_o_deg {
        check_phi(p)?;
    }
    let solve = solve_options(&a.solve)?;
    let taus = a.taus.as_deref().map(parse_taus).transpose()?;
    let o = DopVsMuOptions {
        taus,
        mu0,
        phi_o_deg: a.phi_o_deg.clone(),
        stokes,
        mu_samples: a.mu_samples,
        solve,
        size: size(&a.out)?,
    };
    let plot = match (&a.spec, &a.table) {
        (Some(path), None) => {
            let spec = load_spec(path, &a.solve)?;
            figures::dop_vs_mu(Source::Spec { path, spec: &spec }, &o)
        }
        (None, Some(src)) => {
            if o.taus.is_some() {
                return Err(
                    "--taus needs a spec: a table holds one thickness (plot it without --taus)"
                        .into(),
                );
            }
            if o.solve.streams.is_some() {
                return Err("--streams applies to specs; a table is already solved".into());
            }
            let table = super::source::load_table(src)?;
            figures::dop_vs_mu(
                Source::Table {
                    path: src,
                    table: &table,
                },
                &o,
            )
        }
        _ => return Err("give a spec or --table, not both".into()),
    }
    .map_err(|e| e.to_string())?;
    let csv = write_plot(&plot.figure, &plot.csv, &a.out.output)?;
    report(
        "dop-vs-mu",
        &plot.summary,
        &[("image", &a.out.output), ("csv", &csv)],
    )
}

fn dop_vs_tau(a: &DopVsTauArgs) -> Result<Value, String> {
    let mu0 = check_mu("--mu0", a.mu0)?;
    let mu = check_mu("--mu", a.mu)?;
    let phi_o_deg = check_phi(a.phi_o_deg)?;
    let stokes = parse_stokes(&a.stokes)?;
    let solve = solve_options(&a.solve)?;
    let taus = thicknesses(a.taus.as_deref(), &a.tau_range, a.per_decade)?;
    check_finite("dop-vs-tau", &taus)?;
    let o = DopVsTauOptions {
        taus,
        mu0,
        mu,
        phi_o_deg,
        stokes,
        solve,
        size: size(&a.out)?,
    };
    let spec = load_spec(&a.spec, &a.solve)?;
    let plot = figures::dop_vs_tau(&a.spec, &spec, &o).map_err(|e| e.to_string())?;
    let csv = write_plot(&plot.figure, &plot.csv, &a.out.output)?;
    report(
        "dop-vs-tau",
        &plot.summary,
        &[("image", &a.out.output), ("csv", &csv)],
    )
}

fn scalar_error(a: &ScalarErrorArgs) -> Result<Value, String> {
    let pairs = parse_pairs(&a.pairs)?;
    let phi_o_deg = check_phi(a.phi_o_deg)?;
    let taus = thicknesses(a.taus.as_deref(), &a.tau_range, a.per_decade)?;
    check_finite("scalar-error", &taus)?;
    let o = ScalarErrorOptions {
        taus,
        pairs,
        phi_o_deg,
        solve: solve_options(&a.solve)?,
        size: size(&a.out)?,
    };
    let specs = load_specs(&a.specs, &a.labels, &a.solve)?;
    let plot = figures::scalar_error(&labelled(&a.specs, &specs, &a.labels), &o)
        .map_err(|e| e.to_string())?;
    let csv = write_plot(&plot.figure, &plot.csv, &a.out.output)?;
    report(
        "scalar-error",
        &plot.summary,
        &[("image", &a.out.output), ("csv", &csv)],
    )
}

fn lobe(a: &LobeArgs) -> Result<Value, String> {
    if !(a.theta_i.is_finite() && (0.0..90.0).contains(&a.theta_i)) {
        return Err(format!("--theta-i {} is outside [0, 90)", a.theta_i));
    }
    if !(a.step_deg.is_finite() && a.step_deg >= 0.05 && a.step_deg <= 30.0) {
        return Err(format!("--step-deg {} is outside [0.05, 30]", a.step_deg));
    }
    let map_cells = parse_cells(&a.map_cells)?;
    let n_sources = a.specs.len() + a.table.len();
    if n_sources == 0 {
        return Err("give at least one spec or --table".into());
    }
    if n_sources > 8 {
        return Err(format!("{n_sources} lobes: at most 8 fit one figure"));
    }
    if !a.labels.is_empty() && a.labels.len() != n_sources {
        return Err(format!(
            "--labels has {} entries for {n_sources} specs and tables",
            a.labels.len()
        ));
    }
    let grid = PolarGrid::graded(a.nodes).map_err(|e| format!("--nodes: {e}"))?;
    let solve = solve_options(&a.solve)?;
    if solve.streams.is_some() && !a.table.is_empty() {
        return Err("--streams applies to specs; a table is already solved".into());
    }
    let o = LobeOptions {
        theta_i_deg: a.theta_i,
        step_deg: a.step_deg,
        map_cells,
        grid,
        solve,
        size: size(&a.out)?,
    };
    // Read every spec and table before solving any.
    let specs = a
        .specs
        .iter()
        .map(|p| load_spec(p, &a.solve))
        .collect::<Result<Vec<_>, _>>()?;
    let tables = a
        .table
        .iter()
        .map(|s| super::source::load_table(s))
        .collect::<Result<Vec<_>, _>>()?;
    let sources = a
        .specs
        .iter()
        .zip(&specs)
        .map(|(path, spec)| Source::Spec { path, spec })
        .chain(
            a.table
                .iter()
                .zip(&tables)
                .map(|(path, table)| Source::Table { path, table }),
        );
    let inputs: Vec<LobeInput> = sources
        .enumerate()
        .map(|(k, source)| LobeInput {
            source,
            label: a.labels.get(k).map(String::as_str),
        })
        .collect();
    let plot = figures::lobe(&inputs, &o).map_err(|e| e.to_string())?;
    let out = &a.out.output;
    let csv = write_plot(&plot.figure, &plot.csv, out)?;
    let ext = out
        .extension()
        .map_or("png".into(), |e| e.to_string_lossy().into_owned());
    let map_image = sibling(out, "-map", &ext);
    let map_csv = write_plot(&plot.map_figure, &plot.map_csv, &map_image)?;
    report(
        "lobe",
        &plot.summary,
        &[
            ("image", out),
            ("csv", &csv),
            ("map_image", &map_image),
            ("map_csv", &map_csv),
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn taus_parse_and_name_bad_items() {
        assert_eq!(
            parse_taus("0.1, 0.5,1,10,infinite").unwrap(),
            vec![
                Thickness::Finite(0.1),
                Thickness::Finite(0.5),
                Thickness::Finite(1.0),
                Thickness::Finite(10.0),
                Thickness::Infinite
            ]
        );
        let e = parse_taus("0.1,abc").unwrap_err();
        assert!(e.contains("'abc' is not a number"), "{e}");
        assert!(parse_taus("-1").unwrap_err().contains("outside (0, 1e12]"));
        assert!(parse_taus("0").is_err());
        assert!(parse_taus(" , ").unwrap_err().contains("empty"));
        assert!(parse_taus("nan").is_err());
    }

    #[test]
    fn ranges_pairs_stokes_sizes() {
        assert_eq!(parse_range("0.001:1000").unwrap(), (0.001, 1000.0));
        assert!(parse_range("10:1").is_err());
        assert!(parse_range("0:1").is_err());
        assert!(parse_range("1-10").is_err());
        assert_eq!(
            parse_pairs("0.9:1.0,0.6:0.6").unwrap(),
            vec![(0.9, 1.0), (0.6, 0.6)]
        );
        assert!(parse_pairs("0.9:1.5").unwrap_err().contains("(0, 1]"));
        assert!(parse_pairs("0.9").is_err());
        assert_eq!(parse_stokes("1:0:0:1").unwrap(), vec![[1.0, 0.0, 0.0, 1.0]]);
        assert!(
            parse_stokes("1:1:1:0")
                .unwrap_err()
                .contains("more than fully")
        );
        assert!(parse_stokes("0:0:0:0").unwrap_err().contains("I > 0"));
        assert!(parse_stokes("1:0:0").is_err());
        assert_eq!(parse_size("800x500").unwrap(), (800, 500));
        assert!(parse_size("10x10").is_err());
        assert_eq!(parse_cells("30x60").unwrap(), (30, 60));
        assert!(parse_cells("1x60").is_err());
    }

    #[test]
    fn map_files_sit_next_to_the_image() {
        assert_eq!(
            sibling(Path::new("out/fig13.png"), "-map", "csv"),
            PathBuf::from("out/fig13-map.csv")
        );
    }

    #[test]
    fn sweeps_need_a_finite_thickness() {
        let t = thicknesses(None, "0.1:10", 1).unwrap();
        assert_eq!(t.len(), 3);
        assert_eq!(
            (t[0], t[2]),
            (Thickness::Finite(0.1), Thickness::Finite(10.0))
        );
        assert_eq!(thicknesses(Some("2,inf"), "bad", 0).unwrap().len(), 2);
        let e = check_finite("scalar-error", &[Thickness::Infinite]).unwrap_err();
        assert!(e.contains("at least one finite thickness"), "{e}");
        assert!(check_finite("dop-vs-tau", &parse_taus("1,inf").unwrap()).is_ok());
    }
}
