//! A Klipper linear delta calibrated as a printer is: its probe's touches on the bed and a few
//! ballbar lengths. The truth and the check are the delta written here in Klipper's convention
//! (not kinecal's): tower `i`'s carriage at `b_i + d_i·(q_i + o_i)` (`q_i` the carriage height
//! the printer reports as configured when measured), a rod of `L_i` from it to the nozzle below.
use kinecal::calibrate::{calibrate, CalibrationOptions};
use kinecal::io::controllers::bed::bed_from_touches;
use kinecal::io::controllers::klipper_delta::{export_with, KlipperDelta, KlipperOptions};
use kinecal::io::data_file::DataSet;
use kinecal::measure::{Measurement, Noise, Observation, Touch};
use nalgebra::{Matrix3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The printer as configured (Klipper's defaults): the model the calibration starts from.
fn configured() -> KlipperDelta {
    KlipperDelta {
        radius: 140.0,
        angle: [210.0, 330.0, 90.0],
        arm_length: [250.0; 3],
        position_endstop: [250.0; 3],
    }
}

/// A delta in Klipper's convention, written here.
#[derive(Debug, Clone)]
struct Printer {
    base: [Vector3<f64>; 3],
    dir: [Vector3<f64>; 3],
    arm: [f64; 3],
    offset: [f64; 3],
}

impl Printer {
    /// Klipper's parameters read from `printer.cfg` text, the inputs' endstop values `upper`:
    /// carriage height `h = q − upper + position_endstop + √(L² − R²)`.
    fn of_cfg(text: &str, upper: [f64; 3]) -> Printer {
        let (mut r, mut a, mut l, mut e) = (0.0, [0.0; 3], [0.0; 3], [0.0; 3]);
        let mut tower = 0;
        for line in text.lines().filter(|l| !l.starts_with('#')) {
            if let Some(t) = line.strip_prefix("[stepper_") {
                tower = ["a]", "b]", "c]"].iter().position(|x| *x == t).unwrap();
            } else if let Some((k, v)) = line.split_once(':') {
                let v = v.trim();
                match k {
                    "delta_radius" => r = v.parse().unwrap(),
                    "angle" => a[tower] = v.parse::<f64>().unwrap(),
                    "arm_length" => l[tower] = v.parse().unwrap(),
                    "position_endstop" => e[tower] = v.parse().unwrap(),
                    _ => {}
                }
            }
        }
        Printer {
            base: std::array::from_fn(|i| Vector3::new(r * a[i].to_radians().cos(), r * a[i].to_radians().sin(), 0.0)),
            dir: [Vector3::z(); 3],
            arm: l,
            offset: std::array::from_fn(|i| e[i] + (l[i] * l[i] - r * r).sqrt() - upper[i]),
        }
    }

    fn carriage(&self, i: usize, q: f64) -> Vector3<f64> {
        self.base[i] + self.dir[i] * (q + self.offset[i])
    }

    /// The inputs that put the nozzle at `p` (the carriage above it on its rail).
    fn inverse(&self, p: &Vector3<f64>) -> [f64; 3] {
        std::array::from_fn(|i| {
            let w = p - self.base[i];
            let s = self.dir[i].dot(&w);
            s + (s * s - w.norm_squared() + self.arm[i] * self.arm[i]).sqrt() - self.offset[i]
        })
    }

    /// The nozzle at inputs `q`: Newton on the three rod equations from below the carriages.
    fn forward(&self, q: &[f64]) -> Vector3<f64> {
        let c: [Vector3<f64>; 3] = std::array::from_fn(|i| self.carriage(i, q[i]));
        let mut p = (c[0] + c[1] + c[2]) / 3.0 - Vector3::new(0.0, 0.0, self.arm[0]);
        for _ in 0..100 {
            let f = Vector3::from_fn(|i, _| (p - c[i]).norm_squared() - self.arm[i] * self.arm[i]);
            let j = Matrix3::from_fn(|i, k| 2.0 * (p - c[i])[k]);
            let step = j.lu().solve(&-f).unwrap();
            p += step;
            if step.norm() < 1e-13 {
                break;
            }
        }
        p
    }
}

/// The truth: the configured printer with random errors of Klipper's kinds (each tower's radius
/// and angle, arm length, endstop: ±1 mm, ±0.5°), its rails tilted by up to `tilt_deg` (0:
/// Klipper's kinds only). Its frame: the bed is z = 0, towers about the origin.
fn truth(seed: u64, tilt_deg: f64) -> Printer {
    let c = configured();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut u = || rng.random_range(-1.0..1.0);
    let mut p = Printer {
        base: [Vector3::zeros(); 3],
        dir: [Vector3::z(); 3],
        arm: [0.0; 3],
        offset: [0.0; 3],
    };
    for i in 0..3 {
        let (r, a) = (c.radius + u(), (c.angle[i] + 0.5 * u()).to_radians());
        p.base[i] = Vector3::new(r * a.cos(), r * a.sin(), 0.0);
        p.arm[i] = c.arm_length[i] + u();
        // The endstop: where the carriage stops against where the configured printer puts it.
        p.offset[i] = c.position_endstop[i] + u() + (p.arm[i].powi(2) - r * r).sqrt() - c.endstop_height(i);
        let (tx, ty) = (tilt_deg * u(), tilt_deg * u());
        p.dir[i] = Vector3::new(tx.to_radians().tan(), ty.to_radians().tan(), 1.0).normalize();
    }
    p
}

/// The probe's touches on the bed (z = 0) at xy points of a 15 mm grid within 60 mm of the
/// middle, and a ballbar of 100 ± 0.8 mm from three pivots on the bed, `per_pivot` lengths
/// each in directions within 50° of the vertical (where the printer reaches): the rows.
fn bed_and_ballbar(truth: &Printer, per_pivot: usize, seed: u64) -> Vec<Measurement> {
    let mut rows = Vec::new();
    for i in -4..=4 {
        for j in -4..=4 {
            let p = Vector3::new(15.0 * i as f64, 15.0 * j as f64, 0.0);
            if p.norm() <= 60.0 {
                rows.push(Measurement {
                    q: truth.inverse(&p).to_vec(),
                    obs: Observation::Touch(Touch::Plane { plane: 0, probe: 0.0 }),
                    joints: Vec::new(),
                });
            }
        }
    }
    let upper: [f64; 3] = std::array::from_fn(|i| configured().endstop_height(i));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let pivots = [
        Vector3::new(50.0, 0.0, 0.0),
        Vector3::new(-25.0, 43.0, 0.0),
        Vector3::new(-25.0, -43.0, 0.0),
    ];
    for (k, pivot) in pivots.iter().enumerate() {
        let mut found = 0;
        while found < per_pivot {
            let length = 100.0 + rng.random_range(-0.8..0.8);
            let (tilt, turn) = (
                rng.random_range(0.0..50f64.to_radians()),
                rng.random_range(0.0..std::f64::consts::TAU),
            );
            let d = Vector3::new(tilt.sin() * turn.cos(), tilt.sin() * turn.sin(), tilt.cos());
            let q = truth.inverse(&(pivot + d * length));
            // Where the rods reach, and the carriages stay below their endstops.
            if q.iter().zip(&upper).any(|(q, u)| !q.is_finite() || q > u) {
                continue;
            }
            found += 1;
            rows.push(Measurement {
                q: q.to_vec(),
                obs: Observation::Distance {
                    pivot: k,
                    length,
                    relative: false,
                },
                joints: Vec::new(),
            });
        }
    }
    rows
}

/// The largest nozzle distance between two printers over a grid of carriage inputs spread over
/// the printable volume, the second seen from `origin` (its Klipper frame's origin in the first's).
fn apart(a: &Printer, b: &Printer, origin: Vector3<f64>) -> f64 {
    let mut worst = 0.0f64;
    for x in [-45.0, 0.0, 45.0] {
        for y in [-45.0, 0.0, 45.0] {
            for z in [5.0, 60.0, 120.0] {
                let q = a.inverse(&Vector3::new(x, y, z));
                worst = worst.max((a.forward(&q) - origin - b.forward(&q)).norm());
            }
        }
    }
    worst
}

/// The circle through the towers' feet: Klipper's origin and radius, and tower c's angle (°).
fn towers_circle(p: &Printer) -> (Vector3<f64>, f64, f64) {
    let (a, b, c) = (p.base[0], p.base[1], p.base[2]);
    let (ab, ac) = (b - a, c - a);
    let n = ab.cross(&ac);
    let centre = a + (ac.norm_squared() * n.cross(&ab) + ab.norm_squared() * ac.cross(&n)) / (2.0 * n.norm_squared());
    let t = c - centre;
    (centre, t.norm(), t.y.atan2(t.x).to_degrees())
}

/// Calibrate the configured printer from `rows`, find the bed, write Klipper's file with tower c
/// at `angle_c`: the file's text and what the export printed.
fn calibrate_and_export(rows: Vec<Measurement>, angle_c: f64) -> (String, kinecal::io::controllers::Projection, String) {
    let file = configured().model_file().unwrap();
    let data = DataSet::from_measurements("bed.csv", rows);
    let opts = CalibrationOptions {
        noise: Noise {
            position: 0.01,
            ..Noise::default()
        },
        ..CalibrationOptions::default()
    };
    let cal = calibrate(&file, &data, None, &opts).unwrap();
    let verdict = format!("{:?} {:?}", cal.report.verdict.status, cal.report.verdict.reasons);
    let bed = bed_from_touches(&cal.model_file, &data.measurements, None).unwrap();
    assert!(bed.max_mm < 1e-9, "{bed:?}");
    let export = export_with(
        &cal.model_file,
        &KlipperOptions {
            bed: Some(bed.bed),
            angle_c: Some(angle_c),
        },
    )
    .unwrap();
    (export.text, export.projection, verdict)
}

/// Errors of the kinds Klipper models (radii, tower angles, arm lengths, endstops), noise-free
/// bed touches and ballbar lengths: the written file, read by the delta written here, is the
/// truth to 1e-9 mm in the truth's own frame (bed z = 0, origin at the towers' circle centre,
/// tower c at its angle), and its values are the truth's Klipper parameters.
#[test]
fn printer_calibrated_on_its_bed_is_written_for_klipper_exactly() {
    let truth = truth(70, 0.0);
    let rows = bed_and_ballbar(&truth, 5, 71);
    let (touches, lengths) = (rows.iter().filter(|m| matches!(m.obs, Observation::Touch(_))).count(), 15);
    let (centre, radius, angle_c) = towers_circle(&truth);
    let (text, printed, verdict) = calibrate_and_export(rows, angle_c);
    let upper = std::array::from_fn(|i| configured().endstop_height(i));
    let written = Printer::of_cfg(&text, upper);
    let worst = apart(&truth, &written, centre);
    // The truth's Klipper parameters, from its geometry.
    let k = KlipperDelta::parse(&text).unwrap();
    let mut params = (k.radius - radius).abs();
    for (i, u) in upper.iter().enumerate() {
        let t = truth.base[i] - centre;
        let angle = t.y.atan2(t.x).to_degrees().rem_euclid(360.0);
        let endstop = u + truth.offset[i] - (truth.arm[i].powi(2) - radius * radius).sqrt();
        params = params
            .max((k.angle[i] - angle).to_radians().abs() * radius)
            .max((k.arm_length[i] - truth.arm[i]).abs())
            .max((k.position_endstop[i] - endstop).abs());
    }
    eprintln!(
        "Klipper kinds, {touches} bed touches + {lengths} ballbar lengths: written file vs truth {worst:.2e} mm (nozzle), parameters {params:.2e} mm; printed {}; {verdict}",
        printed.difference
    );
    assert!(verdict.starts_with("Calibrated"), "{verdict}");
    assert!(worst < 1e-9, "{worst:e} mm\n{text}");
    assert!(params < 1e-9, "{params:e}\n{text}");
    assert!(printed.difference.position_max_mm < 1e-9, "{}", printed.difference);
    assert!(
        !printed.not_represented.iter().any(|l| l.contains("leans")),
        "{:?}",
        printed.not_represented
    );
}

/// Rails tilted by up to 0.1° as well (no Klipper parameter): the calibration sees them, the
/// export names each rail's lean from the bed's normal, and the delta written here, read from
/// the file and placed on the truth's bed by the best turn and shift in its plane, leaves the
/// printed difference.
#[test]
fn tilted_rails_leave_the_printed_residual_named() {
    let truth = truth(72, 0.1);
    let rows = bed_and_ballbar(&truth, 12, 73);
    let (_, _, angle_c) = towers_circle(&truth);
    let (text, printed, verdict) = calibrate_and_export(rows, angle_c);
    let upper = std::array::from_fn(|i| configured().endstop_height(i));
    let written = Printer::of_cfg(&text, upper);
    // The nozzle positions of both at the same inputs, over the printable volume; the written
    // printer placed on the truth's bed (z kept) by the best turn and shift in the bed's plane.
    let mut rng = ChaCha8Rng::seed_from_u64(74);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    while a.len() < 500 {
        let (r, t) = (
            45.0 * rng.random_range(0.0..1.0f64).sqrt(),
            rng.random_range(0.0..std::f64::consts::TAU),
        );
        let q = truth.inverse(&Vector3::new(r * t.cos(), r * t.sin(), rng.random_range(5.0..120.0)));
        a.push(truth.forward(&q));
        b.push(written.forward(&q));
    }
    let (ma, mb) = (a.iter().sum::<Vector3<f64>>() / 500.0, b.iter().sum::<Vector3<f64>>() / 500.0);
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (p, k) in a.iter().zip(&b) {
        let (p, k) = (p - ma, k - mb);
        sxx += k.x * p.x + k.y * p.y;
        sxy += k.x * p.y - k.y * p.x;
    }
    let turn = sxy.atan2(sxx);
    let (s, c) = turn.sin_cos();
    let place = |k: &Vector3<f64>| {
        let k = k - mb;
        Vector3::new(c * k.x - s * k.y + ma.x, s * k.x + c * k.y + ma.y, k.z + mb.z)
    };
    let worst = a.iter().zip(&b).map(|(p, k)| (p - place(k)).norm()).fold(0.0f64, f64::max);
    let leans: Vec<&String> = printed.not_represented.iter().filter(|l| l.contains("leans")).collect();
    eprintln!(
        "rails tilted ≤ 0.1°: written file vs truth {worst:.4e} mm (after a turn {:.2e}° and shift in the bed); printed {}; {verdict}\n  {}",
        turn.to_degrees(),
        printed.difference,
        printed.not_represented.join("\n  ")
    );
    assert!(verdict.starts_with("Calibrated"), "{verdict}");
    let p = printed.difference.position_max_mm;
    assert!(p > 1e-3, "tilted rails are not Klipper's: {}", printed.difference);
    assert!(
        worst <= 1.5 * p && worst >= p / 1.5,
        "independent {worst:e} mm against printed {p:e} mm"
    );
    assert_eq!(leans.len(), 3, "{:?}", printed.not_represented);
    // Each tower's lean as printed against the truth's.
    for (i, t) in ["a", "b", "c"].iter().enumerate() {
        let line = leans.iter().find(|l| l.starts_with(&format!("tower {t}'s"))).unwrap();
        let printed_lean: f64 = line.split("leans ").nth(1).unwrap().split('°').next().unwrap().parse().unwrap();
        let lean = truth.dir[i].z.acos().to_degrees();
        assert!(
            (printed_lean - lean).abs() < 1e-5,
            "tower {t}: printed {printed_lean}° against {lean}°"
        );
    }
}

/// The printer's path from files: its printer.cfg imported, a virtual prototype with errors of
/// Klipper's kinds (lengths only) touched on its bed and measured with a ballbar into one file,
/// identified, written for Klipper on the bed found: the values are the prototype's own (its
/// bed is its base plane) to 1e-7; the file round-trips; wrong inputs are one line, exit 1.
#[test]
fn printer_on_its_bed_from_the_command_line() {
    use crate::cli::{fails, ok};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("printer.cfg"),
        "[printer]\nkinematics: delta\ndelta_radius: 140\n\n[stepper_a]\narm_length: 250\nposition_endstop: 250\n",
    )
    .unwrap();
    ok(
        d,
        &[
            "model",
            "import",
            "printer.cfg",
            "--format",
            "klipper-delta",
            "--out",
            "printer.toml",
        ],
    );
    ok(
        d,
        &[
            "simulate",
            "printer.toml",
            "--error-deg",
            "0",
            "--seed",
            "1",
            "--planes",
            "0,0,0",
            "--plane-normals",
            "0,0,1",
            "--probe-radius-mm",
            "0",
            "--per-point",
            "40",
            "--pivots",
            "50,0,0;-25,43,0;-25,-43,0",
            "--ballbar-mm",
            "100",
            "--lengths-per-pivot",
            "5",
            "--reference",
            "290,290,290",
            "--tilt-deg",
            "40",
            "--out",
            "bed.csv",
            "--truth",
            "truth.toml",
        ],
    );
    let identified = ok(d, &["identify", "printer.toml", "bed.csv", "--out", "cal.toml"]);
    assert!(identified.contains("verdict: calibrated"), "{identified}");
    let printed = ok(
        d,
        &[
            "model",
            "export",
            "cal.toml",
            "--format",
            "klipper-delta",
            "--bed",
            "bed.csv",
            "--angle-c",
            "90",
            "--out",
            "cal.cfg",
        ],
    );
    assert!(printed.starts_with("bed: plane 0 of bed.csv, 40 touches"), "{printed}");
    ok(
        d,
        &[
            "model",
            "export",
            "truth.toml",
            "--format",
            "klipper-delta",
            "--angle-c",
            "90",
            "--out",
            "truth.cfg",
        ],
    );
    let read = |f: &str| KlipperDelta::parse(&std::fs::read_to_string(d.join(f)).unwrap()).unwrap();
    let (cal, truth) = (read("cal.cfg"), read("truth.cfg"));
    let mut worst = (cal.radius - truth.radius).abs();
    for i in 0..3 {
        worst = worst
            .max((cal.angle[i] - truth.angle[i]).abs())
            .max((cal.arm_length[i] - truth.arm_length[i]).abs())
            .max((cal.position_endstop[i] - truth.position_endstop[i]).abs());
    }
    eprintln!("printer from files: written values vs the prototype's {worst:.2e} (mm, °)\n{printed}");
    assert!(worst < 1e-7, "{cal:?}\n{truth:?}");
    // Round trip.
    ok(
        d,
        &["model", "import", "cal.cfg", "--format", "klipper-delta", "--out", "back.toml"],
    );
    ok(
        d,
        &["model", "export", "back.toml", "--format", "klipper-delta", "--out", "back.cfg"],
    );
    assert_eq!(
        std::fs::read(d.join("back.cfg")).unwrap(),
        std::fs::read(d.join("cal.cfg")).unwrap()
    );
    // Wrong inputs: one line each.
    let e = fails(d, &["model", "export", "cal.toml", "--format", "ur-yaml", "--bed", "bed.csv"]);
    assert!(e.contains("only with --format klipper-delta"), "{e}");
    let e = fails(
        d,
        &[
            "model",
            "export",
            "cal.toml",
            "--format",
            "klipper-delta",
            "--bed",
            "bed.csv",
            "--bed-plane",
            "3",
        ],
    );
    assert!(e.starts_with("bed.csv: plane 3 is not touched"), "{e}");
    ok(
        d,
        &[
            "simulate",
            "printer.toml",
            "--poses",
            "10",
            "--measure",
            "position",
            "--out",
            "track.csv",
            "--truth",
            "t2.toml",
        ],
    );
    let e = fails(
        d,
        &["model", "export", "cal.toml", "--format", "klipper-delta", "--bed", "track.csv"],
    );
    assert!(e.starts_with("track.csv: no plane touches"), "{e}");
}
