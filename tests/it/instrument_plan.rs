//! Planning for an instrument without a tracker: a plan of seat or ballbar rows on
//! the nominal model has the rows asked for, each point its minimum, is deterministic, and is at
//! least as good by its criterion as random rows; the command line plans, measures the plan on a
//! virtual prototype (`simulate --at`) and identifies it back noise-free.
use kinecal::design::{instrument_blocks, plan_instrument, Criterion, InstrumentLayout, InstrumentPlanOptions, ObservabilityIndices};
use kinecal::design::{SelectOptions, SelectionMethod};
use kinecal::instrument::simulate::{seat_rows, Placement};
use kinecal::instrument::{MIN_PIVOT_ROWS, MIN_SEAT_ROWS};
use kinecal::io::builtin;
use kinecal::io::model_file::ModelFile;
use kinecal::measure::{register_points, Measurement};
use kinecal::model::framed::Framed;
use kinecal::se3::{self, Pose};
use kinecal::simulate::random_configurations;
use kinecal::Mechanism;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The IRB 120's reference configuration (rad): the tool pointing down in front of the robot.
const REFERENCE: [f64; 6] = [0.0, 0.35, 0.2, 0.0, 1.0, 0.0];

/// The ball on the flange (mm): 120 mm out and off the axis.
const BALL: [f64; 3] = [15.0, -10.0, 120.0];

/// The IRB 120 and four seats where its nominal ball stands near the reference.
fn irb120() -> (ModelFile, Vec<Vector3<f64>>) {
    let file = builtin::model_file("irb120").unwrap();
    let framed = Framed::new(
        file.build(),
        Pose::identity(),
        se3::pose_from_parts(Vector3::from(BALL), Vector3::zeros()),
    );
    let seats = [[0.0, 0.0, 0.0], [0.5, 0.1, -0.1], [-0.5, -0.1, 0.2], [0.2, 0.3, 0.3]]
        .iter()
        .map(|s| {
            let mut q = REFERENCE.to_vec();
            for k in 0..3 {
                q[k] += s[k];
            }
            framed.forward(&q).unwrap().translation.vector
        })
        .collect();
    (file, seats)
}

fn options(file: &ModelFile, n: usize, per_point: usize, min: usize, criterion: Criterion) -> InstrumentPlanOptions {
    InstrumentPlanOptions {
        draw: Placement {
            per_point,
            reference: REFERENCE.to_vec(),
            max_tilt: 35f64.to_radians(),
            noise_mm: 0.01,
            seed: 5,
            inputs: file.inputs(),
        },
        min_per_point: min,
        method: SelectionMethod::Sffs,
        select: SelectOptions {
            n,
            criterion,
            ..Default::default()
        },
    }
}

/// Rows of each point.
fn per_point(rows: &[Measurement], points: usize) -> Vec<usize> {
    (0..points)
        .map(|k| rows.iter().filter(|m| m.obs.artifact_point().unwrap().1 == k).count())
        .collect()
}

#[test]
fn a_seat_plan_has_its_rows_each_seat_its_minimum_is_deterministic_and_beats_random_rows() {
    let (file, seats) = irb120();
    let layout = InstrumentLayout {
        points: seats.clone(),
        bar_length: None,
        ball: Vector3::from(BALL),
    };
    // A minimum above the instrument's: the repair gives every seat its 6 rows.
    let opts = options(&file, 28, 30, 6, Criterion::DOptimal);
    let plan = plan_instrument(&file, &layout, &opts).unwrap();
    let counts = per_point(&plan.rows, 4);
    eprintln!(
        "seat plan: per seat {counts:?}, {} repair moves, {}",
        plan.repairs, plan.selection.indices
    );
    assert_eq!(plan.rows.len(), 28);
    assert!(counts.iter().all(|&c| c >= 6), "{counts:?}");
    let again = plan_instrument(&file, &layout, &opts).unwrap();
    assert_eq!(plan.rows, again.rows, "the same seed gives the same plan");

    // Random rows of the same size (7 per seat, the same tilt), on one scaling with the plan's.
    let random = seat_rows(
        &Framed::new(
            file.build(),
            Pose::identity(),
            se3::pose_from_parts(Vector3::from(BALL), Vector3::zeros()),
        ),
        &seats,
        &Placement {
            per_point: 7,
            seed: 99,
            ..opts.draw.clone()
        },
    )
    .unwrap();
    let both: Vec<Measurement> = plan.rows.iter().chain(&random).cloned().collect();
    let blocks = instrument_blocks(&file, &layout, &both, 0.01, Some(&plan.columns)).unwrap();
    let value =
        |set: Vec<usize>| ObservabilityIndices::from_information(&blocks.information(&set), 3 * set.len()).value(Criterion::DOptimal);
    let (planned, random) = (value((0..28).collect()), value((28..56).collect()));
    eprintln!(
        "log det on the plan's {} columns: planned {planned:.3}, random {random:.3}",
        plan.columns.len()
    );
    assert!(planned >= random, "planned {planned} < random {random}");
}

#[test]
fn a_ballbar_plan_gives_each_pivot_its_minimum_and_a_bad_layout_is_refused() {
    let (file, seats) = irb120();
    let pivots: Vec<Vector3<f64>> = seats[..3].iter().map(|c| c - Vector3::new(0.0, 0.0, 100.0)).collect();
    let layout = InstrumentLayout {
        points: pivots,
        bar_length: Some(100.0),
        ball: Vector3::from(BALL),
    };
    let plan = plan_instrument(&file, &layout, &options(&file, 18, 20, 0, Criterion::O2)).unwrap();
    let counts = per_point(&plan.rows, 3);
    eprintln!("ballbar plan: per pivot {counts:?}, {} repair moves", plan.repairs);
    assert_eq!(plan.rows.len(), 18);
    assert!(counts.iter().all(|&c| c >= MIN_PIVOT_ROWS), "{counts:?}");
    // Too few rows for the pivots' minimum, a negative bar: one clear error each.
    let e = plan_instrument(&file, &layout, &options(&file, 10, 20, 0, Criterion::O2))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cannot give each of the 3 pivots its 4 rows"), "{e}");
    let e = plan_instrument(&file, &layout, &options(&file, 18, 3, 0, Criterion::O2))
        .unwrap_err()
        .to_string();
    assert!(e.contains("3 candidates per pivot cannot give each its 4 rows"), "{e}");
    let bad = InstrumentLayout {
        bar_length: Some(-100.0),
        ..layout
    };
    let e = plan_instrument(&file, &bad, &options(&file, 18, 20, 0, Criterion::O2))
        .unwrap_err()
        .to_string();
    assert!(e.contains("must be positive"), "{e}");
}

#[test]
fn cli_plan_seats_simulate_at_identify_recovers_the_prototype() {
    use crate::cli::{fails, json, ok};
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let seats = "400,0,300;450,100,250;350,-100,350;420,50,400";
    let plan = [
        "plan",
        "--model",
        "irb120",
        "--seats",
        seats,
        "--reference",
        "0,20,11.5,0,57,0",
        "--tool-mm",
        "15,-10,120",
        "--tilt-deg",
        "35",
        "--candidates-per-point",
        "25",
        "-n",
        "40",
        "--criterion",
        "d",
        "--seed",
        "3",
        "--output",
    ];
    let summary = json(dir, &[&plan[..], &["p.csv"]].concat());
    assert_eq!(summary["rows"], 40);
    let counts: Vec<u64> = summary["rows_per_point"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_u64().unwrap())
        .collect();
    assert!(counts.iter().all(|&c| c >= MIN_SEAT_ROWS as u64), "{counts:?}");
    let p = std::fs::read(dir.join("p.csv")).unwrap();
    ok(dir, &[&plan[..], &["p.csv", "--force"]].concat());
    let q = std::fs::read(dir.join("p.csv")).unwrap();
    assert!(p == q, "the same seed, the same plan file");
    let text = String::from_utf8(p).unwrap();
    assert!(text.lines().find(|l| !l.starts_with('#')).unwrap().ends_with(",seat"), "{text}");

    let sim = json(
        dir,
        &[
            "simulate",
            "irb120",
            "--at",
            "p.csv",
            "--seats",
            seats,
            "--tool-mm",
            "15,-10,120",
            "--seed",
            "4",
            "--out",
            "d.csv",
            "--truth",
            "t.toml",
        ],
    );
    assert_eq!(sim["data"][0]["rows"], 40);
    let mut identify = vec!["identify", "irb120", "d.csv", "--out", "cal.toml", "--noise-mm", "0.01"];
    assert_eq!(sim["seat_distances"].as_array().unwrap().len(), 3);
    // The artifact's certified distances at full precision (the printed ones have 6 decimals).
    let points = kinecal::instrument::simulate::parse_points(seats).unwrap();
    let distances: Vec<String> = (1..4).map(|k| format!("0:{k}:{}", (points[k] - points[0]).norm())).collect();
    for d in &distances {
        identify.extend(["--seat-distance", d.as_str()]);
    }
    let out = ok(dir, &identify);
    assert!(out.contains("verdict: calibrated"), "{out}");
    let load = |name: &str| ModelFile::load(&dir.join(name)).unwrap().build();
    let (truth, cal) = (load("t.toml"), load("cal.toml"));
    let file = builtin::model_file("irb120").unwrap();
    let qs = random_configurations(&*file.build(), &file.inputs(), 30, &mut ChaCha8Rng::seed_from_u64(8)).unwrap();
    let at = |m: &dyn Mechanism| -> Vec<Vector3<f64>> { qs.iter().map(|q| m.forward(q).unwrap().translation.vector).collect() };
    let (a, b) = (at(&*cal), at(&*truth));
    let t = register_points(&a, &b).unwrap();
    let worst = a
        .iter()
        .zip(&b)
        .map(|(p, q)| (t.transform_point(&(*p).into()).coords - q).norm())
        .fold(0.0, f64::max);
    eprintln!("irb120 planned seats via the CLI, noise-free: held-out max {worst:.2e} mm after a rigid motion");
    assert!(worst < 1e-9, "held-out {worst} mm");

    // Mistakes are one line and a non-zero exit.
    for (args, says) in [
        (
            vec!["plan", "--model", "irb120", "--seats", "400,0,300;450,100", "-o", "x.csv"],
            "'450,100': a point is X,Y,Z",
        ),
        (
            vec![
                "plan",
                "--model",
                "irb120",
                "--pivots",
                "400,0,200",
                "--ballbar-mm",
                "-100",
                "-o",
                "x.csv",
            ],
            "ballbar length -100 mm: must be positive",
        ),
    ] {
        let e = fails(dir, &args);
        assert!(e.contains(says), "{e}");
        assert_eq!(e.trim().lines().count(), 1, "{e}");
    }
}

/// Three spheres and a datum cube in front of the IRB 120 (mm, base frame).
fn touch_layout() -> kinecal::design::TouchLayout {
    use kinecal::instrument::simulate::Touched;
    let mut artifacts: Vec<Touched> = [[300.0, 0.0, 300.0], [350.0, -150.0, 250.0], [350.0, 150.0, 250.0]]
        .iter()
        .enumerate()
        .map(|(k, c)| Touched::sphere(k, Vector3::from(*c), 25.4, 1.5))
        .collect();
    artifacts.extend(Touched::cube(
        se3::pose_from_parts(Vector3::new(350.0, 0.0, 100.0), Vector3::new(0.1, 0.2, 0.3)),
        100.0,
        1.5,
    ));
    kinecal::design::TouchLayout {
        artifacts,
        ball: Vector3::from(BALL),
    }
}

/// A touch plan: the touches asked for, each sphere and cube face its minimum, every planned
/// configuration touching its nominal surface, deterministic, and at least as good by its
/// criterion as as many candidates taken evenly.
#[test]
fn a_touch_plan_gives_each_sphere_and_face_its_minimum_and_beats_evenly_taken_touches() {
    use kinecal::design::{plan_touches, touch_blocks, touch_model};
    let file = builtin::model_file("irb120").unwrap();
    let layout = touch_layout();
    let opts = options(&file, 60, 40, 0, Criterion::DOptimal);
    let plan = plan_touches(&file, &layout, &opts).unwrap();
    assert_eq!(plan.rows.len(), 60);
    let (model, _) = touch_model(&file, &layout).unwrap();
    let mut counts = std::collections::BTreeMap::new();
    for m in &plan.rows {
        let kinecal::measure::Observation::Touch(t) = m.obs else {
            panic!("not a touch")
        };
        let face = match t {
            kinecal::measure::Touch::Face { face, .. } => face,
            _ => 0,
        };
        *counts.entry((t.artifact(), face)).or_insert(0usize) += 1;
        // The planned configuration touches the nominal artifact.
        let (kind, id) = t.artifact();
        let a = layout.artifacts.iter().find(|a| a.touch.artifact() == (kind, id)).unwrap();
        let tip = model.inner.forward(&m.q).unwrap().translation.vector;
        let r = t.residual(&a.frame.inverse_transform_point(&tip.into()).coords);
        assert!(r.abs() < 1e-8, "{kind:?} {id}: {r} mm off its surface");
    }
    eprintln!(
        "touch plan: {} candidates, per artifact (and face) {:?}, {} repair moves, {} columns, {}",
        plan.candidates.len(),
        counts.values().collect::<Vec<_>>(),
        plan.repairs,
        plan.columns.len(),
        plan.selection.indices
    );
    assert_eq!(counts.len(), 9, "three spheres and six faces: {counts:?}");
    assert!(
        counts.iter().all(|((k, _), &c)| c >= kinecal::instrument::touch::min_rows(k.0)),
        "{counts:?}"
    );
    assert_eq!(
        plan.rows,
        plan_touches(&file, &layout, &opts).unwrap().rows,
        "the same seed gives the same plan"
    );
    // As many candidates taken evenly through the list (every sphere and face in proportion).
    let step = plan.candidates.len() as f64 / 60.0;
    let even: Vec<Measurement> = (0..60).map(|k| plan.candidates[(k as f64 * step) as usize].clone()).collect();
    let both: Vec<Measurement> = plan.rows.iter().chain(&even).cloned().collect();
    let blocks = touch_blocks(&file, &layout, &both, 0.01, Some(&plan.columns)).unwrap();
    let value =
        |set: Vec<usize>| ObservabilityIndices::from_information(&blocks.information(&set), 3 * set.len()).value(Criterion::DOptimal);
    let (planned, evenly) = (value((0..60).collect()), value((60..120).collect()));
    eprintln!("log det on the plan's columns: planned {planned:.3}, evenly taken {evenly:.3}");
    assert!(planned > evenly, "planned {planned} ≤ evenly taken {evenly}");
    // A layout without artifacts and a plan smaller than the minimum touches are refused.
    let none = kinecal::design::TouchLayout {
        artifacts: Vec::new(),
        ball: Vector3::zeros(),
    };
    assert!(plan_touches(&file, &none, &opts)
        .unwrap_err()
        .to_string()
        .contains("no sphere, plane or cube face"));
    let small = options(&file, 20, 40, 0, Criterion::DOptimal);
    let e = plan_touches(&file, &layout, &small).unwrap_err().to_string();
    assert!(e.contains("30 are needed"), "{e}");
}

/// The command line plans where to touch a datum cube, measures the plan on a virtual prototype
/// (`simulate --at` moves each planned configuration onto the real faces) and identifies it
/// back noise-free; a plan file of seats is refused as a touch plan.
#[test]
fn cli_plan_cube_touches_simulate_at_identify_recovers_the_prototype() {
    use crate::cli::{fails, json, ok};
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let cube = [
        "--cube",
        "350,0,250",
        "--cube-edge-mm",
        "100",
        "--cube-rotation-deg",
        "5,10,15",
        "--probe-radius-mm",
        "1.5",
        "--tool-mm",
        "15,-10,120",
    ];
    let plan = [
        &[
            "plan",
            "--model",
            "irb120",
            "-n",
            "48",
            "--candidates-per-point",
            "30",
            "--criterion",
            "d",
        ][..],
        &cube,
        &["--output", "p.csv"],
    ]
    .concat();
    let summary = json(dir, &plan);
    assert_eq!(summary["rows"], 48);
    assert_eq!(summary["rows_per_artifact"]["cube 0"], 48, "{summary}");
    let text = std::fs::read_to_string(dir.join("p.csv")).unwrap();
    assert!(
        text.lines()
            .find(|l| !l.starts_with('#'))
            .unwrap()
            .ends_with(",face,cube_edge_mm,probe_radius_mm"),
        "{text}"
    );
    let sim = [
        &["simulate", "irb120", "--at", "p.csv", "-o", "touches.csv", "--truth", "truth.toml"][..],
        &cube,
    ]
    .concat();
    let out = ok(dir, &sim);
    assert!(out.contains("48 planned touches of p.csv"), "{out}");
    let out = ok(dir, &["identify", "irb120", "touches.csv", "--out", "cal.toml"]);
    eprintln!("{out}");
    assert!(out.contains("σ̂₀ = 0.000") && !out.contains("verdict: failed"), "{out}");
    // A seat plan is not a touch plan.
    ok(
        dir,
        &[
            "plan",
            "--model",
            "irb120",
            "--seats",
            "400,0,300;450,100,250",
            "--tool-mm",
            "15,-10,120",
            "-n",
            "12",
            "--output",
            "seats.csv",
        ],
    );
    let e = fails(
        dir,
        &[
            &["simulate", "irb120", "--at", "seats.csv", "-o", "t2.csv", "--truth", "t2.toml"][..],
            &cube,
        ]
        .concat(),
    );
    assert!(e.contains("not a plan of touches"), "{e}");
}
