//! `kinecal model list | export NAME`: the built-in models and their model files.
use clap::{Args, Subcommand};
use kinecal::io::model_file::{AngleUnit, LengthUnit, ModelFile};
use kinecal::io::output::Outputs;
use kinecal::model::builtin;
use std::path::PathBuf;

/// Arguments of `kinecal model`.
#[derive(Args, Debug)]
pub struct ModelArgs {
    #[command(subcommand)]
    command: ModelCommand,
}

#[derive(Subcommand, Debug)]
enum ModelCommand {
    /// List the built-in models.
    List {
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Print a built-in model (or re-write a model file) as a model file (TOML) to edit and load back.
    Export {
        /// Built-in model name (see `kinecal model list`) or a model file.
        name: String,
        /// Length unit of the written file: mm or m.
        #[arg(long, default_value = "mm")]
        length: String,
        /// Angle unit of the written file: deg or rad.
        #[arg(long, default_value = "deg")]
        angle: String,
        /// Write to this file instead of standard output.
        #[arg(long, short)]
        out: Option<PathBuf>,
        /// Replace an existing output file.
        #[arg(long)]
        force: bool,
    },
}

/// Run the command.
pub fn run(args: ModelArgs) -> anyhow::Result<()> {
    match args.command {
        ModelCommand::List { json } => {
            let list = builtin::list();
            if json {
                let v: Vec<_> = list
                    .iter()
                    .map(|(name, description)| {
                        let f = builtin::model_file(name).expect("listed models exist");
                        let m = f.build();
                        serde_json::json!({"name": name, "description": description, "kind": f.mechanism.kind(),
                            "inputs": m.input_names(), "params": m.n_params()})
                    })
                    .collect();
                println!("{}", serde_json::to_string_pretty(&v)?);
            } else {
                for (name, description) in list {
                    println!("{name:<12} {description}");
                }
            }
        }
        ModelCommand::Export {
            name,
            length,
            angle,
            out,
            force,
        } => {
            let mut outputs = Outputs::new(force);
            outputs.input(std::path::Path::new(&name)).output_opt(out.as_deref())?;
            let mut file = ModelFile::load_or_builtin(&name)?;
            file.units.length =
                LengthUnit::parse(&length).ok_or_else(|| anyhow::anyhow!("--length: unknown unit '{length}' (use mm or m)"))?;
            file.units.angle =
                AngleUnit::parse(&angle).ok_or_else(|| anyhow::anyhow!("--angle: unknown unit '{angle}' (use deg or rad)"))?;
            match out {
                Some(path) => {
                    let text = file.to_toml().map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
                    outputs.stage(&path, text.as_bytes())?;
                    outputs.commit()?;
                }
                None => print!("{}", file.to_toml().map_err(|e| anyhow::anyhow!("{name}: {e}"))?),
            }
        }
    }
    Ok(())
}
