//! `polbrdf plot {dop-vs-mu,dop-vs-tau,scalar-error,lobe} ... -o OUT.svg|OUT.png`:
//! the seed's figures 8, 4, 7 and 13 from our own solves. Every command
//! writes the image (format from the extension), the plotted numbers next to
//! it as CSV (same stem, `.csv`; `lobe` also writes `STEM-map.{svg,png,csv}`)
//! and prints a JSON summary (files, settings, the key numbers of each
//! curve). Images show DOP and `e` in percent; the CSVs hold fractions.
//!
//! Thickness sweeps (`dop-vs-mu --taus`, `dop-vs-tau`, `scalar-error`)
//! replace the optical thickness of the spec's **top** layer and solve once
//! per thickness at the few user cosines the plot needs (in parallel). The
//! lobe needs the whole hemisphere and goes through a BRDF table
//! (`Table::from_spec`, or a table file / service result given with
//! `--table`).

use crate::brdf::{Directions, PolarGrid, Table, grid::DEFAULT_NODES};
use crate::plot::csv::{Cell, Csv};
use crate::plot::curves::{self, DopSample, ErrorSample, LobeSample};
use crate::plot::draw;
use crate::plot::figure::{
    Axis, Dash, Figure, Legend, LinePanel, LobePanel, MapPanel, Panel, Series, lobe_xy, nice_ceil,
};
use crate::solver::{Problem, Thickness};
use crate::spec::{self, BaseSpec, MaterialSpec, ScattererSpec, Spec, StreamPolicy, ThicknessSpec};
use clap::{Args, Subcommand};
use rayon::prelude::*;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The plot subcommands.
#[derive(Debug, Subcommand)]
pub enum PlotCommand {
    /// Degree of polarization against outgoing μ for incident μ0, one curve per
    /// optical thickness of the top layer (seed Fig. 8). A table (--table) gives
    /// one curve at its own thickness.
    DopVsMu(DopVsMuArgs),
    /// Degree of polarization against the top layer's optical thickness for
    /// several incident Stokes vectors (seed Fig. 4). Needs a spec: a table
    /// holds one thickness only.
    DopVsTau(DopVsTauArgs),
    /// Error of the scalar RTE, e = 1 − F_s/F_v of the (1,1) element, against the
    /// top layer's optical thickness, per spec and (μ0, μ) pair (seed Fig. 7).
    /// Needs specs: each is solved polarized and scalar with the same settings.
    ScalarError(ScalarErrorArgs),
    /// BRDF (f11) and DOP lobes in the plane of incidence, and both over the
    /// outgoing hemisphere as polar maps (STEM-map.*), one per spec or table
    /// (seed Fig. 13).
    Lobe(LobeArgs),
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
    #[arg(long, allow_negative_numbers = true)]
    pub taus: Option<String>,
    /// Cosine of the incident polar angle, (0, 1].
    #[arg(long, default_value_t = 0.6)]
    pub mu0: f64,
    /// Outgoing azimuths (deg, φ_i = 0): 180 = mirror side of the plane of incidence, 0 = backscattering side.
    #[arg(
        long,
        value_delimiter = ',',
        allow_negative_numbers = true,
        default_value = "180"
    )]
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
    #[arg(long, conflicts_with = "tau_range", allow_negative_numbers = true)]
    pub taus: Option<String>,
    /// Log-spaced thickness range LO:HI (the semi-infinite layer is added for one-layer specs).
    #[arg(long, default_value = "0.001:1000")]
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
    #[arg(long, allow_negative_numbers = true, default_value_t = 180.0)]
    pub phi_o_deg: f64,
    /// Incident Stokes vectors I:Q:U:V, comma separated (default: the four of seed Fig. 4).
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
    #[arg(long, default_value = "0.9:1.0,0.6:0.6")]
    pub pairs: String,
    /// Optical thicknesses, e.g. 0.01,0.1,1,10 (instead of --tau-range).
    #[arg(long, conflicts_with = "tau_range", allow_negative_numbers = true)]
    pub taus: Option<String>,
    /// Log-spaced thickness range LO:HI.
    #[arg(long, default_value = "0.0001:1000")]
    pub tau_range: String,
    /// Thicknesses per decade in --tau-range.
    #[arg(long, default_value_t = 6)]
    pub per_decade: usize,
    /// Outgoing azimuth (deg, φ_i = 0; 180 = mirror side).
    #[arg(long, allow_negative_numbers = true, default_value_t = 180.0)]
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

/// A Stokes vector as `1:0:0:0` text (labels, CSV).
pub fn stokes_text(s: [f64; 4]) -> String {
    s.map(|c| format!("{c}")).join(":")
}

/// Seed wording of the Fig. 4 states, else the vector.
fn stokes_name(s: [f64; 4]) -> String {
    let v = stokes_text(s);
    let name = match v.as_str() {
        "1:0:0:0" => "unpolarized",
        "1:1:0:0" => "linear, in the plane of incidence",
        "1:-1:0:0" => "linear, perpendicular",
        "1:0:1:0" => "linear at +45°",
        "1:0:0:1" => "right circular",
        "1:0:0:-1" => "left circular",
        _ => return format!("[{}]", v.replace(':', ", ")),
    };
    format!("[{}] {name}", v.replace(':', ", "))
}

// ---------------------------------------------------------------------------
// Specs, labels, settings.

fn load_spec(path: &str) -> Result<Spec, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    spec::parse(&text).map_err(|e| format!("{path}: {e}"))
}

fn material_name(spec: &Spec) -> String {
    let Some(layer) = spec.layers.first() else {
        return "no layer".into();
    };
    match &layer.scatterer {
        ScattererSpec::Mie(m) => {
            let mat = match &m.material {
                MaterialSpec::Name(n) => n.clone(),
                MaterialSpec::Index { n, k } => format!("n = {n} + {k}i"),
            };
            match m.radius_um {
                Some(r) => format!("{mat}, r = {r} µm"),
                None => format!("{mat} (size distribution)"),
            }
        }
        ScattererSpec::Expansion(_) => "expansion".into(),
        ScattererSpec::Rayleigh { .. } => "Rayleigh".into(),
        ScattererSpec::HenyeyGreenstein { g, .. } => format!("Henyey–Greenstein g = {g}"),
    }
}

fn base_name(spec: &Spec) -> String {
    match &spec.base {
        BaseSpec::Black => "black".into(),
        BaseSpec::Lambertian { albedo } => format!("Lambertian {albedo}"),
        BaseSpec::Fresnel { material, .. } => match material {
            MaterialSpec::Name(n) => n.clone(),
            MaterialSpec::Index { n, k } => format!("mirror n = {n} + {k}i"),
        },
    }
}

fn spec_thickness(spec: &Spec) -> Thickness {
    match spec.layers.first().map(|l| &l.optical_thickness) {
        Some(ThicknessSpec::Number(t)) => Thickness::Finite(*t),
        Some(ThicknessSpec::Word(_)) => Thickness::Infinite,
        None => Thickness::Finite(0.0),
    }
}

fn tau_text(t: f64) -> String {
    if t.is_infinite() {
        "∞".into()
    } else {
        format!("{t}")
    }
}

fn file_name(path: &str) -> String {
    Path::new(path)
        .file_name()
        .map_or(path.to_string(), |f| f.to_string_lossy().into_owned())
}

/// The wavelength to plot for a spec: `--wavelength-nm`, else its first.
fn spec_wavelength(spec: &Spec, opt: Option<f64>) -> Option<f64> {
    opt.or_else(|| spec::wavelengths(spec)[0])
}

fn wl_text(wl: Option<f64>) -> String {
    wl.map_or(String::new(), |w| format!(", λ = {w} nm"))
}

/// The stream policy: `--streams` wins over the spec.
fn policy(spec: &Spec, streams: Option<usize>) -> Result<StreamPolicy, String> {
    match streams {
        Some(n) if (1..=spec::MAX_STREAMS).contains(&n) => Ok(StreamPolicy::Fixed(n)),
        Some(n) => Err(format!(
            "--streams {n} is outside [1, {}]",
            spec::MAX_STREAMS
        )),
        None => Ok(spec::stream_policy(spec)),
    }
}

fn policy_text(p: StreamPolicy) -> String {
    match p {
        StreamPolicy::Fixed(n) => format!("{n} streams"),
        StreamPolicy::Tolerance(t) => format!("streams for tolerance {t}"),
    }
}

fn policy_json(p: StreamPolicy) -> Value {
    match p {
        StreamPolicy::Fixed(n) => json!({"streams": n}),
        StreamPolicy::Tolerance(t) => json!({"tolerance": t}),
    }
}

/// The problem of a spec at the plot's wavelength.
fn problem_of(path: &str, spec: &Spec, wl: Option<f64>) -> Result<Problem, String> {
    spec::problem(spec, wl).map_err(|e| format!("{path}: {e}"))
}

/// Thicknesses from `--taus` or `--tau-range`/`--per-decade`, plus the
/// semi-infinite layer when asked and possible.
fn sweep(
    taus: Option<&str>,
    range: &str,
    per_decade: usize,
    semi_infinite: bool,
) -> Result<Vec<Thickness>, String> {
    let mut t = match taus {
        Some(s) => parse_taus(s)?,
        None => {
            let (lo, hi) = parse_range(range)?;
            curves::log_space(lo, hi, per_decade)
                .map_err(|e| format!("--tau-range: {e}"))?
                .into_iter()
                .map(Thickness::Finite)
                .collect()
        }
    };
    if semi_infinite && !t.contains(&Thickness::Infinite) {
        t.push(Thickness::Infinite);
    }
    Ok(t)
}

fn size_or(out: &OutputArgs, default: (u32, u32)) -> Result<(u32, u32), String> {
    out.size.as_deref().map_or(Ok(default), parse_size)
}

/// `STEM-suffix.ext` next to `path`.
fn sibling(path: &Path, suffix: &str, ext: &str) -> PathBuf {
    let stem = path
        .file_stem()
        .map_or("plot".into(), |s| s.to_string_lossy().into_owned());
    path.with_file_name(format!("{stem}{suffix}.{ext}"))
}

fn write_csv(path: &Path, csv: &Csv) -> Result<(), String> {
    std::fs::write(path, csv.text()).map_err(|e| format!("{}: {e}", path.display()))
}

/// `(lo, hi)` of a percent axis: from 0 (or below, for negative data) to a
/// nice value above the data, at most 100 for data within 100 (a DOP).
fn percent_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    let hi = if hi <= 100.0 {
        nice_ceil(hi * 1.05).min(100.0)
    } else {
        nice_ceil(hi * 1.05)
    };
    let lo = if lo < 0.0 {
        -nice_ceil(-lo * 1.05)
    } else {
        0.0
    };
    (lo, hi)
}

// ---------------------------------------------------------------------------
// DOP CSV (dop-vs-mu, dop-vs-tau).

const DOP_HEADER: [&str; 15] = [
    "tau",
    "mu0",
    "mu",
    "theta_o_deg",
    "phi_o_deg",
    "stokes_in_i",
    "stokes_in_q",
    "stokes_in_u",
    "stokes_in_v",
    "f11_per_sr",
    "i_per_sr",
    "q_per_sr",
    "u_per_sr",
    "v_per_sr",
    "dop",
];

fn dop_csv(rows: &[DopSample]) -> Csv {
    let mut c = Csv::new(&DOP_HEADER);
    for r in rows {
        let mut row: Vec<Cell> = vec![
            r.tau.into(),
            r.mu0.into(),
            r.mu.into(),
            curves::theta_deg(r.mu).into(),
            r.phi_o_deg.into(),
        ];
        row.extend(r.stokes_in.iter().map(|&x| Cell::Num(x)));
        row.push(r.f11.into());
        row.extend(r.stokes_out.iter().map(|&x| Cell::Num(x)));
        row.push(r.dop.into());
        c.push(row);
    }
    c
}

fn min_max_by<T>(items: &[T], key: impl Fn(&T) -> f64) -> Option<(&T, &T)> {
    let lo = items.iter().min_by(|a, b| key(a).total_cmp(&key(b)))?;
    let hi = items.iter().max_by(|a, b| key(a).total_cmp(&key(b)))?;
    Some((lo, hi))
}

// ---------------------------------------------------------------------------
// dop-vs-mu (seed Fig. 8).

fn dop_vs_mu(a: &DopVsMuArgs) -> Result<Value, String> {
    let mu0 = check_mu("--mu0", a.mu0)?;
    let e = *parse_stokes(&a.stokes)?
        .first()
        .ok_or("--stokes: give one vector")?;
    if !(1..=2000).contains(&a.mu_samples) {
        return Err(format!(
            "--mu-samples {} is outside [1, 2000]",
            a.mu_samples
        ));
    }
    for &p in &a.phi_o_deg {
        if !(p.is_finite() && (-360.0..=360.0).contains(&p)) {
            return Err(format!("--phi-o-deg {p} is outside [-360, 360]"));
        }
    }
    let mus = curves::mu_samples(a.mu_samples);
    let (rows, what, wl, settings) = match (&a.spec, &a.table) {
        (Some(path), None) => {
            let spec = load_spec(path)?;
            let wl = spec_wavelength(&spec, a.solve.wavelength_nm);
            let pol = policy(&spec, a.solve.streams)?;
            let problem = problem_of(path, &spec, wl)?;
            let taus = match &a.taus {
                Some(s) => parse_taus(s)?,
                None => vec![spec_thickness(&spec)],
            };
            let rows = curves::dop_vs_mu(&problem, pol, mu0, &taus, &mus, &a.phi_o_deg, e)
                .map_err(|e| format!("{path}: {e}"))?;
            let what = format!(
                "{} ({} on {} base)",
                file_name(path),
                material_name(&spec),
                base_name(&spec)
            );
            (rows, what, wl, (policy_text(pol), policy_json(pol)))
        }
        (None, Some(src)) => {
            if a.taus.is_some() {
                return Err(
                    "--taus needs a spec: a table holds one thickness (plot it without --taus)"
                        .into(),
                );
            }
            if a.solve.streams.is_some() {
                return Err("--streams applies to specs; a table is already solved".into());
            }
            let table = super::source::load_table(src)?;
            let wl = table_wavelength(&table, a.solve.wavelength_nm)?;
            let (tau, label) = table_description(&table);
            let rows = curves::dop_vs_mu_table(&table, wl, tau, mu0, &mus, &a.phi_o_deg, e)?;
            let s = table.metadata.solver.streams;
            (
                rows,
                format!("table {} ({label})", file_name(src)),
                wl,
                (format!("{s} streams (table)"), json!({"streams": s})),
            )
        }
        _ => return Err("give a spec or --table, not both".into()),
    };

    // One curve per (τ, φ_o): colour by τ, dash by φ_o.
    let mut taus: Vec<f64> = Vec::new();
    for r in &rows {
        if !taus.iter().any(|t| t.total_cmp(&r.tau).is_eq()) {
            taus.push(r.tau);
        }
    }
    let several_phi = a.phi_o_deg.len() > 1;
    let mut series = Vec::new();
    let mut summary = Vec::new();
    for (ti, &tau) in taus.iter().enumerate() {
        for (pi, &phi) in a.phi_o_deg.iter().enumerate() {
            let curve: Vec<DopSample> = rows
                .iter()
                .filter(|r| r.tau.total_cmp(&tau).is_eq() && r.phi_o_deg == phi)
                .cloned()
                .collect();
            let label = if several_phi {
                format!("τ = {}, φ_o = {phi}°", tau_text(tau))
            } else {
                format!("τ = {}", tau_text(tau))
            };
            series.push(Series {
                label,
                points: curve.iter().map(|r| (r.mu, 100.0 * r.dop)).collect(),
                color: ti,
                dash: if pi % 2 == 0 {
                    Dash::Solid
                } else {
                    Dash::Dashed
                },
                markers: false,
            });
            if let Some((lo, hi)) = min_max_by(&curve, |r| r.dop) {
                summary.push(json!({
                    "tau": tau, "phi_o_deg": phi,
                    "dop_min": lo.dop, "mu_at_min": lo.mu,
                    "dop_max": hi.dop, "mu_at_max": hi.mu,
                }));
            }
        }
    }
    let (lo, hi) = percent_range(rows.iter().map(|r| 100.0 * r.dop));
    let phis = a
        .phi_o_deg
        .iter()
        .enumerate()
        .map(|(i, p)| format!("{p}°{}", if i % 2 == 0 { " solid" } else { " dashed" }))
        .collect::<Vec<_>>()
        .join(", ");
    let fig = Figure {
        size: size_or(&a.out, (900, 540))?,
        rows: 1,
        cols: 1,
        panels: vec![Panel::Line(LinePanel {
            title: format!(
                "Degree of polarization of the reflected light, μ0 = {mu0}, incident {}",
                stokes_name(e)
            ),
            x: Axis {
                label: "outgoing μ = cos θ_o".into(),
                lo: 0.0,
                hi: 1.0,
                log: false,
            },
            y: Axis {
                label: "degree of polarization (%)".into(),
                lo,
                hi,
                log: false,
            },
            series,
            legend: Legend::UpperLeft,
        })],
        footnote: format!(
            "{what}{}, {}; φ_o (φ_i = 0): {phis} (180° = mirror side)",
            wl_text(wl),
            settings.0
        ),
    };
    let csv_path = a.out.output.with_extension("csv");
    write_csv(&csv_path, &dop_csv(&rows))?;
    draw::write(&fig, &a.out.output)?;
    Ok(json!({
        "plot": "dop-vs-mu",
        "image": a.out.output, "csv": csv_path,
        "wavelength_nm": wl, "solver": settings.1,
        "mu0": mu0, "stokes_in": e, "rows": rows.len(),
        "curves": summary,
    }))
}

/// The wavelength to evaluate a table at: `--wavelength-nm`, else its only
/// (first) one.
fn table_wavelength(table: &Table, opt: Option<f64>) -> Result<Option<f64>, String> {
    match opt {
        Some(w) => {
            table
                .wavelength_weights(Some(w))
                .map_err(|e| e.to_string())?;
            Ok(Some(w))
        }
        None => Ok(table.wavelengths.first().and_then(|w| w.wavelength_nm)),
    }
}

/// A table's top-layer thickness and a label, from the spec in its metadata.
fn table_description(table: &Table) -> (f64, String) {
    match serde_json::from_value::<Spec>(table.metadata.spec.clone()) {
        Ok(s) => (
            curves::tau_value(spec_thickness(&s)),
            format!("{} on {} base", material_name(&s), base_name(&s)),
        ),
        Err(_) => (f64::NAN, "spec unknown".into()),
    }
}

// ---------------------------------------------------------------------------
// dop-vs-tau (seed Fig. 4).

fn dop_vs_tau(a: &DopVsTauArgs) -> Result<Value, String> {
    let mu0 = check_mu("--mu0", a.mu0)?;
    let mu = check_mu("--mu", a.mu)?;
    if !(a.phi_o_deg.is_finite() && (-360.0..=360.0).contains(&a.phi_o_deg)) {
        return Err(format!(
            "--phi-o-deg {} is outside [-360, 360]",
            a.phi_o_deg
        ));
    }
    let stokes = parse_stokes(&a.stokes)?;
    let spec = load_spec(&a.spec)?;
    let wl = spec_wavelength(&spec, a.solve.wavelength_nm);
    let pol = policy(&spec, a.solve.streams)?;
    let problem = problem_of(&a.spec, &spec, wl)?;
    let one_layer = spec.layers.len() == 1;
    let taus = sweep(a.taus.as_deref(), &a.tau_range, a.per_decade, one_layer)?;
    let rows = curves::dop_vs_tau(&problem, pol, mu0, mu, a.phi_o_deg, &taus, &stokes)
        .map_err(|e| format!("{}: {e}", a.spec))?;

    let mut series = Vec::new();
    let mut summary = Vec::new();
    for (k, &e) in stokes.iter().enumerate() {
        let curve: Vec<&DopSample> = rows.iter().filter(|r| r.stokes_in == e).collect();
        let finite: Vec<DopSample> = curve
            .iter()
            .filter(|r| r.tau.is_finite())
            .map(|r| (*r).clone())
            .collect();
        let semi = curve.iter().find(|r| r.tau.is_infinite()).map(|r| r.dop);
        let label = match semi {
            Some(d) => format!("{}  (τ = ∞: {:.1}%)", stokes_name(e), 100.0 * d),
            None => stokes_name(e),
        };
        series.push(Series {
            label,
            points: finite.iter().map(|r| (r.tau, 100.0 * r.dop)).collect(),
            color: k,
            dash: Dash::Solid,
            markers: true,
        });
        let (lo, _) = min_max_by(&finite, |r| r.dop)
            .ok_or("dop-vs-tau needs at least one finite thickness (with --taus)")?;
        summary.push(json!({
            "stokes_in": e,
            "dop_at_smallest_tau": finite.first().map(|r| r.dop),
            "dop_at_largest_tau": finite.last().map(|r| r.dop),
            "dop_min": lo.dop, "tau_at_min": lo.tau,
            "dop_semi_infinite": semi,
        }));
    }
    let finite_taus: Vec<f64> = rows
        .iter()
        .map(|r| r.tau)
        .filter(|t| t.is_finite())
        .collect();
    let t_lo = finite_taus.iter().cloned().fold(f64::INFINITY, f64::min);
    let t_hi = finite_taus.iter().cloned().fold(0.0, f64::max);
    let (x_lo, x_hi) = (
        10f64.powf(t_lo.log10().floor()),
        10f64.powf(t_hi.log10().ceil()),
    );
    let (lo, hi) = percent_range(rows.iter().map(|r| 100.0 * r.dop));
    let fig = Figure {
        size: size_or(&a.out, (900, 540))?,
        rows: 1,
        cols: 1,
        panels: vec![Panel::Line(LinePanel {
            title: format!(
                "Degree of polarization against thickness, μ0 = {mu0}, μ = {mu}, φ_o = {}°",
                a.phi_o_deg
            ),
            x: Axis {
                label: "optical thickness τ of the top layer".into(),
                lo: x_lo,
                hi: if x_hi > x_lo { x_hi } else { 10.0 * x_lo },
                log: true,
            },
            y: Axis {
                label: "degree of polarization (%)".into(),
                lo,
                hi,
                log: false,
            },
            series,
            legend: Legend::LowerLeft,
        })],
        footnote: format!(
            "{} ({} on {} base){}, {}; incident Stokes in the meridian frame (Q > 0: in the plane of incidence)",
            file_name(&a.spec),
            material_name(&spec),
            base_name(&spec),
            wl_text(wl),
            policy_text(pol)
        ),
    };
    let csv_path = a.out.output.with_extension("csv");
    write_csv(&csv_path, &dop_csv(&rows))?;
    draw::write(&fig, &a.out.output)?;
    Ok(json!({
        "plot": "dop-vs-tau",
        "image": a.out.output, "csv": csv_path,
        "wavelength_nm": wl, "solver": policy_json(pol),
        "mu0": mu0, "mu": mu, "phi_o_deg": a.phi_o_deg, "rows": rows.len(),
        "curves": summary,
    }))
}

// ---------------------------------------------------------------------------
// scalar-error (seed Fig. 7).

fn scalar_error(a: &ScalarErrorArgs) -> Result<Value, String> {
    let pairs = parse_pairs(&a.pairs)?;
    if !(a.phi_o_deg.is_finite() && (-360.0..=360.0).contains(&a.phi_o_deg)) {
        return Err(format!(
            "--phi-o-deg {} is outside [-360, 360]",
            a.phi_o_deg
        ));
    }
    if !a.labels.is_empty() && a.labels.len() != a.specs.len() {
        return Err(format!(
            "--labels has {} entries for {} specs",
            a.labels.len(),
            a.specs.len()
        ));
    }
    let taus = sweep(a.taus.as_deref(), &a.tau_range, a.per_decade, false)?;
    // Parse everything before solving anything.
    let mut inputs = Vec::new();
    for (k, path) in a.specs.iter().enumerate() {
        let spec = load_spec(path)?;
        let wl = spec_wavelength(&spec, a.solve.wavelength_nm);
        let pol = policy(&spec, a.solve.streams)?;
        let problem = problem_of(path, &spec, wl)?;
        let label = a
            .labels
            .get(k)
            .cloned()
            .unwrap_or_else(|| material_name(&spec));
        inputs.push((path, spec, wl, pol, problem, label));
    }
    let solved: Vec<Result<Vec<ErrorSample>, String>> = inputs
        .par_iter()
        .map(|(path, _, _, pol, problem, _)| {
            curves::scalar_error_vs_tau(problem, *pol, &pairs, a.phi_o_deg, &taus)
                .map_err(|e| format!("{path}: {e}"))
        })
        .collect();
    let mut csv = Csv::new(&[
        "label",
        "tau",
        "mu0",
        "mu",
        "phi_o_deg",
        "f_vector_per_sr",
        "f_scalar_per_sr",
        "e",
    ]);
    let mut series = Vec::new();
    let mut summary = Vec::new();
    let mut all_e = Vec::new();
    for (k, ((path, spec, wl, pol, _, label), rows)) in inputs.iter().zip(solved).enumerate() {
        let rows = rows?;
        for r in &rows {
            csv.push(vec![
                label.as_str().into(),
                r.tau.into(),
                r.mu0.into(),
                r.mu.into(),
                r.phi_o_deg.into(),
                r.f_vector.into(),
                r.f_scalar.into(),
                r.e.into(),
            ]);
            all_e.push(100.0 * r.e);
        }
        for (j, &(mu0, mu)) in pairs.iter().enumerate() {
            let curve: Vec<ErrorSample> = rows
                .iter()
                .filter(|r| r.mu0 == mu0 && r.mu == mu)
                .cloned()
                .collect();
            series.push(Series {
                label: format!("{label}, (μ0, μ) = ({mu0}, {mu})"),
                points: curve.iter().map(|r| (r.tau, 100.0 * r.e)).collect(),
                color: k,
                dash: if j % 2 == 0 {
                    Dash::Solid
                } else {
                    Dash::Dashed
                },
                markers: false,
            });
            let (lo, hi) = min_max_by(&curve, |r| r.e).ok_or("no thickness")?;
            summary.push(json!({
                "label": label, "spec": path, "wavelength_nm": wl,
                "solver": policy_json(*pol), "base": base_name(spec),
                "mu0": mu0, "mu": mu,
                "e_max": hi.e, "tau_at_max": hi.tau,
                "e_min": lo.e, "tau_at_min": lo.tau,
                "e_at_smallest_tau": curve.first().map(|r| r.e),
                "e_at_largest_tau": curve.last().map(|r| r.e),
            }));
        }
    }
    let t_lo = taus
        .iter()
        .map(|&t| curves::tau_value(t))
        .fold(f64::INFINITY, f64::min);
    let t_hi = taus
        .iter()
        .map(|&t| curves::tau_value(t))
        .filter(|t| t.is_finite())
        .fold(0.0, f64::max);
    let (x_lo, x_hi) = (
        10f64.powf(t_lo.log10().floor()),
        10f64.powf(t_hi.log10().ceil()),
    );
    let (lo, hi) = percent_range(all_e.into_iter());
    let details: Vec<String> = inputs
        .iter()
        .map(|(path, spec, wl, pol, _, _)| {
            format!(
                "{} ({} base{}, {})",
                file_name(path),
                base_name(spec),
                wl_text(*wl),
                policy_text(*pol)
            )
        })
        .collect();
    let fig = Figure {
        size: size_or(&a.out, (900, 540))?,
        rows: 1,
        cols: 1,
        panels: vec![Panel::Line(LinePanel {
            title: format!(
                "Error of the scalar RTE in f11, e = 1 − F_s/F_v, φ_o = {}°",
                a.phi_o_deg
            ),
            x: Axis {
                label: "optical thickness τ of the top layer".into(),
                lo: x_lo,
                hi: if x_hi > x_lo { x_hi } else { 10.0 * x_lo },
                log: true,
            },
            y: Axis {
                label: "e = 1 − F_s/F_v (%)".into(),
                lo,
                hi,
                log: false,
            },
            series,
            legend: Legend::UpperLeft,
        })],
        footnote: details.join("; "),
    };
    let csv_path = a.out.output.with_extension("csv");
    write_csv(&csv_path, &csv)?;
    draw::write(&fig, &a.out.output)?;
    Ok(json!({
        "plot": "scalar-error",
        "image": a.out.output, "csv": csv_path,
        "phi_o_deg": a.phi_o_deg, "rows": csv.rows.len(),
        "curves": summary,
    }))
}

// ---------------------------------------------------------------------------
// lobe (seed Fig. 13).

/// One lobe source: a label and its table.
struct LobeSource {
    label: String,
    origin: String,
    table: Table,
    wavelength_nm: Option<f64>,
}

fn lobe(a: &LobeArgs) -> Result<Value, String> {
    if !(a.theta_i.is_finite() && (0.0..90.0).contains(&a.theta_i)) {
        return Err(format!("--theta-i {} is outside [0, 90)", a.theta_i));
    }
    if !(a.step_deg.is_finite() && a.step_deg >= 0.05 && a.step_deg <= 30.0) {
        return Err(format!("--step-deg {} is outside [0.05, 30]", a.step_deg));
    }
    let (n_theta, n_phi) = parse_cells(&a.map_cells)?;
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
    // Parse every spec before solving any.
    let mut specs = Vec::new();
    for path in &a.specs {
        let mut spec = load_spec(path)?;
        let wl = spec_wavelength(&spec, a.solve.wavelength_nm);
        if let Some(w) = wl {
            spec.wavelengths_nm = Some(vec![w]);
        }
        if let Some(n) = a.solve.streams {
            policy(&spec, Some(n))?;
            spec.solver.streams = Some(n);
        }
        spec::validate(&spec).map_err(|e| format!("{path}: {e}"))?;
        specs.push((path, spec, wl));
    }
    let built: Vec<Result<LobeSource, String>> = specs
        .par_iter()
        .map(|(path, spec, wl)| {
            let table = Table::from_spec(spec, grid.clone()).map_err(|e| format!("{path}: {e}"))?;
            Ok(LobeSource {
                label: format!("{} on {}", material_name(spec), base_name(spec)),
                origin: format!(
                    "{} ({})",
                    file_name(path),
                    policy_text(spec::stream_policy(spec))
                ),
                table,
                wavelength_nm: *wl,
            })
        })
        .collect();
    let mut sources = built.into_iter().collect::<Result<Vec<_>, _>>()?;
    for src in &a.table {
        if a.solve.streams.is_some() {
            return Err("--streams applies to specs; a table is already solved".into());
        }
        let table = super::source::load_table(src)?;
        let wl = table_wavelength(&table, a.solve.wavelength_nm)?;
        let (_, label) = table_description(&table);
        let streams = table.metadata.solver.streams;
        sources.push(LobeSource {
            label: label.replace(" base", ""),
            origin: format!("table {} ({streams} streams)", file_name(src)),
            table,
            wavelength_nm: wl,
        });
    }
    for (s, l) in sources.iter_mut().zip(&a.labels) {
        s.label = l.clone();
    }

    // Samples.
    let mut in_plane = Vec::new();
    let mut maps = Vec::new();
    for s in &sources {
        in_plane.push(curves::lobe_in_plane(
            &s.table,
            s.wavelength_nm,
            a.theta_i,
            a.step_deg,
        )?);
        maps.push(curves::lobe_map(
            &s.table,
            s.wavelength_nm,
            a.theta_i,
            n_theta,
            n_phi,
        )?);
    }

    // CSVs.
    let mut csv = Csv::new(&[
        "label",
        "theta_i_deg",
        "theta_o_deg",
        "phi_o_deg",
        "theta_o_signed_deg",
        "f11_per_sr",
        "i_per_sr",
        "q_per_sr",
        "u_per_sr",
        "v_per_sr",
        "dop",
    ]);
    let mut map_csv = Csv::new(&[
        "label",
        "theta_i_deg",
        "theta_o_deg",
        "phi_o_deg",
        "f11_per_sr",
        "dop",
    ]);
    for (s, (lobe, map)) in sources.iter().zip(in_plane.iter().zip(&maps)) {
        for r in lobe {
            let mut row: Vec<Cell> = vec![
                s.label.as_str().into(),
                a.theta_i.into(),
                r.theta_o_deg.into(),
                r.phi_o_deg.into(),
                curves::signed_theta_deg(r.theta_o_deg, r.phi_o_deg).into(),
                r.f11.into(),
            ];
            row.extend(r.stokes_out.iter().map(|&x| Cell::Num(x)));
            row.push(r.dop.into());
            csv.push(row);
        }
        for r in map {
            map_csv.push(vec![
                s.label.as_str().into(),
                a.theta_i.into(),
                r.theta_o_deg.into(),
                r.phi_o_deg.into(),
                r.f11.into(),
                r.dop.into(),
            ]);
        }
    }

    // In-plane lobes.
    let signed = |r: &LobeSample| curves::signed_theta_deg(r.theta_o_deg, r.phi_o_deg);
    let f11_max = in_plane.iter().flatten().map(|r| r.f11).fold(0.0, f64::max);
    let dop_max = in_plane
        .iter()
        .flatten()
        .map(|r| 100.0 * r.dop)
        .fold(0.0, f64::max);
    let lobe_series = |value: &dyn Fn(&LobeSample) -> f64| -> Vec<Series> {
        sources
            .iter()
            .zip(&in_plane)
            .enumerate()
            .map(|(k, (s, lobe))| Series {
                label: s.label.clone(),
                points: lobe.iter().map(|r| lobe_xy(signed(r), value(r))).collect(),
                color: k,
                dash: Dash::Solid,
                markers: false,
            })
            .collect()
    };
    let wls: Vec<String> = sources
        .iter()
        .map(|s| s.wavelength_nm.map_or("-".into(), |w| format!("{w}")))
        .collect();
    let mut wls_unique = wls.clone();
    wls_unique.dedup();
    let origins = sources
        .iter()
        .map(|s| s.origin.clone())
        .collect::<Vec<_>>()
        .join(", ");
    let mirror_note = if sources
        .iter()
        .any(|s| s.table.wavelengths.iter().any(|w| w.specular.is_some()))
    {
        "; the specular reflection of a mirror base (a delta) is not drawn"
    } else {
        ""
    };
    let footnote = format!(
        "{origins}; λ = {} nm; unpolarized light incident at θ_i = {}°{mirror_note}",
        wls_unique.join("/"),
        a.theta_i
    );
    let fig = Figure {
        size: size_or(&a.out, (900, 800))?,
        rows: 2,
        cols: 1,
        panels: vec![
            Panel::Lobe(LobePanel {
                title: "BRDF f11 in the plane of incidence".into(),
                radius_label: "f11 (1/sr)".into(),
                r_max: nice_ceil(f11_max),
                series: lobe_series(&|r| r.f11),
                theta_i_deg: a.theta_i,
            }),
            Panel::Lobe(LobePanel {
                title: "Degree of polarization in the plane of incidence".into(),
                radius_label: "DOP (%)".into(),
                r_max: nice_ceil(dop_max),
                series: lobe_series(&|r| 100.0 * r.dop),
                theta_i_deg: a.theta_i,
            }),
        ],
        footnote: footnote.clone(),
    };
    let csv_path = a.out.output.with_extension("csv");
    write_csv(&csv_path, &csv)?;
    draw::write(&fig, &a.out.output)?;

    // Hemisphere maps: f11 on one scale, DOP on another, for all sources.
    let map_f11_max = maps.iter().flatten().map(|r| r.f11).fold(0.0, f64::max);
    let map_dop_max = maps
        .iter()
        .flatten()
        .map(|r| 100.0 * r.dop)
        .fold(0.0, f64::max);
    let mut panels = Vec::new();
    for (row, (name, unit)) in [("f11", "f11 (1/sr)"), ("DOP", "DOP (%)")]
        .into_iter()
        .enumerate()
    {
        for (s, map) in sources.iter().zip(&maps) {
            let values: Vec<f64> = map
                .iter()
                .map(|r| if row == 0 { r.f11 } else { 100.0 * r.dop })
                .collect();
            panels.push(Panel::Map(MapPanel {
                title: format!("{name}: {}", s.label),
                n_theta,
                n_phi,
                values,
                lo: 0.0,
                hi: nice_ceil(if row == 0 { map_f11_max } else { map_dop_max }),
                colorbar_label: unit.into(),
                theta_i_deg: a.theta_i,
            }));
        }
    }
    let map_path = sibling(
        &a.out.output,
        "-map",
        &a.out
            .output
            .extension()
            .map_or("png".into(), |e| e.to_string_lossy().into_owned()),
    );
    let map_csv_path = sibling(&a.out.output, "-map", "csv");
    let n = sources.len() as u32;
    let map_fig = Figure {
        size: (320 * n.max(2), 640),
        rows: 2,
        cols: sources.len(),
        panels,
        footnote: format!(
            "{footnote}; hemisphere seen from above, polar angle = distance from the centre (horizon = outer circle)"
        ),
    };
    write_csv(&map_csv_path, &map_csv)?;
    draw::write(&map_fig, &map_path)?;

    let summary: Vec<Value> = sources
        .iter()
        .zip(&in_plane)
        .map(|(s, lobe)| {
            let (_, fmax) = min_max_by(lobe, |r| r.f11).expect("samples");
            let (_, dmax) = min_max_by(lobe, |r| r.dop).expect("samples");
            let at = |signed_deg: f64| {
                lobe.iter()
                    .min_by(|x, y| {
                        (signed(x) - signed_deg)
                            .abs()
                            .total_cmp(&(signed(y) - signed_deg).abs())
                    })
                    .map(|r| json!({"theta_o_signed_deg": signed(r), "f11": r.f11, "dop": r.dop}))
            };
            let specular = s
                .table
                .specular(
                    &Directions {
                        theta_i_deg: a.theta_i,
                        phi_i_deg: 0.0,
                        theta_o_deg: a.theta_i,
                        phi_o_deg: 180.0,
                    },
                    s.wavelength_nm,
                )
                .ok()
                .flatten();
            json!({
                "label": s.label, "source": s.origin, "wavelength_nm": s.wavelength_nm,
                "f11_max": fmax.f11, "theta_o_signed_at_f11_max": signed(fmax),
                "dop_max": dmax.dop, "theta_o_signed_at_dop_max": signed(dmax),
                "normal": at(0.0), "mirror": at(a.theta_i), "backscatter": at(-a.theta_i),
                "specular": specular,
            })
        })
        .collect();
    Ok(json!({
        "plot": "lobe",
        "image": a.out.output, "csv": csv_path,
        "map_image": map_path, "map_csv": map_csv_path,
        "theta_i_deg": a.theta_i, "rows": csv.rows.len(), "map_rows": map_csv.rows.len(),
        "curves": summary,
    }))
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
    fn names_of_states_and_files() {
        assert_eq!(
            stokes_name([1.0, 0.0, 0.0, 1.0]),
            "[1, 0, 0, 1] right circular"
        );
        assert_eq!(stokes_name([1.0, 0.5, 0.0, 0.0]), "[1, 0.5, 0, 0]");
        assert_eq!(
            sibling(Path::new("out/fig13.png"), "-map", "csv"),
            PathBuf::from("out/fig13-map.csv")
        );
        assert_eq!(percent_range([3.0, 47.0].into_iter()), (0.0, 50.0));
        assert_eq!(percent_range([-3.0, 9.0].into_iter()), (-5.0, 10.0));
        assert_eq!(percent_range([99.9].into_iter()), (0.0, 100.0));
    }
}
