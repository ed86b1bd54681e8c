//! ISO 9283 pose accuracy and repeatability before and after calibration, on virtual prototypes
//! of the IRB 120 and the 5-DOF pm5 (docs/assess.md).
//!
//! ```sh
//! cargo run --release --example iso9283 -- [--seed S] [--cycles N] [--repeatability-mm R]
//! ```
//!
//! For each machine: a virtual prototype with random geometric errors (the IRB 120 ±0.5 mm /
//! ±0.1°, pm5 ±0.2 mm / ±0.02°, as `kinecal simulate` and `kinecal quickstart` draw them), 60
//! tracker poses with 20 µm / 0.02° noise, identified with the model's frames (`identify`); the
//! standard's test positions P1–P5 in a cube of the workspace ([`kinecal::assess::test_positions`])
//! at one tool orientation; nominal commands (the nominal model's inverse kinematics) and
//! compensated commands (the calibrated model's, [`kinecal::compensate::compensate`]); `N`
//! cycles of each on the prototype, which repeats to `R` mm per axis
//! ([`kinecal::assess::measure_cycles`]); then [`kinecal::assess::iso9283`] on both runs.
use kinecal::assess::{iso9283, measure_cycles, test_positions, Attained, Iso9283, Repeatability, TestPose};
use kinecal::compensate::compensate;
use kinecal::identify::{identify, Options};
use kinecal::io::builtin;
use kinecal::measure::Noise;
use kinecal::se3::{self, Pose};
use kinecal::simulate::{random_configurations, synthesize, virtual_prototype, Instrument};
use kinecal::Mechanism;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

struct Args {
    seed: u64,
    cycles: usize,
    repeatability_mm: f64,
}

fn args() -> Result<Args, String> {
    let mut a = Args {
        seed: 1,
        cycles: 30,
        repeatability_mm: 0.005,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let value = it.next().ok_or(format!("{flag} needs a value"))?;
        let bad = |e: String| format!("{flag} {value}: {e}");
        match flag.as_str() {
            "--seed" => a.seed = value.parse().map_err(|e: std::num::ParseIntError| bad(e.to_string()))?,
            "--cycles" => a.cycles = value.parse().map_err(|e: std::num::ParseIntError| bad(e.to_string()))?,
            "--repeatability-mm" => a.repeatability_mm = value.parse().map_err(|e: std::num::ParseFloatError| bad(e.to_string()))?,
            _ => return Err(format!("unknown option {flag} (use --seed, --cycles, --repeatability-mm)")),
        }
    }
    if a.cycles < 2 || a.repeatability_mm.is_nan() || a.repeatability_mm <= 0.0 {
        return Err("--cycles must be at least 2 and --repeatability-mm positive".into());
    }
    Ok(a)
}

/// One machine: its built-in name, errors of its prototype, the test box and the tool rotation.
struct Case {
    name: &'static str,
    error_mm: f64,
    error_deg: f64,
    min: Vector3<f64>,
    max: Vector3<f64>,
    /// Inputs at which the nominal model's tool rotation is the test poses' rotation (none: the
    /// base frame's).
    rotation_at: Option<Vec<f64>>,
}

fn case(c: &Case, a: &Args) -> Result<(Iso9283, Iso9283), String> {
    let file = builtin::model_file(c.name).ok_or(format!("no built-in {}", c.name))?;
    let nominal = file.build();
    let inputs = file.inputs();
    let free = file.free_indices().map_err(|e| e.to_string())?;
    let mut rng = ChaCha8Rng::seed_from_u64(a.seed);
    let (truth, _) = virtual_prototype(&nominal, &free, c.error_mm, c.error_deg.to_radians(), &mut rng);
    let noise = Noise {
        position: 0.02,
        orientation: 0.02f64.to_radians(),
        ..Noise::default()
    };
    let qs = random_configurations(&*nominal, &inputs, 60, &mut rng).map_err(|e| e.to_string())?;
    let data = synthesize(&*truth, qs, Instrument::Pose, &noise, &mut rng, &|_| {}).map_err(|e| e.to_string())?;
    let opts = Options {
        noise,
        free: Some(free),
        ..Options::default()
    };
    let calibrated = identify(&nominal, &data.measurements, &opts).map_err(|e| e.to_string())?.model;
    let rotation = match &c.rotation_at {
        Some(q) => nominal.forward(q).map_err(|e| e.to_string())?.rotation,
        None => nalgebra::UnitQuaternion::identity(),
    };
    let (positions, _) = test_positions(&c.min, &c.max);
    let targets: Vec<Pose> = positions.iter().map(|p| Pose::from_parts((*p).into(), rotation)).collect();
    let commanded: Vec<TestPose> = targets
        .iter()
        .enumerate()
        .map(|(k, t)| {
            let [x, y, z] = se3::rpy(&t.rotation);
            TestPose {
                pose: k as i64 + 1,
                position: t.translation.vector,
                angles: Some([x.to_degrees(), y.to_degrees(), z.to_degrees()]),
            }
        })
        .collect();
    let nominal_cmd = compensate(&*nominal, &inputs, &targets, None, &|_| {}).map_err(|e| format!("nominal: {:?}", e.source))?;
    let compensated = compensate(&*calibrated, &inputs, &targets, None, &|_| {}).map_err(|e| format!("calibrated: {:?}", e.source))?;
    let repeat = Repeatability {
        position_mm: a.repeatability_mm,
        orientation_rad: 0.0,
    };
    let exact = Noise {
        position: 0.0,
        orientation: 0.0,
        ..Noise::default()
    };
    let mut run = |commands: Vec<Vec<f64>>| {
        let commands: Vec<(i64, Vec<f64>)> = (1..).zip(commands).collect();
        measure_cycles(&*truth, &commands, a.cycles, &repeat, &exact, &mut rng).map_err(|e| e.to_string())
    };
    let before = run(nominal_cmd)?;
    let after = run(compensated)?;
    let assess = |r: &[Attained]| iso9283(&commanded, r, &[(2, 4)]).map_err(|e| e.to_string());
    Ok((assess(&before)?, assess(&after)?))
}

fn main() -> std::process::ExitCode {
    let a = match args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("iso9283: {e}");
            return std::process::ExitCode::from(1);
        }
    };
    let cases = [
        Case {
            name: "irb120",
            error_mm: 0.5,
            error_deg: 0.1,
            min: Vector3::new(300.0, -150.0, 250.0),
            max: Vector3::new(500.0, 150.0, 550.0),
            rotation_at: Some(vec![0.0, 0.0, 0.0, 0.0, 90f64.to_radians(), 0.0]),
        },
        Case {
            name: "pm5",
            error_mm: 0.2,
            error_deg: 0.02,
            min: Vector3::new(-30.0, -30.0, 370.0),
            max: Vector3::new(30.0, 30.0, 430.0),
            rotation_at: None,
        },
    ];
    println!(
        "ISO 9283 on virtual prototypes: seed {}, {} cycles, repeatability {} mm per axis (Gaussian); AP and RP in mm, AP_a/AP_b in deg",
        a.seed, a.cycles, a.repeatability_mm
    );
    for c in &cases {
        match case(c, &a) {
            Ok((before, after)) => {
                println!("\n{} (test cube {:?} – {:?} mm)", c.name, c.min.as_slice(), c.max.as_slice());
                println!(
                    "{:>4} {:>22} {:>22} {:>22}",
                    "pose", "AP_P before → after", "RP_l before → after", "AP_a, AP_b after"
                );
                for (p, q) in before.poses.iter().zip(&after.poses) {
                    let ab = q.ap_abc.map_or("—".into(), |v| format!("{:+.4}, {:+.4}", v[0], v[1]));
                    println!(
                        "{:>4} {:>10.4} → {:<9.4} {:>10.4} → {:<9.4} {:>22}",
                        format!("P{}", p.pose),
                        p.ap_p,
                        q.ap_p,
                        p.rp_l,
                        q.rp_l,
                        ab
                    );
                }
                let (d0, d1) = (&before.distances[0], &after.distances[0]);
                println!(
                    "P2–P4 ({:.1} mm): AD_P {:+.4} → {:+.4} mm, RD_P ±{:.4} → ±{:.4} mm",
                    d0.commanded_mm, d0.ad_p, d1.ad_p, d0.rd_p, d1.rd_p
                );
            }
            Err(e) => println!("\n{}: {e}", c.name),
        }
    }
    std::process::ExitCode::SUCCESS
}
