//! The voxel grid of the retargeting space and the per-voxel shape descriptors G(x) of thesis
//! eq. 4.4.
//!
//! The grid lives in canonical space ([`super::canonical`]): voxel `(i, j, k)` is the box
//! `origin + [i, i+1) × pitch₀ × [j, j+1) × pitch₁ × [k, k+1) × pitch₂`, with `origin` the
//! minimum corner of the input's canonical bounding box (thesis 4.2.2: "discretize Ω … using the
//! principle offsets as the generators"). Voxels are numbered with the first axis fastest.
//!
//! **Triangle assignment.** Each triangle belongs to exactly one input voxel, the one containing
//! its centroid. A centroid on a voxel face (a board end face lying exactly on a cell boundary,
//! common in man-made models whose cells the offsets delimit) is ambiguous up to rounding, so the
//! probe point is the centroid moved inwards by 10⁻⁶ of the smallest cell edge against the face
//! normal: for closed, outward-oriented parts a face then belongs to the voxel its solid lies in.
//!
//! **Descriptors.** G(x) is "the set of SHOT descriptors contained in the voxel" (4.2.2). As in
//! thesis 4.3, a dense Poisson-disc cloud (spacing 0.02) supports the descriptors and a sparser
//! feature cloud (spacing 0.06) resampled from it are the keypoints; SHOT uses the world frame
//! (4.4) and radius 0.2. A feature belongs to the voxel of the triangle it was sampled on, so the
//! descriptors of a voxel describe exactly the geometry that a copy of the voxel carries. A voxel
//! with triangles but no feature (a small piece) gets its dense samples as keypoints, or failing
//! those its triangles' centroids, so that "non-empty" always means "has triangles".

use std::sync::Arc;

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use motif_core::geometry::{Point3, add, scale, sub};
use motif_core::mesh::TriMesh;
use motif_core::progress::Progress;
use motif_core::sampling::{
    Constraints, PoissonDiscOptions, Spacing, poisson_disc_points, poisson_disc_surface,
};
use motif_core::shot::{SHOT_LEN, ShotFrame, ShotOptions, compute_shot_with_tree};
use motif_core::spatial::KdTree;
use rayon::prelude::*;

use super::canonical::Lattice;
use super::error::RetargetResult;
use crate::offsets::{DescriptorDistances, OffsetFeatures};

/// A regular grid of voxels in canonical space.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct VoxelGrid {
    /// Minimum corner, canonical coordinates.
    pub origin: Point3,
    /// Voxel edge lengths, normalised units.
    pub pitch: [f64; 3],
    /// Number of voxels along each axis.
    pub dims: [usize; 3],
}

/// Slack when counting voxels, in cells: an extent of up to 5.01 cells is 5 cells, whatever lies
/// beyond the last voxel face is assigned to the last voxel. Detected offsets are accurate to about
/// 10⁻⁴ of a cell and carry tiny skews, which would otherwise add sliver voxels at the ends.
const COUNT_SLACK: f64 = 0.01;

impl VoxelGrid {
    /// The grid covering the canonical bounding box of `points` (model space).
    pub fn covering(lattice: &Lattice, points: &[Point3]) -> VoxelGrid {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in points {
            let c = lattice.canonical(*p);
            for a in 0..3 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        let mut dims = [1; 3];
        for a in 0..3 {
            let cells = (hi[a] - lo[a]) / lattice.pitch[a];
            dims[a] = if cells.is_finite() { ((cells - COUNT_SLACK).ceil().max(1.0)) as usize } else { 1 };
        }
        VoxelGrid { origin: lo, pitch: lattice.pitch, dims }
    }

    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Linear index of integer coordinates (first axis fastest).
    #[inline]
    pub fn linear(&self, c: [usize; 3]) -> usize {
        c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])
    }

    /// Linear index of signed coordinates, `None` outside the grid.
    #[inline]
    pub fn linear_checked(&self, c: [i64; 3]) -> Option<usize> {
        for a in 0..3 {
            if c[a] < 0 || c[a] >= self.dims[a] as i64 {
                return None;
            }
        }
        Some(self.linear([c[0] as usize, c[1] as usize, c[2] as usize]))
    }

    /// Integer coordinates of a linear index.
    #[inline]
    pub fn coords(&self, i: usize) -> [usize; 3] {
        let x = i % self.dims[0];
        let r = i / self.dims[0];
        [x, r % self.dims[1], r / self.dims[1]]
    }

    /// The voxel containing a canonical point, clamped into the grid.
    #[inline]
    pub fn voxel_of(&self, c: Point3) -> [usize; 3] {
        let mut v = [0; 3];
        for a in 0..3 {
            let f = ((c[a] - self.origin[a]) / self.pitch[a]).floor();
            v[a] = if f.is_finite() { f.clamp(0.0, (self.dims[a] - 1) as f64) as usize } else { 0 };
        }
        v
    }
}

/// The input voxel (linear index) of every triangle: its centroid probed slightly inwards (see the
/// module docs).
pub(crate) fn assign_triangles(mesh: &TriMesh, lattice: &Lattice, grid: &VoxelGrid) -> Vec<u32> {
    let min_pitch = grid.pitch[0].min(grid.pitch[1]).min(grid.pitch[2]);
    let delta = 1e-6 * min_pitch;
    (0..mesh.triangles.len())
        .into_par_iter()
        .map(|f| {
            let [a, b, c] = mesh.corners(f);
            let centroid = scale(add(add(a, b), c), 1.0 / 3.0);
            let n = motif_core::geometry::normalize(mesh.face_cross(f)).unwrap_or([0.0; 3]);
            // Normalised space is a uniform scaling of model space: normals are unchanged.
            let probe = sub(lattice.canonical(centroid), lattice.canonical_vector(scale(n, delta)));
            grid.linear(grid.voxel_of(probe)) as u32
        })
        .collect()
}

/// Sampling and descriptor parameters (from [`super::RetargetOptions`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct DescriptorParams {
    pub sample_spacing: f64,
    pub feature_spacing: f64,
    pub shot_radius: f64,
    pub seed: u64,
}

/// The descriptor sets G(x) of every input voxel.
#[derive(Debug, Clone, Default)]
pub(crate) struct VoxelDescriptors {
    /// Valid descriptors, grouped by voxel: rows `start[v]..start[v + 1]` belong to voxel `v`;
    /// each row has [`SHOT_LEN`] values and unit length.
    pub rows: Vec<f32>,
    /// Row ranges per voxel (`#voxels + 1`).
    pub start: Vec<u32>,
    /// Whether each voxel holds triangles.
    pub occupied: Vec<bool>,
    /// Dense support samples drawn.
    pub num_samples: usize,
    /// Keypoints described (features plus fallbacks).
    pub num_keypoints: usize,
    /// Keypoints with a valid descriptor.
    pub num_valid: usize,
    /// Per row, its index in `table` (the feature's compact index in the matching step's
    /// distance table), or `u32::MAX` for rows without one (fallback keypoints, or no table).
    pub keys: Vec<u32>,
    /// The matching step's pairwise descriptor distances (thesis 4.2.2), when the rows came from
    /// the offset detection's features and it kept them.
    pub table: Option<Arc<DescriptorDistances>>,
}

impl VoxelDescriptors {
    /// The descriptor rows of voxel `v` (`#rows × 352`).
    #[inline]
    pub fn of(&self, v: usize) -> &[f32] {
        &self.rows[self.start[v] as usize * SHOT_LEN..self.start[v + 1] as usize * SHOT_LEN]
    }

    /// The table keys of voxel `v`'s rows, when every row has one (they are then strictly
    /// ascending, as [`hausdorff_lookup`] needs: rows are stored in feature order).
    #[inline]
    fn keys_of(&self, v: usize) -> Option<&[u32]> {
        let k = self.keys.get(self.start[v] as usize..self.start[v + 1] as usize)?;
        let usable = self.table.is_some()
            && !k.is_empty()
            && k[k.len() - 1] != u32::MAX
            && k.windows(2).all(|w| w[0] < w[1]);
        usable.then_some(k)
    }

    /// d_H between the descriptor sets of voxels `s` and `t`: looked up in the matching step's
    /// distance table when both sets are in it (thesis 4.2.2), otherwise computed by
    /// [`hausdorff_with_norms`] (`norms` = [`squared_norms`] of all rows).
    pub fn hausdorff(&self, s: usize, t: usize, norms: &[f32]) -> f64 {
        if let (Some(table), Some(a), Some(b)) = (&self.table, self.keys_of(s), self.keys_of(t)) {
            return hausdorff_lookup(table, a, b);
        }
        let norms_of = |v: usize| &norms[self.start[v] as usize..self.start[v + 1] as usize];
        hausdorff_with_norms(self.of(s), norms_of(s), self.of(t), norms_of(t))
    }

    /// Whether [`VoxelDescriptors::hausdorff`] needs the rows' squared norms for some pair.
    pub fn needs_norms(&self) -> bool {
        self.table.is_none() || self.keys.contains(&u32::MAX)
    }
}

/// Below this many entries (`|a| · |b|`, sets of about 64 features each), [`hausdorff_lookup`]
/// reads the whole block once for both directions, a pass without branches that vectorises,
/// where the early break reads each direction separately, an entry at a time. The break saves
/// time only when it skips most entries: on the dense baseline's voxels of the generated shelf
/// (two or three features each) it read 34% more entries; on the offsets' voxels of the shelf
/// (about 46 features) it read 62% fewer but took as long or longer (`motif bench retarget`,
/// stage "distances": 0.86 and 1.08 ms against 0.62 and 0.93); on the facade's (about 115) it
/// read 84% fewer and took 1.02 and 1.05 ms against 1.44 and 1.13, on the gridbeam shelf's
/// (about 320) 89% fewer, 1.82 and 2.44 ms against 8.41 and 7.89.
const EXHAUSTIVE_BELOW: usize = 4096;

/// d_H from a distance table: the larger of the two directed distances
/// `max_a min_b d(a, b)` and `max_b min_a d(a, b)` over the quantised table entries, exact.
///
/// Each directed distance ([`directed_lookup`]) breaks off its scan of `b` as soon as an entry
/// is no larger than the largest minimum found so far, since that `a` cannot raise the maximum
/// (Taha and Hanbury, "An efficient algorithm for calculating the exact Hausdorff distance",
/// 2015), and the second direction starts from the first one's value. Small sets are read
/// whole ([`EXHAUSTIVE_BELOW`]). The lookups of `motif retarget MESH --steps 1,0,0` read 35,039
/// entries instead of 213,505 on the generated facade, 230,032 instead of 2,092,421 on the
/// gridbeam shelf of the shared data (counted with a temporary counter).
fn hausdorff_lookup(table: &DescriptorDistances, a: &[u32], b: &[u32]) -> f64 {
    if a.len() * b.len() < EXHAUSTIVE_BELOW {
        return DescriptorDistances::dequantise(exhaustive_lookup(table, a, b));
    }
    let forward = directed_lookup(table, a, b, 0);
    DescriptorDistances::dequantise(directed_lookup(table, b, a, forward))
}

/// `max(floor, max_{i ∈ a} min_{j ∈ b} d(i, j))` with the early break of [`hausdorff_lookup`].
///
/// The members of `a` are visited in a fixed scattered order (a stride of about 0.618 |a|,
/// coprime to |a|), as the early break wants an order unrelated to the sets' layout: the
/// largest minima then turn up early, and the breaks with them (on the facade above, 19% fewer
/// reads than in key order). The scan of `b` for each `a` starts where the previous one found
/// its nearest entry, and goes round from there in at most three runs on which the order of
/// the keys is fixed (keys below `i` are read along column `i` of the table, keys above along
/// row `i`), so the reads have no branch on it.
fn directed_lookup(table: &DescriptorDistances, a: &[u32], b: &[u32], floor: u16) -> u16 {
    let n = a.len();
    let mut stride = ((n as f64 * 0.618) as usize) | 1;
    while gcd(stride, n) != 1 {
        stride += 2;
    }
    let mut worst = floor;
    let mut start = 0;
    for q in 0..n {
        let i = a[q * stride % n];
        let split = b.partition_point(|&j| j < i);
        // (first index, run, whether its keys lie below i)
        let runs: [(usize, &[u32], bool); 3] = if start <= split {
            [(start, &b[start..split], true), (split, &b[split..], false), (0, &b[..start], true)]
        } else {
            [(start, &b[start..], false), (0, &b[..split], true), (split, &b[split..start], false)]
        };
        let mut nearest = u16::MAX;
        let mut at = start;
        'scan: for (first, run, below) in runs {
            for (k, &j) in run.iter().enumerate() {
                let d = if below {
                    table.quantised_ordered(j, i)
                } else if j == i {
                    0
                } else {
                    table.quantised_ordered(i, j)
                };
                if d < nearest {
                    nearest = d;
                    at = first + k;
                    if d <= worst {
                        break 'scan;
                    }
                }
            }
        }
        worst = worst.max(nearest);
        start = at;
    }
    worst
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// Both directed distances in one pass over the `|a| × |b|` entries (a `u16` minimum per row
/// and per column). Both key lists are ascending (rows are stored in feature order), so for
/// each `i` of `a` the keys of `b` above `i` are read along row `i` of the table and those
/// below along column `i`, without a branch per entry.
fn exhaustive_lookup(table: &DescriptorDistances, a: &[u32], b: &[u32]) -> u16 {
    let mut col_min = vec![u16::MAX; b.len()];
    let mut worst = 0u16;
    for &i in a {
        let split = b.partition_point(|&j| j < i);
        let mut row_min = u16::MAX;
        let (lo, hi) = b.split_at(split);
        let (col_lo, col_hi) = col_min.split_at_mut(split);
        for (c, &j) in col_lo.iter_mut().zip(lo) {
            let d = table.quantised_ordered(j, i);
            row_min = row_min.min(d);
            *c = (*c).min(d);
        }
        for (c, &j) in col_hi.iter_mut().zip(hi) {
            let d = if j == i { 0 } else { table.quantised_ordered(i, j) };
            row_min = row_min.min(d);
            *c = (*c).min(d);
        }
        worst = worst.max(row_min);
    }
    col_min.iter().fold(worst, |w, &c| w.max(c))
}

/// Samples the normalised mesh, describes its features with SHOT and groups the descriptors by
/// the voxel of the triangle each feature lies on. Reports progress in the stages "sampling" and
/// "SHOT descriptors"; returns the descriptors and the time spent sampling (ms).
pub(crate) fn describe_voxels(
    normalised: &TriMesh,
    tri_voxel: &[u32],
    num_voxels: usize,
    params: &DescriptorParams,
    progress: &dyn Progress,
) -> RetargetResult<(VoxelDescriptors, f64)> {
    let t0 = std::time::Instant::now();
    let mut occupied = vec![false; num_voxels];
    for &v in tri_voxel {
        occupied[v as usize] = true;
    }
    progress.start("sampling", 0);
    let dense = poisson_disc_surface(
        normalised,
        &Constraints::default(),
        &PoissonDiscOptions {
            spacing: Spacing::Radius(params.sample_spacing),
            seed: params.seed,
            ..Default::default()
        },
    )?;
    let mut points = dense.positions.clone();
    let mut normals = dense.normals.clone().unwrap_or_else(|| vec![[0.0; 3]; points.len()]);
    let faces = dense.faces.clone().unwrap_or_else(|| vec![0; points.len()]);
    let mut point_voxel: Vec<u32> = faces.iter().map(|&f| tri_voxel[f as usize]).collect();
    let mut keypoints: Vec<usize> = if points.is_empty() {
        Vec::new()
    } else {
        poisson_disc_points(
            &points,
            None,
            &Constraints::default(),
            &PoissonDiscOptions {
                spacing: Spacing::Radius(params.feature_spacing),
                seed: params.seed.wrapping_add(1),
                ..Default::default()
            },
        )?
        .candidate_indices()
    };
    // Fallbacks for occupied voxels without a feature.
    let mut has_key = vec![false; num_voxels];
    for &k in &keypoints {
        has_key[point_voxel[k] as usize] = true;
    }
    let mut has_sample = vec![false; num_voxels];
    for (i, &v) in point_voxel.iter().enumerate() {
        if occupied[v as usize] && !has_key[v as usize] {
            keypoints.push(i);
            has_sample[v as usize] = true;
        }
    }
    const MAX_CENTROIDS: usize = 16;
    let mut centroids_added = vec![0usize; num_voxels];
    let face_normals = normalised.face_normals();
    for (f, &v) in tri_voxel.iter().enumerate() {
        let v = v as usize;
        if occupied[v] && !has_key[v] && !has_sample[v] && centroids_added[v] < MAX_CENTROIDS {
            let [a, b, c] = normalised.corners(f);
            points.push(scale(add(add(a, b), c), 1.0 / 3.0));
            normals.push(face_normals[f]);
            point_voxel.push(v as u32);
            keypoints.push(points.len() - 1);
            centroids_added[v] += 1;
        }
    }
    progress.finish();
    let sampling_ms = t0.elapsed().as_secs_f64() * 1e3;

    let mut out = VoxelDescriptors {
        occupied,
        num_samples: dense.positions.len(),
        num_keypoints: keypoints.len(),
        ..Default::default()
    };
    if points.is_empty() {
        out.start = vec![0; num_voxels + 1];
        return Ok((out, sampling_ms));
    }
    let tree = KdTree::new(&points)?;
    let shot = compute_shot_with_tree(
        &tree,
        &points,
        &normals,
        &keypoints,
        &ShotOptions { radius: params.shot_radius, frame: ShotFrame::World, ..Default::default() },
        progress,
    )?;
    // Group valid rows by voxel (stable: keypoint order within a voxel).
    let mut count = vec![0u32; num_voxels + 1];
    for (i, &k) in keypoints.iter().enumerate() {
        if shot.valid[i] {
            count[point_voxel[k] as usize + 1] += 1;
        }
    }
    for v in 0..num_voxels {
        count[v + 1] += count[v];
    }
    let total = count[num_voxels] as usize;
    let mut rows = vec![0f32; total * SHOT_LEN];
    let mut fill = count.clone();
    for (i, &k) in keypoints.iter().enumerate() {
        if let (true, Some(d)) = (shot.valid[i], shot.descriptor(i)) {
            let v = point_voxel[k] as usize;
            let r = fill[v] as usize;
            rows[r * SHOT_LEN..(r + 1) * SHOT_LEN].copy_from_slice(d);
            fill[v] += 1;
        }
    }
    out.rows = rows;
    out.start = count;
    out.num_valid = total;
    Ok((out, sampling_ms))
}

/// The voxel sets G(x) from features prepared by the offset detection
/// ([`crate::offsets::prepare_features`]; thesis 4.2.2: "the pairwise feature distances have
/// already been computed in the previous step … and can be reused here"). Features carry no
/// triangle, so each goes to the voxel containing its position probed 10⁻⁶ cells against its
/// normal (the same rule as for triangles). Occupied voxels without a feature get their dense
/// points as keypoints, described with the detection's dense cloud and kd-tree.
pub(crate) fn describe_from_features(
    features: &OffsetFeatures,
    lattice: &Lattice,
    grid: &VoxelGrid,
    occupied: Vec<bool>,
    shot_radius: f64,
    progress: &dyn Progress,
) -> RetargetResult<(VoxelDescriptors, f64)> {
    let t0 = std::time::Instant::now();
    let min_pitch = grid.pitch[0].min(grid.pitch[1]).min(grid.pitch[2]);
    let delta = 1e-6 * min_pitch;
    let voxel_of_point = |i: usize| {
        let p = sub(features.dense[i], scale(features.dense_normals[i], delta));
        grid.linear(grid.voxel_of(lattice.canonical_of_normalised(p)))
    };
    let n = grid.len();
    // (voxel, descriptor row source): reused rows first, then fallback keypoints.
    let mut entries: Vec<(usize, usize)> = Vec::new();
    let mut has_key = vec![false; n];
    for (i, &d) in features.features.iter().enumerate() {
        if !features.valid[i] {
            continue;
        }
        let v = voxel_of_point(d);
        if occupied[v] {
            entries.push((v, i));
            has_key[v] = true;
        }
    }
    let fallback: Vec<usize> = (0..features.dense.len())
        .filter(|&i| {
            let v = voxel_of_point(i);
            occupied[v] && !has_key[v]
        })
        .collect();
    let extra = if fallback.is_empty() {
        None
    } else {
        Some(compute_shot_with_tree(
            &features.tree,
            &features.dense,
            &features.dense_normals,
            &fallback,
            &ShotOptions { radius: shot_radius, frame: ShotFrame::World, ..Default::default() },
            progress,
        )?)
    };
    let mut count = vec![0u32; n + 1];
    for &(v, _) in &entries {
        count[v + 1] += 1;
    }
    if let Some(extra) = &extra {
        for (j, &k) in fallback.iter().enumerate() {
            if extra.valid[j] {
                count[voxel_of_point(k) + 1] += 1;
            }
        }
    }
    for v in 0..n {
        count[v + 1] += count[v];
    }
    let total = count[n] as usize;
    let mut rows = vec![0f32; total * SHOT_LEN];
    let mut keys = vec![u32::MAX; total];
    let table = features.descriptor_distances().cloned();
    let mut fill = count.clone();
    let mut put = |v: usize, d: &[f32], key: Option<u32>| {
        let r = fill[v] as usize;
        rows[r * SHOT_LEN..(r + 1) * SHOT_LEN].copy_from_slice(d);
        keys[r] = key.unwrap_or(u32::MAX);
        fill[v] += 1;
    };
    for &(v, i) in &entries {
        let key = table.as_ref().and_then(|t| t.compact_index(i));
        put(v, &features.descriptors[i * SHOT_LEN..(i + 1) * SHOT_LEN], key);
    }
    if let Some(extra) = &extra {
        for (j, &k) in fallback.iter().enumerate() {
            if let (true, Some(d)) = (extra.valid[j], extra.descriptor(j)) {
                put(voxel_of_point(k), d, None);
            }
        }
    }
    let out = VoxelDescriptors {
        rows,
        start: count,
        occupied,
        num_samples: features.dense.len(),
        num_keypoints: entries.len() + fallback.len(),
        num_valid: total,
        keys,
        table,
    };
    Ok((out, t0.elapsed().as_secs_f64() * 1e3))
}

/// Distance given to two non-empty voxels when one of them has no valid descriptor: √2, the
/// largest distance between two unit SHOT descriptors (whose entries are non-negative).
pub(crate) const UNKNOWN_DISTANCE: f64 = std::f64::consts::SQRT_2;

/// The Hausdorff distance d_H between two descriptor sets (rows of [`SHOT_LEN`] values), with the
/// L2 norm between descriptors (thesis 4.2.2). Empty sets give [`UNKNOWN_DISTANCE`].
///
/// All pairwise distances come from one matrix product, ‖a − b‖² = ‖a‖² + ‖b‖² − 2 a·b with the
/// a·b block computed by faer's f32 GEMM (SIMD-dispatched at run time): the pairs of large
/// voxels that the offset labels compare hold hundreds of descriptors each, and this is the
/// dominant cost of building a retargeting session.
#[cfg(test)]
pub(crate) fn hausdorff(a: &[f32], b: &[f32]) -> f64 {
    hausdorff_with_norms(a, &squared_norms(a), b, &squared_norms(b))
}

/// Squared L2 norm of every descriptor row (eight lanes, so that the sum vectorises).
pub(crate) fn squared_norms(rows: &[f32]) -> Vec<f32> {
    rows.chunks_exact(SHOT_LEN)
        .map(|r| {
            let mut acc = [0f32; 8];
            for c in r.chunks_exact(8) {
                for k in 0..8 {
                    acc[k] += c[k] * c[k];
                }
            }
            acc.iter().sum::<f32>() + r.chunks_exact(8).remainder().iter().map(|x| x * x).sum::<f32>()
        })
        .collect()
}

/// d_H between two descriptor sets (`#rows × 352`, row-major) with the rows' squared norms given
/// (`norm_a[i]` = ‖a_i‖², from [`squared_norms`]), so that a voxel compared with many others
/// computes them once.
pub(crate) fn hausdorff_with_norms(a: &[f32], norm_a: &[f32], b: &[f32], norm_b: &[f32]) -> f64 {
    let (na, nb) = (a.len() / SHOT_LEN, b.len() / SHOT_LEN);
    if na == 0 || nb == 0 {
        return UNKNOWN_DISTANCE;
    }
    let am = MatRef::from_row_major_slice(a, na, SHOT_LEN);
    let bm = MatRef::from_row_major_slice(b, nb, SHOT_LEN);
    let mut dots = Mat::<f32>::zeros(na, nb);
    matmul(dots.as_mut(), Accum::Replace, am, bm.transpose(), 1.0f32, Par::Seq);
    // Column-major storage: each column is contiguous. Minima of squared distances without the
    // constant norm terms (added afterwards), with eight lanes so that the loops vectorise.
    let mut row_min = vec![f32::INFINITY; na];
    let mut col_min = vec![f32::INFINITY; nb];
    for (j, cm) in col_min.iter_mut().enumerate() {
        let col = dots.col_as_slice(j);
        let mut lanes = [f32::INFINITY; 8];
        let (rows, rest) = row_min.split_at_mut(na - na % 8);
        let (na8, nrest) = norm_a.split_at(na - na % 8);
        let (c8, crest) = col.split_at(na - na % 8);
        for ((rm, n), c) in rows.chunks_exact_mut(8).zip(na8.chunks_exact(8)).zip(c8.chunks_exact(8)) {
            for k in 0..8 {
                let d = n[k] - 2.0 * c[k];
                rm[k] = rm[k].min(d + norm_b[j]);
                lanes[k] = lanes[k].min(d);
            }
        }
        for ((rm, n), c) in rest.iter_mut().zip(nrest).zip(crest) {
            let d = n - 2.0 * c;
            *rm = rm.min(d + norm_b[j]);
            lanes[0] = lanes[0].min(d);
        }
        *cm = lanes.iter().fold(f32::INFINITY, |m, &x| m.min(x)) + norm_b[j];
    }
    let m = row_min.iter().chain(&col_min).fold(0f32, |m, &x| m.max(x.max(0.0)));
    (m as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hausdorff_of_identical_sets_is_zero_and_symmetric() {
        let mut a = vec![0f32; 2 * SHOT_LEN];
        a[0] = 1.0;
        a[SHOT_LEN + 1] = 1.0;
        let mut b = vec![0f32; SHOT_LEN];
        b[0] = 1.0;
        assert!(hausdorff(&a, &a) < 1e-6);
        let d = hausdorff(&a, &b);
        assert!((d - std::f64::consts::SQRT_2).abs() < 1e-6, "{d}");
        assert_eq!(hausdorff(&a, &b), hausdorff(&b, &a));
        assert_eq!(hausdorff(&a, &[]), UNKNOWN_DISTANCE);
    }

    /// The GEMM form agrees with the definition (max over both sets of the nearest L2 distance)
    /// on random sets whose sizes are not multiples of the vector width.
    #[test]
    fn hausdorff_matches_the_naive_definition() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for (na, nb) in [(1, 1), (7, 13), (33, 9), (64, 65)] {
            let a: Vec<f32> = (0..na * SHOT_LEN).map(|_| rng.random::<f32>()).collect();
            let b: Vec<f32> = (0..nb * SHOT_LEN).map(|_| rng.random::<f32>()).collect();
            let dist = |x: &[f32], y: &[f32]| {
                x.iter().zip(y).map(|(p, q)| ((p - q) as f64).powi(2)).sum::<f64>().sqrt()
            };
            let directed = |x: &[f32], y: &[f32]| {
                x.chunks_exact(SHOT_LEN)
                    .map(|r| y.chunks_exact(SHOT_LEN).map(|c| dist(r, c)).fold(f64::INFINITY, f64::min))
                    .fold(0.0, f64::max)
            };
            let want = directed(&a, &b).max(directed(&b, &a));
            let got = hausdorff(&a, &b);
            assert!((got - want).abs() < 1e-3 * want.max(1.0), "{na}x{nb}: {got} vs {want}");
        }
    }

    /// The lookup gives exactly the d_H of a scan of every entry, on random tables with few
    /// distinct values (many ties) and with many, for sets of 1 to 120 keys that share keys or
    /// not, read whole and with the early break (both are checked to occur).
    #[test]
    fn hausdorff_lookup_equals_the_exhaustive_scan() {
        use rand::{Rng, SeedableRng, seq::index::sample};
        use rand_chacha::ChaCha8Rng;
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let n = 200;
        let mut early = 0;
        for round in 0..400 {
            let spread: u16 = if round % 2 == 0 { 6 } else { u16::MAX };
            let packed = (0..n * (n - 1) / 2).map(|_| rng.random_range(0..=spread)).collect();
            let table = DescriptorDistances::from_packed(n, packed);
            let pick = |rng: &mut ChaCha8Rng| {
                let k = rng.random_range(1..=120);
                let mut keys: Vec<u32> = sample(rng, n, k).into_iter().map(|i| i as u32).collect();
                keys.sort_unstable();
                keys
            };
            let (a, b) = (pick(&mut rng), pick(&mut rng));
            let directed = |a: &[u32], b: &[u32]| {
                a.iter().map(|&i| b.iter().map(|&j| table.quantised(i, j)).min().unwrap()).max().unwrap()
            };
            let want = DescriptorDistances::dequantise(directed(&a, &b).max(directed(&b, &a)));
            assert_eq!(hausdorff_lookup(&table, &a, &b), want, "round {round}: {a:?} vs {b:?}");
            early += usize::from(a.len() * b.len() >= EXHAUSTIVE_BELOW);
        }
        assert!((50..350).contains(&early), "{early} of 400 rounds took the early break");
    }

    /// Thesis 4.2.2's reuse of the matching step's distances: on the generated facade, every d_H
    /// that the table gives equals the one computed from the descriptors (GEMM), within the
    /// table's 16-bit quantisation; without the table the computed distance is used.
    #[test]
    fn distances_from_the_matching_table_equal_computed_ones() {
        use crate::offsets::{OffsetOptions, analyze_features, prepare_features};
        use motif_core::progress::NoProgress;
        let ex = motif_core::procedural::generate("facade", 0).expect("facade");
        let options = OffsetOptions::default();
        let features = prepare_features(&ex.mesh, &options, &NoProgress).expect("features");
        assert!(features.descriptor_distances().is_none(), "no table before matching");
        analyze_features(&features, &options, &NoProgress).expect("analysis");
        let table = features.descriptor_distances().expect("the matching step kept its distances");
        assert_eq!(table.len(), features.valid.iter().filter(|&&v| v).count());
        let normalisation = super::super::canonical::normalisation_of(&ex.mesh).expect("bounds");
        let lattice = Lattice::from_offsets(normalisation, &ex.structure.cell_pitch, 0.2).expect("lattice");
        let grid = VoxelGrid::covering(&lattice, &ex.mesh.positions);
        let tri_voxel = assign_triangles(&ex.mesh, &lattice, &grid);
        let mut occupied = vec![false; grid.len()];
        for &v in &tri_voxel {
            occupied[v as usize] = true;
        }
        let (d, _) = describe_from_features(&features, &lattice, &grid, occupied, 0.2, &NoProgress)
            .expect("descriptors");
        let norms = squared_norms(&d.rows);
        let norms_of = |v: usize| &norms[d.start[v] as usize..d.start[v + 1] as usize];
        let keyed: Vec<usize> = (0..grid.len()).filter(|&v| d.keys_of(v).is_some()).collect();
        assert!(keyed.len() >= 10, "{} voxels with table keys", keyed.len());
        let mut compared = 0;
        for (k, &s) in keyed.iter().enumerate() {
            for &t in &keyed[k + 1..] {
                let looked_up = d.hausdorff(s, t, &norms);
                let computed = hausdorff_with_norms(d.of(s), norms_of(s), d.of(t), norms_of(t));
                assert!((looked_up - computed).abs() < 1e-4, "voxels {s}, {t}: {looked_up} vs {computed}");
                compared += 1;
            }
        }
        assert!(compared >= 45);
        // A set without keys falls back to the computed distance.
        let mut no_table = d.clone();
        no_table.table = None;
        let (s, t) = (keyed[0], keyed[1]);
        assert_eq!(
            no_table.hausdorff(s, t, &norms),
            hausdorff_with_norms(d.of(s), norms_of(s), d.of(t), norms_of(t))
        );
    }

    #[test]
    fn grid_indexing_round_trips() {
        let g = VoxelGrid { origin: [0.0; 3], pitch: [0.5, 0.25, 1.0], dims: [3, 4, 2] };
        for i in 0..g.len() {
            assert_eq!(g.linear(g.coords(i)), i);
        }
        assert_eq!(g.voxel_of([1.2, 0.3, 5.0]), [2, 1, 1]);
        assert_eq!(g.voxel_of([-1.0, 0.0, 0.0]), [0, 0, 0]);
        assert_eq!(g.linear_checked([3, 0, 0]), None);
        assert_eq!(g.linear_checked([2, 3, 1]), Some(g.len() - 1));
    }
}
