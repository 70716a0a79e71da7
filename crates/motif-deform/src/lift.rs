//! Lifting displacements of the sampling to the mesh (thesis 3.4, "lifting the displacements").
//!
//! Each vertex `k` gets weights `w_kl` from Gaussians of standard deviation `σ` (the sampling
//! radius by default) around the samples, cut off where the Gaussian falls below `0.001`, and
//! normalised to a partition of unity: `u_k = Σ_l w_kl ū_l / Σ_l w_kl`. The normalised weights
//! are precomputed as a sparse matrix `W` (`#V × #S`, CSR), so a frame's lift is one sparse
//! product, parallel over vertices.
//!
//! **Continuity of the cut-off.** The weight is `max(0, G(d) − c)` with `G(d) = exp(−d²/2σ²)` and
//! `c = cutoff`: the Gaussian shifted by the cut-off, so it reaches zero continuously. A hard
//! cut-off jumps by `c` at the support boundary; rounding (10⁻¹⁶) in `|x_k − s_l|` could then put a
//! pair inside on one side of a symmetry and outside on the other, an error of order 10⁻³ that
//! would break exactness.
//!
//! **Exactness.** `u_{φ(k)} = O_g u_k` holds when the weights commute with the symmetry:
//! `w(g x_k, g s_l) = w(x_k, s_l)` (true for distance-based weights) *and* `g` maps the samples
//! vertex `k` sees onto the samples its image `φ(k)` sees. For a global symmetry the second holds
//! because the sampling is symmetric. For partial symmetries it fails near a region's border
//! (samples outside the region are not mapped), and for tilings it fails on faces shared by two
//! cells: such a face is tied by the lattice maps to the outer faces of the first and last cell,
//! which see samples on one side only. With [`LiftSupport::Equivariant`] (default) each vertex's
//! support `R(k)` is the largest set with
//!
//! `R(k) ⊆ {samples within the cut-off}` and `m(R(k)) ⊆ R(φ_m(k))` for every generating map `m`
//! whose domain contains `k`
//!
//! (group generators; for instance sets the maps between instance 0 and each other instance, both
//! ways), computed as a greatest fixpoint: start from the samples within the cut-off that lie in
//! the domain of every map applicable to `k`, then repeatedly drop samples whose image is not
//! supported at the image vertex. Samples inside a region then only influence vertices of that
//! region; a face shared by two cells moves with the samples on that face. The deformation can be
//! discontinuous where a region's border cuts through a connected part (e.g. the windmill's rotor
//! box cutting the shaft): exact symmetry on the region (thesis eq. 3.2) is the contract. Vertices
//! without an image vertex under a map (approximate symmetries) are not constrained by that map.
//!
//! **Vertices far from every eligible sample** (support empty after the fixpoint): the nearest
//! samples within the cut-off, or else the nearest samples overall, get equal weights (ties within
//! 10⁻⁹ × the diagonal share); counted in [`Lifting::fallback_vertices`]. Exactness is not
//! guaranteed at those vertices.

use std::collections::HashMap;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use motif_core::TriMesh;
use motif_core::geometry::{Mat4, Point3, dist, dist2, mat4_mul, transform_point};
use motif_core::spatial::KdTree;

use crate::annotation::{ResolvedAnnotation, ResolvedKind};
use crate::error::{DeformError, Result};
use crate::mat3::{IDENTITY3, Mat3, linear_part, mul as mul3, mul_vec};
use crate::residual::{induced_map, one_ring_means};
use crate::symbols::get_bit;
use crate::symmetric_sampling::SymmetricSampling;

/// Which samples may influence a vertex.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LiftSupport {
    /// The largest symmetry-consistent support (exact on partial symmetries and tilings; default).
    Equivariant,
    /// Every sample within the cut-off, as in the thesis (exact for global symmetries only).
    AllSamples,
}

/// How the lift is evaluated per frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LiftEvaluation {
    /// One row of `W` per vertex-orbit representative; the other vertices of the orbit get the
    /// representative's displacement turned by the orbit frame, `u_{φ(k)} = O u_k` (default: the
    /// same result up to rounding, with symmetry structural and a fraction of the memory traffic).
    PerOrbit,
    /// One row of `W` per vertex.
    PerVertex,
}

/// Options of the lifting (thesis 3.4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LiftOptions {
    /// σ, the Gaussians' standard deviation, in units of the sampling radius `r` ("standard
    /// deviation equal to the sampling density"); default 1.
    pub sigma: f64,
    /// Gaussian values below this are cut off (thesis: 0.001); default 0.001. The support radius
    /// is `σ · sqrt(2 ln(1/cutoff))` (3.72 σ by default).
    pub cutoff: f64,
    /// Which samples may influence a vertex; default [`LiftSupport::Equivariant`].
    pub support: LiftSupport,
    /// Per orbit or per vertex; default [`LiftEvaluation::PerOrbit`] (only with the equivariant
    /// support).
    pub evaluation: LiftEvaluation,
}

impl Default for LiftOptions {
    fn default() -> Self {
        LiftOptions {
            sigma: 1.0,
            cutoff: 1e-3,
            support: LiftSupport::Equivariant,
            evaluation: LiftEvaluation::PerOrbit,
        }
    }
}

/// The lifting matrix `W` (`#V × #S`, rows sum to 1), stored for the vertex-orbit
/// representatives (all vertices with [`LiftEvaluation::PerVertex`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Lifting {
    /// CSR rows, one per representative.
    start: Vec<usize>,
    cols: Vec<u32>,
    weights: Vec<f64>,
    /// Vertex of each row.
    row_vertex: Vec<u32>,
    /// Per vertex: its representative's row and the frame (index into `frames`, 0 = identity)
    /// turning the representative's displacement into its own.
    slot: Vec<u32>,
    frame: Vec<u32>,
    frames: Vec<Mat3>,
    fallback: usize,
    fallback_rows: Vec<bool>,
}

impl Lifting {
    /// Computes `W` for the vertices of `mesh` (parallel over vertices).
    pub(crate) fn new(
        mesh: &TriMesh,
        resolved: &ResolvedAnnotation,
        sampling: &SymmetricSampling,
        options: &LiftOptions,
    ) -> Result<Lifting> {
        if !(options.sigma.is_finite() && options.sigma > 0.0) {
            return Err(DeformError::InvalidOption {
                name: "lift.sigma",
                message: format!("must be positive (units of the sampling radius), got {}", options.sigma),
            });
        }
        if !(options.cutoff > 0.0 && options.cutoff < 1.0) {
            return Err(DeformError::InvalidOption {
                name: "lift.cutoff",
                message: format!("must lie in (0, 1), got {}", options.cutoff),
            });
        }
        let positions = &mesh.positions;
        let tree = KdTree::new(&sampling.positions)?;
        let sigma = options.sigma * sampling.radius;
        let c = options.cutoff;
        let reach = sigma * (2.0 * (1.0 / c).ln()).sqrt();
        let inv2s2 = 1.0 / (2.0 * sigma * sigma);
        let tie = resolved.margin.max(1e-300);
        // Candidate supports: samples within the cut-off, ascending index.
        let mut support: Vec<Vec<u32>> = positions
            .par_iter()
            .map(|&x| {
                let mut v: Vec<u32> = tree
                    .within_unsorted(x, reach)
                    .into_iter()
                    .filter(|nb| (-(nb.distance * nb.distance) * inv2s2).exp() - c > 0.0)
                    .map(|nb| nb.index as u32)
                    .collect();
                v.sort_unstable();
                v
            })
            .collect();
        let nv = positions.len();
        // Per vertex: representative and frame (identity: every vertex is its own representative).
        let mut rep: Vec<u32> = (0..nv as u32).collect();
        let mut frame = vec![0u32; nv];
        let mut frames = vec![IDENTITY3];
        if options.support == LiftSupport::Equivariant && !resolved.symmetries.is_empty() {
            let (maps, vmaps) = equivariant_supports(mesh, resolved, sampling, &tree, &mut support)?;
            if options.evaluation == LiftEvaluation::PerOrbit {
                vertex_orbits(&maps, &vmaps, &mut rep, &mut frame, &mut frames);
            }
        }
        let n = sampling.len();
        let row_vertex: Vec<u32> = (0..nv as u32).filter(|&k| rep[k as usize] == k).collect();
        let mut slot_of = vec![0u32; nv];
        for (i, &k) in row_vertex.iter().enumerate() {
            slot_of[k as usize] = i as u32;
        }
        let slot: Vec<u32> = rep.iter().map(|&r| slot_of[r as usize]).collect();
        let rows: Vec<(Vec<(u32, f64)>, bool)> = row_vertex
            .par_iter()
            .map(|&k| {
                let (x, sup) = (positions[k as usize], &support[k as usize]);
                let mut row: Vec<(u32, f64)> = sup
                    .iter()
                    .filter_map(|&l| {
                        let d2 = dist2(x, sampling.positions[l as usize]);
                        let w = (-d2 * inv2s2).exp() - c;
                        (w > 0.0).then_some((l, w))
                    })
                    .collect();
                let fallback = row.is_empty();
                if fallback {
                    let found: Vec<(usize, f64)> =
                        (0..n).map(|l| (l, dist(x, sampling.positions[l]))).collect();
                    let dmin = found.iter().map(|f| f.1).fold(f64::INFINITY, f64::min);
                    row = found.iter().filter(|f| f.1 <= dmin + tie).map(|f| (f.0 as u32, 1.0)).collect();
                }
                let s: f64 = row.iter().map(|r| r.1).sum();
                for r in &mut row {
                    r.1 /= s;
                }
                (row, fallback)
            })
            .collect();
        let mut start = Vec::with_capacity(row_vertex.len() + 1);
        start.push(0);
        let nnz: usize = rows.iter().map(|r| r.0.len()).sum();
        let mut cols = Vec::with_capacity(nnz);
        let mut weights = Vec::with_capacity(nnz);
        let mut fallback_row = Vec::with_capacity(row_vertex.len());
        for (row, fb) in rows {
            fallback_row.push(fb);
            for (l, w) in row {
                cols.push(l);
                weights.push(w);
            }
            start.push(cols.len());
        }
        let fallback_rows: Vec<bool> = slot.iter().map(|&s| fallback_row[s as usize]).collect();
        let fallback = fallback_rows.iter().filter(|b| **b).count();
        Ok(Lifting { start, cols, weights, row_vertex, slot, frame, frames, fallback, fallback_rows })
    }

    /// Number of non-zero weights stored.
    pub fn nnz(&self) -> usize {
        self.cols.len()
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.slot.len()
    }

    /// Number of stored rows (vertex-orbit representatives; all vertices per vertex). The
    /// `work` buffer of [`Lifting::lift`] has this length.
    pub fn num_rows(&self) -> usize {
        self.row_vertex.len()
    }

    /// Vertices whose support was empty (lifted from their nearest samples; exactness is not
    /// guaranteed there).
    pub fn fallback_vertices(&self) -> usize {
        self.fallback
    }

    /// Positions of vertices with an empty support, thinned so no two are closer than `spacing`
    /// (seeds for extra orbits).
    pub(crate) fn fallback_seeds(&self, positions: &[Point3], spacing: f64) -> Vec<Point3> {
        let mut seeds: Vec<Point3> = Vec::new();
        for (k, fb) in self.fallback_rows.iter().enumerate() {
            if *fb && seeds.iter().all(|s| dist2(*s, positions[k]) >= spacing * spacing) {
                seeds.push(positions[k]);
            }
        }
        seeds
    }

    /// How vertex `k` is lifted: its representative vertex, that vertex's row (sample indices and
    /// normalised weights) and the frame `O` with `u_k = O u_rep`.
    pub fn row(&self, k: usize) -> (usize, &[u32], &[f64], Mat3) {
        let s = self.slot[k] as usize;
        let r = self.start[s]..self.start[s + 1];
        (
            self.row_vertex[s] as usize,
            &self.cols[r.clone()],
            &self.weights[r],
            self.frames[self.frame[k] as usize],
        )
    }

    /// `out = rest + W ū`: the representatives' rows into `work` (length [`Lifting::num_rows`]),
    /// then every vertex from its representative; parallel, allocation-free.
    pub fn lift(&self, ubar: &[Point3], rest: &[Point3], work: &mut [Point3], out: &mut [Point3]) {
        work.par_iter_mut().with_min_len(1024).enumerate().for_each(|(s, o)| {
            let (a, b) = (self.start[s], self.start[s + 1]);
            let mut u = [0.0; 3];
            for (l, w) in self.cols[a..b].iter().zip(&self.weights[a..b]) {
                let v = ubar[*l as usize];
                u[0] += w * v[0];
                u[1] += w * v[1];
                u[2] += w * v[2];
            }
            *o = u;
        });
        out.par_iter_mut().with_min_len(4096).enumerate().for_each(|(k, o)| {
            let u = work[self.slot[k] as usize];
            let f = self.frame[k];
            let u = if f == 0 { u } else { mul_vec(&self.frames[f as usize], u) };
            let x = rest[k];
            *o = [x[0] + u[0], x[1] + u[1], x[2] + u[2]];
        });
    }
}

/// Vertex orbits under the generating maps (breadth-first from the lowest index): every vertex
/// gets the orbit's first vertex as representative and the frame `O` (product of the maps' linear
/// parts along the path) with `u_k = O u_rep`.
fn vertex_orbits(
    maps: &[GenMap],
    vmaps: &[Vec<(u32, u32)>],
    rep: &mut [u32],
    frame: &mut [u32],
    frames: &mut Vec<Mat3>,
) {
    let nv = rep.len();
    let mut seen = vec![false; nv];
    let mut index: HashMap<[i64; 9], u32> = HashMap::new();
    let key = |m: &Mat3| -> [i64; 9] {
        let mut k = [0i64; 9];
        for i in 0..3 {
            for j in 0..3 {
                k[3 * i + j] = (m[i][j] * 1e9).round() as i64;
            }
        }
        k
    };
    index.insert(key(&IDENTITY3), 0);
    let lin: Vec<Mat3> = maps.iter().map(|m| linear_part(&m.transform)).collect();
    let mut queue = std::collections::VecDeque::new();
    for k0 in 0..nv {
        if seen[k0] {
            continue;
        }
        seen[k0] = true;
        rep[k0] = k0 as u32;
        frame[k0] = 0;
        queue.push_back(k0);
        while let Some(k) = queue.pop_front() {
            for &(mi, j) in &vmaps[k] {
                if j == NONE || seen[j as usize] {
                    continue;
                }
                let j = j as usize;
                let o = mul3(&lin[mi as usize], &frames[frame[k] as usize]);
                let next = frames.len() as u32;
                let f = *index.entry(key(&o)).or_insert_with(|| {
                    frames.push(o);
                    next
                });
                seen[j] = true;
                rep[j] = k0 as u32;
                frame[j] = f;
                queue.push_back(j);
            }
        }
    }
}

const NONE: u32 = u32::MAX;

/// A generating map of the annotation's groupoid: transform, source region (symbol) and the
/// vertices it maps.
struct GenMap {
    transform: Mat4,
    symbol: usize,
    domain: Vec<u32>,
}

fn generating_maps(resolved: &ResolvedAnnotation) -> Vec<GenMap> {
    let mut maps = Vec::new();
    for s in &resolved.symmetries {
        match &s.kind {
            ResolvedKind::Group { region, generators, .. } => {
                for g in generators {
                    maps.push(GenMap {
                        transform: *g,
                        symbol: region.symbol,
                        domain: region.vertices.clone(),
                    });
                }
            }
            ResolvedKind::Instances { instances, transforms, inverses } => {
                for a in 1..instances.len() {
                    for (to, from) in [(a, 0), (0, a)] {
                        maps.push(GenMap {
                            transform: mat4_mul(&transforms[to], &inverses[from]),
                            symbol: instances[from].symbol,
                            domain: instances[from].vertices.clone(),
                        });
                    }
                }
            }
        }
    }
    maps
}

/// Shrinks every vertex's support to the greatest equivariant one (see the module docs).
fn equivariant_supports(
    mesh: &TriMesh,
    resolved: &ResolvedAnnotation,
    sampling: &SymmetricSampling,
    sample_tree: &KdTree,
    support: &mut [Vec<u32>],
) -> Result<(Vec<GenMap>, Vec<Vec<(u32, u32)>>)> {
    let maps = generating_maps(resolved);
    let nv = mesh.num_vertices();
    let ns = sampling.len();
    // Image of every sample under every map (NONE outside the map's domain or without image).
    let tol = sampling.doublet_distance.max(resolved.margin);
    let images: Vec<Vec<u32>> = maps
        .iter()
        .map(|m| {
            (0..ns)
                .into_par_iter()
                .map(|l| {
                    if !get_bit(&sampling.sets.sets[sampling.has[l] as usize], m.symbol) {
                        return NONE;
                    }
                    let q = transform_point(&m.transform, sampling.positions[l]);
                    let cands = sample_tree.within_unsorted(q, tol);
                    let same = cands.iter().filter(|c| sampling.orbit_of[c.index] == sampling.orbit_of[l]);
                    same.min_by(|a, b| a.distance.total_cmp(&b.distance))
                        .or_else(|| cands.iter().min_by(|a, b| a.distance.total_cmp(&b.distance)))
                        .map_or(NONE, |c| c.index as u32)
                })
                .collect()
        })
        .collect();
    // Vertex maps φ_m, stored per vertex as (map, image vertex); NONE image: φ undefined there.
    let vtree = KdTree::new(&mesh.positions)?;
    let neigh = one_ring_means(mesh);
    let mut vmaps: Vec<Vec<(u32, u32)>> = vec![Vec::new(); nv];
    for (mi, m) in maps.iter().enumerate() {
        let e = crate::annotation::SymmetryElement {
            symmetry: 0,
            name: String::new(),
            label: String::new(),
            transform: m.transform,
            domain: m.domain.clone(),
        };
        let map = induced_map(mesh, &vtree, &neigh, &e, resolved.tolerance * resolved.diagonal);
        let mut img = vec![NONE; nv];
        for (k, j) in map.pairs {
            img[k as usize] = j;
        }
        for &k in &m.domain {
            vmaps[k as usize].push((mi as u32, img[k as usize]));
        }
    }
    // Initial supports: samples in the domain of every map applicable to the vertex.
    support.par_iter_mut().zip(&vmaps).for_each(|(sup, vm)| {
        sup.retain(|&l| vm.iter().all(|&(mi, _)| images[mi as usize][l as usize] != NONE));
    });
    // Greatest fixpoint (Jacobi sweeps).
    loop {
        let next: Vec<Vec<u32>> = (0..nv)
            .into_par_iter()
            .map(|k| {
                support[k]
                    .iter()
                    .copied()
                    .filter(|&l| {
                        vmaps[k].iter().all(|&(mi, j)| {
                            j == NONE
                                || support[j as usize].binary_search(&images[mi as usize][l as usize]).is_ok()
                        })
                    })
                    .collect()
            })
            .collect();
        let changed = next.iter().zip(support.iter()).any(|(a, b)| a.len() != b.len());
        support.iter_mut().zip(next).for_each(|(s, n)| *s = n);
        if !changed {
            return Ok((maps, vmaps));
        }
    }
}
