//! The Motif studio: a local web app to open a model, see its structure, deform it with a mouse,
//! resize it along its repetitions and look at building-block detections.
//!
//! An axum server (bound to 127.0.0.1 unless told otherwise) serves one page with three.js — both
//! compiled into the binary, so it works offline — and a WebSocket API ([`protocol`]) over the
//! library crates. The server holds no geometry algorithm: every request calls `motif-core`
//! (reading, writing, generated examples), `motif-deform` (symmetry detection and checking, the
//! [`motif_deform::DeformSession`]), `motif-retarget` (principal offsets, the retargeting session)
//! or `motif-detect` (detection results).
//!
//! - [`protocol`]: the messages, JSON for requests and replies, binary for geometry;
//! - [`session`]: one client's state and its operations (blocking functions);
//! - [`sandbox`]: file access only under the root, checked after resolution;
//! - [`cancel`]: progress messages and cancellation of long computations;
//! - `server`: routing, size limits, stale-frame dropping, cleanup on disconnect.
//!
//! ```no_run
//! # async fn f() -> motif_studio::Result<()> {
//! let studio = motif_studio::Studio::bind(motif_studio::StudioOptions::default()).await?;
//! println!("open {}", studio.url());
//! studio.serve().await
//! # }
//! ```

#![warn(missing_docs)]

mod assets;
pub mod cancel;
pub mod error;
pub mod protocol;
pub mod sandbox;
mod server;
pub mod session;

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::PathBuf;
use std::sync::Arc;

pub use error::{Result, StudioError};
pub use protocol::{ClientMessage, Limits, ServerMessage};
pub use sandbox::Sandbox;
pub use session::SessionCounter;

/// Options of [`Studio::bind`].
#[derive(Debug, Clone, PartialEq)]
pub struct StudioOptions {
    /// Address to listen on; default 127.0.0.1 (this machine only). Anything else exposes the
    /// studio — and every file under `root` — to the network.
    pub host: IpAddr,
    /// TCP port; default 0 (a free port chosen by the system).
    pub port: u16,
    /// The only folder files are read from and written to; default the current directory.
    pub root: PathBuf,
    /// A model under `root` every new page opens first.
    pub model: Option<String>,
    /// Message, upload and session limits.
    pub limits: Limits,
    /// Seed of every random choice (sampling, detection), so results reproduce; default 1.
    pub seed: u64,
}

impl Default for StudioOptions {
    fn default() -> Self {
        StudioOptions {
            host: IpAddr::V4(Ipv4Addr::LOCALHOST),
            port: 0,
            root: PathBuf::from("."),
            model: None,
            limits: Limits::default(),
            seed: 1,
        }
    }
}

/// A bound, not yet serving studio.
pub struct Studio {
    listener: tokio::net::TcpListener,
    app: Arc<server::App>,
}

impl Studio {
    /// Checks the options (root, model), binds the port.
    pub async fn bind(options: StudioOptions) -> Result<Studio> {
        let sandbox = Arc::new(Sandbox::new(&options.root)?);
        if let Some(m) = &options.model {
            sandbox.resolve_read(m)?;
        }
        let addr = SocketAddr::new(options.host, options.port);
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .map_err(|source| StudioError::Io { what: format!("listening on {addr}"), source })?;
        let allowed_hosts = if options.host.is_loopback() {
            let mut h = vec!["localhost".to_string(), "127.0.0.1".to_string(), "[::1]".to_string()];
            h.push(match options.host {
                IpAddr::V6(v6) => format!("[{v6}]"),
                v4 => v4.to_string(),
            });
            h
        } else {
            Vec::new()
        };
        let app = Arc::new(server::App {
            sandbox,
            limits: options.limits,
            seed: options.seed,
            model: options.model.clone(),
            counter: SessionCounter::default(),
            allowed_hosts,
        });
        Ok(Studio { listener, app })
    }

    /// The address it listens on.
    pub fn local_addr(&self) -> Result<SocketAddr> {
        self.listener
            .local_addr()
            .map_err(|source| StudioError::Io { what: "local address".to_string(), source })
    }

    /// The page's URL.
    pub fn url(&self) -> String {
        match self.local_addr() {
            Ok(a) => format!("http://{a}/"),
            Err(_) => "http://127.0.0.1/".to_string(),
        }
    }

    /// The canonical root folder.
    pub fn root(&self) -> PathBuf {
        self.app.sandbox.root().to_path_buf()
    }

    /// Live sessions (open WebSocket connections whose state is still held).
    pub fn sessions(&self) -> SessionCounter {
        self.app.counter.clone()
    }

    /// Serves until the process ends.
    pub async fn serve(self) -> Result<()> {
        let router = server::router(self.app);
        axum::serve(self.listener, router.into_make_service_with_connect_info::<SocketAddr>())
            .await
            .map_err(|source| StudioError::Io { what: "serving".to_string(), source })
    }
}

/// Runs a studio on a new multi-threaded runtime until the process ends; `ready` is called once
/// it listens (e.g. to print the URL).
pub fn run(options: StudioOptions, ready: impl FnOnce(&Studio)) -> Result<()> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(|source| StudioError::Io { what: "starting the runtime".to_string(), source })?;
    rt.block_on(async move {
        let studio = Studio::bind(options).await?;
        ready(&studio);
        studio.serve().await
    })
}
