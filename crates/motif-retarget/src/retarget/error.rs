//! The error type of offset-based retargeting (kept inside the `retarget` folder so that the
//! retargeting stage owns its messages, as parry does for its large algorithms).

/// Errors of [`crate::retarget::retarget`] and [`crate::retarget::RetargetSession`].
///
/// Every message names the offending input and says what to change.
#[derive(Debug, thiserror::Error)]
pub enum RetargetError {
    /// The mesh has no triangles (a point cloud or an empty file): there is no geometry to copy.
    #[error(
        "the mesh has no faces ({vertices} vertices, 0 triangles); retargeting copies triangles, so give it a triangle mesh"
    )]
    NoFaces {
        /// Number of vertices of the mesh.
        vertices: usize,
    },
    /// The mesh has no extent (all vertices coincide), so it cannot be normalised.
    #[error("the mesh has no extent (its bounding box is a point); it cannot be normalised to [-1, 1]")]
    DegenerateMesh,
    /// The principal offsets are unusable: none or more than three, zero or non-finite, or
    /// (nearly) linearly dependent.
    #[error("invalid principal offsets: {message}")]
    InvalidOffsets {
        /// What is wrong, in words a user can act on.
        message: String,
    },
    /// Non-zero steps were given for a direction that has no principal offset (a dummy direction
    /// of thesis 4.4, which only discretises the model).
    #[error(
        "steps[{direction}] = {steps}, but only {offsets} principal offset(s) were given; direction {direction} is a dummy direction that cannot be resized (give 0)"
    )]
    StepsAlongDummy {
        /// The direction index (0, 1 or 2).
        direction: usize,
        /// The steps requested.
        steps: i32,
        /// How many principal offsets there are.
        offsets: usize,
    },
    /// The dense baseline's regular grid would keep fewer voxels than the model needs along a
    /// world axis (its voxels are 0.1 normalised units, not cells, so no bound on the steps along
    /// the principal offsets can be given).
    #[error(
        "the dense baseline's grid of {spacing} (normalised units) would shrink along {axis} from {input_voxels} to {output_voxels} {}; at least {minimum} must remain: ask for fewer negative steps",
        voxels(*.output_voxels)
    )]
    DenseShrinkTooFar {
        /// The world axis, "x", "y" or "z".
        axis: &'static str,
        /// The grid spacing in normalised units.
        spacing: f64,
        /// Voxels of the input along this axis.
        input_voxels: usize,
        /// Voxels the output would have.
        output_voxels: i64,
        /// The smallest number of voxels allowed.
        minimum: usize,
    },
    /// Shrinking would leave fewer voxels than the model needs along a direction.
    #[error(
        "steps[{direction}] = {steps} shrinks direction {direction} from {input_voxels} to {output_voxels} {} of the retargeting grid (one principal offset long each; the end voxels may hold only part of a cell, such as a closing board, so the grid can count one more than the model's whole cells); at least {minimum} must remain (steps >= {min_steps})",
        voxels(*.output_voxels)
    )]
    ShrinkBelowOneCell {
        /// The direction index.
        direction: usize,
        /// The steps requested.
        steps: i32,
        /// Voxels (cells) of the input along this direction.
        input_voxels: usize,
        /// Voxels the output would have.
        output_voxels: i64,
        /// The smallest number of voxels allowed (2 when the ends are preserved while shrinking:
        /// the first and the last cell; otherwise 1).
        minimum: usize,
        /// The smallest `steps` value allowed.
        min_steps: i64,
    },
    /// The problem is larger than the configured limit (voxels of the output grid, or labels).
    #[error(
        "the {what} would have {value} {unit} (limit {limit}); use fewer steps or larger principal offsets, or pass --force to run anyway"
    )]
    TooLarge {
        /// `"retargeting space"` or `"offset space"`.
        what: &'static str,
        /// `"voxels"` or `"labels"`.
        unit: &'static str,
        /// The size that was computed.
        value: u128,
        /// The limit.
        limit: u128,
    },
    /// The per-(voxel, label) tables would not fit in memory or in the graph's indices: a hard
    /// limit, which `force` does not lift (the message of [`RetargetError::TooLarge`] offered
    /// `--force` here too, to no effect).
    #[error(
        "the retargeting problem would have {value} voxel-label pairs, more than fit in memory (limit {limit}, which --force does not lift); use fewer steps or larger principal offsets"
    )]
    TooLargeForMemory {
        /// Voxel-label pairs the tables would hold.
        value: u128,
        /// The hard limit.
        limit: u128,
    },
    /// An option is out of its valid range.
    #[error("invalid retargeting option `{name}`: {message}")]
    InvalidOption {
        /// The field of [`crate::retarget::RetargetOptions`].
        name: &'static str,
        /// What is wrong and what range is valid.
        message: String,
    },
    /// Sampling, descriptors or another geometry-core step failed.
    #[error(transparent)]
    Core(#[from] motif_core::Error),
    /// The graph-cut optimisation failed (malformed energy; a bug if it happens).
    #[error(transparent)]
    GraphCut(#[from] crate::error::Error),
}

impl RetargetError {
    /// True when the error is the caller's input (mesh, offsets, steps, options) rather than a
    /// failure of the system; the CLI exits with code 2 for these.
    pub fn is_bad_input(&self) -> bool {
        match self {
            RetargetError::Core(e) => e.is_bad_input(),
            RetargetError::GraphCut(_) => false,
            _ => true,
        }
    }
}

/// Result alias of the retargeting stage.
pub type RetargetResult<T> = std::result::Result<T, RetargetError>;

/// "voxel" or "voxels", as `n` needs.
fn voxels(n: i64) -> &'static str {
    if n == 1 { "voxel" } else { "voxels" }
}
