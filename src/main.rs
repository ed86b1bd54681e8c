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
    /// The §6 simulation study of the 3T1R 4-DOF manipulator (Zhang et al. 2020): ranks,
    /// identification of the B1/B3 pair with the closure-computed lower angles, idle-pair
    /// cross-validation and §7 compensation, noise-free and noisy, paper vs kinecal.
    #[command(name = "t3r1-study")]
    StudyT3r1(cli::study_t3r1::StudyT3r1Args),
}

fn main() -> ExitCode {
    let args = Args::parse();
    let result = match args.command {
        Command::Irb120(a) => cli::irb120::run(a),
        Command::StudyT3r1(a) => cli::study_t3r1::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("kinecal: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
