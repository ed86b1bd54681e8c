//! Progress bars on standard error (hidden with `--json` and when stderr is not a terminal).
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::sync::{Mutex, OnceLock};
use std::time::Duration;

/// A bar over `n` steps called `what`.
pub fn bar(n: usize, what: &str, hidden: bool) -> ProgressBar {
    if hidden {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::with_draw_target(Some(n as u64), ProgressDrawTarget::stderr());
    pb.set_style(
        ProgressStyle::with_template("{msg:>14} [{bar:40}] {pos}/{len} ({elapsed})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

/// A spinner for a step of unknown length.
pub fn spinner(what: &str, hidden: bool) -> ProgressBar {
    if hidden {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
    pb.set_style(ProgressStyle::with_template("{spinner} {msg} ({elapsed})").expect("valid template"));
    pb.set_message(what.to_string());
    pb.enable_steady_tick(Duration::from_millis(120));
    pb
}

/// Progress of a run in stages, fed from any thread (a library call's progress callback): each
/// [`Stages::start`] replaces the bar, [`Stages::spin`] ends it and shows a spinner with a message,
/// [`Stages::finish`] clears both.
pub struct Stages {
    hidden: bool,
    bar: Mutex<ProgressBar>,
    spinner: OnceLock<ProgressBar>,
}

impl Stages {
    /// No bar yet; `hidden` hides everything.
    pub fn new(hidden: bool) -> Self {
        Stages {
            hidden,
            bar: Mutex::new(ProgressBar::hidden()),
            spinner: OnceLock::new(),
        }
    }

    /// A new bar over `n` steps called `what` (the previous one cleared).
    pub fn start(&self, n: usize, what: &str) {
        let mut bar = self.bar.lock().unwrap_or_else(|e| e.into_inner());
        bar.finish_and_clear();
        *bar = self::bar(n, what, self.hidden);
    }

    /// `k` more steps done.
    pub fn inc(&self, k: u64) {
        self.bar.lock().unwrap_or_else(|e| e.into_inner()).inc(k);
    }

    /// Clear the bar (its stage is over).
    pub fn end(&self) {
        self.bar.lock().unwrap_or_else(|e| e.into_inner()).finish_and_clear();
    }

    /// End the bar and show `message` on the spinner.
    pub fn spin(&self, message: String) {
        self.end();
        self.spinner.get_or_init(|| spinner("", self.hidden)).set_message(message);
    }

    /// Clear the bar and the spinner.
    pub fn finish(&self) {
        self.end();
        if let Some(s) = self.spinner.get() {
            s.finish_and_clear();
        }
    }
}
