//! What detection reports: every candidate tested with its residuals, the groups found, the
//! parts analysed, and stage times.

use motif_core::Point3;
use motif_core::geometry::Mat4;
use motif_core::procedural::SymmetryAnnotation;
use serde::{Deserialize, Serialize};

use super::candidates::PrincipalAxes;
use super::element::SymmetryElement;
use super::group::GroupStructure;
use super::residual::Residual;

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

/// The result of [`detect_symmetries`](super::detect_symmetries): the annotation and the report.
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
