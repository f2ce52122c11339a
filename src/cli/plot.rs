//! `polbrdf plot {dop-vs-mu,dop-vs-tau,scalar-error,lobe} ...`.

use clap::Args;
use serde_json::Value;

#[derive(Debug, Args)]
pub struct PlotArgs {}

/// Run `plot`.
pub fn run(_a: &PlotArgs) -> Result<Value, String> {
    Err("plot: not implemented yet".into())
}
