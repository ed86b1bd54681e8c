//! Real tracker data arrive in the tracker's own frame, with unknown tool / reflector offsets:
//! `calibrate` finds both frames from the data, for every mechanism kind and measurement kind.
//! Each kind: tracker 2 m away and rotated 120° about an oblique axis, the measured tool 150 mm
//! from the flange/platform; noise-free data recover the geometry (held-out poses to 1e-9 mm),
//! 20 µm / 0.02° noise gives held-out errors at the noise level.
use kinecal::calibrate::{calibrate, CalibrationOptions};
use kinecal::io::builtin;
use kinecal::io::data_file::{DataSet, MeasurementFormat};
use kinecal::io::model_file::ModelFile;
use kinecal::measure::{Measurement, Noise, Observation};
use kinecal::model::framed::Framed;
use kinecal::report::Status;
use kinecal::se3::{self, Pose};
use kinecal::simulate::{random_configurations, virtual_prototype};
use kinecal::validate::{pose_errors, ErrorStats};
use kinecal::Mechanism;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// The tracker: 2 m away, rotated 120° about an oblique axis.
pub(crate) fn tracker() -> Pose {
    se3::pose_from_parts(
        Vector3::new(2000.0, -700.0, 400.0),
        Vector3::new(1.0, 2.0, -0.5).normalize() * 120f64.to_radians(),
    )
}

/// The measured tool frame, 150 mm from the flange / platform and turned.
pub(crate) fn tool() -> Pose {
    se3::pose_from_parts(Vector3::new(90.0, -80.0, 90.0), Vector3::new(0.3, -0.2, 0.5))
}

#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Kind {
    Pose,
    Position,
}

pub(crate) fn data_set(name: &str, truth: &dyn Mechanism, qs: &[Vec<f64>], kind: Kind, noise: Option<Noise>, seed: u64) -> DataSet {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut draw = |s: f64| match noise {
        Some(_) => {
            let d = Normal::new(0.0, s).unwrap();
            Vector3::new(d.sample(&mut rng), d.sample(&mut rng), d.sample(&mut rng))
        }
        None => Vector3::zeros(),
    };
    let n = noise.unwrap_or(Noise {
        position: 1.0,
        orientation: 1.0,
        ..Noise::default()
    });
    let measurements: Vec<Measurement> = qs
        .iter()
        .map(|q| {
            let t = truth.forward(q).unwrap();
            let obs = match kind {
                Kind::Pose => {
                    let (dp, dw) = (draw(n.position), draw(n.orientation));
                    Observation::Pose(Pose::from_parts((t.translation.vector + dp).into(), se3::so3_exp(&dw) * t.rotation))
                }
                Kind::Position => Observation::Position(t.translation.vector + draw(n.position)),
            };
            Measurement {
                joints: Vec::new(),
                q: q.clone(),
                obs,
            }
        })
        .collect();
    DataSet {
        path: name.into(),
        lines: (2..2 + qs.len()).collect(),
        ids: (0..qs.len() as i64).collect(),
        format: if kind == Kind::Pose {
            MeasurementFormat::PoseQuaternion
        } else {
            MeasurementFormat::Position
        },
        has_inputs: true,
        dropped: Vec::new(),
        reflectors: Vec::new(),
        derived: Vec::new(),
        beyond_limits: Vec::new(),
        measurements,
    }
}

/// Calibrate the built-in `name` from tracker-frame data of a virtual prototype; returns the
/// held-out statistics of the calibrated model against the truth's exact poses.
fn run(name: &str, kind: Kind, noise: Option<Noise>, poses: usize) -> ErrorStats {
    run_judged(name, kind, noise, poses).0
}

/// [`run`], with the verdict of the calibration.
fn run_judged(name: &str, kind: Kind, noise: Option<Noise>, poses: usize) -> (ErrorStats, Status) {
    let file: ModelFile = builtin::model_file(name).unwrap();
    let nominal = file.build();
    let free = file.free_indices().unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (proto, _) = virtual_prototype(&nominal, &free, 0.5, 0.1f64.to_radians(), &mut rng);
    let truth = Framed::new(proto, tracker(), tool());
    let inputs = file.inputs();
    let ident_q = random_configurations(&*nominal, &inputs, poses, &mut rng).unwrap();
    let valid_q = random_configurations(&*nominal, &inputs, 20, &mut rng).unwrap();
    let data = data_set("ident.csv", &truth, &ident_q, kind, noise, 1);
    let exact = data_set("valid.csv", &truth, &valid_q, kind, None, 2);
    let opts = CalibrationOptions {
        noise: noise.unwrap_or_default(),
        ..CalibrationOptions::default()
    };
    let cal = calibrate(&file, &data, Some(&exact), &opts).unwrap();
    assert!(cal.identification.converged, "{name}: not converged");
    // The calibrated model file, written and read back, predicts the same poses.
    let text = cal.model_file.to_toml().unwrap();
    let back = ModelFile::load_str(std::path::Path::new("cal.toml"), &text).unwrap().build();
    (
        ErrorStats::of(&pose_errors(&*back, &exact.measurements).unwrap()),
        cal.report.verdict.status,
    )
}

fn check_exact(name: &str, kind: Kind) {
    let s = run(name, kind, None, 40);
    eprintln!(
        "{name}, noise-free, tracker 2 m / 120°, tool 150 mm: held-out max {:.1e} mm",
        s.position_max_mm
    );
    assert!(
        s.position_max_mm < 1e-9,
        "{name}: held-out position error {:e} mm",
        s.position_max_mm
    );
    if let Some(o) = s.orientation_max_deg {
        assert!(o.to_radians() < 1e-9, "{name}: held-out rotation error {o:e} deg");
    }
}

fn check_noisy(name: &str, kind: Kind) {
    let noise = Noise::default();
    let s = run(name, kind, Some(noise), 60);
    eprintln!(
        "{name}, 20 µm noise, tracker 2 m / 120°, tool 150 mm: held-out RMS {:.4} mm",
        s.position_rms_mm
    );
    // Held-out errors of the calibrated model against exact poses: at the noise level (20 µm per
    // axis, so ~35 µm per point), not at the geometric errors (0.5 mm / 0.1°).
    assert!(
        s.position_rms_mm < 2.0 * noise.position,
        "{name}: held-out RMS {} mm",
        s.position_rms_mm
    );
}

#[test]
fn serial_arm_poses_in_any_frame() {
    check_exact("irb120", Kind::Pose);
}

#[test]
fn serial_arm_one_reflector_in_any_frame() {
    check_exact("irb120", Kind::Position);
}

#[test]
fn serial_arm_noisy() {
    check_noisy("irb120", Kind::Pose);
}

#[test]
fn pm5_poses_in_any_frame() {
    check_exact("pm5", Kind::Pose);
}

#[test]
fn pm5_noisy() {
    check_noisy("pm5", Kind::Pose);
}

#[test]
fn stewart_poses_in_any_frame() {
    check_exact("stewart", Kind::Pose);
}

#[test]
fn stewart_noisy() {
    check_noisy("stewart", Kind::Pose);
}

/// Through the command line: data simulated by a model file whose `[frames]` put the tracker
/// 2 m away and the tool 150 mm out, calibrated from the plain exported model.
fn tracker_data() -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    crate::cli::ok(d, &["model", "export", "irb120", "--out", "m.toml"]);
    let mut text = std::fs::read_to_string(d.join("m.toml")).unwrap();
    text.push_str(
        "\n[frames]\n[frames.measurement]\nposition = [2000.0, -700.0, 400.0]\nrpy = [100.0, -40.0, 75.0]\n\
         [frames.tool]\nposition = [90.0, -80.0, 90.0]\nrpy = [10.0, 20.0, -30.0]\n",
    );
    std::fs::write(d.join("tracker.toml"), text).unwrap();
    crate::cli::ok(
        d,
        &[
            "simulate",
            "tracker.toml",
            "--poses",
            "60",
            "--seed",
            "5",
            "--noise-mm",
            "0.02",
            "--noise-deg",
            "0.02",
            "--out",
            "d.csv",
            "--truth",
            "t.toml",
            "--validation-poses",
            "20",
            "--validation-out",
            "v.csv",
        ],
    );
    tmp
}

#[test]
fn command_line_calibration_of_tracker_frame_data() {
    let tmp = tracker_data();
    let d = tmp.path();
    let out = crate::cli::ok(d, &["identify", "m.toml", "d.csv", "--validation", "v.csv", "--out", "c.toml"]);
    assert!(out.contains("converged"), "{out}");
    let v = crate::cli::json(d, &["validate", "c.toml", "v.csv"]);
    let rms = v["stats"]["position_rms_mm"].as_f64().unwrap();
    assert!(rms < 0.06, "held-out RMS {rms} mm with 20 µm noise");
    // The model's own frames cannot explain tracker data: that fit fails its checks (exit 2).
    let out = crate::cli::kinecal(d, &["identify", "m.toml", "d.csv", "--frames", "model", "--out", "c2.toml"]);
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stdout));
    assert!(!d.join("c2.toml").exists());
}

#[test]
fn wrong_units_and_wrong_models_are_named() {
    let tmp = tracker_data();
    let d = tmp.path();
    let text = std::fs::read_to_string(d.join("d.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let rows: Vec<Vec<String>> = lines.map(|l| l.split(',').map(String::from).collect()).collect();
    let write = |name: &str, header: &str, f: &dyn Fn(usize, &str) -> String| {
        let mut s = header.to_string() + "\n";
        for r in &rows {
            let v: Vec<String> = r.iter().enumerate().map(|(k, x)| f(k, x)).collect();
            s += &(v.join(",") + "\n");
        }
        std::fs::write(d.join(name), s).unwrap();
    };
    // Metres in millimetre columns (x, y, z are columns 7..9).
    write("metres.csv", &header, &|k, x| {
        if (7..10).contains(&k) {
            (x.parse::<f64>().unwrap() / 1000.0).to_string()
        } else {
            x.into()
        }
    });
    let e = crate::cli::fails(d, &["identify", "m.toml", "metres.csv", "--out", "c.toml"]);
    assert!(
        e.contains("metres in the _mm columns") && e.contains("1/1000 of the model's reach"),
        "{e}"
    );
    // Radians in degree columns.
    write("rad.csv", &header, &|k, x| {
        if (1..7).contains(&k) {
            x.parse::<f64>().unwrap().to_radians().to_string()
        } else {
            x.into()
        }
    });
    let e = crate::cli::fails(d, &["identify", "m.toml", "rad.csv", "--out", "c.toml"]);
    assert!(e.contains("look like radians"), "{e}");
    // Joint columns swapped (q2 ↔ q3): out of the limits, or a fit that fails its checks.
    std::fs::write(d.join("swapped.csv"), text.replacen("q2_deg,q3_deg", "q3_deg,q2_deg", 1)).unwrap();
    let out = crate::cli::kinecal(d, &["identify", "m.toml", "swapped.csv", "--out", "c.toml"]);
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("joint order") || err.contains("beyond the model's tolerances"),
        "{err}"
    );
    assert!(!String::from_utf8(out.stdout).unwrap().contains(" converged after"));
    // A model of another machine: a link 120 mm longer.
    let model = std::fs::read_to_string(d.join("m.toml")).unwrap().replacen("270.0", "390.0", 1);
    std::fs::write(d.join("other.toml"), model).unwrap();
    let out = crate::cli::kinecal(d, &["identify", "other.toml", "d.csv", "--out", "c.toml"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("beyond the model's tolerances"), "{err}");
    // The link absorbs the difference, the fit matches the data: the message says both readings.
    assert!(
        err.contains("the fit matches the data") && err.contains("a model of another machine (check its dimensions"),
        "{err}"
    );
    assert!(!String::from_utf8(out.stdout).unwrap().contains(" converged after"));
}

/// Held-out RMS (mm, against exact poses) of the IRB 120 calibrated from `poses` tracker-frame
/// measurements of `kind` with 20 µm noise, `blunders` of them moved by 5–50 mm; the ids listed
/// as blunders, the ids moved, and the verdict.
fn with_blunders_of(poses: usize, kind: Kind, blunders: usize) -> (f64, Vec<i64>, Vec<i64>, Status) {
    let file = builtin::model_file("irb120").unwrap();
    let nominal = file.build();
    let free = file.free_indices().unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (proto, _) = virtual_prototype(&nominal, &free, 0.5, 0.1f64.to_radians(), &mut rng);
    let truth = Framed::new(proto, tracker(), tool());
    let qs = random_configurations(&*nominal, &file.inputs(), poses, &mut rng).unwrap();
    let valid_q = random_configurations(&*nominal, &file.inputs(), 30, &mut rng).unwrap();
    let mut data = data_set("ident.csv", &truth, &qs, kind, Some(Noise::default()), 3);
    let mut moved = Vec::new();
    for k in 0..blunders {
        let i = k * 10 + 3;
        let size = 5.0 + 45.0 * k as f64 / blunders.max(1) as f64;
        let dir = Vector3::new((k as f64).sin(), (k as f64).cos(), 0.5).normalize();
        match &mut data.measurements[i].obs {
            Observation::Pose(t) => t.translation.vector += dir * size,
            Observation::Position(p) => *p += dir * size,
            _ => unreachable!("tracker data"),
        }
        moved.push(data.ids[i]);
    }
    let exact = data_set("valid.csv", &truth, &valid_q, kind, None, 4);
    let cal = calibrate(&file, &data, Some(&exact), &CalibrationOptions::default()).unwrap();
    let stats = ErrorStats::of(&pose_errors(&*cal.identification.model, &exact.measurements).unwrap());
    (stats.position_rms_mm, cal.blunders.clone(), moved, cal.report.verdict.status)
}

fn with_blunders(blunders: usize) -> (f64, Vec<i64>, Vec<i64>) {
    let (rms, listed, moved, _) = with_blunders_of(100, Kind::Pose, blunders);
    (rms, listed, moved)
}

#[test]
fn blunders_are_set_aside_on_a_short_serial_position_set() {
    // 80 position poses, 8 of them 5–50 mm off: set aside, not a failed calibration.
    let (clean, _, _, _) = with_blunders_of(80, Kind::Position, 0);
    let (dirty, listed, moved, status) = with_blunders_of(80, Kind::Position, 8);
    assert_ne!(status, Status::Failed);
    for id in &moved {
        assert!(listed.contains(id), "blunder {id} not listed ({listed:?})");
    }
    assert!(dirty < 2.0 * clean, "held-out RMS {dirty} mm against {clean} mm clean");
}

#[test]
fn gross_blunders_are_down_weighted_and_listed() {
    let (clean, listed_clean, _) = with_blunders(0);
    let (dirty, listed, moved) = with_blunders(10);
    assert!(
        dirty < 2.0 * clean,
        "10 % blunders: held-out RMS {dirty} mm against {clean} mm clean"
    );
    for id in &moved {
        assert!(listed.contains(id), "blunder {id} not listed ({listed:?})");
    }
    assert!(listed.len() <= moved.len() + 3, "too many poses listed: {listed:?}");
    assert!(listed_clean.len() <= 2, "clean data: {listed_clean:?}");
}

/// Every built-in model (`kinecal model list`, the shipped example files among them): noise-free
/// pose data with the tracker 2 m away and turned, the tool 150 mm out, frames estimated, to
/// round-off (the whole 3T1R machine too: `identify` continues its fit on the parameters its
/// converged geometry shows beyond the start's).
#[test]
fn every_shipped_model_in_a_tracker_frame() {
    for (name, _) in builtin::list() {
        let e = run(name, Kind::Pose, None, 60).position_max_mm;
        eprintln!("{name}: noise-free, tracker 2 m / 120°, tool 150 mm, frames estimated: held-out max {e:.2e} mm");
        assert!(e < 1e-9, "{name}: held-out {e:e} mm");
    }
}

/// The linear delta with its frames estimated and the tool 150 mm out is fitted
/// to round-off like every other machine. Its start (a platform that only translates) hides the
/// tool offset and three hinge parameters; the fit continues on them where it converged
/// (`identify`'s refit), and retractions that add up keep that continuation path-independent.
/// It stopped at 2.3e-2 mm before.
#[test]
fn linear_delta_with_a_tool_offset_in_any_frame() {
    let s = run("linear-delta", Kind::Pose, None, 60);
    eprintln!(
        "linear delta, noise-free, tracker 2 m / 120°, tool 150 mm: held-out max {:.2e} mm",
        s.position_max_mm
    );
    assert!(s.position_max_mm < 1e-9, "held-out {:e} mm", s.position_max_mm);
}

/// Position data taken at one tool orientation do not separate the tool offset from where the
/// tracker stands (an offset moves every measured point alike). The registration's Newton step
/// is then the minimum-norm one: the frames stay where the alternation put them, within
/// millimetres, instead of running off to metres in opposite directions (as a Cholesky solve of
/// the singular normal matrix did: held-out errors of 5 m on a UR5e plan at one orientation).
#[test]
fn position_data_at_one_tool_orientation_register_without_running_off() {
    use kinecal::design::{candidates_in_workspace, CandidateFilter, Sampling, Workspace};
    use nalgebra::{Point3, Vector3};
    let file = kinecal::io::urdf::import(&crate::urdf::ur5e_urdf(), None, None).unwrap();
    let mech = file.build();
    // As `kinecal plan --model ur5e.toml --x-mm 300,600 --y-mm -200,200 --z-mm 200,500` samples:
    // from zero inputs, the tool turned as there.
    let q0 = [0.0; 6];
    let home = mech.forward(&q0).unwrap();
    let ws = Workspace {
        position_min: Vector3::new(300.0, -200.0, 200.0),
        position_max: Vector3::new(600.0, 200.0, 500.0),
        reference: home.rotation,
        rpy_min: [0.0; 3],
        rpy_max: [0.0; 3],
    };
    let (cands, _) = candidates_in_workspace(
        &*mech,
        &ws,
        &Sampling::Halton { n: 60, seed: 3 },
        Some(&q0),
        &CandidateFilter::default(),
        None,
    )
    .unwrap();
    assert!(cands.len() >= 30, "{} candidates", cands.len());
    // A tracker 3 m away, turned, and a reflector 40 mm off the flange, all unknown.
    let tracker = se3::exp(&se3::Twist::from_column_slice(&[2500.0, -1200.0, 800.0, 0.3, -0.2, 1.1]));
    let reflector = Vector3::new(10.0, -20.0, 40.0);
    // The machine is not the drawing: each point 0.3 mm off, differently per pose.
    let data: Vec<Measurement> = cands
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let k = i as f64;
            let off = 0.3 * Vector3::new(k.sin(), (1.7 * k).cos(), (2.3 * k).sin());
            let p = c.target.transform_point(&Point3::from(reflector)).coords + off;
            // The tool turned by a microradian or so between poses (what an inverse solved to a
            // tolerance leaves): the blind direction is then nearly, not exactly, singular.
            let mut q = c.q.clone();
            q[5] += 1e-6 * (3.0 * k).sin();
            q[3] += 1e-6 * (5.0 * k).cos();
            Measurement {
                q,
                obs: Observation::Position(tracker.transform_point(&Point3::from(p)).coords),
                joints: Vec::new(),
            }
        })
        .collect();
    let reg = kinecal::register::register(&mech, &data, &Pose::identity()).unwrap();
    assert!(reg.rms_mm < 0.6, "registration RMS {} mm", reg.rms_mm);
    // The offset along the data's blind direction is not found, but it is not made up either.
    let t = reg.tool.translation.vector;
    assert!(t.norm() < 100.0, "tool offset {t} mm");
}

/// Models whose frames one reflector's positions do not register from the drawing: the 3-PRS
/// head only lifts and tilts, and its fit stops in another minimum (7.6 mm RMS left, the starts
/// 3.3–3.9 mm apart). Such a fit must be failed, never reported calibrated.
const REFLECTOR_UNREGISTERED: [&str; 1] = ["head-3prs"];

/// Every built-in model measured by one reflector (positions only) in a tracker frame 2 m away
/// and turned, 150 mm from the flange / platform, frames estimated, noise-free: to round-off,
/// but the 3-PRS head, which must then fail. The whole 3T1R machine gets there through
/// `identify`'s finer refit: the tilts and shift of its rail 3, redundant at the start, are seen
/// where the first fit converged (singular values 3e-6 and 3e-8 of the largest) and fitted.
#[test]
fn every_shipped_model_with_one_reflector_in_a_tracker_frame() {
    for (name, _) in builtin::list() {
        let (stats, status) = run_judged(name, Kind::Position, None, 60);
        let e = stats.position_max_mm;
        eprintln!("{name}: noise-free, one reflector, tracker 2 m / 120°, frames estimated: held-out max {e:.2e} mm, {status:?}");
        if REFLECTOR_UNREGISTERED.contains(&name) {
            assert!(e < 1e-9 || status == Status::Failed, "{name}: held-out {e:e} mm, {status:?}");
            continue;
        }
        assert!(e < 1e-9, "{name}: held-out {e:e} mm");
    }
}

/// The calibrated machine driven to targets of the user's tool (`user`, in the flange) as
/// `kinecal compensate --tool` drives it: the targets are the nominal's user tool poses at `qs`
/// (in the robot's base frame), the calibrated model in its base frame with that tool gives the
/// commands ([`kinecal::compensate::compensate`]), and the truth at those commands says where
/// the user's tool point goes. Compared in the tracker's frame, where the calibration placed
/// the base (its `[frames]`): the largest distance (mm) between where the tool point went and
/// the target.
fn user_tool_error(calibrated: &ModelFile, nominal: &ModelFile, truth: &dyn Mechanism, user: Pose, qs: &[Vec<f64>]) -> f64 {
    let targets: Vec<Pose> = {
        let m = nominal.build_in_base_frame(&user);
        qs.iter().map(|q| m.forward(q).unwrap()).collect()
    };
    let model = calibrated.build_in_base_frame(&user);
    let commands = kinecal::compensate::compensate(&*model, &calibrated.inputs(), &targets, Some(qs), &|_| {}).unwrap();
    let base = calibrated.frames.expect("a tracker calibration has frames").measurement;
    let truth = Framed::new(truth.box_clone(), tracker(), user);
    (commands.iter().zip(&targets))
        .map(|(q, t)| (truth.forward(q).unwrap().translation.vector - (base * t).translation.vector).norm())
        .fold(0.0, f64::max)
}

/// A tracker calibration through a reflector: the parameters the report calls redundant (the
/// last link and the flange, which the reflector's unknown offset takes up) stay as drawn, so
/// the calibrated robot, driven by `compensate` to targets of another tool — a TCP 150 mm out
/// and turned —, reaches them as well as a calibration that fixes those parameters in the model
/// file does (within 1.1×). Reflector on the last axis and off it.
#[test]
fn the_robot_keeps_what_only_the_reflector_offset_explains() {
    let file: ModelFile = builtin::model_file("irb120").unwrap();
    let nominal = file.build();
    let free = file.free_indices().unwrap();
    let user = se3::pose_from_parts(Vector3::new(40.0, -30.0, 150.0), Vector3::new(0.2, 0.3, -0.4));
    for (what, reflector) in [
        ("on the last axis", Vector3::new(60.0, 0.0, 0.0)),
        ("off it", Vector3::new(15.0, -10.0, 120.0)),
    ] {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let (proto, _) = virtual_prototype(&nominal, &free, 0.5, 0.1f64.to_radians(), &mut rng);
        let truth = Framed::new(proto.box_clone(), tracker(), se3::pose_from_parts(reflector, Vector3::zeros()));
        let inputs = file.inputs();
        let ident_q = random_configurations(&*nominal, &inputs, 60, &mut rng).unwrap();
        let check_q = random_configurations(&*nominal, &inputs, 30, &mut rng).unwrap();
        let noise = Noise::default();
        let data = data_set("ident.csv", &truth, &ident_q, Kind::Position, Some(noise), 3);
        let opts = CalibrationOptions {
            noise,
            ..CalibrationOptions::default()
        };
        let cal = calibrate(&file, &data, None, &opts).unwrap();
        assert_ne!(cal.report.verdict.status, Status::Failed, "{what}: {:?}", cal.report.verdict);
        // The redundant parameters stay exactly as drawn.
        let params = cal.identification.model.params();
        for name in &cal.report.redundant {
            let k = params.iter().position(|p| &p.name == name).unwrap();
            assert_eq!(cal.identification.delta[k], 0.0, "{what}: redundant {name} moved");
        }
        let held: Vec<String> = cal
            .report
            .redundant
            .iter()
            .filter(|n| !n.starts_with(['m', 't']))
            .cloned()
            .collect();
        assert!(held.iter().any(|n| n.starts_with("6-T.")), "{what}: {held:?}");
        let mut fixed = file.clone();
        fixed.fixed.extend(held.iter().cloned());
        let baseline = calibrate(&fixed, &data, None, &opts).unwrap();
        let e = user_tool_error(&cal.model_file, &file, &*proto, user, &check_q);
        let b = user_tool_error(&baseline.model_file, &file, &*proto, user, &check_q);
        eprintln!("reflector {what}: compensated to the user's TCP, max error {e:.4} mm; with the redundant parameters fixed in the file {b:.4} mm");
        assert!(e <= 1.1 * b + 1e-6, "{what}: {e} mm against {b} mm");
    }
}
