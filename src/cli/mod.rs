//! The `graybox` command line: simulate datasets, train, evaluate and inspect models, and run
//! benchmarks. Results go to stdout (JSON), progress and logs to stderr.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod energy;
mod eval;
mod health;
mod import;
mod inverse;
mod model;
mod plan;
mod serve;
mod simulate;
mod train;
mod worker;

pub use eval::{EvalArgs, InspectArgs};
pub use health::HealthArgs;
pub use model::ModelArgs;
pub use plan::PlanArgs;
pub use simulate::SimulateArgs;
pub use train::TrainArgs;
pub use worker::WorkerArgs;

use crate::error::{Error, Result};
use crate::physics::templates::Template;
use crate::physics::urdf::UrdfTemplate;

/// A `--template` argument: a built-in template's name, a template document's JSON file (a
/// path ending in .json) or a URDF file (.urdf, every default); a bad document's error names
/// the file, the field and the offset.
pub fn template_arg(arg: &str) -> Result<Template> {
    let urdf = arg.ends_with(".urdf");
    if !arg.ends_with(".json") && !urdf {
        // No built-in's name has a dot or a slash: this was meant as a file.
        if arg.contains(['.', '/']) {
            return Err(Error::invalid(
                "template",
                format!(
                    "'{arg}' is not a built-in template ({}), and a template file is \
                     recognised by its extension: .json (a template document) or .urdf (a \
                     URDF robot)",
                    Template::ALL.map(|t| t.name().to_string()).join(", ")
                ),
            ));
        }
        return Template::parse(arg);
    }
    let text = std::fs::read_to_string(arg)
        .map_err(|e| Error::invalid("template", format!("cannot read {arg}: {e}")))?;
    let t = if urdf {
        UrdfTemplate::from_urdf(&text).map(|u| Template::Urdf(std::sync::Arc::new(u)))
    } else {
        Template::from_json(&text)
    };
    t.map_err(|e| match e {
        Error::Unprocessable { field, message } => Error::Unprocessable {
            field: format!("{arg}: {field}"),
            message,
        },
        other => other,
    })
}

#[derive(Parser, Debug)]
#[command(
    name = "graybox",
    version,
    about = "Structured Lagrangian dynamics models: learn, evaluate, serve"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Sample a transition dataset from a white-box template (the paper's sampling).
    Simulate(SimulateArgs),
    /// A robot's log (CSV or Parquet: time, positions, optionally velocities, inputs) as a
    /// dataset of trajectories on the samples' own times (or an even grid), velocities
    /// estimated where the log has none.
    Import(import::ImportArgs),
    /// Train a model on a dataset and write the best-validation model file.
    Train(TrainArgs),
    /// The training loss of a model file on a dataset.
    Eval(EvalArgs),
    /// Print a model file's spec, dimensions, scalings and physical parameters.
    Inspect(InspectArgs),
    /// A model file's energies at a dataset's states (T, V, E, the power of F and the split
    /// of its dynamics), one JSON line each; with --report, its energy drift and passivity.
    Energy(energy::EnergyArgs),
    /// The generalized force τ = M q̈ + c + ∇V − F(q, q̇, 0) that produces given
    /// accelerations at given states (feed-forward torque), with its terms, one JSON line each.
    InverseDynamics(inverse::InverseArgs),
    /// Write the white-box model of a template with given physical values (no training).
    Model(ModelArgs),
    /// Write a URDF model's identified robot: its URDF with the learned inertial and joint
    /// values.
    ExportUrdf(model::ExportUrdfArgs),
    /// Plan a trajectory to a goal on a model file (iLQR with input bounds) and its gains.
    Plan(PlanArgs),
    /// Run the service: REST, gRPC and training workers over one database (with 0 workers, an
    /// API node that trains nothing).
    // `graybox serve`'s flags are the service's settings.
    Serve(crate::app::Settings),
    /// Run training workers alone (no API), on the database the API nodes use.
    Worker(WorkerArgs),
    /// Exit 0 if the service on this machine is ready (for container health checks).
    Health(HealthArgs),
}

/// Writes one line of a command's results to stdout. A reader that stopped reading (`graybox
/// simulate … | head`) ends the command quietly with 0, as it ends any well-behaved filter:
/// it has what it wanted, and every command writes its files before its summary line. Rust's
/// `println!` panicked there, with a backtrace and exit 101.
pub fn say(line: impl std::fmt::Display) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{line}").and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => std::process::exit(0),
        done => done.map_err(Error::from),
    }
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    init_tracing();
    // A container health check reads 1 as unhealthy (2 is reserved there).
    let health = matches!(cli.command, Command::Health(_));
    exit_code(run(cli.command), health)
}

/// Logs to stderr, filtered by RUST_LOG (default: warnings, and graybox's info).
pub fn init_tracing() {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        // Colour only on a terminal: logs redirected to files stay plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "warn,graybox=info".into()),
        )
        .init();
}

/// A command's exit status: 0, 2 for what the input got wrong, 1 for the rest (`health`:
/// 1 for any error).
pub fn exit_code(result: Result<()>, health: bool) -> ExitCode {
    let Err(e) = result else {
        return ExitCode::SUCCESS;
    };
    eprintln!("error: {e}");
    if health {
        return ExitCode::FAILURE;
    }
    ExitCode::from(match e {
        Error::Invalid { .. }
        | Error::Unprocessable { .. }
        | Error::NotFound(_)
        | Error::Conflict(_)
        | Error::FailedPrecondition(_)
        | Error::ResourceExhausted(_)
        | Error::Corrupt { .. } => 2,
        Error::Training(_)
        | Error::Cancelled
        | Error::Io(_)
        | Error::Storage(_)
        | Error::Busy(_)
        | Error::DeadlineExceeded(_)
        | Error::Internal(_) => 1,
    })
}

pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Simulate(a) => simulate::simulate(a),
        Command::Import(a) => import::import(a),
        Command::Train(a) => train::train(a),
        Command::Eval(a) => eval::eval(a),
        Command::Inspect(a) => eval::inspect(a),
        Command::Energy(a) => energy::energy(a),
        Command::InverseDynamics(a) => inverse::inverse(a),
        Command::Model(a) => model::model(a),
        Command::ExportUrdf(a) => model::export_urdf(a),
        Command::Plan(a) => plan::run(a),
        Command::Serve(a) => serve::serve(a),
        Command::Worker(a) => worker::worker(a),
        Command::Health(a) => health::health(a),
    }
}
