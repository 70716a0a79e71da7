//! How far a transform is from mapping a point set onto a surface: the closest-point residual.

use motif_core::Point3;
use motif_core::geometry::{Mat4, transform_point};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::bvh::{Hit, TriangleBvh};

/// Slack of the closest-point search relative to the diagonal (see [`TriangleBvh::closest`]):
/// far below any tolerance, and it lets queries on the surface stop at the first triangle.
const SLACK: f64 = 1e-10;

/// Points per sequential block of a validation (each block runs in parallel); a block boundary is
/// where a validation that already exceeds its cap stops.
const BLOCK: usize = 4096;

/// Distances of transformed points to the surface, relative to the bounding-box diagonal.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Residual {
    /// Largest distance (relative). When `complete` is false this is a lower bound: the
    /// evaluation stopped once a block of points exceeded the cap.
    pub max: f64,
    /// Mean distance (relative) over the points evaluated.
    pub mean: f64,
    /// Number of points evaluated.
    pub points: usize,
    /// False when the evaluation stopped early because the cap was exceeded.
    pub complete: bool,
}

/// The surface a candidate must map onto itself, with its closest-point acceleration structure.
#[derive(Debug, Clone)]
pub(crate) struct Surface {
    pub bvh: TriangleBvh,
    /// Bounding-box diagonal (absolute), the unit of every relative residual.
    pub diagonal: f64,
}

impl Surface {
    /// The residual of `m` on `points`: distances from `m p` to the surface. Distances are capped
    /// at `cap` (relative); as soon as a block's maximum reaches the cap the evaluation stops and
    /// returns an incomplete residual whose `max` is the cap.
    pub fn residual(&self, points: &[Point3], m: &Mat4, cap: f64) -> Residual {
        self.residual_in_blocks(points, m, cap, BLOCK)
    }

    /// [`Surface::residual`] checking the cap after every `block` points (small blocks stop a
    /// bad candidate sooner, large ones parallelise better).
    pub fn residual_in_blocks(&self, points: &[Point3], m: &Mat4, cap: f64, block: usize) -> Residual {
        let cap_abs = cap * self.diagonal;
        let cap2 = cap_abs * cap_abs;
        let (mut max, mut sum, mut n) = (0.0f64, 0.0f64, 0usize);
        // Distances are collected in point order and summed sequentially, so the mean does not
        // depend on how rayon split the work (a parallel float sum would, in the last bits).
        let mut dists: Vec<f64> = Vec::with_capacity(block.min(points.len()));
        for block in points.chunks(block.max(1)) {
            block
                .par_iter()
                .map(|&p| {
                    let q = transform_point(m, p);
                    self.bvh.closest(q, cap2, SLACK * self.diagonal).map_or(cap_abs, |h| h.d2.sqrt())
                })
                .collect_into_vec(&mut dists);
            let bmax = dists.iter().copied().fold(0.0, f64::max);
            let bsum: f64 = dists.iter().sum();
            max = max.max(bmax);
            sum += bsum;
            n += block.len();
            if bmax >= cap_abs {
                return Residual {
                    max: cap,
                    mean: sum / (n as f64 * self.diagonal),
                    points: n,
                    complete: false,
                };
            }
        }
        let d = self.diagonal;
        Residual {
            max: max / d,
            mean: if n > 0 { sum / (n as f64 * d) } else { 0.0 },
            points: n,
            complete: true,
        }
    }

    /// Closest surface points of the transformed points (within `cap`, relative), in order.
    pub fn matches(&self, points: &[Point3], m: &Mat4, cap: f64) -> Vec<(Point3, Option<Hit>)> {
        let cap_abs = cap * self.diagonal;
        points
            .par_iter()
            .map(|&p| {
                let q = transform_point(m, p);
                (q, self.bvh.closest(q, cap_abs * cap_abs, SLACK * self.diagonal))
            })
            .collect()
    }
}
