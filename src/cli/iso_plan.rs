//! `kinecal plan --iso9283`: the ISO 9283 test poses P1–P5 in the model's workspace, checked
//! reachable, written as one file that `assess --commanded`, `simulate --at … --cycles N` and
//! `compensate` read. One call, [`kinecal::assess::iso9283_commands`]; this module parses and
//! prints. The test poses are written once: the `N` cycles are the robot program's loop over them
//! (`simulate --cycles N` on a virtual prototype), since `assess` takes each commanded pose once.
use super::plan::PlanArgs;
use clap::Args;
use kinecal::assess::{iso9283_commands, CubeRequest};
use kinecal::io::{model_file::ModelFile, output::Outputs, test_poses::test_poses_text};
use nalgebra::Vector3;

/// The arguments of `kinecal plan --iso9283` (the region is `--x-mm`, `--y-mm`, `--z-mm`, the
/// seed `--seed`, the file `--output`).
#[derive(Args, Debug)]
pub struct IsoArgs {
    /// Place the ISO 9283 test poses P1–P5 (largest reachable cube in the workspace, or in the box
    /// --x-mm/--y-mm/--z-mm) and write them with their commands, instead of planning identification poses.
    #[arg(long)]
    pub iso9283: bool,
    /// Tool orientation of the test poses, "ROLL,PITCH,YAW" about the base x, y, z (degrees); default:
    /// the tool's at the middle of the input ranges.
    #[arg(long, requires = "iso9283", allow_hyphen_values = true, value_parser = angles)]
    pub orientation_deg: Option<[f64; 3]>,
    /// Reachability grid points along the longest edge of the region searched.
    #[arg(long, requires = "iso9283", default_value_t = 10)]
    pub cube_grid: usize,
    /// Configurations sampled to bound the region and seed the inverse kinematics.
    #[arg(long, requires = "iso9283", default_value_t = 500)]
    pub cube_samples: usize,
}

/// "ROLL,PITCH,YAW".
fn angles(text: &str) -> Result<[f64; 3], String> {
    let v: Result<Vec<f64>, _> = text.split(',').map(|t| t.trim().parse::<f64>()).collect();
    match v.as_deref() {
        Ok(&[a, b, c]) if [a, b, c].iter().all(|x| x.is_finite()) => Ok([a, b, c]),
        _ => Err(format!("expected ROLL,PITCH,YAW in degrees, got '{text}'")),
    }
}

/// Run `kinecal plan --iso9283`.
pub fn run(args: &PlanArgs, file: ModelFile) -> anyhow::Result<()> {
    let (iso, s) = (&args.iso, &args.sampling);
    let region = match (s.x_mm, s.y_mm, s.z_mm) {
        (None, None, None) => None,
        (Some(x), Some(y), Some(z)) => Some((Vector3::new(x.0, y.0, z.0), Vector3::new(x.1, y.1, z.1))),
        _ => anyhow::bail!("--iso9283: give all three of --x-mm, --y-mm, --z-mm (MIN,MAX), or none"),
    };
    let request = CubeRequest {
        region,
        rotation: iso
            .orientation_deg
            .map(|[r, p, y]| nalgebra::UnitQuaternion::from_euler_angles(r.to_radians(), p.to_radians(), y.to_radians())),
        grid: iso.cube_grid,
        samples: iso.cube_samples,
        seed: s.seed,
    };
    let mut outputs = Outputs::new(args.force);
    if let Some(m) = &args.model {
        outputs.input(std::path::Path::new(m));
    }
    outputs.output(&args.output)?;
    let inputs = file.inputs();
    let plan = iso9283_commands(&*file.build(), &inputs, &request).map_err(|e| anyhow::anyhow!("{}: {e}", file.name))?;
    outputs.stage(&args.output, test_poses_text(&plan, &inputs).as_bytes())?;
    outputs.commit()?;
    let (lo, hi) = plan.region;
    let c = plan.cube_min;
    if args.json {
        let poses: Vec<_> = plan
            .poses
            .iter()
            .zip(&plan.commands)
            .map(|(p, q)| serde_json::json!({"pose": p.pose, "position_mm": p.position.as_slice(), "angles_deg": p.angles, "inputs": q}))
            .collect();
        let v = serde_json::json!({"model": file.name, "region_mm": [lo.as_slice(), hi.as_slice()],
            "cube_min_mm": c.as_slice(), "side_mm": plan.side, "grid_reachable": plan.reachable.0,
            "grid_points": plan.reachable.1, "poses": poses, "output": args.output});
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    let v3 = |v: &Vector3<f64>| format!("({:.1}, {:.1}, {:.1})", v.x, v.y, v.z);
    println!(
        "{}: region {} – {} mm, {} of {} grid points reachable at the test orientation",
        file.name,
        v3(&lo),
        v3(&hi),
        plan.reachable.0,
        plan.reachable.1
    );
    println!("ISO 9283 cube: side {:.2} mm from C1 {} mm", plan.side, v3(&c));
    for p in &plan.poses {
        let a = p.angles.unwrap_or_default();
        println!(
            "P{}: ({:.3}, {:.3}, {:.3}) mm, roll/pitch/yaw ({:.3}, {:.3}, {:.3}) deg: reachable",
            p.pose, p.position.x, p.position.y, p.position.z, a[0], a[1], a[2]
        );
    }
    println!(
        "wrote {} (test poses and the model's commands; assess --commanded, simulate --at … --cycles N, compensate read it)",
        args.output.display()
    );
    Ok(())
}
