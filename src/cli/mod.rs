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
pub mod report;
pub mod scene;
pub mod serve;
pub mod solve;
pub mod source;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::any::TypeId;

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
    /// Reports that recompute published experiments (`report experiment`: the
    /// seed's Table 1).
    #[command(subcommand)]
    Report(report::ReportCommand),
    /// Render scenes: what a scene needs of its materials (`scene plan`).
    #[command(subcommand)]
    Scene(scene::SceneCommand),
    /// Run the HTTP service (docs/service.md).
    Serve(serve::ServeArgs),
    /// Benchmarks (timings go to docs/performance.md).
    #[command(subcommand)]
    Bench(bench::BenchCommand),
}

/// The command line: the derived parser, with every numeric option taking a
/// value that starts with `-`. clap's own negative-number test knows no
/// exponent (`--phi-i -1.5e-05` would be read as an unknown flag `-1`); with
/// hyphen values allowed every number a user can print reaches the number
/// parser, and `-inf` or `-1e400` reach the range checks and their errors.
/// A forgotten value (`--phi-i --theta-o 30`) is then an invalid number
/// `--theta-o` for `--phi-i`, still a clear refusal.
pub fn command() -> clap::Command {
    numeric_options_take_hyphen_values(Cli::command())
}

fn numeric_options_take_hyphen_values(cmd: clap::Command) -> clap::Command {
    cmd.mut_args(|arg| {
        if is_numeric_option(&arg) {
            arg.allow_hyphen_values(true)
        } else {
            arg
        }
    })
    .mut_subcommands(numeric_options_take_hyphen_values)
}

/// An option (not a positional argument) whose values parse as a number.
fn is_numeric_option(arg: &clap::Arg) -> bool {
    let numeric = [
        TypeId::of::<f64>(),
        TypeId::of::<f32>(),
        TypeId::of::<i64>(),
        TypeId::of::<i32>(),
        TypeId::of::<isize>(),
        TypeId::of::<u64>(),
        TypeId::of::<u32>(),
        TypeId::of::<usize>(),
    ];
    let takes_values = arg.get_num_args().is_none_or(|n| n.takes_values());
    let value_type = arg.get_value_parser().type_id();
    (arg.get_long().is_some() || arg.get_short().is_some())
        && takes_values
        && numeric.iter().any(|t| value_type == *t)
}

/// Parse arguments, run, and return the process exit code.
pub fn main() -> i32 {
    let cli = Cli::from_arg_matches(&command().get_matches()).unwrap_or_else(|e| e.exit());
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
        Command::Report(c) => return report::main(&c),
    };
    finish(result.map(|v| serde_json::to_string_pretty(&v).expect("JSON")))
}

/// Print a command's output (or its error, one line on stderr) and return
/// the exit code: 0, 1 when stdout cannot be written, 2 for the error.
pub(crate) fn finish(result: Result<String, String>) -> i32 {
    match result {
        Ok(text) => {
            // A closed pipe (`polbrdf … | head`) is not an error of ours.
            use std::io::Write;
            match writeln!(std::io::stdout().lock(), "{}", text.trim_end()) {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Every numeric option of every subcommand, as `path --long`.
    fn numeric_options(cmd: &clap::Command, path: &str, out: &mut Vec<(String, bool)>) {
        for arg in cmd.get_arguments().filter(|a| is_numeric_option(a)) {
            let name = arg.get_long().unwrap_or_default();
            out.push((format!("{path} --{name}"), arg.is_allow_hyphen_values_set()));
        }
        for sub in cmd.get_subcommands() {
            numeric_options(sub, &format!("{path} {}", sub.get_name()), out);
        }
    }

    #[test]
    fn every_numeric_option_takes_values_starting_with_a_hyphen() {
        let mut found = Vec::new();
        numeric_options(&command(), "polbrdf", &mut found);
        for wanted in [
            "polbrdf eval --phi-i",
            "polbrdf mie --wavelength-nm",
            "polbrdf solve --max-streams",
        ] {
            assert!(
                found.iter().any(|(n, _)| n == wanted),
                "{wanted} not seen as numeric"
            );
        }
        let refused: Vec<&String> = found.iter().filter(|(_, h)| !h).map(|(n, _)| n).collect();
        assert!(refused.is_empty(), "{refused:?}");
    }

    /// Options whose value is a list of numbers in a string of our own
    /// syntax (parsed by `plot::parse_*`) take values starting with `-` too,
    /// so that `--taus -1` reaches the range check and its message.
    #[test]
    fn number_list_options_take_values_starting_with_a_hyphen() {
        let cmd = command();
        for (sub, option) in [
            ("dop-vs-mu", "taus"),
            ("dop-vs-tau", "taus"),
            ("dop-vs-tau", "tau-range"),
            ("scalar-error", "taus"),
            ("scalar-error", "tau-range"),
            ("scalar-error", "pairs"),
        ] {
            let plot = cmd.find_subcommand("plot").expect("plot");
            let arg = plot
                .find_subcommand(sub)
                .and_then(|c| c.get_arguments().find(|a| a.get_long() == Some(option)))
                .unwrap_or_else(|| panic!("plot {sub} --{option}"));
            assert!(arg.is_allow_hyphen_values_set(), "plot {sub} --{option}");
        }
    }

    #[test]
    fn negative_numbers_in_every_notation_parse() {
        for (value, want) in [
            ("-1.5e-05", -1.5e-5),
            ("-2E+1", -20.0),
            ("-45", -45.0),
            ("-.5", -0.5),
            ("-0", 0.0),
        ] {
            let argv = [
                "polbrdf",
                "eval",
                "t.pbrdf",
                "--theta-i",
                "30",
                "--phi-i",
                value,
                "--theta-o",
                "10",
                "--phi-o",
                value,
            ];
            let m = command().try_get_matches_from(argv).expect(value);
            let cli = Cli::from_arg_matches(&m).unwrap();
            let Command::Eval(a) = cli.command else {
                panic!("not eval")
            };
            assert_eq!((a.phi_i, a.phi_o), (want, want), "{value}");
        }
        // A forgotten value is still refused, naming the option.
        let argv = [
            "polbrdf",
            "eval",
            "t",
            "--theta-i",
            "30",
            "--phi-i",
            "--theta-o",
            "1",
        ];
        let err = command()
            .try_get_matches_from(argv)
            .unwrap_err()
            .to_string();
        assert!(err.contains("--phi-i"), "{err}");
    }
}
