//! `polbrdf eval TABLE --theta-i DEG --phi-i DEG --theta-o DEG --phi-o DEG
//! [--wavelength-nm NM] [--cache-dir DIR]`: one Mueller BRDF from a table
//! (docs/table-format.md).

use crate::brdf::export::{FRAMES, mueller_json};
use crate::brdf::table::{Directions, MIRROR_TOLERANCE_RAD};
use clap::Args;
use serde_json::{Value, json};

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// A table written by `polbrdf solve SPEC --table OUT`, or a service result URL (`http://HOST:PORT/v1/brdfs/ID`).
    pub table: String,
    /// Incident polar angle (deg, [0, 90]; graphics convention).
    #[arg(long)]
    pub theta_i: f64,
    /// Incident azimuth (deg, [-360, 360]).
    #[arg(long)]
    pub phi_i: f64,
    /// Outgoing polar angle (deg, [0, 90]).
    #[arg(long)]
    pub theta_o: f64,
    /// Outgoing azimuth (deg, [-360, 360]).
    #[arg(long)]
    pub phi_o: f64,
    /// Vacuum wavelength (nm) inside the table's range (linear between
    /// wavelengths); may be omitted for a one-wavelength table.
    #[arg(long)]
    pub wavelength_nm: Option<f64>,
    #[command(flatten)]
    pub cache: super::source::CacheArgs,
}

/// Run `eval`.
pub fn run(a: &EvalArgs) -> Result<Value, String> {
    let cache = a.cache.resolve()?;
    let table = super::source::load_table_with(&a.table, cache.as_ref())?;
    let d = Directions {
        theta_i_deg: a.theta_i,
        phi_i_deg: a.phi_i,
        theta_o_deg: a.theta_o,
        phi_o_deg: a.phi_o,
    };
    let m = table.eval(&d, a.wavelength_nm).map_err(|e| e.to_string())?;
    let s = table
        .specular(&d, a.wavelength_nm)
        .map_err(|e| e.to_string())?;
    let wl = match a.wavelength_nm {
        Some(w) => Some(w),
        None => table.wavelengths[0].wavelength_nm,
    };
    Ok(json!({
        "wavelength_nm": wl,
        "theta_i_deg": a.theta_i, "phi_i_deg": a.phi_i,
        "theta_o_deg": a.theta_o, "phi_o_deg": a.phi_o,
        "mueller": mueller_json(&table, &m),
        "units": "1/sr",
        "frames": FRAMES,
        "specular": s.map(|s| mueller_json(&table, &s)),
        "specular_note": format!(
            "a mirror base or a smooth top_interface only, and only when w_o is within {MIRROR_TOLERANCE_RAD:e} rad of the mirror direction (theta_i, phi_i + 180): S with integral of L_out over the delta = S F_beam (docs/conventions.md §6, §8)"
        ),
    }))
}
