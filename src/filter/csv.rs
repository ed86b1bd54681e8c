//! CSV targets (`kinecal compensate`'s TARGETS format): `x_mm,y_mm,z_mm` (or `_m`) with
//! `qw,qx,qy,qz` or `roll_deg,pitch_deg,yaw_deg` (or `_rad`, `R = Rz(yaw)·Ry(pitch)·Rx(roll)`),
//! an optional `id` and optional input columns (joint values the nominal inverse kinematics
//! starts from). The targets are tool poses in the base frame with [`FilterOptions::tool`];
//! their cells are rewritten in place, every other byte (other columns, comments, line ends)
//! kept. Positions get at least 0.001 mm (1e-6 m), quaternions 7 decimals, angles 1e-5 deg
//! (1e-7 rad).
use super::path::{slerp, Path as MovePath, PathPoint};
use super::rewrite::{apply, number_edit, Edit};
use super::{correct_located, FilterError, FilterModels, FilterOptions, FilteredProgram, Format, PathReport, Target};
use crate::compensate::target_poses;
use crate::io::data_file::{data_from_table, InputColumns};
use crate::io::table::parse_table;
use crate::se3;
use nalgebra::UnitQuaternion;
use std::ops::Range;
use std::path::Path;

/// The byte range of each line's content (without its line end), by 0-based line index.
pub(crate) fn line_ranges(text: &str) -> Vec<Range<usize>> {
    let mut out = Vec::new();
    let mut at = 0;
    for l in text.split_inclusive('\n') {
        let content = l.trim_end_matches(['\n', '\r']);
        out.push(at..at + content.len());
        at += l.len();
    }
    out
}

/// The trimmed cells of a CSV line starting at byte `start`, with their ranges.
fn cells(line: &str, start: usize) -> Vec<(Range<usize>, &str)> {
    let mut out = Vec::new();
    let mut at = 0;
    for c in line.split(',') {
        let lead = c.len() - c.trim_start().len();
        let t = c.trim();
        out.push((start + at + lead..start + at + lead + t.len(), t));
        at += c.len() + 1;
    }
    out
}

/// Roll, pitch, yaw of `r` (`R = Rz(yaw)·Ry(pitch)·Rx(roll)`) nearest the angles `old`: at
/// gimbal lock (pitch ±90°), where only the difference or sum of roll and yaw counts, the roll
/// as written and the yaw that goes with it.
fn rpy_near(r: &UnitQuaternion<f64>, old: [f64; 3]) -> [f64; 3] {
    let a = se3::rpy(r);
    if (a[1].abs() - std::f64::consts::FRAC_PI_2).abs() > 1e-6 {
        return a;
    }
    let gap = |x: &[f64; 3]| se3::so3_log(&(UnitQuaternion::from_euler_angles(x[0], x[1], x[2]).inverse() * r)).norm();
    [1.0, -1.0]
        .iter()
        .map(|s| [old[0], a[1], a[2] + s * (old[0] - a[0])])
        .min_by(|x, y| gap(x).total_cmp(&gap(y)))
        .filter(|x| gap(x) < 1e-9)
        .unwrap_or(a)
}

/// Filter a CSV targets file.
pub fn filter_csv(path: &Path, text: &str, models: &FilterModels, opts: &FilterOptions) -> Result<FilteredProgram, FilterError> {
    let table = parse_table(path, text)?;
    let data = data_from_table(&table, &models.columns, InputColumns::Optional)?;
    let poses = target_poses(&data.measurements).map_err(|i| FilterError::Parse {
        path: path.to_path_buf(),
        line: data.lines[i],
        message: "a target needs an orientation (qw,qx,qy,qz or roll,pitch,yaw), not only a position".into(),
    })?;
    let col = |name: &str| table.columns.iter().position(|c| c == name);
    let position: Vec<(usize, f64, usize)> = ["x", "y", "z"]
        .iter()
        .filter_map(|a| {
            col(&format!("{a}_mm"))
                .map(|c| (c, 1.0, 3))
                .or_else(|| col(&format!("{a}_m")).map(|c| (c, 1e-3, 6)))
        })
        .collect();
    let quat: Vec<usize> = ["qw", "qx", "qy", "qz"].iter().filter_map(|c| col(c)).collect();
    let rpy: Vec<(usize, f64, usize)> = ["roll", "pitch", "yaw"]
        .iter()
        .filter_map(|a| {
            col(&format!("{a}_deg"))
                .map(|c| (c, 1.0f64.to_degrees(), 5))
                .or_else(|| col(&format!("{a}_rad")).map(|c| (c, 1.0, 7)))
        })
        .collect();
    let targets: Vec<Target> = poses
        .iter()
        .zip(&data.measurements)
        .map(|(p, m)| Target {
            pose: *p,
            tool: opts.tool,
            configuration: None,
            seed: data.has_inputs.then(|| m.q.clone()),
        })
        .collect();
    let located: Vec<(std::path::PathBuf, usize, String)> = data
        .lines
        .iter()
        .zip(&data.ids)
        .map(|(l, id)| (path.to_path_buf(), *l, format!("target {id}")))
        .collect();
    let super::Located {
        corrected,
        reports,
        uncorrected,
    } = correct_located(models, &targets, &located, opts.force)?;
    let lines = line_ranges(text);
    // The edits writing `pose` over the cells of the line `line` (1-based), `original` the
    // row's own target.
    let row_edits = |line: usize, pose: &crate::se3::Pose, original: &crate::se3::Pose| -> Vec<Edit> {
        let mut edits = Vec::new();
        let range = lines[line - 1].clone();
        let cells = cells(&text[range.clone()], range.start);
        let p = pose.translation.vector;
        for (k, (ci, f, d)) in position.iter().enumerate() {
            let (r, t) = &cells[*ci];
            edits.extend(number_edit(t, r.clone(), p[k] * f, *d));
        }
        if quat.len() == 4 {
            let mut q = pose.rotation.into_inner();
            if q.coords.dot(&original.rotation.coords) < 0.0 {
                q = -q;
            }
            for (ci, v) in quat.iter().zip([q.w, q.i, q.j, q.k]) {
                let (r, t) = &cells[*ci];
                edits.extend(number_edit(t, r.clone(), v, 7));
            }
        } else if rpy.len() == 3 {
            let old: Vec<f64> = rpy
                .iter()
                .map(|(ci, f, _)| cells[*ci].1.parse::<f64>().unwrap_or(0.0) / f)
                .collect();
            let a = rpy_near(&pose.rotation, [old[0], old[1], old[2]]);
            for ((ci, f, d), v) in rpy.iter().zip(a) {
                let (r, t) = &cells[*ci];
                // The whole-turn equivalent nearest the angle as written.
                let old = t.parse::<f64>().unwrap_or(0.0) / f;
                let v = old + se3::wrap_angle(v - old);
                edits.extend(number_edit(t, r.clone(), v * f, *d));
            }
        }
        edits
    };
    let mut edits: Vec<Edit> = Vec::new();
    let paths = row_paths(models, opts, &corrected, &poses, &data.lines, path)?;
    let eol = if text.contains("\r\n") { "\r\n" } else { "\n" };
    let mut next_id = data.ids.iter().copied().max().unwrap_or(0);
    for (k, ((c, line), original)) in corrected.iter().zip(&data.lines).zip(&poses).enumerate() {
        let Some(c) = c else { continue };
        // Rows added before this one: copies of it with their targets.
        let range = lines[line - 1].clone();
        for added in &paths.1[k] {
            let mut row = row_edits(*line, added, original);
            // An id of its own, after the file's largest.
            if let Some(ci) = col("id") {
                let (r, _) = &cells(&text[range.clone()], range.start)[ci];
                next_id += 1;
                row.push(Edit {
                    range: r.clone(),
                    text: next_id.to_string(),
                });
            }
            let shifted: Vec<Edit> = row
                .into_iter()
                .map(|e| Edit {
                    range: e.range.start - range.start..e.range.end - range.start,
                    text: e.text,
                })
                .collect();
            edits.push(Edit {
                range: range.start..range.start,
                text: format!("{}{eol}", apply(&text[range.clone()], &shifted)),
            });
        }
        edits.extend(row_edits(*line, &c.pose, original));
    }
    Ok(FilteredProgram {
        text: apply(text, &edits),
        companion: None,
        format: Format::Csv,
        targets: reports,
        uncorrected,
        notes: Vec::new(),
        paths: Some(paths.0),
    })
}

/// The straight moves between consecutive rows (position at a constant rate, rotation turned
/// at one): their report and, by row, the corrected targets of the rows to add before it.
fn row_paths(
    models: &FilterModels,
    opts: &FilterOptions,
    corrected: &[Option<super::Corrected>],
    poses: &[se3::Pose],
    lines: &[usize],
    path: &Path,
) -> Result<(PathReport, Vec<Vec<se3::Pose>>), FilterError> {
    let (cal, nom) = models.with_tool(&opts.tool);
    let starts = crate::compensate::fixed_starts(&models.inputs, crate::compensate::COMPENSATION_STARTS);
    let mover = MovePath {
        models,
        cal: &*cal,
        nom: &*nom,
        tool: opts.tool,
        interp: &slerp,
        starts: &starts,
    };
    let mut report = PathReport::default();
    let mut added = vec![Vec::new(); corrected.len()];
    let point = |k: usize| {
        corrected[k].as_ref().map(|c| PathPoint {
            original: poses[k],
            corrected: c.clone(),
            fraction: 0.0,
        })
    };
    for k in 1..corrected.len() {
        let (Some(a), Some(mut b)) = (point(k - 1), point(k)) else {
            continue;
        };
        b.fraction = 1.0;
        let fail = |message: String| FilterError::Target {
            path: path.to_path_buf(),
            line: lines[k],
            message,
        };
        let (points, worst) = match opts.max_deviation_mm {
            Some(d) => mover.split(&a, &b, d).map_err(fail)?,
            None => match mover.deviation(&a, &b) {
                Ok(d) => (Vec::new(), d),
                Err(_) => {
                    report.unjudged += 1;
                    continue;
                }
            },
        };
        report.moves += 1;
        if worst > report.largest_deviation_mm {
            report.largest_deviation_mm = worst;
            report.largest_deviation_line = lines[k];
        }
        report.added_points += points.len();
        added[k] = points.into_iter().map(|p| p.corrected.pose).collect();
    }
    Ok((report, added))
}
