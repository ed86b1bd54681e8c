//! G-code (`.nc`, `.ngc`, `.gcode`) for a machine that commands its tool position (a delta
//! printer, [`Task::Position`]) or its position and tool axis (a 5-axis parallel head,
//! [`Task::PositionAndAxis`]): `G0`/`G1` blocks with `X Y Z` and, for the tool axis, `A B` — the
//! rotations about x then y, `R = Rot(x, A)·Rot(y, B)` in degrees (the platform coordinates of a
//! closed-loop model file, [`crate::se3::euler_xyz`]; the rotation about the tool axis is not
//! commanded). Targets in the machine's base frame with its tool ([`FilterOptions::tool`]).
//!
//! Modal: the motion (`G0`, `G1`), `G90`/`G91` (absolute or incremental: an incremental block's
//! words are rewritten as the increments between the corrected positions), `G20`/`G21` (inch or
//! mm). Comments (`;` to the end of the line, `( … )`) and every other word stay. An axis a
//! block does not name keeps its value on the nominal machine but not after correction: its word
//! is added after the block's last axis word when its corrected value differs at the precision
//! written.
//!
//! Arcs (`G2`, `G3`; `I J K` or `R`; planes `G17`, `G18`, `G19`; a helix) are linearised into
//! `G1` chords within half the tolerance ([`FilterOptions::max_deviation_mm`], else
//! [`super::DEFAULT_ARC_TOLERANCE_MM`]): the arc's own line becomes the first chord (its `G2`/`G3`
//! a `G1`, its `I J K R` removed, its other words kept) and the other chords follow it on lines of
//! their own. Straight moves (`G1` and chords) are judged by their path ([`super::path`]) and,
//! with a tolerance, split the same way. An extrusion `E` on a split block is shared along it
//! (relative after `M83` or `G91`, absolute after `M82` or `G90`). Refused with a line: an arc
//! whose end is off its circle by more than half the tolerance, an `R` too short, `P` turns,
//! absolute arc centres (`G90.1`), an incremental move before the position is known, `G92`.
use super::arc::{linearise, Centre};
use super::path::{Path as MovePath, PathPoint};
use super::rewrite::{apply, decimals, format_fixed, number_edit, Edit};
use super::{correct_located, FilterError, FilterModels, FilterOptions, FilteredProgram, Format, PathReport, Target};
use crate::model::Task;
use crate::se3::Pose;
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use std::ops::Range;
use std::path::Path;

/// A word: letter (upper case), value, text and range of its number.
#[derive(Debug, Clone)]
struct Word {
    letter: char,
    value: f64,
    text: String,
    /// Byte of the letter.
    start: usize,
    range: Range<usize>,
}

/// The words of a line (comments skipped), or an error message.
fn words(line: &str, start: usize) -> Result<Vec<Word>, String> {
    let b = line.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        match c {
            b';' => break,
            b'(' => {
                let close = line[i..].find(')').ok_or("a comment '(' without its ')'")?;
                i += close + 1;
            }
            _ if c.is_ascii_whitespace() || c == b'%' => i += 1,
            _ if c.is_ascii_alphabetic() => {
                let letter = (c as char).to_ascii_uppercase();
                let s = i + 1;
                let mut j = s;
                while j < b.len() && b[j] == b' ' {
                    j += 1;
                }
                let ns = j;
                if j < b.len() && (b[j] == b'-' || b[j] == b'+') {
                    j += 1;
                }
                while j < b.len() && (b[j].is_ascii_digit() || b[j] == b'.') {
                    j += 1;
                }
                let text = &line[ns..j];
                let value: f64 = text.trim_start_matches('+').parse().map_err(|_| {
                    format!(
                        "word '{}': '{}' is not a number",
                        letter,
                        line[s..].split_whitespace().next().unwrap_or("")
                    )
                })?;
                out.push(Word {
                    letter,
                    value,
                    text: text.to_string(),
                    start: start + i,
                    range: start + ns..start + j,
                });
                i = j;
            }
            _ => return Err(format!("unexpected '{}'", line[i..].chars().next().unwrap_or(' '))),
        }
    }
    Ok(out)
}

/// A motion block: its line, words, and the absolute nominal points (mm, deg) it reaches, each
/// with its fraction of the block (an arc's chords; else its end alone).
struct Block {
    line: usize,
    words: Vec<Word>,
    points: Vec<([f64; 5], f64)>,
    motion: u8,
    arc: bool,
    sagitta: f64,
    incremental: bool,
    inch: bool,
    e_relative: bool,
    /// The absolute extrusion before the block, where known.
    e_before: Option<f64>,
    /// The line's leading white space.
    indent: String,
}

const AXES: [char; 5] = ['X', 'Y', 'Z', 'A', 'B'];

/// The pose of X Y Z (mm) and A B (deg, `Rot(x, A)·Rot(y, B)`).
fn pose_of(t: &[f64; 5]) -> Pose {
    Pose::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), t[3].to_radians())
            * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), t[4].to_radians()),
    )
}

/// X Y Z A B of a pose.
fn coords_of(p: &Pose) -> [f64; 5] {
    let t = p.translation.vector;
    let e = crate::se3::euler_xyz(&p.rotation.to_rotation_matrix().into_inner());
    [t.x, t.y, t.z, e[0].to_degrees(), e[1].to_degrees()]
}

/// The controller's straight move: each axis at a constant rate.
fn axis_lerp(a: &Pose, b: &Pose, s: f64) -> Pose {
    let (x, y) = (coords_of(a), coords_of(b));
    let mut v = [0.0; 5];
    for k in 0..5 {
        v[k] = x[k] + (y[k] - x[k]) * s;
    }
    pose_of(&v)
}

/// The blocks of a program (parse errors as (line, message)).
fn parse(text: &str, axes: usize, arc_tolerance: f64) -> Result<Vec<Block>, (usize, String)> {
    let ranges = super::csv::line_ranges(text);
    let (mut motion, mut incremental, mut inch, mut plane, mut e_relative) = (0u8, false, false, 17u8, false);
    // Firmware starts at E 0.
    let mut e_abs: Option<f64> = Some(0.0);
    let mut pos: [Option<f64>; 5] = [None; 5];
    if axes == 3 {
        pos[3] = Some(0.0);
        pos[4] = Some(0.0);
    }
    let mut blocks: Vec<Block> = Vec::new();
    for (k, r) in ranges.iter().enumerate() {
        let line = k + 1;
        let at = |m: String| (line, m);
        let ws = words(&text[r.clone()], r.start).map_err(at)?;
        for w in ws.iter().filter(|w| w.letter == 'G') {
            if (w.value - 90.1).abs() < 1e-9 {
                return Err(at("G90.1 (absolute arc centres) is not supported".into()));
            }
            if w.value.fract() != 0.0 {
                continue;
            }
            match w.value as i64 {
                v @ 0..=3 => motion = v as u8,
                v @ 17..=19 => plane = v as u8,
                90 => (incremental, e_relative) = (false, false),
                91 => (incremental, e_relative) = (true, true),
                20 => inch = true,
                21 => inch = false,
                92 => return Err(at("G92 (a position set by the program) is not supported".into())),
                _ => {}
            }
        }
        for w in ws.iter().filter(|w| w.letter == 'M') {
            match w.value as i64 {
                82 => e_relative = false,
                83 => e_relative = true,
                _ => {}
            }
        }
        let e_before = e_abs;
        if let Some(e) = ws.iter().find(|w| w.letter == 'E') {
            e_abs = if e_relative { e_abs.map(|a| a + e.value) } else { Some(e.value) };
        }
        let named: Vec<&Word> = ws.iter().filter(|w| AXES[..axes].contains(&w.letter)).collect();
        let centre_words: Vec<&Word> = ws.iter().filter(|w| "IJKR".contains(w.letter)).collect();
        let arc = motion >= 2 && (!named.is_empty() || !centre_words.is_empty());
        if named.is_empty() && !arc {
            continue;
        }
        if !centre_words.is_empty() && !arc {
            return Err(at(format!("'{}' outside an arc (G{motion})", centre_words[0].letter)));
        }
        let start = pos;
        for w in &named {
            let a = AXES.iter().position(|c| *c == w.letter).expect("axis");
            let v = if a < 3 && inch { w.value * 25.4 } else { w.value };
            pos[a] = Some(match (incremental, pos[a]) {
                (false, _) => v,
                (true, Some(p)) => p + v,
                (true, None) => {
                    return Err(at(format!(
                        "an incremental (G91) move of {} before its position is known",
                        w.letter
                    )))
                }
            });
        }
        let Some(target) = pos.iter().copied().collect::<Option<Vec<f64>>>() else {
            let missing: String = AXES[..axes]
                .iter()
                .zip(&pos)
                .filter(|(_, p)| p.is_none())
                .map(|(c, _)| *c)
                .collect();
            return Err(at(format!("the first move must give every axis ({missing} unknown)")));
        };
        let end = [target[0], target[1], target[2], target[3], target[4]];
        let (points, sagitta) = if arc {
            let Some(start) = start.iter().copied().collect::<Option<Vec<f64>>>() else {
                return Err(at(format!("an arc (G{motion}) before the position is known")));
            };
            let start = [start[0], start[1], start[2], start[3], start[4]];
            if let Some(p) = ws.iter().find(|w| w.letter == 'P').filter(|p| p.value != 1.0) {
                return Err(at(format!("an arc (G{motion}) of P{} turns is not supported", p.text)));
            }
            let unit = if inch { 25.4 } else { 1.0 };
            let word = |c: char| ws.iter().find(|w| w.letter == c).map(|w| w.value * unit);
            let centre = match word('R') {
                Some(r) => Centre::Radius(r),
                None => Centre::Offsets([word('I').unwrap_or(0.0), word('J').unwrap_or(0.0), word('K').unwrap_or(0.0)]),
            };
            let chords = linearise(&start, &end, plane, motion == 2, centre, arc_tolerance)
                .map_err(|m| at(format!("an arc (G{motion}, G{plane}): {m}")))?;
            (chords.points, chords.sagitta)
        } else {
            (vec![(end, 1.0)], 0.0)
        };
        let text_line = &text[r.clone()];
        blocks.push(Block {
            line,
            words: ws.clone(),
            points,
            motion,
            arc,
            sagitta,
            incremental,
            inch,
            e_relative,
            e_before,
            indent: text_line[..text_line.len() - text_line.trim_start().len()].to_string(),
        });
    }
    Ok(blocks)
}

/// Filter a G-code program.
pub fn filter_gcode(path: &Path, text: &str, models: &FilterModels, opts: &FilterOptions) -> Result<FilteredProgram, FilterError> {
    let task = models.task();
    let axes = match task {
        Task::Position => 3,
        Task::PositionAndAxis => 5,
        other => {
            return Err(FilterError::Models(format!(
                "G-code is filtered for machines that command their tool position, or position and tool axis; this one commands {other:?}"
            )))
        }
    };
    let tolerance = opts.max_deviation_mm.unwrap_or(super::DEFAULT_ARC_TOLERANCE_MM);
    let blocks = parse(text, axes, tolerance / 2.0).map_err(FilterError::parse_at(path))?;
    let mut targets: Vec<Target> = Vec::new();
    let mut located: Vec<(std::path::PathBuf, usize, String)> = Vec::new();
    for b in &blocks {
        for (p, _) in &b.points {
            targets.push(Target {
                pose: pose_of(p),
                tool: opts.tool,
                configuration: None,
                seed: None,
            });
            let name = if b.arc { "arc point" } else { "move" };
            located.push((path.to_path_buf(), b.line, name.to_string()));
        }
    }
    let super::Located {
        corrected,
        reports,
        uncorrected,
    } = correct_located(models, &targets, &located, opts.force)?;
    // The path of each straight move; the points added to hold the tolerance.
    let (cal, nom) = models.with_tool(&opts.tool);
    let starts = crate::compensate::fixed_starts(&models.inputs, crate::compensate::COMPENSATION_STARTS);
    let mover = MovePath {
        models,
        cal: &*cal,
        nom: &*nom,
        tool: opts.tool,
        interp: &axis_lerp,
        starts: &starts,
    };
    let mut report = PathReport::default();
    let mut written: Vec<Vec<([f64; 5], f64)>> = Vec::with_capacity(blocks.len());
    let mut previous: Option<PathPoint> = None;
    let mut flat = corrected.iter().zip(&targets);
    for b in &blocks {
        if b.arc {
            report.arcs += 1;
            report.arc_chords += b.points.len();
            report.largest_chord_error_mm = report.largest_chord_error_mm.max(b.sagitta);
        }
        let mut out = Vec::new();
        let mut from = 0.0;
        for (p, f) in &b.points {
            let (c, t) = flat.next().expect("one correction per point");
            let Some(c) = c else {
                out.push((*p, *f));
                previous = None;
                from = *f;
                continue;
            };
            let here = PathPoint {
                original: t.pose,
                corrected: c.clone(),
                fraction: *f,
            };
            if let (Some(a), true) = (&previous, b.motion >= 1) {
                let a = PathPoint {
                    fraction: from,
                    ..a.clone()
                };
                let fail = |message: String| FilterError::Target {
                    path: path.to_path_buf(),
                    line: b.line,
                    message,
                };
                let (added, worst) = match opts.max_deviation_mm {
                    Some(d) => mover.split(&a, &here, d - b.sagitta).map_err(fail)?,
                    None => match mover.deviation(&a, &here) {
                        Ok(d) => (Vec::new(), d),
                        Err(_) => {
                            report.unjudged += 1;
                            (Vec::new(), -1.0)
                        }
                    },
                };
                report.moves += usize::from(worst >= 0.0);
                if worst > report.largest_deviation_mm {
                    report.largest_deviation_mm = worst;
                    report.largest_deviation_line = b.line;
                }
                report.added_points += added.len();
                out.extend(added.iter().map(|x| (coords_of(&x.corrected.pose), x.fraction)));
            }
            let mut v = coords_of(&c.pose);
            if axes == 3 {
                v[3] = p[3];
                v[4] = p[4];
            }
            out.push((v, *f));
            previous = Some(here);
            from = *f;
        }
        written.push(out);
    }
    let edits = write(text, &blocks, &written, axes);
    Ok(FilteredProgram {
        text: apply(text, &edits),
        companion: None,
        format: Format::Gcode,
        targets: reports,
        uncorrected,
        notes: Vec::new(),
        paths: Some(report),
    })
}

/// The edits that write each block's points: the first on the block's own line, the others on
/// lines of their own after it.
fn write(text: &str, blocks: &[Block], written: &[Vec<([f64; 5], f64)>], axes: usize) -> Vec<Edit> {
    let eol = if text.contains("\r\n") { "\r\n" } else { "\n" };
    let ranges = super::csv::line_ranges(text);
    let mut edits: Vec<Edit> = Vec::new();
    let mut previous: Option<[f64; 5]> = None;
    for (b, points) in blocks.iter().zip(written) {
        let unit = |a: usize| if a < 3 && b.inch { 25.4 } else { 1.0 };
        // 0.001 mm, 0.0001 inch, 0.0001 degree.
        let min_dec = |a: usize| if a >= 3 || b.inch { 4 } else { 3 };
        let value = |a: usize, new: &[f64; 5], prev: Option<[f64; 5]>| match (b.incremental, prev) {
            (true, Some(p)) => (new[a] - p[a]) / unit(a),
            _ => new[a] / unit(a),
        };
        let axis_words: Vec<&Word> = b.words.iter().filter(|w| AXES[..axes].contains(&w.letter)).collect();
        let dec = axis_words.iter().map(|w| decimals(&w.text)).max().unwrap_or(3);
        let first = points[0].0;
        // The first point on the block's line: its axis words, and those it does not name.
        for w in &axis_words {
            let a = AXES.iter().position(|c| *c == w.letter).expect("axis");
            edits.extend(number_edit(&w.text, w.range.clone(), value(a, &first, previous), min_dec(a)));
        }
        let mut added = String::new();
        for a in 0..axes {
            if b.words.iter().any(|w| w.letter == AXES[a]) {
                continue;
            }
            let was = match (b.incremental, previous) {
                (true, _) => 0.0,
                (false, Some(p)) => p[a] / unit(a),
                (false, None) => b.points[0].0[a] / unit(a),
            };
            let now = value(a, &first, previous);
            let d = dec.max(min_dec(a));
            if format_fixed(now, d) != format_fixed(was, d) {
                added.push_str(&format!(" {}{}", AXES[a], format_fixed(now, d)));
            }
        }
        let centre: Vec<&Word> = b.words.iter().filter(|w| b.arc && "IJKRP".contains(w.letter)).collect();
        if b.arc {
            // G2/G3 → G1 (or G1 written where the arc was modal).
            match b.words.iter().find(|w| w.letter == 'G' && (w.value == 2.0 || w.value == 3.0)) {
                Some(g) => edits.push(Edit {
                    range: g.range.clone(),
                    text: if g.text.starts_with('0') { "01" } else { "1" }.into(),
                }),
                None => {
                    let at = b.words.iter().find(|w| w.letter != 'N').map_or(b.words[0].start, |w| w.start);
                    edits.push(Edit {
                        range: at..at,
                        text: "G1 ".into(),
                    });
                }
            }
        }
        if !added.is_empty() {
            let at = match axis_words.last() {
                Some(w) => w.range.end,
                None => centre.first().map_or(b.words.last().expect("a word").range.end, |w| w.start),
            };
            let text = if axis_words.is_empty() {
                format!("{} ", added.trim_start())
            } else {
                added
            };
            edits.push(Edit { range: at..at, text });
        }
        for w in &centre {
            let line_end = ranges[b.line - 1].end;
            let rest = &text[w.range.end..line_end];
            let spaces = rest.len() - rest.trim_start_matches([' ', '\t']).len();
            edits.push(Edit {
                range: w.start..w.range.end + spaces,
                text: String::new(),
            });
        }
        // The extrusion shared along the block's pieces.
        let e_word = b.words.iter().find(|w| w.letter == 'E');
        let e_at = |f: f64, f0: f64| -> Option<f64> {
            let e = e_word?;
            Some(if b.e_relative {
                e.value * (f - f0)
            } else {
                b.e_before.map_or(e.value, |e0| e0 + (e.value - e0) * f)
            })
        };
        if points.len() > 1 {
            if let (Some(e), Some(v)) = (e_word, e_at(points[0].1, 0.0)) {
                edits.extend(number_edit(&e.text, e.range.clone(), v, decimals(&e.text).max(5)));
            }
        }
        previous = Some(first);
        let mut tail = String::new();
        for k in 1..points.len() {
            let p = points[k].0;
            tail.push_str(eol);
            tail.push_str(&b.indent);
            tail.push_str("G1");
            for (a, letter) in AXES.iter().enumerate().take(axes) {
                tail.push_str(&format!(" {letter}{}", format_fixed(value(a, &p, previous), dec.max(min_dec(a)))));
            }
            if let (Some(e), Some(v)) = (e_word, e_at(points[k].1, points[k - 1].1)) {
                tail.push_str(&format!(" E{}", format_fixed(v, decimals(&e.text).max(5))));
            }
            previous = Some(p);
        }
        if !tail.is_empty() {
            let end = ranges[b.line - 1].end;
            edits.push(Edit {
                range: end..end,
                text: tail,
            });
        }
    }
    edits
}
