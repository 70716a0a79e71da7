//! Cancelling long computations and reporting their progress to the page.
//!
//! The library's long computations take a `&dyn motif_core::progress::Progress` and call it from
//! their loops (also from rayon workers). [`JobProgress`] forwards those calls to the page as
//! throttled `progress` messages, and when the client has cancelled it unwinds out of the
//! computation with [`std::panic::resume_unwind`] and a [`Cancelled`] payload: no panic hook runs,
//! rayon carries the payload to the caller, and the job runner recognises it. Library state is
//! plain owned data built by the computation, so unwinding out of it leaves nothing behind.
//! Computations that never report progress (building a deformation session) cannot be stopped
//! this way; for them a cancel only discards the result.

use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use axum::extract::ws::Message;
use motif_core::progress::Progress;
use tokio::sync::{Notify, mpsc};

use crate::protocol::ServerMessage;

/// The unwind payload of a cancelled computation.
#[derive(Debug, Clone, Copy)]
pub struct Cancelled;

/// A cancellation flag shared by the connection and the computation.
#[derive(Debug, Clone, Default)]
pub struct CancelToken {
    inner: Arc<(AtomicBool, Notify)>,
}

impl CancelToken {
    /// A fresh, not cancelled token.
    pub fn new() -> Self {
        Self::default()
    }

    /// Requests cancellation.
    pub fn cancel(&self) {
        self.inner.0.store(true, Ordering::SeqCst);
        self.inner.1.notify_waiters();
    }

    /// Whether cancellation was requested.
    pub fn is_cancelled(&self) -> bool {
        self.inner.0.load(Ordering::SeqCst)
    }

    /// Resolves once cancelled.
    pub async fn cancelled(&self) {
        loop {
            let notified = self.inner.1.notified();
            if self.is_cancelled() {
                return;
            }
            notified.await;
        }
    }
}

/// Minimum time between two progress messages of one job.
const PROGRESS_INTERVAL: Duration = Duration::from_millis(100);

/// A [`Progress`] that sends throttled `progress` messages and stops the computation on cancel.
pub struct JobProgress {
    job: String,
    out: mpsc::Sender<Message>,
    token: CancelToken,
    stage: Mutex<(String, u64, Instant)>,
    done: AtomicU64,
}

impl JobProgress {
    /// Progress of `job`, sent on `out`, cancelled by `token`.
    pub fn new(job: &str, out: mpsc::Sender<Message>, token: CancelToken) -> Self {
        JobProgress {
            job: job.to_string(),
            out,
            token,
            stage: Mutex::new((String::new(), 0, Instant::now() - PROGRESS_INTERVAL)),
            done: AtomicU64::new(0),
        }
    }

    /// Unwinds with [`Cancelled`] when the job was cancelled.
    pub fn check(&self) {
        if self.token.is_cancelled() {
            std::panic::resume_unwind(Box::new(Cancelled));
        }
    }

    /// The job's token.
    pub fn token(&self) -> &CancelToken {
        &self.token
    }

    fn send(&self, force: bool) {
        let Ok(mut st) = self.stage.lock() else { return };
        if !force && st.2.elapsed() < PROGRESS_INTERVAL {
            return;
        }
        st.2 = Instant::now();
        let msg = ServerMessage::Progress {
            job: self.job.clone(),
            stage: st.0.clone(),
            done: self.done.load(Ordering::Relaxed),
            total: st.1,
        };
        if let Ok(text) = serde_json::to_string(&msg) {
            // Progress is advisory: when the connection is congested it is dropped, not queued.
            let _ = self.out.try_send(Message::Text(text.into()));
        }
    }

    /// Reports a stage of the studio's own (e.g. "reading").
    pub fn stage(&self, stage: &str) {
        self.start(stage, 0);
    }
}

impl Progress for JobProgress {
    fn start(&self, stage: &str, total: u64) {
        self.check();
        if let Ok(mut st) = self.stage.lock() {
            st.0 = stage.to_string();
            st.1 = total;
        }
        self.done.store(0, Ordering::Relaxed);
        self.send(true);
    }

    fn inc(&self, n: u64) {
        self.check();
        self.done.fetch_add(n, Ordering::Relaxed);
        self.send(false);
    }

    fn finish(&self) {
        self.check();
    }
}
