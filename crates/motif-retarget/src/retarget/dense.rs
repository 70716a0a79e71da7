//! The dense-MRF baseline of thesis 4.5 ("conventional MRF based results without offset
//! statistics", Fig. 4.8, blue models): the same energy and stitching, but the grid and the labels
//! use regular axis-aligned offsets of 0.1 (normalised units) instead of the principal offsets, so
//! there are many more voxels and labels and the copies are not aligned with the model's cells.
//!
//! The caller still asks for `steps` along the principal offsets, so that both methods produce the
//! same output size: the requested growth `g = Σ stepsᵢ vᵢ` (model units) becomes
//! `round(gₐ / 0.1)` regular steps along each world axis `a` of normalised space.

use motif_core::geometry::Point3;

use super::canonical::{Lattice, Normalisation};

/// The regular lattice of the baseline.
pub(crate) fn dense_lattice(normalisation: Normalisation, spacing: f64) -> Lattice {
    Lattice::regular(normalisation, spacing)
}

/// Regular steps along the world axes that grow the model by about as much as `steps` principal
/// offsets would.
pub(crate) fn dense_steps(
    normalisation: &Normalisation,
    principal_offsets: &[Point3],
    steps: [i32; 3],
    spacing: f64,
) -> [i64; 3] {
    let mut g = [0.0; 3];
    for (o, &s) in principal_offsets.iter().zip(&steps) {
        for a in 0..3 {
            g[a] += s as f64 * o[a];
        }
    }
    g.map(|c| (c * normalisation.scale / spacing).round() as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_follow_the_growth_vector() {
        let n = Normalisation { centre: [0.0; 3], scale: 2.0 };
        let s = dense_steps(&n, &[[0.42, 0.0, 0.0], [0.15, 0.37, 0.0]], [1, -1, 0], 0.1);
        assert_eq!(s, [5, -7, 0]);
    }
}
