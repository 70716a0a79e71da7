//! Offset statistics: dominant and principal translational offsets of a model (thesis 4.2.1, 4.4).
//!
//! Pipeline ([`analyze_offsets`]):
//! 1. **Normalise** the model so its largest bounding-box dimension spans [−1, 1] (thesis 4.3);
//!    every length option is in these normalised units, and results are reported in both
//!    normalised and model units ([`Normalisation`]).
//! 2. **Sample** a dense cloud (Poisson disc, 0.02) and features (re-sampled at 0.06, plus thinned
//!    mesh vertices), and describe each feature by SHOT in the world frame with radius 0.2, the
//!    dense cloud as support ([`prepare_features`]; see [`features`] for the reading of 4.2.1).
//!    Thin models (fewer than 12 000 dense points at 0.02) get proportionally finer spacings
//!    ([`Density`]).
//! 3. **Match** each feature to the most similar feature farther than τ = 0.15 (eq. 4.1,
//!    [`match_features`]).
//! 4. **Histogram** the offsets in 0.05 bins, `v` and `−v` folded together
//!    ([`SignConvention::Canonical`]), and find **peaks** by non-maximum suppression with radius
//!    0.15 ([`OffsetHistogram::peaks`]): the dominant offsets.
//! 5. **Refine** each dominant offset by translation-only ICP of the cloud onto itself (4.4) and
//!    reject those that collapse towards zero, drift away from their peak, barely overlap, or
//!    duplicate a stronger one.
//! 6. **Select** up to three principal offsets greedily by support, each at least θ = π/3 from
//!    those chosen (4.4), and reduce each to its fundamental period ([`PeriodReduction`], a Motif
//!    extension: a principal offset must be the pitch, not a multiple of it), then snap it to the
//!    mesh's exact vertex-to-vertex translation when there is one
//!    ([`refine::snap_to_vertices`], a Motif extension: seams of CAD models then weld exactly).
//! 7. **Judge** whether the model repeats at all ([`RepetitionVerdict`]): some principal offset
//!    must be a discrete period by overlap contrast.
//!
//! Precompute/solve split: [`prepare_features`] (sampling, SHOT) then [`analyze_features`]
//! (matching onwards) — the sparsity study and the retargeting MRF reuse the features.

mod error;
pub mod features;
pub mod histogram;
pub mod matching;
pub mod refine;

use std::f64::consts::PI;
use std::time::Instant;

use motif_core::Point3;
use motif_core::geometry::{dot, norm};
use motif_core::mesh::TriMesh;
use motif_core::progress::Progress;
use serde::{Deserialize, Serialize};

pub use error::{OffsetsError, Result};
pub use features::{FeatureKind, FeatureTimings, Normalisation, OffsetFeatures, prepare_features};
pub use histogram::{HistogramBin, HistogramPeak, OffsetHistogram, SignConvention};
pub use matching::{DescriptorDistances, FeatureMatch, match_features, match_features_keeping_distances};
pub use refine::{IcpSummary, PeriodCandidate, VertexSnap};

use refine::Prober;

/// Which mesh vertices become features (thesis 4.2.1: "we also include all mesh vertexes as
/// features").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VertexFeatures {
    /// Every vertex used by a triangle (the thesis, literally). Matching cost grows with the
    /// square of the vertex count: only for small meshes.
    All,
    /// A Poisson-disc selection among the vertices: none closer than `min_spacing`, and at most
    /// about `max_count` (the spacing grows when needed). Default `min_spacing` 0.02 (the dense
    /// spacing, normalised units) and `max_count` 3000.
    Thinned {
        /// Minimum distance between kept vertices, normalised units; default 0.02.
        min_spacing: f64,
        /// Upper bound on kept vertices (±5%); default 3000.
        max_count: usize,
    },
    /// No vertex features: Poisson-disc samples only.
    None,
}

/// How dominant offsets are refined (thesis 4.4).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Refinement {
    /// Keep the peaks' mean offsets (accurate to about a bin).
    None,
    /// Translation-only point-to-plane ICP of the cloud onto itself from the peak's mean offset,
    /// pairing only points whose normals agree (thesis 4.4: "a global iterative closest point
    /// algorithm on the entire point cloud"; see [`refine`]).
    Icp {
        /// Iteration limit; default 30.
        max_iterations: usize,
        /// Correspondences farther apart are ignored, normalised units; default 0.05 (one bin:
        /// the peak is accurate to about that). Capped at 0.4 × the offset's length so a short
        /// period cannot snap to its neighbour.
        max_correspondence: f64,
    },
}

/// How much lower the overlap of a lattice generator may be than that of the multiple it replaces
/// (see [`PeriodReduction::Fundamental`]).
const LATTICE_OVERLAP_SLACK: f64 = 0.02;

/// A principal offset snapped to a vertex translation (see [`refine::snap_to_vertices`]) must
/// overlap the surface at least this close to the refined offset's overlap: an exact period
/// overlaps as much or more, a tessellation step beside it less.
const SNAP_OVERLAP_SLACK: f64 = 0.01;

/// Reduction of a principal offset to its fundamental period (a Motif extension; the thesis keeps
/// the selected dominant offsets as they are). A principal offset should be a generator of the
/// lattice — the pitch, not a multiple of it — but the strongest peak along a direction is often
/// a multiple: when the repeated parts alternate (a facade whose window styles alternate by
/// floor repeats exactly only every two floors, yet the floor grid repeats every floor), or when
/// the pitch is shorter than τ, which eq. 4.1 cannot see (a row of 41 fence posts, heat-sink
/// fins).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PeriodReduction {
    /// Report principal offsets as selected (the thesis).
    Off,
    /// Two steps, in this order:
    /// 1. *Lattice*: replace a principal offset `v` by the shortest accepted dominant offset `u`
    ///    with `v ≈ k u` for an integer `k ≥ 2` (`u`'s refined or peak mean offset within half a
    ///    bin or 2.5% of `|v|`), every
    ///    multiple `m v / k` in between also a dominant offset, and a support at least
    ///    `min_support_ratio ×` that of `v`, and whose translation maps at least as much of the
    ///    surface onto itself as `v` does (overlap, see [`refine`], within 0.02) — the generator
    ///    of the dominant offsets along that direction (thesis 4.2.1: principal offsets are the
    ///    generators the dominant offsets are combinations of), and of everything `v` repeats, not
    ///    of a part only. Its offset is `v / k`: `v`, the stronger peak, is often the exact
    ///    repetition and `u` a fuzzy one (a facade's floors with alternating window styles).
    /// 2. *Below τ*: score `v / k` for `k ≤ max_divisor` with `min_length ≤ |v / k| < τ` by the
    ///    overlap contrast (see [`refine`]) and take the best when it beats `v` itself.
    Fundamental {
        /// Minimum support of `u` relative to `v` in step 1; default 0.1.
        min_support_ratio: f64,
        /// Largest divisor tried in step 2; default 8.
        max_divisor: usize,
        /// Shortest period considered in step 2, normalised units; default 0.03 (periods much
        /// shorter than the dense spacing are not resolved).
        min_length: f64,
    },
}

/// How the sampling density adapts to the model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Density {
    /// The spacings as given (the thesis).
    Fixed,
    /// When the dense spacing would give fewer than `min_dense_points` points (thin models: a
    /// fence, heat-sink fins, a lattice of struts, whose parts are only a few dense spacings
    /// wide), shrink the dense spacing, the feature spacing, the vertex thinning spacing and the
    /// overlap tolerance by the same factor so the model gets about that many dense points.
    /// Default `min_dense_points` 12 000 (not in the thesis).
    AtLeast {
        /// Minimum expected number of dense points.
        min_dense_points: usize,
    },
}

/// The axis (0, 1, 2 for x, y, z) along which `v` has its largest component, the first on ties.
pub(crate) fn dominant_axis(v: Point3) -> usize {
    (0..3).fold(0, |k, a| if v[a].abs() > v[k].abs() { a } else { k })
}

/// Options of the offset analysis. Lengths are in normalised units (the model's largest
/// dimension spans [−1, 1], thesis 4.3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct OffsetOptions {
    /// Poisson-disc spacing of the dense cloud, the SHOT support (thesis 4.3: 0.02); default 0.02.
    pub dense_spacing: f64,
    /// Poisson-disc spacing of the features, re-sampled from the dense cloud (thesis 4.3: 0.06);
    /// default 0.06.
    pub feature_spacing: f64,
    /// Which mesh vertices are added as features (thesis 4.2.1); default
    /// `Thinned { min_spacing: 0.02, max_count: 3000 }`.
    pub vertex_features: VertexFeatures,
    /// Adaptation of the spacings to thin models; default `AtLeast { min_dense_points: 12000 }`.
    pub density: Density,
    /// Surface candidates drawn per expected dense sample before Poisson-disc elimination (not in
    /// the thesis); more gives a more even cloud, fewer is faster. Default 8 (at least 1).
    pub oversampling: f64,
    /// SHOT support radius `R` with the world frame (thesis 4.3, 4.4: 0.2); default 0.2.
    pub shot_radius: f64,
    /// τ, minimum offset length of a match (thesis eq. 4.1: 0.15); default 0.15.
    pub tau: f64,
    /// Side of the cubic histogram bins (thesis 4.3, 4.4: 0.05); default 0.05.
    pub bin_size: f64,
    /// How `v` and `−v` are binned; default [`SignConvention::Canonical`] (folded together).
    pub sign: SignConvention,
    /// Non-maximum suppression radius of the peak detection (thesis 4.2.1, 4.4: 0.15); default
    /// 0.15.
    pub nms_radius: f64,
    /// Peaks with fewer offsets in their 27-bin window are ignored (not in the thesis); default 3.
    pub min_peak_support: u32,
    /// Dominant offsets kept, strongest first (thesis 4.2.1: "usually about 20"); default 20.
    pub max_dominant: usize,
    /// Refinement of the dominant offsets (thesis 4.4); default ICP with 30 iterations and gate
    /// 0.05.
    pub refinement: Refinement,
    /// Most surface samples moved by the ICP refinement and the overlap measure (an even random
    /// subset when the dense cloud is larger; not in the thesis, which uses "the entire point
    /// cloud"); default 8000.
    pub icp_points: usize,
    /// Tangent-plane tolerance of the overlap measure (see [`refine`]), normalised units; default
    /// 0.005 (a quarter of the dense spacing).
    pub overlap_tolerance: f64,
    /// Dominant offsets whose refined translation overlaps less than this share of the surface
    /// are rejected (not in the thesis); default 0.05.
    pub min_overlap: f64,
    /// Maximum number of principal offsets (thesis 4.2.1: three, the generators of a 3-D
    /// lattice); default 3.
    pub max_principal: usize,
    /// θ, minimum angle between principal offsets (thesis 4.4: π/3), radians; default π/3.
    pub min_angle: f64,
    /// Reduction of principal offsets to their fundamental period; default
    /// `Fundamental { min_support_ratio: 0.1, max_divisor: 8, min_length: 0.03 }`.
    pub period_reduction: PeriodReduction,
    /// The repetition verdict needs a principal offset whose overlap contrast (see [`refine`])
    /// is at least this: shifting by it must map clearly more of the salient surface onto itself
    /// than shifting by half or one and a half of it (not in the thesis); default 0.1.
    pub min_contrast: f64,
    /// Snap each principal offset to the exact vertex-to-vertex translation of the mesh near it,
    /// when there is one (see [`refine::snap_to_vertices`]; not in the thesis); default true.
    pub snap_to_vertices: bool,
    /// [`analyze_features`] keeps the descriptor distances of all feature pairs computed by
    /// matching in the features, for the retargeting MRF's Hausdorff distances (thesis 4.2.2;
    /// [`analyze_offsets`], which drops its features, keeps none), when at most this many features have
    /// a descriptor (the table takes about n² bytes: 64 MiB for the default); 0 keeps none. Default
    /// 8192.
    pub keep_distances_up_to: usize,
    /// Seed of every random choice (sampling); default 0.
    pub seed: u64,
}

impl Default for OffsetOptions {
    fn default() -> Self {
        OffsetOptions {
            dense_spacing: 0.02,
            feature_spacing: 0.06,
            vertex_features: VertexFeatures::Thinned { min_spacing: 0.02, max_count: 3000 },
            density: Density::AtLeast { min_dense_points: 12_000 },
            oversampling: 8.0,
            shot_radius: 0.2,
            tau: 0.15,
            bin_size: 0.05,
            sign: SignConvention::Canonical,
            nms_radius: 0.15,
            min_peak_support: 3,
            max_dominant: 20,
            refinement: Refinement::Icp { max_iterations: 30, max_correspondence: 0.05 },
            icp_points: 8000,
            overlap_tolerance: 0.005,
            min_overlap: 0.05,
            max_principal: 3,
            min_angle: PI / 3.0,
            period_reduction: PeriodReduction::Fundamental {
                min_support_ratio: 0.1,
                max_divisor: 8,
                min_length: 0.03,
            },
            min_contrast: 0.1,
            snap_to_vertices: true,
            keep_distances_up_to: 8192,
            seed: 0,
        }
    }
}

fn positive(name: &'static str, v: f64) -> Result<()> {
    if v > 0.0 && v.is_finite() {
        Ok(())
    } else {
        Err(OffsetsError::InvalidOption { name, message: format!("must be positive and finite, got {v}") })
    }
}

impl OffsetOptions {
    /// Checks that every option is in its valid range.
    pub fn validate(&self) -> Result<()> {
        positive("dense_spacing", self.dense_spacing)?;
        positive("feature_spacing", self.feature_spacing)?;
        positive("shot_radius", self.shot_radius)?;
        positive("bin_size", self.bin_size)?;
        positive("nms_radius", self.nms_radius)?;
        positive("overlap_tolerance", self.overlap_tolerance)?;
        if !(self.oversampling.is_finite() && self.oversampling >= 1.0) {
            return Err(OffsetsError::InvalidOption {
                name: "oversampling",
                message: format!("must be at least 1, got {}", self.oversampling),
            });
        }
        if !(self.tau.is_finite() && self.tau >= 0.0) {
            return Err(OffsetsError::InvalidOption {
                name: "tau",
                message: format!("must be finite and ≥ 0, got {}", self.tau),
            });
        }
        if !(self.min_angle.is_finite() && (0.0..=PI / 2.0).contains(&self.min_angle)) {
            return Err(OffsetsError::InvalidOption {
                name: "min_angle",
                message: format!("must be between 0 and π/2 radians, got {}", self.min_angle),
            });
        }
        if let VertexFeatures::Thinned { min_spacing, max_count } = self.vertex_features {
            positive("vertex_features.min_spacing", min_spacing)?;
            if max_count == 0 {
                return Err(OffsetsError::InvalidOption {
                    name: "vertex_features.max_count",
                    message: "must be at least 1 (use VertexFeatures::None for no vertex features)".into(),
                });
            }
        }
        if let Refinement::Icp { max_correspondence, .. } = self.refinement {
            positive("refinement.max_correspondence", max_correspondence)?;
        }
        if let PeriodReduction::Fundamental { min_length, min_support_ratio, .. } = self.period_reduction {
            positive("period_reduction.min_length", min_length)?;
            if !(min_support_ratio.is_finite() && min_support_ratio >= 0.0) {
                return Err(OffsetsError::InvalidOption {
                    name: "period_reduction.min_support_ratio",
                    message: format!("must be finite and ≥ 0, got {min_support_ratio}"),
                });
            }
        }
        Ok(())
    }
}

/// Why a dominant offset was kept or set aside after refinement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "status")]
pub enum DominantStatus {
    /// A valid candidate for the principal offsets.
    Accepted,
    /// The refined offset is shorter than τ/2: ICP slid to the trivial translation (typical of
    /// smooth shapes without repetition).
    Collapsed,
    /// ICP moved more than two bins away from the peak: the peak is not a stable translation.
    Drifted,
    /// The refined translation maps less than `min_overlap` of the surface onto itself.
    LowOverlap,
    /// ICP found no correspondence within its gate.
    NoOverlap,
    /// Refines to within one bin of a stronger dominant offset (or its negative).
    Duplicate {
        /// Index of the stronger dominant offset.
        of: usize,
    },
}

/// A histogram peak with its refinement (thesis 4.2.1 "dominant offsets").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DominantOffset {
    /// The histogram peak (bin, counts, mean offset).
    pub peak: HistogramPeak,
    /// The offset after refinement (the peak's mean offset without refinement), normalised
    /// units, in the canonical half-space.
    pub offset: Point3,
    /// `offset` in model units.
    pub offset_model: Point3,
    /// Share of the surface the translation maps onto itself (see [`refine`]).
    pub overlap: f64,
    /// ICP details, when refined.
    pub icp: Option<IcpSummary>,
    /// Kept or why not.
    pub status: DominantStatus,
}

/// A principal offset: a generator of the model's translational lattice (thesis 4.2.1, 4.4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PrincipalOffset {
    /// The offset, normalised units, with its largest-magnitude component positive (the
    /// direction retargeting grows along, [`crate::retarget::orient_offsets`]).
    pub offset: Point3,
    /// The offset in model units.
    pub offset_model: Point3,
    /// Its length, normalised units.
    pub length: f64,
    /// Its length, model units.
    pub length_model: f64,
    /// Offsets supporting its dominant offset (27-bin window of the peak).
    pub support: u32,
    /// Share of all matched offsets that `support` is.
    pub support_share: f64,
    /// Index into [`OffsetAnalysis::dominant`] of the dominant offset the greedy selection chose
    /// (thesis 4.4).
    pub selected: usize,
    /// Index of the dominant offset this principal offset comes from after the lattice step of
    /// [`PeriodReduction::Fundamental`] (equal to `selected` when unchanged); `support` is its.
    pub dominant: usize,
    /// The selected dominant offset is this multiple of `dominant` (1 = unchanged).
    pub multiple: usize,
    /// `dominant` was divided by this to reach a period shorter than τ (1 = unchanged).
    pub divisor: usize,
    /// Share of the surface the translation maps onto itself.
    pub overlap: f64,
    /// Overlap contrast (see [`refine`]): high for a true period.
    pub contrast: f64,
    /// The candidates scored by the period reduction (empty when it is off).
    pub period_candidates: Vec<PeriodCandidate>,
    /// The snap of the refined offset to an exact vertex-to-vertex translation, when the mesh
    /// has one (`offset` is then the snapped offset).
    pub vertex_snap: Option<VertexSnap>,
}

/// Whether the model has translational repetition.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Repetition {
    /// A principal offset is a discrete period: shifting by it maps repeated parts onto each
    /// other, shifting by half or one and a half of it does not.
    Repetitive,
    /// No histogram peak is a translation of the model onto itself (a sphere, a natural shape:
    /// the peaks collapse or drift under ICP), or the translations found are continuous (a
    /// plane, an extrusion) or weak. Offset-based retargeting has nothing to follow here.
    NoRepetition,
}

/// The repetition verdict and its evidence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RepetitionVerdict {
    /// The verdict.
    pub kind: Repetition,
    /// Share of all offsets in the window of the strongest histogram peak (0 without peaks).
    pub top_peak_share: f64,
    /// Share that window would hold if the offsets were spread evenly over the non-empty bins:
    /// the window's non-empty bins over all non-empty bins (0 without peaks).
    pub uniform_share: f64,
    /// `top_peak_share / uniform_share`: about 1 for a flat histogram. Smooth shapes can have a
    /// concentrated histogram too (their best matches sit just beyond τ), so this is evidence,
    /// not the criterion.
    pub concentration: f64,
    /// Dominant offsets that refined to a translation of the model onto itself (accepted or
    /// duplicates), out of `dominant_total`.
    pub dominant_accepted: usize,
    /// Dominant offsets examined.
    pub dominant_total: usize,
    /// Dominant offsets that collapsed towards the zero offset under ICP.
    pub dominant_collapsed: usize,
    /// The principal offset with the highest overlap contrast (index into
    /// [`OffsetAnalysis::principal`]), if any.
    pub best_principal: Option<usize>,
    /// Its overlap (0 without one).
    pub overlap: f64,
    /// Its overlap contrast (0 without one): the criterion, see
    /// [`OffsetOptions::min_contrast`].
    pub contrast: f64,
    /// One sentence for people.
    pub summary: String,
}

/// Wall-clock milliseconds per stage (`_ms`, as every report of Motif gives times).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct StageTimings {
    /// Normalising and sampling (both scales, vertices).
    pub sampling_ms: f64,
    /// Kd-tree of the dense cloud.
    pub tree_ms: f64,
    /// SHOT descriptors.
    pub shot_ms: f64,
    /// Feature matching (eq. 4.1).
    pub matching_ms: f64,
    /// Histogram and peaks.
    pub histogram_ms: f64,
    /// ICP refinement of the dominant offsets.
    pub refinement_ms: f64,
    /// Principal offsets, period reduction and verdict.
    pub principal_ms: f64,
    /// Everything.
    pub total_ms: f64,
}

/// Counts of the sampled model.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct SampleCounts {
    /// Mesh vertices that some triangle uses (the surface's; `motif retarget --json` reported 0
    /// here, from [`analyze_features`]).
    pub mesh_vertices: usize,
    /// Dense points (SHOT support).
    pub dense: usize,
    /// Features (vertices + samples).
    pub features: usize,
    /// Of which thinned mesh vertices.
    pub vertex_features: usize,
    /// Features with a descriptor.
    pub valid_features: usize,
    /// Matched offsets in the histogram.
    pub offsets: usize,
    /// Non-empty histogram bins.
    pub bins: usize,
    /// Dense spacing used, normalised units (`dense_spacing` × `spacing_scale`).
    pub dense_spacing: f64,
    /// Feature spacing used, normalised units.
    pub feature_spacing: f64,
    /// Factor the spacings were scaled by for a thin model (see [`Density`]); 1 otherwise.
    pub spacing_scale: f64,
}

/// The result of [`analyze_offsets`]: serialisable for `motif offsets MESH --json OUT`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OffsetAnalysis {
    /// Model → normalised coordinates (`normalised = scale · (model − centre)`).
    pub normalisation: Normalisation,
    /// Sample and offset counts.
    pub counts: SampleCounts,
    /// Dominant offsets (histogram peaks, strongest first) with their refinement.
    pub dominant: Vec<DominantOffset>,
    /// Up to three principal offsets (thesis 4.4), in order of selection.
    pub principal: Vec<PrincipalOffset>,
    /// Indices into `principal` by the model axis each offset runs along most (x, then y, then
    /// z; then by support): the order in which `motif offsets` lists them and `motif retarget
    /// --steps U,V,W` counts them. The order of selection follows support, a count over a random
    /// sample, so two offsets of similar support swap when the sample changes (the generated
    /// shelf at 10⁻³ of its size: y 432 and x 427, against 386 and 420 at full size), and steps
    /// counted in that order grew a model the other way in another unit.
    #[serde(default)]
    pub axis_order: Vec<usize>,
    /// Whether the model repeats, with the evidence.
    pub repetition: RepetitionVerdict,
    /// Bin side of the histogram, normalised units.
    pub bin_size: f64,
    /// The non-empty histogram bins, largest first (canonical half-space with the default
    /// sign convention).
    pub histogram: Vec<HistogramBin>,
    /// The options used.
    pub parameters: OffsetOptions,
    /// Seconds per stage.
    pub timings: StageTimings,
}

/// Offset statistics of a mesh: [`prepare_features`] then [`analyze_features`]. Reports stages
/// to `progress`.
pub fn analyze_offsets(
    mesh: &TriMesh,
    options: &OffsetOptions,
    progress: &dyn Progress,
) -> Result<OffsetAnalysis> {
    let t0 = Instant::now();
    let features = prepare_features(mesh, options, progress)?;
    // The features are dropped here: keeping the matching distances for a retargeting MRF would
    // be wasted work.
    let mut a = analyze(&features, options, 0, progress)?;
    a.timings.total_ms = 1e3 * t0.elapsed().as_secs_f64();
    Ok(a)
}

/// Offset statistics from prepared features (matching, histogram, peaks, refinement, principal
/// offsets, verdict). `options` should be the ones the features were prepared with.
pub fn analyze_features(
    features: &OffsetFeatures,
    options: &OffsetOptions,
    progress: &dyn Progress,
) -> Result<OffsetAnalysis> {
    analyze(features, options, options.keep_distances_up_to, progress)
}

/// [`analyze_features`], keeping the matching distances in `features` for up to `keep_up_to`
/// features with a descriptor.
fn analyze(
    features: &OffsetFeatures,
    options: &OffsetOptions,
    keep_up_to: usize,
    progress: &dyn Progress,
) -> Result<OffsetAnalysis> {
    options.validate()?;
    let t_start = Instant::now();
    let nz = &features.normalisation;

    let t = Instant::now();
    let (matches, distances) =
        match_features_keeping_distances(features, &[options.tau], keep_up_to, progress)?;
    let matches = matches.into_iter().next().unwrap_or_default();
    if let Some(d) = distances {
        // Features analysed twice keep the first table (the same distances).
        let _ = features.distances.set(std::sync::Arc::new(d));
    }
    let matching = 1e3 * t.elapsed().as_secs_f64();

    let t = Instant::now();
    let hist =
        OffsetHistogram::from_offsets(matches.iter().map(|m| m.offset), options.bin_size, options.sign);
    let peaks = hist.peaks(options.nms_radius, options.min_peak_support);
    let histogram_time = 1e3 * t.elapsed().as_secs_f64();

    // Refinement.
    let t = Instant::now();
    let prober = Prober::new(
        features,
        features.dense_spacing,
        options.overlap_tolerance * features.spacing_scale,
        options.icp_points,
    )
    .ok_or(OffsetsError::NoSurface)?;
    let kept: Vec<HistogramPeak> = peaks.into_iter().take(options.max_dominant).collect();
    progress.start("refining dominant offsets", kept.len() as u64);
    let mut dominant: Vec<DominantOffset> = kept
        .iter()
        .map(|p| {
            let (offset, icp) = match options.refinement {
                Refinement::None => (p.mean_offset, None),
                Refinement::Icp { max_iterations, max_correspondence } => {
                    match prober.icp(p.mean_offset, max_iterations, max_correspondence) {
                        Some(s) => (s.offset, Some(s)),
                        None => (p.mean_offset, None),
                    }
                }
            };
            let offset = histogram::canonical_vector(offset, 1e-12);
            let overlap = prober.overlap(offset);
            let moved = norm(sub_canonical(offset, p.mean_offset));
            let status = if matches!(options.refinement, Refinement::Icp { .. }) && icp.is_none() {
                DominantStatus::NoOverlap
            } else if norm(offset) < 0.5 * options.tau {
                DominantStatus::Collapsed
            } else if moved > 2.0 * options.bin_size {
                DominantStatus::Drifted
            } else if overlap < options.min_overlap {
                DominantStatus::LowOverlap
            } else {
                DominantStatus::Accepted
            };
            progress.inc(1);
            DominantOffset {
                peak: *p,
                offset,
                offset_model: nz.offset_to_model(offset),
                overlap,
                icp,
                status,
            }
        })
        .collect();
    progress.finish();
    for i in 0..dominant.len() {
        if dominant[i].status != DominantStatus::Accepted {
            continue;
        }
        if let Some(j) = (0..i).find(|&j| {
            dominant[j].status == DominantStatus::Accepted
                && norm(sub_canonical(dominant[i].offset, dominant[j].offset)) <= options.bin_size
        }) {
            dominant[i].status = DominantStatus::Duplicate { of: j };
        }
    }
    let refinement = 1e3 * t.elapsed().as_secs_f64();

    // Principal offsets (thesis 4.4): greedy by support with the angle test.
    let t = Instant::now();
    let cos_max = options.min_angle.cos();
    let total = hist.total().max(1) as f64;
    let mut chosen: Vec<usize> = Vec::new();
    for (i, d) in dominant.iter().enumerate() {
        if chosen.len() >= options.max_principal {
            break;
        }
        if d.status != DominantStatus::Accepted {
            continue;
        }
        let ok = chosen.iter().all(|&j| {
            let c = dot(d.offset, dominant[j].offset) / (norm(d.offset) * norm(dominant[j].offset));
            c.abs() <= cos_max + 1e-12
        });
        if ok {
            chosen.push(i);
        }
    }
    let vertex_tree = if options.snap_to_vertices && !features.mesh_vertices.is_empty() {
        motif_core::spatial::KdTree::new(&features.mesh_vertices).ok()
    } else {
        None
    };
    let principal: Vec<PrincipalOffset> = chosen
        .iter()
        .map(|&i| {
            let mut source = i;
            let mut multiple = 1;
            let (mut divisor, mut candidates) = (1, Vec::new());
            if let PeriodReduction::Fundamental { min_support_ratio, max_divisor, min_length } =
                options.period_reduction
            {
                // Step 1: the shortest dominant offset that `v` is an integer multiple of, with
                // every multiple in between a dominant offset too.
                let v = dominant[i].offset;
                let lv = norm(v);
                let tol = (0.5 * options.bin_size).max(0.025 * lv);
                // A fuzzy repetition refines poorly, so its peak's mean offset counts too.
                let near = |d: &DominantOffset, w: Point3| {
                    norm(sub_canonical(d.offset, w)) <= tol
                        || norm(sub_canonical(d.peak.mean_offset, w)) <= tol
                };
                let near_dominant = |w: Point3| {
                    dominant.iter().any(|d| {
                        !matches!(d.status, DominantStatus::Collapsed | DominantStatus::NoOverlap)
                            && near(d, w)
                    })
                };
                let mut generators: Vec<(f64, usize, usize)> = Vec::new();
                for (j, u) in dominant.iter().enumerate() {
                    let lu = norm(u.offset);
                    if j == i || u.status != DominantStatus::Accepted || lu >= lv - tol || lu <= 0.0 {
                        continue;
                    }
                    let k = (lv / lu).round().max(1.0);
                    let fits = k >= 2.0
                        && near(u, v.map(|c| c / k))
                        && (2..k as usize).all(|m| near_dominant(v.map(|c| c * m as f64 / k)));
                    let strong = u.peak.support as f64 >= min_support_ratio * dominant[i].peak.support as f64;
                    if fits && strong {
                        generators.push((lu, j, k as usize));
                    }
                }
                // Shortest first; the generator must map at least as much of the surface onto
                // itself as `v` does — true of a period of everything `v` repeats, false of a
                // period of a part only (a gridbeam shelf's posts have a hole every 38 mm, its
                // boards repeat every 76 mm: 38 mm maps less of the surface than 76 mm).
                generators.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                if !generators.is_empty() {
                    let ov = prober.overlap(v);
                    if let Some(&(_, j, k)) = generators.iter().find(|&&(_, _, k)| {
                        prober.overlap(v.map(|c| c / k as f64)) >= ov - LATTICE_OVERLAP_SLACK
                    }) {
                        source = j;
                        multiple = k;
                    }
                }
                // Step 2: periods shorter than τ, by overlap contrast.
                let v = if multiple > 1 {
                    dominant[i].offset.map(|c| c / multiple as f64)
                } else {
                    dominant[i].offset
                };
                let min_len = min_length * features.spacing_scale;
                let (cands, k) = refine::reduce_period(&prober, v, max_divisor, min_len, options.tau);
                candidates = cands;
                divisor = k;
            }
            let d = &dominant[source];
            // A generator found by the lattice step is read off the refined multiple it divides:
            // the multiple is the exact repetition (a facade's two floors, window style A onto
            // A), the generator may be a fuzzy one (one floor, style A onto B) that ICP cannot
            // pin down on its own.
            let mut offset = if multiple > 1 {
                let v = dominant[i].offset;
                let k = multiple as f64;
                let to_u = if dot(v, d.offset) >= 0.0 { 1.0 / k } else { -1.0 / k };
                histogram::canonical_vector(v.map(|c| c * to_u), 1e-12)
            } else {
                d.offset
            };
            if divisor > 1 {
                let start = offset.map(|c| c / divisor as f64);
                offset = match options.refinement {
                    Refinement::Icp { max_iterations, max_correspondence } => prober
                        .icp(start, max_iterations, max_correspondence)
                        .map(|s| s.offset)
                        .filter(|o| norm(sub_canonical(*o, start)) <= 0.25 * norm(start))
                        .unwrap_or(start),
                    Refinement::None => start,
                };
                offset = histogram::canonical_vector(offset, 1e-12);
            }
            let mut vertex_snap = vertex_tree
                .as_ref()
                .and_then(|tree| {
                    refine::snap_to_vertices(features, tree, offset, 0.5 * features.dense_spacing)
                })
                // The snapped translation must map the surface onto itself at least as well.
                .filter(|snap| prober.overlap(snap.offset) >= prober.overlap(offset) - SNAP_OVERLAP_SLACK);
            if let Some(snap) = vertex_snap.as_mut() {
                offset = histogram::canonical_vector(snap.offset, 1e-12);
                snap.offset = offset;
            }
            let (overlap, contrast) = prober.contrast(offset);
            let length = norm(offset);
            // Measured as found (the overlap of `u` and of `−u` differ by sampling), then
            // reported with its largest-magnitude component positive, the orientation
            // retargeting grows along ([`crate::retarget::orient_offsets`]), so `motif offsets`
            // and `motif retarget` print the same vector. The histogram's half-space (first
            // non-zero coordinate positive, beyond 10⁻¹²) gave the heat sink's screw-hole pitch
            // as (2·10⁻⁹, −0.238, −3·10⁻⁹) normalised, printed as −0.0125 along y.
            let offset = crate::retarget::orient_offsets(&[offset])[0];
            if let Some(snap) = vertex_snap.as_mut() {
                snap.offset = offset;
            }
            PrincipalOffset {
                offset,
                offset_model: nz.offset_to_model(offset),
                length,
                length_model: length / nz.scale,
                support: d.peak.support,
                support_share: d.peak.support as f64 / total,
                selected: i,
                dominant: source,
                multiple,
                divisor,
                overlap,
                contrast,
                period_candidates: candidates,
                vertex_snap,
            }
        })
        .collect();

    // The flat reference counts the non-empty bins inside the peak's own window: on a model
    // whose offsets lie along one line (a fence) the window holds 3 of them, not 27, and a
    // reference of 27 bins called a peak holding 31.5% of the offsets "0.3× flat".
    let uniform_share = dominant.first().map_or(0.0, |d| {
        (hist.window_occupied(d.peak.index, 1) as f64 / hist.num_bins().max(1) as f64).min(1.0)
    });
    let top_peak_share = dominant.first().map_or(0.0, |d| d.peak.support as f64 / total);
    let repetition = verdict(&principal, &dominant, top_peak_share, uniform_share, options);
    let principal_time = 1e3 * t.elapsed().as_secs_f64();

    let timings = StageTimings {
        sampling_ms: features.timings.sampling_ms,
        tree_ms: features.timings.tree_ms,
        shot_ms: features.timings.shot_ms,
        matching_ms: matching,
        histogram_ms: histogram_time,
        refinement_ms: refinement,
        principal_ms: principal_time,
        total_ms: features.timings.sampling_ms
            + features.timings.tree_ms
            + features.timings.shot_ms
            + 1e3 * t_start.elapsed().as_secs_f64(),
    };
    let mut axis_order: Vec<usize> = (0..principal.len()).collect();
    axis_order.sort_by_key(|&i| {
        let p = &principal[i];
        (dominant_axis(p.offset), std::cmp::Reverse(p.support), p.selected)
    });
    Ok(OffsetAnalysis {
        axis_order,
        normalisation: *nz,
        counts: SampleCounts {
            mesh_vertices: features.mesh_vertices.len(),
            dense: features.dense.len(),
            features: features.len(),
            vertex_features: features.num_vertex_points,
            valid_features: features.num_valid(),
            offsets: hist.total(),
            bins: hist.num_bins(),
            dense_spacing: features.dense_spacing,
            feature_spacing: features.feature_spacing,
            spacing_scale: features.spacing_scale,
        },
        dominant,
        principal,
        repetition,
        bin_size: options.bin_size,
        histogram: hist.bins(),
        parameters: options.clone(),
        timings,
    })
}

/// `a − b` or `a + b`, whichever is shorter: the difference of two offsets up to sign.
fn sub_canonical(a: Point3, b: Point3) -> Point3 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let s = [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
    if norm(d) <= norm(s) { d } else { s }
}

fn verdict(
    principal: &[PrincipalOffset],
    dominant: &[DominantOffset],
    top_peak_share: f64,
    uniform_share: f64,
    options: &OffsetOptions,
) -> RepetitionVerdict {
    let accepted = dominant
        .iter()
        .filter(|d| matches!(d.status, DominantStatus::Accepted | DominantStatus::Duplicate { .. }))
        .count();
    let collapsed = dominant.iter().filter(|d| d.status == DominantStatus::Collapsed).count();
    let best = (0..principal.len()).max_by(|&a, &b| principal[a].contrast.total_cmp(&principal[b].contrast));
    let concentration = if uniform_share > 0.0 { top_peak_share / uniform_share } else { 0.0 };
    let (overlap, contrast) = best.map_or((0.0, 0.0), |b| (principal[b].overlap, principal[b].contrast));
    let repetitive = best.is_some() && contrast >= options.min_contrast;
    let histogram = format!(
        "the strongest histogram peak holds {:.1}% of the offsets, {concentration:.1}× what a flat spread over \
         the non-empty bins would give",
        100.0 * top_peak_share
    );
    let summary = match best {
        None => format!(
            "no repetition: none of the {} histogram peaks is a translation of the model onto itself under ICP \
             ({collapsed} collapsed to the zero offset, the others drifted or barely overlap); {histogram}",
            dominant.len()
        ),
        Some(b) if repetitive => {
            let p = &principal[b];
            format!(
                "repetitive: shifting by {} (model units) maps {:.0}% of the surface onto itself and {:.0} \
                 points more of its edges and corners than half or one and a half of that shift; {histogram}",
                motif_core::geometry::format_length(p.length_model, p.length_model, 4),
                100.0 * p.overlap,
                100.0 * p.contrast
            )
        }
        Some(b) => format!(
            "no repetition: the best offset ({:.4} model units, {:.0}% overlap) is no discrete period — half or \
             one and a half of it map the edges and corners as well (contrast {:.0} points, needs {:.0}): a \
             continuous symmetry (an extrusion, a plane) or a weak partial match; {histogram}",
            principal[b].length_model,
            100.0 * overlap,
            100.0 * contrast,
            100.0 * options.min_contrast
        ),
    };
    RepetitionVerdict {
        kind: if repetitive { Repetition::Repetitive } else { Repetition::NoRepetition },
        top_peak_share,
        uniform_share,
        concentration,
        dominant_accepted: accepted,
        dominant_total: dominant.len(),
        dominant_collapsed: collapsed,
        best_principal: best,
        overlap,
        contrast,
        summary,
    }
}
