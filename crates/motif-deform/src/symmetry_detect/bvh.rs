//! Exact closest-point queries on a triangle mesh: a bounding-volume hierarchy of axis-aligned
//! boxes over the triangles (median split on the longest axis of the centroid box, at most
//! [`LEAF_SIZE`] triangles per leaf) with branch-and-bound nearest search, and the exact
//! point–triangle closest point (the Voronoi-region case analysis of Ericson, *Real-Time
//! Collision Detection*, 2005, §5.1.5).

use motif_core::Point3;
use motif_core::geometry::{add, closest_point_on_triangle, cross, dot, normalize, scale, sub};
use rayon::prelude::*;

/// Largest number of triangles in a leaf.
const LEAF_SIZE: usize = 4;

/// One box of the hierarchy. An inner node's left child is the next node in the array; `right`
/// is the index of its right child. A leaf (`count > 0`) holds triangles `start..start + count`
/// of the reordered triangle arrays.
#[derive(Debug, Clone, Copy)]
struct Node {
    min: Point3,
    max: Point3,
    start: u32,
    count: u32,
    right: u32,
}

/// The closest surface point found for a query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Hit {
    /// Squared distance from the query to `point`.
    pub d2: f64,
    /// The closest point on the surface.
    pub point: Point3,
    /// Unit normal of the triangle `point` lies in.
    pub normal: Point3,
}

/// A bounding-volume hierarchy over the triangles of a mesh, answering exact closest-point
/// queries. Triangles are copied (corners and unit normal) in leaf order for cache locality.
#[derive(Debug, Clone)]
pub(crate) struct TriangleBvh {
    nodes: Vec<Node>,
    corners: Vec<[Point3; 3]>,
    normals: Vec<Point3>,
}

impl TriangleBvh {
    /// Builds the hierarchy over the given triangles (corner positions). Degenerate triangles are
    /// allowed (their normal is zero) but should be removed by the caller. Returns `None` when
    /// there is no triangle.
    pub fn new(triangles: &[[Point3; 3]]) -> Option<TriangleBvh> {
        if triangles.is_empty() {
            return None;
        }
        let split = split_long_triangles(triangles);
        let triangles: &[[Point3; 3]] = &split;
        let centroids: Vec<Point3> =
            triangles.iter().map(|t| scale(add(add(t[0], t[1]), t[2]), 1.0 / 3.0)).collect();
        let boxes: Vec<(Point3, Point3)> = triangles
            .par_iter()
            .map(|t| {
                let mut lo = t[0];
                let mut hi = t[0];
                for p in &t[1..] {
                    for k in 0..3 {
                        lo[k] = lo[k].min(p[k]);
                        hi[k] = hi[k].max(p[k]);
                    }
                }
                (lo, hi)
            })
            .collect();
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
        let nodes = build(&mut order, 0, &boxes, &centroids);
        let corners: Vec<[Point3; 3]> = order.iter().map(|&i| triangles[i as usize]).collect();
        let normals = corners
            .iter()
            .map(|t| normalize(cross(sub(t[1], t[0]), sub(t[2], t[0]))).unwrap_or([0.0; 3]))
            .collect();
        Some(TriangleBvh { nodes, corners, normals })
    }

    /// The closest surface point to `q` if it is closer than `sqrt(max_d2)`; `None` otherwise.
    /// The search stops refining once no box can be closer by more than `slack` (absolute): the
    /// distance returned is exact for the triangle found and at most `slack` above the true
    /// minimum (a query on the surface then ends at the first triangle it lies on).
    pub fn closest(&self, q: Point3, max_d2: f64, slack: f64) -> Option<Hit> {
        let mut best_d2 = max_d2;
        let mut prune_d2 = max_d2;
        let mut best: Option<(Point3, u32)> = None;
        let mut stack = [0u32; 64];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if box_d2(node, q) >= prune_d2 {
                continue;
            }
            if node.count > 0 {
                for t in node.start..node.start + node.count {
                    let c = closest_on_triangle(q, &self.corners[t as usize]);
                    let d2 = dist2(q, c);
                    if d2 < best_d2 {
                        best_d2 = d2;
                        best = Some((c, t));
                        let r = (d2.sqrt() - slack).max(0.0);
                        prune_d2 = r * r;
                    }
                }
            } else {
                let left = stack[top] + 1;
                let right = node.right;
                let (nl, nr) = (&self.nodes[left as usize], &self.nodes[right as usize]);
                let dl = box_d2(nl, q);
                let dr = box_d2(nr, q);
                // Push the farther child first so the nearer one is searched first; when the
                // query is inside both boxes, the one whose centre is nearer.
                let left_first = if dl == dr { centre_d2(nl, q) <= centre_d2(nr, q) } else { dl < dr };
                let (near, far, dfar) = if left_first { (left, right, dr) } else { (right, left, dl) };
                if dfar < prune_d2 && top < stack.len() {
                    stack[top] = far;
                    top += 1;
                }
                if top < stack.len() {
                    stack[top] = near;
                    top += 1;
                }
            }
        }
        best.map(|(point, t)| Hit { d2: best_d2, point, normal: self.normals[t as usize] })
    }
}

/// Long triangles (CAD exports fan whole faces into slivers) make boxes that overlap everywhere.
/// Triangles whose longest edge exceeds twice the median longest edge are bisected at their
/// longest edge until they do not; the pieces partition the same surface, so closest points are
/// unchanged. The threshold grows if splitting would more than triple the triangle count.
fn split_long_triangles(tris: &[[Point3; 3]]) -> Vec<[Point3; 3]> {
    let longest = |t: &[Point3; 3]| -> (usize, f64) {
        (0..3)
            .map(|k| (k, dist2(t[k], t[(k + 1) % 3])))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0, 0.0))
    };
    let mut lengths: Vec<f64> = tris.iter().map(|t| longest(t).1).collect();
    let mid = lengths.len() / 2;
    lengths.select_nth_unstable_by(mid, f64::total_cmp);
    let mut h2 = 4.0 * lengths[mid];
    // Pieces from bisecting until the longest edge is at most h: about (L/h)² for fat
    // triangles; estimate and raise h until the total stays within 3× the input.
    for _ in 0..20 {
        let pieces: f64 = tris.iter().map(|t| (longest(t).1 / h2).max(1.0)).sum();
        if pieces <= 3.0 * tris.len() as f64 || h2.is_nan() || h2 <= 0.0 {
            break;
        }
        h2 *= 2.0;
    }
    if h2.is_nan() || h2 <= 0.0 {
        return tris.to_vec();
    }
    let mut out = Vec::with_capacity(tris.len());
    let mut stack: Vec<([Point3; 3], u32)> = Vec::new();
    for t in tris {
        stack.push((*t, 0));
        while let Some((t, depth)) = stack.pop() {
            let (k, l2) = longest(&t);
            if l2 <= h2 || depth >= 24 {
                out.push(t);
                continue;
            }
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            let m = scale(add(a, b), 0.5);
            // Both halves keep the winding of the original.
            stack.push(([a, m, c], depth + 1));
            stack.push(([m, b, c], depth + 1));
        }
    }
    out
}

/// Sorts points along a Morton (Z-order) curve of their bounding box, so that consecutive
/// queries walk the same parts of the hierarchy (far fewer cache misses than random order).
pub(crate) fn sort_spatially(points: &mut [Point3]) {
    let Some(b) = motif_core::geometry::Aabb::from_points(points) else { return };
    let ext = b.extent();
    let key = |p: &Point3| -> u64 {
        let mut q = [0u64; 3];
        for i in 0..3 {
            let t = if ext[i] > 0.0 { (p[i] - b.min[i]) / ext[i] } else { 0.0 };
            q[i] = (t.clamp(0.0, 1.0) * 2_097_151.0) as u64;
        }
        let mut k = 0u64;
        for bit in (0..21).rev() {
            for (i, v) in q.iter().enumerate() {
                k |= ((v >> bit) & 1) << (3 * bit + 2 - i as u32);
            }
        }
        k
    };
    let mut keyed: Vec<(u64, Point3)> = points.par_iter().map(|p| (key(p), *p)).collect();
    keyed.par_sort_unstable_by(|a, b| {
        a.0.cmp(&b.0).then(a.1.partial_cmp(&b.1).unwrap_or(std::cmp::Ordering::Equal))
    });
    for (dst, (_, p)) in points.iter_mut().zip(keyed) {
        *dst = p;
    }
}

fn dist2(a: Point3, b: Point3) -> f64 {
    let d = sub(a, b);
    dot(d, d)
}

/// Squared distance from `q` to the centre of the node's box.
#[inline]
fn centre_d2(n: &Node, q: Point3) -> f64 {
    (0..3).map(|k| (0.5 * (n.min[k] + n.max[k]) - q[k]).powi(2)).sum()
}

/// Squared distance from `q` to the node's box (0 inside).
#[inline]
fn box_d2(n: &Node, q: Point3) -> f64 {
    let mut s = 0.0;
    for k in 0..3 {
        let d = if q[k] < n.min[k] {
            n.min[k] - q[k]
        } else if q[k] > n.max[k] {
            q[k] - n.max[k]
        } else {
            0.0
        };
        s += d * d;
    }
    s
}

/// Subtrees with more triangles than this are built in parallel.
const PARALLEL_BUILD: usize = 8192;

/// Bounds of the triangles and of their centroids.
fn bounds(order: &[u32], boxes: &[(Point3, Point3)], centroids: &[Point3]) -> [Point3; 4] {
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    let mut cmin = [f64::INFINITY; 3];
    let mut cmax = [f64::NEG_INFINITY; 3];
    for &i in order {
        let (lo, hi) = boxes[i as usize];
        for k in 0..3 {
            min[k] = min[k].min(lo[k]);
            max[k] = max[k].max(hi[k]);
        }
        let c = centroids[i as usize];
        for k in 0..3 {
            cmin[k] = cmin[k].min(c[k]);
            cmax[k] = cmax[k].max(c[k]);
        }
    }
    [min, max, cmin, cmax]
}

/// Builds the subtree over `order[..]` (whose first triangle is at global position `offset`)
/// and returns its nodes in depth-first order, indices local to the subtree (the root is 0).
/// Large subtrees build their two halves in parallel.
fn build(order: &mut [u32], offset: usize, boxes: &[(Point3, Point3)], centroids: &[Point3]) -> Vec<Node> {
    if order.len() <= PARALLEL_BUILD {
        let mut nodes = Vec::with_capacity(order.len() / 2 + 1);
        build_sequential(&mut nodes, order, offset, boxes, centroids);
        return nodes;
    }
    let [min, max, cmin, cmax] = bounds(order, boxes, centroids);
    let mid = sah_split(order, boxes, centroids, cmin, cmax);
    let (lo, hi) = order.split_at_mut(mid);
    let (left, right) =
        rayon::join(|| build(lo, offset, boxes, centroids), || build(hi, offset + mid, boxes, centroids));
    let right_at = 1 + left.len() as u32;
    let mut nodes = Vec::with_capacity(1 + left.len() + right.len());
    nodes.push(Node { min, max, start: offset as u32, count: 0, right: right_at });
    for (subtree, shift) in [(left, 1), (right, right_at)] {
        nodes.extend(subtree.into_iter().map(|mut x| {
            if x.count == 0 {
                x.right += shift;
            }
            x
        }));
    }
    nodes
}

/// Builds the subtree over `order[..]` into `nodes` (global indices) and returns its root.
fn build_sequential(
    nodes: &mut Vec<Node>,
    order: &mut [u32],
    offset: usize,
    boxes: &[(Point3, Point3)],
    centroids: &[Point3],
) -> u32 {
    let [min, max, cmin, cmax] = bounds(order, boxes, centroids);
    let index = nodes.len() as u32;
    nodes.push(Node { min, max, start: offset as u32, count: order.len() as u32, right: 0 });
    if order.len() <= LEAF_SIZE {
        return index;
    }
    let mid = sah_split(order, boxes, centroids, cmin, cmax);
    let (lo, hi) = order.split_at_mut(mid);
    nodes[index as usize].count = 0;
    build_sequential(nodes, lo, offset, boxes, centroids);
    let right = build_sequential(nodes, hi, offset + mid, boxes, centroids);
    nodes[index as usize].right = right;
    index
}

/// Nodes with at most this many triangles are split at the median.
const SAH_MIN: usize = 64;

/// Bins of the surface-area-heuristic split.
const BINS: usize = 16;

fn half_area(min: Point3, max: Point3) -> f64 {
    let e = [max[0] - min[0], max[1] - min[1], max[2] - min[2]];
    e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
}

/// Partitions `order` by the binned surface-area heuristic (the split minimising
/// `area(left)·n(left) + area(right)·n(right)` over 16 centroid bins per axis; Wald 2007) and
/// returns the size of the left part; falls back to the median on the longest centroid axis.
fn sah_split(
    order: &mut [u32],
    boxes: &[(Point3, Point3)],
    centroids: &[Point3],
    cmin: Point3,
    cmax: Point3,
) -> usize {
    let mut best: Option<(f64, usize, usize)> = None; // (cost, axis, bins on the left)
    // Small nodes: the median is nearly as good and much cheaper.
    let axes = if order.len() > SAH_MIN { 0..3 } else { 0..0 };
    for axis in axes {
        let ext = cmax[axis] - cmin[axis];
        if ext.is_nan() || ext <= 0.0 {
            continue;
        }
        let bin_of = |c: f64| (((c - cmin[axis]) / ext * BINS as f64) as usize).min(BINS - 1);
        let mut bmin = [[f64::INFINITY; 3]; BINS];
        let mut bmax = [[f64::NEG_INFINITY; 3]; BINS];
        let mut count = [0usize; BINS];
        for &i in order.iter() {
            let b = bin_of(centroids[i as usize][axis]);
            count[b] += 1;
            let (lo, hi) = boxes[i as usize];
            for k in 0..3 {
                bmin[b][k] = bmin[b][k].min(lo[k]);
                bmax[b][k] = bmax[b][k].max(hi[k]);
            }
        }
        // Sweep from the right to get the right-hand areas, then from the left.
        let mut right_area = [0.0; BINS];
        let (mut rmin, mut rmax, mut rn) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3], 0usize);
        let mut right_n = [0usize; BINS];
        for b in (1..BINS).rev() {
            rn += count[b];
            for k in 0..3 {
                rmin[k] = rmin[k].min(bmin[b][k]);
                rmax[k] = rmax[k].max(bmax[b][k]);
            }
            right_area[b] = if rn > 0 { half_area(rmin, rmax) } else { 0.0 };
            right_n[b] = rn;
        }
        let (mut lmin, mut lmax, mut ln) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3], 0usize);
        for b in 0..BINS - 1 {
            ln += count[b];
            for k in 0..3 {
                lmin[k] = lmin[k].min(bmin[b][k]);
                lmax[k] = lmax[k].max(bmax[b][k]);
            }
            if ln == 0 || right_n[b + 1] == 0 {
                continue;
            }
            let cost = half_area(lmin, lmax) * ln as f64 + right_area[b + 1] * right_n[b + 1] as f64;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b + 1));
            }
        }
    }
    if let Some((_, axis, left_bins)) = best {
        let ext = cmax[axis] - cmin[axis];
        let bin_of = |c: f64| (((c - cmin[axis]) / ext * BINS as f64) as usize).min(BINS - 1);
        let mut l = 0;
        for i in 0..order.len() {
            if bin_of(centroids[order[i] as usize][axis]) < left_bins {
                order.swap(i, l);
                l += 1;
            }
        }
        if l > 0 && l < order.len() {
            return l;
        }
    }
    let ext = [cmax[0] - cmin[0], cmax[1] - cmin[1], cmax[2] - cmin[2]];
    let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
        0
    } else if ext[1] >= ext[2] {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
    });
    mid
}

/// The point of the triangle `t` closest to `p` (see [`closest_point_on_triangle`]).
pub(crate) fn closest_on_triangle(p: Point3, t: &[Point3; 3]) -> Point3 {
    closest_point_on_triangle(p, t[0], t[1], t[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn brute(p: Point3, tris: &[[Point3; 3]]) -> f64 {
        tris.iter().map(|t| dist2(p, closest_on_triangle(p, t))).fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn closest_point_regions() {
        let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        for (p, expected) in [
            ([0.2, 0.2, 1.0], [0.2, 0.2, 0.0]),   // face
            ([-1.0, -1.0, 0.0], [0.0, 0.0, 0.0]), // corner a
            ([2.0, -0.5, 0.0], [1.0, 0.0, 0.0]),  // corner b
            ([-0.5, 2.0, 0.5], [0.0, 1.0, 0.0]),  // corner c
            ([0.5, -1.0, 3.0], [0.5, 0.0, 0.0]),  // edge ab
            ([-1.0, 0.3, 0.0], [0.0, 0.3, 0.0]),  // edge ac
            ([1.0, 1.0, 0.0], [0.5, 0.5, 0.0]),   // edge bc
        ] {
            let q = closest_on_triangle(p, &t);
            assert!(dist2(q, expected) < 1e-24, "{p:?} -> {q:?}");
        }
    }

    #[test]
    fn bvh_matches_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut tris = Vec::new();
        for _ in 0..300 {
            let o: Point3 = [rng.random::<f64>(), rng.random::<f64>(), rng.random::<f64>()];
            let mut t = [o; 3];
            for c in t.iter_mut().skip(1) {
                *c =
                    add(o, [rng.random::<f64>() * 0.1, rng.random::<f64>() * 0.1, rng.random::<f64>() * 0.1]);
            }
            tris.push(t);
        }
        let bvh = TriangleBvh::new(&tris).unwrap();
        for _ in 0..500 {
            let q: Point3 = [rng.random::<f64>() * 1.4 - 0.2, rng.random::<f64>(), rng.random::<f64>()];
            let hit = bvh.closest(q, f64::INFINITY, 0.0).unwrap();
            assert!((hit.d2 - brute(q, &tris)).abs() < 1e-14);
        }
        // A bound below the true distance finds nothing.
        let q = [5.0, 5.0, 5.0];
        assert!(bvh.closest(q, 1.0, 0.0).is_none());
    }
}
