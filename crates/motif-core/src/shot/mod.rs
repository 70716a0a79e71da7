//! The SHOT descriptor (Signature of Histograms of OrienTations; Tombari, Salti, Di Stefano,
//! "Unique Signatures of Histograms for Local Surface Description", ECCV 2010), computed so that it
//! agrees with PCL's `pcl::SHOTEstimation<PointNormal, PointNormal, SHOT352>`.
//!
//! For each keypoint `p` with support radius `R`:
//! 1. **Frame** ([`ShotFrame::Lrf`]): the eigenvectors of the covariance of the neighbours'
//!    offsets `q − p`, each weighted by `R − |q − p|`; `x` is the eigenvector of the largest
//!    eigenvalue, `z` of the smallest, each signed to point towards the majority of the neighbours,
//!    `y = z × x` (right-handed). [`ShotFrame::World`] uses the world axes instead (thesis §4.4:
//!    matching under translations only, where rotation invariance is unwanted).
//! 2. **Grid**: the ball of radius `R` around `p`, seen in that frame, is split into 32 volumes:
//!    8 azimuth sectors × 2 elevations (above/below the `xy` plane) × 2 shells (inside/outside
//!    `R/2`).
//! 3. **Histograms**: in each volume an 11-bin histogram of `cos θ = n_q · z`, the cosine between
//!    the neighbour's normal `n_q` and the frame's `z` axis, over the bin values
//!    `(1 + cos θ) · 10 / 2 ∈ [0, 10]`. Each neighbour votes with interpolation between adjacent
//!    cosine bins, shells, elevations and azimuth sectors (the azimuth wraps around).
//! 4. The 32 × 11 = 352 values (volume-major: value `11 · volume + bin`, volume
//!    `4 · sector + 2 · shell + elevation`) are scaled to unit Euclidean length.
//!
//! Conventions shared with PCL (all observed on PCL 1.13, see `tools/pcl-shot/`):
//! - the interpolation is PCL's *additive* form of the paper's quadrilinear interpolation: the
//!   neighbour's own bin receives the sum of the four one-dimensional weights `Σ (1 − |dᵢ|)` and
//!   each neighbouring bin along one dimension receives `|dᵢ|`, rather than the tensor product;
//! - the shell interpolation is linear between the shell mid-radii `R/4` and `3R/4`, elevation
//!   between inclinations 45° and 135°, azimuth between sector centres; outside those the weight
//!   keeps decreasing linearly (to ½ at the centre and at `R`);
//! - neighbours that coincide with the keypoint are ignored; neighbours whose normal has a NaN or
//!   infinite component are ignored by the histogram (but still shape the frame);
//! - a keypoint with fewer than [`ShotOptions::min_neighbours`] other points within `R`, a
//!   degenerate covariance or an all-zero histogram has no descriptor: PCL writes NaN, Motif marks
//!   it invalid ([`ShotDescriptors::valid`]) and leaves zeros;
//! - the cosine interpolation's neighbour bin is taken modulo 10 as in PCL (see
//!   [`CosineInterpolation`]).
//!
//! Geometry is f64; histograms are f32 like PCL's. Keypoints are processed in parallel (rayon);
//! the result does not depend on the number of threads.

mod lrf;
mod peershot;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::{Point3, dot, sub};
use crate::progress::{NoProgress, Progress};
use crate::spatial::KdTree;
use crate::{Error, Result};

pub use peershot::{read_peershot, read_peershot_file, write_peershot, write_shot_csv};

/// Number of values in one SHOT descriptor: 32 volumes × 11 cosine bins.
pub const SHOT_LEN: usize = 352;

/// Cosine bins per volume (PCL's `nr_shape_bins_ + 1`).
const COS_BINS: usize = 11;
/// Bin value of `cos θ = 1`: bin values are `(1 + cos θ) · COS_STEPS / 2` (PCL's `nr_shape_bins_`).
const COS_STEPS: usize = 10;
/// Spatial volumes: 8 azimuth sectors × 2 shells × 2 elevations.
const VOLUMES: usize = 32;

/// Which reference frame the descriptor is expressed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShotFrame {
    /// The local reference frame of Tombari et al. 2010 (§4): rotation invariant; PCL's
    /// `SHOTLocalReferenceFrameEstimation`.
    #[default]
    Lrf,
    /// The world axes `x, y, z`: descriptors change under rotation but not under translation, as
    /// the thesis needs for translation-only offset statistics (thesis §4.4).
    World,
}

/// How a vote is shared between adjacent cosine bins.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CosineInterpolation {
    /// As PCL: the neighbouring bin is `(bin ± 1) mod 10`, so a neighbour with `cos θ ∈ (0.8, 0.9)`
    /// puts its upper share into bin 0 instead of bin 10 (and bin 10 only ever receives votes
    /// with `cos θ ≥ 0.8`). Needed to agree with descriptors computed by PCL.
    #[default]
    Pcl,
    /// Linear interpolation between the two nearest of the 11 bins, as the paper describes.
    /// Descriptors are not comparable with PCL's.
    Linear,
}

/// Options of [`compute_shot`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ShotOptions {
    /// `R`, the support radius: points within this Euclidean distance of a keypoint (inclusive)
    /// describe it and define its frame. Same unit as the points. Default 0.2, the thesis's value
    /// for models scaled so their largest dimension spans [−1, 1] (thesis §4.3); for meshes a
    /// radius of 10–20 mean edge lengths is typical. Must be positive and finite.
    pub radius: f64,
    /// The frame the descriptor is expressed in. Default [`ShotFrame::Lrf`] (Tombari 2010, PCL);
    /// the thesis's offset statistics use [`ShotFrame::World`] (thesis §4.4).
    pub frame: ShotFrame,
    /// Minimum number of points within the radius, not counting points that coincide with the
    /// keypoint, for a keypoint to get a descriptor. Default 5 (PCL's threshold for its local
    /// reference frame); fewer leave the keypoint invalid. Values below 5 are allowed; the frame
    /// needs at least 3 non-collinear neighbours to be meaningful.
    pub min_neighbours: usize,
    /// How votes are shared between adjacent cosine bins. Default [`CosineInterpolation::Pcl`],
    /// which agrees with PCL's descriptors.
    pub cosine_interpolation: CosineInterpolation,
}

impl Default for ShotOptions {
    fn default() -> Self {
        ShotOptions {
            radius: 0.2,
            frame: ShotFrame::Lrf,
            min_neighbours: 5,
            cosine_interpolation: CosineInterpolation::Pcl,
        }
    }
}

impl ShotOptions {
    /// Checks that every option is in its valid range.
    pub fn validate(&self) -> Result<()> {
        if !(self.radius > 0.0 && self.radius.is_finite()) {
            return Err(Error::InvalidOption {
                name: "radius",
                message: format!("the SHOT support radius must be positive and finite, got {}", self.radius),
            });
        }
        Ok(())
    }
}

/// SHOT descriptors of a set of keypoints, in the order the keypoints were given.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ShotDescriptors {
    /// The keypoints' indices into the point set, `#K`.
    pub keypoints: Vec<usize>,
    /// The descriptors, `#K × 352` row-major (see [`SHOT_LEN`] and the module docs for the
    /// layout); each valid row has unit Euclidean length, each invalid row is zero.
    pub descriptors: Vec<f32>,
    /// Each keypoint's frame as its `x`, `y`, `z` axes (unit, right-handed), `#K`; the world axes
    /// with [`ShotFrame::World`], zero for invalid keypoints.
    pub frames: Vec<[[f32; 3]; 3]>,
    /// Whether each keypoint has a descriptor, `#K`. A keypoint is invalid when it has fewer than
    /// [`ShotOptions::min_neighbours`] neighbours, its covariance is degenerate (non-finite), or
    /// none of its neighbours has a finite normal.
    pub valid: Vec<bool>,
}

impl ShotDescriptors {
    /// Number of keypoints.
    pub fn len(&self) -> usize {
        self.keypoints.len()
    }

    /// True when there are no keypoints.
    pub fn is_empty(&self) -> bool {
        self.keypoints.is_empty()
    }

    /// The descriptor of the `i`-th keypoint (352 values), `None` past the end.
    pub fn descriptor(&self, i: usize) -> Option<&[f32]> {
        self.descriptors.get(i * SHOT_LEN..(i + 1) * SHOT_LEN)
    }

    /// Number of valid keypoints.
    pub fn num_valid(&self) -> usize {
        self.valid.iter().filter(|&&v| v).count()
    }
}

/// Computes SHOT descriptors of `keypoints` (indices into `points`), using all of `points` with
/// their `normals` as the support. Builds a kd-tree over `points`; use
/// [`compute_shot_with_tree`] to reuse one.
///
/// `points` and `normals` are `#P × 3` (normals unit length; non-finite normals are ignored),
/// `keypoints` is `#K`. Fails when the lengths differ, a keypoint is out of range, a point is not
/// finite, or an option is invalid.
///
/// ```
/// use motif_core::shot::{SHOT_LEN, ShotFrame, ShotOptions, compute_shot};
///
/// // A 21 × 21 grid on the plane z = 0, normals +z; describe its centre in the world frame.
/// let points: Vec<[f64; 3]> =
///     (0..441).map(|i| [(i % 21) as f64 * 0.05, (i / 21) as f64 * 0.05, 0.0]).collect();
/// let normals = vec![[0.0, 0.0, 1.0]; points.len()];
/// let options = ShotOptions { radius: 0.3, frame: ShotFrame::World, ..Default::default() };
/// let shots = compute_shot(&points, &normals, &[220], &options)?;
/// assert!(shots.valid[0]);
/// assert_eq!(shots.descriptor(0).map(<[f32]>::len), Some(SHOT_LEN));
/// # Ok::<(), motif_core::Error>(())
/// ```
pub fn compute_shot(
    points: &[Point3],
    normals: &[Point3],
    keypoints: &[usize],
    options: &ShotOptions,
) -> Result<ShotDescriptors> {
    options.validate()?;
    check_input(points, normals, keypoints)?;
    let tree = KdTree::new(points)?;
    compute_shot_with_tree(&tree, points, normals, keypoints, options, &NoProgress)
}

/// [`compute_shot`] with a kd-tree already built over `points`, reporting one progress unit per
/// keypoint.
pub fn compute_shot_with_tree(
    tree: &KdTree,
    points: &[Point3],
    normals: &[Point3],
    keypoints: &[usize],
    options: &ShotOptions,
    progress: &dyn Progress,
) -> Result<ShotDescriptors> {
    options.validate()?;
    check_input(points, normals, keypoints)?;
    if tree.len() != points.len() {
        return Err(Error::InvalidInput(format!(
            "the kd-tree holds {} points but {} points were given; build it over the same points",
            tree.len(),
            points.len()
        )));
    }
    let k = keypoints.len();
    let mut out = ShotDescriptors {
        keypoints: keypoints.to_vec(),
        descriptors: vec![0.0; k * SHOT_LEN],
        frames: vec![[[0.0; 3]; 3]; k],
        valid: vec![false; k],
    };
    progress.start("SHOT descriptors", k as u64);
    let support = Support { points, normals, tree, options };
    out.descriptors
        .par_chunks_mut(SHOT_LEN)
        .zip(out.frames.par_iter_mut())
        .zip(out.valid.par_iter_mut())
        .zip(keypoints.par_iter())
        .for_each_init(Vec::new, |scratch, (((desc, frame), valid), &key)| {
            let desc: &mut [f32; SHOT_LEN] = desc.try_into().expect("chunks are SHOT_LEN long");
            if let Some(f) = support.describe(key, scratch, desc) {
                *frame = f.map(|axis| axis.map(|c| c as f32));
                *valid = true;
            } else {
                desc.fill(0.0);
            }
            progress.inc(1);
        });
    progress.finish();
    Ok(out)
}

fn check_input(points: &[Point3], normals: &[Point3], keypoints: &[usize]) -> Result<()> {
    if normals.len() != points.len() {
        return Err(Error::InvalidInput(format!(
            "SHOT needs one normal per point: {} points but {} normals",
            points.len(),
            normals.len()
        )));
    }
    if let Some((i, &k)) = keypoints.iter().enumerate().find(|&(_, &k)| k >= points.len()) {
        return Err(Error::InvalidInput(format!(
            "keypoint {i} is point {k}, but there are only {} points",
            points.len()
        )));
    }
    Ok(())
}

/// A neighbour of the keypoint, in world coordinates relative to the keypoint.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Offset {
    /// Index of the neighbour in the point set.
    pub index: usize,
    /// `q − p`.
    pub delta: Point3,
    /// `|q − p|`, positive.
    pub distance: f64,
}

/// Everything shared by all keypoints of one computation.
struct Support<'a> {
    points: &'a [Point3],
    normals: &'a [Point3],
    tree: &'a KdTree,
    options: &'a ShotOptions,
}

impl Support<'_> {
    /// Fills `desc` for keypoint `key` and returns its frame, or `None` when it is invalid.
    /// `scratch` is per-thread storage for the neighbour offsets (reused across keypoints).
    fn describe(
        &self,
        key: usize,
        scratch: &mut Vec<Offset>,
        desc: &mut [f32; SHOT_LEN],
    ) -> Option<[Point3; 3]> {
        let p = self.points[key];
        let radius = self.options.radius;
        scratch.clear();
        for n in self.tree.within_unsorted(p, radius) {
            // PCL skips neighbours that coincide with the keypoint (the keypoint itself included).
            if n.distance > 0.0 {
                scratch.push(Offset {
                    index: n.index,
                    delta: sub(self.points[n.index], p),
                    distance: n.distance,
                });
            }
        }
        if scratch.len() < self.options.min_neighbours || scratch.is_empty() {
            return None;
        }
        let frame = match self.options.frame {
            ShotFrame::Lrf => lrf::shot_lrf(scratch, radius)?,
            ShotFrame::World => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        };
        desc.fill(0.0);
        let grid = Grid::new(radius, self.options.cosine_interpolation);
        let mut voted = false;
        for o in scratch.iter() {
            let n = self.normals[o.index];
            if !crate::geometry::is_finite(n) {
                continue;
            }
            let cos = dot(n, frame[2]).clamp(-1.0, 1.0);
            let local = [dot(o.delta, frame[0]), dot(o.delta, frame[1]), dot(o.delta, frame[2])];
            grid.vote(desc, local, o.distance, cos);
            voted = true;
        }
        if !voted || !normalize_histogram(desc) {
            return None;
        }
        Some(frame)
    }
}

/// Scales `h` to unit Euclidean length (the norm accumulated in f64 as PCL does). Returns false
/// when the histogram is zero or not finite.
fn normalize_histogram(h: &mut [f32; SHOT_LEN]) -> bool {
    let norm = h.iter().map(|&v| f64::from(v) * f64::from(v)).sum::<f64>().sqrt();
    if !(norm > 0.0 && norm.is_finite()) {
        return false;
    }
    let norm = norm as f32;
    h.iter_mut().for_each(|v| *v /= norm);
    true
}

/// The spatial grid and the interpolation of one vote.
#[derive(Debug, Clone, Copy)]
struct Grid {
    r_quarter: f64,
    r_half: f64,
    r_three_quarters: f64,
    cosine: CosineInterpolation,
}

const FRAC_PI_2: f64 = std::f64::consts::FRAC_PI_2;
const FRAC_PI_4: f64 = std::f64::consts::FRAC_PI_4;
const PI: f64 = std::f64::consts::PI;
/// Centre of azimuth sector 0: sector `s` spans `[−π + s π/4, −π + (s + 1) π/4]`.
const SECTOR0_CENTRE: f64 = -7.0 * PI / 8.0;

impl Grid {
    fn new(radius: f64, cosine: CosineInterpolation) -> Self {
        Grid { r_quarter: radius / 4.0, r_half: radius / 2.0, r_three_quarters: radius * 3.0 / 4.0, cosine }
    }

    /// Adds one neighbour's vote: `local` is its offset in the keypoint's frame, `distance` its
    /// length (positive), `cos` the cosine between its normal and the frame's `z` axis.
    #[inline]
    fn vote(&self, h: &mut [f32; SHOT_LEN], local: Point3, distance: f64, cos: f64) {
        // Tiny coordinates snap to zero so that points on the axes fall on a definite side.
        let snap = |v: f64| if v.abs() < 1e-30 { 0.0 } else { v };
        let [x, y, z] = local.map(snap);

        // Azimuth sector: atan2 in [−π, π], 8 sectors of π/4 starting at −π. A point on the z axis
        // has no azimuth: it goes to sector 0 without azimuth interpolation (as PCL).
        let azimuth = (x != 0.0 || y != 0.0).then(|| y.atan2(x));
        let sector = match azimuth {
            Some(a) => (((a + PI) / FRAC_PI_4).floor() as isize).clamp(0, 7) as usize,
            None => 0,
        };
        let shell = usize::from(distance > self.r_half);
        let upper = z > 0.0;
        let volume = 4 * sector + 2 * shell + usize::from(upper);
        let at = |volume: usize, bin: usize| volume * COS_BINS + bin;

        // Cosine: bin values (1 + cos) · 10 / 2 in [0, 10], nearest bin plus its neighbour.
        let value = (1.0 + cos) * COS_STEPS as f64 / 2.0;
        let bin = ((value + 0.5).floor() as usize).min(COS_STEPS);
        let d = value - bin as f64;
        let mut own = 1.0 - d.abs();
        if d > 0.0 {
            let next = match self.cosine {
                CosineInterpolation::Pcl => (bin + 1) % COS_STEPS,
                CosineInterpolation::Linear => bin + 1,
            };
            h[at(volume, next)] += d as f32;
        } else if d < 0.0 {
            // bin ≥ 1 here: d < 0 needs value < bin.
            h[at(volume, bin - 1)] += (-d) as f32;
        }

        // Shells: linear between the shell mid-radii R/4 and 3R/4.
        if shell == 1 {
            let d = (distance - self.r_three_quarters) / self.r_half;
            if distance > self.r_three_quarters {
                own += 1.0 - d;
            } else {
                own += 1.0 + d;
                h[at(volume - 2, bin)] -= d as f32;
            }
        } else {
            let d = (distance - self.r_quarter) / self.r_half;
            if distance < self.r_quarter {
                own += 1.0 + d;
            } else {
                own += 1.0 - d;
                h[at(volume + 2, bin)] += d as f32;
            }
        }

        // Elevation: linear in the inclination from +z between 45° and 135°.
        let inclination = (z / distance).clamp(-1.0, 1.0).acos();
        if upper {
            let d = (inclination - FRAC_PI_4) / FRAC_PI_2;
            if inclination < FRAC_PI_4 {
                own += 1.0 + d;
            } else {
                own += 1.0 - d;
                h[at(volume - 1, bin)] += d as f32;
            }
        } else {
            let d = (inclination - 3.0 * FRAC_PI_4) / FRAC_PI_2;
            if inclination > 3.0 * FRAC_PI_4 {
                own += 1.0 - d;
            } else {
                own += 1.0 + d;
                h[at(volume + 1, bin)] -= d as f32;
            }
        }

        // Azimuth: linear between sector centres, wrapping around.
        if let Some(a) = azimuth {
            let d = ((a - (SECTOR0_CENTRE + sector as f64 * FRAC_PI_4)) / FRAC_PI_4).clamp(-0.5, 0.5);
            if d > 0.0 {
                own += 1.0 - d;
                h[at((volume + 4) % VOLUMES, bin)] += d as f32;
            } else {
                own += 1.0 + d;
                h[at((volume + VOLUMES - 4) % VOLUMES, bin)] -= d as f32;
            }
        }

        h[at(volume, bin)] += own as f32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn total(h: &[f32; SHOT_LEN]) -> f64 {
        h.iter().map(|&v| f64::from(v)).sum()
    }

    #[test]
    fn a_vote_in_the_middle_of_everything_weighs_four() {
        // Each of the four dimensions contributes weight 1 in total (own + neighbour share).
        let grid = Grid::new(1.0, CosineInterpolation::Pcl);
        let mut h = [0.0; SHOT_LEN];
        let dir = [0.3_f64, -0.5, 0.2];
        let n = crate::geometry::norm(dir);
        let d = 0.4;
        grid.vote(&mut h, crate::geometry::scale(dir, d / n), d, 0.1);
        assert!((total(&h) - 4.0).abs() < 1e-5, "{}", total(&h));
    }

    #[test]
    fn points_on_the_z_axis_have_no_azimuth_share() {
        let grid = Grid::new(1.0, CosineInterpolation::Pcl);
        let mut h = [0.0; SHOT_LEN];
        grid.vote(&mut h, [0.0, 0.0, 0.5], 0.5, 1.0);
        // Sector 0, inner shell (0.5 is not > R/2), upper: volume 1; cos 1 → bin 10. Weights:
        // cosine 1, shell 1 (half to the outer shell), elevation ½ (inclination 0), azimuth none.
        assert!((h[COS_BINS + 10] - 2.0).abs() < 1e-6);
        assert!((h[3 * COS_BINS + 10] - 0.5).abs() < 1e-6);
        assert!((total(&h) - 2.5).abs() < 1e-6);
    }

    #[test]
    fn pcl_cosine_wrap_sends_the_upper_share_to_bin_zero() {
        let mut pcl = [0.0; SHOT_LEN];
        let mut lin = [0.0; SHOT_LEN];
        let local = [0.05, 0.1, 0.1];
        let d = crate::geometry::norm(local);
        // cos 0.86: value 9.3, bin 9, upper share 0.3.
        Grid::new(1.0, CosineInterpolation::Pcl).vote(&mut pcl, local, d, 0.86);
        Grid::new(1.0, CosineInterpolation::Linear).vote(&mut lin, local, d, 0.86);
        let volume = 4 * 5 + 1; // azimuth 63° is sector 5, inner shell, upper
        assert!((pcl[volume * COS_BINS] - 0.3).abs() < 1e-5);
        assert_eq!(pcl[volume * COS_BINS + 10], 0.0);
        assert!((lin[volume * COS_BINS + 10] - 0.3).abs() < 1e-5);
        assert_eq!(lin[volume * COS_BINS], 0.0);
    }

    #[test]
    fn options_reject_bad_radius() {
        for r in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let o = ShotOptions { radius: r, ..Default::default() };
            assert!(o.validate().is_err());
        }
        assert!(ShotOptions::default().validate().is_ok());
    }

    #[test]
    fn options_round_trip_through_json() {
        let o = ShotOptions { radius: 0.3, frame: ShotFrame::World, ..Default::default() };
        let s = serde_json::to_string(&o).unwrap();
        assert_eq!(serde_json::from_str::<ShotOptions>(&s).unwrap(), o);
        assert_eq!(serde_json::from_str::<ShotOptions>("{}").unwrap(), ShotOptions::default());
    }
}
