//! Triangle meshes: the shared mesh type and its basic measures.
//!
//! `V` is `#V × 3` f64 positions, `F` is `#F × 3` u32 vertex indices, counter-clockwise seen from
//! outside. Polygons are triangulated (as fans) on load, so every algorithm sees triangles only.

use std::collections::HashMap;

use serde::Serialize;

use crate::geometry::{Aabb, Point3, add, cross, dist2, norm, normalize, scale, sub};
use crate::{Error, Result};

/// A triangle mesh with f64 positions and u32 triangles.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions, `#V × 3`.
    pub positions: Vec<Point3>,
    /// Triangles as vertex indices, `#F × 3`, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

/// Edge statistics of a mesh (see [`TriMesh::edge_stats`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct EdgeStats {
    /// Number of distinct undirected edges.
    pub edges: usize,
    /// Edges used by exactly one triangle.
    pub boundary: usize,
    /// Edges used by three or more triangles.
    pub non_manifold: usize,
    /// Edges that more triangles run one way than the other, by two or more: two neighbouring
    /// triangles facing opposite ways (trimesh's `is_winding_consistent` is false when any is).
    /// An edge with an odd number of triangles is off by one at best and is not counted for it.
    pub misoriented: usize,
}

/// Connected components of a mesh (see [`TriMesh::components`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Components {
    /// Component id of every vertex (isolated vertices get a component of their own).
    pub vertex_component: Vec<u32>,
    /// Number of components that contain at least one triangle.
    pub count: usize,
    /// Number of vertices referenced by no triangle.
    pub isolated_vertices: usize,
}

impl TriMesh {
    /// Builds a mesh and checks it: indices in range and finite coordinates.
    pub fn new(positions: Vec<Point3>, triangles: Vec<[u32; 3]>) -> Result<TriMesh> {
        let m = TriMesh { positions, triangles };
        m.validate()?;
        Ok(m)
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    pub fn num_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// Checks that every index is in range and every coordinate finite.
    pub fn validate(&self) -> Result<()> {
        if let Some(i) = self.positions.iter().position(|p| !crate::geometry::is_finite(*p)) {
            return Err(Error::InvalidInput(format!("vertex {i} has a NaN or infinite coordinate")));
        }
        let n = self.positions.len() as u64;
        for (f, t) in self.triangles.iter().enumerate() {
            if let Some(&bad) = t.iter().find(|&&i| i as u64 >= n) {
                return Err(Error::InvalidInput(format!(
                    "triangle {f} refers to vertex {bad}, but the mesh has only {n} vertices"
                )));
            }
        }
        Ok(())
    }

    /// Bounding box of the vertices, `None` for an empty mesh.
    pub fn aabb(&self) -> Option<Aabb> {
        Aabb::from_points(&self.positions)
    }

    /// Bounding box of the surface: of the vertices some triangle uses (`None` without
    /// triangles). A stray vertex no triangle uses (as some exporters leave) does not widen it.
    pub fn surface_aabb(&self) -> Option<Aabb> {
        let first = self.triangles.first()?[0];
        let mut b = Aabb { min: self.positions[first as usize], max: self.positions[first as usize] };
        for t in &self.triangles {
            for &v in t {
                b.grow(self.positions[v as usize]);
            }
        }
        Some(b)
    }

    /// Whether some vertex is used by no triangle.
    pub fn has_unreferenced_vertices(&self) -> bool {
        let mut used = vec![false; self.positions.len()];
        for t in &self.triangles {
            for &v in t {
                used[v as usize] = true;
            }
        }
        used.iter().any(|u| !u)
    }

    /// Length of the bounding-box diagonal (0 for an empty mesh).
    pub fn diagonal(&self) -> f64 {
        self.aabb().map_or(0.0, |b| b.diagonal())
    }

    /// The three corner positions of triangle `f`.
    #[inline]
    pub fn corners(&self, f: usize) -> [Point3; 3] {
        let [a, b, c] = self.triangles[f];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }

    /// Signed volume enclosed by the triangles (divergence theorem, Σ a · (b × c) / 6): positive
    /// for a closed mesh whose faces wind counter-clockwise seen from outside.
    pub fn signed_volume(&self) -> f64 {
        (0..self.triangles.len())
            .map(|f| {
                let [a, b, c] = self.corners(f);
                crate::geometry::dot(a, cross(b, c)) / 6.0
            })
            .sum()
    }

    /// Unnormalised normal `(b − a) × (c − a)` of triangle `f`; its length is twice the area.
    #[inline]
    pub fn face_cross(&self, f: usize) -> Point3 {
        let [a, b, c] = self.corners(f);
        cross(sub(b, a), sub(c, a))
    }

    /// Unit face normals (zero for degenerate triangles), `#F × 3`.
    pub fn face_normals(&self) -> Vec<Point3> {
        (0..self.triangles.len()).map(|f| normalize(self.face_cross(f)).unwrap_or([0.0; 3])).collect()
    }

    /// Triangle areas, `#F`.
    pub fn face_areas(&self) -> Vec<f64> {
        (0..self.triangles.len()).map(|f| 0.5 * norm(self.face_cross(f))).collect()
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        // + 0.0: Rust's sum of no floats is −0.0, which `motif info --json` printed for a point
        // cloud's area.
        self.face_areas().iter().sum::<f64>() + 0.0
    }

    /// Area-weighted vertex normals, unit length (zero for vertices with no non-degenerate
    /// incident triangle), `#V × 3`.
    pub fn vertex_normals(&self) -> Vec<Point3> {
        let mut acc = vec![[0.0; 3]; self.positions.len()];
        for f in 0..self.triangles.len() {
            // |cross| = 2 × area, so summing the raw cross products weights by area.
            let c = self.face_cross(f);
            for &v in &self.triangles[f] {
                acc[v as usize] = add(acc[v as usize], c);
            }
        }
        acc.into_iter().map(|n| normalize(n).unwrap_or([0.0; 3])).collect()
    }

    /// Mean edge length over all triangle edges (each shared edge counted once per triangle).
    pub fn mean_edge_length(&self) -> f64 {
        if self.triangles.is_empty() {
            return 0.0;
        }
        let mut s = 0.0;
        for f in 0..self.triangles.len() {
            let [a, b, c] = self.corners(f);
            s += dist2(a, b).sqrt() + dist2(b, c).sqrt() + dist2(c, a).sqrt();
        }
        s / (3 * self.triangles.len()) as f64
    }

    /// Counts distinct edges, boundary edges (one triangle), non-manifold edges (three or more)
    /// and misoriented edges (see [`EdgeStats::misoriented`]).
    pub fn edge_stats(&self) -> EdgeStats {
        self.edge_stats_and_boundary().0
    }

    /// [`TriMesh::edge_stats`], and per vertex whether it lies on a boundary edge (empty when
    /// there is none), from one pass over the edge table.
    pub fn edge_stats_and_boundary(&self) -> (EdgeStats, Vec<bool>) {
        let keys = edges_by_key(&self.triangles, self.positions.len());
        let mut stats = EdgeStats { edges: 0, boundary: 0, non_manifold: 0, misoriented: 0 };
        let mut on_boundary = Vec::new();
        for run in keys.chunk_by(|a, b| a.0 == b.0) {
            let (low, high) = ((run[0].0 >> 32) as u32, run[0].0 as u32);
            if low == high {
                continue; // a degenerate side is no edge
            }
            stats.edges += 1;
            if run.len() == 1 {
                stats.boundary += 1;
                if on_boundary.is_empty() {
                    on_boundary = vec![false; self.positions.len()];
                }
                on_boundary[low as usize] = true;
                on_boundary[high as usize] = true;
            }
            stats.non_manifold += usize::from(run.len() >= 3);
            // Triangles running low → high minus those running high → low.
            let net: i64 = run
                .iter()
                .map(|&(_, f, k)| if self.triangles[f as usize][k as usize] == low { 1 } else { -1 })
                .sum();
            stats.misoriented += usize::from(net.abs() >= 2);
        }
        (stats, on_boundary)
    }

    /// Flips the patches of triangles that run against the rest of their surface, so that every
    /// edge shared by exactly two triangles is used once each way where the surface allows it.
    ///
    /// Triangles are joined across edges of exactly two triangles (edges of one triangle or of
    /// three or more join nothing); each group so joined is made consistent by breadth-first
    /// propagation, and of its two consistent orientations the one that flips the smaller area
    /// is kept, so a consistent group is never touched and a small patch turned the wrong way
    /// inside a large surface is turned back. A group that cannot be oriented (a Möbius strip)
    /// is left as it is. Returns the number of triangles flipped. The repair libigl's
    /// `bfs_orient` and trimesh's `fix_winding` make; Motif runs it on meshes it builds itself.
    pub fn orient_patches(&mut self) -> usize {
        let n = self.triangles.len();
        let keys = edges_by_key(&self.triangles, self.positions.len());
        // For each manifold edge: its two triangles and whether they already agree on it.
        let mut start = vec![0u32; n + 1];
        let mut pairs: Vec<(u32, u32, bool)> = Vec::new();
        for run in keys.chunk_by(|a, b| a.0 == b.0) {
            if run.len() != 2 || (run[0].0 >> 32) == (run[0].0 & 0xffff_ffff) {
                continue;
            }
            let from = |&(_, f, k): &(u64, u32, u8)| self.triangles[f as usize][k as usize];
            let agree = from(&run[0]) != from(&run[1]);
            let (f, g) = (run[0].1, run[1].1);
            if f != g {
                pairs.push((f, g, agree));
                start[f as usize + 1] += 1;
                start[g as usize + 1] += 1;
            }
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut adjacency = vec![(0u32, false); start[n] as usize];
        for &(f, g, agree) in &pairs {
            adjacency[fill[f as usize] as usize] = (g, agree);
            fill[f as usize] += 1;
            adjacency[fill[g as usize] as usize] = (f, agree);
            fill[g as usize] += 1;
        }
        let areas = self.face_areas();
        let mut flip: Vec<Option<bool>> = vec![None; n];
        let mut flipped = 0;
        let mut group: Vec<u32> = Vec::new();
        let mut queue = std::collections::VecDeque::new();
        for seed in 0..n {
            if flip[seed].is_some() {
                continue;
            }
            group.clear();
            flip[seed] = Some(false);
            queue.push_back(seed as u32);
            let mut orientable = true;
            while let Some(f) = queue.pop_front() {
                group.push(f);
                let here = flip[f as usize] == Some(true);
                for &(g, agree) in &adjacency[start[f as usize] as usize..start[f as usize + 1] as usize] {
                    // Agreeing neighbours keep the same flip; disagreeing ones take the other.
                    let want = here ^ !agree;
                    match flip[g as usize] {
                        None => {
                            flip[g as usize] = Some(want);
                            queue.push_back(g);
                        }
                        Some(have) => orientable &= have == want,
                    }
                }
            }
            if !orientable {
                continue;
            }
            let (mut keep, mut turn) = (0.0, 0.0);
            for &f in &group {
                if flip[f as usize] == Some(true) {
                    turn += areas[f as usize]
                } else {
                    keep += areas[f as usize]
                }
            }
            let turn_marked = turn <= keep;
            for &f in &group {
                if (flip[f as usize] == Some(true)) == turn_marked {
                    self.triangles[f as usize].swap(1, 2);
                    flipped += 1;
                }
            }
        }
        flipped
    }

    /// Connected components through shared vertices (union–find).
    pub fn components(&self) -> Components {
        let n = self.positions.len();
        let mut uf = UnionFind::new(n);
        let mut used = vec![false; n];
        for t in &self.triangles {
            for &v in t {
                used[v as usize] = true;
            }
            uf.union(t[0] as usize, t[1] as usize);
            uf.union(t[0] as usize, t[2] as usize);
        }
        let mut ids: HashMap<usize, u32> = HashMap::new();
        let mut vertex_component = vec![0u32; n];
        for v in 0..n {
            let r = uf.find(v);
            let next = ids.len() as u32;
            vertex_component[v] = *ids.entry(r).or_insert(next);
        }
        let isolated_vertices = used.iter().filter(|u| !**u).count();
        let mut with_tri = vec![false; ids.len()];
        for t in &self.triangles {
            with_tri[vertex_component[t[0] as usize] as usize] = true;
        }
        Components { vertex_component, count: with_tri.iter().filter(|x| **x).count(), isolated_vertices }
    }

    /// Number of triangles with zero area or a repeated vertex index.
    pub fn degenerate_triangles(&self) -> usize {
        (0..self.triangles.len())
            .filter(|&f| {
                let t = self.triangles[f];
                t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || norm(self.face_cross(f)) == 0.0
            })
            .count()
    }

    /// Removes triangles with a repeated vertex index or zero area; returns how many were removed.
    pub fn remove_degenerate_triangles(&mut self) -> usize {
        let before = self.triangles.len();
        let positions = &self.positions;
        self.triangles.retain(|t| {
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                return false;
            }
            let [a, b, c] = [positions[t[0] as usize], positions[t[1] as usize], positions[t[2] as usize]];
            norm(cross(sub(b, a), sub(c, a))) > 0.0
        });
        before - self.triangles.len()
    }

    /// Merges vertices closer than `relative_tolerance × diagonal` (0 merges exact duplicates
    /// only), remaps the triangles, and drops triangles that collapse. Returns the number of
    /// vertices removed. The first vertex of each cluster (in index order) is kept, so welding is
    /// deterministic.
    pub fn weld(&mut self, relative_tolerance: f64) -> usize {
        let tol = relative_tolerance.max(0.0) * self.diagonal();
        let (remap, kept) = weld_map(&self.positions, tol);
        let before = self.positions.len();
        let mut new_pos = Vec::with_capacity(kept);
        let mut seen = vec![false; kept];
        for (old, &new) in remap.iter().enumerate() {
            if !seen[new as usize] {
                seen[new as usize] = true;
                new_pos.push(self.positions[old]);
            }
        }
        self.positions = new_pos;
        for t in &mut self.triangles {
            for v in t.iter_mut() {
                *v = remap[*v as usize];
            }
        }
        self.triangles.retain(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
        before - self.positions.len()
    }

    /// Removes vertices referenced by no triangle; returns the old→new index map (`u32::MAX` for
    /// removed vertices).
    pub fn remove_unreferenced_vertices(&mut self) -> Vec<u32> {
        let mut map = vec![u32::MAX; self.positions.len()];
        let mut next = 0u32;
        let mut new_pos = Vec::new();
        for t in &mut self.triangles {
            for v in t.iter_mut() {
                let m = &mut map[*v as usize];
                if *m == u32::MAX {
                    *m = next;
                    next += 1;
                    new_pos.push(self.positions[*v as usize]);
                }
                *v = *m;
            }
        }
        self.positions = new_pos;
        map
    }

    /// Appends another mesh (indices shifted).
    pub fn append(&mut self, other: &TriMesh) {
        let off = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.triangles.extend(other.triangles.iter().map(|t| [t[0] + off, t[1] + off, t[2] + off]));
    }

    /// Applies an affine 4×4 transform to every vertex; reflections flip the winding so normals
    /// keep pointing outward.
    pub fn transform(&mut self, m: &crate::geometry::Mat4) {
        for p in &mut self.positions {
            *p = crate::geometry::transform_point(m, *p);
        }
        let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        if det < 0.0 {
            for t in &mut self.triangles {
                t.swap(1, 2);
            }
        }
    }

    /// Area-weighted centroid of the surface (vertex mean for a mesh without area).
    pub fn surface_centroid(&self) -> Point3 {
        let mut c = [0.0; 3];
        let mut total = 0.0;
        for f in 0..self.triangles.len() {
            let [a, b, d] = self.corners(f);
            let w = 0.5 * norm(cross(sub(b, a), sub(d, a)));
            c = add(c, scale(add(add(a, b), d), w / 3.0));
            total += w;
        }
        if total > 0.0 {
            scale(c, 1.0 / total)
        } else if !self.positions.is_empty() {
            let s = self.positions.iter().fold([0.0; 3], |acc, p| add(acc, *p));
            scale(s, 1.0 / self.positions.len() as f64)
        } else {
            [0.0; 3]
        }
    }
}

/// Every edge of `triangles` as (key, triangle, corner k), the edge running from corner k to
/// corner k + 1 and its key `min << 32 | max` of its vertices, sorted by (key, triangle, corner):
/// equal keys (one edge's uses) are adjacent. Bucketed by the smaller vertex (a counting pass),
/// then each short bucket sorted, which is several times faster than one sort of all edges.
pub fn edges_by_key(triangles: &[[u32; 3]], num_vertices: usize) -> Vec<(u64, u32, u8)> {
    let mut start = vec![0u32; num_vertices + 1];
    for t in triangles {
        for k in 0..3 {
            start[t[k].min(t[(k + 1) % 3]) as usize + 1] += 1;
        }
    }
    for v in 0..num_vertices {
        start[v + 1] += start[v];
    }
    let mut fill = start.clone();
    let mut keys = vec![(0u64, 0u32, 0u8); 3 * triangles.len()];
    for (f, t) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let slot = &mut fill[a.min(b) as usize];
            keys[*slot as usize] = (((a.min(b) as u64) << 32) | a.max(b) as u64, f as u32, k as u8);
            *slot += 1;
        }
    }
    for v in 0..num_vertices {
        keys[start[v] as usize..start[v + 1] as usize].sort_unstable();
    }
    keys
}

/// The entries of [`edges_by_key`] output whose edge no other entry shares: the edges used by one
/// triangle only.
pub fn single_use(keys: &[(u64, u32, u8)]) -> impl Iterator<Item = &(u64, u32, u8)> {
    keys.chunk_by(|a, b| a.0 == b.0).filter(|run| run.len() == 1).map(|run| &run[0])
}

/// Maps each point to a representative: points within `tol` of an earlier kept point merge into
/// it (greedy in index order, grid-hashed so it is linear for well-spread points). Returns the
/// map to new compact indices and the number kept. `tol = 0` merges exactly equal points only.
pub fn weld_map(points: &[Point3], tol: f64) -> (Vec<u32>, usize) {
    let mut remap = vec![0u32; points.len()];
    if tol <= 0.0 {
        let mut exact: HashMap<[u64; 3], u32> = HashMap::with_capacity(points.len());
        for (i, p) in points.iter().enumerate() {
            // +0.0 and −0.0 are the same position.
            let key = p.map(|c| if c == 0.0 { 0u64 } else { c.to_bits() });
            let next = exact.len() as u32;
            remap[i] = *exact.entry(key).or_insert(next);
        }
        return (remap, exact.len());
    }
    let cell = tol;
    let key = |p: Point3| p.map(|c| (c / cell).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    let mut kept: Vec<Point3> = Vec::new();
    for (i, p) in points.iter().enumerate() {
        let k = key(*p);
        let mut found = None;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = grid.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                        for &j in list {
                            if dist2(kept[j as usize], *p) <= tol * tol {
                                found = Some(j);
                                break 'search;
                            }
                        }
                    }
                }
            }
        }
        remap[i] = match found {
            Some(j) => j,
            None => {
                let j = kept.len() as u32;
                kept.push(*p);
                grid.entry(k).or_default().push(j);
                j
            }
        };
    }
    (remap, kept.len())
}

/// Disjoint-set forest with path halving and union by size.
#[derive(Debug, Clone)]
pub struct UnionFind {
    parent: Vec<usize>,
    size: Vec<usize>,
}

impl UnionFind {
    /// `n` singleton sets.
    pub fn new(n: usize) -> Self {
        UnionFind { parent: (0..n).collect(), size: vec![1; n] }
    }

    /// Representative of `x`'s set.
    pub fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] != x {
            self.parent[x] = self.parent[self.parent[x]];
            x = self.parent[x];
        }
        x
    }

    /// Merges the sets of `a` and `b`; returns false when they were already one set.
    pub fn union(&mut self, a: usize, b: usize) -> bool {
        let (mut a, mut b) = (self.find(a), self.find(b));
        if a == b {
            return false;
        }
        if self.size[a] < self.size[b] {
            std::mem::swap(&mut a, &mut b);
        }
        self.parent[b] = a;
        self.size[a] += self.size[b];
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_triangles() -> TriMesh {
        // A unit square split along its diagonal, plus a duplicate of vertex 2.
        TriMesh::new(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]],
            vec![[0, 1, 2], [0, 4, 3]],
        )
        .unwrap()
    }

    #[test]
    fn boundary_vertices_are_those_of_edges_used_once() {
        let cube = crate::procedural::box_mesh([0.0; 3], [1.0, 1.0, 1.0], [1, 1, 1]).unwrap();
        let (stats, on) = cube.edge_stats_and_boundary();
        assert_eq!((stats.boundary, on.len()), (0, 0), "closed: no per-vertex table");
        let mut open = cube.clone();
        let gone = open.triangles.remove(0);
        let (stats, on) = open.edge_stats_and_boundary();
        assert_eq!(stats, open.edge_stats());
        assert_eq!(stats.boundary, 3);
        let marked: Vec<u32> = (0..on.len() as u32).filter(|&v| on[v as usize]).collect();
        let mut expected = gone.to_vec();
        expected.sort_unstable();
        assert_eq!(marked, expected);
    }

    #[test]
    fn flipped_patches_are_turned_back() {
        let cube = crate::procedural::box_mesh([0.0; 3], [1.0, 2.0, 3.0], [4, 4, 4]).unwrap();
        assert_eq!(cube.edge_stats().misoriented, 0);
        let volume = cube.signed_volume();
        // A consistent surface is left alone.
        let mut m = cube.clone();
        assert_eq!(m.orient_patches(), 0);
        assert_eq!(m.triangles, cube.triangles);
        // A patch of 7 triangles turned over inside it is turned back, and nothing else moves.
        let mut m = cube.clone();
        for f in [3usize, 4, 5, 6, 7, 8, 9] {
            m.triangles[f].swap(0, 1);
        }
        assert!(m.edge_stats().misoriented > 0);
        assert_eq!(m.orient_patches(), 7);
        assert_eq!(m.edge_stats().misoriented, 0);
        assert!((m.signed_volume() - volume).abs() < 1e-12);
        // Turned over as a whole, a surface stays as it is (it is consistent, only inside out).
        let mut m = cube.clone();
        for t in &mut m.triangles {
            t.swap(1, 2);
        }
        assert_eq!(m.orient_patches(), 0);
        // A Möbius strip cannot be oriented: left untouched.
        let k = 12;
        let mut positions = Vec::new();
        for i in 0..k {
            let u = std::f64::consts::TAU * i as f64 / k as f64;
            for w in [-0.2, 0.2] {
                let (c, s) = ((u / 2.0).cos(), (u / 2.0).sin());
                positions.push([(1.0 + w * c) * u.cos(), (1.0 + w * c) * u.sin(), w * s]);
            }
        }
        let mut triangles = Vec::new();
        for i in 0..k as u32 {
            let (a, b) = (2 * i, 2 * i + 1);
            // The last quad joins the first with its sides swapped: the half twist.
            let (c, d) = if i + 1 == k as u32 { (1, 0) } else { (2 * i + 2, 2 * i + 3) };
            triangles.push([a, c, b]);
            triangles.push([b, c, d]);
        }
        let mut strip = TriMesh::new(positions, triangles).unwrap();
        let before = strip.triangles.clone();
        assert!(strip.edge_stats().misoriented > 0, "no orientation of a Möbius strip is consistent");
        assert_eq!(strip.edge_stats().boundary, 2 * k, "one boundary running twice around");
        assert_eq!(strip.orient_patches(), 0);
        assert_eq!(strip.triangles, before);
    }

    #[test]
    fn areas_normals_and_edges() {
        let m = two_triangles();
        assert!((m.area() - 1.0).abs() < 1e-12);
        for n in m.face_normals() {
            assert!((n[2] - 1.0).abs() < 1e-12);
        }
        // Before welding the two triangles share only vertex 0: 6 edges, all boundary.
        let e = m.edge_stats();
        assert_eq!((e.edges, e.boundary, e.non_manifold), (6, 6, 0));
    }

    #[test]
    fn welding_joins_duplicates() {
        let mut m = two_triangles();
        assert_eq!(m.weld(1e-9), 1);
        assert_eq!(m.num_vertices(), 4);
        let e = m.edge_stats();
        assert_eq!((e.edges, e.boundary), (5, 4));
        assert_eq!(m.components().count, 1);
    }

    #[test]
    fn components_and_non_manifold() {
        let mut m = two_triangles();
        m.weld(0.0);
        // A third triangle on the shared diagonal makes it non-manifold; a far triangle is a second component.
        m.positions.extend([[0.5, 0.5, 1.0], [5.0, 0.0, 0.0], [6.0, 0.0, 0.0], [5.0, 1.0, 0.0]]);
        m.triangles.extend([[0, 2, 4], [5, 6, 7]]);
        assert_eq!(m.edge_stats().non_manifold, 1);
        assert_eq!(m.components().count, 2);
    }

    #[test]
    fn rejects_bad_indices_and_nan() {
        assert!(TriMesh::new(vec![[0.0; 3]; 3], vec![[0, 1, 3]]).is_err());
        assert!(TriMesh::new(vec![[f64::NAN, 0.0, 0.0]], vec![]).is_err());
    }

    #[test]
    fn reflection_keeps_outward_winding() {
        let mut m = two_triangles();
        let before = m.face_normals()[0];
        let mirror =
            [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
        m.transform(&mirror);
        let after = m.face_normals()[0];
        assert!((before[2] + after[2]).abs() < 1e-12, "mirror in z flips the z normal");
    }
    #[test]
    fn edges_by_key_equal_one_global_sort() {
        let m = crate::procedural::generate("facade", 0).unwrap().mesh;
        let mut expected: Vec<(u64, u32, u8)> = Vec::new();
        for (f, t) in m.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                expected.push((((a.min(b) as u64) << 32) | a.max(b) as u64, f as u32, k as u8));
            }
        }
        expected.sort_unstable();
        assert_eq!(edges_by_key(&m.triangles, m.positions.len()), expected);
    }
}
