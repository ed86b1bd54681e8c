//! A draw-wire sensor's unknown zero: distances read relative to an unknown zero per
//! pivot (`reading_mm`), the zeros estimated with the geometry.
use crate::instruments::points_of;
use kinecal::calibrate::{calibrate, CalibrationOptions};
use kinecal::instrument::simulate::{as_readings, distance_rows, middle_of_limits, Placement};
use kinecal::io::builtin;
use kinecal::io::data_file::{DataSet, MeasurementFormat};
use kinecal::io::model_file::ModelFile;
use kinecal::measure::{Measurement, Observation};
use kinecal::model::framed::Framed;
use kinecal::se3::{self, Pose};
use kinecal::simulate::{random_configurations, virtual_prototype};
use kinecal::Mechanism;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The true zeros of the three pivots (mm): the second makes every reading negative.
const ZEROS: [f64; 3] = [250.0, 140.0, -35.5];

struct Found {
    held_out_max_mm: f64,
    zero_errors_mm: Vec<f64>,
    zero_sigmas_mm: Vec<f64>,
    status: String,
}

/// A virtual prototype of `name` (±0.5 mm / ±0.1°, the ball at (15, −10, 120) mm), a draw-wire
/// at three pivots 100 mm below tool points (`pivots`) reading lengths drawn in 100 ± `range`
/// mm minus [`ZEROS`], `per_point` rows each, calibrated with default options (noise 0.01 mm);
/// held-out tool points against the truth's after a rigid motion, and the zeros found.
fn wire(
    name: &str,
    reference: Vec<f64>,
    tilt_deg: f64,
    range: f64,
    per_point: usize,
    pivots: impl Fn(&dyn Mechanism) -> Vec<Vector3<f64>>,
) -> Found {
    let file: ModelFile = builtin::model_file(name).unwrap();
    let nominal = file.build();
    let free = file.free_indices().unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (proto, _) = virtual_prototype(&nominal, &free, 0.5, 0.1f64.to_radians(), &mut rng);
    let truth = Framed::new(
        proto,
        Pose::identity(),
        se3::pose_from_parts(Vector3::new(15.0, -10.0, 120.0), Vector3::zeros()),
    );
    let how = Placement {
        per_point,
        reference,
        max_tilt: tilt_deg.to_radians(),
        noise_mm: 0.0,
        seed: 3,
        inputs: file.inputs(),
    };
    let centres: Vec<Vector3<f64>> = pivots(&truth).iter().map(|c| c - Vector3::new(0.0, 0.0, 100.0)).collect();
    let rows = as_readings(distance_rows(&truth, &centres, 100.0, range, &how).unwrap(), &ZEROS);
    assert!(rows.iter().all(|m| matches!(m.obs, Observation::Distance { relative: true, .. })));
    let data = DataSet::from_measurements("wire.csv", rows.clone());
    assert_eq!(data.format, MeasurementFormat::Distance);
    let (cal, back) = crate::instruments::calibrated(&file, &data, Vec::new());
    assert!(cal.identification.converged, "{name}: not converged");
    let held_out = random_configurations(&*nominal, &file.inputs(), 30, &mut rng).unwrap();
    let placed = kinecal::instrument::held_out(&*back, &rows, &[]).unwrap();
    let zero_errors_mm = placed
        .pivots
        .iter()
        .map(|p| p.zero_mm.expect("a reading pivot's zero") - ZEROS[p.pivot])
        .collect();
    let zero_sigmas_mm = (0..3)
        .map(|k| {
            let row = cal
                .report
                .params
                .iter()
                .find(|r| r.name == format!("pivot{k}.zero"))
                .expect("a zero parameter");
            assert_eq!(row.group, "artifact");
            row.std_dev
        })
        .collect();
    Found {
        held_out_max_mm: crate::instruments::held_out_gap(&*back, &truth, &held_out),
        zero_errors_mm,
        zero_sigmas_mm,
        status: format!("{:?}: {}", cal.report.verdict.status, cal.report.verdict.reasons.join(" | ")),
    }
}

impl Found {
    fn exact(&self, what: &str) {
        eprintln!(
            "{what}, noise-free, zeros unknown: held-out max {:.2e} mm after a rigid motion, zero errors {:?} mm, σ {:?} mm, {}",
            self.held_out_max_mm, self.zero_errors_mm, self.zero_sigmas_mm, self.status
        );
        assert!(self.held_out_max_mm < 1e-9, "{what}: held-out {:e} mm", self.held_out_max_mm);
        assert!(
            self.zero_errors_mm.iter().all(|e| e.abs() < 1e-8),
            "{what}: zeros {:?}",
            self.zero_errors_mm
        );
        assert!(self.zero_sigmas_mm.iter().all(|s| *s > 0.0), "{what}: a zero not identified");
    }
}

#[test]
fn unknown_zeros_recover_the_irb120_and_its_zeros() {
    const REFERENCE: [f64; 6] = [0.0, 0.35, 0.2, 0.0, 1.0, 0.0];
    let points = |truth: &dyn Mechanism| {
        [[0.0, 0.0, 0.0], [0.5, 0.1, -0.1], [-0.5, -0.1, 0.2]]
            .iter()
            .map(|s| {
                let mut q = REFERENCE.to_vec();
                for k in 0..3 {
                    q[k] += s[k];
                }
                truth.forward(&q).unwrap().translation.vector
            })
            .collect()
    };
    wire("irb120", REFERENCE.to_vec(), 35.0, 30.0, 40, points).exact("irb120, draw-wire 100 ± 30 mm, 3 pivots × 40");
}

#[test]
fn unknown_zeros_recover_the_pm5_machine() {
    let file: ModelFile = builtin::model_file("pm5").unwrap();
    let reference = middle_of_limits(&file.inputs());
    wire("pm5", reference, 15.0, 10.0, 40, |truth| points_of(truth, &file)[..3].to_vec())
        .exact("pm5, draw-wire 100 ± 10 mm, 3 pivots × 40");
}

/// Mistakes with readings are one line: a pivot with too few rows, one pivot with readings and
/// lengths, readings that never change.
#[test]
fn reading_mistakes_are_one_line() {
    let file: ModelFile = builtin::model_file("irb120").unwrap();
    let row = |pivot: usize, length: f64, relative: bool| Measurement {
        q: vec![0.1 * length.sin(), 0.2, 0.1, 0.0, 0.9 + 0.01 * length, 0.0],
        obs: Observation::Distance { pivot, length, relative },
        joints: Vec::new(),
    };
    let fail = |rows: Vec<Measurement>| {
        let data = DataSet::from_measurements("wire.csv", rows);
        let e = calibrate(&file, &data, None, &CalibrationOptions::default())
            .err()
            .expect("refused")
            .to_string();
        assert_eq!(e.lines().count(), 1, "{e}");
        e
    };
    let e = fail((0..4).map(|k| row(1, k as f64, true)).collect());
    assert!(e.contains("pivot 1 has 4 rows; at least 5"), "{e}");
    let e = fail((0..6).map(|k| row(0, k as f64, k % 2 == 0)).collect());
    assert!(e.contains("pivot 0 has 3 reading rows (zero unknown) and 3 length rows"), "{e}");
    let e = fail((0..6).map(|_| row(2, 12.5, true)).collect());
    assert!(e.contains("pivot 2: every reading is 12.5000 mm"), "{e}");
}

/// `simulate --pivots … --length-zero-mm` writes readings (`reading_mm`), `identify` estimates
/// the zeros with the geometry and prints them, `validate` of the calibrated file fits the
/// held-out readings.
#[test]
fn cli_draw_wire_simulate_identify_validate() {
    use crate::cli::{fails, ok};
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let sim = ok(
        dir,
        &[
            "simulate",
            "irb120",
            "--pivots",
            "400,0,200;450,100,150;350,-100,250",
            "--ballbar-mm",
            "100",
            "--ballbar-range-mm",
            "30",
            "--length-zero-mm",
            "250,140,-35.5",
            "--reference",
            "0,20,11.5,0,57,0",
            "--tool-mm",
            "15,-10,120",
            "--per-pivot",
            "40",
            "--tilt-deg",
            "35",
            "--out",
            "d.csv",
            "--truth",
            "t.toml",
            "--validation-poses",
            "10",
            "--validation-out",
            "v.csv",
        ],
    );
    eprintln!("{sim}");
    let data = std::fs::read_to_string(dir.join("d.csv")).unwrap();
    assert!(data.lines().next().unwrap().ends_with(",pivot,reading_mm"), "{data}");
    let check = ok(dir, &["data", "check", "irb120", "d.csv"]);
    assert!(
        check.contains("120 poses, measured: readings relative to an unknown zero"),
        "{check}"
    );
    let out = ok(dir, &["identify", "irb120", "d.csv", "--out", "cal.toml", "--noise-mm", "0.01"]);
    eprintln!("{out}");
    for (k, z) in ["250.0000", "140.0000", "-35.5000"].iter().enumerate() {
        assert!(out.contains(&format!("pivot {k}: zero {z} mm")), "{out}");
    }
    let worst = |model: &str| -> f64 {
        let out = ok(dir, &["validate", model, "v.csv"]);
        eprintln!("validate {model}: {out}");
        out.lines()
            .filter(|l| l.starts_with("pivot "))
            .map(|l| {
                let max = l.split(" mm RMS, ").nth(1).unwrap().split(' ').next().unwrap();
                max.parse::<f64>().unwrap()
            })
            .fold(0.0, f64::max)
    };
    let (nominal, calibrated) = (worst("irb120"), worst("cal.toml"));
    eprintln!("irb120 draw-wire via the CLI: held-out worst reading error {nominal:.4} mm (nominal) → {calibrated:.4} mm (calibrated)");
    assert!(nominal > 0.5 && calibrated < 1e-3, "{nominal} → {calibrated}");
    // A pivot with too few rows is one line.
    let short: String = data.lines().take(5).map(|l| format!("{l}\n")).collect();
    std::fs::write(dir.join("short.csv"), short).unwrap();
    for command in [
        &["identify", "irb120", "short.csv", "--out", "x.toml"][..],
        &["data", "check", "irb120", "short.csv"],
    ] {
        let e = fails(dir, command);
        assert!(e.trim().lines().count() == 1 && e.contains("pivot 0 has 4 rows; at least 5"), "{e}");
    }
}
