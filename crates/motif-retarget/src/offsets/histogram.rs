//! The sparse 3-D offset histogram and its peaks (thesis 4.2.1, 4.4).
//!
//! Bins are cubes of side `h` (0.05) *centred* on the lattice `h · (i, j, k)`: an offset `v` falls
//! in bin `round(v / h)`. Centring makes the binning antisymmetric (`bin(−v) = −bin(v)`), which the
//! sign convention needs:
//!
//! - [`SignConvention::Canonical`] (offset analysis): `v` and `−v` describe the same translational
//!   repetition, so every offset is flipped into the canonical half-space of bin indices
//!   (`i > 0`, or `i = 0, j > 0`, or `i = j = 0, k ≥ 0`) — the whole vector is negated when its bin
//!   is not canonical, so a peak is never split by the flip. Peaks then count the matches of both
//!   directions, and the neighbourhood of a bin on the boundary of the half-space is read through
//!   the mirror (`count(b) = count(−b)` for non-canonical `b`), so non-maximum suppression and
//!   window sums see the full, point-symmetric histogram.
//! - [`SignConvention::Raw`] (sparsity study, as the thesis bins "the offsets between matched
//!   features"): offsets are binned as they are.
//!
//! Peaks: a non-empty bin is a peak when its *support* — the number of offsets in the 3 × 3 × 3
//! bins around it — is the largest among the non-empty bins within the suppression radius (0.15,
//! thesis 4.4; ties go to the smaller index). The thesis runs non-maximum suppression on the raw
//! bin magnitudes; summing the 27-bin window first keeps a peak whose offsets straddle a bin
//! boundary (feature positions are only accurate to the feature spacing, comparable to a bin)
//! from losing against a sharper but weaker one. Each peak also carries the mean of the offsets in
//! its window: a sub-bin estimate that starts the ICP refinement.

use std::collections::HashMap;

use motif_core::Point3;
use serde::{Deserialize, Serialize};

/// How offsets `v` and `−v` are binned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SignConvention {
    /// `v` and `−v` share one bin in the canonical half-space (see the module docs). Default.
    #[default]
    Canonical,
    /// Offsets are binned as matched (thesis 4.3's sparsity study).
    Raw,
}

#[derive(Debug, Clone, Copy, Default)]
struct Acc {
    count: u32,
    sum: Point3,
}

/// A sparse 3-D histogram of offsets with cubic bins centred on `bin_size · (i, j, k)`.
#[derive(Debug, Clone)]
pub struct OffsetHistogram {
    bin_size: f64,
    sign: SignConvention,
    bins: HashMap<[i32; 3], Acc>,
    total: usize,
}

/// One non-empty bin, for reports and pictures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HistogramBin {
    /// Bin index `(i, j, k)`; the bin's centre is `bin_size · (i, j, k)`.
    pub index: [i32; 3],
    /// Number of offsets in the bin.
    pub count: u32,
}

/// A histogram peak (a dominant offset before refinement).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HistogramPeak {
    /// Bin index of the peak.
    pub index: [i32; 3],
    /// Offsets in the peak's bin.
    pub bin_count: u32,
    /// Offsets in the 3 × 3 × 3 bins around the peak: the peak's support.
    pub support: u32,
    /// Mean of the offsets in those bins, normalised units.
    pub mean_offset: Point3,
}

/// True when bin `b` lies in the canonical half-space.
pub fn is_canonical(b: [i32; 3]) -> bool {
    b[0] > 0 || (b[0] == 0 && (b[1] > 0 || (b[1] == 0 && b[2] >= 0)))
}

/// `v` or `−v`, whichever is in the canonical half-space of vectors (first non-zero coordinate
/// positive, with components below `eps` in magnitude treated as zero).
pub fn canonical_vector(v: Point3, eps: f64) -> Point3 {
    for c in v {
        if c > eps {
            return v;
        }
        if c < -eps {
            return v.map(|x| -x);
        }
    }
    v
}

impl OffsetHistogram {
    /// An empty histogram. `bin_size` must be positive (checked by the callers' options).
    pub fn new(bin_size: f64, sign: SignConvention) -> Self {
        OffsetHistogram { bin_size, sign, bins: HashMap::new(), total: 0 }
    }

    /// A histogram of `offsets`.
    pub fn from_offsets(
        offsets: impl IntoIterator<Item = Point3>,
        bin_size: f64,
        sign: SignConvention,
    ) -> Self {
        let mut h = Self::new(bin_size, sign);
        for v in offsets {
            h.add(v);
        }
        h
    }

    /// The bin side length.
    pub fn bin_size(&self) -> f64 {
        self.bin_size
    }

    /// The sign convention.
    pub fn sign(&self) -> SignConvention {
        self.sign
    }

    /// Number of offsets added.
    pub fn total(&self) -> usize {
        self.total
    }

    /// Number of non-empty (stored) bins.
    pub fn num_bins(&self) -> usize {
        self.bins.len()
    }

    /// The bin index of `v` before any sign flip.
    pub fn raw_index(&self, v: Point3) -> [i32; 3] {
        v.map(|c| (c / self.bin_size).round() as i32)
    }

    /// Adds one offset. Non-finite offsets are ignored.
    pub fn add(&mut self, v: Point3) {
        if !v.iter().all(|c| c.is_finite()) {
            return;
        }
        let mut b = self.raw_index(v);
        let mut v = v;
        if self.sign == SignConvention::Canonical && !is_canonical(b) {
            b = b.map(|i| -i);
            v = v.map(|c| -c);
        }
        let acc = self.bins.entry(b).or_default();
        acc.count += 1;
        for i in 0..3 {
            acc.sum[i] += v[i];
        }
        self.total += 1;
    }

    /// Count and offset sum of bin `b`, reading non-canonical bins through the mirror.
    fn lookup(&self, b: [i32; 3]) -> Acc {
        if self.sign == SignConvention::Canonical && !is_canonical(b) {
            let m = b.map(|i| -i);
            return self
                .bins
                .get(&m)
                .map_or_else(Acc::default, |a| Acc { count: a.count, sum: a.sum.map(|c| -c) });
        }
        self.bins.get(&b).copied().unwrap_or_default()
    }

    /// Number of offsets in bin `b` (any index; mirrored for [`SignConvention::Canonical`]).
    pub fn count(&self, b: [i32; 3]) -> u32 {
        self.lookup(b).count
    }

    /// Count and mean offset of the bins within Chebyshev distance `r` (in bins) of `b`.
    pub fn window(&self, b: [i32; 3], r: i32) -> (u32, Point3) {
        let mut count = 0;
        let mut sum = [0.0; 3];
        for di in -r..=r {
            for dj in -r..=r {
                for dk in -r..=r {
                    let a = self.lookup([b[0] + di, b[1] + dj, b[2] + dk]);
                    count += a.count;
                    for i in 0..3 {
                        sum[i] += a.sum[i];
                    }
                }
            }
        }
        let mean = if count > 0 { sum.map(|s| s / count as f64) } else { [0.0; 3] };
        (count, mean)
    }

    /// Number of non-empty bins within Chebyshev distance `r` (in bins) of `b`.
    pub fn window_occupied(&self, b: [i32; 3], r: i32) -> usize {
        let mut n = 0;
        for di in -r..=r {
            for dj in -r..=r {
                for dk in -r..=r {
                    n += usize::from(self.lookup([b[0] + di, b[1] + dj, b[2] + dk]).count > 0);
                }
            }
        }
        n
    }

    /// The non-empty bins, largest count first (ties by index).
    pub fn bins(&self) -> Vec<HistogramBin> {
        let mut v: Vec<HistogramBin> =
            self.bins.iter().map(|(&index, a)| HistogramBin { index, count: a.count }).collect();
        v.sort_by(|a, b| b.count.cmp(&a.count).then(a.index.cmp(&b.index)));
        v
    }

    /// The counts of the non-empty bins in descending order (the sparsity study's sorted bins).
    pub fn sorted_counts(&self) -> Vec<u32> {
        let mut c: Vec<u32> = self.bins.values().map(|a| a.count).collect();
        c.sort_unstable_by(|a, b| b.cmp(a));
        c
    }

    /// Peaks by non-maximum suppression of the 27-bin window sums within `radius` (normalised
    /// units; thesis 4.4: 0.15), keeping peaks with at least `min_support` offsets, strongest
    /// first (ties by index).
    pub fn peaks(&self, radius: f64, min_support: u32) -> Vec<HistogramPeak> {
        // 0.15 / 0.05 is 2.9999999999999996 in floating point: a little slack keeps it 3 bins.
        let r = (radius / self.bin_size + 1e-9).max(0.0);
        let ri = r.floor() as i32;
        let mut ball = Vec::new();
        for di in -ri..=ri {
            for dj in -ri..=ri {
                for dk in -ri..=ri {
                    let d2 = (di * di + dj * dj + dk * dk) as f64;
                    if d2 > 0.0 && d2 <= r * r {
                        ball.push([di, dj, dk]);
                    }
                }
            }
        }
        let score: HashMap<[i32; 3], (u32, Point3)> =
            self.bins.keys().map(|&b| (b, self.window(b, 1))).collect();
        let canon = |b: [i32; 3]| {
            if self.sign == SignConvention::Canonical && !is_canonical(b) { b.map(|i| -i) } else { b }
        };
        let mut peaks: Vec<HistogramPeak> = score
            .iter()
            .filter(|&(b, &(s, _))| {
                s >= min_support.max(1)
                    && ball.iter().all(|d| {
                        let n = canon([b[0] + d[0], b[1] + d[1], b[2] + d[2]]);
                        if n == *b {
                            return true;
                        }
                        match score.get(&n) {
                            Some(&(sn, _)) => sn < s || (sn == s && *b < n),
                            None => true,
                        }
                    })
            })
            .map(|(&b, &(support, mean))| HistogramPeak {
                index: b,
                bin_count: self.bins.get(&b).map_or(0, |a| a.count),
                support,
                mean_offset: mean,
            })
            .collect();
        peaks.sort_by(|a, b| b.support.cmp(&a.support).then(a.index.cmp(&b.index)));
        peaks
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn canonical_folds_v_and_minus_v() {
        let mut h = OffsetHistogram::new(0.05, SignConvention::Canonical);
        h.add([0.5, 0.0, 0.0]);
        h.add([-0.5, 0.0, 0.0]);
        h.add([0.001, 0.3, 0.0]);
        h.add([-0.001, -0.3, 0.0]);
        assert_eq!(h.num_bins(), 2);
        assert_eq!(h.count([10, 0, 0]), 2);
        assert_eq!(h.count([-10, 0, 0]), 2);
        assert_eq!(h.count([0, 6, 0]), 2);
        let raw =
            OffsetHistogram::from_offsets([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]], 0.05, SignConvention::Raw);
        assert_eq!(raw.num_bins(), 2);
    }

    #[test]
    fn window_occupied_counts_the_non_empty_bins_around_a_bin() {
        // Offsets on a line along x, one bin in two filled: a window of 3 × 3 × 3 bins around a
        // filled bin holds it alone; around an empty one, its two filled neighbours.
        let line: Vec<Point3> = (0..10).map(|i| [0.1 + 0.1 * i as f64, 0.0, 0.0]).collect();
        let h = OffsetHistogram::from_offsets(line, 0.05, SignConvention::Raw);
        assert_eq!(h.num_bins(), 10);
        assert_eq!(h.window_occupied([6, 0, 0], 1), 1);
        assert_eq!(h.window_occupied([7, 0, 0], 1), 2);
        assert_eq!(h.window_occupied([6, 0, 0], 2), 3);
        assert_eq!(h.window_occupied([6, 1, -1], 1), 1);
        assert_eq!(h.window_occupied([100, 0, 0], 1), 0);
    }

    #[test]
    fn peaks_suppress_neighbours_and_straddling_peaks_win() {
        let mut h = OffsetHistogram::new(0.05, SignConvention::Canonical);
        // A peak split over two bins (10 + 10) against a sharper but weaker one (15).
        for _ in 0..10 {
            h.add([0.524, 0.0, 0.0]);
            h.add([0.526, 0.0, 0.0]);
        }
        for _ in 0..15 {
            h.add([0.0, 0.5, 0.0]);
        }
        // A bump three bins from the first peak is suppressed.
        for _ in 0..5 {
            h.add([0.7, 0.0, 0.0]);
        }
        let p = h.peaks(0.15, 3);
        assert_eq!(p.len(), 2, "{p:?}");
        assert_eq!(p[0].support, 20);
        assert_eq!(p[0].index, [10, 0, 0], "a tie goes to the smaller index");
        assert!((p[0].mean_offset[0] - 0.525).abs() < 1e-9);
        assert_eq!(p[1].index, [0, 10, 0]);
    }

    #[test]
    fn mirrored_neighbours_are_seen_across_the_half_space_boundary() {
        let mut h = OffsetHistogram::new(0.05, SignConvention::Canonical);
        // Offsets near the plane x = 0: bin (−1, 10, 0) is stored as its mirror (1, −10, 0) but is
        // still a neighbour of bin (0, 10, 0).
        for _ in 0..12 {
            h.add([0.0, 0.5, 0.0]);
        }
        for _ in 0..8 {
            h.add([-0.05, 0.5, 0.0]);
        }
        assert_eq!(h.num_bins(), 2);
        let p = h.peaks(0.15, 3);
        assert_eq!(p.len(), 1, "{p:?}");
        assert_eq!(p[0].index, [0, 10, 0]);
        assert_eq!(p[0].support, 20);
        assert!((p[0].mean_offset[0] + 0.02).abs() < 1e-9, "{:?}", p[0].mean_offset);
    }
}
