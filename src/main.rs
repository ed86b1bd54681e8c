//! `kinecal`: the command line over the kinecal library. It parses arguments, calls the library,
//! prints tables or JSON, and turns every error into one line on stderr and a non-zero exit.
use clap::{Parser, Subcommand};
use std::process::ExitCode;

mod cli;

/// Kinematic calibration of parallel and serial manipulators.
///
/// Units: lengths in mm, angles in degrees on the command line and in reports (radians inside
/// model files only where a file says so).
#[derive(Parser, Debug)]
#[command(name = "kinecal", version, about, long_about = None)]
struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Calibrate the ABB IRB 120 from real laser-tracker data (three tool reflectors), identify
    /// on poses idx < 500 and validate on idx ≥ 500.
    Irb120(cli::irb120::Irb120Args),
    /// Choose measurement configurations that maximise an observability index (greedy, SFFS or
    /// exchange over a large candidate set) and write them as CSV.
    Plan(cli::plan::PlanArgs),
}

fn main() -> ExitCode {
    let args = Args::parse();
    let result = match args.command {
        Command::Irb120(a) => cli::irb120::run(a),
        Command::Plan(a) => cli::plan::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("kinecal: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
