//! Parallel machines written only as model files (`kind = "limbs"`, `examples/models/`): the whole
//! workflow through the binary (plan → simulate → identify with frames estimated → validate →
//! compensate on the virtual prototype), and the one-line errors of a limb that cannot close, a
//! machine with the wrong mobility and other mistakes, each naming the limb and the line.
use crate::cli::{fails, json, ok};
use crate::support::nominal_targets;
use kinecal::io::data_file::{read_data, InputColumns};
use kinecal::io::model_file::ModelFile;
use kinecal::io::table::read_table;
use kinecal::validate::commanded_error;
use kinecal::Mechanism;
use std::path::Path;

const HEAD: &str = include_str!("../../examples/models/head-3prs.toml");
const HEXAPOD: &str = include_str!("../../examples/models/hexapod-6rus.toml");
const DELTA: &str = include_str!("../../examples/models/linear-delta.toml");

fn commands(path: &Path, angle_inputs: &[bool]) -> Vec<Vec<f64>> {
    read_table(path)
        .unwrap()
        .rows
        .iter()
        .map(|r| {
            r[1..]
                .iter()
                .zip(angle_inputs)
                .map(|(v, a)| if *a { v.to_radians() } else { *v })
                .collect()
        })
        .collect()
}

/// `frames`: how the first identification takes the data's frames (`estimate` unless the
/// machine's fit with frames is exact only at first order, see the linear delta).
fn whole_workflow(text: &str, rank: u64, frames: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("m.toml"), text).unwrap();
    let plan = ok(
        d,
        &[
            "plan",
            "--model",
            "m.toml",
            "-n",
            "30",
            "--candidates",
            "3000",
            "--output",
            "plan.csv",
        ],
    );
    assert!(plan.contains("wrote plan.csv"), "{plan}");
    ok(
        d,
        &[
            "simulate",
            "m.toml",
            "--at",
            "plan.csv",
            "--seed",
            "3",
            "--error-mm",
            "0.3",
            "--error-deg",
            "0.05",
            "--out",
            "ident.csv",
            "--truth",
            "truth.toml",
            "--validation-poses",
            "20",
            "--validation-out",
            "valid.csv",
        ],
    );
    // Noise-free, data in the model frame but frames estimated all the same: round-off.
    let rep = json(
        d,
        &[
            "identify",
            "m.toml",
            "ident.csv",
            "--validation",
            "valid.csv",
            "--out",
            "cal.toml",
            "--report",
            "r.html",
            "--frames",
            frames,
        ],
    );
    assert_eq!(rep["converged"], true, "{}", rep["verdict"]);
    // Observed joints (the 3T1R machine's encoders): their readings are in the data and fitted
    // to round-off, in the JSON and in the report.
    if let Some(joints) = rep["validation"]["joints_after"].as_array().filter(|j| !j.is_empty()) {
        let header = std::fs::read_to_string(d.join("ident.csv")).unwrap();
        assert!(header.lines().next().unwrap().contains("u1_deg"), "{header}");
        for j in joints {
            assert!(j["rms"].as_f64().unwrap() < 1e-6, "{j}");
        }
        assert!(rep["validation"]["joints_before"][0]["rms"].as_f64().unwrap() > 1e-3);
        let html = std::fs::read_to_string(d.join("r.html")).unwrap();
        assert!(html.contains("<h2>Observed joints</h2>"));
    }
    // The frames add nothing: the limbs' base placements and platform points absorb them.
    assert_eq!(rep["rank"].as_u64().unwrap(), rank);
    let v = &rep["validation"];
    assert!(
        v["before_stats"]["position_rms_mm"].as_f64().unwrap() > 0.03,
        "{}",
        v["before_stats"]
    );
    let after = v["after_stats"]["position_max_mm"].as_f64().unwrap();
    assert!(after < 1e-6, "held-out after calibration: {after} mm");
    // Compensation: the calibrated commands put the true machine on the targets (what its task
    // commands); the nominal commands miss by tenths of a millimetre.
    let model = ModelFile::load(&d.join("m.toml")).unwrap();
    let truth = ModelFile::load(&d.join("truth.toml")).unwrap().build();
    let targets = nominal_targets(d, &model);
    // (A machine commanding less than a pose commands it in its base frame, which frames
    // estimated from the data leave free to tilt with the limbs' base placements: compensation
    // is checked with the model calibrated in the data's frame, the machine's base.)
    ok(d, &["identify", "m.toml", "ident.csv", "--frames", "model", "--out", "calm.toml"]);
    ok(d, &["compensate", "calm.toml", "targets.csv", "--out", "cmd.csv"]);
    let angles: Vec<bool> = model.inputs().iter().map(|i| i.unit == kinecal::params::Unit::Angle).collect();
    let val = read_data(&d.join("valid.csv"), &model.data_columns(), InputColumns::Required).unwrap();
    let (mut worst, mut nominal) = (0.0f64, 0.0f64);
    for ((q, t), m) in commands(&d.join("cmd.csv"), &angles).iter().zip(&targets).zip(&val.measurements) {
        let (dp, dw) = commanded_error(truth.task(), t, &truth.forward(q).unwrap());
        worst = worst.max(dp).max(dw * 1e3);
        nominal = nominal.max(commanded_error(truth.task(), t, &truth.forward(&m.q).unwrap()).0);
    }
    assert!(worst < 1e-6, "compensated: {worst}");
    assert!(nominal > 0.05, "nominal commands should miss: {nominal}");
    // The commands file is a configurations file too: the true machine measured there (noise-free)
    // stands on the targets.
    ok(
        d,
        &[
            "simulate",
            "truth.toml",
            "--at",
            "cmd.csv",
            "--error-mm",
            "0",
            "--error-deg",
            "0",
            "--out",
            "reached.csv",
            "--truth",
            "same.toml",
        ],
    );
    let reached = read_data(&d.join("reached.csv"), &model.data_columns(), InputColumns::Required).unwrap();
    assert_eq!(reached.measurements.len(), targets.len());
    for (m, t) in reached.measurements.iter().zip(&targets) {
        let kinecal::measure::Observation::Pose(x) = &m.obs else {
            panic!("pose data expected")
        };
        let (dp, _) = commanded_error(truth.task(), t, x);
        assert!(dp < 1e-6, "reached: {dp} mm");
    }
}

#[test]
fn a_3prs_head_from_its_model_file_through_the_whole_workflow() {
    whole_workflow(HEAD, 33, "estimate");
}

#[test]
fn a_6rus_hexapod_from_its_model_file_through_the_whole_workflow() {
    whole_workflow(HEXAPOD, 66, "estimate");
}

#[test]
fn a_linear_delta_from_its_model_file_through_the_whole_workflow() {
    whole_workflow(DELTA, 30, "model");
}

const PLANAR: &str = include_str!("../../examples/models/planar-3rrr.toml");

/// A planar 3-RRR is overconstrained: every leg holds the platform in the plane. Its 36
/// out-of-plane errors (joint axes tilted, joints lifted) would keep it from assembling; they are
/// found from the closure at home and held as drawn, so that the whole workflow runs on the
/// in-plane geometry. Before, `simulate` failed ("does not assemble at its home inputs") and
/// `identify` never left the nominal model yet said "converged … usable with warnings".
#[test]
fn a_planar_3rrr_holds_its_out_of_plane_errors_and_runs_the_whole_workflow() {
    let file = load(PLANAR).unwrap();
    let held = file.held_by_assembly();
    assert_eq!(held.len(), 36, "{held:?}");
    for name in ["leg1.0-1.wx", "leg1.0-1.wy", "leg1.0-1.vz", "leg3.3-T.wx"] {
        assert!(held.iter().any(|h| h == name), "{name} should be held: {held:?}");
    }
    for name in ["leg1.0-1.vx", "leg1.0-1.wz", "leg2.1-2.vx"] {
        assert!(!held.iter().any(|h| h == name), "{name} is in-plane: {held:?}");
    }
    let free = file.free_indices().unwrap();
    let params = file.build().params();
    assert!(free.iter().all(|&i| !held.contains(&params[i].name)));
    // Every machine that is not overconstrained holds nothing (sensed joints included: the 3T1R).
    for text in [
        HEAD,
        HEXAPOD,
        DELTA,
        include_str!("../../examples/models/t3r1.toml"),
        include_str!("../../examples/models/pm5-limbs.toml"),
    ] {
        let f = load(text).unwrap();
        assert!(f.held_by_assembly().is_empty(), "{}: {:?}", f.name, f.held_by_assembly());
    }
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("m.toml"), PLANAR).unwrap();
    let out = ok(tmp.path(), &["identifiability", "m.toml"]);
    assert!(out.contains("held as drawn (36, not free: planar-3rrr is overconstrained"), "{out}");
    // A [calibration] that frees only held parameters is a mistake, said in one line (a virtual
    // prototype "with errors on 0 free parameters" was written before).
    let only_tilts = format!("{PLANAR}\n[calibration]\nfree = [\"leg*.*.wx\"]\n");
    std::fs::write(tmp.path().join("tilts.toml"), only_tilts).unwrap();
    let e = fails(
        tmp.path(),
        &["simulate", "tilts.toml", "--error-mm", "0.1", "--out", "x.csv", "--truth", "t.toml"],
    );
    assert!(
        e.contains("calibration pattern 'leg*.*.wx' frees only parameters planar-3rrr cannot take alone"),
        "{e}"
    );
    assert!(!tmp.path().join("x.csv").exists() && !tmp.path().join("t.toml").exists());
    // A drawing whose axes are not all parallel (one elbow tilted by 1.1°, the legs' ends placed
    // as exported) cannot close: the error names the limb and how far it stays, a few millimetres
    // (it said 448 mm before: the limb's least-squares solve wandered off its minimum and
    // reported where it ended).
    let exported = file.to_toml().unwrap();
    let at = exported.find("name = \"e2\"").unwrap();
    let mut tilted = exported.clone();
    let axis = at + tilted[at..].find("axis = [0.0, 0.0, 1.0]").unwrap();
    tilted.replace_range(axis..axis + "axis = [0.0, 0.0, 1.0]".len(), "axis = [0.0, 0.02, 1.0]");
    let e = load(&tilted).unwrap_err();
    assert!(e.contains("limb 'leg2' is furthest off"), "{e}");
    let gap: f64 = e
        .split("furthest off (")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(gap > 1.0 && gap < 10.0, "{e}");
    // The report names them too.
    let sim = ok(
        tmp.path(),
        &["simulate", "m.toml", "--poses", "30", "--out", "d.csv", "--truth", "t.toml"],
    );
    assert!(
        sim.contains("planar-3rrr is overconstrained") && sim.contains("on 36 free parameters"),
        "{sim}"
    );
    ok(
        tmp.path(),
        &["identify", "m.toml", "d.csv", "--out", "c.toml", "--report", "r.html"],
    );
    let html = std::fs::read_to_string(tmp.path().join("r.html")).unwrap();
    assert!(html.contains("<b>Held as drawn</b> (36: the machine is overconstrained"));
    whole_workflow(PLANAR, 26, "estimate");
}

fn load(text: &str) -> Result<ModelFile, String> {
    ModelFile::load_str(Path::new("m.toml"), text).map_err(|e| e.to_string())
}

#[test]
fn mistakes_in_a_limbs_file_are_one_line_errors_naming_the_limb() {
    // A platform point 80 mm off: the limb cannot reach it at home.
    let e = load(&HEAD.replacen(
        "[mechanism.limbs.end_placement]",
        "platform_point = [140.0, 0.0, 0.0]\n\n[mechanism.limbs.end_placement]",
        1,
    ))
    .unwrap_err();
    assert!(e.contains("limb 'leg1' cannot close at the home pose"), "{e}");
    // A placement of -1e308 mm (a mutated file that used to hang in the SVD of the mobility
    // check): refused at once.
    let e = load(&HEAD.replacen("position = [129.9038, -75.0000, 0.0]", "position = [-1e308, -75.0000, 0.0]", 1)).unwrap_err();
    assert!(e.contains("extreme values") && e.lines().count() == 1, "{e}");
    // An actuator made passive: the platform keeps a freedom.
    let e = load(&HEAD.replacen("role = \"actuated\"", "role = \"passive\"", 1)).unwrap_err();
    assert!(e.contains("wrong mobility"), "{e}");
    // ... naming what moves, and the limb's line.
    assert!(
        e.contains("it moves the platform and joint s1 of limb 'leg1'") && e.starts_with("m.toml:"),
        "{e}"
    );
    for (from, to, expect) in [
        ("role = \"passive\"", "role = \"pasive\"", "m.toml:"),
        ("type = \"revolute\"", "type = \"ball\"", "unknown joint type 'ball'"),
        ("end = \"point\"", "end = \"sphere\"", "unknown end 'sphere'"),
        ("task = \"height-and-axis\"", "task = \"3T\"", "unknown task '3T'"),
    ] {
        let e = load(&HEAD.replacen(from, to, 1)).unwrap_err();
        assert!(e.contains(expect) && !e.contains('\n'), "{from} → {to}: {e}");
        assert!(e.starts_with("m.toml:"), "a line number: {e}");
    }
    // A machine that closes at home only with a joint beyond its limits (home values are seeds
    // of the assembly: a solve can land on another branch, e.g. a crank wound by turns).
    let e = load(&HEAD.replacen("limits = [200.0, 400.0]", "limits = [200.0, 250.0]", 1)).unwrap_err();
    assert!(
        e.contains("limb 'leg1' closes at the home pose only with joint s1 = 300.000 mm, outside its limits [200.000, 250.000] mm")
            && !e.contains('\n'),
        "{e}"
    );
    // A parallelogram without its bar, or with two home values.
    let chain = include_str!("../../examples/models/t3r1-chain.toml");
    for (from, to, expect) in [
        ("bar = { position = [0.0, 700.0, 0.0] }\n", "", "a parallelogram needs 'bar'"),
        ("home = 45.0", "home = [45.0, -45.0]", "give one value (the parallelogram's angle)"),
    ] {
        assert!(chain.contains(from), "{from}");
        let e = load(&chain.replacen(from, to, 1)).unwrap_err();
        assert!(e.contains(expect) && e.contains("('q12')") && !e.contains('\n'), "{e}");
    }
    // Sub-closed loops (pm5): a body that does not exist, or on a limb listed later.
    let pm5 = include_str!("../../examples/models/pm5-limbs.toml");
    for (from, to, expect) in [
        (
            "start = { limb = \"leg2\", after = \"r2\" }",
            "start = { limb = \"leg9\", after = \"r2\" }",
            "no limb named 'leg9' (limbs: puu, leg2, leg3, act2, act3)",
        ),
        (
            "end_on = { limb = \"leg2\", after = \"k2\" }",
            "end_on = { limb = \"leg2\", after = \"knee\" }",
            "limb 'leg2' has no joint 'knee' (its joints: g2, r2, k2)",
        ),
        (
            "end_on = { limb = \"leg2\", after = \"k2\" }",
            "end_on = { limb = \"act3\", after = \"g5\" }",
            "limb 'act2' closes on a body of a limb that is not an earlier limb starting on the base",
        ),
    ] {
        assert!(pm5.contains(from), "{from}");
        let e = load(&pm5.replacen(from, to, 1)).unwrap_err();
        assert!(
            e.contains(expect) && !e.contains('\n') && e.starts_with("m.toml:"),
            "{from} → {to}: {e}"
        );
    }
    let e = load(&HEXAPOD.replacen("home = [0.0, -35.0]", "home = [0.0]", 1)).unwrap_err();
    assert!(e.contains("give 2 value(s)") && e.contains("leg1"), "{e}");
    // And through the binary: one line, non-zero exit.
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("bad.toml"),
        HEAD.replacen("role = \"actuated\"", "role = \"passive\"", 1),
    )
    .unwrap();
    let msg = fails(tmp.path(), &["identifiability", "bad.toml"]);
    assert!(msg.contains("wrong mobility") && msg.trim().lines().count() == 1, "{msg}");
}

const STEWART: &str = include_str!("../../examples/models/stewart-limbs.toml");

/// The largest forward-kinematics difference (mm, rad) of two models over `qs`.
fn forward_difference(a: &dyn Mechanism, b: &dyn Mechanism, qs: &[Vec<f64>]) -> (f64, f64) {
    let mut worst = (0.0f64, 0.0f64);
    for q in qs {
        let e = kinecal::se3::pose_error(&a.forward(q).unwrap(), &b.forward(q).unwrap());
        worst = (worst.0.max(kinecal::se3::lin(&e).norm()), worst.1.max(kinecal::se3::ang(&e).norm()));
    }
    worst
}

/// The identification Jacobians stacked over `qs`, unit columns (lengths and angles mixed: rank
/// decisions on the directions only), columns of no effect (round-off) dropped.
fn stacked_directions(m: &dyn Mechanism, qs: &[Vec<f64>]) -> nalgebra::DMatrix<f64> {
    let p = m.n_params();
    let mut j = nalgebra::DMatrix::zeros(6 * qs.len(), p);
    for (k, q) in qs.iter().enumerate() {
        let (_, jk) = m.forward_with_jacobian(q).unwrap();
        j.view_mut((6 * k, 0), (6, p)).copy_from(&jk);
    }
    let biggest = j.column_iter().map(|c| c.norm()).fold(0.0, f64::max);
    let kept: Vec<_> = j
        .column_iter()
        .filter(|c| c.norm() > 1e-9 * biggest)
        .map(|c| c / c.norm())
        .collect();
    nalgebra::DMatrix::from_columns(&kept)
}

/// How far the identification Jacobian of `a` is from a fixed linear map of `b`'s: the map `M`
/// fitted on the configurations `fit` (`J_b·M = J_a` stacked, least squares on unit columns), the
/// largest `|J_b(q)·M − J_a(q)|` over the configurations `check`, relative to `J_a(q)`'s largest
/// column. Round-off when every error `a` models is one `b` models, the same way everywhere.
fn jacobian_map_residual(a: &dyn Mechanism, b: &dyn Mechanism, fit: &[Vec<f64>], check: &[Vec<f64>]) -> f64 {
    use nalgebra::DMatrix;
    let stack = |m: &dyn Mechanism, qs: &[Vec<f64>]| {
        let p = m.n_params();
        let mut j = DMatrix::zeros(6 * qs.len(), p);
        for (k, q) in qs.iter().enumerate() {
            j.view_mut((6 * k, 0), (6, p)).copy_from(&m.forward_with_jacobian(q).unwrap().1);
        }
        j
    };
    let (ja, jb) = (stack(a, fit), stack(b, fit));
    let scale: Vec<f64> = jb.column_iter().map(|c| c.norm().max(1e-300)).collect();
    let jb_unit = DMatrix::from_fn(jb.nrows(), jb.ncols(), |r, c| jb[(r, c)] / scale[c]);
    let svd = jb_unit.svd(true, true);
    let tol = svd.singular_values.max() * 1e-10;
    let m_unit = svd.solve(&ja, tol).unwrap();
    let m = DMatrix::from_fn(m_unit.nrows(), m_unit.ncols(), |r, c| m_unit[(r, c)] / scale[r]);
    let mut worst = 0.0f64;
    for q in check {
        let (ja, jb) = (a.forward_with_jacobian(q).unwrap().1, b.forward_with_jacobian(q).unwrap().1);
        let biggest = ja.column_iter().map(|c| c.norm()).fold(0.0, f64::max);
        let diff = (&jb * &m - &ja).amax();
        worst = worst.max(diff / biggest);
    }
    worst
}

/// Ranks of the stacked directions of `a`, of `b` and of both together.
fn ranks(a: &nalgebra::DMatrix<f64>, b: &nalgebra::DMatrix<f64>) -> (usize, usize, usize) {
    let rank = |m: &nalgebra::DMatrix<f64>| {
        let sv = m.clone().singular_values();
        sv.iter().filter(|s| **s > sv.max() * 1e-9).count()
    };
    let both = nalgebra::DMatrix::from_fn(a.nrows(), a.ncols() + b.ncols(), |r, c| {
        if c < a.ncols() {
            a[(r, c)]
        } else {
            b[(r, c - a.ncols())]
        }
    });
    (rank(a), rank(b), rank(&both))
}

/// The preset perturbed (0.3 mm / 0.001 rad on every parameter, seed 2).
fn perturbed_preset(preset: &dyn Mechanism) -> Box<dyn Mechanism> {
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(2);
    let errors = kinecal::simulate::random_errors(preset, &mut rng, 0.3, 0.001, None);
    kinecal::simulate::perturbed(&preset.box_clone(), &errors)
}

/// Largest held-out position difference (mm) of two models over `qs`.
fn held_out(a: &dyn Mechanism, b: &dyn Mechanism, qs: &[Vec<f64>]) -> f64 {
    qs.iter()
        .map(|q| (a.forward(q).unwrap().translation.vector - b.forward(q).unwrap().translation.vector).norm())
        .fold(0.0, f64::max)
}

/// A preset, the same machine as a limbs file, and configurations.
type Beside = (Box<dyn Mechanism>, Box<dyn Mechanism>, Vec<Vec<f64>>);

/// A preset and the same machine as a limbs file, and 1000 configurations of the preset's
/// workspace at which their forward kinematics agree to 1e-9 mm / 1e-12 rad.
fn preset_beside_limbs(name: &str, text: &str) -> Beside {
    let preset = kinecal::io::builtin::model_file(name).unwrap().build();
    let limbs = load(text).unwrap().build();
    assert_eq!(preset.input_names(), limbs.input_names());
    let qs = preset.sample_configurations(1000, 1).unwrap().unwrap();
    let worst = forward_difference(&*preset, &*limbs, &qs);
    eprintln!(
        "{name} preset vs limbs, 1000 configurations: FK differs by {:.2e} mm / {:.2e} rad",
        worst.0, worst.1
    );
    assert!(worst.0 < 1e-9 && worst.1 < 1e-12, "FK differs by {worst:?} mm / rad");
    (preset, limbs, qs)
}

#[test]
fn the_stewart_platform_written_as_limbs_is_the_preset() {
    use kinecal::identify::{identify, Options};
    use kinecal::measure::Noise;
    let (preset, limbs, qs) = preset_beside_limbs("stewart", STEWART);
    // The identification Jacobians span the same space of prediction changes (rank 42 each and
    // together), stacked over 20 configurations.
    let (jp, jl) = (stacked_directions(&*preset, &qs[..20]), stacked_directions(&*limbs, &qs[..20]));
    assert_eq!(ranks(&jp, &jl), (42, 42, 42));
    // And the preset's Jacobian is one fixed linear map of the limbs model's at all 1000.
    let map = jacobian_map_residual(&*preset, &*limbs, &qs[..20], &qs);
    eprintln!("stewart: preset Jacobian = limbs Jacobian · M on 1000 configurations to {map:.2e} (relative)");
    assert!(map < 1e-9, "{map}");
    // The same noisy data identified with either model: the same predictions on held-out poses.
    let truth = perturbed_preset(&*preset);
    let noise = Noise {
        position: 0.01,
        orientation: 1e-4,
        ..Noise::default()
    };
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(3);
    let data = kinecal::simulate::measure(&truth, &qs[..60], kinecal::simulate::ObservationKind::Pose, Some(&noise), &mut rng).unwrap();
    let opts = Options {
        noise,
        ..Options::default()
    };
    let (a, b) = (identify(&preset, &data, &opts).unwrap(), identify(&limbs, &data, &opts).unwrap());
    assert!(a.converged && b.converged);
    let diff = held_out(&*a.model, &*b.model, &qs[100..200]);
    eprintln!(
        "identified from the same 60 noisy poses: held-out predictions differ by {diff:.2e} mm, σ̂₀ {:.6} / {:.6}",
        a.sigma0, b.sigma0
    );
    assert!(diff < 1e-6, "held-out predictions differ by {diff} mm");
    assert!((a.sigma0 - b.sigma0).abs() < 1e-6 * a.sigma0, "σ̂₀ {} vs {}", a.sigma0, b.sigma0);
    // Noise-free data of the perturbed preset: the limbs model recovers it to round-off.
    let exact = kinecal::simulate::measure(&truth, &qs[..60], kinecal::simulate::ObservationKind::Pose, None, &mut rng).unwrap();
    let fit = identify(&limbs, &exact, &Options::default()).unwrap();
    let worst = held_out(&*fit.model, &*truth, &qs[100..200]);
    eprintln!("noise-free: held-out {worst:.2e} mm from the truth");
    assert!(worst < 1e-9, "{worst}");
}

/// pm5 written as limbs (its RPRR sub-closed loops as limbs that start and end on the leg's
/// bodies) is the hand-derived preset: the same forward kinematics, every error the preset models
/// is one the limbs model has (the preset's directions lie in the limbs model's span, which also
/// holds the universal-joint and rail errors the preset leaves out), and noise-free data of a
/// perturbed preset are fitted to round-off.
#[test]
fn pm5_written_as_limbs_is_the_preset() {
    use kinecal::identify::{identify, Options};
    let (preset, limbs, qs) = preset_beside_limbs("pm5", include_str!("../../examples/models/pm5-limbs.toml"));
    let (jp, jl) = (stacked_directions(&*preset, &qs[..30]), stacked_directions(&*limbs, &qs[..30]));
    let (rp, rl, both) = ranks(&jp, &jl);
    eprintln!("ranks: preset {rp}, limbs {rl}, together {both}");
    assert_eq!((rp, rl, both), (32, 48, 48));
    let map = jacobian_map_residual(&*preset, &*limbs, &qs[..30], &qs);
    eprintln!("pm5: preset Jacobian = limbs Jacobian · M on 1000 configurations to {map:.2e} (relative)");
    assert!(map < 1e-9, "{map}");
    // Every parameter free (the file fixes the redundant ones for its own fits).
    let truth = perturbed_preset(&*preset);
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(3);
    let exact = kinecal::simulate::measure(&truth, &qs[..60], kinecal::simulate::ObservationKind::Pose, None, &mut rng).unwrap();
    let fit = identify(&limbs, &exact, &Options::default()).unwrap();
    assert!(fit.converged);
    let worst = held_out(&*fit.model, &*truth, &qs[100..200]);
    eprintln!("noise-free data of the perturbed preset: held-out {worst:.2e} mm from the truth");
    assert!(worst < 1e-9, "{worst}");
}

#[test]
fn inverse_kinematics_returns_the_inputs_of_the_same_assembly_mode() {
    let delta = include_str!("../../examples/models/linear-delta.toml");
    for (name, text) in [("head", HEAD), ("hexapod", HEXAPOD), ("stewart", STEWART), ("delta", delta)] {
        let m = load(text).unwrap().build();
        let qs = m.sample_configurations(300, 9).unwrap().unwrap();
        let mut worst = 0.0f64;
        for q in &qs {
            let back = m.inverse(&m.forward(q).unwrap(), None).unwrap();
            worst = q.iter().zip(&back).map(|(a, b)| (a - b).abs()).fold(worst, f64::max);
        }
        assert!(worst < 1e-7, "{name}: IK(FK(q)) differs from q by {worst:.3e}");
    }
}

#[test]
fn the_limbs_machines_are_listed_and_exported_like_the_presets() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let list = ok(d, &["model", "list"]);
    for name in [
        "hexapod-6rus",
        "head-3prs",
        "linear-delta",
        "stewart-limbs",
        "pm5-limbs",
        "t3r1-chain",
        "t3r1",
    ] {
        assert!(list.contains(name), "{list}");
        let file = kinecal::io::builtin::model_file(name).unwrap();
        assert_eq!(file.mechanism.kind(), "limbs");
        ok(d, &["model", "export", name, "--out", &format!("{name}.toml")]);
        let back = ModelFile::load(&d.join(format!("{name}.toml"))).unwrap();
        let (a, b) = (file.build(), back.build());
        for q in a.sample_configurations(5, 1).unwrap().unwrap() {
            let e = kinecal::se3::pose_error(&a.forward(&q).unwrap(), &b.forward(&q).unwrap());
            assert!(e.norm() < 1e-9, "{name}: {e}");
        }
    }
    // A built-in name works wherever a model file does.
    let id = json(d, &["identifiability", "head-3prs", "--poses", "40"]);
    assert_eq!(id["rank"], 33, "{id}");
}

#[test]
fn pm5_as_limbs_with_its_sub_closed_loops_through_the_whole_workflow() {
    whole_workflow(include_str!("../../examples/models/pm5-limbs.toml"), 48, "estimate");
}

/// One chain of the 3T1R machine written as a one-limb file with two parallelogram joints is the
/// study's branched chain: the same forward kinematics on 1000 configurations, the same span of
/// identification directions (the paper's per-chain rank 20, together 20), every joint a data
/// column.
#[test]
fn a_3t1r_chain_with_parallelograms_is_the_studys_chain() {
    use kinecal::studies::t3r1_machine::{BranchedChain, ChainId, Geometry};
    let study = BranchedChain::nominal(&Geometry::default(), ChainId::B1);
    let limbs = load(include_str!("../../examples/models/t3r1-chain.toml")).unwrap().build();
    assert_eq!(limbs.input_names(), ["q11", "q12", "q13", "q14"]);
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(11);
    let qs: Vec<Vec<f64>> = (0..1000)
        .map(|_| {
            use rand::RngExt;
            vec![
                rng.random_range(-300.0..300.0),
                rng.random_range(30.0f64..60.0).to_radians(),
                rng.random_range(50.0f64..70.0).to_radians(),
                rng.random_range(-20.0f64..20.0).to_radians(),
            ]
        })
        .collect();
    let worst = forward_difference(&study, &*limbs, &qs);
    eprintln!(
        "3T1R chain, study vs limbs file, 1000 configurations: FK differs by {:.2e} mm / {:.2e} rad",
        worst.0, worst.1
    );
    assert!(worst.0 < 1e-9 && worst.1 < 1e-12, "{worst:?}");
    let (js, jl) = (stacked_directions(&study, &qs[..30]), stacked_directions(&*limbs, &qs[..30]));
    assert_eq!(ranks(&js, &jl), (20, 20, 20));
    let map = jacobian_map_residual(&study, &*limbs, &qs[..30], &qs);
    eprintln!("3T1R chain: study Jacobian = limbs Jacobian · M on 1000 configurations to {map:.2e} (relative)");
    assert!(map < 1e-9, "{map}");
}

#[test]
fn the_3t1r_machine_through_the_whole_workflow() {
    // (Frames estimated, the fit stops at 4e-6 mm, as the linear delta's: see the contract suite.)
    whole_workflow(include_str!("../../examples/models/t3r1.toml"), 43, "model");
}

#[test]
fn a_3t1r_chain_commanded_in_position_and_yaw_through_the_whole_workflow() {
    whole_workflow(include_str!("../../examples/models/t3r1-chain.toml"), 20, "estimate");
}

/// The whole 3T1R machine written as limbs (its minimal-constraint equivalent, four sliders) is
/// the study's machine: at 1000 poses of the study's workspace, the study's closed-form inverse
/// gives the sliders and the limbs file's forward kinematics puts the platform back on the pose.
#[test]
fn the_3t1r_machine_written_as_limbs_is_the_studys_machine() {
    use kinecal::studies::t3r1_machine::{Geometry, T3r1, Workspace};
    let machine = T3r1 {
        geometry: Geometry::default(),
    };
    let limbs = load(include_str!("../../examples/models/t3r1.toml")).unwrap().build();
    assert_eq!(limbs.input_names(), ["s1", "s3", "s2", "s4"]);
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(12);
    let ws = Workspace::default();
    let mut worst = (0.0f64, 0.0f64);
    for _ in 0..1000 {
        let target = ws.sample(&mut rng);
        let c = machine.inverse(&target).unwrap();
        let s = c.sliders;
        let x = limbs.forward(&[s[0], s[2], s[1], s[3]]).unwrap();
        let e = kinecal::se3::pose_error(&target.to_pose(), &x);
        worst = (worst.0.max(kinecal::se3::lin(&e).norm()), worst.1.max(kinecal::se3::ang(&e).norm()));
        // And the limbs file's own inverse gives the study's sliders back.
        let q = limbs.inverse(&target.to_pose(), None).unwrap();
        let back = [q[0], q[2], q[1], q[3]];
        assert!(back.iter().zip(&s).all(|(a, b)| (a - b).abs() < 1e-8), "{back:?} vs {s:?}");
    }
    eprintln!(
        "3T1R machine, study vs limbs file, 1000 poses: FK differs by {:.2e} mm / {:.2e} rad",
        worst.0, worst.1
    );
    assert!(worst.0 < 1e-9 && worst.1 < 1e-12, "{worst:?}");
}
