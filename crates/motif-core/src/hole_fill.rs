//! Filling the holes of a triangle mesh: the boundary is split into simple loops and each loop is
//! closed by a triangulation of small largest dihedral angle, then small area (Liepa, "Filling
//! holes in meshes", SGP 2003, section 3, after Barequet and Sharir 1995).
//!
//! Why here: stitching copies of a model (retargeting, thesis 4.2.2) welds the copies where their
//! geometry continues across a seam; where two neighbouring copies differ (a fin of a heat sink
//! that is not an exact translate of the next one near the base), the seam leaves a narrow slit
//! between two nearly coincident outlines. A closed input should give a closed output (a model
//! for a game engine or a 3D printer), and the minimal triangulation of such a slit is the strip
//! of thin triangles that zips its two sides together. This is the coarse fill of Liepa's method
//! (the one `CGAL::Polygon_mesh_processing::triangulate_hole`, PMP's `SurfaceHoleFilling` and
//! libigl's `fill_holes` start from); the refinement and fairing that follow it there are for
//! large holes in scans and are not done: the holes met here are slits, where new vertices would
//! only add triangles.
//!
//! **Loops.** Every edge used by exactly one triangle is a boundary edge; the hole side runs it
//! the other way round (a triangle that closes the hole uses the edge opposite to the existing
//! triangle, so the fill keeps the mesh's orientation). The boundary half-edges are walked from
//! their start vertex (first where a chain of them starts, then lowest index first); when the
//! walk comes back to a vertex already on its path, the part after that vertex is a simple loop
//! and is cut off. So a boundary that touches itself at a vertex (two holes sharing a corner,
//! which is common along seams) gives two simple loops instead of one loop visiting a vertex
//! twice. A walk can also end at a vertex with no unused outgoing half-edge, where the boundary
//! meets a non-manifold edge: when a chain of at most 8 existing edges leads from there back to
//! the walk's start, each used by an odd number (three or more) of triangles, fewer of them
//! running the walk's way than back, the walk is closed along the chain (the one of fewest edges,
//! found breadth first). Those edges then have as many triangles each way: where a part's face
//! ends on the edges at which two other faces meet (a heat sink's fin cut where its foot, split
//! into three short edges, meets the base), the fill completes the part. Other such walks are
//! left open.
//!
//! **Triangulation.** For a loop `v₀ … v_{n−1}`, the weight of the best triangulation of the
//! sub-polygon `vᵢ … v_k` is `W(i, k) = min_{i<m<k} W(i, m) ⊕ W(m, k) ⊕ w(i, m, k)`, where a
//! weight is the pair (largest dihedral angle, total area) compared lexicographically and ⊕ takes
//! the larger angle and the sum of areas. The angles of triangle `(i, m, k)` are those with its
//! neighbours across `(i, m)` and `(m, k)`: the existing triangle when that side is a boundary
//! edge, the triangle the sub-solution put there otherwise; the last triangle also meets the
//! existing triangle across `(v_{n−1}, v₀)`. The dihedral angle is the angle between the two unit
//! normals (0 where the surface continues flat, π where it folds back). A triangle of zero area
//! has no normal and counts as π: it is used only when nothing else closes the loop. For area
//! alone the recursion finds the least-area triangulation; with the angles it is Liepa's
//! heuristic, since a sub-polygon's triangulation is chosen before the triangle above it, whose
//! angle with it then counts (on random non-planar loops of 4–9 vertices, 13 in 60 miss the
//! smallest largest angle of all triangulations; the tests check both). O(n³) time
//! and O(n²) memory; loops of more than [`HoleFillOptions::max_loop_vertices`] are left open.
//!
//! **Never non-manifold.** A diagonal `(vᵢ, v_k)` that is already an edge of the mesh (two parts
//! of the loop that an existing triangle joins) is not allowed, since it would be used by three
//! triangles; diagonals of earlier fills count as existing edges. A loop with no triangulation
//! left is reported open.

use std::collections::{HashMap, HashSet};

use serde::{Deserialize, Serialize};

use crate::geometry::{Point3, cross, dot, norm, normalize, scale, sub};
use crate::mesh::{TriMesh, edges_by_key, single_use};

/// Options of [`fill_holes`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct HoleFillOptions {
    /// Loops with more vertices are left open: the triangulation takes O(n³) time (15 ms for the
    /// 193-vertex loop of the CGAL cheese grown along its third offset, so about 0.4 s at 600).
    /// Default 600.
    pub max_loop_vertices: usize,
}

impl Default for HoleFillOptions {
    fn default() -> Self {
        HoleFillOptions { max_loop_vertices: 600 }
    }
}

/// What [`fill_holes`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct HoleFillReport {
    /// Simple boundary loops found.
    pub loops: usize,
    /// Loops closed.
    pub filled: usize,
    /// Triangles added.
    pub triangles: usize,
    /// Boundary edges left open: on loops too long or with no triangulation that keeps the mesh
    /// manifold, and on walks that did not close.
    pub open_edges: usize,
    /// Loops left open as asked ([`fill_holes_except`]).
    #[serde(default)]
    pub kept_open: usize,
}

/// The triangles [`fill_holes`] appended, and for each the existing triangle next to its loop.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FilledHoles {
    /// What was done.
    pub report: HoleFillReport,
    /// For each appended triangle (in order, after the mesh's original ones), the index of an
    /// existing triangle along the boundary of the loop it closes (e.g. to give it that
    /// triangle's attributes).
    pub neighbour: Vec<u32>,
}

/// Longest chain of odd edges along which a walk is closed (module documentation).
const MAX_CLOSING_CHAIN: usize = 8;

/// A boundary half-edge on the hole side: `from → to`, the existing triangle `face` uses `to →
/// from`.
#[derive(Debug, Clone, Copy)]
struct HalfEdge {
    from: u32,
    to: u32,
    face: u32,
}

/// Fills the holes of `mesh` (module documentation), appending triangles.
pub fn fill_holes(mesh: &mut TriMesh, options: &HoleFillOptions) -> FilledHoles {
    fill_holes_except(mesh, options, &|_, _| false)
}

/// [`fill_holes`], leaving open every loop with an edge `keep_open(a, b)` holds true for (a
/// retargeted model's loops along the input's own open boundary: a scan's edge stays an edge).
/// Such loops are counted in [`HoleFillReport::kept_open`], not in `open_edges`.
pub fn fill_holes_except(
    mesh: &mut TriMesh,
    options: &HoleFillOptions,
    keep_open: &dyn Fn(u32, u32) -> bool,
) -> FilledHoles {
    let mut out = FilledHoles::default();
    let edges = EdgeTable::new(&mesh.triangles, mesh.positions.len());
    let mut half: Vec<HalfEdge> = single_use(&edges.rows)
        .filter(|&&(key, _, _)| key >> 32 != key & 0xffff_ffff)
        .map(|&(_, f, k)| {
            let t = mesh.triangles[f as usize];
            HalfEdge { from: t[(k as usize + 1) % 3], to: t[k as usize], face: f }
        })
        .collect();
    if half.is_empty() {
        return out;
    }
    half.sort_by_key(|h| (h.from, h.to));
    // Edges the fills add, checked besides the table.
    let mut added: HashSet<u64> = HashSet::new();
    // A walk that ends where a chain of existing edges, each used by an odd number of triangles
    // (three or more), leads back to its start (a part's face ends on edges where two other faces
    // meet) is closed along that chain: with the fill's triangles each edge of it has an even
    // number, as many each way when fewer existing ones run the walk's way than back.
    let mut odd_next: HashMap<u32, Vec<u32>> = HashMap::new();
    for group in edges.rows.chunk_by(|a, b| a.0 == b.0) {
        let (key, n) = (group[0].0, group.len());
        if n >= 3 && n % 2 == 1 {
            let (a, b) = ((key >> 32) as u32, key as u32);
            odd_next.entry(a).or_default().push(b);
            odd_next.entry(b).or_default().push(a);
        }
    }
    // Neighbours in ascending order, so that the search below is deterministic.
    for around in odd_next.values_mut() {
        around.sort_unstable();
    }
    let mut closed_along: HashSet<u64> = HashSet::new();
    let close = |v: u32, s: u32, walked: usize, on_path: &dyn Fn(u32) -> bool| -> Option<Vec<HalfEdge>> {
        // The existing triangle to take the normal from, when the edge a → b may close a walk.
        let closable = |a: u32, b: u32| -> Option<u32> {
            let key = edge_key(a, b);
            let uses = edges.uses(key, &mesh.triangles);
            let forward = uses.iter().filter(|&&(from, _)| from == a).count();
            (2 * forward < uses.len() && !closed_along.contains(&key)).then(|| uses[0].1)
        };
        // Breadth first: the chain of fewest edges.
        let mut came_from: HashMap<u32, (u32, u32)> = HashMap::new();
        let mut frontier = vec![v];
        for _ in 0..MAX_CLOSING_CHAIN {
            let mut next = Vec::new();
            for &a in &frontier {
                for &b in odd_next.get(&a).map_or(&[][..], Vec::as_slice) {
                    if b == v || came_from.contains_key(&b) || (b != s && on_path(b)) {
                        continue;
                    }
                    let Some(face) = closable(a, b) else { continue };
                    came_from.insert(b, (a, face));
                    if b == s {
                        let mut chain = Vec::new();
                        let mut to = s;
                        while to != v {
                            let (from, face) = came_from[&to];
                            chain.push(HalfEdge { from, to, face });
                            to = from;
                        }
                        chain.reverse();
                        // A loop needs three edges; a chain that cannot make one stays unused.
                        if walked + chain.len() < 3 {
                            return None;
                        }
                        for h in &chain {
                            closed_along.insert(edge_key(h.from, h.to));
                        }
                        return Some(chain);
                    }
                    next.push(b);
                }
            }
            frontier = next;
        }
        None
    };
    let (loops, closing) = simple_loops(&half, &mut out.report.open_edges, close);
    half.extend(closing);
    out.report.loops = loops.len();
    let normal_of = |mesh: &TriMesh, f: u32| -> Option<Point3> {
        let [a, b, c] = mesh.corners(f as usize);
        normalize(cross(sub(b, a), sub(c, a)))
    };
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    for l in loops {
        let n = l.len();
        if l.iter().any(|&e| keep_open(half[e].from, half[e].to)) {
            out.report.kept_open += 1;
            continue;
        }
        if n > options.max_loop_vertices {
            out.report.open_edges += n;
            continue;
        }
        let vertices: Vec<u32> = l.iter().map(|&e| half[e].from).collect();
        let points: Vec<Point3> = vertices.iter().map(|&v| mesh.positions[v as usize]).collect();
        let beside: Vec<Option<Point3>> = l.iter().map(|&e| normal_of(mesh, half[e].face)).collect();
        let allowed = |i: usize, k: usize| {
            k == i + 1 || (i == 0 && k == n - 1) || {
                let key = edge_key(vertices[i], vertices[k]);
                !added.contains(&key) && !edges.contains(key)
            }
        };
        triangles.clear();
        if !triangulate(&points, &beside, allowed, &mut triangles) {
            out.report.open_edges += n;
            continue;
        }
        for t in &triangles {
            let t = t.map(|i| vertices[i as usize]);
            for k in 0..3 {
                added.insert(edge_key(t[k], t[(k + 1) % 3]));
            }
            mesh.triangles.push(t);
            out.neighbour.push(half[l[0]].face);
        }
        out.report.filled += 1;
        out.report.triangles += triangles.len();
    }
    out
}

fn edge_key(a: u32, b: u32) -> u64 {
    ((a.min(b) as u64) << 32) | a.max(b) as u64
}

/// The mesh's edges ([`edges_by_key`]), with lookups by edge.
struct EdgeTable {
    rows: Vec<(u64, u32, u8)>,
}

impl EdgeTable {
    fn new(triangles: &[[u32; 3]], num_vertices: usize) -> EdgeTable {
        EdgeTable { rows: edges_by_key(triangles, num_vertices) }
    }

    /// The rows of edge `key`.
    fn of(&self, key: u64) -> &[(u64, u32, u8)] {
        let lo = self.rows.partition_point(|r| r.0 < key);
        let hi = self.rows[lo..].partition_point(|r| r.0 == key);
        &self.rows[lo..lo + hi]
    }

    /// The triangles using the edge `key`, each as (the vertex its side starts from, triangle).
    fn uses(&self, key: u64, triangles: &[[u32; 3]]) -> Vec<(u32, u32)> {
        self.of(key).iter().map(|&(_, f, k)| (triangles[f as usize][k as usize], f)).collect()
    }

    fn contains(&self, key: u64) -> bool {
        !self.of(key).is_empty()
    }
}

/// Splits the boundary half-edges (sorted by `from`) into simple loops, each a list of indices
/// into `half` followed by the returned closing half-edges (index `half.len() + j` is the
/// `j`-th of them). Walks start where a chain of boundary edges starts (a vertex with more
/// boundary edges leaving than arriving), then anywhere. A walk that ends at a vertex `v` with no
/// unused boundary edge left is closed when `close(v, s, edges, on_path)`, `s` its first vertex
/// and `edges` its length, gives a chain of existing edges from `v` to `s` that avoids the walk's
/// other vertices and makes a loop of three edges or more (see [`fill_holes`]); otherwise its
/// edges are added to `open`.
fn simple_loops(
    half: &[HalfEdge],
    open: &mut usize,
    mut close: impl FnMut(u32, u32, usize, &dyn Fn(u32) -> bool) -> Option<Vec<HalfEdge>>,
) -> (Vec<Vec<usize>>, Vec<HalfEdge>) {
    let mut first_out: HashMap<u32, usize> = HashMap::new();
    let mut surplus: HashMap<u32, i64> = HashMap::new();
    for (i, h) in half.iter().enumerate().rev() {
        first_out.insert(h.from, i);
        *surplus.entry(h.from).or_insert(0) += 1;
        *surplus.entry(h.to).or_insert(0) -= 1;
    }
    let mut used = vec![false; half.len()];
    // The next unused half-edge leaving `v`, lowest `to` first.
    let next_from = |v: u32, used: &[bool]| -> Option<usize> {
        let mut i = *first_out.get(&v)?;
        while i < half.len() && half[i].from == v {
            if !used[i] {
                return Some(i);
            }
            i += 1;
        }
        None
    };
    let mut order: Vec<usize> = (0..half.len()).filter(|&i| surplus[&half[i].from] > 0).collect();
    order.extend((0..half.len()).filter(|&i| surplus[&half[i].from] <= 0));
    let mut loops = Vec::new();
    let mut closing: Vec<HalfEdge> = Vec::new();
    let mut path: Vec<usize> = Vec::new();
    let mut on_path: HashMap<u32, usize> = HashMap::new();
    for start in order {
        if used[start] {
            continue;
        }
        path.clear();
        on_path.clear();
        on_path.insert(half[start].from, 0);
        let mut e = start;
        loop {
            used[e] = true;
            path.push(e);
            let v = half[e].to;
            if let Some(&p) = on_path.get(&v) {
                // path[p..] runs from v back to v: a simple loop.
                let cycle: Vec<usize> = path.drain(p..).collect();
                for &c in &cycle[1..] {
                    on_path.remove(&half[c].from);
                }
                loops.push(cycle);
                if path.is_empty() {
                    break;
                }
            } else {
                on_path.insert(v, path.len());
            }
            match next_from(v, &used) {
                Some(n) => e = n,
                None => {
                    let s = half[path[0]].from;
                    let on = |x: u32| on_path.contains_key(&x);
                    match close(v, s, path.len(), &on) {
                        Some(chain) => {
                            let mut cycle = std::mem::take(&mut path);
                            for h in chain {
                                closing.push(h);
                                cycle.push(half.len() + closing.len() - 1);
                            }
                            loops.push(cycle);
                        }
                        _ => *open += path.len(),
                    }
                    break;
                }
            }
        }
    }
    (loops, closing)
}

/// A triangulation's weight: largest dihedral angle (as its [`fold`], which orders angles alike
/// and needs no arccosine), then total area.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Weight {
    bend: f64,
    area: f64,
}

impl Weight {
    const ZERO: Weight = Weight { bend: 0.0, area: 0.0 };
    const NONE: Weight = Weight { bend: f64::INFINITY, area: f64::INFINITY };

    fn better(self, other: Weight) -> bool {
        self.bend < other.bend || (self.bend == other.bend && self.area < other.area)
    }
}

/// 1 − the cosine of the angle between two unit normals: 0 where the surface continues flat, 2
/// where it folds back, and 2 when either is missing (a degenerate triangle).
fn fold(a: Option<Point3>, b: Option<Point3>) -> f64 {
    match (a, b) {
        (Some(a), Some(b)) => 1.0 - dot(a, b).clamp(-1.0, 1.0),
        _ => 2.0,
    }
}

/// Liepa's triangulation of the closed polygon `p` (module documentation): `beside[i]` is the
/// unit normal of the existing triangle across edge `(i, i + 1 mod n)`, `allowed(i, k)` whether
/// `(i, k)`, `i < k`, may be a side of a triangle. Appends triangles as indices into `p`, in the
/// polygon's orientation; false (nothing appended) when no triangulation exists.
fn triangulate(
    p: &[Point3],
    beside: &[Option<Point3>],
    allowed: impl Fn(usize, usize) -> bool,
    out: &mut Vec<[u32; 3]>,
) -> bool {
    triangulate_by(p, beside, allowed, true, out).is_some()
}

/// [`triangulate`], with the dihedral angles counted (`angles`) or not (area only, Barequet and
/// Sharir's criterion, for which the recursion is exact); returns the weight of the
/// triangulation found.
fn triangulate_by(
    p: &[Point3],
    beside: &[Option<Point3>],
    allowed: impl Fn(usize, usize) -> bool,
    angles: bool,
    out: &mut Vec<[u32; 3]>,
) -> Option<Weight> {
    let n = p.len();
    if n < 3 {
        return None;
    }
    let at = |i: usize, k: usize| i * n + k;
    let mut w = vec![Weight::NONE; n * n];
    let mut best = vec![u32::MAX; n * n];
    // The unit normal of the triangle on the far side of (i, k), i < k: the existing one for a
    // polygon side, the chosen one for a diagonal.
    let mut across: Vec<Option<Point3>> = vec![None; n * n];
    for i in 0..n - 1 {
        w[at(i, i + 1)] = Weight::ZERO;
        across[at(i, i + 1)] = beside[i];
    }
    for len in 2..n {
        for i in 0..n - len {
            let k = i + len;
            if !allowed(i, k) {
                continue;
            }
            let mut wk = Weight::NONE;
            let mut mk = u32::MAX;
            let mut nk = None;
            for m in i + 1..k {
                let (a, b) = (w[at(i, m)], w[at(m, k)]);
                if a.bend.is_infinite() || b.bend.is_infinite() {
                    continue;
                }
                let c = cross(sub(p[m], p[i]), sub(p[k], p[i]));
                let twice_area = norm(c);
                let nt = (twice_area > 0.0 && twice_area.is_finite()).then(|| scale(c, 1.0 / twice_area));
                let mut bend = a.bend.max(b.bend);
                if angles {
                    bend = bend.max(fold(nt, across[at(i, m)])).max(fold(nt, across[at(m, k)]));
                    if i == 0 && k == n - 1 {
                        bend = bend.max(fold(nt, beside[n - 1]));
                    }
                }
                let c = Weight { bend, area: a.area + b.area + 0.5 * twice_area };
                if c.better(wk) {
                    wk = c;
                    mk = m as u32;
                    nk = nt;
                }
            }
            w[at(i, k)] = wk;
            best[at(i, k)] = mk;
            across[at(i, k)] = nk;
        }
    }
    if best[at(0, n - 1)] == u32::MAX {
        return None;
    }
    let mut stack = vec![(0usize, n - 1)];
    while let Some((i, k)) = stack.pop() {
        if k <= i + 1 {
            continue;
        }
        let m = best[at(i, k)] as usize;
        out.push([i as u32, m as u32, k as u32]);
        stack.push((i, m));
        stack.push((m, k));
    }
    Some(w[at(0, n - 1)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Every edge used exactly twice, once each way: closed and consistently oriented.
    fn assert_closed_and_oriented(mesh: &TriMesh) {
        let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &mesh.triangles {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        for (&(a, b), &c) in &directed {
            assert_eq!(c, 1, "edge {a}→{b} used {c} times the same way");
            assert_eq!(directed.get(&(b, a)), Some(&1), "edge {a}→{b} has no twin");
        }
    }

    /// A unit cube, 12 triangles, outward.
    fn cube() -> TriMesh {
        let positions =
            (0..8).map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64]).collect();
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let triangles = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
        TriMesh { positions, triangles }
    }

    /// Weight of a whole triangulation (triangles as polygon indices), computed from the finished
    /// triangle set: every interior diagonal between its two triangles, every polygon edge
    /// between its triangle and the existing neighbour.
    fn weight_of(p: &[Point3], beside: &[Option<Point3>], tris: &[[usize; 3]]) -> Weight {
        let n = p.len();
        let normal = |t: &[usize; 3]| normalize(cross(sub(p[t[1]], p[t[0]]), sub(p[t[2]], p[t[0]])));
        let mut by_edge: HashMap<(usize, usize), Vec<usize>> = HashMap::new();
        let mut area = 0.0;
        for (j, t) in tris.iter().enumerate() {
            area += 0.5 * norm(cross(sub(p[t[1]], p[t[0]]), sub(p[t[2]], p[t[0]])));
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                by_edge.entry((a.min(b), a.max(b))).or_default().push(j);
            }
        }
        let mut bend: f64 = 0.0;
        for (&(a, b), ts) in &by_edge {
            let boundary = b == a + 1 || (a == 0 && b == n - 1);
            if boundary {
                let side = if b == a + 1 { a } else { n - 1 };
                bend = bend.max(fold(normal(&tris[ts[0]]), beside[side]));
            } else {
                assert_eq!(ts.len(), 2);
                bend = bend.max(fold(normal(&tris[ts[0]]), normal(&tris[ts[1]])));
            }
        }
        Weight { bend, area }
    }

    /// Every triangulation of the polygon i..=k, by brute force.
    fn all_triangulations(i: usize, k: usize) -> Vec<Vec<[usize; 3]>> {
        if k <= i + 1 {
            return vec![Vec::new()];
        }
        let mut all = Vec::new();
        for m in i + 1..k {
            for a in all_triangulations(i, m) {
                for b in all_triangulations(m, k) {
                    let mut t = a.clone();
                    t.extend(b.iter().copied());
                    t.push([i, m, k]);
                    all.push(t);
                }
            }
        }
        all
    }

    /// A wobbly loop of `n` vertices around the z axis, and tilted neighbour normals.
    fn random_loop(rng: &mut ChaCha8Rng, n: usize) -> (Vec<Point3>, Vec<Option<Point3>>) {
        let p = (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64 + rng.random_range(-0.2..0.2);
                let r = rng.random_range(0.6..1.4);
                [r * a.cos(), r * a.sin(), rng.random_range(-0.5..0.5)]
            })
            .collect();
        let beside = (0..n)
            .map(|_| normalize([rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5), 1.0]))
            .collect();
        (p, beside)
    }

    /// The triangulation of the polygon `p` with every diagonal allowed, with or without the
    /// angles, as polygon indices, and its weight; it has n − 2 triangles.
    fn triangulated(p: &[Point3], beside: &[Option<Point3>], angles: bool) -> (Weight, Vec<[usize; 3]>) {
        let mut got = Vec::new();
        let w = triangulate_by(p, beside, |_, _| true, angles, &mut got).expect("a triangulation");
        assert_eq!(got.len(), p.len() - 2);
        (w, got.iter().map(|t| t.map(|v| v as usize)).collect())
    }

    #[test]
    fn the_least_area_triangulation_is_the_best_of_all() {
        // Area alone is a sum over triangles, so the recursion is exact: check it against every
        // triangulation (Catalan(n − 2) of them).
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for trial in 0..60 {
            let n = 4 + trial % 6;
            let (p, beside) = random_loop(&mut rng, n);
            let (w, got) = triangulated(&p, &beside, false);
            let best = all_triangulations(0, n - 1)
                .iter()
                .map(|t| weight_of(&p, &beside, t).area)
                .fold(f64::INFINITY, f64::min);
            assert!((weight_of(&p, &beside, &got).area - best).abs() < 1e-12, "trial {trial}");
            assert!((w.area - best).abs() < 1e-12, "trial {trial}");
        }
    }

    #[test]
    fn the_angle_weight_is_that_of_the_triangulation_returned() {
        // With dihedral angles the recursion is Liepa's heuristic (a sub-polygon's best
        // triangulation is chosen before the triangle above it), not a global optimum: check the
        // weight it reports against the finished triangulation, recomputed from its triangles,
        // and count how often it misses the best largest angle of all triangulations.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut worse = 0;
        for trial in 0..60 {
            let n = 4 + trial % 6;
            let (p, beside) = random_loop(&mut rng, n);
            let (w, got) = triangulated(&p, &beside, true);
            let real = weight_of(&p, &beside, &got);
            assert!((w.bend - real.bend).abs() < 1e-12, "trial {trial}: {} vs {}", w.bend, real.bend);
            assert!((w.area - real.area).abs() < 1e-12, "trial {trial}");
            let best = all_triangulations(0, n - 1)
                .iter()
                .map(|t| weight_of(&p, &beside, t).bend)
                .fold(f64::INFINITY, f64::min);
            assert!(real.bend >= best - 1e-12);
            if real.bend > best + 1e-9 {
                worse += 1;
            }
        }
        // Measured: 13 of these 60 random, strongly non-planar loops miss the smallest largest
        // angle. The bound only guards against the recursion degrading into an arbitrary choice.
        assert!(worse < 30, "{worse} of 60 loops above the best angle");
    }

    #[test]
    fn a_missing_face_is_closed_flat_and_outwards() {
        let full = cube();
        let mut m = full.clone();
        m.triangles.drain(2..4); // the +z face
        let f = fill_holes(&mut m, &HoleFillOptions::default());
        assert_eq!(
            f.report,
            HoleFillReport { loops: 1, filled: 1, triangles: 2, open_edges: 0, kept_open: 0 }
        );
        assert_eq!(f.neighbour.len(), 2);
        assert_closed_and_oriented(&m);
        assert!((m.area() - full.area()).abs() < 1e-12);
        assert!((m.signed_volume() - 1.0).abs() < 1e-12, "volume {}", m.signed_volume());
    }

    #[test]
    fn two_holes_sharing_a_corner_are_two_loops() {
        // Remove one triangle from each of two faces that meet only at corner 0... the two
        // triangles (0, 2, 3) of -z and (0, 1, 5) of -y share vertex 0 and no edge.
        let mut m = cube();
        let removed: Vec<[u32; 3]> = vec![[0, 2, 3], [0, 1, 5]];
        m.triangles.retain(|t| !removed.contains(t));
        assert_eq!(m.triangles.len(), 10);
        let f = fill_holes(&mut m, &HoleFillOptions::default());
        assert_eq!(f.report.loops, 2);
        assert_eq!(f.report.filled, 2);
        assert_closed_and_oriented(&m);
    }

    #[test]
    fn a_slit_between_two_outlines_is_zipped() {
        // The cube's top face as a fan whose centre is split in two, 0.001 apart (two copies
        // meeting at a seam without welding): the slit 4 → c₁ → 7 → c₂ is the only hole, and
        // closing it restores the top face's area exactly.
        let mut m = cube();
        m.triangles.drain(2..4);
        m.positions.push([0.5, 0.5, 1.0]);
        m.positions.push([0.499, 0.5, 1.0]);
        let (c1, c2) = (8, 9);
        m.triangles.extend([[4, 5, c1], [5, 7, c1], [7, 6, c2], [6, 4, c2]]);
        let open_area = m.area();
        assert!(open_area < 6.0);
        let f = fill_holes(&mut m, &HoleFillOptions::default());
        assert_eq!(
            f.report,
            HoleFillReport { loops: 1, filled: 1, triangles: 2, open_edges: 0, kept_open: 0 }
        );
        assert_closed_and_oriented(&m);
        assert!((m.area() - 6.0).abs() < 1e-12, "area {}", m.area());
        assert!((m.signed_volume() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_walk_ending_on_an_edge_three_triangles_share_is_closed_along_it() {
        // A one-sided fin (one triangle) standing on the cube's edge 0–1, either way round: that
        // edge has three triangles and the fin's other two sides are open. The walk along them
        // ends at one end of 0–1 and is closed along it: the fin gets its back, and edge 0–1
        // four triangles, two each way.
        let c = 8;
        for fin in [[0, 1, c], [1, 0, c]] {
            let mut m = cube();
            m.positions.push([0.5, -0.5, -0.5]);
            m.triangles.push(fin);
            let f = fill_holes(&mut m, &HoleFillOptions::default());
            assert_eq!(
                f.report,
                HoleFillReport { loops: 1, filled: 1, triangles: 1, open_edges: 0, kept_open: 0 }
            );
            let back = [fin[1], fin[0], fin[2]];
            let added = m.triangles[13];
            assert!((0..3).any(|r| [0, 1, 2].map(|k| back[(k + r) % 3]) == added), "{fin:?}: {added:?}");
            assert_eq!(m.edge_stats().boundary, 0);
            let mut net: HashMap<(u32, u32), i64> = HashMap::new();
            for t in &m.triangles {
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    *net.entry((a.min(b), a.max(b))).or_insert(0) += if a < b { 1 } else { -1 };
                }
            }
            assert!(net.values().all(|&n| n == 0), "{fin:?}: every edge used as often each way");
        }
    }

    #[test]
    fn a_walk_ending_on_a_chain_of_shared_edges_is_closed_along_it() {
        // The cube's edge 0–1 bent outwards through a new vertex m (the two faces along it
        // re-triangulated), and a one-sided flap (0, m, 1) or (1, m, 0) standing on the two halves:
        // each half has three triangles and the flap's third side is open. The walk along it ends
        // at one end of the chain and is closed along both halves: the flap gets its back.
        let m = 8;
        for flap in [[0, m, 1], [1, m, 0]] {
            let mut mesh = cube();
            mesh.positions.push([0.5, -0.2, -0.2]);
            // Faces z = 0 ([0, 2, 3, 1]) and y = 0 ([0, 1, 5, 4]) through m.
            mesh.triangles.retain(|t| ![[0, 2, 3], [0, 3, 1], [0, 1, 5], [0, 5, 4]].contains(t));
            mesh.triangles.extend([[0, 2, m], [2, 3, m], [3, 1, m], [0, m, 4], [m, 5, 4], [m, 1, 5]]);
            assert_closed_and_oriented(&mesh);
            let n = mesh.triangles.len();
            mesh.triangles.push(flap);
            let f = fill_holes(&mut mesh, &HoleFillOptions::default());
            assert_eq!(
                f.report,
                HoleFillReport { loops: 1, filled: 1, triangles: 1, open_edges: 0, kept_open: 0 }
            );
            let back = [flap[2], flap[1], flap[0]];
            let added = mesh.triangles[n + 1];
            assert!((0..3).any(|r| [0, 1, 2].map(|k| back[(k + r) % 3]) == added), "{flap:?}: {added:?}");
            let stats = mesh.edge_stats();
            assert_eq!((stats.boundary, stats.misoriented), (0, 0), "{flap:?}");
        }
    }

    #[test]
    fn long_loops_are_left_open_and_counted() {
        let mut m = cube();
        m.triangles.drain(2..4);
        let f = fill_holes(&mut m, &HoleFillOptions { max_loop_vertices: 3 });
        assert_eq!(
            f.report,
            HoleFillReport { loops: 1, filled: 0, triangles: 0, open_edges: 4, kept_open: 0 }
        );
        assert_eq!(m.triangles.len(), 10);
    }

    #[test]
    fn loops_along_a_kept_edge_stay_open() {
        // Two holes in a cube: the one along a kept edge stays open, the other is filled.
        let mut m = cube();
        let first = m.triangles[0];
        m.triangles.drain(2..4);
        m.triangles.remove(0);
        let stats = m.edge_stats();
        assert!(stats.boundary > 0);
        let (a, b) = (first[0], first[1]);
        let edge = |u: u32, v: u32| (u, v) == (a, b) || (u, v) == (b, a);
        let f = fill_holes_except(&mut m, &HoleFillOptions::default(), &edge);
        assert_eq!(f.report.kept_open, 1, "{:?}", f.report);
        assert_eq!(f.report.filled, f.report.loops - 1, "{:?}", f.report);
        assert!(m.edge_stats().boundary >= 3);
        let mut again = m.clone();
        fill_holes(&mut again, &HoleFillOptions::default());
        assert_eq!(again.edge_stats().boundary, 0, "without the kept edge the cube closes");
    }

    #[test]
    fn a_diagonal_that_is_already_an_edge_is_not_used() {
        // A square hole 0-1-2-3 whose diagonal 0-2 is an existing edge elsewhere (a triangle
        // standing on it): the fill must use 1-3.
        let positions: Vec<Point3> =
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.5, 1.0]];
        // Hole side runs 0→1→2→3; the existing triangles use 1→0, 2→1, 3→2, 0→3 on the other side.
        let mut m = TriMesh {
            positions,
            triangles: vec![[1, 0, 4], [2, 1, 4], [3, 2, 4], [0, 3, 4], [0, 2, 4], [2, 0, 4]],
        };
        let f = fill_holes(&mut m, &HoleFillOptions::default());
        assert_eq!(f.report.filled, 1);
        let added = &m.triangles[6..];
        for t in added {
            let has = |a: u32, b: u32| {
                (0..3).any(|k| (t[k], t[(k + 1) % 3]) == (a, b) || (t[k], t[(k + 1) % 3]) == (b, a))
            };
            assert!(!has(0, 2), "diagonal 0-2 reused in {t:?}");
        }
    }
}
