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
    let mut key_to_vertex: HashMap<(u32, [i32; 3]), u32> = HashMap::new();
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
        for &f in &by_voxel[start[s] as usize..start[s + 1] as usize] {
            let tri = mesh.triangles[f as usize].map(|v| {
                *key_to_vertex.entry((v, k)).or_insert_with(|| {
                    positions.push(add(mesh.positions[v as usize], t));
                    origin_of.push((v, k));
                    (positions.len() - 1) as u32
                })
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
    Stitched { mesh: TriMesh { positions: new_positions, triangles: kept }, triangle_voxels: kept_voxels, welded }
}
