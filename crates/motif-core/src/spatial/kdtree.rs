//! A 3-D kd-tree over a fixed point set, wrapping kiddo's `ImmutableKdTree`.
//!
//! Distances returned are Euclidean (not squared); radius queries take a radius (not squared).
//! Results are sorted by distance, ties broken by index, so every query is deterministic.
//!
//! Exact duplicates are stored once. A kd-tree cannot split a bucket of identical points, so a
//! scan with 150,000 invalid returns at the origin made every query near the origin scan all of
//! them, and k-nearest queries over the whole scan quadratic (`motif normals` took 30 s instead of
//! 0.7 s; 300,000 identical points did not finish in 100 s). The tree is built over the distinct
//! positions, and each query expands a position into the indices that share it, so results are
//! the same as over the full set. Finding the duplicates (a parallel sort of the coordinates'
//! bit patterns) doubles the build time when there are none: 100,000 points 5.9 → 11.5 ms
//! (`cargo bench -p motif-core --bench kdtree`), against 93 ms for one k-nearest query per point.

use std::num::NonZeroUsize;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use crate::geometry::Point3;
use crate::{Error, Result};

/// One neighbour found by a query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neighbour {
    /// Index of the point in the slice the tree was built from.
    pub index: usize,
    /// Euclidean distance to the query.
    pub distance: f64,
}

/// A kd-tree over a fixed set of 3-D points.
pub struct KdTree {
    tree: ImmutableKdTree<f64, 3>,
    len: usize,
    /// When some points coincide exactly: the indices sharing each distinct position.
    shared: Option<Shared>,
}

/// The original indices of each distinct position, in compressed rows: distinct position `u`
/// (the tree's item `u`) stands for `members[offsets[u]..offsets[u + 1]]`, in ascending order.
struct Shared {
    /// The distinct positions' exact keys, sorted (position `u` has key `keys[u]`).
    keys: Vec<[u64; 3]>,
    offsets: Vec<u32>,
    members: Vec<u32>,
}

/// A position's exact key: bit patterns compare exactly, and 0.0 and -0.0 are one position.
fn exact_key(p: &Point3) -> [u64; 3] {
    p.map(|c| if c == 0.0 { 0u64 } else { c.to_bits() })
}

impl Shared {
    /// Groups exactly coincident points; `None` when all points are distinct.
    fn find(points: &[Point3]) -> Option<(Vec<Point3>, Shared)> {
        let mut keyed: Vec<([u64; 3], u32)> =
            points.par_iter().enumerate().map(|(i, p)| (exact_key(p), i as u32)).collect();
        keyed.par_sort_unstable();
        let distinct = 1 + keyed.windows(2).filter(|w| w[0].0 != w[1].0).count();
        if distinct == points.len() {
            return None;
        }
        let mut unique = Vec::with_capacity(distinct);
        let mut keys = Vec::with_capacity(distinct);
        let mut offsets = Vec::with_capacity(distinct + 1);
        for (pos, &(k, i)) in keyed.iter().enumerate() {
            if pos == 0 || keyed[pos - 1].0 != k {
                offsets.push(pos as u32);
                keys.push(k);
                unique.push(points[i as usize]);
            }
        }
        offsets.push(keyed.len() as u32);
        Some((unique, Shared { keys, offsets, members: keyed.into_iter().map(|(_, i)| i).collect() }))
    }

    fn members(&self, u: usize) -> &[u32] {
        &self.members[self.offsets[u] as usize..self.offsets[u + 1] as usize]
    }

    /// The indices of the points exactly at `q`, if any.
    fn at(&self, q: &Point3) -> Option<&[u32]> {
        self.keys.binary_search(&exact_key(q)).ok().map(|u| self.members(u))
    }
}

impl std::fmt::Debug for KdTree {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("KdTree").field("len", &self.len).finish()
    }
}

impl KdTree {
    /// Builds the tree. Fails on an empty set or non-finite coordinates.
    pub fn new(points: &[Point3]) -> Result<KdTree> {
        if points.is_empty() {
            return Err(Error::InvalidInput("cannot build a kd-tree over zero points".into()));
        }
        if let Some(i) = points.iter().position(|p| !crate::geometry::is_finite(*p)) {
            return Err(Error::InvalidInput(format!("point {i} has a NaN or infinite coordinate")));
        }
        if points.len() > u32::MAX as usize {
            return Err(Error::InvalidInput(format!(
                "a kd-tree holds at most {} points, got {}",
                u32::MAX,
                points.len()
            )));
        }
        let (distinct, shared) = match Shared::find(points) {
            Some((unique, shared)) => (std::borrow::Cow::Owned(unique), Some(shared)),
            None => (std::borrow::Cow::Borrowed(points), None),
        };
        let tree = if distinct.len() > 50_000 {
            ImmutableKdTree::new_from_slice_parallel(&distinct)
        } else {
            ImmutableKdTree::new_from_slice(&distinct)
        }
        .map_err(|e| Error::InvalidInput(format!("kd-tree construction failed: {e:?}")))?;
        Ok(KdTree { tree, len: points.len(), shared })
    }

    /// Number of distinct positions (equal to [`KdTree::len`] when no two points coincide).
    pub fn distinct_len(&self) -> usize {
        self.shared.as_ref().map_or(self.len, |s| s.offsets.len() - 1)
    }

    /// Replaces each distinct position found by the original indices that share it, at most
    /// `limit` per position (its lowest indices, which are the ones a sort by distance and index
    /// would keep among the first `limit`).
    fn expand(&self, found: impl IntoIterator<Item = Neighbour>, limit: usize, out: &mut Vec<Neighbour>) {
        match &self.shared {
            None => out.extend(found),
            Some(s) => {
                for n in found {
                    let members = s.members(n.index);
                    let members = &members[..members.len().min(limit)];
                    out.extend(members.iter().map(|&i| Neighbour { index: i as usize, ..n }));
                }
            }
        }
    }

    /// Number of points in the tree.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Always false: a tree is never empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The nearest point to `q`.
    pub fn nearest(&self, q: Point3) -> Neighbour {
        let r = self.tree.query(&q).nearest_one::<SquaredEuclidean<f64>>().execute();
        let index = match &self.shared {
            None => r.item as usize,
            Some(s) => s.members(r.item as usize)[0] as usize,
        };
        Neighbour { index, distance: r.distance.sqrt() }
    }

    /// The `k` nearest points to `q`, closest first (fewer when the tree is smaller).
    pub fn knn(&self, q: Point3, k: usize) -> Vec<Neighbour> {
        let k = k.min(self.len);
        // A query at a heap of at least k coincident points (a scan's invalid returns, queried
        // from each of them) is answered without searching: a far-off heap would make each of
        // its points search the whole neighbourhood of the nearest surface.
        if let Some(here) = self.shared.as_ref().and_then(|s| s.at(&q)) {
            if here.len() >= k {
                return here[..k].iter().map(|&i| Neighbour { index: i as usize, distance: 0.0 }).collect();
            }
        }
        // Each distinct position stands for at least one point, so the k nearest points are
        // among the points of the k nearest distinct positions.
        let Some(k_distinct) = NonZeroUsize::new(k.min(self.distinct_len())) else { return Vec::new() };
        let found = self
            .tree
            .query(&q)
            .nearest_n::<SquaredEuclidean<f64>>(k_distinct)
            .execute()
            .into_iter()
            .map(|r| Neighbour { index: r.item as usize, distance: r.distance.sqrt() });
        let mut out = Vec::with_capacity(k);
        self.expand(found, k, &mut out);
        sort_neighbours(&mut out);
        out.truncate(k);
        out
    }

    /// All points within distance `r` of `q` (inclusive), closest first.
    pub fn within(&self, q: Point3, r: f64) -> Vec<Neighbour> {
        let mut out = self.within_unsorted(q, r);
        sort_neighbours(&mut out);
        out
    }

    /// All points within distance `r` of `q` (inclusive), in no particular order; faster than
    /// [`KdTree::within`] when order does not matter.
    pub fn within_unsorted(&self, q: Point3, r: f64) -> Vec<Neighbour> {
        if r.is_nan() || r < 0.0 {
            return Vec::new();
        }
        let found = self
            .tree
            .query(&q)
            .within::<SquaredEuclidean<f64>>(r * r)
            .unsorted()
            .execute()
            .into_iter()
            .map(|n| Neighbour { index: n.item as usize, distance: n.distance.sqrt() });
        let mut out = Vec::new();
        self.expand(found, usize::MAX, &mut out);
        out
    }

    /// [`KdTree::within_unsorted`], except at a heap of more than `cap` coincident points: a
    /// query made exactly there returns `cap` of them (distance 0) and nothing else, instead of
    /// the whole heap. A heap's neighbourhood is degenerate anyway, and listing it from each of
    /// its points is quadratic (150,000 returns at a scanner's origin). Elsewhere the result is
    /// the full radius neighbourhood.
    pub fn within_unsorted_capped(&self, q: Point3, r: f64, cap: usize) -> Vec<Neighbour> {
        if let Some(here) = self.shared.as_ref().and_then(|s| s.at(&q))
            && here.len() > cap
            && r >= 0.0
        {
            return here[..cap].iter().map(|&i| Neighbour { index: i as usize, distance: 0.0 }).collect();
        }
        self.within_unsorted(q, r)
    }

    /// True when some point lies within distance `r` of `q`.
    pub fn any_within(&self, q: Point3, r: f64) -> bool {
        self.nearest(q).distance <= r
    }

    /// [`KdTree::nearest`] for many queries, in parallel.
    pub fn nearest_batch(&self, queries: &[Point3]) -> Vec<Neighbour> {
        queries.par_iter().map(|q| self.nearest(*q)).collect()
    }

    /// [`KdTree::knn`] for many queries, in parallel.
    pub fn knn_batch(&self, queries: &[Point3], k: usize) -> Vec<Vec<Neighbour>> {
        queries.par_iter().map(|q| self.knn(*q, k)).collect()
    }

    /// [`KdTree::within`] for many queries, in parallel.
    pub fn within_batch(&self, queries: &[Point3], r: f64) -> Vec<Vec<Neighbour>> {
        queries.par_iter().map(|q| self.within(*q, r)).collect()
    }
}

fn sort_neighbours(v: &mut [Neighbour]) {
    v.sort_unstable_by(|a, b| a.distance.total_cmp(&b.distance).then(a.index.cmp(&b.index)));
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn cloud(n: usize, seed: u64) -> Vec<Point3> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n).map(|_| [rng.random(), rng.random(), rng.random()]).collect()
    }

    fn brute(points: &[Point3], q: Point3) -> Vec<Neighbour> {
        let mut v: Vec<Neighbour> = points
            .iter()
            .enumerate()
            .map(|(i, p)| Neighbour { index: i, distance: crate::geometry::dist(*p, q) })
            .collect();
        sort_neighbours(&mut v);
        v
    }

    #[test]
    fn queries_agree_with_brute_force() {
        let pts = cloud(2000, 1);
        let tree = KdTree::new(&pts).unwrap();
        for q in cloud(50, 2) {
            let b = brute(&pts, q);
            assert_eq!(tree.nearest(q).index, b[0].index);
            let k: Vec<usize> = tree.knn(q, 10).iter().map(|n| n.index).collect();
            let bk: Vec<usize> = b[..10].iter().map(|n| n.index).collect();
            assert_eq!(k, bk);
            let w: Vec<usize> = tree.within(q, 0.1).iter().map(|n| n.index).collect();
            let bw: Vec<usize> = b.iter().take_while(|n| n.distance <= 0.1).map(|n| n.index).collect();
            assert_eq!(w, bw);
        }
    }

    #[test]
    fn many_duplicates_are_fine() {
        let mut pts = vec![[0.5, 0.5, 0.5]; 5000];
        pts.extend(cloud(100, 3));
        let tree = KdTree::new(&pts).unwrap();
        assert_eq!(tree.within([0.5, 0.5, 0.5], 1e-12).len(), 5000);
    }

    #[test]
    fn coincident_points_give_the_same_answers_as_brute_force() {
        // Random points, some repeated up to 40 times, plus a heap of 3,000 at one spot (a scan's
        // invalid returns); -0.0 and 0.0 are the same position.
        let base = cloud(500, 4);
        let mut pts = Vec::new();
        for (i, p) in base.iter().enumerate() {
            for _ in 0..(1 + (i * 7) % 40) {
                pts.push(*p);
            }
        }
        pts.extend(std::iter::repeat_n([0.0, 0.0, 0.0], 3000));
        pts.push([-0.0, 0.0, -0.0]);
        // Interleave so members of a group are not consecutive indices.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for i in (1..pts.len()).rev() {
            pts.swap(i, rng.random_range(0..=i));
        }
        let tree = KdTree::new(&pts).unwrap();
        assert_eq!(tree.len(), pts.len());
        assert_eq!(tree.distinct_len(), 501);
        let mut queries = cloud(40, 6);
        queries.extend(base.iter().take(10).copied());
        queries.push([0.0, 0.0, 0.0]);
        for q in queries {
            let b = brute(&pts, q);
            let nearest = tree.nearest(q);
            assert_eq!(nearest.distance, b[0].distance);
            assert_eq!(nearest.index, b[0].index, "the lowest index among coincident nearest points");
            for k in [1, 16, 50, 4000] {
                let got: Vec<usize> = tree.knn(q, k).iter().map(|n| n.index).collect();
                let want: Vec<usize> = b[..k].iter().map(|n| n.index).collect();
                assert_eq!(got, want, "knn k = {k} at {q:?}");
            }
            let got: Vec<usize> = tree.within(q, 0.15).iter().map(|n| n.index).collect();
            let want: Vec<usize> = b.iter().take_while(|n| n.distance <= 0.15).map(|n| n.index).collect();
            assert_eq!(got, want);
        }
    }

    #[test]
    fn radius_queries_at_a_heap_are_capped_there_only() {
        let mut pts = cloud(200, 8);
        pts.extend(std::iter::repeat_n([0.5, 0.5, 0.5], 500));
        let tree = KdTree::new(&pts).unwrap();
        let at_heap = tree.within_unsorted_capped([0.5, 0.5, 0.5], 0.2, 64);
        assert_eq!(at_heap.len(), 64);
        assert!(at_heap.iter().all(|n| n.distance == 0.0 && n.index >= 200));
        // Anywhere else, and at a heap no larger than the cap, the full neighbourhood.
        for (q, cap) in [(pts[3], 64), ([0.5, 0.5, 0.5], 500)] {
            let mut a: Vec<usize> =
                tree.within_unsorted_capped(q, 0.2, cap).iter().map(|n| n.index).collect();
            let mut b: Vec<usize> = tree.within_unsorted(q, 0.2).iter().map(|n| n.index).collect();
            a.sort_unstable();
            b.sort_unstable();
            assert_eq!(a, b);
        }
    }

    #[test]
    fn rejects_empty_and_nan() {
        assert!(KdTree::new(&[]).is_err());
        assert!(KdTree::new(&[[f64::NAN, 0.0, 0.0]]).is_err());
    }
}
