//! The supervised rigid-ICP baseline of thesis 5.5.3 ("RigidICP"): "for each class in the ground
//! truth, we perform a sliding window detection using the template from user annotation".
//!
//! For every ground-truth class, the points of its first instance are the template. The template
//! is slid over the scene: a window puts the template's centroid on a seed (the mean of the scene
//! points in each cell of a grid whose step is [`RigidIcpOptions::step`] × the template's
//! diagonal), turned about the up axis (y) when the class needs it. From every window a small
//! subset of the template is aligned by rigid ICP ([`motif_core::icp`], point-to-plane when the
//! scene has normals); windows that converge to the same place are merged, and the best are
//! refined with the whole template and scored in both directions: the fraction of template points
//! within an inlier distance of the scene, and the fraction of scene points in the moved template
//! box within the inlier distance of the moved template. Placements scoring at least
//! [`RigidIcpOptions::min_score`] go through non-maximum suppression; each survivor is an
//! instance whose box is the template's box moved by the ICP transform (the axis-aligned box of
//! its moved corners).
//!
//! The thesis gives no parameters for this baseline; the defaults below are chosen so that it
//! finds the instances of a rigid, noise-free, fully sampled scene (`scene-facade --difficulty
//! easy`) and are documented with the reason for each. Like the thesis's, the baseline has no
//! notion of non-rigid variation, so it degrades on scenes with variation and occlusion: that is
//! the point of the comparison.

use std::collections::HashMap;
use std::time::Instant;

use motif_core::Point3;
use motif_core::geometry::{Aabb, Mat4, dist, mat4_from_rt, mat4_mul, rotation_about_axis, transform_point};
use motif_core::icp::{IcpMetric, IcpMotion, IcpOptions, icp_with_tree};
use motif_core::procedural::rigid_inverse;
use motif_core::spatial::KdTree;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::detection::{DetectedClass, DetectedInstance, DetectionResult};
use crate::error::{DetectError, Result};

const IDENTITY3: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// When templates are also tried turned about the up axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RotationSearch {
    /// For the classes whose annotated instances are turned about the up axis relative to the
    /// template (some ground-truth transform has a rotation of more than 1°): the annotation
    /// tells the supervised baseline which classes are free-standing. The default.
    Auto,
    /// Never: translations only (plus what ICP itself turns).
    Never,
    /// For every class.
    Always,
}

/// Whether the classes compete for places.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClassCompetition {
    /// Every class keeps its detections (each class is a separate sliding-window search, as the
    /// thesis describes it).
    Independent,
    /// A detection is dropped when the box of a better-scoring detection of another class
    /// overlaps it by more than [`RigidIcpOptions::nms_overlap`]: each place goes to the template
    /// that explains it best. The default: without it a window template also "finds" the
    /// windows of a similar style, halving the precision.
    BestScore,
}

/// Options of [`rigid_icp`]. The thesis (5.5.3) gives none; each default says why it was chosen.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RigidIcpOptions {
    /// Window grid step, as a fraction of the template's bounding-box diagonal. Default 0.2: a
    /// true placement is then at most about 0.1 diagonals (a quarter of a window's width) from a
    /// window in the plane of a facade, inside the basin from which untrimmed point-to-plane ICP
    /// converges on the generated windows.
    pub step: f64,
    /// Which classes are also searched over rotations about the up axis. Default
    /// [`RotationSearch::Auto`].
    pub rotations: RotationSearch,
    /// Number of yaw angles tried when rotating (evenly spaced over 360°). Default 12 (30°
    /// apart): ICP corrects the remaining ≤ 15°.
    pub rotation_steps: usize,
    /// Template points used by ICP and the score (a seeded random subset of the annotated
    /// instance). Default 400: enough to score a match to 0.25%, few enough for hundreds of ICP
    /// runs per class.
    pub template_points: usize,
    /// A seed is tried only when the number of scene points within half the template box's
    /// diagonal of it is within this factor (either way) of the number around the template's
    /// own centroid. Default 2: occlusion and density changes stay well inside it, open ground
    /// and blank wall mostly outside.
    pub density_ratio: f64,
    /// Window budget per class: when seeds × yaws exceed it, the grid step grows until they do
    /// not. Default 12,000 (a facade class needs 3,000 to 6,000 windows at the default step; a
    /// small free-standing class rotated 12 ways in a street needs ten times that, which at about
    /// a millisecond per window on two cores is too slow for a baseline).
    pub max_windows: usize,
    /// Template points of the coarse ICP stage that starts from every window. Default 64.
    pub window_points: usize,
    /// ICP iterations of the coarse stage. Default 12.
    pub coarse_iterations: usize,
    /// Minimum window score for a window to be refined: the two-way score of
    /// [`Self::min_score`] after the coarse stage, at twice the inlier distance, with the coarse
    /// points and every 8th scene point. Default 0.5.
    pub window_score: f64,
    /// At most this many local maxima of the window score are refined by ICP, per class.
    /// Default 200 (about fifteen times the instances of the largest generated class).
    pub max_refined: usize,
    /// ICP iterations of each of the two refinement stages. Default 20 (point-to-plane converges in under 10 from a coarse result).
    pub iterations: usize,
    /// Trimmed-ICP fraction of the last refinement stage: the closest fraction of
    /// correspondences drives each update. Default 0.8, tolerating 20% of the template being
    /// unmatched (occlusion, variation).
    pub trim_fraction: f64,
    /// Inlier distance, as a fraction of the template's diagonal. Default 0.01 (2.4 cm for a
    /// facade's `window_a`): below the 4–8 cm depth of frames, shutters and sills, so a template
    /// slid along the wall loses their points; larger values let a window template "match" a
    /// plain wall.
    pub inlier_distance: f64,
    /// Lower bound of the inlier distance in scene sample spacings (median nearest-neighbour
    /// distance): at low densities a perfectly placed template point may be this far from the
    /// nearest sample. Default 1.5.
    pub spacing_factor: f64,
    /// Lower bound of the inlier distance in multiples of the scene's estimated noise σ (the
    /// median RMS distance of 16-neighbourhoods to their fitted planes): noisy points of a
    /// perfectly placed template lie about σ from the nearest sample. Default 2.
    pub noise_factor: f64,
    /// Minimum score of a detection: the smaller of the fraction of template points within the
    /// inlier distance of the scene and the fraction of scene points in the moved template box
    /// within the inlier distance of the moved template (both directions, so neither a template
    /// lying on a plain wall nor a box full of unrelated clutter scores well). Default 0.5: on
    /// `scene-facade` the template's own instance scores 0.8 to 0.95 when noise-free, rigid copies
    /// elsewhere as much, and instances seen from another angle (occlusion) or varied by 7-15%
    /// drop to 0.5-0.7, so 0.5 keeps most of them; 0.6 and 0.7 give the same F on the easy scene
    /// and lower F on the medium and hard ones.
    pub min_score: f64,
    /// Non-maximum suppression: a candidate is dropped when its box overlaps a better one of the
    /// same class by more than this fraction of the smaller box's volume. Default 0.25.
    pub nms_overlap: f64,
    /// Whether classes compete for places. Default [`ClassCompetition::BestScore`].
    pub competition: ClassCompetition,
    /// Seed of the template subsets.
    pub seed: u64,
}

impl Default for RigidIcpOptions {
    fn default() -> Self {
        RigidIcpOptions {
            step: 0.2,
            rotations: RotationSearch::Auto,
            rotation_steps: 12,
            template_points: 400,
            density_ratio: 2.0,
            max_windows: 12_000,
            window_points: 64,
            coarse_iterations: 12,
            window_score: 0.5,
            max_refined: 200,
            iterations: 20,
            trim_fraction: 0.8,
            inlier_distance: 0.01,
            spacing_factor: 1.5,
            noise_factor: 2.0,
            min_score: 0.5,
            nms_overlap: 0.25,
            competition: ClassCompetition::BestScore,
            seed: 0,
        }
    }
}

impl RigidIcpOptions {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<()> {
        let bad = |name: &'static str, message: String| Err(DetectError::InvalidOption { name, message });
        let unit = |v: f64| v.is_finite() && v > 0.0 && v <= 1.0;
        if !(self.step.is_finite() && self.step >= 0.02 && self.step <= 2.0) {
            return bad("step", format!("{} is outside 0.02 to 2 template diagonals", self.step));
        }
        if !(1..=360).contains(&self.rotation_steps) {
            return bad("rotation_steps", format!("{}: use 1 to 360", self.rotation_steps));
        }
        if !(8..=100_000).contains(&self.template_points) || !(8..=100_000).contains(&self.window_points) {
            return bad(
                "template_points",
                format!("{} / {} window points: use 8 to 100000", self.template_points, self.window_points),
            );
        }
        if self.iterations == 0
            || self.coarse_iterations == 0
            || self.max_refined == 0
            || self.max_windows == 0
        {
            return bad("iterations", "need at least one ICP iteration and one refined window".into());
        }
        for (name, v) in [
            ("trim_fraction", self.trim_fraction),
            ("min_score", self.min_score),
            ("window_score", self.window_score),
            ("nms_overlap", self.nms_overlap),
        ] {
            if !unit(v) {
                return bad(name, format!("{v} is outside (0, 1]"));
            }
        }
        if !(self.inlier_distance.is_finite() && self.inlier_distance > 0.0 && self.inlier_distance < 1.0) {
            return bad(
                "inlier_distance",
                format!("{} is outside (0, 1) template diagonals", self.inlier_distance),
            );
        }
        if !(self.density_ratio.is_finite() && self.density_ratio >= 1.0) {
            return bad("density_ratio", format!("{} must be at least 1", self.density_ratio));
        }
        for (name, v) in [("spacing_factor", self.spacing_factor), ("noise_factor", self.noise_factor)] {
            if !(v.is_finite() && (0.0..=100.0).contains(&v)) {
                return bad(name, format!("{v} is outside 0 to 100"));
            }
        }
        Ok(())
    }
}

/// What happened for one class.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigidIcpClassReport {
    /// The class name (or `class_k`).
    pub name: String,
    /// Template points available in the annotated first instance (before subsampling).
    pub template_points: usize,
    /// The template's bounding-box diagonal, metres (scene units).
    pub template_diagonal: f64,
    /// The inlier distance used, scene units.
    pub inlier_distance: f64,
    /// Seeds (grid cells with scene points).
    pub seeds: usize,
    /// Seeds whose neighbourhood density passed [`RigidIcpOptions::density_ratio`].
    pub plausible_seeds: usize,
    /// The grid step used, scene units ([`RigidIcpOptions::step`] × the template's diagonal,
    /// enlarged when the window budget [`RigidIcpOptions::max_windows`] demanded it).
    pub step: f64,
    /// Windows (seed × yaw placements) scoring at least `window_score`.
    pub windows: usize,
    /// Yaw angles tried per seed.
    pub orientations: usize,
    /// Local maxima of the window score refined by ICP.
    pub refined: usize,
    /// Candidates scoring at least `min_score`.
    pub accepted: usize,
    /// Detections after non-maximum suppression (within the class, then between classes).
    pub detections: usize,
    /// Wall-clock time of the seeds and the coarse stage over every window, seconds.
    pub window_seconds: f64,
    /// Wall-clock time of the refinement and scoring, seconds.
    pub refine_seconds: f64,
    /// Wall-clock time, seconds.
    pub seconds: f64,
    /// Why the class was skipped, when it was (too few template points).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skipped: Option<String>,
}

/// What [`rigid_icp`] did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigidIcpReport {
    /// The options used.
    pub options: RigidIcpOptions,
    /// Scene points.
    pub scene_points: usize,
    /// Median nearest-neighbour distance of the scene (of a subsample), scene units.
    pub scene_spacing: f64,
    /// Estimated scanner noise σ of the scene, scene units (see [`RigidIcpOptions::noise_factor`]).
    pub scene_noise: f64,
    /// One entry per ground-truth class, in order.
    pub classes: Vec<RigidIcpClassReport>,
    /// Total wall-clock time, seconds.
    pub seconds: f64,
}

/// A refined placement.
#[derive(Debug, Clone)]
struct Candidate {
    transform: Mat4,
    score: f64,
    /// Order of creation, for deterministic tie-breaking.
    index: usize,
}

/// Median nearest-neighbour distance over up to 4,000 evenly strided points.
fn scene_spacing(points: &[Point3], tree: &KdTree) -> f64 {
    let stride = (points.len() / 4000).max(1);
    let mut d: Vec<f64> = points
        .par_iter()
        .step_by(stride)
        .filter_map(|p| tree.knn(*p, 2).get(1).map(|n| n.distance))
        .collect();
    d.sort_by(f64::total_cmp);
    d.get(d.len() / 2).copied().unwrap_or(0.0)
}

/// Median over up to 2,000 evenly strided points of the RMS distance of their 16 nearest
/// neighbours to the neighbours' least-squares plane: the scanner noise σ on the (mostly planar)
/// surfaces of a scan, plus a little curvature.
fn scene_noise(points: &[Point3], tree: &KdTree) -> f64 {
    let stride = (points.len() / 2000).max(1);
    let mut s: Vec<f64> = points
        .par_iter()
        .step_by(stride)
        .filter_map(|p| {
            let nb = tree.knn(*p, 16);
            if nb.len() < 4 {
                return None;
            }
            let n = nb.len() as f64;
            let mut c = [0.0; 3];
            for q in &nb {
                let x = points[q.index];
                c = [c[0] + x[0] / n, c[1] + x[1] / n, c[2] + x[2] / n];
            }
            let mut cov = nalgebra::Matrix3::<f64>::zeros();
            for q in &nb {
                let d = nalgebra::Vector3::from(motif_core::geometry::sub(points[q.index], c));
                cov += d * d.transpose() / n;
            }
            let e = nalgebra::SymmetricEigen::new(cov).eigenvalues;
            Some(e.iter().fold(f64::INFINITY, |a, &b| a.min(b)).max(0.0).sqrt())
        })
        .collect();
    s.sort_by(f64::total_cmp);
    s.get(s.len() / 2).copied().unwrap_or(0.0)
}

/// Seeds: the mean of the scene points in each occupied grid cell of side `cell` holding at
/// least 3 points (cells of lone outliers are skipped), in a deterministic order.
fn seeds(points: &[Point3], cell: f64) -> Vec<Point3> {
    let mut cells: HashMap<[i64; 3], ([f64; 3], usize)> = HashMap::new();
    for p in points {
        let key = [(p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64, (p[2] / cell).floor() as i64];
        let e = cells.entry(key).or_insert(([0.0; 3], 0));
        for k in 0..3 {
            e.0[k] += p[k];
        }
        e.1 += 1;
    }
    let mut v: Vec<([i64; 3], Point3)> = cells
        .into_iter()
        .filter(|(_, (_, n))| *n >= 3)
        .map(|(k, (s, n))| (k, [s[0] / n as f64, s[1] / n as f64, s[2] / n as f64]))
        .collect();
    v.sort_by_key(|(k, _)| *k);
    v.into_iter().map(|(_, p)| p).collect()
}

/// Fraction of `template` points within `radius` of the scene after `transform` (how much of the
/// template the scene explains).
fn forward_score(template: &[Point3], transform: &Mat4, tree: &KdTree, radius: f64) -> f64 {
    let hits =
        template.iter().filter(|p| tree.nearest(transform_point(transform, **p)).distance <= radius).count();
    hits as f64 / template.len().max(1) as f64
}

/// The class template for the backward score: a kd-tree of all annotated points of the first
/// instance, and its box.
struct Template {
    tree: KdTree,
    bbox: Aabb,
}

/// Fraction of the scene points inside the template's box moved by `transform` that lie within
/// `radius` of the moved template (how much of the scene in the window the template explains);
/// 0 when the box holds no scene point.
/// Only every `stride`-th scene point of the ball around the box is looked at (1: all).
fn backward_score(
    t: &Template,
    transform: &Mat4,
    scene: &[Point3],
    tree: &KdTree,
    radius: f64,
    stride: usize,
) -> f64 {
    let inv = rigid_inverse(transform);
    let centre = transform_point(transform, t.bbox.center());
    let (mut inside, mut hits) = (0usize, 0usize);
    for n in tree.within_unsorted(centre, 0.5 * t.bbox.diagonal()).into_iter().step_by(stride.max(1)) {
        let q = transform_point(&inv, scene[n.index]);
        if t.bbox.contains(q) {
            inside += 1;
            if t.tree.nearest(q).distance <= radius {
                hits += 1;
            }
        }
    }
    if inside == 0 { 0.0 } else { hits as f64 / inside as f64 }
}

/// The axis-aligned box of a box's corners moved by `m`.
fn moved_box(min: &Point3, max: &Point3, m: &Mat4) -> Aabb {
    Aabb { min: *min, max: *max }.mapped(|c| transform_point(m, c))
}

/// Yaw (rotation about y) of a transform's rotation part, radians.
fn yaw_of(m: &Mat4) -> f64 {
    m[0][2].atan2(m[0][0])
}

/// Non-maximum suppression: best first, a candidate survives when its box overlaps no survivor by
/// more than `overlap` of the smaller volume.
fn suppress(mut cands: Vec<(Candidate, Aabb)>, overlap: f64) -> Vec<(Candidate, Aabb)> {
    cands.sort_by(|a, b| b.0.score.total_cmp(&a.0.score).then(a.0.index.cmp(&b.0.index)));
    let mut kept: Vec<(Candidate, Aabb)> = Vec::new();
    for (c, b) in cands {
        let clash = kept.iter().any(|(_, k)| {
            k.intersection(&b).is_some_and(|i| i.volume() > overlap * k.volume().min(b.volume()).max(1e-300))
        });
        if !clash {
            kept.push((c, b));
        }
    }
    kept
}

/// Runs the rigid-ICP baseline on a scene (`positions`, optional unit `normals`: point-to-plane
/// ICP when given, point-to-point otherwise) with the classes and first-instance templates of
/// `ground_truth`. Returns one detected class per ground-truth class that has a usable template
/// (at least 10 points), named like it, and a report.
pub fn rigid_icp(
    positions: &[Point3],
    normals: Option<&[Point3]>,
    ground_truth: &DetectionResult,
    options: &RigidIcpOptions,
) -> Result<(DetectionResult, RigidIcpReport)> {
    let start = Instant::now();
    options.validate()?;
    ground_truth.validate(&format!("ground truth of scene `{}`", ground_truth.scene))?;
    if positions.is_empty() {
        return Err(DetectError::InvalidInput("the scene has no points".into()));
    }
    if let Some(n) = normals {
        if n.len() != positions.len() {
            return Err(DetectError::InvalidInput(format!(
                "{} normals for {} points",
                n.len(),
                positions.len()
            )));
        }
    }
    let tree = KdTree::new(positions)?;
    let spacing = scene_spacing(positions, &tree);
    let noise = scene_noise(positions, &tree);
    let metric = if normals.is_some() { IcpMetric::PointToPlane } else { IcpMetric::PointToPoint };

    let mut found: Vec<(String, usize, Vec<(Candidate, Aabb)>)> = Vec::new();
    let mut reports = Vec::new();
    for (c, gt_class) in ground_truth.classes.iter().enumerate() {
        let t0 = Instant::now();
        let name = gt_class.name.clone().unwrap_or_else(|| format!("class_{c}"));
        let first = &gt_class.instances[0];
        // The template: the annotated points of the first instance, else the scene points in
        // its box.
        let mut ids: Vec<usize> = match &first.points {
            Some(p) if !p.is_empty() => {
                if let Some(&bad) = p.iter().find(|&&i| i as usize >= positions.len()) {
                    return Err(DetectError::InvalidInput(format!(
                        "ground-truth class `{name}` instance 0 lists point {bad}, but the scene has {} points: \
                         is this the ground truth of this scene?",
                        positions.len()
                    )));
                }
                p.iter().map(|&i| i as usize).collect()
            }
            _ => {
                let b = Aabb { min: first.bbox_min, max: first.bbox_max };
                (0..positions.len()).filter(|&i| b.contains(positions[i])).collect()
            }
        };
        let mut report = RigidIcpClassReport {
            name: name.clone(),
            template_points: ids.len(),
            template_diagonal: 0.0,
            inlier_distance: 0.0,
            seeds: 0,
            plausible_seeds: 0,
            step: 0.0,
            windows: 0,
            orientations: 0,
            refined: 0,
            accepted: 0,
            detections: 0,
            window_seconds: 0.0,
            refine_seconds: 0.0,
            seconds: 0.0,
            skipped: None,
        };
        if ids.len() < 10 {
            report.skipped = Some(format!("the template has {} points; at least 10 are needed", ids.len()));
            reports.push(report);
            continue;
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(options.seed.wrapping_add(c as u64));
        ids.shuffle(&mut rng);
        let template: Vec<Point3> = ids.iter().take(options.template_points).map(|&i| positions[i]).collect();
        let coarse: Vec<Point3> = template.iter().take(options.window_points).copied().collect();
        let all_points: Vec<Point3> = ids.iter().map(|&i| positions[i]).collect();
        let diag = Aabb::from_points(&template).map_or(0.0, |b| b.diagonal());
        if diag.is_nan() || diag <= 0.0 {
            report.skipped = Some("the template's points all coincide".into());
            reports.push(report);
            continue;
        }
        let centroid = {
            let s = template.iter().fold([0.0; 3], |a, p| [a[0] + p[0], a[1] + p[1], a[2] + p[2]]);
            let n = template.len() as f64;
            [s[0] / n, s[1] / n, s[2] / n]
        };
        let radius = (options.inlier_distance * diag)
            .max(options.spacing_factor * spacing)
            .max(options.noise_factor * noise);
        let rotate = match options.rotations {
            RotationSearch::Never => false,
            RotationSearch::Always => true,
            RotationSearch::Auto => gt_class
                .instances
                .iter()
                .filter_map(|i| i.transform.as_ref())
                .any(|t| yaw_of(t).abs() > 1f64.to_radians() || (t[1][1] - 1.0).abs() > 1e-3),
        };
        let yaws: Vec<f64> = if rotate {
            (0..options.rotation_steps)
                .map(|k| std::f64::consts::TAU * k as f64 / options.rotation_steps as f64)
                .collect()
        } else {
            vec![0.0]
        };
        report.template_diagonal = diag;
        report.inlier_distance = radius;
        report.orientations = yaws.len();
        // Seeds whose neighbourhood holds far more or far fewer points than the template's own
        // (open ground where a lamp post should be, the middle of a wall) cannot hold an
        // instance; the count in a ball does not depend on the yaw, so it is tested once per
        // seed.
        let ball = 0.5 * Aabb { min: first.bbox_min, max: first.bbox_max }.diagonal();
        let reference = tree.within_unsorted(centroid, ball).len().max(1) as f64;
        // The window budget: a coarser grid when seeds × yaws would exceed `max_windows` (seeds
        // on surfaces scale with the inverse square of the step).
        let mut step = options.step * diag;
        let mut plausible: Vec<Point3>;
        loop {
            let seed_points = seeds(positions, step);
            report.seeds = seed_points.len();
            plausible = seed_points
                .par_iter()
                .filter(|s| {
                    let r = tree.within_unsorted(**s, ball).len() as f64 / reference;
                    r * options.density_ratio >= 1.0 && r <= options.density_ratio
                })
                .copied()
                .collect();
            let windows = plausible.len() * yaws.len();
            if windows <= options.max_windows {
                break;
            }
            step *= (1.05 * windows as f64 / options.max_windows as f64).sqrt();
        }
        report.step = step;
        report.plausible_seeds = plausible.len();
        let starts: Vec<(Point3, f64)> =
            plausible.iter().flat_map(|s| yaws.iter().map(move |y| (*s, *y))).collect();
        // Coarse stage: from every window (the template's centroid on a seed, turned by a yaw),
        // untrimmed point-to-plane ICP of a small subset. Untrimmed, because the correspondences
        // that pull a template along a wall are the far ones that trimming drops; point-to-plane
        // with all of them converges from a quarter of a window's size (point-to-point from less,
        // trimmed ICP of either kind from less than a frame's width).
        let coarse_options = IcpOptions {
            metric,
            motion: IcpMotion::Rigid,
            max_iterations: options.coarse_iterations,
            tolerance: 1e-4,
            trim_fraction: 1.0,
            max_correspondence_distance: Some(step.max(4.0 * radius)),
        };
        let full = Template {
            tree: KdTree::new(&all_points)?,
            bbox: Aabb { min: first.bbox_min, max: first.bbox_max },
        };
        let windows: Vec<Candidate> = starts
            .par_iter()
            .enumerate()
            .filter_map(|(index, &(seed, yaw))| {
                let to_centroid = mat4_from_rt(IDENTITY3, [-centroid[0], -centroid[1], -centroid[2]]);
                let initial =
                    mat4_mul(&mat4_from_rt(rotation_about_axis([0.0, 1.0, 0.0], yaw), seed), &to_centroid);
                let c = icp_with_tree(&coarse, positions, &tree, normals, &initial, &coarse_options).ok()?;
                // A window that wandered off its seed is another seed's business.
                if dist(transform_point(&c.transform, centroid), seed) > 1.5 * step {
                    return None;
                }
                let forward = forward_score(&coarse, &c.transform, &tree, 2.0 * radius);
                if forward < options.window_score {
                    return None;
                }
                let score =
                    forward.min(backward_score(&full, &c.transform, positions, &tree, 2.0 * radius, 8));
                (score >= options.window_score).then_some(Candidate { transform: c.transform, score, index })
            })
            .collect();
        report.windows = windows.len();
        report.window_seconds = t0.elapsed().as_secs_f64();
        // Windows that converged to the same place (within a tenth of the diagonal and 45° of
        // yaw) are refined once, best first, at most `max_refined` of them.
        let mut windows = windows;
        windows.sort_by(|a, b| b.score.total_cmp(&a.score).then(a.index.cmp(&b.index)));
        let mut peaks: Vec<(Candidate, Point3)> = Vec::new();
        for c in windows {
            if peaks.len() >= options.max_refined {
                break;
            }
            let at = transform_point(&c.transform, centroid);
            let yaw = yaw_of(&c.transform);
            let same = peaks.iter().any(|(d, p)| {
                let dyaw = (yaw - yaw_of(&d.transform)).rem_euclid(std::f64::consts::TAU);
                dist(at, *p) < 0.1 * diag && dyaw.min(std::f64::consts::TAU - dyaw) < 45f64.to_radians()
            });
            if !same {
                peaks.push((c, at));
            }
        }
        report.refined = peaks.len();
        // Refinement: the whole template, untrimmed first (as above), then trimmed with
        // correspondences limited to twice the inlier distance, which snaps onto the surfaces.
        let wide = IcpOptions { max_iterations: options.iterations, ..coarse_options.clone() };
        let tight = IcpOptions {
            max_iterations: options.iterations,
            trim_fraction: options.trim_fraction,
            max_correspondence_distance: Some(2.0 * radius),
            ..coarse_options.clone()
        };
        let accepted: Vec<(Candidate, Aabb)> = peaks
            .par_iter()
            .filter_map(|(c, _)| {
                let f = icp_with_tree(&template, positions, &tree, normals, &c.transform, &wide).ok()?;
                let transform = icp_with_tree(&template, positions, &tree, normals, &f.transform, &tight)
                    .map_or(f.transform, |t| t.transform);
                let forward = forward_score(&template, &transform, &tree, radius);
                if forward < options.min_score {
                    return None;
                }
                let score = forward.min(backward_score(&full, &transform, positions, &tree, radius, 1));
                (score >= options.min_score).then(|| {
                    let b = moved_box(&first.bbox_min, &first.bbox_max, &transform);
                    (Candidate { transform, score, index: c.index }, b)
                })
            })
            .collect();
        report.accepted = accepted.len();
        report.refine_seconds = t0.elapsed().as_secs_f64() - report.window_seconds;
        let kept = suppress(accepted, options.nms_overlap);
        report.detections = kept.len();
        report.seconds = t0.elapsed().as_secs_f64();
        reports.push(report);
        found.push((name, c, kept));
    }
    if options.competition == ClassCompetition::BestScore {
        // Each place goes to the class whose template explains it best.
        let mut all: Vec<(usize, usize, f64)> = found
            .iter()
            .enumerate()
            .flat_map(|(k, (_, _, kept))| kept.iter().enumerate().map(move |(i, (c, _))| (k, i, c.score)))
            .collect();
        all.sort_by(|a, b| b.2.total_cmp(&a.2).then(a.0.cmp(&b.0)).then(a.1.cmp(&b.1)));
        let mut keep: Vec<Vec<bool>> = found.iter().map(|f| vec![false; f.2.len()]).collect();
        let mut taken: Vec<(usize, Aabb)> = Vec::new();
        for (k, i, _) in all {
            let b = found[k].2[i].1;
            let clash = taken.iter().any(|(other, t)| {
                *other != k
                    && t.intersection(&b).is_some_and(|x| {
                        x.volume() > options.nms_overlap * t.volume().min(b.volume()).max(1e-300)
                    })
            });
            if !clash {
                keep[k][i] = true;
                taken.push((k, b));
            }
        }
        for (k, f) in found.iter_mut().enumerate() {
            let mut i = 0;
            f.2.retain(|_| {
                i += 1;
                keep[k][i - 1]
            });
            if let Some(r) = reports.iter_mut().find(|r| r.name == f.0) {
                r.detections = f.2.len();
            }
        }
    }
    let classes: Vec<DetectedClass> = found
        .into_iter()
        .filter(|f| !f.2.is_empty())
        .map(|(name, _, kept)| DetectedClass {
            name: Some(name),
            instances: kept
                .into_iter()
                .map(|(c, b)| DetectedInstance {
                    bbox_min: b.min,
                    bbox_max: b.max,
                    transform: Some(c.transform),
                    points: None,
                })
                .collect(),
        })
        .collect();
    let detection = DetectionResult { scene: ground_truth.scene.clone(), classes };
    let report = RigidIcpReport {
        options: options.clone(),
        scene_points: positions.len(),
        scene_spacing: spacing,
        scene_noise: noise,
        classes: reports,
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok((detection, report))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suppression_keeps_the_best_of_overlapping_boxes() {
        let c = |score, index| Candidate { transform: motif_core::geometry::IDENTITY4, score, index };
        let b = |x: f64| Aabb { min: [x, 0.0, 0.0], max: [x + 1.0, 1.0, 1.0] };
        let kept = suppress(vec![(c(0.7, 0), b(0.0)), (c(0.9, 1), b(0.3)), (c(0.8, 2), b(2.0))], 0.25);
        let idx: Vec<usize> = kept.iter().map(|(c, _)| c.index).collect();
        assert_eq!(idx, vec![1, 2]);
    }

    #[test]
    fn moved_box_of_a_quarter_turn() {
        let m =
            mat4_from_rt(rotation_about_axis([0.0, 1.0, 0.0], std::f64::consts::FRAC_PI_2), [10.0, 0.0, 0.0]);
        let b = moved_box(&[0.0, 0.0, 0.0], &[2.0, 1.0, 1.0], &m);
        assert!((b.extent()[0] - 1.0).abs() < 1e-12 && (b.extent()[2] - 2.0).abs() < 1e-12);
        assert!((yaw_of(&m) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }
}
