//! `kinecal filter CAL PROGRAM --nominal NOMINAL --out OUT`: a program's targets corrected for a
//! controller that keeps its nominal kinematics.
use clap::Args;
use kinecal::filter::{filter_program, FilterModels, FilterOptions, Format};
use kinecal::io::model_file::ModelFile;
use kinecal::io::output::Outputs;
use std::path::{Path, PathBuf};

/// Arguments of `kinecal filter`.
#[derive(Args, Debug)]
pub struct FilterArgs {
    /// Calibrated model file.
    pub calibrated: String,
    /// The program: CSV targets (.csv), an ABB RAPID module (.mod, .modx, .prg), a KUKA KRL
    /// program (.src; its .dat beside it is filtered too and written beside OUT), URScript
    /// (.script, .urscript) or G-code (.nc, .ngc, .gcode: G0/G1 X Y Z, and A B about x then y
    /// where the machine commands its tool axis).
    pub program: PathBuf,
    /// The nominal model the controller computes with (file or built-in name).
    #[arg(long)]
    pub nominal: String,
    /// The filtered program to write (never one of the inputs).
    #[arg(long, short)]
    pub out: PathBuf,
    /// The program's format when its extension does not say: csv, rapid, urscript, krl or gcode.
    #[arg(long)]
    pub format: Option<Format>,
    /// CSV targets: the tool they are given for, in the flange (the mechanism's tool frame):
    /// X,Y,Z,ROLL,PITCH,YAW in mm and degrees, R = Rz(yaw)·Ry(pitch)·Rx(roll). Default: the flange.
    #[arg(long, value_name = "X,Y,Z,ROLL,PITCH,YAW", allow_hyphen_values = true)]
    pub tool: Option<String>,
    /// KRL: a TOOL_DATA[N] the program's files do not assign, N=X,Y,Z,A,B,C (mm; A, B, C about
    /// Z, Y', X'' in degrees), in the flange frame; repeat for several.
    #[arg(long, value_name = "N=X,Y,Z,A,B,C", allow_hyphen_values = true)]
    pub tool_data: Vec<String>,
    /// KRL: a BASE_DATA[N] the program's files do not assign, N=X,Y,Z,A,B,C, in the robot's base
    /// frame; repeat for several.
    #[arg(long, value_name = "N=X,Y,Z,A,B,C", allow_hyphen_values = true)]
    pub base_data: Vec<String>,
    /// G-code and CSV targets: split each straight move so that the machine, driven by the
    /// nominal controller between the corrected points, stays within this distance (mm) of the
    /// commanded line (judged on the calibrated model); G-code arcs are linearised within it
    /// (half for the chords). Without it nothing is split, the largest deviation is printed and
    /// arcs are linearised within 0.01 mm.
    #[arg(long, value_name = "MM")]
    pub max_deviation_mm: Option<f64>,
    /// Correct joint targets too (URScript joint lists `movej([…])`): taught on the nominal
    /// controller, they name the pose FK_nominal(q) of the tool in effect; written as the
    /// calibrated model's joint values for that pose on the same branch. Without it they are left
    /// as they are, with a note.
    #[arg(long)]
    pub joints: bool,
    /// Replace an existing output; leave targets that cannot be corrected as they are (listed)
    /// instead of writing nothing; use a model marked failed.
    #[arg(long)]
    pub force: bool,
    /// Print the predicted error at each target before and after.
    #[arg(long)]
    pub report: bool,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// A tool given as `X,Y,Z,ROLL,PITCH,YAW` (mm, degrees).
pub fn parse_tool(s: &str) -> anyhow::Result<kinecal::se3::Pose> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<Vec<_>>>()
        .filter(|v| v.len() == 6)
        .ok_or_else(|| anyhow::anyhow!("--tool '{s}': expected six numbers X,Y,Z,ROLL,PITCH,YAW (mm, degrees)"))?;
    Ok(kinecal::se3::Pose::from_parts(
        nalgebra::Translation3::new(v[0], v[1], v[2]),
        nalgebra::UnitQuaternion::from_euler_angles(v[3].to_radians(), v[4].to_radians(), v[5].to_radians()),
    ))
}

/// `N=X,Y,Z,A,B,C` (KUKA: mm, degrees about Z, Y', X'').
fn parse_indexed(option: &str, s: &str) -> anyhow::Result<(u32, kinecal::se3::Pose)> {
    let bad = || anyhow::anyhow!("{option} '{s}': expected N=X,Y,Z,A,B,C (an index, mm, degrees)");
    let (n, rest) = s.split_once('=').ok_or_else(bad)?;
    let n: u32 = n.trim().parse().map_err(|_| bad())?;
    let v: Vec<f64> = rest
        .split(',')
        .map(|x| x.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<Vec<_>>>()
        .filter(|v| v.len() == 6)
        .ok_or_else(bad)?;
    // A, B, C = yaw, pitch, roll.
    Ok((n, parse_tool(&format!("{},{},{},{},{},{}", v[0], v[1], v[2], v[5], v[4], v[3]))?))
}

/// Run the command.
pub fn run(a: FilterArgs) -> anyhow::Result<()> {
    let mut outputs = Outputs::new(a.force);
    outputs
        .input(Path::new(&a.calibrated))
        .input(&a.program)
        .input(Path::new(&a.nominal));
    outputs.output(&a.out)?;
    let format = match a.format {
        Some(f) => f,
        None => Format::from_path(&a.program).ok_or_else(|| {
            anyhow::anyhow!(
                "{}: unknown program format (extension .csv, .mod, .modx, .prg, .src, .script, .urscript, .nc, .ngc or .gcode, or --format csv|rapid|krl|urscript|gcode)",
                a.program.display()
            )
        })?,
    };
    // A KRL program's .dat beside it is read and written beside the output.
    let dat = (format == Format::Krl)
        .then(|| a.program.with_extension("dat"))
        .filter(|p| p.exists());
    let dat_out = dat.as_ref().map(|_| a.out.with_extension("dat"));
    let mut outputs = Outputs::new(a.force);
    outputs
        .input(Path::new(&a.calibrated))
        .input(&a.program)
        .input(Path::new(&a.nominal));
    if let Some(d) = &dat {
        outputs.input(d);
    }
    outputs.output(&a.out)?;
    outputs.output_opt(dat_out.as_deref())?;
    let cal = ModelFile::load_or_builtin(&a.calibrated)?;
    if let Some(p) = cal.provenance.as_ref().filter(|p| p.status == "failed") {
        anyhow::ensure!(
            a.force,
            "{}: this model is marked failed ({}); recalibrate, or pass --force to use it anyway",
            a.calibrated,
            p.reasons.first().map_or("see its [provenance]", String::as_str)
        );
    }
    let nominal = ModelFile::load_or_builtin(&a.nominal)?;
    let models = FilterModels::new(&cal, &nominal)?;
    let mut opts = FilterOptions {
        force: a.force,
        max_deviation_mm: a.max_deviation_mm,
        joints: a.joints,
        ..FilterOptions::default()
    };
    if let Some(t) = &a.tool {
        opts.tool = parse_tool(t)?;
    }
    for t in &a.tool_data {
        opts.tool_data.push(parse_indexed("--tool-data", t)?);
    }
    for t in &a.base_data {
        opts.base_data.push(parse_indexed("--base-data", t)?);
    }
    let text = kinecal::io::read_text(&a.program)?;
    let dat_text = dat.as_deref().map(kinecal::io::read_text).transpose()?;
    let companion = dat.as_deref().zip(dat_text.as_deref());
    let filtered = filter_program(&a.program, &text, companion, format, &models, &opts)?;
    outputs.stage(&a.out, filtered.text.as_bytes())?;
    if let (Some(p), Some(t)) = (&dat_out, &filtered.companion) {
        outputs.stage(p, t.as_bytes())?;
    }
    outputs.commit()?;
    let worst = |f: fn(&kinecal::filter::TargetReport) -> f64| filtered.targets.iter().map(f).fold(0.0f64, f64::max);
    let (before_mm, before_deg) = (worst(|t| t.before_mm), worst(|t| t.before_deg));
    let (after_mm, after_deg) = (worst(|t| t.after_mm), worst(|t| t.after_deg));
    let (shift_mm, shift_deg) = (worst(|t| t.shift_mm), worst(|t| t.shift_deg));
    if a.json {
        let mut j = serde_json::json!({"program": a.program, "out": a.out, "format": format,
            "corrected": filtered.targets.len(), "uncorrected": filtered.uncorrected, "notes": filtered.notes,
            "worst_before_mm": before_mm, "worst_before_deg": before_deg, "worst_after_mm": after_mm,
            "worst_after_deg": after_deg, "largest_shift_mm": shift_mm, "largest_shift_deg": shift_deg,
            "paths": filtered.paths});
        if a.report {
            j["targets"] = serde_json::to_value(&filtered.targets)?;
        }
        println!("{}", serde_json::to_string_pretty(&j)?);
        return Ok(());
    }
    println!(
        "{} targets of {} corrected for {} → {}",
        filtered.targets.len(),
        a.program.display(),
        nominal.name,
        a.out.display()
    );
    println!("predicted error at the targets (calibrated model): before max {before_mm:.4} mm / {before_deg:.4} deg, after max {after_mm:.4} mm / {after_deg:.4} deg; targets moved by up to {shift_mm:.4} mm / {shift_deg:.4} deg");
    if let Some(p) = &filtered.paths {
        if p.arcs > 0 {
            println!(
                "{} arcs linearised into {} chords, within {:.4} mm of the arcs",
                p.arcs, p.arc_chords, p.largest_chord_error_mm
            );
        }
        match a.max_deviation_mm {
            Some(d) => println!(
                "{} points added to hold {d} mm on {} straight moves: largest deviation of the machine's path from the commanded line {:.4} mm (line {})",
                p.added_points, p.moves, p.largest_deviation_mm, p.largest_deviation_line
            ),
            None if p.moves > 0 => println!(
                "largest deviation expected between points (the machine's path from the commanded line, on the calibrated model): {:.4} mm (line {}), over {} straight moves; --max-deviation-mm splits them",
                p.largest_deviation_mm, p.largest_deviation_line, p.moves
            ),
            None => {}
        }
        if p.unjudged > 0 {
            println!(
                "{} moves not judged: the nominal controller's inverse kinematics does not follow a straight line between their targets",
                p.unjudged
            );
        }
    }
    for n in &filtered.notes {
        println!("note: {n}");
    }
    for u in &filtered.uncorrected {
        println!("not corrected (left as it was): {u}");
    }
    if a.report {
        println!(
            "{:>6} {:<28} {:>10} {:>10} {:>10} {:>10}",
            "line", "target", "before_mm", "before_deg", "after_mm", "after_deg"
        );
        for t in &filtered.targets {
            println!(
                "{:>6} {:<28} {:>10.4} {:>10.4} {:>10.6} {:>10.6}",
                t.line, t.name, t.before_mm, t.before_deg, t.after_mm, t.after_deg
            );
        }
    }
    Ok(())
}
