//! `kinecal quickstart`: a complete calibration of the built-in 5-DOF parallel machine in one
//! command. It runs the same `kinecal` command lines a user would type (each is printed before it
//! runs), so its output is the tutorial: export the model, plan the measurement configurations,
//! measure a virtual prototype there, identify, validate, compensate — then it checks the
//! compensated commands on the virtual prototype itself.
use clap::Args;
use kinecal::compensate::target_poses;
use kinecal::io::data_file::{read_data, read_inputs, InputColumns};
use kinecal::io::model_file::ModelFile;
use kinecal::validate::commanded_error;
use std::path::{Path, PathBuf};

/// Arguments of `kinecal quickstart`.
#[derive(Args, Debug)]
pub struct QuickstartArgs {
    /// Folder for the files the workflow writes (created if missing).
    #[arg(long, short, default_value = "kinecal-quickstart")]
    pub out: PathBuf,
    /// Seed of the virtual prototype's geometric errors and measurement noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Candidate configurations the planner chooses from.
    #[arg(long, default_value_t = 300_000)]
    pub candidates: usize,
}

/// The command lines of the quickstart, with paths under `dir`. The quickstart owns its
/// directory: the steps that write files pass `--force`, so a second run replaces the first's.
pub fn command_lines(dir: &Path, seed: u64, candidates: usize) -> Vec<Vec<String>> {
    let mut lines = steps(dir, seed, candidates);
    for line in &mut lines {
        if ["model", "plan", "simulate", "identify", "compensate"].contains(&line[0].as_str()) {
            line.push("--force".into());
        }
    }
    lines
}

fn steps(dir: &Path, seed: u64, candidates: usize) -> Vec<Vec<String>> {
    let p = |f: &str| dir.join(f).display().to_string();
    vec![
        vec!["model".into(), "export".into(), "pm5".into(), "--out".into(), p("pm5.toml")],
        vec![
            "plan".into(),
            "--model".into(),
            p("pm5.toml"),
            "--candidates".into(),
            candidates.to_string(),
            "-n".into(),
            "30".into(),
            "--method".into(),
            "sffs".into(),
            "--output".into(),
            p("plan.csv"),
        ],
        vec![
            "simulate".into(),
            p("pm5.toml"),
            "--at".into(),
            p("plan.csv"),
            "--seed".into(),
            seed.to_string(),
            "--error-mm".into(),
            "0.2".into(),
            "--error-deg".into(),
            "0.02".into(),
            "--noise-mm".into(),
            "0.02".into(),
            "--noise-deg".into(),
            "0.02".into(),
            "--out".into(),
            p("measurements.csv"),
            "--truth".into(),
            p("truth.toml"),
            "--validation-poses".into(),
            "20".into(),
            "--validation-out".into(),
            p("validation.csv"),
        ],
        vec!["identifiability".into(), p("pm5.toml"), p("measurements.csv")],
        vec![
            "identify".into(),
            p("pm5.toml"),
            p("measurements.csv"),
            "--frames".into(),
            "model".into(),
            "--validation".into(),
            p("validation.csv"),
            "--noise-mm".into(),
            "0.02".into(),
            "--noise-deg".into(),
            "0.02".into(),
            "--out".into(),
            p("calibrated.toml"),
            "--report".into(),
            p("report.html"),
        ],
        vec!["validate".into(), p("calibrated.toml"), p("validation.csv")],
        vec![
            "compensate".into(),
            p("calibrated.toml"),
            p("validation.csv"),
            "--nominal".into(),
            p("pm5.toml"),
            "--out".into(),
            p("commands.csv"),
        ],
    ]
}

/// Run the quickstart; `run_line` runs one `kinecal` command line (without the program name).
pub fn run(a: QuickstartArgs, run_line: fn(&[String]) -> anyhow::Result<()>) -> anyhow::Result<()> {
    std::fs::create_dir_all(&a.out).map_err(|e| anyhow::anyhow!("{}: cannot create: {e}", a.out.display()))?;
    println!("kinecal quickstart: a complete calibration of the built-in 5-DOF PUU-2PR(RPRR)S machine (pm5)");
    println!("files go to {}/", a.out.display());
    for line in command_lines(&a.out, a.seed, a.candidates) {
        println!();
        println!("$ kinecal {}", line.join(" "));
        run_line(&line)?;
    }
    // The proof of compensation: drive the virtual prototype (the truth) with the commands.
    println!();
    println!("check: the virtual prototype (truth.toml) driven to the validation targets");
    let truth_file = ModelFile::load(&a.out.join("truth.toml"))?;
    let truth = truth_file.build();
    let inputs = truth_file.inputs();
    let nominal = ModelFile::load(&a.out.join("pm5.toml"))?.build();
    let targets_set = read_data(&a.out.join("validation.csv"), &inputs, InputColumns::Required)?;
    let targets = target_poses(&targets_set.measurements).map_err(|i| anyhow::anyhow!("validation.csv: pose {i} is not a full pose"))?;
    let (_, commands) = read_inputs(&a.out.join("commands.csv"), &inputs)?;
    anyhow::ensure!(
        commands.len() == targets.len(),
        "commands.csv: {} rows for {} targets",
        commands.len(),
        targets.len()
    );
    let task = truth.task();
    let mut before = (0.0f64, 0.0f64);
    let mut after = (0.0f64, 0.0f64);
    for (t, cmd) in targets.iter().zip(&commands) {
        // What the uncalibrated controller would send: the nominal model's inverse kinematics.
        let q_nominal = nominal.inverse(t, None)?;
        let b = commanded_error(task, t, &truth.forward(&q_nominal)?);
        let c = commanded_error(task, t, &truth.forward(cmd)?);
        before = (before.0.max(b.0), before.1.max(b.1));
        after = (after.0.max(c.0), after.1.max(c.1));
    }
    println!(
        "  nominal commands:     max position error {:.4} mm, max tool-axis error {:.4} deg",
        before.0,
        before.1.to_degrees()
    );
    println!(
        "  compensated commands: max position error {:.4} mm, max tool-axis error {:.4} deg",
        after.0,
        after.1.to_degrees()
    );
    println!("  (the targets are the validation measurements, so they include the 20 µm / 0.02° measurement noise)");
    println!();
    println!("report: {}", a.out.join("report.html").display());
    Ok(())
}
