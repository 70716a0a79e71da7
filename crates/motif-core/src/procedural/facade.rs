//! A building facade: a wall slab with a grid of bays × floors, recessed windows of two styles and
//! a door on the ground floor. Windows are geometry, not texture: each has a recess into the wall
//! (side walls and a back pane), a protruding frame, and a sill (style A) or a lintel and a mullion
//! (style B); the door has a frame, a handle and a front step.
//!
//! The wall's front face is tiled per bay: a ring from the bay's rectangle to a *collar* rectangle
//! that belongs to the window template, then the collar from there to the opening. Bay edges are
//! subdivided the same way everywhere, so the wall is watertight even when bays have different
//! sizes, and every window (collar, recess and parts) is an exact translate of its template.
//! Coordinates: x right, y up, the wall's front face at `z = 0`, the wall behind it (`z < 0`).

use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::geometry::{Aabb, Point3};
use crate::mesh::TriMesh;
use crate::procedural::Example;
use crate::procedural::primitives::{
    Annotator, Assembly, add_quad, box_part, check_positive, check_resolution, weld,
};
use crate::procedural::structure::{Structure, SymmetryAnnotation, translation};
use crate::{Error, Result};

/// How bays and floors are spaced.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FacadeSpacing {
    /// All bays `bay_width` wide, all floors `floor_height` high: a lattice.
    Regular,
    /// Every inner bay boundary and floor boundary moved by a uniform random amount in
    /// `[−amount, amount] ×` the bay width (floor height), drawn from the seed; no lattice.
    Jittered {
        /// Largest shift as a fraction of the bay width / floor height, 0 to 0.25.
        amount: f64,
    },
}

/// Which windows get which style.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WindowLayout {
    /// Style A on even floors (the ground floor is floor 0), style B on odd floors.
    AlternateFloors,
    /// Style A in even bays (from the left), style B in odd bays.
    AlternateColumns,
}

/// Options of [`facade`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FacadeOptions {
    /// Number of bays (window columns); 1 to 200, default 5.
    pub columns: usize,
    /// Number of floors; 1 to 200, default 4.
    pub floors: usize,
    /// Nominal bay width (horizontal lattice pitch), metres; default 3.
    pub bay_width: f64,
    /// Nominal floor height (vertical lattice pitch), metres; default 3.2.
    pub floor_height: f64,
    /// Wall thickness, metres; must exceed the recess depth; default 0.4.
    pub wall_thickness: f64,
    /// Depth of the window and door recesses (from the front face to the pane), metres; default 0.15.
    pub recess_depth: f64,
    /// Opening `[width, height]` of style-A windows (with sill), metres; default `[1.2, 1.5]`.
    pub window_a_size: [f64; 2],
    /// Opening `[width, height]` of style-B windows (with lintel and mullion), metres; default
    /// `[0.9, 1.8]`.
    pub window_b_size: [f64; 2],
    /// Door opening `[width, height]`, metres; default `[1.1, 2.2]`.
    pub door_size: [f64; 2],
    /// Bay of the door on the ground floor (0 = leftmost); default 2 (the middle of 5).
    pub door_column: usize,
    /// Which windows get which style; default alternate floors.
    pub layout: WindowLayout,
    /// Regular (a lattice) or jittered spacing; default regular.
    pub spacing: FacadeSpacing,
    /// Seed of the jitter (ignored for regular spacing); default 0.
    pub seed: u64,
    /// Subdivision multiplier of the whole tessellation; default 1.
    pub resolution: usize,
}

impl Default for FacadeOptions {
    fn default() -> Self {
        FacadeOptions {
            columns: 5,
            floors: 4,
            bay_width: 3.0,
            floor_height: 3.2,
            wall_thickness: 0.4,
            recess_depth: 0.15,
            window_a_size: [1.2, 1.5],
            window_b_size: [0.9, 1.8],
            door_size: [1.1, 2.2],
            door_column: 2,
            layout: WindowLayout::AlternateFloors,
            spacing: FacadeSpacing::Regular,
            seed: 0,
            resolution: 1,
        }
    }
}

impl FacadeOptions {
    /// The default facade with jittered bays and floors (amount 0.08).
    pub fn irregular() -> Self {
        FacadeOptions { spacing: FacadeSpacing::Jittered { amount: 0.08 }, ..Default::default() }
    }
}

/// Frame width and depth (protrusion from the wall), metres.
const FRAME_WIDTH: f64 = 0.08;
const FRAME_DEPTH: f64 = 0.06;
/// Gap between the window parts and the collar rectangle, metres.
const COLLAR_MARGIN: f64 = 0.05;
/// Height of the door's front step (the door opening starts on top of it), metres.
const STEP_HEIGHT: f64 = 0.15;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Style {
    A,
    B,
    Door,
}

/// A window template centred on its opening: the opening's half-size, the boxes of its parts
/// (relative to the opening's centre on the wall's front face), the collar rectangle and the
/// template's full box.
struct Template {
    half: [f64; 2],
    parts: Vec<(Point3, Point3)>,
    collar: [f64; 4],
    bounds: Aabb,
}

fn template(style: Style, size: [f64; 2], recess: f64) -> Template {
    let (w, h) = (0.5 * size[0], 0.5 * size[1]);
    let (f, fd) = (FRAME_WIDTH, FRAME_DEPTH);
    let bottom = if style == Style::Door { -h } else { -h - f };
    let mut parts = vec![
        ([-w - f, bottom, 0.0], [-w, h + f, fd]),
        ([w, bottom, 0.0], [w + f, h + f, fd]),
        ([-w, h, 0.0], [w, h + f, fd]),
    ];
    match style {
        Style::A => {
            parts.push(([-w, -h - f, 0.0], [w, -h, fd]));
            parts.push(([-w - f - 0.05, -h - f - 0.06, 0.0], [w + f + 0.05, -h - f, 0.14]));
        }
        Style::B => {
            parts.push(([-w, -h - f, 0.0], [w, -h, fd]));
            parts.push(([-0.03, -h, -recess], [0.03, h, -recess + 0.05]));
            parts.push(([-w - f - 0.1, h + f, 0.0], [w + f + 0.1, h + f + 0.15, 0.12]));
        }
        Style::Door => {
            parts.push(([0.25 * w, -0.05, -recess], [0.25 * w + 0.04, 0.05, -recess + 0.06]));
        }
    }
    let mut bounds = Aabb { min: [-w, -h, -recess], max: [w, h, 0.0] };
    for (a, b) in &parts {
        bounds.grow(*a);
        bounds.grow(*b);
    }
    let m = COLLAR_MARGIN;
    let collar = [bounds.min[0] - m, bounds.min[1] - m, bounds.max[0] + m, bounds.max[1] + m];
    if style == Style::Door {
        // The step stands on the ground in front of the wall, below the collar.
        parts.push(([-w - f - 0.2, -h - STEP_HEIGHT, 0.0], [w + f + 0.2, -h, 0.35]));
    }
    Template { half: [w, h], parts, collar, bounds }
}

/// Segments for a box edge of length `len`.
fn segs(len: f64, res: usize) -> usize {
    ((len / 0.4).ceil() as usize).max(1) * res
}

/// Appends the four trapezoids between rectangle `outer` and rectangle `inner` (both
/// `[x0, y0, x1, y1]`) at depth `z`, facing +z: `n = [horizontal, vertical]` segments along the
/// edges, `nr` across.
fn ring(mesh: &mut TriMesh, outer: [f64; 4], inner: [f64; 4], z: f64, n: [usize; 2], nr: usize) {
    let corners = |r: [f64; 4]| [[r[0], r[1], z], [r[2], r[1], z], [r[2], r[3], z], [r[0], r[3], z]];
    let (c, k) = (corners(outer), corners(inner));
    for i in 0..4 {
        let j = (i + 1) % 4;
        add_quad(mesh, [c[i], c[j], k[j], k[i]], n[i % 2], nr);
    }
}

/// Appends the recess behind opening `o` (`[x0, y0, x1, y1]` on `z = 0`) of depth `d`: four side
/// walls facing into the opening and the back pane facing +z.
fn recess(mesh: &mut TriMesh, o: [f64; 4], d: f64, n: [usize; 2], nd: usize) {
    let front = [[o[0], o[1], 0.0], [o[2], o[1], 0.0], [o[2], o[3], 0.0], [o[0], o[3], 0.0]];
    let back = front.map(|p| [p[0], p[1], -d]);
    for i in 0..4 {
        let j = (i + 1) % 4;
        add_quad(mesh, [front[i], front[j], back[j], back[i]], n[i % 2], nd);
    }
    add_quad(mesh, [back[0], back[1], back[2], back[3]], n[0], n[1]);
}

/// Generates the facade. Structure: instance classes `window_a`, `window_b`, `door` (translations;
/// boxes around collar, recess and parts), instance-set symmetries `window_a` and `window_b` with
/// the same boxes as regions; with regular spacing the lattice `cell_pitch = [(bay, 0, 0), (0,
/// floor, 0)]`, `cells = [columns, floors, 1]` (the door takes one cell), none when jittered.
pub fn facade(o: &FacadeOptions) -> Result<Example> {
    let res = check_resolution(o.resolution)?;
    let (nc, nf) = (o.columns, o.floors);
    if !(1..=200).contains(&nc) || !(1..=200).contains(&nf) {
        return Err(Error::InvalidOption {
            name: "columns/floors",
            message: format!("need 1 to 200 bays and floors, got {nc} x {nf}"),
        });
    }
    if o.door_column >= nc {
        return Err(Error::InvalidOption {
            name: "door_column",
            message: format!("bay {} does not exist; there are {nc} bays", o.door_column),
        });
    }
    for (name, v) in [
        ("bay_width", o.bay_width),
        ("floor_height", o.floor_height),
        ("wall_thickness", o.wall_thickness),
        ("recess_depth", o.recess_depth),
    ] {
        check_positive(name, v)?;
    }
    for (name, s) in
        [("window_a_size", o.window_a_size), ("window_b_size", o.window_b_size), ("door_size", o.door_size)]
    {
        check_positive(name, s[0].min(s[1]))?;
    }
    if o.recess_depth + 0.05 >= o.wall_thickness {
        return Err(Error::InvalidOption {
            name: "recess_depth",
            message: format!("{} leaves less than 5 cm of a {} m wall", o.recess_depth, o.wall_thickness),
        });
    }
    // Bay and floor boundaries.
    let mut xs: Vec<f64> = (0..=nc).map(|c| c as f64 * o.bay_width).collect();
    let mut ys: Vec<f64> = (0..=nf).map(|f| f as f64 * o.floor_height).collect();
    if let FacadeSpacing::Jittered { amount } = o.spacing {
        if !(0.0..=0.25).contains(&amount) {
            return Err(Error::InvalidOption {
                name: "amount",
                message: format!("jitter {amount} is out of range 0 to 0.25"),
            });
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(o.seed);
        for x in &mut xs[1..nc] {
            *x += o.bay_width * amount * (2.0 * rng.random::<f64>() - 1.0);
        }
        for y in &mut ys[1..nf] {
            *y += o.floor_height * amount * (2.0 * rng.random::<f64>() - 1.0);
        }
    }
    let rd = o.recess_depth;
    let templates = [
        template(Style::A, o.window_a_size, rd),
        template(Style::B, o.window_b_size, rd),
        template(Style::Door, o.door_size, rd),
    ];
    let (n_edge, nr) = ([3 * res, 3 * res], res);
    let mut wall = TriMesh::default();
    let mut asm_parts: Vec<(Style, Point3, Vec<TriMesh>)> = Vec::new();
    for f in 0..nf {
        for c in 0..nc {
            let style = if f == 0 && c == o.door_column {
                Style::Door
            } else {
                let even = match o.layout {
                    WindowLayout::AlternateFloors => f % 2 == 0,
                    WindowLayout::AlternateColumns => c % 2 == 0,
                };
                if even { Style::A } else { Style::B }
            };
            let t = &templates[style as usize];
            let cx = 0.5 * (xs[c] + xs[c + 1]);
            let cy = if style == Style::Door {
                ys[0] + STEP_HEIGHT + t.half[1]
            } else {
                0.5 * (ys[f] + ys[f + 1])
            };
            let tile = [xs[c], ys[f], xs[c + 1], ys[f + 1]];
            let collar = [cx + t.collar[0], cy + t.collar[1], cx + t.collar[2], cy + t.collar[3]];
            let opening = [cx - t.half[0], cy - t.half[1], cx + t.half[0], cy + t.half[1]];
            if collar[0] <= tile[0] + 0.01
                || collar[1] <= tile[1] + 0.01
                || collar[2] >= tile[2] - 0.01
                || collar[3] >= tile[3] - 0.01
            {
                return Err(Error::InvalidOption {
                    name: "facade",
                    message: format!(
                        "the {:?} in bay {c}, floor {f} does not fit its {:.2} x {:.2} m bay: enlarge the bays or shrink the windows",
                        style,
                        tile[2] - tile[0],
                        tile[3] - tile[1]
                    ),
                });
            }
            ring(&mut wall, tile, collar, 0.0, n_edge, nr);
            ring(&mut wall, collar, opening, 0.0, n_edge, nr);
            recess(&mut wall, opening, rd, n_edge, res);
            // Back of the wall, facing -z.
            let zb = -o.wall_thickness;
            add_quad(
                &mut wall,
                [
                    [tile[2], tile[1], zb],
                    [tile[0], tile[1], zb],
                    [tile[0], tile[3], zb],
                    [tile[2], tile[3], zb],
                ],
                n_edge[0],
                n_edge[1],
            );
            let parts = t
                .parts
                .iter()
                .map(|(a, b)| {
                    let min = [a[0] + cx, a[1] + cy, a[2]];
                    let max = [b[0] + cx, b[1] + cy, b[2]];
                    box_part(
                        min,
                        max,
                        [segs(b[0] - a[0], res), segs(b[1] - a[1], res), segs(b[2] - a[2], res)],
                    )
                })
                .collect();
            asm_parts.push((style, [cx, cy, 0.0], parts));
        }
    }
    // Sides of the slab.
    let (w_total, h_total, zb) = (xs[nc], ys[nf], -o.wall_thickness);
    for c in 0..nc {
        let (x0, x1) = (xs[c], xs[c + 1]);
        add_quad(&mut wall, [[x0, 0.0, zb], [x1, 0.0, zb], [x1, 0.0, 0.0], [x0, 0.0, 0.0]], n_edge[0], res);
        add_quad(
            &mut wall,
            [[x0, h_total, 0.0], [x1, h_total, 0.0], [x1, h_total, zb], [x0, h_total, zb]],
            n_edge[0],
            res,
        );
    }
    for f in 0..nf {
        let (y0, y1) = (ys[f], ys[f + 1]);
        add_quad(&mut wall, [[0.0, y0, 0.0], [0.0, y1, 0.0], [0.0, y1, zb], [0.0, y0, zb]], n_edge[1], res);
        add_quad(
            &mut wall,
            [[w_total, y0, zb], [w_total, y1, zb], [w_total, y1, 0.0], [w_total, y0, 0.0]],
            n_edge[1],
            res,
        );
    }
    let mut asm = Assembly::default();
    asm.add("wall", &weld(wall));

    let mut classes: [(Vec<Vec<usize>>, Vec<Aabb>, Vec<Point3>); 3] = Default::default();
    for (style, c, parts) in &asm_parts {
        let ids: Vec<usize> = parts.iter().map(|p| asm.add(format!("{style:?}"), p)).collect();
        let t = &templates[*style as usize];
        let b = Aabb {
            min: [c[0] + t.collar[0], c[1] + t.collar[1], t.bounds.min[2]],
            max: [c[0] + t.collar[2], c[1] + t.collar[3], t.bounds.max[2]],
        };
        let mut b = b;
        for &i in &ids {
            let pb = asm.aabb_of(&[i]);
            b.grow(pb.min);
            b.grow(pb.max);
        }
        let k = &mut classes[*style as usize];
        k.0.push(ids);
        k.1.push(b);
        k.2.push(*c);
    }
    let ann = Annotator::new(&asm)?;
    let mut symmetries = Vec::new();
    let mut instances = Vec::new();
    for (style, name) in [(Style::A, "window_a"), (Style::B, "window_b"), (Style::Door, "door")] {
        let (parts, boxes, centers) = &classes[style as usize];
        if parts.is_empty() {
            continue;
        }
        let c0 = centers[0];
        let transforms: Vec<_> =
            centers.iter().map(|c| translation([c[0] - c0[0], c[1] - c0[1], c[2] - c0[2]])).collect();
        if parts.len() > 1 {
            symmetries.push(ann.instances_in_boxes(name, boxes, parts, &transforms));
        }
        instances.push(ann.class_in_boxes(name, boxes, &transforms));
    }
    let (cell_pitch, cells) = match o.spacing {
        FacadeSpacing::Regular => {
            (vec![[o.bay_width, 0.0, 0.0], [0.0, o.floor_height, 0.0]], Some([nc, nf, 1]))
        }
        FacadeSpacing::Jittered { .. } => (Vec::new(), None),
    };
    let structure = Structure {
        symmetry: SymmetryAnnotation { symmetries, ..Default::default() },
        cell_pitch,
        cells,
        instances,
    };
    let name = match o.spacing {
        FacadeSpacing::Regular => "facade",
        FacadeSpacing::Jittered { .. } => "facade_irregular",
    };
    Ok(Example { name: name.into(), mesh: asm.mesh, structure })
}
