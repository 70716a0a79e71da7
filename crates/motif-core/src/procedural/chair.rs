//! A chair: seat, four legs, two back posts and a backrest, mirror-symmetric about the plane
//! `x = 0`. Parts crossing the mirror plane are built as a half and its mirror image; the parts on
//! the left are mirror images of those on the right. The chair stands on `y = 0`, faces +z.

use serde::{Deserialize, Serialize};

use crate::geometry::IDENTITY4;
use crate::mesh::TriMesh;
use crate::procedural::Example;
use crate::procedural::primitives::{
    Annotator, Assembly, Hexa, Side, add_hexa, box_part, check_positive, check_resolution, orbit, transformed,
};
use crate::procedural::structure::{Structure, SymmetryAnnotation, reflection, translation};
use crate::{Error, Result};

/// Options of [`chair`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ChairOptions {
    /// Seat width (x), metres; default 0.46.
    pub seat_width: f64,
    /// Seat depth (z), metres; default 0.44.
    pub seat_depth: f64,
    /// Height of the seat's top above the floor, metres; default 0.46.
    pub seat_height: f64,
    /// Seat thickness, metres; default 0.04.
    pub seat_thickness: f64,
    /// Side of the legs' and back posts' square cross-section, metres; default 0.04.
    pub leg_width: f64,
    /// Height of the back posts above the seat, metres; default 0.42.
    pub back_height: f64,
    /// Height of the backrest board, metres; default 0.16.
    pub backrest_height: f64,
    /// Thickness of the backrest board, metres; at most the leg width; default 0.025.
    pub backrest_thickness: f64,
    /// Subdivision multiplier of the whole tessellation; default 1.
    pub resolution: usize,
}

impl Default for ChairOptions {
    fn default() -> Self {
        ChairOptions {
            seat_width: 0.46,
            seat_depth: 0.44,
            seat_height: 0.46,
            seat_thickness: 0.04,
            leg_width: 0.04,
            back_height: 0.42,
            backrest_height: 0.16,
            backrest_thickness: 0.025,
            resolution: 1,
        }
    }
}

/// Generates the chair. Structure: the group `chair mirror` (`x ↦ −x`, region all), the
/// instance-set symmetry `legs` and the instance class `leg` (four translations).
pub fn chair(o: &ChairOptions) -> Result<Example> {
    let res = check_resolution(o.resolution)?;
    for (name, v) in [
        ("seat_width", o.seat_width),
        ("seat_depth", o.seat_depth),
        ("seat_height", o.seat_height),
        ("seat_thickness", o.seat_thickness),
        ("leg_width", o.leg_width),
        ("back_height", o.back_height),
        ("backrest_height", o.backrest_height),
        ("backrest_thickness", o.backrest_thickness),
    ] {
        check_positive(name, v)?;
    }
    let (w, d, sh, st, lw) = (o.seat_width, o.seat_depth, o.seat_height, o.seat_thickness, o.leg_width);
    if 2.5 * lw >= w.min(d)
        || st >= sh
        || o.backrest_height + 0.03 >= o.back_height
        || o.backrest_thickness > lw
    {
        return Err(Error::InvalidOption {
            name: "chair",
            message:
                "inconsistent sizes: legs must be narrower than 40% of the seat, the seat thinner than its \
                      height, the backrest lower than the back posts and thinner than a leg"
                    .into(),
        });
    }
    let mirror = reflection([1.0, 0.0, 0.0], [0.0; 3]);
    let halves = [IDENTITY4, mirror];
    let half_box = |min: [f64; 3], max: [f64; 3], n: [usize; 3]| -> TriMesh {
        let mut m = TriMesh::default();
        add_hexa(&mut m, &Hexa::axis_box(min, max), n, &[Side::MinX]);
        orbit(&m, &halves)
    };
    let mut asm = Assembly::default();
    asm.add("seat", &half_box([0.0, sh - st, -0.5 * d], [0.5 * w, sh, 0.5 * d], [2 * res, res, 4 * res]));
    let leg_h = sh - st;
    let x_out = 0.5 * w;
    let leg = |z0: f64| box_part([x_out - lw, 0.0, z0], [x_out, leg_h, z0 + lw], [res, 6 * res, res]);
    let front_right = leg(0.5 * d - lw);
    let back_right = leg(-0.5 * d);
    let fr = asm.add("leg front right", &front_right);
    let fl = asm.add("leg front left", &transformed(&front_right, &mirror));
    let br = asm.add("leg back right", &back_right);
    let bl = asm.add("leg back left", &transformed(&back_right, &mirror));
    let post =
        box_part([x_out - lw, sh, -0.5 * d], [x_out, sh + o.back_height, -0.5 * d + lw], [res, 6 * res, res]);
    asm.add("back post right", &post);
    asm.add("back post left", &transformed(&post, &mirror));
    let top = sh + o.back_height - 0.03;
    let zc = -0.5 * d + 0.5 * lw;
    let bt = 0.5 * o.backrest_thickness;
    asm.add(
        "backrest",
        &half_box(
            [0.0, top - o.backrest_height, zc - bt],
            [x_out - lw, top, zc + bt],
            [3 * res, 2 * res, res],
        ),
    );

    let leg_parts = vec![vec![fr], vec![fl], vec![br], vec![bl]];
    let (dx, dz) = (-(w - lw), -(d - lw));
    let transforms =
        vec![IDENTITY4, translation([dx, 0.0, 0.0]), translation([0.0, 0.0, dz]), translation([dx, 0.0, dz])];
    let ann = Annotator::new(&asm)?;
    let structure = Structure {
        symmetry: SymmetryAnnotation {
            symmetries: vec![
                ann.group("chair mirror", None, None, vec![mirror]),
                ann.instances("legs", &leg_parts, &transforms),
            ],
            ..Default::default()
        },
        cell_pitch: Vec::new(),
        cells: None,
        instances: vec![ann.class("leg", &leg_parts, &transforms)],
    };
    Ok(Example { name: "chair".into(), mesh: asm.mesh, structure })
}
