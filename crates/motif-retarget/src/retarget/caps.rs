//! Capping the openings a stitching leaves on voxel faces (a Motif extension; not in the thesis).
//!
//! **Why.** Triangles cut at voxel faces ([`super::TriangleAssignment::Cut`]) leave each copy's
//! geometry open along the faces where it was cut. Along a seam of finite cost the neighbouring
//! copy continues it and welding closes the cut; along a seam of infinite cost (one copy's geometry
//! against another copy's empty space, [`super::RetargetReport::infinite_seams`]) nothing does,
//! and the output has holes through which the inside of its parts shows: the gridbeam shelf of
//! `../shared/data`, two cells wide, grown in width puts a beam cut open against the side of a
//! post (764 open edges for +1,+1). When the input is closed, the user expects a closed output.
//!
//! **What.** After welding, the open boundary is traced into loops (each boundary edge followed
//! from its end vertex; loops through a vertex with several outgoing boundary edges are left
//! alone). A loop is an opening of a cut when all its vertices lie on one interior voxel face
//! plane of the output grid (within 10⁻³ of a cell). The loops of one plane are nested by
//! containment (even depth: an outline, odd depth: a hole in the outline around it, such as the
//! inside of a hollow beam, or the cut of another copy's part that touches the plane inside it)
//! and each outline with its holes is triangulated by ear clipping (the `earcut` crate, a port of
//! Mapbox's earcut) in the plane's grid coordinates, an affine image of the plane (so sheared
//! lattices triangulate alike). The caps reuse the loops' vertices and are oriented against the
//! loop edges, so that every boundary edge gains its missing twin; ear clipping may skip
//! collinear loop vertices, which the T-junction pass then splits in. A group whose
//! triangulation does not cover its area (a relative deviation above 10⁻⁶: loops that cross, or
//! an outline and hole that do not fit) is left open, and so is every cap that would run along a
//! loop edge instead of against it (where a loop crosses itself by a sliver, as two copies'
//! overlapping outlines do, ear clipping covers the overlap twice, once each way). What stays
//! open is left to the hole fill ([`motif_core::hole_fill`], `RetargetOptions::fill_holes`).
//! This is the cap a mesh slicer puts on a cut (Blender's bisect with fill, trimesh's
//! `slice_plane(cap=True)`); where two copies' parts touch at the plane, the caps make two closed
//! parts touching, or, when one's opening lies inside the other's, one surface joined around it.
//!
//! Capping runs only when the input is closed: an input with its own open boundary (a scan, a
//! single-sided facade) is stitched as it is.

use std::collections::{HashMap, HashSet};

use earcut::Earcut;
use foldhash::fast::FixedState;
use motif_core::geometry::Point3;
use motif_core::mesh::{TriMesh, UnionFind, edges_by_key, single_use};

use super::canonical::Lattice;
use super::stitch::{for_each_earlier_within, split_t_junctions};
use super::voxels::VoxelGrid;

/// How close to a voxel face plane (in cells) a loop's vertices must lie.
const PLANE_EPS: f64 = 1e-3;
/// Largest relative difference between a group's polygon area and its triangulation's.
const MAX_DEVIATION: f64 = 1e-6;

/// What capping did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Capped {
    /// Boundary loops closed.
    pub loops: usize,
    /// Triangles added.
    pub triangles: usize,
    /// Coincident boundary vertices merged first.
    pub merged: usize,
}

/// A boundary loop on a voxel face plane: mesh vertices in the order of the boundary edges, their
/// coordinates in the plane, and its signed area there.
struct Loop {
    vertices: Vec<u32>,
    plane: Vec<[f64; 2]>,
    area: f64,
}

/// Caps the openings of `mesh` on the interior voxel faces of the output grid (`out_dims` voxels
/// placed on the input grid `grid_in`'s lattice); `tol` is the weld tolerance (model units) for the
/// T-junction pass. New triangles get the output voxel of the triangle along their loop's first
/// edge.
pub(crate) fn cap_openings(
    mesh: &mut TriMesh,
    triangle_voxels: &mut Vec<u32>,
    grid_in: &VoxelGrid,
    out_dims: [usize; 3],
    lattice: &Lattice,
    tol: f64,
) -> Capped {
    let grid = |p: Point3| -> [f64; 3] {
        let c = lattice.canonical(p);
        std::array::from_fn(|d| (c[d] - grid_in.origin[d]) / grid_in.pitch[d])
    };
    let on_interior_face = |u: [f64; 3]| (0..3).any(|d| interior_plane(u[d], out_dims[d]).is_some());
    let mut keys = edges_by_key(&mesh.triangles, mesh.positions.len());
    let mut capped = Capped {
        merged: merge_coincident_boundary(mesh, triangle_voxels, &keys, &on_interior_face, &grid, tol),
        ..Default::default()
    };
    if capped.merged > 0 {
        split_t_junctions(mesh, triangle_voxels, tol);
        keys = edges_by_key(&mesh.triangles, mesh.positions.len());
    }

    // Directed boundary edges a → b (as in their one triangle), by start vertex.
    let mut next: HashMap<u32, (u32, u32), FixedState> = HashMap::default();
    let mut branching: Vec<u32> = Vec::new();
    for &(_, f, k) in single_use(&keys) {
        let t = mesh.triangles[f as usize];
        let (a, b) = (t[k as usize], t[(k as usize + 1) % 3]);
        if a != b && next.insert(a, (b, f)).is_some() {
            branching.push(a);
        }
    }
    for a in branching {
        next.remove(&a);
    }

    // Loops, in order of their smallest start vertex (deterministic).
    let mut starts: Vec<u32> = next.keys().copied().collect();
    starts.sort_unstable();
    let mut used: HashSet<u32, FixedState> = HashSet::default();
    let mut groups: HashMap<(usize, i64), Vec<(Loop, u32)>, FixedState> = HashMap::default();
    for &s in &starts {
        if used.contains(&s) {
            continue;
        }
        let mut vertices = vec![s];
        let mut first_face = u32::MAX;
        let mut v = s;
        let closed = loop {
            let Some(&(w, f)) = next.get(&v) else { break false };
            if first_face == u32::MAX {
                first_face = f;
            }
            if w == s {
                break true;
            }
            if used.contains(&w) || vertices.len() > next.len() {
                break false;
            }
            used.insert(w);
            vertices.push(w);
            v = w;
        };
        used.insert(s);
        if !closed || vertices.len() < 3 {
            continue;
        }
        let u: Vec<[f64; 3]> = vertices.iter().map(|&v| grid(mesh.positions[v as usize])).collect();
        let Some(axis) = (0..3).find(|&d| {
            interior_plane(u[0][d], out_dims[d])
                .is_some_and(|r| u.iter().all(|p| (p[d] - r).abs() <= PLANE_EPS))
        }) else {
            continue;
        };
        let (d1, d2) = ((axis + 1) % 3, (axis + 2) % 3);
        let plane: Vec<[f64; 2]> = u.iter().map(|p| [p[d1], p[d2]]).collect();
        let area = signed_area(&plane);
        let key = (axis, u[0][axis].round() as i64);
        groups.entry(key).or_default().push((Loop { vertices, plane, area }, first_face));
    }

    let mut keys: Vec<(usize, i64)> = groups.keys().copied().collect();
    keys.sort_unstable();
    let mut earcut = Earcut::new();
    let mut out: Vec<u32> = Vec::new();
    for key in keys {
        let mut loops = groups.remove(&key).unwrap_or_default();
        loops.sort_by(|a, b| b.0.area.abs().total_cmp(&a.0.area.abs()));
        // The innermost larger loop holding each loop (point in polygon of its first vertex).
        let parent: Vec<Option<usize>> = (0..loops.len())
            .map(|i| (0..i).rev().find(|&j| contains(&loops[j].0.plane, loops[i].0.plane[0])))
            .collect();
        let mut depth = vec![0usize; loops.len()];
        for i in 0..loops.len() {
            depth[i] = parent[i].map_or(0, |p| depth[p] + 1);
        }
        for o in (0..loops.len()).filter(|&o| depth[o] % 2 == 0) {
            let holes: Vec<usize> = (0..loops.len()).filter(|&h| parent[h] == Some(o)).collect();
            // A hole runs against its outline (the surface is consistently oriented).
            if loops[o].0.area == 0.0 || holes.iter().any(|&h| loops[h].0.area * loops[o].0.area >= 0.0) {
                continue;
            }
            let mut points: Vec<[f64; 2]> = loops[o].0.plane.clone();
            let mut ids: Vec<u32> = loops[o].0.vertices.clone();
            let mut hole_starts: Vec<u32> = Vec::with_capacity(holes.len());
            for &h in &holes {
                hole_starts.push(points.len() as u32);
                points.extend_from_slice(&loops[h].0.plane);
                ids.extend_from_slice(&loops[h].0.vertices);
            }
            earcut.earcut_slice(&points, &hole_starts, &mut out);
            if out.is_empty() || earcut::deviation(points.iter().copied(), &hole_starts, &out) > MAX_DEVIATION
            {
                continue;
            }
            // Every loop edge a cap uses must run against its triangle. A loop that crosses
            // itself by a sliver (two copies' outlines overlapping) can pass the area test while
            // its twisted part runs the other way, and caps there flip the surface (58 edges used
            // twice the same way on the CGAL cheese grown by +1 along its second offset, 93 by
            // +0,+0,+1). Those caps are left out. Earcut covers the overlap twice, once each way,
            // so this leaves the cheese +1 closed and consistently oriented; any opening left
            // runs consistently, and the hole fill closes it along its own edges
            // ([`motif_core::hole_fill`]).
            let along: HashSet<(u32, u32), FixedState> = std::iter::once(o)
                .chain(holes.iter().copied())
                .flat_map(|l| {
                    let v = &loops[l].0.vertices;
                    (0..v.len()).map(move |i| (v[i], v[(i + 1) % v.len()]))
                })
                .collect();
            // Caps turn against the outline's boundary edges: the opposite sign of its area.
            let want = -loops[o].0.area.signum();
            let caps = out.chunks_exact(3).filter_map(|t| {
                let (a, b, c) = (t[0] as usize, t[1] as usize, t[2] as usize);
                let s = signed_area(&[points[a], points[b], points[c]]);
                let tri = if s * want >= 0.0 { [ids[a], ids[b], ids[c]] } else { [ids[a], ids[c], ids[b]] };
                (!(0..3).any(|k| along.contains(&(tri[k], tri[(k + 1) % 3])))).then_some(tri)
            });
            let voxel = triangle_voxels[loops[o].1 as usize];
            for tri in caps {
                mesh.triangles.push(tri);
                triangle_voxels.push(voxel);
                capped.triangles += 1;
            }
            capped.loops += 1 + holes.len();
        }
    }
    if capped.triangles > 0 && tol > 0.0 {
        split_t_junctions(mesh, triangle_voxels, tol);
    }
    if capped.merged > 0 {
        mesh.remove_unreferenced_vertices();
    }
    capped
}

/// Merges boundary vertices on interior voxel faces that coincide within `tol` (model units):
/// two copies' cuts of one part meet there with vertices that the seam welding did not join
/// (it joins only translational twins of one input vertex), e.g. the same bolt hole's rim from
/// both sides. Triangles that collapse are dropped. `keys` are the mesh's [`edges_by_key`].
/// Returns the number of vertices merged.
fn merge_coincident_boundary(
    mesh: &mut TriMesh,
    triangle_voxels: &mut Vec<u32>,
    keys: &[(u64, u32, u8)],
    on_interior_face: &dyn Fn([f64; 3]) -> bool,
    grid: &dyn Fn(Point3) -> [f64; 3],
    tol: f64,
) -> usize {
    if tol <= 0.0 {
        return 0;
    }
    let mut boundary = vec![false; mesh.positions.len()];
    for &(key, _, _) in single_use(keys) {
        boundary[(key >> 32) as usize] = true;
        boundary[(key & 0xffff_ffff) as usize] = true;
    }
    if !boundary.contains(&true) {
        return 0;
    }
    let candidate: Vec<bool> =
        (0..mesh.positions.len()).map(|v| boundary[v] && on_interior_face(grid(mesh.positions[v]))).collect();
    let mut uf = UnionFind::new(mesh.positions.len());
    let mut merged = 0;
    for_each_earlier_within(
        &mesh.positions,
        |v| candidate[v],
        tol,
        |a, b| {
            if uf.union(a, b) {
                merged += 1;
            }
        },
    );
    if merged == 0 {
        return 0;
    }
    let mut kept = 0;
    for f in 0..mesh.triangles.len() {
        let t = mesh.triangles[f].map(|v| uf.find(v as usize) as u32);
        if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
            mesh.triangles[kept] = t;
            triangle_voxels[kept] = triangle_voxels[f];
            kept += 1;
        }
    }
    mesh.triangles.truncate(kept);
    triangle_voxels.truncate(kept);
    merged
}

/// The interior voxel face plane (grid units) a coordinate lies on along an axis of `n` output
/// voxels: an integer in `1..n` within [`PLANE_EPS`].
fn interior_plane(u: f64, n: usize) -> Option<f64> {
    let r = u.round();
    (r >= 1.0 && r <= (n as f64) - 1.0 && (u - r).abs() <= PLANE_EPS).then_some(r)
}

/// The signed area of a closed polygon (shoelace formula), positive counter-clockwise.
fn signed_area(p: &[[f64; 2]]) -> f64 {
    let n = p.len();
    0.5 * (0..n).map(|i| p[i][0] * p[(i + 1) % n][1] - p[(i + 1) % n][0] * p[i][1]).sum::<f64>()
}

/// Whether `q` lies inside the closed polygon `p` (even–odd rule).
fn contains(p: &[[f64; 2]], q: [f64; 2]) -> bool {
    let mut inside = false;
    let n = p.len();
    for i in 0..n {
        let (a, b) = (p[i], p[(i + 1) % n]);
        if (a[1] > q[1]) != (b[1] > q[1]) {
            let x = a[0] + (q[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if q[0] < x {
                inside = !inside;
            }
        }
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::retarget::stitch::mesh_stats;
    use motif_core::procedural::box_mesh;

    /// A box with the faces on `x = at` removed.
    fn open_box(min: Point3, max: Point3, at: f64) -> TriMesh {
        let mut m = box_mesh(min, max, [1, 1, 1]).unwrap();
        let p = m.positions.clone();
        m.triangles.retain(|t| !t.iter().all(|&v| (p[v as usize][0] - at).abs() < 1e-12));
        m
    }

    /// The lattice and grid of unit cells over [0, 2] × [0, 1] × [0, 1] (model units): the plane
    /// x = 1 is the one interior voxel face along x.
    fn two_cells() -> (Lattice, VoxelGrid) {
        let bounds = box_mesh([0.0; 3], [2.0, 1.0, 1.0], [1, 1, 1]).unwrap();
        let n = crate::retarget::canonical::normalisation_of(&bounds).unwrap();
        let lattice = Lattice::regular(n, n.scale); // one model unit per cell
        let grid = VoxelGrid::covering(&lattice, &bounds.positions);
        assert_eq!(grid.dims, [2, 1, 1]);
        (lattice, grid)
    }

    fn cap(mesh: &mut TriMesh) -> Capped {
        let (lattice, grid) = two_cells();
        let mut voxels = vec![0u32; mesh.triangles.len()];
        let c = cap_openings(mesh, &mut voxels, &grid, [2, 1, 1], &lattice, 1e-6);
        assert_eq!(voxels.len(), mesh.triangles.len());
        c
    }

    /// Every edge used exactly twice, once each way: closed and consistently oriented.
    fn assert_closed_and_oriented(mesh: &TriMesh) {
        let mut uses: HashMap<(u32, u32), i32> = HashMap::new();
        for t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
            }
        }
        assert!(uses.values().all(|&u| u == 0), "an edge is open or used twice the same way");
        assert_eq!(mesh_stats(mesh).1, 0);
    }

    #[test]
    fn an_opening_on_an_interior_face_is_capped_outwards() {
        let mut m = open_box([0.0; 3], [1.0; 3], 1.0);
        assert_eq!(mesh_stats(&m).1, 4);
        let c = cap(&mut m);
        assert_eq!((c.loops, c.triangles, c.merged), (1, 2, 0));
        assert_closed_and_oriented(&m);
        assert!((m.signed_volume() - 1.0).abs() < 1e-12, "outward caps: volume {}", m.signed_volume());
    }

    #[test]
    fn a_hollow_section_gets_a_cap_with_a_hole() {
        // A box with a box-shaped cavity, both open at x = 1: a hollow beam cut at a voxel face.
        let mut m = open_box([0.0; 3], [1.0; 3], 1.0);
        let mut cavity = open_box([0.2, 0.3, 0.3], [1.0, 0.7, 0.7], 1.0);
        for t in &mut cavity.triangles {
            t.swap(1, 2); // inward-facing
        }
        m.append(&cavity);
        assert_eq!(mesh_stats(&m).1, 8);
        let c = cap(&mut m);
        assert_eq!((c.loops, c.merged), (2, 0));
        assert_closed_and_oriented(&m);
        let want = 1.0 - 0.8 * 0.4 * 0.4;
        assert!((m.signed_volume() - want).abs() < 1e-12, "volume {} vs {want}", m.signed_volume());
    }

    #[test]
    fn two_copies_meeting_on_a_face_are_merged_not_capped() {
        // Left and right halves, each open towards the other, with their own vertices on x = 1.
        let mut m = open_box([0.0; 3], [1.0; 3], 1.0);
        m.append(&open_box([1.0, 0.0, 0.0], [2.0, 1.0, 1.0], 1.0));
        let c = cap(&mut m);
        assert_eq!((c.loops, c.triangles, c.merged), (0, 0, 4));
        assert_eq!(m.positions.len(), 12, "the merged duplicates are removed");
        assert_closed_and_oriented(&m);
        assert!((m.signed_volume() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn openings_on_the_outer_faces_stay_open() {
        // The output's own outer faces are no seam: a model open there stays open.
        let mut m = open_box([0.0; 3], [1.0; 3], 0.0);
        let c = cap(&mut m);
        assert_eq!(c, Capped::default());
        assert_eq!(mesh_stats(&m).1, 4);
    }
}
