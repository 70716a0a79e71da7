//! Instance detection by spectral clustering of co-occurrence (thesis 5.3.3): the co-occurrence
//! matrix of eq. 5.3, classical MDS to 5 dimensions, mean-shift (bandwidth 0.5), the median word of
//! each cluster as the instances' centres, the star model linking each centre to its co-occurring
//! features, instance boxes averaged per class, and the transforms between instances.
//!
//! Choices where the thesis is silent:
//! - eq. 5.3 is not symmetric (Ψ(i, j) counts sources in Dⁱ); Motif averages mᵢⱼ and mⱼᵢ, and
//!   uses dᵢⱼ = 1 − mᵢⱼ as the distance that classical MDS embeds. Words that co-occur with no
//!   other word take no part.
//! - Mean-shift uses the flat kernel (radius = bandwidth), so words that do not co-occur (distance
//!   ≈ 1) never pull on each other; modes closer than half the bandwidth merge. As a guard against
//!   MDS squeezing unrelated groups together in 5 dimensions, each cluster is split into the
//!   connected components of its co-occurrence graph.
//! - An instance is kept when it links at least `min_links` of its class's other words and at
//!   least `min_instance_features` features in all. Its box ([`InstanceBoxes`]) is by default
//!   the union of the class's constellation: every instance's linked features carried onto the
//!   best-linked instance by the least-squares rigid motion between the features their stars
//!   link through the same words, trimmed, padded by half a HOC cell (features sit on creases,
//!   the block's surface extends a little beyond them), and carried back; the thesis's
//!   per-class averaging of boxes, made robust to occlusion.
//! - A cluster is split into classes whose instances' surfaces differ ([`ClassSplit`]). Boxes are world-axis-aligned, as the
//!   evaluation protocol (5.5.2) and the schema are, rather than taken in the centre feature's
//!   frame: on a crease the normal bisects the two faces, and a box in that tilted frame would
//!   inflate every world box. Overlapping instances of one class (a word that fires on two
//!   symmetric corners of one window) are merged, the better-linked one kept.

use motif_core::Point3;
use motif_core::geometry::{Aabb, Mat4, mat4_from_rt};
use serde::{Deserialize, Serialize};

use rayon::prelude::*;

use crate::class_merge::ClassMerge;
use crate::cooccurrence::PairMatch;
use crate::dictionary::Word;
use crate::grid::SpatialHash;
use crate::preprocess::Feature;

/// Options of [`detect_instances`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct InstanceOptions {
    /// Dimensions of the classical-MDS embedding (thesis 5.4: 5).
    pub embedding_dims: usize,
    /// Mean-shift bandwidth in the embedding (thesis 5.4: 0.5).
    pub bandwidth: f64,
    /// Minimum fraction of the class's other words an instance must link to. Default 0.25.
    pub min_links: f64,
    /// An instance needs at least this many features in its star (the centre and its links).
    /// Not in the thesis, which discards word pairs with |Ψ(i, j)| < 5 (5.4) but states no
    /// minimum for an instance; a "building block" of one or two co-occurring features is a
    /// coincidence, not a block. Default 5, the thesis's |Ψ| threshold.
    pub min_instance_features: usize,
    /// Box padding around the linked features, in ε. Default 4 (half a HOC cell).
    pub box_margin: f64,
    /// How instance boxes are estimated. Default [`InstanceBoxes::Union`].
    pub boxes: InstanceBoxes,
    /// [`InstanceBoxes::Union`]: the pooled features' box spans the quantiles `box_trim` to
    /// `1 − box_trim` per axis, so a few wrong links do not stretch it. Default 0.05.
    pub box_trim: f64,
    /// Two instances of one class whose boxes overlap by more than this fraction of the smaller
    /// box are merged. Default 0.5.
    pub merge_overlap: f64,
    /// Classes need at least this many instances. Default 2 (a building block repeats).
    pub min_instances: usize,
    /// Whether a cluster found by the spectral clustering is split into classes whose instances'
    /// surfaces agree. Default [`ClassSplit::Surface`].
    pub split: ClassSplit,
    /// [`ClassSplit::Surface`]: two groups of a cluster become separate classes only when the
    /// average surface distance between them is at least this many times the average distance
    /// within the tighter of the two (a group that absorbed stragglers has an inflated spread).
    /// Not in the thesis. Default 2.
    pub split_ratio: f64,
    /// [`ClassSplit::Surface`]: ... and at least this average fraction of unmatched surface
    /// points, so that near-identical copies (distances ≈ 0) are never split; classes closer than
    /// this are joined after the MDL rounds ([`ClassMerge::Surface`]). Default 0.1.
    pub split_min_distance: f64,
    /// [`ClassSplit::Surface`]: a surface point is matched when the other instance has a point
    /// within this distance, in ε. Default 2.
    pub surface_tolerance: f64,
    /// Whether classes of different MDL rounds (or split from one cluster) whose instances'
    /// surfaces agree are joined after the last round ([`crate::class_merge`]). Not in the
    /// thesis. Default [`ClassMerge::Surface`].
    pub merge: ClassMerge,
}

/// How instance boxes are estimated (5.3.3: "the bounding boxes of all instances from the same
/// class are averaged").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum InstanceBoxes {
    /// Each instance's linked features' box, side lengths replaced by the class median.
    Median,
    /// The box of the union of all instances' linked features, each instance's carried onto a
    /// reference instance by the rigid motion between their star models (least squares over the
    /// features linked through the same word), carried back to every instance. Under occlusion
    /// each instance shows part of the block and the median box shrinks to the commonly seen
    /// part; the union recovers the block. The default.
    #[default]
    Union,
}

/// How the instances of one co-occurrence cluster become classes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ClassSplit {
    /// One class per cluster, as in the thesis (5.3.3).
    None,
    /// Split each cluster by average-linkage clustering of its instances under the surface
    /// distance: 1 − the larger of the two directed fractions of crease points (resampled points
    /// whose curvature passes the feature threshold) in one instance's box that find a crease
    /// point within [`InstanceOptions::surface_tolerance`] when laid onto the other instance by
    /// the rigid motion (least squares) between their star models' features. The larger
    /// direction, because occlusion hides different parts of two instances of one block; two
    /// different blocks miss in both directions. Not in the thesis: co-occurrence alone cannot
    /// tell apart two blocks that share their co-occurring corners (window styles with the same
    /// frame), and the evaluation (5.5.2) scores a merged class against one ground-truth class
    /// only.
    ///
    /// Two variants were measured and dropped (`motif bench detect --no-icp --scenes 3`, facade
    /// and street, seeds 1–3). Comparing a region larger than the box, so that the parts of a
    /// block outside a partial constellation take part, by 1.25×/1.5×/1.75× of the box: facade
    /// medium F 0.766/0.847/0.677 against 0.794, street medium 0.611/0.606/0.640 against 0.652,
    /// hard scenes 0.01–0.07 lower. A looser [`InstanceOptions::split_ratio`] (1.25 or 1.5
    /// instead of 2) raised facade medium F to 0.837 but cut facade hard F from 0.449 to
    /// 0.32–0.34: on hard scenes the classes break into fragments, and each ground-truth class
    /// counts only its best fragment.
    ///
    /// A third was prototyped (in Python) and dropped: splitting the final classes again by the
    /// rotation-aware shape coverage of [`crate::segment_classes`] (72 starts refined by ICP,
    /// points within 2ε, mean of both directions), computed on each instance's own points with
    /// this split's linkage rule. On 18 fresh check scenes (6 hard facades, 6 hard streets,
    /// 3 medium of each) no setting of the ratio (1.5–2.5) and minimum distance (0.15–0.3)
    /// gained more than 0.011 on one level without losing on another (medium facades lost up
    /// to 0.043). The similarity carries too little of the style. In the classes that mix
    /// styles, a *supervised* 3-nearest-neighbour vote on it (each instance labelled by its
    /// neighbours' true styles) is right for 66% of the instances on hard facades, 61% on hard
    /// streets and 73% on medium streets. Labelling every instance with its class's majority
    /// style is right for 67%, 60% and 71%.
    #[default]
    Surface,
}

impl Default for InstanceOptions {
    fn default() -> Self {
        InstanceOptions {
            embedding_dims: 5,
            bandwidth: 0.5,
            min_links: 0.25,
            min_instance_features: 5,
            box_margin: 4.0,
            boxes: InstanceBoxes::Union,
            box_trim: 0.05,
            merge_overlap: 0.5,
            min_instances: 2,
            split: ClassSplit::Surface,
            split_ratio: 2.0,
            split_min_distance: 0.1,
            surface_tolerance: 2.0,
            merge: ClassMerge::Surface,
        }
    }
}

/// One detected instance.
#[derive(Debug, Clone, PartialEq)]
pub struct Instance {
    /// The centre feature (a member of the class's median word; for a class of repeated
    /// segments, [`crate::segment_classes`], the segment's feature nearest its centroid).
    pub centre: usize,
    /// Its frame flip.
    pub flip: u8,
    /// Features linked by the star model, the centre included.
    pub features: Vec<usize>,
    /// The class's words (dictionary indices, ascending) this instance links to, the centre word
    /// excluded: the instance's constellation signature.
    pub links: Vec<usize>,
    /// World-space frame: local (x, y, z, 1) to world.
    pub frame: Mat4,
    /// Axis-aligned world box of the class box placed at this instance.
    pub aabb: Aabb,
    /// The block's size per world axis measured free of its turn about the class's thinnest
    /// axis, when [`crate::extent`] measured it (`None`: the box's extent stands for it).
    pub footprint: Option<Point3>,
    /// The turn of that footprint's rectangle about the thinnest axis, folded into [0, π/4]
    /// radians (0 when upright or unmeasured): how far the block is turned from the world axes.
    pub turn: f64,
}

/// One building-block class.
#[derive(Debug, Clone, PartialEq)]
pub struct Class {
    /// Indices of the words forming the class.
    pub words: Vec<usize>,
    /// The centre (median) word; `usize::MAX` for a class of repeated segments
    /// ([`crate::segment_classes`]), which has no words.
    pub centre_word: usize,
    /// The class box's size in world axes (median over instances, padded).
    pub extent: Point3,
    /// The instances.
    pub instances: Vec<Instance>,
    /// The co-occurrence cluster the class came from (classes split from one cluster share it);
    /// classes of repeated segments ([`crate::segment_classes`]) get numbers of their own after
    /// the clusters'.
    pub cluster: usize,
}

impl Class {
    /// Whether world point `p` lies inside instance `k`'s box.
    pub fn contains(&self, k: usize, p: Point3) -> bool {
        self.instances[k].aabb.contains(p)
    }
}

/// What the clustering saw, for reports.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ClusteringReport {
    /// Words with at least one strong co-occurrence.
    pub connected_words: usize,
    /// Mean-shift clusters (after the connectivity split).
    pub clusters: usize,
    /// Classes with enough instances.
    pub classes: usize,
    /// Extra classes made by splitting clusters ([`ClassSplit`]).
    pub splits: usize,
}

/// Symmetrised eq. 5.3 over `k` words, zero below the support threshold.
pub fn cooccurrence_matrix(words: &[Word], matches: &[Option<PairMatch>], min_support: usize) -> Vec<f64> {
    let k = words.len();
    let m = |i: usize, j: usize| -> f64 {
        match &matches[i * k + j] {
            Some(p) if p.support.len() >= min_support.max(1) => {
                p.support.len() as f64 / words[i].members.len().max(words[j].members.len()) as f64
            }
            _ => 0.0,
        }
    };
    let mut out = vec![0.0; k * k];
    for i in 0..k {
        out[i * k + i] = 1.0;
        for j in (i + 1)..k {
            let v = (0.5 * (m(i, j) + m(j, i))).min(1.0);
            out[i * k + j] = v;
            out[j * k + i] = v;
        }
    }
    out
}

/// Classical MDS of a distance matrix (`n × n`, row-major) into `dims` dimensions.
pub fn classical_mds(dist: &[f64], n: usize, dims: usize) -> Vec<Vec<f64>> {
    let mut b = nalgebra::DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        for j in 0..n {
            b[(i, j)] = dist[i * n + j] * dist[i * n + j];
        }
    }
    // Double centring: B = −½ J D² J.
    let row_mean: Vec<f64> = (0..n).map(|i| (0..n).map(|j| b[(i, j)]).sum::<f64>() / n as f64).collect();
    let total = row_mean.iter().sum::<f64>() / n as f64;
    let mut c = nalgebra::DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        for j in 0..n {
            c[(i, j)] = -0.5 * (b[(i, j)] - row_mean[i] - row_mean[j] + total);
        }
    }
    let eig = nalgebra::SymmetricEigen::new(c);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]).then(a.cmp(&b)));
    (0..n)
        .map(|i| {
            order
                .iter()
                .take(dims)
                .map(|&k| {
                    let l = eig.eigenvalues[k];
                    if l > 0.0 {
                        // Fix each eigenvector's sign (largest-magnitude entry positive) so the
                        // embedding is deterministic.
                        let col = eig.eigenvectors.column(k);
                        let s =
                            col.iter().cloned().fold(0.0f64, |m, v| if v.abs() > m.abs() { v } else { m });
                        col[i] * l.sqrt() * if s < 0.0 { -1.0 } else { 1.0 }
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect()
}

/// Flat-kernel mean-shift; returns a cluster label per point.
pub fn mean_shift(points: &[Vec<f64>], bandwidth: f64) -> Vec<usize> {
    let d2 = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>();
    let h2 = bandwidth * bandwidth;
    let modes: Vec<Vec<f64>> = points
        .iter()
        .map(|start| {
            let mut x = start.clone();
            for _ in 0..200 {
                let mut sum = vec![0.0; x.len()];
                let mut n = 0usize;
                for p in points {
                    if d2(p, &x) <= h2 {
                        n += 1;
                        for (s, v) in sum.iter_mut().zip(p) {
                            *s += v;
                        }
                    }
                }
                if n == 0 {
                    break;
                }
                let next: Vec<f64> = sum.iter().map(|s| s / n as f64).collect();
                let shift = d2(&next, &x);
                x = next;
                if shift < 1e-14 * h2.max(1e-30) {
                    break;
                }
            }
            x
        })
        .collect();
    let mut centres: Vec<Vec<f64>> = Vec::new();
    modes
        .iter()
        .map(|m| {
            if let Some(c) = centres.iter().position(|c| d2(c, m) <= 0.25 * h2) {
                c
            } else {
                centres.push(m.clone());
                centres.len() - 1
            }
        })
        .collect()
}

/// Spectral clustering of the words and the star model (thesis 5.3.3).
pub fn detect_instances(
    words: &[Word],
    matches: &[Option<PairMatch>],
    features: &[Feature],
    eps: f64,
    match_radius: f64,
    min_support: usize,
    surface: Option<&SpatialHash>,
    o: &InstanceOptions,
) -> (Vec<Class>, ClusteringReport) {
    let k = words.len();
    let mut report = ClusteringReport::default();
    let cm = cooccurrence_matrix(words, matches, min_support);
    let connected: Vec<usize> = (0..k).filter(|&i| (0..k).any(|j| j != i && cm[i * k + j] > 0.0)).collect();
    report.connected_words = connected.len();
    if connected.len() < 2 {
        return (Vec::new(), report);
    }
    let n = connected.len();
    let mut dist = vec![0.0; n * n];
    for a in 0..n {
        for b in 0..n {
            dist[a * n + b] = 1.0 - cm[connected[a] * k + connected[b]];
        }
    }
    let emb = classical_mds(&dist, n, o.embedding_dims.max(1));
    let labels = mean_shift(&emb, o.bandwidth);
    // Split every mean-shift cluster into connected components of the co-occurrence graph.
    let mut clusters: Vec<Vec<usize>> = Vec::new();
    let nlab = labels.iter().max().map_or(0, |m| m + 1);
    for l in 0..nlab {
        let members: Vec<usize> = (0..n).filter(|&a| labels[a] == l).collect();
        let mut seen = vec![false; members.len()];
        for s in 0..members.len() {
            if seen[s] {
                continue;
            }
            let mut comp = vec![members[s]];
            seen[s] = true;
            let mut q = 0;
            while q < comp.len() {
                let a = comp[q];
                for (t, &b) in members.iter().enumerate() {
                    if !seen[t] && cm[connected[a] * k + connected[b]] > 0.0 {
                        seen[t] = true;
                        comp.push(b);
                    }
                }
                q += 1;
            }
            clusters.push(comp);
        }
    }
    report.clusters = clusters.len();
    let fine_r = match_radius * eps;
    let word_hashes: Vec<SpatialHash> = words
        .iter()
        .map(|w| {
            SpatialHash::new(
                &w.members.iter().map(|m| features[m.feature as usize].position).collect::<Vec<_>>(),
                fine_r,
            )
        })
        .collect();
    let mut classes = Vec::new();
    for (cluster, comp) in clusters.into_iter().enumerate() {
        if comp.len() < 2 {
            continue;
        }
        // Centre word: the member nearest the cluster's coordinate-wise median in the embedding.
        let dims = emb[0].len();
        let median: Vec<f64> = (0..dims)
            .map(|d| {
                let mut v: Vec<f64> = comp.iter().map(|&a| emb[a][d]).collect();
                v.sort_by(f64::total_cmp);
                v[v.len() / 2]
            })
            .collect();
        let centre_local = *comp
            .iter()
            .min_by(|&&a, &&b| {
                let da: f64 = emb[a].iter().zip(&median).map(|(x, y)| (x - y) * (x - y)).sum();
                let db: f64 = emb[b].iter().zip(&median).map(|(x, y)| (x - y) * (x - y)).sum();
                da.total_cmp(&db).then(a.cmp(&b))
            })
            .unwrap_or(&comp[0]);
        let c = connected[centre_local];
        let others: Vec<(usize, &PairMatch)> = comp
            .iter()
            .map(|&a| connected[a])
            .filter(|&j| j != c)
            .filter_map(|j| {
                matches[c * k + j].as_ref().filter(|m| m.support.len() >= min_support.max(1)).map(|m| (j, m))
            })
            .collect();
        if others.is_empty() {
            continue;
        }
        let need = ((o.min_links * others.len() as f64).ceil() as usize).max(1);
        // Star model: link each centre feature to the predicted member of every other word.
        let mut raw: Vec<RawInstance> = Vec::new();
        for m in &words[c].members {
            let f = &features[m.feature as usize];
            let mut linked = vec![m.feature as usize];
            let mut link_words = Vec::new();
            let mut link_frames = vec![(m.feature as usize, m.flip)];
            for &(j, pm) in &others {
                let pred = f.to_world(m.flip, pm.offset);
                if let Some((b, _)) = word_hashes[j].nearest_within(pred, fine_r) {
                    let mb = words[j].members[b];
                    let fb = mb.feature as usize;
                    if fb != m.feature as usize {
                        link_words.push(j);
                        linked.push(fb);
                        link_frames.push((fb, mb.flip));
                    }
                }
            }
            if link_words.len() < need || link_words.len() + 1 < o.min_instance_features {
                continue;
            }
            linked.sort_unstable();
            linked.dedup();
            let mut lo = f.position;
            let mut hi = f.position;
            for &g in &linked {
                let q = features[g].position;
                for d in 0..3 {
                    lo[d] = lo[d].min(q[d]);
                    hi[d] = hi[d].max(q[d]);
                }
            }
            // Word indices of `others` are ascending only when `comp` is; keep the pairing of
            // words and frames, sorted by word.
            let mut by_word: Vec<(usize, (usize, u8))> =
                link_words.iter().copied().zip(link_frames[1..].iter().copied()).collect();
            by_word.sort_unstable_by_key(|x| x.0);
            raw.push(RawInstance {
                centre: m.feature as usize,
                flip: m.flip,
                linked,
                lo,
                hi,
                links: by_word.iter().map(|x| x.0).collect(),
                frames: std::iter::once((m.feature as usize, m.flip))
                    .chain(by_word.iter().map(|x| x.1))
                    .collect(),
            });
        }
        if raw.len() < o.min_instances.max(1) {
            continue;
        }
        let mut words_of_class: Vec<usize> = comp.iter().map(|&a| connected[a]).collect();
        words_of_class.sort_unstable();
        let groups = match (o.split, surface) {
            (ClassSplit::Surface, Some(surface)) => {
                let tol = o.surface_tolerance * eps;
                // Each instance's region: the class box (median linked extents, before any split)
                // at the instance; its surface points, at most `SURFACE_SAMPLES` of them.
                let ext = median_extent(&raw, o.box_margin * eps);
                let regions: Vec<Vec<Point3>> = raw
                    .iter()
                    .map(|r| {
                        let c =
                            [(r.lo[0] + r.hi[0]) / 2.0, (r.lo[1] + r.hi[1]) / 2.0, (r.lo[2] + r.hi[2]) / 2.0];
                        let half = [ext[0] / 2.0, ext[1] / 2.0, ext[2] / 2.0];
                        let radius = (half[0] * half[0] + half[1] * half[1] + half[2] * half[2]).sqrt();
                        crease_samples(surface, c, radius, SURFACE_SAMPLES, |p| {
                            (0..3).all(|d| (p[d] - c[d]).abs() <= half[d])
                        })
                    })
                    .collect();
                let dist = pairwise(raw.len(), |a, b| {
                    let (pa, pb) = correspondences(&raw[a], &raw[b], features);
                    let Some(b_from_a) = kabsch(&pa, &pb) else { return 1.0 };
                    let a_from_b = b_from_a.inverse();
                    if regions[a].is_empty() || regions[b].is_empty() {
                        return 1.0;
                    }
                    let fa = surface_hit_fraction(&regions[a], &b_from_a, surface, tol);
                    let fb = surface_hit_fraction(&regions[b], &a_from_b, surface, tol);
                    1.0 - fa.max(fb)
                });
                split_by_linkage(
                    &dist,
                    raw.len(),
                    o.min_instances.max(2),
                    o.split_ratio,
                    o.split_min_distance,
                )
            }
            _ => vec![(0..raw.len()).collect()],
        };
        report.splits += groups.len().saturating_sub(1);
        let mut raw: Vec<Option<RawInstance>> = raw.into_iter().map(Some).collect();
        for g in groups {
            let part: Vec<RawInstance> = g.iter().filter_map(|&r| raw[r].take()).collect();
            if let Some(class) = assemble(part, &words_of_class, c, cluster, features, eps, o) {
                classes.push(class);
            }
        }
    }
    // Largest first: most instances, then most linked features.
    classes.sort_by(|a, b| {
        let fa: usize = a.instances.iter().map(|i| i.features.len()).sum();
        let fb: usize = b.instances.iter().map(|i| i.features.len()).sum();
        b.instances.len().cmp(&a.instances.len()).then(fb.cmp(&fa)).then(a.centre_word.cmp(&b.centre_word))
    });
    report.classes = classes.len();
    (classes, report)
}

/// One star-model instance before boxes are averaged.
struct RawInstance {
    centre: usize,
    flip: u8,
    linked: Vec<usize>,
    lo: Point3,
    hi: Point3,
    /// Linked words, ascending.
    links: Vec<usize>,
    /// (feature, flip) of the centre, then of each linked word's member in `links` order.
    frames: Vec<(usize, u8)>,
}

/// At most this many surface points represent an instance in [`ClassSplit::Surface`].
const SURFACE_SAMPLES: usize = 800;

/// The median side lengths of the instances' linked boxes, each grown by `pad` on both sides.
fn median_extent(raw: &[RawInstance], pad: f64) -> Point3 {
    let med = |d: usize| {
        let mut v: Vec<f64> = raw.iter().map(|r| r.hi[d] - r.lo[d]).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0) + 2.0 * pad
    };
    [med(0), med(1), med(2)]
}

/// Corresponding positions of two instances: their centres and the features each links through
/// the same word.
fn correspondences(a: &RawInstance, b: &RawInstance, features: &[Feature]) -> (Vec<Point3>, Vec<Point3>) {
    let pos = |r: &RawInstance, k: usize| features[r.frames[k].0].position;
    let mut pa = vec![pos(a, 0)];
    let mut pb = vec![pos(b, 0)];
    let (mut i, mut j) = (0, 0);
    while i < a.links.len() && j < b.links.len() {
        match a.links[i].cmp(&b.links[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                pa.push(pos(a, i + 1));
                pb.push(pos(b, j + 1));
                i += 1;
                j += 1;
            }
        }
    }
    (pa, pb)
}

/// The crease points of `surface` within `radius` of `centre` that pass `inside`, at most `max`
/// of them: an even subset in point-index order (deterministic).
pub(crate) fn crease_samples(
    surface: &SpatialHash,
    centre: Point3,
    radius: f64,
    max: usize,
    inside: impl Fn(Point3) -> bool,
) -> Vec<Point3> {
    let mut v = Vec::new();
    surface.for_each_within(centre, radius, |i, _| {
        let p = surface.point(i);
        if inside(p) {
            v.push((i, p));
        }
    });
    v.sort_unstable_by_key(|x| x.0);
    let step = v.len().div_ceil(max).max(1);
    v.into_iter().step_by(step).map(|x| x.1).collect()
}

/// Share of `points` that land within `tol` of a crease point of `surface` when moved by `t`
/// (0 for no points).
pub(crate) fn surface_hit_fraction(
    points: &[Point3],
    t: &nalgebra::Isometry3<f64>,
    surface: &SpatialHash,
    tol: f64,
) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let hits = points
        .iter()
        .filter(|p| {
            let q = t * nalgebra::Point3::new(p[0], p[1], p[2]);
            surface.nearest_within([q.x, q.y, q.z], tol).is_some()
        })
        .count();
    hits as f64 / points.len() as f64
}

/// The rigid motion that best maps `from` onto `to` in the least-squares sense (Kabsch), or
/// `None` with fewer than three pairs.
///
/// Degenerate pairs get a motion that a rigid motion of the input carries along: when both sets
/// lie on one line (star models linking features along one crease), the rotation about that line
/// is not determined and an SVD leaves it to rounding, so the line's direction is turned onto the
/// other's by the smallest rotation; when the points coincide, the rotation is the identity.
pub(crate) fn kabsch(from: &[Point3], to: &[Point3]) -> Option<nalgebra::Isometry3<f64>> {
    if from.len() < 3 {
        return None;
    }
    let n = from.len() as f64;
    let v = |p: Point3| nalgebra::Vector3::new(p[0], p[1], p[2]);
    let ca = from.iter().fold(nalgebra::Vector3::zeros(), |s, &p| s + v(p)) / n;
    let cb = to.iter().fold(nalgebra::Vector3::zeros(), |s, &p| s + v(p)) / n;
    let mut h = nalgebra::Matrix3::<f64>::zeros();
    let (mut spread_a, mut spread_b) = (0.0, 0.0);
    for (&a, &b) in from.iter().zip(to) {
        h += (v(a) - ca) * (v(b) - cb).transpose();
        spread_a += (v(a) - ca).norm_squared();
        spread_b += (v(b) - cb).norm_squared();
    }
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let sv = svd.singular_values;
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| sv[b].total_cmp(&sv[a]));
    let rot = if sv[order[0]] <= 1e-12 * (spread_a * spread_b).sqrt() {
        nalgebra::UnitQuaternion::identity()
    } else if sv[order[1]] <= 1e-9 * sv[order[0]] {
        // H = σ₁ u₁ v₁ᵀ: u₁ and v₁ are the two lines' directions, signed alike.
        let u1 = u.column(order[0]).into_owned();
        let v1 = vt.row(order[0]).transpose();
        nalgebra::UnitQuaternion::rotation_between(&u1, &v1)?
    } else {
        let mut d = nalgebra::Matrix3::<f64>::identity();
        if (vt.transpose() * u.transpose()).determinant() < 0.0 {
            d[(2, 2)] = -1.0;
        }
        let r = vt.transpose() * d * u.transpose();
        // `r` is orthonormal (to rounding) already; `UnitQuaternion::from_matrix` would iterate
        // to extract a rotation and, started from the identity, never returns for some inputs.
        nalgebra::UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(r))
    };
    let t = cb - rot * ca;
    Some(nalgebra::Isometry3::from_parts(nalgebra::Translation3::from(t), rot))
}

/// The world box of the class box `lo..hi` (in the reference instance's place) carried to an
/// instance by `instance_from_reference`.
fn carried_box(instance_from_reference: &nalgebra::Isometry3<f64>, lo: Point3, hi: Point3) -> Aabb {
    // Through `Aabb::mapped`, not a grow-per-corner loop: see its note on a miscompilation.
    Aabb { min: lo, max: hi }.mapped(|c| {
        let w = instance_from_reference * nalgebra::Point3::new(c[0], c[1], c[2]);
        [w.x, w.y, w.z]
    })
}

/// The symmetric `n × n` matrix of `d(a, b)` (row-major), computed for a < b in parallel.
fn pairwise(n: usize, d: impl Fn(usize, usize) -> f64 + Sync) -> Vec<f64> {
    let upper: Vec<f64> =
        (0..n * n).into_par_iter().map(|ij| if ij / n < ij % n { d(ij / n, ij % n) } else { 0.0 }).collect();
    let mut out = upper.clone();
    for i in 0..n {
        for j in 0..i {
            out[i * n + j] = upper[j * n + i];
        }
    }
    out
}

/// Average-linkage agglomerative clustering of `n` instances under the distance matrix `dist`
/// that refuses to merge two groups when both hold at least `min_size` instances and the average
/// distance between them is at least `min_distance` and at least `ratio` times the average
/// distance within the tighter of the two: groups clearly further apart than their members are
/// from each other stay separate classes; stragglers join their nearest group. Groups in order
/// of their first instance.
fn split_by_linkage(
    dist: &[f64],
    n: usize,
    min_size: usize,
    ratio: f64,
    min_distance: f64,
) -> Vec<Vec<usize>> {
    let d = |i: usize, j: usize| dist[i * n + j];
    let sum =
        |a: &[usize], b: &[usize]| a.iter().map(|&i| b.iter().map(|&j| d(i, j)).sum::<f64>()).sum::<f64>();
    // Each group: members and the sum of its within-group distances (each pair once).
    let mut groups: Vec<(Vec<usize>, f64)> = (0..n).map(|i| (vec![i], 0.0)).collect();
    let within = |g: &(Vec<usize>, f64)| {
        let m = g.0.len();
        if m < 2 { 0.0 } else { g.1 / (m * (m - 1) / 2) as f64 }
    };
    loop {
        let mut best: Option<(f64, usize, usize, f64)> = None;
        for a in 0..groups.len() {
            for b in (a + 1)..groups.len() {
                let s = sum(&groups[a].0, &groups[b].0);
                let h = s / (groups[a].0.len() * groups[b].0.len()) as f64;
                let apart = groups[a].0.len() >= min_size
                    && groups[b].0.len() >= min_size
                    && h >= min_distance
                    && h >= ratio * within(&groups[a]).min(within(&groups[b]));
                if !apart && best.is_none_or(|x| h < x.0) {
                    best = Some((h, a, b, s));
                }
            }
        }
        let Some((_, a, b, s)) = best else { break };
        let (mb, wb) = groups.swap_remove(b);
        groups[a].0.extend(mb);
        groups[a].1 += wb + s;
    }
    let mut out: Vec<Vec<usize>> = groups
        .into_iter()
        .map(|(mut g, _)| {
            g.sort_unstable();
            g
        })
        .collect();
    out.sort_by_key(|g| g[0]);
    out
}

/// A class from a group of star-model instances: the per-class box (median side lengths, padded)
/// placed at each instance, overlapping instances merged; `None` with too few instances.
fn assemble(
    raw: Vec<RawInstance>,
    words_of_class: &[usize],
    centre_word: usize,
    cluster: usize,
    features: &[Feature],
    eps: f64,
    o: &InstanceOptions,
) -> Option<Class> {
    if raw.len() < o.min_instances.max(1) {
        return None;
    }
    let pad = o.box_margin * eps;
    let extent = median_extent(&raw, pad);
    // The class box as the union of the instances' constellations: every instance's linked
    // features are carried onto a reference instance (the best linked) by the rigid motion
    // between their star models, and the box of the pooled features (trimmed at the
    // `box_trim` quantiles against stray links) is carried back to each instance. Occlusion
    // hides different parts of different instances; their union covers the block.
    let reference = (0..raw.len())
        .max_by(|&a, &b| raw[a].linked.len().cmp(&raw[b].linked.len()).then(b.cmp(&a)))
        .unwrap_or(0);
    let transforms: Vec<Option<nalgebra::Isometry3<f64>>> = raw
        .iter()
        .map(|r| {
            let (from, to) = correspondences(r, &raw[reference], features);
            kabsch(&from, &to)
        })
        .collect();
    let union_box = match o.boxes {
        InstanceBoxes::Union => {
            let mut pooled: [Vec<f64>; 3] = Default::default();
            for (r, t) in raw.iter().zip(&transforms) {
                let Some(t) = t else { continue };
                for &g in &r.linked {
                    let p = features[g].position;
                    let q = t * nalgebra::Point3::new(p[0], p[1], p[2]);
                    for d in 0..3 {
                        pooled[d].push(q[d]);
                    }
                }
            }
            if pooled[0].len() < 4 {
                None
            } else {
                let mut lo = [0.0; 3];
                let mut hi = [0.0; 3];
                for d in 0..3 {
                    let v = &mut pooled[d];
                    v.sort_by(f64::total_cmp);
                    // Symmetric ranks (k-th smallest and k-th largest), so that a motion that
                    // turns an axis around picks the same two features.
                    let last = v.len() - 1;
                    let k = ((o.box_trim.clamp(0.0, 0.5) * last as f64).round() as usize).min(last / 2);
                    lo[d] = v[k] - pad;
                    hi[d] = v[last - k] + pad;
                }
                Some((lo, hi))
            }
        }
        InstanceBoxes::Median => None,
    };
    let mut instances: Vec<Instance> = raw
        .into_iter()
        .zip(transforms)
        .map(|(r, t)| {
            let f = &features[r.centre];
            let a = f.axes(r.flip);
            let rot = [[a[0][0], a[1][0], a[2][0]], [a[0][1], a[1][1], a[2][1]], [a[0][2], a[1][2], a[2][2]]];
            let frame = mat4_from_rt(rot, f.position);
            let aabb = match (union_box, t) {
                (Some((lo, hi)), Some(t)) => carried_box(&t.inverse(), lo, hi),
                _ => {
                    let c = [(r.lo[0] + r.hi[0]) / 2.0, (r.lo[1] + r.hi[1]) / 2.0, (r.lo[2] + r.hi[2]) / 2.0];
                    Aabb {
                        min: [c[0] - extent[0] / 2.0, c[1] - extent[1] / 2.0, c[2] - extent[2] / 2.0],
                        max: [c[0] + extent[0] / 2.0, c[1] + extent[1] / 2.0, c[2] + extent[2] / 2.0],
                    }
                }
            };
            Instance {
                centre: r.centre,
                flip: r.flip,
                features: r.linked,
                links: r.links,
                frame,
                aabb,
                footprint: None,
                turn: 0.0,
            }
        })
        .collect();
    // Merge overlapping instances, best linked first.
    instances.sort_by(|a, b| b.features.len().cmp(&a.features.len()).then(a.centre.cmp(&b.centre)));
    let mut kept: Vec<Instance> = Vec::new();
    for inst in instances {
        if !overlaps_any(&inst, &kept, o.merge_overlap) {
            kept.push(inst);
        }
    }
    if kept.len() < o.min_instances.max(1) {
        return None;
    }
    Some(Class { words: words_of_class.to_vec(), centre_word, extent, instances: kept, cluster })
}

/// Whether `inst`'s box overlaps one of `others`' by more than `share` of the smaller box (the
/// test of [`InstanceOptions::merge_overlap`]).
pub(crate) fn overlaps_any(inst: &Instance, others: &[Instance], share: f64) -> bool {
    others.iter().any(|q| {
        inst.aabb.intersection(&q.aabb).is_some_and(|x| {
            x.volume() > share * inst.aabb.volume().min(q.aabb.volume()).max(f64::MIN_POSITIVE)
        })
    })
}

/// Instance `k` of a test class (feature `k` its centre) with this box, footprint and turn.
#[cfg(test)]
pub(crate) fn test_instance(k: usize, aabb: Aabb, footprint: Option<Point3>, turn: f64) -> Instance {
    Instance {
        centre: k,
        flip: 0,
        features: vec![k],
        links: vec![],
        frame: motif_core::geometry::IDENTITY4,
        aabb,
        footprint,
        turn,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kabsch_recovers_a_motion_and_handles_collinear_and_coincident_points() {
        let axis = nalgebra::Unit::new_normalize(nalgebra::Vector3::new(0.3, -0.5, 0.8));
        let m = nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(1.0, -2.0, 0.5),
            nalgebra::UnitQuaternion::from_axis_angle(&axis, 2.0),
        );
        let apply = |m: &nalgebra::Isometry3<f64>, p: Point3| {
            let q = m * nalgebra::Point3::new(p[0], p[1], p[2]);
            [q.x, q.y, q.z]
        };
        let from = [[0.0, 0.0, 0.0], [1.0, 0.2, 0.0], [0.3, 1.5, -0.4], [-0.7, 0.1, 0.9]];
        let to: Vec<Point3> = from.iter().map(|&p| apply(&m, p)).collect();
        let k = kabsch(&from, &to).expect("a motion");
        assert!((k.to_homogeneous() - m.to_homogeneous()).abs().max() < 1e-12);
        // Collinear: the result maps the line onto the line and does not depend on rounding:
        // moving both sets by a motion `g` conjugates it.
        let line = [[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [2.5, 2.5, 0.0], [4.0, 4.0, 0.0]];
        let to: Vec<Point3> = line.iter().map(|&p| apply(&m, p)).collect();
        let k = kabsch(&line, &to).expect("a motion");
        for (p, q) in line.iter().zip(&to) {
            let r = apply(&k, *p);
            assert!((0..3).all(|d| (r[d] - q[d]).abs() < 1e-12), "{r:?} vs {q:?}");
        }
        let g = nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(8.0, -4.0, 30.0),
            nalgebra::UnitQuaternion::from_axis_angle(&nalgebra::Vector3::x_axis(), 1.1),
        );
        let gl: Vec<Point3> = line.iter().map(|&p| apply(&g, p)).collect();
        let gt: Vec<Point3> = to.iter().map(|&p| apply(&g, p)).collect();
        let kg = kabsch(&gl, &gt).expect("a motion");
        let conj = g * k * g.inverse();
        assert!((kg.to_homogeneous() - conj.to_homogeneous()).abs().max() < 1e-9);
        // Coincident points: a translation.
        let k = kabsch(&[[1.0, 2.0, 3.0]; 3], &[[0.0, 0.0, 1.0]; 3]).expect("a translation");
        assert!(k.rotation.angle() < 1e-12);
        assert!((k.translation.vector - nalgebra::Vector3::new(-1.0, -2.0, -2.0)).norm() < 1e-12);
    }

    #[test]
    fn a_carried_box_holds_every_carried_corner() {
        // A 4° rotation and a shift between two window instances of a generated facade, as
        // Kabsch gave them; rustc 1.95.0 at opt-level 3 (`cargo test --release`) dropped the
        // last corner from the z bound of the obvious grow-per-corner loop (0.244, not 0.290).
        let r = nalgebra::Matrix3::new(
            0.9974614985953107,
            -0.0014641553978736665,
            -0.07119280208678487,
            -0.0008696721386265516,
            0.9994635323864849,
            -0.03273974801218342,
            0.07120254553292697,
            0.03271855251231094,
            0.9969251194704298,
        )
        .transpose();
        let t = nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(6.033801142786978, -6.3810382191022414, 0.7497097852416694),
            nalgebra::UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(r)),
        );
        let lo = [9.79664719562898, 4.639849054650811, -0.2916363947198993];
        let hi = [11.202675125995079, 6.058377533497345, 0.26354371024347706];
        let inv = std::hint::black_box(t.inverse());
        let b = carried_box(&inv, std::hint::black_box(lo), std::hint::black_box(hi));
        for c in (Aabb { min: lo, max: hi }).corners() {
            let w = inv * nalgebra::Point3::new(c[0], c[1], c[2]);
            for d in 0..3 {
                assert!(b.min[d] <= w[d] && w[d] <= b.max[d], "corner {c:?} → {w:?} outside {b:?}");
            }
        }
        assert!((b.max[2] - 0.2903654902671897).abs() < 1e-9, "{b:?}");
    }

    #[test]
    fn mds_recovers_planar_distances() {
        let pts: [[f64; 2]; 5] = [[0.0, 0.0], [1.0, 0.0], [0.0, 2.0], [3.0, 1.0], [-1.0, 0.5]];
        let n = pts.len();
        let mut d = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                d[i * n + j] = ((pts[i][0] - pts[j][0]).powi(2) + (pts[i][1] - pts[j][1]).powi(2)).sqrt();
            }
        }
        let e = classical_mds(&d, n, 5);
        for i in 0..n {
            for j in 0..n {
                let de: f64 = e[i].iter().zip(&e[j]).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
                assert!((de - d[i * n + j]).abs() < 1e-9, "{i} {j}: {de} vs {}", d[i * n + j]);
            }
        }
    }

    #[test]
    fn kabsch_recovers_a_rigid_motion() {
        let from: Vec<Point3> =
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.3, 0.4, 1.5], [-1.0, 0.7, 0.2]];
        let r = nalgebra::UnitQuaternion::from_axis_angle(
            &nalgebra::Unit::new_normalize(nalgebra::Vector3::new(0.2, -0.7, 0.4)),
            1.1,
        );
        let t = nalgebra::Isometry3::from_parts(nalgebra::Translation3::new(3.0, -1.0, 0.5), r);
        let to: Vec<Point3> = from
            .iter()
            .map(|p| {
                let q = t * nalgebra::Point3::new(p[0], p[1], p[2]);
                [q.x, q.y, q.z]
            })
            .collect();
        let k = kabsch(&from, &to).expect("three or more pairs");
        for (p, q) in from.iter().zip(&to) {
            let m = k * nalgebra::Point3::new(p[0], p[1], p[2]);
            assert!((m.x - q[0]).abs() + (m.y - q[1]).abs() + (m.z - q[2]).abs() < 1e-9);
        }
        assert!(kabsch(&from[..2], &to[..2]).is_none());
    }

    /// A distance matrix of groups with the given sizes: `within` inside a group (plus a small
    /// deterministic jitter), `between` across groups.
    fn grouped(sizes: &[usize], within: f64, between: f64) -> (Vec<f64>, usize) {
        let label: Vec<usize> =
            sizes.iter().enumerate().flat_map(|(g, &n)| std::iter::repeat_n(g, n)).collect();
        let n = label.len();
        let mut d = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                if i != j {
                    let jitter = 0.01 * (((i * 7 + j * 7) % 5) as f64 / 5.0);
                    d[i * n + j] = if label[i] == label[j] { within } else { between } + jitter;
                }
            }
        }
        (d, n)
    }

    #[test]
    fn linkage_splits_groups_that_are_clearly_apart() {
        let (d, n) = grouped(&[6, 5], 0.05, 0.3);
        let g = split_by_linkage(&d, n, 2, 2.0, 0.1);
        assert_eq!(g, vec![(0..6).collect::<Vec<_>>(), (6..11).collect()]);
    }

    #[test]
    fn linkage_keeps_a_noisy_class_whole() {
        // Two groups no further apart than their members are from each other stay one class.
        let (d, n) = grouped(&[6, 5], 0.2, 0.25);
        assert_eq!(split_by_linkage(&d, n, 2, 2.0, 0.1).len(), 1);
        // Near-identical groups (below the minimum distance) stay one class too.
        let (d, n) = grouped(&[6, 5], 0.0, 0.05);
        assert_eq!(split_by_linkage(&d, n, 2, 2.0, 0.1).len(), 1);
    }

    #[test]
    fn a_straggler_joins_its_nearest_group() {
        let (mut d, n) = grouped(&[5, 5, 1], 0.05, 0.4);
        // The single instance 10 is closer to the first group.
        for i in 0..5 {
            d[i * n + 10] = 0.2;
            d[10 * n + i] = 0.2;
        }
        let g = split_by_linkage(&d, n, 2, 2.0, 0.1);
        assert_eq!(g, vec![vec![0, 1, 2, 3, 4, 10], (5..10).collect()]);
    }

    #[test]
    fn union_boxes_cover_what_each_instance_shows_in_part() {
        // One block (a 2 × 3 unit constellation) at two places; the first instance shows its
        // lower part, the second its upper part, both its four shared corners.
        let block: [Point3; 6] = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 1.0, 0.5],
            [2.0, 1.0, 0.5],
            [0.0, -1.0, 0.0],
            [1.0, 2.0, 0.0],
        ];
        let mut features = Vec::new();
        let mut raw = Vec::new();
        for (shift, extra) in [([0.0, 0.0, 0.0], 4usize), ([10.0, 5.0, 0.0], 5)] {
            let base = features.len();
            for p in block {
                let position = [p[0] + shift[0], p[1] + shift[1], p[2] + shift[2]];
                features.push(Feature {
                    point: 0,
                    position,
                    x: [0.0, 0.0, 1.0],
                    y: [1.0, 0.0, 0.0],
                    kappa: 1.0,
                });
            }
            let shown: Vec<usize> = vec![base, base + 1, base + 2, base + 3, base + extra];
            let lo = [0.0; 3];
            raw.push(RawInstance {
                centre: base,
                flip: 0,
                linked: shown.clone(),
                lo,
                hi: lo,
                links: vec![1, 2, 3, 10 + extra],
                frames: shown.iter().map(|&f| (f, 0)).collect(),
            });
        }
        let o = InstanceOptions { box_margin: 0.0, box_trim: 0.0, ..Default::default() };
        let c = assemble(raw, &[0, 1, 2, 3], 0, 0, &features, 1.0, &o).expect("two instances");
        for inst in &c.instances {
            let s = if inst.centre == 0 { [0.0, 0.0, 0.0] } else { [10.0, 5.0, 0.0] };
            for p in block {
                let q = [p[0] + s[0], p[1] + s[1], p[2] + s[2]];
                assert!(inst.aabb.contains(q), "{q:?} outside {:?}", inst.aabb);
            }
        }
    }

    #[test]
    fn mean_shift_separates_two_blobs() {
        let mut pts = Vec::new();
        for i in 0..10 {
            pts.push(vec![0.01 * i as f64, 0.0]);
            pts.push(vec![2.0 + 0.01 * i as f64, 1.0]);
        }
        let l = mean_shift(&pts, 0.5);
        for i in 0..10 {
            assert_eq!(l[2 * i], l[0]);
            assert_eq!(l[2 * i + 1], l[1]);
        }
        assert_ne!(l[0], l[1]);
    }
}
