//! The HTTP server: embedded assets on `/`, one WebSocket per page on `/ws`.
//!
//! Per connection: a reader routes messages, a writer sends replies, and three workers run the
//! requests on blocking threads: commands in order (opening, detection, ...; one at a time, each
//! cancellable), drags and retargeting requests through a "latest value" slot so a slow solve
//! drops stale frames instead of queueing them. Choosing handles (which builds the deformation
//! session the first time) is cancellable too. When the socket closes the running jobs are
//! cancelled, the workers stop and the session is dropped.
//!
//! Size limits: the WebSocket transport accepts messages up to twice the larger application
//! limit, so a message over an application limit (but under that) is read and answered with an
//! error naming the limit, on the same connection; only a message over the transport limit closes
//! the connection (code 1009).

use std::net::SocketAddr;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use axum::Router;
use axum::extract::ws::{CloseFrame, Message, WebSocket, WebSocketUpgrade};
use axum::extract::{ConnectInfo, State};
use axum::http::{HeaderMap, Method, StatusCode, Uri, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use futures_util::{SinkExt, StreamExt};
use motif_core::geometry::Mat4;
use tokio::sync::{Notify, mpsc};

use crate::cancel::{Cancelled, JobProgress, Jobs};
use crate::error::{Result, StudioError};
use crate::protocol::{ClientMessage, HandleSpec, Limits, ServerMessage, decode_upload, unix_ms};
use crate::sandbox::Sandbox;
use crate::session::{self, Out, Session, SessionCounter, Shared};

/// Shared by every connection.
pub(crate) struct App {
    pub sandbox: Arc<Sandbox>,
    pub limits: Limits,
    pub seed: u64,
    pub model: Option<String>,
    pub counter: SessionCounter,
    /// Host names a WebSocket `Host` header may carry (DNS-rebinding guard); empty: any.
    pub allowed_hosts: Vec<String>,
}

pub(crate) fn router(app: Arc<App>) -> Router {
    Router::new().route("/ws", get(ws_handler)).fallback(static_handler).with_state(app)
}

async fn static_handler(method: Method, uri: Uri) -> Response {
    // The page and its assets are read-only: other methods are refused (a POST used to get the
    // page, 200), as static file servers do.
    if method != Method::GET && method != Method::HEAD {
        return (StatusCode::METHOD_NOT_ALLOWED, [(header::ALLOW, "GET, HEAD")], "method not allowed")
            .into_response();
    }
    match crate::assets::find(uri.path()) {
        Some(a) => (
            [
                (header::CONTENT_TYPE, a.mime),
                (header::CACHE_CONTROL, "no-cache"),
                (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            ],
            a.body,
        )
            .into_response(),
        None => (StatusCode::NOT_FOUND, "not found").into_response(),
    }
}

/// The host part of a `Host` header or an origin's authority (`[::1]:80` → `[::1]`).
fn host_name(authority: &str) -> &str {
    if authority.starts_with('[') {
        return authority.split(']').next().map(|h| &authority[..h.len() + 1]).unwrap_or(authority);
    }
    authority.split(':').next().unwrap_or(authority)
}

/// Browsers send `Origin`: it must be this server (a page elsewhere must not drive the studio,
/// cross-site WebSocket hijacking), and `Host` must name this machine (DNS rebinding).
fn request_allowed(headers: &HeaderMap, allowed_hosts: &[String]) -> bool {
    let host = headers.get(header::HOST).and_then(|h| h.to_str().ok()).unwrap_or("");
    if !allowed_hosts.is_empty() && !allowed_hosts.iter().any(|a| a == host_name(host)) {
        return false;
    }
    match headers.get(header::ORIGIN).map(|o| o.to_str()) {
        None => true,
        Some(Ok(origin)) => origin == format!("http://{host}"),
        Some(Err(_)) => false,
    }
}

async fn ws_handler(
    ws: WebSocketUpgrade,
    headers: HeaderMap,
    ConnectInfo(_peer): ConnectInfo<SocketAddr>,
    State(app): State<Arc<App>>,
) -> Response {
    if !request_allowed(&headers, &app.allowed_hosts) {
        return (StatusCode::FORBIDDEN, "the studio accepts WebSocket connections from its own page only")
            .into_response();
    }
    if app.counter.get() >= app.limits.max_sessions {
        return (StatusCode::SERVICE_UNAVAILABLE, "too many open studio pages; close one").into_response();
    }
    let max = transport_limit(&app.limits);
    ws.max_message_size(max).max_frame_size(max).on_upgrade(move |socket| connection(socket, app))
}

/// The WebSocket transport's message limit: twice the larger application limit, so oversized
/// messages up to that size get an error reply instead of a closed connection.
fn transport_limit(limits: &Limits) -> usize {
    limits.max_upload_bytes.max(limits.max_text_bytes).saturating_mul(2).saturating_add(4096)
}

/// Sends replies to the writer task.
#[derive(Clone)]
struct Outbox(mpsc::Sender<Message>);

impl Outbox {
    async fn text(&self, m: &ServerMessage) {
        if let Ok(t) = serde_json::to_string(m) {
            let _ = self.0.send(Message::Text(t.into())).await;
        }
    }

    async fn error(&self, e: &StudioError, request: &str) {
        let m = ServerMessage::Error { message: e.to_string(), request: Some(request.to_string()) };
        self.text(&m).await;
    }

    async fn send_all(&self, outs: Vec<Out>) {
        for o in outs {
            match o {
                Out::Text(m) => self.text(&m).await,
                Out::Binary(b) => {
                    let _ = self.0.send(Message::Binary(b.into())).await;
                }
            }
        }
    }

    async fn reply(&self, r: Result<Vec<Out>>, request: &str) {
        match r {
            Ok(outs) => self.send_all(outs).await,
            Err(StudioError::Cancelled) => {
                self.text(&ServerMessage::Cancelled { job: request.to_string() }).await
            }
            Err(e) => self.error(&e, request).await,
        }
    }
}

/// A slot holding only the newest request; the worker takes it when it is free.
struct Latest<T> {
    value: Mutex<T>,
    notify: Notify,
    closed: AtomicBool,
}

impl<T: Default + Pending> Latest<T> {
    fn new() -> Arc<Self> {
        Arc::new(Latest {
            value: Mutex::new(T::default()),
            notify: Notify::new(),
            closed: AtomicBool::new(false),
        })
    }

    fn update(&self, f: impl FnOnce(&mut T)) {
        f(&mut self.value.lock().unwrap_or_else(|e| e.into_inner()));
        self.notify.notify_one();
    }

    fn close(&self) {
        self.closed.store(true, Ordering::SeqCst);
        self.notify.notify_one();
    }

    /// The pending value (reset to default), or `None` once closed.
    async fn take(&self) -> Option<T> {
        loop {
            if self.closed.load(Ordering::SeqCst) {
                return None;
            }
            {
                let mut v = self.value.lock().unwrap_or_else(|e| e.into_inner());
                let taken = std::mem::take(&mut *v);
                if !taken.is_empty() {
                    return Some(taken);
                }
            }
            self.notify.notified().await;
        }
    }
}

/// A slot value that may hold nothing.
trait Pending {
    fn is_empty(&self) -> bool;
}

impl Pending for Option<(u32, [i32; 3])> {
    fn is_empty(&self) -> bool {
        self.is_none()
    }
}

/// A pending drag: sequence number, transforms, normals wanted, when it arrived (monotonic and
/// Unix ms).
type PendingDrag = (u32, Vec<Mat4>, bool, (Instant, f64));

/// Pending deformation requests, applied in this order: new handles, newest drag, release.
#[derive(Default)]
struct DeformQueue {
    handles: Option<(Vec<HandleSpec>, Vec<Option<Mat4>>)>,
    drag: Option<PendingDrag>,
    release: bool,
}

impl Pending for DeformQueue {
    fn is_empty(&self) -> bool {
        self.handles.is_none() && self.drag.is_none() && !self.release
    }
}

/// Runs a blocking operation; a panic (a bug) becomes an error reply.
async fn blocking(f: impl FnOnce() -> Result<Vec<Out>> + Send + 'static, what: &str) -> Result<Vec<Out>> {
    match tokio::task::spawn_blocking(move || std::panic::catch_unwind(AssertUnwindSafe(f))).await {
        Ok(Ok(r)) => r,
        Ok(Err(p)) if p.is::<Cancelled>() => Err(StudioError::Cancelled),
        _ => Err(StudioError::Internal(what.to_string())),
    }
}

enum Command {
    Message(ClientMessage),
    Upload(String, Vec<u8>),
}

fn request_name(m: &ClientMessage) -> &'static str {
    match m {
        ClientMessage::Open { .. } => "open",
        ClientMessage::Example { .. } => "example",
        ClientMessage::DetectSymmetry => "detect_symmetry",
        ClientMessage::LoadAnnotation { .. } => "load_annotation",
        ClientMessage::SaveAnnotation { .. } => "save_annotation",
        ClientMessage::SetHandles { .. } => "set_handles",
        ClientMessage::Drag { .. } => "drag",
        ClientMessage::Release => "release",
        ClientMessage::Export { .. } => "export",
        ClientMessage::Offsets => "offsets",
        ClientMessage::Retarget { .. } => "retarget",
        ClientMessage::LoadDetections { .. } => "load_detections",
        ClientMessage::Detect => "detect",
        ClientMessage::SaveDetections { .. } => "save_detections",
        ClientMessage::ListFiles => "list_files",
        ClientMessage::Cancel => "cancel",
    }
}

/// Runs `work` as a cancellable job: a cancel replies at once; the blocking thread stops at its
/// next progress report (or finishes) and its result is not committed (see
/// `JobProgress::check`).
async fn run_job(
    job: &str,
    jobs: &Jobs,
    out: &Outbox,
    work: impl FnOnce(&JobProgress) -> Result<Vec<Out>> + Send + 'static,
) {
    let (token, _guard) = jobs.start();
    let progress = JobProgress::new(job, out.0.clone(), token.clone());
    let result = tokio::select! {
        r = blocking(move || work(&progress), job) => Some(r),
        _ = token.cancelled() => None,
    };
    match result {
        None => out.text(&ServerMessage::Cancelled { job: job.to_string() }).await,
        Some(r) => out.reply(r, job).await,
    }
}

/// Runs one command as a cancellable job.
async fn run_command(cmd: Command, shared: &Shared, out: &Outbox, jobs: &Jobs) {
    let job = match &cmd {
        Command::Message(m) => request_name(m),
        Command::Upload(..) => "upload",
    };
    let shared = shared.clone();
    let work = move |p: &JobProgress| -> Result<Vec<Out>> {
        match cmd {
            Command::Upload(name, bytes) => session::upload(&shared, &name, &bytes, p),
            Command::Message(m) => match m {
                ClientMessage::Open { path } => session::open(&shared, &path, p),
                ClientMessage::Example { name } => session::example(&shared, &name, p),
                ClientMessage::DetectSymmetry => session::detect_symmetry(&shared, p),
                ClientMessage::LoadAnnotation { path } => session::load_annotation(&shared, &path, p),
                ClientMessage::SaveAnnotation { path, overwrite } => {
                    session::save_annotation(&shared, &path, overwrite)
                }
                ClientMessage::Export { path, source, overwrite, download } => {
                    session::export(&shared, &path, source, overwrite, download)
                }
                ClientMessage::Offsets => session::offsets(&shared, p),
                ClientMessage::LoadDetections { path } => session::load_detections(&shared, &path),
                ClientMessage::Detect => session::detect(&shared, p),
                ClientMessage::ListFiles => session::list_files(&shared),
                ClientMessage::SaveDetections { path, overwrite } => {
                    session::save_detections(&shared, &path, overwrite)
                }
                _ => Ok(Vec::new()),
            },
        }
    };
    run_job(job, jobs, out, work).await;
}

async fn deform_worker(shared: Shared, out: Outbox, slot: Arc<Latest<DeformQueue>>, jobs: Jobs) {
    while let Some(q) = slot.take().await {
        if let Some((h, t)) = q.handles {
            let s = shared.clone();
            run_job("set_handles", &jobs, &out, move |p| session::set_handles(&s, &h, &t, p)).await;
        }
        if let Some((seq, t, normals, received)) = q.drag {
            let s = shared.clone();
            out.reply(blocking(move || session::drag(&s, seq, &t, normals, received), "drag").await, "drag")
                .await;
        }
        if q.release {
            let s = shared.clone();
            out.reply(blocking(move || session::release(&s), "release").await, "release").await;
        }
    }
}

async fn retarget_worker(shared: Shared, out: Outbox, slot: Arc<Latest<Option<(u32, [i32; 3])>>>) {
    while let Some(Some((seq, steps))) = slot.take().await {
        let s = shared.clone();
        out.reply(blocking(move || session::retarget(&s, seq, steps), "retarget").await, "retarget").await;
    }
}

async fn connection(socket: WebSocket, app: Arc<App>) {
    let (mut sink, mut stream) = socket.split();
    let (tx, mut rx) = mpsc::channel::<Message>(32);
    let writer = tokio::spawn(async move {
        while let Some(m) = rx.recv().await {
            let close = matches!(m, Message::Close(_));
            if sink.send(m).await.is_err() || close {
                break;
            }
        }
        let _ = sink.close().await;
    });
    let out = Outbox(tx);
    let shared: Shared = Arc::new(Mutex::new(Session::new(app.sandbox.clone(), app.seed, &app.counter)));
    out.text(&ServerMessage::Hello {
        version: env!("CARGO_PKG_VERSION").to_string(),
        root: app.sandbox.root().display().to_string(),
        limits: app.limits,
        examples: motif_core::procedural::names().iter().map(|s| s.to_string()).collect(),
    })
    .await;

    let jobs = Jobs::default();
    let (cmd_tx, mut cmd_rx) = mpsc::channel::<Command>(8);
    let deform_slot = Latest::<DeformQueue>::new();
    let retarget_slot = Latest::<Option<(u32, [i32; 3])>>::new();
    let commands = {
        let (shared, out, jobs) = (shared.clone(), out.clone(), jobs.clone());
        tokio::spawn(async move {
            while let Some(cmd) = cmd_rx.recv().await {
                if jobs.is_closed() {
                    continue; // the client left: queued requests are dropped, not run
                }
                run_command(cmd, &shared, &out, &jobs).await;
            }
        })
    };
    let deformer =
        tokio::spawn(deform_worker(shared.clone(), out.clone(), deform_slot.clone(), jobs.clone()));
    let retargeter = tokio::spawn(retarget_worker(shared.clone(), out.clone(), retarget_slot.clone()));
    drop(shared);
    if let Some(path) = &app.model {
        let _ = cmd_tx.try_send(Command::Message(ClientMessage::Open { path: path.clone() }));
    }

    while let Some(msg) = stream.next().await {
        let msg = match msg {
            Ok(m) => m,
            Err(e) => {
                // Over the protocol limit (or a broken frame): say why, then drop this client.
                let text = e.to_string();
                let code = if text.contains("too long") || text.contains("limit") { 1009 } else { 1002 };
                let _ = out
                    .0
                    .try_send(Message::Close(Some(CloseFrame { code, reason: truncate(&text, 120).into() })));
                break;
            }
        };
        let cmd = match msg {
            Message::Text(t) => {
                if t.len() > app.limits.max_text_bytes {
                    let e = StudioError::BadMessage(format!(
                        "{} bytes: text messages are limited to {} bytes",
                        t.len(),
                        app.limits.max_text_bytes
                    ));
                    out.error(&e, "message").await;
                    continue;
                }
                match serde_json::from_str::<ClientMessage>(t.as_str()) {
                    Ok(m) => m,
                    Err(e) => {
                        out.error(&StudioError::BadMessage(truncate(&e.to_string(), 300)), "message").await;
                        continue;
                    }
                }
            }
            Message::Binary(b) => {
                if b.len() > app.limits.max_upload_bytes {
                    let e = StudioError::BadMessage(format!(
                        "upload of {} bytes: the limit is {} bytes",
                        b.len(),
                        app.limits.max_upload_bytes
                    ));
                    out.error(&e, "upload").await;
                    continue;
                }
                match decode_upload(&b) {
                    Some((name, bytes)) => {
                        if cmd_tx.try_send(Command::Upload(name, bytes.to_vec())).is_err() {
                            out.error(&StudioError::Busy("earlier requests".to_string()), "upload").await;
                        }
                    }
                    None => {
                        let e = StudioError::BadMessage(
                            "an upload is [name length u32 LE][name][bytes]".to_string(),
                        );
                        out.error(&e, "upload").await;
                    }
                }
                continue;
            }
            Message::Close(_) => break,
            _ => continue,
        };
        match cmd {
            ClientMessage::Cancel => jobs.cancel_all(),
            ClientMessage::SetHandles { handles, transforms } => deform_slot.update(|q| {
                q.handles = Some((handles, transforms));
                q.drag = None;
            }),
            ClientMessage::Drag { seq, transforms, normals } => {
                let received = (Instant::now(), unix_ms());
                deform_slot.update(|q| q.drag = Some((seq, transforms, normals, received)))
            }
            ClientMessage::Release => deform_slot.update(|q| q.release = true),
            ClientMessage::Retarget { seq, steps } => retarget_slot.update(|q| *q = Some((seq, steps))),
            other => {
                let name = request_name(&other);
                if cmd_tx.try_send(Command::Message(other)).is_err() {
                    out.error(&StudioError::Busy("earlier requests".to_string()), name).await;
                }
            }
        }
    }

    // Disconnected: stop the running jobs, the workers, and with them the session.
    jobs.close();
    drop(cmd_tx);
    deform_slot.close();
    retarget_slot.close();
    let _ = tokio::join!(commands, deformer, retargeter);
    drop(out);
    let _ = writer.await;
}

fn truncate(s: &str, n: usize) -> String {
    crate::sandbox::shorten(&s.chars().take(n).collect::<String>())
}
