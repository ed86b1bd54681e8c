//! The report of `kinecal assess --report`: one self-contained HTML page with the ISO 9283 table
//! of each test run (AP, RP per test pose; AD, RD), the before/after comparison when two runs are
//! given, and the ISO 230-4 circular test's figures with its polar error plot.
use crate::assess::{BidirectionalTest, CircularTest, Iso9283};
use std::fmt::Write as _;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// A 1, 2, 5 × 10^k value at least `v` (> 0).
fn nice_above(v: f64) -> f64 {
    let e = 10f64.powf(v.max(1e-12).log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * e)
        .find(|s| *s >= v * (1.0 - 1e-9))
        .unwrap_or(10.0 * e)
}

/// The polar error plot of a circular test, as ballbar software draws it: the radial deviation
/// `|p_i| − R` about the nominal centre, magnified, around the nominal circle (bold ring); dashed
/// rings at ± one scale step (labelled in µm, or mm from a step of 0.1 mm). An inline SVG.
pub fn polar_plot(title: &str, t: &CircularTest) -> String {
    polar_plot_runs(title, &[("", t)])
}

/// Colours of the runs of a polar plot: the clockwise (or only) run, then the anticlockwise one.
const RUN_COLOURS: [&str; 2] = ["#c0392b", "#2471a3"];

/// [`polar_plot`] of one or two runs of the same circle (clockwise, then anticlockwise), on one
/// scale, each in its colour with its label (`""` for a single run: no legend).
pub fn polar_plot_runs(title: &str, runs: &[(&str, &CircularTest)]) -> String {
    let (size, cx, cy, r0, band) = (440.0, 220.0, 240.0, 120.0, 50.0);
    let Some(&(_, t)) = runs.first() else {
        return String::new();
    };
    let peak = runs
        .iter()
        .flat_map(|(_, t)| t.radial.iter().map(|p| p[1].abs()))
        .fold(0.0, f64::max);
    let step = nice_above(peak.max(1e-6));
    let at = |deg: f64, dev: f64| {
        let r = r0 + dev / step * band;
        let (s, c) = deg.to_radians().sin_cos();
        (cx + r * c, cy - r * s)
    };
    let mut svg = format!(
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{h}" viewBox="0 0 {size} {h}" font-family="sans-serif"><rect width="100%" height="100%" fill="white"/><text x="{cx}" y="18" text-anchor="middle" font-size="13" font-weight="bold">{}</text>"##,
        esc(title),
        h = size + 20.0
    );
    for (dev, style) in [(-step, DASHED), (0.0, r##"stroke="#333" stroke-width="1.5""##), (step, DASHED)] {
        let _ = write!(
            svg,
            r##"<circle cx="{cx}" cy="{cy}" r="{:.1}" fill="none" {style}/>"##,
            r0 + dev / step * band
        );
    }
    for deg in [0.0, 90.0, 180.0, 270.0] {
        let (x0, y0) = at(deg, -step * 1.6);
        let (x1, y1) = at(deg, step * 1.2);
        let (tx, ty) = at(deg, step * 1.45);
        let _ = write!(
            svg,
            r##"<line x1="{x0:.1}" y1="{y0:.1}" x2="{x1:.1}" y2="{y1:.1}" stroke="#ccc"/><text x="{tx:.1}" y="{:.1}" text-anchor="middle" font-size="11">{deg}°</text>"##,
            ty + 4.0
        );
    }
    // µm up to a step of 50 µm, mm beyond.
    let label = |dev: f64| {
        if step < 0.1 {
            format!("{:+} µm", (dev * 1000.0 * 1e6).round() / 1e6)
        } else {
            format!("{:+} mm", (dev * 1e6).round() / 1e6)
        }
    };
    for dev in [-step, 0.0, step] {
        let (x, y) = at(45.0, dev);
        let text = if dev == 0.0 {
            format!("R = {} mm", t.nominal_radius_mm)
        } else {
            label(dev)
        };
        let _ = write!(
            svg,
            r##"<text x="{:.1}" y="{y:.1}" font-size="10" fill="#555">{}</text>"##,
            x + 3.0,
            esc(&text)
        );
    }
    for (n, (label, t)) in runs.iter().enumerate() {
        let colour = RUN_COLOURS[n % RUN_COLOURS.len()];
        let mut path = String::new();
        for (k, p) in t.radial.iter().enumerate() {
            let (x, y) = at(p[0], p[1]);
            let _ = write!(path, "{}{x:.2},{y:.2} ", if k == 0 { "M" } else { "L" });
        }
        let _ = write!(svg, r##"<path d="{path}Z" fill="none" stroke="{colour}" stroke-width="1.4"/>"##);
        if !label.is_empty() {
            let y = size - 22.0 + 14.0 * n as f64;
            let _ = write!(
                svg,
                r##"<line x1="12" y1="{:.1}" x2="34" y2="{:.1}" stroke="{colour}" stroke-width="2"/><text x="40" y="{y:.1}" font-size="11">{}</text>"##,
                y - 4.0,
                y - 4.0,
                esc(label)
            );
        }
    }
    svg.push_str("</svg>");
    svg
}

/// A dashed grey ring.
const DASHED: &str = r##"stroke="#999" stroke-dasharray="4 3""##;

const STYLE: &str = "body{font-family:sans-serif;margin:24px;color:#222}table{border-collapse:collapse;margin:8px 0 18px}\
th,td{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}\
.note{color:#555;font-size:90%}";

/// `v` as shown with 4 decimals, without the sign of a value that shows as zero (`-0.0000`).
fn z(v: f64) -> f64 {
    if v.abs() < 5e-5 {
        0.0
    } else {
        v
    }
}

fn f4(v: f64) -> String {
    format!("{:.4}", z(v))
}

fn abc(v: Option<[f64; 3]>) -> String {
    v.map_or("—".into(), |v| format!("{:.4} / {:.4} / {:.4}", z(v[0]), z(v[1]), z(v[2])))
}

/// The ISO 9283 table of one run.
fn run_table(out: &mut String, name: &str, r: &Iso9283) {
    let _ = write!(out, "<h3>{}</h3><table><tr><th>pose</th><th>cycles</th><th>AP<sub>x</sub></th><th>AP<sub>y</sub></th><th>AP<sub>z</sub></th><th>AP<sub>P</sub></th><th>l̄</th><th>S<sub>l</sub></th><th>RP<sub>l</sub></th><th>AP<sub>a</sub> / AP<sub>b</sub> / AP<sub>c</sub> (deg)</th><th>RP<sub>a</sub> / RP<sub>b</sub> / RP<sub>c</sub> (±deg)</th></tr>", esc(name));
    for p in &r.poses {
        let cells = [p.ap_xyz[0], p.ap_xyz[1], p.ap_xyz[2], p.ap_p, p.l_mean, p.s_l, p.rp_l]
            .map(f4)
            .join("</td><td>");
        let _ = write!(
            out,
            "<tr><td>P{}</td><td>{}</td><td>{cells}</td><td>{}</td><td>{}</td></tr>",
            p.pose,
            p.cycles,
            abc(p.ap_abc),
            abc(p.rp_abc)
        );
    }
    out.push_str("</table>");
    if !r.distances.is_empty() {
        out.push_str("<table><tr><th>distance</th><th>cycles</th><th>D<sub>c</sub></th><th>AD<sub>P</sub></th><th>AD<sub>x</sub></th><th>AD<sub>y</sub></th><th>AD<sub>z</sub></th><th>RD<sub>P</sub> (±)</th><th>AD<sub>a</sub> / AD<sub>b</sub> / AD<sub>c</sub> (deg)</th><th>RD<sub>a</sub> / RD<sub>b</sub> / RD<sub>c</sub> (±deg)</th></tr>");
        for d in &r.distances {
            let cells = [d.commanded_mm, d.ad_p, d.ad_xyz[0], d.ad_xyz[1], d.ad_xyz[2], d.rd_p]
                .map(f4)
                .join("</td><td>");
            let _ = write!(
                out,
                "<tr><td>P{}–P{}</td><td>{}</td><td>{cells}</td><td>{}</td><td>{}</td></tr>",
                d.from,
                d.to,
                d.cycles,
                abc(d.ad_abc),
                abc(d.rd_abc)
            );
        }
        out.push_str("</table>");
    }
}

/// The page: `title`, the ISO 9283 runs (file name and figures; with two, the first is taken as
/// before calibration and the second as after), and the circular test (file name and figures;
/// with `both`, that file is the clockwise run and `both` names the anticlockwise one and holds
/// the figures of the two directions: G each way, G(b), H, both paths on one polar plot).
pub fn assess_html(
    title: &str,
    runs: &[(String, Iso9283)],
    circle: Option<(&str, &CircularTest)>,
    both: Option<(&str, &BidirectionalTest)>,
) -> String {
    let mut out = format!(
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>{0}</title><style>{STYLE}</style></head><body><h1>{0}</h1>",
        esc(title)
    );
    if !runs.is_empty() {
        out.push_str("<h2>ISO 9283 pose characteristics</h2><p class=\"note\">mm and degrees. AP: the barycentre of the attained poses against the commanded pose; RP<sub>l</sub> = l̄ + 3·S<sub>l</sub>; RP<sub>a,b,c</sub> = ±3·S; AD, RD: distance accuracy and repeatability, of position and orientation (ISO 9283 §7.2, §7.3). Orientation figures are the components about the base x, y, z of the rotation vectors of the orientation errors (docs/assess.md).</p>");
    }
    if let [(b, before), (a, after)] = runs {
        let _ = write!(out, "<h3>Before → after</h3><table><tr><th>pose</th><th>AP<sub>P</sub> {}</th><th>AP<sub>P</sub> {}</th><th>RP<sub>l</sub> {0}</th><th>RP<sub>l</sub> {1}</th></tr>", esc(b), esc(a));
        for (p, q) in before.poses.iter().zip(&after.poses) {
            let _ = write!(
                out,
                "<tr><td>P{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                p.pose,
                f4(p.ap_p),
                f4(q.ap_p),
                f4(p.rp_l),
                f4(q.rp_l)
            );
        }
        out.push_str("</table>");
    }
    for (name, r) in runs {
        run_table(&mut out, name, r);
    }
    if let Some((name, t)) = circle {
        let row = |label: &str, t: &CircularTest| {
            format!(
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.4}</td><td>({:.4}, {:.4})</td><td>{:.4}</td><td>{:+.4}</td><td>{:+.4}</td></tr>",
                esc(label),
                t.points,
                t.nominal_radius_mm,
                t.lsq_radius_mm,
                z(t.centre_offset_mm[0]),
                z(t.centre_offset_mm[1]),
                t.circular_deviation_g_mm,
                t.radial_deviation_f_max_mm,
                t.radial_deviation_f_min_mm
            )
        };
        let heading = match both {
            Some((ccw, _)) => format!("{} (clockwise), {} (anticlockwise)", esc(name), esc(ccw)),
            None => esc(name),
        };
        let _ = write!(out, "<h2>ISO 230-4 circular test: {heading}</h2><p class=\"note\">G: max − min radius about the least-squares centre; F: radius less the nominal radius about the nominal centre (the ballbar's pivot); G(b): max − min radius of both directions about their common centre; H: the largest radial difference between the two directions at the same angle; mm.</p><table><tr><th>run</th><th>points</th><th>R nominal</th><th>LSQ radius</th><th>centre offset</th><th>G</th><th>F<sub>max</sub></th><th>F<sub>min</sub></th></tr>");
        match both {
            Some((ccw, b)) => {
                out.push_str(&row(&format!("clockwise: {name}"), &b.clockwise));
                out.push_str(&row(&format!("anticlockwise: {ccw}"), &b.anticlockwise));
                let _ = write!(
                    out,
                    "</table><table><tr><th>both directions</th><th>G<sub>cw</sub></th><th>G<sub>ccw</sub></th><th>G(b)</th><th>H (hysteresis)</th><th>common centre offset</th></tr><tr><td>{} / {}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td><td>({:.4}, {:.4})</td></tr></table>",
                    esc(name),
                    esc(ccw),
                    b.clockwise.circular_deviation_g_mm,
                    b.anticlockwise.circular_deviation_g_mm,
                    b.circular_deviation_g_both_mm,
                    b.circular_hysteresis_h_mm,
                    z(b.centre_offset_mm[0]),
                    z(b.centre_offset_mm[1])
                );
                out.push_str(&polar_plot_runs(
                    "radial deviation (magnified)",
                    &[("clockwise", &b.clockwise), ("anticlockwise", &b.anticlockwise)],
                ));
            }
            None => {
                out.push_str(&row(name, t));
                out.push_str("</table>");
                out.push_str(&polar_plot("radial deviation (magnified)", t));
            }
        }
    }
    out.push_str("</body></html>\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_polar_plot_scales_to_a_nice_step_and_closes_its_path() {
        let t = crate::assess::iso230_4(&[[100.01, 0.0], [0.0, 99.99], [-100.01, 0.0], [0.0, -99.99]], 100.0).unwrap();
        let svg = polar_plot("p", &t);
        assert_eq!(nice_above(0.01), 0.01);
        assert_eq!(nice_above(0.013), 0.02);
        assert!(
            svg.contains("+10 µm") && svg.contains("-10 µm") && svg.contains("R = 100 mm"),
            "{svg}"
        );
        // The path: 4 points, the first at 0° one step (50 px) outside the nominal ring (120 px).
        assert!(svg.contains("M390.00,240.00 L") && svg.contains(" Z\""), "{svg}");
        let html = assess_html("t", &[], Some(("c.csv", &t)), None);
        assert!(html.contains("<td>0.0200</td>") && html.contains("<svg"), "{html}");
        // Both directions: a row per run, G(b) and H, two paths on one plot with a legend.
        let cw = [[100.01, 0.0], [0.0, 100.01], [-100.01, 0.0], [0.0, -100.01]];
        let ccw = [[99.99, 0.0], [0.0, 99.99], [-99.99, 0.0], [0.0, -99.99]];
        let b = crate::assess::iso230_4_both(&cw, &ccw, 100.0).unwrap();
        let html = assess_html("t", &[], Some(("cw.csv", &b.clockwise)), Some(("ccw.csv", &b)));
        assert!(
            html.contains("clockwise: cw.csv") && html.contains("anticlockwise: ccw.csv") && html.contains("<th>H (hysteresis)</th>"),
            "{html}"
        );
        assert!(html.contains("<td>0.0200</td><td>0.0200</td><td>(")); // G(b), H
        assert_eq!(html.matches("<path d=").count(), 2);
        assert!(html.contains(">anticlockwise</text>"));
    }
}
