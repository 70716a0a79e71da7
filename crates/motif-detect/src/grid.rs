//! Spatial hashing for the co-occurrence loop: points bucketed into cubes of a fixed side, stored
//! as one sorted array, so a radius query visits the 27 (or more) cubes around the query without
//! allocating.
//!
//! The EM step of thesis 5.3.2 asks two kinds of neighbourhood questions many millions of times —
//! "which features of word j lie within 64ε of this one?" and "is there a feature of word j within
//! 8ε of this prediction?" — over sets of a few hundred to a few thousand points. A kd-tree per
//! word would allocate per query (kiddo returns a `Vec`); a flat sorted hash answers both in a
//! handful of binary searches with a callback, which keeps the inner loop allocation-free.

use motif_core::Point3;

/// Points hashed into cubes of side `cell`.
#[derive(Debug, Clone)]
pub struct SpatialHash {
    cell: f64,
    /// Cube keys of the occupied cubes, ascending.
    keys: Vec<[i32; 3]>,
    /// `starts[k]..starts[k + 1]` indexes `order` for the points of cube `keys[k]`.
    starts: Vec<u32>,
    /// Point indices grouped by cube.
    order: Vec<u32>,
    /// The hashed points, by point index.
    points: Vec<Point3>,
}

fn key_of(p: Point3, cell: f64) -> [i32; 3] {
    let k = |x: f64| (x / cell).floor().clamp(i32::MIN as f64 + 1.0, i32::MAX as f64 - 1.0) as i32;
    [k(p[0]), k(p[1]), k(p[2])]
}

impl SpatialHash {
    /// Hashes `points` (finite coordinates) into cubes of side `cell` (> 0).
    pub fn new(points: &[Point3], cell: f64) -> SpatialHash {
        let cell = if cell > 0.0 && cell.is_finite() { cell } else { 1.0 };
        let mut keyed: Vec<([i32; 3], u32)> =
            points.iter().enumerate().map(|(i, &p)| (key_of(p, cell), i as u32)).collect();
        keyed.sort_unstable();
        let mut keys = Vec::new();
        let mut starts = Vec::new();
        let mut order = Vec::with_capacity(keyed.len());
        for (i, &(k, idx)) in keyed.iter().enumerate() {
            if i == 0 || keyed[i - 1].0 != k {
                keys.push(k);
                starts.push(i as u32);
            }
            order.push(idx);
        }
        starts.push(keyed.len() as u32);
        SpatialHash { cell, keys, starts, order, points: points.to_vec() }
    }

    /// Number of hashed points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when no point is hashed.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The hashed point with index `i`.
    pub fn point(&self, i: usize) -> Point3 {
        self.points[i]
    }

    /// Calls `f(index, squared distance)` for every point within distance `r` of `q` (inclusive).
    pub fn for_each_within(&self, q: Point3, r: f64, mut f: impl FnMut(usize, f64)) {
        if self.points.is_empty() || r.is_nan() || r < 0.0 {
            return;
        }
        let r2 = r * r;
        let lo = key_of([q[0] - r, q[1] - r, q[2] - r], self.cell);
        let hi = key_of([q[0] + r, q[1] + r, q[2] + r], self.cell);
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                // Cubes with the same (x, y) and consecutive z are contiguous in `keys`.
                let start = self.keys.partition_point(|k| *k < [x, y, lo[2]]);
                for k in start..self.keys.len() {
                    let key = self.keys[k];
                    if key[0] != x || key[1] != y || key[2] > hi[2] {
                        break;
                    }
                    for &idx in &self.order[self.starts[k] as usize..self.starts[k + 1] as usize] {
                        let p = self.points[idx as usize];
                        let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
                        if d2 <= r2 {
                            f(idx as usize, d2);
                        }
                    }
                }
            }
        }
    }

    /// The point nearest to `q` within distance `r`, as `(index, squared distance)`.
    pub fn nearest_within(&self, q: Point3, r: f64) -> Option<(usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        self.for_each_within(q, r, |i, d2| {
            if best.is_none_or(|(bi, bd)| d2 < bd || (d2 == bd && i < bi)) {
                best = Some((i, d2));
            }
        });
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radius_queries_agree_with_brute_force() {
        let mut s = 12345u64;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s % 10_000) as f64 / 1000.0 - 5.0
        };
        let pts: Vec<Point3> = (0..2000).map(|_| [rnd(), rnd(), rnd()]).collect();
        for cell in [0.3, 1.0, 4.0] {
            let h = SpatialHash::new(&pts, cell);
            for qi in 0..50 {
                let q = [rnd(), rnd(), rnd()];
                let r = 0.2 + (qi % 7) as f64 * 0.4;
                let mut got = Vec::new();
                h.for_each_within(q, r, |i, _| got.push(i));
                got.sort_unstable();
                let want: Vec<usize> =
                    (0..pts.len()).filter(|&i| motif_core::geometry::dist(pts[i], q) <= r).collect();
                assert_eq!(got, want, "cell {cell} r {r}");
                let near = h.nearest_within(q, r).map(|(i, _)| i);
                let brute = want.iter().copied().min_by(|&a, &b| {
                    motif_core::geometry::dist2(pts[a], q).total_cmp(&motif_core::geometry::dist2(pts[b], q))
                });
                assert_eq!(near, brute);
            }
        }
    }
}
