//! The shape of the crate, checked on its sources: the `use` edges between modules of `src/`
//! (`crate::…` paths, `super::…`, and relative `use child::…`; a parent's use of its own child
//! module is containment, not an edge) form no cycle; no core file (outside `src/cli/` and
//! `src/studies/`) is longer than 700 lines; the core never imports the studies or the CLI; the
//! general commands of `src/cli/` name no mechanism kind.
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// `model::closed` for `src/model/closed.rs` or `src/model/closed/mod.rs`.
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|p| p.to_string_lossy().into_owned()).collect();
    if parts.last().is_some_and(|l| l == "mod") {
        parts.pop();
    }
    parts.join("::")
}

/// Module path segments after `crate::` in `text`, as the longest known module prefix.
fn targets(text: &str, me: &str, modules: &BTreeSet<String>) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let longest = |path: &[&str]| -> Option<String> { (1..=path.len()).rev().map(|k| path[..k].join("::")).find(|c| modules.contains(c)) };
    let code: String = text
        .split("#[cfg(test)]")
        .next()
        .unwrap_or("")
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n");
    let ident = |s: &str| {
        s.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == ':'))
            .next()
            .unwrap_or("")
            .to_string()
    };
    for (i, _) in code.match_indices("crate::") {
        let path = ident(&code[i + 7..]);
        let segs: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
        if let Some(t) = longest(&segs) {
            out.insert(t);
        }
    }
    let parent: Vec<&str> = me.split("::").collect();
    let parent = parent[..parent.len().saturating_sub(1)].join("::");
    for (i, _) in code.match_indices("super::") {
        let rest = ident(&code[i + 7..]);
        let mut segs: Vec<&str> = parent.split("::").filter(|s| !s.is_empty()).collect();
        segs.extend(rest.split("::").filter(|s| !s.is_empty()));
        match longest(&segs) {
            Some(t) => {
                out.insert(t);
            }
            None if !parent.is_empty() => {
                out.insert(parent.clone());
            }
            None => {}
        }
    }
    out.remove(me);
    out
}

#[test]
fn modules_form_no_cycle_and_core_files_stay_short() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let modules: BTreeSet<String> = files.iter().map(|f| module_of(&src, f)).collect();
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in &files {
        let m = module_of(&src, f);
        if m == "main" || m == "lib" || m.starts_with("cli") {
            continue;
        }
        let text = std::fs::read_to_string(f).unwrap();
        let is_core = !m.starts_with("studies");
        if is_core {
            let lines = text.lines().count();
            assert!(lines <= 700, "{}: {lines} lines in the core (at most 700)", f.display());
        }
        let t = targets(&text, &m, &modules);
        for target in &t {
            if is_core {
                assert!(!target.starts_with("studies"), "core module {m} imports {target}");
            }
        }
        // A parent's use of its own child is containment.
        edges.insert(m.clone(), t.into_iter().filter(|t| !t.starts_with(&format!("{m}::"))).collect());
    }
    // Depth-first search for a cycle.
    fn visit(
        n: &str,
        edges: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(n.to_string(), 1);
        stack.push(n.to_string());
        for t in edges.get(n).into_iter().flatten() {
            match state.get(t.as_str()) {
                Some(1) => {
                    let from = stack.iter().position(|s| s == t).unwrap();
                    let mut c = stack[from..].to_vec();
                    c.push(t.clone());
                    return Some(c);
                }
                Some(_) => {}
                None => {
                    if let Some(c) = visit(t, edges, state, stack) {
                        return Some(c);
                    }
                }
            }
        }
        stack.pop();
        state.insert(n.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for n in edges.keys() {
        if !state.contains_key(n) {
            let cycle = visit(n, &edges, &mut state, &mut Vec::new());
            assert!(cycle.is_none(), "import cycle: {}", cycle.unwrap().join(" → "));
        }
    }
    assert!(edges.len() > 30, "only {} modules found", edges.len());
}

/// The general commands (`src/cli/`) reach every mechanism through the library: their code names
/// no mechanism kind — no type of a kind (the presets `Pm5`, `Stewart`, the closed-loop and limbs
/// types, `SerialChain`, the `MechanismSpec` variants) and no comparison with a kind's name as
/// written in a model file (`== "pm5"`, a match arm `"limbs" =>`). A built-in model's name given
/// as an argument (e.g. `quickstart` exporting `pm5`) is data, not a decision on the kind. The
/// paper-study commands (`study.rs`, `study_t3r1.rs`, `irb120.rs`) reproduce studies of named
/// machines and are exempt. Comments are not code.
#[test]
fn the_general_commands_name_no_mechanism_kind() {
    const TYPES: [&str; 12] = [
        "Pm5",
        "Stewart",
        "ClosedLoop",
        "ConstraintSystem",
        "LimbMechanism",
        "SerialChain",
        "WithJointTerms",
        "MechanismSpec",
        "Serial",
        "SerialTerms",
        "Limbs",
        "presets",
    ];
    const STUDIES: [&str; 3] = ["study.rs", "study_t3r1.rs", "irb120.rs"];
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/cli");
    let mut files = Vec::new();
    rust_files(&dir, &mut files);
    let mut checked = 0;
    for f in &files {
        if STUDIES.iter().any(|s| f.ends_with(s)) {
            continue;
        }
        checked += 1;
        let text = std::fs::read_to_string(f).unwrap();
        for (n, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            let words = code.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'));
            if let Some(w) = words.clone().find(|w| TYPES.contains(w)) {
                panic!("{}:{}: names the mechanism kind {w}: {line}", f.display(), n + 1);
            }
            for kind in kinecal::model::kind::KINDS {
                let quoted = format!("\"{kind}\"");
                let compared = [format!("== {quoted}"), format!("{quoted} =>"), format!("{quoted} |")];
                assert!(
                    !compared.iter().any(|c| code.contains(c.as_str())),
                    "{}:{}: decides on the mechanism kind {kind}: {line}",
                    f.display(),
                    n + 1
                );
            }
        }
    }
    assert!(checked >= 8, "only {checked} command files checked");
}
