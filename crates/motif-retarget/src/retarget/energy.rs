//! The MRF of thesis eq. 4.3 over the retargeting space Ω: labels, unary and pairwise terms, the
//! 26-neighbourhood, the feasible start, and the alpha-expansion solve.
//!
//! **Labels** (eq. 4.2). A label is an integer step vector `k = (k₀, k₁, k₂)`; output voxel `x`
//! with label `k` copies input voxel `x − k`, translated by `Σ kᵢ vᵢ`. For `steps = (U, V, W)` the
//! label set is `kᵢ ∈ [0, Uᵢ]` (or `[Uᵢ, 0]` when shrinking), so there are
//! `M = (|U|+1)(|V|+1)(|W|+1)` labels. This is our reading of "the offset space contains
//! `M = U × V × W` translational copies": with `steps` counted as added cells, the copies shifted
//! by 0…U cells are exactly those that can reach the new cells, and it gives the label counts of
//! thesis Fig. 4.8 (3 labels for +2 steps in one direction, 9 for +2 in two). Label 0 is the
//! identity; labels are numbered with the first axis fastest and `|kᵢ|` increasing.
//!
//! **Unary** (4.2.2). 0 when `x − k` is a voxel of the input grid, +∞ otherwise. When growing,
//! this alone pins the ends: the first output voxel along a direction can only copy the first
//! input voxel, the last only the last. When shrinking it does not — every constant labelling is
//! a zero-energy crop that drops one end of the model — so [`super::BoundaryMode::Preserve`]
//! (default) adds what growth implies: an output voxel on the low (high) face of Ω along a
//! resized direction must take `kᵢ = 0` (`kᵢ = stepsᵢ`), i.e. copy the input's low (high)
//! face. The thesis states only the validity term; this constraint is our addition for shrinking.
//!
//! **Pairwise** (eq. 4.4, written there with `x + l`; we use `x − l` consistently with "voxel x …
//! copied from voxel x − l"). For 26-neighbours `x, x'` with labels `lᵢ ≠ lⱼ`:
//! `E = d_H(G(x − lᵢ), G(x − lⱼ)) + d_H(G(x' − lᵢ), G(x' − lⱼ))` — at each of the two voxels the
//! geometry the two copies would put there is compared (as in graph-cut texture seams). `G` is the
//! SHOT set of an input voxel; d_H is 0 when both voxels are empty and +∞ when exactly one is.
//! A voxel outside the input grid holds no geometry, so it counts as empty: this forbids seams
//! where one copy would end abruptly next to geometry of the other (and keeps the input's
//! boundary voxels on the output's boundary). The term is 0 when `lᵢ = lⱼ`. Since d_H is a
//! metric (with the ∞ convention), `E` is a metric in the labels and alpha-expansion applies.
//! All edges have weight 1.
//!
//! **Start.** Alpha-expansion needs a labelling of finite unary cost. The identity is infeasible
//! when growing (new voxels have nothing to copy); we start, per direction, from a single seam in
//! the middle of the model: `kᵢ(x) = 0` below a middle voxel `c` and `stepsᵢ` from `c` on, with
//! `c` the middle of `[stepsᵢ, U_in]` when growing (so both sides copy from inside) and the middle
//! output voxel when shrinking. When a direction grows by more voxels than the input has, the
//! middle input voxel is repeated instead (`kᵢ(x) = clamp(x − c, 0, stepsᵢ)`). Unlike "the
//! smallest shift that copies from inside" (which repeats the last voxel, usually a distinct
//! end), this start has finite pairwise energy on regular models and a single seam per direction,
//! so few expansion moves remain; the solve then moves the seams wherever they cost least.

use std::collections::HashMap;

use rayon::prelude::*;

use crate::alpha_expansion::{AlphaExpansion, AlphaExpansionOptions, AlphaExpansionResult, MrfEnergy};

use super::BoundaryMode;
use super::error::RetargetResult;
use super::voxels::{VoxelDescriptors, VoxelGrid, squared_norms};

/// The offset labels of eq. 4.2 for given steps.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LabelSpace {
    /// Steps per direction (negative shrinks).
    pub steps: [i32; 3],
    /// Labels per direction, `|stepsᵢ| + 1`.
    pub counts: [usize; 3],
    /// The step vector of every label.
    pub labels: Vec<[i32; 3]>,
}

impl LabelSpace {
    /// All labels for `steps`.
    pub fn new(steps: [i32; 3]) -> LabelSpace {
        let counts = steps.map(|s| s.unsigned_abs() as usize + 1);
        let mut labels = Vec::with_capacity(counts.iter().product());
        let signs = steps.map(|s| if s < 0 { -1 } else { 1 });
        for i2 in 0..counts[2] {
            for i1 in 0..counts[1] {
                for i0 in 0..counts[0] {
                    labels.push([i0 as i32 * signs[0], i1 as i32 * signs[1], i2 as i32 * signs[2]]);
                }
            }
        }
        LabelSpace { steps, counts, labels }
    }

    /// The index of step vector `k` (which must be in the set).
    pub fn index_of(&self, k: [i32; 3]) -> usize {
        let i = k.map(|c| c.unsigned_abs() as usize);
        i[0] + self.counts[0] * (i[1] + self.counts[1] * i[2])
    }

    /// Number of labels M.
    pub fn len(&self) -> usize {
        self.labels.len()
    }
}

/// Pairwise descriptor distances d(s, s + δ) between input voxels, for every input voxel `s` and
/// every label difference δ (`|δᵢ| ≤ |stepsᵢ|`), with the empty/outside conventions applied.
#[derive(Debug, Clone)]
struct DistTable {
    radius: [i32; 3],
    span: [usize; 3],
    per_voxel: usize,
    values: Vec<f64>,
}

impl DistTable {
    #[inline]
    fn diff_index(&self, d: [i32; 3]) -> usize {
        let i = [
            (d[0] + self.radius[0]) as usize,
            (d[1] + self.radius[1]) as usize,
            (d[2] + self.radius[2]) as usize,
        ];
        i[0] + self.span[0] * (i[1] + self.span[1] * i[2])
    }
}

/// Cache of d_H between input voxels, keyed by the ordered pair of linear indices; filled on
/// demand and kept across solves of one session.
pub(crate) type DistanceCache = HashMap<(u32, u32), f64, foldhash::fast::FixedState>;

/// Fills `cache` with every d_H that labels of `labels` can ask for and builds the lookup table.
/// Returns the table and the number of distances computed now.
fn distance_table(
    grid: &VoxelGrid,
    descriptors: &VoxelDescriptors,
    labels: &LabelSpace,
    cache: &mut DistanceCache,
) -> (DistTable, usize) {
    let radius = labels.steps.map(|s| s.abs());
    let span = radius.map(|r| 2 * r as usize + 1);
    let per_voxel = span[0] * span[1] * span[2];
    let diffs: Vec<[i32; 3]> = (0..per_voxel)
        .map(|i| {
            let (x, r) = (i % span[0], i / span[0]);
            let (y, z) = (r % span[1], r / span[1]);
            [x as i32 - radius[0], y as i32 - radius[1], z as i32 - radius[2]]
        })
        .collect();
    let n = grid.len();
    let occ = &descriptors.occupied;
    let partner = |s: usize, d: [i32; 3]| {
        let c = grid.coords(s);
        grid.linear_checked([c[0] as i64 + d[0] as i64, c[1] as i64 + d[1] as i64, c[2] as i64 + d[2] as i64])
    };
    // Missing pairs, in a deterministic order.
    let mut missing: Vec<(u32, u32)> = Vec::new();
    for s in 0..n {
        if !occ[s] {
            continue;
        }
        for &d in &diffs {
            if let Some(t) = partner(s, d) {
                if t > s && occ[t] && !cache.contains_key(&(s as u32, t as u32)) {
                    missing.push((s as u32, t as u32));
                }
            }
        }
    }
    missing.sort_unstable();
    missing.dedup();
    // Each voxel takes part in many pairs: its rows' norms are computed once (when some pair is
    // not in the matching step's distance table).
    let norms = if missing.is_empty() || !descriptors.needs_norms() {
        Vec::new()
    } else {
        squared_norms(&descriptors.rows)
    };
    let computed: Vec<f64> =
        missing.par_iter().map(|&(s, t)| descriptors.hausdorff(s as usize, t as usize, &norms)).collect();
    for (k, d) in missing.iter().zip(&computed) {
        cache.insert(*k, *d);
    }
    let mut values = vec![0.0; n * per_voxel];
    for s in 0..n {
        for (di, &d) in diffs.iter().enumerate() {
            values[s * per_voxel + di] = if d == [0, 0, 0] {
                0.0
            } else {
                match partner(s, d) {
                    // Outside the input grid: empty.
                    None => {
                        if occ[s] {
                            f64::INFINITY
                        } else {
                            0.0
                        }
                    }
                    Some(t) => match (occ[s], occ[t]) {
                        (false, false) => 0.0,
                        (true, true) => {
                            let key = (s.min(t) as u32, s.max(t) as u32);
                            cache.get(&key).copied().unwrap_or(f64::INFINITY)
                        }
                        _ => f64::INFINITY,
                    },
                }
            };
        }
    }
    (DistTable { radius, span, per_voxel, values }, missing.len())
}

/// The 13 neighbour directions of the 26-neighbourhood that are lexicographically positive.
fn half_neighbourhood() -> Vec<[i64; 3]> {
    let mut dirs = Vec::with_capacity(13);
    for dz in -1..=1i64 {
        for dy in -1..=1i64 {
            for dx in -1..=1i64 {
                let d = [dx, dy, dz];
                if d > [0, 0, 0] {
                    dirs.push(d);
                }
            }
        }
    }
    // Sort for a stable, readable order (+x first).
    dirs.sort_unstable_by_key(|d| (d[2].abs() + d[1].abs() + d[0].abs(), *d));
    dirs
}

/// The 26-neighbourhood edges `[p, q]` (each pair once) of a grid with `dims` voxels.
pub(crate) fn grid_edges(dims: [usize; 3]) -> Vec<[u32; 2]> {
    let g = VoxelGrid { origin: [0.0; 3], pitch: [1.0; 3], dims };
    let dirs = half_neighbourhood();
    let mut edges = Vec::with_capacity(g.len() * 13);
    for p in 0..g.len() {
        let c = g.coords(p);
        for d in &dirs {
            if let Some(q) = g.linear_checked([c[0] as i64 + d[0], c[1] as i64 + d[1], c[2] as i64 + d[2]]) {
                edges.push([p as u32, q as u32]);
            }
        }
    }
    edges
}

/// Everything a solve produces.
#[derive(Debug, Clone)]
pub(crate) struct Solved {
    /// Step vector chosen for every output voxel (first axis fastest).
    pub labels: Vec<[i32; 3]>,
    /// The alpha-expansion outcome (labels as indices).
    pub result: AlphaExpansionResult<f64>,
    /// Number of 26-neighbourhood edges.
    pub edges: usize,
    /// Edges whose voxels got different labels.
    pub seams: usize,
    /// Seams of infinite cost: one copy's geometry meets another copy's empty space (or the
    /// outside of the input) there, so the stitched output may be open along them.
    pub infinite_seams: usize,
    /// Distinct labels used.
    pub labels_used: usize,
    /// d_H evaluations done for this solve (the rest came from the cache).
    pub distances_computed: usize,
    /// Time spent on the distance table, ms.
    pub distances_ms: f64,
}

/// Sets up eq. 4.3 for the input grid `grid_in` and `steps`, and minimises it by alpha-expansion.
pub(crate) fn solve(
    grid_in: &VoxelGrid,
    descriptors: &VoxelDescriptors,
    steps: [i32; 3],
    boundary: BoundaryMode,
    cache: &mut DistanceCache,
    options: &AlphaExpansionOptions,
) -> RetargetResult<Solved> {
    let t0 = std::time::Instant::now();
    let labels = LabelSpace::new(steps);
    let (table, distances_computed) = distance_table(grid_in, descriptors, &labels, cache);
    let distances_ms = t0.elapsed().as_secs_f64() * 1e3;

    let n_in = grid_in.dims.map(|d| d as i64);
    let out_dims: [usize; 3] =
        std::array::from_fn(|a| (grid_in.dims[a] as i64 + steps[a] as i64).max(1) as usize);
    let out = VoxelGrid { origin: [0.0; 3], pitch: [1.0; 3], dims: out_dims };
    let coords: Vec<[i64; 3]> = (0..out.len()).map(|p| out.coords(p).map(|c| c as i64)).collect();
    let edges = grid_edges(out_dims);
    let pinned = |a: usize| boundary == BoundaryMode::Preserve && steps[a] != 0;

    let valid = |p: usize, l: usize| {
        let x = coords[p];
        let k = labels.labels[l];
        (0..3).all(|a| {
            let s = x[a] - k[a] as i64;
            if s < 0 || s >= n_in[a] {
                return false;
            }
            if pinned(a) {
                if x[a] == 0 && k[a] != 0 {
                    return false;
                }
                if x[a] == out_dims[a] as i64 - 1 && k[a] != steps[a] {
                    return false;
                }
            }
            true
        })
    };
    // The callbacks are evaluated four times per edge and move: precompute the source voxel of
    // every (site, label) (`NONE` outside the input) and the difference index of every label
    // pair, so that a term is three lookups.
    const NONE: u32 = u32::MAX;
    let num_labels = labels.len();
    let source: Vec<u32> = (0..out.len())
        .flat_map(|p| {
            let c = coords[p];
            labels.labels.iter().map(move |k| {
                let s = [c[0] - k[0] as i64, c[1] - k[1] as i64, c[2] - k[2] as i64];
                grid_in.linear_checked(s).map_or(NONE, |i| i as u32)
            })
        })
        .collect();
    let unary: Vec<f64> = (0..out.len())
        .flat_map(|p| (0..num_labels).map(move |l| (p, l)))
        .map(|(p, l)| if valid(p, l) { 0.0 } else { f64::INFINITY })
        .collect();
    let diff_index: Vec<u32> = labels
        .labels
        .iter()
        .flat_map(|kp| {
            labels
                .labels
                .iter()
                .map(|kq| table.diff_index([kp[0] - kq[0], kp[1] - kq[1], kp[2] - kq[2]]) as u32)
        })
        .collect();
    let occ = &descriptors.occupied;
    // d(G(x − k_lp), G(x − k_lq)) at output voxel x.
    let term = |x: usize, lp: usize, lq: usize| -> f64 {
        let s = source[x * num_labels + lp];
        if s != NONE {
            table.values[s as usize * table.per_voxel + diff_index[lp * num_labels + lq] as usize]
        } else {
            // Outside the input: empty.
            match source[x * num_labels + lq] {
                NONE => 0.0,
                t if occ[t as usize] => f64::INFINITY,
                _ => 0.0,
            }
        }
    };
    let energy = MrfEnergy::new(
        out.len(),
        num_labels,
        &edges,
        |p, l| unary[p * num_labels + l],
        |p, q, lp, lq| if lp == lq { 0.0 } else { term(p, lp, lq) + term(q, lp, lq) },
    );
    let init = initial_labels(grid_in.dims, out_dims, steps, &labels);
    let result = AlphaExpansion::new().solve(&energy, &init, options)?;
    let (mut seams, mut infinite_seams) = (0, 0);
    for &[p, q] in &edges {
        let (lp, lq) = (result.labels[p as usize] as usize, result.labels[q as usize] as usize);
        if lp != lq {
            seams += 1;
            if (term(p as usize, lp, lq) + term(q as usize, lp, lq)).is_infinite() {
                infinite_seams += 1;
            }
        }
    }
    let mut used = vec![false; labels.len()];
    for &l in &result.labels {
        used[l as usize] = true;
    }
    Ok(Solved {
        labels: result.labels.iter().map(|&l| labels.labels[l as usize]).collect(),
        edges: edges.len(),
        seams,
        infinite_seams,
        labels_used: used.iter().filter(|u| **u).count(),
        result,
        distances_computed,
        distances_ms,
    })
}

/// The feasible start described in the module docs.
fn initial_labels(
    in_dims: [usize; 3],
    out_dims: [usize; 3],
    steps: [i32; 3],
    labels: &LabelSpace,
) -> Vec<u32> {
    let per_axis: [Vec<i32>; 3] = std::array::from_fn(|a| {
        let s = steps[a] as i64;
        let n_out = out_dims[a] as i64;
        (0..n_out)
            .map(|x| {
                let n_in = in_dims[a] as i64;
                let k = if s > 0 && s <= n_in {
                    // One jump by s at c ∈ [s, n_in]: voxels below c copy themselves, the rest
                    // copy x − s (valid since x − s ≥ c − s ≥ 0 and c − 1 ≤ n_in − 1).
                    let c = (s + n_in) / 2;
                    if x < c { 0 } else { s }
                } else if s > 0 {
                    // More new voxels than the input has: repeat the middle voxel.
                    let c = (n_in - 1) / 2;
                    (x - c).clamp(0, s)
                } else if s < 0 {
                    let c = (n_out / 2).clamp(1, (n_out - 1).max(1));
                    if x < c { 0 } else { s }
                } else {
                    0
                };
                k as i32
            })
            .collect()
    });
    let g = VoxelGrid { origin: [0.0; 3], pitch: [1.0; 3], dims: out_dims };
    (0..g.len())
        .map(|p| {
            let c = g.coords(p);
            labels.index_of([per_axis[0][c[0]], per_axis[1][c[1]], per_axis[2][c[2]]]) as u32
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn label_space_counts_and_indices() {
        let l = LabelSpace::new([2, -1, 0]);
        assert_eq!(l.len(), 6);
        assert_eq!(l.labels[0], [0, 0, 0]);
        for (i, k) in l.labels.iter().enumerate() {
            assert_eq!(l.index_of(*k), i);
        }
        assert!(l.labels.contains(&[2, -1, 0]));
    }

    #[test]
    fn neighbourhood_has_26_neighbours() {
        assert_eq!(half_neighbourhood().len(), 13);
        // A 3×3×3 grid: the centre voxel has 26 edges.
        let e = grid_edges([3, 3, 3]);
        assert_eq!(e.iter().filter(|[p, q]| *p == 13 || *q == 13).count(), 26);
    }

    #[test]
    fn initial_labels_are_valid() {
        for (n_in, s) in [(5usize, 2i32), (5, -2), (4, 1), (1, 3), (3, -1)] {
            let labels = LabelSpace::new([s, 0, 0]);
            let out = [(n_in as i32 + s) as usize, 1, 1];
            let init = initial_labels([n_in, 1, 1], out, [s, 0, 0], &labels);
            for (x, &l) in init.iter().enumerate() {
                let k = labels.labels[l as usize][0];
                let src = x as i32 - k;
                assert!((0..n_in as i32).contains(&src), "n_in {n_in} steps {s}: voxel {x} label {k}");
            }
            // The ends copy the ends.
            assert_eq!(labels.labels[init[0] as usize][0], 0);
            assert_eq!(labels.labels[init[out[0] - 1] as usize][0], s);
        }
    }
}
