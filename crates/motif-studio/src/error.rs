//! The studio's error type: every message says what to do.

use std::path::PathBuf;

/// Errors of the studio server. Library errors keep their own message (they already name the
/// file or option at fault).
#[derive(Debug, thiserror::Error)]
pub enum StudioError {
    /// A path from a client points outside the root after resolving `..` and symlinks.
    #[error("{path}: outside the studio's root {root} (only files under --root can be read or written)")]
    OutsideRoot {
        /// The path as given.
        path: String,
        /// The canonical root.
        root: PathBuf,
    },
    /// A path from a client is unusable (empty, a NUL byte, no file name, a directory...).
    #[error("{path}: {problem}")]
    BadPath {
        /// The path as given.
        path: String,
        /// What is wrong with it.
        problem: String,
    },
    /// The root folder is missing or not a folder.
    #[error("--root {path}: {problem}")]
    BadRoot {
        /// The root as given.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// A client message that cannot be parsed or is too large.
    #[error("bad message: {0}")]
    BadMessage(String),
    /// A request that needs something the session does not have yet.
    #[error("{0}")]
    NotReady(String),
    /// A long computation is already running for this client.
    #[error("busy: {0} is still running (cancel it first)")]
    Busy(String),
    /// The computation was cancelled by the client.
    #[error("cancelled")]
    Cancelled,
    /// Reading, writing or parsing a model or a JSON file failed.
    #[error(transparent)]
    Core(#[from] motif_core::Error),
    /// Deformation or symmetry errors.
    #[error(transparent)]
    Deform(#[from] motif_deform::DeformError),
    /// Symmetry-detection errors.
    #[error(transparent)]
    Symmetry(#[from] motif_deform::symmetry_detect::SymmetryDetectError),
    /// Offset-analysis errors.
    #[error(transparent)]
    Offsets(#[from] motif_retarget::offsets::OffsetsError),
    /// Retargeting errors.
    #[error(transparent)]
    Retarget(#[from] motif_retarget::retarget::RetargetError),
    /// Detection-result errors.
    #[error(transparent)]
    Detect(#[from] motif_detect::DetectError),
    /// The server could not start (port in use, ...).
    #[error("{what}: {source}")]
    Io {
        /// What was being done.
        what: String,
        /// The cause.
        source: std::io::Error,
    },
    /// A bug: a computation panicked. The server keeps serving.
    #[error("internal error in {0} (a bug; the session keeps working)")]
    Internal(String),
}

/// Results of the studio.
pub type Result<T> = std::result::Result<T, StudioError>;
