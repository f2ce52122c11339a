//! `polbrdf render SCENE.json ...`: the polarized preview renderer.

use clap::Args;
use serde_json::Value;

#[derive(Debug, Args)]
pub struct RenderArgs {}

/// Run `render`.
pub fn run(_a: &RenderArgs) -> Result<Value, String> {
    Err("render: not implemented yet".into())
}
