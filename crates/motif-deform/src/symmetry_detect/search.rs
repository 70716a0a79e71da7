//! Candidate generation and testing on one shape: directions from coordinate axes, principal
//! axes and pair votes; every rotation order per axis; scans around detected axes; screening,
//! refinement and validation of each candidate.

use std::time::Instant;

use motif_core::Point3;
use motif_core::geometry::{add, cross, normalize, scale};
use motif_core::progress::Progress;

use super::element::{SymmetryElement, canonical_sign, line_angle};
use super::options::{AnnotationContents, SymmetryDetectOptions};
use super::report::{CandidateReport, CandidateSource, CandidateStatus, Scope, Timings};
use super::shape::Shape;
use super::{candidates, ms, refine};

/// A validated (or approximate) element with its validation residual.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Found {
    pub(crate) element: SymmetryElement,
    pub(crate) residual: f64,
    pub(crate) status: CandidateStatus,
}

/// Tests one candidate: screening, refinement, validation. When `full` is false, a candidate
/// whose refined residual on the refinement samples exceeds the tolerance is not validated
/// (status [`CandidateStatus::Unverified`]).
pub(crate) fn test_candidate(
    shape: &Shape,
    o: &SymmetryDetectOptions,
    element: SymmetryElement,
    source: CandidateSource,
    scope: Scope,
    full: bool,
    timings: &mut Timings,
) -> CandidateReport {
    let s = &shape.surface;
    let t = Instant::now();
    // The screening samples are in spatial order: interleave them so that each block of 64
    // covers the whole shape and a bad candidate fails in the first block.
    let screening = s.residual_in_blocks(&shape.screen, &element.matrix(), o.screening_tolerance, 64);
    timings.screening_ms += ms(t);
    let mut report = CandidateReport {
        element,
        source,
        scope,
        status: CandidateStatus::Rejected,
        screening,
        refined: None,
        validation: None,
    };
    if !screening.complete || screening.max > o.screening_tolerance {
        return report;
    }
    let t = Instant::now();
    // Matches farther than twice the screening residual are outliers anyway, and far queries
    // are the expensive ones.
    let search = (2.0 * screening.max).clamp(5.0 * o.tolerance, o.screening_tolerance);
    // A candidate that will not be validated unless it can be verified is dropped as soon as
    // the coarse refinement shows it cannot (twice the tolerance on a subset of the samples).
    let give_up =
        if full { o.approximate_tolerance } else { (2.0 * o.tolerance).min(o.approximate_tolerance) };
    let Some(refined) = refine::refine(s, &shape.refine, element, o.refine_iterations, search, give_up)
    else {
        timings.refine_ms += ms(t);
        return report;
    };
    let refined = refined.canonical(shape.center);
    report.element = refined;
    let m = refined.matrix();
    let r = s.residual(&shape.refine, &m, o.approximate_tolerance);
    timings.refine_ms += ms(t);
    report.refined = Some(r);
    if !r.complete {
        return report;
    }
    if r.max > o.tolerance && !full {
        report.status = CandidateStatus::Unverified;
        return report;
    }
    let t = Instant::now();
    let v = s.residual(&shape.validate, &m, o.approximate_tolerance);
    timings.validation_ms += ms(t);
    report.validation = Some(v);
    report.status = if v.complete && v.max <= o.tolerance {
        CandidateStatus::Verified
    } else if v.complete {
        CandidateStatus::Approximate
    } else {
        CandidateStatus::Rejected
    };
    report
}

/// Adds `d` to `list` unless a line within `tol` radians is there.
pub(crate) fn push_direction(
    list: &mut Vec<(Point3, CandidateSource)>,
    d: Point3,
    source: CandidateSource,
    tol: f64,
) {
    let Some(d) = normalize(d) else { return };
    if !list.iter().any(|(e, _)| line_angle(*e, d) < tol) {
        list.push((canonical_sign(d), source));
    }
}

/// The elements found on a shape: verified and approximate, deduplicated.
pub(crate) struct Analysis {
    pub(crate) found: Vec<Found>,
}

/// Runs candidate generation and testing on `shape`, appending every tested candidate to
/// `reports`.
pub(crate) fn analyse(
    shape: &Shape,
    o: &SymmetryDetectOptions,
    scope: Scope,
    reports: &mut Vec<CandidateReport>,
    timings: &mut Timings,
    progress: &dyn Progress,
) -> Analysis {
    let c = shape.center;
    let pa = &shape.principal;
    let same = 1f64.to_radians();

    // Directions: coordinate axes, principal axes, votes.
    let mut axes: Vec<(Point3, CandidateSource)> = Vec::new();
    let mut normals: Vec<(Point3, CandidateSource)> = Vec::new();
    for k in 0..3 {
        let mut e = [0.0; 3];
        e[k] = 1.0;
        push_direction(&mut axes, e, CandidateSource::CoordinateAxis, same);
        push_direction(&mut normals, e, CandidateSource::CoordinateAxis, same);
    }
    for a in pa.axes {
        push_direction(&mut axes, a, CandidateSource::PrincipalAxis, same);
        push_direction(&mut normals, a, CandidateSource::PrincipalAxis, same);
    }
    let t = Instant::now();
    progress.start("pair votes", 0);
    let (mirror_peaks, axis_peaks) =
        candidates::vote(&shape.tris, c, shape.surface.diagonal, o.vote_sources, o.vote_peaks, o.seed);
    for p in &axis_peaks {
        push_direction(&mut axes, p.direction, CandidateSource::AxisVotes { votes: p.votes }, same);
    }
    for p in &mirror_peaks {
        push_direction(&mut normals, p.direction, CandidateSource::MirrorVotes { votes: p.votes }, same);
    }
    progress.finish();
    timings.votes_ms += ms(t);

    let t = Instant::now();
    progress.start("testing candidates", (axes.len() + normals.len()) as u64);
    let mut found: Vec<Found> = Vec::new();
    let all_approx = o.annotation == AnnotationContents::VerifiedAndApproximate;
    let record = |rep: CandidateReport, found: &mut Vec<Found>, reports: &mut Vec<CandidateReport>| {
        if matches!(rep.status, CandidateStatus::Verified | CandidateStatus::Approximate) {
            let residual = rep.validation.map_or(f64::INFINITY, |v| v.max);
            add_found(found, Found { element: rep.element, residual, status: rep.status });
        }
        reports.push(rep);
    };

    // Rotations: the largest order that validates about each axis.
    let mut scan_axes: Vec<(Point3, Point3, u32)> = Vec::new();
    for &(a, source) in &axes {
        let mut best_approx: Option<CandidateReport> = None;
        let mut validated_approx = false;
        for n in (2..=o.max_rotation_order).rev() {
            let e = SymmetryElement::Rotation { axis: a, point: c, order: n };
            // Near surfaces of revolution every order passes screening: fully validate only the
            // first order that cannot be verified (to report it as approximate), not all of them.
            let full = all_approx || !validated_approx;
            let rep = test_candidate(shape, o, e, source, scope, full, timings);
            if rep.validation.is_some() && rep.status != CandidateStatus::Verified {
                validated_approx = true;
            }
            match rep.status {
                CandidateStatus::Verified => {
                    if let SymmetryElement::Rotation { axis, point, order } = rep.element {
                        if order >= 3 {
                            scan_axes.push((axis, point, order));
                        }
                    }
                    record(rep, &mut found, reports);
                    best_approx = None;
                    break;
                }
                CandidateStatus::Approximate => {
                    if best_approx.is_none() {
                        best_approx = Some(rep.clone());
                    }
                    reports.push(rep);
                }
                CandidateStatus::Rejected | CandidateStatus::Unverified => reports.push(rep),
            }
        }
        if let Some(rep) = best_approx {
            let residual = rep.validation.map_or(f64::INFINITY, |v| v.max);
            add_found(&mut found, Found { element: rep.element, residual, status: rep.status });
        }
        progress.inc(1);
    }
    // Mirrors.
    for &(nrm, source) in &normals {
        let e = SymmetryElement::Mirror { normal: nrm, point: c };
        record(test_candidate(shape, o, e, source, scope, true, timings), &mut found, reports);
        progress.inc(1);
    }
    // Scans around rotation axes of order ≥ 3, and around the distinct principal axis when the
    // other two moments are equal (any direction of their plane is then a principal axis).
    let m = pa.moments;
    let rel = |a: f64, b: f64| (a - b).abs() / m[2].abs().max(1e-300);
    if rel(m[0], m[1]) < 1e-2 && rel(m[1], m[2]) >= 1e-2 {
        scan_axes.push((pa.axes[2], c, 1));
    }
    if rel(m[1], m[2]) < 1e-2 && rel(m[0], m[1]) >= 1e-2 {
        scan_axes.push((pa.axes[0], c, 1));
    }
    let mut scanned: Vec<Point3> = Vec::new();
    let t_scan = Instant::now();
    // The highest orders first; a few axes suffice (a polyhedral group's other axes are found
    // by the votes, and the group assembly generates the rest).
    scan_axes.sort_by_key(|x| std::cmp::Reverse(x.2));
    for (a, p, n) in scan_axes {
        if scanned.len() >= MAX_SCANNED_AXES || scanned.iter().any(|s| line_angle(*s, a) < same) {
            continue;
        }
        scanned.push(a);
        for (e, source) in scan_candidates(shape, o, a, p, n) {
            record(test_candidate(shape, o, e, source, scope, true, timings), &mut found, reports);
        }
        // The plane perpendicular to the axis, and the rotoreflection S₂ₙ about it.
        let e = SymmetryElement::Mirror { normal: a, point: p };
        record(
            test_candidate(shape, o, e, CandidateSource::FromAxis, scope, true, timings),
            &mut found,
            reports,
        );
        if n >= 2 {
            let e = SymmetryElement::RotoReflection { axis: a, point: p, order: 2 * n };
            record(
                test_candidate(shape, o, e, CandidateSource::FromAxis, scope, true, timings),
                &mut found,
                reports,
            );
        }
    }
    timings.scan_ms += ms(t_scan);
    // Rotoreflections about 2-fold axes (S4), and the inversion.
    let two_fold: Vec<(Point3, Point3)> = found
        .iter()
        .filter_map(|f| match f.element {
            SymmetryElement::Rotation { axis, point, order: 2 } if f.status == CandidateStatus::Verified => {
                Some((axis, point))
            }
            _ => None,
        })
        .collect();
    for (a, p) in two_fold {
        let e = SymmetryElement::RotoReflection { axis: a, point: p, order: 4 };
        record(
            test_candidate(shape, o, e, CandidateSource::FromAxis, scope, true, timings),
            &mut found,
            reports,
        );
    }
    let e = SymmetryElement::Inversion { center: c };
    record(test_candidate(shape, o, e, CandidateSource::Centroid, scope, true, timings), &mut found, reports);
    progress.finish();
    timings.test_ms += ms(t);
    Analysis { found }
}

/// Largest number of axes scanned for perpendicular mirrors and 2-fold axes.
const MAX_SCANNED_AXES: usize = 3;

/// Adds `f` unless the same element (type, line within 0.5°, same order) is there; keeps the
/// one with the lower residual.
pub(crate) fn add_found(list: &mut Vec<Found>, f: Found) {
    let tol = 0.5f64.to_radians();
    let same = |a: &SymmetryElement, b: &SymmetryElement| match (a, b) {
        (SymmetryElement::Mirror { normal: n1, .. }, SymmetryElement::Mirror { normal: n2, .. }) => {
            line_angle(*n1, *n2) < tol
        }
        (
            SymmetryElement::Rotation { axis: a1, order: o1, .. },
            SymmetryElement::Rotation { axis: a2, order: o2, .. },
        )
        | (
            SymmetryElement::RotoReflection { axis: a1, order: o1, .. },
            SymmetryElement::RotoReflection { axis: a2, order: o2, .. },
        ) => o1 == o2 && line_angle(*a1, *a2) < tol,
        (SymmetryElement::Inversion { .. }, SymmetryElement::Inversion { .. }) => true,
        _ => false,
    };
    match list.iter_mut().find(|g| same(&g.element, &f.element)) {
        Some(g) => {
            let better = (f.status == CandidateStatus::Verified && g.status != CandidateStatus::Verified)
                || (f.status == g.status && f.residual < g.residual);
            if better {
                *g = f;
            }
        }
        None => list.push(f),
    }
}

/// Mirror normals and 2-fold axes perpendicular to the axis `a` through `p`: local minima of
/// the screening residual over `φ ∈ [0, π/n)` (a group with an `n`-fold axis repeats its
/// mirror planes and 2-fold axes every `π/n`), the best three of each kind.
pub(crate) fn scan_candidates(
    shape: &Shape,
    o: &SymmetryDetectOptions,
    a: Point3,
    p: Point3,
    n: u32,
) -> Vec<(SymmetryElement, CandidateSource)> {
    let e1 = motif_core::geometry::any_orthonormal(a);
    let e2 = cross(a, e1);
    let span = std::f64::consts::PI / f64::from(n.max(1));
    let steps = ((span / o.scan_step_degrees.to_radians()).ceil() as usize).max(1);
    // The first 256 screening points span the shape (see `interleave`).
    let pts = &shape.screen[..shape.screen.len().min(256)];
    let dir = |i: usize| {
        let phi = span * i as f64 / steps as f64;
        add(scale(e1, phi.cos()), scale(e2, phi.sin()))
    };
    let mut out = Vec::new();
    for kind in 0..2 {
        let make = |d: Point3| {
            if kind == 0 {
                SymmetryElement::Mirror { normal: d, point: p }
            } else {
                SymmetryElement::Rotation { axis: d, point: p, order: 2 }
            }
        };
        let scores: Vec<f64> = (0..steps)
            .map(|i| {
                shape.surface.residual_in_blocks(pts, &make(dir(i)).matrix(), o.screening_tolerance, 32).max
            })
            .collect();
        let mut minima: Vec<(f64, usize)> = (0..steps)
            .filter(|&i| {
                let prev = scores[(i + steps - 1) % steps];
                let next = scores[(i + 1) % steps];
                scores[i] < o.screening_tolerance && scores[i] <= prev && scores[i] <= next
            })
            .map(|i| (scores[i], i))
            .collect();
        minima.sort_by(|x, y| x.0.total_cmp(&y.0));
        for (_, i) in minima.into_iter().take(3) {
            out.push((make(dir(i)), CandidateSource::AxisScan));
        }
    }
    out
}

/// One report per distinct element (the lowest residual of each).
pub(crate) fn dedupe_reports<'a>(reports: impl Iterator<Item = &'a CandidateReport>) -> Vec<CandidateReport> {
    let mut out: Vec<CandidateReport> = Vec::new();
    let mut found: Vec<Found> = Vec::new();
    for r in reports {
        let residual = r.validation.map_or(f64::INFINITY, |v| v.max);
        let before = found.len();
        add_found(&mut found, Found { element: r.element, residual, status: r.status });
        if found.len() > before {
            out.push(r.clone());
        } else if let Some(i) = out.iter().position(|o| {
            let mut tmp = vec![Found { element: o.element, residual: 0.0, status: o.status }];
            add_found(&mut tmp, Found { element: r.element, residual: 0.0, status: o.status });
            tmp.len() == 1
        }) {
            if out[i].validation.map_or(f64::INFINITY, |v| v.max) > residual {
                out[i] = r.clone();
            }
        }
    }
    out
}
