//! The basis `U` of symmetry-preserving displacements of a sampling (thesis 3.4, the matrix `U`
//! of eq. 3.4).
//!
//! Each orbit contributes one column per basis vector `v` of its seed (three in general position,
//! fewer on invariant sets); the column's entry at sample `l` of the orbit is `O_l v`, zero
//! elsewhere, so every column touches exactly one orbit. For any coefficients `q`, `ū = U q`
//! satisfies `ū_{g(l)} = O_g ū_l` for every symmetry `g` mapping sample `l` to sample `g(l)`:
//! symmetry is built into the space, no constraint is ever solved for.

use motif_core::geometry::Point3;

use crate::mat3::mul_vec;
use crate::symmetric_sampling::SymmetricSampling;

/// The sparse basis `U` (`3·#S × dof`), stored per sample.
#[derive(Debug, Clone, PartialEq)]
pub struct SymmetricBasis {
    dof: usize,
    /// First column of each sample's orbit.
    col: Vec<u32>,
    /// Number of columns of each sample's orbit (0 to 3).
    cnt: Vec<u8>,
    /// `O_l v_c` for the orbit's basis vectors `v_c`.
    vecs: Vec<[Point3; 3]>,
}

impl SymmetricBasis {
    /// Builds `U` from the sampling's frames and orbit bases.
    pub fn new(sampling: &SymmetricSampling) -> SymmetricBasis {
        let n = sampling.len();
        let mut col = vec![0u32; n];
        let mut cnt = vec![0u8; n];
        let mut vecs = vec![[[0.0; 3]; 3]; n];
        let mut next = 0usize;
        for o in &sampling.orbits {
            for l in o.start..o.start + o.len {
                col[l] = next as u32;
                cnt[l] = o.basis.len() as u8;
                for (c, v) in o.basis.iter().enumerate() {
                    vecs[l][c] = mul_vec(&sampling.frames[l], *v);
                }
            }
            next += o.basis.len();
        }
        SymmetricBasis { dof: next, col, cnt, vecs }
    }

    /// Number of columns: the dimension of the space of symmetry-preserving displacements.
    pub fn dof(&self) -> usize {
        self.dof
    }

    /// Number of samples (rows / 3).
    pub fn num_samples(&self) -> usize {
        self.col.len()
    }

    /// The columns touching sample `l`: the first column index and the vectors `O_l v_c`.
    #[inline]
    pub fn entries(&self, l: usize) -> (usize, &[Point3]) {
        (self.col[l] as usize, &self.vecs[l][..self.cnt[l] as usize])
    }

    /// `ū = U q` (`q`: `dof`, `out`: `#S`).
    pub fn apply(&self, q: &[f64], out: &mut [Point3]) {
        for (l, o) in out.iter_mut().enumerate() {
            let (c0, v) = self.entries(l);
            let mut u = [0.0; 3];
            for (c, vc) in v.iter().enumerate() {
                let s = q[c0 + c];
                u[0] += s * vc[0];
                u[1] += s * vc[1];
                u[2] += s * vc[2];
            }
            *o = u;
        }
    }

    /// `out += Uᵀ r` (`r`: `#S`, `out`: `dof`).
    pub fn apply_transpose_add(&self, r: &[Point3], out: &mut [f64]) {
        for (l, rl) in r.iter().enumerate() {
            let (c0, v) = self.entries(l);
            for (c, vc) in v.iter().enumerate() {
                out[c0 + c] += vc[0] * rl[0] + vc[1] * rl[1] + vc[2] * rl[2];
            }
        }
    }
}
