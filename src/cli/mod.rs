//! One module per subcommand: each parses its arguments, calls the library and prints.
pub mod assess;
pub mod check;
pub mod compensate;
pub mod data;
pub mod filter;
pub mod identifiability;
pub mod identify;
pub mod identify_prior;
pub mod instrument_plan;
pub mod irb120;
pub mod iso_plan;
pub mod model;
pub mod plan;
pub mod progress;
pub mod quickstart;
pub mod sampling;
pub mod simulate;
pub mod study;
pub mod study_t3r1;
pub mod touch_args;
pub mod usage;
pub mod validate;

/// A result that was computed but failed its checks (not converged, implausible, residual far
/// beyond the noise): the command exits with [`EXIT_FAILED_CHECKS`] instead of 1.
#[derive(Debug)]
pub struct FailedChecks(pub String);

impl std::fmt::Display for FailedChecks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for FailedChecks {}

/// Exit code of a command whose input or options were wrong, or that could not compute.
pub const EXIT_ERROR: u8 = 1;
/// Exit code of a command that computed a result which failed its checks ([`FailedChecks`]).
pub const EXIT_FAILED_CHECKS: u8 = 2;

/// One line when the model's mechanism is overconstrained: the error parameters it cannot take
/// alone ([`ModelFile::held_by_assembly`]), held at their drawn values whatever its
/// `[calibration]` says. Nothing for every other model. On stderr when stdout carries JSON.
pub fn note_held(file: &kinecal::io::model_file::ModelFile, json: bool) {
    let held = file.held_by_assembly();
    if held.is_empty() {
        return;
    }
    let shown = if held.len() > 6 {
        format!("{} … (kinecal identifiability lists all)", held[..6].join(" "))
    } else {
        held.join(" ")
    };
    let line = format!(
        "{} is overconstrained (its limbs repeat constraints, as a planar machine's do): {} error parameters would keep it from assembling and stay as drawn: {shown}",
        file.name,
        held.len()
    );
    if json {
        eprintln!("{line}");
    } else {
        println!("{line}");
    }
}

/// One `warning:` line on stderr per input of `data` with rows beyond the model's limits (kept
/// as measured: [`kinecal::io::data_file::BeyondLimits`]).
pub fn warn_limits(data: &kinecal::io::data_file::DataSet) {
    for line in data.limit_warnings() {
        eprintln!("warning: {line}");
    }
}

/// The current UTC date and time as ISO 8601 (`2026-11-24T13:05:00Z`), for provenance records.
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z", rem / 3600, rem % 3600 / 60, rem % 60)
}

/// `n` and a noun, singular for one: `count(1, "pose")` is "1 pose", `count(3, "pose")` "3 poses".
pub fn count(n: usize, noun: &str) -> String {
    match n {
        1 => format!("1 {noun}"),
        _ => format!("{n} {noun}s"),
    }
}

/// What `data check`, `validate` and `identify` say of a data file's units: a note naming the
/// columns read as metres or radians (`x_m`, `yaw_rad`), and, with `check`, the plausibility
/// checks of [`kinecal::calibrate::checks`] (metres or inches in `_mm` columns, radians in `_deg`
/// ones: one line naming the mistake).
pub fn check_units(file: &kinecal::io::model_file::ModelFile, d: &kinecal::io::data_file::DataSet, check: bool) -> anyhow::Result<()> {
    if let Some(note) = kinecal::io::data_file::si_units_note(&d.path) {
        eprintln!("note: {note}");
    }
    if check {
        kinecal::calibrate::checks::plausible_angles(file, d)?;
        kinecal::calibrate::checks::plausible_units(file, d)?;
    }
    Ok(())
}
