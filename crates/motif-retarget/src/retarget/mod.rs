//! Structure-aware retargeting by stitching shifted copies of a model with a multi-label graph
//! cut (thesis 4.2.2, 4.4), and the dense-MRF baseline (thesis 4.5).
//!
//! Given the principal offsets `v₁…v_K` of a model's repetition (K ≤ 3, model units; found by the
//! offset detection of 4.2.1, or known) and a number of steps per offset, the model is resized
//! along its own lattice:
//! 1. **Normalise** so that the largest dimension spans [−1, 1] (the thesis's lengths 0.02, 0.06,
//!    0.1, 0.2 are in these units) and map to the **canonical space** `B⁻¹ x`, `B = [v₁/|v₁|
//!    v₂/|v₂| v₃/|v₃|]`, where the offsets are the coordinate axes (4.4, Fig. 4.7). Fewer than three
//!    offsets are completed by orthogonal dummy directions of length 0.2 (4.4).
//! 2. **Voxelise** with cells equal to the offsets, origin at the minimum corner of the canonical
//!    bounding box: `U_in × V_in × W_in` input voxels (extents are rounded up to whole cells, with
//!    a slack of 1% of a cell so that slightly inaccurate detected offsets add no sliver voxels);
//!    the retargeting space Ω has
//!    `(U_in + U) × (V_in + V) × (W_in + W)` voxels, the graph's nodes.
//! 3. **Describe** every input voxel by G(x), the set of SHOT descriptors (world frame, radius
//!    0.2) of the features on its triangles (features: Poisson-disc spacing 0.06 over a dense cloud
//!    of spacing 0.02 that supports the descriptors, as in 4.3).
//! 4. **Label** every voxel of Ω with a step vector `k` — it copies input voxel `x − k`, shifted
//!    by `Σ kᵢ vᵢ` — by minimising eq. 4.3 with alpha-expansion ([`mod@crate::alpha_expansion`]).
//! 5. **Stitch** the copies' triangles and weld the seams; where no copy continues a part cut at
//!    a voxel face, cap the opening (`caps`), and fill the holes still open, slits where two
//!    neighbouring copies differ ([`motif_core::hole_fill`]); neither touches an opening the
//!    input has itself, and neither is in the thesis. The result is in model units.
//!
//! [`RetargetSession`] does steps 1–3 once and solves for any number of step vectors
//! (interactive resizing; Hausdorff distances are cached across solves); [`retarget`] and
//! [`retarget_dense`] are the one-shot forms. [`RetargetSession::with_features`] reuses the
//! features and descriptors of the offset detection ([`crate::offsets`]) instead of sampling
//! again. Everything is deterministic for a seed.
//!
//! # How the thesis is read
//! Where the text leaves a choice, this is what the code does (and why):
//! - **Labels** (eq. 4.2): `kᵢ ∈ [0, Uᵢ]` (`[Uᵢ, 0]` when shrinking), so M = (|U|+1)(|V|+1)(|W|+1)
//!   labels: the copies that can reach the added cells. This matches Fig. 4.8's counts (3 labels
//!   for +2 in one direction, 9 for +2,+2); the text's "M = U × V × W" would be 0 for a direction
//!   that is not resized.
//! - **Unary** (4.2.2): 0 when `x − k` is an input voxel, +∞ otherwise. Growing, this already
//!   pins the ends (the first output voxel along a direction can only copy the first input voxel,
//!   the last only the last). Shrinking, it does not: every constant labelling is a zero-energy
//!   crop. [`BoundaryMode::Preserve`] (default) therefore also requires the low (high) face of Ω
//!   along a resized direction to copy the input's low (high) face — our addition.
//! - **Pairwise** (eq. 4.4): the thesis writes `G(x + lᵢ)` but copies from `x − l`; we use `x − l`
//!   throughout: `E = d_H(G(x − lᵢ), G(x − lⱼ)) + d_H(G(x' − lᵢ), G(x' − lⱼ))` for 26-neighbours
//!   `x, x'` with `lᵢ ≠ lⱼ` — at each of the two voxels, what the two copies would put there is
//!   compared (the seam cost of graph-cut textures). d_H is the Hausdorff distance with the L2
//!   norm between descriptors; 0 when both voxels are empty, +∞ when exactly one is. A voxel
//!   outside the input grid holds no geometry and counts as empty, which forbids seams where one
//!   copy ends abruptly and keeps the input's boundary cells on the output's boundary. Unit edge
//!   weights. The term is a metric in the labels, as alpha-expansion needs.
//! - **Descriptors**: a feature belongs to the voxel of the triangle it lies on, so G(x) describes
//!   exactly what a copy of x carries; the descriptors' support (radius 0.2) reaches beyond the
//!   voxel, as in the thesis where they come from the offset detection. A voxel with triangles but
//!   no feature gets its dense samples (or triangle centroids) as keypoints, so "empty" always
//!   means "no triangles". The distances are computed once per voxel pair and cached. With
//!   [`RetargetSession::with_features`], d_H is read from the descriptor distances that the
//!   matching step already computed for every pair of features (thesis 4.2.2: they "can be reused
//!   here"; [`crate::offsets::DescriptorDistances`]); only voxels described by fallback keypoints
//!   compute theirs from the descriptors.
//! - **Triangles** belong to the voxel containing their centroid; a centroid on a voxel face (a
//!   board's end face on a cell boundary) is probed 10⁻⁶ cells inwards against the face normal, so
//!   a face goes with the solid it bounds. [`TriangleAssignment::Cut`] first cuts triangles at
//!   the voxel faces, for meshes with triangles spanning several cells.
//! - **Start labelling**: the identity is infeasible when growing; we start from one seam per
//!   direction in the middle of the model (feasible, few seams), see `energy.rs`.
//! - **Seams** are welded where copies of a vertex that was shared across voxel faces meet again
//!   (within 10⁻³ of a cell, [`RetargetOptions::weld_tolerance`]); parts that merely touch stay
//!   separate, as in the input.
//! - **Dense baseline** (4.5): the same pipeline with regular axis-aligned offsets of 0.1 in
//!   normalised space and no canonical map; `steps` (along the principal offsets) become
//!   `round(gₐ / 0.1)` regular steps along each world axis `a`, `g = Σ stepsᵢ vᵢ`.
//!
//! ```no_run
//! use motif_core::procedural::generate;
//! use motif_core::progress::NoProgress;
//! use motif_retarget::retarget::{RetargetOptions, retarget};
//!
//! let shelf = generate("shelf", 0)?;
//! // The known cell pitch as principal offsets; one more column and one more row.
//! let out = retarget(&shelf.mesh, &shelf.structure.cell_pitch, [1, 1, 0], &RetargetOptions::default(), &NoProgress)?;
//! println!("{} nodes, {} labels, graph cut {:.1} ms", out.report.nodes, out.report.labels, out.report.graph_cut_ms);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod attributes;
mod canonical;
mod caps;
mod cut;
mod dense;
mod energy;
mod error;
mod stitch;
mod voxels;

use std::time::Instant;

use motif_core::geometry::{Mat4, Point3};
use motif_core::mesh::TriMesh;
use motif_core::progress::Progress;
use serde::{Deserialize, Serialize};

use crate::alpha_expansion::{AlphaExpansionOptions, Termination};
use crate::offsets::OffsetFeatures;

pub use attributes::{VertexOrigin, carry_vertex_data};
pub use canonical::{Mat3, Normalisation};
pub use error::{RetargetError, RetargetResult};

use canonical::Lattice;
use energy::DistanceCache;
use voxels::{DescriptorParams, VoxelDescriptors, VoxelGrid};

/// Which transformation space the copies are taken from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RetargetMethod {
    /// The thesis's method: voxels and labels from the principal offsets (4.2.2).
    #[default]
    Offsets,
    /// The baseline of 4.5: regular axis-aligned offsets of [`RetargetOptions::dense_spacing`].
    Dense,
}

impl RetargetMethod {
    /// The name reports and the `--method` flag use: `offsets` or `dense`.
    pub fn as_str(self) -> &'static str {
        match self {
            RetargetMethod::Offsets => "offsets",
            RetargetMethod::Dense => "dense",
        }
    }
}

/// How the ends of the model are treated when shrinking.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BoundaryMode {
    /// Output voxels on the low (high) face of Ω along a resized direction copy the input's low
    /// (high) face: what the validity term already implies when growing, added when shrinking so
    /// that the ends of the model are kept (see `energy.rs`). Shrinking then needs at least two
    /// output voxels along the direction.
    #[default]
    Preserve,
    /// Only the validity term of 4.2.2; a shrink may crop an end of the model.
    Free,
}

/// How input triangles are distributed over the voxels they are copied with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TriangleAssignment {
    /// Each triangle goes, whole, with the voxel containing its centroid (faces lying on a voxel
    /// face go with the solid they bound). Keeps the tessellation exactly; right when the model's
    /// parts are tessellated within its cells. On CAD meshes whose long triangles span several
    /// cells (the gridbeam shelf of `../shared/data`) it tears holes at seams.
    Centroid,
    /// Triangles are first cut at the voxel faces (new vertices on the cuts, shared exactly
    /// between neighbouring triangles), so that a triangle spanning several cells — a back panel
    /// made of one quad, a beam between two holes — is stretched with the model instead of copied
    /// whole. Triangles inside one voxel are untouched. The default: it is exact on both kinds of
    /// model (the generated shelves, fence and facade give the same cells as with
    /// [`TriangleAssignment::Centroid`]).
    #[default]
    Cut,
}

/// Options of [`retarget`] and [`RetargetSession`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RetargetOptions {
    /// Offsets (thesis 4.2.2) or the dense baseline (4.5). Default [`RetargetMethod::Offsets`].
    pub method: RetargetMethod,
    /// Length of the dummy directions that complete fewer than three principal offsets to a frame
    /// (thesis 4.4: "up to two orthogonal dummy directions with length 0.2"); normalised units,
    /// default 0.2. Only discretises the model; no steps are taken along dummies.
    pub dummy_length: f64,
    /// Regular offset of the dense baseline (thesis 4.5: "regular offset (set to 0.1) is used");
    /// normalised units, default 0.1.
    pub dense_spacing: f64,
    /// Poisson-disc spacing of the dense cloud that supports the SHOT descriptors (thesis 4.3:
    /// "Poisson sampling with 0.02 as the sampling space"); normalised units, default 0.02.
    pub sample_spacing: f64,
    /// Poisson-disc spacing of the features, resampled from the dense cloud, whose descriptors
    /// form the voxel sets G(x) of eq. 4.4 (thesis 4.3: "re-sampled using 0.06"); normalised
    /// units, default 0.06. Set it to `sample_spacing` to describe every dense sample.
    pub feature_spacing: f64,
    /// SHOT support radius R (thesis 4.3: "set to 0.2"); normalised units, default 0.2. The frame
    /// is always the world frame (thesis 4.4).
    pub shot_radius: f64,
    /// Seed of the Poisson-disc sampling (results are deterministic for a seed); default 0.
    pub seed: u64,
    /// Treatment of the model's ends when shrinking; default [`BoundaryMode::Preserve`].
    pub boundary: BoundaryMode,
    /// How triangles are assigned to voxels (thesis 4.2.2 copies "the source geometry" of a
    /// voxel without saying how triangles crossing voxel faces are split); default
    /// [`TriangleAssignment::Cut`].
    pub assignment: TriangleAssignment,
    /// Seam welding tolerance, relative to the smallest cell edge (the shortest principal offset,
    /// or the dense spacing); default 10⁻³. Offsets snapped to a mesh's exact vertex translation
    /// ([`crate::offsets::refine::snap_to_vertices`]) are exact to rounding, but offsets given by
    /// hand or refined by ICP alone are off by 10⁻⁵–10⁻³ of a cell, and a copy k cells away
    /// carries k times that: at the former default of 10⁻⁶ the sheared shelf grown by +1,+1 kept
    /// 60–130 open edges along its seams. A thousandth of a cell is still far below any detail a
    /// model resized along that cell has. 0 disables seam welding.
    pub weld_tolerance: f64,
    /// Largest retargeting space Ω accepted, in voxels (graph nodes); default 10⁶. The thesis's
    /// interactive graphs have < 1,000 nodes (4.4), its dense baselines < 10⁴ (Fig. 4.8).
    pub max_voxels: u64,
    /// Largest offset space Φ accepted, in labels; default 10⁴ (the thesis uses ≤ 64).
    pub max_labels: u64,
    /// Run even above `max_voxels` / `max_labels` (the CLI's `--force`). A flag rather than a
    /// mode enum because it only lifts a safety limit. Default false.
    pub force: bool,
    /// Options of the alpha-expansion that minimises eq. 4.3 (cycles, label order, the finite
    /// stand-in for +∞ inside moves).
    pub graph_cut: AlphaExpansionOptions,
    /// Cap the openings that cuts at voxel faces leave where no copy continues them (seams of
    /// infinite cost), except openings that run along the input's own open boundary (an edge
    /// copied from it; see the `caps` module). Not in the thesis; default true.
    pub cap_openings: bool,
    /// Fill the holes still open after welding and capping, except those that run along the
    /// input's own open boundary (a scan's edge, a single-sided sheet stays as it was): slits along
    /// seams where two neighbouring copies' geometry differs, which no copy continues and no
    /// voxel face plane holds ([`motif_core::hole_fill`]: Liepa's triangulation of each boundary
    /// loop, no new vertices). Not in the thesis; default true.
    pub fill_holes: bool,
}

impl Default for RetargetOptions {
    fn default() -> Self {
        RetargetOptions {
            method: RetargetMethod::Offsets,
            dummy_length: 0.2,
            dense_spacing: 0.1,
            sample_spacing: 0.02,
            feature_spacing: 0.06,
            shot_radius: 0.2,
            seed: 0,
            boundary: BoundaryMode::Preserve,
            assignment: TriangleAssignment::Cut,
            weld_tolerance: 1e-3,
            max_voxels: 1_000_000,
            max_labels: 10_000,
            force: false,
            graph_cut: AlphaExpansionOptions::default(),
            cap_openings: true,
            fill_holes: true,
        }
    }
}

impl RetargetOptions {
    /// Checks that every option is in its valid range.
    pub fn validate(&self) -> RetargetResult<()> {
        let positive = |name: &'static str, v: f64| {
            if v > 0.0 && v.is_finite() {
                Ok(())
            } else {
                Err(RetargetError::InvalidOption {
                    name,
                    message: format!("must be a positive length in normalised units, got {v}"),
                })
            }
        };
        positive("dummy_length", self.dummy_length)?;
        positive("dense_spacing", self.dense_spacing)?;
        positive("sample_spacing", self.sample_spacing)?;
        positive("feature_spacing", self.feature_spacing)?;
        positive("shot_radius", self.shot_radius)?;
        for (name, v) in [("dummy_length", self.dummy_length), ("dense_spacing", self.dense_spacing)] {
            if v < 1e-4 {
                return Err(RetargetError::InvalidOption {
                    name,
                    message: format!(
                        "{v} is below 1e-4 of the normalised model; the grid would have billions of voxels"
                    ),
                });
            }
        }
        if self.sample_spacing < 1e-4 {
            return Err(RetargetError::InvalidOption {
                name: "sample_spacing",
                message: format!(
                    "{} would draw hundreds of millions of samples; use at least 1e-4 (the thesis uses 0.02)",
                    self.sample_spacing
                ),
            });
        }
        if !(self.weld_tolerance >= 0.0 && self.weld_tolerance < 0.5) {
            return Err(RetargetError::InvalidOption {
                name: "weld_tolerance",
                message: format!("must be in [0, 0.5) of the cell size, got {}", self.weld_tolerance),
            });
        }
        Ok(())
    }
}

/// Wall-clock time of each stage, in milliseconds (the precomputation is done once per
/// [`RetargetSession`]; its stages are repeated in every report of the session).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct StageTimings {
    /// Normalisation, canonical map, voxel grid and triangle assignment.
    pub voxelize_ms: f64,
    /// Poisson-disc sampling of the dense cloud and the features.
    pub sampling_ms: f64,
    /// SHOT descriptors.
    pub descriptors_ms: f64,
    /// Hausdorff distances between voxel descriptor sets needed by this solve (cached per session).
    pub distances_ms: f64,
    /// Alpha-expansion (graph cuts) of eq. 4.3.
    pub graph_cut_ms: f64,
    /// Copying, translating and welding the geometry.
    pub stitch_ms: f64,
}

/// What a retargeting run did: the graph-cut figures of thesis Fig. 4.8 and the output's counts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RetargetReport {
    /// The method used.
    pub method: RetargetMethod,
    /// Steps requested along the principal offsets.
    pub steps: [i32; 3],
    /// Steps along the grid's axes (equal to `steps` for [`RetargetMethod::Offsets`]; regular
    /// steps of the dense spacing for [`RetargetMethod::Dense`]).
    pub grid_steps: [i32; 3],
    /// Number of principal offsets given (the rest of the three grid axes are dummies).
    pub num_offsets: usize,
    /// Voxel edge lengths along the grid axes, normalised units.
    pub pitch: [f64; 3],
    /// Input grid, voxels per axis (U_in, V_in, W_in).
    pub input_voxels: [usize; 3],
    /// Retargeting space Ω, voxels per axis.
    pub output_voxels: [usize; 3],
    /// Graph nodes: voxels of Ω.
    pub nodes: usize,
    /// Labels: size M of the offset space.
    pub labels: usize,
    /// Graph edges (26-neighbourhood pairs).
    pub edges: usize,
    /// Input voxels that hold triangles.
    pub occupied_voxels: usize,
    /// Dense support samples.
    pub samples: usize,
    /// Features (SHOT keypoints) described, including the fallbacks of small voxels.
    pub features: usize,
    /// Valid SHOT descriptors in the voxel sets.
    pub descriptors: usize,
    /// Hausdorff distances computed for this solve (others came from the session's cache).
    pub distances_computed: usize,
    /// Energy of the start labelling (may be +∞).
    pub initial_energy: f64,
    /// Energy of eq. 4.3 at the solution (+∞ when no seam-consistent labelling exists).
    pub energy: f64,
    /// Alpha-expansion cycles.
    pub cycles: usize,
    /// Expansion moves (graph cuts) solved.
    pub moves: usize,
    /// Why alpha-expansion stopped.
    pub termination: Termination,
    /// Edges whose voxels copy from different copies.
    pub seams: usize,
    /// Seams of infinite cost (eq. 4.4: one copy's geometry against another's empty voxel, or
    /// against the outside of the input, which counts as empty).
    /// Non-zero exactly when `energy` is +∞: no seam-consistent labelling was found, and the
    /// output may be open along these seams.
    #[serde(default)]
    pub infinite_seams: usize,
    /// Distinct labels in the solution.
    pub labels_used: usize,
    /// Time of the graph cut, ms (Fig. 4.8's figure).
    pub graph_cut_ms: f64,
    /// Time of this solve (distances, graph cut, stitching), ms.
    pub solve_ms: f64,
    /// Precomputation plus this solve, ms: the cost of a one-shot [`retarget`].
    pub total_ms: f64,
    /// Time per stage.
    pub stages: StageTimings,
    /// Output vertices.
    pub output_vertices: usize,
    /// Output triangles.
    pub output_triangles: usize,
    /// Connected components of the output.
    pub output_components: usize,
    /// Boundary edges of the output (cracks along seams show up here; closed inputs give 0).
    pub output_boundary_edges: usize,
    /// Vertices merged by seam welding (and, where openings are capped, coincident boundary
    /// vertices of different copies merged first; see [`RetargetOptions::cap_openings`]).
    pub welded_vertices: usize,
    /// Openings of cuts capped because no copy continued them (boundary loops closed; see
    /// [`RetargetOptions::cap_openings`]).
    #[serde(default)]
    pub capped_loops: usize,
    /// Triangles those caps added.
    #[serde(default)]
    pub cap_triangles: usize,
    /// Open loops that ran over several voxel face planes (folding over a voxel edge, or around
    /// a voxel corner) and were split into loops on each plane before capping.
    #[serde(default)]
    pub capped_folded_loops: usize,
    /// Vertices added at voxel corners where such a loop's caps on three planes meet.
    #[serde(default)]
    pub cap_corners: usize,
    /// Pairs of triangles on the same three vertices facing opposite ways (walls of no
    /// thickness, such as a cap over an input face lying on the voxel face it caps) or the same
    /// way (a sheet laid twice), removed after capping.
    #[serde(default)]
    pub cancelled_pairs: usize,
    /// Closed parts lying flat on one voxel face plane (two layers of no thickness that do not
    /// match triangle for triangle), removed after capping.
    #[serde(default)]
    pub flat_sheets: usize,
    /// Voxel face planes whose openings cross (copies' sections overlapping) and were capped by
    /// the winding rule.
    #[serde(default)]
    pub winding_cap_planes: usize,
    /// Holes filled after capping (boundary loops closed; see [`RetargetOptions::fill_holes`]).
    #[serde(default)]
    pub filled_holes: usize,
    /// Triangles those fills added.
    #[serde(default)]
    pub fill_triangles: usize,
    /// Triangles turned back after capping and filling because a patch of them ran against the
    /// rest of the surface ([`motif_core::TriMesh::orient_patches`]).
    #[serde(default)]
    pub reoriented_triangles: usize,
    /// Openings left open because they run along the input's own open boundary (loops with an
    /// edge copied from it, as the last of capping and filling saw them).
    #[serde(default)]
    pub kept_open: usize,
    /// `normalised_from_model`, row-major 4×4.
    pub normalised_from_model: Mat4,
    /// `canonical_from_normalised`, row-major 3×3 (identity for the dense baseline).
    pub canonical_from_normalised: Mat3,
}

/// The result of retargeting.
#[derive(Debug, Clone, PartialEq)]
pub struct Retargeted {
    /// The resized model, model units.
    pub mesh: TriMesh,
    /// What was done.
    pub report: RetargetReport,
    /// The step vector `k` chosen for every voxel of Ω (`#nodes`, first grid axis fastest): the
    /// voxel copies input voxel `x − k`, shifted by `Σ kᵢ vᵢ`.
    pub voxel_labels: Vec<[i32; 3]>,
    /// The voxel of Ω each output triangle was copied into (`#F`, indices into `voxel_labels`),
    /// e.g. to colour the result by label as in thesis Fig. 4.4 c.
    pub triangle_voxels: Vec<u32>,
}

/// Precomputed retargeting of one model (normalisation, canonical map, voxel grid, descriptors),
/// solved for any number of step vectors; Hausdorff distances are cached between solves.
#[derive(Debug, Clone)]
pub struct RetargetSession {
    options: RetargetOptions,
    mesh: TriMesh,
    principal_offsets: Vec<Point3>,
    lattice: Lattice,
    grid: VoxelGrid,
    tri_voxel: Vec<u32>,
    /// The input triangle each triangle of `mesh` is a piece of.
    pieces: stitch::Pieces,
    descriptors: VoxelDescriptors,
    cache: DistanceCache,
    precompute: StageTimings,
    precompute_ms: f64,
    /// Whether to cap openings ([`RetargetOptions::cap_openings`]; openings along the input's
    /// own open boundary are left open).
    cap_openings: bool,
    /// Whether to fill holes ([`RetargetOptions::fill_holes`]; likewise).
    fill_holes: bool,
    /// The cut mesh's open boundary and orientation (openings the input has stay open).
    input_surface: stitch::InputSurface,
}

/// What a stitching with seams of infinite cost left open, in words for a warning: the output's
/// open edges against the input's, or that caps and fills closed what the seams opened (the
/// gridbeam shelf grown in width: every seam infinite, no edge left open).
pub fn open_edges_after(output_boundary_edges: usize, input_boundary_edges: usize) -> String {
    if output_boundary_edges <= input_boundary_edges {
        format!(
            "caps and fills closed the openings this leaves (the output has {output_boundary_edges} open \
             boundary edges, the input {input_boundary_edges}), but the copies may not meet as the input's cells do"
        )
    } else {
        format!(
            "the output has {output_boundary_edges} open boundary edges (the input has {input_boundary_edges})"
        )
    }
}

impl RetargetSession {
    /// The seam-welding tolerance, model units: a thousandth of a cell
    /// ([`RetargetOptions::weld_tolerance`]), but never more than a twentieth of the model's
    /// thinnest extent: a bar 10⁴ long and 1 thick, grown along a cell of 2500, would otherwise
    /// weld the corners of its cross-section into one point.
    fn weld_tolerance(&self) -> f64 {
        let min_pitch = (0..3)
            .filter(|&a| a < self.lattice.num_active)
            .map(|a| self.lattice.pitch[a])
            .fold(f64::INFINITY, f64::min);
        let thinnest = self.mesh.aabb().map_or(f64::INFINITY, |b| {
            (0..3).map(|k| b.max[k] - b.min[k]).filter(|&e| e > 0.0).fold(f64::INFINITY, f64::min)
        });
        (self.options.weld_tolerance * min_pitch / self.lattice.normalisation.scale)
            .min(MAX_WELD_SHARE_OF_THINNEST * thinnest)
    }

    /// Where each vertex of `out` (a result of this session) lies on the input surface, `None`
    /// for the vertices capping added; see [`attributes`]. With
    /// [`attributes::carry_vertex_data`] this carries the input's normals, colours and other
    /// per-vertex data onto the output.
    pub fn vertex_origins(&self, out: &Retargeted) -> Vec<Option<VertexOrigin>> {
        let translation = |f: usize| {
            let k = out.triangle_voxels.get(f).and_then(|&x| out.voxel_labels.get(x as usize));
            k.map_or([0.0; 3], |&k| self.lattice.translation(k))
        };
        attributes::vertex_origins(
            &self.mesh,
            self.pieces.parents(),
            self.pieces.originals(),
            &out.mesh,
            &translation,
            self.weld_tolerance(),
        )
    }

    /// Normalises `mesh`, builds the canonical space of `principal_offsets` (model units, 1–3
    /// vectors), voxelises the input and computes the voxels' descriptor sets.
    ///
    /// # Errors
    /// [`RetargetError::NoFaces`] for meshes without triangles, [`RetargetError::InvalidOffsets`],
    /// [`RetargetError::InvalidOption`], [`RetargetError::TooLarge`] when the input grid alone
    /// exceeds `max_voxels`, and sampling/descriptor failures.
    pub fn new(
        mesh: &TriMesh,
        principal_offsets: &[Point3],
        options: &RetargetOptions,
        progress: &dyn Progress,
    ) -> RetargetResult<RetargetSession> {
        Self::build(mesh, principal_offsets, None, options, progress)
    }

    /// [`RetargetSession::new`] reusing the features and SHOT descriptors that the offset
    /// detection prepared for the same mesh ([`crate::offsets::prepare_features`]), as thesis
    /// 4.2.2 suggests ("the pairwise feature distances have already been computed in the previous
    /// step … and can be reused here"): no sampling and (almost) no SHOT here, and when
    /// [`crate::offsets::analyze_features`] kept the matching step's distances
    /// ([`OffsetFeatures::descriptor_distances`]) the Hausdorff distances are looked up in them. The sampling options
    /// of `options` are then unused; keep `shot_radius` equal to the detection's.
    ///
    /// # Errors
    /// As [`RetargetSession::new`], and [`RetargetError::InvalidOption`] when `features` were
    /// prepared for a mesh with another bounding box.
    pub fn with_features(
        mesh: &TriMesh,
        features: &OffsetFeatures,
        principal_offsets: &[Point3],
        options: &RetargetOptions,
        progress: &dyn Progress,
    ) -> RetargetResult<RetargetSession> {
        Self::build(mesh, principal_offsets, Some(features), options, progress)
    }

    fn build(
        mesh: &TriMesh,
        principal_offsets: &[Point3],
        features: Option<&OffsetFeatures>,
        options: &RetargetOptions,
        progress: &dyn Progress,
    ) -> RetargetResult<RetargetSession> {
        let t0 = Instant::now();
        options.validate()?;
        mesh.validate()?;
        if mesh.triangles.is_empty() {
            return Err(RetargetError::NoFaces { vertices: mesh.positions.len() });
        }
        // Vertices no triangle uses are no part of the surface; one far off used to widen the
        // normalisation and the grid (the offsets then found no repetition).
        let cleaned;
        let mesh = if mesh.has_unreferenced_vertices() {
            let mut m = mesh.clone();
            m.remove_unreferenced_vertices();
            cleaned = m;
            &cleaned
        } else {
            mesh
        };
        let (cap_openings, fill_holes) = (options.cap_openings, options.fill_holes);
        progress.start("voxelize", 0);
        let normalisation = canonical::normalisation_of(mesh)?;
        if let Some(f) = features {
            let (a, b) = (&f.normalisation, &normalisation);
            let moved = motif_core::geometry::dist(a.centre, b.centre) * b.scale;
            if moved > 1e-9 || (a.scale / b.scale - 1.0).abs() > 1e-9 {
                return Err(RetargetError::InvalidOption {
                    name: "features",
                    message: "the features were prepared for a mesh with another bounding box; \
                              prepare them from the mesh being retargeted"
                        .into(),
                });
            }
        }
        // Always validated, also for the baseline, which needs them for its step counts.
        let offsets_lattice = Lattice::from_offsets(normalisation, principal_offsets, options.dummy_length)?;
        let lattice = match options.method {
            RetargetMethod::Offsets => offsets_lattice,
            RetargetMethod::Dense => dense::dense_lattice(normalisation, options.dense_spacing),
        };
        // Count the input voxels before allocating anything per voxel.
        let dims = input_dims(&lattice, mesh);
        let count: u128 = dims.iter().fold(1u128, |a, &d| a.saturating_mul(d as u128));
        if count > options.max_voxels as u128 && !options.force {
            return Err(RetargetError::TooLarge {
                what: "input voxel grid",
                unit: "voxels",
                value: count,
                limit: options.max_voxels as u128,
            });
        }
        let grid = VoxelGrid::covering(&lattice, &mesh.positions);
        let original = mesh.triangles.clone();
        let (mesh, parent) = match options.assignment {
            TriangleAssignment::Centroid => (mesh.clone(), (0..original.len() as u32).collect()),
            TriangleAssignment::Cut => cut::cut_at_voxel_faces(mesh, &lattice, &grid),
        };
        let pieces = stitch::Pieces::new(parent, original);
        let tri_voxel = voxels::assign_triangles(&mesh, &lattice, &grid);
        let input_surface = stitch::InputSurface::of(&mesh);
        progress.finish();
        let voxelize_ms = t0.elapsed().as_secs_f64() * 1e3;

        let t1 = Instant::now();
        let (descriptors, sampling_ms) = match features {
            Some(f) => {
                let mut occupied = vec![false; grid.len()];
                for &v in &tri_voxel {
                    occupied[v as usize] = true;
                }
                let (d, _) = voxels::describe_from_features(
                    f,
                    &lattice,
                    &grid,
                    occupied,
                    options.shot_radius,
                    progress,
                )?;
                (d, 0.0)
            }
            None => {
                let mut normalised = mesh.clone();
                for p in &mut normalised.positions {
                    *p = normalisation.to_normalised(*p);
                }
                let params = DescriptorParams {
                    sample_spacing: options.sample_spacing,
                    feature_spacing: options.feature_spacing,
                    shot_radius: options.shot_radius,
                    seed: options.seed,
                };
                voxels::describe_voxels(&normalised, &tri_voxel, grid.len(), &params, progress)?
            }
        };
        let descriptors_ms = t1.elapsed().as_secs_f64() * 1e3 - sampling_ms;
        Ok(RetargetSession {
            options: options.clone(),
            mesh,
            principal_offsets: principal_offsets.to_vec(),
            lattice,
            grid,
            tri_voxel,
            pieces,
            descriptors,
            cache: DistanceCache::default(),
            precompute: StageTimings { voxelize_ms, sampling_ms, descriptors_ms, ..Default::default() },
            precompute_ms: t0.elapsed().as_secs_f64() * 1e3,
            input_surface,
            cap_openings,
            fill_holes,
        })
    }

    /// Steps near `steps` to suggest when `steps` stitch with seams of infinite cost: each
    /// requested direction alone (when several are), and a single requested count moved to every
    /// other principal offset (the heat sink of `../shared/data` grown by two along its 12.5 mm
    /// screw-hole spacing has infinite seams, by two fins along its 3.8 mm offset none). Each
    /// candidate is one more solve on the session's descriptors (milliseconds); those with no
    /// infinite seam are returned, in this order. Steps are in the session's order of offsets.
    pub fn clean_alternatives(&mut self, steps: [i32; 3]) -> Vec<[i32; 3]> {
        let requested: Vec<usize> = (0..3).filter(|&k| steps[k] != 0).collect();
        let mut candidates: Vec<[i32; 3]> = Vec::new();
        if requested.len() > 1 {
            for &k in &requested {
                let mut s = [0; 3];
                s[k] = steps[k];
                candidates.push(s);
            }
        }
        if let [k] = requested[..] {
            for j in (0..self.principal_offsets.len().min(3)).filter(|&j| j != k) {
                let mut s = [0; 3];
                s[j] = steps[k];
                candidates.push(s);
            }
        }
        candidates
            .into_iter()
            .filter(|&s| {
                self.retarget(s, &motif_core::progress::NoProgress)
                    .is_ok_and(|r| r.report.infinite_seams == 0)
            })
            .collect()
    }

    /// The most negative steps [`retarget`](Self::retarget) accepts along each principal offset:
    /// shrinking keeps at least 2 voxels when the ends are preserved
    /// ([`BoundaryMode::Preserve`]: the first and the last cell), else 1. 0 along dummy
    /// directions, and for the dense baseline, whose voxels are not one per offset (its bound
    /// depends on all the steps at once).
    pub fn min_steps(&self) -> [i32; 3] {
        let minimum = self.min_voxels(-1) as i64;
        std::array::from_fn(|a| {
            if a >= self.principal_offsets.len() || self.options.method == RetargetMethod::Dense {
                0
            } else {
                (minimum - self.grid.dims[a] as i64).min(0) as i32
            }
        })
    }

    /// The fewest voxels a direction keeps under `steps` along it: 2 when shrinking with the ends
    /// preserved (the first and the last cell), else 1.
    fn min_voxels(&self, steps: i64) -> usize {
        if steps < 0 && self.options.boundary == BoundaryMode::Preserve { 2 } else { 1 }
    }

    /// Voxels of the input grid per axis (U_in, V_in, W_in).
    pub fn input_voxels(&self) -> [usize; 3] {
        self.grid.dims
    }

    /// Voxel edge lengths along the grid axes, normalised units.
    pub fn pitch(&self) -> [f64; 3] {
        self.grid.pitch
    }

    /// The model → normalised-space similarity.
    pub fn normalisation(&self) -> Normalisation {
        self.lattice.normalisation
    }

    /// The options the session was built with.
    pub fn options(&self) -> &RetargetOptions {
        &self.options
    }

    /// Resizes the model by `steps[i]` principal offsets along offset `i` (negative shrinks; 0
    /// for dummy directions).
    ///
    /// # Errors
    /// [`RetargetError::StepsAlongDummy`], [`RetargetError::ShrinkBelowOneCell`],
    /// [`RetargetError::TooLarge`] (Ω above `max_voxels`, Φ above `max_labels`, unless `force`).
    pub fn retarget(&mut self, steps: [i32; 3], progress: &dyn Progress) -> RetargetResult<Retargeted> {
        let t0 = Instant::now();
        let num_offsets = self.principal_offsets.len();
        for (a, &s) in steps.iter().enumerate() {
            if a >= num_offsets && s != 0 {
                return Err(RetargetError::StepsAlongDummy { direction: a, steps: s, offsets: num_offsets });
            }
        }
        let grid_steps_wide: [i64; 3] = match self.options.method {
            RetargetMethod::Offsets => steps.map(i64::from),
            RetargetMethod::Dense => dense::dense_steps(
                &self.lattice.normalisation,
                &self.principal_offsets,
                steps,
                self.options.dense_spacing,
            ),
        };
        let limit = |what, unit, value: u128, limit: u64| {
            if value > limit as u128 && !self.options.force {
                Err(RetargetError::TooLarge { what, unit, value, limit: limit as u128 })
            } else {
                Ok(())
            }
        };
        let mut out_dims = [0usize; 3];
        let mut voxels: u128 = 1;
        let mut labels: u128 = 1;
        for a in 0..3 {
            let s = grid_steps_wide[a];
            let n_in = self.grid.dims[a];
            let n_out = n_in as i64 + s;
            let minimum = self.min_voxels(s);
            if s < 0 && n_out < minimum as i64 && self.options.method == RetargetMethod::Dense {
                return Err(RetargetError::DenseShrinkTooFar {
                    axis: ["x", "y", "z"][a],
                    spacing: self.options.dense_spacing,
                    input_voxels: n_in,
                    output_voxels: n_out,
                    minimum,
                });
            }
            if s < 0 && n_out < minimum as i64 {
                return Err(RetargetError::ShrinkBelowOneCell {
                    direction: a,
                    steps: steps.get(a).copied().unwrap_or(0),
                    input_voxels: n_in,
                    output_voxels: n_out,
                    minimum,
                    min_steps: minimum as i64 - n_in as i64,
                });
            }
            voxels = voxels.saturating_mul(n_out.max(1) as u128);
            labels = labels.saturating_mul(s.unsigned_abs() as u128 + 1);
            out_dims[a] = n_out.max(1) as usize;
        }
        limit("retargeting space", "voxels", voxels, self.options.max_voxels)?;
        limit("offset space", "labels", labels, self.options.max_labels)?;
        // Past the limits (or forced), the per-(voxel, label) tables must still fit in memory
        // and the graph's u32 indices: a hard limit that `force` does not lift.
        let input_voxels = self.grid.len() as u128;
        let differences: u128 =
            grid_steps_wide.iter().fold(1u128, |a, s| a.saturating_mul(2 * s.unsigned_abs() as u128 + 1));
        let table = voxels.saturating_mul(labels).max(input_voxels.saturating_mul(differences));
        if table > MAX_TABLE_ENTRIES || voxels >= u32::MAX as u128 / 16 {
            return Err(RetargetError::TooLargeForMemory { value: table, limit: MAX_TABLE_ENTRIES });
        }
        let grid_steps = grid_steps_wide.map(|s| s as i32);

        progress.start("graph cut", 0);
        let solved = energy::solve(
            &self.grid,
            &self.descriptors,
            grid_steps,
            self.options.boundary,
            &mut self.cache,
            &self.options.graph_cut,
        )?;
        progress.finish();

        progress.start("stitch", 0);
        let t_stitch = Instant::now();
        let weld_tolerance = self.weld_tolerance();
        let stitched = stitch::stitch(
            &self.mesh,
            &self.tri_voxel,
            &self.pieces,
            &self.grid,
            out_dims,
            &solved.labels,
            &self.lattice,
            weld_tolerance,
            self.cap_openings,
            self.fill_holes,
            &self.input_surface,
        );
        let stitch_ms = t_stitch.elapsed().as_secs_f64() * 1e3;
        progress.finish();

        let (components, boundary_edges) = stitch::mesh_stats(&stitched.mesh);
        let solve_ms = t0.elapsed().as_secs_f64() * 1e3;
        let r = &solved.result;
        let report = RetargetReport {
            method: self.options.method,
            steps,
            grid_steps,
            num_offsets,
            pitch: self.grid.pitch,
            input_voxels: self.grid.dims,
            output_voxels: out_dims,
            nodes: solved.labels.len(),
            labels: grid_steps.iter().map(|s| s.unsigned_abs() as usize + 1).product(),
            edges: solved.edges,
            occupied_voxels: self.descriptors.occupied.iter().filter(|o| **o).count(),
            samples: self.descriptors.num_samples,
            features: self.descriptors.num_keypoints,
            descriptors: self.descriptors.num_valid,
            distances_computed: solved.distances_computed,
            initial_energy: r.initial_energy,
            energy: r.energy,
            cycles: r.cycles,
            moves: r.moves,
            termination: r.termination,
            seams: solved.seams,
            infinite_seams: solved.infinite_seams,
            labels_used: solved.labels_used,
            graph_cut_ms: r.elapsed_ms,
            solve_ms,
            total_ms: self.precompute_ms + solve_ms,
            stages: StageTimings {
                distances_ms: solved.distances_ms,
                graph_cut_ms: r.elapsed_ms,
                stitch_ms,
                ..self.precompute
            },
            output_vertices: stitched.mesh.positions.len(),
            output_triangles: stitched.mesh.triangles.len(),
            output_components: components,
            output_boundary_edges: boundary_edges,
            welded_vertices: stitched.welded + stitched.capped.merged,
            capped_loops: stitched.capped.loops,
            cap_triangles: stitched.capped.triangles,
            capped_folded_loops: stitched.capped.split_loops,
            cap_corners: stitched.capped.corners,
            cancelled_pairs: stitched.capped.cancelled_pairs,
            flat_sheets: stitched.capped.flat_sheets,
            winding_cap_planes: stitched.capped.winding_planes,
            filled_holes: stitched.filled.filled,
            // The fill sees again what capping kept open: the later count, not the sum.
            kept_open: if self.fill_holes { stitched.filled.kept_open } else { stitched.capped.kept_open },
            fill_triangles: stitched.filled.triangles,
            reoriented_triangles: stitched.reoriented,
            normalised_from_model: canonical::normalised_from_model(&self.lattice.normalisation),
            canonical_from_normalised: self.lattice.canonical_from_normalised,
        };
        Ok(Retargeted {
            mesh: stitched.mesh,
            report,
            voxel_labels: solved.labels,
            triangle_voxels: stitched.triangle_voxels,
        })
    }
}

/// Largest number of (voxel, label) and (input voxel, label difference) table entries a solve may
/// allocate, whatever `force` says (10⁸: about 1 GB of tables, and hours of graph cuts).
const MAX_TABLE_ENTRIES: u128 = 100_000_000;

/// The seam-welding tolerance never exceeds this share of the model's thinnest (non-zero)
/// bounding-box extent, whatever the cell size.
const MAX_WELD_SHARE_OF_THINNEST: f64 = 0.05;

/// Voxels of the input grid per axis, computed without allocating.
fn input_dims(lattice: &Lattice, mesh: &TriMesh) -> [usize; 3] {
    VoxelGrid::covering(lattice, &mesh.positions).dims
}

/// The offsets flipped where needed so that each one's largest-magnitude component is positive.
///
/// The sign of an offset chooses which end of the model grows: copies are added at the `+vᵢ` end
/// while the `−vᵢ` end stays in place. The offset detection reports offsets in an arbitrary half
/// space (e.g. `(0, −3.2, 0)` for a facade's floors); orienting them first makes a facade grow
/// upwards and a shelf to the right, keeping the model's minimum corner fixed.
pub fn orient_offsets(offsets: &[Point3]) -> Vec<Point3> {
    offsets
        .iter()
        .map(|v| {
            let k = crate::offsets::dominant_axis(*v);
            if v[k] < 0.0 { [-v[0], -v[1], -v[2]] } else { *v }
        })
        .collect()
}

/// Resizes `mesh` by `steps[i]` copies of `principal_offsets[i]` (model units, 1–3 vectors;
/// negative steps shrink, steps along missing offsets must be 0), with the method of
/// `options.method`. Copies are added (removed) at the `+vᵢ` end; see [`orient_offsets`].
/// One-shot form of [`RetargetSession`].
///
/// # Errors
/// See [`RetargetSession::new`] and [`RetargetSession::retarget`].
pub fn retarget(
    mesh: &TriMesh,
    principal_offsets: &[Point3],
    steps: [i32; 3],
    options: &RetargetOptions,
    progress: &dyn Progress,
) -> RetargetResult<Retargeted> {
    RetargetSession::new(mesh, principal_offsets, options, progress)?.retarget(steps, progress)
}

/// The dense-MRF baseline of thesis 4.5: [`retarget`] with [`RetargetMethod::Dense`] (regular
/// offsets of `options.dense_spacing` instead of the principal offsets; the output has about the
/// same size as `steps` principal offsets would give).
pub fn retarget_dense(
    mesh: &TriMesh,
    principal_offsets: &[Point3],
    steps: [i32; 3],
    options: &RetargetOptions,
    progress: &dyn Progress,
) -> RetargetResult<Retargeted> {
    let options = RetargetOptions { method: RetargetMethod::Dense, ..options.clone() };
    retarget(mesh, principal_offsets, steps, &options, progress)
}
