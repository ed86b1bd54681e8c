//! Token-level rewriting: numbers replaced in place, every other byte kept.
use std::ops::Range;

/// A replacement of the bytes `range` of a text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Edit {
    /// Bytes replaced.
    pub range: Range<usize>,
    /// Their new text.
    pub text: String,
}

/// `text` with `edits` applied (they must not overlap; any order).
pub fn apply(text: &str, edits: &[Edit]) -> String {
    let mut sorted: Vec<&Edit> = edits.iter().collect();
    sorted.sort_by_key(|e| e.range.start);
    let mut out = String::with_capacity(text.len() + 16 * edits.len());
    let mut at = 0;
    for e in sorted {
        debug_assert!(e.range.start >= at, "overlapping edits");
        out.push_str(&text[at..e.range.start]);
        out.push_str(&e.text);
        at = e.range.end;
    }
    out.push_str(&text[at..]);
    out
}

/// Digits after the decimal point of a number as written (`"1.250"` → 3, `"9E+09"` → 0).
pub fn decimals(token: &str) -> usize {
    let mantissa = token.split(['e', 'E']).next().unwrap_or(token);
    mantissa
        .split_once('.')
        .map_or(0, |(_, f)| f.chars().filter(char::is_ascii_digit).count())
}

/// The edit that writes `value` over the number `token` at `range`, with the token's decimals
/// or `min_decimals`, whichever is more; `None` when the number does not change at that
/// precision (the token is kept as it is).
pub fn number_edit(token: &str, range: Range<usize>, value: f64, min_decimals: usize) -> Option<Edit> {
    let d = decimals(token).max(min_decimals);
    let old: f64 = token.trim_start_matches('+').parse().unwrap_or(f64::NAN);
    let scale = 10f64.powi(d as i32);
    if old.is_finite() && ((old * scale).round() - (value * scale).round()).abs() < 0.5 {
        return None;
    }
    Some(Edit {
        range,
        text: format_fixed(value, d),
    })
}

/// `value` with `d` decimals, never `-0.000`.
pub fn format_fixed(value: f64, d: usize) -> String {
    let s = format!("{value:.d$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_keep_their_precision_or_gain_some() {
        assert_eq!(decimals("12.50"), 2);
        assert_eq!(decimals("-3"), 0);
        assert_eq!(decimals("9E+09"), 0);
        assert_eq!(number_edit("300", 0..3, 300.0002, 3), None);
        assert_eq!(number_edit("300", 0..3, 300.0012, 3).unwrap().text, "300.001");
        assert_eq!(number_edit("0.61234567", 0..10, 0.6123, 6).unwrap().text, "0.61230000");
        assert_eq!(format_fixed(-0.00001, 3), "0.000");
        let text = "a=[1,2.5];! keep\r\n";
        let out = apply(
            text,
            &[Edit {
                range: 5..8,
                text: "2.625".into(),
            }],
        );
        assert_eq!(out, "a=[1,2.625];! keep\r\n");
    }
}
