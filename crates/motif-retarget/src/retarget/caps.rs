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
//! from its end vertex). Where two openings touch at a vertex (two boundary edges leave it), the
//! edge arriving from one fan of triangles continues with the edge leaving the other fan, so that
//! each opening is its own loop ([`pinch_exits`]); vertices with more openings are left alone.
//! A loop is an opening of a cut when each of its edges lies on an interior voxel face plane of
//! the output grid (within 10⁻³ of a cell). A loop that runs over several planes, folding over a
//! voxel edge or around a voxel corner, is split into loops on each plane, closed by chords along
//! the voxel edges where it passes from one plane to the next, with a vertex added at a voxel
//! corner where three planes' chords meet ([`split_over_planes`]). The loops of one plane are nested by
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
//! A plane where ear clipping fails (loops that cross, as where two copies' sections overlap by a
//! sliver, or a hole that runs with its outline) is capped by the winding rule instead: a
//! constrained Delaunay triangulation of all its loops (`spade`), crossings split, keeping the
//! triangles the loops wind around once, each turned against its loops ([`winding_caps`]).
//!
//! On the CGAL cheese grown by +1 along its first two offsets (`motif retarget cgal_cheese.off
//! --steps 1,1,0`) an opening folds over a voxel edge, touches another at a vertex, and its part
//! on one plane is two copies' sections overlapping by a sliver. Before these three steps it was
//! one loop of 609 vertices, which the hole fill (limit 600 vertices) left open; filling it
//! anyway spanned a flat sheet across the cavity. Now caps close it with the cavity's
//! cross-sections cut out, and the fill adds nothing.
//! Grown by +2 along its first offset, one opening of 753 vertices runs over four planes and
//! around a voxel corner; split over its planes, caps close it too. Two kinds of opening were
//! still left open until 2026-11-28 (over all six orders of the offsets of the cheese, as it is
//! and turned by 47°, times five step vectors, 12 of 60 outputs kept 672–1,075 open edges,
//! `the_cheese_grown_with_its_offsets_in_every_order_stitches_closed`): an opening that wraps round a voxel,
//! whose planes' lines enclose a face, so that the chords are not unique plane by plane, and two
//! copies' sections touching along a voxel edge, whose chords run twice along it. Chords chosen
//! over all planes at once ([`joint_chords`]), each segment crossed up to twice, close all 60
//! (0 open, 0 misoriented edges; up to 3 edges of four triangles where sections touch).
//! This is the cap a mesh slicer puts on a cut (Blender's bisect with fill, trimesh's
//! `slice_plane(cap=True)`); where two copies' parts touch at the plane, the caps make two closed
//! parts touching, or, when one's opening lies inside the other's, one surface joined around it.
//!
//! After capping, walls of no thickness are removed: pairs of triangles on the same three
//! vertices facing opposite ways ([`remove_cancelling_pairs`]) and closed parts lying flat on one
//! voxel face ([`remove_flat_sheets`]), where a cap was laid over input faces lying on the voxel
//! face it caps.
//!
//! The input's own openings stay open: a loop with an edge copied from the input's open boundary
//! (a scan's edge, a single-sided facade's rim, an open part of a model whose other parts are
//! closed) is neither capped nor filled. Before, any open edge in the input turned capping off for
//! the whole model: the Kiva shelf pod of the shared data (2 of its 64 parts open, 16 open edges)
//! grown by two levels kept 165 open edges (47 now, 0 misoriented).

use std::collections::{HashMap, HashSet};

use earcut::Earcut;
use foldhash::fast::FixedState;
use motif_core::geometry::Point3;
use motif_core::mesh::{TriMesh, UnionFind, edges_by_key, single_use};
use spade::handles::FixedVertexHandle;
use spade::{ConstrainedDelaunayTriangulation, HasPosition, Point2, Triangulation};

use super::canonical::{Lattice, Mat3, invert3, mul3};
use super::stitch::{for_each_earlier_within, split_t_junctions};
use super::voxels::VoxelGrid;

/// How close to a voxel face plane (in cells) a loop's vertices must lie.
const PLANE_EPS: f64 = 1e-3;
/// Largest relative difference between a group's polygon area and its triangulation's.
const MAX_DEVIATION: f64 = 1e-6;

/// What capping did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Capped {
    /// Boundary loops closed (on a plane capped by the winding rule, every loop of the plane,
    /// though a region that two of its loops wind around twice the same way stays open).
    pub loops: usize,
    /// Triangles added.
    pub triangles: usize,
    /// Coincident boundary vertices merged first.
    pub merged: usize,
    /// Loops over several voxel face planes split into loops on each (`split_over_planes`).
    pub split_loops: usize,
    /// Vertices added at voxel corners where such a loop's parts meet.
    pub corners: usize,
    /// Planes whose openings were capped by the winding rule (loops that cross).
    pub winding_planes: usize,
    /// Pairs of triangles on the same vertices facing opposite ways, or the same way (a sheet
    /// laid twice), removed after capping ([`remove_cancelling_pairs`]).
    pub cancelled_pairs: usize,
    /// Closed parts lying flat on one voxel face plane, removed after capping
    /// ([`remove_flat_sheets`]).
    pub flat_sheets: usize,
    /// Openings left open because they run along the input's own open boundary.
    pub kept_open: usize,
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
    keep_open: &mut Vec<bool>,
) -> Capped {
    // `keep_open` follows the vertices through every merge, addition and renumbering below.
    if !keep_open.is_empty() {
        keep_open.resize(mesh.positions.len(), false);
    }
    let grid = |p: Point3| -> [f64; 3] {
        let c = lattice.canonical(p);
        std::array::from_fn(|d| (c[d] - grid_in.origin[d]) / grid_in.pitch[d])
    };
    let on_interior_face = |u: [f64; 3]| (0..3).any(|d| interior_plane(u[d], out_dims[d]).is_some());
    let mut keys = edges_by_key(&mesh.triangles, mesh.positions.len());
    let mut capped = Capped {
        merged: merge_coincident_boundary(
            mesh,
            triangle_voxels,
            &keys,
            &on_interior_face,
            &grid,
            tol,
            keep_open,
        ),
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
    branching.sort_unstable();
    branching.dedup();
    // At a vertex where two openings touch (two boundary edges leave it), an edge arriving from
    // one fan of triangles leaves through the other fan's edge (see `pinch_exits`).
    let mut exits: HashMap<(u32, u32), (u32, u32), FixedState> = HashMap::default();
    let mut rings: HashMap<u32, Vec<u32>, FixedState> = branching.iter().map(|&v| (v, Vec::new())).collect();
    if !rings.is_empty() {
        for (f, t) in mesh.triangles.iter().enumerate() {
            for v in t {
                if let Some(r) = rings.get_mut(v)
                    && r.last() != Some(&(f as u32))
                {
                    r.push(f as u32);
                }
            }
        }
    }
    for &v in &branching {
        next.remove(&v);
        if let Some(pairs) = pinch_exits(mesh, &keys, v, &rings[&v]) {
            for (from, to) in pairs {
                exits.insert((from, v), to);
            }
        }
    }

    // Grid coordinates back to model space (the map is affine), for the vertices added
    // where a loop's parts on several planes meet at a corner, or where loops cross (winding caps).
    let origin = grid([0.0; 3]);
    let columns = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]].map(|e| {
        let g = grid(e);
        [g[0] - origin[0], g[1] - origin[1], g[2] - origin[2]]
    });
    let to_grid: Mat3 = std::array::from_fn(|r| std::array::from_fn(|c| columns[c][r]));
    let from_grid = invert3(&to_grid);

    // Loops, in order of their smallest start vertex (deterministic).
    let mut starts: Vec<u32> = next.keys().copied().collect();
    starts.sort_unstable();
    let mut used: HashSet<u32, FixedState> = HashSet::default();
    let mut groups: HashMap<(usize, i64), Vec<(Loop, u32)>, FixedState> = HashMap::default();
    let mut corner_ids = Corners::default();
    for &s in &starts {
        if used.contains(&s) {
            continue;
        }
        let mut vertices = vec![s];
        // faces[k]: the triangle along the edge from vertices[k] to the next vertex.
        let mut faces: Vec<u32> = Vec::new();
        let mut v = s;
        let closed = loop {
            let step = match next.get(&v) {
                Some(&e) => Some(e),
                None => vertices.len().checked_sub(2).and_then(|i| exits.get(&(vertices[i], v)).copied()),
            };
            let Some((w, f)) = step else { break false };
            faces.push(f);
            if w == s {
                break true;
            }
            if (used.contains(&w) && !rings.contains_key(&w)) || vertices.len() > next.len() + 2 * rings.len()
            {
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
        // An opening along the input's own boundary (an edge of it between two vertices on that
        // boundary) stays as the input had it.
        if runs_along(&vertices, keep_open) {
            capped.kept_open += 1;
            continue;
        }
        let u: Vec<[f64; 3]> = vertices.iter().map(|&v| grid(mesh.positions[v as usize])).collect();
        let base = if from_grid.is_some() { mesh.positions.len() as u32 } else { u32::MAX };
        let Some((parts, corners)) =
            split_over_planes(&vertices, &faces, &u, out_dims, &mut corner_ids, base)
        else {
            continue;
        };
        if parts.len() > 1 {
            capped.split_loops += 1;
        }
        if let Some(m) = from_grid {
            for c in corners {
                mesh.positions.push(mul3(&m, [c[0] - origin[0], c[1] - origin[1], c[2] - origin[2]]));
                capped.corners += 1;
            }
        }
        for part in parts {
            let (d1, d2) = ((part.axis + 1) % 3, (part.axis + 2) % 3);
            let plane: Vec<[f64; 2]> = part.u.iter().map(|p| [p[d1], p[d2]]).collect();
            let area = signed_area(&plane);
            groups
                .entry((part.axis, part.at))
                .or_default()
                .push((Loop { vertices: part.vertices, plane, area }, part.face));
        }
    }

    let mut keys: Vec<(usize, i64)> = groups.keys().copied().collect();
    keys.sort_unstable();
    let mut earcut = Earcut::new();
    let mut out: Vec<u32> = Vec::new();
    let mut caps: Vec<([u32; 3], u32)> = Vec::new();
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
        caps.clear();
        let mut closed_loops = 0;
        let mut simple = true;
        for o in (0..loops.len()).filter(|&o| depth[o] % 2 == 0) {
            let holes: Vec<usize> = (0..loops.len()).filter(|&h| parent[h] == Some(o)).collect();
            // A hole runs against its outline (the surface is consistently oriented).
            if loops[o].0.area == 0.0 || holes.iter().any(|&h| loops[h].0.area * loops[o].0.area >= 0.0) {
                simple = false;
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
                simple = false;
                continue;
            }
            // Caps turn against the outline's boundary edges: the opposite sign of its area.
            let want = -loops[o].0.area.signum();
            let voxel = triangle_voxels[loops[o].1 as usize];
            caps.extend(out.chunks_exact(3).map(|t| {
                let (a, b, c) = (t[0] as usize, t[1] as usize, t[2] as usize);
                let s = signed_area(&[points[a], points[b], points[c]]);
                let tri = if s * want >= 0.0 { [ids[a], ids[b], ids[c]] } else { [ids[a], ids[c], ids[b]] };
                (tri, voxel)
            }));
            closed_loops += 1 + holes.len();
        }
        if !simple
            && let Some(m) = from_grid
            && let Some(w) = winding_caps(&loops, mesh.positions.len() as u32)
        {
            // Loops that cross (two copies' sections overlapping, or a section folded over a
            // voxel edge and split over its planes) or a hole that runs with its outline: the whole plane
            // is capped by the winding rule instead.
            let (d1, d2) = ((key.0 + 1) % 3, (key.0 + 2) % 3);
            for q in &w.new_points {
                let mut u = [0.0; 3];
                u[key.0] = key.1 as f64;
                u[d1] = q[0];
                u[d2] = q[1];
                mesh.positions.push(mul3(&m, [u[0] - origin[0], u[1] - origin[1], u[2] - origin[2]]));
            }
            let voxel = triangle_voxels[loops[0].1 as usize];
            caps.clear();
            caps.extend(w.triangles.iter().map(|&t| (t, voxel)));
            closed_loops = loops.len();
            capped.winding_planes += 1;
        }
        // Every loop edge a cap uses must run against its triangle. A loop that crosses itself by
        // a sliver (two copies' outlines overlapping) can pass the area test while its twisted
        // part runs the other way, and caps there flip the surface (58 edges used twice the same
        // way on the CGAL cheese grown by +1 along its second offset, 93 by +0,+0,+1). Those caps
        // are left out. Earcut covers the overlap twice, once each way, so this leaves the cheese
        // +1 closed and consistently oriented; any opening left runs consistently, and the hole
        // fill closes it along its own edges ([`motif_core::hole_fill`]).
        let along: HashSet<(u32, u32), FixedState> = loops
            .iter()
            .flat_map(|l| {
                let v = &l.0.vertices;
                (0..v.len()).map(move |i| (v[i], v[(i + 1) % v.len()]))
            })
            .collect();
        for &(tri, voxel) in &caps {
            if (0..3).any(|k| along.contains(&(tri[k], tri[(k + 1) % 3]))) {
                continue;
            }
            mesh.triangles.push(tri);
            triangle_voxels.push(voxel);
            capped.triangles += 1;
        }
        capped.loops += closed_loops;
    }
    if capped.triangles > 0 && tol > 0.0 {
        split_t_junctions(mesh, triangle_voxels, tol);
    }
    if !keep_open.is_empty() {
        keep_open.resize(mesh.positions.len(), false);
    }
    if capped.merged > 0 || capped.corners > 0 {
        let map = mesh.remove_unreferenced_vertices();
        remap_flags(keep_open, &map, mesh.positions.len());
    }
    capped.cancelled_pairs = remove_cancelling_pairs(mesh, triangle_voxels, keep_open);
    capped.flat_sheets = remove_flat_sheets(mesh, triangle_voxels, &grid, keep_open);
    capped
}

/// True when the closed loop `vertices` has an edge between two vertices `flags` marks: an edge
/// copied from the input's own open boundary. (A single marked vertex is not enough: a cut
/// opening of a closed part may touch an open part's rim at one vertex.)
pub(crate) fn runs_along(vertices: &[u32], flags: &[bool]) -> bool {
    let on = |v: u32| flags.get(v as usize).copied().unwrap_or(false);
    !flags.is_empty()
        && (0..vertices.len()).any(|i| on(vertices[i]) && on(vertices[(i + 1) % vertices.len()]))
}

/// Carries per-vertex flags through a renumbering (`map`: old vertex → new, `u32::MAX` for a
/// vertex removed); `len` is the new vertex count. Empty flags stay empty.
fn remap_flags(flags: &mut Vec<bool>, map: &[u32], len: usize) {
    if flags.is_empty() {
        return;
    }
    let mut moved = vec![false; len];
    for (v, &m) in map.iter().enumerate() {
        if m != u32::MAX && flags.get(v).copied().unwrap_or(false) {
            moved[m as usize] = true;
        }
    }
    *flags = moved;
}

/// The continuations of the boundary at a pinch vertex `v` where two openings touch: two boundary
/// edges arrive and two leave, each pair bounding one fan of triangles around `v` (a fan is
/// followed from its leaving edge through the triangles that share an edge at `v`, once each way,
/// to its arriving edge). An opening is the gap between two fans, so the edge arriving from one
/// fan continues with the edge leaving the other; following the same fan would trace both
/// openings as one figure of eight. Returns `(a, b)` pairs: the edge `a → v` continues with
/// `v → b`. `None` (the vertex stays a dead end for the tracing) for more than two fans or a fan
/// through an edge used by more than two triangles. `ring` lists the triangles around `v`.
fn pinch_exits(
    mesh: &TriMesh,
    keys: &[(u64, u32, u8)],
    v: u32,
    ring: &[u32],
) -> Option<[(u32, (u32, u32)); 2]> {
    let uses = |a: u32, b: u32| -> &[(u64, u32, u8)] {
        let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
        let lo = keys.partition_point(|e| e.0 < key);
        let hi = keys.partition_point(|e| e.0 <= key);
        &keys[lo..hi]
    };
    let other = |f: u32, a: u32| -> Option<u32> {
        // The third vertex of triangle f given its vertices v and a.
        mesh.triangles[f as usize].into_iter().find(|&x| x != v && x != a)
    };
    // The boundary edges leaving v, with their triangles.
    let mut leaving: Vec<(u32, u32)> = Vec::new();
    for &f in ring {
        let t = mesh.triangles[f as usize];
        let k = t.iter().position(|&x| x == v)?;
        let b = t[(k + 1) % 3];
        if uses(v, b).len() == 1 {
            leaving.push((b, f));
        }
    }
    if leaving.len() != 2 {
        return None;
    }
    // From each leaving edge, round its fan to the arriving edge.
    let mut arriving = [0u32; 2];
    for (i, &(b, f0)) in leaving.iter().enumerate() {
        let (mut f, mut a) = (f0, b);
        let mut steps = 0;
        arriving[i] = loop {
            let c = other(f, a)?; // the triangle's other vertex: its edge c → v arrives at v
            let u = uses(v, c);
            if u.len() == 1 {
                break c;
            }
            if u.len() != 2 || steps > ring.len() {
                return None;
            }
            f = if u[0].1 == f { u[1].1 } else { u[0].1 };
            a = c;
            steps += 1;
        };
    }
    Some([(arriving[0], leaving[1]), (arriving[1], leaving[0])])
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
    flags: &mut [bool],
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
    // A merged group keeps the flag any of its vertices had.
    for v in 0..flags.len() {
        if flags[v] {
            let r = uf.find(v);
            flags[r] = true;
        }
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

/// Caps by the winding rule: the triangles (mesh vertex ids; `base + k` for the k-th new point)
/// and the plane coordinates of the vertices added where loops cross.
struct WindingCaps {
    triangles: Vec<[u32; 3]>,
    new_points: Vec<[f64; 2]>,
}

/// A vertex of the constrained triangulation of a plane's loops.
#[derive(Clone, Copy, Debug)]
struct PlaneVertex(Point2<f64>);

impl HasPosition for PlaneVertex {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.0
    }
}

/// Caps the loops of one plane by the winding rule, where ear clipping cannot: loops that cross
/// (two copies' sections overlapping by a sliver, each capped from its own side, as on the CGAL
/// cheese grown by +1 along two offsets), or a hole that runs with its outline.
///
/// The loops' edges are the constraints of a constrained Delaunay triangulation of their
/// vertices (`spade`, with crossing constraints split at a new vertex). Each triangle gets the
/// winding number of the loops around its centroid: +1 is an opening whose boundary runs
/// counter-clockwise, capped clockwise (against its edges, as every cap); −1 the reverse; 0 is
/// outside, or where two openings that face each other overlap and nothing is missing (the two
/// copies' solids meet there). Other values (openings stacked the same way) are left open. This
/// is the non-zero fill of vector graphics, read per sign, and the way a slicer resolves
/// self-intersecting outlines. `None` when two different mesh vertices share a position (the
/// triangulation would merge them; one mesh vertex met twice, at a pinch, is fine), or the
/// triangulation refuses a vertex or panics. The winding number of each triangle is counted
/// over the loops whose box holds its centroid (O(triangles × vertices of those loops); planes
/// of a few thousand loop vertices, as on the models of `../shared/data`, take milliseconds).
fn winding_caps(loops: &[(Loop, u32)], base: u32) -> Option<WindingCaps> {
    // spade asserts on some near-degenerate splits of crossing constraints (slivers are what this
    // path serves); such a plane is left to the hole fill rather than ending the run.
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| winding_caps_unguarded(loops, base)))
        .ok()
        .flatten()
}

fn winding_caps_unguarded(loops: &[(Loop, u32)], base: u32) -> Option<WindingCaps> {
    let mut cdt: ConstrainedDelaunayTriangulation<PlaneVertex> = ConstrainedDelaunayTriangulation::new();
    let mut ids: Vec<u32> = Vec::new();
    let mut handles: Vec<Vec<FixedVertexHandle>> = Vec::with_capacity(loops.len());
    for (l, _) in loops {
        let mut hs = Vec::with_capacity(l.vertices.len());
        for (&v, p) in l.vertices.iter().zip(&l.plane) {
            let h = cdt.insert(PlaneVertex(Point2::new(p[0], p[1]))).ok()?;
            if h.index() == ids.len() {
                ids.push(v);
            } else if ids.get(h.index()) != Some(&v) {
                return None;
            }
            hs.push(h);
        }
        handles.push(hs);
    }
    for hs in &handles {
        for i in 0..hs.len() {
            let (a, b) = (hs[i], hs[(i + 1) % hs.len()]);
            if a != b {
                cdt.add_constraint_and_split(a, b, PlaneVertex);
            }
        }
    }
    let new_points: Vec<[f64; 2]> = cdt
        .vertices()
        .filter(|v| v.fix().index() >= ids.len())
        .map(|v| [v.position().x, v.position().y])
        .collect();
    let id = |h: FixedVertexHandle| -> u32 {
        let i = h.index();
        if i < ids.len() { ids[i] } else { base + (i - ids.len()) as u32 }
    };
    // Each loop's box: a point outside it has winding number 0 about the loop.
    let boxes: Vec<[f64; 4]> = loops
        .iter()
        .map(|(l, _)| {
            l.plane
                .iter()
                .fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |b, p| {
                    [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])]
                })
        })
        .collect();
    let mut triangles = Vec::new();
    for face in cdt.inner_faces() {
        let [a, b, c] = face.vertices();
        let (pa, pb, pc) = (a.position(), b.position(), c.position());
        let q = [(pa.x + pb.x + pc.x) / 3.0, (pa.y + pb.y + pc.y) / 3.0];
        let w: i32 = loops
            .iter()
            .zip(&boxes)
            .filter(|(_, b)| q[0] >= b[0] && q[1] >= b[1] && q[0] <= b[2] && q[1] <= b[3])
            .map(|((l, _), _)| winding(&l.plane, q))
            .sum();
        // spade's faces run counter-clockwise.
        match w {
            1 => triangles.push([id(a.fix()), id(c.fix()), id(b.fix())]),
            -1 => triangles.push([id(a.fix()), id(b.fix()), id(c.fix())]),
            _ => {}
        }
    }
    Some(WindingCaps { triangles, new_points })
}

/// The winding number of the closed polygon `p` around `q`.
fn winding(p: &[[f64; 2]], q: [f64; 2]) -> i32 {
    let mut w = 0;
    let n = p.len();
    for i in 0..n {
        let (a, b) = (p[i], p[(i + 1) % n]);
        let side = (b[0] - a[0]) * (q[1] - a[1]) - (q[0] - a[0]) * (b[1] - a[1]);
        if a[1] <= q[1] {
            if b[1] > q[1] && side > 0.0 {
                w += 1;
            }
        } else if b[1] <= q[1] && side < 0.0 {
            w -= 1;
        }
    }
    w
}

/// A loop's part on one face plane (`axis`, grid coordinate `at`): its vertices, their grid
/// coordinates, and the triangle along its first boundary edge (whose voxel its caps get).
struct Part {
    axis: usize,
    at: i64,
    vertices: Vec<u32>,
    u: Vec<[f64; 3]>,
    face: u32,
}

/// The vertices added at voxel corners by [`split_over_planes`] while capping one mesh: one per
/// corner (grid coordinates), shared by every loop that needs it.
#[derive(Default)]
struct Corners {
    ids: HashMap<[i64; 3], u32, FixedState>,
}

/// A voxel face plane: (axis, grid coordinate).
type Plane = (usize, i64);

/// A node on the voxel edge lines of a loop's planes: a loop vertex, or a voxel corner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Key {
    Vertex(u32),
    Corner([i64; 3]),
}

/// Most times a chord may run along one segment of a voxel edge line (2: two copies' sections
/// touching along it, closed into two solids that share the edge).
const MAX_CROSSINGS: i32 = 2;

/// Most voxel corners whose flows [`joint_chords`] searches over (3^k choices).
const MAX_JOINT_CORNERS: usize = 9;

/// The chords of a loop whose planes' lines close a cycle, chosen over all its planes at once
/// (the fallback of [`split_over_planes`] step 3).
///
/// A loop that wraps round a voxel (on the CGAL cheese turned by 47° and grown +1,+1,+1 with its
/// offsets listed by axis, one opening of 672 vertices runs over five planes: x = 2 and x = 3 on
/// either side of a voxel, and y = 3, z = 2, z = 3 across it) has lines that enclose a voxel
/// face: on that face's plane, the chain between the lines is not unique (it may or may not take
/// in the whole face), and a plane may need a line the loop never passes from one of its planes to
/// the other (here y = 3 ∩ z = 3), to join two parallel lines.
///
/// Every pair of perpendicular planes of the loop is a line; its nodes are the loop vertices on
/// it and the corners where a third of the loop's planes crosses it. The chord chain `c_L` along a
/// line `L = (P, Q)` belongs to `P`, and `−c_L` to `Q`, so the two planes' chords cancel there
/// (step 4 holds by construction). Its boundary `b_L = ∂c_L` is what is unknown: on a plane `P`
/// the chords must close the runs, `Σ_L ±b_L(v) = need_P(v)` at every node `v`. At a node on one
/// line that fixes `b_L(v)`; at a corner of three planes the three equations have rank two, which
/// leaves one integer `t` per corner; and each line's chain must end: `Σ_v b_L(v) = 0`. Among the
/// choices `t ∈ {−1, 0, 1}` per corner, that chain is taken which satisfies every line and has
/// the least length, counted with multiplicity (each segment crossed at most [`MAX_CROSSINGS`]
/// times): the smallest cap that closes the loop, as a minimal surface would. More than
/// [`MAX_JOINT_CORNERS`] corners, or no such choice, fails.
///
/// Returns the chords `(plane, from, to)` over `nodes` followed by the nodes added (corners not in
/// `nodes`).
#[allow(clippy::type_complexity)]
fn joint_chords(
    planes: &[Plane],
    demand: &[((Plane, Plane), Vec<(u32, i32)>)],
    vertices: &[u32],
    u: &[[f64; 3]],
    on: &[[Option<i64>; 3]],
    nodes: &[(Key, [f64; 3])],
) -> Option<(Vec<(Plane, usize, usize)>, Vec<(Key, [f64; 3])>)> {
    type Line = (Plane, Plane);
    let n = vertices.len();
    let lies_on = |i: usize, p: Plane| on[i][p.0] == Some(p.1);
    let mut all: Vec<(Key, [f64; 3])> = nodes.to_vec();
    let mut node_of = |key: Key, g: [f64; 3]| -> usize {
        all.iter().position(|x| x.0 == key).unwrap_or_else(|| {
            all.push((key, g));
            all.len() - 1
        })
    };
    // Lines, their first plane the earlier in `planes` (as `demand`'s), with their nodes in order
    // along them.
    let mut lines: Vec<(Line, Vec<usize>)> = Vec::new();
    for (k, &a) in planes.iter().enumerate() {
        for &b in planes[k + 1..].iter().filter(|b| b.0 != a.0) {
            let t = 3 - a.0 - b.0;
            let mut ids: Vec<usize> = (0..n)
                .filter(|&i| lies_on(i, a) && lies_on(i, b))
                .map(|i| node_of(Key::Vertex(vertices[i]), u[i]))
                .collect();
            for &c in planes.iter().filter(|c| c.0 == t) {
                let mut g = [0i64; 3];
                g[a.0] = a.1;
                g[b.0] = b.1;
                g[t] = c.1;
                ids.push(match (0..n).find(|&i| lies_on(i, a) && lies_on(i, b) && lies_on(i, c)) {
                    Some(i) => node_of(Key::Vertex(vertices[i]), u[i]),
                    None => node_of(Key::Corner(g), g.map(|v| v as f64)),
                });
            }
            lines.push(((a, b), ids));
        }
    }
    for ((a, b), ids) in &mut lines {
        let t = 3 - a.0 - b.0;
        ids.sort_by(|&i, &j| all[i].1[t].total_cmp(&all[j].1[t]).then(all[i].0.cmp(&all[j].0)));
        ids.dedup();
    }
    // need_P(v): +1 where a run on P starts at v, −1 where one ends.
    let mut need: HashMap<(Plane, usize), i32, FixedState> = HashMap::default();
    for (line, list) in demand {
        for &(x, d) in list {
            let i = all.iter().position(|nd| nd.0 == Key::Vertex(x))?;
            *need.entry((line.0, i)).or_default() += d;
            *need.entry((line.1, i)).or_default() -= d;
        }
    }
    let need_at = |p: Plane, v: usize| need.get(&(p, v)).copied().unwrap_or(0);
    let sigma = |p: Plane, l: Line| if l.0 == p { 1 } else { -1 };
    // b_L(v) = c0 + c1·t[var], per (line, position on the line).
    let mut at: Vec<Vec<(usize, usize)>> = vec![Vec::new(); all.len()];
    for (l, (_, ids)) in lines.iter().enumerate() {
        for (k, &v) in ids.iter().enumerate() {
            at[v].push((l, k));
        }
    }
    let mut b: Vec<Vec<(i32, i32, usize)>> =
        lines.iter().map(|(_, ids)| vec![(0, 0, 0); ids.len()]).collect();
    let mut vars = 0usize;
    for v in 0..all.len() {
        match at[v][..] {
            [] => {}
            [(l, k)] => {
                let (p, q) = lines[l].0;
                let x = need_at(p, v);
                if need_at(q, v) != -x {
                    return None;
                }
                b[l][k] = (x, 0, 0);
            }
            [(l1, k1), (l2, k2), (l3, k3)] => {
                // t = b_L1; the other two lines through L1's planes follow from those planes'
                // equations; the third plane's must then hold.
                let (a, bb) = lines[l1].0;
                let through = |p: Plane| {
                    [(l2, k2), (l3, k3)].into_iter().find(|&(l, _)| lines[l].0.0 == p || lines[l].0.1 == p)
                };
                let ((la, ka), (lb, kb)) = (through(a)?, through(bb)?);
                if la == lb {
                    return None;
                }
                let var = vars;
                vars += 1;
                b[l1][k1] = (0, 1, var);
                // Plane a: t + σ(a, La)·b_La = need_a; plane bb: −t + σ(bb, Lb)·b_Lb = need_bb.
                let sa = sigma(a, lines[la].0);
                let sb = sigma(bb, lines[lb].0);
                b[la][ka] = (sa * need_at(a, v), -sa, var);
                b[lb][kb] = (sb * need_at(bb, v), sb, var);
                let (ca, cb) = (lines[la].0, lines[lb].0);
                let c = [ca.0, ca.1].into_iter().find(|&p| p != a)?;
                if ![cb.0, cb.1].contains(&c) {
                    return None;
                }
                let (sca, scb) = (sigma(c, ca), sigma(c, cb));
                let holds = |t: i32| {
                    sca * (b[la][ka].0 + b[la][ka].1 * t) + scb * (b[lb][kb].0 + b[lb][kb].1 * t)
                        == need_at(c, v)
                };
                if !holds(0) || !holds(1) {
                    return None;
                }
            }
            _ => return None,
        }
    }
    if vars > MAX_JOINT_CORNERS {
        return None;
    }
    // The least-length choice, each segment crossed at most MAX_CROSSINGS times.
    let mut t = vec![-1i32; vars];
    let mut best: Option<(f64, Vec<i32>)> = None;
    'choices: loop {
        let mut cost = 0.0;
        let mut ok = true;
        for (l, ((a, bb), ids)) in lines.iter().enumerate() {
            let axis = 3 - a.0 - bb.0;
            let mut f = 0;
            for (k, &(c0, c1, var)) in b[l].iter().enumerate() {
                f -= c0 + if c1 != 0 { c1 * t[var] } else { 0 };
                if f.abs() > MAX_CROSSINGS || (k + 1 == ids.len() && f != 0) {
                    ok = false;
                    break;
                }
                if f != 0 {
                    cost += f.abs() as f64 * (all[ids[k + 1]].1[axis] - all[ids[k]].1[axis]).abs();
                }
            }
            if !ok {
                break;
            }
        }
        if ok && best.as_ref().is_none_or(|(c, _)| cost < *c) {
            best = Some((cost, t.clone()));
        }
        // Next choice (odometer over {−1, 0, 1}).
        for x in t.iter_mut() {
            if *x < 1 {
                *x += 1;
                continue 'choices;
            }
            *x = -1;
        }
        break;
    }
    let (_, t) = best?;
    let mut chords = Vec::new();
    for (l, ((p, q), ids)) in lines.iter().enumerate() {
        let mut f = 0;
        for (k, &(c0, c1, var)) in b[l].iter().enumerate().take(ids.len().saturating_sub(1)) {
            f -= c0 + if c1 != 0 { c1 * t[var] } else { 0 };
            let (x, y) = (ids[k], ids[k + 1]);
            match f {
                1.. => chords.extend((0..f).flat_map(|_| [(*p, x, y), (*q, y, x)])),
                ..=-1 => chords.extend((0..-f).flat_map(|_| [(*p, y, x), (*q, x, y)])),
                0 => {}
            }
        }
    }
    let extra = all.split_off(nodes.len());
    Some((chords, extra))
}

/// Splits a loop over the interior face planes its edges lie on into closed loops, one or more
/// per plane, so that each plane is capped on its own.
///
/// A copy cut at several voxel faces that meet in edges and corners (where the output grows
/// along two directions, or where copies of a holey part meet around a voxel) has openings that
/// fold from one face plane onto another: on the CGAL cheese grown by +2 along its first offset,
/// one loop of 753 vertices runs over four planes and around a voxel corner. The missing surface
/// is a polygon on each plane; they meet along the voxel edges where the loop passes from one
/// plane to the next. So:
/// 1. every loop edge is given the plane both its ends lie on (an edge along a voxel edge lies on
///    two: it stays on the plane of the edge before it); an edge with no such plane fails;
/// 2. the edges of one plane make runs, each from the vertex where the loop comes onto the plane
///    to the vertex where it leaves, both on the line (voxel edge) it shares with the
///    neighbouring run's plane;
/// 3. on each plane the runs are closed by chords along those lines: the chain on the union of
///    the plane's lines whose boundary cancels the runs' ends. A line whose ends balance is
///    closed along itself; lines that do not are joined at their crossings (voxel corners, added
///    as vertices where no loop vertex lies). The lines form a graph (nodes: the loop vertices on
///    each line and the corners; edges: consecutive nodes); where it is a forest the chain is
///    unique: the flow through each edge is what the ends beyond it leave unbalanced. An edge
///    may be crossed twice ([`MAX_CROSSINGS`]: two copies' sections touching along a voxel edge,
///    capped as two solids sharing it; on the CGAL cheese grown by +1,+0,+2 such an opening of
///    820 vertices used to stay open);
/// 4. the chords of the two planes through each line must cancel, segment by segment (a run's
///    end on one plane is the next run's start on the other, so they do, unless the lines of
///    several planes close a cycle in space and the planes chose different ways round it).
///    Where step 3 or 4 fails (a graph with a cycle, a tree whose ends do not balance, or planes
///    that chose differently), the chords are chosen over all planes at once ([`joint_chords`]);
/// 5. each plane's runs and chords are traced into closed loops, without spikes ([`drop_spikes`]).
///
/// Both planes through a line split it at the same nodes, so their caps meet there edge to edge
/// without the T-junction pass. This generalises the cap of a mesh slicer (Blender's bisect with
/// fill) from one cutting plane to the faces of a voxel. What fails is left open for the hole
/// fill.
///
/// Returns the parts and the grid coordinates of the corners added, which get the vertex ids
/// `base, base + 1, ...` (and are entered in `corners`); no corner can be added when `base` is
/// `u32::MAX`. `faces[k]` is the triangle along the edge from `vertices[k]` to the next vertex.
/// A loop on one plane is returned as it is.
fn split_over_planes(
    vertices: &[u32],
    faces: &[u32],
    u: &[[f64; 3]],
    out_dims: [usize; 3],
    corners: &mut Corners,
    base: u32,
) -> Option<(Vec<Part>, Vec<[f64; 3]>)> {
    let n = vertices.len();
    let on: Vec<[Option<i64>; 3]> = u
        .iter()
        .map(|p| std::array::from_fn(|d| interior_plane(p[d], out_dims[d]).map(|r| r as i64)))
        .collect();
    let lies_on = |i: usize, p: Plane| on[i][p.0] == Some(p.1);
    let commons: Vec<Vec<Plane>> = (0..n)
        .map(|e| {
            let (a, b) = (&on[e], &on[(e + 1) % n]);
            (0..3).filter_map(|d| a[d].filter(|&r| b[d] == Some(r)).map(|r| (d, r))).collect()
        })
        .collect();
    if commons.iter().any(Vec::is_empty) {
        return None;
    }
    // 1. Each edge's plane, starting from an edge on one plane only.
    let first = (0..n).find(|&e| commons[e].len() == 1)?;
    let mut plane: Vec<Plane> = vec![commons[first][0]; n];
    for k in 1..n {
        let e = (first + k) % n;
        let prev = plane[(e + n - 1) % n];
        plane[e] = if commons[e].contains(&prev) {
            prev
        } else {
            // The plane of the next edge that has only one, when this edge lies on it too.
            let ahead = (1..n).map(|j| &commons[(e + j) % n]).find(|c| c.len() == 1).map(|c| c[0]);
            ahead.filter(|p| commons[e].contains(p)).unwrap_or(commons[e][0])
        };
    }
    let faces_of = |e: usize| faces.get(e).copied().unwrap_or(u32::MAX);
    if plane.iter().all(|&p| p == plane[0]) {
        let part = Part {
            axis: plane[0].0,
            at: plane[0].1,
            vertices: vertices.to_vec(),
            u: u.to_vec(),
            face: faces_of(0),
        };
        return Some((vec![part], Vec::new()));
    }
    // 2. Runs: (plane, first edge, number of edges), in loop order from a change of plane.
    let start = (0..n).find(|&e| plane[e] != plane[(e + n - 1) % n])?;
    let mut runs: Vec<(Plane, usize, usize)> = Vec::new();
    for k in 0..n {
        let e = (start + k) % n;
        match runs.last_mut() {
            Some(r) if r.0 == plane[e] => r.2 += 1,
            _ => runs.push((plane[e], e, 1)),
        }
    }
    let r = runs.len();
    let mut planes: Vec<Plane> = Vec::new();
    for run in &runs {
        if !planes.contains(&run.0) {
            planes.push(run.0);
        }
    }

    // Lines, each a pair of planes (in `planes` order), with their transitions: the loop
    // vertex where a run of one plane ends and a run of the other starts, and the demand on the
    // line's first plane there (the boundary its chords must add: +1 where its run starts, −1
    // where one ends; the second plane's demand is the opposite).
    type Line = (Plane, Plane);
    let order = |p: Plane| planes.iter().position(|&q| q == p).unwrap_or(usize::MAX);
    let mut demand: Vec<(Line, Vec<(u32, i32)>)> = Vec::new();
    for k in 0..r {
        let (a, b) = (runs[k].0, runs[(k + 1) % r].0);
        let x = vertices[(runs[k].1 + runs[k].2) % n];
        let (line, d) = if order(a) < order(b) { ((a, b), -1) } else { ((b, a), 1) };
        let i = match demand.iter().position(|l| l.0 == line) {
            Some(i) => i,
            None => {
                demand.push((line, Vec::new()));
                demand.len() - 1
            }
        };
        match demand[i].1.iter_mut().find(|e| e.0 == x) {
            Some(e) => e.1 += d,
            None => demand[i].1.push((x, d)),
        }
    }
    // Nodes of each line, the same for both its planes: the loop vertices on it, and corners
    // where it crosses another line of one of its planes, when either line does not balance.
    let balanced = |line: Line| {
        demand.iter().find(|l| l.0 == line).is_none_or(|l| l.1.iter().map(|e| e.1).sum::<i32>() == 0)
    };
    let mut nodes: Vec<(Key, [f64; 3])> = Vec::new();
    let mut node_of = |key: Key, g: [f64; 3]| -> usize {
        nodes.iter().position(|x| x.0 == key).unwrap_or_else(|| {
            nodes.push((key, g));
            nodes.len() - 1
        })
    };
    let mut line_nodes: Vec<(Line, Vec<usize>)> = Vec::new();
    for (line, _) in &demand {
        let ids: Vec<usize> = (0..n)
            .filter(|&i| lies_on(i, line.0) && lies_on(i, line.1))
            .map(|i| node_of(Key::Vertex(vertices[i]), u[i]))
            .collect();
        line_nodes.push((*line, ids));
    }
    for &p in &planes {
        let mine: Vec<usize> =
            (0..line_nodes.len()).filter(|&l| line_nodes[l].0.0 == p || line_nodes[l].0.1 == p).collect();
        for (x, &la) in mine.iter().enumerate() {
            for &lb in &mine[x + 1..] {
                let (a, b) = (line_nodes[la].0, line_nodes[lb].0);
                let qa = if a.0 == p { a.1 } else { a.0 };
                let qb = if b.0 == p { b.1 } else { b.0 };
                if qa.0 == qb.0 || (balanced(a) && balanced(b)) {
                    continue; // parallel, or nothing to carry between them
                }
                let mut c = [0i64; 3];
                c[p.0] = p.1;
                c[qa.0] = qa.1;
                c[qb.0] = qb.1;
                let at_vertex = (0..n).find(|&i| lies_on(i, p) && lies_on(i, qa) && lies_on(i, qb));
                let id = match at_vertex {
                    Some(i) => node_of(Key::Vertex(vertices[i]), u[i]),
                    None => node_of(Key::Corner(c), c.map(|v| v as f64)),
                };
                for l in [la, lb] {
                    if !line_nodes[l].1.contains(&id) {
                        line_nodes[l].1.push(id);
                    }
                }
            }
        }
    }
    for (line, ids) in &mut line_nodes {
        let t = 3 - line.0.0 - line.1.0;
        ids.sort_by(|&i, &j| nodes[i].1[t].total_cmp(&nodes[j].1[t]).then(nodes[i].0.cmp(&nodes[j].0)));
        ids.dedup(); // a vertex the loop passes twice (a pinch)
    }

    // 3. Per plane, the chain on its lines: a forest, flows from the leaves up.
    let forest: Option<Vec<(Plane, usize, usize)>> = 'forest: {
        let mut chords: Vec<(Plane, usize, usize)> = Vec::new();
        for &p in &planes {
            let mut uf = UnionFind::new(nodes.len());
            let mut adjacent: Vec<Vec<usize>> = vec![Vec::new(); nodes.len()];
            let mut need = vec![0i32; nodes.len()];
            let mut present = vec![false; nodes.len()];
            for (line, ids) in line_nodes.iter().filter(|(l, _)| l.0 == p || l.1 == p) {
                for w in ids.windows(2) {
                    if !uf.union(w[0], w[1]) {
                        break 'forest None;
                    }
                    adjacent[w[0]].push(w[1]);
                    adjacent[w[1]].push(w[0]);
                }
                for &i in ids {
                    present[i] = true;
                }
                let sign = if line.0 == p { 1 } else { -1 };
                for &(x, d) in demand.iter().find(|l| l.0 == *line).map(|l| &l.1[..]).unwrap_or(&[]) {
                    let Some(i) = nodes.iter().position(|nd| nd.0 == Key::Vertex(x)) else {
                        break 'forest None;
                    };
                    need[i] += sign * d;
                }
            }
            let mut seen = vec![false; nodes.len()];
            for root in (0..nodes.len()).filter(|&i| present[i]) {
                if seen[root] {
                    continue;
                }
                let mut order = vec![(root, usize::MAX)];
                seen[root] = true;
                let mut i = 0;
                while i < order.len() {
                    let (x, _) = order[i];
                    for &y in &adjacent[x] {
                        if !seen[y] {
                            seen[y] = true;
                            order.push((y, x));
                        }
                    }
                    i += 1;
                }
                for &(x, parent) in order.iter().rev() {
                    if parent == usize::MAX {
                        if need[x] != 0 {
                            break 'forest None;
                        }
                        continue;
                    }
                    // ∂(x → parent) = parent − x, so the chord x → parent carries −need(subtree).
                    let f = -need[x];
                    if f.abs() > MAX_CROSSINGS {
                        break 'forest None;
                    }
                    let chord = if f > 0 { (p, x, parent) } else { (p, parent, x) };
                    chords.extend(std::iter::repeat_n(chord, f.unsigned_abs() as usize));
                    need[parent] += need[x];
                }
            }
        }
        // 4. The two planes through a line run their chords there opposite ways.
        let mut net: HashMap<(usize, usize), i32, FixedState> = HashMap::default();
        for &(_, a, b) in &chords {
            *net.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
        }
        if net.values().any(|&v| v != 0) {
            break 'forest None;
        }
        Some(chords)
    };
    // Where the lines close a cycle (a loop wrapping round a voxel: its planes' lines enclose a
    // face), the chain is not unique; it is chosen over all the loop's planes at once.
    let chords = match forest {
        Some(chords) => chords,
        None => {
            let (chords, extra) = joint_chords(&planes, &demand, vertices, u, &on, &nodes)?;
            nodes.extend(extra);
            chords
        }
    };
    // Vertex ids of the corners the chords use.
    let mut added: Vec<([i64; 3], u32)> = Vec::new();
    let mut id_of = vec![u32::MAX; nodes.len()];
    for &(_, a, b) in &chords {
        for i in [a, b] {
            id_of[i] = match nodes[i].0 {
                Key::Vertex(v) => v,
                Key::Corner(c) => match corners.ids.get(&c).or(added.iter().find(|x| x.0 == c).map(|x| &x.1))
                {
                    Some(&id) => id,
                    None if base == u32::MAX => return None,
                    None => {
                        let id = base + added.len() as u32;
                        added.push((c, id));
                        id
                    }
                },
            };
        }
    }

    // 5. Trace each plane's runs and chords into closed loops: items from node to node, with the
    // loop vertices they pass before their end node.
    let mut parts: Vec<Part> = Vec::new();
    for &p in &planes {
        let mut items: Vec<(usize, usize, Vec<usize>, u32)> = Vec::new();
        for run in runs.iter().filter(|run| run.0 == p) {
            let (s, t) = (run.1, (run.1 + run.2) % n);
            let from = nodes.iter().position(|x| x.0 == Key::Vertex(vertices[s]))?;
            let to = nodes.iter().position(|x| x.0 == Key::Vertex(vertices[t]))?;
            items.push((from, to, (0..run.2).map(|k| (s + k) % n).collect(), faces_of(s)));
        }
        let runs_here = items.len();
        items.extend(chords.iter().filter(|c| c.0 == p).map(|&(_, a, b)| (a, b, Vec::new(), u32::MAX)));
        let mut used = vec![false; items.len()];
        for first_item in 0..runs_here {
            if used[first_item] {
                continue;
            }
            let (mut vs, mut gs) = (Vec::new(), Vec::new());
            let face = items[first_item].3;
            let start_node = items[first_item].0;
            let mut it = first_item;
            loop {
                used[it] = true;
                let (from, to, path, _) = &items[it];
                if path.is_empty() {
                    vs.push(id_of[*from]);
                    gs.push(nodes[*from].1);
                } else {
                    vs.extend(path.iter().map(|&i| vertices[i]));
                    gs.extend(path.iter().map(|&i| u[i]));
                }
                if *to == start_node {
                    break;
                }
                let to = *to;
                it = (0..items.len()).find(|&j| !used[j] && items[j].0 == to)?;
            }
            drop_spikes(&mut vs, &mut gs, p.0);
            if vs.len() >= 3 {
                parts.push(Part { axis: p.0, at: p.1, vertices: vs, u: gs, face });
            }
        }
        if used.iter().any(|&x| !x) {
            return None;
        }
    }
    let points = added.iter().map(|&(c, _)| c.map(|v| v as f64)).collect();
    corners.ids.extend(added);
    Some((parts, points))
}

/// Removes the parts of the mesh (connected through vertices) that lie flat on one voxel face
/// plane and are closed: two layers of no thickness over the same region, triangulated
/// differently (a cap over input faces lying on the voxel face it caps, where they meet no
/// other surface; [`remove_cancelling_pairs`] removes such layers where their triangles match).
/// They enclose no volume and show nothing; on the CGAL cheese grown by +1 along all three
/// offsets two such parts of 12 and 14 triangles were the output's only other components.
/// `grid` maps model space to grid coordinates. Returns the number of parts removed.
fn remove_flat_sheets(
    mesh: &mut TriMesh,
    triangle_voxels: &mut Vec<u32>,
    grid: &dyn Fn(Point3) -> [f64; 3],
    flags: &mut Vec<bool>,
) -> usize {
    let mut uf = UnionFind::new(mesh.positions.len());
    for t in &mesh.triangles {
        uf.union(t[0] as usize, t[1] as usize);
        uf.union(t[0] as usize, t[2] as usize);
    }
    // Per part (by root): the planes (grid coordinate per axis) every vertex so far lies on.
    let mut planes: HashMap<usize, [Option<f64>; 3], FixedState> = HashMap::default();
    for t in &mesh.triangles {
        for &v in t {
            let u = grid(mesh.positions[v as usize]);
            let entry = planes.entry(uf.find(v as usize)).or_insert_with(|| u.map(|c| Some(c.round())));
            for d in 0..3 {
                if entry[d].is_some_and(|r| (u[d] - r).abs() > PLANE_EPS) {
                    entry[d] = None;
                }
            }
        }
    }
    let mut flat: HashMap<usize, bool, FixedState> =
        planes.iter().map(|(&root, p)| (root, p.iter().any(Option::is_some))).collect();
    if !flat.values().any(|&f| f) {
        return 0;
    }
    // Closed: every edge of a flat part used as often one way as the other.
    let mut balance: HashMap<(u32, u32), i32, FixedState> = HashMap::default();
    for t in &mesh.triangles {
        if flat[&uf.find(t[0] as usize)] {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *balance.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
            }
        }
    }
    for (&(a, _), &n) in &balance {
        if n != 0 {
            flat.insert(uf.find(a as usize), false);
        }
    }
    let drop: Vec<bool> = mesh.triangles.iter().map(|t| flat[&uf.find(t[0] as usize)]).collect();
    let removed = flat.values().filter(|&&f| f).count();
    drop_triangles(mesh, triangle_voxels, &drop, flags);
    removed
}

/// Removes the pairs of triangles that have the same three vertices and face opposite ways,
/// keeping `triangle_voxels` in step; returns the number of pairs removed.
///
/// Such a pair is a wall of no thickness between two solids that touch face to face, or, after
/// capping, a cap laid over an input face that lies on the voxel face it caps (on the CGAL cheese
/// grown by +1 along all three offsets a copy keeps faces of its pockets that lie on a voxel
/// face, while the solid they bounded is another copy's; the cap over the opening around them
/// covers them facing the other way: 12 such pairs, each making edges of four triangles). Both go,
/// as a mesh Boolean union would remove them: every edge loses one use each way, so a closed,
/// consistently oriented mesh stays so, with fewer non-manifold edges. Where there are more
/// copies one way than the other, the latest triangles of each orientation go (caps come last),
/// and of the copies left, which all run one way, pairs go as well (see below). Returns the
/// pairs removed.
pub(crate) fn remove_cancelling_pairs(
    mesh: &mut TriMesh,
    triangle_voxels: &mut Vec<u32>,
    flags: &mut Vec<bool>,
) -> usize {
    // (sorted vertices, orientation against the sorted order, triangle), sorted.
    let mut keyed: Vec<([u32; 3], bool, u32)> = mesh
        .triangles
        .iter()
        .enumerate()
        .map(|(f, t)| {
            let m = (0..3).min_by_key(|&k| t[k]).unwrap_or(0);
            let (a, b, c) = (t[m], t[(m + 1) % 3], t[(m + 2) % 3]);
            ([a, b.min(c), b.max(c)], b > c, f as u32)
        })
        .collect();
    keyed.sort_unstable();
    let mut drop = vec![false; mesh.triangles.len()];
    let mut pairs = 0;
    for group in keyed.chunk_by(|x, y| x.0 == y.0) {
        let split = group.partition_point(|x| !x.1);
        let (one, other) = group.split_at(split);
        let k = one.len().min(other.len());
        for x in one.iter().rev().take(k).chain(other.iter().rev().take(k)) {
            drop[x.2 as usize] = true;
        }
        pairs += k;
        // What is left runs one way. Two copies the same way are a sheet laid twice, which no
        // closed, consistently oriented surface has (each of its edges would run twice the same
        // way): both go too, leaving one copy of an odd number. (The CGAL cheese turned by 47°
        // and grown +1 along its second offset got two such pairs, slivers of no area laid twice
        // by caps over a T-junction; without them its surface is closed and consistent.)
        let rest = if one.len() > k { &one[..one.len() - k] } else { &other[..other.len() - k] };
        let doubled = rest.len() / 2 * 2;
        for x in rest.iter().rev().take(doubled) {
            drop[x.2 as usize] = true;
        }
        pairs += doubled / 2;
    }
    if pairs > 0 {
        drop_triangles(mesh, triangle_voxels, &drop, flags);
    }
    pairs
}

/// Removes the triangles marked in `drop` (and their entries in `triangle_voxels`), then the
/// vertices no triangle uses.
fn drop_triangles(mesh: &mut TriMesh, triangle_voxels: &mut Vec<u32>, drop: &[bool], flags: &mut Vec<bool>) {
    let mut kept = drop.iter().map(|&d| !d);
    mesh.triangles.retain(|_| kept.next().unwrap_or(true));
    let mut kept = drop.iter().map(|&d| !d);
    triangle_voxels.retain(|_| kept.next().unwrap_or(true));
    let map = mesh.remove_unreferenced_vertices();
    remap_flags(flags, &map, mesh.positions.len());
}

/// Removes the spikes of a closed polygon on the face plane across `axis`: vertices where it
/// turns straight back along its way, as where a run ends with a stretch along a voxel edge line
/// and its chord sets off back over that stretch. A spike has no area, and a cap over it would put
/// a triangle of no area on the line; the stretch gets its twin from the chord of the other plane
/// through the line, which the T-junction pass splits at the spike's vertices.
fn drop_spikes(vertices: &mut Vec<u32>, u: &mut Vec<[f64; 3]>, axis: usize) {
    let (d1, d2) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut i = 0;
    let mut since_change = 0;
    while vertices.len() >= 3 && since_change <= vertices.len() {
        let n = vertices.len();
        let (a, b, c) = (u[(i + n - 1) % n], u[i % n], u[(i + 1) % n]);
        let e = [b[d1] - a[d1], b[d2] - a[d2]];
        let f = [c[d1] - b[d1], c[d2] - b[d2]];
        let (cross, dot) = (e[0] * f[1] - e[1] * f[0], e[0] * f[0] + e[1] * f[1]);
        let scale = e[0].hypot(e[1]) * f[0].hypot(f[1]);
        let same = vertices[(i + n - 1) % n] == vertices[i % n];
        if same || (cross.abs() <= 1e-9 * scale && dot < 0.0) {
            vertices.remove(i % n);
            u.remove(i % n);
            i = (i + n - 2) % (n - 1).max(1);
            since_change = 0;
        } else {
            i = (i + 1) % n;
            since_change += 1;
        }
    }
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

    /// The lattice and grid of unit cells over `[0, dims₀] × [0, dims₁] × [0, dims₂]` (model
    /// units).
    fn cells(dims: [usize; 3]) -> (Lattice, VoxelGrid) {
        let bounds = box_mesh([0.0; 3], dims.map(|n| n as f64), [1, 1, 1]).unwrap();
        let n = crate::retarget::canonical::normalisation_of(&bounds).unwrap();
        let lattice = Lattice::regular(n, n.scale);
        let grid = VoxelGrid::covering(&lattice, &bounds.positions);
        assert_eq!(grid.dims, dims);
        (lattice, grid)
    }

    fn cap(mesh: &mut TriMesh) -> Capped {
        let (lattice, grid) = two_cells();
        let mut voxels = vec![0u32; mesh.triangles.len()];
        let c = cap_openings(mesh, &mut voxels, &grid, [2, 1, 1], &lattice, 1e-6, &mut Vec::new());
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
    fn an_opening_folded_over_a_voxel_edge_is_capped_on_both_faces() {
        // A unit cube without its faces on x = 1 and y = 1, which meet in the voxel edge
        // x = y = 1 of a 2 × 2 × 1 grid: one loop of six vertices on two planes.
        let mut m = box_mesh([0.0; 3], [1.0; 3], [1, 1, 1]).unwrap();
        let p = m.positions.clone();
        let on = |t: &[u32; 3], d: usize| t.iter().all(|&v| (p[v as usize][d] - 1.0).abs() < 1e-12);
        m.triangles.retain(|t| !on(t, 0) && !on(t, 1));
        assert_eq!(mesh_stats(&m).1, 6);
        let (lattice, grid) = cells([2, 2, 1]);
        let mut voxels = vec![0u32; m.triangles.len()];
        let c = cap_openings(&mut m, &mut voxels, &grid, [2, 2, 1], &lattice, 1e-6, &mut Vec::new());
        assert_eq!((c.loops, c.split_loops, c.triangles, c.winding_planes), (2, 1, 4, 0));
        assert_closed_and_oriented(&m);
        assert!((m.signed_volume() - 1.0).abs() < 1e-12, "volume {}", m.signed_volume());
    }

    #[test]
    fn an_opening_around_a_voxel_corner_is_capped_on_its_three_faces() {
        // A unit cube without its faces on x = 1, y = 1 and z = 1, which meet in the corner
        // (1, 1, 1) of a 2 × 2 × 2 grid: one hexagonal loop over three planes. Each plane's run
        // is closed by chords along two voxel edges through the corner, a new vertex.
        let mut m = box_mesh([0.0; 3], [1.0; 3], [1, 1, 1]).unwrap();
        let p = m.positions.clone();
        let on = |t: &[u32; 3], d: usize| t.iter().all(|&v| (p[v as usize][d] - 1.0).abs() < 1e-12);
        m.triangles.retain(|t| !on(t, 0) && !on(t, 1) && !on(t, 2));
        m.remove_unreferenced_vertices();
        assert_eq!((mesh_stats(&m).1, m.positions.len()), (6, 7));
        let (lattice, grid) = cells([2, 2, 2]);
        let mut voxels = vec![0u32; m.triangles.len()];
        let c = cap_openings(&mut m, &mut voxels, &grid, [2, 2, 2], &lattice, 1e-6, &mut Vec::new());
        assert_eq!((c.loops, c.split_loops, c.corners, c.triangles), (3, 1, 1, 6));
        assert_closed_and_oriented(&m);
        assert!((m.signed_volume() - 1.0).abs() < 1e-12, "volume {}", m.signed_volume());
        assert_eq!(m.positions.len(), 8);
        assert!(m.positions.iter().any(|x| x.iter().all(|&c| (c - 1.0).abs() < 1e-12)), "the corner");
    }

    #[test]
    fn a_run_along_a_voxel_edge_leaves_no_spike() {
        // A loop over the planes x = 1 and y = 1 of a 2 × 2 × 1 grid (grid coordinates). Its run
        // on x = 1 reaches the voxel edge x = y = 1 at z = 0.3 and follows it to z = 0.6 before
        // leaving onto y = 1; the chord that closes it runs from there back to z = 0, over that
        // stretch: a spike, on which a cap would put a triangle of no area (as on the CGAL cheese
        // grown by +2 along its first offset, where the stretch's edge ended up in four triangles).
        let u: Vec<[f64; 3]> = vec![
            [1.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.0, 1.0],
            [1.0, 0.5, 1.0],
            [1.0, 0.5, 0.3],
            [1.0, 1.0, 0.3],
            [1.0, 1.0, 0.6],
            [0.0, 1.0, 0.6],
            [0.0, 1.0, 0.0],
        ];
        let vertices: Vec<u32> = (0..u.len() as u32).collect();
        let faces = vec![0u32; u.len()];
        let (parts, corners) =
            split_over_planes(&vertices, &faces, &u, [2, 2, 1], &mut Corners::default(), 100).expect("split");
        assert!(corners.is_empty());
        let mut areas: Vec<(usize, f64)> = Vec::new();
        for part in &parts {
            let (d1, d2) = ((part.axis + 1) % 3, (part.axis + 2) % 3);
            let q: Vec<[f64; 2]> = part.u.iter().map(|p| [p[d1], p[d2]]).collect();
            let n = q.len();
            for i in 0..n {
                let (a, b, c) = (q[(i + n - 1) % n], q[i], q[(i + 1) % n]);
                let (e, f) = ([b[0] - a[0], b[1] - a[1]], [c[0] - b[0], c[1] - b[1]]);
                let turns_back = (e[0] * f[1] - e[1] * f[0]).abs() < 1e-12 && e[0] * f[0] + e[1] * f[1] < 0.0;
                assert!(!turns_back, "a spike at {:?} on the plane across axis {}", part.u[i], part.axis);
            }
            areas.push((part.axis, signed_area(&q).abs()));
        }
        areas.sort_by_key(|a| a.0);
        assert_eq!(areas.len(), 2);
        // x = 1: an L of 1 × 0.3 and 0.5 × 0.7; y = 1: 1 × 0.6.
        assert!((areas[0].1 - 0.65).abs() < 1e-12 && (areas[1].1 - 0.6).abs() < 1e-12, "{areas:?}");
    }

    #[test]
    fn a_loop_round_a_voxel_is_capped_by_half_its_surface() {
        // The hexagon where the plane x + y + z = 4.5 cuts the faces of the voxel [1, 2]³ of a
        // 3 × 3 × 3 grid (one edge on each of its six faces), as the boundary of a fan over it.
        // The lines of its planes run round the voxel and enclose its faces, so the chords are
        // not unique plane by plane (this loop used to be left open for the hole fill); chosen
        // over all planes at once, they take the half of the voxel's surface on one side of the
        // hexagon (corners added where three of its faces meet), which closes the fan into half
        // the voxel: volume 1/2, closed and consistently oriented.
        let ring: [[f64; 3]; 6] = [
            [2.0, 1.5, 1.0],
            [1.5, 2.0, 1.0],
            [1.0, 2.0, 1.5],
            [1.0, 1.5, 2.0],
            [1.5, 1.0, 2.0],
            [2.0, 1.0, 1.5],
        ];
        for reversed in [false, true] {
            let mut positions: Vec<[f64; 3]> = ring.to_vec();
            positions.push([1.5; 3]);
            let triangles: Vec<[u32; 3]> =
                (0..6u32).map(|k| if reversed { [6, (k + 1) % 6, k] } else { [6, k, (k + 1) % 6] }).collect();
            let mut m = TriMesh::new(positions, triangles).unwrap();
            let (lattice, grid) = cells([3, 3, 3]);
            let mut voxels = vec![0u32; m.triangles.len()];
            let c = cap_openings(&mut m, &mut voxels, &grid, [3, 3, 3], &lattice, 1e-6, &mut Vec::new());
            assert_eq!((c.split_loops, c.corners), (1, 4), "{c:?}");
            assert_closed_and_oriented(&m);
            assert!((m.signed_volume().abs() - 0.5).abs() < 1e-12, "volume {}", m.signed_volume());
        }
    }

    #[test]
    fn sections_touching_along_a_voxel_edge_are_capped_as_two_solids_sharing_it() {
        // A loop over the planes x = 1 and y = 1 of a 2 × 2 × 1 grid, one run in each quarter
        // round their line (grid coordinates): on x = 1 below y = 1 from z = 0.1 to 0.6 and above
        // it from 0.3 to 0.9, on y = 1 left of x = 1 from 0.6 to 0.3 and right of it from 0.9 to
        // 0.1 (two copies' sections meeting along a voxel edge, as on the CGAL cheese grown by
        // +1,+0,+2, which kept 820 open edges). The chords of each plane run twice along the line
        // from z = 0.3 to 0.6; the caps are the four rectangles, meeting there in an edge of
        // four triangles, two each way.
        let ring: Vec<[f64; 3]> = vec![
            [1.0, 1.0, 0.1],
            [1.0, 0.5, 0.1],
            [1.0, 0.5, 0.6],
            [1.0, 1.0, 0.6],
            [0.5, 1.0, 0.6],
            [0.5, 1.0, 0.3],
            [1.0, 1.0, 0.3],
            [1.0, 1.5, 0.3],
            [1.0, 1.5, 0.9],
            [1.0, 1.0, 0.9],
            [1.5, 1.0, 0.9],
            [1.5, 1.0, 0.1],
        ];
        let n = ring.len() as u32;
        let mut positions = ring.clone();
        positions.push([1.25, 1.25, 0.5]);
        let triangles: Vec<[u32; 3]> = (0..n).map(|k| [n, k, (k + 1) % n]).collect();
        let mut m = TriMesh::new(positions, triangles).unwrap();
        let fan = m.triangles.len();
        let (lattice, grid) = cells([2, 2, 1]);
        let mut voxels = vec![0u32; m.triangles.len()];
        let c = cap_openings(&mut m, &mut voxels, &grid, [2, 2, 1], &lattice, 1e-6, &mut Vec::new());
        assert_eq!(c.split_loops, 1, "{c:?}");
        assert_closed_and_oriented(&m);
        // Cap area per plane: x = 1 holds 0.5 × 0.5 and 0.5 × 0.6, y = 1 0.5 × 0.3 and 0.5 × 0.8.
        let mut area = [0.0; 2];
        for t in &m.triangles[fan..] {
            let [a, b, c] = t.map(|v| m.positions[v as usize]);
            let axis =
                (0..2).find(|&d| [a, b, c].iter().all(|p| (p[d] - 1.0).abs() < 1e-12)).expect("on a plane");
            let (e, f) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
            let x = [e[1] * f[2] - e[2] * f[1], e[2] * f[0] - e[0] * f[2], e[0] * f[1] - e[1] * f[0]];
            area[axis] += 0.5 * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
        }
        assert!((area[0] - 0.55).abs() < 1e-12 && (area[1] - 0.55).abs() < 1e-12, "{area:?}");
    }

    #[test]
    fn walls_of_no_thickness_are_removed() {
        // Two unit cubes sharing the face x = 1 (its vertices and triangles too): the face is
        // there twice, once each way, between two closed solids; without it they are one closed
        // box of volume 2 whose edges are each used by two triangles.
        let a = box_mesh([0.0; 3], [1.0; 3], [1, 1, 1]).unwrap();
        let b = open_box([1.0, 0.0, 0.0], [2.0, 1.0, 1.0], 1.0);
        let mut m = a.clone();
        let map: Vec<u32> = b
            .positions
            .iter()
            .map(|p| match a.positions.iter().position(|q| q == p) {
                Some(i) => i as u32,
                None => {
                    m.positions.push(*p);
                    (m.positions.len() - 1) as u32
                }
            })
            .collect();
        m.triangles.extend(b.triangles.iter().map(|t| t.map(|v| map[v as usize])));
        let shared: Vec<[u32; 3]> = a
            .triangles
            .iter()
            .filter(|t| t.iter().all(|&v| a.positions[v as usize][0] == 1.0))
            .map(|t| [t[0], t[2], t[1]])
            .collect();
        m.triangles.extend(shared);
        assert_eq!(m.positions.len(), 12);
        assert!(m.edge_stats().non_manifold > 0);
        let on_wall: Vec<u32> = (0..m.triangles.len() as u32)
            .filter(|&f| m.triangles[f as usize].iter().all(|&v| m.positions[v as usize][0] == 1.0))
            .collect();
        assert_eq!(on_wall.len(), 4);
        // Each triangle's voxel is its index here, so the voxels left name the triangles left.
        let mut voxels: Vec<u32> = (0..m.triangles.len() as u32).collect();
        assert_eq!(remove_cancelling_pairs(&mut m, &mut voxels, &mut Vec::new()), 2);
        assert_eq!((m.triangles.len(), voxels.len()), (20, 20));
        assert!(voxels.iter().all(|v| !on_wall.contains(v)) && voxels.is_sorted());
        assert_closed_and_oriented(&m);
        assert_eq!(m.edge_stats().non_manifold, 0);
        assert!((m.signed_volume() - 2.0).abs() < 1e-12, "volume {}", m.signed_volume());
        // Nothing to remove on a closed box.
        let mut c = a.clone();
        let mut v = vec![0u32; c.triangles.len()];
        assert_eq!(remove_cancelling_pairs(&mut c, &mut v, &mut Vec::new()), 0);
        assert_eq!(c.triangles, a.triangles);
    }

    #[test]
    fn flat_closed_sheets_are_removed() {
        // A closed box and, apart from it, a square on the voxel face x = 1 twice, once each way
        // and triangulated along different diagonals: a closed part of no thickness.
        let mut m = open_box([1.0, 0.0, 0.0], [2.0, 1.0, 1.0], 3.0);
        let b = m.positions.len() as u32;
        m.positions.extend([[1.0, 2.0, 2.0], [1.0, 3.0, 2.0], [1.0, 3.0, 3.0], [1.0, 2.0, 3.0]]);
        m.triangles.extend([[b, b + 1, b + 2], [b, b + 2, b + 3], [b, b + 3, b + 1], [b + 1, b + 3, b + 2]]);
        assert_eq!(m.edge_stats().boundary, 0);
        let (lattice, grid_in) = cells([2, 4, 4]);
        let grid = |p: Point3| -> [f64; 3] {
            let c = lattice.canonical(p);
            std::array::from_fn(|d| (c[d] - grid_in.origin[d]) / grid_in.pitch[d])
        };
        let mut voxels: Vec<u32> = (0..m.triangles.len() as u32).collect();
        assert_eq!(remove_flat_sheets(&mut m, &mut voxels, &grid, &mut Vec::new()), 1);
        assert_eq!((m.triangles.len(), m.positions.len()), (12, 8));
        assert_eq!(voxels, (0..12).collect::<Vec<u32>>());
        assert!((m.signed_volume() - 1.0).abs() < 1e-12);
        // The box's face on x = 1 is flat, but the box is not: it stays.
        assert_eq!(remove_flat_sheets(&mut m, &mut voxels, &grid, &mut Vec::new()), 0);
    }

    #[test]
    fn two_openings_touching_at_a_vertex_are_capped_apart() {
        // The face x = 1 of a unit cube as 2 × 2 squares, two diagonal ones removed: two square
        // openings sharing the vertex (1, ½, ½), which two boundary edges leave.
        let mut m = box_mesh([0.0; 3], [1.0; 3], [1, 2, 2]).unwrap();
        let p = m.positions.clone();
        m.triangles.retain(|t| {
            let c = |d: usize| t.iter().map(|&v| p[v as usize][d]).sum::<f64>() / 3.0;
            !(c(0) > 1.0 - 1e-9 && (c(1) < 0.5) == (c(2) < 0.5))
        });
        assert_eq!(mesh_stats(&m).1, 8);
        let c = cap(&mut m);
        assert_eq!((c.loops, c.triangles, c.split_loops, c.winding_planes), (2, 4, 0, 0));
        assert_closed_and_oriented(&m);
        assert!((m.signed_volume() - 1.0).abs() < 1e-12, "volume {}", m.signed_volume());
    }

    #[test]
    fn crossing_openings_are_capped_by_the_winding_rule() {
        // Two boxes on either side of x = 1, each open towards the other, whose openings overlap:
        // their loops cross twice. Each box is closed where the other does not cover its opening;
        // where both are open, the two solids meet and nothing is missing.
        let mut m = open_box([0.0; 3], [1.0; 3], 1.0);
        m.append(&open_box([1.0, 0.5, 0.2], [2.0, 1.5, 1.2], 1.0));
        assert_eq!(mesh_stats(&m).1, 8);
        let c = cap(&mut m);
        assert_eq!((c.loops, c.winding_planes, c.merged), (2, 1, 0));
        assert_closed_and_oriented(&m);
        assert!((m.signed_volume() - 2.0).abs() < 1e-12, "volume {}", m.signed_volume());
        // The caps (the only faces on x = 1) cover each box's opening less the overlap:
        // 2 × (1 − ½ · 0.8).
        let area: f64 = m
            .triangles
            .iter()
            .map(|t| t.map(|v| m.positions[v as usize]))
            .filter(|t| t.iter().all(|x| (x[0] - 1.0).abs() < 1e-12))
            .map(|[a, b, q]| 0.5 * ((b[1] - a[1]) * (q[2] - a[2]) - (q[1] - a[1]) * (b[2] - a[2])).abs())
            .sum();
        assert!((area - 1.2).abs() < 1e-12, "cap area {area}");
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
