//! `polbrdf plot spectrum`: the arguments and the run of the spectrum
//! figure (`plot::figures::spectrum`), with the parent module's helpers.

use super::{
    OutputArgs, SolveArgs, check_phi, labelled, load_specs, report, size, solve_options, write_plot,
};
use crate::plot::figures::{self, SpectrumOptions};
use clap::Args;
use serde_json::Value;

#[derive(Debug, Args)]
pub struct SpectrumArgs {
    /// Material specs (docs/spec.md) with `wavelengths_nm`, one colour each.
    #[arg(required = true)]
    pub specs: Vec<String>,
    /// Legend labels, one per spec, comma separated (default: material on base).
    #[arg(long, value_delimiter = ',')]
    pub labels: Vec<String>,
    /// Incident polar angle (deg, azimuth 0).
    #[arg(long, default_value_t = 45.0)]
    pub theta_i: f64,
    /// Viewing polar angle (deg) of π f11 and the DOP (0: the 45°/0° geometry).
    #[arg(long, default_value_t = 0.0)]
    pub theta_o: f64,
    /// Viewing azimuth (deg, φ_i = 0; 180 = mirror side).
    #[arg(long, default_value_t = 180.0)]
    pub phi_o_deg: f64,
    #[command(flatten)]
    pub solve: SolveArgs,
    #[command(flatten)]
    pub out: OutputArgs,
}

/// Run `polbrdf plot spectrum`: check the options, read every spec, plot.
pub(super) fn spectrum(a: &SpectrumArgs) -> Result<Value, String> {
    let polar = |flag: &str, t: f64| {
        if t.is_finite() && (0.0..90.0).contains(&t) {
            Ok(t.to_radians().cos())
        } else {
            Err(format!("{flag} {t} is outside [0, 90)"))
        }
    };
    let mu0 = polar("--theta-i", a.theta_i)?;
    let mu = polar("--theta-o", a.theta_o)?;
    let phi_o_deg = check_phi(a.phi_o_deg)?;
    if a.solve.wavelength_nm.is_some() {
        return Err(
            "--wavelength-nm does not apply to spectrum: it plots every wavelength of each spec"
                .into(),
        );
    }
    let o = SpectrumOptions {
        mu0,
        mu,
        phi_o_deg,
        solve: solve_options(&a.solve)?,
        size: size(&a.out)?,
    };
    let specs = load_specs(&a.specs, &a.labels, &a.solve)?;
    let plot =
        figures::spectrum(&labelled(&a.specs, &specs, &a.labels), &o).map_err(|e| e.to_string())?;
    let csv = write_plot(&plot.figure, &plot.csv, &a.out.output)?;
    report(
        "spectrum",
        &plot.summary,
        &[("image", &a.out.output), ("csv", &csv)],
    )
}
