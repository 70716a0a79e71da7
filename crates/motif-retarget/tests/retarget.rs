//! Quality tests of offset-based retargeting (thesis 4.2.2, 4.4) and the dense baseline (4.5) on
//! generated shapes with known lattices: cell counts, per-cell residuals against the input's
//! cells, comparisons with the generator's own larger/smaller shapes, errors, and invariances.

use std::collections::HashMap;

use motif_core::geometry::{Point3, add, cross, dot, norm, scale, sub};
use motif_core::mesh::TriMesh;
use motif_core::procedural::{FenceOptions, ShelfOptions, box_mesh, fence, generate, shelf};
use motif_core::progress::NoProgress;
use motif_core::sampling::sample_surface;
use motif_retarget::retarget::{
    BoundaryMode, RetargetError, RetargetMethod, RetargetOptions, RetargetSession, Retargeted,
    TriangleAssignment, orient_offsets, retarget, retarget_dense,
};

// ---------------------------------------------------------------------------------------------
// Geometry helpers
// ---------------------------------------------------------------------------------------------

/// Closest point on triangle `abc` to `p` (Ericson, Real-Time Collision Detection, 5.1.5).
fn closest_on_triangle(p: Point3, a: Point3, b: Point3, c: Point3) -> Point3 {
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return add(a, scale(ab, d1 / (d1 - d3)));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return add(a, scale(ac, d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return add(b, scale(sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    let denom = 1.0 / (va + vb + vc);
    add(a, add(scale(ab, vb * denom), scale(ac, vc * denom)))
}

/// Point-to-surface distances, exact below `cap` and `cap` above it.
struct SurfaceDistance {
    tris: Vec<[Point3; 3]>,
    bin: f64,
    cap: f64,
    bins: HashMap<[i64; 3], Vec<u32>>,
}

impl SurfaceDistance {
    fn new(mesh: &TriMesh, cap: f64, bin: f64) -> Self {
        let tris: Vec<[Point3; 3]> = (0..mesh.triangles.len()).map(|f| mesh.corners(f)).collect();
        let mut bins: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        let key = |x: f64| (x / bin).floor() as i64;
        for (f, t) in tris.iter().enumerate() {
            let lo: [i64; 3] =
                std::array::from_fn(|a| key(t.iter().map(|p| p[a]).fold(f64::INFINITY, f64::min) - cap));
            let hi: [i64; 3] =
                std::array::from_fn(|a| key(t.iter().map(|p| p[a]).fold(f64::NEG_INFINITY, f64::max) + cap));
            for x in lo[0]..=hi[0] {
                for y in lo[1]..=hi[1] {
                    for z in lo[2]..=hi[2] {
                        bins.entry([x, y, z]).or_default().push(f as u32);
                    }
                }
            }
        }
        SurfaceDistance { tris, bin, cap, bins }
    }

    fn distance(&self, p: Point3) -> f64 {
        let k = p.map(|c| (c / self.bin).floor() as i64);
        let mut best = self.cap;
        if let Some(list) = self.bins.get(&k) {
            for &f in list {
                let [a, b, c] = self.tris[f as usize];
                best = best.min(norm(sub(p, closest_on_triangle(p, a, b, c))));
            }
        }
        best
    }
}

/// Surface samples plus all vertices.
fn samples(mesh: &TriMesh, n: usize) -> Vec<Point3> {
    let mut pts = sample_surface(mesh, n, 7).map(|s| s.points).unwrap_or_default();
    pts.extend_from_slice(&mesh.positions);
    pts
}

/// Largest distance from either mesh's samples to the other mesh (capped).
fn two_sided_distance(a: &TriMesh, b: &TriMesh, cap: f64) -> f64 {
    let bin = (a.diagonal() / 40.0).max(cap);
    let (da, db) = (SurfaceDistance::new(a, cap, bin), SurfaceDistance::new(b, cap, bin));
    let ab = samples(a, 20_000).iter().map(|p| db.distance(*p)).fold(0.0, f64::max);
    let ba = samples(b, 20_000).iter().map(|p| da.distance(*p)).fold(0.0, f64::max);
    ab.max(ba)
}

// ---------------------------------------------------------------------------------------------
// Cells of a lattice
// ---------------------------------------------------------------------------------------------

/// The cells of a model's lattice: the parallelepipeds spanned by the pitch vectors, starting at
/// the minimum corner of the model in lattice coordinates (the same grid the retargeting uses).
/// Directions without a pitch vector form a single cell covering the model.
struct CellGrid {
    origin: Point3,
    /// Lattice coordinates of a model point: rows of the inverse of [a b c].
    inv: [[f64; 3]; 3],
    vectors: [Point3; 3],
    counts: [usize; 3],
    num_real: usize,
}

impl CellGrid {
    fn new(mesh: &TriMesh, pitch: &[Point3]) -> CellGrid {
        let mut v: Vec<Point3> = pitch.to_vec();
        let ext = mesh.diagonal() * 4.0;
        // Complete with orthogonal directions long enough to hold the model in one cell.
        let axes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        for ax in axes {
            if v.len() == 3 {
                break;
            }
            let mut d = ax;
            for u in &v {
                let un = scale(*u, 1.0 / norm(*u));
                d = sub(d, scale(un, dot(d, un)));
            }
            if norm(d) > 0.5 {
                v.push(scale(d, ext / norm(d)));
            }
        }
        let (a, b, c) = (v[0], v[1], v[2]);
        let det = dot(a, cross(b, c));
        let inv =
            [scale(cross(b, c), 1.0 / det), scale(cross(c, a), 1.0 / det), scale(cross(a, b), 1.0 / det)];
        let coords = |p: Point3| [dot(inv[0], p), dot(inv[1], p), dot(inv[2], p)];
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &mesh.positions {
            let u = coords(*p);
            for k in 0..3 {
                lo[k] = lo[k].min(u[k]);
                hi[k] = hi[k].max(u[k]);
            }
        }
        let origin = add(add(scale(a, lo[0]), scale(b, lo[1])), scale(c, lo[2]));
        let counts = std::array::from_fn(|k| ((hi[k] - lo[k]) - 0.01).ceil().max(1.0) as usize);
        CellGrid { origin, inv, vectors: [a, b, c], counts, num_real: pitch.len() }
    }

    /// The cell of `p` when `p` is at least `margin` (lattice units) inside it.
    fn cell(&self, p: Point3, margin: f64) -> Option<[usize; 3]> {
        let q = sub(p, self.origin);
        let mut c = [0; 3];
        for k in 0..3 {
            let u = dot(self.inv[k], q);
            let f = u.floor();
            if u - f < margin || f + 1.0 - u < margin || f < 0.0 || f >= self.counts[k] as f64 {
                return None;
            }
            c[k] = f as usize;
        }
        Some(c)
    }

    fn shift(&self, d: [i64; 3]) -> Point3 {
        (0..3).fold([0.0; 3], |t, k| add(t, scale(self.vectors[k], d[k] as f64)))
    }

    fn len(&self) -> usize {
        self.counts.iter().product()
    }
}

/// Per-cell comparison of an output with its input.
struct CellReport {
    cells: usize,
    broken: usize,
    worst_intact: f64,
    /// Best-matching input cell of every output cell (`None` when broken).
    matches: HashMap<[usize; 3], [usize; 3]>,
}

/// Checks every cell of `output` against the input cells it may copy: an output cell on the low
/// (high) end of a lattice direction against the input's low (high) end, an interior cell against
/// the input's interior cells. A cell is intact when, for some candidate, every sample of the
/// output cell lies within `tol` of the input shifted onto it and vice versa.
fn check_cells(input: &TriMesh, output: &TriMesh, pitch: &[Point3], tol: f64) -> CellReport {
    let gin = CellGrid::new(input, pitch);
    // The output's cells are where the input's lattice puts them: the low ends are kept, so an
    // output whose lattice corner moved has broken cells.
    let mut gout = CellGrid::new(output, pitch);
    gout.origin = gin.origin;
    let cap = 4.0 * tol;
    let bin = pitch.iter().map(|v| norm(*v)).fold(f64::INFINITY, f64::min) / 6.0;
    let (din, dout) = (SurfaceDistance::new(input, cap, bin), SurfaceDistance::new(output, cap, bin));
    let group = |g: &CellGrid, m: &TriMesh| {
        let mut by: HashMap<[usize; 3], Vec<Point3>> = HashMap::new();
        for p in samples(m, 60 * m.triangles.len().max(1000)) {
            if let Some(c) = g.cell(p, 1e-4) {
                by.entry(c).or_default().push(p);
            }
        }
        by
    };
    let (pin, pout) = (group(&gin, input), group(&gout, output));
    let empty = Vec::new();
    let mut report = CellReport { cells: gout.len(), broken: 0, worst_intact: 0.0, matches: HashMap::new() };
    for x in 0..gout.len() {
        let xc = [
            x % gout.counts[0],
            (x / gout.counts[0]) % gout.counts[1],
            x / (gout.counts[0] * gout.counts[1]),
        ];
        let cand: Vec<Vec<usize>> = (0..3)
            .map(|k| {
                let (n_in, n_out) = (gin.counts[k], gout.counts[k]);
                if k >= gin.num_real || n_in < 3 {
                    if k >= gin.num_real { vec![xc[k]] } else { (0..n_in).collect() }
                } else if xc[k] == 0 {
                    vec![0]
                } else if xc[k] == n_out - 1 {
                    vec![n_in - 1]
                } else {
                    (1..n_in - 1).collect()
                }
            })
            .collect();
        let mut best = (f64::INFINITY, [0; 3]);
        for &i in &cand[0] {
            for &j in &cand[1] {
                for &k in &cand[2] {
                    let y = [i, j, k];
                    let d = [0, 1, 2].map(|a| y[a] as i64 - xc[a] as i64);
                    let t = gin.shift(d);
                    let r1 = pout
                        .get(&xc)
                        .unwrap_or(&empty)
                        .iter()
                        .map(|p| din.distance(add(*p, t)))
                        .fold(0.0, f64::max);
                    let r2 = pin
                        .get(&y)
                        .unwrap_or(&empty)
                        .iter()
                        .map(|p| dout.distance(sub(*p, t)))
                        .fold(0.0, f64::max);
                    let r = r1.max(r2);
                    if r < best.0 {
                        best = (r, y);
                    }
                }
            }
        }
        if best.0 < tol {
            report.worst_intact = report.worst_intact.max(best.0);
            report.matches.insert(xc, best.1);
        } else {
            report.broken += 1;
        }
    }
    report
}

// ---------------------------------------------------------------------------------------------
// Shapes
// ---------------------------------------------------------------------------------------------

fn run(mesh: &TriMesh, pitch: &[Point3], steps: [i32; 3], method: RetargetMethod) -> Retargeted {
    let options = RetargetOptions { method, ..Default::default() };
    retarget(mesh, pitch, steps, &options, &NoProgress).unwrap_or_else(|e| panic!("retarget {steps:?}: {e}"))
}

fn min_pitch(pitch: &[Point3]) -> f64 {
    pitch.iter().map(|v| norm(*v)).fold(f64::INFINITY, f64::min)
}

/// Components of a shelf by kind (boards, panels, joints), from their extents in lattice units.
fn shelf_parts(mesh: &TriMesh, pitch: &[Point3]) -> [usize; 3] {
    let g = CellGrid::new(mesh, pitch);
    let comp = mesh.components();
    let mut lo: HashMap<u32, [f64; 2]> = HashMap::new();
    let mut hi: HashMap<u32, [f64; 2]> = HashMap::new();
    for (v, p) in mesh.positions.iter().enumerate() {
        let u = [dot(g.inv[0], *p), dot(g.inv[1], *p)];
        let c = comp.vertex_component[v];
        let l = lo.entry(c).or_insert(u);
        *l = [l[0].min(u[0]), l[1].min(u[1])];
        let h = hi.entry(c).or_insert(u);
        *h = [h[0].max(u[0]), h[1].max(u[1])];
    }
    let mut kinds = [0; 3];
    for (c, l) in &lo {
        let h = hi[c];
        let e = [h[0] - l[0], h[1] - l[1]];
        if e[0] > 0.9 {
            kinds[0] += 1; // board: one pitch wide
        } else if e[1] > 0.5 {
            kinds[1] += 1; // panel: most of a pitch high
        } else {
            kinds[2] += 1; // joint block
        }
    }
    kinds
}

/// Expected part counts of a k × m shelf: boards k·m + k, panels k·m + m, joints m + 1.
fn shelf_expected(k: usize, m: usize) -> [usize; 3] {
    [k * m + k, k * m + m, m + 1]
}

// ---------------------------------------------------------------------------------------------
// Tests: the shelf
// ---------------------------------------------------------------------------------------------

#[test]
fn shelf_grows_by_one_column_and_one_row() {
    let ex = generate("shelf", 0).unwrap();
    let pitch = ex.structure.cell_pitch.clone();
    let out = run(&ex.mesh, &pitch, [1, 1, 0], RetargetMethod::Offsets);
    let r = &out.report;
    eprintln!(
        "shelf +1,+1: {} nodes, {} labels, {} edges, energy {:.3}, {} cycles, graph cut {:.2} ms, total {:.0} ms",
        r.nodes, r.labels, r.edges, r.energy, r.cycles, r.graph_cut_ms, r.total_ms
    );
    assert_eq!(
        r.input_voxels,
        [5, 4, 2],
        "4×3 cells plus the closing column and top row; 2 dummy voxels deep"
    );
    assert_eq!(r.output_voxels, [6, 5, 2]);
    assert_eq!((r.nodes, r.labels), (60, 4));
    assert!(r.energy.is_finite());

    // Exactly the expected parts: 5×4 cells.
    assert_eq!(shelf_parts(&out.mesh, &pitch), shelf_expected(5, 4));
    assert_eq!(r.output_components, 54);
    assert_eq!(r.output_boundary_edges, 0);

    // The result is the generator's own 5×4 shelf.
    let reference = shelf(&ShelfOptions { cells: [5, 4], ..Default::default() }).unwrap().mesh;
    let d = two_sided_distance(&out.mesh, &reference, 0.01);
    eprintln!("shelf +1,+1: distance to the generated 5×4 shelf {d:.2e} m");
    assert!(d < 1e-9, "{d}");

    // Every cell is a complete copy of an input cell.
    let tol = 0.01 * min_pitch(&pitch);
    let cells = check_cells(&ex.mesh, &out.mesh, &pitch, tol);
    eprintln!(
        "shelf +1,+1: {} cells checked (5×4 + closing column and row), {} broken, worst residual {:.2e} m (tol {tol:.2e})",
        cells.cells, cells.broken, cells.worst_intact
    );
    assert_eq!(cells.cells, 30);
    assert_eq!(cells.broken, 0);

    motif_core::io::write_mesh(std::path::Path::new("/tmp/retarget-shelf.obj"), &out.mesh).unwrap();
}

#[test]
fn shelf_shrinks_by_one_column_and_one_row() {
    let ex = generate("shelf", 0).unwrap();
    let pitch = ex.structure.cell_pitch.clone();
    let out = run(&ex.mesh, &pitch, [-1, -1, 0], RetargetMethod::Offsets);
    assert_eq!(out.report.output_voxels, [4, 3, 2]);
    assert_eq!(shelf_parts(&out.mesh, &pitch), shelf_expected(3, 2));
    let reference = shelf(&ShelfOptions { cells: [3, 2], ..Default::default() }).unwrap().mesh;
    let d = two_sided_distance(&out.mesh, &reference, 0.01);
    eprintln!("shelf -1,-1: distance to the generated 3×2 shelf {d:.2e} m, labels {}", out.report.labels);
    assert!(d < 1e-9, "{d}");
    let cells = check_cells(&ex.mesh, &out.mesh, &pitch, 0.01 * min_pitch(&pitch));
    assert_eq!(cells.broken, 0);
}

#[test]
fn shelf_grows_by_two_and_shrinks_one_direction() {
    let ex = generate("shelf", 0).unwrap();
    let pitch = ex.structure.cell_pitch.clone();
    for (steps, cells) in
        [([2, 0, 0], [6, 3]), ([0, 2, 0], [4, 5]), ([2, -2, 0], [6, 1]), ([-3, 1, 0], [1, 4])]
    {
        let out = run(&ex.mesh, &pitch, steps, RetargetMethod::Offsets);
        assert_eq!(shelf_parts(&out.mesh, &pitch), shelf_expected(cells[0], cells[1]), "{steps:?}");
        let reference = shelf(&ShelfOptions { cells, ..Default::default() }).unwrap().mesh;
        let d = two_sided_distance(&out.mesh, &reference, 0.01);
        assert!(d < 1e-9, "{steps:?}: {d}");
    }
}

#[test]
fn sheared_shelf_grows_in_canonical_space() {
    let ex = generate("shelf_sheared", 0).unwrap();
    let pitch = ex.structure.cell_pitch.clone();
    let out = run(&ex.mesh, &pitch, [1, 1, 0], RetargetMethod::Offsets);
    let c = out.report.canonical_from_normalised;
    assert!(c[0][1].abs() > 0.1, "a shear must be undone: {c:?}");
    assert_eq!(out.report.output_voxels, [6, 5, 2]);
    assert_eq!(shelf_parts(&out.mesh, &pitch), shelf_expected(5, 4));
    let reference = shelf(&ShelfOptions { cells: [5, 4], ..ShelfOptions::sheared() }).unwrap().mesh;
    let d = two_sided_distance(&out.mesh, &reference, 0.01);
    eprintln!("shelf_sheared +1,+1: distance to the generated sheared 5×4 shelf {d:.2e} m");
    assert!(d < 1e-9, "{d}");
    let cells = check_cells(&ex.mesh, &out.mesh, &pitch, 0.01 * min_pitch(&pitch));
    assert_eq!(cells.broken, 0);

    let small = run(&ex.mesh, &pitch, [-1, -1, 0], RetargetMethod::Offsets);
    let reference = shelf(&ShelfOptions { cells: [3, 2], ..ShelfOptions::sheared() }).unwrap().mesh;
    assert!(two_sided_distance(&small.mesh, &reference, 0.01) < 1e-9);
}

/// The shelf with a back panel made of one box (12 triangles) spanning all cells.
fn shelf_with_back(cells: [usize; 2]) -> TriMesh {
    let ex = shelf(&ShelfOptions { cells, ..Default::default() }).unwrap();
    let bb = ex.mesh.aabb().unwrap();
    let back = box_mesh([bb.min[0], bb.min[1], -0.01], [bb.max[0], bb.max[1], 0.0], [1, 1, 1]).unwrap();
    let mut m = ex.mesh;
    m.append(&back);
    m
}

#[test]
fn cutting_at_voxel_faces_stretches_a_panel_spanning_all_cells() {
    let pitch = shelf(&ShelfOptions::default()).unwrap().structure.cell_pitch;
    let input = shelf_with_back([4, 3]);
    let reference = shelf_with_back([5, 4]);
    let cut = RetargetOptions { assignment: TriangleAssignment::Cut, ..Default::default() };
    let out = retarget(&input, &pitch, [1, 1, 0], &cut, &NoProgress).unwrap();
    let d = two_sided_distance(&out.mesh, &reference, 0.01);
    eprintln!(
        "shelf with one-quad back panel, cut at voxel faces: distance to reference {d:.2e}, {} triangles, {} welded, {} boundary edges",
        out.report.output_triangles, out.report.welded_vertices, out.report.output_boundary_edges
    );
    assert!(d < 1e-9, "{d}");
    assert_eq!(out.report.output_boundary_edges, 0, "the cut panel is welded back together");
    // The back panel is one component again (plus the shelf's 54 parts).
    assert_eq!(out.report.output_components, 55);

    // Centroid assignment copies the panel whole: it cannot cover the grown shelf.
    let centroid = RetargetOptions { assignment: TriangleAssignment::Centroid, ..Default::default() };
    let whole = retarget(&input, &pitch, [1, 1, 0], &centroid, &NoProgress).unwrap();
    let d = two_sided_distance(&whole.mesh, &reference, 0.01);
    eprintln!("the same with centroid assignment: distance to reference {d:.2e}");
    assert!(d > 0.005, "{d}");

    // On the plain shelf both assignments agree.
    let ex = generate("shelf", 0).unwrap();
    let a = retarget(&ex.mesh, &pitch, [1, 1, 0], &cut, &NoProgress).unwrap();
    let b = run(&ex.mesh, &pitch, [1, 1, 0], RetargetMethod::Offsets);
    assert!(two_sided_distance(&a.mesh, &b.mesh, 0.01) < 1e-9);
}

/// The input's per-vertex data follows each copied vertex from where it lies on the input: on a
/// shelf with a one-quad back panel (cut at every voxel face, so most of the panel's output
/// vertices lie inside its two input triangles), a value linear in position comes out, at every
/// vertex with an origin, as the value at the vertex moved back by one of the copies' shifts.
#[test]
fn per_vertex_data_is_carried_from_where_each_copy_lies_on_the_input() {
    use motif_core::point_cloud::{Attribute, AttributeData, PointCloud};
    use motif_retarget::retarget::carry_vertex_data;
    let pitch = shelf(&ShelfOptions::default()).unwrap().structure.cell_pitch;
    let input = shelf_with_back([4, 3]);
    let h = |p: Point3| 3.0 * p[0] - 2.0 * p[1] + 5.0 * p[2] + 1.0;
    let data = PointCloud {
        positions: Vec::new(),
        normals: Some(input.positions.iter().map(|_| [0.0, 0.6, 0.8]).collect()),
        colors: Some((0..input.positions.len()).map(|v| [(v % 256) as u8, 7, 9]).collect()),
        attributes: vec![
            Attribute {
                name: "h".into(),
                data: AttributeData::Float(input.positions.iter().map(|&p| h(p)).collect()),
            },
            Attribute {
                name: "id".into(),
                data: AttributeData::Int((0..input.positions.len() as i64).collect()),
            },
        ],
    };
    let options = RetargetOptions { assignment: TriangleAssignment::Cut, ..Default::default() };
    let session = RetargetSession::new(&input, &pitch, &options, &NoProgress).unwrap();
    let out = session.clone().retarget([1, 1, 0], &NoProgress).unwrap();
    let origins = session.vertex_origins(&out);
    let carried = carry_vertex_data(&data, &input.triangles, &out.mesh, &origins);
    assert_eq!(carried.positions, out.mesh.positions);
    let with_origin = origins.iter().filter(|o| o.is_some()).count();
    eprintln!("{with_origin} of {} output vertices lie on the input", origins.len());
    assert_eq!(with_origin, origins.len(), "a closed shelf grown needs no caps");
    let AttributeData::Float(hs) = &carried.attributes[0].data else { panic!("h is real") };
    let AttributeData::Int(ids) = &carried.attributes[1].data else { panic!("id is an integer") };
    let shifts: Vec<Point3> = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]
        .iter()
        .map(|k| add(scale(pitch[0], k[0]), scale(pitch[1], k[1])))
        .collect();
    let mut interior = 0;
    for (v, o) in origins.iter().enumerate() {
        let o = o.expect("every vertex has an origin");
        let p = out.mesh.positions[v];
        let err = shifts.iter().map(|&t| (hs[v] - h(sub(p, t))).abs()).fold(f64::INFINITY, f64::min);
        assert!(err < 1e-9, "vertex {v} at {p:?}: h {} off by {err}", hs[v]);
        if o.weights.iter().all(|&w| w < 1.0) {
            interior += 1;
        }
        // An integer attribute is one of the origin triangle's corners', and so is the colour
        // of a vertex copied from an input vertex.
        let corners = input.triangles[o.triangle as usize];
        assert!(corners.iter().any(|&c| c as i64 == ids[v]), "vertex {v}: id {}", ids[v]);
        if let Some(k) = o.weights.iter().position(|&w| w == 1.0) {
            assert_eq!(
                carried.colors.as_ref().unwrap()[v],
                data.colors.as_ref().unwrap()[corners[k] as usize]
            );
        }
        let n = carried.normals.as_ref().unwrap()[v];
        assert!((n[0]).abs() < 1e-12 && (n[1] - 0.6).abs() < 1e-12 && (n[2] - 0.8).abs() < 1e-12, "{n:?}");
    }
    assert!(interior > 20, "the back panel's cut vertices: {interior}");
}

// ---------------------------------------------------------------------------------------------
// Tests: fence and facade
// ---------------------------------------------------------------------------------------------

#[test]
fn fence_grows_and_shrinks_along_its_one_offset() {
    let ex = generate("fence", 0).unwrap();
    let pitch = ex.structure.cell_pitch.clone();
    assert_eq!(pitch.len(), 1);
    for (steps, posts) in [(2, 10), (-3, 5)] {
        let out = run(&ex.mesh, &pitch, [steps, 0, 0], RetargetMethod::Offsets);
        let reference = fence(&FenceOptions { posts, ..Default::default() }).unwrap().mesh;
        let d = two_sided_distance(&out.mesh, &reference, 0.01);
        let cells = check_cells(&ex.mesh, &out.mesh, &pitch, 0.01 * min_pitch(&pitch));
        eprintln!(
            "fence {steps:+}: {} nodes, {} labels, {} posts expected, distance to reference {d:.2e}, {} cells / {} broken, {} welded vertices, {} components",
            out.report.nodes,
            out.report.labels,
            posts,
            cells.cells,
            cells.broken,
            out.report.welded_vertices,
            out.report.output_components
        );
        assert!(d < 1e-9, "{d}");
        assert_eq!(cells.broken, 0);
        // Posts plus two rails per bay, each a closed box: the rails' seam copies are welded.
        assert_eq!(out.report.output_components, posts + 2 * (posts - 1));
        assert_eq!(out.report.output_boundary_edges, 0);
    }
}

#[test]
fn facade_grows_by_one_bay_and_one_floor_with_intact_cells() {
    let ex = generate("facade", 0).unwrap();
    let pitch = ex.structure.cell_pitch.clone();
    let out = run(&ex.mesh, &pitch, [1, 1, 0], RetargetMethod::Offsets);
    let r = &out.report;
    assert_eq!(r.input_voxels[..2], [5, 4]);
    assert_eq!(r.output_voxels[..2], [6, 5]);
    let cells = check_cells(&ex.mesh, &out.mesh, &pitch, 0.01 * min_pitch(&pitch));
    // Which input cell each output cell copies; the door is input cell (2, 0).
    let doors = cells.matches.values().filter(|c| **c == [2, 0, 0]).count();
    eprintln!(
        "facade +1,+1: {} nodes, {} labels, energy {:.3}, {} cells / {} broken (worst {:.1e} m), {} door(s), boundary edges {}",
        r.nodes,
        r.labels,
        r.energy,
        cells.cells,
        cells.broken,
        cells.worst_intact,
        doors,
        r.output_boundary_edges
    );
    assert_eq!(cells.cells, 30);
    assert_eq!(cells.broken, 0);
    // The door is kept. Whether it is also repeated depends on the descriptor distances: with
    // SHOT's radius of 0.2 (1.5 m on this 15 m facade) the bays at the facade's ends differ from
    // the inner bays about as much as the door bay does, so eq. 4.4 may prefer a seam through
    // the door column (which repeats it) to one next to an end bay. Reported, not asserted.
    assert!(doors >= 1, "the door must not be lost");
    assert_eq!(r.output_boundary_edges, 0, "the wall is welded watertight across seams");
}

// ---------------------------------------------------------------------------------------------
// Tests: the dense baseline
// ---------------------------------------------------------------------------------------------

#[test]
fn dense_baseline_runs_and_breaks_cells() {
    // (example, steps, expected cell regions of the output: cells plus closing column/row)
    for (name, steps, expected) in [
        ("shelf", [1, 1, 0], 30),
        ("shelf_sheared", [1, 1, 0], 30),
        ("fence", [2, 0, 0], 10),
        ("facade", [1, 1, 0], 30),
    ] {
        let ex = generate(name, 0).unwrap();
        let pitch = ex.structure.cell_pitch.clone();
        let offsets = run(&ex.mesh, &pitch, steps, RetargetMethod::Offsets);
        let dense =
            retarget_dense(&ex.mesh, &pitch, steps, &RetargetOptions::default(), &NoProgress).unwrap();
        let (o, d) = (&offsets.report, &dense.report);
        assert_eq!(d.method, RetargetMethod::Dense);
        assert_eq!(d.pitch, [0.1; 3]);
        assert!(
            d.nodes > 2 * o.nodes && d.labels > o.labels,
            "{name}: {} / {} nodes, {} / {} labels",
            d.nodes,
            o.nodes,
            d.labels,
            o.labels
        );
        assert!(!dense.mesh.triangles.is_empty());
        let tol = 0.01 * min_pitch(&pitch);
        let cells_o = check_cells(&ex.mesh, &offsets.mesh, &pitch, tol);
        let cells_d = check_cells(&ex.mesh, &dense.mesh, &pitch, tol);
        eprintln!(
            "{name} {steps:?} offsets: {:>5} nodes, {:>3} labels, graph cut {:>8.2} ms, total {:>5.0} ms; {} cell regions (expected {expected}), {} broken, {} boundary edges",
            o.nodes,
            o.labels,
            o.graph_cut_ms,
            o.total_ms,
            cells_o.cells,
            cells_o.broken,
            o.output_boundary_edges
        );
        eprintln!(
            "{name} {steps:?} dense:   {:>5} nodes, {:>3} labels, graph cut {:>8.2} ms, total {:>5.0} ms; {} cell regions (expected {expected}), {} broken, {} boundary edges, energy {:.2}",
            d.nodes,
            d.labels,
            d.graph_cut_ms,
            d.total_ms,
            cells_d.cells,
            cells_d.broken,
            d.output_boundary_edges,
            d.energy
        );
        assert_eq!((cells_o.cells, cells_o.broken), (expected, 0), "{name}");
    }
}

// ---------------------------------------------------------------------------------------------
// Tests: errors
// ---------------------------------------------------------------------------------------------

#[test]
fn errors_are_reported() {
    let ex = generate("shelf", 0).unwrap();
    let pitch = ex.structure.cell_pitch.clone();
    let o = RetargetOptions::default();
    let err = |r: Result<Retargeted, RetargetError>| r.err().unwrap_or_else(|| panic!("expected an error"));

    // 5 voxels across (4 cells + the closing column): the ends need two.
    let e = err(retarget(&ex.mesh, &pitch, [-4, 0, 0], &o, &NoProgress));
    assert!(matches!(e, RetargetError::ShrinkBelowOneCell { direction: 0, minimum: 2, .. }), "{e}");
    assert!(e.to_string().contains("steps >= -3"), "{e}");
    assert!(matches!(
        err(retarget(&ex.mesh, &pitch, [0, -9, 0], &o, &NoProgress)),
        RetargetError::ShrinkBelowOneCell { .. }
    ));
    // Without end preservation one voxel may remain, not zero.
    let free = RetargetOptions { boundary: BoundaryMode::Free, ..Default::default() };
    assert!(retarget(&ex.mesh, &pitch, [-4, 0, 0], &free, &NoProgress).is_ok());
    assert!(matches!(
        err(retarget(&ex.mesh, &pitch, [-5, 0, 0], &free, &NoProgress)),
        RetargetError::ShrinkBelowOneCell { .. }
    ));

    let e = err(retarget(&ex.mesh, &pitch, [0, 0, 1], &o, &NoProgress));
    assert!(matches!(e, RetargetError::StepsAlongDummy { direction: 2, .. }), "{e}");

    let e = err(retarget(&ex.mesh, &pitch, [100_000, 100_000, 0], &o, &NoProgress));
    assert!(matches!(e, RetargetError::TooLarge { unit: "voxels", .. }), "{e}");
    assert!(e.to_string().contains("force"), "{e}");
    let e = err(retarget(
        &ex.mesh,
        &pitch,
        [i32::MAX, i32::MAX, 0],
        &RetargetOptions { force: true, ..o.clone() },
        &NoProgress,
    ));
    // Forced, the memory limit still holds, and the message does not offer --force.
    assert!(matches!(e, RetargetError::TooLargeForMemory { .. }), "{e}");
    assert!(e.to_string().contains("does not lift"), "{e}");
    let e = err(retarget(&ex.mesh, &[[1e-9, 0.0, 0.0]], [1, 0, 0], &o, &NoProgress));
    assert!(matches!(e, RetargetError::InvalidOffsets { .. }), "{e}");
    let tiny = [[0.001, 0.0, 0.0], [0.0, 0.001, 0.0], [0.0, 0.0, 0.001]];
    let e = err(retarget(&ex.mesh, &tiny, [1, 0, 0], &o, &NoProgress));
    assert!(matches!(e, RetargetError::TooLarge { .. }), "{e}");

    let points_only = TriMesh { positions: ex.mesh.positions.clone(), triangles: Vec::new() };
    let e = err(retarget(&points_only, &pitch, [1, 0, 0], &o, &NoProgress));
    assert!(matches!(e, RetargetError::NoFaces { .. }), "{e}");
    assert!(e.is_bad_input());

    for bad in [vec![], vec![[0.0; 3]], vec![[1.0, 0.0, 0.0], [1.0, 1e-4, 0.0]], vec![[f64::NAN, 0.0, 0.0]]] {
        let e = err(retarget(&ex.mesh, &bad, [0, 0, 0], &o, &NoProgress));
        assert!(matches!(e, RetargetError::InvalidOffsets { .. }), "{bad:?}: {e}");
    }
    let e = err(retarget(
        &ex.mesh,
        &pitch,
        [1, 0, 0],
        &RetargetOptions { sample_spacing: 0.0, ..o.clone() },
        &NoProgress,
    ));
    assert!(matches!(e, RetargetError::InvalidOption { name: "sample_spacing", .. }), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Tests: session, determinism, invariance
// ---------------------------------------------------------------------------------------------

#[test]
fn options_and_reports_round_trip_through_json() {
    let o = RetargetOptions {
        method: RetargetMethod::Dense,
        assignment: TriangleAssignment::Cut,
        ..Default::default()
    };
    let json = serde_json::to_string(&o).unwrap();
    assert_eq!(serde_json::from_str::<RetargetOptions>(&json).unwrap(), o);
    // Missing fields take their defaults.
    assert_eq!(serde_json::from_str::<RetargetOptions>("{}").unwrap(), RetargetOptions::default());
    let ex = generate("fence", 0).unwrap();
    let out =
        retarget(&ex.mesh, &ex.structure.cell_pitch, [1, 0, 0], &RetargetOptions::default(), &NoProgress)
            .unwrap();
    let v = serde_json::to_value(&out.report).unwrap();
    for key in [
        "nodes",
        "labels",
        "edges",
        "energy",
        "cycles",
        "graph_cut_ms",
        "total_ms",
        "stages",
        "output_triangles",
    ] {
        assert!(v.get(key).is_some(), "{key}");
    }
}

#[test]
fn session_reuses_descriptors_and_is_deterministic() {
    let ex = generate("shelf", 0).unwrap();
    let pitch = ex.structure.cell_pitch.clone();
    let mut s = RetargetSession::new(&ex.mesh, &pitch, &RetargetOptions::default(), &NoProgress).unwrap();
    assert_eq!(s.input_voxels(), [5, 4, 2]);
    let a = s.retarget([1, 1, 0], &NoProgress).unwrap();
    let b = s.retarget([1, 1, 0], &NoProgress).unwrap();
    assert!(a.report.distances_computed > 0);
    assert_eq!(b.report.distances_computed, 0, "the second solve reads the cache");
    assert_eq!(a.mesh, b.mesh);
    assert_eq!(a.voxel_labels, b.voxel_labels);
    let c = retarget(&ex.mesh, &pitch, [1, 1, 0], &RetargetOptions::default(), &NoProgress).unwrap();
    assert_eq!(a.mesh, c.mesh);
    assert_eq!(a.report.energy, c.report.energy);
    // Zero steps reproduce the input exactly.
    let same = s.retarget([0, 0, 0], &NoProgress).unwrap();
    assert_eq!(same.report.labels, 1);
    assert!(two_sided_distance(&same.mesh, &ex.mesh, 0.01) < 1e-12);
    // Cut at voxel faces (the default), boards spanning cells are cut into pieces, but where one
    // copy holds all of a triangle's pieces it is copied whole: with one label everywhere the
    // tessellation is the input's (pieces: 1.7 times its triangles before).
    assert_eq!(same.mesh.triangles.len(), ex.mesh.triangles.len());
    assert_eq!(same.mesh.positions.len(), ex.mesh.positions.len());
    let centroid = RetargetOptions { assignment: TriangleAssignment::Centroid, ..Default::default() };
    let mut s = RetargetSession::new(&ex.mesh, &pitch, &centroid, &NoProgress).unwrap();
    let same = s.retarget([0, 0, 0], &NoProgress).unwrap();
    assert!(two_sided_distance(&same.mesh, &ex.mesh, 0.01) < 1e-12);
    assert_eq!(same.mesh.triangles.len(), ex.mesh.triangles.len());
}

/// Offset detection and retargeting give bit-identical results on 1 and 3 threads (parallel sums
/// are taken in a fixed order; graph-cut moves solved in parallel are used in sequence).
#[test]
fn detection_and_retargeting_do_not_depend_on_the_thread_count() {
    use motif_retarget::offsets::{OffsetOptions, analyze_features, prepare_features};
    let ex = generate("shelf_sheared", 0).unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let oo = OffsetOptions::default();
            let features = prepare_features(&ex.mesh, &oo, &NoProgress).unwrap();
            let analysis = analyze_features(&features, &oo, &NoProgress).unwrap();
            let detected =
                orient_offsets(&analysis.principal.iter().map(|p| p.offset_model).collect::<Vec<_>>());
            let options = RetargetOptions { shot_radius: oo.shot_radius, ..Default::default() };
            let mut session =
                RetargetSession::with_features(&ex.mesh, &features, &detected, &options, &NoProgress)
                    .unwrap();
            (detected, session.retarget([1, 1, 0], &NoProgress).unwrap())
        })
    };
    let (offsets_1, out_1) = run(1);
    let (offsets_3, out_3) = run(3);
    assert_eq!(offsets_1, offsets_3, "principal offsets, bit for bit");
    assert_eq!(out_1.voxel_labels, out_3.voxel_labels);
    assert_eq!(out_1.report.energy.to_bits(), out_3.report.energy.to_bits());
    assert_eq!(out_1.mesh, out_3.mesh, "stitched mesh, bit for bit");
}

#[test]
fn rigid_motion_of_the_input_moves_the_output() {
    let ex = generate("shelf", 0).unwrap();
    let pitch = ex.structure.cell_pitch.clone();
    let base = run(&ex.mesh, &pitch, [1, 1, 0], RetargetMethod::Offsets);
    let r = motif_core::geometry::rotation_about_axis([0.3, 1.0, 0.2], 0.7);
    let m = motif_core::geometry::mat4_from_rt(r, [3.0, -2.0, 0.5]);
    let mut moved = ex.mesh.clone();
    moved.transform(&m);
    let rot = |v: Point3| motif_core::geometry::transform_vector(&m, v);
    let moved_pitch: Vec<Point3> = pitch.iter().map(|v| rot(*v)).collect();
    let out = run(&moved, &moved_pitch, [1, 1, 0], RetargetMethod::Offsets);
    let mut expected = base.mesh.clone();
    expected.transform(&m);
    let d = two_sided_distance(&out.mesh, &expected, 0.01);
    eprintln!("rotated shelf +1,+1: distance to the rotated result {d:.2e}");
    assert!(d < 1e-6, "{d}");
    assert_eq!(shelf_parts(&out.mesh, &moved_pitch), shelf_expected(5, 4));
}

// ---------------------------------------------------------------------------------------------
// Tests: detection → retargeting, as the CLI glues them
// ---------------------------------------------------------------------------------------------

#[test]
fn detected_offsets_retarget_the_shelf_and_reuse_the_features() {
    use motif_retarget::offsets::{OffsetOptions, analyze_features, prepare_features};
    for name in ["shelf", "shelf_sheared", "fence", "facade"] {
        let ex = generate(name, 0).unwrap();
        let known = ex.structure.cell_pitch.clone();
        let oo = OffsetOptions::default();
        let features = prepare_features(&ex.mesh, &oo, &NoProgress).unwrap();
        let analysis = analyze_features(&features, &oo, &NoProgress).unwrap();
        // As the CLI glues them: growth at the +x / +y ends.
        let detected = orient_offsets(&analysis.principal.iter().map(|p| p.offset_model).collect::<Vec<_>>());
        eprintln!("{name}: known {known:?}, detected {detected:?}");
        let options = RetargetOptions { shot_radius: oo.shot_radius, ..Default::default() };
        let mut session =
            RetargetSession::with_features(&ex.mesh, &features, &detected, &options, &NoProgress).unwrap();
        let steps: [i32; 3] = std::array::from_fn(|i| if i < detected.len() { 1 } else { 0 });
        let out = session.retarget(steps, &NoProgress).unwrap();
        let r = &out.report;
        let tol = 0.01 * min_pitch(&known);
        // Cells are checked on the known lattice (the detected one may be ± or a different basis).
        let cells = check_cells(&ex.mesh, &out.mesh, &known, tol);
        eprintln!(
            "{name} +1 per detected offset, features reused: {:?} -> {:?}, {} nodes, {} labels, graph cut {:.2} ms, total {:.1} ms (sampling {:.1}, SHOT {:.1}); {} cells, {} broken (worst {:.1e})",
            r.input_voxels,
            r.output_voxels,
            r.nodes,
            r.labels,
            r.graph_cut_ms,
            r.total_ms,
            r.stages.sampling_ms,
            r.stages.descriptors_ms,
            cells.cells,
            cells.broken,
            cells.worst_intact
        );
        let expected: usize = (0..known.len()).map(|i| r.input_voxels[i] + 1).product();
        assert_eq!(detected.len(), known.len(), "{name}");
        assert_eq!((cells.cells, cells.broken), (expected, 0), "{name}");
        // The inputs are closed; with detected offsets (snapped to the exact vertex translation)
        // every seam welds shut. The sheared shelf had 60–130 open edges before the snap.
        assert_eq!(r.output_boundary_edges, 0, "{name}: open edges along seams");
        assert_eq!(r.stages.sampling_ms, 0.0, "features are reused");
    }
}

#[test]
fn infinite_seams_are_counted_exactly_when_the_energy_is_infinite() {
    // The generated examples with their true pitch stitch seam-consistently (finite energy, no
    // infinite seam); offsets that do not match the cells (0.55 × and 1.3 × the pitch) leave the
    // solver seams where one copy's geometry meets another copy's empty voxel.
    let mut infinite = 0;
    for name in ["shelf", "fence", "facade"] {
        let ex = generate(name, 0).unwrap();
        let pitch = ex.structure.cell_pitch.clone();
        let steps = if pitch.len() >= 2 { [1, 1, 0] } else { [2, 0, 0] };
        let r = run(&ex.mesh, &pitch, steps, RetargetMethod::Offsets).report;
        assert!(
            r.energy.is_finite() && r.infinite_seams == 0,
            "{name}: {} with {} infinite seams",
            r.energy,
            r.infinite_seams
        );
        for factor in [0.55, 1.3] {
            let wrong: Vec<Point3> = pitch.iter().map(|v| scale(*v, factor)).collect();
            let r = run(&ex.mesh, &wrong, steps, RetargetMethod::Offsets).report;
            assert_eq!(
                r.energy.is_infinite(),
                r.infinite_seams > 0,
                "{name} × {factor}: energy {}, {} infinite of {} seams",
                r.energy,
                r.infinite_seams,
                r.seams
            );
            assert!(r.infinite_seams <= r.seams);
            infinite += usize::from(r.infinite_seams > 0);
        }
    }
    assert!(infinite > 0, "some misaligned offsets give infinite seams");
}

/// The shared data folder (`MOTIF_DATA` or `shared/data` above the crate), or `None` after one
/// line saying the test is skipped.
fn shared_data() -> Option<std::path::PathBuf> {
    let dir = motif_core::data::shared_data_dir(std::path::Path::new(env!("CARGO_MANIFEST_DIR")));
    if dir.is_none() {
        println!("skipping: no shared data found (set MOTIF_DATA)");
    }
    dir
}

/// Caps close what seams of infinite cost leave open, and the hole fill what is left (slits where
/// neighbouring copies differ), on the closed grid-like models of the shared data (`MOTIF_DATA`
/// or `shared/data` above the crate); neither changes anything else.
#[test]
fn caps_and_fills_close_the_openings_of_real_models() {
    let Some(dir) = shared_data() else {
        return;
    };
    use motif_retarget::offsets::{OffsetOptions, analyze_offsets};
    // (file, steps per detected principal offset, most open edges left with caps (None: fewer
    // than without), most left with caps and fills). Seed 1, as `motif retarget` uses by default.
    // Walks that end on a chain of edges three triangles share (the heat sink, where a cut fin's
    // foot meets the base along three short edges; 6 open edges were left before chains were
    // followed) are closed along it. The cheese grown along its first offset and along all
    // three: vertices of its pockets lie on cell boundaries to single precision (caps and fill left
    // 136 and 471 open edges, and edges of four triangles, before the cut's tolerance was 10⁻⁶
    // of a cell). The cheese grown along its first two offsets has an opening that folds over a
    // voxel edge, touches another at a vertex and crosses itself; caps close it alone (609 open
    // edges were left before loops were split at voxel edges, paired at pinch vertices and capped
    // by the winding rule), and along the third offset too (one hole of 191 triangles was filled).
    // Openings that run over several voxel face planes and around a voxel corner are split into
    // one loop per plane (before, the cheese +2 along its first offset kept a loop of 753 edges
    // over four planes, +1,+1,+1 left 391 open edges to the fill and the heat sink 324).
    let cases = [
        ("man-made/oscad_example019_fence.stl", [3, 0, 0], Some(0), 0),
        ("man-made/mcad_gridbeam_shelf.stl", [1, 1, 0], Some(10), 0),
        ("man-made/pyb_xavier_heatsink.stl", [0, 2, 0], Some(6), 0),
        ("man-made/cgal_cheese.off", [0, 1, 0], Some(0), 0),
        ("man-made/cgal_cheese.off", [0, 0, 1], Some(0), 0),
        ("man-made/cgal_cheese.off", [1, 1, 0], Some(0), 0),
        ("man-made/cgal_cheese.off", [1, 0, 0], None, 0),
        ("man-made/cgal_cheese.off", [1, 1, 1], Some(0), 0),
        ("man-made/cgal_cheese.off", [2, 0, 0], Some(0), 0),
        ("man-made/cgal_cheese.off", [0, 0, 2], Some(0), 0),
    ];
    for (file, steps, most_capped, most_filled) in cases {
        let mesh = motif_core::io::read_mesh(&dir.join(file)).expect("mesh loads");
        assert_eq!(mesh.edge_stats().boundary, 0, "{file}: the input is closed");
        let a = analyze_offsets(&mesh, &OffsetOptions { seed: 1, ..Default::default() }, &NoProgress)
            .expect("offsets");
        let principal = orient_offsets(&a.principal.iter().map(|p| p.offset_model).collect::<Vec<_>>());
        let run = |cap_openings, fill_holes| {
            let o = RetargetOptions { cap_openings, fill_holes, seed: 1, ..Default::default() };
            retarget(&mesh, &principal, steps, &o, &NoProgress).expect("retarget")
        };
        let (filled, capped, open) = (run(true, true), run(true, false), run(false, false));
        let (f, c, o) = (&filled.report, &capped.report, &open.report);
        println!(
            "{file} {steps:?}: open edges {} -> {} ({} loops capped with {} triangles) -> {} ({} holes \
             filled with {} triangles), infinite seams {}",
            o.output_boundary_edges,
            c.output_boundary_edges,
            c.capped_loops,
            c.cap_triangles,
            f.output_boundary_edges,
            f.filled_holes,
            f.fill_triangles,
            c.infinite_seams
        );
        assert!(o.output_boundary_edges > 0, "{file}: the plain stitching leaves openings");
        let bound = most_capped.unwrap_or(o.output_boundary_edges - 1);
        assert!(c.output_boundary_edges <= bound, "{file}: {} open edges left", c.output_boundary_edges);
        assert!(
            f.output_boundary_edges <= most_filled,
            "{file}: {} open edges left",
            f.output_boundary_edges
        );
        assert!(f.output_boundary_edges <= c.output_boundary_edges);
        for (r, m) in [(f, &filled.mesh), (c, &capped.mesh)] {
            assert_eq!(r.output_boundary_edges, m.edge_stats().boundary);
        }
        assert_eq!((o.capped_loops, o.cap_triangles, o.filled_holes), (0, 0, 0));
        assert_eq!((c.filled_holes, c.fill_triangles), (0, 0));
        // The fill only adds triangles, on the holes' existing vertices.
        assert_eq!(filled.mesh.positions.len(), capped.mesh.positions.len());
        assert_eq!(filled.mesh.triangles.len(), capped.mesh.triangles.len() + f.fill_triangles);
        assert_eq!(filled.mesh.triangles[..capped.mesh.triangles.len()], capped.mesh.triangles[..]);
        assert_eq!(filled.triangle_voxels.len(), filled.mesh.triangles.len());
        // Caps and fill keep the orientation: they add no edge used more times one way than the
        // other, beyond the one an odd number of uses leaves. (Caps on a loop that crosses itself
        // by a sliver used to: 93 such edges on the cheese.)
        let same_way = |m: &motif_core::mesh::TriMesh| m.edge_stats().misoriented;
        let flips = [same_way(&open.mesh), same_way(&capped.mesh), same_way(&filled.mesh)];
        println!("{file}: edges used more often one way (plain, capped, filled) {flips:?}");
        assert!(flips[1] <= flips[0] && flips[2] <= flips[1], "{file}: {flips:?}");
        // An input without non-manifold edges gives none: walls of no thickness (a cap over an
        // input face lying on the voxel face it caps) are removed (8 and 12 such pairs made
        // edges of four triangles on the cheese +1,+1 and +1,+1,+1).
        if mesh.edge_stats().non_manifold == 0 {
            assert_eq!(filled.mesh.edge_stats().non_manifold, 0, "{file}: non-manifold edges");
        }
        // The same copies, labels and energy: capping and filling only add faces.
        for r in [f, c] {
            assert_eq!((r.energy.to_bits(), r.seams), (o.energy.to_bits(), o.seams));
        }
    }
}

/// An open part does not turn capping off for the closed parts beside it: the CGAL cheese (whose
/// growth needs caps) with a single-sided sheet hovering over it comes out with the cheese's
/// copies closed, the sheet's copies open along their rims only, and no edge misoriented. (Before,
/// any open edge in the input left every opening open: the Kiva shelf pod, 2 of its 64 parts open,
/// kept 165 open edges grown by two levels.)
#[test]
fn openings_of_an_open_part_stay_open_while_closed_parts_are_capped() {
    let Some(dir) = shared_data() else {
        return;
    };
    use motif_retarget::offsets::{OffsetOptions, analyze_offsets};
    let cheese = motif_core::io::read_mesh(&dir.join("man-made/cgal_cheese.off")).expect("mesh loads");
    let a = analyze_offsets(&cheese, &OffsetOptions { seed: 1, ..Default::default() }, &NoProgress)
        .expect("offsets");
    let principal = orient_offsets(&a.principal.iter().map(|p| p.offset_model).collect::<Vec<_>>());
    let b = cheese.aabb().expect("non-empty");
    // A sheet over the cheese's top, 8 × 8 squares, facing up, at a height no voxel face holds.
    let z = b.max[2] + 0.013 * b.diagonal();
    let n = 8usize;
    let mut mesh = cheese.clone();
    let base = mesh.positions.len() as u32;
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
            mesh.positions.push([
                b.min[0] + u * (b.max[0] - b.min[0]),
                b.min[1] + v * (b.max[1] - b.min[1]),
                z,
            ]);
        }
    }
    let at = |i: usize, j: usize| base + (j * (n + 1) + i) as u32;
    for j in 0..n {
        for i in 0..n {
            mesh.triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            mesh.triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    let input = mesh.edge_stats();
    assert_eq!((input.boundary, input.misoriented), (4 * n, 0), "only the sheet's rim is open");
    let options = RetargetOptions { seed: 1, ..Default::default() };
    for steps in [[1, 0, 0], [1, 1, 0]] {
        let out = retarget(&mesh, &principal, steps, &options, &NoProgress).expect("retarget");
        // The sheet's copies lie at its height shifted by the copies' translations.
        let mut heights = vec![z];
        for (p, &k) in principal.iter().zip(&steps) {
            heights = heights.iter().flat_map(|&h| (0..=k).map(move |m| h + m as f64 * p[2])).collect();
        }
        let on_sheet = |v: u32| {
            heights.iter().any(|&h| (out.mesh.positions[v as usize][2] - h).abs() < 1e-9 * b.diagonal())
        };
        let keys = motif_core::mesh::edges_by_key(&out.mesh.triangles, out.mesh.positions.len());
        let mut rim = 0;
        for &(_, f, k) in motif_core::mesh::single_use(&keys) {
            let t = out.mesh.triangles[f as usize];
            let (p, q) = (t[k as usize], t[(k as usize + 1) % 3]);
            assert!(
                on_sheet(p) && on_sheet(q),
                "{steps:?}: an open edge off the sheet, at {:?}",
                out.mesh.positions[p as usize]
            );
            rim += 1;
        }
        assert!(rim >= 4 * n, "{steps:?}: the sheet's rim stays open ({rim} edges)");
        assert!(out.report.capped_loops > 0, "{steps:?}: the cheese's openings were capped");
        assert!(out.report.kept_open > 0, "{steps:?}: the sheet's openings were kept");
        assert_eq!(out.mesh.edge_stats().misoriented, 0, "{steps:?}: misoriented edges");
        assert_eq!(out.mesh.degenerate_triangles(), 0, "{steps:?}: degenerate triangles");
    }
    // The Kiva pod: its two open parts are cracks between duplicate vertices, next to closed
    // parts whose openings capping merges and renumbers. The cracks' copies stay open and are not
    // filled with triangles of no area (which happened while the marks of the input's boundary
    // were not carried through capping's renumbering: 2 such triangles).
    let kiva = motif_core::io::read_mesh(&dir.join("man-made/pyb_kiva_shelf_pod.stl")).expect("mesh loads");
    let input = kiva.edge_stats();
    let out = retarget(&kiva, &[[0.0, 0.2479, 0.0]], [2, 0, 0], &options, &NoProgress).expect("retarget");
    let e = out.mesh.edge_stats();
    println!("Kiva +2: {} open edges (input {}), {:?}", e.boundary, input.boundary, out.report.kept_open);
    assert!(out.report.capped_loops > 0 && out.report.kept_open > 0, "{:?}", out.report);
    assert_eq!((e.misoriented, out.mesh.degenerate_triangles()), (0, 0));
    assert!(e.boundary < 165 / 2, "{} open edges (165 when nothing was capped)", e.boundary);
}

/// A bar 10⁴ long and 1 thick grown along a cell of 2500: seams are welded within a thousandth
/// of a cell (2.5) but never across the bar's cross-section, whose corners are 1 apart.
#[test]
fn a_long_thin_bar_keeps_its_cross_section() {
    let bar = box_mesh([0.0; 3], [1e4, 1.0, 1.0], [1, 1, 1]).unwrap();
    let out = retarget(&bar, &[[2500.0, 0.0, 0.0]], [2, 0, 0], &RetargetOptions::default(), &NoProgress)
        .expect("retargeted");
    let bb = out.mesh.aabb().unwrap();
    assert!((bb.max[0] - bb.min[0] - 1.5e4).abs() < 1e-6, "{bb:?}");
    // A box of 15000 × 1 × 1: four long faces and two ends.
    assert!((out.mesh.area() - 60_002.0).abs() < 1e-3, "area {}", out.mesh.area());
    for p in &out.mesh.positions {
        // On the bar's surface (cuts at voxel faces add vertices along its faces' diagonals).
        let side = |c: f64| c.abs() < 1e-9 || (c - 1.0).abs() < 1e-9;
        let inside = |c: f64| (-1e-9..=1.0 + 1e-9).contains(&c);
        assert!((side(p[1]) || side(p[2])) && inside(p[1]) && inside(p[2]), "vertex {p:?} off the bar");
    }
}

/// A turn by 47° about (0.3, −0.7, 0.5) as a 3×3 matrix computed once (so the turned model is
/// the same to the bit on every machine), applied as row · point summed left to right.
const TURN: [[f64; 3]; 3] = [
    [0.720773800136392, -0.4781414942719781, -0.5018623720626045],
    [0.3196617592142547, 0.8717068811437476, -0.371407421927306],
    [0.6150621828181213, 0.10727453016443367, 0.7811470325393344],
];

/// Real closed models turned to an arbitrary attitude stitch into closed, consistently oriented
/// surfaces, as they do axis-aligned. Turned by 47° about (0.3, −0.7, 0.5), the CGAL cheese grown
/// by +1 along its first offset had 13 edges used twice the same way, a cap of 11 triangles laid
/// inside out over two copies' crossing sections; turned by the same rotation rounded otherwise
/// and grown along its second offset, it had two slivers of no area laid twice the same way by
/// caps over a T-junction (4 edges of three triangles, 4 used twice the same way).
#[test]
fn turned_real_models_stitch_into_consistent_closed_surfaces() {
    let Some(dir) = shared_data() else {
        return;
    };
    use motif_retarget::offsets::{OffsetOptions, analyze_offsets};
    // The same turn as Motif computes it (rounded differently, so the cuts fall differently).
    let attitudes = [TURN, motif_core::geometry::rotation_about_axis([0.3, -0.7, 0.5], 0.8137)];
    // (file, steps per principal offset, most non-manifold edges beyond the input's). The cheese
    // grown along all three offsets has two copies' parts touching along one voxel edge line,
    // an edge of four triangles, two each way (as a Boolean union of solids touching along an
    // edge leaves it).
    let cases = [
        ("man-made/cgal_cheese.off", [1, 0, 0], 0),
        ("man-made/cgal_cheese.off", [0, 1, 0], 0),
        ("man-made/cgal_cheese.off#1", [0, 1, 0], 0),
        ("man-made/cgal_cheese.off", [0, 0, 1], 0),
        ("man-made/cgal_cheese.off", [1, 1, 0], 0),
        ("man-made/cgal_cheese.off", [2, 0, 0], 0),
        ("man-made/cgal_cheese.off", [1, 1, 1], 1),
        // The same with the offsets listed by model axis (`axis_order`): alpha-expansion stops at
        // another labelling, whose seams leave one opening of 672 vertices wrapping round a voxel
        // over five planes, which capping left open until its chords were chosen over all planes
        // at once.
        ("man-made/cgal_cheese.off@axis", [1, 1, 1], 1),
        // Two copies' sections touching along a voxel edge (820 open edges before the chords
        // could run twice along a line): closed as two solids sharing that edge.
        ("man-made/cgal_cheese.off", [1, 0, 2], 2),
        ("man-made/cgal_cheese.off", [2, 1, 0], 2),
        ("man-made/oscad_example019_fence.stl", [3, 0, 0], 0),
        ("man-made/mcad_gridbeam_shelf.stl", [1, 1, 0], 0),
        // Turned, the fins' pitch (3.8 mm) is the first principal offset (the second axis-aligned).
        // The input has 15 non-manifold edges (fins on the base), and each copied fin adds some.
        ("man-made/pyb_xavier_heatsink.stl", [2, 0, 0], usize::MAX),
    ];
    // A file name ending in #1 is turned by the second attitude; one ending in @axis gets its
    // principal offsets in the order of the model's axes instead of the order of selection.
    for (file, steps, extra_non_manifold) in cases {
        let (file_turned, by_axis) = match file.strip_suffix("@axis") {
            Some(f) => (f, true),
            None => (file, false),
        };
        let (path, turn) = match file_turned.strip_suffix("#1") {
            Some(path) => (path, attitudes[1]),
            None => (file_turned, attitudes[0]),
        };
        let mut mesh = motif_core::io::read_mesh(&dir.join(path)).expect("mesh loads");
        for p in &mut mesh.positions {
            *p = turn.map(|r| r[0] * p[0] + r[1] * p[1] + r[2] * p[2]);
        }
        let input = mesh.edge_stats();
        assert_eq!((input.boundary, input.misoriented), (0, 0), "{file}: the input is closed and consistent");
        let a = analyze_offsets(&mesh, &OffsetOptions { seed: 1, ..Default::default() }, &NoProgress)
            .expect("offsets");
        let mut offsets: Vec<[f64; 3]> = a.principal.iter().map(|p| p.offset_model).collect();
        if by_axis {
            assert_ne!(a.axis_order, (0..offsets.len()).collect::<Vec<_>>(), "{file}: another order");
            offsets = a.axis_order.iter().map(|&i| offsets[i]).collect();
        }
        let principal = orient_offsets(&offsets);
        let options = RetargetOptions { seed: 1, ..Default::default() };
        let out = retarget(&mesh, &principal, steps, &options, &NoProgress).expect("retarget");
        let e = out.mesh.edge_stats();
        println!(
            "{file} turned, {steps:?}: {} triangles, boundary {}, non-manifold {} (input {}), misoriented {}, \
             {} triangles turned back",
            out.mesh.triangles.len(),
            e.boundary,
            e.non_manifold,
            input.non_manifold,
            e.misoriented,
            out.report.reoriented_triangles
        );
        assert_eq!(e.boundary, 0, "{file} {steps:?}: open edges");
        assert_eq!(e.misoriented, 0, "{file} {steps:?}: edges used more often one way");
        assert!(
            e.non_manifold <= input.non_manifold.saturating_add(extra_non_manifold),
            "{file} {steps:?}: {} non-manifold edges",
            e.non_manifold
        );
        assert!(out.mesh.signed_volume() > mesh.signed_volume(), "{file} {steps:?}: grown outward");
    }
}

/// The CGAL cheese as it is and turned ([`TURN`]), its three principal offsets in each of their
/// six orders, grown by five step vectors: 60 outputs, every one closed with no edge used twice
/// the same way. Before capping chose chords over all of a loop's planes at once and let them run
/// twice along a voxel edge (2026-11-28), 12 of these kept 672–1,075 open edges (openings wrapping
/// round a voxel, or two copies' sections touching along a voxel edge; with the first change
/// alone, 8 kept 820–1,075); alpha-expansion stops at a different labelling in each order, so the
/// orders reach different seams. Where two sections touch along a voxel edge, the output has
/// edges of four triangles, two each way (as a Boolean union of solids touching along an edge
/// has): at most 3 per output.
#[test]
fn the_cheese_grown_with_its_offsets_in_every_order_stitches_closed() {
    let Some(dir) = shared_data() else {
        return;
    };
    use motif_retarget::offsets::{OffsetOptions, analyze_offsets};
    let input = motif_core::io::read_mesh(&dir.join("man-made/cgal_cheese.off")).expect("mesh loads");
    let orders = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let steps = [[1, 1, 1], [1, 1, 0], [0, 1, 1], [2, 1, 0], [1, 0, 2]];
    let mut worst = 0;
    for turned in [false, true] {
        let mut mesh = input.clone();
        if turned {
            for p in &mut mesh.positions {
                *p = TURN.map(|r| r[0] * p[0] + r[1] * p[1] + r[2] * p[2]);
            }
        }
        let a = analyze_offsets(&mesh, &OffsetOptions { seed: 1, ..Default::default() }, &NoProgress)
            .expect("offsets");
        assert_eq!(a.principal.len(), 3);
        let offsets: Vec<Point3> = a.principal.iter().map(|p| p.offset_model).collect();
        for order in orders {
            let principal = orient_offsets(&order.map(|i| offsets[i]));
            for s in steps {
                let options = RetargetOptions { seed: 1, ..Default::default() };
                let out = retarget(&mesh, &principal, s, &options, &NoProgress).expect("retarget");
                let e = out.mesh.edge_stats();
                println!(
                    "cheese{} order {order:?} steps {s:?}: boundary {}, non-manifold {}, misoriented {}",
                    if turned { " turned" } else { "" },
                    e.boundary,
                    e.non_manifold,
                    e.misoriented
                );
                assert_eq!(
                    (e.boundary, e.misoriented),
                    (0, 0),
                    "turned {turned}, order {order:?}, steps {s:?}"
                );
                worst = worst.max(e.non_manifold);
            }
        }
    }
    assert!(worst <= 3, "{worst} edges of more than two triangles in one output");
}
