//! Partial symmetries from classes of congruent connected components (thesis 3.2: a symmetry of
//! a part of the surface; regions maximal first in group size, then in area).
//!
//! Connected components are grouped into classes of congruent parts (equal area and principal
//! moments). The union of each class with at least two members is analysed like a whole shape;
//! a group found there that the whole shape does not have is then given the largest region it
//! maps onto itself: the union of every component whose image under each generator lies on the
//! region's surface (iterated to a fixed point). Subgroups (the rotations about the principal
//! axis with the mirror planes through it, then the rotations alone) are tried as well and kept
//! when their region is larger, which yields nested symmetries (thesis Fig. 3.3): for the
//! windmill, the sails alone, and the rotor (sails, hub and shaft) under its 4-fold rotation.

use motif_core::Point3;
use motif_core::geometry::{Mat4, dot};
use motif_core::mesh::TriMesh;
use motif_core::progress::Progress;
use motif_core::sampling::sample_surface;

use super::assemble::AssembledGroup;
use super::bvh::TriangleBvh;
use super::candidates::principal_axes;
use super::element::line_angle;
use super::error::Result;
use super::group::{self, Kind, group_closure, group_contains, kind_of};
use super::residual::Surface;
use super::shape::Shape;
use super::{CandidateReport, PartReport, Scope, SymmetryDetectOptions, Timings};

/// At most this many classes are analysed (the largest by area).
const MAX_CLASSES: usize = 6;
/// Classes smaller than this fraction of the total area are ignored.
const MIN_CLASS_AREA: f64 = 0.01;
/// Samples spread over the whole mesh to test which components a group maps onto the region.
const REGION_SAMPLES: usize = 20_000;
/// Vertices per component (evenly strided) added to its samples for that test.
const COMPONENT_VERTICES: usize = 256;
/// Validation samples of a part.
const PART_SAMPLES: usize = 10_000;
/// Vertices of a part (evenly strided) added to its validation samples.
const PART_VERTICES: usize = 10_000;

/// A partial symmetry: the index of the analysed class it came from, the group, the region.
pub(crate) struct PartResult {
    pub part: usize,
    pub group: AssembledGroup,
    pub faces: Vec<u32>,
}

struct Component {
    faces: Vec<usize>,
    area: f64,
    moments: [f64; 3],
}

/// See the module documentation. `global` are the elements of the global group.
#[allow(clippy::too_many_arguments)]
pub(crate) fn detect(
    mesh: &TriMesh,
    diag: f64,
    whole: &Shape,
    global: &[Mat4],
    o: &SymmetryDetectOptions,
    tol: f64,
    include_approx: bool,
    reports: &mut Vec<CandidateReport>,
    progress: &dyn Progress,
) -> Result<(Vec<PartReport>, Vec<PartResult>)> {
    let comps = components(mesh);
    if comps.len() < 2 {
        return Ok((Vec::new(), Vec::new()));
    }
    let total: f64 = comps.iter().map(|c| c.area).sum();
    // Congruence classes by area and principal moments.
    let mut classes: Vec<Vec<usize>> = Vec::new();
    for (i, c) in comps.iter().enumerate() {
        let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-3 * scale;
        let k = classes.iter().position(|cl| {
            let r = &comps[cl[0]];
            close(r.area, c.area, r.area) && (0..3).all(|k| close(r.moments[k], c.moments[k], r.moments[2]))
        });
        match k {
            Some(k) => classes[k].push(i),
            None => classes.push(vec![i]),
        }
    }
    let mut classes: Vec<(f64, Vec<usize>)> = classes
        .into_iter()
        .filter(|cl| cl.len() >= 2)
        .map(|cl| (cl.iter().map(|&i| comps[i].area).sum::<f64>(), cl))
        .filter(|(a, _)| *a >= MIN_CLASS_AREA * total)
        .collect();
    classes.sort_by(|a, b| b.0.total_cmp(&a.0));
    classes.truncate(MAX_CLASSES);
    if classes.is_empty() {
        return Ok((Vec::new(), Vec::new()));
    }

    // Samples of the whole mesh, bucketed by component, plus each component's vertices.
    let face_comp = face_components(mesh, &comps);
    let samples = sample_surface(mesh, REGION_SAMPLES, o.seed ^ 0x7061_7274)?;
    let mut comp_points: Vec<Vec<Point3>> = vec![Vec::new(); comps.len()];
    for (p, &f) in samples.points.iter().zip(&samples.faces) {
        if let Some(c) = face_comp[f as usize] {
            comp_points[c].push(*p);
        }
    }
    let mut comp_vertices: Vec<Vec<Point3>> = Vec::with_capacity(comps.len());
    for (c, comp) in comps.iter().enumerate() {
        let mut seen = std::collections::HashSet::new();
        let mut vertices = Vec::new();
        for &f in &comp.faces {
            for &v in &mesh.triangles[f] {
                if seen.insert(v) {
                    vertices.push(mesh.positions[v as usize]);
                }
            }
        }
        let stride = vertices.len().div_ceil(COMPONENT_VERTICES).max(1);
        comp_points[c].extend(vertices.iter().copied().step_by(stride));
        comp_vertices.push(vertices);
    }

    // Parts are validated on fewer points than the whole shape (a bonus must not dominate the
    // run time): at most PART_SAMPLES samples and PART_VERTICES vertices.
    let part_options =
        SymmetryDetectOptions { validation_samples: o.validation_samples.min(PART_SAMPLES), ..o.clone() };
    let global_metric = whole.metric();
    let global_merge = super::assemble::merge_distance(whole, tol);
    let mut parts: Vec<PartReport> = Vec::new();
    let mut out: Vec<PartResult> = Vec::new();
    let mut emitted: Vec<(usize, Vec<u32>)> = Vec::new();
    let mut timings = Timings::default();
    for (k, (_, class)) in classes.iter().enumerate() {
        progress.inc(1);
        let faces: Vec<usize> = class.iter().flat_map(|&i| comps[i].faces.iter().copied()).collect();
        let seed = o.seed.wrapping_add(k as u64 + 1);
        let shape = Shape::new(mesh, &faces, diag, &part_options, seed, PART_VERTICES)?;
        let part = parts.len();
        let analysis =
            super::search::analyse(&shape, &part_options, Scope::Part(part), reports, &mut timings, progress);
        parts.push(PartReport { components: class.len(), faces: faces.len(), center: shape.center });
        let Some(g) = super::assemble::assemble(&shape, &analysis, &part_options, tol, include_approx) else {
            continue;
        };
        // Nothing new when the whole shape already has every element.
        if g.elements.iter().all(|m| group_contains(global, m, &global_metric, global_merge)) {
            continue;
        }
        let mut first = true;
        let mut best_region = 0usize;
        for h in subgroups(&g, &shape, tol) {
            // A subgroup the whole shape has already (the shelf's C2v inside a board's D2h)
            // maps the whole mesh onto itself: a region for it would repeat the global group.
            if h.elements.iter().all(|m| group_contains(global, m, &global_metric, global_merge)) {
                continue;
            }
            let Some((region, residual)) =
                region_of(&h, class, &comps, &comp_points, &comp_vertices, whole, mesh, tol)
            else {
                continue;
            };
            let h = AssembledGroup { residual: h.residual.max(residual), ..h };
            let region_faces: Vec<u32> =
                region.iter().flat_map(|&c| comps[c].faces.iter().map(|&f| f as u32)).collect();
            // Keep the largest group, then each subgroup with a strictly larger region.
            if !first && region_faces.len() <= best_region {
                continue;
            }
            let order = h.structure.order;
            let mut sorted = region_faces.clone();
            sorted.sort_unstable();
            if emitted.iter().any(|(o, r)| *o == order && *r == sorted) {
                first = false;
                best_region = best_region.max(region_faces.len());
                continue;
            }
            emitted.push((order, sorted));
            best_region = region_faces.len();
            first = false;
            out.push(PartResult { part, group: h, faces: region_faces });
        }
    }
    Ok((parts, out))
}

/// Connected components (through shared vertices) of the faces with positive area.
fn components(mesh: &TriMesh) -> Vec<Component> {
    let labels = mesh.components().vertex_component;
    let mut by_label: std::collections::HashMap<u32, Vec<usize>> = std::collections::HashMap::new();
    for f in 0..mesh.num_triangles() {
        if motif_core::geometry::norm(mesh.face_cross(f)) > 0.0 {
            by_label.entry(labels[mesh.triangles[f][0] as usize]).or_default().push(f);
        }
    }
    let mut list: Vec<(u32, Vec<usize>)> = by_label.into_iter().collect();
    list.sort_by_key(|(l, _)| *l);
    list.into_iter()
        .filter_map(|(_, faces)| {
            let tris: Vec<[Point3; 3]> = faces.iter().map(|&f| mesh.corners(f)).collect();
            let pa = principal_axes(&tris)?;
            let area = faces.iter().map(|&f| 0.5 * motif_core::geometry::norm(mesh.face_cross(f))).sum();
            Some(Component { faces, area, moments: pa.moments })
        })
        .collect()
}

fn face_components(mesh: &TriMesh, comps: &[Component]) -> Vec<Option<usize>> {
    let mut fc = vec![None; mesh.num_triangles()];
    for (c, comp) in comps.iter().enumerate() {
        for &f in &comp.faces {
            fc[f] = Some(c);
        }
    }
    fc
}

/// The group and its subgroups about its principal axis: `Cnv`-like (rotations about the axis
/// and mirror planes containing it), then `Cn` (the rotations), largest first, without repeats.
fn subgroups(g: &AssembledGroup, shape: &Shape, tol: f64) -> Vec<AssembledGroup> {
    let metric = shape.metric();
    let merge = super::assemble::merge_distance(shape, tol);
    let mut out = vec![AssembledGroup {
        name: g.name.clone(),
        elements: g.elements.clone(),
        generators: g.generators.clone(),
        structure: g.structure.clone(),
        residual: g.residual,
        center: g.center,
        max_order: g.max_order,
    }];
    let Some(&(a, _)) = g.structure.rotation_axes.first() else { return out };
    let about = |m: &Mat4, mirrors: bool| match kind_of(m) {
        Kind::Identity => true,
        Kind::Rotation { axis, .. } => line_angle(axis, a) < 0.02,
        Kind::Mirror { normal } => mirrors && dot(normal, a).abs() < 0.02,
        _ => false,
    };
    for mirrors in [true, false] {
        let elements: Vec<Mat4> = g.elements.iter().copied().filter(|m| about(m, mirrors)).collect();
        if elements.len() <= 1 || out.iter().any(|h| h.elements.len() == elements.len()) {
            continue;
        }
        let structure = group::classify(&elements);
        let generators = group::choose_generators(&elements, &structure, &metric, merge);
        // A sanity check that the filtered set is closed.
        if group_closure(&generators, &metric, merge, elements.len())
            .is_none_or(|c| c.len() != elements.len())
        {
            continue;
        }
        let name = super::assemble::group_name(&structure, &generators, g.center);
        out.push(AssembledGroup {
            name,
            elements,
            generators,
            structure,
            residual: g.residual,
            center: g.center,
            max_order: g.max_order,
        });
    }
    out
}

/// The largest union of components that every generator of `h` maps onto itself (within
/// `tol`), if it contains the whole class, with its residual: the largest distance from the
/// surface of a region vertex's image under any element of `h`.
///
/// Components are screened on their samples and at most [`COMPONENT_VERTICES`] of their
/// vertices (cheap, and enough to reject most), then every vertex of a component that passes
/// is mapped by every element of the group and must land within `tol` of the surface: that is
/// what `motif symmetry check` and `motif deform` measure, and a strided screen alone once let a
/// component that one element maps 1.4·10⁻³ of the diagonal off the surface into a region
/// reported at 10⁻¹⁵ (a Lego brick's studs, two tessellated unlike).
#[allow(clippy::too_many_arguments)]
fn region_of(
    h: &AssembledGroup,
    class: &[usize],
    comps: &[Component],
    comp_points: &[Vec<Point3>],
    comp_vertices: &[Vec<Point3>],
    whole: &Shape,
    mesh: &TriMesh,
    tol: f64,
) -> Option<(Vec<usize>, f64)> {
    let maps_onto = |surface: &Surface, c: usize| {
        h.generators.iter().all(|g| {
            let r = surface.residual(&comp_points[c], g, tol);
            r.complete && r.max <= tol
        })
    };
    // Every element on every vertex, against the whole surface (as the check measures).
    let vertex_residual = |c: usize| -> Option<f64> {
        let mut worst = 0.0f64;
        for m in &h.elements {
            let r = whole.surface.residual(&comp_vertices[c], m, tol);
            if !r.complete || r.max > tol {
                return None;
            }
            worst = worst.max(r.max);
        }
        Some(worst)
    };
    let mut residual = vec![None; comps.len()];
    let mut region: Vec<usize> = Vec::new();
    for c in 0..comps.len() {
        if maps_onto(&whole.surface, c) {
            residual[c] = vertex_residual(c);
            if residual[c].is_some() {
                region.push(c);
            }
        }
    }
    for _ in 0..8 {
        if !class.iter().all(|c| region.contains(c)) {
            return None;
        }
        let tris: Vec<[Point3; 3]> =
            region.iter().flat_map(|&c| comps[c].faces.iter().map(|&f| mesh.corners(f))).collect();
        let surface = Surface { bvh: TriangleBvh::new(&tris)?, diagonal: whole.surface.diagonal };
        let next: Vec<usize> = region.iter().copied().filter(|&c| maps_onto(&surface, c)).collect();
        if next.len() == region.len() {
            let worst = region.iter().filter_map(|&c| residual[c]).fold(0.0, f64::max);
            return Some((region, worst));
        }
        region = next;
    }
    None
}
