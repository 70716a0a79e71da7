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

/// Best match of every valid feature for each threshold in `taus` (normalised units, each ≥ 0;
/// τ = 0 still excludes the feature itself and coincident features). Returns one list per
/// threshold, in the order of `taus`, with the matches of the features that have one.
pub fn match_features(
    features: &OffsetFeatures,
    taus: &[f64],
    progress: &dyn Progress,
) -> Result<Vec<Vec<FeatureMatch>>> {
    if let Some(&t) = taus.iter().find(|t| !(t.is_finite() && **t >= 0.0)) {
        return Err(OffsetsError::InvalidOption {
            name: "tau",
            message: format!("minimum offset lengths must be finite and ≥ 0, got {t}"),
        });
    }
    if taus.is_empty() {
        return Ok(Vec::new());
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

    progress.start("matching features", n as u64);
    let blocks: Vec<Vec<(usize, usize, f32)>> = (0..n.div_ceil(QUERY_BLOCK))
        .into_par_iter()
        .map(|b| {
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
                    for tj in 0..(t1 - t0) {
                        let gt = t0 + tj;
                        let d2 = (sq[gq] + sq[gt] - 2.0 * dst[(qi, tj)]).max(0.0);
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
    Ok(result)
}
