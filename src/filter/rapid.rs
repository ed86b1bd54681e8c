//! ABB RAPID modules: `robtarget` declarations and inline robtargets of `MoveL`, `MoveJ`,
//! `MoveC` and their variants (`MoveLDO`, `MoveJSync`, `MoveCAO`, …).
//!
//! A robtarget `[[x, y, z], [q1, q2, q3, q4], [cf1, cf4, cf6, cfx], [eax_a, …, eax_f]]` is the
//! tool pose in the move's work object (mm, quaternion w first), the arm configuration
//! ([`super::branch`]) and the external axes. A move's tool (its fourth argument, the fifth for
//! `MoveC`) and work object (`\WObj:=`) are `tooldata` and `wobjdata` declared in the module,
//! or `tool0` (the flange) and `wobj0` (the base frame): the target in the base frame is
//! `uframe · oframe · T` with the tool's `tframe` on the flange.
//!
//! Written back: the position (at least 0.001 mm), the quaternion (at least 7 decimals, the sign
//! of the original kept) and the configuration numbers that change; the external axes and every
//! other byte stay. A declared robtarget used by several moves must be used with one tool and
//! one work object (it takes one correction). Left as they are, with a note: joint targets
//! (`MoveAbsJ`), targets computed at run time (`Offs(p10, …)`, `RelTool`, `CRobT()`), arrays of
//! robtargets, and declarations no move uses. Refused: a stationary tool (`robhold` FALSE), a
//! work object held by the robot or moved by a mechanical unit.
use super::branch::{ArmConfiguration, Configuration};
use super::lex::{lex, value, Kind, Tok, Value};
use super::rewrite::{apply, number_edit, Edit};
use super::{correct_located, FilterError, FilterModels, FilterOptions, FilteredProgram, Format, Target};
use crate::se3::Pose;
use nalgebra::{Quaternion, Translation3, UnitQuaternion};
use std::collections::HashMap;
use std::path::Path;

/// A declaration `CONST|PERS|VAR type name := value;`.
#[derive(Debug, Clone)]
struct Decl {
    name: String,
    value: Value,
    line: usize,
}

/// A robtarget read: its pose (in its work object), configuration, and the number tokens.
#[derive(Debug, Clone)]
struct RobTarget {
    pose: Pose,
    conf: ArmConfiguration,
    /// Position, quaternion (w first) and configuration numbers: (text, range, value).
    numbers: Numbers,
    quaternion: Quaternion<f64>,
}

/// One use of a target by a move.
#[derive(Debug, Clone)]
struct Use {
    tool: String,
    wobj: String,
    line: usize,
}

type Located<T> = Result<T, (usize, String)>;
/// Number tokens: text, range, value.
type Numbers = Vec<(String, std::ops::Range<usize>, f64)>;
/// A pose read, its number tokens and its quaternion as written.
type PoseRead = (Pose, Numbers, Quaternion<f64>);

/// A move's targets (a literal, or a declared name), tool, work object and line.
struct Move {
    targets: Vec<Result<Value, String>>,
    tool: String,
    wobj: String,
    line: usize,
}

fn nums(v: &Value, n: usize, what: &str) -> Located<Numbers> {
    match v {
        Value::List(items, line) if items.len() == n => items
            .iter()
            .map(|x| match x {
                Value::Num { value, text, range, .. } => Ok((text.clone(), range.clone(), *value)),
                other => Err((other.line(), format!("{what}: expected {n} numbers"))),
            })
            .collect(),
        other => Err((other.line(), format!("{what}: expected [{}]", vec!["…"; n].join(", ")))),
    }
}

/// A pose `[[x, y, z], [q1, q2, q3, q4]]` and its number tokens.
fn pose(v: &Value, what: &str) -> Located<PoseRead> {
    let Value::List(items, line) = v else {
        return Err((v.line(), format!("{what}: expected [[x, y, z], [q1, q2, q3, q4]]")));
    };
    if items.len() != 2 {
        return Err((*line, format!("{what}: expected [[x, y, z], [q1, q2, q3, q4]]")));
    }
    let p = nums(&items[0], 3, &format!("{what}: the position"))?;
    let q = nums(&items[1], 4, &format!("{what}: the quaternion"))?;
    let quat = Quaternion::new(q[0].2, q[1].2, q[2].2, q[3].2);
    let norm = quat.norm();
    if !norm.is_finite() || (norm - 1.0).abs() > 1e-3 {
        return Err((
            items[1].line(),
            format!(
                "{what}: [{}] is not a unit quaternion (norm {norm:.6})",
                q.iter().map(|x| x.0.as_str()).collect::<Vec<_>>().join(",")
            ),
        ));
    }
    let pose = Pose::from_parts(Translation3::new(p[0].2, p[1].2, p[2].2), UnitQuaternion::from_quaternion(quat));
    Ok((pose, p.into_iter().chain(q).collect(), quat))
}

fn robtarget(v: &Value, what: &str) -> Located<RobTarget> {
    let shape = || format!("{what}: expected [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,…,eax_f]]");
    let Value::List(items, line) = v else {
        return Err((v.line(), shape()));
    };
    if items.len() != 4 {
        return Err((*line, shape()));
    }
    let (pose, mut numbers, quaternion) = pose(&Value::List(items[..2].to_vec(), *line), what)?;
    let conf = nums(&items[2], 4, &format!("{what}: the configuration"))?;
    if let Some(c) = conf.iter().find(|c| c.2.fract() != 0.0) {
        return Err((items[2].line(), format!("{what}: configuration value '{}' is not an integer", c.0)));
    }
    nums(&items[3], 6, &format!("{what}: the external axes"))?;
    let c = |k: usize| conf[k].2 as i32;
    let conf_data = ArmConfiguration {
        cf1: c(0),
        cf4: c(1),
        cf6: c(2),
        cfx: c(3),
    };
    numbers.extend(conf);
    Ok(RobTarget {
        pose,
        conf: conf_data,
        numbers,
        quaternion,
    })
}

fn atom<'a>(v: &'a Value, what: &str) -> Located<&'a str> {
    match v {
        Value::Atom(a, _) => Ok(a),
        other => Err((other.line(), format!("{what}: expected a name or string"))),
    }
}

/// A tooldata's `tframe` (the tool in the flange frame).
fn tooldata(d: &Decl) -> Located<Pose> {
    let what = format!("tooldata {}", d.name);
    let Value::List(items, line) = &d.value else {
        return Err((d.line, format!("{what}: expected [robhold, tframe, tload]")));
    };
    if items.len() != 3 {
        return Err((*line, format!("{what}: expected [robhold, tframe, tload]")));
    }
    if !atom(&items[0], &what)?.eq_ignore_ascii_case("TRUE") {
        return Err((*line, format!("{what}: a stationary tool (robhold FALSE) is not supported")));
    }
    Ok(pose(&items[1], &format!("{what}: tframe"))?.0)
}

/// A wobjdata's `uframe · oframe` (the work object in the base frame).
fn wobjdata(d: &Decl) -> Located<Pose> {
    let what = format!("wobjdata {}", d.name);
    let Value::List(items, line) = &d.value else {
        return Err((d.line, format!("{what}: expected [robhold, ufprog, ufmec, uframe, oframe]")));
    };
    if items.len() != 5 {
        return Err((*line, format!("{what}: expected [robhold, ufprog, ufmec, uframe, oframe]")));
    }
    if !atom(&items[0], &what)?.eq_ignore_ascii_case("FALSE") {
        return Err((
            *line,
            format!("{what}: a work object held by the robot (robhold TRUE) is not supported"),
        ));
    }
    let ufmec = atom(&items[2], &what)?;
    if !atom(&items[1], &what)?.eq_ignore_ascii_case("TRUE") || !ufmec.trim_matches('"').is_empty() {
        return Err((*line, format!("{what}: a user frame moved by a mechanical unit is not supported")));
    }
    let u = pose(&items[3], &format!("{what}: uframe"))?.0;
    let o = pose(&items[4], &format!("{what}: oframe"))?.0;
    Ok(u * o)
}

/// Whether an instruction is a Cartesian move: `Move{L,J,C}` with an optional `DO`, `AO`, `GO`
/// or `Sync`.
fn move_targets(name: &str) -> Option<usize> {
    let n = name.to_ascii_lowercase();
    let rest = n.strip_prefix("move")?;
    let (kind, suffix) = rest.split_at(rest.len().min(1));
    if !["", "do", "ao", "go", "sync"].contains(&suffix) {
        return None;
    }
    match kind {
        "l" | "j" => Some(1),
        "c" => Some(2),
        _ => None,
    }
}

/// Arguments of an instruction split at top-level commas.
fn split_args(toks: &[Tok]) -> Vec<&[Tok]> {
    let mut out = Vec::new();
    let (mut depth, mut start) = (0i32, 0);
    for (k, t) in toks.iter().enumerate() {
        match t.kind {
            Kind::Punct(b'[' | b'(' | b'{') => depth += 1,
            Kind::Punct(b']' | b')' | b'}') => depth -= 1,
            Kind::Punct(b',') if depth == 0 => {
                out.push(&toks[start..k]);
                start = k + 1;
            }
            _ => {}
        }
    }
    out.push(&toks[start..]);
    out
}

/// An argument's value before its first top-level `\`, and its optional arguments
/// (`\Name:=value`, lower-case name → value tokens).
fn split_optional(arg: &[Tok]) -> (&[Tok], Vec<(usize, usize)>) {
    let mut depth = 0i32;
    let mut cuts = Vec::new();
    for (k, t) in arg.iter().enumerate() {
        match t.kind {
            Kind::Punct(b'[' | b'(' | b'{') => depth += 1,
            Kind::Punct(b']' | b')' | b'}') => depth -= 1,
            Kind::Punct(b'\\') if depth == 0 => cuts.push(k),
            _ => {}
        }
    }
    let base = &arg[..cuts.first().copied().unwrap_or(arg.len())];
    let spans = cuts
        .iter()
        .enumerate()
        .map(|(i, &c)| (c, cuts.get(i + 1).copied().unwrap_or(arg.len())))
        .collect();
    (base, spans)
}

/// Filter a RAPID module.
pub fn filter_rapid(path: &Path, text: &str, models: &FilterModels, opts: &FilterOptions) -> Result<FilteredProgram, FilterError> {
    let parse_err = FilterError::parse_at(path);
    let toks = lex(text, b'!').map_err(parse_err)?;
    let src = |t: &Tok| &text[t.range.clone()];
    let mut decls: HashMap<(String, String), Decl> = HashMap::new();
    let mut robtarget_order: Vec<String> = Vec::new();
    let mut notes: Vec<String> = Vec::new();
    let mut moves: Vec<Move> = Vec::new();
    let mut i = 0;
    while i < toks.len() {
        let t = &toks[i];
        let word = if t.kind == Kind::Ident {
            src(t).to_ascii_lowercase()
        } else {
            String::new()
        };
        let next_is = |k: usize, c: u8| toks.get(k).is_some_and(|x| x.is(c));
        if ["robtarget", "tooldata", "wobjdata"].contains(&word.as_str()) && toks.get(i + 1).is_some_and(|n| n.kind == Kind::Ident) {
            let name = src(&toks[i + 1]).to_string();
            let line = toks[i + 1].line;
            if next_is(i + 2, b'{') {
                if word == "robtarget" {
                    notes.push(format!("{}:{line}: the robtarget array {name} is left as it is", path.display()));
                }
                while i < toks.len() && !toks[i].is(b';') {
                    i += 1;
                }
                continue;
            }
            if toks.get(i + 2).is_some_and(|n| n.kind == Kind::Assign) {
                let mut j = i + 3;
                let v = value(text, &toks, &mut j).map_err(parse_err)?;
                if !next_is(j, b';') {
                    let l = toks.get(j).map_or(line, |x| x.line);
                    return Err(parse_err((l, format!("{word} {name}: expected ';' after its value"))));
                }
                let key = (word.clone(), name.to_ascii_lowercase());
                if word == "robtarget" {
                    robtarget_order.push(key.1.clone());
                }
                decls.insert(key, Decl { name, value: v, line });
                i = j + 1;
                continue;
            }
            i += 1;
            continue;
        }
        let at_statement = i == 0 || !matches!(toks[i - 1].kind, Kind::Punct(b'.') | Kind::Ident | Kind::Assign);
        if t.kind == Kind::Ident && at_statement && word.starts_with("moveabsj") {
            notes.push(format!("{}:{}: a joint target (MoveAbsJ) is left as it is", path.display(), t.line));
        }
        if let (Some(n), true) = (move_targets(&word), at_statement) {
            let end = (i + 1..toks.len())
                .find(|&k| toks[k].is(b';'))
                .ok_or_else(|| parse_err((t.line, format!("{}: no ';' ends the instruction", src(t)))))?;
            let args = &toks[i + 1..end];
            let mut positional: Vec<&[Tok]> = Vec::new();
            let mut wobj = "wobj0".to_string();
            for a in split_args(args) {
                let (base, optional) = split_optional(a);
                for (s, e) in optional {
                    let o = &a[s..e];
                    if o.get(1).is_some_and(|x| src(x).eq_ignore_ascii_case("WObj")) {
                        match (o.get(2), o.get(3), o.len()) {
                            (Some(x), Some(w), 4) if x.kind == Kind::Assign && w.kind == Kind::Ident => wobj = src(w).to_string(),
                            _ => return Err(parse_err((o[0].line, "\\WObj: expected \\WObj:=name".into()))),
                        }
                    }
                }
                if !base.is_empty() {
                    positional.push(base);
                }
            }
            let tool = match positional.get(n + 2) {
                Some([t]) if t.kind == Kind::Ident => src(t).to_string(),
                _ => {
                    return Err(parse_err((
                        t.line,
                        format!("{}: expected the tool (a tooldata name) as argument {}", src(t), n + 3),
                    )))
                }
            };
            let mut targets = Vec::new();
            for a in positional.iter().take(n) {
                if a.first().is_some_and(|x| x.is(b'[')) {
                    let mut j = 0;
                    let v = value(text, a, &mut j).map_err(parse_err)?;
                    if j != a.len() {
                        return Err(parse_err((a[j].line, format!("unexpected '{}' after a robtarget", src(&a[j])))));
                    }
                    targets.push(Ok(v));
                } else if let [x] = a {
                    if x.kind != Kind::Ident {
                        return Err(parse_err((x.line, format!("'{}' is not a robtarget", src(x)))));
                    }
                    targets.push(Err(src(x).to_ascii_lowercase()));
                } else {
                    notes.push(format!(
                        "{}:{}: a target computed at run time is left as it is",
                        path.display(),
                        a[0].line
                    ));
                }
            }
            moves.push(Move {
                targets,
                tool,
                wobj,
                line: t.line,
            });
            i = end + 1;
            continue;
        }
        i += 1;
    }
    // Tools and work objects.
    let tool_of = |name: &str, line: usize| -> Result<Pose, FilterError> {
        if name.eq_ignore_ascii_case("tool0") {
            return Ok(Pose::identity());
        }
        let d = decls.get(&("tooldata".into(), name.to_ascii_lowercase())).ok_or_else(|| {
            parse_err((
                line,
                format!("unknown tooldata '{name}' (not declared in this module, and not tool0)"),
            ))
        })?;
        tooldata(d).map_err(parse_err)
    };
    let wobj_of = |name: &str, line: usize| -> Result<Pose, FilterError> {
        if name.eq_ignore_ascii_case("wobj0") {
            return Ok(Pose::identity());
        }
        let d = decls.get(&("wobjdata".into(), name.to_ascii_lowercase())).ok_or_else(|| {
            parse_err((
                line,
                format!("unknown wobjdata '{name}' (not declared in this module, and not wobj0)"),
            ))
        })?;
        wobjdata(d).map_err(parse_err)
    };
    // Each target once, in the order the moves first use it.
    let mut uses: HashMap<String, Use> = HashMap::new();
    let mut items: Vec<(RobTarget, Pose, Pose, usize, String)> = Vec::new();
    for Move {
        targets,
        tool: tool_name,
        wobj: wobj_name,
        line,
    } in &moves
    {
        let tool = tool_of(tool_name, *line)?;
        let wobj = wobj_of(wobj_name, *line)?;
        for t in targets {
            match t {
                Ok(v) => items.push((
                    robtarget(v, "inline robtarget").map_err(parse_err)?,
                    tool,
                    wobj,
                    *line,
                    "inline robtarget".into(),
                )),
                Err(name) => {
                    let d = decls
                        .get(&("robtarget".into(), name.clone()))
                        .ok_or_else(|| parse_err((*line, format!("'{name}' is not a robtarget declared in this module"))))?;
                    if let Some(u) = uses.get(name) {
                        if !u.tool.eq_ignore_ascii_case(tool_name) || !u.wobj.eq_ignore_ascii_case(wobj_name) {
                            return Err(parse_err((
                                *line,
                                format!(
                                    "robtarget {} is used with {}\\WObj:={} here and with {}\\WObj:={} on line {}: a declared target takes one correction (declare one per tool and work object)",
                                    d.name, tool_name, wobj_name, u.tool, u.wobj, u.line
                                ),
                            )));
                        }
                        continue;
                    }
                    uses.insert(
                        name.clone(),
                        Use {
                            tool: tool_name.clone(),
                            wobj: wobj_name.clone(),
                            line: *line,
                        },
                    );
                    let what = format!("robtarget {}", d.name);
                    items.push((robtarget(&d.value, &what).map_err(parse_err)?, tool, wobj, d.line, what));
                }
            }
        }
    }
    for name in &robtarget_order {
        if !uses.contains_key(name) {
            let d = &decls[&("robtarget".to_string(), name.clone())];
            robtarget(&d.value, &format!("robtarget {}", d.name)).map_err(parse_err)?;
            notes.push(format!(
                "{}:{}: robtarget {} is used by no move: left as it is",
                path.display(),
                d.line,
                d.name
            ));
        }
    }
    let targets: Vec<Target> = items
        .iter()
        .map(|(r, tool, wobj, _, _)| Target {
            pose: wobj * r.pose,
            tool: *tool,
            configuration: Some(Configuration::Abb(r.conf)),
            seed: None,
        })
        .collect();
    let located: Vec<(std::path::PathBuf, usize, String)> =
        items.iter().map(|(_, _, _, l, n)| (path.to_path_buf(), *l, n.clone())).collect();
    let super::Located {
        corrected,
        reports,
        uncorrected,
    } = correct_located(models, &targets, &located, opts.force)?;
    let mut edits: Vec<Edit> = Vec::new();
    for (c, (r, _, wobj, _, _)) in corrected.iter().zip(&items) {
        let Some(c) = c else { continue };
        let local = wobj.inverse() * c.pose;
        let p = local.translation.vector;
        let mut q = local.rotation.into_inner();
        if q.coords.dot(&r.quaternion.coords) < 0.0 {
            q = -q;
        }
        let conf = c.configuration.unwrap_or(r.conf);
        let values = [
            p.x,
            p.y,
            p.z,
            q.w,
            q.i,
            q.j,
            q.k,
            conf.cf1 as f64,
            conf.cf4 as f64,
            conf.cf6 as f64,
            conf.cfx as f64,
        ];
        for (k, ((text, range, _), v)) in r.numbers.iter().zip(values).enumerate() {
            let min = match k {
                0..=2 => 3,
                3..=6 => 7,
                _ => 0,
            };
            edits.extend(number_edit(text, range.clone(), v, min));
        }
    }
    Ok(FilteredProgram {
        text: apply(text, &edits),
        companion: None,
        format: Format::Rapid,
        targets: reports,
        uncorrected,
        notes,
        paths: None,
    })
}
