//! Which error parameters a model file frees: the `[calibration]` patterns (globs, with ASCII
//! spellings of Greek letters) and the parameters an overconstrained mechanism cannot take alone.
use crate::model::Mechanism;
use crate::params::Param;

/// True when `name` matches the glob `pattern` (`*`: any run of characters, `?`: one character).
pub fn glob_match(pattern: &str, name: &str) -> bool {
    let (p, n): (Vec<char>, Vec<char>) = (pattern.chars().collect(), name.chars().collect());
    let (mut pi, mut ni, mut star, mut mark) = (0, 0, None, 0);
    while ni < n.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == n[ni]) {
            pi += 1;
            ni += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some(pi);
            mark = ni;
            pi += 1;
        } else if let Some(s) = star {
            pi = s + 1;
            mark += 1;
            ni = mark;
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

/// A pattern with ASCII spellings of the Greek letters in parameter names replaced
/// (`phi` → `φ`, `alpha` → `α`, `beta` → `β`, `gamma` → `γ`: `dphi1` means `dφ1`).
pub fn greek_pattern(pattern: &str) -> String {
    pattern
        .replace("alpha", "α")
        .replace("beta", "β")
        .replace("gamma", "γ")
        .replace("phi", "φ")
}

/// True when `name` matches `pattern` as a glob ([`glob_match`]), or with the pattern's ASCII
/// Greek letters spelt out ([`greek_pattern`]).
pub fn param_match(pattern: &str, name: &str) -> bool {
    glob_match(pattern, name) || glob_match(&greek_pattern(pattern), name)
}

/// Indices of the parameters selected by `free` patterns minus those matching `fixed`, in the
/// order of the patterns (priority order), each parameter once; patterns match as [`param_match`]. Returns the first pattern that
/// matches no parameter as an error.
pub fn select_params(params: &[Param], free: &[String], fixed: &[String]) -> Result<Vec<usize>, String> {
    for pat in free.iter().chain(fixed) {
        if !params.iter().any(|p| param_match(pat, &p.name)) {
            return Err(pat.clone());
        }
    }
    let mut out = Vec::new();
    for pat in free {
        for (i, p) in params.iter().enumerate() {
            if param_match(pat, &p.name) && !fixed.iter().any(|f| param_match(f, &p.name)) && !out.contains(&i) {
                out.push(i);
            }
        }
    }
    Ok(out)
}

/// [`select_params`] over `mech`'s parameters, without those it cannot take alone
/// ([`Mechanism::assembly_breaking`]: an overconstrained mechanism's): the parameters a fit,
/// a virtual prototype or a plan moves. Errors (the message): a pattern that matches no
/// parameter, or a `free` pattern that matches only parameters held that way.
pub fn free_params(mech: &dyn Mechanism, free: &[String], fixed: &[String]) -> Result<Vec<usize>, String> {
    let params = mech.params();
    let held = mech.assembly_breaking();
    let out = select_params(&params, free, fixed).map_err(|pat| format!("calibration pattern '{pat}' matches no parameter"))?;
    let only_held = |pat: &String| {
        params
            .iter()
            .enumerate()
            .all(|(i, p)| held.contains(&i) || !param_match(pat, &p.name))
    };
    if let Some(pat) = free.iter().find(|p| only_held(p)) {
        return Err(format!(
            "calibration pattern '{pat}' frees only parameters {} cannot take alone: it is overconstrained and would not assemble with one of them changed, so they stay as drawn (kinecal identifiability lists them); free the others",
            mech.name()
        ));
    }
    Ok(out.into_iter().filter(|i| !held.contains(i)).collect())
}
