//! Free-standing blocks grouped by their shapes (not in the thesis; step 11 of
//! [`crate::extent`]).
//!
//! Why: the co-occurrence classes of 5.3.3 gather instances whose feature constellations
//! match; on smooth, curved blocks the constellations of two different blocks can match as
//! well as two copies of one. On a hard scene of five natural shapes from the shared data
//! (`motif example scene-parts --parts` bunny, duck, cow, armadillo and dragon, seed 1) the
//! detector made one class of 29 instances holding all five (F 0.326), and the thesis's own
//! output (`--regroup none`) two classes mixing them (F 0.323). On medium scenes of the same
//! shapes the classes are small and both mixed and split: seed 2 gave eleven classes for five
//! shapes, the cows as two classes of three, a class of five holding two bunnies, two armadillos
//! and a duck. The extent stage's later steps cannot mend this: the scenes scale every part to
//! one size, so grouping by size sees one block, and the depth images of [`crate::aligned`]
//! picture only instances whose box is a slab along their class's thin axis (blocks on a wall).
//!
//! What it does: the free-standing instances (a box whose smallest side is more than
//! [`crate::aligned::AlignedOptions::flatness`] times its middle side) of all classes together,
//! when at least [`ShapeSplitOptions::min_instances`] of them have points enough to compare (with
//! more than [`ShapeSplitOptions::max_instances`], class by class as below):
//! 1. **Points.** Each free-standing instance's resampled points inside its box, off the support
//!    planes of [`crate::extent::segment`] (the ground, a wall): the block alone. An instance
//!    with fewer than [`ShapeSplitOptions::min_points`] is not compared, nor one on the same
//!    block as an instance of a larger class (ties: an earlier class): it stays where it is.
//!    Two instances of one block cover each other fully, so the repeats of a few blocks would
//!    otherwise form a group of their own (the aligned step's communities leave such pairs
//!    unlinked for the same reason); on the demo's facade a second class repeating four
//!    balconies took two blocks from the first (F 0.958 → 0.944).
//! 2. **Similarity.** Of every two compared instances, the shape similarity of
//!    [`crate::segment_classes`] step 5: one aligned onto the other by principal frames, turns
//!    about the first axis and ICP, the share of its points within
//!    [`crate::extent::ExtentOptions::shape_tolerance`] of the other's, averaged over both
//!    directions. The alignment is free of any rigid motion of the input; the boxes are not
//!    (they are axis-aligned, as everywhere in the stage), so which instances count as
//!    free-standing, and what their boxes hold, follow the world axes.
//! 3. **Communities.** Distances 1 − similarity, weighted by the self-tuning affinity
//!    ([`crate::communities::self_tuning_weights`], rank [`ShapeSplitOptions::scale_rank`]),
//!    grouped into the communities of highest modularity ([`crate::communities::louvain`],
//!    resolution [`ShapeSplitOptions::resolution`]), as [`crate::aligned`] groups depth images.
//!    A partition counts only when two or more communities have at least
//!    [`ShapeSplitOptions::min_group`] members (three: two instances alike and unlike the rest
//!    happen by chance) and its modularity is at least [`ShapeSplitOptions::min_modularity`];
//!    the members of smaller communities join the group they resemble most (mean similarity,
//!    each compared with the groups as the communities left them), and each group is
//!    partitioned again the same way.
//! 4. **Joined again.** Groups whose members cover each other at least
//!    [`ShapeSplitOptions::join_similarity`] on average are joined, the most alike first:
//!    copies of one block seen from different sides, or with different surroundings in their
//!    boxes, form communities as readily as different blocks do, but they still cover each other
//!    well.
//! 5. **Hosted.** Each group is hosted by a class it shares instances with, one group per class,
//!    the pairs sharing the most instances first (`aligned::host`, as the aligned step
//!    hosts its communities); a group left without a host becomes a new class, a copy (words,
//!    cluster) of the class most of its members came from.
//! 6. **Moved only on clear evidence.** An instance leaves its class for its group's host only
//!    when it covers the group's other members at least
//!    [`ShapeSplitOptions::join_similarity`] on average, as copies do, or when it resembles them
//!    more (mean similarity) than the compared members of its class that went to other groups;
//!    otherwise it stays. On a hard street (seed 2) two cars seen from one side cover each
//!    other 0.59 and the balconies 0.49–0.60, fall into the balconies' group, and without this
//!    test left their class of cars for the balconies' (hard streets of seeds 1–12, F 0.694 →
//!    0.671). A new class that would keep fewer than two members is not made, and they stay. Then each class keeps one
//!    instance per block (a newcomer that repeats a block the class holds is dropped), and
//!    classes left with fewer than two instances go (`content::apply_labels`).
//!
//! With [`ShapeSplitOptions::across_classes`] off (`--shape-split-per-class`, the step's first
//! version) steps 1–4 run within each class that has at least
//! [`ShapeSplitOptions::min_instances`] compared free-standing instances, and when two or more
//! groups remain the largest stays in the class, with the instances that were not compared,
//! and the others become new classes: classes are split, but never joined or corrected, and
//! classes of fewer than six are left alone.
//!
//! Cost: two coverages per pair of compared instances (72 starts and two ICP refinements of
//! [`crate::segment_classes::SHAPE_SAMPLE`] points each), in parallel over pairs. With more
//! than [`ShapeSplitOptions::max_instances`] free-standing instances in the scene the step
//! works class by class instead, leaving alone classes with more than that many, which bounds
//! the cost at that many squared over two pairs (per class).
//!
//! # Measured
//! Scenes of five natural shapes of the shared data (`motif bench detect --kind scene-parts
//! --parts` bunny, duck, cow, armadillo, dragon; seeds 1–6), EM + SC F without the step →
//! class by class (the first version) → across classes: 0.924 → 0.971 → 0.977 (easy), 0.577 →
//! 0.724 → 0.868 (medium), 0.389 → 0.434 → 0.463 (hard). On the facade and street benchmark
//! (`motif bench detect --scenes 12 --no-icp`, seeds 1–12) class by class → across classes:
//! facades 0.952 / 0.950 / 0.870 → 0.953 / 0.948 / 0.869, streets 0.941 / 0.858 / 0.694 →
//! 0.941 / 0.868 / 0.695 (easy / medium / hard; no street scene lower by more than 0.001).
//! Across classes with every instance moving with its group (no step 6): natural 0.960 / 0.882
//! / 0.479, streets 0.939 / 0.853 / 0.671; with step 6's first condition only: natural hard
//! 0.400; with repeats compared (step 1): natural medium 0.882, the demo's facade 0.944
//! instead of 0.958. Without
//! [`ShapeSplitOptions::min_group`] (groups of two) and the joining, the first version split
//! classes of one balcony style in two on 8 of the 12 medium scenes (medium facades 0.973 →
//! 0.953). The variants and the held-out seeds: `docs/detect.md`, "Natural shapes, and
//! classes split by shape" and "Free-standing blocks grouped by shape across classes".

use motif_core::geometry::Point3;
use serde::{Deserialize, Serialize};

use crate::extent::median_box_size;
use crate::grid::SpatialHash;
use crate::instances::{Class, Instance, overlaps_any};
use crate::segment_classes::{Shape, Similarities, principal_frame};

/// Options of the step (module documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ShapeSplitOptions {
    /// Whether the step runs. Default true.
    pub enabled: bool,
    /// The step runs when at least this many free-standing instances can be compared (in the
    /// scene; per class with [`Self::across_classes`] off): two groups of [`Self::min_group`].
    /// Default 6.
    pub min_instances: usize,
    /// A community becomes a class of its own only with at least this many members; the
    /// members of smaller ones join the group they resemble most. Three, as
    /// [`crate::extent::ExtentOptions::segment_min_instances`]: two instances alike and unlike
    /// the rest happen by chance (on medium streets, pairs of balconies seen alike split off
    /// their class). Default 3.
    pub min_group: usize,
    /// With more free-standing instances than this in the scene, the step works class by
    /// class (as with [`Self::across_classes`] off), and a class with more than this is left
    /// alone: the cost grows with the square. Default 64.
    pub max_instances: usize,
    /// An instance is compared when its box holds at least this many resampled points off the
    /// support planes (fewer cannot fix a principal frame). Default 30.
    pub min_points: usize,
    /// Rank of the neighbour that sets an instance's scale in the self-tuning affinity. Default
    /// 3, as [`crate::aligned::AlignedOptions::scale_rank`].
    pub scale_rank: usize,
    /// Resolution γ of the modularity. Default 1.
    pub resolution: f64,
    /// A partition counts only when its modularity (on the affinity weights) is at least this.
    /// Default 0.05.
    pub min_modularity: f64,
    /// Groups whose members cover each other at least this much on average (the mean
    /// similarity over the pairs across them) are joined again: copies of one block seen from
    /// different sides, or varied, fall into communities as readily as different blocks do.
    /// Across classes, an instance moves to another class only when it covers its group's other
    /// members this much on average.
    /// A share at the coverage tolerance (2ε), so it holds for blocks several tens of ε across,
    /// as on the benchmark scenes (a 1.5 m animal at ε ≈ 3 cm): at a tolerance of 7% of the
    /// size instead of 4%, a whole bunny and a whole cow cover each other 75%. Default 0.7.
    pub join_similarity: f64,
    /// Whether the free-standing instances of all classes are grouped together (module
    /// documentation), rather than each class's alone (the step's first version, which only
    /// splits classes). Default true.
    pub across_classes: bool,
}

impl Default for ShapeSplitOptions {
    fn default() -> Self {
        ShapeSplitOptions {
            enabled: true,
            min_instances: 6,
            min_group: 3,
            max_instances: 64,
            min_points: 30,
            scale_rank: 3,
            resolution: 1.0,
            min_modularity: 0.05,
            join_similarity: 0.7,
            across_classes: true,
        }
    }
}

impl ShapeSplitOptions {
    /// Checks the ranges: the offending option's name and what is wrong.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if self.min_group < 2 {
            return Err(("extent.shapes.min_group", format!("must be at least 2, got {}", self.min_group)));
        }
        if self.min_instances < 2 * self.min_group {
            return Err((
                "extent.shapes.min_instances",
                format!(
                    "must be at least twice min_group ({}), got {}",
                    2 * self.min_group,
                    self.min_instances
                ),
            ));
        }
        if self.max_instances < self.min_instances {
            return Err((
                "extent.shapes.max_instances",
                format!(
                    "must be at least min_instances ({}), got {}",
                    self.min_instances, self.max_instances
                ),
            ));
        }
        if self.min_points < 3 {
            return Err(("extent.shapes.min_points", format!("must be at least 3, got {}", self.min_points)));
        }
        if self.scale_rank == 0 {
            return Err(("extent.shapes.scale_rank", "must be at least 1, got 0".into()));
        }
        if !(self.resolution > 0.0 && self.resolution.is_finite()) {
            return Err((
                "extent.shapes.resolution",
                format!("must be finite and positive, got {}", self.resolution),
            ));
        }
        if !(0.0..=1.0).contains(&self.join_similarity) {
            return Err((
                "extent.shapes.join_similarity",
                format!("must be between 0 and 1, got {}", self.join_similarity),
            ));
        }
        if !self.min_modularity.is_finite() {
            return Err((
                "extent.shapes.min_modularity",
                format!("must be finite, got {}", self.min_modularity),
            ));
        }
        Ok(())
    }
}

/// What the step did, for reports.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ShapeSplitReport {
    /// Classes examined.
    pub classes: usize,
    /// Instances compared.
    pub instances: usize,
    /// Classes split (across classes: classes whose compared instances went to two classes or
    /// more).
    pub split: usize,
    /// Classes added by the splits.
    pub new_classes: usize,
    /// Across classes: the groups the compared instances formed.
    pub groups: usize,
    /// Across classes: compared instances that changed class (including those then dropped as
    /// repeats).
    pub moved: usize,
    /// Across classes: instances dropped because their new class already held their block.
    pub duplicates: usize,
    /// Across classes: classes left with fewer than two instances and dropped.
    pub dropped_classes: usize,
}

/// Whether a box of these extents is free-standing: its smallest side is more than `flatness`
/// times its middle one.
fn free_standing(extent: Point3, flatness: f64) -> bool {
    let mut e = extent;
    e.sort_by(f64::total_cmp);
    e[0] > flatness * e[1]
}

/// What the step reads besides the classes.
pub(crate) struct ShapeInputs<'a> {
    /// The resampled points.
    pub points: &'a [Point3],
    /// Their segments (`None` on support planes).
    pub segment_of: &'a [Option<u32>],
    /// A spatial hash of `points`.
    pub hash: &'a SpatialHash,
    /// [`crate::aligned::AlignedOptions::flatness`]: which boxes stand free.
    pub flatness: f64,
    /// The coverage tolerance, in input units.
    pub tolerance: f64,
    /// [`crate::instances::InstanceOptions::merge_overlap`]: when two boxes are one block.
    pub merge_overlap: f64,
}

/// The step (module documentation) on `classes`, in place; new classes are appended.
pub(crate) fn split_by_shape(
    classes: &mut Vec<Class>,
    input: &ShapeInputs,
    o: &ShapeSplitOptions,
) -> ShapeSplitReport {
    let mut report = ShapeSplitReport::default();
    if !o.enabled {
        return report;
    }
    if o.across_classes {
        if let Some(report) = group_across(classes, input, o) {
            return report;
        }
    }
    let mut added: Vec<Class> = Vec::new();
    let mut block: Vec<Point3> = Vec::new();
    let mut inside: Vec<usize> = Vec::new();
    for class in classes.iter_mut() {
        let free: Vec<usize> = (0..class.instances.len())
            .filter(|&k| free_standing(class.instances[k].aabb.extent(), input.flatness))
            .collect();
        if free.len() < o.min_instances || free.len() > o.max_instances {
            continue;
        }
        let shapes: Vec<Option<Shape>> = free
            .iter()
            .map(|&k| shape_in(&class.instances[k].aabb, input, o, &mut inside, &mut block))
            .collect();
        let compared: Vec<usize> = (0..free.len()).filter(|&i| shapes[i].is_some()).collect();
        if compared.len() < o.min_instances {
            continue;
        }
        report.classes += 1;
        report.instances += compared.len();
        let similarity = Similarities::new(&shapes, input.tolerance);
        let sim = |a: usize, b: usize| similarity.get(a, b);
        let groups = join_alike(partition(&compared, &sim, o), &sim, o.join_similarity);
        if groups.len() < 2 {
            continue;
        }
        // The largest group stays (ties: the first).
        let host = (0..groups.len())
            .max_by(|&a, &b| groups[a].len().cmp(&groups[b].len()).then(b.cmp(&a)))
            .expect("two groups or more");
        let mut leave = vec![false; class.instances.len()];
        for (g, m) in groups.iter().enumerate() {
            if g == host {
                continue;
            }
            let mut ks: Vec<usize> = m.iter().map(|&i| free[i]).collect();
            ks.sort_unstable();
            let instances: Vec<Instance> = ks.iter().map(|&k| class.instances[k].clone()).collect();
            for &k in &ks {
                leave[k] = true;
            }
            added.push(Class {
                words: class.words.clone(),
                centre_word: class.centre_word,
                extent: median_box_size(&instances),
                instances,
                cluster: class.cluster,
            });
            report.new_classes += 1;
        }
        let mut k = 0;
        class.instances.retain(|_| {
            let keep = !leave[k];
            k += 1;
            keep
        });
        class.extent = median_box_size(&class.instances);
        report.split += 1;
    }
    classes.extend(added);
    report
}

/// The shape of the resampled points inside box `b`, off the support planes, or `None` with
/// fewer than [`ShapeSplitOptions::min_points`] of them. `inside` and `block` are scratch
/// buffers.
fn shape_in(
    b: &motif_core::geometry::Aabb,
    input: &ShapeInputs,
    o: &ShapeSplitOptions,
    inside: &mut Vec<usize>,
    block: &mut Vec<Point3>,
) -> Option<Shape> {
    let ShapeInputs { points, segment_of, hash, .. } = *input;
    inside.clear();
    hash.for_each_within(b.center(), 0.5 * b.diagonal(), |i, _| {
        if segment_of[i].is_some() && b.contains(points[i]) {
            inside.push(i);
        }
    });
    // The hash visits points in cell order; in index order the sample (every k-th point) does
    // not depend on how the cells fall.
    inside.sort_unstable();
    block.clear();
    block.extend(inside.iter().map(|&i| points[i]));
    if block.len() < o.min_points {
        return None;
    }
    let (frame, _) = principal_frame(block)?;
    Shape::new(block, &frame)
}

/// The step across classes (module documentation): the free-standing instances of all classes
/// grouped together by shape, the groups hosted by the classes they share most with
/// ([`crate::aligned::host`]), moves kept on clear evidence only, repeats and classes of one
/// dropped ([`crate::content::apply_labels`]). `None` (nothing done) with more than
/// [`ShapeSplitOptions::max_instances`] free-standing instances.
fn group_across(
    classes: &mut Vec<Class>,
    input: &ShapeInputs,
    o: &ShapeSplitOptions,
) -> Option<ShapeSplitReport> {
    let ShapeInputs { flatness, tolerance, merge_overlap, .. } = *input;
    let mut report = ShapeSplitReport::default();
    let free: Vec<(usize, usize)> = classes
        .iter()
        .enumerate()
        .flat_map(|(ci, c)| (0..c.instances.len()).map(move |k| (ci, k)))
        .filter(|&(ci, k)| free_standing(classes[ci].instances[k].aabb.extent(), flatness))
        .collect();
    // One instance per block: an instance on the block of one in a larger class (ties: an
    // earlier class) takes no part and stays where it is. Two instances of one block cover each
    // other fully, so with both a block's repeats would form a group of their own and move
    // together (as the aligned step's communities, which leave such pairs unlinked).
    let size = |ci: usize| classes[ci].instances.len();
    let ranks_above = |(cj, j): (usize, usize), (ci, k): (usize, usize)| {
        (size(cj), std::cmp::Reverse(cj), std::cmp::Reverse(j))
            > (size(ci), std::cmp::Reverse(ci), std::cmp::Reverse(k))
    };
    let free: Vec<(usize, usize)> = free
        .iter()
        .copied()
        .filter(|&a| {
            !free.iter().any(|&b| {
                ranks_above(b, a)
                    && overlaps_any(
                        &classes[a.0].instances[a.1],
                        std::slice::from_ref(&classes[b.0].instances[b.1]),
                        merge_overlap,
                    )
            })
        })
        .collect();
    if free.len() > o.max_instances {
        return None;
    }
    if free.len() < o.min_instances {
        return Some(report);
    }
    let (mut inside, mut block) = (Vec::new(), Vec::new());
    let mut items: Vec<(usize, usize)> = Vec::new();
    let mut shapes: Vec<Option<Shape>> = Vec::new();
    for &(ci, k) in &free {
        if let Some(shape) = shape_in(&classes[ci].instances[k].aabb, input, o, &mut inside, &mut block) {
            items.push((ci, k));
            shapes.push(Some(shape));
        }
    }
    if items.len() < o.min_instances {
        return Some(report);
    }
    let mut examined: Vec<usize> = items.iter().map(|it| it.0).collect();
    examined.dedup();
    report.classes = examined.len();
    report.instances = items.len();
    let similarity = Similarities::new(&shapes, tolerance);
    let sim = |a: usize, b: usize| similarity.get(a, b);
    let nodes: Vec<usize> = (0..items.len()).collect();
    let groups = join_alike(partition(&nodes, &sim, o), &sim, o.join_similarity);
    report.groups = groups.len();
    let mut community = vec![0; items.len()];
    for (g, members) in groups.iter().enumerate() {
        for &i in members {
            community[i] = g;
        }
    }
    let before = classes.len();
    let mut label = crate::aligned::host(classes, &items, &community, &mut report.new_classes);
    // An instance leaves its class only on clear evidence (module documentation, step 6): it
    // covers its group's other members as copies do, or it resembles them more than the
    // compared members of its class that went to other groups. Otherwise the shapes say less
    // than the co-occurrence did (a car seen from one side, as like a balcony as another car).
    let mean_to = |i: usize, others: &mut dyn Iterator<Item = usize>| {
        let (sum, count) = others.fold((0.0, 0usize), |(s, c), j| (s + similarity.get(i, j), c + 1));
        (count > 0).then(|| sum / count as f64)
    };
    let stay: Vec<bool> = (0..items.len())
        .map(|i| {
            let group = &groups[community[i]];
            let to_group = mean_to(i, &mut group.iter().copied().filter(|&j| j != i)).unwrap_or(0.0);
            let to_rest = mean_to(
                i,
                &mut (0..items.len()).filter(|&j| items[j].0 == items[i].0 && community[j] != community[i]),
            );
            to_group < o.join_similarity && to_rest.is_none_or(|r| to_group <= r)
        })
        .collect();
    for (i, it) in items.iter().enumerate() {
        if stay[i] {
            label[i] = it.0;
        }
    }
    // A new class needs two members, or [`crate::content::apply_labels`] would drop it with
    // the one that moved there: such a member stays too. New classes left empty go again.
    for c in before..classes.len() {
        if label.iter().filter(|&&l| l == c).count() < 2 {
            for (l, it) in label.iter_mut().zip(&items) {
                if *l == c {
                    *l = it.0;
                }
            }
        }
    }
    let used: Vec<bool> = (before..classes.len()).map(|c| label.contains(&c)).collect();
    let mut renumber: Vec<usize> = (0..classes.len()).collect();
    let mut next = before;
    for (k, &u) in used.iter().enumerate() {
        if u {
            renumber[before + k] = next;
            next += 1;
        }
    }
    let mut k = 0;
    classes.retain(|_| {
        let keep = k < before || used[k - before];
        k += 1;
        keep
    });
    report.new_classes = next - before;
    for l in &mut label {
        *l = renumber[*l];
    }
    report.split = examined
        .iter()
        .filter(|&&ci| {
            let mut to = items.iter().zip(&label).filter(|(it, _)| it.0 == ci).map(|(_, &l)| l);
            let first = to.next();
            to.any(|l| Some(l) != first)
        })
        .count();
    report.moved = label.iter().zip(&items).filter(|(l, it)| **l != it.0).count();
    if report.moved > 0 {
        let (duplicates, dropped) = crate::content::apply_labels(classes, &items, &label, merge_overlap);
        report.duplicates = duplicates;
        report.dropped_classes = dropped;
    }
    Some(report)
}

/// The groups of `nodes` (indices into `sim`): the communities of the self-tuning affinity on
/// 1 − `sim`, each split again the same way, as long as a partition has two communities of
/// [`ShapeSplitOptions::min_group`] or more and modularity at least
/// [`ShapeSplitOptions::min_modularity`]. The members of smaller communities join the group
/// whose members they resemble most, each compared with the groups as the communities left them
/// (so the result does not depend on the order in which they are placed). The order of the
/// groups is deterministic.
fn partition(nodes: &[usize], sim: &impl Fn(usize, usize) -> f64, o: &ShapeSplitOptions) -> Vec<Vec<usize>> {
    let n = nodes.len();
    if n < 2 * o.min_group {
        return vec![nodes.to_vec()];
    }
    let d: Vec<f64> = (0..n * n).map(|ab| 1.0 - sim(nodes[ab / n], nodes[ab % n])).collect();
    let w = crate::communities::self_tuning_weights(&d, n, |a, b| a != b, o.scale_rank);
    let community = crate::communities::louvain(&w, n, o.resolution);
    let count = community.iter().max().map_or(0, |c| c + 1);
    let mut groups: Vec<Vec<usize>> = vec![Vec::new(); count];
    for (i, &c) in community.iter().enumerate() {
        groups[c].push(i);
    }
    let (mut groups, small): (Vec<Vec<usize>>, Vec<Vec<usize>>) =
        groups.into_iter().partition(|g| g.len() >= o.min_group);
    if groups.len() < 2 {
        return vec![nodes.to_vec()];
    }
    // Each member of a small community is compared with the groups as the communities left
    // them, so where one goes does not depend on where the others went.
    let joins: Vec<(usize, usize)> = small
        .into_iter()
        .flatten()
        .map(|i| {
            let mean = |g: &[usize]| g.iter().map(|&j| 1.0 - d[i * n + j]).sum::<f64>() / g.len() as f64;
            let best = (0..groups.len())
                .max_by(|&a, &b| mean(&groups[a]).total_cmp(&mean(&groups[b])).then(b.cmp(&a)))
                .expect("two groups or more");
            (best, i)
        })
        .collect();
    for (g, i) in joins {
        groups[g].push(i);
    }
    let mut membership = vec![0; n];
    for (g, m) in groups.iter_mut().enumerate() {
        m.sort_unstable();
        for &i in m.iter() {
            membership[i] = g;
        }
    }
    groups.sort_by_key(|m| m[0]);
    if crate::communities::modularity(&w, n, &membership, o.resolution) < o.min_modularity {
        return vec![nodes.to_vec()];
    }
    groups
        .iter()
        .flat_map(|m| {
            let sub: Vec<usize> = m.iter().map(|&i| nodes[i]).collect();
            partition(&sub, sim, o)
        })
        .collect()
}

/// `groups` with every two whose members resemble each other at least `join` on average (mean
/// similarity over the pairs across them) joined, the most alike first, until no two do.
fn join_alike(mut groups: Vec<Vec<usize>>, sim: &impl Fn(usize, usize) -> f64, join: f64) -> Vec<Vec<usize>> {
    let across = |a: &[usize], b: &[usize]| {
        a.iter().flat_map(|&i| b.iter().map(move |&j| sim(i, j))).sum::<f64>() / (a.len() * b.len()) as f64
    };
    loop {
        let mut best: Option<(f64, usize, usize)> = None;
        for a in 0..groups.len() {
            for b in a + 1..groups.len() {
                let s = across(&groups[a], &groups[b]);
                if s >= join && best.is_none_or(|(t, _, _)| s > t) {
                    best = Some((s, a, b));
                }
            }
        }
        let Some((_, a, b)) = best else { return groups };
        let moved = groups.remove(b);
        groups[a].extend(moved);
        groups[a].sort_unstable();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use motif_core::geometry::{Aabb, IDENTITY4};

    const H: f64 = 0.05;

    /// The step's inputs, with [`crate::instances::InstanceOptions::merge_overlap`]'s default.
    fn inputs<'a>(
        points: &'a [Point3],
        segment_of: &'a [Option<u32>],
        hash: &'a SpatialHash,
        flatness: f64,
        tolerance: f64,
    ) -> ShapeInputs<'a> {
        ShapeInputs { points, segment_of, hash, flatness, tolerance, merge_overlap: 0.5 }
    }

    /// Points about every `H` on a crate of `size` (x, y, z) standing on y = 0: its four sides
    /// and top.
    fn crate_points(size: Point3) -> Vec<Point3> {
        let mut out = Vec::new();
        let n = |l: f64| (l / H).round().max(1.0) as usize;
        let (a, b, c) = (size[0], size[1], size[2]);
        for i in 0..=n(a) {
            for j in 0..=n(b) {
                let (x, y) = (-0.5 * a + a * i as f64 / n(a) as f64, b * j as f64 / n(b) as f64);
                out.push([x, y, -0.5 * c]);
                out.push([x, y, 0.5 * c]);
            }
        }
        for i in 0..=n(c) {
            for j in 0..=n(b) {
                let (z, y) = (-0.5 * c + c * i as f64 / n(c) as f64, b * j as f64 / n(b) as f64);
                out.push([-0.5 * a, y, z]);
                out.push([0.5 * a, y, z]);
            }
        }
        for i in 0..=n(a) {
            for k in 0..=n(c) {
                out.push([-0.5 * a + a * i as f64 / n(a) as f64, b, -0.5 * c + c * k as f64 / n(c) as f64]);
            }
        }
        out
    }

    /// Points about every `H` on a drum of radius `r` and height `h` standing on y = 0: its
    /// side and top.
    fn drum_points(r: f64, h: f64) -> Vec<Point3> {
        let mut out = Vec::new();
        let around = (std::f64::consts::TAU * r / H).round() as usize;
        let up = (h / H).round() as usize;
        for i in 0..around {
            let t = std::f64::consts::TAU * i as f64 / around as f64;
            for j in 0..=up {
                out.push([r * t.cos(), h * j as f64 / up as f64, r * t.sin()]);
            }
        }
        let rings = (r / H).round() as usize;
        for k in 1..rings {
            let rr = r * k as f64 / rings as f64;
            let m = (std::f64::consts::TAU * rr / H).round().max(1.0) as usize;
            for i in 0..m {
                let t = std::f64::consts::TAU * i as f64 / m as f64;
                out.push([rr * t.cos(), h, rr * t.sin()]);
            }
        }
        out
    }

    /// The scale of block `k`: within 4% of 1.
    fn scale_of(k: usize) -> f64 {
        1.0 + 0.04 * ((k * 7 % 5) as f64 / 2.0 - 1.0)
    }

    /// One class holding `blocks` (points around the origin), block k turned about the up axis
    /// by `turn[0]` k + `turn[1]` radians and moved 3k m along x: the points, their segments
    /// (none on support) and the class.
    fn placed(blocks: &[Vec<Point3>], turn: [f64; 2]) -> (Vec<Point3>, Vec<Option<u32>>, Vec<Class>) {
        let mut points = Vec::new();
        let mut instances = Vec::new();
        for (k, block) in blocks.iter().enumerate() {
            let (sin, cos) = (turn[0] * k as f64 + turn[1]).sin_cos();
            let at = 3.0 * k as f64;
            let start = points.len();
            points
                .extend(block.iter().map(|p| [cos * p[0] + sin * p[2] + at, p[1], -sin * p[0] + cos * p[2]]));
            let mut b = Aabb { min: [f64::INFINITY; 3], max: [f64::NEG_INFINITY; 3] };
            for p in &points[start..] {
                for a in 0..3 {
                    b.min[a] = b.min[a].min(p[a] - 0.5 * H);
                    b.max[a] = b.max[a].max(p[a] + 0.5 * H);
                }
            }
            instances.push(Instance {
                centre: start,
                flip: 0,
                features: Vec::new(),
                links: Vec::new(),
                frame: IDENTITY4,
                aabb: b,
                footprint: None,
                turn: 0.0,
            });
        }
        let extent = median_box_size(&instances);
        let class = Class { words: vec![0], centre_word: 0, extent, instances, cluster: 0 };
        let segments = vec![Some(0); points.len()];
        (points, segments, vec![class])
    }

    /// One class holding the blocks `kinds` (true: a crate, false: a drum), each scaled by up to
    /// 4% ([`placed`]).
    fn scene(kinds: &[bool]) -> (Vec<Point3>, Vec<Option<u32>>, Vec<Class>) {
        let blocks: Vec<Vec<Point3>> = kinds
            .iter()
            .enumerate()
            .map(|(k, &is_crate)| {
                let s = scale_of(k);
                if is_crate { crate_points([1.2 * s, 0.8, 0.6 * s]) } else { drum_points(0.45 * s, 1.0) }
            })
            .collect();
        placed(&blocks, [0.7, 0.3])
    }

    fn run(kinds: &[bool], o: &ShapeSplitOptions) -> (Vec<Class>, ShapeSplitReport) {
        let (points, segments, mut classes) = scene(kinds);
        let hash = SpatialHash::new(&points, 8.0 * H);
        let r = split_by_shape(&mut classes, &inputs(&points, &segments, &hash, 0.6, 2.0 * H), o);
        (classes, r)
    }

    /// The kind (crate: true) of each instance of each class, from its box's x position.
    fn kinds_of(classes: &[Class], kinds: &[bool]) -> Vec<Vec<bool>> {
        classes
            .iter()
            .map(|c| c.instances.iter().map(|i| kinds[(i.aabb.center()[0] / 3.0).round() as usize]).collect())
            .collect()
    }

    #[test]
    fn a_class_of_crates_and_drums_is_split_into_crates_and_drums() {
        let kinds = [true, false, false, true, true, false, true, false];
        let (classes, r) = run(&kinds, &ShapeSplitOptions::default());
        assert_eq!((r.classes, r.instances, r.split, r.new_classes), (1, 8, 1, 1), "{r:?}");
        let mut got = kinds_of(&classes, &kinds);
        got.sort();
        assert_eq!(got, vec![vec![false; 4], vec![true; 4]]);
        // The new class copies the words and cluster; boxes are untouched.
        assert_eq!((classes[1].words.clone(), classes[1].cluster), (vec![0], 0));
        // Off, nothing changes.
        let (classes, r) = run(&kinds, &ShapeSplitOptions { enabled: false, ..Default::default() });
        assert_eq!((classes.len(), classes[0].instances.len(), r), (1, 8, ShapeSplitReport::default()));
    }

    /// The class of `run`'s scene spread over classes: block k goes to class `class_of[k]`
    /// (copies of the first's words and cluster 1, 2, ...), and the step run on them.
    fn run_spread(
        kinds: &[bool],
        class_of: &[usize],
        o: &ShapeSplitOptions,
    ) -> (Vec<Class>, ShapeSplitReport) {
        let (points, segments, one) = scene(kinds);
        let count = class_of.iter().max().map_or(0, |c| c + 1);
        let mut classes: Vec<Class> =
            (0..count).map(|c| Class { instances: Vec::new(), cluster: c, ..one[0].clone() }).collect();
        for (inst, &c) in one[0].instances.iter().zip(class_of) {
            classes[c].instances.push(inst.clone());
        }
        let hash = SpatialHash::new(&points, 8.0 * H);
        let r = split_by_shape(&mut classes, &inputs(&points, &segments, &hash, 0.6, 2.0 * H), o);
        (classes, r)
    }

    #[test]
    fn mixed_classes_are_grouped_again_by_kind() {
        // Two classes, each two crates and two drums: two classes, one of each kind.
        let kinds = [true, false, false, true, true, false, true, false];
        let class_of = [0, 0, 0, 0, 1, 1, 1, 1];
        let (classes, r) = run_spread(&kinds, &class_of, &ShapeSplitOptions::default());
        assert_eq!((r.classes, r.instances, r.groups, r.split), (2, 8, 2, 2), "{r:?}");
        let mut got = kinds_of(&classes, &kinds);
        got.sort();
        assert_eq!(got, vec![vec![false; 4], vec![true; 4]]);
        // Each class keeps its cluster: the crates' class is the one that held most crates
        // first (ties: the lower class), the drums go to the other.
        assert_eq!(classes.iter().map(|c| c.cluster).collect::<Vec<_>>(), vec![0, 1]);
        // Class by class (the step's first version), each class of four is too small to split;
        // so too with more free-standing instances in the scene than `max_instances`.
        let per_class = ShapeSplitOptions { across_classes: false, ..Default::default() };
        let too_many = ShapeSplitOptions { max_instances: 7, ..Default::default() };
        for o in [per_class, too_many] {
            let (classes, r) = run_spread(&kinds, &class_of, &o);
            assert_eq!((r.classes, r.split), (0, 0), "{r:?}");
            let got = kinds_of(&classes, &kinds);
            assert_eq!(got, vec![vec![true, false, false, true], vec![true, false, true, false]]);
        }
    }

    #[test]
    fn one_kind_found_as_two_classes_is_one_class() {
        let kinds = [true; 6];
        let (classes, r) = run_spread(&kinds, &[0, 1, 0, 1, 0, 1], &ShapeSplitOptions::default());
        assert_eq!((r.groups, r.moved, r.dropped_classes), (1, 3, 1), "{r:?}");
        assert_eq!((classes.len(), classes[0].instances.len()), (1, 6));
    }

    #[test]
    fn repeats_of_a_block_take_no_part() {
        // Six crates, and a second class holding two of them again: the repeats are not
        // compared (they would cover each other fully and form a group of their own), and stay.
        let (points, segments, mut classes) = scene(&[true; 6]);
        let again = Class { instances: classes[0].instances[..2].to_vec(), cluster: 1, ..classes[0].clone() };
        classes.push(again.clone());
        let hash = SpatialHash::new(&points, 8.0 * H);
        let o = ShapeSplitOptions::default();
        let r = split_by_shape(&mut classes, &inputs(&points, &segments, &hash, 0.6, 2.0 * H), &o);
        assert_eq!((r.classes, r.instances, r.groups, r.moved), (1, 6, 1, 0), "{r:?}");
        assert_eq!((classes.len(), classes[0].instances.len()), (2, 6));
        assert_eq!(classes[1].instances.len(), again.instances.len());
    }

    #[test]
    fn copies_of_one_block_stay_one_class() {
        for kinds in [[true; 8], [false; 8]] {
            let (classes, r) = run(&kinds, &ShapeSplitOptions::default());
            assert_eq!((r.classes, r.split), (1, 0), "{kinds:?}: {r:?}");
            assert_eq!((classes.len(), classes[0].instances.len()), (1, 8));
        }
    }

    #[test]
    fn a_pair_unlike_the_rest_is_no_class_of_its_own() {
        // Two drums among six crates: a community of two joins the crates.
        let kinds = [true, true, false, true, true, false, true, true];
        let (classes, r) = run(&kinds, &ShapeSplitOptions::default());
        assert_eq!((classes.len(), r.split), (1, 0), "{r:?}");
        // With groups of two allowed, they split off.
        let o = ShapeSplitOptions { min_group: 2, min_instances: 4, ..Default::default() };
        let (classes, _) = run(&kinds, &o);
        let mut got = kinds_of(&classes, &kinds);
        got.sort();
        assert_eq!(got, vec![vec![false; 2], vec![true; 6]]);
    }

    /// Points of `mesh` (its vertices, every `step`-th) scaled to a 1.5 m diagonal, standing
    /// on y = 0, centred on x = z = 0.
    fn part_points(mesh: &motif_core::TriMesh, step: usize) -> Vec<Point3> {
        let b = mesh.aabb().expect("a mesh with vertices");
        let s = 1.5 / b.diagonal();
        let c = b.center();
        mesh.positions
            .iter()
            .step_by(step)
            .map(|p| [(p[0] - c[0]) * s, (p[1] - b.min[1]) * s, (p[2] - c[2]) * s])
            .collect()
    }

    #[test]
    fn real_animals_in_one_class_are_split_by_kind() {
        let Some(dir) = motif_core::data::shared_data_dir(std::path::Path::new(env!("CARGO_MANIFEST_DIR")))
        else {
            println!("skipping: no test data (set MOTIF_DATA or put shared/data beside the repository)");
            return;
        };
        let read = |f: &str| motif_core::io::read_mesh(&dir.join(f)).expect("a shared mesh");
        let (bunny, cow) = (read("natural/cgal_bunny00.off"), read("natural/cgal_cow.off"));
        // About two thousand points each, as a block of a 300k-point scene holds.
        let (bunny, cow) = (part_points(&bunny, 18), part_points(&cow, 1));
        let kinds = [true, false, false, true, true, false, true, false];
        let blocks: Vec<Vec<Point3>> = kinds
            .iter()
            .enumerate()
            .map(|(k, &is_bunny)| {
                let s = scale_of(k);
                (if is_bunny { &bunny } else { &cow }).iter().map(|p| p.map(|v| s * v)).collect()
            })
            .collect();
        let (points, segments, mut classes) = placed(&blocks, [0.9, 0.2]);
        let hash = SpatialHash::new(&points, 8.0 * H);
        // Every box stands free (flatness 0.2): a cow is long and narrow. The tolerance is 2ε of
        // the natural benchmark scenes (ε = 0.0012 × their diagonal, about 3 cm).
        let r = split_by_shape(
            &mut classes,
            &inputs(&points, &segments, &hash, 0.2, 0.06),
            &ShapeSplitOptions::default(),
        );
        assert_eq!((r.classes, r.instances, r.split), (1, 8, 1), "{r:?}");
        let mut got = kinds_of(&classes, &kinds);
        got.sort();
        assert_eq!(got, vec![vec![false; 4], vec![true; 4]]);
    }

    #[test]
    fn alike_groups_are_joined_again() {
        let sim = |a: usize, b: usize| {
            if a == b {
                1.0
            } else if (a < 3) == (b < 3) {
                0.95
            } else {
                0.8
            }
        };
        assert_eq!(join_alike(vec![vec![0, 1, 2], vec![3, 4, 5]], &sim, 0.7), vec![vec![0, 1, 2, 3, 4, 5]]);
        assert_eq!(
            join_alike(vec![vec![0, 1, 2], vec![3, 4, 5]], &sim, 0.85),
            vec![vec![0, 1, 2], vec![3, 4, 5]]
        );
    }

    #[test]
    fn options_are_checked() {
        assert!(ShapeSplitOptions::default().validate().is_ok());
        let bad = |o: ShapeSplitOptions| o.validate().unwrap_err().0;
        assert_eq!(
            bad(ShapeSplitOptions { min_instances: 5, ..Default::default() }),
            "extent.shapes.min_instances"
        );
        assert_eq!(bad(ShapeSplitOptions { min_group: 1, ..Default::default() }), "extent.shapes.min_group");
        assert_eq!(
            bad(ShapeSplitOptions { max_instances: 5, ..Default::default() }),
            "extent.shapes.max_instances"
        );
        assert_eq!(
            bad(ShapeSplitOptions { join_similarity: 1.5, ..Default::default() }),
            "extent.shapes.join_similarity"
        );
        assert_eq!(
            bad(ShapeSplitOptions { scale_rank: 0, ..Default::default() }),
            "extent.shapes.scale_rank"
        );
        assert_eq!(
            bad(ShapeSplitOptions { resolution: 0.0, ..Default::default() }),
            "extent.shapes.resolution"
        );
        assert_eq!(
            bad(ShapeSplitOptions { min_points: 2, ..Default::default() }),
            "extent.shapes.min_points"
        );
    }

    #[test]
    fn slabs_are_not_free_standing() {
        assert!(free_standing([1.0, 1.2, 0.9], 0.5));
        assert!(!free_standing([1.2, 1.5, 0.2], 0.5));
    }
}
