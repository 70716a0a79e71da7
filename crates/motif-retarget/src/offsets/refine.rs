//! Refinement of dominant offsets by translation-only ICP (thesis 4.4), the overlap measure that
//! judges a translation, and the reduction of a principal offset to its fundamental period.
//!
//! - **ICP** (thesis 4.4: "a global iterative closest point algorithm on the entire point
//!   cloud"): the dense cloud shifted by the offset is aligned to itself by translation-only
//!   point-to-plane ICP with normal-compatible correspondences ([`Prober::icp`]; written here
//!   rather than calling `motif_core::icp`, whose correspondences ignore the source normals —
//!   on plane-dominated models that pulls walls onto the sides of their openings). The fixed
//!   cloud is every surface sample of the dense cloud through one kd-tree shared by all runs
//!   (the thinned vertices are left out: see [`Prober`]); the moving cloud is the same samples,
//!   or an even random subset of them for large models (`OffsetOptions::icp_points`). Details
//!   such as a window's recess sides are only a sample or two deep at the thesis's spacing, so
//!   the moving cloud must be dense too: with the feature samples alone a facade's bay came out
//!   0.6% short, with the dense cloud 0.08%. Correspondences farther than a gate are ignored,
//!   since only the overlapping part of a shifted copy has partners.
//! - **Overlap** of a translation `u`: the share of moving points `p` whose shifted position
//!   `p + u` lies on the surface with a matching orientation — its nearest dense point `q` is
//!   within 1.5 dense spacings (vertices excluded), `|(p + u − q) · n_q|` is below the overlap tolerance, and the
//!   normals agree (`n_p · n_q ≥ 0.8`). Distances to the tangent plane rather than to the sample
//!   make the test independent of where the random samples fell; the normal test stops a point
//!   from "overlapping" the back face of a thin part.
//! - **Fundamental period** (a Motif extension, see [`super::PeriodReduction`]): eq. 4.1 only sees
//!   offsets longer than τ, so a repetition with a pitch below τ (41 fence posts across the
//!   model, heat-sink fins) shows up as some multiple of its pitch, and even above τ the
//!   strongest peak can be a multiple. For a principal offset `v` the candidates `v / k` are
//!   scored by the *contrast* `overlap(u) − max(overlap(u / 2), overlap(3u / 2))`: a period maps
//!   the repeated parts onto each other while half and one-and-a-half periods map them into the
//!   gaps; a multiple of the period has a period at `u / 2` and a sub-multiple has none at `u`, so
//!   both score low. The best-scoring `k` (the largest among near-ties) is refined by ICP. This
//!   step only looks below τ; above τ the histogram itself holds the evidence (see
//!   [`super::PeriodReduction`]).

use motif_core::Point3;
use motif_core::geometry::{dot, norm, sub};
use motif_core::spatial::KdTree;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::features::OffsetFeatures;

/// Radius of the saliency test, in dense spacings.
pub const SALIENT_RADIUS_SPACINGS: f64 = 1.5;
/// A sample is salient when a surface normal within [`SALIENT_RADIUS_SPACINGS`] turns from its
/// own by more than this many degrees.
pub const SALIENT_ANGLE_DEGREES: f64 = 20.0;
/// Fewer salient samples than this and the contrast uses all samples.
pub const MIN_SALIENT: usize = 100;

/// Most feature samples in the coarse ICP cloud and the overlap measure.
pub const MAX_COARSE: usize = 2500;

/// Iterations with the full moving cloud after the coarse ones (see [`Prober::icp`]).
pub const FINE_ITERATIONS: usize = 3;

/// Minimum cosine between the normals of a point and its partner for the point to overlap.
pub const OVERLAP_MIN_NORMAL_DOT: f64 = 0.8;
/// Gate of the overlap measure, in dense spacings.
pub const OVERLAP_GATE_SPACINGS: f64 = 1.5;

/// The outcome of one ICP refinement.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IcpSummary {
    /// The refined offset, normalised units.
    pub offset: Point3,
    /// Root mean square point-to-plane distance of the kept correspondences, normalised units.
    pub rmse: f64,
    /// Fraction of moving points with a correspondence (within the gate, normals agreeing) at the
    /// end.
    pub inlier_fraction: f64,
    /// ICP iterations run (coarse and fine).
    pub iterations: usize,
    /// Whether the last fine step was below 10⁻⁶ of the gate.
    pub converged: bool,
}

/// Measures translations of a sampled model onto itself.
pub struct Prober<'a> {
    features: &'a OffsetFeatures,
    /// Kd-tree over the surface samples `dense[num_vertex_points..]` (index `i` is dense point
    /// `num_vertex_points + i`), shared by every ICP run and overlap measure. The thinned mesh
    /// vertices are left out: their area-averaged normals at sharp corners (a wall's edge) are no
    /// tangent plane, and a point-to-plane residual against them pulls the fit sideways.
    tree: KdTree,
    /// Moving cloud of the fine ICP iterations (dense indices of surface samples).
    moving: Vec<usize>,
    /// Moving cloud of the coarse ICP iterations and of the overlap measure: the feature samples
    /// (at most [`MAX_COARSE`]).
    coarse: Vec<usize>,
    /// The salient surface samples of the moving cloud (see [`SALIENT_ANGLE_DEGREES`]): the points of the contrast.
    salient: Vec<usize>,
    gate: f64,
    tolerance: f64,
}

impl<'a> Prober<'a> {
    /// A prober of `features` (the gate is [`OVERLAP_GATE_SPACINGS`] × `dense_spacing`, the
    /// tangent-plane tolerance `tolerance`, both normalised units) moving at most `max_points`
    /// surface samples. `None` when the model has no surface samples.
    pub fn new(
        features: &'a OffsetFeatures,
        dense_spacing: f64,
        tolerance: f64,
        max_points: usize,
    ) -> Option<Self> {
        let nv = features.num_vertex_points;
        let tree = KdTree::new(&features.dense[nv..]).ok()?;
        // Surface samples come in the random order Poisson-disc elimination accepted them, so a
        // prefix is a spatially even random subset.
        let moving: Vec<usize> = (nv..features.dense.len()).take(max_points.max(1)).collect();
        // Feature samples are in Poisson-disc acceptance order (random): a prefix is an even subset.
        let coarse: Vec<usize> = features.uniform.iter().copied().take(MAX_COARSE).collect();
        // Salient surface samples: the normals within a few dense spacings turn by more than
        // SALIENT_ANGLE (an edge, a corner, a curved patch), unlike the inside of a wall. Taken
        // from the moving cloud (the dense samples, up to `max_points`) rather than the sparser
        // feature samples: the contrast is a difference of two shares of this set, and with the
        // few hundred salient feature samples of a facade its sampling noise (±0.05 between
        // seeds) straddled the verdict's threshold.
        let r = SALIENT_RADIUS_SPACINGS * dense_spacing;
        let cos_max = SALIENT_ANGLE_DEGREES.to_radians().cos();
        let salient: Vec<usize> = moving
            .par_iter()
            .copied()
            .filter(|&i| {
                let n = features.dense_normals[i];
                tree.within_unsorted(features.dense[i], r)
                    .iter()
                    .any(|nb| dot(features.dense_normals[nv + nb.index], n) < cos_max)
            })
            .collect();
        Some(Prober {
            features,
            tree,
            moving,
            coarse,
            salient,
            gate: OVERLAP_GATE_SPACINGS * dense_spacing,
            tolerance,
        })
    }

    /// Nearest surface sample to `s` within `r`: its dense index and distance. A bounded
    /// search: an unbounded nearest-neighbour query from far outside the model (a shift by most
    /// of its size) visits much of the tree.
    #[inline]
    fn nearest_within(&self, s: Point3, r: f64) -> Option<(usize, f64)> {
        self.tree
            .within_unsorted(s, r)
            .into_iter()
            .min_by(|a, b| a.distance.total_cmp(&b.distance).then(a.index.cmp(&b.index)))
            .map(|nb| (self.features.num_vertex_points + nb.index, nb.distance))
    }

    /// Share of the feature samples (a spatially even subset of the surface) that land on the
    /// surface, with agreeing normals, when shifted by `u`.
    pub fn overlap(&self, u: Point3) -> f64 {
        self.overlap_of(self.probe_set(), u)
    }

    fn overlap_of(&self, probe: &[usize], u: Point3) -> f64 {
        if probe.is_empty() {
            return 0.0;
        }
        let f = self.features;
        let hits: usize = probe
            .par_iter()
            .filter(|&&i| {
                let p = f.dense[i];
                let s = [p[0] + u[0], p[1] + u[1], p[2] + u[2]];
                let Some((j, _)) = self.nearest_within(s, self.gate) else {
                    return false;
                };
                let nq = f.dense_normals[j];
                dot(sub(s, f.dense[j]), nq).abs() <= self.tolerance
                    && dot(f.dense_normals[i], nq) >= OVERLAP_MIN_NORMAL_DOT
            })
            .count();
        hits as f64 / probe.len() as f64
    }

    /// The points the overlap measure moves: the feature samples, or the full moving cloud when
    /// there are too few of them to measure a share.
    fn probe_set(&self) -> &[usize] {
        if self.coarse.len() >= 500 { &self.coarse } else { &self.moving }
    }

    /// The overlap of `u` and its contrast `s(u) − max(s(u/2), s(3u/2))`, where `s` is the
    /// overlap of the salient samples alone (all samples when fewer than
    /// [`MIN_SALIENT`] are salient): high for a period, low for multiples and sub-multiples of
    /// one. Salient points only, because the inside of a large plane overlaps under any shift
    /// within it and would drown the difference (a facade's wall around its windows).
    pub fn contrast(&self, u: Point3) -> (f64, f64) {
        let set: &[usize] = if self.salient.len() >= MIN_SALIENT { &self.salient } else { self.probe_set() };
        let s = |u: Point3| self.overlap_of(set, u);
        let o = s(u);
        let half = s(u.map(|c| 0.5 * c));
        let three_halves = s(u.map(|c| 1.5 * c));
        (self.overlap(u), o - half.max(three_halves))
    }

    /// Number of salient samples.
    pub fn num_salient(&self) -> usize {
        self.salient.len()
    }

    /// Translation-only ICP of the cloud onto itself from `start`; `None` when fewer than three
    /// correspondences were found.
    ///
    /// Each iteration pairs every moving point `p` (normal `n_p`) shifted by the current `t` with
    /// its nearest surface sample `q` (normal `n_q`), keeps the pair when `|p + t − q|` is within
    /// the gate and the normals agree (`n_p · n_q ≥ 0.8`), and solves the point-to-plane step
    /// `Σ n_q n_qᵀ δ = Σ n_q ((q − p − t) · n_q)`, regularised by a vanishing multiple (10⁻⁶) of
    /// the point-to-point step (the mean of `q − p − t`) so that a direction no plane constrains
    /// (a wall sliding in itself) takes the point-to-point step instead of a singular one. The
    /// normal test is what a plain ICP lacks on plane-dominated CAD models: without it the wall
    /// around a window is pulled onto the window's recess sides, with it only like faces
    /// correspond.
    ///
    /// Coarse to fine: up to `max_iterations` iterations with the feature samples as the moving
    /// cloud (a few thousand points), then up to [`FINE_ITERATIONS`] with the full moving cloud.
    pub fn icp(&self, start: Point3, max_iterations: usize, gate: f64) -> Option<IcpSummary> {
        let n = self.moving.len();
        if n == 0 {
            return None;
        }
        let gate = gate.min(0.4 * norm(start)).max(1e-12);
        let coarse: &[usize] = if self.coarse.len() >= 3 { &self.coarse } else { &self.moving };
        let (t, it1, _) = self.run_icp(coarse, start, gate, max_iterations, 1e-4 * gate)?;
        let (t, it2, conv) = self.run_icp(&self.moving, t, gate, FINE_ITERATIONS, 1e-6 * gate)?;
        let last = self.accumulate(&self.moving, t, gate);
        if last.count < 3 {
            return None;
        }
        Some(IcpSummary {
            offset: t,
            rmse: (last.sum_d2 / last.count as f64).sqrt(),
            inlier_fraction: last.count as f64 / n as f64,
            iterations: it1 + it2,
            converged: conv,
        })
    }

    /// Iterates from `t` until a step is below `tolerance` or `max_iterations` steps were taken;
    /// returns the offset, the steps taken and whether it converged.
    fn run_icp(
        &self,
        moving: &[usize],
        mut t: Point3,
        gate: f64,
        max_iterations: usize,
        tolerance: f64,
    ) -> Option<(Point3, usize, bool)> {
        for it in 0..max_iterations {
            let acc = self.accumulate(moving, t, gate);
            if acc.count < 3 {
                return None;
            }
            let Some(delta) = acc.step() else { return Some((t, it, false)) };
            t = [t[0] + delta[0], t[1] + delta[1], t[2] + delta[2]];
            if norm(delta) <= tolerance {
                return Some((t, it + 1, true));
            }
        }
        Some((t, max_iterations, false))
    }

    fn accumulate(&self, moving: &[usize], t: Point3, gate: f64) -> Accum {
        let f = self.features;
        // Fixed chunks summed in order: the sums (and so the refined offsets) do not depend on
        // how rayon schedules the work, bit for bit.
        let partial: Vec<Accum> = moving
            .par_chunks(ACCUM_CHUNK)
            .map(|chunk| {
                chunk.iter().fold(Accum::default(), |mut acc, &i| {
                    let p = f.dense[i];
                    let s = [p[0] + t[0], p[1] + t[1], p[2] + t[2]];
                    let Some((j, _)) = self.nearest_within(s, gate) else {
                        return acc;
                    };
                    let nq = f.dense_normals[j];
                    if dot(f.dense_normals[i], nq) < OVERLAP_MIN_NORMAL_DOT {
                        return acc;
                    }
                    let r = sub(f.dense[j], s);
                    let d = dot(r, nq);
                    for a in 0..3 {
                        for b in 0..3 {
                            acc.a[a][b] += nq[a] * nq[b];
                        }
                        acc.b[a] += nq[a] * d;
                        acc.r[a] += r[a];
                    }
                    acc.sum_d2 += d * d;
                    acc.count += 1;
                    acc
                })
            })
            .collect();
        partial.into_iter().fold(Accum::default(), Accum::merge)
    }
}

/// Side of the difference cells in which [`snap_to_vertices`] looks for the most frequent exact
/// vertex-to-vertex translation, normalised units (10⁻⁵ of the model's half-size: well above the
/// rounding of 7-digit ASCII STL coordinates, far below any modelled feature).
pub const SNAP_CELL: f64 = 1e-5;
/// Least number of vertex pairs that must agree on the snapped translation.
pub const SNAP_MIN_PAIRS: usize = 8;
/// Least share of the probed vertices (those with a partner near `v + t`) that must agree.
pub const SNAP_MIN_SHARE: f64 = 0.1;

/// An offset snapped to an exact vertex-to-vertex translation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VertexSnap {
    /// The snapped offset, normalised units: the mean of the agreeing vertex differences.
    pub offset: Point3,
    /// Vertex pairs that agree on it (within [`SNAP_CELL`]).
    pub pairs: usize,
    /// Vertices probed that found a partner within the search radius.
    pub probed: usize,
    /// Distance from the refined offset to the snapped one, normalised units.
    pub shift: f64,
}

/// Snaps `t` (a refined offset, normalised units) to the translation that maps mesh vertices
/// exactly onto mesh vertices, when the mesh has one near `t` (a Motif extension, not in the
/// thesis).
///
/// ICP on sampled points leaves a refined offset off by 10⁻⁵–10⁻³ of its length (the samples are
/// random, and parts that differ from copy to copy, like a fence's posts of varying height, pull
/// the fit). Each copy placed k cells away carries k times that error, and on a CAD model it
/// opens the seams: vertices that should weld miss each other. A CAD model's copies are exact, so
/// the differences `w − v` between each thinned mesh vertex `v` and its nearest mesh vertex `w`
/// to `v + t` (within `radius`) pile up on the exact translation. The most populated cell of side
/// [`SNAP_CELL`] (with its neighbours) is taken when it holds at least [`SNAP_MIN_PAIRS`] pairs and
/// [`SNAP_MIN_SHARE`] of the probed vertices. Scanned surfaces have no such pile and keep their ICP
/// offset. A mesh tessellated on a regular grid of its own (a subdivided plane) can pile up on a
/// grid step near `t` instead, so the caller also checks that the snapped offset maps the surface
/// onto itself at least as well as `t` (see `analyze_features`). `tree` holds
/// `features.mesh_vertices`.
pub fn snap_to_vertices(
    features: &OffsetFeatures,
    tree: &KdTree,
    t: Point3,
    radius: f64,
) -> Option<VertexSnap> {
    use std::collections::HashMap;
    let targets = &features.mesh_vertices;
    if targets.is_empty() || features.num_vertex_points == 0 {
        return None;
    }
    // Bounded searches: an unbounded one from outside the model (the last copy's vertices land
    // there) visits much of the tree.
    let diffs: Vec<Point3> = features.dense[..features.num_vertex_points]
        .par_iter()
        .filter_map(|&v| {
            let q = [v[0] + t[0], v[1] + t[1], v[2] + t[2]];
            tree.within_unsorted(q, radius)
                .into_iter()
                .min_by(|a, b| a.distance.total_cmp(&b.distance).then(a.index.cmp(&b.index)))
                .map(|nb| sub(targets[nb.index], v))
        })
        .collect();
    let key = |d: Point3| d.map(|c| (c / SNAP_CELL).floor() as i64);
    let mut counts: HashMap<[i64; 3], usize> = HashMap::new();
    for &d in &diffs {
        *counts.entry(key(d)).or_default() += 1;
    }
    // The cell whose 3×3×3 block holds the most differences (smallest key on ties).
    let block = |k: [i64; 3]| {
        let mut n = 0;
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    n += counts.get(&[k[0] + dx, k[1] + dy, k[2] + dz]).copied().unwrap_or(0);
                }
            }
        }
        n
    };
    let (best, pairs) =
        counts.keys().map(|&k| (k, block(k))).max_by(|a, b| a.1.cmp(&b.1).then(b.0.cmp(&a.0)))?;
    if pairs < SNAP_MIN_PAIRS || (pairs as f64) < SNAP_MIN_SHARE * diffs.len() as f64 {
        return None;
    }
    let mut sum = [0.0; 3];
    let mut n = 0usize;
    for &d in &diffs {
        let k = key(d);
        if (0..3).all(|i| (k[i] - best[i]).abs() <= 1) {
            for i in 0..3 {
                sum[i] += d[i];
            }
            n += 1;
        }
    }
    let offset = sum.map(|c| c / n as f64);
    Some(VertexSnap { offset, pairs: n, probed: diffs.len(), shift: norm(sub(offset, t)) })
}

/// Points per partial sum of an ICP iteration.
const ACCUM_CHUNK: usize = 512;

/// Sums of one ICP iteration.
#[derive(Debug, Clone, Copy, Default)]
struct Accum {
    a: [[f64; 3]; 3],
    b: [f64; 3],
    r: [f64; 3],
    sum_d2: f64,
    count: usize,
}

/// Weight of the point-to-point term in the ICP step (see [`Prober::icp`]).
const POINT_TO_POINT_WEIGHT: f64 = 1e-6;

impl Accum {
    fn merge(mut x: Accum, y: Accum) -> Accum {
        for a in 0..3 {
            for b in 0..3 {
                x.a[a][b] += y.a[a][b];
            }
            x.b[a] += y.b[a];
            x.r[a] += y.r[a];
        }
        x.sum_d2 += y.sum_d2;
        x.count += y.count;
        x
    }

    /// The regularised point-to-plane step.
    fn step(&self) -> Option<Point3> {
        let n = self.count as f64;
        let w = POINT_TO_POINT_WEIGHT;
        let mut m = self.a.map(|row| row.map(|v| v / n));
        let mut rhs = [0.0; 3];
        for i in 0..3 {
            m[i][i] += w;
            rhs[i] = self.b[i] / n + w * self.r[i] / n;
        }
        solve3(m, rhs)
    }
}

/// Solves the 3 × 3 system `m x = b` by Cramer's rule; `None` when singular.
fn solve3(m: [[f64; 3]; 3], b: Point3) -> Option<Point3> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(m);
    if d.is_nan() || d.abs() <= 1e-300 {
        return None;
    }
    let mut x = [0.0; 3];
    for c in 0..3 {
        let mut mc = m;
        for r in 0..3 {
            mc[r][c] = b[r];
        }
        x[c] = det(mc) / d;
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The result of reducing a principal offset to its fundamental period.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PeriodCandidate {
    /// The divisor `k` (1 = the offset itself).
    pub divisor: usize,
    /// Overlap of `v / k`.
    pub overlap: f64,
    /// Contrast of `v / k` (see the module docs).
    pub contrast: f64,
}

/// Contrasts closer than this count as a tie (and a contrast below it as no evidence).
const TIE_MARGIN: f64 = 0.02;

/// Scores `v / k` for `k = 1..=max_divisor` with `min_length ≤ |v / k| < max_length`; returns the
/// candidates
/// and the chosen divisor: the best contrast, preferring the larger `k` among near-ties; `1`
/// when no candidate has a contrast above the tie margin.
pub fn reduce_period(
    prober: &Prober,
    v: Point3,
    max_divisor: usize,
    min_length: f64,
    max_length: f64,
) -> (Vec<PeriodCandidate>, usize) {
    let len = norm(v);
    let ks: Vec<usize> = (1..=max_divisor.max(1))
        .filter(|&k| k == 1 || (len / k as f64 >= min_length && len / (k as f64) < max_length))
        .collect();
    if ks.len() == 1 {
        return (Vec::new(), 1);
    }
    let cands: Vec<PeriodCandidate> = ks
        .iter()
        .map(|&k| {
            let u = v.map(|c| c / k as f64);
            let (overlap, contrast) = prober.contrast(u);
            PeriodCandidate { divisor: k, overlap, contrast }
        })
        .collect();
    let best = cands.iter().map(|c| c.contrast).fold(f64::NEG_INFINITY, f64::max);
    let chosen = cands
        .iter()
        .filter(|c| c.contrast >= best - TIE_MARGIN && c.contrast > TIE_MARGIN)
        .map(|c| c.divisor)
        .max()
        .unwrap_or(1);
    (cands, chosen)
}
