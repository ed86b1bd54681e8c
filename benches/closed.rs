//! Timings of the closed-loop engine on the 5-DOF preset: forward kinematics, forward kinematics
//! with the identification Jacobian, inverse kinematics.
use criterion::{criterion_group, criterion_main, Criterion};
use kinecal::model::presets::pm5::{Parasitic, Pm5};
use kinecal::model::Mechanism;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

fn pm5(c: &mut Criterion) {
    let m = Pm5::mechanism(Parasitic::Physical);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let q = m.random_configurations(&mut rng, 1).unwrap().remove(0);
    let target = m.forward(&q).unwrap();
    c.bench_function("pm5 forward", |b| b.iter(|| m.forward(black_box(&q)).unwrap()));
    c.bench_function("pm5 forward_with_jacobian (44 params)", |b| {
        b.iter(|| m.forward_with_jacobian(black_box(&q)).unwrap())
    });
    c.bench_function("pm5 inverse", |b| b.iter(|| m.inverse(black_box(&target), None).unwrap()));
}

criterion_group!(benches, pm5);
criterion_main!(benches);
