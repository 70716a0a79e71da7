//! A bounding-volume hierarchy over triangles for the virtual scanner's visibility rays.
//!
//! Median split along the longest axis of the centroids' box, leaves of up to 4 triangles;
//! segment queries walk the tree with an explicit stack and stop at the first hit (a shadow ray
//! needs no closest hit). Ray–triangle tests are Möller–Trumbore in f64.

use motif_core::geometry::{Point3, cross, dot, sub};

const LEAF: usize = 4;

#[derive(Debug, Clone, Copy)]
struct Node {
    min: Point3,
    max: Point3,
    /// Leaf: first index into `order`; inner: index of the left child (the right one follows
    /// the left subtree, at `right`).
    first: u32,
    /// Leaf: number of triangles (> 0); inner: 0.
    count: u32,
    /// Inner: index of the right child.
    right: u32,
}

/// A BVH over a triangle soup.
#[derive(Debug, Clone)]
pub(crate) struct Bvh {
    nodes: Vec<Node>,
    tris: Vec<[Point3; 3]>,
    /// Triangle indices in leaf order.
    order: Vec<u32>,
}

fn bounds_of(tris: &[[Point3; 3]], ids: &[u32]) -> (Point3, Point3) {
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    for &i in ids {
        for p in &tris[i as usize] {
            for k in 0..3 {
                min[k] = min[k].min(p[k]);
                max[k] = max[k].max(p[k]);
            }
        }
    }
    (min, max)
}

fn centroid(t: &[Point3; 3], k: usize) -> f64 {
    (t[0][k] + t[1][k] + t[2][k]) / 3.0
}

impl Bvh {
    /// Builds the hierarchy over `tris` (triangle `i` keeps index `i` in query results).
    pub fn new(tris: Vec<[Point3; 3]>) -> Self {
        let mut order: Vec<u32> = (0..tris.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF + 1);
        if !tris.is_empty() {
            Self::build(&tris, &mut order, 0, &mut nodes);
        }
        Bvh { nodes, tris, order }
    }

    /// Builds the subtree over `order[..]` (which starts at `offset` in the full order); returns
    /// its node index.
    fn build(tris: &[[Point3; 3]], ids: &mut [u32], offset: usize, nodes: &mut Vec<Node>) -> u32 {
        let (min, max) = bounds_of(tris, ids);
        let me = nodes.len() as u32;
        nodes.push(Node { min, max, first: offset as u32, count: ids.len() as u32, right: 0 });
        if ids.len() <= LEAF {
            return me;
        }
        let mut cmin = [f64::INFINITY; 3];
        let mut cmax = [f64::NEG_INFINITY; 3];
        for &i in ids.iter() {
            for k in 0..3 {
                let c = centroid(&tris[i as usize], k);
                cmin[k] = cmin[k].min(c);
                cmax[k] = cmax[k].max(c);
            }
        }
        let axis = (0..3).max_by(|&a, &b| (cmax[a] - cmin[a]).total_cmp(&(cmax[b] - cmin[b]))).unwrap_or(0);
        let mid = ids.len() / 2;
        ids.select_nth_unstable_by(mid, |&a, &b| {
            centroid(&tris[a as usize], axis).total_cmp(&centroid(&tris[b as usize], axis)).then(a.cmp(&b))
        });
        let (left, right) = ids.split_at_mut(mid);
        let l = Self::build(tris, left, offset, nodes);
        let r = Self::build(tris, right, offset + mid, nodes);
        let node = &mut nodes[me as usize];
        node.first = l;
        node.count = 0;
        node.right = r;
        me
    }

    /// True when the open segment from `from` to `to` hits a triangle other than `skip`, at a
    /// parameter below `1 − slack / |to − from|` (so the surface `to` lies on, and neighbours
    /// touching it, do not count).
    pub fn occluded(&self, from: Point3, to: Point3, skip: u32, slack: f64) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let d = sub(to, from);
        let len = dot(d, d).sqrt();
        if len <= slack {
            return false;
        }
        let t_max = 1.0 - slack / len;
        let inv = [1.0 / d[0], 1.0 / d[1], 1.0 / d[2]];
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if !slab_hit(&node.min, &node.max, from, inv, t_max) {
                continue;
            }
            if node.count > 0 {
                let ids = &self.order[node.first as usize..(node.first + node.count) as usize];
                for &i in ids {
                    if i != skip && segment_hits(&self.tris[i as usize], from, d, t_max) {
                        return true;
                    }
                }
            } else if top + 2 <= stack.len() {
                stack[top] = node.first;
                stack[top + 1] = node.right;
                top += 2;
            }
        }
        false
    }
}

/// Whether the segment `from + t·d`, `t ∈ [0, t_max]`, meets the box (slab test; `inv = 1/d`
/// componentwise, infinite for axis-parallel segments).
fn slab_hit(min: &Point3, max: &Point3, from: Point3, inv: Point3, t_max: f64) -> bool {
    let (mut t0, mut t1) = (0.0f64, t_max);
    for k in 0..3 {
        let a = (min[k] - from[k]) * inv[k];
        let b = (max[k] - from[k]) * inv[k];
        let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
        // NaN (0 · ∞ for a segment in the slab's plane) leaves the interval unchanged.
        if lo > t0 {
            t0 = lo;
        }
        if hi < t1 {
            t1 = hi;
        }
        if t0 > t1 {
            return false;
        }
    }
    true
}

/// Möller–Trumbore: whether `from + t·d` meets the triangle for some `t ∈ (0, t_max)`.
fn segment_hits(tri: &[Point3; 3], from: Point3, d: Point3, t_max: f64) -> bool {
    let e1 = sub(tri[1], tri[0]);
    let e2 = sub(tri[2], tri[0]);
    let p = cross(d, e2);
    let det = dot(e1, p);
    let scale = dot(e1, e1).sqrt() * dot(e2, e2).sqrt() * dot(d, d).sqrt();
    if det.abs() <= 1e-12 * scale {
        return false;
    }
    let inv = 1.0 / det;
    let s = sub(from, tri[0]);
    let u = dot(s, p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let q = cross(s, e1);
    let v = dot(d, q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let t = dot(e2, q) * inv;
    t > 1e-9 && t < t_max
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f64, x0: f64) -> Vec<[Point3; 3]> {
        let (a, b, c, d) = ([x0, 0.0, z], [x0 + 1.0, 0.0, z], [x0 + 1.0, 1.0, z], [x0, 1.0, z]);
        vec![[a, b, c], [a, c, d]]
    }

    #[test]
    fn a_square_hides_what_is_behind_it() {
        let mut tris = Vec::new();
        for i in 0..20 {
            tris.extend(square(0.0, 2.0 * i as f64));
        }
        tris.extend(square(-1.0, 0.0));
        let bvh = Bvh::new(tris);
        let eye = [0.5, 0.5, 5.0];
        // Behind the first square: hidden; the square's own point: visible.
        assert!(bvh.occluded(eye, [0.5, 0.5, -1.0], 40, 1e-6));
        assert!(!bvh.occluded(eye, [0.25, 0.5, 0.0], 0, 1e-6));
        // Behind a gap between squares: visible.
        assert!(!bvh.occluded([1.5, 0.5, 5.0], [1.5, 0.5, -1.0], u32::MAX, 1e-6));
        // Brute force agrees on a fan of segments.
        for k in 0..200 {
            let to = [-1.0 + 0.21 * k as f64, 0.3 + 0.002 * k as f64, -0.5];
            let brute = bvh.tris.iter().any(|t| segment_hits(t, eye, sub(to, eye), 1.0 - 1e-6 / 5.5));
            assert_eq!(bvh.occluded(eye, to, u32::MAX, 1e-6), brute, "segment {k}");
        }
    }
}
