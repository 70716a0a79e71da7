//! The sampling graph and its Laplace matrix (thesis 3.5), and the per-sample rotations of
//! co-rotated Laplace editing.
//!
//! Any two distinct samples closer than `2r` are joined by an edge. `L` is the graph's
//! Laplace–Kirchhoff matrix, degree minus adjacency (positive semi-definite; constant fields per
//! connected component are its null space), applied to each coordinate (the `3n × 3n` extension
//! `L ⊗ I₃`). The Laplace coordinates are `δ = L x̄`: `δ_i = Σ_{j∈N(i)} (x̄_i − x̄_j)`.

use rayon::prelude::*;

use motif_core::geometry::Point3;
use motif_core::spatial::KdTree;

use crate::error::Result;
use crate::mat3::{IDENTITY3, Mat3};

/// The sampling graph in CSR form.
#[derive(Debug, Clone, PartialEq)]
pub struct SamplingGraph {
    start: Vec<u32>,
    adj: Vec<u32>,
}

impl SamplingGraph {
    /// Joins every pair of distinct samples closer than `2 · radius`.
    pub fn new(positions: &[Point3], radius: f64) -> Result<SamplingGraph> {
        let n = positions.len();
        if n == 0 {
            return Ok(SamplingGraph { start: vec![0], adj: Vec::new() });
        }
        let tree = KdTree::new(positions)?;
        let reach = 2.0 * radius;
        let lists: Vec<Vec<u32>> = positions
            .par_iter()
            .enumerate()
            .map(|(i, p)| {
                let mut v: Vec<u32> = tree
                    .within_unsorted(*p, reach)
                    .into_iter()
                    .filter(|nb| nb.index != i && nb.distance < reach)
                    .map(|nb| nb.index as u32)
                    .collect();
                v.sort_unstable();
                v
            })
            .collect();
        let mut start = Vec::with_capacity(n + 1);
        start.push(0u32);
        let mut adj = Vec::new();
        for l in lists {
            adj.extend_from_slice(&l);
            start.push(adj.len() as u32);
        }
        Ok(SamplingGraph { start, adj })
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.start.len() - 1
    }

    /// True when the graph has no vertex.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Neighbours of sample `i`, ascending.
    #[inline]
    pub fn neighbours(&self, i: usize) -> &[u32] {
        &self.adj[self.start[i] as usize..self.start[i + 1] as usize]
    }

    /// Number of undirected edges.
    pub fn num_edges(&self) -> usize {
        self.adj.len() / 2
    }

    /// Mean of the diagonal of `LᵀL` (`deg_i² + deg_i`): the scale of the Laplace energy, used to
    /// make α and the regularisation relative (at least 1).
    pub fn energy_scale(&self) -> f64 {
        let n = self.len();
        if n == 0 {
            return 1.0;
        }
        let s: f64 = (0..n)
            .map(|i| {
                let d = self.neighbours(i).len() as f64;
                d * d + d
            })
            .sum();
        (s / n as f64).max(1.0)
    }

    /// `out = L x` (per coordinate).
    pub fn apply_laplacian(&self, x: &[Point3], out: &mut [Point3]) {
        for (i, o) in out.iter_mut().enumerate() {
            let nb = self.neighbours(i);
            let d = nb.len() as f64;
            let mut s = [d * x[i][0], d * x[i][1], d * x[i][2]];
            for &j in nb {
                let xj = x[j as usize];
                s[0] -= xj[0];
                s[1] -= xj[1];
                s[2] -= xj[2];
            }
            *o = s;
        }
    }

    /// The rotation of sample `i` alone (see [`SamplingGraph::fit_rotations`]).
    fn fit_rotation(&self, i: usize, rest: &[Point3], deformed: &[Point3]) -> Mat3 {
        let nb = self.neighbours(i);
        if nb.is_empty() {
            return IDENTITY3;
        }
        let mut s = nalgebra::Matrix3::<f64>::zeros();
        for &j in nb {
            let j = j as usize;
            let e = [rest[j][0] - rest[i][0], rest[j][1] - rest[i][1], rest[j][2] - rest[i][2]];
            let f = [
                deformed[j][0] - deformed[i][0],
                deformed[j][1] - deformed[i][1],
                deformed[j][2] - deformed[i][2],
            ];
            for a in 0..3 {
                for b in 0..3 {
                    s[(a, b)] += e[a] * f[b];
                }
            }
        }
        best_rotation(s)
    }

    /// For each sample, the rotation `R_i` that best maps its rest neighbourhood onto the deformed
    /// one, `argmin Σ_j |(y_j − y_i) − R (x_j − x_i)|²` (Sorkine & Alexa 2007): with the
    /// covariance `S = Σ_j (x_j − x_i)(y_j − y_i)ᵀ = U Σ Vᵀ`, `R = V Uᵀ`, and when `det R < 0`
    /// the column of `U` of the smallest singular value is negated (a rotation, never a
    /// reflection). Samples without neighbours get the identity. Runs in parallel over samples.
    pub fn fit_rotations(&self, rest: &[Point3], deformed: &[Point3], out: &mut [Mat3]) {
        let fit = |(i, r): (usize, &mut Mat3)| *r = self.fit_rotation(i, rest, deformed);
        if out.len() >= 512 {
            out.par_iter_mut().enumerate().with_min_len(128).for_each(fit);
        } else {
            out.iter_mut().enumerate().for_each(fit);
        }
    }
}

/// The rotation `V Uᵀ` of `S = U Σ Vᵀ`, reflection-fixed; the identity for a zero or non-finite
/// covariance.
pub(crate) fn best_rotation(s: nalgebra::Matrix3<f64>) -> Mat3 {
    if !s.iter().all(|x| x.is_finite()) || s.iter().all(|x| *x == 0.0) {
        return IDENTITY3;
    }
    let svd = s.svd(true, true);
    let (Some(mut u), Some(v_t)) = (svd.u, svd.v_t) else { return IDENTITY3 };
    let v = v_t.transpose();
    let mut r = v * u.transpose();
    if r.determinant() < 0.0 {
        let k =
            (0..3).min_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b])).unwrap_or(2);
        for row in 0..3 {
            u[(row, k)] = -u[(row, k)];
        }
        r = v * u.transpose();
    }
    [[r[(0, 0)], r[(0, 1)], r[(0, 2)]], [r[(1, 0)], r[(1, 1)], r[(1, 2)]], [r[(2, 0)], r[(2, 1)], r[(2, 2)]]]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mat3::{max_abs_diff, mul_vec};

    #[test]
    fn laplacian_of_a_constant_is_zero_and_rotations_are_recovered() {
        let pts: Vec<Point3> = (0..30)
            .map(|i| {
                let t = i as f64 * 0.7;
                [t.cos(), t.sin(), 0.1 * i as f64]
            })
            .collect();
        let g = SamplingGraph::new(&pts, 0.6).unwrap();
        let mut out = vec![[0.0; 3]; pts.len()];
        g.apply_laplacian(&vec![[1.0, 2.0, 3.0]; pts.len()], &mut out);
        assert!(out.iter().all(|v| v.iter().all(|c| c.abs() < 1e-12)));
        let r = motif_core::geometry::rotation_about_axis([1.0, 2.0, 0.5], 1.3);
        let moved: Vec<Point3> = pts.iter().map(|p| mul_vec(&r, *p)).collect();
        let mut rots = vec![IDENTITY3; pts.len()];
        g.fit_rotations(&pts, &moved, &mut rots);
        for (i, q) in rots.iter().enumerate() {
            if !g.neighbours(i).is_empty() {
                assert!(max_abs_diff(q, &r) < 1e-9, "{q:?}");
            }
        }
    }

    #[test]
    fn reflections_become_rotations() {
        let mut s = nalgebra::Matrix3::<f64>::identity();
        s[(2, 2)] = -0.5;
        let r = best_rotation(s);
        let m = nalgebra::Matrix3::from_fn(|i, j| r[i][j]);
        assert!((m.determinant() - 1.0).abs() < 1e-12);
    }
}

/// Which samples can take their rotation from their orbit's seed: sample `l` with frame `O_l`
/// qualifies when `O_l`'s motion maps the seed's graph neighbourhood exactly onto `l`'s (as
/// samples of the same orbits, with displacements related by `O_l`). Then the covariance of `l` is
/// `O_l S_seed O_lᵀ` and its best rotation `R_l = O_l R_seed O_lᵀ`: one SVD per orbit under a
/// symmetry of the whole sampling graph (thesis 3.4, "redundancy-free").
#[derive(Debug, Clone, PartialEq)]
pub struct RotationPlan {
    /// `source[l]`: the seed to copy from, or `u32::MAX` when `l` fits its own rotation.
    source: Vec<u32>,
    /// Samples that fit their own rotation.
    own: Vec<u32>,
}

impl RotationPlan {
    /// Builds the plan from the sampling's orbits, frames and the graph.
    pub fn new(
        graph: &SamplingGraph,
        sampling: &crate::symmetric_sampling::SymmetricSampling,
    ) -> Result<RotationPlan> {
        let n = sampling.len();
        let mut source = vec![u32::MAX; n];
        if n > 0 && !sampling.orbits.iter().all(|o| o.len == 1) {
            let tree = KdTree::new(&sampling.positions)?;
            let tol = sampling.doublet_distance.max(1e-12);
            let found: Vec<bool> = (0..n)
                .into_par_iter()
                .map(|l| {
                    let o = &sampling.orbits[sampling.orbit_of[l] as usize];
                    let s = o.start;
                    if l == s || graph.neighbours(l).len() != graph.neighbours(s).len() {
                        return false;
                    }
                    let ol = &sampling.frames[l];
                    // The seed's frame is the identity; x_l = g(x_s) with linear part O_l.
                    let t = {
                        let m = crate::mat3::mul_vec(ol, sampling.positions[s]);
                        let p = sampling.positions[l];
                        [p[0] - m[0], p[1] - m[1], p[2] - m[2]]
                    };
                    let mut image = Vec::with_capacity(graph.neighbours(s).len());
                    for &j in graph.neighbours(s) {
                        let j = j as usize;
                        let m = crate::mat3::mul_vec(ol, sampling.positions[j]);
                        let q = [m[0] + t[0], m[1] + t[1], m[2] + t[2]];
                        let hit = tree.within_unsorted(q, tol).into_iter().find(|c| {
                            let c = c.index;
                            sampling.orbit_of[c] == sampling.orbit_of[j] && {
                                let oj = &sampling.orbits[sampling.orbit_of[j] as usize];
                                let olj = crate::mat3::mul(ol, &sampling.frames[j]);
                                oj.basis.iter().all(|v| {
                                    let a = crate::mat3::mul_vec(&sampling.frames[c], *v);
                                    let b = crate::mat3::mul_vec(&olj, *v);
                                    (a[0] - b[0]).abs() + (a[1] - b[1]).abs() + (a[2] - b[2]).abs() < 1e-9
                                })
                            }
                        });
                        match hit {
                            Some(c) => image.push(c.index as u32),
                            None => return false,
                        }
                    }
                    image.sort_unstable();
                    image.as_slice() == graph.neighbours(l)
                })
                .collect();
            for l in 0..n {
                if found[l] {
                    source[l] = sampling.orbits[sampling.orbit_of[l] as usize].start as u32;
                }
            }
        }
        let own = (0..n as u32).filter(|&l| source[l as usize] == u32::MAX).collect();
        Ok(RotationPlan { source, own })
    }

    /// Number of samples that fit their own rotation (SVDs per iteration).
    pub fn own_fits(&self) -> usize {
        self.own.len()
    }

    /// [`SamplingGraph::fit_rotations`] following the plan: own fits (in parallel), then
    /// `R_l = O_l R_seed O_lᵀ` for the others. Allocation-free.
    pub fn fit_rotations(
        &self,
        graph: &SamplingGraph,
        frames: &[Mat3],
        rest: &[Point3],
        deformed: &[Point3],
        out: &mut [Mat3],
    ) {
        let fit_one = |i: usize| graph.fit_rotation(i, rest, deformed);
        if self.own.len() >= 256 {
            out.par_iter_mut()
                .enumerate()
                .with_min_len(64)
                .filter(|(i, _)| self.source[*i] == u32::MAX)
                .for_each(|(i, r)| *r = fit_one(i));
        } else {
            for &i in &self.own {
                out[i as usize] = fit_one(i as usize);
            }
        }
        for l in 0..out.len() {
            let s = self.source[l];
            if s != u32::MAX {
                let o = &frames[l];
                out[l] = crate::mat3::mul(&crate::mat3::mul(o, &out[s as usize]), &crate::mat3::transpose(o));
            }
        }
    }
}
