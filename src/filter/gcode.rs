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
//! written. Refused with a line: arcs (`G2`, `G3`), an incremental move before the position is
//! known, `G92`.
use super::rewrite::{apply, decimals, format_fixed, number_edit, Edit};
use super::{correct_located, FilterError, FilterModels, FilterOptions, FilteredProgram, Format, Target};
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
                    range: start + ns..start + j,
                });
                i = j;
            }
            _ => return Err(format!("unexpected '{}'", line[i..].chars().next().unwrap_or(' '))),
        }
    }
    Ok(out)
}

/// A motion block: its line, words, and the absolute nominal target (mm, deg) it reaches.
struct Block {
    line: usize,
    words: Vec<Word>,
    target: [f64; 5],
    incremental: bool,
    inch: bool,
}

const AXES: [char; 5] = ['X', 'Y', 'Z', 'A', 'B'];

/// Filter a G-code program.
pub fn filter_gcode(path: &Path, text: &str, models: &FilterModels, opts: &FilterOptions) -> Result<FilteredProgram, FilterError> {
    let at = |line: usize, message: String| FilterError::Parse {
        path: path.to_path_buf(),
        line,
        message,
    };
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
    let ranges = super::csv::line_ranges(text);
    let (mut motion, mut incremental, mut inch) = (0u8, false, false);
    let mut pos: [Option<f64>; 5] = [None; 5];
    if axes == 3 {
        pos[3] = Some(0.0);
        pos[4] = Some(0.0);
    }
    let mut blocks: Vec<Block> = Vec::new();
    for (k, r) in ranges.iter().enumerate() {
        let line = k + 1;
        let ws = words(&text[r.clone()], r.start).map_err(|m| at(line, m))?;
        for w in ws.iter().filter(|w| w.letter == 'G' && w.value.fract() == 0.0) {
            match w.value as i64 {
                v @ 0..=3 => motion = v as u8,
                90 => incremental = false,
                91 => incremental = true,
                20 => inch = true,
                21 => inch = false,
                92 => return Err(at(line, "G92 (a position set by the program) is not supported".into())),
                _ => {}
            }
        }
        let named: Vec<&Word> = ws.iter().filter(|w| AXES[..axes].contains(&w.letter)).collect();
        if named.is_empty() {
            continue;
        }
        if ws.iter().any(|w| "IJKR".contains(w.letter)) || motion >= 2 {
            return Err(at(
                line,
                format!("an arc (G{motion}) is not corrected: linearise it into G1 moves first"),
            ));
        }
        for w in &named {
            let a = AXES.iter().position(|c| *c == w.letter).expect("axis");
            let v = if a < 3 && inch { w.value * 25.4 } else { w.value };
            pos[a] = Some(match (incremental, pos[a]) {
                (false, _) => v,
                (true, Some(p)) => p + v,
                (true, None) => {
                    return Err(at(
                        line,
                        format!("an incremental (G91) move of {} before its position is known", w.letter),
                    ))
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
            return Err(at(line, format!("the first move must give every axis ({missing} unknown)")));
        };
        blocks.push(Block {
            line,
            words: ws.clone(),
            target: [target[0], target[1], target[2], target[3], target[4]],
            incremental,
            inch,
        });
    }
    let pose = |t: &[f64; 5]| {
        Pose::from_parts(
            Translation3::new(t[0], t[1], t[2]),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), t[3].to_radians())
                * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), t[4].to_radians()),
        )
    };
    let targets: Vec<Target> = blocks
        .iter()
        .map(|b| Target {
            pose: pose(&b.target),
            tool: opts.tool,
            configuration: None,
            seed: None,
        })
        .collect();
    let located: Vec<(std::path::PathBuf, usize, String)> =
        blocks.iter().map(|b| (path.to_path_buf(), b.line, "move".to_string())).collect();
    let super::Located {
        corrected,
        reports,
        uncorrected,
    } = correct_located(models, &targets, &located, opts.force)?;
    let mut edits: Vec<Edit> = Vec::new();
    let mut previous: Option<[f64; 5]> = None;
    for (b, c) in blocks.iter().zip(&corrected) {
        let new = match c {
            Some(c) => {
                let p = c.pose.translation.vector;
                let e = crate::se3::euler_xyz(&c.pose.rotation.to_rotation_matrix().into_inner());
                let mut v = [p.x, p.y, p.z, e[0].to_degrees(), e[1].to_degrees()];
                if axes == 3 {
                    v[3] = b.target[3];
                    v[4] = b.target[4];
                }
                v
            }
            None => b.target,
        };
        let unit = |a: usize| if a < 3 && b.inch { 25.4 } else { 1.0 };
        // 0.001 mm, 0.0001 inch, 0.0001 degree.
        let min_dec = |a: usize| if a >= 3 || b.inch { 4 } else { 3 };
        let written = |a: usize| match (b.incremental, previous) {
            (true, Some(p)) => (new[a] - p[a]) / unit(a),
            _ => new[a] / unit(a),
        };
        let mut last_axis: Option<&Word> = None;
        let mut dec = 3;
        for w in b.words.iter().filter(|w| AXES[..axes].contains(&w.letter)) {
            let a = AXES.iter().position(|c| *c == w.letter).expect("axis");
            edits.extend(number_edit(&w.text, w.range.clone(), written(a), min_dec(a)));
            last_axis = Some(w);
            dec = decimals(&w.text).max(min_dec(a));
        }
        // Axes the block does not name, where the correction moves them.
        let mut added = String::new();
        for a in 0..axes {
            if b.words.iter().any(|w| w.letter == AXES[a]) {
                continue;
            }
            let was = match (b.incremental, previous) {
                (true, _) => 0.0,
                (false, Some(p)) => p[a] / unit(a),
                (false, None) => b.target[a] / unit(a),
            };
            let now = written(a);
            let d = dec.max(min_dec(a));
            if format_fixed(now, d) != format_fixed(was, d) {
                added.push_str(&format!(" {}{}", AXES[a], format_fixed(now, d)));
            }
        }
        if let (Some(w), false) = (last_axis, added.is_empty()) {
            edits.push(Edit {
                range: w.range.end..w.range.end,
                text: added,
            });
        }
        previous = Some(new);
    }
    Ok(FilteredProgram {
        text: apply(text, &edits),
        companion: None,
        format: Format::Gcode,
        targets: reports,
        uncorrected,
        notes: Vec::new(),
    })
}
