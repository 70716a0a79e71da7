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

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use motif_core::TriMesh;
use motif_core::geometry::{Mat4, Point3, dist, dist2, mat4_mul, transform_point};
use motif_core::spatial::KdTree;

use crate::annotation::{ResolvedAnnotation, ResolvedKind};
use crate::error::{DeformError, Result};
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
}

impl Default for LiftOptions {
    fn default() -> Self {
        LiftOptions { sigma: 1.0, cutoff: 1e-3, support: LiftSupport::Equivariant }
    }
}

/// The lifting matrix `W` (`#V × #S`, rows sum to 1).
#[derive(Debug, Clone, PartialEq)]
pub struct Lifting {
    start: Vec<usize>,
    cols: Vec<u32>,
    weights: Vec<f64>,
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
        if options.support == LiftSupport::Equivariant && !resolved.symmetries.is_empty() {
            equivariant_supports(mesh, resolved, sampling, &tree, &mut support)?;
        }
        let n = sampling.len();
        let rows: Vec<(Vec<(u32, f64)>, bool)> = positions
            .par_iter()
            .zip(&support)
            .map(|(&x, sup)| {
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
        let mut start = Vec::with_capacity(positions.len() + 1);
        start.push(0);
        let nnz: usize = rows.iter().map(|r| r.0.len()).sum();
        let mut cols = Vec::with_capacity(nnz);
        let mut weights = Vec::with_capacity(nnz);
        let mut fallback = 0;
        let mut fallback_rows = Vec::with_capacity(positions.len());
        for (row, fb) in rows {
            fallback += fb as usize;
            fallback_rows.push(fb);
            for (l, w) in row {
                cols.push(l);
                weights.push(w);
            }
            start.push(cols.len());
        }
        Ok(Lifting { start, cols, weights, fallback, fallback_rows })
    }

    /// Number of non-zero weights.
    pub fn nnz(&self) -> usize {
        self.cols.len()
    }

    /// Number of vertices (rows).
    pub fn num_vertices(&self) -> usize {
        self.start.len() - 1
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

    /// Row `k`: sample indices and normalised weights.
    pub fn row(&self, k: usize) -> (&[u32], &[f64]) {
        let r = self.start[k]..self.start[k + 1];
        (&self.cols[r.clone()], &self.weights[r])
    }

    /// `out = rest + W ū`, parallel over vertices; allocation-free.
    pub fn lift(&self, ubar: &[Point3], rest: &[Point3], out: &mut [Point3]) {
        out.par_iter_mut().with_min_len(2048).enumerate().for_each(|(k, o)| {
            let (a, b) = (self.start[k], self.start[k + 1]);
            let mut u = [0.0; 3];
            for (l, w) in self.cols[a..b].iter().zip(&self.weights[a..b]) {
                let v = ubar[*l as usize];
                u[0] += w * v[0];
                u[1] += w * v[1];
                u[2] += w * v[2];
            }
            let x = rest[k];
            *o = [x[0] + u[0], x[1] + u[1], x[2] + u[2]];
        });
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
) -> Result<()> {
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
            return Ok(());
        }
    }
}
