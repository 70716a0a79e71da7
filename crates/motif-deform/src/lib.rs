//! Symmetry-preserving real-time deformation (thesis chapter 3, Wu et al. 2014b).
//!
//! Shapes with (partial, overlapping, nested) symmetries are deformed in the space of
//! displacements that preserve those symmetries *exactly* (thesis eq. 3.2): the space is built
//! directly, so no constraint is ever solved for.
//!
//! Pipeline (one module per step):
//! 1. [`annotation`]: parse `motif_symmetry_v1`, close groups, resolve regions (3.2);
//!    [`check_annotation`] measures how well each transform fits the shape.
//! 2. [`mod@symmetric_sampling`]: Poisson-disc sampling closed under the symmetries, with local frames
//!    and reduced bases on invariant sets (3.4).
//! 3. [`basis`]: the basis `U` of symmetry-preserving displacements of the sampling (3.4).
//! 4. [`lift`]: Gaussian partition-of-unity weights `W` carrying sample displacements to the mesh (3.4).
//! 5. [`laplace`] and [`editing`]: the sampling graph Laplacian and co-rotated Laplace editing
//!    solved in the subspace, eq. 3.4 (3.5).
//! 6. [`session`]: [`DeformSession`] precomputes once, factorises per handle set and solves per
//!    frame; [`deform`] is the one-shot version.
//! 7. [`residual`]: [`symmetry_residual`] measures eq. 3.2 on a deformed mesh with the induced
//!    vertex maps φ of eq. 3.1.
//!
//! How exactness is achieved (and where this goes beyond the thesis text):
//! - every `U q` is symmetric, so the sampling's displacement is exact whatever the solver does;
//! - degenerate orbits (seeds on mirror planes / axes) are projected onto their invariant set, so
//!   merged doublets coincide exactly, and their basis is reduced (thesis Fig. 3.7b);
//! - the lift's weights depend on distance only and each vertex's support is the largest
//!   symmetry-consistent one (a greatest fixpoint, `lift.rs`): this makes partial, nested and
//!   tiled (instance-set) symmetries exact, not only global ones; where no consistent sample is in
//!   reach (edges where lattice cells meet) an orbit is seeded at the vertex itself;
//! - the Gaussian is shifted by its cut-off so weights vanish continuously (a hard cut-off would
//!   turn rounding into 10⁻³ errors).
//!
//! Symmetry also saves work: co-rotations are fitted once per orbit where a symmetry maps the
//! neighbourhood ([`RotationPlan`]), and the lift is evaluated once per vertex orbit and turned by
//! the orbit frame ([`LiftEvaluation::PerOrbit`]). Measured (criterion medians, shared 2-core
//! machine at load 5–8): a 200k-vertex windmill frame (5 iterations + lift) in about 5 ms, the
//! prefactor at 700 samples in 10–20 ms.
//!
//! Conventions: positions `[f64; 3]` in mesh units; transforms row-major 4×4 on column vectors
//! (`p' = M p`); "relative" tolerances and radii are multiples of the rest mesh's bounding-box
//! diagonal. Handles follow `motif_handles_v1` ([`handles`]).

#![warn(missing_docs)]

pub mod annotation;
pub mod basis;
pub mod editing;
pub mod error;
pub mod handles;
pub mod laplace;
pub mod lift;
mod mat3;
pub mod residual;
pub mod session;
mod symbols;
pub mod symmetric_sampling;

pub use annotation::{
    ResolvedAnnotation, ResolvedKind, ResolvedRegion, ResolvedSymmetry, SymmetryElement, group_closure,
    parse_annotation, read_annotation, regions_as_vertices, resolve_annotation,
};
pub use basis::SymmetricBasis;
pub use editing::EditingOptions;
pub use error::{DeformError, Result};
pub use handles::{HANDLES_FORMAT, Handle, HandlesFile};
pub use laplace::{RotationPlan, SamplingGraph};
pub use lift::{LiftEvaluation, LiftOptions, LiftSupport, Lifting};
pub use mat3::Mat3;
pub use residual::{
    AnnotationReport, ElementResidual, InducedMap, ResidualReport, SymmetryCheck, SymmetryMaps,
    TransformCheck, check_annotation, induced_vertex_map, symmetry_residual,
};
pub use session::{
    AnnotationValidation, DeformOptions, DeformResult, DeformSession, DeformStats, HandleFit, SymmetryMode,
    Timings, deform,
};
pub use symmetric_sampling::{
    Orbit, RegionCoverage, SampleSpacing, SymmetricSampling, SymmetricSamplingOptions, symmetric_sampling,
};

/// The thesis chapter this crate implements, for reports and `--version` output.
pub const THESIS_CHAPTER: &str = "3: real-time symmetry-preserving deformation";

pub mod symmetry_detect;
