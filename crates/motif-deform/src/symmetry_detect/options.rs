//! Options of [`detect_symmetries`](super::detect_symmetries).

use serde::{Deserialize, Serialize};

use super::error::{Result, SymmetryDetectError};

/// Which points a candidate must map onto the surface to be validated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ValidationPoints {
    /// The area-uniform surface samples and every mesh vertex referenced by a triangle (the
    /// shared data set's check: vertices catch small sharp features the samples may miss). The
    /// default.
    #[default]
    SamplesAndVertices,
    /// The surface samples only (faster on very dense meshes).
    Samples,
}

/// Which symmetries go into the annotation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AnnotationContents {
    /// Only groups whose every element is verified within `tolerance`. The default.
    #[default]
    Verified,
    /// Also elements that are only approximate (within `approximate_tolerance`); the annotation's
    /// tolerance is then `approximate_tolerance`.
    VerifiedAndApproximate,
}

/// Whether to look for symmetries of parts of the shape (thesis 3.2, partial symmetry).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PartialSymmetries {
    /// Global symmetries only.
    Off,
    /// Also analyse classes of congruent connected components (e.g. the sails of a windmill's
    /// rotor): the union of each class is analysed like a whole shape, and a group found there
    /// that the whole shape does not have is written with the largest union of components it
    /// maps onto itself as its region. The default.
    #[default]
    ComponentClasses,
}

/// Options of [`detect_symmetries`](super::detect_symmetries). Lengths are relative to the
/// bounding-box diagonal of the mesh, like the annotation's tolerance
/// (`../shared/formats/symmetry.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SymmetryDetectOptions {
    /// A candidate is verified when the largest distance from a transformed validation point to
    /// the surface is at most this (relative to the diagonal). Default `1e-3`: the shared data
    /// set's "verified" threshold (`MANIFEST.json`, `symmetry_check_method`). Written into the
    /// annotation as its `tolerance`.
    pub tolerance: f64,
    /// Candidates whose residual is below this but above `tolerance` are reported as
    /// approximate (relative to the diagonal); default `1e-2`, the data set's "approximate".
    pub approximate_tolerance: f64,
    /// Candidates whose residual on the screening samples exceeds this before refinement are
    /// rejected without refinement (relative to the diagonal); default `5e-2`, loose enough for
    /// candidate directions a degree or two off.
    pub screening_tolerance: f64,
    /// Number of area-uniform surface samples of the validation (seeded); default 30 000 (the
    /// data set's check uses 30k).
    pub validation_samples: usize,
    /// Which points are validated; default [`ValidationPoints::SamplesAndVertices`].
    pub validation_points: ValidationPoints,
    /// Number of surface samples of the quick first test of every candidate; default 512.
    pub screening_samples: usize,
    /// Number of surface samples the refinement matches; default 2 000.
    pub refine_samples: usize,
    /// Gauss–Newton iterations of the refinement of each candidate; default 8.
    pub refine_iterations: usize,
    /// Largest rotation order tested about each candidate axis (orders `max..2` are tried, the
    /// largest that validates is kept; its divisors are implied). Default 24. A surface of
    /// revolution validates at this order.
    pub max_rotation_order: u32,
    /// Largest group order assembled; generators whose closure exceeds it are dropped (two
    /// mirror planes at an angle that is not a rational multiple of π generate no finite
    /// group). Default 120 (the icosahedral group `Ih`).
    pub max_group_order: usize,
    /// Number of triangles drawn (seeded) as sources of the pair votes; default 2 000.
    pub vote_sources: usize,
    /// Largest number of mirror-normal peaks and of rotation-axis peaks taken from the votes;
    /// default 12 each.
    pub vote_peaks: usize,
    /// Angular step of the scan for mirror planes and 2-fold axes around a detected rotation
    /// axis (and the distinct principal axis of a shape with two equal moments), degrees;
    /// default 1 (a mirror is then at most 0.5° off, well inside screening; its basin is wider).
    pub scan_step_degrees: f64,
    /// Which symmetries the annotation holds; default [`AnnotationContents::Verified`].
    pub annotation: AnnotationContents,
    /// Whether to look for partial symmetries; default [`PartialSymmetries::ComponentClasses`].
    pub partial: PartialSymmetries,
    /// Seed of every random choice (samples, vote sources); default 1.
    pub seed: u64,
}

impl Default for SymmetryDetectOptions {
    fn default() -> Self {
        SymmetryDetectOptions {
            tolerance: 1e-3,
            approximate_tolerance: 1e-2,
            screening_tolerance: 5e-2,
            validation_samples: 30_000,
            validation_points: ValidationPoints::SamplesAndVertices,
            screening_samples: 512,
            refine_samples: 2_000,
            refine_iterations: 8,
            max_rotation_order: 24,
            max_group_order: 120,
            vote_sources: 2_000,
            vote_peaks: 12,
            scan_step_degrees: 1.0,
            annotation: AnnotationContents::Verified,
            partial: PartialSymmetries::ComponentClasses,
            seed: 1,
        }
    }
}

impl SymmetryDetectOptions {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<()> {
        let bad =
            |name: &'static str, message: String| Err(SymmetryDetectError::InvalidOption { name, message });
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return bad("tolerance", format!("{} must be in (0, 1) (e.g. 1e-3)", self.tolerance));
        }
        if !(self.approximate_tolerance >= self.tolerance && self.approximate_tolerance < 1.0) {
            return bad(
                "approximate_tolerance",
                format!(
                    "{} must be at least tolerance ({}) and below 1",
                    self.approximate_tolerance, self.tolerance
                ),
            );
        }
        if !(self.screening_tolerance >= self.approximate_tolerance && self.screening_tolerance <= 1.0) {
            return bad(
                "screening_tolerance",
                format!(
                    "{} must be at least approximate_tolerance ({}) and at most 1",
                    self.screening_tolerance, self.approximate_tolerance
                ),
            );
        }
        for (name, v, min) in [
            ("validation_samples", self.validation_samples, 100),
            ("screening_samples", self.screening_samples, 16),
            ("refine_samples", self.refine_samples, 32),
            ("max_group_order", self.max_group_order, 2),
        ] {
            if v < min {
                return bad(name, format!("{v} is too small: use at least {min}"));
            }
        }
        if !(2..=360).contains(&self.max_rotation_order) {
            return bad("max_rotation_order", format!("{} must be in 2..=360", self.max_rotation_order));
        }
        if !(self.scan_step_degrees > 0.0 && self.scan_step_degrees <= 10.0) {
            return bad(
                "scan_step_degrees",
                format!("{} must be in (0, 10] degrees", self.scan_step_degrees),
            );
        }
        Ok(())
    }
}
