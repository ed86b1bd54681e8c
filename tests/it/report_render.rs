//! The HTML report rendered by a real browser: headless Chromium when it is installed (skipped
//! with a message otherwise). The rendered page opens with the verdict, has no NaN, no empty
//! section and no console error.
use crate::cli::ok;
use std::path::Path;
use std::process::Command;

fn chromium() -> Option<&'static str> {
    ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|b| Command::new(b).arg("--version").output().is_ok_and(|o| o.status.success()))
}

/// The DOM after rendering, and the browser's log (console messages included).
fn render(browser: &str, page: &Path, profile: &Path) -> (String, String) {
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--enable-logging=stderr",
            "--v=0",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("--dump-dom")
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("run the browser");
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn check(dom: &str, log: &str, expect_verdict: &str) {
    assert!(dom.contains("id=\"verdict\""), "no verdict rendered");
    let verdict_at = dom.find("id=\"verdict\"").unwrap();
    let first_h2 = dom.find("<h2").unwrap_or(usize::MAX);
    assert!(verdict_at < first_h2, "the verdict is not the first section");
    assert!(dom.contains(expect_verdict), "verdict '{expect_verdict}' missing");
    assert!(!dom.contains("NaN") && !dom.contains(">inf<"), "NaN or inf on the page");
    // Every section has content before the next heading.
    for part in dom.split("<h2>").skip(1) {
        let body = part.split_once("</h2>").map_or("", |(_, b)| b);
        let before_next = body.split("<h2>").next().unwrap_or("");
        assert!(before_next.trim().len() >= 8, "empty section: {}", &part[..part.len().min(80)]);
    }
    let console_errors: Vec<&str> = log.lines().filter(|l| l.contains("CONSOLE") && l.contains("rror")).collect();
    assert!(console_errors.is_empty(), "console errors: {console_errors:?}");
}

#[test]
fn report_renders_in_a_browser_with_its_verdict_and_flags() {
    let Some(browser) = chromium() else {
        eprintln!("report_render: no Chromium on this machine (apt-get install chromium); browser check skipped");
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ok(d, &["model", "export", "irb120", "--out", "m.toml"]);
    ok(
        d,
        &[
            "simulate",
            "m.toml",
            "--poses",
            "40",
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
            "--validation-poses",
            "20",
            "--validation-out",
            "v.csv",
        ],
    );
    ok(
        d,
        &[
            "identify",
            "m.toml",
            "d.csv",
            "--validation",
            "v.csv",
            "--out",
            "c.toml",
            "--report",
            "r.html",
        ],
    );
    let (dom, log) = render(browser, &d.join("r.html"), &d.join("profile"));
    check(&dom, &log, "Verdict: Calibrated");
    assert!(
        dom.contains("id=\"params\"") && dom.contains("id=\"redundant\""),
        "parameter or redundancy table missing"
    );
    assert!(dom.contains("absorbed into"), "redundant parameters without what absorbs them");
    assert!(dom.contains("command</th>") && dom.contains("kinecal version"), "no provenance");
    // A failed calibration (a wrong model, written with --force) renders as failed, with reasons.
    let model = std::fs::read_to_string(d.join("m.toml")).unwrap().replacen("270.0", "390.0", 1);
    std::fs::write(d.join("other.toml"), model).unwrap();
    let out = crate::cli::kinecal(
        d,
        &[
            "identify",
            "other.toml",
            "d.csv",
            "--out",
            "f.toml",
            "--report",
            "f.html",
            "--force",
        ],
    );
    assert_eq!(out.status.code(), Some(2));
    let (dom, log) = render(browser, &d.join("f.html"), &d.join("profile"));
    check(&dom, &log, "FAILED");
    assert!(dom.contains("beyond the model"), "the failure reason is not shown");
}

/// `assess --report` renders: the ISO 9283 table, the circular test's table and its polar plot
/// (an SVG with the path), no NaN, no console error.
#[test]
fn assess_report_renders_in_a_browser() {
    let Some(browser) = chromium() else {
        eprintln!("report_render: no Chromium on this machine; browser check skipped");
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("c.csv"), "pose,x_mm,y_mm,z_mm\n1,0,0,0\n").unwrap();
    std::fs::write(d.join("a.csv"), "pose,cycle,x_mm,y_mm,z_mm\n1,1,1,0,0\n1,2,1,2,0\n1,3,1,0,2\n").unwrap();
    std::fs::write(d.join("bb.csv"), "angle_deg,deviation_mm\n0,0.01\n90,-0.01\n180,0.01\n270,-0.01\n").unwrap();
    ok(
        d,
        &[
            "assess",
            "--commanded",
            "c.csv",
            "a.csv",
            "--circle",
            "bb.csv",
            "--radius-mm",
            "100",
            "--report",
            "r.html",
        ],
    );
    let (dom, log) = render(browser, &d.join("r.html"), &d.join("profile"));
    assert!(
        dom.contains("ISO 9283 pose characteristics") && dom.contains("<td>1.3744</td>"),
        "{dom}"
    );
    assert!(
        dom.contains("ISO 230-4 circular test: bb.csv") && dom.contains("<path d=\"M"),
        "{dom}"
    );
    assert!(!dom.contains("NaN") && !dom.contains(">inf<"), "NaN or inf on the page");
    let console_errors: Vec<&str> = log.lines().filter(|l| l.contains("CONSOLE") && l.contains("rror")).collect();
    assert!(console_errors.is_empty(), "console errors: {console_errors:?}");
}
