//! Normalisation and the canonical space of the principal offsets (thesis 4.2.2, 4.4, Fig. 4.7).
//!
//! Three spaces are involved:
//! - **model** space: the caller's units;
//! - **normalised** space: the model translated to its bounding-box centre and scaled uniformly so
//!   that its largest dimension spans [−1, 1] (thesis 4.3; the offset detection normalises the
//!   same way, so the thesis's lengths 0.02, 0.06, 0.1, 0.2 apply here);
//! - **canonical** space: normalised space expressed in the basis of the unit principal offsets
//!   `dᵢ = vᵢ / |vᵢ|` (thesis 4.4: "collecting all 3 normalised principle offset vectors into a 3D
//!   transformation matrix"). With `B = [d₁ d₂ d₃]` (columns), `canonical = B⁻¹ · normalised`, so
//!   the offset `vᵢ` becomes `|vᵢ| eᵢ` and the lattice of cells becomes axis-aligned boxes of size
//!   `|v₁| × |v₂| × |v₃|`. For orthogonal offsets `B` is orthonormal (a rotation, possibly with
//!   a reflection) and lengths are kept; for sheared grids it removes the shear.
//!
//! Fewer than three offsets are completed by dummy directions of length 0.2 (normalised units,
//! thesis 4.4) orthogonal to the given ones; they only discretise the model.

use motif_core::geometry::{Mat4, Point3, cross, dot, norm, normalize, scale, sub};
use motif_core::mesh::TriMesh;

use super::error::{RetargetError, RetargetResult};
pub use crate::offsets::Normalisation;

/// The normalisation of a mesh's bounding box (the offset detection's [`Normalisation`], so that
/// both stages share normalised units).
pub(crate) fn normalisation_of(mesh: &TriMesh) -> RetargetResult<Normalisation> {
    let bb = mesh.aabb().ok_or(RetargetError::DegenerateMesh)?;
    Normalisation::from_bounds(bb.min, bb.max).map_err(|_| RetargetError::DegenerateMesh)
}

/// `normalised_from_model` as a row-major 4×4 matrix.
pub(crate) fn normalised_from_model(n: &Normalisation) -> Mat4 {
    let s = n.scale;
    let c = n.centre;
    [[s, 0.0, 0.0, -s * c[0]], [0.0, s, 0.0, -s * c[1]], [0.0, 0.0, s, -s * c[2]], [0.0, 0.0, 0.0, 1.0]]
}

/// A 3×3 matrix, row-major.
pub type Mat3 = [[f64; 3]; 3];

/// The lattice the voxel grid is built on: canonical axes, cell sizes, and the model-space
/// translation of one step along each axis.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Lattice {
    /// Model → normalised space.
    pub normalisation: Normalisation,
    /// `B⁻¹`: normalised → canonical (linear).
    pub canonical_from_normalised: Mat3,
    /// Cell edge length along each canonical axis, normalised units (`|vᵢ|`, or the dummy length).
    pub pitch: [f64; 3],
    /// Translation of one step along each axis, model units (`vᵢ` itself for principal offsets).
    pub step_model: [Point3; 3],
    /// Number of axes along which steps are allowed (the principal offsets, or 3 for the dense
    /// baseline). Axes `num_active..3` are dummies.
    pub num_active: usize,
}

/// Smallest accepted angle between two principal offsets (and of the third out of the plane of
/// the first two): 5°. The thesis's detector keeps 60° (4.4); smaller angles make the canonical
/// map nearly singular.
const MIN_SIN_ANGLE: f64 = 0.087;

impl Lattice {
    /// The lattice of the principal offsets `offsets` (model units, 1–3 vectors), completed by
    /// dummy directions of normalised length `dummy_length`.
    pub fn from_offsets(
        normalisation: Normalisation,
        offsets: &[Point3],
        dummy_length: f64,
    ) -> RetargetResult<Lattice> {
        let bad = |message: String| RetargetError::InvalidOffsets { message };
        if offsets.is_empty() || offsets.len() > 3 {
            return Err(bad(format!(
                "{} vectors given; give 1 to 3 principal offsets (thesis 4.2.1 keeps up to three)",
                offsets.len()
            )));
        }
        let mut dirs: Vec<Point3> = Vec::with_capacity(3);
        let mut pitch = [dummy_length; 3];
        let mut step_model = [[0.0; 3]; 3];
        for (i, o) in offsets.iter().enumerate() {
            if !o.iter().all(|c| c.is_finite()) {
                return Err(bad(format!("offset {i} = {o:?} is not finite")));
            }
            // In normalised units first: squaring model units overflows for models far from the
            // unit range (a shelf at 10²⁰⁰ had its offsets called of zero length).
            let o_normalised = scale(*o, normalisation.scale);
            let len = norm(o_normalised);
            // A cell smaller than 10⁻⁶ of the normalised model is certainly a mistake (and would
            // need more than 10¹² voxels).
            if len < 1e-6 {
                return Err(bad(format!(
                    "offset {i} = {o:?} has (nearly) zero length; principal offsets are the cell \
                     sizes of the repetition, in model units"
                )));
            }
            let d =
                normalize(o_normalised).ok_or_else(|| bad(format!("offset {i} = {o:?} has zero length")))?;
            for (j, e) in dirs.iter().enumerate() {
                let sin = norm(cross(*e, d));
                if sin < MIN_SIN_ANGLE {
                    return Err(bad(format!(
                        "offsets {j} and {i} are (nearly) parallel ({:.1}° apart); principal \
                         offsets must span independent directions",
                        sin.asin().to_degrees()
                    )));
                }
            }
            if dirs.len() == 2 {
                let n = normalize(cross(dirs[0], dirs[1])).unwrap_or([0.0; 3]);
                if dot(n, d).abs() < MIN_SIN_ANGLE {
                    return Err(bad(
                        "the third offset lies (nearly) in the plane of the first two".to_string()
                    ));
                }
            }
            dirs.push(d);
            pitch[i] = len;
            step_model[i] = *o;
        }
        let num_active = dirs.len();
        // Dummy directions, orthogonal to the given ones (thesis 4.4).
        if dirs.len() == 1 {
            let u = dirs[0];
            // The world axis least aligned with u (first one on ties), made orthogonal to u: for
            // an offset along x this is y, then z, so the grid stays aligned with the box.
            let axes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
            let mut best = axes[0];
            let mut best_dot = f64::INFINITY;
            for a in axes {
                let c = dot(a, u).abs();
                if c < best_dot - 1e-12 {
                    best_dot = c;
                    best = a;
                }
            }
            let d2 = normalize(sub(best, scale(u, dot(best, u))))
                .ok_or_else(|| bad("cannot complete the frame of offset 0".into()))?;
            dirs.push(d2);
        }
        if dirs.len() == 2 {
            let mut d3 = normalize(cross(dirs[0], dirs[1]))
                .ok_or_else(|| bad("offsets 0 and 1 are parallel".into()))?;
            // Sign convention: the largest component positive (z for offsets in the xy plane).
            let k = (0..3).fold(0, |k, a| if d3[a].abs() > d3[k].abs() + 1e-12 { a } else { k });
            if d3[k] < 0.0 {
                d3 = scale(d3, -1.0);
            }
            dirs.push(d3);
        }
        for a in num_active..3 {
            step_model[a] = scale(dirs[a], dummy_length / normalisation.scale);
        }
        // B has the unit directions as columns.
        let b: Mat3 = [
            [dirs[0][0], dirs[1][0], dirs[2][0]],
            [dirs[0][1], dirs[1][1], dirs[2][1]],
            [dirs[0][2], dirs[1][2], dirs[2][2]],
        ];
        let canonical_from_normalised =
            invert3(&b).ok_or_else(|| bad("the principal offsets do not span a frame".into()))?;
        Ok(Lattice { normalisation, canonical_from_normalised, pitch, step_model, num_active })
    }

    /// The dense baseline of thesis 4.5: regular axis-aligned offsets of length `spacing`
    /// (normalised units) along the world axes, no canonical map.
    pub fn regular(normalisation: Normalisation, spacing: f64) -> Lattice {
        let h = spacing / normalisation.scale;
        Lattice {
            normalisation,
            canonical_from_normalised: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            pitch: [spacing; 3],
            step_model: [[h, 0.0, 0.0], [0.0, h, 0.0], [0.0, 0.0, h]],
            num_active: 3,
        }
    }

    /// A model-space point in canonical space.
    #[inline]
    pub fn canonical(&self, p: Point3) -> Point3 {
        mul3(&self.canonical_from_normalised, self.normalisation.to_normalised(p))
    }

    /// A normalised-space point in canonical space.
    #[inline]
    pub fn canonical_of_normalised(&self, p: Point3) -> Point3 {
        mul3(&self.canonical_from_normalised, p)
    }

    /// A normalised-space vector in canonical space.
    #[inline]
    pub fn canonical_vector(&self, v: Point3) -> Point3 {
        mul3(&self.canonical_from_normalised, v)
    }

    /// The model-space translation of the integer step vector `k`.
    #[inline]
    pub fn translation(&self, k: [i32; 3]) -> Point3 {
        let mut t = [0.0; 3];
        for a in 0..3 {
            if k[a] != 0 {
                for c in 0..3 {
                    t[c] += k[a] as f64 * self.step_model[a][c];
                }
            }
        }
        t
    }
}

/// `m · v`.
#[inline]
pub fn mul3(m: &Mat3, v: Point3) -> Point3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

/// The inverse of a 3×3 matrix, `None` when it is (numerically) singular.
pub fn invert3(m: &Mat3) -> Option<Mat3> {
    let c0 = cross(m[1], m[2]);
    let det = dot(m[0], c0);
    if det.is_nan() || det.abs() <= 1e-12 {
        return None;
    }
    let c1 = cross(m[2], m[0]);
    let c2 = cross(m[0], m[1]);
    // The inverse's columns are the cofactor rows divided by det.
    let inv = 1.0 / det;
    Some([
        [c0[0] * inv, c1[0] * inv, c2[0] * inv],
        [c0[1] * inv, c1[1] * inv, c2[1] * inv],
        [c0[2] * inv, c1[2] * inv, c2[2] * inv],
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_norm() -> Normalisation {
        Normalisation { centre: [0.0; 3], scale: 1.0 }
    }

    #[test]
    fn sheared_offsets_become_axes() {
        let v1 = [0.4, 0.0, 0.0];
        let v2 = [0.15, 0.37, 0.0];
        let l = Lattice::from_offsets(unit_norm(), &[v1, v2], 0.2).unwrap();
        let c1 = l.canonical(v1);
        let c2 = l.canonical(v2);
        assert!((c1[0] - norm(v1)).abs() < 1e-12 && c1[1].abs() < 1e-12 && c1[2].abs() < 1e-12);
        assert!(c2[0].abs() < 1e-12 && (c2[1] - norm(v2)).abs() < 1e-12 && c2[2].abs() < 1e-12);
        assert_eq!(l.pitch[2], 0.2);
        assert_eq!(l.num_active, 2);
        let t = l.translation([2, -1, 0]);
        assert!(motif_core::geometry::dist(t, [0.65, -0.37, 0.0]) < 1e-12);
    }

    #[test]
    fn one_offset_gets_orthogonal_dummies_along_the_other_axes() {
        let l = Lattice::from_offsets(unit_norm(), &[[1.5, 0.0, 0.0]], 0.2).unwrap();
        let y = l.canonical([0.0, 1.0, 0.0]);
        let z = l.canonical([0.0, 0.0, 1.0]);
        assert!((y[1] - 1.0).abs() < 1e-12 && (z[2] - 1.0).abs() < 1e-12);
        assert_eq!(l.pitch, [1.5, 0.2, 0.2]);
    }

    #[test]
    fn rejects_parallel_zero_and_too_many_offsets() {
        let n = unit_norm();
        assert!(Lattice::from_offsets(n, &[], 0.2).is_err());
        assert!(Lattice::from_offsets(n, &[[1.0, 0.0, 0.0]; 4], 0.2).is_err());
        assert!(Lattice::from_offsets(n, &[[0.0; 3]], 0.2).is_err());
        assert!(Lattice::from_offsets(n, &[[f64::NAN, 0.0, 0.0]], 0.2).is_err());
        assert!(Lattice::from_offsets(n, &[[1.0, 0.0, 0.0], [2.0, 0.01, 0.0]], 0.2).is_err());
        assert!(
            Lattice::from_offsets(n, &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.01]], 0.2).is_err()
        );
    }

    #[test]
    fn normalisation_maps_the_largest_dimension_to_minus_one_one() {
        let m =
            TriMesh::new(vec![[1.0, 2.0, 3.0], [5.0, 3.0, 3.5], [2.0, 2.5, 4.0]], vec![[0, 1, 2]]).unwrap();
        let n = normalisation_of(&m).unwrap();
        assert!((n.to_normalised([1.0, 2.0, 3.0])[0] + 1.0).abs() < 1e-12);
        assert!((n.to_normalised([5.0, 2.0, 3.0])[0] - 1.0).abs() < 1e-12);
        let p = motif_core::geometry::transform_point(&normalised_from_model(&n), [5.0, 3.0, 3.5]);
        assert!(motif_core::geometry::dist(p, n.to_normalised([5.0, 3.0, 3.5])) < 1e-12);
    }
}
