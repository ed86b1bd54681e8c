//! Mixed instruments: tracker rows beside seat rows, distances beside seats, in one
//! fit, each kind weighted by its own σ. Noise-free, held-out tool points are the truth's to
//! round-off (the tracker places the base: no rigid motion removed when it is in the set); with
//! noise the held-out 3-D error of the mixed set is printed beside each kind alone
//! (`cargo test --test it mixed -- --nocapture`; the figures are in docs/instruments.md).
use crate::instruments::{aligned_max, irb120_points, points_of, IRB120_REFERENCE};
use kinecal::calibrate::{calibrate, CalibrationOptions};
use kinecal::instrument::simulate::{distance_rows, middle_of_limits, seat_rows, Placement, DEFAULT_BALLBAR_RANGE_MM};
use kinecal::instrument::SeatDistance;
use kinecal::io::builtin;
use kinecal::io::data_file::DataSet;
use kinecal::io::model_file::ModelFile;
use kinecal::measure::{KindNoise, Measurement, Noise, Observation, RowKind};
use kinecal::model::framed::Framed;
use kinecal::se3;
use kinecal::simulate::{random_configurations, virtual_prototype};
use kinecal::Mechanism;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A virtual prototype of built-in `name` (errors ±0.5 mm / ±0.1°), the ball 120 mm out on its
/// flange, seen by a tracker standing 2 m away and turned: the truth the rows are drawn from.
pub(crate) fn truth_of(name: &str) -> (ModelFile, Framed<Box<dyn Mechanism>>) {
    let file: ModelFile = builtin::model_file(name).unwrap();
    let nominal = file.build();
    let free = file.free_indices().unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (proto, _) = virtual_prototype(&nominal, &free, 0.5, 0.1f64.to_radians(), &mut rng);
    let tracker = se3::pose_from_parts(Vector3::new(2000.0, -300.0, 150.0), Vector3::new(0.02, -0.03, 2.5));
    let ball = se3::pose_from_parts(Vector3::new(15.0, -10.0, 120.0), Vector3::zeros());
    (file, Framed::new(proto, tracker, ball))
}

/// `n` tracker positions of the tool point at random configurations (seed 21), noise σ per axis.
pub(crate) fn tracker_rows(truth: &dyn Mechanism, file: &ModelFile, n: usize, sigma: f64) -> Vec<Measurement> {
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let qs = random_configurations(&*file.build(), &file.inputs(), n, &mut rng).unwrap();
    let normal = Normal::new(0.0, sigma.max(1e-300)).unwrap();
    qs.into_iter()
        .map(|q| {
            let mut p = truth.forward(&q).unwrap().translation.vector;
            if sigma > 0.0 {
                p += Vector3::from_fn(|_, _| normal.sample(&mut rng));
            }
            Measurement {
                q,
                obs: Observation::Position(p),
                joints: Vec::new(),
            }
        })
        .collect()
}

/// Where rows are drawn about: the IRB 120's reference, else the middle of the limits.
fn reference(file: &ModelFile) -> Vec<f64> {
    if file.name == "irb120" {
        IRB120_REFERENCE.to_vec()
    } else {
        middle_of_limits(&file.inputs())
    }
}

/// Artifact points: on the IRB 120 the tool points near its reference, else [`points_of`].
fn artifact_points(file: &ModelFile, truth: &dyn Mechanism) -> Vec<Vector3<f64>> {
    if file.name != "irb120" {
        return points_of(truth, file);
    }
    irb120_points(truth, &[[0.0, 0.0, 0.0], [0.5, 0.1, -0.1], [-0.5, -0.1, 0.2], [0.2, 0.3, 0.3]])
}

/// Ballbar pivots 100 mm below the first three [`artifact_points`].
fn pivots(file: &ModelFile, truth: &dyn Mechanism) -> Vec<Vector3<f64>> {
    artifact_points(file, truth)[..3]
        .iter()
        .map(|c| c - Vector3::new(0.0, 0.0, 100.0))
        .collect()
}

/// How rows are drawn on `file` about its [`reference`].
pub(crate) fn placement(file: &ModelFile, per_point: usize, max_tilt_deg: f64, noise_mm: f64) -> Placement {
    Placement {
        per_point,
        reference: reference(file),
        max_tilt: max_tilt_deg.to_radians(),
        noise_mm,
        seed: 3,
        inputs: file.inputs(),
    }
}

/// Calibrate `rows` with the stated noise; `None` when the fit is refused. The held-out tool
/// points' largest gap to the truth's: directly (`None` without tracker rows: no frame) and
/// after the best rigid motion; and the report's verdict.
struct Fit {
    direct_mm: Option<f64>,
    aligned_mm: f64,
    aligned_rms_mm: f64,
    /// After the best similarity (rotation, translation, scale).
    similar_mm: f64,
    status: String,
    per_kind: String,
}

fn fit(file: &ModelFile, truth: &dyn Mechanism, rows: Vec<Measurement>, noise: Noise, distances: Vec<SeatDistance>) -> Result<Fit, String> {
    let tracked = rows.iter().any(|m| RowKind::of(&m.obs) == Some(RowKind::Tracker));
    let data = DataSet::from_measurements("mixed.csv", rows);
    let opts = CalibrationOptions {
        noise,
        seat_distances: distances,
        ..CalibrationOptions::default()
    };
    let cal = calibrate(file, &data, None, &opts).map_err(|e| e.to_string())?;
    let back = ModelFile::load_str(std::path::Path::new("cal.toml"), &cal.model_file.to_toml().unwrap())
        .unwrap()
        .build();
    let held_out = random_configurations(&*file.build(), &file.inputs(), 30, &mut ChaCha8Rng::seed_from_u64(99)).unwrap();
    let points = |m: &dyn Mechanism| -> Vec<Vector3<f64>> { held_out.iter().map(|q| m.forward(q).unwrap().translation.vector).collect() };
    let (a, b) = (points(&*back), points(truth));
    let direct = a.iter().zip(&b).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
    let t = kinecal::measure::register_points(&a, &b).unwrap();
    let gaps: Vec<f64> = a
        .iter()
        .zip(&b)
        .map(|(p, q)| (t.transform_point(&(*p).into()).coords - q).norm())
        .collect();
    Ok(Fit {
        direct_mm: tracked.then_some(direct),
        aligned_mm: aligned_max(&a, &b),
        similar_mm: crate::contract::similar_gap(&*back, truth, &held_out),
        aligned_rms_mm: (gaps.iter().map(|g| g * g).sum::<f64>() / gaps.len() as f64).sqrt(),
        status: format!("{:?}: {}", cal.report.verdict.status, cal.report.verdict.reasons.join(" | ")),
        per_kind: format!(
            "{} (rank {} of {} free, redundant: {})",
            cal.report
                .kinds
                .iter()
                .map(|k| format!("{} {:.4} mm RMS = {:.2} σ", k.kind, k.rms_mm, k.ratio))
                .collect::<Vec<_>>()
                .join(", "),
            cal.report.rank,
            cal.report.free,
            cal.report.redundant.join(" ")
        ),
    })
}

/// The seats' rows of `truth` at the tool points of [`points_of`] (`n` of them).
fn seats(file: &ModelFile, truth: &dyn Mechanism, n: usize, how: &Placement) -> Vec<Measurement> {
    seat_rows(truth, &artifact_points(file, truth)[..n], how).unwrap()
}

/// The noise-free fits: held-out points within 1e-9 mm of the truth's, directly when the
/// tracker placed the base.
fn exact(what: &str, f: Fit) {
    eprintln!(
        "{what}, noise-free: held-out max {:?} mm direct, {:.2e} mm after a rigid motion; {}; {}",
        f.direct_mm, f.aligned_mm, f.per_kind, f.status
    );
    assert!(
        f.direct_mm.unwrap_or(f.aligned_mm) < 1e-9,
        "{what}: {:?} / {:e}",
        f.direct_mm,
        f.aligned_mm
    );
}

fn exact_noise() -> Noise {
    Noise {
        position: 0.01,
        ..Noise::default()
    }
}

/// Ten tracker positions and seats, on a serial arm, a closed-loop machine and a limbs machine:
/// the seats need no known distance (the tracker gives the scale and places the base).
#[test]
fn tracker_points_and_seats_recover_serial_closed_and_limbs_machines() {
    for (name, per_seat, tilt) in [("irb120", 15, 35.0), ("pm5", 30, 35.0), ("hexapod-6rus", 20, 10.0)] {
        let (file, truth) = truth_of(name);
        let mut rows = tracker_rows(&truth, &file, 10, 0.0);
        rows.extend(seats(&file, &truth, 4, &placement(&file, per_seat, tilt, 0.0)));
        exact(
            &format!("{name}: 10 tracker positions + 4 seats × {per_seat}"),
            fit(&file, &truth, rows, exact_noise(), Vec::new()).unwrap(),
        );
    }
}

/// A ballbar's lengths beside seats (no tracker): up to where the machine stands.
#[test]
fn distances_and_seats_recover_a_serial_arm() {
    let (file, truth) = truth_of("irb120");
    let how = placement(&file, 30, 30.0, 0.0);
    let pivots = pivots(&file, &truth);
    let mut rows = distance_rows(&truth, &pivots, 100.0, DEFAULT_BALLBAR_RANGE_MM, &how).unwrap();
    rows.extend(seats(&file, &truth, 3, &how));
    exact(
        "irb120: 3 pivots × 30 + 3 seats × 30",
        fit(&file, &truth, rows, exact_noise(), Vec::new()).unwrap(),
    );
}

/// Tracker positions and ballbar lengths.
#[test]
fn tracker_points_and_distances_recover_a_serial_arm() {
    let (file, truth) = truth_of("irb120");
    let how = placement(&file, 30, 30.0, 0.0);
    let pivots = pivots(&file, &truth);
    let mut rows = tracker_rows(&truth, &file, 10, 0.0);
    rows.extend(distance_rows(&truth, &pivots, 100.0, DEFAULT_BALLBAR_RANGE_MM, &how).unwrap());
    exact(
        "irb120: 10 tracker positions + 3 pivots × 30",
        fit(&file, &truth, rows, exact_noise(), Vec::new()).unwrap(),
    );
}

/// With noise (tracker 20 µm, seats 5 µm, each weighted by its own σ): the held-out 3-D error of
/// 10 tracker positions + 4 seats × 15 beside the tracker's 10 alone, the seats alone (with the
/// true distance of two, their scale) and 30 tracker positions (as many rows as the mixed
/// set's tracker + a third of its seats' rows).
#[test]
fn with_noise_the_mixed_set_beside_each_alone() {
    let (file, truth) = truth_of("irb120");
    let noise = Noise {
        position: 0.020,
        kinds: KindNoise {
            seat: Some(0.005),
            ..KindNoise::default()
        },
        ..Noise::default()
    };
    let seat_set = seats(&file, &truth, 4, &placement(&file, 15, 35.0, 0.005));
    let centre = |s: usize| {
        let m = seat_set.iter().find(|m| m.obs == Observation::Seat(s)).unwrap();
        truth.forward(&m.q).unwrap().translation.vector
    };
    let known = vec![SeatDistance {
        a: 0,
        b: 1,
        length: (centre(0) - centre(1)).norm(),
    }];
    let mut mixed = tracker_rows(&truth, &file, 10, 0.020);
    mixed.extend(seat_set.clone());
    for (what, rows, distances) in [
        ("10 tracker positions + 4 seats × 15 (mixed)", mixed, Vec::new()),
        ("10 tracker positions alone", tracker_rows(&truth, &file, 10, 0.020), Vec::new()),
        ("30 tracker positions alone", tracker_rows(&truth, &file, 30, 0.020), Vec::new()),
        ("4 seats × 15 alone (+ the distance of two)", seat_set, known),
    ] {
        match fit(&file, &truth, rows, noise, distances) {
            Ok(f) => eprintln!(
                "irb120 with noise, {what}: held-out max {} direct, {:.4} mm max / {:.4} mm RMS after a rigid motion; {}; {}",
                f.direct_mm.map_or("—".into(), |d| format!("{d:.4} mm")),
                f.aligned_mm,
                f.aligned_rms_mm,
                f.per_kind,
                f.status
            ),
            Err(e) => eprintln!("irb120 with noise, {what}: refused: {e}"),
        }
    }
}

/// Seats stated four times better than they are: the verdict names the seat rows (a warning,
/// never a failure), and each kind's ratio to its own σ is in the report.
#[test]
fn a_kind_far_above_its_own_noise_is_named() {
    let (file, truth) = truth_of("irb120");
    let mut rows = tracker_rows(&truth, &file, 10, 0.020);
    rows.extend(seats(&file, &truth, 4, &placement(&file, 15, 35.0, 0.005)));
    let noise = Noise {
        position: 0.020,
        kinds: KindNoise {
            seat: Some(0.0012),
            ..KindNoise::default()
        },
        ..Noise::default()
    };
    let f = fit(&file, &truth, rows, noise, Vec::new()).unwrap();
    eprintln!("{}; {}", f.per_kind, f.status);
    assert!(f.status.contains("the seat rows' residual is"), "{}", f.status);
    assert!(!f.status.contains("the tracker rows' residual"), "{}", f.status);
    assert!(!f.status.starts_with("Failed"), "{}", f.status);
}

/// `[noise]` per kind in a model file: read in the file's unit, written back, a kind without
/// its own σ on the position noise; a σ ≤ 0 is a one-line error.
#[test]
fn noise_per_kind_in_the_model_file() {
    let base = builtin::model_file("irb120").unwrap().to_toml().unwrap();
    let with = |noise: &str| format!("{base}\n[noise]\nposition = 0.02\norientation = 0.02\n{noise}\n");
    let file = ModelFile::load_str(std::path::Path::new("m.toml"), &with("seat = 0.005")).unwrap();
    let n = file.noise.unwrap();
    assert_eq!(
        (n.sigma(RowKind::Seat), n.sigma(RowKind::Distance), n.sigma(RowKind::Tracker)),
        (0.005, 0.02, 0.02)
    );
    let back = ModelFile::load_str(std::path::Path::new("m.toml"), &file.to_toml().unwrap()).unwrap();
    assert_eq!(back.noise, file.noise);
    // The touch probe's σ too (the file written by `identify --kind-noise probe=…` reads back).
    let file = ModelFile::load_str(std::path::Path::new("m.toml"), &with("probe = 0.004")).unwrap();
    assert_eq!(file.noise.unwrap().sigma(RowKind::Probe), 0.004);
    let back = ModelFile::load_str(std::path::Path::new("m.toml"), &file.to_toml().unwrap()).unwrap();
    assert_eq!(back.noise, file.noise);
    let e = ModelFile::load_str(std::path::Path::new("m.toml"), &with("distance = 0"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("m.toml") && e.contains("distance must be finite and > 0") && !e.contains('\n'),
        "{e}"
    );
}

/// From the command line: a file mixing tracker positions and seat rows (written by
/// `data_text`, empty cells for the other kind), `identify` with each kind's σ, `validate` of
/// the calibrated file on the same file (the tracker rows' errors, then the seats' spread).
#[test]
fn cli_identify_and_validate_a_mixed_file() {
    use crate::cli::{fails, ok};
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let (file, truth) = truth_of("irb120");
    let mut rows = tracker_rows(&truth, &file, 10, 0.0);
    rows.extend(seats(&file, &truth, 4, &placement(&file, 15, 35.0, 0.0)));
    let ids: Vec<i64> = (0..rows.len() as i64).collect();
    let text = kinecal::io::data_file::data_text(&dir.join("d.csv"), &file.data_columns(), &ids, &rows, None).unwrap();
    assert!(text.lines().next().unwrap().ends_with(",x_mm,y_mm,z_mm,seat"), "{text}");
    std::fs::write(dir.join("d.csv"), &text).unwrap();
    let out = ok(
        dir,
        &[
            "identify",
            "irb120",
            "d.csv",
            "--out",
            "cal.toml",
            "--noise-mm",
            "0.01",
            "--kind-noise",
            "seat=0.005",
        ],
    );
    assert!(out.contains("verdict: calibrated"), "{out}");
    assert!(
        out.contains("seat rows (60): residual") && out.contains("tracker rows (10)"),
        "{out}"
    );
    let cal = std::fs::read_to_string(dir.join("cal.toml")).unwrap();
    assert!(cal.contains("seat = 0.005"), "{cal}");
    let v = ok(dir, &["validate", "cal.toml", "d.csv"]);
    eprintln!("{v}");
    assert!(v.contains("10 tracker rows"), "{v}");
    let bad = fails(dir, &["identify", "irb120", "d.csv", "--out", "x.toml", "--kind-noise", "seat=-1"]);
    assert!(
        bad.contains("--kind-noise") && bad.contains("> 0") && !bad.trim().contains('\n'),
        "{bad}"
    );
}

/// With noise, no tracker: a ballbar (5 µm along the bar) and seats (5 µm) mixed, beside each
/// alone (the seats with the true distance of two); held-out error after a rigid motion.
#[test]
fn with_noise_distances_and_seats_beside_each_alone() {
    let (file, truth) = truth_of("irb120");
    let noise = Noise {
        position: 0.020,
        kinds: KindNoise {
            seat: Some(0.005),
            distance: Some(0.005),
            ..KindNoise::default()
        },
        ..Noise::default()
    };
    let how = placement(&file, 30, 30.0, 0.005);
    let pivots = pivots(&file, &truth);
    let bar = distance_rows(&truth, &pivots, 100.0, DEFAULT_BALLBAR_RANGE_MM, &how).unwrap();
    let seat_set = seats(&file, &truth, 3, &how);
    let centre = |s: usize| {
        let m = seat_set.iter().find(|m| m.obs == Observation::Seat(s)).unwrap();
        truth.forward(&m.q).unwrap().translation.vector
    };
    let known = vec![SeatDistance {
        a: 0,
        b: 1,
        length: (centre(0) - centre(1)).norm(),
    }];
    let mut mixed = bar.clone();
    mixed.extend(seat_set.clone());
    for (what, rows, distances) in [
        ("3 pivots × 30 + 3 seats × 30 (mixed)", mixed.clone(), Vec::new()),
        ("3 pivots × 30 + 3 seats × 30 (mixed, + the distance of two)", mixed, known.clone()),
        ("3 pivots × 30 alone", bar, Vec::new()),
        ("3 seats × 30 alone (+ the distance of two)", seat_set, known),
    ] {
        match fit(&file, &truth, rows, noise, distances) {
            Ok(f) => eprintln!(
                "irb120 with noise, {what}: held-out {:.4} mm max / {:.4} mm RMS after a rigid motion; {}; {}",
                f.aligned_mm, f.aligned_rms_mm, f.per_kind, f.status
            ),
            Err(e) => eprintln!("irb120 with noise, {what}: refused: {e}"),
        }
    }
}

/// Touch-probe kinds alone and beside ten tracker points, noise-free: a UR5e from its URDF and
/// the IRB 120, reference spheres, a datum cube and three unknown planes (the cube's faces)
/// standing in the tracker's frame.
#[test]
fn touches_alone_and_beside_tracker_points_recover_a_ur5e_and_an_irb120() {
    use kinecal::instrument::simulate::{touch_rows, Touched};
    let ur5e = kinecal::io::urdf::import(&crate::urdf::ur5e_urdf(), Some("base_link_inertia"), Some("tool0")).unwrap();
    let machines = [
        (
            ur5e,
            [[450.0, -150.0, 100.0], [450.0, 150.0, 100.0], [300.0, 0.0, 300.0]],
            [400.0, 0.0, 150.0],
        ),
        (
            builtin::model_file("irb120").unwrap(),
            [[300.0, 0.0, 300.0], [350.0, -150.0, 250.0], [350.0, 150.0, 250.0]],
            [350.0, 0.0, 250.0],
        ),
    ];
    for (file, spheres, cube) in machines {
        let nominal = file.build();
        let (proto, _) = virtual_prototype(
            &nominal,
            &file.free_indices().unwrap(),
            0.5,
            0.1f64.to_radians(),
            &mut ChaCha8Rng::seed_from_u64(11),
        );
        let tracker = se3::pose_from_parts(Vector3::new(2000.0, -300.0, 150.0), Vector3::new(0.02, -0.03, 2.5));
        let truth = Framed::new(
            proto,
            tracker,
            se3::pose_from_parts(Vector3::new(15.0, -10.0, 120.0), Vector3::zeros()),
        );
        let seen = |p: [f64; 3]| tracker.transform_point(&Vector3::from(p).into()).coords;
        let spheres: Vec<Touched> = (0..3).map(|k| Touched::sphere(k, seen(spheres[k]), 25.4, 1.5)).collect();
        let cube_pose = tracker * se3::pose_from_parts(Vector3::from(cube), Vector3::new(0.0, 0.0, 20f64.to_radians()));
        let cube = Touched::cube(cube_pose, 100.0, 1.5);
        // Three of the cube's faces as unknown planes (+x, +y, +z).
        let planes: Vec<Touched> = (0..3)
            .map(|k| {
                let n = cube_pose.rotation * Vector3::ith(k, 1.0);
                Touched::plane(k, cube_pose.translation.vector + 50.0 * n, n, 1.5)
            })
            .collect();
        let inputs = file.inputs();
        let touched = |artifacts: &[Touched], per: usize, seed: u64| {
            let candidates =
                random_configurations(&truth, &inputs, 30 * per * artifacts.len(), &mut ChaCha8Rng::seed_from_u64(seed)).unwrap();
            touch_rows(&truth, &candidates, artifacts, per, 0.0, seed, &inputs).unwrap()
        };
        // Planes give no length: alone on these arms (every joint turns) the fit holds the scale
        // by keeping one link as drawn, right up to a similarity, and the verdict names it;
        // beside the tracker they calibrate (the tracker gives the scale).
        for (what, rows, alone) in [
            ("3 spheres × 30", touched(&spheres, 30, 3), true),
            ("a datum cube, 6 faces × 10", touched(&cube, 10, 4), true),
            ("3 unknown planes × 30", touched(&planes, 30, 5), false),
        ] {
            let name = &file.name;
            let by_itself = fit(&file, &truth, rows.clone(), exact_noise(), Vec::new()).unwrap();
            if alone {
                exact(&format!("{name}: {what}"), by_itself);
            } else {
                eprintln!(
                    "{name}: {what} alone: held-out max {:.2e} mm after a rigid motion, {:.2e} mm after a similarity; {}",
                    by_itself.aligned_mm, by_itself.similar_mm, by_itself.status
                );
                assert!(by_itself.status.contains("is kept as drawn"), "{}", by_itself.status);
                assert!(
                    by_itself.similar_mm < 1e-9,
                    "{what}: {:e} mm after a similarity",
                    by_itself.similar_mm
                );
            }
            let mut mixed = tracker_rows(&truth, &file, 10, 0.0);
            mixed.extend(rows);
            exact(
                &format!("{name}: 10 tracker positions + {what}"),
                fit(&file, &truth, mixed, exact_noise(), Vec::new()).unwrap(),
            );
        }
    }
}

/// A validation file mixing tracker rows and seats beside a mixed identification: the tracker
/// rows are judged as poses in the frame the tracker placed, the seats (numbered 0 and 1 like
/// the identification's, at other places) as held-out artifacts of their own. Noise-free, both
/// are met to round-off.
#[test]
fn a_mixed_validation_file_judges_tracker_rows_as_poses_and_seats_as_their_own() {
    let (file, truth) = truth_of("irb120");
    let mut tracker = tracker_rows(&truth, &file, 20, 0.0);
    let held_tracker = tracker.split_off(10);
    let all = seats(&file, &truth, 4, &placement(&file, 15, 35.0, 0.0));
    let (mut rows, mut held): (Vec<Measurement>, Vec<Measurement>) =
        all.into_iter().partition(|m| matches!(m.obs, Observation::Seat(s) if s < 2));
    for m in &mut held {
        let Observation::Seat(s) = m.obs else { unreachable!() };
        m.obs = Observation::Seat(s - 2);
    }
    rows.extend(tracker);
    held.extend(held_tracker);
    let opts = CalibrationOptions {
        noise: exact_noise(),
        ..CalibrationOptions::default()
    };
    let data = DataSet::from_measurements("mixed.csv", rows);
    let validation = DataSet::from_measurements("held.csv", held);
    let cal = calibrate(&file, &data, Some(&validation), &opts).unwrap();
    let poses = cal.report.validation.as_ref().expect("the tracker rows, as poses");
    let seats = cal.report.held_out.as_ref().expect("the seats, placed by their own rows");
    eprintln!(
        "irb120, mixed validation: 10 tracker rows {:.2e} mm RMS, 2 held-out seats {:.4} → {:.2e} mm RMS",
        poses.after_stats.position_rms_mm, seats.before_rms_mm, seats.after_rms_mm
    );
    assert_eq!((poses.after_stats.poses, seats.rows, seats.calibrated.seats.len()), (10, 30, 2));
    assert!(poses.after_stats.position_rms_mm < 1e-9 && seats.after_rms_mm < 1e-9);
    assert!(seats.before_rms_mm > 0.1, "{}", seats.before_rms_mm);
}
