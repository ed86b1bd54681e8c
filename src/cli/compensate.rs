//! `kinecal compensate MODEL TARGETS`: actuator commands that reach target poses on the
//! calibrated model.
use super::progress;
use clap::Args;
use kinecal::compensate::{compensate, target_poses};
use kinecal::io::data_file::{csv_text, input_headers, input_values_for_file, read_data, InputColumns};
use kinecal::io::model_file::ModelFile;
use kinecal::io::output::Outputs;
use kinecal::model::Task;
use kinecal::se3;
use std::path::{Path, PathBuf};

/// Arguments of `kinecal compensate`.
#[derive(Args, Debug)]
pub struct CompensateArgs {
    /// Calibrated model file (or a built-in name).
    pub model: String,
    /// Target poses (CSV): x_mm,y_mm,z_mm with qw,qx,qy,qz or roll_deg,pitch_deg,yaw_deg; optional
    /// id; optional input columns (e.g. q1_deg…) with the nominal commands, used as starting points.
    pub targets: PathBuf,
    /// Commands file to write (CSV): id and one column per input (deg for angles, mm for lengths).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Nominal model (file or built-in name): when the targets have no input columns, the nominal
    /// model's inverse kinematics gives the starting points, so the compensated commands stay on
    /// the same solution branch (elbow, wrist) as the commands the nominal controller would send.
    #[arg(long)]
    pub nominal: Option<String>,
    /// The targets are in the mechanism's base frame (a robot's base frame, as its programs are),
    /// not in the calibration's measurement frame, and the tool is the mechanism's own (the
    /// flange) or --tool's, not the instrument's reflector or probe.
    #[arg(long)]
    pub base_frame: bool,
    /// The tool the targets are given for, in the flange (the mechanism's tool frame):
    /// X,Y,Z,ROLL,PITCH,YAW in mm and degrees, R = Rz(yaw)·Ry(pitch)·Rx(roll). Implies --base-frame.
    #[arg(long, value_name = "X,Y,Z,ROLL,PITCH,YAW", allow_hyphen_values = true)]
    pub tool: Option<String>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Replace an existing output file; use a model marked failed by `kinecal identify --force`.
    #[arg(long)]
    pub force: bool,
}

/// Run the command.
pub fn run(a: CompensateArgs) -> anyhow::Result<()> {
    let mut outputs = Outputs::new(a.force);
    outputs.input(Path::new(&a.model)).input(&a.targets);
    if let Some(n) = &a.nominal {
        outputs.input(Path::new(n));
    }
    outputs.output(&a.out)?;
    let file = ModelFile::load_or_builtin(&a.model)?;
    if let Some(p) = file.provenance.as_ref().filter(|p| p.status == "failed") {
        anyhow::ensure!(
            a.force,
            "{}: this model is marked failed ({}); recalibrate, or pass --force to use it anyway",
            a.model,
            p.reasons.first().map_or("see its [provenance]", String::as_str)
        );
    }
    let tool = a.tool.as_deref().map(super::filter::parse_tool).transpose()?;
    let in_base = a.base_frame || tool.is_some();
    let tool = tool.unwrap_or_else(se3::Pose::identity);
    let build = |f: &ModelFile| if in_base { f.build_in_base_frame(&tool) } else { f.build() };
    let model = build(&file);
    let inputs = file.inputs();
    let data = read_data(&a.targets, &file.data_columns(), InputColumns::Optional)?;
    super::warn_limits(&data);
    if let Some(note) = kinecal::io::data_file::si_units_note(&a.targets) {
        eprintln!("note: {note}");
    }
    let targets = target_poses(&data.measurements).map_err(|i| {
        anyhow::anyhow!(
            "{}:{}: a target needs an orientation (qw,qx,qy,qz or roll,pitch,yaw), not only a position",
            a.targets.display(),
            data.lines[i]
        )
    })?;
    let locate = |e: kinecal::compensate::CompensationError, what: &str| {
        anyhow::anyhow!(
            "{}:{}: target {}: {what}{}",
            a.targets.display(),
            data.lines[e.target],
            data.ids[e.target],
            e.source
        )
    };
    let mut seeds: Option<Vec<Vec<f64>>> = data.has_inputs.then(|| data.measurements.iter().map(|m| m.q.clone()).collect());
    if let (None, Some(nominal)) = (&seeds, &a.nominal) {
        let nominal_file = ModelFile::load_or_builtin(nominal)?;
        anyhow::ensure!(
            nominal_file.inputs().iter().map(|i| &i.name).eq(inputs.iter().map(|i| &i.name)),
            "--nominal {nominal}: its inputs differ from those of {}",
            a.model
        );
        let pb = progress::bar(targets.len(), "nominal IK", a.json);
        let q0 = compensate(&*build(&nominal_file), &inputs, &targets, None, &|_| pb.inc(1)).map_err(|e| locate(e, "nominal model: "))?;
        pb.finish_and_clear();
        seeds = Some(q0);
    }
    let pb = progress::bar(targets.len(), "compensating", a.json);
    let commands = compensate(&*model, &inputs, &targets, seeds.as_deref(), &|_| pb.inc(1)).map_err(|e| locate(e, ""))?;
    pb.finish_and_clear();
    let mut header = vec!["id".to_string()];
    header.extend(input_headers(&inputs));
    let rows: Vec<Vec<f64>> = commands
        .iter()
        .zip(&data.ids)
        .map(|(q, id)| std::iter::once(*id as f64).chain(input_values_for_file(&inputs, q)).collect())
        .collect();
    outputs.stage(&a.out, csv_text(&header, &rows).as_bytes())?;
    outputs.commit()?;
    // A 5-DOF machine matches position and tool axis; the rotation about the axis follows from its
    // constraints. Say how far it is from the targets' (the whole rotation error, the axis being met).
    // What the commands cannot reach: the worst position and rotation left between each target
    // and the pose its command reaches on the model (zero but for round-off on a 6-DOF machine).
    let (mut left_mm, mut left_deg) = (0.0f64, 0.0f64);
    for (q, t) in commands.iter().zip(&targets) {
        let e = se3::pose_error(t, &model.forward(q)?);
        left_mm = left_mm.max(se3::lin(&e).norm());
        left_deg = left_deg.max(se3::ang(&e).norm().to_degrees());
    }
    let parasitic_deg = (model.task() == Task::PositionAndAxis).then_some(left_deg);
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({"model": file.name, "targets": a.targets,
                "commands": a.out, "count": commands.len(), "columns": header,
                "commanded": match model.task() { Task::Full => "pose", Task::PositionAndAxis => "position and tool axis", Task::Position => "position", Task::HeightAndAxis => "height and tool axis", Task::PositionAndYaw => "position and yaw" },
                "rotation_about_tool_axis_max_deg": parasitic_deg, "parasitic_max_mm": left_mm, "parasitic_max_deg": left_deg}))?
        );
    } else {
        println!(
            "{} targets → {} commands for {} → {}",
            targets.len(),
            commands.len(),
            file.name,
            a.out.display()
        );
        let name = &file.name;
        let left = format!("up to {left_mm:.4} mm and {left_deg:.4} deg from the targets'");
        match model.task() {
            Task::Full => {}
            Task::PositionAndAxis => println!(
                "{name} is a 5-DOF machine: the commands reach each target's position and tool axis (< 1e-6 mm, < 1e-8 rad); the rotation about the tool axis is a parasitic motion it cannot command (up to {left_deg:.4} deg from the targets')"
            ),
            Task::HeightAndAxis => println!(
                "{name} commands its height and tool axis: the commands reach each target's z and tool axis; x, y and the rotation about the axis are parasitic motions it cannot command ({left}): judge its test poses by AP_z and the axis, not by AP_P"
            ),
            Task::Position => println!(
                "{name} commands the tool position: the commands reach each target's position; the orientation follows from its constraints ({left})"
            ),
            Task::PositionAndYaw => println!(
                "{name} commands the tool position and yaw: the commands reach each target's position and yaw; the tilts follow from its constraints ({left})"
            ),
        }
    }
    Ok(())
}
