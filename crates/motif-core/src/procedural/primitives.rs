//! Building blocks of the procedural shapes: subdivided hexahedra (boxes, tapered boxes, wedge
//! sectors), extruded profiles, orbits of a fundamental piece under a finite group, and an assembly
//! of closed parts that remembers which vertices and faces belong to which part.
//!
//! Exactness comes from construction: a symmetric part is built as a *fundamental piece* (a half
//! blade, a half tooth sector, ...) that is open where it meets its images, and the part is the
//! union of the piece's images under the group, welded. Every symmetric vertex is then the image of
//! a piece vertex up to floating-point rounding, and the triangulation is symmetric too.

use std::ops::Range;

use crate::geometry::{Aabb, Mat4, Point3, mat4_mul};
use crate::mesh::TriMesh;
use crate::procedural::structure::{
    Instance, InstanceClass, Region, Symmetry, SymmetryInstance, SymmetryKind, maps_regions_onto_regions,
    reflection, residual_with_tree, rotation_about,
};
use crate::spatial::KdTree;
use crate::{Error, Result};

/// Welding tolerance relative to a part's diagonal: merges seam vertices that differ by rounding
/// only; distinct vertices of the shapes are many orders of magnitude further apart.
pub(crate) const WELD_TOLERANCE: f64 = 1e-9;

/// A face of a hexahedron, named by the parameter that is constant on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Side {
    /// `s = 0`.
    MinX,
    /// `s = 1`.
    MaxX,
    /// `t = 0`.
    MinY,
    /// `t = 1`.
    MaxY,
    /// `w = 0`.
    MinZ,
    /// `w = 1`.
    MaxZ,
}

/// A trilinear hexahedron: `corners[s + 2t + 4w]` is the corner at parameters `(s, t, w) ∈ {0,1}³`.
/// The map must preserve orientation (`∂s × ∂t · ∂w > 0`) for the faces to point outward.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Hexa {
    pub corners: [Point3; 8],
}

/// `(1 − t) a + t b`, exact at `t = 0` and `t = 1`.
#[inline]
fn mix(a: Point3, b: Point3, t: f64) -> Point3 {
    let u = 1.0 - t;
    [u * a[0] + t * b[0], u * a[1] + t * b[1], u * a[2] + t * b[2]]
}

impl Hexa {
    /// The axis-aligned box `[min, max]`.
    pub fn axis_box(min: Point3, max: Point3) -> Hexa {
        let mut corners = [[0.0; 3]; 8];
        for (i, c) in corners.iter_mut().enumerate() {
            *c = [
                if i & 1 == 0 { min[0] } else { max[0] },
                if i & 2 == 0 { min[1] } else { max[1] },
                if i & 4 == 0 { min[2] } else { max[2] },
            ];
        }
        Hexa { corners }
    }

    /// The point at parameters `(s, t, w) ∈ [0,1]³`.
    pub fn eval(&self, s: f64, t: f64, w: f64) -> Point3 {
        let c = &self.corners;
        let b0 = mix(mix(c[0], c[1], s), mix(c[2], c[3], s), t);
        let b1 = mix(mix(c[4], c[5], s), mix(c[6], c[7], s), t);
        mix(b0, b1, w)
    }
}

/// Appends a `nu × nv` grid patch `f: [0,1]² → R³`; triangles are oriented so that the normal
/// points along `∂f/∂u × ∂f/∂v`. Every quad is split along the same diagonal.
pub(crate) fn add_patch(mesh: &mut TriMesh, nu: usize, nv: usize, f: impl Fn(f64, f64) -> Point3) {
    let (nu, nv) = (nu.max(1), nv.max(1));
    let base = mesh.positions.len() as u32;
    for i in 0..=nu {
        for j in 0..=nv {
            mesh.positions.push(f(i as f64 / nu as f64, j as f64 / nv as f64));
        }
    }
    let idx = |i: usize, j: usize| base + (i * (nv + 1) + j) as u32;
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
            mesh.triangles.push([a, b, c]);
            mesh.triangles.push([a, c, d]);
        }
    }
}

/// Appends the bilinear quad `p00 p10 p11 p01` subdivided `nu × nv`; the normal points along
/// `(p10 − p00) × (p01 − p00)`.
pub(crate) fn add_quad(mesh: &mut TriMesh, [p00, p10, p11, p01]: [Point3; 4], nu: usize, nv: usize) {
    add_patch(mesh, nu, nv, |u, v| mix(mix(p00, p10, u), mix(p01, p11, u), v));
}

/// Appends the faces of a hexahedron subdivided `n = [ns, nt, nw]`, leaving out the `open` faces
/// (where the piece meets another piece or its own mirror image). Faces point outward.
pub(crate) fn add_hexa(mesh: &mut TriMesh, h: &Hexa, n: [usize; 3], open: &[Side]) {
    let [ns, nt, nw] = n;
    for side in [Side::MinX, Side::MaxX, Side::MinY, Side::MaxY, Side::MinZ, Side::MaxZ] {
        if open.contains(&side) {
            continue;
        }
        match side {
            Side::MinX => add_patch(mesh, nw, nt, |u, v| h.eval(0.0, v, u)),
            Side::MaxX => add_patch(mesh, nt, nw, |u, v| h.eval(1.0, u, v)),
            Side::MinY => add_patch(mesh, ns, nw, |u, v| h.eval(u, 0.0, v)),
            Side::MaxY => add_patch(mesh, nw, ns, |u, v| h.eval(v, 1.0, u)),
            Side::MinZ => add_patch(mesh, nt, ns, |u, v| h.eval(v, u, 0.0)),
            Side::MaxZ => add_patch(mesh, ns, nt, |u, v| h.eval(u, v, 1.0)),
        }
    }
}

/// Welds a part (see [`WELD_TOLERANCE`]) and drops triangles that collapse.
pub(crate) fn weld(mut mesh: TriMesh) -> TriMesh {
    mesh.weld(WELD_TOLERANCE);
    mesh
}

/// A closed, subdivided box `[min, max]` as one welded part.
pub(crate) fn box_part(min: Point3, max: Point3, n: [usize; 3]) -> TriMesh {
    let mut m = TriMesh::default();
    add_hexa(&mut m, &Hexa::axis_box(min, max), n, &[]);
    weld(m)
}

/// The union of the images of `piece` under `elements`, welded: a part with exactly the symmetry
/// of the group the elements enumerate.
pub(crate) fn orbit(piece: &TriMesh, elements: &[Mat4]) -> TriMesh {
    let mut out = TriMesh::default();
    for g in elements {
        let mut c = piece.clone();
        c.transform(g);
        out.append(&c);
    }
    weld(out)
}

/// A copy of `part` moved by `m` (reflections keep outward winding).
pub(crate) fn transformed(part: &TriMesh, m: &Mat4) -> TriMesh {
    let mut c = part.clone();
    c.transform(m);
    c
}

/// The `2n` elements of the dihedral group generated by the rotation by `2π/n` about the line
/// (`center`, `axis`) and the reflection in the plane through `center` with normal `mirror_normal`
/// (which must contain the axis): rotations first, then rotations composed with the reflection.
pub(crate) fn dihedral_elements(n: usize, axis: Point3, center: Point3, mirror_normal: Point3) -> Vec<Mat4> {
    let m = reflection(mirror_normal, center);
    let rotations: Vec<Mat4> =
        (0..n).map(|k| rotation_about(axis, center, std::f64::consts::TAU * k as f64 / n as f64)).collect();
    let mut out = rotations.clone();
    out.extend(rotations.iter().map(|r| mat4_mul(r, &m)));
    out
}

/// A closed solid extruded along z between `z0` and `z1` from a profile given as matching
/// polylines `inner` and `outer` in the xy-plane (z of the points is ignored), walked
/// counter-clockwise about the z axis; strip `j` is the quad `inner[j] inner[j+1] outer[j+1]
/// outer[j]`. Strips are subdivided `n_radial` from inner to outer and `n_z` along z. The radial end
/// faces of the first and last strip are left out (`open_ends`) where the piece meets its images,
/// the bottom face when `open_bottom`. An inner polyline that collapses to a point (a hub's axis)
/// gets no inner wall; welding removes the collapsed triangles.
pub(crate) fn profile_solid(
    inner: &[Point3],
    outer: &[Point3],
    z: [f64; 2],
    n_radial: usize,
    n_z: usize,
    open_ends: bool,
    open_bottom: bool,
) -> TriMesh {
    let mut m = TriMesh::default();
    let last = outer.len().saturating_sub(2);
    for j in 0..outer.len().saturating_sub(1) {
        let at = |p: Point3, zz: f64| [p[0], p[1], zz];
        let h = Hexa {
            corners: [
                at(inner[j], z[0]),
                at(outer[j], z[0]),
                at(inner[j + 1], z[0]),
                at(outer[j + 1], z[0]),
                at(inner[j], z[1]),
                at(outer[j], z[1]),
                at(inner[j + 1], z[1]),
                at(outer[j + 1], z[1]),
            ],
        };
        let mut open = Vec::new();
        if j > 0 || open_ends {
            open.push(Side::MinY);
        }
        if j < last || open_ends {
            open.push(Side::MaxY);
        }
        if open_bottom {
            open.push(Side::MinZ);
        }
        if inner[j][..2] == inner[j + 1][..2] {
            open.push(Side::MinX);
        }
        add_hexa(&mut m, &h, [n_radial, 1, n_z], &open);
    }
    m
}

/// The outline of one half-sector `[0, half_angle]` of a polygonal hub of circumradius `radius`
/// whose face centred on angle 0 is flat with half-angle `alpha` (so a blade root of half-width
/// `≤ radius·sin(alpha)` sits flush on it), followed by `corners` further corners up to and including
/// `half_angle`. Points are in the xy-plane, counter-clockwise; the first point lies on the x axis
/// (the middle of the flat face).
pub(crate) fn hub_half_outline(radius: f64, alpha: f64, half_angle: f64, corners: usize) -> Vec<Point3> {
    let mut pts = vec![[radius * alpha.cos(), 0.0, 0.0]];
    let corners = corners.max(1);
    for j in 0..=corners {
        let a =
            if j == corners { half_angle } else { alpha + (half_angle - alpha) * j as f64 / corners as f64 };
        pts.push([radius * a.cos(), radius * a.sin(), 0.0]);
    }
    pts
}

/// `resolution` as a subdivision multiplier, checked.
pub(crate) fn check_resolution(resolution: usize) -> Result<usize> {
    if resolution == 0 || resolution > 1000 {
        return Err(Error::InvalidOption {
            name: "resolution",
            message: format!("{resolution} is out of range: use 1 (default tessellation) to 1000"),
        });
    }
    Ok(resolution)
}

/// Checks that a length option is finite and positive.
pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<()> {
    if !(value.is_finite() && value > 0.0) {
        return Err(Error::InvalidOption {
            name,
            message: format!("must be positive and finite, got {value}"),
        });
    }
    Ok(())
}

/// One closed part of an [`Assembly`].
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Part {
    /// What the part is ("blade 3", "leg").
    pub tag: String,
    /// Its vertices in the assembled mesh.
    pub vertices: Range<usize>,
    /// Its triangles in the assembled mesh.
    pub faces: Range<usize>,
}

/// Closed parts concatenated into one mesh (parts touch but are never welded to each other, so
/// each stays closed and manifold).
#[derive(Debug, Clone, Default)]
pub(crate) struct Assembly {
    pub mesh: TriMesh,
    pub parts: Vec<Part>,
}

impl Assembly {
    /// Appends a part; returns its index.
    pub fn add(&mut self, tag: impl Into<String>, part: &TriMesh) -> usize {
        let v0 = self.mesh.num_vertices();
        let f0 = self.mesh.num_triangles();
        self.mesh.append(part);
        self.parts.push(Part {
            tag: tag.into(),
            vertices: v0..self.mesh.num_vertices(),
            faces: f0..self.mesh.num_triangles(),
        });
        self.parts.len() - 1
    }

    /// The box around the given parts.
    pub fn aabb_of(&self, parts: &[usize]) -> Aabb {
        let points: Vec<_> = parts
            .iter()
            .flat_map(|&p| self.parts[p].vertices.clone().map(|v| self.mesh.positions[v]))
            .collect();
        Aabb::from_points(&points).unwrap_or(Aabb { min: [0.0; 3], max: [0.0; 3] })
    }

    /// The triangles of the given parts, ascending.
    pub fn faces_of(&self, parts: &[usize]) -> Vec<u32> {
        let mut f: Vec<u32> =
            parts.iter().flat_map(|&p| self.parts[p].faces.clone()).map(|f| f as u32).collect();
        f.sort_unstable();
        f
    }
}

/// Residual (relative to the diagonal) below which a symmetry counts as exact when choosing how to
/// write its regions.
pub(crate) const EXACT: f64 = 1e-9;

/// Writes the structure of an [`Assembly`]: instance classes and symmetries whose regions are the
/// most readable form that is exact: one box per instance, else a union of per-part boxes, else
/// the parts' faces (always exact, since the parts are built symmetric).
pub(crate) struct Annotator<'a> {
    asm: &'a Assembly,
    tree: KdTree,
}

impl<'a> Annotator<'a> {
    /// Indexes the assembled mesh.
    pub fn new(asm: &'a Assembly) -> Result<Self> {
        Ok(Annotator { asm, tree: KdTree::new(&asm.mesh.positions)? })
    }

    fn is_exact(&self, name: &str, kind: &SymmetryKind) -> bool {
        let s = Symmetry { name: name.to_string(), kind: kind.clone() };
        residual_with_tree(&self.asm.mesh, &self.tree, &s) <= EXACT
            && maps_regions_onto_regions(&self.asm.mesh, &self.tree, &s)
    }

    /// The first exact candidate (the last one, faces, is exact by construction).
    fn pick(&self, name: &str, candidates: Vec<SymmetryKind>) -> Symmetry {
        let n = candidates.len();
        for (i, kind) in candidates.into_iter().enumerate() {
            if i + 1 == n || self.is_exact(name, &kind) {
                return Symmetry { name: name.to_string(), kind };
            }
        }
        Symmetry { name: name.to_string(), kind: SymmetryKind::Instances { instances: Vec::new() } }
    }

    /// An instance-set symmetry: instance `i` consists of `parts[i]` and is `transforms[i]` applied
    /// to instance 0.
    pub fn instances(&self, name: &str, parts: &[Vec<usize>], transforms: &[Mat4]) -> Symmetry {
        let make = |region: &dyn Fn(&[usize]) -> Region| SymmetryKind::Instances {
            instances: parts
                .iter()
                .zip(transforms)
                .map(|(p, t)| SymmetryInstance { region: region(p), transform: *t })
                .collect(),
        };
        let one_box = make(&|p| Region::aabb(self.asm.aabb_of(p)));
        let boxes =
            make(&|p| Region::Union(p.iter().map(|&q| Region::aabb(self.asm.aabb_of(&[q]))).collect()));
        let faces = make(&|p| Region::Faces(self.asm.faces_of(p)));
        self.pick(name, vec![one_box, boxes, faces])
    }

    /// An instance-set symmetry whose instance `i` is the region `boxes[i]` (falling back to the
    /// faces of `parts[i]` when the boxes are not exact).
    pub fn instances_in_boxes(
        &self,
        name: &str,
        boxes: &[Aabb],
        parts: &[Vec<usize>],
        transforms: &[Mat4],
    ) -> Symmetry {
        let in_boxes = SymmetryKind::Instances {
            instances: boxes
                .iter()
                .zip(transforms)
                .map(|(b, t)| SymmetryInstance { region: Region::aabb(*b), transform: *t })
                .collect(),
        };
        let faces = SymmetryKind::Instances {
            instances: parts
                .iter()
                .zip(transforms)
                .map(|(p, t)| SymmetryInstance { region: Region::Faces(self.asm.faces_of(p)), transform: *t })
                .collect(),
        };
        self.pick(name, vec![in_boxes, faces])
    }

    /// A group symmetry generated by `generators` acting on `parts` (`None`: the whole shape).
    /// `preferred` boxes are tried first, then the parts' box, then their faces.
    pub fn group(
        &self,
        name: &str,
        parts: Option<&[usize]>,
        preferred: Option<Aabb>,
        generators: Vec<Mat4>,
    ) -> Symmetry {
        let Some(parts) = parts else {
            return Symmetry {
                name: name.to_string(),
                kind: SymmetryKind::Group { region: Region::All, generators },
            };
        };
        let mut candidates = Vec::new();
        if let Some(b) = preferred {
            candidates.push(SymmetryKind::Group { region: Region::aabb(b), generators: generators.clone() });
        }
        candidates.push(SymmetryKind::Group {
            region: Region::aabb(self.asm.aabb_of(parts)),
            generators: generators.clone(),
        });
        candidates.push(SymmetryKind::Group { region: Region::Faces(self.asm.faces_of(parts)), generators });
        self.pick(name, candidates)
    }

    /// A class of repeated parts for the detection ground truth, with given boxes.
    pub fn class_in_boxes(&self, name: &str, boxes: &[Aabb], transforms: &[Mat4]) -> InstanceClass {
        InstanceClass {
            name: name.to_string(),
            instances: boxes
                .iter()
                .zip(transforms)
                .map(|(b, t)| Instance { bbox_min: b.min, bbox_max: b.max, transform: *t })
                .collect(),
        }
    }

    /// A class of repeated parts for the detection ground truth.
    pub fn class(&self, name: &str, parts: &[Vec<usize>], transforms: &[Mat4]) -> InstanceClass {
        InstanceClass {
            name: name.to_string(),
            instances: parts
                .iter()
                .zip(transforms)
                .map(|(p, t)| {
                    let b = self.asm.aabb_of(p);
                    Instance { bbox_min: b.min, bbox_max: b.max, transform: *t }
                })
                .collect(),
        }
    }
}

/// A closed box mesh `[min, max]` with every face subdivided: `subdivisions[k]` segments along axis
/// `k` (at least 1). Triangles are counter-clockwise seen from outside; vertices are shared, so the
/// mesh is watertight.
pub fn box_mesh(min: Point3, max: Point3, subdivisions: [usize; 3]) -> Result<TriMesh> {
    for k in 0..3 {
        if !(min[k].is_finite() && max[k].is_finite() && max[k] > min[k]) {
            return Err(Error::InvalidOption {
                name: "box",
                message: format!("max must exceed min on every axis, got {min:?} .. {max:?}"),
            });
        }
    }
    Ok(box_part(min, max, subdivisions.map(|n| n.max(1))))
}

/// A closed prism approximating a cylinder of `radius` about the z axis between `z0` and `z1`:
/// a regular polygon of `segments` corners (at least 3, corner 0 on the +x axis), caps fanned
/// around the axis, the side split into `rings` bands. Watertight, outward winding.
pub fn cylinder_mesh(radius: f64, z0: f64, z1: f64, segments: usize, rings: usize) -> Result<TriMesh> {
    check_positive("radius", radius)?;
    if !(z0.is_finite() && z1.is_finite() && z1 > z0) {
        return Err(Error::InvalidOption {
            name: "height",
            message: format!("need z1 > z0, got {z0} .. {z1}"),
        });
    }
    if segments < 3 {
        return Err(Error::InvalidOption {
            name: "segments",
            message: format!("need at least 3, got {segments}"),
        });
    }
    let outer: Vec<Point3> = (0..=segments)
        .map(|j| {
            let a = std::f64::consts::TAU * (j % segments) as f64 / segments as f64;
            [radius * a.cos(), radius * a.sin(), 0.0]
        })
        .collect();
    let inner = vec![[0.0; 3]; outer.len()];
    Ok(weld(profile_solid(&inner, &outer, [z0, z1], 1, rings.max(1), true, false)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_are_closed_and_outward() {
        let m = box_mesh([0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [2, 3, 4]).unwrap();
        let e = m.edge_stats();
        assert_eq!((e.boundary, e.non_manifold), (0, 0));
        assert!((TriMesh::signed_volume(&m) - 6.0).abs() < 1e-12);
        assert_eq!(m.degenerate_triangles(), 0);
        assert!(box_mesh([0.0; 3], [1.0, 0.0, 1.0], [1, 1, 1]).is_err());
    }

    #[test]
    fn cylinders_are_closed_and_outward() {
        let m = cylinder_mesh(1.0, -0.5, 0.5, 64, 2).unwrap();
        let e = m.edge_stats();
        assert_eq!((e.boundary, e.non_manifold), (0, 0));
        assert_eq!(m.degenerate_triangles(), 0);
        let exact = 0.5 * 64.0 * (std::f64::consts::TAU / 64.0).sin();
        assert!((TriMesh::signed_volume(&m) - exact).abs() < 1e-12);
    }

    #[test]
    fn orbit_of_a_half_box_is_a_closed_box() {
        let mut half = TriMesh::default();
        add_hexa(&mut half, &Hexa::axis_box([0.0, -1.0, -1.0], [1.0, 1.0, 1.0]), [2, 2, 2], &[Side::MinX]);
        let mirror = reflection([1.0, 0.0, 0.0], [0.0; 3]);
        let full = orbit(&half, &[crate::geometry::IDENTITY4, mirror]);
        let e = full.edge_stats();
        assert_eq!((e.boundary, e.non_manifold), (0, 0));
        assert!((TriMesh::signed_volume(&full) - 8.0).abs() < 1e-12);
        // Welded along the mirror seam: the surface points of a 5 × 3 × 3 grid (45 minus 3 inside).
        assert_eq!(full.num_vertices(), 42);
    }
}
