//! Rigid registration by the iterative closest point algorithm (Besl & McKay 1992; point-to-plane:
//! Chen & Medioni 1992, linearised as in Low 2004), trimmed (Chetverikov et al., "The trimmed
//! iterative closest point algorithm", ICPR 2002).
//!
//! Each iteration matches every transformed source point to its nearest target point, keeps the
//! `trim_fraction` closest pairs (and only pairs within `max_correspondence_distance`), and solves
//! for the motion that best aligns them:
//! - point-to-point, rigid: closed form by SVD of the cross-covariance (Kabsch/Umeyama), with the
//!   reflection case fixed;
//! - point-to-point, translation only: the mean offset;
//! - point-to-plane, rigid: the 6×6 normal equations of the small-angle linearisation
//!   `Σ ((p + ω × (p − c) + τ − q)·n)²` (Low 2004), in centred and scaled unknowns, the rotation
//!   then rebuilt exactly from `ω` (Rodrigues) so it stays orthonormal;
//! - point-to-plane, translation only: the 3×3 system `Σ n nᵀ τ = Σ n ((q − p)·n)`.
//!
//! Point-to-plane systems are degenerate when the normals do not constrain every direction (a
//! plane slides in itself, a cylinder along and around its axis). Directions whose eigenvalue is
//! below `1e-6` of the largest take the point-to-point solution instead, so the solver degrades
//! gracefully rather than producing huge steps.
//!
//! Transforms are row-major 4×4 matrices acting on column vectors, named by the spaces they map:
//! the result is `target_from_source`.
//!
//! Thesis use: §4.4 refines each dominant offset (a histogram peak, accurate only to the bin
//! size) "using a global iterative closest point algorithm on the entire point cloud", i.e.
//! translation-only ICP of the cloud shifted by the offset against itself, many times against one
//! cloud: [`icp_with_tree`] lets those runs share one kd-tree of the target. §5.5 uses rigid ICP
//! as the detection baseline and in the annotation tool.

use nalgebra::{Matrix3, Matrix6, SMatrix, SymmetricEigen, Vector3, Vector6};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::{
    Aabb, IDENTITY4, Mat4, Point3, cross, dot, is_finite, mat4_from_rt, mat4_mul, norm, rotation_about_axis,
    scale, sub, transform_point,
};
use crate::spatial::KdTree;
use crate::{Error, Result};

/// The distance ICP minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IcpMetric {
    /// Squared Euclidean distance to the matched target point (Besl & McKay 1992). Needs no
    /// normals; converges linearly. The default.
    #[default]
    PointToPoint,
    /// Squared distance to the tangent plane of the matched target point (Chen & Medioni 1992).
    /// Needs target normals; converges in a few iterations on smooth surfaces.
    PointToPlane,
}

/// Which motions ICP may apply to the source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IcpMotion {
    /// Rotation and translation. The default.
    #[default]
    Rigid,
    /// Translation only; the rotation of `initial` is kept. Used to refine offset vectors.
    TranslationOnly,
}

/// Options of [`icp`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IcpOptions {
    /// Error metric. Default [`IcpMetric::PointToPoint`]; [`IcpMetric::PointToPlane`] requires
    /// target normals. The thesis does not specify one.
    pub metric: IcpMetric,
    /// Allowed motion. Default [`IcpMotion::Rigid`]; the offset refinement of thesis §4.4 uses
    /// [`IcpMotion::TranslationOnly`].
    pub motion: IcpMotion,
    /// Maximum number of iterations (correspondence + update steps). Default 50 (point-to-plane
    /// typically converges in under 10; point-to-point may need more for rotations beyond ~10°).
    /// Not specified by the thesis.
    pub max_iterations: usize,
    /// Convergence tolerance, relative to the bounding-box diagonal of the source: ICP stops when
    /// the last update moves no matched source point by more than `tolerance × diagonal`.
    /// Default 1e-6 (dimensionless). Not specified by the thesis.
    pub tolerance: f64,
    /// Fraction of the (distance-filtered) correspondences kept each iteration, the closest ones
    /// (trimmed ICP, Chetverikov et al. 2002). Should not exceed the expected overlap of source
    /// and target; for the §4.4 offset refinement that is the overlap of the cloud with its
    /// shifted copy, often well below 1. In (0, 1]; default 0.9.
    pub trim_fraction: f64,
    /// Correspondences farther apart than this (input units) are rejected before trimming.
    /// Default `None` (no limit). A few sample spacings (the thesis's ε, §5.4) suit refinement
    /// from a close start.
    pub max_correspondence_distance: Option<f64>,
}

impl Default for IcpOptions {
    fn default() -> Self {
        IcpOptions {
            metric: IcpMetric::PointToPoint,
            motion: IcpMotion::Rigid,
            max_iterations: 50,
            tolerance: 1e-6,
            trim_fraction: 0.9,
            max_correspondence_distance: None,
        }
    }
}

impl IcpOptions {
    fn validate(&self) -> Result<()> {
        if !(self.trim_fraction > 0.0 && self.trim_fraction <= 1.0) {
            return Err(Error::InvalidOption {
                name: "trim_fraction",
                message: format!(
                    "{} is outside (0, 1]; use the expected overlap, e.g. 0.9",
                    self.trim_fraction
                ),
            });
        }
        if !(self.tolerance >= 0.0 && self.tolerance.is_finite()) {
            return Err(Error::InvalidOption {
                name: "tolerance",
                message: format!("{} must be finite and non-negative (e.g. 1e-6)", self.tolerance),
            });
        }
        if let Some(d) = self.max_correspondence_distance {
            if d.is_nan() || d <= 0.0 {
                return Err(Error::InvalidOption {
                    name: "max_correspondence_distance",
                    message: format!("{d} must be positive (or unset for no limit)"),
                });
            }
        }
        Ok(())
    }
}

/// The outcome of [`icp`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IcpResult {
    /// The transform mapping source coordinates into the target's (`target_from_source`),
    /// row-major, acting on column vectors; includes `initial`.
    pub transform: Mat4,
    /// Root mean square residual over the inliers of the final transform, in input units:
    /// Euclidean distances for point-to-point, distances to the target tangent planes for
    /// point-to-plane (Euclidean distances where a target normal is zero).
    pub rmse: f64,
    /// Fraction of source points that are inliers at the final transform (within
    /// `max_correspondence_distance` and kept by trimming).
    pub inlier_fraction: f64,
    /// Number of update steps performed.
    pub iterations: usize,
    /// True when the last update was below the tolerance before `max_iterations` ran out.
    pub converged: bool,
}

/// Aligns `source` to `target` by trimmed ICP, starting from `initial` (`target_from_source`).
///
/// `target_normals` (`#target × 3`, any length ≠ 0) is required for
/// [`IcpMetric::PointToPlane`] and ignored otherwise. Builds a kd-tree of the target; to align
/// many sources against one target use [`icp_with_tree`].
pub fn icp(
    source: &[Point3],
    target: &[Point3],
    target_normals: Option<&[Point3]>,
    initial: &Mat4,
    options: &IcpOptions,
) -> Result<IcpResult> {
    options.validate()?;
    if target.is_empty() {
        return Err(Error::InvalidInput("ICP needs a non-empty target".into()));
    }
    let tree = KdTree::new(target)?;
    icp_with_tree(source, target, &tree, target_normals, initial, options)
}

/// [`icp`] with a kd-tree the caller built once over `target` (e.g. the translation-only
/// refinement of many offset candidates against one cloud).
pub fn icp_with_tree(
    source: &[Point3],
    target: &[Point3],
    target_tree: &KdTree,
    target_normals: Option<&[Point3]>,
    initial: &Mat4,
    options: &IcpOptions,
) -> Result<IcpResult> {
    options.validate()?;
    check_inputs(source, target, target_tree, target_normals, initial, options)?;
    let normals = match options.metric {
        IcpMetric::PointToPlane => target_normals,
        IcpMetric::PointToPoint => None,
    };
    let diagonal = Aabb::from_points(source).map_or(0.0, |b| b.diagonal());
    let threshold = options.tolerance * diagonal;

    let mut state = Correspondences::new(source.len());
    let mut transform = *initial;
    let mut iterations = 0;
    let mut converged = false;
    while iterations < options.max_iterations {
        state.update(source, target_tree, &transform, options);
        if state.inliers.is_empty() {
            return Err(no_inliers(options));
        }
        let step = solve_step(&state, target, normals, options.motion);
        transform = mat4_mul(&step.transform, &transform);
        iterations += 1;
        if transform.iter().flatten().any(|v| !v.is_finite()) {
            return Err(diverged(iterations));
        }
        if step.max_displacement <= threshold {
            converged = true;
            break;
        }
    }
    state.update(source, target_tree, &transform, options);
    if state.inliers.is_empty() {
        return Err(no_inliers(options));
    }
    let rmse = state.rmse(target, normals);
    if !rmse.is_finite() {
        return Err(diverged(iterations));
    }
    Ok(IcpResult {
        transform,
        rmse,
        inlier_fraction: state.inliers.len() as f64 / source.len() as f64,
        iterations,
        converged,
    })
}

/// The arithmetic overflowed: coordinates so large (about 1e154 or more) that their squares are
/// infinite.
fn diverged(iterations: usize) -> Error {
    Error::InvalidInput(format!(
        "ICP diverged at iteration {iterations}: the transform or its error is NaN or infinite (are \
         the coordinates too large to square? rescale the inputs)"
    ))
}

fn no_inliers(options: &IcpOptions) -> Error {
    Error::InvalidInput(format!(
        "ICP found no correspondence within max_correspondence_distance {:?}: start closer (initial) or \
         raise the limit",
        options.max_correspondence_distance
    ))
}

fn check_inputs(
    source: &[Point3],
    target: &[Point3],
    tree: &KdTree,
    normals: Option<&[Point3]>,
    initial: &Mat4,
    options: &IcpOptions,
) -> Result<()> {
    if source.is_empty() || target.is_empty() {
        return Err(Error::InvalidInput(format!(
            "ICP needs non-empty clouds, got {} source and {} target points",
            source.len(),
            target.len()
        )));
    }
    if tree.len() != target.len() {
        return Err(Error::InvalidInput(format!(
            "the kd-tree holds {} points but the target has {}",
            tree.len(),
            target.len()
        )));
    }
    if let Some(i) = source.iter().position(|p| !is_finite(*p)) {
        return Err(Error::InvalidInput(format!("source point {i} has a NaN or infinite coordinate")));
    }
    if initial.iter().flatten().any(|v| !v.is_finite()) {
        return Err(Error::InvalidInput("the initial transform has a NaN or infinite entry".into()));
    }
    if options.metric == IcpMetric::PointToPlane {
        let Some(n) = normals else {
            return Err(Error::InvalidInput(
                "point-to-plane ICP needs target normals: pass them (e.g. from normals::estimate_normals) \
                 or use IcpMetric::PointToPoint"
                    .into(),
            ));
        };
        if n.len() != target.len() {
            return Err(Error::InvalidInput(format!(
                "{} normals for {} target points",
                n.len(),
                target.len()
            )));
        }
        if let Some(i) = n.iter().position(|v| !is_finite(*v)) {
            return Err(Error::InvalidInput(format!("target normal {i} has a NaN or infinite coordinate")));
        }
    }
    Ok(())
}

/// Per-iteration buffers, allocated once per ICP run.
struct Correspondences {
    /// Transformed source point, matched target index and squared distance, per source point.
    pairs: Vec<(Point3, u32, f64)>,
    /// Indices into `pairs` of the inliers of the current iteration.
    inliers: Vec<u32>,
}

impl Correspondences {
    fn new(n: usize) -> Self {
        Correspondences { pairs: vec![([0.0; 3], 0, 0.0); n], inliers: Vec::with_capacity(n) }
    }

    fn update(&mut self, source: &[Point3], tree: &KdTree, m: &Mat4, options: &IcpOptions) {
        self.pairs.par_iter_mut().zip(source.par_iter()).for_each(|(pair, &s)| {
            let p = transform_point(m, s);
            let nb = tree.nearest(p);
            *pair = (p, nb.index as u32, nb.distance * nb.distance);
        });
        let max_d2 = options.max_correspondence_distance.map_or(f64::INFINITY, |d| d * d);
        self.inliers.clear();
        self.inliers.extend((0..self.pairs.len() as u32).filter(|&i| self.pairs[i as usize].2 <= max_d2));
        let keep =
            ((options.trim_fraction * self.inliers.len() as f64).ceil() as usize).min(self.inliers.len());
        if keep < self.inliers.len() && keep > 0 {
            let pairs = &self.pairs;
            self.inliers.select_nth_unstable_by(keep - 1, |&a, &b| {
                pairs[a as usize].2.total_cmp(&pairs[b as usize].2).then(a.cmp(&b))
            });
            self.inliers.truncate(keep);
        }
    }

    fn rmse(&self, target: &[Point3], normals: Option<&[Point3]>) -> f64 {
        let sum: f64 = self
            .inliers
            .iter()
            .map(|&i| {
                let (p, j, d2) = self.pairs[i as usize];
                match normals {
                    // A target point without a normal (zero: a degenerate neighbourhood) has no
                    // plane; its residual is the distance itself, not 0.
                    Some(n) if norm(n[j as usize]) > 0.0 => {
                        let r = plane_residual(p, target[j as usize], n[j as usize]);
                        r * r
                    }
                    _ => d2,
                }
            })
            .sum();
        (sum / self.inliers.len() as f64).sqrt()
    }
}

/// Signed distance of `p` to the plane through `q` with normal `n` (normalised here, so callers
/// may pass non-unit normals; a zero normal gives 0).
#[inline]
fn plane_residual(p: Point3, q: Point3, n: Point3) -> f64 {
    let len = norm(n);
    if len > 0.0 { dot(sub(p, q), n) / len } else { 0.0 }
}

struct Step {
    /// The update, applied after the current transform.
    transform: Mat4,
    /// Upper bound of the distance the update moves an inlier.
    max_displacement: f64,
}

fn solve_step(
    state: &Correspondences,
    target: &[Point3],
    normals: Option<&[Point3]>,
    motion: IcpMotion,
) -> Step {
    let inl = || state.inliers.iter().map(|&i| state.pairs[i as usize]);
    let count = state.inliers.len() as f64;
    let mut c = [0.0; 3];
    for (p, _, _) in inl() {
        c = crate::geometry::add(c, p);
    }
    c = scale(c, 1.0 / count);
    let (mut rms, mut rmax) = (0.0, 0.0f64);
    for (p, _, _) in inl() {
        let d2 = crate::geometry::dist2(p, c);
        rms += d2;
        rmax = rmax.max(d2);
    }
    let rmax = rmax.sqrt();
    // Length unit of the rotational unknowns; any positive value works, the RMS radius balances
    // the columns of the 6×6 system.
    let s = (rms / count).sqrt().max(f64::MIN_POSITIVE.sqrt());
    let mean_offset = {
        let mut t = [0.0; 3];
        for (p, j, _) in inl() {
            t = crate::geometry::add(t, sub(target[j as usize], p));
        }
        scale(t, 1.0 / count)
    };

    match (motion, normals) {
        (IcpMotion::TranslationOnly, None) => translation_step(mean_offset),
        (IcpMotion::TranslationOnly, Some(n)) => {
            let mut h = Matrix3::<f64>::zeros();
            let mut g = Vector3::<f64>::zeros();
            for (p, j, _) in inl() {
                let Some(nj) = crate::geometry::normalize(n[j as usize]) else { continue };
                let nv = Vector3::from(nj);
                h += nv * nv.transpose();
                g += nv * dot(sub(target[j as usize], p), nj);
            }
            let fallback = Vector3::from(mean_offset);
            let t = solve_truncated3(&h, &g, &fallback);
            translation_step([t[0], t[1], t[2]])
        }
        (IcpMotion::Rigid, None) => kabsch_step(state, target, c, rmax),
        (IcpMotion::Rigid, Some(n)) => {
            let mut h = Matrix6::<f64>::zeros();
            let mut g = Vector6::<f64>::zeros();
            // Point-to-point linearisation, the fallback for directions the planes leave free.
            let mut hp = Matrix6::<f64>::zeros();
            let mut gp = Vector6::<f64>::zeros();
            for (p, j, _) in inl() {
                let q = target[j as usize];
                let u = scale(sub(p, c), 1.0 / s);
                let b = scale(sub(q, p), 1.0 / s);
                if let Some(nj) = crate::geometry::normalize(n[j as usize]) {
                    let a = cross(u, nj);
                    let row = Vector6::new(a[0], a[1], a[2], nj[0], nj[1], nj[2]);
                    h += row * row.transpose();
                    g += row * dot(b, nj);
                }
                // p + ω × u s + τ − q: rows [−[u]×, I] for y = (ω, τ / s).
                #[rustfmt::skip]
                let a = SMatrix::<f64, 3, 6>::from_row_slice(&[
                    0.0, u[2], -u[1], 1.0, 0.0, 0.0,
                    -u[2], 0.0, u[0], 0.0, 1.0, 0.0,
                    u[1], -u[0], 0.0, 0.0, 0.0, 1.0,
                ]);
                hp += a.transpose() * a;
                gp += a.transpose() * Vector3::from(b);
            }
            let fallback = solve_truncated6(&hp, &gp, &Vector6::zeros());
            let y = solve_truncated6(&h, &g, &fallback);
            let omega = [y[0], y[1], y[2]];
            let tau = [y[3] * s, y[4] * s, y[5] * s];
            let angle = norm(omega);
            let r = if angle > 0.0 {
                rotation_about_axis(omega, angle)
            } else {
                [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
            };
            // x ↦ R (x − c) + c + τ
            let rc = rotate(&r, c);
            let t = crate::geometry::add(sub(c, rc), tau);
            Step { transform: mat4_from_rt(r, t), max_displacement: norm(tau) + angle * rmax }
        }
    }
}

fn translation_step(t: Point3) -> Step {
    let mut m = IDENTITY4;
    for k in 0..3 {
        m[k][3] = t[k];
    }
    Step { transform: m, max_displacement: norm(t) }
}

/// Kabsch: the rotation and translation minimising `Σ |R p + t − q|²`, reflections excluded.
fn kabsch_step(state: &Correspondences, target: &[Point3], pc: Point3, rmax: f64) -> Step {
    let count = state.inliers.len() as f64;
    let mut qc = [0.0; 3];
    for &i in &state.inliers {
        qc = crate::geometry::add(qc, target[state.pairs[i as usize].1 as usize]);
    }
    qc = scale(qc, 1.0 / count);
    let mut cov = Matrix3::<f64>::zeros();
    for &i in &state.inliers {
        let (p, j, _) = state.pairs[i as usize];
        let a = Vector3::from(sub(p, pc));
        let b = Vector3::from(sub(target[j as usize], qc));
        cov += b * a.transpose();
    }
    let r = kabsch_rotation(&cov);
    let t = sub(qc, rotate(&r, pc));
    // Displacement bound: translation of the centroid plus rotation about it.
    let angle = rotation_angle(&r);
    let moved = norm(sub(crate::geometry::add(rotate(&r, pc), t), pc));
    Step { transform: mat4_from_rt(r, t), max_displacement: moved + angle * rmax }
}

/// The rotation of Kabsch's method from the cross-covariance `cov = Σ (q − q̄)(p − p̄)ᵀ`:
/// `cov = U S Vᵀ ⇒ R = U diag(1, 1, det(U Vᵀ)) Vᵀ` (reflections excluded).
fn kabsch_rotation(cov: &Matrix3<f64>) -> [[f64; 3]; 3] {
    let svd = cov.svd(true, true);
    let r = match (svd.u, svd.v_t) {
        (Some(mut u), Some(v_t)) => {
            if (u * v_t).determinant() < 0.0 {
                // nalgebra sorts singular values in decreasing order: flip the weakest axis.
                let mut col = u.column_mut(2);
                col.neg_mut();
            }
            u * v_t
        }
        _ => Matrix3::identity(),
    };
    std::array::from_fn(|a| std::array::from_fn(|b| r[(a, b)]))
}

/// The rigid motion `target_from_source` (rotation and translation, no reflection) minimising
/// `Σ |R pᵢ + t − qᵢ|²` over paired points `pᵢ = source[i]`, `qᵢ = target[i]` (Kabsch 1976).
/// When the source points do not span a plane (one point, or all on a line) the rotation is
/// undetermined and only the translation of the centroids is returned. `None` when the slices
/// are empty, differ in length or hold a non-finite coordinate.
pub fn fit_rigid(source: &[Point3], target: &[Point3]) -> Option<Mat4> {
    if source.is_empty()
        || source.len() != target.len()
        || !source.iter().chain(target).all(|p| is_finite(*p))
    {
        return None;
    }
    let n = source.len() as f64;
    let centroid = |v: &[Point3]| scale(v.iter().fold([0.0; 3], |a, p| crate::geometry::add(a, *p)), 1.0 / n);
    let (pc, qc) = (centroid(source), centroid(target));
    let mut cov = Matrix3::<f64>::zeros();
    let mut spread = Matrix3::<f64>::zeros();
    for (p, q) in source.iter().zip(target) {
        let a = Vector3::from(sub(*p, pc));
        cov += Vector3::from(sub(*q, qc)) * a.transpose();
        spread += a * a.transpose();
    }
    // Rank of the source spread: below 2 the rotation about the line (or point) is free.
    let ev = SymmetricEigen::new(spread).eigenvalues;
    let mut ev = [ev[0], ev[1], ev[2]];
    ev.sort_by(|a, b| b.total_cmp(a));
    let r = if ev[0] > 0.0 && ev[1] > 1e-12 * ev[0] {
        kabsch_rotation(&cov)
    } else {
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    };
    Some(mat4_from_rt(r, sub(qc, rotate(&r, pc))))
}

fn rotate(r: &[[f64; 3]; 3], v: Point3) -> Point3 {
    [dot(r[0], v), dot(r[1], v), dot(r[2], v)]
}

/// Rotation angle of a rotation matrix, in radians, robust near 0 and π.
pub(crate) fn rotation_angle(r: &[[f64; 3]; 3]) -> f64 {
    let tr = r[0][0] + r[1][1] + r[2][2];
    let s = 0.5 * norm([r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]]);
    s.atan2(0.5 * (tr - 1.0))
}

/// Defines a solver of the symmetric positive semi-definite `H x = g` restricted to the span of
/// the eigenvectors whose eigenvalue exceeds `1e-6 × λ_max`; in the remaining (ill-determined)
/// directions `x` takes `fallback`'s component.
macro_rules! truncated_solver {
    ($name:ident, $mat:ty, $vec:ty, $dim:expr) => {
        fn $name(h: &$mat, g: &$vec, fallback: &$vec) -> $vec {
            let eig = SymmetricEigen::new(*h);
            let lmax = eig.eigenvalues.iter().fold(0.0f64, |a, &b| a.max(b));
            let mut x = <$vec>::zeros();
            for k in 0..$dim {
                let v = eig.eigenvectors.column(k);
                let lam = eig.eigenvalues[k];
                if lmax > 0.0 && lam > 1e-6 * lmax {
                    x += v * (v.dot(g) / lam);
                } else {
                    x += v * v.dot(fallback);
                }
            }
            x
        }
    };
}

truncated_solver!(solve_truncated3, Matrix3<f64>, Vector3<f64>, 3);
truncated_solver!(solve_truncated6, Matrix6<f64>, Vector6<f64>, 6);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_angle_of_rodrigues() {
        for &a in &[0.0, 1e-9, 0.3, 2.0, std::f64::consts::PI - 1e-6] {
            let r = rotation_about_axis([0.3, -1.0, 0.2], a);
            assert!((rotation_angle(&r) - a).abs() < 1e-9);
        }
    }

    #[test]
    fn truncated_solve_uses_fallback_in_null_space() {
        let h = Matrix3::new(1.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0);
        let g = Vector3::new(1.0, 1.0, 0.0);
        let x = solve_truncated3(&h, &g, &Vector3::new(9.0, 9.0, 7.0));
        assert!((x - Vector3::new(1.0, 0.5, 7.0)).norm() < 1e-12);
    }

    #[test]
    fn rejects_bad_input() {
        let pts = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let o = IcpOptions::default();
        assert!(icp(&[], &pts, None, &IDENTITY4, &o).is_err());
        assert!(icp(&pts, &[], None, &IDENTITY4, &o).is_err());
        let p2l = IcpOptions { metric: IcpMetric::PointToPlane, ..Default::default() };
        assert!(icp(&pts, &pts, None, &IDENTITY4, &p2l).is_err());
        let bad = IcpOptions { trim_fraction: 0.0, ..Default::default() };
        assert!(icp(&pts, &pts, None, &IDENTITY4, &bad).is_err());
        let far = IcpOptions { max_correspondence_distance: Some(1e-3), ..Default::default() };
        let shifted: Vec<Point3> = pts.iter().map(|p| [p[0] + 10.0, p[1], p[2]]).collect();
        assert!(icp(&shifted, &pts, None, &IDENTITY4, &far).is_err());
        // Coordinates whose squares overflow: an error, not a NaN transform.
        let huge: Vec<Point3> =
            pts.iter().map(|p| [1e300 + p[0] * 1e300, 1e300, 1e300 + p[1] * 1e300]).collect();
        let e = icp(&huge, &pts, None, &IDENTITY4, &o).expect_err("overflowing input");
        assert!(e.to_string().contains("diverged"), "{e}");
    }

    #[test]
    fn plane_slides_gracefully_point_to_plane() {
        // A planar target leaves in-plane motion free: the point-to-point fallback takes over
        // there and the result stays finite.
        let grid: Vec<Point3> =
            (0..400).map(|i| [(i % 20) as f64 * 0.05, (i / 20) as f64 * 0.05, 0.0]).collect();
        let normals = vec![[0.0, 0.0, 1.0]; grid.len()];
        let src: Vec<Point3> = grid.iter().map(|p| [p[0] + 0.01, p[1] - 0.02, p[2] + 0.3]).collect();
        for motion in [IcpMotion::Rigid, IcpMotion::TranslationOnly] {
            let o = IcpOptions {
                metric: IcpMetric::PointToPlane,
                motion,
                trim_fraction: 1.0,
                ..Default::default()
            };
            let r = icp(&src, &grid, Some(&normals), &IDENTITY4, &o).unwrap();
            assert!(r.transform.iter().flatten().all(|v| v.is_finite()));
            assert!((r.transform[2][3] + 0.3).abs() < 1e-9, "{:?}", r.transform);
            assert!(r.rmse < 1e-9);
        }
    }

    #[test]
    fn fit_rigid_recovers_a_motion_and_degrades_to_translation() {
        let pts: Vec<Point3> = (0..50)
            .map(|i| {
                let t = i as f64;
                [(t * 0.37).sin(), (t * 0.91).cos(), (t * 0.13).sin() * 0.5]
            })
            .collect();
        let m = mat4_from_rt(rotation_about_axis([0.3, -1.0, 0.4], 0.8), [0.2, -0.5, 1.5]);
        let moved: Vec<Point3> = pts.iter().map(|p| transform_point(&m, *p)).collect();
        let f = fit_rigid(&pts, &moved).unwrap();
        for (a, b) in f.iter().flatten().zip(m.iter().flatten()) {
            assert!((a - b).abs() < 1e-9, "{f:?} vs {m:?}");
        }
        // One point, or points on a line: the centroid's translation only.
        let line: Vec<Point3> = (0..5).map(|i| [i as f64, 0.0, 0.0]).collect();
        let shifted: Vec<Point3> = line.iter().map(|p| [p[0] + 1.0, p[1] + 2.0, p[2]]).collect();
        let f = fit_rigid(&line, &shifted).unwrap();
        assert_eq!(f, mat4_from_rt([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [1.0, 2.0, 0.0]));
        assert!(fit_rigid(&[], &[]).is_none());
        assert!(fit_rigid(&line, &shifted[..2]).is_none());
        assert!(fit_rigid(&[[f64::NAN, 0.0, 0.0]], &[[0.0; 3]]).is_none());
    }
}
