//! The report's 3-D view: the measured tool positions coloured by their error before or after
//! calibration, their error vectors, identification and validation poses, the measurement and
//! base frames and the machine's skeleton at home, drawn by a small inline script on a canvas
//! (`view.js`: orthographic projection, drag to turn, wheel to zoom, hover for a pose's id and
//! errors; nothing fetched).
//!
//! The script reads its data from a JSON block of the page (`<script id="view-data"
//! type="application/json">`), written here from the report's own fields: the same per-pose
//! errors as the report's JSON ([`SetErrors`]), rounded to 10 nm, at most [`VIEW_POINTS`] poses
//! per set (evenly spread, the worst [`VIEW_WORST`] before and after always kept), each with its
//! index in the set (`i`) so that it can be traced back.
use super::artifacts::axes;
use super::{CalibrationReport, SetErrors};
use crate::measure::Measurement;
use crate::model::Mechanism;
use nalgebra::Vector3;
use serde::Serialize;
use std::fmt::Write as _;

/// At most this many poses per data set are drawn in the 3-D view.
pub const VIEW_POINTS: usize = 2000;

/// The poses with the largest errors (before and after) always drawn, however many are thinned.
pub const VIEW_WORST: usize = 50;

/// The machine and its frames as the 3-D view draws them, in the measurement frame (mm).
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct MachineView {
    /// The calibrated machine at home: polylines through its joints
    /// ([`Mechanism::skeleton`]); empty for a mechanism without a drawing.
    pub skeleton: Vec<Vec<[f64; 3]>>,
    /// The starting model's drawing, the same polylines: a vertex's shift between the two is
    /// how far the calibration moved that part.
    pub skeleton_nominal: Vec<Vec<[f64; 3]>>,
    /// The calibrated base frame in the measurement frame: origin, then its x, y and z unit
    /// axes; `None` when the model carries no separate frames (its world frame is then the
    /// measurement frame), and for an instrument calibration no tracker placed (the world frame
    /// is then the machine's base frame as drawn: [`super::artifacts`]).
    pub base: Option<[[f64; 3]; 4]>,
    /// The calibrated model's tool frame at the first identification pose (origin, then its
    /// x, y, z unit axes, in the measurement frame): where the tool frame found by the
    /// calibration (the registered tool offset, for a model seen through frames) sits on the
    /// measured points. `None` without poses.
    pub tool: Option<[[f64; 3]; 4]>,
    /// How far each vertex of `skeleton` lies from its place in `skeleton_nominal` once the two
    /// drawings are brought together by the best rigid motion (mm): what the calibration
    /// changed in the machine's shape, apart from where it stands (a change of the frames, or
    /// of a redundant base placement, moves every vertex alike and shows nowhere). Empty when
    /// the drawings differ in structure.
    pub moved: Vec<Vec<f64>>,
    /// An instrument's artifacts (seats, pivots, spheres, planes, a cube) at their places,
    /// indexed as [`SetErrors::artifact`]; empty for tracker data.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub artifacts: Vec<super::ArtifactView>,
}

/// Per vertex of `b`, its distance from the same vertex of `a` after the rigid motion that
/// brings `b` closest to `a` (least squares, Kabsch); empty when the structures differ.
fn shape_change(a: &[Vec<[f64; 3]>], b: &[Vec<[f64; 3]>]) -> Vec<Vec<f64>> {
    if a.len() != b.len() || a.iter().zip(b).any(|(x, y)| x.len() != y.len()) || a.is_empty() {
        return Vec::new();
    }
    let v = |p: &[f64; 3]| Vector3::new(p[0], p[1], p[2]);
    let pa: Vec<Vector3<f64>> = a.iter().flatten().map(v).collect();
    let pb: Vec<Vector3<f64>> = b.iter().flatten().map(v).collect();
    let n = pa.len().max(1) as f64;
    let (ca, cb) = (pa.iter().sum::<Vector3<f64>>() / n, pb.iter().sum::<Vector3<f64>>() / n);
    let h: nalgebra::Matrix3<f64> = pb.iter().zip(&pa).map(|(y, x)| (y - cb) * (x - ca).transpose()).sum();
    let svd = h.svd(true, true);
    let r = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => {
            let d = (vt.transpose() * u.transpose()).determinant().signum();
            vt.transpose() * nalgebra::Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose()
        }
        _ => nalgebra::Matrix3::identity(),
    };
    let r = if r.iter().all(|x| x.is_finite()) {
        r
    } else {
        nalgebra::Matrix3::identity()
    };
    a.iter()
        .zip(b)
        .map(|(la, lb)| la.iter().zip(lb).map(|(x, y)| (r * (v(y) - cb) + ca - v(x)).norm()).collect())
        .collect()
}

fn arr(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

fn lines(m: &(impl Mechanism + ?Sized)) -> Vec<Vec<[f64; 3]>> {
    m.skeleton().iter().map(|l| l.iter().map(arr).collect()).collect()
}

impl MachineView {
    /// The drawing of `nominal` (the starting model) and `calibrated`, the calibrated base
    /// frame, and the calibrated tool frame at the measurement `first` (the first pose), if
    /// given (for an instrument's row, the machine's own tool frame:
    /// [`super::artifacts::machine_pose`]). Without artifacts ([`MachineView::artifacts`]).
    pub fn of<A: Mechanism + ?Sized, B: Mechanism + ?Sized>(nominal: &A, calibrated: &B, first: Option<&Measurement>) -> MachineView {
        let base = calibrated.frames().map(|(x, _)| axes(&x));
        let tool = first
            .and_then(|m| super::artifacts::machine_pose(calibrated, m).ok())
            .map(|t| axes(&t));
        let (skeleton, skeleton_nominal) = (lines(calibrated), lines(nominal));
        MachineView {
            moved: shape_change(&skeleton_nominal, &skeleton),
            skeleton,
            skeleton_nominal,
            base,
            tool,
            artifacts: Vec::new(),
        }
    }
}

/// Indices of the poses the view draws: every k-th of `n`, and the `VIEW_WORST` largest of
/// each of `worst_of` always.
pub fn view_indices(n: usize, worst_of: &[&[f64]]) -> Vec<usize> {
    if n <= VIEW_POINTS {
        return (0..n).collect();
    }
    let step = n.div_ceil(VIEW_POINTS - VIEW_WORST * worst_of.len());
    let mut keep: Vec<usize> = (0..n).step_by(step).collect();
    for v in worst_of {
        let mut order: Vec<usize> = (0..v.len().min(n)).filter(|&i| v[i].is_finite()).collect();
        order.sort_by(|&a, &b| v[b].total_cmp(&v[a]).then(a.cmp(&b)));
        keep.extend(order.into_iter().take(VIEW_WORST));
    }
    keep.sort_unstable();
    keep.dedup();
    keep
}

/// A number rounded to `d` decimals, `null` when not finite (JSON has no NaN).
fn num(out: &mut String, v: f64, d: usize) {
    if v.is_finite() {
        let s = format!("{v:.d$}");
        // Trim trailing zeros (and a bare point) to keep the page small.
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.')
        } else {
            &s
        };
        out.push_str(if s == "-0" { "0" } else { s });
    } else {
        out.push_str("null");
    }
}

/// `values` as a JSON array, each rounded to `d` decimals.
pub(super) fn array(out: &mut String, values: impl Iterator<Item = f64>, d: usize) {
    out.push('[');
    for (k, v) in values.enumerate() {
        if k > 0 {
            out.push(',');
        }
        num(out, v, d);
    }
    out.push(']');
}

/// `"key":[values],` (see [`array`]).
pub(super) fn list(out: &mut String, key: &str, values: impl Iterator<Item = f64>, d: usize) {
    let _ = write!(out, "\"{key}\":");
    array(out, values, d);
    out.push(',');
}

/// A JSON string, safe inside a `<script>` element.
pub(super) fn string(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".into()).replace('<', "\\u003c")
}

/// Decimals of positions (10 µm) and of errors (10 nm) in the view's data.
pub(super) const POSITION_DECIMALS: usize = 2;
const ERROR_DECIMALS: usize = 5;

fn set_json(out: &mut String, name: &str, s: &SetErrors) {
    let n = s.after.position.len();
    let keep = view_indices(n, &[&s.after.position, &s.before.position]);
    let _ = write!(out, "{{\"name\":{},\"source\":{},\"n\":{n},", string(name), string(&s.source));
    let at = |v: &[[f64; 3]], i: usize| v.get(i).copied().unwrap_or([f64::NAN; 3]);
    list(out, "i", keep.iter().map(|&i| i as f64), 0);
    list(out, "id", keep.iter().map(|&i| s.ids.get(i).copied().unwrap_or(i as i64) as f64), 0);
    let flat = |v: &[[f64; 3]]| keep.iter().flat_map(|&i| at(v, i)).collect::<Vec<f64>>();
    list(out, "p", flat(&s.measured).into_iter(), POSITION_DECIMALS);
    if !s.artifact.is_empty() {
        // An instrument's rows: the artifact of each (−1 for a tracker row) and the starting
        // model's tool point, drawn when the view shows the errors before calibration.
        let k = |i: usize| s.artifact.get(i).copied().flatten().map_or(-1.0, |k| k as f64);
        list(out, "k", keep.iter().map(|&i| k(i)), 0);
        list(out, "pb", flat(&s.nominal_point).into_iter(), POSITION_DECIMALS);
    }
    list(out, "eb", flat(&s.error_before).into_iter(), ERROR_DECIMALS);
    list(out, "ea", flat(&s.error_after).into_iter(), ERROR_DECIMALS);
    list(out, "b", keep.iter().map(|&i| s.before.position[i]), ERROR_DECIMALS);
    list(out, "a", keep.iter().map(|&i| s.after.position[i]), ERROR_DECIMALS);
    let deg = |v: &[Option<f64>], i: usize| v.get(i).copied().flatten().map_or(f64::NAN, f64::to_degrees);
    if s.after.orientation.iter().any(Option::is_some) {
        list(out, "ob", keep.iter().map(|&i| deg(&s.before.orientation, i)), ERROR_DECIMALS);
        list(out, "oa", keep.iter().map(|&i| deg(&s.after.orientation, i)), ERROR_DECIMALS);
    }
    out.pop();
    out.push('}');
}

/// `"key":[[x, y, z, …], …],`: polylines as flat arrays.
pub(super) fn polylines(out: &mut String, key: &str, l: &[Vec<[f64; 3]>]) {
    let _ = write!(out, "\"{key}\":[");
    for (k, line) in l.iter().enumerate() {
        if k > 0 {
            out.push(',');
        }
        array(out, line.iter().flat_map(|p| p.iter().copied()), POSITION_DECIMALS);
    }
    out.push_str("],");
}

impl CalibrationReport {
    /// The 3-D view's data as the report page embeds it (JSON): per data set its name, `n` (its
    /// number of poses), and for the drawn poses their index `i` in the set, `id`, measured
    /// position `p` and error vectors `eb`/`ea` (flat x, y, z), position errors `b`/`a` and,
    /// for pose measurements, orientation errors `ob`/`oa` (deg), before/after calibration; the
    /// machine's `skeleton` and `nominal` drawing (flat x, y, z per polyline), the shape change
    /// `moved` per skeleton vertex ([`MachineView::moved`]), the `base` frame and the `tool`
    /// frame at the first identification pose, whose id is `toolPose`. For an instrument's
    /// data, per set also each drawn pose's artifact `k` (−1 for a tracker row) and the
    /// starting model's tool point `pb`, `world` (`"base frame"`: the name of the view's world
    /// frame, when no tracker placed it), and the `artifacts`: `name`, `kind`, the fitted frame
    /// `f` and the starting model's `n` (origin, then the x, y, z axes, flat), `size`
    /// ([`super::ArtifactView`]).
    pub fn view_json(&self) -> String {
        let mut out = String::from("{\"sets\":[");
        set_json(&mut out, "identification", &self.identification);
        if let Some(v) = &self.validation {
            out.push(',');
            set_json(&mut out, "validation", v);
        }
        out.push_str("],");
        polylines(&mut out, "skeleton", &self.machine.skeleton);
        polylines(&mut out, "nominal", &self.machine.skeleton_nominal);
        let _ = write!(out, "\"moved\":[");
        for (k, m) in self.machine.moved.iter().enumerate() {
            if k > 0 {
                out.push(',');
            }
            array(&mut out, m.iter().copied(), ERROR_DECIMALS);
        }
        out.push_str("],");
        for (key, frame) in [("base", &self.machine.base), ("tool", &self.machine.tool)] {
            match frame {
                Some(b) => list(&mut out, key, b.iter().flatten().copied(), 6),
                None => {
                    let _ = write!(out, "\"{key}\":null,");
                }
            }
        }
        let tool_pose = self.identification.ids.first().copied().unwrap_or(0);
        let _ = write!(out, "\"toolPose\":{tool_pose},");
        if !self.machine.artifacts.is_empty() {
            // An instrument alone places nothing: the world frame is the machine's base frame.
            if self.identification.artifact.iter().all(Option::is_some) {
                out.push_str("\"world\":\"base frame\",");
            }
            out.push_str("\"artifacts\":[");
            for (k, a) in self.machine.artifacts.iter().enumerate() {
                if k > 0 {
                    out.push(',');
                }
                let _ = write!(out, "{{\"name\":{},\"kind\":{},", string(&a.name), string(&a.kind));
                list(&mut out, "f", a.frame.iter().flatten().copied(), 6);
                list(&mut out, "n", a.frame_nominal.iter().flatten().copied(), 6);
                let _ = write!(out, "\"size\":");
                num(&mut out, a.size, POSITION_DECIMALS);
                out.push('}');
            }
            out.push_str("],");
        }
        out.pop();
        out.push('}');
        out
    }

    /// The 3-D view section: controls, the canvas, its data and the script.
    pub(super) fn view_html(&self, h: &mut String) {
        let n: usize = self.identification.after.position.len() + self.validation.as_ref().map_or(0, |v| v.after.position.len());
        h.push_str("<h2 id=\"view\">3-D view: where the errors are</h2>\n");
        // What the points are, where they are drawn, what their error vectors show.
        let (points, frame, vectors) = if self.machine.artifacts.is_empty() {
            (
                "The measured tool positions",
                "in the measurement frame",
                "Lines from each point toward the model's position show the error vectors, scaled as stated.",
            )
        } else {
            (
                "The tool points the calibrated model puts at each row's configuration",
                "in the machine's base frame (the starting model's tool points when coloured by the error before calibration), with the instrument's artifacts (calibrated solid, as the starting model placed them dashed; a ballbar's bar from its pivot to each tool point)",
                "Lines from each tool point toward where the instrument puts it (a seat's centre, the bar's measured length, the touched surface) show the error vectors, scaled as stated.",
            )
        };
        let _ = write!(
            h,
            "<p class=\"muted\">{points} ({n} poses; at most {VIEW_POINTS} per set drawn, evenly spread, the {VIEW_WORST} worst before and after always) {frame}, coloured by their position error; ● identification, □ validation. {vectors} Drag to turn, shift-drag to move, wheel to zoom, hover for a pose's id and errors.{}</p>",
            if self.machine.skeleton.is_empty() {
                " This kind of machine has no drawing."
            } else {
                " The machine at home: calibrated solid, starting model dashed, drawn over the points; the three joints whose place the calibration changed most (apart from where the whole machine stands) are circled."
            }
        );
        let _ = writeln!(
            h,
            "<div id=\"view-controls\" style=\"font-size:13px;margin:4px 0\">colour by error <label><input type=\"radio\" name=\"view-mode\" value=\"after\" checked> after calibration</label> <label><input type=\"radio\" name=\"view-mode\" value=\"before\"> before</label> · <label><input type=\"checkbox\" id=\"view-vectors\" checked> error vectors</label> ×<input type=\"number\" id=\"view-scale\" min=\"0\" step=\"any\" style=\"width:6em\"> · <label><input type=\"checkbox\" id=\"view-identification\" checked> identification</label> <label><input type=\"checkbox\" id=\"view-validation\" checked> validation</label> · {VIEW_BUTTONS}</div>"
        );
        canvas(h, &self.view_json());
    }
}

/// The view's canvas, its data (`json`, as [`CalibrationReport::view_json`] writes it; a set
/// may instead give a fixed `colour`, a marker `size`, a `tag` drawn beside each point and a
/// hover `label` per point) and the script.
pub(super) fn canvas(h: &mut String, json: &str) {
    h.push_str(
        "<div style=\"position:relative\"><canvas id=\"view3d\" width=\"1100\" height=\"620\" style=\"border:1px solid #ddd;max-width:100%;cursor:grab\" data-drawn=\"0\"></canvas>\
         <div id=\"view-tip\" style=\"position:absolute;display:none;background:#fff;border:1px solid #888;padding:3px 6px;font-size:12px;pointer-events:none;white-space:pre\"></div></div>\n",
    );
    let _ = writeln!(h, "<script type=\"application/json\" id=\"view-data\">{json}</script>");
    let _ = writeln!(h, "<script>\n{}</script>", include_str!("view.js"));
}

/// The buttons that turn the view to the three planes of the measurement frame.
pub(super) const VIEW_BUTTONS: &str = "view <button type=\"button\" data-view=\"iso\">3-D</button> <button type=\"button\" data-view=\"xy\">x–y</button> <button type=\"button\" data-view=\"xz\">x–z</button> <button type=\"button\" data-view=\"yz\">y–z</button>";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thinning_keeps_the_worst_and_stays_bounded() {
        let n = 100_000;
        let v: Vec<f64> = (0..n).map(|i| ((i * 7919) % 1000) as f64).collect();
        let keep = view_indices(n, &[&v]);
        assert!(keep.len() <= VIEW_POINTS, "{}", keep.len());
        assert!(keep.windows(2).all(|w| w[0] < w[1]));
        let worst = v.iter().copied().fold(0.0, f64::max);
        assert!(keep.iter().filter(|&&i| v[i] == worst).count() >= VIEW_WORST.min(100));
        assert_eq!(view_indices(10, &[&v[..10]]), (0..10).collect::<Vec<_>>());
    }

    #[test]
    fn a_rigid_motion_changes_no_shape() {
        let a = vec![vec![[0.0, 0.0, 0.0], [100.0, 0.0, 0.0], [100.0, 50.0, 0.0], [100.0, 50.0, 30.0]]];
        let (c, s) = (0.3f64.cos(), 0.3f64.sin());
        let moved = |p: &[f64; 3]| [c * p[0] - s * p[1] + 5.0, s * p[0] + c * p[1] - 2.0, p[2] + 7.0];
        let b: Vec<Vec<[f64; 3]>> = a.iter().map(|l| l.iter().map(moved).collect()).collect();
        assert!(shape_change(&a, &b)[0].iter().all(|d| *d < 1e-9), "{:?}", shape_change(&a, &b));
        let mut bent = b.clone();
        bent[0][3][2] += 1.0;
        let d = &shape_change(&a, &bent)[0];
        let worst = d.iter().copied().fold(0.0, f64::max);
        assert!((d[3] - worst).abs() < 1e-12 && worst > 0.5, "{d:?}");
        assert!(shape_change(&a, &[]).is_empty());
    }

    #[test]
    fn numbers_are_short_and_json_safe() {
        let mut s = String::new();
        num(&mut s, 1.50000, 5);
        s.push(' ');
        num(&mut s, f64::NAN, 5);
        s.push(' ');
        num(&mut s, -0.000001, 5);
        assert_eq!(s, "1.5 null 0");
        assert_eq!(string("a</script>"), "\"a\\u003c/script>\"");
    }
}
