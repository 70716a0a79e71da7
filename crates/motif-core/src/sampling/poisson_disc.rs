//! Poisson-disc sampling by elimination: candidates are visited in a seeded random order and each
//! is kept when no earlier sample lies closer than the radius `r` (thesis 3.4, 4.3, 5.3.1).
//!
//! Guarantees, for the candidates given (a point cloud's points, or the dense area-weighted
//! candidates drawn on a surface):
//! - (a) no two samples are closer than `r` — except forced samples among themselves, which are
//!   taken as given;
//! - (b) every candidate lies closer than `r` to a sample or to an exclusion point (a rejected
//!   candidate was rejected because of one; a kept candidate is a sample).
//!
//! Forced samples are samples from the start: they exclude the candidates around them. Exclusion
//! points exclude the same way but are not samples. Thesis 3.4's symmetric sampling interleaves
//! insertion with the orbit closure: use [`PoissonDiscSampler`] directly (`is_free`, then
//! `insert_forced` for the whole orbit). [`Spacing::Count`] searches the radius that gives about a
//! requested number of samples.
//!
//! The spatial index is a hash grid of cell size `r` (27 neighbour cells per query): with cells of
//! `r/√3` a cell holds at most one sample but a query visits 117 cells; both inspect about the same
//! number of points, and fewer cells means fewer hash probes.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::geometry::{Point3, dist2, is_finite};
use crate::mesh::TriMesh;
use crate::point_cloud::PointCloud;
use crate::sampling::surface::{area_cdf, sample_surface};
use crate::{Error, Result};

/// How dense the sampling is.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Spacing {
    /// The Poisson-disc radius `r` (ϕ_sam in thesis 3.4; the sample spacing of 4.3 and 5.3.1), in
    /// the units of the input.
    Radius(f64),
    /// About this many output samples: the radius is searched (see
    /// [`PoissonDiscOptions::count_tolerance`]).
    Count(usize),
}

/// The order in which candidates are tried.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CandidateOrder {
    /// A random permutation drawn from the seed (blue-noise sampling).
    Random,
    /// The order of the input (e.g. candidates sorted by priority, feature points first).
    Given,
}

/// Whether forced samples appear in the output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ForcedOutput {
    /// Forced samples come first in the output (and count towards [`Spacing::Count`]).
    Include,
    /// Only samples taken from the candidates are output.
    Omit,
}

/// Options of Poisson-disc sampling.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PoissonDiscOptions {
    /// Radius or target count; default `Radius(0.01)` (units of the input).
    pub spacing: Spacing,
    /// For [`Spacing::Count`]: accepted relative deviation of the count, default 0.02 (at least ±1
    /// sample). The radius is searched by a safeguarded secant/bisection in log r, at most 40
    /// sampling runs; since the count is a step function of r an exact count may not exist, and
    /// then the run closest to the target is returned.
    pub count_tolerance: f64,
    /// Seed of the candidate order (and of the surface candidates); default 0.
    pub seed: u64,
    /// Random (seeded) or given candidate order; default random.
    pub order: CandidateOrder,
    /// Whether forced samples are output; default include.
    pub forced_output: ForcedOutput,
    /// Surfaces only: candidates drawn per expected sample (dense area-weighted random points, then
    /// elimination); more gives a more even coverage of the surface; default 20.
    pub oversampling: f64,
}

impl Default for PoissonDiscOptions {
    fn default() -> Self {
        PoissonDiscOptions {
            spacing: Spacing::Radius(0.01),
            count_tolerance: 0.02,
            seed: 0,
            order: CandidateOrder::Random,
            forced_output: ForcedOutput::Include,
            oversampling: 20.0,
        }
    }
}

/// Points that constrain the sampling.
#[derive(Debug, Clone, Copy, Default)]
pub struct Constraints<'a> {
    /// Samples from the start: output (see [`ForcedOutput`]) and excluding candidates within `r`.
    pub forced: &'a [Point3],
    /// Points that exclude candidates within `r` but are not samples (e.g. samples of a
    /// neighbouring region, or orbit images handled elsewhere).
    pub exclusion: &'a [Point3],
}

/// Where an output sample comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SampleSource {
    /// Forced sample `i` of [`Constraints::forced`].
    Forced(usize),
    /// Candidate `i`: the input point `i`, or for surfaces candidate `i` of
    /// `sample_surface(mesh, num_candidates, seed)`.
    Candidate(usize),
}

/// Face index given to forced samples in [`PoissonDiscSamples::faces`].
pub const NO_FACE: u32 = u32::MAX;

/// The result of Poisson-disc sampling.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PoissonDiscSamples {
    /// The radius used (searched in count mode).
    pub radius: f64,
    /// Sample positions: forced samples first (when included), then accepted candidates in the
    /// order they were accepted.
    pub positions: Vec<Point3>,
    /// Where each sample comes from.
    pub sources: Vec<SampleSource>,
    /// The candidates' normals when known (cloud normals, or face normals on a surface); forced
    /// samples get `[0, 0, 0]`.
    pub normals: Option<Vec<Point3>>,
    /// Surfaces only: the triangle of each sample ([`NO_FACE`] for forced samples).
    pub faces: Option<Vec<u32>>,
    /// Number of candidates considered.
    pub num_candidates: usize,
    /// Number of sampling runs (1 unless the count mode searched the radius).
    pub runs: usize,
}

impl PoissonDiscSamples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The candidate indices of the samples taken from the candidates, in output order.
    pub fn candidate_indices(&self) -> Vec<usize> {
        self.sources
            .iter()
            .filter_map(|s| match s {
                SampleSource::Candidate(i) => Some(*i),
                SampleSource::Forced(_) => None,
            })
            .collect()
    }
}

/// A mixing hasher for packed cell keys (the default SipHash is several times slower here).
#[derive(Debug, Default, Clone, Copy)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ b as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }
    fn write_u64(&mut self, x: u64) {
        // splitmix64 finaliser: every key bit affects the low bits used for the bucket.
        let mut z = (x ^ self.0).wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        self.0 = z ^ (z >> 31);
    }
}

const NONE: u32 = u32::MAX;
const KEY_BITS: u32 = 21;
const KEY_MASK: u64 = (1 << KEY_BITS) - 1;

/// What an inserted point is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SampleKind {
    /// Inserted unconditionally with [`PoissonDiscSampler::insert_forced`].
    Forced,
    /// Accepted by [`PoissonDiscSampler::try_insert`].
    Accepted,
}

/// An incremental Poisson-disc sampler over a hash grid: insert forced samples and exclusion points
/// at will, try candidates one at a time. Every point must be finite: non-finite points are never
/// free and are refused.
#[derive(Debug, Clone)]
pub struct PoissonDiscSampler {
    radius: f64,
    r2: f64,
    inv_cell: f64,
    heads: HashMap<u64, u32, BuildHasherDefault<CellHasher>>,
    /// Per inserted point: the next point in the same cell.
    next: Vec<u32>,
    /// Every inserted point (samples and exclusion points).
    points: Vec<Point3>,
    samples: Vec<Point3>,
    kinds: Vec<SampleKind>,
}

impl PoissonDiscSampler {
    /// An empty sampler of radius `r` (finite, positive).
    pub fn new(radius: f64) -> Result<Self> {
        Self::with_capacity(radius, 0)
    }

    /// An empty sampler with room for about `capacity` points.
    pub fn with_capacity(radius: f64, capacity: usize) -> Result<Self> {
        check_radius(radius)?;
        let mut heads = HashMap::with_hasher(BuildHasherDefault::default());
        heads.reserve(capacity);
        Ok(PoissonDiscSampler {
            radius,
            r2: radius * radius,
            inv_cell: 1.0 / radius,
            heads,
            next: Vec::with_capacity(capacity),
            points: Vec::with_capacity(capacity),
            samples: Vec::with_capacity(capacity),
            kinds: Vec::with_capacity(capacity),
        })
    }

    /// The radius `r`.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    #[inline]
    fn cell(&self, p: Point3) -> [i64; 3] {
        p.map(|c| (c * self.inv_cell).floor() as i64)
    }

    #[inline]
    fn key(c: [i64; 3]) -> u64 {
        // Cells 2²¹ apart share a key: harmless, distances are always checked exactly.
        (c[0] as u64 & KEY_MASK)
            | ((c[1] as u64 & KEY_MASK) << KEY_BITS)
            | ((c[2] as u64 & KEY_MASK) << (2 * KEY_BITS))
    }

    /// True when no sample or exclusion point lies closer than `r` to `p` (and `p` is finite).
    pub fn is_free(&self, p: Point3) -> bool {
        if !is_finite(p) {
            return false;
        }
        let c = self.cell(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(&h) = self.heads.get(&Self::key([c[0] + dx, c[1] + dy, c[2] + dz])) else {
                        continue;
                    };
                    let mut i = h;
                    while i != NONE {
                        if dist2(self.points[i as usize], p) < self.r2 {
                            return false;
                        }
                        i = self.next[i as usize];
                    }
                }
            }
        }
        true
    }

    fn insert_point(&mut self, p: Point3) {
        let idx = self.points.len() as u32;
        let key = Self::key(self.cell(p));
        let head = self.heads.entry(key).or_insert(NONE);
        self.next.push(*head);
        *head = idx;
        self.points.push(p);
    }

    /// Inserts `p` as a sample when it is free; returns its sample index.
    pub fn try_insert(&mut self, p: Point3) -> Option<usize> {
        if !self.is_free(p) {
            return None;
        }
        self.insert_point(p);
        self.samples.push(p);
        self.kinds.push(SampleKind::Accepted);
        Some(self.samples.len() - 1)
    }

    /// Inserts `p` as a sample whatever is near it; returns its sample index.
    pub fn insert_forced(&mut self, p: Point3) -> Result<usize> {
        check_point(p)?;
        self.insert_point(p);
        self.samples.push(p);
        self.kinds.push(SampleKind::Forced);
        Ok(self.samples.len() - 1)
    }

    /// Inserts an exclusion point: it blocks candidates within `r` but is not a sample.
    pub fn insert_exclusion(&mut self, p: Point3) -> Result<()> {
        check_point(p)?;
        self.insert_point(p);
        Ok(())
    }

    /// The samples (forced and accepted) in insertion order.
    pub fn samples(&self) -> &[Point3] {
        &self.samples
    }

    /// How each sample got in, parallel to [`PoissonDiscSampler::samples`].
    pub fn kinds(&self) -> &[SampleKind] {
        &self.kinds
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }
}

fn check_radius(r: f64) -> Result<()> {
    if !(r.is_finite() && r > 0.0) {
        return Err(Error::InvalidOption {
            name: "radius",
            message: format!("must be positive and finite, got {r}"),
        });
    }
    Ok(())
}

fn check_point(p: Point3) -> Result<()> {
    if !is_finite(p) {
        return Err(Error::InvalidInput(format!("point {p:?} has a NaN or infinite coordinate")));
    }
    Ok(())
}

fn check_points(what: &str, pts: &[Point3]) -> Result<()> {
    if let Some(i) = pts.iter().position(|p| !is_finite(*p)) {
        return Err(Error::InvalidInput(format!("{what} {i} has a NaN or infinite coordinate")));
    }
    Ok(())
}

/// Indices of the candidates not within `r` of any forced sample: the candidates that remain
/// after the forced samples have excluded their neighbourhoods.
pub fn outside_forced(candidates: &[Point3], forced: &[Point3], radius: f64) -> Result<Vec<usize>> {
    let mut s = PoissonDiscSampler::with_capacity(radius, forced.len())?;
    for p in forced {
        s.insert_exclusion(*p)?;
    }
    Ok((0..candidates.len()).filter(|&i| s.is_free(candidates[i])).collect())
}

/// One elimination run: returns the output positions and sources.
fn run(
    radius: f64,
    candidates: &[Point3],
    order: &[u32],
    constraints: &Constraints,
    forced_output: ForcedOutput,
) -> Result<(Vec<Point3>, Vec<SampleSource>)> {
    let mut s = PoissonDiscSampler::with_capacity(radius, constraints.forced.len() + candidates.len() / 8)?;
    let mut sources = Vec::new();
    for (i, p) in constraints.forced.iter().enumerate() {
        s.insert_forced(*p)?;
        sources.push(SampleSource::Forced(i));
    }
    for p in constraints.exclusion {
        s.insert_exclusion(*p)?;
    }
    for &c in order {
        if s.try_insert(candidates[c as usize]).is_some() {
            sources.push(SampleSource::Candidate(c as usize));
        }
    }
    let mut positions = s.samples;
    if forced_output == ForcedOutput::Omit {
        let nf = constraints.forced.len();
        positions.drain(..nf);
        sources.drain(..nf);
    }
    Ok((positions, sources))
}

/// Maximum sampling runs of the count mode.
const MAX_RUNS: usize = 40;

/// Runs the elimination at the given spacing; in count mode searches the radius starting from
/// `r_guess` (count ∝ r^−2 is assumed until two runs measure the actual exponent).
fn sample_with_spacing(
    candidates: &[Point3],
    constraints: &Constraints,
    options: &PoissonDiscOptions,
    r_guess: f64,
    extent: f64,
) -> Result<(f64, Vec<Point3>, Vec<SampleSource>, usize)> {
    if candidates.len() >= NONE as usize {
        return Err(Error::InvalidInput(format!(
            "{} candidates are too many (limit 2³²−1)",
            candidates.len()
        )));
    }
    check_points("candidate", candidates)?;
    check_points("forced sample", constraints.forced)?;
    check_points("exclusion point", constraints.exclusion)?;
    let mut order: Vec<u32> = (0..candidates.len() as u32).collect();
    if options.order == CandidateOrder::Random {
        let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
        rng.set_stream(u64::MAX);
        order.shuffle(&mut rng);
    }
    match options.spacing {
        Spacing::Radius(r) => {
            check_radius(r)?;
            let (p, s) = run(r, candidates, &order, constraints, options.forced_output)?;
            Ok((r, p, s, 1))
        }
        Spacing::Count(target) => {
            if target == 0 {
                return Err(Error::InvalidOption { name: "count", message: "must be at least 1".into() });
            }
            let tol = options.count_tolerance;
            if !(0.0..1.0).contains(&tol) {
                return Err(Error::InvalidOption {
                    name: "count_tolerance",
                    message: format!("{tol} is out of range 0 to 1"),
                });
            }
            let slack = (tol * target as f64).round().max(1.0);
            let goal = target as f64;
            let floor_r = extent.max(f64::MIN_POSITIVE) * 1e-12;
            let mut r = if r_guess.is_finite() && r_guess > 0.0 { r_guess } else { extent.max(1.0) };
            let (mut lo, mut hi): (Option<(f64, f64)>, Option<(f64, f64)>) = (None, None);
            let mut best: Option<(f64, f64, Vec<Point3>, Vec<SampleSource>)> = None;
            let mut exponent = 2.0;
            let mut runs = 0;
            while runs < MAX_RUNS {
                let (p, s) = run(r, candidates, &order, constraints, options.forced_output)?;
                runs += 1;
                let count = p.len() as f64;
                let err = (count - goal).abs();
                if best.as_ref().is_none_or(|b| err < b.1) {
                    best = Some((r, err, p, s));
                }
                if err <= slack {
                    break;
                }
                // Bracket: lo has too many samples (r too small), hi too few.
                if count > goal {
                    lo = Some((r, count));
                } else {
                    hi = Some((r, count));
                }
                if let (Some((rl, cl)), Some((rh, ch))) = (lo, hi) {
                    if rh / rl < 1.0 + 1e-12 {
                        break;
                    }
                    if cl > 0.0 && ch > 0.0 && cl > ch {
                        exponent = ((cl / ch).ln() / (rh / rl).ln()).clamp(0.5, 4.0);
                    }
                }
                let mut next = if count > 0.0 { r * (count / goal).powf(1.0 / exponent) } else { 0.5 * r };
                match (lo, hi) {
                    (Some((rl, _)), Some((rh, _))) if !(next > rl && next < rh) => next = (rl * rh).sqrt(),
                    (Some((rl, _)), None) if next <= rl => next = 2.0 * rl,
                    (None, Some((rh, _))) if next >= rh => next = 0.5 * rh,
                    _ => {}
                }
                if next < floor_r {
                    // More samples were asked for than there are distinct candidates.
                    break;
                }
                r = next;
            }
            let (r, _, p, s) = best.ok_or_else(|| Error::InvalidInput("no sampling run".into()))?;
            Ok((r, p, s, runs))
        }
    }
}

/// Poisson-disc sampling of a point set: the points are the candidates. `normals` (one per point)
/// are carried over when given.
pub fn poisson_disc_points(
    points: &[Point3],
    normals: Option<&[Point3]>,
    constraints: &Constraints,
    options: &PoissonDiscOptions,
) -> Result<PoissonDiscSamples> {
    if let Some(n) = normals {
        if n.len() != points.len() {
            return Err(Error::InvalidInput(format!("{} normals for {} points", n.len(), points.len())));
        }
    }
    let bb = crate::geometry::Aabb::from_points(points);
    let diag = bb.map_or(0.0, |b| b.diagonal());
    let guess = match options.spacing {
        // Assume a surface-like cloud filling a fraction of its box's faces.
        Spacing::Count(n) => bb.map_or(1.0, |b| {
            let e = b.extent();
            let area = 2.0 * (e[0] * e[1] + e[1] * e[2] + e[0] * e[2]);
            (0.5 * area / (1.5 * n as f64)).sqrt()
        }),
        Spacing::Radius(r) => r,
    };
    let (radius, positions, sources, runs) = sample_with_spacing(points, constraints, options, guess, diag)?;
    let normals = normals.map(|n| {
        sources
            .iter()
            .map(|s| match s {
                SampleSource::Candidate(i) => n[*i],
                SampleSource::Forced(_) => [0.0; 3],
            })
            .collect()
    });
    Ok(PoissonDiscSamples {
        radius,
        positions,
        sources,
        normals,
        faces: None,
        num_candidates: points.len(),
        runs,
    })
}

/// Poisson-disc sampling of a point cloud (its points are the candidates, its normals carried over).
pub fn poisson_disc_cloud(
    cloud: &PointCloud,
    constraints: &Constraints,
    options: &PoissonDiscOptions,
) -> Result<PoissonDiscSamples> {
    cloud.validate()?;
    poisson_disc_points(&cloud.positions, cloud.normals.as_deref(), constraints, options)
}

/// Largest number of surface candidates drawn.
const MAX_CANDIDATES: usize = 50_000_000;

/// Poisson-disc sampling of a mesh surface: `oversampling ×` the expected number of samples are
/// drawn with [`sample_surface`] (seeded by `options.seed`; the count is
/// [`PoissonDiscSamples::num_candidates`]) and eliminated. Normals are face normals.
pub fn poisson_disc_surface(
    mesh: &TriMesh,
    constraints: &Constraints,
    options: &PoissonDiscOptions,
) -> Result<PoissonDiscSamples> {
    let (cdf, _) = area_cdf(mesh)?;
    let area = cdf.last().copied().unwrap_or(0.0);
    if !(options.oversampling.is_finite() && options.oversampling >= 1.0) {
        return Err(Error::InvalidOption {
            name: "oversampling",
            message: format!("must be at least 1, got {}", options.oversampling),
        });
    }
    // A saturated Poisson-disc set on a surface has about one sample per 1.5 r² of area.
    const AREA_PER_SAMPLE: f64 = 1.5;
    let (expected, guess) = match options.spacing {
        Spacing::Radius(r) => {
            check_radius(r)?;
            (area / (AREA_PER_SAMPLE * r * r), r)
        }
        Spacing::Count(n) => (n as f64, (area / (AREA_PER_SAMPLE * n.max(1) as f64)).sqrt()),
    };
    let wanted = (options.oversampling * expected).ceil();
    if wanted > MAX_CANDIDATES as f64 {
        return Err(Error::InvalidOption {
            name: "radius",
            message: format!(
                "about {expected:.0} samples would need {wanted:.0} candidates (limit {MAX_CANDIDATES}): {}",
                if matches!(options.spacing, Spacing::Radius(_)) {
                    "use a larger radius"
                } else {
                    "ask for fewer samples"
                }
            ),
        });
    }
    let m = (wanted as usize).max(1);
    let cands = sample_surface(mesh, m, options.seed)?;
    let (radius, positions, sources, runs) =
        sample_with_spacing(&cands.points, constraints, options, guess, mesh.diagonal())?;
    let normals = sources
        .iter()
        .map(|s| match s {
            SampleSource::Candidate(i) => cands.normals[*i],
            SampleSource::Forced(_) => [0.0; 3],
        })
        .collect();
    let faces = sources
        .iter()
        .map(|s| match s {
            SampleSource::Candidate(i) => cands.faces[*i],
            SampleSource::Forced(_) => NO_FACE,
        })
        .collect();
    Ok(PoissonDiscSamples {
        radius,
        positions,
        sources,
        normals: Some(normals),
        faces: Some(faces),
        num_candidates: m,
        runs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampler_respects_radius_forced_and_exclusion() {
        let mut s = PoissonDiscSampler::new(1.0).unwrap();
        assert_eq!(s.try_insert([0.0; 3]), Some(0));
        assert_eq!(s.try_insert([0.5, 0.0, 0.0]), None);
        assert_eq!(s.try_insert([1.0, 0.0, 0.0]), Some(1), "exactly r apart is allowed");
        assert_eq!(s.insert_forced([0.2, 0.0, 0.0]).unwrap(), 2);
        s.insert_exclusion([10.0, 0.0, 0.0]).unwrap();
        assert!(!s.is_free([10.5, 0.0, 0.0]));
        assert!(s.is_free([-1.0, -1.0, 0.0]));
        assert_eq!(s.len(), 3);
        assert_eq!(s.kinds(), &[SampleKind::Accepted, SampleKind::Accepted, SampleKind::Forced]);
        assert!(!s.is_free([f64::NAN, 0.0, 0.0]));
        assert!(s.insert_forced([f64::INFINITY, 0.0, 0.0]).is_err());
        assert!(PoissonDiscSampler::new(0.0).is_err());
        assert!(PoissonDiscSampler::new(f64::NAN).is_err());
    }

    #[test]
    fn far_apart_cells_with_equal_keys_are_told_apart() {
        let mut s = PoissonDiscSampler::new(1.0).unwrap();
        let far = (1u64 << KEY_BITS) as f64;
        assert!(s.try_insert([0.5, 0.5, 0.5]).is_some());
        assert!(s.try_insert([0.5 + far, 0.5, 0.5]).is_some());
    }

    #[test]
    fn outside_forced_filters() {
        let c = [[0.0; 3], [0.5, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert_eq!(outside_forced(&c, &[[0.0; 3]], 1.0).unwrap(), vec![2]);
    }
}
