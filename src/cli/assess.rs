//! `kinecal assess --commanded C ATTAINED [AFTER]`: ISO 9283 pose accuracy and repeatability
//! (and distance accuracy) of measured test runs, before and after calibration side by side.
use anyhow::Context;
use clap::Args;
use kinecal::assess::{iso9283, AssessError, Iso9283};
use kinecal::io::test_poses::{read_attained, read_commanded};
use std::path::{Path, PathBuf};

/// Arguments of `kinecal assess`.
#[derive(Args, Debug)]
pub struct AssessArgs {
    /// The commanded test poses (CSV: pose,x_mm,y_mm,z_mm[,roll_deg,pitch_deg,yaw_deg]).
    #[arg(long)]
    pub commanded: PathBuf,
    /// The attained poses, measured (CSV: pose,cycle,x_mm,y_mm,z_mm[,roll_deg,pitch_deg,yaw_deg]),
    /// in the same frame as the commanded ones.
    pub attained: PathBuf,
    /// A second test run (e.g. with compensated commands), assessed beside the first.
    pub after: Option<PathBuf>,
    /// Distance accuracy between two test poses, `FROM:TO` (e.g. `2:4`); repeatable.
    #[arg(long, value_name = "FROM:TO")]
    pub distance: Vec<String>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The figures of one attained file, its mistakes named with the file and line.
fn assess_file(commanded: &[kinecal::assess::TestPose], path: &Path, distances: &[(i64, i64)]) -> anyhow::Result<Iso9283> {
    let attained = read_attained(path)?;
    iso9283(commanded, &attained, distances).map_err(|e| match e {
        AssessError::UnknownPose { pose, line, known } => anyhow::anyhow!(
            "{}:{line}: test pose {pose} is not among the commanded poses ({known}): check the pose column or the commanded file",
            path.display()
        ),
        e => anyhow::anyhow!("{}: {e}", path.display()),
    })
}

/// Run the command.
pub fn run(a: AssessArgs) -> anyhow::Result<()> {
    let distances = a
        .distance
        .iter()
        .map(|d| {
            let (f, t) = d.split_once(':').context(format!("--distance '{d}': expected FROM:TO, e.g. 2:4"))?;
            Ok((f.trim().parse::<i64>()?, t.trim().parse::<i64>()?))
        })
        .collect::<anyhow::Result<Vec<_>>>()
        .map_err(|e: anyhow::Error| anyhow::anyhow!("{e:#}"))?;
    let commanded = read_commanded(&a.commanded)?;
    let runs: Vec<(String, Iso9283)> = std::iter::once(&a.attained)
        .chain(a.after.as_ref())
        .map(|p| Ok((p.display().to_string(), assess_file(&commanded, p, &distances)?)))
        .collect::<anyhow::Result<_>>()?;
    if a.json {
        let v: Vec<_> = runs.iter().map(|(f, r)| serde_json::json!({"attained": f, "iso9283": r})).collect();
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!("ISO 9283 pose characteristics (mm, deg), commanded poses {}", a.commanded.display());
    for (file, r) in &runs {
        println!("\n{file}");
        println!(
            "{:>5} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} {:>24} {:>24}",
            "pose", "cycles", "AP_x", "AP_y", "AP_z", "AP_P", "RP_l", "AP_a,b,c", "RP_a,b,c"
        );
        for p in &r.poses {
            let deg = |v: Option<[f64; 3]>| v.map_or("—".to_string(), |v| format!("{:.4}/{:.4}/{:.4}", v[0], v[1], v[2]));
            println!(
                "{:>5} {:>6} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>24} {:>24}",
                format!("P{}", p.pose),
                p.cycles,
                p.ap_xyz[0],
                p.ap_xyz[1],
                p.ap_xyz[2],
                p.ap_p,
                p.rp_l,
                deg(p.ap_abc),
                deg(p.rp_abc)
            );
        }
        for d in &r.distances {
            println!(
                "distance P{}–P{} ({:.3} mm commanded, {} cycles): AD_P {:.4} (AD_x {:.4}, AD_y {:.4}, AD_z {:.4}), RD_P ±{:.4}",
                d.from, d.to, d.commanded_mm, d.cycles, d.ad_p, d.ad_xyz[0], d.ad_xyz[1], d.ad_xyz[2], d.rd_p
            );
        }
    }
    if let [(b, before), (f, after)] = &runs[..] {
        println!("\nbefore → after (AP_P / RP_l, mm): {b} → {f}");
        for (p, q) in before.poses.iter().zip(&after.poses) {
            println!(
                "P{}: AP_P {:.4} → {:.4}, RP_l {:.4} → {:.4}",
                p.pose, p.ap_p, q.ap_p, p.rp_l, q.rp_l
            );
        }
    }
    Ok(())
}
