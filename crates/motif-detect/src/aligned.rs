//! Classes formed again by aligned depth images at one common scale (not in the thesis): the
//! extent stage's last step, after [`crate::content`].
//!
//! Why: [`crate::content`] stretches each instance's depth image to the instance's own box, so
//! that 15% variation leaves a mullion in the middle cell. That is right when the boxes are
//! right, but on hard scenes they often are not: of the `window_a` boxes that the detector puts
//! on the hard facades of seeds 1–6, a tenth are about half the window's height (a corner's
//! constellation that no segment grew), and a `window_c` box often leaves its shutters out. A
//! stretched image of half a window looks like no window, and the box's size, which the
//! content step also weighs, says the wrong thing too. Here every instance of one thin axis is
//! pictured at the same scale (metres per cell), and two images are compared at the best of a
//! few relative shifts, as template matching does: a box off by a quarter of a window still
//! finds the window under it, and absolute size (a `window_b`'s cornice 1.3 m above its centre,
//! a `window_a`'s sill 0.8 m below) stays in the picture instead of being stretched away.
//!
//! # Image
//! For the instances whose class has thin axis t (classes of freely turning blocks take no
//! part, as in [`crate::content`]), let S be the median, over those instances, of the larger of
//! their box's two sides across t (a facade element's width or height). Cells are
//! S / [`AlignedOptions::cells_per_block`] wide; the image is [`AlignedOptions::image_cells`]²
//! cells centred on the box's centre; along t it holds the box's slab
//! ([`AlignedOptions::slab`] times the box's thickness), depths from the median of its points,
//! in ε, with confidences, exactly as [`crate::content`] builds its cells.
//!
//! # Distance
//! The central [`AlignedOptions::core_cells`]² cells of a's image against b's image shifted by
//! up to [`AlignedOptions::max_shift`] cells on each axis: the least confidence-weighted mean
//! |difference| over the shifts, and of the two ways round (a's core against b, b's core
//! against a). No size term: the scale is common, so sizes are in the images.
//!
//! # Grouping by communities (the default, [`Grouping::Communities`])
//! The pictured instances are grouped afresh, from their distances alone: a graph with one node
//! per instance and an edge between every two of one thin axis that do not share a block (the
//! [`crate::instances::InstanceOptions::merge_overlap`] test), weighted exp(−d² / (s_a s_b)),
//! where an instance's scale s is its distance to its [`AlignedOptions::scale_rank`]-th
//! nearest instance (the self-tuning affinity of Zelnik-Manor and Perona 2004: each instance
//! measured against its own neighbourhood, so that a tight style and a loose one are both
//! groups); the classes are the graph's communities of highest modularity
//! ([`crate::communities`], resolution [`AlignedOptions::resolution`]). The number of classes
//! is not fixed: a style the earlier steps found as two classes (two constellations of one
//! window) is one community, a class holding two styles is two, and a single class can be
//! split. Each community is hosted by a class it shares instances with, one community per class,
//! the pairs sharing the most instances taken first (so a community may get a class it shares
//! fewer with, when that one went to a larger share); a community no class is left to host
//! becomes a new class, a copy (words, cluster) of the class most of it came from. Instances
//! that take no part stay in their class, also when it hosts no community (then they are the
//! class, and one alone goes with it, below; letting them follow most of their class's
//! pictured members instead lowered hard streets from 0.693 to 0.682, P 0.792 → 0.756, and
//! moved the other levels by at most 0.003, on the scenes of the figures below). A member
//! whose block its class already holds (through a member
//! that takes no part, or another member of the community: such pairs have no edge, but may
//! still share a community) is dropped as a repeat, so a class keeps one box per block. Classes
//! left with fewer than two instances are dropped: a community of one, an instance like no
//! other, goes unless it keeps a class with members that take no part.
//!
//! Communities can also split one style whose copies vary: on the test wall of this module's
//! tests, five two-transom windows varied by up to 10% per axis came out as communities of two
//! and three. On the benchmark the blocks a split or mixed class costs the recall fell on hard
//! facades (68 → 17 of 433, over seeds 1–12) but rose for hard streets' tall windows (35 → 46
//! of 149), where F stayed level.
//!
//! Why not keep correcting the classes (the reassignment below): on hard facades the classes
//! that reach this step are mixed, and split, so the median distance to a class's members is a
//! distance to two kinds, and one style over two classes stays two. The images themselves sort
//! the styles better than the classes do: each instance's nearest neighbour by this distance
//! is of its own style for 93.5% of the instances of hard facades (seeds 1–12) that overlap a
//! block (intersection over union above 0.2; 161 of 164 `window_a`, 158 of 162 `window_b`, 48
//! of 52 `window_c`, 8 of 23 doors), while 19% of the instances the reassignment left (91 of
//! 486) were in a class whose best-matching block was another style.
//!
//! # What stands in front
//! An instance that takes no part (its box is deep, [`AlignedOptions::flatness`]: a balcony, a
//! car, a window whose box grew to what stands before it) is a block in front of the wall, not
//! the wall's relief. Where such a box reaches an image's slab, is not on the pictured
//! instance's own block (the [`crate::instances::InstanceOptions::merge_overlap`] test) and is
//! of typical size for its class (no side above [`AlignedOptions::mask_typical`] times the
//! median of that side over the class's deep boxes: a balcony's box grown down over the ground
//! floor says nothing of what stands there), the image's cells whose centres it covers get
//! confidence 0 ([`AlignedOptions::mask_deep`]; `--no-aligned-mask` keeps them). The distance,
//! a confidence-weighted mean over the cells both images see, then compares a window behind a
//! balcony with a plain one on the rest of their pictures.
//!
//! Without it, on medium streets the tall windows behind balconies (a slab at their sill, posts
//! and rails beside them) were 0.20–0.33 from each other and 0.25–0.50 from plain ones, formed
//! a community of their own, and 42 of the 160 tall windows of seeds 1–12 were credited to no
//! class that recall counts (3 with it). Measured with `motif bench detect --kind
//! scene-street|scene-facade --scenes 12 --no-icp` (seeds 1–12), EM + SC F without → with,
//! easy / medium / hard: streets 0.941 → 0.941, 0.868 → **0.909** (every medium scene equal or
//! higher, by up to 0.095), 0.695 → 0.690; facades 0.953 → 0.963, 0.948 → 0.950, 0.869 →
//! 0.862. SC gains less on medium streets (0.783 → 0.809), so EM + SC's lead there rose from
//! +0.086 to +0.100. The cost is on hard scenes, where the masks also remove what told a tall
//! window from a short one: on hard street 1, with the balconies' cells left out, a short
//! window's nearest image became a tall one behind a balcony and the short windows joined a
//! mixed class (F 0.693 → 0.639); 6 of 12 hard streets are lower, by up to 0.054, 5 higher, by
//! up to 0.117. Tried on hard streets 1 and 8 and medium streets 1 and 4 (F without mask:
//! 0.693, 0.642, 0.912, 0.800): masking every deep box, 0.639, 0.568, 0.990, 0.895; only boxes
//! of typical size (1.25, kept), 0.639, 0.644, and the medium ones as before; at most 1.5 times
//! typical, 0.639, 0.568; only when the mask leaves at least 75% of the image, 0.623, 0.568;
//! weighting covered cells 0.25 instead of 0, 0.647, 0.608, 0.971, 0.895. Over all 12 scenes
//! of each level, every deep box against boxes of typical size: streets medium 0.910 / 0.909,
//! hard 0.684 / 0.690; facades equal.
//!
//! # Reassignment ([`Grouping::Reassign`], `--aligned-grouping reassign`)
//! Each instance in turn (classes in order, instances in order; a move counts at once for the
//! instances after it) joins the class whose other members' distances to it have the least
//! median, among the classes of its thin axis, when that median is below `1 −`
//! [`AlignedOptions::margin`] times the median to the other members of its own class; never a
//! class that holds its block (the rule of [`crate::content`]; a member that takes no part holds
//! its block too), and not when it is alone in
//! its class among the instances pictured. Up to [`AlignedOptions::rounds`] rounds, or until no
//! instance moves; then newcomers that repeat an instance of their class are dropped, and so are
//! classes left with fewer than two instances. Medians of member
//! distances rather than a distance to one median image: the images of two styles, shifted
//! differently, have no meaningful per-cell median.
//!
//! # Measured
//! The images and distances, with the reassignment (the step's first version, 2026-11-29), then
//! with communities. A Python prototype of this step, run on the output of `motif detect --epsilon 0.0012
//! --seed 1` for the scenes of `motif example scene-facade|scene-street --difficulty D --seed
//! S`, mean F before → after: hard facades of seeds 1–6 0.709 → 0.780, of seeds 7–12 (not used
//! to choose anything) 0.688 → 0.729; hard streets 0.666 → 0.687 and 0.652 → 0.658; medium
//! (seeds 1–6) facades 0.919 → 0.949, streets 0.859 → 0.880; easy facades 0.953 → 0.951,
//! streets 0.921 → 0.924. Leave-one-out nearest-neighbour agreement with the ground-truth class,
//! hard facades 1–6: 0.88 by the stretched images and sizes of [`crate::content`], 0.93–0.94 by
//! these. Settings tried on the hard facades of seeds 1–6 (mean F): shifts up to 0.36 m (3
//! cells of 0.12 m) 0.754, 0.6 m 0.772–0.784 (cells of 0.10, 0.12, 0.15 m), 0.72 m 0.785, 0.84 m
//! 0.777; a core of 2.6 m 0.767, 3.0 m 0.783, 3.6 m 0.761. The defaults are the 0.12 m cells, 3 m
//! core and 0.6 m shifts of the best of these, written relative to S (about 2.2 m there).
//! Joining whole classes by the median distance between their members, after this step, was
//! tried in the same prototype: at ratios 0.8–1.0 of the classes' own spreads it moved F by
//! −0.05 to −0.02, above 1.0 it joined window styles (F 0.58–0.64).
//!
//! This implementation, the same scenes and detection settings (2026-11-29), mean F without →
//! with the step: hard facades 0.709 → 0.773 (seeds 1–6) and 0.688 → 0.720 (seeds 7–12), hard
//! streets 0.666 → 0.694 and 0.652 → 0.691; medium (seeds 1–6) facades 0.919 → 0.938, streets
//! 0.859 → 0.874; easy facades 0.953 → 0.953, streets 0.921 → 0.922. Its first version let every
//! instance take part: easy facades fell to 0.874 and easy streets to 0.836, because a class
//! of tall windows held six whose boxes had grown to the balcony in front and two doors, and
//! the median distance to that class, for its eight plain windows, was a distance to the other
//! kind ([`AlignedOptions::flatness`], as the prototype, fixed it). Over the hard scenes of
//! seeds 1–12 (facades / streets): margin 0.1 (the default) 0.747 / 0.693, margin 0 0.758 /
//! 0.694, margin 0.2 0.736 / 0.668 (margin 0 on easy and medium scenes: facades 0.947 and
//! 0.947, streets 0.926 and 0.862, no clearer gain than its hard levels' noise); candidate
//! classes needing two or three other members: 0.746 / 0.692 and 0.746 / 0.695; this step
//! alone, without [`crate::content`]'s reassignment before it: 0.728 / 0.668.
//!
//! ## Communities
//! A Python prototype on the reassignment's output (the same scenes and settings) regrouped the
//! instances it pictured, mean F from 0.746 on hard facades of seeds 1–12: agglomerative
//! clustering of the distances cut at 1.5–5 times the median nearest-neighbour distance
//! (average, complete or weighted linkage) 0.60–0.77, peaking sharply; label propagation from
//! the classes (each instance takes its k nearest neighbours' majority) 0.78–0.79 at k = 5–7,
//! 0.65 at k = 15, and lower on hard streets (0.67 at k = 5, from 0.69) and easy scenes
//! (facades 0.943, streets 0.897 at k = 5, from 0.953 and 0.922); joining classes whose members' nearest neighbours lie
//! in each other as often as a random split of one class would give: at most 0.75 (mixed
//! classes join); modularity communities of the k-nearest-neighbour graph, unweighted: 0.73
//! (k = 2) to 0.81–0.815 (k = 5–12), but easy facades fell from 0.953 to 0.91–0.93 (small
//! styles such as `window_c`, five instances, lost to k ≥ 6 neighbours); weighted by the
//! self-tuning affinity: 0.82–0.84 for k from 10 to all pairs, scale rank 2–5 and resolution
//! 0.8–1.2, easy facades 0.95–0.97, medium 0.96–0.97. The default is all pairs, rank 3,
//! resolution 1 (no k to choose). This implementation, the same scenes, mean F reassignment →
//! communities: hard facades (seeds 1–12) 0.746 → 0.838, streets 0.692 → 0.693; medium (1–6)
//! facades 0.938 → 0.964, streets 0.874 → 0.887; easy facades 0.953 → 0.972, streets 0.922 →
//! 0.935.
//!
//! Lower resolutions, tried again on this implementation (2026-11-30; EM + SC mean F over the
//! hard streets of seeds 1–12, `motif detect --epsilon 0.0012`): 1.0 (the default) 0.714, 0.9
//! 0.726, 0.8 0.735, 0.7 0.714, 0.6 0.694. At 0.8 the halves into which one scanner's views
//! split a hard street's tall windows join (six scenes gain 0.035–0.076), but window styles
//! join too (three lose 0.013–0.019), and medium streets fall from 0.922 to 0.912, hard
//! facades from 0.861 to 0.837.
//!
//! Images compared also mirrored across the wall's horizontal axis (a window seen from the left
//! shows its reveal's inner side on the right), with one slab for all of a wall's boxes (1.5
//! times their median thickness, not each box's own), tried on the same scenes (2026-11-30,
//! seeds 1–12): hard streets 0.714 → 0.730 (+0.016 ±0.007 paired), but medium streets 0.922 →
//! 0.912 and hard facades 0.861 → 0.847; dropped (`docs/detect.md`, "mirrored images"). The
//! mirrored images alone, along the axis the pictured blocks are most symmetric along (chosen
//! from the images, so a turned scan would mirror along the turned axis), measured after:
//! within one standard error of the defaults at every level, on seeds 1–12 (hard streets
//! +0.009 ±0.008) and on seeds 13–24 (hard streets +0.003 ±0.007, hard facades −0.002
//! ±0.007); dropped as well.
//!
//! On the benchmark, EM + SC F reassignment → communities, paired over the 12 scenes (seeds
//! 1–12): facades 0.938 → 0.952 (+0.014 ±0.011) / 0.921 → 0.941 (+0.020 ±0.010) / 0.735 →
//! 0.832 (+0.097 ±0.022), easy / medium / hard; streets 0.933 → 0.939 (+0.006 ±0.004) / 0.863
//! → 0.852 (−0.011 ±0.013) / 0.671 → 0.675 (+0.004 ±0.007). SC gains too (medium facades
//! 0.821 → 0.863), so EM + SC's lead on medium facades is +0.077 ±0.026. The demo's detection
//! (a medium facade of 200k points) went from F 0.858 to 0.958 (P 0.920, R 1.000).
//!
//! Seeds 13–24, used for nothing before (`motif bench detect ... --seed 13 --aligned-grouping
//! reassign|communities`), the same comparison: facades 0.964 → 0.970 (+0.007 ±0.008) / 0.898
//! → 0.924 (+0.026 ±0.008) / 0.756 → 0.857 (+0.102 ±0.020); streets 0.940 → 0.950 (+0.010
//! ±0.007) / 0.860 → 0.869 (+0.009 ±0.015) / 0.682 → 0.698 (+0.016 ±0.011). EM + SC's lead on
//! medium facades there: +0.065 ±0.037 with reassignment, +0.056 ±0.039 with communities.
//!
//! ## Reassignment
//! On the benchmark (`motif bench detect --kind scene-facade|scene-street --scenes 12 --no-icp`,
//! seeds 1–12), EM + SC F without → with the step, paired over the scenes: facades 0.935 →
//! 0.938 (+0.003 ±0.003) / 0.920 → 0.921 (+0.000 ±0.009) / 0.702 → 0.735 (+0.034 ±0.013), easy
//! / medium / hard; streets 0.926 → 0.933 (+0.007 ±0.006) / 0.839 → 0.863 (+0.024 ±0.008) /
//! 0.656 → 0.671 (+0.014 ±0.011). SC gained more than EM + SC on medium facades (0.758 → 0.821),
//! so EM + SC's lead there fell to +0.100 ±0.028. The demo's detection (a medium facade) went
//! from F 0.874 to 0.858.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use motif_core::Point3;
use motif_core::geometry::Aabb;

use crate::content::{apply_labels, depth_image, plane_axes, thin_axes};
use crate::extent::median;
use crate::grid::SpatialHash;
use crate::instances::{Class, Instance, overlaps_any};

/// Options of the aligned step (module documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct AlignedOptions {
    /// Whether the step runs. Default true.
    pub enabled: bool,
    /// Cells per S, the typical block's larger side (module documentation). 18: cells of about
    /// 0.12 m on the facades' windows, a third of a transom's spacing. Default 18.
    pub cells_per_block: f64,
    /// Cells per side of the image. 37: about two blocks across, so that the core and its
    /// shifts stay inside. Default 37.
    pub image_cells: usize,
    /// Cells per side of the core compared (centred in the image). 25: about 1.4 blocks, the
    /// block and the cornices, sills and shutters beside it. Default 25.
    pub core_cells: usize,
    /// Largest shift, in cells on each axis (at most half of `image_cells − core_cells`). 5:
    /// about a quarter of a block, the error of a box fitted to half a window. Default 5.
    pub max_shift: usize,
    /// Extent of the image along the thin axis, as a multiple of the box's thickness (as
    /// [`crate::content::ContentOptions::window`]). Default 1.5.
    pub slab: f64,
    /// For [`Grouping::Reassign`]: an instance leaves its class only for one whose median
    /// distance is below `1 − margin` times its own class's. Default 0.1 (as
    /// [`crate::content::ContentOptions::margin`]).
    pub margin: f64,
    /// For [`Grouping::Reassign`]: most rounds. Default 5.
    pub rounds: usize,
    /// Only instances whose box is at most this multiple of its smaller side thick (across the
    /// class's thin axis) take part: a window whose box grew to the balcony in front of it, or
    /// a door's box reaching down its steps, pictures what stands in front, and would make its
    /// class look like two kinds. Such instances keep their class and count for no class.
    /// Default 0.6 (the prototype's choice; the facades' windows measure 0.15–0.3, a window
    /// grown with its balcony 0.7–1.0).
    pub flatness: f64,
    /// How the pictured instances are grouped once their distances are known (module
    /// documentation). Default [`Grouping::Communities`].
    pub grouping: Grouping,
    /// For [`Grouping::Communities`]: an instance's distance scale is its distance to its
    /// `scale_rank`-th nearest other instance (of its thin axis, not on its block). 3: the
    /// local scale of self-tuning spectral clustering (Zelnik-Manor and Perona 2004, who use
    /// the 7th neighbour on point sets of hundreds; the classes here have 2–20 members).
    /// Default 3.
    pub scale_rank: usize,
    /// For [`Grouping::Communities`]: the resolution γ of the modularity
    /// ([`crate::communities`]). Default 1 (plain modularity).
    pub resolution: f64,
    /// Whether the cells of an image that fall inside the box of an instance taking no part (a
    /// deep box, see `flatness`: a balcony, a car) that reaches the image's slab are left out of
    /// the comparison (module documentation, "What stands in front"). Default true.
    pub mask_deep: bool,
    /// With `mask_deep`: a deep box masks only when none of its sides exceeds this multiple of
    /// the median of that side over its class's deep members (module documentation). Default
    /// 1.25.
    pub mask_typical: f64,
}

/// How [`realign`] groups the instances it pictures.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Grouping {
    /// Communities of the graph of all pairs, weighted by distance (module documentation):
    /// the classes are formed again from the images alone.
    #[default]
    Communities,
    /// Each instance in turn moves to the class whose members it resembles most (module
    /// documentation): the classes are kept and corrected.
    Reassign,
}

impl Default for AlignedOptions {
    fn default() -> Self {
        AlignedOptions {
            enabled: true,
            cells_per_block: 18.0,
            image_cells: 37,
            core_cells: 25,
            max_shift: 5,
            slab: 1.5,
            margin: 0.1,
            rounds: 5,
            flatness: 0.6,
            grouping: Grouping::Communities,
            scale_rank: 3,
            resolution: 1.0,
            mask_deep: true,
            mask_typical: 1.25,
        }
    }
}

/// What the aligned step did, for reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct AlignedReport {
    /// Instances given an image.
    pub described: usize,
    /// Pictured instances that changed class (including those then dropped as repeats or with a
    /// class of one).
    pub moved: usize,
    /// Rounds run ([`Grouping::Reassign`]; 0 otherwise).
    pub rounds: usize,
    /// Instances dropped as repeats within their new class.
    pub duplicates: usize,
    /// Classes left with fewer than two instances and dropped.
    pub dropped_classes: usize,
    /// Communities found ([`Grouping::Communities`]; 0 otherwise).
    pub communities: usize,
    /// Classes made for communities that no class was left to host.
    pub new_classes: usize,
}

/// One instance's image: `n × n` depths in ε and confidences.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Cells per side.
    pub n: usize,
    /// Depths, row-major over the two plane axes in ascending order.
    pub cells: Vec<f64>,
    /// Confidences in [0, 1).
    pub confidence: Vec<f64>,
}

/// The least confidence-weighted mean |difference| between `a`'s central `core`² cells and
/// `b`'s cells shifted by up to `max_shift` on each axis (module documentation), one way round;
/// infinite when no shift has a cell both images see, or when the images are not both `n × n`
/// or the core does not fit. Shifts beyond `(n − core) / 2` are not tried.
pub fn shifted_distance(a: &Image, b: &Image, core: usize, max_shift: usize) -> f64 {
    let n = a.n;
    let whole = |im: &Image| im.cells.len() == n * n && im.confidence.len() == n * n;
    if b.n != n || core == 0 || core > n || !whole(a) || !whole(b) {
        return f64::INFINITY;
    }
    let o = (n - core) / 2;
    let s = max_shift.min(o) as i64;
    let mut best = f64::INFINITY;
    for dx in -s..=s {
        for dy in -s..=s {
            let (mut sum, mut weight) = (0.0, 0.0);
            for i in 0..core {
                let ra = (o + i) * n + o;
                let rb = ((o + i) as i64 + dx) as usize * n;
                let cb = (o as i64 + dy) as usize;
                let (va, ca) = (&a.cells[ra..ra + core], &a.confidence[ra..ra + core]);
                let (vb, wb) = (&b.cells[rb + cb..rb + cb + core], &b.confidence[rb + cb..rb + cb + core]);
                for j in 0..core {
                    let w = ca[j] * wb[j];
                    sum += w * (va[j] - vb[j]).abs();
                    weight += w;
                }
            }
            if weight > 0.0 {
                best = best.min(sum / weight);
            }
        }
    }
    best
}

/// The distance of the module documentation: the lesser of the two ways round.
pub fn distance(a: &Image, b: &Image, o: &AlignedOptions) -> f64 {
    shifted_distance(a, b, o.core_cells, o.max_shift).min(shifted_distance(b, a, o.core_cells, o.max_shift))
}

/// The instances this step pictures, as (class, instance) pairs in class order: those whose own
/// box is a slab across their class's thin axis `thin` ([`AlignedOptions::flatness`]); and the
/// image cell size per thin axis, S / [`AlignedOptions::cells_per_block`] with S the median
/// larger side of those instances' boxes across it (0 for an axis with none).
pub(crate) fn pictured(
    classes: &[Class],
    thin: &[Option<usize>],
    o: &AlignedOptions,
) -> (Vec<(usize, usize)>, [f64; 3]) {
    let flat = |ci: usize, k: usize| {
        let Some(t) = thin[ci] else { return false };
        let e = classes[ci].instances[k].aabb.extent();
        let [a0, a1] = plane_axes(t);
        e[t] <= o.flatness * e[a0].min(e[a1])
    };
    let items: Vec<(usize, usize)> = classes
        .iter()
        .enumerate()
        .flat_map(|(ci, c)| (0..c.instances.len()).map(move |k| (ci, k)))
        .filter(|&(ci, k)| flat(ci, k))
        .collect();
    let larger_side = |ci: usize, k: usize, t: usize| {
        let e = classes[ci].instances[k].aabb.extent();
        let [a0, a1] = plane_axes(t);
        e[a0].max(e[a1])
    };
    let cell: [f64; 3] = [0, 1, 2].map(|t| {
        let sides: Vec<f64> = items
            .iter()
            .filter(|(ci, _)| thin[*ci] == Some(t))
            .map(|&(ci, k)| larger_side(ci, k, t))
            .collect();
        median(sides) / o.cells_per_block
    });
    (items, cell)
}

/// Groups the instances of `classes` again by aligned images, as [`AlignedOptions::grouping`]
/// says (module documentation). `points` are the resampled points, indexed by `hash`; `eps` is
/// ε; `merge_overlap` is [`crate::instances::InstanceOptions::merge_overlap`]. Classes come
/// back in their order, without those dropped, followed by any new ones; extents are
/// recomputed.
pub fn realign(
    classes: &mut Vec<Class>,
    points: &[Point3],
    hash: &SpatialHash,
    eps: f64,
    merge_overlap: f64,
    o: &AlignedOptions,
) -> AlignedReport {
    let mut report = AlignedReport::default();
    let n = o.image_cells;
    // Reassignment needs a second class to move to; communities may split a single class.
    if !o.enabled
        || (classes.len() < 2 && o.grouping == Grouping::Reassign)
        || classes.is_empty()
        || n == 0
        || o.core_cells == 0
        || o.core_cells > n
        || !(o.cells_per_block > 0.0 && o.cells_per_block.is_finite())
    {
        return report;
    }
    let thin = thin_axes(classes);
    let (items, cell) = pictured(classes, &thin, o);
    let images = images(classes, &thin, &items, cell, points, hash, eps, merge_overlap, o);
    let (items, images): (Vec<(usize, usize)>, Vec<Image>) =
        items.into_iter().zip(images).filter_map(|(it, im)| Some((it, im?))).unzip();
    report.described = items.len();
    let m = items.len();
    let group: Vec<Option<usize>> = items.iter().map(|it| thin[it.0]).collect();
    // Distances between instances of one thin axis (upper triangle, then mirrored).
    let rows: Vec<Vec<f64>> =
        (0..m)
            .into_par_iter()
            .map(|a| {
                (a + 1..m)
                    .map(|b| {
                        if group[a] == group[b] { distance(&images[a], &images[b], o) } else { f64::INFINITY }
                    })
                    .collect()
            })
            .collect();
    let mut d = vec![f64::INFINITY; m * m];
    for (a, row) in rows.iter().enumerate() {
        for (k, &v) in row.iter().enumerate() {
            let b = a + 1 + k;
            d[a * m + b] = v;
            d[b * m + a] = v;
        }
    }
    let inst = |k: usize| &classes[items[k].0].instances[items[k].1];
    let clash: Vec<Vec<usize>> = (0..m)
        .map(|k| {
            (0..m)
                .filter(|&j| j != k && overlaps_any(inst(k), std::slice::from_ref(inst(j)), merge_overlap))
                .collect()
        })
        .collect();
    let label = match o.grouping {
        Grouping::Reassign => {
            // Classes that hold an instance's block through a member that takes no part (a deep
            // box): such members never move, so this is fixed. (Communities form the classes
            // afresh, and a repeat of a block its class holds is dropped when applied.)
            let mut taking_part: Vec<Vec<bool>> =
                classes.iter().map(|c| vec![false; c.instances.len()]).collect();
            for &(ci, k) in &items {
                taking_part[ci][k] = true;
            }
            let fixed_clash: Vec<Vec<usize>> = (0..m)
                .map(|a| {
                    (0..classes.len())
                        .filter(|&ci| {
                            classes[ci].instances.iter().zip(&taking_part[ci]).any(|(q, &part)| {
                                !part && overlaps_any(inst(a), std::slice::from_ref(q), merge_overlap)
                            })
                        })
                        .collect()
                })
                .collect();
            reassign(&items, &group, &d, &clash, &fixed_clash, classes.len(), o, &mut report)
        }
        Grouping::Communities => {
            let community = communities(&group, &d, &clash, o);
            report.communities = community.iter().max().map_or(0, |c| c + 1);
            host(classes, &items, &community, &mut report.new_classes)
        }
    };
    report.moved = label.iter().zip(&items).filter(|(l, it)| **l != it.0).count();
    if report.moved > 0 {
        let (duplicates, dropped) = apply_labels(classes, &items, &label, merge_overlap);
        report.duplicates = duplicates;
        report.dropped_classes = dropped;
    }
    report
}

/// The images of the pictured `items` (as [`pictured`] gives them, with their thin axes `thin`
/// and cell sizes `cell`), `None` for one with no points; cells inside the deep boxes in front
/// of an instance are masked when [`AlignedOptions::mask_deep`] says so.
#[allow(clippy::too_many_arguments)]
fn images(
    classes: &[Class],
    thin: &[Option<usize>],
    items: &[(usize, usize)],
    cell: [f64; 3],
    points: &[Point3],
    hash: &SpatialHash,
    eps: f64,
    merge_overlap: f64,
    o: &AlignedOptions,
) -> Vec<Option<Image>> {
    let n = o.image_cells;
    // The boxes of the instances that take no part (deep boxes: balconies, cars, a window grown
    // with what stands in front of it), masked out of the images they reach.
    let mut pictured_item: Vec<Vec<bool>> = classes.iter().map(|c| vec![false; c.instances.len()]).collect();
    for &(ci, k) in items {
        pictured_item[ci][k] = true;
    }
    let deep: Vec<&Instance> = if o.mask_deep {
        classes
            .iter()
            .zip(&pictured_item)
            .flat_map(|(c, part)| {
                let members: Vec<&Instance> =
                    c.instances.iter().zip(part).filter(|(_, p)| !**p).map(|(q, _)| q).collect();
                let typical = [0, 1, 2].map(|a| median(members.iter().map(|q| q.aabb.extent()[a]).collect()));
                members
                    .into_iter()
                    .filter(move |q| (0..3).all(|a| q.aabb.extent()[a] <= o.mask_typical * typical[a]))
            })
            .collect()
    } else {
        Vec::new()
    };
    items
        .par_iter()
        .map(|&(ci, k)| {
            let t = thin[ci]?;
            if !(cell[t] > 0.0 && cell[t].is_finite()) {
                return None;
            }
            let inst = &classes[ci].instances[k];
            let b = &inst.aabb;
            let half = 0.5 * n as f64 * cell[t];
            let slab = 0.5 * o.slab * b.extent()[t];
            let (cells, mut confidence) =
                depth_image(b.center(), [half, half], slab, n, t, points, hash, eps)?;
            mask_deep_boxes(&mut confidence, inst, &deep, [half, half], slab, n, t, merge_overlap);
            Some(Image { n, cells, confidence })
        })
        .collect()
}

/// Sets to zero the confidence of the cells of `inst`'s image (`n × n` cells over its box's
/// centre ± `half` across the thin axis `t`, ± `slab` along it) whose centres fall inside the
/// box of a `deep` instance that reaches the image's slab and is not on `inst`'s own block (the
/// [`crate::instances::InstanceOptions::merge_overlap`] test): what stands in front of a
/// block is another block, not the block's surroundings ([`AlignedOptions::mask_deep`]).
#[allow(clippy::too_many_arguments)]
fn mask_deep_boxes(
    confidence: &mut [f64],
    inst: &Instance,
    deep: &[&Instance],
    half: [f64; 2],
    slab: f64,
    n: usize,
    t: usize,
    merge_overlap: f64,
) {
    let c = inst.aabb.center();
    let [a0, a1] = plane_axes(t);
    // The region the image pictures.
    let (mut region, mut reach) = (Aabb { min: c, max: c }, [0.0; 3]);
    (reach[a0], reach[a1], reach[t]) = (half[0], half[1], slab);
    for a in 0..3 {
        region.min[a] -= reach[a];
        region.max[a] += reach[a];
    }
    let centre = |k: usize, a: usize, h: f64| c[a] - h + (k as f64 + 0.5) * 2.0 * h / n as f64;
    for q in deep {
        if q.aabb.intersection(&region).is_none()
            || overlaps_any(inst, std::slice::from_ref(*q), merge_overlap)
        {
            continue;
        }
        for i in 0..n {
            let u = centre(i, a0, half[0]);
            if u < q.aabb.min[a0] || u > q.aabb.max[a0] {
                continue;
            }
            for j in 0..n {
                let v = centre(j, a1, half[1]);
                if v >= q.aabb.min[a1] && v <= q.aabb.max[a1] {
                    confidence[i * n + j] = 0.0;
                }
            }
        }
    }
}

/// The reassignment of the module documentation: each item's class after it. `items` are
/// (class, instance) pairs, `group` their thin axes, `d` their distances (`m × m`), `clash` the
/// items on each one's block, `fixed_clash` the classes holding it through a member that takes
/// no part.
#[allow(clippy::too_many_arguments)]
fn reassign(
    items: &[(usize, usize)],
    group: &[Option<usize>],
    d: &[f64],
    clash: &[Vec<usize>],
    fixed_clash: &[Vec<usize>],
    class_count: usize,
    o: &AlignedOptions,
    report: &mut AlignedReport,
) -> Vec<usize> {
    let m = items.len();
    let mut label: Vec<usize> = items.iter().map(|it| it.0).collect();
    let mut per_class: Vec<Vec<f64>> = vec![Vec::new(); class_count];
    for _ in 0..o.rounds {
        report.rounds += 1;
        let mut moved = false;
        for a in 0..m {
            per_class.iter_mut().for_each(Vec::clear);
            for j in (0..m).filter(|&j| j != a && group[j] == group[a]) {
                per_class[label[j]].push(d[a * m + j]);
            }
            if per_class[label[a]].is_empty() {
                continue;
            }
            let own = median(per_class[label[a]].clone());
            let mut best: Option<(f64, usize)> = None;
            for (ci, ds) in per_class.iter().enumerate() {
                if ds.is_empty() {
                    continue;
                }
                let v = median(ds.clone());
                if best.is_none_or(|b| v < b.0) {
                    best = Some((v, ci));
                }
            }
            if let Some((v, ci)) = best
                && ci != label[a]
                && v < (1.0 - o.margin) * own
                && !clash[a].iter().any(|&j| label[j] == ci)
                && !fixed_clash[a].contains(&ci)
            {
                label[a] = ci;
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
    label
}

/// Communities of the pictured instances (module documentation), per item; items of
/// different thin axes, or with no finite distance, never share one.
fn communities(group: &[Option<usize>], d: &[f64], clash: &[Vec<usize>], o: &AlignedOptions) -> Vec<usize> {
    let m = group.len();
    let linked = |a: usize, b: usize| {
        a != b && group[a] == group[b] && d[a * m + b].is_finite() && !clash[a].contains(&b)
    };
    let w = crate::communities::self_tuning_weights(d, m, linked, o.scale_rank);
    crate::communities::louvain(&w, m, o.resolution)
}

/// Classes for the communities: each class hosts at most one community and each community at
/// most one class, the pairs sharing the most instances first (ties: lower community, then
/// lower class); a community left without a host gets a new class, a copy of the class most of
/// its instances came from (its words and cluster; ties: the lower). Returns each item's class
/// (new classes are appended to `classes` empty, to be filled by [`apply_labels`]).
pub(crate) fn host(
    classes: &mut Vec<Class>,
    items: &[(usize, usize)],
    community: &[usize],
    new_classes: &mut usize,
) -> Vec<usize> {
    let count = community.iter().max().map_or(0, |c| c + 1);
    let mut shared = std::collections::BTreeMap::<(usize, usize), usize>::new();
    for (&(ci, _), &c) in items.iter().zip(community) {
        *shared.entry((c, ci)).or_default() += 1;
    }
    let mut pairs: Vec<((usize, usize), usize)> = shared.into_iter().collect();
    pairs.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    let mut class_of: Vec<Option<usize>> = vec![None; count];
    let mut taken = vec![false; classes.len()];
    for &((c, ci), _) in &pairs {
        if class_of[c].is_none() && !taken[ci] {
            class_of[c] = Some(ci);
            taken[ci] = true;
        }
    }
    for (c, slot) in class_of.iter_mut().enumerate() {
        if slot.is_none() {
            // The first pair of c in `pairs` is its largest share.
            let &((_, ci), _) = pairs.iter().find(|p| p.0.0 == c).expect("every community has an item");
            let from = &classes[ci];
            let new = Class {
                words: from.words.clone(),
                centre_word: from.centre_word,
                extent: from.extent,
                instances: Vec::new(),
                cluster: from.cluster,
            };
            classes.push(new);
            *slot = Some(classes.len() - 1);
            *new_classes += 1;
        }
    }
    community.iter().map(|&c| class_of[c].expect("every community has a class")).collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::content::tests::{H, Window, class_of, opening, styled_scene};
    use crate::grid::SpatialHash;

    /// An image whose only relief is a `w × w` square of depth 1 with its corner at (`x`, `y`).
    pub(crate) fn square(n: usize, x: usize, y: usize, w: usize) -> Image {
        let mut cells = vec![0.0; n * n];
        for i in x..x + w {
            for j in y..y + w {
                cells[i * n + j] = 1.0;
            }
        }
        Image { n, cells, confidence: vec![0.9; n * n] }
    }

    #[test]
    fn a_shifted_copy_is_at_distance_zero_and_an_unlike_image_is_not() {
        let a = square(15, 5, 5, 4);
        let o = AlignedOptions { image_cells: 15, core_cells: 9, max_shift: 3, ..Default::default() };
        // Shifted by (2, −3): found within the shifts.
        assert_eq!(distance(&a, &square(15, 7, 2, 4), &o), 0.0);
        // Shifted by 4, beyond them: the best shift leaves a difference.
        assert!(distance(&a, &square(15, 9, 5, 4), &o) > 0.0);
        // A larger square is not the same block, wherever it is put.
        assert!(distance(&a, &square(15, 4, 4, 6), &o) > 0.1);
        // Nothing seen in common: infinite, not zero.
        let blind = Image { confidence: vec![0.0; 225], ..a.clone() };
        assert_eq!(distance(&a, &blind, &o), f64::INFINITY);
    }

    /// Eight windows 3 m apart, styles as `two_bars`, sized as the benchmark scenes' styles:
    /// two-transom windows 1.0 × 2.2 m (a `window_b`), one-transom ones 1.2 × 1.5 m (a
    /// `window_a`), each varied by up to 10% per axis; their wall and its spatial hash.
    fn scene(two_bars: [bool; 8]) -> (Vec<Window>, Vec<Point3>, SpatialHash) {
        styled_scene(two_bars, |two| if two { (1.0 / 1.2, 2.2 / 1.6) } else { (1.0, 1.5 / 1.6) }, 0.1)
    }

    /// The box of the top half of window `w`'s opening (a box fitted to a corner's constellation
    /// that no segment grew).
    fn top_half(w: &Window) -> Aabb {
        let mut b = opening(w);
        b.min[1] = 0.5 * (b.min[1] + b.max[1]);
        b
    }

    #[test]
    fn instances_with_misplaced_boxes_join_their_style() {
        // Class 0 holds three one-transom windows and a two-transom one, class 1 the reverse,
        // and the two odd ones have boxes of only the top half of their opening.
        let (ws, pts, hash) = scene([false, false, false, true, true, true, true, false]);
        let mut classes = vec![class_of(&ws, &[0, 1, 2, 3], 0, 0.0), class_of(&ws, &[4, 5, 6, 7], 1, 0.0)];
        classes[0].instances[3].aabb = top_half(&ws[3]);
        classes[1].instances[3].aabb = top_half(&ws[7]);
        // The content step's images, stretched to each box, picture half a window: a class
        // still mixes the styles after it.
        let mut stretched = classes.clone();
        crate::content::reassign(&mut stretched, &pts, &hash, H, 0.5, &Default::default());
        let mixed = |c: &Class| c.instances.iter().any(|i| ws[i.centre].3 != ws[c.instances[0].centre].3);
        assert!(stretched.iter().any(mixed), "the stretched images sorted the styles");
        for grouping in BOTH {
            let mut classes = classes.clone();
            let r = realign(
                &mut classes,
                &pts,
                &hash,
                H,
                0.5,
                &AlignedOptions { grouping, ..Default::default() },
            );
            assert_eq!(
                (r.described, r.moved, r.duplicates, r.dropped_classes),
                (8, 2, 0, 0),
                "{grouping:?} {r:?}"
            );
            assert_eq!(members(&classes), vec![vec![0, 1, 2, 7], vec![3, 4, 5, 6]], "{grouping:?}");
        }
        // Switched off, nothing changes.
        let mut off = vec![class_of(&ws, &[0, 1, 2, 3], 0, 0.0), class_of(&ws, &[4, 5, 6, 7], 1, 0.0)];
        let o = AlignedOptions { enabled: false, ..Default::default() };
        assert_eq!(realign(&mut off, &pts, &hash, H, 0.5, &o), AlignedReport::default());
        assert_eq!(off[0].instances.len(), 4);
    }

    #[test]
    fn instances_with_deep_boxes_keep_their_class() {
        // Class 0 holds three one-transom windows and a two-transom one whose box reaches 1.5 m
        // in front of the wall (grown to a balcony): it takes no part and stays. Let take part,
        // it would join its style.
        let (ws, pts, hash) = scene([false, false, false, true, true, true, true, true]);
        let classes = vec![class_of(&ws, &[0, 1, 2, 3], 0, 0.0), class_of(&ws, &[4, 5, 6, 7], 1, 0.0)];
        let mut deep = classes.clone();
        deep[0].instances[3].aabb.max[2] = 1.5;
        for grouping in BOTH {
            let o = AlignedOptions { grouping, ..Default::default() };
            let r = realign(&mut deep.clone(), &pts, &hash, H, 0.5, &o);
            assert_eq!((r.described, r.moved), (7, 0), "{grouping:?} {r:?}");
            let all = AlignedOptions { flatness: f64::INFINITY, ..o };
            let mut moved = deep.clone();
            let r = realign(&mut moved, &pts, &hash, H, 0.5, &all);
            assert_eq!((r.described, r.moved), (8, 1), "{grouping:?} {r:?}");
            assert_eq!(moved[1].instances.len(), 5);
        }
    }

    #[test]
    fn what_stands_in_front_is_left_out_of_the_picture() {
        // Eight windows of one style, varied by up to 3% per axis (10% can split a style by
        // size alone); in front of the lower part of windows 0–3 stands a balcony, 2 m wide,
        // whose front the wall's images see 0.2 m before the wall, with a deep box of its own
        // (a third class, which takes no part). The windows behind balconies form class 0, the
        // plain ones class 1.
        let (ws, mut pts, _) = styled_scene([true; 8], |_| (1.0 / 1.2, 2.2 / 1.6), 0.03);
        let balcony = |w: &Window| {
            let b = opening(w);
            let x = 0.5 * (b.min[0] + b.max[0]);
            Aabb { min: [x - 1.0, b.min[1] - 0.4, -0.05], max: [x + 1.0, b.min[1] + 0.5, 1.2] }
        };
        let fronts: Vec<Aabb> = ws[..4].iter().map(balcony).collect();
        for p in &mut pts {
            if fronts
                .iter()
                .any(|b| p[0] >= b.min[0] && p[0] <= b.max[0] && p[1] >= b.min[1] && p[1] <= b.max[1])
            {
                p[2] = 0.2;
            }
        }
        let hash = SpatialHash::new(&pts, 8.0 * H);
        let mut balconies = class_of(&ws, &[0, 1, 2, 3], 2, 0.0);
        for (q, b) in balconies.instances.iter_mut().zip(&fronts) {
            q.aabb = *b;
        }
        let classes =
            vec![class_of(&ws, &[0, 1, 2, 3], 0, 0.0), class_of(&ws, &[4, 5, 6, 7], 1, 0.0), balconies];
        // The mean image distance between two windows with balconies (`both`), a window with
        // one and a plain window (`across`) and two plain windows (`plain`).
        let means = |o: &AlignedOptions| {
            let thin = thin_axes(&classes);
            let (items, cell) = pictured(&classes, &thin, o);
            assert_eq!(items.len(), 8, "{items:?}");
            let im: Vec<Image> = images(&classes, &thin, &items, cell, &pts, &hash, H, 0.5, o)
                .into_iter()
                .map(|i| i.expect("pictured"))
                .collect();
            let mean = |pairs: Vec<(usize, usize)>| {
                pairs.iter().map(|&(a, b)| distance(&im[a], &im[b], o)).sum::<f64>() / pairs.len() as f64
            };
            let pairs = |a: std::ops::Range<usize>, b: std::ops::Range<usize>| {
                a.flat_map(|i| b.clone().filter(move |&j| j > i).map(move |j| (i, j))).collect::<Vec<_>>()
            };
            [mean(pairs(0..4, 0..4)), mean(pairs(0..4, 4..8)), mean(pairs(4..8, 4..8))]
        };
        // Pictured, the balconies set the windows behind them apart...
        let seen = AlignedOptions { mask_deep: false, ..Default::default() };
        let [both, across, plain] = means(&seen);
        assert!(across > 2.0 * both.max(plain), "{both:.3} {across:.3} {plain:.3}");
        // ... and split the style in two classes, by balconies.
        let mut split = classes.clone();
        let r = realign(&mut split, &pts, &hash, H, 0.5, &seen);
        assert_eq!((r.described, r.communities, r.moved), (8, 2, 0), "{r:?}");
        assert_eq!(members(&split), members(&classes));
        // Left out, a window behind a balcony is as near a plain one as two plain ones are.
        let [both, across, plain] = means(&AlignedOptions::default());
        assert!(across < 1.25 * both.max(plain), "{both:.3} {across:.3} {plain:.3}");
        // A box larger than its class's typical deep box masks nothing: with every box above
        // half the typical size, the images are those of `seen`.
        let half = AlignedOptions { mask_typical: 0.5, ..Default::default() };
        assert_eq!(means(&half), means(&seen));
    }

    const BOTH: [Grouping; 2] = [Grouping::Communities, Grouping::Reassign];

    /// Each class's members (window indices), sorted, classes in order.
    fn members(classes: &[Class]) -> Vec<Vec<usize>> {
        let mut m: Vec<Vec<usize>> =
            classes.iter().map(|c| c.instances.iter().map(|i| i.centre).collect()).collect();
        m.iter_mut().for_each(|m| m.sort_unstable());
        m
    }

    #[test]
    fn well_grouped_classes_stay() {
        let (ws, pts, hash) = scene([false, false, false, false, true, true, true, true]);
        for grouping in BOTH {
            let mut classes =
                vec![class_of(&ws, &[0, 1, 2, 3], 0, 0.0), class_of(&ws, &[4, 5, 6, 7], 1, 0.0)];
            let o = AlignedOptions { grouping, ..Default::default() };
            let r = realign(&mut classes, &pts, &hash, H, 0.5, &o);
            let expected = match grouping {
                Grouping::Communities => (8, 0, 0, 2, 0),
                Grouping::Reassign => (8, 0, 1, 0, 0),
            };
            assert_eq!((r.described, r.moved, r.rounds, r.communities, r.new_classes), expected, "{r:?}");
            assert_eq!(members(&classes), vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]]);
        }
    }

    #[test]
    fn communities_join_a_split_style_and_split_a_mixed_class() {
        // One-transom windows 0–3 and two-transom windows 4–7, in three classes: {0, 1}, the
        // mix {2, 3, 4} and {5, 6, 7}. By communities of the images the classes become the two
        // styles, each hosted by a class it shares most with (a tie between {0, 1} and the mix
        // goes to the lower), and the emptied mix is dropped.
        let (ws, pts, hash) = scene([false, false, false, false, true, true, true, true]);
        let three = || {
            vec![
                class_of(&ws, &[0, 1], 0, 0.0),
                class_of(&ws, &[2, 3, 4], 1, 0.0),
                class_of(&ws, &[5, 6, 7], 2, 0.0),
            ]
        };
        let mut classes = three();
        let r = realign(&mut classes, &pts, &hash, H, 0.5, &AlignedOptions::default());
        assert_eq!((r.communities, r.moved, r.new_classes, r.dropped_classes), (2, 3, 0, 1), "{r:?}");
        assert_eq!(members(&classes), vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]]);
        assert_eq!(classes.iter().map(|c| c.words[0]).collect::<Vec<_>>(), [0, 2]);
        // Reassignment keeps a class per style found and cannot join {0, 1} with {2, 3}: the
        // styles stay split over two classes.
        let mut kept = three();
        let o = AlignedOptions { grouping: Grouping::Reassign, ..Default::default() };
        realign(&mut kept, &pts, &hash, H, 0.5, &o);
        assert!(members(&kept).len() > 2, "{:?}", members(&kept));
    }

    #[test]
    fn a_class_of_two_styles_is_split_into_a_new_class() {
        let (ws, pts, hash) = scene([false, true, false, true, false, true, false, true]);
        // One class: communities split it (reassignment has nowhere to move to).
        let mut classes = vec![class_of(&ws, &[0, 1, 2, 3, 4, 5, 6, 7], 4, 0.0)];
        let r = realign(&mut classes, &pts, &hash, H, 0.5, &AlignedOptions::default());
        assert_eq!((r.described, r.communities, r.new_classes, r.moved), (8, 2, 1, 4), "{r:?}");
        assert_eq!(classes.len(), 2);
        let m = members(&classes);
        assert!(m.contains(&vec![0, 2, 4, 6]) && m.contains(&vec![1, 3, 5, 7]), "{m:?}");
        // The new class copies the words and cluster of the class its members came from.
        assert!(classes.iter().filter(|c| c.words == [4] && c.cluster == 4).count() == 2);
        let o = AlignedOptions { grouping: Grouping::Reassign, ..Default::default() };
        let mut one = vec![class_of(&ws, &[0, 1, 2, 3, 4, 5, 6, 7], 4, 0.0)];
        assert_eq!(realign(&mut one, &pts, &hash, H, 0.5, &o), AlignedReport::default());
    }

    #[test]
    fn a_deep_box_stays_when_its_class_hosts_no_community() {
        // Class 0 holds two-transom window 4, one-transom window 1 and a deep box on window 0;
        // class 1 holds two-transom windows 5–7, class 2 one-transom windows 2 and 3. Each
        // community shares more with class 1 or 2 than with class 0, so class 0 hosts none: its
        // pictured members leave, its deep box stays, alone, and its class of one is dropped.
        let (ws, pts, hash) = scene([false, false, false, false, true, true, true, true]);
        let mut classes = vec![
            class_of(&ws, &[4, 1, 0], 0, 0.0),
            class_of(&ws, &[5, 6, 7], 1, 0.0),
            class_of(&ws, &[2, 3], 2, 0.0),
        ];
        classes[0].instances[2].aabb.max[2] = 1.5;
        let r = realign(&mut classes, &pts, &hash, H, 0.5, &AlignedOptions::default());
        let m = members(&classes);
        assert_eq!((r.described, r.communities, r.moved, r.dropped_classes), (7, 2, 2, 1), "{r:?} {m:?}");
        assert_eq!(m, vec![vec![4, 5, 6, 7], vec![1, 2, 3]]);
    }
}
