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

/// The 3-D view's data embedded in the page (`<script id="view-data">`).
fn view_data(html: &str) -> serde_json::Value {
    let start = html.find("id=\"view-data\">").expect("no view data in the page") + "id=\"view-data\">".len();
    let end = start + html[start..].find("</script>").unwrap();
    serde_json::from_str(&html[start..end]).expect("the view data is JSON")
}

/// The report's 3-D view carries the report's own figures: per set the JSON's pose count, and
/// for each drawn pose the JSON's errors before and after and its measured position; the
/// machine's skeleton at home (a serial chain: base, six joints, tool) and the base frame. In
/// Chromium (when installed) the script draws every embedded pose (`data-drawn`) with no
/// console error.
#[test]
fn the_3d_view_draws_the_reports_own_data() {
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
            "5",
            "--out",
            "d.csv",
            "--truth",
            "t.toml",
            "--validation-poses",
            "25",
            "--validation-out",
            "v.csv",
        ],
    );
    let json = crate::cli::json(
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
    let html = std::fs::read_to_string(d.join("r.html")).unwrap();
    let view = view_data(&html);
    let sets = view["sets"].as_array().unwrap();
    assert_eq!(sets.len(), 2);
    let mut embedded = 0;
    for (set, key) in sets.iter().zip(["identification", "validation"]) {
        let report = &json[key];
        let after = report["after"]["position"].as_array().unwrap();
        let before = report["before"]["position"].as_array().unwrap();
        assert_eq!(set["name"], key);
        assert_eq!(set["n"].as_u64().unwrap() as usize, after.len(), "{key}: pose count");
        let rows = set["i"].as_array().unwrap();
        assert_eq!(rows.len(), after.len(), "{key}: every pose drawn below the thinning limit");
        for (j, i) in rows.iter().enumerate() {
            let i = i.as_u64().unwrap() as usize;
            let close = |a: &serde_json::Value, b: &serde_json::Value, tol: f64| (a.as_f64().unwrap() - b.as_f64().unwrap()).abs() <= tol;
            assert!(
                close(&set["a"][j], &after[i], 6e-6),
                "{key} pose {i}: error after {} vs {}",
                set["a"][j],
                after[i]
            );
            assert!(close(&set["b"][j], &before[i], 6e-6), "{key} pose {i}: error before");
            assert_eq!(set["id"][j], report["ids"][i], "{key} pose {i}: id");
            for c in 0..3 {
                assert!(
                    close(&set["p"][3 * j + c], &report["measured"][i][c], 6e-3),
                    "{key} pose {i}: position"
                );
            }
            // The error vector's length is the position error (pose measurements).
            let ea: f64 = (0..3).map(|c| set["ea"][3 * j + c].as_f64().unwrap().powi(2)).sum::<f64>().sqrt();
            assert!(
                (ea - after[i].as_f64().unwrap()).abs() < 2e-5,
                "{key} pose {i}: |error vector| {ea}"
            );
        }
        embedded += rows.len();
    }
    let skeleton = view["skeleton"].as_array().unwrap();
    assert_eq!(skeleton.len(), 1, "one polyline for a serial chain");
    assert_eq!(skeleton[0].as_array().unwrap().len(), 3 * 8, "base, six joints and the tool");
    assert_eq!(view["base"].as_array().map(Vec::len), Some(12), "the registered base frame");
    // The tool frame at the first identification pose: its origin is where the calibrated model
    // puts that pose, the measured position less its error vector.
    let (tool, first) = (&view["tool"], &json["identification"]);
    for c in 0..3 {
        let model = first["measured"][0][c].as_f64().unwrap() - first["error_after"][0][c].as_f64().unwrap();
        assert!(
            (tool[c].as_f64().unwrap() - model).abs() < 1e-5,
            "tool frame origin {c}: {} vs {model}",
            tool[c]
        );
    }
    assert_eq!(view["toolPose"], first["ids"][0]);
    assert!(
        html.contains("id=\"maps\"") && html.matches("position error after calibration</text>").count() >= 2,
        "no workspace maps"
    );
    let Some(browser) = chromium() else {
        eprintln!("the_3d_view_draws_the_reports_own_data: no Chromium on this machine; the browser check skipped");
        return;
    };
    let (dom, log) = render(browser, &d.join("r.html"), &d.join("profile"));
    check(&dom, &log, "Verdict:");
    let drawn: usize = dom
        .split("data-drawn=\"")
        .nth(1)
        .and_then(|s| s.split('"').next())
        .and_then(|s| s.parse().ok())
        .expect("the view's canvas has no data-drawn");
    assert_eq!(drawn, embedded, "the script drew {drawn} of {embedded} poses");
}

/// 100,000 identification poses (and 20,000 held out): the report stays under 2 MB, its 3-D view
/// states each set's pose count and draws at most `VIEW_POINTS` of them per set.
#[test]
fn a_100000_pose_report_stays_under_2_mb() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    ok(d, &["model", "export", "irb120", "--out", "m.toml"]);
    #[rustfmt::skip]
    ok(d, &["simulate", "m.toml", "--poses", "100000", "--seed", "7", "--noise-mm", "0.02", "--noise-deg", "0.02", "--out", "d.csv", "--truth", "t.toml", "--validation-poses", "20000", "--validation-out", "v.csv"]);
    #[rustfmt::skip]
    ok(d, &["identify", "m.toml", "d.csv", "--validation", "v.csv", "--noise-mm", "0.02", "--noise-deg", "0.02", "--out", "c.toml", "--report", "r.html"]);
    let html = std::fs::read_to_string(d.join("r.html")).unwrap();
    assert!(html.len() <= 2_000_000, "report of {} bytes", html.len());
    let view = view_data(&html);
    let limit = kinecal::report::VIEW_POINTS;
    for (set, n) in view["sets"].as_array().unwrap().iter().zip([100_000, 20_000]) {
        assert_eq!(set["n"], n);
        let drawn = set["i"].as_array().unwrap().len();
        assert!(drawn <= limit && drawn >= limit / 2, "{drawn} poses drawn of {n}");
        let a: Vec<f64> = set["a"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        assert!(a.iter().all(|v| v.is_finite() && *v >= 0.0));
    }
    eprintln!("100,000-pose report: {} bytes", html.len());
}

/// `kinecal plan --report`: the page shows the candidates and the chosen configurations in the
/// 3-D view (the chosen ones in the order of the plan's CSV, numbered), the criterion per move,
/// the chosen configurations' table and the parameters identified and not; in Chromium the
/// script draws every embedded point with no console error.
#[test]
fn a_plan_report_shows_candidates_and_chosen_configurations() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    #[rustfmt::skip]
    let summary = crate::cli::json(d, &["plan", "--candidates", "1500", "-n", "8", "--method", "sffs", "-o", "plan.csv", "--report", "plan.html"]);
    let html = std::fs::read_to_string(d.join("plan.html")).unwrap();
    let view = view_data(&html);
    let sets = view["sets"].as_array().unwrap();
    assert_eq!(sets[0]["name"], "candidates");
    assert_eq!(sets[0]["n"], 1500);
    assert_eq!(sets[1]["name"], "chosen");
    let chosen: Vec<u64> = sets[1]["i"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap()).collect();
    assert_eq!(chosen.len(), 8);
    assert_eq!(sets[1]["tag"][7], "8");
    assert_eq!(sets[0]["i"].as_array().unwrap().len(), 1500 - 8, "every candidate but the chosen");
    // The same configurations as the CSV, in its order: their targets.
    let text = std::fs::read_to_string(d.join("plan.csv")).unwrap();
    let table = kinecal::io::table::parse_table(&d.join("plan.csv"), &text).unwrap();
    let x = table.values("x_mm").unwrap();
    for (k, xk) in x.iter().enumerate() {
        assert!((sets[1]["p"][3 * k].as_f64().unwrap() - xk).abs() < 0.006, "chosen #{k}: x");
    }
    let identifiable = summary["identifiable_parameters"].as_u64().unwrap();
    assert!(html.contains(&format!("<b>Identified</b> by these configurations ({identifiable})")));
    assert!(html.contains("<b>Not identifiable</b>") && html.contains("after each move</text>"));
    assert_eq!(html.matches("<tr><td>").count(), 8, "one row per chosen configuration");
    assert_eq!(view["skeleton"].as_array().unwrap().len(), 1, "the random chain drawn at home");
    let Some(browser) = chromium() else {
        eprintln!("a_plan_report_shows_candidates_and_chosen_configurations: no Chromium; the browser check skipped");
        return;
    };
    let (dom, log) = render(browser, &d.join("plan.html"), &d.join("profile"));
    let console_errors: Vec<&str> = log.lines().filter(|l| l.contains("CONSOLE") && l.contains("rror")).collect();
    assert!(console_errors.is_empty(), "console errors: {console_errors:?}");
    assert!(dom.contains("data-drawn=\"1500\""), "the script did not draw the 1500 points");
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

/// The report of an instrument calibration (the built-in IRB 120, four seats with a ball off the
/// flange axis, 10 µm noise, three known distances between seats): the known distances are no
/// poses (the JSON's and the page's pose counts are the file's rows, no id is negative, they
/// have their own table), the summary states the seats' σ, and the 3-D view holds the machine
/// and the four seats at distinct places near where they stood (the base frame as drawn: the
/// prototype's ±0.5 mm / ±0.1° errors apart), each row's calibrated tool point in its seat. In
/// Chromium (when installed) the view draws every row with no console error.
#[test]
fn an_instrument_report_draws_the_seats_where_they_are_and_counts_no_known_distance() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let seats = [
        [400.0, 0.0, 300.0],
        [450.0, 100.0, 250.0],
        [350.0, -100.0, 350.0],
        [420.0, 50.0, 400.0],
    ];
    let at: Vec<String> = seats.iter().map(|s| format!("{},{},{}", s[0], s[1], s[2])).collect();
    #[rustfmt::skip]
    let sim = crate::cli::json(d, &["simulate", "irb120", "--seats", &at.join(";"), "--reference", "0,20,11.5,0,57,0", "--tool-mm", "15,-10,120", "--per-seat", "15", "--tilt-deg", "35", "--noise-mm", "0.01", "--out", "d.csv", "--truth", "t.toml"]);
    let mut identify = vec![
        "identify",
        "irb120",
        "d.csv",
        "--out",
        "cal.toml",
        "--noise-mm",
        "0.01",
        "--report",
        "r.html",
    ];
    let distances: Vec<String> = sim["seat_distances"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    assert_eq!(distances.len(), 3);
    for k in &distances {
        identify.extend(["--seat-distance", k.as_str()]);
    }
    let text = ok(d, &identify);
    assert!(
        text.contains("from 60 poses") && text.contains("seat rows (60): residual"),
        "{text}"
    );
    assert!(text.contains("3 known distances between seats"), "{text}");
    identify.extend(["--json", "--force"]);
    let json: serde_json::Value = serde_json::from_str(&ok(d, &identify)).unwrap();
    let set = &json["identification"];
    let ids: Vec<i64> = set["ids"].as_array().unwrap().iter().map(|v| v.as_i64().unwrap()).collect();
    assert_eq!(ids, (0..60).collect::<Vec<i64>>(), "the file's rows, and only those, are poses");
    assert_eq!(set["before_stats"]["poses"], 60);
    assert_eq!(set["after"]["position"].as_array().unwrap().len(), 60);
    assert!(json["blunders"].as_array().unwrap().iter().all(|v| v.as_i64().unwrap() >= 0));
    let known = json["known_distances"].as_array().unwrap();
    assert_eq!(known.len(), 3);
    for k in known {
        assert!(k["error_mm"].as_f64().unwrap().abs() < 0.01 && k["set_aside"] == false, "{k}");
    }
    assert!(json["kinds"][0]["kind"] == "seat" && json["kinds"][0]["rows"] == 60);
    let html = std::fs::read_to_string(d.join("r.html")).unwrap();
    assert!(html.contains("<th class=\"l\">poses (identification)</th><td class=\"l\">60</td>"));
    assert!(html.contains("id=\"known-distances\"") && html.contains("seat spread (per axis) (60 rows)"));
    assert!(!html.contains(" of 63 poses") && !html.contains("63 poses"));
    let view = view_data(&html);
    let set = &view["sets"][0];
    assert_eq!(set["n"], 60);
    assert!(
        set["id"].as_array().unwrap().iter().all(|v| v.as_i64().unwrap() >= 0),
        "a negative id in the view"
    );
    assert_eq!(view["world"], "base frame");
    assert_eq!(
        view["skeleton"][0].as_array().unwrap().len(),
        3 * 8,
        "the IRB 120 drawn: base, six joints, tool"
    );
    let artifacts = view["artifacts"].as_array().unwrap();
    assert_eq!(artifacts.len(), 4);
    let at = |v: &serde_json::Value, k: usize| -> [f64; 3] { [0, 1, 2].map(|c| v[3 * k + c].as_f64().unwrap()) };
    let dist = |a: [f64; 3], b: [f64; 3]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    let fitted: Vec<[f64; 3]> = artifacts.iter().map(|a| at(&a["f"], 0)).collect();
    for (k, a) in artifacts.iter().enumerate() {
        assert_eq!(a["name"], format!("seat {k}"));
        let off = dist(fitted[k], seats[k]);
        assert!(off < 5.0, "seat {k} drawn at {:?}, {off:.3} mm from where it stood", fitted[k]);
        for j in 0..k {
            assert!(dist(fitted[k], fitted[j]) > 50.0, "seats {j} and {k} drawn together");
        }
    }
    // Each row's calibrated tool point in its seat (at the noise), the starting model's beside it.
    let (k, pb) = (set["k"].as_array().unwrap(), &set["pb"]);
    assert_eq!(k.len(), 60);
    for (j, seat) in k.iter().enumerate() {
        let seat = seat.as_u64().unwrap() as usize;
        assert!(dist(at(&set["p"], j), fitted[seat]) < 0.1, "row {j}: tool point off its seat");
        assert!(dist(at(pb, j), fitted[seat]) < 30.0, "row {j}: nominal tool point");
    }
    let Some(browser) = chromium() else {
        eprintln!("an_instrument_report_…: no Chromium on this machine; the browser check skipped");
        return;
    };
    let (dom, log) = render(browser, &d.join("r.html"), &d.join("profile"));
    check(&dom, &log, "Verdict:");
    assert!(dom.contains("data-drawn=\"60\""), "the view did not draw the 60 rows");
}

/// A ballbar report (the IRB 120, three pivots, a fixed 100 mm bar, noise-free): every row's
/// calibrated tool point is drawn one bar length from its pivot's drawn centre, and the error
/// vectors lie along the bar.
#[test]
fn a_ballbar_report_draws_each_bar_from_its_pivot() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    #[rustfmt::skip]
    ok(d, &["simulate", "irb120", "--pivots", "400,0,200;450,100,150;350,-100,250", "--ballbar-mm", "100", "--ballbar-range-mm", "0", "--reference", "0,20,11.5,0,57,0", "--tool-mm", "15,-10,120", "--per-point", "40", "--tilt-deg", "35", "--noise-mm", "0", "--out", "d.csv", "--truth", "t.toml"]);
    ok(
        d,
        &[
            "identify",
            "irb120",
            "d.csv",
            "--out",
            "cal.toml",
            "--noise-mm",
            "0.001",
            "--report",
            "r.html",
        ],
    );
    let view = view_data(&std::fs::read_to_string(d.join("r.html")).unwrap());
    let artifacts = view["artifacts"].as_array().unwrap();
    assert_eq!(artifacts.len(), 3);
    assert!(artifacts.iter().all(|a| a["kind"] == "pivot"));
    let set = &view["sets"][0];
    let n = set["i"].as_array().unwrap().len();
    assert_eq!(n, 120);
    for j in 0..n {
        let a = &artifacts[set["k"][j].as_u64().unwrap() as usize]["f"];
        let bar: Vec<f64> = (0..3)
            .map(|c| set["p"][3 * j + c].as_f64().unwrap() - a[c].as_f64().unwrap())
            .collect();
        let length = bar.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!((length - 100.0).abs() < 0.02, "row {j}: drawn bar {length:.4} mm");
        let e: Vec<f64> = (0..3).map(|c| set["ea"][3 * j + c].as_f64().unwrap()).collect();
        let cross = (bar[1] * e[2] - bar[2] * e[1])
            .hypot(bar[2] * e[0] - bar[0] * e[2])
            .hypot(bar[0] * e[1] - bar[1] * e[0]);
        assert!(
            cross <= 1e-3 * length * e.iter().map(|v| v.abs()).sum::<f64>() + 1e-9,
            "row {j}: error vector off the bar"
        );
    }
}
