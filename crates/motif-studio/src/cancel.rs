//! Cancelling long computations and reporting their progress to the page.
//!
//! The library's long computations take a `&dyn motif_core::progress::Progress` and call it from
//! their loops (also from rayon workers). [`JobProgress`] forwards those calls to the page as
//! throttled `progress` messages, and when the client has cancelled it unwinds out of the
//! computation with [`std::panic::resume_unwind`] and a [`Cancelled`] payload: no panic hook runs,
//! rayon carries the payload to the caller, and the job runner recognises it. Library state is
//! plain owned data built by the computation, so unwinding out of it leaves nothing behind.
//! Building a deformation session reports its stages
//! ([`motif_deform::DeformSession::with_progress`]), so it stops at the next stage.
//!
//! [`Jobs`] holds the tokens of every running job of one connection (commands and the session
//! build run on different workers): a cancel request, or the client leaving, cancels them all.

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

/// The running jobs of one connection.
#[derive(Debug, Clone, Default)]
pub struct Jobs {
    inner: Arc<(Mutex<Vec<CancelToken>>, AtomicBool)>,
}

/// Unregisters a job's token when the job ends.
#[derive(Debug)]
pub struct JobGuard {
    jobs: Jobs,
    token: CancelToken,
}

impl Drop for JobGuard {
    fn drop(&mut self) {
        let mut v = self.jobs.inner.0.lock().unwrap_or_else(|e| e.into_inner());
        v.retain(|t| !Arc::ptr_eq(&t.inner, &self.token.inner));
    }
}

impl Jobs {
    /// A token for a new job, registered until the guard drops; already cancelled once the
    /// connection has closed.
    pub fn start(&self) -> (CancelToken, JobGuard) {
        let token = CancelToken::new();
        self.inner.0.lock().unwrap_or_else(|e| e.into_inner()).push(token.clone());
        if self.inner.1.load(Ordering::SeqCst) {
            token.cancel();
        }
        (token.clone(), JobGuard { jobs: self.clone(), token })
    }

    /// Cancels every running job.
    pub fn cancel_all(&self) {
        for t in self.inner.0.lock().unwrap_or_else(|e| e.into_inner()).iter() {
            t.cancel();
        }
    }

    /// The connection closed: cancels every running job and every job started later.
    pub fn close(&self) {
        self.inner.1.store(true, Ordering::SeqCst);
        self.cancel_all();
    }

    /// Whether [`Jobs::close`] was called.
    pub fn is_closed(&self) -> bool {
        self.inner.1.load(Ordering::SeqCst)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jobs_cancel_running_and_later_jobs() {
        let jobs = Jobs::default();
        let (a, ga) = jobs.start();
        let (b, gb) = jobs.start();
        drop(gb);
        jobs.cancel_all();
        assert!(a.is_cancelled());
        assert!(!b.is_cancelled(), "a finished job is no longer registered");
        drop(ga);
        let (c, _gc) = jobs.start();
        assert!(!c.is_cancelled());
        jobs.close();
        assert!(c.is_cancelled());
        assert!(jobs.start().0.is_cancelled());
    }
}
