//! `polbrdf export TABLE --format {npy,json,csv,mitsuba} -o FILE` and the
//! table writer behind `polbrdf solve SPEC --table OUT`
//! (docs/table-format.md, docs/mitsuba.md).

use crate::brdf::export::{self, DenseGrid, NpyType};
use crate::brdf::format::{self, DataType};
use crate::brdf::mitsuba::{self, BelowHorizon, MitsubaOptions};
use crate::brdf::table::BuildOptions;
use crate::brdf::{Directions, Table};
use crate::material;
use clap::{Args, ValueEnum};
use serde::Deserialize;
use serde_json::{Value, json};

/// Export formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ExportFormat {
    /// Dense (W, Ti, To, P, 4, 4) array on the 51 x 51 x 61 grid of Collin et al.,
    /// "Computation of Polarized Subsurface BRDF for Rendering" (GI 2014).
    Npy,
    /// Mueller matrices at the direction pairs of --points.
    Json,
    /// The plane of incidence at one incident angle (--theta-i-deg).
    Csv,
    /// Mitsuba 3 `measured_polarized` tensor_file (five wavelengths; docs/mitsuba.md).
    Mitsuba,
}

/// What the Mitsuba export stores at nodes below the horizon.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BelowHorizonArg {
    /// The BRDF at the node's directions moved up to the horizon (continuous extension).
    Extend,
    /// Zero.
    Zero,
}

/// Element type of the .npy export.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Dtype {
    /// float32 (`<f4`).
    F32,
    /// float64 (`<f8`).
    F64,
}

#[derive(Debug, Args)]
pub struct ExportArgs {
    /// A table written by `polbrdf solve SPEC --table OUT`, or a service result URL (`http://HOST:PORT/v1/brdfs/ID`).
    pub table: String,
    /// Output format.
    #[arg(long, value_enum)]
    pub format: ExportFormat,
    /// Output file.
    #[arg(short = 'o', long = "output")]
    pub output: String,
    /// Direction pairs for --format json: {"points": [{"theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg"}]}.
    #[arg(long)]
    pub points: Option<String>,
    /// Incident polar angle (deg) of the --format csv slice (plane of incidence, phi_i = 0).
    #[arg(long)]
    pub theta_i_deg: Option<f64>,
    /// Element type of --format npy.
    #[arg(long, value_enum, default_value = "f32")]
    pub dtype: Dtype,
    /// Only this wavelength (nm) for --format json (default: every wavelength of the table).
    #[arg(long)]
    pub wavelength_nm: Option<f64>,
    /// --format mitsuba: nodes in phi_d over [-180, 180] deg (default 73: 5 deg steps).
    #[arg(long)]
    pub phi_d_nodes: Option<usize>,
    /// --format mitsuba: nodes in theta_d over [0, 90] deg (default 46: 2 deg steps).
    #[arg(long)]
    pub theta_d_nodes: Option<usize>,
    /// --format mitsuba: nodes in theta_h over [0, 90] deg (default 46: 2 deg steps).
    #[arg(long)]
    pub theta_h_nodes: Option<usize>,
    /// --format mitsuba: interpolate the table linearly onto five evenly spaced whole-nm wavelengths in its range (the plugin reads exactly five).
    #[arg(long)]
    pub resample_wavelengths: bool,
    /// --format mitsuba: what nodes below the horizon hold (default extend).
    #[arg(long, value_enum)]
    pub below_horizon: Option<BelowHorizonArg>,
    #[command(flatten)]
    pub cache: super::source::CacheArgs,
}

impl ExportArgs {
    fn has_mitsuba_options(&self) -> bool {
        self.phi_d_nodes.is_some()
            || self.theta_d_nodes.is_some()
            || self.theta_h_nodes.is_some()
            || self.resample_wavelengths
            || self.below_horizon.is_some()
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PointsFile {
    points: Vec<Directions>,
}

fn write(path: &str, bytes: &[u8]) -> Result<(), String> {
    std::fs::write(path, bytes).map_err(|e| format!("{path}: {e}"))
}

fn read_points(path: &str) -> Result<Vec<Directions>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let p: PointsFile = material::from_json_str(&text).map_err(|e| format!("{path}: {e}"))?;
    for (i, d) in p.points.iter().enumerate() {
        d.validate()
            .map_err(|e| format!("{path}: points[{i}].{e}"))?;
    }
    Ok(p.points)
}

/// Run `export`; the summary JSON is printed by the caller.
pub fn run(a: &ExportArgs) -> Result<Value, String> {
    if a.format != ExportFormat::Mitsuba && a.has_mitsuba_options() {
        return Err("--phi-d-nodes, --theta-d-nodes, --theta-h-nodes, --resample-wavelengths and --below-horizon apply to --format mitsuba only".into());
    }
    let cache = a.cache.resolve()?;
    let table = super::source::load_table_with(&a.table, cache.as_ref())?;
    match a.format {
        ExportFormat::Npy => {
            if a.points.is_some() || a.theta_i_deg.is_some() || a.wavelength_nm.is_some() {
                return Err("--format npy exports the whole table: --points, --theta-i-deg and --wavelength-nm do not apply".into());
            }
            let grid = DenseGrid::default();
            let d = export::dense(&table, &grid).map_err(|e| e.to_string())?;
            let ty = match a.dtype {
                Dtype::F32 => NpyType::F32,
                Dtype::F64 => NpyType::F64,
            };
            let bytes = export::npy_bytes(&d.shape(), &d.data, ty).map_err(|e| e.to_string())?;
            write(&a.output, &bytes)?;
            Ok(npy_summary(&a.output, &d, &grid, ty, &bytes))
        }
        ExportFormat::Json => {
            let path = a
                .points
                .as_deref()
                .ok_or("--format json needs --points POINTS.json")?;
            let points = read_points(path)?;
            let v =
                export::points_json(&table, &points, a.wavelength_nm).map_err(|e| e.to_string())?;
            let text = serde_json::to_string_pretty(&v).expect("JSON");
            write(&a.output, text.as_bytes())?;
            Ok(json!({"file": a.output, "format": "json", "points": points.len()}))
        }
        ExportFormat::Csv => {
            let t = a
                .theta_i_deg
                .ok_or("--format csv needs --theta-i-deg DEG")?;
            let text = export::csv_slice(&table, t).map_err(|e| e.to_string())?;
            write(&a.output, text.as_bytes())?;
            Ok(json!({
                "file": a.output, "format": "csv", "rows": text.lines().count() - 1,
                "slice": "plane of incidence, phi_i = 0; phi_o = 0 (theta_o_signed < 0) and 180 (> 0)",
            }))
        }
        ExportFormat::Mitsuba => export_mitsuba(a, &table),
    }
}

/// The summary `--format npy` prints: what was written and the axes as
/// counts and ranges (their values follow from docs/table-format.md's
/// regular grid; the file holds only the array).
fn npy_summary(
    output: &str,
    d: &export::Dense,
    grid: &DenseGrid,
    ty: NpyType,
    bytes: &[u8],
) -> Value {
    let axis = |v: &[f64], rule: &str| json!({"count": v.len(), "first": v.first(), "last": v.last(), "spacing": rule});
    let wavelengths: Vec<f64> = d.wavelength_nm.iter().flatten().copied().collect();
    json!({
        "file": output, "format": "npy", "shape": d.shape(),
        "dtype": match ty { NpyType::F32 => "<f4", NpyType::F64 => "<f8" },
        "bytes": bytes.len(),
        "sha256_of_file": crate::digest::sha256_hex(bytes),
        "axes": {
            "wavelength_nm": if wavelengths.is_empty() {
                json!({"count": d.wavelength_nm.len(), "values": "none: a wavelength-free table"})
            } else {
                json!({"count": wavelengths.len(), "first": wavelengths.first(), "last": wavelengths.last(), "spacing": "the table's wavelengths"})
            },
            "theta_i_deg": axis(&grid.theta_i_deg, "midpoints of equal steps of 0..90"),
            "theta_o_deg": axis(&grid.theta_o_deg, "midpoints of equal steps of 0..90"),
            "phi_deg": axis(&grid.phi_deg, "equal steps, both ends included"),
            "phi_note": "phi = phi_o - phi_i (graphics convention, phi_i = 0; 180 = mirror side)",
        },
        "frames": export::FRAMES, "units": "1/sr",
    })
}

/// The CLI's way to a finer grid, for [`mitsuba::export_warnings`].
fn finer_grid_flags() -> String {
    let n = mitsuba::FINER_THETA_NODES;
    format!("--theta-d-nodes {n} --theta-h-nodes {n} (1 deg steps; 4 times the file size)")
}

fn export_mitsuba(a: &ExportArgs, table: &Table) -> Result<Value, String> {
    if a.points.is_some() || a.theta_i_deg.is_some() || a.wavelength_nm.is_some() {
        return Err("--format mitsuba exports the whole table: --points, --theta-i-deg and --wavelength-nm do not apply".into());
    }
    let d = MitsubaOptions::default();
    let opts = MitsubaOptions {
        phi_d: a.phi_d_nodes.unwrap_or(d.phi_d),
        theta_d: a.theta_d_nodes.unwrap_or(d.theta_d),
        theta_h: a.theta_h_nodes.unwrap_or(d.theta_h),
        resample_wavelengths: a.resample_wavelengths,
        below_horizon: match a.below_horizon {
            None | Some(BelowHorizonArg::Extend) => BelowHorizon::Extend,
            Some(BelowHorizonArg::Zero) => BelowHorizon::Zero,
        },
    };
    let mt = mitsuba::build(table, &opts).map_err(|e| e.to_string())?;
    let check = mitsuba::resampling_error(table, &mt, mitsuba::CHECK_PAIRS, mitsuba::CHECK_SEED)
        .map_err(|e| e.to_string())?;
    for w in mitsuba::export_warnings(table, &check, &finer_grid_flags()) {
        eprintln!("polbrdf: warning: {w}");
    }
    let bytes = mt.to_bytes();
    write(&a.output, &bytes)?;
    let meta: Value = serde_json::from_str(&mt.metadata).expect("metadata JSON");
    Ok(json!({
        "file": a.output, "format": "mitsuba", "bytes": bytes.len(),
        "plugin": "measured_polarized (Mitsuba 3, *_spectral_polarized variants)",
        "shape": mt.shape(),
        "axes": ["phi_d", "theta_d", "theta_h", "wavelength", "row", "column"],
        "wavelengths_nm": mt.wavelengths_nm,
        "wavelength_policy": meta["wavelength_policy"],
        "grid": meta["grid"],
        "below_horizon": opts.below_horizon.name(),
        "frames": meta["frames"],
        "units": meta["units"],
        "specular_delta": meta["specular_delta"],
        "resampling_check": {
            "what": "the plugin's interpolation of this file against the table, on f cos(theta_i), at seeded random direction pairs (uniform in solid angle) at the five wavelengths",
            "result": check,
        },
    }))
}

/// `polbrdf solve SPEC --table OUT`: build the table on the default polar
/// grid (one solve per wavelength, [`Table::from_spec_with`] with the
/// caller's stream cap and progress sink) and write it (f64 coefficients).
/// Returns the file's summary and the table (its metadata has the
/// per-wavelength streams, orders, timings and error estimates).
pub fn write_table(
    spec: &material::Spec,
    spec_path: &str,
    out: &str,
    options: &BuildOptions,
) -> Result<(Value, Table), String> {
    let table = Table::from_spec_needs(spec, options).map_err(|e| format!("{spec_path}: {e}"))?;
    format::write_file(&table, out, DataType::F64).map_err(|e| e.to_string())?;
    let bytes = std::fs::read(out).map_err(|e| format!("{out}: {e}"))?;
    let summary = json!({
        "file": out,
        "bytes": bytes.len(),
        "sha256_of_file": crate::digest::sha256_hex(&bytes),
        "polar_nodes": table.grid.len(),
        "wavelengths": table.metadata.wavelengths,
    });
    Ok((summary, table))
}
