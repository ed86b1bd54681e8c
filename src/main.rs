//! `kinecal`: the command line over the kinecal library. It parses arguments, calls the library,
//! prints tables or JSON, and turns every error into one line on stderr and a non-zero exit.
use clap::{CommandFactory, Parser, Subcommand};
use std::process::ExitCode;

mod cli;

/// Kinematic calibration of parallel and serial manipulators.
///
/// Units: lengths in mm, angles in degrees on the command line and in reports (radians inside
/// model files only where a file says so).
///
/// Exit codes: 0 the result is usable; 1 wrong input or options, or nothing could be computed;
/// 2 a result was computed but failed its checks (not converged, residual far beyond the noise).
/// Outputs are written all together only when the command succeeds, never over an input, and
/// replace existing files only with --force.
#[derive(Parser, Debug)]
#[command(name = "kinecal", version, about)]
struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// A complete calibration of the built-in 5-DOF parallel machine in one command: export the
    /// model, plan 30 measurement configurations, measure a virtual prototype there, identify,
    /// validate, compensate, and check the compensated commands on the prototype.
    Quickstart(cli::quickstart::QuickstartArgs),
    /// Models: list the built-in ones, export one (or a calibrated model file) as a model file,
    /// DH table or URDF, import a URDF.
    Model(cli::model::ModelArgs),
    /// Choose measurement configurations that maximise an observability index (greedy, SFFS or
    /// exchange over a large candidate set) and write them as CSV.
    Plan(Box<cli::plan::PlanArgs>),
    /// Virtual prototype: random geometric errors and noisy measurements → data CSV + true model.
    Simulate(Box<cli::simulate::SimulateArgs>),
    /// Rank, redundant parameters and condition number of the identification problem.
    Identifiability(cli::identifiability::IdentifiabilityArgs),
    /// Identify the free parameters from measurements → calibrated model (TOML) + report.
    Identify(cli::identify::IdentifyArgs),
    /// Position / orientation error statistics of a model against measurements.
    Validate(cli::validate::ValidateArgs),
    /// Re-measured poses judged against a calibration's prediction: exit 0 "still calibrated",
    /// 2 "drifted" with the poses beyond their expected error and the pattern that explains it.
    Check(cli::check::CheckArgs),
    /// Target poses → actuator commands through the calibrated model's inverse kinematics.
    Compensate(cli::compensate::CompensateArgs),
    /// A program's targets corrected for a controller that keeps its nominal kinematics (CSV
    /// targets, ABB RAPID): T' = FK_nominal(IK_calibrated(T)) on the program's configuration.
    Filter(Box<cli::filter::FilterArgs>),
    /// ISO 9283 pose accuracy and repeatability (and distance accuracy) of measured test runs at
    /// commanded test poses, before and after calibration side by side.
    Assess(cli::assess::AssessArgs),
    /// Data files: check one against a model, join an inputs file and a measurement file.
    Data(cli::data::DataArgs),
    /// Reproduce a seed paper's simulation study (`study pm5`, `study pm5-design`: the 5-DOF paper; `study t3r1`: the 3T1R paper) and print
    /// the paper's figures beside kinecal's.
    Study(cli::study::StudyCommand),
    /// Calibrate the ABB IRB 120 from real laser-tracker data (three tool reflectors), identify
    /// on poses idx < 500 and validate on idx ≥ 500.
    Irb120(cli::irb120::Irb120Args),
}

/// Run one parsed command.
fn dispatch(command: Command) -> anyhow::Result<()> {
    let command = match command {
        // `plan MODEL` is `plan --model MODEL` (what the runs read).
        Command::Plan(mut a) => {
            a.model = a.model.take().or(a.model_arg.take());
            Command::Plan(a)
        }
        other => other,
    };
    match command {
        Command::Quickstart(a) => cli::quickstart::run(a, run_line),
        Command::Irb120(a) => cli::irb120::run(a),
        Command::Study(a) => cli::study::run(a),
        Command::Model(a) => cli::model::run(a),
        Command::Data(a) => cli::data::run(a),
        Command::Simulate(a) => cli::simulate::run(*a),
        Command::Identifiability(a) => cli::identifiability::run(a),
        Command::Identify(a) => cli::identify::run(a),
        Command::Validate(a) => cli::validate::run(a),
        Command::Check(a) => cli::check::run(a),
        Command::Compensate(a) => cli::compensate::run(a),
        Command::Filter(a) => cli::filter::run(*a),
        Command::Assess(a) => cli::assess::run(a),
        Command::Plan(a) if a.iso.iso9283 => cli::plan::model(&a).and_then(|(f, _)| cli::iso_plan::run(&a, f)),
        Command::Plan(a) if a.instrument.active() => cli::plan::model(&a).and_then(|(f, _)| cli::instrument_plan::run(&a, f)),
        Command::Plan(a) => cli::plan::run(*a),
    }
}

/// Run one `kinecal` command line given without the program name (the quickstart's steps).
fn run_line(line: &[String]) -> anyhow::Result<()> {
    let argv: Vec<String> = std::iter::once("kinecal".to_string()).chain(line.iter().cloned()).collect();
    let args = Args::try_parse_from(&argv)
        .map_err(|e| anyhow::anyhow!(cli::usage::fold(&e, &Args::command(), &argv).unwrap_or_else(|| e.to_string())))?;
    dispatch(args.command)
}

fn main() -> ExitCode {
    // Exit quietly when the reader of our output goes away (`kinecal … | head`), as command-line
    // tools do, instead of panicking in `println!` on a broken pipe.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    // glibc serves every allocation above 128 KiB (a block of Jacobian rows, a factor) with a
    // fresh mmap and returns it on free, so each one costs page faults again: a fifth of a
    // 500-pose identification's time went to faults. Keeping such blocks on the heap (and
    // its top) lets them be reused.
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only tunes the allocator; called before any allocation-heavy work or thread.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 256 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 512 << 20);
        libc::mallopt(libc::M_TOP_PAD, 16 << 20);
    }
    let argv: Vec<String> = std::env::args_os().map(|a| a.to_string_lossy().into_owned()).collect();
    let args = match Args::try_parse_from(&argv) {
        Ok(args) => args,
        // A usage error is wrong input (exit 1), on one line; --help and --version exit 0.
        Err(e) => match cli::usage::fold(&e, &Args::command(), &argv) {
            None => e.exit(),
            Some(line) => {
                eprintln!("kinecal: error: {line}");
                return ExitCode::from(cli::EXIT_ERROR);
            }
        },
    };
    match dispatch(args.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // Library errors already include their cause in their message: print the top one only.
            if e.downcast_ref::<cli::FailedChecks>().is_some() {
                eprintln!("kinecal: failed: {e}");
                ExitCode::from(cli::EXIT_FAILED_CHECKS)
            } else {
                eprintln!("kinecal: error: {e}");
                ExitCode::from(cli::EXIT_ERROR)
            }
        }
    }
}
