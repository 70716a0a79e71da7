//! The known structure of a procedural example: its symmetries in the `motif_symmetry_v1`
//! annotation format (`../shared/formats/symmetry.md`), its translational lattice, and its classes of
//! repeated parts in the building-block ground-truth format (`../shared/formats/detection.md`).
//!
//! Transforms are row-major 4×4 matrices acting on column vectors (`p' = M p`) whose upper-left 3×3
//! is orthogonal (a rotation or a reflection). An instance transform maps instance 0 (the template)
//! onto the instance: it is `instance_from_template`.

use serde::{Deserialize, Serialize};

use crate::geometry::{Aabb, IDENTITY4, Mat4, Point3, dist2, transform_point};
use crate::mesh::TriMesh;
use crate::spatial::KdTree;
use crate::{Error, Result};

/// The format tag written into every annotation.
pub const SYMMETRY_FORMAT: &str = "motif_symmetry_v1";

/// Default annotation tolerance, relative to the bounding-box diagonal: the doublet threshold of
/// symmetric sampling (thesis 3.4 uses 10⁻⁴ × the scene size). Procedural shapes are far more exact
/// than this (their residuals are at floating-point rounding level).
pub const DEFAULT_SYMMETRY_TOLERANCE: f64 = 1e-4;

/// Everything known about an example's structure; written as JSON by
/// `motif example NAME OUT --structure S.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Structure {
    /// The symmetries, exactly in the `motif_symmetry_v1` annotation format.
    pub symmetry: SymmetryAnnotation,
    /// Translational lattice vectors (shelf cells, facade bays and floors, fence posts), in metres;
    /// empty when the shape has no lattice.
    pub cell_pitch: Vec<Point3>,
    /// Number of cells along each of the `cell_pitch` vectors when the repetition is a full grid
    /// (entries beyond `cell_pitch.len()` are 1); `None` when there is no lattice.
    pub cells: Option<[usize; 3]>,
    /// Named classes of repeated parts with per-instance boxes and transforms, in the schema of
    /// `../shared/formats/detection.md`, so they can serve as detection ground truth.
    pub instances: Vec<InstanceClass>,
}

impl Structure {
    /// The building-block ground truth of this example in the `motif detect` / `motif eval`
    /// schema: `{"scene": scene, "classes": [{"name", "instances": [{"bbox_min", "bbox_max",
    /// "transform"}]}]}`.
    pub fn detection_ground_truth(&self, scene: &str) -> serde_json::Value {
        serde_json::json!({ "scene": scene, "classes": self.instances })
    }
}

/// A symmetry annotation in the `motif_symmetry_v1` format.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SymmetryAnnotation {
    /// Always [`SYMMETRY_FORMAT`].
    pub format: String,
    /// Tolerance relative to the bounding-box diagonal, used to validate transforms and to merge
    /// coinciding samples ([`DEFAULT_SYMMETRY_TOLERANCE`]).
    pub tolerance: f64,
    /// The symmetries; regions may overlap and nest (thesis Fig. 3.3).
    pub symmetries: Vec<Symmetry>,
}

impl Default for SymmetryAnnotation {
    fn default() -> Self {
        SymmetryAnnotation {
            format: SYMMETRY_FORMAT.to_string(),
            tolerance: DEFAULT_SYMMETRY_TOLERANCE,
            symmetries: Vec::new(),
        }
    }
}

/// One symmetry: a group acting on a region, or a set of congruent instances.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Symmetry {
    /// A human-readable name ("fan blades", "windows").
    pub name: String,
    /// The group or the instance set.
    #[serde(flatten)]
    pub kind: SymmetryKind,
}

/// The two kinds of symmetry of the format; serialised without a tag, distinguished by their
/// fields (`region` + `generators`, or `instances`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum SymmetryKind {
    /// A finite group, the closure of `generators`, under which `region` is invariant.
    Group {
        /// The region the group acts on.
        region: Region,
        /// Generators of the group, row-major 4×4.
        generators: Vec<Mat4>,
    },
    /// Congruent copies: each transform maps instance 0's region onto the instance's region
    /// (partial symmetry, thesis 3.2 and 5.2).
    Instances {
        /// The instances; the first one's transform is the identity.
        instances: Vec<SymmetryInstance>,
    },
}

/// One instance of an instance-set symmetry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SymmetryInstance {
    /// Where the instance is.
    pub region: Region,
    /// `instance_from_template`: maps instance 0 onto this instance.
    pub transform: Mat4,
}

/// A region of a shape, serialised as in the format: `"all"`, `{"vertices": [...]}`,
/// `{"faces": [...]}`, `{"aabb": {"min", "max"}}`, `{"sphere": {"center", "radius"}}` or
/// `{"union": [...]}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Region {
    /// The whole shape.
    All,
    /// These vertex indices.
    Vertices(Vec<u32>),
    /// These triangles (and their vertices).
    Faces(Vec<u32>),
    /// Everything inside a closed axis-aligned box.
    Aabb {
        /// Smallest corner.
        min: Point3,
        /// Largest corner.
        max: Point3,
    },
    /// Everything inside a closed ball.
    Sphere {
        /// Centre.
        center: Point3,
        /// Radius.
        radius: f64,
    },
    /// The union of several regions.
    Union(Vec<Region>),
}

impl Region {
    /// The box region of an [`Aabb`].
    pub fn aabb(b: Aabb) -> Region {
        Region::Aabb { min: b.min, max: b.max }
    }

    /// Indices of the mesh vertices in the region, ascending. Geometric regions (box, ball) are
    /// enlarged by `tolerance` (absolute, in mesh units) so vertices on their boundary count.
    pub fn vertex_indices(&self, mesh: &TriMesh, tolerance: f64) -> Vec<usize> {
        let mut inside = vec![false; mesh.num_vertices()];
        self.mark(mesh, tolerance, &mut inside);
        inside.iter().enumerate().filter(|(_, b)| **b).map(|(i, _)| i).collect()
    }

    fn mark(&self, mesh: &TriMesh, tol: f64, inside: &mut [bool]) {
        let n = inside.len();
        match self {
            Region::All => inside.iter_mut().for_each(|b| *b = true),
            Region::Vertices(v) => {
                for &i in v {
                    if (i as usize) < n {
                        inside[i as usize] = true;
                    }
                }
            }
            Region::Faces(f) => {
                for &t in f {
                    if let Some(tri) = mesh.triangles.get(t as usize) {
                        for &i in tri {
                            if (i as usize) < n {
                                inside[i as usize] = true;
                            }
                        }
                    }
                }
            }
            Region::Aabb { min, max } => {
                for (i, p) in mesh.positions.iter().enumerate() {
                    if (0..3).all(|k| p[k] >= min[k] - tol && p[k] <= max[k] + tol) {
                        inside[i] = true;
                    }
                }
            }
            Region::Sphere { center, radius } => {
                let r = radius + tol;
                for (i, p) in mesh.positions.iter().enumerate() {
                    if dist2(*p, *center) <= r * r {
                        inside[i] = true;
                    }
                }
            }
            Region::Union(parts) => parts.iter().for_each(|r| r.mark(mesh, tol, inside)),
        }
    }

    /// True when the region is defined by positions (box, ball, or a union of those), so it can be
    /// tested on any point rather than only on mesh vertices.
    pub fn is_geometric(&self) -> bool {
        match self {
            Region::All | Region::Aabb { .. } | Region::Sphere { .. } => true,
            Region::Vertices(_) | Region::Faces(_) => false,
            Region::Union(parts) => parts.iter().all(Region::is_geometric),
        }
    }
}

/// A named class of repeated parts (detection ground truth).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InstanceClass {
    /// Class name ("window_a", "blade").
    pub name: String,
    /// The instances; instance 0 is the template (identity transform).
    pub instances: Vec<Instance>,
}

/// One instance of a class: its axis-aligned box and its pose.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Instance {
    /// Smallest corner of the instance's axis-aligned box, world coordinates.
    pub bbox_min: Point3,
    /// Largest corner of the instance's axis-aligned box.
    pub bbox_max: Point3,
    /// `instance_from_template`, row-major 4×4.
    pub transform: Mat4,
}

impl Instance {
    /// The instance's box.
    pub fn aabb(&self) -> Aabb {
        Aabb { min: self.bbox_min, max: self.bbox_max }
    }
}

/// The translation by `t`.
pub fn translation(t: Point3) -> Mat4 {
    let mut m = IDENTITY4;
    for k in 0..3 {
        m[k][3] = t[k];
    }
    m
}

/// The rotation by `angle` radians about the line through `point` with direction `axis`
/// (right-hand rule).
pub fn rotation_about(axis: Point3, point: Point3, angle: f64) -> Mat4 {
    let r = crate::geometry::rotation_about_axis(axis, angle);
    affine_about(r, point)
}

/// The reflection in the plane through `point` with normal `normal` (need not be unit; a zero
/// normal gives the identity).
pub fn reflection(normal: Point3, point: Point3) -> Mat4 {
    let Some(n) = crate::geometry::normalize(normal) else { return IDENTITY4 };
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = if i == j { 1.0 } else { 0.0 } - 2.0 * n[i] * n[j];
        }
    }
    affine_about(r, point)
}

/// `x ↦ R (x − c) + c` as a 4×4 matrix.
fn affine_about(r: [[f64; 3]; 3], c: Point3) -> Mat4 {
    let rc = [
        r[0][0] * c[0] + r[0][1] * c[1] + r[0][2] * c[2],
        r[1][0] * c[0] + r[1][1] * c[1] + r[1][2] * c[2],
        r[2][0] * c[0] + r[2][1] * c[1] + r[2][2] * c[2],
    ];
    crate::geometry::mat4_from_rt(r, [c[0] - rc[0], c[1] - rc[1], c[2] - rc[2]])
}

/// The inverse of a rigid (orthogonal linear part) transform: `[Rᵀ | −Rᵀ t]`.
pub fn rigid_inverse(m: &Mat4) -> Mat4 {
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = m[j][i];
        }
    }
    let t = [m[0][3], m[1][3], m[2][3]];
    let rt = [
        -(r[0][0] * t[0] + r[0][1] * t[1] + r[0][2] * t[2]),
        -(r[1][0] * t[0] + r[1][1] * t[1] + r[1][2] * t[2]),
        -(r[2][0] * t[0] + r[2][1] * t[1] + r[2][2] * t[2]),
    ];
    crate::geometry::mat4_from_rt(r, rt)
}

/// How far a symmetry is from mapping its region's vertices onto the mesh's vertices: the largest
/// distance from an image `g(v)` (each generator `g`, each vertex `v` of the region; for instance
/// sets each transform on instance 0's vertices and each inverse on the instance's vertices) to the
/// nearest mesh vertex, divided by the bounding-box diagonal. Geometric regions are enlarged by
/// `10⁻⁹ ×` the diagonal so vertices on their boundary count. Procedural examples give residuals
/// at rounding level (≤ 10⁻¹²).
pub fn symmetry_residual(mesh: &TriMesh, symmetry: &Symmetry) -> Result<f64> {
    if mesh.diagonal() <= 0.0 {
        return Err(Error::InvalidInput("the mesh has no extent".into()));
    }
    let tree = KdTree::new(&mesh.positions)?;
    Ok(residual_with_tree(mesh, &tree, symmetry))
}

/// [`symmetry_residual`] with a kd-tree over `mesh.positions` built by the caller.
pub(crate) fn residual_with_tree(mesh: &TriMesh, tree: &KdTree, symmetry: &Symmetry) -> f64 {
    let diag = mesh.diagonal();
    let tol = 1e-9 * diag;
    let worst = |verts: &[usize], m: &Mat4| -> f64 {
        verts
            .iter()
            .map(|&v| tree.nearest(transform_point(m, mesh.positions[v])).distance)
            .fold(0.0, f64::max)
    };
    let mut r: f64 = 0.0;
    match &symmetry.kind {
        SymmetryKind::Group { region, generators } => {
            let verts = region.vertex_indices(mesh, tol);
            for g in generators {
                r = r.max(worst(&verts, g));
            }
        }
        SymmetryKind::Instances { instances } => {
            let Some(first) = instances.first() else { return 0.0 };
            let verts0 = first.region.vertex_indices(mesh, tol);
            let from0 = rigid_inverse(&first.transform);
            for inst in instances {
                let to_i = crate::geometry::mat4_mul(&inst.transform, &from0);
                r = r.max(worst(&verts0, &to_i));
                let verts_i = inst.region.vertex_indices(mesh, tol);
                r = r.max(worst(&verts_i, &rigid_inverse(&to_i)));
            }
        }
    }
    r / diag
}

/// True when every transform of the symmetry maps the vertices of its source region onto vertices
/// (within `10⁻⁹ ×` the diagonal) that lie in its target region: the group's region is invariant,
/// instance 0's region maps into instance `i`'s and back.
pub(crate) fn maps_regions_onto_regions(mesh: &TriMesh, tree: &KdTree, symmetry: &Symmetry) -> bool {
    let tol = 1e-9 * mesh.diagonal();
    let mask = |r: &Region| {
        let mut m = vec![false; mesh.num_vertices()];
        r.mark(mesh, tol, &mut m);
        m
    };
    let maps = |from: &[bool], to: &[bool], g: &Mat4| {
        from.iter().enumerate().filter(|(_, b)| **b).all(|(v, _)| {
            let q = transform_point(g, mesh.positions[v]);
            tree.within_unsorted(q, tol).iter().any(|n| to[n.index])
        })
    };
    match &symmetry.kind {
        SymmetryKind::Group { region, generators } => {
            let m = mask(region);
            generators.iter().all(|g| maps(&m, &m, g))
        }
        SymmetryKind::Instances { instances } => {
            let Some(first) = instances.first() else { return true };
            let m0 = mask(&first.region);
            let from0 = rigid_inverse(&first.transform);
            instances.iter().all(|inst| {
                let mi = mask(&inst.region);
                let to_i = crate::geometry::mat4_mul(&inst.transform, &from0);
                maps(&m0, &mi, &to_i) && maps(&mi, &m0, &rigid_inverse(&to_i))
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_serialise_as_in_the_format() {
        let all = serde_json::to_value(Region::All).unwrap();
        assert_eq!(all, serde_json::json!("all"));
        let b = serde_json::to_value(Region::Aabb { min: [0.0; 3], max: [1.0; 3] }).unwrap();
        assert_eq!(b, serde_json::json!({"aabb": {"min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 1.0]}}));
        let f = serde_json::to_value(Region::Faces(vec![1, 2])).unwrap();
        assert_eq!(f, serde_json::json!({"faces": [1, 2]}));
        let u = serde_json::to_value(Region::Union(vec![Region::Vertices(vec![3])])).unwrap();
        assert_eq!(u, serde_json::json!({"union": [{"vertices": [3]}]}));
    }

    #[test]
    fn symmetries_round_trip() {
        let a = SymmetryAnnotation {
            symmetries: vec![
                Symmetry {
                    name: "g".into(),
                    kind: SymmetryKind::Group { region: Region::All, generators: vec![IDENTITY4] },
                },
                Symmetry {
                    name: "i".into(),
                    kind: SymmetryKind::Instances {
                        instances: vec![SymmetryInstance {
                            region: Region::Sphere { center: [0.0; 3], radius: 1.0 },
                            transform: translation([1.0, 2.0, 3.0]),
                        }],
                    },
                },
            ],
            ..Default::default()
        };
        let s = serde_json::to_string(&a).unwrap();
        let v: serde_json::Value = serde_json::from_str(&s).unwrap();
        assert_eq!(v["format"], "motif_symmetry_v1");
        assert_eq!(v["symmetries"][0]["region"], "all");
        assert!(v["symmetries"][1]["instances"][0]["transform"].is_array());
        let back: SymmetryAnnotation = serde_json::from_str(&s).unwrap();
        assert_eq!(back, a);
    }

    #[test]
    fn transforms_behave() {
        let m = reflection([1.0, 0.0, 0.0], [2.0, 0.0, 0.0]);
        assert_eq!(transform_point(&m, [3.0, 1.0, 1.0]), [1.0, 1.0, 1.0]);
        let r = rotation_about([0.0, 0.0, 1.0], [1.0, 0.0, 0.0], std::f64::consts::PI);
        let p = transform_point(&r, [2.0, 0.0, 0.0]);
        assert!(dist2(p, [0.0, 0.0, 0.0]) < 1e-24);
        let back = transform_point(&rigid_inverse(&r), p);
        assert!(dist2(back, [2.0, 0.0, 0.0]) < 1e-24);
    }
}
