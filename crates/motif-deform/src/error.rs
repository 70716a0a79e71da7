//! The error type of the deformation pipeline.
//!
//! Every variant says what is wrong and what to do about it; the CLI prints the message once and
//! exits with code 2 when [`DeformError::is_bad_input`] is true (the user's annotation, handles or
//! options), 1 otherwise.

use std::path::PathBuf;

use motif_core::geometry::Point3;

/// Errors of `motif-deform`.
#[derive(Debug, thiserror::Error)]
pub enum DeformError {
    /// An error of the geometry core (reading a mesh, building a kd-tree, ...).
    #[error(transparent)]
    Core(#[from] motif_core::Error),
    /// A JSON document could not be parsed.
    #[error("{what}: {source}")]
    Json {
        /// What was being parsed (a file name, or "symmetry annotation").
        what: String,
        /// The parser's error, with line and column.
        #[source]
        source: serde_json::Error,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A JSON document carries another `format` tag than expected.
    #[error("{what}: expected format {expected:?}, found {found:?}")]
    WrongFormat {
        /// What was being parsed.
        what: String,
        /// The tag this reader understands.
        expected: &'static str,
        /// The tag found in the document.
        found: String,
    },
    /// The mesh cannot be deformed (no vertices, no extent, NaN coordinates, ...).
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    /// A field of an annotation or handles file holds a value out of its range: the message
    /// names the file and the field (these are not options, so not said as one).
    #[error("{message}")]
    InvalidFileContent {
        /// The field of the file (`"frames"`, `"region"`, `"tolerance"`).
        field: &'static str,
        /// The file, the field and what is wrong.
        message: String,
    },
    /// An option is out of its valid range.
    #[error("invalid option {name}: {message}")]
    InvalidOption {
        /// The option's name as the user knows it.
        name: &'static str,
        /// What is wrong and what range is valid.
        message: String,
    },
    /// A symmetry transform is not an affine map with an orthogonal linear part.
    #[error(
        "symmetry {symmetry:?}: transform {transform} is not a rigid motion or reflection \
         (largest deviation of OᵀO from the identity or of the last row from 0 0 0 1: {deviation:.3e}); \
         give row-major 4×4 matrices whose upper-left 3×3 is orthogonal"
    )]
    NonOrthogonal {
        /// The symmetry's name.
        symmetry: String,
        /// Index of the offending generator or instance.
        transform: usize,
        /// The largest deviation found.
        deviation: f64,
    },
    /// The generators of a group symmetry do not close into a finite group.
    #[error(
        "symmetry {symmetry:?}: its generators do not close into a group of at most {limit} elements; \
         check that every rotation angle divides 360° and that the generators share a fixed point \
         (translations generate infinite groups: use an instance set instead)"
    )]
    GroupTooLarge {
        /// The symmetry's name.
        symmetry: String,
        /// The largest group order accepted.
        limit: usize,
    },
    /// A generator turns by an angle that is a multiple of 360°/n only for a large n, and not
    /// 360°/n itself: an angle such as 1 radian, which closes into a "group" of 710 elements
    /// within any tolerance (710 rad is 113 turns to within 6·10⁻⁵ rad).
    #[error(
        "symmetry {symmetry:?}: generator {transform} turns by {degrees:.4}°, which is {k}·360°/{n}; a finite \
         rotation symmetry is given by its smallest turn, 360°/n (an angle that is no such fraction of a \
         turn, like 1 radian, has no finite group)"
    )]
    NotAFiniteTurn {
        /// The symmetry's name.
        symmetry: String,
        /// Index of the offending generator.
        transform: usize,
        /// Its turning angle, degrees (0–180).
        degrees: f64,
        /// The angle is `k · 360° / n` (in lowest terms).
        k: u64,
        /// See `k`.
        n: u64,
    },
    /// A region selects no vertex of the mesh.
    #[error(
        "{what} selects no vertex of the mesh: check its indices, box or sphere against the mesh's bounds"
    )]
    EmptyRegion {
        /// Which region ("symmetry \"fan\"", "handle 2", "instance 3 of symmetry \"legs\"").
        what: String,
    },
    /// A region lists a vertex or face index that does not exist.
    #[error("{what} refers to {kind} {index}, but the mesh has only {count}")]
    IndexOutOfRange {
        /// Which region.
        what: String,
        /// "vertex" or "face".
        kind: &'static str,
        /// The offending index.
        index: u32,
        /// Number of vertices or faces of the mesh.
        count: usize,
    },
    /// A symmetry transform does not map its region onto the shape within the tolerance
    /// (`AnnotationValidation::Force` deforms on the approximate symmetry instead).
    #[error(
        "symmetry {symmetry:?}: {transform} maps region vertices up to {residual:.3e} × the diagonal away \
         from the shape (tolerance {tolerance:.1e}); fix the annotation, or raise its tolerance"
    )]
    SymmetryMismatch {
        /// The symmetry's name.
        symmetry: String,
        /// Which transform ("element 3", "instance 2").
        transform: String,
        /// Largest distance from a transformed region vertex to the shape, relative to the diagonal.
        residual: f64,
        /// The annotation's tolerance, relative to the diagonal.
        tolerance: f64,
    },
    /// The transitive closure of a sample's orbit did not terminate.
    #[error(
        "the orbit of the sample at {position:?} grew beyond {limit} points: overlapping regions keep \
         mapping it further (check that every instance transform maps instance 0's region onto the \
         instance's region)"
    )]
    OrbitTooLarge {
        /// The orbit's seed.
        position: Point3,
        /// The largest orbit accepted.
        limit: usize,
    },
    /// `set_handles` was given no handle.
    #[error(
        "no handles: the deformation is undetermined; select at least one handle region (fixed or moved)"
    )]
    NoHandles,
    /// A handle region contains vertices but no sample point.
    #[error(
        "handle {handle} selects {vertices} vertices but no sample point (sampling radius {radius:.4}): \
         enlarge the handle region or sample more densely"
    )]
    HandleSelectsNoSample {
        /// Index of the handle.
        handle: usize,
        /// Number of mesh vertices in its region.
        vertices: usize,
        /// The sampling radius r, mesh units.
        radius: f64,
    },
    /// Two handles select the same sample point.
    #[error(
        "handles {first} and {second} overlap (both select the sample at {position:?}): make their regions disjoint"
    )]
    OverlappingHandles {
        /// The first handle.
        first: usize,
        /// The second handle.
        second: usize,
        /// The shared sample's position.
        position: Point3,
    },
    /// Some part of the sampling is connected to no handle, so the system (eq. 3.4) is singular.
    #[error(
        "the deformation is undetermined: {components} part(s) of the sampling graph are connected to no \
         handle (one contains the sample at {position:?}); add a handle there, enlarge the sampling \
         radius so the parts connect, or set editing.regularization > 0"
    )]
    Unconstrained {
        /// Number of unconstrained components of the sampling graph (joined through orbits).
        components: usize,
        /// A sample in one of them.
        position: Point3,
    },
    /// The Cholesky factorisation of the reduced system failed.
    #[error(
        "factorisation of the reduced system (eq. 3.4) failed: {0}; the system is singular or badly \
         scaled (try a smaller alpha or a positive regularization)"
    )]
    Factorization(String),
    /// `solve` was called before `set_handles`.
    #[error("no handles are set: call set_handles before solve")]
    HandlesNotSet,
    /// `solve` got a different number of transforms than there are handles.
    #[error("expected one transform per handle ({expected}), got {found}")]
    TransformCount {
        /// Number of handles.
        expected: usize,
        /// Number of transforms given.
        found: usize,
    },
    /// A handle transform contains NaN or infinity, or its last row is not `0 0 0 1`.
    #[error("the transform of handle {handle} is not a finite affine 4×4 matrix (last row must be 0 0 0 1)")]
    InvalidTransform {
        /// Index of the handle.
        handle: usize,
    },
    /// A handle transform scales, shears or flattens: handles move rigidly (`motif_handles_v1`).
    #[error(
        "the transform of handle {handle} is not a rigid motion (its linear part is {deviation:.2e} from \
         orthogonal; handles move their region rigidly, motif_handles_v1)"
    )]
    NonRigidTransform {
        /// Index of the handle.
        handle: usize,
        /// The largest entry of |OᵀO − I| of its linear part O.
        deviation: f64,
    },
    /// The solve produced non-finite values (overflow from enormous transforms); nothing was written.
    #[error(
        "the solve produced non-finite displacements (are the handle transforms enormous?); the previous positions are kept"
    )]
    NonFinite,
}

impl DeformError {
    /// True when the error is caused by the user's input (annotation, handles, options, files),
    /// as opposed to a failure of the system.
    pub fn is_bad_input(&self) -> bool {
        match self {
            DeformError::Core(e) => e.is_bad_input(),
            DeformError::Io { source, .. } => matches!(
                source.kind(),
                std::io::ErrorKind::NotFound
                    | std::io::ErrorKind::InvalidData
                    | std::io::ErrorKind::IsADirectory
            ),
            DeformError::Factorization(_) | DeformError::NonFinite => false,
            _ => true,
        }
    }
}

/// Result alias of `motif-deform`.
pub type Result<T, E = DeformError> = std::result::Result<T, E>;
