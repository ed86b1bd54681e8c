//! `kinecal data check | join`: check a data file against a model, or join an inputs file and a
//! measurement file into one data file.
use clap::{Args, Subcommand};
use kinecal::io::data_file::{data_text, join_files, read_data, DataSet, InputColumns};
use kinecal::io::model_file::ModelFile;
use kinecal::io::output::Outputs;
use std::path::PathBuf;

/// Arguments of `kinecal data`.
#[derive(Args, Debug)]
pub struct DataArgs {
    #[command(subcommand)]
    command: DataCommand,
}

#[derive(Subcommand, Debug)]
enum DataCommand {
    /// Read a data file for a model and report what it holds (or the first problem, with its line).
    Check {
        /// Model file or built-in name (decides the input columns).
        model: String,
        /// Data file (CSV).
        data: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Join an inputs file (id + input columns, e.g. q1_deg…) and a measurement file (id +
    /// x_mm,y_mm,z_mm[,qw..qz | roll_deg..yaw_deg] or m1x_mm..m3z_mm) row by row; both must have the
    /// same rows (and the same ids, when both have an id column). Writes positions in mm and
    /// orientations as quaternions (reflector triples as their frame).
    Join {
        /// Model file or built-in name (decides the input columns).
        model: String,
        /// Inputs file (CSV).
        inputs: PathBuf,
        /// Measurement file (CSV).
        measurements: PathBuf,
        /// Joined data file to write (CSV).
        #[arg(long, short)]
        out: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
        /// Replace an existing output file.
        #[arg(long)]
        force: bool,
    },
}

fn summary(d: &DataSet, json: bool) -> anyhow::Result<()> {
    let format = d.format.describe();
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({"path": d.path, "poses": d.measurements.len(), "format": format}))?
        );
    } else {
        println!("{}: {} poses, measured: {format}", d.path.display(), d.measurements.len());
        if let Some(note) = d.dropped_note() {
            println!("{note}");
        }
    }
    Ok(())
}

/// Run the command.
pub fn run(args: DataArgs) -> anyhow::Result<()> {
    match args.command {
        DataCommand::Check { model, data, json } => {
            let file = ModelFile::load_or_builtin(&model)?;
            summary(&read_data(&data, &file.inputs(), InputColumns::Required)?, json)
        }
        DataCommand::Join {
            model,
            inputs,
            measurements,
            out,
            json,
            force,
        } => {
            let mut outputs = Outputs::new(force);
            outputs.input(std::path::Path::new(&model)).input(&inputs).input(&measurements);
            outputs.output(&out)?;
            let file = ModelFile::load_or_builtin(&model)?;
            let d = join_files(&inputs, &measurements, &file.inputs())?;
            outputs.stage(&out, data_text(&out, &file.inputs(), &d.ids, &d.measurements, None)?.as_bytes())?;
            outputs.commit()?;
            summary(&d, json)?;
            if !json {
                println!("joined → {}", out.display());
            }
            Ok(())
        }
    }
}
