//! graybox-lab: the benchmarks that print the issues' figures (`bench`) and the paper's
//! experiments (`experiment`), on the graybox library; the service binary does not carry
//! them (ARCHITECTURE.md).

mod bench;
mod experiment;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// The service's allocator, so that what a benchmark measures is what `graybox` runs.
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser, Debug)]
#[command(
    name = "graybox-lab",
    version,
    about = "graybox's benchmarks and the paper's experiments"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Benchmarks (figures for the issues' targets).
    #[command(subcommand)]
    Bench(bench::BenchCommand),
    /// The paper's experiments, each writing tables, plots and run.json to --out (resumable).
    #[command(subcommand)]
    Experiment(experiment::ExperimentCommand),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    graybox::cli::init_tracing();
    graybox::cli::exit_code(
        match cli.command {
            Command::Bench(b) => bench::run(b),
            Command::Experiment(e) => experiment::run(e),
        },
        false,
    )
}
