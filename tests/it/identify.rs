use kinecal::identify::{identify, linearize, rls_solve, Method, Options};
use kinecal::measure::{self, Noise};
use kinecal::model::Mechanism;
use kinecal::simulate::{self, random_joint_values, random_serial_chain, ObservationKind};
use kinecal::CalibError;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn held_out_error<M: Mechanism>(model: &M, truth: &M, inputs: &[Vec<f64>]) -> (f64, f64) {
    let (mut dp, mut dw) = (0.0f64, 0.0f64);
    for q in inputs {
        let (p, w) = measure::errors(&measure::Observation::Pose(truth.forward(q).unwrap()), &model.forward(q).unwrap());
        dp = dp.max(p);
        dw = dw.max(w.unwrap());
    }
    (dp, dw)
}

#[test]
fn noise_free_calibration_of_random_chains_is_exact() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for (r, p, kind) in [
        (6, 0, ObservationKind::Pose),
        (3, 2, ObservationKind::Pose),
        (4, 1, ObservationKind::Position),
        (6, 0, ObservationKind::Position),
    ] {
        let nominal = random_serial_chain(&mut rng, r, p);
        let delta = simulate::random_errors(&nominal, &mut rng, 2.0, 0.02, None);
        let truth = simulate::perturbed(&nominal, &delta);
        let ident_q: Vec<Vec<f64>> = (0..40).map(|_| random_joint_values(&nominal, &mut rng, 2.5, 200.0)).collect();
        let test_q: Vec<Vec<f64>> = (0..20).map(|_| random_joint_values(&nominal, &mut rng, 2.5, 200.0)).collect();
        let data = simulate::measure(&truth, &ident_q, kind, None, &mut rng).unwrap();
        let before = held_out_error(&nominal, &truth, &test_q);
        let res = identify(&nominal, &data, &Options::default()).unwrap();
        assert!(res.converged, "{r}r{p}p {kind:?} did not converge");
        let (ep, ew) = if kind == ObservationKind::Pose {
            held_out_error(&res.model, &truth, &test_q)
        } else {
            // Position-only: the tool orientation is unobservable, compare positions only.
            let mut e = 0.0f64;
            for q in &test_q {
                e = e.max((truth.forward(q).unwrap().translation.vector - res.model.forward(q).unwrap().translation.vector).norm());
            }
            (e, 0.0)
        };
        assert!(before.0 > 1.0, "the errors must be visible before calibration");
        assert!(
            ep < 1e-9 && ew < 1e-9,
            "{r}r{p}p {kind:?}: held-out error {ep:.3e} mm, {ew:.3e} rad"
        );
    }
}

#[test]
fn recursive_least_squares_equals_batch() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let nominal = random_serial_chain(&mut rng, 5, 1);
    let delta = simulate::random_errors(&nominal, &mut rng, 1.0, 0.01, None);
    let truth = simulate::perturbed(&nominal, &delta);
    let q: Vec<Vec<f64>> = (0..30).map(|_| random_joint_values(&nominal, &mut rng, 2.5, 200.0)).collect();
    let data = simulate::measure(&truth, &q, ObservationKind::Pose, Some(&Noise::default()), &mut rng).unwrap();
    let batch = identify(
        &nominal,
        &data,
        &Options {
            method: Method::Linear,
            ..Options::default()
        },
    )
    .unwrap();
    let rls = identify(
        &nominal,
        &data,
        &Options {
            method: Method::Recursive,
            ..Options::default()
        },
    )
    .unwrap();
    let diff = (&batch.delta - &rls.delta).amax();
    assert!(diff < 1e-9 * batch.delta.amax(), "RLS differs from batch by {diff:.3e}");
    // And directly on one linearisation.
    let lin = linearize(&nominal, &data, &Noise::default()).unwrap();
    let cols = batch.identifiability.identifiable.clone();
    let x = rls_solve(&lin, &cols).unwrap();
    assert!((&x - &batch.delta).amax() < 1e-9 * batch.delta.amax());
}

#[test]
fn noisy_calibration_reports_consistent_uncertainty() {
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let nominal = random_serial_chain(&mut rng, 6, 0);
    let delta = simulate::random_errors(&nominal, &mut rng, 1.0, 0.01, None);
    let truth = simulate::perturbed(&nominal, &delta);
    let q: Vec<Vec<f64>> = (0..200).map(|_| random_joint_values(&nominal, &mut rng, 2.5, 200.0)).collect();
    let noise = Noise {
        position: 0.02,
        orientation: 2e-4,
        ..Noise::default()
    };
    let data = simulate::measure(&truth, &q, ObservationKind::Pose, Some(&noise), &mut rng).unwrap();
    let res = identify(
        &nominal,
        &data,
        &Options {
            noise,
            ..Options::default()
        },
    )
    .unwrap();
    // With the right noise model the unit-weight standard deviation is close to 1.
    assert!((res.sigma0 - 1.0).abs() < 0.1, "sigma0 = {}", res.sigma0);
    let ident = &res.identifiability.identifiable;
    assert_eq!(ident.len(), 30);
    assert!(ident.iter().all(|&c| res.std_dev[c] > 0.0));
}

#[test]
fn too_few_poses_is_a_clear_error() {
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let nominal = random_serial_chain(&mut rng, 6, 0);
    let q: Vec<Vec<f64>> = (0..3).map(|_| random_joint_values(&nominal, &mut rng, 2.5, 200.0)).collect();
    let data = simulate::measure(&nominal, &q, ObservationKind::Pose, None, &mut rng).unwrap();
    match identify(&nominal, &data, &Options::default()) {
        Err(CalibError::TooFewMeasurements { poses: 3, .. }) => {}
        other => panic!("expected TooFewMeasurements, got {other:?}"),
    }
}

/// Gauss–Newton works on the triangular factor / normal equations of the weighted Jacobian, never
/// on the rows × p matrix: its identifiability, its stopping point and its covariance must be those
/// of the full problem.
#[test]
fn reduced_gauss_newton_is_the_full_problem() {
    use kinecal::identifiability::{analyze, scale_columns};
    use kinecal::identify::information;
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let nominal = kinecal::model::irb120::nominal();
    let delta = simulate::random_errors(&nominal, &mut rng, 0.5, 0.002, None);
    let truth = simulate::perturbed(&nominal, &delta);
    // 700 poses: more than one block of poses, so the factor is folded several times.
    let qs: Vec<Vec<f64>> = (0..700).map(|_| random_joint_values(&nominal, &mut rng, 2.5, 0.0)).collect();
    let noise = Noise {
        position: 0.02,
        orientation: 2e-4,
        ..Noise::default()
    };
    let data = simulate::measure(&truth, &qs, ObservationKind::Pose, Some(&noise), &mut rng).unwrap();
    let opts = Options {
        noise,
        ..Options::default()
    };
    let id = identify(&nominal, &data, &opts).unwrap();
    assert!(id.converged);

    // Identifiability: the same as the analysis of the full Jacobian at the start.
    let all: Vec<usize> = (0..nominal.n_params()).collect();
    let full = analyze(&linearize(&nominal, &data, &noise).unwrap().jacobian, &all, opts.rank_tolerance);
    assert_eq!(id.identifiability.rank, full.rank);
    assert_eq!(id.identifiability.identifiable, full.identifiable);
    assert_eq!(id.identifiability.redundant, full.redundant);

    // The information matrix equals AᵀA of the full linearisation.
    let lin = linearize(&id.model, &data, &noise).unwrap();
    let ata = lin.jacobian.transpose() * &lin.jacobian;
    let info = information(&id.model, &data, &noise).unwrap();
    assert!(
        (&info - &ata).norm() <= 1e-10 * ata.norm(),
        "{:e}",
        (&info - &ata).norm() / ata.norm()
    );

    // Stationary for the full problem: the minimum-norm Gauss–Newton step of the full weighted
    // Jacobian at the solution, truncated at the rank, predicts no change beyond the solver's
    // own stopping rule (a step below 1e-6·(1 + |r|) that no longer lowers the cost: here a
    // change of the cost at round-off level, 1e-13 relative).
    let effective: Vec<usize> = all.iter().copied().filter(|c| !full.no_effect.contains(c)).collect();
    let (a, _) = scale_columns(&lin.jacobian, &effective);
    let svd = a.clone().svd(true, true);
    let (u, vt) = (svd.u.as_ref().unwrap(), svd.v_t.as_ref().unwrap());
    let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
    order.sort_by(|&i, &j| svd.singular_values[j].total_cmp(&svd.singular_values[i]));
    let mut step = nalgebra::DVector::zeros(effective.len());
    for &i in order.iter().take(full.rank) {
        step += vt.row(i).transpose() * (u.column(i).dot(&lin.residual) / svd.singular_values[i]);
    }
    let predicted = (&a * &step).norm();
    assert!(
        predicted < 1e-6 * (1.0 + lin.residual.norm()),
        "full GN step from the solution predicts {predicted:e}"
    );

    // The covariance: σ̂₀² times the inverse of AᵀA on the identifiable subset (the parameters
    // the fit moved; the redundant ones stay as drawn).
    let subset = id.identifiability.identifiable.clone();
    let (a_s, norms_s) = scale_columns(&lin.jacobian, &subset);
    let inv = (a_s.transpose() * &a_s).try_inverse().unwrap();
    for (i, &ci) in subset.iter().enumerate() {
        let expected = id.sigma0.powi(2) * inv[(i, i)] / (norms_s[i] * norms_s[i]);
        assert!(
            (id.covariance[(ci, ci)] - expected).abs() <= 1e-8 * expected.abs().max(1e-30),
            "{ci}: {} vs {expected}",
            id.covariance[(ci, ci)]
        );
    }
}

#[test]
fn a_start_that_reaches_a_known_solution_stops_there_and_one_that_does_not_runs_on() {
    use kinecal::identify::Agreement;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let nominal = random_serial_chain(&mut rng, 6, 0);
    let delta = simulate::random_errors(&nominal, &mut rng, 1.0, 0.01, None);
    let truth = simulate::perturbed(&nominal, &delta);
    let q: Vec<Vec<f64>> = (0..60).map(|_| random_joint_values(&nominal, &mut rng, 2.5, 200.0)).collect();
    let noise = Noise {
        position: 0.01,
        orientation: 1e-4,
        ..Noise::default()
    };
    let data = simulate::measure(&truth, &q, ObservationKind::Pose, Some(&noise), &mut rng).unwrap();
    let opts = Options {
        noise,
        ..Options::default()
    };
    let full = identify(&nominal, &data, &opts).unwrap();
    assert!(full.converged);
    let known: Vec<_> = data.iter().map(|m| full.model.forward(&m.q).unwrap().translation.vector).collect();
    let agree = |positions: Vec<nalgebra::Vector3<f64>>| Options {
        agree_with: Some(Agreement {
            positions,
            tolerance_mm: 1e-3,
            identifiability: Some(full.identifiability.clone()),
        }),
        ..opts.clone()
    };
    // Agreeing with the fit's own minimum: fewer iterations, within the tolerance of it.
    let early = identify(&nominal, &data, &agree(known.clone())).unwrap();
    assert!(early.converged);
    assert!(
        early.iterations.len() < full.iterations.len(),
        "{} vs {}",
        early.iterations.len(),
        full.iterations.len()
    );
    let worst = data
        .iter()
        .zip(&known)
        .map(|(m, p)| (early.model.forward(&m.q).unwrap().translation.vector - p).norm())
        .fold(0.0, f64::max);
    assert!(worst <= 1e-3, "{worst}");
    assert_eq!(early.identifiability.rank, full.identifiability.rank);
    // Predictions no fit reaches (1 mm off everywhere): the fit runs to its own end, the same.
    let far: Vec<_> = known.iter().map(|p| p + nalgebra::Vector3::new(1.0, 0.0, 0.0)).collect();
    let own = identify(&nominal, &data, &agree(far)).unwrap();
    assert!(own.converged);
    assert_eq!(own.iterations.len(), full.iterations.len());
    assert!((own.sigma0 - full.sigma0).abs() < 1e-9 * full.sigma0);
}

/// A serial chain that cannot be evaluated once its first parameter has moved, as a closed loop
/// pushed out of its assembly: every step of a fit that moves that parameter fails.
#[derive(Clone)]
struct Brittle {
    chain: kinecal::model::chain::SerialChain,
    moved: bool,
}

impl Brittle {
    fn check(&self) -> Result<(), kinecal::KinError> {
        if self.moved {
            return Err(kinecal::KinError::NoConvergence {
                what: "brittle forward kinematics".into(),
                iterations: 1,
                residual: 1.0,
            });
        }
        Ok(())
    }
}

impl Mechanism for Brittle {
    fn name(&self) -> &str {
        "brittle"
    }
    fn input_names(&self) -> Vec<String> {
        self.chain.input_names()
    }
    fn params(&self) -> Vec<kinecal::params::Param> {
        self.chain.params()
    }
    fn forward(&self, q: &[f64]) -> Result<kinecal::se3::Pose, kinecal::KinError> {
        self.check()?;
        self.chain.forward(q)
    }
    fn forward_with_jacobian(&self, q: &[f64]) -> Result<(kinecal::se3::Pose, nalgebra::Matrix6xX<f64>), kinecal::KinError> {
        self.check()?;
        self.chain.forward_with_jacobian(q)
    }
    fn retract(&mut self, delta: &nalgebra::DVector<f64>) {
        self.moved |= delta[0] != 0.0;
        self.chain.retract(delta);
    }
    fn inverse(&self, target: &kinecal::se3::Pose, seed: Option<&[f64]>) -> Result<Vec<f64>, kinecal::KinError> {
        self.chain.inverse(target, seed)
    }
    fn box_clone(&self) -> Box<dyn Mechanism> {
        Box::new(self.clone())
    }
}

/// A fit whose every step makes the model fail never leaves its start: it is not converged and
/// says why (the pose and the kinematic error), instead of "converged" at the nominal model.
#[test]
fn a_fit_that_cannot_take_a_step_is_not_converged_and_names_the_failure() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let nominal = random_serial_chain(&mut rng, 6, 0);
    let delta = simulate::random_errors(&nominal, &mut rng, 0.5, 0.01, None);
    let truth = simulate::perturbed(&nominal, &delta);
    let q: Vec<Vec<f64>> = (0..30).map(|_| random_joint_values(&nominal, &mut rng, 2.5, 200.0)).collect();
    let data = simulate::measure(&truth, &q, ObservationKind::Pose, None, &mut rng).unwrap();
    let brittle = Brittle {
        chain: nominal.clone(),
        moved: false,
    };
    let res = identify(&brittle, &data, &Options::default()).unwrap();
    assert!(!res.converged);
    let why = res.stalled.expect("the reason it never moved");
    assert!(why.contains("pose 0") && why.contains("brittle forward kinematics"), "{why}");
    assert!(res.delta.iter().all(|d| *d == 0.0));
    // The same chain without the failure converges (the stall is the failure, not the data).
    let res = identify(&nominal, &data, &Options::default()).unwrap();
    assert!(res.converged && res.stalled.is_none());
}
