//! `kinecal validate MODEL DATA`: error statistics of a model against measurements.
use clap::Args;
use kinecal::io::data_file::{read_data, DataSet, InputColumns, MeasurementFormat};
use kinecal::io::model_file::ModelFile;
use kinecal::model::Task;
use kinecal::validate::{outliers, pose_errors, ErrorStats};
use std::path::{Path, PathBuf};

/// Arguments of `kinecal validate`.
#[derive(Args, Debug)]
pub struct ValidateArgs {
    /// Model file (e.g. the calibrated one) or a built-in name.
    pub model: String,
    /// Measurement data file (CSV); not needed with --predict.
    #[arg(required_unless_present = "predict")]
    pub data: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Seat data: a known distance between two seats, `A:B:MM` (its error is printed); repeat
    /// for more.
    #[arg(long = "seat-distance", value_name = "A:B:MM")]
    pub seat_distances: Vec<kinecal::instrument::SeatDistance>,
    /// The accuracy the calibrated model predicts (its [covariance] carried to each pose) over
    /// GRID: `box` (configurations spread over the workspace box, as `kinecal plan` samples it;
    /// --x-mm/--y-mm/--z-mm narrow it, --points sets how many) or a CSV of configurations (the
    /// model's input columns) or of target poses (solved by the calibrated model). Writes --out.
    #[arg(long, value_name = "GRID", requires = "out")]
    pub predict: Option<String>,
    /// The CSV --predict writes: one row per configuration, predicted tool position (mm), its σ
    /// (mm: RMS 3-D and worst axis), the orientation σ (deg), the inputs (deg / mm).
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Configurations in the workspace box of --predict box (Halton points, seed 1).
    #[arg(long, default_value_t = 500)]
    pub points: usize,
    /// Range of x of --predict box, "MIN,MAX" (mm; measurement frame).
    #[arg(long, allow_hyphen_values = true, value_parser = super::sampling::range)]
    pub x_mm: Option<(f64, f64)>,
    /// Range of y of --predict box (mm).
    #[arg(long, allow_hyphen_values = true, value_parser = super::sampling::range)]
    pub y_mm: Option<(f64, f64)>,
    /// Range of z of --predict box (mm).
    #[arg(long, allow_hyphen_values = true, value_parser = super::sampling::range)]
    pub z_mm: Option<(f64, f64)>,
    /// Replace an existing --out file.
    #[arg(long)]
    pub force: bool,
}

/// Run the command.
pub fn run(a: ValidateArgs) -> anyhow::Result<()> {
    let file = ModelFile::load_or_builtin(&a.model)?;
    if let Some(grid) = &a.predict {
        return predict(&a, &file, grid);
    }
    let data_path = a.data.clone().expect("clap requires DATA without --predict");
    let model = file.build();
    let mut data = read_data(&data_path, &file.data_columns(), InputColumns::Required)?;
    if let Some(u) = data.set_aside_unassembled(&*model)? {
        eprintln!("warning: {}", u.note(&data));
    }
    if let Some(note) = data.derived_note() {
        eprintln!("note: {note}");
    }
    if let Some(note) = data.dropped_note() {
        eprintln!("{note}");
    }
    super::warn_limits(&data);
    if matches!(
        data.format,
        MeasurementFormat::Seat | MeasurementFormat::Distance | MeasurementFormat::Touch
    ) {
        return instrument(&a, &data_path, &file.name, &*model, &data);
    }
    if data.format == MeasurementFormat::Mixed {
        return mixed(&a, &data_path, &file.name, &*model, &data);
    }
    let errors = pose_errors(&*model, &data.measurements).map_err(|e| data.locate(e))?;
    let stats = ErrorStats::of(&errors);
    let flagged = outliers(&*model, &data.measurements, 3.0).map_err(|e| data.locate(e))?;
    let joints = kinecal::validate::observed_joint_errors(&*model, &data.measurements).map_err(|e| data.locate(e))?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({"model": file.name, "data": data_path, "stats": stats,
                "per_pose": errors, "outliers": flagged, "observed_joints": joints}))?
        );
    } else {
        println!(
            "{} on {} ({}): {}",
            file.name,
            data_path.display(),
            super::count(stats.poses, "pose"),
            stats
        );
        if !joints.is_empty() {
            let per: Vec<String> = joints
                .iter()
                .map(|j| format!("{} {:.4} / {:.4} {}", j.name, j.rms, j.max, j.unit))
                .collect();
            println!("observed joints, reading − model RMS / max: {}", per.join(", "));
        }
        if let (Task::PositionAndAxis, Some(m), Some(x)) = (model.task(), stats.tool_axis_mean_deg, stats.tool_axis_max_deg) {
            println!("tool axis (what this 5-DOF machine commands; the rotation about it is parasitic): mean {m:.5} / max {x:.5} deg");
        }
        // The worst first, at most SHOWN of them (--json lists every one).
        const SHOWN: usize = 20;
        let mut worst: Vec<_> = flagged.iter().collect();
        worst.sort_by(|a, b| b.score.total_cmp(&a.score));
        if !worst.is_empty() {
            println!(
                "{} with a residual component beyond 3σ (by chance 1–2 % of poses are); the worst:",
                super::count(worst.len(), "pose")
            );
        }
        for o in worst.iter().take(SHOWN) {
            println!(
                "outlier: pose {} (line {}): {:.4} mm, score {:.1}σ",
                data.ids[o.pose], data.lines[o.pose], o.position_mm, o.score
            );
        }
        if worst.len() > SHOWN {
            println!("… and {} more (all of them with --json)", worst.len() - SHOWN);
        }
    }
    Ok(())
}

/// A file mixing kinds: the tracker rows' errors (the calibrated model's frames are the
/// tracker's), then the instrument rows judged as [`instrument`] judges them.
fn mixed(a: &ValidateArgs, data_path: &Path, name: &str, model: &dyn kinecal::Mechanism, data: &DataSet) -> anyhow::Result<()> {
    let subset = |tracker: bool| -> DataSet {
        let keep: Vec<usize> = (0..data.measurements.len())
            .filter(|&i| data.measurements[i].obs.artifact_point().is_none() == tracker)
            .collect();
        DataSet {
            measurements: keep.iter().map(|&i| data.measurements[i].clone()).collect(),
            lines: keep.iter().map(|&i| data.lines[i]).collect(),
            ids: keep.iter().map(|&i| data.ids[i]).collect(),
            ..data.clone()
        }
    };
    let (tracker, rows) = (subset(true), subset(false));
    let errors = pose_errors(model, &tracker.measurements).map_err(|e| tracker.locate(e))?;
    let stats = ErrorStats::of(&errors);
    if !a.json {
        println!("{name} on {}: {} tracker rows: {}", data_path.display(), stats.poses, stats);
    }
    if rows.measurements.is_empty() {
        return Ok(());
    }
    instrument(a, data_path, name, model, &rows)
}

/// Instrument data: each seat's spread and the known distances' errors, each pivot's (and
/// sphere's) length residuals, each plane's flatness, each datum cube's touches from its placed
/// faces ([`kinecal::instrument::held_out`]).
fn instrument(a: &ValidateArgs, data_path: &Path, name: &str, model: &dyn kinecal::Mechanism, data: &DataSet) -> anyhow::Result<()> {
    let h = kinecal::instrument::held_out(model, &data.measurements, &a.seat_distances).map_err(|e| data.locate(e))?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({"model": name, "data": data_path, "instrument": h}))?
        );
        return Ok(());
    }
    println!(
        "{name} on {} ({} rows, {}):",
        data_path.display(),
        data.measurements.len(),
        data.format.describe()
    );
    for s in &h.seats {
        println!(
            "seat {}: {} rows, spread of the tool points about their mean {:.4} mm RMS, {:.4} mm max",
            s.seat, s.rows, s.rms_mm, s.max_mm
        );
    }
    if let Some(rms) = h.seat_rms_mm() {
        println!("all seats: spread {rms:.4} mm RMS (3-D; 0 if the model were exact)");
    }
    for (x, y, known, e) in &h.distances {
        println!("seats {x}–{y}: {:.4} mm apart, known {known:.4} mm: error {e:+.4} mm", known + e);
    }
    for p in &h.pivots {
        let zero = p.zero_mm.map(|z| format!(" and its zero {z:.4} mm")).unwrap_or_default();
        let what = p.kind.name();
        println!(
            "{what} {}: {} rows, measured − modelled length {:.4} mm RMS, {:.4} mm max ({what}{zero} placed by these rows)",
            p.pivot, p.rows, p.rms_mm, p.max_mm
        );
    }
    for p in &h.planes {
        println!(
            "plane {}: {} rows, probe centres from their best plane {:.4} mm RMS, {:.4} mm max (0 if the model were exact)",
            p.plane, p.rows, p.rms_mm, p.max_mm
        );
    }
    for c in &h.cubes {
        println!(
            "cube {}: {} rows, probe centres from the placed cube's faces {:.4} mm RMS, {:.4} mm max (0 if the model were exact)",
            c.cube, c.rows, c.rms_mm, c.max_mm
        );
    }
    Ok(())
}

/// `--predict GRID`: the predicted accuracy over a workspace box or a file's configurations,
/// written to `--out` ([`kinecal::predict`]).
fn predict(a: &ValidateArgs, file: &ModelFile, grid: &str) -> anyhow::Result<()> {
    use kinecal::design::{CandidateSampling, Points, PoseRanges, Region};
    let out = a.out.as_ref().expect("clap requires --out with --predict");
    let mut outputs = kinecal::io::output::Outputs::new(a.force);
    outputs.input(Path::new(&a.model));
    let configurations = if grid == "box" {
        anyhow::ensure!(a.points > 0, "--points must be at least 1");
        let sampling = CandidateSampling {
            region: Region::Poses(PoseRanges {
                position: [a.x_mm, a.y_mm, a.z_mm],
                angles: [None; 3],
            }),
            points: Points::Halton { n: a.points, seed: 1 },
            max_condition: None,
        };
        kinecal::predict::configurations_in(file, &sampling)?
    } else {
        let path = Path::new(grid);
        outputs.input(path);
        let data = read_data(path, &file.data_columns(), InputColumns::Optional)?;
        kinecal::predict::configurations_of(file, &data).map_err(|e| anyhow::anyhow!("{grid}: {e}"))?
    };
    outputs.output(out)?;
    let acc = kinecal::predict::accuracy_of_file(file, &a.model, &configurations)?;
    let inputs = file.inputs();
    let text = kinecal::predict::csv(&acc, &kinecal::io::data_file::input_headers(&inputs), |q| {
        kinecal::io::data_file::input_values_for_file(&inputs, q)
    });
    outputs.stage(out, text.as_bytes())?;
    outputs.commit()?;
    let (max, rms) = acc.position_summary();
    let omax = acc.poses.iter().map(|p| p.orientation_deg).fold(0.0, f64::max);
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({"model": file.name, "predicted": acc}))?
        );
        return Ok(());
    }
    println!(
        "{}: predicted accuracy at {} (the parameters' covariance carried to each pose): position σ RMS {rms:.4} mm, max {max:.4} mm (RMS 3-D error); orientation σ max {omax:.5} deg",
        file.name,
        super::count(acc.poses.len(), "configuration")
    );
    println!(
        "a measurement there adds its noise: {:.4} mm, {:.5} deg (√3·σ of [noise])",
        acc.noise_position_mm, acc.noise_orientation_deg
    );
    println!("wrote {} (mm, deg)", out.display());
    Ok(())
}
