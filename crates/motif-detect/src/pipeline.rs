//! The whole detector (thesis 5.3–5.4): pre-processing, HOC descriptors, dictionary, EM
//! co-occurrence, spectral instance detection, repeated as the MDL incremental scheme, with the
//! result in the shared detection schema plus per-point labels and a symmetry annotation.
//!
//! One-shot entry points: [`detect`] for point clouds, [`detect_mesh`] for meshes (sampled first).

use std::time::Instant;

use motif_core::procedural::{Region, Symmetry, SymmetryAnnotation, SymmetryInstance, SymmetryKind};
use motif_core::progress::Progress;
use motif_core::sampling::sample_surface;
use motif_core::spatial::KdTree;
use motif_core::{PointCloud, TriMesh};
use serde::{Deserialize, Serialize};

use crate::cooccurrence::{EmOptions, EmReport, match_all, run_em};
use crate::detection::{DetectedClass, DetectedInstance, DetectionResult};
use crate::dictionary::{DictionaryOptions, build};
use crate::error::{DetectError, Result};
use crate::extent::{ExtentOptions, ExtentReport, Regroup, regroup};
use crate::grid::SpatialHash;
use crate::hoc::{HocOptions, compute};
use crate::instances::{Class, ClusteringReport, InstanceOptions, detect_instances};
use crate::preprocess::{Feature, PreprocessOptions, Preprocessed, preprocess};
use crate::refine::{RefineOptions, RefineReport, VertexSnapReport, refine_on_vertices, refine_transforms};

/// Most EM iterations [`DetectOptions::validate`] accepts: the thesis runs 5 (5.4), and on
/// noisy scans the memberships keep changing by more than the 1% stopping rule, so an absurd
/// count would run for hours.
pub const MAX_EM_ITERATIONS: usize = 100;

/// Which variant of the detector runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// EM co-occurrence refinement, then spectral clustering (the thesis's "EM + SC").
    #[default]
    EmSc,
    /// Spectral clustering on the initial dictionary, no EM (the thesis's "SC" baseline, 5.5.3).
    Sc,
}

/// Options of [`detect`]: every parameter of thesis 5.3–5.4, grouped by stage.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DetectOptions {
    /// Resampling, curvature and features (5.3.1, 5.4).
    pub preprocess: PreprocessOptions,
    /// The HOC descriptor (5.4).
    pub hoc: HocOptions,
    /// The dictionary and the matching score (5.3.1, 5.4).
    pub dictionary: DictionaryOptions,
    /// EM co-occurrence detection (5.3.2, 5.4).
    pub em: EmOptions,
    /// Spectral clustering and the star model (5.3.3, 5.4).
    pub instances: InstanceOptions,
    /// Instance extents by segmentation and classes regrouped by size (not in the thesis; see
    /// [`crate::extent`]).
    pub extent: ExtentOptions,
    /// EM + SC or the SC baseline.
    pub method: Method,
    /// Rounds of the MDL incremental scheme (5.4): each keeps the largest class and removes its
    /// features. The thesis's Fig. 5.6 found five classes; Motif allows 7 rounds because small
    /// classes (balconies, doors, cars, bins: 2–8 instances a scene) only come after the windows
    /// and their splits, and the stopping rule below ends the scheme earlier on most scenes.
    /// Default 7.
    pub mdl_rounds: usize,
    /// MDL stopping rule: a round's class is kept only when describing its instances as copies of
    /// one template saves at least this fraction of all features, saving = (N − 1)·f̄ − f̄ − N
    /// for N instances of f̄ features each (the template once, one transform per instance, instead
    /// of every instance's features); for a cluster split into several classes
    /// ([`crate::instances::ClassSplit`]), the sum of its classes' savings. The thesis keeps "the
    /// minimal number of classes that describe most of the input" without a number; 0.005 stops
    /// once a class explains under 0.5% of the features (20 of the default 4,000: five instances
    /// of six features). Was 0.02, which on the generated benchmark scenes stopped before the
    /// classes of 2–6 instances (balconies of 6 instances with 15 features each save 4·15 − 6 =
    /// 54 < 80) and cost about a third of the recall on medium scenes. Default 0.005.
    pub mdl_min_saving: f64,
    /// Fewer features than this: nothing to detect (an empty result, not an error). Default 40.
    pub min_features: usize,
    /// Meshes are sampled with this many points before detection. Default 300,000.
    pub mesh_samples: usize,
    /// Seed of every random choice (resampling order, k-means++, mesh sampling).
    pub seed: u64,
    /// Refining the transforms between instances by ICP ([`crate::refine`]; not in the thesis).
    pub refine: RefineOptions,
}

impl Default for DetectOptions {
    fn default() -> Self {
        DetectOptions {
            preprocess: PreprocessOptions::default(),
            hoc: HocOptions::default(),
            dictionary: DictionaryOptions::default(),
            em: EmOptions::default(),
            instances: InstanceOptions::default(),
            extent: ExtentOptions::default(),
            method: Method::EmSc,
            mdl_rounds: 7,
            mdl_min_saving: 0.005,
            min_features: 40,
            mesh_samples: 300_000,
            seed: 0,
            refine: RefineOptions::default(),
        }
    }
}

impl DetectOptions {
    /// Checks the options of the later stages ([`preprocess`] checks its own, and ε once it knows
    /// the data): lengths, widths and bandwidths positive and finite, shares and scores within
    /// [0, 1], at least two words. [`detect`] calls it first; front ends may call it before
    /// reading any input.
    ///
    /// # Errors
    /// [`DetectError::InvalidOption`] naming the first field out of range (`em.peak_share`, ...).
    pub fn validate(&self) -> Result<()> {
        let bad = |name: &'static str, message: String| Err(DetectError::InvalidOption { name, message });
        for (name, v) in [
            ("hoc.cell", self.hoc.cell),
            ("dictionary.sigma", self.dictionary.sigma),
            ("dictionary.tolerance", self.dictionary.tolerance),
            ("em.match_radius", self.em.match_radius),
            ("em.pair_radius", self.em.pair_radius),
            ("em.sigma_s", self.em.sigma_s),
            ("instances.bandwidth", self.instances.bandwidth),
            ("extent.link_radius", self.extent.link_radius),
            ("extent.plane_tolerance", self.extent.plane_tolerance),
            ("extent.support_diagonal", self.extent.support_diagonal),
            ("extent.max_growth", self.extent.max_growth),
            ("extent.split_distance", self.extent.split_distance),
            ("extent.merge_distance", self.extent.merge_distance),
            ("extent.spread_floor", self.extent.spread_floor),
            ("extent.spread_cap", self.extent.spread_cap),
            ("extent.segment_distance", self.extent.segment_distance),
            ("extent.shape_tolerance", self.extent.shape_tolerance),
            ("extent.content.window", self.extent.content.window),
            ("extent.aligned.cells_per_block", self.extent.aligned.cells_per_block),
            ("extent.aligned.slab", self.extent.aligned.slab),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, format!("must be positive and finite, got {v}"));
            }
        }
        for (name, v) in [
            ("dictionary.min_score", self.dictionary.min_score),
            ("em.peak_share", self.em.peak_share),
            ("em.min_confidence", self.em.min_confidence),
            ("instances.min_links", self.instances.min_links),
            ("instances.merge_overlap", self.instances.merge_overlap),
            ("extent.normal_cos", self.extent.normal_cos),
            ("extent.turned_area", self.extent.turned_area),
            ("extent.shape_similarity", self.extent.shape_similarity),
            ("extent.content.surface_coverage", self.extent.content.surface_coverage),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return bad(name, format!("must be between 0 and 1, got {v}"));
            }
        }
        if !(0.0..0.5).contains(&self.extent.fit_trim) {
            let v = self.extent.fit_trim;
            return bad("extent.fit_trim", format!("must be at least 0 and below 0.5, got {v}"));
        }
        if !(0.0..0.5).contains(&self.instances.box_trim) {
            let v = self.instances.box_trim;
            return bad("instances.box_trim", format!("must be at least 0 and below 0.5, got {v}"));
        }
        if self.mdl_rounds == 0 {
            return bad("mdl_rounds", "must be at least 1 (one round finds the first class)".into());
        }
        if self.mesh_samples < MIN_MESH_SAMPLES {
            let v = self.mesh_samples;
            return bad("mesh_samples", format!("must be at least {MIN_MESH_SAMPLES}, got {v}"));
        }
        if self.preprocess.max_features == 0 {
            return bad("preprocess.max_features", "must be at least 1".into());
        }
        if !(self.mdl_min_saving.is_finite() && self.mdl_min_saving >= 0.0) {
            let v = self.mdl_min_saving;
            return bad("mdl_min_saving", format!("must be finite and ≥ 0, got {v}"));
        }
        if !(self.extent.segment_contrast.is_finite() && self.extent.segment_contrast >= 0.0) {
            let v = self.extent.segment_contrast;
            return bad("extent.segment_contrast", format!("must be finite and ≥ 0, got {v}"));
        }
        if self.extent.shape_length.is_nan() || self.extent.shape_length <= 0.0 {
            let v = self.extent.shape_length;
            return bad(
                "extent.shape_length",
                format!("must be positive (infinity: no shape groups), got {v}"),
            );
        }
        if self.extent.spread_cap < self.extent.spread_floor {
            let (c, f) = (self.extent.spread_cap, self.extent.spread_floor);
            return bad("extent.spread_cap", format!("must be at least extent.spread_floor ({f}), got {c}"));
        }
        if !(self.extent.content.size_weight.is_finite() && self.extent.content.size_weight >= 0.0) {
            let v = self.extent.content.size_weight;
            return bad("extent.content.size_weight", format!("must be finite and ≥ 0, got {v}"));
        }
        let al = &self.extent.aligned;
        if !(0.0..1.0).contains(&al.margin) {
            return bad(
                "extent.aligned.margin",
                format!("must be at least 0 and below 1, got {}", al.margin),
            );
        }
        if al.flatness.is_nan() || al.flatness <= 0.0 {
            let v = al.flatness;
            return bad(
                "extent.aligned.flatness",
                format!("must be positive (infinity: every instance), got {v}"),
            );
        }
        if let Err((name, message)) = self.extent.copies.validate() {
            return bad(name, message);
        }
        if let Err((name, message)) = self.extent.shapes.validate() {
            return bad(name, message);
        }
        if al.scale_rank == 0 {
            return bad("extent.aligned.scale_rank", "must be at least 1, got 0".to_string());
        }
        if !(al.resolution.is_finite() && al.resolution > 0.0) {
            let v = al.resolution;
            return bad("extent.aligned.resolution", format!("must be finite and positive, got {v}"));
        }
        if al.core_cells == 0 || al.core_cells > al.image_cells || (al.image_cells - al.core_cells) % 2 == 1 {
            let (n, c) = (al.image_cells, al.core_cells);
            return bad(
                "extent.aligned.core_cells",
                format!(
                    "must be at least 1 and at most extent.aligned.image_cells ({n}), with an even difference \
                     (the core is centred), got {c}"
                ),
            );
        }
        if !(0.0..1.0).contains(&self.extent.content.margin) {
            let v = self.extent.content.margin;
            return bad("extent.content.margin", format!("must be at least 0 and below 1, got {v}"));
        }
        for (name, v) in [
            ("extent.content.class_residual", self.extent.content.class_residual),
            ("extent.content.outlier_residual", self.extent.content.outlier_residual),
        ] {
            // Infinity is allowed: it switches that test off.
            if v.is_nan() || v <= 0.0 {
                return bad(name, format!("must be positive (infinity switches the test off), got {v}"));
            }
        }
        if !(self.extent.content.class_explained.is_finite() && self.extent.content.class_explained >= 0.0) {
            let v = self.extent.content.class_explained;
            return bad("extent.content.class_explained", format!("must be finite and ≥ 0, got {v}"));
        }
        if self.extent.content.grid == 0 {
            return bad("extent.content.grid", "must be at least 1, got 0".into());
        }
        if !(1..=MAX_EM_ITERATIONS).contains(&self.em.iterations) {
            let v = self.em.iterations;
            return bad(
                "em.iterations",
                format!(
                    "must be 1 to {MAX_EM_ITERATIONS} (thesis 5.4: 5; EM rarely settles on noisy scans), got {v}"
                ),
            );
        }
        if self.dictionary.words < 2 {
            return bad("dictionary.words", format!("must be at least 2, got {}", self.dictionary.words));
        }
        if self.instances.embedding_dims == 0 {
            return bad("instances.embedding_dims", "must be at least 1, got 0".into());
        }
        Ok(())
    }
}

/// One MDL round.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RoundReport {
    /// Features entering the round.
    pub features: usize,
    /// k-means clusters used.
    pub k: usize,
    /// Words with at least two matches after the sliding window.
    pub words: usize,
    /// Members per word after the sliding window: (median, maximum).
    pub word_sizes: (usize, usize),
    /// Members per word after EM: (median, maximum).
    pub word_sizes_after_em: (usize, usize),
    /// d̂, the median within-cluster L1 distance (the matching score's unit).
    pub descriptor_unit: f64,
    /// The EM run (empty for the SC baseline).
    pub em: EmReport,
    /// Spectral clustering.
    pub clustering: ClusteringReport,
    /// Instances of the classes kept in this round (0 when the round found nothing).
    pub kept_instances: usize,
    /// Classes kept in this round: the largest and those split from its cluster.
    pub kept_classes: usize,
    /// The MDL saving of a class that was found but rejected by the stopping rule.
    pub rejected_saving: Option<f64>,
    /// Words of the kept class.
    pub kept_words: usize,
    /// Mean features per instance of the kept class (the star model's links plus the centre).
    pub kept_features_per_instance: f64,
    /// Seconds in the dictionary, EM and instance stages.
    pub seconds: [f64; 3],
}

/// Timings and counts of a whole detection, for `--json`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DetectReport {
    /// Input points.
    pub input_points: usize,
    /// ε in input units.
    pub epsilon: f64,
    /// The principal-axes diagonal ε is relative to.
    pub diagonal: f64,
    /// Points after resampling.
    pub resampled_points: usize,
    /// Salient features.
    pub features: usize,
    /// Whether normals were estimated.
    pub normals_estimated: bool,
    /// The MDL rounds.
    pub rounds: Vec<RoundReport>,
    /// Classes found, instances per class.
    pub instances_per_class: Vec<usize>,
    /// Classes joined after the MDL rounds ([`crate::class_merge`]).
    pub class_merges: usize,
    /// Instance extents and classes regrouped by size ([`crate::extent`]).
    pub extent: ExtentReport,
    /// Instance transforms refined by ICP ([`crate::refine`]).
    #[serde(default)]
    pub refine: RefineReport,
    /// For a mesh input, instance transforms snapped to its vertices ([`crate::refine`]).
    #[serde(default)]
    pub vertex_snap: VertexSnapReport,
    /// Seconds per stage: preprocess, descriptors, dictionary, EM, instances, output.
    pub seconds: StageSeconds,
    /// Warnings, in words.
    pub warnings: Vec<String>,
}

/// Wall-clock seconds per stage.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StageSeconds {
    /// Resampling, normals, curvature, features.
    pub preprocess: f64,
    /// HOC descriptors.
    pub descriptors: f64,
    /// k-means and sliding windows (all rounds).
    pub dictionary: f64,
    /// EM (all rounds).
    pub em: f64,
    /// Clustering and star model (all rounds).
    pub instances: f64,
    /// Point labels and boxes, and the transforms refined ([`crate::refine`]).
    pub output: f64,
    /// Everything.
    pub total: f64,
}

/// A detection: the shared-schema result, per-point labels and the internals.
#[derive(Debug, Clone)]
pub struct Detection {
    /// The result in the schema of `../shared/formats/detection.md` (instance points are input
    /// indices).
    pub result: DetectionResult,
    /// Per input point: (class, instance), or `None` for background.
    pub labels: Vec<Option<(u32, u32)>>,
    /// The classes with their star models.
    pub classes: Vec<Class>,
    /// The features (frames canonicalised).
    pub features: Vec<Feature>,
    /// Counts and timings.
    pub report: DetectReport,
    /// For a mesh input, the sampled points the labels refer to (the instances' `points` name the
    /// mesh's vertices).
    pub samples: Option<PointCloud>,
}

impl Detection {
    /// The classes as a `motif_symmetry_v1` annotation of instance sets (regions are the instance
    /// boxes), so a detection can drive symmetry-preserving deformation.
    pub fn as_symmetry(&self) -> SymmetryAnnotation {
        self.as_symmetry_selecting(None).0
    }

    /// [`Self::as_symmetry`] for the mesh the detection ran on (`vertices`, its vertex
    /// positions): an annotation's region must select vertices of the mesh it annotates, so an
    /// instance whose box holds none (a box inside one large triangle of a wall) is left out, and
    /// a class left with fewer than two instances too. Returns the annotation and a note per
    /// omission.
    pub fn as_symmetry_on_mesh(&self, vertices: &[motif_core::Point3]) -> (SymmetryAnnotation, Vec<String>) {
        self.as_symmetry_selecting(Some(vertices))
    }

    fn as_symmetry_selecting(
        &self,
        vertices: Option<&[motif_core::Point3]>,
    ) -> (SymmetryAnnotation, Vec<String>) {
        let mut a = SymmetryAnnotation::default();
        let mut notes = Vec::new();
        for (ci, c) in self.result.classes.iter().enumerate() {
            let name = c.name.clone().unwrap_or_else(|| format!("class_{ci}"));
            let holds_vertex = |i: &DetectedInstance| {
                vertices.is_none_or(|v| {
                    v.iter().any(|p| (0..3).all(|k| p[k] >= i.bbox_min[k] && p[k] <= i.bbox_max[k]))
                })
            };
            let kept: Vec<&DetectedInstance> = c.instances.iter().filter(|i| holds_vertex(i)).collect();
            let dropped = c.instances.len() - kept.len();
            if kept.len() < 2 {
                if dropped > 0 {
                    notes.push(format!(
                        "{name}: left out of the symmetry annotation: {dropped} of its {} instance boxes {} no \
                         mesh vertex, which leaves fewer than two",
                        c.instances.len(),
                        if dropped == 1 { "holds" } else { "hold" }
                    ));
                }
                if !c.instances.is_empty() && vertices.is_some() {
                    continue;
                }
            } else if dropped > 0 {
                notes.push(format!(
                    "{name}: {dropped} of its {} instance boxes {} no mesh vertex and {} left out of the \
                     symmetry annotation",
                    c.instances.len(),
                    if dropped == 1 { "holds" } else { "hold" },
                    if dropped == 1 { "is" } else { "are" }
                ));
            }
            // The first instance kept is the template: transforms are re-based onto it, so that
            // its own is the identity as the format asks (the partial maps T_a·T_b⁻¹ between
            // instances are unchanged).
            let identity = motif_core::geometry::IDENTITY4;
            let base = kept.first().map_or(identity, |i| {
                motif_core::procedural::rigid_inverse(&i.transform.unwrap_or(identity))
            });
            let instances = kept
                .iter()
                .map(|i| SymmetryInstance {
                    region: Region::Aabb { min: i.bbox_min, max: i.bbox_max },
                    transform: motif_core::geometry::mat4_mul(&i.transform.unwrap_or(identity), &base),
                })
                .collect();
            a.symmetries.push(Symmetry { name, kind: SymmetryKind::Instances { instances } });
        }
        (a, notes)
    }
}

/// Fewest points [`detect_mesh`] samples on a mesh ([`DetectOptions::mesh_samples`]).
pub const MIN_MESH_SAMPLES: usize = 100;

/// Detects building blocks in a mesh: samples `mesh_samples` points on its surface (with face
/// normals) and runs [`detect`]; instance point indices refer to those samples. `force` lifts
/// the limits on ε, as for [`detect`].
pub fn detect_mesh(
    mesh: &TriMesh,
    scene: &str,
    o: &DetectOptions,
    progress: &dyn Progress,
    force: bool,
) -> Result<Detection> {
    o.validate()?;
    let s = sample_surface(mesh, o.mesh_samples, o.seed)?;
    let mut cloud = PointCloud::from_positions(s.points);
    cloud.normals = Some(s.normals);
    let mut d = detect(&cloud, scene, o, progress, force)?;
    // The density is this function's choice, not the data's: say which option sets it.
    for w in &mut d.report.warnings {
        if w.ends_with(crate::preprocess::SPARSER_THAN_THE_THESIS) {
            w.push_str(&format!(
                " (the mesh was sampled at {} points: more, with --mesh-samples, keep the thesis's ε)",
                o.mesh_samples
            ));
        }
    }
    d.report.vertex_snap = refine_on_vertices(&mut d.result, &mesh.positions);
    points_on_vertices(&mut d.result, &cloud, mesh)?;
    d.samples = Some(cloud);
    Ok(d)
}

/// Renames the instances' `points` from the surface samples the detection ran on to the mesh's
/// vertices, the input's points (`../shared/formats/detection.md`: "indices of input points"):
/// each vertex joins the instances of its nearest sample. They indexed the samples, up to 59,996
/// on a 3,380-vertex facade, which no reader of the result has (the studio dropped them).
fn points_on_vertices(result: &mut DetectionResult, samples: &PointCloud, mesh: &TriMesh) -> Result<()> {
    let tree = KdTree::new(&samples.positions)?;
    let nearest: Vec<usize> = mesh.positions.iter().map(|p| tree.nearest(*p).index).collect();
    // The instances each sample belongs to (a sample may lie in two overlapping instances).
    let mut member: Vec<Vec<(u32, u32)>> = vec![Vec::new(); samples.len()];
    for (c, class) in result.classes.iter().enumerate() {
        for (i, inst) in class.instances.iter().enumerate() {
            for &k in inst.points.iter().flatten() {
                if let Some(m) = member.get_mut(k as usize) {
                    m.push((c as u32, i as u32));
                }
            }
        }
    }
    let mut points: Vec<Vec<Vec<u32>>> =
        result.classes.iter().map(|c| vec![Vec::new(); c.instances.len()]).collect();
    for (v, &s) in nearest.iter().enumerate() {
        for &(c, i) in &member[s] {
            points[c as usize][i as usize].push(v as u32);
        }
    }
    for (class, pts) in result.classes.iter_mut().zip(points) {
        for (inst, p) in class.instances.iter_mut().zip(pts) {
            if inst.points.is_some() {
                inst.points = Some(p);
            }
        }
    }
    Ok(())
}

/// Detects building blocks in a point cloud (thesis 5.3–5.4). `force` lifts the limit on the
/// resampled size. An input with too few features yields an empty result and a warning.
pub fn detect(
    cloud: &PointCloud,
    scene: &str,
    o: &DetectOptions,
    progress: &dyn Progress,
    force: bool,
) -> Result<Detection> {
    o.validate()?;
    let t0 = Instant::now();
    let mut report = DetectReport { input_points: cloud.len(), ..Default::default() };
    progress.start("resample, normals, curvature, features", 0);
    let mut popts = o.preprocess.clone();
    popts.seed = o.seed;
    let mut pre = preprocess(cloud, &popts, force)?;
    progress.finish();
    report.seconds.preprocess = t0.elapsed().as_secs_f64();
    report.epsilon = pre.epsilon;
    report.diagonal = pre.diagonal;
    report.resampled_points = pre.points.len();
    report.features = pre.features.len();
    report.normals_estimated = pre.normals_estimated;
    report.warnings.extend(pre.warnings.iter().cloned());
    let empty = |report: DetectReport, features: Vec<Feature>| Detection {
        result: DetectionResult { scene: scene.to_string(), classes: Vec::new() },
        labels: vec![None; cloud.len()],
        classes: Vec::new(),
        features,
        report,
        samples: None,
    };
    if pre.features.len() < o.min_features.max(8) {
        if pre.points.is_empty() && !pre.warnings.is_empty() {
            // Preprocessing already said why there is nothing to detect (too few points, or no
            // extent); advice about ε or κ would mislead.
            report.seconds.total = t0.elapsed().as_secs_f64();
            return Ok(empty(report, pre.features));
        }
        // A smaller ε helps only while resampling drops points; at the data's own spacing it
        // cannot add any.
        let at_data_resolution = pre.points.len() as f64 >= 0.9 * cloud.len() as f64;
        let advice = if at_data_resolution {
            "ε is at or below the data's own spacing, so a smaller one adds no points: try a lower kappa \
             threshold, or denser data"
        } else {
            "try a smaller ε or a lower kappa threshold"
        };
        report.warnings.push(format!(
            "only {} salient features (need {}): too few for a dictionary, nothing detected; {advice}",
            pre.features.len(),
            o.min_features.max(8)
        ));
        report.seconds.total = t0.elapsed().as_secs_f64();
        return Ok(empty(report, pre.features));
    }
    // The dictionary keeps at most a quarter as many words as features (dictionary::build); a
    // request for more words than features is a mistake worth naming.
    let n = pre.features.len();
    if o.dictionary.words > n {
        report.warnings.push(format!(
            "{} words asked for {n} features: the dictionary has {} (at most a quarter of the features)",
            o.dictionary.words,
            (n / 4).max(1)
        ));
    }
    let t1 = Instant::now();
    progress.start("HOC descriptors", 0);
    // The frames are canonicalised in place by the descriptor; `pre` keeps no second copy.
    let mut features = std::mem::take(&mut pre.features);
    let desc = compute(&pre, &mut features, &o.hoc, o.seed);
    progress.finish();
    report.seconds.descriptors = t1.elapsed().as_secs_f64();

    // The crease points of the resampled surface (dimensionless curvature above the feature
    // threshold), hashed once for the instance stage's surface comparisons: flat wall matches
    // anything, the creases carry the shape.
    let crease =
        o.preprocess.kappa_threshold / (o.preprocess.curvature_radius * pre.epsilon).max(f64::MIN_POSITIVE);
    let crease_pts: Vec<motif_core::Point3> =
        (0..pre.points.len()).filter(|&i| pre.kappa[i] > crease).map(|i| pre.points[i]).collect();
    let surface = SpatialHash::new(&crease_pts, o.instances.surface_tolerance * pre.epsilon);
    let mut active: Vec<bool> = vec![true; features.len()];
    let mut classes: Vec<Class> = Vec::new();
    for round in 0..o.mdl_rounds.max(1) {
        let ids: Vec<usize> = (0..features.len()).filter(|&f| active[f]).collect();
        if ids.len() < o.min_features.max(8) {
            break;
        }
        progress.start(
            &format!("MDL round {}: dictionary, EM, instances", round + 1),
            3 + o.em.iterations as u64,
        );
        let (found, mut rr) = run_round(&pre, &surface, &features, &desc, &ids, o, round, progress);
        progress.finish();
        report.seconds.dictionary += rr.seconds[0];
        report.seconds.em += rr.seconds[1];
        report.seconds.instances += rr.seconds[2];
        // The largest class and the classes split from its cluster: the MDL stopping rule is
        // applied to the cluster (a split refines one description; its saving is the sum of its
        // classes'), and within it classes that save nothing are dropped.
        let saving = mdl_saving;
        let total: f64 = found.iter().map(|c| saving(c).max(0.0)).sum();
        let kept: Vec<Class> = if total < o.mdl_min_saving * features.len() as f64 {
            if !found.is_empty() {
                rr.rejected_saving = Some(total);
            }
            Vec::new()
        } else {
            found.into_iter().filter(|c| saving(c) > 0.0).collect()
        };
        if kept.is_empty() {
            report.rounds.push(rr);
            break;
        }
        let main = &kept[0];
        rr.kept_instances = kept.iter().map(|c| c.instances.len()).sum();
        rr.kept_words = main.words.len();
        rr.kept_features_per_instance =
            kept.iter().flat_map(|c| c.instances.iter().map(|i| i.features.len())).sum::<usize>() as f64
                / rr.kept_instances.max(1) as f64;
        rr.kept_classes = kept.len();
        report.rounds.push(rr);
        for class in kept {
            // Remove the features the kept class covers (5.4).
            for &f in &ids {
                if (0..class.instances.len()).any(|k| class.contains(k, features[f].position)) {
                    active[f] = false;
                }
            }
            for inst in &class.instances {
                for &f in &inst.features {
                    active[f] = false;
                }
            }
            classes.push(class);
        }
    }

    if o.instances.merge == crate::class_merge::ClassMerge::Surface {
        let t = Instant::now();
        let (merged, joins) = crate::class_merge::merge_classes(classes, &surface, pre.epsilon, &o.instances);
        classes = merged;
        report.class_merges = joins;
        report.seconds.instances += t.elapsed().as_secs_f64();
    }
    if o.extent.regroup == Regroup::Extent {
        let t = Instant::now();
        let (regrouped, r) = regroup(classes, &pre, &features, &o.instances, &o.extent);
        classes = regrouped;
        report.extent = r;
        report.seconds.instances += t.elapsed().as_secs_f64();
    }

    let t5 = Instant::now();
    progress.start("labels, boxes and transforms", 0);
    // One kd-tree over the input serves the point labels and the transform refinement.
    let tree = if classes.is_empty() { None } else { Some(KdTree::new(&cloud.positions)?) };
    let (mut result, labels) = to_result(cloud, tree.as_ref(), scene, &classes)?;
    if let Some(tree) = &tree {
        report.refine = refine_transforms(&mut result, cloud, tree, &o.refine);
    }
    progress.finish();
    report.seconds.output = t5.elapsed().as_secs_f64();
    report.instances_per_class = classes.iter().map(|c| c.instances.len()).collect();
    report.seconds.total = t0.elapsed().as_secs_f64();
    Ok(Detection { result, labels, classes, features, report, samples: None })
}

/// One MDL round over the active features `ids`: returns the classes of the cluster that saves
/// most, largest first (in global feature indices), and the round's
/// report.
fn run_round(
    pre: &Preprocessed,
    surface: &SpatialHash,
    features: &[Feature],
    desc: &crate::hoc::Descriptors,
    ids: &[usize],
    o: &DetectOptions,
    round: usize,
    progress: &dyn Progress,
) -> (Vec<Class>, RoundReport) {
    let eps = pre.epsilon;
    let mut rr = RoundReport { features: ids.len(), ..Default::default() };
    // Work on the sub-problem of active features; map back at the end.
    let sub_features: Vec<Feature> = ids.iter().map(|&f| features[f]).collect();
    let mut sub_desc = crate::hoc::Descriptors { data: Vec::with_capacity(ids.len() * 2 * crate::hoc::DIM) };
    for &f in ids {
        sub_desc.data.extend_from_slice(desc.row(f, 0));
        sub_desc.data.extend_from_slice(desc.row(f, 1));
    }
    let t = Instant::now();
    let dict = build(&sub_features, &sub_desc, eps, &o.dictionary, o.seed.wrapping_add(round as u64));
    rr.k = dict.k;
    rr.words = dict.words.len();
    rr.descriptor_unit = dict.matcher.unit;
    rr.seconds[0] = t.elapsed().as_secs_f64();
    progress.inc(1);
    let mut words = dict.words;
    rr.word_sizes = size_stats(&words);
    let t = Instant::now();
    if o.method == Method::EmSc {
        rr.em = run_em(&mut words, &sub_features, &sub_desc, &dict.matcher, eps, &o.em, |_| progress.inc(1));
    }
    rr.word_sizes_after_em = size_stats(&words);
    let matches = match_all(&words, &sub_features, eps, &o.em);
    rr.seconds[1] = t.elapsed().as_secs_f64();
    progress.inc(1);
    let t = Instant::now();
    let (mut classes, cr) = detect_instances(
        &words,
        &matches,
        &sub_features,
        eps,
        o.em.match_radius,
        o.em.min_support,
        Some(surface),
        &o.instances,
    );
    rr.clustering = cr;
    rr.seconds[2] = t.elapsed().as_secs_f64();
    progress.inc(1);
    // "The largest class" of 5.4, read as MDL does: the cluster whose classes save the most.
    let mut totals: Vec<(usize, f64)> = Vec::new();
    for c in &classes {
        match totals.iter_mut().find(|t| t.0 == c.cluster) {
            Some(t) => t.1 += mdl_saving(c).max(0.0),
            None => totals.push((c.cluster, mdl_saving(c).max(0.0))),
        }
    }
    let Some(&(cluster, _)) = totals.iter().max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0))) else {
        return (Vec::new(), rr);
    };
    classes.retain(|c| c.cluster == cluster);
    for c in &mut classes {
        for inst in &mut c.instances {
            inst.centre = ids[inst.centre];
            for f in &mut inst.features {
                *f = ids[*f];
            }
        }
    }
    (classes, rr)
}

/// The MDL saving of describing a class's instances as copies of one template (see
/// [`DetectOptions::mdl_min_saving`]).
fn mdl_saving(class: &Class) -> f64 {
    let n = class.instances.len() as f64;
    let fbar = class.instances.iter().map(|i| i.features.len()).sum::<usize>() as f64 / n.max(1.0);
    (n - 1.0) * fbar - fbar - n
}

fn size_stats(words: &[crate::dictionary::Word]) -> (usize, usize) {
    let mut s: Vec<usize> = words.iter().map(|w| w.members.len()).collect();
    s.sort_unstable();
    (s.get(s.len() / 2).copied().unwrap_or(0), s.last().copied().unwrap_or(0))
}

/// The shared-schema result and per-point labels: an input point belongs to the first instance
/// (in class order) whose oriented box contains it. `tree` is over `cloud`'s positions (`None`
/// when there are no classes).
fn to_result(
    cloud: &PointCloud,
    tree: Option<&KdTree>,
    scene: &str,
    classes: &[Class],
) -> Result<(DetectionResult, Vec<Option<(u32, u32)>>)> {
    let mut labels: Vec<Option<(u32, u32)>> = vec![None; cloud.len()];
    let mut out = Vec::new();
    for (ci, c) in classes.iter().enumerate() {
        let first = c.instances.first().map(|i| motif_core::procedural::rigid_inverse(&i.frame));
        let mut instances = Vec::new();
        for (k, inst) in c.instances.iter().enumerate() {
            let centre = inst.aabb.center();
            let r = inst.aabb.diagonal() / 2.0;
            let mut pts: Vec<u32> = tree
                .map(|t| t.within_unsorted(centre, r))
                .unwrap_or_default()
                .into_iter()
                .filter(|nb| c.contains(k, cloud.positions[nb.index]))
                .map(|nb| nb.index as u32)
                .collect();
            pts.sort_unstable();
            for &p in &pts {
                if labels[p as usize].is_none() {
                    labels[p as usize] = Some((ci as u32, k as u32));
                }
            }
            let transform = first.map(|inv| motif_core::geometry::mat4_mul(&inst.frame, &inv));
            instances.push(DetectedInstance {
                bbox_min: inst.aabb.min,
                bbox_max: inst.aabb.max,
                transform,
                points: Some(pts),
            });
        }
        out.push(DetectedClass { name: Some(format!("class_{ci}")), instances });
    }
    if cloud.positions.len() > u32::MAX as usize {
        return Err(DetectError::InvalidInput("more than 2³² points".into()));
    }
    Ok((DetectionResult { scene: scene.to_string(), classes: out }, labels))
}
