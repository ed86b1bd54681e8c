//! Measurement planning: indices against direct SVDs, low-rank updates against recomputation,
//! lazy gains against brute force, SFFS/exchange against greedy, determinism.
use approx::assert_relative_eq;
use kinecal::design::information::InformationState;
use kinecal::design::lazy::LazyGains;
use kinecal::design::{
    self, candidates_in_input_box, candidates_in_workspace, Candidate, CandidateFilter, CandidateJacobians, Criterion, ExchangeStart,
    ObservabilityIndices, Sampling, SelectOptions, SelectionMethod, Workspace,
};
use kinecal::identify::linearize;
use kinecal::measure::{Measurement, Noise, Observation};
use kinecal::model::chain::SerialChain;
use kinecal::model::Mechanism;
use kinecal::se3;
use kinecal::simulate::{random_serial_chain, ObservationKind};
use nalgebra::{DMatrix, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn random_blocks(n: usize, rows: usize, k: usize, seed: u64) -> CandidateJacobians {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let raw: Vec<f64> = (0..n * rows * k)
        .map(|i| rng.random_range(-1.0..1.0) * (1.0 + (i % k) as f64))
        .collect();
    CandidateJacobians::from_raw(rows, (0..k).collect(), raw).unwrap()
}

fn chain_setup(n: usize, seed: u64) -> (SerialChain, Vec<Candidate>, CandidateJacobians) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let chain = random_serial_chain(&mut rng, 6, 0);
    let lim = 2.5;
    let (cands, rep) = candidates_in_input_box(
        &chain,
        &[-lim; 6],
        &[lim; 6],
        &Sampling::Halton { n, seed },
        &CandidateFilter::default(),
        None,
    )
    .unwrap();
    assert_eq!(rep.kept, n);
    let noise = Noise::default();
    let cols = design::identifiable_columns(&chain, &cands, ObservationKind::Pose, &noise, None, 100, 1e-8).unwrap();
    // 6R chain, full-pose measurements: 4·6 + 6 = 30 identifiable parameters.
    assert_eq!(cols.len(), 30);
    let blocks = CandidateJacobians::build(&chain, &cands, ObservationKind::Pose, &noise, &cols, None).unwrap();
    (chain, cands, blocks)
}

#[test]
fn indices_match_a_direct_svd() {
    for (rows, k, seed) in [(6, 8, 1), (3, 5, 2), (6, 12, 3)] {
        let blocks = random_blocks(40, rows, k, seed);
        let set = [3, 7, 11, 19, 23, 31];
        let a = blocks.stacked(&set);
        let svd = a.clone().svd(false, false);
        let mut s: Vec<f64> = svd.singular_values.iter().copied().collect();
        s.sort_by(|x, y| y.total_cmp(x));
        let (smax, smin) = (s[0], s[k - 1]);
        let m = a.nrows() as f64;
        let o1 = s.iter().product::<f64>().powf(1.0 / k as f64) / m.sqrt();
        let o5 = 1.0 / s.iter().map(|v| 1.0 / v).sum::<f64>();
        let log_det = (a.transpose() * &a).determinant().ln();
        for ix in [
            ObservabilityIndices::from_jacobian(&a),
            ObservabilityIndices::from_information(&blocks.information(&set), a.nrows()),
        ] {
            assert_relative_eq!(ix.o1, o1, max_relative = 1e-9);
            assert_relative_eq!(ix.o2, smin / smax, max_relative = 1e-9);
            assert_relative_eq!(ix.o3, smin, max_relative = 1e-9);
            assert_relative_eq!(ix.o4, smin * smin / smax, max_relative = 1e-9);
            assert_relative_eq!(ix.o5, o5, max_relative = 1e-9);
            assert_relative_eq!(ix.log_det, log_det, max_relative = 1e-9);
            assert_relative_eq!(ix.o_t, smax / smin, max_relative = 1e-9);
            assert_eq!(ix.value(Criterion::O2), ix.o2);
        }
    }
    // Rank-deficient: fewer rows than columns.
    let blocks = random_blocks(10, 6, 8, 4);
    let ix = ObservabilityIndices::from_information(&blocks.information(&[0]), 6);
    assert_eq!((ix.o1, ix.o2, ix.o3, ix.o4, ix.o5), (0.0, 0.0, 0.0, 0.0, 0.0));
    assert_eq!(ix.log_det, f64::NEG_INFINITY);
}

#[test]
fn column_scaling_gives_unit_mean_information() {
    let blocks = random_blocks(200, 6, 7, 5);
    let all: Vec<usize> = (0..200).collect();
    let m = blocks.information(&all);
    for j in 0..7 {
        assert_relative_eq!(m[(j, j)] / 200.0, 1.0, max_relative = 1e-12);
    }
}

#[test]
fn blocks_are_the_weighted_scaled_identification_jacobian() {
    let (chain, cands, blocks) = chain_setup(300, 7);
    let noise = Noise::default();
    let data: Vec<Measurement> = cands[..5]
        .iter()
        .map(|c| Measurement {
            joints: Vec::new(),
            q: c.q.clone(),
            obs: Observation::Pose(c.target),
        })
        .collect();
    let lin = linearize(&chain, &data, &noise).unwrap();
    for i in 0..5 {
        let b = blocks.block_matrix(i);
        for r in 0..6 {
            for (j, &c) in blocks.columns().iter().enumerate() {
                assert_relative_eq!(
                    b[(r, j)],
                    lin.jacobian[(6 * i + r, c)] / blocks.column_scale()[j],
                    max_relative = 1e-12,
                    epsilon = 1e-12
                );
            }
        }
    }
}

fn direct_leverage(blocks: &CandidateJacobians, set: &[usize], ridge: f64, i: usize) -> DMatrix<f64> {
    let k = blocks.n_columns();
    let p = (blocks.information(set) + DMatrix::identity(k, k) * ridge).try_inverse().unwrap();
    let a = blocks.block_matrix(i);
    &a * p * a.transpose()
}

#[test]
fn low_rank_updates_match_full_recomputation() {
    for rows in [6, 3] {
        let blocks = random_blocks(60, rows, 10, 11);
        let ridge = 1e-3;
        let mut st = InformationState::new(&blocks, ridge).unwrap();
        st.refresh_every = usize::MAX; // updates only, no exact refresh in between
        for j in [5, 17, 2, 40, 33, 8, 51] {
            st.add(j).unwrap();
        }
        st.remove(17).unwrap();
        st.remove(5).unwrap();
        st.add(17).unwrap();
        let set = st.selected().to_vec();
        assert_eq!(set, vec![2, 40, 33, 8, 51, 17]);
        let k = blocks.n_columns();
        let reg = blocks.information(&set) + DMatrix::identity(k, k) * ridge;
        assert_relative_eq!(st.log_det_regularized(), reg.determinant().ln(), max_relative = 1e-9);
        assert_relative_eq!(
            *st.inverse(),
            reg.clone().try_inverse().unwrap(),
            max_relative = 1e-8,
            epsilon = 1e-10
        );
        for i in 0..blocks.len() {
            let g = direct_leverage(&blocks, &set, ridge, i);
            let got = DMatrix::from_row_slice(rows, rows, st.leverage(i));
            assert_relative_eq!(got, g, max_relative = 1e-8, epsilon = 1e-10);
            // Determinant lemma: the gain is the change of log det.
            let mut plus = set.clone();
            if !plus.contains(&i) {
                plus.push(i);
                let reg2 = blocks.information(&plus) + DMatrix::identity(k, k) * ridge;
                assert_relative_eq!(st.gain(i), reg2.determinant().ln() - reg.determinant().ln(), max_relative = 1e-8);
            }
        }
        // The exact refresh gives the same state.
        let fresh = InformationState::with_set(&blocks, &set, ridge).unwrap();
        for i in 0..blocks.len() {
            for (a, b) in st.leverage(i).iter().zip(fresh.leverage(i)) {
                assert_relative_eq!(*a, *b, max_relative = 1e-8, epsilon = 1e-10);
            }
        }
    }
}

#[test]
fn lazy_gains_agree_with_brute_force() {
    let blocks = random_blocks(500, 6, 9, 13);
    let ridge = 1e-6;
    let mut lazy = LazyGains::new(&blocks, ridge).unwrap();
    let mut set: Vec<usize> = Vec::new();
    for _ in 0..8 {
        let m = blocks.information(&set);
        let top = lazy.top(5);
        let all = LazyGains::all_exact(&blocks, &m, ridge).unwrap();
        let mut order: Vec<(usize, f64)> = all.into_iter().enumerate().filter(|(i, _)| !set.contains(i)).collect();
        order.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        for (got, want) in top.iter().zip(&order) {
            assert_eq!(got.0, want.0);
            assert_relative_eq!(got.1, want.1, max_relative = 1e-9);
        }
        let pick = top[0].0;
        set.push(pick);
        lazy.add(pick).unwrap();
        assert_relative_eq!(*lazy.information(), blocks.information(&set), max_relative = 1e-12);
    }
    // Stale gains are upper bounds: later steps evaluate fewer than all candidates.
    assert!(lazy.evaluations < 8 * 500, "{} evaluations", lazy.evaluations);
}

fn opts(criterion: Criterion, n: usize) -> SelectOptions {
    SelectOptions {
        n,
        criterion,
        pool: 400,
        max_cycles: 60,
        ..Default::default()
    }
}

#[test]
fn greedy_d_optimal_matches_brute_force_greedy() {
    let blocks = random_blocks(300, 6, 9, 17);
    let o = opts(Criterion::DOptimal, 6);
    let sel = design::greedy(&blocks, &o, &mut |_| {}).unwrap();
    // Brute force: at each step the candidate maximising log det(M + εI + AᵢᵀAᵢ).
    let mut set: Vec<usize> = Vec::new();
    let k = blocks.n_columns();
    for _ in 0..6 {
        let (mut best, mut val) = (usize::MAX, f64::NEG_INFINITY);
        for i in (0..blocks.len()).filter(|i| !set.contains(i)) {
            let mut s = set.clone();
            s.push(i);
            let v = (blocks.information(&s) + DMatrix::identity(k, k) * o.ridge).determinant().ln();
            if v > val {
                (best, val) = (i, v);
            }
        }
        set.push(best);
    }
    assert_eq!(sel.selected, set);
    assert_eq!(sel.warm_up, 0);
}

#[test]
fn lazy_greedy_matches_eager_low_rank_greedy_on_a_chain() {
    let (_, _, blocks) = chain_setup(3000, 19);
    let o = opts(Criterion::DOptimal, 15);
    let lazy = design::greedy(&blocks, &o, &mut |_| {}).unwrap();
    let mut st = InformationState::new(&blocks, o.ridge).unwrap();
    while st.selected().len() < 15 {
        let (i, _) = st.best_gain().unwrap();
        st.add(i).unwrap();
    }
    assert_eq!(lazy.selected, st.selected());
}

#[test]
fn sffs_and_exchange_are_never_worse_than_greedy() {
    let (_, _, blocks) = chain_setup(1500, 21);
    for criterion in [Criterion::O2, Criterion::DOptimal, Criterion::O3] {
        let o = opts(criterion, 12);
        let g = design::greedy(&blocks, &o, &mut |_| {}).unwrap();
        let s = design::sffs(&blocks, &o, &mut |_| {}).unwrap();
        let e = design::exchange(&blocks, &o, &mut |_| {}).unwrap();
        assert_eq!(g.selected.len(), 12);
        assert_eq!(s.selected.len(), 12);
        assert_eq!(e.selected.len(), 12);
        for set in [&s.selected, &e.selected] {
            let mut u = set.clone();
            u.sort_unstable();
            u.dedup();
            assert_eq!(u.len(), 12, "no configuration twice");
        }
        let gv = g.value();
        assert!(s.value() >= gv, "{criterion}: SFFS {} < greedy {gv}", s.value());
        assert!(e.value() >= gv, "{criterion}: exchange {} < greedy {gv}", e.value());
        // The reported indices are those of the returned set.
        let direct = ObservabilityIndices::from_jacobian(&blocks.stacked(&s.selected));
        assert_relative_eq!(s.indices.o2, direct.o2, max_relative = 1e-7);
        if !criterion.is_determinant_based() {
            assert!(g.warm_up >= 5, "a 30-parameter set needs ≥ 5 poses before O2 is defined");
        }
    }
}

#[test]
fn optimised_sets_beat_random_sets() {
    let (_, _, blocks) = chain_setup(1500, 23);
    let o = opts(Criterion::O2, 15);
    let best = design::sffs(&blocks, &o, &mut |_| {}).unwrap().value();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for _ in 0..20 {
        let set: Vec<usize> = (0..15).map(|_| rng.random_range(0..blocks.len())).collect();
        let v = ObservabilityIndices::from_jacobian(&blocks.stacked(&set)).o2;
        assert!(best > v, "random set O2 {v} ≥ optimised {best}");
    }
}

#[test]
fn selection_is_deterministic() {
    let (_, c1, b1) = chain_setup(1200, 31);
    let (_, c2, b2) = chain_setup(1200, 31);
    assert_eq!(c1, c2);
    assert_eq!(b1, b2);
    for method in [SelectionMethod::Greedy, SelectionMethod::Sffs, SelectionMethod::Exchange] {
        let mut o = opts(Criterion::O2, 10);
        o.exchange_start = ExchangeStart::Random { seed: 9 };
        let a = design::select(&b1, method, &o, &mut |_| {}).unwrap();
        let b = design::select(&b2, method, &o, &mut |_| {}).unwrap();
        assert_eq!(a.selected, b.selected, "{method:?}");
        assert_eq!(a.history, b.history);
    }
}

/// Same inputs, same plan on any number of threads: the column scaling (a parallel sum over all
/// blocks) and the selection on it are bit-identical in pools of 1–4 threads. (The sum used to be
/// a rayon fold/reduce, whose partition follows work stealing: `kinecal plan --model head-3prs`
/// wrote different plans from run to run on a loaded machine.)
#[test]
fn blocks_and_selection_do_not_depend_on_the_thread_count() {
    let (n, rows, k) = (20_000, 6, 9);
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let raw: Vec<f64> = (0..n * rows * k)
        .map(|i| rng.random_range(-1.0..1.0) * 10f64.powi((i % 7) as i32 - 3))
        .collect();
    let o = SelectOptions {
        pool: 2_000,
        ..opts(Criterion::O2, 12)
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let b = CandidateJacobians::from_raw(rows, (0..k).collect(), raw.clone()).unwrap();
            let sel = design::select(&b, SelectionMethod::Sffs, &o, &mut |_| {}).unwrap();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
            (bits(b.column_scale()), bits(b.data()), sel.selected)
        })
    };
    let one = run(1);
    for threads in [2, 3, 4] {
        let other = run(threads);
        assert!(other.0 == one.0, "column scales differ on {threads} threads");
        assert!(other.1 == one.1, "blocks differ on {threads} threads");
        assert_eq!(other.2, one.2, "chosen set on {threads} threads");
    }
}

#[test]
fn workspace_candidates_are_reachable_and_filtered() {
    let mut rng = ChaCha8Rng::seed_from_u64(41);
    let chain = random_serial_chain(&mut rng, 6, 0);
    let q0 = vec![0.3, -0.4, 0.5, 0.2, -0.3, 0.6];
    let home = chain.forward(&q0).unwrap();
    let p = home.translation.vector;
    let ws = Workspace {
        position_min: p - Vector3::new(20.0, 20.0, 20.0),
        position_max: p + Vector3::new(20.0, 20.0, 20.0),
        reference: home.rotation,
        rpy_min: [-0.05, -0.05, 0.0],
        rpy_max: [0.05, 0.05, 0.0],
    };
    let limits: Vec<(f64, f64)> = q0.iter().map(|q| (q - 0.5, q + 0.5)).collect();
    let filter = CandidateFilter {
        input_limits: Some(limits.clone()),
        max_condition: Some(1e4),
        ..Default::default()
    };
    let (cands, rep) = candidates_in_workspace(&chain, &ws, &Sampling::Halton { n: 200, seed: 1 }, Some(&q0), &filter, None).unwrap();
    assert_eq!(rep.sampled, 200);
    assert_eq!(
        rep.kept + rep.unreachable + rep.out_of_limits + rep.near_singular + rep.rejected,
        200
    );
    assert!(rep.kept > 100, "{rep:?}");
    for c in &cands {
        let t = chain.forward(&c.q).unwrap();
        let e = se3::pose_error(&t, &c.target);
        assert!(se3::lin(&e).norm() < 1e-6 && se3::ang(&e).norm() < 1e-8);
        assert!(c.q.iter().zip(&limits).all(|(v, (a, b))| v >= a && v <= b));
        let pp = c.target.translation.vector;
        assert!((pp - p).abs().max() <= 20.0 + 1e-9);
    }
    // A custom filter that rejects everything.
    let none = CandidateFilter {
        custom: Some(std::sync::Arc::new(|_: &Candidate| false)),
        ..Default::default()
    };
    let (c, r) = candidates_in_workspace(
        &chain,
        &ws,
        &Sampling::Grid {
            counts: vec![2, 2, 1, 1, 1, 1],
        },
        Some(&q0),
        &none,
        None,
    )
    .unwrap();
    assert!(c.is_empty());
    assert_eq!(r.sampled, 4);
}

#[test]
fn singularity_filter_rejects_a_singular_configuration() {
    // A z–x–z wrist: at q2 = 0 the first and last axes coincide (a wrist singularity).
    use kinecal::model::chain::ChainJoint;
    let arm = SerialChain::new(
        "zxz",
        vec![
            ChainJoint::revolute("q1", Vector3::z()),
            ChainJoint::revolute("q2", Vector3::x()),
            ChainJoint::revolute("q3", Vector3::z()),
        ],
        vec![se3::translation(0.0, 0.0, 0.0); 3],
        se3::translation(50.0, 20.0, 100.0),
    );
    let c_sing = design::candidates::input_condition(&arm, &[0.3, 0.0, 0.2], 1e-6, 100.0).unwrap();
    let c_ok = design::candidates::input_condition(&arm, &[0.3, 1.2, 0.2], 1e-6, 100.0).unwrap();
    assert!(c_sing > 1e6 && c_ok < 1e3, "{c_sing} {c_ok}");
    let filter = CandidateFilter {
        max_condition: Some(1e3),
        ..Default::default()
    };
    let (cands, rep) = candidates_in_input_box(
        &arm,
        &[0.3, -1.0, 0.2],
        &[0.3, 1.0, 0.2],
        &Sampling::Grid { counts: vec![1, 3, 1] },
        &filter,
        None,
    )
    .unwrap();
    assert_eq!(rep.near_singular, 1);
    assert_eq!(cands.len(), 2);
}

#[test]
fn plan_csv_has_one_row_per_configuration() {
    let (chain, cands, blocks) = chain_setup(400, 43);
    let sel = design::greedy(&blocks, &opts(Criterion::O2, 8), &mut |_| {}).unwrap();
    let mut out = Vec::new();
    design::write_plan_csv(&mut out, &chain.input_names(), &[true; 6], &cands, &sel).unwrap();
    let text = String::from_utf8(out).unwrap();
    let lines: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(lines.len(), 9);
    assert!(lines[0].starts_with("id,q1_deg"));
    let first: Vec<f64> = lines[1].split(',').map(|v| v.parse().unwrap()).collect();
    let c = &cands[sel.selected[0]];
    assert_relative_eq!(first[1], c.q[0].to_degrees(), max_relative = 1e-8);
    assert_relative_eq!(first[7], c.target.translation.vector.x, epsilon = 1e-5);
}

#[test]
fn plan_command_writes_the_chosen_configurations() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan.csv");
    let res = assert_cmd::Command::cargo_bin("kinecal")
        .unwrap()
        .args([
            "plan",
            "--candidates",
            "1500",
            "-n",
            "8",
            "--method",
            "sffs",
            "--criterion",
            "o2",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let stdout = String::from_utf8_lossy(&res.stdout);
    assert!(stdout.contains("O_T"), "{stdout}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(text.lines().filter(|l| !l.starts_with('#')).count(), 9);
    let table = kinecal::io::table::parse_table(&out, &text).unwrap();
    assert_eq!(table.len(), 8);
    assert!(table.values("q6_deg").unwrap().iter().all(|v| v.abs() <= 170.0));

    let bad = assert_cmd::Command::cargo_bin("kinecal")
        .unwrap()
        .args(["plan", "--candidates", "100", "--observe", "angles"])
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("--observe must be pose or position") && err.lines().count() == 1,
        "{err}"
    );
}

#[test]
fn plan_is_the_pipeline_of_columns_blocks_and_selection_in_one_call() {
    let (chain, cands, blocks) = chain_setup(400, 11);
    let select = SelectOptions {
        n: 12,
        ..Default::default()
    };
    let direct = design::select(&blocks, SelectionMethod::Sffs, &select, &mut |_| {}).unwrap();
    let opts = design::PlanOptions {
        select,
        ..Default::default()
    };
    let mut moves = 0;
    let planned = design::plan(&chain, &cands, &opts, None, &mut |_| moves += 1).unwrap();
    assert_eq!(planned.columns.len(), 30);
    assert_eq!(planned.rows_per_candidate, 6);
    assert_eq!(planned.selection.selected, direct.selected);
    assert_relative_eq!(planned.selection.indices.o2, direct.indices.o2, max_relative = 1e-12);
    assert_eq!(moves, direct.history.len());
    // More configurations than candidates: a clear error, not a panic.
    let too_many = design::PlanOptions {
        select: SelectOptions {
            n: 401,
            ..Default::default()
        },
        ..Default::default()
    };
    let err = design::plan(&chain, &cands, &too_many, None, &mut |_| {}).unwrap_err().to_string();
    assert!(err.contains("fewer than the 401"), "{err}");
}

#[test]
fn synthesized_measurements_are_the_prototype_plus_the_stated_noise() {
    use kinecal::simulate::{synthesize, Instrument};
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let chain = random_serial_chain(&mut rng, 6, 0);
    let qs: Vec<Vec<f64>> = (0..200).map(|_| (0..6).map(|_| rng.random_range(-2.0..2.0)).collect()).collect();
    let exact = synthesize(
        &chain,
        qs.clone(),
        Instrument::Pose,
        &Noise {
            position: 0.0,
            orientation: 0.0,
            ..Noise::default()
        },
        &mut rng,
        &|_| {},
    )
    .unwrap();
    for (m, q) in exact.measurements.iter().zip(&qs) {
        let Observation::Pose(p) = m.obs else { panic!("pose expected") };
        assert!(se3::pose_error(&chain.forward(q).unwrap(), &p).norm() < 1e-12);
    }
    let noise = Noise {
        position: 0.1,
        orientation: 0.001,
        ..Noise::default()
    };
    let noisy = synthesize(
        &chain,
        qs.clone(),
        Instrument::Reflectors,
        &noise,
        &mut ChaCha8Rng::seed_from_u64(9),
        &|_| {},
    )
    .unwrap();
    let refl = noisy.reflectors.as_ref().expect("reflector centres kept");
    assert_eq!(refl.len(), 200);
    // Each centre's deviation from its noise-free place: RMS per axis ≈ σ (600 centres × 3 axes).
    let mut sq = 0.0;
    for (c, q) in refl.iter().zip(&qs) {
        let t = chain.forward(q).unwrap();
        for (k, r) in kinecal::simulate::REFLECTORS.iter().enumerate() {
            sq += (c[k] - t.transform_point(&Vector3::from(*r).into()).coords).norm_squared();
        }
    }
    let rms = (sq / (200.0 * 9.0)).sqrt();
    assert!((rms - 0.1).abs() < 0.01, "per-axis RMS {rms} for σ 0.1 mm");
    let again = synthesize(
        &chain,
        qs,
        Instrument::Reflectors,
        &noise,
        &mut ChaCha8Rng::seed_from_u64(9),
        &|_| {},
    )
    .unwrap();
    assert_eq!(again.reflectors, noisy.reflectors, "same seed, same data");
}

#[test]
fn plan_replaces_a_chosen_candidate_the_forward_kinematics_does_not_reach() {
    let (chain, mut cands, _) = chain_setup(400, 11);
    let select = SelectOptions {
        n: 12,
        ..Default::default()
    };
    let unchecked = design::PlanOptions {
        select: select.clone(),
        forward_tolerance: None,
        ..Default::default()
    };
    let first = design::plan(&chain, &cands, &unchecked, None, &mut |_| {}).unwrap();
    assert!(first.set_aside.is_empty());
    // The candidate chosen first gets a target 1 mm away from where its inputs take the tool
    // (as a candidate of another assembly mode would): the checked plan replaces it.
    let bad = first.selection.selected[0];
    assert!(design::forward_agrees(&chain, &cands[bad].q, &cands[bad].target, (1e-6, 1e-8)));
    cands[bad].target = se3::Pose::from_parts(
        nalgebra::Translation3::from(cands[bad].target.translation.vector + nalgebra::Vector3::new(1.0, 0.0, 0.0)),
        cands[bad].target.rotation,
    );
    assert!(!design::forward_agrees(&chain, &cands[bad].q, &cands[bad].target, (1e-6, 1e-8)));
    let checked = design::PlanOptions {
        select,
        ..Default::default()
    };
    let planned = design::plan(&chain, &cands, &checked, None, &mut |_| {}).unwrap();
    assert_eq!(planned.set_aside, vec![bad]);
    assert_eq!(planned.selection.selected.len(), 12);
    assert!(!planned.selection.selected.contains(&bad));
    for &i in &planned.selection.selected {
        assert!(design::forward_agrees(&chain, &cands[i].q, &cands[i].target, (1e-6, 1e-8)));
    }
}

#[test]
fn plan_sampled_takes_the_model_s_own_box_and_needs_a_box_otherwise() {
    use kinecal::design::{CandidateSampling, Points, PoseRanges, Region};
    let halton = Points::Halton { n: 300, seed: 2 };
    let poses = |ranges: PoseRanges| CandidateSampling {
        region: Region::Poses(ranges),
        points: halton.clone(),
        max_condition: None,
    };
    let opts = design::PlanOptions {
        select: SelectOptions {
            n: 8,
            ..Default::default()
        },
        ..Default::default()
    };
    // A serial arm has no box of its own: given no range, its inputs are sampled within their
    // limits (as `simulate` draws them); its paper grid does not exist.
    let irb = kinecal::io::builtin::model_file("irb120").unwrap();
    let sp = design::plan_sampled(&irb, &poses(PoseRanges::default()), &opts, None).unwrap();
    assert!(matches!(sp.candidates.space, design::SampledSpace::Inputs { .. }));
    assert_eq!(sp.candidates.candidates.len(), 300);
    let limits: Vec<(f64, f64)> = irb.inputs().iter().map(|i| i.limits.unwrap()).collect();
    for c in &sp.candidates.candidates {
        assert!(c.q.iter().zip(&limits).all(|(q, (a, b))| (a..=b).contains(&q)), "{:?}", c.q);
    }
    // Without limits on every input it needs a box.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("open.toml");
    std::fs::write(
        &path,
        "name = \"open\"\n[units]\nlength = \"mm\"\nangle = \"deg\"\n[mechanism]\nkind = \"serial\"\n\
         [[mechanism.dh]]\nname = \"j1\"\ntype = \"revolute\"\na = 100.0\nalpha = 90.0\nd = 0.0\ntheta = 0.0\n\
         [[mechanism.dh]]\nname = \"j2\"\ntype = \"revolute\"\na = 100.0\nalpha = 0.0\nd = 0.0\ntheta = 0.0\nlimits = [-90.0, 90.0]\n",
    )
    .unwrap();
    let open = kinecal::io::model_file::ModelFile::load(&path).unwrap();
    let err = design::plan_sampled(&open, &poses(PoseRanges::default()), &opts, None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("range of x is required"), "{err}");
    let ranges = PoseRanges {
        position: [Some((250.0, 450.0)), Some((-200.0, 200.0)), Some((300.0, 600.0))],
        ..Default::default()
    };
    let paper = CandidateSampling {
        points: Points::PaperGrid,
        ..poses(ranges)
    };
    let err = design::plan_sampled(&irb, &paper, &opts, None).unwrap_err().to_string();
    assert!(err.contains("paper's grid"), "{err}");
    let sp = design::plan_sampled(&irb, &poses(ranges), &opts, None).unwrap();
    assert_eq!(sp.plan.selection.selected.len(), 8);
    assert!(sp.angle_inputs.iter().all(|&a| a));
    // A limbs machine samples its own workspace box from its home inputs.
    let head = kinecal::io::builtin::model_file("head-3prs").unwrap();
    let sp = design::plan_sampled(&head, &poses(PoseRanges::default()), &opts, None).unwrap();
    let z: Vec<f64> = sp.candidates.candidates.iter().map(|c| c.target.translation.vector.z).collect();
    assert!(z.iter().all(|&z| (81.4 - 1e-6..=161.4 + 1e-6).contains(&z)), "{z:?}");
    // So does a Stewart platform (its tool frame is its platform frame): positions in its
    // workspace box (z 260–340 mm), its Euler-angle ranges as roll, pitch and yaw offsets.
    let stewart = kinecal::io::builtin::model_file("stewart").unwrap();
    let sp = design::plan_sampled(&stewart, &poses(PoseRanges::default()), &opts, None).unwrap();
    assert_eq!(sp.plan.selection.selected.len(), 8);
    assert!(sp.candidates.candidates.len() > 250, "{}", sp.candidates.report);
    for c in &sp.candidates.candidates {
        let p = c.target.translation.vector;
        assert!(
            p.x.abs() <= 40.0 + 1e-6 && p.y.abs() <= 40.0 + 1e-6 && (260.0 - 1e-6..=340.0 + 1e-6).contains(&p.z),
            "{p}"
        );
        assert!(c.target.rotation.angle() <= 15f64.to_radians(), "{}", c.target.rotation.angle());
    }
    // Non-positive noise is refused before any sampling.
    let bad = design::PlanOptions {
        noise: kinecal::measure::Noise {
            position: 0.0,
            ..Default::default()
        },
        ..opts
    };
    assert!(design::plan_sampled(&head, &poses(PoseRanges::default()), &bad, None).is_err());
}

/// A candidate keeps the rest of the solution its inverse kinematics found (a limbs machine's
/// passive joints): its Jacobian block computed there is the block of the forward kinematics
/// solved again from home, to round-off, so a plan does not depend on which solve gave it.
#[test]
fn blocks_at_a_kept_inverse_solution_are_the_blocks_solved_again() {
    use kinecal::design::{sample_candidates, CandidateSampling, Points, PoseRanges, Region};
    let hexapod = kinecal::io::builtin::model_file("hexapod-6rus").unwrap();
    let sampling = CandidateSampling {
        region: Region::Poses(PoseRanges::default()),
        points: Points::Halton { n: 400, seed: 5 },
        max_condition: None,
    };
    let (mech, made) = sample_candidates(&hexapod, &sampling, None).unwrap();
    let kept = made.candidates;
    // Some of the box is out of reach (given up by the cheap test), the rest kept with a solution.
    assert!(made.report.unreachable > 0 && kept.len() > 300, "{}", made.report);
    assert!(kept.iter().all(|c| c.solution.as_ref().is_some_and(|s| s.len() == 12)));
    let again: Vec<Candidate> = kept
        .iter()
        .map(|c| Candidate {
            solution: None,
            ..c.clone()
        })
        .collect();
    let noise = Noise::default();
    let tolerance = kinecal::identifiability::DEFAULT_RANK_TOLERANCE;
    let columns = design::identifiable_columns(&*mech, &kept, ObservationKind::Pose, &noise, None, 100, tolerance).unwrap();
    let a = CandidateJacobians::build(&*mech, &kept, ObservationKind::Pose, &noise, &columns, None).unwrap();
    let b = CandidateJacobians::build(&*mech, &again, ObservationKind::Pose, &noise, &columns, None).unwrap();
    let scale = b.data().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let worst = a.data().iter().zip(b.data()).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    assert!(
        scale > 0.0 && worst <= 1e-9 * scale,
        "blocks differ by {worst:e} (largest entry {scale:e})"
    );
}

/// `kinecal plan robot.toml` takes the model first, as `identify` and `simulate` do: the same
/// plan as `--model robot.toml`; with both it says they conflict.
#[test]
fn plan_takes_the_model_file_as_its_first_argument() {
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| crate::cli::kinecal(dir.path(), args);
    assert!(run(&["model", "export", "irb120", "-o", "irb.toml"]).status.success());
    let common = [
        "-n",
        "8",
        "--candidates",
        "800",
        "--x-mm",
        "250,450",
        "--y-mm",
        "-200,200",
        "--z-mm",
        "300,600",
    ];
    let a = run(&[&["plan", "irb.toml", "-o", "a.csv"][..], &common[..]].concat());
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    let b = run(&[&["plan", "--model", "irb.toml", "-o", "b.csv"][..], &common[..]].concat());
    assert!(b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));
    let read = |f: &str| std::fs::read_to_string(dir.path().join(f)).unwrap();
    assert_eq!(read("a.csv"), read("b.csv"));
    let both = run(&["plan", "irb.toml", "--model", "irb120", "-o", "c.csv"]);
    assert!(!both.status.success());
    assert!(String::from_utf8_lossy(&both.stderr).contains("cannot be used with"));
    assert!(!dir.path().join("c.csv").exists());
}

/// The rotation ranges go by the names the printed workspace uses (roll, pitch, yaw) as well as
/// α, β, γ: a new user planning a planar 3-RRR typed `--yaw-deg` and got "unexpected argument".
#[test]
fn plan_takes_roll_pitch_yaw_ranges_by_those_names() {
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| crate::cli::kinecal(dir.path(), args);
    let common = ["plan", "planar-3rrr", "-n", "8", "--candidates", "600"];
    let a = run(&[&common[..], &["--yaw-deg", "-10,10", "-o", "a.csv"][..]].concat());
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    assert!(String::from_utf8_lossy(&a.stdout).contains("yaw (-10.0, 10.0)°"));
    let b = run(&[&common[..], &["--gamma-deg", "-10,10", "-o", "b.csv"][..]].concat());
    assert!(b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));
    let read = |f: &str| std::fs::read_to_string(dir.path().join(f)).unwrap();
    assert_eq!(read("a.csv"), read("b.csv"));
}
