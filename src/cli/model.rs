//! `kinecal model list | export NAME | import FILE`: the built-in models, model files in
//! their forms (local POE, DH, modified DH, URDF, controllers' kinematics files), URDF and
//! controllers' files in.
use clap::{Args, Subcommand, ValueEnum};
use kinecal::io::builtin;
use kinecal::io::controllers::{self, Controller};
use kinecal::io::model_file::{AngleUnit, LengthUnit, ModelFile};
use kinecal::io::output::Outputs;
use kinecal::io::urdf;
use kinecal::model::dh::{DhConvention, DhOptions};
use std::path::{Path, PathBuf};

/// What `kinecal model export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ExportFormat {
    /// kinecal's model file (TOML), serial chains in local-POE joint form.
    Toml,
    /// kinecal's model file (TOML) with a standard DH table (serial chains only).
    Dh,
    /// kinecal's model file (TOML) with a modified (Craig) DH table (serial chains only).
    Mdh,
    /// URDF (XML, metres and radians; serial chains only).
    Urdf,
    /// Universal Robots kinematics YAML (ur_description / ROS driver; six revolute joints).
    UrYaml,
    /// LinuxCNC genhexkins HAL parameters (Stewart platforms).
    LinuxcncHexapod,
    /// Klipper linear delta printer.cfg sections.
    KlipperDelta,
}

impl ExportFormat {
    fn controller(self) -> Option<Controller> {
        match self {
            ExportFormat::UrYaml => Some(Controller::UrYaml),
            ExportFormat::LinuxcncHexapod => Some(Controller::LinuxcncHexapod),
            ExportFormat::KlipperDelta => Some(Controller::KlipperDelta),
            _ => None,
        }
    }
}

/// What `kinecal model import` reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ImportFormat {
    /// URDF (XML).
    Urdf,
    /// Universal Robots kinematics YAML.
    UrYaml,
    /// LinuxCNC genhexkins HAL parameters.
    LinuxcncHexapod,
    /// Klipper linear delta printer.cfg.
    KlipperDelta,
}

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
    /// Print a built-in model (or re-write a model file, e.g. a calibrated one) as a model file
    /// (TOML) to edit and load back, as a DH / modified-DH table, or as URDF.
    Export {
        /// Built-in model name (see `kinecal model list`) or a model file.
        name: String,
        /// What to write: toml (the model file), dh / mdh (the model file with a standard or
        /// modified DH table, where the geometry allows), urdf (for ROS / MoveIt), or a
        /// controller's kinematics file: ur-yaml, linuxcnc-hexapod, klipper-delta (the model
        /// projected onto the controller's parameters; what that leaves is printed).
        #[arg(long, value_enum, default_value_t = ExportFormat::Toml)]
        format: ExportFormat,
        /// With --format dh: Hayati's β for joints whose next axis is nearly parallel (needed for
        /// most calibrated arms).
        #[arg(long)]
        hayati: bool,
        /// Length unit of the written model file: mm or m (URDF is always in m).
        #[arg(long)]
        length: Option<String>,
        /// Angle unit of the written model file: deg or rad (URDF is always in rad).
        #[arg(long)]
        angle: Option<String>,
        /// With --format klipper-delta: the bed, found from the probe's touches on it in this data
        /// file (the rows with a `plane`, e.g. those the model was calibrated from): Klipper's
        /// z = 0 on it, z along its normal, the nozzle the model's tool point.
        #[arg(long, value_name = "DATA.csv")]
        bed: Option<PathBuf>,
        /// With --bed: which plane of the file is the bed (default: its only plane).
        #[arg(long, value_name = "K", requires = "bed")]
        bed_plane: Option<usize>,
        /// With --format klipper-delta: tower c's angle (degrees), the frame turned about z to
        /// put it there (nothing measured fixes that turn; keep the printer's own).
        #[arg(long, value_name = "DEG", allow_hyphen_values = true)]
        angle_c: Option<f64>,
        /// Write to this file instead of standard output.
        #[arg(long, short)]
        out: Option<PathBuf>,
        /// Replace an existing output file.
        #[arg(long)]
        force: bool,
    },
    /// A model file from a URDF (the chain from --base to --tip, fixed joints folded into the
    /// next joint's placement; xacro files: expand them with `xacro` first) or from a
    /// controller's kinematics file (--format ur-yaml, linuxcnc-hexapod, klipper-delta).
    Import {
        /// The URDF or controller file.
        urdf: PathBuf,
        /// What the file is.
        #[arg(long, value_enum, default_value_t = ImportFormat::Urdf)]
        format: ImportFormat,
        /// The chain's base link (default: the root link).
        #[arg(long)]
        base: Option<String>,
        /// The chain's tip link (default: the only leaf reached through the most movable joints).
        #[arg(long)]
        tip: Option<String>,
        /// Length unit of the written model file: mm or m.
        #[arg(long, default_value = "mm")]
        length: String,
        /// Angle unit of the written model file: deg or rad.
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

fn units(file: &mut ModelFile, length: &str, angle: &str) -> anyhow::Result<()> {
    file.units.length = LengthUnit::parse(length).ok_or_else(|| anyhow::anyhow!("--length: unknown unit '{length}' (use mm or m)"))?;
    file.units.angle = AngleUnit::parse(angle).ok_or_else(|| anyhow::anyhow!("--angle: unknown unit '{angle}' (use deg or rad)"))?;
    Ok(())
}

fn write_out(mut outputs: Outputs, out: Option<&Path>, text: &str) -> anyhow::Result<()> {
    match out {
        Some(path) => {
            outputs.stage(path, text.as_bytes())?;
            outputs.commit()?;
        }
        None => print!("{text}"),
    }
    Ok(())
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
            format,
            hayati,
            length,
            angle,
            bed,
            bed_plane,
            angle_c,
            out,
            force,
        } => {
            let mut outputs = Outputs::new(force);
            outputs.input(Path::new(&name)).output_opt(out.as_deref())?;
            if let Some(b) = &bed {
                outputs.input(b);
            }
            let mut file = ModelFile::load_or_builtin(&name)?;
            if hayati && format != ExportFormat::Dh {
                anyhow::bail!("--hayati: only with --format dh (Hayati's β is a standard-DH term)");
            }
            if format == ExportFormat::Urdf && (length.is_some() || angle.is_some()) {
                anyhow::bail!("--length / --angle: URDF is always in metres and radians");
            }
            if let Some(controller) = format.controller() {
                if length.is_some() || angle.is_some() {
                    anyhow::bail!("--length / --angle: a controller file has its own units (docs/controllers.md)");
                }
                let (export, bed_line) = match (controller, &bed, angle_c) {
                    (Controller::KlipperDelta, _, _) if bed.is_some() || angle_c.is_some() => {
                        klipper_on_bed(&file, &name, bed.as_deref(), bed_plane, angle_c)?
                    }
                    (_, None, None) => (
                        controllers::export(&file, controller).map_err(|e| anyhow::anyhow!("{}", e.at(&name)))?,
                        None,
                    ),
                    _ => anyhow::bail!(
                        "--bed / --angle-c: only with --format klipper-delta (where Klipper's frame stands on a printer's bed)"
                    ),
                };
                write_out(outputs, out.as_deref(), &export.text)?;
                let p = &export.projection;
                let mut report = bed_line.unwrap_or_default();
                report += &format!("{}: {}\n", controller.name(), p.difference);
                if p.not_represented.is_empty() {
                    report += "  every error parameter of the model is represented\n";
                } else {
                    report += "  not represented by the controller's parameters:\n";
                    for l in &p.not_represented {
                        report += &format!("    {l}\n");
                    }
                }
                for l in &p.not_written {
                    report += &format!("  not in the file: {l}\n");
                }
                if out.is_some() {
                    print!("{report}");
                } else {
                    eprint!("{report}");
                }
                return Ok(());
            }
            if bed.is_some() || angle_c.is_some() {
                anyhow::bail!("--bed / --angle-c: only with --format klipper-delta (where Klipper's frame stands on a printer's bed)");
            }
            units(&mut file, length.as_deref().unwrap_or("mm"), angle.as_deref().unwrap_or("deg"))?;
            let text = match format {
                ExportFormat::Toml => file.to_toml().map_err(|e| anyhow::anyhow!("{name}: {e}"))?,
                ExportFormat::Dh | ExportFormat::Mdh => {
                    let convention = if format == ExportFormat::Dh {
                        DhConvention::Standard
                    } else {
                        DhConvention::Modified
                    };
                    file.to_toml_dh(convention, DhOptions { hayati })
                        .map_err(|e| anyhow::anyhow!("{name}: {e}"))?
                }
                ExportFormat::Urdf => urdf::export(&file).map_err(|e| anyhow::anyhow!("{name}: {e}"))?,
                ExportFormat::UrYaml | ExportFormat::LinuxcncHexapod | ExportFormat::KlipperDelta => {
                    unreachable!("controller formats are written above")
                }
            };
            write_out(outputs, out.as_deref(), &text)?;
            if let Some(o) = &out {
                println!(
                    "{} ({}) as {} → {}",
                    file.name,
                    super::count(file.build().input_names().len(), "input"),
                    format!("{format:?}").to_lowercase(),
                    o.display()
                );
            }
        }
        ModelCommand::Import {
            urdf: path,
            format,
            base,
            tip,
            length,
            angle,
            out,
            force,
        } => {
            let mut outputs = Outputs::new(force);
            outputs.input(&path).output_opt(out.as_deref())?;
            let text = kinecal::io::read_text(&path)?;
            let controller = match format {
                ImportFormat::Urdf => None,
                ImportFormat::UrYaml => Some(Controller::UrYaml),
                ImportFormat::LinuxcncHexapod => Some(Controller::LinuxcncHexapod),
                ImportFormat::KlipperDelta => Some(Controller::KlipperDelta),
            };
            if controller.is_some() && (base.is_some() || tip.is_some()) {
                anyhow::bail!("--base / --tip: only with --format urdf");
            }
            let mut file = match controller {
                None => urdf::import(&text, base.as_deref(), tip.as_deref()).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?,
                Some(c) => controllers::import(&text, c).map_err(|e| anyhow::anyhow!("{}", e.at(&path.display().to_string())))?,
            };
            units(&mut file, &length, &angle)?;
            let toml = file.to_toml().map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            write_out(outputs, out.as_deref(), &toml)?;
            if let Some(o) = &out {
                let names = file.build().input_names();
                println!(
                    "{}: {} joints ({}) → {}",
                    file.description.as_deref().unwrap_or(&file.name),
                    names.len(),
                    names.join(", "),
                    o.display()
                );
            }
        }
    }
    Ok(())
}

/// `model export --format klipper-delta` with `--bed` and/or `--angle-c`: the export and a line
/// about the bed found.
fn klipper_on_bed(
    file: &ModelFile,
    name: &str,
    bed: Option<&Path>,
    bed_plane: Option<usize>,
    angle_c: Option<f64>,
) -> anyhow::Result<(controllers::Export, Option<String>)> {
    use kinecal::io::controllers::{bed::bed_from_touches, klipper_delta};
    use kinecal::io::data_file::{read_data, InputColumns};
    if let Some(a) = angle_c {
        anyhow::ensure!(a.is_finite(), "--angle-c: a finite angle in degrees, got {a}");
    }
    let (found, line) = match bed {
        Some(path) => {
            let data = read_data(path, &file.data_columns(), InputColumns::Required)?;
            let fit = bed_from_touches(file, &data.measurements, bed_plane)
                .map_err(|e| anyhow::anyhow!("{}", e.at(&path.display().to_string())))?;
            let line = format!(
                "bed: plane {} of {}, {} touches, {:.4} mm RMS from their plane ({:.4} mm max)\n",
                fit.plane,
                path.display(),
                fit.touches,
                fit.rms_mm,
                fit.max_mm
            );
            (Some(fit.bed), Some(line))
        }
        None => (None, None),
    };
    let opts = klipper_delta::KlipperOptions { bed: found, angle_c };
    let export = klipper_delta::export_with(file, &opts).map_err(|e| anyhow::anyhow!("{}", e.at(name)))?;
    Ok((export, line))
}
