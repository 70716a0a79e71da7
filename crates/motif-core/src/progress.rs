//! Progress reporting that library code can call without knowing about terminals.
//!
//! Algorithms that run longer than about a second take a `&dyn Progress` and report steps; the CLI
//! passes an indicatif bar (hidden when stdout is not a terminal or with `--quiet`), tests and
//! library users pass [`NoProgress`].

/// Receives progress from a long computation. Implementations must be cheap and thread-safe:
/// `inc` is called from rayon workers.
pub trait Progress: Sync {
    /// A new stage begins with `total` units of work (0 when unknown).
    fn start(&self, stage: &str, total: u64);
    /// `n` more units of the current stage are done.
    fn inc(&self, n: u64);
    /// The current stage is finished.
    fn finish(&self);
}

/// A [`Progress`] that ignores everything.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoProgress;

impl Progress for NoProgress {
    fn start(&self, _stage: &str, _total: u64) {}
    fn inc(&self, _n: u64) {}
    fn finish(&self) {}
}
