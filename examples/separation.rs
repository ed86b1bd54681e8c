//! How well 5 check poses can tell pm5's patterns apart: for one pattern's change (by default
//! a rod 0.1 mm longer, `dl1`), the χ² that fitting each other pattern leaves (noise-free
//! rows, the prior's covariance included), for 5 random poses and for the 5 poses chosen
//! greedily among 2000 to make the closest alternative leave the most. The smaller that χ²,
//! the more often noise makes a check name the alternative first.
//!
//! ```text
//! cargo run --release --example separation -- 20
//! cargo run --release --example separation -- 20 "joint g2 zero" 0.05
//! ```
mod common;
use common::drift::{calibrated, configurations, machine, measure};
use kinecal::drift::patterns;
use kinecal::identify::linearize;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The χ² left by the closest alternative for a change `size` of pattern `t`, on rows `a`
/// (noise-weighted Jacobian of the chosen poses) with the prior's factor `l`.
fn closest(a: &DMatrix<f64>, l: &DMatrix<f64>, d: &[DMatrix<f64>], t: usize, alts: &[usize], size: f64) -> f64 {
    let rows = a.nrows();
    let b = a * l;
    let c = DMatrix::identity(rows, rows) + &b * b.transpose();
    let ci = c.try_inverse().expect("covariance");
    let e: DVector<f64> = (a * &d[t]).column(0) * size;
    alts.iter()
        .map(|&k| {
            let g = a * &d[k];
            let n = g.transpose() * &ci * &g;
            let Some(ni) = n.try_inverse() else { return f64::INFINITY };
            let beta = ni * (g.transpose() * &ci * &e);
            let left = &e - &g * beta;
            left.dot(&(&ci * &left))
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let draws: u64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(20);
    let target = args.get(2).map_or("dl1", String::as_str);
    let size: f64 = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(0.1);
    let mut names: Vec<String> = Vec::new();
    let mut random_best = Vec::new();
    let mut greedy_best = Vec::new();
    for k in 0..draws {
        let m = machine("pm5", 1000 + k);
        let zero = vec![0.0; m.file.inputs().len()];
        let prior = calibrated(&m, &*m.truth, &zero, 60, 2000 + k);
        let model = prior.model.build();
        let l = prior.factor();
        let all = patterns(&*model, &prior.model.inputs(), 1).expect("patterns");
        let idx = |name: &str| all.iter().position(|p| p.name == name).expect(name);
        let t = idx(target);
        let alts: Vec<usize> = (0..all.len()).filter(|&k| k != t).collect();
        let d: Vec<DMatrix<f64>> = all.iter().map(|p| p.directions.clone()).collect();
        let mut rng = ChaCha8Rng::seed_from_u64(5000 + k);
        let q = configurations(&m, 2000, &mut rng);
        let data = measure(&*model, &zero, &q, None, &mut rng);
        let lin = linearize(&*model, &data, &prior.noise).expect("linearize");
        let block = |i: usize| {
            let s = lin.offsets[i];
            let e = lin.offsets.get(i + 1).copied().unwrap_or(lin.residual.len());
            lin.jacobian.rows(s, e - s).into_owned()
        };
        let stack = |set: &[usize]| {
            let blocks: Vec<DMatrix<f64>> = set.iter().map(|&i| block(i)).collect();
            let rows: usize = blocks.iter().map(|b| b.nrows()).sum();
            let mut a = DMatrix::zeros(rows, lin.jacobian.ncols());
            let mut at = 0;
            for b in &blocks {
                a.view_mut((at, 0), (b.nrows(), b.ncols())).copy_from(b);
                at += b.nrows();
            }
            a
        };
        // Five random poses (the first five drawn).
        let random = closest(&stack(&[0, 1, 2, 3, 4]), &l, &d, t, &alts, size);
        // Five chosen greedily among the 2000.
        let mut chosen: Vec<usize> = Vec::new();
        for _ in 0..5 {
            let mut best = (f64::NEG_INFINITY, 0);
            for i in 0..q.len() {
                if chosen.contains(&i) {
                    continue;
                }
                let mut set = chosen.clone();
                set.push(i);
                let v = closest(&stack(&set), &l, &d, t, &alts, size);
                if v > best.0 {
                    best = (v, i);
                }
            }
            chosen.push(best.1);
        }
        let greedy = closest(&stack(&chosen), &l, &d, t, &alts, size);
        let nearest = |set: &[usize]| {
            alts.iter()
                .copied()
                .min_by(|&x, &y| {
                    let a = closest(&stack(set), &l, &d, t, &[x], size);
                    let b = closest(&stack(set), &l, &d, t, &[y], size);
                    a.total_cmp(&b)
                })
                .map(|k| all[k].name.clone())
                .unwrap_or_default()
        };
        let near = nearest(&[0, 1, 2, 3, 4]);
        println!(
            "draw {k}: χ² left by the closest alternative to {target} {size:+}: 5 random poses {random:.2} ({near}), 5 chosen among 2000 {greedy:.2} ({})",
            nearest(&chosen)
        );
        names.push(near);
        random_best.push(random);
        greedy_best.push(greedy);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "median over {draws} draws: 5 random poses {:.2}, 5 chosen {:.2} (a pattern is named alone when the closest alternative leaves more than 6.6: the χ² quantile of one degree of freedom at 1 %)",
        median(&mut random_best),
        median(&mut greedy_best)
    );
}
