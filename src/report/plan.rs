//! The report of a measurement plan (`kinecal plan --report`): one self-contained HTML page with
//! the candidates and the chosen configurations in the 3-D view of the calibration report (the
//! chosen numbered in the order the selection added them), the criterion as configurations are
//! added, the chosen configurations' inputs and tool positions, and which parameters the plan
//! identifies and which it cannot.
use super::plot;
use super::view::{self, list, polylines, string, POSITION_DECIMALS, VIEW_BUTTONS, VIEW_POINTS};
use crate::design::select::Action;
use crate::design::SampledPlan;
use std::fmt::Write as _;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// The 3-D view's data of a plan: the candidates' target positions (at most [`VIEW_POINTS`],
/// spread by a fixed hash, the chosen ones left out) in grey, the chosen ones in red with their order of
/// addition, and the mechanism at home.
pub fn plan_view_json(p: &SampledPlan) -> String {
    let cands = &p.candidates.candidates;
    let chosen = &p.plan.selection.selected;
    // Spread by a multiplicative hash, not every k-th: candidates often come from a grid, whose
    // every k-th point is a slice of it.
    let n = cands.len() as u64;
    let mut others: Vec<usize> = if cands.len() <= VIEW_POINTS {
        (0..cands.len()).collect()
    } else {
        (0..VIEW_POINTS as u64)
            .map(|k| ((k * 2_654_435_761 + 12_345) % n) as usize)
            .collect()
    };
    others.sort_unstable();
    others.dedup();
    others.retain(|i| !chosen.contains(i));
    let pos = |i: &usize| {
        let t = cands[*i].target.translation.vector;
        [t.x, t.y, t.z]
    };
    let mut out = String::from("{\"sets\":[");
    let _ = write!(
        out,
        "{{\"name\":\"candidates\",\"n\":{},\"colour\":\"#b8b8b8\",\"size\":2,",
        cands.len()
    );
    list(&mut out, "i", others.iter().map(|&i| i as f64), 0);
    list(&mut out, "p", others.iter().flat_map(pos), POSITION_DECIMALS);
    let labels: Vec<String> = others.iter().map(|i| string(&format!("candidate {i}"))).collect();
    let _ = write!(out, "\"label\":[{}]}},", labels.join(","));
    let _ = write!(
        out,
        "{{\"name\":\"chosen\",\"n\":{},\"colour\":\"#d62728\",\"size\":5,",
        chosen.len()
    );
    list(&mut out, "i", chosen.iter().map(|&i| i as f64), 0);
    list(&mut out, "p", chosen.iter().flat_map(pos), POSITION_DECIMALS);
    let tags: Vec<String> = (1..=chosen.len()).map(|k| format!("\"{k}\"")).collect();
    let labels: Vec<String> = chosen
        .iter()
        .enumerate()
        .map(|(k, i)| string(&format!("chosen #{} (candidate {i})", k + 1)))
        .collect();
    let _ = write!(out, "\"tag\":[{}],\"label\":[{}]}}],", tags.join(","), labels.join(","));
    let skeleton: Vec<Vec<[f64; 3]>> = p.skeleton.iter().map(|l| l.iter().map(|v| [v.x, v.y, v.z]).collect()).collect();
    polylines(&mut out, "skeleton", &skeleton);
    out.push_str("\"nominal\":[],\"moved\":[],\"base\":null,\"tool\":null}");
    out
}

/// The plan as one self-contained HTML page (inline CSS, SVG and script; nothing fetched).
pub fn plan_html(p: &SampledPlan) -> Result<String, String> {
    let sel = &p.plan.selection;
    let mut h = String::new();
    h.push_str("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">");
    let _ = write!(h, "<title>kinecal measurement plan: {}</title>", esc(&p.mechanism));
    h.push_str(
        "<style>body{font-family:sans-serif;margin:24px;max-width:1180px;color:#222}h1{font-size:22px}\
         h2{font-size:18px;border-bottom:1px solid #ccc;padding-bottom:4px;margin-top:28px}\
         table{border-collapse:collapse;font-size:13px;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}\
         th{background:#f0f0f0}td.l,th.l{text-align:left}.plots svg{border:1px solid #ddd}.muted{color:#888}</style></head><body>\n",
    );
    let _ = writeln!(h, "<h1>Measurement plan: {}</h1>", esc(&p.mechanism));
    h.push_str("<h2>Summary</h2>\n<table>");
    let row = |h: &mut String, k: &str, v: String| {
        let _ = write!(h, "<tr><th class=\"l\">{k}</th><td class=\"l\">{v}</td></tr>");
    };
    row(
        &mut h,
        "candidates",
        format!("{} ({})", p.candidates.candidates.len(), esc(&p.candidates.report.to_string())),
    );
    row(&mut h, "space sampled", esc(&p.candidates.space.to_string()));
    row(
        &mut h,
        "chosen",
        format!(
            "{} configurations by {:?} on {} ({} chosen D-optimally before full rank)",
            sel.selected.len(),
            sel.method,
            sel.criterion,
            sel.warm_up
        ),
    );
    row(&mut h, "indices of the chosen set (scaled)", esc(&sel.indices.to_string()));
    row(
        &mut h,
        "identifiable parameters",
        format!("{} of {}", p.plan.columns.len(), p.parameters),
    );
    h.push_str("</table>\n");
    h.push_str("<h2 id=\"view\">3-D view: candidates and chosen configurations</h2>\n");
    let _ = write!(
        h,
        "<p class=\"muted\">The candidates' tool positions (grey; at most {VIEW_POINTS} drawn, spread over the candidates) and the chosen configurations (red, numbered in the order the selection added them), in the model's world frame{}. Drag to turn, shift-drag to move, wheel to zoom, hover for a candidate's number.</p>",
        if p.skeleton.is_empty() { "" } else { ", with the machine at home" }
    );
    let _ = writeln!(
        h,
        "<div id=\"view-controls\" style=\"font-size:13px;margin:4px 0\">{VIEW_BUTTONS}</div>"
    );
    view::canvas(&mut h, &plan_view_json(p));
    h.push_str("<h2>The criterion as configurations are added</h2>\n<p class=\"muted\">The selection's criterion after each move (regularised log det for D and O1; a removal of SFFS or exchange is a move too).</p><div class=\"plots\">");
    let scores: Vec<f64> = sel.history.iter().map(|s| s.score).collect();
    h.push_str(&plot::per_pose_chart_with_x(
        &format!("{} after each move", sel.criterion),
        "move",
        &sel.criterion.to_string(),
        &scores,
    )?);
    h.push_str("</div>\n<h2>Chosen configurations</h2>\n<table id=\"chosen\"><tr><th>#</th><th>candidate</th><th>added at move</th>");
    for (name, angle) in p.input_names.iter().zip(&p.angle_inputs) {
        let _ = write!(h, "<th>{} ({})</th>", esc(name), if *angle { "deg" } else { "mm" });
    }
    h.push_str("<th>x mm</th><th>y mm</th><th>z mm</th></tr>");
    for (k, &i) in sel.selected.iter().enumerate() {
        let c = &p.candidates.candidates[i];
        let added = sel
            .history
            .iter()
            .rposition(|s| s.candidate == i && s.action == Action::Add)
            .map_or(0, |m| m + 1);
        let _ = write!(h, "<tr><td>{}</td><td>{i}</td><td>{added}</td>", k + 1);
        for (q, angle) in c.q.iter().zip(&p.angle_inputs) {
            let _ = write!(h, "<td>{:.3}</td>", if *angle { q.to_degrees() } else { *q });
        }
        let t = c.target.translation.vector;
        let _ = write!(h, "<td>{:.2}</td><td>{:.2}</td><td>{:.2}</td></tr>", t.x, t.y, t.z);
    }
    h.push_str("</table>\n<h2>Parameters</h2>\n");
    let names = |cols: &mut dyn Iterator<Item = usize>| {
        cols.map(|c| esc(p.parameter_names.get(c).map_or("?", |s| s.as_str())))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let _ = write!(
        h,
        "<p><b>Identified</b> by these configurations ({}): {}</p>",
        p.plan.columns.len(),
        names(&mut p.plan.columns.iter().copied())
    );
    let rest = (0..p.parameters).filter(|c| !p.plan.columns.contains(c)).collect::<Vec<_>>();
    let _ = write!(
        h,
        "<p><b>Not identifiable</b> from any pose of this kind ({}; redundant with the identified ones or without effect on the measurements): {}</p>",
        rest.len(),
        if rest.is_empty() { "none".to_string() } else { names(&mut rest.into_iter()) }
    );
    h.push_str("<p class=\"muted\">Generated by kinecal.</p></body></html>\n");
    Ok(h)
}
