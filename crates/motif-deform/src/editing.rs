//! Symmetry-preserving co-rotated Laplace editing (thesis 3.5).
//!
//! The deformation of the sampling minimises `E(ū) = |L(x̄ + ū) − δ'|² + α |Aū − a|²` (eq. 3.3)
//! over the symmetry-preserving displacements `ū = U q`. By the null-space method this is the
//! linear system (eq. 3.4)
//!
//! `Uᵀ(LᵀL + αAᵀA)U q = Uᵀ(αAᵀa + Lᵀ(δ' − L x̄))`,
//!
//! whose matrix only changes with the handle set: it is assembled and Cholesky-factorised once
//! per handle set (faer); each solve is two triangular solves. Small systems (fewer than
//! [`DENSE_DOF_LIMIT`] unknowns) use a dense factorisation; larger ones a sparse supernodal one
//! with a fill-reducing (AMD) ordering: every column of `U` touches one orbit, so `K` couples
//! only orbits whose samples are within two graph steps, and the dense factor of a few thousand
//! unknowns would be tens of megabytes read per solve. `A` selects
//! the handle samples, `a` lists their desired displacements `T_h x̄_i − x̄_i`.
//!
//! Co-rotation (after Au et al. 2006): the first solve uses the rest Laplace coordinates
//! `δ' = δ = L x̄` (linear Laplace editing); each further iteration rotates every `δ_i` by the best
//! rotation of sample `i`'s graph neighbourhood from rest to the current deformed sampling
//! (Sorkine–Alexa, see `laplace.rs`) and solves again. Exactness does not depend on the rotated
//! `δ'` being symmetric — every `U q` is symmetric — but it is, up to rounding, for symmetries of
//! the whole sampling graph, since the graph, the deformed sampling and the fitted rotations
//! commute with them (`R_{g(i)} = O_g R_i O_gᵀ`).
//!
//! Rotations are fitted once per orbit where a symmetry maps the seed's neighbourhood onto the
//! sample's (see [`RotationPlan`]); elsewhere per sample.
//!
//! Each solve starts from the rest state, so the result depends only on the handle transforms (not
//! on the previous frames).
//!
//! **α.** `α = alpha × s`, with `s` the mean diagonal entry of `LᵀL` (`deg² + deg`, about 200 for
//! the ~14 neighbours a Poisson-disc sample has within `2r`). With the default `alpha = 1000` the
//! handle term dominates every Laplace term by three orders of magnitude, so handles reach their
//! targets to about 10⁻³ of the edit's size (reported as the fit error) while the system stays well
//! conditioned (≲ 10¹¹) for a dense Cholesky in f64.

use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, Mat, Par, Side};
use serde::{Deserialize, Serialize};

use motif_core::geometry::{Mat4, Point3, transform_point};

use crate::annotation::RegionTest;
use crate::basis::SymmetricBasis;
use crate::error::{DeformError, Result};
use crate::handles::Handle;
use crate::laplace::{RotationPlan, SamplingGraph};
use crate::mat3::{IDENTITY3, Mat3, mul_vec};

/// Options of co-rotated Laplace editing (thesis 3.5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct EditingOptions {
    /// α of eq. 3.3, the weight of the handle constraints, relative to the mean diagonal of `LᵀL`
    /// (see the module docs); default 1000.
    pub alpha: f64,
    /// Number of linear solves per frame: the first with the rest Laplace coordinates, each
    /// further one after co-rotating them (thesis: "usually 5–10"); default 5.
    pub iterations: usize,
    /// Tikhonov weight on `|ū|²`, relative like `alpha`: keeps parts of the sampling that no
    /// handle reaches at rest instead of failing; default 1e-8 (negligible elsewhere). With 0,
    /// such handle sets fail with [`DeformError::Unconstrained`].
    pub regularization: f64,
}

impl Default for EditingOptions {
    fn default() -> Self {
        EditingOptions { alpha: 1e3, iterations: 5, regularization: 1e-8 }
    }
}

impl EditingOptions {
    pub(crate) fn validate(&self) -> Result<()> {
        if !(self.alpha.is_finite() && self.alpha > 0.0) {
            return Err(DeformError::InvalidOption {
                name: "editing.alpha",
                message: format!("must be positive, got {}", self.alpha),
            });
        }
        if self.iterations == 0 || self.iterations > 1000 {
            return Err(DeformError::InvalidOption {
                name: "editing.iterations",
                message: format!("must lie in 1..=1000, got {}", self.iterations),
            });
        }
        if !(self.regularization.is_finite() && self.regularization >= 0.0) {
            return Err(DeformError::InvalidOption {
                name: "editing.regularization",
                message: format!("must be >= 0, got {}", self.regularization),
            });
        }
        Ok(())
    }
}

/// Selects the samples of each handle. A sample belongs to a handle when its position lies in the
/// handle's box / ball (enlarged by `margin`), or, for `vertices` / `faces` regions, when its
/// nearest mesh vertex does. Errors: no handles, a region without vertices, a handle without
/// samples, two handles sharing a sample.
pub(crate) fn select_handle_samples(
    mesh: &motif_core::TriMesh,
    samples: &[Point3],
    radius: f64,
    handles: &[Handle],
    margin: f64,
) -> Result<(Vec<Vec<u32>>, Vec<Vec<u32>>)> {
    if handles.is_empty() {
        return Err(DeformError::NoHandles);
    }
    let tests: Vec<RegionTest> = handles
        .iter()
        .enumerate()
        .map(|(h, hd)| RegionTest::compile(&hd.region, mesh, margin, &format!("handle {h}")))
        .collect::<Result<_>>()?;
    let need_nearest = tests.iter().any(RegionTest::needs_nearest);
    let nearest: Vec<Option<usize>> = if need_nearest {
        let tree = motif_core::spatial::KdTree::new(&mesh.positions)?;
        samples.iter().map(|p| Some(tree.nearest(*p).index)).collect()
    } else {
        vec![None; samples.len()]
    };
    let mut owner: Vec<Option<usize>> = vec![None; samples.len()];
    let mut out = Vec::with_capacity(handles.len());
    let mut handle_vertices = Vec::with_capacity(handles.len());
    for (h, t) in tests.iter().enumerate() {
        let held: Vec<u32> = (0..mesh.num_vertices())
            .filter(|&v| t.contains_vertex(v, mesh.positions[v]))
            .map(|v| v as u32)
            .collect();
        let vertices = held.len();
        if vertices == 0 {
            return Err(DeformError::EmptyRegion { what: format!("handle {h}") });
        }
        let mut sel = Vec::new();
        for (i, p) in samples.iter().enumerate() {
            if t.contains_point(*p, nearest[i]) {
                if let Some(first) = owner[i] {
                    return Err(DeformError::OverlappingHandles { first, second: h, position: *p });
                }
                owner[i] = Some(h);
                sel.push(i as u32);
            }
        }
        if sel.is_empty() {
            return Err(DeformError::HandleSelectsNoSample { handle: h, vertices, radius });
        }
        out.push(sel);
        handle_vertices.push(held);
    }
    Ok((out, handle_vertices))
}

/// Systems with fewer unknowns are factorised densely, larger ones sparsely.
pub const DENSE_DOF_LIMIT: usize = 400;

/// A Cholesky factor of `K = Uᵀ(LᵀL + αAᵀA + εI)U`.
#[derive(Debug, Clone)]
enum Factor {
    /// Lower factor `L_K` and its transpose (column-major, for a fast backward solve).
    Dense { l: Mat<f64>, lt: Mat<f64> },
    /// Supernodal or simplicial factor with its fill-reducing permutation.
    Sparse { symbolic: Arc<SymbolicCholesky<usize>>, values: Vec<f64> },
}

/// The factorised reduced system of one handle set.
#[derive(Debug, Clone)]
pub(crate) struct HandleSystem {
    /// Samples of each handle.
    pub(crate) samples: Vec<Vec<u32>>,
    factor: Factor,
    /// Absolute α.
    pub(crate) alpha: f64,
}

/// Scratch memory of the sparse triangular solves, allocated once per handle set.
pub(crate) struct Scratch {
    buf: MemBuffer,
    req: StackReq,
}

impl Scratch {
    fn new(req: StackReq) -> Scratch {
        Scratch { buf: MemBuffer::new(req), req }
    }
}

impl Clone for Scratch {
    fn clone(&self) -> Self {
        Scratch::new(self.req)
    }
}

impl std::fmt::Debug for Scratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scratch").field("req", &self.req).finish()
    }
}

/// Accumulates the lower triangle of `K`, densely or as triplets.
enum Assembly {
    Dense(Mat<f64>),
    Sparse(Vec<Triplet<usize, usize, f64>>),
}

impl Assembly {
    /// `K v` from the lower triangle.
    fn mul(&self, v: &[f64], d: usize) -> Vec<f64> {
        let mut out = vec![0.0; d];
        match self {
            Assembly::Dense(m) => {
                for c in 0..d {
                    for r in c..d {
                        let x = m[(r, c)];
                        out[r] += x * v[c];
                        if r != c {
                            out[c] += x * v[r];
                        }
                    }
                }
            }
            Assembly::Sparse(t) => {
                for e in t {
                    out[e.row] += e.val * v[e.col];
                    if e.row != e.col {
                        out[e.col] += e.val * v[e.row];
                    }
                }
            }
        }
        out
    }

    /// Largest diagonal entry.
    fn max_diag(&self, d: usize) -> f64 {
        match self {
            Assembly::Dense(m) => (0..d).map(|i| m[(i, i)]).fold(0.0, f64::max),
            Assembly::Sparse(t) => {
                let mut diag = vec![0.0; d];
                for e in t.iter().filter(|e| e.row == e.col) {
                    diag[e.row] += e.val;
                }
                diag.into_iter().fold(0.0, f64::max)
            }
        }
    }

    #[inline]
    fn add(&mut self, row: usize, col: usize, v: f64) {
        match self {
            Assembly::Dense(m) => m[(row, col)] += v,
            Assembly::Sparse(t) => t.push(Triplet { row, col, val: v }),
        }
    }
}

impl HandleSystem {
    /// Assembles `K` (dense) and factorises it.
    pub(crate) fn new(
        graph: &SamplingGraph,
        basis: &SymmetricBasis,
        handle_samples: Vec<Vec<u32>>,
        seeds: &[Point3],
        options: &EditingOptions,
    ) -> Result<HandleSystem> {
        options.validate()?;
        let d = basis.dof();
        let n = basis.num_samples();
        let scale = graph.energy_scale();
        let alpha = options.alpha * scale;
        let eps = options.regularization * scale;
        let mut k = if d < DENSE_DOF_LIMIT {
            Assembly::Dense(Mat::zeros(d, d))
        } else {
            Assembly::Sparse(Vec::new())
        };
        // Uᵀ LᵀL U = Σ_i M_iᵀ M_i with M_i the block row i of L U.
        let mut row: Vec<(usize, Point3)> = Vec::new();
        for i in 0..n {
            row.clear();
            let nb = graph.neighbours(i);
            let push = |row: &mut Vec<(usize, Point3)>, j: usize, c: f64| {
                let (c0, v) = basis.entries(j);
                for (t, vt) in v.iter().enumerate() {
                    row.push((c0 + t, [c * vt[0], c * vt[1], c * vt[2]]));
                }
            };
            push(&mut row, i, nb.len() as f64);
            for &j in nb {
                push(&mut row, j as usize, -1.0);
            }
            row.sort_unstable_by_key(|e| e.0);
            let mut m = 0;
            for e in 0..row.len() {
                if m > 0 && row[m - 1].0 == row[e].0 {
                    let v = row[e].1;
                    let w = &mut row[m - 1].1;
                    w[0] += v[0];
                    w[1] += v[1];
                    w[2] += v[2];
                } else {
                    row[m] = row[e];
                    m += 1;
                }
            }
            row.truncate(m);
            for a in 0..row.len() {
                let (ca, va) = row[a];
                for &(cb, vb) in &row[a..] {
                    let x = va[0] * vb[0] + va[1] * vb[1] + va[2] * vb[2];
                    k.add(cb, ca, x);
                }
            }
        }
        // α UᵀAᵀAU + ε UᵀU: per sample, U_iᵀ U_i.
        let mut on_handle = vec![false; n];
        for h in &handle_samples {
            for &i in h {
                on_handle[i as usize] = true;
            }
        }
        for i in 0..n {
            let w = if on_handle[i] { alpha + eps } else { eps };
            if w == 0.0 {
                continue;
            }
            let (c0, v) = basis.entries(i);
            for a in 0..v.len() {
                for b in a..v.len() {
                    let x = v[a][0] * v[b][0] + v[a][1] * v[b][1] + v[a][2] * v[b][2];
                    k.add(c0 + b, c0 + a, w * x);
                }
            }
        }
        // Only the lower triangle was filled.
        let orbit_seed_of_col = |c: usize| -> Point3 {
            // Columns are numbered by orbit: find the sample owning column c.
            (0..n)
                .find(|&i| {
                    let (c0, v) = basis.entries(i);
                    c >= c0 && c < c0 + v.len()
                })
                .map(|i| seeds[i])
                .unwrap_or([f64::NAN; 3])
        };
        let singular = |index: usize| -> DeformError {
            if options.regularization == 0.0 {
                DeformError::Unconstrained { components: 1, position: orbit_seed_of_col(index) }
            } else {
                DeformError::Factorization(format!("non-positive pivot at column {index}"))
            }
        };
        let mut k_copy: Option<Assembly> = None;
        let factor = match k {
            Assembly::Dense(k) => {
                if options.regularization == 0.0 {
                    k_copy = Some(Assembly::Dense(k.clone()));
                }
                let max_diag = (0..d).map(|i| k[(i, i)]).fold(0.0, f64::max);
                let l = match k.llt(Side::Lower) {
                    Ok(l) => l.L().to_owned(),
                    Err(faer::linalg::solvers::LltError::NonPositivePivot { index }) => {
                        return Err(singular(index));
                    }
                };
                // A numerically singular K can factor with tiny pivots: treat it as singular.
                let tiny: Vec<usize> =
                    (0..d).filter(|&i| l[(i, i)] * l[(i, i)] <= 1e-14 * max_diag).collect();
                if let Some(&first) = tiny.first() {
                    return Err(DeformError::Unconstrained {
                        components: tiny.len(),
                        position: orbit_seed_of_col(first),
                    });
                }
                let lt = l.transpose().to_owned();
                Factor::Dense { l, lt }
            }
            Assembly::Sparse(triplets) => {
                let a = SparseColMat::<usize, f64>::try_new_from_triplets(d, d, &triplets)
                    .map_err(|e| DeformError::Factorization(format!("{e:?}")))?;
                let symbolic = factorize_symbolic_cholesky(
                    a.symbolic(),
                    Side::Lower,
                    SymmetricOrdering::Amd,
                    CholeskySymbolicParams::default(),
                )
                .map_err(|e| DeformError::Factorization(format!("{e:?}")))?;
                let mut values = vec![0.0; symbolic.len_val()];
                let mut mem = MemBuffer::new(
                    symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
                );
                let r = symbolic.factorize_numeric_llt(
                    &mut values,
                    a.as_ref(),
                    Side::Lower,
                    LltRegularization::default(),
                    Par::Seq,
                    MemStack::new(&mut mem),
                    Default::default(),
                );
                if let Err(faer::linalg::cholesky::llt::factor::LltError::NonPositivePivot { index }) = r {
                    return Err(singular(index));
                }
                if options.regularization == 0.0 {
                    k_copy = Some(Assembly::Sparse(triplets));
                }
                Factor::Sparse { symbolic: Arc::new(symbolic), values }
            }
        };
        let sys = HandleSystem { samples: handle_samples, factor, alpha };
        // Without regularisation, a singular K may still factor with rounding-level pivots:
        // estimate its smallest eigenvalue by inverse iteration and refuse near-singular systems.
        if let Some(k) = k_copy
            && d > 0
        {
            let (lambda, x) = sys.smallest_eigenpair(&k, d);
            let max_diag = k.max_diag(d);
            if lambda.is_nan() || lambda <= 1e-13 * max_diag {
                let col = (0..d).max_by(|&a, &b| x[a].abs().total_cmp(&x[b].abs())).unwrap_or(0);
                return Err(DeformError::Unconstrained { components: 1, position: orbit_seed_of_col(col) });
            }
        }
        Ok(sys)
    }

    /// Estimate of the smallest eigenvalue of `K` (and its eigenvector) by a few steps of inverse
    /// iteration with the factor.
    fn smallest_eigenpair(&self, k: &Assembly, d: usize) -> (f64, Vec<f64>) {
        let mut scratch = self.scratch();
        let mut x = Mat::<f64>::from_fn(d, 1, |i, _| 1.0 + ((i * 7919) % 101) as f64 / 101.0);
        let mut lambda = f64::INFINITY;
        for _ in 0..6 {
            let n = (0..d).map(|i| x[(i, 0)] * x[(i, 0)]).sum::<f64>().sqrt();
            if !(n > 0.0 && n.is_finite()) {
                return (0.0, vec![0.0; d]);
            }
            for i in 0..d {
                x[(i, 0)] /= n;
            }
            let v: Vec<f64> = (0..d).map(|i| x[(i, 0)]).collect();
            let kv = k.mul(&v, d);
            lambda = v.iter().zip(&kv).map(|(a, b)| a * b).sum();
            self.solve_in_place(&mut x, &mut scratch);
        }
        ((lambda).max(0.0), (0..d).map(|i| x[(i, 0)]).collect())
    }

    /// Scratch memory needed by [`HandleSystem::solve_in_place`].
    pub(crate) fn scratch(&self) -> Option<Scratch> {
        match &self.factor {
            Factor::Dense { .. } => None,
            Factor::Sparse { symbolic, .. } => {
                Some(Scratch::new(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq)))
            }
        }
    }

    /// Solves `K q = rhs` in place (allocation-free; `scratch` from [`HandleSystem::scratch`]).
    fn solve_in_place(&self, rhs: &mut Mat<f64>, scratch: &mut Option<Scratch>) {
        if rhs.nrows() == 0 {
            return;
        }
        match (&self.factor, scratch) {
            (Factor::Dense { l, lt }, _) => {
                solve_lower_triangular_in_place(l.as_ref(), rhs.as_mut(), Par::Seq);
                solve_upper_triangular_in_place(lt.as_ref(), rhs.as_mut(), Par::Seq);
            }
            (Factor::Sparse { symbolic, values }, Some(s)) => {
                LltRef::new(symbolic, values).solve_in_place_with_conj(
                    Conj::No,
                    rhs.as_mut(),
                    Par::Seq,
                    MemStack::new(&mut s.buf),
                );
            }
            (Factor::Sparse { .. }, None) => {}
        }
    }

    /// True when the factor is sparse.
    pub(crate) fn is_sparse(&self) -> bool {
        matches!(self.factor, Factor::Sparse { .. })
    }
}

/// Buffers of the per-frame solve, allocated once per handle set.
#[derive(Debug, Clone)]
pub(crate) struct Workspace {
    q: Mat<f64>,
    b_handles: Vec<f64>,
    pub(crate) ubar: Vec<Point3>,
    deformed: Vec<Point3>,
    rotations: Vec<Mat3>,
    resid: Vec<Point3>,
    lresid: Vec<Point3>,
    /// Per handle: largest and summed squared distance of its samples to their targets.
    pub(crate) fit_max: Vec<f64>,
    pub(crate) fit_sq: Vec<f64>,
    scratch: Option<Scratch>,
}

impl Workspace {
    pub(crate) fn new(
        dof: usize,
        samples: usize,
        handles: usize,
        system: Option<&HandleSystem>,
    ) -> Workspace {
        Workspace {
            scratch: system.and_then(HandleSystem::scratch),
            q: Mat::zeros(dof, 1),
            b_handles: vec![0.0; dof],
            ubar: vec![[0.0; 3]; samples],
            deformed: vec![[0.0; 3]; samples],
            rotations: vec![IDENTITY3; samples],
            resid: vec![[0.0; 3]; samples],
            lresid: vec![[0.0; 3]; samples],
            fit_max: vec![0.0; handles],
            fit_sq: vec![0.0; handles],
        }
    }
}

/// One frame of co-rotated Laplace editing: fills `ws.ubar` with the displacement of the sampling.
/// `rest` are the sample positions `x̄`, `delta = L x̄`. Allocation-free.
pub(crate) fn solve_frame(
    sys: &HandleSystem,
    graph: &SamplingGraph,
    plan: &RotationPlan,
    frames: &[Mat3],
    basis: &SymmetricBasis,
    rest: &[Point3],
    delta: &[Point3],
    transforms: &[Mat4],
    iterations: usize,
    ws: &mut Workspace,
) {
    // αUᵀAᵀa, fixed for the frame.
    ws.b_handles.iter_mut().for_each(|b| *b = 0.0);
    for (h, samples) in sys.samples.iter().enumerate() {
        let t = &transforms[h];
        for &i in samples {
            let i = i as usize;
            let target = transform_point(t, rest[i]);
            let a = [
                sys.alpha * (target[0] - rest[i][0]),
                sys.alpha * (target[1] - rest[i][1]),
                sys.alpha * (target[2] - rest[i][2]),
            ];
            let (c0, v) = basis.entries(i);
            for (c, vc) in v.iter().enumerate() {
                ws.b_handles[c0 + c] += vc[0] * a[0] + vc[1] * a[1] + vc[2] * a[2];
            }
        }
    }
    let d = basis.dof();
    for it in 0..iterations {
        for c in 0..d {
            ws.q[(c, 0)] = ws.b_handles[c];
        }
        if it > 0 {
            // δ' − δ with δ'_i = R_i δ_i, then Lᵀ(δ' − δ) (L is symmetric).
            plan.fit_rotations(graph, frames, rest, &ws.deformed, &mut ws.rotations);
            for i in 0..rest.len() {
                let r = mul_vec(&ws.rotations[i], delta[i]);
                ws.resid[i] = [r[0] - delta[i][0], r[1] - delta[i][1], r[2] - delta[i][2]];
            }
            graph.apply_laplacian(&ws.resid, &mut ws.lresid);
            for (l, rl) in ws.lresid.iter().enumerate() {
                let (c0, v) = basis.entries(l);
                for (c, vc) in v.iter().enumerate() {
                    ws.q[(c0 + c, 0)] += vc[0] * rl[0] + vc[1] * rl[1] + vc[2] * rl[2];
                }
            }
        }
        sys.solve_in_place(&mut ws.q, &mut ws.scratch);
        for (l, o) in ws.ubar.iter_mut().enumerate() {
            let (c0, v) = basis.entries(l);
            let mut u = [0.0; 3];
            for (c, vc) in v.iter().enumerate() {
                let s = ws.q[(c0 + c, 0)];
                u[0] += s * vc[0];
                u[1] += s * vc[1];
                u[2] += s * vc[2];
            }
            *o = u;
        }
        for i in 0..rest.len() {
            let (x, u) = (rest[i], ws.ubar[i]);
            ws.deformed[i] = [x[0] + u[0], x[1] + u[1], x[2] + u[2]];
        }
    }
    for (h, samples) in sys.samples.iter().enumerate() {
        let t = &transforms[h];
        let (mut m, mut s2) = (0.0f64, 0.0);
        for &i in samples {
            let i = i as usize;
            let target = transform_point(t, rest[i]);
            let y = ws.deformed[i];
            let e2 = (y[0] - target[0]).powi(2) + (y[1] - target[1]).powi(2) + (y[2] - target[2]).powi(2);
            m = m.max(e2.sqrt());
            s2 += e2;
        }
        ws.fit_max[h] = m;
        ws.fit_sq[h] = s2;
    }
}
