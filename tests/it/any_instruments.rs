//! Any instruments in one file, in any row order: seats, a ballbar, sphere and plane touches
//! and ten tracker points, shuffled, on a serial arm (the IRB 120) and a limbs machine (the 6-RUS
//! hexapod). Every instrument is started from the tool point whichever instruments find
//! (`instrument::start_points`). Noise-free, held-out tool points are the truth's to round-off;
//! with noise, the held-out error is that of the same fit started at the truth (the start costs
//! no accuracy). `cargo test --test it any_instruments -- --nocapture` prints the figures of
//! docs/instruments.md ("Any instruments in one file").
use crate::instruments::{irb120_points, points_of};
use crate::mixed::{placement, tracker_rows, truth_of};
use kinecal::calibrate::{calibrate, CalibrationOptions};
use kinecal::instrument::simulate::{distance_rows, seat_rows, touch_rows, Touched, DEFAULT_BALLBAR_RANGE_MM};
use kinecal::io::data_file::DataSet;
use kinecal::io::model_file::{Frames, ModelFile};
use kinecal::measure::{KindNoise, Measurement, Noise, RowKind};
use kinecal::model::framed::Framed;
use kinecal::se3;
use kinecal::simulate::random_configurations;
use kinecal::Mechanism;
use nalgebra::Vector3;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The probe's tip radius (mm).
const PROBE_MM: f64 = 1.5;

/// The simulated noise of each kind (mm): tracker per axis, seat per axis, along the bar, along
/// a touched surface's normal.
#[derive(Clone, Copy)]
struct Sigmas {
    tracker: f64,
    seat: f64,
    distance: f64,
    probe: f64,
}

const NOISE_FREE: Sigmas = Sigmas {
    tracker: 0.0,
    seat: 0.0,
    distance: 0.0,
    probe: 0.0,
};

const NOISY: Sigmas = Sigmas {
    tracker: 0.020,
    seat: 0.005,
    distance: 0.005,
    probe: 0.005,
};

/// What each kind's rows are weighted by: the simulated σ (10 µm where it is zero).
fn stated(s: Sigmas) -> Noise {
    let or = |v: f64| if v > 0.0 { v } else { 0.01 };
    Noise {
        position: or(s.tracker),
        kinds: KindNoise {
            seat: Some(or(s.seat)),
            distance: Some(or(s.distance)),
            probe: Some(or(s.probe)),
        },
        ..Noise::default()
    }
}

/// The artifacts of machine `file` in the frame `truth` measures in: seats (three), ballbar
/// pivots (three, 100 mm below the seats), spheres (three) and planes (three), and how far
/// the tool may tilt in a seat (deg).
struct Artifacts {
    seats: Vec<Vector3<f64>>,
    pivots: Vec<Vector3<f64>>,
    touched: Vec<Touched>,
    tilt_deg: f64,
}

fn artifacts(file: &ModelFile, truth: &Framed<Box<dyn Mechanism>>) -> Artifacts {
    let seats = if file.name == "irb120" {
        irb120_points(truth, &[[0.0, 0.0, 0.0], [0.5, 0.1, -0.1], [-0.5, -0.1, 0.2]])
    } else {
        points_of(truth, file)[..3].to_vec()
    };
    let pivots = seats.iter().map(|c| c - Vector3::new(0.0, 0.0, 100.0)).collect();
    // Spheres and planes: on the IRB 120 reference spheres (25.4 mm) in front of it and three
    // faces of a box; elsewhere spheres beyond the workspace whose surfaces pass through its
    // middle and three planes through it, tilted against each other.
    let mut touched = Vec::new();
    if file.name == "irb120" {
        let seen = |p: [f64; 3]| truth.measurement.transform_point(&Vector3::from(p).into()).coords;
        for (k, c) in [[300.0, 0.0, 300.0], [350.0, -150.0, 250.0], [350.0, 150.0, 250.0]]
            .into_iter()
            .enumerate()
        {
            touched.push(Touched::sphere(k, seen(c), 25.4, PROBE_MM));
        }
        let box_pose = truth.measurement * se3::pose_from_parts(Vector3::new(350.0, 0.0, 250.0), Vector3::new(0.0, 0.0, 0.35));
        for k in 0..3 {
            let n = box_pose.rotation * Vector3::ith(k, 1.0);
            touched.push(Touched::plane(k, box_pose.translation.vector + 50.0 * n, n, PROBE_MM));
        }
    } else {
        let qs = random_configurations(&*file.build(), &file.inputs(), 400, &mut ChaCha8Rng::seed_from_u64(34)).unwrap();
        let points: Vec<Vector3<f64>> = qs.iter().map(|q| truth.forward(q).unwrap().translation.vector).collect();
        let centre = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
        let size = (points.iter().map(|p| (p - centre).norm_squared()).sum::<f64>() / points.len() as f64).sqrt();
        let away = [
            Vector3::new(1.0, 0.0, -1.0),
            Vector3::new(-1.0, 1.0, -1.0),
            Vector3::new(0.0, -1.0, -1.5),
        ];
        for (k, d) in away.iter().enumerate() {
            let c = centre + d * 2.0 * size;
            touched.push(Touched::sphere(k, c, 2.0 * ((c - centre).norm() - PROBE_MM), PROBE_MM));
        }
        for (k, n) in [
            Vector3::new(1.0, 0.0, 0.3),
            Vector3::new(0.0, 1.0, 0.3),
            Vector3::new(0.3, -0.2, 1.0),
        ]
        .iter()
        .enumerate()
        {
            touched.push(Touched::plane(k, centre, n.normalize(), PROBE_MM));
        }
    }
    let tilt_deg = if file.name == "irb120" { 30.0 } else { 10.0 };
    Artifacts {
        seats,
        pivots,
        touched,
        tilt_deg,
    }
}

/// The rows of every kind on `truth` with noise `s`: 3 seats × 15, 3 pivots × 20 (a 100 ± 0.8 mm
/// ballbar), 20 touches on each sphere and plane, and `tracker` tracker positions; shuffled
/// (seed `order`).
fn mixed_rows(file: &ModelFile, truth: &Framed<Box<dyn Mechanism>>, s: Sigmas, tracker: usize, order: u64) -> Vec<Measurement> {
    let a = artifacts(file, truth);
    let mut rows = tracker_rows(truth, file, tracker, s.tracker);
    rows.extend(seat_rows(truth, &a.seats, &placement(file, 15, a.tilt_deg, s.seat)).unwrap());
    let bar = placement(file, 20, a.tilt_deg, s.distance);
    rows.extend(distance_rows(truth, &a.pivots, 100.0, DEFAULT_BALLBAR_RANGE_MM, &bar).unwrap());
    let per = 20;
    let candidates = random_configurations(truth, &file.inputs(), 30 * per * a.touched.len(), &mut ChaCha8Rng::seed_from_u64(7)).unwrap();
    rows.extend(touch_rows(truth, &candidates, &a.touched, per, s.probe, 8, &file.inputs()).unwrap());
    rows.shuffle(&mut ChaCha8Rng::seed_from_u64(order));
    rows
}

/// The held-out tool points' error of a calibration (30 random configurations): RMS and max,
/// directly against the truth when tracker rows placed the base, else after the best rigid
/// motion; the blunders set aside, the verdict.
struct Held {
    rms_mm: f64,
    max_mm: f64,
    blunders: usize,
    sigma0: f64,
    status: String,
}

/// `calibrate` from `file` (the nominal, or the truth's own file: the same fit started at the
/// truth) on `rows`, judged against `truth`.
fn held_out(file: &ModelFile, truth: &dyn Mechanism, rows: &[Measurement], noise: Noise) -> Held {
    let tracked = rows.iter().any(|m| RowKind::of(&m.obs) == Some(RowKind::Tracker));
    let data = DataSet::from_measurements("any.csv", rows.to_vec());
    let opts = CalibrationOptions {
        noise,
        ..CalibrationOptions::default()
    };
    let cal = calibrate(file, &data, None, &opts).unwrap_or_else(|e| panic!("{}: {e}", file.name));
    let back = ModelFile::load_str(std::path::Path::new("cal.toml"), &cal.model_file.to_toml().unwrap())
        .unwrap()
        .build();
    let qs = random_configurations(&*file.build(), &file.inputs(), 30, &mut ChaCha8Rng::seed_from_u64(99)).unwrap();
    let points = |m: &dyn Mechanism| -> Vec<Vector3<f64>> { qs.iter().map(|q| m.forward(q).unwrap().translation.vector).collect() };
    let (mut a, b) = (points(&*back), points(truth));
    if !tracked {
        let t = kinecal::measure::register_points(&a, &b).unwrap();
        a = a.iter().map(|p| t.transform_point(&(*p).into()).coords).collect();
    }
    let gaps: Vec<f64> = a.iter().zip(&b).map(|(p, q)| (p - q).norm()).collect();
    Held {
        rms_mm: (gaps.iter().map(|g| g * g).sum::<f64>() / gaps.len() as f64).sqrt(),
        max_mm: gaps.iter().copied().fold(0.0, f64::max),
        blunders: cal.blunders.len(),
        sigma0: cal.identification.sigma0,
        status: format!("{:?}: {}", cal.report.verdict.status, cal.report.verdict.reasons.join(" | ")),
    }
}

/// The truth's own model file: the prototype's geometry, the tracker's placement and the ball
/// as its frames. Calibrated from it, the fit starts at the truth.
fn truth_file(file: &ModelFile, truth: &Framed<Box<dyn Mechanism>>) -> ModelFile {
    let mut t = file.with_geometry_of(&*truth.inner).unwrap();
    t.frames = Some(Frames {
        measurement: truth.measurement,
        tool: truth.tool,
    });
    t
}

/// The machines: the IRB 120 and the Stewart platform written as limbs (its platform turns
/// enough to hold a ball in a seat from several orientations).
const MACHINES: [&str; 2] = ["irb120", "stewart-limbs"];

/// Noise-free, every kind in one shuffled file, with and without the ten tracker points: the
/// held-out tool points are the truth's to round-off (directly with the tracker, after a rigid
/// motion without).
#[test]
fn any_instruments_in_any_order_recover_a_serial_arm_and_a_limbs_machine() {
    let mut failures = Vec::new();
    // The 6-RUS hexapod (limbs) too: started from the flange, its sphere touches were set aside
    // as blunders.
    for name in MACHINES.into_iter().chain(["hexapod-6rus"]) {
        let (file, truth) = truth_of(name);
        for tracker in [10, 0] {
            let rows = mixed_rows(&file, &truth, NOISE_FREE, tracker, 5);
            let h = held_out(&file, &truth, &rows, stated(NOISE_FREE));
            let what = format!("{name}: {tracker} tracker + 3 seats × 15 + 3 pivots × 20 + 3 spheres × 20 + 3 planes × 20, shuffled");
            eprintln!(
                "{what}, noise-free: held-out max {:.2e} mm ({}), σ̂₀ {:.2e}, {} blunders; {}",
                h.max_mm,
                if tracker > 0 { "direct" } else { "after a rigid motion" },
                h.sigma0,
                h.blunders,
                h.status
            );
            if h.max_mm.is_nan() || h.max_mm >= 1e-9 || h.blunders > 0 || h.status.starts_with("Failed") {
                failures.push(format!("{what}: {:e} mm, {} blunders, {}", h.max_mm, h.blunders, h.status));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// With noise (tracker 20 µm, seats, ballbar and probe 5 µm, each kind weighted by its own σ):
/// the held-out error of the fit from the nominal is that of the same fit started at the truth.
#[test]
fn with_noise_any_instruments_lose_nothing_to_the_start() {
    let mut failures = Vec::new();
    for name in MACHINES {
        let (file, truth) = truth_of(name);
        for tracker in [10, 0] {
            let rows = mixed_rows(&file, &truth, NOISY, tracker, 5);
            let from_nominal = held_out(&file, &truth, &rows, stated(NOISY));
            let from_truth = held_out(&truth_file(&file, &truth), &truth, &rows, stated(NOISY));
            let ratio = from_nominal.rms_mm / from_truth.rms_mm;
            eprintln!(
                "{name}, {tracker} tracker + every instrument, with noise: held-out RMS {:.4} mm (max {:.4}, {} blunders, σ̂₀ {:.3}) from the nominal, {:.4} mm (max {:.4}, {} blunders) from the truth: {ratio:.3}×; {}",
                from_nominal.rms_mm,
                from_nominal.max_mm,
                from_nominal.blunders,
                from_nominal.sigma0,
                from_truth.rms_mm,
                from_truth.max_mm,
                from_truth.blunders,
                from_nominal.status
            );
            if ratio.is_nan() || ratio > 1.05 || from_nominal.blunders > 0 {
                failures.push(format!(
                    "{name}, {tracker} tracker: {ratio:.3}×, {} blunders",
                    from_nominal.blunders
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The starting model `calibrate` fits (`calibrate::instrument_model`): every kind's RMS
/// residual there (mm), in `RowKind::ALL` order.
fn start_residuals(file: &ModelFile, rows: &[Measurement]) -> Vec<(String, f64)> {
    let data = DataSet::from_measurements("any.csv", rows.to_vec());
    let (start, _, indexed) = kinecal::calibrate::instrument_model(file, &data, &[]).unwrap().unwrap();
    kinecal::report::kinds::kind_residuals(&*start, &indexed, &Noise::default())
        .into_iter()
        .map(|k| (k.kind, k.rms_mm))
        .collect()
}

/// Which rows of a set to keep.
type Keep<'a> = dyn Fn(&Measurement) -> bool + 'a;

/// Every instrument starts from the tool point whichever instruments find (seats, tracker,
/// ballbar, touches), in any row order: at the nominal geometry each kind's residual is that of
/// the machine's own errors (±0.5 mm / ±0.1°), not of a probe centre taken at the flange
/// 120 mm away; and the start is the same whatever the rows' order.
#[test]
fn every_kind_starts_from_the_tool_point_the_others_find() {
    use kinecal::measure::Observation;
    let mut failures = Vec::new();
    for name in ["irb120", "stewart-limbs", "hexapod-6rus"] {
        let (file, truth) = truth_of(name);
        let all = mixed_rows(&file, &truth, NOISE_FREE, 10, 5);
        let tracker = |m: &Measurement| RowKind::of(&m.obs) == Some(RowKind::Tracker);
        let seat = |m: &Measurement| matches!(m.obs, Observation::Seat(_));
        let bar = |m: &Measurement| matches!(m.obs, Observation::Distance { .. });
        let sets: [(&str, &Keep<'_>); 5] = [
            ("every kind", &|_| true),
            ("every kind but the tracker", &|m| !tracker(m)),
            ("seats and touches", &|m| !tracker(m) && !bar(m)),
            ("ballbar and touches", &|m| !tracker(m) && !seat(m)),
            ("spheres and planes", &|m| RowKind::of(&m.obs) == Some(RowKind::Probe)),
        ];
        for (what, keep) in sets {
            let rows: Vec<Measurement> = all.iter().filter(|m| keep(m)).cloned().collect();
            let start = start_residuals(&file, &rows);
            let mut other = rows.clone();
            other.shuffle(&mut ChaCha8Rng::seed_from_u64(6));
            let again = start_residuals(&file, &other);
            eprintln!("{name}, {what}: residual at the start {start:.4?}");
            if let Some((kind, rms)) = start.iter().find(|(_, rms)| rms.is_nan() || *rms >= 2.0) {
                failures.push(format!("{name}, {what}: the {kind} rows start {rms:.3} mm off"));
            }
            for ((kind, a), (_, b)) in start.iter().zip(&again) {
                if (a - b).abs().is_nan() || (a - b).abs() > 1e-6 {
                    failures.push(format!("{name}, {what}: the {kind} rows start {a} mm off, {b} mm in another order"));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// From the command line: one file of every kind written by `data_text` (shuffled rows, each
/// filling its own kind's cells), and a file of sphere and plane touches alone; `identify`
/// calibrates both, `validate` judges each artifact in its own terms.
#[test]
fn cli_a_file_of_every_kind_and_a_file_of_spheres_and_planes() {
    use crate::cli::ok;
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let (file, truth) = truth_of("irb120");
    let all = mixed_rows(&file, &truth, NOISE_FREE, 10, 5);
    let touches: Vec<Measurement> = all
        .iter()
        .filter(|m| RowKind::of(&m.obs) == Some(RowKind::Probe))
        .cloned()
        .collect();
    for (name, rows, header_end) in [
        (
            "every.csv",
            &all,
            ",x_mm,y_mm,z_mm,seat,pivot,length_mm,sphere,sphere_diameter_mm,plane,probe_radius_mm",
        ),
        ("touches.csv", &touches, ",sphere,sphere_diameter_mm,plane,probe_radius_mm"),
    ] {
        let ids: Vec<i64> = (0..rows.len() as i64).collect();
        let text = kinecal::io::data_file::data_text(&dir.join(name), &file.data_columns(), &ids, rows, None).unwrap();
        assert!(
            text.lines().next().unwrap().ends_with(header_end),
            "{}",
            text.lines().next().unwrap()
        );
        std::fs::write(dir.join(name), &text).unwrap();
        let check = ok(dir, &["data", "check", "irb120", name]);
        assert!(
            check.contains("sphere 2: 20 touches") && check.contains("plane 2: 20 touches"),
            "{check}"
        );
        let out = ok(
            dir,
            &["identify", "irb120", name, "--out", "cal.toml", "--noise-mm", "0.01", "--force"],
        );
        eprintln!("{name}:\n{out}");
        assert!(out.contains("verdict: calibrated"), "{out}");
        let v = ok(dir, &["validate", "cal.toml", name]);
        eprintln!("{v}");
        assert!(
            v.contains("sphere 0: 20 rows, measured − modelled length 0.0000 mm RMS")
                && v.contains("plane 0: 20 rows, probe centres from their best plane 0.0000 mm RMS"),
            "{v}"
        );
    }
}
