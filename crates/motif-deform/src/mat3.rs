//! 3×3 and rigid 4×4 helpers on plain arrays (row-major, acting on column vectors).

use motif_core::geometry::{Mat4, Point3};

/// A row-major 3×3 matrix.
pub type Mat3 = [[f64; 3]; 3];

/// The 3×3 identity.
pub const IDENTITY3: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// The upper-left 3×3 (linear part) of a 4×4 transform.
#[inline]
pub fn linear_part(m: &Mat4) -> Mat3 {
    [[m[0][0], m[0][1], m[0][2]], [m[1][0], m[1][1], m[1][2]], [m[2][0], m[2][1], m[2][2]]]
}

/// `a · v`.
#[inline]
pub fn mul_vec(a: &Mat3, v: Point3) -> Point3 {
    [
        a[0][0] * v[0] + a[0][1] * v[1] + a[0][2] * v[2],
        a[1][0] * v[0] + a[1][1] * v[1] + a[1][2] * v[2],
        a[2][0] * v[0] + a[2][1] * v[1] + a[2][2] * v[2],
    ]
}

/// `a · b`.
#[inline]
pub fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    r
}

/// `aᵀ`.
#[inline]
pub fn transpose(a: &Mat3) -> Mat3 {
    [[a[0][0], a[1][0], a[2][0]], [a[0][1], a[1][1], a[2][1]], [a[0][2], a[1][2], a[2][2]]]
}

/// Largest absolute entry of `a − b`.
#[inline]
pub fn max_abs_diff(a: &Mat3, b: &Mat3) -> f64 {
    let mut m: f64 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            m = m.max((a[i][j] - b[i][j]).abs());
        }
    }
    m
}

/// How far a 4×4 matrix is from an affine map with orthogonal linear part: the largest entry of
/// `|OᵀO − I|` and of the last row's deviation from `0 0 0 1`; infinity for non-finite entries.
pub fn rigidity_deviation(m: &Mat4) -> f64 {
    if m.iter().flatten().any(|x| !x.is_finite()) {
        return f64::INFINITY;
    }
    let o = linear_part(m);
    let oto = mul(&transpose(&o), &o);
    let mut d = max_abs_diff(&oto, &IDENTITY3);
    for (j, e) in [0.0, 0.0, 0.0, 1.0].iter().enumerate() {
        d = d.max((m[3][j] - e).abs());
    }
    d
}

/// True when `a` and `b` are the same rigid map within `lin_tol` (entries of the linear part) and
/// `trans_tol` (translation, mesh units).
#[inline]
pub fn rigid_approx_eq(a: &Mat4, b: &Mat4, lin_tol: f64, trans_tol: f64) -> bool {
    (0..3).all(|i| (0..3).all(|j| (a[i][j] - b[i][j]).abs() <= lin_tol))
        && (0..3).map(|i| (a[i][3] - b[i][3]).powi(2)).sum::<f64>().sqrt() <= trans_tol
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rigidity() {
        let m = motif_core::procedural::rotation_about([0.0, 0.0, 1.0], [1.0, 2.0, 0.0], 0.3);
        assert!(rigidity_deviation(&m) < 1e-12);
        let mut s = m;
        s[0][0] *= 1.1;
        assert!(rigidity_deviation(&s) > 1e-2);
        let mut p = m;
        p[3][0] = 0.5;
        assert!(rigidity_deviation(&p) >= 0.5);
    }
}
