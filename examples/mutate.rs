//! Mutated files through every command: no panic, no hang, one clear line, inputs untouched.
//!
//! ```sh
//! cargo build --release && cargo run --release --example mutate -- --cases 10000 --seed 1
//! ```
//!
//! Builds small valid inputs with the `kinecal` binary (model files of every built-in kind, data,
//! validation and target files), then for each case mutates one file at random (a number made
//! extreme, negated, NaN or removed; a line deleted, duplicated or cut; header names swapped or
//! misspelt; a BOM, bytes that are not UTF-8, a key renamed, an array lengthened, the file
//! emptied) and runs one command on it with a watchdog of `--timeout` seconds. Every outcome is
//! counted: exit 0, 1 (input refused), 2 (computed but failed its checks), and the defects: a
//! panic or another exit code, a hang, an error of more than one line, an input file changed.
//! The program exits non-zero when any defect was found and prints the first ones; `--keep CASE`
//! stops at that case and leaves its files in a temporary directory.
use rand::seq::IndexedRandom;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn kinecal() -> PathBuf {
    let exe = std::env::current_exe().expect("own path");
    // target/release/examples/mutate → target/release/kinecal
    let dir = exe.parent().and_then(|p| p.parent()).expect("target dir");
    let bin = dir.join(if cfg!(windows) { "kinecal.exe" } else { "kinecal" });
    assert!(bin.exists(), "{} missing: run `cargo build --release` first", bin.display());
    bin
}

fn run_ok(bin: &Path, dir: &Path, args: &[&str]) {
    let out = Command::new(bin).current_dir(dir).args(args).output().expect("run kinecal");
    assert!(out.status.success(), "setup {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

/// One kind's valid inputs.
struct Kind {
    model: &'static str,
    data: &'static str,
    validation: &'static str,
    targets: &'static str,
}

const KINDS: [Kind; 8] = [
    Kind {
        model: "irb120.toml",
        data: "irb120-d.csv",
        validation: "irb120-v.csv",
        targets: "irb120-t.csv",
    },
    Kind {
        model: "pm5.toml",
        data: "pm5-d.csv",
        validation: "pm5-v.csv",
        targets: "pm5-t.csv",
    },
    Kind {
        model: "stewart.toml",
        data: "stewart-d.csv",
        validation: "stewart-v.csv",
        targets: "stewart-t.csv",
    },
    Kind {
        model: "terms.toml",
        data: "terms-d.csv",
        validation: "terms-v.csv",
        targets: "terms-t.csv",
    },
    Kind {
        model: "head.toml",
        data: "head-d.csv",
        validation: "head-v.csv",
        targets: "head-t.csv",
    },
    Kind {
        model: "pm5-limbs.toml",
        data: "pm5l-d.csv",
        validation: "pm5l-v.csv",
        targets: "pm5l-t.csv",
    },
    Kind {
        model: "chain.toml",
        data: "chain-d.csv",
        validation: "chain-v.csv",
        targets: "chain-t.csv",
    },
    Kind {
        model: "t3r1.toml",
        data: "t3r1-d.csv",
        validation: "t3r1-v.csv",
        targets: "t3r1-t.csv",
    },
];

fn setup(bin: &Path, dir: &Path) {
    // (pm5-limbs: limbs on other limbs' bodies; t3r1-chain: parallelogram joints.)
    for (k, name) in KINDS
        .iter()
        .zip(["irb120", "pm5", "stewart", "irb120", "head", "pm5-limbs", "t3r1-chain", "t3r1"])
    {
        if name == "head" {
            // A parallel machine that is only a model file (kind = "limbs").
            std::fs::write(dir.join(k.model), include_str!("models/head-3prs.toml")).unwrap();
        } else {
            run_ok(bin, dir, &["model", "export", name, "--out", k.model, "--force"]);
        }
        if k.model == "terms.toml" {
            // The IRB 120 with joint terms (lost motion, gravity compliance, a harmonic).
            let text = std::fs::read_to_string(dir.join(k.model)).unwrap().replace(
                "\n[calibration]",
                "\n[mechanism.joint_terms]\nbacklash = [\"q1\", \"q2\", \"q3\"]\ngravity = [\"q2\", \"q3\"]\nharmonic = [\"q2\"]\n\n[calibration]",
            );
            std::fs::write(dir.join(k.model), text).unwrap();
        }
        run_ok(
            bin,
            dir,
            &[
                "simulate",
                k.model,
                "--poses",
                "40",
                "--seed",
                "1",
                "--noise-mm",
                "0.02",
                "--noise-deg",
                "0.02",
                "--out",
                k.data,
                "--truth",
                "truth.toml",
                "--validation-poses",
                "10",
                "--validation-out",
                k.validation,
                "--force",
            ],
        );
        // Targets: the validation poses without their inputs.
        let v = std::fs::read_to_string(dir.join(k.validation)).unwrap();
        let mut lines = v.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let keep: Vec<usize> = (0..header.len())
            .filter(|&i| matches!(header[i], "id" | "x_mm" | "y_mm" | "z_mm" | "qw" | "qx" | "qy" | "qz"))
            .collect();
        let mut t = keep.iter().map(|&i| header[i]).collect::<Vec<_>>().join(",") + "\n";
        for l in lines {
            let f: Vec<&str> = l.split(',').collect();
            t += &(keep.iter().map(|&i| f[i]).collect::<Vec<_>>().join(",") + "\n");
        }
        std::fs::write(dir.join(k.targets), t).unwrap();
    }
}

const EXTREME: [&str; 12] = [
    "0", "-0", "1e308", "-1e308", "1e-308", "1e15", "NaN", "inf", "-inf", "", "abc", "1e400",
];

/// Mutate `text` once (see the module docs).
fn mutate(text: &str, rng: &mut ChaCha8Rng) -> Vec<u8> {
    let lines: Vec<&str> = text.lines().collect();
    let pick_line = |rng: &mut ChaCha8Rng| rng.random_range(0..lines.len().max(1));
    let numbers: Vec<(usize, usize)> = {
        // Byte ranges of numbers in the text.
        let b = text.as_bytes();
        let mut v = Vec::new();
        let mut i = 0;
        while i < b.len() {
            if b[i].is_ascii_digit() || (b[i] == b'-' && i + 1 < b.len() && b[i + 1].is_ascii_digit()) {
                let s = i;
                i += 1;
                while i < b.len() && (b[i].is_ascii_digit() || matches!(b[i], b'.' | b'e' | b'E' | b'-' | b'+')) {
                    i += 1;
                }
                v.push((s, i));
            } else {
                i += 1;
            }
        }
        v
    };
    let replace_number = |rng: &mut ChaCha8Rng, with: &dyn Fn(&str, &mut ChaCha8Rng) -> String| -> Vec<u8> {
        if numbers.is_empty() {
            return text.as_bytes().to_vec();
        }
        let (s, e) = *numbers.choose(rng).unwrap();
        let new = with(&text[s..e], rng);
        format!("{}{}{}", &text[..s], new, &text[e..]).into_bytes()
    };
    match rng.random_range(0..14) {
        0 => replace_number(rng, &|_, r| EXTREME.choose(r).unwrap().to_string()),
        1 => replace_number(rng, &|n, _| {
            if let Some(m) = n.strip_prefix('-') {
                m.to_string()
            } else {
                format!("-{n}")
            }
        }),
        2 => replace_number(rng, &|n, r| {
            let v: f64 = n.parse().unwrap_or(1.0);
            format!(
                "{}",
                v * [10.0, 0.1, 1000.0, 0.001, 57.29577951308232, 0.017453292519943295]
                    .choose(r)
                    .unwrap()
            )
        }),
        3 => {
            let k = pick_line(rng);
            lines
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != k)
                .map(|(_, l)| format!("{l}\n"))
                .collect::<String>()
                .into_bytes()
        }
        4 => {
            let k = pick_line(rng);
            lines
                .iter()
                .enumerate()
                .flat_map(|(i, l)| if i == k { vec![*l, *l] } else { vec![*l] })
                .map(|l| format!("{l}\n"))
                .collect::<String>()
                .into_bytes()
        }
        5 => {
            let cut = rng.random_range(0..text.len().max(1));
            text.as_bytes()[..cut].to_vec()
        }
        6 => {
            // Swap two fields of the first line (a header, or a model file's comment).
            let mut f: Vec<&str> = lines.first().copied().unwrap_or("").split(',').collect();
            if f.len() > 1 {
                let (a, b) = (rng.random_range(0..f.len()), rng.random_range(0..f.len()));
                f.swap(a, b);
            }
            let mut s = f.join(",") + "\n";
            for l in lines.iter().skip(1) {
                s += l;
                s.push('\n');
            }
            s.into_bytes()
        }
        7 => {
            let mut v = vec![0xEF, 0xBB, 0xBF];
            v.extend_from_slice(text.as_bytes());
            v
        }
        8 => {
            let mut v = text.as_bytes().to_vec();
            let at = rng.random_range(0..v.len().max(1));
            v.insert(at.min(v.len()), 0xFF);
            v
        }
        9 => {
            // Rename a key or a column: a letter changed.
            let mut v = text.as_bytes().to_vec();
            let letters: Vec<usize> = (0..v.len()).filter(|&i| v[i].is_ascii_lowercase()).collect();
            if let Some(&i) = letters.choose(rng) {
                v[i] = if v[i] == b'z' { b'a' } else { v[i] + 1 };
            }
            v
        }
        10 => {
            // An array or a row one element longer.
            let k = pick_line(rng);
            lines
                .iter()
                .enumerate()
                .map(|(i, l)| {
                    if i == k {
                        if let Some(p) = l.rfind(']') {
                            format!("{}, 5{}\n", &l[..p], &l[p..])
                        } else {
                            format!("{l},5\n")
                        }
                    } else {
                        format!("{l}\n")
                    }
                })
                .collect::<String>()
                .into_bytes()
        }
        11 => Vec::new(),
        12 => {
            // Many numbers at once (a unit mistake over a whole column-like span).
            let mut t = text.to_string();
            for _ in 0..rng.random_range(2..20) {
                t = String::from_utf8(replace_number_in(&t, rng)).unwrap_or(t);
            }
            t.into_bytes()
        }
        _ => {
            let mut v = text.as_bytes().to_vec();
            let at = rng.random_range(0..v.len().max(1));
            v.insert(at.min(v.len()), *b",;#[]=\"\n ".choose(rng).unwrap());
            v
        }
    }
}

fn replace_number_in(text: &str, rng: &mut ChaCha8Rng) -> Vec<u8> {
    let b = text.as_bytes();
    let starts: Vec<usize> = (0..b.len())
        .filter(|&i| b[i].is_ascii_digit() && (i == 0 || !b[i - 1].is_ascii_digit() && b[i - 1] != b'.'))
        .collect();
    let Some(&s) = starts.choose(rng) else { return b.to_vec() };
    let mut e = s;
    while e < b.len() && (b[e].is_ascii_digit() || b[e] == b'.') {
        e += 1;
    }
    let v: f64 = text[s..e].parse().unwrap_or(1.0);
    format!("{}{}{}", &text[..s], v * 1000.0, &text[e..]).into_bytes()
}

#[derive(Default)]
struct Counts {
    exit0: usize,
    exit1: usize,
    exit2: usize,
    panics: Vec<String>,
    hangs: Vec<String>,
    multi_line: Vec<String>,
    inputs_changed: Vec<String>,
    slowest: (f64, String),
    /// Runs that took more than half the watchdog's time, with their seconds.
    slow: Vec<(f64, String)>,
}

fn main() {
    let mut cases = 10_000usize;
    let mut seed = 1u64;
    let mut timeout = 10.0f64;
    let mut keep: Option<usize> = None;
    let args: Vec<String> = std::env::args().collect();
    let mut i = 1;
    while i < args.len() {
        let v = args.get(i + 1).cloned().unwrap_or_default();
        match args[i].as_str() {
            "--cases" => cases = v.parse().expect("--cases N"),
            "--seed" => seed = v.parse().expect("--seed S"),
            "--timeout" => timeout = v.parse().expect("--timeout SECONDS"),
            "--keep" => keep = Some(v.parse().expect("--keep CASE")),
            other => panic!("unknown argument {other} (--cases N, --seed S, --timeout SECONDS, --keep CASE)"),
        }
        i += 2;
    }
    let bin = kinecal();
    let tmp = std::env::temp_dir().join(format!("kinecal-mutate-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    setup(&bin, &tmp);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut counts = Counts::default();
    let start = Instant::now();
    for case in 0..cases {
        let kind = KINDS.choose(&mut rng).unwrap();
        // Which file is mutated, and which command reads it.
        let target = [kind.model, kind.data, kind.validation, kind.targets][rng.random_range(0..4)];
        let original = std::fs::read_to_string(tmp.join(target)).unwrap();
        let mutated = mutate(&original, &mut rng);
        let case_dir = tmp.join("case");
        let _ = std::fs::remove_dir_all(&case_dir);
        std::fs::create_dir_all(&case_dir).unwrap();
        for f in [kind.model, kind.data, kind.validation, kind.targets] {
            std::fs::copy(tmp.join(f), case_dir.join(f)).unwrap();
        }
        std::fs::write(case_dir.join(target), &mutated).unwrap();
        if keep == Some(case) {
            // The files of one case, to run its commands by hand.
            let kept = std::env::temp_dir().join(format!("kinecal-mutate-case-{case}"));
            let _ = std::fs::remove_dir_all(&kept);
            std::fs::rename(&case_dir, &kept).unwrap();
            println!("case {case}: {target} mutated; files in {}", kept.display());
            return;
        }
        let (m, d, v, t) = (kind.model, kind.data, kind.validation, kind.targets);
        let commands: Vec<Vec<&str>> = if target == kind.model {
            vec![
                vec!["data", "check", m, d],
                vec!["identify", m, d, "--validation", v, "--out", "out.toml", "--report", "out.html"],
                vec!["identifiability", m, d],
                vec!["validate", m, v],
                vec!["simulate", m, "--poses", "8", "--out", "out.csv", "--truth", "out.toml"],
                vec!["compensate", m, t, "--out", "out.csv"],
                vec!["plan", "--model", m, "--candidates", "300", "-n", "10", "--output", "out.csv"],
            ]
        } else if target == kind.targets {
            vec![vec!["compensate", m, t, "--out", "out.csv"]]
        } else if target == kind.validation {
            vec![
                vec!["validate", m, v],
                vec!["identify", m, d, "--validation", v, "--out", "out.toml"],
            ]
        } else {
            vec![
                vec!["data", "check", m, d],
                vec!["identify", m, d, "--out", "out.toml", "--report", "out.html"],
                vec!["identifiability", m, d],
                vec!["data", "split", m, d, "--by", "even", "--out", "a.csv", "--rest", "b.csv"],
            ]
        };
        let cmd = commands.choose(&mut rng).unwrap().clone();
        let label = format!("case {case}: {target} mutated, kinecal {}", cmd.join(" "));
        let before: Vec<Vec<u8>> = [m, d, v, t].iter().map(|f| std::fs::read(case_dir.join(f)).unwrap()).collect();
        let t0 = Instant::now();
        let mut child = Command::new(&bin)
            .current_dir(&case_dir)
            .args(&cmd)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawn kinecal");
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break Some(s);
            }
            if t0.elapsed() > Duration::from_secs_f64(timeout) {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
            std::thread::sleep(Duration::from_millis(2));
        };
        let secs = t0.elapsed().as_secs_f64();
        if secs > 0.5 * timeout {
            counts.slow.push((secs, label.clone()));
        }
        if secs > counts.slowest.0 {
            counts.slowest = (secs, label.clone());
        }
        let mut err = String::new();
        if let Some(mut e) = child.stderr.take() {
            use std::io::Read;
            let _ = e.read_to_string(&mut err);
        }
        match status.map(|s| s.code()) {
            None => counts.hangs.push(label.clone()),
            Some(Some(0)) => counts.exit0 += 1,
            Some(Some(c @ (1 | 2))) => {
                if c == 1 {
                    counts.exit1 += 1
                } else {
                    counts.exit2 += 1
                }
                if err.lines().filter(|l| l.starts_with("kinecal: ")).count() != 1 {
                    counts.multi_line.push(format!("{label}: {err}"));
                }
            }
            Some(other) => counts.panics.push(format!(
                "{label}: exit {other:?}: {}",
                err.lines().take(3).collect::<Vec<_>>().join(" | ")
            )),
        }
        let after: Vec<Vec<u8>> = [m, d, v, t]
            .iter()
            .map(|f| std::fs::read(case_dir.join(f)).unwrap_or_default())
            .collect();
        if after != before {
            counts.inputs_changed.push(label);
        }
        if (case + 1) % 1000 == 0 {
            eprintln!("{} cases in {:.0} s", case + 1, start.elapsed().as_secs_f64());
        }
    }
    let _ = std::fs::remove_dir_all(&tmp);
    println!(
        "{cases} mutated files (seed {seed}) in {:.0} s: exit 0 {}, exit 1 (refused) {}, exit 2 (failed checks) {}; panics {}, hangs (> {timeout} s) {}, errors not on one line {}, inputs changed {}; slowest {:.2} s ({})",
        start.elapsed().as_secs_f64(),
        counts.exit0,
        counts.exit1,
        counts.exit2,
        counts.panics.len(),
        counts.hangs.len(),
        counts.multi_line.len(),
        counts.inputs_changed.len(),
        counts.slowest.0,
        counts.slowest.1
    );
    for (secs, label) in &counts.slow {
        println!("slow ({secs:.2} s, over half the watchdog's time): {label}");
    }
    let defects: Vec<&String> = counts
        .panics
        .iter()
        .chain(&counts.hangs)
        .chain(&counts.multi_line)
        .chain(&counts.inputs_changed)
        .collect();
    for d in defects.iter().take(20) {
        println!("DEFECT {d}");
    }
    if !defects.is_empty() {
        std::process::exit(1);
    }
}
