use approx::assert_relative_eq;
use kinecal::identifiability;
use kinecal::identify::linearize;
use kinecal::measure::{Measurement, Noise, Observation};
use kinecal::model::Mechanism;
use kinecal::se3;
use kinecal::simulate::{random_joint_values, random_serial_chain};
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The shared finite-difference Jacobian with one step for every coordinate.
fn fd_jacobian<M: Mechanism + Clone>(m: &M, q: &[f64], h: f64) -> DMatrix<f64> {
    crate::support::fd_jacobian(m, q, &vec![h; m.n_params()])
}

#[test]
fn identification_jacobian_matches_finite_differences_on_random_chains() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for (r, p) in [(6, 0), (3, 2), (1, 4), (5, 1), (2, 2)] {
        for _ in 0..3 {
            let chain = random_serial_chain(&mut rng, r, p);
            let q = random_joint_values(&chain, &mut rng, 2.5, 200.0);
            let (_, jac) = chain.forward_with_jacobian(&q).unwrap();
            let fd = fd_jacobian(&chain, &q, 1e-6);
            let jac = DMatrix::from_iterator(6, jac.ncols(), jac.iter().copied());
            let scale = jac.amax().max(1.0);
            assert!(
                (&jac - &fd).amax() < 1e-6 * scale,
                "chain {r}r{p}p: max deviation {}",
                (&jac - &fd).amax()
            );
        }
    }
}

#[test]
fn joint_jacobian_matches_finite_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let chain = random_serial_chain(&mut rng, 4, 2);
    let q = random_joint_values(&chain, &mut rng, 2.5, 200.0);
    let (_, jq) = chain.joint_jacobian(&q).unwrap();
    for j in 0..q.len() {
        let h = 1e-6;
        let mut qp = q.clone();
        qp[j] += h;
        let mut qm = q.clone();
        qm[j] -= h;
        let d = se3::log(&(chain.forward(&qp).unwrap() * chain.forward(&qm).unwrap().inverse())) / (2.0 * h);
        for i in 0..6 {
            assert!((jq[(i, j)] - d[i]).abs() < 1e-6 * (1.0 + d[i].abs()), "joint {j} row {i}");
        }
    }
}

#[test]
fn inverse_kinematics_round_trip() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let chain = random_serial_chain(&mut rng, 6, 0);
    for _ in 0..10 {
        let q = random_joint_values(&chain, &mut rng, 2.0, 100.0);
        let target = chain.forward(&q).unwrap();
        let seed: Vec<f64> = q.iter().map(|v| v + 0.05).collect();
        let qi = chain.inverse(&target, Some(&seed)).unwrap();
        let back = chain.forward(&qi).unwrap();
        let e = se3::pose_error(&back, &target);
        assert!(se3::lin(&e).norm() < 1e-8 && se3::ang(&e).norm() < 1e-10, "FK∘IK error {e}");
    }
}

fn rank_of(chain: &kinecal::model::chain::SerialChain, position_only: bool, seed: u64) -> usize {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let data: Vec<Measurement> = (0..40)
        .map(|_| {
            let q = random_joint_values(chain, &mut rng, 3.0, 300.0);
            let t = chain.forward(&q).unwrap();
            let obs = if position_only {
                Observation::Position(t.translation.vector)
            } else {
                Observation::Pose(t)
            };
            Measurement {
                joints: Vec::new(),
                q,
                obs,
            }
        })
        .collect();
    let lin = linearize(chain, &data, &Noise::default()).unwrap();
    let all: Vec<usize> = (0..chain.n_params()).collect();
    identifiability::analyze(&lin.jacobian, &all, identifiability::DEFAULT_RANK_TOLERANCE).rank
}

#[test]
fn rank_is_4r_2p_6_full_pose_and_4r_2p_3_position_only() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for (r, p) in [(6, 0), (4, 2), (3, 3), (2, 1), (1, 3), (5, 2)] {
        for trial in 0..2 {
            let chain = random_serial_chain(&mut rng, r, p);
            assert_eq!(rank_of(&chain, false, 10 + trial), 4 * r + 2 * p + 6, "{r}r{p}p full pose");
            assert_eq!(rank_of(&chain, true, 20 + trial), 4 * r + 2 * p + 3, "{r}r{p}p position");
        }
    }
}

#[test]
fn retract_matches_paper_update() {
    // T(0) ← T(0)·exp(δt) (eq. (33)).
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let chain = random_serial_chain(&mut rng, 2, 1);
    let mut delta = DVector::zeros(chain.n_params());
    delta[6 + 4] = 0.01;
    delta[6] = 0.5;
    let mut c2 = chain.clone();
    c2.retract(&delta);
    let expected = chain.initial_poses()[1] * se3::exp(&se3::Twist::new(0.5, 0.0, 0.0, 0.0, 0.01, 0.0));
    assert_relative_eq!(c2.initial_poses()[1].to_homogeneous(), expected.to_homogeneous(), epsilon = 1e-12);
}

/// Retractions add up in each dyad's error coordinates, so a chain moved in some coordinates only
/// (`vz wy wz`, as a model file that fixes the others) stays where one move by the sum puts it,
/// whatever the path; its Jacobian, through the right Jacobian of `exp`, is still the finite
/// differences of the retraction there.
#[test]
fn retractions_add_up_and_the_jacobian_follows_them() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let chain = random_serial_chain(&mut rng, 4, 2);
    let p = chain.n_params();
    // Steps in vz, wy, wz of every dyad only: 5 mm and 0.05 rad, large enough that the path mattered.
    let step = |scale: f64| {
        DVector::from_fn(p, |i, _| {
            if [2, 4, 5].contains(&(i % 6)) {
                scale * (1.0 + (i % 7) as f64 / 7.0)
            } else {
                0.0
            }
        })
    };
    let d1 = step(5.0).component_mul(&DVector::from_fn(p, |i, _| if i % 6 == 2 { 1.0 } else { 0.01 }));
    let d2 = -step(3.0).component_mul(&DVector::from_fn(p, |i, _| if i % 6 == 2 { 1.0 } else { 0.015 }));
    let mut path = chain.clone();
    path.retract(&d1);
    path.retract(&d2);
    let mut once = chain.clone();
    once.retract(&(&d1 + &d2));
    for (a, b) in path.initial_poses().iter().zip(once.initial_poses()) {
        assert!(
            se3::log(&(a * b.inverse())).amax() < 1e-12,
            "the path moved a dyad: {a} against {b}"
        );
    }
    let q = random_joint_values(&path, &mut rng, 2.5, 200.0);
    let (_, jac) = path.forward_with_jacobian(&q).unwrap();
    let fd = fd_jacobian(&path, &q, 1e-6);
    let jac = DMatrix::from_iterator(6, jac.ncols(), jac.iter().copied());
    let scale = jac.amax().max(1.0);
    assert!((&jac - &fd).amax() < 1e-6 * scale, "max deviation {}", (&jac - &fd).amax());
}
