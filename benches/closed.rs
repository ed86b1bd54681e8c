//! Timings of the closed-loop engine on the 5-DOF preset: forward kinematics, forward kinematics
//! with the identification Jacobian, inverse kinematics, beside the same machine written as limbs
//! (`examples/models/pm5-limbs.toml`); and the same three of the Stewart
//! platform as its hand-written preset (constraint equations) beside the same machine written as
//! limbs (`examples/models/stewart-limbs.toml`, the generic `kind = "limbs"`), and the 6-RUS
//! hexapod and 3-PRS head that exist only as limbs files.
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
    // The same machine written as limbs (its sub-closed loops as limbs), at the same configuration.
    let l =
        kinecal::io::model_file::ModelFile::load_str(std::path::Path::new("pm5-limbs"), include_str!("../examples/models/pm5-limbs.toml"))
            .unwrap()
            .build();
    c.bench_function("pm5 limbs forward", |b| b.iter(|| l.forward(black_box(&q)).unwrap()));
    c.bench_function(&format!("pm5 limbs forward_with_jacobian ({} params)", l.n_params()), |b| {
        b.iter(|| l.forward_with_jacobian(black_box(&q)).unwrap())
    });
    c.bench_function("pm5 limbs inverse", |b| b.iter(|| l.inverse(black_box(&target), None).unwrap()));
}

fn limbs(c: &mut Criterion) {
    let load = |name: &str, text: &str| {
        kinecal::io::model_file::ModelFile::load_str(std::path::Path::new(name), text)
            .unwrap()
            .build()
    };
    let machines = [
        ("stewart preset", kinecal::io::builtin::model_file("stewart").unwrap().build()),
        (
            "stewart limbs",
            load("stewart-limbs", include_str!("../examples/models/stewart-limbs.toml")),
        ),
        (
            "hexapod-6rus limbs",
            load("hexapod-6rus", include_str!("../examples/models/hexapod-6rus.toml")),
        ),
        (
            "head-3prs limbs",
            load("head-3prs", include_str!("../examples/models/head-3prs.toml")),
        ),
    ];
    for (name, m) in &machines {
        let q = m.sample_configurations(1, 7).unwrap().unwrap().remove(0);
        let target = m.forward(&q).unwrap();
        c.bench_function(&format!("{name} forward"), |b| b.iter(|| m.forward(black_box(&q)).unwrap()));
        c.bench_function(&format!("{name} forward_with_jacobian ({} params)", m.n_params()), |b| {
            b.iter(|| m.forward_with_jacobian(black_box(&q)).unwrap())
        });
        c.bench_function(&format!("{name} inverse"), |b| {
            b.iter(|| m.inverse(black_box(&target), None).unwrap())
        });
    }
}

criterion_group!(benches, pm5, limbs);
criterion_main!(benches);
