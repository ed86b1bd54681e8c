//! Seat calibrations of arms kinecal was not tuned on, from the real Panda's configurations.
//!
//! The real data (`mukca-panda`: a ball guided into two sockets 50 mm apart at nine places on
//! a table, about 30 configurations per socket) give realistic sockets and orientations. Each
//! arm below is a virtual prototype (random geometric errors on its free parameters) driven to
//! the same sockets: a 7-joint arm moves from each real configuration to its socket (position
//! inverse kinematics started there), a 6-joint arm takes each real row's tool orientation at
//! the socket (full inverse kinematics). Arms:
//!
//! - `7-joint, on axis`: the Panda's geometry changed (longer upper arm and forearm, wider
//!   elbow offset), the ball exactly on the last joint's axis, 30 mm out;
//! - `7-joint, 0.7 mm off`: the same with the ball 0.7 mm off that axis;
//! - `6-joint, 0.7 mm off`: a UR5e from its URDF, the ball 0.7 mm off the last axis.
//!
//! Each is calibrated through `calibrate()` with default options (the known 50 mm between the
//! two sockets of a placement) one-to-many (one placement identifies, every other judges) and
//! all-but-one (each placement held out in turn), the held-out placements given as the
//! validation data (as `identify --validation` does). Held-out figure: each socket's spread of the
//! calibrated model's ball points about their own fitted centre (what `kinecal validate` prints
//! for seats), RMS over the held-out placements, against the nominal model's.
//!
//! ```text
//! cargo run --release --example unseen_arms -- /path/to/mukca-panda/panda_2 [noise_mm] [seed]
//! ```
//! With `noise_mm` 0 the data are exact and the stated noise is 1 nm.
use kinecal::calibrate::{calibrate, CalibrationOptions};
use kinecal::instrument::{held_out, SeatDistance};
use kinecal::io::data_file::DataSet;
use kinecal::io::model_file::ModelFile;
use kinecal::measure::{Measurement, Noise, Observation};
use kinecal::report::Status;
use kinecal::se3::Pose;
use kinecal::Mechanism;
use nalgebra::{DMatrix, DVector, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::path::{Path, PathBuf};

/// The placements of the real data, in the order of the data's README.
const PLACEMENTS: [&str; 9] = [
    "back_left",
    "back_right",
    "front_center",
    "front_left",
    "front_right",
    "high",
    "mid-high",
    "mid_left",
    "mid_right",
];

/// The real data's configurations: per placement, per socket, the joint angles (rad).
type Configurations = Vec<[Vec<Vec<f64>>; 2]>;

fn read_configurations(dir: &Path) -> Configurations {
    let read = |p: PathBuf| -> Vec<Vec<f64>> {
        std::fs::read_to_string(&p)
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
            .lines()
            .filter(|l| !l.trim().is_empty())
            .map(|l| l.split([',', ' ']).filter(|t| !t.is_empty()).map(|t| t.parse().unwrap()).collect())
            .collect()
    };
    PLACEMENTS
        .iter()
        .map(|p| [read(dir.join(p).join("socket_0.csv")), read(dir.join(p).join("socket_1.csv"))])
        .collect()
}

/// The Panda's URDF (next to the placements' folder) with another geometry and a ball at
/// `ball_m` (m) on the flange.
fn seven_joint(panda_urdf: &str, ball_m: [f64; 3]) -> ModelFile {
    let mut text = panda_urdf
        .replace("xyz=\"0 0 0.333\"", "xyz=\"0 0 0.340\"")
        .replace("xyz=\"0 -0.316 0\"", "xyz=\"0 -0.350 0\"")
        .replace("xyz=\"0.0825 0 0\"", "xyz=\"0.0900 0 0\"")
        .replace("xyz=\"-0.0825 0.384 0\"", "xyz=\"-0.0900 0.410 0\"");
    let ball = "<origin rpy=\"0.0 0.0 0.0\" xyz=\"7.773732033005863e-05 -4.214022515884392e-05 0.030128297908475325\" />";
    assert!(text.contains(ball), "the Panda URDF's ball joint is not where expected");
    text = text.replace(
        ball,
        &format!("<origin rpy=\"0 0 0\" xyz=\"{} {} {}\" />", ball_m[0], ball_m[1], ball_m[2]),
    );
    kinecal::io::urdf::import(&text, None, Some("ball_link")).unwrap()
}

/// A UR5e from its URDF with a ball at `ball_m` (m) on `tool0`.
fn six_joint(ur5e_urdf: &str, ball_m: [f64; 3]) -> ModelFile {
    let ball = format!(
        "<link name=\"ball\"/><joint name=\"ball_joint\" type=\"fixed\"><parent link=\"tool0\"/><child link=\"ball\"/><origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/></joint></robot>",
        ball_m[0], ball_m[1], ball_m[2]
    );
    let text = ur5e_urdf.replace("</robot>", &ball);
    kinecal::io::urdf::import(&text, None, Some("ball")).unwrap()
}

/// Damped Newton on the tool point's position from `q` (finite-difference Jacobian, minimum
/// norm: a redundant arm stays near `q`).
fn position_ik(m: &dyn Mechanism, mut q: Vec<f64>, target: &Vector3<f64>) -> Option<Vec<f64>> {
    for _ in 0..50 {
        let p = m.forward(&q).ok()?.translation.vector;
        let e = target - p;
        if e.norm() < 1e-11 {
            return Some(q);
        }
        let mut j = DMatrix::zeros(3, q.len());
        for k in 0..q.len() {
            let mut qk = q.clone();
            qk[k] += 1e-7;
            let pk = m.forward(&qk).ok()?.translation.vector;
            j.set_column(k, &((pk - p) / 1e-7));
        }
        let jjt = &j * j.transpose() + DMatrix::identity(3, 3) * 1e-12;
        let y = jjt.lu().solve(&DVector::from_column_slice(e.as_slice()))?;
        let dq = j.transpose() * y;
        for (a, d) in q.iter_mut().zip(dq.iter()) {
            *a += d;
        }
    }
    None
}

/// One arm's data: per placement, its seat rows (seats 0 and 1) and the sockets' distance.
struct ArmData {
    name: &'static str,
    nominal: ModelFile,
    placements: Vec<(Vec<Measurement>, f64)>,
}

/// The prototype's rows at the real data's sockets (see the module docs), the ball seated with
/// `noise_mm` per axis.
fn arm_data(name: &'static str, nominal: ModelFile, configs: &Configurations, panda: &dyn Mechanism, noise_mm: f64, seed: u64) -> ArmData {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nom = nominal.build();
    let free = nominal.free_indices().unwrap();
    let (truth, _) = kinecal::simulate::virtual_prototype(&nom, &free, 0.5, 0.1f64.to_radians(), &mut rng);
    let seven = truth.input_names().len() == 7;
    let normal = Normal::new(0.0, noise_mm.max(1e-300)).unwrap();
    let mut placements = Vec::new();
    let mut seed_q: Option<Vec<f64>> = None;
    for sockets in configs {
        let mut rows = Vec::new();
        let mut centres = Vec::new();
        for (s, qs) in sockets.iter().enumerate() {
            // The socket: where the Panda's drawing puts the ball, on average.
            let c: Vector3<f64> = qs
                .iter()
                .map(|q| panda.forward(q).unwrap().translation.vector)
                .sum::<Vector3<f64>>()
                / qs.len() as f64;
            centres.push(c);
            for q in qs {
                let jitter = if noise_mm > 0.0 {
                    Vector3::new(normal.sample(&mut rng), normal.sample(&mut rng), normal.sample(&mut rng))
                } else {
                    Vector3::zeros()
                };
                let target = c + jitter;
                let solved = if seven {
                    position_ik(&truth, q.clone(), &target)
                } else {
                    let rotation = panda.forward(q).unwrap().rotation;
                    let pose = Pose::from_parts(target.into(), rotation);
                    let seeds = seed_q.iter().cloned().chain([vec![0.0, -1.2, 1.5, -1.9, -1.57, 0.0]]);
                    seeds.into_iter().find_map(|s| truth.inverse(&pose, Some(&s)).ok())
                };
                let Some(qt) = solved else { continue };
                if !seven {
                    seed_q = Some(qt.clone());
                }
                rows.push(Measurement {
                    q: qt,
                    obs: Observation::Seat(s),
                    joints: Vec::new(),
                });
            }
        }
        placements.push((rows, (centres[0] - centres[1]).norm()));
    }
    ArmData { name, nominal, placements }
}

/// The nominal's and the calibration's held-out spread (mm RMS over every held-out socket).
struct Judged {
    before: f64,
    after: f64,
    status: Status,
    converged: bool,
    weak: Vec<String>,
    cause: Option<String>,
    beyond: usize,
}

/// The sum of squared spreads over every seat row, and the rows.
fn spread(model: &dyn Mechanism, rows: &[Measurement]) -> (f64, usize) {
    let h = held_out(model, rows, &[]).unwrap();
    let n: usize = h.seats.iter().map(|s| s.rows).sum();
    (h.seat_rms_mm().unwrap().powi(2) * n as f64, n)
}

/// The placements `which` of `arm` in one file, placement k's sockets as seats 2k and 2k + 1,
/// with their known distances.
fn joined(arm: &ArmData, which: &[usize]) -> (DataSet, Vec<SeatDistance>) {
    let mut rows = Vec::new();
    let mut distances = Vec::new();
    for (k, &p) in which.iter().enumerate() {
        let (r, d) = &arm.placements[p];
        rows.extend(r.iter().map(|m| Measurement {
            obs: match &m.obs {
                Observation::Seat(s) => Observation::Seat(2 * k + s),
                o => o.clone(),
            },
            ..m.clone()
        }));
        distances.push(SeatDistance {
            a: 2 * k,
            b: 2 * k + 1,
            length: *d,
        });
    }
    (DataSet::from_measurements(arm.name, rows), distances)
}

/// Calibrated on the placements `ident`, the placements `judged` given as the validation data
/// (as `identify --validation` does: the verdict judges them).
fn run(arm: &ArmData, ident: &[usize], judged: &[usize], noise_mm: f64) -> Judged {
    let (data, distances) = joined(arm, ident);
    let (validation, validation_distances) = joined(arm, judged);
    let opts = CalibrationOptions {
        noise: Noise {
            position: if noise_mm > 0.0 { noise_mm } else { 1e-6 },
            ..Noise::default()
        },
        seat_distances: distances,
        validation_seat_distances: validation_distances,
        ..CalibrationOptions::default()
    };
    let cal = calibrate(&arm.nominal, &data, Some(&validation), &opts).unwrap_or_else(|e| panic!("{}: {e}", arm.name));
    let fitted = cal.model_file.build();
    let nominal = arm.nominal.build();
    let (mut before, mut after, mut n) = (0.0, 0.0, 0);
    for &p in judged {
        let rows = &arm.placements[p].0;
        let (b, k) = spread(&*nominal, rows);
        let (a, _) = spread(&*fitted, rows);
        before += b;
        after += a;
        n += k;
    }
    let r = &cal.report;
    Judged {
        before: (before / n as f64).sqrt(),
        after: (after / n as f64).sqrt(),
        status: r.verdict.status,
        converged: r.converged,
        weak: r.weak.clone(),
        cause: r.weak_cause.clone(),
        beyond: r.tolerance_check.as_ref().map_or(0, |t| t.beyond.len()),
    }
}

fn main() {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(args.next().expect("the mukca-panda/panda_2 folder"));
    let noise_mm: f64 = args.next().map_or(0.1, |a| a.parse().unwrap());
    let seed: u64 = args.next().map_or(1, |a| a.parse().unwrap());
    let configs = read_configurations(&dir);
    let panda_urdf = std::fs::read_to_string(dir.join("../panda.urdf")).unwrap();
    let panda = kinecal::io::urdf::import(&panda_urdf, None, Some("ball_link")).unwrap().build();
    let ur5e = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/examples/models/ur5e.urdf")).unwrap();
    let arms = [
        arm_data(
            "7-joint, on axis",
            seven_joint(&panda_urdf, [0.0, 0.0, 0.03]),
            &configs,
            &*panda,
            noise_mm,
            seed,
        ),
        arm_data(
            "7-joint, 0.7 mm off",
            seven_joint(&panda_urdf, [0.0007, 0.0, 0.03]),
            &configs,
            &*panda,
            noise_mm,
            seed,
        ),
        arm_data(
            "6-joint, 0.7 mm off",
            six_joint(&ur5e, [0.0007, 0.0, 0.03]),
            &configs,
            &*panda,
            noise_mm,
            seed,
        ),
    ];
    println!("noise {noise_mm} mm per axis, prototype seed {seed}; held-out spread RMS (mm), nominal → calibrated");
    for arm in &arms {
        let rows: Vec<usize> = arm.placements.iter().map(|p| p.0.len()).collect();
        println!("\n{} ({} rows per placement: {rows:?})", arm.name, rows.iter().sum::<usize>());
        let n = arm.placements.len();
        for (what, runs) in [
            (
                "one-to-many",
                (0..n)
                    .map(|k| (vec![k], (0..n).filter(|&j| j != k).collect::<Vec<_>>()))
                    .collect::<Vec<_>>(),
            ),
            (
                "all-but-one",
                (0..n).map(|k| ((0..n).filter(|&j| j != k).collect::<Vec<_>>(), vec![k])).collect(),
            ),
        ] {
            let mut worst_after: f64 = 0.0;
            let mut failed = 0;
            let mut weak = std::collections::BTreeSet::new();
            let mut causes = std::collections::BTreeSet::new();
            for (ident, judged) in runs {
                let j = run(arm, &ident, &judged, noise_mm);
                println!(
                    "  {what} {:<12} {:.4} → {:.3e}  {:?}{}{}{}",
                    PLACEMENTS[if ident.len() == 1 { ident[0] } else { judged[0] }],
                    j.before,
                    j.after,
                    j.status,
                    if j.converged { "" } else { ", NOT converged" },
                    if j.beyond > 0 {
                        format!(", {} beyond tolerances", j.beyond)
                    } else {
                        String::new()
                    },
                    if j.weak.is_empty() {
                        String::new()
                    } else {
                        format!(", weak: {}", j.weak.join(" "))
                    }
                );
                worst_after = worst_after.max(j.after);
                failed += usize::from(j.status == Status::Failed || !j.converged);
                weak.extend(j.weak);
                causes.extend(j.cause);
            }
            println!("  {what}: worst held-out spread {worst_after:.3e} mm, {failed} failed; held as weak somewhere: {weak:?}");
            for c in causes {
                println!("    likely cause: {c}");
            }
        }
    }
}
