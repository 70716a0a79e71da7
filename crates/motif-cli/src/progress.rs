//! indicatif progress bars behind the library's `Progress` trait: drawn on stderr, and only when
//! both stdout and stderr are terminals and `--quiet` is not given.

use std::io::IsTerminal;
use std::sync::Mutex;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use motif_core::progress::Progress;

/// A progress reporter for one command.
pub struct Bar {
    visible: bool,
    bar: Mutex<Option<ProgressBar>>,
}

impl Bar {
    /// A reporter that draws only when appropriate.
    pub fn new(quiet: bool) -> Bar {
        let visible = !quiet && std::io::stdout().is_terminal() && std::io::stderr().is_terminal();
        Bar { visible, bar: Mutex::new(None) }
    }
}

impl Bar {
    /// Runs `f` under a spinner labelled `stage` (for library steps that report no progress).
    pub fn spin<T>(&self, stage: &str, f: impl FnOnce() -> T) -> T {
        self.start(stage, 0);
        let out = f();
        self.finish();
        out
    }
}

impl Progress for Bar {
    fn start(&self, stage: &str, total: u64) {
        if !self.visible {
            return;
        }
        let pb = if total > 0 {
            ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr())
        } else {
            ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr())
        };
        let style = if total > 0 {
            ProgressStyle::with_template("{msg:>14} [{bar:40}] {pos}/{len} ({eta})")
        } else {
            ProgressStyle::with_template("{msg:>14} {spinner} {elapsed}")
        };
        if let Ok(s) = style {
            pb.set_style(s.progress_chars("=> "));
        }
        pb.set_message(stage.to_string());
        if total == 0 {
            pb.enable_steady_tick(std::time::Duration::from_millis(120));
        }
        if let Ok(mut g) = self.bar.lock() {
            if let Some(old) = g.replace(pb) {
                old.finish_and_clear();
            }
        }
    }

    fn inc(&self, n: u64) {
        if let Ok(g) = self.bar.lock() {
            if let Some(pb) = g.as_ref() {
                pb.inc(n);
            }
        }
    }

    fn finish(&self) {
        if let Ok(mut g) = self.bar.lock() {
            if let Some(pb) = g.take() {
                pb.finish_and_clear();
            }
        }
    }
}
