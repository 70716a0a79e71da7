//! The surface under analysis (the whole mesh or a union of its parts) with its sample sets and
//! closest-point structure.

use motif_core::Point3;
use motif_core::geometry::{norm, sub};
use motif_core::mesh::TriMesh;
use motif_core::sampling::sample_surface;

use super::bvh::{self, TriangleBvh};
use super::candidates::{self, PrincipalAxes};
use super::error::{Result, SymmetryDetectError};
use super::group::TransformMetric;
use super::options::{SymmetryDetectOptions, ValidationPoints};
use super::refine;
use super::residual::Surface;

/// Indices of the triangles with positive area.
pub(crate) fn non_degenerate(mesh: &TriMesh) -> Vec<usize> {
    (0..mesh.num_triangles()).filter(|&f| norm(mesh.face_cross(f)) > 0.0).collect()
}

/// `points` (in spatial order) regrouped into blocks of `block` consecutive points, each taking
/// every `n/block`-th point: every block spans the whole set while points within a block keep
/// some coherence.
fn interleave(points: &[Point3], block: usize) -> Vec<Point3> {
    let n = points.len();
    let blocks = n.div_ceil(block.max(1)).max(1);
    let mut out = Vec::with_capacity(n);
    for b in 0..blocks {
        out.extend(points.iter().skip(b).step_by(blocks).copied());
    }
    out
}

/// The surface under analysis (the whole mesh or a union of parts) with its point sets.
pub(crate) struct Shape {
    pub(crate) surface: Surface,
    pub(crate) principal: PrincipalAxes,
    pub(crate) center: Point3,
    /// Largest distance of a validation point from the centre (absolute).
    pub(crate) radius: f64,
    pub(crate) screen: Vec<Point3>,
    pub(crate) refine: Vec<Point3>,
    pub(crate) validate: Vec<Point3>,
    pub(crate) tris: Vec<[Point3; 3]>,
}

impl Shape {
    /// Prepares the faces `faces` of `mesh`; residuals are relative to `diag`. At most
    /// `max_vertices` vertices (evenly strided) join the validation samples.
    pub(crate) fn new(
        mesh: &TriMesh,
        faces: &[usize],
        diag: f64,
        o: &SymmetryDetectOptions,
        seed: u64,
        max_vertices: usize,
    ) -> Result<Shape> {
        if faces.is_empty() || diag.is_nan() || diag <= 0.0 {
            return Err(SymmetryDetectError::NoSurface);
        }
        let tris: Vec<[Point3; 3]> = faces.iter().map(|&f| mesh.corners(f)).collect();
        let principal = candidates::principal_axes(&tris).ok_or(SymmetryDetectError::NoSurface)?;
        let bvh = TriangleBvh::new(&tris).ok_or(SymmetryDetectError::NoSurface)?;
        // A compact copy of the faces for sampling (sampling needs a mesh).
        let mut used = vec![u32::MAX; mesh.num_vertices()];
        let mut sub_mesh = TriMesh::default();
        for &f in faces {
            let mut t = [0u32; 3];
            for (k, &v) in mesh.triangles[f].iter().enumerate() {
                if used[v as usize] == u32::MAX {
                    used[v as usize] = sub_mesh.positions.len() as u32;
                    sub_mesh.positions.push(mesh.positions[v as usize]);
                }
                t[k] = used[v as usize];
            }
            sub_mesh.triangles.push(t);
        }
        let n = o.validation_samples + o.screening_samples + o.refine_samples;
        let samples = sample_surface(&sub_mesh, n, seed)?.points;
        let mut validate: Vec<Point3> = samples[..o.validation_samples].to_vec();
        let mut screen = samples[o.validation_samples..o.validation_samples + o.screening_samples].to_vec();
        let mut refine = samples[o.validation_samples + o.screening_samples..].to_vec();
        if o.validation_points == ValidationPoints::SamplesAndVertices {
            let stride = sub_mesh.positions.len().div_ceil(max_vertices.max(1)).max(1);
            validate.extend(sub_mesh.positions.iter().step_by(stride).copied());
        }
        // Spatially coherent query order: several times faster closest-point queries. The
        // screening samples are then dealt into 64-point blocks that each span the shape.
        for set in [&mut validate, &mut screen, &mut refine] {
            bvh::sort_spatially(set);
        }
        let screen = interleave(&screen, 64);
        let refine = interleave(&refine, refine::COARSE_POINTS);
        let center = principal.center;
        let radius = validate.iter().map(|p| norm(sub(*p, center))).fold(0.0, f64::max).max(1e-12 * diag);
        Ok(Shape {
            surface: Surface { bvh, diagonal: diag },
            principal,
            center,
            radius,
            screen,
            refine,
            validate,
            tris,
        })
    }

    pub(crate) fn metric(&self) -> TransformMetric {
        TransformMetric { center: self.center, radius: self.radius }
    }
}
