//! The error type of offset statistics, the sparsity study and their pictures.
//!
//! Kept inside the `offsets` module (not a crate-wide `error.rs`) so that it merges without
//! conflict with the solver's error type; the crate may fold both into one enum later.

use std::path::PathBuf;

/// Errors of [`crate::offsets`], [`crate::sparsity`] and [`crate::plot`].
#[derive(Debug, thiserror::Error)]
pub enum OffsetsError {
    /// The geometry core refused the input (bad file, NaN coordinates, ...).
    #[error(transparent)]
    Core(#[from] motif_core::Error),
    /// An option is outside its valid range.
    #[error("invalid option `{name}`: {message}")]
    InvalidOption {
        /// The option's field name.
        name: &'static str,
        /// What is wrong and what to use instead.
        message: String,
    },
    /// The mesh has no triangles (offset statistics sample the surface).
    #[error("the mesh has no triangles: offset statistics sample a surface, give a triangle mesh")]
    NoSurface,
    /// The mesh's bounding box is a single point, so it cannot be normalised.
    #[error("the mesh's largest dimension is {extent}: it cannot be scaled to [-1, 1]")]
    Degenerate {
        /// The largest extent of the bounding box.
        extent: f64,
    },
    /// Too few features got a SHOT descriptor to match anything.
    #[error(
        "only {valid} of {total} features have a SHOT descriptor (each needs {min} neighbours within the \
         radius {radius}): the surface is too small or the support radius too small"
    )]
    TooFewFeatures {
        /// Features with a descriptor.
        valid: usize,
        /// Features sampled.
        total: usize,
        /// The SHOT neighbour minimum.
        min: usize,
        /// The SHOT support radius (normalised units).
        radius: f64,
    },
    /// A manifest or input list could not be read or is malformed.
    #[error("{path}: {message}")]
    Input {
        /// The file or directory concerned.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Drawing or writing a picture failed.
    #[error("picture {path}: {message}")]
    Plot {
        /// The picture's path.
        path: PathBuf,
        /// What failed.
        message: String,
    },
}

/// Results of this module.
pub type Result<T, E = OffsetsError> = std::result::Result<T, E>;
