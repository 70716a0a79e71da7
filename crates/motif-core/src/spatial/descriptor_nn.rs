//! Blocked brute-force nearest neighbours for high-dimensional descriptors (SHOT 352-d, HOC 1024-d).
//!
//! kd-trees degrade to linear scans beyond ~20 dimensions, so descriptor matching is done by brute
//! force, arranged as a matrix product: ‖a − b‖² = ‖a‖² + ‖b‖² − 2 a·b, where the a·b terms for a
//! block of queries against a block of targets are one GEMM (faer, f32). Query blocks run in
//! parallel (rayon); each keeps its running best-k per query, so memory stays O(block²).

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// Options of [`descriptor_nn`] / [`descriptor_knn`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DescriptorNnOptions {
    /// Queries per block (rows of one GEMM). Default 256.
    pub query_block: usize,
    /// Targets per block (columns of one GEMM). Default 2048: 2048 × 1024 f32 = 8 MiB.
    pub target_block: usize,
}

impl Default for DescriptorNnOptions {
    fn default() -> Self {
        DescriptorNnOptions { query_block: 256, target_block: 2048 }
    }
}

/// A match from a query descriptor to a target descriptor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DescriptorMatch {
    /// Index of the target descriptor.
    pub target: usize,
    /// Euclidean (L2) distance between the descriptors.
    pub distance: f32,
}

/// For each query (rows of `queries`, `dim` values each, row-major) the nearest target (rows of
/// `targets`), by Euclidean distance. With `exclude_self`, query `i` never matches target `i`
/// (for matching a set against itself).
pub fn descriptor_nn(
    queries: &[f32],
    targets: &[f32],
    dim: usize,
    exclude_self: bool,
    options: &DescriptorNnOptions,
) -> Result<Vec<Option<DescriptorMatch>>> {
    Ok(descriptor_knn(queries, targets, dim, 1, exclude_self, options)?
        .into_iter()
        .map(|v| v.first().copied())
        .collect())
}

/// For each query the `k` nearest targets, closest first (ties by target index). See
/// [`descriptor_nn`] for the layout.
pub fn descriptor_knn(
    queries: &[f32],
    targets: &[f32],
    dim: usize,
    k: usize,
    exclude_self: bool,
    options: &DescriptorNnOptions,
) -> Result<Vec<Vec<DescriptorMatch>>> {
    if dim == 0 || queries.len() % dim != 0 || targets.len() % dim != 0 {
        return Err(Error::InvalidInput(format!(
            "descriptor arrays of {} and {} values are not whole rows of {dim}",
            queries.len(),
            targets.len()
        )));
    }
    let nq = queries.len() / dim;
    let nt = targets.len() / dim;
    let qb = options.query_block.max(1);
    let tb = options.target_block.max(1);
    let sq = |rows: &[f32]| -> Vec<f32> {
        rows.chunks_exact(dim).map(|r| r.iter().map(|x| x * x).sum::<f32>()).collect()
    };
    let qn = sq(queries);
    let tn = sq(targets);

    let blocks: Vec<Vec<Vec<DescriptorMatch>>> = (0..nq.div_ceil(qb))
        .into_par_iter()
        .map(|b| {
            let q0 = b * qb;
            let q1 = (q0 + qb).min(nq);
            let qm = MatRef::from_row_major_slice(&queries[q0 * dim..q1 * dim], q1 - q0, dim);
            let mut best: Vec<Vec<DescriptorMatch>> = vec![Vec::with_capacity(k + 1); q1 - q0];
            let mut prod = Mat::<f32>::zeros(q1 - q0, tb.min(nt.max(1)));
            for t0 in (0..nt).step_by(tb) {
                let t1 = (t0 + tb).min(nt);
                let tm = MatRef::from_row_major_slice(&targets[t0 * dim..t1 * dim], t1 - t0, dim);
                let mut dst = prod.as_mut().subcols_mut(0, t1 - t0);
                matmul(dst.as_mut(), Accum::Replace, qm, tm.transpose(), 1.0f32, Par::Seq);
                let dst = dst.as_ref();
                for (qi, list) in best.iter_mut().enumerate() {
                    let gq = q0 + qi;
                    for tj in 0..(t1 - t0) {
                        let gt = t0 + tj;
                        if exclude_self && gq == gt {
                            continue;
                        }
                        let d2 = (qn[gq] + tn[gt] - 2.0 * dst[(qi, tj)]).max(0.0);
                        let d = d2.sqrt();
                        if list.len() == k && d >= list[k - 1].distance {
                            continue;
                        }
                        let pos =
                            list.partition_point(|m| m.distance < d || (m.distance == d && m.target < gt));
                        list.insert(pos, DescriptorMatch { target: gt, distance: d });
                        list.truncate(k);
                    }
                }
            }
            best
        })
        .collect();
    Ok(blocks.into_iter().flatten().collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn agrees_with_naive_search() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let dim = 352;
        let q: Vec<f32> = (0..300 * dim).map(|_| rng.random()).collect();
        let t: Vec<f32> = (0..700 * dim).map(|_| rng.random()).collect();
        let opts = DescriptorNnOptions { query_block: 64, target_block: 128 };
        let got = descriptor_knn(&q, &t, dim, 3, false, &opts).unwrap();
        for (i, row) in q.chunks_exact(dim).enumerate() {
            let mut all: Vec<(f32, usize)> = t
                .chunks_exact(dim)
                .enumerate()
                .map(|(j, c)| (row.iter().zip(c).map(|(a, b)| (a - b) * (a - b)).sum::<f32>().sqrt(), j))
                .collect();
            all.sort_by(|a, b| a.0.total_cmp(&b.0));
            assert_eq!(got[i][0].target, all[0].1);
            assert!((got[i][0].distance - all[0].0).abs() < 1e-3 * all[0].0.max(1.0));
            assert_eq!(got[i].len(), 3);
        }
    }

    #[test]
    fn exclude_self_skips_the_diagonal() {
        let dim = 4;
        let d: Vec<f32> = vec![0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0];
        let m = descriptor_nn(&d, &d, dim, true, &DescriptorNnOptions::default()).unwrap();
        assert_eq!(m[0].unwrap().target, 1);
        assert_eq!(m[2].unwrap().target, 1);
    }
}
