//! Command-line front door (`polbrdf ...`).

use clap::{Parser, Subcommand};

/// polbrdf: polarized BRDFs of paints, coatings and powders.
#[derive(Debug, Parser)]
#[command(name = "polbrdf", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print the crate version.
    Version,
}

/// Parse arguments, run, and return the process exit code.
pub fn main() -> i32 {
    let cli = Cli::parse();
    match cli.command {
        Command::Version => {
            println!("{}", env!("CARGO_PKG_VERSION"));
            0
        }
    }
}
