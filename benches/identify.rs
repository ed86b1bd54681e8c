//! Identification speed on an IRB 120-sized problem (7 dyads, 42 coordinates, rank 30), synthetic
//! noisy full-pose data: 500 poses, as in the real-data job.
use criterion::{criterion_group, criterion_main, Criterion};
use kinecal::identify::{identify, Method, Options};
use kinecal::measure::Noise;
use kinecal::model::irb120;
use kinecal::simulate::{self, ObservationKind};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn bench(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let nominal = irb120::nominal();
    let delta = simulate::random_errors(&nominal, &mut rng, 0.5, 0.002, None);
    let truth = simulate::perturbed(&nominal, &delta);
    let q: Vec<Vec<f64>> = (0..500).map(|_| (0..6).map(|_| rng.random_range(-2.0..2.0)).collect()).collect();
    let noise = Noise {
        position: 0.02,
        orientation: 2e-4,
        ..Noise::default()
    };
    let data = simulate::measure(&truth, &q, ObservationKind::Pose, Some(&noise), &mut rng).unwrap();
    let mut g = c.benchmark_group("identify_irb120_500_poses");
    for (name, method) in [
        ("gauss_newton", Method::GaussNewton),
        ("linear", Method::Linear),
        ("recursive", Method::Recursive),
    ] {
        let opts = Options {
            method,
            noise,
            ..Options::default()
        };
        g.bench_function(name, |b| b.iter(|| identify(&nominal, &data, &opts).unwrap()));
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
