//! Mutated model and data files through the parsers and a small calibration, as a proptest run
//! by `cargo test`, under a watchdog: every case answers (a value or a typed error) within
//! seconds, none panics. (`cargo run --release --example mutate` does the same through every
//! command of the binary, ten thousand files at a time.)
use kinecal::calibrate::{calibrate, CalibrationOptions};
use kinecal::io::data_file::{data_from_table, InputColumns};
use kinecal::io::model_file::ModelFile;
use kinecal::io::table::parse_table_with_gaps;
use proptest::prelude::*;
use std::path::Path;
use std::sync::mpsc;
use std::sync::OnceLock;
use std::time::Duration;

/// Valid inputs of every built-in kind: (model text, data text of 12 poses).
fn fixtures() -> &'static Vec<(String, String)> {
    static F: OnceLock<Vec<(String, String)>> = OnceLock::new();
    F.get_or_init(|| {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        ["irb120", "pm5", "stewart"]
            .iter()
            .map(|k| {
                crate::cli::ok(d, &["model", "export", k, "--out", "m.toml", "--force"]);
                crate::cli::ok(
                    d,
                    &[
                        "simulate",
                        "m.toml",
                        "--poses",
                        "12",
                        "--seed",
                        "2",
                        "--noise-mm",
                        "0.02",
                        "--noise-deg",
                        "0.02",
                        "--out",
                        "d.csv",
                        "--truth",
                        "t.toml",
                        "--force",
                    ],
                );
                (
                    std::fs::read_to_string(d.join("m.toml")).unwrap(),
                    std::fs::read_to_string(d.join("d.csv")).unwrap(),
                )
            })
            .collect()
    })
}

const REPLACEMENTS: [&str; 14] = [
    "0", "-0", "1e308", "-1e308", "1e-308", "1e15", "NaN", "inf", "", "x", ",", "]", "\n", "-",
];

/// Replace the `len` characters at `at` (a fraction of the text) with `with`.
fn mutate(text: &str, at: f64, len: usize, with: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let i = ((at * chars.len() as f64) as usize).min(chars.len());
    let j = (i + len).min(chars.len());
    chars[..i].iter().collect::<String>() + with + &chars[j..].iter().collect::<String>()
}

/// Parse both texts and, when they are valid, calibrate; `Ok(())` or a typed error are answers.
fn answer(model: &str, data: &str) {
    let Ok(file) = ModelFile::load_str(Path::new("m.toml"), model) else {
        return;
    };
    let Ok(table) = parse_table_with_gaps(Path::new("d.csv"), data) else {
        return;
    };
    let Ok(set) = data_from_table(&table, &file.inputs(), InputColumns::Required) else {
        return;
    };
    let _ = calibrate(&file, &set, None, &CalibrationOptions::default());
}

/// Run `answer` in a thread; fail if it takes longer than the watchdog or panics.
fn within_watchdog(model: String, data: String) -> Result<(), String> {
    let (tx, rx) = mpsc::channel();
    let (m, d) = (model.clone(), data.clone());
    std::thread::spawn(move || {
        let r = std::panic::catch_unwind(|| answer(&m, &d));
        let _ = tx.send(r.is_ok());
    });
    match rx.recv_timeout(Duration::from_secs(20)) {
        Ok(true) => Ok(()),
        Ok(false) => Err("panicked".into()),
        Err(_) => Err("no answer within 20 s".into()),
    }
}

proptest! {
    // A fixed seed: the same cases on every run (CI must not depend on the draw).
    #![proptest_config(ProptestConfig { rng_seed: proptest::test_runner::RngSeed::Fixed(20261125), ..ProptestConfig::with_cases(96) })]

    #[test]
    fn mutated_files_get_an_answer(kind in 0usize..3, in_model: bool, at in 0.0..1.0f64, len in 0usize..6, with in proptest::sample::select(REPLACEMENTS.to_vec())) {
        let (model, data) = fixtures()[kind].clone();
        let (model, data) = if in_model { (mutate(&model, at, len, with), data) } else { (model, mutate(&data, at, len, with)) };
        let r = within_watchdog(model.clone(), data.clone());
        prop_assert!(r.is_ok(), "{:?} on {} mutated at {at:.3} ({len} chars → {with:?})", r, if in_model { "the model" } else { "the data" });
    }
}
