//! Symmetric Poisson-disc sampling (thesis 3.4).
//!
//! Candidates are dense area-weighted random points on the surface (seeded). Each candidate that
//! is farther than `r` from every sample becomes an orbit *seed*: every map of every region
//! containing it is applied (a group's elements, an instance set's maps `T_a · T_b⁻¹` out of the
//! instances containing it), and recursively to every new point — the transitive closure across
//! overlapping and nested regions. Images within the doublet threshold of a point of the same
//! orbit are merged with it; all points of the orbit are inserted as forced samples, each with its
//! local frame `O` (the orthogonal part of the concatenated transforms that map the seed to it).
//!
//! **Degenerate orbits.** A merge records a stabiliser `h = G_j⁻¹ · m · G_i` of the seed (the loop
//! seed → i → (m) → j → seed). When it is not the identity (the seed lies on a mirror plane or a
//! rotation axis, thesis Fig. 3.7b), (1) the seed is projected onto the fixed set of the
//! stabiliser group `H` (the mean of `h(p)` over `H`) and the orbit regenerated from it, so the
//! merged points coincide *exactly* (as they must for the lifted deformation to be exactly
//! symmetric), and (2) the orbit's basis is reduced to the vectors `v` with `O_h v = v` for every
//! stabiliser (the null space of the stacked `I − O_h`, by eigen-decomposition of
//! `Σ (I − O_h)ᵀ(I − O_h)`), which is `O_i v = O_j v` for all frames of a point.
//!
//! **Coverage per region.** Lifting only lets samples influence vertices of the same regions (see
//! `lift.rs`). With [`RegionCoverage::PerRegion`] a second pass seeds a new orbit at every
//! candidate that has no such eligible sample within `r`, so every region is `r`-sampled on its own.
//!
//! Images of a seed that land near a sample of *another* orbit are kept as separate samples
//! (coupling two orbits is never done): forced samples may be closer than `r` to each other.

use std::collections::{HashMap, VecDeque};

use serde::{Deserialize, Serialize};

use motif_core::TriMesh;
use motif_core::geometry::{IDENTITY4, Mat4, Point3, dist2, mat4_mul, scale};
use motif_core::procedural::rigid_inverse;
use motif_core::sampling::{PoissonDiscSampler, sample_surface};

use crate::annotation::{ResolvedAnnotation, ResolvedKind, apply, group_closure};
use crate::error::{DeformError, Result};
use crate::mat3::{IDENTITY3, Mat3, linear_part, rigid_approx_eq};
use crate::symbols::{Bits, Interner, Symbols, get_bit, set_bit, subset};

/// Largest number of points in one orbit.
pub const MAX_ORBIT_SIZE: usize = 20_000;

/// Largest number of surface candidates drawn.
const MAX_CANDIDATES: usize = 4_000_000;

/// Area of the surface per sample of a maximal Poisson-disc sampling, in units of r², used to
/// guess the radius of a target count (hexagonal packing gives 0.87; random maximal sets ~0.7).
const AREA_PER_SAMPLE: f64 = 0.7;

/// The default number of samples ([`SymmetricSamplingOptions::default`]).
pub const DEFAULT_SAMPLE_COUNT: usize = 400;

/// The Poisson-disc radius that `count` samples on a surface of area `area` come out at, about
/// (the spacing [`SampleSpacing::Count`] starts its search from). Handle regions narrower than
/// this may hold no sample.
pub fn radius_for_count(area: f64, count: usize) -> f64 {
    (area / (AREA_PER_SAMPLE * count.max(1) as f64)).sqrt()
}

/// How dense the sampling is.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SampleSpacing {
    /// The exclusion radius `r` (ϕ_sam, thesis 3.4) relative to the bounding-box diagonal.
    Radius(f64),
    /// About this many samples in total (orbit images included): the radius is searched.
    Count(usize),
}

/// Whether every region is sampled on its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RegionCoverage {
    /// A second pass adds orbits where a region has no sample of its own within `r` (default;
    /// needed so that region-restricted lifting finds samples everywhere).
    PerRegion,
    /// Plain symmetric Poisson-disc sampling as in the thesis.
    Plain,
}

/// Options of [`symmetric_sampling`] (thesis 3.4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SymmetricSamplingOptions {
    /// Radius `r` (ϕ_sam) relative to the diagonal, or a target sample count; default
    /// `Count(400)` (the thesis used 72 to 690 samples).
    pub spacing: SampleSpacing,
    /// For `Count`: accepted relative deviation of the count; default 0.05. The radius is searched
    /// by a secant method in log r (at most 30 sampling runs); the closest run is kept.
    pub count_tolerance: f64,
    /// Seed of the random candidates; default 0.
    pub seed: u64,
    /// Candidates drawn per expected sample; default 20.
    pub oversampling: f64,
    /// Distance below which two points of an orbit are one sample (a doublet), relative to the
    /// diagonal; default `None`: the annotation's tolerance (thesis 3.4: 10⁻⁴ × the scene size).
    pub doublet_threshold: Option<f64>,
    /// Per-region coverage pass; default [`RegionCoverage::PerRegion`].
    pub coverage: RegionCoverage,
}

impl Default for SymmetricSamplingOptions {
    fn default() -> Self {
        SymmetricSamplingOptions {
            spacing: SampleSpacing::Count(DEFAULT_SAMPLE_COUNT),
            count_tolerance: 0.05,
            seed: 0,
            oversampling: 20.0,
            doublet_threshold: None,
            coverage: RegionCoverage::PerRegion,
        }
    }
}

/// One orbit: samples `start..start + len`, sample `start` is the seed.
#[derive(Debug, Clone, PartialEq)]
pub struct Orbit {
    /// Index of the seed sample; the orbit's samples are contiguous from here.
    pub start: usize,
    /// Number of samples in the orbit.
    pub len: usize,
    /// Basis of the seed's admissible displacements, orthonormal, in the seed's frame: the three
    /// axes for a point in general position, fewer on transformation-invariant sets (thesis 3.4,
    /// "degenerate samples").
    pub basis: Vec<Point3>,
    /// Order of the seed's stabiliser group (1 for points in general position).
    pub stabilizer_order: usize,
}

/// A symmetric sampling of a surface.
#[derive(Debug, Clone)]
pub struct SymmetricSampling {
    /// The exclusion radius `r`, mesh units.
    pub radius: f64,
    /// Sample positions, `#S × 3`.
    pub positions: Vec<Point3>,
    /// Local frame `O` of each sample: the orthogonal part of the transform mapping its orbit's
    /// seed to it (a displacement `v` of the seed moves the sample by `O v`).
    pub frames: Vec<Mat3>,
    /// Orbit index of each sample.
    pub orbit_of: Vec<u32>,
    /// The orbits, in sampling order.
    pub orbits: Vec<Orbit>,
    /// Number of sampling runs (more than 1 when a target count was searched).
    pub runs: usize,
    /// Distance below which two points of an orbit were merged (doublet threshold), mesh units.
    pub doublet_distance: f64,
    /// Region set (`has`) id of each sample, into `sets`.
    pub(crate) has: Vec<u32>,
    pub(crate) sets: Interner,
}

impl SymmetricSampling {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Number of orbits whose basis was reduced (seeds on transformation-invariant sets).
    pub fn degenerate_orbits(&self) -> usize {
        self.orbits.iter().filter(|o| o.basis.len() < 3).count()
    }

    /// Dimension of the space of symmetry-preserving displacements of the sampling.
    pub fn dof(&self) -> usize {
        self.orbits.iter().map(|o| o.basis.len()).sum()
    }
}

/// One orbit under construction.
struct OrbitPoints {
    pos: Vec<Point3>,
    paths: Vec<Mat4>,
    implied: Vec<Bits>,
    stabilizers: Vec<Mat4>,
}

/// Everything a sampling run needs.
struct Ctx<'a> {
    mesh_diag: f64,
    symbols: Symbols<'a>,
    merge_tol: f64,
    tol: f64,
}

impl Ctx<'_> {
    /// The transitive closure of the orbit of `seed` (thesis 3.4), with degenerate orbits
    /// projected onto their invariant set.
    fn close_orbit(&self, seed: Point3) -> Result<(OrbitPoints, Vec<Point3>, usize)> {
        let cell = self.merge_tol.max(f64::MIN_POSITIVE);
        let key = |p: Point3| p.map(|c| (c / cell).floor() as i64);
        let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        let mut o = OrbitPoints {
            pos: vec![seed],
            paths: vec![IDENTITY4],
            implied: vec![self.symbols.empty()],
            stabilizers: Vec::new(),
        };
        let mut has = vec![self.symbols.point_has(seed)];
        grid.entry(key(seed)).or_default().push(0);
        let near_identity_lin = (10.0 * self.tol).clamp(1e-6, 1e-2);
        let mut queue: VecDeque<usize> = VecDeque::from([0]);
        while let Some(i) = queue.pop_front() {
            let p = o.pos[i];
            let gi = o.paths[i];
            let hi = has[i].clone();
            let mut maps: Vec<(Mat4, usize)> = Vec::new();
            for s in &self.symbols.resolved.symmetries {
                match &s.kind {
                    ResolvedKind::Group { region, elements, .. } => {
                        if get_bit(&hi, region.symbol) {
                            maps.extend(elements.iter().skip(1).map(|g| (*g, region.symbol)));
                        }
                    }
                    ResolvedKind::Instances { instances, transforms, inverses } => {
                        for (b, rb) in instances.iter().enumerate() {
                            if !get_bit(&hi, rb.symbol) {
                                continue;
                            }
                            for (a, ra) in instances.iter().enumerate() {
                                if a != b {
                                    maps.push((mat4_mul(&transforms[a], &inverses[b]), ra.symbol));
                                }
                            }
                        }
                    }
                }
            }
            for (m, implied_symbol) in maps {
                let q = apply(&m, p);
                let gq = mat4_mul(&m, &gi);
                let k = key(q);
                let mut found = None;
                'search: for dx in -1..=1 {
                    for dy in -1..=1 {
                        for dz in -1..=1 {
                            if let Some(list) = grid.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                                for &j in list {
                                    if dist2(o.pos[j as usize], q) <= self.merge_tol * self.merge_tol {
                                        found = Some(j as usize);
                                        break 'search;
                                    }
                                }
                            }
                        }
                    }
                }
                match found {
                    Some(j) => {
                        set_bit(&mut o.implied[j], implied_symbol);
                        if !get_bit(&has[j], implied_symbol) {
                            // Known to lie in the region although the test missed it (boundary
                            // rounding): apply that region's maps to it too.
                            set_bit(&mut has[j], implied_symbol);
                            queue.push_back(j);
                        }
                        let h = mat4_mul(&rigid_inverse(&o.paths[j]), &gq);
                        let trivial = rigid_approx_eq(
                            &h,
                            &IDENTITY4,
                            near_identity_lin,
                            near_identity_lin * self.mesh_diag,
                        );
                        if !trivial
                            && !o
                                .stabilizers
                                .iter()
                                .any(|s| rigid_approx_eq(s, &h, 1e-9, 1e-9 * self.mesh_diag))
                        {
                            o.stabilizers.push(h);
                        }
                    }
                    None => {
                        if o.pos.len() >= MAX_ORBIT_SIZE {
                            return Err(DeformError::OrbitTooLarge { position: seed, limit: MAX_ORBIT_SIZE });
                        }
                        let idx = o.pos.len();
                        grid.entry(k).or_default().push(idx as u32);
                        let mut imp = self.symbols.empty();
                        set_bit(&mut imp, implied_symbol);
                        o.pos.push(q);
                        o.paths.push(gq);
                        o.implied.push(imp);
                        let mut hq = self.symbols.point_has(q);
                        hq.iter_mut().zip(&o.implied[idx]).for_each(|(a, b)| *a |= b);
                        has.push(hq);
                        queue.push_back(idx);
                    }
                }
            }
        }
        // Degenerate orbit: project the seed onto the stabiliser's fixed set, regenerate.
        let mut basis = vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let mut order = 1;
        if !o.stabilizers.is_empty() {
            if let Ok(group) = group_closure("stabiliser", &o.stabilizers, self.mesh_diag, self.tol) {
                order = group.len();
                let mut c = [0.0; 3];
                for h in &group {
                    let q = apply(h, seed);
                    for k in 0..3 {
                        c[k] += q[k];
                    }
                }
                let projected = scale(c, 1.0 / group.len() as f64);
                for (pos, path) in o.pos.iter_mut().zip(&o.paths) {
                    *pos = apply(path, projected);
                }
            }
            basis = fixed_space(&o.stabilizers);
        }
        Ok((o, basis, order))
    }
}

/// Orthonormal basis of `{v : O_h v = v for every h}`.
fn fixed_space(stabilizers: &[Mat4]) -> Vec<Point3> {
    let mut c = nalgebra::Matrix3::<f64>::zeros();
    for h in stabilizers {
        let o = linear_part(h);
        let mut d = nalgebra::Matrix3::<f64>::zeros();
        for i in 0..3 {
            for j in 0..3 {
                d[(i, j)] = IDENTITY3[i][j] - o[i][j];
            }
        }
        c += d.transpose() * d;
    }
    let eig = nalgebra::SymmetricEigen::new(c);
    let mut out = Vec::new();
    for k in 0..3 {
        if eig.eigenvalues[k].abs() < 1e-8 {
            let v = eig.eigenvectors.column(k);
            out.push([v[0], v[1], v[2]]);
        }
    }
    out
}

/// A growing symmetric sampling of one run: the sampling plus its Poisson-disc and region grids.
struct Run {
    s: SymmetricSampling,
    sampler: PoissonDiscSampler,
    grid: HashMap<[i64; 3], Vec<u32>>,
    inv_cell: f64,
}

impl Run {
    fn new(radius: f64, doublet_distance: f64) -> Result<Self> {
        Ok(Run {
            s: SymmetricSampling {
                radius,
                positions: Vec::new(),
                frames: Vec::new(),
                orbit_of: Vec::new(),
                orbits: Vec::new(),
                runs: 1,
                doublet_distance,
                has: Vec::new(),
                sets: Interner::default(),
            },
            sampler: PoissonDiscSampler::new(radius)?,
            grid: HashMap::new(),
            inv_cell: 1.0 / radius,
        })
    }

    fn add_orbit(&mut self, ctx: &Ctx, seed: Point3) -> Result<()> {
        push_orbit(&mut self.s, ctx, seed, |p| {
            self.sampler.insert_forced(p)?;
            Ok(())
        })?;
        let first = self.s.orbits.last().map_or(0, |o| o.start);
        for idx in first..self.s.positions.len() {
            let p = self.s.positions[idx];
            self.grid.entry(p.map(|c| (c * self.inv_cell).floor() as i64)).or_default().push(idx as u32);
        }
        Ok(())
    }

    /// Is there a sample within `r` of `p` whose region set contains `required`?
    fn has_eligible_near(&self, p: Point3, required: &[u64], r: f64) -> bool {
        let c = p.map(|x| (x * self.inv_cell).floor() as i64);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = self.grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        for &l in list {
                            let l = l as usize;
                            if dist2(self.s.positions[l], p) < r * r
                                && subset(required, &self.s.sets.sets[self.s.has[l] as usize])
                            {
                                return true;
                            }
                        }
                    }
                }
            }
        }
        false
    }
}

/// Closes the orbit of `seed` and appends it to `s`; `on_point` sees every new position.
fn push_orbit(
    s: &mut SymmetricSampling,
    ctx: &Ctx,
    seed: Point3,
    mut on_point: impl FnMut(Point3) -> Result<()>,
) -> Result<()> {
    let (o, basis, order) = ctx.close_orbit(seed)?;
    let start = s.positions.len();
    let id = s.orbits.len() as u32;
    for (k, (p, path)) in o.pos.iter().zip(&o.paths).enumerate() {
        on_point(*p)?;
        let mut h = ctx.symbols.point_has(*p);
        h.iter_mut().zip(&o.implied[k]).for_each(|(a, b)| *a |= b);
        let hid = s.sets.id(h);
        s.positions.push(*p);
        s.frames.push(linear_part(path));
        s.orbit_of.push(id);
        s.has.push(hid);
    }
    s.orbits.push(Orbit { start, len: o.pos.len(), basis, stabilizer_order: order });
    Ok(())
}

/// Adds one orbit per seed (closing each under the annotation), e.g. at vertices whose
/// symmetry-consistent lifting support is empty.
pub(crate) fn add_orbits(
    sampling: &mut SymmetricSampling,
    mesh: &TriMesh,
    resolved: &ResolvedAnnotation,
    seeds: &[Point3],
) -> Result<()> {
    let ctx = Ctx {
        mesh_diag: mesh.diagonal(),
        symbols: Symbols::new(mesh, resolved)?,
        merge_tol: sampling.doublet_distance,
        tol: resolved.tolerance,
    };
    for &p in seeds {
        push_orbit(sampling, &ctx, p, |_| Ok(()))?;
    }
    Ok(())
}

/// The largest radius the search for a sample count tries, as a multiple of the radius that
/// count would have on a surface without symmetries ([`radius_for_count`]). Orbits of exact
/// symmetries merge their coinciding images, so the count falls as the radius grows, as on a
/// surface without symmetries, and the search settles near the guess. An approximate symmetry forced on a model (a
/// mirror 1.7% of the diagonal off the windmill's plane) merges nothing: every orbit keeps all
/// its images, the count stays high at any radius, and the search used to grow the radius to a
/// third of the diagonal, where handles held no sample. The capped search keeps the samples dense
/// and returns more of them than asked.
const MAX_RADIUS_OVER_GUESS: f64 = 2.0;

/// Symmetric Poisson-disc sampling of `mesh` under the resolved annotation (thesis 3.4).
pub fn symmetric_sampling(
    mesh: &TriMesh,
    resolved: &ResolvedAnnotation,
    options: &SymmetricSamplingOptions,
) -> Result<SymmetricSampling> {
    let diag = crate::annotation::check_mesh(mesh)?;
    let o = options;
    if !(o.oversampling.is_finite() && o.oversampling >= 1.0) {
        return Err(DeformError::InvalidOption {
            name: "sampling.oversampling",
            message: format!("must be at least 1, got {}", o.oversampling),
        });
    }
    let doublet = o.doublet_threshold.unwrap_or(resolved.tolerance);
    if !(doublet.is_finite() && doublet > 0.0 && doublet < 0.1) {
        return Err(DeformError::InvalidOption {
            name: "sampling.doublet_threshold",
            message: format!("must lie in (0, 0.1) relative to the diagonal, got {doublet}"),
        });
    }
    let area = mesh.area();
    if !(area > 0.0 && area.is_finite()) {
        return Err(DeformError::InvalidMesh("the surface has no area".into()));
    }
    let (expected, guess) = match o.spacing {
        SampleSpacing::Radius(r) => {
            if !(r.is_finite() && r > 0.0 && r <= 1.0) {
                return Err(DeformError::InvalidOption {
                    name: "sampling.spacing",
                    message: format!("the radius must lie in (0, 1] relative to the diagonal, got {r}"),
                });
            }
            let r = r * diag;
            (area / (AREA_PER_SAMPLE * r * r), r)
        }
        SampleSpacing::Count(n) => {
            if n == 0 || n > 1_000_000 {
                return Err(DeformError::InvalidOption {
                    name: "sampling.spacing",
                    message: format!("the sample count must lie in 1..=1000000, got {n}"),
                });
            }
            (n as f64, radius_for_count(area, n))
        }
    };
    let wanted = (o.oversampling * expected).ceil().max(64.0);
    if wanted > MAX_CANDIDATES as f64 {
        return Err(DeformError::InvalidOption {
            name: "sampling.spacing",
            message: format!(
                "about {expected:.0} samples would need {wanted:.0} candidates (limit {MAX_CANDIDATES}): use a larger radius"
            ),
        });
    }
    let cands = sample_surface(mesh, wanted as usize, o.seed)?.points;
    let symbols = Symbols::new(mesh, resolved)?;
    let ctx = Ctx { mesh_diag: diag, symbols, merge_tol: doublet * diag, tol: resolved.tolerance };
    // Required region sets of the candidates do not depend on the radius: compute them once.
    let required: Vec<Option<Bits>> = if o.coverage == RegionCoverage::PerRegion && resolved.num_symbols > 0 {
        cands
            .iter()
            .map(|&c| {
                let b = ctx.symbols.point_required(c);
                b.iter().any(|w| *w != 0).then_some(b)
            })
            .collect()
    } else {
        vec![None; cands.len()]
    };
    let run = |r: f64| -> Result<Run> {
        let mut run = Run::new(r, doublet * diag)?;
        for &c in &cands {
            if run.sampler.is_free(c) {
                run.add_orbit(&ctx, c)?;
            }
        }
        for (c, req) in cands.iter().zip(&required) {
            if let Some(req) = req
                && !run.has_eligible_near(*c, req, r)
            {
                run.add_orbit(&ctx, *c)?;
            }
        }
        Ok(run)
    };
    let (radius, best, runs) = match o.spacing {
        SampleSpacing::Radius(_) => (guess, run(guess)?, 1),
        SampleSpacing::Count(n) => {
            let target = n as f64;
            let tol = (o.count_tolerance.max(0.0) * target).max(1.0);
            let mut r = guess;
            let mut best: Option<(f64, Run)> = None;
            let mut prev: Option<(f64, f64)> = None;
            let mut runs = 0;
            for _ in 0..30 {
                let s = run(r)?;
                runs += 1;
                let count = s.s.positions.len() as f64;
                let better = best.as_ref().is_none_or(|(_, b)| {
                    (count - target).abs() < (b.s.positions.len() as f64 - target).abs()
                });
                if better {
                    best = Some((r, s));
                }
                if (count - target).abs() <= tol {
                    break;
                }
                // Secant in log-log, assuming count ∝ r^-2 until two runs measure the exponent.
                let mut slope = -2.0;
                if let Some((pr, pc)) = prev
                    && (pr.ln() - r.ln()).abs() > 1e-12
                    && pc > 0.0
                    && count > 0.0
                {
                    let s = (pc.ln() - count.ln()) / (pr.ln() - r.ln());
                    if s.is_finite() && s < -0.3 {
                        slope = s.max(-4.0);
                    }
                }
                prev = Some((r, count));
                let step = ((target.ln() - count.max(1.0).ln()) / slope).clamp(-1.0, 1.0);
                let next = (r * step.exp()).min(MAX_RADIUS_OVER_GUESS * guess);
                // At the cap already: a larger radius is not tried (see MAX_RADIUS_OVER_GUESS).
                if !(next.is_finite() && next > 1e-6 * diag) || next == r {
                    break;
                }
                r = next;
            }
            let (r, s) = best.ok_or_else(|| DeformError::InvalidOption {
                name: "sampling.spacing",
                message: "no sampling run succeeded".into(),
            })?;
            (r, s, runs)
        }
    };
    let mut out = best.s;
    out.radius = radius;
    out.runs = runs;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use motif_core::procedural::{reflection, rotation_about};

    #[test]
    fn fixed_space_of_a_mirror_is_its_plane() {
        let m = reflection([0.0, 1.0, 0.0], [0.0; 3]);
        let b = fixed_space(&[m]);
        assert_eq!(b.len(), 2);
        for v in b {
            assert!(v[1].abs() < 1e-12);
        }
        let r = rotation_about([0.0, 0.0, 1.0], [0.0; 3], 1.0);
        let b = fixed_space(&[r]);
        assert_eq!(b.len(), 1);
        assert!((b[0][2].abs() - 1.0).abs() < 1e-12);
        assert!(fixed_space(&[r, reflection([0.0, 0.0, 1.0], [0.0; 3])]).is_empty());
    }
}
