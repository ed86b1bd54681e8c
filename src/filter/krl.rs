//! KUKA KRL (`.src` with its `.dat`): `POS`, `E6POS` and `FRAME` aggregates
//! `{X, Y, Z, A, B, C, S, T, …}` declared in either file, and inline in `PTP`, `LIN`, `CIRC`,
//! `SPTP`, `SLIN`, `SCIRC` (the auxiliary and end points of a circle). Positions in mm; `A, B, C`
//! rotations about Z, Y′, X″ in degrees (`R = Rz(A)·Ry(B)·Rx(C)`); Status and Turn
//! ([`super::branch::StatusTurn`]) state the configuration when given.
//!
//! Tool and base follow the program: `$TOOL =` / `$BASE =` a `TOOL_DATA[n]` / `BASE_DATA[n]`, a
//! declared `FRAME` or a frame aggregate; `BAS(#TOOL, n)` / `BAS(#BASE, n)`; `FDAT_ACT = name`
//! (its `TOOL_NO`, `BASE_NO`). `TOOL_DATA[n]` and `BASE_DATA[n]` are taken from the files when
//! they assign them, else from [`FilterOptions::tool_data`] / [`FilterOptions::base_data`]; index
//! 0 is the flange and the robot's base. Before any assignment, [`FilterOptions::tool`] and the
//! robot's base. The base is taken in the robot's base frame (the world frame at the robot's
//! foot).
//!
//! Written back: X, Y, Z (at least 0.001 mm), A, B, C (at least 1e-5 deg, the turn nearest the
//! one written), S and T when given (decimal, or `'B…'` binary as written); external axes and
//! every other byte stay. Left as they are, with a note: axis targets (`{A1 …}`, `E6AXIS`),
//! relative motions (`PTP_REL`, `LIN_REL`), names declared elsewhere (`XHOME` in `$config.dat`).
//! A declared point used with two tools or bases is refused (it takes one correction).
use super::branch::{Configuration, StatusTurn};
use super::lex::{lex, Kind, Tok};
use super::rewrite::{apply, number_edit, Edit};
use super::{correct_located, FilterError, FilterModels, FilterOptions, FilteredProgram, Format, Target};
use crate::se3::{self, Pose};
use nalgebra::{Translation3, UnitQuaternion};
use std::collections::HashMap;
use std::ops::Range;
use std::path::Path;

/// One field of an aggregate: its key (upper case), its number (value, text, range) when it is
/// one, and its raw text.
#[derive(Debug, Clone)]
struct Field {
    key: String,
    num: Option<(f64, String, Range<usize>)>,
}

/// An aggregate `{KEY value, …}` of file `file` (0 the `.src`, 1 the `.dat`).
#[derive(Debug, Clone)]
struct Agg {
    fields: Vec<Field>,
    line: usize,
    file: usize,
}

impl Agg {
    fn get(&self, key: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.key == key)
    }
    fn value(&self, key: &str) -> Option<f64> {
        self.get(key).and_then(|f| f.num.as_ref().map(|n| n.0))
    }
    /// The pose of a frame aggregate (X, Y, Z, A, B, C all given), else `None`.
    fn pose(&self) -> Option<Pose> {
        let v: Option<Vec<f64>> = ["X", "Y", "Z", "A", "B", "C"].iter().map(|k| self.value(k)).collect();
        let v = v?;
        Some(Pose::from_parts(
            Translation3::new(v[0], v[1], v[2]),
            UnitQuaternion::from_euler_angles(v[5].to_radians(), v[4].to_radians(), v[3].to_radians()),
        ))
    }
}

/// A number token (`'B101'` read as binary) at `toks[k..]`: value, text, range.
fn number(text: &str, toks: &[Tok]) -> Option<(f64, String, Range<usize>)> {
    match toks {
        [t] if t.kind == Kind::Num => Some((
            text[t.range.clone()].parse().ok()?,
            text[t.range.clone()].to_string(),
            t.range.clone(),
        )),
        [s, t] if (s.is(b'-') || s.is(b'+')) && t.kind == Kind::Num => {
            let r = s.range.start..t.range.end;
            let x = &text[r.clone()];
            Some((x.trim_start_matches('+').parse().ok()?, x.to_string(), r))
        }
        [t] if t.kind == Kind::Str => {
            let x = &text[t.range.clone()];
            let bits = x.strip_prefix("'B")?.strip_suffix('\'')?;
            Some((i64::from_str_radix(bits, 2).ok()? as f64, x.to_string(), t.range.clone()))
        }
        _ => None,
    }
}

/// The aggregate starting at `toks[*i]` (`{`), moving `*i` past its `}`.
fn aggregate(text: &str, toks: &[Tok], i: &mut usize, file: usize) -> Result<Agg, (usize, String)> {
    let line = toks[*i].line;
    let start = *i + 1;
    let mut depth = 0i32;
    let mut end = None;
    for (k, t) in toks.iter().enumerate().skip(*i) {
        match t.kind {
            Kind::Punct(b'{') => depth += 1,
            Kind::Punct(b'}') => {
                depth -= 1;
                if depth == 0 {
                    end = Some(k);
                    break;
                }
            }
            _ => {}
        }
    }
    let end = end.ok_or((line, "an aggregate without its closing '}'".to_string()))?;
    *i = end + 1;
    let mut body = &toks[start..end];
    // An optional type: `{E6POS: X …}`.
    if body.len() > 1 && body[0].kind == Kind::Ident && body[1].is(b':') {
        body = &body[2..];
    }
    let mut fields = Vec::new();
    let mut depth = 0i32;
    let mut item_start = 0;
    for k in 0..=body.len() {
        let at_end = k == body.len();
        if !at_end {
            match body[k].kind {
                Kind::Punct(b'{' | b'[' | b'(') => depth += 1,
                Kind::Punct(b'}' | b']' | b')') => depth -= 1,
                _ => {}
            }
        }
        if at_end || (depth == 0 && body[k].is(b',')) {
            let item = &body[item_start..k];
            item_start = k + 1;
            if item.is_empty() {
                continue;
            }
            if item[0].kind != Kind::Ident {
                return Err((
                    item[0].line,
                    format!("expected a field name, found '{}'", &text[item[0].range.clone()]),
                ));
            }
            let key = text[item[0].range.clone()].to_ascii_uppercase();
            let mut v = &item[1..];
            // `POINT2[] " "`: a name with brackets.
            if v.first().is_some_and(|t| t.is(b'[')) {
                let close = v.iter().position(|t| t.is(b']')).unwrap_or(v.len() - 1);
                v = &v[close + 1..];
            }
            fields.push(Field { num: number(text, v), key });
        }
    }
    Ok(Agg { fields, line, file })
}

/// A declared point, frame or FDAT.
#[derive(Debug, Clone)]
struct Decl {
    kind: String,
    name: String,
    agg: Agg,
}

/// The text of a file and its tokens.
struct Source<'a> {
    path: &'a Path,
    text: &'a str,
    toks: Vec<Tok>,
}

/// Filter a KRL `.src` (`path`, `text`) with its `.dat` (`dat`), both rewritten.
pub fn filter_krl(
    path: &Path,
    text: &str,
    dat: Option<(&Path, &str)>,
    models: &FilterModels,
    opts: &FilterOptions,
) -> Result<FilteredProgram, FilterError> {
    let err = FilterError::parse_at;
    let mut sources = vec![Source {
        path,
        text,
        toks: lex(text, b';').map_err(err(path))?,
    }];
    if let Some((p, t)) = dat {
        sources.push(Source {
            path: p,
            text: t,
            toks: lex(t, b';').map_err(err(p))?,
        });
    }
    // Declarations and TOOL_DATA/BASE_DATA assignments in both files.
    let mut decls: HashMap<String, Decl> = HashMap::new();
    let mut tool_data: HashMap<u32, Pose> = opts.tool_data.iter().copied().collect();
    let mut base_data: HashMap<u32, Pose> = opts.base_data.iter().copied().collect();
    for (f, s) in sources.iter().enumerate() {
        let (toks, text) = (&s.toks, s.text);
        let mut i = 0;
        while i + 3 < toks.len() {
            let word = text[toks[i].range.clone()].to_ascii_uppercase();
            if toks[i].kind == Kind::Ident
                && ["POS", "E6POS", "FRAME", "FDAT", "AXIS", "E6AXIS"].contains(&word.as_str())
                && toks[i + 1].kind == Kind::Ident
                && toks[i + 2].is(b'=')
                && toks[i + 3].is(b'{')
            {
                let name = text[toks[i + 1].range.clone()].to_string();
                let mut j = i + 3;
                let agg = aggregate(text, toks, &mut j, f).map_err(err(s.path))?;
                decls.insert(name.to_ascii_uppercase(), Decl { kind: word, name, agg });
                i = j;
                continue;
            }
            if toks[i].kind == Kind::Ident && (word == "TOOL_DATA" || word == "BASE_DATA") && toks[i + 1].is(b'[') {
                if let (Some(n), Some(eq), Some(open)) = (toks.get(i + 2), toks.get(i + 4), toks.get(i + 5)) {
                    if n.kind == Kind::Num && eq.is(b'=') && open.is(b'{') {
                        let mut j = i + 5;
                        let agg = aggregate(text, toks, &mut j, f).map_err(err(s.path))?;
                        let pose = agg
                            .pose()
                            .ok_or_else(|| err(s.path)((agg.line, format!("{word}: a frame needs X, Y, Z, A, B and C"))))?;
                        let k: u32 = text[n.range.clone()].parse().unwrap_or(0);
                        if word == "TOOL_DATA" {
                            tool_data.insert(k, pose)
                        } else {
                            base_data.insert(k, pose)
                        };
                        i = j;
                        continue;
                    }
                }
            }
            i += 1;
        }
    }
    let src = &sources[0];
    let (toks, stext) = (&src.toks, src.text);
    let at = err(path);
    let word = |t: &Tok| stext[t.range.clone()].to_ascii_uppercase();
    let indexed = |data: &HashMap<u32, Pose>, what: &str, option: &str, k: u32, line: usize| -> Result<Pose, FilterError> {
        if k == 0 {
            return Ok(Pose::identity());
        }
        data.get(&k).copied().ok_or_else(|| {
            at((
                line,
                format!("{what}[{k}] is not in the files: give it with {option} {k}=X,Y,Z,A,B,C"),
            ))
        })
    };
    let (mut tool, mut base) = (opts.tool, Pose::identity());
    let (mut tool_name, mut base_name) = ("the tool given".to_string(), "the robot's base".to_string());
    let mut notes = Vec::new();
    let mut uses: HashMap<String, (String, String, usize)> = HashMap::new();
    // (aggregate, tool, base, line, name)
    let mut items: Vec<(Agg, Pose, Pose, usize, String)> = Vec::new();
    let mut i = 0;
    while i < toks.len() {
        let t = &toks[i];
        let first_on_line = i == 0 || toks[i - 1].line != t.line;
        let w = if t.kind == Kind::Ident { word(t) } else { String::new() };
        // $TOOL = … / $BASE = …
        if t.is(b'$')
            && toks.get(i + 1).is_some_and(|x| matches!(word(x).as_str(), "TOOL" | "BASE"))
            && toks.get(i + 2).is_some_and(|x| x.is(b'='))
        {
            let is_tool = word(&toks[i + 1]) == "TOOL";
            let v = toks.get(i + 3).ok_or_else(|| at((t.line, "expected a frame after '='".into())))?;
            let (pose, name, next) = if v.is(b'{') {
                let mut j = i + 3;
                let agg = aggregate(stext, toks, &mut j, 0).map_err(&at)?;
                (
                    agg.pose().ok_or_else(|| at((v.line, "a frame needs X, Y, Z, A, B and C".into())))?,
                    format!("the frame on line {}", v.line),
                    j,
                )
            } else if v.kind == Kind::Ident
                && matches!(word(v).as_str(), "TOOL_DATA" | "BASE_DATA")
                && toks.get(i + 4).is_some_and(|x| x.is(b'['))
            {
                let n = toks
                    .get(i + 5)
                    .filter(|n| n.kind == Kind::Num)
                    .ok_or_else(|| at((v.line, "expected an index".into())))?;
                let k: u32 = stext[n.range.clone()]
                    .parse()
                    .map_err(|_| at((n.line, "expected an index".into())))?;
                let (data, option) = if is_tool {
                    (&tool_data, "--tool-data")
                } else {
                    (&base_data, "--base-data")
                };
                (indexed(data, &word(v), option, k, v.line)?, format!("{}[{k}]", word(v)), i + 7)
            } else if v.kind == Kind::Ident {
                let d = decls.get(&word(v)).filter(|d| d.kind == "FRAME").ok_or_else(|| {
                    at((
                        v.line,
                        format!("'{}' is not a FRAME declared in the files", &stext[v.range.clone()]),
                    ))
                })?;
                (
                    d.agg
                        .pose()
                        .ok_or_else(|| at((v.line, format!("FRAME {}: needs X, Y, Z, A, B and C", d.name))))?,
                    d.name.clone(),
                    i + 4,
                )
            } else {
                return Err(at((v.line, "expected a frame, a TOOL_DATA/BASE_DATA or a FRAME's name".into())));
            };
            if is_tool {
                (tool, tool_name) = (pose, name)
            } else {
                (base, base_name) = (pose, name)
            }
            i = next;
            continue;
        }
        // BAS(#TOOL, n) / BAS(#BASE, n)
        if w == "BAS" && toks.get(i + 2).is_some_and(|x| x.is(b'#')) {
            let which = toks.get(i + 3).map(word).unwrap_or_default();
            if let Some(n) = toks
                .get(i + 5)
                .filter(|n| n.kind == Kind::Num && (which == "TOOL" || which == "BASE"))
            {
                let k: u32 = stext[n.range.clone()].parse().unwrap_or(0);
                if which == "TOOL" {
                    tool = indexed(&tool_data, "TOOL_DATA", "--tool-data", k, n.line)?;
                    tool_name = format!("TOOL_DATA[{k}]");
                } else {
                    base = indexed(&base_data, "BASE_DATA", "--base-data", k, n.line)?;
                    base_name = format!("BASE_DATA[{k}]");
                }
            }
        }
        // FDAT_ACT = name: its TOOL_NO and BASE_NO.
        if w == "FDAT_ACT" && toks.get(i + 1).is_some_and(|x| x.is(b'=')) {
            if let Some(d) = toks.get(i + 2).and_then(|n| decls.get(&word(n))).filter(|d| d.kind == "FDAT") {
                if let Some(k) = d.agg.value("TOOL_NO") {
                    tool = indexed(&tool_data, "TOOL_DATA", "--tool-data", k as u32, t.line)?;
                    tool_name = format!("TOOL_DATA[{k}]");
                }
                if let Some(k) = d.agg.value("BASE_NO") {
                    base = indexed(&base_data, "BASE_DATA", "--base-data", k as u32, t.line)?;
                    base_name = format!("BASE_DATA[{k}]");
                }
            }
        }
        let n_targets = match w.as_str() {
            "PTP" | "LIN" | "SPTP" | "SLIN" => 1,
            "CIRC" | "SCIRC" => 2,
            "PTP_REL" | "LIN_REL" | "CIRC_REL" | "SPTP_REL" | "SLIN_REL" | "SCIRC_REL" if first_on_line => {
                notes.push(format!("{}:{}: a relative motion is left as it is", path.display(), t.line));
                0
            }
            _ => 0,
        };
        if n_targets > 0 && first_on_line {
            let mut j = i + 1;
            for k in 0..n_targets {
                let Some(x) = toks.get(j).filter(|x| x.line == t.line) else {
                    return Err(at((t.line, format!("{w}: expected {n_targets} target(s)"))));
                };
                if x.is(b'{') {
                    let agg = aggregate(stext, toks, &mut j, 0).map_err(&at)?;
                    if agg.get("A1").is_some() {
                        notes.push(format!("{}:{}: an axis target is left as it is", path.display(), x.line));
                    } else if agg.pose().is_some() {
                        items.push((agg, tool, base, x.line, "inline point".into()));
                    } else {
                        return Err(at((x.line, "a Cartesian target needs X, Y, Z, A, B and C".into())));
                    }
                } else if x.kind == Kind::Ident {
                    let key = word(x);
                    j += 1;
                    match decls.get(&key).filter(|d| matches!(d.kind.as_str(), "POS" | "E6POS" | "FRAME")) {
                        None => notes.push(format!(
                            "{}:{}: {} is not a point declared in these files: left as it is",
                            path.display(),
                            x.line,
                            &stext[x.range.clone()]
                        )),
                        Some(d) => {
                            let what = format!("{} {}", d.kind, d.name);
                            if let Some((tn, bn, l)) = uses.get(&key) {
                                if *tn != tool_name || *bn != base_name {
                                    return Err(at((x.line, format!("{what} is moved to with {tool_name} and {base_name} here and with {tn} and {bn} on line {l}: a declared point takes one correction"))));
                                }
                            } else {
                                d.agg.pose().ok_or_else(|| {
                                    err(sources[d.agg.file].path)((d.agg.line, format!("{what}: needs X, Y, Z, A, B and C")))
                                })?;
                                uses.insert(key, (tool_name.clone(), base_name.clone(), x.line));
                                items.push((d.agg.clone(), tool, base, d.agg.line, what));
                            }
                        }
                    }
                } else {
                    return Err(at((x.line, format!("{w}: '{}' is not a target", &stext[x.range.clone()]))));
                }
                if k + 1 < n_targets && toks.get(j).is_some_and(|x| x.is(b',')) {
                    j += 1;
                }
            }
            i = j;
            continue;
        }
        i += 1;
    }
    let status_turn = |a: &Agg| match (a.value("S"), a.value("T")) {
        (Some(s), Some(t)) => Some(Configuration::Kuka(StatusTurn { s: s as i32, t: t as i32 })),
        _ => None,
    };
    let targets: Vec<Target> = items
        .iter()
        .map(|(a, tool, base, _, _)| Target {
            pose: base * a.pose().expect("checked"),
            tool: *tool,
            configuration: status_turn(a),
            seed: None,
        })
        .collect();
    // Errors name the file the point is in.
    let located: Vec<(std::path::PathBuf, usize, String)> = items
        .iter()
        .map(|(a, _, _, l, n)| (sources[a.file].path.to_path_buf(), *l, n.clone()))
        .collect();
    let super::Located {
        corrected,
        reports,
        uncorrected,
    } = correct_located(models, &targets, &located, opts.force)?;
    let mut edits: Vec<Vec<Edit>> = vec![Vec::new(); sources.len()];
    for (c, (a, _, base, _, _)) in corrected.iter().zip(&items) {
        let Some(c) = c else { continue };
        let local = base.inverse() * c.pose;
        let p = local.translation.vector;
        let [roll, pitch, yaw] = se3::rpy(&local.rotation);
        let mut values = vec![("X", p.x, 3), ("Y", p.y, 3), ("Z", p.z, 3)];
        for (k, v) in [("A", yaw), ("B", pitch), ("C", roll)] {
            let old = a.value(k).unwrap_or(0.0).to_radians();
            values.push((k, (old + se3::wrap_angle(v - old)).to_degrees(), 5));
        }
        if let (Some(st), Some(_)) = (c.status_turn, status_turn(a)) {
            values.push(("S", st.s as f64, 0));
            values.push(("T", st.t as f64, 0));
        }
        for (k, v, d) in values {
            let Some((_, tok, range)) = a.get(k).and_then(|f| f.num.clone()) else {
                continue;
            };
            if let Some(bits) = tok.strip_prefix("'B") {
                let width = bits.len().saturating_sub(1);
                let new = format!("'B{:0width$b}'", v as i64);
                if new != tok {
                    edits[a.file].push(Edit { range, text: new });
                }
                continue;
            }
            edits[a.file].extend(number_edit(&tok, range, v, d));
        }
    }
    Ok(FilteredProgram {
        text: apply(text, &edits[0]),
        companion: dat.map(|(_, t)| apply(t, &edits[1])),
        format: Format::Krl,
        targets: reports,
        uncorrected,
        notes,
        paths: None,
    })
}
