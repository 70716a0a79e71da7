//! Copies of a class found by their picture (not in the thesis): the extent stage's last step,
//! after [`crate::aligned`].
//!
//! Why: the co-occurrence analysis finds a block where its word pairs have enough support
//! (|Ψ(i, j)| ≥ 5, thesis 5.4), and the MDL rounds remove the features of every class they keep
//! (5.4). A style with few copies left once a class has absorbed some of them is never found:
//! on a hard street (one scanner, parked cars) two of the five ground-floor windows went into
//! the class of upper windows in the first round, and the other three, with 47–66 salient
//! features each, were covered by no class of any round, because three copies cannot support a
//! word pair five times. Once a class is known, its members' depth images ([`crate::aligned`])
//! say what its blocks look like, and the wall can be searched for that picture where no
//! instance stands: template matching with the detected members as templates, the supervised
//! search of the thesis's RigidICP baseline (5.5.2), here with the detector's own classes.
//!
//! # What it does
//! For each axis t, over the classes whose thin axis is t (not those of freely turning blocks)
//! with at least [`MIN_MEMBERS`] pictured (flat) instances:
//! 1. **Templates.** The images of the class's pictured instances, at the scale and slab of
//!    [`crate::aligned`]. Each member's *typicality* is the median of its distances to the
//!    other members; the class's *spread* r is the median typicality, and the
//!    [`CopiesOptions::templates`] most typical members are its templates.
//! 2. **Search.** A grid over the class's plane (centred on the box of the resampled points
//!    within its slab: the members' median position along t, ± half the slab), one node every
//!    `2 ×` [`crate::aligned::AlignedOptions::max_shift`] cells, so that every position is
//!    within one shift of a node; only nodes within one step (on the plane) of a salient
//!    feature inside the slab that no instance box holds are pictured, since a copy must hold
//!    features no other instance explains. At each node, the node's image against each
//!    template: the distance of [`crate::aligned::distance`] and the shift of its best
//!    alignment. The node's raw score is the median distance to the class's templates, and its
//!    score that over the class's spread r.
//! 3. **Candidates.** A node scoring at most [`CopiesOptions::accept`] is moved by the
//!    templates' median shift to where the block lies, pictured again there, and kept if it
//!    still scores within `accept`, its raw score is below 1 (it matches the templates better
//!    than a plain plane would), and no other searched class of the axis, pictured there at its
//!    own depth and slab, has a lower raw score. Its box is the median box of the class's flat
//!    members, centred there.
//! 4. **New instances.** Candidates in order of score: one is added to its class when its box
//!    holds at least [`crate::instances::InstanceOptions::min_instance_features`] salient
//!    features and overlaps no instance of any class, nor a copy added before it, by more than
//!    [`crate::instances::InstanceOptions::merge_overlap`] of the smaller box.
//!
//! Distances are relative: each is divided by the template's distance to a blank plane (all
//! depths 0, fully seen), so that 0 means the template's relief is all matched and 1 that a
//! plain wall would match it as well. The class's spread and the scores use these.
//!
//! The scale, image and shift range are those of [`crate::aligned`], so a copy is found on the
//! terms by which the step before grouped the classes. The grid is centred on its region, so a
//! rigid motion of the input (quarter turns included) moves it with the points. Nodes are
//! independent (parallel); the greedy adding is sequential and ordered by score, then node and
//! class, so the result does not depend on the thread count. The best shift prefers, among
//! equal distances, the one nearest zero, so a featureless patch does not drift to a corner;
//! invariance to a mirror holds up to exact ties in floating point.
//!
//! The library runs this step whenever [`CopiesOptions::enabled`] is set; the CLI's
//! `--no-aligned` turns it off too, since it searches with the aligned step's images. A new
//! instance's `centre` is the salient feature nearest its box's centre (as for the classes of
//! [`crate::segment_classes`]), not a member of the class's median word.
//!
//! # Measured
//! On the harness of [`crate::aligned`] (`motif example scene-facade|scene-street --difficulty
//! D --seed S`, then `motif detect --epsilon 0.0012 --seed 1`; hard levels seeds 1–12, easy and
//! medium seeds 1–6; 2026-11-29), mean F without → with this step:
//!
//! | | easy | medium | hard |
//! |---|---|---|---|
//! | facade | 0.972 → 0.972 | 0.964 → 0.973 | 0.838 → **0.865** |
//! | street | 0.935 → 0.944 | 0.887 → 0.893 | 0.701 → **0.715** |
//!
//! On the hard levels it added 22 boxes to the facades (17 on blocks no box located, 5 on
//! blocks already located, none on no block) and 19 to the streets (15, 4, none). Cost: about
//! 0.2–0.5 s per 300k-point scene (a few hundred nodes per class, eight templates; measured
//! with `motif detect --json` with and without `--no-copies` on four scenes).
//!
//! Variants, measured on the hard levels in the same way (facades / streets; 0.838 / 0.701
//! without the step):
//! - Distances over the class's spread without the blank plane's normalisation and without the
//!   coverage test: 137 boxes added to five hard streets, 10 of them on unlocated blocks; F of
//!   street 1 fell from 0.693 to 0.420. Nodes over sky, the wall's edge or the ground matched
//!   best, because a confidence-weighted distance ignores what is not seen.
//! - Relative distances, coverage 0.7, accept 1.0, every class searched: 0.843 / 0.670 (a
//!   class of balconies whose boxes reach the windows behind, and one of ground patches under
//!   lamp posts, matched the wall and the road everywhere).
//! - Accept 0.8, coverage 0.8: 0.838 / 0.687 (no copy on the facades).
//! - Classes of spread at most 0.8: accept 1.0 0.845 / 0.704, 1.2 0.859 / 0.708, 1.4 0.860 /
//!   0.706. At most 0.9 and accept 1.2: **0.866 / 0.713** (kept); with coverage 0.8 0.860 /
//!   0.712; spread at most 1.0 (any class likelier than a plane) 0.858 / 0.712.
//! - Without the rule that a copy goes to the class it is most like, the same figures on this
//!   harness, but on this module's test wall a one-transom window joined the two-transom
//!   class (scores normalised by a looser class's spread are lower).
//! - A grid anchored at the region's corner instead of centred: 0.866 / 0.713 against 0.865 /
//!   0.715 centred, and not invariant to a mirror of the input.
//!
//! What it cannot do: a style no class holds three pictured copies of (doors, two per scene)
//! is never searched, and bins, which stand free, have no plane to search.

use motif_core::Point3;
use motif_core::geometry::{Aabb, Mat4};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::aligned::{AlignedOptions, Image, distance, pictured};
use crate::content::{depth_image, plane_axes, thin_axes};
use crate::extent::{median, median_box_size};
use crate::grid::SpatialHash;
use crate::instances::{Class, Instance, overlaps_any};
use crate::preprocess::{Feature, nearest_feature};

/// Fewest pictured instances a class needs to be searched for: with two, its spread is one
/// distance, no measure of how its copies vary.
pub const MIN_MEMBERS: usize = 3;

/// Options of the search for copies (module documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CopiesOptions {
    /// Whether the step runs. Default true.
    pub enabled: bool,
    /// Templates per class: its most typical pictured members. Default 8 (bounds the cost on
    /// classes of many copies; the median over eight is as steady as over all).
    pub templates: usize,
    /// A position is a copy when the median of its distances to the class's templates is at
    /// most this multiple of the class's spread (the median over members of their median
    /// distance to the other members): 1 is as like the class as its typical member is. Default
    /// 1.2.
    pub accept: f64,
    /// Only classes whose spread is at most this are searched: members that leave more of each
    /// other's relief unexplained than this share are not alike enough to be a template (a
    /// class of balconies whose boxes reach the windows behind them, a class of ground-plane
    /// patches). 1 would be "no more alike than a plain plane". Default 0.9.
    pub max_spread: f64,
    /// A position is pictured only where the scan shows at least this share of what it shows
    /// of the templates (mean confidence over the image's core, against the templates' median):
    /// confidence-weighted distances ignore what is not seen, so a window of sky or of the
    /// wall's edge, holding a few points, would match anything. Default 0.7.
    pub min_coverage: f64,
}

impl Default for CopiesOptions {
    fn default() -> Self {
        CopiesOptions { enabled: true, templates: 8, accept: 1.2, max_spread: 0.9, min_coverage: 0.7 }
    }
}

impl CopiesOptions {
    /// Checks the ranges: the offending option's name and what is wrong.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if self.templates == 0 {
            return Err(("extent.copies.templates", "must be at least 1, got 0".into()));
        }
        if !(self.accept > 0.0 && self.accept.is_finite()) {
            return Err((
                "extent.copies.accept",
                format!("must be finite and positive, got {}", self.accept),
            ));
        }
        if self.max_spread.is_nan() || self.max_spread <= 0.0 {
            return Err((
                "extent.copies.max_spread",
                format!("must be positive (infinity: every class), got {}", self.max_spread),
            ));
        }
        if !(self.min_coverage >= 0.0 && self.min_coverage.is_finite()) {
            return Err((
                "extent.copies.min_coverage",
                format!("must be finite and ≥ 0, got {}", self.min_coverage),
            ));
        }
        Ok(())
    }
}

/// What the search did, for reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct CopiesReport {
    /// Classes searched (enough pictured members).
    pub classes: usize,
    /// Grid nodes near an unexplained feature, compared with the templates where the scan
    /// shows enough of them.
    pub nodes: usize,
    /// Candidates that scored within the threshold where they were moved to.
    pub candidates: usize,
    /// Copies added as new instances.
    pub added: usize,
}

/// A searched class: its index, templates, spread, slab and median pictured box size.
struct Searched {
    class: usize,
    templates: Vec<Image>,
    /// Each template's distance to a blank plane.
    blank: Vec<f64>,
    /// The templates' median coverage ([`coverage`]).
    coverage: f64,
    spread: f64,
    /// Position along the thin axis and half-thickness of the image's slab.
    along: f64,
    slab_half: f64,
    size: Point3,
    /// A member's frame and box centre, to place a copy's frame.
    frame: Mat4,
    centre: Point3,
}

/// The mean confidence over an image's central `core`² cells: how much of it the scan shows.
fn coverage(im: &Image, core: usize) -> f64 {
    let n = im.n;
    if core == 0 || core > n || im.confidence.len() != n * n {
        return 0.0;
    }
    let o = (n - core) / 2;
    let sum: f64 =
        (0..core).map(|i| im.confidence[(o + i) * n + o..(o + i) * n + o + core].iter().sum::<f64>()).sum();
    sum / (core * core) as f64
}

/// The shift (cells, on the two plane axes) at which `b` best matches `a`'s core, one way
/// round ([`crate::aligned::shifted_distance`]'s search): `a`'s core cell i lies on `b`'s cell
/// i + shift.
fn best_shift(a: &Image, b: &Image, core: usize, max_shift: usize) -> Option<[i64; 2]> {
    let n = a.n;
    let whole = |im: &Image| im.cells.len() == n * n && im.confidence.len() == n * n;
    if b.n != n || core == 0 || core > n || !whole(a) || !whole(b) {
        return None;
    }
    let o = (n - core) / 2;
    let s = max_shift.min(o) as i64;
    let mut best: Option<(f64, [i64; 2])> = None;
    for dx in -s..=s {
        for dy in -s..=s {
            let (mut sum, mut weight) = (0.0, 0.0);
            for i in 0..core {
                let ra = (o + i) * n + o;
                let rb = ((o + i) as i64 + dx) as usize * n + (o as i64 + dy) as usize;
                for j in 0..core {
                    let w = a.confidence[ra + j] * b.confidence[rb + j];
                    sum += w * (a.cells[ra + j] - b.cells[rb + j]).abs();
                    weight += w;
                }
            }
            if weight > 0.0 {
                let (v, r) = (sum / weight, dx * dx + dy * dy);
                let better = best.is_none_or(|(bv, [bx, by])| v < bv || (v == bv && r < bx * bx + by * by));
                if better {
                    best = Some((v, [dx, dy]));
                }
            }
        }
    }
    best.map(|b| b.1)
}

/// Adds to `classes` the copies the search finds (module documentation). `features` are the
/// detector's features, `points` the resampled points indexed by `hash`, `eps` ε; `ao` gives
/// the images' scale and shifts. Class extents are recomputed for the classes that grew.
#[allow(clippy::too_many_arguments)]
pub fn find_copies(
    classes: &mut [Class],
    features: &[Feature],
    points: &[Point3],
    hash: &SpatialHash,
    eps: f64,
    merge_overlap: f64,
    min_features: usize,
    ao: &AlignedOptions,
    o: &CopiesOptions,
) -> CopiesReport {
    let mut report = CopiesReport::default();
    let n = ao.image_cells;
    if !o.enabled || classes.is_empty() || n == 0 || ao.core_cells == 0 || ao.core_cells > n {
        return report;
    }
    let thin = thin_axes(classes);
    let (items, cells) = pictured(classes, &thin, ao);
    let mut found: Vec<(f64, usize, usize, Aabb, Mat4)> = Vec::new();
    let view: &[Class] = classes;
    // Salient features no instance box holds: a copy must hold some.
    let free: Vec<Point3> = features
        .iter()
        .map(|f| f.position)
        .filter(|&p| !view.iter().any(|c| c.instances.iter().any(|i| i.aabb.contains(p))))
        .collect();
    for t in 0..3 {
        let [a0, a1] = plane_axes(t);
        // Each class's pictured instances on this axis.
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); view.len()];
        for &(ci, k) in items.iter().filter(|(ci, _)| thin[*ci] == Some(t)) {
            members[ci].push(k);
        }
        let cell = cells[t];
        if !(cell > 0.0 && cell.is_finite()) {
            continue;
        }
        let half = 0.5 * n as f64 * cell;
        let picture = |c: Point3, slab_half: f64| -> Option<Image> {
            let (cells, confidence) = depth_image(c, [half, half], slab_half, n, t, points, hash, eps)?;
            Some(Image { n, cells, confidence })
        };
        let mut searched: Vec<Searched> = Vec::new();
        for (ci, m) in members.iter().enumerate() {
            if m.len() < MIN_MEMBERS {
                continue;
            }
            let c = &view[ci];
            let insts: Vec<&Instance> = m.iter().map(|&k| &c.instances[k]).collect();
            let along = median(insts.iter().map(|i| i.aabb.center()[t]).collect());
            let slab_half = 0.5 * ao.slab * median(insts.iter().map(|i| i.aabb.extent()[t]).collect());
            let images: Vec<Option<Image>> = insts
                .par_iter()
                .map(|i| picture(i.aabb.center(), 0.5 * ao.slab * i.aabb.extent()[t]))
                .collect();
            let pictured: Vec<(usize, Image)> =
                images.into_iter().enumerate().filter_map(|(k, im)| Some((k, im?))).collect();
            if pictured.len() < MIN_MEMBERS {
                continue;
            }
            let k = pictured.len();
            // Distances relative to the blank plane's: how much of the other's relief is left
            // unexplained (0: all of it matched, 1: no better than a plain wall).
            let blank_image = Image { n, cells: vec![0.0; n * n], confidence: vec![1.0; n * n] };
            let blank: Vec<f64> = pictured.iter().map(|(_, im)| distance(im, &blank_image, ao)).collect();
            let d: Vec<Vec<f64>> = (0..k)
                .into_par_iter()
                .map(|a| {
                    (0..k)
                        .map(|b| {
                            if a == b { 0.0 } else { distance(&pictured[a].1, &pictured[b].1, ao) / blank[b] }
                        })
                        .collect()
                })
                .collect();
            let typicality: Vec<f64> =
                (0..k).map(|a| median((0..k).filter(|&b| b != a).map(|b| d[a][b]).collect())).collect();
            let spread = median(typicality.clone());
            if !(spread > 0.0 && spread.is_finite()) || spread > o.max_spread {
                continue;
            }
            let mut order: Vec<usize> = (0..k).collect();
            order.sort_by(|&x, &y| typicality[x].total_cmp(&typicality[y]).then(x.cmp(&y)));
            order.truncate(o.templates.max(1));
            let first = insts[pictured[order[0]].0];
            let size: Point3 = [0, 1, 2].map(|a| median(insts.iter().map(|i| i.aabb.extent()[a]).collect()));
            searched.push(Searched {
                class: ci,
                templates: order.iter().map(|&x| pictured[x].1.clone()).collect(),
                blank: order.iter().map(|&x| blank[x]).collect(),
                coverage: median(order.iter().map(|&x| coverage(&pictured[x].1, ao.core_cells)).collect()),
                spread,
                along,
                slab_half,
                size,
                frame: first.frame,
                centre: first.aabb.center(),
            });
        }
        if searched.is_empty() {
            continue;
        }
        report.classes += searched.len();
        let shift_cap = ao.max_shift.min((n - ao.core_cells) / 2).max(1);
        let step = 2.0 * shift_cap as f64 * cell;
        // Grid nodes per searched class: over the box of the points in its slab.
        let mut nodes: Vec<(usize, Point3)> = Vec::new();
        for (si, s) in searched.iter().enumerate() {
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            for p in points.iter().filter(|p| (p[t] - s.along).abs() <= s.slab_half) {
                for (q, a) in [a0, a1].into_iter().enumerate() {
                    lo[q] = lo[q].min(p[a]);
                    hi[q] = hi[q].max(p[a]);
                }
            }
            if !(lo[0] <= hi[0] && lo[1] <= hi[1]) {
                continue;
            }
            // Centred on the region, so that a mirror of the input mirrors the grid onto itself.
            let mid = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
            let reach = |q: usize| (0.5 * (hi[q] - lo[q]) / step).ceil() as i64;
            // Nodes within one step of an unexplained feature in the slab.
            let mut near: std::collections::HashSet<(i64, i64)> = std::collections::HashSet::new();
            for p in free.iter().filter(|p| (p[t] - s.along).abs() <= s.slab_half) {
                let range = |q: usize, x: f64| {
                    let lo = ((x - step - mid[q]) / step).ceil() as i64;
                    let hi = ((x + step - mid[q]) / step).floor() as i64;
                    lo..=hi
                };
                for i in range(0, p[a0]) {
                    for j in range(1, p[a1]) {
                        near.insert((i, j));
                    }
                }
            }
            for i in -reach(0)..=reach(0) {
                for j in -reach(1)..=reach(1) {
                    if !near.contains(&(i, j)) {
                        continue;
                    }
                    let mut c = [0.0; 3];
                    c[t] = s.along;
                    c[a0] = mid[0] + i as f64 * step;
                    c[a1] = mid[1] + j as f64 * step;
                    nodes.push((si, c));
                }
            }
        }
        // Each node against its class's templates: score, and where the block lies.
        // The median relative distance to a class's templates (unnormalised), and the image.
        let raw_at = |s: &Searched, c: Point3| -> Option<(f64, Image)> {
            let im = picture(c, s.slab_half)?;
            if coverage(&im, ao.core_cells) < o.min_coverage * s.coverage {
                return None;
            }
            let ds: Vec<f64> =
                s.templates.iter().zip(&s.blank).map(|(tpl, b)| distance(&im, tpl, ao) / b).collect();
            let v = median(ds);
            v.is_finite().then_some((v, im))
        };
        let score_at = |s: &Searched, c: Point3| raw_at(s, c).map(|(v, im)| (v / s.spread, im));
        let hits: Vec<Option<(f64, usize, Point3)>> = nodes
            .par_iter()
            .map(|&(si, c)| {
                let s = &searched[si];
                let (v, im) = score_at(s, c)?;
                if v > o.accept {
                    return None;
                }
                // Move to where the templates put the block: the template's centre lies on the
                // node image's cell centre − shift.
                let shifts: Vec<[i64; 2]> = s
                    .templates
                    .iter()
                    .filter_map(|tpl| best_shift(&im, tpl, ao.core_cells, ao.max_shift))
                    .collect();
                if shifts.is_empty() {
                    return None;
                }
                let mut moved = c;
                for (q, a) in [a0, a1].into_iter().enumerate() {
                    let m = median(shifts.iter().map(|sh| sh[q] as f64).collect());
                    moved[a] -= m * cell;
                }
                let (raw, _) = raw_at(s, moved)?;
                let v = raw / s.spread;
                // The block is a copy of the class it is most like: another class of this axis
                // whose templates it resembles more takes it, if its own search finds it.
                let likest = searched.iter().enumerate().filter(|&(sj, _)| sj != si).all(|(_, other)| {
                    let mut there = moved;
                    there[t] = other.along;
                    raw_at(other, there).is_none_or(|(r, _)| r > raw)
                });
                (v <= o.accept && raw < 1.0 && likest).then_some((v, si, moved))
            })
            .collect();
        report.nodes += nodes.len();
        for (node, hit) in hits.into_iter().enumerate() {
            let Some((v, si, c)) = hit else { continue };
            report.candidates += 1;
            let s = &searched[si];
            let h = s.size.map(|x| 0.5 * x);
            let aabb = Aabb {
                min: [c[0] - h[0], c[1] - h[1], c[2] - h[2]],
                max: [c[0] + h[0], c[1] + h[1], c[2] + h[2]],
            };
            let mut frame = s.frame;
            for (r, row) in frame.iter_mut().take(3).enumerate() {
                row[3] += c[r] - s.centre[r];
            }
            found.push((v, node, s.class, aabb, frame));
        }
    }
    // Greedy, best score first; ties by node (per axis), then class.
    found.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    let mut added: Vec<(usize, Instance)> = Vec::new();
    for (_, _, ci, aabb, frame) in found {
        let inside: Vec<usize> =
            (0..features.len()).filter(|&f| aabb.contains(features[f].position)).collect();
        if inside.len() < min_features.max(1) {
            continue;
        }
        let centre = nearest_feature(features, &inside, aabb.center()).expect("at least one feature");
        let inst = Instance {
            centre,
            flip: 0,
            features: inside,
            links: Vec::new(),
            frame,
            aabb,
            footprint: None,
            turn: 0.0,
        };
        let clashes = classes.iter().any(|c| overlaps_any(&inst, &c.instances, merge_overlap))
            || added.iter().any(|(_, q)| overlaps_any(&inst, std::slice::from_ref(q), merge_overlap));
        if clashes {
            continue;
        }
        added.push((ci, inst));
    }
    report.added = added.len();
    let mut grown = vec![false; classes.len()];
    for (ci, inst) in added {
        classes[ci].instances.push(inst);
        grown[ci] = true;
    }
    for (c, g) in classes.iter_mut().zip(grown) {
        if g {
            c.extent = median_box_size(&c.instances);
        }
    }
    report
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::aligned::tests::square;
    use crate::content::tests::{H, Window, class_of, opening, styled_scene};

    /// Eight windows 3 m apart, styles as `two_bars`, sized as the benchmark scenes' styles (as
    /// [`crate::aligned`]'s tests: two-transom 1.0 × 2.2 m, one-transom 1.2 × 1.5 m, each
    /// varied by up to 10% per axis), their wall, its hash, and salient features: six at the
    /// corners and bars of each window, and six on the plain wall between each two windows.
    fn scene(two_bars: [bool; 8]) -> (Vec<Window>, Vec<Point3>, SpatialHash, Vec<Feature>) {
        let (ws, pts, hash) =
            styled_scene(two_bars, |two| if two { (1.0 / 1.2, 2.2 / 1.6) } else { (1.0, 1.5 / 1.6) }, 0.1);
        let feature =
            |p: Point3| Feature { point: 0, position: p, x: [0.0, 0.0, 1.0], y: [1.0, 0.0, 0.0], kappa: 1.0 };
        let mut features = Vec::new();
        for w in &ws {
            let b = opening(w);
            for (u, v) in [(0.1, 0.1), (0.9, 0.1), (0.1, 0.9), (0.9, 0.9), (0.5, 0.3), (0.5, 0.7)] {
                let x = b.min[0] + u * (b.max[0] - b.min[0]);
                let y = b.min[1] + v * (b.max[1] - b.min[1]);
                features.push(feature([x, y, -0.1]));
            }
            // Plain wall 1.5 m to the right of the window's centre (between two windows).
            for k in 0..6 {
                features.push(feature([w.0 + 1.5, 0.3 + 0.45 * k as f64, 0.0]));
            }
        }
        (ws, pts, hash, features)
    }

    /// Each class's members by window (the window whose opening the box overlaps most), sorted.
    fn members(classes: &[Class], ws: &[Window]) -> Vec<Vec<usize>> {
        classes
            .iter()
            .map(|c| {
                let mut m: Vec<usize> = c
                    .instances
                    .iter()
                    .map(|i| {
                        (0..ws.len())
                            .max_by(|&a, &b| {
                                let share = |k: usize| {
                                    i.aabb.intersection(&opening(&ws[k])).map_or(0.0, |x| x.volume())
                                };
                                share(a).total_cmp(&share(b))
                            })
                            .expect("windows")
                    })
                    .collect();
                m.sort_unstable();
                m
            })
            .collect()
    }

    fn run(
        classes: &mut [Class],
        pts: &[Point3],
        hash: &SpatialHash,
        features: &[Feature],
        o: &CopiesOptions,
    ) -> CopiesReport {
        find_copies(classes, features, pts, hash, H, 0.5, 5, &AlignedOptions::default(), o)
    }

    #[test]
    fn a_window_no_class_covers_is_added_to_its_style() {
        let (ws, pts, hash, features) = scene([false, false, false, false, true, true, true, true]);
        // Windows 3 (one transom) and 7 (two) are in no class.
        let mut classes = vec![class_of(&ws, &[0, 1, 2], 0, 0.0), class_of(&ws, &[4, 5, 6], 1, 0.0)];
        let r = run(&mut classes, &pts, &hash, &features, &CopiesOptions::default());
        assert_eq!((r.classes, r.added), (2, 2), "{r:?}");
        assert_eq!(members(&classes, &ws), vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]]);
        // The added boxes lie on their windows: most of each opening, and of each box, shared.
        for (c, k) in [(0, 3), (1, 7)] {
            let added = classes[c].instances.last().expect("added");
            let o = opening(&ws[k]);
            let shared = added.aabb.intersection(&o).map_or(0.0, |x| x.volume());
            assert!(
                shared > 0.6 * o.volume() && shared > 0.6 * added.aabb.volume(),
                "window {k}: {:?}",
                added.aabb
            );
            assert!(added.features.len() >= 5 && added.features.contains(&added.centre));
        }
        // Searched again, there is nothing left to add.
        let again = run(&mut classes, &pts, &hash, &features, &CopiesOptions::default());
        assert_eq!(again.added, 0, "{again:?}");
    }

    #[test]
    fn nothing_is_added_where_no_copy_stands_or_when_switched_off() {
        // Every window is already in a class: the plain wall between them, with features of its
        // own, is no copy.
        let (ws, pts, hash, features) = scene([false, false, false, false, true, true, true, true]);
        let complete = vec![class_of(&ws, &[0, 1, 2, 3], 0, 0.0), class_of(&ws, &[4, 5, 6, 7], 1, 0.0)];
        let mut classes = complete.clone();
        let r = run(&mut classes, &pts, &hash, &features, &CopiesOptions::default());
        assert_eq!((r.classes, r.added), (2, 0), "{r:?}");
        assert!(r.nodes > 0);
        assert_eq!(classes, complete);
        // Off, or a class of two pictured members (too few to measure a spread): no search.
        let mut missing = vec![class_of(&ws, &[0, 1, 2], 0, 0.0), class_of(&ws, &[4, 5], 1, 0.0)];
        let off = CopiesOptions { enabled: false, ..Default::default() };
        assert_eq!(run(&mut missing.clone(), &pts, &hash, &features, &off), CopiesReport::default());
        let r = run(&mut missing, &pts, &hash, &features, &CopiesOptions::default());
        assert_eq!((r.classes, r.added), (1, 1), "{r:?}");
        assert_eq!(members(&missing, &ws), vec![vec![0, 1, 2, 3], vec![4, 5]]);
    }

    #[test]
    fn a_copy_needs_the_features_of_a_block() {
        // Without features in window 3's box it is not added (a picture alone is not a block).
        let (ws, pts, hash, features) = scene([false, false, false, false, true, true, true, true]);
        let o3 = opening(&ws[3]);
        let grown = Aabb { min: o3.min.map(|v| v - 0.5), max: o3.max.map(|v| v + 0.5) };
        let fewer: Vec<Feature> = features.into_iter().filter(|f| !grown.contains(f.position)).collect();
        let mut classes = vec![class_of(&ws, &[0, 1, 2], 0, 0.0), class_of(&ws, &[4, 5, 6, 7], 1, 0.0)];
        let r = run(&mut classes, &pts, &hash, &fewer, &CopiesOptions::default());
        assert_eq!(r.added, 0, "{r:?}");
        assert!(r.candidates > 0, "the picture matched: {r:?}");
    }

    #[test]
    fn the_best_shift_points_from_a_core_cell_to_the_same_relief_in_the_other_image() {
        // `a`'s square at (7, 7), `b`'s at (9, 4): a's cell i lies on b's cell i + (2, −3).
        let a = square(21, 7, 7, 4);
        for (bx, by, want) in [(9, 4, [2, -3]), (7, 7, [0, 0]), (4, 7, [-3, 0]), (7, 11, [0, 4])] {
            assert_eq!(best_shift(&a, &square(21, bx, by, 4), 11, 5), Some(want), "square at ({bx}, {by})");
        }
        // A blank patch ties at every shift: the shift nearest zero is kept.
        let blank = Image { n: 21, cells: vec![0.0; 441], confidence: vec![0.9; 441] };
        assert_eq!(best_shift(&blank, &blank, 11, 5), Some([0, 0]));
        // Nothing seen: no shift.
        let blind = Image { confidence: vec![0.0; 441], ..blank.clone() };
        assert_eq!(best_shift(&blind, &blank, 11, 5), None);
    }

    #[test]
    fn options_are_checked() {
        assert!(CopiesOptions::default().validate().is_ok());
        let bad = [
            CopiesOptions { templates: 0, ..Default::default() },
            CopiesOptions { accept: 0.0, ..Default::default() },
            CopiesOptions { accept: f64::NAN, ..Default::default() },
            CopiesOptions { max_spread: 0.0, ..Default::default() },
            CopiesOptions { min_coverage: -0.1, ..Default::default() },
        ];
        for o in bad {
            let (name, _) = o.validate().expect_err("rejected");
            assert!(name.starts_with("extent.copies."), "{name}");
        }
    }
}
