//! `kinecal data check | join`: check a data file against a model, or join an inputs file and a
//! measurement file into one data file.
use clap::{Args, Subcommand};
use kinecal::io::data_file::{data_text, join_files, read_data, DataSet, InputColumns};
use kinecal::io::exports::{join_exports, ExportFiles, JoinedExports};
use kinecal::io::model_file::{AngleUnit, LengthUnit, ModelFile};
use kinecal::io::output::Outputs;
use kinecal::io::seat_exports::join_seat_exports;
use kinecal::io::split::{split, SplitRule};
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
    /// Split a data file into an identification part and a held-out validation part, by id
    /// (`below:500`), parity of the id (`even`: even ids first) or at random (`random:0.5`, with
    /// `--seed`).
    Split {
        /// Model file or built-in name (decides the input columns).
        model: String,
        /// Data file to split.
        data: PathBuf,
        /// The rule: below:ID, even, random:FRACTION.
        #[arg(long)]
        by: String,
        /// Seed of a random split.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// File for the poses the rule selects (identification).
        #[arg(long)]
        out: PathBuf,
        /// File for the other poses (validation).
        #[arg(long)]
        rest: PathBuf,
        /// Replace existing output files.
        #[arg(long)]
        force: bool,
    },
    /// Join raw exports into one data file. Two forms:
    ///
    /// * `data join MODEL INPUTS MEASUREMENTS --out F`: an inputs file (id + input columns, e.g.
    ///   q1_deg…) and a measurement file (id + x_mm,y_mm,z_mm[,qw..qz | roll_deg..yaw_deg] or
    ///   m1x_mm..m3z_mm), row by row;
    /// * `data join MODEL --joints LOG --reflector R1 [--reflector R2 --reflector R3]
    ///   [--reference B1 …] --angles deg|rad --units mm|m --out F`: a controller log (idx or id,
    ///   then one column per input in the model's order) and one tracker export per reflector
    ///   (idx or id, x, y, z), matched by id; lost beams (empty or 0,0,0) and unmatched ids are
    ///   dropped and listed; fixed reference reflectors report how steady the tracker stood;
    /// * `data join MODEL --seat S0 --seat S1 … --angles deg|rad --out F`: one file per seat,
    ///   each the joint configurations (one column per joint, header optional) at which the tool
    ///   ball sat in that seat; seat k is the k-th file (docs/instruments.md).
    Join {
        /// Model file or built-in name (decides the input columns).
        model: String,
        /// Inputs file (CSV), first form.
        #[arg(required_unless_present_any = ["joints", "seat"], conflicts_with_all = ["joints", "seat"])]
        inputs: Option<PathBuf>,
        /// Measurement file (CSV), first form.
        #[arg(required_unless_present_any = ["joints", "seat"], conflicts_with_all = ["joints", "seat"])]
        measurements: Option<PathBuf>,
        /// A seat's export (third form): the joint configurations at which the ball sat in it;
        /// once per seat, seat numbers 0, 1, … in the order given.
        #[arg(long, action = clap::ArgAction::Append, conflicts_with = "joints")]
        seat: Vec<PathBuf>,
        /// Controller log of the joint values (second form).
        #[arg(long, requires = "reflector")]
        joints: Option<PathBuf>,
        /// Tool reflector export (idx,x,y,z): once for a position, three times for the tool frame.
        #[arg(long, action = clap::ArgAction::Append)]
        reflector: Vec<PathBuf>,
        /// Fixed reference reflector export (idx,x,y,z), any number: tracker stability only.
        #[arg(long, action = clap::ArgAction::Append)]
        reference: Vec<PathBuf>,
        /// Unit of the controller log's angle columns.
        #[arg(long, value_parser = ["deg", "rad"], default_value = "deg")]
        angles: String,
        /// Unit of the length columns of the exports.
        #[arg(long, value_parser = ["mm", "m"], default_value = "mm")]
        units: String,
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
    let readings = d
        .measurements
        .iter()
        .any(|m| matches!(m.obs, kinecal::measure::Observation::Distance { relative: true, .. }));
    let format = if readings {
        // Readings relative to an unknown zero: each pivot must place its centre and its zero.
        kinecal::instrument::index_points(&d.measurements, &[]).map_err(|e| anyhow::anyhow!("{}: {e}", d.path.display()))?;
        "readings relative to an unknown zero per pivot (pivot, reading)"
    } else {
        d.format.describe()
    };
    // The rows per artifact (seat, pivot, sphere, plane, cube face).
    let artifacts = kinecal::measure::artifact_rows(&d.measurements);
    // (stderr, so that --json stays one document on stdout.)
    super::warn_limits(d);
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({"path": d.path, "poses": d.measurements.len(), "format": format,
                "artifacts": artifacts, "beyond_limits": d.beyond_limits}))?
        );
    } else {
        println!(
            "{}: {}, measured: {format}",
            d.path.display(),
            super::count(d.measurements.len(), "pose")
        );
        if !artifacts.is_empty() {
            let each: Vec<String> = artifacts.iter().map(ToString::to_string).collect();
            println!("{}", each.join(", "));
        }
        if let Some(n) = d.measurements.first().map(|m| m.joints.len()).filter(|n| *n > 0) {
            println!("with the readings of {n} observed joints");
        }
        if let Some(note) = d.derived_note() {
            eprintln!("note: {note}");
        }
        if let Some(note) = d.dropped_note() {
            println!("{note}");
        }
    }
    Ok(())
}

/// Dropped poses and reference stability of a join from exports (stderr for dropped lines, so
/// that `--json` stays one document on stdout).
fn print_join(j: &JoinedExports, json: bool) {
    if !j.dropped.is_empty() {
        eprintln!("{} dropped:", super::count(j.dropped.len(), "pose"));
        for (id, why) in j.dropped.iter().take(20) {
            eprintln!("  id {id}: {why}");
        }
        if j.dropped.len() > 20 {
            eprintln!("  … ({} more)", j.dropped.len() - 20);
        }
    }
    if json {
        return;
    }
    for r in &j.references {
        println!(
            "reference {}: {} readings within {} mm of its median ({} lost or beyond), max deviation {:.4} mm, RMS {:.4} mm",
            r.path.display(),
            r.valid,
            kinecal::io::exports::REFERENCE_OUTLIER_MM,
            r.failed,
            r.max_deviation_mm,
            r.rms_deviation_mm
        );
    }
}

/// Run the command.
pub fn run(args: DataArgs) -> anyhow::Result<()> {
    match args.command {
        DataCommand::Check { model, data, json } => {
            let file = ModelFile::load_or_builtin(&model)?;
            let d = read_data(&data, &file.data_columns(), InputColumns::Required)?;
            super::check_units(&file, &d, true)?;
            summary(&d, json)
        }
        DataCommand::Split {
            model,
            data,
            by,
            seed,
            out,
            rest,
            force,
        } => {
            let rule = SplitRule::parse(&by, seed).map_err(|e| anyhow::anyhow!("--by {e}"))?;
            let mut outputs = Outputs::new(force);
            outputs.input(std::path::Path::new(&model)).input(&data);
            outputs.output(&out)?.output(&rest)?;
            let file = ModelFile::load_or_builtin(&model)?;
            let inputs = file.data_columns();
            let d = read_data(&data, &inputs, InputColumns::Required)?;
            super::warn_limits(&d);
            let (a, b) = split(&d, rule);
            for (part, path) in [(&a, &out), (&b, &rest)] {
                anyhow::ensure!(!part.ids.is_empty(), "--by {by}: {} would get no pose", path.display());
                let refl = (!part.reflectors.is_empty()).then_some(part.reflectors.as_slice());
                outputs.stage(path, data_text(path, &inputs, &part.ids, &part.measurements, refl)?.as_bytes())?;
            }
            outputs.commit()?;
            println!(
                "{}: {} → {} ({}) and {} ({})",
                data.display(),
                super::count(d.ids.len(), "pose"),
                out.display(),
                super::count(a.ids.len(), "pose"),
                rest.display(),
                super::count(b.ids.len(), "pose")
            );
            Ok(())
        }
        DataCommand::Join {
            model,
            inputs,
            measurements,
            joints,
            seat,
            reflector,
            reference,
            angles,
            units,
            out,
            json,
            force,
        } => {
            let mut outputs = Outputs::new(force);
            outputs.input(std::path::Path::new(&model));
            for p in inputs
                .iter()
                .chain(&measurements)
                .chain(&joints)
                .chain(&reflector)
                .chain(&reference)
                .chain(&seat)
            {
                outputs.input(p);
            }
            outputs.output(&out)?;
            // One file in two places (the same seat twice, the inputs as the measurements).
            let given: Vec<&PathBuf> = inputs
                .iter()
                .chain(&measurements)
                .chain(&joints)
                .chain(&reflector)
                .chain(&reference)
                .chain(&seat)
                .collect();
            let canonical: Vec<PathBuf> = given.iter().map(|p| p.canonicalize().unwrap_or_else(|_| p.to_path_buf())).collect();
            for (j, c) in canonical.iter().enumerate() {
                if canonical[..j].contains(c) {
                    anyhow::bail!(
                        "{}: given twice: each file once (data join --help says which goes where)",
                        given[j].display()
                    );
                }
            }
            let file = ModelFile::load_or_builtin(&model)?;
            let angle_unit = AngleUnit::parse(&angles).unwrap_or(AngleUnit::Deg);
            let length_unit = LengthUnit::parse(&units).unwrap_or(LengthUnit::Mm);
            let (d, reflectors) = match (inputs, measurements, joints) {
                _ if !seat.is_empty() => {
                    let d = join_seat_exports(&seat, angle_unit, length_unit, &file.data_columns())?;
                    if let Some(w) = kinecal::io::seat_exports::uneven_seats(&d) {
                        eprintln!("warning: {w}");
                    }
                    (d, None)
                }
                (Some(i), Some(m), None) => (join_files(&i, &m, &file.data_columns())?, None),
                (None, None, Some(joints)) => {
                    let files = ExportFiles {
                        joints,
                        angles: angle_unit,
                        reflectors: reflector,
                        references: reference,
                        lengths: length_unit,
                    };
                    let j = join_exports(&files, &file.data_columns(), &out)?;
                    print_join(&j, json);
                    let r = (!j.data.reflectors.is_empty()).then(|| j.data.reflectors.clone());
                    (j.data, r)
                }
                _ => anyhow::bail!("data join: give either INPUTS and MEASUREMENTS, --joints with --reflector, or --seat files"),
            };
            outputs.stage(
                &out,
                data_text(&out, &file.data_columns(), &d.ids, &d.measurements, reflectors.as_deref())?.as_bytes(),
            )?;
            outputs.commit()?;
            summary(&d, json)?;
            if !json {
                println!("joined → {}", out.display());
            }
            Ok(())
        }
    }
}
