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
    /// Reproduce a seed paper's simulation study (`study pm5`: §5.1 of the 5-DOF paper; `study t3r1`: §6 of the 3T1R paper) and print
    /// the paper's figures beside kinecal's.
    Study(cli::study::StudyCommand),
    /// Built-in models: list them, export one as a model file (TOML) to edit.
    Model(cli::model::ModelArgs),
    /// Data files: check one against a model, join an inputs file and a measurement file.
    Data(cli::data::DataArgs),
    /// Virtual prototype: random geometric errors and noisy measurements → data CSV + true model.
    Simulate(cli::simulate::SimulateArgs),
    /// Rank, redundant parameters and condition number of the identification problem.
    Identifiability(cli::identifiability::IdentifiabilityArgs),
    /// Identify the free parameters from measurements → calibrated model (TOML) + report.
    Identify(cli::identify::IdentifyArgs),
    /// Position / orientation error statistics of a model against measurements.
    Validate(cli::validate::ValidateArgs),
    /// Target poses → actuator commands through the calibrated model's inverse kinematics.
    Compensate(cli::compensate::CompensateArgs),
    /// Choose measurement configurations that maximise an observability index (greedy, SFFS or
    /// exchange over a large candidate set) and write them as CSV.
    Plan(Box<cli::plan::PlanArgs>),
}

fn main() -> ExitCode {
    let args = Args::parse();
    let result = match args.command {
        Command::Irb120(a) => cli::irb120::run(a),
        Command::Study(a) => cli::study::run(a),
        Command::Model(a) => cli::model::run(a),
        Command::Data(a) => cli::data::run(a),
        Command::Simulate(a) => cli::simulate::run(a),
        Command::Identifiability(a) => cli::identifiability::run(a),
        Command::Identify(a) => cli::identify::run(a),
        Command::Validate(a) => cli::validate::run(a),
        Command::Compensate(a) => cli::compensate::run(a),
        Command::Plan(a) => cli::plan::run(*a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // Library errors already include their cause in their message: print the top one only.
            eprintln!("kinecal: error: {e}");
            ExitCode::FAILURE
        }
    }
}
