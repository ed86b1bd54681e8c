//! docs/assess.md's walk-through runs as written: every `sh` block from "The same through the
//! commands" to the report section, one after the other, in one empty directory with the
//! `kinecal` under test on the PATH.
use std::path::Path;

/// The `sh` blocks of `text` between the headings `from` and `to`.
fn blocks(text: &str, from: &str, to: &str) -> Vec<String> {
    let start = text.find(from).unwrap_or_else(|| panic!("no heading {from}"));
    let end = start + text[start..].find(to).unwrap_or_else(|| panic!("no heading {to}"));
    text[start..end]
        .split("```sh\n")
        .skip(1)
        .map(|b| b.split("```").next().unwrap().to_string())
        .collect()
}

#[test]
fn the_assess_walkthrough_runs_as_written_in_one_empty_directory() {
    let doc = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/assess.md")).unwrap();
    let blocks = blocks(&doc, "## The same through the commands", "## The report");
    assert!(blocks.len() >= 4, "{} blocks", blocks.len());
    let bin = assert_cmd::cargo::cargo_bin("kinecal");
    let path = format!("{}:{}", bin.parent().unwrap().display(), std::env::var("PATH").unwrap_or_default());
    let dir = tempfile::tempdir().unwrap();
    for (k, block) in blocks.iter().enumerate() {
        let out = std::process::Command::new("sh")
            .args(["-e", "-c", block])
            .current_dir(dir.path())
            .env("PATH", &path)
            .output()
            .unwrap();
        let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        assert!(
            out.status.success(),
            "block {}:\n{block}\nstdout:\n{stdout}\nstderr:\n{stderr}",
            k + 1
        );
        // Each block ends with an assessment that prints its figures.
        assert!(stdout.contains("AP_P") || stdout.contains("ISO 230-4"), "block {}: {stdout}", k + 1);
    }
    // The figures the page quotes come out of these runs.
    for (file, needle) in [
        ("after.csv", "pose,cycle"),
        ("irb-iso.csv", "id,x_mm"),
        ("circle-after-cw.csv", "x_mm"),
    ] {
        let text = std::fs::read_to_string(dir.path().join(file)).unwrap();
        assert!(text.starts_with(needle) || text.contains(needle), "{file}");
    }
}
