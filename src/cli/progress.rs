//! Progress on long work: a bar with the time left (indicatif) on standard error when it is a
//! terminal, nothing when it is not or with `--quiet`. Standard output (`--json`) never sees it.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::time::Duration;

/// A progress bar over `total` steps, or a spinner for work of unknown length.
pub struct Progress {
    bar: Option<ProgressBar>,
    quiet: bool,
}

impl Progress {
    fn shown(quiet: bool) -> bool {
        !quiet && std::io::stderr().is_terminal()
    }

    /// A bar over `total` steps of `what` (e.g. "settings"), with the time left.
    pub fn bar(total: u64, what: &str, quiet: bool) -> Progress {
        let bar = Self::shown(quiet).then(|| {
            let b = ProgressBar::new(total);
            b.set_style(
                ProgressStyle::with_template(&format!(
                    "{{bar:30}} {{pos}}/{{len}} {what}, {{elapsed}} gone, about {{eta}} left"
                ))
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            b
        });
        Progress { bar, quiet }
    }

    /// A spinner with the elapsed time, for work whose length is not known ahead (`what`:
    /// "fitting hysteresis,dynamics").
    pub fn spinner(what: &str, quiet: bool) -> Progress {
        let bar = Self::shown(quiet).then(|| {
            let b = ProgressBar::new_spinner();
            b.set_style(
                ProgressStyle::with_template("{spinner} {msg} ({elapsed})")
                    .unwrap_or_else(|_| ProgressStyle::default_spinner()),
            );
            b.set_message(what.to_string());
            b.enable_steady_tick(Duration::from_millis(200));
            b
        });
        Progress { bar, quiet }
    }

    /// One step done.
    pub fn inc(&self) {
        if let Some(b) = &self.bar {
            b.inc(1);
        }
    }

    /// A line said even when quiet, above the bar.
    pub fn notice(&self, text: &str) {
        match &self.bar {
            Some(b) => b.println(text),
            None => eprintln!("{text}"),
        }
    }

    /// A line of the log, above the bar (on standard error, unless quiet).
    pub fn line(&self, text: &str) {
        match &self.bar {
            Some(b) => b.println(text),
            None if !self.quiet => eprintln!("{text}"),
            None => {}
        }
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}
