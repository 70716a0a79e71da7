//! Normalisation, two-scale Poisson-disc sampling and world-frame SHOT descriptors (thesis 4.2.1,
//! 4.3, 4.4): the precomputation shared by the offset analysis, the sparsity study and, later, the
//! retargeting MRF (which reuses the descriptors, thesis 4.2.2).
//!
//! Reading of the thesis (4.2.1 and 4.3): a *dense* cloud is Poisson-disc sampled at spacing 0.02;
//! *features* are re-sampled from it at spacing 0.06, and all mesh vertices are added as features.
//! Each feature gets a SHOT descriptor whose support is the dense cloud ("the high density samples
//! are used for computing feature descriptors"), and eq. 4.1 matches features against features
//! (`S(x + v)` with `x + v` another feature). So the dense cloud is the *support* of the
//! descriptors, not the matching pool; matching feature-to-feature is also what 4.3 describes
//! ("for each feature, we find its closest match").
//!
//! Mesh vertices: the thesis adds all of them. They are where exact copies produce exact offsets
//! (a corner maps onto a corner), which sharpens the histogram; but a 100k-vertex mesh would make
//! matching quadratic in 100k. They are therefore thinned ([`VertexFeatures::Thinned`]): a
//! Poisson-disc selection among the vertices at the dense spacing (vertices closer than that carry
//! no extra information at the descriptor's scale), then, if still more than `max_count`, the
//! spacing that gives about `max_count`. The kept vertices are forced samples of the dense cloud,
//! so they are part of the descriptors' support exactly once and the dense cloud keeps its spacing
//! around them; their normals are the mesh's area-weighted vertex normals.

use std::sync::{Arc, OnceLock};
use std::time::Instant;

use motif_core::Point3;
use motif_core::mesh::TriMesh;
use motif_core::progress::Progress;
use motif_core::sampling::{
    CandidateOrder, Constraints, ForcedOutput, PoissonDiscOptions, Spacing, poisson_disc_points,
    poisson_disc_surface,
};
use motif_core::shot::{SHOT_LEN, ShotFrame, ShotOptions, compute_shot_with_tree};
use motif_core::spatial::KdTree;
use serde::{Deserialize, Serialize};

use super::error::{OffsetsError, Result};
use super::matching::DescriptorDistances;
use super::{Density, OffsetOptions, VertexFeatures};

/// The similarity transform that scales a model so that its largest bounding-box dimension spans
/// [−1, 1] (thesis 4.3): `normalised = scale · (model − centre)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Normalisation {
    /// Centre of the model's bounding box, model units.
    pub centre: Point3,
    /// `2 / largest extent` (normalised units per model unit).
    pub scale: f64,
}

impl Normalisation {
    /// The normalisation of a bounding box `[min, max]`; fails when it is a single point.
    pub fn from_bounds(min: Point3, max: Point3) -> Result<Normalisation> {
        let extent = (0..3).map(|i| max[i] - min[i]).fold(0.0, f64::max);
        if !(extent > 0.0 && extent.is_finite()) {
            return Err(OffsetsError::Degenerate { extent });
        }
        Ok(Normalisation { centre: [0, 1, 2].map(|i| 0.5 * (min[i] + max[i])), scale: 2.0 / extent })
    }

    /// A model-space point in normalised coordinates.
    pub fn to_normalised(&self, p: Point3) -> Point3 {
        [0, 1, 2].map(|i| self.scale * (p[i] - self.centre[i]))
    }

    /// A normalised offset (a difference of points) in model units.
    pub fn offset_to_model(&self, v: Point3) -> Point3 {
        v.map(|c| c / self.scale)
    }

    /// A model-space offset in normalised units.
    pub fn offset_to_normalised(&self, v: Point3) -> Point3 {
        v.map(|c| c * self.scale)
    }
}

/// Where a feature comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeatureKind {
    /// A (thinned) mesh vertex.
    Vertex,
    /// A Poisson-disc sample of the dense cloud at the feature spacing.
    Sample,
}

/// Wall-clock milliseconds of the precomputation stages.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FeatureTimings {
    /// Normalising, thinning the vertices, Poisson-disc sampling at both scales, ms.
    pub sampling_ms: f64,
    /// Building the kd-tree of the dense cloud, ms.
    pub tree_ms: f64,
    /// SHOT descriptors of the features, ms.
    pub shot_ms: f64,
}

/// Sampled and described model: the input of matching (eq. 4.1), of the ICP refinement (4.4) and
/// of the retargeting MRF. All positions are normalised (see [`Normalisation`]).
#[derive(Debug)]
pub struct OffsetFeatures {
    /// Model → normalised coordinates.
    pub normalisation: Normalisation,
    /// The dense cloud (`#D`, normalised): the thinned vertices first, then surface samples.
    pub dense: Vec<Point3>,
    /// Unit normals of the dense cloud (`#D`): vertex normals, then face normals.
    pub dense_normals: Vec<Point3>,
    /// Number of leading dense points that are thinned mesh vertices.
    pub num_vertex_points: usize,
    /// Every mesh vertex used by a triangle (normalised): the partners of the vertex snap of the
    /// principal offsets (see [`super::refine::snap_to_vertices`]).
    pub mesh_vertices: Vec<Point3>,
    /// The features as indices into `dense` (`#F`): vertices first, then samples.
    pub features: Vec<usize>,
    /// Where each feature comes from (`#F`).
    pub kinds: Vec<FeatureKind>,
    /// SHOT descriptors in the world frame, `#F × 352` row-major; zero rows where invalid.
    pub descriptors: Vec<f32>,
    /// Whether each feature has a descriptor (`#F`).
    pub valid: Vec<bool>,
    /// Indices into `dense` of the uniform feature samples (not the vertices): the source cloud of
    /// the ICP refinement and of the overlap measure (evenly spread, unlike vertices).
    pub uniform: Vec<usize>,
    /// Kd-tree over `dense`, built once and shared by SHOT, ICP and the overlap measure.
    pub tree: KdTree,
    /// Surface area of the normalised mesh.
    pub area: f64,
    /// Factor (≤ 1) applied to the spacings for thin models (see [`Density`]); 1 otherwise.
    pub spacing_scale: f64,
    /// The dense spacing used, normalised units.
    pub dense_spacing: f64,
    /// The feature spacing used, normalised units.
    pub feature_spacing: f64,
    /// Stage timings.
    pub timings: FeatureTimings,
    /// The pairwise descriptor distances of the matching step, kept by [`super::analyze_features`]
    /// for the retargeting MRF (thesis 4.2.2); see [`OffsetFeatures::descriptor_distances`].
    pub(crate) distances: OnceLock<Arc<DescriptorDistances>>,
}

impl OffsetFeatures {
    /// The descriptor distances between all pairs of features, when [`super::analyze_features`]
    /// kept them (at most [`super::OffsetOptions::keep_distances_up_to`] features with a
    /// descriptor); the retargeting MRF then computes its Hausdorff distances from them.
    pub fn descriptor_distances(&self) -> Option<&Arc<DescriptorDistances>> {
        self.distances.get()
    }

    /// Number of features.
    pub fn len(&self) -> usize {
        self.features.len()
    }

    /// True when there are no features.
    pub fn is_empty(&self) -> bool {
        self.features.is_empty()
    }

    /// Position of feature `i` (normalised).
    pub fn position(&self, i: usize) -> Point3 {
        self.dense[self.features[i]]
    }

    /// Descriptor of feature `i` (352 values).
    pub fn descriptor(&self, i: usize) -> &[f32] {
        &self.descriptors[i * SHOT_LEN..(i + 1) * SHOT_LEN]
    }

    /// Number of features with a descriptor.
    pub fn num_valid(&self) -> usize {
        self.valid.iter().filter(|&&v| v).count()
    }
}

/// Normalises `mesh`, samples it at both scales and computes the features' SHOT descriptors
/// (thesis 4.2.1, 4.3). Only `dense_spacing`, `feature_spacing`, `vertex_features`,
/// `oversampling`, `shot_radius` and `seed` of `options` are used.
pub fn prepare_features(
    mesh: &TriMesh,
    options: &OffsetOptions,
    progress: &dyn Progress,
) -> Result<OffsetFeatures> {
    options.validate()?;
    if mesh.triangles.is_empty() {
        return Err(OffsetsError::NoSurface);
    }
    mesh.validate()?;
    let t0 = Instant::now();
    progress.start("sampling", 0);
    // The surface's box: a vertex no triangle uses (one stray vertex far off) would otherwise
    // shrink the model in normalised space until no offset passes the thresholds.
    let aabb = mesh.surface_aabb().ok_or(OffsetsError::NoSurface)?;
    let normalisation = Normalisation::from_bounds(aabb.min, aabb.max)?;
    let positions: Vec<Point3> = mesh.positions.iter().map(|&p| normalisation.to_normalised(p)).collect();
    let norm_mesh = TriMesh::new(positions, mesh.triangles.clone())?;
    let area = norm_mesh.area();
    // Thin models get proportionally finer spacings (see `Density`).
    let spacing_scale = match options.density {
        Density::Fixed => 1.0,
        Density::AtLeast { min_dense_points } => {
            let expected = area / (1.5 * options.dense_spacing * options.dense_spacing);
            if expected < min_dense_points as f64 && expected > 0.0 {
                (expected / min_dense_points as f64).sqrt().max(1e-3)
            } else {
                1.0
            }
        }
    };
    let dense_spacing = options.dense_spacing * spacing_scale;
    let feature_spacing = options.feature_spacing * spacing_scale;

    // Thinned vertices (only those used by a triangle).
    let mut used = vec![false; norm_mesh.positions.len()];
    for t in &norm_mesh.triangles {
        for &v in t {
            used[v as usize] = true;
        }
    }
    let vertex_normals = norm_mesh.vertex_normals();
    let used_idx: Vec<usize> = (0..used.len()).filter(|&i| used[i]).collect();
    let mesh_vertices: Vec<Point3> = used_idx.iter().map(|&i| norm_mesh.positions[i]).collect();
    let vertex_idx: Vec<usize> = match options.vertex_features {
        VertexFeatures::None => Vec::new(),
        VertexFeatures::All => used_idx,
        VertexFeatures::Thinned { min_spacing, max_count } => {
            let pts: Vec<Point3> = used_idx.iter().map(|&i| norm_mesh.positions[i]).collect();
            let mut o = PoissonDiscOptions {
                spacing: Spacing::Radius(min_spacing * spacing_scale),
                seed: options.seed,
                order: CandidateOrder::Random,
                forced_output: ForcedOutput::Include,
                ..Default::default()
            };
            let mut s = poisson_disc_points(&pts, None, &Constraints::default(), &o)?;
            if s.len() > max_count {
                o.spacing = Spacing::Count(max_count);
                o.count_tolerance = 0.05;
                s = poisson_disc_points(&pts, None, &Constraints::default(), &o)?;
            }
            s.candidate_indices().into_iter().map(|i| used_idx[i]).collect()
        }
    };
    let vertex_pos: Vec<Point3> = vertex_idx.iter().map(|&i| norm_mesh.positions[i]).collect();

    // Dense cloud: the vertices are forced samples, surface samples fill the rest.
    let dense_opts = PoissonDiscOptions {
        spacing: Spacing::Radius(dense_spacing),
        seed: options.seed,
        order: CandidateOrder::Random,
        forced_output: ForcedOutput::Include,
        oversampling: options.oversampling,
        ..Default::default()
    };
    let constraints = Constraints { forced: &vertex_pos, exclusion: &[] };
    let dense_s = poisson_disc_surface(&norm_mesh, &constraints, &dense_opts)?;
    let nv = vertex_pos.len();
    let dense = dense_s.positions;
    let mut dense_normals = dense_s.normals.unwrap_or_else(|| vec![[0.0; 3]; dense.len()]);
    for (k, &vi) in vertex_idx.iter().enumerate() {
        dense_normals[k] = vertex_normals[vi];
    }

    // Features: the vertices plus a Poisson-disc resampling of the surface samples.
    let feat_opts = PoissonDiscOptions {
        spacing: Spacing::Radius(feature_spacing),
        seed: options.seed.wrapping_add(1),
        order: CandidateOrder::Random,
        ..Default::default()
    };
    let resample = poisson_disc_points(&dense[nv..], None, &Constraints::default(), &feat_opts)?;
    let uniform: Vec<usize> = resample.candidate_indices().into_iter().map(|i| nv + i).collect();
    let mut features: Vec<usize> = (0..nv).collect();
    features.extend_from_slice(&uniform);
    let mut kinds = vec![FeatureKind::Vertex; nv];
    kinds.resize(features.len(), FeatureKind::Sample);
    progress.finish();
    let sampling = 1e3 * t0.elapsed().as_secs_f64();

    let t1 = Instant::now();
    let tree = KdTree::new(&dense)?;
    let tree_time = 1e3 * t1.elapsed().as_secs_f64();

    let t2 = Instant::now();
    let shot_opts =
        ShotOptions { radius: options.shot_radius, frame: ShotFrame::World, ..Default::default() };
    let shots = compute_shot_with_tree(&tree, &dense, &dense_normals, &features, &shot_opts, progress)?;
    let shot = 1e3 * t2.elapsed().as_secs_f64();
    let valid_count = shots.num_valid();
    if valid_count < 2 {
        return Err(OffsetsError::TooFewFeatures {
            valid: valid_count,
            total: features.len(),
            min: shot_opts.min_neighbours,
            radius: shot_opts.radius,
        });
    }
    Ok(OffsetFeatures {
        normalisation,
        dense,
        dense_normals,
        num_vertex_points: nv,
        mesh_vertices,
        features,
        kinds,
        descriptors: shots.descriptors,
        valid: shots.valid,
        uniform,
        tree,
        area,
        spacing_scale,
        dense_spacing,
        feature_spacing,
        timings: FeatureTimings { sampling_ms: sampling, tree_ms: tree_time, shot_ms: shot },
        distances: OnceLock::new(),
    })
}
