//! A windmill with nested symmetry: a tapered tower, a nacelle, and a rotor of `n` sails on a
//! horizontal axis (z) in front of the nacelle.
//!
//! Symmetries (thesis Fig. 3.3, 3.6): the whole windmill is mirror-symmetric about `x = 0`; the
//! rotation by `2π/n` about the rotor axis acts only on the rotor (shaft, hub and sails); each sail
//! is mirror-symmetric about the plane through the rotor axis and its own axis, acting only on that
//! sail. Sail 0 points up, so the global mirror maps the rotor onto itself for every `n`.
//!
//! A sail is a square spar with a thin tapered sail board behind it, both flush on the hub's flat
//! face towards the sail. The rotor is built, like the fan, as the orbit of half-sector pieces under
//! the dihedral group of the rotor (whose mirror is the global one).

use serde::{Deserialize, Serialize};

use crate::geometry::{Aabb, IDENTITY4, Point3, mat4_mul};
use crate::mesh::TriMesh;
use crate::procedural::Example;
use crate::procedural::fan::half_blade;
use crate::procedural::primitives::{
    Annotator, Assembly, Hexa, Side, add_hexa, check_positive, check_resolution, dihedral_elements,
    hub_half_outline, orbit, profile_solid, transformed,
};
use crate::procedural::structure::{Structure, SymmetryAnnotation, reflection, rotation_about, translation};
use crate::{Error, Result};

/// Options of [`windmill`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct WindmillOptions {
    /// Number of sails `n` (the order of the rotor's rotation); 2 to 12, default 4.
    pub blades: usize,
    /// Height of the tower (to the nacelle's floor), metres; default 8.
    pub tower_height: f64,
    /// Width of the square tower at the ground and at the top, metres; default `[2.4, 1.4]`.
    pub tower_width: [f64; 2],
    /// Nacelle size `[width (x), height (y), depth (z)]`, metres; default `[1.8, 1.4, 2.3]` (see
    /// [`windmill`] for the layout).
    pub nacelle_size: [f64; 3],
    /// Circumradius of the polygonal hub, metres; default 0.35.
    pub hub_radius: f64,
    /// Length of the hub along the rotor axis, metres; default 0.5.
    pub hub_length: f64,
    /// Length of the shaft between nacelle and hub, metres; default 0.4.
    pub shaft_length: f64,
    /// Sail length from the hub face to the tip, metres; default 5.
    pub blade_length: f64,
    /// Width of the sail board `[at its root, at the tip]`, metres; default `[0.8, 1.3]`.
    pub sail_width: [f64; 2],
    /// Side of the spar's square cross-section, metres; default 0.2.
    pub spar_width: f64,
    /// Subdivision multiplier of the whole tessellation (vertex count grows quadratically);
    /// default 1 (about 1.1k vertices); 11 gives about 109k vertices (`windmill_100k`).
    pub resolution: usize,
}

impl Default for WindmillOptions {
    fn default() -> Self {
        WindmillOptions {
            blades: 4,
            tower_height: 8.0,
            tower_width: [2.4, 1.4],
            nacelle_size: [1.8, 1.4, 2.3],
            hub_radius: 0.35,
            hub_length: 0.5,
            shaft_length: 0.4,
            blade_length: 5.0,
            sail_width: [0.8, 1.3],
            spar_width: 0.2,
            resolution: 1,
        }
    }
}

/// Generates the windmill. Layout: tower centred on the y axis from `y = 0` to `tower_height`;
/// nacelle on top, centred in x, its back `0.4 · depth` behind the tower axis; shaft and hub along
/// +z from the nacelle's front; rotor centre at mid-height of the nacelle.
///
/// Structure: groups `windmill mirror` (`x ↦ −x`, region all), `rotor` (rotation by `2π/n` about
/// the rotor axis, region a box around the rotor that cuts the shaft in half), `blade k` (mirror in
/// the plane of the rotor axis and sail `k`'s axis, region a box around sail `k` without its root
/// face; given as faces when no box isolates the sail); instance class `blade` (rotations).
pub fn windmill(o: &WindmillOptions) -> Result<Example> {
    let res = check_resolution(o.resolution)?;
    let n = o.blades;
    if !(2..=12).contains(&n) {
        return Err(Error::InvalidOption { name: "blades", message: format!("need 2 to 12 sails, got {n}") });
    }
    for (name, v) in [
        ("tower_height", o.tower_height),
        ("tower_width", o.tower_width[0].min(o.tower_width[1])),
        ("nacelle_size", o.nacelle_size.iter().copied().fold(f64::INFINITY, f64::min)),
        ("hub_radius", o.hub_radius),
        ("hub_length", o.hub_length),
        ("shaft_length", o.shaft_length),
        ("blade_length", o.blade_length),
        ("sail_width", o.sail_width[0].min(o.sail_width[1])),
        ("spar_width", o.spar_width),
    ] {
        check_positive(name, v)?;
    }
    let [nw, nh, nd] = o.nacelle_size;
    let mirror_x = reflection([1.0, 0.0, 0.0], [0.0; 3]);
    let halves = [IDENTITY4, mirror_x];

    // Tower: a square frustum, built as its x >= 0 half and mirrored.
    let h = o.tower_height;
    let (wb, wt) = (0.5 * o.tower_width[0], 0.5 * o.tower_width[1]);
    let mut corners = [[0.0; 3]; 8];
    for (c, p) in corners.iter_mut().enumerate() {
        let (y, hw) = if c & 2 == 0 { (0.0, wb) } else { (h, wt) };
        *p = [if c & 1 == 0 { 0.0 } else { hw }, y, if c & 4 == 0 { -hw } else { hw }];
    }
    let mut tower_half = TriMesh::default();
    add_hexa(&mut tower_half, &Hexa { corners }, [2 * res, 8 * res, 4 * res], &[Side::MinX]);
    let tower = orbit(&tower_half, &halves);

    // Nacelle: a box on the tower top.
    let z_back = -0.4 * nd;
    let z_front = z_back + nd;
    let mut nacelle_half = TriMesh::default();
    add_hexa(
        &mut nacelle_half,
        &Hexa::axis_box([0.0, h, z_back], [0.5 * nw, h + nh, z_front]),
        [2 * res, 2 * res, 4 * res],
        &[Side::MinX],
    );
    let nacelle = orbit(&nacelle_half, &halves);

    // Rotor, built in a local frame: axis z, sail 0 along +x, mirror y -> -y, hub from z = 0 to
    // hub_length, shaft behind it. world_from_local turns sail 0 up and moves the hub into place.
    let half_angle = std::f64::consts::PI / n as f64;
    let spar_hw = 0.5 * o.spar_width;
    let alpha = ((1.2 * spar_hw) / o.hub_radius).min(1.0).asin();
    if alpha >= 0.9 * half_angle || o.spar_width >= 0.5 * o.hub_length {
        return Err(Error::InvalidOption {
            name: "hub_radius",
            message: format!(
                "a hub of radius {} and length {} cannot carry {n} spars {} wide: enlarge the hub",
                o.hub_radius, o.hub_length, o.spar_width
            ),
        });
    }
    let local_elements = dihedral_elements(n, [0.0, 0.0, 1.0], [0.0; 3], [0.0, 1.0, 0.0]);
    let outline = hub_half_outline(o.hub_radius, alpha, half_angle, 2);
    let axis_pts = vec![[0.0; 3]; outline.len()];
    let hub = orbit(
        &profile_solid(&axis_pts, &outline, [0.0, o.hub_length], 2 * res, 2 * res, true, false),
        &local_elements,
    );
    let shaft_r = 0.5 * o.hub_radius;
    let shaft_outline: Vec<Point3> = (0..=2)
        .map(|j| {
            let a = half_angle * j as f64 / 2.0;
            [shaft_r * a.cos(), shaft_r * a.sin(), 0.0]
        })
        .collect();
    let shaft = orbit(
        &profile_solid(&axis_pts[..3], &shaft_outline, [-o.shaft_length, 0.0], res, 2 * res, true, false),
        &local_elements,
    );
    let apothem = o.hub_radius * alpha.cos();
    let len = o.blade_length;
    // Spar in front (towards +z), sail board behind it, both inside the hub's z range.
    let zc = 0.5 * o.hub_length;
    let spar_z = [zc - spar_hw + 0.25 * o.spar_width, zc + spar_hw + 0.25 * o.spar_width];
    let sail_t = 0.25 * o.spar_width;
    let sail_z = [spar_z[0] - sail_t, spar_z[0]];
    let spar = half_blade(&[(apothem, spar_hw), (apothem + len, spar_hw)], &[10 * res], spar_z, res, res);
    let s0 = apothem + 0.15 * len;
    let sail_stations = [
        (s0, 0.5 * o.sail_width[0]),
        (s0 + 0.6 * (len - 0.15 * len), 0.5 * o.sail_width[1]),
        (apothem + len, 0.5 * o.sail_width[1]),
    ];
    let sail = half_blade(&sail_stations, &[6 * res, 3 * res], sail_z, 2 * res, res);
    let local_mirror = [IDENTITY4, local_elements[n]];
    let spar = orbit(&spar, &local_mirror);
    let sail = orbit(&sail, &local_mirror);

    let center: Point3 = [0.0, h + 0.5 * nh, z_front + o.shaft_length];
    let world_from_local = mat4_mul(
        &translation(center),
        &rotation_about([0.0, 0.0, 1.0], [0.0; 3], std::f64::consts::FRAC_PI_2),
    );
    let mut asm = Assembly::default();
    asm.add("tower", &tower);
    asm.add("nacelle", &nacelle);
    let shaft_id = asm.add("shaft", &transformed(&shaft, &world_from_local));
    let hub_id = asm.add("hub", &transformed(&hub, &world_from_local));
    let mut blade_parts = Vec::new();
    let mut transforms = Vec::new();
    for k in 0..n {
        let rot = rotation_about([0.0, 0.0, 1.0], center, std::f64::consts::TAU * k as f64 / n as f64);
        let place = mat4_mul(&world_from_local, &local_elements[k]);
        let a = asm.add(format!("blade {k} spar"), &transformed(&spar, &place));
        let b = asm.add(format!("blade {k} sail"), &transformed(&sail, &place));
        blade_parts.push(vec![a, b]);
        transforms.push(rot);
    }
    let ann = Annotator::new(&asm)?;
    let rotor_gen = rotation_about([0.0, 0.0, 1.0], center, std::f64::consts::TAU / n as f64);
    let reach = apothem + len + 0.5 * o.sail_width[1];
    let rotor_box = Aabb {
        min: [center[0] - reach, center[1] - reach, center[2] - 0.5 * o.shaft_length],
        max: [center[0] + reach, center[1] + reach, center[2] + o.hub_length],
    };
    let mut rotor_parts = vec![shaft_id, hub_id];
    rotor_parts.extend(blade_parts.iter().flatten().copied());
    let mut symmetries = vec![
        ann.group("windmill mirror", None, None, vec![mirror_x]),
        ann.group("rotor", Some(&rotor_parts), Some(rotor_box), vec![rotor_gen]),
    ];
    for (k, parts) in blade_parts.iter().enumerate() {
        let a = std::f64::consts::FRAC_PI_2 + std::f64::consts::TAU * k as f64 / n as f64;
        let (dir, normal) = ([a.cos(), a.sin(), 0.0], [-a.sin(), a.cos(), 0.0]);
        let blade_mirror = reflection(normal, center);
        // The sail's box without its root face (which lies on the hub).
        let cut = apothem * (1.0 + 1e-6);
        let sail: Vec<_> = parts
            .iter()
            .flat_map(|&p| asm.parts[p].vertices.clone().map(|v| asm.mesh.positions[v]))
            .filter(|q| (q[0] - center[0]) * dir[0] + (q[1] - center[1]) * dir[1] > cut)
            .collect();
        let b = Aabb::from_points(&sail);
        symmetries.push(ann.group(&format!("blade {k}"), Some(parts), b, vec![blade_mirror]));
    }
    let structure = Structure {
        symmetry: SymmetryAnnotation { symmetries, ..Default::default() },
        cell_pitch: Vec::new(),
        cells: None,
        instances: vec![ann.class("blade", &blade_parts, &transforms)],
    };
    Ok(Example { name: "windmill".into(), mesh: asm.mesh, structure })
}
