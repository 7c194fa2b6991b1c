//! Progress of long steps: one line on stderr every [`EVERY`] whether or not stderr is a
//! terminal (a log file or a pipe gets the same lines), none with `--quiet`; Ctrl-C asks the
//! step to stop, and the command then writes nothing.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use visuotact_nn::fit::FitProgress;
use visuotact_nn::lm::Control;
use visuotact_pipeline::replay::ReplayError;
use visuotact_pipeline::sink::FrameSink;

/// Time between two progress lines.
pub(crate) const EVERY: Duration = Duration::from_secs(2);

/// Prints a step's progress now and then and carries Ctrl-C to it.
pub(crate) struct Reporter {
    quiet: bool,
    stop: Arc<AtomicBool>,
    stage: Mutex<Stage>,
    finished: AtomicUsize,
}

struct Stage {
    name: String,
    started: Instant,
    last_line: Instant,
}

impl Reporter {
    /// A reporter (silent when `quiet`) whose [`Reporter::interrupted`] turns true on Ctrl-C.
    pub(crate) fn new(quiet: bool) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        // A second handler cannot be set (a test harness may have one): Ctrl-C then kills the
        // process as it would without one, which also writes nothing half-done.
        let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
        let now = Instant::now();
        Self {
            quiet,
            stop,
            stage: Mutex::new(Stage {
                name: String::new(),
                started: now,
                last_line: now,
            }),
            finished: AtomicUsize::new(0),
        }
    }

    /// Starts a stage called `name` (its first line says so at once).
    pub(crate) fn stage(&self, name: &str) {
        let now = Instant::now();
        if let Ok(mut s) = self.stage.lock() {
            *s = Stage {
                name: name.to_string(),
                started: now,
                last_line: now,
            };
        }
        self.finished.store(0, Ordering::Relaxed);
        self.line(format_args!("{name}: started"));
    }

    /// Whether Ctrl-C was pressed.
    pub(crate) fn interrupted(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    fn line(&self, args: std::fmt::Arguments<'_>) {
        if !self.quiet {
            note!("{args}");
        }
    }

    /// The callback for a training: a line every [`EVERY`] (network k of K, epoch, error,
    /// elapsed, an estimate of the time left once a network has finished); stops on Ctrl-C.
    pub(crate) fn training(&self, p: &FitProgress) -> Control {
        if self.interrupted() {
            return Control::Stop;
        }
        let finished = if p.finished {
            self.finished.fetch_add(1, Ordering::Relaxed) + 1
        } else {
            self.finished.load(Ordering::Relaxed)
        };
        let Some((name, elapsed)) = self.due() else {
            return Control::Continue;
        };
        let left = if finished == 0 {
            "time left known after the first network".to_string()
        } else {
            let rest = elapsed * (p.networks.saturating_sub(finished)) as f64 / finished as f64;
            format!("about {} left", seconds(rest))
        };
        let validation = if p.validation_mse.is_nan() {
            String::new()
        } else {
            format!(", validation {:.3e}", p.validation_mse)
        };
        self.line(format_args!(
            "{}: network {} of {}, epoch {}, mse {:.3e}{validation} (scaled); {} done of {}, {} elapsed, {left}",
            name,
            p.network + 1,
            p.networks,
            p.epoch,
            p.train_mse,
            finished,
            p.networks,
            seconds(elapsed)
        ));
        Control::Continue
    }
}

impl Reporter {
    /// Whether a line is due (and marks it printed), with the stage's name and elapsed time.
    fn due(&self) -> Option<(String, f64)> {
        let now = Instant::now();
        let mut s = self.stage.lock().ok()?;
        if now.duration_since(s.last_line) < EVERY {
            return None;
        }
        s.last_line = now;
        Some((s.name.clone(), now.duration_since(s.started).as_secs_f64()))
    }

    /// The callback for a pass over frames (or any counted items): a line every [`EVERY`]
    /// (`done` of `total` items, elapsed, time left when the total is known); stops on Ctrl-C.
    pub(crate) fn items(&self, done: usize, total: Option<usize>, what: &str) -> ControlFlow<()> {
        if self.interrupted() {
            return ControlFlow::Break(());
        }
        if let Some((name, elapsed)) = self.due() {
            let of = match total {
                Some(t) if done > 0 => format!(
                    " of {t}, {} elapsed, about {} left",
                    seconds(elapsed),
                    seconds(elapsed * t.saturating_sub(done) as f64 / done as f64)
                ),
                Some(t) => format!(" of {t}, {} elapsed", seconds(elapsed)),
                None => format!(", {} elapsed", seconds(elapsed)),
            };
            self.line(format_args!("{name}: {done} {what}{of}"));
        }
        ControlFlow::Continue(())
    }
}

/// A pass over frames seen from the command line: at most `max_warnings` warnings printed (the
/// rest counted), progress lines and Ctrl-C from the [`Reporter`].
pub(crate) struct FramePass<'a> {
    reporter: &'a Reporter,
    max_warnings: usize,
    /// Warnings heard, printed or not.
    pub(crate) warned: usize,
}

impl<'a> FramePass<'a> {
    /// A pass reporting to `reporter`, printing the first `max_warnings` warnings.
    pub(crate) fn new(reporter: &'a Reporter, max_warnings: usize) -> Self {
        Self {
            reporter,
            max_warnings,
            warned: 0,
        }
    }

    /// Says how many warnings were not printed, if any.
    pub(crate) fn print_unshown(&self) {
        if self.warned > self.max_warnings && self.max_warnings > 0 {
            note!(
                "… {} more warnings not shown",
                self.warned - self.max_warnings
            );
        }
    }
}

impl FrameSink for FramePass<'_> {
    fn warn(&mut self, message: &str) {
        if self.warned < self.max_warnings {
            note!("warning: {message}");
        }
        self.warned += 1;
    }

    fn progress(&mut self, done: usize, total: Option<usize>) -> ControlFlow<()> {
        self.reporter.items(done, total, "frames")
    }
}

/// A pass's error as the command says it: a pass stopped by Ctrl-C says so and that `output`
/// was not written.
pub(crate) fn pass_error(e: ReplayError, output: &std::path::Path) -> anyhow::Error {
    match e {
        ReplayError::Stopped { frames } => anyhow::anyhow!(
            "interrupted (Ctrl-C) after {frames} frames: {} not written",
            output.display()
        ),
        e => e.into(),
    }
}

/// `s` seconds as `12 s` or `3 min 05 s`.
fn seconds(s: f64) -> String {
    let s = s.max(0.0).round() as u64;
    if s < 60 {
        format!("{s} s")
    } else {
        format!("{} min {:02} s", s / 60, s % 60)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_as_minutes_and_seconds() {
        assert_eq!(seconds(4.4), "4 s");
        assert_eq!(seconds(125.0), "2 min 05 s");
    }
}
