//! The building blocks of the benchmark scenes: facade elements (three window styles, a door, a
//! balcony), free-standing street furniture (a car, a wheelie bin, a lamp post) and real meshes
//! given by the user, each as a template of closed, outward-wound parts in its own local frame.
//!
//! Local frames (metres, y up): wall elements have the centre of their opening (the balcony: the
//! top of its slab) at the origin on the wall plane `z = 0`, protruding towards `+z`; free-standing
//! parts stand on the ground `y = 0` with their footprint centred on the origin, the long axis
//! along x.

use motif_core::geometry::{Aabb, Mat4, Point3, add, scale};
use motif_core::procedural::{box_mesh, cylinder_mesh};
use motif_core::{Result as CoreResult, TriMesh};

/// Where a template is attached in a scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Mount {
    /// On the facade, facing the street; never rotated.
    Wall,
    /// On the ground; rotated about the up axis in irregular scenes.
    Ground,
}

/// One closed part of a template.
#[derive(Debug, Clone)]
pub(crate) struct TemplatePart {
    pub mesh: TriMesh,
    /// Whether the per-instance variation may shift this part on its own ("part-wise offsets").
    pub movable: bool,
}

/// A building block in its local frame.
#[derive(Debug, Clone)]
pub(crate) struct Template {
    /// Class name in the ground truth (`window_a`, `car`, or a part file's stem).
    pub name: String,
    pub parts: Vec<TemplatePart>,
    pub mount: Mount,
    /// The hole the element needs in the wall, `[x0, y0, x1, y1]` in its local frame.
    pub opening: Option<[f64; 4]>,
    /// Whether the parts are closed and outward-wound, so a sample whose face points away from a
    /// scanner is hidden by its own part (back-face culling). False for user meshes, whose
    /// orientation is unknown: their visibility is decided by ray casting alone.
    pub outward: bool,
}

impl Template {
    /// The box around all parts.
    pub fn bounds(&self) -> Aabb {
        let corners: Vec<_> =
            self.parts.iter().filter_map(|p| p.mesh.aabb()).flat_map(|b| [b.min, b.max]).collect();
        Aabb::from_points(&corners).unwrap_or(Aabb { min: [0.0; 3], max: [0.0; 3] })
    }
}

/// Segments for an edge of length `len`: about one per 25 cm, so smooth deformations (bend,
/// twist) bend the parts instead of only moving their corners.
fn segs(len: f64) -> usize {
    ((len / 0.25).ceil() as usize).clamp(1, 64)
}

/// A closed subdivided box `[min, max]`.
pub(crate) fn cuboid(min: Point3, max: Point3) -> CoreResult<TriMesh> {
    box_mesh(min, max, [segs(max[0] - min[0]), segs(max[1] - min[1]), segs(max[2] - min[2])])
}

/// Appends the parallelogram `origin + s·u + t·v`, `(s, t) ∈ [0,1]²`, subdivided `nu × nv`, facing
/// `u × v`.
pub(crate) fn add_rect(mesh: &mut TriMesh, origin: Point3, u: Point3, v: Point3, nu: usize, nv: usize) {
    let (nu, nv) = (nu.max(1), nv.max(1));
    let base = mesh.positions.len() as u32;
    for i in 0..=nu {
        for j in 0..=nv {
            let p = add(origin, add(scale(u, i as f64 / nu as f64), scale(v, j as f64 / nv as f64)));
            mesh.positions.push(p);
        }
    }
    let idx = |i: usize, j: usize| base + (i * (nv + 1) + j) as u32;
    for i in 0..nu {
        for j in 0..nv {
            mesh.triangles.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
            mesh.triangles.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
        }
    }
}

/// An axis-aligned rectangle `[x0, y0, x1, y1]` in the plane `z`, facing `+z`.
pub(crate) fn add_front_rect(mesh: &mut TriMesh, r: [f64; 4], z: f64) {
    let (w, h) = (r[2] - r[0], r[3] - r[1]);
    if w > 0.0 && h > 0.0 {
        add_rect(mesh, [r[0], r[1], z], [w, 0.0, 0.0], [0.0, h, 0.0], segs(w), segs(h));
    }
}

/// The recess behind an opening `[x0, y0, x1, y1]` in the wall plane, `depth` deep: four side
/// walls facing into the opening and the back pane facing `+z`. Open towards the street, so not a
/// closed part, but every face is seen from the street side only (culling is still exact).
fn recess(o: [f64; 4], depth: f64) -> TriMesh {
    let mut m = TriMesh::default();
    let (w, h) = (o[2] - o[0], o[3] - o[1]);
    let d = [0.0, 0.0, depth];
    let nd = segs(depth);
    // Left wall faces +x: u = +y, v = +z.
    add_rect(&mut m, [o[0], o[1], -depth], [0.0, h, 0.0], d, segs(h), nd);
    // Right wall faces −x: u = +z, v = +y.
    add_rect(&mut m, [o[2], o[1], -depth], d, [0.0, h, 0.0], nd, segs(h));
    // Bottom faces +y: u = +z, v = +x.
    add_rect(&mut m, [o[0], o[1], -depth], d, [w, 0.0, 0.0], nd, segs(w));
    // Top faces −y: u = +x, v = +z.
    add_rect(&mut m, [o[0], o[3], -depth], [w, 0.0, 0.0], d, segs(w), nd);
    add_front_rect(&mut m, o, -depth);
    m
}

/// `cylinder_mesh` (about z) turned so its axis is y: `(x, y, z) ↦ (x, z, −y)`, a proper rotation.
const Z_TO_Y: Mat4 =
    [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
/// Turns the z axis into the x axis: `(x, y, z) ↦ (z, y, −x)`, a proper rotation about y.
const Z_TO_X: Mat4 =
    [[0.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]];

/// A closed cylinder of `radius` along `axis` (0 = x, 1 = y, 2 = z) from `a` to `b` on that axis,
/// centred on `center` in the other two coordinates.
pub(crate) fn cylinder(
    axis: usize,
    center: Point3,
    radius: f64,
    a: f64,
    b: f64,
    segments: usize,
) -> CoreResult<TriMesh> {
    let mut m = cylinder_mesh(radius, a, b, segments, segs(b - a))?;
    match axis {
        0 => m.transform(&Z_TO_X),
        1 => m.transform(&Z_TO_Y),
        _ => {}
    }
    let mut shift = center;
    shift[axis] = 0.0;
    for p in &mut m.positions {
        *p = add(*p, shift);
    }
    Ok(m)
}

/// A closed UV sphere of `radius` about `center`, `n` segments around, `n / 2` rings.
pub(crate) fn sphere(center: Point3, radius: f64, n: usize) -> TriMesh {
    let (nu, nv) = (n.max(6), (n / 2).max(3));
    let mut m = TriMesh::default();
    m.positions.push(add(center, [0.0, radius, 0.0]));
    for j in 1..nv {
        let th = std::f64::consts::PI * j as f64 / nv as f64;
        for i in 0..nu {
            let ph = std::f64::consts::TAU * i as f64 / nu as f64;
            m.positions.push(add(
                center,
                [radius * th.sin() * ph.cos(), radius * th.cos(), -radius * th.sin() * ph.sin()],
            ));
        }
    }
    m.positions.push(add(center, [0.0, -radius, 0.0]));
    let ring = |j: usize, i: usize| (1 + (j - 1) * nu + i % nu) as u32;
    let south = (m.positions.len() - 1) as u32;
    for i in 0..nu {
        m.triangles.push([0, ring(1, i), ring(1, i + 1)]);
        for j in 1..nv - 1 {
            m.triangles.push([ring(j, i), ring(j + 1, i), ring(j + 1, i + 1)]);
            m.triangles.push([ring(j, i), ring(j + 1, i + 1), ring(j, i + 1)]);
        }
        m.triangles.push([ring(nv - 1, i), south, ring(nv - 1, i + 1)]);
    }
    m
}

fn part(mesh: TriMesh, movable: bool) -> TemplatePart {
    TemplatePart { mesh, movable }
}

fn fixed(mesh: CoreResult<TriMesh>) -> CoreResult<TemplatePart> {
    Ok(part(mesh?, false))
}

fn movable(mesh: CoreResult<TriMesh>) -> CoreResult<TemplatePart> {
    Ok(part(mesh?, true))
}

/// Frame width and its protrusion from the wall, metres.
const FRAME: f64 = 0.1;
const FRAME_DEPTH: f64 = 0.08;

/// Frame boxes around an opening `[−w, −h] .. [w, h]` (half sizes); `with_bottom` adds the lower
/// bar (doors have none).
fn frame(w: f64, h: f64, with_bottom: bool) -> CoreResult<Vec<TemplatePart>> {
    let (f, fd) = (FRAME, FRAME_DEPTH);
    let bottom = if with_bottom { -h - f } else { -h };
    let mut v = vec![
        fixed(cuboid([-w - f, bottom, 0.0], [-w, h + f, fd]))?,
        fixed(cuboid([w, bottom, 0.0], [w + f, h + f, fd]))?,
        fixed(cuboid([-w, h, 0.0], [w, h + f, fd]))?,
    ];
    if with_bottom {
        v.push(fixed(cuboid([-w, -h - f, 0.0], [w, -h, fd]))?);
    }
    Ok(v)
}

/// Window style A: a 1.2 × 1.5 m opening, 20 cm recess, frame, a wide sill, a cross of glazing
/// bars (mullion and transom) in the recess.
pub(crate) fn window_a() -> CoreResult<Template> {
    let (w, h, d) = (0.6, 0.75, 0.2);
    let mut parts = vec![part(recess([-w, -h, w, h], d), false)];
    parts.extend(frame(w, h, true)?);
    parts.push(movable(cuboid([-w - 0.2, -h - FRAME - 0.08, 0.0], [w + 0.2, -h - FRAME, 0.22]))?);
    parts.push(fixed(cuboid([-0.03, -h, -d], [0.03, h, -d + 0.06]))?);
    parts.push(fixed(cuboid([-w, 0.2 - 0.03, -d], [w, 0.2 + 0.03, -d + 0.06]))?);
    Ok(Template {
        name: "window_a".into(),
        parts,
        mount: Mount::Wall,
        opening: Some([-w, -h, w, h]),
        outward: true,
    })
}

/// Window style B: a tall French window (1.0 × 2.2 m) with a cornice and a keystone above the
/// frame, a mullion and two transoms in the recess.
pub(crate) fn window_b() -> CoreResult<Template> {
    let (w, h, d) = (0.5, 1.1, 0.2);
    let mut parts = vec![part(recess([-w, -h, w, h], d), false)];
    parts.extend(frame(w, h, true)?);
    let top = h + FRAME;
    parts.push(movable(cuboid([-w - 0.25, top, 0.0], [w + 0.25, top + 0.16, 0.18]))?);
    parts.push(movable(cuboid([-0.09, top - 0.22, FRAME_DEPTH], [0.09, top, 0.14]))?);
    parts.push(fixed(cuboid([-0.03, -h, -d], [0.03, h, -d + 0.06]))?);
    for y in [-0.35, 0.45] {
        parts.push(fixed(cuboid([-w, y - 0.03, -d], [w, y + 0.03, -d + 0.06]))?);
    }
    Ok(Template {
        name: "window_b".into(),
        parts,
        mount: Mount::Wall,
        opening: Some([-w, -h, w, h]),
        outward: true,
    })
}

/// Window style C (ground floor): a 1.2 × 1.3 m opening with two open shutters flat against the
/// wall, each with four battens.
pub(crate) fn window_c() -> CoreResult<Template> {
    let (w, h, d) = (0.6, 0.65, 0.15);
    let mut parts = vec![part(recess([-w, -h, w, h], d), false)];
    parts.extend(frame(w, h, true)?);
    let sw = 0.45;
    for side in [-1.0, 1.0] {
        let (x0, x1) = if side < 0.0 { (-w - FRAME - sw, -w - FRAME) } else { (w + FRAME, w + FRAME + sw) };
        let mut shutter = cuboid([x0, -h, 0.0], [x1, h, 0.04])?;
        for k in 0..4 {
            let y = -h + 0.2 + k as f64 * (2.0 * h - 0.4) / 3.0;
            shutter.append(&cuboid([x0 + 0.05, y - 0.03, 0.04], [x1 - 0.05, y + 0.03, 0.07])?);
        }
        parts.push(part(shutter, true));
    }
    parts.push(fixed(cuboid([-0.03, -h, -d], [0.03, h, -d + 0.05]))?);
    Ok(Template {
        name: "window_c".into(),
        parts,
        mount: Mount::Wall,
        opening: Some([-w, -h, w, h]),
        outward: true,
    })
}

/// Height of the door's step; the door opening starts on top of it.
const DOOR_STEP: f64 = 0.15;

/// A 1.1 × 2.3 m door in a 25 cm recess, with frame (no bottom bar), a transom bar, a handle and a
/// step in front. Unlike the windows, its origin is on the ground (under the opening's centre).
pub(crate) fn door() -> CoreResult<Template> {
    let (w, h, d) = (0.55, 1.15, 0.25);
    let mut parts = vec![part(recess([-w, -h, w, h], d), false)];
    parts.extend(frame(w, h, false)?);
    parts.push(fixed(cuboid([-w, 0.6, -d], [w, 0.66, -d + 0.06]))?);
    parts.push(movable(cuboid([0.3, -0.1, -d], [0.36, 0.0, -d + 0.08]))?);
    parts.push(fixed(cuboid([-w - FRAME - 0.2, -h - DOOR_STEP, 0.0], [w + FRAME + 0.2, -h, 0.45]))?);
    // The origin goes to the ground below the opening's centre, so that the variation's scaling
    // (about the origin) keeps the step on the ground.
    let lift = h + DOOR_STEP;
    for p in &mut parts {
        for q in &mut p.mesh.positions {
            q[1] += lift;
        }
    }
    Ok(Template {
        name: "door".into(),
        parts,
        mount: Mount::Wall,
        opening: Some([-w, DOOR_STEP, w, DOOR_STEP + 2.0 * h]),
        outward: true,
    })
}

/// A balcony: a 2.0 × 1.0 m slab 15 cm thick whose top is the origin's level, 17 round posts 1 m
/// high, a top rail along the front and the sides.
pub(crate) fn balcony() -> CoreResult<Template> {
    let (w, depth) = (1.0, 1.0);
    let mut parts = vec![fixed(cuboid([-w, -0.15, 0.0], [w, 0.0, depth]))?];
    let mut posts = TriMesh::default();
    for k in 0..11 {
        let x = -0.95 + 0.19 * k as f64;
        posts.append(&cylinder(1, [x, 0.0, 0.95], 0.025, 0.0, 1.0, 8)?);
    }
    for x in [-0.95, 0.95] {
        for z in [0.2, 0.45, 0.7] {
            posts.append(&cylinder(1, [x, 0.0, z], 0.025, 0.0, 1.0, 8)?);
        }
    }
    parts.push(part(posts, false));
    parts.push(movable(cuboid([-w, 1.0, 0.91], [w, 1.06, 0.99]))?);
    parts.push(movable(cuboid([-w, 1.0, 0.0], [-w + 0.08, 1.06, 0.91]))?);
    parts.push(movable(cuboid([w - 0.08, 1.0, 0.0], [w, 1.06, 0.91]))?);
    Ok(Template { name: "balcony".into(), parts, mount: Mount::Wall, opening: None, outward: true })
}

/// A car 4.4 m long (x), 1.8 m wide (z), 1.5 m high: body, cabin, four wheels, bumpers and mirrors.
pub(crate) fn car() -> CoreResult<Template> {
    let mut parts = vec![
        fixed(cuboid([-2.1, 0.3, -0.9], [2.1, 1.0, 0.9]))?,
        fixed(cuboid([-1.1, 1.0, -0.8], [0.9, 1.5, 0.8]))?,
        movable(cuboid([2.1, 0.35, -0.85], [2.2, 0.55, 0.85]))?,
        movable(cuboid([-2.2, 0.35, -0.85], [-2.1, 0.55, 0.85]))?,
    ];
    for x in [-1.35, 1.35] {
        parts.push(fixed(cylinder(2, [x, 0.33, 0.0], 0.33, 0.7, 0.92, 16))?);
        parts.push(fixed(cylinder(2, [x, 0.33, 0.0], 0.33, -0.92, -0.7, 16))?);
    }
    for s in [-1.0, 1.0] {
        let (z0, z1) = if s < 0.0 { (-1.05, -0.9) } else { (0.9, 1.05) };
        parts.push(movable(cuboid([0.75, 1.0, z0], [0.9, 1.12, z1]))?);
    }
    Ok(Template { name: "car".into(), parts, mount: Mount::Ground, opening: None, outward: true })
}

/// A wheelie bin 0.6 × 1.06 × 0.76 m: body, overhanging lid, a handle bar at the back and two
/// small wheels.
pub(crate) fn bin() -> CoreResult<Template> {
    let mut parts = vec![
        fixed(cuboid([-0.3, 0.08, -0.35], [0.3, 1.0, 0.35]))?,
        movable(cuboid([-0.33, 1.0, -0.38], [0.33, 1.06, 0.38]))?,
        movable(cuboid([-0.28, 0.9, -0.45], [0.28, 0.96, -0.35]))?,
    ];
    for (a, b) in [(-0.3, -0.22), (0.22, 0.3)] {
        parts.push(fixed(cylinder(0, [0.0, 0.08, -0.3], 0.08, a, b, 10))?);
    }
    Ok(Template { name: "bin".into(), parts, mount: Mount::Ground, opening: None, outward: true })
}

/// A lamp post 5 m high: a base block, a round pole, an arm along +x and a lamp head.
pub(crate) fn lamp_post() -> CoreResult<Template> {
    let parts = vec![
        fixed(cuboid([-0.2, 0.0, -0.2], [0.2, 0.5, 0.2]))?,
        fixed(cylinder(1, [0.0, 0.0, 0.0], 0.07, 0.5, 5.0, 12))?,
        fixed(cuboid([0.05, 4.8, -0.04], [1.2, 4.9, 0.04]))?,
        movable(cuboid([1.0, 4.6, -0.15], [1.5, 4.8, 0.15]))?,
    ];
    Ok(Template { name: "lamp_post".into(), parts, mount: Mount::Ground, opening: None, outward: true })
}

/// A user mesh as a free-standing template: scaled uniformly so its bounding-box diagonal is
/// `size` metres, its footprint centred on the origin and its lowest point on the ground. Its up
/// axis is taken to be y (Motif's convention). One part, not movable.
pub(crate) fn from_mesh(name: &str, mesh: &TriMesh, size: f64) -> Option<Template> {
    let b = mesh.aabb()?;
    let diag = b.diagonal();
    if !(diag > 0.0 && diag.is_finite()) {
        return None;
    }
    let s = size / diag;
    let c = b.center();
    let mut m = mesh.clone();
    for p in &mut m.positions {
        *p = [(p[0] - c[0]) * s, (p[1] - b.min[1]) * s, (p[2] - c[2]) * s];
    }
    m.remove_degenerate_triangles();
    if m.triangles.is_empty() {
        return None;
    }
    Some(Template {
        name: name.to_string(),
        parts: vec![part(m, false)],
        mount: Mount::Ground,
        opening: None,
        outward: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use motif_core::geometry::dot;

    #[test]
    fn primitives_are_closed_and_outward() {
        let s = sphere([1.0, 2.0, 3.0], 0.5, 24);
        let e = s.edge_stats();
        assert_eq!((e.boundary, e.non_manifold), (0, 0));
        let v = TriMesh::signed_volume(&s);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.125;
        assert!(v > 0.9 * exact && v < exact, "{v} vs {exact}");
        for axis in 0..3 {
            let c = cylinder(axis, [0.5, 0.5, 0.5], 0.2, 1.0, 2.0, 12).unwrap();
            assert!(TriMesh::signed_volume(&c) > 0.0, "axis {axis}");
            let b = c.aabb().unwrap();
            assert!((b.min[axis] - 1.0).abs() < 1e-12 && (b.max[axis] - 2.0).abs() < 1e-12);
        }
    }

    #[test]
    fn recess_faces_point_into_the_opening() {
        let r = recess([-1.0, -1.0, 1.0, 1.0], 0.5);
        for f in 0..r.num_triangles() {
            let [a, b, c] = r.corners(f);
            let centre = scale(add(add(a, b), c), 1.0 / 3.0);
            // Every face looks towards the point in front of the opening.
            let to_viewer = motif_core::geometry::sub([0.0, 0.0, 5.0], centre);
            assert!(dot(r.face_normals()[f], to_viewer) > 0.0, "face {f}");
        }
    }

    #[test]
    fn templates_have_outward_parts() {
        for t in [window_a(), window_b(), window_c(), door(), balcony(), car(), bin(), lamp_post()] {
            let t = t.unwrap();
            for (i, p) in t.parts.iter().enumerate() {
                let e = p.mesh.edge_stats();
                if e.boundary == 0 {
                    assert!(TriMesh::signed_volume(&p.mesh) > 0.0, "{} part {i}", t.name);
                }
            }
        }
    }
}
