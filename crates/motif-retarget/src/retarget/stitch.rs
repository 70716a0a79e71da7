//! Stitching the output geometry from the labelling (thesis 4.2.2, Fig. 4.4 d).
//!
//! Every output voxel `x` with step vector `k` receives the triangles of input voxel `x − k`,
//! translated by `Σ kᵢ vᵢ` (model units, so no round trip through the canonical map is needed:
//! the canonical map is linear and the normalisation a similarity, so translating in model space
//! equals translating in canonical space and mapping back). An output vertex is identified by
//! (input vertex, step vector): within one copy, triangles that shared a vertex in the input still
//! share it, and parts that only touched in the input stay separate.
//!
//! **Seams.** Where neighbouring voxels copy from different copies, a vertex whose triangles were
//! split between input voxels (it *straddles* voxel faces) appears once per copy. Such vertices
//! are welded when they coincide within the tolerance and both copies would have used them in at
//! least two common output voxels — i.e. they are translational twins continuing across the seam,
//! not two distinct parts that happen to touch there.

use std::collections::HashMap;

use motif_core::geometry::{Point3, add, dist2, dot, scale, sub};
use motif_core::mesh::{TriMesh, UnionFind};

use super::canonical::Lattice;
use super::voxels::VoxelGrid;

/// The stitched mesh.
#[derive(Debug, Clone)]
pub(crate) struct Stitched {
    pub mesh: TriMesh,
    /// Output voxel (linear index in the output grid) of every output triangle.
    pub triangle_voxels: Vec<u32>,
    /// Vertices merged by seam welding.
    pub welded: usize,
}

/// Assembles the output mesh. `labels` has one step vector per output voxel of the grid with
/// `out_dims` voxels; `weld_tolerance` is in model units.
pub(crate) fn stitch(
    mesh: &TriMesh,
    tri_voxel: &[u32],
    grid_in: &VoxelGrid,
    out_dims: [usize; 3],
    labels: &[[i32; 3]],
    lattice: &Lattice,
    weld_tolerance: f64,
) -> Stitched {
    let n_in = grid_in.len();
    // Triangles per input voxel (CSR, triangle order kept).
    let mut start = vec![0u32; n_in + 1];
    for &v in tri_voxel {
        start[v as usize + 1] += 1;
    }
    for v in 0..n_in {
        start[v + 1] += start[v];
    }
    let mut fill = start.clone();
    let mut by_voxel = vec![0u32; tri_voxel.len()];
    for (f, &v) in tri_voxel.iter().enumerate() {
        by_voxel[fill[v as usize] as usize] = f as u32;
        fill[v as usize] += 1;
    }
    // Input voxels touched by each vertex's triangles (sorted, unique).
    let mut vertex_voxels: Vec<Vec<u32>> = vec![Vec::new(); mesh.positions.len()];
    for (f, t) in mesh.triangles.iter().enumerate() {
        for &v in t {
            let list = &mut vertex_voxels[v as usize];
            if !list.contains(&tri_voxel[f]) {
                list.push(tri_voxel[f]);
            }
        }
    }
    for l in &mut vertex_voxels {
        l.sort_unstable();
    }

    let out = VoxelGrid { origin: [0.0; 3], pitch: [1.0; 3], dims: out_dims };
    // Output vertex of (input vertex, label): one table of #V entries per label in use.
    const UNSET: u32 = u32::MAX;
    let num_in_vertices = mesh.positions.len();
    let mut label_slot: HashMap<[i32; 3], usize> = HashMap::new();
    let mut vertex_of: Vec<Vec<u32>> = Vec::new();
    let mut positions: Vec<Point3> = Vec::new();
    let mut origin_of: Vec<(u32, [i32; 3])> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut triangle_voxels: Vec<u32> = Vec::new();
    for (x, &k) in labels.iter().enumerate() {
        let c = out.coords(x);
        let src = [c[0] as i64 - k[0] as i64, c[1] as i64 - k[1] as i64, c[2] as i64 - k[2] as i64];
        // Labels with infinite unary cost are never chosen; skip defensively.
        let Some(s) = grid_in.linear_checked(src) else { continue };
        let t = lattice.translation(k);
        let slot = *label_slot.entry(k).or_insert_with(|| {
            vertex_of.push(vec![UNSET; num_in_vertices]);
            vertex_of.len() - 1
        });
        let table = &mut vertex_of[slot];
        for &f in &by_voxel[start[s] as usize..start[s + 1] as usize] {
            let tri = mesh.triangles[f as usize].map(|v| {
                let e = &mut table[v as usize];
                if *e == UNSET {
                    positions.push(add(mesh.positions[v as usize], t));
                    origin_of.push((v, k));
                    *e = (positions.len() - 1) as u32;
                }
                *e
            });
            triangles.push(tri);
            triangle_voxels.push(x as u32);
        }
    }

    // Seam welding of straddling vertices.
    let mut uf = UnionFind::new(positions.len());
    let mut welded = 0;
    if weld_tolerance > 0.0 {
        let cell = weld_tolerance;
        let key = |p: Point3| p.map(|c| (c / cell).floor() as i64);
        let mut buckets: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        let footprint = |i: usize| -> Vec<[i64; 3]> {
            let (v, k) = origin_of[i];
            vertex_voxels[v as usize]
                .iter()
                .map(|&s| {
                    let c = grid_in.coords(s as usize);
                    [c[0] as i64 + k[0] as i64, c[1] as i64 + k[1] as i64, c[2] as i64 + k[2] as i64]
                })
                .collect()
        };
        for i in 0..positions.len() {
            let (v, k) = origin_of[i];
            if vertex_voxels[v as usize].len() < 2 {
                continue;
            }
            let kc = key(positions[i]);
            let fi = footprint(i);
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let Some(list) = buckets.get(&[kc[0] + dx, kc[1] + dy, kc[2] + dz]) else { continue };
                        for &j in list {
                            let j = j as usize;
                            if origin_of[j].1 == k || dist2(positions[i], positions[j]) > cell * cell {
                                continue;
                            }
                            let fj = footprint(j);
                            let common = fi.iter().filter(|c| fj.contains(c)).count();
                            if common >= 2 && uf.union(i, j) {
                                welded += 1;
                            }
                        }
                    }
                }
            }
            buckets.entry(kc).or_default().push(i as u32);
        }
    }
    // Compact: each class keeps its first vertex's position.
    let mut remap = vec![u32::MAX; positions.len()];
    let mut new_positions = Vec::with_capacity(positions.len() - welded);
    for i in 0..positions.len() {
        let r = uf.find(i);
        if remap[r] == u32::MAX {
            remap[r] = new_positions.len() as u32;
            new_positions.push(positions[r]);
        }
        remap[i] = remap[r];
    }
    let mut kept_voxels = Vec::with_capacity(triangles.len());
    let mut kept = Vec::with_capacity(triangles.len());
    for (t, &x) in triangles.iter().zip(&triangle_voxels) {
        let t = t.map(|v| remap[v as usize]);
        if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
            kept.push(t);
            kept_voxels.push(x);
        }
    }
    let mut mesh = TriMesh { positions: new_positions, triangles: kept };
    let mut triangle_voxels = kept_voxels;
    if weld_tolerance > 0.0 {
        split_t_junctions(&mut mesh, &mut triangle_voxels, weld_tolerance);
    }
    Stitched { mesh, triangle_voxels, welded }
}

/// Removes T-junctions along seams: where one copy's boundary edge has another copy's boundary
/// vertex on it (within `tol`), the triangle is split at that vertex. This happens when the two
/// sides of a seam were tessellated differently, e.g. pieces of a large triangle cut at voxel
/// faces ([`super::TriangleAssignment::Cut`]). Iterates until no boundary edge has a vertex on it.
/// Every boundary edge is examined, not only those on seams: a split only re-tessellates (the
/// vertex lies on the edge within `tol`), so an input's own open boundary keeps its shape.
fn split_t_junctions(mesh: &mut TriMesh, triangle_voxels: &mut Vec<u32>, tol: f64) {
    for _round in 0..8 {
        // Boundary edges as (triangle, corner k): the edge from corner k to corner k + 1.
        let mut keys: Vec<(u64, u32, u8)> = Vec::with_capacity(3 * mesh.triangles.len());
        for (f, t) in mesh.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                keys.push((((a.min(b) as u64) << 32) | a.max(b) as u64, f as u32, k as u8));
            }
        }
        keys.sort_unstable();
        let mut boundary: Vec<(u32, u8)> = Vec::new();
        let mut i = 0;
        while i < keys.len() {
            let mut j = i + 1;
            while j < keys.len() && keys[j].0 == keys[i].0 {
                j += 1;
            }
            if j - i == 1 {
                boundary.push((keys[i].1, keys[i].2));
            }
            i = j;
        }
        if boundary.is_empty() {
            return;
        }
        let edge = |f: u32, k: u8| {
            let t = mesh.triangles[f as usize];
            (t[k as usize], t[(k as usize + 1) % 3])
        };
        // Boundary vertices sorted along each axis; each edge scans, on the axis where that is
        // fewest, the vertices whose coordinate lies within its span widened by `tol` (a grid
        // keyed on the edge length degenerates when a few long edges meet many short ones, and
        // one fixed axis when many vertices share a seam plane across it).
        let mut seen = vec![false; mesh.positions.len()];
        let mut verts: Vec<u32> = Vec::new();
        for &(f, k) in &boundary {
            let (a, b) = edge(f, k);
            for v in [a, b] {
                if !std::mem::replace(&mut seen[v as usize], true) {
                    verts.push(v);
                }
            }
        }
        let sorted: [(Vec<u32>, Vec<f64>); 3] = std::array::from_fn(|axis| {
            let mut vs = verts.clone();
            vs.sort_unstable_by(|&u, &w| {
                mesh.positions[u as usize][axis].total_cmp(&mesh.positions[w as usize][axis]).then(u.cmp(&w))
            });
            let coord = vs.iter().map(|&v| mesh.positions[v as usize][axis]).collect();
            (vs, coord)
        });
        // For every boundary edge, the boundary vertices strictly inside it, by parameter.
        let mut splits: HashMap<u32, Vec<(u8, Vec<u32>)>> = HashMap::new();
        let mut on: Vec<(f64, u32)> = Vec::new();
        for &(f, k) in &boundary {
            let (a, b) = edge(f, k);
            let (pa, pb) = (mesh.positions[a as usize], mesh.positions[b as usize]);
            let d = sub(pb, pa);
            let len2 = dot(d, d);
            if len2 <= tol * tol {
                continue;
            }
            let window = |axis: usize| {
                let coord = &sorted[axis].1;
                let (c0, c1) = (pa[axis].min(pb[axis]) - tol, pa[axis].max(pb[axis]) + tol);
                coord.partition_point(|&c| c < c0)..coord.partition_point(|&c| c <= c1)
            };
            let (axis, range) =
                (0..3).map(|axis| (axis, window(axis))).min_by_key(|(_, r)| r.len()).unwrap_or((0, 0..0));
            let candidates = &sorted[axis].0[range];
            on.clear();
            for &v in candidates {
                if v == a || v == b {
                    continue;
                }
                let p = mesh.positions[v as usize];
                let s = dot(sub(p, pa), d) / len2;
                if s <= 0.0 || s >= 1.0 {
                    continue;
                }
                let q = add(pa, scale(d, s));
                if dist2(p, q) <= tol * tol && dist2(p, pa) > tol * tol && dist2(p, pb) > tol * tol {
                    on.push((s, v));
                }
            }
            if !on.is_empty() {
                on.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
                on.dedup_by_key(|x| x.1);
                splits.entry(f).or_default().push((k, on.iter().map(|x| x.1).collect()));
            }
        }
        if splits.is_empty() {
            return;
        }
        // Re-triangulate each split triangle: its corners and split points form a convex polygon
        // (the points lie on its edges), fanned from a corner not on a split edge when possible.
        let mut faces: Vec<u32> = splits.keys().copied().collect();
        faces.sort_unstable();
        for f in faces {
            let t = mesh.triangles[f as usize];
            let list = &splits[&f];
            let mut polygon: Vec<u32> = Vec::new();
            for k in 0..3u8 {
                polygon.push(t[k as usize]);
                if let Some((_, vs)) = list.iter().find(|(kk, _)| *kk == k) {
                    polygon.extend_from_slice(vs);
                }
            }
            // The corner opposite the first split edge sees every split point of that edge.
            let first = list.iter().map(|(k, _)| *k).min().unwrap_or(0);
            let apex = t[(first as usize + 2) % 3];
            let start = polygon.iter().position(|&v| v == apex).unwrap_or(0);
            polygon.rotate_left(start);
            let x = triangle_voxels[f as usize];
            let mut fan = (1..polygon.len() - 1).map(|i| [polygon[0], polygon[i], polygon[i + 1]]);
            if let Some(tri) = fan.next() {
                mesh.triangles[f as usize] = tri;
            }
            for tri in fan {
                mesh.triangles.push(tri);
                triangle_voxels.push(x);
            }
        }
    }
}

/// Connected components (through shared vertices, counting only components with triangles) and
/// boundary edges (used by one triangle) of a mesh. Sort-based, several times faster than
/// [`TriMesh::edge_stats`] and [`TriMesh::components`], which hash every edge; this runs on every
/// interactive solve.
pub(crate) fn mesh_stats(mesh: &TriMesh) -> (usize, usize) {
    let mut keys: Vec<u64> = Vec::with_capacity(3 * mesh.triangles.len());
    let mut uf = UnionFind::new(mesh.positions.len());
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if a != b {
                keys.push(((a.min(b) as u64) << 32) | a.max(b) as u64);
            }
        }
        uf.union(t[0] as usize, t[1] as usize);
        uf.union(t[0] as usize, t[2] as usize);
    }
    keys.sort_unstable();
    let mut boundary = 0;
    let mut i = 0;
    while i < keys.len() {
        let mut j = i + 1;
        while j < keys.len() && keys[j] == keys[i] {
            j += 1;
        }
        if j - i == 1 {
            boundary += 1;
        }
        i = j;
    }
    let mut seen = vec![false; mesh.positions.len()];
    let mut components = 0;
    for t in &mesh.triangles {
        let r = uf.find(t[0] as usize);
        if !seen[r] {
            seen[r] = true;
            components += 1;
        }
    }
    (components, boundary)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_agree_with_the_mesh_methods() {
        let m = motif_core::procedural::generate("fence", 0).unwrap().mesh;
        let (c, b) = mesh_stats(&m);
        assert_eq!(c, m.components().count);
        assert_eq!(b, m.edge_stats().boundary);
        let mut open = m.clone();
        open.triangles.truncate(open.triangles.len() - 1);
        assert_eq!(mesh_stats(&open).1, open.edge_stats().boundary);
    }
}
