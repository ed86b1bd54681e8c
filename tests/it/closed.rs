//! Closed-loop engine and its presets: FK∘IK, identification Jacobians vs finite differences,
//! identifiability of the 5-DOF machine, Stewart recovery, and the error paths.
use kinecal::identify::{identify, Options};
use kinecal::measure::Noise;
use kinecal::model::closed::{ClosedLoop, ConstraintSystem, SolverOptions};
use kinecal::model::presets::pm5::{self, Parasitic, Pm5, PAPER_REDUNDANT};
use kinecal::model::presets::stewart::{Stewart, StewartGeometry};
use kinecal::model::Mechanism;
use kinecal::se3;
use kinecal::simulate::{self, ObservationKind};
use kinecal::KinError;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::support::{fd_jacobian, steps};

fn check_jacobian<C: ConstraintSystem>(m: &ClosedLoop<C>, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for q in m.random_configurations(&mut rng, 4).unwrap() {
        let (_, jac) = m.forward_with_jacobian(&q).unwrap();
        let jac = DMatrix::from_iterator(6, jac.ncols(), jac.iter().copied());
        let fd = fd_jacobian(m, &q, &steps(m));
        for c in 0..jac.ncols() {
            let scale = jac.column(c).amax().max(fd.column(c).amax()).max(1e-3);
            let dev = (jac.column(c) - fd.column(c)).amax();
            assert!(
                dev < 1e-6 * scale.max(1.0),
                "{} column {c}: deviation {dev:.3e} (scale {scale:.3e})",
                m.name()
            );
        }
    }
}

#[test]
fn pm5_identification_jacobian_matches_finite_differences() {
    check_jacobian(&Pm5::mechanism(Parasitic::Physical), 1);
    check_jacobian(&Pm5::mechanism(Parasitic::NominalGeometry), 2);
}

#[test]
fn stewart_identification_jacobian_matches_finite_differences() {
    check_jacobian(&Stewart::mechanism(StewartGeometry::default()), 3);
}

#[test]
fn constraint_partials_match_finite_differences() {
    let m = Pm5::mechanism(Parasitic::Physical);
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let q = m.random_configurations(&mut rng, 1).unwrap().remove(0);
    let x = m.platform_pose(&q, None).unwrap();
    let jacs = m.constraint_jacobians(&x, &q).unwrap();
    let (fx, fq, ft) = (jacs.x, jacs.q, jacs.theta);
    assert!(matches!(m.residual(&x, &q[..3]), Err(KinError::InputLength { .. })));
    for j in 0..6 {
        let h = if j < 3 { 1e-4 } else { 1e-7 };
        let (mut a, mut b) = (x, x);
        a[j] += h;
        b[j] -= h;
        let (fa, fb) = (m.residual(&a, &q).unwrap(), m.residual(&b, &q).unwrap());
        for i in 0..6 {
            assert!((fx[(i, j)] - (fa[i] - fb[i]) / (2.0 * h)).abs() < 1e-5 * fx.column(j).amax().max(1.0));
        }
    }
    for j in 0..5 {
        let (mut a, mut b) = (q.clone(), q.clone());
        a[j] += 1e-4;
        b[j] -= 1e-4;
        let (fa, fb) = (m.residual(&x, &a).unwrap(), m.residual(&x, &b).unwrap());
        for i in 0..6 {
            assert!((fq[(i, j)] - (fa[i] - fb[i]) / 2e-4).abs() < 1e-6);
        }
    }
    for j in 0..35 {
        let h = if matches!(j, 8 | 16 | 29) { 1e-7 } else { 1e-4 };
        let mut plus = m.clone();
        let mut minus = m.clone();
        let mut e = DVector::zeros(44);
        e[j] = h;
        plus.retract(&e);
        minus.retract(&(-e));
        let (fa, fb) = (plus.residual(&x, &q).unwrap(), minus.residual(&x, &q).unwrap());
        for i in 0..6 {
            let fd = (fa[i] - fb[i]) / (2.0 * h);
            assert!(
                (ft[(i, j)] - fd).abs() < 1e-5 * ft.column(j).amax().max(1.0),
                "F_θ[{i},{j}] {} vs {fd}",
                ft[(i, j)]
            );
        }
    }
}

fn round_trip<C: ConstraintSystem>(m: &ClosedLoop<C>, seed: u64, full: bool) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let ws = m.system().workspace();
    for _ in 0..25 {
        let x = ws.sample(&mut rng);
        let target = m.tool_pose_of(&x);
        let q = m.inverse(&target, None).unwrap();
        let reached = m.forward(&q).unwrap();
        let e = se3::pose_error(&reached, &target);
        assert!(
            se3::lin(&e).norm() < 1e-8,
            "{}: position error {:.3e}",
            m.name(),
            se3::lin(&e).norm()
        );
        let z_err = (se3::rotation_matrix(&reached).column(2) - se3::rotation_matrix(&target).column(2)).norm();
        assert!(z_err < 1e-10, "tool axis error {z_err:.3e}");
        if full {
            assert!(se3::ang(&e).norm() < 1e-10);
        }
        // IK∘FK on the inputs too.
        let q2 = m.inverse(&reached, None).unwrap();
        for (a, b) in q.iter().zip(&q2) {
            assert!((a - b).abs() < 1e-8);
        }
    }
}

#[test]
fn fk_ik_round_trips_over_the_workspace() {
    round_trip(&Pm5::mechanism(Parasitic::Physical), 5, false);
    round_trip(&Pm5::mechanism(Parasitic::NominalGeometry), 6, false);
    round_trip(&Stewart::mechanism(StewartGeometry::default()), 7, true);
    // With geometric errors too.
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let nominal = Pm5::mechanism(Parasitic::Physical);
    let d = simulate::random_errors(&nominal, &mut rng, 0.2, 0.02f64.to_radians(), None);
    round_trip(&simulate::perturbed(&nominal, &d), 9, false);
}

/// The rotation about the tool axis of a 5-DOF target does not change its commands, whatever
/// its size (a yaw of ±90° or more once failed as a singular seed).
#[test]
fn pm5_commands_ignore_the_rotation_about_the_tool_axis() {
    let m = Pm5::mechanism(Parasitic::Physical);
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let ws = m.system().workspace();
    for _ in 0..10 {
        let target = m.tool_pose_of(&ws.sample(&mut rng));
        let q = m.inverse(&target, None).unwrap();
        for yaw in [89.9f64, -89.99, 120.0, 179.9] {
            let turned = target * se3::pose_from_parts(nalgebra::Vector3::zeros(), nalgebra::Vector3::z() * yaw.to_radians());
            let q2 = m.inverse(&turned, None).unwrap();
            for (a, b) in q.iter().zip(&q2) {
                assert!((a - b).abs() < 1e-8, "yaw {yaw}: {a} vs {b}");
            }
        }
    }
}

#[test]
fn pm5_rank_and_redundant_parameters() {
    let paper = kinecal::study::pm5_identifiability(Parasitic::NominalGeometry, 40, 10, &pm5::paper_priority()).unwrap();
    assert_eq!(paper.rank, 35);
    assert_eq!(paper.redundant, PAPER_REDUNDANT.map(String::from).to_vec());
    let natural = kinecal::study::pm5_identifiability(Parasitic::NominalGeometry, 40, 10, &pm5::natural_priority()).unwrap();
    assert_eq!(
        natural.redundant,
        ["db1y", "db2y", "dl4", "dl5", "db3y", "dl8", "dl9", "dty", "dy0"]
            .map(String::from)
            .to_vec()
    );
    let physical = kinecal::study::pm5_identifiability(Parasitic::Physical, 40, 10, &pm5::natural_priority()).unwrap();
    assert_eq!(physical.rank, 32);
    assert_eq!(
        physical.redundant,
        ["db1y", "db2y", "dl4", "dl5", "db3y", "dl8", "dl9", "dty", "dx0", "dy0", "dz0", "dγ0"]
            .map(String::from)
            .to_vec()
    );
    assert_eq!(physical.identifiable.len(), 32);
}

#[test]
fn stewart_noise_free_recovery_of_all_42_parameters() {
    let nominal = Stewart::mechanism(StewartGeometry::default());
    assert_eq!(nominal.n_params(), 42);
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let delta = simulate::random_errors(&nominal, &mut rng, 1.0, 0.0, None);
    let truth = simulate::perturbed(&nominal, &delta);
    let qs = nominal.random_configurations(&mut rng, 40).unwrap();
    let data = simulate::measure(&truth, &qs, ObservationKind::Pose, None, &mut rng).unwrap();
    let res = identify(&nominal, &data, &Options::default()).unwrap();
    assert!(res.converged);
    assert_eq!(res.identifiability.rank, 42);
    let got = res.model.values();
    let want = truth.values();
    for (i, (a, b)) in got.iter().zip(&want).enumerate() {
        assert!((a - b).abs() < 1e-8, "parameter {i}: {a} vs {b}");
    }
}

#[test]
fn pm5_noise_free_identification_is_exact() {
    let nominal = Pm5::mechanism(Parasitic::Physical);
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let delta = simulate::random_errors(&nominal, &mut rng, 0.2, 0.02f64.to_radians(), None);
    let truth = simulate::perturbed(&nominal, &delta);
    let qs = nominal.random_configurations(&mut rng, 30).unwrap();
    let data = simulate::measure(&truth, &qs, ObservationKind::Pose, None, &mut rng).unwrap();
    let ident = kinecal::study::pm5_identifiability(Parasitic::Physical, 40, 10, &pm5::natural_priority()).unwrap();
    let opts = Options {
        free: Some(ident.identifiable_indices.clone()),
        noise: Noise::default(),
        ..Options::default()
    };
    let res = identify(&nominal, &data, &opts).unwrap();
    assert!(res.converged);
    for q in nominal.random_configurations(&mut rng, 10).unwrap() {
        let e = se3::pose_error(&res.model.forward(&q).unwrap(), &truth.forward(&q).unwrap());
        assert!(se3::lin(&e).norm() < 1e-7 && se3::ang(&e).norm() < 1e-9, "held-out error {e:?}");
    }
}

#[test]
fn error_paths_are_typed() {
    let m = Pm5::mechanism(Parasitic::Physical);
    // Unreachable target: far above the machine.
    let far = se3::translation(0.0, 0.0, 2000.0);
    assert!(matches!(m.inverse(&far, None), Err(KinError::Unreachable(_))));
    // Input outside the strokes.
    assert!(matches!(
        m.forward(&[600.0, 50.0, 50.0, 200.0, 200.0]),
        Err(KinError::OutOfWorkspace(_))
    ));
    // Target whose inputs leave the strokes (reachable geometry, g1 beyond 550 mm).
    let low = m.tool_pose_of(&[0.0, 120.0, 320.0, 0.0, 0.0, 0.0]);
    assert!(matches!(m.inverse(&low, None), Err(KinError::OutOfWorkspace(_))));
    // Platform pose outside the prescribed workspace.
    assert!(matches!(
        m.inputs_for(&[80.0, 0.0, 400.0, 0.0, 0.0, 0.0]),
        Err(KinError::OutOfWorkspace(_))
    ));
    // Wrong number of inputs.
    assert!(matches!(m.forward(&[400.0, 50.0]), Err(KinError::InputLength { .. })));
    // Forward kinematics that cannot converge: too few Newton iterations from home.
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let q = m.random_configurations(&mut rng, 1).unwrap().remove(0);
    let starved = m.clone().with_solver(SolverOptions {
        max_iterations: 1,
        ..SolverOptions::default()
    });
    assert!(matches!(starved.forward(&q), Err(KinError::NoConvergence { .. })));
    // Inputs within the strokes for which the machine cannot assemble.
    for q in [[300.0, 160.0, -20.0, 160.0, 280.0], [550.0, -20.0, -20.0, 280.0, 280.0]] {
        let r = m.forward(&q);
        assert!(matches!(r, Err(KinError::NoConvergence { .. })), "{r:?}");
    }
    let s = Stewart::mechanism(StewartGeometry::default());
    let r = s.forward(&[120.0, -120.0, 120.0, -120.0, 120.0, -120.0]);
    assert!(
        matches!(r, Err(KinError::NoConvergence { .. }) | Err(KinError::Singular { .. })),
        "{r:?}"
    );
}

/// Starting forward kinematics from a known pose (planned candidates) gives the pose and the
/// identification Jacobian of the usual start from home.
#[test]
fn jacobian_from_a_known_pose_equals_the_jacobian_from_home() {
    use rand::SeedableRng;
    let m = Pm5::mechanism(Parasitic::Physical);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
    for q in m.random_configurations(&mut rng, 20).unwrap() {
        let (p0, j0) = m.forward_with_jacobian(&q).unwrap();
        let (p1, j1) = m.forward_with_jacobian_near(&q, &p0).unwrap();
        assert!(kinecal::se3::pose_error(&p0, &p1).norm() < 1e-9);
        assert!((&j0 - &j1).norm() <= 1e-8 * j0.norm(), "{:e}", (&j0 - &j1).norm() / j0.norm());
    }
}

/// The reduced inverse (only the free twist solved, inputs from the closed form) gives the full
/// Newton's answer on the 5-DOF machine (one free coordinate) and the Stewart platform (none),
/// at random workspace poses and at poses with a twist about the tool axis in the target, and
/// the same errors where the target cannot be reached.
#[test]
fn reduced_inverse_gives_the_full_newton_answer() {
    let pm5 = Pm5::mechanism(Parasitic::Physical);
    let stewart = Stewart::mechanism(StewartGeometry::default());
    fn compare<C: ConstraintSystem>(m: &ClosedLoop<C>, seed: u64) -> (f64, f64, usize) {
        let full = m.clone().with_solver(SolverOptions {
            reduced_inverse: false,
            ..SolverOptions::default()
        });
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let ws = m.system().workspace();
        let (mut dq, mut dx, mut both_fail) = (0.0f64, 0.0f64, 0);
        for i in 0..300 {
            let mut x = ws.sample(&mut rng);
            if i % 3 == 0 {
                // Beyond the workspace: some of these cannot be reached at all.
                x[0] *= 4.0;
                x[2] *= 1.6;
            }
            let mut target = m.tool_pose_of(&x);
            if i % 2 == 1 {
                // A twist about the tool axis the 5-DOF machine must undo.
                target *= nalgebra::UnitQuaternion::from_axis_angle(&nalgebra::Vector3::z_axis(), 0.3);
            }
            match (m.inverse_with_pose(&target), full.inverse_with_pose(&target)) {
                (Ok((qa, xa)), Ok((qb, xb))) => {
                    dq = qa.iter().zip(&qb).fold(dq, |d, (a, b)| d.max((a - b).abs()));
                    dx = xa.iter().zip(&xb).fold(dx, |d, (a, b)| d.max((a - b).abs()));
                }
                (Err(a), Err(b)) => {
                    assert_eq!(std::mem::discriminant(&a), std::mem::discriminant(&b), "{a} / {b}");
                    both_fail += 1;
                }
                (a, b) => panic!("reduced {a:?}, full {b:?} at {x:?}"),
            }
        }
        (dq, dx, both_fail)
    }
    for (name, (dq, dx, fails)) in [("pm5", compare(&pm5, 31)), ("stewart", compare(&stewart, 32))] {
        println!("{name}: reduced vs full Newton: max |Δq| {dq:.2e}, max |ΔX| {dx:.2e}; {fails} unreachable by both");
        assert!(dq < 1e-9 && dx < 1e-9, "{name}: {dq} {dx}");
        assert!(
            fails > 0 && fails < 200,
            "{name}: {fails} failures: the test should see both outcomes"
        );
    }
}
