//! Command-line front door (`polbrdf ...`). Thin: parses arguments, calls the
//! library, prints JSON; errors are one line on stderr and a non-zero exit.

pub mod bench;
pub mod convergence;
pub mod eval;
pub mod export;
pub mod mie;
pub mod plot;
pub mod render;
pub mod serve;
pub mod solve;
pub mod source;

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
    /// Mie theory for one particle population: efficiencies, scattering matrix, expansion.
    Mie(mie::MieArgs),
    /// Solve a material spec: BRDF at direction pairs, internal field.
    Solve {
        /// The material spec (JSON, docs/spec.md).
        spec: String,
        /// Direction pairs: {"points": [{"theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg"}]}.
        #[arg(long)]
        points: Option<String>,
        /// Internal field request: {"mu0", "phi0_deg", "stokes", "tau", "mu", "phi_deg"}.
        #[arg(long)]
        field: Option<String>,
        /// Also write the BRDF table (binary, docs/table-format.md) to this file.
        #[arg(long)]
        table: Option<String>,
    },
    /// Evaluate a BRDF table at one direction pair.
    Eval(eval::EvalArgs),
    /// Export a BRDF table: dense .npy, JSON point set or CSV slice.
    Export(export::ExportArgs),
    /// Error against run time: solve at increasing streams, compare with a reference.
    Convergence(convergence::ConvergenceArgs),
    /// Plots of the seed's figures (SVG/PNG plus the plotted numbers as CSV).
    #[command(subcommand)]
    Plot(plot::PlotCommand),
    /// Polarized preview renderer (spheres with BRDF tables on a floor).
    Render(render::RenderArgs),
    /// Run the HTTP service (docs/service.md).
    Serve(serve::ServeArgs),
    /// Benchmarks (timings go to docs/performance.md).
    #[command(subcommand)]
    Bench(bench::BenchCommand),
}

/// Parse arguments, run, and return the process exit code.
pub fn main() -> i32 {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Mie(args) => mie::run(&args),
        Command::Solve {
            spec,
            points,
            field,
            table,
        } => solve::run(&spec, points.as_deref(), field.as_deref()).and_then(|mut v| {
            if let Some(out) = table {
                v["table"] = export::write_table(&spec, &out)?;
            }
            Ok(v)
        }),
        Command::Eval(a) => eval::run(&a),
        Command::Export(a) => export::run(&a),
        Command::Convergence(a) => convergence::run(&a),
        Command::Bench(b) => bench::run(&b),
        Command::Plot(a) => plot::run(&a),
        Command::Render(a) => render::run(&a),
        Command::Serve(a) => return serve::main(&a),
    };
    match result {
        Ok(v) => {
            // A closed pipe (`polbrdf … | head`) is not an error of ours.
            use std::io::Write;
            let text = serde_json::to_string_pretty(&v).expect("JSON");
            match writeln!(std::io::stdout().lock(), "{text}") {
                Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
                    eprintln!("polbrdf: writing the output: {e}");
                    1
                }
                _ => 0,
            }
        }
        Err(e) => {
            eprintln!("polbrdf: {e}");
            2
        }
    }
}
