//! URScript (`.script`, `.urscript`): pose literals `p[x, y, z, rx, ry, rz]` (metres, rotation
//! vector in radians, in the robot's base frame) as the targets of `movel`, `movej`, `movep` and
//! `movec` (its via and end points), directly or through a variable assigned a pose literal
//! (`wp1 = p[…]`, the assignment before the move). The tool is the last `set_tcp(p[…])` before the
//! move (the flange before any). The controller chooses the joint solution nearest where the arm
//! is, so the branch is the previous target's, or that of the joint list of a `movej([…])` before
//! it (radians).
//!
//! Written back: the pose literal's numbers (at least 1e-6 m and 1e-7 rad; the rotation vector
//! of the turn nearest the one written). Left as they are, with a note: joint lists
//! (`movej([…])`), poses computed at run time (`pose_trans(…)`), literals no move uses. A
//! variable's pose used by moves with different tools is refused (it takes one correction).
use super::lex::{lex, value, Kind, Tok, Value};
use super::rewrite::{apply, number_edit, Edit};
use super::{correct_located, FilterError, FilterModels, FilterOptions, FilteredProgram, Format, Target};
use crate::se3::{self, Pose};
use nalgebra::Vector3;
use std::collections::HashMap;
use std::path::Path;

/// A pose literal `p[…]`: its pose (mm), its rotation vector as written and its number tokens.
#[derive(Debug, Clone)]
struct Literal {
    pose: Pose,
    rotvec: Vector3<f64>,
    numbers: Vec<(String, std::ops::Range<usize>)>,
    line: usize,
}

fn literal(v: &Value) -> Result<Literal, (usize, String)> {
    let line = v.line();
    let Value::List(items, _) = v else {
        return Err((line, "a pose literal: expected p[x, y, z, rx, ry, rz]".into()));
    };
    let mut x = Vec::new();
    let mut numbers = Vec::new();
    for it in items {
        match it {
            Value::Num { value, text, range, .. } => {
                x.push(*value);
                numbers.push((text.clone(), range.clone()));
            }
            other => return Err((other.line(), "a pose literal holds six numbers: p[x, y, z, rx, ry, rz]".into())),
        }
    }
    if x.len() != 6 {
        return Err((
            line,
            format!("a pose literal holds six numbers: p[x, y, z, rx, ry, rz], found {}", x.len()),
        ));
    }
    let rotvec = Vector3::new(x[3], x[4], x[5]);
    Ok(Literal {
        pose: se3::pose_from_parts(Vector3::new(x[0], x[1], x[2]) * 1000.0, rotvec),
        rotvec,
        numbers,
        line,
    })
}

/// The pose literal at `toks[i]` (`p` followed by `[`), and the index after it.
fn literal_at(text: &str, toks: &[Tok], i: usize) -> Option<Result<(Literal, usize), (usize, String)>> {
    let is_p = toks.get(i).is_some_and(|t| t.kind == Kind::Ident && &text[t.range.clone()] == "p");
    if !is_p || !toks.get(i + 1).is_some_and(|t| t.is(b'[')) {
        return None;
    }
    let mut j = i + 1;
    Some(value(text, toks, &mut j).and_then(|v| literal(&v)).map(|l| (l, j)))
}

/// The rotation vector of `r` nearest `near` (the same rotation, whole turns about its axis).
fn rotvec_near(r: &nalgebra::UnitQuaternion<f64>, near: &Vector3<f64>) -> Vector3<f64> {
    let v = se3::so3_log(r);
    let angle = v.norm();
    if angle < 1e-12 {
        return v;
    }
    let axis = v / angle;
    (-2..=2)
        .map(|k| axis * (angle + k as f64 * std::f64::consts::TAU))
        .min_by(|a, b| (a - near).norm().total_cmp(&(b - near).norm()))
        .unwrap_or(v)
}

/// Filter a URScript program.
pub fn filter_urscript(path: &Path, text: &str, models: &FilterModels, opts: &FilterOptions) -> Result<FilteredProgram, FilterError> {
    let parse_err = FilterError::parse_at(path);
    let toks = lex(text, b'#').map_err(parse_err)?;
    let src = |t: &Tok| &text[t.range.clone()];
    let mut tcp = Pose::identity();
    // Variables: name → (literal index, tool it was first used with).
    let mut vars: HashMap<String, usize> = HashMap::new();
    let mut literals: Vec<Literal> = Vec::new();
    let mut used: Vec<Option<(Pose, usize)>> = Vec::new();
    let mut order: Vec<usize> = Vec::new();
    // The joint values of the last joint move, starting the next target's inverse.
    let mut joints: Option<Vec<f64>> = None;
    let mut seeds: Vec<Option<Vec<f64>>> = Vec::new();
    let mut notes = Vec::new();
    // --joints: the corrected joint lists.
    let (mut joint_edits, mut joint_uncorrected): (Vec<Edit>, Vec<String>) = (Vec::new(), Vec::new());
    let note = |notes: &mut Vec<String>, line: usize, what: &str| notes.push(format!("{}:{line}: {what} is left as it is", path.display()));
    let mut i = 0;
    while i < toks.len() {
        let t = &toks[i];
        let word = if t.kind == Kind::Ident { src(t) } else { "" };
        // name = p[…]
        if t.kind == Kind::Ident && toks.get(i + 1).is_some_and(|x| x.is(b'=')) && !toks.get(i + 2).is_some_and(|x| x.is(b'=')) {
            if let Some(r) = literal_at(text, &toks, i + 2) {
                let (lit, next) = r.map_err(parse_err)?;
                vars.insert(word.to_string(), literals.len());
                literals.push(lit);
                used.push(None);
                i = next;
                continue;
            }
        }
        let is_call = toks.get(i + 1).is_some_and(|x| x.is(b'('));
        if word == "set_tcp" && is_call {
            tcp = match literal_at(text, &toks, i + 2) {
                Some(r) => r.map_err(parse_err)?.0.pose,
                None => match toks.get(i + 2) {
                    Some(v) if v.kind == Kind::Ident && vars.contains_key(src(v)) => literals[vars[src(v)]].pose,
                    _ => {
                        return Err(parse_err((
                            t.line,
                            "set_tcp: expected a pose literal p[…] or a variable assigned one".into(),
                        )))
                    }
                },
            };
            i += 2;
            continue;
        }
        let targets = match word {
            "movel" | "movej" | "movep" => 1,
            "movec" => 2,
            _ => 0,
        };
        if targets > 0 && is_call {
            let mut j = i + 2;
            for k in 0..targets {
                if let Some(r) = literal_at(text, &toks, j) {
                    let (lit, next) = r.map_err(parse_err)?;
                    used.push(Some((tcp, lit.line)));
                    order.push(literals.len());
                    seeds.push(joints.take());
                    literals.push(lit);
                    j = next;
                } else if let Some(v) = toks
                    .get(j)
                    .filter(|v| v.kind == Kind::Ident && vars.contains_key(src(v)) && !toks.get(j + 1).is_some_and(|x| x.is(b'(')))
                {
                    let idx = vars[src(v)];
                    match used[idx] {
                        Some((tool, line)) if tool != tcp => {
                            return Err(parse_err((
                                v.line,
                                format!(
                                    "{} is moved to with another tool (set_tcp) than on line {line}: a pose variable takes one correction",
                                    src(v)
                                ),
                            )))
                        }
                        Some(_) => {}
                        None => {
                            used[idx] = Some((tcp, v.line));
                            order.push(idx);
                            seeds.push(joints.take());
                        }
                    }
                    j += 1;
                } else if toks.get(j).is_some_and(|x| x.is(b'[')) {
                    let mut e = j;
                    let v = value(text, &toks, &mut e).map_err(parse_err)?;
                    let mut corrected_joints = false;
                    if let Value::List(items, _) = &v {
                        let nums: Vec<(&String, &std::ops::Range<usize>, f64)> = items
                            .iter()
                            .filter_map(|x| {
                                if let Value::Num { value, text, range, .. } = x {
                                    Some((text, range, *value))
                                } else {
                                    None
                                }
                            })
                            .collect();
                        let q: Vec<f64> = nums.iter().map(|n| n.2).collect();
                        if q.len() == models.inputs.len() {
                            if opts.joints {
                                match super::correct_joints(models, &q, &tcp) {
                                    Ok((new, _)) => {
                                        for ((text, range, _), v) in nums.iter().zip(&new) {
                                            joint_edits.extend(number_edit(text, (*range).clone(), *v, 7));
                                        }
                                        corrected_joints = true;
                                    }
                                    Err(m) if opts.force => {
                                        joint_uncorrected.push(format!("{}:{}: joint list: {m}", path.display(), t.line))
                                    }
                                    Err(m) => return Err(parse_err((t.line, format!("joint list: {m}")))),
                                }
                            }
                            joints = Some(q);
                        }
                    }
                    if !corrected_joints {
                        note(&mut notes, t.line, "a joint target");
                    }
                    break;
                } else {
                    let what = "a target computed at run time";
                    note(&mut notes, t.line, what);
                    break;
                }
                if k + 1 < targets {
                    if !toks.get(j).is_some_and(|x| x.is(b',')) {
                        return Err(parse_err((t.line, format!("{word}: expected two poses (via and end point)"))));
                    }
                    j += 1;
                }
            }
            i = j;
            continue;
        }
        i += 1;
    }
    for (k, l) in literals.iter().enumerate() {
        if used[k].is_none() {
            note(&mut notes, l.line, "a pose literal no move uses");
        }
    }
    let targets: Vec<Target> = order
        .iter()
        .zip(seeds)
        .map(|(&k, seed)| Target {
            pose: literals[k].pose,
            tool: used[k].expect("used").0,
            configuration: None,
            seed,
        })
        .collect();
    let located: Vec<(std::path::PathBuf, usize, String)> = order
        .iter()
        .map(|&k| (path.to_path_buf(), literals[k].line, "pose".to_string()))
        .collect();
    let super::Located {
        corrected,
        reports,
        uncorrected,
    } = correct_located(models, &targets, &located, opts.force)?;
    let mut uncorrected = uncorrected;
    uncorrected.extend(joint_uncorrected);
    let mut edits: Vec<Edit> = joint_edits;
    for (c, &k) in corrected.iter().zip(&order) {
        let Some(c) = c else { continue };
        let l = &literals[k];
        let p = c.pose.translation.vector / 1000.0;
        let r = rotvec_near(&c.pose.rotation, &l.rotvec);
        for (k, ((text, range), v)) in l.numbers.iter().zip([p.x, p.y, p.z, r.x, r.y, r.z]).enumerate() {
            edits.extend(number_edit(text, range.clone(), v, if k < 3 { 6 } else { 7 }));
        }
    }
    Ok(FilteredProgram {
        text: apply(text, &edits),
        companion: None,
        format: Format::UrScript,
        targets: reports,
        uncorrected,
        notes,
        paths: None,
    })
}
