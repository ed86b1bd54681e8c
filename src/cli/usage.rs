//! Usage errors (a misspelled flag, a bad value, a missing argument, an unknown command) as one
//! line naming the flag or value and the fix, for exit code 1 like any other wrong input.
use clap::error::{ContextKind, ContextValue, ErrorKind};

/// What to do with a clap error: `None` for `--help` / `--version` (clap prints them and the
/// command exits 0), else the one line to print after `kinecal: error: `.
pub fn fold(err: &clap::Error, cmd: &clap::Command, argv: &[String]) -> Option<String> {
    if matches!(err.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
        return None;
    }
    let (path, sub) = command_path(cmd, argv);
    let help = format!("`{path} --help` lists what it takes");
    if err.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
        let names: Vec<&str> = sub
            .get_subcommands()
            .filter(|c| !c.is_hide_set())
            .map(clap::Command::get_name)
            .collect();
        return Some(if names.is_empty() {
            format!("`{path}` needs arguments: {help}")
        } else {
            format!(
                "`{path}` needs a command: {} (`{path} --help` says what each does)",
                names.join(", ")
            )
        });
    }
    let text = err.render().to_string();
    let mut parts: Vec<String> = Vec::new();
    let mut usage = None;
    for line in text.lines() {
        let t = line.trim();
        if t.is_empty() || t.starts_with("For more information") {
            continue;
        }
        if let Some(u) = t.strip_prefix("Usage:") {
            usage = Some(u.trim().to_string());
            continue;
        }
        let t = t.strip_prefix("error: ").unwrap_or(t);
        // A list under a heading ("the following required arguments were not provided:") joins
        // the heading.
        match parts.last_mut() {
            Some(last) if last.ends_with(':') => {
                last.push(' ');
                last.push_str(t);
            }
            Some(last) if line.starts_with("  ") && !t.starts_with("tip:") && last.contains("not provided: ") => {
                last.push_str(", ");
                last.push_str(t);
            }
            _ => parts.push(t.to_string()),
        }
    }
    let mut line = parts.join("; ");
    match err.kind() {
        ErrorKind::InvalidSubcommand if !line.contains("tip:") => {
            let names: Vec<&str> = sub
                .get_subcommands()
                .filter(|c| !c.is_hide_set())
                .map(clap::Command::get_name)
                .collect();
            line.push_str(&format!("; the commands of `{path}` are {}", names.join(", ")));
        }
        ErrorKind::MissingRequiredArgument
        | ErrorKind::WrongNumberOfValues
        | ErrorKind::TooFewValues
        | ErrorKind::TooManyValues
        | ErrorKind::ArgumentConflict
        | ErrorKind::UnknownArgument
            if usage.is_some() =>
        {
            line.push_str(&format!("; usage: {}", usage.unwrap_or_default()));
        }
        ErrorKind::InvalidValue | ErrorKind::ValueValidation => {
            if let Some(ContextValue::Strings(v)) = err.get(ContextKind::ValidValue) {
                if !v.is_empty() && !line.contains("possible values") {
                    line.push_str(&format!("; possible values: {}", v.join(", ")));
                }
            }
        }
        _ => {}
    }
    Some(format!("{line} ({help})"))
}

/// The command line's subcommand path (`kinecal data join`) and the deepest command it names.
fn command_path<'a>(cmd: &'a clap::Command, argv: &[String]) -> (String, &'a clap::Command) {
    let mut cur = cmd;
    let mut path = vec![cmd.get_name().to_string()];
    for a in argv.iter().skip(1) {
        if a.starts_with('-') {
            continue;
        }
        match cur.find_subcommand(a) {
            Some(c) => {
                path.push(c.get_name().to_string());
                cur = c;
            }
            None if cur.has_subcommands() => break,
            None => {}
        }
    }
    (path.join(" "), cur)
}
