//! The error type of `motif-detect`.

use std::path::PathBuf;

/// Everything that can go wrong when reading, validating, scoring or plotting detection results.
#[derive(Debug, thiserror::Error)]
pub enum DetectError {
    /// A detection or ground-truth file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// A file is not JSON of the detection schema (`../shared/formats/detection.md`).
    #[error("{path}: not a detection/ground-truth JSON file: {source}")]
    Json {
        /// The file.
        path: PathBuf,
        /// The parser's message, with line and column.
        source: serde_json::Error,
    },
    /// A detection or ground truth parsed but holds a value the scoring cannot use.
    #[error("{origin}: field `{field}`: {problem}")]
    Invalid {
        /// The file (or `<memory>` for a value built in code).
        origin: String,
        /// The JSON path of the bad field, e.g. `classes[2].instances[0].bbox_min[1]`.
        field: String,
        /// What is wrong and how to fix it.
        problem: String,
    },
    /// An options field ([`crate::eval::EvalOptions`], [`crate::scenes::SceneOptions`],
    /// [`crate::rigid_icp::RigidIcpOptions`], ...) is out of range.
    #[error("invalid option `{name}`: {message}")]
    InvalidOption {
        /// The option's field name.
        name: &'static str,
        /// Why the value is rejected.
        message: String,
    },
    /// Input data the algorithm cannot work with (empty cloud, NaN coordinates, ...).
    #[error("{0}")]
    InvalidInput(String),
    /// A geometry-core operation (kd-tree, ICP, sampling, file IO) failed.
    #[error(transparent)]
    Core(#[from] motif_core::Error),
    /// A mesh given as a benchmark-scene part cannot be read or used.
    #[error("scene part {path}: {message}")]
    ScenePart {
        /// The part's file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// [`crate::eval::evaluate_many`] was given no scenes, so there is nothing to average.
    #[error("no scenes to evaluate: give at least one (detection, ground truth) pair")]
    NoScenes,
    /// A picture could not be drawn or written.
    #[error("picture {path}: {message}")]
    Plot {
        /// The PNG file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
}

/// `Result` with [`DetectError`].
pub type Result<T> = std::result::Result<T, DetectError>;
