//! Where candidate planes and axes come from: the principal axes of the surface, and votes of
//! matched triangle pairs.
//!
//! Every global symmetry fixes the area-weighted centroid `c` of the surface, so a mirror plane
//! passes through `c` and a rotation axis contains it: candidates are directions only.
//!
//! - **Principal axes**: eigenvectors of the area-weighted covariance of the surface (exact
//!   second moments of the triangles). A mirror normal and a rotation axis are always
//!   eigenvectors; when two eigenvalues coincide (an axis of order ≥ 3, e.g. a 17-fold gear) any
//!   direction of their plane is an eigenvector, so in-plane directions must come from elsewhere
//!   (the votes, and the scan around a detected axis in the caller).
//! - **Pair votes** (in the spirit of Mitra, Guibas and Pauly, "Partial and approximate symmetry
//!   detection for 3D geometry", SIGGRAPH 2006): triangles are described by invariants of the
//!   symmetries fixing `c` (distance of the centroid to `c`, signed height `n·(g − c)` of the
//!   face plane, sorted edge lengths). A pair `(s, t)` with equal invariants proposes the mirror
//!   plane bisecting their centroids when the reflection also maps `n_s` to `n_t`, and the
//!   rotation axis `(g_t − g_s) × (n_t − n_s)` (perpendicular to both displacements) when the
//!   rotation angles measured on positions and on normals agree. Votes are accumulated on a
//!   cube-map of the sphere (each direction with its antipode) and the peaks are returned.

use std::collections::HashMap;

use motif_core::Point3;
use motif_core::geometry::{add, cross, dot, norm, normalize, scale, sub};
use nalgebra::{Matrix3, SymmetricEigen};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Area-weighted principal axes of a surface.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PrincipalAxes {
    /// Area-weighted centroid of the surface.
    pub center: Point3,
    /// Eigenvalues of the covariance (second moments about the centroid per unit area, units²),
    /// ascending.
    pub moments: [f64; 3],
    /// Unit eigenvectors, in the order of `moments`.
    pub axes: [Point3; 3],
}

/// Area-weighted centroid and covariance of the triangles (corner positions), by exact
/// integration: `∫_T x xᵀ dA = A/12 (Σ vᵢvᵢᵀ + s sᵀ)` with `s = Σ vᵢ`. `None` without area.
pub(crate) fn principal_axes(tris: &[[Point3; 3]]) -> Option<PrincipalAxes> {
    let mut area = 0.0;
    let mut c = [0.0; 3];
    for t in tris {
        let a = 0.5 * norm(cross(sub(t[1], t[0]), sub(t[2], t[0])));
        area += a;
        c = add(c, scale(add(add(t[0], t[1]), t[2]), a / 3.0));
    }
    if !(area > 0.0 && area.is_finite()) {
        return None;
    }
    let c = scale(c, 1.0 / area);
    let mut m = Matrix3::<f64>::zeros();
    for t in tris {
        let a = 0.5 * norm(cross(sub(t[1], t[0]), sub(t[2], t[0])));
        let v = [sub(t[0], c), sub(t[1], c), sub(t[2], c)];
        let s = add(add(v[0], v[1]), v[2]);
        for i in 0..3 {
            for j in 0..3 {
                let vv: f64 = v.iter().map(|p| p[i] * p[j]).sum();
                m[(i, j)] += a / 12.0 * (vv + s[i] * s[j]);
            }
        }
    }
    m /= area;
    let eig = SymmetricEigen::new(m);
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let mut moments = [0.0; 3];
    let mut axes = [[0.0; 3]; 3];
    for (k, &i) in idx.iter().enumerate() {
        moments[k] = eig.eigenvalues[i];
        let v = eig.eigenvectors.column(i);
        axes[k] = normalize([v[0], v[1], v[2]]).unwrap_or([0.0; 3]);
    }
    Some(PrincipalAxes { center: c, moments, axes })
}

/// A direction proposed by the votes, with its number of votes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Peak {
    pub direction: Point3,
    pub votes: usize,
}

/// Invariants of one triangle under isometries fixing the centre.
#[derive(Debug, Clone, Copy)]
struct Feature {
    g: Point3,
    n: Point3,
    r: f64,
    h: f64,
    edges: [f64; 3],
}

/// Largest number of partners tried per source triangle (the closest in radius).
const MAX_PARTNERS: usize = 256;

/// Mirror-normal peaks and rotation-axis peaks from matched triangle pairs. `sources` triangles
/// are drawn (seeded) and paired with every triangle of similar invariants; tolerances are
/// relative to `diag`.
pub(crate) fn vote(
    tris: &[[Point3; 3]],
    center: Point3,
    diag: f64,
    sources: usize,
    max_peaks: usize,
    seed: u64,
) -> (Vec<Peak>, Vec<Peak>) {
    let mut feats: Vec<Feature> = tris
        .iter()
        .filter_map(|t| {
            let n = normalize(cross(sub(t[1], t[0]), sub(t[2], t[0])))?;
            let g = scale(add(add(t[0], t[1]), t[2]), 1.0 / 3.0);
            let d = sub(g, center);
            let mut edges = [norm(sub(t[1], t[0])), norm(sub(t[2], t[1])), norm(sub(t[0], t[2]))];
            edges.sort_by(f64::total_cmp);
            Some(Feature { g, n, r: norm(d), h: dot(n, d), edges })
        })
        .collect();
    if feats.len() < 2 {
        return (Vec::new(), Vec::new());
    }
    feats.sort_by(|a, b| a.r.total_cmp(&b.r));
    let radii: Vec<f64> = feats.iter().map(|f| f.r).collect();
    let picks: Vec<usize> = if feats.len() <= sources {
        (0..feats.len()).collect()
    } else {
        // A seeded random subset: the `sources` indices with the smallest hashes.
        let mut keyed: Vec<(u64, usize)> =
            (0..feats.len()).map(|i| (splitmix64(seed ^ i as u64), i)).collect();
        keyed.select_nth_unstable(sources);
        let mut v: Vec<usize> = keyed[..sources].iter().map(|k| k.1).collect();
        v.sort_unstable();
        v
    };
    let eps_r = 2e-3 * diag;
    let eps_h = 2e-3 * diag;
    let min_sep = 1e-3 * diag;
    let votes: Vec<(Vec<Point3>, Vec<Point3>)> = picks
        .par_iter()
        .map(|&i| {
            let s = &feats[i];
            let lo = radii.partition_point(|&r| r < s.r - eps_r);
            let hi = radii.partition_point(|&r| r <= s.r + eps_r);
            // The MAX_PARTNERS closest in radius around i.
            let (lo, hi) = if hi - lo > MAX_PARTNERS {
                let half = MAX_PARTNERS / 2;
                let a = i.saturating_sub(half).max(lo);
                (a, (a + MAX_PARTNERS).min(hi))
            } else {
                (lo, hi)
            };
            let mut mirrors = Vec::new();
            let mut axes = Vec::new();
            for (j, t) in feats.iter().enumerate().take(hi).skip(lo) {
                if j == i || (s.h - t.h).abs() > eps_h {
                    continue;
                }
                if (0..3).any(|k| (s.edges[k] - t.edges[k]).abs() > 0.05 * s.edges[k] + 1e-4 * diag) {
                    continue;
                }
                let dg = sub(s.g, t.g);
                let sep = norm(dg);
                if sep < min_sep {
                    continue;
                }
                let m = scale(dg, 1.0 / sep);
                // Mirror: the reflection in the bisecting plane maps n_s to n_t.
                let refl = sub(s.n, scale(m, 2.0 * dot(s.n, m)));
                if norm(sub(refl, t.n)) < 0.05 {
                    mirrors.push(m);
                    continue;
                }
                // Rotation: the axis is perpendicular to both displacements.
                let dn = sub(t.n, s.n);
                if norm(dn) < 0.05 {
                    continue;
                }
                let a = cross(scale(dg, -1.0 / sep), scale(dn, 1.0 / norm(dn)));
                if norm(a) < 0.1 {
                    continue;
                }
                let a = scale(a, 1.0 / norm(a));
                let turn = |u: Point3, v: Point3| -> Option<f64> {
                    let pu = sub(u, scale(a, dot(u, a)));
                    let pv = sub(v, scale(a, dot(v, a)));
                    if norm(pu) < 1e-2 * norm(u).max(1e-300) || norm(pv) < 1e-2 * norm(v).max(1e-300) {
                        return None;
                    }
                    Some(dot(a, cross(pu, pv)).atan2(dot(pu, pv)))
                };
                let (Some(tp), Some(tn)) = (turn(sub(s.g, center), sub(t.g, center)), turn(s.n, t.n)) else {
                    continue;
                };
                let diff = (tp - tn).abs();
                let diff = diff.min(std::f64::consts::TAU - diff);
                if diff < 0.05 {
                    axes.push(a);
                }
            }
            (mirrors, axes)
        })
        .collect();
    let (mut mv, mut av) = (Vec::new(), Vec::new());
    for (m, a) in votes {
        mv.extend(m);
        av.extend(a);
    }
    (peaks(&mv, max_peaks), peaks(&av, max_peaks))
}

/// SplitMix64 (Steele, Lea and Flood 2014): a cheap, well-mixed hash of a 64-bit key.
pub(crate) fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Cells per cube-face side of the direction histogram (about 1.9° per cell at face centres).
const CELLS: usize = 48;

fn cell_of(d: Point3) -> (usize, usize, usize) {
    let k = (0..3).max_by(|&i, &j| d[i].abs().total_cmp(&d[j].abs())).unwrap_or(0);
    let face = 2 * k + usize::from(d[k] < 0.0);
    let (u, v) = match k {
        0 => (d[1], d[2]),
        1 => (d[0], d[2]),
        _ => (d[0], d[1]),
    };
    let m = d[k].abs().max(1e-300);
    let q = |x: f64| (((x / m + 1.0) * 0.5 * CELLS as f64) as usize).min(CELLS - 1);
    (face, q(u), q(v))
}

/// Peaks of a set of undirected unit vectors: histogram on a cube map (each vote counted with
/// its antipode), non-maximum suppression within 4°, the mean of the cell's votes as the peak.
fn peaks(votes: &[Point3], max_peaks: usize) -> Vec<Peak> {
    let mut cells: HashMap<(usize, usize, usize), Vec<Point3>> = HashMap::new();
    for &d in votes {
        for v in [d, scale(d, -1.0)] {
            cells.entry(cell_of(v)).or_default().push(v);
        }
    }
    let mut list: Vec<((usize, usize, usize), Vec<Point3>)> = cells.into_iter().collect();
    list.sort_by(|a, b| b.1.len().cmp(&a.1.len()).then(a.0.cmp(&b.0)));
    let top = list.first().map_or(0, |c| c.1.len());
    let min_votes = 3.max(top / 50);
    let mut out: Vec<Peak> = Vec::new();
    for (_, members) in list {
        if out.len() >= max_peaks || members.len() < min_votes {
            break;
        }
        let mut acc = [0.0; 3];
        for m in &members {
            acc = add(acc, *m);
        }
        let Some(d) = normalize(acc) else { continue };
        if out.iter().any(|p| dot(p.direction, d).abs() > 4f64.to_radians().cos()) {
            continue;
        }
        out.push(Peak { direction: d, votes: members.len() });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_principal_axes() {
        let m = motif_core::procedural::box_mesh([0.0, 0.0, 0.0], [4.0, 2.0, 1.0], [2, 2, 2]).unwrap();
        let tris: Vec<[Point3; 3]> = (0..m.num_triangles()).map(|f| m.corners(f)).collect();
        let pa = principal_axes(&tris).unwrap();
        assert!(motif_core::geometry::dist(pa.center, [2.0, 1.0, 0.5]) < 1e-12);
        assert!(pa.axes[2][0].abs() > 0.999_999);
        assert!(pa.axes[0][2].abs() > 0.999_999);
    }

    #[test]
    fn peaks_merge_antipodes() {
        let v = vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.999, 0.01, 0.0], [0.0, 1.0, 0.0]];
        let p = peaks(&v, 5);
        assert_eq!(p.len(), 1);
        assert!(p[0].direction[0].abs() > 0.99);
    }
}
