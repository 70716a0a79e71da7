//! ICP-like refinement of a symmetry element: Gauss–Newton on the point-to-surface distances of
//! the transformed samples, over the element's own parameters (plane normal and offset; axis
//! direction and position, the angle `2π / n` fixed), so the result stays an exact reflection or
//! rotation of the candidate's order.
//!
//! Each iteration matches every transformed sample `g(x)` to its closest surface point `z`,
//! keeps the pairs closer than three times the median distance (trimming, so a part of the shape
//! that is not symmetric cannot drag the element), and solves the damped normal equations of the
//! linearised distances `nᵀ(g(x) − z)`, with `n = (g(x) − z)/|g(x) − z|` (the gradient of the
//! distance field; the face normal on the surface). The Jacobian is taken by central differences
//! of the element's matrix, which are exact up to rounding for these smooth parametrisations.

use motif_core::Point3;
use motif_core::geometry::{dot, sub, transform_point};
use nalgebra::{DMatrix, DVector};

use super::element::SymmetryElement;
use super::residual::Surface;

/// Step of the central differences, in radians and units of the diagonal.
const H: f64 = 1e-6;

/// Gauss–Newton steps on the first `coarse` points (spread over the shape) before the candidate
/// is checked and the remaining steps run on every point.
pub(crate) const COARSE_POINTS: usize = 500;
/// Coarse steps.
const COARSE_STEPS: usize = 3;

/// Refines `element` on `points` for at most `iterations` Gauss–Newton steps: the first few on
/// the first [`COARSE_POINTS`] points, after which a candidate whose largest distance on those
/// points exceeds `give_up` (relative) is abandoned (`None`), then the rest on all points.
/// `search` is the largest distance (relative to the diagonal) at which a transformed point
/// still finds its match. Returns the best element seen.
pub(crate) fn refine(
    surface: &Surface,
    points: &[Point3],
    element: SymmetryElement,
    iterations: usize,
    search: f64,
    give_up: f64,
) -> Option<SymmetryElement> {
    let coarse = &points[..points.len().min(COARSE_POINTS)];
    let (e, _) = gauss_newton(surface, coarse, element, iterations.min(COARSE_STEPS), search);
    let r = surface.residual_in_blocks(coarse, &e.matrix(), give_up, 64);
    if !r.complete || r.max > give_up {
        return None;
    }
    if iterations <= COARSE_STEPS || coarse.len() == points.len() {
        return Some(e);
    }
    Some(gauss_newton(surface, points, e, iterations - COARSE_STEPS, search).0)
}

/// At most `iterations` damped Gauss–Newton steps on `points`; returns the best element seen and
/// its root-mean-square matched distance (relative).
fn gauss_newton(
    surface: &Surface,
    points: &[Point3],
    element: SymmetryElement,
    iterations: usize,
    search: f64,
) -> (SymmetryElement, f64) {
    let diag = surface.diagonal;
    let dof = element.dof();
    let mut current = element;
    let mut best = (element, f64::INFINITY);
    for _ in 0..=iterations {
        let m = current.matrix();
        let matches = surface.matches(points, &m, search);
        let mut d: Vec<f64> = matches.iter().filter_map(|(_, h)| h.map(|h| h.d2.sqrt())).collect();
        if d.len() < dof * 4 {
            break;
        }
        let mid = d.len() / 2;
        d.select_nth_unstable_by(mid, f64::total_cmp);
        let trim = (3.0 * d[mid]).max(1e-9 * diag);
        // Objective: RMS over all points, distances capped at the search radius, so steps that
        // push points out of reach are not rewarded.
        let cap = search * diag;
        let rms = (matches.iter().map(|(_, h)| h.map_or(cap * cap, |h| h.d2)).sum::<f64>()
            / matches.len() as f64)
            .sqrt()
            / diag;
        if rms < best.1 {
            let converged = rms > 0.999 * best.1;
            best = (current, rms);
            if converged {
                break;
            }
        } else {
            break;
        }
        if rms < 1e-13 {
            break;
        }
        // Matrices of the perturbed elements for the central differences.
        let perturbed: Vec<(motif_core::geometry::Mat4, motif_core::geometry::Mat4)> = (0..dof)
            .map(|k| {
                let mut p = vec![0.0; dof];
                p[k] = H;
                let plus = current.perturbed(&p, diag).matrix();
                p[k] = -H;
                let minus = current.perturbed(&p, diag).matrix();
                (plus, minus)
            })
            .collect();
        let mut jtj = DMatrix::<f64>::zeros(dof, dof);
        let mut jtr = DVector::<f64>::zeros(dof);
        let mut row = vec![0.0; dof];
        for ((q, hit), x) in matches.iter().zip(points) {
            let Some(hit) = hit else { continue };
            let dist = hit.d2.sqrt();
            if dist > trim {
                continue;
            }
            let v = sub(*q, hit.point);
            let n = if dist > 1e-12 * diag { [v[0] / dist, v[1] / dist, v[2] / dist] } else { hit.normal };
            let r = dot(n, v) / diag;
            for (k, (plus, minus)) in perturbed.iter().enumerate() {
                let dp = sub(transform_point(plus, *x), transform_point(minus, *x));
                row[k] = dot(n, dp) / (2.0 * H * diag);
            }
            for a in 0..dof {
                jtr[a] += row[a] * r;
                for b in 0..dof {
                    jtj[(a, b)] += row[a] * row[b];
                }
            }
        }
        let damping = 1e-9 * (0..dof).map(|k| jtj[(k, k)]).sum::<f64>().max(1e-30);
        for k in 0..dof {
            jtj[(k, k)] += damping;
        }
        let Some(step) = jtj.lu().solve(&(-jtr)) else { break };
        if !step.iter().all(|s| s.is_finite()) {
            break;
        }
        // Limit each step to a tenth of a radian / diagonal: beyond that the linearisation and
        // the matching are meaningless.
        let len = step.norm();
        let s = if len > 0.1 { 0.1 / len } else { 1.0 };
        let p: Vec<f64> = step.iter().map(|v| v * s).collect();
        current = current.perturbed(&p, diag);
        if len < 1e-12 {
            break;
        }
    }
    if best.1.is_infinite() {
        return (element, f64::INFINITY);
    }
    best
}
