//! `kinecal plan --seats …` / `--pivots … --ballbar-mm L`: plan the rows of an instrument without
//! a tracker (orientations at each seat, directions about each pivot) and write them as a data
//! file with a `seat` (or `pivot,length_mm`) column, which `kinecal simulate --at` measures on a
//! virtual prototype. One call, [`kinecal::design::plan_instrument`]; this module parses and
//! prints. The size, method, criterion, seed, noise (`--noise-position-mm`) and output are
//! `kinecal plan`'s.
use super::plan::PlanArgs;
use clap::Args;
use kinecal::design::{plan_instrument, InstrumentLayout, InstrumentPlan, InstrumentPlanOptions, SelectOptions};
use kinecal::instrument::simulate::{parse_points, Placement};
use kinecal::io::data_file::data_text;
use kinecal::io::{model_file::ModelFile, output::Outputs};
use nalgebra::Vector3;

/// The arguments of an instrument plan.
#[derive(Args, Debug)]
pub struct InstrumentArgs {
    /// Plan for fixed seats at these points (mm, base frame, `X,Y,Z;X,Y,Z;…`): orientations at
    /// each seat; the plan gets a `seat` column.
    #[arg(long, value_name = "X,Y,Z;…", conflicts_with_all = ["pivots", "iso9283"])]
    pub seats: Option<String>,
    /// Plan for a ballbar between the tool point and each of these pivots (mm, base frame):
    /// directions about each pivot; columns `pivot,length_mm`. Needs --ballbar-mm.
    #[arg(long, value_name = "X,Y,Z;…", requires = "ballbar_mm", conflicts_with = "iso9283")]
    pub pivots: Option<String>,
    /// The ballbar's length (mm).
    #[arg(long, value_name = "L", requires = "pivots", allow_hyphen_values = true)]
    pub ballbar_mm: Option<f64>,
    /// The ball's centre on the flange or platform (mm, `X,Y,Z`), the nominal tool point.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub tool_mm: Option<String>,
    /// Candidate rows drawn per seat or pivot on the nominal model.
    #[arg(long, default_value_t = 100)]
    pub candidates_per_point: usize,
    /// Largest tilt of the tool from its orientation at the reference configuration (degrees).
    #[arg(long, default_value_t = 30.0)]
    pub tilt_deg: f64,
    /// The configuration orientations are drawn about, the model's inputs in deg / mm
    /// (comma-separated); default the middle of each input's limits.
    #[arg(long, value_name = "Q1,Q2,…", allow_hyphen_values = true)]
    pub reference: Option<String>,
    /// Rows each seat or pivot gets at least (never fewer than 2 per seat, 4 per pivot; for
    /// touches 4 per sphere, 3 per plane or cube face).
    #[arg(long, default_value_t = 0)]
    pub min_per_point: usize,
    /// A touch probe's artifacts instead: where to touch them ([`kinecal::design::plan_touches`];
    /// `--candidates-per-point` candidates per sphere, plane or cube face).
    #[command(flatten)]
    pub touch: super::touch_args::TouchArgs,
}

impl InstrumentArgs {
    /// Whether an instrument plan is asked for.
    pub fn active(&self) -> bool {
        self.seats.is_some() || self.pivots.is_some() || self.touch.active()
    }
}

/// Run an instrument plan.
pub fn run(args: &PlanArgs, file: ModelFile) -> anyhow::Result<()> {
    let a = &args.instrument;
    anyhow::ensure!(
        !(a.touch.active() && a.pivots.is_some()),
        "--planes and --pivots: plan the touches and the ballbar's rows apart"
    );
    if a.touch.active() {
        return touch_run(args, file);
    }
    let (option, text) = match (&a.seats, &a.pivots) {
        (Some(s), _) => ("--seats", s),
        (None, Some(p)) => ("--pivots", p),
        (None, None) => anyhow::bail!("an instrument plan needs --seats or --pivots"),
    };
    let points = parse_points(text).map_err(|e| anyhow::anyhow!("{option} {e}"))?;
    let ball = match &a.tool_mm {
        Some(t) => match parse_points(t).map_err(|e| anyhow::anyhow!("--tool-mm {e}"))?.as_slice() {
            [b] => *b,
            _ => anyhow::bail!("--tool-mm '{t}': one point X,Y,Z (mm)"),
        },
        None => Vector3::zeros(),
    };
    anyhow::ensure!(
        a.tilt_deg.is_finite() && (0.0..=90.0).contains(&a.tilt_deg),
        "--tilt-deg: must be between 0 and 90, got {}",
        a.tilt_deg
    );
    anyhow::ensure!(a.candidates_per_point > 0, "--candidates-per-point: must be at least 1");
    let inputs = file.inputs();
    let layout = InstrumentLayout {
        points: points.clone(),
        bar_length: a.ballbar_mm,
        ball,
    };
    let reference = kinecal::instrument::simulate::reference_configuration(a.reference.as_deref(), &inputs).map_err(anyhow::Error::msg)?;
    let opts = plan_options(args, reference, a.tilt_deg.to_radians(), inputs.clone());
    let outputs = plan_outputs(args)?;
    let plan = plan_instrument(&file, &layout, &opts).map_err(|e| anyhow::anyhow!("{option}: {e}"))?;
    let kind = layout.kind().name();
    let sel = &plan.selection;
    let per_point: Vec<usize> = (0..points.len())
        .map(|k| {
            plan.rows
                .iter()
                .filter(|m| m.obs.artifact_point().is_some_and(|p| p.1 == k))
                .count()
        })
        .collect();
    let list = |v: &[Vector3<f64>]| v.iter().map(|p| format!("{},{},{}", p.x, p.y, p.z)).collect::<Vec<_>>().join(";");
    let measure = match a.ballbar_mm {
        Some(l) => format!("--pivots \"{}\" --ballbar-mm {l}", list(&points)),
        None => format!("--seats \"{}\"", list(&points)),
    };
    let what = format!("{} rows for {} {kind}s ({per_point:?} each)", plan.rows.len(), points.len());
    write_plan(args, &file, outputs, &plan, &what, &measure)?;
    if args.json {
        let v = serde_json::json!({"model": file.name, "instrument": kind, "points": points.len(), "rows": plan.rows.len(),
            "rows_per_point": per_point, "candidates": plan.candidates.len(), "repairs": plan.repairs,
            "method": sel.method, "criterion": sel.criterion, "indices": sel.indices, "columns": plan.column_names, "output": args.output});
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "{}: {} candidates ({} per {kind}, tilt ≤ {}°), {} identifiable columns (the tool point, the geometry, the {kind}s)",
        file.name,
        plan.candidates.len(),
        a.candidates_per_point,
        a.tilt_deg,
        plan.columns.len()
    );
    println!(
        "{:?} on {}: {} rows, per {kind} {per_point:?} ({} moves to give each its minimum)",
        sel.method,
        sel.criterion,
        plan.rows.len(),
        plan.repairs
    );
    println!("indices (scaled, dimensionless): {}", sel.indices);
    println!(
        "wrote {} (measure it: kinecal simulate {} --at {} {measure} …)",
        args.output.display(),
        args.model.as_deref().unwrap_or(&file.name),
        args.output.display()
    );
    Ok(())
}

/// Plan where to touch `--spheres`, `--planes` or `--cube` ([`kinecal::design::plan_touches`]).
fn touch_run(args: &PlanArgs, file: ModelFile) -> anyhow::Result<()> {
    use kinecal::design::{plan_touches, TouchLayout};
    let a = &args.instrument;
    let (kind, artifacts, probe) = a.touch.artifacts()?;
    let ball = match &a.tool_mm {
        Some(t) => match parse_points(t).map_err(|e| anyhow::anyhow!("--tool-mm {e}"))?.as_slice() {
            [b] => *b,
            _ => anyhow::bail!("--tool-mm '{t}': one point X,Y,Z (mm)"),
        },
        None => Vector3::zeros(),
    };
    anyhow::ensure!(a.candidates_per_point > 0, "--candidates-per-point: must be at least 1");
    let layout = TouchLayout { artifacts, ball };
    let opts = plan_options(args, Vec::new(), 0.0, file.inputs());
    let outputs = plan_outputs(args)?;
    let plan = plan_touches(&file, &layout, &opts)?;
    let sel = &plan.selection;
    let counts: std::collections::BTreeMap<String, usize> = (kinecal::measure::artifact_rows(&plan.rows).iter())
        .map(|a| (a.name(), a.rows))
        .collect();
    let per: Vec<String> = counts.iter().map(|(k, c)| format!("{k}: {c}")).collect();
    let measure = a.touch.command_line();
    let what = format!(
        "{} touches of {} {kind}s ({})",
        plan.rows.len(),
        layout.artifacts.len(),
        per.join(", ")
    );
    write_plan(args, &file, outputs, &plan, &what, &measure)?;
    if args.json {
        let v = serde_json::json!({"model": file.name, "instrument": kind, "artifacts": layout.artifacts.len(), "rows": plan.rows.len(),
            "rows_per_artifact": counts, "candidates": plan.candidates.len(), "repairs": plan.repairs, "probe_radius_mm": probe,
            "method": sel.method, "criterion": sel.criterion, "indices": sel.indices, "columns": plan.column_names, "output": args.output});
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "{}: {} candidate touches ({} per {kind}), {} identifiable columns (the probe offset, the geometry, the {kind}s)",
        file.name,
        plan.candidates.len(),
        a.candidates_per_point,
        plan.columns.len()
    );
    println!(
        "{:?} on {}: {} touches, {} ({} moves to give each its minimum)",
        sel.method,
        sel.criterion,
        plan.rows.len(),
        per.join(", "),
        plan.repairs
    );
    println!("indices (scaled, dimensionless): {}", sel.indices);
    println!(
        "wrote {} (measure it: kinecal simulate {} --at {} {measure} …)",
        args.output.display(),
        args.model.as_deref().unwrap_or(&file.name),
        args.output.display()
    );
    Ok(())
}

/// The plan's options from the command line: candidates drawn per point about `reference`,
/// tilted up to `max_tilt` (rad; unused for touches), within `inputs`' limits.
fn plan_options(
    args: &PlanArgs,
    reference: Vec<f64>,
    max_tilt: f64,
    inputs: Vec<kinecal::model::kind::InputSpec>,
) -> InstrumentPlanOptions {
    let a = &args.instrument;
    InstrumentPlanOptions {
        draw: Placement {
            per_point: a.candidates_per_point,
            reference,
            max_tilt,
            noise_mm: args.noise_position_mm,
            seed: args.sampling.seed,
            inputs,
        },
        min_per_point: a.min_per_point,
        method: args.method,
        select: SelectOptions {
            n: args.n,
            criterion: args.criterion,
            pool: args.pool,
            shortlist: args.shortlist,
            ..Default::default()
        },
    }
}

/// The plan file as the one output (never replacing the model file read).
fn plan_outputs(args: &PlanArgs) -> anyhow::Result<Outputs> {
    let mut outputs = Outputs::new(args.force);
    if let Some(m) = &args.model {
        outputs.input(std::path::Path::new(m));
    }
    outputs.output(&args.output)?;
    Ok(outputs)
}

/// Write `plan` to `--output` whole (through `outputs`): a comment header (the method and
/// criterion, `what` was planned, the indices, the identifiable columns, the `simulate` command
/// that measures it with the instrument options `measure`), then the rows as a data file.
fn write_plan(
    args: &PlanArgs,
    file: &ModelFile,
    mut outputs: Outputs,
    plan: &InstrumentPlan,
    what: &str,
    measure: &str,
) -> anyhow::Result<()> {
    let sel = &plan.selection;
    if let Some(line) = sel
        .indices
        .rank_shortfall(&format!("the plan's {}", super::count(plan.rows.len(), "row")))
    {
        anyhow::ensure!(args.force, "{line}");
        eprintln!("warning: {line}");
    }
    let mut text = format!(
        "# kinecal plan: {:?} on {}, {what} from {} candidates, {} repair moves\n# {}\n# identifiable columns: {}\n# measure on a virtual prototype: kinecal simulate {} --at {} {measure} --tool-mm X,Y,Z …\n",
        sel.method,
        sel.criterion,
        plan.candidates.len(),
        plan.repairs,
        sel.indices,
        plan.column_names.join(" "),
        args.model.as_deref().unwrap_or(&file.name),
        args.output.display()
    );
    // Rows at which the nominal model does not assemble (its forward kinematics from home does
    // not converge) are left out of the plan, with a line.
    let mut rows = kinecal::io::data_file::DataSet::from_measurements(&args.output.display().to_string(), plan.rows.clone());
    if let Some(u) = rows.set_aside_unassembled(&*file.build())? {
        eprintln!("warning: {} (left out of the plan)", u.note(&rows));
    }
    let ids: Vec<i64> = (0..rows.measurements.len() as i64).collect();
    text += &data_text(&args.output, &file.data_columns(), &ids, &rows.measurements, None)?;
    outputs.stage(&args.output, text.as_bytes())?;
    outputs.commit()?;
    Ok(())
}
