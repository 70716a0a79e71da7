//! How well symmetries hold: [`check_annotation`] measures each transform of an annotation against
//! the rest shape, [`SymmetryMaps`] holds the induced vertex maps φ of thesis eq. 3.1
//! (`g ∘ x = x ∘ φ`), and [`symmetry_residual`] measures eq. 3.2 on a deformed mesh:
//! `max_k |g(x_k + u_k) − (x + u)_{φ(k)}|`, relative to the rest shape's diagonal.

use rayon::prelude::*;
use serde::Serialize;

use motif_core::TriMesh;
use motif_core::geometry::{Mat4, Point3, add, dist, scale, transform_point};
use motif_core::procedural::SymmetryAnnotation;
use motif_core::spatial::KdTree;

use crate::annotation::{ResolvedAnnotation, ResolvedKind, SymmetryElement, check_mesh, resolve_symmetry};
use crate::error::Result;
use crate::symmetry_detect::bvh::TriangleBvh;

/// Distances from points to a triangle mesh's surface.
///
/// The nearest vertex bounds the distance from above (it lies on the surface); a bounding-volume
/// hierarchy over the triangles ([`TriangleBvh`], branch and bound, exact) then finds any closer
/// point. It replaced a search of every triangle at a vertex within that bound plus the mesh's
/// longest edge: on CAD meshes, whose longest edges (fanned faces) reach 13–18% of the diagonal,
/// that ball held a quarter of the mesh, and `motif symmetry check` took 62 s on the 9,210-vertex
/// CGAL turbine (C10v, 19 transforms).
pub(crate) struct SurfaceDistance {
    tree: KdTree,
    /// `None` when the mesh has no triangle.
    bvh: Option<TriangleBvh>,
    exact_below: f64,
}

impl SurfaceDistance {
    pub(crate) fn new(mesh: &TriMesh) -> Result<Self> {
        let tree = KdTree::new(&mesh.positions)?;
        let triangles: Vec<[Point3; 3]> = (0..mesh.num_triangles()).map(|f| mesh.corners(f)).collect();
        Ok(SurfaceDistance { tree, bvh: TriangleBvh::new(&triangles), exact_below: 1e-12 * mesh.diagonal() })
    }

    pub(crate) fn tree(&self) -> &KdTree {
        &self.tree
    }

    /// Distance from `q` to the closest point on the surface, exact. Points closer than
    /// `10⁻¹² ×` the diagonal to a vertex return that distance without looking at triangles.
    pub(crate) fn distance(&self, q: Point3) -> f64 {
        let nv = self.tree.nearest(q);
        if nv.distance <= self.exact_below {
            return nv.distance;
        }
        let Some(bvh) = &self.bvh else { return nv.distance };
        bvh.closest(q, nv.distance * nv.distance, 0.0)
            .map_or(nv.distance, |hit| hit.d2.sqrt().min(nv.distance))
    }
}

/// Largest distance from `g(x_k)`, `k` in the element's domain, to the surface, relative to the
/// diagonal.
pub(crate) fn element_residual(mesh: &TriMesh, surface: &SurfaceDistance, e: &SymmetryElement) -> f64 {
    let worst = e
        .domain
        .par_iter()
        .map(|&k| surface.distance(transform_point(&e.transform, mesh.positions[k as usize])))
        .reduce(|| 0.0, f64::max);
    worst / mesh.diagonal()
}

/// The check of one transform of a symmetry.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TransformCheck {
    /// "element 3" or "instance 2 -> 0".
    pub label: String,
    /// The transform, row-major 4×4.
    pub transform: Mat4,
    /// Largest distance from a transformed region vertex to the surface (closest point on the
    /// triangles), relative to the bounding-box diagonal.
    pub residual: f64,
    /// Number of region vertices transformed.
    pub vertices: usize,
    /// How many of them land on a mesh vertex within the tolerance (the domain of the induced
    /// vertex map φ).
    pub matched_vertices: usize,
}

/// The check of one symmetry.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SymmetryCheck {
    /// The symmetry's name.
    pub name: String,
    /// "group" or "instances".
    pub kind: &'static str,
    /// Group order (closure of the generators), or number of instances.
    pub order: usize,
    /// Vertices in the region (groups) or in all instances together (instance sets).
    pub region_vertices: usize,
    /// Every non-identity group element, or for instance sets the maps between instance 0 and each
    /// other instance, both ways.
    pub transforms: Vec<TransformCheck>,
    /// Largest residual over the transforms, relative to the diagonal.
    pub max_residual: f64,
    /// True when the symmetry resolved and every residual is within the tolerance.
    pub ok: bool,
    /// Why the symmetry could not be resolved (non-orthogonal transform, group too large, empty
    /// region, ...), if so.
    pub problem: Option<String>,
}

/// The report of [`check_annotation`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AnnotationReport {
    /// Bounding-box diagonal of the mesh.
    pub diagonal: f64,
    /// The annotation's tolerance, relative to the diagonal.
    pub tolerance: f64,
    /// One entry per symmetry, in annotation order.
    pub symmetries: Vec<SymmetryCheck>,
    /// True when every symmetry is ok.
    pub ok: bool,
}

/// Checks every symmetry of `annotation` against `mesh`: group order, and for every transform the
/// largest distance from a transformed region vertex to the surface (closest point on triangles),
/// relative to the diagonal, and how many vertices map exactly onto vertices (the induced vertex
/// map φ). Problems of single symmetries are reported in the entries; errors are returned only for
/// an unusable mesh or tolerance.
pub fn check_annotation(mesh: &TriMesh, annotation: &SymmetryAnnotation) -> Result<AnnotationReport> {
    let diagonal = check_mesh(mesh)?;
    let tol = annotation.tolerance;
    let empty = SymmetryAnnotation { symmetries: Vec::new(), ..annotation.clone() };
    crate::annotation::resolve_annotation(mesh, &empty)?;
    let surface = SurfaceDistance::new(mesh)?;
    let neigh = one_ring_means(mesh);
    let margin = crate::annotation::REGION_MARGIN * diagonal;
    let mut symmetries = Vec::new();
    for s in &annotation.symmetries {
        let kind = match s.kind {
            motif_core::procedural::SymmetryKind::Group { .. } => "group",
            motif_core::procedural::SymmetryKind::Instances { .. } => "instances",
        };
        let mut sym_counter = 0;
        match resolve_symmetry(mesh, s, diagonal, tol, margin, &mut sym_counter) {
            Err(e) => symmetries.push(SymmetryCheck {
                name: s.name.clone(),
                kind,
                order: 0,
                region_vertices: 0,
                transforms: Vec::new(),
                max_residual: f64::INFINITY,
                ok: false,
                problem: Some(e.to_string()),
            }),
            Ok(None) => symmetries.push(SymmetryCheck {
                name: s.name.clone(),
                kind,
                order: 0,
                region_vertices: 0,
                transforms: Vec::new(),
                max_residual: 0.0,
                ok: true,
                problem: Some("no instances: ignored".into()),
            }),
            Ok(Some(r)) => {
                let region_vertices = match &r.kind {
                    ResolvedKind::Group { region, .. } => region.vertices.len(),
                    ResolvedKind::Instances { instances, .. } => {
                        let mut all: Vec<u32> =
                            instances.iter().flat_map(|i| i.vertices.iter().copied()).collect();
                        all.sort_unstable();
                        all.dedup();
                        all.len()
                    }
                };
                let order = r.order();
                let single = ResolvedAnnotation {
                    symmetries: vec![r],
                    ..ResolvedAnnotation::identity_only(diagonal, tol)
                };
                let transforms: Vec<TransformCheck> = single
                    .elements()
                    .iter()
                    .map(|e| {
                        let residual = element_residual(mesh, &surface, e);
                        let map = induced_map(mesh, surface.tree(), &neigh, e, tol * diagonal);
                        TransformCheck {
                            label: e.label.clone(),
                            transform: e.transform,
                            residual,
                            vertices: e.domain.len(),
                            matched_vertices: map.pairs.len(),
                        }
                    })
                    .collect();
                let max_residual = transforms.iter().map(|t| t.residual).fold(0.0, f64::max);
                symmetries.push(SymmetryCheck {
                    name: s.name.clone(),
                    kind,
                    order,
                    region_vertices,
                    transforms,
                    max_residual,
                    ok: max_residual <= tol,
                    problem: None,
                });
            }
        }
    }
    let ok = symmetries.iter().all(|s| s.ok);
    Ok(AnnotationReport { diagonal, tolerance: tol, symmetries, ok })
}

/// Mean position of each vertex's neighbours along triangle edges (the vertex itself when it has
/// none): tells coincident vertices of different parts apart.
pub(crate) fn one_ring_means(mesh: &TriMesh) -> Vec<Point3> {
    let n = mesh.num_vertices();
    let mut sum = vec![[0.0; 3]; n];
    let mut cnt = vec![0u32; n];
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            sum[a] = add(sum[a], mesh.positions[b]);
            sum[b] = add(sum[b], mesh.positions[a]);
            cnt[a] += 1;
            cnt[b] += 1;
        }
    }
    (0..n).map(|v| if cnt[v] == 0 { mesh.positions[v] } else { scale(sum[v], 1.0 / cnt[v] as f64) }).collect()
}

/// An induced vertex map: `pairs[i] = (k, φ(k))`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct InducedMap {
    /// `(k, φ(k))` for every domain vertex whose image lies on a vertex within the tolerance.
    pub pairs: Vec<(u32, u32)>,
    /// Domain vertices whose image is no vertex (φ undefined there).
    pub unmatched: usize,
}

/// φ of one element: vertex `k` ↦ the vertex at `g(x_k)` within `tol` (absolute). Coincident
/// candidates (parts that touch without being welded) are told apart by their neighbourhoods:
/// the candidate whose one-ring mean is closest to `g`(one-ring mean of `k`) wins.
pub(crate) fn induced_map(
    mesh: &TriMesh,
    tree: &KdTree,
    neigh: &[Point3],
    e: &SymmetryElement,
    tol: f64,
) -> InducedMap {
    let res: Vec<Option<(u32, u32)>> = e
        .domain
        .par_iter()
        .map(|&k| {
            let q = transform_point(&e.transform, mesh.positions[k as usize]);
            let cands = tree.within_unsorted(q, tol);
            match cands.len() {
                0 => None,
                1 => Some((k, cands[0].index as u32)),
                _ => {
                    let gm = transform_point(&e.transform, neigh[k as usize]);
                    let best = cands
                        .iter()
                        .min_by(|a, b| {
                            let da = dist(neigh[a.index], gm) + a.distance;
                            let db = dist(neigh[b.index], gm) + b.distance;
                            da.total_cmp(&db).then(a.index.cmp(&b.index))
                        })
                        .map(|n| n.index as u32)?;
                    Some((k, best))
                }
            }
        })
        .collect();
    let unmatched = res.iter().filter(|r| r.is_none()).count();
    InducedMap { pairs: res.into_iter().flatten().collect(), unmatched }
}

/// Computes the induced vertex map φ of `transform` on `domain` (vertices whose image lies within
/// `tolerance × diagonal` of a vertex).
pub fn induced_vertex_map(
    mesh: &TriMesh,
    transform: &Mat4,
    domain: &[u32],
    tolerance: f64,
) -> Result<InducedMap> {
    let d = check_mesh(mesh)?;
    let tree = KdTree::new(&mesh.positions)?;
    let neigh = one_ring_means(mesh);
    let e = SymmetryElement {
        symmetry: 0,
        name: String::new(),
        label: String::new(),
        transform: *transform,
        domain: domain.iter().copied().filter(|&k| (k as usize) < mesh.num_vertices()).collect(),
    };
    Ok(induced_map(mesh, &tree, &neigh, &e, tolerance * d))
}

/// The residual of one element on a deformed mesh.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ElementResidual {
    /// Index of the symmetry in the annotation.
    pub symmetry: usize,
    /// The symmetry's name.
    pub name: String,
    /// "element 3" or "instance 2 -> 0".
    pub label: String,
    /// `max_k |g(y_k) − y_{φ(k)}|` over the matched domain, relative to the rest diagonal.
    pub residual: f64,
    /// The same on the rest shape (`y = x`): how exact the annotation is.
    pub rest_residual: f64,
    /// Domain vertices with an image vertex (where φ is defined).
    pub matched: usize,
    /// Domain vertices without one (skipped).
    pub unmatched: usize,
}

/// The report of [`symmetry_residual`] / [`SymmetryMaps::residual`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualReport {
    /// Largest residual over all elements, relative to the rest diagonal.
    pub max: f64,
    /// The same on the rest shape.
    pub rest_max: f64,
    /// Per element.
    pub elements: Vec<ElementResidual>,
}

/// The elements of an annotation with their induced vertex maps on a rest mesh: precompute once,
/// then measure any number of deformed versions of the mesh with [`SymmetryMaps::residual`].
#[derive(Debug, Clone)]
pub struct SymmetryMaps {
    /// Diagonal of the rest mesh.
    pub diagonal: f64,
    /// The elements (see [`ResolvedAnnotation::elements`]).
    pub elements: Vec<SymmetryElement>,
    /// φ of each element.
    pub maps: Vec<InducedMap>,
    rest: Vec<Point3>,
}

impl SymmetryMaps {
    /// Resolves `annotation` on `mesh` and computes the induced vertex maps (image within the
    /// annotation's tolerance of a vertex).
    pub fn new(mesh: &TriMesh, annotation: &SymmetryAnnotation) -> Result<SymmetryMaps> {
        let resolved = crate::annotation::resolve_annotation(mesh, annotation)?;
        SymmetryMaps::from_resolved(mesh, &resolved)
    }

    /// [`SymmetryMaps::new`] from an already resolved annotation.
    pub fn from_resolved(mesh: &TriMesh, resolved: &ResolvedAnnotation) -> Result<SymmetryMaps> {
        let diagonal = check_mesh(mesh)?;
        let tree = KdTree::new(&mesh.positions)?;
        let neigh = one_ring_means(mesh);
        let elements = resolved.elements();
        let maps = elements
            .iter()
            .map(|e| induced_map(mesh, &tree, &neigh, e, resolved.tolerance * diagonal))
            .collect();
        Ok(SymmetryMaps { diagonal, elements, maps, rest: mesh.positions.clone() })
    }

    /// Eq. 3.2 on `deformed` (same vertex order as the rest mesh): for every element `g` with map
    /// φ, `max_k |g(y_k) − y_{φ(k)}|` relative to the rest diagonal. Fails when the vertex count
    /// differs.
    pub fn residual(&self, deformed: &[Point3]) -> Result<ResidualReport> {
        if deformed.len() != self.rest.len() {
            return Err(crate::error::DeformError::InvalidOption {
                name: "deformed",
                message: format!("has {} vertices, the rest mesh {}", deformed.len(), self.rest.len()),
            });
        }
        let measure = |y: &[Point3], e: &SymmetryElement, m: &InducedMap| -> f64 {
            m.pairs
                .par_iter()
                .map(|&(k, j)| {
                    let d = dist(transform_point(&e.transform, y[k as usize]), y[j as usize]);
                    if d.is_nan() { f64::INFINITY } else { d }
                })
                .reduce(|| 0.0, f64::max)
        };
        let elements: Vec<ElementResidual> = self
            .elements
            .iter()
            .zip(&self.maps)
            .map(|(e, m)| ElementResidual {
                symmetry: e.symmetry,
                name: e.name.clone(),
                label: e.label.clone(),
                residual: measure(deformed, e, m) / self.diagonal,
                rest_residual: measure(&self.rest, e, m) / self.diagonal,
                matched: m.pairs.len(),
                unmatched: m.unmatched,
            })
            .collect();
        Ok(ResidualReport {
            max: elements.iter().map(|e| e.residual).fold(0.0, f64::max),
            rest_max: elements.iter().map(|e| e.rest_residual).fold(0.0, f64::max),
            elements,
        })
    }
}

/// Eq. 3.2 on a deformed mesh: for every element `g` of `annotation` (resolved on the rest `mesh`)
/// with induced vertex map φ, `max_k |g(y_k) − y_{φ(k)}|` relative to the rest diagonal, where
/// `y = deformed`. Use [`SymmetryMaps`] to measure many deformations of one mesh.
pub fn symmetry_residual(
    mesh: &TriMesh,
    deformed: &[Point3],
    annotation: &SymmetryAnnotation,
) -> Result<ResidualReport> {
    SymmetryMaps::new(mesh, annotation)?.residual(deformed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use motif_core::geometry::closest_point_on_triangle;

    /// The hierarchy's distance equals a scan of every triangle, for points near and far from
    /// three generated meshes and on them (at vertices, and just off the triangles' insides).
    #[test]
    fn surface_distance_equals_a_scan_of_every_triangle() {
        use rand::{Rng, SeedableRng};
        for name in ["fan", "chair", "windmill"] {
            let mesh = motif_core::procedural::generate(name, 0).expect(name).mesh;
            let surface = SurfaceDistance::new(&mesh).expect("surface");
            let bb = mesh.aabb().expect("bounds");
            let diag = mesh.diagonal();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
            for k in 0..600 {
                let q = match k % 3 {
                    0 => std::array::from_fn(|i| {
                        rng.random_range(bb.min[i] - 0.1 * diag..bb.max[i] + 0.1 * diag)
                    }),
                    1 => mesh.positions[rng.random_range(0..mesh.num_vertices())],
                    _ => {
                        let [a, b, c] = mesh.corners(rng.random_range(0..mesh.num_triangles()));
                        let (u, v): (f64, f64) = (rng.random(), rng.random());
                        let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
                        std::array::from_fn(|i| {
                            a[i] + u * (b[i] - a[i]) + v * (c[i] - a[i]) + 1e-3 * diag * (u - 0.5)
                        })
                    }
                };
                let scan = (0..mesh.num_triangles())
                    .map(|f| {
                        let [a, b, c] = mesh.corners(f);
                        dist(q, closest_point_on_triangle(q, a, b, c))
                    })
                    .fold(f64::INFINITY, f64::min);
                let got = surface.distance(q);
                assert!((got - scan).abs() <= 1e-12 * diag, "{name}, point {k}: {got} vs {scan}");
            }
        }
    }

    #[test]
    fn closest_point_regions() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert!(dist(closest_point_on_triangle([0.2, 0.2, 1.0], a, b, c), [0.2, 0.2, 0.0]) < 1e-15);
        assert_eq!(closest_point_on_triangle([-1.0, -1.0, 0.0], a, b, c), a);
        assert_eq!(closest_point_on_triangle([2.0, -0.5, 0.0], a, b, c), b);
        let p = closest_point_on_triangle([1.0, 1.0, 0.0], a, b, c);
        assert!(dist(p, [0.5, 0.5, 0.0]) < 1e-15);
    }
}
