//! A shelf of `k × m` cells: a 2-D translational lattice, optionally sheared (thesis Fig. 4.7).
//!
//! The shelf is assembled from cell modules so that shifting by one lattice vector maps cells onto
//! cells exactly: cell `(i, j)` is its bottom board (spanning the joint to its left and the cell)
//! plus its left panel; a closing column on the right (joint block + panel per row), a closing row
//! of boards on top and a corner block complete the frame. Every board is a separate closed box.
//! Coordinates: x right, y up, z towards the viewer; the shelf stands on `y = 0` with its back at
//! `z = 0`.

use serde::{Deserialize, Serialize};

use crate::geometry::{Mat4, Point3, transform_point};
use crate::mesh::TriMesh;
use crate::procedural::Example;
use crate::procedural::primitives::{
    Annotator, Assembly, Hexa, Side, add_hexa, box_part, check_positive, check_resolution, weld,
};
use crate::procedural::structure::{Structure, SymmetryAnnotation, translation};
use crate::{Error, Result};

/// The lattice of the shelf's cells.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShelfLattice {
    /// Rows stacked straight: lattice vectors `(pitch_x, 0, 0)` and `(0, pitch_y, 0)`.
    Orthogonal,
    /// Every row shifted sideways by `offset` metres relative to the row below (a sheared,
    /// non-orthogonal lattice as in thesis Fig. 4.7); panels lean accordingly.
    Sheared {
        /// Horizontal shift of one row relative to the one below, metres.
        offset: f64,
    },
}

/// Options of [`shelf`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ShelfOptions {
    /// Number of cells `[columns, rows]`; default `[4, 3]`.
    pub cells: [usize; 2],
    /// Inner size of a cell `[width, height]` in metres; default `[0.4, 0.35]`. The lattice pitch is
    /// this plus the board thickness.
    pub cell_size: [f64; 2],
    /// Thickness of boards and panels, metres; default 0.02.
    pub board_thickness: f64,
    /// Depth of the shelf (z extent), metres; default 0.3.
    pub depth: f64,
    /// Orthogonal or sheared lattice; default orthogonal.
    pub lattice: ShelfLattice,
    /// Subdivision multiplier: every edge of the default tessellation is split into this many
    /// segments (vertex count grows about quadratically); default 1.
    pub resolution: usize,
}

impl Default for ShelfOptions {
    fn default() -> Self {
        ShelfOptions {
            cells: [4, 3],
            cell_size: [0.4, 0.35],
            board_thickness: 0.02,
            depth: 0.3,
            lattice: ShelfLattice::Orthogonal,
            resolution: 1,
        }
    }
}

impl ShelfOptions {
    /// The default shelf with a sheared lattice (each row shifted by 0.15 m).
    pub fn sheared() -> Self {
        ShelfOptions { lattice: ShelfLattice::Sheared { offset: 0.15 }, ..Default::default() }
    }
}

/// Generates the shelf. Structure: one instance class `cell` (`k·m` instances, translations),
/// the same as an instance-set symmetry `cells`, the two lattice vectors as `cell_pitch` and
/// `cells = [k, m, 1]`. The symmetry's regions are the cells' boxes on the orthogonal lattice; on a
/// sheared lattice a cell's box also catches vertices of the neighbouring row, so the regions are
/// the cells' faces there.
pub fn shelf(o: &ShelfOptions) -> Result<Example> {
    let res = check_resolution(o.resolution)?;
    let [k, m] = o.cells;
    if k == 0 || m == 0 || k * m > 10_000 {
        return Err(Error::InvalidOption {
            name: "cells",
            message: format!("need 1 to 10000 cells in total, got {k} x {m}"),
        });
    }
    check_positive("cell_size", o.cell_size[0].min(o.cell_size[1]))?;
    check_positive("board_thickness", o.board_thickness)?;
    check_positive("depth", o.depth)?;
    let shear = match o.lattice {
        ShelfLattice::Orthogonal => 0.0,
        ShelfLattice::Sheared { offset } => {
            if !offset.is_finite() {
                return Err(Error::InvalidOption { name: "offset", message: "must be finite".into() });
            }
            offset
        }
    };
    let t = o.board_thickness;
    let d = o.depth;
    let p = [o.cell_size[0] + t, o.cell_size[1] + t];
    // The shear maps the orthogonal shelf onto the sheared one: x' = x + (offset / pitch_y) y.
    let sigma = shear / p[1];
    let shear_map: Mat4 =
        [[1.0, sigma, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
    let (n_t, n_d) = (res, 2 * res);
    // A board is a joint block and a span welded into one box, so it has vertices where the
    // panels below and above meet it, as every cell has.
    let board = |x: f64, y: f64| {
        let mut m = TriMesh::default();
        add_hexa(&mut m, &Hexa::axis_box([x, y, 0.0], [x + t, y + t, d]), [n_t, n_t, n_d], &[Side::MaxX]);
        add_hexa(
            &mut m,
            &Hexa::axis_box([x + t, y, 0.0], [x + p[0], y + t, d]),
            [4 * res, n_t, n_d],
            &[Side::MinX],
        );
        weld(m)
    };
    let panel = |x: f64, y: f64| box_part([x, y + t, 0.0], [x + t, y + p[1], d], [n_t, 3 * res, n_d]);
    let joint = |x: f64, y: f64| box_part([x, y, 0.0], [x + t, y + t, d], [n_t, n_t, n_d]);
    let mut asm = Assembly::default();
    let add = |asm: &mut Assembly, tag: String, mut part: TriMesh| {
        part.transform(&shear_map);
        asm.add(tag, &part)
    };
    let mut cell_parts = Vec::new();
    let mut transforms = Vec::new();
    let a: Point3 = [p[0], 0.0, 0.0];
    let b: Point3 = transform_point(&shear_map, [0.0, p[1], 0.0]);
    for j in 0..m {
        for i in 0..k {
            let (x, y) = (i as f64 * p[0], j as f64 * p[1]);
            let b0 = add(&mut asm, format!("cell {i},{j} board"), board(x, y));
            let p0 = add(&mut asm, format!("cell {i},{j} panel"), panel(x, y));
            cell_parts.push(vec![b0, p0]);
            let (fi, fj) = (i as f64, j as f64);
            transforms.push(translation([fi * a[0] + fj * b[0], fi * a[1] + fj * b[1], 0.0]));
        }
        let (x, y) = (k as f64 * p[0], j as f64 * p[1]);
        add(&mut asm, format!("closing joint {j}"), joint(x, y));
        add(&mut asm, format!("closing panel {j}"), panel(x, y));
    }
    for i in 0..k {
        add(&mut asm, format!("top board {i}"), board(i as f64 * p[0], m as f64 * p[1]));
    }
    add(&mut asm, "top corner".into(), joint(k as f64 * p[0], m as f64 * p[1]));

    let ann = Annotator::new(&asm)?;
    let structure = Structure {
        symmetry: SymmetryAnnotation {
            symmetries: vec![ann.instances("cells", &cell_parts, &transforms)],
            ..Default::default()
        },
        cell_pitch: vec![a, b],
        cells: Some([k, m, 1]),
        instances: vec![ann.class("cell", &cell_parts, &transforms)],
    };
    let name = match o.lattice {
        ShelfLattice::Orthogonal => "shelf",
        ShelfLattice::Sheared { .. } => "shelf_sheared",
    };
    Ok(Example { name: name.to_string(), mesh: asm.mesh, structure })
}
