//! Feature matching with a minimum offset length (thesis eq. 4.1):
//!
//! `v = argmin_v |S(x + v) − S(x)|  s.t.  |v| > τ`,
//!
//! i.e. for each feature `x` the feature `x + v` whose SHOT descriptor is nearest in L2 among the
//! features farther than `τ` from `x`. Several thresholds are answered in one pass (the sparsity
//! study's τ ∈ {0, 0.05, 0.1, 0.15, 0.2}): a target admissible for τ is admissible for every
//! smaller τ, so the best distance grows with τ and one scan keeps one best match per threshold.
//!
//! The scan is blocked brute force: ‖a − b‖² = ‖a‖² + ‖b‖² − 2 a·b with the a·b of a block of
//! queries against a block of targets as one f32 GEMM (faer), query blocks in parallel (rayon).
//! Features without a descriptor neither query nor match. Ties go to the lower target index, so
//! the result is deterministic and independent of the number of threads.
//!
//! The scan computes the descriptor distance of every pair of features anyway. Thesis 4.2.2 reuses
//! them for the retargeting MRF ("the pairwise feature distances have already been computed in the
//! previous step … and can be reused here"), so [`match_features_keeping_distances`] also keeps
//! them, as a [`DescriptorDistances`] table, when there are few enough features.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use motif_core::Point3;
use motif_core::progress::Progress;
use motif_core::shot::SHOT_LEN;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::error::{OffsetsError, Result};
use super::features::OffsetFeatures;

/// One feature's best match (eq. 4.1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FeatureMatch {
    /// The query feature (index into [`OffsetFeatures::features`]).
    pub feature: usize,
    /// The matched feature.
    pub target: usize,
    /// `v = x_target − x_feature`, normalised units.
    pub offset: Point3,
    /// L2 distance of the SHOT descriptors (unit-length descriptors: 0 to 2).
    pub descriptor_distance: f32,
}

const QUERY_BLOCK: usize = 128;
const TARGET_BLOCK: usize = 2048;

/// The L2 descriptor distance of every pair of valid features, kept from the matching scan
/// (thesis 4.2.2) for the Hausdorff distances of the retargeting MRF (eq. 4.4).
///
/// Storage: the strict upper triangle, row-major, over the valid features in feature order
/// ("compact" indices), each distance quantised to 16 bits over [0, 2] (the range of distances
/// between unit descriptors): a step of 3.1·10⁻⁵, an error of at most 1.6·10⁻⁵, below the f32
/// rounding of the GEMM that computed them for descriptors of 352 values. 8,192 features take
/// 64 MiB. Chosen over f32 to halve the memory at no visible cost in the MRF's energies, whose
/// seam costs differ by 10⁻² and more between labels.
#[derive(Debug, Clone)]
pub struct DescriptorDistances {
    /// Compact index of every feature (`#F`), `u32::MAX` for features without a descriptor.
    compact: Vec<u32>,
    /// Number of valid features.
    n: usize,
    /// Quantised distances, `n(n − 1)/2`.
    packed: Vec<u16>,
}

/// Quantisation scale: 65,535 steps over [0, 2].
const QUANT: f32 = 65535.0 / 2.0;

impl DescriptorDistances {
    /// Start of row `i` in the packed triangle (columns `i + 1 .. n`).
    #[inline]
    fn row_start(n: usize, i: usize) -> usize {
        i * n - i * (i + 1) / 2
    }

    #[inline]
    fn quantise(d: f32) -> u16 {
        (d.clamp(0.0, 2.0) * QUANT).round() as u16
    }

    /// A table of `n` features from its packed upper triangle (tests of the lookups).
    #[cfg(test)]
    pub(crate) fn from_packed(n: usize, packed: Vec<u16>) -> Self {
        assert_eq!(packed.len(), n * n.saturating_sub(1) / 2);
        DescriptorDistances { compact: (0..n as u32).collect(), n, packed }
    }

    /// A quantised distance in descriptor units.
    #[inline]
    pub fn dequantise(q: u16) -> f64 {
        q as f64 / QUANT as f64
    }

    /// Number of features with a descriptor (the table is `n × n`).
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether no feature has a descriptor.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Bytes held by the table.
    pub fn memory_bytes(&self) -> usize {
        self.packed.len() * 2 + self.compact.len() * 4
    }

    /// The compact index of feature `feature` (an index into [`OffsetFeatures::features`]), `None`
    /// when it has no descriptor or is out of range.
    #[inline]
    pub fn compact_index(&self, feature: usize) -> Option<u32> {
        self.compact.get(feature).copied().filter(|&c| c != u32::MAX)
    }

    /// The quantised distance between two compact indices (0 for `i == j`); see
    /// [`DescriptorDistances::dequantise`].
    #[inline]
    pub fn quantised(&self, i: u32, j: u32) -> u16 {
        let (i, j) = (i.min(j) as usize, i.max(j) as usize);
        if i == j {
            return 0;
        }
        self.packed[Self::row_start(self.n, i) + (j - i - 1)]
    }

    /// [`DescriptorDistances::quantised`] for `i < j`.
    #[inline]
    pub fn quantised_ordered(&self, i: u32, j: u32) -> u16 {
        debug_assert!(i < j);
        let (i, j) = (i as usize, j as usize);
        self.packed[Self::row_start(self.n, i) + (j - i - 1)]
    }

    /// The descriptor distance between two features (indices into [`OffsetFeatures::features`]),
    /// `None` when either has no descriptor.
    pub fn distance(&self, a: usize, b: usize) -> Option<f64> {
        Some(Self::dequantise(self.quantised(self.compact_index(a)?, self.compact_index(b)?)))
    }
}

/// Best match of every valid feature for each threshold in `taus` (normalised units, each ≥ 0;
/// τ = 0 still excludes the feature itself and coincident features). Returns one list per
/// threshold, in the order of `taus`, with the matches of the features that have one.
pub fn match_features(
    features: &OffsetFeatures,
    taus: &[f64],
    progress: &dyn Progress,
) -> Result<Vec<Vec<FeatureMatch>>> {
    Ok(match_features_keeping_distances(features, taus, 0, progress)?.0)
}

/// [`match_features`], also keeping every pairwise descriptor distance of the scan when the
/// features with a descriptor number at most `keep_up_to` (`0` keeps nothing).
pub fn match_features_keeping_distances(
    features: &OffsetFeatures,
    taus: &[f64],
    keep_up_to: usize,
    progress: &dyn Progress,
) -> Result<(Vec<Vec<FeatureMatch>>, Option<DescriptorDistances>)> {
    if let Some(&t) = taus.iter().find(|t| !(t.is_finite() && **t >= 0.0)) {
        return Err(OffsetsError::InvalidOption {
            name: "tau",
            message: format!("minimum offset lengths must be finite and ≥ 0, got {t}"),
        });
    }
    if taus.is_empty() {
        return Ok((Vec::new(), None));
    }
    // Thresholds in ascending order; `order[k]` is the caller's index of the k-th smallest.
    let mut order: Vec<usize> = (0..taus.len()).collect();
    order.sort_by(|&a, &b| taus[a].total_cmp(&taus[b]));
    let tau2: Vec<f64> = order.iter().map(|&k| taus[k] * taus[k]).collect();
    let nt = tau2.len();

    // Compact the valid features.
    let valid: Vec<usize> = (0..features.len()).filter(|&i| features.valid[i]).collect();
    let n = valid.len();
    let mut desc = Vec::with_capacity(n * SHOT_LEN);
    for &i in &valid {
        desc.extend_from_slice(features.descriptor(i));
    }
    let pos: Vec<Point3> = valid.iter().map(|&i| features.position(i)).collect();
    let sq: Vec<f32> = desc.chunks_exact(SHOT_LEN).map(|r| r.iter().map(|x| x * x).sum()).collect();

    // The kept triangle, split into the disjoint row ranges of the query blocks.
    let keep = n >= 2 && n <= keep_up_to;
    let mut packed = vec![0u16; if keep { n * (n - 1) / 2 } else { 0 }];
    let num_blocks = n.div_ceil(QUERY_BLOCK);
    let mut slices: Vec<&mut [u16]> = Vec::with_capacity(num_blocks);
    {
        let mut rest: &mut [u16] = &mut packed;
        for b in 0..num_blocks {
            let q0 = b * QUERY_BLOCK;
            let q1 = (q0 + QUERY_BLOCK).min(n);
            let len = if keep {
                DescriptorDistances::row_start(n, q1) - DescriptorDistances::row_start(n, q0)
            } else {
                0
            };
            let (head, tail) = std::mem::take(&mut rest).split_at_mut(len);
            slices.push(head);
            rest = tail;
        }
    }

    progress.start("matching features", n as u64);
    let blocks: Vec<Vec<(usize, usize, f32)>> = slices
        .into_par_iter()
        .enumerate()
        .map(|(b, kept)| {
            let kept_base = if keep { DescriptorDistances::row_start(n, b * QUERY_BLOCK) } else { 0 };
            let q0 = b * QUERY_BLOCK;
            let q1 = (q0 + QUERY_BLOCK).min(n);
            let nq = q1 - q0;
            let qm = MatRef::from_row_major_slice(&desc[q0 * SHOT_LEN..q1 * SHOT_LEN], nq, SHOT_LEN);
            // best[q * nt + k] = (squared descriptor distance, target) for threshold k.
            let mut best = vec![(f32::INFINITY, usize::MAX); nq * nt];
            let mut prod = Mat::<f32>::zeros(nq, TARGET_BLOCK.min(n));
            for t0 in (0..n).step_by(TARGET_BLOCK) {
                let t1 = (t0 + TARGET_BLOCK).min(n);
                let tm = MatRef::from_row_major_slice(&desc[t0 * SHOT_LEN..t1 * SHOT_LEN], t1 - t0, SHOT_LEN);
                let mut dst = prod.as_mut().subcols_mut(0, t1 - t0);
                matmul(dst.as_mut(), Accum::Replace, qm, tm.transpose(), 1.0f32, Par::Seq);
                let dst = dst.as_ref();
                for qi in 0..nq {
                    let gq = q0 + qi;
                    let p = pos[gq];
                    let row = &mut best[qi * nt..(qi + 1) * nt];
                    // Row gq of the kept triangle holds targets gq + 1 .. n.
                    let row_base = if keep { DescriptorDistances::row_start(n, gq) - kept_base } else { 0 };
                    for tj in 0..(t1 - t0) {
                        let gt = t0 + tj;
                        let d2 = (sq[gq] + sq[gt] - 2.0 * dst[(qi, tj)]).max(0.0);
                        if keep && gt > gq {
                            kept[row_base + (gt - gq - 1)] = DescriptorDistances::quantise(d2.sqrt());
                        }
                        // The largest threshold's best is the worst of all: nothing above it helps.
                        if d2 > row[nt - 1].0 {
                            continue;
                        }
                        let q = pos[gt];
                        let s2 = (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) + (q[2] - p[2]).powi(2);
                        if s2 <= 0.0 {
                            continue;
                        }
                        for (k, &t2) in tau2.iter().enumerate() {
                            if s2 <= t2 {
                                break;
                            }
                            let cur = row[k];
                            if d2 < cur.0 || (d2 == cur.0 && gt < cur.1) {
                                row[k] = (d2, gt);
                            }
                        }
                    }
                }
            }
            progress.inc(nq as u64);
            best.chunks_exact(nt)
                .enumerate()
                .flat_map(|(qi, row)| row.iter().enumerate().map(move |(k, &(d2, t))| (qi, k, d2, t)))
                .filter(|&(_, _, _, t)| t != usize::MAX)
                .map(|(qi, k, d2, t)| (q0 + qi, k * n + t, d2))
                .collect()
        })
        .collect();
    progress.finish();

    let mut out: Vec<Vec<FeatureMatch>> = vec![Vec::new(); nt];
    for (gq, packed, d2) in blocks.into_iter().flatten() {
        let (k, gt) = (packed / n, packed % n);
        let (fi, fj) = (valid[gq], valid[gt]);
        let (p, q) = (pos[gq], pos[gt]);
        out[k].push(FeatureMatch {
            feature: fi,
            target: fj,
            offset: [q[0] - p[0], q[1] - p[1], q[2] - p[2]],
            descriptor_distance: d2.sqrt(),
        });
    }
    // Back to the caller's order of thresholds.
    let mut result: Vec<Vec<FeatureMatch>> = vec![Vec::new(); nt];
    for (k, list) in out.into_iter().enumerate() {
        result[order[k]] = list;
    }
    let distances = keep.then(|| {
        let mut compact = vec![u32::MAX; features.len()];
        for (c, &i) in valid.iter().enumerate() {
            compact[i] = c as u32;
        }
        DescriptorDistances { compact, n, packed }
    });
    Ok((result, distances))
}
