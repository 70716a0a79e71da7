//! Point-cloud normals: PCA over the k nearest neighbours, then a consistent orientation.
//!
//! The unoriented normal of point `i` is the eigenvector of the smallest eigenvalue of the
//! covariance of its `k` nearest neighbours (the point itself included), i.e. the normal of the
//! least-squares plane through them (Hoppe et al., "Surface reconstruction from unorganized
//! points", SIGGRAPH 1992, §3.2).
//!
//! The sign is then fixed according to [`Orientation`]. The default, [`Orientation::Consistent`],
//! follows Hoppe et al. §3.3: a minimum spanning tree over the symmetrised kNN graph with edge
//! weight `1 − |nᵢ·nⱼ|` (so the propagation prefers edges across which the tangent plane barely
//! turns, and crosses sharp features through the blended normals PCA gives there), signs
//! propagated from the root of every connected component. By default ([`GraphWeight`]) the weight
//! also penalises edges that leave the tangent planes, `+ |nᵢ·êᵢⱼ| |nⱼ·êᵢⱼ|` with `êᵢⱼ` the unit
//! edge direction: across the two sides of a thin plate the normals are parallel, so Hoppe's
//! weight is 0 there and the sign jumps to the wrong side; the penalty makes the tree go round
//! the rim instead (a plate three sample spacings thick is oriented correctly with it, half wrong
//! without). Each component is then turned as a
//! whole so that its normals point **outward**: by the divergence theorem
//! `∮ n·(p − c) dA = 3·volume > 0` for any `c` when `n` is the outward normal of a closed surface,
//! so a component whose area-weighted sum `Σ aᵢ nᵢ·(pᵢ − c)` (`c` its centroid, `aᵢ ∝ rᵢ²` with
//! `rᵢ` the distance to the k-th neighbour, a local area estimate robust to uneven sampling) is
//! negative is flipped. This global vote is more robust than seeding at one extreme point, whose
//! single PCA normal decides everything. For an open, flat component the sum vanishes; then the
//! component's mean normal is made to point along the positive side of its dominant axis (e.g. a
//! horizontal patch gets normals towards +z).
//!
//! Output normals are unit length, one per input point, in the input's order.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use nalgebra::{Matrix3, SymmetricEigen};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::{Point3, dot, is_finite, scale, sub};
use crate::spatial::KdTree;
use crate::{Error, Result};

/// How the sign of the estimated normals is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Orientation {
    /// Consistent over the kNN graph (Hoppe et al. 1992 minimum spanning tree), each connected
    /// component turned so its normals point outward (see the module documentation). The default.
    #[default]
    Consistent,
    /// Every normal points towards this viewpoint (`n·(v − p) ≥ 0`), the usual choice for a
    /// single scan with a known sensor position. In the units of the input points.
    TowardsViewpoint(Point3),
    /// The raw PCA eigenvector, with an arbitrary sign per point.
    Unoriented,
}

/// Edge weights of the spanning tree along which [`Orientation::Consistent`] propagates signs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GraphWeight {
    /// `1 − |nᵢ·nⱼ|`, exactly Hoppe et al. 1992.
    Hoppe,
    /// `1 − |nᵢ·nⱼ| + |nᵢ·ê| |nⱼ·ê|`, `ê` the unit edge direction: Hoppe's weight plus a penalty
    /// on edges leaving the tangent planes, which keeps the propagation on one side of thin
    /// structures. The default.
    #[default]
    TangentPenalised,
}

/// Options of [`estimate_normals`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NormalsOptions {
    /// `k`, the number of nearest neighbours (the point itself included) whose covariance gives the
    /// normal, and the degree of the kNN graph used to orient normals. At least 3; values above
    /// the number of points are clamped. Default 16. The thesis (§5.3.1) takes its input with
    /// oriented normals; this is how Motif provides them for raw scans.
    pub neighbours: usize,
    /// How signs are chosen. Default [`Orientation::Consistent`] (outward on closed shapes).
    pub orientation: Orientation,
    /// Spanning-tree weights of [`Orientation::Consistent`] (ignored by the other modes).
    /// Default [`GraphWeight::TangentPenalised`]. Not specified by the thesis.
    pub graph_weight: GraphWeight,
}

impl Default for NormalsOptions {
    fn default() -> Self {
        NormalsOptions {
            neighbours: 16,
            orientation: Orientation::Consistent,
            graph_weight: GraphWeight::TangentPenalised,
        }
    }
}

impl NormalsOptions {
    fn validate(&self) -> Result<()> {
        if self.neighbours < 3 {
            return Err(Error::InvalidOption {
                name: "neighbours",
                message: format!("got {}, need at least 3 points to fit a plane", self.neighbours),
            });
        }
        if let Orientation::TowardsViewpoint(v) = self.orientation {
            if !is_finite(v) {
                return Err(Error::InvalidOption {
                    name: "orientation",
                    message: "the viewpoint has a NaN or infinite coordinate".into(),
                });
            }
        }
        Ok(())
    }
}

/// Estimates one unit normal per point by PCA over the `k` nearest neighbours and orients them
/// as `options.orientation` says (outward on closed shapes by default).
///
/// `points` is `#P × 3`; the result is `#P × 3`, unit length. Fails on fewer than 3 points,
/// non-finite coordinates or invalid options.
pub fn estimate_normals(points: &[Point3], options: &NormalsOptions) -> Result<Vec<Point3>> {
    Ok(estimate_normals_detailed(points, options)?.normals)
}

/// Estimated normals and how many of them the data did not determine.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatedNormals {
    /// One unit normal per point, as [`estimate_normals`] returns them.
    pub normals: Vec<Point3>,
    /// Points whose neighbourhood spans no plane: its `k` neighbours coincide or lie on one line
    /// (the covariance's middle eigenvalue is below [`UNDETERMINED_RATIO`] times the largest).
    /// Their normal is an arbitrary direction perpendicular to that line (or any direction).
    pub undetermined: usize,
}

/// Middle-to-largest covariance eigenvalue ratio below which a neighbourhood counts as a line or
/// a point, not a surface patch ([`EstimatedNormals::undetermined`]). 1e-10 is a relative spread
/// of 1e-5 across the line: far below any scan's noise, far above rounding.
pub const UNDETERMINED_RATIO: f64 = 1e-10;

/// [`estimate_normals`], also counting the normals the data did not determine.
pub fn estimate_normals_detailed(points: &[Point3], options: &NormalsOptions) -> Result<EstimatedNormals> {
    options.validate()?;
    if points.len() < 3 {
        return Err(Error::InvalidInput(format!(
            "normal estimation needs at least 3 points, got {}",
            points.len()
        )));
    }
    let tree = KdTree::new(points)?;
    normals_with_tree(points, &tree, options)
}

/// [`estimate_normals`] with a kd-tree the caller already built over `points`.
///
/// Fails when the tree was not built over a set of the same size.
pub fn estimate_normals_with_tree(
    points: &[Point3],
    tree: &KdTree,
    options: &NormalsOptions,
) -> Result<Vec<Point3>> {
    Ok(normals_with_tree(points, tree, options)?.normals)
}

fn normals_with_tree(points: &[Point3], tree: &KdTree, options: &NormalsOptions) -> Result<EstimatedNormals> {
    options.validate()?;
    if points.len() < 3 {
        return Err(Error::InvalidInput(format!(
            "normal estimation needs at least 3 points, got {}",
            points.len()
        )));
    }
    if tree.len() != points.len() {
        return Err(Error::InvalidInput(format!(
            "the kd-tree holds {} points but {} points were given",
            tree.len(),
            points.len()
        )));
    }
    let k = options.neighbours.min(points.len());
    let graph = KnnGraph::build(points, tree, k);

    let mut normals = vec![[0.0; 3]; points.len()];
    let undetermined: usize = normals
        .par_iter_mut()
        .enumerate()
        .map(|(i, n)| {
            let determined;
            (*n, determined) = pca_normal(points, points[i], graph.neighbours(i));
            usize::from(!determined)
        })
        .sum();

    match options.orientation {
        Orientation::Unoriented => {}
        Orientation::TowardsViewpoint(v) => {
            normals.par_iter_mut().zip(points.par_iter()).for_each(|(n, p)| {
                if dot(*n, sub(v, *p)) < 0.0 {
                    *n = scale(*n, -1.0);
                }
            });
        }
        Orientation::Consistent => orient_consistently(points, &graph, options.graph_weight, &mut normals),
    }
    Ok(EstimatedNormals { normals, undetermined })
}

/// The kNN lists of every point, flattened (`k` entries per point, the point itself included), and
/// the distance to each point's farthest (k-th) neighbour.
struct KnnGraph {
    k: usize,
    indices: Vec<u32>,
    radius: Vec<f64>,
}

impl KnnGraph {
    fn build(points: &[Point3], tree: &KdTree, k: usize) -> KnnGraph {
        let n = points.len();
        let mut indices = vec![0u32; n * k];
        let mut radius = vec![0.0; n];
        indices.par_chunks_mut(k).zip(radius.par_iter_mut()).enumerate().for_each(|(i, (row, r))| {
            // `KdTree::knn` returns a fresh Vec; the tree API has no buffer-reusing variant.
            let found = tree.knn(points[i], k);
            for (slot, nb) in row.iter_mut().zip(&found) {
                *slot = nb.index as u32;
            }
            *r = found.last().map_or(0.0, |nb| nb.distance);
        });
        KnnGraph { k, indices, radius }
    }

    fn neighbours(&self, i: usize) -> &[u32] {
        &self.indices[i * self.k..(i + 1) * self.k]
    }
}

/// Unit normal of the least-squares plane through `nbrs` (covariance about their centroid,
/// accumulated relative to `origin` to avoid cancellation far from the coordinate origin), and
/// whether the neighbours span a plane at all (see [`UNDETERMINED_RATIO`]).
fn pca_normal(points: &[Point3], origin: Point3, nbrs: &[u32]) -> (Point3, bool) {
    let cov = covariance(nbrs.iter().map(|&j| sub(points[j as usize], origin)));
    let (values, vectors) = sorted_eigen(&cov);
    (vectors[0], values[2] > 0.0 && values[1] > UNDETERMINED_RATIO * values[2])
}

/// Covariance (not divided by the count) of a set of vectors about their mean.
pub(crate) fn covariance(vs: impl Iterator<Item = Point3> + Clone) -> Matrix3<f64> {
    let mut mean = [0.0; 3];
    let mut count = 0usize;
    for v in vs.clone() {
        mean = crate::geometry::add(mean, v);
        count += 1;
    }
    if count == 0 {
        return Matrix3::zeros();
    }
    mean = scale(mean, 1.0 / count as f64);
    let mut c = Matrix3::zeros();
    for v in vs {
        let d = sub(v, mean);
        for r in 0..3 {
            for s in r..3 {
                c[(r, s)] += d[r] * d[s];
            }
        }
    }
    for r in 0..3 {
        for s in 0..r {
            c[(r, s)] = c[(s, r)];
        }
    }
    c
}

/// Eigenvectors of a symmetric 3×3 matrix sorted by ascending eigenvalue, as unit columns, with
/// the third recomputed as the cross product of the first two so the frame is right-handed.
pub(crate) fn sorted_eigenvectors(cov: &Matrix3<f64>) -> [Point3; 3] {
    sorted_eigen(cov).1
}

/// [`sorted_eigenvectors`] with their eigenvalues, ascending.
fn sorted_eigen(cov: &Matrix3<f64>) -> ([f64; 3], [Point3; 3]) {
    let eig = SymmetricEigen::new(*cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let col = |i: usize| {
        let c = eig.eigenvectors.column(order[i]);
        crate::geometry::normalize([c[0], c[1], c[2]])
    };
    let values = order.map(|i| eig.eigenvalues[i]);
    let vectors = match (col(0), col(1)) {
        (Some(a), Some(b)) => {
            // Re-orthogonalise b against a in case the solver returned a slightly skewed pair.
            let b = crate::geometry::normalize(sub(b, scale(a, dot(a, b))))
                .unwrap_or_else(|| crate::geometry::any_orthonormal(a));
            [a, b, crate::geometry::cross(a, b)]
        }
        _ => [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
    };
    (values, vectors)
}

/// Hoppe-style orientation: MST over the symmetrised kNN graph (Prim, weight `1 − |nᵢ·nⱼ|`),
/// sign propagation from each component's root, then an outward vote per component.
fn orient_consistently(
    points: &[Point3],
    graph: &KnnGraph,
    weight_kind: GraphWeight,
    normals: &mut [Point3],
) {
    let n = points.len();
    let adjacency = symmetric_adjacency(graph, n);

    let mut visited = vec![false; n];
    // Lightest known edge into every unvisited vertex: only improvements are pushed, which keeps
    // the lazy heap close to #V entries instead of #E.
    let mut best = vec![f64::INFINITY; n];
    let mut heap: BinaryHeap<Reverse<(u64, u32, u32)>> = BinaryHeap::new();
    let mut component: Vec<u32> = Vec::new();
    for root in 0..n {
        if visited[root] {
            continue;
        }
        component.clear();
        heap.clear();
        heap.push(Reverse((0, root as u32, root as u32)));
        while let Some(Reverse((_, v, parent))) = heap.pop() {
            let v = v as usize;
            if visited[v] {
                continue;
            }
            visited[v] = true;
            component.push(v as u32);
            if v != parent as usize && dot(normals[v], normals[parent as usize]) < 0.0 {
                normals[v] = scale(normals[v], -1.0);
            }
            for &w in adjacency.neighbours(v) {
                let wi = w as usize;
                if !visited[wi] {
                    // Clamped at 0 against rounding: non-negative f64 order like their bits.
                    let mut weight = (1.0 - dot(normals[v], normals[wi]).abs()).max(0.0);
                    if weight_kind == GraphWeight::TangentPenalised {
                        let e = crate::geometry::normalize(sub(points[wi], points[v])).unwrap_or([0.0; 3]);
                        weight += dot(normals[v], e).abs() * dot(normals[wi], e).abs();
                    }
                    if weight < best[wi] {
                        best[wi] = weight;
                        heap.push(Reverse((weight.to_bits(), w, v as u32)));
                    }
                }
            }
        }
        if outward_vote(points, graph, normals, &component) < 0.0 {
            for &v in &component {
                normals[v as usize] = scale(normals[v as usize], -1.0);
            }
        }
    }
}

/// Positive when the component's normals point outward (see the module documentation).
fn outward_vote(points: &[Point3], graph: &KnnGraph, normals: &[Point3], component: &[u32]) -> f64 {
    let mut c = [0.0; 3];
    for &v in component {
        c = crate::geometry::add(c, points[v as usize]);
    }
    c = scale(c, 1.0 / component.len() as f64);
    let mut flux = 0.0;
    let mut area = 0.0;
    let mut extent2: f64 = 0.0;
    let mut mean_normal = [0.0; 3];
    for &v in component {
        let v = v as usize;
        let a = graph.radius[v] * graph.radius[v];
        let d = sub(points[v], c);
        flux += a * dot(normals[v], d);
        area += a;
        extent2 = extent2.max(dot(d, d));
        mean_normal = crate::geometry::add(mean_normal, scale(normals[v], a));
    }
    // |flux| ≤ area × extent; below a small fraction of that the component is flat or open and
    // the divergence vote carries no information.
    if flux.abs() > 1e-3 * area * extent2.sqrt() {
        return flux;
    }
    let axis = (0..3).max_by(|&a, &b| mean_normal[a].abs().total_cmp(&mean_normal[b].abs())).unwrap_or(2);
    mean_normal[axis]
}

/// Compressed adjacency lists of the kNN graph made symmetric (j ∈ kNN(i) or i ∈ kNN(j)).
/// Duplicate edges are harmless for Prim's algorithm and are kept.
struct Adjacency {
    offsets: Vec<usize>,
    targets: Vec<u32>,
}

impl Adjacency {
    fn neighbours(&self, v: usize) -> &[u32] {
        &self.targets[self.offsets[v]..self.offsets[v + 1]]
    }
}

fn symmetric_adjacency(graph: &KnnGraph, n: usize) -> Adjacency {
    let mut degree = vec![0usize; n + 1];
    for i in 0..n {
        for &j in graph.neighbours(i) {
            if j as usize != i {
                degree[i] += 1;
                degree[j as usize] += 1;
            }
        }
    }
    let mut offsets = vec![0usize; n + 1];
    for i in 0..n {
        offsets[i + 1] = offsets[i] + degree[i];
    }
    let mut fill = offsets.clone();
    let mut targets = vec![0u32; offsets[n]];
    for i in 0..n {
        for &j in graph.neighbours(i) {
            let j = j as usize;
            if j != i {
                targets[fill[i]] = j as u32;
                fill[i] += 1;
                targets[fill[j]] = i as u32;
                fill[j] += 1;
            }
        }
    }
    Adjacency { offsets, targets }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_normals_are_unit_and_vertical() {
        let pts: Vec<Point3> =
            (0..400).map(|i| [(i % 20) as f64 * 0.1, (i / 20) as f64 * 0.1, 0.0]).collect();
        let n = estimate_normals(&pts, &NormalsOptions::default()).unwrap();
        for v in &n {
            // An open flat patch falls back to the dominant-axis rule: +z.
            assert!((v[2] - 1.0).abs() < 1e-9, "{v:?}");
        }
    }

    #[test]
    fn neighbourhoods_without_a_plane_are_counted() {
        // A 20×20 grid (determined), a heap of 30 coincident points and a line of 40 points far
        // away: the heap's and the line's normals are arbitrary, and counted as such.
        let mut pts: Vec<Point3> =
            (0..400).map(|i| [(i % 20) as f64 * 0.1, (i / 20) as f64 * 0.1, 0.0]).collect();
        pts.extend(std::iter::repeat_n([50.0, 50.0, 50.0], 30));
        pts.extend((0..40).map(|i| [-50.0 + 0.1 * i as f64, -50.0, 7.0]));
        let est = estimate_normals_detailed(&pts, &NormalsOptions::default()).unwrap();
        assert_eq!(est.undetermined, 70);
        assert_eq!(est.normals.len(), pts.len());
        // A slightly noisy plane is determined everywhere.
        let noisy: Vec<Point3> = (0..400)
            .map(|i| [(i % 20) as f64 * 0.1, (i / 20) as f64 * 0.1, 1e-4 * ((i * 7919) % 13) as f64])
            .collect();
        assert_eq!(estimate_normals_detailed(&noisy, &NormalsOptions::default()).unwrap().undetermined, 0);
    }

    #[test]
    fn viewpoint_orientation() {
        let pts: Vec<Point3> = (0..100).map(|i| [(i % 10) as f64, (i / 10) as f64, 0.0]).collect();
        let opts = NormalsOptions {
            orientation: Orientation::TowardsViewpoint([0.0, 0.0, -5.0]),
            ..Default::default()
        };
        for v in estimate_normals(&pts, &opts).unwrap() {
            assert!(v[2] < -0.999);
        }
    }

    #[test]
    fn rejects_bad_input() {
        assert!(estimate_normals(&[[0.0; 3]; 2], &NormalsOptions::default()).is_err());
        let opts = NormalsOptions { neighbours: 2, ..Default::default() };
        assert!(estimate_normals(&[[0.0; 3]; 10], &opts).is_err());
        assert!(estimate_normals(&[[f64::NAN, 0.0, 0.0]; 10], &NormalsOptions::default()).is_err());
    }

    #[test]
    fn coincident_points_give_finite_normals() {
        let pts = vec![[1.0, 2.0, 3.0]; 50];
        for v in estimate_normals(&pts, &NormalsOptions::default()).unwrap() {
            assert!(is_finite(v));
            assert!((crate::geometry::norm(v) - 1.0).abs() < 1e-9);
        }
    }
}
