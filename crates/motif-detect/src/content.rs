//! Classes refined by what their instances hold (not in the thesis): step 8 of
//! [`crate::extent`], which reassigns instances ([`reassign`]) and then prunes incoherent classes
//! and unlike instances ([`prune`]). Step 9, [`crate::aligned`], reassigns them once more by
//! images drawn at one common scale and compared at the best shift.
//!
//! Why: under strong per-instance variation the sizes of two blocks overlap, and the split and
//! merge by size (extent steps 4–5) mixes them. On hard facades (15% non-rigid variation) the
//! fitted boxes of `window_a` are 1.5–2.3 m tall and those of `window_b` 1.8–3.1 m; a class by
//! size holds both, and `window_c` (whose shutters lie flat on the wall, so its box is a
//! `window_a`'s) goes with them. What tells them apart is what the box holds: one transom or
//! two, a cornice above, shutters beside. So each instance gets a *depth image* of its
//! surroundings, and instances move to the class whose depth images theirs resembles.
//!
//! # Descriptor
//! Over the two axes other than the class's thinnest (a facade element's depth), a window
//! centred on the instance's box and [`ContentOptions::window`] times its size is cut into
//! [`ContentOptions::grid`]² cells. Along the thin axis the window is the same multiple of the
//! box's own thickness: it holds the block's slab (the wall, the recess, the bars), not what
//! stands in front of it (a balcony in front of a window, a parked car, clutter), which would
//! otherwise make a window behind a balcony look like the balcony. Every resampled point in the
//! window adds its depth — its coordinate along the thin axis minus the median of the window's
//! points, which is the wall — to the four cells around it with bilinear weights. A cell holds
//! the weighted mean depth in ε and a confidence Σw / (Σw + 1): a cell that occlusion left
//! empty has confidence 0 and says nothing, instead of saying "wall".
//!
//! The grid is stretched to each instance's own box, so an instance 15% wider than the others
//! still has its mullion in the middle cell; the margin beyond the box sees shutters and
//! cornices that the box left out. Values and confidences move continuously with the points: a
//! quarter turn of the input rounds coordinates differently, and a cell boundary must not turn
//! that into a different class (the invariance test of `tests/detect.rs`). A turn or mirror of
//! the input permutes or negates the cells of every instance alike, which leaves the distances
//! alone.
//!
//! # Distance and reassignment
//! d(a, b) = Σ cₐ c_b |a − b| / Σ cₐ c_b over cells (depths in ε, c the confidences) +
//! [`ContentOptions::size_weight`] × the Chebyshev distance of the two log sizes. Starting from
//! the classes of the earlier steps, Lloyd iterations (k-medians): each class's per-cell median
//! depth and confidence and per-axis median log size, then each instance joins the nearest
//! class (ties: the lower class index) among the classes of its thin axis that have at least
//! two instances, if that class is clearly nearer than its own ([`ContentOptions::margin`]);
//! up to [`ContentOptions::rounds`] rounds, or until no instance moves. Two rules keep it from
//! undoing what the earlier steps got right:
//! - An instance never joins a class that holds its block: another instance whose box it
//!   overlaps by the [`crate::instances::InstanceOptions::merge_overlap`] test. A window behind
//!   a balcony is found by the window class and, through the balcony, by a balcony class; had
//!   it joined the balcony class it would have been dropped there as a repeat, and the window
//!   class would have lost it (on easy facade seed 1 recall fell from 1 to 0.85 before this
//!   rule). When the nearest class is one that holds its block, the instance stays where it
//!   is rather than going to the next nearest: on easy facade seed 13, boxes of a window grown
//!   with its balcony were nearest the balcony class, and without this they went to the
//!   ground-floor windows' class instead (F 0.963 → 0.841).
//! - Classes whose blocks turn freely about their thin axis (cars at any heading;
//!   `extent::turns_freely`) keep their instances and take none: the grid is not invariant to
//!   the turn.
//!
//! Afterwards an instance that still repeats one of its new class is dropped (instances that
//! were there first win), and so is a class left with fewer than two instances.
//!
//! The start matters: this is a refinement of the classes by size, not a clustering from
//! scratch. A prototype that clustered all instances of a scene by these distances alone
//! (average or complete linkage) scored below the classes by size on hard facades.
//!
//! # Measured
//! A prototype of this step (Python, on the detections of `motif detect --epsilon 0.0012`,
//! hard facade scenes of `motif bench detect --seed 13`, the first six): leave-one-out
//! nearest-neighbour agreement with the ground-truth class was 0.63 by log sizes alone and
//! 0.93 by depth images; the mean F went from 0.688 to 0.720.
//!
//! Variants of this implementation on sixteen scenes (`motif example scene-facade|scene-street
//! --seed S`, detection seed S, `--epsilon 0.0012`: facade hard 13–18, street hard 13–15, and
//! seven others: street medium 7 and 14, facade medium 3 and 8, facade easy 1 and 3, street easy
//! 10), mean F facade hard / street hard / the others:
//! - without the step: 0.681 / 0.629 / 0.898;
//! - a window along the thin axis as deep as it is wide (1.5 half-widths, so a balcony in front
//!   of a window counts), no confidences: 0.693 / 0.622 / 0.853. On facade medium 3 (F 0.923 →
//!   0.769) half the `window_b` class stood behind balconies, its per-cell median fell between
//!   the two kinds, and the other half went to the `window_a` class;
//! - the box's own slab, no confidences: 0.698 / 0.605 / 0.912; with medoids instead of
//!   per-cell medians as class centres: 0.689 / 0.630 / 0.905;
//! - the slab with confidences: 0.699 / 0.605 / 0.916; and staying when the nearest class holds
//!   the block (the default): 0.700 / 0.598 / 0.916, with easy facade 13 at 0.975 instead of
//!   0.841 (module documentation above).
//!
//! `motif bench detect --scenes 12 --no-icp --seed 1|13` (24 scenes per level), EM + SC F
//! without → with the step, and the paired difference: facade easy 0.946 → 0.949 (+0.002
//! ±0.003), medium 0.881 → 0.896 (+0.015 ±0.007), hard 0.677 → 0.696 (+0.019 ±0.008); street
//! easy 0.925 → 0.927 (+0.002 ±0.005), medium 0.804 → 0.812 (+0.008 ±0.004), hard 0.601 →
//! 0.615 (+0.014 ±0.007). On seeds 1–12, which played no part in the design, no level fell by
//! more than 0.005. The version without the block rule had lost 0.040 on easy facades of seeds
//! 13–24. The demo's detection (a medium facade, 200k points) went from F 0.804 to 0.866.
//!
//! # Pruning
//! [`prune`] then looks at each class as a whole, with the same depth images. An instance's
//! *relief* is its confidence-weighted mean |depth|; its *residual* against an image is the cell
//! part of d over that relief: the share of its relief that the image leaves unexplained. A
//! class whose typical instance (the median) keeps more than
//! [`ContentOptions::class_residual`] of its relief against the class's median image does not
//! hold one kind of block. On hard scenes such classes are the clutter boxes (signs, air
//! conditioners of 0.3–0.9 m, sixteen per hard scene) that co-occurrence groups because their
//! corners look alike: the class box, averaged over unlike boxes, frames a different box at a
//! different spot in each instance, and the median image is almost flat wall. Such a class is
//! dropped unless what it does explain, n × (1 − residual), is worth
//! [`ContentOptions::class_explained`] instances or more (a large class mixing two window
//! styles is a real block badly grouped). In the classes that stay, an instance of a class of
//! three or more whose residual against the median of the others exceeds
//! [`ContentOptions::outlier_residual`] (a clutter box or a bare wall patch among windows)
//! leaves the class. Only classes whose depth images are mostly covered
//! ([`ContentOptions::surface_coverage`]) are pruned: around free-standing blocks (bins, lamp
//! posts) the window is mostly empty space and the residual measures nothing.
//!
//! Measured (2026-11-27). A Python prototype on the sixteen scenes above raised the mean F of
//! their hard facades from 0.700 to 0.732 and of their hard streets from 0.598 to 0.615; on
//! eighteen fresh scenes (`motif example`, seeds 1–6 hard facades and streets, 1–3 medium),
//! 0.696 → 0.718 and 0.619 → 0.625; the class test alone gave 0.698 and 0.627 there, so on
//! facades the gain is the outlier test's. This implementation on the sixteen scenes: 0.700 /
//! 0.598 / 0.916 → 0.721 / 0.612 / 0.917 (hard facades / hard streets / the others); before
//! the coverage test it dropped the bins and lamp posts of two street scenes
//! ([`ContentOptions::surface_coverage`]).
//!
//! `motif bench detect --scenes 12 --no-icp --seed 1|13` (24 scenes per level), EM + SC F
//! without → with pruning, and the paired difference: facade easy 0.949 → 0.950 (+0.001
//! ±0.001), medium 0.896 → 0.899 (+0.002 ±0.001), hard 0.696 → 0.711 (+0.015 ±0.003); street
//! easy 0.927 → 0.929 (+0.002 ±0.001), medium 0.812 → 0.814 (+0.002 ±0.001), hard 0.615 →
//! 0.624 (+0.009 ±0.003). No level lost on either half (seeds 1–12 hard: facade +0.014 ±0.004,
//! street +0.007 ±0.004). The demo's detection went from F 0.866 to 0.874 (P 0.855 → 0.870).
//!
//! Splitting a class in two by its depth images (2-medians, kept when the halves' mean residual
//! fell below 0.6–0.8 of the class's) was tried in the prototype and dropped: on the sixteen
//! scenes it gained at most 0.008 on hard facades and cost 0.05–0.07 on the others, splitting
//! real classes whose residuals were already low.
//!
//! A vote by nearest neighbours after the Lloyd rounds was implemented, measured and dropped
//! (2026-11-28): each instance whose image is mostly covered joined the class most of its k
//! nearest instances (by the distance above, same thin axis) and itself belonged to, when that
//! class had more votes than its own, never into a class holding its block. A Python prototype
//! on six hard facades had raised F from 0.711 to 0.740 (k = 3); without the coverage test, hard
//! street 1 lost its lamp posts and its `window_b` class (F 0.632 → 0.494). With it, on the
//! benchmark (`motif bench detect --scenes 12 --no-icp --seed 1|13`, k = 4, paired over the 24
//! scenes per level): facade −0.003 ±0.004 / +0.005 ±0.005 / +0.010 ±0.008 (easy / medium /
//! hard), street −0.003 ±0.005 / +0.004 ±0.003 / +0.012 ±0.009. The hard levels gained about one
//! standard error, the easy ones lost a little, and SC gained more than EM + SC on street medium
//! (lead +0.095 → +0.090).
//!
//! Joining whole classes whose depth images look alike was tried and dropped (2026-11-28). On
//! hard facades a block is often split over two classes (`window_a` as 8 + 4 instances on seed
//! 1), so a class-level merge after the Lloyd rounds looked promising: join two classes of one
//! thin axis, closest first, when the distance between their medians is below a ratio times the
//! mean of their median member-to-median distances, and not when more than half the smaller
//! one's boxes repeat the other's. On the hard scenes of seeds 1–6 (`motif example
//! scene-facade|scene-street --difficulty hard --seed S`, `motif detect --epsilon 0.0012`),
//! mean F facade / street: without 0.709 / 0.666; ratio 1.1: 0.713 / 0.662; 1.5: 0.661 / 0.680;
//! 2.0: 0.634 / 0.677; with the size term weighted 6 or 12 instead of 2 (ratios 1.3, 1.45):
//! 0.708 / 0.671 and 0.714 / 0.671. Recall rose as much as precision fell (facade at 1.5: R
//! 0.709 → 0.828, P 0.718 → 0.561): the medians of `window_a` and `window_c` classes lie as
//! close as those of two halves of one style. In the same runs a grid of 7 or 16 cells and a
//! window of 1.8 box sizes gave 0.691 / 0.651, 0.715 / 0.649 and 0.678 / 0.645.
//! `motif eval --per-class` on those runs says where the loss is: the detected boxes locate
//! 92.2% of the annotated blocks (no grouping of them scores F above 0.958), and most of the gap
//! from 0.709 is window styles mixed within classes (of 74 `window_b`, 70 located, 27 of them in
//! classes credited to another style), which a merge of whole classes leaves mixed.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use motif_core::Point3;
use motif_core::geometry::Aabb;

use crate::extent::{median, median_box_size, thinnest, turns_freely};
use crate::grid::SpatialHash;
use crate::instances::{Class, Instance, overlaps_any};

/// Options of the reassignment by content (module documentation). Not in the thesis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ContentOptions {
    /// Whether the step runs. Default true.
    pub enabled: bool,
    /// Cells per axis of the depth image. 10: cells of about 0.25 m on a facade's windows, finer
    /// than a transom's spacing, coarse enough that 15% variation moves a part by at most about
    /// one cell at the window's edge. Default 10.
    pub grid: usize,
    /// The depth image's window, as a multiple of the instance's box size on each axis, the thin
    /// one included. 1.5: a quarter of the box beyond each side, where shutters and cornices lie
    /// when the box left them out. Default 1.5.
    pub window: f64,
    /// Weight of the log-size distance, in ε per unit of log size. The Python prototype weighed
    /// 0.1 m per unit (with ε = 4.4 cm, about 2.3ε): sizes alone mixed the styles, depth images
    /// alone (weight 0) lost the classes whose depth images look alike but whose sizes differ
    /// (its mean F on six hard facades was 0.670 without the size term, 0.720 with it, 0.700
    /// with three times as much). In this implementation's first version, weights 1 / 2 / 4 gave
    /// a mean F of 0.706 / 0.716 / 0.701 over the ten scenes named under [`Self::margin`].
    /// Default 2.
    pub size_weight: f64,
    /// An instance leaves its class only for a class at most `1 − margin` times as far as its own
    /// (hysteresis, so that near ties do not churn). Measured with this implementation's first
    /// version (a window reaching 1.5 half-widths along the thin axis, no rule against joining
    /// a class that holds the block) on ten scenes of `motif bench detect --seed 13` (facade hard
    /// 13–18, street hard 13–15, street medium 14, detection seed 1): mean F 0.709 with no
    /// margin, 0.716 with 0.1, 0.711 with 0.2; without it, on hard street seed 14, five
    /// `window_b` that a balcony or a car partly hid joined a class of the other styles. Default
    /// 0.1.
    pub margin: f64,
    /// Most Lloyd rounds. Default 5.
    pub rounds: usize,
    /// Pruning (module documentation): a class whose typical instance keeps more than this share
    /// of its relief after the class's median image is taken away is *incoherent*. Window and
    /// balcony classes measured 0.1–0.6 on the sixteen scenes named in the module documentation
    /// (in a Python prototype of this step), classes of clutter boxes (unlike sizes, so their
    /// median is nearly flat wall) 0.65–0.87; in this implementation one clutter class of hard
    /// facade seed 13 measured 0.75. Mean F over those scenes' hard facades with 0.65 / 0.7 /
    /// 0.75: 0.725 / 0.729 / 0.721, but on the benchmark (`motif bench detect --scenes 12 --no-icp
    /// --seed 1|13`, 24 scenes per level) 0.7 gained less on hard streets than 0.75 (paired with
    /// the step's reassignment alone: +0.003 ±0.006 against +0.009 ±0.003; hard facades +0.017
    /// ±0.004 against +0.015 ±0.003). Default 0.75.
    pub class_residual: f64,
    /// An incoherent class is dropped only when the relief it explains, n × (1 − residual) for
    /// its n described instances, is worth fewer than this many instances: a class of twenty
    /// that mixes two window styles (residual 0.71 on hard street seed 15) is a real block
    /// badly grouped, and dropping it would lose most of the scene's windows. Default 3.
    pub class_explained: f64,
    /// Pruning: an instance of a class of three or more is dropped when the median image of the
    /// class's other instances leaves more than this multiple of its own relief (it is a wall
    /// patch, a clutter box or another block that joined the class). With 1.0 occluded windows
    /// went too on easy scenes (easy facade seed 1 F 0.932 → 0.855, easy street seed 10 0.955 →
    /// 0.892); 1.15, 1.2, 1.3 and 1.5 gave mean F within 0.005 of each other on the sixteen
    /// scenes' hard facades (0.734 / 0.732 / 0.729 / 0.732) and their other levels, and on
    /// eighteen fresh scenes (hard facades and streets of seeds 1–6, medium of seeds 1–3). 1.3
    /// stays well clear of where easy scenes lose. Default 1.3.
    pub outlier_residual: f64,
    /// Pruning looks only at classes whose depth images are mostly covered: the median share of
    /// cells with confidence above 1/2 is at least this. Blocks on a wall measured 0.79–1.00 on
    /// the sixteen scenes (hard streets, where one scanner leaves shadows, included); bins and
    /// lamp posts standing free 0.50–0.63, and their residuals (0.8–0.9) measure empty space,
    /// not a block (street medium seed 7 lost its bins and lamp posts, F 0.856 → 0.741, before
    /// this test). Default 0.75.
    pub surface_coverage: f64,
}

impl Default for ContentOptions {
    fn default() -> Self {
        ContentOptions {
            enabled: true,
            grid: 10,
            window: 1.5,
            size_weight: 2.0,
            margin: 0.1,
            rounds: 5,
            class_residual: 0.75,
            class_explained: 3.0,
            outlier_residual: 1.3,
            surface_coverage: 0.75,
        }
    }
}

/// One instance's depth image and log sizes on the two axes other than its class's thinnest.
#[derive(Debug, Clone, PartialEq)]
pub struct Descriptor {
    /// `grid × grid` cell values, depth in ε, row-major over the two axes in ascending order.
    pub cells: Vec<f64>,
    /// Per cell, how much the cell's value is to be trusted, in [0, 1): Σw / (Σw + 1).
    pub confidence: Vec<f64>,
    /// ln of the box size on those axes.
    pub log_size: [f64; 2],
}

/// The two axes other than `thin`, ascending.
pub(crate) fn plane_axes(thin: usize) -> [usize; 2] {
    let (a, b) = ((thin + 1) % 3, (thin + 2) % 3);
    [a.min(b), a.max(b)]
}

/// The depth image of the box `b` (module documentation) over the resampled `points` indexed by
/// `hash`; `None` when the box is flat along one of the plane's axes or its window holds no
/// point.
pub fn describe(
    b: &Aabb,
    thin: usize,
    points: &[Point3],
    hash: &SpatialHash,
    eps: f64,
    o: &ContentOptions,
) -> Option<Descriptor> {
    let [a0, a1] = plane_axes(thin);
    let (c, e) = (b.center(), b.extent());
    if !(e[a0] > 0.0 && e[a1] > 0.0) || o.grid == 0 {
        return None;
    }
    let h = [0.5 * o.window * e[a0], 0.5 * o.window * e[a1]];
    let (cells, confidence) = depth_image(c, h, 0.5 * o.window * e[thin], o.grid, thin, points, hash, eps)?;
    Some(Descriptor { cells, confidence, log_size: [e[a0].ln(), e[a1].ln()] })
}

/// The `n × n` depth image (values in ε, confidences) of the window of half-sizes `h` over the
/// plane axes and `ht` along `thin`, centred on `c` (module documentation: depths from the
/// median of the window's points, bilinear weights, confidence Σw / (Σw + 1)); `None` when the
/// window holds no point. Also used by [`crate::aligned`].
#[allow(clippy::too_many_arguments)]
pub(crate) fn depth_image(
    c: Point3,
    h: [f64; 2],
    ht: f64,
    n: usize,
    thin: usize,
    points: &[Point3],
    hash: &SpatialHash,
    eps: f64,
) -> Option<(Vec<f64>, Vec<f64>)> {
    let [a0, a1] = plane_axes(thin);
    let radius = (h[0] * h[0] + h[1] * h[1] + ht * ht).sqrt();
    // (u, v, coordinate along thin) of the points in the window.
    let mut inside: Vec<(f64, f64, f64)> = Vec::new();
    hash.for_each_within(c, radius, |i, _| {
        let p = points[i];
        let (du, dv, dt) = (p[a0] - c[a0], p[a1] - c[a1], p[thin] - c[thin]);
        if du.abs() <= h[0] && dv.abs() <= h[1] && dt.abs() <= ht {
            inside.push((du, dv, p[thin]));
        }
    });
    if inside.is_empty() || n == 0 {
        return None;
    }
    let wall = median(inside.iter().map(|q| q.2).collect());
    let (mut sw, mut sd) = (vec![0.0; n * n], vec![0.0; n * n]);
    let scale = n as f64;
    for &(du, dv, t) in &inside {
        // Cell-centre coordinates: cell k's centre is at k.
        let u = (du + h[0]) / (2.0 * h[0]) * scale - 0.5;
        let v = (dv + h[1]) / (2.0 * h[1]) * scale - 0.5;
        let d = (t - wall) / eps;
        let (i0, j0) = (u.floor(), v.floor());
        let (fu, fv) = (u - i0, v - j0);
        for (di, wu) in [(0, 1.0 - fu), (1, fu)] {
            let i = i0 as i64 + di;
            if i < 0 || i >= n as i64 {
                continue;
            }
            for (dj, wv) in [(0, 1.0 - fv), (1, fv)] {
                let j = j0 as i64 + dj;
                if j < 0 || j >= n as i64 {
                    continue;
                }
                let k = i as usize * n + j as usize;
                let w = wu * wv;
                sw[k] += w;
                sd[k] += w * d;
            }
        }
    }
    let cells = sd.iter().zip(&sw).map(|(d, w)| if *w > 0.0 { d / w } else { 0.0 }).collect();
    let confidence = sw.iter().map(|w| w / (w + 1.0)).collect();
    Some((cells, confidence))
}

/// d(a, b) of the module documentation.
pub fn distance(a: &Descriptor, b: &Descriptor, size_weight: f64) -> f64 {
    let (mut sum, mut weight) = (0.0, 0.0);
    for k in 0..a.cells.len() {
        let w = a.confidence[k] * b.confidence[k];
        sum += w * (a.cells[k] - b.cells[k]).abs();
        weight += w;
    }
    let cells = if weight > 0.0 { sum / weight } else { 0.0 };
    let size = (a.log_size[0] - b.log_size[0]).abs().max((a.log_size[1] - b.log_size[1]).abs());
    cells + size_weight * size
}

/// The per-cell and per-axis median of `members`.
fn centre(members: &[&Descriptor]) -> Descriptor {
    let cells =
        (0..members[0].cells.len()).map(|k| median(members.iter().map(|d| d.cells[k]).collect())).collect();
    let confidence = (0..members[0].cells.len())
        .map(|k| median(members.iter().map(|d| d.confidence[k]).collect()))
        .collect();
    let log_size = [0, 1].map(|k| median(members.iter().map(|d| d.log_size[k]).collect()));
    Descriptor { cells, confidence, log_size }
}

/// What the reassignment did, for reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ContentReport {
    /// Instances given a depth image.
    pub described: usize,
    /// Instances that changed class.
    pub moved: usize,
    /// Lloyd rounds run.
    pub rounds: usize,
    /// Instances dropped as repeats within their new class.
    pub duplicates: usize,
    /// Classes left with fewer than two instances and dropped.
    pub dropped_classes: usize,
    /// Pruning: classes dropped as incoherent.
    pub incoherent_classes: usize,
    /// Pruning: instances dropped as outliers of their class.
    pub outliers: usize,
}

/// Per class: its thin axis ([`thinnest`]), or `None` when its blocks turn freely (their depth
/// images mean nothing) or it has no instance.
pub(crate) fn thin_axes(classes: &[Class]) -> Vec<Option<usize>> {
    classes
        .iter()
        .map(|c| (!c.instances.is_empty() && !turns_freely(&c.instances)).then(|| thinnest(&c.instances)))
        .collect()
}

/// Reassigns the instances of `classes` by content (module documentation). `points` are the
/// resampled points, indexed by `hash`; `eps` is ε; `merge_overlap` is
/// [`crate::instances::InstanceOptions::merge_overlap`]. Classes come back in their order,
/// without those dropped; extents are recomputed.
pub fn reassign(
    classes: &mut Vec<Class>,
    points: &[Point3],
    hash: &SpatialHash,
    eps: f64,
    merge_overlap: f64,
    o: &ContentOptions,
) -> ContentReport {
    let mut report = ContentReport::default();
    if !o.enabled || classes.len() < 2 {
        return report;
    }
    let thin = thin_axes(classes);
    // (class, instance) of every instance that takes part, and its descriptor.
    let items: Vec<(usize, usize)> = classes
        .iter()
        .enumerate()
        .filter(|(ci, _)| thin[*ci].is_some())
        .flat_map(|(ci, c)| (0..c.instances.len()).map(move |k| (ci, k)))
        .collect();
    let described: Vec<Option<Descriptor>> = items
        .par_iter()
        .map(|&(ci, k)| describe(&classes[ci].instances[k].aabb, thin[ci]?, points, hash, eps, o))
        .collect();
    let (items, descs): (Vec<(usize, usize)>, Vec<Descriptor>) =
        items.into_iter().zip(described).filter_map(|(it, d)| Some((it, d?))).unzip();
    report.described = items.len();
    let mut label: Vec<usize> = items.iter().map(|it| it.0).collect();
    // Pairs of instances that are one block by the merge-overlap test (a window and the balcony
    // in front of it, found by two classes): an instance never joins a class that holds its block.
    let inst = |k: usize| &classes[items[k].0].instances[items[k].1];
    let clash: Vec<Vec<usize>> = (0..items.len())
        .map(|k| {
            (0..items.len())
                .filter(|&j| j != k && overlaps_any(inst(k), std::slice::from_ref(inst(j)), merge_overlap))
                .collect()
        })
        .collect();
    for _ in 0..o.rounds {
        report.rounds += 1;
        let centres: Vec<Option<Descriptor>> = (0..classes.len())
            .map(|ci| {
                let members: Vec<&Descriptor> =
                    label.iter().zip(&descs).filter(|(l, _)| **l == ci).map(|(_, d)| d).collect();
                (members.len() >= 2).then(|| centre(&members))
            })
            .collect();
        let next: Vec<usize> = (0..items.len())
            .into_par_iter()
            .map(|k| {
                let own = thin[items[k].0];
                let mut best: Option<(f64, usize)> = None;
                for (ci, c) in centres.iter().enumerate() {
                    let Some(c) = c else { continue };
                    if thin[ci] != own {
                        continue;
                    }
                    let d = distance(&descs[k], c, o.size_weight);
                    if best.is_none_or(|b| d < b.0) {
                        best = Some((d, ci));
                    }
                }
                // Nearest to a class that holds its block: it is that class's repeat, and stays.
                if best.is_some_and(|(_, ci)| ci != label[k] && clash[k].iter().any(|&j| label[j] == ci)) {
                    return label[k];
                }
                // An instance leaves a class of two or more only for one clearly closer.
                let own = centres[label[k]].as_ref().map(|c| distance(&descs[k], c, o.size_weight));
                match (best, own) {
                    (Some((d, ci)), Some(od)) if d < (1.0 - o.margin) * od => ci,
                    (Some((_, ci)), None) => ci,
                    _ => label[k],
                }
            })
            .collect();
        if next == label {
            break;
        }
        label = next;
    }
    report.moved = label.iter().zip(&items).filter(|(l, it)| **l != it.0).count();
    if report.moved == 0 {
        return report;
    }
    let (duplicates, dropped) = apply_labels(classes, &items, &label, merge_overlap);
    report.duplicates = duplicates;
    report.dropped_classes = dropped;
    report
}

/// Moves instance `items[k]` (class, index) of `classes` to class `label[k]`: each class keeps
/// its instances that stayed, in order, then takes the newcomers in the order of their old
/// classes, except those that repeat one of its instances by the `merge_overlap` test
/// (instances that were there first win). Classes left with fewer than two instances are
/// dropped and extents recomputed. Returns (newcomers dropped as repeats, classes dropped).
pub(crate) fn apply_labels(
    classes: &mut Vec<Class>,
    items: &[(usize, usize)],
    label: &[usize],
    merge_overlap: f64,
) -> (usize, usize) {
    let mut duplicates = 0;
    let mut leaving = vec![Vec::new(); classes.len()];
    let mut arriving: Vec<Vec<Instance>> = vec![Vec::new(); classes.len()];
    for (&(ci, k), &l) in items.iter().zip(label) {
        if l != ci {
            leaving[ci].push(k);
            arriving[l].push(classes[ci].instances[k].clone());
        }
    }
    for (c, gone) in classes.iter_mut().zip(&leaving) {
        let mut k = 0;
        c.instances.retain(|_| {
            k += 1;
            !gone.contains(&(k - 1))
        });
    }
    for (c, new) in classes.iter_mut().zip(arriving) {
        for inst in new {
            if overlaps_any(&inst, &c.instances, merge_overlap) {
                duplicates += 1;
            } else {
                c.instances.push(inst);
            }
        }
    }
    let before = classes.len();
    classes.retain(|c| c.instances.len() >= 2);
    for c in classes.iter_mut() {
        c.extent = median_box_size(&c.instances);
    }
    (duplicates, before - classes.len())
}

/// Share of `x`'s relief that the image `m` leaves: the cell part of [`distance`] over the
/// confidence-weighted mean |depth| of `x`; `None` when `x` has no relief to measure.
fn residual(x: &Descriptor, m: &Descriptor) -> Option<f64> {
    let (mut sum, mut weight) = (0.0, 0.0);
    for (v, c) in x.cells.iter().zip(&x.confidence) {
        sum += c * v.abs();
        weight += c;
    }
    let relief = if weight > 0.0 { sum / weight } else { 0.0 };
    (relief > 0.0).then(|| distance(x, m, 0.0) / relief)
}

/// Share of `d`'s cells with confidence above 1/2 (weight above 1: at least a point's worth).
fn coverage(d: &Descriptor) -> f64 {
    d.confidence.iter().filter(|c| **c > 0.5).count() as f64 / d.confidence.len() as f64
}

/// Pruning (module documentation): drops incoherent classes and the instances that do not
/// look like the rest of their class. Runs over the classes as they are after [`reassign`];
/// classes of freely turning blocks are left alone. Adds to `report`; extents are recomputed.
pub fn prune(
    classes: &mut Vec<Class>,
    points: &[Point3],
    hash: &SpatialHash,
    eps: f64,
    o: &ContentOptions,
    report: &mut ContentReport,
) {
    if !o.enabled {
        return;
    }
    // Per class: whether it stays, and the instances it drops.
    let verdicts: Vec<(bool, Vec<usize>)> = classes
        .par_iter()
        .map(|c| {
            if c.instances.is_empty() || turns_freely(&c.instances) {
                return (true, Vec::new());
            }
            let thin = thinnest(&c.instances);
            let (ks, descs): (Vec<usize>, Vec<Descriptor>) = c
                .instances
                .iter()
                .enumerate()
                .filter_map(|(k, inst)| Some((k, describe(&inst.aabb, thin, points, hash, eps, o)?)))
                .unzip();
            if descs.len() < 2 {
                return (true, Vec::new());
            }
            // Free-standing blocks (bins, lamp posts): the window around them is mostly empty
            // space, the median is no wall, and the residual says nothing.
            if median(descs.iter().map(coverage).collect()) < o.surface_coverage {
                return (true, Vec::new());
            }
            let all: Vec<&Descriptor> = descs.iter().collect();
            let m = centre(&all);
            let r: Vec<f64> = descs.iter().filter_map(|d| residual(d, &m)).collect();
            if !r.is_empty() {
                let r = median(r);
                if r > o.class_residual && descs.len() as f64 * (1.0 - r) < o.class_explained {
                    return (false, Vec::new());
                }
            }
            if descs.len() < 3 {
                return (true, Vec::new());
            }
            let out = (0..descs.len())
                .filter(|&j| {
                    let others: Vec<&Descriptor> =
                        descs.iter().enumerate().filter(|(i, _)| *i != j).map(|(_, d)| d).collect();
                    residual(&descs[j], &centre(&others)).is_none_or(|r| r > o.outlier_residual)
                })
                .map(|j| ks[j])
                .collect();
            (true, out)
        })
        .collect();
    let mut k = 0;
    classes.retain_mut(|c| {
        let (keep, out) = &verdicts[k];
        k += 1;
        if !keep {
            report.incoherent_classes += 1;
            return false;
        }
        report.outliers += out.len();
        let mut i = 0;
        c.instances.retain(|_| {
            i += 1;
            !out.contains(&(i - 1))
        });
        if c.instances.len() < 2 {
            report.dropped_classes += 1;
            return false;
        }
        c.extent = median_box_size(&c.instances);
        true
    });
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Grid spacing of the test walls, and ε.
    pub(crate) const H: f64 = 0.04;

    /// A window of the test wall: centre x, its scale on x and y, and its style (true: two
    /// transoms, a mullion and a cornice above; false: one transom and a sill below).
    pub(crate) type Window = (f64, f64, f64, bool);

    /// The box of `w`: its 1.2 × 1.6 m opening times its scale, centred at (x, 1.5), from the
    /// back of its recess to the front of its cornice or sill.
    pub(crate) fn opening(w: &Window) -> Aabb {
        let (x, sx, sy, _) = *w;
        let (hw, hh) = (0.6 * sx, 0.8 * sy);
        Aabb { min: [x - hw, 1.5 - hh, -0.2], max: [x + hw, 1.5 + hh, 0.15] }
    }

    /// A wall in z = 0 sampled every [`H`] as a height field: the `windows` recessed 0.2 m,
    /// their bars 0.1 m behind the wall, cornices and sills 0.15 m in front of it.
    fn wall(windows: &[Window]) -> Vec<Point3> {
        occluded_wall(windows, &[])
    }

    /// [`wall`] without its points inside the x–y rectangles `holes` (occlusion).
    fn occluded_wall(windows: &[Window], holes: &[Aabb]) -> Vec<Point3> {
        let mut out = Vec::new();
        let (nx, ny) = ((windows.len() as f64 * 3.0 / H) as usize, (3.0 / H) as usize);
        for i in 0..=nx {
            for j in 0..=ny {
                let (x, y) = (i as f64 * H, j as f64 * H);
                if holes.iter().any(|b| x >= b.min[0] && x <= b.max[0] && y >= b.min[1] && y <= b.max[1]) {
                    continue;
                }
                let mut z = 0.0;
                for w in windows {
                    let b = opening(w);
                    let (x0, x1, y0, y1) = (b.min[0], b.max[0], b.min[1], b.max[1]);
                    // Cornice (two transoms) or sill (one), beside the opening's top or bottom.
                    let ledge = if w.3 { y > y1 && y <= y1 + 0.15 } else { y < y0 && y >= y0 - 0.1 };
                    if ledge && x >= x0 - 0.15 && x <= x1 + 0.15 {
                        z = 0.15;
                    }
                    if x < x0 || x > x1 || y < y0 || y > y1 {
                        continue;
                    }
                    let (u, v) = ((x - x0) / (x1 - x0), (y - y0) / (y1 - y0));
                    let near = |t: f64, at: f64, half: f64| (t - at).abs() <= half;
                    let bar = if w.3 {
                        near(v, 0.3, 0.04) || near(v, 0.7, 0.04) || near(u, 0.5, 0.05)
                    } else {
                        near(v, 0.65, 0.04)
                    };
                    z = if bar { -0.1 } else { -0.2 };
                }
                out.push([x, y, z]);
            }
        }
        out
    }

    fn instance(k: usize, aabb: Aabb, turn: f64) -> Instance {
        crate::instances::test_instance(k, aabb, None, turn)
    }

    /// The windows of styles `two_bars` ([`windows`]), their wall and its spatial hash.
    fn scene(two_bars: [bool; 8]) -> (Vec<Window>, Vec<Point3>, SpatialHash) {
        styled_scene(two_bars, |_| (1.0, 1.0), 0.15)
    }

    /// Eight windows 3 m apart, sizes varied by up to 15% per axis; styles as `two_bars`.
    fn windows(two_bars: [bool; 8]) -> Vec<Window> {
        styled_windows(two_bars, |_| (1.0, 1.0), 0.15)
    }

    /// Eight windows 3 m apart, styles as `two_bars`, window k of style s scaled by `size(s)`
    /// (x, y) times a variation of up to `amplitude` per axis.
    pub(crate) fn styled_windows(
        two_bars: [bool; 8],
        size: impl Fn(bool) -> (f64, f64),
        amplitude: f64,
    ) -> Vec<Window> {
        (0..8)
            .map(|k| {
                let t = k as f64;
                let (sx, sy) = size(two_bars[k]);
                let (vx, vy) = (1.0 + amplitude * (1.3 * t).sin(), 1.0 + amplitude * (2.1 * t + 0.5).cos());
                (1.5 + 3.0 * t, sx * vx, sy * vy, two_bars[k])
            })
            .collect()
    }

    /// [`styled_windows`], their wall and its spatial hash.
    pub(crate) fn styled_scene(
        two_bars: [bool; 8],
        size: impl Fn(bool) -> (f64, f64),
        amplitude: f64,
    ) -> (Vec<Window>, Vec<Point3>, SpatialHash) {
        let ws = styled_windows(two_bars, size, amplitude);
        let pts = wall(&ws);
        let hash = SpatialHash::new(&pts, 8.0 * H);
        (ws, pts, hash)
    }

    pub(crate) fn class_of(ws: &[Window], members: &[usize], word: usize, turn: f64) -> Class {
        let instances = members.iter().map(|&k| instance(k, opening(&ws[k]), turn)).collect();
        Class { words: vec![word], centre_word: word, extent: [1.2, 1.6, 0.2], instances, cluster: word }
    }

    #[test]
    fn depth_images_tell_styles_apart_where_sizes_do_not() {
        let (ws, pts, hash) = scene([false, false, true, true, false, true, false, true]);
        let o = ContentOptions::default();
        let d: Vec<Descriptor> =
            ws.iter().map(|w| describe(&opening(w), 2, &pts, &hash, H, &o).expect("described")).collect();
        // Every window is nearer (by depth image alone) to each window of its style than to any
        // of the other style, although sizes vary by 15% within a style.
        for a in 0..8 {
            let same = (0..8).filter(|&b| b != a && ws[b].3 == ws[a].3).map(|b| distance(&d[a], &d[b], 0.0));
            let other = (0..8).filter(|&b| ws[b].3 != ws[a].3).map(|b| distance(&d[a], &d[b], 0.0));
            let (far_same, near_other) = (same.fold(0.0, f64::max), other.fold(f64::INFINITY, f64::min));
            assert!(
                far_same < near_other,
                "window {a}: same style up to {far_same:.3}, other from {near_other:.3}"
            );
        }
        // Sizes alone do not separate them: some window is nearer in size to the other style.
        let size = |a: usize, b: usize| distance(&d[a], &d[b], 1.0) - distance(&d[a], &d[b], 0.0);
        let mixed = (0..8).any(|a| {
            let nearest =
                (0..8).filter(|&b| b != a).min_by(|&x, &y| size(a, x).total_cmp(&size(a, y))).unwrap();
            ws[nearest].3 != ws[a].3
        });
        assert!(mixed, "the test's sizes should not separate the styles");
    }

    #[test]
    fn instances_move_to_the_class_of_their_style() {
        // Class 0 holds three one-transom windows and a two-transom one, class 1 the reverse.
        let (ws, pts, hash) = scene([false, false, false, true, true, true, true, false]);
        let mut classes = vec![class_of(&ws, &[0, 1, 2, 3], 0, 0.0), class_of(&ws, &[4, 5, 6, 7], 1, 0.0)];
        let r = reassign(&mut classes, &pts, &hash, H, 0.5, &ContentOptions::default());
        assert_eq!((r.described, r.moved, r.duplicates, r.dropped_classes), (8, 2, 0, 0), "{r:?}");
        for c in &classes {
            let styles: Vec<bool> = c.instances.iter().map(|i| ws[i.centre].3).collect();
            assert!(styles.iter().all(|&s| s == styles[0]), "mixed class: {styles:?}");
        }
        let mut members: Vec<Vec<usize>> =
            classes.iter().map(|c| c.instances.iter().map(|i| i.centre).collect()).collect();
        members.iter_mut().for_each(|m| m.sort_unstable());
        assert_eq!(members, vec![vec![0, 1, 2, 7], vec![3, 4, 5, 6]]);
        // Switched off, nothing changes.
        let mut off = vec![class_of(&ws, &[0, 1, 2, 3], 0, 0.0), class_of(&ws, &[4, 5, 6, 7], 1, 0.0)];
        let o = ContentOptions { enabled: false, ..Default::default() };
        assert_eq!(reassign(&mut off, &pts, &hash, H, 0.5, &o), ContentReport::default());
        assert_eq!(off[0].instances.len(), 4);
    }

    #[test]
    fn classes_of_freely_turned_blocks_neither_give_nor_take() {
        let (ws, pts, hash) = scene([false, false, false, true, true, true, true, false]);
        // Class 1's blocks are turned by 0.5 rad (cars at any heading): its depth images mean
        // nothing, so class 0's odd window has no class to go to, and class 1 keeps its own.
        let mut classes = vec![class_of(&ws, &[0, 1, 2, 3], 0, 0.0), class_of(&ws, &[4, 5, 6, 7], 1, 0.5)];
        let r = reassign(&mut classes, &pts, &hash, H, 0.5, &ContentOptions::default());
        assert_eq!((r.described, r.moved), (4, 0), "{r:?}");
        let ids = |c: &Class| c.instances.iter().map(|i| i.centre).collect::<Vec<_>>();
        assert_eq!((ids(&classes[0]), ids(&classes[1])), (vec![0, 1, 2, 3], vec![4, 5, 6, 7]));
    }

    #[test]
    fn occluded_instances_still_join_their_style() {
        // As above, but the two misplaced windows lose the left 40% of their surroundings, wall
        // included, to occlusion: empty cells carry no weight instead of reading as wall.
        let ws = windows([false, false, false, true, true, true, true, false]);
        let hole = |w: &Window| {
            let b = opening(w);
            let (x0, half) = (b.center()[0] - 0.75 * (b.max[0] - b.min[0]), 0.75 * (b.max[1] - b.min[1]));
            Aabb { min: [x0, 1.5 - half, -1.0], max: [x0 + 0.6 * (b.max[0] - b.min[0]), 1.5 + half, 1.0] }
        };
        let pts = occluded_wall(&ws, &[hole(&ws[3]), hole(&ws[7])]);
        let hash = SpatialHash::new(&pts, 8.0 * H);
        let mut classes = vec![class_of(&ws, &[0, 1, 2, 3], 0, 0.0), class_of(&ws, &[4, 5, 6, 7], 1, 0.0)];
        let r = reassign(&mut classes, &pts, &hash, H, 0.5, &ContentOptions::default());
        assert_eq!(r.moved, 2, "{r:?}");
        for c in &classes {
            let styles: Vec<bool> = c.instances.iter().map(|i| ws[i.centre].3).collect();
            assert!(styles.iter().all(|&s| s == styles[0]), "mixed class: {styles:?}");
        }
    }

    #[test]
    fn an_instance_does_not_join_a_class_that_holds_its_block() {
        // Window 3 (two transoms) sits in the one-transom class; the two-transom class also holds
        // a box in front of window 3 (a balcony found with it) that overlaps it by 71%. Moving
        // there would make window 3 a repeat of that box, so it stays.
        let (ws, pts, hash) = scene([false, false, false, true, true, true, true, false]);
        let front = {
            let b = opening(&ws[3]);
            instance(9, Aabb { min: [b.min[0], b.min[1], -0.1], max: [b.max[0], b.max[1], 1.0] }, 0.0)
        };
        let mut with_front = class_of(&ws, &[4, 5, 6], 1, 0.0);
        with_front.instances.push(front);
        let mut classes = vec![class_of(&ws, &[0, 1, 2, 3], 0, 0.0), with_front];
        let r = reassign(&mut classes, &pts, &hash, H, 0.5, &ContentOptions::default());
        assert_eq!((r.moved, r.duplicates), (0, 0), "{r:?}");
        let ids = |c: &Class| c.instances.iter().map(|i| i.centre).collect::<Vec<_>>();
        assert_eq!((ids(&classes[0]), ids(&classes[1])), (vec![0, 1, 2, 3], vec![4, 5, 6, 9]));
    }

    /// Five boxes of unlike sizes, each 0.2 m proud of the wall between two windows of
    /// [`windows`] (x = 3, 6, ..., 15) and off that spot by a different amount: (x0, x1, y0, y1).
    fn clutter() -> Vec<[f64; 4]> {
        let size = [(0.3, 0.6), (0.9, 0.3), (0.5, 0.7), (0.8, 0.4), (0.4, 0.35)];
        let off = [(-0.2, 0.25), (0.15, -0.3), (0.0, 0.0), (-0.1, 0.3), (0.2, -0.25)];
        (0..5)
            .map(|k| {
                let (x, y) = (3.0 * (k + 1) as f64 + off[k].0, 1.5 + off[k].1);
                let (hw, hh) = (0.5 * size[k].0, 0.5 * size[k].1);
                [x - hw, x + hw, y - hh, y + hh]
            })
            .collect()
    }

    /// The points of [`wall`] with the [`clutter`] boxes on it, or (`on_wall` false) the boxes'
    /// fronts alone, standing free.
    fn cluttered(ws: &[Window], on_wall: bool) -> Vec<Point3> {
        let boxes = clutter();
        let inside =
            |p: &Point3| boxes.iter().any(|b| p[0] >= b[0] && p[0] <= b[1] && p[1] >= b[2] && p[1] <= b[3]);
        let mut pts = wall(ws);
        for p in pts.iter_mut().filter(|p| inside(p)) {
            p[2] = 0.2;
        }
        if !on_wall {
            pts.retain(|p| inside(p));
        }
        pts
    }

    /// A class whose instances are 1 × 1 m boxes around the [`clutter`] boxes, centred where
    /// they were put before their offsets (as a class box averaged over unlike blocks would be).
    fn clutter_class() -> Class {
        let instances = (0..5)
            .map(|k| {
                let x = 3.0 * (k + 1) as f64;
                instance(10 + k, Aabb { min: [x - 0.5, 1.0, -0.1], max: [x + 0.5, 2.0, 0.3] }, 0.0)
            })
            .collect();
        Class { words: vec![7], centre_word: 7, extent: [1.0, 1.0, 0.4], instances, cluster: 7 }
    }

    #[test]
    fn a_class_of_unlike_boxes_is_dropped_and_a_class_of_windows_kept() {
        let ws = windows([false; 8]);
        let pts = cluttered(&ws, true);
        let hash = SpatialHash::new(&pts, 8.0 * H);
        let mut classes = vec![class_of(&ws, &[0, 1, 2, 3, 4, 5, 6, 7], 0, 0.0), clutter_class()];
        let mut r = ContentReport::default();
        prune(&mut classes, &pts, &hash, H, &ContentOptions::default(), &mut r);
        assert_eq!((r.incoherent_classes, r.outliers, r.dropped_classes), (1, 0, 0), "{r:?}");
        assert_eq!(classes.len(), 1);
        assert_eq!(
            classes[0].instances.iter().map(|i| i.centre).collect::<Vec<_>>(),
            (0..8).collect::<Vec<_>>()
        );
        // With the class test off, the outlier test alone does not remove the boxes' class: the
        // median of five unlike boxes is nearly flat wall, so each box is "explained" about as
        // badly as the others, and some of them stay.
        let mut classes = vec![class_of(&ws, &[0, 1, 2, 3], 0, 0.0), clutter_class()];
        let mut r = ContentReport::default();
        let o = ContentOptions { class_residual: f64::INFINITY, ..Default::default() };
        prune(&mut classes, &pts, &hash, H, &o, &mut r);
        assert_eq!((r.incoherent_classes, r.dropped_classes, classes.len()), (0, 0, 2), "{r:?}");
    }

    #[test]
    fn an_instance_unlike_its_class_is_dropped() {
        let ws = windows([false; 8]);
        let pts = cluttered(&ws, true);
        let hash = SpatialHash::new(&pts, 8.0 * H);
        // Six windows and the box around the third clutter box.
        let mut c = class_of(&ws, &[0, 1, 2, 3, 4, 5], 0, 0.0);
        c.instances.push(clutter_class().instances[2].clone());
        let mut classes = vec![c];
        let mut r = ContentReport::default();
        prune(&mut classes, &pts, &hash, H, &ContentOptions::default(), &mut r);
        assert_eq!((r.incoherent_classes, r.outliers), (0, 1), "{r:?}");
        assert_eq!(classes[0].instances.iter().map(|i| i.centre).collect::<Vec<_>>(), vec![0, 1, 2, 3, 4, 5]);
        // Switched off, nothing changes.
        let mut r = ContentReport::default();
        let mut off = classes.clone();
        off[0].instances.push(clutter_class().instances[2].clone());
        prune(&mut off, &pts, &hash, H, &ContentOptions { enabled: false, ..Default::default() }, &mut r);
        assert_eq!((r, off[0].instances.len()), (ContentReport::default(), 7));
    }

    #[test]
    fn free_standing_blocks_are_not_pruned() {
        // The same unlike boxes without a wall around them: their depth images are mostly
        // empty, the median of a window's points is no wall, and the class is left alone.
        let ws = windows([false; 8]);
        let pts = cluttered(&ws, false);
        let hash = SpatialHash::new(&pts, 8.0 * H);
        let mut classes = vec![clutter_class()];
        let mut r = ContentReport::default();
        prune(&mut classes, &pts, &hash, H, &ContentOptions::default(), &mut r);
        assert_eq!((r, classes[0].instances.len()), (ContentReport::default(), 5));
        // With the coverage test off, it goes.
        let o = ContentOptions { surface_coverage: 0.0, ..Default::default() };
        prune(&mut classes, &pts, &hash, H, &o, &mut r);
        assert!(classes.is_empty(), "{r:?}");
    }
}
