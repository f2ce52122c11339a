//! `polbrdf mie` (filled in with the Mie module).
use clap::Args;
use serde_json::Value;

#[derive(Debug, Args)]
pub struct MieArgs {}

pub fn run(_a: &MieArgs) -> Result<Value, String> {
    Err("not yet".into())
}
