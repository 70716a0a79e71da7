//! Errors of automatic symmetry detection.

/// What can go wrong in [`detect_symmetries`](super::detect_symmetries).
#[derive(Debug, thiserror::Error)]
pub enum SymmetryDetectError {
    /// The mesh has no triangle with positive area, so there is no surface to test symmetries on.
    #[error("the mesh has no surface area (no non-degenerate triangle): nothing to detect symmetries on")]
    NoSurface,
    /// An option is outside its valid range.
    #[error("invalid option {name}: {message}")]
    InvalidOption {
        /// The option's field name in [`SymmetryDetectOptions`](super::SymmetryDetectOptions).
        name: &'static str,
        /// What is wrong and which range is valid.
        message: String,
    },
    /// The geometry core rejected the mesh (indices out of range, NaN coordinates, ...).
    #[error(transparent)]
    Core(#[from] motif_core::Error),
}

/// Result alias of this module.
pub type Result<T> = std::result::Result<T, SymmetryDetectError>;
