//! Command-line front door (`polbrdf ...`). Thin: parses arguments, calls the
//! library, prints JSON; errors are one line on stderr and a non-zero exit.

pub mod bench;
pub mod convergence;
pub mod eval;
pub mod export;
pub mod fetch;
pub mod mie;
pub mod plot;
pub mod progress;
pub mod render;
pub mod scene;
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
    /// Solve a material spec: BRDF at direction pairs, internal field, BRDF table.
    ///
    /// Prints {"results": [{"wavelength_nm", "computed", ...}]}: per wavelength,
    /// "computed" lists what was computed ("points", "field", "table") and only
    /// those parts are present: "points" and "specular" (with --points), "field"
    /// (with --field), "solver": {"streams", "polarized", "fourier_orders",
    /// "wall_time_ms", "error_estimate"} for the direct solve (with --points or
    /// --field; "error_estimate" only when the direction pairs were solved), and
    /// "table": {"streams", "fourier_orders", "wall_time_ms", "error_estimate"} for
    /// the table build at that wavelength (with --table, which also adds the
    /// top-level "table": {"file", "bytes", "sha256_of_file", "polar_nodes",
    /// "wavelengths"}). Nothing that was not computed appears, not even as an
    /// empty list, 0 or null; without --points, --field or --table the spec is
    /// only checked ("computed": []).
    ///
    /// With stderr a terminal, a progress bar while solving and a one-line
    /// summary at the end go to stderr; otherwise stderr stays empty on success.
    Solve(solve::SolveArgs),
    /// Evaluate a BRDF table at one direction pair.
    Eval(eval::EvalArgs),
    /// Export a BRDF table: dense .npy, JSON point set or CSV slice.
    Export(export::ExportArgs),
    /// Copy a service result's table into a render node's cache directory (or find it there).
    ///
    /// Verified against the service's digest, written atomically, one download per node
    /// however many processes ask at once; works offline once cached (docs/deploy.md,
    /// "Render nodes"). `eval`, `export` and `render` use the same cache with --cache-dir.
    Fetch(fetch::FetchArgs),
    /// Error against run time: solve at increasing streams, compare with a reference.
    Convergence(convergence::ConvergenceArgs),
    /// Plots of the figures of Collin et al., "Computation of Polarized Subsurface
    /// BRDF for Rendering" (Graphics Interface 2014): SVG/PNG plus the plotted
    /// numbers as CSV.
    #[command(subcommand)]
    Plot(plot::PlotCommand),
    /// Polarized preview renderer (spheres with BRDF tables or material specs on a floor).
    Render(render::RenderArgs),
    /// Render scenes: what a scene needs of its materials (`scene plan`).
    #[command(subcommand)]
    Scene(scene::SceneCommand),
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
        Command::Solve(a) => solve::run(&a),
        Command::Eval(a) => eval::run(&a),
        Command::Export(a) => export::run(&a),
        Command::Fetch(a) => fetch::run(&a),
        Command::Convergence(a) => convergence::run(&a),
        Command::Bench(b) => bench::run(&b),
        Command::Plot(a) => plot::run(&a),
        Command::Render(a) => render::run(&a),
        Command::Scene(c) => scene::run(&c),
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
