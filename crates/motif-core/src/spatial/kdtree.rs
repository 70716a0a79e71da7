//! A 3-D kd-tree over a fixed point set, wrapping kiddo's `ImmutableKdTree`.
//!
//! Distances returned are Euclidean (not squared); radius queries take a radius (not squared).
//! Results are sorted by distance, ties broken by index, so every query is deterministic.

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
        let tree = if points.len() > 50_000 {
            ImmutableKdTree::new_from_slice_parallel(points)
        } else {
            ImmutableKdTree::new_from_slice(points)
        }
        .map_err(|e| Error::InvalidInput(format!("kd-tree construction failed: {e:?}")))?;
        Ok(KdTree { tree, len: points.len() })
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
        Neighbour { index: r.item as usize, distance: r.distance.sqrt() }
    }

    /// The `k` nearest points to `q`, closest first (fewer when the tree is smaller).
    pub fn knn(&self, q: Point3, k: usize) -> Vec<Neighbour> {
        let Some(k) = NonZeroUsize::new(k.min(self.len)) else { return Vec::new() };
        let mut out: Vec<Neighbour> = self
            .tree
            .query(&q)
            .nearest_n::<SquaredEuclidean<f64>>(k)
            .execute()
            .into_iter()
            .map(|r| Neighbour { index: r.item as usize, distance: r.distance.sqrt() })
            .collect();
        sort_neighbours(&mut out);
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
        self.tree
            .query(&q)
            .within::<SquaredEuclidean<f64>>(r * r)
            .unsorted()
            .execute()
            .into_iter()
            .map(|n| Neighbour { index: n.item as usize, distance: n.distance.sqrt() })
            .collect()
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
    fn rejects_empty_and_nan() {
        assert!(KdTree::new(&[]).is_err());
        assert!(KdTree::new(&[[f64::NAN, 0.0, 0.0]]).is_err());
    }
}
