//! Automatic detection of global (and, from congruent parts, partial) symmetries of a triangle
//! mesh, written as a `motif_symmetry_v1` annotation (`../shared/formats/symmetry.md`) so nobody
//! has to write 4×4 matrices by hand (thesis 3.2: "we use both manual annotation as well as
//! automatic detection").
//!
//! Pipeline of [`detect_symmetries`]:
//! 1. **Centre and candidates.** Every global symmetry fixes the area-weighted centroid `c`, so
//!    candidates are directions through `c`: the coordinate axes, the principal axes of the
//!    area-weighted covariance, and the peaks of votes of matched triangle pairs (a pair with
//!    equal invariants proposes the plane bisecting it and the axis turning one into the other,
//!    in the spirit of Mitra, Guibas and Pauly, "Partial and approximate symmetry detection for
//!    3D geometry", SIGGRAPH 2006). Each axis is tried as a rotation axis of every order
//!    `max_rotation_order..=2` (the largest order that validates is kept; its divisors are
//!    implied), each direction as a mirror normal; the inversion through `c` and the
//!    rotoreflections `S₂ₙ` about detected axes are tried too. Around each detected axis of
//!    order `n ≥ 3` (and around the distinct principal axis when the other two moments are
//!    equal, where principal axes say nothing about in-plane directions) mirror normals and
//!    2-fold axes perpendicular to it are scanned over `[0, π/n)`.
//! 2. **Validation by closest-point residual.** A candidate is screened on a few hundred
//!    samples, refined by Gauss–Newton on point-to-surface distances (ICP-like, the element's
//!    type and order kept; a few coarse steps first, after which hopeless candidates are
//!    dropped), then the largest distance from the transformed validation points (area-uniform
//!    samples and mesh vertices) to the surface — exact point–triangle distance through a
//!    bounding-volume hierarchy — is compared with the tolerance (relative to the bounding-box
//!    diagonal): verified, approximate, or rejected.
//! 3. **Group assembly.** Verified elements are added greedily (higher rotation orders first,
//!    then mirrors, then the rest, lowest residual first) as long as the group they generate is
//!    finite, has no axis of an order above `max_rotation_order`, and each of its new elements
//!    passes the same validation as a candidate. Elements nearly aligned with the principal axis
//!    of the group are snapped onto it, so the written generators generate the group exactly.
//!    The annotation holds the full group with an irredundant generator set, region `"all"`.
//! 4. **Partial symmetries** (optional): each class of congruent connected components is
//!    analysed like a whole shape; a group it has that the shape lacks is written with the
//!    largest union of components it maps onto itself as its region (the windmill's 4-fold
//!    rotor), see `partial.rs`.
//!
//! The report lists every candidate with its residuals, the approximate symmetries, and the
//! groups with their structure (Schoenflies symbol, rotation axes and orders, mirror planes).
//!
//! Conventions: transforms are row-major 4×4 acting on column vectors; residuals and tolerances
//! are relative to the bounding-box diagonal of the mesh. Detection is deterministic for a seed
//! (only the reported mean residuals can differ in the last bits between thread counts).

mod assemble;
pub(crate) mod bvh;
mod candidates;
mod element;
mod error;
mod group;
mod options;
mod partial;
mod refine;
mod report;
mod residual;
mod search;
mod shape;

use std::time::Instant;

use motif_core::geometry::IDENTITY4;
use motif_core::mesh::TriMesh;
use motif_core::procedural::{Region, SYMMETRY_FORMAT, Symmetry, SymmetryAnnotation, SymmetryKind};
use motif_core::progress::{NoProgress, Progress};

pub use candidates::PrincipalAxes;
pub use element::SymmetryElement;
pub use error::{Result, SymmetryDetectError};
pub use group::{GroupStructure, TransformMetric, group_closure, group_contains};
pub use options::{AnnotationContents, PartialSymmetries, SymmetryDetectOptions, ValidationPoints};
pub use report::{
    CandidateReport, CandidateSource, CandidateStatus, GroupReport, PartReport, Scope, SymmetryDetection,
    SymmetryReport, Timings,
};
pub use residual::Residual;

use assemble::{AssembledGroup, assemble};
use search::{analyse, dedupe_reports};
use shape::{Shape, non_degenerate};

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
    let shape = Shape::new(mesh, &non_degenerate(mesh), diag, options, options.seed, usize::MAX)?;
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
