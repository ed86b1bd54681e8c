//! Tokens of a robot language and its bracketed aggregates (`[[x, y, z], [q1, q2, q3, q4], …]`),
//! with their byte ranges and lines. Comments (from the language's comment character to the end
//! of the line: `!` in RAPID, `#` in URScript) are skipped; strings are one token.
use std::ops::Range;

/// A token's kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    Ident,
    Num,
    Str,
    Assign,
    Punct(u8),
}

/// A token.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Tok {
    pub kind: Kind,
    pub range: Range<usize>,
    pub line: usize,
}

impl Tok {
    pub fn is(&self, c: u8) -> bool {
        self.kind == Kind::Punct(c)
    }
}

/// The tokens of `text`; an error is (line, message).
pub(crate) fn lex(text: &str, comment: u8) -> Result<Vec<Tok>, (usize, String)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let (mut i, mut line) = (0, 1);
    while i < b.len() {
        let c = b[i];
        let start = i;
        match c {
            b'\n' => {
                line += 1;
                i += 1;
            }
            _ if c.is_ascii_whitespace() => i += 1,
            _ if c == comment => {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
            }
            b'"' | b'\'' => {
                i += 1;
                loop {
                    match b.get(i) {
                        None | Some(b'\n') => return Err((line, format!("a string without its closing {}", c as char))),
                        Some(&q) if q == c && b.get(i + 1) == Some(&c) => i += 2,
                        Some(&q) if q == c => {
                            i += 1;
                            break;
                        }
                        Some(_) => i += 1,
                    }
                }
                out.push(Tok {
                    kind: Kind::Str,
                    range: start..i,
                    line,
                });
            }
            _ if c.is_ascii_digit() || (c == b'.' && b.get(i + 1).is_some_and(u8::is_ascii_digit)) => {
                while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.') {
                    i += 1;
                }
                if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
                    let mut j = i + 1;
                    if j < b.len() && (b[j] == b'+' || b[j] == b'-') {
                        j += 1;
                    }
                    if j < b.len() && b[j].is_ascii_digit() {
                        i = j;
                        while i < b.len() && b[i].is_ascii_digit() {
                            i += 1;
                        }
                    }
                }
                out.push(Tok {
                    kind: Kind::Num,
                    range: start..i,
                    line,
                });
            }
            _ if c.is_ascii_alphabetic() || c == b'_' => {
                while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                    i += 1;
                }
                out.push(Tok {
                    kind: Kind::Ident,
                    range: start..i,
                    line,
                });
            }
            b':' if b.get(i + 1) == Some(&b'=') => {
                i += 2;
                out.push(Tok {
                    kind: Kind::Assign,
                    range: start..i,
                    line,
                });
            }
            _ if c.is_ascii() => {
                i += 1;
                out.push(Tok {
                    kind: Kind::Punct(c),
                    range: start..i,
                    line,
                });
            }
            _ => {
                // A non-ASCII character outside comments and strings: one punctuation token.
                let n = text[i..].chars().next().map_or(1, char::len_utf8);
                i += n;
                out.push(Tok {
                    kind: Kind::Punct(b'?'),
                    range: start..i,
                    line,
                });
            }
        }
    }
    Ok(out)
}

/// A value of an aggregate.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Value {
    /// `[a, b, …]`.
    List(Vec<Value>, usize),
    /// A number (with its sign), its text and range.
    Num {
        value: f64,
        text: String,
        range: Range<usize>,
        line: usize,
    },
    /// Anything else in one token: `TRUE`, a name, a string.
    Atom(String, usize),
}

impl Value {
    pub fn line(&self) -> usize {
        match self {
            Value::List(_, l) | Value::Num { line: l, .. } | Value::Atom(_, l) => *l,
        }
    }
}

/// Parse one value at `toks[*i]`, moving `*i` past it.
pub(crate) fn value(text: &str, toks: &[Tok], i: &mut usize) -> Result<Value, (usize, String)> {
    let end_line = toks.last().map_or(1, |t| t.line);
    let t = toks.get(*i).ok_or((end_line, "the value ends early".to_string()))?;
    if t.is(b'[') {
        *i += 1;
        let mut items = Vec::new();
        if toks.get(*i).is_some_and(|t| t.is(b']')) {
            *i += 1;
            return Ok(Value::List(items, t.line));
        }
        loop {
            items.push(value(text, toks, i)?);
            match toks.get(*i) {
                Some(s) if s.is(b',') => *i += 1,
                Some(s) if s.is(b']') => {
                    *i += 1;
                    return Ok(Value::List(items, t.line));
                }
                Some(s) => return Err((s.line, format!("expected ',' or ']', found '{}'", &text[s.range.clone()]))),
                None => return Err((end_line, "an aggregate without its closing ']'".into())),
            }
        }
    }
    if (t.is(b'-') || t.is(b'+')) && toks.get(*i + 1).is_some_and(|n| n.kind == Kind::Num) {
        let n = &toks[*i + 1];
        *i += 2;
        return num(text, t.range.start..n.range.end, t.line);
    }
    *i += 1;
    match t.kind {
        Kind::Num => num(text, t.range.clone(), t.line),
        Kind::Ident | Kind::Str => Ok(Value::Atom(text[t.range.clone()].to_string(), t.line)),
        _ => Err((t.line, format!("unexpected '{}' in an aggregate", &text[t.range.clone()]))),
    }
}

fn num(text: &str, range: Range<usize>, line: usize) -> Result<Value, (usize, String)> {
    let s = &text[range.clone()];
    let v: f64 = s
        .trim_start_matches('+')
        .parse()
        .map_err(|_| (line, format!("'{s}' is not a number")))?;
    Ok(Value::Num {
        value: v,
        text: s.to_string(),
        range,
        line,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_and_aggregates() {
        let text = "CONST robtarget p:=[[1,-2.5,3E+2],[1,0,0,0]]; ! a \"comment\n s:=\"a\"\"b\";";
        let toks = lex(text, b'!').unwrap();
        assert_eq!(toks.iter().filter(|t| t.kind == Kind::Str).count(), 1);
        let at = toks.iter().position(|t| t.kind == Kind::Assign).unwrap();
        let mut i = at + 1;
        let v = value(text, &toks, &mut i).unwrap();
        let Value::List(items, _) = v else { panic!() };
        let Value::List(pos, _) = &items[0] else { panic!() };
        let nums: Vec<f64> = pos
            .iter()
            .map(|p| if let Value::Num { value, .. } = p { *value } else { f64::NAN })
            .collect();
        assert_eq!(nums, vec![1.0, -2.5, 300.0]);
        assert_eq!(toks.last().unwrap().line, 2);
        assert!(lex("s:=\"open\n", b'!').is_err());
    }
}
