//! Structure-aware retargeting by offset statistics and graph cuts (thesis chapter 4,
//! Wu et al. 2014a).
//!
//! This crate's place in the workspace is fixed now; its algorithms land with the retargeting
//! issue: offset statistics (4.2.1, 4.4), the offset-sparsity study (4.3), the voxel MRF over the
//! offset label space with alpha-expansion on a Boykov–Kolmogorov max-flow (4.2.2), and the dense
//! baseline (4.5). It depends on `motif-core` only.
//!
//! Modules so far: [`offsets`] (offset statistics: dominant and principal offsets, 4.2.1, 4.4),
//! [`sparsity`] (the sparsity study, 4.3) and [`plot`] (their pictures).

#![warn(missing_docs)]

/// The thesis chapter this crate implements, for reports and `--version` output.
pub const THESIS_CHAPTER: &str = "4: 3D model retargeting using offset statistics";

pub mod offsets;
pub mod plot;
pub mod sparsity;
