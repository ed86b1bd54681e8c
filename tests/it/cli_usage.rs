//! Usage errors over the whole command set: a misspelled flag, a bad value, a missing argument or
//! an unknown command exits 1 (wrong input) with one line naming the flag or value and the fix;
//! `--help` and `--version` exit 0.
use crate::cli::kinecal;

/// The commands listed under `Commands:` in `kinecal PATH --help` (without `help`).
fn subcommands(path: &[&str]) -> Vec<String> {
    let dir = tempfile::tempdir().unwrap();
    let mut args = path.to_vec();
    args.push("--help");
    let out = kinecal(dir.path(), &args);
    assert_eq!(out.status.code(), Some(0), "kinecal {args:?}");
    let text = String::from_utf8(out.stdout).unwrap();
    let mut names = Vec::new();
    let mut inside = false;
    for line in text.lines() {
        if line.starts_with("Commands:") {
            inside = true;
        } else if inside && line.starts_with("  ") && !line.starts_with("   ") {
            let name = line.split_whitespace().next().unwrap().to_string();
            if name != "help" {
                names.push(name);
            }
        } else if inside && !line.starts_with("  ") {
            break;
        }
    }
    names
}

/// Every command path, leaves and groups (`[]`, `["data"]`, `["data", "join"]`, …).
fn all_paths() -> (Vec<Vec<String>>, Vec<Vec<String>>) {
    let (mut leaves, mut groups) = (Vec::new(), vec![Vec::new()]);
    let mut todo: Vec<Vec<String>> = vec![Vec::new()];
    while let Some(path) = todo.pop() {
        let p: Vec<&str> = path.iter().map(String::as_str).collect();
        for name in subcommands(&p) {
            let mut child = path.clone();
            child.push(name);
            let c: Vec<&str> = child.iter().map(String::as_str).collect();
            if subcommands(&c).is_empty() {
                leaves.push(child);
            } else {
                groups.push(child.clone());
                todo.push(child);
            }
        }
    }
    (leaves, groups)
}

/// The one error line of a run that must exit 1.
fn usage_error(args: &[&str]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let out = kinecal(dir.path(), args);
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(1), "kinecal {args:?} should exit 1: {err}");
    assert!(out.stdout.is_empty(), "kinecal {args:?} printed on stdout");
    assert_eq!(err.lines().count(), 1, "kinecal {args:?}: one line expected, got: {err}");
    err.trim_end()
        .strip_prefix("kinecal: error: ")
        .unwrap_or_else(|| panic!("prefix: {err}"))
        .to_string()
}

#[test]
fn every_command_refuses_a_misspelled_flag_on_one_line_with_exit_1() {
    let (leaves, groups) = all_paths();
    assert!(leaves.len() >= 15, "commands found: {leaves:?}");
    for path in &leaves {
        let mut args: Vec<&str> = path.iter().map(String::as_str).collect();
        args.push("--no-such-flagg");
        let line = usage_error(&args);
        assert!(line.contains("'--no-such-flagg'"), "{args:?}: {line}");
        assert!(line.contains(&format!("kinecal {} --help", path.join(" "))), "{args:?}: {line}");
        // --help still exits 0 with the help on stdout.
        let dir = tempfile::tempdir().unwrap();
        let mut help: Vec<&str> = path.iter().map(String::as_str).collect();
        help.push("--help");
        let out = kinecal(dir.path(), &help);
        assert_eq!(out.status.code(), Some(0), "{help:?}");
        assert!(String::from_utf8(out.stdout).unwrap().contains("Usage:"), "{help:?}");
    }
    for path in &groups {
        let mut args: Vec<&str> = path.iter().map(String::as_str).collect();
        // A group without its command names the commands it has.
        let line = usage_error(&args);
        let first = subcommands(&args)[0].clone();
        assert!(line.contains("needs a command") && line.contains(&first), "{args:?}: {line}");
        // An unknown command names the commands there are.
        args.push("frobnicate");
        let line = usage_error(&args);
        assert!(line.contains("'frobnicate'") && line.contains(&first), "{args:?}: {line}");
    }
}

#[test]
fn usage_errors_name_the_flag_or_value_and_the_fix() {
    // A misspelled flag keeps clap's suggestion.
    let line = usage_error(&["identify", "m.toml", "d.csv", "--out", "c.toml", "--seat-distnace", "0:1:50"]);
    assert!(line.contains("'--seat-distnace'") && line.contains("'--seat-distance'"), "{line}");
    // A bad value names the value and the flag.
    let line = usage_error(&["simulate", "pm5", "--out", "d.csv", "--noise-mm", "1um"]);
    assert!(line.contains("'1um'") && line.contains("--noise-mm"), "{line}");
    let line = usage_error(&["identify", "m.toml", "d.csv", "--out", "c.toml", "--seat-distance", "0,1,50"]);
    assert!(
        line.contains("'0,1,50'") && line.contains("A:B:MM") && line.contains("0:1:50"),
        "{line}"
    );
    let line = usage_error(&["data", "join", "--angles", "radians"]);
    assert!(line.contains("'radians'") && line.contains("--angles"), "{line}");
    // A missing argument names it and shows the usage.
    let line = usage_error(&["identify", "m.toml"]);
    assert!(
        line.contains("<DATA>") && line.contains("--out") && line.contains("usage: kinecal identify"),
        "{line}"
    );
    let line = usage_error(&["identify", "m.toml", "d.csv", "--out"]);
    assert!(line.contains("--out") && line.contains("value is required"), "{line}");
    // A misspelled command keeps the suggestion.
    let line = usage_error(&["identfy"]);
    assert!(line.contains("'identfy'") && line.contains("'identify'"), "{line}");
    // --version exits 0.
    let dir = tempfile::tempdir().unwrap();
    let out = kinecal(dir.path(), &["--version"]);
    assert_eq!(out.status.code(), Some(0));
    assert!(String::from_utf8(out.stdout).unwrap().starts_with("kinecal "));
}
