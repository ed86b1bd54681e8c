//! The figures of docs/drift.md: `kinecal check` and `identify --prior` on virtual prototypes.
//! Each draw: a prototype (errors ±0.2 mm / ±0.02° on the model file's parameters) calibrated
//! from 60 tracker poses (20 µm / 0.02° noise); then, unchanged or after one drift, 5 new poses
//! checked ([`kinecal::drift::check`], false-alarm rate 1 %) and 10 new poses used to update the
//! calibration ([`kinecal::drift::update`]), its held-out error on 50 noise-free poses compared
//! with a full recalibration on 60 poses of the drifted machine. Draws run in parallel, each
//! seeded.
//!
//! ```text
//! cargo run --release --example drift -- 100 irb120
//! cargo run --release --example drift -- 100 pm5
//! cargo run --release --example drift -- 100 pm5 file   # the prior read back from the written file
//! cargo run --release --example drift -- 1000 pm5 unchanged   # the false-alarm rate alone
//! cargo run --release --example drift -- 100 pm5 planned   # the check's 5 poses planned
//! ```
//!
//! `planned`: the check's 5 configurations are chosen by [`kinecal::drift::plan_check_poses`]
//! among 2000 drawn over the workspace, on the draw's calibration (before any drift), as
//! `kinecal check CAL --plan 5` chooses them; everything else as without it.
mod common;
use common::drift::{calibrated, calibrated_file, configurations, drifted, held_out_rms, machine, measure, Drift};
use kinecal::drift::{check, plan_check_poses, update, CheckOptions, CheckPlanOptions, UpdateOptions};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// One draw's outcome under one drift.
#[derive(Debug, Clone, Default)]
struct Outcome {
    drifted: bool,
    named: bool,
    /// The true pattern named, or among those the new poses cannot tell from the one named.
    among: bool,
    /// The pattern named with no alternative.
    alone: bool,
    pattern: String,
    released: usize,
    released_true: bool,
    released_among: bool,
    update_mm: f64,
    recal_mm: f64,
    prior_mm: f64,
    largest_move: f64,
}

fn scenarios(model: &str) -> Vec<(&'static str, Drift, &'static str)> {
    match model {
        "pm5" => vec![
            ("unchanged", Drift::None, ""),
            (
                "input g2 zero +0.05 mm",
                Drift::InputOffset { input: 1, amount: 0.05 },
                "joint g2 zero",
            ),
            (
                "input g2 zero +0.1 mm",
                Drift::InputOffset { input: 1, amount: 0.1 },
                "joint g2 zero",
            ),
            ("length dl1 +0.1 mm", Drift::Parameter { name: "dl1", amount: 0.1 }, "dl1"),
            ("tool re-mounted 0.2 mm off", Drift::Tool { mm: 0.2 }, "tool position"),
        ],
        _ => vec![
            ("unchanged", Drift::None, ""),
            (
                "joint q2 offset +0.05°",
                Drift::InputOffset {
                    input: 1,
                    amount: 0.05f64.to_radians(),
                },
                "joint q2 offset",
            ),
            (
                "link length 2-3.vz +0.1 mm",
                Drift::Parameter {
                    name: "2-3.vz",
                    amount: 0.1,
                },
                "2-3.vz",
            ),
            ("tool re-mounted 0.2 mm off", Drift::Tool { mm: 0.2 }, "tool position"),
        ],
    }
}

fn main() {
    let draws: u64 = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(100);
    let model = std::env::args().nth(2).unwrap_or_else(|| "irb120".into());
    // "file": the prior read back from the calibrated model file as written.
    let from_file = std::env::args().skip(3).any(|a| a == "file");
    let planned = std::env::args().skip(3).any(|a| a == "planned");
    let mut scen = scenarios(&model);
    if std::env::args().skip(3).any(|a| a == "unchanged") {
        scen.retain(|s| s.1 == Drift::None);
    }
    let t = std::time::Instant::now();
    let results: Vec<Vec<Outcome>> = (0..draws)
        .into_par_iter()
        .map(|k| {
            let m = machine(&model, 1000 + k);
            let zero = vec![0.0; m.file.inputs().len()];
            let prior = if from_file {
                calibrated_file(&m, &*m.truth, &zero, 60, 2000 + k)
            } else {
                calibrated(&m, &*m.truth, &zero, 60, 2000 + k)
            };
            let plan = planned.then(|| {
                let mut rng = ChaCha8Rng::seed_from_u64(6000 + k);
                let candidates = configurations(&m, 2000, &mut rng);
                let p = plan_check_poses(&prior, &candidates, &CheckPlanOptions::default()).expect("plan");
                p.selected.iter().map(|&i| candidates[i].clone()).collect::<Vec<_>>()
            });
            scen.iter()
                .map(|(_, drift, truth_name)| {
                    let mut rng = ChaCha8Rng::seed_from_u64(3000 + k);
                    let (truth, shift) = drifted(&m, *drift, &mut rng);
                    let mut q5 = configurations(&m, 5, &mut rng);
                    if let Some(p) = &plan {
                        q5 = p.clone();
                    }
                    let five = measure(&*truth, &shift, &q5, Some(&m.noise), &mut rng);
                    let c = check(&prior, &five, &CheckOptions::default()).expect("check");
                    let pattern = c.pattern.as_ref().map(|p| p.name.clone()).unwrap_or_default();
                    let alternatives: Vec<String> = c
                        .pattern
                        .as_ref()
                        .map(|p| p.alternatives.iter().map(|a| a.name.clone()).collect())
                        .unwrap_or_default();
                    let q10 = configurations(&m, 10, &mut rng);
                    let ten = measure(&*truth, &shift, &q10, Some(&m.noise), &mut rng);
                    let up = update(&prior, &ten, &UpdateOptions::default()).expect("update");
                    let q50 = configurations(&m, 50, &mut rng);
                    let recal = calibrated(&m, &*truth, &shift, 60, 4000 + k);
                    let update_mm = held_out_rms(&*up.model_file.build(), &*truth, &shift, &q50);
                    let recal_mm = held_out_rms(&*recal.model.build(), &*truth, &shift, &q50);
                    if std::env::var_os("DRIFT_VERBOSE").is_some() {
                        eprintln!(
                            "draw {k} {truth_name}: held out update {update_mm:.4} recal {recal_mm:.4}; check {} pattern {pattern} (cannot tell from {alternatives:?}); update releases {:?} chi2 {:.1}/{:.1} converged {}",
                            c.drifted,
                            up.releases.iter().map(|r| r.describe()).collect::<Vec<_>>(),
                            up.chi2,
                            up.bound,
                            up.converged
                        );
                    }
                    Outcome {
                        drifted: c.drifted,
                        named: pattern == *truth_name,
                        among: pattern == *truth_name || alternatives.iter().any(|a| a == truth_name),
                        alone: alternatives.is_empty(),
                        pattern,
                        released: up.releases.len(),
                        released_true: up.releases.first().is_some_and(|r| r.name == *truth_name),
                        released_among: up
                            .releases
                            .first()
                            .is_some_and(|r| r.name == *truth_name || r.alternatives.iter().any(|a| a.name == *truth_name)),
                        update_mm,
                        recal_mm,
                        prior_mm: held_out_rms(&*prior.model.build(), &*truth, &shift, &q50),
                        largest_move: up.largest_move_sigmas,
                    }
                })
                .collect()
        })
        .collect();
    println!(
        "{model}: {draws} draws, calibration on 60 tracker poses (20 µm / 0.02° noise), check on 5 {} poses at a false-alarm rate of 1 %, update from 10 poses, held out 50 poses ({:.0} s)",
        if planned { "planned" } else { "random" },
        t.elapsed().as_secs_f64()
    );
    for (s, (label, drift, _)) in scen.iter().enumerate() {
        let o: Vec<&Outcome> = results.iter().map(|r| &r[s]).collect();
        let n = o.len() as f64;
        let count = |f: &dyn Fn(&Outcome) -> bool| o.iter().filter(|x| f(x)).count();
        let mean = |f: &dyn Fn(&Outcome) -> f64| o.iter().map(|x| f(x)).sum::<f64>() / n;
        let ratio = mean(&|x| x.update_mm) / mean(&|x| x.recal_mm);
        let within = count(&|x| x.update_mm <= 1.2 * x.recal_mm);
        if *drift == Drift::None {
            let mut moves: Vec<f64> = o.iter().map(|x| x.largest_move).collect();
            moves.sort_by(f64::total_cmp);
            println!(
                "{label}: check 'still calibrated' {}/{draws}; update released nothing {}/{draws}; largest parameter move over the draws' parameters median {:.2} σ, 95th percentile {:.2} σ, max {:.2} σ; held out: update {:.4} mm, recalibration {:.4} mm (mean)",
                count(&|x| !x.drifted),
                count(&|x| x.released == 0),
                moves[moves.len() / 2],
                moves[(moves.len() * 95 / 100).min(moves.len() - 1)],
                moves[moves.len() - 1],
                mean(&|x| x.update_mm),
                mean(&|x| x.recal_mm)
            );
        } else {
            let mut others: std::collections::BTreeMap<&str, usize> = Default::default();
            for x in o.iter().filter(|x| !x.named) {
                *others.entry(x.pattern.as_str()).or_default() += 1;
            }
            println!(
                "{label}: check 'drifted' {}/{draws}, the named pattern the true one {}/{draws} (others: {others:?}), the true one named or among those it cannot tell it from {}/{draws}, named with no alternative {}/{draws}; update released the true pattern first {}/{draws} (or one it cannot tell from it: {}/{draws}); held out (mean): prior {:.4} mm, update {:.4} mm, recalibration on 60 poses {:.4} mm, ratio {ratio:.3}; update within 1.2x of the recalibration in {within}/{draws} draws",
                count(&|x| x.drifted),
                count(&|x| x.named),
                count(&|x| x.among),
                count(&|x| x.alone),
                count(&|x| x.released_true),
                count(&|x| x.released_among),
                mean(&|x| x.prior_mm),
                mean(&|x| x.update_mm),
                mean(&|x| x.recal_mm),
            );
        }
    }
}
