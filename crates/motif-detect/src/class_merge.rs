//! Merging classes that describe the same building block (not in the thesis): after the MDL
//! rounds (5.4), classes whose instances' surfaces agree are joined into one class.
//!
//! Why: the MDL scheme keeps one cluster per round and [`crate::instances::ClassSplit`] splits a
//! cluster where its instances' surfaces disagree. Under occlusion and per-instance variation
//! one block (a window style) then often comes out as two or three classes — found through
//! different words in different rounds, or split apart in one round because different scanners
//! saw different parts of its instances. The evaluation (5.5.2) scores each ground-truth class
//! against its best detected class only, so every such split loses recall.
//!
//! Two classes are joined when the mean surface distance between their instances (the distance
//! of [`crate::instances::ClassSplit::Surface`]: 1 − the larger directed fraction of crease
//! points that find a crease point within [`InstanceOptions::surface_tolerance`] of the other
//! instance) is below [`InstanceOptions::split_min_distance`], the distance below which the split
//! never separates two groups either: such classes would have stayed one class had they come out
//! of one cluster. Joins are greedy, closest first, with complete linkage over joined classes.
//! Instances of two classes share no words, so the rigid motion between two instances is found
//! by ICP on their crease points, started from the translation between their centroids.
//! A ratio test like the split's (between-class distance against within-class distance) was
//! tried and dropped: on strongly varied scenes every class is loose, and the ratio test joined
//! different window styles.

use motif_core::Point3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::grid::SpatialHash;
use crate::instances::{Class, InstanceOptions, crease_samples, kabsch, overlaps_any, surface_hit_fraction};

/// Whether classes are merged after the MDL rounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ClassMerge {
    /// Keep every class the MDL rounds kept (the thesis).
    None,
    /// Join classes whose instances' surfaces agree (see the module documentation). The default.
    #[default]
    Surface,
}

/// At most this many instances of a class take part in the distance averages.
const SAMPLE_INSTANCES: usize = 6;
/// At most this many crease points represent an instance.
const SAMPLE_POINTS: usize = 200;
/// ICP iterations per instance pair.
const ICP_ITERATIONS: usize = 8;

/// The crease points inside an instance box, at most [`SAMPLE_POINTS`], in index order.
fn region(surface: &SpatialHash, aabb: &motif_core::geometry::Aabb) -> Vec<Point3> {
    crease_samples(surface, aabb.center(), aabb.diagonal() / 2.0, SAMPLE_POINTS, |p| aabb.contains(p))
}

fn centroid(p: &[Point3]) -> nalgebra::Vector3<f64> {
    let n = p.len().max(1) as f64;
    p.iter().fold(nalgebra::Vector3::zeros(), |s, q| s + nalgebra::Vector3::new(q[0], q[1], q[2])) / n
}

/// Surface distance of two regions: 1 − the larger of the two directed fractions of points that
/// find a crease point within `tol` after ICP carries one region onto the other.
fn surface_distance(a: &[Point3], b: &[Point3], surface: &SpatialHash, tol: f64, reach: f64) -> f64 {
    if a.len() < 3 || b.len() < 3 {
        return 1.0;
    }
    let shift = centroid(b) - centroid(a);
    let mut t = nalgebra::Isometry3::translation(shift.x, shift.y, shift.z);
    let reach2 = reach * reach;
    for _ in 0..ICP_ITERATIONS {
        // Correspondences: every other point of `a`, its nearest point of `b` (a brute-force scan
        // of at most `SAMPLE_POINTS`, cheaper than a radius query of a fine hash at this reach).
        let mut from = Vec::new();
        let mut to = Vec::new();
        for p in a.iter().step_by(2) {
            let q = t * nalgebra::Point3::new(p[0], p[1], p[2]);
            let q = [q.x, q.y, q.z];
            let best =
                b.iter().map(|&r| (motif_core::geometry::dist2(r, q), r)).min_by(|x, y| x.0.total_cmp(&y.0));
            if let Some((_, r)) = best.filter(|x| x.0 <= reach2) {
                from.push(*p);
                to.push(r);
            }
        }
        match kabsch(&from, &to) {
            Some(k) => t = k,
            None => break,
        }
    }
    1.0 - surface_hit_fraction(a, &t, surface, tol).max(surface_hit_fraction(b, &t.inverse(), surface, tol))
}

/// Joins classes that describe the same block (see the module documentation); returns the
/// classes, largest first, and the number of joins.
pub fn merge_classes(
    classes: Vec<Class>,
    surface: &SpatialHash,
    eps: f64,
    o: &InstanceOptions,
) -> (Vec<Class>, usize) {
    let n = classes.len();
    if n < 2 || surface.is_empty() {
        return (classes, 0);
    }
    let tol = o.surface_tolerance * eps;
    // ICP correspondences within one HOC cell (8ε): instances of one block found through
    // different words can be offset by about that much.
    let reach = 8.0 * eps;
    let regions: Vec<Vec<Vec<Point3>>> = classes
        .iter()
        .map(|c| c.instances.iter().take(SAMPLE_INSTANCES).map(|i| region(surface, &i.aabb)).collect())
        .collect();
    // Mean distance between the sampled instances of classes a < b.
    let pairs: Vec<(usize, usize)> = (0..n).flat_map(|a| ((a + 1)..n).map(move |b| (a, b))).collect();
    let means: Vec<f64> = pairs
        .par_iter()
        .map(|&(a, b)| {
            let mut s = 0.0;
            let mut m = 0usize;
            for ra in &regions[a] {
                for rb in &regions[b] {
                    s += surface_distance(ra, rb, surface, tol, reach);
                    m += 1;
                }
            }
            if m == 0 { 1.0 } else { s / m as f64 }
        })
        .collect();
    let mut d = vec![0.0; n * n];
    for (&(a, b), &v) in pairs.iter().zip(&means) {
        d[a * n + b] = v;
        d[b * n + a] = v;
    }
    // Greedy: join the closest pair closer than the split's minimum distance, until none is
    // left; the distance of two groups is the largest of their classes' (complete linkage, so a
    // join never makes the next one easier).
    let mut group: Vec<usize> = (0..n).collect();
    let mut joins = 0;
    loop {
        let mut best: Option<(f64, usize, usize)> = None;
        for a in 0..n {
            for b in (a + 1)..n {
                if group[a] != a || group[b] != b {
                    continue;
                }
                let mut h = 0.0f64;
                for x in (0..n).filter(|&x| group[x] == a) {
                    for y in (0..n).filter(|&y| group[y] == b) {
                        h = h.max(d[x * n + y]);
                    }
                }
                let apart = h >= o.split_min_distance;
                if !apart && best.is_none_or(|x| h < x.0) {
                    best = Some((h, a, b));
                }
            }
        }
        let Some((_, a, b)) = best else { break };
        for g in group.iter_mut() {
            if *g == b {
                *g = a;
            }
        }
        joins += 1;
    }
    let mut slots: Vec<Option<Class>> = classes.into_iter().map(Some).collect();
    let mut out: Vec<Class> = Vec::new();
    for a in 0..n {
        if group[a] != a {
            continue;
        }
        let Some(mut c) = slots[a].take() else { continue };
        for b in (a + 1)..n {
            if group[b] != a {
                continue;
            }
            let Some(other) = slots[b].take() else { continue };
            for inst in other.instances {
                if !overlaps_any(&inst, &c.instances, o.merge_overlap) {
                    c.instances.push(inst);
                }
            }
            c.words.extend(other.words);
        }
        c.words.sort_unstable();
        c.words.dedup();
        out.push(c);
    }
    out.sort_by_key(|c| std::cmp::Reverse(c.instances.len()));
    (out, joins)
}

#[cfg(test)]
mod tests {
    use super::*;
    use motif_core::geometry::{Aabb, IDENTITY4};

    use crate::instances::Instance;

    /// Crease points along the edges of a `w × h` rectangle in the plane z = 0 at `origin`, every
    /// 0.05, plus a cross bar at a fraction `bar` of the height.
    fn frame(origin: Point3, w: f64, h: f64, bar: f64) -> Vec<Point3> {
        let mut v = Vec::new();
        let steps = |l: f64| (l / 0.05).round() as usize;
        for i in 0..=steps(w) {
            let x = origin[0] + i as f64 * 0.05;
            for y in [0.0, h, bar * h] {
                v.push([x, origin[1] + y, origin[2]]);
            }
        }
        for j in 0..=steps(h) {
            let y = origin[1] + j as f64 * 0.05;
            v.push([origin[0], y, origin[2]]);
            v.push([origin[0] + w, y, origin[2]]);
        }
        v
    }

    fn class(origins: &[Point3], w: f64, h: f64, word: usize) -> Class {
        let instances = origins
            .iter()
            .map(|o| Instance {
                centre: 0,
                flip: 0,
                features: vec![0, 1, 2],
                links: vec![],
                frame: IDENTITY4,
                aabb: Aabb {
                    min: [o[0] - 0.1, o[1] - 0.1, o[2] - 0.1],
                    max: [o[0] + w + 0.1, o[1] + h + 0.1, o[2] + 0.1],
                },
                footprint: None,
                turn: 0.0,
            })
            .collect();
        Class { words: vec![word], centre_word: word, extent: [w, h, 0.2], instances, cluster: word }
    }

    #[test]
    fn classes_of_one_block_are_joined_and_other_blocks_kept_apart() {
        // Blocks of style A (1 × 1, bar at mid height) found as two classes, and style B (1 × 2,
        // bar at 0.4 of the height) as a third; every instance slightly shifted so no two are identical.
        let a1: Vec<Point3> = vec![[0.0, 0.0, 0.0], [3.0, 0.01, 0.0], [6.0, 0.0, 0.01]];
        let a2: Vec<Point3> = vec![[9.0, 0.02, 0.0], [12.0, 0.0, 0.0]];
        let b: Vec<Point3> = vec![[0.0, 5.0, 0.0], [3.0, 5.01, 0.0], [6.0, 5.0, 0.0]];
        let mut pts = Vec::new();
        for o in a1.iter().chain(&a2) {
            pts.extend(frame(*o, 1.0, 1.0, 0.5));
        }
        for o in &b {
            pts.extend(frame(*o, 1.0, 2.0, 0.4));
        }
        let eps = 0.05;
        let o = InstanceOptions::default();
        let surface = SpatialHash::new(&pts, o.surface_tolerance * eps);
        let classes = vec![class(&a1, 1.0, 1.0, 0), class(&b, 1.0, 2.0, 1), class(&a2, 1.0, 1.0, 2)];
        let (merged, joins) = merge_classes(classes.clone(), &surface, eps, &o);
        assert_eq!(joins, 1);
        assert_eq!(merged.len(), 2);
        assert_eq!(merged[0].instances.len(), 5);
        assert_eq!(merged[0].words, vec![0, 2]);
        assert_eq!(merged[1].instances.len(), 3);
        // With a zero distance threshold nothing is joined.
        let none = InstanceOptions { split_min_distance: 0.0, ..o };
        assert_eq!(merge_classes(classes, &surface, eps, &none).1, 0);
    }
}
