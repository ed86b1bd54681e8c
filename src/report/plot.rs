//! Inline SVG plots for the HTML report.
//!
//! Geometry (axes, grid, lines, markers, bars) is drawn with plotters' SVG backend. Built without
//! font support (hermetic, no font files), plotters cannot measure text and leaves tick labels
//! out, so every text element (title, tick labels, axis names, legend) is written here as a plain
//! SVG `<text>` placed with the chart's own coordinate mapping; the browser renders it with its
//! default sans-serif font.
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::fmt::Write as _;

/// One data series: legend name, colour (`#rrggbb`), values.
pub struct Series<'a> {
    /// Legend text.
    pub name: &'a str,
    /// Colour as `(r, g, b)`.
    pub color: (u8, u8, u8),
    /// Values (y for line charts, samples for histograms).
    pub values: &'a [f64],
}

const W: u32 = 560;
const H: u32 = 260;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// About `n` "nice" tick values (1, 2, 5 × 10^k steps) covering `[lo, hi]`.
pub fn nice_ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    if hi <= lo || !lo.is_finite() || !hi.is_finite() {
        return vec![lo];
    }
    let raw = (hi - lo) / n.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let start = (lo / step).ceil() as i64;
    let end = (hi / step).floor() as i64;
    (start..=end).map(|k| k as f64 * step).collect()
}

fn fmt_tick(v: f64, step: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = step.abs();
    if !(1e-4..1e5).contains(&a) {
        return format!("{v:.1e}");
    }
    let decimals = (-a.log10().floor()).max(0.0) as usize;
    format!("{v:.decimals$}")
}

struct Frame {
    texts: String,
}

impl Frame {
    fn text(&mut self, x: i32, y: i32, anchor: &str, size: u32, s: &str, extra: &str) {
        let _ = write!(
            self.texts,
            r##"<text x="{x}" y="{y}" text-anchor="{anchor}" font-family="sans-serif" font-size="{size}" fill="#222"{extra}>{}</text>"##,
            esc(s)
        );
    }
}

/// The chart with its text, and without the attributes plotters writes on every marker that
/// only restate SVG's defaults (`opacity="1"`; `stroke="none"` with its width): a large data set
/// draws a thousand markers per series, and these made a third of the report.
fn finish(svg: String, frame: Frame) -> String {
    let mut svg = svg
        .replace(" opacity=\"1\"", "")
        .replace(" stroke=\"none\" stroke-width=\"1\"/>", "/>");
    if let Some(pos) = svg.rfind("</svg>") {
        svg.insert_str(pos, &frame.texts);
    }
    svg
}

type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Draw grid, tick labels, axis names, title and legend around a chart.
fn decorate(
    chart: &mut Chart<'_, '_>,
    frame: &mut Frame,
    (x0, x1, y0, y1): (f64, f64, f64, f64),
    title: &str,
    x_label: &str,
    y_label: &str,
    legend: &[(&str, (u8, u8, u8))],
) -> Result<(), String> {
    let grid = RGBColor(220, 220, 220);
    let xt = nice_ticks(x0, x1, 8);
    let yt = nice_ticks(y0, y1, 5);
    let xstep = if xt.len() > 1 { xt[1] - xt[0] } else { 1.0 };
    let ystep = if yt.len() > 1 { yt[1] - yt[0] } else { 1.0 };
    for &y in &yt {
        chart
            .draw_series(LineSeries::new([(x0, y), (x1, y)], grid))
            .map_err(|e| e.to_string())?;
        let (px, py) = chart.backend_coord(&(x0, y));
        frame.text(px - 6, py + 4, "end", 11, &fmt_tick(y, ystep), "");
    }
    for &x in &xt {
        let (px, py) = chart.backend_coord(&(x, y0));
        frame.text(px, py + 16, "middle", 11, &fmt_tick(x, xstep), "");
    }
    // Axes.
    chart
        .draw_series(LineSeries::new([(x0, y1), (x0, y0), (x1, y0)], BLACK))
        .map_err(|e| e.to_string())?;
    let (lx, by) = chart.backend_coord(&(x0, y0));
    let (rx, ty) = chart.backend_coord(&(x1, y1));
    frame.text((lx + rx) / 2, by + 32, "middle", 12, x_label, "");
    let cy = (by + ty) / 2;
    frame.text(14, cy, "middle", 12, y_label, &format!(r#" transform="rotate(-90 14 {cy})""#));
    frame.text(W as i32 / 2, 17, "middle", 13, title, r#" font-weight="bold""#);
    let mut lxp = rx;
    for (name, (r, g, b)) in legend.iter().rev() {
        let w = 14 + 7 * name.chars().count() as i32;
        lxp -= w + 10;
        let _ = write!(
            frame.texts,
            r##"<rect x="{lxp}" y="{}" width="10" height="10" fill="#{r:02x}{g:02x}{b:02x}"/>"##,
            ty - 14
        );
        frame.text(lxp + 14, ty - 5, "start", 11, name, "");
    }
    Ok(())
}

fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    (lo, hi)
}

/// A line-and-marker chart of per-pose values (x = pose index), one line per series; the y axis
/// starts at 0.
pub fn per_pose_chart(title: &str, y_label: &str, series: &[Series<'_>]) -> Result<String, String> {
    line_chart(title, "pose", y_label, series, true)
}

/// A line-and-marker chart of one sequence against its index, y axis fitted to the data.
pub fn per_pose_chart_with_x(title: &str, x_label: &str, y_label: &str, values: &[f64]) -> Result<String, String> {
    let s = Series {
        name: "",
        color: (60, 60, 60),
        values,
    };
    line_chart(title, x_label, y_label, &[s], false)
}

/// A line-and-marker chart of sequences against their index (x = 0, 1, …).
pub fn line_chart(title: &str, x_label: &str, y_label: &str, series: &[Series<'_>], from_zero: bool) -> Result<String, String> {
    let n = series.iter().map(|s| s.values.len()).max().unwrap_or(0);
    let (lo, hi) = range(series.iter().flat_map(|s| s.values.iter().copied()));
    let (y0, y1) = if from_zero {
        (0.0, if hi > 0.0 { hi * 1.1 } else { 1.0 })
    } else {
        let pad = ((hi - lo) * 0.08).max(1e-9);
        (lo - pad, hi + pad)
    };
    let (x0, x1) = (0.0, (n.max(2) - 1) as f64);
    let mut svg = String::new();
    let mut frame = Frame { texts: String::new() };
    {
        let root = SVGBackend::with_string(&mut svg, (W, H)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .margin_top(44)
            .margin_right(14)
            .x_label_area_size(38)
            .y_label_area_size(64)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        let legend: Vec<_> = series.iter().filter(|s| !s.name.is_empty()).map(|s| (s.name, s.color)).collect();
        decorate(&mut chart, &mut frame, (x0, x1, y0, y1), title, x_label, y_label, &legend)?;
        for s in series {
            let c = RGBColor(s.color.0, s.color.1, s.color.2);
            let pts: Vec<(f64, f64)> = s.values.iter().enumerate().map(|(i, v)| (i as f64, *v)).collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), c.stroke_width(1)))
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(PointSeries::of_element(pts, 2, c, &|p, s, st| Circle::new(p, s, st.filled())))
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(finish(svg, frame))
}

/// A histogram of each series' values over common bins (bars side by side within a bin).
pub fn histogram(title: &str, x_label: &str, series: &[Series<'_>], bins: usize) -> Result<String, String> {
    let (mut lo, mut hi) = range(series.iter().flat_map(|s| s.values.iter().copied()));
    lo = lo.min(0.0);
    if hi <= lo {
        hi = lo + 1.0;
    }
    let bins = bins.max(1);
    let width = (hi - lo) / bins as f64;
    let counts: Vec<Vec<usize>> = series
        .iter()
        .map(|s| {
            let mut c = vec![0usize; bins];
            for v in s.values.iter().filter(|v| v.is_finite()) {
                let k = (((v - lo) / width) as usize).min(bins - 1);
                c[k] += 1;
            }
            c
        })
        .collect();
    let ymax = counts.iter().flatten().copied().max().unwrap_or(1).max(1) as f64 * 1.15;
    let mut svg = String::new();
    let mut frame = Frame { texts: String::new() };
    {
        let root = SVGBackend::with_string(&mut svg, (W, H)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .margin_top(44)
            .margin_right(14)
            .x_label_area_size(38)
            .y_label_area_size(64)
            .build_cartesian_2d(lo..hi, 0.0..ymax)
            .map_err(|e| e.to_string())?;
        let legend: Vec<_> = series.iter().map(|s| (s.name, s.color)).collect();
        decorate(&mut chart, &mut frame, (lo, hi, 0.0, ymax), title, x_label, "poses", &legend)?;
        let m = series.len().max(1) as f64;
        for (si, s) in series.iter().enumerate() {
            let c = RGBColor(s.color.0, s.color.1, s.color.2);
            let bars = counts[si].iter().enumerate().filter(|(_, n)| **n > 0).map(|(k, n)| {
                let a = lo + width * k as f64 + width * (0.05 + 0.9 * si as f64 / m);
                let b = a + width * 0.9 / m;
                Rectangle::new([(a, 0.0), (b, *n as f64)], c.filled())
            });
            chart.draw_series(bars).map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(finish(svg, frame))
}

/// At most this many points are drawn per scatter or sorted series; larger sets are thinned
/// evenly (every k-th point, the worst ones always kept) so that the report stays small.
pub const MAX_POINTS: usize = 1000;

/// Indices `0..n` thinned to about [`MAX_POINTS`], keeping `always`.
fn thin(n: usize, always: &[usize]) -> Vec<usize> {
    if n <= MAX_POINTS {
        return (0..n).collect();
    }
    let step = n.div_ceil(MAX_POINTS);
    let mut keep: Vec<usize> = (0..n).step_by(step).chain(always.iter().copied()).collect();
    keep.sort_unstable();
    keep.dedup();
    keep
}

/// Per-pose values sorted in increasing order (x = rank), one curve per series: readable at any
/// number of poses, unlike values joined in file order. The `label_worst` largest values of the
/// last series are labelled with their pose ids.
pub fn sorted_chart(title: &str, y_label: &str, series: &[Series<'_>], ids: &[i64], label_worst: usize) -> Result<String, String> {
    let n = series.iter().map(|s| s.values.len()).max().unwrap_or(0);
    let (_, hi) = range(series.iter().flat_map(|s| s.values.iter().copied()));
    let (y0, y1) = (0.0, if hi > 0.0 { hi * 1.12 } else { 1.0 });
    let (x0, x1) = (0.0, (n.max(2) - 1) as f64);
    let mut svg = String::new();
    let mut frame = Frame { texts: String::new() };
    {
        let root = SVGBackend::with_string(&mut svg, (W, H)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .margin_top(44)
            .margin_right(14)
            .x_label_area_size(38)
            .y_label_area_size(64)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        let legend: Vec<_> = series.iter().filter(|s| !s.name.is_empty()).map(|s| (s.name, s.color)).collect();
        decorate(
            &mut chart,
            &mut frame,
            (x0, x1, y0, y1),
            title,
            "poses, sorted by error",
            y_label,
            &legend,
        )?;
        for (k, s) in series.iter().enumerate() {
            let c = RGBColor(s.color.0, s.color.1, s.color.2);
            let mut order: Vec<usize> = (0..s.values.len()).filter(|&i| s.values[i].is_finite()).collect();
            order.sort_by(|&a, &b| s.values[a].total_cmp(&s.values[b]));
            let m = order.len();
            let worst: Vec<usize> = (m.saturating_sub(label_worst)..m).collect();
            let pts: Vec<(f64, f64)> = thin(m, &worst).into_iter().map(|r| (r as f64, s.values[order[r]])).collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), c.stroke_width(1)))
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(PointSeries::of_element(pts, 2, c, &|p, s, st| Circle::new(p, s, st.filled())))
                .map_err(|e| e.to_string())?;
            if k + 1 == series.len() {
                for &r in &worst {
                    let i = order[r];
                    let (px, py) = chart.backend_coord(&(r as f64, s.values[i]));
                    let id = ids.get(i).copied().unwrap_or(i as i64);
                    frame.text(px - 4, py - 4 - 10 * ((m - 1 - r) as i32 % 2), "end", 10, &format!("id {id}"), "");
                }
            }
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(finish(svg, frame))
}

/// Markers of `ys` against `xs` (one series), y axis from 0: e.g. the error after calibration
/// against one joint angle, to show what the geometric model leaves.
pub fn scatter(title: &str, x_label: &str, y_label: &str, xs: &[f64], ys: &[f64], color: (u8, u8, u8)) -> Result<String, String> {
    let (lo, hi) = range(xs.iter().copied());
    let pad = ((hi - lo) * 0.04).max(1e-9);
    let (x0, x1) = (lo - pad, hi + pad);
    let (_, yhi) = range(ys.iter().copied());
    let (y0, y1) = (0.0, if yhi > 0.0 { yhi * 1.1 } else { 1.0 });
    let mut svg = String::new();
    let mut frame = Frame { texts: String::new() };
    {
        let root = SVGBackend::with_string(&mut svg, (W / 2, H)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .margin_top(44)
            .margin_right(10)
            .x_label_area_size(38)
            .y_label_area_size(56)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        decorate(&mut chart, &mut frame, (x0, x1, y0, y1), "", x_label, y_label, &[])?;
        frame.text(W as i32 / 4, 17, "middle", 12, title, r#" font-weight="bold""#);
        let c = RGBColor(color.0, color.1, color.2);
        let pts: Vec<(f64, f64)> = thin(xs.len().min(ys.len()), &[]).into_iter().map(|i| (xs[i], ys[i])).collect();
        chart
            .draw_series(PointSeries::of_element(pts, 2, c, &|p, s, st| Circle::new(p, s, st.filled())))
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(finish(svg, frame))
}

/// The colour of `v` on the error scale from 0 (blue) through green and yellow to `top` (red),
/// the scale of the report's 3-D view.
pub fn error_colour(v: f64, top: f64) -> (u8, u8, u8) {
    const STOPS: [(f64, f64, f64); 5] = [
        (49.0, 54.0, 149.0),
        (69.0, 117.0, 180.0),
        (116.0, 196.0, 118.0),
        (254.0, 224.0, 80.0),
        (215.0, 48.0, 39.0),
    ];
    let t = if top > 0.0 && v.is_finite() {
        (v / top).clamp(0.0, 1.0)
    } else {
        0.0
    } * 4.0;
    let k = (t.floor() as usize).min(3);
    let f = t - k as f64;
    let (a, b) = (STOPS[k], STOPS[k + 1]);
    let mix = |x: f64, y: f64| (x + f * (y - x)).round() as u8;
    (mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// The poses over one projection of the workspace (`xs` against `ys`, mm, equal scales),
/// coloured by `values` from 0 to their 98th percentile ([`error_colour`], with its colour bar); a pose
/// with `hollow[i]` is an open square (e.g. a validation pose), the others filled circles, as
/// `legend` says (e.g. `"● identification  □ validation"`).
/// Thinned like the other plots, the ten largest values always kept; larger values drawn last.
#[allow(clippy::too_many_arguments)]
pub fn workspace_map(
    title: &str,
    x_label: &str,
    y_label: &str,
    xs: &[f64],
    ys: &[f64],
    values: &[f64],
    hollow: &[bool],
    legend: &str,
) -> Result<String, String> {
    const SIDE: u32 = 440;
    let n = xs.len().min(ys.len()).min(values.len());
    let (xlo, xhi) = range(xs[..n].iter().copied());
    let (ylo, yhi) = range(ys[..n].iter().copied());
    // Equal scales: both axes span the larger extent.
    let half = ((xhi - xlo).max(yhi - ylo) * 0.54).max(1e-6);
    let (cx, cy) = ((xlo + xhi) / 2.0, (ylo + yhi) / 2.0);
    let (x0, x1, y0, y1) = (cx - half, cx + half, cy - half, cy + half);
    let mut order: Vec<usize> = (0..n).filter(|&i| values[i].is_finite()).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]).then(a.cmp(&b)));
    let m = order.len();
    // The scale ends at the 98th percentile (redder beyond), as in the 3-D view.
    let top = order.get((0.98 * m.saturating_sub(1) as f64) as usize).map_or(1.0, |&i| values[i]);
    let most = order.last().map_or(top, |&i| values[i]);
    let worst: Vec<usize> = (m.saturating_sub(10)..m).collect();
    let mut svg = String::new();
    let mut frame = Frame { texts: String::new() };
    {
        let root = SVGBackend::with_string(&mut svg, (SIDE, SIDE + 46)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .margin_top(44)
            .margin_right(14)
            .margin_bottom(46)
            .x_label_area_size(38)
            .y_label_area_size(64)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        decorate(&mut chart, &mut frame, (x0, x1, y0, y1), "", x_label, y_label, &[])?;
        frame.text(SIDE as i32 / 2, 17, "middle", 12, title, r#" font-weight="bold""#);
        for r in thin(m, &worst) {
            let i = order[r];
            let (cr, cg, cb) = error_colour(values[i], top);
            let c = RGBColor(cr, cg, cb);
            if hollow.get(i).copied().unwrap_or(false) {
                chart
                    .draw_series(std::iter::once(
                        EmptyElement::at((xs[i], ys[i])) + Rectangle::new([(-3, -3), (3, 3)], c.stroke_width(1)),
                    ))
                    .map_err(|e| e.to_string())?;
            } else {
                chart
                    .draw_series(std::iter::once(Circle::new((xs[i], ys[i]), 3, c.filled())))
                    .map_err(|e| e.to_string())?;
            }
        }
        root.present().map_err(|e| e.to_string())?;
    }
    // The colour bar under the chart.
    let (bx, by) = (80, SIDE as i32 + 6);
    for k in 0..100 {
        let (r, g, b) = error_colour(k as f64 / 99.0 * top, top);
        let _ = write!(
            frame.texts,
            r##"<rect x="{}" y="{by}" width="2" height="10" fill="#{r:02x}{g:02x}{b:02x}"/>"##,
            bx + 2 * k
        );
    }
    frame.text(bx - 4, by + 9, "end", 11, "0", "");
    let beyond = if most > top {
        format!("+ (max {})", fmt_tick(most, top / 100.0))
    } else {
        String::new()
    };
    frame.text(
        bx + 204,
        by + 9,
        "start",
        11,
        &format!("{}{beyond} mm", fmt_tick(top, top / 100.0)),
        "",
    );
    if hollow.iter().any(|h| *h) {
        frame.text(bx, by + 26, "start", 11, legend, "");
    }
    Ok(finish(svg, frame))
}

/// A correlation matrix as a heat map (−1 blue, 0 white, +1 red), parameter names on both axes.
pub fn heat_map(title: &str, names: &[String], matrix: &[Vec<f64>]) -> String {
    let k = names.len();
    let cell = 520usize.checked_div(k).map_or(12, |c| c.clamp(6, 16)) as i32;
    let margin = 90;
    let size = margin + cell * k as i32 + 20;
    let mut s = format!(
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{}" viewBox="0 0 {size} {}"><rect width="100%" height="100%" fill="#fff"/>"##,
        size + 24,
        size + 24
    );
    let _ = write!(
        s,
        r##"<text x="{}" y="16" text-anchor="middle" font-family="sans-serif" font-size="13" font-weight="bold" fill="#222">{}</text>"##,
        size / 2,
        esc(title)
    );
    let colour = |r: f64| {
        let r = r.clamp(-1.0, 1.0);
        let f = |a: f64| (255.0 * (1.0 - a)).round() as u8;
        if r >= 0.0 {
            (255, f(r), f(r))
        } else {
            (f(-r), f(-r), 255)
        }
    };
    let font = (cell - 2).clamp(6, 11);
    for (i, name) in names.iter().enumerate() {
        let y = 24 + margin + cell * i as i32;
        let _ = write!(
            s,
            r##"<text x="{}" y="{}" text-anchor="end" font-family="sans-serif" font-size="{font}" fill="#222">{}</text>"##,
            margin - 4,
            y + cell - 2,
            esc(name)
        );
        let x = margin + cell * i as i32;
        let _ = write!(
            s,
            r##"<text x="{}" y="{}" text-anchor="start" font-family="sans-serif" font-size="{font}" fill="#222" transform="rotate(-90 {} {})">{}</text>"##,
            x + cell - 2,
            24 + margin - 4,
            x + cell - 2,
            24 + margin - 4,
            esc(name)
        );
        for (j, v) in matrix[i].iter().enumerate() {
            let (r, g, b) = colour(*v);
            let _ = write!(
                s,
                r##"<rect x="{}" y="{y}" width="{cell}" height="{cell}" fill="#{r:02x}{g:02x}{b:02x}"><title>{} / {}: {:.3}</title></rect>"##,
                margin + cell * j as i32,
                esc(name),
                esc(&names[j]),
                v
            );
        }
    }
    s.push_str("</svg>");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_nice() {
        assert_eq!(nice_ticks(0.0, 1.0, 5), vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]);
        assert_eq!(nice_ticks(0.0, 49.0, 8), vec![0.0, 10.0, 20.0, 30.0, 40.0]);
    }

    #[test]
    fn charts_carry_their_text() {
        let v = [0.5, 1.0, 0.25];
        let s = per_pose_chart(
            "Position error",
            "mm",
            &[Series {
                name: "before",
                color: (200, 0, 0),
                values: &v,
            }],
        )
        .unwrap();
        assert!(s.starts_with("<svg") && s.trim_end().ends_with("</svg>"));
        assert!(s.contains(">Position error</text>") && s.contains(">before</text>") && s.contains("<circle"));
        let h = histogram(
            "h",
            "mm",
            &[Series {
                name: "after",
                color: (0, 0, 200),
                values: &v,
            }],
            4,
        )
        .unwrap();
        assert!(h.contains("<rect") && h.contains(">after</text>"));
    }
}
