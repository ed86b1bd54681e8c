//! `kinecal irb120 DATA_DIR`: real-data calibration of an ABB IRB 120 measured by a laser tracker.
use clap::Args;
use kinecal::io::split::SplitRule;
use kinecal::io::tracker;
use kinecal::measure::{self, Noise};
use kinecal::model::irb120;
use kinecal::tracker_calibration::{self, CalibrateOptions, Scheme, SchemeResult, ToolMeasurement};
use kinecal::validate::ErrorStats;
use kinecal::Mechanism;
use serde::Serialize;
use std::path::PathBuf;

/// Arguments of `kinecal irb120`.
#[derive(Args, Debug)]
pub struct Irb120Args {
    /// Folder with joints_deg.csv (idx,q1..q6 in degrees), smr1.csv..smr3.csv (idx,x,y,z in mm,
    /// tracker frame) and optionally base1.csv..base3.csv.
    pub data: PathBuf,
    /// Poses with idx below this identify the model; the others validate it.
    #[arg(long, default_value_t = 500)]
    pub split: i64,
    /// Another split instead of --split: `below:ID`, `even` (even ids identify) or
    /// `random:FRACTION` (with --seed).
    #[arg(long)]
    pub by: Option<String>,
    /// Seed of a random split.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print the tables as JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Position noise σ (mm per axis): the weight of position rows of the frame fits.
    #[arg(long, default_value_t = 0.05)]
    pub sigma_position: f64,
    /// Orientation noise σ (degrees per axis): the weight of orientation rows of the frame fits.
    #[arg(long, default_value_t = 0.03)]
    pub sigma_orientation: f64,
    /// Write an HTML report of the full geometric calibration (row (ii)) to this file: per-pose
    /// errors before (registered nominal geometry) and after, histograms, parameters with
    /// standard deviations, identifiability, outliers.
    #[arg(long, value_name = "FILE.html")]
    pub report: Option<PathBuf>,
}

/// One calibration run of the table.
#[derive(Serialize)]
struct Run {
    label: String,
    fit: &'static str,
    #[serde(flatten)]
    result: SchemeResult,
}

#[derive(Serialize)]
struct Output {
    data: DataSummary,
    runs: Vec<Run>,
    general_path: Vec<tracker_calibration::GeneralRun>,
    unexplained: Unexplained,
}

#[derive(Serialize)]
struct DataSummary {
    folder: String,
    poses: usize,
    identification_poses: usize,
    validation_poses: usize,
    dropped: Vec<(i64, String)>,
    failed_base_readings: usize,
    base_reflector_max_deviation_mm: Vec<f64>,
    tool_reflector_distance_std_mm: f64,
}

/// What geometry cannot explain: validation error of the full frame fit by joint-1 range.
#[derive(Serialize)]
struct Unexplained {
    residual_over_tracker_noise: f64,
    by_q1: Vec<(f64, f64, usize, f64)>,
}

fn fmt_stats(s: &ErrorStats) -> String {
    let rot = match (s.orientation_mean_deg, s.orientation_max_deg) {
        (Some(a), Some(b)) => format!("{a:>7.3} {b:>7.3}"),
        _ => format!("{:>7} {:>7}", "-", "-"),
    };
    format!(
        "{:>7.3} {:>7.3} {:>7.3}  {rot}",
        s.position_mean_mm, s.position_rms_mm, s.position_max_mm
    )
}

/// Standard deviation (mm) of the three inter-reflector distances over all poses, pooled: the
/// tracker's repeatability as seen by a rigid tool.
fn reflector_distance_std(data: &tracker::TrackerData) -> f64 {
    let mut var = 0.0;
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        let d: Vec<f64> = data.tool.iter().map(|m| (m[a] - m[b]).norm()).collect();
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        var += d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / d.len() as f64;
    }
    (var / 3.0).sqrt()
}

/// The identification and validation parts of a split, in words.
fn describe(rule: SplitRule) -> (String, String) {
    match rule {
        SplitRule::IdBelow(v) => (format!("idx < {v}"), format!("idx ≥ {v}")),
        SplitRule::EvenIds => ("even idx".into(), "odd idx".into()),
        SplitRule::Random { fraction, seed } => (
            format!("random {:.0} % (seed {seed})", fraction * 100.0),
            format!("the other {:.0} %", (1.0 - fraction) * 100.0),
        ),
    }
}

/// Run the command.
pub fn run(args: Irb120Args) -> anyhow::Result<()> {
    if !(args.sigma_position > 0.0 && args.sigma_orientation > 0.0) {
        anyhow::bail!(
            "--sigma-position and --sigma-orientation must be positive (got {} mm, {} deg)",
            args.sigma_position,
            args.sigma_orientation
        );
    }
    let data = tracker::read_folder(&args.data, 6)?;
    let nominal = irb120::nominal();
    let rule = match &args.by {
        Some(text) => SplitRule::parse(text, args.seed).map_err(|e| anyhow::anyhow!("--by {e}"))?,
        None => SplitRule::IdBelow(args.split),
    };
    let (split_in, split_out) = describe(rule);
    // The identification ids, chosen the way `kinecal data split` chooses them.
    let all = kinecal::io::split::subset_ids(&data.idx, rule);
    let ident: std::collections::HashSet<i64> = all.into_iter().collect();
    let frame = ToolMeasurement::FullPose;
    let train = tracker_calibration::measurements(&data, frame, |i| ident.contains(&i))?;
    let test = tracker_calibration::measurements(&data, frame, |i| !ident.contains(&i))?;
    if test.is_empty() || train.is_empty() {
        anyhow::bail!(
            "{}: the split {split_in} leaves no pose to identify on or none to validate on",
            args.data.display()
        );
    }
    let points = tracker_calibration::reflector_measurements(&data, |i| ident.contains(&i))?;
    let r1 = ToolMeasurement::Reflector(1);
    let train1 = tracker_calibration::measurements(&data, r1, |i| ident.contains(&i))?;
    let test1 = tracker_calibration::measurements(&data, r1, |i| !ident.contains(&i))?;

    let fixed = CalibrateOptions {
        noise: Noise {
            position: args.sigma_position,
            orientation: args.sigma_orientation.to_radians(),
            ..Noise::default()
        },
        reweight: false,
    };
    let vce = CalibrateOptions {
        reweight: true,
        ..fixed.clone()
    };
    let frame_label = format!("frame, σ {} mm / {}°", args.sigma_position, args.sigma_orientation);
    let mut runs = Vec::new();
    let mut add = |label: &str, fit: &'static str, r: SchemeResult| {
        runs.push(Run {
            label: label.to_string(),
            fit,
            result: r,
        })
    };
    add(
        "(i)  base + tool only",
        "frame",
        tracker_calibration::calibrate(&nominal, &train, &train, &test, frame, Scheme::FramesOnly, &fixed)?,
    );
    add(
        "(ii) full geometric",
        "frame",
        tracker_calibration::calibrate(&nominal, &train, &train, &test, frame, Scheme::Full, &fixed)?,
    );
    add(
        "     base + tool only",
        "3 points",
        tracker_calibration::calibrate(&nominal, &points, &train, &test, frame, Scheme::FramesOnly, &fixed)?,
    );
    add(
        "     full geometric",
        "3 points",
        tracker_calibration::calibrate(&nominal, &points, &train, &test, frame, Scheme::Full, &fixed)?,
    );
    add(
        "     full geometric",
        "frame, σ from residuals",
        tracker_calibration::calibrate(&nominal, &train, &train, &test, frame, Scheme::Full, &vce)?,
    );
    add(
        "     reflector 1: base + tool",
        "position",
        tracker_calibration::calibrate(&nominal, &train1, &train1, &test1, r1, Scheme::FramesOnly, &fixed)?,
    );
    add(
        "     reflector 1: full geometric",
        "position",
        tracker_calibration::calibrate(&nominal, &train1, &train1, &test1, r1, Scheme::Full, &fixed)?,
    );

    // What geometry does not explain: validation errors of (ii) by joint-1 range.
    let full = &runs[1].result.fit.model;
    let mut rows: Vec<(f64, f64)> = Vec::new();
    for m in &test {
        let t = full.forward(&m.q)?;
        rows.push((m.q[0].to_degrees(), measure::errors(&m.obs, &t).0));
    }
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let bins = 4;
    let by_q1: Vec<(f64, f64, usize, f64)> = (0..bins)
        .map(|b| {
            let chunk = &rows[b * rows.len() / bins..(b + 1) * rows.len() / bins];
            let rms = (chunk.iter().map(|r| r.1 * r.1).sum::<f64>() / chunk.len().max(1) as f64).sqrt();
            (
                chunk.first().map_or(0.0, |r| r.0),
                chunk.last().map_or(0.0, |r| r.0),
                chunk.len(),
                rms,
            )
        })
        .collect();
    let noise = reflector_distance_std(&data);
    let unexplained = Unexplained {
        residual_over_tracker_noise: runs[1].result.validation.position_rms_mm / noise,
        by_q1,
    };

    let general = tracker_calibration::general_path(&args.data, rule, fixed.noise)?;

    if let Some(path) = &args.report {
        let r = &runs[1].result;
        let report = kinecal::report::CalibrationReport::new(
            &r.start,
            &r.fit,
            &r.free_params,
            "GaussNewton, frame residual",
            &format!("{} ({split_in})", args.data.display()),
            &train,
            Some((&format!("{} ({split_out})", args.data.display()), &test)),
        )?;
        let html = report.to_html().map_err(|e| anyhow::anyhow!("report: {e}"))?;
        kinecal::io::write_atomic(path, html.as_bytes())?;
        eprintln!("report → {}", path.display());
    }
    let summary = DataSummary {
        folder: args.data.display().to_string(),
        poses: data.len(),
        identification_poses: train.len(),
        validation_poses: test.len(),
        dropped: data.dropped.clone(),
        failed_base_readings: data.failed_base.len(),
        base_reflector_max_deviation_mm: data.base_stability(),
        tool_reflector_distance_std_mm: noise,
    };
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&Output {
                data: summary,
                runs,
                general_path: general,
                unexplained
            })?
        );
        return Ok(());
    }
    println!("ABB IRB 120, laser-tracker data: {}", summary.folder);
    println!(
        "  {} poses kept ({} dropped); identification {split_in}: {}, validation {split_out}: {}",
        summary.poses,
        summary.dropped.len(),
        summary.identification_poses,
        summary.validation_poses
    );
    let dev: Vec<String> = summary.base_reflector_max_deviation_mm.iter().map(|d| format!("{d:.3}")).collect();
    println!(
        "  base reflectors: {} failed readings flagged and ignored; valid ones stay within [{}] mm of their median",
        summary.failed_base_readings,
        dev.join(", ")
    );
    println!("  tracker repeatability (std of the tool-reflector distances): {:.4} mm", noise);
    println!();
    println!("Held-out validation ({split_out}): tool-frame position error (mm), orientation error (deg)");
    println!(
        "{:<34} {:<24} {:>6} {:>7} {:>7} {:>7}  {:>7} {:>7} {:>5} {:>8}",
        "scheme", "fitted residual", "params", "mean", "RMS", "max", "mean°", "max°", "iter", "time"
    );
    for r in &runs {
        let fit = if r.fit == "frame" { frame_label.clone() } else { r.fit.to_string() };
        println!(
            "{:<34} {:<24} {:>6} {}  {:>5} {:>6.1}ms",
            r.label,
            fit,
            format!("{}/{}", r.result.identified, r.result.free),
            fmt_stats(&r.result.validation),
            r.result.iterations,
            r.result.seconds * 1e3
        );
    }
    println!();
    println!("Identification poses ({split_in}), same order and columns:");
    for r in &runs {
        println!("{:<34} {:<24} {:>6} {}", r.label, r.fit, "", fmt_stats(&r.result.identification));
    }
    println!();
    println!("The same data through the general path (data join → data split → identify, frames estimated, {frame_label}):");
    // The pipeline rows they correspond to: (ii) frame, 3 points full, reflector 1 full.
    for (g, k) in general.iter().zip([1, 3, 6]) {
        let v = g.validation.position_rms_mm;
        let p = runs[k].result.validation.position_rms_mm;
        println!(
            "  {:<12} held-out RMS {:.4} mm (pipeline above {:.4} mm, {:+.2} %), mean {:.4}, max {:.4} mm, {}/{} params, {} iterations, {:.0} ms, {}",
            g.fit,
            v,
            p,
            100.0 * (v - p) / p,
            g.validation.position_mean_mm,
            g.validation.position_max_mm,
            g.identified,
            g.free,
            g.iterations,
            g.seconds * 1e3,
            g.status
        );
    }
    println!();
    println!(
        "What geometry does not explain: after (ii) the held-out RMS is {:.0}× the tracker repeatability; by joint 1:",
        unexplained.residual_over_tracker_noise
    );
    for (lo, hi, n, rms) in &unexplained.by_q1 {
        println!("  q1 in [{lo:>7.1}°, {hi:>7.1}°]  {n:>4} poses  RMS {rms:.3} mm");
    }
    Ok(())
}
