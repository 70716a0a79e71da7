//! A spur gear: `n` teeth with a trapezoidal (straight-flank) profile, extruded, with a round bore.
//! Its symmetry group is `Dₙ × Z₂`: rotation by `2π/n` about z, the mirror `y ↦ −y` through the
//! middle of tooth 0, and the mid-plane mirror `z ↦ −z`. The gear is the orbit of one quarter
//! tooth sector (half the angular pitch, half the face width) under those `4n` elements.

use serde::{Deserialize, Serialize};

use crate::geometry::{Point3, mat4_mul, transform_point};
use crate::procedural::Example;
use crate::procedural::primitives::{
    Annotator, Assembly, check_positive, check_resolution, dihedral_elements, orbit, profile_solid,
};
use crate::procedural::structure::{Instance, InstanceClass, Structure, SymmetryAnnotation, reflection};
use crate::{Error, Result};

/// Options of [`gear`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GearOptions {
    /// Number of teeth `n`; 3 to 500, default 17.
    pub teeth: usize,
    /// Gear module (pitch diameter / teeth), metres: the pitch radius is `module · n / 2`, the
    /// tip radius one module more, the root radius 1.25 modules less; default 0.004.
    pub module: f64,
    /// Face width (z extent), metres; default 0.012.
    pub face_width: f64,
    /// Radius of the bore, metres; below 90 % of the root radius; default 0.008.
    pub bore_radius: f64,
    /// Subdivision multiplier of the whole tessellation; default 1.
    pub resolution: usize,
}

impl Default for GearOptions {
    fn default() -> Self {
        GearOptions { teeth: 17, module: 0.004, face_width: 0.012, bore_radius: 0.008, resolution: 1 }
    }
}

/// Half-angles of the tooth at the tip and at the root as fractions of half the angular pitch.
const TIP_FRACTION: f64 = 0.3;
const ROOT_FRACTION: f64 = 0.7;

/// Generates the gear. Structure: the group `gear` (generators: rotation by `2π/n`, mirror
/// `y ↦ −y`, mirror `z ↦ −z`; region all) and the instance class `tooth` (`n` rotations; boxes
/// around the part of each tooth outside the root circle).
pub fn gear(o: &GearOptions) -> Result<Example> {
    let res = check_resolution(o.resolution)?;
    let n = o.teeth;
    if !(3..=500).contains(&n) {
        return Err(Error::InvalidOption { name: "teeth", message: format!("need 3 to 500 teeth, got {n}") });
    }
    check_positive("module", o.module)?;
    check_positive("face_width", o.face_width)?;
    check_positive("bore_radius", o.bore_radius)?;
    let r_pitch = 0.5 * o.module * n as f64;
    let r_tip = r_pitch + o.module;
    let r_root = r_pitch - 1.25 * o.module;
    if o.bore_radius >= 0.9 * r_root {
        return Err(Error::InvalidOption {
            name: "bore_radius",
            message: format!("{} leaves no material inside the root radius {r_root:.4}", o.bore_radius),
        });
    }
    let beta = std::f64::consts::PI / n as f64;
    let (a_tip, a_root) = (TIP_FRACTION * beta, ROOT_FRACTION * beta);
    let polar = |r: f64, a: f64| -> Point3 { [r * a.cos(), r * a.sin(), 0.0] };
    // Outer outline of the half sector [0, beta], counter-clockwise: tip arc, flank, root arc.
    let k = 2 * res;
    let mut outer: Vec<Point3> = (0..k).map(|i| polar(r_tip, a_tip * i as f64 / k as f64)).collect();
    let (f0, f1) = (polar(r_tip, a_tip), polar(r_root, a_root));
    outer.extend((0..k).map(|i| {
        let t = i as f64 / k as f64;
        [(1.0 - t) * f0[0] + t * f1[0], (1.0 - t) * f0[1] + t * f1[1], 0.0]
    }));
    outer.extend((0..=k).map(|i| polar(r_root, a_root + (beta - a_root) * i as f64 / k as f64)));
    let teeth_points = 2 * k + 1; // outline points from the tooth's middle to the end of its flank
    let inner: Vec<Point3> = outer.iter().map(|p| polar(o.bore_radius, p[1].atan2(p[0]))).collect();
    let hw = 0.5 * o.face_width;
    let piece = profile_solid(&inner, &outer, [0.0, hw], 3 * res, res, true, true);

    let dihedral = dihedral_elements(n, [0.0, 0.0, 1.0], [0.0; 3], [0.0, 1.0, 0.0]);
    let mid = reflection([0.0, 0.0, 1.0], [0.0; 3]);
    let mut elements = dihedral.clone();
    elements.extend(dihedral.iter().map(|g| mat4_mul(&mid, g)));
    let body = orbit(&piece, &elements);
    let mut asm = Assembly::default();
    asm.add("gear", &body);

    // Tooth boxes: the tooth outline outside the root circle, both halves, both faces.
    let mut tooth: Vec<Point3> = Vec::new();
    for p in &outer[..teeth_points] {
        for s in [1.0, -1.0] {
            for z in [-hw, hw] {
                tooth.push([p[0], s * p[1], z]);
            }
        }
    }
    let mut instances = Vec::new();
    for g in &dihedral[..n] {
        let pts: Vec<Point3> = tooth.iter().map(|p| transform_point(g, *p)).collect();
        let b = crate::geometry::Aabb::from_points(&pts)
            .ok_or_else(|| Error::InvalidInput("empty tooth".into()))?;
        instances.push(Instance { bbox_min: b.min, bbox_max: b.max, transform: *g });
    }
    let ann = Annotator::new(&asm)?;
    let structure = Structure {
        symmetry: SymmetryAnnotation {
            symmetries: vec![ann.group("gear", None, None, vec![dihedral[1], dihedral[n], mid])],
            ..Default::default()
        },
        cell_pitch: Vec::new(),
        cells: None,
        instances: vec![InstanceClass { name: "tooth".into(), instances }],
    };
    Ok(Example { name: "gear".into(), mesh: asm.mesh, structure })
}
