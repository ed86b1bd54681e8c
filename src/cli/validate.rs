//! `kinecal validate MODEL DATA`: error statistics of a model against measurements.
use clap::Args;
use kinecal::io::data_file::{read_data, DataSet, InputColumns, MeasurementFormat};
use kinecal::io::model_file::ModelFile;
use kinecal::model::Task;
use kinecal::validate::{outliers, pose_errors, ErrorStats};
use std::path::PathBuf;

/// Arguments of `kinecal validate`.
#[derive(Args, Debug)]
pub struct ValidateArgs {
    /// Model file (e.g. the calibrated one) or a built-in name.
    pub model: String,
    /// Measurement data file (CSV).
    pub data: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Seat data: a known distance between two seats, `A:B:MM` (its error is printed); repeat
    /// for more.
    #[arg(long = "seat-distance", value_name = "A:B:MM")]
    pub seat_distances: Vec<kinecal::instrument::SeatDistance>,
}

/// Run the command.
pub fn run(a: ValidateArgs) -> anyhow::Result<()> {
    let file = ModelFile::load_or_builtin(&a.model)?;
    let model = file.build();
    let mut data = read_data(&a.data, &file.data_columns(), InputColumns::Required)?;
    super::check_units(&file, &data, true)?;
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
        return instrument(&a, &file.name, &*model, &data);
    }
    if data.format == MeasurementFormat::Mixed {
        return mixed(&a, &file.name, &*model, &data);
    }
    let errors = pose_errors(&*model, &data.measurements).map_err(|e| data.locate(e))?;
    let stats = ErrorStats::of(&errors);
    let flagged = outliers(&*model, &data.measurements, 3.0).map_err(|e| data.locate(e))?;
    let joints = kinecal::validate::observed_joint_errors(&*model, &data.measurements).map_err(|e| data.locate(e))?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({"model": file.name, "data": a.data, "stats": stats,
                "per_pose": errors, "outliers": flagged, "observed_joints": joints}))?
        );
    } else {
        println!(
            "{} on {} ({}): {}",
            file.name,
            a.data.display(),
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
fn mixed(a: &ValidateArgs, name: &str, model: &dyn kinecal::Mechanism, data: &DataSet) -> anyhow::Result<()> {
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
        println!("{name} on {}: {} tracker rows: {}", a.data.display(), stats.poses, stats);
    }
    if rows.measurements.is_empty() {
        return Ok(());
    }
    instrument(a, name, model, &rows)
}

/// Instrument data: each seat's spread and the known distances' errors, each pivot's (and
/// sphere's) length residuals, each plane's flatness, each datum cube's touches from its placed
/// faces ([`kinecal::instrument::held_out`]).
fn instrument(a: &ValidateArgs, name: &str, model: &dyn kinecal::Mechanism, data: &DataSet) -> anyhow::Result<()> {
    let h = kinecal::instrument::held_out(model, &data.measurements, &a.seat_distances).map_err(|e| data.locate(e))?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({"model": name, "data": a.data, "instrument": h}))?
        );
        return Ok(());
    }
    println!(
        "{name} on {} ({} rows, {}):",
        a.data.display(),
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
