//! Small vector helpers on `[f64; 3]`, axis-aligned boxes, and 4×4 rigid transforms.
//!
//! Positions stay plain arrays so callers never need an internal type; these helpers keep the
//! arithmetic readable. nalgebra is used where real 3×3 linear algebra (SVD, eigen) is needed.

use serde::{Deserialize, Serialize};

/// A point or vector in 3-D, in f64.
pub type Point3 = [f64; 3];

/// A row-major 4×4 matrix acting on column vectors (`p' = M p`), as in the shared JSON formats.
pub type Mat4 = [[f64; 4]; 4];

/// `a + b`.
#[inline]
pub fn add(a: Point3, b: Point3) -> Point3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a - b`.
#[inline]
pub fn sub(a: Point3, b: Point3) -> Point3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `s * a`.
#[inline]
pub fn scale(a: Point3, s: f64) -> Point3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Dot product.
#[inline]
pub fn dot(a: Point3, b: Point3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Cross product `a × b`.
#[inline]
pub fn cross(a: Point3, b: Point3) -> Point3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Euclidean length.
#[inline]
pub fn norm(a: Point3) -> f64 {
    dot(a, a).sqrt()
}

/// Squared distance between two points.
#[inline]
pub fn dist2(a: Point3, b: Point3) -> f64 {
    let d = sub(a, b);
    dot(d, d)
}

/// Distance between two points.
#[inline]
pub fn dist(a: Point3, b: Point3) -> f64 {
    dist2(a, b).sqrt()
}

/// `a / |a|`, or `None` when `|a|` is zero or not finite.
#[inline]
pub fn normalize(a: Point3) -> Option<Point3> {
    let n = norm(a);
    (n > 0.0 && n.is_finite()).then(|| scale(a, 1.0 / n))
}

/// Linear interpolation `a + t (b - a)`.
#[inline]
pub fn lerp(a: Point3, b: Point3, t: f64) -> Point3 {
    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])]
}

/// True when all three coordinates are finite.
#[inline]
pub fn is_finite(a: Point3) -> bool {
    a.iter().all(|c| c.is_finite())
}

/// An axis-aligned bounding box.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Point3,
    /// Largest corner.
    pub max: Point3,
}

impl Aabb {
    /// The box of a set of points, or `None` when the set is empty.
    pub fn from_points(points: &[Point3]) -> Option<Aabb> {
        let first = *points.first()?;
        let mut b = Aabb { min: first, max: first };
        for p in points {
            b.grow(*p);
        }
        Some(b)
    }

    /// Enlarges the box to contain `p`.
    pub fn grow(&mut self, p: Point3) {
        for k in 0..3 {
            self.min[k] = self.min[k].min(p[k]);
            self.max[k] = self.max[k].max(p[k]);
        }
    }

    /// The eight corners; corner `k` takes `max` on axis `d` when bit `d` of `k` is set.
    pub fn corners(&self) -> [Point3; 8] {
        std::array::from_fn(|k| {
            std::array::from_fn(|d| if k >> d & 1 == 0 { self.min[d] } else { self.max[d] })
        })
    }

    /// The box of this box's corners moved by `f` (for a rigid motion: the axis-aligned box of
    /// the moved box).
    ///
    /// The corners are collected before the box is taken. rustc 1.95.0 at opt-level 3 miscompiled
    /// the obvious loop (grow an `Option<Aabb>` corner by corner with a quaternion rotation
    /// inlined): the last corner was dropped from one axis, and detection results changed with
    /// unrelated edits. Rust 1.97.1 fixes it; `motif_detect::instances` tests it.
    pub fn mapped(&self, f: impl Fn(Point3) -> Point3) -> Aabb {
        Aabb::from_points(&self.corners().map(f)).unwrap_or(*self)
    }

    /// Edge lengths.
    pub fn extent(&self) -> Point3 {
        sub(self.max, self.min)
    }

    /// Length of the diagonal, the unit of every "relative" tolerance in Motif.
    pub fn diagonal(&self) -> f64 {
        norm(self.extent())
    }

    /// Centre of the box.
    pub fn center(&self) -> Point3 {
        lerp(self.min, self.max, 0.5)
    }

    /// True when `p` lies in the closed box.
    pub fn contains(&self, p: Point3) -> bool {
        (0..3).all(|k| p[k] >= self.min[k] && p[k] <= self.max[k])
    }

    /// Volume of the box (zero for flat boxes).
    pub fn volume(&self) -> f64 {
        let e = self.extent();
        e[0].max(0.0) * e[1].max(0.0) * e[2].max(0.0)
    }

    /// Intersection of two boxes, `None` when they do not overlap.
    pub fn intersection(&self, other: &Aabb) -> Option<Aabb> {
        let mut r = *self;
        for k in 0..3 {
            r.min[k] = self.min[k].max(other.min[k]);
            r.max[k] = self.max[k].min(other.max[k]);
            if r.min[k] > r.max[k] {
                return None;
            }
        }
        Some(r)
    }
}

/// The 4×4 identity.
pub const IDENTITY4: Mat4 =
    [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];

/// Applies an affine 4×4 transform to a point (the last row is assumed to be `0 0 0 1`).
#[inline]
pub fn transform_point(m: &Mat4, p: Point3) -> Point3 {
    [
        m[0][0] * p[0] + m[0][1] * p[1] + m[0][2] * p[2] + m[0][3],
        m[1][0] * p[0] + m[1][1] * p[1] + m[1][2] * p[2] + m[1][3],
        m[2][0] * p[0] + m[2][1] * p[1] + m[2][2] * p[2] + m[2][3],
    ]
}

/// Applies the linear part of a 4×4 transform to a vector (no translation).
#[inline]
pub fn transform_vector(m: &Mat4, v: Point3) -> Point3 {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

/// Matrix product `a · b` (apply `b` first, then `a`).
pub fn mat4_mul(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut r = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            r[i][j] = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    r
}

/// Builds a rigid transform from a row-major 3×3 rotation and a translation.
pub fn mat4_from_rt(r: [[f64; 3]; 3], t: Point3) -> Mat4 {
    [
        [r[0][0], r[0][1], r[0][2], t[0]],
        [r[1][0], r[1][1], r[1][2], t[1]],
        [r[2][0], r[2][1], r[2][2], t[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// The rotation by `angle` radians about the unit `axis` through the origin (Rodrigues).
pub fn rotation_about_axis(axis: Point3, angle: f64) -> [[f64; 3]; 3] {
    let [x, y, z] = normalize(axis).unwrap_or([0.0, 0.0, 1.0]);
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

/// `x` as text with `decimals` decimals, in scientific notation instead when the model's size
/// `scale` is below 10⁻³ or above 10⁶, where fixed decimals would print a model 10⁻⁹ across as
/// zeros (or one 10⁹ across with twelve digits before the point).
pub fn format_length(x: f64, scale: f64, decimals: usize) -> String {
    let scale = scale.abs();
    let text = if scale == 0.0 || (1e-3..=1e6).contains(&scale) || !scale.is_finite() {
        format!("{x:.decimals$}")
    } else {
        format!("{x:.decimals$e}")
    };
    // A tiny negative rounds to "-0.000000": printed as the zero it is.
    match text.strip_prefix('-') {
        Some(rest)
            if rest.split(['e', 'E']).next().is_some_and(|m| m.chars().all(|c| c == '0' || c == '.')) =>
        {
            rest.to_string()
        }
        _ => text,
    }
}

/// Any unit vector orthogonal to the unit vector `n` (stable for every direction).
pub fn any_orthonormal(n: Point3) -> Point3 {
    let a = if n[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    normalize(cross(n, a)).unwrap_or([0.0, 0.0, 1.0])
}

/// The point of triangle `abc` closest to `p`: classifies `p` against the Voronoi regions of the
/// corners, then the edges, then the face, using barycentric quantities only (Ericson, Real-Time
/// Collision Detection, 5.1.5). A zero-area triangle gives its closest corner.
pub fn closest_point_on_triangle(p: Point3, a: Point3, b: Point3, c: Point3) -> Point3 {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return add(a, scale(ab, v));
    }
    let cp = sub(p, c);
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return add(a, scale(ac, w));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return add(b, scale(sub(c, b), w));
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE {
        // A degenerate (zero-area) triangle that slipped through: its closest corner.
        return [a, b, c].into_iter().min_by(|x, y| dist2(p, *x).total_cmp(&dist2(p, *y))).unwrap_or(a);
    }
    let v = vb / denom;
    let w = vc / denom;
    add(a, add(scale(ab, v), scale(ac, w)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths_keep_their_digits_at_every_scale() {
        assert_eq!(format_length(0.42, 1.0, 4), "0.4200");
        assert_eq!(format_length(4.2e-10, 1e-9, 4), "4.2000e-10");
        assert_eq!(format_length(4.2e8, 1e9, 2), "4.20e8");
        assert_eq!(format_length(0.0, 0.0, 3), "0.000");
        // A tiny negative is the zero it rounds to, not "-0.000".
        assert_eq!(format_length(-3e-9, 1.0, 3), "0.000");
        assert_eq!(format_length(-0.25, 1.0, 2), "-0.25");
        assert_eq!(format_length(-0.0, 1e-9, 2), "0.00e0");
        assert_eq!(format_length(-1e-20, 1e-9, 2), "-1.00e-20");
    }

    #[test]
    fn rotation_is_orthogonal_and_turns_x_to_y() {
        let r = rotation_about_axis([0.0, 0.0, 1.0], std::f64::consts::FRAC_PI_2);
        let m = mat4_from_rt(r, [0.0; 3]);
        let p = transform_point(&m, [1.0, 0.0, 0.0]);
        assert!(dist(p, [0.0, 1.0, 0.0]) < 1e-12);
        let rt = mat4_mul(&m, &mat4_from_rt(transpose3(r), [0.0; 3]));
        for i in 0..4 {
            for j in 0..4 {
                let e = if i == j { 1.0 } else { 0.0 };
                assert!((rt[i][j] - e).abs() < 1e-12);
            }
        }
    }

    fn transpose3(r: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
        let mut t = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                t[i][j] = r[j][i];
            }
        }
        t
    }

    #[test]
    fn aabb_intersection_and_volume() {
        let a = Aabb { min: [0.0; 3], max: [2.0; 3] };
        let b = Aabb { min: [1.0; 3], max: [3.0; 3] };
        assert_eq!(a.intersection(&b).map(|i| i.volume()), Some(1.0));
        let c = Aabb { min: [5.0; 3], max: [6.0; 3] };
        assert!(a.intersection(&c).is_none());
    }
}
