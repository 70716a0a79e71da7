//! Where everything goes: the facade grid, free-standing parts on the ground, clutter, the wall
//! with its openings, the ground, and the scanner positions.

use motif_core::TriMesh;
use motif_core::geometry::{Aabb, Mat4, Point3, mat4_from_rt, rotation_about_axis};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::elements::{self, Template, add_front_rect, add_rect, cuboid, cylinder, sphere};
use super::variation::Variation;
use super::{Placement, Scanning, SceneKind, SceneOptions, ScenePart, SceneSettings};
use crate::error::{DetectError, Result};

/// Bay width (horizontal pitch of the facade grid), metres.
pub(crate) const BAY: f64 = 2.9;
/// Number of bays.
const BAYS: usize = 7;
/// Ground-floor and upper-floor heights, metres.
const GROUND_FLOOR: f64 = 3.6;
/// Upper floor height (vertical pitch), metres.
pub(crate) const FLOOR: f64 = 3.2;
/// Wall above the top floor, metres.
const PARAPET: f64 = 0.6;
/// Bays of the doors on the ground floor, and of the balconies on odd floors.
const DOOR_BAYS: [usize; 2] = [1, 5];
const BALCONY_BAYS: [usize; 3] = [1, 3, 5];
/// Margin of ground around the facade (left and right), metres.
const SIDE_MARGIN: f64 = 3.0;

/// One placed building block.
#[derive(Debug, Clone)]
pub(crate) struct PlacedInstance {
    /// Index into [`Layout::templates`].
    pub class: usize,
    /// The rigid pose (translation and yaw), `world_from_local`.
    pub world_from_local: Mat4,
    /// The varied, placed geometry.
    pub mesh: TriMesh,
}

/// Everything of a scene before sampling.
#[derive(Debug, Clone)]
pub(crate) struct Layout {
    pub templates: Vec<Template>,
    pub instances: Vec<PlacedInstance>,
    /// Wall (front face, with the openings cut out) and ground; open surfaces seen from the
    /// street side.
    pub background: TriMesh,
    /// Clutter objects, each closed and outward.
    pub clutter: Vec<TriMesh>,
    pub scanners: Vec<Point3>,
}

/// `translation(p) · rotation_y(yaw)`.
fn pose(p: Point3, yaw: f64) -> Mat4 {
    mat4_from_rt(rotation_about_axis([0.0, 1.0, 0.0], yaw), p)
}

/// A uniform number in `[−1, 1]`.
fn sym(rng: &mut impl Rng) -> f64 {
    2.0 * rng.random::<f64>() - 1.0
}

/// Random streams of one scene, one per purpose so that changing one setting (say, the noise)
/// leaves the rest of the scene (the layout) as it was.
pub(crate) fn stream(seed: u64, purpose: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(purpose);
    rng
}

/// Stream purposes.
pub(crate) const LAYOUT: u64 = 1;
pub(crate) const VARIATION: u64 = 2;
pub(crate) const CLUTTER: u64 = 3;
pub(crate) const NOISE: u64 = 4;
pub(crate) const OUTLIERS: u64 = 5;
pub(crate) const ORDER: u64 = 6;

/// A request to place `template` at `world_from_local`.
struct Slot {
    class: usize,
    world_from_local: Mat4,
}

/// A free-standing object's footprint for collision tests: centre (x, z) and radius.
#[derive(Clone, Copy)]
struct Disc {
    x: f64,
    z: f64,
    r: f64,
}

fn overlaps(discs: &[Disc], d: Disc, gap: f64) -> bool {
    discs.iter().any(|o| (o.x - d.x).hypot(o.z - d.z) < o.r + d.r + gap)
}

/// Footprint radius of a ground template: half the diagonal of its box's x–z extent, counting only
/// what is below 2.5 m (a lamp post's arm overhangs cars).
fn footprint_radius(t: &Template) -> f64 {
    let mut r: f64 = 0.1;
    for p in &t.parts {
        for q in &p.mesh.positions {
            if q[1] < 2.5 {
                r = r.max(q[0].hypot(q[2]));
            }
        }
    }
    r
}

/// The facade's width and height for `floors` floors.
fn facade_size(floors: usize) -> (f64, f64) {
    (BAYS as f64 * BAY, GROUND_FLOOR + (floors - 1) as f64 * FLOOR + PARAPET)
}

/// Facade elements on the bay × floor grid (see the module documentation of `scenes`).
fn facade_slots(
    floors: usize,
    classes: &FacadeClasses,
    templates: &[Template],
    s: &SceneSettings,
    rng: &mut ChaCha8Rng,
) -> Vec<Slot> {
    let mut slots = Vec::new();
    for f in 0..floors {
        let base = if f == 0 { 0.0 } else { GROUND_FLOOR + (f - 1) as f64 * FLOOR };
        for b in 0..BAYS {
            let x = (b as f64 + 0.5) * BAY;
            let (class, y, with_balcony) = if f == 0 {
                if DOOR_BAYS.contains(&b) {
                    (classes.door, 0.0, false)
                } else {
                    (classes.window_c, 1.0 + 0.65, false)
                }
            } else if f % 2 == 1 {
                (classes.window_b, base + 0.15 + 1.1, BALCONY_BAYS.contains(&b))
            } else {
                (classes.window_a, base + 0.9 + 0.75, false)
            };
            let is_door = class == classes.door;
            let (mut dx, mut dy) = (0.0, 0.0);
            if s.placement == Placement::Irregular {
                // Draw everything every time so the layout of one cell does not depend on
                // whether an earlier one was dropped.
                let (u, v, keep) = (sym(rng), sym(rng), rng.random::<f64>());
                if !is_door && keep < s.drop_fraction {
                    continue;
                }
                // The element, grown by the largest variation (scale and part offsets), stays
                // inside its bay.
                let b = templates[class].bounds();
                let half =
                    b.min[0].abs().max(b.max[0]) * (1.0 + s.variation) + 0.1 * s.variation * b.diagonal();
                let room = (0.5 * BAY - half - 0.05).max(0.0);
                dx = (u * s.jitter * BAY).clamp(-room, room);
                // Doors stay on their step, on the ground.
                dy = if is_door { 0.0 } else { v * s.jitter * 0.4 * FLOOR };
            }
            slots.push(Slot { class, world_from_local: pose([x + dx, y + dy, 0.0], 0.0) });
            if with_balcony {
                // The balcony's slab top is the floor level, below its window.
                slots.push(Slot {
                    class: classes.balcony,
                    world_from_local: pose([x + dx, base + dy, 0.0], 0.0),
                });
            }
        }
    }
    slots
}

struct FacadeClasses {
    window_a: usize,
    window_b: usize,
    window_c: usize,
    balcony: usize,
    door: usize,
}

/// One row of free-standing objects of a class: how many, where (an x range and a z range), and
/// the yaw they face in a regular scene.
struct Row {
    class: usize,
    count: usize,
    x: [f64; 2],
    z: [f64; 2],
    yaw: f64,
    /// Cars: may face either way along the street in an irregular scene.
    flip: bool,
}

/// Places rows of free-standing objects: evenly spaced along each row's centre line (regular),
/// or at random non-overlapping positions in the row's rectangle with random yaw (irregular).
/// Objects that find no free spot after 400 tries are left out.
fn ground_slots(
    rows: &[Row],
    templates: &[Template],
    s: &SceneSettings,
    rng: &mut ChaCha8Rng,
    discs: &mut Vec<Disc>,
) -> Vec<Slot> {
    let mut slots = Vec::new();
    for row in rows {
        let r = footprint_radius(&templates[row.class]);
        for k in 0..row.count {
            match s.placement {
                Placement::Regular => {
                    let t = (k as f64 + 0.5) / row.count as f64;
                    let x = row.x[0] + t * (row.x[1] - row.x[0]);
                    let z = 0.5 * (row.z[0] + row.z[1]);
                    discs.push(Disc { x, z, r });
                    slots.push(Slot { class: row.class, world_from_local: pose([x, 0.0, z], row.yaw) });
                }
                Placement::Irregular => {
                    for _ in 0..400 {
                        let x = row.x[0] + rng.random::<f64>() * (row.x[1] - row.x[0]);
                        let z = row.z[0] + rng.random::<f64>() * (row.z[1] - row.z[0]);
                        let flip = if row.flip && rng.random::<bool>() { std::f64::consts::PI } else { 0.0 };
                        let yaw = row.yaw + flip + sym(rng) * s.yaw_spread_deg.to_radians();
                        let d = Disc { x, z, r };
                        if !overlaps(discs, d, 0.3) {
                            discs.push(d);
                            slots.push(Slot { class: row.class, world_from_local: pose([x, 0.0, z], yaw) });
                            break;
                        }
                    }
                }
            }
        }
    }
    slots
}

/// The wall's front face `[0, w] × [0, h]` at `z = 0` with rectangular `holes` cut out: the
/// rectangle is split at every hole edge and each band is covered by maximal runs of cells
/// outside the holes.
fn wall_with_holes(w: f64, h: f64, holes: &[[f64; 4]]) -> TriMesh {
    let clip = |v: f64, hi: f64| v.clamp(0.0, hi);
    let mut xs = vec![0.0, w];
    let mut ys = vec![0.0, h];
    for o in holes {
        xs.extend([clip(o[0], w), clip(o[2], w)]);
        ys.extend([clip(o[1], h), clip(o[3], h)]);
    }
    for v in [&mut xs, &mut ys] {
        v.sort_by(f64::total_cmp);
        v.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    }
    let mut mesh = TriMesh::default();
    for j in 0..ys.len() - 1 {
        let (y0, y1) = (ys[j], ys[j + 1]);
        let yc = 0.5 * (y0 + y1);
        let mut run: Option<f64> = None;
        for i in 0..xs.len() - 1 {
            let xc = 0.5 * (xs[i] + xs[i + 1]);
            let solid = !holes.iter().any(|o| xc > o[0] && xc < o[2] && yc > o[1] && yc < o[3]);
            match (solid, run) {
                (true, None) => run = Some(xs[i]),
                (false, Some(x0)) => {
                    add_front_rect(&mut mesh, [x0, y0, xs[i], y1], 0.0);
                    run = None;
                }
                _ => {}
            }
        }
        if let Some(x0) = run {
            add_front_rect(&mut mesh, [x0, y0, w, y1], 0.0);
        }
    }
    mesh
}

/// The ground `[x0, x1] × [z0, z1]` at `y = 0`, facing up.
fn ground(x: [f64; 2], z: [f64; 2]) -> TriMesh {
    let mut m = TriMesh::default();
    let n = |l: f64| ((l / 1.0).ceil() as usize).max(1);
    add_rect(
        &mut m,
        [x[0], 0.0, z[0]],
        [0.0, 0.0, z[1] - z[0]],
        [x[1] - x[0], 0.0, 0.0],
        n(z[1] - z[0]),
        n(x[1] - x[0]),
    );
    m
}

/// `count` scanners evenly spread along x over `[x0, x1]` at height `y`, depth `z`.
fn scanner_row(count: usize, x: [f64; 2], y: f64, z: f64) -> Vec<Point3> {
    (0..count).map(|i| [x[0] + (x[1] - x[0]) * (i as f64 + 0.5) / count as f64, y, z]).collect()
}

/// The templates of the user's parts (errors name the part).
fn part_templates(parts: &[ScenePart], size: f64) -> Result<Vec<Template>> {
    parts
        .iter()
        .map(|p| {
            elements::from_mesh(&p.name, &p.mesh, size).ok_or_else(|| DetectError::ScenePart {
                path: p.name.clone().into(),
                message: "the mesh has no finite, non-degenerate triangles".into(),
            })
        })
        .collect()
}

/// Clutter: `n` objects, half on the wall (when there is one) as boxes of 0.3–0.9 × 0.3–0.7 m
/// protruding 0.1–0.35 m (signs, air conditioners), the rest on the ground in `region` as boxes
/// (0.3–1.2 m, any yaw), spheres (radius 0.2–0.5 m) or poles (radius 4–10 cm, 1–3 m high),
/// never overlapping an instance's box, a free-standing part or a scanner.
fn clutter(
    n: usize,
    wall: Option<(f64, f64)>,
    region: ([f64; 2], [f64; 2]),
    instance_boxes: &[Aabb],
    discs: &mut Vec<Disc>,
    scanners: &[Point3],
    rng: &mut ChaCha8Rng,
) -> Result<Vec<TriMesh>> {
    let mut out = Vec::new();
    let mut wall_boxes: Vec<Aabb> = Vec::new();
    let n_wall = if wall.is_some() { n / 2 } else { 0 };
    let mut range = |lo: f64, hi: f64| lo + rng.random::<f64>() * (hi - lo);
    if let Some((w, h)) = wall {
        for _ in 0..n_wall {
            for _ in 0..100 {
                let (bw, bh, bd) = (range(0.3, 0.9), range(0.3, 0.7), range(0.1, 0.35));
                let (x, y) = (range(0.2, w - 0.2 - bw), range(0.5, h - 0.3 - bh));
                let b = Aabb { min: [x, y, 0.0], max: [x + bw, y + bh, bd] };
                let grown =
                    Aabb { min: [x - 0.1, y - 0.1, -1.0], max: [x + bw + 0.1, y + bh + 0.1, bd + 0.1] };
                if instance_boxes.iter().chain(&wall_boxes).any(|o| o.intersection(&grown).is_some()) {
                    continue;
                }
                wall_boxes.push(b);
                out.push(cuboid(b.min, b.max)?);
                break;
            }
        }
    }
    for _ in n_wall..n {
        for _ in 0..100 {
            let kind = range(0.0, 3.0);
            let (x, z) = (range(region.0[0], region.0[1]), range(region.1[0], region.1[1]));
            let (mesh, r) = if kind < 1.0 {
                let (a, b, c) = (range(0.3, 1.2), range(0.3, 1.2), range(0.3, 1.2));
                let mut m = cuboid([-0.5 * a, 0.0, -0.5 * c], [0.5 * a, b, 0.5 * c])?;
                m.transform(&pose([x, 0.0, z], range(0.0, std::f64::consts::TAU)));
                (m, 0.5 * a.hypot(c))
            } else if kind < 2.0 {
                let r = range(0.2, 0.5);
                (sphere([x, r, z], r, 20), r)
            } else {
                let (r, h) = (range(0.04, 0.1), range(1.0, 3.0));
                (cylinder(1, [x, 0.0, z], r, 0.0, h, 12)?, r)
            };
            let d = Disc { x, z, r };
            let near_scanner = scanners.iter().any(|s| (s[0] - x).hypot(s[2] - z) < r + 1.0);
            if overlaps(discs, d, 0.2) || near_scanner {
                continue;
            }
            discs.push(d);
            out.push(mesh);
            break;
        }
    }
    Ok(out)
}

/// Lays out a scene of `kind`.
pub(crate) fn layout(
    kind: SceneKind,
    options: &SceneOptions,
    s: &SceneSettings,
    parts: &[ScenePart],
) -> Result<Layout> {
    let mut rng = stream(options.seed, LAYOUT);
    let mut templates: Vec<Template> = Vec::new();
    let add = |t: Template, templates: &mut Vec<Template>| {
        templates.push(t);
        templates.len() - 1
    };
    let mut slots: Vec<Slot> = Vec::new();
    let mut discs: Vec<Disc> = Vec::new();
    let user = part_templates(parts, options.part_size)?;

    let (wall, ground_x, ground_z, scanners, clutter_region);
    match kind {
        SceneKind::Facade | SceneKind::Street => {
            let floors = if kind == SceneKind::Facade { 5 } else { 4 };
            let classes = FacadeClasses {
                window_a: add(elements::window_a()?, &mut templates),
                window_b: add(elements::window_b()?, &mut templates),
                window_c: add(elements::window_c()?, &mut templates),
                balcony: add(elements::balcony()?, &mut templates),
                door: add(elements::door()?, &mut templates),
            };
            slots.extend(facade_slots(floors, &classes, &templates, s, &mut rng));
            let (w, h) = facade_size(floors);
            wall = Some((w, h));
            ground_x = [-SIDE_MARGIN, w + SIDE_MARGIN];
            let mut rows = Vec::new();
            let (x_row, x_wide) = ([0.0, w], [-SIDE_MARGIN + 0.5, w + SIDE_MARGIN - 0.5]);
            if kind == SceneKind::Facade {
                ground_z = [0.0, 6.0];
                scanners = match s.scanning {
                    Scanning::Complete => Vec::new(),
                    Scanning::Scanners { count } => scanner_row(count, [0.0, w], 1.8, 10.0),
                };
                clutter_region = (x_wide, [0.5, 5.5]);
                for (i, t) in user.into_iter().enumerate() {
                    let z = 1.5 + 2.0 * (i % 2) as f64;
                    let class = add(t, &mut templates);
                    rows.push(Row {
                        class,
                        count: options.part_instances,
                        x: x_row,
                        z: [z - 0.8, z + 0.8],
                        yaw: 0.0,
                        flip: false,
                    });
                }
            } else {
                ground_z = [0.0, 14.0];
                scanners = match s.scanning {
                    Scanning::Complete => Vec::new(),
                    Scanning::Scanners { count } => scanner_row(count, [0.0, w], 2.2, 9.0),
                };
                clutter_region = (x_wide, [0.5, 13.5]);
                let lamp = add(elements::lamp_post()?, &mut templates);
                let bin = add(elements::bin()?, &mut templates);
                let car = add(elements::car()?, &mut templates);
                let half_pi = std::f64::consts::FRAC_PI_2;
                rows.push(Row { class: lamp, count: 5, x: x_row, z: [2.5, 3.0], yaw: -half_pi, flip: false });
                rows.push(Row { class: bin, count: 6, x: x_row, z: [0.6, 1.8], yaw: 0.0, flip: false });
                rows.push(Row { class: car, count: 4, x: x_wide, z: [4.0, 5.4], yaw: 0.0, flip: true });
                rows.push(Row { class: car, count: 4, x: x_wide, z: [11.6, 13.0], yaw: 0.0, flip: true });
                for t in user {
                    let class = add(t, &mut templates);
                    rows.push(Row {
                        class,
                        count: options.part_instances,
                        x: x_row,
                        z: [6.0, 7.6],
                        yaw: 0.0,
                        flip: false,
                    });
                }
            }
            slots.extend(ground_slots(&rows, &templates, s, &mut rng, &mut discs));
        }
        SceneKind::Parts => {
            let user = if user.is_empty() {
                vec![elements::car()?, elements::bin()?, elements::lamp_post()?]
            } else {
                user
            };
            let n = options.part_instances;
            // Each class gets a row as wide as its objects need; the ground fits the rows.
            let widths: Vec<f64> = user.iter().map(|t| 2.0 * footprint_radius(t) + 0.8).collect();
            let len = widths.iter().map(|w| w * n as f64).fold(20.0, f64::max);
            let depth: f64 = widths.iter().sum::<f64>() + 2.0;
            let mut rows = Vec::new();
            let mut z = 1.0;
            for (t, w) in user.into_iter().zip(&widths) {
                let class = add(t, &mut templates);
                rows.push(Row { class, count: n, x: [1.0, len + 1.0], z: [z, z + w], yaw: 0.0, flip: false });
                z += w;
            }
            // Irregular scenes scatter the parts over the whole ground, not in rows, keeping
            // each one on the ground.
            if s.placement == Placement::Irregular {
                for r in &mut rows {
                    let rad = footprint_radius(&templates[r.class]) + 0.3;
                    r.x = [rad, (len + 2.0 - rad).max(rad)];
                    r.z = [rad, (depth - rad).max(rad)];
                }
            }
            slots.extend(ground_slots(&rows, &templates, s, &mut rng, &mut discs));
            wall = None;
            ground_x = [0.0, len + 2.0];
            ground_z = [0.0, depth];
            scanners = match s.scanning {
                Scanning::Complete => Vec::new(),
                Scanning::Scanners { count } => scanner_row(count, ground_x, 2.0, depth + 6.0),
            };
            clutter_region = (ground_x, [0.5, depth - 0.5]);
        }
    }

    let mut vrng = stream(options.seed, VARIATION);
    let mut instances = Vec::with_capacity(slots.len());
    let mut holes = Vec::new();
    for slot in &slots {
        let t = &templates[slot.class];
        let var = Variation::draw(t, s.variation, &mut vrng);
        if let Some(o) = var.opening(t) {
            let (x, y) = (slot.world_from_local[0][3], slot.world_from_local[1][3]);
            holes.push([o[0] + x, o[1] + y, o[2] + x, o[3] + y]);
        }
        let mesh = var.apply(t, &slot.world_from_local);
        instances.push(PlacedInstance { class: slot.class, world_from_local: slot.world_from_local, mesh });
    }
    let boxes: Vec<Aabb> = instances.iter().filter_map(|i| i.mesh.aabb()).collect();
    let mut crng = stream(options.seed, CLUTTER);
    let clutter = clutter(s.clutter_objects, wall, clutter_region, &boxes, &mut discs, &scanners, &mut crng)?;

    let mut background = ground(ground_x, ground_z);
    if let Some((w, h)) = wall {
        background.append(&wall_with_holes(w, h, &holes));
    }
    // Templates of classes that got no instance (all left out) are dropped with their classes.
    let used: Vec<bool> = (0..templates.len()).map(|c| instances.iter().any(|i| i.class == c)).collect();
    if used.iter().any(|u| !u) {
        let mut map = vec![usize::MAX; templates.len()];
        let mut kept = Vec::new();
        for (c, t) in templates.into_iter().enumerate() {
            if used[c] {
                map[c] = kept.len();
                kept.push(t);
            }
        }
        templates = kept;
        for i in &mut instances {
            i.class = map[i.class];
        }
    }
    Ok(Layout { templates, instances, background, clutter, scanners })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wall_area_is_the_rectangle_minus_the_holes() {
        let holes = [[1.0, 1.0, 2.0, 3.0], [4.0, 0.5, 5.0, 1.5], [1.5, 4.0, 4.5, 4.5]];
        let m = wall_with_holes(6.0, 5.0, &holes);
        let holes_area: f64 = holes.iter().map(|o| (o[2] - o[0]) * (o[3] - o[1])).sum();
        assert!((m.area() - (30.0 - holes_area)).abs() < 1e-9, "{}", m.area());
        assert!(m.face_normals().iter().all(|n| (n[2] - 1.0).abs() < 1e-12));
    }

    #[test]
    fn ground_faces_up() {
        let g = ground([0.0, 3.0], [0.0, 2.0]);
        assert!((g.area() - 6.0).abs() < 1e-12);
        assert!(g.face_normals().iter().all(|n| (n[1] - 1.0).abs() < 1e-12));
    }
}
