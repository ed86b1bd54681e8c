//! Observed joints (`role = "observed"`): passive joints the closure solves whose sensor readings
//! are observations, weighted by the encoder noise. On the 3T1R machine with its upper and
//! platform angles read, as the 3T1R paper's machine has them.
use kinecal::identify::{identify, Options};
use kinecal::io::model_file::ModelFile;
use kinecal::measure::{Measurement, Noise, Observation};
use kinecal::params::Unit;
use kinecal::Mechanism;
use nalgebra::DVector;
use std::path::Path;

/// The 3T1R machine file: the upper angles of all four chains and the platform revolute of
/// chain B1 observed.
fn t3r1_observed() -> ModelFile {
    ModelFile::load_str(Path::new("t3r1.toml"), include_str!("../../examples/models/t3r1.toml")).unwrap()
}

fn configurations(m: &dyn Mechanism, n: usize, seed: u64) -> Vec<Vec<f64>> {
    m.sample_configurations(n, seed).unwrap().unwrap()
}

#[test]
fn observed_joints_are_named_and_their_jacobian_is_the_finite_differences() {
    let file = t3r1_observed();
    let m = file.build();
    let names: Vec<String> = m
        .observed_joints()
        .into_iter()
        .map(|(n, u)| {
            assert_eq!(u, Unit::Angle);
            n
        })
        .collect();
    assert_eq!(names, ["u1", "r1", "u3", "u2", "u4"]);
    // Still actuated by the four sliders alone.
    assert_eq!(m.input_names(), ["s1", "s3", "s2", "s4"]);
    let p = m.n_params();
    let h = 1e-6;
    for q in configurations(&m, 3, 4) {
        let (v, j) = m.observed_joints_with_jacobian(&q).unwrap();
        assert_eq!(v, m.observed_joint_values(&q).unwrap());
        assert_eq!(j.shape(), (5, p));
        let mut worst: f64 = 0.0;
        for c in 0..p {
            let mut d = DVector::zeros(p);
            d[c] = h;
            let mut a = m.clone();
            a.retract(&d);
            let mut b = m.clone();
            b.retract(&(-d));
            let (va, vb) = (a.observed_joint_values(&q).unwrap(), b.observed_joint_values(&q).unwrap());
            for k in 0..5 {
                let fd = (va[k] - vb[k]) / (2.0 * h);
                worst = worst.max((fd - j[(k, c)]).abs());
            }
        }
        assert!(worst < 1e-7 * j.amax().max(1.0), "worst {worst:e}, largest {:e}", j.amax());
    }
}

/// Noise-free data of a perturbed machine with the readings of its observed joints: the fit
/// recovers it to round-off, and the readings identify more than the poses alone.
#[test]
fn observed_readings_enter_the_identification() {
    let file = t3r1_observed();
    let nominal = file.build();
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(7);
    let free = file.free_indices().unwrap();
    let errors = kinecal::simulate::random_errors(&nominal, &mut rng, 0.3, 0.001, Some(&free));
    let truth = kinecal::simulate::perturbed(&nominal, &errors);
    let qs = configurations(&nominal, 30, 8);
    let data: Vec<Measurement> = qs
        .iter()
        .map(|q| Measurement {
            q: q.clone(),
            obs: Observation::Pose(truth.forward(q).unwrap()),
            joints: truth.observed_joint_values(q).unwrap(),
        })
        .collect();
    let opts = Options {
        free: Some(free),
        ..Default::default()
    };
    let with = identify(&nominal, &data, &opts).unwrap();
    let poses_only: Vec<Measurement> = data
        .iter()
        .map(|m| Measurement {
            joints: Vec::new(),
            ..m.clone()
        })
        .collect();
    let without = identify(&nominal, &poses_only, &opts).unwrap();
    eprintln!(
        "3T1R machine, 30 poses: rank {} with the five observed angles, {} from the poses alone",
        with.identifiability.rank, without.identifiability.rank
    );
    assert_eq!((with.identifiability.rank, without.identifiability.rank), (43, 38));
    assert!(with.converged);
    let check = configurations(&nominal, 20, 9);
    for q in &check {
        let e = kinecal::se3::pose_error(&truth.forward(q).unwrap(), &with.model.forward(q).unwrap());
        assert!(kinecal::se3::lin(&e).norm() < 1e-8, "{e}");
        let (a, b) = (
            truth.observed_joint_values(q).unwrap(),
            with.model.observed_joint_values(q).unwrap(),
        );
        assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-10), "{a:?} {b:?}");
    }
    // A reading count that does not match the model's observed joints is a clear error.
    let mut bad = data.clone();
    bad[3].joints.pop();
    let err = identify(&nominal, &bad, &opts).err().unwrap().to_string();
    assert!(
        err.contains("pose 3: 4 observed-joint readings for the model's 5 observed joints (u1, r1, u3, u2, u4)"),
        "{err}"
    );
    let _ = Noise::default();
}

/// `kinecal simulate t3r1 ARGS --out OUT --truth truth.toml` in `d`.
fn simulate_t3r1(d: &Path, out: &str, args: &[&str]) {
    let mut a = vec!["simulate", "t3r1"];
    a.extend_from_slice(args);
    a.extend_from_slice(&["--out", out, "--truth", "truth.toml"]);
    crate::cli::ok(d, &a);
}

/// The command line with the encoders: `simulate` writes their columns (with their noise),
/// `data check` says so, `validate` reports reading − model per joint; a data file with one of
/// them missing is a one-line error naming it.
#[test]
fn observed_joints_through_the_command_line() {
    use crate::cli::{fails, ok};
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    simulate_t3r1(
        d,
        "d.csv",
        &[
            "--poses",
            "12",
            "--seed",
            "2",
            "--error-mm",
            "0.2",
            "--error-deg",
            "0.02",
            "--encoder-noise-deg",
            "0.01",
        ],
    );
    let text = std::fs::read_to_string(d.join("d.csv")).unwrap();
    assert!(
        text.starts_with("id,s1_mm,s3_mm,s2_mm,s4_mm,u1_deg,r1_deg,u3_deg,u2_deg,u4_deg,x_mm"),
        "{text}"
    );
    assert!(ok(d, &["data", "check", "t3r1", "d.csv"]).contains("with the readings of 5 observed joints"));
    // The true machine on its own data: the encoders' noise is what is left (0.01 deg).
    let v = ok(d, &["validate", "truth.toml", "d.csv"]);
    let line = v.lines().find(|l| l.starts_with("observed joints")).unwrap();
    let rms: Vec<f64> = line
        .split_once(": ")
        .unwrap()
        .1
        .split(", ")
        .map(|s| s.split_whitespace().rev().nth(3).unwrap().parse().unwrap())
        .collect();
    assert_eq!(rms.len(), 5, "{line}");
    assert!(rms.iter().all(|r| (0.003..0.02).contains(r)), "{line}");
    let cut: String = text
        .lines()
        .map(|l| {
            let mut c: Vec<&str> = l.split(',').collect();
            c.remove(9);
            c.join(",")
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(d.join("cut.csv"), cut).unwrap();
    let e = fails(d, &["identify", "t3r1", "cut.csv", "--out", "c.toml"]);
    assert!(
        e.contains("observed-joint columns missing: u4_deg") && e.trim().lines().count() == 1,
        "{e}"
    );
}

/// A controller log with the encoders' readings after the sliders, joined with three reflector
/// exports (`data join --joints … --reflector …`): the joined file holds the readings as observed
/// columns; a log without them joins to a file without them.
#[test]
fn a_controller_log_with_the_encoders_joins_with_the_tracker_exports() {
    use crate::cli::ok;
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    simulate_t3r1(d, "sim.csv", &["--poses", "6", "--seed", "3", "--measure", "reflectors"]);
    let text = std::fs::read_to_string(d.join("sim.csv")).unwrap();
    let rows: Vec<Vec<&str>> = text.lines().map(|l| l.split(',').collect()).collect();
    let col = |name: &str| rows[0].iter().position(|c| *c == name).unwrap();
    let write = |file: &str, names: &[&str], header: &str| {
        let mut t = format!("{header}\n");
        for r in &rows[1..] {
            let v: Vec<&str> = std::iter::once(r[0]).chain(names.iter().map(|n| r[col(n)])).collect();
            t += &(v.join(",") + "\n");
        }
        std::fs::write(d.join(file), t).unwrap();
    };
    let sliders = ["s1_mm", "s3_mm", "s2_mm", "s4_mm"];
    let encoders = ["u1_deg", "r1_deg", "u3_deg", "u2_deg", "u4_deg"];
    let all: Vec<&str> = sliders.iter().chain(&encoders).copied().collect();
    write("log.csv", &all, "idx,s1,s3,s2,s4,u1,r1,u3,u2,u4");
    write("log-sliders.csv", &sliders, "idx,s1,s3,s2,s4");
    for k in 1..=3 {
        let names = [format!("m{k}x_mm"), format!("m{k}y_mm"), format!("m{k}z_mm")];
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        write(&format!("smr{k}.csv"), &names, "idx,x,y,z");
    }
    let join = |log: &str, out: &str| {
        ok(
            d,
            &[
                "data",
                "join",
                "t3r1",
                "--joints",
                log,
                "--reflector",
                "smr1.csv",
                "--reflector",
                "smr2.csv",
                "--reflector",
                "smr3.csv",
                "--out",
                out,
            ],
        )
    };
    join("log.csv", "joined.csv");
    let joined = std::fs::read_to_string(d.join("joined.csv")).unwrap();
    assert!(
        joined.starts_with("id,s1_mm,s3_mm,s2_mm,s4_mm,u1_deg,r1_deg,u3_deg,u2_deg,u4_deg,m1x_mm"),
        "{joined}"
    );
    let t3r1 = ModelFile::load_str(Path::new("t3r1.toml"), include_str!("../../examples/models/t3r1.toml")).unwrap();
    let a = kinecal::io::data_file::read_data(
        &d.join("joined.csv"),
        &t3r1.data_columns(),
        kinecal::io::data_file::InputColumns::Required,
    )
    .unwrap();
    let b = kinecal::io::data_file::read_data(
        &d.join("sim.csv"),
        &t3r1.data_columns(),
        kinecal::io::data_file::InputColumns::Required,
    )
    .unwrap();
    for (x, y) in a.measurements.iter().zip(&b.measurements) {
        assert!(x.joints.iter().zip(&y.joints).all(|(p, q)| (p - q).abs() < 1e-12));
        assert_eq!(x.joints.len(), 5);
    }
    join("log-sliders.csv", "joined-sliders.csv");
    let plain = std::fs::read_to_string(d.join("joined-sliders.csv")).unwrap();
    assert!(plain.starts_with("id,s1_mm,s3_mm,s2_mm,s4_mm,m1x_mm"), "{plain}");
}
