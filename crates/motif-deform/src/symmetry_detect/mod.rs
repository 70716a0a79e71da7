//! Automatic detection of global (and, from congruent parts, partial) symmetries of a triangle
//! mesh, written as a `motif_symmetry_v1` annotation (`../shared/formats/symmetry.md`) so nobody
//! has to write 4×4 matrices by hand (thesis 3.2: "we use both manual annotation as well as
//! automatic detection").
//!
//! Pipeline of [`detect_symmetries`]:
//! 1. **Centre and candidates.** Every global symmetry fixes the area-weighted centroid `c`, so
//!    candidates are directions through `c`: the coordinate axes, the principal axes of the
//!    area-weighted covariance, and the peaks of votes of matched triangle pairs (a pair with
//!    equal invariants proposes the plane bisecting it and the axis turning one into the
//!    other), see [`candidates`](self) internals. Each axis is tried as a rotation axis of
//!    every order `max_rotation_order..=2` (the largest order that validates is kept), each
//!    direction as a mirror normal, and the inversion through `c` and the rotoreflections
//!    `S₂ₙ` about detected axes are tried too. Around each detected axis of order `n ≥ 3` (and
//!    the distinct principal axis when the other two moments are equal, where principal axes
//!    say nothing) mirror normals and 2-fold axes perpendicular to it are scanned over
//!    `[0, π/n)`.
//! 2. **Validation by closest-point residual.** A candidate is screened on a few hundred
//!    samples, refined by Gauss–Newton on point-to-surface distances (ICP-like, the element's
//!    type and order kept), then the largest distance from the transformed validation points
//!    (area-uniform samples and mesh vertices) to the surface — exact point–triangle distance
//!    through a bounding-volume hierarchy — is compared with the tolerance (relative to the
//!    bounding-box diagonal): verified, approximate, or rejected.
//! 3. **Group assembly.** Verified elements are added greedily (higher rotation orders first,
//!    then mirrors, then the rest, lowest residual first) as long as the group they generate is
//!    finite, has no axis of an order above `max_rotation_order`, and each of its new elements
//!    passes the same validation as a candidate. Elements
//!    nearly aligned with the principal axis of the group are snapped onto it, so the written
//!    generators generate the group exactly. The annotation holds the full group with an
//!    irredundant generator set, region `"all"`.
//! 4. **Partial symmetries** (optional): each class of congruent connected components is
//!    analysed like a whole shape; a group it has that the shape lacks is written with the
//!    largest union of components it maps onto itself as its region (the windmill's 4-fold
//!    rotor).
//!
//! The report lists every candidate with its residuals, the approximate symmetries, and the
//! groups with their structure (Schoenflies symbol, rotation axes and orders, mirror planes).
//!
//! Conventions: transforms are row-major 4×4 acting on column vectors; residuals and tolerances
//! are relative to the bounding-box diagonal of the mesh. Detection is deterministic for a seed.

mod bvh;
mod candidates;
mod element;
mod error;
mod group;
mod options;
mod partial;
mod refine;
mod residual;

use std::time::Instant;

use motif_core::Point3;
use motif_core::geometry::{IDENTITY4, Mat4, add, cross, dot, norm, normalize, scale, sub};
use motif_core::mesh::TriMesh;
use motif_core::procedural::{Region, SYMMETRY_FORMAT, Symmetry, SymmetryAnnotation, SymmetryKind};
use motif_core::progress::{NoProgress, Progress};
use motif_core::sampling::sample_surface;
use serde::{Deserialize, Serialize};

pub use candidates::PrincipalAxes;
pub use element::SymmetryElement;
pub use error::{Result, SymmetryDetectError};
pub use group::{GroupStructure, TransformMetric, group_closure, group_contains};
pub use options::{AnnotationContents, PartialSymmetries, SymmetryDetectOptions, ValidationPoints};
pub use residual::Residual;

use bvh::TriangleBvh;
use element::{canonical_sign, closest_on_line, line_angle};
use residual::Surface;

/// Where a candidate came from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "source", rename_all = "snake_case")]
pub enum CandidateSource {
    /// A coordinate axis through the centroid.
    CoordinateAxis,
    /// A principal axis of the area-weighted covariance.
    PrincipalAxis,
    /// A peak of the mirror votes of matched triangle pairs.
    MirrorVotes {
        /// Votes in the peak's histogram cell.
        votes: usize,
    },
    /// A peak of the rotation-axis votes of matched triangle pairs.
    AxisVotes {
        /// Votes in the peak's histogram cell.
        votes: usize,
    },
    /// A local minimum of the scan around a detected axis.
    AxisScan,
    /// Derived from a detected axis: the plane perpendicular to it, a rotoreflection about it.
    FromAxis,
    /// The inversion through the centroid.
    Centroid,
}

/// The outcome of testing one candidate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CandidateStatus {
    /// Largest residual on the validation points within `tolerance`.
    Verified,
    /// Largest residual within `approximate_tolerance` but above `tolerance`.
    Approximate,
    /// Passed screening, but after refinement its residual on the refinement samples already
    /// exceeds `tolerance` (so it cannot be verified); not validated further to save time. Its
    /// `refined` residual is a lower bound of the validation residual.
    Unverified,
    /// Rejected at screening, after refinement, or at validation (residual above
    /// `approximate_tolerance`).
    Rejected,
}

/// Which part of the shape a candidate was tested on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "scope", content = "index", rename_all = "snake_case")]
pub enum Scope {
    /// The whole mesh.
    Global,
    /// The union of the components of class `index` of [`SymmetryReport::parts`].
    Part(usize),
}

/// One tested candidate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CandidateReport {
    /// The element: as refined when the candidate reached refinement, else as proposed.
    pub element: SymmetryElement,
    /// Where it came from.
    pub source: CandidateSource,
    /// Whole shape or a part.
    pub scope: Scope,
    /// The verdict.
    pub status: CandidateStatus,
    /// Residual of the unrefined candidate on the screening samples (capped at
    /// `screening_tolerance`).
    pub screening: Residual,
    /// Residual of the refined candidate on the refinement samples (capped at
    /// `approximate_tolerance`), when it got that far.
    pub refined: Option<Residual>,
    /// Residual on the validation points (capped at `approximate_tolerance`), when it got that
    /// far.
    pub validation: Option<Residual>,
}

/// A detected group.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroupReport {
    /// The name written into the annotation.
    pub name: String,
    /// Whole shape or a part.
    pub scope: Scope,
    /// Schoenflies symbol, order, axes and planes.
    pub structure: GroupStructure,
    /// The generators written into the annotation, as geometric elements.
    pub generators: Vec<SymmetryElement>,
    /// The generators as row-major 4×4 matrices (exactly as in the annotation).
    pub generator_matrices: Vec<Mat4>,
    /// Largest residual (relative) over the validation of every group element.
    pub max_residual: f64,
    /// Number of faces of the region (`None`: the whole mesh).
    pub region_faces: Option<usize>,
    /// True when the highest-order axis has the largest order tested (`max_rotation_order`):
    /// the shape is probably a surface of revolution at this tolerance, and the group written is
    /// a finite subgroup of its continuous symmetry (thesis 3.2: continuous symmetries are not
    /// handled).
    pub possibly_continuous: bool,
}

/// A class of congruent connected components analysed for partial symmetry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartReport {
    /// Number of components in the class.
    pub components: usize,
    /// Number of faces of their union.
    pub faces: usize,
    /// Area-weighted centroid of their union.
    pub center: Point3,
}

/// Wall-clock times of the stages, milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Timings {
    /// Cleaning, sampling, acceleration structure, principal axes.
    pub prepare_ms: f64,
    /// Pair votes.
    pub votes_ms: f64,
    /// Testing every candidate (screening, refinement, validation, scans).
    pub test_ms: f64,
    /// Of which screening (summed over candidates and parts).
    pub screening_ms: f64,
    /// Of which refinement.
    pub refine_ms: f64,
    /// Of which validation.
    pub validation_ms: f64,
    /// Of which the scans around axes (including testing what they propose).
    pub scan_ms: f64,
    /// Group assembly.
    pub group_ms: f64,
    /// Partial symmetries.
    pub partial_ms: f64,
    /// Everything.
    pub total_ms: f64,
}

/// Everything detection measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SymmetryReport {
    /// Bounding-box diagonal (absolute), the unit of every relative residual.
    pub diagonal: f64,
    /// Principal axes and area-weighted centroid of the surface.
    pub principal: PrincipalAxes,
    /// Number of validation points (samples plus vertices).
    pub validation_points: usize,
    /// Every candidate tested, in testing order.
    pub candidates: Vec<CandidateReport>,
    /// The approximate symmetries (status `Approximate`, one per element).
    pub approximate: Vec<CandidateReport>,
    /// The groups found (global first).
    pub groups: Vec<GroupReport>,
    /// Classes of congruent components analysed for partial symmetry.
    pub parts: Vec<PartReport>,
    /// Stage times.
    pub timings: Timings,
}

/// The result of [`detect_symmetries`]: the annotation and the report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SymmetryDetection {
    /// The `motif_symmetry_v1` annotation: one group per detected symmetry.
    pub annotation: SymmetryAnnotation,
    /// Candidates, residuals, groups and timings.
    pub report: SymmetryReport,
}

impl SymmetryDetection {
    /// The global group (scope [`Scope::Global`]), if any symmetry was found.
    pub fn global_group(&self) -> Option<&GroupReport> {
        self.report.groups.iter().find(|g| g.scope == Scope::Global)
    }
}

/// Detects the symmetries of `mesh` (see the module documentation).
///
/// ```
/// use motif_core::procedural::generate;
/// use motif_deform::symmetry_detect::{SymmetryDetectOptions, detect_symmetries};
///
/// let gear = generate("gear", 0).unwrap();
/// let found = detect_symmetries(&gear.mesh, &SymmetryDetectOptions::default()).unwrap();
/// let g = found.global_group().unwrap();
/// // 17-fold rotation, 17 mirror planes through its axis, and the mid-plane mirror.
/// assert_eq!(g.structure.schoenflies, "D17h");
/// assert_eq!(g.structure.order, 68);
/// let json = serde_json::to_string_pretty(&found.annotation).unwrap();
/// assert!(json.contains("motif_symmetry_v1"));
/// ```
pub fn detect_symmetries(mesh: &TriMesh, options: &SymmetryDetectOptions) -> Result<SymmetryDetection> {
    detect_symmetries_with_progress(mesh, options, &NoProgress)
}

/// [`detect_symmetries`] reporting its stages to `progress`.
pub fn detect_symmetries_with_progress(
    mesh: &TriMesh,
    options: &SymmetryDetectOptions,
    progress: &dyn Progress,
) -> Result<SymmetryDetection> {
    options.validate()?;
    mesh.validate()?;
    let t0 = Instant::now();
    let mut timings = Timings::default();
    let diag = mesh.diagonal();
    progress.start("preparing", 0);
    let shape = Shape::new(mesh, &non_degenerate(mesh), diag, options, options.seed)?;
    progress.finish();
    timings.prepare_ms = ms(t0);

    let mut candidates = Vec::new();
    let analysis = analyse(&shape, options, Scope::Global, &mut candidates, &mut timings, progress);
    let t = Instant::now();
    progress.start("assembling the group", 0);
    let include_approx = options.annotation == AnnotationContents::VerifiedAndApproximate;
    let tol = if include_approx { options.approximate_tolerance } else { options.tolerance };
    let mut groups = Vec::new();
    let mut found: Vec<AssembledGroup> = Vec::new();
    if let Some(g) = assemble(&shape, &analysis, options, tol, include_approx) {
        groups.push(g.report(Scope::Global, None));
        found.push(g);
    }
    progress.finish();
    timings.group_ms = ms(t);

    let t = Instant::now();
    let mut parts = Vec::new();
    let mut partial_symmetries = Vec::new();
    if options.partial == PartialSymmetries::ComponentClasses {
        progress.start("partial symmetries", 0);
        let global = found.first().map(|g| g.elements.clone()).unwrap_or_else(|| vec![IDENTITY4]);
        let (classes, results) = partial::detect(
            mesh,
            diag,
            &shape,
            &global,
            options,
            tol,
            include_approx,
            &mut candidates,
            progress,
        )?;
        parts = classes;
        for r in results {
            groups.push(r.group.report(Scope::Part(r.part), Some(r.faces.len())));
            partial_symmetries.push(Symmetry {
                name: format!("part: {}", r.group.name),
                kind: SymmetryKind::Group { region: Region::Faces(r.faces), generators: r.group.generators },
            });
        }
        progress.finish();
    }
    timings.partial_ms = ms(t);

    let mut annotation =
        SymmetryAnnotation { format: SYMMETRY_FORMAT.to_string(), tolerance: tol, symmetries: Vec::new() };
    for g in &found {
        annotation.symmetries.push(Symmetry {
            name: g.name.clone(),
            kind: SymmetryKind::Group { region: Region::All, generators: g.generators.clone() },
        });
    }
    annotation.symmetries.extend(partial_symmetries);
    let approximate = dedupe_reports(
        candidates.iter().filter(|c| c.status == CandidateStatus::Approximate && c.scope == Scope::Global),
    );
    timings.total_ms = ms(t0);
    Ok(SymmetryDetection {
        annotation,
        report: SymmetryReport {
            diagonal: diag,
            principal: shape.principal,
            validation_points: shape.validate.len(),
            candidates,
            approximate,
            groups,
            parts,
            timings,
        },
    })
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Corner positions of the triangles with positive area.
fn non_degenerate(mesh: &TriMesh) -> Vec<usize> {
    (0..mesh.num_triangles()).filter(|&f| norm(mesh.face_cross(f)) > 0.0).collect()
}

/// `points` (in spatial order) regrouped into blocks of `block` consecutive points, each taking
/// every `n/block`-th point: every block spans the whole set while points within a block keep
/// some coherence.
fn interleave(points: &[Point3], block: usize) -> Vec<Point3> {
    let n = points.len();
    let blocks = n.div_ceil(block.max(1)).max(1);
    let mut out = Vec::with_capacity(n);
    for b in 0..blocks {
        out.extend(points.iter().skip(b).step_by(blocks).copied());
    }
    out
}

/// The surface under analysis (the whole mesh or a union of parts) with its point sets.
pub(crate) struct Shape {
    surface: Surface,
    principal: PrincipalAxes,
    center: Point3,
    /// Largest distance of a validation point from the centre (absolute).
    radius: f64,
    screen: Vec<Point3>,
    refine: Vec<Point3>,
    validate: Vec<Point3>,
    tris: Vec<[Point3; 3]>,
}

impl Shape {
    /// Prepares the faces `faces` of `mesh`; residuals are relative to `diag`.
    fn new(
        mesh: &TriMesh,
        faces: &[usize],
        diag: f64,
        o: &SymmetryDetectOptions,
        seed: u64,
    ) -> Result<Shape> {
        if faces.is_empty() || diag.is_nan() || diag <= 0.0 {
            return Err(SymmetryDetectError::NoSurface);
        }
        let tris: Vec<[Point3; 3]> = faces.iter().map(|&f| mesh.corners(f)).collect();
        let principal = candidates::principal_axes(&tris).ok_or(SymmetryDetectError::NoSurface)?;
        let bvh = TriangleBvh::new(&tris).ok_or(SymmetryDetectError::NoSurface)?;
        // A compact copy of the faces for sampling (sampling needs a mesh).
        let mut used = vec![u32::MAX; mesh.num_vertices()];
        let mut sub_mesh = TriMesh::default();
        for &f in faces {
            let mut t = [0u32; 3];
            for (k, &v) in mesh.triangles[f].iter().enumerate() {
                if used[v as usize] == u32::MAX {
                    used[v as usize] = sub_mesh.positions.len() as u32;
                    sub_mesh.positions.push(mesh.positions[v as usize]);
                }
                t[k] = used[v as usize];
            }
            sub_mesh.triangles.push(t);
        }
        let n = o.validation_samples + o.screening_samples + o.refine_samples;
        let samples = sample_surface(&sub_mesh, n, seed)?.points;
        let mut validate: Vec<Point3> = samples[..o.validation_samples].to_vec();
        let mut screen = samples[o.validation_samples..o.validation_samples + o.screening_samples].to_vec();
        let mut refine = samples[o.validation_samples + o.screening_samples..].to_vec();
        if o.validation_points == ValidationPoints::SamplesAndVertices {
            validate.extend_from_slice(&sub_mesh.positions);
        }
        // Spatially coherent query order: several times faster closest-point queries. The
        // screening samples are then dealt into 64-point blocks that each span the shape.
        for set in [&mut validate, &mut screen, &mut refine] {
            bvh::sort_spatially(set);
        }
        let screen = interleave(&screen, 64);
        let refine = interleave(&refine, refine::COARSE_POINTS);
        let center = principal.center;
        let radius = validate.iter().map(|p| norm(sub(*p, center))).fold(0.0, f64::max).max(1e-12 * diag);
        Ok(Shape {
            surface: Surface { bvh, diagonal: diag },
            principal,
            center,
            radius,
            screen,
            refine,
            validate,
            tris,
        })
    }

    fn metric(&self) -> TransformMetric {
        TransformMetric { center: self.center, radius: self.radius }
    }
}

/// A validated (or approximate) element with its validation residual.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Found {
    element: SymmetryElement,
    residual: f64,
    status: CandidateStatus,
}

/// Tests one candidate: screening, refinement, validation. When `full` is false, a candidate
/// whose refined residual on the refinement samples exceeds the tolerance is not validated
/// (status [`CandidateStatus::Unverified`]).
fn test_candidate(
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
fn push_direction(list: &mut Vec<(Point3, CandidateSource)>, d: Point3, source: CandidateSource, tol: f64) {
    let Some(d) = normalize(d) else { return };
    if !list.iter().any(|(e, _)| line_angle(*e, d) < tol) {
        list.push((canonical_sign(d), source));
    }
}

/// The elements found on a shape: verified and approximate, deduplicated.
pub(crate) struct Analysis {
    found: Vec<Found>,
}

/// Runs candidate generation and testing on `shape`, appending every tested candidate to
/// `reports`.
fn analyse(
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
fn add_found(list: &mut Vec<Found>, f: Found) {
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
fn scan_candidates(
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

/// A group assembled from found elements.
pub(crate) struct AssembledGroup {
    name: String,
    elements: Vec<Mat4>,
    generators: Vec<Mat4>,
    structure: GroupStructure,
    residual: f64,
    center: Point3,
    /// `max_rotation_order` of the options (for [`GroupReport::possibly_continuous`]).
    max_order: u32,
}

impl AssembledGroup {
    fn report(&self, scope: Scope, region_faces: Option<usize>) -> GroupReport {
        GroupReport {
            name: self.name.clone(),
            scope,
            structure: self.structure.clone(),
            generators: self.generators.iter().filter_map(|m| group::element_of(m, self.center)).collect(),
            generator_matrices: self.generators.clone(),
            max_residual: self.residual,
            region_faces,
            possibly_continuous: self
                .structure
                .rotation_axes
                .first()
                .is_some_and(|(_, n)| *n >= self.max_order),
        }
    }
}

/// Angle within which an element is snapped onto (or perpendicular to) the principal axis.
const SNAP: f64 = 3.0 * std::f64::consts::PI / 180.0;

/// The element moved so that it is exactly compatible with the principal axis `(a, p)`: planes
/// and 2-fold axes nearly containing / perpendicular to the axis are made exactly so.
fn snap(e: SymmetryElement, a: Point3, p: Point3) -> SymmetryElement {
    let perp = |d: Point3| dot(d, a).abs() < SNAP.sin();
    match e {
        SymmetryElement::Mirror { normal, point } => {
            if perp(normal) {
                let n = normalize(sub(normal, scale(a, dot(normal, a)))).unwrap_or(normal);
                SymmetryElement::Mirror { normal: n, point: p }
            } else if line_angle(normal, a) < SNAP {
                SymmetryElement::Mirror { normal: a, point: closest_on_line(point, p, a) }
            } else {
                e
            }
        }
        SymmetryElement::Rotation { axis, point, order } => {
            if perp(axis) {
                let b = normalize(sub(axis, scale(a, dot(axis, a)))).unwrap_or(axis);
                SymmetryElement::Rotation { axis: b, point: closest_on_line(point, p, a), order }
            } else if line_angle(axis, a) < SNAP {
                let b = if dot(axis, a) < 0.0 { scale(a, -1.0) } else { a };
                SymmetryElement::Rotation { axis: b, point: p, order }
            } else {
                e
            }
        }
        SymmetryElement::RotoReflection { axis, point, order } => {
            if line_angle(axis, a) < SNAP {
                let b = if dot(axis, a) < 0.0 { scale(a, -1.0) } else { a };
                SymmetryElement::RotoReflection { axis: b, point: closest_on_line(point, p, a), order }
            } else {
                e
            }
        }
        SymmetryElement::Inversion { center } => {
            SymmetryElement::Inversion { center: closest_on_line(center, p, a) }
        }
    }
}

/// Greedy group assembly (module documentation, step 3). `tol` is the acceptance tolerance of
/// the group's elements on the validation points.
fn assemble(
    shape: &Shape,
    analysis: &Analysis,
    o: &SymmetryDetectOptions,
    tol: f64,
    include_approx: bool,
) -> Option<AssembledGroup> {
    let mut list: Vec<Found> = analysis
        .found
        .iter()
        .copied()
        .filter(|f| f.status == CandidateStatus::Verified || include_approx)
        .collect();
    let rank = |e: &SymmetryElement| match e {
        SymmetryElement::Rotation { order, .. } => (0, u32::MAX - order),
        SymmetryElement::Mirror { .. } => (1, 0),
        SymmetryElement::RotoReflection { order, .. } => (2, u32::MAX - order),
        SymmetryElement::Inversion { .. } => (3, 0),
    };
    list.sort_by(|x, y| rank(&x.element).cmp(&rank(&y.element)).then(x.residual.total_cmp(&y.residual)));
    let metric = shape.metric();
    let merge = merge_distance(shape, tol);
    let mut elements = vec![IDENTITY4];
    let mut gens: Vec<Mat4> = Vec::new();
    let mut principal: Option<(Point3, Point3)> = None;
    let mut residual: f64 = 0.0;
    for f in list {
        let e = match principal {
            Some((a, p)) => snap(f.element, a, p),
            None => f.element,
        };
        let m = e.matrix();
        if group_contains(&elements, &m, &metric, merge) {
            continue;
        }
        let mut trial = gens.clone();
        trial.push(m);
        let Some(closure) = group_closure(&trial, &metric, merge, o.max_group_order) else { continue };
        // No axis of a higher order than was asked for (products of near-coincident elements
        // of a near-surface of revolution would otherwise build one).
        if group::classify(&closure).rotation_axes.first().is_some_and(|(_, n)| *n > o.max_rotation_order) {
            continue;
        }
        let new: Vec<&Mat4> =
            closure.iter().filter(|x| !group_contains(&elements, x, &metric, merge)).collect();
        let mut worst: f64 = 0.0;
        let mut ok = true;
        for x in new {
            let r = shape.surface.residual(&shape.validate, x, tol);
            if !r.complete || r.max > tol {
                ok = false;
                break;
            }
            worst = worst.max(r.max);
        }
        if !ok {
            continue;
        }
        residual = residual.max(worst).max(f.residual);
        gens = trial;
        elements = closure;
        if principal.is_none() {
            if let SymmetryElement::Rotation { axis, point, .. } = e {
                principal = Some((axis, point));
            }
        }
    }
    if elements.len() <= 1 {
        return None;
    }
    let structure = group::classify(&elements);
    let generators = group::choose_generators(&elements, &structure, &metric, merge);
    let name = group_name(&structure, &generators, shape.center);
    Some(AssembledGroup {
        name,
        elements,
        generators,
        structure,
        residual,
        center: shape.center,
        max_order: o.max_rotation_order,
    })
}

/// Distance below which two group elements are the same: five times the tolerance (products
/// of a few validated generators drift by about that much), at most 5% of the radius.
pub(crate) fn merge_distance(shape: &Shape, tol: f64) -> f64 {
    (5.0 * tol * shape.surface.diagonal).min(0.05 * shape.radius)
}

/// "mirror plane normal [...]", "rotation C10 about axis [...]", or
/// "C6v (order 12): rotation C6 about axis [...]; mirror plane normal [...]".
fn group_name(structure: &GroupStructure, generators: &[Mat4], center: Point3) -> String {
    let parts: Vec<String> =
        generators.iter().filter_map(|m| group::element_of(m, center)).map(|e| e.describe()).collect();
    if generators.len() == 1 && parts.len() == 1 {
        return parts[0].clone();
    }
    format!("{} (order {}): {}", structure.schoenflies, structure.order, parts.join("; "))
}

/// One report per distinct element (the lowest residual of each).
fn dedupe_reports<'a>(reports: impl Iterator<Item = &'a CandidateReport>) -> Vec<CandidateReport> {
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
