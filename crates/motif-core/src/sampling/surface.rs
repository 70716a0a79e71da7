//! Seeded, area-weighted random sampling of a triangle mesh's surface.
//!
//! Each sample picks a triangle with probability proportional to its area (binary search in the
//! prefix sum of areas) and a uniform point in it (`√r₁` barycentric mapping). Samples are drawn in
//! fixed-size blocks, block `b` from its own ChaCha8 stream `b` of the seed, so the result is
//! identical for every thread count and the blocks run in parallel.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::geometry::Point3;
use crate::mesh::TriMesh;
use crate::{Error, Result};

/// Samples per random stream (and per parallel task).
const BLOCK: usize = 4096;

/// Random points on a surface with the triangle each lies in.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceSamples {
    /// Sample positions, `#S × 3`.
    pub points: Vec<Point3>,
    /// Unit normal of the triangle each sample lies in (the face normal), `#S × 3`.
    pub normals: Vec<Point3>,
    /// Index of the triangle each sample lies in, `#S`.
    pub faces: Vec<u32>,
    /// Barycentric coordinates of each sample in its triangle's corners `[a, b, c]` (non-negative,
    /// summing to 1), `#S × 3`.
    pub barycentric: Vec<[f64; 3]>,
}

impl SurfaceSamples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// Prefix sums of the triangle areas (`cdf[f]` = area of triangles `0..=f`), and unit face normals.
pub(crate) fn area_cdf(mesh: &TriMesh) -> Result<(Vec<f64>, Vec<Point3>)> {
    mesh.validate()?;
    let areas = mesh.face_areas();
    let mut cdf = Vec::with_capacity(areas.len());
    let mut acc = 0.0;
    for a in areas {
        acc += a;
        cdf.push(acc);
    }
    if !acc.is_finite() {
        return Err(Error::InvalidInput(
            "cannot sample a surface whose area overflows (coordinates too large to square; rescale it)"
                .into(),
        ));
    }
    if acc <= 0.0 {
        return Err(Error::InvalidInput(
            "cannot sample a surface of zero area (no non-degenerate triangle)".into(),
        ));
    }
    Ok((cdf, mesh.face_normals()))
}

/// `n` samples distributed uniformly by area over the surface of `mesh`, deterministic for a
/// `seed` (and independent of the number of threads). Fails on a mesh without area.
pub fn sample_surface(mesh: &TriMesh, n: usize, seed: u64) -> Result<SurfaceSamples> {
    let (cdf, normals) = area_cdf(mesh)?;
    let total = *cdf.last().unwrap_or(&0.0);
    // The last triangle with positive area: a draw of exactly `total` lands there.
    let last_positive = (0..cdf.len()).rev().find(|&f| f == 0 || cdf[f] > cdf[f - 1]).unwrap_or(0);
    let blocks: Vec<Vec<(Point3, u32, [f64; 3])>> = (0..n.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(b as u64);
            let count = BLOCK.min(n - b * BLOCK);
            (0..count)
                .map(|_| {
                    let x = rng.random::<f64>() * total;
                    let f = cdf.partition_point(|&c| c <= x).min(last_positive);
                    let (r1, r2): (f64, f64) = (rng.random(), rng.random());
                    let s = r1.sqrt();
                    let bary = [1.0 - s, s * (1.0 - r2), s * r2];
                    let [a, bb, c] = mesh.corners(f);
                    let p = [
                        bary[0] * a[0] + bary[1] * bb[0] + bary[2] * c[0],
                        bary[0] * a[1] + bary[1] * bb[1] + bary[2] * c[1],
                        bary[0] * a[2] + bary[1] * bb[2] + bary[2] * c[2],
                    ];
                    (p, f as u32, bary)
                })
                .collect()
        })
        .collect();
    let mut out = SurfaceSamples {
        points: Vec::with_capacity(n),
        normals: Vec::with_capacity(n),
        faces: Vec::with_capacity(n),
        barycentric: Vec::with_capacity(n),
    };
    for (p, f, b) in blocks.into_iter().flatten() {
        out.points.push(p);
        out.normals.push(normals[f as usize]);
        out.faces.push(f);
        out.barycentric.push(b);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_area_is_an_error_and_zero_samples_is_fine() {
        let flat = TriMesh::new(vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], vec![[0, 1, 2]]).unwrap();
        assert!(sample_surface(&flat, 10, 0).is_err());
        let tri = TriMesh::new(vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]]).unwrap();
        assert!(sample_surface(&tri, 0, 0).unwrap().is_empty());
    }

    #[test]
    fn blocks_do_not_repeat() {
        let tri = TriMesh::new(vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]]).unwrap();
        let s = sample_surface(&tri, 2 * BLOCK, 5).unwrap();
        assert_ne!(s.points[0], s.points[BLOCK]);
    }
}
