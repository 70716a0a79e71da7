//! The histogram-of-oriented-curvature (HOC) descriptor (thesis 5.3.1, 5.4; Kerber et al. 2013,
//! Herzog et al. 2015): curvature pooled into 8 orientation × 8 × 8 spatial bins on the tangent
//! plane of the feature's frame, and again on the plane normal to its y axis — 2 × 8 × 8 × 8 =
//! 1,024 values, L1-normalised.
//!
//! Choices where the thesis is silent, and why:
//! - The support is the cube of side `grid × cell` (64ε) centred on the feature, in its frame;
//!   each support point is projected onto both planes. A point contributes its |κ₁| times the
//!   length of its t₁ projected onto the plane, at the orientation of that projection (an
//!   undirected line, so orientations span [0, π)). This is HOG's "gradient magnitude at gradient
//!   orientation", with curvature in the role of the gradient.
//! - Votes are spread bilinearly over the spatial bins and linearly (circularly) over orientation
//!   bins, as HOG does, so a point near a bin border does not flip the descriptor under noise.
//! - Support points are the resampled cloud thinned to 2ε (`support_spacing`, Poisson-disc): a 64ε cube at
//!   spacing ε holds ~4,000 surface points; at 2ε ~1,000 carry the same histogram (each bin, 8ε
//!   wide, still receives ~16 points) for a quarter of the cost.
//! - The sign of t₁ is ambiguous; the thesis keeps two frames turned 180° about x. Motif stores
//!   both descriptors, and canonicalises which one is "frame 0" by the sign of the curvature-
//!   weighted first moment along y (like SHOT's sign disambiguation), so that k-means sees the
//!   same pose of the same geometry.

use motif_core::Point3;
use motif_core::geometry::{dot, scale, sub};
use motif_core::sampling::{CandidateOrder, Constraints, PoissonDiscOptions, Spacing, poisson_disc_points};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::grid::SpatialHash;
use crate::preprocess::{Feature, Preprocessed};

/// Options of [`compute`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct HocOptions {
    /// Width of one spatial bin, in ε (thesis 5.4: 8ε). Default 8.
    pub cell: f64,
    /// Spacing of the support points, in ε (see the module documentation). Default 2.
    pub support_spacing: f64,
}

impl Default for HocOptions {
    fn default() -> Self {
        HocOptions { cell: 8.0, support_spacing: 2.0 }
    }
}

/// Spatial bins per side (thesis: 8).
pub const GRID: usize = 8;
/// Orientation bins (thesis: 8).
pub const ORIENTATIONS: usize = 8;
/// Descriptor length: 2 planes × 8 × 8 × 8 = 1,024.
pub const DIM: usize = 2 * GRID * GRID * ORIENTATIONS;

/// HOC descriptors of every feature in both of its frames.
#[derive(Debug, Clone)]
pub struct Descriptors {
    /// Row `2 f + flip` is feature `f`'s descriptor in frame `flip` (0 canonical, 1 turned 180°
    /// about x); `DIM` values per row, L1 norm 1 (all zero when the support had no curvature).
    pub data: Vec<f32>,
}

impl Descriptors {
    /// Feature `f`'s descriptor in frame `flip`.
    pub fn row(&self, f: usize, flip: u8) -> &[f32] {
        let r = 2 * f + flip as usize;
        &self.data[r * DIM..(r + 1) * DIM]
    }

    /// Number of features.
    pub fn len(&self) -> usize {
        self.data.len() / (2 * DIM)
    }

    /// True when there are no features.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
}

/// L1 distance of two descriptors (eight running sums so the loop vectorises).
pub fn l1(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let ca = a.chunks_exact(8);
    let cb = b.chunks_exact(8);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            acc[k] += (x[k] - y[k]).abs();
        }
    }
    let mut s: f32 = acc.iter().sum();
    for (x, y) in ra.iter().zip(rb) {
        s += (x - y).abs();
    }
    s
}

/// Index of bin (plane, a, b, orientation).
fn bin(plane: usize, a: usize, b: usize, o: usize) -> usize {
    ((plane * GRID + a) * GRID + b) * ORIENTATIONS + o
}

/// The bin permutation that turns a frame-0 descriptor into the frame turned 180° about x
/// (y → −y, z → −z): on the tangent plane (y, z) both spatial indices mirror and orientations
/// (lines) are unchanged; on the (x, z) plane z mirrors and orientations reflect.
fn flip_permutation() -> Vec<usize> {
    let g = GRID - 1;
    let mut perm = vec![0; DIM];
    for a in 0..GRID {
        for b in 0..GRID {
            for o in 0..ORIENTATIONS {
                perm[bin(0, a, b, o)] = bin(0, g - a, g - b, o);
                perm[bin(1, a, b, o)] = bin(1, a, g - b, ORIENTATIONS - 1 - o);
            }
        }
    }
    perm
}

/// Dimensionless curvature κ₁ε below which a point counts as flat (rounding noise of the
/// quadratic fit; crease points start at κ₁ε = 0.0375 with the default feature threshold).
const FLAT_KAPPA: f64 = 1e-6;

/// Computes the descriptors and canonicalises each feature's y axis in place.
pub fn compute(pre: &Preprocessed, features: &mut [Feature], o: &HocOptions, seed: u64) -> Descriptors {
    let eps = pre.epsilon;
    let cell = o.cell * eps;
    let half = cell * GRID as f64 / 2.0;
    // Support points: the resampled cloud thinned to `support_spacing`·ε by Poisson-disc
    // elimination in a seeded order — distance-based, so the choice is invariant to a rigid
    // motion of the input (a world-axis grid would not be).
    let spacing = (o.support_spacing * eps).max(eps * 1e-6);
    // "Curved" means above rounding noise: on a flat part κ₁ comes out as ±1e-16/ε, and a
    // sign test would pick a motion-dependent half of the plane, which reshuffles the seeded
    // elimination order of everything else (so the descriptors of the whole input changed after
    // a rigid motion).
    let curved: Vec<usize> = (0..pre.points.len()).filter(|&i| pre.kappa[i] * eps > FLAT_KAPPA).collect();
    let curved_pts: Vec<Point3> = curved.iter().map(|&i| pre.points[i]).collect();
    let po = PoissonDiscOptions {
        spacing: Spacing::Radius(spacing),
        seed,
        order: CandidateOrder::Random,
        ..Default::default()
    };
    let support: Vec<usize> = match poisson_disc_points(&curved_pts, None, &Constraints::default(), &po) {
        Ok(s) => s.candidate_indices().into_iter().map(|k| curved[k]).collect(),
        Err(_) => curved,
    };
    let support_pts: Vec<Point3> = support.iter().map(|&i| pre.points[i]).collect();
    let hash = SpatialHash::new(&support_pts, half);
    let perm = flip_permutation();
    let reach = half * 3f64.sqrt();
    let mut data = vec![0.0f32; features.len() * 2 * DIM];
    data.par_chunks_mut(2 * DIM).zip(features.par_iter_mut()).for_each(|(rows, f)| {
        let (d0, d1) = rows.split_at_mut(DIM);
        let (x, y, z) = (f.x, f.y, f.z());
        // One pass in the frame as given; the first moment along y (curvature-weighted) decides
        // afterwards which of the two frames is canonical.
        let mut moment = 0.0;
        hash.for_each_within(f.position, reach, |j, _| {
            let i = support[j];
            let v = sub(pre.points[i], f.position);
            let (lx, ly, lz) = (dot(v, x), dot(v, y), dot(v, z));
            if lx.abs() >= half || ly.abs() >= half || lz.abs() >= half {
                return;
            }
            let k = pre.kappa[i];
            moment += k * ly;
            let t = pre.t1[i];
            let (tx, ty, tz) = (dot(t, x), dot(t, y), dot(t, z));
            // Plane 0: tangent plane, coordinates (y, z); plane 1: normal y, coordinates (x, z).
            splat(d0, 0, ly, lz, ty, tz, k, half, cell);
            splat(d0, 1, lx, lz, tx, tz, k, half, cell);
        });
        let s: f32 = d0.iter().sum();
        if s > 0.0 {
            d0.iter_mut().for_each(|v| *v /= s);
        }
        for (b, &p) in perm.iter().enumerate() {
            d1[p] = d0[b];
        }
        if moment < 0.0 {
            f.y = scale(f.y, -1.0);
            d0.swap_with_slice(d1);
        }
    });
    Descriptors { data }
}

/// Adds one curvature vote at plane coordinates (u, w) with in-plane direction (tu, tw).
fn splat(d: &mut [f32], plane: usize, u: f64, w: f64, tu: f64, tw: f64, kappa: f64, half: f64, cell: f64) {
    let len = (tu * tu + tw * tw).sqrt();
    let weight = kappa * len;
    if weight.is_nan() || weight <= 0.0 {
        return;
    }
    let theta = tw.atan2(tu).rem_euclid(std::f64::consts::PI);
    let fo = theta / (std::f64::consts::PI / ORIENTATIONS as f64) - 0.5;
    let o0 = fo.floor();
    let wo = fo - o0;
    let o0 = (o0 as i64).rem_euclid(ORIENTATIONS as i64) as usize;
    let o1 = (o0 + 1) % ORIENTATIONS;
    let fa = (u + half) / cell - 0.5;
    let fb = (w + half) / cell - 0.5;
    let (a0, b0) = (fa.floor(), fb.floor());
    let (wa, wb) = (fa - a0, fb - b0);
    for (da, wa_) in [(0i64, 1.0 - wa), (1, wa)] {
        let a = a0 as i64 + da;
        if a < 0 || a >= GRID as i64 || wa_ <= 0.0 {
            continue;
        }
        for (db, wb_) in [(0i64, 1.0 - wb), (1, wb)] {
            let b = b0 as i64 + db;
            if b < 0 || b >= GRID as i64 || wb_ <= 0.0 {
                continue;
            }
            let base = weight * wa_ * wb_;
            d[bin(plane, a as usize, b as usize, o0)] += (base * (1.0 - wo)) as f32;
            d[bin(plane, a as usize, b as usize, o1)] += (base * wo) as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flip_permutation_is_an_involution() {
        let p = flip_permutation();
        for i in 0..DIM {
            assert_eq!(p[p[i]], i);
        }
        let mut sorted = p.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..DIM).collect::<Vec<_>>());
    }

    #[test]
    fn l1_matches_naive() {
        let a: Vec<f32> = (0..1027).map(|i| (i as f32 * 0.37).sin()).collect();
        let b: Vec<f32> = (0..1027).map(|i| (i as f32 * 0.11).cos()).collect();
        let naive: f32 = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum();
        assert!((l1(&a, &b) - naive).abs() < 1e-3);
    }
}
