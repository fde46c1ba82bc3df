//! Progress of long work: a bar on a terminal; where stderr is not one
//! (logs, CI, a pipe), a line at every tenth of the work once it has run a
//! second (`HITEX_PROGRESS_AFTER` sets that delay in seconds), so that no
//! long command is silent anywhere.

use indicatif::{ProgressBar, ProgressStyle};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// A progress bar with the line fallback.
pub(crate) struct Progress {
    pb: ProgressBar,
    what: String,
    unit: std::sync::Mutex<String>,
    /// Lines instead of the bar (stderr is not a terminal).
    lines: bool,
    start: Instant,
    after: f64,
    /// The last tenth reported.
    decile: AtomicU64,
}

impl Progress {
    /// A bar over `len` steps (0: set later) named `what`, counting `unit`.
    pub(crate) fn new(len: u64, what: &str, unit: &str, template: &str) -> Progress {
        let pb = ProgressBar::new(len);
        pb.set_style(
            ProgressStyle::with_template(template)
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        pb.set_prefix(what.to_string());
        let after = std::env::var("HITEX_PROGRESS_AFTER").ok().and_then(|v| v.parse::<f64>().ok()).unwrap_or(1.0);
        Progress {
            pb,
            what: what.to_string(),
            unit: std::sync::Mutex::new(unit.to_string()),
            lines: !std::io::IsTerminal::is_terminal(&std::io::stderr()),
            start: Instant::now(),
            after,
            decile: AtomicU64::new(0),
        }
    }

    /// Shows nothing, neither bar nor lines (`--quiet`).
    pub(crate) fn hidden() -> Progress {
        let mut p = Progress::new(0, "", "", "");
        p.pb = ProgressBar::hidden();
        p.lines = false;
        p
    }

    pub(crate) fn set_length(&self, len: u64) {
        self.pb.set_length(len);
    }

    pub(crate) fn set_position(&self, done: u64) {
        self.pb.set_position(done);
        self.report();
    }

    pub(crate) fn inc(&self, n: u64) {
        self.pb.inc(n);
        self.report();
    }

    /// What the steps count (shown after the counts).
    pub(crate) fn set_message(&self, unit: &str) {
        self.pb.set_message(unit.to_string());
        if let Ok(mut u) = self.unit.lock() {
            *u = unit.to_string();
        }
    }

    /// Runs `f` with the bar out of the way of its output.
    pub(crate) fn suspend<R>(&self, f: impl FnOnce() -> R) -> R {
        self.pb.suspend(f)
    }

    pub(crate) fn finish_and_clear(&self) {
        self.pb.finish_and_clear();
    }

    fn report(&self) {
        let (done, total) = (self.pb.position(), self.pb.length().unwrap_or(0));
        if !self.lines || total == 0 || self.start.elapsed().as_secs_f64() < self.after {
            return;
        }
        let d = done.min(total) * 10 / total;
        if d > self.decile.fetch_max(d, Ordering::Relaxed) {
            let unit = self.unit.lock().map(|u| u.clone()).unwrap_or_default();
            let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
            eprintln!("hitex: {}: {done}/{total}{unit} ({}%)", self.what, d * 10);
        }
    }
}
