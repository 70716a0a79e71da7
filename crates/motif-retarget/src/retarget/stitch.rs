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

use motif_core::geometry::{Point3, add, dist2};
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
    Stitched {
        mesh: TriMesh { positions: new_positions, triangles: kept },
        triangle_voxels: kept_voxels,
        welded,
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
