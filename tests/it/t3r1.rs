//! The 3T1R manipulator: preset closure (FK∘IK), the actual machine, the method of the paper.
use approx::assert_relative_eq;
use kinecal::model::presets::t3r1::{tilt, ActualMachine, BranchedChain, ChainId, Geometry, PlatformPose, PresetErrors, T3r1, Workspace};
use kinecal::model::Mechanism;
use kinecal::se3::{self, Pose};
use nalgebra::{UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn poses(n: usize, seed: u64) -> Vec<PlatformPose> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let w = Workspace::default();
    (0..n).map(|_| w.sample(&mut rng)).collect()
}

#[test]
fn nominal_fk_ik_round_trip_over_the_workspace() {
    let m = T3r1::default();
    let mut worst_cond: f64 = 0.0;
    for target in poses(200, 1) {
        let cfg = m.inverse(&target).unwrap();
        let back = m.forward(&cfg.sliders).unwrap();
        for k in 0..4 {
            assert_relative_eq!(back.upper[k], cfg.upper[k], epsilon = 1e-10);
        }
        for s in 0..2 {
            assert_relative_eq!(back.lower[s], cfg.lower[s], epsilon = 1e-10);
            assert_relative_eq!(back.platform[s], cfg.platform[s], epsilon = 1e-10);
        }
        // Every chain reaches the same pose, without tilt.
        for id in ChainId::ALL {
            let t = m.chain(id).forward(&cfg.chain_inputs(id)).unwrap();
            let p = PlatformPose::from_pose(&t);
            assert_relative_eq!(p.x, target.x, epsilon = 1e-9);
            assert_relative_eq!(p.y, target.y, epsilon = 1e-9);
            assert_relative_eq!(p.z, target.z, epsilon = 1e-9);
            assert_relative_eq!(p.yaw, target.yaw, epsilon = 1e-12);
            assert!(tilt(&t) < 1e-12);
        }
        let j = m.actuator_jacobian(&cfg.sliders).unwrap();
        let sv = j.singular_values();
        let cond = sv.max() / sv.min();
        worst_cond = worst_cond.max(cond);
    }
    // Well conditioned (yaw row in rad vs mm: the scale of σ is set by 1/a).
    assert!(worst_cond < 1e4, "worst condition number {worst_cond}");
}

#[test]
fn home_pose_has_the_printed_angles_and_the_printed_chain_is_the_frozen_one() {
    let g = Geometry::default();
    assert_relative_eq!(g.beta(), 60f64.to_radians(), epsilon = 1e-12);
    let m = T3r1::default();
    let cfg = m.inverse(&g.home()).unwrap();
    assert_relative_eq!(cfg.upper[0], g.alpha(), epsilon = 1e-12);
    assert_relative_eq!(cfg.upper[1], std::f64::consts::PI - g.alpha(), epsilon = 1e-12);
    assert_relative_eq!(cfg.lower[0], g.beta(), epsilon = 1e-12);
    assert_relative_eq!(cfg.lower[1], std::f64::consts::PI - g.beta(), epsilon = 1e-12);
    // The printed chain 1 of §6 (counter-rotations frozen at α, β) at the home pose.
    let rx = |a: f64| {
        Pose::from_parts(
            nalgebra::Translation3::identity(),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), a),
        )
    };
    let ry = |a: f64| {
        Pose::from_parts(
            nalgebra::Translation3::identity(),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), a),
        )
    };
    let rz = |a: f64| {
        Pose::from_parts(
            nalgebra::Translation3::identity(),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), a),
        )
    };
    for (id, x0, tool, q3n) in [
        (ChainId::B1, 0.0, 150.0, g.beta()),
        (ChainId::B3, 1000.0, -150.0, std::f64::consts::PI - g.beta()),
    ] {
        let q = cfg.chain_inputs(id);
        let printed = se3::translation(x0, 30.0, 0.0)
            * se3::translation(0.0, q[0], 0.0)
            * rx(q[1])
            * se3::translation(0.0, 700.0, 0.0)
            * rx(-g.alpha())
            * ry(q[2])
            * se3::translation(700.0, 0.0, 0.0)
            * ry(-q3n)
            * rz(q[3])
            * se3::translation(tool, 0.0, 0.0);
        let ours = m.chain(id).forward(&q).unwrap();
        assert_relative_eq!(printed.to_homogeneous(), ours.to_homogeneous(), epsilon = 1e-9);
    }
}

#[test]
fn actual_machine_assembles_and_its_reading_chains_are_exact() {
    let m = T3r1::default();
    let actual = ActualMachine::new(&m, &PresetErrors::default());
    for target in poses(10, 2) {
        let cmd = m.inverse(&target).unwrap();
        let (cfg, pose) = actual.forward(&cmd.sliders).unwrap();
        for id in ChainId::ALL {
            let q = cfg.chain_inputs(id);
            let t = actual.chain(id).forward(&q).unwrap();
            let e = se3::pose_error(&t, &pose);
            assert!(e.norm() < 1e-9, "chain {id:?} misses the platform by {e}");
            // Literal chain (tilted twists, offsets) gives the same pose.
            let off = actual.offsets();
            let ql: Vec<f64> = q.iter().zip(off.iter()).map(|(a, b)| a + b).collect();
            let tl = actual.literal_chain(id).forward(&ql).unwrap();
            assert!(se3::pose_error(&tl, &pose).norm() < 1e-9);
        }
        // The errors matter: millimetres and a visible tilt.
        let err = se3::pose_error(&pose, &target.to_pose());
        assert!(se3::lin(&err).norm() > 1.0);
        assert!(tilt(&pose) > 1e-3);
    }
}

#[test]
fn chain_jacobian_matches_finite_differences() {
    let m = T3r1::default();
    let actual = ActualMachine::new(&m, &PresetErrors::default());
    let target = poses(1, 3)[0];
    let cmd = m.inverse(&target).unwrap();
    let (cfg, _) = actual.forward(&cmd.sliders).unwrap();
    for chain in [m.chain(ChainId::B1), actual.chain(ChainId::B3).clone()] {
        let q = cfg.chain_inputs(ChainId::B3);
        let (g, j) = chain.forward_with_jacobian(&q).unwrap();
        let h = 1e-6;
        for c in 0..30 {
            let mut dp = nalgebra::DVector::zeros(30);
            dp[c] = h;
            let mut a = chain.clone();
            a.retract(&dp);
            dp[c] = -h;
            let mut b = chain.clone();
            b.retract(&dp);
            let fd = (se3::log(&(a.forward(&q).unwrap() * g.inverse())) - se3::log(&(b.forward(&q).unwrap() * g.inverse()))) / (2.0 * h);
            let an = j.column(c);
            assert!((fd - an).norm() < 1e-6 * (1.0 + an.norm()), "column {c}: fd {fd} vs {an}");
        }
        let (_, jq) = chain.joint_jacobian(&q).unwrap();
        for c in 0..4 {
            let (mut a, mut b) = (q, q);
            a[c] += h;
            b[c] -= h;
            let fd =
                (se3::log(&(chain.forward(&a).unwrap() * g.inverse())) - se3::log(&(chain.forward(&b).unwrap() * g.inverse()))) / (2.0 * h);
            assert!((fd - jq.column(c)).norm() < 1e-6 * (1.0 + fd.norm()));
        }
    }
}

#[test]
fn printed_chain_tool_offsets() {
    let c = BranchedChain::nominal(&Geometry::default(), ChainId::B4);
    assert_eq!(c.dyad_names()[4], "2'4-P");
    assert_eq!(c.params().len(), 30);
}
