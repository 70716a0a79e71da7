//! A fan (propeller): a polygonal hub and `n` flat blades, with the dihedral symmetry `Dₙ`
//! (rotation by `2π/n` about the z axis and the mirror `y ↦ −y`).
//!
//! The blades are flat and mirror-symmetric about their own axis (pitched blades would break the
//! mirror). Blade 0 points along +x; the rotor axis is z through the origin. The hub's face towards
//! each blade is flat and the blade root sits flush on it.

use serde::{Deserialize, Serialize};

use crate::geometry::IDENTITY4;
use crate::mesh::TriMesh;
use crate::procedural::Example;
use crate::procedural::primitives::{
    Annotator, Assembly, Hexa, Side, add_hexa, check_positive, check_resolution, dihedral_elements,
    hub_half_outline, orbit, profile_solid, transformed,
};
use crate::procedural::structure::{Structure, SymmetryAnnotation, reflection, rotation_about};
use crate::{Error, Result};

/// Options of [`fan`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FanOptions {
    /// Number of blades `n` (the order of the rotation); 2 to 64, default 6.
    pub blades: usize,
    /// Circumradius of the polygonal hub, metres; default 0.05.
    pub hub_radius: f64,
    /// Height (z extent) of the hub, metres; default 0.04.
    pub hub_height: f64,
    /// Blade length from the hub face to the tip, metres; default 0.25.
    pub blade_length: f64,
    /// Largest blade width, metres; default 0.09.
    pub blade_width: f64,
    /// Blade width at the root, metres; must fit on the hub's flat face; default 0.024.
    pub blade_root_width: f64,
    /// Blade thickness (z extent), metres; at most the hub height; default 0.006.
    pub blade_thickness: f64,
    /// Polygon corners of the hub per half sector between two blades (the hub has
    /// `2 · n · (hub_corners + 1)` corners); default 2.
    pub hub_corners: usize,
    /// Subdivision multiplier of the whole tessellation; default 1.
    pub resolution: usize,
}

impl Default for FanOptions {
    fn default() -> Self {
        FanOptions {
            blades: 6,
            hub_radius: 0.05,
            hub_height: 0.04,
            blade_length: 0.25,
            blade_width: 0.09,
            blade_root_width: 0.024,
            blade_thickness: 0.006,
            hub_corners: 2,
            resolution: 1,
        }
    }
}

/// Blade outline: (fraction of the length, fraction of the largest half-width); the root
/// half-width replaces the first entry.
const BLADE_PROFILE: [(f64, f64); 6] =
    [(0.0, 0.0), (0.12, 0.55), (0.45, 1.0), (0.8, 0.95), (0.95, 0.7), (1.0, 0.3)];
/// Segments along the blade per profile interval (times the resolution).
const BLADE_SEGMENTS: [usize; 5] = [1, 2, 2, 1, 1];

/// One half (`y ≥ 0`) of a flat blade along +x starting at `x0`, open on `y = 0`:
/// `stations` are `(x, half-width)`, thickness along z is `z`.
pub(crate) fn half_blade(
    stations: &[(f64, f64)],
    segments: &[usize],
    z: [f64; 2],
    n_w: usize,
    n_z: usize,
) -> TriMesh {
    let mut m = TriMesh::default();
    let last = stations.len().saturating_sub(2);
    for i in 0..stations.len().saturating_sub(1) {
        let (x0, h0) = stations[i];
        let (x1, h1) = stations[i + 1];
        let mut corners = [[0.0; 3]; 8];
        for (c, corner) in corners.iter_mut().enumerate() {
            let (x, h) = if c & 1 == 0 { (x0, h0) } else { (x1, h1) };
            let y = if c & 2 == 0 { 0.0 } else { h };
            *corner = [x, y, if c & 4 == 0 { z[0] } else { z[1] }];
        }
        let mut open = vec![Side::MinY];
        if i > 0 {
            open.push(Side::MinX);
        }
        if i < last {
            open.push(Side::MaxX);
        }
        add_hexa(&mut m, &Hexa { corners }, [segments[i], n_w, n_z], &open);
    }
    m
}

/// Generates the fan. Structure: the group `fan` (generators: rotation by `2π/n` about z, mirror
/// `y ↦ −y`; region all) and the instance class `blade` (rotations).
pub fn fan(o: &FanOptions) -> Result<Example> {
    let res = check_resolution(o.resolution)?;
    let n = o.blades;
    if !(2..=64).contains(&n) {
        return Err(Error::InvalidOption {
            name: "blades",
            message: format!("need 2 to 64 blades, got {n}"),
        });
    }
    for (name, v) in [
        ("hub_radius", o.hub_radius),
        ("hub_height", o.hub_height),
        ("blade_length", o.blade_length),
        ("blade_width", o.blade_width),
        ("blade_root_width", o.blade_root_width),
        ("blade_thickness", o.blade_thickness),
    ] {
        check_positive(name, v)?;
    }
    if o.blade_thickness > o.hub_height {
        return Err(Error::InvalidOption {
            name: "blade_thickness",
            message: format!("{} exceeds the hub height {}", o.blade_thickness, o.hub_height),
        });
    }
    let half_angle = std::f64::consts::PI / n as f64;
    // The hub's flat face towards a blade has half-angle alpha: wide enough for the root.
    let alpha = ((0.5 * o.blade_root_width * 1.1) / o.hub_radius).min(1.0).asin();
    if alpha >= 0.9 * half_angle {
        return Err(Error::InvalidOption {
            name: "blade_root_width",
            message: format!(
                "a root {} wide does not fit on a hub of radius {} with {n} blades: widen the hub or narrow the root",
                o.blade_root_width, o.hub_radius
            ),
        });
    }
    let outline = hub_half_outline(o.hub_radius, alpha, half_angle, o.hub_corners.clamp(1, 64));
    let center = vec![[0.0; 3]; outline.len()];
    let hh = 0.5 * o.hub_height;
    let hub_piece = profile_solid(&center, &outline, [-hh, hh], 2 * res, res, true, false);
    let elements = dihedral_elements(n, [0.0, 0.0, 1.0], [0.0; 3], [0.0, 1.0, 0.0]);
    let hub = orbit(&hub_piece, &elements);

    let x0 = o.hub_radius * alpha.cos();
    let mut stations: Vec<(f64, f64)> =
        BLADE_PROFILE.iter().map(|&(f, w)| (x0 + f * o.blade_length, 0.5 * w * o.blade_width)).collect();
    stations[0].1 = 0.5 * o.blade_root_width;
    let segments: Vec<usize> = BLADE_SEGMENTS.iter().map(|s| s * res).collect();
    let ht = 0.5 * o.blade_thickness;
    let half = half_blade(&stations, &segments, [-ht, ht], 2 * res, res);
    let blade0 = orbit(&half, &[IDENTITY4, reflection([0.0, 1.0, 0.0], [0.0; 3])]);

    let mut asm = Assembly::default();
    asm.add("hub", &hub);
    let mut blade_parts = Vec::new();
    let mut transforms = Vec::new();
    for k in 0..n {
        let r = rotation_about([0.0, 0.0, 1.0], [0.0; 3], std::f64::consts::TAU * k as f64 / n as f64);
        blade_parts.push(vec![asm.add(format!("blade {k}"), &transformed(&blade0, &r))]);
        transforms.push(r);
    }
    let ann = Annotator::new(&asm)?;
    let generators = vec![elements[1], elements[n]];
    let structure = Structure {
        symmetry: SymmetryAnnotation {
            symmetries: vec![ann.group("fan", None, None, generators)],
            ..Default::default()
        },
        cell_pitch: Vec::new(),
        cells: None,
        instances: vec![ann.class("blade", &blade_parts, &transforms)],
    };
    Ok(Example { name: "fan".into(), mesh: asm.mesh, structure })
}
