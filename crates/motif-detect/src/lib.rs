//! Approximate partial symmetry detection by co-occurrence analysis (thesis chapter 5,
//! Li et al. 2015).
//!
//! This crate's place in the workspace is fixed now; its algorithms land with the detection
//! issue: curvature features and the HOC descriptor (5.3.1, 5.4), the dictionary, EM
//! co-occurrence voting (5.3.2), spectral grouping into instances (5.3.3), MDL incremental
//! detection, and the evaluation protocol of 5.5.2. It depends on `motif-core` only.

#![warn(missing_docs)]

/// The thesis chapter this crate implements, for reports and `--version` output.
pub const THESIS_CHAPTER: &str = "5: approximate 3D partial symmetry detection by co-occurrence analysis";
