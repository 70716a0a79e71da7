//! Cutting triangles at voxel faces ([`super::TriangleAssignment::Cut`]).
//!
//! Centroid assignment copies a triangle wholesale with its voxel, which is right for models whose
//! parts are tessellated within cells and wrong for a triangle spanning several cells (a back
//! panel made of one quad): it would be copied, not stretched. Cutting splits every triangle by
//! the grid planes inside it into convex pieces, each inside one voxel, and fan-triangulates them.
//!
//! New vertices are shared exactly: a point where a plane crosses an input edge is identified by
//! (edge, plane) and computed from the edge's endpoints in index order, so both triangles of the
//! edge get the same vertex, bit for bit; a point where two planes cross inside a triangle is
//! shared by the pieces of that triangle. The cut mesh describes the same surface as the input.
//!
//! A vertex within 10⁻⁶ of a cell from a plane lies on it (the centroid probe's step,
//! [`super::voxels`]; seams are welded within 10⁻³): the plane is not cut through its edges.
//! Models stored in single precision place vertices meant to be on a cell boundary up to about
//! 10⁻⁸ of a cell off it (the CGAL cheese: −0.0250000005 for −0.025), and a tolerance of 10⁻⁹
//! cut their edges a few 10⁻¹¹ model units from them, into 176 triangles of no area whose
//! copies then met as edges of three and four triangles. Measured with `cargo test --release -p
//! motif-retarget --test retarget caps_and_fills -- --nocapture`, open edges plain → with caps
//! with 10⁻⁹ and then 10⁻⁶: gridbeam shelf +1,+1 764 → 6 and 16 → 0; cheese +1 along its first
//! offset 917 → 156 (240 edges of three or four triangles, 12 misoriented) and 800 → 0.

use std::collections::HashMap;

use foldhash::fast::FixedState;

use motif_core::geometry::{Point3, lerp};
use motif_core::mesh::TriMesh;

use super::canonical::Lattice;
use super::voxels::VoxelGrid;

/// Where a polygon vertex lies on its input triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum On {
    /// An input vertex.
    Vertex(u32),
    /// The interior of input edge (a, b), a < b.
    Edge(u32, u32),
    /// The interior of the triangle.
    Inside,
}

#[derive(Debug, Clone, Copy)]
struct PolyVertex {
    id: u32,
    /// Canonical coordinates.
    c: Point3,
    on: On,
}

/// The input edge a segment lies on, if any.
fn common_edge(u: On, w: On) -> Option<(u32, u32)> {
    let sorted = |a: u32, b: u32| (a.min(b), a.max(b));
    match (u, w) {
        (On::Vertex(a), On::Vertex(b)) if a != b => Some(sorted(a, b)),
        (On::Vertex(a), On::Edge(c, d)) | (On::Edge(c, d), On::Vertex(a)) if a == c || a == d => Some((c, d)),
        (On::Edge(a, b), On::Edge(c, d)) if (a, b) == (c, d) => Some((a, b)),
        _ => None,
    }
}

/// The input mesh cut at the grid's interior planes (canonical space).
/// Returns the cut mesh (the input's vertices first, with their indices) and, for each of its
/// triangles, the input triangle it is a piece of.
pub(crate) fn cut_at_voxel_faces(mesh: &TriMesh, lattice: &Lattice, grid: &VoxelGrid) -> (TriMesh, Vec<u32>) {
    let canon: Vec<Point3> = mesh.positions.iter().map(|p| lattice.canonical(*p)).collect();
    let mut positions = mesh.positions.clone();
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(mesh.triangles.len());
    // Edge crossings shared between triangles: (a, b, axis, plane) → vertex.
    let mut edge_points: HashMap<(u32, u32, u8, i64), u32, FixedState> = HashMap::default();
    let eps: [f64; 3] = std::array::from_fn(|a| 1e-6 * grid.pitch[a]);
    // The interior grid plane along `axis` that canonical point `c` lies on, if any.
    let plane_of = |c: Point3, axis: usize| -> Option<i64> {
        let k = ((c[axis] - grid.origin[axis]) / grid.pitch[axis]).round();
        let on = (c[axis] - (grid.origin[axis] + k * grid.pitch[axis])).abs() <= eps[axis];
        (on && k >= 1.0 && k <= (grid.dims[axis] - 1) as f64).then_some(k as i64)
    };
    // Crossings of two planes inside one triangle, shared by the pieces of that triangle:
    // ((axis, plane) of the earlier cut, plane of the current cut along `axis`) → vertex.
    let mut inside_points: HashMap<((usize, i64), i64), u32, FixedState> = HashMap::default();
    let mut parent: Vec<u32> = Vec::with_capacity(mesh.triangles.len());
    for (f, t) in mesh.triangles.iter().enumerate() {
        inside_points.clear();
        let mut pieces: Vec<Vec<PolyVertex>> =
            vec![t.iter().map(|&v| PolyVertex { id: v, c: canon[v as usize], on: On::Vertex(v) }).collect()];
        for axis in 0..3 {
            let mut next_pieces = Vec::with_capacity(pieces.len());
            for poly in pieces {
                let (lo, hi) = poly.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                    (l.min(v.c[axis]), h.max(v.c[axis]))
                });
                // Interior planes strictly inside the piece's extent.
                let first = (((lo - grid.origin[axis]) / grid.pitch[axis]).floor() as i64 + 1).max(1);
                let last = (((hi - grid.origin[axis]) / grid.pitch[axis]).ceil() as i64 - 1)
                    .min(grid.dims[axis] as i64 - 1);
                let mut rest = poly;
                for plane in first..=last {
                    let h = grid.origin[axis] + plane as f64 * grid.pitch[axis];
                    if !(lo < h - eps[axis] && hi > h + eps[axis]) {
                        continue;
                    }
                    let mut below = Vec::with_capacity(rest.len() + 1);
                    let mut above = Vec::with_capacity(rest.len() + 1);
                    for i in 0..rest.len() {
                        let u = rest[i];
                        let w = rest[(i + 1) % rest.len()];
                        let (du, dw) = (u.c[axis] - h, w.c[axis] - h);
                        if du <= eps[axis] {
                            below.push(u);
                        }
                        if du >= -eps[axis] {
                            above.push(u);
                        }
                        if (du < -eps[axis] && dw > eps[axis]) || (du > eps[axis] && dw < -eps[axis]) {
                            let x = match common_edge(u.on, w.on) {
                                Some((a, b)) => {
                                    let key = (a, b, axis as u8, plane);
                                    let (ca, cb) = (canon[a as usize], canon[b as usize]);
                                    let s = (h - ca[axis]) / (cb[axis] - ca[axis]);
                                    let mut c = lerp(ca, cb, s);
                                    c[axis] = h;
                                    let id = *edge_points.entry(key).or_insert_with(|| {
                                        positions.push(lerp(
                                            mesh.positions[a as usize],
                                            mesh.positions[b as usize],
                                            s,
                                        ));
                                        (positions.len() - 1) as u32
                                    });
                                    PolyVertex { id, c, on: On::Edge(a, b) }
                                }
                                None => {
                                    let s = (h - u.c[axis]) / (w.c[axis] - u.c[axis]);
                                    let mut c = lerp(u.c, w.c, s);
                                    c[axis] = h;
                                    // The segment runs along an earlier cut plane (both ends lie on
                                    // it); the pieces on either side of that plane share the point.
                                    let along =
                                        (0..axis).find_map(|a| match (plane_of(u.c, a), plane_of(w.c, a)) {
                                            (Some(p), Some(q)) if p == q => Some((a, p)),
                                            _ => None,
                                        });
                                    let mut fresh = || {
                                        positions.push(lerp(
                                            positions[u.id as usize],
                                            positions[w.id as usize],
                                            s,
                                        ));
                                        (positions.len() - 1) as u32
                                    };
                                    let id = match along {
                                        Some(key) => *inside_points.entry((key, plane)).or_insert_with(fresh),
                                        None => fresh(),
                                    };
                                    PolyVertex { id, c, on: On::Inside }
                                }
                            };
                            below.push(x);
                            above.push(x);
                        }
                    }
                    if below.len() >= 3 {
                        next_pieces.push(below);
                    }
                    rest = above;
                    if rest.len() < 3 {
                        break;
                    }
                }
                if rest.len() >= 3 {
                    next_pieces.push(rest);
                }
            }
            pieces = next_pieces;
        }
        for poly in pieces {
            for i in 1..poly.len() - 1 {
                let tri = [poly[0].id, poly[i].id, poly[i + 1].id];
                if tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2] {
                    triangles.push(tri);
                    parent.push(f as u32);
                }
            }
        }
    }
    (TriMesh { positions, triangles }, parent)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::retarget::canonical::Normalisation;

    #[test]
    fn a_big_quad_is_cut_into_cells_without_changing_its_area() {
        // A 3 × 2 quad in the plane z = 0; cells of 1 × 1 (normalisation scale 1).
        let mesh = TriMesh::new(
            vec![[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [3.0, 2.0, 0.0], [0.0, 2.0, 0.0]],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .unwrap();
        let n = Normalisation { centre: [0.0; 3], scale: 1.0 };
        let lattice = Lattice::from_offsets(n, &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], 0.2).unwrap();
        let grid = VoxelGrid::covering(&lattice, &mesh.positions);
        assert_eq!(grid.dims, [3, 2, 1]);
        let (cut, parent) = cut_at_voxel_faces(&mesh, &lattice, &grid);
        assert!((cut.area() - 6.0).abs() < 1e-12);
        // The input's vertices keep their indices, and each piece names its input triangle: the
        // pieces of each add up to its area.
        assert_eq!(cut.positions[..4], mesh.positions[..]);
        assert_eq!(parent.len(), cut.triangles.len());
        let areas = cut.face_areas();
        for p in 0..2 {
            let area: f64 = (0..cut.triangles.len()).filter(|&f| parent[f] == p).map(|f| areas[f]).sum();
            assert!((area - 3.0).abs() < 1e-12, "input triangle {p}: area {area}");
        }
        // Every piece lies in one cell.
        for f in 0..cut.triangles.len() {
            let c = cut.corners(f);
            for a in 0..2 {
                let lo = c.iter().map(|p| p[a]).fold(f64::INFINITY, f64::min);
                let hi = c.iter().map(|p| p[a]).fold(f64::NEG_INFINITY, f64::max);
                assert!(hi - lo <= 1.0 + 1e-12 && (lo + 1e-9).floor() == (hi - 1e-9).floor(), "{c:?}");
            }
        }
        // Shared edges got shared vertices: the cut mesh is one connected, manifold sheet.
        assert_eq!(cut.components().count, 1);
        let e = cut.edge_stats();
        assert_eq!(e.non_manifold, 0);
        // Boundary: 2·(3 + 2) cell edges long, each cell side one boundary edge at least.
        assert!(e.boundary >= 10);
        let len: f64 = {
            let mut count: HashMap<(u32, u32), u32> = HashMap::new();
            for t in &cut.triangles {
                for k in 0..3 {
                    let (a, b) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
                    *count.entry((a, b)).or_insert(0) += 1;
                }
            }
            count
                .iter()
                .filter(|(_, c)| **c == 1)
                .map(|((a, b), _)| {
                    motif_core::geometry::dist(cut.positions[*a as usize], cut.positions[*b as usize])
                })
                .sum()
        };
        assert!((len - 10.0).abs() < 1e-12, "boundary length {len}");
    }
}
