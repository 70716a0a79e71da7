//! Principal curvatures and directions by degree-2 jet fitting (Cazals & Pouget, "Estimating
//! differential quantities using polynomial fitting of osculating jets", CAGD 2005).
//!
//! For every point `p`:
//! 1. its neighbourhood `N(p)` ([`Neighbourhood`]: k nearest, the point included, a ball, or
//!    mesh edge rings);
//! 2. a fitting frame `(x, y, z)` at `p`: PCA of `N(p)` (`z` = least-variance axis) or the given
//!    normal ([`FittingFrame`]); `z` is turned to agree with the reference normal;
//! 3. a (weighted) least-squares fit of the height function
//!    `z = a x² + b xy + c y² + d x + e y + f` in that frame, with coordinates divided by the
//!    neighbourhood radius `h` so the six monomials are of order one (the precondition of
//!    Cazals–Pouget §4.2; the normal matrix is then well conditioned for any input scale);
//! 4. the shape operator of the *fitted* surface at the parameter origin, from its first and second
//!    fundamental forms, `I = [[1+d², de], [de, 1+e²]]`, `II = [[2a, b], [b, 2c]] / √(1+d²+e²)`,
//!    `W = I⁻¹ II`, whose eigenvalues and eigenvectors give κ and t. Keeping the first-order
//!    terms `d, e` yields the curvature of the fitted surface itself, so a fitting plane tilted
//!    against the true tangent plane (PCA frames always are, slightly; the tests tilt it by 15°)
//!    costs only the fit's truncation error; reading κ off `2a, 2c` alone would be biased by the
//!    factor `(1+d²)^(3/2)` along the tilt.
//!
//! The thesis (§5.4) estimates curvature by a quadratic moving-least-squares fit over a ball of
//! radius 4ε and the Cazals–Pouget curvature tensor; `Neighbourhood::Radius(4.0 * eps)` reproduces
//! that set-up, the default `Knn(15)` matches CGAL's `Monge_via_jet_fitting` example.
//!
//! **Sign convention.** Curvatures are measured with respect to the *reference normal* `n`:
//! `κ > 0` where the surface bends away from `n` (convex seen from the side `n` points to). With
//! outward normals a sphere of radius `R` has `κ₁ = κ₂ = +1/R`, the inner equator of a torus has
//! `κ₂ < 0`. The reference normal is the given normal (point normals passed by the caller, or the
//! area-weighted vertex normal of a mesh), else the normal estimated and oriented by
//! [`crate::normals`] (outward on closed shapes by default).
//!
//! **Output.** One [`PrincipalCurvature`] per point (array of structs: callers usually need all
//! fields of a point together, e.g. the thesis's feature frame `(n, t₁, n × t₁)`), with
//! `k1 ≥ k2`, unit `d1 ⟂ d2 ⟂ normal`, `(d1, d2, normal)` right-handed. Degenerate neighbourhoods
//! never produce NaN: they get zero curvature and a [`CurvatureStatus`] other than `Fitted`.

use nalgebra::{Matrix6, Vector6};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::{Point3, add, any_orthonormal, cross, dot, is_finite, normalize, scale, sub};
use crate::mesh::TriMesh;
use crate::normals::{NormalsOptions, covariance, estimate_normals_with_tree, sorted_eigenvectors};
use crate::spatial::KdTree;
use crate::{Error, Result};

/// Which points form the neighbourhood a jet is fitted to.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Neighbourhood {
    /// The `k` nearest points, the point itself included (at least 6, the number of jet
    /// coefficients; 15 is CGAL's example and the default).
    Knn(usize),
    /// Every point within this distance (input units, inclusive). The thesis (§5.4) uses `4ε`,
    /// `ε` the resampling spacing. Balls with fewer than 6 points are reported as
    /// [`CurvatureStatus::TooFewNeighbours`].
    Radius(f64),
    /// Meshes only: edge rings around the vertex (1-ring, 2-ring, …), grown until the
    /// neighbourhood holds at least this many vertices, the vertex included (at least 6; CGAL's
    /// mesh example does the same). Prefer it on meshes with strongly anisotropic sampling (a
    /// UV sphere near its poles), where the k nearest vertices can all lie on one curve and the
    /// fit is [`CurvatureStatus::Degenerate`]. Rejected for point clouds.
    Rings(usize),
}

/// Weights of the neighbours in the least-squares fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Weighting {
    /// All neighbours weigh 1 (Cazals–Pouget's and CGAL's default).
    Uniform,
    /// `w = exp(−|q − p|² / (2 σ²))` with `σ = sigma × h`, `h` the neighbourhood radius (the
    /// distance to the farthest neighbour); `sigma` is dimensionless, e.g. 0.5. Favours the
    /// closest points, which helps on noisy data and near sharp features (MLS-style weighting,
    /// Alexa et al. 2003, as the thesis §5.4 cites).
    Gaussian {
        /// σ relative to the neighbourhood radius (dimensionless, > 0).
        sigma: f64,
    },
}

/// The frame in which the height function is fitted.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FittingFrame {
    /// `z` = the least-variance axis of the neighbourhood (Cazals–Pouget §4.2). Robust to noisy
    /// or approximate reference normals; the reference normal only chooses the sign.
    Pca,
    /// `z` = the reference normal. Slightly more accurate when the normals are exact (analytic
    /// or from a good mesh); degrades with poor normals.
    ReferenceNormal,
}

/// Options of [`principal_curvatures_points`] and [`principal_curvatures_mesh`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CurvatureOptions {
    /// Neighbourhood of each point. Default `Knn(15)` (CGAL's example); the thesis (§5.4) uses
    /// `Radius(4ε)`.
    pub neighbourhood: Neighbourhood,
    /// Weights in the fit. Default [`Weighting::Uniform`]; `Gaussian` approximates the MLS
    /// weighting the thesis (§5.4) cites.
    pub weighting: Weighting,
    /// Frame of the height function. Default [`FittingFrame::Pca`] (Cazals–Pouget's choice; the
    /// thesis does not specify one).
    pub frame: FittingFrame,
    /// How reference normals are estimated when a point cloud comes without normals (ignored
    /// otherwise). Default [`NormalsOptions::default`]: k = 16, oriented outward.
    pub normals: NormalsOptions,
}

impl Default for CurvatureOptions {
    fn default() -> Self {
        CurvatureOptions {
            neighbourhood: Neighbourhood::Knn(15),
            weighting: Weighting::Uniform,
            frame: FittingFrame::Pca,
            normals: NormalsOptions::default(),
        }
    }
}

impl CurvatureOptions {
    fn validate(&self) -> Result<()> {
        match self.neighbourhood {
            Neighbourhood::Knn(k) | Neighbourhood::Rings(k) if k < MIN_POINTS => {
                return Err(Error::InvalidOption {
                    name: "neighbourhood",
                    message: format!(
                        "{:?} is too small: a quadratic jet has 6 coefficients, use at least 6 (15 is typical)",
                        self.neighbourhood
                    ),
                });
            }
            Neighbourhood::Radius(r) if !(r > 0.0 && r.is_finite()) => {
                return Err(Error::InvalidOption {
                    name: "neighbourhood",
                    message: format!("Radius({r}) must be positive and finite"),
                });
            }
            _ => {}
        }
        if let Weighting::Gaussian { sigma } = self.weighting {
            if !(sigma > 0.0 && sigma.is_finite()) {
                return Err(Error::InvalidOption {
                    name: "weighting",
                    message: format!("Gaussian sigma {sigma} must be positive and finite (e.g. 0.5)"),
                });
            }
        }
        Ok(())
    }
}

/// How the curvature of one point was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CurvatureStatus {
    /// The jet was fitted and the reference normal fixed the sign.
    Fitted,
    /// The jet was fitted but the point had no usable reference normal (zero or non-finite, e.g.
    /// an unreferenced mesh vertex), so the sign of the curvatures and normal is arbitrary.
    Unoriented,
    /// Fewer than 6 distinct neighbours: curvature set to 0.
    TooFewNeighbours,
    /// The neighbours do not span a surface (collinear, coincident) so the fit is singular:
    /// curvature set to 0.
    Degenerate,
}

impl CurvatureStatus {
    /// How files and reports spell it: `fitted`, `unoriented`, `too_few_neighbours`, `degenerate`.
    pub fn as_str(self) -> &'static str {
        match self {
            CurvatureStatus::Fitted => "fitted",
            CurvatureStatus::Unoriented => "unoriented",
            CurvatureStatus::TooFewNeighbours => "too_few_neighbours",
            CurvatureStatus::Degenerate => "degenerate",
        }
    }
}

/// Principal curvatures and directions at one point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PrincipalCurvature {
    /// Maximum principal curvature κ₁ (1 / input units), signed as in the module documentation.
    pub k1: f64,
    /// Minimum principal curvature κ₂ ≤ κ₁.
    pub k2: f64,
    /// Unit direction of κ₁ (the thesis's `t₁`), tangent to the fitted surface. Its sign is
    /// arbitrary (a principal direction is a line).
    pub d1: Point3,
    /// Unit direction of κ₂, `d2 = normal × d1`.
    pub d2: Point3,
    /// Unit normal of the fitted surface, on the side of the reference normal.
    pub normal: Point3,
    /// How the values were obtained; anything but [`CurvatureStatus::Fitted`] deserves caution.
    pub status: CurvatureStatus,
}

impl PrincipalCurvature {
    /// Mean curvature `(κ₁ + κ₂) / 2`.
    pub fn mean(&self) -> f64 {
        0.5 * (self.k1 + self.k2)
    }

    /// Gaussian curvature `κ₁ κ₂`.
    pub fn gaussian(&self) -> f64 {
        self.k1 * self.k2
    }

    /// The principal curvature of largest magnitude and its direction: `(κ₁, d1)` unless
    /// `|κ₂| > |κ₁|` (concave or saddle-like points), then `(κ₂, d2)`. Useful when "maximum
    /// curvature" means the strongest bending regardless of sign, as for salient-feature
    /// selection (thesis §5.4 thresholds the magnitude of κ₁).
    pub fn dominant(&self) -> (f64, Point3) {
        if self.k2.abs() > self.k1.abs() { (self.k2, self.d2) } else { (self.k1, self.d1) }
    }
}

/// Principal curvatures of a point cloud by degree-2 jet fitting.
///
/// `points` is `#P × 3`; `normals`, when given, `#P × 3` and only used for orientation (and as
/// the fitting frame with [`FittingFrame::ReferenceNormal`]); they need not be unit length. Without
/// normals they are estimated with `options.normals`. Returns one entry per point, in order.
pub fn principal_curvatures_points(
    points: &[Point3],
    normals: Option<&[Point3]>,
    options: &CurvatureOptions,
) -> Result<Vec<PrincipalCurvature>> {
    options.validate()?;
    if let Neighbourhood::Rings(_) = options.neighbourhood {
        return Err(Error::InvalidOption {
            name: "neighbourhood",
            message: "Rings needs mesh connectivity; use Knn or Radius for point clouds".into(),
        });
    }
    if points.is_empty() {
        return Ok(Vec::new());
    }
    let tree = KdTree::new(points)?;
    let estimated;
    let reference = match normals {
        Some(n) => {
            check_normals(n, points.len())?;
            n
        }
        None if points.len() >= 3 => {
            estimated = estimate_normals_with_tree(points, &tree, &options.normals)?;
            &estimated[..]
        }
        None => {
            // Too few points for any normal: every point is degenerate anyway.
            estimated = vec![[0.0; 3]; points.len()];
            &estimated[..]
        }
    };
    Ok(fit_all(points, reference, Neighbours::Tree(&tree), options))
}

/// Principal curvatures at the vertices of a triangle mesh by degree-2 jet fitting.
///
/// Neighbourhoods are taken from the vertex set (as for a point cloud); the reference normals are
/// the area-weighted vertex normals [`TriMesh::vertex_normals`], so a closed mesh with outward
/// (counter-clockwise) winding has positive curvature where convex. Returns one entry per vertex;
/// unreferenced vertices get [`CurvatureStatus::Unoriented`] (or worse).
pub fn principal_curvatures_mesh(
    mesh: &TriMesh,
    options: &CurvatureOptions,
) -> Result<Vec<PrincipalCurvature>> {
    options.validate()?;
    if mesh.positions.is_empty() {
        return Ok(Vec::new());
    }
    mesh.validate()?;
    let normals = mesh.vertex_normals();
    if let Neighbourhood::Rings(_) = options.neighbourhood {
        let rings = VertexAdjacency::new(mesh);
        return Ok(fit_all(&mesh.positions, &normals, Neighbours::Rings(&rings), options));
    }
    let tree = KdTree::new(&mesh.positions)?;
    Ok(fit_all(&mesh.positions, &normals, Neighbours::Tree(&tree), options))
}

/// At a heap of more coincident points than this, a radius neighbourhood is this many of them
/// ([`KdTree::within_unsorted_capped`]): a fit over a heap is degenerate whatever its size, and
/// listing the whole heap from each of its points made `--radius` quadratic in the heap.
const HEAP_CAP: usize = 256;

/// Where neighbourhoods come from.
enum Neighbours<'a> {
    Tree(&'a KdTree),
    Rings(&'a VertexAdjacency),
}

/// Vertex–vertex adjacency of a mesh (compressed rows, duplicates removed).
struct VertexAdjacency {
    offsets: Vec<usize>,
    targets: Vec<u32>,
}

impl VertexAdjacency {
    fn new(mesh: &TriMesh) -> Self {
        let n = mesh.positions.len();
        let mut edges: Vec<(u32, u32)> = Vec::with_capacity(mesh.triangles.len() * 6);
        for t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if a != b {
                    edges.push((a, b));
                    edges.push((b, a));
                }
            }
        }
        edges.par_sort_unstable();
        edges.dedup();
        let mut offsets = vec![0usize; n + 1];
        for &(a, _) in &edges {
            offsets[a as usize + 1] += 1;
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        VertexAdjacency { offsets, targets: edges.into_iter().map(|(_, b)| b).collect() }
    }

    fn neighbours(&self, v: usize) -> &[u32] {
        &self.targets[self.offsets[v]..self.offsets[v + 1]]
    }
}

/// Collects whole edge rings around `v` into `found` until it holds at least `min_points`
/// vertices (or the vertex's component is exhausted). Neighbourhoods are small (tens of
/// vertices), so membership is a linear scan: no per-vertex allocation, no O(#V) marker array.
fn grow_rings(adjacency: &VertexAdjacency, v: usize, min_points: usize, found: &mut Vec<u32>) {
    found.clear();
    found.push(v as u32);
    let mut ring_start = 0;
    while found.len() < min_points {
        let ring_end = found.len();
        for i in ring_start..ring_end {
            for &w in adjacency.neighbours(found[i] as usize) {
                if !found.contains(&w) {
                    found.push(w);
                }
            }
        }
        if found.len() == ring_end {
            break;
        }
        ring_start = ring_end;
    }
}

fn check_normals(normals: &[Point3], n: usize) -> Result<()> {
    if normals.len() != n {
        return Err(Error::InvalidInput(format!("{} normals for {n} points", normals.len())));
    }
    if let Some(i) = normals.iter().position(|v| !is_finite(*v)) {
        return Err(Error::InvalidInput(format!("normal {i} has a NaN or infinite coordinate")));
    }
    Ok(())
}

/// Six jet coefficients need at least six points.
const MIN_POINTS: usize = 6;

fn fit_all(
    points: &[Point3],
    reference: &[Point3],
    source: Neighbours<'_>,
    options: &CurvatureOptions,
) -> Vec<PrincipalCurvature> {
    match source {
        Neighbours::Tree(tree) => {
            let capacity = match options.neighbourhood {
                Neighbourhood::Knn(k) => k,
                _ => 64,
            };
            points
                .par_iter()
                .zip(reference.par_iter())
                .map_init(
                    || Vec::with_capacity(capacity),
                    |local, (&p, &n)| {
                        // The kd-tree API returns a fresh Vec per query; the rest reuses `local`.
                        let nbrs = match options.neighbourhood {
                            Neighbourhood::Radius(r) => tree.within_unsorted_capped(p, r, HEAP_CAP),
                            Neighbourhood::Knn(k) | Neighbourhood::Rings(k) => tree.knn(p, k),
                        };
                        local.clear();
                        local.extend(nbrs.iter().map(|nb| sub(points[nb.index], p)));
                        fit_jet(local, normalize(n), options)
                    },
                )
                .collect()
        }
        Neighbours::Rings(adjacency) => {
            let min_points = match options.neighbourhood {
                Neighbourhood::Knn(k) | Neighbourhood::Rings(k) => k,
                Neighbourhood::Radius(_) => MIN_POINTS,
            };
            points
                .par_iter()
                .zip(reference.par_iter())
                .enumerate()
                .map_init(
                    || (Vec::with_capacity(4 * min_points), Vec::with_capacity(4 * min_points)),
                    |(found, local), (i, (&p, &n))| {
                        grow_rings(adjacency, i, min_points, found);
                        local.clear();
                        local.extend(found.iter().map(|&j| sub(points[j as usize], p)));
                        fit_jet(local, normalize(n), options)
                    },
                )
                .collect()
        }
    }
}

/// Fits the jet to the neighbours `local` (positions relative to the point) and returns the
/// curvature at the point. `reference` is the unit reference normal, if any.
fn fit_jet(local: &[Point3], reference: Option<Point3>, options: &CurvatureOptions) -> PrincipalCurvature {
    let fallback = |status| degenerate(local, reference, status);
    if local.len() < MIN_POINTS {
        return fallback(CurvatureStatus::TooFewNeighbours);
    }
    let h = local.iter().map(|v| dot(*v, *v)).fold(0.0, f64::max).sqrt();
    if !(h > 0.0 && h.is_finite()) {
        return fallback(CurvatureStatus::TooFewNeighbours);
    }

    // Fitting frame, z towards the reference normal, right-handed.
    let (ex, ey, ez) = match (options.frame, reference) {
        (FittingFrame::ReferenceNormal, Some(n)) => {
            let x = any_orthonormal(n);
            (x, cross(n, x), n)
        }
        _ => {
            let [z, _, x] = sorted_eigenvectors(&covariance(local.iter().copied()));
            let z = match reference {
                Some(n) if dot(z, n) < 0.0 => scale(z, -1.0),
                _ => z,
            };
            (x, cross(z, x), z)
        }
    };

    // Weighted normal equations of the scaled monomial basis [x², xy, y², x, y, 1].
    let inv_h = 1.0 / h;
    let gauss = match options.weighting {
        Weighting::Uniform => None,
        Weighting::Gaussian { sigma } => Some(-0.5 / (sigma * sigma)),
    };
    let mut m = Matrix6::<f64>::zeros();
    let mut rhs = Vector6::<f64>::zeros();
    let mut weight_sum = 0.0;
    for v in local {
        let v = scale(*v, inv_h);
        let (x, y, z) = (dot(v, ex), dot(v, ey), dot(v, ez));
        let w = gauss.map_or(1.0, |g| (g * dot(v, v)).exp());
        let phi = [x * x, x * y, y * y, x, y, 1.0];
        for r in 0..6 {
            let wr = w * phi[r];
            for s in r..6 {
                m[(r, s)] += wr * phi[s];
            }
            rhs[r] += wr * z;
        }
        weight_sum += w;
    }
    for r in 0..6 {
        for s in 0..r {
            m[(r, s)] = m[(s, r)];
        }
    }
    // Jacobi scaling, then Cholesky; a tiny pivot means the points do not determine a quadric
    // (collinear, or all on a conic through the point): a singular fit.
    let mut dscale = [0.0; 6];
    for r in 0..6 {
        let d = m[(r, r)];
        if d.is_nan() || d <= 1e-14 * weight_sum {
            return fallback(CurvatureStatus::Degenerate);
        }
        dscale[r] = 1.0 / d.sqrt();
    }
    for r in 0..6 {
        for s in 0..6 {
            m[(r, s)] *= dscale[r] * dscale[s];
        }
        rhs[r] *= dscale[r];
    }
    let Some(chol) = m.cholesky() else { return fallback(CurvatureStatus::Degenerate) };
    let l = chol.l_dirty();
    let (mut lmin, mut lmax) = (f64::INFINITY, 0.0f64);
    for r in 0..6 {
        lmin = lmin.min(l[(r, r)]);
        lmax = lmax.max(l[(r, r)]);
    }
    // (lmin / lmax)² estimates the reciprocal condition number of the scaled normal matrix;
    // well-spread neighbourhoods stay far above 1e-8, near-collinear scan lines fall below.
    if lmin.is_nan() || lmin <= 1e-4 * lmax {
        return fallback(CurvatureStatus::Degenerate);
    }
    let coef = chol.solve(&rhs);
    let c: [f64; 6] = std::array::from_fn(|r| coef[r] * dscale[r]);

    // Back to input units: z = h Z(x/h, y/h) ⇒ second derivatives / h, first derivatives as is.
    let (hxx, hxy, hyy) = (2.0 * c[0] * inv_h, c[1] * inv_h, 2.0 * c[2] * inv_h);
    let (hx, hy) = (c[3], c[4]);
    let w = (1.0 + hx * hx + hy * hy).sqrt();
    // First fundamental form I = L Lᵀ (Cholesky, always positive definite), second form II.
    let (e, f, g) = (1.0 + hx * hx, hx * hy, 1.0 + hy * hy);
    let (l, mm, n) = (hxx / w, hxy / w, hyy / w);
    let l11 = e.sqrt();
    let l21 = f / l11;
    let l22 = (g - l21 * l21).sqrt();
    // C = L⁻¹ II L⁻ᵀ is symmetric with the eigenvalues of the shape operator I⁻¹ II.
    let (a11, a12, a22) = {
        // L⁻¹ = [[1/l11, 0], [−l21/(l11 l22), 1/l22]]
        let (i11, i21, i22) = (1.0 / l11, -l21 / (l11 * l22), 1.0 / l22);
        // T = L⁻¹ II
        let t11 = i11 * l;
        let t12 = i11 * mm;
        let t21 = i21 * l + i22 * mm;
        let t22 = i21 * mm + i22 * n;
        // C = T L⁻ᵀ
        (t11 * i11, t11 * i21 + t12 * i22, t21 * i21 + t22 * i22)
    };
    let (lam_small, vec_small) = sym2_smallest(a11, a12, a22);
    let lam_large = a11 + a22 - lam_small;
    // II is measured against the fitted normal on the +z side, i.e. the reference side; the
    // convention is κ > 0 where the surface bends away from it, so κ = −λ: κ₁ = −λ_min.
    let k1 = -lam_small;
    let k2 = -lam_large;
    // Parameter-space direction u = L⁻ᵀ w, then the tangent u₀ r_x + u₁ r_y in the frame.
    let u1 = vec_small[1] / l22;
    let u0 = (vec_small[0] - l21 * u1) / l11;
    let t = [u0, u1, u0 * hx + u1 * hy];
    let nrm = [-hx / w, -hy / w, 1.0 / w];
    let to_world = |v: [f64; 3]| add(add(scale(ex, v[0]), scale(ey, v[1])), scale(ez, v[2]));
    let normal = normalize(to_world(nrm)).unwrap_or(ez);
    let d1 = normalize(to_world(t)).unwrap_or_else(|| any_orthonormal(normal));
    // Remove any rounding drift so the frame is exactly orthonormal.
    let d1 = normalize(sub(d1, scale(normal, dot(d1, normal)))).unwrap_or_else(|| any_orthonormal(normal));
    let d2 = cross(normal, d1);
    if !(k1.is_finite() && k2.is_finite()) {
        return fallback(CurvatureStatus::Degenerate);
    }
    let status = if reference.is_some() { CurvatureStatus::Fitted } else { CurvatureStatus::Unoriented };
    PrincipalCurvature { k1, k2, d1, d2, normal, status }
}

/// Smallest eigenvalue of the symmetric 2×2 `[[a, b], [b, c]]` and a unit eigenvector.
fn sym2_smallest(a: f64, b: f64, c: f64) -> (f64, [f64; 2]) {
    let half_diff = 0.5 * (a - c);
    let r = half_diff.hypot(b);
    let lam = 0.5 * (a + c) - r;
    // (A − λ I) v = 0: use the better-conditioned of the two rows.
    let v = if r == 0.0 {
        [1.0, 0.0]
    } else if half_diff <= 0.0 {
        // a − λ = r + half_diff is small; row 2: b x + (c − λ) y = 0, c − λ = r − half_diff ≥ r.
        [r - half_diff, -b]
    } else {
        // row 1: (a − λ) x + b y = 0, a − λ = r + half_diff ≥ r.
        [-b, r + half_diff]
    };
    let len = v[0].hypot(v[1]);
    if len > 0.0 { (lam, [v[0] / len, v[1] / len]) } else { (lam, [1.0, 0.0]) }
}

/// Zero curvature with the best frame available: the reference normal, else PCA, else +z.
fn degenerate(local: &[Point3], reference: Option<Point3>, status: CurvatureStatus) -> PrincipalCurvature {
    let normal = reference.unwrap_or_else(|| {
        if local.len() >= 3 {
            sorted_eigenvectors(&covariance(local.iter().copied()))[0]
        } else {
            [0.0, 0.0, 1.0]
        }
    });
    let d1 = any_orthonormal(normal);
    PrincipalCurvature { k1: 0.0, k2: 0.0, d1, d2: cross(normal, d1), normal, status }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sym2_eigen() {
        for &(a, b, c) in
            &[(1.0, 0.0, 2.0), (2.0, 0.0, 1.0), (1.0, 0.5, -3.0), (0.3, -2.0, 0.3), (1.0, 0.0, 1.0)]
        {
            let (lam, v) = sym2_smallest(a, b, c);
            let av = [a * v[0] + b * v[1], b * v[0] + c * v[1]];
            assert!((av[0] - lam * v[0]).abs() < 1e-12 && (av[1] - lam * v[1]).abs() < 1e-12);
            let other = a + c - lam;
            assert!(lam <= other + 1e-15);
        }
    }

    #[test]
    fn paraboloid_exact() {
        // z = −(x² + 2y²)/2 ⇒ at the origin, with normal +z, κ = (2, 1) along (y, x).
        let mut pts = vec![[0.0; 3]];
        for i in -3i32..=3 {
            for j in -3i32..=3 {
                if i != 0 || j != 0 {
                    let (x, y) = (i as f64 * 0.01, j as f64 * 0.01);
                    pts.push([x, y, -(x * x + 2.0 * y * y) / 2.0]);
                }
            }
        }
        let local = pts.clone();
        let opts = CurvatureOptions { neighbourhood: Neighbourhood::Knn(49), ..Default::default() };
        let pc = fit_jet(&local, Some([0.0, 0.0, 1.0]), &opts);
        assert_eq!(pc.status, CurvatureStatus::Fitted);
        assert!((pc.k1 - 2.0).abs() < 1e-9 && (pc.k2 - 1.0).abs() < 1e-9, "{pc:?}");
        assert!(pc.d1[1].abs() > 1.0 - 1e-9, "{pc:?}");
        assert!(pc.normal[2] > 1.0 - 1e-12);
    }

    #[test]
    fn collinear_and_tiny_inputs_are_nan_free() {
        let line: Vec<Point3> = (0..30).map(|i| [i as f64, 2.0 * i as f64, 0.5]).collect();
        let out = principal_curvatures_points(&line, None, &CurvatureOptions::default()).unwrap();
        for pc in &out {
            assert_eq!(pc.status, CurvatureStatus::Degenerate);
            assert_eq!((pc.k1, pc.k2), (0.0, 0.0));
            assert!(is_finite(pc.normal) && is_finite(pc.d1) && is_finite(pc.d2));
        }
        let few = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        for pc in principal_curvatures_points(&few, None, &CurvatureOptions::default()).unwrap() {
            assert_eq!(pc.status, CurvatureStatus::TooFewNeighbours);
        }
        let same = vec![[3.0; 3]; 40];
        for pc in principal_curvatures_points(&same, None, &CurvatureOptions::default()).unwrap() {
            assert_eq!(pc.status, CurvatureStatus::TooFewNeighbours);
            assert!(is_finite(pc.normal));
        }
    }

    #[test]
    fn options_are_validated() {
        let pts = vec![[0.0; 3]; 10];
        let bad = CurvatureOptions { neighbourhood: Neighbourhood::Knn(5), ..Default::default() };
        assert!(principal_curvatures_points(&pts, None, &bad).is_err());
        let bad = CurvatureOptions { neighbourhood: Neighbourhood::Radius(-1.0), ..Default::default() };
        assert!(principal_curvatures_points(&pts, None, &bad).is_err());
        let bad = CurvatureOptions { weighting: Weighting::Gaussian { sigma: 0.0 }, ..Default::default() };
        assert!(principal_curvatures_points(&pts, None, &bad).is_err());
        assert!(
            principal_curvatures_points(&pts, Some(&[[0.0; 3]; 3]), &CurvatureOptions::default()).is_err()
        );
    }
}
