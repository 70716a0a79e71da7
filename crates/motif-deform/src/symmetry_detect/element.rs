//! Symmetry elements (mirror planes, rotation axes, rotoreflection axes, inversion centres) and
//! their small-perturbation parametrisation used by the refinement.

use std::f64::consts::TAU;

use motif_core::Point3;
use motif_core::geometry::{Mat4, add, any_orthonormal, cross, dot, mat4_mul, normalize, scale, sub};
use motif_core::procedural::{reflection, rotation_about};
use serde::{Deserialize, Serialize};

/// A symmetry element: an isometry with a fixed point, described geometrically.
///
/// Directions are unit vectors; `point` is a point on the plane / axis (after refinement, the
/// point of the axis or plane closest to the shape's centre).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SymmetryElement {
    /// The reflection in the plane through `point` with unit normal `normal`.
    Mirror {
        /// Unit plane normal (sign is arbitrary).
        normal: Point3,
        /// A point of the plane.
        point: Point3,
    },
    /// The rotation by `2π / order` about the line through `point` with unit direction `axis`
    /// (right-hand rule); its powers are rotations by the divisors' angles.
    Rotation {
        /// Unit axis direction.
        axis: Point3,
        /// A point of the axis.
        point: Point3,
        /// The order `n ≥ 2` (the rotation angle is `2π / n`).
        order: u32,
    },
    /// The rotoreflection `S_n`: the rotation by `2π / order` about the axis, followed by the
    /// reflection in the plane through `point` perpendicular to the axis.
    RotoReflection {
        /// Unit axis direction.
        axis: Point3,
        /// The fixed point (on the axis, in the plane).
        point: Point3,
        /// `n ≥ 3` (the rotation part's angle is `2π / n`).
        order: u32,
    },
    /// The point reflection `x ↦ 2 c − x`.
    Inversion {
        /// The centre `c`.
        center: Point3,
    },
}

impl SymmetryElement {
    /// The element as a row-major 4×4 matrix acting on column vectors.
    pub fn matrix(&self) -> Mat4 {
        match *self {
            SymmetryElement::Mirror { normal, point } => reflection(normal, point),
            SymmetryElement::Rotation { axis, point, order } => {
                rotation_about(axis, point, TAU / f64::from(order.max(1)))
            }
            SymmetryElement::RotoReflection { axis, point, order } => mat4_mul(
                &reflection(axis, point),
                &rotation_about(axis, point, TAU / f64::from(order.max(1))),
            ),
            SymmetryElement::Inversion { center } => {
                let mut m = [[0.0; 4]; 4];
                for k in 0..3 {
                    m[k][k] = -1.0;
                    m[k][3] = 2.0 * center[k];
                }
                m[3][3] = 1.0;
                m
            }
        }
    }

    /// Number of refinement parameters (degrees of freedom of the element with its type and
    /// order fixed).
    pub(crate) fn dof(&self) -> usize {
        match self {
            SymmetryElement::Mirror { .. } => 3,
            SymmetryElement::Rotation { .. } => 4,
            SymmetryElement::RotoReflection { .. } => 5,
            SymmetryElement::Inversion { .. } => 3,
        }
    }

    /// The element moved by the parameters `p` (`dof()` of them): tilts of the normal / axis in
    /// radians, shifts in units of `length`.
    pub(crate) fn perturbed(&self, p: &[f64], length: f64) -> SymmetryElement {
        let tilt = |d: Point3, u1: f64, u2: f64| -> (Point3, Point3, Point3) {
            let e1 = any_orthonormal(d);
            let e2 = cross(d, e1);
            let nd = normalize(add(d, add(scale(e1, u1), scale(e2, u2)))).unwrap_or(d);
            (nd, e1, e2)
        };
        match *self {
            SymmetryElement::Mirror { normal, point } => {
                let (n, _, _) = tilt(normal, p[0], p[1]);
                SymmetryElement::Mirror { normal: n, point: add(point, scale(normal, p[2] * length)) }
            }
            SymmetryElement::Rotation { axis, point, order } => {
                let (a, e1, e2) = tilt(axis, p[0], p[1]);
                let shift = add(scale(e1, p[2] * length), scale(e2, p[3] * length));
                SymmetryElement::Rotation { axis: a, point: add(point, shift), order }
            }
            SymmetryElement::RotoReflection { axis, point, order } => {
                let (a, e1, e2) = tilt(axis, p[0], p[1]);
                let shift =
                    add(add(scale(e1, p[2] * length), scale(e2, p[3] * length)), scale(axis, p[4] * length));
                SymmetryElement::RotoReflection { axis: a, point: add(point, shift), order }
            }
            SymmetryElement::Inversion { center } => {
                SymmetryElement::Inversion { center: add(center, scale([p[0], p[1], p[2]], length)) }
            }
        }
    }

    /// The same element with its point moved to the point of the plane / axis closest to `c`
    /// (the inversion centre is unchanged), and its direction's sign made canonical (largest
    /// component positive).
    pub(crate) fn canonical(&self, c: Point3) -> SymmetryElement {
        match *self {
            SymmetryElement::Mirror { normal, point } => {
                let n = canonical_sign(normal);
                SymmetryElement::Mirror { normal: n, point: sub(c, scale(n, dot(sub(c, point), n))) }
            }
            SymmetryElement::Rotation { axis, point, order } => {
                // The sign of the axis matters for the direction of turning; keep it as is.
                SymmetryElement::Rotation { axis, point: closest_on_line(c, point, axis), order }
            }
            SymmetryElement::RotoReflection { axis, point, order } => {
                SymmetryElement::RotoReflection { axis, point, order }
            }
            e @ SymmetryElement::Inversion { .. } => e,
        }
    }

    /// The direction of the element (plane normal or axis); `None` for an inversion.
    pub fn direction(&self) -> Option<Point3> {
        match *self {
            SymmetryElement::Mirror { normal, .. } => Some(normal),
            SymmetryElement::Rotation { axis, .. } | SymmetryElement::RotoReflection { axis, .. } => {
                Some(axis)
            }
            SymmetryElement::Inversion { .. } => None,
        }
    }

    /// A short human-readable description ("mirror plane normal [0.000, 1.000, 0.000]").
    pub fn describe(&self) -> String {
        match *self {
            SymmetryElement::Mirror { normal, point } => {
                format!("mirror plane normal {} through {}", fmt3(normal), fmt3(point))
            }
            SymmetryElement::Rotation { axis, point, order } => {
                format!("rotation C{order} about axis {} through {}", fmt3(axis), fmt3(point))
            }
            SymmetryElement::RotoReflection { axis, point, order } => {
                format!("rotoreflection S{order} about axis {} through {}", fmt3(axis), fmt3(point))
            }
            SymmetryElement::Inversion { center } => format!("inversion through {}", fmt3(center)),
        }
    }
}

/// `[x, y, z]` with three decimals.
pub(crate) fn fmt3(p: Point3) -> String {
    let z = |x: f64| if x.abs() < 5e-4 { 0.0 } else { x };
    format!("[{:.3}, {:.3}, {:.3}]", z(p[0]), z(p[1]), z(p[2]))
}

/// `d` or `−d`, whichever has its largest-magnitude component positive.
pub(crate) fn canonical_sign(d: Point3) -> Point3 {
    let k = (0..3).max_by(|&i, &j| d[i].abs().total_cmp(&d[j].abs())).unwrap_or(0);
    if d[k] < 0.0 { scale(d, -1.0) } else { d }
}

/// The point of the line through `p` with unit direction `a` closest to `q`.
pub(crate) fn closest_on_line(q: Point3, p: Point3, a: Point3) -> Point3 {
    add(p, scale(a, dot(sub(q, p), a)))
}

/// The angle in radians between the lines spanned by unit vectors `a` and `b` (0 to π/2).
pub(crate) fn line_angle(a: Point3, b: Point3) -> f64 {
    dot(a, b).abs().min(1.0).acos()
}

#[cfg(test)]
mod tests {
    use super::*;
    use motif_core::geometry::{dist, transform_point};

    #[test]
    fn matrices_act_as_described() {
        let c = [1.0, 2.0, 3.0];
        let inv = SymmetryElement::Inversion { center: c }.matrix();
        assert!(dist(transform_point(&inv, [2.0, 2.0, 3.0]), [0.0, 2.0, 3.0]) < 1e-12);
        let s4 =
            SymmetryElement::RotoReflection { axis: [0.0, 0.0, 1.0], point: [0.0; 3], order: 4 }.matrix();
        assert!(dist(transform_point(&s4, [1.0, 0.0, 1.0]), [0.0, 1.0, -1.0]) < 1e-12);
        let r =
            SymmetryElement::Rotation { axis: [0.0, 0.0, 1.0], point: [1.0, 0.0, 0.0], order: 2 }.matrix();
        assert!(dist(transform_point(&r, [2.0, 0.0, 5.0]), [0.0, 0.0, 5.0]) < 1e-12);
    }

    #[test]
    fn zero_perturbation_is_identity() {
        let e = SymmetryElement::Rotation { axis: [0.0, 0.6, 0.8], point: [1.0, 0.0, 0.0], order: 5 };
        assert_eq!(e.perturbed(&[0.0; 4], 2.0), e);
        let m = SymmetryElement::Mirror { normal: [0.0, -1.0, 0.0], point: [0.0, 2.0, 0.0] };
        let cm = m.canonical([5.0, 0.0, 1.0]);
        assert_eq!(cm, SymmetryElement::Mirror { normal: [0.0, 1.0, 0.0], point: [5.0, 2.0, 1.0] });
    }
}
